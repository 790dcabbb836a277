"""PNGs encoded while the render runs (tracer.png_stream, issue #23) are the files the plain write makes.

The reference is :func:`tracer.film.write_image` (numpy's sRGB curve per pixel, then OpenImageIO): the streamed
path converts with a threshold table and writes bands of scanlines from a thread, and must give the same bytes.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from tracer import RenderSettings, write_image
from tracer import render
from tracer.film import to_display
from tracer.png_stream import StreamedPNG, display_thresholds, to_display_fast
from usd_io.outputs import Outputs

from tracer_scenes import lit_sphere_on_floor


def test_the_threshold_table_gives_to_displays_codes():
    """Every code's threshold and its float32 neighbours, random values, NaN/inf/negative/over-range: the table's
    codes equal ``to_display`` of the values ``write_image`` would hand it (NaN and inf as 0)."""
    colour, alpha = display_thresholds()
    edges = np.concatenate([colour, alpha]).view(np.int32)
    near = np.concatenate([edges - 1, edges, edges + 1]).view(np.float32)
    rng = np.random.default_rng(7)
    special = np.array([np.nan, np.inf, -np.inf, -1.0, -0.0, 0.0, 1e-45, 1.0, 1.0000001, 3.5, 1e38], np.float32)
    values = np.concatenate([near, special, rng.random(40_000, np.float32), rng.random(4000, np.float32) * 0.01])
    rgba = np.repeat(values[:, None], 4, axis=1)[None]  # the same value in every channel
    want = to_display(np.nan_to_num(rgba, nan=0.0, posinf=0.0, neginf=0.0))
    assert np.array_equal(to_display_fast(rgba), want)
    scaled = rgba.copy()
    scaled[..., :3] *= np.float32(2.0 ** 1.7)
    assert np.array_equal(to_display_fast(rgba, np.float32(2.0 ** 1.7)),
                          to_display(np.nan_to_num(scaled, nan=0.0, posinf=0.0, neginf=0.0)))


@pytest.mark.parametrize("exposure", [0.0, 1.25])
def test_a_streamed_png_is_the_plain_write_byte_for_byte(tmp_path, exposure):
    """A render fed tile by tile into the stream (bands written while later tiles trace) gives the same file as the
    finished image written whole, at an exposure too (the stream applies it, the plain write exposes the image)."""
    scene = lit_sphere_on_floor().build()
    settings = RenderSettings(width=72, height=40, tile_size=16, threads=2, samples=1)
    outputs = Outputs(exposure=exposure)
    streamed = tmp_path / "streamed.png"
    stream = outputs.stream(str(streamed), settings.width, settings.height)
    bands = []
    feed = stream.on_tile
    stream.on_tile = lambda image, tile: (feed(image, tile), bands.append(stream._next))
    image = render(scene, settings, on_tile=stream.on_tile)
    outputs.write(image, str(streamed), stream)
    assert bands[0] == 0 and 0 < bands[4] < settings.height  # rows went out before the last tile came in
    plain = tmp_path / "plain.png"
    again = render(scene, settings)
    outputs.write(again, str(plain))
    assert streamed.read_bytes() == plain.read_bytes()
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".whitted-")]


def test_an_aborted_stream_leaves_no_file(tmp_path):
    out = tmp_path / "x.png"
    stream = StreamedPNG(str(out), 8, 4)
    stream.abort()
    assert os.listdir(tmp_path) == []


def test_streamed_and_plain_writes_agree_on_odd_values(tmp_path):
    """An image with NaN, inf, negative and over-range pixels and partial alpha, fed in two uneven bands."""
    rng = np.random.default_rng(3)
    rgba = rng.random((37, 53, 4), np.float32) * 1.3 - 0.1
    rgba[3, :5, 0] = [np.nan, np.inf, -np.inf, 1e30, -1e30]
    rgba[5, 7, 3] = np.nan

    class Img:
        pass

    img = Img()
    img.rgba = rgba
    stream = StreamedPNG(str(tmp_path / "s.png"), 53, 37)
    stream.on_tile(img, (0, 0, 53, 11))
    stream.on_tile(img, (0, 11, 30, 37))  # the rest of the rows only half filled: finish() writes them
    stream.finish(img)
    write_image(tmp_path / "p.png", rgba)
    assert (tmp_path / "s.png").read_bytes() == (tmp_path / "p.png").read_bytes()

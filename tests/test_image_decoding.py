"""One image decoder for the tracer's API and the USD reader (issue #31): ``tracer.shading.texture.decode_image``.

Files are written here with OpenImageIO with known code values, and the expected linear values come from the sRGB
transfer function's closed form (IEC 61966-2-1), not from the decoder's own code."""

from __future__ import annotations

import numpy as np
import OpenImageIO as oiio
import pytest

from tracer.shading.graph import ImageRef
from tracer.shading.texture import decode_image, load_texture
from usd_io.materials.texture_files import read_texture_file


def _srgb(code: int, levels: int = 255) -> float:
    """The sRGB EOTF at an integer code value (closed form)."""
    c = code / levels
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


def _write(path, pixels: np.ndarray, fmt):
    spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], fmt)
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec)
    assert out.write_image(pixels)
    out.close()


def test_auto_is_storms_rule(tmp_path):
    """auto: an 8-bit RGB file is sRGB; an 8-bit grey one, a 16-bit RGB one and a float one keep their values."""
    rgb8 = tmp_path / "rgb8.png"
    _write(rgb8, np.full((2, 2, 3), 128, np.uint8), oiio.UINT8)
    grey8 = tmp_path / "grey8.png"
    _write(grey8, np.full((2, 2, 1), 128, np.uint8), oiio.UINT8)
    rgb16 = tmp_path / "rgb16.png"
    _write(rgb16, np.full((2, 2, 3), 32768, np.uint16), oiio.UINT16)
    flt = tmp_path / "f.exr"
    _write(flt, np.full((2, 2, 3), 0.25, np.float32), oiio.FLOAT)
    assert decode_image(rgb8).rgba[0, 0, 0] == pytest.approx(_srgb(128), abs=1e-6)
    assert decode_image(rgb8).srgb
    assert decode_image(grey8).rgba[0, 0, :3] == pytest.approx([128 / 255] * 3, abs=1e-6)
    assert decode_image(rgb16).rgba[0, 0, 0] == pytest.approx(32768 / 65535, abs=1e-6)
    assert decode_image(flt).rgba[0, 0, 0] == pytest.approx(0.25)
    # an explicit space wins, in either spelling
    assert decode_image(grey8, "sRGB").rgba[0, 0, 0] == pytest.approx(_srgb(128), abs=1e-6)
    assert decode_image(rgb8, "raw").rgba[0, 0, 0] == pytest.approx(128 / 255, abs=1e-6)
    with pytest.raises(ValueError, match="colour space"):
        decode_image(rgb8, "acescg")


def test_alpha_stays_straight_and_is_never_decoded(tmp_path):
    """A half-transparent pure red texel reads red 1 (PNG stores straight alpha; premultiplied it would be 0.5) and
    its alpha 128/255 as stored."""
    png = tmp_path / "cutout.png"
    px = np.zeros((1, 2, 4), np.uint8)
    px[..., 0], px[..., 3] = 255, 128
    _write(png, px, oiio.UINT8)
    rgba = decode_image(png).rgba
    assert rgba[0, 0, 0] == pytest.approx(1.0) and rgba[0, 0, 3] == pytest.approx(128 / 255, abs=1e-6)
    assert load_texture(str(png), channels=4)[0, 0, 0] == pytest.approx(1.0)


def test_api_and_usd_read_a_file_alike(tmp_path):
    """The tracer's API (an ImageRef by path, load_texture) and the USD reader decode the same file to the same
    texels with the same rule: a grey 8-bit mask stays linear in both (the API made it sRGB before)."""
    mask = tmp_path / "mask.png"
    _write(mask, np.arange(16, dtype=np.uint8).reshape(4, 4, 1) * 16, oiio.UINT8)
    usd = read_texture_file(str(mask), "auto").pixels
    api = ImageRef(path=str(mask)).rgba()
    np.testing.assert_array_equal(np.asarray(api), usd)
    assert usd[0, 1, 0] == pytest.approx(16 / 255, abs=1e-6)

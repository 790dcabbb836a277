"""tracer.shading.udim: the UDIM atlases of the USD reader (affine, unpadded) and of the Blender add-on (each tile
padded with its own wrap, Cycles' tile map)."""

from __future__ import annotations

import numpy as np
import pytest

from tracer.shading.udim import tile_uv, udim_atlas, udim_atlas_padded, udim_st

MAGENTA = (1.0, 0.0, 1.0, 1.0)


def flat(colour, size):
    return np.broadcast_to(np.asarray(colour, np.float32), (size, size, 4)).copy()


def texel(atlas, s, t):
    """The texel (closest) of ``atlas`` at (s, t), clamped (t up, row 0 = top)."""
    h, w = atlas.shape[:2]
    col = np.clip(np.floor(np.asarray(s) * w).astype(int), 0, w - 1)
    row = np.clip(np.floor((1.0 - np.asarray(t)) * h).astype(int), 0, h - 1)
    return atlas[row, col]


def test_tile_numbers():
    assert tile_uv(1001) == (0, 0) and tile_uv(1002) == (1, 0) and tile_uv(1011) == (0, 1) and tile_uv(1100) == (9, 9)


def test_unpadded_atlas_puts_tiles_where_their_numbers_say():
    red, blue = flat((1, 0, 0, 1), 4), flat((0, 0, 1, 1), 4)
    atlas, m, notes = udim_atlas([(1001, red), (1012, blue)], (0.5, 0.5, 0.5, 1.0))
    assert atlas.shape == (8, 8, 4) and not notes
    np.testing.assert_allclose(np.diag(m), (0.5, 0.5, 1.0))
    np.testing.assert_allclose(texel(atlas, 0.25 * 0.5, 0.25 * 0.5), (1, 0, 0, 1))  # uv (0.25, 0.25): 1001
    np.testing.assert_allclose(texel(atlas, 1.5 * 0.5, 1.5 * 0.5), (0, 0, 1, 1))  # uv (1.5, 1.5): 1012
    np.testing.assert_allclose(texel(atlas, 1.5 * 0.5, 0.5 * 0.5), (0.5, 0.5, 0.5, 1.0))  # 1002: fallback


@pytest.mark.parametrize("wrap", ["repeat", "clamp", "mirror", "black"])
def test_padded_atlas_reads_each_tile_with_its_own_wrap(wrap):
    """Every texel of every tile is where udim_st puts it; the border past a tile's edge is what its own wrap
    reads there; absent tiles and outside the set are magenta."""
    rng = np.random.default_rng(1)
    a, b = rng.random((4, 4, 4)).astype(np.float32), rng.random((4, 4, 4)).astype(np.float32)
    atlas, k, notes = udim_atlas_padded([(1001, a), (1012, b)], wrap, MAGENTA)
    assert not notes and k["tiles"] == (2, 2)
    centres = (np.arange(4) + 0.5) / 4
    for img, (i, j) in ((a, (0, 0)), (b, (1, 1))):
        for r in range(4):
            for c in range(4):  # texel (r, c) of the tile (row 0 the top) sits at uv (i + x, j + 1 - y)
                s, t = udim_st(i + centres[c], j + 1 - centres[r], k)
                np.testing.assert_allclose(texel(atlas, s, t), img[r, c])
    s, t = udim_st(1.0 + 0.25 / 4, 0.5, k)  # tile 1002 (absent): magenta
    np.testing.assert_allclose(texel(atlas, s, t), MAGENTA)
    s, t = udim_st(0.999, 1.0 - 0.5 / 4, k)  # 1001's top-right texel, then one texel past its right edge:
    np.testing.assert_allclose(texel(atlas, s, t), a[0, 3])
    past = texel(atlas, s + 1.0 / atlas.shape[1], t)
    expected = {"repeat": a[0, 0], "clamp": a[0, 3], "mirror": a[0, 3], "black": (0, 0, 0, 0)}[wrap]
    np.testing.assert_allclose(past, expected)
    for x, y in ((2.5, 0.5), (0.5, 2.5), (5.0, 5.0), (-3.0, 0.5)):  # outside the set
        np.testing.assert_allclose(texel(atlas, *udim_st(x, y, k)), MAGENTA)


def test_padded_atlas_enlarges_smaller_tiles_to_the_largest():
    big, small = flat((1, 0, 0, 1), 8), flat((0, 1, 0, 1), 2)
    atlas, k, notes = udim_atlas_padded([(1001, small), (1002, big)], "clamp", MAGENTA)
    assert not notes  # enlarging loses nothing
    assert atlas.shape[:2] == (8 + 4 + 2, 2 * (8 + 4) + 2)
    np.testing.assert_allclose(texel(atlas, *udim_st(0.5, 0.5, k)), (0, 1, 0, 1))
    np.testing.assert_allclose(texel(atlas, *udim_st(1.5, 0.5, k)), (1, 0, 0, 1))

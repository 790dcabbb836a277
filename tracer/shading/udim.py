"""UDIM tile sets read as one texture: the tiles laid into an atlas, and the (s, t) matrix that reads it.

Tile ``1001 + u + 10·v`` covers uv ∈ [u, u+1] × [v, v+1] (u in 0..9). :func:`udim_atlas` lays the tiles into one
image ``U`` tiles wide and ``V`` high (U, V: the largest u and v present, plus one), every tile resampled (nearest)
to the first tile's size, the places of absent tiles filled with a fallback colour; a lookup followed by the matrix
``(s/U, t/V)`` then reads each texel where the tile set puts it. Wrap the atlas with clamp: tiles do not repeat.
Filtering across a seam blends the neighbouring tile's edge texel (each tile's own renderer, without padding, reads
its own edge instead: a half-texel difference).

The one implementation of both front ends: the USD reader (``usd_io/materials/texture_assets.py``, ``<UDIM>``
asset paths) and the Blender add-on (``addon/udim.py``, images whose source is ``TILED``).
"""

from __future__ import annotations

import numpy as np

FIRST_TILE = 1001
MAX_TILES = 100  # UDIM's range: 1001..1100 (10 × 10)


def is_udim_tile(number: int) -> bool:
    """Whether ``number`` names a tile of the UDIM range."""
    return FIRST_TILE <= int(number) < FIRST_TILE + MAX_TILES


def tile_uv(number: int) -> tuple[int, int]:
    """(u, v) of the tile ``number``: its uv square is [u, u+1] × [v, v+1]."""
    i = int(number) - FIRST_TILE
    return i % 10, i // 10


def udim_atlas(tiles: list, fallback) -> tuple[np.ndarray, np.ndarray, list]:
    """(atlas pixels (V·H, U·W, 4) float32, the (3, 3) uv matrix diag(1/U, 1/V, 1), notes) of ``tiles``, a list of
    (tile number, (H, W, 4) pixels, row 0 = the top); ``fallback`` (RGBA) fills the places of absent tiles. Row 0
    is the top of every image: tile v = 0 goes to the atlas's bottom rows. Raises ValueError without tiles."""
    if not tiles:
        raise ValueError("no UDIM tiles")
    notes = []
    uvs = [tile_uv(t) for t, _px in tiles]
    n_u, n_v = max(u for u, _v in uvs) + 1, max(v for _u, v in uvs) + 1
    h, w = np.asarray(tiles[0][1]).shape[:2]
    fill = np.ones(4, np.float32)
    fb = np.asarray(tuple(fallback), np.float32)[:4]
    fill[:fb.size] = fb
    atlas = np.empty((n_v * h, n_u * w, 4), np.float32)
    atlas[:] = fill
    for (number, img), (u, v) in zip(tiles, uvs):
        img = np.asarray(img, np.float32)
        if img.shape[:2] != (h, w):
            notes.append(f"tile {number} is {img.shape[1]}x{img.shape[0]}, not {w}x{h}: resampled")
            yi = (np.arange(h) * img.shape[0] // h)[:, None]
            xi = (np.arange(w) * img.shape[1] // w)[None, :]
            img = img[yi, xi]
        row = (n_v - 1 - v) * h
        atlas[row:row + h, u * w:(u + 1) * w] = img[..., :4]
    return atlas, np.diag([1.0 / n_u, 1.0 / n_v, 1.0]), notes

"""UDIM tile sets read as one texture: the tiles laid into an atlas, and the (s, t) matrix that reads it.

Tile ``1001 + u + 10·v`` covers uv ∈ [u, u+1] × [v, v+1] (u in 0..9). :func:`udim_atlas` lays the tiles into one
image ``U`` tiles wide and ``V`` high (U, V: the largest u and v present, plus one), every tile resampled (nearest)
to the first tile's size, the places of absent tiles filled with a fallback colour; a lookup followed by the matrix
``(s/U, t/V)`` then reads each texel where the tile set puts it. Wrap the atlas with clamp: tiles do not repeat.
Filtering across a seam blends the neighbouring tile's edge texel (each tile's own renderer reads its own edge
instead: a half-texel difference, which a few low-resolution tiles show).

:func:`udim_atlas_padded` reads the tiles as Cycles does: each tile in a cell with a border of what its own wrap
reads past its edge, absent tiles and the outside of the set magenta; the map from the tile set to that atlas is
affine within each tile (the tile index is ⌊u⌋), so it is a few Vector Math nodes in front of the lookup rather
than a matrix.

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


def _resample(img: np.ndarray, h: int, w: int, smooth: bool) -> np.ndarray:
    """``img`` at h × w: nearest texel, or (``smooth``) bilinear at the new texel centres with the edges extended
    (an enlarged tile then reads, texel by texel, what a bilinear lookup of the tile itself reads there)."""
    if not smooth or img.shape[0] > h or img.shape[1] > w:
        yi = (np.arange(h) * img.shape[0] // h)[:, None]
        xi = (np.arange(w) * img.shape[1] // w)[None, :]
        return img[yi, xi]
    def axis(n_in, n_out):
        x = np.clip((np.arange(n_out) + 0.5) * n_in / n_out - 0.5, 0.0, n_in - 1)
        i0 = np.floor(x).astype(int)
        i1 = np.minimum(i0 + 1, n_in - 1)
        return i0, i1, (x - i0).astype(np.float32)
    y0, y1, fy = axis(img.shape[0], h)
    x0, x1, fx = axis(img.shape[1], w)
    rows = img[y0] * (1 - fy)[:, None, None] + img[y1] * fy[:, None, None]
    return rows[:, x0] * (1 - fx)[None, :, None] + rows[:, x1] * fx[None, :, None]


def _tiles(tiles: list, size: str = "first", smooth: bool = False):
    """(uvs, U, V, h, w, images resampled to one size, notes) of (tile number, pixels) pairs: the first tile's size
    (``size`` "first") or the largest width and height of any (``size`` "largest": no tile loses texels; smaller
    ones are enlarged, bilinearly when ``smooth``)."""
    if not tiles:
        raise ValueError("no UDIM tiles")
    notes, images = [], []
    uvs = [tile_uv(t) for t, _px in tiles]
    n_u, n_v = max(u for u, _v in uvs) + 1, max(v for _u, v in uvs) + 1
    shapes = [np.asarray(px).shape[:2] for _t, px in tiles]
    h, w = shapes[0] if size == "first" else (max(s[0] for s in shapes), max(s[1] for s in shapes))
    for number, img in tiles:
        img = np.asarray(img, np.float32)
        if img.shape[:2] != (h, w):
            if size == "first":  # (enlarging to the largest loses nothing: no note)
                notes.append(f"tile {number} is {img.shape[1]}x{img.shape[0]}, not {w}x{h}: resampled")
            img = _resample(img, h, w, smooth)
        images.append(img[..., :4])
    return uvs, n_u, n_v, h, w, images, notes


def _rgba(colour) -> np.ndarray:
    out = np.ones(4, np.float32)
    c = np.asarray(tuple(colour), np.float32)[:4]
    out[:c.size] = c
    return out


def udim_atlas(tiles: list, fallback) -> tuple[np.ndarray, np.ndarray, list]:
    """(atlas pixels (V·H, U·W, 4) float32, the (3, 3) uv matrix diag(1/U, 1/V, 1), notes) of ``tiles``, a list of
    (tile number, (H, W, 4) pixels, row 0 = the top); ``fallback`` (RGBA) fills the places of absent tiles. Row 0
    is the top of every image: tile v = 0 goes to the atlas's bottom rows. Raises ValueError without tiles."""
    uvs, n_u, n_v, h, w, images, notes = _tiles(tiles)
    atlas = np.empty((n_v * h, n_u * w, 4), np.float32)
    atlas[:] = _rgba(fallback)
    for img, (u, v) in zip(images, uvs):
        row = (n_v - 1 - v) * h
        atlas[row:row + h, u * w:(u + 1) * w] = img
    return atlas, np.diag([1.0 / n_u, 1.0 / n_v, 1.0]), notes


#: Texels of each padded tile's border (:func:`udim_atlas_padded`): bicubic reads two texels past its cell.
PAD = 2
#: A tile's own wrap -> the ``np.pad`` mode that fills its border with what that wrap reads past its edge.
_PAD_MODES = {"repeat": "wrap", "clamp": "edge", "mirror": "symmetric", "black": "constant"}


def udim_atlas_padded(tiles: list, wrap: str, missing, pad: int = PAD, smooth: bool = True) -> tuple[np.ndarray, dict,
                                                                                                   list]:
    """Tiles laid as Cycles reads them, each with its own wrap: (atlas, coefficients, notes).

    Every tile (enlarged to the largest tile's size h × w: bilinearly when ``smooth``, for a Linear or Cubic
    lookup; by nearest texel for Closest) gets a border of ``pad`` texels holding what its own
    ``wrap`` ("repeat" | "clamp" | "mirror" | "black") reads past its edges, so a filter at a seam reads the tile
    itself, not its neighbour; cells of absent tiles are ``missing`` (RGBA), and so is a one-texel ring round the
    atlas (Cycles reads no tile there: magenta). The atlas is U·(w + 2·pad) + 2 texels wide and V·(h + 2·pad) + 2
    high. A point (X, Y) of the tile set maps to the atlas's (s, t) through the tile (i, j) = (min(⌊max(X, 0)⌋, U),
    min(⌊max(Y, 0)⌋, V)):  s = X·a_s + i·b_s + c_s,  t = Y·a_t + j·b_t + c_t  (the coefficients' "scale", "tile",
    "offset"; "tiles" = (U, V)); look the atlas up with clamp. :func:`udim_st` evaluates it."""
    if wrap not in _PAD_MODES:
        raise ValueError(f"unknown wrap {wrap!r}")
    uvs, n_u, n_v, h, w, images, notes = _tiles(tiles, "largest", smooth)
    cw, ch = w + 2 * pad, h + 2 * pad
    width, height = n_u * cw + 2, n_v * ch + 2
    atlas = np.empty((height, width, 4), np.float32)
    atlas[:] = _rgba(missing)
    for img, (u, v) in zip(images, uvs):
        cell = np.pad(img, ((pad, pad), (pad, pad), (0, 0)), mode=_PAD_MODES[wrap])
        top = height - 1 - (v + 1) * ch  # rows from the top: the ring, then the cells of rows V-1 .. v+1
        col = 1 + u * cw
        atlas[top:top + ch, col:col + cw] = cell
    coeffs = {"tiles": (n_u, n_v), "scale": (w / width, h / height),
              "tile": (2 * pad / width, 2 * pad / height), "offset": ((1 + pad) / width, (1 + pad) / height)}
    return atlas, coeffs, notes


def udim_st(x, y, coeffs: dict):
    """The atlas (s, t) of tile-set points (x, y) (arrays): :func:`udim_atlas_padded`'s map."""
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    n_u, n_v = coeffs["tiles"]
    i = np.minimum(np.floor(np.maximum(x, 0.0)), n_u)
    j = np.minimum(np.floor(np.maximum(y, 0.0)), n_v)
    (a_s, a_t), (b_s, b_t), (c_s, c_t) = coeffs["scale"], coeffs["tile"], coeffs["offset"]
    return x * a_s + i * b_s + c_s, y * a_t + j * b_t + c_t

"""Blender's tiled (UDIM) images read as one texture: every tile's pixels, laid into an atlas.

``Image.pixels`` holds the first tile only, so each tile is read from where Blender keeps it:

- a **packed** tile (``Image.packed_files``, one per tile number): its bytes, written to a temporary file;
- a tile **on disk**: the image's path with ``<UDIM>`` (or ``<UVTILE>``, ``u{u+1}_v{v+1}``) replaced by the tile;
- a tile held **in memory only** (generated, or painted and not saved: ``Image.is_dirty``): Blender saves a copy
  of the tile set to a temporary folder (``Image.save(save_copy=True)``, the datablock is untouched) and the copy is
  read.

Each file is loaded as a temporary image datablock with the tiled image's colour space and alpha mode and decoded
exactly as a single image (:func:`addon.nodes.image_rgba`'s reader), then removed (where Blender allows no new
datablock, OpenImageIO decodes it with the colour space's transfer). The tiles go into one atlas as
Cycles reads them (:func:`tracer.shading.udim.udim_atlas_padded`, beside the USD reader's atlas): each tile
bordered by what the node's Extension reads past its own edges, so a seam filters as in Cycles (each tile is its
own texture there). A tile Blender lists but cannot give pixels for (a tile added without a fill, a missing file)
is Cycles' missing-image magenta; so are the place of a tile the set lacks and uv outside the set.
"""

from __future__ import annotations

import os
import shutil
import tempfile

import numpy as np

from .bundled import tracer_module

_udim = tracer_module("shading.udim")
udim_atlas_padded, tile_uv, is_udim_tile = _udim.udim_atlas_padded, _udim.tile_uv, _udim.is_udim_tile
decode_image = tracer_module("shading.texture").decode_image

#: What Cycles renders for a tile it cannot read (TEX_IMAGE_MISSING_R/G/B/A): magenta, alpha 1.
MISSING = (1.0, 0.0, 1.0, 1.0)


def tile_path(filepath: str, number: int) -> str:
    """``filepath`` with its UDIM token replaced by tile ``number``."""
    u, v = tile_uv(number)
    return filepath.replace("<UDIM>", str(number)).replace("<UVTILE>", f"u{u + 1}_v{v + 1}")


def new_image(path: str):
    """A new image datablock of the file ``path`` (a test replaces it to refuse, as a viewport's drawing does)."""
    import bpy

    return bpy.data.images.load(path, check_existing=False)


def _load_rgba(path: str, like, read) -> np.ndarray:
    """Pixels of the file ``path`` decoded as the image ``like`` would be (colour space, alpha mode): through a
    temporary image datablock, or, where Blender allows no new datablock (a viewport's drawing), OpenImageIO with
    the colour space's transfer (sRGB or none)."""
    import bpy

    try:
        im = new_image(path)
    except (RuntimeError, AttributeError):  # blend data not writable in this context
        space = "srgb" if "srgb" in like.colorspace_settings.name.lower() else "raw"
        return decode_image(path, space, label=path).rgba
    try:
        im.colorspace_settings.name = like.colorspace_settings.name
        if hasattr(like, "alpha_mode"):
            im.alpha_mode = like.alpha_mode
        if im.size[0] == 0 or im.size[1] == 0:
            raise ValueError(f"{path!r} has no pixels")
        return read(im)
    finally:
        bpy.data.images.remove(im)


def tile_pixels(image, read) -> tuple[list, list]:
    """([(tile number, (H, W, 4) pixels)] in tile order, notes) of a tiled image; ``read(image)`` decodes a single
    image datablock (:func:`addon.nodes._read_rgba`)."""
    import bpy

    notes = []
    numbers = sorted(int(t.number) for t in image.tiles if is_udim_tile(t.number))
    dropped = [int(t.number) for t in image.tiles if not is_udim_tile(t.number)]
    if dropped:
        notes.append(f"tiles {dropped} are outside UDIM's 1001..1100 and not read")
    packed = {int(p.tile_number): p for p in getattr(image, "packed_files", ()) if getattr(p, "packed_file", None)}
    tokenised = image.filepath_raw or image.filepath
    try:
        base = bpy.path.abspath(tokenised, library=image.library)
    except (ValueError, AttributeError):
        base = tokenised
    ext = os.path.splitext(tokenised)[1] or ".png"
    tmp = tempfile.mkdtemp(prefix="whitted-udim-")
    try:
        copy = None  # tile number -> file of the saved copy (in-memory tiles)
        if image.is_dirty or any(getattr(t, "is_generated_tile", False) for t in image.tiles):
            copy = _saved_copy(image, tmp, ext)
        out = []
        for n in numbers:
            path = None
            if copy is not None and n in copy:
                path = copy[n]
            elif n in packed:
                path = os.path.join(tmp, f"packed.{n}{ext}")
                with open(path, "wb") as f:
                    f.write(packed[n].packed_file.data)
            elif base and os.path.isfile(tile_path(base, n)):
                path = tile_path(base, n)
            if path is None:
                notes.append(f"tile {n} has no pixels (no file, nothing packed); magenta stands in, as in Cycles")
                continue
            try:
                out.append((n, _load_rgba(path, image, read)))
            except Exception as exc:  # noqa: BLE001  (an unreadable file: Blender's own error)
                notes.append(f"tile {n} not read ({exc}); magenta stands in, as in Cycles")
        return out, notes
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _saved_copy(image, folder: str, ext: str) -> dict:
    """{tile number: file} of a copy of ``image``'s tiles saved by Blender into ``folder`` (the tiles Blender holds
    in memory: generated or painted); empty when Blender cannot save them."""
    path = os.path.join(folder, f"copy.<UDIM>{ext}")
    try:
        image.save(filepath=path, save_copy=True)
    except Exception:  # noqa: BLE001  (a tile without a buffer stops the save: the tiles before it are written)
        pass
    found = {}
    for t in image.tiles:
        p = tile_path(path, int(t.number))
        if os.path.isfile(p):
            found[int(t.number)] = p
    return found


def tiled_atlas(tiles: list, wrap: str, smooth: bool = True) -> tuple[np.ndarray, dict, list]:
    """(atlas (H, W, 4), the tile set -> atlas map's coefficients, notes) of ``tiles`` (:func:`tile_pixels`), each
    tile bordered by what its own ``wrap`` (the node's Extension) reads past its edges, absent tiles magenta
    (:func:`tracer.shading.udim.udim_atlas_padded`: smaller tiles enlarged to the largest, bilinearly when
    ``smooth``); raises ValueError without tiles."""
    atlas, coeffs, notes = udim_atlas_padded(tiles, wrap, MISSING, smooth=smooth)
    return np.ascontiguousarray(atlas), coeffs, notes

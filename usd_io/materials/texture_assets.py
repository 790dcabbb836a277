"""Texture asset paths the default resolver does not find by itself: Windows backslashes and UDIM sets.

Backslashes. Exporters on Windows write ``textures\\wood.png``; USD's resolver treats ``\\`` as a file-name
character on Linux/macOS, so the file is not found. When the path as authored does not resolve and holds a
backslash, it is tried again with forward slashes, anchored to the layer that authored it (one note per stage).

UDIM. ``<UDIM>`` in a path names tiles 1001, 1002, …: tile ``1001 + u + 10·v`` covers uv ∈ [u, u+1] × [v, v+1]
(``UsdShade.UdimUtils.ResolveUdimTilePaths`` finds them next to the authoring layer). The tiles are laid into one
atlas image, ``U`` tiles wide and ``V`` high (every tile resampled to the first tile's size; a missing tile is the
lookup's fallback colour), and the lookup's uv transform is followed by ``(s/U, t/V)``, so a texel is read where
the tile set puts it. Wrap is clamp (UDIM tiles do not repeat). Filtering across a tile seam blends the
neighbouring tile's edge texel — the same as the tiles' own renderers without padding. The atlas itself is
:func:`tracer.shading.udim.udim_atlas`, shared with the Blender add-on's tiled images.
"""

from __future__ import annotations

import os

import numpy as np
from pxr import Sdf, UsdShade

from tracer.shading.udim import is_udim_tile, udim_atlas

from .texture_files import TextureFile


def authoring_layer(attr, time=None):
    """The layer holding the strongest opinion of ``attr`` (a ``Usd.Attribute``), or None."""
    try:
        stack = attr.GetPropertyStack() if time is None else attr.GetPropertyStack(time)
    except Exception:  # noqa: BLE001  (pxr raises for instance proxies of odd kinds)
        return None
    return stack[0].layer if stack else None


def resolve_backslashes(asset: Sdf.AssetPath, layer) -> str | None:
    """The file an asset path with backslashes means, anchored to ``layer``; None when that does not exist."""
    if asset is None or "\\" not in asset.path:
        return None
    path = asset.path.replace("\\", "/")
    candidates = [path] if os.path.isabs(path) else []
    if layer is not None:
        candidates.append(layer.ComputeAbsolutePath(path))
    for c in candidates:
        if c and os.path.isfile(c):
            return c
    return None


def udim_tiles(asset: Sdf.AssetPath, layer) -> list[tuple[str, int]]:
    """(resolved path, tile number) of the tiles of a ``<UDIM>`` path that exist."""
    path = asset.path.replace("\\", "/")
    if layer is None:
        return []
    try:
        found = UsdShade.UdimUtils.ResolveUdimTilePaths(path, layer)
    except Exception:  # noqa: BLE001
        found = []
    return [(str(p), int(t)) for p, t in found if is_udim_tile(t)]


def open_texture(lk, colorspace: str, files, warn, label: str, name: str):
    """(TextureFile, (3, 3) uv matrix applied after the lookup's own) for a texture lookup, or None (one warning;
    the caller uses the fallback). Handles plain resolved paths, backslashes and UDIM sets."""
    asset = lk.asset
    if "<UDIM>" in asset.path:
        cache = files.__dict__.setdefault("_udim", {})
        key = (asset.path, id(lk.layer), colorspace, tuple(lk.fallback))
        if key not in cache:
            tiles = udim_tiles(asset, lk.layer)
            if not tiles:
                cache[key] = None
            else:
                try:
                    atlas, m, notes = udim_atlas([(t, files.get(p, colorspace, p).pixels) for p, t in tiles],
                                                  lk.fallback)
                except ValueError as exc:
                    warn(f"{label}: {exc}; {name} uses the fallback {lk.fallback}")
                    cache[key] = False
                else:
                    for n in notes:
                        warn(f"{label}: UDIM {asset.path!r}: {n}")
                    cache[key] = (TextureFile(atlas, ("clamp", "clamp"), colorspace == "sRGB", asset.path), m)
        got = cache[key]
        if got is None:
            warn(f"{label}: no tiles of UDIM texture {asset.path!r} found; {name} uses the fallback {lk.fallback}")
            return None
        if got is False:
            return None
        lk.wrap_s = lk.wrap_t = "useMetadata"  # the atlas clamps: tiles do not repeat
        return got
    resolved = asset.resolvedPath or resolve_backslashes(asset, lk.layer)
    if not resolved:
        warn(f"{label}: texture {asset.path!r} not found; {name} uses the fallback {lk.fallback}")
        return None
    if not asset.resolvedPath:
        warn(f"{label}: texture {asset.path!r} read as {resolved!r} (Windows backslashes)")
    try:
        got = files.get(resolved, colorspace, asset.path)
        if got.mip_levels > 1 and not getattr(got, "mips_said", False):
            got.mips_said = True  # once per file
            warn(f"{label}: texture {asset.path!r} has {got.mip_levels} authored MIP levels; level 0 is read (a "
                 "viewer selects the level by screen footprint)")
        return got, np.eye(3)
    except ValueError as exc:
        warn(f"{label}: {exc}; {name} uses the fallback {lk.fallback}")
        return None

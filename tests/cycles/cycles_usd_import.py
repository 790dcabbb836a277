"""Cycles references for USD stages, through Blender's own USD *importer* (``bpy.ops.wm.usd_import``).

The stage (a .usda with its textures, built by a test) is imported into an empty Blender scene as a user would open
it, rendered by Cycles at the Whitted-equivalent settings (``bench.cycles.whitted_cycles_settings``) and cached
by a hash of the stage's files. The same stage is read by ``usd_io.load_stage`` for our side, so the comparison
covers both readings of UsdPreviewSurface / UsdLux, independently written.
"""

from __future__ import annotations

import hashlib
import os

import numpy as np

import cycles_harness as H


def _files_hash(stage_path: str) -> str:
    """Hash of every file in the stage's directory (the stage and the textures it names)."""
    d = os.path.dirname(os.path.abspath(stage_path))
    h = hashlib.sha256()
    for name in sorted(os.listdir(d)):
        p = os.path.join(d, name)
        if os.path.isfile(p) and not name.endswith((".exr", ".tmp")):
            h.update(name.encode())
            with open(p, "rb") as f:
                h.update(f.read())
    return h.hexdigest()


def import_into_blender(stage_path: str, width: int, height: int, samples: int, depth: int = 0):
    bpy = H.bpy()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    w = bpy.data.worlds.new("World")  # the importer turns a DomeLight into this world (it makes none itself)
    if w.node_tree is None:
        w.use_nodes = True
    w.node_tree.nodes["Background"].inputs["Color"].default_value = (0, 0, 0, 1)
    sc.world = w
    bpy.ops.wm.usd_import(filepath=stage_path, create_world_material=True, import_usd_preview=True,
                          set_material_blend=True)
    cams = [o for o in sc.objects if o.type == "CAMERA"]
    if not cams:
        raise ValueError(f"{stage_path}: Blender imported no camera")
    sc.camera = cams[0]
    for o in sc.objects:
        if o.type == "MESH":  # Whitted offsets shadow rays by ε only (as cycles_harness.build_bpy)
            o.cycles.shadow_terminator_geometry_offset = 0.0
            o.cycles.shadow_terminator_offset = 0.0
    sc.render.resolution_x, sc.render.resolution_y = width, height
    sc.render.resolution_percentage = 100
    H.whitted_cycles_settings(sc, depth=depth, samples=samples)
    sc.render.film_transparent = False
    return sc


def cycles_reference_usd(stage_path: str, name: str, width: int, height: int, samples: int, depth: int = 0) -> dict:
    """{"rgb": (H, W, 3) linear, "path", "cached"} of Cycles rendering Blender's import of ``stage_path``."""
    key = H.content_hash("usd-import", name, _files_hash(stage_path), width, height, samples, depth)
    path, seconds, cached = H.cached_exr(
        f"usdimport-{name}-{key}",
        lambda tmp: H.render_multilayer(import_into_blender(stage_path, width, height, samples, depth), tmp),
        (name, "usd-import"))
    chans = H._read_exr_channels(path)
    rgb = np.stack([H._channel(chans, f"Combined.{c}") for c in "RGB"], axis=-1)
    return {"rgb": rgb, "path": path, "cached": cached, "seconds": seconds}

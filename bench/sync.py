"""``python -m bench.sync``: what one edit costs the add-on's scene sync (addon/sync.py) on the UI thread, on a
1 M-triangle Blender scene of 100 objects with a material each (issue #22: "a material edit on a 1 M-triangle
scene with 100 materials").

Each number is :meth:`addon.sync.SceneSync.update` as the engine's ``view_update`` runs it (Blender's
``depsgraph_update_post`` handler sees the same ``depsgraph.updates``), median of ``--repeat`` edits, plus the
session edits it made (applying them is the worker's, measured by bench/viewport.py):

- ``material_s``: one material's Base Color changed;
- ``move_s``: one object moved;
- ``world_s``: the world colour changed.

    python -m bench.sync [--objects 100] [--triangles 1000000] [--repeat 5]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time


def build(objects: int, triangles: int):
    """``objects`` UV spheres of ≈ triangles/objects triangles, each with its own Principled material, a camera
    and a light (the scene is built with bpy.ops-free data API calls)."""
    import bpy
    import numpy as np
    import trimesh

    from blender_kit import scene as bs

    bs.reset(size=(320, 180))
    count = max(4, int(round(np.sqrt(max(20, triangles // objects) / 4.0))))
    ico = trimesh.creation.uv_sphere(radius=1.0, count=[count, count])  # ≈ 4·count² triangles
    side = int(np.ceil(np.sqrt(objects)))
    for i in range(objects):
        mesh = bpy.data.meshes.new(f"Ball{i}")
        mesh.from_pydata(ico.vertices.tolist(), [], ico.faces.tolist())
        mat = bs.principled_material(f"Mat{i}", **{"Base Color": (0.2 + 0.6 * (i % 7) / 6, 0.4, 0.5)})
        mesh.materials.append(mat)
        obj = bpy.data.objects.new(f"Ball{i}", mesh)
        obj.location = (2.5 * (i % side), 2.5 * (i // side), 0)
        bpy.context.scene.collection.objects.link(obj)
    bs.add_camera((side * 1.25, -side * 2.5, side * 2.0), (side * 1.25, side * 1.25, 0))
    bs.add_point_light((side * 1.25, side * 1.25, side * 3.0), power=10000)
    world = bpy.data.worlds.new("World")
    if not world.node_tree:  # Blender 5 makes worlds with nodes
        world.use_nodes = True
    bpy.context.scene.world = world
    return len(ico.faces) * objects


def measure(objects=100, triangles=1_000_000, repeat=5):
    import bpy

    from addon import sync

    tris = build(objects, triangles)
    s = sync.SceneSync(quality="low", track_camera=False)
    seen = {}

    def handler(scene, depsgraph):  # what WhittedRenderEngine.view_update runs on the UI thread
        t0 = time.perf_counter()
        edits = s.update(depsgraph)
        seen["s"] = time.perf_counter() - t0
        seen["edits"] = sorted({e.kind for e in edits})

    dg = bpy.context.evaluated_depsgraph_get()
    t0 = time.perf_counter()
    s.update(dg)
    out = {"objects": objects, "triangles": tris, "first_export_s": time.perf_counter() - t0}
    bpy.app.handlers.depsgraph_update_post.append(handler)
    try:
        def edit(name, change):
            times = []
            for k in range(repeat):
                change(k)
                bpy.context.view_layer.update()
                times.append(seen["s"])
            out[f"{name}_s"] = statistics.median(times)
            out[f"{name}_edits"] = seen["edits"]

        bsdf = bpy.data.materials["Mat7"].node_tree.nodes["Principled BSDF"]
        edit("material", lambda k: setattr(bsdf.inputs["Base Color"], "default_value", (0.1 * k, 0.3, 0.1, 1.0)))
        obj = bpy.data.objects["Ball3"]
        edit("move", lambda k: setattr(obj, "location", (obj.location.x + 0.1, obj.location.y, 0.0)))
        bg = bpy.context.scene.world.node_tree.nodes["Background"]
        edit("world", lambda k: setattr(bg.inputs["Color"], "default_value", (0.05 * k, 0.05, 0.05, 1.0)))
    finally:
        bpy.app.handlers.depsgraph_update_post.remove(handler)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m bench.sync", description=__doc__.split("\n\n")[0])
    ap.add_argument("--objects", type=int, default=100)
    ap.add_argument("--triangles", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args(argv)
    print(json.dumps(measure(args.objects, args.triangles, args.repeat), indent=1))


if __name__ == "__main__":
    main()

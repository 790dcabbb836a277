"""``python -m bench.viewport``: the add-on's viewport and Persistent Data on the 1 M-triangle bench scene, driven
as the engine drives them, inside Blender (the bpy module; no UI or GPU needed):

- the scene is built in Blender (:func:`bench.cycles.build_blender_scene`, the same meshes and materials Cycles
  renders in ``make bench``);
- ``view_update``: Blender's ``depsgraph_update_post`` handler sees ``depsgraph.updates`` exactly as view_update
  does, and runs what the engine's view_update runs (:class:`addon.sync.SceneSync` on this thread ->
  :meth:`addon.viewport.ViewportRender.edit`); ``view_draw``: :meth:`ViewportRender.set_view` + ``latest()`` (the
  GPU upload itself cannot run headless; its pixels are prepared on the worker);
- each number is from the change (``set_view`` for an orbit step, the property edit for the others) to the first
  (coarse) pass that shows it, as a user would see it;
- Persistent Data: F12 (``bpy.ops.render.render``) with ``use_persistent_data`` on, again after a camera move and
  on the next frame of an animation, against the first F12.

    python -m bench.viewport [--size 960x540] [--f12-size 1920x1080] [--threads 2]
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time

import numpy as np


def _orbit(cam, angle_deg, about=(0.0, 3.5, 1.0)):
    import tracer

    a = math.radians(angle_deg)
    c, s = math.cos(a), math.sin(a)
    rot = np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    t = np.eye(4)
    t[:3, 3] = about
    m = t @ rot @ np.linalg.inv(t) @ cam.camera_to_world
    return tracer.Camera(camera_to_world=m, focal_length=cam.focal_length,
                         horizontal_aperture=cam.horizontal_aperture, vertical_aperture=cam.vertical_aperture)


def measure_viewport(size=(960, 540), threads=2, orbit_steps=12, instanced=True):
    import bpy

    import tracer
    from addon import engine, export, sync, viewport

    from . import scenes
    from .cycles import build_blender_scene

    tracer.compile_kernels()
    bs = scenes.build("heavy")
    sc = build_blender_scene(bs, size[0], size[1], samples=1, threads=threads, max_depth=4)
    dg = bpy.context.evaluated_depsgraph_get()
    cam = export.scene_camera(sc, *size)
    settings = tracer.RenderSettings(light_samples=4, max_depth=4, threads=threads)
    vr = viewport.ViewportRender(settings=settings, instanced=instanced)
    s = sync.SceneSync(quality=viewport.QUALITY, track_camera=False)
    ui = {}

    def view_update(scene, depsgraph):  # what WhittedRenderEngine.view_update runs
        t0 = time.perf_counter()
        vr.edit(s.update(depsgraph, width=size[0], height=size[1], camera=cam))
        ui["view_update"] = time.perf_counter() - t0
        ui["edits"] = dict(s.stats["edits"])

    out = {"triangles": None, "size": list(size), "threads": threads}
    try:
        t0 = time.perf_counter()
        view_update(sc, dg)
        vr.set_view(cam, size)
        vr.wait_for(lambda f: True, 600)
        out["first_export_s"] = ui["view_update"]
        out["first_coarse_pass_s"] = vr.latest().done - t0
        vr.wait_until_converged(600)
        out["triangles"] = len(vr.session.scene.triangles)

        # orbit: one set_view per step (what view_draw does), the time to the step's coarse pass
        steps, draw = [], []
        for k in range(orbit_steps):
            view = _orbit(cam, 2.0 * (k + 1))
            t0 = time.perf_counter()
            vr.set_view(view, size)
            vr.latest()
            draw.append(time.perf_counter() - t0)
            vr.wait_for(lambda f: True, 600)
            steps.append(vr.first_pass_seconds())
        out["orbit_coarse_pass_s"] = statistics.median(steps)
        out["orbit_fps"] = 1.0 / statistics.median(steps)
        out["view_draw_ms"] = 1e3 * max(draw)
        vr.set_view(cam, size)
        vr.wait_until_converged(600)
        full = [f for f in [vr.latest()]]
        out["converged_s"] = full[0].done - full[0].changed

        bpy.app.handlers.depsgraph_update_post.append(view_update)

        def edit(change):
            t0 = time.perf_counter()
            change()
            bpy.context.view_layer.update()  # Blender's depsgraph evaluation -> view_update
            vr.wait_for(lambda f: True, 600)
            # from the property edit: view_update's time on the UI thread + the worker's edit and first pass
            return ui["view_update"] + vr.first_pass_seconds(), ui["view_update"], ui["edits"]

        torus = bpy.data.materials["Torus"].node_tree.nodes["Principled BSDF"]
        out["material_s"], out["material_ui_s"], out["material_edits"] = edit(
            lambda: setattr(torus.inputs["Base Color"], "default_value", (0.8, 0.3, 0.1, 1.0)))
        obj = bpy.data.objects["Torus_3"]
        out["move_s"], out["move_ui_s"], out["move_edits"] = edit(
            lambda: setattr(obj, "location", (obj.location.x + 0.3, obj.location.y, obj.location.z)))
        floor = bpy.data.objects["Floor_0"]

        def floor_geometry():
            floor.data.vertices[0].co.z += 0.2
            floor.data.update()
        out["mesh_small_s"], out["mesh_small_ui_s"], out["mesh_small_edits"] = edit(floor_geometry)
        out["errors"] = list(vr.errors)
    finally:
        if view_update in bpy.app.handlers.depsgraph_update_post:
            bpy.app.handlers.depsgraph_update_post.remove(view_update)
        vr.stop()
    return out


def measure_persistent(size=(1920, 1080), threads=2, samples=1):
    """F12 with Persistent Data: the first render, then after a camera move, then the next animation frame (the
    torus moves); each against the first. Also the same F12s without Persistent Data."""
    import bpy

    import addon
    import tracer
    from addon import engine

    from . import scenes
    from .cycles import build_blender_scene

    tracer.compile_kernels()
    addon.register()
    try:
        bs = scenes.build("heavy")
        sc = build_blender_scene(bs, size[0], size[1], samples=1, threads=threads, max_depth=8)
        sc.render.engine = "WHITTED"
        sc.whitted.samples = samples
        sc.whitted.threads = threads
        sc.whitted.denoise = False  # F12's Denoise (on by default) is not what this measures
        torus = bpy.data.objects["Torus_3"]
        torus.keyframe_insert("location", frame=1)
        torus.location.x += 0.5
        torus.keyframe_insert("location", frame=2)
        cam = bpy.data.objects["Camera"]
        out = {"size": list(size), "samples": samples, "threads": threads}
        for persistent in (True, False):
            sc.render.use_persistent_data = persistent
            sc.frame_set(1)
            runs = {}
            for label, change in (("first", None), ("camera_move", lambda: setattr(cam, "location", (
                    cam.location.x + 0.2, cam.location.y, cam.location.z))), ("next_frame", lambda: sc.frame_set(2))):
                if change is not None:
                    change()
                t0 = time.perf_counter()
                bpy.ops.render.render()
                st = engine.WhittedRenderEngine.last_render.stats
                runs[label] = {"seconds": time.perf_counter() - t0, "trace_s": st["seconds"],
                               "prepare_s": st["export_seconds"], "edits": st.get("sync", {}).get("edits")}
            cam.location.x -= 0.2
            out["persistent" if persistent else "plain"] = runs
        sc.render.use_persistent_data = False
        return out
    finally:
        addon.unregister()


def main(argv=None):
    ap = argparse.ArgumentParser(description="viewport and Persistent Data timings on the 1 M-triangle scene")
    ap.add_argument("--size", default="960x540")
    ap.add_argument("--f12-size", default="1920x1080")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--skip-f12", action="store_true")
    ap.add_argument("--flat", action="store_true", help="the viewport session in Embree's flat layout")
    a = ap.parse_args(argv)
    size = tuple(int(x) for x in a.size.split("x"))
    vp = measure_viewport(size, a.threads, instanced=not a.flat)
    print(f"bench.viewport: {vp['triangles']:,} triangles, {size[0]}x{size[1]} viewport, {a.threads} threads, "
          f"{'flat' if a.flat else 'instanced'} Embree layout")
    print(f"  first view_update (full export, UI thread) {vp['first_export_s']:.2f} s; first coarse pass "
          f"{vp['first_coarse_pass_s']:.2f} s after it; converged (3x3 AA) {vp['converged_s']:.2f} s after a change")
    print(f"  orbit: set_view -> first (1/16) pass median {vp['orbit_coarse_pass_s'] * 1e3:.0f} ms ({vp['orbit_fps']:.0f} fps);"
          f" view_draw's calls (set_view + latest) at most {vp['view_draw_ms']:.2f} ms")
    for key, label in (("material", "material colour"), ("move", "object move"), ("mesh_small", "floor mesh edit")):
        print(f"  {label}: visible (first pass) after {vp[key + '_s']:.2f} s, of which view_update on the UI thread "
              f"{vp[key + '_ui_s'] * 1e3:.0f} ms; edits {vp[key + '_edits']}")
    result = {"viewport": vp}
    if not a.skip_f12:
        f12 = measure_persistent(tuple(int(x) for x in a.f12_size.split("x")), a.threads)
        for mode in ("persistent", "plain"):
            r = f12[mode]
            first = r["first"]["seconds"]
            print(f"  F12 {f12['size'][0]}x{f12['size'][1]} {mode}: first {first:.2f} s (prepare "
                  f"{r['first']['prepare_s']:.2f} s); camera move {r['camera_move']['seconds']:.2f} s "
                  f"({100 * r['camera_move']['seconds'] / first:.0f} %, prepare {r['camera_move']['prepare_s']:.2f} s);"
                  f" next frame {r['next_frame']['seconds']:.2f} s ({100 * r['next_frame']['seconds'] / first:.0f} %,"
                  f" prepare {r['next_frame']['prepare_s']:.2f} s)")
        result["f12"] = f12
    print("BENCH_JSON " + json.dumps(result, default=str), flush=True)


if __name__ == "__main__":
    main()

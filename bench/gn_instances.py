"""``python -m bench.gn_instances``: 20 000 Geometry-Nodes instances (an icosphere of 320 triangles on each point of
a 200 × 100 grid, each rotated and scaled: 6.4 M triangles flattened) through the add-on's F12 and through Cycles,
each in a fresh process: export time (the add-on's depsgraph walk and placement), render time and peak memory
(ru_maxrss of the process, with the process's own size after building the scene alongside).

    python -m bench.gn_instances [--width 480 --height 270]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time

import numpy as np

NX, NY = 200, 100


def build_scene(width, height):
    import bpy

    from blender_kit import scatter
    from blender_kit import scene as bs

    bs.reset(size=(width, height))
    paint = bs.principled_material("paint", **{"Base Color": (0.2, 0.5, 0.8)})
    scatter.add(scatter.graph(size=(60.0, 30.0), points=(NX, NY), radius=0.12, subdivisions=3, material=paint,
                              scale=((0.6, 0.6, 0.6), (1.4, 1.2, 1.0))), (0, 0, 0.2))
    bs.add_plane((0, 0, 0), 80.0, name="Floor")
    bs.add_camera((0, -30, 18), (0, 0, 0))
    bs.add_point_light((5, -10, 20), power=20000)
    bs.set_world((0.1, 0.1, 0.12))
    return bpy.context.scene


def measure(renderer, width, height, threads):
    import bpy

    sc = build_scene(width, height)
    bpy.context.evaluated_depsgraph_get()  # Blender's own evaluation of the node tree, outside the timings
    base_rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    out = {"renderer": renderer, "width": width, "height": height, "instances": NX * NY}
    if renderer == "whitted":
        import addon
        import tracer
        from addon import engine, export

        tracer.compile_kernels()
        t0 = time.perf_counter()
        scene, _ = export.scene_from_depsgraph(bpy.context.evaluated_depsgraph_get())
        out["export_only_s"] = time.perf_counter() - t0
        out["triangles"] = len(scene.triangles)  # stored: world-space triangles + each shared mesh once
        inst = scene.instances
        per_object = np.bincount(scene.object_ids, minlength=len(scene.object_names))
        out["instances_placed"] = 0 if inst is None else len(inst)
        out["triangles_drawn"] = int(len(scene.triangles) - (0 if inst is None else per_object[
            np.unique(inst.prototypes)].sum()) + (0 if inst is None else per_object[inst.prototypes].sum()))
        del scene
        addon.register()
        sc.render.engine = "WHITTED"
        sc.whitted.samples = 1
        sc.whitted.threads = threads
        bs.plain_whitted(sc)  # Denoise off: the render alone, against Cycles without its denoiser
        t0 = time.perf_counter()
        bpy.ops.render.render()
        out["f12_s"] = time.perf_counter() - t0
        out["export_s"] = engine.WhittedRenderEngine.last_render.stats["export_seconds"]
        out["trace_s"] = engine.WhittedRenderEngine.last_render.stats["seconds"]
    else:
        from blender_kit.cycles import whitted_cycles_settings

        whitted_cycles_settings(sc, depth=8, samples=1)
        sc.render.threads_mode = "FIXED"
        sc.render.threads = threads
        t0 = time.perf_counter()
        bpy.ops.render.render()
        out["f12_s"] = time.perf_counter() - t0
    out["base_rss"] = base_rss
    out["peak_rss"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description="20 000 Geometry-Nodes instances: the add-on vs Cycles")
    ap.add_argument("--width", type=int, default=480)
    ap.add_argument("--height", type=int, default=270)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--child", choices=("whitted", "cycles"))
    a = ap.parse_args(argv)
    if a.child:
        print("BENCH_JSON " + json.dumps(measure(a.child, a.width, a.height, a.threads)), flush=True)
        return
    results = {}
    for renderer in ("whitted", "cycles"):
        proc = subprocess.run([sys.executable, "-m", "bench.gn_instances", "--child", renderer, "--width",
                               str(a.width), "--height", str(a.height), "--threads", str(a.threads)],
                              capture_output=True, text=True, cwd=os.getcwd())
        line = [l for l in proc.stdout.splitlines() if l.startswith("BENCH_JSON ")]
        if not line:
            print(f"bench.gn_instances: {renderer} failed:\n{proc.stderr[-2000:]}", file=sys.stderr)
            return
        results[renderer] = json.loads(line[-1][len("BENCH_JSON "):])
    w, c = results["whitted"], results["cycles"]
    gb = 1 / 2**30
    print(f"bench.gn_instances: {w['instances']:,} GN instances ({w.get('instances_placed', 0):,} tracer instances), "
          f"{w.get('triangles_drawn', w['triangles']):,} triangles drawn, {w['triangles']:,} stored, "
          f"{a.width}x{a.height}, 1 sample, {a.threads} threads")
    print(f"  add-on export {w['export_only_s']:.2f} s (in F12: {w['export_s']:.2f} s), F12 {w['f12_s']:.2f} s, "
          f"peak RSS {w['peak_rss'] * gb:.2f} GB (process before rendering {w['base_rss'] * gb:.2f} GB)")
    print(f"  Cycles F12 {c['f12_s']:.2f} s, peak RSS {c['peak_rss'] * gb:.2f} GB "
          f"(before rendering {c['base_rss'] * gb:.2f} GB); memory ratio {w['peak_rss'] / c['peak_rss']:.2f}")
    print("BENCH_JSON " + json.dumps(results))


if __name__ == "__main__":
    main()

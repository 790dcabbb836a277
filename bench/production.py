"""``python -m bench.production``: a production-shaped stage against raw Embree (issue #29, "Production assets render
at the speed of the bench scenes").

The stage is generated here (no downloads) and written once to ``.cache/bench/production.usdc``: a set dressed with
``--meshes`` props (default 1 600: boxes, spheres, cylinders and tori of 240–3 900 triangles each, ≈ 1.5 M triangles
in all) standing on a floor in rows, every prop its own ``UsdGeom.Mesh`` with its own transform and a
``primvars:displayColor`` (constant on most, per vertex on every fifth) and no material or texture, lit by a sun
and two sphere lights, seen by one camera. Polygonal meshes (``subdivisionScheme = "none"``), so the triangle count
is the stage's. The lights are delta lights (sun angle 0, lamp radius 0): three shadow rays per eye hit, so the
cost of shading a hit is not hidden behind soft shadows' rays (issue #29's kitchen traced 2.4 M rays in all).

One child process reads it (``usd_io.load_stage``), renders it once at 960×540 (kernels, allocator), then times the
second ``tracer.render`` (AA 2×2, sky samples 0, 2 threads) ``--runs`` times and splits it as bench.ours does:
Embree build (``bvh_seconds``), Embree queries (``intersect_seconds``, thread-seconds), shading (thread-seconds in
``Integrator.trace`` minus the queries) and per-tile work (threads × wall − time in ``trace``: eye rays, film, tile
dispatch, idle threads). Then raw Embree on the same rays (bench.ours.replay: a fresh bare Embree scene of the same
triangles + the recorded ray batches, one ray per call and in our packets), and the ratios of issue 23:
end to end, our rays/s over raw rays/s, both sides building their Embree scene.

    python -m bench.production [--meshes 1600] [--runs 3] [--width 960 --height 540] [--root CHECKOUT]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
STAGE = os.path.join(os.path.dirname(HERE), ".cache", "bench", "production.usdc")


# ------------------------------------------------------------------------------------------------------ the stage
def _box(n):
    """A box of n×n quads per side (12 n² triangles), side 1, centred on the origin."""
    g = np.linspace(-0.5, 0.5, n + 1)
    u, v = np.meshgrid(g, g, indexing="ij")
    pts, faces = [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            p = np.zeros((n + 1, n + 1, 3))
            p[..., axis] = 0.5 * sign
            p[..., (axis + 1) % 3] = u if sign > 0 else v
            p[..., (axis + 2) % 3] = v if sign > 0 else u
            base = sum(len(q) for q in pts)
            pts.append(p.reshape(-1, 3))
            i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
            faces.append(base + np.stack([i, i + n + 1, i + n + 2, i + 1], -1).reshape(-1, 4))
    return np.concatenate(pts), np.concatenate(faces)


def _lathe(profile, segments):
    """Revolve a (r, z) profile of k points around z: (k × segments) quads' points, (k−1) × segments quads."""
    r, z = profile[:, 0], profile[:, 1]
    a = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    pts = np.stack([r[:, None] * np.cos(a)[None], r[:, None] * np.sin(a)[None],
                    np.broadcast_to(z[:, None], (len(r), segments))], -1).reshape(-1, 3)
    k = len(r)
    i = np.arange(k - 1)[:, None] * segments + np.arange(segments)[None, :]
    j = np.arange(k - 1)[:, None] * segments + (np.arange(segments)[None, :] + 1) % segments
    faces = np.stack([i, j, j + segments, i + segments], -1).reshape(-1, 4)
    return pts, faces


def _sphere(rings, segments):
    t = np.linspace(0.02, np.pi - 0.02, rings)
    return _lathe(np.stack([0.5 * np.sin(t), -0.5 * np.cos(t)], -1), segments)


def _cylinder(rings, segments):
    z = np.linspace(-0.5, 0.5, rings)
    prof = np.concatenate([[[0.02, -0.5]], np.stack([np.full(rings, 0.5), z], -1), [[0.02, 0.5]]])
    return _lathe(prof, segments)


def _torus(rings, segments):
    t = np.linspace(0, 2 * np.pi, rings)
    return _lathe(np.stack([0.35 + 0.15 * np.cos(t), 0.15 * np.sin(t)], -1), segments)


def write_stage(path: str, meshes: int = 1600, seed: int = 7) -> str:
    """Write the production-shaped stage to ``path``; returns a one-line summary."""
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, Vt

    rng = np.random.default_rng(seed)
    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(stage, "Z")
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/Set")
    stage.SetDefaultPrim(root.GetPrim())
    kinds = [("box", lambda s: _box(s)), ("sphere", lambda s: _sphere(s + 2, 2 * s + 4)),
             ("cylinder", lambda s: _cylinder(s, 2 * s + 4)), ("torus", lambda s: _torus(s + 3, 2 * s + 6))]
    side = int(np.ceil(np.sqrt(meshes)))
    spacing = 1.2
    triangles = 0
    for k in range(meshes):
        name, make = kinds[k % len(kinds)]
        pts, quads = make(int(rng.integers(5, 18)))
        m = UsdGeom.Mesh.Define(stage, f"/Set/Props/{name}_{k:04d}")
        m.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        m.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts.astype(np.float32)))
        m.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(quads), 4, np.int32)))
        m.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(quads.reshape(-1).astype(np.int32)))
        triangles += 2 * len(quads)
        col = rng.uniform(0.1, 0.9, 3)
        pv = UsdGeom.PrimvarsAPI(m).CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray,
                                                 UsdGeom.Tokens.vertex if k % 5 == 0 else UsdGeom.Tokens.constant)
        if k % 5 == 0:
            shade = np.clip(col[None] * (0.6 + 0.8 * (pts[:, 2:3] + 0.5)), 0, 1)
            pv.Set(Vt.Vec3fArray.FromNumpy(shade.astype(np.float32)))
        else:
            pv.Set(Vt.Vec3fArray([Gf.Vec3f(*col)]))
        x, y = (k % side - side / 2) * spacing, (k // side) * spacing
        s = rng.uniform(0.4, 1.0)
        m.AddTranslateOp().Set(Gf.Vec3d(x, y, 0.5 * s))
        m.AddRotateZOp().Set(float(rng.uniform(0, 360)))
        m.AddScaleOp().Set(Gf.Vec3f(s, s, s))
    floor = UsdGeom.Mesh.Define(stage, "/Set/Floor")
    e = side * spacing
    floor.CreatePointsAttr([(-e, -2, 0), (e, -2, 0), (e, e + 2, 0), (-e, e + 2, 0)])
    floor.CreateFaceVertexCountsAttr([4])
    floor.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    floor.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    floor.CreateDisplayColorAttr([(0.45, 0.42, 0.4)])
    triangles += 2
    sun = UsdLux.DistantLight.Define(stage, "/Lights/Sun")
    sun.CreateIntensityAttr(6.0)
    sun.CreateAngleAttr(0.0)  # delta lights: one shadow ray per light and hit, so shading per hit shows
    sun.AddRotateXYZOp().Set(Gf.Vec3f(40, 0, 30))
    for i, (x, y) in enumerate(((-0.25 * e, 0.3 * e), (0.3 * e, 0.6 * e))):
        lamp = UsdLux.SphereLight.Define(stage, f"/Lights/Lamp{i}")
        lamp.CreateIntensityAttr(1500.0)
        lamp.CreateRadiusAttr(0.0)
        lamp.AddTranslateOp().Set(Gf.Vec3d(x, y, 4.0))
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    cam.CreateFocalLengthAttr(24.0)
    cam.CreateHorizontalApertureAttr(36.0)
    cam.CreateVerticalApertureAttr(20.25)
    eye, target = Gf.Vec3d(0, -0.3 * e, 0.45 * e), Gf.Vec3d(0, 0.4 * e, 0)
    look = Gf.Matrix4d().SetLookAt(eye, target, Gf.Vec3d(0, 0, 1)).GetInverse()
    cam.AddTransformOp().Set(look)
    stage.GetRootLayer().Save()
    return f"{meshes} meshes, {triangles:,} triangles"


def ensure_stage(path: str = STAGE, meshes: int = 1600) -> str:
    if not os.path.exists(path):
        os.makedirs(os.path.dirname(path), exist_ok=True)
        tmp = path + ".tmp.usdc"
        print("writing", path, write_stage(tmp, meshes), file=sys.stderr)
        os.replace(tmp, path)
    return path


# ------------------------------------------------------------------------------------------------------ measuring
def child(path: str, width: int, height: int, runs: int, threads: int = 2, record: bool = True) -> dict:
    import tracer
    from usd_io import load_stage

    from .ours import TraceTimer, replay

    t0 = time.perf_counter()
    scene, info = load_stage(path, width=width, height=height)
    load = time.perf_counter() - t0
    settings = tracer.RenderSettings(width=info.width, height=info.height, samples=2, sky_samples=0,
                                     threads=threads, progress=False)
    tracer.render(scene, settings)  # the first render: kernels loaded, allocator warmed
    rows = []
    for _ in range(runs):
        with TraceTimer() as tt:
            w0, c0 = time.perf_counter(), time.process_time()
            img = tracer.render(scene, settings)
            wall, cpu = time.perf_counter() - w0, time.process_time() - c0
        isect = img.stats["intersect_seconds"]
        rows.append({"wall": wall, "cpu": cpu, "bvh": img.stats["bvh_seconds"], "intersect": isect,
                     "shading": tt.seconds - isect, "tiles": threads * wall - tt.seconds - img.stats["bvh_seconds"],
                     "rays": img.stats["rays"]["total"]})
    out = {"triangles": int(len(scene.triangles)), "meshes": len(info.meshes), "objects": len(scene.object_names),
           "materials": len(scene.materials), "load": load, "rays": rows[0]["rays"], "width": info.width,
           "height": info.height, "runs": rows,
           "median": {k: statistics.median(r[k] for r in rows) for k in rows[0] if k != "rays"},
           "ray_kinds": {k: v for k, v in img.stats["rays"].items() if k != "total"}}
    if record:
        rec = tracer.render(scene, settings.with_(extra={"record_rays": True}))
        out["replay"] = replay(tracer.scene.flatten(scene), rec.stats["ray_batches"], threads, runs)
    return out


def profile(path: str, width: int, height: int, runs: int = 2) -> dict:
    """One thread's CPU seconds per stage (bench.stages' wrappers, ``time.thread_time``: other jobs on the machine do
    not count) of the second and later renders, best of ``runs``, and raw Embree's single-ray and packet replays of
    the same rays on one thread (CPU seconds too), the Embree build excluded on both sides (it runs on Embree's own
    threads; the timed table above has it)."""
    import tracer
    from usd_io import load_stage

    from .ours import replay
    from .stages import stage_seconds

    scene, info = load_stage(path, width=width, height=height)
    settings = tracer.RenderSettings(width=info.width, height=info.height, samples=2, sky_samples=0, threads=1,
                                     progress=False)
    tracer.render(scene, settings)
    best, img = stage_seconds(scene, settings, runs, whole="whole render (this thread)")
    rec = tracer.render(scene, settings.with_(extra={"record_rays": True}))
    rp = replay(tracer.scene.flatten(scene), rec.stats["ray_batches"], 1, runs)
    return {"cpu_seconds": best, "rays": img.stats["rays"], "bvh_seconds": img.stats["bvh_seconds"],
            "raw_single_cpu": rp["single_replay_cpu_seconds"], "raw_packet_cpu": rp["replay_cpu_seconds"],
            "raw_build": rp["build_seconds"]}


def run_child(root: str, args, what: str = "child") -> dict:
    code = (f"import json, sys; sys.path.insert(0, {root!r}); from bench.production import {what}; "
            f"print('BENCH_JSON ' + json.dumps({what}({args.stage!r}, {args.width}, {args.height}, {args.runs})))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=root,
                       env=dict(os.environ, PYTHONPATH=root))
    line = next((ln for ln in r.stdout.splitlines() if ln.startswith("BENCH_JSON ")), None)
    if r.returncode or line is None:
        raise SystemExit(r.stderr[-3000:])
    return json.loads(line[len("BENCH_JSON "):])


def report(res: dict, threads: int = 2) -> str:
    m, rp = res["median"], res.get("replay")
    rays = res["rays"]
    lines = [f"production stage: {res['meshes']} meshes, {res['triangles']:,} triangles, {res['materials']} "
             f"materials, {res['width']}x{res['height']}, AA 2x2, sky samples 0, {threads} threads; load_stage "
             f"{res['load']:.2f} s; {rays:,} rays ({', '.join(f'{k} {v:,}' for k, v in res['ray_kinds'].items() if v)})",
             "", "| second tracer.render (median of runs) | seconds |", "| --- | --- |",
             f"| wall | {m['wall']:.3f} |", f"| CPU (every thread) | {m['cpu']:.3f} |",
             f"| Embree build (bvh_seconds, wall) | {m['bvh']:.3f} |",
             f"| Embree queries (thread-seconds) | {m['intersect']:.3f} |",
             f"| shading (thread-seconds in Integrator.trace minus queries) | {m['shading']:.3f} |",
             f"| per-tile work and idle (threads × wall − trace − build) | {m['tiles']:.3f} |"]
    if rp:
        ours = rays / m["wall"]
        lines += ["", "| raw Embree, same triangles and rays | seconds | end to end: ours / raw |", "| --- | --- | --- |",
                  f"| build | {rp['build_seconds']:.3f} | |",
                  f"| single-ray replay (rtcIntersect1/rtcOccluded1) | {rp['single_seconds']:.3f} | "
                  f"**{ours / rp['single_end_to_end_rays_per_second']:.0%}** (CPU "
                  f"{rp['single_cpu_seconds'] / m['cpu']:.0%}) |",
                  f"| replay of our packets | {rp['seconds']:.3f} | {ours / rp['end_to_end_rays_per_second']:.0%} "
                  f"(CPU {rp['cpu_seconds'] / m['cpu']:.0%}) |"]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", type=int, default=1600)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--width", type=int, default=960)
    ap.add_argument("--height", type=int, default=540)
    ap.add_argument("--stage", default=STAGE)
    ap.add_argument("--root", default=os.path.dirname(HERE), help="checkout to measure (default: this one)")
    ap.add_argument("--json", help="also write the raw results here")
    ap.add_argument("--profile", action="store_true", help="one thread's CPU seconds per stage instead")
    args = ap.parse_args(argv)
    ensure_stage(args.stage, args.meshes)
    if args.profile:
        res = run_child(os.path.abspath(args.root), args, "profile")
        cpu = res["cpu_seconds"]
        print("| stage (one thread, CPU s, best of runs) | seconds |\n| --- | --- |")
        for k, v in cpu.items():
            print(f"| {k} | {v:.3f} |")
        whole = cpu["whole render (this thread)"]
        print(f"| raw Embree single-ray replay (same rays, one thread, CPU) | {res['raw_single_cpu']:.3f} |")
        print(f"| raw Embree replay of our packets (one thread, CPU) | {res['raw_packet_cpu']:.3f} |")
        tiles = cpu["tiles: trace_tile"]
        print(f"tiles only (ours: trace_tile; raw: the replay; no build on either side): ours / raw single-ray "
              f"{res['raw_single_cpu'] / tiles:.0%}, ours / raw packets {res['raw_packet_cpu'] / tiles:.0%}; the "
              f"whole render on this thread adds {whole - tiles:.3f} s of set-up (its share of the Embree build, "
              f"the integrator's tables); rays {res['rays']}")
    else:
        res = run_child(os.path.abspath(args.root), args)
        print(report(res))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(res, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())

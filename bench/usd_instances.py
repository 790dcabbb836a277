"""``python -m bench.usd_instances``: a USD stage with 50 000 PointInstancer instances of a 1 280-triangle prototype
(an icosphere, each instance rotated and scaled; 64 M triangles if flattened) rendered at 1920×1080 through
``usd_io.load_stage`` + ``tracer.render``, in a fresh process: load time, render time, peak RSS (ru_maxrss).

    python -m bench.usd_instances [--instances 50000 --width 1920 --height 1080]

Target (issue #12): ≤ 1.5 GB peak RSS. ``--instances`` smaller runs the same stage with fewer points (what the
flattened reader of before could still hold in memory).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np


def write_stage(path: str, count: int) -> None:
    import trimesh
    from pxr import Gf, Usd, UsdGeom, UsdLux, Vt

    s = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(s, UsdGeom.Tokens.z)
    ball = trimesh.creation.icosphere(3, 0.4)  # 1 280 triangles
    assert len(ball.faces) == 1280
    pi = UsdGeom.PointInstancer.Define(s, "/Field")
    mesh = UsdGeom.Mesh.Define(s, "/Field/Protos/Ball")
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(ball.vertices.astype(np.float32)))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(ball.faces), 3, np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(ball.faces.ravel().astype(np.int32)))
    mesh.CreateSubdivisionSchemeAttr("none")
    side = int(np.ceil(np.sqrt(count)))
    rng = np.random.default_rng(7)
    xy = np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2)[:count].astype(np.float32)
    pos = np.c_[xy * 1.0 - side / 2, np.full(count, 0.5, np.float32)]
    q = rng.normal(size=(count, 4)).astype(np.float32)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    pi.CreatePrototypesRel().SetTargets([mesh.GetPath()])
    pi.CreateProtoIndicesAttr(Vt.IntArray.FromNumpy(np.zeros(count, np.int32)))
    pi.CreatePositionsAttr(Vt.Vec3fArray.FromNumpy(pos.astype(np.float32)))
    pi.CreateScalesAttr(Vt.Vec3fArray.FromNumpy(rng.uniform(0.6, 1.3, (count, 3)).astype(np.float32)))
    pi.CreateOrientationsAttr(Vt.QuathArray.FromNumpy(q.astype(np.float16)))
    cam = UsdGeom.Camera.Define(s, "/Cam")
    cam.AddTranslateOp().Set(Gf.Vec3d(0, -side * 0.62, side * 0.35))
    cam.AddRotateXOp().Set(62.0)
    cam.CreateFocalLengthAttr(20.0)
    sun = UsdLux.DistantLight.Define(s, "/Sun")
    sun.AddRotateXYZOp().Set(Gf.Vec3f(40, 10, 30))
    sun.CreateIntensityAttr(30000.0)  # usd_io: ≈ 2 W/m² of irradiance
    s.GetRootLayer().Save()


def measure(path, width, height, threads):
    import tracer
    from usd_io import load_stage

    tracer.compile_kernels()
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    t0 = time.perf_counter()
    scene, _info = load_stage(path, width=width, height=height)
    load = time.perf_counter() - t0
    t0 = time.perf_counter()
    img = tracer.render(scene, tracer.RenderSettings(width=width, height=height, samples=1, threads=threads))
    f = time.perf_counter() - t0
    return {"load_s": load, "render_s": f, "triangles_stored": len(scene.triangles),
            "instances": 0 if scene.instances is None else len(scene.instances),
            "base_rss": base, "peak_rss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024,
            "mean": float(img.rgba[..., :3].mean())}


def main(argv=None):
    ap = argparse.ArgumentParser(description="50 000 USD PointInstancer instances at 1920x1080")
    ap.add_argument("--instances", type=int, default=50_000)
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--child")
    a = ap.parse_args(argv)
    if a.child:
        print("BENCH_JSON " + json.dumps(measure(a.child, a.width, a.height, a.threads)), flush=True)
        return
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "field.usdc")
        write_stage(path, a.instances)
        proc = subprocess.run([sys.executable, "-m", "bench.usd_instances", "--child", path, "--width", str(a.width),
                               "--height", str(a.height), "--threads", str(a.threads)], capture_output=True, text=True)
    line = [l for l in proc.stdout.splitlines() if l.startswith("BENCH_JSON ")]
    if not line:
        print(f"bench.usd_instances failed:\n{proc.stderr[-2000:]}", file=sys.stderr)
        sys.exit(1)
    r = json.loads(line[-1][len("BENCH_JSON "):])
    gb = 1 / 2**30
    print(f"bench.usd_instances: {a.instances:,} instances x 1,280 triangles ({a.instances * 1280:,} drawn, "
          f"{r['triangles_stored']:,} stored, {r['instances']:,} tracer instances), {a.width}x{a.height}, "
          f"{a.threads} threads")
    print(f"  load {r['load_s']:.2f} s, render {r['render_s']:.2f} s, peak RSS {r['peak_rss'] * gb:.2f} GB "
          f"(after kernel load {r['base_rss'] * gb:.2f} GB), mean pixel {r['mean']:.3f}")
    print("BENCH_JSON " + json.dumps(r))


if __name__ == "__main__":
    main()

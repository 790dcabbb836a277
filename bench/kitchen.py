"""``python -m bench.kitchen``: time to first pixel on a production-like stage (issue #23).

The stage is bench/kitchen_stage.py's synthetic kitchen set (1 788 catmullClark meshes, ~545 k cage triangles, 16
topologies shared by many meshes, native instances), written once to ``.cache/bench/kitchen.usdc``. Each run is a
fresh child process that imports the tracer and usd_io, then times, phase by phase (wall and CPU seconds of the
whole process, every thread):

    usd read     load_stage minus the phases below (pxr reads, primvars, materials, the reader's own numpy)
    subdivision  time inside tracer.geometry.subdivision's entry points (refine, refine_batch)
    validation   time inside Scene.validate
    builder      SceneBuilder.add_mesh / add_meshes / build, minus the validation they run
    bvh          the Embree scene: tracer.accel.accelerator.Accelerator(scene)
    render       tracer.render at --width × --height with that Accelerator (--no-render skips it)

and the peak RSS (ru_maxrss) after loading and after the BVH build, as bytes per refined triangle (the whole
process: interpreter, imports and USD read included). Phases nest (validation runs inside the builder's build):
each is counted once, exclusively. Medians over ``--runs`` runs, complexities interleaved.

    python -m bench.kitchen [--complexity medium,high] [--runs 3] [--width 960 --height 540] [--no-render]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
STAGE = os.path.join(os.path.dirname(HERE), ".cache", "bench", "kitchen.usdc")


def ensure_stage(path: str = STAGE) -> str:
    if not os.path.exists(path):
        from .kitchen_stage import write_kitchen

        os.makedirs(os.path.dirname(path), exist_ok=True)
        tmp = path + ".tmp.usdc"
        print("writing", path, write_kitchen(tmp), file=sys.stderr)
        os.replace(tmp, path)
    return path


class _Phases:
    """Exclusive wall and CPU seconds per phase of wrapped functions (nested phases subtracted from their parent)."""

    def __init__(self):
        self.wall, self.cpu, self.stack = {}, {}, []

    def wrap(self, owner, name, phase):
        fn = getattr(owner, name, None)
        if fn is None:
            return
        phases = self

        def wrapped(*a, **k):
            w0, c0 = time.perf_counter(), time.process_time()
            phases.stack.append([0.0, 0.0])
            try:
                return fn(*a, **k)
            finally:
                cw, cc = phases.stack.pop()
                dw, dc = time.perf_counter() - w0, time.process_time() - c0
                phases.wall[phase] = phases.wall.get(phase, 0.0) + dw - cw
                phases.cpu[phase] = phases.cpu.get(phase, 0.0) + dc - cc
                if phases.stack:
                    phases.stack[-1][0] += dw
                    phases.stack[-1][1] += dc

        setattr(owner, name, wrapped)


def _rss() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def child(path: str, complexity: str, width: int, height: int, render: bool) -> dict:
    t_start = time.perf_counter()
    import numpy as np  # noqa: F401

    import tracer
    import tracer.geometry.subdivision as subdivision
    from tracer.accel.accelerator import Accelerator
    from tracer.builder import SceneBuilder
    from tracer.scene import Scene
    from usd_io import load_stage
    from pxr import Usd  # noqa: F401

    import_s = time.perf_counter() - t_start
    base_rss = _rss()
    ph = _Phases()
    for name in ("refine", "refine_batch"):
        ph.wrap(subdivision, name, "subdivision")
    ph.wrap(Scene, "validate", "validation")
    for name in ("add_mesh", "add_meshes", "build"):
        ph.wrap(SceneBuilder, name, "builder")
    w0, c0 = time.perf_counter(), time.process_time()
    scene, info = load_stage(path, complexity=complexity, width=width, height=height)
    load_w, load_c = time.perf_counter() - w0, time.process_time() - c0
    load_rss = _rss()
    wall = dict(ph.wall)
    cpu = dict(ph.cpu)
    wall["usd read"] = load_w - sum(wall.values())
    cpu["usd read"] = load_c - sum(cpu.values())
    w0, c0 = time.perf_counter(), time.process_time()
    accel = Accelerator(scene)
    wall["bvh"], cpu["bvh"] = time.perf_counter() - w0, time.process_time() - c0
    bvh_rss = _rss()
    if render:
        settings = tracer.RenderSettings(width=width, height=height, threads=2)
        w0, c0 = time.perf_counter(), time.process_time()
        image = tracer.render(scene, settings, accel=accel)
        wall["render"], cpu["render"] = time.perf_counter() - w0, time.process_time() - c0
        assert image.rgba.shape[:2] == (height, width)
    n_tri = len(scene.triangles)
    return {"complexity": complexity, "triangles": n_tri, "meshes": len(info.meshes), "import": import_s,
            "load": load_w, "load_cpu": load_c, "wall": wall, "cpu": cpu, "base_rss": base_rss,
            "load_rss": load_rss, "peak_rss": max(bvh_rss, _rss()), "bvh_rss": bvh_rss,
            "warnings": len(info.warnings)}


def run_child(root: str, complexity: str, args) -> dict:
    code = (f"import json, sys; sys.path.insert(0, {root!r}); from bench.kitchen import child; "
            f"print(json.dumps(child({args.stage!r}, {complexity!r}, {args.width}, {args.height}, "
            f"{not args.no_render})))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=root,
                       env=dict(os.environ, PYTHONPATH=root))
    if r.returncode:
        raise SystemExit(r.stderr[-3000:])
    return json.loads(r.stdout.strip().splitlines()[-1])


PHASES = ("usd read", "subdivision", "validation", "builder", "bvh", "render")


def report(results: list[dict]) -> str:
    first = results[0]
    med = lambda xs: statistics.median(xs)  # noqa: E731
    lines = [f"complexity {first['complexity']}: {first['meshes']} meshes, {first['triangles']:,} triangles, "
             f"{len(results)} runs (medians; wall / CPU seconds of the process)",
             "| phase | wall s | CPU s |", "|---|---|---|"]
    for p in PHASES:
        if p in first["wall"]:
            lines.append(f"| {p} | {med([r['wall'][p] for r in results]):.3f} | "
                         f"{med([r['cpu'][p] for r in results]):.3f} |")
    lines.append(f"| load_stage (usd read … builder) | {med([r['load'] for r in results]):.3f} | "
                 f"{med([r['load_cpu'] for r in results]):.3f} |")
    total = [r["load"] + r["wall"]["bvh"] + r["wall"].get("render", 0.0) for r in results]
    lines.append(f"| load + bvh + render | {med(total):.3f} | |")
    n = first["triangles"]
    lines.append(f"imports {med([r['import'] for r in results]):.3f} s; peak RSS after load "
                 f"{med([r['load_rss'] for r in results]) / 1e9:.2f} GB, after BVH "
                 f"{med([r['peak_rss'] for r in results]) / 1e9:.2f} GB = "
                 f"{med([r['peak_rss'] for r in results]) / n:.0f} bytes/triangle "
                 f"(process after imports {med([r['base_rss'] for r in results]) / 1e9:.2f} GB; above it "
                 f"{(med([r['peak_rss'] for r in results]) - med([r['base_rss'] for r in results])) / n:.0f} "
                 "bytes/triangle)")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--complexity", default="medium,high")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--width", type=int, default=960)
    ap.add_argument("--height", type=int, default=540)
    ap.add_argument("--no-render", action="store_true")
    ap.add_argument("--stage", default=STAGE)
    ap.add_argument("--root", default=os.path.dirname(HERE), help="checkout to measure (default: this one)")
    ap.add_argument("--json", help="also write the raw results here")
    args = ap.parse_args(argv)
    ensure_stage(args.stage)
    levels = args.complexity.split(",")
    results = {c: [] for c in levels}
    for _ in range(args.runs):
        for c in levels:
            results[c].append(run_child(os.path.abspath(args.root), c, args))
    for c in levels:
        print(report(results[c]))
        print()
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())

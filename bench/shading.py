"""What the material model costs: the bench scenes rendered with the notes' classic model, the Principled model, and
the Principled model with a texture on every parameter, against the tracer before the Principled model.

    python -m bench.shading [--before REV] [--scenes whitted,heavy,instances] [--width 960 --height 540] [--runs 3]

Each variant renders in a fresh child process (kernels warmed by one untimed render first), 2 threads, depth 8,
pixel centres; the median wall time of ``--runs`` renders is printed with its ratio to the classic model of the
same tree. ``--before REV`` also measures the git revision REV (checked out into a temporary worktree), where the
classic model was the only one. The textured variant gives every material a 1024² base-colour, roughness and
normal-map texture on planar UVs (x, y of the world position), so every hit does three extra bilinear lookups and
a tangent frame.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: The child: build a bench scene, optionally texture it, render it warm ``runs`` times; print the wall times.
CHILD = r"""
import json, sys, time
import numpy as np
import tracer
from bench import scenes
name, w, h, runs, variant = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
scene = scenes.to_tracer(scenes.build(name), w, h)
kw = dict(width=w, height=h, samples=1, max_depth=8, threads=2)
if variant != "before":
    kw["shading"] = "classic" if variant == "classic" else "principled"
if variant == "textured":
    rng = np.random.default_rng(0)
    n = 1024
    y, x = np.mgrid[0:n, 0:n] / n
    base = np.stack([0.5 + 0.4 * np.sin(12 * x), 0.5 + 0.4 * np.cos(9 * y), 0.5 + 0.3 * np.sin(7 * (x + y))], -1)
    rough = (0.2 + 0.6 * rng.random((n, n, 1)))
    nrm = np.stack([0.5 + 0.2 * np.sin(40 * x), 0.5 + 0.2 * np.cos(40 * y), np.ones_like(x)], -1)
    first = len(scene.textures)
    scene.textures = list(scene.textures) + [tracer.Texture(base.astype(np.float32)),
                                             tracer.Texture(rough.astype(np.float32)),
                                             tracer.Texture(nrm.astype(np.float32), scale=(2, 2, 2, 1),
                                                            bias=(-1, -1, -1, 0))]
    p = scene.vertices[scene.triangles]
    scene.uvs = np.ascontiguousarray(p[..., :2] * 0.25, np.float32)
    scene.uv_sets = [scene.uvs]
    m = scene.materials
    m.base_color_texture[:] = first
    m.roughness_texture[:] = first + 1
    m.roughness_channel[:] = 0
    m.normal_texture[:] = first + 2
    scene.validate()
settings = tracer.RenderSettings(**kw)
img = tracer.render(scene, settings)  # warm-up: kernels compiled or loaded
times = []
for _ in range(runs):
    t0 = time.perf_counter()
    img = tracer.render(scene, settings)
    times.append(time.perf_counter() - t0)
print(json.dumps({"times": times, "mean": float(img.rgb.mean())}))
"""


def measure(tree: str, scene: str, width: int, height: int, runs: int, variant: str) -> dict:
    env = dict(os.environ, PYTHONPATH=tree)
    r = subprocess.run([sys.executable, "-c", CHILD, scene, str(width), str(height), str(runs), variant], cwd=tree,
                       env=env, capture_output=True, text=True, timeout=3600)
    if r.returncode:
        raise SystemExit(f"bench.shading: {variant} on {scene} failed: {r.stderr.strip().splitlines()[-1:]}")
    out = json.loads(r.stdout.strip().splitlines()[-1])
    out["median"] = statistics.median(out["times"])
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(prog="python -m bench.shading", description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default="whitted,heavy,instances")
    ap.add_argument("--width", type=int, default=960)
    ap.add_argument("--height", type=int, default=540)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--before", help="a git revision to measure too (the tracer before the Principled model)")
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="whitted-before-") as tmp:
        trees = [("classic", ROOT, "classic"), ("principled", ROOT, "principled"), ("textured", ROOT, "textured")]
        if a.before:
            before = os.path.join(tmp, "tree")
            subprocess.run(["git", "-C", ROOT, "worktree", "add", "--detach", before, a.before], check=True,
                           capture_output=True)
            trees.insert(0, (f"before ({a.before})", before, "before"))
        try:
            print(f"| scene | {' | '.join(t[0] for t in trees)} |")
            print(f"|---|{'---|' * len(trees)}")
            for scene in a.scenes.split(","):
                got = {label: measure(tree, scene, a.width, a.height, a.runs, variant)
                       for label, tree, variant in trees}
                ref = got["classic"]["median"]
                cells = [f"{g['median']:.3f} s ({g['median'] / ref:.2f}×)" for g in got.values()]
                print(f"| {scene} | {' | '.join(cells)} |", flush=True)
        finally:
            if a.before:
                subprocess.run(["git", "-C", ROOT, "worktree", "remove", "--force", before], capture_output=True)


if __name__ == "__main__":
    main()

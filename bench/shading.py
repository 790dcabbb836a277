"""What the material model costs: the bench scenes rendered with the notes' classic model, the Principled model, and
the Principled model with a texture on every parameter, against the tracer before the Principled model.

    python -m bench.shading [--before REV | --before-tree PATH] [--scenes whitted,heavy,instances]
                            [--width 960 --height 540] [--runs 3] [--threads 2] [--texture 1024] [--cpu]
                            [--variants classic,principled,textured,procedural]

Each variant renders in a fresh child process (kernels warmed by one untimed render first), 2 threads, depth 8,
pixel centres; the median wall time of ``--runs`` renders is printed with its ratio to the classic model of the
same tree. ``--before REV`` also measures the git revision REV (checked out into a temporary worktree), where the
classic model was the only one. The textured variant gives every material a 1024² base-colour, roughness and
normal-map texture on planar UVs (the world position projected along each triangle's dominant axis), so every hit does three extra bilinear lookups and
a tangent frame; the roughness texels are 1 and the normal map flat, so it traces exactly the rays of the
untextured scene and the difference is the cost of texturing alone.
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
import json, os, sys, time
import numpy as np
import tracer
from bench import scenes
name, w, h, runs, variant = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
threads, clock = int(sys.argv[6]), (time.process_time if sys.argv[7] == "cpu" else time.perf_counter)
scene = scenes.to_tracer(scenes.build(name), w, h)
kw = dict(width=w, height=h, samples=1, max_depth=8, threads=threads)
if variant != "before":
    kw["shading"] = "classic" if variant == "classic" else "principled"
if variant == "textured":
    n = int(os.environ.get('WHITTED_BENCH_TEXTURE', 1024))
    y, x = np.mgrid[0:n, 0:n] / n
    base = np.stack([0.5 + 0.4 * np.sin(12 * x), 0.5 + 0.4 * np.cos(9 * y), 0.5 + 0.3 * np.sin(7 * (x + y))], -1)
    rough = np.ones((n, n, 1))  # x the constant: every material keeps its roughness (the same rays)
    nrm = np.broadcast_to([0.5, 0.5, 1.0], (n, n, 3))  # flat: the same normals (the same rays)
    first = len(scene.textures)
    scene.textures = list(scene.textures) + [tracer.Texture(base.astype(np.float32)),
                                             tracer.Texture(rough.astype(np.float32)),
                                             tracer.Texture(nrm.astype(np.float32), scale=(2, 2, 2, 1),
                                                            bias=(-1, -1, -1, 0))]
    p = scene.vertices[scene.triangles].astype(np.float64)
    fn = np.abs(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]))
    keep = np.array([[1, 2], [0, 2], [0, 1]])[fn.argmax(axis=1)]  # project along each triangle's dominant axis
    scene.uvs = np.ascontiguousarray(np.take_along_axis(p, keep[:, None, :], axis=2) * 0.25, np.float32)
    scene.uv_sets = [scene.uvs]
    m = scene.materials
    m.base_color_texture[:] = first
    m.roughness_texture[:] = first + 1
    m.roughness_channel[:] = 0
    m.normal_texture[:] = first + 2
    scene.validate()
if variant == "procedural":  # every material a dozen-node program (tracer.shading.graph), bump included
    from tracer.shading.compiler import BoundGraph, compile_graph
    from tracer.shading.graph import Graph
    m = scene.materials
    programs, n_ops = [], 0
    for i in range(len(m)):
        g = Graph(f"proc{i}")
        p = g.add("texture_coordinate")["Object"]
        p = g.add("mapping", {"Vector": p, "Scale": (4.0, 4.0, 4.0)})["Vector"]
        w = g.add("vector_math", {"Vector": p}, operation="SINE")["Vector"]
        xyz = g.add("separate_xyz", {"Vector": w})
        f = g.add("math", {"Value": xyz["X"], "Value_001": xyz["Y"]}, operation="ADD")["Value"]
        f = g.add("math", {"Value": f, "Value_001": 0.25, "Value_002": 0.5}, operation="MULTIPLY_ADD")["Value"]
        ramp = g.add("rgb_ramp", {"Fac": f}, ramp=[(0.2, (0.6, 0.6, 0.6, 1)), (0.8, (1, 1, 1, 1))])["Color"]
        base = g.add("vector_math", {"Vector": ramp, "Vector_001": tuple(map(float, m.diffuse[i]))},
                     operation="MULTIPLY")["Vector"]
        h = g.add("math", {"Value": xyz["Z"], "Value_001": xyz["Y"]}, operation="MULTIPLY")["Value"]
        nrm = g.add("bump", {"Height": h, "Strength": 0.05, "Distance": 0.1})["Normal"]
        g.output(g.add("principled_bsdf", {"Base Color": base, "Roughness": float(m.roughness[i]),
                                           "Metallic": float(m.metallic[i]), "Specular IOR Level": float(m.specular[i]),
                                           "Normal": nrm})["BSDF"])
        programs.append(BoundGraph(g, {}))
        n_ops = compile_graph(g).program.n_ops
    m.programs = programs
    print(json.dumps({"ops": n_ops}), file=sys.stderr)
settings = tracer.RenderSettings(**kw)
img = tracer.render(scene, settings)  # warm-up: kernels compiled or loaded
times = []
for _ in range(runs):
    t0 = clock()
    img = tracer.render(scene, settings)
    times.append(clock() - t0)
print(json.dumps({"times": times, "mean": float(img.rgb.mean())}))
"""


def measure(tree: str, scene: str, width: int, height: int, runs: int, variant: str, threads: int = 2,
            clock: str = "wall", texture: int = 1024) -> dict:
    env = dict(os.environ, PYTHONPATH=tree, WHITTED_BENCH_TEXTURE=str(texture))
    r = subprocess.run([sys.executable, "-c", CHILD, scene, str(width), str(height), str(runs), variant,
                        str(threads), clock], cwd=tree,
                       env=env, capture_output=True, text=True, timeout=3600)
    if r.returncode:
        raise SystemExit(f"bench.shading: {variant} on {scene} failed: {r.stderr.strip().splitlines()[-1:]}")
    out = json.loads(r.stdout.strip().splitlines()[-1])
    out["median"] = statistics.median(out["times"])
    out["best"] = min(out["times"])
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(prog="python -m bench.shading", description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default="whitted,heavy,instances")
    ap.add_argument("--width", type=int, default=960)
    ap.add_argument("--height", type=int, default=540)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--before", help="a git revision to measure too (the tracer before the Principled model)")
    ap.add_argument("--before-tree", help="a checkout to measure as 'before' (instead of --before's worktree)")
    ap.add_argument("--variants", default="classic,principled,textured",
                    help="of classic, principled, textured, procedural (a dozen-node program on every material)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--texture", type=int, default=1024, help="texture size of the textured variant (default 1024)")
    ap.add_argument("--cpu", action="store_true", help="time the child's CPU (steadier on a shared machine with "
                                                       "--threads 1) instead of the wall clock")
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="whitted-before-") as tmp:
        trees = [(v, ROOT, v) for v in a.variants.split(",")]
        if a.before_tree:
            trees.insert(0, ("before", a.before_tree, "principled"))
        elif a.before:
            before = os.path.join(tmp, "tree")
            subprocess.run(["git", "-C", ROOT, "worktree", "add", "--detach", before, a.before], check=True,
                           capture_output=True)
            trees.insert(0, (f"before ({a.before})", before, "before"))
        try:
            print(f"| scene | {' | '.join(t[0] for t in trees)} |")
            print(f"|---|{'---|' * len(trees)}")
            for scene in a.scenes.split(","):
                got = {label: measure(tree, scene, a.width, a.height, a.runs, variant, a.threads,
                                      "cpu" if a.cpu else "wall", a.texture) for label, tree, variant in trees}
                ref = got[trees[0][0]]["best" if a.cpu else "median"]
                key = "best" if a.cpu else "median"
                cells = [f"{g[key]:.3f} s ({g[key] / ref:.2f}×)" for g in got.values()]
                print(f"| {scene} | {' | '.join(cells)} |", flush=True)
        finally:
            if a.before:
                subprocess.run(["git", "-C", ROOT, "worktree", "remove", "--force", before], capture_output=True)


if __name__ == "__main__":
    main()

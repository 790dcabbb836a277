"""``python -m bench.whole``: the whole ``whitted render`` process against POV-Ray on a 246 k-triangle scene (#23).

The scene is the bench's Whitted 1980 picture (:func:`bench.scenes.whitted`) with both spheres tessellated as
176×176 UV spheres: 245 424 triangles (the "hidden 246 k-triangle Whitted scene" of /work/shared/DESIGN.md and
issue #23 was of this kind; it is not in the repository, this one is generated, no downloads). It is written once
as a USD crate (``.cache/bench/whole.usdc``, bench/usd.py) and as POV-Ray SDL (bench/povray.py).

Each run is a fresh process, timed from ``fork`` to exit with ``os.wait4`` (wall and the child's CPU time):
``whitted render whole.usdc -o out.png`` at 1920×1080, depth 8, 2 threads, as the installed script runs it
(``usd_io.cli.run``), and ``povray`` on the same triangles (AA off, ``+WT2``). The two alternate run by run so the
machine's load falls on both. Kernels are compiled and bytecode written by an unmeasured first run.

``--phases`` adds one instrumented run: imports, stage read, render, PNG write (and what is left: Python start-up
and exit), from wrappers around the CLI's own calls. ``--root DIR`` measures another checkout with this venv.
No assertions (docs/benchmarks.md records the numbers).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time

from . import povray, scenes
from .scenes import BenchScene, Mesh

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
COUNT = 176  # UV sphere rings and segments: 2 × 122 388 + 648 floor = 245 424 triangles
ENTRY = "import sys, usd_io.cli as c; sys.exit((getattr(c, 'run', None) or c.main)())"

#: ``--phases``: the CLI in-process, its imports made first in the order it makes them and its own calls wrapped by
#: timers (exclusive of each other): wall and the process's CPU (every thread) of each.
PHASES = r'''
import os, sys, time
marks = {}
clock = lambda: (time.perf_counter(), time.process_time())  # noqa: E731
t0 = last = clock()
def mark(label, since=None):
    global last
    now = clock()
    a = since or last
    w, c = marks.get(label, (0.0, 0.0))
    marks[label] = (w + now[0] - a[0], c + now[1] - a[1])
    last = now
import usd_io.cli as cli
mark("import numpy, usd_io.cli")
import usd_io.stage
mark("import pxr (usd_io.stage)")
import tracer.render
mark("import numba, tracer (tracer.render)")
import usd_io.reader
mark("import usd_io.reader")
import usd_io.request as rq, usd_io.outputs as outs
def wrap(obj, name, label):
    f = getattr(obj, name)
    def timed(*a, **k):
        mark("main: the rest")
        try:
            return f(*a, **k)
        finally:
            mark(label)
    setattr(obj, name, timed)
wrap(rq.StageRequest, "read", "usd read")
import tracer
wrap(tracer, "render", "render (kernel loads, BVH included)")
wrap(outs.Outputs, "write", "image write (the PNG's last rows)")
code = cli.main(sys.argv[1:])
mark("main: the rest")
w, c = clock()
marks["total (after Python start-up)"] = (w - t0[0], c)
for k, (w, c) in marks.items():
    print(f"PHASE {k}\t{w:.4f}\t{c:.4f}")
'''


def build_scene(count: int = COUNT) -> BenchScene:
    """The Whitted scene with ``count``×``count`` UV spheres."""
    bs = scenes.whitted()
    meshes = []
    for m in bs.meshes:
        if m.name in ("MirrorSphere", "GlassSphere"):
            centre = m.vertices.mean(axis=0)
            radius = float(abs(m.vertices[:, 2] - centre[2]).max())
            s = scenes._uv_sphere(m.name, radius, m.material, count=count, center=centre)
            m = Mesh(s.name, s.vertices, s.faces, s.normals, s.material)
        meshes.append(m)
    bs.meshes = meshes
    bs.name = "whole"
    return bs


def _files(work: str, width: int, height: int, depth: int, count: int):
    os.makedirs(work, exist_ok=True)
    usd = os.path.join(work, f"whole_{count}_{width}x{height}.usdc")
    sdl = os.path.join(work, f"whole_{count}_{width}x{height}_d{depth}.pov")
    if not (os.path.exists(usd) and os.path.exists(sdl)):
        from .usd import write_usd

        bs = build_scene(count)
        print(f"bench.whole: writing {usd} and {sdl} ({bs.triangle_count:,} triangles)", flush=True)
        write_usd(bs, usd + ".tmp.usdc", width, height)
        os.replace(usd + ".tmp.usdc", usd)
        povray.write_sdl(bs, sdl, width, height, depth)
    return usd, sdl


def _timed(cmd, env=None, cwd=None) -> tuple[float, float]:
    """Wall and CPU (user + system) seconds of one child process."""
    start = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    err = proc.stderr.read().decode(errors="replace")
    proc.stderr.close()
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"{cmd[:3]} failed: {err[-2000:]}")
    return wall, usage.ru_utime + usage.ru_stime


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(prog="python -m bench.whole", description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    ap.add_argument("--max-depth", type=int, default=8)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--count", type=int, default=COUNT, help="UV sphere rings/segments (176: 245 424 triangles)")
    ap.add_argument("--root", default=ROOT, help="the checkout to measure (default: this one)")
    ap.add_argument("--before", help="another checkout (e.g. git archive of an older commit) measured in the same "
                                     "rounds: ours, before, POV-Ray, ours, before, ...")
    ap.add_argument("--work", default=os.path.join(ROOT, ".cache", "bench"))
    ap.add_argument("--phases", action="store_true", help="also one instrumented run: where our process goes")
    ap.add_argument("--skip-povray", action="store_true")
    a = ap.parse_args(argv)

    usd, sdl = _files(a.work, a.width, a.height, a.max_depth, a.count)
    print("load average (1, 5, 15 min) at the start: " + ", ".join(f"{x:.2f}" for x in os.getloadavg()))
    out = os.path.join(a.work, "whole_whitted.png")
    flags = ["render", usd, "-o", out, "--width", str(a.width), "--height", str(a.height),
             "--max-depth", str(a.max_depth), "--threads", str(a.threads), "--quiet",
             # like for like: POV-Ray's ambient_light is the notes' flat ambient term, not shadowed sky rays
             "--sky-samples", "0", "--aa", "1"]
    env = dict(os.environ, PYTHONPATH=os.path.abspath(a.root))
    env.pop("PYTHONDONTWRITEBYTECODE", None)  # an install has its bytecode; the warm-up run writes it
    ours_cmd = [sys.executable, "-c", ENTRY, *flags]
    _timed(ours_cmd, env=env, cwd=a.root)  # kernels compiled or loaded once, bytecode written
    if a.before:
        env_before = dict(env, PYTHONPATH=os.path.abspath(a.before))
        _timed(ours_cmd, env=env_before, cwd=a.before)
    before = []
    has_pov = not a.skip_povray and povray.povray_binary() is not None
    # bench.povray.render's command line (AA off, no display, its threads), timed here for its CPU time too
    pov_cmd = [str(povray.povray_binary()), f"+I{sdl}", f"+O{os.path.join(a.work, 'whole_povray.png')}",
               f"+W{a.width}", f"+H{a.height}", "-A", f"+WT{a.threads}", "-D", "-P", "+FN", "-V", "+GA"]
    ours, pov = [], []
    for _ in range(a.runs):
        ours.append(_timed(ours_cmd, env=env, cwd=a.root))
        if a.before:
            before.append(_timed(ours_cmd, env=env_before, cwd=a.before))
        if has_pov:
            pov.append(_timed(pov_cmd))
    med = lambda xs, i: statistics.median(x[i] for x in xs)  # noqa: E731
    print(f"scene: {build_scene(a.count).triangle_count:,} triangles, "
          f"{a.width}x{a.height}, depth {a.max_depth}, {a.threads} threads, {a.runs} runs, root {a.root}")
    print(f"whitted render (whole process): median wall {med(ours, 0):.3f} s (min {min(o[0] for o in ours):.3f}), "
          f"CPU {med(ours, 1):.3f} s; PNG {os.path.getsize(out) / 1e3:.0f} kB")
    if before:
        print(f"before ({a.before}): median wall {med(before, 0):.3f} s (min {min(o[0] for o in before):.3f}), "
              f"CPU {med(before, 1):.3f} s")
    if pov:
        print(f"POV-Ray (whole process, AA off): median wall {med(pov, 0):.3f} s (min {min(p[0] for p in pov):.3f}), "
              f"CPU {med(pov, 1):.3f} s")
        print(f"ratio ours / POV-Ray: wall {med(ours, 0) / med(pov, 0):.3f} (pairs: "
              + ", ".join(f"{o[0] / p[0]:.2f}" for o, p in zip(ours, pov))
              + f"), CPU {med(ours, 1) / med(pov, 1):.3f} (pairs: "
              + ", ".join(f"{o[1] / p[1]:.2f}" for o, p in zip(ours, pov)) + ")")
        if before:
            print(f"ratio before / POV-Ray: wall {med(before, 0) / med(pov, 0):.3f} (pairs: "
                  + ", ".join(f"{o[0] / p[0]:.2f}" for o, p in zip(before, pov))
                  + f"), CPU {med(before, 1) / med(pov, 1):.3f}")
    if a.phases:
        p = subprocess.run([sys.executable, "-c", PHASES, *flags], env=env, cwd=a.root, capture_output=True,
                           text=True, check=True)
        print("phases of one instrumented run (wall, CPU of all threads):")
        for line in p.stdout.splitlines():
            if line.startswith("PHASE "):
                name, wall, cpu = line[6:].split("\t")
                print(f"  {name}: {float(wall):.3f} s, CPU {float(cpu):.3f} s")
    print("load average (1, 5, 15 min) at the end: " + ", ".join(f"{x:.2f}" for x in os.getloadavg()))


if __name__ == "__main__":
    main()

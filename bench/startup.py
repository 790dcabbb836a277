"""``python -m bench.startup``: start-up and batch overhead of the ``whitted`` CLI (issue #11).

Measures, warm (kernels already cached, the run repeated), the wall time of ``whitted render`` of a one-sphere
stage at 64×64 as a fresh process, and the per-file overhead of a batch (``whitted render a.usda b.usda ...
-o out/{stem}.png``: (T(N) − T(1)) / (N − 1)); ``--phases`` adds where a start's time goes, each phase run one
after the other in one fresh process (no overlap), and the interpreter's exit as the rest of the wall time.
Prints the median (and minimum) of ``--repeat`` runs; no assertions (docs/benchmarks.md records the numbers).

The command is run as the installed ``whitted`` script runs it (``usd_io.cli.run``, or ``main`` in trees that
predate it). ``--root DIR`` measures another checkout of the project with this venv (e.g. ``git archive`` of an
older commit; its kernels compile into its own tree on the first, unmeasured, run). The first run also writes the
project's bytecode (``__pycache__``), as any install has it, even where ``PYTHONDONTWRITEBYTECODE`` is set:
compiling tracer/ and usd_io/ from source costs 60 ms per start.
"""

from __future__ import annotations

import argparse
import collections
import os
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BATCH = 10
STAGE = '#usda 1.0\ndef Sphere "Ball" {}\n'
#: What the ``whitted`` console script does (``run`` exits without Python's interpreter teardown).
ENTRY = "import sys, usd_io.cli as c; sys.exit((getattr(c, 'run', None) or c.main)())"

#: ``--phases``: one fresh process, each phase timed on its own (as ``whitted render`` meets them, but serially).
PHASES = r'''
import os, sys, time
marks = [("python start-up", time.perf_counter())]
def mark(name):
    marks.append((name, time.perf_counter()))
import numpy; mark("import numpy")
import usd_io.cli as cli; parser = cli.build_parser(); mark("import usd_io.cli + argparse")
from pxr import Sdf, Usd, UsdGeom, UsdLux, UsdShade; mark("import pxr")
import trimesh; mark("import trimesh (usd_io.geometry.gprims)")
import numba; mark("import numba (llvmlite)")
import tracer.jit; mark("tracer.jit (source hash)")
import tracer.render; mark("import tracer.render (kernel modules)")
import usd_io.reader; mark("import usd_io.reader (rest)")
from usd_io.reader import load_stage
from usd_io.stage import open_stage
stage = open_stage(sys.argv[1]); scene, info = load_stage(stage, width=64); mark("open + read the stage")
from numba.core.compiler_lock import global_compiler_lock
from numba.core.registry import cpu_target
with global_compiler_lock:  # what the first cached kernel's load sets up: all of numba's target, or NRT only
    if hasattr(tracer.jit, "_KernelCache") or hasattr(tracer, "kernel_cache"):
        from numba.core.runtime import rtsys
        rtsys.initialize(cpu_target.target_context)
    else:
        cpu_target.target_context.refresh()
mark("numba set-up for cached kernels (refresh / NRT)")
from tracer import embree
embree.library(); mark("Embree library + device")
import numba.core.caching as caching
loads = []
_load = caching.Cache._load_overload
def load_overload(self, sig, ctx):
    t = time.perf_counter(); r = _load(self, sig, ctx); loads.append(time.perf_counter() - t); return r
caching.Cache._load_overload = load_overload
from tracer import RenderSettings, render
image = render(scene, RenderSettings(width=info.width, height=info.height, progress=False)); mark("render")
try:
    from usd_io.outputs import write_outputs
except ImportError:  # trees before usd_io/outputs.py
    write_outputs = cli.write_outputs
write_outputs(image, sys.argv[2], ()); mark("write the PNG (incl. OpenImageIO's import where used)")
print(repr([(n, t - marks[i][1]) for i, (n, t) in enumerate(marks[1:])]
           + [(f"  of which {len(loads)} kernel cache loads", sum(loads)), ("start", marks[0][1]),
              ("end", marks[-1][1])]))
sys.stdout.flush()
'''


def _env(root):
    return dict(os.environ, PYTHONPATH=root + os.pathsep + os.environ.get("PYTHONPATH", ""))


def _run(root, args, code=ENTRY, clock=False):
    t = time.perf_counter()
    p = subprocess.run([sys.executable, "-c", code, *args], check=True, env=_env(root), capture_output=True,
                       text=True, cwd=root)
    end = time.perf_counter()
    return ((t, end) if clock else end - t), p.stdout


def _stats(values):
    return f"{statistics.median(values):6.3f} s (min {min(values):.3f})"


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m bench.startup", description=__doc__.split("\n\n")[0])
    ap.add_argument("--root", default=ROOT, help="the checkout to measure (default: this one)")
    ap.add_argument("--repeat", type=int, default=7, help="runs per measurement (median reported)")
    ap.add_argument("--phases", action="store_true", help="also the serial breakdown of one start")
    a = ap.parse_args(argv)
    root = os.path.abspath(a.root)
    with tempfile.TemporaryDirectory() as d:
        files = []
        for i in range(BATCH):
            p = os.path.join(d, f"ball{i}.usda")
            with open(p, "w") as f:
                f.write(STAGE)
            files.append(p)
        out = os.path.join(d, "{stem}.png")
        common = ["--width", "64", "--quiet"]
        env = _env(root)
        env.pop("PYTHONDONTWRITEBYTECODE", None)  # warm the kernel cache and write the bytecode
        subprocess.run([sys.executable, "-c", ENTRY, "render", files[0], "-o", out, *common], check=True, env=env,
                       capture_output=True, cwd=root)
        version = [_run(root, ["--version"])[0] for _ in range(a.repeat)]
        one, many = [], []
        for _ in range(a.repeat):  # interleaved: load from other users of the machine hits both alike
            one.append(_run(root, ["render", files[0], "-o", out, *common])[0])
            many.append(_run(root, ["render", *files, "-o", out, *common])[0])
        phases = collections.defaultdict(list)
        if a.phases:
            for _ in range(a.repeat):
                (t0, t1), text = _run(root, [files[0], os.path.join(d, "phases.png")], code=PHASES, clock=True)
                rows = dict(eval(text.strip().splitlines()[-1]))  # noqa: S307 — our own child's repr of floats
                # perf_counter is CLOCK_MONOTONIC, one clock for every process: the child's marks place its
                # interpreter start-up (before its first line) and exit (after its last) in the parent's time
                start, end = rows.pop("start"), rows.pop("end")
                for name, t in [("Python start-up (site, editable finder)", start - t0), *rows.items(),
                                ("interpreter exit (teardown; usd_io.cli.run skips it)", t1 - end), ("wall", t1 - t0)]:
                    phases[name].append(t)
    per_file = [(m - o) / (BATCH - 1) for o, m in zip(one, many)]
    print(f"{root}: median of {a.repeat} fresh processes")
    print(f"whitted --version (Python + argparse):   {_stats(version)}")
    print(f"one 64x64 sphere, fresh process, warm:   {_stats(one)}")
    print(f"batch of {BATCH}: {_stats(many)} -> {statistics.median(per_file):.3f} s per extra file")
    if phases:
        print("serial phases of one start (--phases):")
        for name, values in phases.items():
            print(f"  {statistics.median(values) * 1000:7.1f} ms  (min {min(values) * 1000:6.1f})  {name}")


if __name__ == "__main__":
    main()

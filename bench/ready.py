"""``python -m bench.ready``: how long from a fresh install to the first picture, and what an edit recompiles (#29).

Each measure runs in fresh processes with an empty kernel cache of its own (``WHITTED_KERNEL_CACHE``):

- ``cli``: ``whitted render examples/whitted_1980.usda`` (what ``make render`` runs after installing), cold (every
  kernel it uses compiled) and warm (loaded), wall and CPU time of the whole process (``os.wait4``), with the
  number of compile units and the CPU time numba spent compiling them (numba's event API, in the process).
- ``edits``: in a copy of the tracer, after a warm render, an edit of a file that defines no kernel
  (tracer/settings.py) and an edit of one kernel in tracer/shading/procedural/noise.py: the compile units the next render
  of a noise-textured scene compiles.
- ``addon``: the Linux extension zip installed into a temporary Blender profile (bpy, headless), from enabling it to
  the first F12 of the default cube, with the zip's kernels (this machine is in their CPU family) and without them
  (``addon.build --no-kernels``: compiled in the child process); and a latency probe on Blender's main thread (a
  ``sleep(0.01)`` loop while the kernels are prepared): its 99th-percentile and largest gap.
- ``baseline``: the render time of the bench scenes with kernels for this CPU against kernels for the shipped
  baseline (``tracer.kernel_cache.BASELINE_CPU``).

Prints a table; no assertions (docs/benchmarks.md records the numbers).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: A render in a child process, with numba's compile events counted (units, seconds of CPU in compiles).
RENDER = r'''
import json, os, sys, time
from numba.core import event
units, cpu = [0], [0.0]
class L(event.Listener):
    def on_start(self, ev):
        self.c = time.process_time()
    def on_end(self, ev):
        f = getattr(ev.data.get("dispatcher"), "py_func", None)
        if f is not None and f.__module__.startswith("tracer"):
            units[0] += 1
            if os.environ.get("BENCH_UNITS"):
                print("UNIT", f.__module__, f.__qualname__, file=sys.stderr)
lis = L()
event.register("numba:compile", lis)
start = [None]
class Top(event.Listener):  # CPU inside the outermost compiles only (nested ones are inside them)
    depth = 0
    def on_start(self, ev):
        if Top.depth == 0:
            start[0] = time.process_time()
        Top.depth += 1
    def on_end(self, ev):
        Top.depth -= 1
        if Top.depth == 0:
            cpu[0] += time.process_time() - start[0]
event.register("numba:compile", Top())
if sys.argv[1] == "vm":  # a bench.vm scene (a procedural material) through the API
    sys.path.append(os.environ["BENCH_ROOT"])  # bench/ only: the tracer is the one on PYTHONPATH
    import tracer
    from bench import vm
    tracer.render(vm.scene(sys.argv[2]), tracer.RenderSettings(width=64, height=64, progress=False))
    code = 0
else:
    import usd_io.cli as cli
    code = cli.main(sys.argv[1:])
print("BENCH " + json.dumps({"units": units[0], "compile_cpu": cpu[0], "code": code}), flush=True)
'''


def run(cmd, env, cwd=ROOT):
    """(wall s, CPU s of the child and its children, its stdout) of one child process."""
    import resource

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd[:4])}... failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if os.environ.get("BENCH_UNITS"):  # which units compiled (a debugging aid)
        sys.stderr.write("".join(ln + "\n" for ln in proc.stderr.splitlines() if ln.startswith("UNIT ")))
    return wall, cpu, proc.stdout


def render_once(cache: str, tree: str = ROOT, what=("render", "examples/whitted_1980.usda"), processes: int = 1):
    """One render in a child process; ``processes=2`` lets the CLI start its second compiling process
    (tracer/kernel_plan.py), whose CPU time is not in ``cpu`` (it is not a waited-for child)."""
    env = dict(os.environ, WHITTED_KERNEL_CACHE=cache, PYTHONPATH=tree, BENCH_ROOT=ROOT,
               WHITTED_COMPILE_PROCESSES=str(processes))
    cmd = [sys.executable, "-c", RENDER, *what]
    if what[0] == "render":
        cmd += ["-o", os.path.join(cache, "out.png"), "--quiet"]
    os.makedirs(cache, exist_ok=True)
    wall, cpu, out = run(cmd, env, cwd=tree)
    line = next(ln for ln in out.splitlines() if ln.startswith("BENCH "))
    result = dict(wall=wall, cpu=cpu, **json.loads(line[len("BENCH "):]))
    if result["code"]:
        raise RuntimeError(f"{' '.join(what)}: exit {result['code']}")
    return result


def bench_cli(args):
    rows = []
    for k in range(args.runs):
        with tempfile.TemporaryDirectory(prefix="whitted-kernels-") as cache:
            cold = render_once(cache)
            warm = render_once(cache)
        with tempfile.TemporaryDirectory(prefix="whitted-kernels-") as cache:
            two = render_once(cache, processes=2)
        rows.append((cold, warm, two))
        print(f"cli run {k + 1}: cold, one process {cold['wall']:.1f} s wall, {cold['cpu']:.1f} s CPU "
              f"({cold['units']} units, {cold['compile_cpu']:.1f} s CPU compiling); cold, two processes "
              f"{two['wall']:.1f} s wall ({two['units']} units in the render's own process, "
              f"{two['compile_cpu']:.1f} s CPU compiling there); warm {warm['wall']:.2f} s wall, "
              f"{warm['cpu']:.2f} s CPU ({warm['units']} units)", flush=True)
    return rows


def bench_edits(args):
    """Compile units after editing a file without kernels, and after editing one kernel in noise.py."""
    results = {}
    with tempfile.TemporaryDirectory(prefix="whitted-edit-") as tmp:
        tree = os.path.join(tmp, "tree")
        for part in ("tracer", "usd_io", "examples"):
            shutil.copytree(os.path.join(ROOT, part), os.path.join(tree, part),
                            ignore=shutil.ignore_patterns("__pycache__"))
        cache = os.path.join(tmp, "cache")
        plain, noise = ("render", "examples/whitted_1980.usda"), ("vm", "noise")
        first = render_once(cache, tree, plain)["units"] + render_once(cache, tree, noise)["units"]
        with open(os.path.join(tree, "tracer", "settings.py"), "a") as f:
            f.write("\n# an edit of a file that defines no kernel\n")
        results["settings.py"] = render_once(cache, tree, plain)["units"] + render_once(cache, tree, noise)["units"]
        path = os.path.join(tree, "tracer", "shading", "procedural", "noise.py")
        with open(path) as f:
            text = f.read()
        i = text.index("def perlin3(")
        j = text.index('"""', text.index('"""', i) + 3) + 3  # after perlin3's docstring
        with open(path, "w") as f:
            f.write(text[:j] + "\n    _edited = 1.0" + text[j:])
        results["noise.py: default scene"] = render_once(cache, tree, plain)["units"]
        results["noise.py: noise scene"] = render_once(cache, tree, noise)["units"]
        print(f"edits: the two first renders compiled {first} units; after editing settings.py "
              f"{results['settings.py']}; after editing noise.py's perlin3: the default scene "
              f"{results['noise.py: default scene']}, the noise scene {results['noise.py: noise scene']}",
              flush=True)
    return results



#: In a fresh Blender (bpy) process: install and enable the zip, probe the main thread while the kernels are being
#: prepared, then F12 on the default cube.
ADDON = r"""
import json, os, sys, time
import bpy
zip_path, png = sys.argv[1:3]
bpy.ops.wm.read_factory_settings(use_empty=False)
t0 = time.perf_counter()
bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
t_enabled = time.perf_counter()
mod = sys.modules["bl_ext.user_default.whitted"]
gaps, last = [], time.perf_counter()
while not mod.kernels.ready():  # the main thread stays free: a sleep(0.01) loop, its gaps recorded
    time.sleep(0.01)
    now = time.perf_counter()
    gaps.append(now - last)
    last = now
t_ready = time.perf_counter()
scene = bpy.context.scene
scene.render.engine = "WHITTED"
scene.render.resolution_percentage = 50
scene.render.filepath = png
bpy.ops.render.render(write_still=True)
t_picture = time.perf_counter()
gaps.sort()
print("BENCH " + json.dumps(dict(install=t_enabled - t0, ready=t_ready - t_enabled, first_f12=t_picture - t_enabled,
                                 f12=t_picture - t_ready, units=mod.kernels._state.done,
                                 p99=gaps[int(0.99 * (len(gaps) - 1))] if gaps else 0.0,
                                 max=gaps[-1] if gaps else 0.0, samples=len(gaps))), flush=True)
"""


def bench_addon(args):
    from addon import build

    results = {}
    with tempfile.TemporaryDirectory(prefix="whitted-addon-") as tmp:
        for shipped in (True, False):
            start = time.perf_counter()
            z = build.build(os.path.join(tmp, f"dist-{shipped}"), platforms=("linux-x64",), offline=True,
                            kernels=shipped)["linux-x64"]
            made = time.perf_counter() - start
            for k in range(args.runs):
                user = os.path.join(tmp, f"user-{shipped}-{k}")
                env = dict(os.environ, BLENDER_USER_RESOURCES=user, WHITTED_KERNEL_CACHE=os.path.join(user, "cache"))
                wall, cpu, out = run([sys.executable, "-c", ADDON, z, os.path.join(user, "f12.png")], env, cwd=tmp)
                r = json.loads(next(ln for ln in out.splitlines() if ln.startswith("BENCH "))[len("BENCH "):])
                results.setdefault(shipped, []).append(r)
                print(f"add-on {'with' if shipped else 'without'} shipped kernels (zip built in {made:.0f} s), run "
                      f"{k + 1}: enabled -> first F12 {r['first_f12']:.1f} s (kernels ready {r['ready']:.1f} s, "
                      f"{r['units']} units compiled in the child; F12 itself {r['f12']:.1f} s); main-thread probe "
                      f"p99 {r['p99'] * 1000:.1f} ms, max {r['max'] * 1000:.1f} ms over {r['samples']} samples",
                      flush=True)
    return results



#: Render CPU time (best of runs, after a warm-up render) of the bench scenes and the VM's, in one process.
SPEED = r"""
import json, os, sys, time
sys.path.insert(0, os.environ["BENCH_ROOT"])
import tracer
from bench import scenes, vm
runs = int(sys.argv[1])
res = {}
def timed(name, scene, settings):
    tracer.render(scene, settings)
    best = 1e9
    for _ in range(runs):
        c = time.process_time()
        tracer.render(scene, settings)
        best = min(best, time.process_time() - c)
    res[name] = best
for name in ("whitted", "heavy", "instances"):
    timed(name, scenes.to_tracer(scenes.build(name), 960, 540),
          tracer.RenderSettings(width=960, height=540, samples=1, max_depth=8, threads=1, progress=False))
for kind in ("plain", "sine", "noise"):
    timed("vm-" + kind, vm.scene(kind), tracer.RenderSettings(width=384, height=384, samples=1, threads=1,
                                                              progress=False))
print("BENCH " + json.dumps(res), flush=True)
"""


def bench_baseline(args):
    """Render CPU with kernels tuned for this CPU against kernels for the shipped baseline, alternating."""
    from tracer import kernel_cache

    out = {"host": [], "baseline": []}
    with tempfile.TemporaryDirectory(prefix="whitted-baseline-") as tmp:
        for k in range(args.runs):
            for kind in ("host", "baseline"):
                env = dict(os.environ, WHITTED_KERNEL_CACHE=os.path.join(tmp, kind), PYTHONPATH=ROOT, BENCH_ROOT=ROOT)
                if kind == "baseline":
                    env.update(NUMBA_CPU_NAME=kernel_cache.BASELINE_CPU, NUMBA_CPU_FEATURES="")
                if k == 0:  # compile (unmeasured): the first process after a compile runs measurably slower
                    run([sys.executable, "-c", SPEED, "1"], env)
                _, _, text = run([sys.executable, "-c", SPEED, "5"], env)
                out[kind].append(json.loads(next(ln for ln in text.splitlines()
                                                 if ln.startswith("BENCH "))[len("BENCH "):]))
    for name in out["host"][0]:
        h = min(r[name] for r in out["host"])
        b = min(r[name] for r in out["baseline"])
        print(f"baseline {kernel_cache.BASELINE_CPU} vs this CPU: {name:10s} {h * 1000:7.1f} -> {b * 1000:7.1f} ms "
              f"CPU ({(b / h - 1) * 100:+.1f} %)", flush=True)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m bench.ready", description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--only", default="cli,edits,addon", help="comma-separated: cli, edits, addon, baseline")
    args = ap.parse_args(argv)
    only = set(args.only.split(","))
    if "cli" in only:
        bench_cli(args)
    if "edits" in only:
        bench_edits(args)
    if "addon" in only:
        bench_addon(args)
    if "baseline" in only:
        bench_baseline(args)


if __name__ == "__main__":
    main()

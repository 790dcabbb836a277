"""Kernels compiled ahead of time for a portable CPU baseline, to ship inside a package (the Blender add-on's zip).

    python -m tracer.kernel_bundle DIR [--cpu x86-64-v3]

compiles every kernel a render uses (:func:`tracer.compile_kernels`) in a child process whose numba targets the
baseline CPU (``NUMBA_CPU_NAME``, no host features), into ``DIR/<numba-version-python>/``, with a manifest naming
the machine tuple the kernels were compiled for and the CPU features they need. A process that calls
:func:`tracer.kernel_cache.use_bundle` on ``DIR`` copies a kernel from there into the user's cache the first time it
needs one (where this CPU has those features), so from install to first picture a matching machine compiles nothing.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time

from . import kernel_cache

#: A child process that compiles every kernel (:func:`tracer.compile_kernels`) of the tracer package ``argv[1]``
#: found in folder ``argv[2]`` (an extension's tracer is ``bl_ext.<repo>.whitted.tracer``: its parent packages are
#: made empty here, so the add-on's own ``__init__`` does not run), using the bundle in folder ``argv[3]`` if not
#: empty; it prints ``PROGRESS units seconds kernel`` lines, then ``MAGIC [numba's machine tuple]``.
CHILD = r"""
import importlib, json, os, sys, types
name, path, bundle = sys.argv[1], sys.argv[2], sys.argv[3]
parts = name.split(".")
for i in range(1, len(parts)):
    parent = ".".join(parts[:i])
    if parent not in sys.modules:
        module = types.ModuleType(parent)
        module.__path__ = [os.path.dirname(path)] if i == len(parts) - 1 else []
        sys.modules[parent] = module
if len(parts) == 1:
    sys.path.insert(0, os.path.dirname(path))
cache = importlib.import_module(name + ".kernel_cache")
if bundle:
    cache.use_bundle(bundle)
jit = importlib.import_module(name + ".jit")
def report(done, kernel, seconds):
    print(f"PROGRESS {done} {seconds:.1f} {kernel}", flush=True)
with jit.CompileProgress(report):
    importlib.import_module(name + ".warmup").compile_kernels()
from numba.core.registry import cpu_target
print("MAGIC " + json.dumps(list(cpu_target.target_context.codegen().magic_tuple())), flush=True)
"""


def child_command(python: str, package: str, tracer_dir: str, bundle: str = "") -> list:
    """The command line of :data:`CHILD`."""
    return [python, "-c", CHILD, package, tracer_dir, bundle]


def build(folder: str, cpu: str = kernel_cache.BASELINE_CPU, features=kernel_cache.BASELINE_FEATURES,
          package: str = "tracer", tracer_dir: str | None = None) -> dict:
    """Compile the kernels of the tracer in ``tracer_dir`` (default: this one), imported as ``package``, for
    ``cpu`` into ``folder`` (replacing what was there); returns the manifest. The add-on's zip is built with the
    package name Blender gives an extension installed into its default repository
    (``bl_ext.user_default.whitted.tracer``): the cache pickles argument types by module name."""
    out = os.path.join(folder, kernel_cache._flavour())
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(out)
    tracer_dir = tracer_dir or os.path.dirname(os.path.abspath(__file__))
    env = dict(os.environ, NUMBA_CPU_NAME=cpu, NUMBA_CPU_FEATURES="")
    env[kernel_cache.CACHE_ENV] = folder
    start = time.perf_counter()
    proc = subprocess.run(child_command(sys.executable, package, tracer_dir), env=env, capture_output=True,
                          text=True)
    line = next((ln for ln in proc.stdout.splitlines() if ln.startswith("MAGIC ")), None)
    if proc.returncode != 0 or line is None:
        raise RuntimeError(f"compiling the kernel bundle failed:\n{proc.stderr[-3000:]}")
    for name in os.listdir(out):  # the warm-up's marker is this machine's business, not the bundle's
        if name.startswith("."):
            os.unlink(os.path.join(out, name))
    units = [ln for ln in proc.stdout.splitlines() if ln.startswith("PROGRESS ")]
    manifest = dict(magic=json.loads(line[len("MAGIC "):]), cpu=cpu, features=list(features), package=package,
                    kernels=sum(name.endswith(".nbi") for name in os.listdir(out)), units=len(units),
                    seconds=round(time.perf_counter() - start, 1))
    with open(os.path.join(out, kernel_cache.MANIFEST), "w") as f:
        json.dump(manifest, f, indent=1)
    return manifest


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tracer.kernel_bundle", description=__doc__.splitlines()[0])
    ap.add_argument("folder")
    ap.add_argument("--cpu", default=kernel_cache.BASELINE_CPU, help="LLVM CPU name of the baseline")
    ap.add_argument("--package", default="tracer", help="the name the tracer is imported by where the bundle is used")
    args = ap.parse_args(argv)
    m = build(args.folder, args.cpu, package=args.package)
    print(f"{m['kernels']} kernels for {m['cpu']} in {m['seconds']} s -> {args.folder}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

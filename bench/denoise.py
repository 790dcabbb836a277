"""``python -m bench.denoise [--width 960 --height 540] [--site DIR ...]``: the OIDN bindings measured side by side.

Each candidate runs in a fresh process (so loading is measured cold, as a ``whitted render --denoise`` pays it):

- ``ours:<library>``: tracer/denoise.py (ctypes) on each OIDN library found here — the ``bpy`` wheel's (Blender's
  OIDN) and the ``pyoidn`` wheel's;
- ``pyoidn``: the pyoidn package's own API (cffi), ``pyoidn.denoise``;
- ``oidn``: the ``oidn`` package (0.2.x, OIDN 1.4) through its ``capi`` (it wraps no parameter setter, so ``hdr`` and
  ``cleanAux`` are set through its raw library; its Linux wheel lacks the ``libtbb.so.12`` name its library needs:
  run with ``LD_LIBRARY_PATH`` at a folder holding that link).

Per candidate: seconds to import and make the device ("load"), the first denoise of a width × height picture with
albedo and normal guides (the filter's set-up included), and the best of three more ("denoise", wall seconds, and
"cpu", the process's CPU seconds over all OIDN threads: the figure other jobs on a shared machine move least). Ours is timed with
one RT filter and ``cleanAux`` (the same work as pyoidn's call) and with Cycles' "accurate" prefilter (the guides
filtered first: three filters) and as the viewport uses it ("viewport": albedo only, no prefilter, "balanced"
quality). ``--site DIR`` adds a folder of scratch installs (``pip install --target DIR``) to
the children's path. Prints one table; the figures in docs/benchmarks.md ("Denoising") come from it.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import textwrap

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

_INPUTS = """
import numpy as np
rng = np.random.default_rng(0)
h, w = {h}, {w}
y, x = np.mgrid[0:h, 0:w]
clean = np.stack([x / w, y / h, 0.5 + 0 * x], -1).astype(np.float32)
color = (clean * rng.exponential(1.0, (h, w, 1))).astype(np.float32)
albedo = clean.copy()
normal = np.zeros((h, w, 3), np.float32); normal[..., 2] = -1
"""

_OURS = """
import time
t0 = time.perf_counter()
from tracer import denoise as dn
dn.check()
load = time.perf_counter() - t0
{inputs}
def once(prefilter, quality="high", normal=normal):
    t, c = time.perf_counter(), time.process_time()
    dn.denoise(color, albedo, normal, prefilter=prefilter, quality=quality)
    return time.perf_counter() - t, time.process_time() - c
first = once("none")[0]
best = min(once("none") for _ in range(3))
accurate = min(once("accurate") for _ in range(2))
viewport = min(once("fast", "balanced", None) for _ in range(3))
print(json.dumps(dict(version=dn.version(), library=dn.library().path, load=load, first=first, denoise=best[0],
                      cpu=best[1], accurate=accurate[0], accurate_cpu=accurate[1], viewport=viewport[0],
                      viewport_cpu=viewport[1])))
"""

_PYOIDN = """
import time
t0 = time.perf_counter()
import pyoidn
{inputs}
t1 = time.perf_counter()
pyoidn.denoise(color[:8, :8].copy(), albedo[:8, :8].copy(), normal[:8, :8].copy(), hdr=True, clean_aux=True)
load = (t1 - t0) + (time.perf_counter() - t1)  # import + device (made lazily by the first call)
def once():
    t, c = time.perf_counter(), time.process_time()
    pyoidn.denoise(color, albedo, normal, hdr=True, clean_aux=True)
    return time.perf_counter() - t, time.process_time() - c
first = once()[0]
best = min(once() for _ in range(3))
import importlib.metadata as md
print(json.dumps(dict(version="pyoidn " + md.version("pyoidn"), library="(its wheel)", load=load, first=first,
                      denoise=best[0], cpu=best[1], accurate=None)))
"""

_OIDN = """
import time, ctypes
t0 = time.perf_counter()
import oidn
dev = oidn.NewDevice(1); oidn.CommitDevice(dev)
load = time.perf_counter() - t0
{inputs}
def once():
    t, c = time.perf_counter(), time.process_time()
    out = np.zeros_like(color)
    f = oidn.NewFilter(dev, "RT")
    for name, a in (("color", color), ("albedo", albedo), ("normal", normal), ("output", out)):
        oidn.SetSharedFilterImage(f, name, a, oidn.FORMAT_FLOAT3, w, h)
    setb = getattr(oidn, "__lib_oidn").oidnSetFilter1b  # (the package wraps no parameter setter: its raw library)
    setb.argtypes, setb.restype = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_bool], None
    setb(f, b"hdr", True); setb(f, b"cleanAux", True)
    oidn.CommitFilter(f); oidn.ExecuteFilter(f); oidn.ReleaseFilter(f)
    return time.perf_counter() - t, time.process_time() - c
first = once()[0]
best = min(once() for _ in range(3))
import importlib.metadata as md
print(json.dumps(dict(version="oidn " + md.version("oidn") + " (OIDN 1.4)", library="(its wheel)", load=load,
                      first=first, denoise=best[0], cpu=best[1], accurate=None)))
"""


_GUIDES = """
import time
import usd_io, tracer
from tracer import RenderSettings, render
scene, info = usd_io.load_stage("examples/whitted_1980.usda", width={w})
base = RenderSettings(width=info.width, height=info.height, threads=1)
render(scene, base.with_(width=64, height=36, aovs=tracer.denoise.GUIDE_AOVS, denoise=True))  # compile, load OIDN
def cpu(settings):
    best = None
    for _ in range(3):
        c = time.process_time()
        img = render(scene, settings)
        t = time.process_time() - c
        best = t if best is None else min(best, t)
    return best, img
plain, _ = cpu(base)
guided, _ = cpu(base.with_(aovs=tracer.denoise.GUIDE_AOVS))
denoised, img = cpu(base.with_(denoise=True))
print(json.dumps(dict(size=f"{{info.width}}x{{info.height}}", plain=plain, guided=guided, denoised=denoised,
                      filter=img.stats["denoise"]["seconds"], prefilter=img.stats["denoise"]["prefilter"])))
"""


def _run(code: str, sites, env=None) -> dict | str:
    full = dict(os.environ, **(env or {}))
    full["PYTHONPATH"] = os.pathsep.join([*sites, ROOT])
    proc = subprocess.run([sys.executable, "-c", "import json\n" + textwrap.dedent(code)], env=full, cwd=ROOT,
                          capture_output=True, text=True, timeout=600)
    if proc.returncode:
        return (proc.stderr.strip().splitlines() or ["failed"])[-1]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--width", type=int, default=960)
    ap.add_argument("--height", type=int, default=540)
    ap.add_argument("--site", action="append", default=[], help="folder of scratch installs for the children")
    args = ap.parse_args(argv)
    inputs = _INPUTS.format(h=args.height, w=args.width)
    sys.path[:0] = args.site
    from tracer import denoise as dn

    libraries = []
    for d in dn.search_dirs():
        for pattern in dn._patterns():
            import glob

            found = sorted(glob.glob(os.path.join(d, pattern)))
            if found:
                libraries.append(found[0])
                break
    rows = []
    for lib in libraries:
        rows.append((f"ours (ctypes) on {os.path.basename(os.path.dirname(os.path.dirname(lib)))}",
                     _run(_OURS.format(inputs=inputs), args.site, {dn.LIBRARY_ENV: lib})))
    rows.append(("pyoidn (cffi)", _run(_PYOIDN.format(inputs=inputs), args.site)))
    rows.append(("oidn 0.2 (ctypes)", _run(_OIDN.format(inputs=inputs), args.site)))
    print(f"{args.width}x{args.height}, colour + albedo + normal, {os.cpu_count()} cores; seconds")
    print(f"{'binding':34} {'OIDN':22} {'load':>6} {'first':>6} {'denoise':>8} {'cpu':>6} {'accurate':>9} {'cpu':>6} "
          f"{'viewport':>9} {'cpu':>6}")
    for name, r in rows:
        if isinstance(r, str):
            print(f"{name:34} unavailable: {r}")
            continue
        acc = (f"{r['accurate']:9.3f} {r['accurate_cpu']:6.2f} {r['viewport']:9.3f} {r['viewport_cpu']:6.2f}"
               if r["accurate"] is not None else f"{'-':>9} {'-':>6} {'-':>9} {'-':>6}")
        print(f"{name:34} {r['version']:22} {r['load']:6.3f} {r['first']:6.3f} {r['denoise']:8.3f} {r['cpu']:6.2f} "
              f"{acc}")
    g = _run(_GUIDES.format(w=args.width), args.site)
    if isinstance(g, str):
        print(f"guides' cost: failed: {g}")
        return 1
    print(f"\nexamples/whitted_1980.usda at {g['size']}, AA 2, one tile thread; process CPU seconds, best of 3:")
    print(f"  render {g['plain']:.2f}; with the guides {g['guided']:.2f} (+{100 * (g['guided'] / g['plain'] - 1):.1f} %); "
          f"denoised {g['denoised']:.2f} (filter {g['filter']:.2f} s wall, prefilter {g['prefilter']})")
    return 0


if __name__ == "__main__":
    sys.exit(main())

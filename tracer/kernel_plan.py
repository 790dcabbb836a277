"""The kernel plan: which stage kernels a render compiles, in order, with their argument types, so that an empty
kernel cache is filled by two processes at once and the first render's progress has a total.

A render compiles its kernels as it first calls them (tracer/jit.py), one unit after another on one core: on a
fresh machine that is nearly all of the first render's time (docs/benchmarks.md, "Ready at install"). numba compiles
a function only when it sees the argument types, so nothing can compile a stage ahead of the call, unless the
types are known. The plan records them: ``kernel_plan.json`` beside this module lists the stages
(``module.qualname``) that rendering the bundled example compiled, first use first, with their argument types
(numba types, pickled and compressed) and the compile units each brought in. It is made by ``python -m tools.kernel_plan`` with an
empty cache.

With a plan, :func:`start` runs :func:`prepare` in a second process, which compiles the plan's stages last one
first while the render compiles from the first; the two meet in the middle. They never compile the same unit twice:
a process that misses a kernel in the cache takes that kernel's lock (tracer/kernel_cache.py) and looks again once
it holds it, so it loads what the other one just saved. Where a render needs something the plan lacks (another
scene's stages), it compiles that itself, as without a plan; where the plan no longer fits the code (a stage's
arguments changed and the plan was not made again), that stage is skipped in the second process, which costs only
the time it would have saved.
"""

from __future__ import annotations

import base64
import hashlib
import importlib
import io
import json
import os
import pickle
import signal
import subprocess
import sys
import threading
import zlib

from . import jit, kernel_cache
from .accel import embree

#: The plan shipped with the tracer (made by ``python -m tools.kernel_plan``).
PLAN = os.path.join(os.path.dirname(os.path.abspath(__file__)), "kernel_plan.json")
#: Environment variable: set to 0 to compile in the render's process only.
PARALLEL_ENV = "WHITTED_COMPILE_PROCESSES"
_PACKAGE = __package__ or "tracer"  # "tracer", or the add-on's bl_ext.<repo>.whitted.tracer (also as __main__)


class _Unpickler(pickle.Unpickler):
    """Argument types name the tracer's classes (queues are named tuples) as ``tracer.<module>``; inside Blender the
    tracer is ``bl_ext.<repo>.whitted.tracer``."""

    def find_class(self, module, name):
        if module == "tracer" or module.startswith("tracer."):
            module = _PACKAGE + module[len("tracer"):]
        return super().find_class(module, name)


def load(path: str = PLAN) -> dict | None:
    """The plan in ``path``: ``{"stages": [(kernel, argument types, units)], "units": total}``, or None where there is
    none, or it was made with another numba or Python (argument types are numba's)."""
    try:
        with open(path) as f:
            doc = json.load(f)
    except (OSError, ValueError):
        return None
    if doc.get("tools") != list(kernel_cache._TOOLS[:2]):
        return None
    stages = []
    for entry in doc.get("stages", ()):
        try:
            args = _Unpickler(io.BytesIO(zlib.decompress(base64.b64decode(entry["args"])))).load()
        except Exception:  # a class the plan names is gone: the stage is skipped (see the module)
            continue
        stages.append((entry["kernel"], args, int(entry.get("units", 1))))
    return {"stages": stages, "units": int(doc.get("units", 0)), "digest": _digest(doc)}


def _digest(doc: dict) -> str:
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()[:16]


class Recorder:
    """Records the stages compiled while it is installed (numba's ``numba:compile`` events), in order, with their
    argument types and the units each brought in (itself and the helpers it compiled first)."""

    def __init__(self):
        import numba.core.event

        self._event = numba.core.event
        self.stages: list = []
        self._units = 0

    def on_start(self, event):
        pass

    def on_end(self, event):
        d = event.data.get("dispatcher")
        f = getattr(d, "py_func", None)
        if f is None or not kernel_cache._ours(f.__module__) or getattr(event, "_exc_details", None) is not None:
            return
        self._units += 1
        if d.targetoptions.get("no_cpython_wrapper"):  # a helper: compiled by the stage that calls it
            return
        name = f"{f.__module__}.{f.__qualname__}".replace(_PACKAGE + ".", "tracer.", 1)
        self.stages.append((name, tuple(event.data["args"]), self._units))
        self._units = 0

    def __enter__(self):
        import numba.core.event

        listener = type("_L", (numba.core.event.Listener,), {"on_start": self.on_start, "on_end": self.on_end})()
        self._listener = listener
        numba.core.event.register("numba:compile", listener)
        return self

    def __exit__(self, *exc):
        self._event.unregister("numba:compile", self._listener)

    def document(self, made_from: list) -> dict:
        """The plan as written to :data:`PLAN`."""
        stages = [dict(kernel=k, args=base64.b64encode(zlib.compress(pickle.dumps(a, protocol=4), 9)).decode(), units=u)
                  for k, a, u in self.stages]
        return dict(tools=list(kernel_cache._TOOLS[:2]), made_from=made_from, units=sum(u for *_, u in self.stages),
                    stages=stages)


# ---------------------------------------------------------------------------------------------- the second process
def _kernel(name: str):
    module, _, qualname = name.replace("tracer.", _PACKAGE + ".", 1).rpartition(".")
    return getattr(importlib.import_module(module), qualname)


def prepare(plan: dict, status: str | None = None, parent: int | None = None) -> bool:
    """Compile (or load) the plan's stages, the last first; writes the number of units compiled so far to
    ``status`` after each, and stops early when process ``parent`` has gone or on SIGTERM (between stages: a
    stage's files are written whole). True when it went through the whole plan."""
    embree.library()  # the LLVM symbols Embree's calls in kernels link against
    stop = []
    signal.signal(signal.SIGTERM, lambda *a: stop.append(1))
    done = [0]

    def count(n, unit, *_):
        done[0] = n

    with jit.CompileProgress(count):
        for name, args, _units in reversed(plan["stages"]):
            if stop or (parent is not None and os.getppid() != parent):
                return False
            try:
                _kernel(name).dispatcher.compile(args)
            except Exception:  # a stale entry (see the module): the render compiles what it needs itself
                continue
            if status:
                _write(status, done[0])
    return True


def _write(path: str, n: int) -> None:
    tmp = f"{path}.{os.getpid()}.tmp"
    with open(tmp, "w") as f:
        f.write(str(n))
    os.replace(tmp, path)


def _done_marker(plan: dict) -> str:
    """Written once the plan has been worked through for this version of the tracer's sources."""
    return os.path.join(kernel_cache.cache_root(), f".plan-{plan['digest']}-{jit.sources_digest()}")


class Helper:
    """The second compiling process of one render (:func:`start`): its units so far (:meth:`units`), and
    :meth:`stop`."""

    def __init__(self, proc, status: str, total: int):
        self.proc, self.status, self.total = proc, status, total

    def units(self) -> int:
        try:
            with open(self.status) as f:
                return int(f.read() or 0)
        except (OSError, ValueError):
            return 0

    def stop(self) -> None:
        """Ask it to stop (it finishes the stage it is compiling, so no file is left half-written)."""
        if self.proc.poll() is None:
            try:
                self.proc.send_signal(signal.SIGTERM)
            except OSError:
                pass
            # reaped on a daemon thread: the render does not wait for it, and it is never left a zombie
            threading.Thread(target=self.proc.wait, name="whitted-kernel-plan-reaper", daemon=True).start()
        try:
            os.unlink(self.status)
        except OSError:
            pass


def start() -> Helper | None:
    """Start the second compiling process where it can help: a plan that fits this numba, a version of the tracer
    whose plan has not been worked through on this machine yet, no kernels shipped inside the package, more than one
    core, and ``WHITTED_COMPILE_PROCESSES`` not 0. None otherwise."""
    if os.environ.get(PARALLEL_ENV, "2") in ("0", "1") or (os.cpu_count() or 1) < 2:
        return None
    if os.path.isdir(kernel_cache.PACKAGED):  # an installed package with its kernels inside compiles nothing
        return None
    plan = load()
    if plan is None or not plan["stages"] or os.path.exists(_done_marker(plan)):
        return None
    root = kernel_cache.cache_root()
    status = os.path.join(root, f".plan-status-{os.getpid()}")
    try:
        os.makedirs(root, exist_ok=True)
        _write(status, 0)
    except OSError:  # a cache folder this user cannot write: the render compiles alone (and says so when saving)
        return None
    proc = subprocess.Popen([sys.executable, "-m", f"{_PACKAGE}.kernel_plan", status, str(os.getpid())],
                            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    return Helper(proc, status, plan["units"])


def main(argv=None) -> int:
    """``python -m tracer.kernel_plan STATUS PARENT_PID``: :func:`prepare` the shipped plan (the second process of
    :func:`start`); writes the done marker when the whole plan is in the cache."""
    argv = sys.argv[1:] if argv is None else argv
    plan = load()
    if plan is None:
        return 0
    status, parent = argv[0], int(argv[1])
    if prepare(plan, status, parent):
        open(_done_marker(plan), "w").close()
    return 0


if __name__ == "__main__":
    sys.exit(main())

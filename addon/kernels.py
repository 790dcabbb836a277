"""The tracer's kernels, made ready without ever blocking Blender: shipped ones loaded, the rest compiled in a child.

numba compiles while holding Python's GIL, and its garbage (millions of IR objects) makes the collector pause the
whole interpreter: a compile on a background thread of Blender still froze its UI for seconds (docs/benchmarks.md).
So nothing compiles inside Blender's process:

1. At ``register()``, :func:`start` points the tracer at the kernels shipped in the add-on's zip (``kernels/``, built
   by ``python -m addon.build`` for a portable x86-64 baseline: :mod:`tracer.kernel_bundle`) and, unless this version's
   kernels are all in the user's kernel cache already, starts a child process (Blender's own Python, the same
   ``sys.path``) that runs :func:`tracer.compile_kernels` into that cache (``~/.cache/whitted/kernels``: outside the
   extension folder, so an update keeps every kernel it did not change). With a matching bundle the child only
   copies files; elsewhere (another CPU family, macOS, Windows) it compiles.
2. A render that starts before the child is done waits for it (:func:`wait`, sleeping, Esc-able) with the child's
   progress in Blender's status (:func:`status`); then every kernel loads from the cache.

If the child cannot run at all, the kernels compile in Blender's process as they are first used (the old way),
with one warning.
"""

from __future__ import annotations

import functools
import os
import subprocess
import sys
import threading
import time

from .bundled import tracer, tracer_module

class _State:
    started = False
    proc: subprocess.Popen | None = None
    thread: threading.Thread | None = None
    done = 0
    seconds = 0.0
    last = ""
    error: str | None = None
    finished = threading.Event()


_state = _State()
_LOCK = threading.Lock()


def bundle_folder() -> str:
    """Where the zip's shipped kernels are (beside the bundled tracer)."""
    return os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(tracer.__file__))), "kernels")


@functools.lru_cache(maxsize=1)
def expected_units() -> int | None:
    """How many compile units the bundle's manifest counted (an estimate of a compile's length), or None; read
    once (the status line asks ten times a second)."""
    import json

    cache = tracer_module("kernel_cache")
    try:
        with open(os.path.join(bundle_folder(), cache._flavour(), cache.MANIFEST)) as f:
            return int(json.load(f).get("units", 0)) or None
    except (OSError, ValueError):
        return None


def start() -> None:
    """Use the shipped kernels where they fit, and prepare the rest in a child process (at once, non-blocking)."""
    with _LOCK:
        if _state.started:
            return
        _state.started = True
    cache = tracer_module("kernel_cache")
    folder = bundle_folder()
    cache.use_bundle(folder)
    if tracer_module("jit").kernels_cached():
        _state.finished.set()
        return
    _state.finished.clear()
    _state.thread = threading.Thread(target=_run_child, args=(folder,), name="whitted-kernels", daemon=True)
    _state.thread.start()


def _run_child(folder: str) -> None:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    cmd = tracer_module("kernel_bundle").child_command(_python(), tracer.__name__,
                                                       os.path.dirname(os.path.abspath(tracer.__file__)),
                                                       folder if os.path.isdir(folder) else "")
    try:
        _state.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
        if hasattr(os, "setpriority"):  # below Blender's own threads: the UI and a render in progress come first
            try:
                os.setpriority(os.PRIO_PROCESS, _state.proc.pid, 10)
            except OSError:
                pass
        for line in _state.proc.stdout:
            if line.startswith("PROGRESS "):
                _, done, seconds, name = line.split(" ", 3)
                _state.done, _state.seconds, _state.last = int(done), float(seconds), name.strip()
        err = _state.proc.stderr.read()
        if _state.proc.wait() != 0:
            _state.error = err.strip().splitlines()[-1] if err.strip() else f"exit {_state.proc.returncode}"
    except OSError as exc:
        _state.error = str(exc)
    finally:
        _state.finished.set()
    if _state.error:
        print(f"Whitted: preparing the kernels in a separate process failed ({_state.error}); they compile in "
              f"Blender as renders first use them")


def _python() -> str:
    """Blender's Python interpreter (``sys.executable`` is Blender's binary in older Blenders)."""
    exe = sys.executable
    if os.path.basename(exe).lower().startswith("python"):
        return exe
    import glob

    found = sorted(glob.glob(os.path.join(sys.prefix, "bin", "python3*")))
    return found[0] if found else exe


def ready() -> bool:
    start()  # (a no-op after register(); a render engine registered on its own, as tests do, starts it here)
    return _state.finished.is_set()


def status() -> str:
    """A line for Blender's status bar while the kernels are being prepared."""
    total = expected_units()
    of = f" of about {total}" if total else ""
    return (f"Whitted: preparing kernels (first use of this version; in a separate process): {_state.done}{of} "
            f"compiled, {_state.seconds:.0f} s")


def wait(cancelled=lambda: False, on_status=lambda text: None, poll: float = 0.1) -> bool:
    """Wait (sleeping: Blender's UI keeps running) until the kernels are ready; False if cancelled first."""
    start()
    while not _state.finished.wait(poll):
        if cancelled():
            return False
        on_status(status())
    return True


def stop() -> None:
    """At unregister: end a child that is still compiling (what it compiled so far stays cached)."""
    proc = _state.proc
    if proc is not None and proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(5)
        except subprocess.TimeoutExpired:
            proc.kill()

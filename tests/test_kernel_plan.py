"""The kernel plan and the per-kernel compile lock (tracer/kernel_plan.py, tracer/kernel_cache.py): a cold cache is
filled by two processes that never compile the same unit twice, and the shipped plan covers the bundled example."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import time

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE = os.path.join(ROOT, "examples", "whitted_1980.usda")


def _run(code: str, cache: str, *args, timeout=600, **env) -> subprocess.CompletedProcess:
    full = dict(os.environ, WHITTED_KERNEL_CACHE=cache, WHITTED_COMPILE_PROCESSES="0", PYTHONPATH=ROOT, **env)
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code), *args], env=full, cwd=ROOT,
                          capture_output=True, text=True, timeout=timeout)


def test_shipped_plan_covers_the_bundled_example(tmp_path):
    """Every stage kernel and argument types the bundled example's render uses is in the shipped plan: a stale
    plan would leave the second process compiling what no render asks for (tools/kernel_plan.py makes it again)."""
    code = """
        import json, sys
        import usd_io.cli as cli
        assert cli.main(["render", sys.argv[1], "-o", sys.argv[2], "--quiet", "--width", "64", "--height", "36"]) == 0
        from tracer import kernel_plan
        from tracer.jit import Kernel
        used = []
        for name, module in list(sys.modules.items()):
            if not name.startswith("tracer"):
                continue
            for k in vars(module).values():
                if isinstance(k, Kernel) and k._made is not None and not k._opts.get("no_cpython_wrapper"):
                    used += [(f"{k.__module__}.{k.__qualname__}", str(sig)) for sig in k._made.signatures]
        plan = {(n, str(tuple(a))) for n, a, _ in kernel_plan.load()["stages"]}
        print(json.dumps(sorted(set(used) - plan)))
    """
    cache = os.path.join(ROOT, ".cache", "kernels")  # the suite's own cache (tests/conftest.py)
    out = str(tmp_path / "plan-test.png")
    proc = _run(code, cache, SCENE, out)
    assert proc.returncode == 0, proc.stderr[-2000:]
    missing = json.loads(proc.stdout.strip().splitlines()[-1])
    assert not missing, f"the shipped plan lacks {missing}: run python -m tools.kernel_plan"


def test_plan_loads_with_its_argument_types():
    from tracer import kernel_plan

    plan = kernel_plan.load()
    assert plan is not None and plan["stages"], "tracer/kernel_plan.json missing or made with another numba"
    names = [n for n, _a, _u in plan["stages"]]
    assert "tracer.integrator.wavefront._direct_light" in names and "tracer.accel.embree.intersect_rays" in names
    assert plan["units"] == sum(u for *_x, u in plan["stages"]) > len(names)


# A process that compiles one of the plan's cheap stages, as the "holder" (it takes the kernel's lock first and
# waits until the other process queues for it) or the "waiter" (it says when it queues); then prints the
# dispatcher's cache hits and misses.
COMPILE = """
    import os, sys, time
    from tracer import kernel_cache, kernel_plan
    role, signal = sys.argv[1], sys.argv[2]
    name = "tracer.scene_kernels.unit_rows"
    args = next(a for n, a, _u in kernel_plan.load()["stages"] if n == name)
    k = kernel_plan._kernel(name)
    if role == "holder":  # takes the kernel's lock as a compiling process does, and waits for the other to queue
        cache = k.dispatcher._cache
        assert kernel_cache._lock(cache._cache_path, cache._impl.filename_base)
        open(signal + ".locked", "w").close()  # the waiter starts only now
        deadline = time.monotonic() + 120
        while not os.path.exists(signal) and time.monotonic() < deadline:
            time.sleep(0.01)
        print("queued" if os.path.exists(signal) else "nobody queued")
    else:  # says when it is about to wait for the lock (it has missed the kernel once by then)
        real = kernel_cache._lock
        def lock(folder, base):
            if "unit_rows" in base:
                open(signal, "w").close()
            return real(folder, base)
        kernel_cache._lock = lock
    k.dispatcher.compile(args)
    s = k.dispatcher.stats
    print("hits", sum(s.cache_hits.values()), "misses", sum(s.cache_misses.values()))
"""


def test_second_process_waits_for_the_first_and_loads_its_unit(tmp_path):
    """While one process holds a kernel's lock (compiling it), another that misses the kernel waits, then loads
    what the first saved instead of compiling it too."""
    cache, signal = str(tmp_path / "kernels"), str(tmp_path / "queued")
    env = dict(os.environ, WHITTED_KERNEL_CACHE=cache, WHITTED_COMPILE_PROCESSES="0", PYTHONPATH=ROOT)
    holder = subprocess.Popen([sys.executable, "-c", textwrap.dedent(COMPILE), "holder", signal], env=env, cwd=ROOT,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        while not os.path.exists(signal + ".locked") and holder.poll() is None:  # the holder has the lock first
            time.sleep(0.01)
        waiter = _run(COMPILE, cache, "waiter", signal)
    finally:
        out, err = holder.communicate(timeout=600)
    assert holder.returncode == 0, err[-2000:]
    assert waiter.returncode == 0, waiter.stderr[-2000:]
    assert out.splitlines()[0] == "queued", out
    assert out.splitlines()[-1] == "hits 0 misses 1"  # the holder compiled it
    assert waiter.stdout.splitlines()[-1] == "hits 1 misses 0", waiter.stdout  # the waiter loaded it


def test_a_failed_compile_drops_its_lock():
    """A compile that raises never reaches save: its lock is dropped at once (else another process would wait
    LOCK_WAIT seconds for it). numba 0.68's Event.is_failed is inverted, so this is not numba's flag."""
    import numpy as np
    from numba.core.errors import TypingError

    from tracer import kernel_cache
    from tracer.scene_kernels import unit_rows

    out = np.zeros((2, 3), np.float32)
    with pytest.raises(TypingError):
        unit_rows("not an array", out, 0, 2)  # compiled for a str: typing fails
    assert not kernel_cache._HELD
    unit_rows(np.ones((2, 3), np.float32), out, 0, 2)  # a good compile saves, and drops its lock too
    assert not kernel_cache._HELD and out[0, 0] == pytest.approx(3 ** -0.5)


def test_second_process_goes_through_the_plan_and_marks_it_done(tmp_path):
    """``python -m tracer.kernel_plan`` compiles the plan into an empty cache (last stage first), counts its
    units in the status file and leaves the done marker; a render then compiles nothing, and start() stays put."""
    cache = str(tmp_path / "kernels")
    code = """
        import os, subprocess, sys
        from tracer import kernel_plan
        status = sys.argv[1]
        proc = subprocess.run([sys.executable, "-m", "tracer.kernel_plan", status, str(os.getpid())])
        assert proc.returncode == 0
        plan = kernel_plan.load()
        print("units", open(status).read(), "of", plan["units"])
        print("marker", os.path.exists(kernel_plan._done_marker(plan)))
        os.environ["WHITTED_COMPILE_PROCESSES"] = "2"
        print("start", kernel_plan.start())
    """
    proc = _run(code, cache, str(tmp_path / "status"))
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stdout.splitlines()
    units, total = int(lines[0].split()[1]), int(lines[0].split()[3])
    assert units >= total * 0.9, lines  # every unit of the plan (a few more or fewer where helpers are shared)
    assert lines[1:] == ["marker True", "start None"]
    render = """
        import sys
        from tracer.jit import CompileProgress
        import usd_io.cli as cli
        with CompileProgress(lambda *a: None) as p:
            assert cli.main(["render", sys.argv[1], "-o", sys.argv[2], "--quiet", "--width", "64", "--height", "36"]) == 0
        print("compiled", p.done)
    """
    proc = _run(render, cache, SCENE, str(tmp_path / "x.png"))
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.splitlines()[-1] == "compiled 0"


def test_progress_counts_both_processes():
    from usd_io.cli import compile_status

    class Helper:
        total = 120

        def units(self):
            return 40

    assert compile_status(20, 6.0) == "20 units in 6 s"
    assert compile_status(20, 6.0, Helper()) == "60 of about 120 units in 6 s, about 6 s left (2 processes)"
    Helper.units = lambda self: 110
    assert compile_status(20, 6.0, Helper()) == "130 units in 6 s (2 processes)"

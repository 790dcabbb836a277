"""``python -m bench.farm``: the Dask farm against a plain local render of the same frames (issue #29, "Farm workers
stay ready"), measured in one run, interleaved, on this machine.

Two comparisons, each a ratio of frames/s (farm / local; ≥ 0.90 is the target):

- **cli** — whole processes, as a user runs them: ``whitted render SCENE --frames 1:N --width W -o DIR/f.####.png``
  with ``--threads 2`` (local) against ``--scheduler local:2`` (two one-thread worker processes started by the
  command). Wall seconds of the process, and its CPU seconds with every child's (the workers are reaped by it).
- **warm** — a cluster already up (a farm that stays up between jobs: ``tcp://``), workers warmed on *another* stage
  size (imports, kernel cache, nothing of this job), against ``tracer.render`` of the same frames in this process on
  two threads (stage read + render per frame, as ``whitted render --frames`` does). Both sides return images (the
  farm's travel back to the client); neither writes files.

Per-frame costs on the workers (``image.stats["farm"]``: prepare = stage read / session lookup, build = Embree, render)
are printed for the warm runs, so what a frame pays again is visible. ``--stage animated`` uses a copy of the 1980
scene whose mirror sphere moves (time samples): every frame then has its own geometry.

    python -m bench.farm [--frames 8] [--width 480] [--runs 3] [--only cli,warm] [--stage whitted|animated]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE = os.path.join(ROOT, "examples", "whitted_1980.usda")


def animated_stage(folder: str) -> str:
    """The 1980 scene with its mirror sphere moving along x over frames 1..24 (time samples on a translate op)."""
    from pxr import Gf, Usd, UsdGeom

    path = os.path.join(folder, "whitted_animated.usda")
    stage = Usd.Stage.Open(SCENE)
    stage.Export(path)
    stage = Usd.Stage.Open(path)
    ball = UsdGeom.Xformable(stage.GetPrimAtPath("/World/MirrorSphere"))
    op = ball.AddTranslateOp(opSuffix="move")
    op.Set(Gf.Vec3d(-0.3, 0, 0), 1.0)
    op.Set(Gf.Vec3d(0.3, 0, 0), 24.0)
    stage.GetRootLayer().Save()
    return path


# ------------------------------------------------------------------------------------------------------ cli
def _child_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _subreaper() -> None:
    """Become the reaper of orphaned descendants (Linux ``PR_SET_CHILD_SUBREAPER``): a forkserver's workers outlive
    the command's own wait, and their CPU counts only once they are reaped here (:func:`_reap`)."""
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(36, 1, 0, 0, 0)
    except (OSError, AttributeError):
        pass


def _reap(deadline: float = 10.0) -> None:
    """Wait for every descendant left (see :func:`_subreaper`), so RUSAGE_CHILDREN has their CPU."""
    end = time.monotonic() + deadline
    while time.monotonic() < end:
        try:
            pid, _ = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return
        if pid == 0:
            time.sleep(0.02)


def cli_run(scene: str, frames: int, width: int, out: str, farm: bool) -> tuple[float, float]:
    """(wall, CPU) seconds of one ``whitted render`` process (children and every other descendant included)."""
    cmd = [sys.executable, "-m", "usd_io.cli", "render", scene, "-o", os.path.join(out, "f.####.png"),
           "--frames", f"1:{frames}", "--width", str(width), "--quiet"]
    cmd += ["--scheduler", "local:2"] if farm else ["--threads", "2"]
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    c0, t0 = _child_cpu(), time.perf_counter()
    r = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    _reap()
    cpu = _child_cpu() - c0
    if r.returncode:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{r.stderr[-3000:]}")
    return wall, cpu


# ------------------------------------------------------------------------------------------------------ warm
def _cluster(n):
    try:
        from tracer.farm import local_cluster
    except ImportError:  # a checkout from before local_cluster: the cluster its `--scheduler local:N` started
        import logging

        from dask.distributed import Client, LocalCluster

        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                               dashboard_address="127.0.0.1:0", silence_logs=logging.ERROR)
        return Client(cluster), cluster
    return local_cluster(n)  # as `--scheduler local:N` starts it


def _worker_cpu():
    return time.process_time()


def local_frames(scene: str, frames: list, width: int, say: bool = True) -> tuple[float, float]:
    import tracer
    from usd_io.farm import UsdSource

    source = UsdSource(path=scene, width=width, settings=dict(threads=2, progress=False))
    c0, t0 = time.process_time(), time.perf_counter()
    load = 0.0
    for f in frames:
        c = time.process_time()
        scene, settings = source.load(f)
        load += time.process_time() - c
        tracer.render(scene, settings)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    if say:
        print(f"  local CPU {cpu:.2f} s: stage reads {load:.2f}, renders {cpu - load:.2f}", flush=True)
    return wall, cpu


def farm_frames(client, scene: str, frames: list, width: int) -> tuple[float, float, list]:
    from tracer.farm import render_frames
    from usd_io.farm import UsdSource

    source = UsdSource(path=scene, width=width, settings=dict(threads=1))
    w0 = sum(client.run(_worker_cpu).values())
    c0, t0 = time.process_time(), time.perf_counter()
    results = list(render_frames(client, source, frames))
    wall = time.perf_counter() - t0
    client_cpu = time.process_time() - c0
    workers_cpu = sum(client.run(_worker_cpu).values()) - w0
    cpu = client_cpu + workers_cpu
    farm = [r.image.stats.get("farm", {}) for r in results]  # (a checkout before the stats: none)
    tasks = sum(s.get("prepare_cpu", 0.0) + s.get("render_cpu", 0.0) for s in farm)
    print(f"  farm CPU {cpu:.2f} s: client (scheduler, results) {client_cpu:.2f}, workers {workers_cpu:.2f} "
          f"(of which the tasks' threads {tasks:.2f})", flush=True)
    bad = [r.error for r in results if r.error]
    if bad:
        raise SystemExit(f"farm frames failed: {bad}")
    return wall, cpu, [r.image.stats.get("farm", {}) for r in results]


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m bench.farm", description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--width", type=int, default=480)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--only", default="cli,warm")
    ap.add_argument("--stage", default="whitted", choices=("whitted", "animated"))
    a = ap.parse_args(argv)
    only = a.only.split(",")
    frames = [float(f) for f in range(1, a.frames + 1)]
    with tempfile.TemporaryDirectory() as d:
        scene = SCENE if a.stage == "whitted" else animated_stage(d)
        print(f"bench.farm: {a.frames} frames of {os.path.basename(scene)} at width {a.width}, local 2 threads vs "
              f"local:2 (one-thread workers), {a.runs} runs interleaved, {os.cpu_count()} cores, load "
              f"{os.getloadavg()[0]:.1f}", flush=True)
        if "cli" in only:
            _subreaper()
            out = os.path.join(d, "out")
            os.makedirs(out)
            cli_run(scene, 2, 64, out, False)  # kernels cached, files in the OS cache
            rows = {"local": [], "farm": []}
            for _ in range(a.runs):
                for side in ("local", "farm"):
                    rows[side].append(cli_run(scene, a.frames, a.width, out, side == "farm"))
            _report("cli (whole `whitted render` processes)", rows, a.frames)
        if "warm" in only:
            from tracer.farm import render_frames
            from usd_io.farm import UsdSource

            client, cluster = _cluster(2)
            try:
                # Warm both sides on another size of the stage: imports, kernels, the stage opened (not this job).
                list(render_frames(client, UsdSource(path=scene, width=16, settings=dict(threads=1)),
                                   [float(f) for f in range(4)]))
                local_frames(scene, frames[:1], 16, say=False)
                rows = {"local": [], "farm": []}
                per_frame = []
                for _ in range(a.runs):
                    rows["local"].append(local_frames(scene, frames, a.width))
                    wall, cpu, stats = farm_frames(client, scene, frames, a.width)
                    rows["farm"].append((wall, cpu))
                    per_frame.append(stats)
                _report("warm (cluster up and warmed; in-process local loop)", rows, a.frames)
                _per_frame(per_frame[-1])
            finally:
                client.close()
                cluster.close()


def _report(title, rows, n):
    med = lambda xs: statistics.median(xs)  # noqa: E731
    lw, lc = med([w for w, _ in rows["local"]]), med([c for _, c in rows["local"]])
    fw, fc = med([w for w, _ in rows["farm"]]), med([c for _, c in rows["farm"]])
    ratios = [l[0] / f[0] for l, f in zip(rows["local"], rows["farm"])]
    print(f"\n{title}")
    print("| side | wall s (median) | frames/s | CPU s (median) | runs (wall) |")
    print("| --- | --- | --- | --- | --- |")
    for side, w, c in (("local, 2 threads", lw, lc), ("farm, local:2", fw, fc)):
        key = "local" if side.startswith("local") else "farm"
        print(f"| {side} | {w:.2f} | {n / w:.2f} | {c:.2f} | {', '.join(f'{x:.2f}' for x, _ in rows[key])} |")
    print(f"farm / local speed: wall {lw / fw:.0%} (per run: {', '.join(f'{r:.0%}' for r in ratios)}), "
          f"CPU {lc / fc:.0%}", flush=True)


def _per_frame(stats):
    if not stats or not stats[0]:
        return
    print("per frame on the workers (last warm run): " + "; ".join(
        f"{s.get('reused') or 'loaded'}: prepare {s.get('prepare_cpu', 0) * 1e3:.0f} ms, render "
        f"{s.get('render_cpu', 0) * 1e3:.0f} ms CPU" for s in stats), flush=True)


if __name__ == "__main__":
    main()

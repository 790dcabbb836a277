"""``python -m bench.farm``: the Dask farm on this machine — frames/s on local:1 vs local:2 (workers writing their
frames, as --worker-writes), per-task overhead, and what a client-written frame costs the client (receive + PNG
encode), measured in one run. Numbers go to docs/benchmarks.md.

Each task renders with one thread so the worker count is the only parallelism being compared.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE = os.path.join(ROOT, "examples", "whitted_1980.usda")


def _cluster(n):
    from dask.distributed import Client, LocalCluster

    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address="127.0.0.1:0", silence_logs=logging.ERROR)
    return Client(cluster), cluster


def _noop(i):
    return i


def frames_per_second(n_workers, frames, width, spp, out_dir):
    from tracer.farm import render_frames
    from usd_io.farm import UsdSource

    client, cluster = _cluster(n_workers)
    try:
        source = UsdSource(path=SCENE, width=width, settings=dict(samples=spp, threads=1))
        # Warm every worker (imports, kernel cache load, stage open) outside the timed run, as a farm would be.
        list(render_frames(client, UsdSource(path=SCENE, width=16, settings=dict(threads=1)),
                           [float(f) for f in range(n_workers * 2)]))
        from usd_io.farm import WriteFrames

        # Throughput as a farm should run: the workers write their frames (--worker-writes).
        start = time.perf_counter()
        list(render_frames(client, source, [float(f) for f in range(frames)],
                           write=WriteFrames(os.path.join(out_dir, "f.####.png"), True)))
        elapsed = time.perf_counter() - start
        # What a client-written frame costs the client (receive + encode), measured separately.
        write = 0.0
        for res in render_frames(client, source, [0.0, 1.0]):
            t = time.perf_counter()
            res.image.save(os.path.join(out_dir, f"c{int(res.frame):04d}.png"))
            write += time.perf_counter() - t
        # Per-task overhead: round trips of empty tasks through the scheduler.
        n = 400
        t = time.perf_counter()
        client.gather(client.map(_noop, range(n), pure=False))
        overhead = (time.perf_counter() - t) / n
        return frames / elapsed, overhead, write / 2
    finally:
        client.close()
        cluster.close()


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m bench.farm")
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--spp", type=int, default=2)
    a = ap.parse_args(argv)
    print(f"bench.farm: {a.frames} frames of {os.path.basename(SCENE)} at width {a.width}, {a.spp}x{a.spp} AA, "
          f"1 thread per task, {os.cpu_count()} cores", flush=True)
    with tempfile.TemporaryDirectory() as d:
        fps1, over1, write1 = frames_per_second(1, a.frames, a.width, a.spp, d)
        fps2, over2, write2 = frames_per_second(2, a.frames, a.width, a.spp, d)
    print(f"| workers | frames/s | speed-up | per-task overhead | client write per frame |")
    print(f"| --- | --- | --- | --- | --- |")
    print(f"| local:1 | {fps1:.2f} | 1.00x | {over1 * 1e3:.1f} ms | {write1 * 1e3:.0f} ms |")
    print(f"| local:2 | {fps2:.2f} | {fps2 / fps1:.2f}x | {over2 * 1e3:.1f} ms | {write2 * 1e3:.0f} ms |")
    sys.stdout.flush()


if __name__ == "__main__":
    main()

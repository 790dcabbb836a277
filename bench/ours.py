"""Our tracer and raw embreex, measured in a child process (``python -m bench.ours ...`` prints one JSON object).

Timed runs call :func:`tracer.render` without recording. A separate run with ``extra={"record_rays": True}`` captures
the ray batches exactly as the integrator traced them, and :func:`replay` sends the same batches through a bare
embreex scene on the same number of threads (batches handed to a thread pool, as our tiles are).

Our time split (thread-seconds, summed over worker threads, from the timed runs):

- intersection = ``image.stats["intersect_seconds"]`` (time inside Embree queries)
- shading = time inside ``Integrator.trace`` minus intersection (hit geometry, materials, lights, spawning rays)
- overhead = threads × wall − time in ``Integrator.trace`` (eye-ray generation, film, tile dispatch, idle threads,
  BVH build)
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

import tracer
from tracer import RenderSettings
from tracer.integrator import Integrator

from . import scenes


class TraceTimer:
    """Wraps ``Integrator.trace`` to sum the thread-seconds spent in it (the tracer itself is not modified)."""

    def __init__(self):
        self.seconds = 0.0
        self._lock = threading.Lock()
        self._orig = Integrator.trace

    def __enter__(self):
        orig, timer = self._orig, self

        def timed(integ, *a, **kw):
            t0 = time.perf_counter()
            try:
                return orig(integ, *a, **kw)
            finally:
                with timer._lock:
                    timer.seconds += time.perf_counter() - t0

        Integrator.trace = timed
        return self

    def __exit__(self, *exc):
        Integrator.trace = self._orig


def replay(scene, batches, threads: int, runs: int = 3) -> dict:
    """Trace ``batches`` [(query, origins, directions, t_max)] with raw embreex; median wall seconds of ``runs``."""
    emb = rtcore_scene.EmbreeScene()
    tris = np.ascontiguousarray(scene.vertices[scene.triangles], dtype=np.float32)
    TriangleMesh(emb, tris)
    n_rays = int(sum(len(b[1]) for b in batches))

    def prepared():
        out = []
        for q, o, d, t in batches:
            if q == "OCCLUDED":
                out.append((q, o, d, np.ascontiguousarray(t, np.float32).copy()))
            else:
                out.append((q, o, d, None if t is None else np.ascontiguousarray(t, np.float32).copy()))
        return out

    def one(b):
        q, o, d, t = b
        if q == "OCCLUDED":
            emb.run(o, d, dists=t, query="OCCLUDED")
        elif t is None:
            emb.run(o, d, output=1)
        else:
            emb.run(o, d, output=1, dists=t)

    times = []
    with ThreadPoolExecutor(max_workers=threads) as pool:
        for _ in range(runs):
            work = prepared()
            t0 = time.perf_counter()
            list(pool.map(one, work))
            times.append(time.perf_counter() - t0)
    med = statistics.median(times)
    return {"seconds": med, "times": times, "rays": n_rays, "batches": len(batches),
            "rays_per_second": n_rays / med if med > 0 else 0.0}


def measure(name: str, width: int, height: int, threads: int, runs: int, samples: int = 1, max_depth: int = 8,
            record: bool = True, image: str | None = None) -> dict:
    bs = scenes.build(name)
    scene = scenes.to_tracer(bs, width, height)
    settings = RenderSettings(width=width, height=height, samples=samples, max_depth=max_depth, threads=threads)
    times, splits, stats = [], [], None
    for _ in range(runs):
        with TraceTimer() as tt:
            t0 = time.perf_counter()
            img = tracer.render(scene, settings)
            wall = time.perf_counter() - t0
        times.append(wall)
        isect = img.stats["intersect_seconds"]
        total = threads * wall
        splits.append({"intersect": isect, "shading": tt.seconds - isect, "overhead": total - tt.seconds,
                       "bvh": img.stats["bvh_seconds"]})
        stats = img.stats
    if image:
        img.save(image)
    med = statistics.median(times)
    split = {k: statistics.median(s[k] for s in splits) for k in splits[0]}
    out = {"scene": name, "triangles": int(len(scene.triangles)), "width": width, "height": height,
           "threads": threads, "samples": samples, "seconds": med, "times": times, "rays": stats["rays"],
           "rays_per_second": stats["rays"]["total"] / med, "split_thread_seconds": split,
           # Peak RSS of the timed renders (scene building included), taken before the recording run.
           "maxrss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024}
    if record:
        rec = tracer.render(scene, settings.with_(extra={"record_rays": True}))
        batches = rec.stats["ray_batches"]
        out["replay"] = replay(scene, batches, threads, runs)
        recorded = int(sum(len(b[1]) for b in batches))
        out["recorded_rays"] = recorded
        del batches, rec
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description="time our tracer (and raw embreex on its rays) on one bench scene")
    ap.add_argument("--scene", required=True, choices=scenes.ALL_SCENES)
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--samples", type=int, default=1)
    ap.add_argument("--max-depth", type=int, default=8)
    ap.add_argument("--no-record", action="store_true", help="skip the recorded run and the embreex replay")
    ap.add_argument("--image", help="save the last timed render here")
    a = ap.parse_args(argv)
    res = measure(a.scene, a.width, a.height, a.threads, a.runs, a.samples, a.max_depth, not a.no_record, a.image)
    print("BENCH_JSON " + json.dumps(res))


if __name__ == "__main__":
    main()

"""Our tracer and raw embreex, measured in a child process (``python -m bench.ours ...`` prints one JSON object).

Timed runs call :func:`tracer.render` without recording. A separate run with ``extra={"record_rays": True}`` captures
the ray batches exactly as the integrator traced them, and :func:`replay` sends the same batches through a bare
embreex scene on the same number of threads (batches handed to a thread pool, as our tiles are).

Two comparisons are like for like:

- end to end: our rays / our wall time (which includes building our Embree scene, ``image.stats["bvh_seconds"]``)
  vs rays / (raw ``build_seconds`` + raw replay ``seconds``), where the raw build sets up a bare Embree scene the
  way our Accelerator does (vertex and index arrays, ``TriangleMesh``, one query to force the lazy BVH build);
- tracing only: our rays / ``trace_seconds`` (wall − ``bvh_seconds``, per run) vs rays / raw replay ``seconds``.

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


def build_embree(scene) -> tuple:
    """A bare embreex scene over ``scene``'s triangles, set up the way ``tracer.accel.Accelerator`` does it.

    Returns (EmbreeScene, the arrays it was built from, {"triangles", "mesh", "commit": seconds}): the float32
    vertex and int32 index arrays of the indexed mesh, ``TriangleMesh`` on them (embreex copies them into Embree
    buffers), and one occlusion query, which makes embreex commit the scene, i.e. build the BVH (it does so lazily).
    Our render reports the same three steps as ``image.stats["bvh_seconds"]``.
    """
    t0 = time.perf_counter()
    emb = rtcore_scene.EmbreeScene()
    verts = np.ascontiguousarray(scene.vertices, dtype=np.float32)
    tris = np.ascontiguousarray(scene.triangles, dtype=np.int32)
    t1 = time.perf_counter()
    mesh = TriangleMesh(emb, verts, tris)
    t2 = time.perf_counter()
    emb.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32), query="OCCLUDED")
    t3 = time.perf_counter()
    return emb, (verts, tris, mesh), {"triangles": t1 - t0, "mesh": t2 - t1, "commit": t3 - t2}


def replay(scene, batches, threads: int, runs: int = 3) -> dict:
    """Trace ``batches`` [(query, origins, directions, t_max)] with raw embreex, ``runs`` times.

    Each run first sets up a fresh bare Embree scene (:func:`build_embree`, timed on its own: ``build_seconds``),
    then replays the batches through it (``seconds``); both are medians over the runs. ``rays_per_second`` is the
    replay alone (tracing only), ``end_to_end_rays_per_second`` is rays / (build + replay) with the medians.
    """
    n_rays = int(sum(len(b[1]) for b in batches))

    def prepared():
        out = []
        for q, o, d, t in batches:
            if q == "OCCLUDED":
                out.append((q, o, d, np.ascontiguousarray(t, np.float32).copy()))
            else:
                out.append((q, o, d, None if t is None else np.ascontiguousarray(t, np.float32).copy()))
        return out

    times, build_times, build_splits = [], [], []
    with ThreadPoolExecutor(max_workers=threads) as pool:
        for _ in range(runs):
            emb = keep = None  # let the previous run's scene go before building the next (1 M triangles: ~100 MB)
            emb, keep, split = build_embree(scene)
            build_times.append(sum(split.values()))
            build_splits.append(split)

            def one(b, emb=emb):
                q, o, d, t = b
                if q == "OCCLUDED":
                    emb.run(o, d, dists=t, query="OCCLUDED")
                elif t is None:
                    emb.run(o, d, output=1)
                else:
                    emb.run(o, d, output=1, dists=t)

            work = prepared()
            t0 = time.perf_counter()
            list(pool.map(one, work))
            times.append(time.perf_counter() - t0)
            del work, one
    del emb, keep
    med = statistics.median(times)
    build = statistics.median(build_times)
    return {"seconds": med, "times": times, "rays": n_rays, "batches": len(batches),
            "rays_per_second": n_rays / med if med > 0 else 0.0,
            "build_seconds": build, "build_times": build_times,
            "build_split": {k: statistics.median(s[k] for s in build_splits) for k in build_splits[0]},
            "end_to_end_rays_per_second": n_rays / (build + med) if build + med > 0 else 0.0}


def measure(name: str, width: int, height: int, threads: int, runs: int, samples: int = 1, max_depth: int = 8,
            record: bool = True, image: str | None = None) -> dict:
    bs = scenes.build(name)
    scene = scenes.to_tracer(bs, width, height)
    settings = RenderSettings(width=width, height=height, samples=samples, max_depth=max_depth, threads=threads)
    times, trace_times, splits, stats = [], [], [], None
    for _ in range(runs):
        with TraceTimer() as tt:
            t0 = time.perf_counter()
            img = tracer.render(scene, settings)
            wall = time.perf_counter() - t0
        times.append(wall)
        trace_times.append(wall - img.stats["bvh_seconds"])
        isect = img.stats["intersect_seconds"]
        total = threads * wall
        splits.append({"intersect": isect, "shading": tt.seconds - isect, "overhead": total - tt.seconds,
                       "bvh": img.stats["bvh_seconds"]})
        stats = img.stats
    if image:
        img.save(image)
    med = statistics.median(times)
    trace_med = statistics.median(trace_times)
    split = {k: statistics.median(s[k] for s in splits) for k in splits[0]}
    out = {"scene": name, "triangles": int(len(scene.triangles)), "width": width, "height": height,
           "threads": threads, "samples": samples, "seconds": med, "times": times, "rays": stats["rays"],
           "rays_per_second": stats["rays"]["total"] / med, "split_thread_seconds": split,
           # Tracing only: wall minus image.stats["bvh_seconds"] of the same run (median over runs).
           "trace_seconds": trace_med, "trace_times": trace_times,
           "trace_rays_per_second": stats["rays"]["total"] / trace_med if trace_med > 0 else 0.0,
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

"""Our tracer and raw Embree, measured in a child process (``python -m bench.ours ...`` prints one JSON object).

Timed runs call :func:`tracer.render` without recording, after one untimed 64×36 render that loads the kernels. A
separate run with ``extra={"record_rays": True}`` captures the ray batches exactly as the integrator traced them, and
:func:`replay` sends the same batches through a bare Embree scene on the same number of threads (batches handed to a
thread pool, as our tiles are): raw Embree through our binding (:mod:`tracer.accel.embree`: one triangle geometry over all
triangles, the same compiled loops), twice —

- **single-ray**: ``rtcIntersect1`` / ``rtcOccluded1``, one ray per call (Embree's default, incoherent): the
  anchor of issue 23, what an integrator on this library gets tracing one ray at a time;
- **packets**: the packets our tracer made of each batch (recorded with it: 16 lanes on AVX-512, coherent for eye,
  mirror, glass and light-grouped shadow rays), i.e. the limit our integrator could reach with its own queries.

The world lights the bench scenes through the notes' flat ambient term (``sky_samples=0``, pinned in
:func:`measure`), as POV-Ray's ``ambient_light`` does, not through the default shadowed sky rays.

Two comparisons are like for like:

- end to end: our rays / our wall time (which includes building our Embree scene, ``image.stats["bvh_seconds"]``)
  vs rays / (raw ``build_seconds`` + raw replay ``seconds``), where the raw build sets up the bare Embree scene
  (padded vertex and index arrays, one shared-buffer triangle geometry, the BVH commit);
- tracing only: our rays / ``trace_seconds`` (wall − ``bvh_seconds``, per run) vs rays / raw replay ``seconds``.

For the set-up time before this binding, :func:`build_embreex` times embreex's own API on the same arrays
(``TriangleMesh``, which copies the geometry element by element, and the lazy BVH build its first query triggers).

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
import tracer
from tracer import RenderSettings
from tracer.accel import embree
from tracer.integrator.wavefront import Integrator

from . import scenes

ZERO_START = np.zeros(1, np.int64)  # one geometry: row = primID
NO_ROWS = np.zeros(0, np.int32)
NO_INSTANCES = np.zeros(0, np.int32)  # no instance array
NO_TIME = np.zeros(0, np.float32)  # no motion blur


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
    """A bare Embree scene over ``scene``'s triangles through our binding: one triangle geometry on shared buffers.

    Returns (EmbreeScene, what it keeps alive, {"triangles", "mesh", "commit": seconds}): the padded float32 vertex
    and int32 index buffers Embree reads in place, the geometry on them, and the BVH build (``rtcCommitScene``).
    """
    t0 = time.perf_counter()
    verts = embree.padded(scene.vertices, np.float32)
    tris = embree.padded(scene.triangles, np.int32)
    t1 = time.perf_counter()
    top = embree.EmbreeScene("medium", embree.SCENE_FLAG_ROBUST)
    geom = embree.TriangleGeometry(verts, tris, "medium")
    top.attach(geom, embree.OBJECT_GEOM_BASE)  # object 0's geometry id, as the tracer's accelerator
    t2 = time.perf_counter()
    top.commit()
    t3 = time.perf_counter()
    return top, (verts, tris, geom), {"triangles": t1 - t0, "mesh": t2 - t1, "commit": t3 - t2}


def build_embreex(scene) -> dict | None:
    """Seconds embreex's own API takes to set up the same scene (the tracer's Embree set-up before our binding):
    ``TriangleMesh`` on the indexed arrays and the BVH build its first query triggers. None without embreex."""
    try:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh
    except ImportError:
        return None
    t0 = time.perf_counter()
    emb = rtcore_scene.EmbreeScene()
    mesh = TriangleMesh(emb, np.ascontiguousarray(scene.vertices, np.float32),
                        np.ascontiguousarray(scene.triangles, np.int32))
    t1 = time.perf_counter()
    emb.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32), query="OCCLUDED")
    t2 = time.perf_counter()
    del mesh, emb
    return {"mesh": t1 - t0, "commit": t2 - t1, "seconds": t2 - t0}


def replay(scene, batches, threads: int, runs: int = 3) -> dict:
    """Trace ``batches`` [(query, origins, directions, t_max, packet query)] with raw Embree through our binding,
    ``runs`` times, two ways: ``packet`` — each batch in the packets our tracer made of it (its recorded
    :func:`tracer.accel.embree.query`: width, coherent or not), and ``single`` — one ray per ``rtcIntersect1`` /
    ``rtcOccluded1`` call (incoherent, Embree's default), the anchor issue 23 names.

    Each run first sets up a fresh bare Embree scene (:func:`build_embree`, timed on its own: ``build_seconds``),
    then replays the batches through it both ways (``seconds``, ``single_seconds``); all are medians over the runs.
    ``rays_per_second`` is the packet replay alone (tracing only), ``end_to_end_rays_per_second`` is rays / (build
    + packet replay) with the medians; ``single_*`` the same for one ray per call.
    """
    n_rays = int(sum(len(b[1]) for b in batches))
    single = embree.query(False, width=1)

    def prepared():
        out = []
        for q, o, d, t, packet in batches:
            if q == "OCCLUDED":
                out.append((q, o, d, np.ascontiguousarray(np.minimum(t, 3.0e38), np.float32).copy(), packet))
            else:
                t = np.zeros(0, np.float32) if t is None else np.ascontiguousarray(t, np.float32).copy()
                out.append((q, o, d, t, packet))
        return out

    def trace(handle, b, packet):
        q, o, d, t, _ = b
        n = len(o)
        if q == "OCCLUDED":
            embree.occluded_rays(handle, o, d, np.float32(0), t, np.empty(n, np.bool_), embree.ALL_RAYS, NO_TIME,
                                 embree.IN_ORDER, packet)
        else:
            embree.intersect_rays(handle, o, d, np.float32(0), t, ZERO_START, NO_ROWS, NO_INSTANCES,
                                  np.empty(n, np.float32), np.empty(n, np.int32), np.empty(n, np.int32),
                                  np.empty(n, np.float32), np.empty(n, np.float32), embree.ALL_RAYS, NO_TIME,
                                  embree.IN_ORDER, packet)

    times, single_times, build_times, build_splits, cpu_times, single_cpu = [], [], [], [], [], []
    replay_cpu: dict = {}  # CPU seconds of the replays alone (no build), per way
    with ThreadPoolExecutor(max_workers=threads) as pool:
        for _ in range(runs):
            emb = keep = None  # let the previous run's scene go before building the next (1 M triangles: ~100 MB)
            c0 = time.process_time()
            emb, keep, split = build_embree(scene)
            c1 = time.process_time()
            build_times.append(sum(split.values()))
            build_splits.append(split)
            work = prepared()
            for label, pick in (("packet", lambda b: b[4]), ("single", lambda b: single)):
                c2 = time.process_time()
                t0 = time.perf_counter()
                list(pool.map(lambda b, h=emb.handle: trace(h, b, pick(b)), work))
                wall = time.perf_counter() - t0
                cpu = time.process_time() - c2 + (c1 - c0)  # build + replay, not the batch copies
                (times if label == "packet" else single_times).append(wall)
                (cpu_times if label == "packet" else single_cpu).append(cpu)
                replay_cpu.setdefault(label, []).append(cpu - (c1 - c0))
            del work
    del emb, keep
    before = [b for b in (build_embreex(scene) for _ in range(runs)) if b is not None]
    med, med1 = statistics.median(times), statistics.median(single_times)
    build = statistics.median(build_times)
    rate = lambda s: n_rays / s if s > 0 else 0.0  # noqa: E731
    return {"seconds": med, "times": times, "rays": n_rays, "batches": len(batches),
            "rays_per_second": rate(med), "packets": sorted({f"{b[0]}:{_packet_name(b[4])}" for b in batches}),
            "build_seconds": build, "build_times": build_times,
            "build_split": {k: statistics.median(s[k] for s in build_splits) for k in build_splits[0]},
            "end_to_end_rays_per_second": rate(build + med),
            "cpu_seconds": statistics.median(cpu_times), "cpu_times": cpu_times,
            "single_seconds": med1, "single_times": single_times, "single_rays_per_second": rate(med1),
            "single_end_to_end_rays_per_second": rate(build + med1),
            "single_cpu_seconds": statistics.median(single_cpu), "single_cpu_times": single_cpu,
            "replay_cpu_seconds": statistics.median(replay_cpu["packet"]),
            "single_replay_cpu_seconds": statistics.median(replay_cpu["single"]),
            "embreex_build_seconds": statistics.median(b["seconds"] for b in before) if before else None}


def _packet_name(q: int) -> str:
    """"16 coherent", "1", ... for a recorded packet query."""
    return f"{q & 0xFFFF}{' coherent' if q & embree.COHERENT else ''}"


def measure(name: str, width: int, height: int, threads: int, runs: int, samples: int = 1, max_depth: int = 8,
            record: bool = True, image: str | None = None) -> dict:
    bs = scenes.build(name)
    scene = scenes.to_tracer(bs, width, height, instanced=True)  # meshes placed more than once: Embree instances
    # sky_samples=0 pins the notes' flat, unshadowed ambient term (the tracer's default shadows the world with sky
    # rays): POV-Ray's ambient_light is that same term, so the comparison stays like for like.
    settings = RenderSettings(width=width, height=height, samples=samples, max_depth=max_depth, threads=threads,
                              sky_samples=0)
    times, trace_times, cpu_times, splits, stats = [], [], [], [], None
    # kernels loaded and the allocator warmed before the timed runs (the raw replay's runs come after these)
    tracer.render(scene, settings.with_(width=64, height=36))
    for _ in range(runs):
        with TraceTimer() as tt:
            t0, c0 = time.perf_counter(), time.process_time()
            img = tracer.render(scene, settings)
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        times.append(wall)
        cpu_times.append(cpu)
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
    out = {"scene": name, "triangles": bs.triangle_count, "stored_triangles": int(len(scene.triangles)),
           "width": width, "height": height,
           "threads": threads, "samples": samples, "seconds": med, "times": times, "rays": stats["rays"],
           "rays_per_second": stats["rays"]["total"] / med, "split_thread_seconds": split,
           # CPU time of the process over the render (every thread, Embree's own included): what the render
           # costs whatever else the machine runs (wall times on a shared machine include waiting for a core)
           "cpu_seconds": statistics.median(cpu_times), "cpu_times": cpu_times,
           # Tracing only: wall minus image.stats["bvh_seconds"] of the same run (median over runs).
           "trace_seconds": trace_med, "trace_times": trace_times,
           "trace_rays_per_second": stats["rays"]["total"] / trace_med if trace_med > 0 else 0.0,
           # Peak RSS of the timed renders (scene building included), taken before the recording run.
           "maxrss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024}
    if record:
        rec = tracer.render(scene, settings.with_(extra={"record_rays": True}))
        batches = rec.stats["ray_batches"]
        # raw Embree traces the same rays through one flat geometry of every drawn triangle
        out["replay"] = replay(tracer.scene.flatten(scene), batches, threads, runs)
        recorded = int(sum(len(b[1]) for b in batches))
        out["recorded_rays"] = recorded
        del batches, rec
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description="time our tracer (and raw Embree on its rays) on one bench scene")
    ap.add_argument("--scene", required=True, choices=scenes.ALL_SCENES)
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--samples", type=int, default=1)
    ap.add_argument("--max-depth", type=int, default=8)
    ap.add_argument("--no-record", action="store_true", help="skip the recorded run and the raw Embree replay")
    ap.add_argument("--image", help="save the last timed render here")
    a = ap.parse_args(argv)
    res = measure(a.scene, a.width, a.height, a.threads, a.runs, a.samples, a.max_depth, not a.no_record, a.image)
    print("BENCH_JSON " + json.dumps(res))


if __name__ == "__main__":
    main()

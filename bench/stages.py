"""``python -m bench.stages --scene S``: where one thread's CPU time goes in a render, stage by stage.

Renders a bench scene on one thread (the tiles then run on the calling thread) with each stage of
:mod:`tracer.integrator.wavefront`, the Embree queries, eye-ray generation and the film write wrapped to sum
``time.thread_time`` (CPU seconds of this thread: other jobs on a shared machine do not count). Best of ``--runs``
per row. The docs' profile tables ("Where our time goes", docs/benchmarks.md) come from this.
"""

from __future__ import annotations

import argparse
import json
import time

import tracer
from tracer import RenderSettings
from tracer.accel import accelerator as accel
from tracer.integrator import wavefront as integrator, tiles

from . import scenes

#: (label, module, attribute) of what is timed.
STAGES = [
    ("tiles: trace_tile", tiles, "trace_tile"),
    ("integrator: trace", integrator.Integrator, "trace"),
    ("integrator: step", integrator.Integrator, "step"),
    ("Embree closest hits", accel.Accelerator, "closest_hits"),
    ("Embree occlusion", accel.Accelerator, "occluded"),
    ("all shading stages (_shade)", integrator.Integrator, "_shade"),
    ("surfaces", integrator, "_surfaces"),
    ("textures", integrator, "shade_programs"),
    ("first hits", integrator, "_first_hits"),
    ("emitted", integrator, "_emitted"),
    ("direct light", integrator, "_direct_light"),
    ("sky", integrator, "_sky"),
    ("spawn secondary", integrator, "_spawn_secondary"),
    ("add unoccluded", integrator, "_add_unoccluded"),
    ("eye rays", tiles, "timed_eye_rays"),
    ("film (write_tile)", tiles, "write_tile"),
]


def stage_seconds(scene, settings, runs: int, whole: str = "whole render"):
    """(best of ``runs``: one thread's CPU seconds in each of STAGES and in the whole render, the last image): the
    stages wrapped for the duration, ``time.thread_time`` (other jobs on the machine do not count)."""
    spent = {label: 0.0 for label, _, _ in STAGES}
    saved = [(owner, attr, getattr(owner, attr)) for _, owner, attr in STAGES]

    def timed(label, fn):
        def wrapper(*a, **kw):
            c0 = time.thread_time()
            try:
                return fn(*a, **kw)
            finally:
                spent[label] += time.thread_time() - c0
        return wrapper

    best = {}
    try:
        for (label, owner, attr), (_, _, fn) in zip(STAGES, saved):
            setattr(owner, attr, timed(label, fn))
        for _ in range(runs):
            for k in spent:
                spent[k] = 0.0
            c0 = time.thread_time()
            img = tracer.render(scene, settings)
            spent_whole = time.thread_time() - c0
            for k, v in list(spent.items()) + [(whole, spent_whole)]:
                best[k] = min(best.get(k, v), v)
    finally:
        for owner, attr, fn in saved:
            setattr(owner, attr, fn)
    return best, img


def profile(name: str, width: int, height: int, runs: int = 3, sky_samples: int = 0) -> dict:
    bs = scenes.build(name)
    scene = scenes.to_tracer(bs, width, height, instanced=True)
    settings = RenderSettings(width=width, height=height, samples=1, max_depth=8, threads=1,
                              sky_samples=sky_samples)
    tracer.render(scene, settings.with_(width=64, height=36))  # kernels loaded before timing
    best, img = stage_seconds(scene, settings, runs)
    return {"scene": name, "width": width, "height": height, "rays": img.stats["rays"], "cpu_seconds": best}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="whitted", choices=scenes.ALL_SCENES)
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--sky-samples", type=int, default=0)
    a = ap.parse_args(argv)
    res = profile(a.scene, a.width, a.height, a.runs, a.sky_samples)
    for k, v in res["cpu_seconds"].items():
        print(f"{k:30s} {v:7.3f} s")
    print("BENCH_JSON " + json.dumps(res))


if __name__ == "__main__":
    main()

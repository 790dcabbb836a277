"""Cost of motion blur (issue #24): the 1980 scene rendered still, and with its floor and mirror ball moving across
the shutter, in one process (warm kernels), CPU time per eye sample.

    python -m bench.motion [--width 640] [--runs 5]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def _scene(moving: bool, width: int, height: int):
    from tracer.geometry.motion import Motion
    from usd_io.reader import load_stage

    scene, _ = load_stage(os.path.join(HERE, "..", "examples", "whitted_1980.usda"), width=width, height=height)
    if moving:  # the floor and the mirror ball slide 0.3 units across the shutter (3 steps, as the front ends)
        m = np.eye(4)
        m[:3, 3] = (0.3, 0.0, 0.0)
        half = np.eye(4)
        half[:3, 3] = (0.15, 0.0, 0.0)
        steps = np.stack([np.eye(4), half, m])
        scene.motion = Motion(steps=3, object_ids=np.array([0, 1]), object_motion=np.stack([steps, steps]))
        scene.validate_motion()
    return scene


def main(argv=None) -> None:
    import tracer

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--width", type=int, default=640)
    p.add_argument("--runs", type=int, default=5)
    a = p.parse_args(argv)
    w, h = a.width, a.width * 3 // 4
    s = tracer.RenderSettings(width=w, height=h, samples=2, max_depth=8, threads=2)
    for moving in (False, True, False, True):
        scene = _scene(moving, w, h)
        tracer.render(scene, s.with_(width=64, height=48))  # warm
        cpu = []
        for _ in range(a.runs):
            c0 = time.process_time()
            img = tracer.render(scene, s)
            cpu.append(time.process_time() - c0)
        eye = img.stats["rays"]["eye"]
        print(f"{'moving' if moving else 'still '}: CPU min {min(cpu):.3f} s, median {np.median(cpu):.3f} s, "
              f"{min(cpu) / eye * 1e9:.0f} ns per eye sample ({sum(img.stats['rays'].values())} rays)")


if __name__ == "__main__":
    main()

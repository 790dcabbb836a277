"""Cost of depth of field (issue #24): the 1980 scene rendered through a pinhole and through a thin lens (f/1.4-like
aperture, focused on the mirror ball), in one process (warm kernels), CPU time per eye sample.

    python -m bench.dof [--width 640] [--runs 5]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from bench.motion import _scene


def main(argv=None) -> None:
    import tracer

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--width", type=int, default=640)
    p.add_argument("--runs", type=int, default=5)
    a = p.parse_args(argv)
    w, h = a.width, a.width * 3 // 4
    s = tracer.RenderSettings(width=w, height=h, samples=2, max_depth=8, threads=2)
    for lens in (False, True, False, True):
        scene = _scene(False, w, h)
        if lens:
            cam = scene.camera
            focus = float(np.linalg.norm(cam.position))  # about the scene's middle
            scene.camera = dataclasses.replace(cam, lens_radius=0.05 * focus, focus_distance=focus)
        tracer.render(scene, s.with_(width=64, height=48))  # warm
        cpu = []
        for _ in range(a.runs):
            c0 = time.process_time()
            img = tracer.render(scene, s)
            cpu.append(time.process_time() - c0)
        eye = img.stats["rays"]["eye"]
        print(f"{'lens   ' if lens else 'pinhole'}: CPU min {min(cpu):.3f} s, median {np.median(cpu):.3f} s, "
              f"{min(cpu) / eye * 1e9:.0f} ns per eye sample ({sum(img.stats['rays'].values())} rays)")


if __name__ == "__main__":
    main()

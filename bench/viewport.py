"""``python -m bench.viewport``: the add-on's viewport worker (addon/viewport.py) driven as view_draw drives it, on
the 1 M-triangle bench scene: time to the first (1/8-resolution) pass after a camera move, to the full-resolution
pass, and the cost of a scene change (new export -> BVH build in the worker). No Blender UI needed."""

from __future__ import annotations

import time

import numpy as np


def main(size=(960, 540)):
    import tracer
    from addon import viewport

    from .scenes import build, to_tracer

    scene = to_tracer(build("heavy"), *size)
    frames = []
    vr = viewport.ViewportRender(settings=tracer.RenderSettings(light_samples=4, max_depth=4))
    vr.on_frame = lambda: frames.append((time.perf_counter(), vr.latest()))
    try:
        cam = scene.camera
        t0 = time.perf_counter()
        vr.set_scene(scene)
        vr.set_view(cam, size)
        vr.wait_until_converged(600)
        first = [t for t, f in frames if f.level == viewport.LEVELS[0]][0] - t0
        print(f"bench.viewport: {len(scene.triangles):,} triangles, {size[0]}x{size[1]} viewport")
        print(f"  scene set (BVH build in the worker) -> first 1/8 pass: {first:.2f} s")
        moves = []
        for k in range(5):  # orbit: a new camera each time, wait for the coarse pass
            m = cam.camera_to_world.copy()
            a = np.radians(3 * (k + 1))
            rot = np.array([[np.cos(a), -np.sin(a), 0, 0], [np.sin(a), np.cos(a), 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
            moved = tracer.Camera(camera_to_world=rot @ m, focal_length=cam.focal_length,
                                  horizontal_aperture=cam.horizontal_aperture, vertical_aperture=cam.vertical_aperture)
            n = len(frames)
            t0 = time.perf_counter()
            vr.set_view(moved, size)
            while len(frames) == n or frames[-1][1].level != viewport.LEVELS[0]:
                time.sleep(0.001)
            moves.append(frames[-1][0] - t0)
            vr.wait_until_converged(600)
        full = [t for t, f in frames if f.level == 1 and f.samples == 1][-1] - \
            [t for t, f in frames if f.level == viewport.LEVELS[0]][-1]
        print(f"  camera move -> 1/8 pass: median {np.median(moves) * 1e3:.0f} ms ({1 / np.median(moves):.0f} fps)")
        print(f"  1/8 pass -> full-resolution pass: {full:.2f} s")
        t0 = time.perf_counter()
        view_draw = [vr.latest() for _ in range(1000)]
        print(f"  what view_draw asks the worker (latest frame): {(time.perf_counter() - t0) * 1e3 / 1000:.3f} ms")
    finally:
        vr.stop()


if __name__ == "__main__":
    main()

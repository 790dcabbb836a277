"""``python -m bench.session``: what a :class:`tracer.Session` edit costs on the 1 M-triangle bench scene, against
rebuilding everything (a fresh ``tracer.render``), and the Embree set-up before (embreex's own API) and after (our
binding). Each edit is timed on its own, then the render after it (a coarse viewport pass, 480×270, 1 spp), so
"edit + render" is what a viewport waits for. Medians of ``--runs``; no Blender needed.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np


def _median(f, runs):
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="heavy")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--size", default="480x270")
    a = ap.parse_args(argv)
    w, h = (int(x) for x in a.size.split("x"))

    import tracer
    from tracer.accel.accelerator import Accelerator

    from .ours import build_embreex
    from .scenes import build, to_tracer

    bs = build(a.scene)
    scene = to_tracer(bs, w, h)
    settings = tracer.RenderSettings(width=w, height=h, samples=1, max_depth=4, light_samples=1, threads=2)
    tracer.render(scene, settings)  # kernels loaded, library open
    print(f"bench.session: {a.scene}, {len(scene.triangles):,} triangles in {len(np.unique(scene.object_ids))} "
          f"objects, renders {w}x{h} 1 spp, medians of {a.runs}")
    rows = []
    before = [build_embreex(scene) for _ in range(a.runs)]
    rows.append(("Embree set-up: embreex's API (before)", statistics.median(b["seconds"] for b in before), None))
    rows.append(("Embree set-up: our binding, flat (tracer.render)",
                 _median(lambda: Accelerator(scene).close(), a.runs), None))
    rows.append(("Embree set-up: our binding, instanced (Session)",
                 _median(lambda: Accelerator(scene, instanced=True).close(), a.runs), None))
    full = _median(lambda: tracer.render(scene, settings), a.runs)
    rows.append(("everything again (tracer.render: set-up + render)", full, None))

    session = tracer.Session(scene)
    session.render(settings)
    cam = scene.camera
    ball = int(np.unique(scene.object_ids)[1])
    rng = np.random.default_rng(1)

    def camera():
        m = cam.camera_to_world.copy()
        m[:3, 3] += rng.normal(0, 0.05, 3)
        session.update_camera(tracer.Camera(camera_to_world=m, focal_length=cam.focal_length,
                                            horizontal_aperture=cam.horizontal_aperture,
                                            vertical_aperture=cam.vertical_aperture))

    def material():  # the same table handed in again: the cost is the repack, whatever changed in it
        session.update_materials(session.scene.materials)

    def move():
        t = session.transform(ball).copy()
        t[:3, 3] += rng.normal(0, 0.05, 3)
        session.set_transform(ball, t)

    rows_of_ball = scene.object_ids == ball
    vidx = np.unique(scene.triangles[rows_of_ball])
    remap = np.full(len(scene.vertices), -1)
    remap[vidx] = np.arange(len(vidx))
    ball_v, ball_f = scene.vertices[vidx], remap[scene.triangles[rows_of_ball]]
    ball_mat = int(scene.material_ids[rows_of_ball][0])

    def mesh():
        session.update_mesh(ball, ball_v * (1 + rng.normal(0, 0.001)), ball_f, material=ball_mat)

    for name, edit in (("camera", camera), ("material", material), ("object move", move),
                       (f"one mesh ({len(ball_f):,} triangles)", mesh)):
        edits, renders = [], []
        for _ in range(a.runs):
            t0 = time.perf_counter()
            edit()
            t1 = time.perf_counter()
            session.render(settings)
            renders.append(time.perf_counter() - t1)
            edits.append(t1 - t0)
        rows.append((f"Session edit: {name}", statistics.median(edits), statistics.median(renders)))
    session.close()

    print(f"{'':52s} {'edit / set-up':>14s} {'next render':>12s}")
    for label, t, r in rows:
        print(f"{label:52s} {t:12.3f} s {'' if r is None else f'{r:10.3f} s'}")


if __name__ == "__main__":
    main()

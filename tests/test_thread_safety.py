"""Tile threads must not share what they write (issue #30: ``whitted render`` of a stage with cut-out plants died
with SIGSEGV, two tile threads inside tracer/accel/alpha.py's ``occluded``).

The scene is the McUsd pattern, built here: many leaves over a ground, each leaf its own material whose alpha is a
program (an alpha texture times a constant, some cut out by a threshold), so every shadow ray that crosses a leaf
runs the shader VM inside Embree's occlusion filter. It is rendered with 8 tile threads 30 times in one process
(in a child process, so a crash is reported with its signal instead of killing pytest) and every picture must
equal a 1-thread render bit for bit (same seed: the tracer's images do not depend on the thread count)."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

import tracer
from tracer.camera import Camera
from tracer.lights.emitters import DistantLight, PointLight

RUNS = 30
THREADS = 8


def leaves_scene(n_leaves: int = 120, seed: int = 7, instanced: bool = False) -> tracer.Scene:
    """A ground under ``n_leaves`` alpha-textured leaves at random heights, lit by a sun and two point lights;
    ``instanced``: one leaf prototype placed n times, each instance with its own material (the filter's
    instance-array path)."""
    rng = np.random.default_rng(seed)
    b = tracer.SceneBuilder()
    ground = b.add_material("ground", diffuse=(0.5, 0.45, 0.4), specular=0.0, roughness=1.0)
    gv = np.array([[-8, -8, 0], [8, -8, 0], [8, 8, 0], [-8, 8, 0]], np.float32)
    quad = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    b.add_mesh(gv, quad, material=ground, name="ground")
    # a few leaf shapes: alpha images with holes and soft edges (each its own texture, so programs differ)
    textures = []
    for k in range(6):
        img = np.ones((16, 16, 4), np.float32)
        yy, xx = np.mgrid[0:16, 0:16] / 15.0 - 0.5
        r = np.hypot(xx * (1.0 + 0.2 * k), yy)
        img[..., 3] = np.clip((0.5 - r) * (4 + k), 0.0, 1.0)
        img[..., 1] = 0.3 + 0.1 * k
        textures.append(b.add_texture(tracer.Texture(image=img, wrap_s="clamp", wrap_t="clamp")))
    placements, materials = [], []
    for i in range(n_leaves):
        fields = dict(diffuse=tuple(rng.uniform(0.1, 0.9, 3)), specular=0.0, alpha=float(rng.uniform(0.4, 1.0)),
                      alpha_texture=textures[i % len(textures)], alpha_channel=3, diffuse_texture=textures[i % 6])
        if i % 3 == 0:
            fields["alpha_threshold"] = float(rng.uniform(0.2, 0.6))  # a cut-out
        mat = b.add_material(f"leaf{i}", **fields)
        c = rng.uniform(-4, 4, 2)
        h = rng.uniform(0.5, 4.0)
        s = rng.uniform(0.5, 1.5)
        ang = rng.uniform(0, np.pi)
        ca, sa = np.cos(ang), np.sin(ang)
        corners = np.array([[-s, -s], [s, -s], [s, s], [-s, s]]) @ np.array([[ca, sa], [-sa, ca]])
        tilt = rng.uniform(-0.3, 0.3, 2)
        v = np.column_stack([corners[:, 0] + c[0], corners[:, 1] + c[1],
                             h + corners[:, 0] * tilt[0] + corners[:, 1] * tilt[1]]).astype(np.float32)
        if not instanced:
            b.add_mesh(v, quad, material=mat, name=f"leaf{i}", uvs=uv)
            continue
        m = np.eye(4)  # the unit leaf (corners ±1 in x, y) onto this leaf's corners 0, 1, 3
        m[:3, 0], m[:3, 1] = (v[1] - v[0]) / 2, (v[3] - v[0]) / 2
        m[:3, 3] = (v[1] + v[3]) / 2
        m[:3, 2] = np.cross(m[:3, 0], m[:3, 1]) / max(np.linalg.norm(m[:3, 0]), 1e-6)
        placements.append(m)
        materials.append(mat)
    if instanced:
        unit = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
        proto = b.add_mesh(unit, quad, material=materials[0], name="leaf", uvs=uv)
        b.add_instances(proto, np.stack(placements), materials=np.array(materials, np.int32))
    b.add_light(DistantLight(direction=(0.3, 0.2, -1), irradiance=(2.0, 2.0, 2.0)))
    b.add_light(PointLight(position=(2, -3, 7), intensity=(40.0, 35.0, 30.0), radius=0.5))
    b.add_light(PointLight(position=(-3, 2, 6), intensity=(20.0, 25.0, 30.0), radius=0.3))
    b.camera = Camera.look_at((0, -11, 9), (0, 0, 0.5), up=(0, 0, 1), focal_length=30)
    b.background = np.array([0.05, 0.07, 0.1], np.float32)
    return b.build()


def settings(threads: int) -> tracer.RenderSettings:
    return tracer.RenderSettings(width=160, height=112, samples=2, max_depth=2, light_samples=4, sky_samples=0,
                                 tile_size=8, threads=threads, seed=3)


def soak(runs: int = RUNS, threads: int = THREADS, instanced: bool = False) -> str:
    """Render the leaves ``runs`` times with ``threads`` threads: 'ok', or which runs differed from 1 thread."""
    scene = leaves_scene(instanced=instanced)
    reference = tracer.render(scene, settings(1)).rgba
    assert np.isfinite(reference).all() and reference[..., :3].max() > 0.01
    bad = []
    for run in range(runs):
        rgba = tracer.render(scene, settings(threads)).rgba
        if not np.array_equal(rgba, reference):
            bad.append(f"run {run}: {int(np.sum(np.any(rgba != reference, axis=2)))} pixels differ")
    return "ok" if not bad else "; ".join(bad)


@pytest.mark.parametrize("instanced", [False, True])
def test_cut_outs_render_the_same_with_8_threads_30_times(instanced):
    here = os.path.dirname(os.path.abspath(__file__))
    code = (f"import sys; sys.path.insert(0, {here!r}); import test_thread_safety as t; "
            f"print('RESULT', t.soak(instanced={instanced}))")
    env = dict(os.environ, PYTHONFAULTHANDLER="1")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=3000)
    if proc.returncode < 0:
        raise AssertionError(f"the render process died with signal {-proc.returncode}:\n{proc.stderr[-4000:]}")
    assert proc.returncode == 0, proc.stderr[-4000:]
    result = [line for line in proc.stdout.splitlines() if line.startswith("RESULT")]
    assert result == ["RESULT ok"], proc.stdout[-2000:]

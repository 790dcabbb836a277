"""Compile (or load from the kernel cache) every kernel of every render path, before a render needs them.

A render compiles only the kernels it uses, as it first uses them (tracer/jit.py), and later processes load them
from the cache (tracer/kernel_cache.py). :func:`compile_kernels` is for preparing everything ahead: ``whitted
warmup``, the Blender add-on's child process, and the kernels shipped in the add-on's zip (tracer/kernel_bundle.py).
It renders a tiny scene that takes every path through the kernels (all light kinds with and without extent, shading
normals, a texture, mirror, glass, alpha, emission, sky visibility, the denoiser's guides: F12 denoises by default),
then the same scene with motion blur (a moving and a deforming object, a moving camera, a shutter curve:
tracer/geometry/motion.py's kernels and the stages' timed paths), each also with adaptive sampling (its eye rays of
listed samples and its film).
docs/benchmarks.md ("Ready at install") has what that costs, measured.
"""

from __future__ import annotations

import numpy as np

from .builder import SceneBuilder
from .camera import Camera
from .geometry.motion import Motion, curve_table
from .jit import mark_kernels_cached
from .lights.emitters import AreaLight, DistantLight, PointLight, SpotLight
from .render import render
from .settings import RenderSettings


def compile_kernels() -> None:
    """Render an 8×8 scene that touches every kernel specialisation a render uses."""
    b = SceneBuilder()
    tex = b.add_texture(np.ones((2, 2, 3), np.float32))
    plain = b.add_material("plain", diffuse=(0.5, 0.5, 0.5), specular=(0.1, 0.1, 0.1), emission=(0.01, 0, 0),
                           diffuse_texture=tex)
    glass = b.add_material("glass", transmission=1.0, ior=1.5, alpha=0.5)  # alpha: transparent shadows
    mirror = b.add_material("mirror", k_m=1.0)
    quad_v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float64)
    quad_f = np.array([[0, 1, 2], [0, 2, 3]])
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float64)
    b.add_mesh(quad_v, quad_f, material=plain, normals=np.tile([0.0, 0.0, 1.0], (4, 1)), uvs=uv)
    b.add_mesh(quad_v * 0.3 + [0, 0, 0.5], quad_f, material=glass)
    placed = np.diag([0.2, 0.2, 0.2, 1.0])
    placed[:3, 3] = (0.5, 0, 0.8)  # a transform and normals: the builder's placement kernels
    b.add_mesh(quad_v, quad_f, material=mirror, transform=placed, normals=np.tile([0.0, 0.0, 1.0], (4, 1)))
    b.add_light(PointLight(position=(0, 0, 3), intensity=(1, 1, 1)))
    b.add_light(PointLight(position=(1, 0, 3), intensity=(1, 1, 1), radius=0.1))
    b.add_light(SpotLight(position=(0, 1, 3), intensity=(1, 1, 1), direction=(0, 0, -1)))
    b.add_light(DistantLight(direction=(0, 0, -1), irradiance=(1, 1, 1), angle=0.1))
    b.add_light(AreaLight(position=(0, 0, 2), u_axis=(1, 0, 0), v_axis=(0, 1, 0), normal=(0, 0, -1),
                          radiance=(1, 1, 1), shape="disk"))
    b.camera = Camera.look_at((0, -3, 2), (0, 0, 0), up=(0, 0, 1))
    b.background = np.array([0.1, 0.1, 0.1], np.float32)
    b.ambient = np.array([0.1, 0.1, 0.1], np.float32)
    settings = RenderSettings(width=8, height=8, samples=2, light_samples=1, sky_samples=1, threads=1,
                              aovs=("depth", "denoising_albedo", "denoising_normal"), transparent=True)
    render(b.build(), settings)
    render(_with_motion(b), settings)
    adaptive = settings.with_(samples=3, adaptive_threshold=0.5, adaptive_min_samples=4)  # rounds of listed samples
    render(b.build(), adaptive)
    render(_with_motion(b), adaptive)
    b.materials[glass]["alpha"] = 1.0  # nothing see-through: shadow rays take plain occlusion (tracer/accel/alpha.py)
    render(b.build(), settings)
    mark_kernels_cached()


def _with_motion(b):
    """The warm-up scene with everything moving across the shutter: the plain quad by its transform, the glass quad
    by its vertices, the camera, and a shutter curve (every timed path of the kernels)."""
    shift = np.eye(4)
    shift[:3, 3] = (0.1, 0.0, 0.0)
    eye = b.camera.camera_to_world
    b.camera.motion = np.stack([eye, shift @ eye])
    scene = b.build()
    b.camera.motion = None
    moved = scene.vertices.copy()
    moved[scene.triangles[scene.object_ids == 1].ravel()] += np.float32(0.05)  # the glass quad's vertices
    scene.motion = Motion(steps=2, object_ids=np.array([0]), object_motion=np.stack([np.eye(4), shift])[None],
                          vertices=np.stack([scene.vertices, moved]), deforming=np.array([1]),
                          curve=curve_table([0.0, 1.0, 0.5]))
    scene.validate_motion()
    return scene

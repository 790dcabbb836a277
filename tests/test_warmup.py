"""tracer.compile_kernels() prepares every kernel specialisation a render uses, so nothing compiles mid-render.

The check runs in a fresh process: in the test session other tests have already compiled (or loaded) every kernel,
so a compile_kernels() that did nothing would pass there; a fresh interpreter sees only what compile_kernels() and
the renders after it bring in.
"""

import importlib
import json
import os
import subprocess
import sys

import numpy as np

import tracer
from tracer import AreaLight, Camera, DistantLight, PointLight, RenderSettings, SceneBuilder, SpotLight

from tracer_scenes import lit_sphere_on_floor


def _kernels():
    """Every numba kernel defined in the tracer's modules (found, not listed: a kernel added later is checked too)."""
    import pkgutil

    from tracer.jit import Kernel

    found = {}
    for info in pkgutil.walk_packages(tracer.__path__, "tracer."):
        module = importlib.import_module(info.name)
        for name, obj in vars(module).items():
            if isinstance(obj, Kernel) and obj.__module__ == module.__name__:
                found[f"{info.name.removeprefix('tracer.')}.{name}"] = obj
    return found


def _flat_scene_without_normals():
    b = SceneBuilder()
    m = b.add_material("red", diffuse=(0.8, 0.1, 0.1))
    b.add_mesh(np.array([[-1, -1, 0], [1, -1, 0], [0, 1, 0]], float), np.array([[0, 1, 2]]), material=m)
    for light in (SpotLight(position=(0, 0, 3), intensity=(5, 5, 5), direction=(0, 0, -1)),
                  DistantLight(direction=(0, 0.2, -1), irradiance=(1, 1, 1)),
                  AreaLight(position=(0, 0, 2), u_axis=(1, 0, 0), v_axis=(0, 1, 0), normal=(0, 0, -1),
                            radiance=(2, 2, 2))):
        b.add_light(light)
    b.camera = Camera.look_at((0, -3, 3), (0, 0, 0), up=(0, 0, 1), projection="orthographic",
                              horizontal_aperture=3.0, vertical_aperture=3.0)
    return b.build()


def test_compile_kernels_covers_the_kernels_a_render_uses():
    here = os.path.dirname(os.path.abspath(__file__))
    code = ("import json, sys; sys.path[:0] = [%r, %r]; import test_warmup as t; "
            "print(json.dumps(t.check_in_this_process()))" % (os.path.dirname(here), here))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    before, after = json.loads(r.stdout.strip().splitlines()[-1])
    for hot in ("integrator.wavefront._surfaces", "integrator.wavefront._direct_light",
                "integrator.wavefront._spawn_secondary", "integrator.wavefront._add_unoccluded",
                "integrator.tiles._tile_eye_rays", "integrator.tiles._tile_eye_rays_timed",
                "integrator.tiles._list_eye_rays", "integrator.tiles._write_rgba_spent",
                "geometry.motion.frames_at_time"):
        assert before[hot] > 0, f"compile_kernels left {hot} uncompiled: {before}"
    grew = {k: (before[k], n) for k, n in after.items() if n != before.get(k, 0)}
    assert not grew, f"renders after compile_kernels compiled new kernel specialisations: {grew}"


def _moving_sphere():
    """lit_sphere_on_floor with motion blur: the floor slides, the sphere's vertices move, the camera turns, and the
    shutter has a curve (tracer/geometry/motion.py's kernels and the stages' timed paths)."""
    from tracer.geometry.motion import Motion, curve_table

    b = lit_sphere_on_floor()
    eye = b.camera.camera_to_world
    turn = np.eye(4)
    turn[:2, :2] = [[np.cos(0.05), -np.sin(0.05)], [np.sin(0.05), np.cos(0.05)]]
    b.camera.motion = np.stack([eye, turn @ eye])
    scene = b.build()
    slide = np.eye(4)
    slide[:3, 3] = (0.2, 0.0, 0.0)
    moved = scene.vertices.copy()
    moved[np.unique(scene.triangles[scene.object_ids == 1])] += np.float32(0.1)
    scene.motion = Motion(steps=2, object_ids=np.array([0]), object_motion=np.stack([np.eye(4), slide])[None],
                          vertices=np.stack([scene.vertices, moved]), deforming=np.array([1]),
                          curve=curve_table([0.2, 1.0, 0.2]))
    scene.validate_motion()
    return scene


def check_in_this_process():
    """Signatures per kernel after compile_kernels(), and after renders that take other paths (smooth normals,
    lights with extent, AA, no shading normals, orthographic, sky visibility, AOVs, an environment image, motion
    blur)."""
    tracer.compile_kernels()
    kernels = _kernels()
    before = {name: len(k.signatures) for name, k in kernels.items()}
    b = lit_sphere_on_floor()  # smooth normals, a point light
    b.add_light(PointLight(position=(0, 0, 8), intensity=(5, 5, 5), radius=0.5))
    sphere = b.build()
    sky = lit_sphere_on_floor().build()
    sky.environment = tracer.Environment(np.linspace(0.1, 2.0, 16 * 32 * 3, dtype=np.float32).reshape(16, 32, 3))
    placed = lit_sphere_on_floor()  # a mesh placed by a matrix, with normals: the builder's placement kernels
    move = np.eye(4)
    move[:3, 3] = (0.3, -0.2, 0.1)
    placed.add_mesh(np.array([[0, 0, 1], [1, 0, 1], [0, 1, 1.5]], float), np.array([[0, 1, 2]]), transform=move,
                    normals=np.array([[0, 0, 1.0]] * 3))
    for scene, settings in ((sphere, RenderSettings(width=24, height=16, samples=2, light_samples=4)),
                            (placed.build(), RenderSettings(width=16, height=12)),
                            (_flat_scene_without_normals(), RenderSettings(width=16, height=16, sky_samples=4,
                                                                            threads=2, aovs=("normal",))),
                            (sky, RenderSettings(width=16, height=12, samples=1, sky_samples=4)),
                            (_moving_sphere(), RenderSettings(width=16, height=12)),
                            (sphere, RenderSettings(width=16, height=12, samples=4, adaptive_threshold=0.05,
                                                    adaptive_min_samples=4, aovs=("objectid",))),
                            (_moving_sphere(), RenderSettings(width=16, height=12, samples=3,
                                                              adaptive_threshold=0.05))):
        image = tracer.render(scene, settings)
        assert image.rgba[..., :3].max() > 0  # the scenes are lit
    after = {name: len(k.signatures) for name, k in _kernels().items()}
    return before, after


def test_whitted_warmup_compiles_the_kernels():
    """``whitted warmup`` (what a user runs at install time) leaves the render's kernels compiled or loaded, in a
    fresh process (where no render has loaded any yet), and says so on stderr with exit code 0."""
    here = os.path.dirname(os.path.abspath(__file__))
    code = ("import json, sys; sys.path[:0] = [%r, %r]; import test_warmup as t; from usd_io.cli import main; "
            "code = main(['warmup']); print(json.dumps([code, {k: len(d.signatures) for k, d in t._kernels().items()}]))"
            % (os.path.dirname(here), here))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    exit_code, signatures = json.loads(r.stdout.strip().splitlines()[-1])
    assert exit_code == 0 and "whitted: kernels" in r.stderr
    for hot in ("integrator.wavefront._surfaces", "integrator.tiles._tile_eye_rays",
                "scene_kernels.non_degenerate_rows", "builder._affine_rows"):
        assert signatures[hot] > 0, f"whitted warmup left {hot} unprepared"

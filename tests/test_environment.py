"""Lat-long environments: the mapping (Cycles' equirectangular convention, closed form), what misses and mirrors
see, and the environment as a light (uniform sky: E = π·L; an HDRI sun casts a shadow)."""

from __future__ import annotations

import numpy as np
import pytest

from tracer import Camera, Environment, RenderSettings, SceneBuilder
from tracer import render

from tracer_scenes import quad


def _compass(h=32, w=64):
    """Each quarter of longitudes its own colour, centred on u = 0, 0.25, 0.5, 0.75; the upper half bright, the
    lower half dim."""
    rows, cols = np.mgrid[0:h, 0:w]
    quarter = ((cols * 4 + w // 2) // w) % 4
    colours = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0]], np.float32)
    img = colours[quarter] * np.where(rows < h // 2, 1.0, 0.25)[..., None]
    return img.astype(np.float32)


@pytest.mark.parametrize("direction,expected", [
    ((1, 0, 0.3), (0, 0, 1)),     # +X looks at u = 0.5: the third quarter, upper half
    ((0, 1, 0.3), (0, 1, 0)),     # +Y: u = 0.25, second quarter
    ((0, -1, 0.3), (1, 1, 0)),    # −Y: u = 0.75
    ((-1, 0.2, 0.3), (1, 0, 0)),  # −X (a little towards +Y): u just under 1 − … wraps to the first quarter
    ((1, 0, -0.3), (0, 0, 0.25)),  # below the horizon: the dim lower half
])
def test_mapping_is_cycles_equirectangular(direction, expected):
    """u = 0.5 − atan2(y, x)/2π, top row = +Z (Cycles' direction_to_equirectangular)."""
    env = Environment(_compass())
    d = np.asarray(direction, float)
    d /= np.linalg.norm(d)
    np.testing.assert_allclose(env.radiance(d[None])[0], expected, atol=1e-6)


def test_rotation_turns_the_world():
    turn = np.array([[0, 1, 0], [-1, 0, 0], [0, 0, 1]], float)  # world -> env: +Y onto +X
    env = Environment(_compass(), rotation=turn)
    np.testing.assert_allclose(env.radiance(np.array([[0.0, 0.95, 0.31]]))[0], (0, 0, 1), atol=1e-6)


def test_misses_and_mirrors_see_the_environment():
    b = SceneBuilder()
    m = b.add_material("mirror", diffuse=(0, 0, 0), k_m=1.0)
    quad(b, (0, 0, 0), 1.0, m, "mirror")  # faces +z
    b.camera = Camera.look_at((0, -3, 3), (0, 0, 0), up=(0, 0, 1), focal_length=35.0)
    b.environment = Environment(_compass(), strength=2.0)
    scene = b.build()
    img = render(scene, RenderSettings(samples=1, width=33, height=33)).rgb
    o, d = scene.camera.generate_rays(np.array([0.5, 0.02]), np.array([0.5, 0.98]))
    r = d[0] * np.array([1, 1, -1])  # the mirror reflects the centre ray about z
    np.testing.assert_allclose(img[16, 16], scene.environment.radiance(r[None])[0], atol=1e-5)
    np.testing.assert_allclose(img[0, 0], scene.environment.radiance(d[1][None])[0], rtol=0.05)


def test_a_uniform_environment_lights_a_plane_with_irradiance_pi_l():
    b = SceneBuilder()
    m = b.add_material("white", diffuse=(0.5, 0.5, 0.5))
    quad(b, (0, 0, 0), 4.0, m, "plane")
    b.camera = Camera.look_at((0, 0, 5), (0, 0, 0), up=(0, 1, 0), projection="orthographic",
                              horizontal_aperture=1.0, vertical_aperture=1.0)
    b.environment = Environment(np.full((16, 32, 3), 0.8, np.float32))
    scene = b.build()
    for sky in (0, 64):  # the notes' ambient term (L_a = mean radiance) and importance-sampled sky rays
        img = render(scene, RenderSettings(width=4, height=4, sky_samples=sky)).rgb
        np.testing.assert_allclose(img, 0.5 * 0.8, rtol=0.03)


def test_an_hdri_sun_casts_a_shadow():
    """A dim sky with a tiny bright sun patch: importance sampling finds the sun, so a blocker between the sun and
    the floor casts a dark shadow with few samples."""
    h, w = 64, 128
    img = np.full((h, w, 3), 0.05, np.float32)
    img[8:10, 63:65] = 2000.0  # the sun: high in the sky (row 8 of 64), u = 0.5 → towards +X
    b = SceneBuilder()
    m = b.add_material("grey", diffuse=(0.5, 0.5, 0.5))
    quad(b, (0, 0, 0), 20.0, m, "floor")
    black = b.add_material("black", diffuse=(0, 0, 0))
    quad(b, (0.5, 0, 2.0), 1.0, black, "blocker")
    b.camera = Camera.look_at((0, 0, 8), (0, 0, 0), up=(0, 1, 0), projection="orthographic",
                              horizontal_aperture=8.0, vertical_aperture=8.0)
    b.environment = Environment(img)
    out = render(b.build(), RenderSettings(width=64, height=64, sky_samples=16)).rgb[..., 0]
    # the sun's elevation: latitude of row 9 of 64 → the shadow falls towards −X of the blocker
    lat = (0.5 - 9 / 64) * np.pi
    x_shadow = 0.5 - 2.0 / np.tan(lat)
    col = int((x_shadow + 4) / 8 * 64)
    lit = np.median(out[32, 50:60])
    assert out[32, col] < 0.3 * lit, (out[32, col], lit)


@pytest.mark.parametrize("sky", [4, 16])
def test_a_sky_above_the_horizon_lights_a_floor_with_pi_l_and_a_wall_with_half(sky):
    """An environment bright above the horizon (L = 0.8) and black below: a floor facing up sees all of it,
    E = π·L; a wall facing sideways sees the upper half of its hemisphere, E = π·L/2. The sky rays draw half of
    their directions from the luminance CDF (never below the horizon) and half cosine-weighted (half of them below),
    so a wrong mixture pdf for either technique biases one of the two walls' means."""
    h, w = 32, 64
    img = np.zeros((h, w, 3), np.float32)
    img[: h // 2] = 0.8
    b = SceneBuilder()
    m = b.add_material("white", diffuse=(0.5, 0.5, 0.5), specular=(0.0, 0.0, 0.0))
    quad(b, (0, 0, 0), 2.0, m, "floor")  # faces +z
    b.camera = Camera.look_at((0, 0, 5), (0, 0, 0), up=(0, 1, 0), projection="orthographic",
                              horizontal_aperture=1.0, vertical_aperture=1.0)
    b.environment = Environment(img)
    floor = render(b.build(), RenderSettings(width=16, height=16, sky_samples=sky, shading="classic")).rgb
    b = SceneBuilder()
    m = b.add_material("white", diffuse=(0.5, 0.5, 0.5), specular=(0.0, 0.0, 0.0))
    quad(b, (0, 0, 0), 2.0, m, "wall", normal_axis=0)  # faces +x
    b.camera = Camera.look_at((5, 0, 0), (0, 0, 0), up=(0, 0, 1), projection="orthographic",
                              horizontal_aperture=1.0, vertical_aperture=1.0)
    b.environment = Environment(img)
    wall = render(b.build(), RenderSettings(width=16, height=16, sky_samples=sky, shading="classic")).rgb
    np.testing.assert_allclose(floor.mean(), 0.5 * 0.8, rtol=0.01)
    np.testing.assert_allclose(wall.mean(), 0.5 * 0.8 / 2, rtol=0.02)

"""``whitted explain`` / tracer.explain: the recorded ray tree obeys the notes' laws (checked with the formulas
written here, not the tracer's), adds up to the rendered pixel, and the ray-type AOVs add up to the beauty."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from tracer import Camera, PointLight, RenderSettings, SceneBuilder
from tracer import render
from tracer.explain import explain_pixel, format_tree

from tracer_scenes import quad, sphere

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def glass_scene(classic=False):
    """A glass ball and a glass prism (flat faces: total internal reflection inside it) over a checker-free
    two-colour floor, a mirror on the side, two lights, blue sky."""
    b = SceneBuilder()
    glass = b.add_material("glass", diffuse=(0, 0, 0), transmission=1.0, ior=1.5)
    mirror = b.add_material("mirror", diffuse=(0, 0, 0), k_m=0.9, mirror_tint=(0.9, 0.95, 1.0))
    red = b.add_material("red", diffuse=(0.8, 0.15, 0.1), specular=(0.3, 0.3, 0.3), roughness=0.3)
    quad(b, (0, 0, -1.0), 30.0, red, "floor")
    quad(b, (4, 0, 2.0), 6.0, mirror, "mirror", normal_axis=0)
    sphere(b, (-0.8, 0, 0), 1.0, glass, "ball")
    # A triangular prism, apex up, flat faces.
    tri = np.array([[0.6, -0.6, -1.0], [2.2, -0.6, -1.0], [1.4, -0.6, 0.4]])
    v = np.vstack([tri, tri + [0, 1.2, 0]])
    faces = [[0, 2, 1], [3, 4, 5], [0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4], [2, 0, 3], [2, 3, 5]]
    b.add_mesh(v, faces, material=glass, name="prism")
    b.add_light(PointLight(position=(3, -4, 6), intensity=(120.0,) * 3, name="key"))
    b.add_light(PointLight(position=(-4, -2, 3), intensity=(40.0,) * 3, name="fill"))
    b.camera = Camera.look_at((0.5, -7, 1.5), (0.5, 0, 0), up=(0, 0, 1), focal_length=40.0)
    b.background = np.array([0.1, 0.3, 0.8], np.float32)
    return b.build()


@pytest.fixture(scope="module")
def scene():
    return glass_scene()


SETTINGS = RenderSettings(width=48, height=36, samples=1, max_depth=8)


def _all_rays(scene, settings, pixels):
    return [r for x, y in pixels for r in explain_pixel(scene, settings, x, y).rays()]


@pytest.fixture(scope="module")
def rays(scene):
    ys, xs = np.mgrid[0:SETTINGS.height:3, 0:SETTINGS.width:3]
    return _all_rays(scene, SETTINGS, zip(xs.ravel(), ys.ravel()))


def _parent(rays_by_id, r):
    return rays_by_id[r.parent]


def test_every_ray_type_occurs(rays):
    kinds = {r.type for r in rays}
    assert {"eye", "shadow", "reflection", "transmission"} <= kinds
    assert any(r.tir for r in rays), "the prism should show total internal reflection"
    assert any(r.occluded for r in rays) and any(r.occluded is False for r in rays)


def test_reflections_obey_the_mirror_law(scene):
    checked = 0
    for x, y in [(x, y) for y in range(0, 36, 2) for x in range(0, 48, 2)]:
        tree = explain_pixel(scene, SETTINGS, x, y).samples[0]
        for r in tree:
            if r.type != "reflection":
                continue
            d = tree[r.parent].direction
            n = r.normal
            assert abs(np.linalg.norm(n) - 1) < 1e-5 and np.dot(d, n) <= 1e-6  # unit, on the incident side
            expected = d - 2 * np.dot(d, n) * n
            assert np.allclose(r.direction, expected / np.linalg.norm(expected), atol=1e-5)
            checked += 1
    assert checked > 50


def test_transmissions_obey_snell_and_tir_is_where_the_radicand_is_negative(scene):
    refracted = tir = 0
    for x, y in [(x, y) for y in range(0, 36, 2) for x in range(0, 48, 2)]:
        tree = explain_pixel(scene, SETTINGS, x, y).samples[0]
        for r in tree:
            if r.eta_i is None:
                continue
            d, n = tree[r.parent].direction, r.normal
            cos_i = -np.dot(d, n)
            radicand = 1 - (r.eta_i / r.eta_r) ** 2 * (1 - cos_i**2)  # the notes' square-root argument
            if r.type == "transmission":
                assert not r.tir and radicand >= -1e-6
                t = r.direction
                sin_i = np.linalg.norm(np.cross(d, n))
                sin_r = np.linalg.norm(np.cross(t, n))
                assert abs(r.eta_i * sin_i - r.eta_r * sin_r) < 1e-5  # Snell: η_i sin θ_i = η_r sin θ_r
                assert abs(np.dot(np.cross(d, n), t)) < 1e-5  # d, n and t are coplanar
                assert np.dot(t, n) < 0  # it crosses the surface
                refracted += 1
            else:  # a reflection off glass: TIR exactly where the radicand is negative
                assert r.tir == (radicand < 0), (radicand, r.tir)
                tir += r.tir
    assert refracted > 20 and tir > 0


@pytest.mark.parametrize("n", [1, 2])
def test_contributions_add_up_to_the_rendered_pixel(scene, n):
    settings = SETTINGS.with_(samples=n)
    image = render(scene, settings)
    for x, y in [(10, 12), (24, 18), (30, 20), (5, 30), (40, 8), (20, 25)]:
        ex = explain_pixel(scene, settings, x, y)
        assert len(ex.samples) == n * n
        assert np.allclose(ex.color, image.rgba[y, x, :3], atol=1e-5), (x, y, ex.color, image.rgba[y, x])


def test_ray_type_aovs_add_up_to_the_beauty(scene):
    settings = SETTINGS.with_(samples=2, aovs=("direct", "reflection", "transmission", "raydepth"))
    image = render(scene, settings)
    a = image.aovs
    assert np.allclose(a["direct"] + a["reflection"] + a["transmission"], image.rgba[..., :3], atol=1e-5)
    assert a["reflection"].max() > 0.05 and a["transmission"].max() > 0.05
    assert np.allclose(image.rgba, render(scene, settings.with_(aovs=())).rgba, atol=1e-6)
    assert a["raydepth"].min() == 0 and 3 <= a["raydepth"].max() <= settings.max_depth


def test_a_mirror_shows_the_sky_in_the_reflection_aov_only():
    """Closed form: a perfect mirror (k_m = 1, tint t) seen head-on reflects the background c: reflection = t·c,
    direct = 0; around it the sky is seen directly: direct = c, reflection = 0."""
    b = SceneBuilder()
    m = b.add_material("mirror", diffuse=(0, 0, 0), k_m=1.0, mirror_tint=(0.5, 0.7, 0.9))
    quad(b, (0, 0, 0), 1.0, m, "mirror")
    b.camera = Camera.look_at((0.3, 0.2, 5), (0.3, 0.2, 0), up=(0, 1, 0), focal_length=50.0)
    b.background = np.array([0.2, 0.4, 0.6], np.float32)
    image = render(b.build(), RenderSettings(samples=1, width=32, height=32, aovs=("direct", "reflection", "raydepth")))
    a = image.aovs
    centre, corner = (16, 16), (0, 0)
    assert np.allclose(a["reflection"][centre], [0.1, 0.28, 0.54], atol=1e-6)
    assert np.allclose(a["direct"][centre], 0, atol=1e-7) and a["raydepth"][centre] == 1
    assert np.allclose(a["direct"][corner], [0.2, 0.4, 0.6], atol=1e-6) and a["raydepth"][corner] == 0
    assert np.allclose(a["reflection"][corner], 0)


def test_json_tree_and_text(scene):
    ex = explain_pixel(scene, SETTINGS.with_(samples=2), 24, 18)
    j = json.loads(json.dumps(ex.to_json()))
    assert j["pixel"] == [24, 18] and len(j["samples"]) == 4
    rays = j["samples"][0]["rays"]
    ids = {r["id"] for r in rays}
    for r in rays:
        assert set(r) >= {"id", "parent", "type", "origin", "direction", "t_max", "weight", "contribution", "hit"}
        assert r["parent"] is None if r["type"] == "eye" else r["parent"] in ids
        assert abs(np.linalg.norm(r["direction"]) - 1) < 1e-5
        if r["type"] in ("reflection", "transmission"):
            assert "normal" in r
        if r["type"] == "transmission":
            assert {"eta_i", "eta_r", "tir"} <= set(r)
        if r["type"] == "shadow":
            assert "light" in r and "occluded" in r and (not r["occluded"] or "blocker" in r)
        if r["hit"] is not None:
            assert set(r["hit"]) >= {"t", "point", "geometric_normal", "shading_normal", "object", "material",
                                     "front_face"}
    mean = np.mean([np.sum([r["contribution"] for r in s["rays"]], axis=0) for s in j["samples"]], axis=0)
    assert np.allclose(mean, j["color"], atol=1e-6)
    text = format_tree(ex)
    assert text.count("\n") + 1 == 1 + 4 + len(ex.rays())  # header, a line per sample, a line per ray


def test_usd_output_has_one_curve_per_ray(scene, tmp_path):
    from pxr import Usd, UsdGeom

    from usd_io.explain import write_ray_tree

    ex = explain_pixel(scene, SETTINGS, 24, 18)
    path = tmp_path / "rays.usda"
    write_ray_tree(ex, scene, str(path))
    stage = Usd.Stage.Open(str(path))
    n_curves = 0
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.BasisCurves):
            counts = UsdGeom.BasisCurves(prim).GetCurveVertexCountsAttr().Get()
            assert all(c == 2 for c in counts)
            n_curves += len(counts)
    assert n_curves == len(ex.rays())
    assert stage.GetPrimAtPath("/WhittedRays/Camera").IsA(UsdGeom.Camera)


def _whitted(*args):
    cmd = [sys.executable, "-c", "import sys; from usd_io.cli import main; sys.exit(main())", *map(str, args)]
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, env=env, timeout=300)


def test_cli_explains_the_rendered_pixel(tmp_path):
    scene_file = os.path.join(ROOT, "examples", "whitted_1980.usda")
    out = tmp_path / "r.exr"
    # render's flags, non-default ones included (explain once took --spp and had no --shading: issue #22)
    args = ("--width", 96, "--aa", 2, "--shading", "classic", "--max-depth", 3, "--no-fresnel", "--purposes",
            "default,render")
    assert _whitted("render", scene_file, "-o", out, *args, "--quiet").returncode == 0
    r = _whitted("explain", scene_file, "--pixel", 60, 30, *args, "--json", tmp_path / "t.json",
                 "--usd", tmp_path / "t.usda", "--png", tmp_path / "t.png")
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("pixel (60, 30) = ")
    from tracer import read_image

    j = json.loads((tmp_path / "t.json").read_text())
    assert np.allclose(j["color"], read_image(out)[30, 60, :3], atol=2e-3)  # EXR stores half floats
    png = read_image(tmp_path / "t.png")
    assert png.shape[:2] == read_image(out).shape[:2]
    bad = _whitted("explain", scene_file, "--pixel", 500, 30, *args)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "outside" in bad.stderr


def test_cli_ray_type_aovs_and_raydepth_heat_map(tmp_path):
    from tracer import read_image

    scene_file = os.path.join(ROOT, "examples", "whitted_1980.usda")
    out = tmp_path / "r.png"
    r = _whitted("render", scene_file, "-o", out, "--width", 80, "--spp", 1, "--quiet",
                 "--aov", "direct,reflection,transmission,raydepth")
    assert r.returncode == 0, r.stderr
    parts = [read_image(tmp_path / f"r.{k}.exr")[..., :3] for k in ("direct", "reflection", "transmission")]
    beauty = read_image(out)[..., :3]  # sRGB-encoded 8-bit
    from tracer.colorspace import linear_to_srgb

    assert np.abs(linear_to_srgb(sum(parts)) - beauty).max() < 3 / 255  # half-float EXRs, 8-bit PNG
    depth = read_image(tmp_path / "r.raydepth.exr")[..., 0]
    heat = read_image(tmp_path / "r.raydepth.png")
    assert depth.max() >= 3 and heat.shape[:2] == depth.shape
    assert np.all(heat[depth == 0, :3] < 0.05) and np.all(heat[depth == depth.max(), :3].max(axis=-1) > 0.3)

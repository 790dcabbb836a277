"""Denoising (issue #33): tracer/denoise.py (Open Image Denoise through our ctypes binding), the guides of
tracer/integrator/guides.py, ``RenderSettings.denoise`` through the API and ``whitted render --denoise``.

The denoiser is judged against a converged render of the same scene, never against itself: a soft-shadow scene
under a sky at AA 1 with 4 light and 4 sky samples is noisy; the same scene with 400 of each is the reference (same
anti-aliasing pattern, so what differs is the sampling noise the denoiser is for). The guides are compared with
Cycles' own passes in tests/cycles/test_cycles_denoise.py."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

import tracer
from tracer import Camera, PointLight, RenderSettings, SceneBuilder, render
from tracer import denoise as dn

from tracer_scenes import quad, sphere

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
W, H = 96, 72


def _psnr(a, b) -> float:
    a, b = np.asarray(a, np.float64)[..., :3], np.asarray(b, np.float64)[..., :3]
    return float(10 * np.log10(b.max() ** 2 / np.mean((a - b) ** 2)))


def soft_shadow_scene(mirror: bool = False):
    """A red ball on a grey floor under a sphere light of radius 1 and a grey-blue sky (soft shadows from both);
    with ``mirror`` a chrome ball beside it."""
    b = SceneBuilder()
    grey = b.add_material("grey", diffuse=(0.8, 0.8, 0.8))
    red = b.add_material("red", diffuse=(0.8, 0.2, 0.1))
    quad(b, (0, 0, 0), 40.0, grey, "floor")
    sphere(b, (0, 0, 1), 1.0, red, "ball")
    if mirror:
        chrome = b.add_material("chrome", diffuse=(0.9, 0.9, 0.9), metallic=1.0, roughness=0.0)
        sphere(b, (2.2, 0.5, 1), 1.0, chrome, "chrome")
    b.add_light(PointLight(position=(2.0, -1.0, 4.0), intensity=(60.0,) * 3, radius=1.0))
    b.ambient = np.array([0.15, 0.18, 0.25], np.float32)
    b.camera = Camera.look_at((0, -8, 3), (0, 0, 0.8), up=(0, 0, 1), focal_length=35.0,
                              horizontal_aperture=36.0, vertical_aperture=27.0)
    return b.build()


@pytest.fixture(scope="module")
def scene():
    return soft_shadow_scene()


NOISY = dict(width=W, height=H, samples=1, light_samples=4, sky_samples=4)


# ---------------------------------------------------------------------------------------------- the filter
def test_denoise_keeps_shape_and_alpha_and_returns_no_nan():
    rng = np.random.default_rng(1)
    rgba = rng.exponential(0.5, (40, 56, 4)).astype(np.float32)
    rgba[..., 3] = rng.uniform(0, 1, (40, 56))
    rgba[3, 4, 0], rgba[5, 6, 1], rgba[7, 8, 2] = np.nan, np.inf, -np.inf
    albedo = np.full((40, 56, 3), 0.5, np.float32)
    normal = np.zeros((40, 56, 3), np.float32)
    normal[..., 2] = -1
    out = dn.denoise(rgba, albedo, normal)
    assert out.shape == rgba.shape and out.dtype == np.float32
    assert np.array_equal(out[..., 3], rgba[..., 3])  # alpha passes through
    assert np.all(np.isfinite(out))
    assert not np.array_equal(out[..., :3], np.nan_to_num(rgba[..., :3]))  # it did filter
    rgb = dn.denoise(rgba[..., :3], prefilter="fast", quality="balanced")  # RGB, no guides: same shape
    assert rgb.shape == (40, 56, 3) and np.all(np.isfinite(rgb))
    assert dn.denoise(np.zeros((0, 5, 3), np.float32)).shape == (0, 5, 3)
    with pytest.raises(ValueError, match="albedo"):
        dn.denoise(rgba, albedo[:10])
    with pytest.raises(ValueError, match="prefilter"):
        dn.denoise(rgba, prefilter="sometimes")


def test_the_library_is_oidn_2_and_says_where_it_came_from():
    lib = dn.library()
    assert dn.version().startswith("2.")
    assert os.path.isfile(lib.path) or lib.path.startswith("lib")


def _filter_devices(monkeypatch) -> list:
    """The OIDN devices every RT filter is made on from now (a spy on ``oidnNewFilter``)."""
    lib = dn.library()
    real, used = lib.lib.oidnNewFilter, []

    def spy(device, kind):
        used.append(device)
        return real(device, kind)

    monkeypatch.setattr(lib.lib, "oidnNewFilter", spy)
    return used


@pytest.mark.skipif("OIDN_NUM_THREADS" in os.environ, reason="OIDN's own variable overrides numThreads")
def test_the_filter_runs_on_the_thread_count_it_is_given(monkeypatch):
    """OIDN's device parameter ``numThreads`` reaches the device every filter runs on (read back from OIDN after
    the device is committed), for the function and for a render's ``threads`` (``--threads``)."""
    lib = dn.library()
    every = lib.threads_of(None)  # OIDN's default: every core it may use
    assert every >= 1
    used = _filter_devices(monkeypatch)
    rgb = np.random.default_rng(2).exponential(0.5, (24, 32, 3)).astype(np.float32)
    guide = np.full((24, 32, 3), 0.5, np.float32)
    dn.denoise(rgb, guide, guide, threads=1)  # accurate: three filters, all on the one-thread device
    assert len(used) == 3
    assert {int(lib.lib.oidnGetDeviceInt(d, b"numThreads")) for d in used} == {1}
    used.clear()
    dn.denoise(rgb, guide, guide, prefilter="none")  # no count: OIDN's default device
    assert [int(lib.lib.oidnGetDeviceInt(d, b"numThreads")) for d in used] == [every]
    used.clear()
    image = render(soft_shadow_scene(), RenderSettings(width=16, height=12, samples=1, threads=1, denoise=True))
    assert used and {int(lib.lib.oidnGetDeviceInt(d, b"numThreads")) for d in used} == {1}
    assert image.stats["denoise"]["threads"] == 1
    assert lib.device_for(1) == lib.device_for(1)  # one device per count, made once


def test_a_missing_library_is_one_clear_exception(monkeypatch):
    monkeypatch.setattr(dn, "_LIBRARY", None)
    monkeypatch.setenv(dn.LIBRARY_ENV, "/nonexistent/libOpenImageDenoise.so.2")
    with pytest.raises(dn.DenoiseUnavailable, match=dn.LIBRARY_ENV):
        dn.check()
    assert not dn.available()
    monkeypatch.delenv(dn.LIBRARY_ENV)  # nothing anywhere: the message says how to get one
    monkeypatch.setattr(dn, "search_dirs", lambda: [])
    monkeypatch.setattr(dn.ctypes.util, "find_library", lambda name: None)
    with pytest.raises(dn.DenoiseUnavailable, match=r"pip install 'whitted\[denoise\]'"):
        dn.denoise(np.zeros((4, 4, 3), np.float32))
    traced = []  # a render that would denoise fails before it traces anything
    import tracer.integrator.tiles as tiles_module

    monkeypatch.setattr(tiles_module, "trace_tile", lambda *a, **k: traced.append(1))
    with pytest.raises(dn.DenoiseUnavailable):
        render(soft_shadow_scene(), RenderSettings(width=8, height=6, denoise=True))
    assert not traced


# ---------------------------------------------------------------------------------------------- renders
def test_denoised_render_is_closer_to_the_converged_reference_than_the_noisy_one(scene):
    reference = render(scene, RenderSettings(**dict(NOISY, light_samples=400, sky_samples=400)))
    noisy = render(scene, RenderSettings(**NOISY))
    denoised = render(scene, RenderSettings(**NOISY, denoise=True))
    p_noisy, p_denoised = _psnr(noisy.rgba, reference.rgba), _psnr(denoised.rgba, reference.rgba)
    print(f"noisy {p_noisy:.2f} dB, denoised {p_denoised:.2f} dB against 400 light and sky samples")
    assert p_denoised > p_noisy + 2.0, (p_noisy, p_denoised)
    assert denoised.stats["denoise"]["prefilter"] == "none"  # a pinhole, nothing moves: the guides are clean
    assert not denoised.aovs  # the guides were made for the filter, not asked for as outputs


def test_denoising_changes_only_the_picture_and_asked_guides_are_kept(scene):
    asked = ("denoising_albedo", "denoising_normal", "depth")
    noisy = render(scene, RenderSettings(**NOISY, aovs=asked))
    denoised = render(scene, RenderSettings(**NOISY, aovs=asked, denoise=True))
    for name in asked:  # the AOVs are the same with and without the filter
        assert np.array_equal(noisy.aovs[name], denoised.aovs[name]), name
    assert np.array_equal(noisy.rgba[..., 3], denoised.rgba[..., 3])
    assert not np.array_equal(noisy.rgba[..., :3], denoised.rgba[..., :3])


def test_guides_are_first_non_specular_hits_through_a_mirror():
    """Through a chrome ball the albedo is the chrome's reflectance × the albedo of what it mirrors (the floor's
    0.8 grey), and the normal the mirrored floor's; without the specular chain it would be the chrome's own."""
    scene = soft_shadow_scene(mirror=True)
    img = render(scene, RenderSettings(width=W, height=H, samples=2, sky_samples=0,
                                       aovs=("denoising_albedo", "denoising_normal", "objectid")))
    albedo, normal = img.aovs["denoising_albedo"], img.aovs["denoising_normal"]
    chrome = scene.object_names.index("chrome")
    floor = scene.object_names.index("floor")
    ids = img.aovs["objectid"]
    inner = lambda m: m & np.roll(m, 1, 0) & np.roll(m, -1, 0) & np.roll(m, 1, 1) & np.roll(m, -1, 1)  # noqa: E731
    on_floor = inner(ids == floor)  # (pixels whose samples all see the floor)
    np.testing.assert_allclose(albedo[on_floor][:, 0], 0.8, atol=1e-4)  # Lambert grey: its colour
    # the floor (world +z) in camera space: up and towards the camera (negative z, along the view)
    n_floor = normal[on_floor].mean(axis=0)
    assert n_floor[1] > 0.5 and n_floor[2] < -0.1 and abs(n_floor[0]) < 1e-3
    # the chrome's lower half mirrors the floor: a dimmer grey of equal channels, the floor's normal
    rows = np.flatnonzero((ids == chrome).any(axis=1))
    lower = inner(ids == chrome) & (np.arange(H)[:, None] > rows[0] + 0.7 * (rows[-1] - rows[0]))
    assert lower.sum() > 20
    a = albedo[lower]
    assert np.all(a[:, 0] > 0.3) and np.all(a[:, 0] < 0.8)
    np.testing.assert_allclose(normal[lower].mean(axis=0), n_floor, atol=0.05)
    ours_first = img  # the plain first-hit albedo AOV is the chrome's own colour there: a different thing
    assert not np.allclose(render(scene, RenderSettings(width=W, height=H, samples=2, sky_samples=0,
                                                        aovs=("albedo",))).aovs["albedo"][lower], a)
    assert ours_first.stats["rays"]["reflection"] > 0


def test_render_tile_never_denoises_and_carries_the_guides(scene):
    from tracer import Session, render_tile

    settings = RenderSettings(**NOISY, denoise=True)
    with Session(scene) as session:
        tile = render_tile(session, settings, (0, 0, 32, 24))
        plain = render_tile(session, settings.with_(denoise=False), (0, 0, 32, 24))
    assert np.array_equal(tile.rgba, plain.rgba)
    assert set(dn.GUIDE_AOVS) <= set(tile.aovs)  # for the frame's denoise, once assembled (tracer/farm.py)


def test_guides_cost_nothing_when_not_asked(scene):
    from tracer import Session

    with Session(scene) as session:
        integ = session.integrator(RenderSettings(**NOISY))
        o = np.array([[0, -8, 3]], np.float32)
        d = np.array([[0, 1, -0.3]], np.float32) / np.float32(np.linalg.norm([0, 1, -0.3]))
        res = integ.trace(o, d, np.zeros(1, np.int64))
        assert res.guide_albedo is None and res.guide_normal is None
        res = integ.trace(o, d, np.zeros(1, np.int64), guides=True)
        assert res.guide_albedo.shape == (1, 3) and res.guide_albedo[0, 0] > 0


# ---------------------------------------------------------------------------------------------- command line
def _whitted(*args, env=None):
    cmd = [sys.executable, "-c", "from usd_io.cli import run; run()", *map(str, args)]
    full = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""), **(env or {}))
    return subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, env=full, timeout=600)


@pytest.fixture(scope="module")
def stage(tmp_path_factory):
    from pxr import Gf, Usd, UsdGeom, UsdLux

    path = tmp_path_factory.mktemp("denoise") / "soft.usda"
    s = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(s, "Z")
    cam = UsdGeom.Camera.Define(s, "/Cam")
    cam.CreateHorizontalApertureAttr(4.0)
    cam.CreateVerticalApertureAttr(3.0)
    cam.CreateFocalLengthAttr(4.0)
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 8))
    UsdGeom.Sphere.Define(s, "/Ball").AddTranslateOp().Set(Gf.Vec3d(0, 0, 0))
    floor = UsdGeom.Cube.Define(s, "/Floor")
    floor.AddTranslateOp().Set(Gf.Vec3d(0, 0, -2))
    floor.AddScaleOp().Set(Gf.Vec3f(6, 6, 0.5))
    light = UsdLux.SphereLight.Define(s, "/Light")
    light.CreateIntensityAttr(300.0)
    light.CreateRadiusAttr(1.0)
    light.AddTranslateOp().Set(Gf.Vec3d(2, 2, 6))
    s.GetRootLayer().Save()
    return path


def test_cli_denoise_flag_writes_the_denoised_picture_and_the_guides(stage, tmp_path):
    from tracer import read_image

    common = ("--width", 64, "--aa", 1, "--light-samples", 4, "--quiet")
    assert _whitted("render", stage, "-o", tmp_path / "noisy.exr", *common).returncode == 0
    res = _whitted("render", stage, "-o", tmp_path / "clean.exr", *common, "--denoise",
                   "--aov", "denoising_albedo,denoising_normal")
    assert res.returncode == 0, res.stderr
    noisy, clean = read_image(str(tmp_path / "noisy.exr")), read_image(str(tmp_path / "clean.exr"))
    assert noisy.shape == clean.shape and not np.allclose(noisy[..., :3], clean[..., :3], atol=1e-3)
    albedo = read_image(str(tmp_path / "clean.denoising_albedo.exr"))
    normal = read_image(str(tmp_path / "clean.denoising_normal.exr"))
    assert albedo.shape == normal.shape == noisy.shape[:2] + (3,)
    assert albedo.max() > 0.1 and np.abs(normal).max() > 0.5
    # a PNG is not streamed band by band while a denoised render runs: its pixels are the denoised ones
    assert _whitted("render", stage, "-o", tmp_path / "clean.png", *common, "--denoise").returncode == 0
    png = read_image(str(tmp_path / "clean.png"))
    srgb = np.round(tracer.film.to_display(clean)[..., :3].astype(np.float32)) / 255.0
    assert np.abs(png[..., :3] - srgb).max() <= 1.5 / 255.0


def test_cli_denoise_without_a_library_is_one_line_and_exit_2(stage, tmp_path):
    res = _whitted("render", stage, "-o", tmp_path / "x.png", "--width", 16, "--denoise",
                   env={dn.LIBRARY_ENV: "/nonexistent/libOpenImageDenoise.so.2"})
    assert res.returncode == 2, res.stderr
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "--denoise" in lines[0] and dn.LIBRARY_ENV in lines[0], res.stderr
    assert not (tmp_path / "x.png").exists()

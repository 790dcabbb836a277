"""The `whitted` command line, run as a subprocess: renders, frames, AOVs, `info`, and every bad-input exit code
(2, with one line on stderr naming the file and the problem)."""

from __future__ import annotations

import os
import re
import subprocess
import sys

import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom, UsdLux

from tracer import read_image

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def whitted(*args, cwd=None):
    cmd = [sys.executable, "-c", "from usd_io.cli import run; run()", *map(str, args)]  # as the whitted script
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run(cmd, capture_output=True, text=True, cwd=cwd or ROOT, env=env, timeout=300)


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    path = d / "ball.usda"
    s = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(s, "Z")
    cam = UsdGeom.Camera.Define(s, "/Cam")
    cam.CreateHorizontalApertureAttr(4.0)
    cam.CreateVerticalApertureAttr(3.0)
    cam.CreateFocalLengthAttr(5.0)
    cam.CreateClippingRangeAttr(Gf.Vec2f(1.0, 100.0))  # depth is measured from the eye, not the near plane
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 8))
    ball = UsdGeom.Sphere.Define(s, "/Ball")
    op = ball.AddTranslateOp()
    op.Set(Gf.Vec3d(-2, 0, 0), 1.0)
    op.Set(Gf.Vec3d(2, 0, 0), 3.0)
    light = UsdLux.DistantLight.Define(s, "/Sun")
    light.CreateIntensityAttr(1.0)
    s.GetRootLayer().Save()
    return path


def one_line_error(res, *needles):
    assert res.returncode == 2, res.stderr
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, res.stderr
    for n in needles:
        assert n in lines[0], lines[0]


def test_render_png_with_aovs(scene_file, tmp_path):
    out = tmp_path / "out.png"
    res = whitted("render", scene_file, "-o", out, "--width", 40, "--spp", 1, "--aov", "depth,objectid", "--quiet")
    assert res.returncode == 0, res.stderr
    img = read_image(str(out))
    assert img.shape[:2] == (30, 40)  # height from the 4:3 aperture
    depth = read_image(str(tmp_path / "out.depth.exr"))[..., 0]
    hit = depth > 0  # misses are stored as 0
    assert 20 < hit.sum() < 40 * 30 / 2
    # the ball (radius 1 at (-2, 0, 0) at the earliest time) is |eye - centre| - 1 from the eye at its closest
    assert depth[hit].min() == pytest.approx(np.sqrt(4 + 64) - 1, abs=0.05 + 0.01)
    assert (tmp_path / "out.objectid.exr").exists()
    assert not [f for f in os.listdir(tmp_path) if f.startswith(".whitted-")]  # no temp files left


def test_frames_pattern(scene_file, tmp_path):
    res = whitted("render", scene_file, "-o", tmp_path / "f.####.exr", "--width", 32, "--spp", 1,
                  "--frames", "1:3", "--quiet")
    assert res.returncode == 0, res.stderr
    frames = [read_image(str(tmp_path / f"f.{i:04d}.exr"))[..., :3] for i in (1, 2, 3)]
    lum = [f.sum(axis=2) for f in frames]
    cx = [np.average(np.arange(32), weights=l.sum(axis=0)) for l in lum]
    assert cx[0] < cx[1] < cx[2]  # the ball moves right over time
    res = whitted("render", scene_file, "-o", tmp_path / "g.png", "--width", 16, "--frames", "1:3x2", "--quiet")
    assert res.returncode == 0 and sorted(os.listdir(tmp_path))[-2:] == ["g.0001.png", "g.0003.png"]


def test_info(scene_file):
    res = whitted("info", scene_file)
    assert res.returncode == 0, res.stderr
    assert "/Cam" in res.stdout and "DistantLight" in res.stdout
    assert re.search(r"/Ball: [\d,]+ triangles", res.stdout)


def test_progress_bar_unless_quiet(scene_file, tmp_path):
    res = whitted("render", scene_file, "-o", tmp_path / "p.png", "--width", 16)
    assert res.returncode == 0 and "tile" in res.stderr
    res = whitted("render", scene_file, "-o", tmp_path / "q.png", "--width", 16, "--quiet")
    assert res.returncode == 0 and res.stderr == ""


def test_bad_inputs_exit_2_with_one_line(scene_file, tmp_path):
    missing = tmp_path / "nothere.usda"
    one_line_error(whitted("render", missing, "-o", tmp_path / "o.png"), str(missing), "no such file")
    junk = tmp_path / "junk.usda"
    junk.write_text("this is not usd\n")
    one_line_error(whitted("render", junk, "-o", tmp_path / "o.png"), str(junk), "not a readable USD file")
    txt = tmp_path / "notes.txt"
    txt.write_text("hello")
    one_line_error(whitted("render", txt, "-o", tmp_path / "o.png"), str(txt), "not a USD file")
    one_line_error(whitted("render", scene_file, "-o", tmp_path / "o.png", "--camera", "/Nope"),
                   str(scene_file), "/Nope")
    one_line_error(whitted("render", scene_file, "-o", tmp_path / "o.png", "--camera", "/Ball"), "not a Camera")
    one_line_error(whitted("render", scene_file, "-o", tmp_path / "o.png", "--width", 0), str(scene_file), "width")
    one_line_error(whitted("render", scene_file, "-o", tmp_path / "o.png", "--height", "-3"), "height")
    for frames in ("5:1", "a:b", "1:5x0"):
        one_line_error(whitted("render", scene_file, "-o", tmp_path / "o.png", "--frames", frames), "--frames")
    one_line_error(whitted("render", scene_file, "-o", tmp_path / "o.xyz"), "o.xyz", "unsupported output")
    one_line_error(whitted("render", scene_file, "-o", tmp_path / "no" / "o.png"), "does not exist")
    one_line_error(whitted("render", scene_file, "-o", tmp_path / "o.png", "--aov", "beauty"), "beauty")
    one_line_error(whitted("render", scene_file), "-o")
    one_line_error(whitted("info", missing), str(missing))
    assert not (tmp_path / "o.png").exists()


def test_missing_reference_warns_once_and_renders(tmp_path):
    ok = Usd.Stage.CreateNew(str(tmp_path / "ok.usda"))
    UsdGeom.Sphere.Define(ok, "/Asset")
    ok.SetDefaultPrim(ok.GetPrimAtPath("/Asset"))
    ok.GetRootLayer().Save()
    s = Usd.Stage.CreateNew(str(tmp_path / "shot.usda"))
    s.DefinePrim("/A").GetReferences().AddReference("./ok.usda")
    s.DefinePrim("/B").GetReferences().AddReference("./lost.usda")
    s.DefinePrim("/C").GetReferences().AddReference("./lost.usda")
    s.GetRootLayer().Save()
    res = whitted("render", tmp_path / "shot.usda", "-o", tmp_path / "shot.exr", "--width", 24, "--quiet",
                  "--aov", "objectid")
    assert res.returncode == 0, res.stderr
    assert res.stderr.count("lost.usda") == 1, res.stderr
    assert "no camera" in res.stderr
    ids = read_image(str(tmp_path / "shot.objectid.exr"))[..., 0]
    assert (ids == 0).sum() > 20  # the sphere that resolved is in the picture


def test_whitted_1980_example_renders(tmp_path):
    out = tmp_path / "w.png"
    res = whitted("render", os.path.join(ROOT, "examples", "whitted_1980.usda"), "-o", out, "--width", 96,
                  "--spp", 1, "--quiet")
    assert res.returncode == 0, res.stderr
    img = read_image(str(out))[..., :3]
    assert img.shape == (54, 96, 3)
    sky = img[2, 48]
    assert sky[2] > sky[0] + 0.3  # blue sky at the top
    floor = img[-3]
    assert floor[:, 0].max() > 0.5 and floor[:, 1].max() > 0.5  # red and yellow squares at the bottom


def test_purposes_take_one_comma_separated_value(scene_file):
    """README writes `--purposes render,proxy,guide`; argparse alone would read that as one unknown purpose. One
    value, so the scene after it stays a scene (issue #30: `--purposes render SCENE` swallowed SCENE)."""
    from usd_io.cli import build_parser, split_purposes

    args = build_parser().parse_args(["info", str(scene_file), "--purposes", "default,render,proxy"])
    assert split_purposes(args.purposes) == ("default", "render", "proxy")
    args = build_parser().parse_args(["render", "--purposes", "render", str(scene_file), "-o", "x.png"])
    assert args.scenes == [str(scene_file)] and split_purposes(args.purposes) == ("render",)
    res = whitted("info", scene_file, "--purposes", "default,render")
    assert res.returncode == 0 and "/Ball" in res.stdout, res.stderr
    one_line_error(whitted("info", scene_file, "--purposes", "default,nope"), "nope")


def test_a_stage_without_lights_is_lit_by_default_with_one_note(tmp_path):
    """The usd-wg assets carry no lights: they must not render black with exit 0 (usdview lights them)."""
    path = tmp_path / "asset.usda"
    s = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(s, "Y")
    UsdGeom.Sphere.Define(s, "/Asset/Ball")
    s.GetRootLayer().Save()
    lit, dark = tmp_path / "lit.png", tmp_path / "dark.png"
    r = whitted("render", path, "-o", lit, "--width", 32, "--quiet")
    assert r.returncode == 0 and r.stderr.count("whitted: note:") == 1 and "no lights" in r.stderr, r.stderr
    img = read_image(lit)
    assert img[16, 16, :3].min() > 0.5  # the ball's centre faces the headlight
    r = whitted("render", path, "-o", dark, "--width", 32, "--quiet", "--disableCameraLight")
    assert r.returncode == 0 and "note" not in r.stderr
    assert read_image(dark)[..., :3].max() == 0


def test_shading_flag_chooses_the_local_model(tmp_path):
    """--shading classic renders the notes' Blinn-Phong, the default the Principled GGX lobe: a rough gold sphere
    under a sun differs between the two (the highlight's shape and the metal's Fresnel), and each run is the same
    as RenderSettings(shading=...) through the API."""
    from pxr import Sdf, UsdShade

    from tracer import RenderSettings
    from tracer import render
    from usd_io import load_stage

    path = tmp_path / "gold.usda"
    s = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(s, "Z")
    cam = UsdGeom.Camera.Define(s, "/Cam")
    cam.CreateFocalLengthAttr(20.0)
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 6))
    ball = UsdGeom.Sphere.Define(s, "/Ball")
    mat = UsdShade.Material.Define(s, "/Gold")
    ps = UsdShade.Shader.Define(s, "/Gold/PS")
    ps.CreateIdAttr("UsdPreviewSurface")
    ps.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(1.0, 0.77, 0.34))
    ps.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(1.0)
    ps.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.4)
    mat.CreateSurfaceOutput().ConnectToSource(ps.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(ball.GetPrim()).Bind(mat)
    UsdLux.DistantLight.Define(s, "/Sun")  # the spec default: 50 000 over 0.53°, about 3.4 W/m²
    s.GetRootLayer().Save()
    images = {}
    for model in ("classic", "principled"):
        out = tmp_path / f"{model}.exr"
        res = whitted("render", path, "-o", out, "--width", 32, "--aa", 1, "--shading", model, "--quiet")
        assert res.returncode == 0, res.stderr
        images[model] = read_image(str(out))[..., :3]
        scene, info = load_stage(str(path), width=32)
        api = render(scene, RenderSettings(width=info.width, height=info.height, samples=1, shading=model)).rgb
        np.testing.assert_allclose(images[model], api, rtol=1e-3, atol=1e-6)  # the beauty EXR is half-float
    assert np.abs(images["classic"] - images["principled"]).max() > 0.05


def test_adaptive_sampling_flags_and_the_sample_count_aov(tmp_path):
    """--adaptive-threshold / --adaptive-min-samples reach the render; --aov sample_count writes each pixel's
    samples (EXR) and a heat map of them (PNG): a ball's soft shadow takes more than the open ground."""
    path = tmp_path / "shadow.usda"
    s = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(s, "Z")
    cam = UsdGeom.Camera.Define(s, "/Cam")
    cam.CreateFocalLengthAttr(3.0)
    cam.CreateHorizontalApertureAttr(4.0)
    cam.CreateVerticalApertureAttr(3.0)
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 8))  # looking down -Z at the ground
    UsdGeom.Sphere.Define(s, "/Ball").AddTranslateOp().Set(Gf.Vec3d(0, 0, 1))
    ground = UsdGeom.Mesh.Define(s, "/Ground")
    ground.CreatePointsAttr([(-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0)])
    ground.CreateFaceVertexCountsAttr([4])
    ground.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    light = UsdLux.SphereLight.Define(s, "/Lamp")
    light.CreateRadiusAttr(1.0)
    light.CreateIntensityAttr(30.0)
    light.AddTranslateOp().Set(Gf.Vec3d(3, -2, 6))
    s.GetRootLayer().Save()
    out = tmp_path / "out.exr"
    res = whitted("render", path, "-o", out, "--width", 40, "--aa", 6, "--light-samples", 1, "--adaptive-threshold",
                  0.01, "--adaptive-min-samples", 8, "--aov", "sample_count", "--quiet")
    assert res.returncode == 0, res.stderr
    count = read_image(str(tmp_path / "out.sample_count.exr"))[..., 0]
    assert count.min() == 8 and count.max() == 36
    assert 0.05 < (count == 36).mean() < 0.5, (count == 36).mean()
    assert (tmp_path / "out.sample_count.png").exists()
    res = whitted("render", path, "-o", tmp_path / "x.png", "--adaptive-threshold", "2")
    one_line_error(res, "--adaptive-threshold")

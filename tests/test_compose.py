"""Holdouts and shadow catchers (tracer.integrator.compose) against references that do not use them: the same scene rendered
without the flag, its object-id AOV, and the closed forms of a point light's hard shadow (no Blender needed)."""

import os
import subprocess
import sys

import numpy as np
import pytest

from tracer import RenderSettings
from tracer import render
from tracer_scenes import lit_sphere_on_floor

FLOOR, BALL = 0, 1
SIZE = dict(width=40, height=30, samples=1, threads=1)


@pytest.fixture(scope="module")
def plain():
    """The lit ball on its floor without any flag, with its object ids, and its blue world (no ambient light)."""
    b = lit_sphere_on_floor()
    b.background = np.array([0.2, 0.3, 0.5], np.float32)
    scene = b.build()
    img = render(scene, RenderSettings(aovs=("objectid",), **SIZE))
    return scene, img


def test_a_holdout_object_is_cut_out_and_still_casts_its_shadow(plain):
    """Where the eye sees the holdout ball: alpha 0, colour 0; everywhere else (the floor with the ball's shadow,
    the world) the picture is the plain render's, alpha 1."""
    scene, ref = plain
    scene.object_holdout = np.array([False, True])
    try:
        img = render(scene, RenderSettings(**SIZE))
    finally:
        scene.object_holdout = None
    ball = ref.aovs["objectid"] == BALL
    assert ball.sum() > 30
    assert np.all(img.rgba[ball] == 0.0)
    np.testing.assert_allclose(img.rgba[~ball], ref.rgba[~ball], atol=1e-6)


def _catcher(scene, **settings):
    scene.object_shadow_catcher = np.array([True, False])
    try:
        return render(scene, RenderSettings(**SIZE, **settings))
    finally:
        scene.object_shadow_catcher = None


def test_shadow_catcher_pass_is_the_shadow(plain):
    """A point light's shadow is hard and nothing else lights the floor: the Shadow Catcher pass is 0 where the
    plain floor is black (the umbra), 1 where it is lit, and 1 off the floor."""
    scene, ref = plain
    img = _catcher(scene, transparent=True, aovs=("shadow_catcher",))
    floor = ref.aovs["objectid"] == FLOOR
    lit = ref.rgb.max(axis=-1) > 0
    assert (floor & ~lit).sum() > 10 and (floor & lit).sum() > 100
    catcher = img.aovs["shadow_catcher"]
    np.testing.assert_allclose(catcher[floor & lit], 1.0, atol=1e-5)
    np.testing.assert_allclose(catcher[floor & ~lit], 0.0, atol=1e-6)
    np.testing.assert_allclose(catcher[~floor], 1.0, atol=1e-6)
    # with the pass asked for, Combined is the matte: the ball as rendered, the catcher fully transparent
    ball = ref.aovs["objectid"] == BALL
    np.testing.assert_allclose(img.rgba[ball], ref.rgba[ball], atol=1e-6)
    assert np.all(img.rgba[floor] == 0.0)


@pytest.mark.parametrize("transparent", [True, False])
def test_shadow_catcher_combined(plain, transparent):
    """Combined without the pass (Cycles' approximation): on a transparent film the floor is black with alpha =
    its shadow (1 in the umbra, 0 where lit); on an opaque film the world shows through, darkened by the shadow."""
    scene, ref = plain
    img = _catcher(scene, transparent=transparent)
    floor = ref.aovs["objectid"] == FLOOR
    lit = ref.rgb.max(axis=-1) > 0
    world = np.array([0.2, 0.3, 0.5], np.float32)
    if transparent:
        expect_lit, expect_shadow = (0, 0, 0, 0), (0, 0, 0, 1)
    else:
        expect_lit, expect_shadow = (*world, 1), (0, 0, 0, 1)
    for mask, expect in ((floor & lit, expect_lit), (floor & ~lit, expect_shadow)):
        got = img.rgba[mask]
        np.testing.assert_allclose(got, np.broadcast_to(np.asarray(expect, np.float32), got.shape), atol=1e-5)
    ball = ref.aovs["objectid"] == BALL
    np.testing.assert_allclose(img.rgba[ball], ref.rgba[ball], atol=1e-6)


# ------------------------------------------------------------------------------------------ USD, `whitted render`
def _usd_stage(path, matte: bool):
    """A top-down orthographic view of a floor with a card over its left part; ``matte``: the card carries
    ``primvars:arnold:matte = true`` (on its parent Xform: the primvar is inherited)."""
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux

    s = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(s, "Z")
    cam = UsdGeom.Camera.Define(s, "/Cam")
    cam.CreateProjectionAttr("orthographic")
    cam.CreateHorizontalApertureAttr(40.0)  # tenths of a scene unit: a view 4 units wide
    cam.CreateVerticalApertureAttr(40.0)
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 6))

    def quad(name, x0, x1, half, z):
        m = UsdGeom.Mesh.Define(s, name)
        m.CreatePointsAttr([(x0, -half, z), (x1, -half, z), (x1, half, z), (x0, half, z)])
        m.CreateFaceVertexCountsAttr([4])
        m.CreateFaceVertexIndicesAttr([0, 1, 2, 3])

    quad("/Floor", -5.0, 5.0, 5.0, 0.0)
    group = UsdGeom.Xform.Define(s, "/Holdouts")
    quad("/Holdouts/Card", -3.0, -0.5, 3.0, 1.0)
    if matte:
        UsdGeom.PrimvarsAPI(group.GetPrim()).CreatePrimvar("arnold:matte", Sdf.ValueTypeNames.Bool,
                                                           UsdGeom.Tokens.constant).Set(True)
    UsdLux.DistantLight.Define(s, "/Sun").CreateIntensityAttr(2.0)
    s.Save()


def test_usd_matte_is_a_holdout_through_whitted_render(tmp_path):
    """`whitted render` of a stage whose card is an Arnold matte writes alpha 0 exactly where the card is seen
    (its object ids in the render of the same stage without the primvar) and 1 elsewhere, into the EXR."""
    from tracer import read_image
    from usd_io import load_stage

    _usd_stage(tmp_path / "matte.usda", matte=True)
    _usd_stage(tmp_path / "plain.usda", matte=False)
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = dict(os.environ, PYTHONPATH=root + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = tmp_path / "matte.exr"
    res = subprocess.run([sys.executable, "-c", "from usd_io.cli import run; run()", "render",
                          str(tmp_path / "matte.usda"), "-o", str(out), "--width", "16", "--height", "16", "--aa",
                          "1", "--quiet"], capture_output=True, text=True, cwd=root, env=env, timeout=900)
    assert res.returncode == 0, res.stderr
    alpha = read_image(str(out))[..., 3]
    scene, _ = load_stage(str(tmp_path / "plain.usda"), width=16, height=16)
    ids = render(scene, RenderSettings(width=16, height=16, samples=1, aovs=("objectid",))).aovs["objectid"]
    card = ids == scene.object_names.index("/Holdouts/Card")
    assert 0.1 < card.mean() < 0.9
    np.testing.assert_array_equal(alpha, np.where(card, 0.0, 1.0))

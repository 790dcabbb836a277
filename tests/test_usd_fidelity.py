"""Fidelity against references (issue #32): patterns found comparing our renders of OpenUSD's imaging test stages
with Storm's baselines (tools/fidelity.py), each reproduced by a small stage written here (nothing is read from
third-party files).

- Exporter defaults taken as intent: many exporters write ``fStop = 5.6, focusDistance = 5`` on every camera, and a
  shutter on some. ``--no-dof`` / ``--no-motion-blur`` (tracer.settings: ``depth_of_field`` / ``motion_blur``) and
  UsdRender's ``disableDepthOfField`` / ``disableMotionBlur`` give the picture of the same stage without them,
  pixel for pixel.
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdRender

SIZE = 48


def render_cli(path, *flags):
    """What ``whitted render PATH FLAGS`` renders (its parser, StageRequest and settings), in-process."""
    import tracer
    from usd_io.cli import build_parser
    from usd_io.request import StageRequest, settings_from_args

    args = build_parser().parse_args(["render", str(path), "-o", "unused.png", "--width", str(SIZE), "--height",
                                      str(SIZE), "--aa", "2", "--light-samples", "1", "--sky-samples", "0",
                                      *map(str, flags)])
    scene, info = StageRequest.from_args(args, str(path)).read()
    image = tracer.render(scene, settings_from_args(args, width=info.width, height=info.height))
    return np.asarray(image.rgba)


def _stage(path, *, f_stop=0.0, shutter=None, render_settings=None):
    """A z-up stage: a camera 20 units from a unit cube (focal length 50 mm, aperture 36 × 36 mm: the cube fills
    about a fifth of the frame), with ``fStop`` and focusDistance 5 (the exporters' defaults: the cube far out
    of focus), a ``shutter`` (open, close) across which the cube slides 2 units per time code, no lights (the reader's camera headlight),
    and a RenderSettings with the given boolean attributes."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    cam.CreateFocalLengthAttr(50.0)
    cam.CreateHorizontalApertureAttr(36.0)
    cam.CreateVerticalApertureAttr(36.0)
    cam.CreateFStopAttr(f_stop)
    cam.CreateFocusDistanceAttr(5.0)
    UsdGeom.XformCommonAPI(cam).SetTranslate(Gf.Vec3d(0, -20, 0))
    UsdGeom.XformCommonAPI(cam).SetRotate(Gf.Vec3f(90, 0, 0))
    if shutter is not None:
        cam.CreateShutterOpenAttr(shutter[0])
        cam.CreateShutterCloseAttr(shutter[1])
    cube = UsdGeom.Cube.Define(stage, "/Cube")
    op = cube.AddTranslateOp()
    op.Set(Gf.Vec3d(-2, 0, 0), 0.0)
    op.Set(Gf.Vec3d(2, 0, 0), 2.0)
    if render_settings:
        rs = UsdRender.Settings.Define(stage, "/Render/Settings")
        rs.CreateCameraRel().SetTargets([Sdf.Path("/Cam")])
        for name, value in render_settings.items():
            rs.GetPrim().CreateAttribute(name, Sdf.ValueTypeNames.Bool).Set(value)
        stage.SetMetadata("renderSettingsPrimPath", "/Render/Settings")
    stage.GetRootLayer().Save()
    return path


@pytest.fixture(scope="module")
def stages(tmp_path_factory):
    d = tmp_path_factory.mktemp("fidelity")
    return dict(
        pinhole=_stage(d / "pinhole.usda"),
        lens=_stage(d / "lens.usda", f_stop=5.6),
        lens_off=_stage(d / "lens_off.usda", f_stop=5.6, render_settings={"disableDepthOfField": True}),
        shutter=_stage(d / "shutter.usda", shutter=(-0.25, 0.25)),
        shutter_off=_stage(d / "shutter_off.usda", shutter=(-0.25, 0.25),
                           render_settings={"disableMotionBlur": True}),
    )


def _differs(a, b):
    return np.abs(a - b).max() > 0.05


def test_exporter_fstop_blurs_by_default_and_no_dof_gives_the_pinhole_picture(stages):
    """fStop 5.6 focused at 5 on a cube at 20: blurred by default (UsdGeomCamera asks for it); with ``--no-dof``
    or the RenderSettings' ``disableDepthOfField`` the picture is the fStop-0 camera's, pixel for pixel."""
    sharp = render_cli(stages["pinhole"], "--time", 1)
    assert _differs(render_cli(stages["lens"], "--time", 1), sharp)
    assert np.array_equal(render_cli(stages["lens"], "--time", 1, "--no-dof"), sharp)
    assert np.array_equal(render_cli(stages["lens_off"], "--time", 1), sharp)
    assert np.array_equal(render_cli(stages["lens_off"], "--time", 1, "--dof"), sharp)  # the stage's off wins


def test_shutter_blurs_by_default_and_no_motion_blur_gives_the_still_picture(stages):
    """A cube sliding 2 units per time code under a [-0.25, 0.25] shutter: smeared by default; with
    ``--no-motion-blur`` or the RenderSettings' ``disableMotionBlur`` the picture is the shutterless stage's
    at the frame, pixel for pixel."""
    still = render_cli(stages["pinhole"], "--time", 1)
    assert _differs(render_cli(stages["shutter"], "--time", 1), still)
    assert np.array_equal(render_cli(stages["shutter"], "--time", 1, "--no-motion-blur"), still)
    assert np.array_equal(render_cli(stages["shutter_off"], "--time", 1), still)


def test_render_product_overrides_the_settings_switch(tmp_path):
    """A RenderProduct's own ``disableDepthOfField`` (UsdRenderSettingsBase) overrides its RenderSettings', as its
    other settings do; unauthored on the product, the settings' holds."""
    from usd_io.reader import load_stage

    path = _stage(tmp_path / "product.usda", f_stop=5.6, render_settings={"disableDepthOfField": True})
    stage = Usd.Stage.Open(str(path))
    product = UsdRender.Product.Define(stage, "/Render/Product")
    UsdRender.Settings(stage.GetPrimAtPath("/Render/Settings")).CreateProductsRel().SetTargets([product.GetPath()])
    stage.GetRootLayer().Save()
    assert load_stage(str(path), width=8, height=8)[0].camera.lens_radius == 0
    product.GetPrim().CreateAttribute("disableDepthOfField", Sdf.ValueTypeNames.Bool).Set(False)
    stage.GetRootLayer().Save()
    assert load_stage(str(path), width=8, height=8)[0].camera.lens_radius > 0

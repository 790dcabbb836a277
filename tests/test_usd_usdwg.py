"""Patterns found by the usd-wg survey (tools/usdwg_survey.py), each rebuilt in a stage written here.

- Stages without a camera are framed as usdrecord frames them (the assets' thumbnails are usdrecord's): on the
  front axis, looking at the bounds' centre, backed off by the front face's half-diagonal over tan(half FOV) plus
  half the depth (UsdAppUtils FrameRecorder). The reference bounds are pxr's own (UsdGeom.BBoxCache).
- A MaterialX document's ``<UsdPreviewSurface>`` arrives as a shader ``ND_UsdPreviewSurface_surfaceshader`` on
  ``outputs:mtlx:surface`` (what usdMtlx writes; MaterialXTest/basic_flatten.usda): it is a UsdPreviewSurface.
- Pixels that are not finite are written black by the film; the CLI says so once.
"""

from __future__ import annotations

import os

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade

from usd_io import load_stage
from usd_io.camera import DEFAULT_APERTURE, DEFAULT_FOCAL


def box_stage(up: str) -> Usd.Stage:
    """A 2 × 4 × 1 box (Y-up; its Z-up copy turned +90° about X), off the origin, no camera."""
    s = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(s, up)
    root = UsdGeom.Xform.Define(s, "/World")
    if up == "Z":
        root.AddRotateXOp().Set(90.0)
    cube = UsdGeom.Cube.Define(s, "/World/Box")
    cube.AddTranslateOp().Set(Gf.Vec3d(3.0, 1.0, -2.0))
    cube.AddScaleOp().Set(Gf.Vec3f(1.0, 2.0, 0.5))
    return s


def pxr_bounds(stage) -> tuple[np.ndarray, np.ndarray]:
    cache = UsdGeom.BBoxCache(Usd.TimeCode.Default(), ["default", "render"])
    r = cache.ComputeWorldBound(stage.GetPseudoRoot()).ComputeAlignedRange()
    return np.array(r.GetMin()), np.array(r.GetMax())


@pytest.mark.parametrize("up", ["Y", "Z"])
def test_camera_less_stage_is_framed_as_usdrecord_frames_it(up):
    width, height = 64, 64
    stage = box_stage(up)
    scene, info = load_stage(stage, width=width, height=height)
    assert any("no camera" in w for w in info.warnings)
    lo, hi = pxr_bounds(stage)
    centre, dim = (lo + hi) / 2, hi - lo
    # usdrecord: Y-up looks along −Z from +Z; Z-up along +Y from −Y (rotated 90° about X), up = the up axis.
    face, depth, back, up_vec = (((dim[0], dim[1]), dim[2], (0, 0, 1), (0, 1, 0)) if up == "Y" else
                                 ((dim[0], dim[2]), dim[1], (0, -1, 0), (0, 0, 1)))
    # a square image widens the default 20.955 × 15.29 aperture to 20.955 × 20.955: both FOVs are usdrecord's
    # horizontal one (usdrecord itself keeps 15.29 vertically and crops what its horizontal framing lets through)
    half_fov = np.arctan(max(DEFAULT_APERTURE) / 2 / DEFAULT_FOCAL)
    distance = np.hypot(*face) / 2 / np.tan(half_fov) + depth / 2
    c2w = scene.camera.camera_to_world
    np.testing.assert_allclose(c2w[:3, 3], centre + distance * np.array(back), atol=1e-6)
    np.testing.assert_allclose(-c2w[:3, 2] / np.linalg.norm(c2w[:3, 2]), -np.array(back, float), atol=1e-9)
    np.testing.assert_allclose(c2w[:3, 1] / np.linalg.norm(c2w[:3, 1]), up_vec, atol=1e-9)


def mtlx_preview_stage(path) -> Usd.Stage:
    """A sphere bound to a Material whose only surface is MaterialX's UsdPreviewSurface node."""
    s = Usd.Stage.CreateNew(str(path))
    sphere = UsdGeom.Sphere.Define(s, "/Sphere")
    mat = UsdShade.Material.Define(s, "/MaterialX/Materials/USD_Plastic")
    sh = UsdShade.Shader.Define(s, "/MaterialX/Materials/USD_Plastic/SR_plastic")
    sh.CreateIdAttr("ND_UsdPreviewSurface_surfaceshader")
    sh.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0.1047, 0.2419, 0.818))
    sh.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.3247)
    sh.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(0.25)
    mat.CreateSurfaceOutput("mtlx").ConnectToSource(sh.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(sphere.GetPrim()).Bind(mat)
    s.Save()
    return s


def test_materialx_usd_preview_surface_node_reads_as_a_usd_preview_surface(tmp_path):
    stage = mtlx_preview_stage(tmp_path / "mtlx_preview.usda")
    _scene, info = load_stage(stage, width=8, height=8)
    fields = info.materials["/MaterialX/Materials/USD_Plastic"]
    sh = UsdShade.Shader.Get(stage, "/MaterialX/Materials/USD_Plastic/SR_plastic")
    want = tuple(round(float(x), 4) for x in sh.GetInput("diffuseColor").Get())
    assert fields["base_color"] == want  # not the 0.18 grey of an unread surface
    assert fields["roughness"] == pytest.approx(float(sh.GetInput("roughness").Get()), abs=1e-4)
    assert fields["metallic"] == pytest.approx(0.25, abs=1e-4)
    assert not [w for w in info.warnings if "not supported" in w]


def test_non_finite_pixels_are_reported_once(capsys):
    from usd_io.cli import _warn_not_finite

    rgba = np.ones((4, 5, 4), np.float32)
    rgba[1, 2, 0] = np.nan
    rgba[3, 4, 1] = np.inf
    _warn_not_finite(rgba, "scene.usda")
    err = capsys.readouterr().err.splitlines()
    assert err == ["whitted: warning: scene.usda: 2 pixel(s) not finite (NaN or inf; written black)"]
    _warn_not_finite(np.ones((4, 5, 4), np.float32), "scene.usda")
    assert capsys.readouterr().err == ""


# ---------------------------------------------------------------- MaterialX documents (the chess set's pattern)
MTLX_LAMBERT = """<?xml version="1.0"?>
<materialx version="1.38" colorspace="lin_rec709">
  <nodegraph name="NG_blocks">
    <texcoord name="uv" type="vector2" />
    <image name="blocks" type="color3">
      <input name="file" type="filename" value="tex/blocks.png" colorspace="srgb_texture" />
      <input name="texcoord" type="vector2" nodename="uv" />
    </image>
    <output name="color_out" type="color3" nodename="blocks" />
  </nodegraph>
  <UsdPreviewSurface name="SR_blocks" type="surfaceshader">
    <input name="diffuseColor" type="color3" nodegraph="NG_blocks" output="color_out" />
    <input name="useSpecularWorkflow" type="integer" value="1" />
    <input name="specularColor" type="color3" value="0, 0, 0" />
  </UsdPreviewSurface>
  <surfacematerial name="M_blocks" type="material">
    <input name="surfaceshader" type="surfaceshader" nodename="SR_blocks" />
  </surfacematerial>
</materialx>
"""

MTLX_STANDARD = """<?xml version="1.0"?>
<materialx version="1.38">
  <image name="rough" type="float"><input name="file" type="filename" value="r.png" /></image>
  <image name="nrm" type="vector3"><input name="file" type="filename" value="n.png" /></image>
  <normalmap name="nmap" type="vector3"><input name="in" type="vector3" nodename="nrm" /></normalmap>
  <standard_surface name="SR_std" type="surfaceshader">
    <input name="base" type="float" value="0.5" />
    <input name="base_color" type="color3" value="0.2, 0.4, 0.6" />
    <input name="metalness" type="float" value="0.7" />
    <input name="specular_roughness" type="float" nodename="rough" />
    <input name="normal" type="vector3" nodename="nmap" />
    <input name="coat" type="float" value="1" />
  </standard_surface>
  <surfacematerial name="M_std" type="material">
    <input name="surfaceshader" type="surfaceshader" nodename="SR_std" />
  </surfacematerial>
</materialx>
"""


def mtlx_quad_stage(d, document: str, material: str) -> str:
    """The standard lit quad, its material referenced from ``looks/mat.mtlx`` as the chess set does it
    (``def Scope "Materials" (references = @looks/mat.mtlx@</MaterialX/Materials>)``)."""
    import usd_material_stages as S

    os.makedirs(os.path.join(d, "looks", "tex"), exist_ok=True)
    with open(os.path.join(d, "looks", "mat.mtlx"), "w") as f:
        f.write(document)
    s = S.new_stage(os.path.join(d, "scene.usda"))
    S.camera(s)
    q = S.quad(s)
    S.sun(s)
    s.DefinePrim("/Materials", "Scope").GetReferences().AddReference("./looks/mat.mtlx", "/MaterialX/Materials")
    UsdShade.MaterialBindingAPI.Apply(q.GetPrim()).GetDirectBindingRel().SetTargets([f"/Materials/{material}"])
    return S.save(s)


def test_mtlx_document_reference_renders_its_image_node_in_srgb(tmp_path):
    """Closed form (as the texture-orientation test): a Lambert quad under a π W/m² sun at normal incidence shows
    its albedo, so every pixel is the sRGB-decoded texel under it. Before usd_io.materials.mtlx: the reference does not
    compose, the quad is unbound and 0.5 grey; a raw (not sRGB) read or a flipped lookup moves every block."""
    import usd_material_stages as S
    from test_usd_materials import N, assert_blocks, render_stage, st_of_pixels

    d = str(tmp_path)
    os.makedirs(os.path.join(d, "looks", "tex"), exist_ok=True)
    blocks = S.block_texture(os.path.join(d, "looks", "tex", "blocks.png"))
    img, info, _ = render_stage(mtlx_quad_stage(d, MTLX_LAMBERT, "M_blocks"))
    assert not [w for w in info.warnings if "composition" in w or "not supported" in w], info.warnings
    expected, ok = S.block_lookup(st_of_pixels(), blocks, margin=1.5 / N)
    assert_blocks(img, expected, ok)


def test_mtlx_standard_surface_weights_textures_and_normal_map(tmp_path):
    import usd_material_stages as S

    d = str(tmp_path)
    path = mtlx_quad_stage(d, MTLX_STANDARD, "M_std")
    S.write_png(os.path.join(d, "looks", "r.png"), np.full((4, 4, 1), 128, np.uint8))
    S.write_png(os.path.join(d, "looks", "n.png"), np.full((4, 4, 3), (128, 128, 255), np.uint8))
    _scene, info = load_stage(path, width=8, height=8)
    f = info.materials["/Materials/M_std"]
    assert f["base_color"] == pytest.approx((0.1, 0.2, 0.3))  # base · base_color, Standard Surface's weight
    assert f["metallic"] == pytest.approx(0.7)
    assert "r.png" in f["roughness_texture"] and f["roughness_channel"] == 0
    assert "n.png" in f["normal_texture"]
    assert f["layers"][0]["kind"] == "dielectric" and f["layers"][0]["weight"] == 1.0  # the coat: a layer
    assert not [w for w in info.warnings if "coat" in w]
    from usd_io.materials.network import source

    stage = Usd.Stage.Open(path)
    from usd_io.stage import open_stage

    open_stage(stage)
    sh = UsdShade.Material(stage.GetPrimAtPath("/Materials/M_std")).ComputeSurfaceSource("mtlx")[0]
    n = source(sh, "normal", None)
    assert n.scale[:3] == (2.0, 2.0, 2.0) and n.bias[:3] == (-1.0, -1.0, -1.0)  # MaterialX normalmap: 2·texel − 1


@pytest.mark.parametrize("token", ["X", "invalid"])
def test_up_axis_that_is_not_y_or_z_reads_as_y_with_one_warning(token):
    """foundation/stage_configuration/upAxis_X.usda and upAxis_invalid.usda: pxr hands back the authored token;
    it is not valid USD, so it reads as UsdGeom's fallback Y and says so (it was silently taken before)."""
    stage = box_stage("Y")
    stage.SetMetadata("upAxis", token)
    assert UsdGeom.GetStageUpAxis(stage) == token  # what pxr itself gives
    _scene, info = load_stage(stage, width=16, height=16)
    assert info.up_axis == "Y"
    assert [w for w in info.warnings if "upAxis" in w] == [f"upAxis {token!r} is not Y or Z: read as Y, UsdGeom's fallback"]

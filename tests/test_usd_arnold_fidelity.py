"""Patterns found by the Arnold corpus of the fidelity harness (issue #32, tools/fidelity_arnold.py: arnold-usd's
test suite against Arnold's references). Each stage is written here; each check is a closed form or Arnold's
documented behaviour, never a downloaded file."""

from __future__ import annotations

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade

from tracer import RenderSettings, render
from usd_io import load_stage
from usd_io.exporters import detect, written_for_arnold
from usd_io.geometry.mesh import flattened

import usd_pipeline_stages as st
from usd_pipeline_stages import add_camera, bind, new_stage, quad

F, C3 = Sdf.ValueTypeNames.Float, Sdf.ValueTypeNames.Color3f


def _centre(stage, w=24, h=16, samples=1, **kw):
    scene, info = load_stage(stage, width=w, height=h, **kw)
    return render(scene, RenderSettings(width=w, height=h, samples=samples)).rgb[h // 2, w // 2], info


def _arnold_lambert(stage, path="/M", kd=1.0, colour=(1.0, 1.0, 1.0)):
    mat = UsdShade.Material.Define(stage, path)
    sh = UsdShade.Shader.Define(stage, path + "/S")
    sh.CreateIdAttr("arnold:lambert")
    sh.CreateInput("Kd", F).Set(kd)
    sh.CreateInput("Kd_color", C3).Set(Gf.Vec3f(*colour))
    mat.CreateSurfaceOutput("arnold").ConnectToSource(sh.ConnectableAPI(), "out")
    return mat


# ---------------------------------------------------------------- light units: Arnold's own
def test_arnold_distant_light_lights_a_white_diffuse_facing_it_to_its_intensity():
    """Arnold's lights (legacy, no usdlux_version): a distant light of intensity I renders a Lambert of albedo ρ
    facing it as ρ·I (E = π·I), where the UsdLux spec gives ρ·I/π. The stage is Arnold's by its arnold:lambert."""
    c = (0.2, 0.4, 0.8)
    s = st.lit_quad_with("arnold:lambert", {"Kd": (F, 0.5), "Kd_color": (C3, Gf.Vec3f(*c))}, output="arnold:surface")
    px, info = _centre(s)
    np.testing.assert_allclose(px, 0.5 * np.asarray(c) * 2.0, rtol=0.02)
    assert any("Arnold's own units" in n for n in info.notes), info.notes
    spec, _ = _centre(s, light_units="spec")
    np.testing.assert_allclose(spec, 0.5 * np.asarray(c) * 2.0 / np.pi, rtol=0.02)


def _point_lit(radius_prim=None, usdlux_version=None, normalize=True):
    s = new_stage()
    add_camera(s, eye=(0, 0, 10))
    q = quad(s, "/Q", half=3.0)
    bind(q, _arnold_lambert(s, kd=0.5))
    lamp = UsdLux.SphereLight.Define(s, "/Lamp")
    lamp.CreateIntensityAttr(8.0)
    lamp.CreateNormalizeAttr(normalize)  # radius left at UsdLux's 0.5
    lamp.AddTranslateOp().Set(Gf.Vec3d(0, 0, 2))
    if radius_prim is not None:
        lamp.GetPrim().CreateAttribute("primvars:arnold:radius", F).Set(radius_prim)
    if usdlux_version is not None:
        rs = s.DefinePrim("/Render/Settings", "RenderSettings")
        rs.CreateAttribute("arnold:global:usdlux_version", Sdf.ValueTypeNames.String).Set(usdlux_version)
    return s


def test_arnold_point_light_lights_a_white_diffuse_to_intensity_over_distance_squared():
    """A normalized SphereLight in Arnold's units: radiant intensity π·I, so a Lambert (ρ = 0.5) seen at the centre
    pixel (the point (0.15, 0.15, 0) of the floor, the light at (0, 0, 2)) is ρ·I·cosθ/r² = 0.5·8·2/4.045^1.5 = 0.98;
    the spec's I/4 W/sr would give ρ·(I/4)·cosθ/(π r²) = 0.08. Arnold's radius 0 (primvars:arnold:radius): a point."""
    px, info = _centre(_point_lit(radius_prim=0.0), samples=4)
    np.testing.assert_allclose(px, 0.5 * 8 * 2 / 4.045 ** 1.5, rtol=0.02)
    lamp = [lt for _k, _n, lt in info.lights][0]
    np.testing.assert_allclose(lamp.intensity, 8.0 * np.pi, rtol=1e-6)
    _px, info = _centre(_point_lit())
    assert [lt for _k, _n, lt in info.lights][0].radius == 0.5  # UsdLux's radius without Arnold's


def test_arnold_radius_primvar_wins_over_the_usd_radius():
    """arnold-usd reads primvars:arnold:* after the UsdLux inputs: Arnold's radius 0 makes a point light (no soft
    shadow), however the light is normalized: the same π·I, even with normalize off."""
    _px, info = _centre(_point_lit(radius_prim=0.0, normalize=False))
    lamp = [lt for _k, _n, lt in info.lights][0]
    assert lamp.radius == 0.0
    np.testing.assert_allclose(lamp.intensity, 8.0 * np.pi, rtol=1e-6)


def test_arnold_usdlux_version_reads_the_lights_as_the_spec():
    """With arnold:global:usdlux_version set, Arnold follows UsdLux: the normalized sphere is I/4 W/sr."""
    _px, info = _centre(_point_lit(usdlux_version="25.05"))
    lamp = [lt for _k, _n, lt in info.lights][0]
    np.testing.assert_allclose(lamp.intensity, 8.0 / 4.0, rtol=1e-6)


def test_a_stage_without_arnold_content_keeps_the_spec():
    s = new_stage()
    add_camera(s, eye=(0, 0, 10))
    quad(s, "/Q")
    assert written_for_arnold(s) is None and detect(s) is None
    s.GetPrimAtPath("/Q").CreateAttribute("primvars:arnold:smoothing", Sdf.ValueTypeNames.Bool).Set(True)
    assert written_for_arnold(s) == "/Q.primvars:arnold:smoothing" and detect(s).units == "arnold"


# ---------------------------------------------------------------- unbound geometry: Arnold's default surface
def _unbound(display_color=None, marker=True, explicit=None):
    s = new_stage()
    add_camera(s, eye=(0, 0, 10))
    sun = UsdLux.DistantLight.Define(s, "/Sun")
    sun.CreateIntensityAttr(1.0)
    sun.CreateNormalizeAttr(True)
    sun.AddRotateXOp().Set(20.0)  # off the mirror direction: the specular lobe seen at an angle
    q = quad(s, "/Q", half=3.0)
    if display_color is not None:
        q.CreateDisplayColorAttr([display_color])
    if marker:
        rs = s.DefinePrim("/Render/Settings", "RenderSettings")
        rs.CreateAttribute("arnold:global:AA_samples", Sdf.ValueTypeNames.Int).Set(3)
    if explicit is not None:  # Arnold's fallback written out: standard_surface, its defaults, base_color given
        mat = UsdShade.Material.Define(s, "/M")
        sh = UsdShade.Shader.Define(s, "/M/S")
        sh.CreateIdAttr("arnold:standard_surface")
        sh.CreateInput("base_color", C3).Set(Gf.Vec3f(*explicit))
        mat.CreateSurfaceOutput("arnold").ConnectToSource(sh.ConnectableAPI(), "out")
        bind(q, mat)
    return s


def test_unbound_geometry_on_an_arnold_stage_is_arnolds_default_standard_surface():
    """arnold-usd's UsdArnoldReader::GetDefaultShader: geometry without a material gets a standard_surface (every
    default: base 0.8, specular 1, roughness 0.2) whose base_color reads displayColor, white without one. The
    picture equals that shader written out; Hydra's fallback (plain diffuse 0.5 grey) was 4× darker here."""
    for colour in (None, (0.9, 0.1, 0.1)):
        got, info = _centre(_unbound(display_color=colour), samples=2)
        want, _ = _centre(_unbound(display_color=colour, explicit=colour or (1.0, 1.0, 1.0)), samples=2)
        np.testing.assert_allclose(got, want, rtol=0.02, atol=1e-4)
        fields = info.materials["arnold:default_surface"]  # what differs from the Principled defaults
        assert fields["roughness"] == 0.2 and fields["vertex_color"] and "specular" not in fields
    white, _ = _centre(_unbound(), samples=2)
    assert white.mean() > 0.7 * np.cos(np.radians(20)), white  # 0.8·E/π·π: Arnold's units, not 0.5·E/π


def test_unbound_geometry_elsewhere_keeps_hydras_display_colour():
    _px, info = _centre(_unbound(display_color=(0.9, 0.1, 0.1), marker=False))
    assert "arnold:default_surface" not in info.materials
    assert info.materials["displayColor"].get("specular") == 0.0


# ---------------------------------------------------------------- MtoA's faceVarying primvars with elementSize
def test_face_varying_primvar_whose_element_size_does_not_fit_is_read_per_index():
    """MtoA writes faceVarying UVs as 4 values, elementSize 4, indices [0, 1, 3, 2]: USD's ComputeFlattened
    refuses it (the quad rendered without UVs, black); Arnold ignores elementSize: values[indices]."""
    s = new_stage()
    m = quad(s, "/Q")
    pv = UsdGeom.PrimvarsAPI(m).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying,
                                              4)
    values = [(0, 0), (1, 0), (0, 1), (1, 1)]
    pv.Set(values)
    pv.SetIndices([0, 1, 3, 2])
    got = np.asarray(flattened(pv, Usd.TimeCode.Default()), float)
    np.testing.assert_array_equal(got, np.asarray(values, float)[[0, 1, 3, 2]])
    ok = UsdGeom.PrimvarsAPI(m).CreatePrimvar("fine", Sdf.ValueTypeNames.TexCoord2fArray,
                                              UsdGeom.Tokens.faceVarying)
    ok.Set(values)
    ok.SetIndices([3, 2, 1, 0])
    np.testing.assert_array_equal(np.asarray(flattened(ok, Usd.TimeCode.Default()), float),
                                  np.asarray(values, float)[[3, 2, 1, 0]])


def test_a_texture_on_element_size_uvs_is_drawn():
    """A quad whose st is written MtoA's way (elementSize 4) under an Arnold checkerboard (unlit as the surface,
    one cell per UV unit, color1 at the UV origin): with its UVs read, the bottom-left cell is color1 and the one
    right of it color2 (before: no UVs, one colour everywhere)."""
    s = new_stage()
    add_camera(s, eye=(0, 0, 10))
    m = quad(s, "/Q", half=3.0)
    pv = UsdGeom.PrimvarsAPI(m).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying,
                                              4)
    pv.Set([(0, 0), (2, 0), (0, 2), (2, 2)])
    pv.SetIndices([0, 1, 3, 2])
    mat = UsdShade.Material.Define(s, "/M")
    sh = UsdShade.Shader.Define(s, "/M/Checker")
    sh.CreateIdAttr("arnold:checkerboard")
    sh.CreateInput("color1", C3).Set(Gf.Vec3f(1, 0, 0))
    sh.CreateInput("color2", C3).Set(Gf.Vec3f(0, 0, 1))
    mat.CreateSurfaceOutput("arnold").ConnectToSource(sh.ConnectableAPI(), "out")
    bind(m, mat)
    w, h = 24, 16
    scene, info = load_stage(s, width=w, height=h)
    img = render(scene, RenderSettings(width=w, height=h, samples=1)).rgb
    quadrant = lambda y, x: img[y, x]  # noqa: E731  (the quad spans the frame: 2 × 2 cells)
    bottom_left, bottom_right = quadrant(h * 3 // 4, w // 4), quadrant(h * 3 // 4, w * 3 // 4)
    assert bottom_left[0] > 0.5 and bottom_left[2] < 0.1, bottom_left  # cell (0, 0): color1
    assert bottom_right[2] > 0.5 and bottom_right[0] < 0.1, bottom_right  # cell (1, 0): color2


def test_arnold_standard_surface_takes_arnolds_own_defaults():
    """Arnold's standard_surface defaults are base 0.8 and base_color white (MaterialX copied them as its version
    1.0.0; its default 1.0.1 has base 1, base_color 0.8): with only base_color authored the base colour is
    0.8·base_color, with only base authored it is base·white."""
    s = st.lit_quad_with("arnold:standard_surface", {"base_color": (C3, Gf.Vec3f(0.5, 0.25, 1.0))},
                         output="arnold:surface")
    _px, info = _centre(s)
    np.testing.assert_allclose(info.materials["/M"]["base_color"], (0.4, 0.2, 0.8), rtol=1e-6)
    s = st.lit_quad_with("arnold:standard_surface", {"base": (F, 1.0)}, output="arnold:surface")
    _px, info = _centre(s)
    np.testing.assert_allclose(info.materials["/M"]["base_color"], (1.0, 1.0, 1.0), rtol=1e-6)

"""Patterns found by the Arnold corpus of the fidelity harness (issue #32, tools/fidelity_arnold.py: arnold-usd's
test suite against Arnold's references). Each stage is written here; each check is a closed form or Arnold's
documented behaviour, never a downloaded file."""

from __future__ import annotations

import numpy as np
import pytest
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
def test_arnold_distant_light_gives_irradiance_equal_to_its_intensity_whatever_its_angle():
    """Arnold's lights (legacy, no usdlux_version): a distant light of intensity I gives E = I, so a Lambert of
    albedo ρ facing it is ρ·I/π. arnold-usd's test_0191 (I = 1 on a cube of albedo 0.8·0.5) has 100/255 there in
    its sRGB-encoded reference: sRGB(0.4/π) = 0.392 (E = π·I would be sRGB(0.4) = 0.665). Arnold ignores the angle
    (the spec's unnormalized sun is E = I·Ω, Ω the disk's solid angle). The stage is Arnold's by its
    arnold:lambert."""
    c = (0.2, 0.4, 0.8)
    s = st.lit_quad_with("arnold:lambert", {"Kd": (F, 0.5), "Kd_color": (C3, Gf.Vec3f(*c))}, output="arnold:surface")
    sun = UsdLux.DistantLight(s.GetPrimAtPath("/Sun"))
    sun.CreateAngleAttr(10.0)
    sun.CreateNormalizeAttr(False)
    px, info = _centre(s)
    np.testing.assert_allclose(px, 0.5 * np.asarray(c) * 2.0 / np.pi, rtol=0.02)
    assert any("Arnold's own units" in n for n in info.notes), info.notes
    spec, _ = _centre(s, light_units="spec")
    omega = 2 * np.pi * (1 - np.cos(np.radians(5.0)))
    np.testing.assert_allclose(spec, 0.5 * np.asarray(c) * 2.0 * omega / np.pi, rtol=0.02)


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
    """A normalized SphereLight in Arnold's units: radiant intensity I, so a Lambert (ρ = 0.5) seen at the centre
    pixel (the point (0.15, 0.15, 0) of the floor, the light at (0, 0, 2)) is ρ·I·cosθ/(π r²) = 0.5·8·2/(π·4.045^1.5)
    = 0.31; the spec's I/4 W/sr would give a quarter. arnold-usd's test_0192/0193/0200 (points of radius 0) match
    their sRGB-decoded references at 37-42 dB so (π·I: 24 dB at best). Arnold's radius 0 (primvars:arnold:radius):
    a point."""
    px, info = _centre(_point_lit(radius_prim=0.0), samples=4)
    np.testing.assert_allclose(px, 0.5 * 8 * 2 / (np.pi * 4.045 ** 1.5), rtol=0.02)
    lamp = [lt for _k, _n, lt in info.lights][0]
    np.testing.assert_allclose(lamp.intensity, 8.0, rtol=1e-6)
    _px, info = _centre(_point_lit())
    assert [lt for _k, _n, lt in info.lights][0].radius == 0.5  # UsdLux's radius without Arnold's


def test_arnold_radius_primvar_wins_over_the_usd_radius():
    """arnold-usd reads primvars:arnold:* after the UsdLux inputs: Arnold's radius 0 makes a point light (no soft
    shadow), however the light is normalized: the same I W/sr, even with normalize off."""
    _px, info = _centre(_point_lit(radius_prim=0.0, normalize=False))
    lamp = [lt for _k, _n, lt in info.lights][0]
    assert lamp.radius == 0.0
    np.testing.assert_allclose(lamp.intensity, 8.0, rtol=1e-6)


def test_a_treat_as_point_sphere_is_arnolds_default_point_light_normalized():
    """arnold-usd reads inputs:radius and inputs:normalize only when treatAsPoint is off; with it on, the light is
    Arnold's point_light at its defaults (normalize on), so an unnormalized sphere of Arnold radius 1.32 still
    gives I W/sr (arnold-usd's test_0190: 19.4 dB read as I·πr², 39.6 dB so)."""
    s = _point_lit(radius_prim=1.32, normalize=False)
    UsdLux.SphereLight(s.GetPrimAtPath("/Lamp")).CreateTreatAsPointAttr(True)
    _px, info = _centre(s)
    lamp = [lt for _k, _n, lt in info.lights][0]
    np.testing.assert_allclose(lamp.intensity, 8.0, rtol=1e-6)
    assert lamp.radius == pytest.approx(1.32)
    s = _point_lit(normalize=False)  # treatAsPoint on, no Arnold radius: a point (the USD radius is not read)
    UsdLux.SphereLight(s.GetPrimAtPath("/Lamp")).CreateTreatAsPointAttr(True)
    lamp = [lt for _k, _n, lt in _centre(s)[1].lights][0]
    assert lamp.radius == 0.0
    np.testing.assert_allclose(lamp.intensity, 8.0, rtol=1e-6)


def test_an_ies_sphere_light_is_arnolds_photometric_light_aimed_down_its_y(tmp_path):
    """arnold-usd makes a SphereLight with an IES file a photometric_light (its cone ignored: test_1316), whose
    nadir is its local −Y (test_0140's beam lands where −Y points, not −Z), the candela values in W/sr (÷ 683)."""
    path = tmp_path / "down.ies"
    path.write_text("IESNA:LM-63-2002\nTILT=NONE\n1 1000 1 3 1 1 2 0 0 0\n1 1 10\n0 90 180\n0\n683 0 0\n")
    s = _point_lit(radius_prim=0.0)
    lamp = s.GetPrimAtPath("/Lamp")
    UsdGeom.Xformable(lamp).AddRotateXOp().Set(90.0)  # its −Y now points along −Z, at the floor
    sh = UsdLux.ShapingAPI.Apply(lamp)
    sh.CreateShapingIesFileAttr(Sdf.AssetPath(str(path)))
    sh.CreateShapingConeAngleAttr(10.0)
    px, info = _centre(s, samples=4)
    light = [lt for _k, _n, lt in info.lights][0]
    assert type(light).__name__ == "PointLight" and light.shaping is None  # no cone
    np.testing.assert_allclose(light.profile_axes[2], (0, 0, -1), atol=1e-9)
    # the centre pixel sees (0.15, 0.15, 0): θ = atan(0.212/2) from the nadir, I = 8·(1 − θ/90°)
    theta = np.degrees(np.arctan(np.hypot(0.15, 0.15) / 2))
    np.testing.assert_allclose(px, 0.5 * 8 * (1 - theta / 90) * 2 / (np.pi * 4.045 ** 1.5), rtol=0.02)


def test_an_orthographic_camera_is_framed_by_its_arnold_screen_window():
    """arnold-usd's ortho_camera ignores the USD aperture and shows x from screen_window_min.x to max.x in scene
    units (test_0055, ±0.80: 10.0 -> 31.6 dB): a 2 × 2 quad seen through ±0.5 fills the frame, through USD's
    default aperture (2.1 units) it does not."""
    def frame(window):
        s = new_stage()
        cam = UsdGeom.Camera.Define(s, "/Cam")
        cam.CreateProjectionAttr("orthographic")
        cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 10))
        if window is not None:
            pv = UsdGeom.PrimvarsAPI(cam.GetPrim())
            pv.CreatePrimvar("arnold:screen_window_min", Sdf.ValueTypeNames.Float2Array).Set([(-window, -window)])
            pv.CreatePrimvar("arnold:screen_window_max", Sdf.ValueTypeNames.Float2Array).Set([(window, window)])
        quad(s, "/Q", half=0.6)
        scene, info = load_stage(s, width=16, height=16)
        return render(scene, RenderSettings(width=16, height=16, samples=1)).rgb

    windowed, usd = frame(0.5), frame(None)
    np.testing.assert_allclose(windowed[0, 0], windowed[8, 8], rtol=1e-4)  # the quad reaches the corners
    np.testing.assert_allclose(windowed[15, 15], windowed[8, 8], rtol=1e-4)
    assert np.abs(usd[0, 0] - usd[8, 8]).max() > 0.1  # USD's aperture (2.1 units): wider than the quad


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
    picture equals that shader written out; Hydra's fallback (plain diffuse 0.5 grey) was darker here. kick gives
    it to every stage's unbound geometry (arnold-usd's test_2254 logs "_default_arnold_shader" on a stage without
    Arnold content): load_stage(fallback_surface="arnold") does the same whatever the stage."""
    for colour in (None, (0.9, 0.1, 0.1)):
        got, info = _centre(_unbound(display_color=colour), samples=2)
        want, _ = _centre(_unbound(display_color=colour, explicit=colour or (1.0, 1.0, 1.0)), samples=2)
        np.testing.assert_allclose(got, want, rtol=0.02, atol=1e-4)
        fields = info.materials["arnold:default_surface"]  # what differs from the Principled defaults
        assert fields["roughness"] == 0.2 and fields["vertex_color"] and "specular" not in fields
    white, _ = _centre(_unbound(), samples=2)
    assert white.mean() > 0.7 * np.cos(np.radians(20)) / np.pi, white  # ≈ 0.8·E/π (+ specular), not 0.5·E/π
    forced, info = _centre(_unbound(marker=False), samples=2, fallback_surface="arnold")
    np.testing.assert_allclose(forced, white, rtol=0.02, atol=1e-4)
    assert "arnold:default_surface" in info.materials


def test_unbound_geometry_elsewhere_keeps_hydras_display_colour():
    _px, info = _centre(_unbound(display_color=(0.9, 0.1, 0.1), marker=False))
    assert "arnold:default_surface" not in info.materials
    assert info.materials["displayColor"].get("specular") == 0.0
    _px, info = _centre(_unbound(display_color=(0.9, 0.1, 0.1)), fallback_surface="hydra")
    assert "arnold:default_surface" not in info.materials and "displayColor" in info.materials


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
    two cells per UV unit, color2 at the UV origin): with its UVs read, the bottom-left cell is color2 and the one
    right of it color1 (before: no UVs, one colour everywhere)."""
    s = new_stage()
    add_camera(s, eye=(0, 0, 10))
    m = quad(s, "/Q", half=3.0)
    pv = UsdGeom.PrimvarsAPI(m).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying,
                                              4)
    pv.Set([(0, 0), (1, 0), (0, 1), (1, 1)])
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
    assert bottom_left[2] > 0.5 and bottom_left[0] < 0.1, bottom_left  # cell (0, 0): color2
    assert bottom_right[0] > 0.5 and bottom_right[2] < 0.1, bottom_right  # cell (1, 0): color1


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


# ---------------------------------------------------------------- a PointInstancer's per-instance primvars
def _two_cubes(colours=((1.0, 0.0, 0.0), (0.0, 0.0, 1.0)), primvar="displayColor", material=None, nested=False,
               interpolation="varying"):
    """Two instances of one unit cube at x = ∓1.5 (the camera at z = 10 sees their +z faces head-on), lit by a
    normalized distant light of E = 2 along −z; ``colours`` the instancer's per-instance ``primvar``.
    ``nested``: the cube instancer is the prototype of an outer instancer with one instance, which carries the
    primvar (one element: both inner instances take it)."""
    s = new_stage()
    add_camera(s, eye=(0, 0, 10))
    sun = UsdLux.DistantLight.Define(s, "/Sun")
    sun.CreateIntensityAttr(2.0)
    sun.CreateNormalizeAttr(True)
    outer = "/Outer" if nested else None
    root = "/Outer/Protos/PI" if nested else "/PI"
    cube = UsdGeom.Cube.Define(s, root + "/Protos/Cube")
    cube.CreateSizeAttr(1.0)
    if material is not None:
        bind(cube, material(s))
    st.point_instancer(s, root, [root + "/Protos/Cube"], [(-1.5, 0, 0), (1.5, 0, 0)])
    holder = s.GetPrimAtPath(root)
    if nested:
        st.point_instancer(s, outer, ["/Outer/Protos/PI"], [(0, 0, 0)])
        holder = s.GetPrimAtPath(outer)
        colours = colours[:1]
    pv = UsdGeom.PrimvarsAPI(holder).CreatePrimvar(primvar, Sdf.ValueTypeNames.Color3fArray, interpolation)
    pv.Set([Gf.Vec3f(*c) for c in colours])
    return s


def _cube_centres(stage, **kw):
    w, h = 48, 32  # the aperture's 3:2
    scene, info = load_stage(stage, width=w, height=h, default_light=False, **kw)
    img = render(scene, RenderSettings(width=w, height=h, samples=2)).rgb
    # the camera's 3.6-wide aperture at focal 5 sees 3.6·9.5/5 = 6.84 across at z = 0.5: the centres at ∓1.5
    px = lambda x: int(round((x / (3.6 * 9.5 / 5) + 0.5) * w - 0.5))  # noqa: E731
    return img[h // 2, px(-1.5)], img[h // 2, px(1.5)], info


def test_point_instancer_display_color_per_instance_colours_each_instance():
    """Hydra and Arnold give each instance its element of the instancer's vertex/varying primvars. Two instances
    of one unbound cube with displayColor red and blue per instance: Hydra's fallback (a Lambert of albedo
    displayColor) under E = 2 head-on is displayColor·2/π on each +z face. Before, both were the prototype's grey
    (0.18·2/π) and a warning said the primvar was not read."""
    left, right, info = _cube_centres(_two_cubes())
    np.testing.assert_allclose(left, np.array([1.0, 0.0, 0.0]) * 2 / np.pi, rtol=0.03, atol=2e-3)
    np.testing.assert_allclose(right, np.array([0.0, 0.0, 1.0]) * 2 / np.pi, rtol=0.03, atol=2e-3)
    assert not any("per-instance primvars" in w for w in info.warnings), info.warnings


def test_an_outer_instancers_primvar_reaches_the_nested_instances():
    """An outer instancer's per-instance primvar colours every instance of the instancer it instances."""
    left, right, _info = _cube_centres(_two_cubes(colours=((0.0, 1.0, 0.0),), nested=True))
    for got in (left, right):
        np.testing.assert_allclose(got, np.array([0.0, 1.0, 0.0]) * 2 / np.pi, rtol=0.03, atol=2e-3)


def _user_data_material(s):
    """Arnold's lambert (Kd 1) whose Kd_color is user_data_rgb("my_color", default grey)."""
    mat = UsdShade.Material.Define(s, "/M")
    sh = UsdShade.Shader.Define(s, "/M/S")
    sh.CreateIdAttr("arnold:lambert")
    sh.CreateInput("Kd", F).Set(1.0)
    ud = UsdShade.Shader.Define(s, "/M/UD")
    ud.CreateIdAttr("arnold:user_data_rgb")
    ud.CreateInput("attribute", Sdf.ValueTypeNames.String).Set("my_color")
    ud.CreateInput("default", C3).Set(Gf.Vec3f(0.5, 0.5, 0.5))
    sh.CreateInput("Kd_color", C3).ConnectToSource(ud.ConnectableAPI(), "out")
    mat.CreateSurfaceOutput("arnold").ConnectToSource(sh.ConnectableAPI(), "out")
    return mat


def test_user_data_rgb_reads_the_instancers_primvar_per_instance():
    """arnold-usd's arnold_materialbuilder tests (test_0186): user_data_rgb reads an instancer's primvars:my_color,
    one colour per instance (Arnold's instance_my_color), not the default grey. Arnold's units: E = I, so the
    Lambert is colour·2/π."""
    left, right, info = _cube_centres(_two_cubes(primvar="my_color", material=_user_data_material,
                                                 colours=((0.8, 0.4, 0.1), (0.1, 0.3, 0.9))))
    np.testing.assert_allclose(left, np.array([0.8, 0.4, 0.1]) * 2 / np.pi, rtol=0.03, atol=2e-3)
    np.testing.assert_allclose(right, np.array([0.1, 0.3, 0.9]) * 2 / np.pi, rtol=0.03, atol=2e-3)


def test_a_per_instance_primvar_no_material_reads_is_named_in_a_warning():
    s = _two_cubes()
    pv = UsdGeom.PrimvarsAPI(s.GetPrimAtPath("/PI")).CreatePrimvar("weight", Sdf.ValueTypeNames.FloatArray, "varying")
    pv.Set([0.5, 1.0])
    _l, _r, info = _cube_centres(s)
    said = [w for w in info.warnings if "per-instance primvars" in w]
    assert len(said) == 1 and "weight" in said[0] and "displayColor" not in said[0], said


# ---------------------------------------------------------------- a light's camera weight
def test_a_dome_with_a_fractional_arnold_camera_weight_is_seen_at_that_weight():
    """Arnold's light parameter ``camera`` weights the light's contribution to camera rays (arnold-usd's test_1238:
    a white dome of intensity 1 with primvars:arnold:camera = 0.1 is a 0.1 grey background in the reference; it
    was drawn white). The quad it lights is lit the same whatever the weight."""
    def frame(weight):
        s = new_stage()
        add_camera(s, eye=(0, 0, 10))
        quad(s, "/Q", half=1.0)
        dome = UsdLux.DomeLight.Define(s, "/Dome")
        UsdGeom.PrimvarsAPI(dome.GetPrim()).CreatePrimvar("arnold:camera", F).Set(weight)
        scene, info = load_stage(s, width=24, height=16)
        return render(scene, RenderSettings(width=24, height=16, samples=1)).rgb

    full, tenth = frame(1.0), frame(0.1)
    np.testing.assert_allclose(full[0, 0], (1, 1, 1), atol=1e-4)
    np.testing.assert_allclose(tenth[0, 0], (0.1, 0.1, 0.1), atol=1e-4)
    np.testing.assert_allclose(tenth[8, 12], full[8, 12], rtol=0.05)


def test_an_area_light_with_an_arnold_camera_weight_is_seen_by_the_camera():
    """UsdLux has no camera visibility (our USD lights stay unseen by the camera), but Arnold's ``camera`` parameter
    (``primvars:arnold:camera``, authored by arnold-usd's test_0241 on a cylinder light) shows the light's shape to
    camera rays × w, unless ``primvars:arnold:visibility:camera`` is off (test_2439's lights)."""
    def frame(weight=None, visible=None):
        s = new_stage()
        add_camera(s, eye=(0, 0, 10))
        rect = UsdLux.RectLight.Define(s, "/Rect")  # facing the camera (+Z) at the origin, radiance 3
        rect.CreateWidthAttr(2.0)
        rect.CreateHeightAttr(2.0)
        rect.CreateIntensityAttr(3.0)
        rect.AddRotateXOp().Set(180.0)
        pv = UsdGeom.PrimvarsAPI(rect.GetPrim())
        if weight is not None:
            pv.CreatePrimvar("arnold:camera", F).Set(weight)
        if visible is not None:
            pv.CreatePrimvar("arnold:visibility:camera", Sdf.ValueTypeNames.Bool).Set(visible)
        scene, info = load_stage(s, width=24, height=16, light_units="arnold")
        return render(scene, RenderSettings(width=24, height=16, samples=1)).rgb[8, 12]

    np.testing.assert_allclose(frame(), 0.0, atol=1e-6)  # UsdLux alone: unseen, as before
    np.testing.assert_allclose(frame(weight=1.0), 3.0, rtol=1e-5)
    np.testing.assert_allclose(frame(weight=0.5), 1.5, rtol=1e-5)
    np.testing.assert_allclose(frame(weight=1.0, visible=False), 0.0, atol=1e-6)


def _textured_rect_frame(tmp_path, usdlux_version=None):
    """A 2 × 1 texture (left texel red, right texel blue) on a 2 × 2 RectLight of intensity 3 facing the camera
    (turned 180° about Y: its −Z towards +Z), shown to the camera by Arnold's ``camera`` primvar; the frame's left
    and right thirds."""
    import OpenImageIO as oiio

    path = str(tmp_path / "lr.exr")
    out = oiio.ImageOutput.create(path)
    out.open(path, oiio.ImageSpec(2, 1, 3, oiio.FLOAT))
    out.write_image(np.array([[[1, 0, 0], [0, 0, 1]]], np.float32))
    out.close()
    s = new_stage()
    add_camera(s, eye=(0, 0, 10))
    if usdlux_version is not None:
        rs = s.DefinePrim("/Render/Settings", "RenderSettings")
        rs.CreateAttribute("arnold:global:usdlux_version", Sdf.ValueTypeNames.String).Set(usdlux_version)
    rect = UsdLux.RectLight.Define(s, "/Rect")
    rect.CreateWidthAttr(2.0)
    rect.CreateHeightAttr(2.0)
    rect.CreateIntensityAttr(3.0)
    rect.CreateTextureFileAttr(Sdf.AssetPath(path))
    rect.AddRotateYOp().Set(180.0)
    UsdGeom.PrimvarsAPI(rect.GetPrim()).CreatePrimvar("arnold:camera", F).Set(1.0)
    scene, info = load_stage(s, width=24, height=16)
    rgb = render(scene, RenderSettings(width=24, height=16, samples=1)).rgb
    return rgb[8, 9], rgb[8, 14], info


def test_a_rect_light_texture_is_unmirrored_to_an_eye_facing_it_as_usdlux_says(tmp_path):
    """UsdLux (Arnold's usdlux_version 25.05): the texture reads as an image to an eye facing the emitting side
    (arnold-usd's test_2434.1); radiance = texel × intensity. Arnold's own reading mirrors it (test_2434.2, whose
    RenderSettings say usdlux_version "None")."""
    left, right, info = _textured_rect_frame(tmp_path, "25.05")
    assert not any("texture" in w for w in info.warnings), info.warnings
    np.testing.assert_allclose(left, (3, 0, 0), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(right, (0, 0, 3), rtol=1e-5, atol=1e-6)
    left, right, _ = _textured_rect_frame(tmp_path, "None")
    np.testing.assert_allclose(left, (0, 0, 3), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(right, (3, 0, 0), rtol=1e-5, atol=1e-6)


# ---------------------------------------------------------------- the harness: how Arnold wrote its references
def _write_image(path, values, fmt):
    import OpenImageIO as oiio

    h, w = values.shape[:2]
    buf = oiio.ImageBuf(oiio.ImageSpec(w, h, values.shape[2], fmt))
    buf.set_pixels(oiio.ROI(0, w, 0, h, 0, 1, 0, values.shape[2]), values)
    assert buf.write(str(path)), oiio.geterror()


def test_the_harness_reads_integer_references_as_srgb_and_float_ones_as_linear(tmp_path):
    """tools/fidelity_arnold.reference_linear: Arnold's colour manager writes integer outputs (kick's 8-bit
    TIFF) in its narrow colour space, sRGB-encoded by default, and float outputs linear; a stage whose RenderProduct
    or colour manager names a linear narrow space gets linear integers. Code value 100/255 is sRGB(0.4/π) = 0.1273
    linear (arnold-usd's test_0191)."""
    import sys as _sys
    import os as _os

    _sys.path.insert(0, _os.path.join(_os.path.dirname(_os.path.dirname(_os.path.abspath(__file__))), "tools"))
    import fidelity_arnold as fa
    import OpenImageIO as oiio

    code = np.full((2, 2, 4), 100 / 255, np.float32)
    code[..., 3] = 1.0
    _write_image(tmp_path / "int.tif", (code * 255 + 0.5).astype(np.uint8), oiio.UINT8)
    _write_image(tmp_path / "float.exr", code, oiio.FLOAT)
    plain = new_stage()
    plain.GetRootLayer().Export(str(tmp_path / "plain.usda"))
    linear = new_stage()
    rs = linear.DefinePrim("/Render/Settings", "RenderSettings")
    rs.CreateAttribute("arnold:color_manager:color_space_narrow", Sdf.ValueTypeNames.String).Set("sRGB")
    linear.GetRootLayer().Export(str(tmp_path / "linear.usda"))

    rgba, enc, _why = fa.reference_linear(str(tmp_path / "int.tif"), str(tmp_path / "plain.usda"))
    assert enc == "srgb"
    np.testing.assert_allclose(rgba[0, 0, :3], 0.4 / np.pi, rtol=0.01)
    np.testing.assert_allclose(rgba[0, 0, 3], 1.0)
    rgba, enc, _why = fa.reference_linear(str(tmp_path / "float.exr"), str(tmp_path / "plain.usda"))
    assert enc == "linear"
    np.testing.assert_allclose(rgba[0, 0, :3], 100 / 255, rtol=1e-5)
    rgba, enc, why = fa.reference_linear(str(tmp_path / "int.tif"), str(tmp_path / "linear.usda"))
    assert enc == "linear" and "color_space_narrow" in why
    np.testing.assert_allclose(rgba[0, 0, :3], 100 / 255, rtol=1e-5)


def test_the_harness_reads_our_colours_in_arnolds_rendering_space(tmp_path):
    """Arnold's default colour manager renders in ACEScg (every reference log of arnold-usd's suite): a constant
    (1, 0, 0) is ACEScg red, written to an 8-bit output as Rec.709 (1.705, -0.130, -0.024) before its encoding
    (MaterialX's acescg_to_lin_rec709). A float output stays in the rendering space; a stage whose colour manager
    renders in "sRGB" (linear Rec.709 in Arnold's config) needs no conversion."""
    import sys as _sys
    import os as _os

    _sys.path.insert(0, _os.path.join(_os.path.dirname(_os.path.dirname(_os.path.abspath(__file__))), "tools"))
    import fidelity_arnold as fa

    red = np.zeros((1, 1, 4), np.float32)
    red[..., 0] = red[..., 3] = 1.0
    plain = new_stage()
    assert fa.rendering_space(plain)[0] == "acescg"
    np.testing.assert_allclose(fa.to_output_space(red, "acescg", integer=True)[0, 0],
                               (1.705051, -0.130256, -0.024003, 1.0), atol=1e-5)
    np.testing.assert_allclose(fa.to_output_space(red, "acescg", integer=False), red)
    s = new_stage()
    rs = s.DefinePrim("/Render/Settings", "RenderSettings")
    rs.CreateAttribute("arnold:color_manager:color_space_linear", Sdf.ValueTypeNames.String).Set("sRGB")
    space, why = fa.rendering_space(s)
    assert space == "rec709" and "color_space_linear" in why
    np.testing.assert_allclose(fa.to_output_space(red, space, integer=True), red)


# ---------------------------------------------------------------- a primvar read into a colour other than the base
def test_arnold_flat_shows_the_primvar_its_user_data_rgb_reads():
    """arnold-usd's test_2530/test_2687: an arnold:flat whose color is a user_data_rgb of the mesh's primvar
    test_color. flat is unlit: each face shows its colour exactly (here uniform, one per face). It showed the
    fallback white with a warning ("color driven by arnold:user_data_rgb is not supported")."""
    s = new_stage()
    add_camera(s, eye=(0, 0, 10))
    q = quad(s, "/Q", half=3.0)
    q.CreateFaceVertexCountsAttr([4, 4])
    q.CreatePointsAttr([(-3, -3, 0), (0, -3, 0), (0, 3, 0), (-3, 3, 0), (3, -3, 0), (3, 3, 0)])
    q.CreateFaceVertexIndicesAttr([0, 1, 2, 3, 1, 4, 5, 2])
    pv = UsdGeom.PrimvarsAPI(q).CreatePrimvar("test_color", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.uniform)
    pv.Set([Gf.Vec3f(0.2, 0.6, 0.9), Gf.Vec3f(0.9, 0.3, 0.1)])
    mat = UsdShade.Material.Define(s, "/M")
    flat = UsdShade.Shader.Define(s, "/M/Flat")
    flat.CreateIdAttr("arnold:flat")
    ud = UsdShade.Shader.Define(s, "/M/UD")
    ud.CreateIdAttr("arnold:user_data_rgb")
    ud.CreateInput("attribute", Sdf.ValueTypeNames.String).Set("test_color")
    flat.CreateInput("color", C3).ConnectToSource(ud.ConnectableAPI(), "out")
    mat.CreateSurfaceOutput("arnold").ConnectToSource(flat.ConnectableAPI(), "out")
    bind(q, mat)
    scene, info = load_stage(s, width=24, height=16, default_light=False)
    img = render(scene, RenderSettings(width=24, height=16, samples=1)).rgb
    np.testing.assert_allclose(img[8, 6], (0.2, 0.6, 0.9), atol=2e-3)
    np.testing.assert_allclose(img[8, 18], (0.9, 0.3, 0.1), atol=2e-3)
    assert not any("not supported" in w for w in info.warnings), info.warnings


def test_the_harness_renders_the_stages_data_window_as_kick_does(tmp_path):
    """kick renders the region of the stage's resolution that its RenderSettings' dataWindowNDC names (arnold-usd's
    test_0233/0234, 4.5/4.8 dB when the whole frame was squeezed into the region's size): the harness keeps the
    stage's resolution and window (fidelity_arnold.stage_data_window) on its own settings prim."""
    import sys as _sys
    import os as _os

    _sys.path.insert(0, _os.path.join(_os.path.dirname(_os.path.dirname(_os.path.abspath(__file__))), "tools"))
    import fidelity_arnold as fa
    from pxr import UsdRender

    s = new_stage()
    add_camera(s, eye=(0, 0, 10))
    quad(s, "/Q")
    rs = UsdRender.Settings.Define(s, "/Render/Settings")
    rs.CreateResolutionAttr(Gf.Vec2i(160, 120))
    rs.CreateDataWindowNDCAttr(Gf.Vec4f(0.4, 0.1, 0.6, 1.2))
    path = str(tmp_path / "dw.usda")
    s.GetRootLayer().Export(path)
    window = fa.stage_data_window(Usd.Stage.Open(path))
    assert window == ((160, 120), pytest.approx((0.4, 0.1, 0.6, 1.2)))
    stage, prim = fa.arnold_camera(path, "/Cam", None, window)
    _scene, info = load_stage(stage, render_settings_prim=prim)
    assert (info.width, info.height) == (32, 132)


def test_the_harness_opens_a_stage_where_kick_runs_it(tmp_path):
    """arnold-usd's suite runs kick in a directory holding the test's data files beside the suite's common/:
    a stage's ../common/bricks.png names testsuite/common/bricks.png there (fidelity_arnold.kick_layout); read
    from data/ it names test_X/common/, which does not exist (test_1567's dome texture was "not found")."""
    import sys as _sys
    import os as _os

    _sys.path.insert(0, _os.path.join(_os.path.dirname(_os.path.dirname(_os.path.abspath(__file__))), "tools"))
    import fidelity_arnold as fa

    suite = tmp_path / "testsuite"
    (suite / "common").mkdir(parents=True)
    (suite / "common" / "bricks.png").write_bytes(b"png")
    (suite / "test_0001" / "data").mkdir(parents=True)
    s = new_stage()
    s.DefinePrim("/T").CreateAttribute("file", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath("../common/bricks.png"))
    s.GetRootLayer().Export(str(suite / "test_0001" / "data" / "test.usda"))
    path = fa.kick_layout(str(suite / "test_0001" / "data" / "test.usda"), str(tmp_path / "run"))
    mirrored = Usd.Stage.Open(path)
    got = mirrored.GetPrimAtPath("/T").GetAttribute("file").Get().resolvedPath
    assert got and _os.path.samefile(got, suite / "common" / "bricks.png")
    raw = Usd.Stage.Open(str(suite / "test_0001" / "data" / "test.usda"))
    assert not raw.GetPrimAtPath("/T").GetAttribute("file").Get().resolvedPath


def test_reading_a_stage_in_acescg_converts_colour_textures_not_constants(tmp_path):
    """load_stage(rendering_space="acescg"): Arnold's default colour manager converts a colour texture from sRGB
    into its ACEScg rendering space and takes constants as ACEScg numbers. An 8-bit sRGB texture of pure red,
    shown unlit (arnold:image as the surface), is Rec.709→AP1 (0.6131, 0.0702, 0.0206) there (the inverse of
    MaterialX's acescg_to_lin_rec709; converted back for display it is red again); a flat constant is unchanged."""
    import OpenImageIO as oiio
    from tracer.colorspace import AP1_TO_REC709

    red = np.zeros((2, 2, 3), np.uint8)
    red[..., 0] = 255
    _write_image(tmp_path / "red.png", red, oiio.UINT8)
    img_stage = st.arnold_uv_quad("arnold:image", {})
    UsdShade.Shader(img_stage.GetPrimAtPath("/M/S")).CreateInput("filename", Sdf.ValueTypeNames.Asset).Set(
        Sdf.AssetPath(str(tmp_path / "red.png")))
    flat_stage = st.arnold_uv_quad("arnold:flat", {"color": (C3, Gf.Vec3f(0.2, 0.5, 0.7))})

    def centre(stage, space):
        scene, _info = load_stage(stage, width=8, height=8, default_light=False, rendering_space=space)
        return render(scene, RenderSettings(width=8, height=8, samples=1)).rgb[4, 4]

    want = np.linalg.inv(np.asarray(AP1_TO_REC709)) @ np.array([1.0, 0.0, 0.0])
    np.testing.assert_allclose(want, (0.6131, 0.0702, 0.0206), atol=1e-3)
    np.testing.assert_allclose(centre(img_stage, "acescg"), want, atol=2e-3)
    np.testing.assert_allclose(centre(img_stage, "rec709"), (1.0, 0.0, 0.0), atol=2e-3)
    np.testing.assert_allclose(centre(flat_stage, "acescg"), (0.2, 0.5, 0.7), atol=2e-3)


def test_native_instances_take_the_colour_primvar_authored_on_each_instance():
    """arnold-usd's test_0188: instanceable prims referencing one cube, each with its own constant displayColor,
    which the prototype's gprim inherits (UsdGeomPrimvarsAPI). Each instance shows its own colour (Hydra's fallback
    Lambert: displayColor·2/π under E = 2 head-on); the tracer's shared prototype gave both the first one's."""
    s = new_stage()
    add_camera(s, eye=(0, 0, 10))
    sun = UsdLux.DistantLight.Define(s, "/Sun")
    sun.CreateIntensityAttr(2.0)
    sun.CreateNormalizeAttr(True)
    proto = s.DefinePrim("/Proto", "Xform")
    proto.SetSpecifier(Sdf.SpecifierClass)
    UsdGeom.Cube.Define(s, "/Proto/Cube").CreateSizeAttr(1.0)
    for name, x, colour in (("A", -1.5, (1.0, 0.0, 0.0)), ("B", 1.5, (0.0, 0.0, 1.0))):
        inst = UsdGeom.Xform.Define(s, f"/{name}")
        inst.GetPrim().GetInherits().AddInherit("/Proto")
        inst.GetPrim().SetInstanceable(True)
        inst.AddTranslateOp().Set(Gf.Vec3d(x, 0, 0))
        UsdGeom.PrimvarsAPI(inst).CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray,
                                                UsdGeom.Tokens.constant).Set([Gf.Vec3f(*colour)])
    assert s.GetPrimAtPath("/A/Cube").IsInstanceProxy()
    left, right, _info = _cube_centres(s)
    np.testing.assert_allclose(left, np.array([1.0, 0.0, 0.0]) * 2 / np.pi, rtol=0.03, atol=2e-3)
    np.testing.assert_allclose(right, np.array([0.0, 0.0, 1.0]) * 2 / np.pi, rtol=0.03, atol=2e-3)


def test_a_mesh_light_is_named_in_a_warning():
    """UsdLux's MeshLightAPI on a gprim (arnold-usd's test_2707, test_2390) is not drawn as a light: one warning
    names it (it was silent)."""
    s = new_stage()
    add_camera(s, eye=(0, 0, 10))
    q = quad(s, "/Q", half=1.0)
    UsdLux.MeshLightAPI.Apply(q.GetPrim())
    _scene, info = load_stage(s, width=8, height=8)
    said = [w for w in info.warnings if "MeshLightAPI" in w]
    assert len(said) == 1 and "/Q" in said[0], info.warnings

"""USD as pipelines write it (issue #21): stages that crashed, were refused, or lost geometry silently. Each stage is
built in tests/usd_pipeline_stages.py; each test checks the picture or the geometry against a closed form."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, Sdf, UsdGeom, UsdLux, UsdShade

from tracer import RenderSettings, read_image
from tracer import render
from usd_io import load_stage

import usd_pipeline_stages as st
from test_cli import whitted
from test_usd_reader import usd_pixel
from usd_pipeline_stages import (add_camera, bind, blend_shape_stage, float_meters_per_unit_usdc, new_stage,
                                 preview_material, quad)


# ---------------------------------------------------------------- crashes and refusals
def test_float_meters_per_unit_renders(tmp_path):
    """pxr raises on a float metersPerUnit; the layer's value is read as authored and the ball is drawn."""
    path = float_meters_per_unit_usdc(tmp_path / "f.usdc", 0.5)
    scene, info = load_stage(str(path), width=24, height=16)
    assert info.meters_per_unit == 0.5
    img = render(scene, RenderSettings(width=24, height=16, samples=1)).rgb
    assert img[8, 12].mean() > 0.2 and img[0, 0].mean() < img[8, 12].mean()  # the ball, centred, lit
    out = tmp_path / "f.png"
    res = whitted("info", path)
    assert res.returncode == 0 and "Traceback" not in res.stderr and "metersPerUnit: 0.5" in res.stdout
    res = whitted("render", path, "-o", out, "--width", 24, "--quiet")
    assert res.returncode == 0 and "Traceback" not in res.stderr, res.stderr


def _lifted(scene):
    """z of the quad's two far corners (y = +1) and two near ones, from the scene's vertices."""
    v = np.unique(np.round(scene.vertices, 5), axis=0)
    return v[v[:, 1] > 0][:, 2], v[v[:, 1] < 0][:, 2]


@pytest.mark.parametrize("time,want", [(0.0, 0.0), (0.5, 0.5), (1.0, 1.0)])
def test_blend_shape_without_joint_influences(time, want):
    """No traceback from ComputeJointInfluences: the blend shape alone deforms the quad by weight × offset."""
    scene, info = load_stage(blend_shape_stage(), time=time, width=8, height=8, complexity="low")
    far, near = _lifted(scene)
    np.testing.assert_allclose(far, want, atol=1e-5)
    np.testing.assert_allclose(near, 0.0, atol=1e-5)
    assert not any("rest" in w for w in info.warnings), info.warnings


def test_blend_shape_inbetween_and_skinning_compose():
    """Inbetween at 0.5 lifts by its own 0.8 (UsdSkel's piecewise-linear sub-shapes); with a joint that moves
    (0, 3, 0) the shape is applied first, then the skinning."""
    scene, _ = load_stage(blend_shape_stage(inbetween=True), time=0.5, width=8, height=8, complexity="low")
    far, _near = _lifted(scene)
    np.testing.assert_allclose(far, 0.8, atol=1e-5)
    scene, info = load_stage(blend_shape_stage(with_joints=True), time=1.0, width=8, height=8, complexity="low")
    v = np.unique(np.round(scene.vertices, 5), axis=0)
    want = np.array([(-1, -1, 0), (1, -1, 0), (1, 1, 1), (-1, 1, 1)], float) + [0, 3, 0]
    np.testing.assert_allclose(v, np.unique(want, axis=0), atol=1e-5)


def test_blend_shape_frames_differ_in_the_picture():
    """The camera looks along +y at the quad edge-on: lifted at frame 1 it turns towards the camera and covers
    rows of the picture it did not."""
    cover = []
    for t in (0.0, 1.0):
        scene, _ = load_stage(blend_shape_stage(), time=t, width=36, height=24, complexity="low")  # 3:2 aperture
        img = render(scene, RenderSettings(width=36, height=24, samples=1)).rgb
        cover.append(int((np.abs(img - img[0, 0]).max(axis=2) > 0.02).sum()))
    assert cover[1] > cover[0] + 60, cover


def _lit_quad(**inputs):
    s = new_stage()
    add_camera(s, eye=(0, 0, 10))
    sun = UsdLux.DistantLight.Define(s, "/Sun")
    sun.CreateIntensityAttr(2.0)
    sun.CreateNormalizeAttr(True)  # irradiance = intensity
    q = quad(s, "/Q", half=3.0)
    bind(q, preview_material(s, "/M", diffuseColor=(0.8, 0.4, 0.2), **inputs))
    return s


def test_preview_surface_out_of_range_is_clamped_not_refused():
    """roughness 1.05 and metallic -0.2 render as 1 and 0, one warning per material and input."""
    scene, info = load_stage(_lit_quad(roughness=1.05, metallic=-0.2), width=16, height=12)
    ref, _ = load_stage(_lit_quad(roughness=1.0, metallic=0.0), width=16, height=12)
    got = [w for w in info.warnings if "outside the UsdPreviewSurface range" in w]
    assert len(got) == 2 and any("roughness 1.05" in w for w in got) and any("metallic -0.2" in w for w in got)
    a = render(scene, RenderSettings(width=16, height=12, samples=1)).rgb
    b = render(ref, RenderSettings(width=16, height=12, samples=1)).rgb
    assert a[6, 8].max() > 0.1
    np.testing.assert_array_equal(a, b)


# ---------------------------------------------------------------- instancing, every combination
def _cube_centres(scene):
    from tracer.scene import flatten

    f = flatten(scene)
    c = f.vertices[f.triangles].reshape(-1, 36, 3).mean(axis=1)  # 12 triangles per cube
    return sorted(map(tuple, np.round(c, 4).tolist()))


def test_prototypes_under_an_over_are_drawn_through_the_instancer():
    s = st.instancer_under_over()
    add_camera(s, eye=(1.5, 0, 12))
    scene, info = load_stage(s, width=48, height=32)
    assert _cube_centres(scene) == [(0, 0, 0), (3, 0, 0)]
    img = render(scene, RenderSettings(width=48, height=32, samples=1)).rgb
    cam = s.GetPrimAtPath("/Cam")
    for x in (0.0, 3.0):  # both cubes are in the picture where pxr's frustum puts them
        px, py = np.round(usd_pixel(cam, (x, 0, 0.5), 48, 32)).astype(int)
        assert np.abs(img[py, px] - img[0, 0]).max() > 0.05


def test_instancer_of_instancers():
    scene, _ = load_stage(st.nested_instancers(), width=16)
    want = [(x, y, 1.0) for x in (0, 2, 4) for y in (0, 5)]
    assert _cube_centres(scene) == sorted(want)


def test_native_instances_holding_an_instancer():
    scene, _ = load_stage(st.native_instance_of_instancer(), width=16)
    assert _cube_centres(scene) == sorted((x, y, 0.0) for x in (0, 2) for y in (0, 4))


@pytest.mark.parametrize("time,far", [(0.0, 20), (1.0, 30)])
def test_deep_mixed_instancing_with_ids_invisible_ids_and_time_samples(time, far):
    scene, info = load_stage(st.deep_mixed_instancing(), width=16, time=time)
    want = [(ox + x, y, 0.0) for ox in (0, far) for x in (0, 4) for y in (0, 10)]  # id 8 (x = 2) invisible
    assert _cube_centres(scene) == sorted(want)


# ---------------------------------------------------------------- NURBS, tetrahedra
def _centre_pixel_hits(stage, w=40, h=30):
    scene, info = load_stage(stage, width=w, height=h)
    img = render(scene, RenderSettings(width=w, height=h, samples=1)).rgb
    return np.abs(img[h // 2, w // 2] - img[0, 0]).max() > 0.05, scene, info


def _looking_at_the_arc(stage):
    add_camera(stage, eye=(6, 6, 1.5), rotate_z=135.0, rotate_x=90.0)  # looking along (−1, −1, 0)
    return stage


def test_rational_nurbs_patch_is_an_exact_circular_arc_and_is_drawn():
    s = _looking_at_the_arc(st.nurbs_patch_stage(weights=(1, 0.5 ** 0.5, 1)))
    hit, scene, info = _centre_pixel_hits(s)
    r = np.hypot(scene.vertices[:, 0], scene.vertices[:, 1])
    np.testing.assert_allclose(r, 2.0, atol=1e-9)  # rational quadratic: exactly the circle (non-rational bulges)
    assert scene.vertices[:, 2].min() == 0 and scene.vertices[:, 2].max() == 3
    assert hit and not any("not supported" in w for w in info.warnings), info.warnings


def test_nurbs_patch_trim_loop_cuts_a_hole():
    """An inner trim loop (0.25..0.75)² removes the middle: the centre ray passes through the hole."""
    s = _looking_at_the_arc(st.nurbs_patch_stage(weights=(1, 0.5 ** 0.5, 1), trim_hole=True))
    hit, scene, _ = _centre_pixel_hits(s)
    assert not hit
    full, _ = load_stage(st.nurbs_patch_stage(weights=(1, 0.5 ** 0.5, 1)), width=8)
    assert 0.7 < len(scene.triangles) / len(full.triangles) < 0.8  # a quarter of the square (grid-cell precision)


def test_nurbs_curve_is_a_tube_of_its_width():
    s = st.nurbs_curve_stage(width=0.4)
    add_camera(s, eye=(3, 0, 10))
    scene, info = load_stage(s, width=60, height=40)
    lo, hi = scene.vertices.min(axis=0), scene.vertices.max(axis=0)
    np.testing.assert_allclose([lo, hi], [[0, -0.2, -0.2], [6, 0.2, 0.2]], atol=1e-9)
    img = render(scene, RenderSettings(width=60, height=40, samples=1)).rgb
    cam = s.GetPrimAtPath("/Cam")
    on = np.round(usd_pixel(cam, (3, 0, 0.2), 60, 40)).astype(int)
    off = np.round(usd_pixel(cam, (3, 0.6, 0), 60, 40)).astype(int)
    assert np.abs(img[on[1], on[0]] - img[0, 0]).max() > 0.05
    assert np.abs(img[off[1], off[0]] - img[0, 0]).max() < 1e-3


def test_tet_mesh_renders_its_surface_faces():
    s = st.tet_stage()
    add_camera(s, eye=(0.4, 0.4, 8))
    hit, scene, _ = _centre_pixel_hits(s)
    assert hit and len(scene.triangles) == 6  # the shared face is inside


# ---------------------------------------------------------------- texture paths
def _emission_image(path, w=32, h=32):
    scene, info = load_stage(path, width=w, height=h, default_light=False)
    return render(scene, RenderSettings(width=w, height=h, samples=1)).rgb, info


def test_udim_tiles_land_where_their_numbers_say(tmp_path):
    """uv spans [0, 2] × [0, 2]: tiles 1001 (red, lower left), 1002 (green, lower right), 1011 (blue, upper left);
    1012 is missing and reads the fallback (black)."""
    path = st.emissive_texture_quad(str(tmp_path), "./tex/paint.<UDIM>.png", ((0, 0), (2, 0), (2, 2), (0, 2)),
                                    {"tex/paint.1001.png": (255, 0, 0), "tex/paint.1002.png": (0, 255, 0),
                                     "tex/paint.1011.png": (0, 0, 255)})
    img, info = _emission_image(path)
    assert not any("UDIM" in w for w in info.warnings), info.warnings
    quarters = {"lower left": img[24, 8], "lower right": img[24, 24], "upper left": img[8, 8],
                "upper right": img[8, 24]}
    np.testing.assert_allclose(quarters["lower left"], (1, 0, 0), atol=1e-3)
    np.testing.assert_allclose(quarters["lower right"], (0, 1, 0), atol=1e-3)
    np.testing.assert_allclose(quarters["upper left"], (0, 0, 1), atol=1e-3)
    np.testing.assert_allclose(quarters["upper right"], (0, 0, 0), atol=1e-3)


def test_windows_backslash_texture_path_is_found(tmp_path):
    path = st.emissive_texture_quad(str(tmp_path), "textures\\green.png", ((0, 0), (1, 0), (1, 1), (0, 1)),
                                    {"textures/green.png": (0, 255, 0)})
    img, info = _emission_image(path)
    np.testing.assert_allclose(img[16, 16], (0, 1, 0), atol=1e-3)
    assert any("backslash" in w for w in info.warnings)


# ---------------------------------------------------------------- primvars: inheritance, interpolation
@pytest.mark.parametrize("subdivided", [False, True])
def test_display_color_on_an_ancestor_is_inherited(subdivided):
    s = st.inherited_display_color(subdivided)
    scene, info = load_stage(s, width=60, height=40)
    img = render(scene, RenderSettings(width=60, height=40, samples=1)).rgb
    cam = s.GetPrimAtPath("/Cam")
    for p in ((0, 0, 0), (2.5, 0, 0.5)):  # the quad's centre, the ball's top
        x, y = np.round(usd_pixel(cam, p, 60, 40)).astype(int)
        c = img[y, x]
        assert c[0] > 3 * c[1] and c[0] > 3 * c[2], (p, c)  # red-orange, not Hydra's grey


def test_points_keep_their_per_point_colours():
    """Not averaged to grey: each sphere shows its own point's colour, in the picture."""
    for interpolation in ("vertex", "varying", "uniform"):
        s = st.coloured_points(interpolation)
        scene, info = load_stage(s, width=60, height=40)
        assert not any("averaged" in w for w in info.warnings)
        img = render(scene, RenderSettings(width=60, height=40, samples=1)).rgb
        cam = s.GetPrimAtPath("/Cam")
        for x_world, channel in ((-2, 0), (0, 1), (2, 2)):
            x, y = np.round(usd_pixel(cam, (x_world, 0, 0.5), 60, 40)).astype(int)
            c = img[y, x]
            assert c[channel] > 0.1 and c[channel] > 5 * np.delete(c, channel).max(), (interpolation, x_world, c)


@pytest.mark.parametrize("interpolation", ["vertex", "uniform"])
def test_curves_keep_per_vertex_and_per_curve_colours(interpolation):
    s = st.coloured_curves(interpolation)
    scene, info = load_stage(s, width=60, height=40)
    assert not any("averaged" in w for w in info.warnings)
    # vertex: the tube's ring at a control point has that point's colour; uniform: each curve its own
    want = {"vertex": {(-2, 0, 0): (1, 0, 0), (2, 2, 0): (0, 0, 1)},
            "uniform": {(0, 0, 0): (1, 0, 0), (0, 2, 0): (0, 0, 1)}}[interpolation]
    for p, c in want.items():
        v = np.linalg.norm(scene.vertices - np.asarray(p, float), axis=1)
        corner = np.isin(scene.triangles, np.flatnonzero(v < 0.3))
        got = scene.colors[corner]
        assert len(got) and np.allclose(got, c, atol=1e-6), (p, got[:2])


def test_camera_clipping_plane_parallel_to_the_image_cuts_the_near_quad():
    """Two quads facing the camera at depths 4 (red) and 8 (blue); a clipping plane (0, 0, −1, −6) keeps depth >= 6:
    the centre pixel sees blue through where red was. (The oblique plane cuts elsewhere: next test.)"""
    s = new_stage()
    cam = add_camera(s, eye=(0, 0, 10))
    for path, z, rgb in (("/Near", 6.0, (1, 0, 0)), ("/Far", 2.0, (0, 0, 1))):
        q = quad(s, path, z=z, half=3.0)
        q.CreateDisplayColorAttr([rgb])
    scene, _ = load_stage(s, width=20, height=14)
    before = render(scene, RenderSettings(width=20, height=14, samples=1)).rgb[7, 10]
    cam.CreateClippingPlanesAttr([Gf.Vec4f(0, 0, -1, -6), Gf.Vec4f(0.5, 0, -1, -1)])
    scene, info = load_stage(s, width=20, height=14)
    after = render(scene, RenderSettings(width=20, height=14, samples=1)).rgb[7, 10]
    assert before[0] > 5 * before[2] and after[2] > 5 * after[0], (before, after)
    assert not any("clipping plane" in w for w in info.warnings)


def test_camera_oblique_clipping_plane_clips_each_eye_ray():
    """The same quads (red at depth 4, blue at depth 8, both |x| <= 3) and the oblique plane (1, 0, −½, −1): it
    keeps x − ½z − 1 >= 0 in camera space, i.e. x >= −1 at depth 4 and x >= −3 at depth 8. A ray whose red hit has
    x_r in [−1.5, −1) is cut there and meets blue at x = 2·x_r (kept); below −1.5 it leaves blue's edge (background);
    from −1 on it sees red. The planes clip eye rays only: the headlight's shadow rays still meet the red quad, so
    blue shows by the dome's light alone. Before: the plane was ignored (one warning) and the row was red
    throughout."""
    s = new_stage()
    cam = add_camera(s, eye=(0, 0, 10))
    for path, z, rgb in (("/Near", 6.0, (1, 0, 0)), ("/Far", 2.0, (0, 0, 1))):
        q = quad(s, path, z=z, half=3.0)
        q.CreateDisplayColorAttr([rgb])
    cam.CreateClippingPlanesAttr([Gf.Vec4f(1, 0, -0.5, -1)])
    w, h = 120, 40
    scene, info = load_stage(s, width=w, height=h)
    row = render(scene, RenderSettings(width=w, height=h, samples=1)).rgb[h // 2]
    o, d = scene.camera.generate_rays((np.arange(w) + 0.5) / w, np.full(w, 0.5))
    x_r = o[:, 0] + (6.0 - o[:, 2]) / d[:, 2] * d[:, 0]  # where each column's ray meets the red quad's plane
    red, blue, bg = row[x_r > -0.95], row[(x_r > -1.45) & (x_r < -1.05)], row[x_r < -1.55]
    assert len(red) and len(blue) and len(bg), x_r[[0, -1]]
    assert np.all(red[:, 0] > 5 * red[:, 2]) and np.all(blue[:, 2] > 5 * blue[:, 0]), (red[:2], blue[:2])
    assert np.allclose(bg[:, 0], bg[:, 2], atol=1e-3), bg[:2]  # the grey dome: neither quad


# ---------------------------------------------------------------- Arnold, OmniPBR, unknown surfaces (#20, USD side)
F, C3, A, B, I, F2 = (Sdf.ValueTypeNames.Float, Sdf.ValueTypeNames.Color3f, Sdf.ValueTypeNames.Asset,
                      Sdf.ValueTypeNames.Bool, Sdf.ValueTypeNames.Int, Sdf.ValueTypeNames.Float2)


def _centre(stage, w=24, h=16):
    scene, info = load_stage(stage, width=w, height=h)
    return render(scene, RenderSettings(width=w, height=h, samples=1)).rgb[h // 2, w // 2], info


def test_arnold_lambert_is_lambertian_with_kd_times_colour():
    """Closed form: a distant light of intensity 2 head-on on albedo Kd·Kd_color gives radiance albedo·2/π (E = I
    in Arnold's units too, usd_io.exporters; tests/test_usd_arnold_fidelity.py)."""
    c = (0.2, 0.4, 0.8)
    px, info = _centre(st.lit_quad_with("arnold:lambert", {"Kd": (F, 0.5), "Kd_color": (C3, Gf.Vec3f(*c))},
                                        output="arnold:surface"))
    np.testing.assert_allclose(px, 0.5 * np.asarray(c) * 2 / np.pi, rtol=0.02)
    assert not any("not supported" in w for w in info.warnings), info.warnings


def test_arnold_standard_surface_reads_as_materialx_standard_surface():
    c = (0.1, 0.3, 0.9)
    s = st.lit_quad_with("arnold:standard_surface", {"base": (F, 1.0), "base_color": (C3, Gf.Vec3f(*c)),
                                                     "specular_roughness": (F, 0.6), "metalness": (F, 0.0)},
                         output="arnold:surface")
    px, info = _centre(s)
    fields = info.materials["/M"]
    assert fields["base_color"] == c and fields["roughness"] == 0.6
    assert px[2] > 2 * px[0] and px[2] > 1.5 * px[1]  # blue, not 18 % grey
    assert not any("not supported" in w for w in info.warnings), info.warnings


def test_arnold_user_data_rgb_reads_the_primvar():
    s = st.lit_quad_with("arnold:standard_surface", {"base": (F, 1.0), "specular": (F, 0.0),
                                                     "specular_roughness": (F, 1.0)},
                         output="arnold:surface", display_color=(0.9, 0.1, 0.1))
    ud = UsdShade.Shader.Define(s, "/M/UD")
    ud.CreateIdAttr("arnold:user_data_rgb")
    ud.CreateInput("attribute", Sdf.ValueTypeNames.String).Set("displayColor")
    UsdShade.Shader(s.GetPrimAtPath("/M/S")).CreateInput("base_color", C3).ConnectToSource(ud.ConnectableAPI(), "out")
    px, _ = _centre(s)
    np.testing.assert_allclose(px, np.asarray((0.9, 0.1, 0.1)) * 2 / np.pi, rtol=0.03)  # E = I (Arnold's too)


def test_omnipbr_constant_inputs_without_the_mdl_file():
    """diffuse_color_constant · albedo_brightness · diffuse_tint, specular_level 0: Lambert's closed form."""
    s = st.lit_quad_with(None, {"diffuse_color_constant": (C3, Gf.Vec3f(0.8, 0.4, 0.2)),
                                "albedo_brightness": (F, 0.5), "diffuse_tint": (C3, Gf.Vec3f(1, 1, 0.5)),
                                "specular_level": (F, 0.0), "reflection_roughness_constant": (F, 0.7)},
                         output="mdl:surface", mdl="OmniPBR")
    px, info = _centre(s)
    np.testing.assert_allclose(px, np.asarray((0.4, 0.2, 0.05)) * 2 / np.pi, rtol=0.02)
    assert info.materials["/M"]["roughness"] == 0.7
    assert not any("not supported" in w for w in info.warnings), info.warnings


def test_omnipbr_emission_in_kit_units():
    s = st.lit_quad_with(None, {"diffuse_color_constant": (C3, Gf.Vec3f(0, 0, 0)), "enable_emission": (B, True),
                                "emissive_color": (C3, Gf.Vec3f(0.5, 1.0, 0.25)), "emissive_intensity": (F, 512.0),
                                "specular_level": (F, 0.0)}, output="mdl:surface", mdl="OmniPBR")
    px, _ = _centre(s)
    np.testing.assert_allclose(px, (0.5, 1.0, 0.25), rtol=0.02)  # 512 · 2^−9 = 1


def test_omnipbr_diffuse_texture_with_texture_scale(tmp_path):
    """A texture red on its left half, green on its right, with texture_scale (2, 1): across the quad red, green,
    red, green."""
    import usd_material_stages as ms

    rg = np.zeros((4, 64, 3), np.uint8)
    rg[:, :32, 0] = rg[:, 32:, 1] = 255
    ms.write_png(str(tmp_path / "rg.png"), rg)
    s = st.lit_quad_with(None, {"diffuse_texture": (A, Sdf.AssetPath(str(tmp_path / "rg.png"))),
                                "texture_scale": (F2, Gf.Vec2f(2, 1)), "specular_level": (F, 0.0)},
                         output="mdl:surface", mdl="OmniPBR")
    st_pv = UsdGeom.PrimvarsAPI(s.GetPrimAtPath("/Q")).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                                      UsdGeom.Tokens.vertex)
    st_pv.Set([(0, 0), (1, 0), (1, 1), (0, 1)])
    s.GetPrimAtPath("/Cam").GetAttribute("horizontalAperture").Set(8.0)  # sees the quad's whole width
    scene, info = load_stage(s, width=64, height=16)
    img = render(scene, RenderSettings(width=64, height=16, samples=1)).rgb
    cam = s.GetPrimAtPath("/Cam")
    for x_world, channel in ((-2.25, 0), (-0.75, 1), (0.75, 0), (2.25, 1)):
        x, y = np.round(usd_pixel(cam, (x_world, 0, 0), 64, 16)).astype(int)
        c = img[y, x]
        assert c[channel] > 5 * c[1 - channel], (x_world, c)


def test_unknown_surface_warns_once_and_shows_display_color():
    s = st.lit_quad_with("PxrSurface", {"diffuseColor": (C3, Gf.Vec3f(0, 1, 0))}, output="ri:surface",
                         display_color=(0.9, 0.1, 0.1))
    px, info = _centre(s)
    got = [w for w in info.warnings if "/M" in w and "not supported" in w]
    assert len(got) == 1 and "PxrSurface" in got[0] and "displayColor" in got[0], info.warnings
    assert px[0] > 5 * px[1]  # the prim's red displayColor, not 18 % grey


# ---------------------------------------------------------------- the first frame
@pytest.mark.parametrize("up", ["Y", "Z"])
def test_flat_stage_without_camera_is_framed_obliquely_not_edge_on(up):
    """A ground plane (the plane through the up axis's normal) seen from usdrecord's front view is a line: the
    default camera takes the oblique view and the plane fills the middle of the picture."""
    s = new_stage(up)
    ground = quad(s, "/Ground", half=2.0)
    if up == "Y":
        ground.AddRotateXOp().Set(-90.0)  # the quad in the XZ plane, facing +Y
    ground.CreateDisplayColorAttr([(0.8, 0.6, 0.2)])
    scene, info = load_stage(s, width=48, height=32)
    img = render(scene, RenderSettings(width=48, height=32, samples=1)).rgb
    hit = np.abs(img - img[0, 0]).max(axis=2) > 0.05
    assert hit[16, 24] and hit.mean() > 0.15, hit.mean()
    assert any("front-right-above" in w for w in info.warnings), info.warnings


def test_solid_stage_without_camera_keeps_usdrecords_front_view():
    s = new_stage("Y")
    UsdGeom.Cube.Define(s, "/Box")
    scene, info = load_stage(s, width=32, height=24)
    assert any("framed from the front" in w for w in info.warnings), info.warnings
    eye = scene.camera.camera_to_world[:3, 3]
    np.testing.assert_allclose(eye[:2], 0.0, atol=1e-9)  # on the +Z axis through the centre
    assert eye[2] > 1


# ---------------------------------------------------------------- UsdRender
def _render_settings_stage(policy=None, resolution=(100, 100), window=None, par=None, products=("beauty.exr",),
                           var_sources=("color", "depth", "fancyLobe")):
    from pxr import UsdRender

    s = new_stage()
    add_camera(s, "/CamA", eye=(0, 0, 5))
    add_camera(s, "/CamB", eye=(0, 0, 20), h=3.6, v=2.4)
    ball = UsdGeom.Sphere.Define(s, "/Ball")
    ball.CreateRadiusAttr(0.5)
    ball.AddTranslateOp().Set(Gf.Vec3d(0.8, 0.4, 0))
    rs = UsdRender.Settings.Define(s, "/Render/Settings")
    rs.CreateResolutionAttr(Gf.Vec2i(*resolution))
    rs.CreateCameraRel().SetTargets(["/CamB"])
    if policy:
        rs.CreateAspectRatioConformPolicyAttr(policy)
    if window:
        rs.CreateDataWindowNDCAttr(Gf.Vec4f(*window))
    if par:
        rs.CreatePixelAspectRatioAttr(par)
    targets = []
    for i, name in enumerate(products):
        p = UsdRender.Product.Define(s, f"/Render/P{i}")
        p.CreateProductNameAttr(name)
        vars_ = []
        for j, src in enumerate(var_sources):
            v = UsdRender.Var.Define(s, f"/Render/P{i}/V{j}")
            v.CreateSourceNameAttr(src)
            vars_.append(v.GetPath())
        p.CreateOrderedVarsRel().SetTargets(vars_)
        targets.append(p.GetPath())
    rs.CreateProductsRel().SetTargets(targets)
    s.SetMetadata("renderSettingsPrimPath", "/Render/Settings")
    return s


@pytest.mark.parametrize("policy,want", [("expandAperture", (3.6, 3.6)), ("cropAperture", (2.4, 2.4)),
                                         ("adjustApertureWidth", (2.4, 2.4)), ("adjustApertureHeight", (3.6, 3.6)),
                                         ("adjustPixelAspectRatio", (3.6, 2.4))])
def test_render_settings_conform_policies(policy, want):
    """Resolution 100 × 100 and CamB (3.6 × 2.4) from the RenderSettings; the conformed aperture as the UsdRender
    spec defines each policy (expand grows the short side, crop shrinks the long one, adjustApertureWidth keeps the
    height, adjustApertureHeight the width, adjustPixelAspectRatio neither)."""
    scene, info = load_stage(_render_settings_stage(policy))
    assert (info.width, info.height, info.camera) == (100, 100, "/CamB")
    np.testing.assert_allclose([scene.camera.horizontal_aperture, scene.camera.vertical_aperture], want,
                               rtol=1e-6)


def test_render_settings_pixel_aspect_ratio():
    """pixelAspectRatio 2 at 100 × 100: the image is 2:1 wide, so expandAperture grows the width: 4.8 × 2.4
    (each pixel 0.048 wide, 0.024 high)."""
    scene, info = load_stage(_render_settings_stage(par=2.0))
    np.testing.assert_allclose([scene.camera.horizontal_aperture, scene.camera.vertical_aperture], (4.8, 2.4),
                               rtol=1e-6)


def test_render_settings_products_vars_and_flags_win():
    scene, info = load_stage(_render_settings_stage(), width=30, camera="/CamA")
    assert info.camera == "/CamA" and info.width == 30
    spec = info.render_settings
    assert spec.products == ["beauty.exr"] and spec.aovs == ["depth"]
    assert any("fancyLobe" in w for w in info.warnings)


def test_every_tracer_aov_is_a_render_var_by_its_own_name():
    """A RenderVar's sourceName reads every tracer AOV by its name (tracer.settings.AOV_NAMES, the one list:
    raydepth and shadow_catcher were missing from the reader's own copy and warned), and the other renderers'
    names (Ci, z, primId) as well."""
    from tracer.settings import AOV_NAMES

    _, info = load_stage(_render_settings_stage(var_sources=("Ci", "z", "primId") + AOV_NAMES))
    assert info.render_settings.aovs == ["depth", "objectid"] + [a for a in AOV_NAMES if a not in ("depth",
                                                                                                   "objectid")]
    assert not any("no counterpart" in w for w in info.warnings), info.warnings


def test_render_settings_data_window_renders_that_part():
    """dataWindowNDC (0.5, 0.5, 1, 1): the upper-right quarter of the full frame, as its own 50 × 50 image."""
    full_scene, _ = load_stage(_render_settings_stage())
    part_scene, info = load_stage(_render_settings_stage(window=(0.5, 0.5, 1.0, 1.0)))
    assert (info.width, info.height) == (50, 50)
    full = render(full_scene, RenderSettings(width=100, height=100, samples=2)).rgb
    part = render(part_scene, RenderSettings(width=50, height=50, samples=2)).rgb
    assert np.abs(full[:50, 50:] - part).mean() < 0.01 and part.max() > 0.2  # the ball is up and right


def test_render_settings_data_window_beyond_the_frame_renders_the_overscan():
    """UsdRender's dataWindowNDC may reach past 0..1 (overscan; arnold-usd's test_0233): (0.5, 0.5, 1.25, 1) is
    the upper-right quarter of the frame and a quarter of its width more, 75 × 50 pixels."""
    full_scene, _ = load_stage(_render_settings_stage())
    part_scene, info = load_stage(_render_settings_stage(window=(0.5, 0.5, 1.25, 1.0)))
    assert (info.width, info.height) == (75, 50) and not any("dataWindowNDC" in w for w in info.warnings)
    full = render(full_scene, RenderSettings(width=100, height=100, samples=2)).rgb
    part = render(part_scene, RenderSettings(width=75, height=50, samples=2)).rgb
    assert np.abs(full[:50, 50:] - part[:, :50]).mean() < 0.01 and part.max() > 0.2


def test_camera_without_render_settings_expands_its_aperture():
    """A 16:9 aperture rendered at 4:3 keeps its whole width (Arnold's expandAperture), not a 1.33x zoom."""
    s = new_stage()
    add_camera(s, h=3.2, v=1.8)
    UsdGeom.Sphere.Define(s, "/Ball")
    scene, _ = load_stage(s, width=80, height=60)
    np.testing.assert_allclose([scene.camera.horizontal_aperture, scene.camera.vertical_aperture], [3.2, 2.4],
                               rtol=1e-6)


# ---------------------------------------------------------------- light units of known exporters
def _exporter_stage(doc=None, custom=None, light="sphere", intensity=10.0, radius=0.1, normalize=None):
    s = new_stage()
    if doc:
        s.GetRootLayer().documentation = doc
    if custom:
        s.GetRootLayer().customLayerData = custom
    add_camera(s, eye=(0, 0, 10))
    q = quad(s, "/Floor", half=3.0)
    q.CreateDisplayColorAttr([(0.5, 0.5, 0.5)])
    if light == "sphere":
        lt = UsdLux.SphereLight.Define(s, "/Lamp")
        lt.CreateRadiusAttr(radius)
        lt.AddTranslateOp().Set(Gf.Vec3d(0, 0, 2))
    else:
        lt = UsdLux.DomeLight.Define(s, "/Dome")
    lt.CreateIntensityAttr(intensity)
    if normalize is not None:
        lt.CreateNormalizeAttr(normalize)
    return s


def _first_light(info):
    return info.lights[0][2]


def test_blender_31_sphere_light_is_power_over_100():
    """Blender 2.83–3.1 wrote intensity = P/100: 10 is a 1000 W point light, 1000/4π W/sr (the spec would read a
    radiance of 10 over r = 0.1: 0.31 W/sr, a near-black frame). The floor under it: radiance albedo·E/π with
    E = I/d², d = 2."""
    s = _exporter_stage("Blender v3.1.2")
    scene, info = load_stage(s, width=40, height=30)
    np.testing.assert_allclose(_first_light(info).intensity, 1000 / (4 * np.pi), rtol=1e-6)
    assert any("Blender 3.1.2" in n for n in info.notes), info.notes
    img = render(scene, RenderSettings(width=40, height=30, samples=4)).rgb
    np.testing.assert_allclose(img[15, 20], 0.5 * (1000 / (4 * np.pi)) / 4 / np.pi, rtol=0.03)
    spec, info = load_stage(s, width=40, height=30, light_units="spec")
    np.testing.assert_allclose(_first_light(info).intensity, 10 * np.pi * 0.01, rtol=1e-6)
    assert not any("exporter" in n for n in info.notes)


def test_blender_34_dome_light_683_is_strength_one():
    s = _exporter_stage("Blender v3.4.1", light="dome", intensity=683.0)
    scene, info = load_stage(s, width=20, height=16)
    np.testing.assert_allclose(scene.background, 683 * 0.0014641, rtol=1e-5)


def test_omniverse_kit_lights_are_minus_nine_ev():
    s = _exporter_stage(custom={"omni_layer": {"name": "root"}}, intensity=512.0, normalize=True)
    scene, info = load_stage(s, width=20, height=16)
    np.testing.assert_allclose(_first_light(info).intensity, 512 * 2 ** -9 / 4, rtol=1e-6)
    assert any("Omniverse Kit" in n for n in info.notes)


def test_current_blender_and_unknown_writers_keep_the_spec():
    for doc in ("Blender v5.0.1", None, "written by hand"):
        scene, info = load_stage(_exporter_stage(doc, normalize=True), width=20, height=16)
        np.testing.assert_allclose(_first_light(info).intensity, 10 / 4, rtol=1e-6)


# ---------------------------------------------------------------- smaller defects
def test_info_shows_a_textureless_dome_without_nan(tmp_path):
    s = new_stage()
    UsdLux.DomeLight.Define(s, "/Dome").CreateIntensityAttr(0.5)
    UsdGeom.Sphere.Define(s, "/Ball")
    path = str(tmp_path / "dome.usda")
    s.GetRootLayer().Export(path)
    res = whitted("info", path)
    assert res.returncode == 0 and "nan" not in res.stdout and "background=[0.5, 0.5, 0.5]" in res.stdout


@pytest.mark.parametrize("argv,want", [(["rendr", "x.usda"], "unknown command 'rendr': choose from render"),
                                       (["-q"], "a command is required")])
def test_command_errors_are_one_plain_line(argv, want):
    res = whitted(*argv)
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2 and len(lines) == 1 and want in lines[0], res.stderr
    assert "whitted: error: whitted:" not in res.stderr


def test_zero_triangles_warns_and_fails_only_when_there_were_gprims(tmp_path):
    bad = new_stage()
    m = UsdGeom.Mesh.Define(bad, "/Lines")
    m.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (1, 1, 0)])
    m.CreateFaceVertexCountsAttr([2])
    m.CreateFaceVertexIndicesAttr([0, 1])
    empty = new_stage()
    UsdGeom.Xform.Define(empty, "/Nothing")
    codes = {}
    for name, stage in (("bad", bad), ("empty", empty)):
        path = str(tmp_path / f"{name}.usda")
        stage.GetRootLayer().Export(path)
        res = whitted("render", path, "-o", tmp_path / f"{name}.png", "--width", 16, "--quiet")
        codes[name] = res
    assert codes["bad"].returncode == 2 and "1 visible gprim(s) (Mesh) gave 0 triangles" in codes["bad"].stderr
    assert [ln for ln in codes["bad"].stderr.splitlines() if ln.startswith("whitted: error")].__len__() == 1
    assert codes["empty"].returncode == 0 and "no visible gprims" in codes["empty"].stderr


def test_usd_diagnostics_are_summarised_alike_in_info_and_render(tmp_path):
    """A primvar with 40 out-of-range indices: pxr prints a line per index; we print one line."""
    s = new_stage()
    add_camera(s)
    q = quad(s, "/Q")
    pv = UsdGeom.PrimvarsAPI(q).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying)
    pv.Set([(0, 0)] * 4)
    pv.SetIndices([0, 1, 2, 3])
    pv.SetIndices([9] * 4)
    q.CreateDisplayColorAttr([(1, 0, 0)])
    path = str(tmp_path / "d.usda")
    s.GetRootLayer().Export(path)
    info = [ln for ln in whitted("info", path).stderr.splitlines() if "usd:" in ln]
    rend = [ln for ln in whitted("render", path, "-o", tmp_path / "d.png", "--width", 8, "--quiet").stderr.splitlines()
            if "usd:" in ln]
    assert info == rend and 1 <= len(info) <= 5, (info, rend)


def test_instancer_with_velocities_at_the_earliest_time_is_placed_not_nan():
    """Positions and velocities sampled from frame 1001 only (a particle cache): at the default (earliest) time the
    instances stand at the first sample's positions; velocity × (EarliestTime − 1001) used to make them NaN."""
    s = new_stage()
    st.cube(s, "/Protos/Box")
    pi = st.point_instancer(s, "/PI", ["/Protos/Box"], [(0, 0, 0), (3, 0, 0)])
    pi.GetPositionsAttr().Clear()
    pi.GetPositionsAttr().Set([Gf.Vec3f(0, 0, 0), Gf.Vec3f(3, 0, 0)], 1001.0)
    pi.CreateVelocitiesAttr().Set([Gf.Vec3f(1, 0, 0), Gf.Vec3f(1, 0, 0)], 1001.0)
    s.GetPrimAtPath("/Protos").SetSpecifier(Sdf.SpecifierOver)
    scene, info = load_stage(s, width=16)
    assert _cube_centres(scene) == [(0, 0, 0), (3, 0, 0)]
    assert not any("singular" in w or "not finite" in w for w in info.warnings), info.warnings


def test_gprims_without_points_are_an_empty_stage_not_a_failure(tmp_path):
    s = new_stage()
    UsdGeom.Mesh.Define(s, "/NoPoints")
    path = str(tmp_path / "e.usda")
    s.GetRootLayer().Export(path)
    res = whitted("render", path, "-o", tmp_path / "e.png", "--width", 16, "--quiet")
    assert res.returncode == 0 and "1 gprim(s) without points or faces" in res.stderr, res.stderr


def test_cylinder_1_is_a_truncated_cone():
    """UsdGeom Cylinder_1 (radiusBottom 1, radiusTop 0.5, height 2, axis Z): every side point at height z has
    radius 0.75 − z/4; its silhouette seen from above is the bottom disk."""
    s = new_stage()
    c = UsdGeom.Cylinder_1.Define(s, "/C")
    c.CreateRadiusBottomAttr(1.0)
    c.CreateRadiusTopAttr(0.5)
    c.CreateHeightAttr(2.0)
    c.CreateAxisAttr("Z")
    add_camera(s, eye=(0, 0, 10))
    scene, info = load_stage(s, width=40, height=30)
    v = scene.vertices
    r = np.hypot(v[:, 0], v[:, 1])
    rim = r > 1e-9
    on_side = rim & (np.abs(r - (0.75 - v[:, 2] / 4)) < 1e-9)
    assert on_side.sum() >= 0.5 * rim.sum() and not any("not supported" in w for w in info.warnings)
    hit, _, _ = _centre_pixel_hits(s)
    assert hit


def test_explain_and_the_farm_frame_a_flat_stage_as_render_does(tmp_path):
    """One framing rule (usd_io.camera.framing_view, through load_stage): the farm's UsdSource gets the same
    oblique camera as a local render."""
    from usd_io.farm import UsdSource

    s = new_stage("Z")
    quad(s, "/Ground", half=2.0).CreateDisplayColorAttr([(0.8, 0.6, 0.2)])
    path = str(tmp_path / "flat.usda")
    s.GetRootLayer().Export(path)
    local, _ = load_stage(path, width=32, height=24)
    farm, settings = UsdSource(path, width=32, height=24).load(None)
    np.testing.assert_allclose(farm.camera.camera_to_world, local.camera.camera_to_world)
    assert local.camera.camera_to_world[2, 3] > 1  # above the ground, not edge-on


def test_nurbs_patch_vertex_colours_blend_like_the_points():
    """displayColor per control point: red on the z = 0 row, blue on the z = 3 row; v is linear (order 2), so the
    colour at height z is red·(1 − z/3) + blue·z/3 exactly."""
    s = st.nurbs_patch_stage(weights=(1, 0.5 ** 0.5, 1))
    pv = UsdGeom.PrimvarsAPI(s.GetPrimAtPath("/Patch")).CreatePrimvar(
        "displayColor", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.vertex)
    pv.Set([Gf.Vec3f(1, 0, 0)] * 3 + [Gf.Vec3f(0, 0, 1)] * 3)
    scene, info = load_stage(s, width=16)
    z = scene.vertices[scene.triangles][..., 2]  # (T, 3)
    c = scene.colors
    np.testing.assert_allclose(c[..., 0], 1 - z / 3, atol=1e-6)
    np.testing.assert_allclose(c[..., 2], z / 3, atol=1e-6)
    assert not any("averaged" in w for w in info.warnings)


def test_nurbs_curve_without_knots_uses_open_uniform_knots():
    """As Storm draws it: an order-2 curve without knots is its control polyline (x 0 → 6 along a right angle)."""
    s = new_stage()
    nc = UsdGeom.NurbsCurves.Define(s, "/C")
    nc.CreatePointsAttr([(0, 0, 0), (3, 0, 0), (3, 3, 0)])
    nc.CreateCurveVertexCountsAttr([3])
    nc.CreateOrderAttr([2])
    nc.CreateWidthsAttr([0.2])
    scene, info = load_stage(s, width=16)
    lo, hi = scene.vertices.min(axis=0), scene.vertices.max(axis=0)
    np.testing.assert_allclose([lo[:2], hi[:2]], [[0.0, -0.1], [3.1, 3.0]], atol=0.02)  # tube ends are open
    assert any("open uniform knots" in w for w in info.warnings)


def test_cli_render_settings_and_light_units_flags(tmp_path):
    """--render-settings picks the prim (its 100 × 100 resolution and CamB), its RenderVar depth is written as an
    AOV; info lists the products; --light-units spec reads a Blender 3.1 lamp as the spec says (darker)."""
    import OpenImageIO as oiio

    s = _render_settings_stage()
    s.SetMetadata("renderSettingsPrimPath", "")
    path = str(tmp_path / "rs.usda")
    s.GetRootLayer().Export(path)
    out = tmp_path / "rs.png"
    res = whitted("render", path, "-o", out, "--render-settings", "/Render/Settings", "--quiet")
    assert res.returncode == 0, res.stderr
    assert oiio.ImageInput.open(str(out)).spec().width == 100 and (tmp_path / "rs.depth.exr").exists()
    info = whitted("info", path, "--render-settings", "/Render/Settings")
    assert "products beauty.exr, AOVs depth" in info.stdout
    bad = whitted("render", path, "-o", out, "--render-settings", "/Nope", "--quiet")
    assert bad.returncode == 2 and "/Render/Settings" in bad.stderr and "Traceback" not in bad.stderr
    lamp = _exporter_stage("Blender v3.1.2")
    lpath = str(tmp_path / "lamp.usda")
    lamp.GetRootLayer().Export(lpath)
    means = []
    for units in ("auto", "spec"):
        o = tmp_path / f"lamp_{units}.exr"
        assert whitted("render", lpath, "-o", o, "--width", 32, "--light-units", units, "--quiet").returncode == 0
        means.append(float(read_image(str(o))[..., :3].mean()))
    assert means[0] > 50 * means[1], means


def test_cli_without_output_writes_the_render_product(tmp_path):
    """No -o: the picture goes to the RenderProduct's productName (relative to the working directory)."""
    s = _render_settings_stage(products=("product_beauty.png",))
    path = str(tmp_path / "p.usda")
    s.GetRootLayer().Export(path)
    res = whitted("render", path, "--quiet", cwd=tmp_path)
    assert res.returncode == 0 and (tmp_path / "product_beauty.png").exists(), res.stderr
    lone = new_stage()
    UsdGeom.Sphere.Define(lone, "/Ball")
    lpath = str(tmp_path / "lone.usda")
    lone.GetRootLayer().Export(lpath)
    res = whitted("render", lpath, "--quiet", cwd=tmp_path)
    assert res.returncode == 2 and "-o OUT is required" in res.stderr


def test_cli_render_opens_the_stage_once(tmp_path, monkeypatch):
    """`whitted render` without -o, two RenderProducts, two frames: the file is opened once (it was opened for the
    first product's name, again for the list of the others and again for each product's render)."""
    from pxr import Usd

    from usd_io import cli

    s = _render_settings_stage(products=("first.png", "second.png"), var_sources=("color",))
    path = str(tmp_path / "two.usda")
    s.GetRootLayer().Export(path)
    opened = []
    real = Usd.Stage.Open
    monkeypatch.setattr(Usd.Stage, "Open", staticmethod(lambda *a, **k: opened.append(a[0]) or real(*a, **k)))
    monkeypatch.chdir(tmp_path)
    assert cli.main(["render", path, "--quiet", "--width", "16", "--height", "16", "--frames", "1:2"]) == 0
    assert len(opened) == 1
    assert all((tmp_path / f"{p}.000{f}.png").exists() for p in ("first", "second") for f in (1, 2))


@pytest.mark.parametrize("basis", ["bezier", "bspline", "catmullRom"])
def test_cubic_basis_curves_follow_the_curve_not_the_hull(basis):
    """One cubic curve with control points (0,0) (1,2) (2,2) (3,0) (and for bspline/catmullRom the same four): its
    tube's centre line is the basis's curve: the bezier's top is at y = 1.5 (the hull's at 2); bspline's and
    catmullRom's single segment runs between the points the basis says."""
    s = new_stage()
    c = UsdGeom.BasisCurves.Define(s, "/C")
    c.CreateTypeAttr("cubic")
    c.CreateBasisAttr(basis)
    ctrl = np.array([(0, 0, 0), (1, 2, 0), (2, 2, 0), (3, 0, 0)], float)
    c.CreatePointsAttr([Gf.Vec3f(*q) for q in ctrl])
    c.CreateCurveVertexCountsAttr([4])
    c.CreateWidthsAttr([0.02])
    c.SetWidthsInterpolation("constant")
    scene, info = load_stage(s, width=16)
    assert not any("control polygon" in w for w in info.warnings)
    top = scene.vertices[:, 1].max() - 0.01
    m = {"bezier": [[-1, 3, -3, 1], [3, -6, 3, 0], [-3, 3, 0, 0], [1, 0, 0, 0]],
         "bspline": np.array([[-1, 3, -3, 1], [3, -6, 3, 0], [-3, 0, 3, 0], [1, 4, 1, 0]]) / 6,
         "catmullRom": np.array([[-1, 3, -3, 1], [2, -5, 4, -1], [-1, 0, 1, 0], [0, 2, 0, 0]]) / 2}[basis]
    want = (np.array([1 / 8, 1 / 4, 1 / 2, 1]) @ np.asarray(m, float) @ ctrl)[1]  # y at t = 1/2 (symmetric top)
    assert abs(top - want) < 0.01, (basis, top, want)


@pytest.mark.parametrize("basis", ["bezier", "bspline", "catmullRom"])
def test_open_cubic_curves_vectorised_equal_curve_by_curve(basis):
    """The all-at-once evaluation of open curves (hair) equals the curve-by-curve one, curves of 2 to 9 points."""
    from usd_io.geometry import cubic_curves as cc

    rng = np.random.default_rng(7)
    counts = rng.integers(2, 10, 300)
    p, w = rng.random((counts.sum(), 3)), rng.random(counts.sum())
    a = cc._open_polylines(p, counts, basis, w)
    b = cc._curve_by_curve(p, counts, basis, "nonperiodic", w)
    for x, y in zip(a, b):
        np.testing.assert_allclose(x, y, atol=1e-12)


def test_cli_without_output_writes_every_render_product(tmp_path):
    """Two RenderProducts: the first renders with the settings' CamB at 100 × 100; the second has its own camera
    (CamA, 4× closer), resolution 40 × 20 and RenderVars (color, depth). Both files are written, each at its own
    size with its own AOVs, and the ball is bigger in the second (before: only the first product was written)."""
    from pxr import UsdRender

    s = _render_settings_stage(products=("first.png", "second.exr"), var_sources=("color",))
    p1 = UsdRender.Product(s.GetPrimAtPath("/Render/P1"))
    p1.CreateResolutionAttr(Gf.Vec2i(40, 20))
    p1.CreateCameraRel().SetTargets(["/CamA"])
    v = UsdRender.Var.Define(s, "/Render/P1/Depth")
    v.CreateSourceNameAttr("depth")
    p1.GetOrderedVarsRel().AddTarget(v.GetPath())
    path = str(tmp_path / "two.usda")
    s.GetRootLayer().Export(path)
    res = whitted("render", path, "--quiet", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    first, second = read_image(str(tmp_path / "first.png")), read_image(str(tmp_path / "second.exr"))
    assert first.shape[:2] == (100, 100) and second.shape[:2] == (20, 40)
    assert (tmp_path / "second.depth.exr").exists() and not (tmp_path / "first.depth.exr").exists()
    covered = [float((np.abs(im[..., :3] - im[0, 0, :3]).max(axis=-1) > 0.02).mean()) for im in (first, second)]
    assert covered[1] > 3 * covered[0], covered


def test_a_stage_of_only_volumes_says_so_in_one_line():
    """Two Volumes with OpenVDB fields and nothing else (the arnold-usd volume tests): the frame can only be the
    background, and one warning line says why (before: a line per volume plus "gave 0 triangles")."""
    from pxr import UsdVol

    s = new_stage()
    for i in range(2):
        vol = UsdVol.Volume.Define(s, f"/Vol{i}")
        field = UsdVol.OpenVDBAsset.Define(s, f"/Vol{i}/density")
        field.CreateFilePathAttr("./smoke.vdb")
        field.CreateFieldNameAttr("density")
        vol.CreateFieldRelationship("density", field.GetPath())
    _scene, info = load_stage(s, width=16, height=16)
    lines = [w for w in info.warnings if "Vol" in w or "triangles" in w]
    assert len(lines) == 1 and "only gprims are 2 Volume" in lines[0], info.warnings
    assert info.nothing_drawn is None


# ---------------------------------------------------------------- Arnold-only content met by the survey (#21)
def _image(stage, w=40, h=40):
    scene, info = load_stage(stage, width=w, height=h)
    return render(scene, RenderSettings(width=w, height=h, samples=1)).rgb, info


def _lit_columns(img):
    """Fraction of the image width where the middle row sees the (lit) quad."""
    row = img[img.shape[0] // 2]
    return float(np.mean(row.max(axis=1) > 0.05))


def test_arnold_camera_placement_is_read_when_the_usd_camera_has_no_transform():
    """arnold-usd's exports leave the USD camera at the origin and place Arnold's by primvars. Closed form: a
    2-unit quad 10 units away under a horizontal fov of 2·atan(0.5) spans (1/10)/0.5 = 20 % of the width."""
    fov = float(np.degrees(2 * np.arctan(0.5)))
    img, info = _image(st.arnold_camera_stage(position=(10, 0, 10), look_at=(10, 0, 0), fov=fov))
    assert abs(_lit_columns(img) - 0.2) <= 0.05, _lit_columns(img)
    assert any("placed by its Arnold primvars:arnold:position/look_at" in n for n in info.notes), info.notes
    # the same camera as Arnold's matrix (row vectors, translation last) and no fov: the USD lens (50 mm on
    # 20.955 mm: half-width 2.1 at 10 units, so the quad spans 1/2.1 = 48 %)
    m = (1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 10, 0, 10, 1)
    img, _ = _image(st.arnold_camera_stage(matrix=m))
    assert abs(_lit_columns(img) - 1 / 2.0955) <= 0.05, _lit_columns(img)


def test_a_usd_camera_with_a_transform_keeps_it_over_arnold_primvars():
    s = st.arnold_camera_stage(position=(10, 0, 10), look_at=(10, 0, 0))
    UsdGeom.Xformable(s.GetPrimAtPath("/Cam")).AddTranslateOp().Set(Gf.Vec3d(0, 0, 10))  # looks at nothing
    img, info = _image(s)
    assert _lit_columns(img) == 0.0 and not any("placed by its Arnold" in n for n in info.notes)


S_ = Sdf.ValueTypeNames.String
I_ = Sdf.ValueTypeNames.Int
FA, C3A, IA = Sdf.ValueTypeNames.FloatArray, Sdf.ValueTypeNames.Color3fArray, Sdf.ValueTypeNames.IntArray
RED, BLUE = (0.9, 0.1, 0.1), (0.1, 0.2, 0.8)


def test_arnold_checkerboard_as_the_surface_is_unlit_with_color1_at_the_uv_origin():
    """u, v frequency 1 on a quad whose st runs 0..1: four cells, two per period (arnold-usd's references:
    test_1590's frequency 4 on a 0..1 plane shows 8 × 8 cells, test_0055's frequency 1 shows 2 × 2); the one at
    the UV origin (lower left) and its diagonal are color2 (both references), the others color1."""
    img, info = _image(st.arnold_uv_quad("arnold:checkerboard", {
        "color1": (C3, Gf.Vec3f(*RED)), "color2": (C3, Gf.Vec3f(*BLUE)), "u_frequency": (F, 1.0),
        "v_frequency": (F, 1.0)}))
    lower_left, lower_right, upper_left, upper_right = img[30, 10], img[30, 30], img[10, 10], img[10, 30]
    for px, want in ((lower_left, BLUE), (upper_right, BLUE), (lower_right, RED), (upper_left, RED)):
        np.testing.assert_allclose(px, want, atol=0.01)
    assert not any("not supported" in w for w in info.warnings), info.warnings


@pytest.mark.parametrize("interpolation, want_at_quarter", [(1, 0.25), (0, 0.0)])
def test_arnold_ramp_rgb_along_u(interpolation, want_at_quarter):
    """Keys red at 0 and blue at 1 along u; a linear key gives red·0.75 + blue·0.25 a quarter across, a constant
    one red until the next key."""
    img, info = _image(st.arnold_uv_quad("arnold:flat", {"color": (C3, "/M/R.outputs:out")}, nodes=[
        ("/M/R", "arnold:ramp_rgb", {"type": (Sdf.ValueTypeNames.Token, "u"), "position": (FA, [0.0, 1.0]),
                                     "color": (C3A, [Gf.Vec3f(*RED), Gf.Vec3f(*BLUE)]),
                                     "interpolation": (IA, [interpolation] * 2)})]))
    x = 10  # pixel centre u = 10.5/40
    u = (x + 0.5) / 40
    k = u if want_at_quarter else 0.0
    np.testing.assert_allclose(img[20, x], (1 - k) * np.asarray(RED) + k * np.asarray(BLUE), atol=0.015)
    assert not any("not supported" in w for w in info.warnings), info.warnings


def test_arnold_color_correct_shifts_the_hue_of_a_connected_flat():
    """hue_shift −0.555 turns of yellow (1, 0.915, 0) read through another flat shader (Arnold's shaders are all
    connectable): colorsys's HSV rotation is the reference (Arnold's reference image of test_0158 shows it)."""
    import colorsys

    img, info = _image(st.arnold_uv_quad("arnold:flat", {"color": (C3, "/M/CC.outputs:out")}, nodes=[
        ("/M/CC", "arnold:color_correct", {"input": (Sdf.ValueTypeNames.Color4f, "/M/Y.outputs:out"),
                                           "hue_shift": (F, -0.555)}),
        ("/M/Y", "arnold:flat", {"color": (C3, Gf.Vec3f(1.0, 0.915, 0.0))})]))
    h, s, v = colorsys.rgb_to_hsv(1.0, 0.915, 0.0)
    want = colorsys.hsv_to_rgb((h - 0.555) % 1.0, s, v)
    np.testing.assert_allclose(img[20, 20], want, atol=0.01)
    assert img[20, 20][2] > 0.9 and img[20, 20][0] < 0.01  # blue, not the yellow input or white


def test_arnold_background_and_atmosphere_are_named_once():
    _img, info = _image(st.arnold_render_globals_stage(), w=16, h=12)
    said = [w for w in info.warnings if "Arnold background" in w or "Arnold atmosphere" in w]
    assert len(said) == 2 and "arnold:physical_sky" in said[0] and "arnold:fog" in said[1], info.warnings


def test_instancer_motion_blur_at_the_earliest_time_opens_the_shutter_at_the_first_frame():
    """No --time and a camera shutter open: the shutter opens about the stage's startTimeCode (1001), not about
    EarliestTime's −1.8e308 (which made every instance step NaN: arnold-usd test_2231/1442/1427.3 were refused).
    The instances move 1/24 unit per frame: ±0.25 frame keeps the centre cube under the centre pixel."""
    s = new_stage()
    s.SetStartTimeCode(1001)
    s.SetEndTimeCode(1010)
    st.cube(s, "/Protos/Box")
    pi = st.point_instancer(s, "/PI", ["/Protos/Box"], [(0, 0, 0), (3, 0, 0)])
    pi.GetPositionsAttr().Clear()
    pi.GetPositionsAttr().Set([Gf.Vec3f(0, 0, 0), Gf.Vec3f(3, 0, 0)], 1001.0)
    pi.CreateVelocitiesAttr().Set([Gf.Vec3f(1, 0, 0), Gf.Vec3f(1, 0, 0)], 1001.0)
    s.GetPrimAtPath("/Protos").SetSpecifier(Sdf.SpecifierOver)
    cam = add_camera(s, eye=(0, 0, 10))
    cam.CreateShutterOpenAttr(-0.25)
    cam.CreateShutterCloseAttr(0.25)
    scene, _info = load_stage(s, width=24, height=16)
    motion = scene.motion.instance_motion
    assert motion is not None and np.all(np.isfinite(motion))
    np.testing.assert_allclose(motion[0, :, 0, 3], [-0.25 / 24, 0.0, 0.25 / 24], atol=1e-6)
    ids = render(scene, RenderSettings(width=24, height=16, samples=1, aovs=("objectid",))).aovs["objectid"]
    assert ids[8, 12] >= 0


def test_a_dome_arnold_hides_from_the_camera_lights_but_is_not_seen():
    """primvars:arnold:camera = 0 on a textureless dome (Houdini's Arnold exports): the quad is lit as before,
    the background is black instead of the dome's white."""
    def frame(hidden):
        s = new_stage()
        add_camera(s, eye=(0, 0, 10))
        st.quad(s, "/Q", half=1.0)
        dome = UsdLux.DomeLight.Define(s, "/Dome")  # both stages Arnold's (the same fallback surface)
        UsdGeom.PrimvarsAPI(dome.GetPrim()).CreatePrimvar("arnold:camera", F).Set(0.0 if hidden else 1.0)
        return _image(s, w=24, h=16)[0]

    seen, unseen = frame(False), frame(True)
    np.testing.assert_allclose(seen[0, 0], (1, 1, 1), atol=1e-4)
    np.testing.assert_allclose(unseen[0, 0], (0, 0, 0), atol=1e-6)
    np.testing.assert_allclose(unseen[8, 12], seen[8, 12], rtol=0.05)  # the quad: lit the same
    assert unseen[8, 12].max() > 0.1


@pytest.mark.parametrize("interpolation", ["uniform", "vertex"])
def test_curves_read_their_st_per_curve_and_per_point(interpolation):
    """Curves' texture coordinates (arnold-usd test_0189: a ramp over hair by per-curve st): the left curve's
    u = 0.25 falls in the checkerboard's first cell (color2), the right one's 0.75 in the second (color1)."""
    img, info = _image(st.curves_with_st(interpolation), w=48, h=32)
    left, right = img[16, 24 - 8], img[16, 24 + 8]  # x = ∓1 seen through the 3.6-wide aperture at 5 mm, 10 away
    np.testing.assert_allclose(left, (0.1, 0.2, 0.8), atol=0.02)
    np.testing.assert_allclose(right, (0.9, 0.1, 0.1), atol=0.02)


def test_a_missing_mtlx_reference_is_one_warning_not_a_crash(tmp_path):
    """tinyusdz's references-multiple-001 references .mtlx files its checkout lacks: MaterialX raised
    ExceptionFileMissing (not an mx.Exception) through load_stage; now USD's composition warning names the file and
    the rest is drawn."""
    s = new_stage()
    add_camera(s, eye=(0, 0, 10))
    UsdGeom.Sphere.Define(s, "/Ball")
    s.DefinePrim("/Looks").GetReferences().AddReference("./missing_looks.mtlx", "/MaterialX")
    path = str(tmp_path / "m.usda")
    s.GetRootLayer().Export(path)
    img, info = _image(path, w=24, h=16)
    assert any("missing_looks.mtlx" in w for w in info.warnings), info.warnings
    assert np.ptp(img.reshape(-1, 3), axis=0).max() > 0.05  # the ball is drawn


def test_blender_32_to_36_without_a_dome_is_the_released_exporters_power_over_100():
    """Released Blender kept intensity = P/100 until 4.0 (its usd_writer_light.cc, with the PXR ≥ 21.11 code
    path of 3.2+); only the USD branch builds wrote nits, and they also wrote the world as a DomeLight. tinyusdz's
    geomsubset-test-001 (doc "Blender v3.2.0", a default 1000 W point of radius 0.1 written as 10) read as nits was
    a 1.8 mW lamp: a black frame."""
    scene, info = load_stage(_exporter_stage("Blender v3.2.0"), width=20, height=16)
    np.testing.assert_allclose(_first_light(info).intensity, 1000 / (4 * np.pi), rtol=1e-6)
    assert any("power / 100" in n for n in info.notes), info.notes


def test_lights_with_the_pre_2102_usdlux_attribute_names_are_read():
    """OpenUSD's testUsdLuxLightListAPI/torch.usda spells its SphereLight's inputs as UsdLux did before 21.02
    (``radius``, ``exposure``, no ``inputs:``): read as the same light written today (it was USD's dim default,
    r = 0.5, exposure 0: a dark frame)."""
    def light(legacy):
        s = new_stage()
        lt = UsdLux.SphereLight.Define(s, "/Lamp")
        prim = lt.GetPrim()
        for name, typ, v in (("intensity", F, 3.0), ("exposure", F, 2.0), ("radius", F, 0.1)):
            prim.CreateAttribute(name if legacy else f"inputs:{name}", typ).Set(v)
        add_camera(s)
        quad(s, "/Q")
        return _first_light(load_stage(s, width=8, height=8)[1])

    old, new = light(True), light(False)
    np.testing.assert_allclose(old.intensity, new.intensity, rtol=1e-6)
    np.testing.assert_allclose(new.intensity, 3.0 * 4 * np.pi * 0.01, rtol=1e-6)  # I·2^e·πr²
    assert old.radius == new.radius == pytest.approx(0.1)

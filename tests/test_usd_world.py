"""USD as real assets author it (issue #11): stages without lights, Y-up vs Z-up, skinned meshes, variants, malformed
schema values, and the scriptable CLI (batch with a bad file, --aa/--spp, --transparent, float32 AOVs, info on
area lights). Every stage is built here; nothing is downloaded."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdSkel

from tracer.scene import flatten
from tracer import RenderSettings, read_image
from tracer import render
from usd_io import load_stage
from usd_io.lights import DEFAULT_DOME, DEFAULT_HEADLIGHT_IRRADIANCE

from test_cli import whitted

GREY = 0.5


def ball_and_box(up="Y", lights=False, box=True):
    """A grey ball and a box beside it, no camera; the Z-up copy is the Y-up one turned +90° about X."""
    s = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(s, up)
    root = UsdGeom.Xform.Define(s, "/World")
    if up == "Z":
        root.AddRotateXOp().Set(90.0)
    ball = UsdGeom.Sphere.Define(s, "/World/Ball")
    ball.CreateDisplayColorAttr([(GREY, GREY, GREY)])
    if box:
        cube = UsdGeom.Cube.Define(s, "/World/Box")
        cube.AddTranslateOp().Set(Gf.Vec3d(2.5, 0.5, -1.0))
        cube.CreateDisplayColorAttr([(0.8, 0.3, 0.1)])
    if lights:
        UsdLux.DistantLight.Define(s, "/World/Sun").CreateIntensityAttr(1.0)
    return s


def test_no_lights_gets_usdviews_camera_light_and_a_dim_dome():
    """Closed form: where the view ray meets the sphere head-on, a Lambertian albedo a under the camera light
    (irradiance π, no falloff) and the dome L_a shows a·(π/π + L_a)."""
    scene, info = load_stage(ball_and_box(box=False), width=33, height=33)
    assert len(info.notes) == 1 and "no lights" in info.notes[0] and info.default_lighting
    img = render(scene, RenderSettings(width=33, height=33, samples=1))
    centre = img.rgb[16, 16]  # the framing camera looks at the ball's centre: the ray meets it head-on
    want = GREY * (DEFAULT_HEADLIGHT_IRRADIANCE / np.pi + DEFAULT_DOME)
    np.testing.assert_allclose(centre, [want] * 3, rtol=2e-3)
    dark, info2 = load_stage(ball_and_box(box=False), width=33, height=33, default_light=False)
    assert not info2.notes and not info2.default_lighting
    assert render(dark, RenderSettings(width=33, height=33, samples=1)).rgb.max() == 0.0


def test_stage_with_lights_is_lit_only_by_them():
    scene, info = load_stage(ball_and_box(lights=True), width=16, height=16)
    assert not info.notes
    assert len(scene.lights) == 1 and float(np.max(scene.ambient)) == 0.0


def test_y_up_and_z_up_copies_give_the_same_picture():
    images = []
    for up in ("Y", "Z"):
        scene, _ = load_stage(ball_and_box(up), width=48, height=36)
        # the flat ambient term: sky rays' sample patterns turn with each hit's tangent frame, so their noise
        # differs between the two copies (the dome's light is not what this test is about)
        images.append(render(scene, RenderSettings(width=48, height=36, samples=1, sky_samples=0)).rgb)
    assert images[0].max() > 0.1
    assert np.abs(images[0] - images[1]).max() < 2e-3


def test_skinned_mesh_is_posed_not_rest():
    """One joint translated by (0, 3, 0) at frame 1: a rigidly bound quad moves with it (UsdSkel's LBS with
    weight 1 is that translation), checked against the points + translation."""
    s = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(s, "Z")
    root = UsdSkel.Root.Define(s, "/Char")
    skel = UsdSkel.Skeleton.Define(s, "/Char/Skel")
    skel.CreateJointsAttr(["j"])
    skel.CreateBindTransformsAttr([Gf.Matrix4d(1)])
    skel.CreateRestTransformsAttr([Gf.Matrix4d(1)])
    anim = UsdSkel.Animation.Define(s, "/Char/Skel/Anim")
    anim.CreateJointsAttr(["j"])
    anim.CreateTranslationsAttr().Set([Gf.Vec3f(0, 3, 0)], 1.0)
    anim.CreateRotationsAttr().Set([Gf.Quatf(1, 0, 0, 0)], 1.0)
    anim.CreateScalesAttr().Set([Gf.Vec3h(1, 1, 1)], 1.0)
    UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets([anim.GetPath()])
    mesh = UsdGeom.Mesh.Define(s, "/Char/Quad")
    pts = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
    mesh.CreatePointsAttr(pts)
    mesh.CreateFaceVertexCountsAttr([4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skel.GetPath()])
    binding.CreateJointIndicesPrimvar(constant=True, elementSize=1).Set([0])
    binding.CreateJointWeightsPrimvar(constant=True, elementSize=1).Set([1.0])
    binding.CreateGeomBindTransformAttr(Gf.Matrix4d(1))
    assert root
    scene, info = load_stage(s, time=1.0, width=8, height=8, complexity="low")  # the cage (refined: test_subdivision)
    assert not any("rest pose" in w for w in info.warnings), info.warnings
    got = np.unique(np.round(scene.vertices, 5), axis=0)
    want = np.unique(np.asarray(pts, float) + [0, 3, 0], axis=0)
    np.testing.assert_allclose(got, want, atol=1e-5)


def variant_stage(path):
    s = Usd.Stage.CreateNew(str(path))
    ball = UsdGeom.Sphere.Define(s, "/Ball")
    vs = ball.GetPrim().GetVariantSets().AddVariantSet("colour")
    for name, c in (("red", (1, 0, 0)), ("blue", (0, 0, 1))):
        vs.AddVariant(name)
        vs.SetVariantSelection(name)
        with vs.GetVariantEditContext():
            ball.CreateDisplayColorAttr().Set([c])
    vs.SetVariantSelection("red")
    s.GetRootLayer().Save()
    return path


def test_variant_selection(tmp_path):
    path = variant_stage(tmp_path / "v.usda")
    red, _ = load_stage(str(path), width=8, height=8)
    blue, _ = load_stage(str(path), width=8, height=8, variants=[("/Ball", "colour", "blue")])
    colours = lambda sc: np.unique(sc.colors.reshape(-1, 3), axis=0).tolist()  # noqa: E731  (displayColor)
    assert colours(red) == [[1, 0, 0]] and colours(blue) == [[0, 0, 1]]
    out = tmp_path / "b.png"
    res = whitted("render", path, "-o", out, "--width", 16, "--variant", "/Ball:colour=blue", "--quiet")
    assert res.returncode == 0, res.stderr
    px = read_image(str(out))[8, 8]
    assert px[2] > 0.3 and px[0] == 0
    bad = whitted("render", path, "-o", out, "--variant", "/Ball:colour=green", "--quiet")
    assert bad.returncode == 2 and "no variant 'green'" in bad.stderr and "Traceback" not in bad.stderr


def test_batch_goes_on_after_a_bad_file(tmp_path):
    good = variant_stage(tmp_path / "good.usda")
    bad = tmp_path / "broken.usda"
    bad.write_text("#usda 1.0\ndef Sphere \"A\" {\n  double radius = \n}\n")
    other = tmp_path / "other.usda"
    other.write_text(good.read_text())
    res = whitted("render", good, bad, other, "-o", tmp_path / "thumbs_{stem}.png", "--width", 16, "--quiet")
    assert res.returncode == 2
    assert (tmp_path / "thumbs_good.png").exists() and (tmp_path / "thumbs_other.png").exists()
    assert not (tmp_path / "thumbs_broken.png").exists()
    errors = [l for l in res.stderr.splitlines() if l.startswith("whitted: error:")]
    assert len(errors) == 1 and "broken.usda" in errors[0] and ":3" in errors[0], res.stderr  # parser's line
    assert "Traceback" not in res.stderr
    many = whitted("render", good, other, "-o", tmp_path / "same.png", "--quiet")
    assert many.returncode == 2 and "{stem}" in many.stderr


def test_spp_alias_warns_once_and_means_aa(tmp_path):
    path = variant_stage(tmp_path / "v.usda")
    a = whitted("render", path, "-o", tmp_path / "a.exr", "--width", 12, "--aa", 3, "--quiet")
    b = whitted("render", path, "-o", tmp_path / "b.exr", "--width", 12, "--spp", 3, "--quiet")
    assert a.returncode == b.returncode == 0
    assert b.stderr.count("--spp is deprecated") == 1 and "deprecated" not in a.stderr
    assert np.array_equal(read_image(str(tmp_path / "a.exr")), read_image(str(tmp_path / "b.exr")))


def test_transparent_png_exposure_and_float32_aovs(tmp_path):
    import OpenImageIO as oiio

    path = variant_stage(tmp_path / "v.usda")
    out = tmp_path / "t.png"
    res = whitted("render", path, "-o", out, "--width", 24, "--transparent", "--aov", "depth,objectid", "--quiet")
    assert res.returncode == 0, res.stderr
    rgba = read_image(str(out))
    assert rgba.shape[2] == 4 and rgba[0, 0, 3] == 0 and rgba[12, 12, 3] == 1
    for aov in ("depth", "objectid"):
        spec = oiio.ImageInput.open(str(tmp_path / f"t.{aov}.exr")).spec()
        assert spec.format == oiio.FLOAT, aov
    lin = tmp_path / "l.exr"
    brighter = tmp_path / "l2.exr"
    whitted("render", path, "-o", lin, "--width", 24, "--quiet")
    whitted("render", path, "-o", brighter, "--width", 24, "--exposure", 1.5, "--quiet")
    a, b = read_image(str(lin))[..., :3], read_image(str(brighter))[..., :3]
    np.testing.assert_allclose(b, a * 2 ** 1.5, rtol=2e-3, atol=1e-3)  # half-float EXR rounding


def test_info_on_rect_disk_and_cylinder_lights(tmp_path):
    path = tmp_path / "l.usda"
    s = Usd.Stage.CreateNew(str(path))
    UsdGeom.Sphere.Define(s, "/Ball")
    UsdLux.RectLight.Define(s, "/Rect").CreateWidthAttr(2.0)
    UsdLux.DiskLight.Define(s, "/Disk")
    UsdLux.CylinderLight.Define(s, "/Tube")
    s.GetRootLayer().Save()
    res = whitted("info", path)
    assert res.returncode == 0, res.stderr
    assert "/Rect: area -> AreaLight(" in res.stdout and "shape=rect" in res.stdout and "shape=disk" in res.stdout
    assert "/Tube: area" in res.stdout and "shape=cylinder" in res.stdout


def test_malformed_schema_values_warn_not_traceback(tmp_path):
    """usd-wg schemaTests points_types / normals_types: points and normals authored with the wrong types."""
    path = tmp_path / "types.usda"
    path.write_text('''#usda 1.0
def Mesh "Scalar" {
    point3f points = (0, 0, 0)
    int[] faceVertexCounts = [3]
    int[] faceVertexIndices = [0, 0, 0]
}
def Mesh "Ints" {
    int[] points = [0, 1, 2, 3, 4, 5, 6, 7, 8]
    int[] faceVertexCounts = [3]
    int[] faceVertexIndices = [0, 1, 2]
}
def Mesh "Good" {
    point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
    int[] faceVertexCounts = [3]
    int[] faceVertexIndices = [0, 1, 2]
    double[] normals = [1, 2, 3, 4, 5, 6, 7, 8, 9]
    uniform token subdivisionScheme = "none"
}
''')
    res = whitted("render", path, "-o", tmp_path / "o.png", "--width", 16, "--quiet")
    assert res.returncode == 0 and "Traceback" not in res.stderr, res.stderr
    assert "/Scalar" in res.stderr and "/Ints" in res.stderr
    assert all(l.startswith(("whitted: warning:", "whitted: note:")) for l in res.stderr.splitlines()), res.stderr


def test_no_arguments_prints_usage():
    res = whitted()
    assert res.returncode == 2 and "usage: whitted" in res.stderr and "Traceback" not in res.stderr
    v = whitted("--version")
    assert v.returncode == 0 and v.stdout.startswith("whitted ")


def test_nested_point_instancers_place_every_instance_with_its_own_id():
    """Outer instancer: 2 instances at x = 0, 10; its prototype holds an inner instancer of 3 unit cubes at
    y = 0, 2, 4, shifted by the prototype's own z = 1. Expected: 6 cubes at (x, y, 1), 6 object ids."""
    s = Usd.Stage.CreateInMemory()
    outer = UsdGeom.PointInstancer.Define(s, "/Outer")
    proto = UsdGeom.Xform.Define(s, "/Outer/Protos/Group")
    proto.AddTranslateOp().Set(Gf.Vec3d(0, 0, 1))
    inner = UsdGeom.PointInstancer.Define(s, "/Outer/Protos/Group/Inner")
    cube = UsdGeom.Cube.Define(s, "/Outer/Protos/Group/Inner/Protos/Box")
    cube.CreateSizeAttr(1.0)
    inner.CreatePrototypesRel().SetTargets([cube.GetPath()])
    inner.CreateProtoIndicesAttr([0, 0, 0])
    inner.CreatePositionsAttr([(0, 0, 0), (0, 2, 0), (0, 4, 0)])
    outer.CreatePrototypesRel().SetTargets([proto.GetPath()])
    outer.CreateProtoIndicesAttr([0, 0])
    outer.CreatePositionsAttr([(0, 0, 0), (10, 0, 0)])
    scene, info = load_stage(s, width=8, height=8)
    scene = flatten(scene)  # instances as world-space triangles, to check their placement
    assert not any("nested" in w for w in info.warnings), info.warnings
    ids = scene.object_ids
    centres = sorted(tuple(np.round(scene.vertices[np.unique(scene.triangles[ids == i])].mean(axis=0), 4))
                     for i in np.unique(ids))
    want = sorted((x, y, 1.0) for x in (0.0, 10.0) for y in (0.0, 2.0, 4.0))
    assert centres == want


def test_points_render_as_spheres_and_curves_as_tubes():
    """Closed form: sphere vertices lie at |v − p| = width/2 (icosphere: the mesh is inscribed), tube vertices
    at distance width/2 from their segment's axis, within the segment's extent along it."""
    s = Usd.Stage.CreateInMemory()
    pts = UsdGeom.Points.Define(s, "/Dots")
    pts.CreatePointsAttr([(0, 0, 0), (5, 0, 0)])
    pts.CreateWidthsAttr([0.5, 1.0])
    crv = UsdGeom.BasisCurves.Define(s, "/Hair")
    crv.CreateTypeAttr("linear")
    crv.CreateCurveVertexCountsAttr([3])
    crv.CreatePointsAttr([(0, 3, 0), (0, 3, 4), (3, 3, 4)])
    crv.CreateWidthsAttr([0.2])
    scene, info = load_stage(s, width=16, height=16)
    assert not any("not supported" in w for w in info.warnings), info.warnings
    names = scene.object_names
    dots = scene.vertices[np.unique(scene.triangles[scene.object_ids == names.index("/Dots")])]
    d0 = np.linalg.norm(dots, axis=1)
    d1 = np.linalg.norm(dots - [5, 0, 0], axis=1)
    assert np.all(np.isclose(d0, 0.25, atol=1e-5) | np.isclose(d1, 0.5, atol=1e-5))
    assert np.isclose(d0, 0.25, atol=1e-5).sum() == np.isclose(d1, 0.5, atol=1e-5).sum() > 10
    hair = scene.vertices[np.unique(scene.triangles[scene.object_ids == names.index("/Hair")])]
    on_first = np.isclose(np.hypot(hair[:, 0], hair[:, 1] - 3), 0.1, atol=1e-5) & (hair[:, 2] > -1e-6)
    on_second = np.isclose(np.hypot(hair[:, 1] - 3, hair[:, 2] - 4), 0.1, atol=1e-5)
    assert np.all(on_first | on_second) and on_first.sum() >= 8 and on_second.sum() >= 8
    img = render(scene, RenderSettings(width=16, height=16, samples=1))
    assert img.rgb.max() > 0.05


def subdivided_cube_stage(up="Y", sun=False):
    """A Catmull-Clark cube (USD's default subdivisionScheme: nothing authored), grey, seen by an orthographic
    camera straight down the up axis; optionally a DistantLight shining straight down with the schema's defaults
    (intensity 50 000 over the 0.53° disk: the spec's radiance reading). The Z-up copy is the Y-up one turned +90°
    about X, camera and light included."""
    s = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(s, up)
    root = UsdGeom.Xform.Define(s, "/World")
    if up == "Z":
        root.AddRotateXOp().Set(90.0)
    mesh = UsdGeom.Mesh.Define(s, "/World/Cube")
    mesh.CreatePointsAttr([(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1),
                           (-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1)])
    mesh.CreateFaceVertexCountsAttr([4] * 6)
    mesh.CreateFaceVertexIndicesAttr([0, 3, 2, 1, 4, 5, 6, 7, 0, 1, 5, 4, 1, 2, 6, 5, 2, 3, 7, 6, 3, 0, 4, 7])
    mesh.CreateDisplayColorAttr([(GREY, GREY, GREY)])
    cam = UsdGeom.Camera.Define(s, "/World/Top")
    cam.CreateProjectionAttr(UsdGeom.Tokens.orthographic)
    cam.CreateHorizontalApertureAttr(30.0)  # tenths of a scene unit: 3 × 3 units
    cam.CreateVerticalApertureAttr(30.0)
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 5, 0))
    cam.AddRotateXOp().Set(-90.0)  # the camera's −Z looks down −Y
    if sun:
        light = UsdLux.DistantLight.Define(s, "/World/Sun")
        light.AddRotateXOp().Set(-90.0)  # the light travels along its −Z: straight down
    return s


def test_y_up_unlit_subdivided_and_spec_lit_stages_render_as_authored():
    """Issue 11's 'done' stage, written here: a Y-up stage without lights holding a Catmull-Clark cube. It is lit
    by the default light (closed form at the top centre, whose limit normal is +Y by symmetry: albedo·(E_head/π +
    L_dome)), refined (its silhouette from above is the smaller limit surface, not the 2 × 2 cage), matches its
    Z-up copy, and with the schema-default DistantLight it is lit as the spec reads it: E = 50 000 · Ω(0.53°),
    Ω = 2π(1 − cos(0.265°)) ≈ 6.7·10⁻⁵ sr, so 3.36 W/m² — not the 50 000 W/m² of reading intensity as irradiance."""
    n = 61
    st = RenderSettings(width=n, height=n, samples=1, sky_samples=0)  # the dome as the flat ambient term (its
    # sky rays' noise turns with each hit's tangent frame, so the Y-up and Z-up copies would differ by it)
    images = {}
    for up in ("Y", "Z"):
        scene, info = load_stage(subdivided_cube_stage(up), camera="/World/Top", width=n, height=n)
        assert info.default_lighting
        images[up] = render(scene, st).rgb
    centre = images["Y"][n // 2, n // 2]
    np.testing.assert_allclose(centre, [GREY * (DEFAULT_HEADLIGHT_IRRADIANCE / np.pi + DEFAULT_DOME)] * 3, rtol=5e-3)
    assert np.abs(images["Y"] - images["Z"]).max() < 2e-3
    cage, _ = load_stage(subdivided_cube_stage(), camera="/World/Top", width=n, height=n, complexity="low")
    covered = lambda img: int((np.abs(img - img[0, 0]).max(axis=2) > 1e-4).sum())  # noqa: E731  (corner: the dome)
    assert covered(images["Y"]) < 0.85 * covered(render(cage, st).rgb)  # the limit surface lies inside the cage
    lit, info = load_stage(subdivided_cube_stage(sun=True), camera="/World/Top", width=n, height=n)
    assert not info.default_lighting
    e = 50000.0 * 2 * np.pi * (1 - np.cos(np.radians(0.53) / 2))
    np.testing.assert_allclose(render(lit, st).rgb[n // 2, n // 2], [GREY * e / np.pi] * 3, rtol=1e-2)

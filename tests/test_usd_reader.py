"""usd_io: stages built here with pxr -> tracer.Scene. Cameras, meshes, gprims, transforms, instancing, materials,
purposes and composition. Each test checks numbers a broken reader would get wrong."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade, Vt

from tracer.scene import flatten
from tracer import RenderSettings
from tracer import render
from usd_io import UsdInputError, load_stage


def new_stage(up="Z"):
    s = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(s, up)
    return s


def add_camera(stage, path="/Cam", eye=(0, 0, 10), projection="perspective", h=3.6, v=2.4, focal=5.0, ho=0.0,
               vo=0.0):
    cam = UsdGeom.Camera.Define(stage, path)
    cam.CreateProjectionAttr(projection)
    cam.CreateFocalLengthAttr(focal)
    cam.CreateHorizontalApertureAttr(h)
    cam.CreateVerticalApertureAttr(v)
    cam.CreateHorizontalApertureOffsetAttr(ho)
    cam.CreateVerticalApertureOffsetAttr(vo)
    cam.AddTranslateOp().Set(Gf.Vec3d(*eye))
    return cam


def usd_pixel(cam_prim, point, width, height):
    """Pixel position of a world point computed by pxr's own frustum (the independent reference)."""
    gf = UsdGeom.Camera(cam_prim).GetCamera(Usd.TimeCode.EarliestTime())
    fr = gf.frustum
    ndc = (fr.ComputeViewMatrix() * fr.ComputeProjectionMatrix()).Transform(Gf.Vec3d(*point))
    return np.array([(ndc[0] + 1) / 2 * width, (1 - ndc[1]) / 2 * height])


def quad_mesh(stage, path, points, counts, indices, **attrs):
    m = UsdGeom.Mesh.Define(stage, path)
    m.CreatePointsAttr([Gf.Vec3f(*p) for p in points])
    m.CreateFaceVertexCountsAttr(counts)
    m.CreateFaceVertexIndicesAttr(indices)
    m.CreateSubdivisionSchemeAttr("none")
    for k, v in attrs.items():
        getattr(m, f"Create{k}Attr")(v)
    return m


# ---------------------------------------------------------------- cameras
@pytest.mark.parametrize("projection,ho,vo", [("perspective", 0.0, 0.0), ("perspective", 0.5, -0.3),
                                               ("orthographic", 0.0, 0.0), ("orthographic", 4.0, 2.0)])
def test_camera_projects_points_where_usd_does(projection, ho, vo):
    s = new_stage()
    h, v = (3.6, 2.4) if projection == "perspective" else (60.0, 40.0)  # ortho: tenths of a unit -> 6 x 4 units
    cam = add_camera(s, projection=projection, h=h, v=v, ho=ho, vo=vo)
    UsdGeom.Sphere.Define(s, "/Ball").CreateRadiusAttr(0.2)
    UsdGeom.Xformable(s.GetPrimAtPath("/Ball")).AddTranslateOp().Set(Gf.Vec3d(1.0, 0.5, 0.0))
    scene, info = load_stage(s, width=90)
    assert (info.width, info.height) == (90, 60)  # height from the aperture aspect
    pts = np.array([[1.0, 0.5, 0.0], [-2.0, 1.0, -3.0], [0.3, -1.2, 2.0]])
    got = scene.camera.project(pts, 90, 60)[:, :2]
    want = np.array([usd_pixel(cam.GetPrim(), p, 90, 60) for p in pts])
    np.testing.assert_allclose(got, want, atol=1e-3)
    # The rendered ball lands on that pixel (object-id centroid).
    img = render(scene, RenderSettings(width=90, height=60, samples=1, aovs=("objectid",), threads=1))
    ys, xs = np.nonzero(img.aovs["objectid"] == 0)
    assert len(xs) > 5
    np.testing.assert_allclose([xs.mean() + 0.5, ys.mean() + 0.5], want[0], atol=0.75)


def test_conform_expands_the_aperture_like_usdrender():
    """UsdRender's fallback policy expandAperture (Arnold's): a 3.6 × 2.4 aperture at a square image keeps its width
    and grows its height (usdrecord's MatchVertically would crop it to 2.4 × 2.4)."""
    s = new_stage()
    add_camera(s, h=3.6, v=2.4)
    UsdGeom.Sphere.Define(s, "/Ball")
    scene, info = load_stage(s, width=100, height=100)
    assert scene.camera.vertical_aperture == pytest.approx(3.6)
    assert scene.camera.horizontal_aperture == pytest.approx(3.6)
    scene, info = load_stage(s, height=50)
    assert (info.width, info.height) == (75, 50)


def test_camera_choice_and_errors():
    s = new_stage()
    add_camera(s, "/A", eye=(0, 0, 5))
    add_camera(s, "/B", eye=(0, 0, 20))
    UsdGeom.Sphere.Define(s, "/Ball")
    scene, info = load_stage(s, camera="/B", width=16)
    assert info.camera == "/B" and scene.camera.position[2] == pytest.approx(20)
    assert load_stage(s, width=16)[1].camera == "/A"
    with pytest.raises(UsdInputError, match="/Nope"):
        load_stage(s, camera="/Nope")
    with pytest.raises(UsdInputError, match="not a Camera"):
        load_stage(s, camera="/Ball")


def test_no_camera_frames_bounds_and_says_so():
    s = new_stage()
    UsdGeom.Cube.Define(s, "/Box").AddTranslateOp().Set(Gf.Vec3d(10, 20, 3))
    scene, info = load_stage(s, width=64)
    assert info.camera is None and any("no camera" in w for w in info.warnings)
    corners = np.array([[x, y, z] for x in (9, 11) for y in (19, 21) for z in (2, 4)], float)
    px = scene.camera.project(corners, info.width, info.height)
    assert np.all(px[:, 0] > 0) and np.all(px[:, 0] < info.width)
    assert np.all(px[:, 1] > 0) and np.all(px[:, 1] < info.height) and np.all(px[:, 2] > 0)


# ---------------------------------------------------------------- meshes
TWO_QUADS = dict(points=[(0, 0, 0), (1, 0, 0), (2, 0, 0), (0, 1, 0), (1, 1, 0), (2, 1, 0)],
                 counts=[4, 4], indices=[0, 1, 4, 3, 1, 2, 5, 4])


def _normals_of(interp, values, indices=None):
    s = new_stage()
    add_camera(s)
    m = quad_mesh(s, "/M", **TWO_QUADS)
    pv = UsdGeom.PrimvarsAPI(m).CreatePrimvar("normals", Sdf.ValueTypeNames.Normal3fArray, interp)
    pv.Set([Gf.Vec3f(*v) for v in values])
    if indices is not None:
        pv.SetIndices(Vt.IntArray(indices))
    scene, _ = load_stage(s, width=16)
    return scene


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_normals_every_interpolation():
    a, b = (0.0, 0.6, 0.8), (0.6, 0.0, 0.8)
    # constant
    sc = _normals_of("constant", [a])
    np.testing.assert_allclose(sc.corner_normals(), np.broadcast_to(_unit(a), (4, 3, 3)), atol=1e-6)
    # uniform: face 0 -> a, face 1 -> b; triangles 0,1 from face 0
    sc = _normals_of("uniform", [a, b])
    np.testing.assert_allclose(sc.corner_normals()[:2], np.broadcast_to(_unit(a), (2, 3, 3)), atol=1e-6)
    np.testing.assert_allclose(sc.corner_normals()[2:], np.broadcast_to(_unit(b), (2, 3, 3)), atol=1e-6)
    # vertex and varying: one per point, looked up through the triangle's point indices
    per_point = _unit(np.array([[i * 0.1, 0.2, 1.0] for i in range(6)]))
    for interp in ("vertex", "varying"):
        sc = _normals_of(interp, per_point)
        np.testing.assert_allclose(sc.corner_normals(), per_point[sc.triangles], atol=1e-6)
    # faceVarying: one per face-vertex (8), indexed primvar (2 distinct values)
    sc = _normals_of("faceVarying", [a, b], indices=[0, 1, 0, 1, 1, 1, 1, 0])
    fv = _unit(np.array([a, b, a, b, b, b, b, a]))
    # fan triangles: face 0 -> (0,1,2), (0,2,3); face 1 -> (4,5,6), (4,6,7)
    np.testing.assert_allclose(sc.corner_normals(), fv[[[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]]], atol=1e-6)


def test_wrong_size_normals_are_ignored_with_a_warning():
    s = new_stage()
    add_camera(s)
    m = quad_mesh(s, "/M", **TWO_QUADS)
    UsdGeom.PrimvarsAPI(m).CreatePrimvar("normals", Sdf.ValueTypeNames.Normal3fArray, "vertex").Set(
        [Gf.Vec3f(0, 0, 1)] * 3)
    scene, info = load_stage(s, width=16)
    assert scene.normals is None and any("normals" in w for w in info.warnings)


def test_quad_pentagon_triangle_and_left_handed():
    pts = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0),  # quad, area 1
           (2, 0, 0), (3, 0, 0), (3.5, 0.8, 0), (2.5, 1.5, 0), (1.5, 0.8, 0),  # convex pentagon
           (4, 0, 0), (5, 0, 0), (4, 1, 0)]  # triangle, area 0.5
    counts, idx = [4, 5, 3], [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11]
    penta = np.array(pts[4:9])[:, :2]
    pent_area = 0.5 * abs(np.dot(penta[:, 0], np.roll(penta[:, 1], -1)) - np.dot(penta[:, 1], np.roll(penta[:, 0], -1)))
    for orientation, sign in (("rightHanded", 1), ("leftHanded", -1)):
        s = new_stage()
        add_camera(s)
        quad_mesh(s, "/M", pts, counts, idx, Orientation=orientation)
        scene, info = load_stage(s, width=16)
        assert len(scene.triangles) == 2 + 3 + 1
        tri = scene.vertices[scene.triangles].astype(float)
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        assert np.all(np.sign(cross[:, 2]) == sign)  # right-handed counter-clockwise faces +Z; leftHanded -Z
        assert 0.5 * np.abs(cross[:, 2]).sum() == pytest.approx(1 + pent_area + 0.5)


def test_mirroring_transform_flips_winding():
    s = new_stage()
    add_camera(s)
    m = quad_mesh(s, "/M", **TWO_QUADS)
    m.AddScaleOp().Set(Gf.Vec3f(-1, 1, 1))
    scene, _ = load_stage(s, width=16)
    tri = scene.vertices[scene.triangles].astype(float)
    assert np.all(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, 2] > 0)  # still facing +Z


# ---------------------------------------------------------------- gprims
@pytest.mark.parametrize("kind,attrs,area,extent", [
    ("Sphere", dict(Radius=2.0), 4 * np.pi * 4, [2, 2, 2]),
    ("Cube", dict(Size=3.0), 6 * 9, [1.5, 1.5, 1.5]),
    ("Cylinder", dict(Radius=1.0, Height=4.0, Axis="X"), 2 * np.pi * 4 + 2 * np.pi, [2, 1, 1]),
    ("Cone", dict(Radius=1.0, Height=2.0, Axis="Y"), np.pi * np.sqrt(5) + np.pi, [1, 1, 1]),
    ("Capsule", dict(Radius=0.5, Height=2.0, Axis="Z"), 2 * np.pi * 0.5 * 2 + 4 * np.pi * 0.25, [0.5, 0.5, 1.5]),
    ("Plane", dict(Width=2.0, Length=4.0, Axis="X"), 8.0, [0, 1, 2]),
])
def test_gprims(kind, attrs, area, extent):
    s = new_stage()
    add_camera(s, eye=(0, 0, 30))
    g = getattr(UsdGeom, kind).Define(s, f"/{kind}")
    for k, v in attrs.items():
        getattr(g, f"Create{k}Attr")(v)
    g.AddTranslateOp().Set(Gf.Vec3d(1, 2, 3))
    scene, info = load_stage(s, width=16)
    lo, hi = scene.bounds
    np.testing.assert_allclose((hi - lo) / 2, extent, atol=0.01 * max(extent))
    np.testing.assert_allclose((hi + lo) / 2, [1, 2, 3], atol=0.01 * max(extent))
    tri = scene.vertices[scene.triangles].astype(float)
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert 0.5 * np.linalg.norm(cross, axis=1).sum() == pytest.approx(area, rel=0.02)
    if kind != "Plane":  # closed shapes: every face points away from the centre
        assert np.all(np.einsum("ij,ij->i", cross, tri.mean(axis=1) - [1, 2, 3]) > 0)
    if scene.normals is not None:  # shading normals agree with the faces
        assert np.all(np.einsum("ij,ij->i", scene.corner_normals().mean(axis=1), cross) > 0)


# ---------------------------------------------------------------- transforms and time
def test_nested_and_time_sampled_transforms():
    s = new_stage()
    add_camera(s, eye=(0, 0, 50))
    parent = UsdGeom.Xform.Define(s, "/P")
    op = parent.AddTranslateOp()
    op.Set(Gf.Vec3d(0, 0, 0), 1.0)
    op.Set(Gf.Vec3d(10, 0, 0), 11.0)
    parent.AddRotateZOp().Set(90.0)
    child = UsdGeom.Cube.Define(s, "/P/C")
    child.CreateSizeAttr(0.5)
    child.AddTranslateOp().Set(Gf.Vec3d(2, 0, 0))  # in the rotated frame: +Y
    for t, x in ((1.0, 0.0), (6.0, 5.0), (11.0, 10.0), (None, 0.0)):
        scene, _ = load_stage(s, time=t, width=16)
        np.testing.assert_allclose(scene.bounds.mean(axis=0), [x, 2, 0], atol=1e-5)


# ---------------------------------------------------------------- instancing
def test_point_instancer_with_invisible_ids():
    s = new_stage()
    add_camera(s, eye=(0, 0, 50))
    pi = UsdGeom.PointInstancer.Define(s, "/Inst")
    protos = UsdGeom.Scope.Define(s, "/Inst/Protos")
    box = UsdGeom.Cube.Define(s, "/Inst/Protos/Box")
    box.CreateSizeAttr(1.0)
    ball = UsdGeom.Sphere.Define(s, "/Inst/Protos/Ball")
    ball.CreateRadiusAttr(0.5)
    ball.AddTranslateOp().Set(Gf.Vec3d(0, 0, 1))  # the prototype's own xform is kept
    pi.CreatePrototypesRel().SetTargets([box.GetPath(), ball.GetPath()])
    pi.CreateProtoIndicesAttr([0, 1, 0, 0])
    pi.CreatePositionsAttr([Gf.Vec3f(0, 0, 0), Gf.Vec3f(5, 0, 0), Gf.Vec3f(-5, 0, 0), Gf.Vec3f(0, 9, 0)])
    pi.CreateScalesAttr([Gf.Vec3f(1), Gf.Vec3f(1), Gf.Vec3f(2), Gf.Vec3f(1)])
    pi.CreateInvisibleIdsAttr([3])
    UsdGeom.Xformable(pi).AddTranslateOp().Set(Gf.Vec3d(0, 0, 10))
    assert protos  # prototypes are not drawn on their own
    scene, info = load_stage(s, width=16)
    scene = flatten(scene)  # instances as world-space triangles, to check their placement
    lone = new_stage()  # the gprim reader's tessellation of one sphere, whatever it chooses
    UsdGeom.Sphere.Define(lone, "/Ball")
    n_ball = len(load_stage(lone, width=16)[0].triangles)
    assert len(scene.triangles) == 2 * 12 + n_ball and n_ball > 100
    v = scene.vertices[np.unique(scene.triangles)]
    box2 = v[v[:, 0] < -2]  # the scaled box at x = -5
    np.testing.assert_allclose([box2.min(0), box2.max(0)], [[-6, -1, 9], [-4, 1, 11]], atol=1e-5)
    ball_v = v[v[:, 0] > 3]
    np.testing.assert_allclose(ball_v.mean(0), [5, 0, 11], atol=0.05)
    assert not np.any(v[:, 1] > 5)  # the invisible instance


def test_native_instances_are_all_drawn():
    s = new_stage()
    add_camera(s, eye=(0, 0, 50))
    UsdGeom.Cube.Define(s, "/Proto/Box")
    for i in range(3):
        p = s.DefinePrim(f"/I{i}", "Xform")
        p.GetReferences().AddInternalReference("/Proto")
        p.SetInstanceable(True)
        UsdGeom.Xformable(p).AddTranslateOp().Set(Gf.Vec3d(10 * (i + 1), 0, 0))
    scene, info = load_stage(s, width=16)
    scene = flatten(scene)  # instances as world-space triangles, to check their placement
    assert len(scene.triangles) == 4 * 12
    assert scene.bounds[1][0] == pytest.approx(31)


# ---------------------------------------------------------------- materials
def preview(stage, path, **inputs):
    mat = UsdShade.Material.Define(stage, path)
    sh = UsdShade.Shader.Define(stage, path + "/S")
    sh.CreateIdAttr("UsdPreviewSurface")
    for k, v in inputs.items():
        t = Sdf.ValueTypeNames.Color3f if isinstance(v, tuple) else Sdf.ValueTypeNames.Float
        sh.CreateInput(k, t).Set(v)
    mat.CreateSurfaceOutput().ConnectToSource(sh.ConnectableAPI(), "surface")
    return mat


def test_geom_subset_and_collection_bindings():
    s = new_stage()
    add_camera(s)
    m = quad_mesh(s, "/M", **TWO_QUADS)
    red = preview(s, "/Looks/Red", diffuseColor=(1.0, 0.0, 0.0))
    blue = preview(s, "/Looks/Blue", diffuseColor=(0.0, 0.0, 1.0))
    green = preview(s, "/Looks/Green", diffuseColor=(0.0, 1.0, 0.0))
    api = UsdShade.MaterialBindingAPI.Apply(m.GetPrim())
    api.Bind(red)
    sub = api.CreateMaterialBindSubset("right", Vt.IntArray([1]))
    UsdShade.MaterialBindingAPI.Apply(sub.GetPrim()).Bind(blue)
    # A collection binding on an ancestor wins over nothing: the cube below has no direct binding.
    root = UsdGeom.Xform.Define(s, "/G")
    cube = UsdGeom.Cube.Define(s, "/G/Box")
    coll = Usd.CollectionAPI.Apply(root.GetPrim(), "greens")
    coll.CreateIncludesRel().AddTarget(cube.GetPath())
    UsdShade.MaterialBindingAPI.Apply(root.GetPrim()).Bind(coll, green, "greens")
    scene, info = load_stage(s, width=16)
    diffuse = scene.materials.diffuse[scene.material_ids]
    np.testing.assert_allclose(diffuse[:2], [[1, 0, 0]] * 2)
    np.testing.assert_allclose(diffuse[2:4], [[0, 0, 1]] * 2)
    np.testing.assert_allclose(diffuse[4:], [[0, 1, 0]] * 12)


def test_preview_surface_mapping_and_opacity_refracts():
    s = new_stage()
    add_camera(s, eye=(0, 0, 6))
    glass = preview(s, "/Looks/Glass", diffuseColor=(0.2, 0.2, 0.2), opacity=0.0, ior=1.33, roughness=0.0)
    metal = preview(s, "/Looks/Metal", diffuseColor=(0.9, 0.6, 0.2), metallic=1.0, roughness=0.5,
                    emissiveColor=(0.1, 0.2, 0.3))
    a = UsdGeom.Sphere.Define(s, "/A")
    UsdShade.MaterialBindingAPI.Apply(a.GetPrim()).Bind(glass)
    b = UsdGeom.Cube.Define(s, "/B")
    b.AddTranslateOp().Set(Gf.Vec3d(0, 0, -5))
    UsdShade.MaterialBindingAPI.Apply(b.GetPrim()).Bind(metal)
    scene, info = load_stage(s, width=24)
    m = scene.materials
    gi, mi = m.names.index("/Looks/Glass"), m.names.index("/Looks/Metal")
    assert m.transmission[gi] == 1.0 and m.ior[gi] == pytest.approx(1.33)
    assert m.metallic[mi] == 1.0 and m.roughness[mi] == pytest.approx(0.5) and m.k_m[mi] == 0.0
    assert np.allclose(m.diffuse[mi], (0.9, 0.6, 0.2))
    assert np.allclose(m.emission[mi], (0.1, 0.2, 0.3))
    assert m.specular_color[gi][0] == pytest.approx(((1.33 - 1) / 2.33) ** 2, rel=1e-5)
    img = render(scene, RenderSettings(width=24, height=16, samples=1, threads=1))
    assert img.stats["rays"]["transmission"] > 50  # the glass sphere refracts


def test_texture_and_display_color(tmp_path):
    from tracer import write_image

    tex = np.zeros((2, 2, 3), np.float32)
    tex[:, :1] = (1.0, 0.0, 0.0)
    tex[:, 1:] = (0.0, 0.0, 1.0)
    write_image(str(tmp_path / "t.exr"), tex)
    s = new_stage()
    add_camera(s)
    m = quad_mesh(s, "/M", **TWO_QUADS)
    UsdGeom.PrimvarsAPI(m).CreatePrimvar("uv", Sdf.ValueTypeNames.TexCoord2fArray, "vertex").Set(
        [Gf.Vec2f(x / 2.0, y) for x, y in ((0, 0), (1, 0), (2, 0), (0, 1), (1, 1), (2, 1))])
    mat = UsdShade.Material.Define(s, "/Looks/T")
    surf = UsdShade.Shader.Define(s, "/Looks/T/S")
    surf.CreateIdAttr("UsdPreviewSurface")
    t = UsdShade.Shader.Define(s, "/Looks/T/Tex")
    t.CreateIdAttr("UsdUVTexture")
    t.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(str(tmp_path / "t.exr"))
    reader = UsdShade.Shader.Define(s, "/Looks/T/St")
    reader.CreateIdAttr("UsdPrimvarReader_float2")
    reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("uv")
    t.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(reader.ConnectableAPI(), "result")
    surf.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(t.ConnectableAPI(), "rgb")
    mat.CreateSurfaceOutput().ConnectToSource(surf.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(m.GetPrim()).Bind(mat)
    c = UsdGeom.Cube.Define(s, "/C")
    c.CreateDisplayColorAttr([Gf.Vec3f(0.1, 0.7, 0.3)])
    c.AddTranslateOp().Set(Gf.Vec3d(0, 0, -3))
    scene, info = load_stage(s, width=16)
    assert scene.uvs is not None
    np.testing.assert_allclose(scene.corner_uvs()[0], [[0, 0], [0.5, 0], [0.5, 1]])
    # the texture is an image of the material's graph (tracer.shading.graph), read per hit
    graph = scene.materials.programs[scene.material_ids[0]].graph
    (tex,) = [n for n in graph.nodes.values() if n.type == "usd_uv_texture"]
    np.testing.assert_allclose(tex.param("image").rgba()[0, 0][:3], (1, 0, 0))
    # an unbound gprim's displayColor: per-corner vertex colour (Scene.colors) × a white base
    last = scene.material_ids[-1]
    assert any(n.type == "vertex_color" for n in scene.materials.programs[last].graph.nodes.values())
    np.testing.assert_allclose(scene.materials.diffuse[last] * scene.colors[-1], [(0.1, 0.7, 0.3)] * 3, atol=1e-6)


def test_materialx_openpbr_transmission_survives():
    s = new_stage()
    add_camera(s)
    mat = preview(s, "/Looks/G", diffuseColor=(0.2, 0.4, 0.6), ior=1.45)
    ox = UsdShade.Shader.Define(s, "/Looks/G/OpenPBR")
    ox.CreateIdAttr("ND_open_pbr_surface_surfaceshader")
    ox.CreateInput("transmission_weight", Sdf.ValueTypeNames.Float).Set(1.0)
    ox.CreateInput("specular_ior", Sdf.ValueTypeNames.Float).Set(1.45)
    ox.CreateInput("transmission_color", Sdf.ValueTypeNames.Color3f).Set((0.2, 0.4, 0.6))
    mat.CreateSurfaceOutput("mtlx").ConnectToSource(ox.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(UsdGeom.Sphere.Define(s, "/S").GetPrim()).Bind(mat)
    scene, _ = load_stage(s, width=16)
    i = scene.materials.names.index("/Looks/G")
    assert scene.materials.transmission[i] == 1.0 and scene.materials.ior[i] == pytest.approx(1.45)
    np.testing.assert_allclose(scene.materials.transmission_tint[i], (0.2, 0.4, 0.6), atol=1e-6)


# ---------------------------------------------------------------- purposes and visibility
def test_purposes_and_visibility():
    s = new_stage()
    add_camera(s)
    for name, purpose in (("D", None), ("R", "render"), ("P", "proxy"), ("G", "guide")):
        c = UsdGeom.Cube.Define(s, f"/{name}")
        if purpose:
            c.CreatePurposeAttr(purpose)
    grp = UsdGeom.Xform.Define(s, "/Hidden")
    UsdGeom.Cube.Define(s, "/Hidden/Child")
    grp.CreateVisibilityAttr("invisible")
    anim = UsdGeom.Cube.Define(s, "/Blink")
    anim.CreateVisibilityAttr().Set("inherited", 1.0)
    anim.GetVisibilityAttr().Set("invisible", 2.0)
    s.DefinePrim("/Off", "Cube").SetActive(False)
    names = lambda **kw: sorted(p for p, _ in load_stage(s, width=8, **kw)[1].meshes)  # noqa: E731
    assert names(time=1.0) == ["/Blink", "/D", "/R"]
    assert names(time=2.0) == ["/D", "/R"]
    assert names(time=1.0, purposes=("default", "proxy")) == ["/Blink", "/D", "/P"]
    with pytest.raises(UsdInputError, match="purpose"):
        load_stage(s, purposes=("beauty",))


# ---------------------------------------------------------------- composition across files
def _write_ball(path):
    s = Usd.Stage.CreateNew(str(path))
    root = UsdGeom.Xform.Define(s, "/Asset")
    UsdGeom.Sphere.Define(s, "/Asset/Ball")
    s.SetDefaultPrim(root.GetPrim())
    s.GetRootLayer().Save()


def test_references_and_payload_across_files(tmp_path):
    _write_ball(tmp_path / "ref.usda")
    _write_ball(tmp_path / "pay.usda")
    root = Usd.Stage.CreateNew(str(tmp_path / "shot.usda"))
    add_camera(root)
    a = root.DefinePrim("/A", "Xform")
    a.GetReferences().AddReference("./ref.usda")
    UsdGeom.Xformable(a).AddTranslateOp().Set(Gf.Vec3d(3, 0, 0))
    b = root.DefinePrim("/B", "Xform")
    b.GetPayloads().AddPayload("./pay.usda")
    UsdGeom.Xformable(b).AddTranslateOp().Set(Gf.Vec3d(-3, 0, 0))
    root.GetRootLayer().Save()
    scene, info = load_stage(str(tmp_path / "shot.usda"), width=16, default_light=False)
    assert sorted(p for p, _ in info.meshes) == ["/A/Ball", "/B/Ball"]
    np.testing.assert_allclose(scene.bounds, [[-4, -1, -1], [4, 1, 1]], atol=1e-3)
    assert not info.warnings


def test_missing_reference_renders_what_resolves_and_warns_once(tmp_path):
    _write_ball(tmp_path / "ref.usda")
    root = Usd.Stage.CreateNew(str(tmp_path / "shot.usda"))
    add_camera(root)
    root.DefinePrim("/Good").GetReferences().AddReference("./ref.usda")
    for name in ("Lost1", "Lost2"):
        root.DefinePrim(f"/{name}").GetReferences().AddReference("./gone.usda")
    root.GetRootLayer().Save()
    scene, info = load_stage(str(tmp_path / "shot.usda"), width=16)
    assert [p for p, _ in info.meshes] == ["/Good/Ball"]
    missing = [w for w in info.warnings if "gone.usda" in w]
    assert len(missing) == 1 and "/Lost1" in missing[0] and "/Lost2" in missing[0]


def test_malformed_values_give_a_warning_or_one_clear_error():
    """Zero/NaN sizes, zero-scale transforms and NaN light inputs are skipped with a warning (the rest renders);
    a camera or material the render cannot do without raises UsdInputError, never ZeroDivision/LinAlgError."""
    s = new_stage()
    add_camera(s)
    UsdGeom.Sphere.Define(s, "/Good")
    UsdGeom.Sphere.Define(s, "/Flat").CreateRadiusAttr(0.0)
    UsdGeom.Cube.Define(s, "/Gone").AddScaleOp().Set(Gf.Vec3f(0, 0, 0))  # the common "hide by scaling" idiom
    mesh = UsdGeom.Mesh.Define(s, "/Nan")
    mesh.CreatePointsAttr([(0, 0, 0), (1, 0, float("nan")), (0, 1, 0)])
    mesh.CreateFaceVertexCountsAttr([3])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2])
    UsdLux.DiskLight.Define(s, "/Disk").CreateRadiusAttr(float("nan"))
    UsdLux.SphereLight.Define(s, "/Hot").CreateIntensityAttr(float("inf"))
    UsdLux.DistantLight.Define(s, "/Sun")
    scene, info = load_stage(s, width=16)
    assert [p for p, _ in info.meshes] == ["/Good"]
    assert [p for p, _, _ in info.lights] == ["/Sun"]
    for path in ("/Flat", "/Gone", "/Nan", "/Disk", "/Hot"):
        assert any(w.startswith(path + ":") for w in info.warnings), (path, info.warnings)
    assert np.isfinite(scene.vertices).all()

    UsdGeom.Camera(s.GetPrimAtPath("/Cam")).CreateVerticalApertureAttr(0.0)
    with pytest.raises(UsdInputError, match="verticalAperture"):
        load_stage(s, width=16)
    UsdGeom.Camera(s.GetPrimAtPath("/Cam")).CreateVerticalApertureAttr(2.4)
    UsdGeom.Camera(s.GetPrimAtPath("/Cam")).CreateFocalLengthAttr(0.0)
    with pytest.raises(UsdInputError, match="focalLength"):
        load_stage(s, width=16)


def test_zero_scale_instances_are_dropped():
    s = new_stage()
    add_camera(s)
    inst = UsdGeom.PointInstancer.Define(s, "/Inst")
    UsdGeom.Cube.Define(s, "/Inst/Protos/Box")
    inst.CreatePrototypesRel().SetTargets(["/Inst/Protos/Box"])
    inst.CreateProtoIndicesAttr([0, 0, 0])
    inst.CreatePositionsAttr([(0, 0, 0), (3, 0, 0), (-3, 0, 0)])
    inst.CreateScalesAttr([(1, 1, 1), (0, 0, 0), (1, 1, 1)])
    scene, info = load_stage(s, width=16)
    scene = flatten(scene)  # instances as world-space triangles, to check their placement
    assert len(scene.triangles) == 2 * 12
    assert any("1 instance(s)" in w for w in info.warnings)


def test_per_instance_primvars_of_a_point_instancer_are_named_not_dropped_silently():
    """Hydra gives each instance its element of a PointInstancer's vertex/varying primvar (Arnold's user_data
    reads them too). A colour a material reads (displayColor here) is drawn per instance
    (tests/test_usd_arnold_fidelity.py); one warning names the others. A constant primvar is inherited by the
    prototypes below (no warning)."""
    s = new_stage()
    add_camera(s)
    inst = UsdGeom.PointInstancer.Define(s, "/Inst")
    UsdGeom.Cube.Define(s, "/Inst/Protos/Box")
    inst.CreatePrototypesRel().SetTargets(["/Inst/Protos/Box"])
    inst.CreateProtoIndicesAttr([0, 0])
    inst.CreatePositionsAttr([(0, 0, 0), (3, 0, 0)])
    api = UsdGeom.PrimvarsAPI(inst)
    api.CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.varying).Set(
        [(1, 0, 0), (0, 0, 1)])
    api.CreatePrimvar("weight", Sdf.ValueTypeNames.Float, UsdGeom.Tokens.constant).Set(0.5)
    api.CreatePrimvar("age", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.varying).Set([1.0, 2.0])
    _scene, info = load_stage(s, width=16)
    said = [w for w in info.warnings if "per-instance primvars" in w]
    assert len(said) == 1 and "age" in said[0], info.warnings
    assert "displayColor" not in said[0] and "weight" not in said[0], info.warnings

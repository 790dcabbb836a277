"""Shared-mesh instances (issue #12): a scene of prototypes placed by instances renders as the same scene with every
instance flattened to world-space triangles by ``SceneBuilder.add_mesh(transform=...)`` (an independent path:
``place_mesh`` on the CPU, normals by numpy's inverse transpose, winding turned under mirrors), pixel for pixel, in
colour, normal and object-id AOVs; plus closed forms for the normal matrix, emitting prototypes, session edits and
validation."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh

import tracer
from tracer import Camera, Instances, PointLight, RenderSettings, Scene, SceneBuilder, Session
from tracer import render

# Instanced vs flattened: Embree intersects an instance in object space (the ray taken there by M⁻¹), the flat copy
# in world space, so t and the hit point differ by float32 rounding. That moves a few shadow-terminator and
# silhouette samples; everything else agrees to rounding. A broken instance path (wrong normal matrix, wrong row,
# lost object id, wrong winding) changes whole surfaces: > 20 % of the pixels.
MAX_MEAN_ABS = 1e-3  # mean |Δ| over all pixels and channels (colour, normals); measured 0.7–4·10⁻⁴
MAX_DIFFERENT = 0.01  # fraction of pixels whose largest channel differs by more than PIXEL_TOL
PIXEL_TOL = 0.02
MIN_SAME_OBJECT = 0.997  # fraction of pixels with the same object id

SETTINGS = RenderSettings(width=96, height=64, samples=1, max_depth=4, aovs=("normal", "objectid"))


def rot(axis, angle):
    return trimesh.transformations.rotation_matrix(angle, axis)


def place(m, t):
    m = np.array(m, float)
    m[:3, 3] = t
    return m


#: Instance matrices: rotated, non-uniformly scaled, sheared and mirrored (negative determinant) ones.
MATRICES = [
    place(rot([0, 0, 1], 0.3), (-2.4, 0, 0.6)),
    place(rot([1, 1, 0], 0.7) @ np.diag([1.6, 0.7, 1.0, 1]), (-0.8, 0.3, 0.6)),
    place(np.diag([-1.0, 1.0, 1.0, 1]) @ rot([0, 1, 1], 0.5), (0.8, 0, 0.6)),  # mirrored
    place(np.array([[1, 0.6, 0, 0], [0, 1, 0, 0], [0, 0, 0.5, 0], [0, 0, 0, 1]]), (2.4, -0.2, 0.5)),  # shear
]


def _build(instanced: bool, matrices=MATRICES, emit=False, moved=None):
    """Floor + an instanced smooth sphere (per-vertex normals, red plastic), a flat-shaded box (glass) and, with
    ``emit``, a small emitting quad, each placed by ``matrices`` (the box and quad one row up). Object ids are
    the same in both layouts: floor 0, then the instances in order; the prototypes come last."""
    b = SceneBuilder()
    red = b.add_material("red", diffuse=(0.8, 0.2, 0.1), specular=(0.4,) * 3, roughness=0.3)
    grey = b.add_material("grey", diffuse=(0.6, 0.6, 0.6))
    glass = b.add_material("glass", diffuse=(0, 0, 0), transmission=1.0, ior=1.45)
    glow = b.add_material("glow", diffuse=(0, 0, 0), emission=(6.0, 5.0, 3.0))
    b.add_mesh([[-12, -12, 0], [12, -12, 0], [12, 12, 0], [-12, 12, 0]], [[0, 1, 2], [0, 2, 3]], material=grey,
               name="floor")
    ball = trimesh.creation.icosphere(2, 0.5)
    box = trimesh.creation.box((0.6, 0.5, 0.7))
    lamp = (np.array([[-0.3, -0.3, 0], [0.3, -0.3, 0], [0.3, 0.3, 0], [-0.3, 0.3, 0]]), [[0, 2, 1], [0, 3, 2]])
    up = np.eye(4)
    up[2, 3] = 1.5
    pieces = [(ball.vertices, ball.faces, red, ball.vertices / 0.5, matrices),
              (box.vertices, box.faces, glass, None, [up @ m for m in matrices])]
    if emit:
        pieces.append((lamp[0], lamp[1], glow, None, [place(m, m[:3, 3] + (0, 0, 2.6)) for m in matrices]))
    if moved is not None:
        pieces[0] = pieces[0][:4] + ([moved if i == 1 else m for i, m in enumerate(matrices)],)
    if instanced:
        ids = []
        for v, f, mat, n, mats in pieces:
            first = len(b.object_names)
            b.object_names.extend(f"piece{first + k}" for k in range(len(mats)))
            ids.append(np.arange(first, first + len(mats)))
        for (v, f, mat, n, mats), oid in zip(pieces, ids):
            proto = b.add_mesh(v, f, material=mat, normals=n, name="prototype")
            b.add_instances(proto, np.stack(mats), object_ids=oid)
    else:
        for v, f, mat, n, mats in pieces:
            for m in mats:
                b.add_mesh(v, f, material=mat, normals=n, transform=m, name=f"piece{len(b.object_names)}")
    b.add_light(PointLight(position=(2, -4, 6), intensity=(300.0,) * 3))
    b.camera = Camera.look_at((0, -8, 4.5), (0, 0, 1.0), up=(0, 0, 1), focal_length=35)
    b.background = np.array([0.1, 0.12, 0.2], np.float32)
    return b.build()


def assert_same_picture(a, b):
    for name, x, y in (("colour", a.rgba[..., :3], b.rgba[..., :3]), ("normal", a.aovs["normal"], b.aovs["normal"])):
        diff = np.abs(x - y)
        assert diff.mean() < MAX_MEAN_ABS, f"{name}: mean |Δ| {diff.mean():.4g}"
        assert (diff.max(axis=-1) > PIXEL_TOL).mean() < MAX_DIFFERENT, \
            f"{name}: {(diff.max(axis=-1) > PIXEL_TOL).mean():.2%} of the pixels differ"
    same = (a.aovs["objectid"] == b.aovs["objectid"]).mean()
    assert same >= MIN_SAME_OBJECT, f"object ids agree on {same:.2%} of the pixels"


@pytest.fixture(scope="module")
def pair():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return _build(True), _build(False)


def test_the_instanced_scene_keeps_one_copy_of_each_mesh(pair):
    inst, flat = pair
    assert inst.instances is not None and len(inst.instances) == 2 * len(MATRICES)
    assert len(inst.triangles) < len(flat.triangles) / 3
    np.testing.assert_allclose(inst.bounds, flat.bounds, rtol=1e-6, atol=1e-6)  # exact world bounds -> same ε
    assert inst.default_epsilon() == pytest.approx(flat.default_epsilon(), rel=1e-6)


def test_instanced_and_flattened_scenes_give_the_same_pixels(pair):
    inst, flat = pair
    a, b = render(inst, SETTINGS), render(flat, SETTINGS)
    assert_same_picture(a, b)
    ids = set(np.unique(a.aovs["objectid"]).tolist())
    assert set(range(1, 1 + 2 * len(MATRICES))) <= ids  # every instance is seen under its own object id
    assert not ids & set(range(1 + 2 * len(MATRICES), len(inst.object_names)))  # never a prototype's id


def test_a_session_on_the_instanced_scene_renders_the_same(pair):
    inst, flat = pair
    with Session(inst) as s:
        assert_same_picture(s.render(SETTINGS), render(flat, SETTINGS))


def test_normals_of_a_scaled_instance_go_through_the_inverse_transpose():
    """A flat-shaded quad in the plane x + z = 0 (normal (1, 0, 1)/√2), scaled by diag(2, 1, 1): the world plane
    is x/2 + z = 0 with normal ∝ (0.5, 0, 1); the plain matrix would give (2, 0, 1)."""
    b = SceneBuilder()
    grey = b.add_material("grey", diffuse=(0.5, 0.5, 0.5))
    v = np.array([[-1, -1, 1], [1, -1, -1], [1, 1, -1], [-1, 1, 1]], float) * 0.5
    proto = b.add_mesh(v, [[0, 1, 2], [0, 2, 3]], material=grey, normals=np.tile([1.0, 0, 1], (4, 1)))
    b.add_instances(proto, np.diag([2.0, 1.0, 1.0, 1.0]))
    b.camera = Camera.look_at((0.5, 0, 3), (0, 0, 0), up=(0, 1, 0), focal_length=50)
    img = render(b.build(), RenderSettings(width=9, height=9, samples=1, aovs=("normal",)))
    want = np.array([0.5, 0, 1]) / np.linalg.norm([0.5, 0, 1])
    np.testing.assert_allclose(img.aovs["normal"][4, 4], want, atol=1e-5)


def test_an_emitting_prototype_lights_the_scene_from_every_instance():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        inst, flat = _build(True, emit=True), _build(False, emit=True)
    st = RenderSettings(width=96, height=64, samples=1, light_samples=16, max_depth=2, aovs=("normal", "objectid"))
    a, b = render(inst, st), render(flat, st)
    assert_same_picture(a, b)
    no_lamps = render(_build(True), st)
    assert np.abs(a.rgba - no_lamps.rgba).mean() > 0.01  # the lamps do light the scene


def test_moving_an_instance_in_a_session_equals_a_fresh_render():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        inst = _build(True)
        moved = place(rot([0, 1, 0], 1.1) @ np.diag([0.6, 1.3, 1.0, 1]), (-0.5, 1.0, 1.3))
        reference = render(_build(False, moved=moved), SETTINGS)
    with Session(inst) as s:
        s.render(SETTINGS)
        s.set_transform(2, moved)  # the ball's second instance (object id 2)
        assert s.stats["last_edit"]["kind"] == "transform"
        np.testing.assert_array_equal(s.transform(2), moved)
        assert_same_picture(s.render(SETTINGS), reference)
        assert_same_picture(render(s.scene, SETTINGS), reference)  # session.scene is the edited scene


def test_adding_removing_and_reshaping_instances_in_a_session():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        inst = _build(True, matrices=MATRICES[:2])
        full = _build(False)
    with Session(inst) as s:
        ball = int(inst.instances.prototypes[0])
        ids = s.add_instances(ball, np.stack(MATRICES[2:]))
        box = int(inst.instances.prototypes[-1])
        up = np.eye(4)
        up[2, 3] = 1.5
        ids2 = s.add_instances(box, np.stack([up @ m for m in MATRICES[2:]]))
        assert len(ids) == len(ids2) == 2 and len(s.scene.instances) == 8
        img = s.render(SETTINGS)
        # the same pictures as the flat scene with all four (object ids differ: compare colour and normals)
        ref = render(full, SETTINGS)
        assert np.abs(img.rgba - ref.rgba).mean() < MAX_MEAN_ABS
        s.remove_instances(ids2)
        s.remove_object(int(ids[0]))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fewer = _build(False, matrices=MATRICES[:2])
        assert np.abs(s.render(SETTINGS).rgba - render(s.scene, SETTINGS).rgba).mean() < 1e-6
        assert len(s.scene.instances) == 5
        # a new shape for the shared ball: every instance of it changes, its BVH only is rebuilt
        cube = trimesh.creation.box((0.8, 0.8, 0.8))
        s.update_mesh(ball, cube.vertices, cube.faces, material=0)
        after = s.render(SETTINGS)
        fresh = render(s.scene, SETTINGS)
        assert np.abs(after.rgba - fresh.rgba).mean() < 1e-6
        assert np.abs(after.rgba - render(fewer, SETTINGS).rgba).mean() > 1e-3  # the balls did change


def test_bad_instances_raise_clear_errors():
    b = SceneBuilder()
    b.camera = Camera.look_at((0, -5, 0), (0, 0, 0), up=(0, 0, 1))
    proto = b.add_mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    with pytest.raises(ValueError, match=r"\(K, 4, 4\)"):
        b.add_instances(proto, np.eye(3))
    with pytest.raises(ValueError, match="no mesh"):
        b.add_instances(7, np.eye(4))
    scene = b.build()
    tri = dict(vertices=scene.vertices, triangles=scene.triangles, materials=scene.materials, camera=scene.camera)
    with pytest.raises(ValueError, match="singular"):
        Scene(**tri, instances=Instances([0], np.zeros((1, 4, 4)), [1]))
    nan = np.eye(4)[None].copy()
    nan[0, 0, 3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        Scene(**tri, instances=Instances([0], nan, [1]))
    with pytest.raises(ValueError, match="no triangles"):
        Scene(**tri, instances=Instances([3], np.eye(4)[None], [1]))
    with pytest.raises(ValueError, match="prototype's"):
        Scene(**tri, instances=Instances([0], np.eye(4)[None], [0]))
    with pytest.raises(ValueError, match="material"):
        Scene(**tri, instances=Instances([0], np.eye(4)[None], [1], materials=[5]))
    ok = Scene(**tri, instances=Instances([0], np.eye(4)[None], [1]))
    with Session(ok) as s:
        with pytest.raises(ValueError, match="prototype"):
            s.set_transform(0, np.eye(4))
        with pytest.raises(KeyError):
            s.remove_instances([5])


def test_a_scene_without_instances_is_unchanged():
    scene = _build(False)
    assert scene.instances is None and not scene.prototype_rows().any()


# ---------------------------------------------------------------------------------------------------- USD
def _usd_stages():
    """A PointInstancer of a sphere and a cube (scaled non-uniformly, one mirrored, rotated, one masked by
    invisibleIds), a native instanceable reference, and the same placements written as plain prims with the
    instancer's own matrices (from pxr's ComputeInstanceTransformsAtTime: the independent reference)."""
    from pxr import Gf, Usd, UsdGeom

    def base():
        s = Usd.Stage.CreateInMemory()
        UsdGeom.SetStageUpAxis(s, UsdGeom.Tokens.z)
        cam = UsdGeom.Camera.Define(s, "/Cam")
        cam.AddTranslateOp().Set(Gf.Vec3d(0, -9, 5))
        cam.AddRotateXOp().Set(60.0)
        cam.CreateFocalLengthAttr(14.0)
        floor = UsdGeom.Mesh.Define(s, "/Floor")
        floor.CreatePointsAttr([(-9, -9, 0), (9, -9, 0), (9, 9, 0), (-9, 9, 0)])
        floor.CreateFaceVertexCountsAttr([4])
        floor.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
        light = s.DefinePrim("/Sun", "SphereLight")
        UsdGeom.Xformable(light).AddTranslateOp().Set(Gf.Vec3d(2, -4, 7))
        light.CreateAttribute("inputs:intensity", Sdf_float()).Set(400.0)
        return s

    def protos(s, root):
        ball = UsdGeom.Sphere.Define(s, f"{root}/Ball")
        ball.CreateRadiusAttr(0.5)
        box = UsdGeom.Cube.Define(s, f"{root}/Box")
        box.CreateSizeAttr(0.7)
        box.AddTranslateOp().Set(Gf.Vec3d(0, 0, 0.2))  # a prototype's own xform is kept
        return ball, box

    inst = base()
    pi = UsdGeom.PointInstancer.Define(inst, "/Inst")
    ball, box = protos(inst, "/Inst/Protos")
    pi.CreatePrototypesRel().SetTargets([ball.GetPath(), box.GetPath()])
    pi.CreateProtoIndicesAttr([0, 1, 0, 1, 0, 1])
    pi.CreatePositionsAttr([Gf.Vec3f(x, y, 0.7) for x, y in ((-3, 0), (-1.5, 1), (0, 0), (1.5, 1), (3, 0), (0, 3))])
    pi.CreateScalesAttr([Gf.Vec3f(1), Gf.Vec3f(1.5, 0.6, 1), Gf.Vec3f(-1, 1, 1), Gf.Vec3f(1, 1, 2),
                         Gf.Vec3f(1.8, 1, 0.5), Gf.Vec3f(1)])
    pi.CreateOrientationsAttr([Gf.Quath(1, 0, 0, 0), Gf.Quath(0.92, 0, 0.38, 0), Gf.Quath(0.8, 0.6, 0, 0),
                               Gf.Quath(1, 0, 0, 0), Gf.Quath(0.7, 0, 0, 0.7), Gf.Quath(1, 0, 0, 0)])
    pi.CreateInvisibleIdsAttr([5])
    UsdGeom.Xformable(pi).AddTranslateOp().Set(Gf.Vec3d(0, 0, 0.1))
    native = UsdGeom.Xform.Define(inst, "/Lib")
    UsdGeom.Cube.Define(inst, "/Lib/Cube").CreateSizeAttr(0.5)
    native.GetPrim().SetSpecifier(Sdf_over())
    for i, x in enumerate((-2.0, 2.0)):
        p = inst.DefinePrim(f"/N{i}", "Xform")
        p.GetReferences().AddInternalReference("/Lib")
        p.SetInstanceable(True)
        UsdGeom.Xformable(p).AddTranslateOp().Set(Gf.Vec3d(x, -2, 0.25))
        UsdGeom.Xformable(p).AddScaleOp().Set(Gf.Vec3f(1, 2, 1) if i else Gf.Vec3f(-1, 1, 1))

    flat = base()
    now = Usd.TimeCode.Default()
    mats = np.asarray(pi.ComputeInstanceTransformsAtTime(now, now, UsdGeom.PointInstancer.ExcludeProtoXform),
                      np.float64).reshape(-1, 4, 4)  # the copies keep their own xform below
    world = mats @ np.asarray(UsdGeom.Xformable(pi).ComputeLocalToWorldTransform(Usd.TimeCode.Default()))
    for k, m in enumerate(world[:5]):
        x = UsdGeom.Xform.Define(flat, f"/Copy{k}")
        x.AddTransformOp().Set(Gf.Matrix4d(*m.ravel().tolist()))
        ball, box = protos(flat, f"/Copy{k}")
        flat.RemovePrim((ball if k % 2 else box).GetPath())
    for i, x in enumerate((-2.0, 2.0)):
        p = UsdGeom.Xform.Define(flat, f"/N{i}")
        p.AddTranslateOp().Set(Gf.Vec3d(x, -2, 0.25))
        p.AddScaleOp().Set(Gf.Vec3f(1, 2, 1) if i else Gf.Vec3f(-1, 1, 1))
        UsdGeom.Cube.Define(flat, f"/N{i}/Cube").CreateSizeAttr(0.5)
    return inst, flat


def Sdf_float():
    from pxr import Sdf

    return Sdf.ValueTypeNames.Float


def Sdf_over():
    from pxr import Sdf

    return Sdf.SpecifierOver


def test_a_usd_point_instancer_renders_as_its_flattened_copies():
    pytest.importorskip("pxr")
    from usd_io import load_stage

    inst_stage, flat_stage = _usd_stages()
    inst, _ = load_stage(inst_stage, width=96, height=64)
    flat, _ = load_stage(flat_stage, width=96, height=64)
    assert inst.instances is not None and len(inst.instances) == 5 + 2  # 5 visible + 2 native instances
    assert len(inst.triangles) < len(flat.triangles)
    st = RenderSettings(width=96, height=64, samples=1, max_depth=2, aovs=("normal", "objectid"))
    a, b = render(inst, st), render(flat, st)
    for name, x, y in (("colour", a.rgba[..., :3], b.rgba[..., :3]), ("normal", a.aovs["normal"], b.aovs["normal"])):
        diff = np.abs(x - y)
        assert diff.mean() < MAX_MEAN_ABS, f"{name}: mean |Δ| {diff.mean():.4g}"
        assert (diff.max(axis=-1) > PIXEL_TOL).mean() < MAX_DIFFERENT
    # object ids differ in numbering between the stages; each drawn instance is one object of its own
    ids_a = np.unique(a.aovs["objectid"])
    ids_b = np.unique(b.aovs["objectid"])
    assert len(ids_a) == len(ids_b)
    names = {inst.object_name(int(i)) for i in ids_a if i >= 0}
    assert any(n.startswith("/Inst[/Inst/Protos/Ball]") for n in names) and "/N1/Cube" in names


def _override_scene(instanced: bool):
    b = SceneBuilder()
    red = b.add_material("red", diffuse=(0.8, 0.2, 0.1))
    blue = b.add_material("blue", diffuse=(0.1, 0.2, 0.8), k_m=0.3)
    glow = b.add_material("glow", diffuse=(0, 0, 0), emission=(4.0, 4.0, 2.0))
    b.add_mesh([[-12, -12, 0], [12, -12, 0], [12, 12, 0], [-12, 12, 0]], [[0, 1, 2], [0, 2, 3]], material=red,
               name="floor")
    ball = trimesh.creation.icosphere(2, 0.5)
    mats = MATRICES[:3]
    override = [-1, blue, glow]
    if instanced:
        b.object_names.extend(["a", "b", "c"])
        proto = b.add_mesh(ball.vertices, ball.faces, material=red, normals=ball.vertices)
        b.add_instances(proto, np.stack(mats), object_ids=[1, 2, 3], materials=override)
    else:
        for m, mat, name in zip(mats, [red, blue, glow], "abc"):
            b.add_mesh(ball.vertices, ball.faces, material=mat, normals=ball.vertices, transform=m, name=name)
    b.add_light(PointLight(position=(2, -4, 6), intensity=(200.0,) * 3))
    b.camera = Camera.look_at((0, -8, 4.5), (0, 0, 1.0), up=(0, 0, 1), focal_length=35)
    return b.build()


def test_per_instance_material_overrides_shade_and_emit_as_their_own_materials():
    # Points on the glowing ball's triangles land a float's rounding apart in the two layouts, so the floor next to
    # it (1/r²) differs by sampling noise: 256 light samples keep that under the bar (16 did not, by 0.0006).
    st = RenderSettings(width=96, height=64, samples=1, light_samples=256, max_depth=2, aovs=("normal", "objectid"))
    inst, flat = _override_scene(True), _override_scene(False)
    assert inst.instances.materials.tolist() == [-1, 1, 2]
    a, b = render(inst, st), render(flat, st)
    assert_same_picture(a, b)
    # the glowing instance lights the floor: without the override's emission the floor near it is darker
    plain = _override_scene(True)
    plain.instances.materials = None
    assert np.abs(render(plain, st).rgba - a.rgba).mean() > 0.01


def test_explain_names_the_instance_that_was_hit(pair):
    inst, _flat = pair
    st = RenderSettings(width=96, height=64, samples=1, max_depth=2, aovs=("objectid",))
    ids = render(inst, st).aovs["objectid"]
    y, x = np.argwhere(ids == 2)[0]  # a pixel of the ball's second instance
    hit = tracer.explain_pixel(inst, st, int(x), int(y)).samples[0][0].hit
    assert hit.object_id == 2 and hit.object == inst.object_names[2] == "piece2"

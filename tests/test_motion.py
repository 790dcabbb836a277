"""Motion blur: the shutter's time samples, transforms interpolated as Embree interpolates them, and pictures of
moving things against closed forms."""

import numpy as np
import pytest

from tracer import Camera, RenderSettings, SceneBuilder
from tracer import render
from tracer.geometry.motion import Motion, blender_shutter, curve_table, decompose, matrix_at


def _rot_z(a):
    c, s = np.cos(a), np.sin(a)
    m = np.eye(4)
    m[:2, :2] = [[c, -s], [s, c]]
    return m


def _translate(x, y=0.0, z=0.0):
    m = np.eye(4)
    m[:3, 3] = x, y, z
    return m


def test_blender_shutter_positions():
    assert blender_shutter(0.5, "CENTER") == (-0.25, 0.25)
    assert blender_shutter(0.5, "START") == (0.0, 0.5)
    assert blender_shutter(0.5, "END") == (-0.5, 0.0)


def test_interpolation_is_embrees():
    """Our interpolation at any time equals the matrix Embree itself places the instance with
    (rtcGetGeometryTransform on the same quaternion-decomposed steps): rotation, translation, non-uniform scale,
    skew and a mirror."""
    from tracer.accel import embree

    steps = np.stack([_translate(0, 0, 0) @ _rot_z(0.0) @ np.diag([1, 2, 1, 1]),
                      _translate(1, 2, 0) @ _rot_z(1.2) @ np.diag([1.5, 1, 1, 1]),
                      _translate(3, 2, 1) @ _rot_z(2.6) @ np.diag([1, 1, -0.5, 1])])
    steps[1, 0, 1] += 0.3  # a skew
    dec = decompose(steps)
    mesh = embree.EmbreeScene()
    mesh.commit()
    inst = embree.InstanceGeometry(mesh)
    inst.set_motion(dec)
    for k in range(3):  # the steps themselves come back
        assert np.allclose(matrix_at(dec, k / 2), steps[k], atol=1e-9)
    for tau in np.linspace(0, 1, 23):
        assert np.allclose(matrix_at(dec, tau), inst.transform_at(tau), atol=2e-4), tau


def test_rotation_follows_the_arc():
    """Half way through a quarter turn the object is turned by 45° at its full size (slerp), not shrunk onto the
    chord as a linear blend of the matrices would be."""
    dec = decompose(np.stack([_rot_z(0.0), _rot_z(np.pi / 2)]))
    assert np.allclose(matrix_at(dec, 0.5), _rot_z(np.pi / 4), atol=1e-12)


def test_shutter_curve_table():
    """A flat curve leaves the times uniform; a ramp w(t) = t draws τ = √u."""
    assert np.allclose(curve_table([1, 1, 1]), np.linspace(0, 1, 256), atol=1e-6)
    table = curve_table(np.linspace(0, 1, 1001))
    u = np.linspace(0, 1, 256)
    assert np.allclose(table, np.sqrt(u), atol=2e-3)


# ------------------------------------------------------------------------------------------------ pictures
W = 32
SPAN = 4.0  # the orthographic view's width in world units (pixel = SPAN / W)


def _sliding_card(a, v, w, motion="object", samples=32, curve=None):
    """An emissive card of width ``w`` (radiance 1, nothing else in view) that slides from x = a to a + v across
    the shutter, seen head-on by an orthographic camera: a pixel's value is the fraction of the shutter × pixel
    area the card covers. ``motion``: how it moves — "object" (its transform), "instance" (an instance of a
    shared mesh), "deform" (its vertices), "camera" (the camera slides the other way), None (it stands still)."""
    b = SceneBuilder()
    glow = b.add_material("glow", diffuse=(0, 0, 0), emission=(1.0, 1.0, 1.0), specular=0.0)
    v_ = np.array([[0, -1, 0], [w, -1, 0], [w, 1, 0], [0, 1, 0]], np.float64)
    tris = np.array([[0, 1, 2], [0, 2, 3]])
    eye = _translate(0, 0, 5)
    if motion == "instance":
        proto = b.add_mesh(v_, tris, material=glow, name="card mesh")
        b.add_instances(proto, _translate(a)[None])
    else:
        oid = b.add_mesh(v_, tris, material=glow, name="card", transform=_translate(a))
    b.camera = Camera(camera_to_world=eye, projection="orthographic", horizontal_aperture=SPAN,
                      vertical_aperture=SPAN / W * 2,
                      motion=np.stack([eye, _translate(-v) @ eye]) if motion == "camera" else None)
    scene = b.build()
    steps = np.stack([np.eye(4), _translate(v)])
    if motion == "object":
        scene.motion = Motion(steps=2, object_ids=np.array([oid]), object_motion=steps[None])
    elif motion == "instance":
        scene.motion = Motion(steps=2, instance_motion=(steps @ _translate(a))[None])
    elif motion == "deform":
        moved = scene.vertices.astype(np.float64) + [v, 0, 0]
        scene.motion = Motion(steps=2, vertices=np.stack([scene.vertices, moved]), deforming=np.array([oid]))
    if curve is not None:
        scene.motion.curve = curve
    scene.validate_motion()
    return render(scene, RenderSettings(width=W, height=2, samples=samples, max_depth=0, shadows=False))


def _covered(x0, x1, a, v, w):
    """Closed form: the mean over x in [x0, x1] and t in [0, 1] of [a + v·t <= x <= a + v·t + w] (v > 0): the time
    a point x is covered is clamp((x − a)/v) − clamp((x − a − w)/v), integrated with F(z) = ∫ clamp(z) dz."""
    def F(z):
        return np.where(z < 0, 0.0, np.where(z > 1, z - 0.5, 0.5 * z * z))

    def ramp(c):
        return v * (F((x1 - c) / v) - F((x0 - c) / v))

    return (ramp(a) - ramp(a + w)) / (x1 - x0)


@pytest.mark.parametrize("how", ["object", "instance", "deform", "camera"])
def test_sliding_card_covers_pixels_as_the_closed_form(how):
    a, v, w = -1.3, 1.7, 0.9
    img = _sliding_card(a, v, w, how)
    row = img.rgba[0, :, 0]
    edges = -SPAN / 2 + SPAN / W * np.arange(W + 1)
    expect = _covered(edges[:-1], edges[1:], a, v, w)
    assert np.abs(row - expect).max() < 0.015, np.round(np.stack([row, expect]), 3)
    assert abs(row.sum() - expect.sum()) < 0.05  # the card's area over time is kept
    still = _sliding_card(a, v, w, motion=None).rgba[0, :, 0]  # the comparison can fail: a still card is far off
    assert np.abs(still - expect).max() > 0.3


def test_a_shutter_curve_weights_the_times():
    """A shutter curve open only in the last tenth of the interval (a table from tracer.geometry.motion.curve_table) shows
    the card where it is then: coverage as the closed form for a card sliding from a + 0.9·v to a + v."""
    a, v, w = -1.3, 1.7, 0.9
    weights = (np.linspace(0, 1, 1001) >= 0.9).astype(float)
    row = _sliding_card(a, v, w, curve=curve_table(weights, 1024)).rgba[0, :, 0]
    edges = -SPAN / 2 + SPAN / W * np.arange(W + 1)
    expect = _covered(edges[:-1], edges[1:], a + 0.9 * v, 0.1 * v, w)
    assert np.abs(row - expect).max() < 0.02, np.round(np.stack([row, expect]), 3)


def test_a_turning_card_is_shaded_where_it_is_at_each_rays_time():
    """A card turning by 60° about the vertical axis across the shutter: every eye sample's hit lies on the card
    as it stands at that sample's time, and its geometric and shading normals are the card's normal turned by
    60°·τ (closed form), as explain reports them."""
    from tracer import explain_pixel

    b = SceneBuilder()
    m = b.add_material("grey", diffuse=(0.5, 0.5, 0.5))
    quad = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float64)
    normals = np.tile([0.0, 0.0, 1.0], (4, 1))
    oid = b.add_mesh(quad, np.array([[0, 1, 2], [0, 2, 3]]), material=m, name="card", normals=normals)
    b.camera = Camera(camera_to_world=_translate(0, 0, 5), projection="orthographic", horizontal_aperture=0.5,
                      vertical_aperture=0.5)
    scene = b.build()

    def turn(a):
        c, s_ = np.cos(a), np.sin(a)
        r = np.eye(4)
        r[0, 0], r[0, 2], r[2, 0], r[2, 2] = c, s_, -s_, c
        return r

    angle = np.radians(60)
    scene.motion = Motion(steps=3, object_ids=np.array([oid]),
                          object_motion=np.stack([turn(0), turn(angle / 2), turn(angle)])[None])
    scene.validate_motion()
    ex = explain_pixel(scene, RenderSettings(width=4, height=4, samples=4, max_depth=0), 1, 1)
    times = []
    for rays in ex.samples:
        eye = rays[0]
        assert eye.type == "eye" and eye.hit is not None
        n = turn(angle * eye.time)[:3, 2]
        times.append(eye.time)
        assert abs(np.dot(eye.hit.point, n)) < 1e-4  # on the card's plane at that time
        assert np.allclose(eye.hit.geometric_normal, n, atol=1e-5), (eye.time, eye.hit.geometric_normal, n)
        assert np.allclose(eye.hit.shading_normal, n, atol=1e-5)
    assert np.ptp(times) > 0.8  # the samples cover the shutter


# ------------------------------------------------------------------------------------------------ USD
def _stage(tmp_path, shutter=(-0.25, 0.25), settings=None):
    """A stage at 24 time codes per second: a camera (with ``shutter``), a cube sliding +x by 1 per time code
    (time samples), a card whose points move by ``velocities`` (units per second) and a PointInstancer of two
    cubes with ``velocities`` and ``angularVelocities``."""
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdRender, Vt

    stage = Usd.Stage.CreateNew(str(tmp_path / "motion.usda"))
    stage.SetTimeCodesPerSecond(24)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    UsdGeom.XformCommonAPI(cam).SetTranslate(Gf.Vec3d(0, -10, 0))
    UsdGeom.XformCommonAPI(cam).SetRotate(Gf.Vec3f(90, 0, 0))
    if shutter is not None:
        cam.CreateShutterOpenAttr(shutter[0])
        cam.CreateShutterCloseAttr(shutter[1])
    cube = UsdGeom.Cube.Define(stage, "/Slider")
    op = cube.AddTranslateOp()
    op.Set(Gf.Vec3d(0, 0, 0), 0.0)
    op.Set(Gf.Vec3d(2, 0, 0), 2.0)
    card = UsdGeom.Mesh.Define(stage, "/Card")
    card.CreatePointsAttr().Set(Vt.Vec3fArray([(3, 0, 0), (4, 0, 0), (4, 0, 1), (3, 0, 1)]), 1.0)
    card.CreateFaceVertexCountsAttr([4])
    card.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    card.CreateSubdivisionSchemeAttr("none")
    card.CreateVelocitiesAttr().Set(Vt.Vec3fArray([(0, 0, 24.0)] * 4), 1.0)  # 1 unit per time code, upwards
    pi = UsdGeom.PointInstancer.Define(stage, "/Inst")
    UsdGeom.Cube.Define(stage, "/Inst/Protos/Box").CreateSizeAttr(0.5)
    pi.CreatePrototypesRel().SetTargets([Sdf.Path("/Inst/Protos/Box")])
    pi.CreateProtoIndicesAttr([0, 0])
    pi.CreatePositionsAttr().Set(Vt.Vec3fArray([(-3, 0, 0), (-5, 0, 0)]), 1.0)  # velocities need a sample
    pi.CreateOrientationsAttr().Set(Vt.QuathArray([Gf.Quath(1, 0, 0, 0)] * 2), 1.0)
    pi.CreateVelocitiesAttr().Set(Vt.Vec3fArray([(0, 0, 48.0), (0, 0, 0)]), 1.0)  # 2 units per time code
    pi.CreateAngularVelocitiesAttr().Set(Vt.Vec3fArray([(0, 0, 0), (0, 0, 24 * 90.0)]), 1.0)  # 90°/code about z
    if settings is not None:
        rs = UsdRender.Settings.Define(stage, "/Render/Settings")
        rs.CreateCameraRel().SetTargets([Sdf.Path("/Cam")])
        for name, value in settings.items():
            rs.GetPrim().CreateAttribute(name, Sdf.ValueTypeNames.Bool).Set(value)
        stage.SetMetadata("renderSettingsPrimPath", "/Render/Settings")
    stage.GetRootLayer().Save()
    return str(tmp_path / "motion.usda")


def _load(path):
    from usd_io.reader import load_stage

    return load_stage(path, time=1, camera="/Cam", width=32, height=32)[0]


def test_usd_motion_across_the_camera_shutter(tmp_path):
    """Shutter [-0.25, 0.25] around time code 1: the slider's steps move it by -0.25, 0, +0.25 (its time samples,
    relative to where it was placed at the frame), the card's points rise by -0.25, 0, +0.25 (velocities of 24 /s
    at 24 time codes per second), the instancer's first box rises by -0.5, 0, 0.5 and its second turns by
    -22.5°, 0, 22.5° about its position (angularVelocities)."""
    scene = _load(_stage(tmp_path))
    mo = scene.motion
    names = scene.object_names
    slider = names.index("/Slider")
    row = list(mo.object_ids).index(slider)
    assert np.allclose(mo.object_motion[row, :, :3, 3], [[-0.25, 0, 0], [0, 0, 0], [0.25, 0, 0]], atol=1e-9)
    card = names.index("/Card")
    assert card in mo.deforming.tolist()
    rows = np.unique(scene.triangles[scene.object_ids == card])
    lift = mo.vertices[:, rows, 2] - scene.vertices[rows, 2]
    assert np.allclose(lift, [[-0.25], [0.0], [0.25]], atol=1e-5)
    inst = scene.instances
    first = [i for i, o in enumerate(inst.object_ids) if names[o].endswith("[0]")][0]
    second = [i for i, o in enumerate(inst.object_ids) if names[o].endswith("[1]")][0]
    im = mo.instance_motion
    assert np.allclose(im[first, :, 2, 3], [-0.5, 0.0, 0.5], atol=1e-5)
    angles = np.degrees(np.arctan2(im[second, :, 1, 0], im[second, :, 0, 0]))
    assert np.allclose(angles, [-22.5, 0.0, 22.5], atol=1e-3)
    assert np.allclose(im[second, :, :3, 3], [[-5, 0, 0]] * 3, atol=1e-5)


@pytest.mark.parametrize("shutter,settings", [(None, None), ((0.0, 0.0), None),
                                              ((-0.25, 0.25), {"disableMotionBlur": True}),
                                              ((-0.25, 0.25), {"instantaneousShutter": True})])
def test_usd_motion_blur_is_off_where_usd_has_it_off(tmp_path, shutter, settings):
    """USD's defaults (shutter:open = shutter:close = 0) and a RenderSettings that turns motion blur off leave
    every object still."""
    scene = _load(_stage(tmp_path, shutter, settings))
    assert scene.motion is None and scene.camera.motion is None


# ------------------------------------------------------------------------------------------------ Blender
def test_blender_deformation_and_shutter(bpy_module):
    """A plane whose shape key lifts it by 1 between frames 0 and 2 (linear), at frame 1 with a 1-frame shutter:
    its vertex steps are lifted by 0.25, 0.5, 0.75 (deformation blur); with Motion Blur off (Blender's default)
    nothing moves; the START position shifts the steps to 0.5, 0.75, 1."""
    import bpy
    from bpy_extras import anim_utils

    from addon.export import scene_from_depsgraph

    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    me = bpy.data.meshes.new("Sheet")
    me.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    ob = bpy.data.objects.new("Sheet", me)
    sc.collection.objects.link(ob)
    ob.shape_key_add(name="Basis")
    up = ob.shape_key_add(name="Up")
    for v in up.data:
        v.co.z += 1.0
    for f, value in ((0, 0.0), (2, 1.0)):
        up.value = value
        up.keyframe_insert("value", frame=f)
    keys = me.shape_keys
    for fc in anim_utils.action_get_channelbag_for_slot(keys.animation_data.action,
                                                        keys.animation_data.action_slot).fcurves:
        for k in fc.keyframe_points:
            k.interpolation = "LINEAR"
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location = (0, 0, 10)
    sc.collection.objects.link(cam)
    sc.camera = cam
    sc.frame_set(1)

    def steps():
        scene, _ = scene_from_depsgraph(bpy.context.evaluated_depsgraph_get(), width=16, height=16)
        return scene, (None if scene.motion is None else scene.motion.vertices[:, :, 2].mean(axis=1))

    assert steps()[0].motion is None
    sc.render.use_motion_blur = True
    sc.render.motion_blur_shutter = 1.0
    scene, z = steps()
    assert np.allclose(z, [0.25, 0.5, 0.75], atol=1e-6) and scene.motion.deforming.tolist() == [0]
    assert np.allclose(scene.vertices[:, 2], 0.5, atol=1e-6)  # the mesh as it is at the frame
    sc.render.motion_blur_position = "START"
    assert np.allclose(steps()[1], [0.5, 0.75, 1.0], atol=1e-6)
    assert sc.frame_current == 1 and sc.frame_subframe == 0.0  # the frame is put back

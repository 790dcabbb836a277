"""Motion blur: the shutter's time samples, transforms interpolated as Embree interpolates them, and pictures of
moving things against closed forms."""

import numpy as np
import pytest

from tracer import Camera, RenderSettings, SceneBuilder, render
from tracer.motion import Motion, blender_shutter, curve_table, decompose, matrix_at


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
    from tracer import embree

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


def _sliding_card(a, v, w, motion="object", samples=32):
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

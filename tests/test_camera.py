"""Eye rays: a ray through a pixel centre passes through the world point that projects to it — projected by
pxr's ``Gf.Camera`` frustum (USD's own camera model), not by the tracer's ``Camera.project``."""

import numpy as np
import pytest
from pxr import Gf

from tracer import Camera, RenderSettings
from tracer.camera import fit_apertures
from tracer.tiles import eye_samples

W, H = 64, 48


def cameras():
    yield "perspective", Camera.look_at((1, -5, 2), (0, 0, 0.5), up=(0, 0, 1), focal_length=35.0,
                                        horizontal_aperture=36.0, vertical_aperture=27.0)
    yield "shifted", Camera.look_at((1, -5, 2), (0, 0, 0.5), up=(0, 0, 1), focal_length=50.0,
                                    horizontal_aperture=36.0, vertical_aperture=27.0,
                                    horizontal_aperture_offset=5.0, vertical_aperture_offset=-3.0)
    yield "orthographic", Camera.look_at((1, -5, 2), (0, 0, 0.5), up=(0, 0, 1), projection="orthographic",
                                         horizontal_aperture=4.0, vertical_aperture=3.0,
                                         horizontal_aperture_offset=0.5, vertical_aperture_offset=0.25)


def pxr_project(cam, pts, width, height):
    """Pixel coordinates (x right, y down) of world points through pxr's Gf.Camera with the same parameters."""
    ortho = cam.projection == "orthographic"
    k = 10.0 if ortho else 1.0  # Gf.Camera takes orthographic apertures in tenths of a world unit
    g = Gf.Camera(Gf.Matrix4d(np.asarray(cam.camera_to_world).T.tolist()),
                  Gf.Camera.Orthographic if ortho else Gf.Camera.Perspective,
                  cam.horizontal_aperture * k, cam.vertical_aperture * k,
                  cam.horizontal_aperture_offset * k, cam.vertical_aperture_offset * k, cam.focal_length)
    m = g.frustum.ComputeViewMatrix() * g.frustum.ComputeProjectionMatrix()
    out = []
    for p in np.asarray(pts, np.float64):
        c = Gf.Vec4d(*p, 1.0) * m  # row vectors in Gf
        out.append(((c[0] / c[3] + 1) / 2 * width, (1 - c[1] / c[3]) / 2 * height))
    return np.array(out)


@pytest.mark.parametrize("name,cam", list(cameras()), ids=[c[0] for c in cameras()])
def test_pixel_centre_ray_hits_the_projected_point(name, cam):
    rng = np.random.default_rng(7)
    # world points in front of the camera, spread over the view
    u, v = rng.uniform(0.02, 0.98, 200), rng.uniform(0.02, 0.98, 200)
    o, d = cam.generate_rays(u, v)
    depth = rng.uniform(1.0, 8.0, 200)
    pts = o.astype(np.float64) + d * depth[:, None]
    px = pxr_project(cam, pts, W, H)
    np.testing.assert_allclose(px[:, 0], u * W, atol=1e-4)
    np.testing.assert_allclose(px[:, 1], (1 - v) * H, atol=1e-4)
    # the renderer's own pixel-centre rays: project back onto the pixel centres
    settings = RenderSettings(samples=1, width=W, height=H)
    uu, vv, _ = eye_samples(settings, 0, 0, W, H)
    o2, d2 = cam.generate_rays(uu, vv)
    p2 = pxr_project(cam, o2 + 3.0 * d2, W, H)
    cols, rows = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    np.testing.assert_allclose(p2[:, 0], cols.ravel(), atol=2e-3)
    np.testing.assert_allclose(p2[:, 1], rows.ravel(), atol=2e-3)


def test_perspective_rays_start_at_the_eye_and_orthographic_rays_are_parallel():
    _, persp = next(iter(cameras()))
    o, d = persp.generate_rays(np.array([0.1, 0.9]), np.array([0.2, 0.7]))
    np.testing.assert_allclose(o, np.repeat(persp.position[None], 2, 0), atol=1e-6)
    assert not np.allclose(d[0], d[1])
    ortho = list(cameras())[2][1]
    o, d = ortho.generate_rays(np.array([0.1, 0.9]), np.array([0.2, 0.7]))
    np.testing.assert_allclose(d[0], d[1], atol=1e-7)
    assert np.linalg.norm(o[0] - o[1]) > 1.0


def test_lens_shift_moves_the_image_not_the_view_direction():
    base = Camera(focal_length=50, horizontal_aperture=36, vertical_aperture=24)
    shifted = Camera(focal_length=50, horizontal_aperture=36, vertical_aperture=24, horizontal_aperture_offset=3.6)
    # Closed form: an offset of 3.6 on a 36-wide aperture moves the image by 1/10 of the frame, so the view axis
    # (0, 0, -1) is seen at u = 0.4 instead of 0.5, and the eye stays where it was.
    for cam, u in ((base, 0.5), (shifted, 0.4)):
        o, d = cam.generate_rays(np.array([u]), np.array([0.5]))
        np.testing.assert_allclose(d[0], [0, 0, -1], atol=1e-7)
        np.testing.assert_allclose(o[0], [0, 0, 0], atol=1e-7)


def test_stratified_samples_cover_each_pixel():
    s = RenderSettings(width=4, height=3, samples=3)
    u, v, keys = eye_samples(s, 0, 0, 4, 3)
    assert len(u) == 4 * 3 * 9 and len(np.unique(keys)) == len(keys)
    col = np.floor(u * 4).reshape(-1, 9)
    row = np.floor((1 - v) * 3).reshape(-1, 9)
    assert np.all(col == col[:, :1]) and np.all(row == row[:, :1])  # all 9 samples stay in their pixel
    # one sample per stratum: the 3×3 sub-cells of each pixel are all used
    sub = (np.floor(u * 12) % 3 + 3 * (np.floor((1 - v) * 9) % 3)).reshape(-1, 9)
    assert all(len(set(r)) == 9 for r in sub)


@pytest.mark.parametrize("policy,expected", [("expand", (36.0, 36.0)), ("crop", (24.0, 24.0)),
                                             ("horizontal", (36.0, 36.0)), ("vertical", (24.0, 24.0)),
                                             ("none", (36.0, 24.0))])
def test_fit_apertures(policy, expected):
    assert fit_apertures(36.0, 24.0, 100, 100, policy) == pytest.approx(expected)


def test_fit_larger_keeps_the_long_image_side_as_blenders_sensor_fit_auto():
    """Blender's Auto sensor fit: the sensor width spans the image's longer side (the add-on's cameras use it)."""
    assert fit_apertures(36.0, 36.0, 200, 100, "larger") == pytest.approx((36.0, 18.0))
    assert fit_apertures(36.0, 36.0, 100, 200, "larger") == pytest.approx((18.0, 36.0))


def test_camera_rejects_bad_values():
    with pytest.raises(ValueError, match="focal_length"):
        Camera(focal_length=0)
    with pytest.raises(ValueError, match="projection"):
        Camera(projection="fisheye")
    with pytest.raises(ValueError, match="4x4"):
        Camera(camera_to_world=np.full((4, 4), np.nan))


@pytest.mark.parametrize("name,cam", list(cameras()), ids=[c[0] for c in cameras()])
def test_render_tile_rays_are_the_public_eye_rays(name, cam):
    """The renderer's fused per-tile kernel (samples + eye rays) gives exactly what eye_samples + generate_rays give,
    for a tile away from the origin, with stratified jitter and a near plane."""
    from tracer import PointLight, SceneBuilder
    from tracer.tiles import eye_rays

    cam.near = 0.25
    b = SceneBuilder()
    b.add_mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float), np.array([[0, 1, 2]]))
    b.add_light(PointLight(position=(0, 0, 5), intensity=(1, 1, 1)))
    b.camera = cam
    scene = b.build()
    s = RenderSettings(width=W, height=H, samples=2, seed=3)
    o, d, keys = eye_rays(scene, s, 16, 8, 40, 30)
    u, v, keys2 = eye_samples(s, 16, 8, 40, 30)
    o2, d2 = cam.generate_rays(u, v)
    np.testing.assert_array_equal(keys.astype(np.uint32), keys2)
    np.testing.assert_array_equal(o, o2)
    np.testing.assert_array_equal(d, d2)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-6)
    if cam.projection == "perspective":  # rays start on the near plane: camera-space z = −near
        pc = (o.astype(np.float64) - cam.position) @ cam.camera_to_world[:3, :3]
        np.testing.assert_allclose(pc[:, 2], -0.25, atol=1e-5)

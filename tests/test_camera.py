"""Eye rays: a ray through a pixel centre passes through the world point that projects to it — projected by
pxr's ``Gf.Camera`` frustum (USD's own camera model), not by the tracer's ``Camera.project``."""

import numpy as np
import pytest
from pxr import Gf

from tracer import Camera, RenderSettings
from tracer.camera import fit_apertures
from tracer.integrator.tiles import eye_samples

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
    from tracer.integrator.tiles import eye_rays

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


# ---------------------------------------------------------------------------------------------- depth of field
def _lens_camera(**kw):
    from tracer import Camera

    args = dict(focal_length=50.0, horizontal_aperture=36.0, vertical_aperture=24.0, lens_radius=0.05,
                focus_distance=10.0)
    args.update(kw)
    return Camera.look_at((0, -10, 0), (0, 0, 0), up=(0, 0, 1), **args)


def test_thin_lens_rays_meet_the_pinhole_ray_on_the_plane_of_focus():
    """Every lens sample of a film point reaches the plane of focus (10 units ahead, along the view axis) where the
    pinhole ray through that film point does, and starts on the aperture disk around the eye (radius R)."""
    cam = _lens_camera()
    rng = np.random.default_rng(3)
    a, b = rng.random(4000), rng.random(4000)
    u, v = np.full(4000, 0.3), np.full(4000, 0.65)
    o, d = cam.generate_rays(u, v, lens=(a, b))
    po, pd = cam.generate_rays(u[:1], v[:1])
    focus = po[0] + pd[0] * (10.0 / pd[0, 1])  # the pinhole ray at y = 0
    hit = o + d * ((0.0 - o[:, 1]) / d[:, 1])[:, None]
    np.testing.assert_allclose(hit, np.broadcast_to(focus, hit.shape), atol=2e-4)
    r = np.hypot(o[:, 0], o[:, 2])  # origins on the lens (the plane y = -10 through the eye)
    np.testing.assert_allclose(o[:, 1], -10.0, atol=1e-5)
    assert r.max() <= 0.05 + 1e-6
    assert np.mean(r**2) == pytest.approx(0.05**2 / 2, rel=0.05)  # uniform in area: E[r²] = R²/2


def test_polygonal_aperture_is_the_regular_polygon_cycles_draws():
    """Blades: a regular polygon, corners on the unit circle at rotation + (2k ± 1)·π/N (Cycles'
    regular_polygon_sample); every point inside it, the corners reached, uniform in area (mean at the centre)."""
    from tracer.camera import aperture_point

    n, rot = 6, 0.3
    rng = np.random.default_rng(5)
    pts = np.array([aperture_point(n, rot, 1.0, x, y) for x, y in rng.random((6000, 2))])
    corners = rot + (2 * np.arange(n) + 1) * np.pi / n
    apothem = np.cos(np.pi / n)
    for k in range(n):  # inside every edge: the edge between corners k and k+1 has its normal at rot + 2(k+1)π/N
        normal_angle = rot + (2 * k + 2) * np.pi / n
        proj = pts @ np.array([np.cos(normal_angle), np.sin(normal_angle)])
        assert proj.max() <= apothem + 1e-9
        assert proj.max() > apothem - 0.02
    r = np.hypot(pts[:, 0], pts[:, 1])
    ang = np.arctan2(pts[:, 1], pts[:, 0])
    near_corner = r > 0.97
    assert np.all(np.min(np.abs(np.angle(np.exp(1j * (ang[near_corner, None] - corners[None, :])))), axis=1) < 0.05)
    np.testing.assert_allclose(pts.mean(axis=0), 0.0, atol=0.02)
    squeezed = np.array([aperture_point(0, 0.0, 0.5, x, y) for x, y in rng.random((2000, 2))])
    assert np.abs(squeezed[:, 0]).max() == pytest.approx(0.5, abs=0.02)  # anamorphic: x / ratio (ratio 2)
    assert np.abs(squeezed[:, 1]).max() == pytest.approx(1.0, abs=0.02)


def test_lens_radius_and_camera_validation():
    from tracer import lens_radius

    assert lens_radius(0.05, 2.0) == pytest.approx(0.0125)  # 50 mm at f/2: a 25 mm aperture
    assert lens_radius(0.05, 0.0) == 0.0  # USD's fStop 0: a pinhole
    with pytest.raises(ValueError, match="focus_distance"):
        _lens_camera(focus_distance=0.0)
    with pytest.raises(ValueError, match="lens_radius"):
        _lens_camera(lens_radius=-1.0)
    assert _lens_camera(aperture_blades=2).aperture_blades == 0  # fewer than 3 blades: round, as Cycles


def test_defocus_blur_of_an_edge_has_the_thin_lens_width():
    """An out-of-focus edge (a white half-plane 5 units away, focus at 10) is smeared over the circle of confusion:
    on the plane of focus the lens disk of radius R maps to a disk of radius R·|1 − F/z|, on the film (× f/F) c =
    2R·|1 − F/z|·f/F wide. The rendered ramp's extent across the edge, in pixels, must match it (±1.5 px: pixel
    footprint and sampling)."""
    import tracer
    from tracer import Camera, RenderSettings, SceneBuilder

    R, F, z, f, ap, W = 0.1, 10.0, 5.0, 50.0, 36.0, 200
    b = SceneBuilder()
    white = b.add_material("white", diffuse=(0, 0, 0), emission=(1.0, 1.0, 1.0))
    b.add_mesh(np.array([[0.0, z - 10, -50], [50, z - 10, -50], [50, z - 10, 50], [0.0, z - 10, 50]]),
               np.array([[0, 1, 2], [0, 2, 3]]), material=white, name="half")
    b.camera = Camera.look_at((0, -10, 0), (0, 0, 0), up=(0, 0, 1), focal_length=f, horizontal_aperture=ap,
                              vertical_aperture=ap / 4, lens_radius=R, focus_distance=F)
    img = tracer.render(b.build(), RenderSettings(width=W, height=W // 4, samples=16, max_depth=0, threads=2))
    row = img.rgba[W // 8, :, 0]
    blurred = np.flatnonzero((row > 0.02) & (row < 0.98))
    c_px = 2 * R * abs(1 - F / z) * f / F / ap * W
    assert blurred.size == pytest.approx(c_px, abs=1.5), (blurred.size, c_px)
    pinhole = tracer.render(_with_pinhole(b), RenderSettings(
        width=W, height=W // 4, samples=16, max_depth=0, threads=2)).rgba[W // 8, :, 0]
    assert np.count_nonzero((pinhole > 0.02) & (pinhole < 0.98)) <= 1  # the pinhole's edge is one pixel


def _with_pinhole(builder):
    import dataclasses

    builder.camera = dataclasses.replace(builder.camera, lens_radius=0.0)
    return builder.build()

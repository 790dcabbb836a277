"""Whole images from the tracer: each test checks something a broken ray type would get wrong."""

import numpy as np
import pytest

from tests.tracer_scenes import lit_sphere_on_floor, quad, sphere
from tracer import Camera, DistantLight, PointLight, RenderSettings, SceneBuilder
from tracer import render

W, H = 64, 48


def lum(rgb):
    return rgb @ np.array([0.2126, 0.7152, 0.0722], np.float32)


def test_lit_diffuse_sphere_is_brighter_facing_the_light():
    b = SceneBuilder()
    grey = b.add_material("grey", diffuse=(0.8, 0.8, 0.8))
    sphere(b, (0, 0, 0), 1.0, grey, "ball")
    b.add_light(PointLight(position=(10.0, 0.0, 0.0), intensity=(400.0,) * 3))  # light on +x
    b.camera = Camera.look_at((0, -6, 0), (0, 0, 0), up=(0, 0, 1), focal_length=50.0,
                              horizontal_aperture=36.0, vertical_aperture=27.0)
    scene = b.build()
    img = render(scene, RenderSettings(samples=1, width=W, height=H))
    right = scene.camera.project([[0.7, -0.7, 0.0]], W, H)[0].astype(int)
    left = scene.camera.project([[-0.7, -0.7, 0.0]], W, H)[0].astype(int)
    l_right = lum(img.rgb[right[1], right[0]])
    l_left = lum(img.rgb[left[1], left[0]])
    assert l_right > 0.1 and l_left == 0.0  # the far side gets no direct light and there is no ambient


def test_point_light_lambert_matches_the_radiometric_formula():
    # A diffuse plane lit from straight above: L = a/π · I / r² (DESIGN.md: Cycles' point light, radius 0).
    b = SceneBuilder()
    a = 0.5
    m = b.add_material("plane", diffuse=(a, a, a))
    quad(b, (0, 0, 0), 100.0, m, "plane")
    intensity, r = 80.0, 4.0
    b.add_light(PointLight(position=(0, 0, r), intensity=(intensity,) * 3))
    b.camera = Camera.look_at((0, 0, 2.0), (0, 0, 0), up=(0, 1, 0), focal_length=50.0,
                              horizontal_aperture=2.0, vertical_aperture=2.0)
    img = render(b.build(), RenderSettings(samples=1, width=9, height=9))
    centre = img.rgb[4, 4]
    expected = a / np.pi * intensity / r**2
    np.testing.assert_allclose(centre, expected, rtol=2e-3)


def test_sun_lambert_matches_the_radiometric_formula():
    b = SceneBuilder()
    m = b.add_material("plane", diffuse=(0.5, 0.25, 1.0))
    quad(b, (0, 0, 0), 100.0, m, "plane")
    theta = np.radians(30.0)
    b.add_light(DistantLight(direction=(np.sin(theta), 0, -np.cos(theta)), irradiance=(3.0, 3.0, 3.0)))
    b.camera = Camera.look_at((0, 0, 2.0), (0, 0, 0), up=(0, 1, 0))
    img = render(b.build(), RenderSettings(samples=1, width=8, height=8))
    np.testing.assert_allclose(img.rgb[4, 4], np.array([0.5, 0.25, 1.0]) * 3.0 * np.cos(theta) / np.pi, rtol=1e-4)


def test_shadow_lands_where_the_geometry_says():
    b = lit_sphere_on_floor(light_pos=(-6.0, 0.0, 4.0))
    scene = b.build()
    lit = render(scene, RenderSettings(samples=1, width=W, height=H, shadows=False))
    shad = render(scene, RenderSettings(samples=1, width=W, height=H))
    # Where the ray from the light through the ball's centre meets the floor (z = 0):
    light, centre = np.array([-6.0, 0.0, 4.0]), np.array([0.0, 0.0, 1.0])
    floor_pt = light + (centre - light) * (light[2] / (light[2] - centre[2]))
    x, y, _ = scene.camera.project([floor_pt], W, H)[0]
    x, y = int(x), int(y)
    assert lum(shad.rgb[y, x]) < 0.02 * lum(lit.rgb[y, x])
    # The shadowed pixels lie on the far side of the ball from the light (+x on the floor, right in the image).
    darker = lum(shad.rgb) < lum(lit.rgb) - 1e-6
    ys, xs = np.nonzero(darker)
    assert darker[y, x]
    ball_px = scene.camera.project([[0, 0, 0]], W, H)[0]
    assert np.mean(xs) > ball_px[0] + 3


def test_mirror_shows_the_reflected_object_on_the_correct_side():
    b = SceneBuilder()
    mirror = b.add_material("mirror", diffuse=(0, 0, 0), k_m=1.0)
    red = b.add_material("red", diffuse=(0, 0, 0), emission=(1.0, 0.0, 0.0))
    quad(b, (0, 0, 0), 40.0, mirror, "mirror_floor")
    sphere(b, (1.5, 0, 1.5), 0.5, red, "red_ball")
    b.camera = Camera.look_at((0, -8, 1.0), (0, 0, 0.3), up=(0, 0, 1), focal_length=35.0,
                              horizontal_aperture=36.0, vertical_aperture=27.0)
    scene = b.build()
    img = render(scene, RenderSettings(samples=1, width=W, height=H))
    # The mirror image of the ball is the ball reflected through z = 0.
    x, y, _ = scene.camera.project([[1.5, 0, -1.5]], W, H)[0].astype(int)
    xb, yb, _ = scene.camera.project([[1.5, 0, 1.5]], W, H)[0].astype(int)
    assert img.rgb[y, x, 0] > 0.9 and img.rgb[y, x, 1] < 0.05
    assert y > yb and x == pytest.approx(xb, abs=2)  # below the ball, same column
    # The other side (x = −1.5) shows no red.
    xo, yo, _ = scene.camera.project([[-1.5, 0, -1.5]], W, H)[0].astype(int)
    assert img.rgb[yo, xo, 0] < 0.05


def test_glass_sphere_inverts_what_is_behind_it():
    b = SceneBuilder()
    glass = b.add_material("glass", diffuse=(0, 0, 0), transmission=1.0, ior=1.5)
    top = b.add_material("top_red", diffuse=(0, 0, 0), emission=(1.0, 0.0, 0.0))
    bottom = b.add_material("bottom_blue", diffuse=(0, 0, 0), emission=(0.0, 0.0, 1.0))
    # An emissive backdrop at y = 6 facing −y: red above z = 0, blue below.
    v = np.array([[-20, 6, 0], [20, 6, 0], [20, 6, 20], [-20, 6, 20]], float)
    b.add_mesh(v, [[0, 2, 1], [0, 3, 2]], material=top, name="top")
    b.add_mesh(v - [0, 0, 20], [[0, 2, 1], [0, 3, 2]], material=bottom, name="bottom")
    sphere(b, (0, 0, 0), 1.0, glass, "glass_ball", count=64)
    b.camera = Camera.look_at((0, -6, 0), (0, 0, 0), up=(0, 0, 1), focal_length=50.0,
                              horizontal_aperture=36.0, vertical_aperture=27.0)
    scene = b.build()
    img = render(scene, RenderSettings(samples=1, width=W, height=H))
    cx, cy, _ = scene.camera.project([[0, 0, 0]], W, H)[0]
    inside_up = img.rgb[int(cy) - 4, int(cx)]
    inside_down = img.rgb[int(cy) + 4, int(cx)]
    outside_up = img.rgb[2, 2]
    outside_down = img.rgb[H - 3, 2]
    assert outside_up[0] > 0.9 and outside_down[2] > 0.9  # backdrop seen directly: red above, blue below
    assert inside_up[2] > 0.5 and inside_up[0] < 0.1  # through the glass: inverted, blue above
    assert inside_down[0] > 0.5 and inside_down[2] < 0.1  # and red below
    assert img.stats["rays"]["transmission"] > 0


def glass_block_scene(ior):
    b = SceneBuilder()
    glass = b.add_material("glass", diffuse=(0, 0, 0), transmission=1.0, ior=ior)
    import trimesh

    box = trimesh.creation.box(extents=(2, 2, 2))
    b.add_mesh(box.vertices, box.faces, material=glass, name="block")
    b.background = np.array([0.2, 0.4, 0.8], np.float32)
    b.camera = Camera.look_at((3.5, -4.0, 3.0), (0, 0, 0), up=(0, 0, 1), focal_length=35.0,
                              horizontal_aperture=36.0, vertical_aperture=27.0)
    return b.build()


def test_total_internal_reflection_happens_in_a_glass_block_and_not_without_refraction():
    img = render(glass_block_scene(1.5), RenderSettings(samples=1, width=W, height=H, max_depth=6))
    assert img.stats["rays"]["tir"] > 50
    matched = render(glass_block_scene(1.0), RenderSettings(samples=1, width=W, height=H, max_depth=6))
    assert matched.stats["rays"]["tir"] == 0  # η_i = η_r: the square root's argument is cos²θ_i ≥ 0
    # index 1 glass is invisible: every pixel shows the background (Fresnel reflectance is 0 at matched indices)
    np.testing.assert_allclose(matched.rgb, np.broadcast_to([0.2, 0.4, 0.8], matched.rgb.shape), atol=1e-5)


def mirror_and_ball():
    b = SceneBuilder()
    mirror = b.add_material("mirror", diffuse=(0.0, 0.0, 0.0), k_m=1.0)
    matte = b.add_material("matte", diffuse=(0.7, 0.3, 0.1))
    sphere(b, (-1.2, 0, 0), 1.0, mirror, "mirror_ball")
    sphere(b, (1.2, 0, 0), 1.0, matte, "matte_ball")
    b.add_light(PointLight(position=(0, -5, 5), intensity=(200.0,) * 3))
    b.background = np.array([0.1, 0.2, 0.3], np.float32)
    b.ambient = np.array([0.05, 0.05, 0.05], np.float32)  # so that whatever a mirror reflects is not black
    b.camera = Camera.look_at((0, -7, 1), (0, 0, 0), up=(0, 0, 1), focal_length=35.0,
                              horizontal_aperture=36.0, vertical_aperture=27.0)
    return b


def test_max_depth_0_and_1_differ_exactly_on_mirror_pixels():
    scene = mirror_and_ball().build()
    s = RenderSettings(samples=1, width=W, height=H, aovs=("objectid",))
    d0 = render(scene, s.with_(max_depth=0))
    d1 = render(scene, s.with_(max_depth=1))
    differs = np.any(np.abs(d0.rgb - d1.rgb) > 1e-6, axis=-1)
    mirror_id = scene.object_names.index("mirror_ball")
    on_mirror = d0.aovs["objectid"] == mirror_id
    assert on_mirror.sum() > 100
    np.testing.assert_array_equal(differs, on_mirror)
    assert d0.stats["rays"]["reflection"] == 0 and d1.stats["rays"]["reflection"] == on_mirror.sum()


@pytest.mark.parametrize("k_m", [0.0, 0.5])
def test_reflection_rays_only_where_k_m_is_positive(k_m):
    b = mirror_and_ball()
    b.materials[0]["k_m"] = k_m
    scene = b.build()
    img = render(scene, RenderSettings(samples=1, width=W, height=H, aovs=("objectid",), max_depth=1))
    mirror_px = int((img.aovs["objectid"] == 0).sum())
    assert img.stats["rays"]["reflection"] == (0 if k_m == 0 else mirror_px)
    assert img.stats["rays"]["eye"] == W * H


def test_same_pixels_for_any_thread_count_and_tile_size():
    scene = lit_sphere_on_floor().build()
    s = RenderSettings(width=W, height=H, samples=2, light_samples=4)
    a = render(scene, s.with_(threads=1, tile_size=16))
    b = render(scene, s.with_(threads=2, tile_size=40))
    np.testing.assert_array_equal(a.rgba, b.rgba)


def test_a_tile_traced_in_batches_of_eye_samples_gives_the_same_pixels(monkeypatch):
    """tracer.integrator.tiles bounds the shadow queue by tracing a tile's eye samples in batches: each sample's whole path
    (glass: reflection and transmission, soft shadows) stays in one batch, so every pixel and AOV is that of one
    batch, and so are the ray counts."""
    import tracer.integrator.tiles as tiles

    b = lit_sphere_on_floor()
    b.lights[0] = PointLight(position=b.lights[0].position, intensity=b.lights[0].intensity, radius=1.0)
    glass = b.add_material("glass", diffuse=(0, 0, 0), transmission=1.0, ior=1.5)
    sphere(b, (1.2, -1.0, 0.4), 0.4, glass, "glass_ball", count=16)
    scene = b.build()
    s = RenderSettings(width=W, height=H, samples=2, light_samples=4, max_depth=4,
                       aovs=("depth", "normal", "albedo", "objectid", "direct", "transmission", "raydepth"))
    whole = render(scene, s)
    monkeypatch.setattr(tiles, "SHADOW_SLOTS", 1)  # batches of 1 024 eye samples: 12 per tile
    batched = render(scene, s)
    np.testing.assert_array_equal(whole.rgba, batched.rgba)
    for name in s.aovs:
        np.testing.assert_array_equal(whole.aovs[name], batched.aovs[name])
    assert whole.stats["rays"] == batched.stats["rays"] and whole.stats["rays"]["transmission"] > 0


def test_transparent_film_and_aovs():
    scene = mirror_and_ball().build()
    img = render(scene, RenderSettings(samples=1, width=W, height=H, transparent=True,
                                       aovs=("depth", "normal", "albedo", "objectid")))
    ids = img.aovs["objectid"]
    np.testing.assert_array_equal(img.rgba[..., 3] > 0.5, ids >= 0)
    assert np.all(np.isinf(img.aovs["depth"][ids < 0])) and np.all(np.isfinite(img.aovs["depth"][ids >= 0]))
    n = img.aovs["normal"][ids >= 0]
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-4)
    np.testing.assert_allclose(img.aovs["albedo"][ids == 1], np.broadcast_to([0.7, 0.3, 0.1], ((ids == 1).sum(), 3)),
                               atol=1e-6)
    assert np.all(np.isfinite(img.rgba))


def test_soft_shadow_from_a_light_with_radius_has_a_penumbra():
    hard = render(lit_sphere_on_floor().build(), RenderSettings(samples=1, width=W, height=H))
    b = lit_sphere_on_floor()
    b.lights[0] = PointLight(position=b.lights[0].position, intensity=b.lights[0].intensity, radius=1.0)
    soft = render(b.build(), RenderSettings(width=W, height=H, light_samples=16))
    levels = lambda img: len(np.unique(np.round(lum(img.rgb[H // 2:]), 3)))
    assert levels(soft) > levels(hard)
    assert soft.stats["rays"]["shadow"] > 8 * hard.stats["rays"]["shadow"]


def test_png_and_exr_output(tmp_path):
    from tracer import read_image

    img = render(lit_sphere_on_floor().build(), RenderSettings(samples=1, width=W, height=H))
    img.save(tmp_path / "a.png")
    img.save(tmp_path / "a.exr")
    png, exr = read_image(tmp_path / "a.png"), read_image(tmp_path / "a.exr")
    assert png.shape == (H, W, 4) and exr.shape == (H, W, 4)
    np.testing.assert_allclose(exr[..., :3], img.rgb, rtol=2e-3, atol=1e-4)  # half floats
    from tracer.colorspace import linear_to_srgb

    np.testing.assert_allclose(png[..., :3], linear_to_srgb(img.rgb), atol=1 / 255 + 1e-6)
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no temporary left behind


def test_terminal_rays_collect_only_background_past_max_depth():
    scene = mirror_and_ball().build()
    s = RenderSettings(samples=1, width=W, height=H, aovs=("objectid",), max_depth=0)
    plain = render(scene, s)
    term = render(scene, s.with_(terminal_rays=True))
    deeper = render(scene, s.with_(max_depth=1))
    on_mirror = plain.aovs["objectid"] == 0
    # Off the mirror nothing changes; on it, the terminal bounce adds the background where the reflection misses,
    # and never the direct light that a real depth-1 bounce would add on the matte ball.
    np.testing.assert_array_equal(term.rgb[~on_mirror], plain.rgb[~on_mirror])
    gain = lum(term.rgb - plain.rgb)[on_mirror]
    assert np.count_nonzero(gain > 0) > 50
    assert np.all(lum(term.rgb)[on_mirror] <= lum(deeper.rgb)[on_mirror] + 1e-6)
    assert np.any(lum(term.rgb)[on_mirror] < lum(deeper.rgb)[on_mirror] - 1e-3)

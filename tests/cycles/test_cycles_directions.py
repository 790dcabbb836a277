"""Ray directions against Blender: eye rays (both front ends' camera conversions), reflection, refraction."""

import math

import numpy as np
import pytest

import cycles_harness as H
from cycles_scenes import CAM, GREY, IMAGE_SCENES, camera, floor, scene
from cycles_thresholds import EDGE_AGREEMENT_MIN, RAY_DISTANCE_REL

pytestmark = pytest.mark.cycles

# (name, camera kwargs, width, height)
CAMERAS = [
    ("auto_landscape", dict(lens=35.0), 160, 120),
    ("auto_portrait", dict(lens=50.0, sensor_width=32.0), 90, 160),
    ("horizontal_portrait", dict(lens=28.0, sensor_fit="HORIZONTAL"), 100, 150),
    ("vertical_landscape", dict(lens=42.0, sensor_height=20.0, sensor_fit="VERTICAL"), 200, 100),
    ("vertical_portrait_shift", dict(lens=60.0, sensor_height=30.0, sensor_fit="VERTICAL", shift=(0.12, -0.2)),
     120, 180),
    ("auto_shift", dict(lens=24.0, shift=(-0.3, 0.15)), 160, 90),
    ("ortho_landscape", dict(kind="ORTHO", ortho_scale=7.0), 160, 120),
    ("ortho_portrait_shift", dict(kind="ORTHO", ortho_scale=4.5, shift=(0.2, 0.1), sensor_fit="VERTICAL"), 90, 160),
]


def _camera_scene(cam_kwargs, w, h):
    cam = camera((3.0, -6.5, 4.0), (0.3, 0.4, 0.5), **cam_kwargs)
    return scene("camera_probe", camera=cam, materials={"grey": GREY}, objects=[floor(size=4.0)], width=w,
                 height=h, depth=0)


def _ray_distances(bpy, cam_obj, cam, n=400, seed=1):
    """Relative distance of Blender-projected random world points from our ray through the same film position."""
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector

    rng = np.random.default_rng(seed)
    m = np.array(cam_obj.matrix_world)
    # points in front of the camera, spread over (and beyond) the view
    local = np.stack([rng.uniform(-3, 3, n), rng.uniform(-3, 3, n), -rng.uniform(0.5, 20, n)], -1)
    world = local @ m[:3, :3].T + m[:3, 3]
    sc = bpy.context.scene
    uvd = np.array([tuple(world_to_camera_view(sc, cam_obj, Vector(p))) for p in world])
    o, d = cam.generate_rays(uvd[:, 0], uvd[:, 1])
    o, d = o.astype(np.float64), d.astype(np.float64)
    rel = world - o
    along = np.sum(rel * d, axis=1)
    perp = np.linalg.norm(rel - along[:, None] * d, axis=1)
    return perp / np.linalg.norm(world - m[:3, 3], axis=1), along


@pytest.mark.parametrize("front_end", ["addon", "usd"])
@pytest.mark.parametrize("name,cam_kwargs,w,h", CAMERAS, ids=[c[0] for c in CAMERAS])
def test_eye_rays_hit_blender_projections(bpy_module, tmp_path, name, cam_kwargs, w, h, front_end):
    desc = _camera_scene(cam_kwargs, w, h)
    if front_end == "usd" and cam_kwargs.get("kind") == "ORTHO":
        # Blender writes no orthographic camera: the test authors it in the USD (harness.patch_usd) as a user
        # would, and checks the reader's orthographic conversion against Blender's projection.
        pass
    cam = H.build_ours(desc, front_end, str(tmp_path)).camera
    cam_obj = bpy_module.context.scene.camera
    dist, along = _ray_distances(bpy_module, cam_obj, cam)
    assert np.all(along > 0), f"{name} [{front_end}]: points lie behind our rays"
    assert dist.max() <= RAY_DISTANCE_REL, f"{name} [{front_end}]: max relative distance {dist.max():.2e}"


def test_eye_ray_check_can_fail(bpy_module, tmp_path):
    """A shift forgotten by a conversion must fail the distance test by orders of magnitude."""
    desc = _camera_scene(dict(lens=35.0, shift=(0.1, 0.0)), 160, 120)
    cam = H.build_ours(desc, "addon", str(tmp_path)).camera
    cam.horizontal_aperture_offset = 0.0
    dist, _ = _ray_distances(bpy_module, bpy_module.context.scene.camera, cam)
    assert dist.max() > 1e3 * RAY_DISTANCE_REL


def test_reflect_matches_mathutils(bpy_module):
    from mathutils import Vector

    rng = np.random.default_rng(7)
    from tracer import optics

    # mathutils works in float32: give both the same float32 inputs and allow float32 rounding.
    d = rng.normal(size=(1000, 3)).astype(np.float32)
    n = rng.normal(size=(1000, 3))
    n = (n / np.linalg.norm(n, axis=1, keepdims=True)).astype(np.float32)
    ours = optics.reflect(d.astype(np.float64), n.astype(np.float64))
    theirs = np.array([tuple(Vector(a).reflect(Vector(b))) for a, b in zip(d, n)])
    scale = np.linalg.norm(d, axis=1, keepdims=True)
    assert np.max(np.abs(ours - theirs) / scale) < 1e-6
    assert np.max(np.abs(ours - d) / scale) > 0.5  # a no-op "reflect" would fail


def test_refract_obeys_snell():
    from tracer import optics

    rng = np.random.default_rng(3)
    n_rays = 2000
    n = rng.normal(size=(n_rays, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    d = rng.normal(size=(n_rays, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d = np.where((np.sum(d * n, 1) > 0)[:, None], -d, d)  # incident side: d·n ≤ 0
    eta_i = rng.choice([1.0, 1.33, 1.5], n_rays)
    eta_r = rng.choice([1.0, 1.33, 1.5, 2.4], n_rays)
    t, tir = optics.refract(d, n, eta_i, eta_r)
    cos_i = -np.sum(d * n, 1)
    sin_i = np.sqrt(np.maximum(0, 1 - cos_i**2))
    expect_tir = eta_i / eta_r * sin_i > 1
    np.testing.assert_array_equal(tir, expect_tir)
    ok = ~tir
    t = t[ok]
    np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1.0, atol=1e-9)
    cos_r = -np.sum(t * n[ok], 1)
    assert np.all(cos_r > 0), "transmitted rays must cross to the far side"
    sin_r = np.sqrt(np.maximum(0, 1 - cos_r**2))
    np.testing.assert_allclose(eta_r[ok] * sin_r, eta_i[ok] * sin_i[ok], atol=1e-9)  # Snell's law
    coplanar = np.sum(np.cross(d[ok], n[ok]) * t, 1)
    np.testing.assert_allclose(coplanar, 0.0, atol=1e-9)
    # the tangential part keeps its direction
    tan_d = d[ok] + cos_i[ok, None] * n[ok]
    tan_t = t + cos_r[:, None] * n[ok]
    assert np.all(np.sum(tan_d * tan_t, 1) >= -1e-12)


def _classes(rgb, mask):
    lum = rgb @ np.array([0.2126, 0.7152, 0.0722])
    thr = 0.35 * np.percentile(lum[mask], 98)
    return lum > thr


def edge_agreement(ours_rgb, ref_rgb, mask) -> float:
    """Fraction of masked pixels whose black/white class in ours is found in Cycles' 3×3 neighbourhood."""
    a, b = _classes(ours_rgb, mask), _classes(ref_rgb, mask)
    pad = np.pad(b, 1, mode="edge")
    h, w = b.shape
    near = np.zeros((2,) + b.shape, bool)
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            win = pad[dy:dy + h, dx:dx + w]
            near[0] |= ~win
            near[1] |= win
    ok = np.where(a, near[1], near[0])
    return float(ok[mask].mean())


@pytest.mark.parametrize("name", ["glass_slab", "glass_sphere", "water_sphere"])
def test_refracted_checker_edges_match_cycles(bpy_module, tmp_path, name):
    desc = IMAGE_SCENES[name]
    ref = H.cycles_reference(desc)
    img = H.render_ours(desc, "addon", aovs=("objectid",))
    scene_ = H.build_direct(desc)
    glass_id = scene_.object_names.index([o for o in desc["objects"] if o["pass_index"] == 2][0]["name"])
    mask = img.aovs["objectid"] == glass_id
    edges = np.abs(np.diff(_classes(img.rgb, mask).astype(int), axis=1))[mask[:, 1:]].sum()
    assert mask.sum() > 500 and edges > 30, "the glass must cover many checker edges for the test to mean anything"
    agree = edge_agreement(img.rgb, ref["rgb"], mask)
    shifted = edge_agreement(np.roll(img.rgb, 2, axis=1), ref["rgb"], mask)
    print(f"[cycles] {name}: checker-edge agreement through glass {agree:.4f} (2-px shift: {shifted:.4f})")
    assert shifted < EDGE_AGREEMENT_MIN, "the edge test cannot see a 2-pixel shift"
    if agree < EDGE_AGREEMENT_MIN:
        paths = H.save_comparison(str(tmp_path), name, img.rgb, ref["rgb"])
        pytest.fail(f"{name}: edge agreement {agree:.4f} < {EDGE_AGREEMENT_MIN}; images {paths}")

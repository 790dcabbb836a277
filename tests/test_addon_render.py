"""The Whitted render engine inside Blender (bpy module, headless): F12 through ``bpy.ops.render.render``.

Thresholds, and why:
- COVERAGE_AGREEMENT 0.99: the silhouette (alpha > 0.5) and the object-index pass must match Cycles' on 99 % of
  pixels; only edge pixels may differ (Cycles jitters 16 samples in a pixel, Whitted uses its N×N strata).
- DIFFUSE_RATIO 0.10: the default material (Principled, Specular IOR Level 0.5) differs from Blinn-Phong only in
  its specular lobe; the cube's mean brightness must agree with Cycles' within 10 % (measured: 4 %).
"""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

from blender_kit import scene as bs

import bpy  # noqa: E402  (the test extra installs bpy; a missing bpy must fail, not skip)

import addon  # noqa: E402
from addon import engine  # noqa: E402

COVERAGE_AGREEMENT = 0.99
DIFFUSE_RATIO = 0.10


@pytest.fixture(scope="module")
def whitted():
    addon.register()
    yield engine
    addon.unregister()


def render_whitted(scene=None, passes=(), samples=1):
    scene = scene or bpy.context.scene
    scene.whitted.samples = samples
    engine.WhittedRenderEngine.last_render = None
    out = bs.render_exr(scene, engine="WHITTED", passes=passes)
    assert engine.WhittedRenderEngine.last_render is not None, "the engine did not render"
    return out, engine.WhittedRenderEngine.last_render.stats


def test_registered_engine_and_panels(bpy_module, whitted):
    ids = {c.bl_idname for c in bpy.types.RenderEngine.__subclasses__()
           if hasattr(c, "bl_idname") and getattr(c, "is_registered", False)}
    assert "WHITTED" in ids
    bpy.context.scene.render.engine = "WHITTED"  # an unknown engine id would raise TypeError
    assert "WHITTED" in bpy.types.RENDER_PT_format.COMPAT_ENGINES
    assert "WHITTED" in bpy.types.EEVEE_MATERIAL_PT_surface.COMPAT_ENGINES
    assert "WHITTED" in bpy.types.DATA_PT_lens.COMPAT_ENGINES
    # The panel's settings reach the tracer: what F12 would use follows the scene's properties.
    props = bpy.context.scene.whitted
    saved = props.samples, props.max_depth, props.fresnel
    props.samples, props.max_depth, props.fresnel = 3, 2, False
    try:
        st = addon.export.settings_from_scene(bpy.context.scene)
        assert (st.samples, st.max_depth, st.fresnel) == (3, 2, False)
    finally:
        props.samples, props.max_depth, props.fresnel = saved


def test_default_scene_f12_matches_cycles(bpy_module, whitted, tmp_path):
    """Blender's default scene (cube, camera, 1000 W light): the image is written, and silhouette, object index,
    depth and normal passes agree with Cycles'."""
    bpy.ops.wm.read_factory_settings(use_empty=False)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 1920, 1080, 5
    scene.view_settings.view_transform = "Standard"
    scene.render.film_transparent = True
    bpy.data.objects["Cube"].pass_index = 3
    # the plain F12 path: a PNG written by Blender
    scene.render.engine = "WHITTED"
    scene.render.image_settings.file_format = "PNG"
    png = str(tmp_path / "f12.png")
    scene.render.filepath = png
    bpy.ops.render.render(write_still=True)
    assert os.path.getsize(png) > 0
    from tracer import read_image

    assert read_image(png).shape == (54, 96, 4)

    passes = ("Depth", "Normal", "IndexOB")
    ours, stats = render_whitted(scene, passes, samples=4)
    ref = bs.render_cycles_exr(scene, samples=16, passes=passes)
    a, b = ours["rgba"][..., 3] > 0.5, ref["rgba"][..., 3] > 0.5
    assert 0.1 < a.mean() < 0.6
    assert (a == b).mean() >= COVERAGE_AGREEMENT
    assert (ours["IndexOB"] == ref["IndexOB"]).mean() >= COVERAGE_AGREEMENT
    assert set(np.unique(ours["IndexOB"])) == {0.0, 3.0}
    inner = a & b & (np.abs(ours["IndexOB"] - ref["IndexOB"]) == 0)
    assert np.median(np.abs(ours["Depth"][inner] - ref["Depth"][inner])) < 1e-3 * np.median(ref["Depth"][inner])
    assert np.all(ours["Depth"][ours["rgba"][..., 3] == 0] >= 1e9)  # Blender writes 1e10 where nothing was hit
    assert np.median(np.einsum("ijk,ijk->ij", ours["Normal"], ref["Normal"])[inner]) > 0.999
    mean_ours, mean_ref = ours["rgba"][inner, :3].mean(), ref["rgba"][inner, :3].mean()
    assert abs(mean_ours / mean_ref - 1) < DIFFUSE_RATIO
    assert stats["rays"]["eye"] == 96 * 54 * 16 and stats["rays"]["shadow"] > 0


def sphere_scene(size=(64, 48), **material):
    """A sphere over a green plane, one point light, a blue world; returns (scene, sphere)."""
    scene = bs.reset(size)
    bs.add_camera((0, -6, 1.5), target=(0, 0, 0.8), lens=50)
    bs.add_point_light((3, -4, 6), power=2000)
    bs.add_plane(size=20, material=bs.principled_material("Ground", base_color=(0.1, 0.6, 0.1), specular=0.0))
    sphere = bs.add_uv_sphere((0, 0, 1.0), 1.0, segments=32, rings=16,
                              material=bs.principled_material("Ball", **material))
    bs.set_world((0.1, 0.2, 0.6))
    return scene, sphere


def sphere_pixels(out, scene):
    """Colours of the pixels inside the sphere's silhouette (object index 1)."""
    return out["rgba"][out["IndexOB"] == 1][:, :3]


def test_mirror_and_glass_spawn_reflection_and_transmission_rays(bpy_module, whitted):
    counts = {}
    for label, mat in {"diffuse": {}, "mirror": dict(metallic=1.0, roughness=0.0),
                       "glass": dict(transmission=1.0, roughness=0.0, ior=1.5)}.items():
        scene, _ = sphere_scene(**mat)
        _, stats = render_whitted(scene)
        counts[label] = stats["rays"]
    assert counts["diffuse"]["reflection"] == 0 and counts["diffuse"]["transmission"] == 0
    assert counts["mirror"]["reflection"] > 0.1 * counts["mirror"]["eye"]
    assert counts["mirror"]["transmission"] == 0
    assert counts["glass"]["transmission"] > 0.1 * counts["glass"]["eye"]
    assert counts["glass"]["reflection"] > 0  # Fresnel reflection off the glass


def test_resolution_percentage_border_and_film_transparent(bpy_module, whitted):
    scene, _ = sphere_scene(size=(128, 96))
    scene.render.resolution_percentage = 50
    full, _ = render_whitted(scene)
    assert full["rgba"].shape == (48, 64, 4)
    assert np.all(full["rgba"][..., 3] == 1.0)  # opaque film: the world is the background
    scene.render.film_transparent = True
    clear, _ = render_whitted(scene)
    sky = clear["rgba"][0, 0]
    assert sky[3] == 0.0 and np.all(full["rgba"][0, 0, :3] > 0.05)
    scene.render.film_transparent = False
    scene.render.use_border, scene.render.use_crop_to_border = True, False
    scene.render.border_min_x, scene.render.border_max_x = 0.25, 0.75
    scene.render.border_min_y, scene.render.border_max_y = 0.5, 1.0
    part, _ = render_whitted(scene)
    inside = np.zeros((48, 64), bool)
    inside[0:24, 16:48] = True  # top half (Blender's y goes up), middle half of the columns
    np.testing.assert_allclose(part["rgba"][inside], full["rgba"][inside], atol=1e-6)
    assert np.all(part["rgba"][~inside] == 0.0)
    scene.render.use_crop_to_border = True
    cropped, _ = render_whitted(scene)
    assert cropped["rgba"].shape == (24, 32, 4)
    np.testing.assert_allclose(cropped["rgba"], full["rgba"][0:24, 16:48], atol=1e-6)


def test_cancelled_render_stops_and_blender_stays_usable(bpy_module, whitted):
    scene, _ = sphere_scene(size=(256, 192))  # 12 tiles of 64×64
    polls = []

    def hook():
        polls.append(1)
        return len(polls) > 2

    engine.WhittedRenderEngine.break_hook = hook
    try:
        _, stats = render_whitted(scene)
    finally:
        engine.WhittedRenderEngine.break_hook = None
    assert stats.get("cancelled") is True
    # stopped before every tile was traced (Esc is polled during export and the Embree build too: there no tile)
    assert stats.get("rays", {"eye": 0})["eye"] < 256 * 192
    _, again = render_whitted(scene)  # Blender still renders afterwards
    assert not again.get("cancelled") and again["rays"]["eye"] == 256 * 192


def test_principled_inputs_change_the_picture(bpy_module, whitted):
    """Each Principled input moves the sphere's pixels the way the mapping in addon.export says."""
    passes = ("IndexOB",)

    def ball(**mat):
        scene, sphere = sphere_scene(**mat)
        sphere.pass_index = 1
        out, stats = render_whitted(scene, passes)
        return sphere_pixels(out, scene), stats

    grey, _ = ball(base_color=(0.5, 0.5, 0.5), specular=0.0)
    red, _ = ball(base_color=(0.8, 0.05, 0.05), specular=0.0)
    # Base Color: with no highlight the picture is linear in the albedo, channel by channel
    np.testing.assert_allclose(red.mean(axis=0) / grey.mean(axis=0), (1.6, 0.1, 0.1), rtol=1e-3)
    # Metallic: the sphere mirrors the green ground and blue sky, tinted by the base colour
    metal, stats = ball(base_color=(1.0, 1.0, 1.0), metallic=1.0, roughness=0.0)
    assert stats["rays"]["reflection"] > 0
    assert metal[:, 1].mean() > 1.5 * metal[:, 0].mean() and metal[:, 2].mean() > metal[:, 0].mean()
    # Specular IOR Level and IOR scale the highlight (F0 = ((η−1)/(η+1))²·2·level); roughness sharpens it
    no_spec, _ = ball(base_color=(0.2, 0.2, 0.2), specular=0.0, roughness=0.3)
    spec, _ = ball(base_color=(0.2, 0.2, 0.2), specular=1.0, roughness=0.3)
    high_ior, _ = ball(base_color=(0.2, 0.2, 0.2), specular=1.0, roughness=0.3, ior=2.5)
    rough, _ = ball(base_color=(0.2, 0.2, 0.2), specular=1.0, roughness=0.7)
    assert spec.max() > no_spec.max() + 0.05
    assert high_ior.max() > spec.max() + 0.05
    assert rough.max() < spec.max() - 0.05
    # Transmission: the ground and sky show through the glass
    glass, stats = ball(base_color=(1.0, 1.0, 1.0), transmission=1.0, roughness=0.0)
    assert stats["rays"]["transmission"] > 0 and glass[:, 1].mean() > glass[:, 0].mean()
    # Emission: an unlit sphere shows exactly its emission colour × strength
    scene, sphere = sphere_scene(base_color=(0.0, 0.0, 0.0), specular=0.0, emission_color=(1.0, 0.5, 0.25),
                                 emission_strength=0.8)
    sphere.pass_index = 1
    bpy.data.objects.remove(bpy.data.objects["Point"])
    bs.set_world((0.0, 0.0, 0.0))
    out, _ = render_whitted(scene, passes)
    np.testing.assert_allclose(np.median(sphere_pixels(out, scene), axis=0), (0.8, 0.4, 0.2), rtol=1e-3)
    # Alpha 0: the sphere lets rays through unbent; its pixels show the world behind it
    scene = bs.reset((64, 48))
    bs.add_camera((0, -6, 0), target=(0, 0, 0))
    bs.add_uv_sphere(material=bs.principled_material("Ghost", alpha=0.0)).pass_index = 1
    bs.set_world((0.3, 0.2, 0.1))
    out, _ = render_whitted(scene, passes)
    np.testing.assert_allclose(sphere_pixels(out, scene), np.tile((0.3, 0.2, 0.1), (int((out["IndexOB"] == 1)
                                                                                       .sum()), 1)), atol=1e-4)


def test_image_texture_on_base_color(bpy_module, whitted):
    scene, sphere = sphere_scene(specular=0.0)
    sphere.pass_index = 1
    img = bpy.data.images.new("checker", 16, 16, alpha=False, float_buffer=True)
    y, x = np.mgrid[0:16, 0:16]
    on = ((x // 4 + y // 4) % 2).astype(np.float32)
    px = np.stack([on, 0.2 * np.ones_like(on), 1 - on, np.ones_like(on)], -1)
    img.pixels.foreach_set(px.ravel())
    mat = bpy.data.materials["Ball"]
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = img
    mat.node_tree.links.new(tex.outputs["Color"], bs.principled_node(mat).inputs["Base Color"])
    out, _ = render_whitted(scene, ("IndexOB",))
    ball = sphere_pixels(out, scene)
    red_cells = ball[:, 0] > 2 * ball[:, 2]
    blue_cells = ball[:, 2] > 2 * ball[:, 0]
    assert red_cells.mean() > 0.2 and blue_cells.mean() > 0.2  # both checker colours are on the sphere


def test_noise_threshold_and_debug_sample_count_pass_in_f12(bpy_module, whitted):
    """Render Properties → Sampling → Noise Threshold (ticked) reaches F12: with Cycles' Debug Sample Count pass
    asked for, Blender gets each pixel's samples over the N×N budget, as Cycles writes it; a soft shadow takes
    more than the open ground, and the budget's share is below 1 where the ground is flat."""
    scene, _ = sphere_scene()
    scene.objects["Point"].data.shadow_soft_size = 1.0  # a soft shadow
    props = scene.whitted
    props.light_samples = 1
    props.use_adaptive_sampling, props.adaptive_threshold, props.adaptive_min_samples = True, 0.01, 8
    layer = scene.view_layers[0]
    layer.cycles.pass_debug_sample_count = True
    try:
        out, stats = render_whitted(scene, passes=("Debug Sample Count",), samples=6)
    finally:
        props.use_adaptive_sampling, props.light_samples = False, 16
        layer.cycles.pass_debug_sample_count = False
    share = out["Debug Sample Count"]
    share = share[..., 0] if share.ndim == 3 else share
    assert share.min() >= 8 / 36 - 1e-6 and share.max() <= 1.0 + 1e-6
    assert share.min() < 0.5 and share.max() == pytest.approx(1.0)
    assert stats["samples_per_pixel"] == pytest.approx(share.mean() * 36, rel=1e-4)

"""Explain Pixel in Blender (bpy module, headless): the operator adds one curve per ray in a "Whitted rays"
collection, its tree adds up to the pixel F12 renders, Clear Rays removes it all."""

from __future__ import annotations

import numpy as np
import pytest

from blender_kit import scene as bs

import bpy  # noqa: E402

import addon  # noqa: E402
from addon import engine, explain  # noqa: E402


@pytest.fixture(scope="module")
def registered():
    addon.register()
    yield
    addon.unregister()


def _scene():
    bs.reset(size=(64, 48))
    glass = bs.principled_material("Glass", **{"Base Color": (1, 1, 1, 1), "Transmission Weight": 1.0,
                                               "Roughness": 0.0, "IOR": 1.5})
    floor = bs.principled_material("Floor", **{"Base Color": (0.8, 0.2, 0.1, 1), "Specular IOR Level": 0.0})
    bs.add_uv_sphere((0, 0, 1), 1.0, material=glass)
    bs.add_plane((0, 0, 0), 20.0, material=floor)
    bs.add_point_light((3, -3, 5), power=1500.0)
    bs.add_camera((0, -6, 2.5), (0, 0, 0.8))
    bs.set_world((0.1, 0.2, 0.5), 1.0)
    scene = bpy.context.scene
    scene.render.engine = "WHITTED"
    scene.whitted.samples = 1
    return scene


def test_explain_pixel_operator_adds_the_ray_tree(registered):
    scene = _scene()
    x, y = 32, 20  # through the glass ball
    ex, _ = explain.explain(bpy.context, x, y)
    for _ in range(2):  # a second run replaces the first one's curves (which are not traced themselves)
        assert bpy.ops.whitted.explain_pixel(x=x, y=y) == {"FINISHED"}
    coll = bpy.data.collections[explain.COLLECTION]
    kinds = {r.type for r in ex.rays()}
    assert {"eye", "transmission", "reflection"} <= kinds
    assert sum(len(o.data.splines) for o in coll.objects) == len(ex.rays())
    assert {o.name for o in coll.objects} == {f"Whitted {k} rays" for k in kinds}
    text = bpy.data.texts[explain.TEXT].as_string()
    assert text.startswith(f"pixel ({x}, {y}) = ")
    # The tree's colour is the pixel F12 renders (both through the same export and settings).
    f12 = bs.render_exr(scene, engine="WHITTED")["rgba"]
    pixel = f12[y, x, :3]
    assert np.allclose(ex.color, pixel, atol=2e-3), (ex.color, pixel)
    assert bpy.ops.whitted.clear_rays() == {"FINISHED"}
    assert explain.COLLECTION not in bpy.data.collections
    assert not [o for o in bpy.data.objects if o.name.startswith("Whitted ")]


def test_cursor_pixel_matches_the_camera_projection(registered):
    scene = _scene()
    # The ball's centre projects to the image centre column; the camera looks at (0, 0, 0.8) from above.
    x, y = explain.cursor_pixel(scene, (0.0, 0.0, 0.8))
    assert (x, y) in ((31, 23), (31, 24), (32, 23), (32, 24))
    assert bpy.ops.whitted.explain_pixel(use_cursor=True) == {"FINISHED"}


def test_pixel_outside_the_render_is_an_error_not_a_traceback(registered):
    _scene()
    with pytest.raises(RuntimeError, match="outside"):
        bpy.ops.whitted.explain_pixel(x=500, y=10)


def test_ray_type_passes_sum_to_combined(registered):
    scene = _scene()
    scene.whitted.ray_type_passes = True
    out = bs.render_exr(scene, engine="WHITTED", passes=("Whitted Direct",))
    parts = [out[f"Whitted {k}"] for k in ("Direct", "Reflection", "Transmission")]
    assert np.allclose(sum(parts), out["rgba"][..., :3], atol=1e-5)
    assert parts[2].max() > 0.05  # the glass ball passes light through
    depth = out["Whitted Ray Depth"]
    assert depth.max() >= 3 and depth.min() == 0

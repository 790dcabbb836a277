"""Light from the world and from emissive meshes, against Cycles at the tracer's default settings.

- An interior lit by a constant-colour world through its open front and a skylight, and objects lit by a lat-long
  environment only: the default ``sky_samples`` shadows the world as Cycles does; the notes' flat, unshadowed
  ambient term (``sky_samples = 0``) washes them out, which the tests also hold (so they can see the difference).
- A gold, smooth-shaded Suzanne (Blender's own mesh, through the add-on) under a spot and a sky: mirror rays off
  interpolated normals near its silhouettes stay above the surface (tracer.optics.valid_reflection_normal).

Bars in cycles_thresholds.py (WORLD_LIGHT).
"""

from __future__ import annotations

import inspect
import math

import pytest

import cycles_harness as H
from cycles_scenes import camera, floor, lambert, obj, scene, sphere, spot
from cycles_geometry import trs
from cycles_thresholds import PSNR_MIN, WORLD_LIGHT

from tracer.settings import DEFAULT_AA, default_of

pytestmark = pytest.mark.cycles

SIZE = (96, 72)


def world_interior():
    """A 4 × 4 × 2.5 m room, open at the front and along a 1 m skylight by the camera, lit by the world only."""
    mats = {"wall": lambert((0.8, 0.78, 0.72)), "white": lambert((0.85, 0.85, 0.85)),
            "blue": lambert((0.15, 0.3, 0.8))}

    def wall(name, loc, rot, size):
        return obj(name, "plane", "wall", matrix=trs(loc, rot), params=dict(size=size), pass_index=1)

    return scene("world_interior", camera=camera((0.0, -3.8, 1.4), (0.0, 0.5, 0.9), lens=24.0), materials=mats,
                 objects=[floor(material="wall", size=4.0, pass_index=1),
                          wall("Back", (0, 2, 1.25), (math.pi / 2, 0, 0), (4.0, 2.5)),
                          wall("Left", (-2, 0, 1.25), (0, math.pi / 2, 0), (2.5, 4.0)),
                          wall("Right", (2, 0, 1.25), (0, math.pi / 2, 0), (2.5, 4.0)),
                          wall("Ceiling", (0, 0.5, 2.5), (0, 0, 0), (4.0, 3.0)),
                          sphere("Ball", (-0.6, 0.6, 0.5), 0.5, "white", 2),
                          obj("Block", "box", "blue", matrix=trs((0.8, 0.4, 0.4), (0, 0, 0.5), (0.8, 0.8, 0.8)),
                              pass_index=3)],
                 world=(0.6, 0.75, 1.0), world_strength=1.5, depth=0, width=SIZE[0], height=SIZE[1], samples=256,
                 ours_samples=DEFAULT_AA, sky_samples=default_of("sky_samples"),
                 note="a room lit by the world through its open front and a skylight")


def world_hdri_object():
    """A ball and a block on a floor lit only by the "landmarks" lat-long environment (a sky over brown ground, red
    and green patches on the horizon, a yellow one at the zenith)."""
    mats = {"grey": lambert((0.8, 0.8, 0.8)), "white": lambert((0.85, 0.85, 0.85)), "blue": lambert((0.15, 0.3, 0.8))}
    d = scene("world_hdri_object", camera=camera((3.0, -6.0, 2.2), (0.0, 0.0, 0.8)), materials=mats,
              objects=[floor(material="grey", size=5.0, pass_index=1),
                       sphere("Ball", (-0.5, 0.3, 1.0), 1.0, "white", 2),
                       obj("Block", "box", "blue", matrix=trs((1.3, -0.5, 0.5), (0, 0, 0.6), (1.0, 1.0, 1.0)),
                           pass_index=3)],
              depth=0, width=SIZE[0], height=SIZE[1], samples=256, ours_samples=DEFAULT_AA,
              sky_samples=default_of("sky_samples"), note="objects lit by a lat-long environment only")
    d["world"]["texture"] = "landmarks"
    return d


SCENES = {"world_interior": world_interior(), "world_hdri_object": world_hdri_object()}


@pytest.mark.parametrize("name", list(SCENES))
def test_world_light_casts_shadows_at_default_settings(bpy_module, tmp_path, name):
    desc = SCENES[name]
    bar = WORLD_LIGHT[name]
    ref = H.cycles_reference(desc)["rgb"]
    H.check_images(desc, H.render_ours(desc, "direct").rgb, ref, tmp_path, min_psnr=bar["psnr"], max_mae=bar["mae"],
                   label=" [default settings]")
    flat = H.metrics(H.render_ours(desc, "direct", sky_samples=0).rgb, ref)
    print(f"[cycles] {name} flat ambient (sky_samples=0): PSNR {flat['psnr']:.2f} dB")
    assert flat["psnr"] < bar["flat_below"], "the flat ambient term must stay visibly wrong here"


def test_world_light_converges_to_cycles(bpy_module, tmp_path):
    """With more samples the interior meets the shared bar: what is left at the default is noise, not bias."""
    desc = SCENES["world_interior"]
    ours = H.render_ours(desc, "direct", samples=6, sky_samples=64)
    H.check_images(desc, ours.rgb, H.cycles_reference(desc)["rgb"], tmp_path, min_psnr=PSNR_MIN,
                   max_mae=WORLD_LIGHT["world_interior"]["converged_mae"], label=" [6x6, 64 sky samples]")


# ------------------------------------------------------------------------------------- gold Suzanne under a spot
SUZANNE = dict(depth=4, samples=128)
SUZANNE_AA = 8


def scene_gold_suzanne():
    """Blender's Suzanne (bmesh's monkey, 500 faces, smooth-shaded, no subdivision), gold metal at roughness 0,
    over a grey/red checker floor, under a spot and a blue-grey sky."""
    import bmesh
    import bpy
    from mathutils import Matrix

    desc = scene("gold_suzanne", camera=camera((0.0, -6.0, 2.4), (0.0, 0.0, 1.0), lens=40.0),
                 materials={"grey": lambert((0.8, 0.8, 0.8)), "red": lambert((0.8, 0.1, 0.1)),
                            "gold": dict(base_color=[1.0, 0.766, 0.336], metallic=1.0, roughness=0.0)},
                 objects=[floor(checker=("grey", "red"), divisions=(8, 8), pass_index=1)],
                 lights=[spot("Spot", (0.5, -2.5, 6.0), (0.0, 0.5, 0.0), 2500.0, math.radians(45), 0.3)],
                 world=(0.3, 0.4, 0.6), width=SIZE[0], height=SIZE[1], ours_samples=SUZANNE_AA, **SUZANNE)
    sc = H.build_bpy(desc)
    me = bpy.data.meshes.new("Suzanne")
    bm = bmesh.new()
    bmesh.ops.create_monkey(bm)
    bm.to_mesh(me)
    bm.free()
    me.shade_smooth()
    me.materials.append(bpy.data.materials["gold"])
    ob = bpy.data.objects.new("Suzanne", me)
    ob.matrix_world = Matrix(trs((0.0, 0.0, 1.1), (-0.3, 0.0, 0.0), (1.1, 1.1, 1.1)).tolist())
    ob.cycles.shadow_terminator_geometry_offset = 0.0
    ob.cycles.shadow_terminator_offset = 0.0
    sc.collection.objects.link(ob)
    return sc


def test_gold_suzanne_matches_cycles(bpy_module, tmp_path):
    import bpy

    import tracer
    from addon import export

    ref = H.cycles_render("gold_suzanne", scene_gold_suzanne, inspect.getsource(scene_gold_suzanne), SUZANNE)
    scene_gold_suzanne()
    ts, warnings = export.scene_from_depsgraph(bpy.context.evaluated_depsgraph_get(), width=SIZE[0],
                                               height=SIZE[1])
    ours = tracer.render(ts, tracer.RenderSettings(width=SIZE[0], height=SIZE[1], samples=SUZANNE_AA,
                                                   max_depth=SUZANNE["depth"], seed=0)).rgb
    bar = WORLD_LIGHT["gold_suzanne"]
    H.check_images({"name": "gold_suzanne"}, ours, ref, tmp_path, min_psnr=bar["psnr"], max_mae=bar["mae"],
                   label=" [addon]")

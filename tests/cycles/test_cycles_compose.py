"""Compositing against Cycles through the add-on: a shadow catcher plane under a ball (Combined with a transparent
and an opaque film, and the Shadow Catcher pass) and a holdout card in front of a lit ball (object holdout,
collection holdout, the Holdout shader and a Mix Shader of Holdout and the card's BSDF): colour and alpha
(tracer.integrator.compose)."""

import math

import numpy as np
import pytest

import cycles_harness as H
from cycles_geometry import trs
from cycles_scenes import camera, floor, lambert, obj, point, scene, sphere

pytestmark = pytest.mark.cycles

#: Colour (sRGB PSNR) and alpha (PSNR of the linear alpha) against Cycles.
COMPOSE_PSNR_MIN = 33.0

MATS = {"grey": lambert((0.8, 0.8, 0.8)), "red": lambert((0.8, 0.15, 0.1)), "card": lambert((0.1, 0.6, 0.2))}
CAM = camera((0.0, -6.0, 2.6), (0.0, 0.0, 0.6), lens=40.0)


def _catcher(name, transparent, catcher_pass):
    """A red ball over a catcher floor lit by a point light and a dim blue world (sky light in both renderers)."""
    d = scene(name, camera=CAM, materials=MATS, objects=[
        floor(size=12.0, pass_index=1), sphere("Ball", (0.3, 0.4, 0.8), 0.8, "red", 2)],
        lights=[point("Key", (2.5, -2.0, 5.0), 1500.0)], world=(0.2, 0.3, 0.5), depth=1, width=64, height=48,
        samples=128, ours_samples=4, sky_samples=64, note="shadow catcher floor under a ball")
    d["compose"] = dict(catcher=["Floor"], transparent=transparent, catcher_pass=catcher_pass)
    return d


def _holdout(name, how):
    """A lit ball on a floor behind a card that is a holdout (object or collection flag, or a Holdout shader)."""
    d = scene(name, camera=CAM, materials=MATS, objects=[
        floor(size=12.0, pass_index=1), sphere("Ball", (0.0, 0.8, 0.8), 0.8, "red", 2),
        obj("Card", "plane", "card", matrix=trs((-0.5, -1.2, 0.9), (math.pi / 2, 0, 0.3)),
            params=dict(size=(1.2, 1.0)), pass_index=3)],
        lights=[point("Key", (2.5, -3.0, 5.0), 1500.0)], world=(0.0, 0.0, 0.0), depth=1, width=64, height=48,
        samples=64, ours_samples=4, note=f"holdout card ({how}) in front of a lit ball")
    d["compose"] = dict(holdout=how, card="Card")
    return d


SCENES = {d["name"]: d for d in (
    _catcher("catcher_transparent", True, False), _catcher("catcher_pass", True, True),
    _catcher("catcher_opaque", False, False), _holdout("holdout_object", "object"),
    _holdout("holdout_collection", "collection"), _holdout("holdout_shader", "shader"),
    _holdout("holdout_mix", "mix"))}


def _bpy_scene(desc):
    """The harness's Blender scene with the compositing flags of ``desc["compose"]`` set on it."""
    b = H.bpy()
    sc = H.build_bpy(desc)
    c = desc["compose"]
    sc.render.film_transparent = bool(c.get("transparent", False))
    for name in c.get("catcher", ()):
        b.data.objects[name].is_shadow_catcher = True
    sc.view_layers[0].cycles.use_pass_shadow_catcher = bool(c.get("catcher_pass", False))
    how = c.get("holdout")
    if how == "object":
        b.data.objects[c["card"]].is_holdout = True
    elif how == "collection":
        coll = b.data.collections.new("Holdouts")
        sc.collection.children.link(coll)
        card = b.data.objects[c["card"]]
        sc.collection.objects.unlink(card)
        coll.objects.link(card)
        b.context.view_layer.layer_collection.children["Holdouts"].holdout = True
    elif how in ("shader", "mix"):
        m = b.data.materials["card"]
        nodes, links = m.node_tree.nodes, m.node_tree.links
        hold = nodes.new("ShaderNodeHoldout")
        out = hold.outputs["Holdout"]
        if how == "mix":  # 40 % holdout, 60 % the card's BSDF
            mix = nodes.new("ShaderNodeMixShader")
            mix.inputs["Fac"].default_value = 0.4
            links.new(nodes["Principled BSDF"].outputs["BSDF"], mix.inputs[1])
            links.new(out, mix.inputs[2])
            out = mix.outputs["Shader"]
        links.new(out, nodes["Material Output"].inputs["Surface"])
    return sc


def cycles(desc) -> dict:
    """Cycles' Combined (RGBA) and, when asked for, Shadow Catcher pass (cached like every reference)."""

    def render(tmp):
        H.render_multilayer(_bpy_scene(desc), tmp)

    def render_pass(tmp):  # bpy writes no Shadow Catcher layer into its multilayer EXR: the compositor's output
        b = H.bpy()
        sc = _bpy_scene(desc)
        ng = b.data.node_groups.new("Catcher", "CompositorNodeTree")
        sc.compositing_node_group = ng
        layers = ng.nodes.new("CompositorNodeRLayers")
        ng.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
        ng.links.new(layers.outputs["Shadow Catcher"], ng.nodes.new("NodeGroupOutput").inputs[0])
        sc.render.use_compositing = True
        sc.render.image_settings.file_format = "OPEN_EXR"
        sc.render.image_settings.color_depth = "32"
        sc.render.filepath = tmp
        b.ops.render.render(write_still=True)

    path, _, _ = H.cached_exr(f"{desc['name']}-compose-{H.content_hash(desc, 'compose')}", render,
                              (desc["name"], "compose"))
    chans = H._read_exr_channels(path)
    out = {"rgba": np.stack([H._channel(chans, f"Combined.{c}") for c in "RGBA"], axis=-1)}
    if desc["compose"].get("catcher_pass"):
        path, _, _ = H.cached_exr(f"{desc['name']}-catcher-{H.content_hash(desc, 'catcher')}", render_pass,
                                  (desc["name"], "catcher"))
        out["catcher"] = np.stack([H._read_exr_channels(path)[c] for c in "RGB"], axis=-1)
    H.bpy().ops.wm.read_factory_settings(use_empty=True)
    return out


def ours(desc, **changes):
    """The add-on's export of the same Blender scene, rendered with the settings it reads (Film > Transparent,
    the Shadow Catcher pass)."""
    from addon.export import scene_from_depsgraph, settings_from_scene

    import tracer

    sc = _bpy_scene(desc)
    scene_, _ = scene_from_depsgraph(H.bpy().context.evaluated_depsgraph_get(), width=desc["width"],
                                     height=desc["height"])
    for k, v in changes.items():
        setattr(scene_, k, v)
    s = settings_from_scene(sc).with_(samples=desc["ours_samples"], max_depth=desc["depth"],
                                      sky_samples=desc["sky_samples"], seed=0, threads=1)
    img = tracer.render(scene_, s)
    H.bpy().ops.wm.read_factory_settings(use_empty=True)
    return img


def psnr_alpha(a, b) -> float:
    mse = float(np.mean((np.asarray(a, np.float64) - b) ** 2))
    return float("inf") if mse == 0 else 10 * math.log10(1.0 / mse)


def _check(desc, img, ref, tmp_path):
    H.check_images(desc, img.rgb, ref["rgba"][..., :3], tmp_path, min_psnr=COMPOSE_PSNR_MIN, max_mae=0.02)
    pa = psnr_alpha(img.rgba[..., 3], ref["rgba"][..., 3])
    print(f"[cycles] {desc['name']}: alpha PSNR {pa:.2f} dB, mean alpha ours {img.rgba[..., 3].mean():.4f} "
          f"Cycles {ref['rgba'][..., 3].mean():.4f}")
    assert pa >= COMPOSE_PSNR_MIN, (desc["name"], pa)


@pytest.mark.parametrize("name", list(SCENES))
def test_compose_matches_cycles(bpy_module, tmp_path, name):
    desc = SCENES[name]
    ref = cycles(desc)
    img = ours(desc)
    _check(desc, img, ref, tmp_path)
    if "catcher" in ref:
        H.check_images(desc, img.aovs["shadow_catcher"], ref["catcher"], tmp_path, min_psnr=COMPOSE_PSNR_MIN,
                       max_mae=0.02, label=" [Shadow Catcher pass]")


def test_a_plain_floor_is_not_a_catcher(bpy_module, tmp_path):
    """The comparison can fail: without the catcher flag the floor renders opaque, far from Cycles' alpha."""
    desc = SCENES["catcher_transparent"]
    img = ours(desc, object_shadow_catcher=None)
    assert psnr_alpha(img.rgba[..., 3], cycles(desc)["rgba"][..., 3]) < COMPOSE_PSNR_MIN - 10

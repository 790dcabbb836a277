"""Light linking, shadow linking and ray visibility (tracer/linking.py) against Cycles, through the add-on: the same
Blender scene with the same links rendered by both. Each scene differs from its unlinked self where a renderer that
ignores the link gets it wrong (a lit floor that should be dark, a shadow that should be gone, a ball that should be
missing from the camera but in the mirror, a highlight that should be gone)."""

import numpy as np
import pytest

import cycles_harness as H
from cycles_geometry import trs
from cycles_scenes import GREY, camera, floor, lambert, mirror, obj, point, scene, sphere

pytestmark = pytest.mark.cycles

#: Linked scenes are Whitted scenes with hard point lights: the shared bar of the brief (≥ 33 dB).
LINK_PSNR_MIN = 33.0
LINK_MAE_MAX = 0.006

MATS = {"grey": GREY, "white": lambert((0.85, 0.85, 0.85)), "blue": lambert((0.15, 0.3, 0.8)), "mirror": mirror(),
        "shiny": dict(base_color=[0.6, 0.1, 0.1], roughness=0.3, specular_ior_level=0.5)}
CAM = camera((0.0, -7.0, 3.2), (0.0, 0.0, 0.7))
LIGHTS = [point("Key", (2.5, -2.0, 5.0), 1200.0), point("Fill", (-3.0, -1.5, 3.5), 600.0, color=(0.6, 0.7, 1.0))]


def _objects(ball="white"):
    return [floor(pass_index=1), sphere("Ball", (-0.9, 0.3, 1.0), 1.0, ball, 2, segments=48, rings=24),
            obj("Block", "box", "blue", matrix=trs((1.4, -0.4, 0.6), (0, 0, 0.6), (1.2, 1.2, 1.2)), pass_index=3)]


def _desc(name, objects=None, depth=0):
    return scene(f"linking_{name}", camera=CAM, materials=MATS, objects=objects or _objects(), lights=LIGHTS,
                 depth=depth, samples=64, ours_samples=4, width=64, height=48)


#: name -> (scene, links): ``receivers`` / ``blockers``: light -> [(object, INCLUDE | EXCLUDE)]; ``objects`` /
#: ``lights``: object -> {visibility property: value}.
CASES = {
    "include": (_desc("include"), dict(receivers={"Key": [("Ball", "INCLUDE")]})),
    "exclude": (_desc("exclude"), dict(receivers={"Key": [("Floor", "EXCLUDE")], "Fill": [("Ball", "EXCLUDE")]})),
    "shadow": (_desc("shadow"), dict(blockers={"Key": [("Ball", "EXCLUDE")], "Fill": [("Block", "INCLUDE")]})),
    "hidden_in_mirror": (_desc("hidden_in_mirror", depth=1, objects=_objects() + [
        obj("Mirror", "plane", "mirror", matrix=trs((0.0, 2.0, 1.5), (np.pi / 2, 0, 0)), params=dict(size=(6.0, 3.0)))]),
        dict(objects={"Ball": {"visible_camera": False}, "Block": {"visible_shadow": False}})),
    "light_not_glossy": (_desc("light_not_glossy", objects=_objects(ball="shiny")),
                         dict(lights={"Key": {"visible_glossy": False}, "Fill": {"visible_diffuse": False}})),
}


def apply_links(links: dict) -> None:
    """Author ``links`` on the Blender scene build_bpy made: linking collections of their own (not in the scene)
    with each entry's include / exclude state, and visibility properties."""
    b = H.bpy()
    for kind in ("receivers", "blockers"):
        for light, entries in links.get(kind, {}).items():
            coll = b.data.collections.new(f"{light}_{kind}")
            ll = b.data.objects[light].light_linking
            if kind == "receivers":
                ll.receiver_collection = coll
            else:
                ll.blocker_collection = coll
            for name, state in entries:
                coll.objects.link(b.data.objects[name])
                # collection_objects[i] holds the linking state of objects[i]
                coll.collection_objects[len(coll.objects) - 1].light_linking.link_state = state
    for what in ("objects", "lights"):
        for name, props in links.get(what, {}).items():
            for prop, value in props.items():
                setattr(b.data.objects[name], prop, value)


def _build(desc, links):
    def build():
        sc = H.build_bpy(desc)
        apply_links(links)
        return sc
    return build


def _ours(desc, links):
    from addon.export import scene_from_depsgraph

    _build(desc, links)()
    scene_, warnings = scene_from_depsgraph(H.bpy().context.evaluated_depsgraph_get(), width=desc["width"],
                                            height=desc["height"])
    assert not [w for w in warnings if "link" in w], warnings
    return scene_


def reference(key):
    desc, links = CASES[key]
    return H.cycles_render(desc["name"], _build(desc, links), repr(links), dict(depth=desc["depth"],
                                                                                samples=desc["samples"], v=desc))


@pytest.mark.parametrize("key", list(CASES))
def test_linking_matches_cycles(bpy_module, tmp_path, key):
    desc, links = CASES[key]
    ref = reference(key)
    ours = H.tracer.render(_ours(desc, links), H.ours_settings(desc)).rgb
    H.check_images(desc, ours, ref, tmp_path, min_psnr=LINK_PSNR_MIN, max_mae=LINK_MAE_MAX)
    # the links matter: the unlinked scene is far from Cycles' linked render
    unlinked = H.tracer.render(_ours(desc, {}), H.ours_settings(desc)).rgb
    assert H.metrics(unlinked, ref)["psnr"] < LINK_PSNR_MIN - 3, "the scene does not show its links"

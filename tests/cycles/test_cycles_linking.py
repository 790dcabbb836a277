"""Light linking, shadow linking and ray visibility (tracer/lights/linking.py) against Cycles, through the add-on: the same
Blender scene with the same links rendered by both. And through USD: Blender's USD export of the scene (which
writes no linking) with the links authored as UsdLux ``collection:lightLink`` / ``collection:shadowLink`` and
``inputs:diffuse`` / ``inputs:specular``, read by usd_io, within 1 dB of the add-on's render.

Each scene differs from its unlinked self where a renderer that ignores the link gets it wrong (a lit floor that
should be dark, a shadow that should be gone, a ball that should be missing from the camera but in the mirror, a
highlight that should be gone)."""

import numpy as np
import pytest

import cycles_harness as H
from cycles_geometry import trs
from cycles_scenes import GREY, camera, emissive, floor, lambert, mirror, obj, point, scene, sphere

pytestmark = pytest.mark.cycles

#: Linked scenes are Whitted scenes with hard point lights: the shared bar of the brief (≥ 33 dB).
LINK_PSNR_MIN = 33.0
LINK_MAE_MAX = 0.006

MATS = {"grey": GREY, "white": lambert((0.85, 0.85, 0.85)), "blue": lambert((0.15, 0.3, 0.8)), "mirror": mirror(),
        "shiny": dict(base_color=[0.6, 0.1, 0.1], roughness=0.3, specular_ior_level=0.5),
        "glow": emissive((1.0, 0.9, 0.7), strength=8.0)}
CAM = camera((0.0, -7.0, 3.2), (0.0, 0.0, 0.7))
LIGHTS = [point("Key", (2.5, -2.0, 5.0), 1200.0), point("Fill", (-3.0, -1.5, 3.5), 600.0, color=(0.6, 0.7, 1.0))]


def _objects(ball="white"):
    return [floor(pass_index=1), sphere("Ball", (-0.9, 0.3, 1.0), 1.0, ball, 2, segments=48, rings=24),
            obj("Block", "box", "blue", matrix=trs((1.4, -0.4, 0.6), (0, 0, 0.6), (1.2, 1.2, 1.2)), pass_index=3)]


def _desc(name, objects=None, depth=0, lights=LIGHTS, samples=64):
    return scene(f"linking_{name}", camera=CAM, materials=MATS, objects=objects or _objects(), lights=lights,
                 depth=depth, samples=samples, ours_samples=4, width=64, height=48)


#: An emissive panel facing down over the objects (a mesh light of its own once linked: tracer/lights/emitters.py).
PANEL = obj("Panel", "plane", "glow", matrix=trs((0.0, 0.3, 3.2), (np.pi, 0, 0)), params=dict(size=(2.0, 1.2)),
            pass_index=5)


#: name -> (scene, links): ``receivers`` / ``blockers``: light -> [(object, INCLUDE | EXCLUDE)]; ``objects`` /
#: ``lights``: object -> {visibility property: value}.
CASES = {
    "include": (_desc("include"), dict(receivers={"Key": [("Ball", "INCLUDE")]})),
    "exclude": (_desc("exclude"), dict(receivers={"Key": [("Floor", "EXCLUDE")], "Fill": [("Ball", "EXCLUDE")]})),
    "shadow": (_desc("shadow"), dict(blockers={"Key": [("Ball", "EXCLUDE")], "Fill": [("Block", "INCLUDE")]})),
    "hidden_in_mirror": (_desc("hidden_in_mirror", depth=1, objects=_objects() + [
        obj("Mirror", "plane", "mirror", matrix=trs((0.0, 2.0, 1.5), (np.pi / 2, 0, 0)),
            params=dict(size=(6.0, 3.0)))]),
        dict(objects={"Ball": {"visible_camera": False}, "Block": {"visible_shadow": False}})),
    "light_not_glossy": (_desc("light_not_glossy", objects=_objects(ball="shiny")),
                         dict(lights={"Key": {"visible_glossy": False}, "Fill": {"visible_diffuse": False}})),
    # the panel lights the ball only: the floor and block read the fill light alone
    "emitter_include": (_desc("emitter_include", objects=_objects() + [PANEL], lights=LIGHTS[1:], samples=256),
                        dict(receivers={"Panel": [("Ball", "INCLUDE")]})),
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


def author_usd_links(path: str, links: dict) -> None:
    """The Blender links as a USD user writes them on the exported stage: a light's receivers / blockers as its
    lightLink / shadowLink collection (includeRoot off and the included objects when any is included, then the
    excluded ones as excludes), visible_glossy / visible_diffuse off as inputs:specular / inputs:diffuse = 0."""
    from pxr import Usd, UsdLux

    stage = Usd.Stage.Open(path)
    by_name = {}
    for prim in stage.Traverse():
        by_name.setdefault(prim.GetName(), []).append(prim)
    xform = lambda name: next(p for p in by_name[name] if not p.GetParent().GetName() == name)  # noqa: E731
    light = lambda name: UsdLux.LightAPI(next(p for p in by_name[name] if p.HasAPI(UsdLux.LightAPI)))  # noqa
    for kind, get in (("receivers", "GetLightLinkCollectionAPI"), ("blockers", "GetShadowLinkCollectionAPI")):
        for name, entries in links.get(kind, {}).items():
            coll = getattr(light(name), get)()
            included = [xform(o).GetPath() for o, state in entries if state == "INCLUDE"]
            if included:
                coll.CreateIncludeRootAttr().Set(False)
                for p in included:
                    coll.IncludePath(p)
            for o, state in entries:
                if state == "EXCLUDE":
                    coll.ExcludePath(xform(o).GetPath())
    for name, props in links.get("lights", {}).items():
        lux = light(name)
        if props.get("visible_glossy") is False:
            lux.CreateSpecularAttr().Set(0.0)
        if props.get("visible_diffuse") is False:
            lux.CreateDiffuseAttr().Set(0.0)
    stage.Save()


def _ours_usd(desc, links, workdir):
    import os

    from usd_io.reader import load_stage

    H.build_bpy(desc)
    path = os.path.join(workdir, f"{desc['name']}.usda")
    H.bpy().ops.wm.usd_export(filepath=path)
    H.patch_usd(path, desc)
    author_usd_links(path, links)
    scene_, info = load_stage(path, width=desc["width"], height=desc["height"])
    assert not [w for w in info.warnings if "link" in w], info.warnings
    return scene_


#: Object ray visibility and emissive meshes' links have no renderer-neutral USD form (tracer/lights/linking.py,
#: usd_io/lights.py): not in USD.
USD_CASES = [k for k, (_, links) in CASES.items() if "objects" not in links and not k.startswith("emitter")]


@pytest.mark.parametrize("key", USD_CASES)
def test_usd_linking_matches_the_addon(bpy_module, tmp_path, key):
    desc, links = CASES[key]
    ref = reference(key)
    addon = H.metrics(H.tracer.render(_ours(desc, links), H.ours_settings(desc)).rgb, ref)["psnr"]
    ours = H.tracer.render(_ours_usd(desc, links, str(tmp_path)), H.ours_settings(desc)).rgb
    m = H.check_images(desc, ours, ref, tmp_path, min_psnr=LINK_PSNR_MIN, max_mae=LINK_MAE_MAX, label=" [usd]")
    assert m["psnr"] >= addon - 1.0, f"USD {m['psnr']:.2f} dB vs the add-on's {addon:.2f} dB"

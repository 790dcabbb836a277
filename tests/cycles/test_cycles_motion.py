"""Motion blur against Cycles: a translating ball, a turning box and a camera pan, keyframed in Blender, rendered
with Motion Blur on (shutter 1 frame, centred on frame 1) through the add-on and through Blender's USD export
(animation exported, the shutter authored on the camera as ``shutter:open``/``shutter:close``, as a USD user
would: Blender's exporter writes none)."""

import inspect
import math
import os

import numpy as np
import pytest

import cycles_harness as H
from cycles_geometry import look_at, trs
from cycles_scenes import BASE_MATS, camera, floor, lambert, obj, point, scene, sphere

import tracer

pytestmark = pytest.mark.cycles

#: The issue's bar for motion blur against Cycles (both average the same time integral; measured in the output).
MOTION_PSNR_MIN = 33.0
#: USD through `whitted render` against the add-on's render of the same scene (the issue: within 1 dB).
USD_MAX_DB_GAP = 1.0
SHUTTER = 1.0  # frames, centred on frame 1: the motion between frames 0.5 and 1.5

CAM = camera((0.0, -6.0, 2.6), (0.0, 0.0, 0.5), lens=40.0)


def _keys(frames: dict) -> dict:
    """{frame: 4×4 matrix} as JSON-hashable lists."""
    return {str(f): np.asarray(m, np.float64).round(12).tolist() for f, m in frames.items()}


def _translate_scene():
    mats = dict(BASE_MATS, red=lambert((0.8, 0.15, 0.1)))
    return scene("motion_translate", camera=CAM, materials=mats, objects=[
        floor(size=20.0, pass_index=1), sphere("Ball", (0.0, 0.0, 0.5), 0.5, "red", 2)],
        lights=[point("Key", (2.0, -3.0, 5.0), 2000.0)], depth=1, width=96, height=72, samples=256,
        ours_samples=8, note="a ball sliding 2.4 m per 2 frames"), {"Ball": _keys({0: trs((-1.2, 0, 0.5),
                                                                                       scale=(0.5,) * 3),
                                                                                  2: trs((1.2, 0, 0.5),
                                                                                       scale=(0.5,) * 3)})}


def _rotate_scene():
    mats = dict(BASE_MATS, blue=lambert((0.15, 0.3, 0.85)))
    box = obj("Box", "box", "blue", matrix=trs((0, 0, 0.5)), params=dict(size=(2.0, 0.6, 0.6)), pass_index=2)
    return scene("motion_rotate", camera=CAM, materials=mats, objects=[floor(size=20.0, pass_index=1), box],
                 lights=[point("Key", (2.0, -3.0, 5.0), 2000.0)], depth=1, width=96, height=72, samples=256,
                 ours_samples=8, note="a bar turning 180° per 2 frames about z"), {
        "Box": _keys({0: trs((0, 0, 0.5)), 2: trs((0, 0, 0.5), rotation=(0, 0, math.pi * 0.999))})}


def _pan_scene():
    mats = dict(BASE_MATS, red=lambert((0.8, 0.15, 0.1)))
    eye = np.array([0.0, -6.0, 2.6])
    m0 = look_at(eye, (-0.5, 0.0, 0.5))
    m2 = look_at(eye, (0.5, 0.0, 0.5))
    return scene("motion_pan", camera=CAM, materials=mats, objects=[
        floor(size=20.0, pass_index=1, checker=("grey", "red"), divisions=(20, 20)),
        sphere("Ball", (0.0, 0.0, 0.5), 0.5, "red", 2)],
        lights=[point("Key", (2.0, -3.0, 5.0), 2000.0)], depth=1, width=96, height=72, samples=256,
        ours_samples=8, note="the camera pans by 9.5° per 2 frames"), {"Camera": _keys({0: m0, 2: m2})}


SCENES = {d["name"]: (d, keys) for d, keys in (_translate_scene(), _rotate_scene(), _pan_scene())}


def build_animated(desc, keys, blur=True):
    """build_bpy's scene, with the objects (and camera) keyframed at the given frames (linear interpolation), the
    current frame 1 and Motion Blur on (shutter :data:`SHUTTER`, centred)."""
    b = H.bpy()
    from mathutils import Matrix

    from bpy_extras import anim_utils

    sc = H.build_bpy(desc)
    for name, frames in keys.items():
        ob = b.data.objects[name]
        ob.rotation_mode = "XYZ"
        for f, m in frames.items():
            ob.matrix_world = Matrix(m)
            ob.keyframe_insert("location", frame=float(f))
            ob.keyframe_insert("rotation_euler", frame=float(f))
            ob.keyframe_insert("scale", frame=float(f))
        anim = ob.animation_data
        for fc in anim_utils.action_get_channelbag_for_slot(anim.action, anim.action_slot).fcurves:
            for k in fc.keyframe_points:  # constant speed: what USD's linear interpolation of samples gives
                k.interpolation = "LINEAR"
    sc.frame_start, sc.frame_end = 0, 2
    sc.frame_set(1)
    sc.render.use_motion_blur = blur
    sc.render.motion_blur_shutter = SHUTTER
    sc.render.motion_blur_position = "CENTER"
    return sc


def cycles_motion(name):
    desc, keys = SCENES[name]
    source = inspect.getsource(build_animated)
    return H.cycles_render(name, lambda: build_animated(desc, keys), source + repr(keys) + repr(desc),
                           {"depth": desc["depth"], "samples": desc["samples"]})


def ours_addon(name, blur=True):
    from addon.export import scene_from_depsgraph

    desc, keys = SCENES[name]
    build_animated(desc, keys, blur)
    depsgraph = H.bpy().context.evaluated_depsgraph_get()
    sc, _warnings = scene_from_depsgraph(depsgraph, width=desc["width"], height=desc["height"])
    return tracer.render(sc, H.ours_settings(desc)).rgba[..., :3]


def ours_usd(name, workdir):
    """Blender's USD export of the animated scene (frames 0-2) with the shutter authored on its camera, read at
    frame 1 and rendered as `whitted render` renders it."""
    from pxr import Usd, UsdGeom

    from usd_io.reader import load_stage

    desc, keys = SCENES[name]
    build_animated(desc, keys)
    path = os.path.join(workdir, f"{name}.usda")
    H.bpy().ops.wm.usd_export(filepath=path, export_animation=True)
    H.patch_usd(path, desc)
    stage = Usd.Stage.Open(path)
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.Camera):
            cam = UsdGeom.Camera(prim)
            cam.CreateShutterOpenAttr(-SHUTTER / 2)
            cam.CreateShutterCloseAttr(SHUTTER / 2)
    stage.Save()
    sc, _info = load_stage(path, time=1, width=desc["width"], height=desc["height"])
    return tracer.render(sc, H.ours_settings(desc)).rgba[..., :3]


@pytest.mark.parametrize("name", list(SCENES))
def test_motion_blur_matches_cycles(bpy_module, tmp_path, name):
    desc, _ = SCENES[name]
    ref = cycles_motion(name)
    addon = ours_addon(name)
    H.check_images(desc, addon, ref, tmp_path, min_psnr=MOTION_PSNR_MIN, max_mae=0.01, label=" [addon]")
    usd = ours_usd(name, str(tmp_path))
    m_addon, m_usd = H.metrics(addon, ref), H.metrics(usd, ref)
    print(f"{name}: addon {m_addon['psnr']:.1f} dB, usd {m_usd['psnr']:.1f} dB against Cycles")
    assert m_usd["psnr"] >= m_addon["psnr"] - USD_MAX_DB_GAP, (m_usd, m_addon)


def test_a_still_frame_is_not_motion_blur(bpy_module):
    """The comparison can fail: the translating ball without motion blur is far from Cycles' blurred picture."""
    still = ours_addon("motion_translate", blur=False)
    assert H.metrics(still, cycles_motion("motion_translate"))["psnr"] < MOTION_PSNR_MIN - 5


def test_f12_blurs_through_the_engines_frame_set(bpy_module):
    """F12 with the Whitted engine (the add-on registered) samples the sub-frames through RenderEngine.frame_set
    and matches Cycles' motion blur too; the frame is back at 1 afterwards."""
    import addon
    from blender_kit import scene as bs

    desc, keys = SCENES["motion_translate"]
    ref = cycles_motion("motion_translate")
    addon.register()
    try:
        sc = build_animated(desc, keys)
        sc.whitted.samples = desc["ours_samples"]
        sc.whitted.max_depth = desc["depth"]
        out = bs.render_exr(sc, engine="WHITTED")
        assert sc.frame_current == 1 and sc.frame_subframe == 0.0
    finally:
        addon.unregister()
    m = H.metrics(out["rgba"][..., :3], ref)
    assert m["psnr"] >= MOTION_PSNR_MIN, m

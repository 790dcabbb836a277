"""Camera features against Cycles through the add-on and through Blender's USD export: depth of field (a thin lens
focused on an object, round and hexagonal apertures)."""

import math

import pytest

import cycles_harness as H
from cycles_geometry import trs
from cycles_scenes import BASE_MATS, camera, floor, lambert, obj, point, scene, sphere

pytestmark = pytest.mark.cycles

#: Depth of field against Cycles: both renderers average the same thin-lens integral, so the bar is the shared one
#: for Whitted-equivalent scenes raised to what converged references reach (measured in the test's output).
DOF_PSNR_MIN = 33.0


def _dof_scene(name, fstop, blades=0, rotation=0.0):
    """Three balls at 1.5, 3 and 8 m over a checker floor, focused on the middle one (its origin) through an 85 mm
    lens: at f/1.4 the near ball's blur disk is about 8 pixels wide, the far one's 5."""
    mats = dict(BASE_MATS, red=lambert((0.8, 0.1, 0.1)), green=lambert((0.1, 0.7, 0.2)),
                blue=lambert((0.15, 0.25, 0.9)))
    cam = camera((0.0, -3.0, 0.6), (0.0, 4.0, 0.35), lens=85.0)
    cam["dof"] = dict(fstop=fstop, object="Middle", blades=blades, rotation=rotation)
    return scene(name, camera=cam, materials=mats, objects=[
        floor(size=40.0, checker=("grey", "red"), divisions=(80, 80), pass_index=1),
        sphere("Near", (-0.25, -1.5, 0.2), 0.2, "green", 2),
        sphere("Middle", (0.1, 0.0, 0.35), 0.35, "blue", 3),
        sphere("Far", (0.9, 5.0, 0.6), 0.6, "grey", 4)],
        lights=[point("Key", (3.0, -4.0, 6.0), 3000.0)], depth=1, width=128, height=96, samples=512,
        ours_samples=16, note=f"depth of field at f/{fstop:g}, focused on the middle ball")


DOF_SCENES = {s["name"]: s for s in (_dof_scene("dof_f1.4", 1.4), _dof_scene("dof_f8", 8.0),
                                     _dof_scene("dof_f2_hexagon", 2.0, blades=6, rotation=0.3))}


@pytest.mark.parametrize("name,front_end", [(n, f) for n in DOF_SCENES for f in ("addon", "usd")])
def test_depth_of_field_matches_cycles(bpy_module, tmp_path, name, front_end):
    desc = DOF_SCENES[name]
    ours = H.render_ours(desc, front_end, workdir=str(tmp_path))
    H.check_images(desc, ours.rgb, H.cycles_reference(desc)["rgb"], tmp_path, min_psnr=DOF_PSNR_MIN,
                   max_mae=0.01, label=f" [{front_end}]")


def test_depth_of_field_is_not_a_pinhole(bpy_module, tmp_path):
    """The comparison can fail: the same scene through a pinhole is far from Cycles' f/1.4 picture."""
    desc = DOF_SCENES["dof_f1.4"]
    pinhole = dict(desc, camera={k: v for k, v in desc["camera"].items() if k != "dof"})
    m = H.metrics(H.render_ours(pinhole, "addon").rgb, H.cycles_reference(desc)["rgb"])
    assert m["psnr"] < DOF_PSNR_MIN - 3, m

"""Geometry-Nodes instances through the add-on, against Cycles: the add-on exports them as shared-mesh instances
(``tracer.Instances``: one object-space mesh, one matrix per instance), and Cycles renders its own instances of the
same depsgraph. The scene has smooth-shaded, rotated, non-uniformly scaled and mirrored instances, so a normal taken
to world space by the plain matrix instead of its inverse transpose, a lost mirror or a misplaced instance shows.
Reference cached by a hash of this file's scene source; bars in cycles_thresholds.py.
"""

from __future__ import annotations

import inspect

import numpy as np
import pytest

import cycles_harness as H
from cycles_thresholds import MAE_MAX, PSNR_MIN

from blender_kit import scatter
from blender_kit import scene as bs

pytestmark = pytest.mark.cycles

SIZE = (96, 72)
PARAMS = dict(depth=1, samples=128, ours_samples=8)


def scene_gn_instances():
    """A 5 × 4 grid of smooth icospheres, each rotated and scaled non-uniformly, and a row of mirrored
    (scale −1, 1.4, 0.7) ones, made by Geometry Nodes on a floor, one point light."""
    import bpy

    bs.reset(size=SIZE)
    # diffuse only: the specular lobes differ by model (GGX vs Blinn-Phong, cycles_thresholds.INHERENT)
    paint = bs.principled_material("paint", **{"Base Color": (0.2, 0.5, 0.8), "Specular IOR Level": 0.0})
    mirrored = dict(count=4, start=(-2.0, -2.6, 0.0), offset=(1.3, 0.0, 0.0), rotation=(0.4, 0.0, 0.7),
                    scale=(-1.0, 1.4, 0.7))
    scatter.add(scatter.graph(size=(5.0, 3.0), points=(5, 4), radius=0.4, material=paint, smooth=True,
                              scale=((0.6, 0.6, 0.5), (1.3, 1.0, 0.9)), mirrored_row=mirrored), (0, 0.4, 0.5))
    bs.add_plane((0, 0, 0), 20.0, name="Floor", material=bs.principled_material(
        "floor", **{"Base Color": (0.7, 0.7, 0.7), "Specular IOR Level": 0.0}))
    bs.add_camera((0, -7.5, 5.5), (0, -0.3, 0.3))
    bs.add_point_light((2, -4, 7), power=2500)
    bs.set_world((0.0, 0.0, 0.0))
    return bpy.context.scene


def _source() -> str:
    """What the reference depends on: this scene's builder and the scatter graph's."""
    return inspect.getsource(scene_gn_instances) + inspect.getsource(scatter)


def test_geometry_nodes_instances_match_cycles(bpy_module, tmp_path):
    import bpy

    import tracer
    from addon import export

    name = "addon_gn_instances"
    ref = H.cycles_render(name, scene_gn_instances, _source(), PARAMS)
    scene_gn_instances()
    ts, warnings = export.scene_from_depsgraph(bpy.context.evaluated_depsgraph_get())
    assert not warnings, warnings
    assert ts.instances is not None and len(ts.instances) == 24  # 20 + 4 mirrored, one shared mesh
    assert np.sum(np.linalg.det(ts.instances.transforms[:, :3, :3]) < 0) == 4
    settings = tracer.RenderSettings(width=SIZE[0], height=SIZE[1], samples=PARAMS["ours_samples"],
                                     max_depth=PARAMS["depth"], light_samples=16)
    ours = tracer.render(ts, settings).rgb
    H.check_images({"name": name}, ours, ref, tmp_path, min_psnr=PSNR_MIN, max_mae=MAE_MAX, label=" [addon]")

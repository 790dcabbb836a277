"""Geometry-Nodes instances through the add-on, against Cycles: the add-on exports them as shared-mesh instances
(``tracer.Instances``: one object-space mesh, one matrix per instance), and Cycles renders its own instances of the
same depsgraph. The scene has smooth-shaded, rotated, non-uniformly scaled and mirrored instances, so a normal taken
to world space by the plain matrix instead of its inverse transpose, a lost mirror or a misplaced instance shows.
Reference cached by a hash of this file's scene source; bars in cycles_thresholds.py.
"""

from __future__ import annotations

import inspect
import os
import time

import numpy as np
import pytest

import cycles_harness as H
from cycles_thresholds import MAE_MAX, PSNR_MIN

from tests import blender_support as bs

pytestmark = pytest.mark.cycles

SIZE = (96, 72)
PARAMS = dict(depth=1, samples=128, ours_samples=8)


def scene_gn_instances():
    """A 5 × 4 grid of smooth icospheres, each rotated and scaled non-uniformly, and a row of mirrored
    (scale −1, 1.4, 0.7) ones, made by Geometry Nodes on a floor, one point light."""
    import bpy

    bs.reset(size=SIZE)
    ng = bpy.data.node_groups.new("Scatter", "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = ng.nodes, ng.links
    out = nodes.new("NodeGroupOutput")
    grid = nodes.new("GeometryNodeMeshGrid")
    grid.inputs["Size X"].default_value, grid.inputs["Size Y"].default_value = 5.0, 3.0
    grid.inputs["Vertices X"].default_value, grid.inputs["Vertices Y"].default_value = 5, 4
    row = nodes.new("GeometryNodeMeshLine")
    row.inputs["Count"].default_value = 4
    row.inputs["Start Location"].default_value = (-2.0, -2.6, 0.0)
    row.inputs["Offset"].default_value = (1.3, 0.0, 0.0)
    ico = nodes.new("GeometryNodeMeshIcoSphere")
    ico.inputs["Radius"].default_value, ico.inputs["Subdivisions"].default_value = 0.4, 2
    smooth = nodes.new("GeometryNodeSetShadeSmooth")
    mat = nodes.new("GeometryNodeSetMaterial")
    # diffuse only: the specular lobes differ by model (GGX vs Blinn-Phong, cycles_thresholds.INHERENT)
    mat.inputs["Material"].default_value = bs.principled_material("paint", **{"Base Color": (0.2, 0.5, 0.8),
                                                                              "Specular IOR Level": 0.0})
    rot = nodes.new("FunctionNodeRandomValue")
    rot.data_type = "FLOAT_VECTOR"
    rot.inputs["Max"].default_value = (3.0, 3.0, 3.0)
    scale = nodes.new("FunctionNodeRandomValue")
    scale.data_type = "FLOAT_VECTOR"
    scale.inputs["Min"].default_value, scale.inputs["Max"].default_value = (0.6, 0.6, 0.5), (1.3, 1.0, 0.9)
    iop = nodes.new("GeometryNodeInstanceOnPoints")
    mirrored = nodes.new("GeometryNodeInstanceOnPoints")
    mirrored.inputs["Rotation"].default_value = (0.4, 0.0, 0.7)
    mirrored.inputs["Scale"].default_value = (-1.0, 1.4, 0.7)
    join = nodes.new("GeometryNodeJoinGeometry")
    links.new(ico.outputs["Mesh"], smooth.inputs["Geometry"])
    links.new(smooth.outputs["Geometry"], mat.inputs["Geometry"])
    links.new(grid.outputs["Mesh"], iop.inputs["Points"])
    links.new(mat.outputs["Geometry"], iop.inputs["Instance"])
    links.new(rot.outputs["Value"], iop.inputs["Rotation"])
    links.new(scale.outputs["Value"], iop.inputs["Scale"])
    links.new(row.outputs["Mesh"], mirrored.inputs["Points"])
    links.new(mat.outputs["Geometry"], mirrored.inputs["Instance"])
    links.new(iop.outputs["Instances"], join.inputs["Geometry"])
    links.new(mirrored.outputs["Instances"], join.inputs["Geometry"])
    links.new(join.outputs["Geometry"], out.inputs[0])
    host = bs.add_plane((0, 0.4, 0.5), 1.0, name="Host")
    host.modifiers.new("Scatter", "NODES").node_group = ng
    bs.add_plane((0, 0, 0), 20.0, name="Floor", material=bs.principled_material(
        "floor", **{"Base Color": (0.7, 0.7, 0.7), "Specular IOR Level": 0.0}))
    bs.add_camera((0, -7.5, 5.5), (0, -0.3, 0.3))
    bs.add_point_light((2, -4, 7), power=2500)
    bs.set_world((0.0, 0.0, 0.0))
    return bpy.context.scene


def _source() -> str:
    return inspect.getsource(scene_gn_instances)


def test_geometry_nodes_instances_match_cycles(bpy_module, tmp_path):
    import bpy

    import tracer
    from addon import export
    from bench.cycles import whitted_cycles_settings

    name = "addon_gn_instances"
    key = H.content_hash(name, _source(), PARAMS)
    path = os.path.join(H.CACHE_DIR, f"{name}-{key}.exr")
    if not os.path.exists(path):
        scene = scene_gn_instances()
        whitted_cycles_settings(scene, depth=PARAMS["depth"], samples=PARAMS["samples"])
        os.makedirs(H.CACHE_DIR, exist_ok=True)
        tmp = path + f".{os.getpid()}.tmp.exr"
        t0 = time.perf_counter()
        bs.render_exr(scene, tmp)
        H.CYCLES_LOG.append((name, "beauty", time.perf_counter() - t0, False))
        os.replace(tmp, path)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    ref = bs.read_exr(path)["rgba"][..., :3]

    scene_gn_instances()
    ts, warnings = export.scene_from_depsgraph(bpy.context.evaluated_depsgraph_get())
    assert not warnings, warnings
    assert ts.instances is not None and len(ts.instances) == 24  # 20 + 4 mirrored, one shared mesh
    assert np.sum(np.linalg.det(ts.instances.transforms[:, :3, :3]) < 0) == 4
    settings = tracer.RenderSettings(width=SIZE[0], height=SIZE[1], samples=PARAMS["ours_samples"],
                                     max_depth=PARAMS["depth"], light_samples=16)
    ours = tracer.render(ts, settings).rgb
    H.check_images({"name": name}, ours, ref, tmp_path, min_psnr=PSNR_MIN, max_mae=MAE_MAX, label=" [addon]")

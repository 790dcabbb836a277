"""Round trip through Blender's USD exporter: a scene built with bpy, written by bpy.ops.wm.usd_export, read by
usd_io, must have the camera, lights and materials Blender had (in Blender's units)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracer import DistantLight, PointLight, roughness_to_exponent
from usd_io import load_stage

W, H = 160, 120


def _principled(bpy, name, **inputs):
    m = bpy.data.materials.new(name)
    p = m.node_tree.nodes["Principled BSDF"]
    for k, v in inputs.items():
        p.inputs[k].default_value = v
    return m


def test_blender_export_round_trip(bpy_module, tmp_path):
    bpy = bpy_module
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector

    sc = bpy.context.scene
    sc.render.resolution_x, sc.render.resolution_y = W, H
    cam = bpy.data.cameras.new("Cam")
    cam.lens, cam.shift_x, cam.shift_y = 35.0, 0.1, -0.05
    cam_ob = bpy.data.objects.new("Cam", cam)
    sc.collection.objects.link(cam_ob)
    sc.camera = cam_ob
    cam_ob.location = (0.5, -7.0, 2.5)
    cam_ob.rotation_euler = (math.radians(75), 0.0, math.radians(5))

    point = bpy.data.lights.new("Key", "POINT")
    point.energy, point.shadow_soft_size, point.color = 1000.0, 0.1, (1.0, 0.9, 0.8)
    p_ob = bpy.data.objects.new("Key", point)
    sc.collection.objects.link(p_ob)
    p_ob.location = (1.0, 2.0, 3.0)
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy, sun.angle = 3.0, math.radians(2.0)
    s_ob = bpy.data.objects.new("Sun", sun)
    sc.collection.objects.link(s_ob)
    s_ob.rotation_euler = (math.radians(30), 0.0, 0.0)

    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, location=(-1.0, 0.0, 1.0))
    paint = _principled(bpy, "Paint", **{"Base Color": (0.8, 0.2, 0.1, 1.0), "Roughness": 0.4, "Metallic": 0.0})
    bpy.context.active_object.data.materials.append(paint)
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.7, location=(1.5, 0.0, 1.0))
    glass = _principled(bpy, "Glass", **{"Base Color": (0.9, 0.95, 1.0, 1.0), "Transmission Weight": 1.0,
                                         "IOR": 1.45, "Roughness": 0.0})
    bpy.context.active_object.data.materials.append(glass)
    bpy.context.view_layer.update()
    path = tmp_path / "blender.usda"
    bpy.ops.wm.usd_export(filepath=str(path), generate_materialx_network=True)

    scene, info = load_stage(str(path), width=W, height=H)
    assert (info.width, info.height) == (W, H)
    # Camera: points land where Blender's own camera model puts them.
    pts = [(0.0, 0.0, 0.0), (-1.0, 0.0, 2.0), (2.0, 1.0, 0.5), (-2.5, 3.0, 1.5)]
    want = []
    for p in pts:
        u, v, _ = world_to_camera_view(sc, cam_ob, Vector(p))
        want.append((u * W, (1 - v) * H))
    got = scene.camera.project(np.array(pts), W, H)[:, :2]
    np.testing.assert_allclose(got, want, atol=0.05)

    # Lights: Blender's units (point: radiant intensity P/4π per channel; sun: irradiance S).
    lights = {type(l).__name__: l for l in scene.lights}
    pl, dl = lights["PointLight"], lights["DistantLight"]
    assert isinstance(pl, PointLight) and isinstance(dl, DistantLight)
    np.testing.assert_allclose(pl.position, (1, 2, 3), atol=1e-5)
    np.testing.assert_allclose(pl.intensity, 1000 / (4 * np.pi) * np.array([1.0, 0.9, 0.8]), rtol=1e-4)
    assert pl.radius == pytest.approx(0.1, rel=1e-4)
    np.testing.assert_allclose(dl.irradiance, [3.0] * 3, rtol=1e-4)
    sun_dir = np.array(s_ob.matrix_world.to_3x3() @ Vector((0, 0, -1)))
    np.testing.assert_allclose(dl.direction, sun_dir, atol=1e-5)
    assert dl.angle == pytest.approx(math.radians(2.0), rel=1e-3)

    # Materials: base colour, roughness; glass keeps its transmission and IOR through the MaterialX network.
    m = scene.materials
    names = {n.rsplit("/", 1)[-1]: i for i, n in enumerate(m.names)}
    pi, gi = names["Paint"], names["Glass"]
    np.testing.assert_allclose(m.diffuse[pi], (0.8, 0.2, 0.1), atol=1e-5)
    assert m.exponent[pi] == pytest.approx(float(roughness_to_exponent(0.4)), rel=1e-4)
    assert m.transmission[pi] == 0 and m.k_m[pi] == 0
    assert m.transmission[gi] == 1.0 and m.ior[gi] == pytest.approx(1.45, rel=1e-5)
    # Every triangle of each sphere carries its own material.
    obj = np.array(scene.object_names)[scene.object_ids]
    assert set(m.names[i] for i in scene.material_ids[np.char.find(obj.astype(str), "Sphere_001") >= 0]) == {m.names[gi]}

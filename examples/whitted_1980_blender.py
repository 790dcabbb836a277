"""Whitted's 1980 picture rebuilt in Blender (bpy): the scene of examples/whitted_1980.py as Blender objects, so
it can be rendered with the Whitted add-on (F12) and with Cycles side by side.

    python examples/whitted_1980_blender.py                 # both renders into docs/images/
    python examples/whitted_1980_blender.py --save scene.blend --no-render

Inside Blender, run it from the Text Editor (``build_scene()`` only touches the current file's data).
"""

from __future__ import annotations

import argparse
import math
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SKY = (0.12, 0.32, 0.85)
#: Point-light power in W: the tracer example's 120 W/sr radiant intensity × 4π.
KEY_POWER = 120.0 * 4 * math.pi


def _principled(bpy, name, **inputs):
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    bsdf = next(n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    for key, value in inputs.items():
        sock = bsdf.inputs[key]
        sock.default_value = tuple(value) + (1.0,) if isinstance(value, tuple) and len(value) == 3 else value
    if "Base Color" in inputs:
        mat.diffuse_color = tuple(inputs["Base Color"]) + (1.0,)
    return mat


def _link(bpy, obj):
    bpy.context.scene.collection.objects.link(obj)
    return obj


def checker_floor(bpy, red, yellow, extent=((-6, 6), (-3, 15)), square=1.0):
    (x0, x1), (y0, y1) = extent
    nx, ny = int((x1 - x0) / square), int((y1 - y0) / square)
    gx, gy = np.meshgrid(np.arange(nx + 1) * square + x0, np.arange(ny + 1) * square + y0, indexing="ij")
    verts = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], -1)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    i, j = i.ravel(), j.ravel()
    v = lambda a, b: a * (ny + 1) + b  # noqa: E731
    faces = np.stack([v(i, j), v(i + 1, j), v(i + 1, j + 1), v(i, j + 1)], -1)
    mesh = bpy.data.meshes.new("Floor")
    mesh.from_pydata(verts.tolist(), [], faces.tolist())
    mesh.materials.append(red)
    mesh.materials.append(yellow)
    parity = ((np.floor((x0 + i * square) / square) + np.floor((y0 + j * square) / square)) % 2).astype(np.int32)
    mesh.polygons.foreach_set("material_index", parity)
    mesh.update()
    return _link(bpy, bpy.data.objects.new("Floor", mesh))


def sphere(bpy, name, center, radius, material):
    import bmesh

    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=64, v_segments=32, radius=radius)
    mesh = bpy.data.meshes.new(name)
    bm.to_mesh(mesh)
    bm.free()
    mesh.shade_smooth()
    mesh.materials.append(material)
    obj = _link(bpy, bpy.data.objects.new(name, mesh))
    obj.location = center
    return obj


def point_light(bpy, name, location, power):
    data = bpy.data.lights.new(name, "POINT")
    data.energy, data.shadow_soft_size = power, 0.0
    obj = _link(bpy, bpy.data.objects.new(name, data))
    obj.location = location
    return obj


def build_scene(bpy, width=480, height=270):
    """Build the scene into an empty file; returns ``bpy.context.scene`` set up for Whitted and for Cycles."""
    from mathutils import Vector

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = width, height, 100
    scene.view_settings.view_transform = "Standard"
    red = _principled(bpy, "Red", **{"Base Color": (0.75, 0.05, 0.03), "Roughness": 0.5})
    yellow = _principled(bpy, "Yellow", **{"Base Color": (0.8, 0.7, 0.05), "Roughness": 0.5})
    mirror = _principled(bpy, "Mirror", **{"Base Color": (0.9, 0.9, 0.9), "Metallic": 0.85, "Roughness": 0.0})
    glass = _principled(bpy, "Glass", **{"Base Color": (1.0, 1.0, 1.0), "Transmission Weight": 1.0,
                                         "Roughness": 0.0, "IOR": 1.5})
    checker_floor(bpy, red, yellow)
    sphere(bpy, "MirrorSphere", (-1.0, 4.2, 1.25), 1.25, mirror)
    sphere(bpy, "GlassSphere", (0.9, 1.6, 1.35), 0.85, glass)
    point_light(bpy, "Key", (-4.0, -3.0, 9.0), KEY_POWER)
    point_light(bpy, "Fill", (6.0, -1.0, 6.0), 0.6 * KEY_POWER)
    cam = bpy.data.cameras.new("Camera")
    cam.lens, cam.sensor_width, cam.sensor_fit = 35.0, 36.0, "AUTO"
    cam_obj = _link(bpy, bpy.data.objects.new("Camera", cam))
    cam_obj.location = (0.0, -4.5, 2.0)
    cam_obj.rotation_euler = (Vector((0.0, 3.0, 1.0)) - Vector(cam_obj.location)).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam_obj
    world = bpy.data.worlds.new("Sky")
    scene.world = world
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    bg = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
    bg.inputs["Color"].default_value = SKY + (1.0,)
    bg.inputs["Strength"].default_value = 1.0
    world.color = SKY
    return scene


def render_both(out_dir, width=480, height=270, cycles_samples=128):
    """F12 with Whitted and with Cycles (Whitted-equivalent settings) into ``out_dir``; returns the two paths."""
    import bpy

    sys.path.insert(0, ROOT)
    import addon
    from blender_kit import scene as bs

    addon.register()
    try:
        scene = build_scene(bpy, width, height)
        scene.render.image_settings.file_format = "PNG"
        scene.render.image_settings.color_mode = "RGB"
        scene.render.image_settings.compression = 100  # keep the README pictures small
        scene.render.engine = "WHITTED"
        scene.whitted.samples = 3
        scene.whitted.sky_samples = 16  # Cycles shadows its world light; sample the sky's visibility as it does
        paths = {}
        for engine in ("WHITTED", "CYCLES"):
            if engine == "CYCLES":
                bs.set_cycles_whitted(scene, samples=cycles_samples)
            scene.render.engine = engine
            paths[engine] = os.path.join(out_dir, f"whitted_1980_blender_{engine.lower()}.png")
            scene.render.filepath = paths[engine]
            bpy.ops.render.render(write_still=True)
        stats = addon.engine.WhittedRenderEngine.last_render.stats
        print(f"Whitted: {stats['rays']} in {stats['seconds']:.2f} s")
        return paths
    finally:
        addon.unregister()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "images"))
    ap.add_argument("--width", type=int, default=480)
    ap.add_argument("--height", type=int, default=270)
    ap.add_argument("--cycles-samples", type=int, default=128)
    ap.add_argument("--save", help="also save the .blend file here")
    ap.add_argument("--no-render", action="store_true")
    args = ap.parse_args(argv)
    import bpy

    os.makedirs(args.out, exist_ok=True)
    if not args.no_render:
        print(render_both(args.out, args.width, args.height, args.cycles_samples))
    if args.save:
        build_scene(bpy, args.width, args.height)
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(args.save))


if __name__ == "__main__":
    main()

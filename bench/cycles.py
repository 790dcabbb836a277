"""Cycles through bpy, in a child process (``python -m bench.cycles ...`` prints one JSON object).

The Blender scene is built from the same :class:`bench.scenes.BenchScene` arrays (one Blender mesh per bench mesh,
one object per instance sharing it, so Cycles instances as POV-Ray does), not imported from USD: Blender's USD
importer drops glass transmission (DESIGN.md).

Whitted-equivalent Cycles settings (as the Cycles comparison tests use): point lights of radius 0 with power
4π·I, diffuse bounces 0, glossy/transmission bounces = max depth, caustics off, no clamping, box pixel filter of
width 1, adaptive sampling and denoising off, CPU, a fixed thread count. Materials: Principled BSDF for the local
part, mixed with a sharp Glossy BSDF by k_m for mirrors; a sharp Glass BSDF for glass. The world is the background
colour at strength 1 (Cycles lights diffuse surfaces with it, shadowed; ours adds an unshadowed ambient term).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import statistics
import time

import numpy as np

from blender_kit.cycles import whitted_cycles_settings  # noqa: F401 — the one definition (tests use it too)

from . import scenes


def build_blender_scene(bs, width, height, samples, threads, max_depth=8):
    import bpy
    from mathutils import Matrix

    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    whitted_cycles_settings(sc, depth=max_depth, samples=samples)
    sc.render.threads_mode = "FIXED"
    sc.render.threads = threads
    sc.render.resolution_x = width
    sc.render.resolution_y = height
    sc.render.resolution_percentage = 100

    world = bpy.data.worlds.new("World")
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (*bs.background, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
    sc.world = world

    mats = [_material(bpy, m) for m in bs.materials]
    meshes = []
    for mesh in bs.meshes:
        me = bpy.data.meshes.new(mesh.name)
        v = np.asarray(mesh.vertices, np.float32)
        f = np.asarray(mesh.faces, np.int32)
        me.vertices.add(len(v))
        me.vertices.foreach_set("co", v.ravel())
        me.loops.add(3 * len(f))
        me.loops.foreach_set("vertex_index", f.ravel())
        me.polygons.add(len(f))
        me.polygons.foreach_set("loop_start", np.arange(0, 3 * len(f), 3, dtype=np.int32))
        if np.ndim(mesh.material) > 0:
            used = np.unique(mesh.material)
            for u in used:
                me.materials.append(mats[int(u)])
            remap = np.searchsorted(used, np.asarray(mesh.material))
            me.polygons.foreach_set("material_index", remap.astype(np.int32))
        me.polygons.foreach_set("use_smooth", np.full(len(f), mesh.normals is not None, bool))
        me.update()
        meshes.append(me)
    for k, inst in enumerate(bs.instances):
        ob = bpy.data.objects.new(f"{bs.meshes[inst.mesh].name}_{k}", meshes[inst.mesh])
        ob.matrix_world = Matrix([list(r) for r in np.asarray(inst.transform, float)])
        mat = bs.instance_material(inst)
        if np.ndim(mat) == 0:
            if not meshes[inst.mesh].materials:
                meshes[inst.mesh].materials.append(mats[int(mat)])
            ob.material_slots[0].link = "OBJECT"
            ob.material_slots[0].material = mats[int(mat)]
        sc.collection.objects.link(ob)

    for light in bs.lights:
        ld = bpy.data.lights.new(light.name, "POINT")
        ld.energy = float(np.mean(light.intensity)) * 4 * math.pi
        ld.color = tuple(np.asarray(light.intensity) / max(float(np.mean(light.intensity)), 1e-30))
        ld.shadow_soft_size = 0.0
        ob = bpy.data.objects.new(light.name, ld)
        ob.location = tuple(light.position)
        sc.collection.objects.link(ob)

    cam = bs.camera(width, height)
    cd = bpy.data.cameras.new("Camera")
    cd.lens = cam.focal_length
    cd.sensor_fit = "HORIZONTAL"
    cd.sensor_width = cam.horizontal_aperture
    ob = bpy.data.objects.new("Camera", cd)
    ob.matrix_world = Matrix([list(r) for r in cam.camera_to_world])
    sc.collection.objects.link(ob)
    sc.camera = ob
    return sc


def _material(bpy, m):
    mat = bpy.data.materials.new(m["name"])
    if not mat.node_tree:  # Blender < 5 needs use_nodes; 5.x always has a tree
        mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    if float(m.get("transmission", 0)) > 0:
        glass = nt.nodes.new("ShaderNodeBsdfGlass")
        glass.inputs["Roughness"].default_value = 0.0
        glass.inputs["IOR"].default_value = float(m.get("ior", 1.5))
        glass.inputs["Color"].default_value = (*m.get("transmission_tint", (1.0, 1.0, 1.0)), 1.0)
        nt.links.new(glass.outputs[0], out.inputs["Surface"])
        return mat
    p = nt.nodes.new("ShaderNodeBsdfPrincipled")
    p.inputs["Base Color"].default_value = (*m.get("diffuse", (0.8, 0.8, 0.8)), 1.0)
    p.inputs["Roughness"].default_value = float(m.get("roughness", 0.5))
    p.inputs["Specular IOR Level"].default_value = min(1.0, float(np.mean(m.get("specular", (0.0,) * 3))) / 0.08)
    km = float(m.get("k_m", 0))
    if km > 0:
        g = nt.nodes.new("ShaderNodeBsdfGlossy")
        g.inputs["Roughness"].default_value = 0.0
        g.inputs["Color"].default_value = (*m.get("mirror_tint", (1.0, 1.0, 1.0)), 1.0)
        mix = nt.nodes.new("ShaderNodeMixShader")
        mix.inputs["Fac"].default_value = km
        nt.links.new(p.outputs[0], mix.inputs[1])
        nt.links.new(g.outputs[0], mix.inputs[2])
        nt.links.new(mix.outputs[0], out.inputs["Surface"])
    else:
        nt.links.new(p.outputs[0], out.inputs["Surface"])
    return mat


def measure(name, width, height, threads, runs, samples, max_depth=8, image=None):
    import bpy

    bs = scenes.build(name)
    sc = build_blender_scene(bs, width, height, samples, threads, max_depth)
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        bpy.ops.render.render(write_still=False)
        times.append(time.perf_counter() - t0)
    if image:
        rr = bpy.data.images["Render Result"]
        sc.render.image_settings.file_format = "PNG"
        rr.save_render(filepath=os.path.abspath(image), scene=sc)
    med = statistics.median(times)
    return {"scene": name, "width": width, "height": height, "threads": threads, "samples": samples,
            "seconds": med, "times": times, "maxrss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024,
            "blender": bpy.app.version_string}


def main(argv=None):
    ap = argparse.ArgumentParser(description="time Cycles (bpy) on one bench scene")
    ap.add_argument("--scene", required=True, choices=scenes.ALL_SCENES)
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--max-depth", type=int, default=8)
    ap.add_argument("--image")
    a = ap.parse_args(argv)
    res = measure(a.scene, a.width, a.height, a.threads, a.runs, a.samples, a.max_depth, a.image)
    print("BENCH_JSON " + json.dumps(res), flush=True)


if __name__ == "__main__":
    main()

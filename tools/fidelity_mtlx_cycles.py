"""The MaterialX corpus' references (tools/fidelity_mtlx.py): MaterialX-generated OSL shaders rendered by Cycles
(bpy, OSL on the CPU) on the corpus' sphere under its dome. Run by fidelity_mtlx in its own process:

    python tools/fidelity_mtlx_cycles.py JOBS.json

JOBS.json: ``jobs`` [{osl, out}], ``spec`` (size, dome EXR, camera), ``spp``, ``mesh`` (points, counts, indices,
uvs, normals). One scene is built; each job swaps the Script node's file (compiled by Cycles' own OSL compiler) and
writes a linear RGBA EXR (alpha: coverage, the film is transparent). A shader that does not compile writes nothing
(the harness reports the missing reference).

Blender's Python modules for OSL parameters (``oslquery``) and its OpenImageIO bindings live in the bpy wheel's
own site-packages, which must come before the venv's OpenImageIO on sys.path.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time


def _bpy_site():
    import importlib.util

    spec = importlib.util.find_spec("bpy")
    base = os.path.dirname(spec.origin)
    for root, dirs, _files in os.walk(base):
        if "oslquery" in dirs:
            return root
    return None


def build(spec: dict, mesh: dict, spp: int):
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.shading_system = True
    sc.cycles.samples = spp
    sc.cycles.use_adaptive_sampling = False
    sc.cycles.use_denoising = False
    sc.cycles.seed = 0
    sc.cycles.pixel_filter_type = "BOX"
    sc.cycles.filter_width = 1.0
    sc.render.film_transparent = True
    sc.render.resolution_x = sc.render.resolution_y = spec["size"]
    sc.render.resolution_percentage = 100
    sc.view_settings.view_transform = "Standard"
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_mode = "RGBA"
    sc.render.image_settings.color_depth = "32"
    sc.render.threads_mode = "FIXED"
    sc.render.threads = int(os.environ.get("FIDELITY_THREADS", "2"))

    world = bpy.data.worlds.new("Dome")
    sc.world = world
    world.use_nodes = True
    nt = world.node_tree
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(spec["dome"])
    env.image.colorspace_settings.name = "Linear Rec.709"
    env.interpolation = "Linear"
    nt.links.new(env.outputs["Color"], nt.nodes["Background"].inputs["Color"])
    nt.nodes["Background"].inputs["Strength"].default_value = 1.0

    me = bpy.data.meshes.new("Sphere")
    pts = [tuple(p) for p in mesh["points"]]
    faces, k = [], 0
    for c in mesh["counts"]:
        faces.append(tuple(mesh["indices"][k:k + c]))
        k += c
    me.from_pydata(pts, [], faces)
    uv = me.uv_layers.new(name="UVMap")
    for loop in me.loops:
        uv.data[loop.index].uv = tuple(mesh["uvs"][loop.vertex_index])
    me.shade_smooth()
    me.normals_split_custom_set_from_vertices([tuple(n) for n in mesh["normals"]])
    me.update()
    ob = bpy.data.objects.new("Sphere", me)
    sc.collection.objects.link(ob)
    mat = bpy.data.materials.new("M")
    mat.use_nodes = True
    me.materials.append(mat)
    mt = mat.node_tree
    mt.nodes.clear()
    script = mt.nodes.new("ShaderNodeScript")
    out = mt.nodes.new("ShaderNodeOutputMaterial")
    uvmap = mt.nodes.new("ShaderNodeUVMap")
    uvmap.uv_map = "UVMap"
    tangent = mt.nodes.new("ShaderNodeTangent")
    tangent.direction_type = "UV_MAP"
    tangent.uv_map = "UVMap"

    cam = bpy.data.cameras.new("Camera")
    cam.lens = spec["camera"]["focal_mm"]
    cam.sensor_width = spec["camera"]["aperture_mm"]
    cam.sensor_fit = "AUTO"
    cam.clip_start = 0.01
    co = bpy.data.objects.new("Camera", cam)
    co.location = spec["camera"]["location"]
    co.rotation_euler = (math.pi / 2, 0.0, 0.0)
    sc.collection.objects.link(co)
    sc.camera = co
    return sc, mt, script, out, uvmap, tangent


def main(job_file: str) -> int:
    site = _bpy_site()
    if site:
        sys.path.insert(0, site)
        import OpenImageIO  # noqa: F401 — Blender's bindings, before oslquery is imported

    with open(job_file) as f:
        job = json.load(f)
    import bpy

    sc, mt, script, out, uvmap, tangent = build(job["spec"], job["mesh"], job["spp"])
    for j in job["jobs"]:
        start = time.perf_counter()
        # a new Script node per shader: an existing node keeps the sockets (and their values) of the parameters
        # a new shader shares with the previous one, so every standard_surface would render with the first's values
        mt.nodes.remove(script)
        script = mt.nodes.new("ShaderNodeScript")
        script.mode = "EXTERNAL"
        script.filepath = j["osl"]
        marker = j["out"] + ".started"
        open(marker, "w").close()  # a crash in Cycles' OSL compiler leaves it: the harness skips this job
        from cycles import osl as cycles_osl  # Blender's add-on module: compiles, then oslquery makes sockets

        ok = cycles_osl.update_script_node(script, lambda kind, msg: print(kind, msg, flush=True))
        if not ok or "out" not in script.outputs:
            print(f"FAIL {j['osl']}: does not compile", flush=True)
            os.replace(marker, j["out"] + ".fail")
            continue
        mt.links.new(script.outputs["out"], out.inputs["Surface"])
        if "mx_uvmap" in script.inputs:  # the mesh's UV map and UV tangent (fidelity_mtlx.CYCLES_PARAMS)
            mt.links.new(uvmap.outputs["UV"], script.inputs["mx_uvmap"])
        if "mx_tangent" in script.inputs:
            mt.links.new(tangent.outputs["Tangent"], script.inputs["mx_tangent"])
        sc.cycles.samples = int(j.get("spp", job["spp"]))
        sc.render.filepath = j["out"] + ".tmp.exr"
        bpy.ops.render.render(write_still=True)
        os.replace(j["out"] + ".tmp.exr", j["out"])
        os.remove(marker)
        print(f"OK {j['out']} {time.perf_counter() - start:.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))

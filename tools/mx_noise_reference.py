"""Reference values of Open Shading Language's noises, which MaterialX's noise nodes are ports of, computed by OSL
itself: an OSL shader inside Blender's Cycles (the ``bpy`` module, built with OSL) evaluates ``noise("snoise", p)``
(float and vector, 2D and 3D) and ``cellnoise(p)`` at a list of points, one pixel each, and this prints them as
the table that tests/test_usd_mtlx.py holds (``OSL_REFERENCE``).

    python tools/mx_noise_reference.py

(bpy's wheel has no ``oslquery`` module, so the script node's output sockets are added by hand after Cycles
compiles the shader.) The values are float32; tracer.shading.procedural.mx_noise agrees with them to ~2e-6.
"""

from __future__ import annotations

import os
import tempfile

import numpy as np

#: The points (x, y, z); 2D noises read (x, y).
POINTS = [(0.3, 0.7, 0.2), (-1.25, 2.5, 0.75), (3.7, -0.4, -2.9), (12.1, 7.3, 4.45), (-0.05, -0.95, 1.5),
          (5.5, 5.5, 5.5), (0.999, 1.001, -0.5), (-7.3, 2.2, 9.1)]
#: Output name -> OSL expression (a colour; signed noises shifted by +2 so that nothing is negative).
OUTPUTS = {
    "snoise3": 'color(noise("snoise", p) + 2.0, noise("snoise", p[0], p[1]) + 2.0, cellnoise(p))',
    "vsnoise3": 'color((vector)noise("snoise", p) + vector(2.0))',
    "vsnoise2": 'color((vector)noise("snoise", p[0], p[1]) + vector(2.0))',
    "vcell3": 'color((vector)cellnoise(p))',
    "vcell2": 'color((vector)cellnoise(p[0], p[1]))',
    "cell2": 'color(cellnoise(p[0], p[1]), 0, 0)',
}


def shader(expr: str) -> str:
    k = len(POINTS)
    pts = ", ".join(f"point({x!r}, {y!r}, {z!r})" for x, y, z in POINTS)
    return f"""shader mxref(output color Out = 0) {{
    point pts[{k}] = {{{pts}}};
    int i = clamp((int)floor(P[0] * {k} / 2.0), 0, {k - 1});
    point p = pts[i];
    Out = {expr};
}}
"""


def render(expr: str, tmp: str) -> np.ndarray:
    import bpy
    import cycles.osl as cosl

    k = len(POINTS)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.shading_system = True
    sc.cycles.samples = 1
    sc.cycles.use_denoising = False
    sc.cycles.filter_width = 0.01
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = k, 1, 100
    sc.view_settings.view_transform = "Standard"
    txt = bpy.data.texts.new("mxref.osl")
    txt.write(shader(expr))
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(1, 1, 0))
    plane = bpy.context.object
    mat = bpy.data.materials.new("m")
    if not mat.node_tree:
        mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    scr = nt.nodes.new("ShaderNodeScript")
    scr.mode = "INTERNAL"
    scr.script = txt
    ok, _oso, bytecode, digest = cosl.update_internal_script(lambda *a: None, txt)
    assert ok, "OSL compilation failed"
    scr.bytecode, scr.bytecode_hash = bytecode, digest
    scr.outputs.new("NodeSocketColor", "Out")
    em = nt.nodes.new("ShaderNodeEmission")
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(scr.outputs["Out"], em.inputs["Color"])
    nt.links.new(em.outputs[0], out.inputs["Surface"])
    plane.data.materials.append(mat)
    cam = bpy.data.cameras.new("c")
    cam.type, cam.ortho_scale = "ORTHO", 2.0
    co = bpy.data.objects.new("c", cam)
    sc.collection.objects.link(co)
    co.location = (1, 1, 5)
    sc.camera = co
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_depth = "32"
    sc.render.filepath = os.path.join(tmp, "ref.exr")
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(sc.render.filepath)
    return np.array(img.pixels[:], np.float64).reshape(-1, k, 4)[0, :, :3]  # Blender renders at least 4 rows


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        table = {name: render(expr, tmp) for name, expr in OUTPUTS.items()}
    print("OSL_REFERENCE = {  # tools/mx_noise_reference.py: OSL's own noise through Cycles-OSL (float32)")
    print(f"    \"points\": {POINTS},")
    for name, v in table.items():
        if name in ("snoise3", "vsnoise3", "vsnoise2"):
            v = v - 2.0
        if name == "snoise3":
            print(f"    \"snoise3\": {[round(float(x), 6) for x in v[:, 0]]},")
            print(f"    \"snoise2\": {[round(float(x), 6) for x in v[:, 1]]},")
            print(f"    \"cell3\": {[round(float(x + 2.0), 7) for x in v[:, 2]]},")
        elif name == "cell2":
            print(f"    \"cell2\": {[round(float(x), 7) for x in v[:, 0]]},")
        else:
            print(f"    \"{name}\": {[[round(float(x), 6) for x in row] for row in v]},")
    print("}")


if __name__ == "__main__":
    main()

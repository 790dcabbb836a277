"""Is the MaterialX reference's subsurface right? (tools/fidelity_mtlx.py, :func:`fidelity_mtlx.cycles_closures`)

    python tools/fidelity_mtlx_sss_check.py [--spp 64]

On the corpus' sphere under its dome (the harness' scene), in Blender's Cycles (bpy, CPU): MaterialX's
``subsurface_bssrdf(N, albedo, radius, 0)`` as Blender 5.0 renders it, the same adapted as the harness adapts it
(``albedo * subsurface_bssrdf(N, albedo, radius·4π, 0)``), and Cycles' own Subsurface Scattering node (random walk,
IOR 1.4, roughness 1: what its OSL closure sets up) of that colour and radius·4π, whose random walk scales a radius
by 1/(4π) in 5.0 (``bssrdf_setup_radius``), so that its mean free path is MaterialX's ``radius``. Prints each mean
colour and the ΔE00 of the first two against the node; also ``translucent_bsdf`` (unregistered in 5.0) against
its adaptation. Needs bpy; nothing is written but /tmp files.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

CASES = [((0.816, 0.14, 0.124), (0.1, 0.05, 0.02)), ((0.816, 0.14, 0.124), (1.0, 1.0, 1.0)),
         ((0.05, 0.4, 0.2), (0.003, 0.003, 0.003))]


def _osl(path, body):
    with open(path, "w") as f:
        f.write("shader check(color albedo = color(0.5), color radius = color(0.1), output closure color out = 0)\n"
                "{\n    out = " + body + ";\n}\n")
    return path


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--spp", type=int, default=64)
    args = p.parse_args(argv)
    import fidelity_mtlx as fm
    import fidelity_mtlx_cycles as fc

    site = fc._bpy_site()
    if site:
        sys.path.insert(0, site)
        import OpenImageIO  # noqa: F401 — Blender's bindings first
    import bpy
    from cycles import osl as cycles_osl

    tmp = tempfile.mkdtemp(prefix="mtlx_sss_")
    pts, counts, idx, uvs, nrm = fm.sphere_mesh()
    mesh = dict(points=pts.tolist(), counts=counts, indices=idx, uvs=uvs.tolist(), normals=nrm.tolist())
    spec = fm.scene_spec(64, fm.write_dome(os.path.join(tmp, "dome.exr")))
    sc, mt, node, out, _uv, _t = fc.build(spec, mesh, args.spp)
    shaders = dict(
        as_50=_osl(os.path.join(tmp, "a.osl"), "subsurface_bssrdf(N, albedo, radius, 0.0)"),
        adapted=_osl(os.path.join(tmp, "b.osl"), "albedo * subsurface_bssrdf(N, albedo, radius * (4.0 * M_PI), 0.0)"),
        translucent_bsdf=_osl(os.path.join(tmp, "c.osl"), "translucent_bsdf(N, albedo)"),
        translucent_adapted=_osl(os.path.join(tmp, "d.osl"), "albedo * translucent(N)"))
    count = [0]

    def render():
        count[0] += 1
        sc.render.filepath = os.path.join(tmp, f"r{count[0]}.exr")
        bpy.ops.render.render(write_still=True)
        a = fm.read_rgba(sc.render.filepath)
        m = a[..., 3] > 0.999
        return a[..., :3][m].mean(axis=0)

    def script(path, albedo, radius):
        nonlocal node
        mt.nodes.remove(node)
        node = mt.nodes.new("ShaderNodeScript")
        node.mode = "EXTERNAL"
        node.filepath = path
        cycles_osl.update_script_node(node, lambda *_a: None)
        node.inputs["albedo"].default_value = (*albedo, 1.0)
        node.inputs["radius"].default_value = (*radius, 1.0)
        mt.links.new(node.outputs["out"], out.inputs["Surface"])
        return render()

    def lab(c):
        return fm.srgb_linear_to_lab(c)

    worst = 0.0
    for albedo, radius in CASES:
        mt.nodes.remove(node)
        node = mt.nodes.new("ShaderNodeSubsurfaceScattering")
        node.falloff = "RANDOM_WALK"
        node.inputs["Color"].default_value = (*albedo, 1.0)
        node.inputs["Radius"].default_value = tuple(4.0 * 3.141592653589793 * r for r in radius)
        node.inputs["Scale"].default_value = 1.0
        node.inputs["IOR"].default_value = 1.4
        node.inputs["Roughness"].default_value = 1.0
        mt.links.new(node.outputs[0], out.inputs["Surface"])
        ref = render()
        print(f"albedo {albedo} radius {radius}: Subsurface Scattering node (radius·4π) {ref.round(4).tolist()}")
        for name in ("as_50", "adapted"):
            got = script(shaders[name], albedo, radius)
            de = fm.delta_e2000(lab(ref), lab(got))
            worst = max(worst, de) if name == "adapted" else worst
            print(f"    {name:10s} {got.round(4).tolist()}  dE00 {de:.2f}")
    albedo = CASES[0][0]
    mt.nodes.remove(node)
    node = mt.nodes.new("ShaderNodeBsdfTranslucent")
    node.inputs["Color"].default_value = (*albedo, 1.0)
    mt.links.new(node.outputs[0], out.inputs["Surface"])
    ref = render()
    print(f"translucent {albedo}: Translucent BSDF node {ref.round(4).tolist()}")
    for name in ("translucent_bsdf", "translucent_adapted"):
        got = script(shaders[name], albedo, (0.1, 0.1, 0.1))
        de = fm.delta_e2000(lab(ref), lab(got))
        worst = max(worst, de) if name.endswith("adapted") else worst
        print(f"    {name:20s} {got.round(4).tolist()}  dE00 {de:.2f}")
    print(f"adapted against Cycles' own nodes: worst dE00 {worst:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

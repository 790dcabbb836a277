"""``python -m bench.leaves``: a Geometry Nodes tree of alpha-cut leaf cards (issue #23: "a Geometry Nodes tree with
alpha-cut leaves traces 3.5× slower than Cycles' whole render"), built in Blender (no downloads), rendered by
Cycles at Whitted-equivalent settings and by the add-on through F12 (``bpy.ops.render.render``, the path F12 takes),
each in a fresh process.

The scene: a crown of ``--leaves`` (≈ 4 800) leaf cards (a 2-triangle quad, a generated 128² RGBA leaf image whose
alpha is the leaf's outline) instanced by Geometry Nodes (Distribute Points on Faces over an icosphere, Instance on
Points with a random rotation and scale, Object Info as instance), a trunk, a ground plane, a sun and a sky-blue
world (so sky rays, like the sun's shadow rays, look through the leaves). ``--variant principled``: the image's
alpha into Principled Alpha; ``mix``: Mix Shader(Transparent BSDF, Principled) by the alpha.

Reported: wall and CPU time of each F12 (export, BVH and trace for ours), and our time split, measured in a third
process on the same scene with one thread (so the stage times add up to the trace): Embree closest hits, Embree
occlusion, the transparent-shadow rounds (their closest hits and their blocker shading), the shading stages, and
the shadow rays' count and cost per ray.

    python -m bench.leaves [--width 480 --height 270] [--aa 1] [--cycles-samples 16] [--variant principled|mix]
                           [--no-filter] [--only whitted,cycles,split]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import time

import numpy as np


def leaf_pixels(n: int = 128) -> np.ndarray:
    """(n, n, 4) float32 RGBA, top row first: a pointed leaf (alpha 1 inside its outline, 0 outside), green with a
    lighter midrib and a stalk."""
    y, x = np.mgrid[0:n, 0:n].astype(np.float32)
    s = (y + 0.5) / n  # 0 at the top (tip), 1 at the bottom (stalk)
    xc = (x + 0.5) / n - 0.5
    half = 0.42 * np.maximum(np.sin(np.pi * np.clip((s - 0.02) / 0.83, 0, 1)), 0) ** 0.8  # half-width along the leaf
    inside = np.abs(xc) < half
    stalk = (np.abs(xc) < 0.02) & (s > 0.8)
    rib = np.abs(xc) < 0.012
    px = np.zeros((n, n, 4), np.float32)
    px[..., 0] = np.where(rib, 0.25, 0.08)
    px[..., 1] = np.where(rib, 0.45, 0.30 + 0.1 * s)
    px[..., 2] = np.where(rib, 0.10, 0.04)
    px[..., 3] = (inside | stalk).astype(np.float32)
    return px


def leaf_material(variant: str):
    """The leaf material: image colour → Base Color and image alpha → Principled Alpha (``principled``), or the
    Principled mixed with a Transparent BSDF by the alpha (``mix``)."""
    import bpy

    px = leaf_pixels()
    img = bpy.data.images.new("leaf", px.shape[1], px.shape[0], alpha=True, float_buffer=True)
    img.colorspace_settings.name = "Linear Rec.709"
    img.pixels.foreach_set(np.ascontiguousarray(px[::-1]).ravel())
    img.pack()
    mat = bpy.data.materials.new("Leaf")
    nt = mat.node_tree
    for node in list(nt.nodes):
        if node.type != "OUTPUT_MATERIAL":
            nt.nodes.remove(node)
    out = next(node for node in nt.nodes if node.type == "OUTPUT_MATERIAL")
    bsdf = nt.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.inputs["Roughness"].default_value = 0.6
    bsdf.inputs["Specular IOR Level"].default_value = 0.3
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = img
    nt.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    if variant == "principled":
        nt.links.new(tex.outputs["Alpha"], bsdf.inputs["Alpha"])
        nt.links.new(bsdf.outputs[0], out.inputs["Surface"])
    else:
        mix = nt.nodes.new("ShaderNodeMixShader")
        transparent = nt.nodes.new("ShaderNodeBsdfTransparent")
        nt.links.new(tex.outputs["Alpha"], mix.inputs["Fac"])
        nt.links.new(transparent.outputs[0], mix.inputs[1])
        nt.links.new(bsdf.outputs[0], mix.inputs[2])
        nt.links.new(mix.outputs[0], out.inputs["Surface"])
    return mat


def leaf_card(material, size=(0.22, 0.34)):
    """A quad of ``size`` (x, y) m with a 0..1 UV map, its stalk at the origin, not rendered itself (instanced)."""
    import bpy

    w, h = size
    mesh = bpy.data.meshes.new("LeafCard")
    mesh.from_pydata([(-w / 2, 0, 0), (w / 2, 0, 0), (w / 2, h, 0), (-w / 2, h, 0)], [], [(0, 1, 2, 3)])
    uv = mesh.uv_layers.new(name="UVMap")
    uv.data.foreach_set("uv", [0, 0, 1, 0, 1, 1, 0, 1])  # the image's bottom row at the stalk
    mesh.materials.append(material)
    obj = bpy.data.objects.new("LeafCard", mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.hide_render = True
    return obj


def crown_graph(card, density: float, radius: float = 1.6):
    """Geometry Nodes: an icosphere of ``radius``, leaf cards (Object Info, as instance) on points distributed over
    it at ``density`` per m², each randomly rotated and scaled (seeded: the same tree every run)."""
    import bpy

    ng = bpy.data.node_groups.new("Crown", "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = ng.nodes, ng.links
    ico = nodes.new("GeometryNodeMeshIcoSphere")
    ico.inputs["Radius"].default_value, ico.inputs["Subdivisions"].default_value = radius, 3
    dist = nodes.new("GeometryNodeDistributePointsOnFaces")
    dist.inputs["Density"].default_value = density
    dist.inputs["Seed"].default_value = 7
    info = nodes.new("GeometryNodeObjectInfo")
    info.inputs["Object"].default_value = card
    info.inputs["As Instance"].default_value = True
    rot = nodes.new("FunctionNodeRandomValue")
    rot.data_type = "FLOAT_VECTOR"
    rot.inputs["Max"].default_value = (2 * math.pi,) * 3
    scl = nodes.new("FunctionNodeRandomValue")
    scl.data_type = "FLOAT"
    scl.inputs["Min"].default_value, scl.inputs["Max"].default_value = 0.7, 1.3
    iop = nodes.new("GeometryNodeInstanceOnPoints")
    links.new(ico.outputs["Mesh"], dist.inputs["Mesh"])
    links.new(dist.outputs["Points"], iop.inputs["Points"])
    links.new(info.outputs["Geometry"], iop.inputs["Instance"])
    links.new(rot.outputs["Value"], iop.inputs["Rotation"])
    links.new(scl.outputs[1], iop.inputs["Scale"])
    out = nodes.new("NodeGroupOutput")
    links.new(iop.outputs["Instances"], out.inputs[0])
    return ng


def build_scene(width, height, variant="principled", leaves=4800, radius=1.6, sky=0.8):
    """The leaf tree scene (module docstring; ``sky``: the world's strength, 0 for a black world lit by the sun
    alone); returns the Blender scene."""
    import bpy

    from blender_kit import scene as bs

    sc = bs.reset(size=(width, height))
    card = leaf_card(leaf_material(variant))
    density = leaves / (4 * math.pi * radius ** 2)
    host = bs.add_plane((0, 0, 3.0), 1.0, name="Crown")
    host.modifiers.new("Leaves", "NODES").node_group = crown_graph(card, density, radius)
    bark = bs.principled_material("Bark", base_color=(0.25, 0.15, 0.08), specular=0.2)
    trunk = bs.add_cube((0, 0, 1.0), 1.0, material=bark, name="Trunk")
    trunk.scale = (0.22, 0.22, 2.0)
    grass = bs.principled_material("Ground", base_color=(0.35, 0.3, 0.2), specular=0.2)
    bs.add_plane((0, 0, 0), 24.0, material=grass, name="Ground")
    bs.add_camera((6.5, -7.5, 3.6), (0, 0, 2.3), lens=40)
    bs.add_sun((-0.45, 0.3, -0.84), strength=3.0)
    bs.set_world((0.35, 0.45, 0.65) if sky else (0.0, 0.0, 0.0), strength=sky or 1.0)
    return sc


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def measure(renderer, a) -> dict:
    import bpy

    sc = build_scene(a.width, a.height, a.variant, a.leaves)
    if a.no_filter:
        from tracer.accel import alpha

        alpha.ENABLED = False
    depsgraph = bpy.context.evaluated_depsgraph_get()  # Blender evaluates the node tree outside the timings
    n_inst = sum(1 for i in depsgraph.object_instances if i.is_instance)
    out = {"renderer": renderer, "width": a.width, "height": a.height, "variant": a.variant, "leaves": n_inst}
    if renderer == "whitted":
        import addon
        import tracer
        from addon import engine

        tracer.compile_kernels()
        addon.register()
        sc.render.engine = "WHITTED"
        sc.whitted.samples = a.aa
        sc.whitted.threads = a.threads
        bs.plain_whitted(sc)  # Denoise off: the render alone, against Cycles without its denoiser
        c0, t0 = _cpu(), time.perf_counter()
        bpy.ops.render.render()
        out["f12_s"], out["f12_cpu_s"] = time.perf_counter() - t0, _cpu() - c0
        stats = engine.WhittedRenderEngine.last_render.stats
        out["export_s"] = stats.get("export_seconds")
        out["bvh_s"] = stats.get("bvh_seconds")
        out["trace_s"] = stats.get("seconds")
        out["rays"] = stats.get("rays")
    elif renderer == "split":
        out.update(split(a))
    else:
        from blender_kit.cycles import whitted_cycles_settings

        whitted_cycles_settings(sc, depth=8, samples=a.cycles_samples)
        sc.render.threads_mode = "FIXED"
        sc.render.threads = a.threads
        c0, t0 = _cpu(), time.perf_counter()
        bpy.ops.render.render()
        out["f12_s"], out["f12_cpu_s"] = time.perf_counter() - t0, _cpu() - c0
        out["samples"] = a.cycles_samples
    if a.save:
        path = os.path.abspath(f"{a.save}_{renderer}.png")
        if renderer != "split":
            bpy.data.images["Render Result"].save_render(path)
            out["image"] = path
    return out


def split(a) -> dict:
    """Our render of the scene with one thread, each stage timed (wall time of its calls, which is CPU time with
    one thread): the export, the BVH, Embree's closest hits and occlusion, the transparent-shadow rounds and the
    rest of the shading."""
    import bpy

    import tracer
    import tracer.accel.accelerator
    from addon import export
    from tracer.integrator import wavefront as ig

    tracer.compile_kernels()
    t0 = time.perf_counter()
    scene, _ = export.scene_from_depsgraph(bpy.context.evaluated_depsgraph_get())
    res = {"export_s": time.perf_counter() - t0}
    settings = export.settings_from_scene(bpy.context.scene).with_(samples=a.aa, threads=1)
    t0 = time.perf_counter()
    session = tracer.Session(scene)
    res["bvh_s"] = time.perf_counter() - t0
    acc = session.accel if hasattr(session, "accel") else None
    clock = {"intersect": 0.0, "occluded": 0.0, "filtered_occluded": 0.0, "through_shadows": 0.0, "shade": 0.0}
    calls = {"occluded_rays": 0, "filtered_rays": 0, "through_calls": 0}

    def timed(name, fn, count=None):
        def wrapper(*args, **kw):
            s = time.perf_counter()
            try:
                return fn(*args, **kw)
            finally:
                clock[name] += time.perf_counter() - s
                if count:
                    calls[count] += (len(args[1]) if count == "occluded_rays" else
                                     len(args[1].o) if count == "filtered_rays" else 1)
        return wrapper

    Acc = type(acc) if acc is not None else tracer.accel.accelerator.Accelerator
    orig = (Acc.closest_hits, Acc.occluded, ig.Integrator._through_shadows, ig.Integrator._shade)
    Acc.closest_hits = timed("intersect", orig[0])
    Acc.occluded = timed("occluded", orig[1], "occluded_rays")
    ig.Integrator._through_shadows = timed("through_shadows", orig[2], "through_calls")
    ig.Integrator._shade = timed("shade", orig[3])
    try:  # the transparent-shadow filter (absent before it)
        from tracer.accel import alpha
    except ImportError:
        alpha = None
    if alpha is not None:
        filtered = alpha.occluded
        alpha.occluded = timed("filtered_occluded", filtered, "filtered_rays")
    try:
        t0 = time.perf_counter()
        image = session.render(settings)
        res["trace_s"] = time.perf_counter() - t0
    finally:
        Acc.closest_hits, Acc.occluded, ig.Integrator._through_shadows, ig.Integrator._shade = orig
        if alpha is not None:
            alpha.occluded = filtered
    res.update({f"{k}_s": v for k, v in clock.items()})
    res["rays"] = dict(image.stats.get("rays", {}))
    res.update(calls)
    session.close()
    return res


def _child(renderer, a) -> dict:
    cmd = [sys.executable, "-m", "bench.leaves", "--child", renderer, "--width", str(a.width), "--height",
           str(a.height), "--threads", str(a.threads), "--aa", str(a.aa), "--cycles-samples", str(a.cycles_samples),
           "--variant", a.variant, "--leaves", str(a.leaves)] + (["--save", a.save] if a.save else []) + (
               ["--no-filter"] if a.no_filter else [])
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=os.getcwd())
    line = [ln for ln in proc.stdout.splitlines() if ln.startswith("BENCH_JSON ")]
    if not line:
        raise RuntimeError(f"bench.leaves: {renderer} failed:\n{proc.stderr[-3000:]}")
    return json.loads(line[-1][len("BENCH_JSON "):])


def main(argv=None):
    ap = argparse.ArgumentParser(description="alpha-cut Geometry Nodes leaves: the add-on vs Cycles")
    ap.add_argument("--width", type=int, default=480)
    ap.add_argument("--height", type=int, default=270)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--aa", type=int, default=1, help="our N×N eye samples per pixel")
    ap.add_argument("--cycles-samples", type=int, default=16)
    ap.add_argument("--variant", choices=("principled", "mix"), default="principled")
    ap.add_argument("--leaves", type=int, default=4800)
    ap.add_argument("--only", default="whitted,cycles,split")
    ap.add_argument("--no-filter", action="store_true",
                    help="ours with the round-by-round transparent-shadow loop (tracer.accel.alpha.ENABLED = False)")
    ap.add_argument("--save", default="", help="write each F12's picture to SAVE_<renderer>.png")
    ap.add_argument("--child", choices=("whitted", "cycles", "split"))
    a = ap.parse_args(argv)
    if a.child:
        print("BENCH_JSON " + json.dumps(measure(a.child, a)), flush=True)
        return
    results = {r: _child(r, a) for r in a.only.split(",")}
    print(f"bench.leaves: {a.variant}, {a.width}x{a.height}, ours AA {a.aa}x{a.aa}, Cycles "
          f"{a.cycles_samples} spp, {a.threads} threads")
    w, c, s = results.get("whitted"), results.get("cycles"), results.get("split")
    if w:
        print(f"  ours F12 {w['f12_s']:.2f} s wall, {w['f12_cpu_s']:.2f} s CPU (export {w['export_s']:.2f} s, "
              f"BVH {w['bvh_s']:.2f} s, trace {w['trace_s']:.2f} s); {w['leaves']} leaves")
    if c:
        print(f"  Cycles F12 {c['f12_s']:.2f} s wall, {c['f12_cpu_s']:.2f} s CPU")
    if w and c:
        print(f"  ours / Cycles: {w['f12_s'] / c['f12_s']:.2f}x wall, {w['f12_cpu_s'] / c['f12_cpu_s']:.2f}x CPU")
    if s:
        print("  one thread: " + ", ".join(f"{k} {v:.2f}" for k, v in s.items() if k.endswith("_s")))
        print(f"  rays: {s['rays']}; plain occlusion {s['occluded_rays']:,} rays, filtered occlusion "
              f"{s.get('filtered_rays', 0):,} rays, {s['through_calls']} transparent-shadow loops")
    print("BENCH_JSON " + json.dumps(results))


if __name__ == "__main__":
    main()

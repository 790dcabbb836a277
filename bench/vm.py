"""What the shader VM costs per hit and per op: a lit plane seen head-on (every eye ray hits it), rendered with an
untextured material and with a dozen-node procedural material (tracer.shading.graph), warm, CPU time, best of runs.

    python -m bench.vm [--size 384] [--runs 5]

ns per op = (procedural − untextured) / (hits × the program's ops); the untextured render's own time per hit is the
"shading time of an untextured hit" the issue compares against (it includes the light sample and its shadow ray).
"textures stage" is the CPU time inside the VM's stage (tracer.shading.vm.shade_programs) per hit, timed around its
call: what the program itself costs, apart from what a program material costs the other stages; "with the untextured
hit" is (untextured render + textures stage) / untextured render. The three scenes render in rounds (best of
``--runs``), so that the shared machine's load swings touch them alike.

ns per op by kind: the noise material's stage re-run on one render's hits with its ops turned into no-ops, in turn:
per hit without a program (the stage's own work), dispatch (every op a no-op), arithmetic (the Noise ops no-ops),
Noise.
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def material(g, noise: bool):
    """Noise (or a sine pattern) -> ramp -> base colour; height -> bump -> normal: about a dozen nodes."""
    p = g.add("texture_coordinate")["Object"]
    if noise:
        n = g.add("noise_texture", {"Vector": p, "Scale": 4.0, "Detail": 2.0})
        f, h = n["Fac"], n["Fac"]
    else:
        p = g.add("mapping", {"Vector": p, "Scale": (4.0, 4.0, 4.0)})["Vector"]
        w = g.add("vector_math", {"Vector": p}, operation="SINE")["Vector"]
        xyz = g.add("separate_xyz", {"Vector": w})
        f = g.add("math", {"Value": xyz["X"], "Value_001": xyz["Y"]}, operation="ADD")["Value"]
        h = g.add("math", {"Value": xyz["Z"], "Value_001": xyz["Y"]}, operation="MULTIPLY")["Value"]
    f = g.add("math", {"Value": f, "Value_001": 0.5, "Value_002": 0.25}, operation="MULTIPLY_ADD")["Value"]
    ramp = g.add("rgb_ramp", {"Fac": f}, ramp=[(0.2, (0.3, 0.2, 0.1, 1)), (0.8, (0.9, 0.8, 0.6, 1))])["Color"]
    tint = g.add("mix_color", {"Factor": f, "A": ramp, "B": (0.5, 0.5, 0.9)}, blend_type="OVERLAY")["Result"]
    rough = g.add("map_range", {"Value": f, "To Min": 0.3, "To Max": 0.7})["Result"]
    nrm = g.add("bump", {"Height": h, "Strength": 0.3, "Distance": 0.05})["Normal"]
    return g.add("principled_bsdf", {"Base Color": tint, "Roughness": rough, "Normal": nrm})["BSDF"]


def scene(kind: str):
    import tracer
    from tracer.shading.compiler import add_graph
    from tracer.shading.graph import Graph

    b = tracer.SceneBuilder()
    if kind == "plain":
        m = b.add_material("plain", base_color=(0.6, 0.5, 0.4), roughness=0.5, specular=0.5)
    else:
        g = Graph(kind)
        g.output(material(g, kind == "noise"))
        m = add_graph(b, g)
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
    b.add_mesh(v, [[0, 1, 2], [0, 2, 3]], material=m, uvs=(v[:, :2] + 1) / 2, name="plane")
    b.camera = tracer.Camera.look_at((0, 0, 3), (0, 0, 0), up=(0, 1, 0), projection="orthographic",
                                     horizontal_aperture=1.8, vertical_aperture=1.8)
    b.add_light(tracer.PointLight((1.0, 1.0, 3.0), (20.0, 20.0, 20.0)))
    return b.build()


def main(argv=None) -> None:
    import tracer
    from tracer.shading.compiler import compile_graph
    from tracer.shading.graph import Graph

    ap = argparse.ArgumentParser(prog="python -m bench.vm", description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=384)
    ap.add_argument("--runs", type=int, default=5)
    a = ap.parse_args(argv)
    settings = tracer.RenderSettings(width=a.size, height=a.size, samples=1, max_depth=0, threads=1)
    hits = a.size * a.size
    vm_time = [0.0]
    integrator = __import__("tracer.integrator.wavefront", fromlist=["shade_programs"])
    shade = integrator.shade_programs

    def timed(*args):  # the textures stage, timed around its call
        t0 = time.process_time()
        shade(*args)
        vm_time[0] += time.process_time() - t0

    integrator.shade_programs = timed
    scenes = {kind: scene(kind) for kind in ("plain", "sine", "noise")}
    for s in scenes.values():
        tracer.render(s, settings)  # warm: kernels, the program table
    best = {kind: np.inf for kind in scenes}
    stage = dict(best)
    for _ in range(a.runs):  # rounds of the three, so that the machine's load changes touch all of them alike
        for kind, s in scenes.items():
            vm_time[0] = 0.0
            t0 = time.process_time()
            tracer.render(s, settings)
            best[kind] = min(best[kind], time.process_time() - t0)
            stage[kind] = min(stage[kind], vm_time[0])
    integrator.shade_programs = shade
    kinds = op_kinds(scenes["noise"], settings, shade, a.runs)
    plain = best["plain"] * 1e9 / hits
    print(f"untextured: {plain:.0f} ns per hit (whole render, {a.size}² hits)")
    for kind in ("sine", "noise"):
        g = Graph(kind)
        g.output(material(g, kind == "noise"))
        ops = compile_graph(g).program.n_ops
        extra = (best[kind] - best["plain"]) * 1e9 / hits
        print(f"{kind}: {ops} ops, {best[kind] / best['plain']:.2f}x the untextured render, +{extra:.0f} ns per hit, "
              f"{extra / ops:.1f} ns per op; textures stage {stage[kind] * 1e9 / hits:.0f} ns per hit "
              f"({(plain + stage[kind] * 1e9 / hits) / plain:.2f}x with the untextured hit), "
              f"{stage[kind] * 1e9 / hits / ops:.1f} ns per op")

    print("noise material, ns per op by kind: " + ", ".join(f"{k} {v:.0f}" for k, v in kinds.items()))


def op_kinds(s, settings, shade, runs: int) -> dict:
    """ns per hit and per op of the stage's parts (module docstring), from one render's calls of the stage."""
    import tracer
    from tracer.integrator import wavefront as integrator
    from tracer.shading import vm

    calls = []
    integrator.shade_programs = lambda *args: (calls.append(args), shade(*args))
    try:
        tracer.render(s, settings)
    finally:
        integrator.shade_programs = shade
    hits = sum(len(c[0]) for c in calls)
    code = calls[0][8]  # shade_programs' ``code``; ``pstart`` follows

    def stage(code_, pstart=None) -> float:
        best = np.inf
        for _ in range(max(runs, 5) * 2):
            t0 = time.process_time()
            for c in calls:
                shade(*c[:8], code_, c[9] if pstart is None else pstart, *c[10:])
            best = min(best, time.process_time() - t0)
        return best * 1e9 / hits

    def nops(which) -> np.ndarray:
        out = code.copy()
        out[which(out[:, 0]), 0] = vm.OP_NOP
        return out

    def is_noise(op):
        return op == vm.OP_NOISE

    n_noise, n_ops = int(is_noise(code[:, 0]).sum()), len(code)
    full = stage(code)
    no_noise = stage(nops(is_noise))
    all_nop = stage(nops(lambda op: op >= 0))
    empty = stage(code, np.zeros_like(calls[0][9]))
    return {"per hit without a program": empty, "dispatch per op": (all_nop - empty) / n_ops,
            "arithmetic op": (no_noise - all_nop) / (n_ops - n_noise) + (all_nop - empty) / n_ops,
            "Noise op": (full - no_noise) / n_noise + (all_nop - empty) / n_ops}


if __name__ == "__main__":
    main()

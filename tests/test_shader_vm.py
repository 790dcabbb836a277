"""The shader graph compiler and VM (tracer.shading.graph / shader_compile / shader_vm): folding, the program's
shape, and each op's value against its closed form.

Values are read as pictures: an emission-only unit quad seen head-on by an orthographic camera with one sample per
pixel shows, at each pixel centre, the program's emission evaluated at that point's UV (u right, v up), so the
picture *is* the program's value there (no lights, no anti-aliasing)."""

from __future__ import annotations

import colorsys

import numpy as np
import pytest

from tracer import Camera, RenderSettings, SceneBuilder
from tracer import render
from tracer.shading import vm
from tracer.shading.compiler import add_graph, compile_graph
from tracer.shading.graph import Graph, ImageRef

N = 12
_j, _i = np.meshgrid(np.arange(N), np.arange(N))
U = (_j + 0.5) / N  # the UV of each pixel centre
V = 1.0 - (_i + 0.5) / N


def picture(build, n=N):
    """Render an emission-only quad whose emission colour is ``build(g, uv)`` (uv: the UV map's output)."""
    g = Graph("probe")
    uv = g.add("uvmap")["UV"]
    colour = build(g, uv)
    g.output(g.add("emission", {"Color": colour, "Strength": 1.0})["Emission"])
    b = SceneBuilder()
    m = add_graph(b, g)
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    b.add_mesh(v, [[0, 1, 2], [0, 2, 3]], material=m, uvs=v[:, :2], name="quad")
    b.camera = Camera.look_at((0.5, 0.5, 5), (0.5, 0.5, 0), up=(0, 1, 0), projection="orthographic",
                              horizontal_aperture=1.0, vertical_aperture=1.0)
    img = render(b.build(), RenderSettings(width=n, height=n, samples=1, max_depth=0)).rgb
    return img


def xyz(g, uv):
    """(u, v, 0) split into floats."""
    s = g.add("separate_xyz", {"Vector": uv})
    return s["X"], s["Y"]


# ---------------------------------------------------------------------------------------------- compiler
def test_a_constant_graph_compiles_to_no_program_and_its_row():
    g = Graph("c")
    mix = g.add("mix_color", {"Factor": 0.25, "A": (1, 0, 0), "B": (0, 0, 1)}, blend_type="MULTIPLY")
    rough = g.add("math", {"Value": 0.5, "Value_001": 2.0}, operation="POWER")
    g.output(g.add("principled_bsdf", {"Base Color": mix["Result"], "Roughness": rough["Value"]})["BSDF"])
    c = compile_graph(g)
    assert c.program is None
    # Cycles' MULTIPLY blend: c1·(1 − t + t·c2)
    np.testing.assert_allclose(c.row["base_color"], (0.75, 0.0, 0.0), atol=1e-7)
    assert c.row["roughness"] == pytest.approx(0.25)


def test_a_scaled_texture_is_one_lookup():
    g = Graph("t")
    tex = g.add("image_texture", image=ImageRef(pixels=np.random.default_rng(1).random((4, 4, 4), np.float32)))
    scaled = g.add("vector_math", {"Vector": tex["Color"], "Vector_001": (0.5, 0.25, 2.0)}, operation="MULTIPLY")
    g.output(g.add("principled_bsdf", {"Base Color": scaled["Vector"]})["BSDF"])
    p = compile_graph(g).program
    ops = p.code[:, 0].tolist()
    assert ops.count(vm.OP_IMAGE) == 1 and len(ops) == 2  # the UV and the lookup: the scale is in the texture
    assert np.allclose(p.textures[0].scale, (0.5, 0.25, 2.0, 1.0))


def test_nodes_no_output_reads_are_not_compiled():
    g = Graph("dead")
    g.add("noise_texture")  # never linked
    uv = g.add("uvmap")["UV"]
    x = g.add("separate_xyz", {"Vector": uv})
    unused = g.add("math", {"Value": x["X"]}, operation="SINE")  # noqa: F841
    g.output(g.add("principled_bsdf", {"Roughness": x["Y"]})["BSDF"])
    p = compile_graph(g, lambda msg: pytest.fail(msg)).program
    assert p.code[:, 0].tolist() == [vm.OP_INPUT]  # the UV only: Roughness reads its y register


def test_mix_with_transparent_is_coverage_not_darker_colour():
    g = Graph("mix")
    a = g.add("diffuse_bsdf", {"Color": (0.2, 0.4, 0.6)})
    t = g.add("transparent_bsdf")
    g.output(g.add("mix_closure", {"Fac": 0.3, "Shader": a["BSDF"], "Shader_001": t["BSDF"]})["Shader"])
    row = compile_graph(g).row
    assert row["alpha"] == pytest.approx(0.7)
    np.testing.assert_allclose(row["base_color"], (0.2, 0.4, 0.6), atol=1e-7)


def test_add_shader_sums_emission_and_mix_weights_per_hit():
    """Mix Shader by a per-hit factor: emission (1 − u)·red + u·green over the quad."""
    def build(g, uv):
        u, _v = xyz(g, uv)
        red = g.add("emission", {"Color": (1, 0, 0), "Strength": 1.0})
        green = g.add("emission", {"Color": (0, 1, 0), "Strength": 1.0})
        return g, g.add("mix_closure", {"Fac": u, "Shader": red["Emission"], "Shader_001": green["Emission"]})

    g = Graph("m")
    uv = g.add("uvmap")["UV"]
    _g, mix = build(g, uv)
    blue = g.add("emission", {"Color": (0, 0, 1), "Strength": 0.5})
    g.output(g.add("add_closure", {"Shader": mix["Shader"], "Shader_001": blue["Emission"]})["Shader"])
    b = SceneBuilder()
    m = add_graph(b, g)
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    b.add_mesh(v, [[0, 1, 2], [0, 2, 3]], material=m, uvs=v[:, :2], name="quad")
    b.camera = Camera.look_at((0.5, 0.5, 5), (0.5, 0.5, 0), up=(0, 1, 0), projection="orthographic",
                              horizontal_aperture=1.0, vertical_aperture=1.0)
    img = render(b.build(), RenderSettings(width=N, height=N, samples=1, max_depth=0)).rgb
    np.testing.assert_allclose(img[..., 0], 1 - U, atol=1e-5)
    np.testing.assert_allclose(img[..., 1], U, atol=1e-5)
    np.testing.assert_allclose(img[..., 2], 0.5, atol=1e-5)


# ---------------------------------------------------------------------------------------------- ops
MATH = {  # operation: closed form of (a, b, c), a = 4.1u − 2.013, b = 3.07v − 1.029, c = 0.3
    "ADD": lambda a, b, c: a + b, "MULTIPLY_ADD": lambda a, b, c: a * b + c,
    "DIVIDE": lambda a, b, c: np.where(b != 0, a / np.where(b != 0, b, 1), 0),
    "POWER": lambda a, b, c: np.where((a < 0) & (b != np.floor(b)), 0, np.abs(a) ** b * np.where(a < 0, (-1.0) ** b, 1)),
    "SQRT": lambda a, b, c: np.sqrt(np.maximum(a, 0)), "ABSOLUTE": lambda a, b, c: np.abs(a),
    "MINIMUM": lambda a, b, c: np.minimum(a, b), "LESS_THAN": lambda a, b, c: (a < b) * 1.0,
    "SIGN": lambda a, b, c: np.sign(a), "FLOOR": lambda a, b, c: np.floor(a), "FRACT": lambda a, b, c: a - np.floor(a),
    "MODULO": lambda a, b, c: np.fmod(a, b), "FLOORED_MODULO": lambda a, b, c: a - np.floor(a / b) * b,
    "WRAP": lambda a, b, c: a - (b - c) * np.floor((a - c) / (b - c)),
    "PINGPONG": lambda a, b, c: np.abs((((a - b) / (2 * b)) - np.floor((a - b) / (2 * b))) * 2 * b - b),
    "SINE": lambda a, b, c: np.sin(a), "ARCTAN2": lambda a, b, c: np.arctan2(a, b),
    "SMOOTH_MIN": lambda a, b, c: np.minimum(a, b) - np.maximum(c - np.abs(a - b), 0) ** 3 / c ** 2 / 6,
    "COMPARE": lambda a, b, c: (np.abs(a - b) <= c) * 1.0, "TRUNC": lambda a, b, c: np.trunc(a),
    "SNAP": lambda a, b, c: np.floor(a / b) * b, "EXPONENT": lambda a, b, c: np.exp(a),
}


@pytest.mark.parametrize("op", sorted(MATH))
def test_math_node(op):
    def build(g, uv):
        u, v = xyz(g, uv)
        a = g.add("math", {"Value": u, "Value_001": 4.1, "Value_002": -2.013}, operation="MULTIPLY_ADD")["Value"]
        b = g.add("math", {"Value": v, "Value_001": 3.07, "Value_002": -1.029}, operation="MULTIPLY_ADD")["Value"]
        x = g.add("math", {"Value": a, "Value_001": b, "Value_002": 0.3}, operation=op)["Value"]
        return g.add("combine_xyz", {"X": x, "Y": x, "Z": x})["Vector"]
    img = picture(build)
    with np.errstate(all="ignore"):
        want = MATH[op](4.1 * U - 2.013, 3.07 * V - 1.029, 0.3)
    want = np.broadcast_to(want, U.shape)
    ok = np.isfinite(want)
    np.testing.assert_allclose(img[..., 0][ok], want[ok], atol=2e-4, rtol=1e-4)


def test_vector_math_cross_dot_length_and_reflect():
    def build(g, uv):
        a = g.add("vector_math", {"Vector": uv, "Vector_001": (1, 2, 3)}, operation="CROSS_PRODUCT")["Vector"]
        d = g.add("vector_math", {"Vector": uv, "Vector_001": (0.5, -1, 2)}, operation="DOT_PRODUCT")["Value"]
        r = g.add("vector_math", {"Vector": a, "Vector_001": (0, 0, 1)}, operation="REFLECT")["Vector"]
        ln = g.add("vector_math", {"Vector": r}, operation="LENGTH")["Value"]
        x = g.add("separate_xyz", {"Vector": r})
        return g.add("combine_xyz", {"X": x["X"], "Y": d, "Z": ln})["Vector"]
    img = picture(build)
    uvw = np.stack([U, V, np.zeros_like(U)], -1)
    a = np.cross(uvw, [1, 2, 3])
    r = a - 2 * a[..., 2:3] * np.array([0, 0, 1])
    np.testing.assert_allclose(img[..., 0], r[..., 0], atol=1e-5)
    np.testing.assert_allclose(img[..., 1], uvw @ [0.5, -1, 2], atol=1e-5)
    np.testing.assert_allclose(img[..., 2], np.linalg.norm(r, axis=-1), atol=1e-5)


BLENDS = {  # Cycles' blend modes of colour 1 = (u, v, 0.5), colour 2 = (0.3, 0.8, v), factor 0.7
    "MIX": lambda a, b, t: (1 - t) * a + t * b, "MULTIPLY": lambda a, b, t: a * (1 - t + t * b),
    "SCREEN": lambda a, b, t: 1 - (1 - t + t * (1 - b)) * (1 - a), "ADD": lambda a, b, t: a + t * b,
    "SUBTRACT": lambda a, b, t: a - t * b, "DIFFERENCE": lambda a, b, t: (1 - t) * a + t * np.abs(a - b),
    "DARKEN": lambda a, b, t: (1 - t) * a + t * np.minimum(a, b),
    "LIGHTEN": lambda a, b, t: (1 - t) * a + t * np.maximum(a, b),
    "OVERLAY": lambda a, b, t: np.where(a < 0.5, a * (1 - t + 2 * t * b), 1 - (1 - t + 2 * t * (1 - b)) * (1 - a)),
    "LINEAR_LIGHT": lambda a, b, t: a + t * (2 * b - 1),
    "SOFT_LIGHT": lambda a, b, t: (1 - t) * a + t * ((1 - a) * b * a + a * (1 - (1 - b) * (1 - a))),
    "EXCLUSION": lambda a, b, t: np.maximum((1 - t) * a + t * (a + b - 2 * a * b), 0),
}


def _hsv_blend(mode):
    def f(a, b, t):
        out = np.empty_like(a)
        for idx in np.ndindex(a.shape[:-1]):
            c1, c2 = a[idx], b[idx]
            h1, s1, v1 = colorsys.rgb_to_hsv(*c1)
            h2, s2, v2 = colorsys.rgb_to_hsv(*c2)
            if mode == "HUE":
                x = np.array(colorsys.hsv_to_rgb(h2, s1, v1)) if s2 != 0 else c1
                out[idx] = (1 - t) * c1 + t * x
            elif mode == "VALUE":
                out[idx] = colorsys.hsv_to_rgb(h1, s1, (1 - t) * v1 + t * v2)
            elif mode == "SATURATION":
                out[idx] = colorsys.hsv_to_rgb(h1, (1 - t) * s1 + t * s2, v1) if s1 != 0 else c1
            else:
                x = np.array(colorsys.hsv_to_rgb(h2, s2, v1)) if s2 != 0 else c1
                out[idx] = (1 - t) * c1 + t * x
        return out
    return f


@pytest.mark.parametrize("mode", sorted(BLENDS) + ["HUE", "SATURATION", "VALUE", "COLOR"])
def test_mix_color_blend_modes(mode):
    def build(g, uv):
        u, v = xyz(g, uv)
        c1 = g.add("combine_color", {"Red": u, "Green": v, "Blue": 0.5})["Color"]
        c2 = g.add("combine_color", {"Red": 0.3, "Green": 0.8, "Blue": v})["Color"]
        return g.add("mix_color", {"Factor": 0.7, "A": c1, "B": c2}, blend_type=mode)["Result"]
    img = picture(build)
    a = np.stack([U, V, np.full_like(U, 0.5)], -1)
    b = np.stack([np.full_like(U, 0.3), np.full_like(U, 0.8), V], -1)
    want = (BLENDS.get(mode) or _hsv_blend(mode))(a, b, 0.7)
    np.testing.assert_allclose(img, want, atol=1e-5)


def test_map_range_clamp_invert_gamma_and_ramp():
    def build(g, uv):
        u, v = xyz(g, uv)
        m = g.add("map_range", {"Value": u, "From Min": 0.2, "From Max": 0.8, "To Min": 1.0, "To Max": 3.0},
                  interpolation_type="SMOOTHSTEP")["Result"]
        ramp = g.add("rgb_ramp", {"Fac": v}, ramp=[(0.25, (1, 0, 0, 1)), (0.75, (0, 0, 1, 1))])["Color"]
        sep = g.add("separate_color", {"Color": ramp})
        gam = g.add("gamma", {"Color": g.add("combine_color", {"Red": u, "Green": u, "Blue": u})["Color"],
                              "Gamma": 2.2})["Color"]
        gam_r = g.add("separate_color", {"Color": gam})["Red"]
        return g.add("combine_xyz", {"X": m, "Y": sep["Red"], "Z": gam_r})["Vector"]
    img = picture(build)
    x = np.clip((U - 0.2) / 0.6, 0, 1)
    np.testing.assert_allclose(img[..., 0], 1 + 2 * x * x * (3 - 2 * x), atol=1e-5)
    np.testing.assert_allclose(img[..., 1], np.clip((0.75 - V) / 0.5, 0, 1), atol=1e-5)
    np.testing.assert_allclose(img[..., 2], U ** 2.2, atol=1e-5)


def test_separate_color_hsv_and_hue_saturation():
    def build(g, uv):
        u, v = xyz(g, uv)
        c = g.add("combine_color", {"Red": u, "Green": v, "Blue": 0.25})["Color"]
        hsv = g.add("separate_color", {"Color": c}, color_mode="HSV")
        return g.add("combine_xyz", {"X": hsv["Red"], "Y": hsv["Green"], "Z": hsv["Blue"]})["Vector"]
    img = picture(build)
    want = np.array([colorsys.rgb_to_hsv(u, v, 0.25) for u, v in zip(U.ravel(), V.ravel())]).reshape(N, N, 3)
    np.testing.assert_allclose(img, want, atol=1e-5)


def test_checker_on_generated_coordinates_follows_cycles_rule():
    def build(g, uv):
        return g.add("checker_texture", {"Color1": (1, 1, 1), "Color2": (0, 0, 0), "Scale": 3.0})["Color"]
    img = picture(build)
    # Generated = the position within the quad's bounds (x = u, y = v; the flat z axis: 0.5, as Blender's texture
    # space of a flat mesh)
    px, py, pz = ((c * 3 + 1e-6) * 0.999999 for c in (U, V, np.full_like(U, 0.5)))
    first = (np.floor(px).astype(int) % 2 == np.floor(py).astype(int) % 2) == (np.floor(pz).astype(int) % 2 != 0)
    np.testing.assert_allclose(img[..., 0], first * 1.0, atol=1e-6)


def test_mapping_point_rotates_and_scales_the_coordinates():
    def build(g, uv):
        return g.add("mapping", {"Vector": uv, "Location": (0.1, 0.2, 0.0), "Rotation": (0, 0, np.pi / 2),
                                 "Scale": (2.0, 1.0, 1.0)})["Vector"]
    img = picture(build)
    # Point: R·(S ⊙ v) + T, R a quarter turn about z: (x, y) -> (−y, x)
    np.testing.assert_allclose(img[..., 0], -V + 0.1, atol=1e-5)
    np.testing.assert_allclose(img[..., 1], 2 * U + 0.2, atol=1e-5)


# ---------------------------------------------------------------------------------------------- procedural
def _generated():
    """The Generated coordinates of the quad's pixel centres (the flat z axis reads 0.5)."""
    return np.stack([U, V, np.full_like(U, 0.5)], -1)


def test_noise_texture_4d_reads_w_per_hit_and_its_parameters():
    from tracer.shading.procedural.noise import noise_texture_array

    def build(g, uv):
        u, _v = xyz(g, uv)
        return g.add("noise_texture", {"W": u, "Scale": 3.0, "Detail": 3.0, "Roughness": 0.6, "Distortion": 0.3},
                     noise_dimensions="4D", noise_type="RIDGED_MULTIFRACTAL")["Color"]
    img = picture(build)
    _fac, col = noise_texture_array(_generated(), U, dimensions=4, noise_type="RIDGED_MULTIFRACTAL", scale=3.0,
                                    detail=3.0, roughness=0.6, distortion=0.3)
    np.testing.assert_allclose(img, col, atol=1e-5)


def test_voronoi_outputs_and_enums():
    from tracer.shading.procedural.voronoi import voronoi_texture_array

    def build(g, uv):
        v = g.add("voronoi_texture", {"Scale": 4.0, "Randomness": 0.8}, feature="F2", distance="MANHATTAN")
        pos = g.add("separate_xyz", {"Vector": v["Position"]})
        col = g.add("separate_color", {"Color": v["Color"]})
        return g.add("combine_xyz", {"X": v["Distance"], "Y": pos["X"], "Z": col["Green"]})["Vector"]
    img = picture(build)
    want = voronoi_texture_array(_generated(), feature="F2", distance="MANHATTAN", scale=4.0, randomness=0.8)
    np.testing.assert_allclose(img[..., 0], want["Distance"], atol=1e-5)
    np.testing.assert_allclose(img[..., 1], want["Position"][..., 0], atol=1e-5)
    np.testing.assert_allclose(img[..., 2], want["Color"][..., 1], atol=1e-5)


def test_wave_magic_and_brick_factors():
    from tracer.shading.procedural.patterns import brick_array, magic_array, wave_array

    def build(g, uv):
        w = g.add("wave_texture", {"Scale": 2.0, "Distortion": 1.5}, wave_type="RINGS", rings_direction="SPHERICAL",
                  wave_profile="TRI")["Fac"]
        m = g.add("magic_texture", {"Scale": 2.0}, turbulence_depth=3)["Fac"]
        b = g.add("brick_texture", {"Scale": 3.0, "Mortar Size": 0.05}, offset=0.3)["Fac"]
        return g.add("combine_xyz", {"X": w, "Y": m, "Z": b})["Vector"]
    img = picture(build)
    p = _generated()
    np.testing.assert_allclose(img[..., 0], wave_array(p, wave_type="RINGS", rings_direction="SPHERICAL",
                                                       wave_profile="TRI", scale=2.0, distortion=1.5), atol=1e-5)
    np.testing.assert_allclose(img[..., 1], magic_array(p, turbulence_depth=3, scale=2.0).mean(-1), atol=1e-5)
    np.testing.assert_allclose(img[..., 2], brick_array(p, scale=3.0, mortar_size=0.05, offset=0.3)[1], atol=1e-5)


def test_a_texture_column_multiplies_its_constant():
    """A row of the table API (``diffuse`` × ``diffuse_texture``) runs as a program: the picture is constant ×
    texel (red halved, a grey texel per pixel)."""
    from tracer import Texture

    b = SceneBuilder()
    tex = np.random.default_rng(3).uniform(0.2, 1.0, (N, N, 3)).astype(np.float32)
    t = b.add_texture(Texture(tex))
    m = b.add_material("row", diffuse=(0.5, 1.0, 0.25), diffuse_texture=t, specular=0.0)
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    b.add_mesh(v, [[0, 1, 2], [0, 2, 3]], material=m, uvs=v[:, :2], name="quad")
    b.camera = Camera.look_at((0.5, 0.5, 5), (0.5, 0.5, 0), up=(0, 1, 0), projection="orthographic",
                              horizontal_aperture=1.0, vertical_aperture=1.0)
    b.ambient = np.ones(3, np.float32)
    img = render(b.build(), RenderSettings(width=N, height=N, samples=1, max_depth=0)).rgb
    np.testing.assert_allclose(img, tex * np.array([0.5, 1.0, 0.25], np.float32), atol=1e-5)


# ---------------------------------------------------------------------------------------------- the node table
def _branches(fn_name: str) -> list[str]:
    """The OP_* names compared with ``op`` in the if/elif chain of ``tracer.shading.vm.<fn_name>``, in order."""
    import ast
    import inspect

    tree = ast.parse(inspect.getsource(vm))
    fn = next(n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef) and n.name == fn_name)
    out = []
    for n in ast.walk(fn):
        if isinstance(n, ast.If) and isinstance(n.test, ast.Compare) and isinstance(n.test.left, ast.Name) and \
                n.test.left.id == "op" and isinstance(n.test.ops[0], ast.Eq):
            out.append(n.test.comparators[0].id)
    return sorted(set(out), key=out.index) if len(set(out)) == len(out) else out


def test_vm_dispatch_follows_the_op_table():
    """Every instruction of the node table has exactly one branch in the VM (execute, or _procedural for the
    procedural textures, numbered last from OP_NOISE), and no branch names an instruction the table lacks."""
    from tracer.shading import nodes

    main, proc = _branches("execute"), _branches("_procedural")
    assert len(main) == len(set(main)) and len(proc) == len(set(proc)), "an instruction with two branches"
    names = {f"OP_{op.name.upper()}" for op in nodes.OPS if op.name != "nop"}
    assert set(main) | set(proc) == names and not set(main) & set(proc)
    assert {nodes.OPCODE[n[3:].lower()] for n in proc} == set(range(nodes.OP_NOISE, len(nodes.OPS)))
    for k, op in enumerate(nodes.OPS):  # the names numba's branches read are the table's opcodes
        assert getattr(vm, f"OP_{op.name.upper()}", k) == k and vm.OP_NAMES[k] == op.name


def test_node_table_entries_are_whole():
    """Each node type has sockets of known kinds, its lowering (closures: the closure lowering) and a proof."""
    from tracer.shading import nodes

    closures = {n for n, t in nodes.NODE_TYPES.items() if any(s.kind == nodes.CLOSURE for s in t.outputs)}
    for name, t in nodes.NODE_TYPES.items():
        assert all(s.kind in nodes.KINDS for s in t.inputs + t.outputs), name
        assert (t.lower is None) == (name in closures or name == "material_output"), name
        assert t.proof or name == "material_output", name


def _fold_cases():
    from tracer.shading import nodes

    imms = {"math": [k | c for k in range(41) for c in (0, 256)], "vmath": list(range(29)),
            "mix_f": [0, 1], "mix_v": [0, 1], "mix_vn": [0, 1], "mix_c": [k | c for k in range(19) for c in (0, 768)],
            "sep_color": [0, 1, 2], "comb_color": [0, 1, 2], "map_range": [k | c for k in range(4) for c in (0, 256)],
            "map_range_v": [0, 1, 2, 3, 256], "clamp": [0, 1], "mapping": [0, 1, 2, 3], "ramp": [0, 1],
            "curve": [0, 1, 2], "vrotate": [0, 1, 2, 3, 4, 8, 12], "copy": [1, 3], "select": [1, 3]}
    return [(op.name, imm) for op in nodes.OPS if op.fold is not None for imm in imms.get(op.name, [0])]


def test_every_fold_matches_the_vm():
    """The compiler's constant folding (each OPS row's ``fold``) gives what the VM computes for the same
    instruction, for every instruction that folds and every mode: one-instruction programs run through the world
    stage (tracer.shading.vm.shade_directions, whose register file is left holding the results)."""
    from tracer.shading import nodes
    from tracer.shading.texture import pack_textures

    rng = np.random.default_rng(7)
    tex = pack_textures([])
    f32, i32 = np.float32, np.int32
    for name, imm in _fold_cases():
        R0 = rng.uniform(-1.5, 2.5, 96)
        R0[rng.random(96) < 0.15] = 0.0  # divisions by zero, zero vectors
        a, b, c, d, e, f = 8, 24, 40, 56, 64, 72
        if name == "ramp":
            c, R0[b:b + 16] = 4, rng.uniform(0, 1, 16)  # 4 RGBA entries
        elif name == "curve":
            R0[b:b + 3] = (-0.5, 1.5, 4.0)
            R0[b + 3:b + 3 + 16] = rng.uniform(0, 1, 16)  # 4 channels × 4 samples
            c = 4
        elif name == "blackbody":
            R0[a] = 5000.0
        elif name == "wavelength":
            R0[a] = 550.0
        o = 80
        code = np.array([[nodes.OPCODE[name], o, a, b, c, d, e, f, imm]], np.int32)
        want = R0.copy()
        nodes.OPS[nodes.OPCODE[name]].fold(want, o, a, b, c, d, e, f, imm)
        R = np.zeros_like(R0)
        out = np.zeros((1, 3))
        vm.shade_directions(code, np.array([0, 1], i32), np.zeros(1, i32), np.zeros((1, 8), i32), R0, R, 0,
                            np.array([[0.0, 0.0, 1.0]], f32), out, tex.data, tex.params,
                            (np.zeros((0, 3, 2), f32), np.zeros((0, 3), i32), False), np.zeros((0, 3, 3), f32), False,
                            np.zeros((0, 3), f32), np.zeros((0, 3), i32), np.zeros((0, 3), f32), np.zeros(0, i32),
                            np.zeros((2, 9, 4)), np.zeros((0, 3, 3)), np.zeros(0, np.bool_), np.zeros(0, i32), 0,
                            True)
        w = nodes.OPS[nodes.OPCODE[name]].width(imm)
        np.testing.assert_allclose(R[o:o + w], want[o:o + w], rtol=1e-12, atol=1e-12, err_msg=f"{name} imm={imm}")

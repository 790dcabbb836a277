"""tracer.shading.procedural against Cycles: every texture and colour function, one emission-only tile per variant.

One Blender scene holds a grid of 2 × 2 planes, one per variant, seen from above by an orthographic camera at 64 × 64
pixels a tile. Each plane's material reads Object coordinates, snaps them to its pixel's centre inside the shader
(x → (floor(32 x) + 0.5) / 32 with Math nodes, exact in float32), builds the texture's input from them, and emits
the texture's output at strength 1. So each pixel is the program's value at a coordinate known to the bit,
whatever sub-pixel position Cycles' one sample lands on (filter width 0.01 px), and discontinuous textures (cells,
bricks, checkers, white noise) are compared on both sides of every edge. Cycles renders the grid once into a linear
EXR, cached by the content hash of this file's scene code and the variant table (tests/cycles/cycles_harness.py's
``content_hash`` and cache folder); each test then compares one tile with the numpy form of the tracer's function
evaluated at the same coordinates. Bar: PSNR ≥ 60 dB on linear values (peak max(1, the tile's range)).
"""

from __future__ import annotations

import inspect
import json
import math

import numpy as np
import pytest

import cycles_harness as H

from blender_kit import scene as bs
from tracer.shading import ops as shader_ops
from tracer.shading.procedural import color, noise, patterns, voronoi

pytestmark = pytest.mark.cycles

TILE = 64  # pixels per tile side
PER_UNIT = TILE // 2  # pixels per unit of object space (planes are 2 × 2)
COLS = 16
#: The issue asks ≥ 40 dB; every variant measures ≥ 70 dB (noise at detail 15, where float32 runs out of digits;
#: the others ≥ 85 dB), and 40 dB would let a 1 % error in a noise constant through (0.982 -> 0.972 measured
#: 48-62 dB), so the bar is 60 dB.
MIN_PSNR = 60.0


# ---------------------------------------------------------------------------------------------------- coordinates
def pixel_coords():
    """The snapped object coordinates of a tile's pixel centres as Cycles' Math nodes compute them (float32):
    qx, qy (TILE, TILE), row 0 at the top; the texture's vector (qx, qy, qz) and W."""
    f = np.float32
    k = np.arange(TILE, dtype=f)
    qx = (k - f(PER_UNIT) + f(0.5)) / f(PER_UNIT)
    qy = (f(PER_UNIT - 1) - k + f(0.5)) / f(PER_UNIT)
    qx, qy = np.meshgrid(qx, qy)
    qz = qx * f(0.45) + (qy * f(-0.3) + f(0.2))
    w = qx * f(0.6) + (qy * f(0.35) + f(-0.1))
    return np.stack([qx, qy, qz], -1), w


def _math(nt, op, a, b=None, c=None, loc=(0, 0)):
    n = nt.nodes.new("ShaderNodeMath")
    n.operation = op
    n.location = loc
    for i, v in enumerate((a, b, c)):
        if v is None:
            continue
        if isinstance(v, (int, float)):
            n.inputs[i].default_value = v
        else:
            nt.links.new(v, n.inputs[i])
    return n.outputs[0]


def coordinate_sockets(nt):
    """Object coordinates -> (vector socket, W socket) of the snapped coordinate program of :func:`pixel_coords`."""
    tc = nt.nodes.new("ShaderNodeTexCoord")
    sep = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(tc.outputs["Object"], sep.inputs[0])
    q = []
    for axis in "XY":
        s = _math(nt, "MULTIPLY", sep.outputs[axis], float(PER_UNIT))
        s = _math(nt, "FLOOR", s)
        s = _math(nt, "ADD", s, 0.5)
        q.append(_math(nt, "DIVIDE", s, float(PER_UNIT)))
    # separate MULTIPLY and ADD nodes: Cycles' MULTIPLY_ADD may compile to a fused multiply-add (other bits)
    qz = _math(nt, "ADD", _math(nt, "MULTIPLY", q[0], 0.45), _math(nt, "ADD", _math(nt, "MULTIPLY", q[1], -0.3), 0.2))
    w = _math(nt, "ADD", _math(nt, "MULTIPLY", q[0], 0.6), _math(nt, "ADD", _math(nt, "MULTIPLY", q[1], 0.35), -0.1))
    comb = nt.nodes.new("ShaderNodeCombineXYZ")
    nt.links.new(q[0], comb.inputs[0])
    nt.links.new(q[1], comb.inputs[1])
    nt.links.new(qz, comb.inputs[2])
    return comb.outputs[0], w


# ---------------------------------------------------------------------------------------------------- variants
def noise_variant(dim, kind, output="Color", normalize=True, **inputs):
    props = {"noise_dimensions": f"{dim}D", "noise_type": kind, "normalize": normalize}
    base = {"Scale": 3.0, "Detail": 3.5, "Roughness": 0.55, "Lacunarity": 2.2, "Distortion": 0.0}
    if kind != "FBM":
        base["Detail"] = 2.5
    if kind in ("HYBRID_MULTIFRACTAL", "RIDGED_MULTIFRACTAL", "HETERO_TERRAIN"):
        base["Offset"] = 0.7
    if kind in ("HYBRID_MULTIFRACTAL", "RIDGED_MULTIFRACTAL"):
        base["Gain"] = 1.3
    base.update(inputs)
    return {"node": "ShaderNodeTexNoise", "props": props, "inputs": base, "output": output}


VARIANTS = {}
for _dim in (1, 2, 3, 4):
    VARIANTS[f"noise_fbm_{_dim}d"] = noise_variant(_dim, "FBM")
VARIANTS["noise_fbm_3d_unnormalized"] = noise_variant(3, "FBM", normalize=False)
VARIANTS["noise_fbm_3d_distorted"] = noise_variant(3, "FBM", Distortion=1.7)
VARIANTS["noise_fbm_2d_distorted"] = noise_variant(2, "FBM", Distortion=0.8, Detail=0.0)
VARIANTS["noise_fbm_1d_distorted"] = noise_variant(1, "FBM", Distortion=0.8, Detail=1.0)
VARIANTS["noise_fbm_4d_distorted"] = noise_variant(4, "FBM", Distortion=0.6, Detail=6.3, Roughness=0.7)
for _kind in ("MULTIFRACTAL", "HYBRID_MULTIFRACTAL", "RIDGED_MULTIFRACTAL", "HETERO_TERRAIN"):
    for _dim in (1, 2, 3, 4):
        VARIANTS[f"noise_{_kind.lower()}_{_dim}d"] = noise_variant(_dim, _kind)

VORONOI_BASE = {"Scale": 4.0, "Detail": 0.0, "Roughness": 0.5, "Lacunarity": 2.0, "Smoothness": 1.0,
                "Exponent": 0.5, "Randomness": 1.0}


def voronoi_variant(dim, feature="F1", output="Distance", metric="EUCLIDEAN", normalize=False, **inputs):
    props = {"voronoi_dimensions": f"{dim}D", "feature": feature, "distance": metric, "normalize": normalize}
    return {"node": "ShaderNodeTexVoronoi", "props": props, "inputs": {**VORONOI_BASE, **inputs}, "output": output}


for _dim in (1, 2, 3, 4):
    VARIANTS[f"voronoi_f1_{_dim}d"] = voronoi_variant(_dim)
    VARIANTS[f"voronoi_f1_{_dim}d_color"] = voronoi_variant(_dim, output="Color")
    VARIANTS[f"voronoi_f2_{_dim}d"] = voronoi_variant(_dim, "F2")
    VARIANTS[f"voronoi_smooth_f1_{_dim}d"] = voronoi_variant(_dim, "SMOOTH_F1", Smoothness=0.6)
    VARIANTS[f"voronoi_edge_{_dim}d"] = voronoi_variant(_dim, "DISTANCE_TO_EDGE")
    VARIANTS[f"voronoi_radius_{_dim}d"] = voronoi_variant(_dim, "N_SPHERE_RADIUS", output="Radius")
VARIANTS["voronoi_f1_1d_w"] = voronoi_variant(1, output="W")
VARIANTS["voronoi_f1_3d_position"] = voronoi_variant(3, output="Position", Randomness=0.7)
VARIANTS["voronoi_f1_4d_w"] = voronoi_variant(4, output="W")
VARIANTS["voronoi_f2_3d_color"] = voronoi_variant(3, "F2", output="Color")
VARIANTS["voronoi_smooth_f1_3d_color"] = voronoi_variant(3, "SMOOTH_F1", output="Color", Smoothness=0.4)
VARIANTS["voronoi_smooth_f1_2d_position"] = voronoi_variant(2, "SMOOTH_F1", output="Position")
for _metric in ("MANHATTAN", "CHEBYCHEV", "MINKOWSKI"):
    for _dim in (2, 3, 4):
        VARIANTS[f"voronoi_f1_{_dim}d_{_metric.lower()}"] = voronoi_variant(_dim, metric=_metric, Exponent=0.7)
    VARIANTS[f"voronoi_f2_3d_{_metric.lower()}"] = voronoi_variant(3, "F2", metric=_metric, Exponent=2.5)
    VARIANTS[f"voronoi_smooth_f1_2d_{_metric.lower()}"] = voronoi_variant(2, "SMOOTH_F1", metric=_metric,
                                                                         Exponent=1.5, Smoothness=0.5)
_FRACTAL = dict(Detail=2.5, Roughness=0.6, Lacunarity=2.0, Randomness=0.8)
for _feature in ("F1", "F2", "SMOOTH_F1", "DISTANCE_TO_EDGE"):
    for _norm in (False, True):
        _tag = "_normalized" if _norm else ""
        VARIANTS[f"voronoi_fractal_{_feature.lower()}_3d{_tag}"] = voronoi_variant(3, _feature, normalize=_norm,
                                                                                   **_FRACTAL)
VARIANTS["voronoi_fractal_f1_2d_color_normalized"] = voronoi_variant(2, output="Color", normalize=True, **_FRACTAL)
VARIANTS["voronoi_fractal_f1_2d_position"] = voronoi_variant(2, output="Position", **_FRACTAL)
VARIANTS["voronoi_fractal_edge_1d"] = voronoi_variant(1, "DISTANCE_TO_EDGE", normalize=True, **_FRACTAL)
VARIANTS["voronoi_fractal_f1_4d"] = voronoi_variant(4, normalize=True, **{**_FRACTAL, "Detail": 1.3})
VARIANTS["voronoi_fractal_f1_1d_lacunarity"] = voronoi_variant(1, **{**_FRACTAL, "Lacunarity": 2.7})
# edge cases: Cycles' special paths (zero roughness = one octave, smoothness 0 = F1, detail at its clamp)
VARIANTS["voronoi_fractal_f1_3d_lacunarity_color"] = voronoi_variant(3, output="Color", Detail=3.7, Roughness=0.7,
                                                                     Lacunarity=2.7, normalize=True)
VARIANTS["voronoi_fractal_roughness0"] = voronoi_variant(2, Detail=3.0, Roughness=0.0)
VARIANTS["voronoi_smooth_f1_smoothness0"] = voronoi_variant(3, "SMOOTH_F1", output="Color", Smoothness=0.0)
VARIANTS["voronoi_randomness0_edge"] = voronoi_variant(2, "DISTANCE_TO_EDGE", Randomness=0.0)
VARIANTS["noise_fbm_3d_detail15"] = noise_variant(3, "FBM", Detail=15.0, Roughness=0.6)
VARIANTS["noise_ridged_3d_roughness0"] = noise_variant(3, "RIDGED_MULTIFRACTAL", Roughness=0.0, Detail=4.0)


def tex(node, output, props=None, **inputs):
    return {"node": node, "props": props or {}, "inputs": inputs, "output": output}


for _d in ("X", "Y", "Z", "DIAGONAL"):
    VARIANTS[f"wave_bands_{_d.lower()}"] = tex("ShaderNodeTexWave", "Factor", {
        "wave_type": "BANDS", "bands_direction": _d, "wave_profile": "SIN"}, Scale=1.5)
for _d, _profile in (("X", "SAW"), ("Y", "TRI"), ("Z", "SIN"), ("SPHERICAL", "SAW")):
    VARIANTS[f"wave_rings_{_d.lower()}_{_profile.lower()}"] = tex("ShaderNodeTexWave", "Factor", {
        "wave_type": "RINGS", "rings_direction": _d, "wave_profile": _profile}, Scale=1.2)
VARIANTS["wave_bands_distorted"] = tex("ShaderNodeTexWave", "Color", {
    "wave_type": "BANDS", "bands_direction": "DIAGONAL", "wave_profile": "TRI"}, Scale=1.3, Distortion=4.0,
    Detail=3.5, **{"Detail Scale": 1.7, "Detail Roughness": 0.6, "Phase Offset": 0.8})
VARIANTS["wave_rings_distorted"] = tex("ShaderNodeTexWave", "Factor", {
    "wave_type": "RINGS", "rings_direction": "SPHERICAL", "wave_profile": "SIN"}, Scale=0.9, Distortion=7.0,
    Detail=1.0, **{"Detail Scale": 2.5, "Detail Roughness": 0.4, "Phase Offset": -1.1})
for _depth in (0, 1, 2, 4, 7, 10):
    VARIANTS[f"magic_depth{_depth}"] = tex("ShaderNodeTexMagic", "Color", {"turbulence_depth": _depth},
                                           Scale=1.7, Distortion=1.4)
VARIANTS["magic_undistorted"] = tex("ShaderNodeTexMagic", "Color", {"turbulence_depth": 4}, Scale=1.7, Distortion=0.0)
VARIANTS["magic_fac"] = tex("ShaderNodeTexMagic", "Factor", {"turbulence_depth": 3}, Scale=2.5, Distortion=0.6)
for _g in patterns.GRADIENT_TYPES:
    VARIANTS[f"gradient_{_g.lower()}"] = tex("ShaderNodeTexGradient", "Factor", {"gradient_type": _g})
_BRICK = {"Color1": (0.9, 0.3, 0.1, 1.0), "Color2": (0.2, 0.5, 0.8, 1.0), "Mortar": (0.05, 0.05, 0.1, 1.0)}
VARIANTS["brick_default"] = tex("ShaderNodeTexBrick", "Color", None, Scale=2.0, **_BRICK)
VARIANTS["brick_fac"] = tex("ShaderNodeTexBrick", "Factor", None, Scale=2.0, **{"Mortar Smooth": 0.4})
VARIANTS["brick_offset_squash"] = tex("ShaderNodeTexBrick", "Color", {
    "offset": 0.3, "offset_frequency": 3, "squash": 0.6, "squash_frequency": 2}, Scale=3.0, Bias=0.3,
    **_BRICK, **{"Mortar Size": 0.05, "Mortar Smooth": 0.7, "Brick Width": 0.7, "Row Height": 0.3})
VARIANTS["brick_sharp_mortar"] = tex("ShaderNodeTexBrick", "Color", None, Scale=1.5, Bias=-0.4,
                                     **_BRICK, **{"Mortar Size": 0.06, "Mortar Smooth": 0.0})
VARIANTS["brick_every_row"] = tex("ShaderNodeTexBrick", "Color", {"offset_frequency": 1, "squash_frequency": 3,
                                                                  "squash": 0.5}, Scale=2.5, **_BRICK)
VARIANTS["checker"] = tex("ShaderNodeTexChecker", "Color", None, Scale=3.0, Color1=(0.9, 0.2, 0.1, 1.0),
                          Color2=(0.1, 0.3, 0.7, 1.0))
VARIANTS["checker_fac"] = tex("ShaderNodeTexChecker", "Factor", None, Scale=5.5)
for _dim in (1, 2, 3, 4):
    VARIANTS[f"white_noise_{_dim}d"] = tex("ShaderNodeTexWhiteNoise", "Color", {"noise_dimensions": f"{_dim}D"})
    VARIANTS[f"white_noise_{_dim}d_value"] = tex("ShaderNodeTexWhiteNoise", "Value",
                                                 {"noise_dimensions": f"{_dim}D"})

# ---- colour nodes: small graphs over texture outputs (magic colour A, noise colour B, noise factor)
def graph(kind, output=None, **params):
    return {"graph": kind, "params": params, "output": output}


for _blend in shader_ops.BLEND_TYPES:
    VARIANTS[f"mix_{_blend.lower()}"] = graph("mix", blend=_blend, fac=None, clamp_factor=True, clamp_result=False)
VARIANTS["mix_linear_light_clamped"] = graph("mix", blend="LINEAR_LIGHT", fac=0.8, clamp_factor=True,
                                             clamp_result=True)
VARIANTS["mix_add_factor_unclamped"] = graph("mix", blend="ADD", fac=1.6, clamp_factor=False, clamp_result=False)
VARIANTS["mix_burn_constant"] = graph("mix", blend="BURN", fac=0.9, clamp_factor=True, clamp_result=False)
VARIANTS["mix_float"] = graph("mix_float", clamp_factor=True)
VARIANTS["mix_vector"] = graph("mix_vector", non_uniform=False, clamp_factor=True)
VARIANTS["mix_vector_non_uniform"] = graph("mix_vector", non_uniform=True, clamp_factor=False)
VARIANTS["hue_saturation_value"] = graph("hsv", hue=0.3, saturation=1.5, value=0.8, fac=0.9, hue_linked=False)
VARIANTS["hue_saturation_value_linked"] = graph("hsv", hue=0.0, saturation=0.6, value=1.3, fac=1.0, hue_linked=True)
for _mode in ("HSV", "HSL"):
    VARIANTS[f"separate_{_mode.lower()}"] = graph("separate", mode=_mode)
    VARIANTS[f"combine_{_mode.lower()}"] = graph("combine", mode=_mode)
VARIANTS["rgb_to_bw"] = graph("bw")
VARIANTS["blackbody"] = graph("blackbody")
VARIANTS["wavelength"] = graph("wavelength")
RAMP_STOPS = [(0.1, (0.9, 0.1, 0.05, 1.0)), (0.35, (0.1, 0.8, 0.2, 0.6)), (0.6, (0.2, 0.3, 0.95, 1.0)),
              (0.85, (0.95, 0.9, 0.1, 0.3))]
for _ipo in color.RAMP_INTERPOLATIONS:
    VARIANTS[f"ramp_{_ipo.lower()}"] = graph("ramp", "Color", interpolation=_ipo, color_mode="RGB",
                                             hue_interpolation="NEAR")
VARIANTS["ramp_linear_alpha"] = graph("ramp", "Alpha", interpolation="LINEAR", color_mode="RGB",
                                      hue_interpolation="NEAR")
for _hue in color.RAMP_HUE_INTERPOLATIONS:
    VARIANTS[f"ramp_hsv_{_hue.lower()}"] = graph("ramp", "Color", interpolation="LINEAR", color_mode="HSV",
                                                 hue_interpolation=_hue)
VARIANTS["ramp_hsl_near"] = graph("ramp", "Color", interpolation="EASE", color_mode="HSL", hue_interpolation="NEAR")
VARIANTS["ramp_hsl_far"] = graph("ramp", "Color", interpolation="LINEAR", color_mode="HSL", hue_interpolation="FAR")
VARIANTS["rgb_curves"] = graph("rgb_curves", extend="EXTRAPOLATED")
VARIANTS["rgb_curves_horizontal"] = graph("rgb_curves", extend="HORIZONTAL")
VARIANTS["vector_curves"] = graph("vector_curves", extend="EXTRAPOLATED")
VARIANTS["float_curve"] = graph("float_curve", extend="EXTRAPOLATED")


def _grey(x):
    return np.repeat(np.asarray(x)[..., None], 3, -1)


def _magic(vec):
    return patterns.magic_array(vec, turbulence_depth=2, scale=1.7, distortion=1.4)


def _noise_color(vec):
    return noise.noise_texture_array(vec, dimensions=3, scale=3.0, detail=2.0)[1]


def _noise_fac(vec):
    return noise.noise_texture_array(vec, dimensions=2, scale=2.0, detail=1.0)[0]


def ours_graph(spec, vec, w):
    kind, p = spec["graph"], spec["params"]
    f = np.float32
    if kind == "mix":
        fac = _noise_fac(vec) if p["fac"] is None else p["fac"]
        return color.mix_color_array(p["blend"], fac, _magic(vec), _noise_color(vec), p["clamp_factor"],
                                     p["clamp_result"])
    if kind == "mix_float":
        return _grey(color.mix_float_array(_noise_fac(vec) * f(3.0) + f(-1.0), _noise_fac(vec), vec[..., 0],
                                           p["clamp_factor"]))
    if kind == "mix_vector":
        fac = (_noise_color(vec) * f(3.0) + f(-1.0)) if p["non_uniform"] else _noise_fac(vec)
        return color.mix_vector_array(fac, vec, _magic(vec), p["clamp_factor"])
    if kind == "hsv":
        hue = _noise_fac(vec) if p["hue_linked"] else p["hue"]
        return color.hue_saturation_value_array(_magic(vec), hue, p["saturation"], p["value"], p["fac"])
    if kind == "separate":
        return color.convert_array(_magic(vec), f"rgb_to_{p['mode'].lower()}")
    if kind == "combine":
        return color.convert_array(_magic(vec), f"{p['mode'].lower()}_to_rgb")
    if kind == "bw":
        return _grey(color.rgb_to_bw_array(_magic(vec)))
    if kind == "blackbody":
        return color.blackbody_array(vec[..., 0] * f(6500.0) + f(6500.0))
    if kind == "wavelength":
        return color.wavelength_array(vec[..., 0] * f(220.0) + f(580.0))
    if kind == "ramp":
        table = color.color_ramp_table([s[0] for s in RAMP_STOPS], [s[1] for s in RAMP_STOPS], p["interpolation"],
                                       p["color_mode"], p["hue_interpolation"])
        fac = _noise_fac(vec) * f(1.6) + f(-0.3)
        rgba = color.color_ramp_array(fac, table, p["interpolation"] != "CONSTANT")
        return rgba[..., :3] if spec["output"] == "Color" else _grey(rgba[..., 3])
    if kind in ("rgb_curves", "vector_curves", "float_curve"):
        table, lo, hi, extrapolate = bake_curves(kind, p)
        if kind == "rgb_curves":
            return color.rgb_curves_array(_magic(vec), table, 0.85, lo, hi, extrapolate)
        if kind == "vector_curves":
            return color.rgb_curves_array(vec, table, 1.0, lo, hi, extrapolate)
        return _grey(color.float_curve_array(_noise_fac(vec), table, 0.9, lo, hi, extrapolate))
    raise ValueError(f"no numpy form for graph {kind}")


def bake_curves(kind, params):
    """The curve node of ``kind`` set up as in the Cycles scene, sampled into Cycles' table the way Blender's sync
    does it (CurveMapping.evaluate at 256 points over [min first x, max last x]); returns (table, min, max,
    extrapolate)."""
    import bpy

    mat = bpy.data.materials.new("bake")
    node = mat.node_tree.nodes.new(CURVE_NODES[kind])
    setup_curves(node, kind, params)
    cm = node.mapping
    curves = list(cm.curves)
    lo = min(c.points[0].location[0] for c in curves)
    hi = max(c.points[-1].location[0] for c in curves)
    xs = color.curve_table_points(lo, hi)
    if kind == "rgb_curves":
        rows = [[cm.evaluate(curves[k], cm.evaluate(curves[3], float(x))) for k in range(3)] for x in xs]
    else:
        rows = [[cm.evaluate(c, float(x)) for c in curves] for x in xs]
    extrapolate = cm.extend == "EXTRAPOLATED"
    bpy.data.materials.remove(mat)
    return np.asarray(rows, np.float32), lo, hi, extrapolate


def ours(spec, vec, w):
    """Our numpy function for one variant at the tile's coordinates -> (TILE, TILE, 3) linear."""
    if "graph" in spec:
        return ours_graph(spec, vec, w)
    node, props, inp = spec["node"], spec["props"], spec["inputs"]
    if node == "ShaderNodeTexNoise":
        fac, col = noise.noise_texture_array(
            vec, w, dimensions=int(props["noise_dimensions"][0]), noise_type=props["noise_type"],
            normalize=props["normalize"], scale=inp["Scale"], detail=inp["Detail"], roughness=inp["Roughness"],
            lacunarity=inp["Lacunarity"], offset=inp.get("Offset", 0.0), gain=inp.get("Gain", 1.0),
            distortion=inp["Distortion"])
        return col if spec["output"] == "Color" else _grey(fac)
    if node == "ShaderNodeTexVoronoi":
        out = voronoi.voronoi_texture_array(
            vec, w, dimensions=int(props["voronoi_dimensions"][0]), feature=props["feature"],
            distance=props["distance"], normalize=props["normalize"], scale=inp["Scale"], detail=inp["Detail"],
            roughness=inp["Roughness"], lacunarity=inp["Lacunarity"], smoothness=inp["Smoothness"],
            exponent=inp["Exponent"], randomness=inp["Randomness"])[spec["output"]]
        return out if out.ndim == 3 else _grey(out)
    if node == "ShaderNodeTexWave":
        fac = patterns.wave_array(vec, wave_type=props["wave_type"], bands_direction=props.get("bands_direction", "X"),
                                  rings_direction=props.get("rings_direction", "X"), wave_profile=props["wave_profile"],
                                  scale=inp.get("Scale", 5.0), distortion=inp.get("Distortion", 0.0),
                                  detail=inp.get("Detail", 2.0), detail_scale=inp.get("Detail Scale", 1.0),
                                  detail_roughness=inp.get("Detail Roughness", 0.5),
                                  phase_offset=inp.get("Phase Offset", 0.0))
        return _grey(fac)
    if node == "ShaderNodeTexMagic":
        col = patterns.magic_array(vec, turbulence_depth=props["turbulence_depth"], scale=inp["Scale"],
                                   distortion=inp["Distortion"])
        return col if spec["output"] == "Color" else _grey(col.mean(-1))
    if node == "ShaderNodeTexGradient":
        return _grey(patterns.gradient_array(vec, gradient_type=props["gradient_type"]))
    if node == "ShaderNodeTexBrick":
        kw = {"color1": inp.get("Color1", (0.8, 0.8, 0.8)), "color2": inp.get("Color2", (0.2, 0.2, 0.2)),
              "mortar": inp.get("Mortar", (0.0, 0.0, 0.0)), "scale": inp.get("Scale", 5.0),
              "mortar_size": inp.get("Mortar Size", 0.02), "mortar_smooth": inp.get("Mortar Smooth", 0.1),
              "bias": inp.get("Bias", 0.0), "brick_width": inp.get("Brick Width", 0.5),
              "row_height": inp.get("Row Height", 0.25), "offset": props.get("offset", 0.5),
              "offset_frequency": props.get("offset_frequency", 2), "squash": props.get("squash", 1.0),
              "squash_frequency": props.get("squash_frequency", 2)}
        col, fac = patterns.brick_array(vec, **kw)
        return col if spec["output"] == "Color" else _grey(fac)
    if node == "ShaderNodeTexChecker":
        col, fac = patterns.checker_array(vec, color1=inp.get("Color1", (0.8, 0.8, 0.8)),
                                          color2=inp.get("Color2", (0.2, 0.2, 0.2)), scale=inp.get("Scale", 5.0))
        return col if spec["output"] == "Color" else _grey(fac)
    if node == "ShaderNodeTexWhiteNoise":
        value, col = patterns.white_noise_array(vec, w, dimensions=int(props["noise_dimensions"][0]))
        return col if spec["output"] == "Color" else _grey(value)
    raise ValueError(f"no numpy form for {node}")


# ---------------------------------------------------------------------------------------------------- Cycles
CURVE_NODES = {"rgb_curves": "ShaderNodeRGBCurve", "vector_curves": "ShaderNodeVectorCurve",
               "float_curve": "ShaderNodeFloatCurve"}


def setup_curves(node, kind, params):
    """Edit the curve node's default curves (same edits for the Cycles scene and for baking ours)."""
    cm = node.mapping
    cm.extend = params["extend"]
    c = cm.curves
    if kind == "rgb_curves":
        c[3].points.new(0.4, 0.55)
        c[0].points[1].location = (1.0, 0.8)
        c[0].points.new(0.3, 0.4)
        c[2].points.new(0.6, 0.9)
        c[1].points[0].location = (0.1, 0.05)
    elif kind == "vector_curves":
        c[0].points.new(0.0, 0.3)
        c[1].points[0].location = (-1.0, -0.5)
        c[2].points.new(0.5, -0.2)
    else:
        c[0].points.new(0.3, 0.7)
        c[0].points.new(0.7, 0.2)
    cm.update()


def _texture(nt, node, vec, props=None, **inputs):
    tex = nt.nodes.new(node)
    for key, value in (props or {}).items():
        setattr(tex, key, value)
    for key, value in inputs.items():
        tex.inputs[key].default_value = value
    nt.links.new(vec, tex.inputs["Vector"])
    return tex


def _sources(nt, vec):
    """The graph inputs: magic colour (A), noise colour (B), noise factor, as ours' _magic/_noise_* compute them."""
    magic = _texture(nt, "ShaderNodeTexMagic", vec, {"turbulence_depth": 2}, Scale=1.7, Distortion=1.4)
    ncol = _texture(nt, "ShaderNodeTexNoise", vec, {"noise_dimensions": "3D"}, Scale=3.0, Detail=2.0)
    nfac = _texture(nt, "ShaderNodeTexNoise", vec, {"noise_dimensions": "2D"}, Scale=2.0, Detail=1.0)
    return magic.outputs["Color"], ncol.outputs["Color"], nfac.outputs["Factor"]


def build_graph(nt, spec, vec, w):
    """A colour-node variant's graph; returns the socket to emit."""
    kind, p = spec["graph"], spec["params"]
    a, b, fac = _sources(nt, vec)
    x = None
    if kind in ("blackbody", "wavelength"):
        sep = nt.nodes.new("ShaderNodeSeparateXYZ")
        nt.links.new(vec, sep.inputs[0])
        x = sep.outputs["X"]
    if kind == "mix":
        n = nt.nodes.new("ShaderNodeMix")
        n.data_type, n.blend_type = "RGBA", p["blend"]
        n.clamp_factor, n.clamp_result = p["clamp_factor"], p["clamp_result"]
        ins = {i.identifier: i for i in n.inputs}
        if p["fac"] is None:
            nt.links.new(fac, ins["Factor_Float"])
        else:
            ins["Factor_Float"].default_value = p["fac"]
        nt.links.new(a, ins["A_Color"])
        nt.links.new(b, ins["B_Color"])
        return next(o for o in n.outputs if o.identifier == "Result_Color")
    if kind in ("mix_float", "mix_vector"):
        n = nt.nodes.new("ShaderNodeMix")
        n.data_type = "FLOAT" if kind == "mix_float" else "VECTOR"
        n.clamp_factor = p["clamp_factor"]
        ins = {i.identifier: i for i in n.inputs}
        if kind == "mix_float":
            sep = nt.nodes.new("ShaderNodeSeparateXYZ")
            nt.links.new(vec, sep.inputs[0])
            nt.links.new(_math(nt, "ADD", _math(nt, "MULTIPLY", fac, 3.0), -1.0), ins["Factor_Float"])
            nt.links.new(fac, ins["A_Float"])
            nt.links.new(sep.outputs["X"], ins["B_Float"])
            return next(o for o in n.outputs if o.identifier == "Result_Float")
        if p["non_uniform"]:
            n.factor_mode = "NON_UNIFORM"
            vm = nt.nodes.new("ShaderNodeVectorMath")
            vm.operation = "MULTIPLY_ADD"
            nt.links.new(b, vm.inputs[0])
            vm.inputs[1].default_value = (3.0, 3.0, 3.0)
            vm.inputs[2].default_value = (-1.0, -1.0, -1.0)
            nt.links.new(vm.outputs[0], ins["Factor_Vector"])
        else:
            nt.links.new(fac, ins["Factor_Float"])
        nt.links.new(vec, ins["A_Vector"])
        nt.links.new(a, ins["B_Vector"])
        return next(o for o in n.outputs if o.identifier == "Result_Vector")
    if kind == "hsv":
        n = nt.nodes.new("ShaderNodeHueSaturation")
        n.inputs["Hue"].default_value = p["hue"]
        n.inputs["Saturation"].default_value = p["saturation"]
        n.inputs["Value"].default_value = p["value"]
        n.inputs["Fac"].default_value = p["fac"]
        if p["hue_linked"]:
            nt.links.new(fac, n.inputs["Hue"])
        nt.links.new(a, n.inputs["Color"])
        return n.outputs["Color"]
    if kind == "separate":
        n = nt.nodes.new("ShaderNodeSeparateColor")
        n.mode = p["mode"]
        nt.links.new(a, n.inputs["Color"])
        comb = nt.nodes.new("ShaderNodeCombineXYZ")
        for i in range(3):
            nt.links.new(n.outputs[i], comb.inputs[i])
        return comb.outputs[0]
    if kind == "combine":
        sep = nt.nodes.new("ShaderNodeSeparateColor")
        nt.links.new(a, sep.inputs["Color"])
        n = nt.nodes.new("ShaderNodeCombineColor")
        n.mode = p["mode"]
        for i in range(3):
            nt.links.new(sep.outputs[i], n.inputs[i])
        return n.outputs["Color"]
    if kind == "bw":
        n = nt.nodes.new("ShaderNodeRGBToBW")
        nt.links.new(a, n.inputs["Color"])
        return n.outputs["Val"]
    if kind == "blackbody":
        n = nt.nodes.new("ShaderNodeBlackbody")
        nt.links.new(_math(nt, "ADD", _math(nt, "MULTIPLY", x, 6500.0), 6500.0), n.inputs["Temperature"])
        return n.outputs["Color"]
    if kind == "wavelength":
        n = nt.nodes.new("ShaderNodeWavelength")
        nt.links.new(_math(nt, "ADD", _math(nt, "MULTIPLY", x, 220.0), 580.0), n.inputs["Wavelength"])
        return n.outputs["Color"]
    if kind == "ramp":
        n = nt.nodes.new("ShaderNodeValToRGB")
        cr = n.color_ramp
        cr.interpolation, cr.color_mode, cr.hue_interpolation = (p["interpolation"], p["color_mode"],
                                                                 p["hue_interpolation"])
        els = cr.elements
        els[0].position, els[0].color = RAMP_STOPS[0]
        els[1].position, els[1].color = RAMP_STOPS[-1]
        for pos, col in RAMP_STOPS[1:-1]:
            els.new(pos).color = col
        nt.links.new(_math(nt, "ADD", _math(nt, "MULTIPLY", fac, 1.6), -0.3), n.inputs["Fac"])
        return n.outputs[spec["output"]]
    if kind in CURVE_NODES:
        n = nt.nodes.new(CURVE_NODES[kind])
        setup_curves(n, kind, p)
        if kind == "rgb_curves":
            n.inputs["Fac"].default_value = 0.85
            nt.links.new(a, n.inputs["Color"])
        elif kind == "vector_curves":
            n.inputs["Fac"].default_value = 1.0
            nt.links.new(vec, n.inputs["Vector"])
        else:
            n.inputs["Factor"].default_value = 0.9
            nt.links.new(fac, n.inputs["Value"])
        return n.outputs[0]
    raise ValueError(f"unknown graph {kind}")


def add_texture(nt, spec, vec, w):
    """A texture variant's node; returns the socket to emit."""
    tex = nt.nodes.new(spec["node"])
    for key, value in spec["props"].items():
        setattr(tex, key, value)
    for key, value in spec["inputs"].items():
        if key in tex.inputs:  # (Blender 5 hides sockets a mode does not read; so does our function)
            tex.inputs[key].default_value = value
    if "Vector" in tex.inputs:
        nt.links.new(vec, tex.inputs["Vector"])
    if "W" in tex.inputs:
        nt.links.new(w, tex.inputs["W"])
    return tex.outputs[spec["output"]]


def build_scene(variants: dict):
    """The grid of emission tiles, one plane and material per variant, and the orthographic camera."""
    import bpy

    n = len(variants)
    rows = (n + COLS - 1) // COLS
    scene = bs.reset(size=(COLS * TILE, rows * TILE))
    for i, (name, spec) in enumerate(variants.items()):
        mat = bpy.data.materials.new(name)
        if mat.node_tree is None:  # (Blender 5 gives new materials a node tree; use_nodes is deprecated)
            mat.use_nodes = True
        nt = mat.node_tree
        nt.nodes.clear()
        vec, w = coordinate_sockets(nt)
        sock = build_graph(nt, spec, vec, w) if "graph" in spec else add_texture(nt, spec, vec, w)
        em = nt.nodes.new("ShaderNodeEmission")
        em.inputs["Strength"].default_value = 1.0
        nt.links.new(sock, em.inputs["Color"])
        out = nt.nodes.new("ShaderNodeOutputMaterial")
        nt.links.new(em.outputs[0], out.inputs["Surface"])
        row, col = divmod(i, COLS)
        bs.add_plane((2.0 * col - COLS + 1.0, rows - 1.0 - 2.0 * row, 0.0), 2.0, material=mat, name=name)
    # (sensor fit AUTO: the ortho scale spans the longer side of the image)
    bs.add_camera((0.0, 0.0, 10.0), rotation=(0.0, 0.0, 0.0), ortho_scale=2.0 * max(COLS, rows), clip_start=1.0,
                  clip_end=20.0)
    bs.set_world((0.0, 0.0, 0.0), 0.0)
    bs.set_cycles_whitted(scene, samples=1, max_depth=0)
    scene.cycles.filter_width = 0.01  # the one sample lands within 0.005 px of the pixel centre
    return scene


def _spec_key(variants):
    return json.dumps(variants, sort_keys=True)


def cycles_grid(variants: dict) -> dict:
    """name -> the Cycles tile (TILE, TILE, 3), from the reference cache or rendered now."""
    scene_code = [inspect.getsource(f) for f in (build_scene, coordinate_sockets, _math, add_texture, build_graph,
                                                 _sources, _texture, setup_curves)]
    key = H.content_hash("procedural", scene_code, TILE, COLS, RAMP_STOPS, _spec_key(variants))
    path, _, _ = H.cached_exr(f"procedural-{key}", lambda tmp: bs.render_exr(build_scene(variants), tmp),
                              ("procedural", "grid"))
    rgb = bs.read_exr(path)["rgba"][..., :3]
    tiles = {}
    for i, name in enumerate(variants):
        row, col = divmod(i, COLS)
        tiles[name] = rgb[row * TILE:(row + 1) * TILE, col * TILE:(col + 1) * TILE]
    return tiles


def psnr(ours_rgb, ref_rgb) -> float:
    """PSNR in dB of linear values, peak max(1, the reference's range)."""
    ref = np.asarray(ref_rgb, np.float64)
    mse = float(np.mean((np.asarray(ours_rgb, np.float64) - ref) ** 2))
    peak = max(1.0, float(ref.max() - ref.min()))
    return math.inf if mse == 0 else 10 * math.log10(peak * peak / mse)


@pytest.fixture(scope="module")
def grid(bpy_module_once):
    return cycles_grid(VARIANTS)


@pytest.fixture(scope="module")
def bpy_module_once():
    import bpy

    return bpy


@pytest.mark.parametrize("name", list(VARIANTS))
def test_procedural_matches_cycles(grid, name, tmp_path):
    vec, w = pixel_coords()
    mine = ours(VARIANTS[name], vec, w)
    ref = grid[name]
    db = psnr(mine, ref)
    print(f"[cycles] {name}: PSNR {db:.2f} dB, max |diff| {np.abs(mine - ref).max():.2e}")
    if db < MIN_PSNR:
        paths = H.save_comparison(str(tmp_path), name, mine, ref)
        raise AssertionError(f"{name}: PSNR {db:.2f} dB < {MIN_PSNR}; images: {', '.join(paths)}")

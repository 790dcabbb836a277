"""tracer.procedural against Cycles: every texture and colour function, one emission-only tile per variant.

One Blender scene holds a grid of 2 × 2 planes, one per variant, seen from above by an orthographic camera at 64 × 64
pixels a tile. Each plane's material reads Object coordinates, snaps them to its pixel's centre inside the shader
(x → (floor(32 x) + 0.5) / 32 with Math nodes, exact in float32), builds the texture's input from them, and emits
the texture's output at strength 1. So each pixel is the program's value at a coordinate known to the bit,
whatever sub-pixel position Cycles' one sample lands on (filter width 0.01 px), and discontinuous textures (cells,
bricks, checkers, white noise) are compared on both sides of every edge. Cycles renders the grid once into a linear
EXR, cached by the content hash of this file's scene code and the variant table (tests/cycles/cycles_harness.py's
``content_hash`` and cache folder); each test then compares one tile with the numpy form of the tracer's function
evaluated at the same coordinates. Bar: PSNR ≥ 40 dB on linear values (peak max(1, the tile's range)).
"""

from __future__ import annotations

import inspect
import json
import math
import os
import time

import numpy as np
import pytest

import cycles_harness as H

from tests import blender_support as bs
from tracer.procedural import noise, patterns, voronoi

pytestmark = pytest.mark.cycles

TILE = 64  # pixels per tile side
PER_UNIT = TILE // 2  # pixels per unit of object space (planes are 2 × 2)
COLS = 16
MIN_PSNR = 40.0


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
VARIANTS["checker"] = tex("ShaderNodeTexChecker", "Color", None, Scale=3.0, Color1=(0.9, 0.2, 0.1, 1.0),
                          Color2=(0.1, 0.3, 0.7, 1.0))
VARIANTS["checker_fac"] = tex("ShaderNodeTexChecker", "Factor", None, Scale=5.5)
for _dim in (1, 2, 3, 4):
    VARIANTS[f"white_noise_{_dim}d"] = tex("ShaderNodeTexWhiteNoise", "Color", {"noise_dimensions": f"{_dim}D"})
    VARIANTS[f"white_noise_{_dim}d_value"] = tex("ShaderNodeTexWhiteNoise", "Value",
                                                 {"noise_dimensions": f"{_dim}D"})


def _grey(x):
    return np.repeat(np.asarray(x)[..., None], 3, -1)


def ours(spec, vec, w):
    """Our numpy function for one variant at the tile's coordinates -> (TILE, TILE, 3) linear."""
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
def build_scene(variants: dict):
    """The grid of emission tiles, one plane and material per variant, and the orthographic camera."""
    import bpy

    n = len(variants)
    rows = (n + COLS - 1) // COLS
    scene = bs.reset(size=(COLS * TILE, rows * TILE))
    for i, (name, spec) in enumerate(variants.items()):
        mat = bpy.data.materials.new(name)
        mat.use_nodes = True
        nt = mat.node_tree
        nt.nodes.clear()
        vec, w = coordinate_sockets(nt)
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
        em = nt.nodes.new("ShaderNodeEmission")
        em.inputs["Strength"].default_value = 1.0
        nt.links.new(tex.outputs[spec["output"]], em.inputs["Color"])
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
    key = H.content_hash("procedural", inspect.getsource(build_scene), inspect.getsource(coordinate_sockets),
                         inspect.getsource(_math), TILE, COLS, _spec_key(variants))
    path = os.path.join(H.CACHE_DIR, f"procedural-{key}.exr")
    if not os.path.exists(path):
        os.makedirs(H.CACHE_DIR, exist_ok=True)
        scene = build_scene(variants)
        tmp = path + f".{os.getpid()}.tmp.exr"
        t0 = time.perf_counter()
        bs.render_exr(scene, tmp)
        H.CYCLES_LOG.append(("procedural", "grid", time.perf_counter() - t0, False))
        os.replace(tmp, path)
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

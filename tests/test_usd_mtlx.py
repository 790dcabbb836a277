"""MaterialX networks: the noises against Open Shading Language's own values (MaterialX's noises are ports of OSL's),
Worley and fractal noise against closed forms, and small stages (a .mtlx document referenced from USD, and networks
of ``ND_*`` shaders authored in USD as usdMtlx and Houdini write them) rendered on the standard lit quad, each pixel
checked against the node definitions' formulas (MaterialX's GLSL reference implementation)."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
from pxr import Gf, Sdf, UsdShade

import usd_material_stages as S
from test_usd_materials import N, render_stage
from tracer.shading.procedural import mx_noise as mxn

#: tools/mx_noise_reference.py: OSL's ``noise("snoise", p)``, ``cellnoise(p)`` (float and vector; 3D at p, 2D at
#: (p.x, p.y)) evaluated by OSL inside Cycles (float32 values).
OSL_REFERENCE = {
    "points": [(0.3, 0.7, 0.2), (-1.25, 2.5, 0.75), (3.7, -0.4, -2.9), (12.1, 7.3, 4.45), (-0.05, -0.95, 1.5),
               (5.5, 5.5, 5.5), (0.999, 1.001, -0.5), (-7.3, 2.2, 9.1)],
    "snoise3": [0.273712, 0.426075, 0.161198, 0.119014, -0.049298, -0.12275, -0.491, -0.192521],
    "snoise2": [0.040744, -0.499107, 0.630442, -0.419638, 0.096943, 0.0, -0.000663, 0.273147],
    "cell3": [0.6110677, 0.9262238, 0.5769418, 0.8317066, 0.1012245, 0.1179089, 0.1671972, 0.6978391],
    "vsnoise3": [[0.273712, -0.188335, 0.404861], [0.426075, -0.130273, 0.110413], [0.161198, 0.128439, -0.425116],
                 [0.119014, -0.217064, 0.100591], [-0.049298, 0.000313, 0.001589], [-0.12275, -0.36825, -0.12275],
                 [-0.491, -0.000982, -0.244026], [-0.192521, -0.345007, 0.316482]],
    "vsnoise2": [[0.040744, 0.651012, -0.30239], [-0.499107, 0.002908, -0.071232], [0.630442, -0.191022, -0.500419],
                 [-0.419638, 0.23324, 0.11473], [0.096943, 0.097557, -0.09687], [0.0, -0.3308, 0.4962],
                 [-0.000663, 0.000663, 0.00066], [0.273147, -0.383118, -0.267391]],
    "vcell3": [[0.111573, 0.3251, 0.339947], [0.893255, 0.712138, 0.124718], [0.757107, 0.318774, 0.596734],
               [0.55664, 0.147687, 0.740377], [0.530017, 0.135412, 0.588548], [0.841193, 0.847126, 0.721378],
               [0.518892, 0.043761, 0.517562], [0.384214, 0.13729, 0.473408]],
    "vcell2": [[0.611068, 0.185824, 0.041306], [0.926224, 0.747328, 0.419895], [0.665347, 0.982825, 0.623442],
               [0.870042, 0.404507, 0.27902], [0.381713, 0.101225, 0.891433], [0.392813, 0.130608, 0.068938],
               [0.8194, 0.607845, 0.434177], [0.527803, 0.68777, 0.971572]],
    "cell2": [0.8603128, 0.5628883, 0.1841555, 0.8667231, 0.978705, 0.6743922, 0.8425211, 0.916226],
}


def test_perlin_and_cell_noise_match_osl():
    """OSL's values (6 decimals of float32): a changed gradient table, fade, hash seed or scale constant (0.6616 /
    0.9820) moves every one of them."""
    ref = OSL_REFERENCE
    for k, (x, y, z) in enumerate(ref["points"]):
        assert mxn.perlin3(x, y, z) == pytest.approx(ref["snoise3"][k], abs=3e-6)
        assert mxn.perlin2(x, y) == pytest.approx(ref["snoise2"][k], abs=3e-6)
        assert mxn.cell_float(x, y, z, 3) == pytest.approx(ref["cell3"][k], abs=1e-6)
        assert mxn.cell_float(x, y, z, 2) == pytest.approx(ref["cell2"][k], abs=1e-6)
        assert mxn.perlin_vec3(x, y, z, 3) == pytest.approx(ref["vsnoise3"][k], abs=3e-6)
        assert mxn.perlin_vec3(x, y, z, 2) == pytest.approx(ref["vsnoise2"][k], abs=3e-6)
        assert mxn.cell_vec3(x, y, z, 3) == pytest.approx(ref["vcell3"][k], abs=1e-6)
        assert mxn.cell_vec3(x, y, z, 2) == pytest.approx(ref["vcell2"][k], abs=1e-6)


def test_worley_without_jitter_is_the_distance_to_the_cell_centres():
    """jitter 0 puts every feature point at its cell's centre: F1, F2, F3 are the three smallest distances to the
    lattice (i + ½, j + ½[, k + ½]); with jitter 1, F1 is at most the distance to the own cell's farthest corner."""
    rng = np.random.default_rng(7)
    for p in rng.uniform(-5, 5, (20, 3)):
        for dims in (2, 3):
            q = p if dims == 3 else np.array([p[0], p[1], 0.0])
            cells = np.array(np.meshgrid(*[np.floor(q[i]) + np.arange(-2, 3) + 0.5 for i in range(dims)])).reshape(
                dims, -1).T
            d = np.sort(np.linalg.norm(cells - q[:dims], axis=1))[:3]
            got = mxn.mx_noise(mxn.WORLEY, dims, 3, 0, q[0], q[1], q[2], 1, 1, 1, 1, 0, 3, 2, 0.5, 0.0)
            assert got[:3] == pytest.approx(tuple(d), abs=1e-9)
            f1 = mxn.mx_noise(mxn.WORLEY, dims, 1, 0, q[0], q[1], q[2], 1, 1, 1, 1, 0, 3, 2, 0.5, 1.0)[0]
            assert 0.0 <= f1 <= math.sqrt(dims)


def test_fractal_noise_is_the_octave_sum_of_perlin_noise():
    """mx_fractal3d_noise: Σ diminish^i · noise(p · lacunarity^i) over ``octaves``, amplitude applied after."""
    p = (0.37, -1.2, 2.9)
    want = sum(0.6 ** i * mxn.perlin3(*(c * 2.1 ** i for c in p)) for i in range(4))
    got = mxn.mx_noise(mxn.FRACTAL, 3, 1, 0, *p, 1.5, 1, 1, 1, 0.0, 4, 2.1, 0.6, 1.0)[0]
    assert got == pytest.approx(1.5 * want, abs=1e-12)


# ---------------------------------------------------------------- stages
NOISE_RAMP = """<?xml version="1.0"?>
<materialx version="1.39">
  <xi:include href="defs/tint.mtlx" />
  <nodegraph name="NG" fileprefix="tex/">
    <position name="pos" type="vector3" />
    <multiply name="scaled" type="vector3">
      <input name="in1" type="vector3" nodename="pos" /><input name="in2" type="float" value="3.0" />
    </multiply>
    <noise3d name="n" type="float">
      <input name="position" type="vector3" nodename="scaled" />
      <input name="amplitude" type="float" value="0.5" /><input name="pivot" type="float" value="0.5" />
    </noise3d>
    <combine2 name="uv" type="vector2">
      <input name="in1" type="float" nodename="n" /><input name="in2" type="float" value="0" />
    </combine2>
    <ramplr name="ramp" type="color3">
      <input name="valuel" type="color3" value="0.9, 0.2, 0.1" /><input name="valuer" type="color3" value="0.1, 0.3, 0.8" />
      <input name="texcoord" type="vector2" nodename="uv" />
    </ramplr>
    <image name="grey" type="color3">
      <input name="file" type="filename" value="grey.png" />
    </image>
    <tint name="tinted" type="color3">
      <input name="in" type="color3" nodename="ramp" /><input name="by" type="color3" nodename="grey" />
    </tint>
    <output name="out" type="color3" nodename="tinted" />
  </nodegraph>
  <standard_surface name="SR" type="surfaceshader">
    <input name="base" type="float" value="1" />
    <input name="base_color" type="color3" nodegraph="NG" output="out" />
    <input name="specular" type="float" value="0" />
  </standard_surface>
  <surfacematerial name="M" type="material">
    <input name="surfaceshader" type="surfaceshader" nodename="SR" />
  </surfacematerial>
</materialx>
"""

#: An included file: a custom node defined by a node graph (MaterialX resolves it; usd_io expands it).
TINT_DEFS = """<?xml version="1.0"?>
<materialx version="1.39">
  <nodedef name="ND_tint_color3" node="tint">
    <input name="in" type="color3" value="1, 1, 1" /><input name="by" type="color3" value="1, 1, 1" />
    <output name="out" type="color3" />
  </nodedef>
  <nodegraph name="NG_tint_color3" nodedef="ND_tint_color3">
    <multiply name="m" type="color3">
      <input name="in1" type="color3" interfacename="in" /><input name="in2" type="color3" interfacename="by" />
    </multiply>
    <output name="out" type="color3" nodename="m" />
  </nodegraph>
</materialx>
"""


def mtlx_stage(d: str, document: str, files: dict, tilt=(0.0, 0.0)) -> str:
    """The standard quad under the sun, bound to /Materials/M of ``m.mtlx`` (the chess set's reference)."""
    for name, text in {"m.mtlx": document, **files}.items():
        os.makedirs(os.path.dirname(os.path.join(d, name)), exist_ok=True)
        with open(os.path.join(d, name), "w") as f:
            f.write(text)
    s = S.new_stage(os.path.join(d, "scene.usda"))
    S.camera(s)
    q = S.quad(s)
    S.sun(s, tilt_deg=tilt)
    s.DefinePrim("/Materials", "Scope").GetReferences().AddReference("./m.mtlx", "/MaterialX/Materials")
    UsdShade.MaterialBindingAPI.Apply(q.GetPrim()).GetDirectBindingRel().SetTargets(["/Materials/M"])
    return S.save(s)


def test_noise_ramp_base_colour_from_a_mtlx_document(tmp_path):
    """noise3d (object position × 3, amplitude ½, pivot ½) → combine2 → ramplr → a document-defined ``tint`` node
    (XIncluded, implemented by a node graph) × an image found through its node graph's ``fileprefix``. A Lambert
    quad under a π W/m² sun at normal incidence shows its albedo: ramp(clamp(n)) × the image's grey (read raw:
    the file names no colour space)."""
    d = str(tmp_path)
    os.makedirs(os.path.join(d, "tex"))
    S.write_png(os.path.join(d, "tex", "grey.png"), np.full((4, 4, 3), 200, np.uint8))
    grey = 200 / 255.0  # no colorspace on the file: the document's working space (linear), read as is
    img, info, _ = render_stage(mtlx_stage(d, NOISE_RAMP, {"defs/tint.mtlx": TINT_DEFS}))
    assert not [w for w in info.warnings if "not supported" in w or "composition" in w], info.warnings
    P = S.pixel_points(N)
    f = np.clip(0.5 * np.vectorize(lambda x, y: mxn.perlin3(3 * x, 3 * y, 0.0))(P[..., 0], P[..., 1]) + 0.5, 0, 1)
    want = (np.array([0.9, 0.2, 0.1]) * (1 - f[..., None]) + np.array([0.1, 0.3, 0.8]) * f[..., None]) * grey
    assert np.ptp(f) > 0.3  # the noise varies across the quad
    assert np.abs(img - want).max() < 2e-3


def usd_network(d: str, build, tilt=(0.0, 0.0)) -> str:
    """The standard quad under the sun with a Material of MaterialX shaders authored in USD (as usdMtlx and Houdini
    write them): ``build(stage, node)`` wires the network and returns the Standard Surface."""
    s = S.new_stage(os.path.join(d, "scene.usda"))
    S.camera(s)
    q = S.quad(s)
    S.sun(s, tilt_deg=tilt)
    mat = UsdShade.Material.Define(s, "/Looks/M")

    def node(name, nd, out_type, **inputs):
        sh = UsdShade.Shader.Define(s, f"/Looks/M/{name}")
        sh.CreateIdAttr(nd)
        sh.CreateOutput("out", out_type)
        for k, (tname, v) in inputs.items():
            i = sh.CreateInput(k, tname)
            if isinstance(v, UsdShade.Shader):
                i.ConnectToSource(v.ConnectableAPI(), "out")
            else:
                i.Set(v)
        return sh

    surf = build(s, node)
    mat.CreateSurfaceOutput("mtlx").ConnectToSource(surf.ConnectableAPI(), "surface")
    S.bind(q, mat)
    return S.save(s)


T = Sdf.ValueTypeNames


def surface(node, **inputs):
    sh = node("SR", "ND_standard_surface_surfaceshader", T.Token, base=(T.Float, 1.0), specular=(T.Float, 0.0),
              **inputs)
    sh.CreateOutput("surface", T.Token)
    return sh


def test_one_material_s_networks_share_their_nodes(tmp_path, monkeypatch):
    """Two inputs driven by one MaterialX node: it is written once into the material's graph (one translator per
    graph, kept by the writer, tracer.shading.principled.PrincipledSurface.graph, not on the Graph object)."""
    from tracer.shading.principled import PrincipledSurface
    from usd_io import load_stage

    graphs = []
    real = PrincipledSurface.graph
    monkeypatch.setattr(PrincipledSurface, "graph", lambda *a, **k: graphs.append(real(*a, **k)) or graphs[-1])

    def build(s, node):
        n = node("n", "ND_noise3d_float", T.Float)
        c = node("c", "ND_convert_float_color3", T.Color3f, **{"in": (T.Float, n)})
        return surface(node, base_color=(T.Color3f, c), specular_roughness=(T.Float, n))

    load_stage(usd_network(str(tmp_path), build))
    g = next(g for g in graphs if any(n.type == "mx_noise" for n in g.nodes.values()))
    assert sum(n.type == "mx_noise" for n in g.nodes.values()) == 1


def test_remap_ifgreater_mask(tmp_path):
    """ifgreater(s, 0.5, red, grey) with grey = convert(remap(t, 0, 1, 0.2, 0.6)): st = ((x+1)/2, (y+1)/2) on the
    quad, so the right half is red and the left half a vertical grey ramp 0.2 + 0.4·t."""

    def build(s, node):
        uv = node("uv", "ND_texcoord_vector2", T.Float2)
        s_ = node("s", "ND_extract_vector2", T.Float, **{"in": (T.Float2, uv), "index": (T.Int, 0)})
        t_ = node("t", "ND_extract_vector2", T.Float, **{"in": (T.Float2, uv), "index": (T.Int, 1)})
        r = node("r", "ND_remap_float", T.Float, **{"in": (T.Float, t_), "outlow": (T.Float, 0.2),
                                                     "outhigh": (T.Float, 0.6)})
        g = node("g", "ND_convert_float_color3", T.Color3f, **{"in": (T.Float, r)})
        m = node("mask", "ND_ifgreater_color3", T.Color3f, value1=(T.Float, s_), value2=(T.Float, 0.5),
                 in1=(T.Color3f, Gf.Vec3f(0.8, 0.1, 0.1)), in2=(T.Color3f, g))
        return surface(node, base_color=(T.Color3f, m))

    img, info, _ = render_stage(usd_network(str(tmp_path), build))
    assert not [w for w in info.warnings if "not supported" in w], info.warnings
    st = (S.pixel_points(N) + 1) / 2
    grey = 0.2 + 0.4 * st[..., 1]
    want = np.where((st[..., 0] > 0.5)[..., None], np.array([0.8, 0.1, 0.1]), grey[..., None] * np.ones(3))
    assert np.abs(img - want).max() < 2e-3


def test_normalmap_scale_and_bump_tilt_the_normal(tmp_path):
    """A sun from +x (30° off the normal). normalmap: in = (0.8, 0.5, 0.8), scale 0.5 gives the tangent-space
    normal (0.6·0.5, 0, 0.6) (MaterialX scales x and y, not a strength blend), so n = (0.447, 0, 0.894). bump:
    height = 0.4·s (s = (x+1)/2), scale 0.5 -> N − 0.5·∇h = (−0.1, 0, 1) normalised (a height rising toward the
    light turns the normal away from it). Each pixel: albedo 0.5 × max(n·L, 0)."""
    L = np.array([math.sin(math.radians(30)), 0.0, math.cos(math.radians(30))])

    def normalmap(s, node):
        nm = node("nm", "ND_normalmap_float", T.Float3, **{"in": (T.Float3, Gf.Vec3f(0.8, 0.5, 0.8)),
                                                           "scale": (T.Float, 0.5)})
        return surface(node, base_color=(T.Color3f, Gf.Vec3f(0.5, 0.5, 0.5)), normal=(T.Float3, nm))

    def bump(s, node):
        uv = node("uv", "ND_texcoord_vector2", T.Float2)
        s_ = node("s", "ND_extract_vector2", T.Float, **{"in": (T.Float2, uv), "index": (T.Int, 0)})
        h = node("h", "ND_multiply_float", T.Float, in1=(T.Float, s_), in2=(T.Float, 0.4))
        b = node("b", "ND_bump_vector3", T.Float3, height=(T.Float, h), scale=(T.Float, 0.5))
        return surface(node, base_color=(T.Color3f, Gf.Vec3f(0.5, 0.5, 0.5)), normal=(T.Float3, b))

    for name, build, n in (("nm", normalmap, (0.3, 0.0, 0.6)), ("bump", bump, (-0.1, 0.0, 1.0))):
        d = tmp_path / name
        d.mkdir()
        img, info, _ = render_stage(usd_network(str(d), build, tilt=(0.0, 30.0)))
        assert not [w for w in info.warnings if "not supported" in w], info.warnings
        n = np.array(n) / np.linalg.norm(n)
        want = 0.5 * max(float(n @ L), 0.0)
        inner = img[4:-4, 4:-4]
        assert np.abs(inner - want).max() < 3e-3, (name, float(inner.mean()), want)


def test_a_library_node_implemented_by_a_node_graph_reads_its_files_through_the_interface(tmp_path):
    """``triplanarprojection`` is a node graph in MaterialX's standard library (switch, extract, combine2, three
    images whose ``file`` is the interface's filex/filey/filez, normal-weighted blend). On the quad (normal +Z) the
    weights are (0, 0, 1): every pixel is filez's texel (read raw: no colour space named), none of filex's or
    filey's."""
    d = str(tmp_path)
    for name, rgb in (("x.png", (200, 0, 0)), ("y.png", (0, 200, 0)), ("z.png", (40, 90, 160))):
        S.write_png(os.path.join(d, name), np.tile(np.array(rgb, np.uint8), (4, 4, 1)))

    def build(s, node):
        tri = node("tri", "ND_triplanarprojection_color3", T.Color3f, filex=(T.Asset, "./x.png"),
                   filey=(T.Asset, "./y.png"), filez=(T.Asset, "./z.png"))
        return surface(node, base_color=(T.Color3f, tri))

    img, info, _ = render_stage(usd_network(d, build))
    assert not [w for w in info.warnings if "not supported" in w or "no file" in w], info.warnings
    assert np.abs(img - np.array([40, 90, 160]) / 255.0).max() < 2e-3

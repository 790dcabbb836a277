"""Issue #32, MaterialX: the wrong pictures of MaterialX's example and test-suite materials, each pattern on a small
hand-written document (no third-party file is read), checked against closed forms of MaterialX's own definitions.

- **A coated metal keeps its colour** (the copper example: a white metal whose colour is its clear coat's
  ``coat_color``, which tints everything under the coat): seen head-on under a uniform white dome a quad shows its
  directional albedo, coat F0 + (1 − coat F0)·coat_color for a white conductor.
- **Tiled circles** (``tiledcircles``, a node-graph node of the standard library) are black and white discs on the
  quad, pixel for pixel where MaterialX's definition puts them.
- **Colour-managed constants and images** (``colorspace="acescg"`` and friends) are converted into linear
  Rec.709, MaterialX's matrices, which tests/test_colorspace.py derives from the primaries.
- **The white furnace** (the closed form the issue asks for before any change to the BSDF): a white dielectric over
  a white diffuse base and a white metal reflect all of a uniform white dome at every roughness — through the
  dome's closed-form ambient term and through its sampled texture — so nothing in the tracer's GGX loses energy.
- **Families**: glTF PBR, Disney Principled, OpenPBR's coat and ``surface_unlit`` read as MaterialX defines them,
  each input that is not rendered named in one warning.
- **What the reader reads** (the spec's own rules): filename tokens of a node definition, a node graph input's
  ``defaultgeomprop``, document-level ``<output>`` s, units (into the definition's unit or the stage's metres per
  unit; tiledimage's real-world sizes), surface inputs driven by networks that vary nowhere (folded),
  ``surface_unlit``'s transmission (MaterialX's OSL).
- **A surface over its medium** (Lama's dielectric: layer(dielectric, VDF)): its transmission rendered, checked on
  a quad under a uniform dome (a lossless interface shows 1; mixed with and layered over gold, their closed forms).
"""

from __future__ import annotations

import os

import numpy as np
import pytest
from pxr import Sdf, UsdLux, UsdShade

import usd_material_stages as S
from test_usd_materials import render_stage
from tracer import colorspace

N = 32


def write(d, name, text):
    path = os.path.join(d, name)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as f:
        f.write(text)
    return path


def document(body: str, material: str = "M", shader: str = "SR", colorspace: str = "lin_rec709") -> str:
    return f"""<?xml version="1.0"?>
<materialx version="1.39" colorspace="{colorspace}">
{body}
  <surfacematerial name="{material}" type="material">
    <input name="surfaceshader" type="surfaceshader" nodename="{shader}" />
  </surfacematerial>
</materialx>
"""


def quad_stage(d: str, doc: str, light: str = "sun", files: dict | None = None) -> str:
    """The standard quad (normal +Z, st over [0, 1]², orthographic camera looking down) bound to /Materials/M of
    ``m.mtlx``, lit by a π W/m² sun at normal incidence (``sun``: a Lambert pixel is its albedo) or a uniform white
    dome (``dome``: its colour; ``dome_tex``: a constant white lat-long texture, sampled; a pixel is the surface's
    directional albedo at normal incidence)."""
    write(d, "m.mtlx", doc)
    for name, text in (files or {}).items():
        write(d, name, text)
    s = S.new_stage(os.path.join(d, "scene.usda"))
    S.camera(s)
    q = S.quad(s)
    if light == "sun":
        S.sun(s)
    else:
        dome = UsdLux.DomeLight.Define(s, "/Dome")
        dome.CreateIntensityAttr(1.0)
        if light == "dome_tex":
            tex = os.path.join(d, "white.exr")
            _write_exr(tex, np.ones((16, 32, 3), np.float32))
            dome.CreateTextureFileAttr(Sdf.AssetPath(tex))
    s.DefinePrim("/Materials", "Scope").GetReferences().AddReference("./m.mtlx", "/MaterialX/Materials")
    UsdShade.MaterialBindingAPI.Apply(q.GetPrim()).GetDirectBindingRel().SetTargets(["/Materials/M"])
    return S.save(s)


def _write_exr(path, px):
    import OpenImageIO as oiio

    h, w = px.shape[:2]
    buf = oiio.ImageBuf(oiio.ImageSpec(w, h, 3, oiio.FLOAT))
    buf.set_pixels(oiio.ROI(0, w, 0, h), px)
    buf.write(path)


def render(path, **kw):
    img, info, _ = render_stage(path, n=kw.pop("n", N), **kw)
    return img, info.warnings


def not_supported(warnings):
    return [w for w in warnings if "not supported" in w or "not rendered" in w or "no node definition" in w
            or "dropped" in w]


# ---------------------------------------------------------------------------------------------- coat
COPPER = """  <standard_surface name="SR" type="surfaceshader">
    <input name="base" type="float" value="1" />
    <input name="base_color" type="color3" value="1, 1, 1" />
    <input name="specular" type="float" value="0" />
    <input name="specular_roughness" type="float" value="0.25" />
    <input name="metalness" type="float" value="1" />
    <input name="coat" type="float" value="1" />
    <input name="coat_color" type="color3" value="0.96467984, 0.37626296, 0.25818297" />
    <input name="coat_roughness" type="float" value="0.2" />
  </standard_surface>"""


def coated_metal_albedo(tint, coat=1.0, ior=1.5):
    """Head-on directional albedo of MaterialX's layer(coat dielectric, white conductor × mix(1, tint, coat)):
    coat·F0 + (1 − coat·F0)·mix(1, tint, coat), F0 = ((ior − 1)/(ior + 1))² (a white conductor reflects all)."""
    f0 = ((ior - 1) / (ior + 1)) ** 2
    att = (1 - coat) + coat * np.asarray(tint)
    return coat * f0 + (1 - coat * f0) * att


def test_a_coated_white_metal_takes_its_coat_colour(tmp_path):
    """standard_surface_copper: base_color white, metalness 1, specular 0, coat 1 with a copper coat_color. Before:
    the coat was dropped with its colour, a silver ball (1, 1, 1) with the warning "coat ... dropped"."""
    img, warnings = render(quad_stage(str(tmp_path), document(COPPER), light="dome"))
    want = coated_metal_albedo((0.96467984, 0.37626296, 0.25818297))
    assert np.abs(img.mean(axis=(0, 1)) - want).max() < 0.02, (img.mean(axis=(0, 1)), want)
    assert not not_supported(warnings), warnings


def test_open_pbr_coat_tints_and_reflects(tmp_path):
    """OpenPBR's coat: coat_weight 1, coat_color, coat_ior 1.6 over a white metal (base_metalness 1): the same
    layering (OpenPBR's coat absorbs by coat_color, MaterialX's open_pbr_surface node graph)."""
    body = """  <open_pbr_surface name="SR" type="surfaceshader">
    <input name="base_color" type="color3" value="1, 1, 1" />
    <input name="base_metalness" type="float" value="1" />
    <input name="specular_roughness" type="float" value="0.2" />
    <input name="coat_weight" type="float" value="1" />
    <input name="coat_color" type="color3" value="0.3, 0.6, 0.9" />
    <input name="coat_roughness" type="float" value="0.1" />
    <input name="coat_ior" type="float" value="1.6" />
  </open_pbr_surface>"""
    img, warnings = render(quad_stage(str(tmp_path), document(body), light="dome"))
    want = coated_metal_albedo((0.3, 0.6, 0.9), ior=1.6)
    assert np.abs(img.mean(axis=(0, 1)) - want).max() < 0.02, (img.mean(axis=(0, 1)), want)
    assert not not_supported(warnings), warnings


def test_an_input_that_is_not_rendered_is_named_once(tmp_path):
    """Thin-film interference is not rendered: one warning naming the input (``thin_film_thickness``)."""
    body = COPPER.replace('<input name="coat" type="float" value="1" />', '<input name="coat" type="float" value="1" />'
                          '<input name="thin_film_thickness" type="float" value="400" />')
    _img, warnings = render(quad_stage(str(tmp_path), document(body), light="dome"))
    named = [w for w in warnings if "thin_film_thickness" in w]
    assert len(named) == 1, warnings


def test_sheen_is_the_principled_sheen_layer(tmp_path):
    """Standard Surface's sheen reads as the Principled sheen (weight, colour, roughness), the tracer's sheen lobe
    over the base: a black base with a white sheen of weight 1 reflects the sheen's albedo, not black; no warning.
    Before: dropped with a warning."""
    body = """  <standard_surface name="SR" type="surfaceshader">
    <input name="base" type="float" value="1" /><input name="base_color" type="color3" value="0, 0, 0" />
    <input name="specular" type="float" value="0" />
    <input name="sheen" type="float" value="1" /><input name="sheen_color" type="color3" value="1, 1, 1" />
    <input name="sheen_roughness" type="float" value="0.5" />
  </standard_surface>"""
    img, warnings = render(quad_stage(str(tmp_path), document(body), light="dome"))
    assert 0.02 < img.mean() < 0.5, img.mean()
    assert not [w for w in warnings if "sheen" in w], warnings


# ---------------------------------------------------------------------------------------------- tiled circles
def tiled_circles(st, tiling, size, offset=(0.0, 0.0), staggered=False):
    """MaterialX's NG_tiledcircles_color3 (stdlib_ng.mtlx) on texture coordinates (..., 2)."""
    t = st * np.asarray(tiling) - np.asarray(offset)
    if not staggered:
        m = np.mod(t, 1.0) * 2 - 1
        return (np.sum(m * m, axis=-1) <= size * size).astype(float)
    x, y = t[..., 0], t[..., 1]
    dx = np.where(np.mod(y, 1.73205) > 0.866025, 0.5, 0.0)
    mx = np.mod(x + dx, 1.0)
    my = np.mod(y, 0.866025)
    r2 = (size / 2) ** 2
    inside = np.zeros(x.shape, bool)
    for cx, cy in ((mx, my), (1 - mx, my), (mx - 0.5, 0.866025 - my)):
        inside |= cx * cx + cy * cy <= r2
    return inside.astype(float)


@pytest.mark.parametrize("staggered", [False, True])
def test_tiled_circles_are_where_materialx_puts_them(tmp_path, staggered):
    """tiledcircles (uvtiling 3, size 0.8) as a Lambert quad's base colour under the sun: each pixel away from a
    disc's edge is 1 inside a disc and 0 outside. Before: a black ball, no warning."""
    body = f"""  <tiledcircles name="tc" type="color3">
    <input name="uvtiling" type="vector2" value="3, 3" />
    <input name="size" type="float" value="0.8" />
    <input name="staggered" type="boolean" value="{'true' if staggered else 'false'}" />
  </tiledcircles>
  <standard_surface name="SR" type="surfaceshader">
    <input name="base" type="float" value="1" />
    <input name="base_color" type="color3" nodename="tc" />
    <input name="specular" type="float" value="0" />
  </standard_surface>"""
    n = 64
    img, warnings = render(quad_stage(str(tmp_path), document(body)), n=n)
    st = (S.pixel_points(n) + 1) / 2
    want = tiled_circles(st, (3, 3), 0.8, staggered=staggered)
    eps = 1.0 / n  # half a pixel in st, times the tiling: pixels whose footprint a disc edge crosses
    near_edge = np.zeros(want.shape, bool)
    for dx in (-eps, 0, eps):
        for dy in (-eps, 0, eps):
            near_edge |= tiled_circles(st + (dx, dy), (3, 3), 0.8, staggered=staggered) != want
    ok = ~near_edge
    assert ok.mean() > 0.6
    assert 0.2 < want[ok].mean() < 0.9  # discs and gaps both there
    assert np.abs(img[ok].mean(axis=-1) - want[ok]).max() < 0.01
    assert not not_supported(warnings), warnings


# ---------------------------------------------------------------------------------------------- colour spaces
#: AP1 -> Rec.709 as published by the Academy (ACES' acescg_to_rec709 linear part; 6 digits).
AP1_TO_REC709_ACES = np.array([[1.705051, -0.621792, -0.083259],
                               [-0.130256, 1.140805, -0.010548],
                               [-0.024003, -0.128969, 1.152972]])


def test_an_acescg_constant_is_the_ap1_matrix_times_it():
    v = np.array([0.2, 0.5, 0.1])
    np.testing.assert_allclose(colorspace.to_lin_rec709(v, "acescg"), AP1_TO_REC709_ACES @ v, atol=2e-6)
    np.testing.assert_allclose(colorspace.to_lin_rec709(v, "lin_ap1"), AP1_TO_REC709_ACES @ v, atol=2e-6)
    np.testing.assert_allclose(colorspace.to_lin_rec709(v, "g22_ap1"), AP1_TO_REC709_ACES @ v ** 2.2, atol=2e-6)
    np.testing.assert_allclose(colorspace.to_lin_rec709(v, "lin_rec709"), v)
    assert colorspace.materialx_space("Linear Rec.2020") is None  # MaterialX's default CMS converts nothing


@pytest.mark.parametrize("where", ["input", "document"])
def test_acescg_constants_are_converted(tmp_path, where):
    """base_color (0.2, 0.5, 0.1) in ACEScg, named on the input or inherited from the document's colorspace, on a
    Lambert quad under the sun: the pixel is AP1→Rec.709 · v, not v (too dark and too saturated: ΔE ≈ 16)."""
    cs = ' colorspace="acescg"' if where == "input" else ""
    body = f"""  <standard_surface name="SR" type="surfaceshader">
    <input name="base" type="float" value="1" />
    <input name="base_color" type="color3" value="0.2, 0.5, 0.1"{cs} />
    <input name="specular" type="float" value="0" />
  </standard_surface>"""
    doc = document(body, colorspace="acescg" if where == "document" else "lin_rec709")
    img, warnings = render(quad_stage(str(tmp_path), doc))
    want = AP1_TO_REC709_ACES @ np.array([0.2, 0.5, 0.1])
    assert np.abs(img.mean(axis=(0, 1)) - want).max() < 2e-3, (img.mean(axis=(0, 1)), want)


def test_colour_spaces_in_a_node_graph_and_on_an_image(tmp_path):
    """A constant node's value in g22_ap1 (inside a node graph) times an image whose file is in ACEScg: each
    converted as MaterialX converts it (the image's texels linear AP1, read raw and put through the matrix)."""
    d = str(tmp_path)
    S.write_png(os.path.join(d, "tex.png"), np.tile(np.array([200, 180, 150], np.uint8), (4, 4, 1)))
    body = """  <nodegraph name="NG">
    <constant name="k" type="color3">
      <input name="value" type="color3" value="0.8, 0.7, 0.6" colorspace="g22_ap1" />
    </constant>
    <image name="img" type="color3"><input name="file" type="filename" value="tex.png" colorspace="acescg" /></image>
    <multiply name="m" type="color3">
      <input name="in1" type="color3" nodename="k" /><input name="in2" type="color3" nodename="img" />
    </multiply>
    <output name="out" type="color3" nodename="m" />
  </nodegraph>
  <standard_surface name="SR" type="surfaceshader">
    <input name="base" type="float" value="1" />
    <input name="base_color" type="color3" nodegraph="NG" output="out" />
    <input name="specular" type="float" value="0" />
  </standard_surface>"""
    img, warnings = render(quad_stage(d, document(body)))
    k = AP1_TO_REC709_ACES @ (np.array([0.8, 0.7, 0.6]) ** 2.2)
    tex = AP1_TO_REC709_ACES @ (np.array([200, 180, 150]) / 255.0)
    assert np.abs(img.mean(axis=(0, 1)) - k * tex).max() < 3e-3, (img.mean(axis=(0, 1)), k * tex)


def test_an_unknown_colour_space_is_named_and_left_alone(tmp_path):
    """An OCIO name MaterialX's default colour management does not know ("Linear Rec.2020"): the value as is
    (as MaterialX's own code generators leave it) and one warning naming the space."""
    body = """  <standard_surface name="SR" type="surfaceshader">
    <input name="base" type="float" value="1" />
    <input name="base_color" type="color3" value="0.2, 0.5, 0.1" colorspace="Linear Rec.2020" />
    <input name="specular" type="float" value="0" />
  </standard_surface>"""
    img, warnings = render(quad_stage(str(tmp_path), document(body)))
    assert np.abs(img.mean(axis=(0, 1)) - (0.2, 0.5, 0.1)).max() < 2e-3
    assert len([w for w in warnings if "Linear Rec.2020" in w]) == 1, warnings


# ---------------------------------------------------------------------------------------------- white furnace
def furnace_body(metal: float, rough: float, base=(1.0, 1.0, 1.0)) -> str:
    return f"""  <standard_surface name="SR" type="surfaceshader">
    <input name="base" type="float" value="1" />
    <input name="base_color" type="color3" value="{base[0]}, {base[1]}, {base[2]}" />
    <input name="metalness" type="float" value="{metal}" />
    <input name="specular" type="float" value="1" />
    <input name="specular_roughness" type="float" value="{rough}" />
  </standard_surface>"""


@pytest.mark.parametrize("light", ["dome", "dome_tex"])
@pytest.mark.parametrize("metal", [0.0, 1.0])
@pytest.mark.parametrize("rough", [0.2, 0.45, 0.7, 0.95])
def test_white_furnace(tmp_path, light, metal, rough):
    """A white dielectric over a white base, and a white metal (F0 = 1), under a uniform white dome: all the light
    comes back (1 within 1 %) at every roughness, through the dome's closed form and through its sampled texture.
    Multiple-scattering GGX is why: single scattering alone would return 0.6 of it for the metal at roughness 0.95,
    which is what Cycles' MaterialX conductor_bsdf does with plain "ggx" (tools/fidelity_mtlx.py renders its
    references with "multi_ggx")."""
    img, _w = render(quad_stage(str(tmp_path), document(furnace_body(metal, rough)), light=light), sky_samples=16)
    assert np.abs(img.mean(axis=(0, 1)) - 1.0).max() < 0.01, img.mean(axis=(0, 1))


def test_a_black_dielectric_reflects_f0_head_on(tmp_path):
    """The dielectric layer alone (black base): F0 = 0.04 for IOR 1.5 at normal incidence, at low roughness."""
    img, _w = render(quad_stage(str(tmp_path), document(furnace_body(0.0, 0.1, (0.0, 0.0, 0.0))), light="dome"))
    assert img.mean() == pytest.approx(0.04, abs=0.002)


# ---------------------------------------------------------------------------------------------- families
GLTF = """  <gltf_pbr name="SR" type="surfaceshader">
    <input name="base_color" type="color3" value="0.7, 0.3, 0.2" />
    <input name="metallic" type="float" value="{metallic}" />
    <input name="roughness" type="float" value="0.4" />
    <input name="specular" type="float" value="{specular}" />
    <input name="emissive" type="color3" value="0.05, 0.1, 0.0" />
    <input name="emissive_strength" type="float" value="2" />{extra}
  </gltf_pbr>"""


def test_gltf_pbr_reads_as_materialx_defines_it(tmp_path):
    """gltf_pbr: specular 0 leaves the diffuse base (Lambert: its colour under the sun) plus emissive ×
    emissive_strength; metallic 1 is a metal of base_color (its albedo head-on under the dome). Before: "not
    supported", grey."""
    d1, d2 = tmp_path / "diffuse", tmp_path / "metal"
    d1.mkdir()
    d2.mkdir()
    img, warnings = render(quad_stage(str(d1), document(GLTF.format(metallic=0, specular=0, extra=""))))
    assert np.abs(img.mean(axis=(0, 1)) - (np.array([0.7, 0.3, 0.2]) + (0.1, 0.2, 0.0))).max() < 3e-3
    assert not not_supported(warnings), warnings
    img, warnings = render(quad_stage(str(d2), document(GLTF.format(metallic=1, specular=1, extra="")),
                                      light="dome"))
    assert np.abs(img.mean(axis=(0, 1)) - (np.array([0.7, 0.3, 0.2]) + (0.1, 0.2, 0.0))).max() < 0.02


def test_gltf_pbr_names_what_it_does_not_render(tmp_path):
    """Iridescence and the volume (thickness) are named once each; sheen_color is rendered (the sheen layer)."""
    extra = '\n    <input name="sheen_color" type="color3" value="0.5, 0.5, 0.5" />' \
            '\n    <input name="iridescence" type="float" value="1" />' \
            '\n    <input name="thickness" type="float" value="0.5" />'
    _img, warnings = render(quad_stage(str(tmp_path), document(GLTF.format(metallic=0, specular=1, extra=extra))))
    for name in ("iridescence", "thickness"):
        assert len([w for w in warnings if name in w]) == 1, (name, warnings)
    assert not [w for w in warnings if "sheen" in w], warnings


DISNEY = """  <disney_principled name="SR" type="surfaceshader">
    <input name="baseColor" type="color3" value="0.6, 0.4, 0.1" />
    <input name="metallic" type="float" value="{metallic}" />
    <input name="roughness" type="float" value="0.3" />
    <input name="specular" type="float" value="{specular}" />
  </disney_principled>"""


def test_disney_principled_reads_as_materialx_defines_it(tmp_path):
    """disney_principled: specular 0 leaves Burley's diffuse, which head-on under a sun at normal incidence is
    Lambert (its retro-reflection factor is 1 at θ = 0); metallic 1 a metal of baseColor. The default specular 0.5
    is MaterialX's generalized_schlick with weight 0.08·specular, F0 = F90 = 1: a constant 0.04 at every angle."""
    for name, metallic, specular, light, want, tol in (
            ("diffuse", 0, 0, "sun", (0.6, 0.4, 0.1), 3e-3),
            ("metal", 1, 0.5, "dome", (0.6, 0.4, 0.1), 0.02),
            ("plastic", 0, 0.5, "dome", 0.04 + 0.96 * np.array([0.6, 0.4, 0.1]), 0.01)):
        d = tmp_path / name
        d.mkdir()
        img, warnings = render(quad_stage(str(d), document(DISNEY.format(metallic=metallic, specular=specular)),
                                          light=light))
        assert np.abs(img.mean(axis=(0, 1)) - np.asarray(want)).max() < tol, (name, img.mean(axis=(0, 1)), want)
        assert not not_supported(warnings), warnings


def test_surface_unlit_shows_its_emission(tmp_path):
    """surface_unlit: emission × emission_color, lit by nothing (the sun does not change it)."""
    body = """  <surface_unlit name="SR" type="surfaceshader">
    <input name="emission" type="float" value="0.5" />
    <input name="emission_color" type="color3" value="0.8, 0.4, 0.2" />
  </surface_unlit>"""
    img, warnings = render(quad_stage(str(tmp_path), document(body)))
    np.testing.assert_allclose(img.mean(axis=(0, 1)), (0.4, 0.2, 0.1), atol=2e-3)
    assert not not_supported(warnings), warnings


@pytest.mark.parametrize("world", ["constant", "environment"])
@pytest.mark.parametrize("rough", [0.25, 0.4, 0.7])
def test_a_sum_of_lobes_under_the_sky_is_lit_lobe_by_lobe(world, rough):
    """The white furnace on the tracer's lobe slots (what a coat writes): 0.96 × a white metal + a black-based
    dielectric lobe (F0 = 0.04) under a uniform white world reflect 0.96 + the coat's albedo ≈ 1. Before: the sky
    stage lit the one-closure blend of the lobes' parameters (metallic 0.5, a white diffuse half), 1.45 at roughness
    0.25 — as much too bright as the mirror share g(r) of the metal."""
    from tracer import Camera, Environment, RenderSettings, SceneBuilder
    from tracer import render as trace
    from tracer.shading.compiler import add_graph
    from tracer.shading.graph import Graph

    g = Graph("furnace")
    metal = g.add("principled_bsdf", {"Base Color": (1.0, 1.0, 1.0), "Metallic": 1.0, "Roughness": rough})["BSDF"]
    coat = g.add("principled_bsdf", {"Base Color": (0.0, 0.0, 0.0), "Roughness": rough})["BSDF"]
    under = g.add("mix_closure", {"Fac": 0.96, "Shader_001": metal})["Shader"]
    g.output(g.add("add_closure", {"Shader": coat, "Shader_001": under})["Shader"])
    b = SceneBuilder()
    m = add_graph(b, g, lambda *_: None)
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    b.add_mesh(v, [[0, 1, 2], [0, 2, 3]], material=m, uvs=v[:, :2], name="quad")
    if world == "constant":
        b.background = np.ones(3, np.float32)
        b.ambient = np.ones(3, np.float32)
    else:
        b.environment = Environment(np.ones((16, 32, 3), np.float32))
    b.camera = Camera.look_at((0.5, 0.5, 5), (0.5, 0.5, 0), up=(0, 1, 0), projection="orthographic",
                              horizontal_aperture=1.0, vertical_aperture=1.0)
    img = trace(b.build(), RenderSettings(width=12, height=12, samples=2, max_depth=4, sky_samples=16)).rgb
    coat = 0.04 if rough < 0.5 else 0.03  # the coat lobe's albedo head-on (F0 = 0.04; less at roughness 0.7)
    assert np.abs(img.mean(axis=(0, 1)) - (0.96 + coat)).max() < 0.01, img.mean(axis=(0, 1))


# ---------------------------------------------------------------------------------------------- pbrlib closures
def test_a_pbrlib_surface_of_layered_closures(tmp_path):
    """pbrlib's ``surface`` over layer(dielectric_bsdf R (IOR 1.5), oren_nayar_diffuse_bsdf c): head-on under a
    uniform white dome, F0 + (1 − F0)·c. Before: "not supported", the prim's display colour."""
    body = """  <dielectric_bsdf name="spec" type="BSDF">
    <input name="ior" type="float" value="1.5" />
    <input name="roughness" type="vector2" value="0.04, 0.04" />
    <input name="scatter_mode" type="string" value="R" />
  </dielectric_bsdf>
  <oren_nayar_diffuse_bsdf name="diff" type="BSDF">
    <input name="color" type="color3" value="0.2, 0.5, 0.7" />
  </oren_nayar_diffuse_bsdf>
  <layer name="lay" type="BSDF">
    <input name="top" type="BSDF" nodename="spec" /><input name="base" type="BSDF" nodename="diff" />
  </layer>
  <surface name="SR" type="surfaceshader"><input name="bsdf" type="BSDF" nodename="lay" /></surface>"""
    img, warnings = render(quad_stage(str(tmp_path), document(body), light="dome"))
    want = 0.04 + 0.96 * np.array([0.2, 0.5, 0.7])
    assert np.abs(img.mean(axis=(0, 1)) - want).max() < 0.01, (img.mean(axis=(0, 1)), want)
    assert not not_supported(warnings), warnings


def test_a_conductor_bsdf_reflects_its_normal_incidence_fresnel(tmp_path):
    """conductor_bsdf with gold's complex index: head-on it reflects ((n − 1)² + k²)/((n + 1)² + k²)."""
    n, k = np.array([0.18, 0.42, 1.37]), np.array([3.42, 2.35, 1.77])
    body = f"""  <conductor_bsdf name="au" type="BSDF">
    <input name="ior" type="color3" value="{n[0]}, {n[1]}, {n[2]}" />
    <input name="extinction" type="color3" value="{k[0]}, {k[1]}, {k[2]}" />
    <input name="roughness" type="vector2" value="0.04, 0.04" />
  </conductor_bsdf>
  <surface name="SR" type="surfaceshader"><input name="bsdf" type="BSDF" nodename="au" /></surface>"""
    img, warnings = render(quad_stage(str(tmp_path), document(body), light="dome"))
    want = ((n - 1) ** 2 + k ** 2) / ((n + 1) ** 2 + k ** 2)
    assert np.abs(img.mean(axis=(0, 1)) - want).max() < 0.01, (img.mean(axis=(0, 1)), want)
    assert not not_supported(warnings), warnings


# ---------------------------------------------------------------------------------------------- more stdlib nodes
def _screen(f, b, m):
    return m * (1 - (1 - f) * (1 - b)) + (1 - m) * b


NODES = [  # (node XML computing "x" of type color3, the closed form of MaterialX's GLSL implementation)
    ('<screen name="x" type="color3"><input name="fg" type="color3" value="0.2, 0.4, 0.6" />'
     '<input name="bg" type="color3" value="0.5, 0.5, 0.5" /><input name="mix" type="float" value="0.5" /></screen>',
     _screen(np.array([0.2, 0.4, 0.6]), 0.5, 0.5)),
    ('<difference name="x" type="color3"><input name="fg" type="color3" value="0.9, 0.1, 0.6" />'
     '<input name="bg" type="color3" value="0.5, 0.5, 0.5" /></difference>', np.array([0.4, 0.4, 0.1])),
    ('<fract name="f" type="float"><input name="in" type="float" value="2.75" /></fract>'
     '<convert name="x" type="color3"><input name="in" type="float" nodename="f" /></convert>', np.full(3, 0.75)),
    ('<rotate2d name="r" type="vector2"><input name="in" type="vector2" value="0.6, 0.2" />'
     '<input name="amount" type="float" value="90" /></rotate2d>'
     '<convert name="v" type="vector3"><input name="in" type="vector2" nodename="r" /></convert>'
     '<add name="x0" type="vector3"><input name="in1" type="vector3" nodename="v" />'
     '<input name="in2" type="vector3" value="0, 1, 0.5" /></add>'
     '<convert name="x" type="color3"><input name="in" type="vector3" nodename="x0" /></convert>',
     np.array([0.2, -0.6 + 1.0, 0.5])),  # (cos·x + sin·y, −sin·x + cos·y) at 90°, + (0, 1, 0.5)
]


@pytest.mark.parametrize("xml,want", NODES, ids=["screen", "difference", "fract", "rotate2d"])
def test_stdlib_nodes_as_materialx_defines_them(tmp_path, xml, want):
    """Nodes MaterialX's test suite uses, each through an unlit surface: the value of its GLSL implementation.
    Before: "not supported", read as 0."""
    body = f"""  <nodegraph name="NG">{xml}<output name="out" type="color3" nodename="x" /></nodegraph>
  <surface_unlit name="SR" type="surfaceshader">
    <input name="emission_color" type="color3" nodegraph="NG" output="out" />
  </surface_unlit>"""
    img, warnings = render(quad_stage(str(tmp_path), document(body)))
    np.testing.assert_allclose(img.mean(axis=(0, 1)), want, atol=2e-3)
    assert not not_supported(warnings), warnings


def test_a_switch_driven_by_a_network_selects_per_hit(tmp_path):
    """switch(which = 2·s): in1 where 2s < 1, in2 from 1 on (the left and right halves of the quad). Before: in1
    everywhere, with a warning."""
    body = """  <nodegraph name="NG">
    <texcoord name="uv" type="vector2" />
    <extract name="s" type="float"><input name="in" type="vector2" nodename="uv" /><input name="index" type="integer" value="0" /></extract>
    <multiply name="w" type="float"><input name="in1" type="float" nodename="s" /><input name="in2" type="float" value="2" /></multiply>
    <switch name="x" type="color3">
      <input name="in1" type="color3" value="0.8, 0.1, 0.1" /><input name="in2" type="color3" value="0.1, 0.1, 0.8" />
      <input name="which" type="float" nodename="w" />
    </switch>
    <output name="out" type="color3" nodename="x" />
  </nodegraph>
  <surface_unlit name="SR" type="surfaceshader"><input name="emission_color" type="color3" nodegraph="NG" output="out" />
  </surface_unlit>"""
    img, warnings = render(quad_stage(str(tmp_path), document(body)))
    np.testing.assert_allclose(img[:, : N // 2 - 1].mean(axis=(0, 1)), (0.8, 0.1, 0.1), atol=2e-3)
    np.testing.assert_allclose(img[:, N // 2 + 1:].mean(axis=(0, 1)), (0.1, 0.1, 0.8), atol=2e-3)
    assert not not_supported(warnings), warnings


@pytest.mark.parametrize("low, high", [(0.2, 0.8), (0.6, 0.4)])
def test_smoothstep_rises_from_low_to_high(tmp_path, low, high):
    """smoothstep(u, low, high) across a quad, as MaterialX's GLSL writes it (mx_smoothstep_float): 1 where u ≥ high,
    else 0 where u ≤ low, else the Hermite. With low > high (nprlib's toon shade: its rim is smoothstep(x, 0.71,
    0.69)) a rising step at high; before, Blender's Map Range made it a falling one (the toon shade's rim lit the
    whole sphere)."""
    body = f"""  <nodegraph name="NG">
    <texcoord name="uv" type="vector2" />
    <extract name="s" type="float"><input name="in" type="vector2" nodename="uv" /><input name="index" type="integer" value="0" /></extract>
    <smoothstep name="f" type="float"><input name="in" type="float" nodename="s" />
      <input name="low" type="float" value="{low}" /><input name="high" type="float" value="{high}" /></smoothstep>
    <convert name="x" type="color3"><input name="in" type="float" nodename="f" /></convert>
    <output name="out" type="color3" nodename="x" />
  </nodegraph>
  <surface_unlit name="SR" type="surfaceshader"><input name="emission_color" type="color3" nodegraph="NG" output="out" />
  </surface_unlit>"""
    img, warnings = render(quad_stage(str(tmp_path), document(body)))
    u = (np.arange(N) + 0.5) / N
    want = np.where(u >= high, 1.0, np.where(u <= low, 0.0, np.clip((u - low) / (high - low), 0, 1)))
    if low < high:
        t = np.clip((u - low) / (high - low), 0, 1)
        want = t * t * (3 - 2 * t)
    row = img[N // 2, :, 0]
    keep = np.abs(u - high) > 2.0 / N  # away from the step's own pixel
    np.testing.assert_allclose(row[keep], want[keep], atol=0.02)
    assert not not_supported(warnings), warnings


def test_a_top_level_node_reads_a_document_input(tmp_path):
    """A node outside any node graph whose input names a document-level ``<input>`` (interfacename): its value.
    Before: the input was dropped and the definition's default (white) shown."""
    doc = document("""  <input name="tint" type="color3" value="0, 0.3, 0.9" />
  <surface_unlit name="SR" type="surfaceshader"><input name="emission_color" type="color3" interfacename="tint" />
  </surface_unlit>""")
    img, _w = render(quad_stage(str(tmp_path), doc))
    np.testing.assert_allclose(img.mean(axis=(0, 1)), (0.0, 0.3, 0.9), atol=2e-3)


# ---------------------------------------------------------------------------------------------- what the reader reads
def test_a_file_named_by_tokens_of_a_node_definition(tmp_path):
    """token_graph_material: a document's own node definition carries ``<token>`` s, its node-graph implementation
    names its image ``tex/[Image_Name].[Image_Extension]``; MaterialX substitutes the definition's token values
    (spec: "Filename Substitutions") and resolves the name against the document. An unlit surface shows the image's
    constant colour. Before: "no file (its default is used)", black."""
    (tmp_path / "tex").mkdir()
    _write_exr(str(tmp_path / "tex" / "grid.exr"), np.full((4, 4, 3), (0.2, 0.6, 0.3), np.float32))
    doc = document("""  <nodedef name="ND_token" node="token_image">
    <token name="Image_Name" type="string" value="grid" />
    <token name="Image_Extension" type="string" value="exr" />
    <output name="out" type="color3" />
  </nodedef>
  <nodegraph name="NG_token" nodedef="ND_token">
    <tiledimage name="tiledimage" type="color3" nodedef="ND_tiledimage_color3">
      <input name="file" type="filename" uniform="true" value="tex/[Image_Name].[Image_Extension]" />
    </tiledimage>
    <output name="out" type="color3" nodename="tiledimage" />
  </nodegraph>
  <nodegraph name="G">
    <token_image name="t" type="color3" />
    <output name="out" type="color3" nodename="t" />
  </nodegraph>
  <surface_unlit name="SR" type="surfaceshader"><input name="emission_color" type="color3" nodegraph="G" output="out" />
  </surface_unlit>""")
    img, warnings = render(quad_stage(str(tmp_path), doc))
    np.testing.assert_allclose(img.mean(axis=(0, 1)), (0.2, 0.6, 0.3), atol=2e-3)
    assert not [w for w in warnings if "no file" in w or "not found" in w], warnings


def test_a_node_graph_input_without_a_value_reads_its_defaultgeomprop(tmp_path):
    """defaultgeomprop.mtlx: a node graph's interface input ``texcoord`` has no value but ``defaultgeomprop="UV0"``;
    MaterialX's spec: an unconnected input with no value takes that geometric property. Shown unlit as (s, t, 0),
    the quad's own texture coordinates: s grows across the columns. Before: read as 0 (black)."""
    doc = document("""  <nodegraph name="G">
    <input name="texcoord" type="vector2" defaultgeomprop="UV0" />
    <convert name="v3" type="vector3"><input name="in" type="vector2" interfacename="texcoord" /></convert>
    <convert name="c" type="color3"><input name="in" type="vector3" nodename="v3" /></convert>
    <output name="out" type="color3" nodename="c" />
  </nodegraph>
  <surface_unlit name="SR" type="surfaceshader"><input name="emission_color" type="color3" nodegraph="G" output="out" />
  </surface_unlit>""")
    img, _w = render(quad_stage(str(tmp_path), doc))
    s = (np.arange(N) + 0.5) / N
    np.testing.assert_allclose(img[..., 0].mean(axis=0), s, atol=0.02)
    np.testing.assert_allclose(sorted(img[..., 1].mean(axis=1)), s, atol=0.02)
    assert abs(img[..., 2]).max() < 1e-3


def test_an_input_reads_a_document_level_output(tmp_path):
    """multioutput_test5: a shader input with ``output="name"`` and no node or graph reads the document's
    ``<output name="name">``, which passes on a node's output (here one output of a multi-output ``separate3``).
    Unlit: emission · emission_color = 0.5 × (0.2, 0.6, 0.9). Before: both inputs unread (the defaults, white)."""
    doc = document("""  <constant name="c" type="color3"><input name="value" type="color3" value="0.2, 0.6, 0.9" /></constant>
  <separate3 name="sep" type="multioutput"><input name="in" type="color3" value="0.1, 0.5, 0.3" /></separate3>
  <output name="col" type="color3" nodename="c" />
  <output name="green" type="float" nodename="sep" output="outg" />
  <surface_unlit name="SR" type="surfaceshader">
    <input name="emission" type="float" output="green" />
    <input name="emission_color" type="color3" output="col" />
  </surface_unlit>""")
    img, warnings = render(quad_stage(str(tmp_path), doc))
    np.testing.assert_allclose(img.mean(axis=(0, 1)), (0.1, 0.3, 0.45), atol=2e-3)
    assert not not_supported(warnings), warnings


@pytest.mark.parametrize("meters_per_unit", [1.0, 0.01])
def test_values_with_units_are_converted(tmp_path, meters_per_unit):
    """texture_units, standard_surface_unit: a value with ``unit``/``unittype`` is converted (MaterialX's "Units")
    into the scene's unit for a distance (the stage's metres per unit: 25 mm is 0.025 m, or 2.5 cm) and into the
    unit the node definition declares for an angle (rotate2d's degrees: π/2 radian turns (0.6, 0.2) into (0.2,
    −0.6)). Shown unlit: (distance / 10, rotated x, rotated y + 1). Before: 25 (the number as written) and no
    turn."""
    from pxr import Usd, UsdGeom

    doc = document("""  <nodegraph name="G">
    <multiply name="d" type="float"><input name="in1" type="float" value="0.1" />
      <input name="in2" type="float" value="25" unit="millimeter" unittype="distance" /></multiply>
    <rotate2d name="r" type="vector2"><input name="in" type="vector2" value="0.6, 0.2" />
      <input name="amount" type="float" value="1.5707963" unit="radian" unittype="angle" /></rotate2d>
    <separate2 name="s" type="multioutput"><input name="in" type="vector2" nodename="r" /></separate2>
    <add name="y" type="float"><input name="in1" type="float" nodename="s" output="outy" /><input name="in2" type="float" value="1" /></add>
    <combine3 name="c" type="color3"><input name="in1" type="float" nodename="d" />
      <input name="in2" type="float" nodename="s" output="outx" /><input name="in3" type="float" nodename="y" /></combine3>
    <output name="out" type="color3" nodename="c" />
  </nodegraph>
  <surface_unlit name="SR" type="surfaceshader"><input name="emission_color" type="color3" nodegraph="G" output="out" />
  </surface_unlit>""")
    path = quad_stage(str(tmp_path), doc)
    stage = Usd.Stage.Open(path)
    UsdGeom.SetStageMetersPerUnit(stage, meters_per_unit)
    stage.Save()
    img, warnings = render(path)
    want = (0.1 * 0.025 / meters_per_unit, 0.2, -0.6 + 1.0)
    np.testing.assert_allclose(img.mean(axis=(0, 1)), want, atol=2e-3)
    assert not not_supported(warnings), warnings


def test_surface_weights_driven_by_a_uniform_network(tmp_path):
    """syntax_1_22's car paint: ``coat`` and ``coat_color`` (and, there, ``base``, ``specular``...) driven by
    node graphs of constants. A network that varies nowhere is its value (folded by the shader compiler): the
    copper's coat 0.5 × 2 and its colour through a constant node give the coated metal's closed form. Before: "coat
    driven by a network is read as 0", a silver ball."""
    body = COPPER.replace('<input name="coat" type="float" value="1" />',
                          '<input name="coat" type="float" nodegraph="W" output="coat" />')
    body = body.replace('<input name="coat_color" type="color3" value="0.96467984, 0.37626296, 0.25818297" />',
                        '<input name="coat_color" type="color3" nodegraph="W" output="tint" />')
    doc = document("""  <nodegraph name="W">
    <multiply name="m" type="float"><input name="in1" type="float" value="0.5" /><input name="in2" type="float" value="2" /></multiply>
    <constant name="c" type="color3"><input name="value" type="color3" value="0.96467984, 0.37626296, 0.25818297" /></constant>
    <output name="coat" type="float" nodename="m" />
    <output name="tint" type="color3" nodename="c" />
  </nodegraph>
""" + body)
    img, warnings = render(quad_stage(str(tmp_path), doc, light="dome"))
    want = coated_metal_albedo((0.96467984, 0.37626296, 0.25818297))
    assert np.abs(img.mean(axis=(0, 1)) - want).max() < 0.02, (img.mean(axis=(0, 1)), want)
    assert not [w for w in warnings if "driven by a network" in w], warnings


# ---------------------------------------------------------------------------------------------- a surface over a medium
GLASS = """  <dielectric_bsdf name="r" type="BSDF"><input name="ior" type="float" value="1.5" />
    <input name="roughness" type="vector2" value="0.0001, 0.0001" /><input name="scatter_mode" type="string" value="R" />
  </dielectric_bsdf>
  <dielectric_bsdf name="t" type="BSDF"><input name="ior" type="float" value="1.5" />
    <input name="roughness" type="vector2" value="0.0001, 0.0001" /><input name="scatter_mode" type="string" value="T" />
  </dielectric_bsdf>
  <anisotropic_vdf name="medium" type="VDF"><input name="absorption" type="vector3" value="0, 0, 0" /></anisotropic_vdf>
  <layer name="inside" type="BSDF"><input name="top" type="BSDF" nodename="t" /><input name="base" type="VDF" nodename="medium" /></layer>
  <layer name="glass" type="BSDF"><input name="top" type="BSDF" nodename="r" /><input name="base" type="BSDF" nodename="inside" /></layer>
  <conductor_bsdf name="au" type="BSDF">
    <input name="ior" type="color3" value="0.18, 0.42, 1.37" /><input name="extinction" type="color3" value="3.42, 2.35, 1.77" />
    <input name="roughness" type="vector2" value="0.0001, 0.0001" />
  </conductor_bsdf>
"""
AU_F0 = ((np.array([0.18, 0.42, 1.37]) - 1) ** 2 + np.array([3.42, 2.35, 1.77]) ** 2) / \
    ((np.array([0.18, 0.42, 1.37]) + 1) ** 2 + np.array([3.42, 2.35, 1.77]) ** 2)


@pytest.mark.parametrize("case", ["glass", "mix", "layer"])
def test_a_transmissive_dielectric_over_its_medium(tmp_path, case):
    """Lama's dielectric is layer(dielectric R, layer(dielectric T, anisotropic_vdf)): a surface over its interior
    medium, whose transmission is rendered (MaterialX: a T dielectric "may be layered over a VDF describing the
    surface interior"). Closed forms on a quad seen head-on under a uniform white dome:

    - *glass*: a lossless interface reflects F and transmits 1 − F of a uniform world: the pixel is 1. Before: only
      the reflection, F = 0.04 (the transmission was taken for light feeding a base that was not there).
    - *mix* (LamaMix) of gold and that glass at ½: ½·(F0(gold) + 1), by linearity.
    - *layer* (LamaLayer) of the glass over gold: its transmission is what lights the base (the spec's vertical
      layering), so the layer reflects F + (1 − F)·F0(gold) — at most 1: MaterialX's layer conserves energy when
      its layers do. (Cycles' reference renders this layer at a mean of 1.66–1.85 under a dome whose brightest
      radiance is 1: more light than falls on it, which no energy-conserving layer can reflect.)"""
    f = 0.04
    bsdf = {"glass": "glass", "mix": "m", "layer": "l"}[case]
    extra = {"glass": "",
             "mix": '<mix name="m" type="BSDF"><input name="fg" type="BSDF" nodename="glass" />'
                    '<input name="bg" type="BSDF" nodename="au" /><input name="mix" type="float" value="0.5" /></mix>',
             "layer": '<layer name="l" type="BSDF"><input name="top" type="BSDF" nodename="glass" />'
                      '<input name="base" type="BSDF" nodename="au" /></layer>'}[case]
    want = {"glass": np.ones(3), "mix": 0.5 * (AU_F0 + 1), "layer": f + (1 - f) * AU_F0}[case]
    doc = document(GLASS + extra + f'\n  <surface name="SR" type="surfaceshader"><input name="bsdf" type="BSDF" '
                                   f'nodename="{bsdf}" /></surface>')
    img, warnings = render(quad_stage(str(tmp_path), doc, light="dome"))
    assert np.abs(img.mean(axis=(0, 1)) - want).max() < 0.02, (img.mean(axis=(0, 1)), want)
    assert not [w for w in warnings if "not supported" in w], warnings


def test_an_unlit_surface_transmits_its_colour(tmp_path):
    """surface_unlit's transmission as MaterialX's OSL implementation (the ray-traced one) defines it, t =
    transmission: (1 − t)·emission·emission_color emitted, t·transmission_color of what is behind passed through.
    Over a uniform white dome with t = ½, a blue transmission and an orange emission: (0.5, 0.25, 0.5). Before:
    the transmission was an alpha of its luminance over the full emission, (1, 0.5, 0.04)."""
    body = """  <surface_unlit name="SR" type="surfaceshader">
    <input name="emission_color" type="color3" value="1, 0.5, 0" />
    <input name="transmission" type="float" value="0.5" />
    <input name="transmission_color" type="color3" value="0, 0, 1" />
  </surface_unlit>"""
    img, warnings = render(quad_stage(str(tmp_path), document(body), light="dome"))
    np.testing.assert_allclose(img.mean(axis=(0, 1)), (0.5, 0.25, 0.5), atol=5e-3)
    assert not not_supported(warnings), warnings


def test_a_uniform_network_with_an_unsupported_node_still_warns(tmp_path):
    """Folding a uniform network must not swallow what it cannot read: a node the translator does not support
    (``flake3d``, read as its default 0) inside the network that drives ``coat`` leaves the network unfolded, and
    so named in a warning (the coat's). Before the check: it folded to 0 without a word."""
    body = COPPER.replace('<input name="coat" type="float" value="1" />',
                          '<input name="coat" type="float" nodegraph="W" output="coat" />')
    doc = document("""  <nodegraph name="W">
    <flake3d name="f" type="multioutput"><input name="size" type="float" value="0.01" /></flake3d>
    <output name="coat" type="float" nodename="f" output="presence" />
  </nodegraph>
""" + body)
    _img, warnings = render(quad_stage(str(tmp_path), doc, light="dome"))
    assert [w for w in warnings if "flake3d" in w or "coat driven by a network" in w], warnings


def test_a_tiled_image_of_real_world_sizes(tmp_path):
    """tiledimage_unit: MaterialX's tiledimage looks up ((uv · uvtiling − uvoffset) / realworldimagesize) ·
    realworldtilesize (NG_tiledimage); with a 0.5 ft image and 0.5 in tiles (units converted into metres) that is
    uv / 12, the same picture as uvtiling 1/12. Before: the real-world sizes were ignored (the picture of uvtiling
    1)."""
    px = np.zeros((8, 8, 3), np.float32)
    px[..., 0] = np.linspace(0, 1, 8)[None, :]
    px[..., 1] = np.linspace(0, 1, 8)[:, None]
    _write_exr(str(tmp_path / "ramp.exr"), px)

    def doc(inputs):
        return document(f"""  <nodegraph name="G">
    <tiledimage name="t" type="color3"><input name="file" type="filename" value="ramp.exr" />{inputs}</tiledimage>
    <output name="out" type="color3" nodename="t" />
  </nodegraph>
  <surface_unlit name="SR" type="surfaceshader"><input name="emission_color" type="color3" nodegraph="G" output="out" />
  </surface_unlit>""")

    real = doc('<input name="realworldimagesize" type="vector2" value="0.5, 0.5" unit="foot" unittype="distance" />'
               '<input name="realworldtilesize" type="vector2" value="0.5, 0.5" unit="inch" unittype="distance" />')
    same = doc('<input name="uvtiling" type="vector2" value="0.0833333, 0.0833333" />')
    plain = doc("")
    imgs = []
    for k, d in enumerate((real, same, plain)):
        sub = tmp_path / str(k)
        sub.mkdir()
        _write_exr(str(sub / "ramp.exr"), px)
        imgs.append(render(quad_stage(str(sub), d))[0])
    np.testing.assert_allclose(imgs[0], imgs[1], atol=2e-3)
    assert np.abs(imgs[0] - imgs[2]).max() > 0.1


def test_a_node_instance_reads_its_definitions_default_file(tmp_path):
    """nodegraph_nodegraph: an instance of a document's own node definition that does not author its ``file``
    input reads the definition's default file (MaterialX: an unauthored input takes its nodedef's value), here
    through the implementation's interface. Before: "no file", black."""
    _write_exr(str(tmp_path / "c.exr"), np.full((4, 4, 3), (0.7, 0.2, 0.4), np.float32))
    doc = document("""  <nodedef name="ND_pic" node="pic">
    <input name="f" type="filename" uniform="true" value="c.exr" />
    <output name="out" type="color3" />
  </nodedef>
  <nodegraph name="NG_pic" nodedef="ND_pic">
    <image name="i" type="color3"><input name="file" type="filename" uniform="true" interfacename="f" /></image>
    <output name="out" type="color3" nodename="i" />
  </nodegraph>
  <nodegraph name="G"><pic name="p" type="color3" /><output name="out" type="color3" nodename="p" /></nodegraph>
  <surface_unlit name="SR" type="surfaceshader"><input name="emission_color" type="color3" nodegraph="G" output="out" />
  </surface_unlit>""")
    img, warnings = render(quad_stage(str(tmp_path), doc))
    np.testing.assert_allclose(img.mean(axis=(0, 1)), (0.7, 0.2, 0.4), atol=2e-3)
    assert not [w for w in warnings if "no file" in w], warnings


def test_a_surface_shader_inside_a_node_graph_reads_its_interface(tmp_path):
    """nodegraph_nodegraph: a material's surface shader is the output of a node graph, and the shader reads the
    graph's interface input. The shader sees that input's value (here an unlit emission colour). Before: the
    shader was written outside its graph and read its definition's default (white)."""
    doc = """<?xml version="1.0"?>
<materialx version="1.39" colorspace="lin_rec709">
  <nodegraph name="G">
    <input name="tint" type="color3" value="0.1, 0.6, 0.3" />
    <surface_unlit name="SR" type="surfaceshader"><input name="emission_color" type="color3" interfacename="tint" />
    </surface_unlit>
    <output name="out" type="surfaceshader" nodename="SR" />
  </nodegraph>
  <surfacematerial name="M" type="material">
    <input name="surfaceshader" type="surfaceshader" nodegraph="G" output="out" />
  </surfacematerial>
</materialx>
"""
    img, warnings = render(quad_stage(str(tmp_path), doc))
    np.testing.assert_allclose(img.mean(axis=(0, 1)), (0.1, 0.6, 0.3), atol=2e-3)
    assert not not_supported(warnings), warnings

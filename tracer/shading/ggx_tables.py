"""Directional-albedo tables of the GGX microfacet BRDF, for the Principled model's energy compensation and layering
(:mod:`tracer.shading.bsdf`).

The tables are integrals of the GGX model with Smith masking-shadowing, laid out (and parametrised) as Cycles lays
out its own so that the same lookups give the same numbers (Cycles ``src/app/cycles_precompute.cpp`` defines the
integrands; these values are computed here, independently, by deterministic stratified quadrature over the
distribution of visible normals: ``python -m tracer.shading.ggx_tables`` rewrites ``tracer/shading/ggx_tables_data.py``):

- ``E[mu][rough]`` (32 × 32): albedo of the single-scattering GGX BRDF without Fresnel, at view cosine mu.
- ``E_AVG[rough]`` (32): its cosine-weighted average over mu, 2∫E(mu)·mu dmu.
- ``IOR_S[z][mu][rough]`` (16 × 16 × 16): the mean, over visible normals, of the dielectric Fresnel's position
  between F0 and 1, s = (F(cos θ_h, η) − F0) / (1 − F0), for η = ior_from_F0(z⁴); a microfacet lobe with Fresnel
  F0 → F90 has albedo mix(F0, F90, s) (Cycles' generalized-Schlick estimate).
- ``FSS[z]`` (64): the cosine-weighted mean of the dielectric Fresnel reflectance, 2∫F(mu, η)·mu dmu, for
  η = ior_from_F0(z⁴) (the average single-scattering Fresnel of the energy compensation).
- ``SCHLICK_S[mu][rough]`` (16 × 16): the same for the Schlick weight (1 − cos θ_h)^p, at the two exponents between
  which Cycles' F82 metal estimate reads (p = 5·(1 − z)/z at z = 7/15 and 8/15), averaged.

Coordinates: rough = x/(n − 1) (clamped to ≥ 10⁻⁴), mu = y/(n − 1) (≥ 10⁻⁴); lookups interpolate linearly and clamp
(:func:`tracer.shading.bsdf.table2`).
"""

from __future__ import annotations

import numpy as np

SAMPLES = 128  # N×N stratified visible-normal samples per table entry


def ior_from_f0(f0):
    s = np.sqrt(np.clip(f0, 0.0, 0.99))
    return (1.0 + s) / (1.0 - s)


def _lambda(alpha2, cos):
    cos2 = np.clip(cos * cos, 1e-30, 1.0)
    return 0.5 * (np.sqrt(1.0 + alpha2 * np.maximum(1.0 / cos2 - 1.0, 0.0)) - 1.0)


def visible_normals(alpha, mu, n=SAMPLES, floor=0.0):
    """(wi, h): a view direction of cosine mu and n × n stratified GGX visible normals h (N, 3) of it (Heitz 2018);
    ``floor`` bounds the normals' z from below (the glass tables keep it off 0)."""
    wi = np.array([np.sqrt(max(0.0, 1.0 - mu * mu)), 0.0, mu])
    v = np.array([alpha * wi[0], alpha * wi[1], wi[2]])
    v /= np.linalg.norm(v)
    lensq = v[0] ** 2 + v[1] ** 2
    t1 = np.array([-v[1], v[0], 0.0]) / np.sqrt(lensq) if lensq > 1e-7 else np.array([1.0, 0.0, 0.0])
    t2 = np.cross(v, t1)
    g = (np.arange(n) + 0.5) / n
    u1, u2 = np.meshgrid(g, g, indexing="ij")
    r, phi = np.sqrt(u1.ravel()), 2 * np.pi * u2.ravel()
    tx, ty = r * np.cos(phi), r * np.sin(phi)
    ty = (1 - 0.5 * (1 + v[2])) * np.sqrt(np.maximum(0.0, 1 - tx * tx)) + 0.5 * (1 + v[2]) * ty
    tz = np.sqrt(np.maximum(0.0, 1 - tx * tx - ty * ty))
    h_ = tx[:, None] * t1 + ty[:, None] * t2 + tz[:, None] * v
    h = np.stack([alpha * h_[:, 0], alpha * h_[:, 1], np.maximum(floor, h_[:, 2])], axis=1)
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    return wi, h


def _vndf(alpha, mu, n=SAMPLES):
    """Stratified visible normals of a view direction with cosine mu (Heitz 2018): (cos θ_h·i = wi·h, wo_z, wi_z)."""
    wi, h = visible_normals(alpha, mu, n)
    cos_hi = h @ wi
    wo_z = 2 * cos_hi * h[:, 2] - wi[2]
    return cos_hi, wo_z, wi[2]


def _fresnel(cos_i, eta):
    """Unpolarised dielectric Fresnel reflectance (1 under total internal reflection)."""
    c = np.abs(cos_i)
    g2 = eta * eta - 1 + c * c
    g = np.sqrt(np.maximum(g2, 0.0))
    a = (g - c) / (g + c)
    b = (c * (g + c) - 1) / (c * (g - c) + 1)
    return np.where(g2 > 0, 0.5 * a * a * (1 + b * b), 1.0)


def _coord(i, n, lo=1e-4, hi=1.0):
    return min(max(i / (n - 1), lo), hi)


def compute():
    """All tables as a dict of float32 arrays."""
    E = np.zeros((32, 32))
    for y in range(32):
        for x in range(32):
            rough, mu = _coord(x, 32), _coord(y, 32)
            a2 = rough**4
            cos_hi, wo_z, wi_z = _vndf(rough * rough, mu)
            ok = wo_z > 0
            g = (1 + _lambda(a2, wi_z)) / (1 + _lambda(a2, wi_z) + _lambda(a2, np.where(ok, wo_z, 1.0)))
            E[y, x] = np.where(ok, g, 0.0).mean()
    E = np.clip(E, 0, 1)
    # cosine-weighted mean over mu, by Gauss-Legendre quadrature of the same integrand
    nodes, weights = np.polynomial.legendre.leggauss(48)
    mus, wts = 0.5 * (nodes + 1), 0.5 * weights
    E_avg = np.zeros(32)
    for x in range(32):
        rough = _coord(x, 32)
        a2 = rough**4
        acc = 0.0
        for mu, w in zip(mus, wts):
            cos_hi, wo_z, wi_z = _vndf(rough * rough, mu, 64)
            ok = wo_z > 0
            g = (1 + _lambda(a2, wi_z)) / (1 + _lambda(a2, wi_z) + _lambda(a2, np.where(ok, wo_z, 1.0)))
            acc += w * 2 * mu * np.where(ok, g, 0.0).mean()
        E_avg[x] = acc
    E_avg = np.clip(E_avg, 0, 1)

    ior_s = np.zeros((16, 16, 16))
    schlick = np.zeros((16, 16))
    etas = [ior_from_f0(_coord(z, 16, 1e-4, 0.99) ** 4) for z in range(16)]
    exps = [5.0 * (1 - z) / z for z in (7 / 15, 8 / 15)]
    for y in range(16):
        for x in range(16):
            rough, mu = _coord(x, 16), _coord(y, 16)
            cos_hi, wo_z, _ = _vndf(rough * rough, mu)
            ok = wo_z > 0
            for z, eta in enumerate(etas):
                f0 = ((eta - 1) / (eta + 1)) ** 2
                s = np.clip((_fresnel(cos_hi, eta) - f0) / (1 - f0), 0, 1)
                ior_s[z, y, x] = np.where(ok, s, 0.0).mean()
            schlick[y, x] = np.mean([np.where(ok, np.clip(1 - cos_hi, 0, 1) ** p, 0.0).mean() for p in exps])
    fss = np.array([np.sum(wts * 2 * mus * _fresnel(mus, ior_from_f0(_coord(z, 64, 1e-4, 0.99) ** 4)))
                    for z in range(64)])
    return {"E": E.astype(np.float32), "E_AVG": E_avg.astype(np.float32), "FSS": fss.astype(np.float32),
            "IOR_S": np.clip(ior_s, 0, 1).astype(np.float32), "SCHLICK_S": np.clip(schlick, 0, 1).astype(np.float32)}


def write(path=None):
    import os

    path = path or os.path.join(os.path.dirname(os.path.abspath(__file__)), "ggx_tables_data.py")
    return write_tables(path, "tracer.shading.ggx_tables", compute())


def write_tables(path: str, module: str, tables: dict) -> str:
    """Write ``tables`` ({name: float32 array}) as the Python data module at ``path``, generated by ``module``."""
    lines = [f'"""Generated by ``python -m {module}`` (see that module); do not edit."""', "",
             "import numpy as np", ""]
    for name, a in tables.items():
        flat = ", ".join(f"{v:.6g}" for v in a.ravel())
        lines.append(f"{name} = np.array([{flat}], np.float32).reshape({a.shape})")
        lines.append("")
    with open(path, "w") as f:
        f.write("\n".join(lines))
    return path


if __name__ == "__main__":
    print(write())

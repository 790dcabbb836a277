"""The seed's optics: reflection, Snell refraction with total internal reflection, dielectric Fresnel.

Convention (as in the notes): ``d`` is the unit incident direction (travelling towards the surface), ``n`` the unit
normal on the incident side, so d·n ≤ 0 and cos θ_i = −d·n.

Each equation is written once, as a scalar function on 3-tuples that the integrator's kernels call per ray
(:func:`reflect_dir`, :func:`refract_dir`, :func:`fresnel_dielectric_1`). :func:`reflect`, :func:`refract` and
:func:`fresnel_dielectric` are their array forms (public and stable API; arrays broadcast over the leading axes).
"""

from __future__ import annotations

import math

import numpy as np

from . import vec
from .jit import kernel


@kernel(inline=True)
def reflect_dir(d, n):
    """Mirror reflection (the notes' ray type 3, Shirley 4.8): r = d − 2(d·n)n."""
    return vec.madd(d, n, -2.0 * vec.dot(d, n))


@kernel(inline=True)
def valid_reflection_normal(d, n, ng):
    """The shading normal n, tilted towards the geometric normal ng just enough that the mirror direction of d
    about it leaves the surface (Cycles' ``ensure_valid_specular_reflection``, which its glossy lobes use).

    An interpolated normal near a silhouette can send r = d − 2(d·n)n below the true surface (r·ng < 0). Write
    wi = −d, z = wi·ng (> 0 on the incident side) and t = min(0.9·z, 0.01), the least r·ng allowed (a reflection may
    be as grazing as the incoming ray). If r·ng ≥ t, n is kept. Otherwise n' = x·X + s·ng in the plane of ng and
    X = normalize(n − (n·ng)ng), with s² solving r'·ng = t, i.e. 2(wi·n')s − z = t; squared, with a = (wi·X)² + z²,
    b = 2(a + z·t), c = (z + t)²:  4a·s⁴ − 2b·s² + c = 0, s² = (b ± √(b² − 4ac))/(4a), the root that keeps
    wi·X and t + z(1 − 2s²) of one sign (the sign lost in squaring): + when wi·X < 0, − otherwise."""
    wi = vec.scale(d, -1.0)
    z = vec.dot(wi, ng)
    if z <= 0.0:
        return n
    t = min(0.9 * z, 0.01)
    if vec.dot(reflect_dir(d, n), ng) >= t:
        return n
    x = vec.madd(n, ng, -vec.dot(n, ng))
    lx = vec.length(x)
    if lx <= 1e-12:
        return ng
    x = vec.scale(x, 1.0 / lx)
    ix = vec.dot(wi, x)
    a = ix * ix + z * z
    b = 2.0 * (a + z * t)
    c = (z + t) * (z + t)
    root = math.sqrt(max(b * b - 4.0 * a * c, 0.0))
    s2 = 0.25 * (b + root) / a if ix < 0.0 else 0.25 * (b - root) / a
    s2 = min(max(s2, 0.0), 1.0)
    return vec.normalize(vec.madd(vec.scale(x, math.sqrt(1.0 - s2)), ng, math.sqrt(s2)))


@kernel(inline=True)
def refract_dir(d, n, eta_i, eta_r):
    """Transmitted direction by Snell's law, η_r sin θ_r = η_i sin θ_i (the notes' ray type 4).

    cos θ_r = [1 − (η_i/η_r)² (1 − cos² θ_i)]^½ and T = (η_i/η_r)(d − (d·n)n) − cos θ_r n.

    Returns (T, tir): under total internal reflection (the square root's argument is negative) T is the zero vector
    and tir is True; callers follow :func:`reflect_dir` instead.
    """
    ratio = eta_i / eta_r
    d_n = vec.dot(d, n)  # = −cos θ_i
    radicand = 1.0 - ratio * ratio * (1.0 - d_n * d_n)  # cos² θ_r
    if radicand < 0.0:
        return (0.0, 0.0, 0.0), True
    cos_r = math.sqrt(radicand)
    t = vec.sub(vec.scale(vec.madd(d, n, -d_n), ratio), vec.scale(n, cos_r))
    return t, False


@kernel(inline=True)
def fresnel_dielectric_1(cos_i, eta_i, eta_r):
    """Unpolarised Fresnel reflectance of a smooth dielectric boundary (the average of R_s and R_p).

    ``cos_i`` = cos θ_i (clamped to [0, 1]). Returns 1 under total internal reflection. Used to weight reflection
    against transmission on glass, as Cycles' Principled BSDF does; the notes' "classic" weights skip it.
    """
    cos_i = min(max(cos_i, 0.0), 1.0)
    ratio = eta_i / eta_r
    sin2_r = ratio * ratio * (1.0 - cos_i * cos_i)
    if sin2_r >= 1.0:
        return 1.0
    cos_r = math.sqrt(max(0.0, 1.0 - sin2_r))
    r_s = (eta_i * cos_i - eta_r * cos_r) / max(eta_i * cos_i + eta_r * cos_r, 1e-30)
    r_p = (eta_r * cos_i - eta_i * cos_r) / max(eta_r * cos_i + eta_i * cos_r, 1e-30)
    return 0.5 * (r_s * r_s + r_p * r_p)


@kernel(inline=True)
def ggx_lambda(alpha2, cos):
    """Smith's Λ of GGX for a direction at cos θ to the macro normal: (√(1 + α²·tan²θ) − 1)/2 (either side)."""
    c2 = min(cos * cos, 1.0)
    if c2 <= 0.0:
        return 1e30
    return 0.5 * (math.sqrt(1.0 + alpha2 * (1.0 - c2) / c2) - 1.0)


@kernel(inline=True)
def sample_ggx_vndf(wi, n, alpha, u1, u2):
    """A GGX microfacet normal m drawn from the distribution of normals visible from wi (unit, towards the
    viewer, wi·n > 0), D_wi(m) = G1(wi)·max(0, wi·m)·D(m)/(wi·n) (Heitz 2018, "Sampling the GGX Distribution of
    Visible Normals", listing 1), for the isotropic GGX of width α about the unit normal n; (u1, u2) in [0, 1)²."""
    tx, ty = vec.orthonormal_basis(n)
    vx, vy, vz = vec.dot(wi, tx), vec.dot(wi, ty), max(vec.dot(wi, n), 1e-7)
    # the view direction in the hemisphere configuration (stretched to α = 1)
    hx, hy, hz = alpha * vx, alpha * vy, vz
    inv = 1.0 / math.sqrt(hx * hx + hy * hy + hz * hz)
    hx, hy, hz = hx * inv, hy * inv, hz * inv
    lensq = hx * hx + hy * hy
    if lensq > 0.0:
        il = 1.0 / math.sqrt(lensq)
        t1x, t1y, t1z = -hy * il, hx * il, 0.0
    else:
        t1x, t1y, t1z = 1.0, 0.0, 0.0
    t2x, t2y, t2z = hy * t1z - hz * t1y, hz * t1x - hx * t1z, hx * t1y - hy * t1x  # h × t1
    r = math.sqrt(u1)
    phi = 2.0 * math.pi * u2
    p1 = r * math.cos(phi)
    p2 = r * math.sin(phi)
    s = 0.5 * (1.0 + hz)
    p2 = (1.0 - s) * math.sqrt(max(1.0 - p1 * p1, 0.0)) + s * p2
    p3 = math.sqrt(max(1.0 - p1 * p1 - p2 * p2, 0.0))
    nx = p1 * t1x + p2 * t2x + p3 * hx
    ny = p1 * t1y + p2 * t2y + p3 * hy
    nz = p1 * t1z + p2 * t2z + p3 * hz
    # back to the ellipsoid configuration
    mx, my, mz = alpha * nx, alpha * ny, max(nz, 1e-7)
    m = vec.add(vec.add(vec.scale(tx, mx), vec.scale(ty, my)), vec.scale(n, mz))
    return vec.normalize(m)


@kernel(inline=True)
def rough_dielectric(d, n, ng, alpha, eta_i, eta_r, u1, u2, fresnel):
    """One sample of a rough dielectric interface (GGX microfacets of width α = roughness², as Cycles' microfacet
    glass): the microfacet normal m, the reflected and refracted directions about it and their shadowing factors.
    Returns (m, r, g_r, t, g_t, F, tir): the reflected ray's weight is w_r = F·g_r, the refracted ray's
    w_t = (1 − F)·g_t (a Refraction BSDF, no Fresnel: g_t).

    Estimator. The Walter et al. 2007 BSDF of the interface, for wi = −d and an outgoing o, is
    f(wi, o) = |wi·m||o·m| / (|wi·n||o·n|) · D(m)·G2(wi, o) · {F(wi·m)/(4|wi·m||o·m|) (reflection, m = h_r);
    (1 − F)·η_o²/(η_i(wi·m) + η_o(o·m))² (transmission, m = h_t)} (radiance form, no 1/η² as the smooth seed
    transmission: its limit at α → 0 is exactly the smooth split F, 1 − F). m is drawn from the visible normals,
    p(m) = G1(wi)·|wi·m|·D(m)/|wi·n| (:func:`sample_ggx_vndf`); given m, o is its mirror image (Jacobian
    dω_m/dω_o = 1/(4|o·m|)) or its refraction (Jacobian η_o²|o·m|/(η_i(wi·m) + η_o(o·m))²). Both rays are
    spawned from the same m, each as the branch of a choice made with probability F (resp. 1 − F), so each
    weight is F·f·|o·n|/(F·p(o)) scaled back by its branch's probability:
        w_r = F · G2(wi, r)/G1(wi),    w_t = (1 − F) · G2(wi, t)/G1(wi),
    D, |wi·m|, the Jacobians and η all cancel. With the height-correlated Smith G2 = 1/(1 + Λ(wi) + Λ(o)) (Cycles')
    G2/G1(wi) = (1 + Λ(wi))/(1 + Λ(wi) + Λ(o)); with the separable G2 = G1(wi)·G1(o) it is G1(o) of the outgoing
    direction: the Fresnel choice × G1(o). A direction on the wrong side of the macro surface (r·n ≤ 0 or r·ng ≤ 0;
    t·n ≥ 0 or t·ng ≥ 0) has weight 0, and so has the refraction under total internal reflection about m (F = 1).
    Summed, w_r + w_t = F·G + (1 − F)·G ≤ 1: the interface reflects and transmits 1 less its single-scattering
    loss (Smith shadowing), 1 exactly as α → 0. ``fresnel`` False: F is 1 under TIR, 0 otherwise (the notes' weights).
    """
    wi = vec.scale(d, -1.0)
    m = sample_ggx_vndf(wi, n, alpha, u1, u2)
    cos_im = vec.dot(wi, m)
    if cos_im <= 0.0:  # cannot happen for visible normals but for rounding
        m = n
        cos_im = max(vec.dot(wi, n), 0.0)
    alpha2 = alpha * alpha
    lam_i = ggx_lambda(alpha2, vec.dot(wi, n))
    r = reflect_dir(d, m)
    t, tir = refract_dir(d, m, eta_i, eta_r)
    if fresnel:
        fr = fresnel_dielectric_1(cos_im, eta_i, eta_r)
    else:
        fr = 1.0 if tir else 0.0
    if tir:
        fr = 1.0
    g_r = 0.0
    r_n = vec.dot(r, n)
    if r_n > 0.0 and vec.dot(r, ng) > 0.0:
        g_r = (1.0 + lam_i) / (1.0 + lam_i + ggx_lambda(alpha2, r_n))
    g_t = 0.0
    if not tir:
        t_n = vec.dot(t, n)
        if t_n < 0.0 and vec.dot(t, ng) < 0.0:
            g_t = (1.0 + lam_i) / (1.0 + lam_i + ggx_lambda(alpha2, t_n))
    return m, r, g_r, t, g_t, fr, tir


@kernel(inline=True)
def ggx_d(alpha2, cos_m):
    """The isotropic GGX distribution of microfacet normals at cos θ_m to the macro normal: α²/(π(cos²θ_m(α² − 1)
    + 1)²) (per steradian of m, projected area normalised: ∫D(m)(m·n)dω_m = 1)."""
    if cos_m <= 0.0:
        return 0.0
    c2 = cos_m * cos_m
    k = c2 * (alpha2 - 1.0) + 1.0
    return alpha2 / (math.pi * k * k)


@kernel(inline=True)
def rough_dielectric_eval(d, o, n, ng, alpha, eta_i, eta_r, fresnel):
    """The rough dielectric interface of :func:`rough_dielectric` evaluated for a given outgoing direction o (unit; a
    light sample): (side, value, F) with side 1 where o is reflected (o·n > 0 and o·ng > 0), −1 where it is
    refracted (o·n < 0 and o·ng < 0), 0 otherwise (value 0). ``value`` is the BSDF × |o·n| without its Fresnel
    split: reflection D(m)·G2(wi, o)/(4|wi·n|) (m = the half vector), refraction
    D(m)·G2·η_r²·|wi·m||o·m|/(|wi·n|·(η_i(wi·m) + η_r(o·m))²) (m = −(η_i·wi + η_r·o), towards n); F is the
    Fresnel reflectance at wi·m. A light of irradiance E adds F·value·E (reflection) or (1 − F)·value·E
    (refraction): the same BSDF whose samples :func:`rough_dielectric` weights F·G2/G1 and (1 − F)·G2/G1, so that a
    light seen by light samples and one seen by the sampled rays have one expected value. ``fresnel`` False: F = 0
    (a refraction exists only without total internal reflection about m, where F = 1)."""
    wi = vec.scale(d, -1.0)
    cos_i = vec.dot(wi, n)
    o_n = vec.dot(o, n)
    o_g = vec.dot(o, ng)
    if cos_i <= 0.0:
        return 0, 0.0, 0.0
    alpha2 = alpha * alpha
    if o_n > 0.0 and o_g > 0.0:
        h = vec.add(wi, o)
        lh = vec.length(h)
        if lh <= 1e-12:
            return 0, 0.0, 0.0
        m = vec.scale(h, 1.0 / lh)
        cos_im = vec.dot(wi, m)
        if cos_im <= 0.0:
            return 0, 0.0, 0.0
        g2 = 1.0 / (1.0 + ggx_lambda(alpha2, cos_i) + ggx_lambda(alpha2, o_n))
        fr = fresnel_dielectric_1(cos_im, eta_i, eta_r) if fresnel else 0.0
        return 1, ggx_d(alpha2, vec.dot(m, n)) * g2 / (4.0 * cos_i), fr
    if o_n < 0.0 and o_g < 0.0:
        h = vec.scale(vec.add(vec.scale(wi, eta_i), vec.scale(o, eta_r)), -1.0)
        lh = vec.length(h)
        if lh <= 1e-12:
            return 0, 0.0, 0.0
        m = vec.scale(h, 1.0 / lh)
        if vec.dot(m, n) < 0.0:
            m = vec.scale(m, -1.0)
        cos_im = vec.dot(wi, m)
        cos_om = vec.dot(o, m)
        if cos_im <= 0.0 or cos_om >= 0.0:
            return 0, 0.0, 0.0
        den = eta_i * cos_im + eta_r * cos_om
        if den * den <= 1e-20:
            return 0, 0.0, 0.0
        g2 = 1.0 / (1.0 + ggx_lambda(alpha2, cos_i) + ggx_lambda(alpha2, o_n))
        fr = fresnel_dielectric_1(cos_im, eta_i, eta_r) if fresnel else 0.0
        value = ggx_d(alpha2, vec.dot(m, n)) * g2 * eta_r * eta_r * cos_im * (-cos_om) / (cos_i * den * den)
        return -1, value, fr
    return 0, 0.0, 0.0


# ---------------------------------------------------------------------- array forms
@kernel
def _reflect_rows(d, n, out):
    for i in range(d.shape[0]):
        r = reflect_dir(vec.row(d, i), vec.row(n, i))
        out[i, 0], out[i, 1], out[i, 2] = r


@kernel
def _refract_rows(d, n, eta_i, eta_r, out, tir):
    for i in range(d.shape[0]):
        t, tir[i] = refract_dir(vec.row(d, i), vec.row(n, i), eta_i[i], eta_r[i])
        out[i, 0], out[i, 1], out[i, 2] = t


@kernel
def _fresnel_rows(cos_i, eta_i, eta_r, out):
    for i in range(cos_i.shape[0]):
        out[i] = fresnel_dielectric_1(cos_i[i], eta_i[i], eta_r[i])


def _rows(*arrays):
    """Broadcast (..., 3) vectors and per-row scalars (shape (...) or (..., 1)) to flat float64 rows."""
    vecs = [np.asarray(a, dtype=np.float64) for a in arrays]
    shape = np.broadcast_shapes(*(v.shape[:-1] for v in vecs))
    return shape, [np.ascontiguousarray(np.broadcast_to(v, shape + (3,)).reshape(-1, 3)) for v in vecs]


def _scalars(x, shape):
    x = np.asarray(x, dtype=np.float64)
    if x.ndim == len(shape) + 1 and x.shape[-1] == 1:
        x = x[..., 0]
    return np.ascontiguousarray(np.broadcast_to(x, shape).reshape(-1))


def reflect(d, n):
    """Array form of :func:`reflect_dir`: r = d − 2(d·n)n for (..., 3) arrays."""
    dtype = np.result_type(np.asarray(d).dtype, np.asarray(n).dtype, np.float32)
    shape, (dd, nn) = _rows(d, n)
    out = np.empty_like(dd)
    _reflect_rows(dd, nn, out)
    return out.reshape(shape + (3,)).astype(dtype, copy=False)


def refract(d, n, eta_i, eta_r):
    """Array form of :func:`refract_dir`. ``eta_i`` / ``eta_r``: the indices on the incident / far side, scalars or
    per-row arrays. Returns ``(t, tir)``: unit transmitted directions (zero where tir) and the boolean TIR mask."""
    dtype = np.result_type(np.asarray(d).dtype, np.asarray(n).dtype, np.float32)
    shape, (dd, nn) = _rows(d, n)
    out = np.empty_like(dd)
    tir = np.empty(len(dd), np.bool_)
    _refract_rows(dd, nn, _scalars(eta_i, shape), _scalars(eta_r, shape), out, tir)
    return out.reshape(shape + (3,)).astype(dtype, copy=False), tir.reshape(shape)


def fresnel_dielectric(cos_i, eta_i, eta_r):
    """Array form of :func:`fresnel_dielectric_1` (float32 result, 1 under total internal reflection)."""
    shape = np.broadcast_shapes(np.shape(cos_i), np.shape(eta_i), np.shape(eta_r))
    out = np.empty(int(np.prod(shape)), np.float64)
    _fresnel_rows(_scalars(cos_i, shape), _scalars(eta_i, shape), _scalars(eta_r, shape), out)
    return out.reshape(shape).astype(np.float32)

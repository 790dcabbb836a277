"""The local reflection models a light sample is weighted by: the Principled BSDF (default) and the notes' classic
Lambert + Blinn-Phong (:mod:`tracer.shading.local`).

Principled, as Cycles 5.0 builds its Principled BSDF (``src/kernel/svm/closure.h``, ``closure/bsdf_microfacet.h``),
for one shading point seen from direction wi with view cosine μ = n·wi, roughness r (α = r²):

- **metal** (weight m = metallic): a GGX lobe with the F82-tint Fresnel of Kutz et al. (Adobe Standard Material):
  F(θ) = F0 + (1 − F0)(1 − cos θ)⁵ − b·cos θ·(1 − cos θ)⁶, F0 = base colour, b chosen so that F at cos θ = 1/7
  (≈ 82°) is the Schlick value × ``specular_tint``;
- **dielectric specular** (weight (1 − m)(1 − transmission)): a GGX lobe whose Fresnel follows the real dielectric
  curve of η, rescaled from its own F0 to F0' = F0(ior)·2·specular·tint: F = F0' + (1 − F0')·s, s = (F_η(θ) −
  F0(η)) / (1 − F0(η)), with η = ior_from_F0(F0(ior)·2·specular);
- **diffuse**: Lambert, base colour × (1 − m)(1 − transmission) × (1 − the specular layer's albedo at μ);
- both GGX lobes are "multiscatter GGX" (Blender's default): the single-scattering lobe
  f = F·D·G₂/(4 cos θ_i cos θ_o) (Smith G₂, height-correlated) is scaled by 1 + F_ms·(1 − E(μ))/E(μ), where E is
  the lobe's albedo without Fresnel, and F_ms = F_ss·E_avg / (1 − F_ss·(1 − E_avg)) the multiple-bounce Fresnel
  (Kulla & Conty 2017; Turquin 2019). E, E_avg and the layering albedo come from :mod:`tracer.shading.ggx_tables`.

A :class:`Closure` is set up once per shading point (:func:`principled` or :func:`classic`) and evaluated per
light direction by :func:`evaluate` (BRDF × cos θ_light, so a light of irradiance E adds evaluate·E). Its
``reflect`` is the directional albedo of the specular lobes at μ: the weight of the mirror ray when roughness gives
the lobe to it (:func:`mirror_share`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .. import vec
from ..jit import kernel
from . import local as shading
from .ggx_glass_data import GLASS_E_IN as _GLASS_E_IN, GLASS_E_OUT as _GLASS_E_OUT
from .ggx_tables_data import E_AVG as _E_AVG, FSS as _FSS, IOR_S as _IOR_S, SCHLICK_S as _SCHLICK_S, E as _E

INV_PI = 1.0 / math.pi
#: Below this α² a GGX lobe is a mirror: it has no value for a light direction, only the mirror ray (Cycles'
#: BSDF_ROUGHNESS_SQ_THRESH).
SINGULAR_ALPHA2 = 2e-10
#: The roughness split (README, "Conventions"): below ROUGH_MIRROR the lobe goes to the mirror ray, above
#: ROUGH_LOCAL to the light samples, smoothstep in between (see :func:`mirror_share`).
ROUGH_MIRROR = 0.3
ROUGH_LOCAL = 0.5
#: The same split for lamps the mirror ray can see (area lights, spheres, sun disks: tracer.lights.emitters.lamp_hit):
#: their light samples follow a GGX lobe well down to a far smaller roughness than a world or an emitting mesh can
#: be sampled, so the mirror ray takes only the nearly smooth lobes' share of them (:func:`lamp_share`): a hammered
#: metal (roughness 0.25) keeps its sampled, blurred highlight of an area light, a polished one (0.05) shows the
#: light's sharp image. Measured on the metal library of docs/fidelity.md ("Lamps in mirrors and glass").
ROUGH_LAMP_MIRROR = 0.1
ROUGH_LAMP_LOCAL = 0.2


class Closure(NamedTuple):
    """One shading point's reflection model (colours are 3-tuples)."""

    principled: bool
    diffuse: tuple  # Lambert weight (R_d): outgoing radiance = diffuse/π · E · cos
    metal: float  # metal lobe weight m
    metal_f0: tuple
    metal_b: tuple  # F82 tint term
    metal_ms: tuple  # multiscatter factor of the metal lobe
    spec: float  # dielectric specular weight (1 − m)(1 − transmission), 0 = no lobe
    spec_f0: tuple  # F0' (tinted)
    spec_eta: float
    spec_ms: tuple
    alpha2: float  # GGX α²
    mu: float  # n·wi
    reflect: tuple  # directional albedo of the specular lobes at μ (the mirror ray's share)
    spec_color: tuple  # classic: R_s
    exponent: float  # classic: e
    # Per shading point, so that :func:`evaluate` does not redo them per light sample:
    lambda_mu: float  # Smith's Λ(μ) of the view direction
    spec_f0r: float  # F0 of spec_eta (the real dielectric curve's own F0)
    spec_rescale: float  # 1 / (1 − spec_f0r): the curve rescaled to run from 0 at normal incidence to 1
    fixed: bool  # the metal lobe's Fresnel is the constant metal_f0 (Glossy BSDF), not F82
    # Anisotropic GGX (:func:`anisotropic`): α is α/aspect along the unit ``axis`` (in the tangent plane) and
    # α·aspect across it; aspect 1 (axis 0): isotropic.
    axis: tuple
    aspect: float


# ---------------------------------------------------------------------------------------------- tables
@kernel(inline=True)
def _read(t, row, x):
    """Linear interpolation of row ``row`` of a 2-D table at x in [0, 1] (clamped), entries at i/(n − 1)."""
    n = t.shape[1]
    x = min(max(x, 0.0), 1.0) * (n - 1)
    i = min(int(x), n - 1)
    j = min(i + 1, n - 1)
    f = x - i
    return (1.0 - f) * t[row, i] + f * t[row, j]


@kernel(inline=True)
def table2(t, x, y):
    """Bilinear read of a (ny, nx) table at (x, y) in [0, 1]²."""
    ny = t.shape[0]
    y = min(max(y, 0.0), 1.0) * (ny - 1)
    i = min(int(y), ny - 1)
    j = min(i + 1, ny - 1)
    f = y - i
    return (1.0 - f) * _read(t, i, x) + f * _read(t, j, x)


@kernel(inline=True)
def _table1(t, x):
    n = t.shape[0]
    x = min(max(x, 0.0), 1.0) * (n - 1)
    i = min(int(x), n - 1)
    j = min(i + 1, n - 1)
    f = x - i
    return (1.0 - f) * t[i] + f * t[j]


@kernel(inline=True)
def _table3(t, x, y, z):
    nz = t.shape[0]
    z = min(max(z, 0.0), 1.0) * (nz - 1)
    i = min(int(z), nz - 1)
    j = min(i + 1, nz - 1)
    f = z - i
    return (1.0 - f) * table2(t[i], x, y) + f * table2(t[j], x, y)


@kernel(inline=True)
def glass_albedo(roughness, mu, eta):
    """E(μ, r, η): what one rough dielectric interface (:func:`tracer.optics.rough_dielectric`, single scattering)
    returns of white light arriving at cos θ = μ, η = η_far/η_near (:mod:`tracer.shading.ggx_glass`). The spawn
    stage divides the interface's weights by it: Cycles' Multiscatter GGX glass loses no energy."""
    r = min(max(roughness, 0.0), 1.0)
    mu = min(max(mu, 0.0), 1.0)
    if eta >= 1.0:
        return _table3(_GLASS_E_IN, r, mu, _z_of(eta))
    return _table3(_GLASS_E_OUT, r, mu, _z_of(1.0 / max(eta, 1e-6)))


# ---------------------------------------------------------------------------------------------- Fresnel
@kernel(inline=True)
def f0_from_ior(eta):
    """F0 = ((η − 1)/(η + 1))² (array form: :func:`tracer.shading.materials.f0_from_ior`)."""
    r = (eta - 1.0) / (eta + 1.0)
    return r * r


@kernel(inline=True)
def ior_from_f0(f0):
    s = math.sqrt(min(max(f0, 0.0), 0.99))
    return (1.0 + s) / (1.0 - s)


@kernel(inline=True)
def fresnel_dielectric(cos_i, eta):
    """Unpolarised dielectric Fresnel reflectance for relative index η (1 under total internal reflection)."""
    c = abs(cos_i)
    g2 = eta * eta - 1.0 + c * c
    if g2 <= 0.0:
        return 1.0
    g = math.sqrt(g2)
    a = (g - c) / (g + c)
    b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    return 0.5 * a * a * (1.0 + b * b)


@kernel(inline=True)
def _z_of(eta):
    """The tables' η coordinate: z = F0(η)^¼."""
    return math.sqrt(abs((eta - 1.0) / (eta + 1.0)))


@kernel(inline=True)
def dielectric_albedo(roughness, mu, eta):
    """The albedo of a single-scattering dielectric GGX lobe at cos θ = μ, what Cycles' coat (GGX, not multiscatter)
    attenuates the layers below by (``bsdf_microfacet_estimate_albedo``, the dielectric case): E(r, μ)·(F0(η) +
    (1 − F0(η))·s(r, μ, η)), E and s the tables the Principled lobes read (:mod:`tracer.shading.ggx_tables`).
    Measured in Cycles through bpy (a white furnace, white Lambert under a coat of IOR 1.5, roughness 0.6): the
    layers below keep 1 − 0.0348 head-on and 1 − 0.0542 at 57°; this gives 0.0337 and 0.0526 (the smooth Fresnel
    0.040 and 0.078)."""
    r = min(max(roughness, 0.0), 1.0)
    mu_c = min(max(mu, 0.0), 1.0)
    f0 = f0_from_ior(eta)
    return table2(_E, r, mu_c) * (f0 + (1.0 - f0) * _table3(_IOR_S, r, mu_c, _z_of(eta)))


@kernel(inline=True)
def fresnel_f82(cos_i, f0, b):
    """F82-tint Fresnel: Schlick's F0 + (1 − F0)(1 − cos)⁵ minus b·cos·(1 − cos)⁶, per channel, clamped to [0, 1]."""
    s = min(max(1.0 - cos_i, 0.0), 1.0)
    s5 = s * s * s * s * s
    return (min(max(f0[0] + (1.0 - f0[0]) * s5 - b[0] * cos_i * s5 * s, 0.0), 1.0),
            min(max(f0[1] + (1.0 - f0[1]) * s5 - b[1] * cos_i * s5 * s, 0.0), 1.0),
            min(max(f0[2] + (1.0 - f0[2]) * s5 - b[2] * cos_i * s5 * s, 0.0), 1.0))


@kernel(inline=True)
def _f82_b(f0, tint):
    """b such that F82(cos = 1/7) = Schlick(1/7)·tint."""
    f = 6.0 / 7.0
    f5 = f * f * f * f * f
    k = 7.0 / (f5 * f)
    return ((f0[0] + (1.0 - f0[0]) * f5) * k * (1.0 - tint[0]), (f0[1] + (1.0 - f0[1]) * f5) * k * (1.0 - tint[1]),
            (f0[2] + (1.0 - f0[2]) * f5) * k * (1.0 - tint[2]))


@kernel(inline=True)
def _multiscatter(fss, e, e_avg):
    """1 + F_ms·(1 − E)/E per channel: the multiscatter GGX factor on the single-scattering lobe."""
    missing = (1.0 - e) / max(e, 1e-6)
    f0 = fss[0] * e_avg / max(1.0 - fss[0] * (1.0 - e_avg), 1e-6)
    f1 = fss[1] * e_avg / max(1.0 - fss[1] * (1.0 - e_avg), 1e-6)
    f2 = fss[2] * e_avg / max(1.0 - fss[2] * (1.0 - e_avg), 1e-6)
    return (1.0 + f0 * missing, 1.0 + f1 * missing, 1.0 + f2 * missing)


# ---------------------------------------------------------------------------------------------- set-up
@kernel(inline=True)
def principled(base, metallic, roughness, specular, tint, ior, transmission, mu):
    """The Principled :class:`Closure` of a shading point (module docstring); μ = n·wi."""
    r = min(max(roughness, 0.0), 1.0)
    alpha = r * r
    alpha2 = alpha * alpha
    mu_c = min(max(mu, 0.0), 1.0)
    e = table2(_E, r, mu_c)
    e_avg = _table1(_E_AVG, r)
    missing = (1.0 - e) / max(e, 1e-6)
    zero = (0.0, 0.0, 0.0)
    reflect = zero

    m = min(max(metallic, 0.0), 1.0)
    f0m, bm, msm = zero, zero, (1.0, 1.0, 1.0)
    if m > 0.0:
        f0m = (min(max(base[0], 0.0), 1.0), min(max(base[1], 0.0), 1.0), min(max(base[2], 0.0), 1.0))
        bm = _f82_b(f0m, (min(tint[0], 1.0), min(tint[1], 1.0), min(tint[2], 1.0)))
        # mean F82 Fresnel over the cosine-weighted hemisphere: F0 + (1 − F0)/21 − b/126
        fss = (f0m[0] + (1.0 - f0m[0]) / 21.0 - bm[0] / 126.0, f0m[1] + (1.0 - f0m[1]) / 21.0 - bm[1] / 126.0,
               f0m[2] + (1.0 - f0m[2]) / 21.0 - bm[2] / 126.0)
        msm = _multiscatter(fss, e, e_avg)
        s82 = table2(_SCHLICK_S, r, mu_c)
        dark = 1.0 / (1.0 + missing)
        reflect = vec.madd(reflect, (msm[0] * dark * (f0m[0] + (1.0 - f0m[0]) * s82),
                                     msm[1] * dark * (f0m[1] + (1.0 - f0m[1]) * s82),
                                     msm[2] * dark * (f0m[2] + (1.0 - f0m[2]) * s82)), m)

    w = (1.0 - m) * (1.0 - min(max(transmission, 0.0), 1.0))
    eta = ior
    f0 = f0_from_ior(ior)
    if specular != 0.5:
        f0 *= 2.0 * max(specular, 0.0)
        eta = ior_from_f0(f0)
        if ior < 1.0:
            eta = 1.0 / eta
    layer = 1.0
    f0s, mss, ws = zero, (1.0, 1.0, 1.0), 0.0
    if w > 0.0 and eta != 1.0:
        ws = w
        f0s = (min(max(f0 * tint[0], 0.0), 1.0), min(max(f0 * tint[1], 0.0), 1.0), min(max(f0 * tint[2], 0.0), 1.0))
        f0_real = f0_from_ior(eta)
        s_ss = min(max((_table1(_FSS, _z_of(eta)) - f0_real) / max(1.0 - f0_real, 1e-6), 0.0), 1.0)
        mss = _multiscatter((f0s[0] + (1.0 - f0s[0]) * s_ss, f0s[1] + (1.0 - f0s[1]) * s_ss,
                             f0s[2] + (1.0 - f0s[2]) * s_ss), e, e_avg)
        s = _table3(_IOR_S, r, mu_c, _z_of(eta))
        dark = 1.0 / (1.0 + missing)
        alb = (mss[0] * dark * (f0s[0] + (1.0 - f0s[0]) * s), mss[1] * dark * (f0s[1] + (1.0 - f0s[1]) * s),
               mss[2] * dark * (f0s[2] + (1.0 - f0s[2]) * s))
        layer = min(max(1.0 - vec.max3(alb), 0.0), 1.0)
        reflect = vec.madd(reflect, alb, ws)
    diffuse = vec.scale((max(base[0], 0.0), max(base[1], 0.0), max(base[2], 0.0)), w * layer)
    f0r = f0_from_ior(eta)
    return Closure(True, diffuse, m, f0m, bm, msm, ws, f0s, np.float64(eta), mss, alpha2, np.float64(mu), reflect, zero,
                   0.0, _lambda(alpha2, mu), np.float64(f0r), 1.0 / max(1.0 - f0r, 1e-6), False, zero, 1.0)


@kernel(inline=True)
def lambertian(color, mu):
    """The Diffuse BSDF (Lambert, R_d = color; Cycles' Diffuse at roughness 0) as a :class:`Closure`."""
    zero = (0.0, 0.0, 0.0)
    d = (max(color[0], 0.0), max(color[1], 0.0), max(color[2], 0.0))
    return Closure(True, d, 0.0, zero, zero, (1.0, 1.0, 1.0), 0.0, zero, 1.0, zero, 1.0, np.float64(mu), zero, zero,
                   0.0, 0.0, 0.0, 1.0, False, zero, 1.0)


@kernel(inline=True)
def glossy(color, roughness, mu, multi=True):
    """The Glossy BSDF (Cycles' ``bsdf_microfacet_setup_fresnel_constant``): one GGX lobe whose Fresnel is the
    constant ``color``; ``multi`` (Multiscatter GGX) scales it by 1 + F_ms(1 − E)/E with F_ss = color, its
    directional albedo (``reflect``) then color·E·(1 + F_ms(1 − E)/E); without (the GGX distribution, single
    scattering) it is color·E: a white Glossy of roughness 1 under a uniform world of radiance 1 shows E(μ), 0.31
    head-on (measured in Cycles through bpy: 0.3067, E 0.3069; Multiscatter GGX 0.9995)."""
    r = min(max(roughness, 0.0), 1.0)
    alpha = r * r
    alpha2 = alpha * alpha
    mu_c = min(max(mu, 0.0), 1.0)
    e = table2(_E, r, mu_c)
    f0 = (min(max(color[0], 0.0), 1.0), min(max(color[1], 0.0), 1.0), min(max(color[2], 0.0), 1.0))
    ms = _multiscatter(f0, e, _table1(_E_AVG, r)) if multi else (1.0, 1.0, 1.0)
    reflect = (ms[0] * e * f0[0], ms[1] * e * f0[1], ms[2] * e * f0[2])
    zero = (0.0, 0.0, 0.0)
    return Closure(True, zero, 1.0, f0, zero, ms, 0.0, zero, 1.0, zero, alpha2, np.float64(mu), reflect, zero, 0.0,
                   _lambda(alpha2, mu), 0.0, 1.0, True, zero, 1.0)


@kernel(inline=True)
def classic(diffuse, spec_color, exponent):
    """The notes' Lambert + Blinn-Phong as a :class:`Closure` (R_d, R_s, e)."""
    zero = (0.0, 0.0, 0.0)
    return Closure(False, diffuse, 0.0, zero, zero, zero, 0.0, zero, 1.0, zero, 0.0, 1.0, zero, spec_color,
                   np.float64(exponent), 0.0, 0.0, 1.0, False, zero, 1.0)


@kernel(inline=True)
def anisotropic(cl, a, n):
    """``cl`` with anisotropic GGX lobes: ``a`` is a material's per-hit anisotropy (the VM's ``aniso`` output,
    :func:`tracer.shading.closures.ClosureLowering.anisotropy`), the axis its lobes are stretched along times
    1 − aspect, aspect = √(1 − 0.9·Anisotropic) for the Principled BSDF (Cycles: α_x = α/aspect along the tangent,
    α_y = α·aspect), 1 − |Anisotropy| for the Glossy BSDF; the axis is projected into the plane normal to n.
    α_x·α_y = α², so the albedo tables (read at (α_x·α_y)^¼ as Cycles does) and the mirror share are unchanged:
    only the light samples' lobe (:func:`evaluate`) changes shape."""
    ax = (float(a[0]), float(a[1]), float(a[2]))
    k = vec.length(ax)
    if k <= 1e-4 or not cl.principled:
        return cl
    t = vec.sub(ax, vec.scale(n, vec.dot(n, ax)))
    lt = vec.length(t)
    if lt <= 1e-6 * k:
        return cl
    t = vec.scale(t, 1.0 / lt)
    return Closure(cl.principled, cl.diffuse, cl.metal, cl.metal_f0, cl.metal_b, cl.metal_ms, cl.spec, cl.spec_f0,
                   cl.spec_eta, cl.spec_ms, cl.alpha2, cl.mu, cl.reflect, cl.spec_color, cl.exponent, cl.lambda_mu,
                   cl.spec_f0r, cl.spec_rescale, cl.fixed, t, max(1.0 - min(k, 1.0), 0.01))


# ---------------------------------------------------------------------------------------------- evaluation
@kernel(inline=True)
def _lambda(alpha2, cos):
    """Smith's Λ for GGX: (√(1 + α²·tan²θ) − 1)/2."""
    c2 = max(cos * cos, 1e-12)
    return 0.5 * (math.sqrt(1.0 + alpha2 * max(1.0 / c2 - 1.0, 0.0)) - 1.0)


@kernel(inline=True)
def bump_shadowing(ns, n, l):
    """Cycles' ``bump_shadowing_term`` (closure/bsdf.h) for a light direction l at a hit whose shading normal n was
    bumped or normal-mapped away from the smooth normal ns (both on the incident side): (valid, diffuse). valid = 0
    where l and n lie on different sides of the smooth surface (no closure is lit from there), else 1; diffuse = the
    factor on the diffuse-type lobes (Diffuse, the Principled diffuse, sheen, translucent): Smith's G₁ of GGX with
    α² = min(tan²(ns, n)/8, 1) at |ns·l| (Conty Estevez et al., "A Microfacet-Based Shadowing Function to Solve the
    Bump Terminator Problem"). (1, 1) where n = ns (no bump)."""
    if n[0] == ns[0] and n[1] == ns[1] and n[2] == ns[2]:
        return 1.0, 1.0
    cos_si = vec.dot(ns, l)
    cos_sn = vec.dot(ns, n)
    if cos_si * cos_sn * vec.dot(n, l) < 0.0:
        return 0.0, 0.0
    cos_i, cos_d = abs(cos_si), abs(cos_sn)
    if cos_d >= 1.0 or cos_i >= 1.0:
        return 1.0, 1.0
    if cos_i < 1e-6:
        return 1.0, 0.0
    alpha2 = min(max(0.125 * (1.0 / (cos_d * cos_d) - 1.0), 0.0), 1.0)
    return 1.0, 1.0 / (1.0 + _lambda(alpha2, cos_i))


@kernel(inline=True)
def _lambda_aniso(ax, ay, x, y, z):
    """Smith's Λ for anisotropic GGX of a direction (x, y, z) in the lobe's frame: (√(1 + (α_x²x² + α_y²y²)/z²) − 1)/2."""
    z2 = max(z * z, 1e-12)
    return 0.5 * (math.sqrt(1.0 + (ax * ax * x * x + ay * ay * y * y) / z2) - 1.0)


@kernel(inline=True)
def evaluate(cl, n, wi, l, n_l, spec_scale):
    """BRDF × cos θ_l of closure ``cl`` for the unit light direction l (n·l = ``n_l`` > 0) seen from wi; the
    specular lobes are multiplied by ``spec_scale`` (the light-sample share of the roughness split)."""
    if not cl.principled:
        c = shading.lambert(cl.diffuse, (1.0, 1.0, 1.0), n_l)
        if vec.max3(cl.spec_color) > 0.0:
            h = shading.half_vector(l, wi)
            c = vec.add(c, shading.blinn_phong(cl.spec_color, cl.exponent, n, h, (1.0, 1.0, 1.0), n_l))
        return c
    c = vec.scale(cl.diffuse, INV_PI * n_l)
    if spec_scale <= 0.0 or cl.mu <= 0.0 or cl.alpha2 <= SINGULAR_ALPHA2 or (cl.metal <= 0.0 and cl.spec <= 0.0):
        return c
    h = vec.normalize(vec.add(wi, l))
    cos_hi = max(vec.dot(h, wi), 0.0)
    cos_nh = min(vec.dot(n, h), 1.0)
    if cos_nh <= 0.0:
        return c
    a2 = cl.alpha2
    if cl.aspect < 1.0:  # anisotropic GGX: D = 1/(π α_x α_y (h_x²/α_x² + h_y²/α_y² + h_z²)²), Λ of the stretched slope
        alpha = math.sqrt(a2)
        ax = min(alpha / cl.aspect, 1.0)
        ay = min(alpha * cl.aspect, 1.0)
        b = vec.cross(n, cl.axis)
        hx, hy = vec.dot(h, cl.axis) / ax, vec.dot(h, b) / ay
        q = hx * hx + hy * hy + cos_nh * cos_nh
        lv = _lambda_aniso(ax, ay, vec.dot(wi, cl.axis), vec.dot(wi, b), cl.mu)
        ll = _lambda_aniso(ax, ay, vec.dot(l, cl.axis), vec.dot(l, b), n_l)
        common = spec_scale / (math.pi * ax * ay * q * q * 4.0 * cl.mu * (1.0 + lv + ll))
    else:
        cnh2 = cos_nh * cos_nh
        t = 1.0 - cnh2 + a2 * cnh2
        # D = α²/(π t²) and the height-correlated Smith G₂ = 1/(1 + Λ(μ) + Λ(n·l)) over 4μ, in one division
        common = a2 * spec_scale / (math.pi * t * t * 4.0 * cl.mu * (1.0 + cl.lambda_mu + _lambda(a2, n_l)))
    if cl.metal > 0.0:
        f = cl.metal_f0 if cl.fixed else fresnel_f82(cos_hi, cl.metal_f0, cl.metal_b)
        c = vec.add(c, vec.scale(vec.mul(f, cl.metal_ms), cl.metal * common))
    if cl.spec > 0.0:
        s = min(max((fresnel_dielectric(cos_hi, cl.spec_eta) - cl.spec_f0r) * cl.spec_rescale, 0.0), 1.0)
        f = (cl.spec_f0[0] + (1.0 - cl.spec_f0[0]) * s, cl.spec_f0[1] + (1.0 - cl.spec_f0[1]) * s,
             cl.spec_f0[2] + (1.0 - cl.spec_f0[2]) * s)
        c = vec.add(c, vec.scale(vec.mul(f, cl.spec_ms), cl.spec * common))
    return c


@kernel(inline=True)
def specular_albedo(cl):
    """Directional albedo of the specular lobes at the view direction (classic: none; the k_m ray is separate)."""
    return cl.reflect


@kernel(inline=True)
def mirror_share(roughness):
    """The share g(r) of the specular lobes the mirror ray takes (the rest is evaluated per light sample):
    1 for r ≤ ROUGH_MIRROR, 0 for r ≥ ROUGH_LOCAL, smoothstep in between (README, "Conventions")."""
    x = min(max((roughness - ROUGH_MIRROR) / (ROUGH_LOCAL - ROUGH_MIRROR), 0.0), 1.0)
    return 1.0 - x * x * (3.0 - 2.0 * x)


@kernel(inline=True)
def lamp_share_of(roughness):
    """1 for roughness ≤ ROUGH_LAMP_MIRROR, 0 from ROUGH_LAMP_LOCAL, smoothstep in between: how much of a lobe (or
    of glass rendered smooth: the classic model) sees lamps through the mirror or refracted ray."""
    x = min(max((roughness - ROUGH_LAMP_MIRROR) / (ROUGH_LAMP_LOCAL - ROUGH_LAMP_MIRROR), 0.0), 1.0)
    return 1.0 - x * x * (3.0 - 2.0 * x)


@kernel(inline=True)
def lamp_share(cl, g):
    """The share of the specular lobes the mirror ray takes of the lamps it sees (at most the mirror share g):
    :func:`lamp_share_of` the closure's roughness α²^¼ (a classic closure, α² = 0, gives g)."""
    return min(g, lamp_share_of(math.sqrt(math.sqrt(max(cl.alpha2, 0.0)))))


@kernel(inline=True)
def is_black(cl):
    """The closure reflects nothing (no diffuse, no lobe): its light samples need not be taken."""
    return vec.max3(cl.diffuse) <= 0.0 and cl.metal <= 0.0 and cl.spec <= 0.0 and vec.max3(cl.spec_color) <= 0.0


@kernel(inline=True)
def perturb_normal(t_value, tangent, sign, strength, n, ng, front):
    """A tangent-space normal-map value (x, y, z) applied to the shading normal n (on the incident side of the
    geometric normal ng; ``front``: the ray hit the front face). OpenGL convention: x along the UV tangent (increasing
    s), y along sign·(n × tangent) (increasing t), z along n, computed on the front side as Cycles' Normal Map node
    does. ``strength`` blends from n (0) to the mapped normal (1). n is kept where the tangent is unusable or the
    mapped normal would face away from the incident side."""
    side = 1.0 if front else -1.0
    nf = vec.scale(n, side)
    tg = vec.sub(tangent, vec.scale(nf, vec.dot(nf, tangent)))
    if vec.dot(tg, tg) < 1e-12:
        return n
    tg = vec.normalize(tg)
    b = vec.scale(vec.cross(nf, tg), sign)
    nm = vec.normalize(vec.madd(vec.madd(vec.scale(tg, t_value[0]), b, t_value[1]), nf, t_value[2]))
    if strength != 1.0:
        nm = vec.normalize(vec.madd(nf, vec.sub(nm, nf), max(strength, 0.0)))
    nm = vec.scale(nm, side)
    if vec.dot(nm, ng) <= 1e-4:
        return n
    return nm

"""A material as a weighted sum of BSDF lobes: what a Mix Shader / Add Shader tree flattens into.

A Blender closure tree such as Mix(Fresnel, Principled, Glossy) is the sum Σᵢ wᵢ·fᵢ of its leaves' BSDFs, each
weighted by the product of the mix factors on its path ((1 − Fac) for the first input, Fac for the second; Add
Shader: 1). :mod:`tracer.shading.closures` flattens the tree and the VM (:func:`tracer.shading.vm.shade_programs`)
writes, per hit, up to :data:`MAX_LOBES` slots of (kind, weight RGB, colour, roughness, metallic, specular,
transmission) into the :class:`tracer.integrator.wavefront.SurfaceQueue`. A material whose tree is one Principled BSDF (with
emission or white transparency beside it) has no slots and keeps the one-closure path.

Kinds and what each contributes (Cycles 5.0, ``kernel/svm/closure.h``):

=============  ===========================================================================================
PRINCIPLED     :func:`tracer.shading.bsdf.principled` with its inputs; its glass part (1 − metallic)·transmission
               reflects by Fresnel (× specular tint) and refracts tinted by its base colour
DIFFUSE        Lambert, R_d = colour (:func:`tracer.shading.bsdf.lambertian`)
GLOSSY         GGX with the constant Fresnel ``colour`` (:func:`tracer.shading.bsdf.glossy`); P_SPEC = 1: multiscatter
               GGX, 0: single scattering (the node's GGX, Beckmann and Ashikhmin-Shirley distributions)
GLASS          dielectric: the mirror ray takes F·colour, the refracted ray (1 − F)·colour; rough (roughness > 0):
               both about one sampled GGX microfacet normal (:func:`tracer.optics.rough_dielectric`)
REFRACTION     the refracted ray takes colour (no Fresnel, no reflection); rough: about a sampled microfacet normal
TRANSLUCENT    Lambert from behind: colour/π·|n·l| for lights on the other side of the surface
SHEEN          :mod:`tracer.shading.sheen` (microfiber or Ashikhmin velvet, P_METAL = the distribution); P_SPEC = 1: the
               Principled sheen layer, which weights the slot before it by 1 − max(w·colour)·E(μ)
=============  ===========================================================================================

Transparent, Emission and Holdout leaves take no slot: their weights are per-hit sums (the pass-through colour
``through``, the emission, the ``holdout`` weight).

For each light sample the direct-light stage adds Σᵢ wᵢ·fᵢ(l)·cos θ_l (:func:`evaluate`, one shadow ray per light
sample); the mirror ray takes Σᵢ wᵢ·g(rᵢ)·(lobe i's albedo at the view angle) (:func:`mirror_weight`, g =
:func:`tracer.shading.bsdf.mirror_share`, the same roughness split as one closure) and the dielectric split of the glass
and refraction lobes (:func:`refraction_weights`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .. import vec
from ..jit import kernel
from . import bsdf, sheen

#: Lobe slots per hit. A tree with more reflecting leaves merges the lightest (one warning per material).
MAX_LOBES = 4

PRINCIPLED, DIFFUSE, GLOSSY, GLASS, REFRACTION, TRANSLUCENT, SHEEN = range(7)
KIND_NAMES = ("principled", "diffuse", "glossy", "glass", "refraction", "translucent", "sheen")

#: Per-slot scalar parameters (``SurfaceQueue.lobe_param``): roughness, metallic, specular level, transmission.
P_ROUGH, P_METAL, P_SPEC, P_TRANS = range(4)


class Lobes(NamedTuple):
    """A hit's lobes set up for light samples: closures, weights, mirror shares g, how many, and the summed
    weight·colour of the translucent lobes (lit from behind)."""

    cl: tuple  # MAX_LOBES × bsdf.Closure
    w: tuple  # MAX_LOBES × (r, g, b)
    g: tuple  # MAX_LOBES × float
    n: int
    translucent: tuple
    sheen: tuple  # Σ weight·colour of the sheen lobes (they share the first one's distribution and roughness)
    sheen_kind: int  # tracer.shading.sheen.MICROFIBER / ASHIKHMIN
    sheen_rough: float
    sheen_albedo: float  # its directional albedo at the view angle


@kernel(inline=True)
def _slot(kinds, w, base, prm, i, k, nl, mu, tint, ior, spawn):
    """(closure, weight, mirror share) of slot k of hit i (a black closure for slots past nl and for the kinds
    that reflect only through secondary rays)."""
    zero = (0.0, 0.0, 0.0)
    if k >= nl:
        return bsdf.lambertian(zero, mu), zero, 0.0
    kind = kinds[i, k]
    wk = (float(w[i, k, 0]), float(w[i, k, 1]), float(w[i, k, 2]))
    col = (float(base[i, k, 0]), float(base[i, k, 1]), float(base[i, k, 2]))
    r = float(prm[i, k, P_ROUGH])
    g = bsdf.mirror_share(r) if spawn else 0.0
    if kind == PRINCIPLED:
        cl = bsdf.principled(col, float(prm[i, k, P_METAL]), r, float(prm[i, k, P_SPEC]), tint, ior,
                             float(prm[i, k, P_TRANS]), mu)
        return cl, wk, g
    if kind == DIFFUSE:
        return bsdf.lambertian(col, mu), wk, 0.0
    if kind == GLOSSY:
        return bsdf.glossy(col, r, mu, float(prm[i, k, P_SPEC]) > 0.0), wk, g
    return bsdf.lambertian(zero, mu), wk, 0.0  # glass, refraction, translucent: nothing from the front


@kernel(inline=True)
def setup(kinds, w, base, prm, i, nl, n, d, tint, ior, spawn, aniso):
    """The :class:`Lobes` of hit i (``nl`` slots of the SurfaceQueue's lobe arrays) seen along d, normal n;
    ``tint``, ``ior``: the material's specular tint and IOR (its Principled lobes'); ``aniso``: the hit's
    anisotropy, which every GGX lobe takes (:func:`tracer.shading.bsdf.anisotropic`)."""
    mu = -vec.dot(n, d)
    c0, w0, g0 = _slot(kinds, w, base, prm, i, 0, nl, mu, tint, ior, spawn)
    c0 = bsdf.anisotropic(c0, aniso, n)
    c1, w1, g1 = _slot(kinds, w, base, prm, i, 1, nl, mu, tint, ior, spawn)
    c1 = bsdf.anisotropic(c1, aniso, n)
    c2, w2, g2 = _slot(kinds, w, base, prm, i, 2, nl, mu, tint, ior, spawn)
    c2 = bsdf.anisotropic(c2, aniso, n)
    c3, w3, g3 = _slot(kinds, w, base, prm, i, 3, nl, mu, tint, ior, spawn)
    c3 = bsdf.anisotropic(c3, aniso, n)
    tr = (0.0, 0.0, 0.0)
    sh = (0.0, 0.0, 0.0)
    sh_kind, sh_rough, sh_albedo, found = 0, 0.5, 0.0, False
    a0, a1, a2 = 1.0, 1.0, 1.0  # the Principled sheen layer's weight on the slot below it (slots 0-2)
    for k in range(nl):
        wc = (float(w[i, k, 0]) * base[i, k, 0], float(w[i, k, 1]) * base[i, k, 1], float(w[i, k, 2]) * base[i, k, 2])
        if kinds[i, k] == TRANSLUCENT:
            tr = vec.add(tr, wc)
        elif kinds[i, k] == SHEEN:
            if not found:
                sh_kind = int(prm[i, k, P_METAL] + 0.5)
                sh_rough = min(max(float(prm[i, k, P_ROUGH]), 0.0), 1.0)
                sh_albedo = sheen.albedo(sh_kind, sh_rough, mu)
                found = True
            sh = vec.add(sh, wc)
            if prm[i, k, P_SPEC] > 0.5 and k > 0:
                e_k = sheen.albedo(int(prm[i, k, P_METAL] + 0.5), min(max(float(prm[i, k, P_ROUGH]), 0.0), 1.0), mu)
                layer = min(max(1.0 - vec.max3(wc) * e_k, 0.0), 1.0)
                if k == 1:
                    a0 = layer
                elif k == 2:
                    a1 = layer
                else:
                    a2 = layer
    return Lobes((c0, c1, c2, c3), (vec.scale(w0, a0), vec.scale(w1, a1), vec.scale(w2, a2), w3),
                 (g0, g1, g2, g3), np.int64(nl), tr, sh,
                 np.int64(sh_kind), sh_rough, sh_albedo)


@kernel(inline=True)
def none():
    """No lobes (the one-closure path's placeholder, made once per stage call)."""
    zero = (0.0, 0.0, 0.0)
    c = bsdf.lambertian(zero, 1.0)
    return Lobes((c, c, c, c), (zero, zero, zero, zero), (0.0, 0.0, 0.0, 0.0), np.int64(0), zero, zero,
                 np.int64(0), 0.5, 0.0)


@kernel(inline=True)
def evaluate(lb, n, wi, l, n_l, mesh, glossy, diffuse):
    """Σᵢ wᵢ·fᵢ(wi, l)·cos θ_l for the unit light direction l (n·l = ``n_l``): the front lobes for n·l > 0, the
    translucent ones for n·l < 0. ``mesh``: the mirror ray also sees the light, so each lobe's specular part is
    scaled by 1 − its share of that ray (as :func:`tracer.shading.bsdf.evaluate`'s ``spec_scale``): 1 − gᵢ for an
    emitting surface or the world (``mesh`` 1), 1 − :func:`tracer.shading.bsdf.lamp_share` for a lamp (``mesh`` 2);
    ``glossy``, ``diffuse``: the light's factors on the specular and diffuse parts (light linking, 1 = all)."""
    c = (0.0, 0.0, 0.0)
    if n_l < 0.0:
        return vec.scale(lb.translucent, -n_l * bsdf.INV_PI * diffuse)
    for k in range(lb.n):
        cl = lb.cl[k]
        share = 0.0
        if mesh == 2:
            share = bsdf.lamp_share(cl, lb.g[k])
        elif mesh:
            share = lb.g[k]
        f = bsdf.evaluate(cl, n, wi, l, n_l, (1.0 - share) * glossy)
        if diffuse != 1.0:  # the diffuse part is the BSDF at spec_scale 0
            f = vec.sub(f, vec.scale(bsdf.evaluate(cl, n, wi, l, n_l, 0.0), 1.0 - diffuse))
        c = vec.add(c, vec.mul(lb.w[k], f))
    if vec.max3(lb.sheen) > 0.0:  # sheen is a diffuse-type lobe (Cycles' LABEL_DIFFUSE)
        c = vec.madd(c, lb.sheen, sheen.evaluate(lb.sheen_kind, lb.sheen_rough, n, wi, l) * diffuse)
    return c


@kernel(inline=True)
def mirror_weight(lb):
    """Σᵢ wᵢ·gᵢ·(lobe i's specular albedo at the view angle): what the mirror ray takes of the lobes."""
    c = (0.0, 0.0, 0.0)
    for k in range(lb.n):
        c = vec.add(c, vec.scale(vec.mul(lb.w[k], bsdf.specular_albedo(lb.cl[k])), lb.g[k]))
    return c


@kernel(inline=True)
def mirror_lamp_weight(lb):
    """Σᵢ wᵢ·lamp shareᵢ·(lobe i's specular albedo): what the mirror ray takes of the lobes for the lamps it sees
    (:func:`tracer.shading.bsdf.lamp_share`)."""
    c = (0.0, 0.0, 0.0)
    for k in range(lb.n):
        cl = lb.cl[k]
        c = vec.add(c, vec.scale(vec.mul(lb.w[k], bsdf.specular_albedo(cl)), bsdf.lamp_share(cl, lb.g[k])))
    return c


@kernel(inline=True)
def ambient(lb, amb):
    """Σᵢ wᵢ·(R_d,ᵢ + (1 − gᵢ)·specular albedoᵢ)·L_a: a uniform sky reflected by the lobes (unshadowed)."""
    c = (0.0, 0.0, 0.0)
    for k in range(lb.n):
        cl = lb.cl[k]
        a = vec.madd(cl.diffuse, bsdf.specular_albedo(cl), 1.0 - lb.g[k])
        c = vec.add(c, vec.mul(lb.w[k], vec.mul(a, amb)))
    return vec.madd(c, vec.mul(lb.sheen, amb), lb.sheen_albedo)


@kernel(inline=True)
def diffuse_albedo(lb):
    """Σᵢ wᵢ·R_d,ᵢ: what the lobes' diffuse parts reflect of a uniform sky (the sky stage's cosine rays carry it)."""
    c = (0.0, 0.0, 0.0)
    for k in range(lb.n):
        c = vec.add(c, vec.mul(lb.w[k], lb.cl[k].diffuse))
    return c


@kernel(inline=True)
def specular_ambient(lb):
    """Σᵢ wᵢ·(1 − gᵢ)·(lobe i's specular albedo) + the sheen lobes' weight·colour × their albedo: what the lobes'
    light-sample share reflects of a uniform sky, unshadowed (as :func:`ambient` adds them)."""
    c = (0.0, 0.0, 0.0)
    for k in range(lb.n):
        c = vec.add(c, vec.scale(vec.mul(lb.w[k], bsdf.specular_albedo(lb.cl[k])), 1.0 - lb.g[k]))
    return vec.madd(c, lb.sheen, lb.sheen_albedo)


@kernel(inline=True)
def is_black(lb):
    """No lobe reflects light samples."""
    if vec.max3(lb.translucent) > 0.0 or vec.max3(lb.sheen) > 0.0:
        return False
    for k in range(lb.n):
        if not bsdf.is_black(lb.cl[k]):
            return False
    return True


@kernel(inline=True)
def glass_roughness(kinds, w, base, prm, i, nl):
    """The roughness of hit i's glass (Glass, Refraction, a Principled's transmission) for the spawn stage's one
    microfacet sample: the lobes' roughnesses averaged by their weights (max of weight·colour; one glass lobe, the
    usual case: its own roughness)."""
    total = 0.0
    acc = 0.0
    for k in range(nl):
        kind = kinds[i, k]
        s = 1.0
        if kind == PRINCIPLED:
            s = (1.0 - float(prm[i, k, P_METAL])) * float(prm[i, k, P_TRANS])
            if s <= 0.0:
                continue
        elif kind != GLASS and kind != REFRACTION:
            continue
        wc = max(float(w[i, k, 0]) * base[i, k, 0], float(w[i, k, 1]) * base[i, k, 1],
                 float(w[i, k, 2]) * base[i, k, 2], 0.0) * s
        if kind == PRINCIPLED:  # its reflected part is the specular tint's, not the base colour's
            wc = max(wc, max(float(w[i, k, 0]), float(w[i, k, 1]), float(w[i, k, 2]), 0.0) * s)
        total += wc
        acc += wc * min(max(float(prm[i, k, P_ROUGH]), 0.0), 1.0)
    return acc / total if total > 0.0 else 0.0


@kernel(inline=True)
def glass_lamp_share(kinds, prm, i, nl):
    """The share of hit i's glass (Glass, Refraction, a Principled's transmission) whose reflected and refracted
    rays see lamps when the glass is rendered smooth (the classic model): :func:`tracer.shading.bsdf.lamp_share_of`
    its roughest such lobe (rough glass blurs a lamp over its whole highlight in Cycles; a sharp image of it is
    further from that than none). Rough glass whose rays sample microfacets sees lamps with all of them."""
    share = 1.0
    for k in range(nl):
        kind = kinds[i, k]
        if kind == GLASS or kind == REFRACTION or (kind == PRINCIPLED and float(prm[i, k, P_TRANS]) > 0.0):
            share = min(share, bsdf.lamp_share_of(float(prm[i, k, P_ROUGH])))
    return share


@kernel(inline=True)
def refraction_weights(kinds, w, base, prm, i, nl, tint):
    """(R, T, T₀) of hit i's lobes for the spawn stage: the reflected ray takes R·F and the refracted ray T·(1 − F)
    + T₀, F the dielectric Fresnel factor of the material's IOR. Glass: R = T = w·colour; Refraction: T₀ = w·colour;
    Principled: its glass part s = (1 − metallic)·transmission, R = w·s·specular tint, T = w·s·base colour."""
    r = (0.0, 0.0, 0.0)
    t = (0.0, 0.0, 0.0)
    t0 = (0.0, 0.0, 0.0)
    for k in range(nl):
        kind = kinds[i, k]
        wc = (float(w[i, k, 0]) * base[i, k, 0], float(w[i, k, 1]) * base[i, k, 1],
              float(w[i, k, 2]) * base[i, k, 2])
        if kind == GLASS:
            r = vec.add(r, wc)
            t = vec.add(t, wc)
        elif kind == REFRACTION:
            t0 = vec.add(t0, wc)
        elif kind == PRINCIPLED:
            s = (1.0 - float(prm[i, k, P_METAL])) * float(prm[i, k, P_TRANS])
            if s > 0.0:
                wk = (float(w[i, k, 0]), float(w[i, k, 1]), float(w[i, k, 2]))
                r = vec.add(r, vec.scale(vec.mul(wk, tint), s))
                t = vec.add(t, vec.scale(wc, s))
    return r, t, t0

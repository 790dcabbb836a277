"""The denoiser's guides as Cycles writes them: the Denoising Albedo and Denoising Normal passes.

Cycles (``kernel/film/denoising_passes.h``, ``film_write_denoising_features_surface``) takes the guides at the first
*non-specular* hit of the eye path, following the specular chain through mirrors and glass:

- at each hit it sums its closures' albedos into a diffuse-like part D (closures with α > 0.075, α = roughness²,
  i.e. roughness > √0.075 ≈ 0.27, and every diffuse, translucent or subsurface closure) and a specular-like part S
  (smoother microfacet lobes, glass, mirrors, transparency);
- when D is more than a quarter of D + S (or there is no closure at all), it writes: albedo += T·D, normal = the
  closures' mean shading normal in camera space (x right, y up, z along the view: Cycles' camera space), and the
  path stops carrying features;
- otherwise the path's feature throughput T is multiplied by S and the features wait for the next hit along
  whichever ray the path takes next;
- emission and the world seen while the path still carries features add T × (what the path adds there) to the
  albedo (``film_write_emission_or_background_pass``): a background seen directly has its own colour as albedo.

Cycles picks one ray per bounce at random; a Whitted tracer spawns every specular ray with its share of the weight.
So the guides here are the expectation of Cycles' per-sample guides: each ray carries ``feature`` = (P·T rgb, P),
P the probability Cycles' path would have taken this branch (each child of a hit gets the share of the weights it
carries, as Cycles samples its closures and Fresnel), and adds P·T·D to the albedo and P·n to the normal where it
stops. The pixel's passes are the mean over its samples, as Cycles' passes are.

:func:`features` is the stage kernel (run by the integrator for every batch of rays while any of them still carries
features); :func:`propagate` hands the features of the hits that wait on to the rays they spawned.
"""

from __future__ import annotations

import math

import numpy as np

from .. import optics, vec
from ..jit import kernel
from ..lights.environment import env_radiance
from ..shading import bsdf, lobes

#: Roughness above which a lobe is diffuse-like for the guides: Cycles' α_x·α_y > 0.075², α = roughness².
ROUGH_DIFFUSE_LIKE = math.sqrt(0.075)


@kernel(inline=True)
def _avg(c):
    return (c[0] + c[1] + c[2]) / 3.0


@kernel(inline=True)
def _glass_albedo(mu, front, ior, refl, tran):
    """Albedo of a smooth dielectric seen at cosine mu: F·refl + (1 − F)·tran (1 under total internal reflection)."""
    eta_i, eta_r = (1.0, ior) if front else (ior, 1.0)
    f = optics.fresnel_dielectric_1(mu, eta_i, eta_r)
    return vec.add(vec.scale(refl, f), vec.scale(tran, 1.0 - f))


@kernel(inline=True)
def _sort(dl, sl, lob, rough):
    """Add ``lob`` to the diffuse-like (rough) or the specular-like part."""
    if rough > ROUGH_DIFFUSE_LIKE:
        return vec.add(dl, lob), sl
    return dl, vec.add(sl, lob)


@kernel(inline=True)
def _one_closure(principled, base, m, rough, spec, tint, ior, w_t, k_m, cover, mirror_tint, ttint, front, mu):
    """(D, S) of a hit whose material is one closure (the parameters of :func:`tracer.integrator.wavefront._local_model`)."""
    zero = (0.0, 0.0, 0.0)
    dl, sl = zero, zero
    a = cover
    if principled:
        local = (1.0 - k_m) * a
        if local > 0.0:
            cl = bsdf.principled(base, m, rough, spec, tint, ior, w_t, mu)
            dl = vec.scale(cl.diffuse, local)
            lob = vec.scale(cl.reflect, local)
            gw = local * (1.0 - m) * w_t  # the glass part: F white, 1 − F through the transmission tint
            if gw > 0.0:
                lob = vec.madd(lob, _glass_albedo(mu, front, ior, (1.0, 1.0, 1.0), ttint), gw)
            dl, sl = _sort(dl, sl, lob, rough)
    else:  # the notes' model: Lambert R_d below, the mirror, glass and smooth metal ray above
        wl = (1.0 - k_m) * (1.0 - w_t) * a
        dl = vec.scale(base, (1.0 - m) * wl)
        sl = vec.madd(vec.scale((1.0, 1.0, 1.0), (1.0 - k_m) * w_t * a), base, wl * m)
    sl = vec.madd(sl, mirror_tint, k_m * a)  # the notes' k_m mirror
    sl = vec.add(sl, (1.0 - a, 1.0 - a, 1.0 - a))  # what passes through alpha < 1
    return dl, sl


@kernel(inline=True)
def _lobe_sum(kinds, w, base, prm, i, nl, mu, front, tint, ior):
    """(D, S) of a hit whose closure is a sum of lobes (tracer/lobes.py's kinds), before k_m and pass-through."""
    zero = (0.0, 0.0, 0.0)
    dl, sl = zero, zero
    for k in range(nl):
        kind = kinds[i, k]
        wk = (float(w[i, k, 0]), float(w[i, k, 1]), float(w[i, k, 2]))
        col = (float(base[i, k, 0]), float(base[i, k, 1]), float(base[i, k, 2]))
        r = float(prm[i, k, lobes.P_ROUGH])
        if kind == lobes.DIFFUSE or kind == lobes.TRANSLUCENT:
            dl = vec.add(dl, vec.mul(wk, col))
        elif kind == lobes.GLOSSY:
            dl, sl = _sort(dl, sl, vec.mul(wk, bsdf.glossy(col, r, mu, float(prm[i, k, lobes.P_SPEC]) > 0.0).reflect), r)
        elif kind == lobes.GLASS:
            dl, sl = _sort(dl, sl, vec.mul(wk, _glass_albedo(mu, front, ior, col, col)), r)
        elif kind == lobes.REFRACTION:
            dl, sl = _sort(dl, sl, vec.mul(wk, col), r)
        else:  # PRINCIPLED
            m = float(prm[i, k, lobes.P_METAL])
            tr = float(prm[i, k, lobes.P_TRANS])
            cl = bsdf.principled(col, m, r, float(prm[i, k, lobes.P_SPEC]), tint, ior, tr, mu)
            dl = vec.add(dl, vec.mul(wk, cl.diffuse))
            lob = cl.reflect
            gw = (1.0 - m) * tr
            if gw > 0.0:
                lob = vec.madd(lob, _glass_albedo(mu, front, ior, tint, col), gw)
            dl, sl = _sort(dl, sl, vec.mul(wk, lob), r)
    return dl, sl


@kernel(refcounts=False)
def features(surf, d, sample, weight, feature, depth, mats, opt, env, cam, g_albedo, g_normal, carry):
    """Guides stage, per ray that still carries features (``feature[i, 3]`` = P > 0; rgb = P·T): where it leaves the
    scene, the world × its throughput into the albedo; where it hits, the emission likewise, then the hit's D and S
    (module docstring): a diffuse-like hit adds P·T·D to ``g_albedo`` and P·(its normal in camera space, rows of
    ``cam``) to ``g_normal`` at the ray's sample and carries nothing on; a specular-like one writes ``carry[i]`` = S
    for :func:`propagate` (0 elsewhere)."""
    s_hit, s_cover, s_e, s_n, s_front, s_mat = surf.hit, surf.cover, surf.emission, surf.n, surf.front, surf.mat
    s_base, s_rough, s_metal, s_spec, s_tran = surf.base, surf.roughness, surf.metallic, surf.specular, \
        surf.transmission
    s_nl, s_lk, s_lw, s_lb, s_lp, s_through = surf.lobes, surf.lobe_kind, surf.lobe_w, surf.lobe_base, \
        surf.lobe_param, surf.through
    m_km, m_ior, m_tint, m_mirror, m_ttint = mats.k_m, mats.ior, mats.specular_tint, mats.mirror_tint, \
        mats.transmission_tint
    env_present, env_data, env_rot = env.present, env.data, env.rot
    bg = (opt.background[0], opt.background[1], opt.background[2])
    principled = opt.principled
    film_clear = depth == 0 and opt.transparent  # a transparent film: the world seen directly is not drawn
    for i in range(s_hit.shape[0]):
        carry[i, 0], carry[i, 1], carry[i, 2] = 0.0, 0.0, 0.0
        p = feature[i, 3]
        if p <= 0.0:
            continue
        s = sample[i]
        fr = (float(feature[i, 0]), float(feature[i, 1]), float(feature[i, 2]))
        tp = vec.scale(vec.row(weight, i), 1.0 / p)  # the throughput of Cycles' one path down this branch
        if not s_hit[i]:
            if not film_clear:
                sky = env_radiance(env_data, env_rot, vec.row(d, i)) if env_present else bg
                c = vec.mul(fr, vec.mul(tp, sky))
                g_albedo[s, 0] += c[0]
                g_albedo[s, 1] += c[1]
                g_albedo[s, 2] += c[2]
            continue
        a = float(s_cover[i])
        if a > 0.0:
            c = vec.mul(fr, vec.mul(tp, vec.scale(vec.row(s_e, i), a)))
            g_albedo[s, 0] += c[0]
            g_albedo[s, 1] += c[1]
            g_albedo[s, 2] += c[2]
        n = vec.row(s_n, i)
        mu = -vec.dot(n, vec.row(d, i))
        mat = s_mat[i]
        k_m = float(m_km[mat])
        nl = s_nl[i] if principled else -1
        if nl >= 0:
            dl, sl = _lobe_sum(s_lk, s_lw, s_lb, s_lp, i, nl, mu, s_front[i], vec.row(m_tint, mat),
                               float(m_ior[mat]))
            dl, sl = vec.scale(dl, 1.0 - k_m), vec.scale(sl, 1.0 - k_m)
            sl = vec.madd(sl, vec.row(m_mirror, mat), k_m)
            sl = vec.add(sl, vec.row(s_through, i))
        else:
            dl, sl = _one_closure(principled, vec.row(s_base, i), float(s_metal[i]), float(s_rough[i]),
                                  float(s_spec[i]), vec.row(m_tint, mat), float(m_ior[mat]), float(s_tran[i]), k_m,
                                  a, vec.row(m_mirror, mat), vec.row(m_ttint, mat), s_front[i], mu)
        wd, ws = _avg(dl), _avg(sl)
        if wd + ws <= 0.0 or 4.0 * wd > wd + ws:
            c = vec.mul(fr, dl)
            g_albedo[s, 0] += c[0]
            g_albedo[s, 1] += c[1]
            g_albedo[s, 2] += c[2]
            if wd + ws > 0.0:  # (no closure: Cycles writes a zero normal)
                for r in range(3):
                    g_normal[s, r] += p * (cam[r, 0] * n[0] + cam[r, 1] * n[1] + cam[r, 2] * n[2])
        else:
            carry[i, 0], carry[i, 1], carry[i, 2] = sl


def camera_rows(camera) -> np.ndarray:
    """World → Cycles' camera space for directions: rows x (right), y (up), z (the view direction) of the camera's
    rotation (ours looks down −z)."""
    m = np.asarray(camera.camera_to_world, np.float64)[:3, :3]
    cols = m / np.maximum(np.linalg.norm(m, axis=0, keepdims=True), 1e-30)
    return np.ascontiguousarray(np.stack([cols[:, 0], cols[:, 1], -cols[:, 2]]))


@kernel
def _add_shares(par, w, total):
    """total[parent] += each child's share (its mean weight)."""
    for j in range(par.shape[0]):
        total[par[j]] += (w[j, 0] + w[j, 1] + w[j, 2]) / 3.0


@kernel
def _hand_on(feature, carry, par, w, total, out):
    """out[j] = the features child j carries (:func:`propagate`)."""
    for j in range(par.shape[0]):
        i = par[j]
        c0, c1, c2 = carry[i, 0], carry[i, 1], carry[i, 2]
        if total[i] <= 0.0 or (c0 <= 0.0 and c1 <= 0.0 and c2 <= 0.0):
            out[j, 0], out[j, 1], out[j, 2], out[j, 3] = 0.0, 0.0, 0.0, 0.0
            continue
        pc = (w[j, 0] + w[j, 1] + w[j, 2]) / 3.0 / total[i]
        out[j, 0] = feature[i, 0] * c0 * pc
        out[j, 1] = feature[i, 1] * c1 * pc
        out[j, 2] = feature[i, 2] * c2 * pc
        out[j, 3] = feature[i, 3] * pc


def propagate(feature: np.ndarray, carry: np.ndarray, children) -> list:
    """The features of the rays a batch of hits spawned: ``children`` is a list of (parent rows, weights) of the
    spawned rays (reflections, transmissions, pass-through rays). A child of hit i gets P_c = its share of the
    average weight among i's children (the chance Cycles' path takes it) and carries (P·T·S_i·P_c, P·P_c); the
    children of hits that wrote their guides (S = 0) carry nothing. Returns one (k, 4) float32 array per entry."""
    total = np.zeros(len(feature), np.float64)
    for par, w in children:
        if len(par):
            _add_shares(par, w, total)
    out = []
    for par, w in children:
        f = np.empty((len(par), 4), np.float32)
        if len(par):
            _hand_on(feature, carry, par, w, total, f)
        out.append(f)
    return out

"""Compositing as Cycles does it: holdouts and shadow catchers, and the alpha they give.

**Holdout** (Holdout shader, object and collection holdout). Where the *eye path* (the eye ray and the rays that pass
straight through alpha < 1 surfaces; Cycles' ``PATH_RAY_TRANSPARENT_BACKGROUND``, cleared by any reflection or
refraction) meets a surface of holdout weight h, the pixel's transparency grows by mean(throughput · h)
(Cycles' ``integrate_surface_holdout``): alpha = 1 − Σ holdout weights along the eye path, with the film opaque or
transparent. A holdout object (h = its coverage) keeps nothing but what passes through it; a full holdout (h = 1)
ends the path: colour zero. A partial Holdout (a Mix Shader of Holdout and a BSDF) reads ``SurfaceQueue.holdout``,
per hit, and the rest of the closure shades as usual. Seen in a mirror or through glass, holdouts are ordinary
surfaces (the object its material, the Holdout shader black), and they cast shadows, as in Cycles.

**Shadow catcher** (``Scene.object_shadow_catcher``). Cycles splits the eye path at its first catcher hit into the
path that renders the catcher as an ordinary object (into Combined) and one that sees only catchers (the Shadow
Catcher pass's denominator); what reached the eye before the split is the *matte*. Per pixel (sums over its samples):

    shadow catcher  = (1 − α) + α · (Combined − Matte) / Catcher      (channel-wise; Catcher = 0 or no catcher: 1)
    Combined output = Matte, alpha α_m = 1 − T_m                       (with the Shadow Catcher pass asked for)
                      Matte, alpha α_m + (1 − α_m)(1 − mean(shadow catcher))   (otherwise, "approximate")
                      opaque film, approximate: Matte + Background·(1 − that alpha), alpha 1

(Cycles' ``film_calculate_shadow_catcher`` and ``…_matte_with_shadow``; α is Combined's alpha, T_m the matte's
transparency, which the split adds its throughput to; Background the world seen by the eye path, and behind the
catcher along the eye ray.) For a Whitted tracer the "catcher only" light at the split hit is the same local light
(every light sample and sky sample, emission and ambient) with its shadow rays blocked only by catchers, plus the
world along the rays it spawns (a reflection off a catcher plane sees the world, not the objects). Light that
semi-transparent surfaces in front of a catcher add through their shadow rays and reflections is counted as the
catcher's (the matte keeps what they add directly).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .. import vec
from ..jit import kernel
from ..lights.environment import env_radiance
from ..shading.graph import Out

#: Columns of the per-sample compositing array (``Tile.compose``): catcher-only light (3), the matte's colour at
#: the split (3), the matte's transparency at the split (1), split flag (1), the world behind (3).
K0, M0, MT, SPLIT, B0 = 0, 3, 6, 7, 8
COLUMNS = 11


class ComposeTables(NamedTuple):
    """What the compositing stage reads: per object id its holdout and catcher flags (padded to every id the scene
    uses), per material the holdout weight of its closure (constant Mix Shader factors), and whether any is set."""

    holdout_object: np.ndarray  # (O,) bool
    catcher_object: np.ndarray  # (O,) bool
    holdout_material: np.ndarray  # (N,) float32
    has_holdout: bool
    has_catcher: bool


def _flags(flags, n: int) -> np.ndarray:
    out = np.zeros(max(n, 1), np.bool_)
    if flags is not None:
        f = np.asarray(flags, np.bool_)[:n]
        out[:len(f)] = f
    return out


def pack(scene) -> ComposeTables:
    """The scene's :class:`ComposeTables`."""
    n = 1
    if len(scene.object_ids):
        n = int(scene.object_ids.max()) + 1
    if scene.instances is not None and len(scene.instances):
        n = max(n, int(scene.instances.object_ids.max()) + 1)
    hold = _flags(scene.object_holdout, n)
    catch = _flags(scene.object_shadow_catcher, n) & ~hold
    mats = holdout_weights(scene.materials)
    return ComposeTables(hold, catch, mats, bool(hold.any() or (mats > 0).any()), bool(catch.any()))


def holdout_weights(materials) -> np.ndarray:
    """(N,) float32: each material's Holdout weight, the sum over its closure tree's Holdout nodes of the products
    of their Mix Shader factors (a linked factor counts as 0: the per-hit weight is ``SurfaceQueue.holdout``)."""
    out = np.zeros(len(materials), np.float32)
    for i, bound in enumerate(getattr(materials, "programs", None) or ()):
        if bound is not None:
            g = bound.graph
            node = g.output_node
            if node is not None:
                out[i] = min(_holdout_of(g, g.input_value(node, "Surface")), 1.0)
    return out


def _holdout_of(g, ref, depth: int = 0) -> float:
    if not isinstance(ref, Out) or depth > 64:
        return 0.0
    node = g.node(ref)
    if node.type == "holdout":
        return 1.0
    if node.type == "add_closure":
        return sum(_holdout_of(g, g.input_value(node, s), depth + 1) for s in ("Shader", "Shader_001"))
    if node.type == "mix_closure":
        f = g.input_value(node, "Fac")
        if isinstance(f, Out):
            return 0.0
        f = min(max(float(f), 0.0), 1.0)
        return ((1.0 - f) * _holdout_of(g, g.input_value(node, "Shader"), depth + 1)
                + f * _holdout_of(g, g.input_value(node, "Shader_001"), depth + 1))
    return 0.0


def empty(n: int, used: bool) -> np.ndarray:
    """The per-sample compositing array of a tile (zero rows when the scene has no shadow catcher)."""
    return np.zeros((n if used else 0, COLUMNS), np.float32)


# ---------------------------------------------------------------------------------------------- the eye-path stage
@kernel(refcounts=False)
def eye_path(surf, prim, inst, tri_ids, inst_ids, d, sample, weight, tables, env, background, out, comp, split):
    """At depth 0 (the eye path), before the other stages: holdouts take their weight out of the pixel's alpha
    (a full holdout or a holdout object keeps only what passes through it: its weight × (1 − coverage) rides on
    with coverage 0); the first catcher hit of each eye sample splits it (``split[i]``; the matte's colour and
    transparency are recorded, the world behind the catcher along the ray too)."""
    hold_obj, catch_obj, hold_mat = tables.holdout_object, tables.catcher_object, tables.holdout_material
    s_hit, s_cover, s_mat, s_hold, s_e = surf.hit, surf.cover, surf.mat, surf.holdout, surf.emission
    o_alpha, o_color = out.alpha, out.color
    env_present, env_data, env_rot = env.present, env.data, env.rot
    catching = comp.shape[0] > 0
    for i in range(s_hit.shape[0]):
        split[i] = False
        s = sample[i]
        w = vec.row(weight, i)
        if not s_hit[i]:
            if catching:  # the world the eye path sees: behind a catcher's shadow on an opaque film
                sky = env_radiance(env_data, env_rot, vec.row(d, i)) if env_present else background
                for c in range(3):
                    comp[s, B0 + c] += w[c] * sky[c]
            continue
        k = inst[i]
        oid = tri_ids[prim[i]] if k < 0 else inst_ids[k]
        a = float(s_cover[i])
        h = max(float(s_hold[i]), float(hold_mat[s_mat[i]]))
        kill = False
        if hold_obj[oid]:
            h, kill = a, True
        elif h >= 1.0:
            h, kill = 1.0, True
        if h > 0.0:
            o_alpha[s] -= (w[0] + w[1] + w[2]) / 3.0 * h
        if kill:  # only what passes through stays: the spawn stage sends weight × (1 − 0) on
            for c in range(3):
                weight[i, c] = w[c] * (1.0 - a)
            s_cover[i] = 0.0
            continue
        if catching and catch_obj[oid] and comp[s, SPLIT] == 0.0:
            split[i] = True
            comp[s, SPLIT] = 1.0
            for c in range(3):
                comp[s, M0 + c] = o_color[s, c]
            comp[s, MT] = 1.0 - o_alpha[s] + (w[0] + w[1] + w[2]) / 3.0
            sky = env_radiance(env_data, env_rot, vec.row(d, i)) if env_present else background
            for c in range(3):
                comp[s, B0 + c] += w[c] * sky[c]
                comp[s, K0 + c] += w[c] * a * s_e[i, c]  # the catcher's own emission: seen by both paths


@kernel(refcounts=False)
def add_world(comp, sample, weight, d, rows, env, background):
    """Catcher-only light of rays spawned at split hits (``rows`` of a ray batch): the world along each, × its
    weight (past a catcher only catchers are seen; a catcher does not see itself)."""
    env_present, env_data, env_rot = env.present, env.data, env.rot
    for q in range(rows.shape[0]):
        j = rows[q]
        s = sample[j]
        sky = env_radiance(env_data, env_rot, vec.row(d, j)) if env_present else background
        for c in range(3):
            comp[s, K0 + c] += weight[j, c] * sky[c]


def add_local(comp, color, before, samples) -> None:
    """Catcher-only light the direct-light and sky stages added straight to the split samples (unshadowed terms):
    the change of their colour, ``before`` being it ahead of those stages."""
    comp[samples, K0:K0 + 3] += color[samples] - before


def catcher_blocked(accel, o, d, t_max, tables, tri_ids, inst_ids, eps, rounds: int = 16) -> np.ndarray:
    """(R,) bool: whether a catcher lies on each shadow ray (the other objects are looked through: the rays of the
    catcher-only path see only catchers)."""
    o, t_max = np.array(o, np.float32), np.array(t_max, np.float32)
    d = np.ascontiguousarray(d, np.float32)
    hit = np.zeros(len(o), bool)
    pending = np.arange(len(o))
    for _ in range(rounds):
        if not len(pending):
            break
        t, prim, _, _, inst = accel.closest_hits(o[pending], d[pending], t_max[pending])
        found = prim >= 0
        oid = tri_ids[np.maximum(prim, 0)]
        if len(inst_ids):
            oid = np.where(inst >= 0, inst_ids[np.clip(inst, 0, len(inst_ids) - 1)], oid)
        caught = found & tables.catcher_object[np.minimum(oid, len(tables.catcher_object) - 1)]
        hit[pending[caught]] = True
        go = found & ~caught
        step = (t[go] + eps).astype(np.float32)
        p = pending[go]
        o[p] += d[p] * step[:, None]
        t_max[p] -= step
        pending = p[t_max[p] > 0]
    return hit


# ---------------------------------------------------------------------------------------------- the film
def composite(color, alpha, comp, spp: int, transparent: bool, approximate: bool, spent=None):
    """Per pixel from a tile's samples (``spp`` consecutive per pixel): (rgba (P, 4), shadow catcher (P, 3)) as
    Cycles reads its Combined (the matte, with the shadow as alpha or over the world) and Shadow Catcher passes.
    With adaptive sampling, ``spent`` (P,) gives each pixel's count of consecutive samples instead."""
    if spent is None:
        n = len(alpha) // spp
        mean = lambda a: a.reshape((n, spp) + a.shape[1:]).mean(axis=1)  # noqa: E731
    else:
        starts = np.cumsum(spent) - spent
        mean = lambda a: (np.add.reduceat(a, starts, axis=0)  # noqa: E731
                          / spent.reshape((-1,) + (1,) * (a.ndim - 1)))
    split = comp[:, SPLIT] > 0
    c = mean(color)
    a_c = np.clip(mean(alpha), 0.0, 1.0)
    matte = mean(np.where(split[:, None], comp[:, M0:M0 + 3], color))
    t_m = mean(np.where(split, comp[:, MT], 1.0 - alpha))
    k = mean(comp[:, K0:K0 + 3])
    caught = mean(split.astype(np.float32)) > 0
    lit = c - matte
    ratio = np.where(k != 0.0, lit / np.where(k != 0.0, k, 1.0), 1.0)
    ratio = np.where(caught[:, None], ratio, 1.0)
    catcher = (1.0 - a_c)[:, None] + a_c[:, None] * ratio
    a_m = np.clip(1.0 - t_m, 0.0, 1.0)
    if approximate:
        a_m = (1.0 - a_m) * (1.0 - np.clip(catcher.mean(axis=1), 0.0, 1.0)) + a_m
    rgba = np.concatenate([matte, a_m[:, None]], axis=1)
    if approximate and not transparent:
        rgba[:, :3] += mean(comp[:, B0:B0 + 3]) * (1.0 - a_m)[:, None]
        rgba[:, 3] = 1.0
    return rgba.astype(np.float32), catcher.astype(np.float32)

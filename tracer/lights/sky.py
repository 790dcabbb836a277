"""The world as a light: how many sky rays a hit takes, and in which directions.

With ``RenderSettings.sky_samples`` = N > 0 (the default, 16) every lit hit sends shadow rays towards the world
("sky rays"), so the world casts shadows as Cycles' does; N = 0 keeps the notes' flat, unshadowed ambient term.

- **How many.** The eye ray's hit takes side² = round(√N)² rays. A deeper hit (seen in a mirror, through glass)
  takes fewer in proportion to what its path still carries: side_d = round(side·√(w·DEEP_SHARE)), at least 1, with
  w the largest channel of the ray's weight. A hit seen in a clear mirror keeps most of its rays (it is as visible
  as a direct one), the faint Fresnel reflections in glass take one.
- **Which directions, for a lat-long environment.** One-sample multiple importance sampling by the mixture pdf
  (the balance heuristic): a share ``ENV_SHARE`` of the stratified sample points is drawn from the environment's
  luminance × solid-angle CDF (:func:`tracer.lights.environment.env_sample`: an HDRI's sun is found with few rays), the
  rest cosine-weighted about the shading normal (a near-uniform sky, and the half of an HDRI below the horizon, are
  not wasted). Each ray carries f·L·cos θ / (α·p_env + (1 − α)·p_cos) / K.
- **A constant-colour world** (``Scene.ambient``, no environment): cosine-weighted directions, each carrying the
  ambient term R_d·L_a / K, so only visibility varies; the Principled lobes' share of a uniform sky is added
  unshadowed (their albedo × L_a).

The stage takes its points from :func:`tracer.sampling.rotated_multijitter`: multi-jittered, rotated per eye sample.
"""

from __future__ import annotations

import math

from .. import vec
from ..jit import kernel
from .environment import env_pdf, env_sample

#: Fraction of the sky rays drawn from an environment's luminance CDF (the rest: cosine-weighted).
ENV_SHARE = 0.5
#: Past the eye ray's hit, a hit takes side·√(w·DEEP_SHARE) rays per side (w: the path weight it carries).
DEEP_SHARE = 0.25


@kernel(inline=True)
def side_at(depth, side, w):
    """√ of the number of sky rays at a hit of ``depth`` whose ray carries weight w (largest channel), for
    ``side`` = √ of the eye ray's hit's."""
    if depth == 0 or side <= 1:
        return side
    return max(1, min(side, int(round(side * math.sqrt(max(w, 0.0) * DEEP_SHARE)))))


@kernel(inline=True)
def cosine_direction(n, tu, tv, s0, s1):
    """A direction about the unit normal n (with tangents tu, tv) drawn with pdf cos θ / π from (s0, s1) in [0,1)²
    (Malley: a uniform point on the disk lifted to the hemisphere)."""
    r = math.sqrt(s0)
    phi = 2.0 * math.pi * s1
    return vec.madd(vec.madd(vec.scale(n, math.sqrt(max(0.0, 1.0 - s0))), tu, r * math.cos(phi)), tv,
                    r * math.sin(phi))


@kernel(inline=True)
def env_direction(data, rot, row_cdf, col_cdf, row_pdf, col_pdf, n, tu, tv, s0, s1):
    """A sky-ray direction for an environment (the :class:`tracer.lights.environment.EnvTables` arrays) from (s0, s1): the
    first ``ENV_SHARE`` of s0 picks from the luminance CDF, the rest cosine-weighted about n; with the mixture pdf
    per steradian (0 for a direction below the surface, which the caller drops)."""
    if s0 < ENV_SHARE:
        d, _ = env_sample(data, rot, row_cdf, col_cdf, row_pdf, col_pdf, s0 / ENV_SHARE, s1)
    else:
        d = cosine_direction(n, tu, tv, (s0 - ENV_SHARE) / (1.0 - ENV_SHARE), s1)
    cos_t = vec.dot(n, d)
    p_cos = max(cos_t, 0.0) / math.pi
    return d, ENV_SHARE * env_pdf(data, rot, row_pdf, col_pdf, d) + (1.0 - ENV_SHARE) * p_cos

"""Local illumination of the seed's Cast-Ray: ambient + Σ over visible lights of Lambert + Blinn-Phong.

    c = L_a·R_a + Σ_lights visible [ L_d·R_d·max(0, n·l) + L_s·R_s·(n·h)^e ],   h = (l + v) / ‖l + v‖

In radiometric units (so the picture matches Cycles): a light delivers irradiance E on a surface facing it
(:mod:`tracer.lights.emitters`); the Lambert term is R_d/π · E · max(0, n·l), and the Blinn-Phong term is the energy-normalised
lobe R_s · (e + 8)/(8π) · (n·h)^e · E · max(0, n·l). The ambient term is R_a·L_a with R_a = R_d and L_a the world's
radiance (a uniform sky of radiance L_a gives a Lambertian surface exactly R_d·L_a).

Scalar functions on 3-tuples (colours are (r, g, b)), called per hit and light sample by the integrator's kernel.
"""

from __future__ import annotations

import math

from .. import vec
from ..jit import kernel

INV_PI = 1.0 / math.pi


@kernel(inline=True)
def half_vector(l, v):
    """h = (l + v) / ‖l + v‖ (the seed's halfway vector)."""
    return vec.normalize(vec.add(l, v))


@kernel(inline=True)
def lambert(diffuse, irradiance, n_dot_l):
    """L_d·R_d·max(0, n·l) with L_d = E/π: outgoing radiance of a Lambertian surface."""
    return vec.scale(vec.mul(diffuse, irradiance), INV_PI * max(n_dot_l, 0.0))


@kernel(inline=True)
def blinn_phong(specular, exponent, n, h, irradiance, n_dot_l):
    """L_s·R_s·(n·h)^e, energy-normalised by (e + 8)/(8π) and weighted by max(0, n·l)."""
    n_dot_h = min(max(vec.dot(n, h), 0.0), 1.0)
    lobe = (exponent + 8.0) * (1.0 / (8.0 * math.pi)) * n_dot_h**exponent
    return vec.scale(vec.mul(specular, irradiance), lobe * max(n_dot_l, 0.0))


@kernel(inline=True)
def ambient(diffuse, ambient_radiance):
    """L_a·R_a: the world's radiance reflected by a Lambertian surface (times the visible sky fraction, when the
    integrator samples it)."""
    return vec.mul(diffuse, ambient_radiance)

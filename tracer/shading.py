"""Local illumination of the seed's Cast-Ray: ambient + Σ over visible lights of Lambert + Blinn-Phong.

    c = L_a·R_a + Σ_lights visible [ L_d·R_d·max(0, n·l) + L_s·R_s·(n·h)^e ],   h = (l + v) / ‖l + v‖

In radiometric units (so the picture matches Cycles): a light delivers irradiance E on a surface facing it
(:mod:`tracer.lights`); the Lambert term is R_d/π · E · max(0, n·l), and the Blinn-Phong term is the energy-normalised
lobe R_s · (e + 8)/(8π) · (n·h)^e · E · max(0, n·l). The ambient term is R_a·L_a with R_a = R_d and L_a the world's
radiance (a uniform sky of radiance L_a gives a Lambertian surface exactly R_d·L_a).
"""

from __future__ import annotations

import numpy as np

INV_PI = np.float32(1.0 / np.pi)


def half_vector(l, v):
    """h = (l + v) / ‖l + v‖ (the seed's halfway vector)."""
    h = l + v
    h /= np.maximum(np.sqrt(np.einsum("ij,ij->i", h, h)), np.float32(1e-30))[:, None]
    return h


def lambert(n_dot_l, diffuse, irradiance):
    """L_d·R_d·max(0, n·l) with L_d = E/π: outgoing radiance of a Lambertian surface."""
    return diffuse * INV_PI * irradiance * n_dot_l


def blinn_phong(n, h, n_dot_l, specular, exponent, irradiance):
    """L_s·R_s·(n·h)^e, energy-normalised by (e + 8)/(8π) and weighted by max(0, n·l)."""
    n_dot_h = np.clip(np.einsum("ij,ij->i", n, h), 0.0, 1.0)
    lobe = (exponent + 8.0) * np.float32(1.0 / (8.0 * np.pi)) * np.power(n_dot_h, exponent)
    return specular * (lobe[:, None] * n_dot_l) * irradiance


def ambient(diffuse, ambient_radiance, sky_visibility=None):
    """L_a·R_a, optionally times the fraction of the sky a point sees (to match Cycles' shadowed world light)."""
    c = diffuse * ambient_radiance[None, :]
    return c if sky_visibility is None else c * sky_visibility[:, None]

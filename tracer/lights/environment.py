"""The world as a lat-long (equirectangular) environment image: what rays that leave the scene see, and a light.

Mapping (Cycles' and Blender's equirectangular convention, so an HDRI looks the same in both): a world direction d
is first turned into the environment's frame, e = R·d (``rotation``, world -> environment); then

    u = 0.5 − atan2(e_y, e_x) / 2π        (u = 0.5, the image's centre column, looks along +X)
    t = 0.5 + asin(e_z) / π               (t up; the image's top row is +Z, the zenith)

and the image is looked up bilinearly (wrapping around in u). Radiance = image · ``strength``.

As a light (``RenderSettings.sky_samples`` > 0, the default), :func:`env_sample` draws directions by the image's
luminance × each pixel's solid angle: a marginal CDF over rows and a conditional CDF over the columns of each row,
then a point uniform in solid angle inside the pixel (so the pdf is constant over a pixel, :func:`env_pdf`), so a sun
in an HDRI casts a sharp-edged shadow with few samples; the sky stage mixes it with cosine-weighted directions
(tracer/lights/sky.py). With ``sky_samples`` = 0 the environment lights diffuse surfaces through the notes' ambient term,
with L_a = the environment's mean radiance (:meth:`Environment.average`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from .. import vec
from ..colorspace import REC709_LUMINANCE
from ..jit import kernel

#: Luminance weights (importance of a pixel for sampling): tracer.colorspace's.
LUMINANCE = np.array(REC709_LUMINANCE)


@dataclass
class Environment:
    """A lat-long environment: ``image`` (H, W, 3) scene-linear radiance, × ``strength``, in the frame ``rotation``
    (3 × 3, world -> environment; identity: Blender's default world orientation)."""

    image: np.ndarray
    strength: float = 1.0
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))

    def __post_init__(self):
        img = np.asarray(self.image, np.float32)
        if img.ndim == 2:
            img = img[..., None]
        if img.ndim != 3 or img.shape[0] < 1 or img.shape[1] < 1 or img.shape[2] not in (1, 3, 4):
            raise ValueError(f"environment image must have shape (H, W, 1|3|4), got {np.shape(self.image)}")
        img = np.repeat(img, 3, axis=2) if img.shape[2] == 1 else img[..., :3]
        self.image = np.ascontiguousarray(np.clip(np.nan_to_num(img, nan=0.0, posinf=0.0, neginf=0.0), 0, None))
        self.strength = float(self.strength)
        if not np.isfinite(self.strength) or self.strength < 0:
            raise ValueError(f"environment strength must be a finite number >= 0, got {self.strength}")
        r = np.asarray(self.rotation, np.float64)
        if r.shape != (3, 3) or not np.all(np.isfinite(r)) or abs(abs(np.linalg.det(r)) - 1) > 1e-3:
            raise ValueError("environment rotation must be a 3x3 rotation matrix")
        self.rotation = r

    def average(self) -> np.ndarray:
        """The mean radiance over all directions (solid-angle weighted): the notes' L_a for this world."""
        w = _row_dz(self.image.shape[0])
        return (self.image * w[:, None, None]).sum(axis=(0, 1)) / (w.sum() * self.image.shape[1]) * self.strength

    def radiance(self, directions: np.ndarray) -> np.ndarray:
        """Radiance (N, 3) seen along unit world directions (N, 3) (array form of :func:`env_radiance`)."""
        d = np.ascontiguousarray(np.asarray(directions, np.float64).reshape(-1, 3))
        out = np.empty((len(d), 3), np.float64)
        env = pack_environment(self)
        _radiance_rows(env.data, env.rot, d, out)
        return out


def _row_dz(h: int) -> np.ndarray:
    """Δz = sin(latitude at a row's top) − sin(latitude at its bottom): a row's solid angle is 2π·Δz."""
    edges = np.sin((0.5 - np.arange(h + 1) / h) * np.pi)
    return edges[:-1] - edges[1:]


class EnvTables(NamedTuple):
    """The environment as the kernels read it (an empty one, ``present`` False, when the scene has none)."""

    present: bool
    data: np.ndarray  # (H, W, 3) float32 radiance (strength applied)
    rot: np.ndarray  # (3, 3) float64 world -> environment
    row_cdf: np.ndarray  # (H,) float64 marginal CDF over rows
    col_cdf: np.ndarray  # (H, W) float64 conditional CDF over the columns of each row
    row_pdf: np.ndarray  # (H,) float64 probability of each row
    col_pdf: np.ndarray  # (H, W) float64 probability of each column given its row


def pack_environment(env: Environment | None) -> EnvTables:
    if env is None:
        z = np.zeros((1, 1, 3), np.float32)
        return EnvTables(False, z, np.eye(3), np.ones(1), np.ones((1, 1)), np.ones(1), np.ones((1, 1)))
    data = np.ascontiguousarray(env.image * np.float32(env.strength), np.float32)
    h, w = data.shape[:2]
    lum = np.maximum(data.astype(np.float64) @ LUMINANCE, 0.0)
    lum = lum * _row_dz(h)[:, None] + 1e-12  # × each row's solid angle (∝ Δz); never a zero pdf
    row_sum = lum.sum(axis=1)
    col_pdf = lum / row_sum[:, None]
    row_pdf = row_sum / row_sum.sum()
    col_cdf = np.cumsum(col_pdf, axis=1)
    col_cdf[:, -1] = 1.0
    row_cdf = np.cumsum(row_pdf)
    row_cdf[-1] = 1.0
    return EnvTables(True, data, np.ascontiguousarray(env.rotation), row_cdf, np.ascontiguousarray(col_cdf),
                     row_pdf, np.ascontiguousarray(col_pdf))


@kernel(inline=True)
def _to_env(r, d):
    return (r[0, 0] * d[0] + r[0, 1] * d[1] + r[0, 2] * d[2], r[1, 0] * d[0] + r[1, 1] * d[1] + r[1, 2] * d[2],
            r[2, 0] * d[0] + r[2, 1] * d[1] + r[2, 2] * d[2])


@kernel(inline=True)
def env_radiance(data, rot, d):
    """Radiance seen along the unit world direction d (bilinear, wrapping in u, clamped at the poles) of the
    environment ``data`` (H, W, 3) in frame ``rot`` (an :class:`EnvTables`' arrays, passed one by one: kernels hand
    inlined helpers arrays, never NamedTuples, whose fields numba reference-counts per call; and read texels as
    scalars, never as row views)."""
    e = _to_env(rot, d)
    h, w = data.shape[0], data.shape[1]
    u = 0.5 - math.atan2(e[1], e[0]) / (2.0 * math.pi)
    t = 0.5 + math.asin(min(max(e[2], -1.0), 1.0)) / math.pi
    x = u * w - 0.5
    y = (1.0 - t) * h - 0.5
    xf, yf = math.floor(x), math.floor(y)
    fx, fy = x - xf, y - yf
    x0 = int(xf) % w
    x1 = (x0 + 1) % w
    y0 = min(max(int(yf), 0), h - 1)
    y1 = min(max(int(yf) + 1, 0), h - 1)
    a, b, c, dd = (1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy
    return (a * data[y0, x0, 0] + b * data[y0, x1, 0] + c * data[y1, x0, 0] + dd * data[y1, x1, 0],
            a * data[y0, x0, 1] + b * data[y0, x1, 1] + c * data[y1, x0, 1] + dd * data[y1, x1, 1],
            a * data[y0, x0, 2] + b * data[y0, x1, 2] + c * data[y1, x0, 2] + dd * data[y1, x1, 2])


@kernel(inline=True)
def _search(cdf, x):
    """The first index of the 1-D ``cdf`` whose value exceeds x."""
    lo, hi = 0, cdf.shape[0] - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if cdf[mid] > x:
            hi = mid
        else:
            lo = mid + 1
    return lo


@kernel(inline=True)
def _search_row(cdf, row, x):
    """:func:`_search` in row ``row`` of a 2-D ``cdf`` (no row view)."""
    lo, hi = 0, cdf.shape[1] - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if cdf[row, mid] > x:
            hi = mid
        else:
            lo = mid + 1
    return lo


@kernel(inline=True)
def env_sample(data, rot, row_cdf, col_cdf, row_pdf, col_pdf, s0, s1):
    """A world direction drawn with probability ∝ luminance × solid angle from (s0, s1) in [0,1)², and its pdf per
    steradian (the pixel's probability / its solid angle). The arguments are an :class:`EnvTables`' arrays."""
    h, w = data.shape[0], data.shape[1]
    row = _search(row_cdf, s0)
    before = row_cdf[row - 1] if row > 0 else 0.0
    fy = min(max((s0 - before) / max(row_pdf[row], 1e-30), 0.0), 1.0)
    col = _search_row(col_cdf, row, s1)
    cbefore = col_cdf[row, col - 1] if col > 0 else 0.0
    fx = min(max((s1 - cbefore) / max(col_pdf[row, col], 1e-30), 0.0), 1.0)
    u = (col + fx) / w
    # uniform in z = sin(latitude) inside the row, i.e. uniform in solid angle inside the pixel
    z_top = math.sin((0.5 - row / h) * math.pi)
    z_bottom = math.sin((0.5 - (row + 1.0) / h) * math.pi)
    z = z_top - fy * (z_top - z_bottom)
    rho = math.sqrt(max(0.0, 1.0 - z * z))
    lon = (0.5 - u) * 2.0 * math.pi
    e = (rho * math.cos(lon), rho * math.sin(lon), z)
    r = rot  # environment -> world is the transpose of the rotation
    d = (r[0, 0] * e[0] + r[1, 0] * e[1] + r[2, 0] * e[2], r[0, 1] * e[0] + r[1, 1] * e[1] + r[2, 1] * e[2],
         r[0, 2] * e[0] + r[1, 2] * e[1] + r[2, 2] * e[2])
    solid = (2.0 * math.pi / w) * max(z_top - z_bottom, 1e-12)  # the pixel's solid angle
    return vec.normalize(d), row_pdf[row] * col_pdf[row, col] / solid


@kernel(inline=True)
def env_pdf(data, rot, row_pdf, col_pdf, d):
    """The pdf per steradian with which :func:`env_sample` draws the unit world direction d: its pixel's probability
    / the pixel's solid angle (the same pixel grid as :func:`env_sample`: column ⌊u·W⌋, row ⌊(1 − t)·H⌋)."""
    e = _to_env(rot, d)
    h, w = data.shape[0], data.shape[1]
    u = 0.5 - math.atan2(e[1], e[0]) / (2.0 * math.pi)
    z = min(max(e[2], -1.0), 1.0)
    t = 0.5 + math.asin(z) / math.pi
    col = min(max(int(math.floor(u * w)), 0), w - 1)
    row = min(max(int(math.floor((1.0 - t) * h)), 0), h - 1)
    z_top = math.sin((0.5 - row / h) * math.pi)
    z_bottom = math.sin((0.5 - (row + 1.0) / h) * math.pi)
    solid = (2.0 * math.pi / w) * max(z_top - z_bottom, 1e-12)
    return row_pdf[row] * col_pdf[row, col] / solid


@kernel
def _radiance_rows(data, rot, d, out):
    for i in range(d.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = env_radiance(data, rot, (d[i, 0], d[i, 1], d[i, 2]))

"""Cycles' Noise Texture: Perlin gradient noise in 1-4 D and its five fractal types.

Followed: ``intern/cycles/kernel/svm/noise.h`` (Perlin noise, gradient sets, OSL's range scales),
``fractal_noise.h`` (fBM with its normalisation, multifractal, hybrid and ridged multifractal, heterogeneous
terrain) and ``noisetex.h`` (random seed offsets, distortion, the colour output) of Blender 5.0, and the manual's
Noise Texture page.

- Perlin noise: the lattice corner's gradient is picked by ``hash_uint{n}`` of the integer corner; gradients are
  Perlin's improved set (1D: ±1..8; 2D: (±1, ±2) and swapped; 3D: the 12 edge midpoints + 4 repeats; 4D: the 32
  edges of the 4-cube), blended with the quintic fade 6t⁵ − 15t⁴ + 10t³; the result is scaled to about [-1, 1] by
  0.25 / 0.6616 / 0.9820 / 0.8344 (1-4D) and wrapped every 100 000 units.
- Fractals take ``detail`` octaves (``int(detail)`` whole ones plus a fraction), ``roughness`` the amplitude ratio,
  ``lacunarity`` the frequency ratio; fBM optionally normalised to [0, 1].

The VM calls :func:`noise_texture` (returns ``(value, (r, g, b))``) or :func:`noise_value` (the value alone, a
third of the work) with the dimension and type as arguments; :func:`snoise1` ... :func:`snoise4` and
:func:`fractal` are the building blocks. :func:`noise_texture_array` is the numpy form over arrays of coordinates.
"""

from __future__ import annotations

import math

import numpy as np

from ...jit import kernel
from .hash import hash_float2_to_float, hash_float_to_float, hash_uint, hash_uint2, hash_uint3_inline, hash_uint4

#: Noise types, numbered as the VM passes them (Blender's enum names in comments).
FBM, MULTIFRACTAL, HYBRID_MULTIFRACTAL, RIDGED_MULTIFRACTAL, HETERO_TERRAIN = 0, 1, 2, 3, 4
NOISE_TYPES = {"FBM": FBM, "MULTIFRACTAL": MULTIFRACTAL, "HYBRID_MULTIFRACTAL": HYBRID_MULTIFRACTAL,
               "RIDGED_MULTIFRACTAL": RIDGED_MULTIFRACTAL, "HETERO_TERRAIN": HETERO_TERRAIN}

#: OSL's experimentally found scales that bring n-D Perlin noise to about [-1, 1] (index = dimension).
NOISE_SCALE = (0.0, 0.2500, 0.6616, 0.9820, 0.8344)
#: Coordinates wrap with this period before the lattice lookup (float precision guard in Cycles).
PERIOD = 100000.0


# ---------------------------------------------------------------------------------------------- Perlin
@kernel(inline="call")
def fade(t):
    """Perlin's quintic 6t⁵ − 15t⁴ + 10t³."""
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


@kernel(inline="call")
def _lerp(a, b, t):
    return (1.0 - t) * a + t * b


@kernel(inline="call")
def grad1(h, x):
    h = h & 15
    g = 1.0 + (h & 7)
    return -g * x if h & 8 else g * x


@kernel(inline="call")
def grad2(h, x, y):
    h = h & 7
    u = x if h < 4 else y
    v = 2.0 * (y if h < 4 else x)
    return (-u if h & 1 else u) + (-v if h & 2 else v)


@kernel(inline="call")
def grad3(h, x, y, z):
    """Cycles' ``grad3``: u = x if h < 8 else y; v = y if h < 4, x if h is 12 or 14, else z; u and v negated by bits
    0 and 1. Without branches (pairs indexed by the bits, a multiplication by ±1: exact), as the hashes are random
    and a branch on them is mispredicted half the time (Perlin 3D on scattered points 93 → 29 ns, docs/benchmarks.md)."""
    h = h & 15
    u = (x, y)[h >> 3]
    v = ((z, x)[int((h | 2) == 14)], y)[int(h < 4)]
    return u * (1.0 - 2.0 * (h & 1)) + v * (1.0 - 2.0 * ((h >> 1) & 1))


@kernel(inline="call")
def grad4(h, x, y, z, w):
    h = h & 31
    u = x if h < 24 else y
    v = y if h < 16 else z
    s = z if h < 8 else w
    return (-u if h & 1 else u) + (-v if h & 2 else v) + (-s if h & 4 else s)


@kernel
def perlin1(x):
    fl = math.floor(x)
    i = int(fl)
    fx = x - fl
    return _lerp(grad1(hash_uint(i), fx), grad1(hash_uint(i + 1), fx - 1.0), fade(fx))


@kernel
def perlin2(x, y):
    flx, fly = math.floor(x), math.floor(y)
    i, j = int(flx), int(fly)
    fx, fy = x - flx, y - fly
    u, v = fade(fx), fade(fy)
    a = _lerp(grad2(hash_uint2(i, j), fx, fy), grad2(hash_uint2(i + 1, j), fx - 1.0, fy), u)
    b = _lerp(grad2(hash_uint2(i, j + 1), fx, fy - 1.0), grad2(hash_uint2(i + 1, j + 1), fx - 1.0, fy - 1.0), u)
    return _lerp(a, b, v)


@kernel
def perlin3(x, y, z):
    """The eight corners' gradients blended trilinearly by the fades (hashes inlined, computed together)."""
    flx, fly, flz = math.floor(x), math.floor(y), math.floor(z)
    i, j, k = int(flx), int(fly), int(flz)
    fx, fy, fz = x - flx, y - fly, z - flz
    gx, gy, gz = fx - 1.0, fy - 1.0, fz - 1.0
    u, v = fade(fx), fade(fy)
    h0, h1 = hash_uint3_inline(i, j, k), hash_uint3_inline(i + 1, j, k)
    h2, h3 = hash_uint3_inline(i, j + 1, k), hash_uint3_inline(i + 1, j + 1, k)
    h4, h5 = hash_uint3_inline(i, j, k + 1), hash_uint3_inline(i + 1, j, k + 1)
    h6, h7 = hash_uint3_inline(i, j + 1, k + 1), hash_uint3_inline(i + 1, j + 1, k + 1)
    lo = _lerp(_lerp(grad3(h0, fx, fy, fz), grad3(h1, gx, fy, fz), u),
               _lerp(grad3(h2, fx, gy, fz), grad3(h3, gx, gy, fz), u), v)
    hi = _lerp(_lerp(grad3(h4, fx, fy, gz), grad3(h5, gx, fy, gz), u),
               _lerp(grad3(h6, fx, gy, gz), grad3(h7, gx, gy, gz), u), v)
    return _lerp(lo, hi, fade(fz))


@kernel
def _perlin4_layer(i, j, k, m, fx, fy, fz, fw, u, v):
    """The bilinear blend of the four corners at lattice (k, m) in z and w (offsets fz, fw)."""
    a = _lerp(grad4(hash_uint4(i, j, k, m), fx, fy, fz, fw),
              grad4(hash_uint4(i + 1, j, k, m), fx - 1.0, fy, fz, fw), u)
    b = _lerp(grad4(hash_uint4(i, j + 1, k, m), fx, fy - 1.0, fz, fw),
              grad4(hash_uint4(i + 1, j + 1, k, m), fx - 1.0, fy - 1.0, fz, fw), u)
    return _lerp(a, b, v)


@kernel
def perlin4(x, y, z, w):
    flx, fly, flz, flw = math.floor(x), math.floor(y), math.floor(z), math.floor(w)
    i, j, k, m = int(flx), int(fly), int(flz), int(flw)
    fx, fy, fz, fw = x - flx, y - fly, z - flz, w - flw
    u, v, t = fade(fx), fade(fy), fade(fz)
    lo = _lerp(_perlin4_layer(i, j, k, m, fx, fy, fz, fw, u, v),
               _perlin4_layer(i, j, k + 1, m, fx, fy, fz - 1.0, fw, u, v), t)
    hi = _lerp(_perlin4_layer(i, j, k, m + 1, fx, fy, fz, fw - 1.0, u, v),
               _perlin4_layer(i, j, k + 1, m + 1, fx, fy, fz - 1.0, fw - 1.0, u, v), t)
    return _lerp(lo, hi, fade(fw))


@kernel(inline="call")
def _wrap(p):
    """C's fmodf(p, 100000): the remainder with the sign of p (numba has no math.fmod)."""
    if abs(p) < PERIOD:
        return p
    return p - math.trunc(p / PERIOD) * PERIOD


@kernel
def snoise1(x):
    """Signed noise, about [-1, 1] (Cycles ``snoise_1d``)."""
    return NOISE_SCALE[1] * perlin1(_wrap(x))


@kernel
def snoise2(x, y):
    return NOISE_SCALE[2] * perlin2(_wrap(x), _wrap(y))


@kernel
def snoise3(x, y, z):
    return NOISE_SCALE[3] * perlin3(_wrap(x), _wrap(y), _wrap(z))


@kernel
def snoise4(x, y, z, w):
    return NOISE_SCALE[4] * perlin4(_wrap(x), _wrap(y), _wrap(z), _wrap(w))


@kernel
def snoise(p, dim):
    """Signed noise of the first ``dim`` components of the 4-tuple p."""
    if dim == 1:
        return snoise1(p[0])
    if dim == 2:
        return snoise2(p[0], p[1])
    if dim == 3:
        return snoise3(p[0], p[1], p[2])
    return snoise4(p[0], p[1], p[2], p[3])


@kernel(inline="call")
def _scale4(p, s):
    return (p[0] * s, p[1] * s, p[2] * s, p[3] * s)


# ---------------------------------------------------------------------------------------------- fractals
@kernel
def fbm(p, dim, detail, roughness, lacunarity, normalize):
    """Fractal Brownian motion: Σ roughnessⁱ · snoise(lacunarityⁱ p); normalised: 0.5 · sum / Σ amp + 0.5.
    The fractional octave blends the sums with and without it by detail − floor(detail)."""
    fscale, amp, maxamp, total = 1.0, 1.0, 0.0, 0.0
    for _ in range(int(detail) + 1):
        total += snoise(_scale4(p, fscale), dim) * amp
        maxamp += amp
        amp *= roughness
        fscale *= lacunarity
    rmd = detail - math.floor(detail)
    if rmd != 0.0:
        total2 = total + snoise(_scale4(p, fscale), dim) * amp
        if normalize:
            return _lerp(0.5 * total / maxamp + 0.5, 0.5 * total2 / (maxamp + amp) + 0.5, rmd)
        return _lerp(total, total2, rmd)
    return 0.5 * total / maxamp + 0.5 if normalize else total


@kernel
def fbm3(x, y, z, scale, detail, roughness, lacunarity, normalize):
    """:func:`noise_value` of a 3D fBM without distortion (the common Noise Texture), without the dimension and type
    dispatch: the same operations in the same order as the general path, so the same value to the bit."""
    detail = min(max(detail, 0.0), 15.0)
    roughness = max(roughness, 0.0)
    x, y, z = x * scale, y * scale, z * scale
    fscale, amp, maxamp, total = 1.0, 1.0, 0.0, 0.0
    for _ in range(int(detail) + 1):
        total += snoise3(x * fscale, y * fscale, z * fscale) * amp
        maxamp += amp
        amp *= roughness
        fscale *= lacunarity
    rmd = detail - math.floor(detail)
    if rmd != 0.0:
        total2 = total + snoise3(x * fscale, y * fscale, z * fscale) * amp
        if normalize:
            return _lerp(0.5 * total / maxamp + 0.5, 0.5 * total2 / (maxamp + amp) + 0.5, rmd)
        return _lerp(total, total2, rmd)
    return 0.5 * total / maxamp + 0.5 if normalize else total


@kernel
def multi_fractal(p, dim, detail, roughness, lacunarity):
    """Π (1 + roughnessⁱ · snoise(lacunarityⁱ p)), the fraction scaling the last factor's noise."""
    value, pwr = 1.0, 1.0
    for _ in range(int(detail) + 1):
        value *= pwr * snoise(p, dim) + 1.0
        pwr *= roughness
        p = _scale4(p, lacunarity)
    rmd = detail - math.floor(detail)
    if rmd != 0.0:
        value *= rmd * pwr * snoise(p, dim) + 1.0
    return value


@kernel
def hetero_terrain(p, dim, detail, roughness, lacunarity, offset):
    """Heterogeneous terrain: each octave adds (snoise + offset) · roughnessⁱ · (the value so far)."""
    pwr = roughness
    value = offset + snoise(p, dim)
    p = _scale4(p, lacunarity)
    for _ in range(1, int(detail) + 1):
        value += (snoise(p, dim) + offset) * pwr * value
        pwr *= roughness
        p = _scale4(p, lacunarity)
    rmd = detail - math.floor(detail)
    if rmd != 0.0:
        value += rmd * ((snoise(p, dim) + offset) * pwr * value)
    return value


@kernel
def hybrid_multi_fractal(p, dim, detail, roughness, lacunarity, offset, gain):
    """Hybrid additive/multiplicative multifractal: octaves weighted by gain · (the previous signal), capped at 1,
    stopping once the weight falls to 0.001."""
    pwr, value, weight = 1.0, 0.0, 1.0
    i = 0
    n = int(detail)
    while weight > 0.001 and i <= n:
        if weight > 1.0:
            weight = 1.0
        signal = (snoise(p, dim) + offset) * pwr
        pwr *= roughness
        value += weight * signal
        weight *= gain * signal
        p = _scale4(p, lacunarity)
        i += 1
    rmd = detail - math.floor(detail)
    if rmd != 0.0 and weight > 0.001:
        if weight > 1.0:
            weight = 1.0
        value += rmd * weight * ((snoise(p, dim) + offset) * pwr)
    return value


@kernel
def ridged_multi_fractal(p, dim, detail, roughness, lacunarity, offset, gain):
    """Ridged multifractal: (offset − |snoise|)², each octave weighted by clamp(gain · previous signal, 0, 1).
    (Cycles takes whole octaves only: the fraction of ``detail`` is ignored.)"""
    pwr = roughness
    signal = offset - abs(snoise(p, dim))
    signal *= signal
    value = signal
    for _ in range(1, int(detail) + 1):
        p = _scale4(p, lacunarity)
        weight = min(max(signal * gain, 0.0), 1.0)
        signal = offset - abs(snoise(p, dim))
        signal *= signal
        signal *= weight
        value += signal * pwr
        pwr *= roughness
    return value


@kernel
def fractal(p, dim, kind, detail, roughness, lacunarity, offset, gain, normalize):
    """The Noise Texture's ``noise_select``: one of the five fractal types (FBM ... HETERO_TERRAIN) of p."""
    if kind == MULTIFRACTAL:
        return multi_fractal(p, dim, detail, roughness, lacunarity)
    if kind == HYBRID_MULTIFRACTAL:
        return hybrid_multi_fractal(p, dim, detail, roughness, lacunarity, offset, gain)
    if kind == RIDGED_MULTIFRACTAL:
        return ridged_multi_fractal(p, dim, detail, roughness, lacunarity, offset, gain)
    if kind == HETERO_TERRAIN:
        return hetero_terrain(p, dim, detail, roughness, lacunarity, offset)
    return fbm(p, dim, detail, roughness, lacunarity, normalize)


# ---------------------------------------------------------------------------------------------- the texture
@kernel
def random_offset(seed, axis):
    """Cycles' seed offsets in [100, 200]: 1D from hash(seed), n-D component ``axis`` from hash(seed, axis)."""
    if axis < 0:
        return 100.0 + hash_float_to_float(seed) * 100.0
    return 100.0 + hash_float2_to_float(seed, float(axis)) * 100.0


@kernel
def _offset_point(p, dim, seed):
    """p + the random offset of ``seed`` (all ``dim`` components; the 1D texture uses the 1D offset)."""
    if dim == 1:
        return (p[0] + random_offset(seed, -1), p[1], p[2], p[3])
    return (p[0] + random_offset(seed, 0), p[1] + random_offset(seed, 1),
            p[2] + (random_offset(seed, 2) if dim >= 3 else 0.0), p[3] + (random_offset(seed, 3) if dim >= 4 else 0.0))


@kernel
def _distorted_point(p, dim, scale, distortion):
    """p scaled, then displaced by ``distortion`` · snoise at the seed offsets 0..dim−1 (Cycles' distortion).
    (float64 from here on, whatever the caller's register type: the fractal loops reassign the point.)"""
    p = (float(p[0]) * float(scale), float(p[1]) * float(scale), float(p[2]) * float(scale),
         float(p[3]) * float(scale))
    if distortion == 0.0:
        return p
    if dim == 1:
        return (p[0] + snoise(_offset_point(p, 1, 0.0), 1) * distortion, p[1], p[2], p[3])
    d0 = snoise(_offset_point(p, dim, 0.0), dim) * distortion
    d1 = snoise(_offset_point(p, dim, 1.0), dim) * distortion
    d2 = snoise(_offset_point(p, dim, 2.0), dim) * distortion if dim >= 3 else 0.0
    d3 = snoise(_offset_point(p, dim, 3.0), dim) * distortion if dim >= 4 else 0.0
    return (p[0] + d0, p[1] + d1, p[2] + d2, p[3] + d3)


@kernel
def noise_value(p, dim, kind, scale, detail, roughness, lacunarity, offset, gain, distortion, normalize):
    """The Noise Texture's Fac alone (what Cycles computes when the Color output is not linked: a third of the
    work of :func:`noise_texture`)."""
    detail = min(max(detail, 0.0), 15.0)
    roughness = max(roughness, 0.0)
    q = _distorted_point(p, dim, scale, distortion)
    return fractal(q, dim, kind, detail, roughness, lacunarity, offset, gain, normalize)


@kernel
def noise_texture(p, dim, kind, scale, detail, roughness, lacunarity, offset, gain, distortion, normalize):
    """Cycles' Noise Texture node on p = (x, y, z, w) (the 1D texture reads p[0] = W; 2D x, y; 3D x, y, z; 4D all),
    ``dim`` 1-4, ``kind`` one of FBM ... HETERO_TERRAIN. Returns (Fac, (r, g, b)); use :func:`noise_value` when only
    Fac is needed.

    As ``svm_node_tex_noise``: p is scaled by ``scale``, detail clamped to [0, 15], roughness to ≥ 0; distortion
    displaces p by ``distortion`` · snoise at seed offsets 0..dim−1; the colour's green and blue are the same fractal
    at the offsets of the next two seeds (dim and dim + 1; for 1D, seeds 1 and 2)."""
    detail = min(max(detail, 0.0), 15.0)
    roughness = max(roughness, 0.0)
    q = _distorted_point(p, dim, scale, distortion)
    value = fractal(q, dim, kind, detail, roughness, lacunarity, offset, gain, normalize)
    s1 = 1.0 if dim == 1 else float(dim)
    g = fractal(_offset_point(q, dim, s1), dim, kind, detail, roughness, lacunarity, offset, gain, normalize)
    b = fractal(_offset_point(q, dim, s1 + 1.0), dim, kind, detail, roughness, lacunarity, offset, gain, normalize)
    return value, (value, g, b)


# ---------------------------------------------------------------------------------------------- numpy form
@kernel
def _noise_rows(pts, dim, kind, params, normalize, fac, col):
    for i in range(pts.shape[0]):
        p = (pts[i, 0], pts[i, 1], pts[i, 2], pts[i, 3])
        v, c = noise_texture(p, dim, kind, params[0], params[1], params[2], params[3], params[4], params[5],
                             params[6], normalize)
        fac[i] = v
        col[i, 0], col[i, 1], col[i, 2] = c


def _points4(vector, w, dim):
    """(..., 3) vectors and a W (scalar or (...)) -> flat (N, 4) float64 rows ordered for noise_texture."""
    vector = np.asarray(vector, np.float64)
    w = np.broadcast_to(np.asarray(w, np.float64), vector.shape[:-1])
    if dim == 1:
        rows = np.stack([w, w * 0, w * 0, w * 0], -1)
    else:
        rows = np.concatenate([vector, w[..., None]], -1)
    return vector.shape[:-1], np.ascontiguousarray(rows.reshape(-1, 4))


def noise_texture_array(vector, w=0.0, *, dimensions=3, noise_type="FBM", scale=5.0, detail=2.0, roughness=0.5,
                        lacunarity=2.0, offset=0.0, gain=1.0, distortion=0.0, normalize=True):
    """The Noise Texture node over arrays: ``vector`` (..., 3), ``w`` (...) or scalar; Blender's defaults.
    Returns (fac (...), color (..., 3)) as float32."""
    if dimensions not in (1, 2, 3, 4):
        raise ValueError(f"noise dimensions must be 1-4, got {dimensions}")
    if noise_type not in NOISE_TYPES:
        raise ValueError(f"unknown noise type {noise_type!r}; choose from {sorted(NOISE_TYPES)}")
    shape, pts = _points4(vector, w, dimensions)
    fac = np.empty(len(pts), np.float64)
    col = np.empty((len(pts), 3), np.float64)
    params = np.array([scale, detail, roughness, lacunarity, offset, gain, distortion], np.float64)
    _noise_rows(pts, dimensions, NOISE_TYPES[noise_type], params, bool(normalize), fac, col)
    return fac.reshape(shape).astype(np.float32), col.reshape(shape + (3,)).astype(np.float32)

"""Cycles' pattern textures: Wave, Magic, Gradient, Brick, Checker and White Noise.

Followed (Blender 5.0): ``intern/cycles/kernel/svm/wave.h``, ``magic.h``, ``gradient.h``, ``brick.h``,
``checker.h``, ``white_noise.h``, and the manual's pages of these nodes. Each node is one scalar function on a
3-tuple (plus W where the node has one) that the shader VM calls per hit; ``*_array`` functions are their numpy forms.

- Wave: bands (x, y, z or diagonal: 20·coordinate) or rings (20·distance from an axis or the origin), plus phase,
  plus distortion · (2·fBM − 1) of the 3D noise (lacunarity 2, normalised); profiles sine 0.5 − 0.5 cos n,
  saw frac(n/2π), triangle 2|n/2π − round(n/2π)|. Coordinates are nudged by (p + 1e-6)·0.999999 as in Cycles.
- Magic: Blender's "magic" turbulence of sines and cosines, ``depth`` 0-10 levels.
- Gradient: linear, quadratic, easing, diagonal, spherical, quadratic sphere, radial; clamped to [0, 1].
- Brick: rows of height ``row_height``, bricks of ``brick_width``, every ``offset_frequency``-th row shifted by
  offset·width, every ``squash_frequency``-th row's bricks squashed; a tint per brick from Blender's integer noise;
  mortar where the distance to the brick's edge is below mortar size (smoothstep with mortar smooth).
- Checker: the parity of floor(x) + floor(y) + floor(z) (nudged like Wave).
- White Noise: the hash of the coordinate's float bits (so it is exactly Cycles' value at an exactly equal input).
"""

from __future__ import annotations

import math

import numpy as np

from ...jit import kernel
from .hash import (hash_float2_to_float, hash_float2_to_float3, hash_float3_to_float, hash_float3_to_float3,
                   hash_float4_to_float, hash_float4_to_float3, hash_float_to_float, hash_float_to_float3)
from .noise import fbm

TWO_PI = 6.283185307179586

BANDS, RINGS = 0, 1
WAVE_TYPES = {"BANDS": BANDS, "RINGS": RINGS}
BANDS_DIRECTIONS = {"X": 0, "Y": 1, "Z": 2, "DIAGONAL": 3}
RINGS_DIRECTIONS = {"X": 0, "Y": 1, "Z": 2, "SPHERICAL": 3}
SIN, SAW, TRI = 0, 1, 2
WAVE_PROFILES = {"SIN": SIN, "SAW": SAW, "TRI": TRI}
LINEAR, QUADRATIC, EASING, DIAGONAL, SPHERICAL, QUADRATIC_SPHERE, RADIAL = 0, 1, 2, 3, 4, 5, 6
GRADIENT_TYPES = {"LINEAR": LINEAR, "QUADRATIC": QUADRATIC, "EASING": EASING, "DIAGONAL": DIAGONAL,
                  "SPHERICAL": SPHERICAL, "QUADRATIC_SPHERE": QUADRATIC_SPHERE, "RADIAL": RADIAL}


@kernel(inline="call")
def _nudge(x):
    """Cycles' guard against unit coordinates landing exactly on a cell edge: (x + 1e-6) · 0.999999."""
    return (x + 0.000001) * 0.999999


# ---------------------------------------------------------------------------------------------- wave
@kernel
def wave(p, wave_type, direction, profile, scale, distortion, detail, detail_scale, detail_roughness, phase):
    """The Wave Texture's Fac for the coordinate p (3-tuple); ``direction`` is the bands or rings direction
    (0-3 as in BANDS_DIRECTIONS / RINGS_DIRECTIONS). Colour = (Fac, Fac, Fac)."""
    x, y, z = _nudge(p[0] * scale), _nudge(p[1] * scale), _nudge(p[2] * scale)
    if wave_type == BANDS:
        if direction == 0:
            n = x * 20.0
        elif direction == 1:
            n = y * 20.0
        elif direction == 2:
            n = z * 20.0
        else:
            n = (x + y + z) * 10.0
    else:
        rx = 0.0 if direction == 0 else x
        ry = 0.0 if direction == 1 else y
        rz = 0.0 if direction == 2 else z
        n = math.sqrt(rx * rx + ry * ry + rz * rz) * 20.0
    n += phase
    if distortion != 0.0:
        q = (x * detail_scale, y * detail_scale, z * detail_scale, 0.0)
        n += distortion * (fbm(q, 3, detail, detail_roughness, 2.0, True) * 2.0 - 1.0)
    if profile == SIN:
        return 0.5 + 0.5 * math.sin(n - 0.5 * math.pi)
    n /= TWO_PI
    if profile == SAW:
        return n - math.floor(n)
    return abs(n - math.floor(n + 0.5)) * 2.0


# ---------------------------------------------------------------------------------------------- magic
@kernel(inline="call")
def _fmod(a, b):
    return a - math.trunc(a / b) * b


@kernel
def magic(p, depth, scale, distortion):
    """The Magic Texture's colour (r, g, b) for p (3-tuple); Fac is their mean."""
    px, py, pz = _fmod(p[0], TWO_PI), _fmod(p[1], TWO_PI), _fmod(p[2], TWO_PI)
    x = math.sin((px + py + pz) * 5.0 * scale)
    y = math.cos((-px + py - pz) * 5.0 * scale)
    z = -math.cos((-px - py + pz) * 5.0 * scale)
    d = distortion
    if depth > 0:
        x *= d
        y *= d
        z *= d
        y = -math.cos(x - y + z) * d
        if depth > 1:
            x = math.cos(x - y - z) * d
            if depth > 2:
                z = math.sin(-x - y - z) * d
                if depth > 3:
                    x = -math.cos(-x + y - z) * d
                    if depth > 4:
                        y = -math.sin(-x + y + z) * d
                        if depth > 5:
                            y = -math.cos(-x + y + z) * d
                            if depth > 6:
                                x = math.cos(x + y + z) * d
                                if depth > 7:
                                    z = math.sin(x + y - z) * d
                                    if depth > 8:
                                        x = -math.cos(-x - y + z) * d
                                        if depth > 9:
                                            y = -math.sin(x - y + z) * d
    if d != 0.0:
        x /= 2.0 * d
        y /= 2.0 * d
        z /= 2.0 * d
    return (0.5 - x, 0.5 - y, 0.5 - z)


# ---------------------------------------------------------------------------------------------- gradient
@kernel
def gradient(p, gradient_type):
    """The Gradient Texture's Fac (clamped to [0, 1]) for p (3-tuple)."""
    x, y, z = p
    if gradient_type == LINEAR:
        f = x
    elif gradient_type == QUADRATIC:
        r = max(x, 0.0)
        f = r * r
    elif gradient_type == EASING:
        r = min(max(x, 0.0), 1.0)
        t = r * r
        f = 3.0 * t - 2.0 * t * r
    elif gradient_type == DIAGONAL:
        f = (x + y) * 0.5
    elif gradient_type == RADIAL:
        f = math.atan2(y, x) / TWO_PI + 0.5
    else:
        r = max(0.999999 - math.sqrt(x * x + y * y + z * z), 0.0)
        f = r * r if gradient_type == QUADRATIC_SPHERE else r
    return min(max(f, 0.0), 1.0)


# ---------------------------------------------------------------------------------------------- brick
@kernel
def brick_noise(n):
    """Blender's fast integer noise of a brick's id -> [0, 1) (uint32 arithmetic)."""
    n = (n + 1013) & 0x7FFFFFFF
    n = (n >> 13) ^ n
    t = ((n * n) & 0xFFFFFFFF) * 60493
    t = (t + 19990303) & 0xFFFFFFFF
    nn = (n * t + 1376312589) & 0x7FFFFFFF
    return 0.5 * (float(np.float32(nn)) / 1073741824.0)


@kernel
def brick(p, scale, mortar_size, mortar_smooth, bias, brick_width, row_height, offset_amount, offset_frequency,
          squash_amount, squash_frequency):
    """The Brick Texture's (tint, mortar) for p (3-tuple): tint in [0, 1] mixes Color1 → Color2, mortar is Fac."""
    x0, y0 = p[0] * scale, p[1] * scale
    rownum = int(math.floor(y0 / row_height))
    offset = 0.0
    if offset_frequency != 0 and squash_frequency != 0:
        if rownum % squash_frequency == 0:  # C's % and Python's agree on zero remainders
            brick_width *= squash_amount
        if rownum % offset_frequency == 0:
            offset = brick_width * offset_amount
    bricknum = int(math.floor((x0 + offset) / brick_width))
    x = (x0 + offset) - brick_width * bricknum
    y = y0 - row_height * rownum
    tint = min(max(brick_noise(((rownum << 16) + (bricknum & 0xFFFF)) & 0xFFFFFFFF) + bias, 0.0), 1.0)
    min_dist = min(min(x, y), min(brick_width - x, row_height - y))
    if min_dist >= mortar_size:
        mortar = 0.0
    elif mortar_smooth == 0.0:
        mortar = 1.0
    else:
        f = (1.0 - min_dist / mortar_size) / mortar_smooth
        if f <= 0.0:
            mortar = 0.0
        elif f >= 1.0:
            mortar = 1.0
        else:
            mortar = 3.0 * f * f - 2.0 * f * f * f
    return tint, mortar


@kernel
def brick_color(p, color1, color2, mortar_color, scale, mortar_size, mortar_smooth, bias, brick_width, row_height,
                offset_amount, offset_frequency, squash_amount, squash_frequency):
    """The Brick Texture node: (Color (r, g, b), Fac)."""
    tint, f = brick(p, scale, mortar_size, mortar_smooth, bias, brick_width, row_height, offset_amount,
                    offset_frequency, squash_amount, squash_frequency)
    c = color1
    if f != 1.0:
        c = ((1.0 - tint) * color1[0] + tint * color2[0], (1.0 - tint) * color1[1] + tint * color2[1],
             (1.0 - tint) * color1[2] + tint * color2[2])
    return (c[0] * (1.0 - f) + mortar_color[0] * f, c[1] * (1.0 - f) + mortar_color[1] * f,
            c[2] * (1.0 - f) + mortar_color[2] * f), f


# ---------------------------------------------------------------------------------------------- checker
@kernel
def checker(p, scale):
    """The Checker Texture's Fac: 1 where |floor x|, |floor y|, |floor z| have the parity pattern of Color1."""
    xi = abs(int(math.floor(_nudge(p[0] * scale))))
    yi = abs(int(math.floor(_nudge(p[1] * scale))))
    zi = abs(int(math.floor(_nudge(p[2] * scale))))
    return 1.0 if ((xi % 2 == yi % 2) == (zi % 2 == 1)) else 0.0


# ---------------------------------------------------------------------------------------------- white noise
@kernel
def white_noise(p, w, dim):
    """The White Noise Texture: (Value, (r, g, b)) hashed from the float32 bits of the inputs (1D: W only)."""
    if dim == 1:
        return hash_float_to_float(w), hash_float_to_float3(w)
    if dim == 2:
        return hash_float2_to_float(p[0], p[1]), hash_float2_to_float3(p[0], p[1])
    if dim == 3:
        return hash_float3_to_float(p[0], p[1], p[2]), hash_float3_to_float3(p[0], p[1], p[2])
    return hash_float4_to_float(p[0], p[1], p[2], w), hash_float4_to_float3(p[0], p[1], p[2], w)


# ---------------------------------------------------------------------------------------------- numpy forms
def _rows3(vector):
    v = np.asarray(vector, np.float64)
    return v.shape[:-1], np.ascontiguousarray(v.reshape(-1, 3))


@kernel
def _wave_rows(pts, ints, fl, out):
    for i in range(pts.shape[0]):
        out[i] = wave((pts[i, 0], pts[i, 1], pts[i, 2]), ints[0], ints[1], ints[2], fl[0], fl[1], fl[2], fl[3],
                      fl[4], fl[5])


def wave_array(vector, *, wave_type="BANDS", bands_direction="X", rings_direction="X", wave_profile="SIN",
               scale=5.0, distortion=0.0, detail=2.0, detail_scale=1.0, detail_roughness=0.5, phase_offset=0.0):
    """Wave Texture Fac over (..., 3) coordinates (Blender's defaults)."""
    shape, pts = _rows3(vector)
    direction = BANDS_DIRECTIONS[bands_direction] if wave_type == "BANDS" else RINGS_DIRECTIONS[rings_direction]
    ints = np.array([WAVE_TYPES[wave_type], direction, WAVE_PROFILES[wave_profile]], np.int64)
    fl = np.array([scale, distortion, detail, detail_scale, detail_roughness, phase_offset], np.float64)
    out = np.empty(len(pts))
    _wave_rows(pts, ints, fl, out)
    return out.reshape(shape).astype(np.float32)


@kernel
def _magic_rows(pts, depth, scale, distortion, out):
    for i in range(pts.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = magic((pts[i, 0], pts[i, 1], pts[i, 2]), depth, scale, distortion)


def magic_array(vector, *, turbulence_depth=2, scale=5.0, distortion=1.0):
    """Magic Texture colour (..., 3); its Fac is ``color.mean(-1)``."""
    shape, pts = _rows3(vector)
    out = np.empty((len(pts), 3))
    _magic_rows(pts, int(turbulence_depth), float(scale), float(distortion), out)
    return out.reshape(shape + (3,)).astype(np.float32)


@kernel
def _gradient_rows(pts, kind, out):
    for i in range(pts.shape[0]):
        out[i] = gradient((pts[i, 0], pts[i, 1], pts[i, 2]), kind)


def gradient_array(vector, *, gradient_type="LINEAR"):
    """Gradient Texture Fac over (..., 3) coordinates."""
    shape, pts = _rows3(vector)
    out = np.empty(len(pts))
    _gradient_rows(pts, GRADIENT_TYPES[gradient_type], out)
    return out.reshape(shape).astype(np.float32)


@kernel
def _brick_rows(pts, cols, fl, offset_frequency, squash_frequency, out, fac):
    c1 = (cols[0, 0], cols[0, 1], cols[0, 2])
    c2 = (cols[1, 0], cols[1, 1], cols[1, 2])
    cm = (cols[2, 0], cols[2, 1], cols[2, 2])
    for i in range(pts.shape[0]):
        c, f = brick_color((pts[i, 0], pts[i, 1], pts[i, 2]), c1, c2, cm, fl[0], fl[1], fl[2], fl[3], fl[4], fl[5],
                           fl[6], offset_frequency, fl[7], squash_frequency)
        out[i, 0], out[i, 1], out[i, 2] = c
        fac[i] = f


def brick_array(vector, *, color1=(0.8, 0.8, 0.8), color2=(0.2, 0.2, 0.2), mortar=(0.0, 0.0, 0.0), scale=5.0,
                mortar_size=0.02, mortar_smooth=0.1, bias=0.0, brick_width=0.5, row_height=0.25, offset=0.5,
                offset_frequency=2, squash=1.0, squash_frequency=2):
    """Brick Texture (Color (..., 3), Fac (...)) with Blender's defaults."""
    shape, pts = _rows3(vector)
    cols = np.array([color1[:3], color2[:3], mortar[:3]], np.float64)
    fl = np.array([scale, mortar_size, mortar_smooth, bias, brick_width, row_height, offset, squash], np.float64)
    out, fac = np.empty((len(pts), 3)), np.empty(len(pts))
    _brick_rows(pts, cols, fl, int(offset_frequency), int(squash_frequency), out, fac)
    return out.reshape(shape + (3,)).astype(np.float32), fac.reshape(shape).astype(np.float32)


@kernel
def _checker_rows(pts, scale, out):
    for i in range(pts.shape[0]):
        out[i] = checker((pts[i, 0], pts[i, 1], pts[i, 2]), scale)


def checker_array(vector, *, color1=(0.8, 0.8, 0.8), color2=(0.2, 0.2, 0.2), scale=5.0):
    """Checker Texture (Color (..., 3), Fac (...))."""
    shape, pts = _rows3(vector)
    fac = np.empty(len(pts))
    _checker_rows(pts, float(scale), fac)
    fac = fac.reshape(shape)
    color = np.where(fac[..., None] == 1.0, np.asarray(color1[:3]), np.asarray(color2[:3]))
    return color.astype(np.float32), fac.astype(np.float32)


@kernel
def _white_rows(pts, w, dim, value, color):
    for i in range(pts.shape[0]):
        v, c = white_noise((pts[i, 0], pts[i, 1], pts[i, 2]), w[i], dim)
        value[i] = v
        color[i, 0], color[i, 1], color[i, 2] = c


def white_noise_array(vector, w=0.0, *, dimensions=3):
    """White Noise Texture (Value (...), Color (..., 3)); inputs are hashed as float32."""
    shape, pts = _rows3(np.asarray(vector, np.float32))
    ww = np.ascontiguousarray(np.broadcast_to(np.asarray(w, np.float32), shape).reshape(-1).astype(np.float64))
    value, color = np.empty(len(pts)), np.empty((len(pts), 3))
    _white_rows(pts, ww, int(dimensions), value, color)
    return value.reshape(shape).astype(np.float32), color.reshape(shape + (3,)).astype(np.float32)

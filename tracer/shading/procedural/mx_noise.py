"""MaterialX's noises (``noise2d/3d``, ``fractal2d/3d``, ``cellnoise2d/3d``, ``worleynoise2d/3d``), which are not
Cycles' noises: MaterialX ports Open Shading Language's (``oslnoise.h``: ``snoise``, ``cellnoise``) to its shading
languages (``libraries/stdlib/genglsl/lib/mx_noise.glsl``), and these follow that description.

- Perlin gradient noise on the integer lattice: the corner's hash is Bob Jenkins' lookup3 of the corner's integer
  coordinates (the same ``hashword`` Cycles uses: :mod:`tracer.shading.procedural.hash`), its low 3 (2D) or 4 (3D) bits
  pick a gradient (±1, ±2)/(±2, ±1) in 2D, a cube edge in 3D; quintic fade 6t⁵ − 15t⁴ + 10t³; the result scaled by
  0.6616 (2D) or 0.9820 (3D). Vector-valued noise takes its three channels from bytes 0, 1 and 2 of one hash.
- Cell noise: the hash of the floored coordinates as a float in [0, 1] (bits / (2³² − 1)); a vector from the
  hashes of (cell, 0), (cell, 1), (cell, 2).
- Fractal noise: ``octaves`` of Perlin noise, amplitude × ``diminish`` and position × ``lacunarity`` per octave
  (no normalisation); the 2-vector's second channel and the 4-vector's w read the float noise at p + (19, 193[, 17]).
- Worley noise: the 3×3(×3) cells around p, each with one feature point at its cell noise vector (−½, × jitter, +½);
  the Euclidean distances to the nearest one, two, three of them (float, vector2, vector3), or with ``style`` 1
  (solid) the cell noise of the nearest feature point.

Scalars in, scalars out (numba), for the shader VM's ``mx_noise`` op: :func:`mx_noise`.
"""

from __future__ import annotations

import math

from ...jit import kernel
from .hash import hash_uint, hash_uint2, hash_uint3, hash_uint4

#: ``kind`` codes of :func:`mx_noise` (the IR node's ``kind`` parameter, in this order).
KINDS = ("perlin", "cell", "worley", "fractal")
PERLIN, CELL, WORLEY, FRACTAL = range(4)
#: Gradient-sum normalisation of the 2D and 3D Perlin noise (OSL's and MaterialX's constants).
SCALE_2D, SCALE_3D = 0.6616, 0.9820
_INV_UINT = 1.0 / 4294967295.0


@kernel(inline="call")
def _bits_to_01(h):
    return h * _INV_UINT


@kernel(inline="call")
def _fade(t):
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


@kernel(inline="call")
def _neg_if(v, b):
    return -v if b else v


@kernel
def _grad2(h, x, y):
    h &= 7
    u = x if h < 4 else y
    v = 2.0 * (y if h < 4 else x)
    return _neg_if(u, h & 1) + _neg_if(v, h & 2)


@kernel
def _grad3(h, x, y, z):
    h &= 15
    u = x if h < 8 else y
    v = y if h < 4 else (x if (h == 12 or h == 14) else z)
    return _neg_if(u, h & 1) + _neg_if(v, h & 2)


@kernel(inline="call")
def _lerp(a, b, t):
    return a * (1.0 - t) + b * t


@kernel
def perlin2(x, y):
    """``mx_perlin_noise_float(vec2)``: OSL's 2D ``snoise``."""
    fx, fy = math.floor(x), math.floor(y)
    X, Y = int(fx), int(fy)
    fx, fy = x - fx, y - fy
    u, v = _fade(fx), _fade(fy)
    r = _lerp(_lerp(_grad2(hash_uint2(X, Y), fx, fy), _grad2(hash_uint2(X + 1, Y), fx - 1.0, fy), u),
              _lerp(_grad2(hash_uint2(X, Y + 1), fx, fy - 1.0), _grad2(hash_uint2(X + 1, Y + 1), fx - 1.0, fy - 1.0),
                    u), v)
    return SCALE_2D * r


@kernel
def perlin3(x, y, z):
    """``mx_perlin_noise_float(vec3)``: OSL's 3D ``snoise``."""
    fx, fy, fz = math.floor(x), math.floor(y), math.floor(z)
    X, Y, Z = int(fx), int(fy), int(fz)
    fx, fy, fz = x - fx, y - fy, z - fz
    u, v, w = _fade(fx), _fade(fy), _fade(fz)
    z0 = _lerp(_lerp(_grad3(hash_uint3(X, Y, Z), fx, fy, fz), _grad3(hash_uint3(X + 1, Y, Z), fx - 1.0, fy, fz), u),
               _lerp(_grad3(hash_uint3(X, Y + 1, Z), fx, fy - 1.0, fz),
                     _grad3(hash_uint3(X + 1, Y + 1, Z), fx - 1.0, fy - 1.0, fz), u), v)
    z1 = _lerp(_lerp(_grad3(hash_uint3(X, Y, Z + 1), fx, fy, fz - 1.0),
                     _grad3(hash_uint3(X + 1, Y, Z + 1), fx - 1.0, fy, fz - 1.0), u),
               _lerp(_grad3(hash_uint3(X, Y + 1, Z + 1), fx, fy - 1.0, fz - 1.0),
                     _grad3(hash_uint3(X + 1, Y + 1, Z + 1), fx - 1.0, fy - 1.0, fz - 1.0), u), v)
    return SCALE_3D * _lerp(z0, z1, w)


@kernel
def _perlin2_ch(x, y, shift):
    """One channel of ``mx_perlin_noise_vec3(vec2)``: byte ``shift``/8 of the corner hashes."""
    fx, fy = math.floor(x), math.floor(y)
    X, Y = int(fx), int(fy)
    fx, fy = x - fx, y - fy
    u, v = _fade(fx), _fade(fy)
    r = _lerp(_lerp(_grad2((hash_uint2(X, Y) >> shift) & 255, fx, fy),
                    _grad2((hash_uint2(X + 1, Y) >> shift) & 255, fx - 1.0, fy), u),
              _lerp(_grad2((hash_uint2(X, Y + 1) >> shift) & 255, fx, fy - 1.0),
                    _grad2((hash_uint2(X + 1, Y + 1) >> shift) & 255, fx - 1.0, fy - 1.0), u), v)
    return SCALE_2D * r


@kernel
def _perlin3_ch(x, y, z, shift):
    """One channel of ``mx_perlin_noise_vec3(vec3)``."""
    fx, fy, fz = math.floor(x), math.floor(y), math.floor(z)
    X, Y, Z = int(fx), int(fy), int(fz)
    fx, fy, fz = x - fx, y - fy, z - fz
    u, v, w = _fade(fx), _fade(fy), _fade(fz)
    z0 = _lerp(_lerp(_grad3((hash_uint3(X, Y, Z) >> shift) & 255, fx, fy, fz),
                     _grad3((hash_uint3(X + 1, Y, Z) >> shift) & 255, fx - 1.0, fy, fz), u),
               _lerp(_grad3((hash_uint3(X, Y + 1, Z) >> shift) & 255, fx, fy - 1.0, fz),
                     _grad3((hash_uint3(X + 1, Y + 1, Z) >> shift) & 255, fx - 1.0, fy - 1.0, fz), u), v)
    z1 = _lerp(_lerp(_grad3((hash_uint3(X, Y, Z + 1) >> shift) & 255, fx, fy, fz - 1.0),
                     _grad3((hash_uint3(X + 1, Y, Z + 1) >> shift) & 255, fx - 1.0, fy, fz - 1.0), u),
               _lerp(_grad3((hash_uint3(X, Y + 1, Z + 1) >> shift) & 255, fx, fy - 1.0, fz - 1.0),
                     _grad3((hash_uint3(X + 1, Y + 1, Z + 1) >> shift) & 255, fx - 1.0, fy - 1.0, fz - 1.0), u), v)
    return SCALE_3D * _lerp(z0, z1, w)


@kernel
def perlin_vec3(x, y, z, dims):
    """``mx_perlin_noise_vec3`` in 2 or 3 dimensions (OSL's vector ``snoise``)."""
    if dims == 2:
        return _perlin2_ch(x, y, 0), _perlin2_ch(x, y, 8), _perlin2_ch(x, y, 16)
    return _perlin3_ch(x, y, z, 0), _perlin3_ch(x, y, z, 8), _perlin3_ch(x, y, z, 16)


@kernel
def perlin(x, y, z, dims):
    return perlin2(x, y) if dims == 2 else perlin3(x, y, z)


@kernel
def cell_float(x, y, z, dims):
    """``mx_cell_noise_float`` (OSL's ``cellnoise``) in 1–3 dimensions."""
    ix, iy, iz = int(math.floor(x)), int(math.floor(y)), int(math.floor(z))
    if dims == 1:
        return _bits_to_01(hash_uint(ix))
    if dims == 2:
        return _bits_to_01(hash_uint2(ix, iy))
    return _bits_to_01(hash_uint3(ix, iy, iz))


@kernel
def cell_vec3(x, y, z, dims):
    """``mx_cell_noise_vec3`` (OSL's vector ``cellnoise``) in 2 or 3 dimensions."""
    ix, iy, iz = int(math.floor(x)), int(math.floor(y)), int(math.floor(z))
    if dims == 2:
        return (_bits_to_01(hash_uint3(ix, iy, 0)), _bits_to_01(hash_uint3(ix, iy, 1)),
                _bits_to_01(hash_uint3(ix, iy, 2)))
    return (_bits_to_01(hash_uint4(ix, iy, iz, 0)), _bits_to_01(hash_uint4(ix, iy, iz, 1)),
            _bits_to_01(hash_uint4(ix, iy, iz, 2)))


@kernel
def fractal(x, y, z, dims, octaves, lacunarity, diminish, vector):
    """``mx_fractal{2,3}d_noise_float`` / ``_vec3`` (``vector``): the octave sum, not normalised."""
    r0, r1, r2 = 0.0, 0.0, 0.0
    amp = 1.0
    for _ in range(int(octaves)):
        if vector:
            a, b, c = perlin_vec3(x, y, z, dims)
            r0 += amp * a
            r1 += amp * b
            r2 += amp * c
        else:
            r0 += amp * perlin(x, y, z, dims)
        amp *= diminish
        x, y, z = x * lacunarity, y * lacunarity, z * lacunarity
    return r0, r1, r2


@kernel
def worley(x, y, z, dims, jitter, style):
    """``mx_worley_noise_vec3`` (Euclidean): the three smallest distances (or, ``style`` 1, the cell noise vector of
    the nearest feature point) and ``mx_worley_noise_float``'s solid value (the float cell noise there)."""
    fx, fy, fz = math.floor(x), math.floor(y), math.floor(z)
    X, Y, Z = int(fx), int(fy), int(fz)
    lx, ly, lz = x - fx, y - fy, z - fz
    d0, d1, d2 = 1e6, 1e6, 1e6
    m0, m1, m2 = 0.0, 0.0, 0.0
    zr = 1 if dims == 3 else 0
    for i in range(-1, 2):
        for j in range(-1, 2):
            for k in range(-zr, zr + 1):
                if dims == 2:
                    o0, o1, o2 = cell_vec3(float(i + X), float(j + Y), 0.0, 2)
                    o2 = 0.5
                else:
                    o0, o1, o2 = cell_vec3(float(i + X), float(j + Y), float(k + Z), 3)
                cx = i + (o0 - 0.5) * jitter + 0.5 - lx
                cy = j + (o1 - 0.5) * jitter + 0.5 - ly
                cz = (k + (o2 - 0.5) * jitter + 0.5 - lz) if dims == 3 else 0.0
                dist = cx * cx + cy * cy + cz * cz
                if dist < d0:
                    d2, d1, d0 = d1, d0, dist
                    m0, m1, m2 = cx, cy, cz
                elif dist < d1:
                    d2, d1 = d1, dist
                elif dist < d2:
                    d2 = dist
    if style == 1:
        px, py, pz = m0 + x, m1 + y, m2 + z
        a, b, c = cell_vec3(px, py, pz, dims)
        return a, b, c, cell_float(px, py, pz, dims)
    return math.sqrt(d0), math.sqrt(d1), math.sqrt(d2), math.sqrt(d0)


@kernel
def mx_noise(kind, dims, width, style, x, y, z, a0, a1, a2, a3, pivot, octaves, lacunarity, diminish, jitter):
    """One MaterialX noise node at (x, y[, z]) with output ``width`` 1–4 (float, vector2, vector3/color3,
    vector4/color4): (x, y, z, w) of its result, amplitude (a0..a3) and pivot applied as its node does."""
    r0, r1, r2, r3 = 0.0, 0.0, 0.0, 0.0
    if kind == PERLIN:
        if width == 1:
            r0 = perlin(x, y, z, dims)
        else:
            r0, r1, r2 = perlin_vec3(x, y, z, dims)
            if width == 4:
                r3 = perlin2(x + 19.0, y + 73.0) if dims == 2 else perlin3(x + 19.0, y + 73.0, z + 29.0)
        return r0 * a0 + pivot, r1 * a1 + pivot, r2 * a2 + pivot, r3 * a3 + pivot
    if kind == FRACTAL:
        if width == 1:
            r0, r1, r2 = fractal(x, y, z, dims, octaves, lacunarity, diminish, False)
        elif width == 2:
            r0, r1, r2 = fractal(x, y, z, dims, octaves, lacunarity, diminish, False)
            r1, q1, q2 = fractal(x + 19.0, y + 193.0, z + 17.0, dims, octaves, lacunarity, diminish, False)
        else:
            r0, r1, r2 = fractal(x, y, z, dims, octaves, lacunarity, diminish, True)
            if width == 4:
                r3, q1, q2 = fractal(x + 19.0, y + 193.0, z + 17.0, dims, octaves, lacunarity, diminish, False)
        return r0 * a0, r1 * a1, r2 * a2, r3 * a3
    if kind == CELL:
        if width == 1:
            return cell_float(x, y, z, dims), 0.0, 0.0, 0.0
        r0, r1, r2 = cell_vec3(x, y, z, dims)
        return r0, r1, r2, 0.0
    r0, r1, r2, f = worley(x, y, z, dims, jitter, style)
    if width == 1:
        return f, 0.0, 0.0, 0.0
    return r0, r1, r2, 0.0

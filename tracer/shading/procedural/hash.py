"""Cycles' integer and float hashes: Bob Jenkins' lookup3 (``hashlittle``'s ``mix``/``final``) on 1-4 words.

Followed: ``intern/cycles/util/hash.h`` (Blender 5.0). Every procedural texture of Cycles draws its randomness from
these: Perlin noise hashes the integer lattice corner, Voronoi the cell, White Noise the float bits of its input.

Words are uint32 held in Python/numba ints (int64) and masked after every operation, so the arithmetic wraps as
C's ``uint`` does; a negative int (a lattice coordinate) enters as its two's complement, as C's ``(uint)`` cast does.
Float inputs are hashed by their *float32* bit pattern (``__float_as_uint``), computed here without an array view so
that the scalar functions stay allocation-free inside kernels.

Voronoi's 2-4D cells use the PCG hashes (``hash_pcg{2,3,4}d_i``, signed-int variant) of the same header.

Scalar functions (``@kernel``) for the shader VM; :func:`hash_uint_array` etc. are numpy forms.
"""

from __future__ import annotations

import math

import numpy as np

from ...jit import kernel

M32 = 0xFFFFFFFF
#: lookup3's initial value for n words: 0xdeadbeef + (n << 2) + 13 (the ``length`` in bytes, seed 13).
_INIT = (0, 0xDEADBEEF + (1 << 2) + 13, 0xDEADBEEF + (2 << 2) + 13, 0xDEADBEEF + (3 << 2) + 13,
         0xDEADBEEF + (4 << 2) + 13)
#: 1 / (2^32 - 1) as float32, Cycles' uint_to_float_incl ([0, 1] inclusive).
_INV_UINT_MAX = float(np.float32(1.0) / np.float32(4294967295.0))


@kernel(inline="call")
def rot(x, k):
    """32-bit rotate left."""
    return ((x << k) | (x >> (32 - k))) & M32


@kernel(inline="call")
def _final(a, b, c):
    """lookup3's ``final(a, b, c)``: the last avalanche of the three words; returns (a, b, c)."""
    c = ((c ^ b) - rot(b, 14)) & M32
    a = ((a ^ c) - rot(c, 11)) & M32
    b = ((b ^ a) - rot(a, 25)) & M32
    c = ((c ^ b) - rot(b, 16)) & M32
    a = ((a ^ c) - rot(c, 4)) & M32
    b = ((b ^ a) - rot(a, 14)) & M32
    c = ((c ^ b) - rot(b, 24)) & M32
    return a, b, c


@kernel
def _mix(a, b, c):
    """lookup3's ``mix(a, b, c)`` (between 3-word blocks, needed by the 4-word hash)."""
    a = ((a - c) & M32) ^ rot(c, 4)
    c = (c + b) & M32
    b = ((b - a) & M32) ^ rot(a, 6)
    a = (a + c) & M32
    c = ((c - b) & M32) ^ rot(b, 8)
    b = (b + a) & M32
    a = ((a - c) & M32) ^ rot(c, 16)
    c = (c + b) & M32
    b = ((b - a) & M32) ^ rot(a, 19)
    a = (a + c) & M32
    c = ((c - b) & M32) ^ rot(b, 4)
    b = (b + a) & M32
    return a, b, c


@kernel
def hash_uint(kx):
    """lookup3 of one 32-bit word (Cycles ``hash_uint``)."""
    a = b = c = _INIT[1]
    a = (a + (kx & M32)) & M32
    a, b, c = _final(a, b, c)
    return c


@kernel
def hash_uint2(kx, ky):
    a = b = c = _INIT[2]
    b = (b + (ky & M32)) & M32
    a = (a + (kx & M32)) & M32
    a, b, c = _final(a, b, c)
    return c


@kernel(inline="call")
def hash_uint3_inline(kx, ky, kz):
    """:func:`hash_uint3` inlined into its caller (Perlin's eight lattice corners: the compiler then schedules the
    eight independent hashes together)."""
    a = b = c = _INIT[3]
    c = (c + (kz & M32)) & M32
    b = (b + (ky & M32)) & M32
    a = (a + (kx & M32)) & M32
    a, b, c = _final(a, b, c)
    return c


@kernel
def hash_uint3(kx, ky, kz):
    return hash_uint3_inline(kx, ky, kz)


@kernel
def hash_uint4(kx, ky, kz, kw):
    a = b = c = _INIT[4]
    a = (a + (kx & M32)) & M32
    b = (b + (ky & M32)) & M32
    c = (c + (kz & M32)) & M32
    a, b, c = _mix(a, b, c)
    a = (a + (kw & M32)) & M32
    a, b, c = _final(a, b, c)
    return c


@kernel
def uint_to_float_incl(n):
    """[0, 2^32-1] -> [0, 1] as Cycles does it: float32(n) · float32(1/(2^32-1)), rounded to float32."""
    return float(np.float32(np.float32(n) * np.float32(_INV_UINT_MAX)))


@kernel
def float_as_uint(f):
    """The IEEE-754 bit pattern of float32(f) as an int (C's ``__float_as_uint``), without an array view."""
    x = float(np.float32(f))
    if x != x:
        return 0x7FC00000
    sign = 0x80000000 if (x < 0.0 or (x == 0.0 and math.copysign(1.0, x) < 0.0)) else 0
    ax = abs(x)
    if ax == 0.0:
        return sign
    if ax == math.inf:
        return sign | 0x7F800000
    m, e = math.frexp(ax)  # ax = m · 2^e, m in [0.5, 1)
    biased = e + 126
    if biased <= 0:  # subnormal: mantissa counts units of 2^-149
        return sign | int(ax * 2.0 ** 149)
    return sign | (biased << 23) | int((m * 2.0 - 1.0) * 8388608.0)


@kernel
def hash_float_to_float(k):
    """[0, 1] from the float32 bits of k (Cycles ``hash_float_to_float``)."""
    return uint_to_float_incl(hash_uint(float_as_uint(k)))


@kernel
def hash_float2_to_float(kx, ky):
    return uint_to_float_incl(hash_uint2(float_as_uint(kx), float_as_uint(ky)))


@kernel
def hash_float3_to_float(kx, ky, kz):
    return uint_to_float_incl(hash_uint3(float_as_uint(kx), float_as_uint(ky), float_as_uint(kz)))


@kernel
def hash_float4_to_float(kx, ky, kz, kw):
    return uint_to_float_incl(hash_uint4(float_as_uint(kx), float_as_uint(ky), float_as_uint(kz),
                                         float_as_uint(kw)))


# --- float^n -> float^m hashes (the component permutations are Cycles'; Voronoi and White Noise use them)
@kernel
def hash_float_to_float3(k):
    return (hash_float_to_float(k), hash_float2_to_float(k, 1.0), hash_float2_to_float(k, 2.0))


@kernel
def hash_float2_to_float2(x, y):
    return (hash_float2_to_float(x, y), hash_float3_to_float(x, y, 1.0))


@kernel
def hash_float2_to_float3(x, y):
    return (hash_float2_to_float(x, y), hash_float3_to_float(x, y, 1.0), hash_float3_to_float(x, y, 2.0))


@kernel
def hash_float3_to_float3(x, y, z):
    return (hash_float3_to_float(x, y, z), hash_float4_to_float(x, y, z, 1.0), hash_float4_to_float(x, y, z, 2.0))


@kernel
def hash_float4_to_float3(x, y, z, w):
    return (hash_float4_to_float(x, y, z, w), hash_float4_to_float(z, x, w, y), hash_float4_to_float(w, z, y, x))


@kernel
def hash_float4_to_float4(x, y, z, w):
    return (hash_float4_to_float(x, y, z, w), hash_float4_to_float(w, x, y, z), hash_float4_to_float(z, w, x, y),
            hash_float4_to_float(y, z, w, x))


# --- PCG integer hashes (Jarzynski & Olano, JCGT 2020, in Cycles' signed-int variant): Voronoi's n-D cells
@kernel(inline="call")
def _mul32(a, b):
    """a · b mod 2^32 for uint32 words, without overflowing int64 (b split into 16-bit halves)."""
    return (a * (b & 0xFFFF) + (((a * (b >> 16)) & 0xFFFF) << 16)) & M32


@kernel(inline="call")
def _xorshift16(v):
    """v ^ (v >> 16) with C's arithmetic (sign-extending) shift of a signed int."""
    s = v - 0x100000000 if v & 0x80000000 else v
    return (v ^ ((s >> 16) & M32)) & M32


@kernel(inline="call")
def _lcg(v):
    return (_mul32(v & M32, 1664525) + 1013904223) & M32


@kernel
def hash_pcg2d(x, y):
    x, y = _lcg(x), _lcg(y)
    x = (x + _mul32(y, 1664525)) & M32
    y = (y + _mul32(x, 1664525)) & M32
    x, y = _xorshift16(x), _xorshift16(y)
    x = (x + _mul32(y, 1664525)) & M32
    y = (y + _mul32(x, 1664525)) & M32
    return x & 0x7FFFFFFF, y & 0x7FFFFFFF


@kernel
def hash_pcg3d(x, y, z):
    x, y, z = _lcg(x), _lcg(y), _lcg(z)
    x = (x + _mul32(y, z)) & M32
    y = (y + _mul32(z, x)) & M32
    z = (z + _mul32(x, y)) & M32
    x, y, z = _xorshift16(x), _xorshift16(y), _xorshift16(z)
    x = (x + _mul32(y, z)) & M32
    y = (y + _mul32(z, x)) & M32
    z = (z + _mul32(x, y)) & M32
    return x & 0x7FFFFFFF, y & 0x7FFFFFFF, z & 0x7FFFFFFF


@kernel
def hash_pcg4d(x, y, z, w):
    x, y, z, w = _lcg(x), _lcg(y), _lcg(z), _lcg(w)
    x = (x + _mul32(y, w)) & M32
    y = (y + _mul32(z, x)) & M32
    z = (z + _mul32(x, y)) & M32
    w = (w + _mul32(y, z)) & M32
    x, y, z, w = _xorshift16(x), _xorshift16(y), _xorshift16(z), _xorshift16(w)
    x = (x + _mul32(y, w)) & M32
    y = (y + _mul32(z, x)) & M32
    z = (z + _mul32(x, y)) & M32
    w = (w + _mul32(y, z)) & M32
    return x & 0x7FFFFFFF, y & 0x7FFFFFFF, z & 0x7FFFFFFF, w & 0x7FFFFFFF


@kernel(inline="call")
def _int31_to_float(h):
    """[0, 2^31-1] -> [0, 1]: float32(h) · 2^-31 (Cycles' (float)h · (1 / (float)0x7FFFFFFF))."""
    return float(np.float32(h)) * 4.656612873077393e-10


@kernel
def hash_int2_to_float2(x, y):
    a, b = hash_pcg2d(x, y)
    return (_int31_to_float(a), _int31_to_float(b))


@kernel
def hash_int3_to_float3(x, y, z):
    a, b, c = hash_pcg3d(x, y, z)
    return (_int31_to_float(a), _int31_to_float(b), _int31_to_float(c))


@kernel
def hash_int4_to_float4(x, y, z, w):
    a, b, c, d = hash_pcg4d(x, y, z, w)
    return (_int31_to_float(a), _int31_to_float(b), _int31_to_float(c), _int31_to_float(d))


# ---------------------------------------------------------------------- array forms (tests, constant folding)
@kernel
def _hash_rows(keys, n, out):
    for i in range(keys.shape[0]):
        if n == 1:
            out[i] = hash_uint(keys[i, 0])
        elif n == 2:
            out[i] = hash_uint2(keys[i, 0], keys[i, 1])
        elif n == 3:
            out[i] = hash_uint3(keys[i, 0], keys[i, 1], keys[i, 2])
        else:
            out[i] = hash_uint4(keys[i, 0], keys[i, 1], keys[i, 2], keys[i, 3])


@kernel
def _hash_float_rows(keys, n, out):
    for i in range(keys.shape[0]):
        if n == 1:
            out[i] = hash_float_to_float(keys[i, 0])
        elif n == 2:
            out[i] = hash_float2_to_float(keys[i, 0], keys[i, 1])
        elif n == 3:
            out[i] = hash_float3_to_float(keys[i, 0], keys[i, 1], keys[i, 2])
        else:
            out[i] = hash_float4_to_float(keys[i, 0], keys[i, 1], keys[i, 2], keys[i, 3])


def hash_uint_array(*keys) -> np.ndarray:
    """lookup3 of 1-4 integer arrays (broadcast; negative values wrap as C's uint cast) -> uint32 array."""
    if not 1 <= len(keys) <= 4:
        raise ValueError(f"hash_uint_array takes 1 to 4 key arrays, got {len(keys)}")
    arrs = np.broadcast_arrays(*[np.asarray(k, np.int64) for k in keys])
    rows = np.ascontiguousarray(np.stack([a.reshape(-1) for a in arrs], -1) & M32)
    out = np.empty(len(rows), np.int64)
    _hash_rows(rows, len(keys), out)
    return out.astype(np.uint32).reshape(arrs[0].shape)


def hash_float_array(*keys) -> np.ndarray:
    """Cycles' hash_float{1..4}_to_float of 1-4 float arrays (hashed as float32 bits) -> [0, 1] float32 array."""
    if not 1 <= len(keys) <= 4:
        raise ValueError(f"hash_float_array takes 1 to 4 key arrays, got {len(keys)}")
    arrs = np.broadcast_arrays(*[np.asarray(k, np.float32).astype(np.float64) for k in keys])
    rows = np.ascontiguousarray(np.stack([a.reshape(-1) for a in arrs], -1))
    out = np.empty(len(rows), np.float64)
    _hash_float_rows(rows, len(keys), out)
    return out.astype(np.float32).reshape(arrs[0].shape)

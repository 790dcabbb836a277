"""Deterministic per-sample random numbers: a counter-based hash, so any tile on any thread gets the same values.

The scalar functions run inside kernels; :func:`uniform` and :func:`uniform2` are their array forms.
"""

from __future__ import annotations

import math

import numpy as np

from .jit import kernel

_M32 = 0xFFFFFFFF
_INV_2_24 = 1.0 / (1 << 24)


@kernel(inline=True)
def pcg_hash(x):
    """PCG-style integer hash of a 32-bit value (Jarzynski & Olano 2020, "pcg" hash), in 64-bit integer maths."""
    state = (x * 747796405 + 2891336453) & _M32
    word = (((state >> ((state >> 28) + 4)) ^ state) * 277803737) & _M32
    return ((word >> 22) ^ word) & _M32


@kernel(inline=True)
def uniform1(key, stream, seed):
    """A float in [0, 1) for an integer ``key`` (e.g. pixel·samples + sample), one independent stream per ``stream``."""
    h = pcg_hash((key ^ pcg_hash((stream * 0x9E3779B1 + seed) & _M32)) & _M32)
    h = pcg_hash((h + stream) & _M32)
    return (h >> 8) * _INV_2_24


@kernel(inline=True)
def uniform2_1(key, stream, seed):
    """Two floats in [0, 1): streams 2·stream and 2·stream + 1."""
    return uniform1(key, 2 * stream, seed), uniform1(key, 2 * stream + 1, seed)


@kernel(inline=True)
def stratum(index, side, r0, r1):
    """Sample ``index`` of a side×side grid of strata over [0,1)², every stratum shifted by (r0, r1) modulo 1.

    The same per-point offsets rotate the whole pattern (Cranley-Patterson), so neighbouring pixels see different
    sample positions while every render of the same scene sees the same ones.
    """
    s0 = ((index // side) + r0) / side
    s1 = ((index % side) + r1) / side
    return s0 - math.floor(s0), s1 - math.floor(s1)


@kernel
def _uniform_array(keys, stream, seed, out):
    for i in range(keys.shape[0]):
        out[i] = uniform1(np.int64(keys[i]) & _M32, stream, seed)


def uniform(keys: np.ndarray, stream: int, seed: int = 0) -> np.ndarray:
    """Floats in [0, 1) for integer ``keys``, one independent stream per ``stream`` (array form of uniform1)."""
    keys = np.ascontiguousarray(np.asarray(keys).reshape(-1).astype(np.int64) & _M32)
    out = np.empty(len(keys), np.float32)
    _uniform_array(keys, int(stream), int(seed), out)
    return out


def uniform2(keys: np.ndarray, stream: int, seed: int = 0) -> np.ndarray:
    """(N, 2) floats in [0, 1) for ``keys``: two consecutive streams."""
    return np.stack([uniform(keys, 2 * stream, seed), uniform(keys, 2 * stream + 1, seed)], axis=-1)


@kernel(inline=True)
def multijitter(index, side, r0, r1):
    """Sample ``index`` of side² points in [0,1)² that are stratified in 2-D (one per cell of a side×side grid) *and*
    in each coordinate alone (one per 1/side² slice): the canonical multi-jittered arrangement, offset inside its
    slices by (r0, r1). For samples whose value depends mostly on one coordinate (the height of an environment
    direction, for a surface's cosine) it has side times finer strata than :func:`stratum`."""
    i = index // side
    j = index % side
    return (i + (j + r0) / side) / side, (j + (i + r1) / side) / side


@kernel(inline=True)
def rotated_multijitter(index, side, r0, r1):
    """Point ``index`` of :func:`multijitter`'s side² points, the whole pattern then rotated by (r1, r0) modulo 1
    (Cranley-Patterson): the fine 1-D strata of multi-jittering, and a different pattern for every (r0, r1) (with
    the offsets inside the slices alone, neighbouring pixels' patterns nearly coincide and their errors add up)."""
    s0, s1 = multijitter(index, side, r0, r1)
    s0, s1 = s0 + r1, s1 + r0
    return s0 - math.floor(s0), s1 - math.floor(s1)


# ---------------------------------------------------------------------------------------------- progressive order
def _sobol2(m: int):
    """The first 2^m points of the 2-D Sobol sequence (dimension 1: van der Corput in base 2; dimension 2: the
    generator of the polynomial x + 1), as 32-bit integers. Every aligned block of 2^j of its points is a (0, j, 2)-net:
    one point in each of the 2^j elementary intervals of area 2^-j (a (0, 2)-sequence)."""
    n = 1 << m
    k = np.arange(n, dtype=np.uint64)
    x = np.zeros(n, np.uint64)
    y = np.zeros(n, np.uint64)
    v = 1 << 31
    for i in range(32):
        bit = (k >> np.uint64(i)) & np.uint64(1)
        x ^= bit * np.uint64(1 << (31 - i))
        y ^= bit * np.uint64(v)
        v ^= v >> 1
    return x, y


_ORDERS: dict = {}


def progressive_order(n: int) -> np.ndarray:
    """The N×N strata (index row·N + column, as the renderer's ``s``) in an order whose every prefix is spread over
    the pixel: the order in which the 2-D Sobol (0, 2)-sequence first enters each stratum. For N a power of two
    that is the sequence's first N² points, so the first 4^j strata of the order form a 2^j × 2^j stratification
    (4 samples of 16: one per quadrant) and any 2^j form a (0, j, 2)-net; for other N, nearly so. Adaptive
    sampling takes a pixel's samples in this order (``tracer.integrator.adaptive``). Cached per N; int32."""
    n = int(n)
    out = _ORDERS.get(n)
    if out is not None:
        return out
    nn = n * n
    m = max(0, (nn - 1).bit_length())
    while True:
        x, y = _sobol2(m)
        cx = np.minimum((x * np.uint64(n)) >> np.uint64(32), np.uint64(n - 1)).astype(np.int64)
        cy = np.minimum((y * np.uint64(n)) >> np.uint64(32), np.uint64(n - 1)).astype(np.int64)
        cell = cy * n + cx  # row (jy, the film's s // N) · N + column (jx, s % N)
        _, first = np.unique(cell, return_index=True)
        if len(first) == nn:
            out = np.ascontiguousarray(cell[np.sort(first)], np.int32)
            break
        m += 1
    out.setflags(write=False)
    _ORDERS[n] = out
    return out


def sample_class_a(k: np.ndarray) -> np.ndarray:
    """Whether positions ``k`` of a progressive order belong to class A of the two interleaved halves adaptive
    sampling compares (Cycles' ``sample_is_class_A``: the parity of k's odd bits, after Christensen et al.,
    "Progressive Multi-Jittered Sample Sequences", 10.2.1): each aligned block of 4 positions has two of each class,
    and each class of a (0, 2)-sequence is itself well stratified."""
    x = np.asarray(k, np.uint32) & np.uint32(0xAAAAAAAA)
    parity = np.zeros(x.shape, np.uint32)
    while np.any(x):
        parity ^= x & np.uint32(1)
        x = x >> np.uint32(1)
    return parity.astype(bool)

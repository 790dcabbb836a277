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

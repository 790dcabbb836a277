"""Deterministic per-sample random numbers: a counter-based hash, so any tile on any thread gets the same values."""

from __future__ import annotations

import numpy as np


def pcg_hash(x: np.ndarray) -> np.ndarray:
    """PCG-style integer hash of uint32 values (Jarzynski & Olano 2020, "pcg" hash)."""
    x = np.asarray(x, dtype=np.uint32)
    state = x * np.uint32(747796405) + np.uint32(2891336453)
    word = ((state >> ((state >> np.uint32(28)) + np.uint32(4))) ^ state) * np.uint32(277803737)
    return (word >> np.uint32(22)) ^ word


def uniform(keys: np.ndarray, stream: int, seed: int = 0) -> np.ndarray:
    """Floats in [0, 1) for integer ``keys`` (e.g. pixel·samples + sample), one independent stream per ``stream``."""
    with np.errstate(over="ignore"):
        h = pcg_hash(np.asarray(keys, dtype=np.uint32) ^ pcg_hash(np.uint32((stream * 0x9E3779B1 + seed) & 0xFFFFFFFF)))
        h = pcg_hash(h + np.uint32(stream))
    return (h >> np.uint32(8)).astype(np.float32) * np.float32(1.0 / (1 << 24))


def uniform2(keys: np.ndarray, stream: int, seed: int = 0) -> np.ndarray:
    """(N, 2) floats in [0, 1) for ``keys``: two consecutive streams."""
    return np.stack([uniform(keys, 2 * stream, seed), uniform(keys, 2 * stream + 1, seed)], axis=-1)

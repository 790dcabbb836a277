"""Scene.validate's per-triangle passes as numba kernels, run over row ranges on every core.

Each kernel takes ``lo, hi`` (a range of rows) and writes only those rows of its output, so :func:`in_threads`
can hand disjoint ranges to one thread per core (the kernels release the GIL). The arithmetic is the numpy
expressions they replace, in the same order and precision (float64 areas from float32 points, float32 normal
lengths), so the masks and normals are bit for bit what the numpy code gave.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .jit import kernel

#: Rows below which a pass runs on the calling thread (thread hand-off costs more than it saves).
_MIN_ROWS_PER_THREAD = 1 << 16
_POOL: ThreadPoolExecutor | None = None


def in_threads(fn, n: int, *args) -> None:
    """Run ``fn(*args, lo, hi)`` over [0, n) split into one contiguous range per core."""
    workers = max(1, min(os.cpu_count() or 1, n // _MIN_ROWS_PER_THREAD))
    if workers == 1:
        fn(*args, 0, n)
        return
    global _POOL
    if _POOL is None:
        _POOL = ThreadPoolExecutor(os.cpu_count() or 1, thread_name_prefix="whitted-load")
    edges = np.linspace(0, n, workers + 1).astype(np.int64)
    for f in [_POOL.submit(fn, *args, int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]:
        f.result()


@kernel
def non_degenerate_rows(vertices, triangles, limit, out, lo, hi):
    """out[i] = |(p1 − p0) × (p2 − p0)| > limit for triangles lo..hi (float64, as scene.non_degenerate)."""
    for i in range(lo, hi):
        a, b, c = triangles[i, 0], triangles[i, 1], triangles[i, 2]
        ax, ay, az = np.float64(vertices[a, 0]), np.float64(vertices[a, 1]), np.float64(vertices[a, 2])
        ux, uy, uz = np.float64(vertices[b, 0]) - ax, np.float64(vertices[b, 1]) - ay, np.float64(vertices[b, 2]) - az
        vx, vy, vz = np.float64(vertices[c, 0]) - ax, np.float64(vertices[c, 1]) - ay, np.float64(vertices[c, 2]) - az
        cx = uy * vz - uz * vy
        cy = uz * vx - ux * vz
        cz = ux * vy - uy * vx
        out[i] = np.sqrt(cx * cx + cy * cy + cz * cz) > limit


@kernel
def unit_rows(normals, out, lo, hi):
    """out[i] = normals[i] / |normals[i]| in float32 for rows lo..hi of (N, 3); zero where the length is zero or
    not finite (as scene.unit_normals)."""
    zero = np.float32(0.0)
    for i in range(lo, hi):
        x, y, z = normals[i, 0], normals[i, 1], normals[i, 2]
        ln = np.sqrt(x * x + y * y + z * z)
        if np.isfinite(ln) and ln > zero:
            out[i, 0], out[i, 1], out[i, 2] = x / ln, y / ln, z / ln
        else:
            out[i, 0], out[i, 1], out[i, 2] = zero, zero, zero


@kernel
def inf_to_nan_rows(values, out, lo, hi):
    """out[i] = values[i] with ±inf replaced by NaN, rows lo..hi of a flat float32 array."""
    nan = np.float32(np.nan)
    for i in range(lo, hi):
        x = values[i]
        out[i] = nan if np.isinf(x) else x


@kernel
def used_bounds(vertices, triangles, rows, out):
    """(2, 3) min/max of the vertices referenced by ``triangles[rows]`` (all rows when ``rows`` is empty)."""
    n = len(rows) if len(rows) else len(triangles)
    for k in range(3):
        out[0, k] = np.inf
        out[1, k] = -np.inf
    for j in range(n):
        i = rows[j] if len(rows) else j
        for c in range(3):
            v = triangles[i, c]
            for k in range(3):
                x = np.float64(vertices[v, k])
                if x < out[0, k]:
                    out[0, k] = x
                if x > out[1, k]:
                    out[1, k] = x


def unit_normals(normals: np.ndarray, in_place: bool = False) -> np.ndarray:
    """Unit float32 rows of an (..., 3) array (zeros where unusable), computed on every core; ``in_place``:
    written over ``normals`` (a float32 contiguous array nobody else needs as it was)."""
    nr = np.ascontiguousarray(normals, dtype=np.float32)
    out = nr if in_place else np.empty_like(nr)
    flat_in, flat_out = nr.reshape(-1, 3), out.reshape(-1, 3)
    in_threads(unit_rows, len(flat_in), flat_in, flat_out)
    return out


def inf_to_nan(values: np.ndarray, in_place: bool = False) -> np.ndarray:
    """A contiguous float32 copy with ±inf as NaN (``in_place``: written over ``values``)."""
    a = np.ascontiguousarray(values, dtype=np.float32)
    out = a if in_place else np.empty_like(a)
    in_threads(inf_to_nan_rows, a.size, a.reshape(-1), out.reshape(-1))
    return out


def non_degenerate(vertices: np.ndarray, triangles: np.ndarray, limit: float) -> np.ndarray:
    v = np.ascontiguousarray(vertices, dtype=np.float32)
    t = np.ascontiguousarray(triangles, dtype=np.int32)
    out = np.empty(len(t), np.bool_)
    in_threads(non_degenerate_rows, len(t), v, t, float(limit), out)
    return out

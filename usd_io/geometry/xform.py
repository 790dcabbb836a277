"""Transforms: USD's row-vector matrices to the tracer's column-vector convention, at a time code.

USD composes ``p' = p · M`` (row vectors, translation in the last row); the tracer uses ``p' = M @ p``. So every
matrix from ``pxr`` is transposed once here and nowhere else. Time-sampled xformOps are evaluated by
``UsdGeom.XformCache`` at the render's time code.
"""

from __future__ import annotations

import numpy as np
from pxr import Gf, Usd, UsdGeom

#: Arnold's implicit shapes the reader draws (usd_io.geometry.gprims.ARNOLD_IMPLICITS), typed prims USD does not know.
ARNOLD_IMPLICITS = ("ArnoldSphere", "ArnoldBox")


def to_numpy(matrix: Gf.Matrix4d) -> np.ndarray:
    """A ``Gf.Matrix4d`` (row vectors) as a 4×4 column-vector matrix."""
    return np.array(matrix, dtype=np.float64).reshape(4, 4).T


class Transforms:
    """World matrices of prims at one time code (cached, like ``UsdGeom.XformCache``)."""

    def __init__(self, time: Usd.TimeCode):
        self.time = time
        self.cache = UsdGeom.XformCache(time)

    def world(self, prim) -> np.ndarray:
        if prim.GetTypeName() in ARNOLD_IMPLICITS:  # a type USD does not know: XformCache skips its own ops
            local = UsdGeom.Xformable(prim).GetLocalTransformation(self.time)
            parent = self.cache.GetLocalToWorldTransform(prim.GetParent())
            return to_numpy(local * parent)
        return to_numpy(self.cache.GetLocalToWorldTransform(prim))

    def relative(self, prim, ancestor) -> np.ndarray:
        """prim's transform relative to ``ancestor`` (the identity if ``ancestor`` is the prim itself)."""
        m, _resets = self.cache.ComputeRelativeTransform(prim, ancestor)
        return to_numpy(m)


def transform_points(m: np.ndarray, p: np.ndarray) -> np.ndarray:
    return p @ m[:3, :3].T + m[:3, 3]


def batch_points(mats: np.ndarray, p: np.ndarray) -> np.ndarray:
    """(K, V, 3): points (V, 3) under K matrices (K, 4, 4), without a Python loop over K."""
    return np.einsum("kij,vj->kvi", mats[:, :3, :3], p) + mats[:, None, :3, 3]


def batch_normals(mats: np.ndarray, n: np.ndarray) -> np.ndarray:
    """(K, ..., 3): normals under the inverse transposes of K matrices."""
    inv = np.linalg.inv(mats[:, :3, :3])  # (K, 3, 3); n' = n @ inv, i.e. inv^T n
    return np.einsum("...j,kji->k...i", n, inv)

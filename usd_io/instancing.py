"""``UsdGeom.PointInstancer``: flattened into world-space triangles, one builder call per prototype piece.

embreex exposes no Embree instancing, so instances are copied. Each prototype gprim is read and converted once;
its K instance matrices W · instanceᵢ · prototype-relative are applied in one batched numpy product (no Python
loop over instances), normals by the batched inverse transposes, winding flipped where a matrix mirrors.
``invisibleIds``/``mask`` are honoured through ``ComputeMaskAtTime``. Native (scenegraph) instancing is handled by
the traversal through instance proxies, with the prototype's geometry read once and cached (reader.py).
"""

from __future__ import annotations

import numpy as np
from pxr import UsdGeom

from .xform import batch_normals, batch_points


def instance_matrices(prim, time) -> tuple[np.ndarray, np.ndarray, list]:
    """(K, 4, 4) column-vector instance matrices (without prototype xforms), (K,) proto indices with masked
    instances set to −1, and the prototype paths."""
    pi = UsdGeom.PointInstancer(prim)
    xforms = pi.ComputeInstanceTransformsAtTime(time, time, UsdGeom.PointInstancer.ExcludeProtoXform,
                                                UsdGeom.PointInstancer.IgnoreMask)
    mats = np.asarray(xforms, dtype=np.float64).reshape(-1, 4, 4).transpose(0, 2, 1)
    idx = np.asarray(pi.GetProtoIndicesAttr().Get(time) or [], dtype=np.int64)
    if len(idx) != len(mats):
        return np.zeros((0, 4, 4)), np.zeros(0, np.int64), []
    mask = pi.ComputeMaskAtTime(time)
    if mask is not None and len(mask) == len(idx):
        idx = np.where(np.asarray(mask, dtype=bool), idx, -1)
    return mats, idx, list(pi.GetPrototypesRel().GetForwardedTargets())


def replicate(mats: np.ndarray, data, material):
    """Vertices, triangles, normals, uvs and per-triangle materials of ``data`` under K world matrices."""
    k, nv, nt = len(mats), len(data.points), len(data.triangles)
    verts = batch_points(mats, data.points).reshape(-1, 3)
    tris = np.repeat(data.triangles[None], k, axis=0) + (np.arange(k) * nv)[:, None, None]
    flip = np.linalg.det(mats[:, :3, :3]) < 0
    tris[flip] = tris[flip][:, :, [0, 2, 1]]
    normals = uvs = None
    if data.normals is not None:
        n = batch_normals(mats, data.normals)  # (K, V, 3) or (K, T, 3, 3)
        if data.normals.ndim == 3:
            n[flip] = n[flip][:, :, [0, 2, 1]]
            normals = n.reshape(-1, 3, 3)
        else:
            normals = n.reshape(-1, 3)
    if data.uvs is not None:
        u = np.repeat(data.uvs[None], k, axis=0)
        u[flip] = u[flip][:, :, [0, 2, 1]]
        uvs = u.reshape(-1, 3, 2)
    mat = np.asarray(material)
    mat = np.tile(mat, k) if mat.ndim else mat
    return verts, tris.reshape(-1, 3), normals, uvs, mat

"""``UsdGeom.PointInstancer``: its instance matrices, which the reader turns into tracer instances.

No instance is copied: each prototype gprim is read and converted once and added to the scene in its own space
(``SceneBuilder.add_mesh``), and its K instance matrices W · instanceᵢ · prototype-relative (one batched numpy
product, no Python loop over instances) become ``SceneBuilder.add_instances`` — Embree instances of one BVH.
Nested instancers compose their matrices, so every (outer, inner) instance keeps an object id of its own.
``invisibleIds``/``mask`` are honoured through ``ComputeMaskAtTime``. Native (scenegraph) instancing: the traversal
meets instance proxies; the prototype's mesh is added once (per material binding) and each proxy is an instance of
it (reader.py).
"""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdGeom


def instance_matrices(prim, time) -> tuple[np.ndarray, np.ndarray, list]:
    """(K, 4, 4) column-vector instance matrices (without prototype xforms), (K,) proto indices with masked
    instances set to −1, and the prototype paths."""
    pi = UsdGeom.PointInstancer(prim)
    if time.IsEarliestTime():  # velocities × (EarliestTime − the sample's time) would be infinite: NaN matrices
        samples = pi.GetPositionsAttr().GetTimeSamples()
        time = Usd.TimeCode(samples[0]) if samples else Usd.TimeCode.Default()
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

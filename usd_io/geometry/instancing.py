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

import re

import numpy as np
from pxr import Usd, UsdGeom

from .xform import to_numpy


def missing_required_input(prim) -> str | None:
    """The first of a PointInstancer's required inputs that has no value, as Storm checks them
    (UsdImagingPointInstancerAdapter: ``prototypes`` targets, then ``protoIndices``, then ``positions``; an authored
    empty array or time samples count as a value), or None. Storm does not add such an instancer to its render
    index; the reader skips it the same way, with one warning."""
    pi = UsdGeom.PointInstancer(prim)
    if not pi.GetPrototypesRel().GetForwardedTargets():
        return "prototypes"
    if not pi.GetProtoIndicesAttr().HasValue():
        return "protoIndices"
    if not pi.GetPositionsAttr().HasValue():
        return "positions"
    return None


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


def instancer_motion(stage, names: list, instance_object_ids, times, base) -> dict:
    """Motion blur of PointInstancer instances: {instance row: (S, 4, 4) world matrices at ``times``} for the rows
    the reader made from a PointInstancer (named ``/Instancer[/piece][i]`` by tracer.SceneBuilder.add_instances),
    from ``ComputeInstanceTransformsAtTimes`` (authored time samples, or positions/orientations moved by
    ``velocities``/``angularVelocities`` (and ``accelerations``) from the sample at ``base``) with the instancer's
    and the piece's own transforms at each time. Rows of nested instancers, or of instancers whose instances were
    filtered, are left out (they stand still)."""
    pattern = re.compile(r"^(/[^\[]*)\[(/[^\]]*)\]\[(\d+)\]$")
    groups: dict = {}
    for row, oid in enumerate(np.asarray(instance_object_ids).tolist()):
        m = pattern.match(names[oid]) if oid < len(names) else None
        if m:
            groups.setdefault((m.group(1), m.group(2)), []).append((int(m.group(3)), row))
    out = {}
    caches = [UsdGeom.XformCache(Usd.TimeCode(t)) for t in times]
    codes = [Usd.TimeCode(t) for t in times]
    for (inst_path, piece_path), members in groups.items():
        prim, piece = stage.GetPrimAtPath(inst_path), stage.GetPrimAtPath(piece_path)
        if not prim or not piece or not prim.IsA(UsdGeom.PointInstancer):
            continue
        pi = UsdGeom.PointInstancer(prim)
        steps = pi.ComputeInstanceTransformsAtTimes(codes, base, UsdGeom.PointInstancer.ExcludeProtoXform,
                                                    UsdGeom.PointInstancer.IgnoreMask)
        if not steps or any(len(s) == 0 for s in steps):
            continue
        mats = np.stack([np.asarray(s, np.float64).reshape(-1, 4, 4).transpose(0, 2, 1) for s in steps])
        idx = np.asarray(pi.GetProtoIndicesAttr().Get(base) or [], np.int64)
        mask = pi.ComputeMaskAtTime(base)
        if mask is not None and len(mask) == len(idx):
            idx = np.where(np.asarray(mask, bool), idx, -1)
        protos = [str(p) for p in pi.GetPrototypesRel().GetForwardedTargets()]
        p_index = next((k for k, p in enumerate(protos) if piece_path == p or piece_path.startswith(p + "/")), None)
        if p_index is None or mats.shape[1] != len(idx):
            continue
        sel = np.flatnonzero(idx == p_index)
        if len(sel) != len(members):  # some instances were dropped (singular) or nested: no motion for them
            continue
        root = stage.GetPrimAtPath(protos[p_index]).GetParent()
        world = np.stack([to_numpy(c.GetLocalToWorldTransform(prim)) for c in caches])
        rel = np.stack([to_numpy(c.ComputeRelativeTransform(piece, root)[0]) for c in caches])
        full = world[:, None] @ mats[:, sel] @ rel[:, None]  # (S, n, 4, 4)
        for i, row in members:
            out[row] = full[:, i]
    return out

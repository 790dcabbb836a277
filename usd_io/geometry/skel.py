"""``UsdSkel``: skinned meshes posed at the time code with usd-core's ``UsdSkel.Cache`` and skinning queries.

A mesh bound to a skeleton (``SkelBindingAPI`` under a ``SkelRoot``) is linear-blend skinned (or rigidly
deformed) by ``UsdSkelSkinningQuery.ComputeSkinnedPoints``; its points then live in the skeleton's space, so the
mesh is placed with the skeleton's world matrix. Normals are recomputed from the posed points (area-weighted).
Anything the query cannot pose (no skeleton, no animation, dual-quaternion skinning on old usd-core, …) keeps its
rest pose with one warning naming the prim.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from pxr import Usd, UsdSkel, Vt

from .mesh import smooth_normals


class Skinning:
    def __init__(self, time, world):
        self.time = time
        self.world = world  # prim -> (4, 4) column-vector world matrix
        self.cache = UsdSkel.Cache()
        self._populated: set[str] = set()

    @staticmethod
    def is_skinned(prim) -> bool:
        return prim.HasAPI(UsdSkel.BindingAPI) and bool(UsdSkel.BindingAPI(prim).GetSkeletonRel().GetTargets()
                                                        or UsdSkel.Root.Find(prim))

    def pose(self, prim, data, warn):
        """(posed MeshData, world matrix) or None (the caller keeps the rest pose; a warning was given).

        Blend shapes first (UsdSkel's order: shapes on the rest points, then skinning), then linear-blend skinning
        where the binding has joint influences; a binding with blend shapes and no influences keeps the mesh's own
        place (its world matrix)."""
        label = str(prim.GetPath())
        root = UsdSkel.Root.Find(prim)
        if not root:
            warn(f"{label}: skinned mesh outside a SkelRoot: rest pose rendered")
            return None
        key = str(root.GetPath())
        if key not in self._populated:
            self.cache.Populate(root, Usd.TraverseInstanceProxies())
            self._populated.add(key)
        query = self.cache.GetSkinningQuery(prim)
        skel = UsdSkel.BindingAPI(prim).GetInheritedSkeleton()
        if not query or not skel:
            warn(f"{label}: no skeleton bound: rest pose rendered")
            return None
        skel_query = self.cache.GetSkelQuery(skel)
        points = np.ascontiguousarray(data.points, np.float64)
        shaped = False
        if query.HasBlendShapes():
            got = apply_blend_shapes(prim, query, skel_query, points, self.time, warn)
            if got is not None:
                points, shaped = got, True
        if not query.HasJointInfluences():
            if not shaped:
                return None
            return replace(data, points=points, normals=smooth_normals(points, data.triangles)), self.world(prim)
        xforms = skel_query.ComputeSkinningTransforms(self.time) if skel_query else None
        if xforms is None:
            warn(f"{label}: skeleton {skel.GetPath()} cannot be posed: rest pose rendered")
            return None
        vt_points = Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(points, np.float32))
        try:
            ok = query.ComputeSkinnedPoints(xforms, vt_points, self.time)
        except Exception as exc:  # pxr's Tf.ErrorException: influences it cannot read
            warn(f"{label}: skinning failed ({_first_line(exc)}): rest pose rendered")
            return None
        if not ok:
            warn(f"{label}: skinning failed: rest pose rendered")
            return None
        posed = np.asarray(vt_points, np.float64)
        if not np.all(np.isfinite(posed)):
            warn(f"{label}: skinning gave non-finite points: rest pose rendered")
            return None
        posed_data = replace(data, points=posed, normals=smooth_normals(posed, data.triangles))
        return posed_data, self.world(skel.GetPrim())


def apply_blend_shapes(prim, query, skel_query, points: np.ndarray, time, warn):
    """The rest points with the mesh's blend shapes applied at ``time`` (UsdSkelBlendShapeQuery: weights from the
    skeleton's animation, remapped to the mesh's ``skel:blendShapes`` order; inbetweens by their weights), or None
    (a warning) when the shapes cannot be read."""
    label = str(prim.GetPath())
    anim = skel_query.GetAnimQuery() if skel_query else None
    if not anim:
        return None  # no animation: every weight 0, the rest shape
    weights = anim.ComputeBlendShapeWeights(time)
    if weights is None or len(weights) == 0:
        return None
    by_name = dict(zip((str(n) for n in anim.GetBlendShapeOrder()), np.asarray(weights, np.float32)))
    order = query.GetBlendShapeOrder() or []
    weights = Vt.FloatArray([float(by_name.get(str(n), 0.0)) for n in order])  # anim order -> the mesh's order
    bsq = UsdSkel.BlendShapeQuery(UsdSkel.BindingAPI(prim))
    try:
        sub_w, bs_idx, sub_idx = bsq.ComputeSubShapeWeights(weights)
        vt_points = Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(points, np.float32))
        ok = bsq.ComputeDeformedPoints(sub_w, bs_idx, sub_idx, bsq.ComputeBlendShapePointIndices(),
                                       bsq.ComputeSubShapePointOffsets(), vt_points)
    except Exception as exc:  # pxr's Tf.ErrorException on malformed shapes
        warn(f"{label}: blend shapes could not be applied ({_first_line(exc)}): rest shape rendered")
        return None
    if not ok:
        warn(f"{label}: blend shapes could not be applied: rest shape rendered")
        return None
    out = np.asarray(vt_points, np.float64)
    return out if np.all(np.isfinite(out)) else None


def _first_line(exc) -> str:
    lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip()]
    text = lines[-1] if lines else type(exc).__name__
    return text.split(" : ", 1)[-1].strip("'")[:160]


#: UsdSkelImaging's bone: a pyramid of five points (the tip at the child joint, a square base at the parent) and
#: four triangles (the base is open), as ``_boneVerts`` in usdSkelImaging/utils.cpp.
BONE_TRIANGLES = np.array([(0, 2, 1), (0, 3, 2), (0, 4, 3), (0, 1, 4)], np.int64)


def bone_points(parents: np.ndarray, joint_skel: np.ndarray) -> np.ndarray:
    """The bone mesh's points (B·5, 3) in skeleton space, as ``UsdSkelImagingComputeBonePoints``: one bone per joint
    with a parent, in joint order; its base square at the parent joint, out by 0.1 × the bone's length along the
    two axes of the parent's transform (``joint_skel``: (J, 4, 4) row-vector skeleton-space matrices) other than
    the first one (X, then Y, else Z) whose unnormalised row meets the bone's direction with |dot| > π/4."""
    parents = np.asarray(parents, np.int64)
    m = np.asarray(joint_skel, np.float64)
    child = np.flatnonzero((parents >= 0) & (parents < len(parents)))
    if not len(child):
        return np.zeros((0, 3))
    parent = parents[child]
    end, start = m[child, 3, :3], m[parent, 3, :3]
    bone = end - start
    length = np.linalg.norm(bone, axis=1)
    direction = bone / np.maximum(length, 1e-10)[:, None]
    rows = m[parent, :3, :3]
    aligned = np.abs(np.einsum("bij,bj->bi", rows, direction)) > np.pi / 4
    principal = np.where(aligned[:, 0], 0, np.where(aligned[:, 1], 1, 2))
    k = np.arange(len(child))
    i_axis = rows[k, np.array([1, 0, 0])[principal]]
    j_axis = rows[k, np.array([2, 2, 1])[principal]]
    size = (0.1 * length)[:, None]
    i_axis = i_axis / np.maximum(np.linalg.norm(i_axis, axis=1), 1e-10)[:, None] * size
    j_axis = j_axis / np.maximum(np.linalg.norm(j_axis, axis=1), 1e-10)[:, None] * size
    pts = np.stack([end, start + i_axis + j_axis, start + i_axis - j_axis, start - i_axis - j_axis,
                    start - i_axis + j_axis], axis=1)
    return pts.reshape(-1, 3)


def bone_mesh(skel, time, cache=None):
    """(points (B·5, 3) in skeleton space, triangles (B·4, 3)) of a ``UsdSkel.Skeleton`` posed at ``time`` (its
    animation where bound, else its rest pose), or None when it cannot be posed."""
    cache = cache or UsdSkel.Cache()
    query = cache.GetSkelQuery(skel)
    if not query:
        return None
    xforms = query.ComputeJointSkelTransforms(time)
    if xforms is None or len(xforms) != len(query.GetTopology()):
        return None
    parents = np.asarray(query.GetTopology().GetParentIndices(), np.int64)
    points = bone_points(parents, np.asarray(xforms, np.float64).reshape(-1, 4, 4))
    tris = (BONE_TRIANGLES[None] + 5 * np.arange(len(points) // 5)[:, None, None]).reshape(-1, 3)
    return points, tris


def skeleton_purpose(prim) -> str:
    """The purpose Storm draws a Skeleton's bone mesh with (UsdSkelImagingSkeletonAdapter::GetPurpose): the
    skeleton's authored purpose, else the nearest ancestor's authored one, else ``guide`` (not ``default``: bones
    are not drawn unless asked for)."""
    from pxr import UsdGeom

    p = prim
    while p and not p.IsPseudoRoot():
        img = UsdGeom.Imageable(p)
        if img and img.GetPurposeAttr().HasAuthoredValue():
            return str(img.GetPurposeAttr().Get())
        p = p.GetParent()
    return "guide"

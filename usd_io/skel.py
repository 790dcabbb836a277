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
from pxr import Usd, UsdSkel

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
        """(posed MeshData, world matrix) or None (the caller keeps the rest pose; a warning was given)."""
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
        xforms = skel_query.ComputeSkinningTransforms(self.time) if skel_query else None
        if xforms is None:
            warn(f"{label}: skeleton {skel.GetPath()} cannot be posed: rest pose rendered")
            return None
        from pxr import Vt

        points = Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(data.points, np.float32))
        if not query.ComputeSkinnedPoints(xforms, points, self.time):
            warn(f"{label}: skinning failed: rest pose rendered")
            return None
        posed = np.asarray(points, np.float64)
        if not np.all(np.isfinite(posed)):
            warn(f"{label}: skinning gave non-finite points: rest pose rendered")
            return None
        posed_data = replace(data, points=posed, normals=smooth_normals(posed, data.triangles))
        return posed_data, self.world(skel.GetPrim())

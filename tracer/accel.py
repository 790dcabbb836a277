"""Ray intersection with Embree 4 (through our binding, :mod:`tracer.embree`): one Embree geometry per object,
batched closest-hit and occlusion queries from compiled loops that release the GIL, so tiles trace on threads.

Two layouts of the same objects:

- **flat** (``instanced=False``, what a one-off :func:`tracer.render` uses): every object's triangle geometry sits in
  the top-level scene, one BVH over all triangles, the fastest to trace;
- **instanced** (``instanced=True``, what a :class:`tracer.Session` uses): every object is an Embree scene of its
  own (its BVH) placed by an ``RTC_GEOMETRY_TYPE_INSTANCE`` in the top-level scene, so moving an object is a
  matrix update and a top-level commit over the instances only, and replacing one object's mesh rebuilds only its
  BVH. (In the flat layout any top-level commit rebuilds the BVH over every triangle: 0.16 s for 660 k.)

Either way a hit reports the *slot* (the object id: instance id, or geometry id in the flat layout) and the
primitive within that object's mesh; :func:`tracer.embree.intersect_rays` maps it back to the row of
``scene.triangles`` through a per-object offset table, so callers see the same ``prim`` as before.
"""

from __future__ import annotations

import threading
import time

import numpy as np

from . import embree
from .scene import Scene

#: "No hit" in ``prim``.
NO_HIT = -1
#: Largest finite ray length handed to Embree (inf would be fine for Embree; this keeps recorded rays finite).
T_FAR_MAX = np.float32(3.0e38)
_NONE_F32 = np.zeros(0, np.float32)


class Accelerator:
    """A committed Embree scene over ``scene``'s triangles, one geometry per object id. ``prim`` of a hit indexes
    ``scene.triangles``.

    ``quality``: Embree build quality of the objects' BVHs ("low" | "medium" | "high"). ``instanced``: the layout
    (see the module docstring). ``seconds`` accumulates the wall time spent inside Embree queries (summed over
    threads). With ``record=True`` every batch is kept in ``batches`` as (query, origins, directions, t_max), so a
    benchmark can replay exactly the rays the integrator traced. ``cancelled``: polled between objects and during
    each BVH build; True stops the set-up with :class:`tracer.embree.BuildCancelled`.
    """

    def __init__(self, scene: Scene, record: bool = False, quality: str = "medium", instanced: bool = False,
                 cancelled=None):
        if quality not in embree.BUILD_QUALITY or quality == "refit":
            raise ValueError(f"quality must be 'low', 'medium' or 'high', got {quality!r}")
        start = time.perf_counter()
        self.seconds = 0.0
        self.record = record
        self.batches: list = []
        self.quality = quality
        self.instanced = instanced
        self._lock = threading.Lock()
        self._top = embree.EmbreeScene("medium" if instanced else quality, embree.SCENE_FLAG_ROBUST)
        self._objects: dict[int, _Object] = {}
        self._cancelled = cancelled
        self.triangle_count = len(scene.triangles)
        if self.triangle_count:
            # One padded copy of each array (Embree reads past the last element); every object's geometry reads
            # its rows of these buffers in place.
            ids = scene.object_ids
            order = None if _is_sorted(ids) else np.argsort(ids, kind="stable")
            self._vertices = embree.padded(scene.vertices, np.float32)
            self._triangles = embree.padded(scene.triangles if order is None else scene.triangles[order], np.int32)
            sorted_ids = ids if order is None else ids[order]
            present = np.flatnonzero(np.bincount(sorted_ids))
            starts = np.searchsorted(sorted_ids, present)
            ends = np.searchsorted(sorted_ids, present, side="right")
            for oid, s, e in zip(present.tolist(), starts.tolist(), ends.tolist()):
                if cancelled is not None and cancelled():
                    raise embree.BuildCancelled("Embree set-up cancelled")
                self._add(oid, self._vertices, self._triangles[s:e])
        self.set_rows(scene.object_ids, commit=False)
        self._top.commit(cancelled)
        self._cancelled = None  # only the set-up is cancellable: edits are short
        self.build_seconds = time.perf_counter() - start

    # ---------------------------------------------------------------------------------------------- queries
    def intersect(self, origins: np.ndarray, directions: np.ndarray, t_max: np.ndarray | None = None,
                  t_min: float = 0.0):
        """Closest hits on [t_min, t_max]: (t, prim_id, u, v) with prim_id = -1 and t = inf for misses.

        (u, v) are the barycentric coordinates of vertices 1 and 2: p = (1 − u − v)·p0 + u·p1 + v·p2.
        """
        n = len(origins)
        t = np.empty(n, np.float32)
        prim = np.empty(n, np.int32)
        u = np.empty(n, np.float32)
        v = np.empty(n, np.float32)
        if n == 0 or not self._objects:
            t.fill(np.inf), prim.fill(NO_HIT), u.fill(0), v.fill(0)
            return t, prim, u, v
        o = np.ascontiguousarray(origins, dtype=np.float32)
        d = np.ascontiguousarray(directions, dtype=np.float32)
        tm = _NONE_F32 if t_max is None else np.ascontiguousarray(np.minimum(t_max, T_FAR_MAX), np.float32)
        start = time.perf_counter()
        embree.intersect_rays(self._top.handle, o, d, np.float32(t_min), tm, self._start, self._rows,
                              t, prim, u, v)
        embree.library().check()
        self._account(start, "INTERSECT", o, d, None if t_max is None else tm)
        return t, prim, u, v

    def occluded(self, origins: np.ndarray, directions: np.ndarray, t_max: np.ndarray, t_min: float = 0.0):
        """Boolean mask: something lies on the segment [origin + t_min·direction, origin + t_max·direction]
        (shadow rays)."""
        n = len(origins)
        blocked = np.zeros(n, bool)
        if n == 0 or not self._objects:
            return blocked
        o = np.ascontiguousarray(origins, dtype=np.float32)
        d = np.ascontiguousarray(directions, dtype=np.float32)
        tm = np.ascontiguousarray(np.minimum(t_max, T_FAR_MAX), dtype=np.float32)
        start = time.perf_counter()
        embree.occluded_rays(self._top.handle, o, d, np.float32(t_min), tm, blocked)
        embree.library().check()
        self._account(start, "OCCLUDED", o, d, tm)
        return blocked

    # ---------------------------------------------------------------------------------------------- edits
    def set_transform(self, object_id: int, matrix) -> None:
        """Place object ``object_id``'s mesh (as it was built) with the 4×4 ``matrix`` (column vectors) and commit
        the top-level scene. In the flat layout the object first becomes an instance of its own."""
        obj = self._objects[object_id]
        if obj.instance is None:
            self._top.detach(object_id)
            self._objects[object_id] = obj = self._instance_of(obj.geometry)
            self._top.attach(obj.instance, object_id)
        obj.instance.set_transform(matrix)
        self._top.commit()

    def set_object(self, object_id: int, vertices: np.ndarray | None, triangles: np.ndarray | None) -> None:
        """Object ``object_id`` gets a new mesh (world-space float32 vertices, int32 triangles of its own; None:
        removed). Only its BVH is built; call :meth:`set_rows` after the scene's arrays changed, which commits."""
        if object_id in self._objects:
            self._top.detach(object_id)
            del self._objects[object_id]
        if vertices is not None and len(triangles):
            self._add(object_id, embree.padded(vertices, np.float32), embree.padded(triangles, np.int32))

    def set_rows(self, object_ids: np.ndarray, commit: bool = True) -> None:
        """Where each object's triangles are in ``scene.triangles`` (its per-row object ids): the k-th triangle of
        object i's mesh is the k-th row with id i. Then commit the top-level scene."""
        ids = np.asarray(object_ids)
        if _is_sorted(ids):
            rows = np.zeros(0, np.int32)
            sorted_ids = ids
        else:
            order = np.argsort(ids, kind="stable")
            rows = order.astype(np.int32)
            sorted_ids = ids[order]
        n = max(int(ids.max()) + 1 if len(ids) else 0, max(self._objects, default=-1) + 1)
        self._start = np.searchsorted(sorted_ids, np.arange(n)).astype(np.int64)
        self._rows = rows
        self.triangle_count = len(ids)
        if commit:
            self._top.commit()

    def close(self) -> None:
        """Release the Embree scenes now (otherwise when this object is garbage collected)."""
        self._objects.clear()
        self._top.release()

    # ---------------------------------------------------------------------------------------------- internals
    def _add(self, object_id, vertices, triangles):
        geometry = embree.TriangleGeometry(vertices, triangles, self.quality)
        if self.instanced:
            obj = self._instance_of(geometry)
            self._top.attach(obj.instance, object_id)
        else:
            obj = _Object(geometry, None, None)
            self._top.attach(geometry, object_id)
        self._objects[object_id] = obj

    def _instance_of(self, geometry):
        mesh = embree.EmbreeScene(self.quality, embree.SCENE_FLAG_ROBUST)
        mesh.attach(geometry, 0)
        mesh.commit(self._cancelled)
        return _Object(geometry, mesh, embree.InstanceGeometry(mesh))

    def _account(self, start, query, o, d, t_max):
        elapsed = time.perf_counter() - start
        with self._lock:
            self.seconds += elapsed
            if self.record:
                self.batches.append((query, o.copy(), d.copy(), None if t_max is None else np.array(t_max, np.float32)))


class _Object:
    __slots__ = ("geometry", "mesh", "instance")

    def __init__(self, geometry, mesh, instance):
        self.geometry, self.mesh, self.instance = geometry, mesh, instance


def _is_sorted(a: np.ndarray) -> bool:
    return bool(len(a) < 2 or np.all(a[1:] >= a[:-1]))

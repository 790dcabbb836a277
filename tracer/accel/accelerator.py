"""Ray intersection with Embree 4 (through our binding, :mod:`tracer.accel.embree`): one Embree geometry per object,
batched closest-hit and occlusion queries from compiled loops that release the GIL, so tiles trace on threads.

Two layouts of the same objects:

- **flat** (``instanced=False``, what a one-off :func:`tracer.render` uses): every object's triangle geometry sits in
  the top-level scene, one BVH over all triangles, the fastest to trace;
- **instanced** (``instanced=True``, what a :class:`tracer.Session` uses): every object is an Embree scene of its
  own (its BVH) placed by an ``RTC_GEOMETRY_TYPE_INSTANCE`` in the top-level scene, so moving an object is a
  matrix update and a top-level commit over the instances only, and replacing one object's mesh rebuilds only its
  BVH. (In the flat layout any top-level commit rebuilds the BVH over every triangle: 0.16 s for 660 k.)

Either way a hit reports the *slot* (the object id: instance id, or geometry id in the flat layout) and the
primitive within that object's mesh; :func:`tracer.accel.embree.intersect_rays` maps it back to the row of
``scene.triangles`` through a per-object offset table, so callers see the same ``prim`` as before.

Shared-mesh instances (``scene.instances``, in both layouts): each prototype's object-space triangles are an Embree
scene of their own (one BVH per prototype, built once however many instances it has), and all K instances are one
``RTC_GEOMETRY_TYPE_INSTANCE_ARRAY`` in the top-level scene over a shared (K, 12) float32 transform buffer (Embree
≥ 4.3). A hit on instance k reports the prototype triangle's row in ``prim`` and k in ``inst``
(:meth:`Accelerator.closest_hits`; -1 for the world-space triangles). Moving an instance writes its row of the
buffer and commits the top level (a BVH over K boxes), no mesh BVH is touched.
"""

from __future__ import annotations

import threading
import time as clock
from typing import NamedTuple

import numpy as np

from ..geometry.motion import decompose
from ..heap import trim
from ..lights import linking
from ..scene import Scene
from . import alpha, embree

#: "No hit" in ``prim``.
NO_HIT = -1
# the ray arguments every Embree query takes (tracer.accel.embree: shared with tracer.accel.alpha's filtered queries)
T_FAR_MAX = embree.T_FAR_MAX
_times, _ray_masks = embree.ray_times, embree.ray_masks
_NONE_F32 = np.zeros(0, np.float32)
_NO_INSTANCES = np.zeros(0, np.int32)


class Hits(NamedTuple):
    """Closest hits of a batch of rays: t (inf on a miss), prim (row of ``scene.triangles``, -1 on a miss), the
    barycentrics u, v, and inst (the instance index into ``scene.instances``, -1 where the triangle is not
    instanced or the ray missed)."""

    t: np.ndarray
    prim: np.ndarray
    u: np.ndarray
    v: np.ndarray
    inst: np.ndarray


class Accelerator:
    """A committed Embree scene over ``scene``'s triangles, one geometry per object id. ``prim`` of a hit indexes
    ``scene.triangles``.

    ``quality``: Embree build quality of the objects' BVHs ("low" | "medium" | "high"). ``instanced``: the layout
    (see the module docstring). ``seconds`` accumulates the wall time spent inside Embree queries (summed over
    threads). With ``record=True`` every batch is kept in ``batches`` as (query, origins, directions, t_max, packet
    query of :func:`tracer.accel.embree.query`), so a benchmark can replay exactly the rays and packets the integrator
    traced. ``cancelled``: polled between objects and during
    each BVH build; True stops the set-up with :class:`tracer.accel.embree.BuildCancelled`.
    """

    def __init__(self, scene: Scene, record: bool = False, quality: str = "medium", instanced: bool = False,
                 cancelled=None):
        if quality not in embree.BUILD_QUALITY or quality == "refit":
            raise ValueError(f"quality must be 'low', 'medium' or 'high', got {quality!r}")
        start = clock.perf_counter()
        trim()  # what loading freed goes back to the OS before Embree's build allocates
        self.seconds = 0.0
        self.record = record
        self.batches: list = []
        self.quality = quality
        self.instanced = instanced
        self._lock = threading.Lock()
        self._top = embree.EmbreeScene("medium" if instanced else quality, embree.SCENE_FLAG_ROBUST)
        self._objects: dict[int, _Object] = {}
        self._prototypes: dict[int, _Object] = {}  # prototype object id -> its own scene (never in the top level)
        self._array = None  # the instance array geometry, or None
        self._inst_proto = _NO_INSTANCES
        self._inst_xfm = None
        self._cancelled = cancelled
        self._motion = _embree_motion(scene)
        # ray visibility and shadow linking (tracer.lights.linking): per-object Embree masks, none when unused
        links = linking.pack(scene, len(scene.lights))
        self._masks = links.object_mask if links.masked else None
        self._array_mask = links.array_mask
        #: objects whose geometry the transparent-shadow filter sees (tracer/accel/alpha.py)
        self.filtered = alpha.see_through_objects(scene)
        self._see_through = set(self.filtered.tolist())
        inst = scene.instances
        protos = set(np.unique(inst.prototypes).tolist()) if inst is not None else set()
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
                if oid in protos:
                    self._prototypes[oid] = self._scene_of(self._triangle_geometry(
                        oid, self._vertices, self._triangles[s:e]))
                else:
                    self._add(oid, self._vertices, self._triangles[s:e])
        if inst is not None:
            if cancelled is not None and cancelled():
                raise embree.BuildCancelled("Embree set-up cancelled")
            self.set_instances(inst.prototypes, inst.transforms, commit=False)
            if self._motion is not None and self._motion.instances is not None:
                self._array.set_motion(self._motion.instances)
        self.set_rows(scene.object_ids, commit=False)
        self._top.commit(cancelled)
        self._cancelled = None  # only the set-up is cancellable: edits are short
        self.build_seconds = clock.perf_counter() - start

    # ---------------------------------------------------------------------------------------------- queries
    def intersect(self, origins: np.ndarray, directions: np.ndarray, t_max: np.ndarray | None = None,
                  t_min: float = 0.0):
        """Closest hits on [t_min, t_max]: (t, prim_id, u, v) with prim_id = -1 and t = inf for misses.

        (u, v) are the barycentric coordinates of vertices 1 and 2: p = (1 − u − v)·p0 + u·p1 + v·p2. A hit on
        an instance reports its prototype's row; :meth:`closest_hits` also says which instance.
        """
        return tuple(self.closest_hits(origins, directions, t_max, t_min)[:4])

    def closest_hits(self, origins: np.ndarray, directions: np.ndarray, t_max: np.ndarray | None = None,
                     t_min: float = 0.0, mask: np.ndarray | None = None, time: np.ndarray | None = None,
                     coherent: bool = False) -> Hits:
        """Closest hits on [t_min, t_max] as :class:`Hits` (t, prim, u, v, inst). ``mask``: the rays' Embree masks
        (uint32, one per ray or one for all; None: they see every object), see :mod:`tracer.lights.linking`; ``time``:
        each ray's time in [0, 1] across the shutter (motion blur; None: time 0); ``coherent``: neighbouring rays
        start close and point alike (Embree traces each packet as a frustum, :data:`tracer.accel.embree.COHERENT`)."""
        n = len(origins)
        t = np.empty(n, np.float32)
        prim = np.empty(n, np.int32)
        inst = np.empty(n, np.int32)
        u = np.empty(n, np.float32)
        v = np.empty(n, np.float32)
        if n == 0 or not (self._objects or self._array is not None):
            t.fill(np.inf), prim.fill(NO_HIT), inst.fill(NO_HIT), u.fill(0), v.fill(0)
            return Hits(t, prim, u, v, inst)
        o = np.ascontiguousarray(origins, dtype=np.float32)
        d = np.ascontiguousarray(directions, dtype=np.float32)
        tm = _NONE_F32 if t_max is None else np.ascontiguousarray(np.minimum(t_max, T_FAR_MAX), np.float32)
        q = embree.query(coherent)
        start = clock.perf_counter()
        embree.intersect_rays(self._top.handle, o, d, np.float32(t_min), tm, self._start, self._rows,
                              self._inst_proto, t, prim, inst, u, v, _ray_masks(mask), _times(time), embree.IN_ORDER,
                              q)
        embree.library().check()
        self._account(start, "INTERSECT", o, d, None if t_max is None else tm, q)
        return Hits(t, prim, u, v, inst)

    def occluded(self, origins: np.ndarray, directions: np.ndarray, t_max: np.ndarray, t_min: float = 0.0,
                 mask: np.ndarray | None = None, time: np.ndarray | None = None, coherent: bool = False,
                 order: np.ndarray | None = None):
        """Boolean mask: something lies on the segment [origin + t_min·direction, origin + t_max·direction]
        (shadow rays); ``mask`` as in :meth:`closest_hits`, ``time`` each ray's time (None: 0); ``coherent`` as there.
        ``order``: which rays share packets (the batch's rows in packet order, e.g. shadow rays grouped by light;
        None: consecutive rows)."""
        n = len(origins)
        blocked = np.zeros(n, bool)
        if n == 0 or not (self._objects or self._array is not None):
            return blocked
        o = np.ascontiguousarray(origins, dtype=np.float32)
        d = np.ascontiguousarray(directions, dtype=np.float32)
        tm = np.ascontiguousarray(np.minimum(t_max, T_FAR_MAX), dtype=np.float32)
        q = embree.query(coherent)
        idx = embree.IN_ORDER if order is None else np.ascontiguousarray(order, np.int64)
        start = clock.perf_counter()
        embree.occluded_rays(self._top.handle, o, d, np.float32(t_min), tm, blocked, _ray_masks(mask),
                             _times(time), idx, q)
        embree.library().check()
        self._account(start, "OCCLUDED", o, d, tm, q, order)
        return blocked

    # ---------------------------------------------------------------------------------------------- edits
    def set_transform(self, object_id: int, matrix) -> None:
        """Place object ``object_id``'s mesh (as it was built) with the 4×4 ``matrix`` (column vectors) and commit
        the top-level scene. In the flat layout the object first becomes an instance of its own."""
        obj = self._objects[object_id]
        if obj.instance is None:
            self._top.detach(_geom_id(object_id))
            self._objects[object_id] = obj = self._instance_of(obj.geometry)
            self._set_mask(object_id, obj.instance)
            self._top.attach(obj.instance, _geom_id(object_id))
        obj.instance.set_transform(matrix)
        self._top.commit()

    def set_instances(self, prototypes: np.ndarray, transforms: np.ndarray, commit: bool = True) -> None:
        """The instance array becomes K instances: instance k places prototype object ``prototypes[k]`` (whose
        scene this accelerator built) with ``transforms[k]`` (4×4). K = 0 removes the array."""
        prototypes = np.ascontiguousarray(prototypes, np.int32)
        if self._array is not None:
            self._top.detach(embree.ARRAY_GEOM_ID)
            self._array = None
        self._inst_proto, self._inst_xfm = _NO_INSTANCES, None
        if len(prototypes):
            for p in np.unique(prototypes).tolist():
                if p not in self._prototypes:  # a prototype without triangles: an empty scene
                    self._prototypes[p] = self._scene_of(None)
            order = sorted(self._prototypes)
            index = np.searchsorted(np.asarray(order), prototypes).astype(np.uint32)
            self._inst_xfm = embree.column_major_3x4(transforms)
            self._array = embree.InstanceArrayGeometry([self._prototypes[p].mesh for p in order], index,
                                                       self._inst_xfm)
            if self._masks is not None:
                self._array.set_mask(self._array_mask)
            self._top.attach(self._array, embree.ARRAY_GEOM_ID)
            self._inst_proto = prototypes
        if commit:
            self._top.commit()

    def set_instance_transforms(self, indices, transforms) -> None:
        """Instances ``indices`` get the 4×4 matrices ``transforms`` (one per index): their rows of the shared
        transform buffer are rewritten and the top level committed (no mesh BVH touched)."""
        idx = np.asarray(indices, np.int64).reshape(-1)
        self._inst_xfm[idx] = embree.column_major_3x4(transforms)[:len(idx)]
        self._array.transforms_changed()
        self._top.commit()

    def set_object(self, object_id: int, vertices: np.ndarray | None, triangles: np.ndarray | None) -> None:
        """Object ``object_id`` gets a new mesh (world-space float32 vertices, int32 triangles of its own; None:
        removed). Only its BVH is built; call :meth:`set_rows` after the scene's arrays changed, which commits."""
        if object_id in self._prototypes:  # a shared mesh: rebuild its scene in place, its instances follow
            proto = self._prototypes[object_id]
            proto.mesh.detach(0)
            geometry = None
            if vertices is not None and len(triangles):
                geometry = self._triangle_geometry(object_id, embree.padded(vertices, np.float32),
                                                   embree.padded(triangles, np.int32))
                proto.mesh.attach(geometry, 0)
            proto.mesh.commit()
            proto.geometry = geometry
            if self._array is not None:
                self._array.commit()
            return
        if object_id in self._objects:
            self._top.detach(_geom_id(object_id))
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
        n = max(int(ids.max()) + 1 if len(ids) else 0, max(self._objects, default=-1) + 1,
                max(self._prototypes, default=-1) + 1)
        self._start = np.searchsorted(sorted_ids, np.arange(n)).astype(np.int64)
        self._rows = rows
        self.triangle_count = len(ids)
        if commit:
            self._top.commit()

    def close(self) -> None:
        """Release the Embree scenes now (otherwise when this object is garbage collected)."""
        self._objects.clear()
        self._array = None
        self._top.release()
        self._prototypes.clear()

    # ---------------------------------------------------------------------------------------------- internals
    def _triangle_geometry(self, object_id, vertices, triangles):
        """The object's triangle geometry; one that may be see-through lets tracer/accel/alpha.py's filter see its hits."""
        geometry = embree.TriangleGeometry(vertices, triangles, self.quality)
        if object_id in self._see_through:
            geometry.enable_argument_filter()
            geometry.commit()
        return geometry

    def _add(self, object_id, vertices, triangles):
        geometry = self._triangle_geometry(object_id, vertices, triangles)
        mo = self._motion
        if mo is not None and object_id in mo.deforming and vertices is getattr(self, "_vertices", None):
            geometry.set_vertex_steps(mo.vertex_steps)  # the same rows of each step's vertex buffer
        if mo is not None and object_id in mo.objects:  # a moving object: an instance with its time steps
            obj = self._instance_of(geometry)
            obj.instance.set_motion(mo.objects[object_id])
            self._set_mask(object_id, obj.instance)
            self._top.attach(obj.instance, _geom_id(object_id))
        elif self.instanced:
            obj = self._instance_of(geometry)
            self._set_mask(object_id, obj.instance)
            self._top.attach(obj.instance, _geom_id(object_id))
        else:
            obj = _Object(geometry, None, None)
            self._set_mask(object_id, geometry)
            self._top.attach(geometry, _geom_id(object_id))
        self._objects[object_id] = obj

    def _set_mask(self, object_id, top_level_geometry):
        """The object's ray-visibility / blocker mask on its top-level geometry (tracer.lights.linking), if any."""
        if self._masks is not None and object_id < len(self._masks):
            top_level_geometry.set_mask(int(self._masks[object_id]))

    def _scene_of(self, geometry):
        """An Embree scene of its own over ``geometry`` (None: empty), committed."""
        mesh = embree.EmbreeScene(self.quality, embree.SCENE_FLAG_ROBUST)
        if geometry is not None:
            mesh.attach(geometry, 0)
        mesh.commit(self._cancelled)
        return _Object(geometry, mesh, None)

    def _instance_of(self, geometry):
        obj = self._scene_of(geometry)
        obj.instance = embree.InstanceGeometry(obj.mesh)
        return obj

    def _account(self, start, query, o, d, t_max, q, order=None):
        """Time spent in Embree; with ``record``, the batch as (query, o, d, t_max, q) in the order its packets were
        made (``q``: :func:`tracer.accel.embree.query`)."""
        elapsed = clock.perf_counter() - start
        with self._lock:
            self.seconds += elapsed
            if self.record:
                rows = slice(None) if order is None else order
                t = None if t_max is None else np.array(t_max, np.float32)[rows]
                self.batches.append((query, o[rows].copy(), d[rows].copy(), t, q))


class _Object:
    __slots__ = ("geometry", "mesh", "instance")

    def __init__(self, geometry, mesh, instance):
        self.geometry, self.mesh, self.instance = geometry, mesh, instance


class _EmbreeMotion(NamedTuple):
    """``scene.motion`` as Embree takes it: per moving object id its (S, 16) decomposed steps, the instances'
    (K, S, 16) (or None), the deforming object ids and the padded vertex buffers of every step."""

    objects: dict
    instances: np.ndarray | None
    deforming: frozenset
    vertex_steps: list


def _embree_motion(scene) -> _EmbreeMotion | None:
    mo = getattr(scene, "motion", None)
    if mo is None or not mo.moves:
        return None
    dec = decompose(mo.object_motion) if len(mo.object_ids) else np.zeros((0, mo.steps, 16))
    steps = [embree.padded(v, np.float32) for v in mo.vertices] if mo.vertices is not None else []
    return _EmbreeMotion(objects={int(o): dec[i] for i, o in enumerate(mo.object_ids.tolist())},
                         instances=None if mo.instance_motion is None else decompose(mo.instance_motion),
                         deforming=frozenset(mo.deforming.tolist()), vertex_steps=steps)


def _geom_id(object_id: int) -> int:
    """The top-level geometry id of object ``object_id`` (id 0 is the instance array's)."""
    return int(object_id) + embree.OBJECT_GEOM_BASE


def _is_sorted(a: np.ndarray) -> bool:
    return bool(len(a) < 2 or np.all(a[1:] >= a[:-1]))

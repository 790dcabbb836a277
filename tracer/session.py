"""A prepared scene that stays prepared: :class:`Session` holds the Embree scene and what the kernels read (packed
materials, lights, textures, the environment) and takes edits that touch only what changed.

    session = tracer.Session(scene)
    image = session.render(settings)
    session.update_camera(camera)            # nothing rebuilt
    session.set_transform(object_id, matrix) # one Embree instance matrix + commit; no mesh rebuild
    image = session.render(settings)

What each edit costs (see docs/session-api.md for the full contract):

==========================  ===================================================================================
``update_camera``           nothing: the next render generates eye rays from the new camera
``update_materials``        repack the material table and textures (no BVH work)
``update_lights``           repack the light table (no BVH work)
``update_world``            repack background / ambient / environment (no BVH work)
``set_transform``           the object's Embree instance matrix + top-level commit; its vertices in
                            ``session.scene`` are moved (numpy, O(its vertices)), no mesh rebuild
``update_mesh``             rebuild that object's Embree geometry only
``add_object``              a new Embree geometry (its BVH) + top-level commit
``remove_object``           detach its geometry + top-level commit
``add_instances``           the instance array's buffers grow (numpy) + top-level commit; no mesh BVH
``remove_instances``        the instance array's buffers shrink + top-level commit
==========================  ===================================================================================

Instances (``scene.instances``): ``set_transform`` of an instance's object id rewrites its row of the instance
array's transform buffer (no BVH but the top level's, over the instances' boxes); ``update_mesh`` of a prototype
rebuilds that one shared BVH and every instance of it follows; ``update_mesh`` of an instance's id turns that
instance into an ordinary object with the given mesh; ``remove_object`` of a prototype removes its instances too.

``session.scene`` is always the edited scene (world-space triangles, prototypes and instances): rendering it afresh
with :func:`tracer.render` gives the same picture as ``session.render`` (tests/test_session.py and
tests/test_instances.py check this for every kind of edit).

A session is not thread-safe against itself: make edits between renders (the viewport cancels the render in
flight first), never during one. Renders themselves run their tiles on threads.
"""

from __future__ import annotations

import copy
import threading
import time
import warnings

import numpy as np

from .accel.accelerator import Accelerator
from .accel.embree import BuildCancelled
from .builder import _corner_extras, place_mesh
from .camera import Camera
from .film import Image
from .integrator.tiles import RenderCancelled, render_session
from .integrator.wavefront import Integrator
from .lights.emitters import AreaLight, DistantLight, PointLight, SpotLight
from .lights.environment import Environment
from .scene import PER_TRIANGLE, Instances, Scene, non_degenerate, singular, unit_normals
from .settings import RenderSettings, integrator_key
from .shading.materials import Materials

#: Sentinel for ``update_world`` arguments that stay as they are.
KEEP = object()


class Session:
    """``Session(scene)``: build the Embree scene for ``scene`` once; render it many times; edit it in place.

    ``scene`` is not modified: the session works on a shallow copy (arrays are shared until an edit replaces
    them). ``quality``: Embree build quality of the object BVHs, "low" | "medium" | "high" (Embree's
    RTC_BUILD_QUALITY_*; "high" traces fastest, "low" builds fastest, for scenes edited while they are looked at).
    ``instanced``: every object an Embree instance of its own mesh (edits touch only that object; the default),
    or one flat BVH over all triangles (a little faster to trace, but every geometry edit rebuilds it all: what
    the one-off :func:`tracer.render` uses). ``accel``: an already built :class:`~tracer.accel.accelerator.Accelerator`.
    ``cancelled``: polled while the Embree scene is built (between objects and inside Embree's builds); True
    stops the construction with :class:`tracer.RenderCancelled` (its ``image`` is None).
    """

    def __init__(self, scene: Scene, *, quality: str = "medium", instanced: bool = True,
                 accel: Accelerator | None = None, cancelled=None):
        if not isinstance(scene, Scene):
            raise TypeError(f"Session expects a tracer.Scene, got {type(scene).__name__}")
        start = time.perf_counter()
        self._scene = copy.copy(scene)
        self._scene.lights = list(scene.lights)
        self._scene.textures = list(scene.textures)
        self._scene.object_names = list(scene.object_names)
        self.quality = quality
        self._lock = threading.Lock()
        self._integrators: dict = {}  # settings key -> Integrator (packed tables), dropped by edits
        if accel is None:
            try:
                accel = Accelerator(self._scene, quality=quality, instanced=instanced, cancelled=cancelled)
            except BuildCancelled:
                raise RenderCancelled(None) from None
        self._accel = accel
        self._geometry = _Objects(self._scene, self._accel)
        self.stats = {"build_seconds": time.perf_counter() - start, "last_edit": None}
        self._closed = False

    # ---------------------------------------------------------------------------------------------- queries
    @property
    def scene(self) -> Scene:
        """The scene as edited so far (world-space triangles, prototypes and instances): what a fresh
        :func:`tracer.render` would need."""
        return self._scene

    @property
    def accel(self) -> Accelerator:
        return self._accel

    def object_ids(self) -> np.ndarray:
        """Ids of the objects that are currently drawn: those with world-space triangles and the instances
        (prototypes, drawn only through their instances, are not listed)."""
        s = self._scene
        ids = np.unique(s.object_ids[~s.prototype_rows()])
        return ids if s.instances is None else np.union1d(ids, s.instances.object_ids)

    def transform(self, object_id: int) -> np.ndarray:
        """The 4×4 object-to-world matrix object ``object_id`` has now."""
        return self._geometry.transform(int(object_id)).copy()

    # ---------------------------------------------------------------------------------------------- edits
    def update_camera(self, camera: Camera) -> None:
        """A new camera: nothing is rebuilt."""
        if not isinstance(camera, Camera):
            raise TypeError(f"update_camera expects a tracer.Camera, got {type(camera).__name__}")
        with self._edit("camera"):
            self._scene.camera = camera  # the packed tables do not depend on the camera: nothing to drop

    def update_materials(self, materials: Materials, textures: list | None = None) -> None:
        """A new material table (and, if given, texture list); repacked at the next render, no BVH work. The
        triangles keep their material ids, so the table must still cover them."""
        with self._edit("materials"):
            s = self._scene
            probe = _probe(s, materials=materials, textures=list(s.textures if textures is None else textures))
            if len(s.material_ids) and int(s.material_ids.max()) >= len(probe.materials):
                raise ValueError(f"update_materials: the scene uses material {int(s.material_ids.max())} but the "
                                 f"new table has {len(probe.materials)} rows")
            if s.instances is not None and int(s.instances.material_overrides().max()) >= len(probe.materials):
                raise ValueError(f"update_materials: an instance uses material "
                                 f"{int(s.instances.material_overrides().max())} but the new table has "
                                 f"{len(probe.materials)} rows")
            s.materials, s.textures = probe.materials, probe.textures
            self._repack()

    def update_lights(self, lights: list) -> None:
        """A new light list; repacked at the next render, no BVH work."""
        with self._edit("lights"):
            self._scene.lights = _probe(self._scene, lights=list(lights)).lights
            self._repack()

    def update_world(self, *, background=KEEP, ambient=KEEP, environment=KEEP) -> None:
        """New world colours and/or environment (``None`` removes it); arguments left out stay as they are.
        Repacked at the next render, no BVH work."""
        with self._edit("world"):
            s = self._scene
            changes = {k: v for k, v in (("background", background), ("ambient", ambient),
                                         ("environment", environment)) if v is not KEEP}
            probe = _probe(s, **changes)
            s.background, s.ambient, s.environment = probe.background, probe.ambient, probe.environment
            self._repack()

    def set_transform(self, object_id: int, matrix) -> None:
        """Place object ``object_id`` with the 4×4 object-to-world ``matrix`` (column vectors: p_world = M @ p),
        replacing the one it has now (``scene.object_transforms``; identity for objects given in world space).

        Embree: the object's instance matrix changes and the top-level scene is committed; its mesh BVH is kept.
        ``session.scene`` gets the moved vertices and normals (numpy over that object's rows). A matrix that
        mirrors where the old one did not (or the reverse) rebuilds that object's mesh instead, since its winding
        turns around (as :meth:`tracer.SceneBuilder.add_mesh` does)."""
        m = _matrix(matrix, f"set_transform({object_id})")
        with self._edit("transform"):
            k = self._geometry.instances_of(int(object_id))
            if len(k):  # an instance (or several under one id): its rows of the instance array, nothing else
                self._geometry.move_instances(int(object_id), k, m)
            else:
                self._geometry.refuse_prototype(int(object_id), "set_transform")
                self._geometry.set_transform(int(object_id), m)
            self._repack()

    def add_instances(self, prototype: int, transforms, names=None, materials=None) -> np.ndarray:
        """Place object ``prototype``'s mesh K more times (arguments as :meth:`tracer.SceneBuilder.add_instances`;
        an object drawn in world space so far cannot become a prototype: add its mesh again for that); returns
        the new instances' object ids. No mesh BVH is built."""
        with self._edit("add_instances"):
            return self._geometry.add_instances(int(prototype), transforms, names, materials)

    def remove_instances(self, object_ids) -> None:
        """Remove the instances with these object ids (their ids and names stay reserved)."""
        with self._edit("remove_instances"):
            self._geometry.remove_instances(np.asarray(object_ids, np.int64).reshape(-1))
            self._repack()

    def update_mesh(self, object_id: int, vertices, triangles, material=0, normals=None, uvs=None,
                    transform=None, uv_sets=None, colors=None) -> None:
        """Replace the geometry of object ``object_id`` (arguments as :meth:`tracer.SceneBuilder.add_mesh`:
        object-space vertices, optional 4×4 ``transform``); only that object's Embree geometry is rebuilt."""
        with self._edit("mesh"):
            object_id = int(object_id)
            if len(self._geometry.instances_of(object_id)):  # an instance becomes an object of its own
                self._geometry.remove_instances(np.array([object_id]))
            else:
                self._geometry.require(object_id)
                if self._geometry.is_prototype(object_id) and transform is not None:
                    raise ValueError(f"update_mesh({object_id}): object {object_id} is a prototype (its mesh is in "
                                     "object space, placed by its instances): pass no transform")
            label = self._scene.object_name(object_id)
            mesh = place_mesh(vertices, triangles, material, transform=transform, normals=normals, uvs=uvs,
                              label=label, n_materials=len(self._scene.materials))
            extra = _corner_rows(label, mesh, vertices, uv_sets, colors)
            self._geometry.replace(object_id, mesh, extra=extra)
            self._repack()

    def add_object(self, vertices, triangles, material=0, name: str | None = None, transform=None, normals=None,
                   uvs=None, uv_sets=None, colors=None) -> int:
        """Add an object (arguments as :meth:`tracer.SceneBuilder.add_mesh`); returns its new object id."""
        with self._edit("add"):
            object_id = self._geometry.next_object_id()
            label = name or f"object{object_id}"
            mesh = place_mesh(vertices, triangles, material, transform=transform, normals=normals, uvs=uvs,
                              label=label, n_materials=len(self._scene.materials))
            extra = _corner_rows(label, mesh, vertices, uv_sets, colors)
            self._geometry.replace(object_id, mesh, name=label, extra=extra)
            self._repack()
            return object_id

    def remove_object(self, object_id: int) -> None:
        """Remove object ``object_id``'s triangles (its id and name stay reserved)."""
        with self._edit("remove"):
            object_id = int(object_id)
            if len(self._geometry.instances_of(object_id)):
                self._geometry.remove_instances(np.array([object_id]))
                self._repack()
                return
            self._geometry.require(object_id)
            if self._geometry.is_prototype(object_id):  # its instances go with it
                inst = self._scene.instances
                self._geometry.remove_instances(inst.object_ids[inst.prototypes == object_id])
            self._geometry.replace(object_id, None)
            self._repack()

    # ---------------------------------------------------------------------------------------------- rendering
    def render(self, settings: RenderSettings | None = None, on_tile=None, cancelled=None) -> Image:
        """Render the session's scene (as :func:`tracer.render`: tiles on threads, ``on_tile(image, tile)`` after
        each tile, ``cancelled()`` polled between tiles and depths, :class:`tracer.RenderCancelled` on a True)."""
        return render_session(self, settings, on_tile=on_tile, cancelled=cancelled)

    def integrator(self, settings: RenderSettings):
        """The :class:`tracer.integrator.wavefront.Integrator` for ``settings`` (packed tables), made once per settings
        until an edit other than the camera drops it."""
        key = integrator_key(settings)
        with self._lock:
            integ = self._integrators.get(key)
            if integ is None:
                integ = Integrator(self._scene, settings, self._accel)
                self._integrators = {key: integ}  # one at a time: the tables can be large
            else:
                integ.settings = settings
            return integ

    def close(self) -> None:
        """Release the Embree scene now (it is also released when the session is garbage collected)."""
        if not self._closed:
            self._closed = True
            self._integrators.clear()
            close = getattr(self._accel, "close", None)
            if close is not None:
                close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # ---------------------------------------------------------------------------------------------- internals
    def _repack(self):
        """Drop the packed tables: the next render packs them again from the edited scene."""
        with self._lock:
            self._integrators = {}

    def _edit(self, kind):
        session = self

        class _Timer:
            def __enter__(self):
                if session._closed:
                    raise RuntimeError("this Session has been closed")
                self.t0 = time.perf_counter()

            def __exit__(self, exc_type, *rest):
                if exc_type is None:
                    session.stats["last_edit"] = {"kind": kind, "seconds": time.perf_counter() - self.t0}

        return _Timer()


class _Objects:
    """The session scene's per-object bookkeeping: which rows of the flat arrays belong to an object, the
    object-to-world matrix it has and the one its Embree geometry was built with; every geometry edit rewrites the
    flat arrays of ``scene`` (so it stays the flattened, edited scene) and tells the accelerator about that object
    only."""

    def __init__(self, scene: Scene, accel: Accelerator):
        self.scene = scene
        self.accel = accel
        self._base = scene.object_transforms  # the matrices of the scene the session was made from (or None)
        self._transforms: dict[int, np.ndarray] = {}  # objects moved or replaced since: their matrix now
        self._built: dict[int, np.ndarray] = {}  # ... and the one their Embree geometry's vertices have
        self._owned: set[str] = set()  # scene arrays the session has copied and may now write in place
        self._rows: dict[int, np.ndarray] = {}  # object id -> its rows (cached until rows move)
        self._vidx: dict[int, np.ndarray] = {}  # object id -> the vertices only it uses (cached likewise)

    def _base_transform(self, object_id: int) -> np.ndarray:
        b = self._base
        return b[object_id] if b is not None and object_id < len(b) else np.eye(4)

    def transform(self, object_id: int) -> np.ndarray:
        m = self._transforms.get(object_id)
        return m if m is not None else self._base_transform(object_id)

    def require(self, object_id: int) -> np.ndarray:
        """The rows of object ``object_id`` (KeyError if it has none)."""
        rows = self._rows.get(object_id)
        if rows is None:
            rows = np.flatnonzero(self.scene.object_ids == object_id)
            if not len(rows):
                raise KeyError(f"object {object_id} has no triangles in this session")
            self._rows[object_id] = rows
        return rows

    def _vertices_of(self, object_id: int, rows) -> np.ndarray:
        """The vertices only object ``object_id`` uses (shared ones are split off first; cached until rows move)."""
        vidx = self._vidx.get(object_id)
        if vidx is None:
            n_v = len(self.scene.vertices)
            vidx = _own_vertices(self.scene, rows)
            if len(self.scene.vertices) != n_v:  # vertices were split off: both arrays are new, and ours
                self._owned.update(("vertices", "triangles"))
            self._vidx[object_id] = vidx
        return vidx

    def _writable(self, name: str) -> np.ndarray:
        """The scene array ``name``, copied the first time the session writes to it (the arrays of the scene the
        session was made from are never written), then edited in place."""
        if name not in self._owned:
            setattr(self.scene, name, np.array(getattr(self.scene, name)))
            self._owned.add(name)
        return getattr(self.scene, name)

    def next_object_id(self) -> int:
        s = self.scene
        return max(len(s.object_names), int(s.object_ids.max()) + 1 if len(s.object_ids) else 0,
                   max(self._transforms, default=-1) + 1,
                   len(self._base) if self._base is not None else 0,
                   int(s.instances.object_ids.max()) + 1 if s.instances is not None else 0)

    # ------------------------------------------------------------------ instances
    def is_prototype(self, object_id: int) -> bool:
        inst = self.scene.instances
        return inst is not None and bool(np.any(inst.prototypes == object_id))

    def refuse_prototype(self, object_id: int, what: str) -> None:
        if self.is_prototype(object_id):
            raise ValueError(f"{what}({object_id}): object {object_id} is a prototype, drawn only through its "
                             "instances: move its instances instead")

    def instances_of(self, object_id: int) -> np.ndarray:
        """Indices into ``scene.instances`` of the instances with object id ``object_id``."""
        inst = self.scene.instances
        return np.zeros(0, np.int64) if inst is None else np.flatnonzero(inst.object_ids == object_id)

    def _set_instances(self, instances: Instances | None) -> None:
        s = self.scene
        s.instances = instances if instances is not None and len(instances) else None
        s._bounds = None
        if s.instances is None:
            self.accel.set_instances(np.zeros(0, np.int32), np.zeros((0, 4, 4)))
        else:
            self.accel.set_instances(s.instances.prototypes, s.instances.transforms)

    def move_instances(self, object_id: int, k: np.ndarray, matrix: np.ndarray) -> None:
        s = self.scene
        inst = s.instances
        transforms = inst.transforms.copy() if "instances" not in self._owned else inst.transforms
        transforms[k] = matrix
        if "instances" not in self._owned:
            s.instances = Instances(inst.prototypes, transforms, inst.object_ids, inst.materials)
            self._owned.add("instances")
        s._bounds = None
        self._transforms[object_id] = matrix
        self._sync_transforms()
        self.accel.set_instance_transforms(k, np.broadcast_to(matrix, (len(k), 4, 4)))

    def add_instances(self, prototype: int, transforms, names, materials) -> np.ndarray:
        s = self.scene
        if not self.is_prototype(prototype):
            if np.any(s.object_ids == prototype):
                raise ValueError(f"add_instances({prototype}): object {prototype} is drawn in world space, not a "
                                 "prototype; add its object-space mesh as a new object and instance that")
            raise KeyError(f"object {prototype} has no triangles in this session")
        m = np.asarray(transforms, np.float64)
        m = m[None] if m.shape == (4, 4) else m
        first = self.next_object_id()
        ids = np.arange(first, first + len(m), dtype=np.int32)
        mats = None if materials is None else np.broadcast_to(np.asarray(materials, np.int32), (len(m),)).copy()
        inst = s.instances
        new = Instances(np.full(len(m), prototype, np.int32), m, ids, mats)
        new.validate(len(s.materials))  # the scene's own checks: shapes, finite, invertible, material rows
        both = Instances(np.concatenate([inst.prototypes, new.prototypes]),
                         np.concatenate([inst.transforms, new.transforms]),
                         np.concatenate([inst.object_ids, ids]),
                         None if inst.materials is None and mats is None else
                         np.concatenate([inst.material_overrides(), new.material_overrides()]))
        label = s.object_name(prototype)
        names = [f"{label}[{i}]" for i in range(len(m))] if names is None else [str(n) for n in names]
        if len(names) != len(m):
            raise ValueError(f"add_instances({prototype}): {len(names)} names for {len(m)} instances")
        s.object_names = list(s.object_names) + [f"object{i}" for i in range(len(s.object_names), first)] + names
        if s.object_pass_indices is not None:
            s.object_pass_indices = np.concatenate([s.object_pass_indices, np.arange(
                len(s.object_pass_indices), first + len(m), dtype=np.int32)])
        for i, mi in zip(ids.tolist(), m):
            self._transforms[i] = mi
        self._owned.add("instances")
        self._set_instances(both)
        self._sync_transforms()
        return ids

    def remove_instances(self, object_ids: np.ndarray) -> None:
        inst = self.scene.instances
        gone = np.zeros(0, bool) if inst is None else np.isin(inst.object_ids, object_ids)
        unknown = np.setdiff1d(object_ids, [] if inst is None else inst.object_ids)
        if len(unknown):
            raise KeyError(f"object {int(unknown[0])} is not an instance in this session")
        keep = ~gone
        self._owned.add("instances")
        self._set_instances(Instances(inst.prototypes[keep], inst.transforms[keep], inst.object_ids[keep],
                                      None if inst.materials is None else inst.materials[keep]))

    def _corner_normals(self) -> None:
        """Edits work on rows of per-triangle fields: per-vertex normals and UV sets (Scene.normals, uv_sets)
        become per-corner ones the first time (new arrays, owned by the session)."""
        if self.scene.normals_per_vertex or self.scene.uvs_per_vertex:
            self.scene.to_corner_layout()
            self._owned.update(("normals", "uv_sets"))

    def set_transform(self, object_id: int, matrix: np.ndarray) -> None:
        rows = self.require(object_id)
        s = self.scene
        self._corner_normals()
        rel = matrix @ np.linalg.inv(self.transform(object_id))
        if np.linalg.det(rel[:3, :3]) < 0:  # the winding turns around: a new mesh for this object
            v, t = _object_mesh(s, rows)
            mesh = place_mesh(v, t, s.material_ids[rows], transform=rel,
                              normals=None if s.normals is None else s.normals[rows],
                              label=s.object_name(object_id))
            # Any other per-triangle data of these rows goes along (UV sets included), corners turned as
            # place_mesh turned them.
            extra = {f: _rows_of(getattr(s, f), rows, mirrored=True) for f in PER_TRIANGLE
                     if f not in ("material_ids", "object_ids", "normals")}
            self._transforms[object_id] = matrix
            self.replace(object_id, mesh, placed_with=matrix, extra=extra)
            return
        vidx = self._vertices_of(object_id, rows)
        v = self._writable("vertices")
        v[vidx] = (v[vidx].astype(np.float64) @ rel[:3, :3].T + rel[:3, 3]).astype(np.float32)
        if s.normals is not None:  # by the inverse transpose, renormalised (zero = unusable stays zero)
            n = self._writable("normals")
            span = slice(rows[0], rows[-1] + 1) if rows[-1] - rows[0] + 1 == len(rows) else rows
            moved = n[span] @ np.linalg.inv(rel[:3, :3]).astype(np.float32)  # n @ (M^-T)^T = n @ M^-1
            length = np.sqrt(np.einsum("rki,rki->rk", moved, moved))[..., None]
            moved /= np.where(length > 0, length, np.float32(1))
            n[span] = moved
        s._bounds = None
        self._transforms[object_id] = matrix
        self._sync_transforms()
        built = self._built.get(object_id)
        built = built if built is not None else self._base_transform(object_id)
        self.accel.set_transform(object_id, matrix @ np.linalg.inv(built))

    def replace(self, object_id: int, mesh, name: str | None = None, placed_with=None, extra=None) -> None:
        """Object ``object_id``'s rows become ``mesh`` (a :func:`place_mesh` result; None: no triangles) and
        ``extra`` (per-triangle fields of ``PER_TRIANGLE`` that place_mesh does not make, e.g. the old rows' data of
        a re-placed mesh). Its new rows go where its old ones began (the end for a new object), so the row order
        stays that of a scene built afresh in the same object order."""
        s = self.scene
        self._corner_normals()
        old = s.object_ids == object_id
        at = int(np.argmax(old)) if old.any() else len(old)  # where its rows began (the end if it had none)
        keep = ~old
        n_v = len(s.vertices)
        rows = dict(extra or {})
        if mesh is not None:
            mesh, rows = _clean(mesh, s, rows)
            nt = len(mesh.triangles)
            rows.update(material_ids=mesh.material_ids, object_ids=np.full(nt, object_id, np.int32),
                        normals=mesh.normals)
            rows["uv_sets"] = _uv_set_rows(rows.get("uv_sets"), mesh.uvs)
            tris = np.concatenate([s.triangles[keep][:at], mesh.triangles + n_v, s.triangles[keep][at:]])
            verts = np.concatenate([s.vertices, mesh.vertices]).astype(np.float32)
        else:
            nt, tris, verts = 0, s.triangles[keep], s.vertices
        new_sets = rows.get("uv_sets") or []
        if len(new_sets) > len(s.uv_sets or []):  # the new rows bring UV sets the scene has not had yet
            s.uv_sets = list(s.uv_sets or []) + [None] * (len(new_sets) - len(s.uv_sets or []))
        for field_name, fill in PER_TRIANGLE.items():
            setattr(s, field_name, _splice(getattr(s, field_name), rows.get(field_name), keep, at, nt, fill))
            self._owned.add(field_name)
        n_rows = len(tris)
        s.uv_sets = [a if a is not None else np.full((n_rows, 3, 2), np.nan, np.float32) for a in s.uv_sets or []]
        s.uvs = s.uv_sets[0] if s.uv_sets else None
        s._uvs_validated = s.uvs
        self._owned.update(("vertices", "triangles"))  # new arrays below
        self._rows.clear()  # rows moved, vertices renumbered
        self._vidx.clear()
        # Drop the vertices no triangle uses any more (the replaced object's), renumbering the rest.
        used = np.zeros(len(verts), bool)
        used[tris.ravel()] = True
        if not used.all():
            remap = np.cumsum(used, dtype=np.int64) - 1
            verts = verts[used]
            tris = remap[tris].astype(np.int32)
        s.vertices = np.ascontiguousarray(verts, np.float32)
        s.triangles = np.ascontiguousarray(tris, np.int32)
        s._bounds = None
        if name is not None:
            s.object_names = list(s.object_names) + [f"object{i}" for i in range(len(s.object_names), object_id)]
            s.object_names[object_id:object_id + 1] = [name]
            if s.object_pass_indices is not None and len(s.object_pass_indices) <= object_id:
                s.object_pass_indices = np.concatenate([s.object_pass_indices, np.arange(
                    len(s.object_pass_indices), object_id + 1, dtype=np.int32)])
        placed = placed_with if placed_with is not None else (mesh.transform if mesh is not None else np.eye(4))
        self._transforms[object_id] = placed
        self._built[object_id] = placed.copy()
        self._sync_transforms()
        self.accel.set_object(object_id, None if mesh is None else mesh.vertices,
                              None if mesh is None else mesh.triangles)
        self.accel.set_rows(s.object_ids)

    def _sync_transforms(self):
        """``scene.object_transforms`` = the matrices the objects have now."""
        n = max(max(self._transforms, default=-1) + 1, len(self._base) if self._base is not None else 0,
                len(self.scene.object_names))
        out = np.tile(np.eye(4), (n, 1, 1)) if self._base is None else np.concatenate(
            [self._base, np.tile(np.eye(4), (max(0, n - len(self._base)), 1, 1))])
        for i, m in self._transforms.items():
            out[i] = m
        self.scene.object_transforms = out


def _splice(current, new, keep, at, n_new, fill):
    """One per-triangle field after an object's rows changed: the kept rows, with ``new`` (``n_new`` rows, or
    ``fill`` where None) inserted at ``at``. List-valued fields (several arrays) are spliced array by array."""
    if isinstance(current, list):
        new = new if isinstance(new, list) else [None] * len(current)
        return [_splice(c, n, keep, at, n_new, fill) for c, n in zip(current, new + [None] * len(current))]
    if current is None and new is None:
        return None
    if new is not None and n_new == 0:
        new = None
    if current is None:
        current = np.full((len(keep),) + np.shape(new)[1:], fill, np.asarray(new).dtype)
    if new is None:
        new = np.full((n_new,) + current.shape[1:], fill, current.dtype)
    kept = current[keep]
    return np.ascontiguousarray(np.concatenate([kept[:at], np.asarray(new, kept.dtype), kept[at:]]))


def _rows_of(field, rows, mirrored=False):
    """The given rows of a per-triangle field (list-valued: of each array), corners 1 and 2 swapped if mirrored."""
    if field is None:
        return None
    if isinstance(field, list):
        return [_rows_of(f, rows, mirrored) for f in field]
    part = field[rows]
    return part[:, [0, 2, 1]] if mirrored and part.ndim >= 2 and part.shape[1] == 3 else part


def _corner_rows(label, mesh, vertices, uv_sets, colors) -> dict:
    """The per-corner UV sets and colours of a mesh given to ``add_object``/``update_mesh``, checked and turned as
    :func:`place_mesh` turned its triangles: {"uv_sets": [arrays or None], "colors": array or None}."""
    mirrored = bool(np.linalg.det(mesh.transform[:3, :3]) < 0)
    n_v = len(np.asarray(vertices).reshape(-1, 3))
    ex = _corner_extras(label, uv_sets, colors, mesh.uvs, n_v, mesh.triangles, mirrored)
    sets = ex["uv_sets"]
    listed = [sets.get(k) for k in range(max(sets, default=-1) + 1)]
    return {"uv_sets": listed or None, "colors": ex["colors"]}


def _uv_set_rows(sets, uvs):
    """The UV sets of new rows as a list (index = set), with the placed mesh's ``uvs`` as set 0."""
    out = list(sets or [])
    if uvs is not None:
        out = out or [None]
        out[0] = uvs
    return out or None


def _clean(mesh, scene: Scene, extra: dict):
    """A placed mesh (and its ``extra`` per-triangle rows) as :meth:`Scene.validate` would leave it: unit corner
    normals, finite uvs, degenerate triangles dropped (with the scene's one warning)."""
    normals = None if mesh.normals is None else unit_normals(mesh.normals)
    uvs = None if mesh.uvs is None else np.ascontiguousarray(np.where(np.isinf(mesh.uvs), np.nan, mesh.uvs),
                                                             np.float32)
    lo, hi = scene.bounds
    if len(mesh.vertices):
        lo, hi = np.minimum(lo, mesh.vertices.min(axis=0)), np.maximum(hi, mesh.vertices.max(axis=0))
    keep = non_degenerate(mesh.vertices, mesh.triangles, float(np.linalg.norm(hi - lo)))
    mesh = mesh._replace(normals=normals, uvs=uvs)
    if not keep.all():
        warnings.warn(f"scene: skipped {int((~keep).sum())} degenerate (zero-area) triangle(s)", stacklevel=4)
        scene.skipped_triangles += int((~keep).sum())
        mesh = mesh._replace(triangles=mesh.triangles[keep], material_ids=mesh.material_ids[keep],
                             normals=None if normals is None else normals[keep], uvs=None if uvs is None else uvs[keep])
        extra = {k: _rows_of(v, keep) for k, v in extra.items()}
    return mesh, extra


def _object_mesh(s: Scene, rows):
    """World-space (vertices, triangles) of the given rows, renumbered to the vertices they use."""
    vidx, inverse = np.unique(s.triangles[rows], return_inverse=True)
    return s.vertices[vidx].astype(np.float64), inverse.reshape(-1, 3)


def _own_vertices(s: Scene, rows) -> np.ndarray:
    """Indices of the vertices of ``rows``; vertices that other rows use too are first copied for these rows
    (appended to ``s.vertices``, ``s.triangles[rows]`` renumbered), so moving them moves nothing else."""
    mine = np.zeros(len(s.triangles), bool)
    mine[rows] = True
    other = np.zeros(len(s.vertices), bool)
    other[s.triangles[~mine].ravel()] = True
    vidx = np.unique(s.triangles[rows])
    shared = vidx[other[vidx]]
    if len(shared):
        new = np.arange(len(s.vertices), len(s.vertices) + len(shared))
        lookup = np.arange(len(s.vertices) + len(shared))
        lookup[shared] = new
        s.vertices = np.concatenate([s.vertices, s.vertices[shared]])
        t = s.triangles.copy()
        t[rows] = lookup[t[rows]]
        s.triangles = t.astype(np.int32)
        vidx = np.unique(s.triangles[rows])
    return vidx


def _probe(scene: Scene, **fields) -> Scene:
    """``scene``'s shading fields with ``fields`` replaced, validated by :class:`Scene` itself on an empty mesh (so
    the rules stay in one place and no per-triangle work is redone)."""
    keep = dict(materials=scene.materials, camera=scene.camera, lights=scene.lights, textures=list(scene.textures),
                background=scene.background, ambient=scene.ambient, environment=scene.environment)
    keep.update(fields)
    return Scene(vertices=np.zeros((0, 3), np.float32), triangles=np.zeros((0, 3), np.int32), **keep)


def _matrix(m, what):
    a = np.asarray(m, dtype=np.float64)
    if a.shape != (4, 4) or not np.all(np.isfinite(a)):
        raise ValueError(f"{what}: the transform must be a finite 4x4 matrix")
    if singular(np.linalg.det(a[:3, :3]), np.abs(a[:3, :3]).max()):
        raise ValueError(f"{what}: the transform is singular (zero scale); remove the object instead")
    return a

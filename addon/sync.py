"""Blender's depsgraph -> edits of a long-lived :class:`tracer.Session` (the add-on's side of issue #12).

Cycles keeps one session per viewport (and, with Persistent Data, per final render) and syncs only what
``depsgraph.updates`` says changed; :class:`SceneSync` does the same for the tracer. It runs on Blender's main
thread (bpy data is not thread-safe) and turns an update into a list of :class:`Edit` s, plain data that
:func:`apply_edits` later applies to the session on whichever thread renders (the viewport's worker applies them
between two passes; an F12 applies them at once):

=====================================  =====================================================================
what changed                            edit (tracer.Session call)
=====================================  =====================================================================
the view only (orbit, zoom)             nothing here: the viewport hands the camera to its worker
a material, a texture image            ``update_materials`` (repack; no BVH work)
a light                                 ``update_lights``
the world                               ``update_world``
an object's transform                   ``set_transform`` (instance matrix + top-level commit; no mesh rebuild)
an object's geometry (edit mode,        ``update_mesh`` of every instance of that mesh (only their BVHs); all the
modifiers, geometry nodes)              instances of a shared mesh: one ``update_mesh`` of the prototype
an object added / deleted / hidden     ``add_object`` / ``remove_object``
the scene camera (F12)                  ``update_camera``
anything it cannot map                  one ``rebuild``: a fresh export and a new Session
=====================================  =====================================================================

How (Cycles' ``sync_recalc``): :func:`changes` reads ``depsgraph.updates`` into what must be read again —
the materials it names (all of them after a node group, image or texture update: any material may use those;
:data:`MATERIAL_TYPES`), the world (:data:`WORLD_TYPES`), and whether any object may have moved, changed,
appeared or gone (anything but a material-only or world-only update). Unchanged materials keep the Principled
fields read last time (no node tree is walked again). Only when objects may have changed are the depsgraph's
instances walked again, after dropping the cached triangle arrays of objects whose geometry changed
(:func:`addon.export.forget_geometry`), with that cache (:func:`addon.export.export_objects`: no mesh is read
twice, material rows and UVs once per mesh), and compared with the last export, object by object, by a key that
is stable across evaluations (object name, instancing parent, ``persistent_id``): the same triangle arrays with
another matrix is a transform, other arrays a mesh edit, a new key an added object, a missing key a removed one.
Materials, lights and world are compared by value before an edit is made.
"""

from __future__ import annotations

import dataclasses
import time
from typing import NamedTuple

import numpy as np

from . import export
from .export import tracer
from .volume import volume_of


class Edit(NamedTuple):
    """One session edit: ``kind`` in :data:`EDIT_KINDS`, ``args`` for it."""

    kind: str
    args: tuple


#: Edit kinds, in the order :func:`apply_edits` must apply one update's edits.
EDIT_KINDS = ("rebuild", "remove", "materials", "mesh", "add", "transform", "lights", "world", "camera")


class _KnownMaterials(export.MaterialWriter):
    """A material writer that takes the Principled fields of the materials in ``known`` (unchanged since they were
    last read) instead of reading their node trees again."""

    def __init__(self, builder, warnings: list, known: dict):
        super().__init__(builder, warnings)
        self.known = known

    def row(self, material) -> int:
        if material is not None and material.name in self.known and material.name not in self._rows:
            self._rows[material.name] = self._add(material.name, self.known[material.name])
            vol = volume_of(material, self.warn)  # a Volume output's medium (cheap: a few nodes)
            if vol is not None:
                self.volumes[self._rows[material.name]] = vol
        return super().row(material)


class _Entry(NamedTuple):
    object_id: int
    obj: "export.ExportedObject"
    #: The session holds object ``object_id`` at ``matrix_world @ offset`` (identity for objects placed with their
    #: matrix; the inverse of the export matrix for instances placed in a world-space batch, see add_objects).
    offset: np.ndarray


#: depsgraph.updates ID types after which every material is read again (a material names only itself; node
#: groups, images and textures may feed any material). A material's or world's own node tree is embedded data
#: and names nothing more than its owner.
MATERIAL_TYPES = {"ShaderNodeTree", "NodeTree", "Image", "Texture"}
#: ... after which the world is read again.
WORLD_TYPES = {"World", "Image"}
#: ... that leave every object as it was when each object update is shading-only (a material's or world's edit:
#: Blender tags the objects using a material for shading too).
SHADING_ONLY_TYPES = {"Material", "ShaderNodeTree", "NodeTree", "Image", "Texture", "World"}

#: ``Changes.materials`` when every material must be read again.
ALL = None


class Changes(NamedTuple):
    """What an update needs read again (:func:`changes`)."""

    #: Names of the materials to read again, or :data:`ALL`.
    materials: "set | None"
    world: bool
    #: Objects may have moved, changed, appeared, gone or been hidden: walk the depsgraph's instances.
    objects: bool
    images: bool


def changes(updates) -> Changes:
    """``depsgraph.updates`` -> :class:`Changes` (see the module docstring)."""
    materials: "set | None" = set()
    world = images = objects = False
    shading_objects = False
    for u in updates:
        id_ = getattr(u.id, "original", u.id)
        kind = type(id_).__name__
        if kind == "Material":
            if materials is not ALL:
                materials.add(id_.name)
        elif kind in MATERIAL_TYPES and not (kind.endswith("NodeTree") and getattr(id_, "is_embedded_data", False)):
            materials = ALL
        images |= kind == "Image"
        world |= kind in WORLD_TYPES or kind == "Scene"
        if kind in ("Object", "Mesh") and not (u.is_updated_transform or u.is_updated_geometry):
            shading_objects = True  # a material's users, or an object's own shading (pass index, colour)
        elif kind not in SHADING_ONLY_TYPES:
            objects = True
    # Objects tagged for shading alone without a material update changed themselves (pass index, ...).
    objects |= shading_objects and not (materials is ALL or materials)
    return Changes(materials, world, objects, images)


class SceneSync:
    """Keeps a session's scene equal to what :func:`addon.export.scene_from_depsgraph` would export now.

    ``quality`` is the Embree build quality of the sessions :func:`apply_edits` builds ("low" for the viewport:
    fastest to build and rebuild, "medium" for final renders). ``track_camera``: whether updates compare the scene
    camera and emit ``camera`` edits (F12); the viewport hands its view camera to its worker itself."""

    def __init__(self, *, quality: str = "medium", track_camera: bool = True):
        self.quality = quality
        self.track_camera = track_camera
        self._diffable = True
        self._depsgraph = None
        self.geometry_cache: dict = {}
        self.images: dict = {}  # image pixels read by the material writer, kept until an Image changes
        self._entries: dict[tuple, _Entry] = {}
        self._order: list[tuple] = []
        self._materials = None
        self._material_names: list[str] = []
        self._fields: dict = {}  # material name -> its Principled fields as last read
        self._textures: list = []
        self._lights: list = []
        self._world = None
        self._camera = None
        self._next_id = 0
        self.pass_indices = np.zeros(0, np.int32)
        self._members: dict[int, set] = {}
        self._prototype_of: dict[int, int] = {}
        self.warnings: list[str] = []
        #: The last update's timings: {"export": s, "edits": {kind: count}}.
        self.stats: dict = {}

    @property
    def synced(self) -> bool:
        return self._materials is not None

    def reset(self) -> None:
        """Forget everything: the next :meth:`update` exports the whole scene again (a rebuild)."""
        self.__init__(quality=self.quality, track_camera=self.track_camera)

    # ---------------------------------------------------------------------------------------------- export
    def full(self, depsgraph, *, width=None, height=None, camera=None, cancelled=None) -> list[Edit]:
        """Export the whole scene: ``[Edit("rebuild", (scene,))]``."""
        start = time.perf_counter()
        self.reset()
        objects: list = []
        scene, warnings = export.scene_from_depsgraph(depsgraph, width=width, height=height, camera=camera,
                                                      geometry_cache=self.geometry_cache, cancelled=cancelled,
                                                      objects=objects, materials=self._fields)
        placed = _placements(scene, objects)
        for oid, (o, offset) in enumerate(zip(objects, placed)):
            self._entries[o.key] = _Entry(oid, o, offset)
        self._order = [o.key for o in objects]
        self._diffable = len(self._entries) == len(objects)  # two instances under one key cannot be diffed
        self._next_id = len(scene.object_names)
        self._depsgraph = depsgraph.as_pointer()  # another depsgraph (file reloaded): export everything again
        self._materials, self._textures = scene.materials, list(scene.textures)
        self._material_names = list(scene.materials.names)
        self._volumes = scene.material_volumes
        self._lights = list(scene.lights)
        self._world = (scene.background, scene.ambient, scene.environment)
        self._camera = scene.camera
        self.pass_indices = np.asarray(scene.object_pass_indices, np.int32)
        self._members = {}  # prototype object id -> object ids of its instances
        self._prototype_of = {}  # instance object id -> its prototype
        if scene.instances is not None:
            for oid, proto in zip(scene.instances.object_ids.tolist(), scene.instances.prototypes.tolist()):
                self._members.setdefault(proto, set()).add(oid)
                self._prototype_of[oid] = proto
        self.warnings = list(warnings)
        self.stats = {"export": time.perf_counter() - start, "edits": {"rebuild": 1}}
        return [Edit("rebuild", (scene,))]

    def update(self, depsgraph, *, width=None, height=None, camera=None, cancelled=None) -> list[Edit]:
        """The edits that bring the session from the last export to ``depsgraph`` as it is now (see the module
        docstring). The first call (or after :meth:`reset`) is a :meth:`full` export. ``camera``: the camera to
        render with (None: the scene camera at width × height)."""
        if not self.synced or not self._diffable or depsgraph.as_pointer() != self._depsgraph:
            return self.full(depsgraph, width=width, height=height, camera=camera, cancelled=cancelled)
        start = time.perf_counter()
        updates = list(depsgraph.updates)
        what = changes(updates)
        if what.objects:
            changed = geometry_changes(updates)
            if changed:
                export.forget_geometry(self.geometry_cache, changed)
        if what.images:
            self.images.clear()
        bpy_scene = depsgraph.scene_eval if hasattr(depsgraph, "scene_eval") else depsgraph.scene
        warnings: list[str] = [] if what.objects else list(self.warnings)
        b = tracer.SceneBuilder()
        known = {} if what.materials is ALL else {k: v for k, v in self._fields.items() if k not in what.materials}
        writer = _KnownMaterials(b, warnings, known)
        writer.images = self.images
        self._keep_material_rows(writer, depsgraph)
        lights: list = []
        objects = list(export.export_objects(depsgraph, writer, warnings, lights,
                                             geometry_cache=self.geometry_cache, cancelled=cancelled)) \
            if what.objects else None
        edits: list[Edit] = []

        materials = tracer.Materials.from_list(b.materials)
        volumes = export.material_volumes(writer, len(materials.names))
        if not same(volumes, getattr(self, "_volumes", None)):  # a medium came, went or changed: export again
            return self.full(depsgraph, width=width, height=height, camera=camera, cancelled=cancelled)
        if not same(materials, self._materials) or not same(b.textures, self._textures):
            if len(materials) < len(self._materials):  # rows went away: the meshes' ids may not fit any more
                return self.full(depsgraph, width=width, height=height, camera=camera, cancelled=cancelled)
            edits.append(Edit("materials", (materials, list(b.textures))))
            self._materials, self._textures = materials, list(b.textures)
            self._material_names = list(materials.names)
        self._fields = {name: f for name, f in writer.fields.values()}
        if objects is not None and not same(lights, self._lights):
            edits.append(Edit("lights", (lights,)))
            self._lights = lights
        if what.world:
            world = export.world_from_blender(bpy_scene.world, warnings, writer.images)
            if not same(world, self._world):
                edits.append(Edit("world", world))
                self._world = world
        if self.track_camera:
            if camera is None:
                rw, rh = export.render_size(bpy_scene)
                camera = export.scene_camera(bpy_scene, width or rw, height or rh)
            if not same(camera, self._camera):
                edits.append(Edit("camera", (camera,)))
                self._camera = camera

        if objects is not None:
            diffed = self._diff_objects(objects)
            if diffed is None:  # two instances under one key: give up diffing
                return self.full(depsgraph, width=width, height=height, camera=camera, cancelled=cancelled)
            edits.extend(diffed)
        self.warnings = list(dict.fromkeys(warnings))
        edits.sort(key=lambda e: EDIT_KINDS.index(e.kind))
        counts: dict = {}
        for e in edits:
            counts[e.kind] = counts.get(e.kind, 0) + 1
        self.stats = {"export": time.perf_counter() - start, "edits": counts}
        return edits

    # ---------------------------------------------------------------------------------------------- internals
    def _diff_objects(self, objects) -> "list[Edit] | None":
        """Edits of the objects (add, mesh, transform, remove) from the last export to ``objects``; None where two
        instances share a key (no diff possible)."""
        edits: list[Edit] = []
        seen = set()
        reshaped = []  # (old entry, new object) whose mesh changed
        for o in objects:
            if o.key in seen:  # two instances under one key: no diff
                return None
            seen.add(o.key)
            old = self._entries.get(o.key)
            if old is None:
                oid = self._next_id
                self._next_id += 1
                edits.append(Edit("add", (oid, _mesh_kwargs(o, name=o.name))))
                self._entries[o.key] = _Entry(oid, o, np.eye(4))
                self._set_pass_index(oid, o.pass_index)
                continue
            same_mesh = (old.obj.geometry is o.geometry and _same_array(old.obj.material, o.material)
                         and _same_corners(old.obj.corners, o.corners))
            if not same_mesh:
                reshaped.append((old, o))
                self._entries[o.key] = _Entry(old.object_id, o, np.eye(4))
            elif not np.array_equal(old.obj.matrix, o.matrix):
                edits.append(Edit("transform", (old.object_id, o.matrix @ old.offset)))
                self._entries[o.key] = old._replace(obj=o)
            if old.obj.pass_index != o.pass_index:
                self._set_pass_index(old.object_id, o.pass_index)
        edits.extend(self._mesh_edits(reshaped))
        for key in [k for k in self._entries if k not in seen]:
            oid = self._entries.pop(key).object_id
            edits.append(Edit("remove", (oid,)))
            self._leave_prototype(oid)
        self._order = [o.key for o in objects]
        return edits

    def _mesh_edits(self, reshaped) -> list[Edit]:
        """``mesh`` edits for objects whose mesh changed. Where every instance of a shared mesh (a prototype) got
        the same new mesh (a Geometry-Nodes instance mesh edited), that is one edit of the prototype — its one
        BVH rebuilt, its instances follow — plus transform edits for those that moved too; any other changed
        object gets its own mesh (an instance then becomes an object of its own)."""
        edits = []
        by_proto: dict[int, list] = {}
        for old, o in reshaped:
            proto = self._prototype_of.get(old.object_id)
            if proto is not None:
                by_proto.setdefault(proto, []).append((old, o))
        done = set()
        for proto, pairs in by_proto.items():
            o0 = pairs[0][1]
            whole = {old.object_id for old, _ in pairs} == self._members[proto]
            shared = all(o.geometry is o0.geometry and o.material is o0.material and o.corners is o0.corners
                         for _, o in pairs)
            if not (whole and shared):
                continue
            kw = _mesh_kwargs(o0)
            del kw["transform"]  # a prototype's mesh is in object space
            edits.append(Edit("mesh", (proto, kw)))
            for old, o in pairs:
                if not np.array_equal(old.obj.matrix, o.matrix):
                    edits.append(Edit("transform", (old.object_id, o.matrix)))
                done.add(old.object_id)
        for old, o in reshaped:
            if old.object_id not in done:
                edits.append(Edit("mesh", (old.object_id, _mesh_kwargs(o))))
                self._leave_prototype(old.object_id)
        return edits

    def _leave_prototype(self, oid: int) -> None:
        proto = self._prototype_of.pop(oid, None)
        if proto is not None:
            self._members[proto].discard(oid)

    def _keep_material_rows(self, writer, depsgraph):
        """Read the materials of the last export first, in their row order, so an unchanged material keeps its
        row (and the meshes their material ids) while another one changes."""
        import bpy

        for name in self._material_names:
            mat = bpy.data.materials.get(name)
            if mat is not None:
                writer.row(mat.evaluated_get(depsgraph))

    def _set_pass_index(self, oid, value):
        if len(self.pass_indices) <= oid:
            self.pass_indices = np.concatenate([self.pass_indices, np.zeros(oid + 1 - len(self.pass_indices),
                                                                            np.int32)])
        self.pass_indices[oid] = value


#: Data-block types whose geometry updates concern only the objects using them (dropped from the cache by name).
GEOMETRY_DATA = {"Mesh", "Curve", "TextCurve", "SurfaceCurve", "MetaBall"}


def geometry_changes(updates) -> list:
    """The IDs of ``depsgraph.updates`` whose triangles may have changed: geometry objects and their data (lights,
    cameras and empties report geometry updates too: they have no triangles). Anything else with a geometry
    update (a geometry node group, ...) is passed on as well, and :func:`addon.export.forget_geometry` then drops
    the whole cache."""
    out = []
    for u in updates:
        if not u.is_updated_geometry:
            continue
        id_ = getattr(u.id, "original", u.id)
        kind = type(id_).__name__
        if kind == "Object":
            if id_.type in export.GEOMETRY_TYPES:
                out.append(id_)
        elif kind in GEOMETRY_DATA or kind.endswith("NodeTree") and getattr(id_, "bl_idname", "") == \
                "GeometryNodeTree":
            out.append(id_)
        elif kind not in ("Scene", "World", "Material", "Image", "Camera", "Collection") and \
                not kind.endswith(("Light", "NodeTree")):
            out.append(id_)
    return out


def _placements(scene, objects) -> list[np.ndarray]:
    """Per exported object, the offset such that the session's matrix = matrix_world @ offset: identity where the
    scene recorded the object's own matrix, the inverse of it where the object was placed in world space."""
    out = []
    rec = scene.object_transforms
    for oid, o in enumerate(objects):
        m = rec[oid] if rec is not None and oid < len(rec) else np.eye(4)
        out.append(np.eye(4) if np.array_equal(m, o.matrix) else np.linalg.inv(o.matrix) @ m)
    return out


def _mesh_kwargs(o, name=None) -> dict:
    g = o.geometry
    kw = dict(vertices=g["vertices"], triangles=g["triangles"], material=o.material, normals=g["normals"],
              transform=o.matrix, **o.corners.kwargs())
    if name is not None:
        kw["name"] = name
    return kw


def _same_corners(a, b) -> bool:
    """Two meshes' UV sets and vertex colours are equal (the same arrays, or equal ones)."""
    if a is b:
        return True
    return (a.uv_sets.keys() == b.uv_sets.keys() and all(_same_array(a.uv_sets[k], b.uv_sets[k]) for k in a.uv_sets)
            and _same_array(a.colors, b.colors))


def _same_array(a, b) -> bool:
    if a is b:
        return True
    if a is None or b is None:
        return False
    return np.array_equal(a, b)


def same(a, b) -> bool:
    """Deep equality of tracer data (dataclasses, arrays, lists, tuples, numbers): what decides whether an edit is
    needed."""
    if a is b:
        return True
    if type(a) is not type(b):
        return False
    if isinstance(a, np.ndarray):
        return a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a, b)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if dataclasses.is_dataclass(a):
        return all(same(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))
    if hasattr(a, "__dict__"):
        return same(vars(a), vars(b))
    return bool(a == b)


def apply_edits(session: "tracer.Session | None", edits: list[Edit], *, quality: str = "medium",
                instanced: bool = False, cancelled=None) -> "tracer.Session":
    """Apply ``edits`` (from :meth:`SceneSync.update`) to ``session``; returns the session to render (a new one
    after a rebuild, of Embree build ``quality`` and layout ``instanced``: see :class:`tracer.Session`; the old
    one is closed; ``cancelled`` is polled while it is built, True raises :class:`tracer.RenderCancelled`). Call
    it where no render of ``session`` is in flight."""
    for e in edits:
        if e.kind == "rebuild":
            if session is not None:
                session.close()
            session = tracer.Session(e.args[0], quality=quality, instanced=instanced, cancelled=cancelled)
            continue
        if session is None:
            raise RuntimeError("apply_edits: no session to edit (the first edit must be a rebuild)")
        if e.kind == "camera":
            session.update_camera(*e.args)
        elif e.kind == "materials":
            session.update_materials(*e.args)
        elif e.kind == "lights":
            session.update_lights(*e.args)
        elif e.kind == "world":
            background, ambient, environment = e.args
            session.update_world(background=background, ambient=ambient, environment=environment)
        elif e.kind == "transform":
            session.set_transform(*e.args)
        elif e.kind == "mesh":
            oid, kw = e.args
            session.update_mesh(oid, **kw)
        elif e.kind == "add":
            oid, kw = e.args
            got = session.add_object(**kw)
            if got != oid:
                raise RuntimeError(f"apply_edits: the session gave object id {got}, the sync expected {oid}")
        elif e.kind == "remove":
            session.remove_object(*e.args)
        else:
            raise ValueError(f"unknown edit {e.kind!r}")
    return session

"""Assemble a :class:`~tracer.scene.Scene` from meshes in object space, one call per object.

Both front ends use this: it applies object-to-world matrices (normals by the inverse transpose), concatenates
the flat arrays and keeps material and object tables. It is also the quickest way to build scenes by hand::

    b = SceneBuilder()
    red = b.add_material(name="red", diffuse=(0.8, 0.1, 0.1))
    b.add_mesh(vertices, triangles, material=red, name="ball")
    b.camera = Camera.look_at((0, 1, 5), (0, 0, 0))
    scene = b.build()
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .camera import Camera
from .heap import trim
from .jit import kernel
from .scene import Instances, Scene, handed_over, singular
from .shading.materials import Materials
from .shading.texture import as_texture


class SceneBuilder:
    def __init__(self):
        self._vertices: list[np.ndarray] = []
        self._triangles: list[np.ndarray] = []
        self._material_ids: list[np.ndarray] = []
        self._object_ids: list[np.ndarray] = []
        self._normals: list[np.ndarray | None] = []
        self._uvs: list[np.ndarray | None] = []
        self._extra: list[dict] = []  # per mesh: {"uv_sets": {index: (T, 3, 2)}, "colors": (T, 3, 3)}
        self._n_vertices = 0
        self.materials: list[dict] = []
        self._material_index: dict[str, int] = {}
        self.object_names: list[str] = []
        self.environment = None  # tracer.Environment or None
        self.lights: list = []
        self.textures: list = []  # tracer.Texture
        self.camera: Camera | None = None
        self.background = np.zeros(3, np.float32)
        self.ambient = np.zeros(3, np.float32)
        self.object_pass_indices = None  # optional per-object user pass indices (see Scene)
        self._transforms: dict[int, np.ndarray] = {}  # object id -> the object-to-world matrix it was placed with
        self._instances: list[tuple] = []  # (prototypes, transforms, object ids, material overrides) per call
        self._mesh_ids: set[int] = set()  # object ids that have triangles (what add_instances may place)

    # ---------------------------------------------------------------- tables
    def add_material(self, name: str | None = None, **fields) -> int:
        """Add a material row (fields of :data:`tracer.shading.materials.DEFAULT_MATERIAL`, or ``roughness``); returns
        its index. A name already added returns the existing index."""
        if name is not None and name in self._material_index:
            return self._material_index[name]
        index = len(self.materials)
        self.materials.append(dict(fields, name=name or f"material{index}"))
        if name is not None:
            self._material_index[name] = index
        return index

    def add_texture(self, texture) -> int:
        """Add a :class:`tracer.Texture` (or a bare (H, W, C) image, wrapped with the defaults); returns its index."""
        self.textures.append(as_texture(texture, f"texture {len(self.textures)}"))
        return len(self.textures) - 1

    def add_light(self, light) -> None:
        self.lights.append(light)

    # ---------------------------------------------------------------- geometry
    def add_mesh(self, vertices, triangles, material=0, name: str | None = None, transform=None,
                 normals=None, uvs=None, object_id: int | None = None, instances: int = 1,
                 uv_sets=None, colors=None) -> int:
        """Add a triangle mesh; returns its object id.

        vertices   (V, 3) object-space points
        triangles  (T, 3) vertex indices
        material   one material index, or (T,) per-triangle indices
        transform  optional 4×4 object-to-world matrix (column vectors: p_world = M @ p); a mirroring one
                   (negative determinant) has its triangles' winding turned back so front faces stay outside
        normals    optional shading normals: (V, 3) per vertex or (T, 3, 3) per corner
        uvs        optional texture coordinates: (V, 2) per vertex or (T, 3, 2) per corner
        object_id  reuse an id (several meshes of one object); by default a new one named ``name``
        instances  K > 1: the triangles are K equal consecutive blocks (copies of one mesh, e.g. a point
                   instancer's instances); each block is an object of its own, ids first..first+K−1 named
                   ``name[i]``; returns the first id (``object_id`` must then be None)
        uv_sets    optional {set index: (V, 2) per vertex or (T, 3, 2) per corner} (a list = indices 0, 1, ...);
                   set 0 is ``uvs``. Sets a mesh does not give are NaN (no coordinates) for its triangles
        colors     optional vertex colours: (V, 3|4) per vertex or (T, 3, 3|4) per corner (alpha dropped);
                   meshes without them read white
        """
        label = name or f"object{len(self.object_names)}"
        mesh = place_mesh(vertices, triangles, material, transform=transform, normals=normals, uvs=uvs, label=label,
                          vertex_normals=True)
        n_tri = len(mesh.triangles)
        instances = int(instances)
        if instances < 1 or n_tri % instances or (instances > 1 and object_id is not None):
            raise ValueError(f"mesh {label!r}: {n_tri} triangles cannot be {instances} instances of one mesh")
        if object_id is None and instances > 1:
            object_id = len(self.object_names)
            self.object_names.extend(f"{label}[{i}]" for i in range(instances))
        elif object_id is None:
            object_id = len(self.object_names)
            self.object_names.append(label)
        for i in range(object_id, object_id + instances):
            self._transforms[i] = mesh.transform
        if n_tri:
            self._mesh_ids.update(range(object_id, object_id + instances))
        self._vertices.append(mesh.vertices)
        self._triangles.append((mesh.triangles + self._n_vertices).astype(np.int32))
        self._n_vertices += len(mesh.vertices)
        self._material_ids.append(mesh.material_ids)
        self._object_ids.append(np.repeat(np.arange(object_id, object_id + instances, dtype=np.int32),
                                          n_tri // instances))
        self._normals.append(mesh.normals)
        self._uvs.append(mesh.uvs)
        a = mesh.transform[:3, :3]
        mirrored = bool(float(a[0] @ _cofactors(a)[0]) < 0)
        self._extra.append(_corner_extras(label, uv_sets, colors, mesh.uvs, len(mesh.vertices), mesh.triangles,
                                          mirrored, vertex_uvs=True))
        return object_id

    def add_instances(self, prototype: int, transforms, object_ids=None, names=None, materials=None) -> np.ndarray:
        """Place the mesh of object ``prototype`` (as :meth:`add_mesh` added it, with its transform if it had one)
        K times without copying it; returns the K instances' object ids.

        prototype   an object id from :meth:`add_mesh`; it becomes a *prototype*: drawn only through its
                    instances, never at its own place (see :class:`tracer.Instances`)
        transforms  (K, 4, 4) object-to-world matrices (column vectors), or one (4, 4)
        object_ids  optional (K,) ids to give the instances (e.g. ids reserved in ``object_names`` already);
                    by default K new ids, consecutive, named ``names[i]`` or ``"<prototype name>[i]"``
        materials   optional material override: one index or (K,) (-1: the prototype's own materials)

        Numpy throughout: 50 000 instances cost one array copy, not a Python loop per instance. Bad input raises
        ``ValueError`` naming the prototype."""
        prototype = int(prototype)
        label = self.object_names[prototype] if 0 <= prototype < len(self.object_names) else f"object{prototype}"
        if prototype not in self._mesh_ids:
            raise ValueError(f"add_instances: object {prototype} ({label!r}) has no mesh to instance")
        m = np.asarray(transforms, dtype=np.float64)
        if m.shape == (4, 4):
            m = m[None]
        if m.ndim != 3 or m.shape[1:] != (4, 4):
            raise ValueError(f"add_instances({label!r}): transforms must be (K, 4, 4), got {m.shape}")
        k = len(m)
        if object_ids is None:
            first = len(self.object_names)
            ids = np.arange(first, first + k, dtype=np.int32)
            if names is None:
                self.object_names.extend(f"{label}[{i}]" for i in range(k))
            else:
                names = list(names)
                if len(names) != k:
                    raise ValueError(f"add_instances({label!r}): {len(names)} names for {k} instances")
                self.object_names.extend(str(n) for n in names)
        else:
            ids = np.asarray(object_ids)
            if ids.shape != (k,) or (k and not np.issubdtype(ids.dtype, np.integer)):
                raise ValueError(f"add_instances({label!r}): object_ids must be {k} integers, got {ids.shape}")
            ids = ids.astype(np.int32)
            if k and ids.max() >= len(self.object_names):  # ids beyond the names so far: name them
                self.object_names.extend(f"object{i}" for i in range(len(self.object_names), int(ids.max()) + 1))
            if names is not None:
                for i, n in zip(ids.tolist(), names):
                    self.object_names[i] = str(n)
        mat = None
        if materials is not None:
            mat = np.broadcast_to(np.asarray(materials, np.int32), (k,)).copy()
        self._instances.append((np.full(k, prototype, np.int32), m, ids, mat))
        return ids

    @property
    def triangle_count(self) -> int:
        return sum(len(t) for t in self._triangles)

    def build(self) -> Scene:
        """The :class:`Scene` of everything added. The per-mesh pieces are joined into one array per field and
        freed as they are copied (the peak holds each field once plus the piece being copied); the builder keeps
        the joined arrays (as one mesh of everything), so a second build() copies nothing, and hands the shading
        arrays to the Scene, whose validation then normalises them in place instead of copying them."""
        if self.camera is None:
            raise ValueError("SceneBuilder.build: no camera set")
        n = self.triangle_count
        sizes = [len(t) for t in self._triangles]
        v_sizes = [len(v) for v in self._vertices]

        def cat(parts, tail, dtype):
            if not parts:
                return np.zeros((0,) + tail, dtype)
            out = (parts[0] if len(parts) == 1 else np.concatenate(parts)).astype(dtype, copy=False)
            parts[:] = [out]
            return out

        # Meshes without normals get zero normals: the integrator uses the geometric normal for those.
        normals = _joined_attribute(self._normals, self._triangles, sizes, v_sizes, 0.0)
        # Meshes without a UV set have no coordinates in it (NaN: textures read their fallback there).
        n_sets = max([1 if u is not None else 0 for u in self._uvs]
                     + [max(e["uv_sets"], default=-1) + 1 for e in self._extra], default=0)
        had_uvs = any(u is not None for u in self._uvs)
        self._uvs[:] = [None] * len(self._uvs)  # set 0 of the extras: the same arrays
        uv_parts = [[e["uv_sets"].pop(k, None) for e in self._extra] for k in range(n_sets)]
        per_vertex = all(p is None or p.ndim == 2 for parts in uv_parts for p in parts)  # one layout for all sets
        uv_sets = [_joined_attribute(parts, self._triangles, sizes, v_sizes, np.nan, per_vertex)
                   for parts in uv_parts]
        del uv_parts
        colors = _joined([e.pop("colors", None) for e in self._extra], sizes, 1.0)
        vertices = cat(self._vertices, (3,), np.float32)
        triangles = cat(self._triangles, (3,), np.int32)
        material_ids = cat(self._material_ids, (), np.int32) if n else np.zeros(0, np.int32)
        object_ids = cat(self._object_ids, (), np.int32) if n else np.zeros(0, np.int32)
        if sizes:  # from now on one mesh of everything
            self._normals[:] = [normals]
            self._uvs[:] = [uv_sets[0] if had_uvs and uv_sets else None]
            self._extra[:] = [{"uv_sets": {k: uv for k, uv in enumerate(uv_sets) if uv is not None},
                               "colors": colors}]
        trim()  # the per-mesh pieces just freed
        with handed_over(normals, colors, *uv_sets):
            return Scene(
                vertices=vertices,
                triangles=triangles,
                material_ids=material_ids,
                object_ids=object_ids,
                normals=normals,
                uv_sets=uv_sets,
                colors=colors,
                materials=Materials.from_list(self.materials),
                camera=self.camera,
                lights=list(self.lights),
                textures=list(self.textures),
                background=self.background,
                ambient=self.ambient,
                environment=self.environment,
                object_names=list(self.object_names),
                object_pass_indices=self.object_pass_indices,
                object_transforms=self._object_transforms(),
                instances=self._instance_table(),
            )

    def _instance_table(self) -> Instances | None:
        if not self._instances:
            return None
        parts = list(zip(*self._instances))
        mats = None
        if any(m is not None for m in parts[3]):
            mats = np.concatenate([m if m is not None else np.full(len(p), -1, np.int32)
                                   for p, m in zip(parts[0], parts[3])])
        return Instances(prototypes=np.concatenate(parts[0]), transforms=np.concatenate(parts[1]),
                         object_ids=np.concatenate(parts[2]), materials=mats)

    def _object_transforms(self):
        """(O, 4, 4) matrices the objects were placed with (identity where none; an instance's: its matrix), or
        None if all are identity."""
        if not self._instances and not any(not np.array_equal(m, np.eye(4)) for m in self._transforms.values()):
            return None
        out = np.tile(np.eye(4), (len(self.object_names), 1, 1))
        for i, m in self._transforms.items():
            if i < len(out):
                out[i] = m
        for _p, m, ids, _mat in self._instances:
            out[ids] = m
        return out


def _joined_attribute(parts: list, triangles: list, sizes: list, v_sizes: list, fill,
                      per_vertex: bool | None = None) -> np.ndarray | None:
    """The meshes' pieces of one shading attribute (normals, a UV set) as one array: per vertex (V, C) when every
    mesh that has it has it per vertex (``per_vertex``: decided by the caller for several attributes at once;
    ``fill`` for the vertices of meshes without), else per corner (T, 3, C), per-vertex pieces gathered through
    their mesh's triangles (``triangles[i]`` hold global vertex indices). Pieces are dropped once copied."""
    if per_vertex is None:
        per_vertex = all(p is None or p.ndim == 2 for p in parts)
    if per_vertex:
        return _joined(parts, v_sizes, fill)
    first = np.cumsum([0] + v_sizes[:-1])
    for i, p in enumerate(parts):
        if p is not None and p.ndim == 2:
            parts[i] = p[triangles[i] - first[i]]
    return _joined(parts, sizes, fill)


def vertex_values(corners: np.ndarray, triangles: np.ndarray, n_vertices: int) -> np.ndarray | None:
    """Per-corner values (T, n, C) of faces ``triangles`` (T, n) as per-vertex values (V, C) when every corner of
    each vertex holds the same value, bit for bit (a smooth mesh's normals, seamless UVs): corner k of face t is
    then ``out[triangles[t, k]]``; None where some vertex has two (a hard edge, a seam). Vertices no face uses
    get zeros."""
    c = np.ascontiguousarray(corners)
    bits = {4: np.uint32, 8: np.uint64}.get(c.dtype.itemsize)
    if bits is None or c.ndim != 3 or c.shape[:2] != np.shape(triangles):
        return None
    out = np.zeros((n_vertices, c.shape[2]), c.dtype)
    ok = _vertex_values(c.view(bits), np.ascontiguousarray(triangles), out.view(bits), np.zeros(n_vertices, np.bool_))
    return out if ok else None


@kernel
def _vertex_values(corners, triangles, out, seen):
    """out[v] = the value every corner of vertex v holds (compared as bits); False at the first disagreement."""
    for t in range(triangles.shape[0]):
        for k in range(triangles.shape[1]):
            x = triangles[t, k]
            if seen[x]:
                for c in range(corners.shape[2]):
                    if out[x, c] != corners[t, k, c]:
                        return False
            else:
                seen[x] = True
                for c in range(corners.shape[2]):
                    out[x, c] = corners[t, k, c]
    return True


def _joined(parts: list, sizes: list, fill) -> np.ndarray | None:
    """Per-mesh per-corner float32 arrays (None: ``fill`` for that mesh's ``sizes[i]`` rows) as one array, or None
    when no mesh has any. Each piece is dropped from ``parts`` once copied."""
    first = next((p for p in parts if p is not None), None)
    if first is None:
        return None
    out = np.empty((sum(sizes),) + first.shape[1:], np.float32)
    at = 0
    for i, size in enumerate(sizes):
        out[at:at + size] = fill if parts[i] is None else parts[i]
        parts[i] = None
        at += size
    return out


class PlacedMesh(NamedTuple):
    """One mesh placed in the world by :func:`place_mesh`: float32 world vertices, int32 triangles indexing them,
    per-triangle material ids, optional normals (per corner; per vertex (V, 3) where ``place_mesh(vertex_normals=True)``
    kept them so) and per-corner uvs, and the matrix it was placed with."""

    vertices: np.ndarray
    triangles: np.ndarray
    material_ids: np.ndarray
    normals: np.ndarray | None
    uvs: np.ndarray | None
    transform: np.ndarray


def place_mesh(vertices, triangles, material=0, *, transform=None, normals=None, uvs=None, label="mesh",
               n_materials: int | None = None, vertex_normals: bool = False) -> PlacedMesh:
    """An object-space mesh in world space (arguments as :meth:`SceneBuilder.add_mesh`): vertices by the 4×4
    ``transform``, normals by its inverse transpose, winding turned back under a mirroring transform. Raises
    ``ValueError`` naming ``label`` for bad input (``n_materials``: also check the material indices). The normals
    come out per corner (T, 3, 3), or with ``vertex_normals`` per vertex (V, 3) wherever that holds the same
    values (given per vertex, or per corner agreeing at every vertex: :func:`vertex_values`)."""
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if t.size and (t.min() < 0 or t.max() >= len(v)):
        raise ValueError(f"mesh {label!r}: triangle index out of range for {len(v)} vertices")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"mesh {label!r}: vertices must be finite")
    mirrored = False
    m = np.eye(4)
    if transform is not None:
        m = np.asarray(transform, dtype=np.float64)
        if m.shape != (4, 4) or not np.all(np.isfinite(m)):
            raise ValueError(f"mesh {label!r}: transform must be a finite 4x4 matrix")
        a = m[:3, :3]
        cof = _cofactors(a)
        det = float(a[0] @ cof[0])
        if singular(det, np.abs(a).max()):
            raise ValueError(f"mesh {label!r}: transform is singular (zero scale); skip the object instead")
        inv_t = cof / det  # inv(a).T
        world = np.empty((len(v), 3), np.float32)
        _affine_rows(np.ascontiguousarray(v), np.ascontiguousarray(a), np.ascontiguousarray(m[:3, 3]), world)
        v = world
        mirrored = det < 0
    n_tri = len(t)
    mat = np.asarray(material, dtype=np.int32)
    mat = np.full(n_tri, int(mat), np.int32) if mat.ndim == 0 else mat.reshape(-1).astype(np.int32)
    if mat.shape != (n_tri,):
        raise ValueError(f"mesh {label!r}: material must be one index or {n_tri} per-triangle indices")
    if n_materials is not None and n_tri and (mat.min() < 0 or mat.max() >= n_materials):
        raise ValueError(f"mesh {label!r}: material index outside the {n_materials} materials")

    corner_normals = None
    if normals is not None:
        nr = np.asarray(normals)
        if nr.dtype != np.float32:
            nr = nr.astype(np.float64, copy=False)
        if vertex_normals and nr.shape == (n_tri, 3, 3) and n_tri:
            per_vertex = vertex_values(nr, t, len(v))  # None: a hard edge, they stay per corner
            nr = nr if per_vertex is None else per_vertex
        if nr.shape == (len(v), 3) and not vertex_normals:
            nr = nr[t]
        if nr.shape != (n_tri, 3, 3) and nr.shape != (len(v), 3):
            raise ValueError(f"mesh {label!r}: normals must be per vertex ({len(v)}, 3) "
                             f"or per corner ({n_tri}, 3, 3), got {nr.shape}")
        if transform is not None:  # by the inverse transpose, in float64, stored as float32
            corner_normals = np.empty(nr.shape, np.float32)
            _linear_rows(np.ascontiguousarray(nr, np.float64).reshape(-1, 3), inv_t, corner_normals.reshape(-1, 3))
        else:
            corner_normals = nr.astype(np.float32)
    corner_uvs = None
    if uvs is not None:
        uv = np.asarray(uvs)
        if uv.dtype != np.float32:  # float32 as it is (a float64 round trip changes nothing)
            uv = uv.astype(np.float64, copy=False)
        if uv.shape == (len(v), 2):
            uv = uv[t]
        if uv.shape != (n_tri, 3, 2):
            raise ValueError(f"mesh {label!r}: uvs must be per vertex ({len(v)}, 2) "
                             f"or per corner ({n_tri}, 3, 2), got {uv.shape}")
        corner_uvs = uv.astype(np.float32)

    if mirrored:
        # A mirroring transform turns the winding around: swap two corners so front faces stay outside
        # (the integrator tells entering from leaving glass by the winding).
        t = t[:, [0, 2, 1]]
        if corner_normals is not None and corner_normals.ndim == 3:  # per vertex: they follow their vertices
            corner_normals = corner_normals[:, [0, 2, 1]]
        corner_uvs = None if corner_uvs is None else corner_uvs[:, [0, 2, 1]]
    return PlacedMesh(np.ascontiguousarray(v, np.float32), np.ascontiguousarray(t, np.int32), mat,
                      corner_normals, corner_uvs, m)


def _cofactors(a: np.ndarray) -> np.ndarray:
    """The cofactor matrix of a 3×3 matrix (rows: cross products of the other two rows), in plain floats: numpy's
    cross, det and inv go through moveaxis or LAPACK (OpenBLAS's threads: 80 µs a call idle, milliseconds on a
    busy machine), once per mesh."""
    (a0, a1, a2), (b0, b1, b2), (c0, c1, c2) = a.tolist()
    return np.array([[b1 * c2 - b2 * c1, b2 * c0 - b0 * c2, b0 * c1 - b1 * c0],
                     [c1 * a2 - c2 * a1, c2 * a0 - c0 * a2, c0 * a1 - c1 * a0],
                     [a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0]])


@kernel
def _affine_rows(src, a, b, out):
    """out[i] = a @ src[i] + b (float64 arithmetic, float32 result): a mesh's points into the world."""
    for i in range(len(src)):
        x, y, z = src[i, 0], src[i, 1], src[i, 2]
        for k in range(3):
            out[i, k] = a[k, 0] * x + a[k, 1] * y + a[k, 2] * z + b[k]


@kernel
def _linear_rows(src, a, out):
    """out[i] = a @ src[i] (float64 arithmetic, float32 result): normals by the inverse transpose."""
    for i in range(len(src)):
        x, y, z = src[i, 0], src[i, 1], src[i, 2]
        for k in range(3):
            out[i, k] = a[k, 0] * x + a[k, 1] * y + a[k, 2] * z


def _corner_extras(label, uv_sets, colors, corner_uvs, n_vertices, t, mirrored, vertex_uvs=False) -> dict:
    """A mesh's UV sets and vertex colours per corner (checked, winding-corrected like its normals and uvs: ``t``
    is already in its final winding, per-corner input is not). ``vertex_uvs``: each UV set per vertex (V, 2)
    instead where every corner of a vertex holds the same coordinates (:func:`vertex_values`)."""
    n_tri = len(t)

    def per_corner(a, width, what):
        a = np.asarray(a, dtype=np.float64)
        if a.ndim == 2 and a.shape[0] == n_vertices and a.shape[1] in width:
            return a[t][..., :width[0]].astype(np.float32)
        if a.shape[:2] != (n_tri, 3) or a.ndim != 3 or a.shape[2] not in width:
            raise ValueError(f"mesh {label!r}: {what} must be per vertex ({n_vertices}, {width[0]}) or per corner "
                             f"({n_tri}, 3, {width[0]}), got {a.shape}")
        a = a[..., :width[0]].astype(np.float32)
        return a[:, [0, 2, 1]] if mirrored else a

    sets = {}
    if uv_sets is not None:
        items = uv_sets.items() if isinstance(uv_sets, dict) else enumerate(uv_sets)
        for k, uv in items:
            if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 0:
                raise ValueError(f"mesh {label!r}: UV set indices must be integers >= 0, got {k!r}")
            if uv is not None:
                sets[int(k)] = per_corner(uv, (2,), f"uv_sets[{k}]")
    if corner_uvs is not None:
        if 0 in sets and not np.allclose(sets[0], corner_uvs, equal_nan=True):
            raise ValueError(f"mesh {label!r}: uvs and uv_sets[0] differ (uvs is UV set 0; give one of them)")
        sets[0] = corner_uvs
    if vertex_uvs and n_tri:
        for k, a in sets.items():
            pv = vertex_values(a, t, n_vertices)
            sets[k] = a if pv is None else pv
    col = per_corner(colors, (3, 4), "colors") if colors is not None else None
    return {"uv_sets": sets, "colors": col}

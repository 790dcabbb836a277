"""The render-ready scene: world-space flat arrays, a material table, lights, a camera and the world colours.

Front ends (``usd_io``, ``addon``) fill one of these; the tracer never learns where a scene came from.
Build one directly or with :class:`tracer.builder.SceneBuilder`.
"""

from __future__ import annotations

import contextlib
import contextvars
import warnings
from dataclasses import dataclass, field

import numpy as np

from . import scene_kernels
from .camera import Camera
from .geometry.motion import Motion
from .lights.emitters import AreaLight, DistantLight, PointLight, SpotLight
from .lights.environment import Environment
from .shading.materials import Materials
from .shading.texture import as_texture

#: Triangles whose area is at most this fraction of the squared bounding-box diagonal are degenerate and skipped.
DEGENERATE_AREA = 1e-14

#: The Scene fields that hold one row per triangle (row i belongs to ``triangles[i]``; list-valued ones are lists
#: of such arrays), with the value a row without such data gets. tracer.Session's mesh edits keep every one of
#: these in step with the triangles; a new per-triangle field belongs here.
#: Per-triangle fields and the value rows without data get (UV sets: NaN = no coordinates). ``uvs`` is not listed:
#: it is ``uv_sets[0]``. ``normals`` and ``uv_sets`` are per triangle in their per-corner layout; code that edits
#: rows first turns per-vertex ones into that (``Scene.to_corner_layout``).
PER_TRIANGLE = {"material_ids": 0, "object_ids": 0, "normals": 0.0, "uv_sets": np.nan, "colors": 1.0}


#: ids of arrays a caller handed over to the Scene being built (see :func:`handed_over`).
_HANDED_OVER: contextvars.ContextVar[frozenset] = contextvars.ContextVar("handed_over", default=frozenset())


@contextlib.contextmanager
def handed_over(*arrays):
    """Scenes validated inside this block may fix these arrays (float32, contiguous) in place rather than copy
    them: the caller (SceneBuilder.build) made them for the scene and keeps no other use for them."""
    token = _HANDED_OVER.set(frozenset(id(a) for a in arrays if a is not None))
    try:
        yield
    finally:
        _HANDED_OVER.reset(token)


def _own(a) -> bool:
    return (id(a) in _HANDED_OVER.get() and isinstance(a, np.ndarray) and a.dtype == np.float32
            and a.flags.c_contiguous and a.flags.writeable)


def unit_normals(normals: np.ndarray) -> np.ndarray:
    """Per-corner shading normals scaled to unit length (float32); unusable ones (zero, NaN) become zeros, which
    the renderer replaces by the face normal. A numba pass on every core (tracer.scene_kernels)."""
    return scene_kernels.unit_normals(normals)


def singular(det, size):
    """The one invertibility rule of placement matrices (scene instances, SceneBuilder.add_mesh, Session edits, the
    add-on's export): a 3×3 linear part is singular (zero scale) when its determinant is not finite or
    |det| <= 1e-12·size³, ``size`` its scale (largest |entry| or longest axis: the bound is relative). Scalars
    give a bool, arrays a bool array."""
    if np.ndim(det) == 0 and np.ndim(size) == 0:  # one matrix (the add-on's export calls this per instance)
        return not (abs(det) > 1e-12 * max(float(size), 1e-300) ** 3)  # NaN compares False: singular
    return ~(np.abs(det) > 1e-12 * np.maximum(size, 1e-300) ** 3)


def non_degenerate(vertices: np.ndarray, triangles: np.ndarray, diagonal: float) -> np.ndarray:
    """Mask of the triangles whose area is more than DEGENERATE_AREA × diagonal² (the others are skipped): twice
    the area in float64 from the float32 points, a numba pass on every core."""
    return scene_kernels.non_degenerate(vertices, triangles, DEGENERATE_AREA * max(diagonal**2, 1e-30))


@dataclass
class Instances:
    """Placements of shared object-space meshes: K instances, each drawing the triangles of one *prototype*.

    prototypes  (K,) int32: the object id whose triangles instance k draws. An object id named here is a
                prototype: its rows of ``Scene.triangles`` are in **object space** and are drawn only through its
                instances (never at their own place; add an instance with its matrix for that)
    transforms  (K, 4, 4) float64 object-to-world matrices (column vectors: p_world = M @ p), finite and
                invertible; a mirroring one (det < 0) is fine: the outside stays outside (as ``add_mesh``)
    object_ids  (K,) int32: each instance's own object id (AOV ``objectid``, ``Scene.object_names``, pass
                indices); must not be a prototype's id
    materials   optional (K,) int32 material override (-1: the prototype's own per-triangle materials)

    ``len(instances)`` is K. Build them with :meth:`tracer.SceneBuilder.add_instances`.
    """

    prototypes: np.ndarray
    transforms: np.ndarray
    object_ids: np.ndarray
    materials: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.prototypes)

    def material_overrides(self) -> np.ndarray:
        """(K,) int32 overrides, -1 where the prototype's own materials apply."""
        return self.materials if self.materials is not None else np.full(len(self), -1, np.int32)

    def validate(self, n_materials: int) -> None:
        p = np.asarray(self.prototypes)
        if p.ndim != 1 or (p.size and not np.issubdtype(p.dtype, np.integer)):
            raise ValueError(f"scene.instances.prototypes must be a 1-D integer array, got shape {p.shape}")
        k = len(p)
        if k and p.min() < 0:
            raise ValueError(f"scene.instances.prototypes: instance {int(np.argmin(p))} names object {int(p.min())}")
        self.prototypes = np.ascontiguousarray(p, np.int32)
        m = np.asarray(self.transforms, dtype=np.float64)
        if m.shape != (k, 4, 4):
            raise ValueError(f"scene.instances.transforms must have shape ({k}, 4, 4), got {m.shape}")
        finite = np.isfinite(m).all(axis=(1, 2))
        if not finite.all():
            raise ValueError(f"scene.instances.transforms: instance {int(np.argmin(finite))} has a NaN or "
                             "infinite entry")
        lin = m[:, :3, :3]
        bad = singular(np.linalg.det(lin), np.abs(lin).max(axis=(1, 2))) if k else np.zeros(0, bool)
        if bad.any():
            raise ValueError(f"scene.instances.transforms: instance {int(np.argmax(bad))} is singular "
                             "(zero scale); leave it out instead")
        self.transforms = np.ascontiguousarray(m)
        ids = np.asarray(self.object_ids)
        if ids.shape != (k,) or (ids.size and not np.issubdtype(ids.dtype, np.integer)):
            raise ValueError(f"scene.instances.object_ids must be {k} integers, got shape {ids.shape}")
        if k and ids.min() < 0:
            raise ValueError(f"scene.instances.object_ids: instance {int(np.argmin(ids))} has a negative id")
        self.object_ids = np.ascontiguousarray(ids, np.int32)
        clash = np.isin(self.object_ids, self.prototypes)
        if clash.any():
            raise ValueError(f"scene.instances: instance {int(np.argmax(clash))} has object id "
                             f"{int(self.object_ids[clash][0])}, which is a prototype's")
        if self.materials is not None:
            mt = np.asarray(self.materials)
            if mt.shape != (k,) or (mt.size and not np.issubdtype(mt.dtype, np.integer)):
                raise ValueError(f"scene.instances.materials must be {k} integers, got shape {mt.shape}")
            bad = (mt < -1) | (mt >= n_materials)
            if bad.any():
                i = int(np.argmax(bad))
                raise ValueError(f"scene.instances.materials: instance {i} uses material {int(mt[i])}, but there "
                                 f"are {n_materials} materials")
            self.materials = np.ascontiguousarray(mt, np.int32)


def instance_bounds(transforms: np.ndarray, points: np.ndarray, chunk: int = 2048) -> np.ndarray:
    """(2, 3) exact bounds of ``points`` (P, 3) placed by every matrix of ``transforms`` (K, 4, 4): per axis the
    support function max_p (row · p) + t, batched (no (K, P, 3) array, no loop over instances)."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    pts = np.asarray(points, np.float64)
    if not len(pts) or not len(transforms):
        return np.stack([lo, hi])
    for c in range(0, len(transforms), chunk):
        m = transforms[c:c + chunk]
        proj = m[:, :3, :3] @ pts.T  # (k, 3, P)
        lo = np.minimum(lo, (proj.min(axis=2) + m[:, :3, 3]).min(axis=0))
        hi = np.maximum(hi, (proj.max(axis=2) + m[:, :3, 3]).max(axis=0))
    return np.stack([lo, hi])


@dataclass
class Scene:
    """World-space geometry and everything needed to shade it.

    vertices      (V, 3) float32
    triangles     (T, 3) int32, indices into ``vertices`` (counter-clockwise = front, right-handed)
    material_ids  (T,) int32, rows of ``materials``
    object_ids    (T,) int32, user-facing object index (AOV "objectid"); names in ``object_names``
    normals       optional float32 shading normals, per vertex (V, 3): corner k of triangle t reads
                  ``normals[triangles[t, k]]`` (6 bytes per triangle on a closed mesh), or per corner (T, 3, 3)
                  where some vertex has different normals on different faces (hard edges). SceneBuilder stores them
                  per vertex whenever every mesh's corners agree per vertex; :meth:`corner_normals` gives the
                  per-corner array either way. Zero = unusable (the face normal is used)
    uvs           optional float32 texture coordinates of UV set 0: per vertex (V, 2) or per corner (T, 3, 2)
    uv_sets       list of texture coordinates, all per vertex (V, 2) or all per corner (T, 3, 2) (as ``normals``;
                  a mix is gathered per corner); set 0 is ``uvs``. NaN = no coordinates in the set (a texture
                  reading it gives its fallback). :meth:`corner_uvs` gives a set per corner either way
    colors        optional (T, 3, 3) float32 per-corner vertex colours (linear RGB), read by materials with
                  ``vertex_color``
    textures      list of :class:`tracer.Texture` (a bare (H, W, C) array is wrapped with the defaults), referenced
                  by the materials' ``*_texture`` columns
    background    colour of rays that hit nothing
    ambient       L_a of the seed (the world's colour × strength): ambient term L_a·R_a
    object_names  name per object id; object_pass_indices optionally maps object ids to user pass indices
    instances     optional :class:`Instances`: placements of prototypes (objects whose triangles are in object
                  space and drawn only through instances); None = every triangle is in world space
    """

    vertices: np.ndarray
    triangles: np.ndarray
    materials: Materials
    camera: Camera
    lights: list = field(default_factory=list)
    material_ids: np.ndarray | None = None
    object_ids: np.ndarray | None = None
    normals: np.ndarray | None = None
    uvs: np.ndarray | None = None
    textures: list = field(default_factory=list)
    uv_sets: list = field(default_factory=list)
    colors: np.ndarray | None = None
    background: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))
    ambient: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))
    object_names: list = field(default_factory=list)
    #: Optional (O,) int32 per object id: a user-facing pass index (Blender's Object.pass_index); None = the id itself.
    object_pass_indices: np.ndarray | None = None
    skipped_triangles: int = 0
    #: Optional lat-long world (tracer.Environment): seen by rays that leave the scene instead of ``background``,
    #: and a light (sky samples, or the ambient term with L_a = its mean radiance when ``ambient`` is zero).
    environment: Environment | None = None
    #: Optional (O, 4, 4) float64 per object id: the object-to-world matrix its vertices were placed with
    #: (SceneBuilder.add_mesh's transform; None = identity for all). The vertices are already in world space;
    #: tracer.Session.set_transform moves an object from this matrix to a new one.
    object_transforms: np.ndarray | None = None
    #: Optional shared-mesh instances (see :class:`Instances`); None: a triangle soup in world space.
    instances: Instances | None = None
    #: Optional :class:`tracer.geometry.motion.Motion`: what moves across the shutter (motion blur); None: nothing moves.
    motion: object | None = None
    #: Optional (O,) uint8 per object id: the ray types that see it (tracer.lights.linking: CAMERA | GLOSSY |
    #: TRANSMISSION | SHADOW); None = every object seen by every ray.
    object_visibility: np.ndarray | None = None
    #: One tracer.lights.linking.LightLink per light of ``lights`` (receivers, blockers, cast shadow, diffuse / glossy),
    #: or empty: no light is linked.
    light_links: list = field(default_factory=list)
    #: {object id: tracer.lights.linking.LightLink} for light-linked emitting objects (receivers, blockers): each becomes a
    #: MESH light of its own (tracer.lights.emitters.pack_lights); empty: every emitting triangle is one light.
    emitter_links: dict = field(default_factory=dict)
    #: Optional (O,) bool per object id: the object is a holdout (Cycles' object / collection holdout): where the
    #: eye path meets it, the pixel is cut out (alpha reduced, colour zero; tracer.integrator.compose). Ids past the end: False.
    object_holdout: np.ndarray | None = None
    #: Optional (O,) bool per object id: the object is a shadow catcher (Blender's ``is_shadow_catcher``): invisible
    #: in the beauty except for the shadows other objects cast on it (tracer.integrator.compose). Ids past the end: False.
    object_shadow_catcher: np.ndarray | None = None
    #: Optional (M, 6) float32 per material: a homogeneous medium inside the objects that wear it, (σ RGB, E RGB):
    #: extinction per unit length and emitted radiance per unit length. A ray that leaves such an object through a
    #: back face after travelling t inside is attenuated by exp(−σ·t) and gains E/σ·(1 − exp(−σ·t)) (E·t where σ =
    #: 0): Beer–Lambert with emission (a Blender material's Volume output; tracer.integrator). None: no media.
    material_volumes: np.ndarray | None = None
    #: Optional (M,) bool per material: its medium (``material_volumes``) is carried by the rays, as Cycles' volume
    #: stack carries it (an inside-out closed mesh's: Blender files): a ray enters it where it crosses a front face
    #: of the material's surface (against the face's winding normal), leaves it where it crosses a back face, keeps
    #: it through reflections and other surfaces, and is attenuated (and gains its emission) over every segment it
    #: travels in it that ends at a hit; its shadow rays are attenuated too. None / False: the back-face rule above.
    material_volume_carried: np.ndarray | None = None

    def __post_init__(self):
        self.validate()

    # ------------------------------------------------------------------ validation
    def validate(self) -> None:
        """Check shapes and values; raise ``ValueError`` naming what is wrong. Drops degenerate triangles.

        A scene is treated as immutable once validated (derived data such as the bounds is cached); call this
        again after changing its arrays."""
        self._bounds = None
        v = np.asarray(self.vertices)
        if v.ndim != 2 or v.shape[1] != 3:
            raise ValueError(f"scene.vertices must have shape (V, 3), got {v.shape}")
        if not np.all(np.isfinite(v)):
            bad = int(np.flatnonzero(~np.isfinite(v).all(axis=1))[0])
            raise ValueError(f"scene.vertices: vertex {bad} has a NaN or infinite coordinate {v[bad].tolist()}")
        self.vertices = np.ascontiguousarray(v, dtype=np.float32)

        t = np.asarray(self.triangles)
        if t.size == 0:
            t = t.reshape(0, 3)
        if t.ndim != 2 or t.shape[1] != 3:
            raise ValueError(f"scene.triangles must have shape (T, 3), got {t.shape}")
        if not np.issubdtype(t.dtype, np.integer):
            raise ValueError(f"scene.triangles must hold integer indices, got {t.dtype}")
        if t.size and (t.min() < 0 or t.max() >= len(self.vertices)):
            bad = int(np.flatnonzero((t < 0).any(axis=1) | (t >= len(self.vertices)).any(axis=1))[0])
            raise ValueError(f"scene.triangles: triangle {bad} has index {t[bad].tolist()} outside "
                             f"the {len(self.vertices)} vertices")
        self.triangles = np.ascontiguousarray(t, dtype=np.int32)
        n = len(self.triangles)

        if not isinstance(self.materials, Materials):
            raise ValueError("scene.materials must be a tracer.Materials table")
        self.materials.validate(len(self.textures))
        self.material_ids = self._per_triangle(self.material_ids, "material_ids", n)
        if n and (self.material_ids.min() < 0 or self.material_ids.max() >= len(self.materials)):
            bad = int(np.flatnonzero((self.material_ids < 0) | (self.material_ids >= len(self.materials)))[0])
            raise ValueError(f"scene.material_ids: triangle {bad} uses material {int(self.material_ids[bad])}, "
                             f"but there are {len(self.materials)} materials")
        self.object_ids = self._per_triangle(self.object_ids, "object_ids", n)

        if self.normals is not None:
            nr = np.asarray(self.normals, dtype=np.float32)
            if nr.shape != (n, 3, 3) and nr.shape != (len(self.vertices), 3):
                raise ValueError(f"scene.normals must have shape ({len(self.vertices)}, 3) (per vertex) or "
                                 f"({n}, 3, 3) (per corner), got {nr.shape}")
            self.normals = scene_kernels.unit_normals(nr, in_place=_own(self.normals))
        self._validate_uv_sets(n)
        if self.colors is not None:
            col = np.asarray(self.colors, dtype=np.float32)
            if col.ndim == 3 and col.shape[:2] == (n, 3) and col.shape[2] == 4:
                col = col[..., :3]
            if col.shape != (n, 3, 3):
                raise ValueError(f"scene.colors must have shape ({n}, 3, 3) (per-corner RGB), got {col.shape}")
            self.colors = np.ascontiguousarray(np.nan_to_num(col, nan=1.0, posinf=0.0, neginf=0.0))

        for i, tex in enumerate(self.textures):
            self.textures[i] = as_texture(tex, f"scene.textures[{i}]")

        for name in ("background", "ambient"):
            c = np.asarray(getattr(self, name), dtype=np.float32).reshape(-1)
            if c.shape != (3,) or not np.all(np.isfinite(c)):
                raise ValueError(f"scene.{name} must be 3 finite numbers, got {getattr(self, name)!r}")
            setattr(self, name, c)

        if self.environment is not None and not isinstance(self.environment, Environment):
            raise ValueError("scene.environment must be a tracer.Environment or None")
        if not isinstance(self.camera, Camera):
            raise ValueError("scene.camera must be a tracer.Camera")
        for light in self.lights:
            if not isinstance(light, (PointLight, SpotLight, DistantLight, AreaLight)):
                raise ValueError(f"scene.lights: {light!r} is not a tracer light")

        if self.object_pass_indices is not None:
            pi = np.asarray(self.object_pass_indices)
            if pi.ndim != 1 or (pi.size and not np.issubdtype(pi.dtype, np.integer)):
                raise ValueError(f"scene.object_pass_indices must be a 1-D integer array, got shape {pi.shape}")
            if len(self.object_ids) and self.object_ids.max() >= len(pi):
                raise ValueError(f"scene.object_pass_indices has {len(pi)} entries but object id "
                                 f"{int(self.object_ids.max())} is used")
            self.object_pass_indices = np.ascontiguousarray(pi, dtype=np.int32)

        if self.object_transforms is not None:
            ot = np.asarray(self.object_transforms, dtype=np.float64)
            if ot.ndim != 3 or ot.shape[1:] != (4, 4) or not np.all(np.isfinite(ot)):
                raise ValueError(f"scene.object_transforms must be finite (O, 4, 4) matrices, got shape {ot.shape}")
            self.object_transforms = ot

        for name in ("object_holdout", "object_shadow_catcher"):
            flags = getattr(self, name)
            if flags is not None:
                fl = np.asarray(flags)
                if fl.ndim != 1:
                    raise ValueError(f"scene.{name} must be a 1-D array of flags per object id, got shape {fl.shape}")
                setattr(self, name, np.ascontiguousarray(fl != 0, dtype=np.bool_))

        if self.instances is not None:
            if not isinstance(self.instances, Instances):
                raise ValueError("scene.instances must be a tracer.Instances table or None")
            self.instances.validate(len(self.materials))
            has = np.zeros(max(int(self.object_ids.max()) + 1 if n else 0,
                               int(self.instances.prototypes.max()) + 1 if len(self.instances) else 0), bool)
            has[self.object_ids] = True
            missing = ~has[self.instances.prototypes]
            if missing.any():
                raise ValueError(f"scene.instances: instance {int(np.argmax(missing))} places object "
                                 f"{int(self.instances.prototypes[missing][0])}, which has no triangles")
            if self.object_pass_indices is not None and len(self.instances) and \
                    self.instances.object_ids.max() >= len(self.object_pass_indices):
                raise ValueError(f"scene.object_pass_indices has {len(self.object_pass_indices)} entries but "
                                 f"instance object id {int(self.instances.object_ids.max())} is used")
            if not len(self.instances):
                self.instances = None

        self.validate_motion()
        self._drop_degenerate()

    def validate_motion(self) -> None:
        """Check ``motion`` against the vertices and instances (a front end that sets it after building the
        scene calls this); an empty one becomes None."""
        if self.motion is None:
            return
        if not isinstance(self.motion, Motion):
            raise ValueError("scene.motion must be a tracer.geometry.motion.Motion or None")
        self.motion.validate(len(self.vertices), len(self.instances) if self.instances is not None else 0)
        if self.motion.empty:
            self.motion = None

    def _validate_uv_sets(self, n):
        """``uv_sets`` and ``uvs`` are one list (set 0 = ``uvs``): fill one from the other, check shapes. Infinite
        coordinates become NaN (no coordinates)."""
        sets = list(self.uv_sets or [])
        seen = getattr(self, "_uvs_validated", None)  # set 0 as the last validation left it
        if self.uvs is not None:
            if not sets:
                sets = [self.uvs]
            elif seen is not None and sets[0] is seen and self.uvs is not seen:
                sets[0] = self.uvs  # uvs was replaced after validation: it is set 0
            elif (sets[0] is not self.uvs and (seen is None or self.uvs is not seen)
                  and not np.array_equal(np.asarray(sets[0]), np.asarray(self.uvs), equal_nan=True)):
                raise ValueError("scene.uvs and scene.uv_sets[0] differ; uvs is UV set 0 (give one of them)")
        elif seen is not None and sets and sets[0] is seen:
            sets = []  # uvs was set to None after validation: no UV sets
        n_v = len(self.vertices)
        for i, uv in enumerate(sets):
            a = np.asarray(uv, dtype=np.float32)
            if a.shape != (n, 3, 2) and a.shape != (n_v, 2):
                raise ValueError(f"scene.uv_sets[{i}] must have shape ({n_v}, 2) (per vertex) or ({n}, 3, 2) "
                                 f"(per corner), got {a.shape}")
            sets[i] = scene_kernels.inf_to_nan(a, in_place=_own(uv))
        if len({a.ndim for a in sets}) > 1:  # one layout for all sets: a mix goes per corner
            sets = [a[self.triangles] if a.ndim == 2 else a for a in sets]
        self.uv_sets = sets
        self.uvs = sets[0] if sets else None
        self._uvs_validated = self.uvs

    @staticmethod
    def _per_triangle(a, name, n):
        if a is None:
            return np.zeros(n, np.int32)
        a = np.asarray(a)
        if a.shape != (n,) or (a.size and not np.issubdtype(a.dtype, np.integer)):
            raise ValueError(f"scene.{name} must be {n} integers (one per triangle), got shape {a.shape}")
        return np.ascontiguousarray(a, dtype=np.int32)

    def _drop_degenerate(self):
        if not len(self.triangles):
            return
        keep = non_degenerate(self.vertices, self.triangles, self.diagonal)
        if self.instances is not None:  # prototypes' triangles against their own (object-space) size
            for proto in np.unique(self.instances.prototypes):
                rows = np.flatnonzero(self.object_ids == proto)
                if not len(rows):
                    continue
                v = self.vertices[np.unique(self.triangles[rows])]
                keep[rows] = non_degenerate(self.vertices, self.triangles[rows],
                                            float(np.linalg.norm(v.max(axis=0) - v.min(axis=0))))
        dropped = int((~keep).sum())
        if dropped:
            warnings.warn(f"scene: skipped {dropped} degenerate (zero-area) triangle(s)", stacklevel=3)
            self.skipped_triangles += dropped
            self.triangles = np.ascontiguousarray(self.triangles[keep])
            self._bounds = None
            self.material_ids = np.ascontiguousarray(self.material_ids[keep])
            self.object_ids = np.ascontiguousarray(self.object_ids[keep])
            if self.normals is not None and not self.normals_per_vertex:
                self.normals = np.ascontiguousarray(self.normals[keep])
            self.uv_sets = [uv if uv.ndim == 2 else np.ascontiguousarray(uv[keep]) for uv in self.uv_sets]
            self.uvs = self._uvs_validated = self.uv_sets[0] if self.uv_sets else None
            if self.colors is not None:
                self.colors = np.ascontiguousarray(self.colors[keep])

    # ------------------------------------------------------------------ queries
    @property
    def normals_per_vertex(self) -> bool:
        """Whether ``normals`` is stored per vertex (V, 3) rather than per corner (T, 3, 3)."""
        return self.normals is not None and np.ndim(self.normals) == 2

    @property
    def uvs_per_vertex(self) -> bool:
        """Whether ``uv_sets`` are stored per vertex (V, 2) rather than per corner (T, 3, 2)."""
        return bool(self.uv_sets) and np.ndim(self.uv_sets[0]) == 2

    def corner_uvs(self, k: int = 0, rows=None) -> np.ndarray | None:
        """UV set k per corner, (T, 3, 2) (or of triangles ``rows`` only), whichever way it is stored; None
        without such a set."""
        if k >= len(self.uv_sets):
            return None
        a = self.uv_sets[k]
        if a.ndim == 3:
            return a if rows is None else a[rows]
        return a[self.triangles if rows is None else self.triangles[rows]]

    def to_corner_layout(self) -> None:
        """Store per-vertex normals and UV sets per corner (new arrays): what code that edits or copies rows of
        the per-triangle fields (``PER_TRIANGLE``) works on."""
        if self.normals_per_vertex:
            self.normals = np.ascontiguousarray(self.corner_normals())
        if self.uvs_per_vertex:
            self.uv_sets = [np.ascontiguousarray(self.corner_uvs(k)) for k in range(len(self.uv_sets))]
            self.uvs = self._uvs_validated = self.uv_sets[0]

    def corner_normals(self, rows=None) -> np.ndarray | None:
        """The shading normals per corner, (T, 3, 3) (or of triangles ``rows`` only), whichever way they are
        stored; None without normals. A per-vertex layout is gathered (a new array)."""
        if self.normals is None:
            return None
        if not self.normals_per_vertex:
            return self.normals if rows is None else self.normals[rows]
        return self.normals[self.triangles if rows is None else self.triangles[rows]]

    def prototype_rows(self) -> np.ndarray:
        """(T,) bool: the rows of ``triangles`` that belong to a prototype (object space, drawn by instances)."""
        if self.instances is None or not len(self.instances):
            return np.zeros(len(self.triangles), bool)
        return np.isin(self.object_ids, self.instances.prototypes)

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) min and max corner of what is drawn in world space: the referenced vertices of world-space
        triangles and every instance's placed prototype vertices (exact; zeros for an empty scene)."""
        if not len(self.triangles):
            return np.zeros((2, 3), np.float64)
        if getattr(self, "_bounds", None) is None:  # cached until the next validate()
            proto = self.prototype_rows()
            lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
            rows = np.flatnonzero(~proto) if proto.any() else np.zeros(0, np.int64)
            if len(rows) or not proto.any():  # the referenced vertices of world-space triangles (numba)
                box = np.empty((2, 3), np.float64)
                scene_kernels.used_bounds(np.ascontiguousarray(self.vertices, np.float32),
                                           np.ascontiguousarray(self.triangles, np.int32), rows, box)
                lo, hi = box
            if proto.any():
                for p in np.unique(self.instances.prototypes):
                    pv = self.vertices[np.unique(self.triangles[self.object_ids == p])]
                    b = instance_bounds(self.instances.transforms[self.instances.prototypes == p], pv)
                    lo, hi = np.minimum(lo, b[0]), np.maximum(hi, b[1])
            if not np.all(np.isfinite(lo)):
                lo = hi = np.zeros(3)
            self._bounds = np.stack([lo, hi]).astype(np.float64)
        return self._bounds.copy()

    @property
    def diagonal(self) -> float:
        lo, hi = self.bounds
        return float(np.linalg.norm(hi - lo))

    def default_epsilon(self) -> float:
        """ε for spawned rays: 5e-5 of the scene's size, where the size is the larger of the bounding-box diagonal
        and the largest coordinate magnitude (float32 spacing grows with distance from the origin)."""
        lo, hi = self.bounds
        size = max(self.diagonal, float(np.abs(np.stack([lo, hi])).max()))
        return max(5e-5 * size, 1e-6)

    def object_name(self, object_id: int) -> str:
        return self.object_names[object_id] if 0 <= object_id < len(self.object_names) else f"object{object_id}"


# ------------------------------------------------------------------------------------------------ flattening
def flatten(scene, chunk: int = 1024):
    """``scene`` with every instance copied out into world-space triangles (the triangle soup of a scene built
    with ``SceneBuilder.add_mesh(transform=M)`` per instance): positions by M, per-corner normals by the inverse
    transpose, corners 1 and 2 swapped under a mirroring M (every per-corner field: normals, UV sets, colours),
    each copy carrying its instance's object id and material override; prototypes are dropped. A scene without
    instances is returned as it is. For tools and tests that want the flat arrays (the renderer never flattens)."""

    inst = scene.instances
    if inst is None or not len(inst):
        return scene
    world = np.flatnonzero(~scene.prototype_rows())
    verts = [np.asarray(scene.vertices, np.float32)]
    tris = [scene.triangles[world]]

    def arrays(f):  # a per-triangle field as a list of arrays (list-valued fields have several), or None
        a = getattr(scene, f)
        return None if a is None else (list(a) if isinstance(a, list) else [a])

    fields = {f: arrays(f) for f in PER_TRIANGLE}
    if scene.normals_per_vertex:  # rows of triangles: per corner
        fields["normals"] = [scene.corner_normals()]
    if scene.uvs_per_vertex:
        fields["uv_sets"] = [scene.corner_uvs(k) for k in range(len(scene.uv_sets))]
    parts = {f: None if a is None else [[x[world]] for x in a] for f, a in fields.items()}
    n_v = len(scene.vertices)
    overrides = inst.material_overrides()
    for p in np.unique(inst.prototypes):
        prow = np.flatnonzero(scene.object_ids == p)
        sel_all = np.flatnonzero(inst.prototypes == p)
        if not len(prow):
            continue
        used, local = np.unique(scene.triangles[prow], return_inverse=True)
        local = local.reshape(-1, 3)
        pv = np.asarray(scene.vertices[used], np.float64)
        for c in range(0, len(sel_all), chunk):
            sel = sel_all[c:c + chunk]
            m = inst.transforms[sel]
            k = len(sel)
            placed = np.einsum("kij,vj->kvi", m[:, :3, :3], pv) + m[:, None, :3, 3]
            mirrored = np.linalg.det(m[:, :3, :3]) < 0
            t = local[None] + (n_v + np.arange(k) * len(pv))[:, None, None]
            t[mirrored] = t[mirrored][:, :, [0, 2, 1]]
            verts.append(placed.reshape(-1, 3).astype(np.float32))
            tris.append(t.reshape(-1, 3))
            n_v += k * len(pv)
            for f, arrs in fields.items():
                for a, out in zip(arrs or [], parts[f] or []):
                    rows = np.broadcast_to(a[prow], (k,) + a[prow].shape).copy()
                    if f == "object_ids":
                        rows[:] = inst.object_ids[sel][:, None]
                    elif f == "material_ids":
                        rows = np.where(overrides[sel][:, None] >= 0, overrides[sel][:, None], rows)
                    elif f == "normals":
                        nm = np.linalg.inv(m[:, :3, :3]).transpose(0, 2, 1)
                        rows = np.einsum("kij,ktcj->ktci", nm, rows.astype(np.float64)).astype(np.float32)
                    if rows.ndim >= 3 and rows.shape[2] == 3:  # per-corner data: corners turned with the winding
                        rows[mirrored] = rows[mirrored][:, :, [0, 2, 1]]
                    out.append(rows.reshape((-1,) + a.shape[1:]))
    flat = {f: None if p is None else [np.concatenate(x) for x in p] for f, p in parts.items()}
    flat = {f: (v if isinstance(getattr(scene, f), list) or v is None else v[0]) for f, v in flat.items()}
    if "uv_sets" in flat:
        flat["uv_sets"] = flat["uv_sets"] or []
    return Scene(vertices=np.concatenate(verts), triangles=np.concatenate(tris).astype(np.int32),
                 materials=scene.materials, camera=scene.camera, lights=list(scene.lights),
                 textures=list(scene.textures), background=scene.background, ambient=scene.ambient,
                 object_names=list(scene.object_names), object_pass_indices=scene.object_pass_indices,
                 environment=scene.environment, object_transforms=scene.object_transforms, **flat)

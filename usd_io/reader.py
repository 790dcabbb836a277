"""``load_stage``: a USD stage at one time code -> (:class:`tracer.Scene`, :class:`StageInfo`).

Geometry stays in stage space: the camera lives in the same space, so a Y-up and a Z-up copy of an asset give the
same picture through their cameras, and the default framing camera puts ``upAxis`` up (the same view of both).
``metersPerUnit`` is reported, not applied: light falloff is per stage unit, as in Hydra's renderers and usdview.
A stage without lights is lit by :func:`usd_io.lights.default_lights` (usdview's camera light) unless
``default_light=False``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pxr import Sdf, Usd, UsdGeom, UsdLux, UsdSkel

from tracer import SceneBuilder
from tracer.colorspace import AP1_TO_REC709
from tracer.scene import instance_bounds

from . import camera as cam
from .diagnostics import summarize
from .dome import environment
from .exporters import light_units as exporter_light_units
from .geometry.curves import read_curves, read_points
from .geometry.gprims import DEFAULT_SEGMENTS, GPRIM_TYPES, geom_type, read_gprim
from .geometry.instancing import instance_matrices, missing_required_input
from .geometry.mesh import (COMPLEXITY, DEFAULT_COMPLEXITY, SUBDIVIDED, MeshData, read_mesh, read_subdivided,
                            smooth_normals)
from .geometry.motion import stage_motion
from .geometry.nurbs import read_nurbs_curves, read_nurbs_patch, read_tet_mesh
from .geometry.skel import Skinning, bone_mesh, skeleton_purpose
from .geometry.xform import Transforms, transform_points
from .holdout import holdout_flags
from .layer_metadata import meters_per_unit
from .lights import convert_light, default_lights, light_links
from .materials.arnold import render_globals as arnold_render_globals
from .materials.table import MaterialTable
from .materials.texture_files import TextureCache
from .render_settings import CONFORM, DEFAULT_CONFORM, crop_to_data_window, read_render_settings
from .stage import (DEFAULT_PURPOSES, UsdInputError, captured_stderr, check_purposes, composition_warnings, open_stage,
                    renderable_prims, stage_messages, stage_time)


@dataclass
class StageInfo:
    """What was read: for ``whitted info``, the CLI's messages and tests."""

    path: str
    time: float | None
    width: int = 0
    height: int = 0
    camera: str | None = None  # the camera prim used; None = the default framing camera
    cameras: list = field(default_factory=list)
    lights: list = field(default_factory=list)  # (path, kind, tracer light or world dict)
    meshes: list = field(default_factory=list)  # (path, triangle count)
    materials: dict = field(default_factory=dict)  # material name -> tracer fields
    warnings: list = field(default_factory=list)
    notes: list = field(default_factory=list)  # what was done on the user's behalf (e.g. the default lighting)
    default_lighting: bool = False
    up_axis: str = "Y"
    meters_per_unit: float = 0.01
    render_settings: object = None  # usd_io.render_settings.RenderSpec of the RenderSettings used, or None
    nothing_drawn: str | None = None  # why a stage with visible gprims drew no triangle (the CLI exits 2)

    def warn(self, message: str) -> None:
        if message not in self.warnings:
            self.warnings.append(message)


FALLBACK_SURFACES = ("auto", "arnold", "hydra")  # load_stage(fallback_surface=...)
RENDERING_SPACES = ("rec709", "acescg")  # load_stage(rendering_space=...)
#: At most this many triangles of prototype copies made to colour a PointInstancer's instances one by one.
INSTANCE_COLOUR_TRIANGLES = 2_000_000


def instance_colour_primvars(prim, time, count: int):
    """({name: (count, 3) float values} of a PointInstancer's per-instance (vertex/varying) primvars with three
    numeric components and one element per instance, [names of every per-instance primvar])."""
    colours, names = {}, []
    for pv in UsdGeom.PrimvarsAPI(prim).GetPrimvarsWithValues():
        if pv.GetInterpolation() not in (UsdGeom.Tokens.vertex, UsdGeom.Tokens.varying):
            continue
        name = pv.GetPrimvarName()
        names.append(name)
        try:
            vals = np.asarray(pv.ComputeFlattened(time), np.float64)
        except (TypeError, ValueError):
            continue
        if vals.ndim == 2 and vals.shape == (count, 3) and pv.GetElementSize() == 1 and np.all(np.isfinite(vals)):
            colours[name] = vals
    return colours, sorted(names)


class _Reader:
    def __init__(self, stage, time, purposes, segments, info: StageInfo, light_units: str = "auto",
                 fallback_surface: str = "auto", rendering_space: str = "rec709"):
        self.stage, self.time, self.purposes, self.segments, self.info = stage, time, purposes, segments, info
        self.light_units, note = exporter_light_units(stage, light_units)  # usd_io.exporters
        if note:
            info.notes.append(note)
        self.b = SceneBuilder()
        self.xf = Transforms(time)
        self.mats = MaterialTable(self.b, time, info.warn)
        if fallback_surface not in FALLBACK_SURFACES:
            raise ValueError(f"fallback surface {fallback_surface!r}: choose one of {', '.join(FALLBACK_SURFACES)}")
        if fallback_surface != "auto":  # else asked of the stage at the first unbound prim (written_for_arnold)
            self.mats._arnold_stage = fallback_surface == "arnold"
        if rendering_space not in RENDERING_SPACES:
            raise ValueError(f"rendering space {rendering_space!r}: choose one of {', '.join(RENDERING_SPACES)}")
        if rendering_space == "acescg":  # colour textures into ACEScg; constants are taken as ACEScg numbers
            self.mats.files = TextureCache(np.linalg.inv(np.asarray(AP1_TO_REC709, np.float64)))
        self.lo = np.full(3, np.inf)
        self.hi = np.full(3, -np.inf)
        self._proto_cache: dict[str, MeshData | None] = {}
        self._proto_ids: dict[tuple, int] = {}  # (prototype prim path, material rows) -> tracer prototype object id
        self._instance_primvars_read: set = set()  # (instancer path, primvar name) drawn per instance
        self.light_prims: list = []  # the UsdLux prim of each tracer light
        self._grey = None
        self.empty: set = set()  # gprims whose geometry is absent or has no faces at this time
        self.invalid: set = set()  # prims left out as Storm leaves them out, or whose prototypes draw nothing here
        # (each named in a warning; a stage of only these is not refused)
        self.skinning = Skinning(time, self.xf.world)
        self.subdivision_level = COMPLEXITY[DEFAULT_COMPLEXITY]
        self._refined: dict = {}  # prim path -> MeshData refined ahead (prefetch_subdivided)
        self._todo, self._todo_at = [], {}  # meshes to refine ahead, and the position of each

    def prefetch_subdivided(self, prims) -> None:
        """Refine the subdivision meshes among ``prims`` in batches of PREFETCH_MESHES (usd_io.geometry.mesh.read_subdivided:
        the meshes of one topology in a batch refined once) ahead of adding them one by one: geometry() takes them
        from here, refining the next batch when it reaches a mesh not yet refined. Skinned meshes (posed before
        refinement) and all but one proxy of each instance prototype are left out."""
        seen, todo = set(), []
        for prim in prims:
            if not prim.IsA(UsdGeom.Mesh) or Skinning.is_skinned(prim):
                continue
            if prim.IsInstanceProxy():
                key = str(prim.GetPrimInPrototype().GetPath())
                if key in seen:
                    continue
                seen.add(key)
            todo.append(prim)
        self._todo, self._todo_at = todo, {str(p.GetPath()): i for i, p in enumerate(todo)}

    def _prefetched(self, prim):
        """The MeshData refined ahead for ``prim`` (its batch refined now if need be), or self if there is none."""
        key = str(prim.GetPath())
        if key not in self._refined and key in self._todo_at:
            batch = self._todo[self._todo_at[key]:][:PREFETCH_MESHES]
            for p in batch:
                self._todo_at.pop(str(p.GetPath()), None)
            self._refined.update(read_subdivided(batch, self.time, "st", self.subdivision_level))
        return self._refined.pop(key, self)

    # ------------------------------------------------------------------ geometry
    def geometry(self, prim, uv_name="st") -> MeshData | None:
        """Object-space geometry, or None (with a warning) where it is malformed."""
        try:
            if prim.IsA(UsdGeom.Mesh):
                skinned = Skinning.is_skinned(prim)  # skinned: the cage now, refined once posed (add_gprim)
                data = self._prefetched(prim) if uv_name == "st" and not skinned else self
                if isinstance(data, ValueError):
                    raise data
                if data is self:  # not refined ahead by prefetch_subdivided
                    data = read_mesh(prim, self.time, uv_name, 0 if skinned else self.subdivision_level)
            elif prim.IsA(UsdGeom.Points):
                data = read_points(prim, self.time)
            elif prim.IsA(UsdGeom.BasisCurves):
                data = read_curves(prim, self.time)
            elif prim.IsA(UsdGeom.NurbsCurves):
                data = read_nurbs_curves(prim, self.time)
            elif prim.IsA(UsdGeom.NurbsPatch):
                data = read_nurbs_patch(prim, self.time)
            elif prim.IsA(UsdGeom.TetMesh):
                data = read_tet_mesh(prim, self.time)
            else:
                data = read_gprim(prim, self.time, self.segments)
        except ValueError as exc:
            self.info.warn(f"{exc} (skipped)")
            return None
        if data is None:
            self.empty.add(str(prim.GetPath()))  # no points or no faces authored at this time: _say_if_empty
        if data is not None and not np.all(np.isfinite(data.points)):
            self.info.warn(f"{prim.GetPath()}: points with NaN or infinite coordinates (skipped)")
            return None
        return data

    def cached_geometry(self, prim) -> MeshData | None:
        """Geometry of an instance proxy is read once per prototype prim."""
        if not prim.IsInstanceProxy():
            return self.geometry(prim)
        key = str(prim.GetPrimInPrototype().GetPath())
        if key not in self._proto_cache:
            self._proto_cache[key] = self.geometry(prim)
        return self._proto_cache[key]

    def shaded(self, prim, data: MeshData):
        """(data, per-triangle material rows, add_mesh keywords for UV sets and vertex colours)"""
        return self.shaded_with_needs(prim, data)[:3]

    def shaded_with_needs(self, prim, data: MeshData, display_color_given: bool = False):
        """:meth:`shaded` and the MeshNeeds of its materials (None when they could not be read)."""
        needs = None
        try:
            material, needs = self.mats.for_prim(prim, data.n_faces, data.faces, display_color_given)
            material, extra = self.mats.mesh_inputs(prim, data, material, needs)
        except (TypeError, ValueError, IndexError) as exc:  # a shading input of an unexpected type or shape
            needs = None
            self.info.warn(f"{prim.GetPath()}: its material could not be read ({type(exc).__name__}: {exc}); "
                           "rendered grey")
            if self._grey is None:
                grey = self.mats.model(base_color=(0.5, 0.5, 0.5))
                self._grey = self.mats.writer.add_material("whitted:unreadable", grey)
            material, extra = self._grey, ({} if data.uvs is None else dict(uvs=data.uvs))
        for w in data.warnings:
            self.info.warn(w)
        return data, material, extra, needs

    def add_gprim(self, prim):
        data = self.cached_geometry(prim)
        if data is None or not len(data.triangles):
            return
        m = self.xf.world(prim)
        if prim.IsA(UsdGeom.Mesh) and Skinning.is_skinned(prim):
            posed = self.skinning.pose(prim, data, self.info.warn)
            if posed is not None:
                data, m = posed
            if self.subdivision_level and (UsdGeom.Mesh(prim).GetSubdivisionSchemeAttr().Get(self.time)
                                           or UsdGeom.Tokens.catmullClark) in SUBDIVIDED:
                # as Hydra does: skin the cage, then refine it
                data = read_mesh(prim, self.time, "st", self.subdivision_level, points=data.points) or data
        if not _usable(m):
            self.info.warn(f"{prim.GetPath()}: transform is singular (zero scale) or not finite (skipped)")
            return
        data, material, extra, needs = self.shaded_with_needs(prim, data)
        arnold_light = prim.GetAttribute("primvars:arnold:light")
        if prim.HasAPI(UsdLux.MeshLightAPI) or (arnold_light and arnold_light.Get(self.time)):
            kind = "UsdLux MeshLightAPI" if prim.HasAPI(UsdLux.MeshLightAPI) else "Arnold's mesh light (primvars:arnold:light)"
            self.info.warn(f"{prim.GetPath()}: {kind} is not supported (drawn with its material; it lights nothing)")
        tris = data.triangles
        if prim.IsInstanceProxy() and not Skinning.is_skinned(prim):
            # native instancing: the prototype's mesh once (object space), this proxy an instance of it; once per
            # instance-given colour when the colour primvar is inherited from outside the prototype
            key = (str(prim.GetPrimInPrototype().GetPath()), np.asarray(material).tobytes(),
                   self.mats.instance_colour_source(prim, needs) if needs is not None else None)
            proto = self._proto_ids.get(key)
            if proto is None:
                proto = self.b.add_mesh(data.points, tris, material=material, name=key[0], normals=data.normals,
                                        **dict(dict(uvs=data.uvs), **extra))
                self._proto_ids[key] = proto
            self.b.add_instances(proto, m, names=[str(prim.GetPath())])
        else:
            # add_mesh turns the winding of mirroring transforms back itself
            self.b.add_mesh(data.points, tris, material=material, name=str(prim.GetPath()), transform=m,
                            normals=data.normals, **dict(dict(uvs=data.uvs), **extra))
        self._grow(transform_points(m, data.points))
        self.info.meshes.append((str(prim.GetPath()), int(len(tris))))

    def add_skeleton(self, prim):
        """A Skeleton drawn as Storm draws it: UsdSkelImaging's bone mesh (usd_io.geometry.skel.bone_mesh), posed
        at the time code, in the skeleton's space and colour (its displayColor), when its purpose (a guide unless
        authored: skeleton_purpose) is one the render shows."""
        if skeleton_purpose(prim) not in self.purposes or prim.IsInstanceProxy():
            return
        label = str(prim.GetPath())
        got = bone_mesh(UsdSkel.Skeleton(prim), self.time, self.skinning.cache)
        if got is None:
            self.info.warn(f"{label}: skeleton cannot be posed: its bones are not drawn")
            return
        points, tris = got
        if not len(tris):
            return
        if not np.all(np.isfinite(points)):
            self.info.warn(f"{label}: skeleton posed at non-finite joints: its bones are not drawn")
            return
        n = len(tris)
        data = MeshData(points=points, triangles=tris, faces=np.arange(n), n_faces=n,
                        normals=smooth_normals(points, tris), corners=np.arange(3 * n).reshape(n, 3),
                        n_face_vertices=3 * n)
        m = self.xf.world(prim)
        if not _usable(m):
            self.info.warn(f"{label}: transform is singular (zero scale) or not finite (skipped)")
            return
        data, material, extra, _needs = self.shaded_with_needs(prim, data)
        self.b.add_mesh(data.points, tris, material=material, name=label, transform=m, normals=data.normals,
                        **dict(dict(uvs=data.uvs), **extra))
        self._grow(transform_points(m, data.points))
        self.info.meshes.append((label, n))

    def add_instancer(self, prim, frames=None, depth=0, outer=None):
        """A PointInstancer; ``frames`` (F, 4, 4) are the world matrices of the instancer itself when it is nested
        in another instancer's prototype (one per outer instance), else its own world matrix; ``outer`` the
        per-instance colour primvars of the enclosing instancers, {name: (source path, (F, 3) values)}.

        Per-instance (vertex/varying) primvars give each instance its element, as Hydra and Arnold do (an
        instancer's value wins over the prototype's own, the innermost instancer's over an outer one's): a
        3-component primvar that a prototype's material reads as its colour (displayColor, a primvar reader,
        Arnold's user_data_rgb) is drawn per instance, by one copy of the prototype mesh per distinct value
        (:data:`INSTANCE_COLOUR_TRIANGLES` at most). Others are named in one warning."""
        missing = missing_required_input(prim)
        if missing is not None:  # Storm leaves it out of the render index and draws the rest
            self.info.warn(f"{prim.GetPath()}: PointInstancer without a value for its required '{missing}' (not "
                           "drawn, as Storm does not draw it)")
            self.invalid.add(str(prim.GetPath()))
            return 0
        mats, idx, protos = instance_matrices(prim, self.time)
        frames = self.xf.world(prim)[None] if frames is None else frames
        here = str(prim.GetPath())
        own, per_instance = instance_colour_primvars(prim, self.time, len(idx))
        total = 0
        undrawn: list = []  # prototype lights (not instanced) and Arnold shapes (not USD geometry)
        for p_index, p_path in enumerate(protos):
            sel = np.flatnonzero(idx == p_index)
            root = self.stage.GetPrimAtPath(p_path)
            if not len(sel) or not root:
                continue
            # world matrix of every (outer instance, instance) pair before the piece's own relative transform
            base = (frames[:, None] @ mats[sel][None]).reshape(-1, 4, 4)
            # the colour primvars of every such pair (row f·S + s), the innermost instancer's winning
            colours = {name: (src, np.repeat(vals, len(sel), axis=0)) for name, (src, vals) in (outer or {}).items()}
            colours.update({name: (here, np.tile(vals[sel], (len(frames), 1))) for name, vals in own.items()})
            for piece in renderable_prims(self.stage, self.time, self.purposes, root=root):
                rel = self.xf.relative(piece, root.GetParent())
                if piece.IsA(UsdGeom.PointInstancer):
                    if depth >= MAX_INSTANCER_DEPTH:  # a guard against prototype cycles
                        self.info.warn(f"{piece.GetPath()}: PointInstancers nested more than "
                                       f"{MAX_INSTANCER_DEPTH} deep (a prototype cycle?) (skipped)")
                    else:
                        total += self.add_instancer(piece, base @ rel[None], depth + 1, colours)
                    continue
                if (geom_type(piece) not in GPRIM_TYPES and not piece.IsA(UsdGeom.Mesh)
                        and not _is_points_or_curves(piece)):
                    if piece.IsA(UsdGeom.Gprim):
                        self.info.warn(f"{piece.GetPath()}: {piece.GetTypeName()} is not supported (a prototype of "
                                       f"{prim.GetPath()}; skipped)")
                    elif piece.HasAPI(UsdLux.LightAPI) or piece.GetTypeName() in ARNOLD_SHAPES:
                        undrawn.append(piece)
                    continue
                data = self.geometry(piece)
                if data is None or not len(data.triangles):
                    continue
                data, material, extra, needs = self.shaded_with_needs(piece, data, "displayColor" in colours)
                full = base @ rel[None]
                usable = _usable(full)
                if not usable.all():
                    self.info.warn(f"{prim.GetPath()}: {int((~usable).sum())} instance(s) of {piece.GetPath()} have "
                                   "a singular (zero scale) or non-finite transform (skipped)")
                    full = full[usable]
                if not len(full):
                    continue
                # the piece's mesh once, in its own space; one instance per (outer instance, instance) with an
                # object id of its own (AOV objectid, picking), ids consecutive in instance order
                label = f"{prim.GetPath()}[{piece.GetPath()}]"
                name = needs.color[0] if needs is not None and needs.color is not None else None
                if name in colours and "colors" in extra:
                    src, values = colours[name]
                    if self._add_coloured_instances(label, data, material, extra, full, values[usable], src, name):
                        self._instance_primvars_read.add((src, name))
                        self._grow_instances(full, data.points)
                        total += len(data.triangles) * len(full)
                        continue
                proto = self.b.add_mesh(data.points, data.triangles, material=material, name=label,
                                        normals=data.normals, **dict(dict(uvs=data.uvs), **extra))
                self.b.add_instances(proto, full)
                self._grow_instances(full, data.points)
                total += len(data.triangles) * len(full)
        if undrawn:
            names = ", ".join(f"{q.GetTypeName()} {q.GetPath()}" for q in undrawn[:3]) + (", ..." if len(undrawn) > 3
                                                                                            else "")
            self.info.warn(f"{here}: prototype(s) not drawn: {names} (lights in prototypes are not instanced; "
                           "Arnold shapes are not USD geometry)")
            if not total:
                self.invalid.add(here)  # said: not a stage refused for drawing nothing
        unread = sorted(set(per_instance) - {n for src, n in self._instance_primvars_read if src == here})
        if unread:  # Hydra gives each instance its element; these reach no material as a colour here
            self.info.warn(f"{prim.GetPath()}: per-instance primvars {', '.join(unread)} are not read (each "
                           "instance shows its prototype's own values)")
        if depth == 0:
            self.info.meshes.append((str(prim.GetPath()), int(total)))
        return total

    def _add_coloured_instances(self, label, data, material, extra, full, values, src, name) -> bool:
        """The instances ``full`` (K, 4, 4) of one prototype piece, each coloured by its row of ``values`` (K, 3):
        one copy of the piece's mesh per distinct colour, its vertex colour that colour. False (nothing added)
        when the copies would pass :data:`INSTANCE_COLOUR_TRIANGLES`."""
        values = np.asarray(values, np.float32)
        uniq, inverse = np.unique(values, axis=0, return_inverse=True)
        inverse = np.asarray(inverse).reshape(-1)
        if len(uniq) * len(data.triangles) > INSTANCE_COLOUR_TRIANGLES:
            self.info.warn(f"{src}: per-instance primvar {name} has {len(uniq)} distinct values on {label}'s "
                           f"{len(data.triangles)} triangles: more than {INSTANCE_COLOUR_TRIANGLES} triangles of "
                           "copies (not read; each instance shows the prototype's own value)")
            return False
        corners = np.asarray(extra["colors"]).shape
        for u, colour in enumerate(uniq):
            rows = np.flatnonzero(inverse == u)
            kw = dict(extra, colors=np.broadcast_to(colour[: corners[-1]], corners).copy())
            proto = self.b.add_mesh(data.points, data.triangles, material=material, name=label,
                                    normals=data.normals, **dict(dict(uvs=data.uvs), **kw))
            # the names an unsplit piece would give (usd_io.geometry.instancing.instancer_motion reads the index)
            self.b.add_instances(proto, full[rows], names=[f"{label}[{i}]" for i in rows])
        return True

    def _grow_instances(self, matrices, points):
        self._grow(instance_bounds(matrices, points))

    def _grow(self, world_points):
        if len(world_points):
            self.lo = np.minimum(self.lo, world_points.min(axis=0))
            self.hi = np.maximum(self.hi, world_points.max(axis=0))

    # ------------------------------------------------------------------ lights
    def add_light(self, prim):
        try:
            kind, light, world = convert_light(prim, self.xf.world(prim), self.time, self.info.warn,
                                               units=self.light_units, textures=self.mats.files)
        except ValueError as exc:  # the tracer's light validation (NaN/Inf intensity, zero-length axes, ...)
            self.info.warn(f"{prim.GetPath()}: {exc} (light skipped)")
            return
        if light is not None:
            self.b.add_light(light)
            self.light_prims.append(prim)  # its links (usd_io.lights.light_links), in the order of b.lights
            self.info.lights.append((str(prim.GetPath()), kind, light))
        elif world is not None:  # `whitted info` shows what the dome is: no "environment" key without a texture
            self._add_world(prim, kind, world)

    def _add_world(self, prim, kind, world):
        if world.get("environment") is not None:  # a lat-long dome texture
            if getattr(self.b, "environment", None) is not None:
                self.info.warn(f"{prim.GetPath()}: a second textured DomeLight is not supported (skipped)")
                return
            self.b.environment = environment(world["environment"])
            self.info.lights.append((str(prim.GetPath()), kind, world))
        else:
            self.b.background = self.b.background + np.asarray(world["background"], np.float32)
            self.b.ambient = self.b.ambient + np.asarray(world["ambient"], np.float32)
            self.info.lights.append((str(prim.GetPath()), kind, {k: v for k, v in world.items() if v is not None}))

    def bounds(self):
        if not np.all(np.isfinite(self.lo)):
            return np.array([[-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]])
        return np.stack([self.lo, self.hi])


def _camera(stage, r, info, tc, camera, width, height, settings_prim, depth_of_field=True) -> None:
    """The render camera and image size (info.width/height/camera, r.b.camera): the stage camera (``camera``, the
    RenderSettings' camera, the first found) conformed by the RenderSettings' policy (expandAperture without one)
    and cropped to its data window, or the default framing camera."""
    spec = read_render_settings(stage, settings_prim, tc, info.warn)
    info.render_settings = spec
    if spec is not None and width is None and height is None and spec.resolution is not None:
        width, height = spec.resolution
    cam_prim = cam.find_camera(stage, camera or (spec.camera if spec else None), r.prims)
    par = spec.pixel_aspect if spec else 1.0
    policy = CONFORM[spec.conform] if spec else CONFORM[DEFAULT_CONFORM]
    if cam_prim is not None:
        raw = cam.fold_arnold_camera(cam.read_camera(cam_prim, tc), cam_prim, tc, info.notes.append)
        shaders = [n for n in ("filtermap", "uv_remap") if (cam_prim.GetAttribute(f"primvars:arnold:{n}")
                                                           and cam_prim.GetAttribute(f"primvars:arnold:{n}").Get())]
        if shaders:  # Arnold camera shaders: not run by the tracer
            info.warn(f"{cam_prim.GetPath()}: Arnold camera {' and '.join(shaders)} are not applied")
        lens = depth_of_field and (spec is None or spec.depth_of_field)  # --no-dof, disableDepthOfField
        raw = cam.fold_depth_of_field(cam.fold_clipping_planes(raw, info.warn), info.warn, lens, info.notes.append)
        info.width, info.height = cam.image_size(raw, width, height, par)
        r.b.camera = cam.to_tracer(raw, info.width, info.height, policy, par)
        info.camera = str(cam_prim.GetPath())
    else:
        aspect = cam.DEFAULT_APERTURE[0] / cam.DEFAULT_APERTURE[1]
        info.width, info.height = cam.image_size(dict(horizontal_aperture=aspect, vertical_aperture=1.0),
                                                 width, height)
        r.b.camera, view = cam.framing_camera(r.bounds(), info.up_axis, info.width, info.height)
        info.warn(f"no camera in the stage: a default camera frames the scene's bounds, {view}")
    if spec is not None:
        r.b.camera, info.width, info.height = crop_to_data_window(r.b.camera, info.width, info.height,
                                                                  spec.data_window)


def _say_if_empty(r, info) -> None:
    """0 triangles: one warning; ``info.nothing_drawn`` names the gprims that gave none (the CLI exits 2 then),
    and stays None when the stage has no visible gprims at all (an empty stage renders its empty frame)."""
    if sum(n for _p, n in info.meshes):
        return
    gprims = [p for p in r.prims if (p.IsA(UsdGeom.Gprim) or p.IsA(UsdGeom.PointInstancer))
              and str(p.GetPath()) not in r.empty and str(p.GetPath()) not in r.invalid]
    if not gprims:
        empty = f" ({len(r.empty)} gprim(s) without points or faces at this time)" if r.empty else ""
        if r.invalid:
            empty += f" ({len(r.invalid)} instancer(s) or instance(s) left out: see the warnings above)"
        info.warn(f"the stage has no visible gprims with geometry{empty}: the frame shows only the background")
        return
    kinds = sorted({p.GetTypeName() for p in gprims})
    undrawn = [_undrawn(p) for p in gprims]  # volumes / splats (an instancer's prototypes): one line says it all
    if all(undrawn):
        skipped = tuple(f"{q.GetPath()}: {q.GetTypeName()} is not supported" for u in undrawn for q in u)
        info.warnings[:] = [w for w in info.warnings if not w.startswith(skipped)]
        prims = [q for u in undrawn for q in u]
        names = ", ".join(str(q.GetPath()) for q in prims[:3]) + (", ..." if len(prims) > 3 else "")
        info.warn(f"the stage's only gprims are {len(prims)} {'/'.join(sorted({q.GetTypeName() for q in prims}))} "
                  f"prim(s) ({names}), which the tracer does not render: the frame shows only the background")
        return
    info.nothing_drawn = (f"{len(gprims)} visible gprim(s) ({', '.join(kinds)}) gave 0 triangles (see the warnings "
                          "above): nothing is drawn")
    info.warn(info.nothing_drawn)


def _undrawn(prim) -> list:
    """The gprims of types the tracer does not draw (volumes, particle fields) that ``prim`` is, or that an
    instancer's prototypes hold only; [] when it has anything drawable."""
    kids = [q for q in Usd.PrimRange(prim) if q != prim and q.IsA(UsdGeom.Gprim)] \
        if prim.IsA(UsdGeom.PointInstancer) else [prim]
    drawn = any(q.IsA(UsdGeom.PointInstancer) or geom_type(q) in GPRIM_TYPES or q.IsA(UsdGeom.Mesh)
                or _is_points_or_curves(q) for q in kids)
    return [] if drawn else kids


def select_variant(stage, prim_path: str, vset: str, value: str) -> None:
    """Select ``vset=value`` on the prim at ``prim_path`` (UsdInputError naming what does not exist)."""
    label = stage.GetRootLayer().identifier
    if not Sdf.Path.IsValidPathString(prim_path) or not Sdf.Path(prim_path).IsAbsolutePath():
        raise UsdInputError(f"{label}: --variant {prim_path}: not an absolute prim path")
    prim = stage.GetPrimAtPath(prim_path)
    if not prim:
        raise UsdInputError(f"{label}: --variant: no prim at {prim_path}")
    sets = prim.GetVariantSets()
    if not sets.HasVariantSet(vset):
        raise UsdInputError(f"{label}: --variant: {prim_path} has no variant set {vset!r} "
                            f"(it has: {', '.join(sets.GetNames()) or 'none'})")
    vs = sets.GetVariantSet(vset)
    if value not in vs.GetVariantNames():
        raise UsdInputError(f"{label}: --variant: {prim_path} {vset} has no variant {value!r} "
                            f"(choose from {', '.join(vs.GetVariantNames())})")
    with Usd.EditContext(stage, stage.GetSessionLayer()):
        vs.SetVariantSelection(value)


def _is_points_or_curves(prim) -> bool:
    """Gprims drawn through a reader of their own (points, curves, NURBS, tetrahedral meshes)."""
    return any(prim.IsA(t) for t in OTHER_GPRIMS)


#: Gprim schemas besides Mesh and the implicit shapes of usd_io.geometry.gprims, each with its reader in geometry().
OTHER_GPRIMS = (UsdGeom.Points, UsdGeom.BasisCurves, UsdGeom.NurbsCurves, UsdGeom.NurbsPatch, UsdGeom.TetMesh)


def _usable(m: np.ndarray) -> np.ndarray:
    """Whether 4×4 matrices (one or a stack) are finite and invertible, so points and normals can go through."""
    finite = np.isfinite(m).all(axis=(-2, -1))
    a = np.where(finite[..., None, None], m, 0.0)[..., :3, :3]
    size = np.abs(a).max(axis=(-2, -1))
    return finite & (np.abs(np.linalg.det(a)) > 1e-12 * size ** 3)


#: PointInstancers nest to any depth a real stage has; this only stops a prototype that instances itself.
MAX_INSTANCER_DEPTH = 32

#: Subdivision meshes refined per batch ahead of the prim loop: bounds the refined meshes held at once (memory)
#: while each batch still refines each of its topologies once.
PREFETCH_MESHES = 400


def _read_prims(r: _Reader, stage, tc, purposes, info: StageInfo) -> None:
    r.prims = list(renderable_prims(stage, tc, purposes))
    r.prefetch_subdivided(r.prims)
    for prim in r.prims:
        t = geom_type(prim)
        if prim.IsInstance() and (prim.IsA(UsdGeom.Gprim) or prim.IsA(UsdGeom.PointInstancer)):
            # UsdImaging's instance adapter skips the prototype's root when it is imageable (its attributes could
            # differ per instance); Storm draws nothing for it, with this warning
            info.warn(f"{prim.GetPath()}: a {t} directly instanced (instanceable = true on the {t} itself) is not "
                      "drawn, as Storm does not draw it: put the prim under an Xform and instance the Xform")
            r.invalid.add(str(prim.GetPath()))
            continue
        if prim.IsA(UsdGeom.PointInstancer):
            r.add_instancer(prim)
        elif t in GPRIM_TYPES or prim.IsA(UsdGeom.Mesh) or _is_points_or_curves(prim):
            r.add_gprim(prim)
        elif prim.IsA(UsdSkel.Skeleton):
            r.add_skeleton(prim)
        elif prim.HasAPI(UsdLux.LightAPI):
            r.add_light(prim)
        elif prim.IsA(UsdGeom.Camera):
            info.cameras.append(str(prim.GetPath()))
        elif prim.IsA(UsdGeom.Gprim):
            info.warn(f"{prim.GetPath()}: {t} is not supported (skipped)")
    _say_draw_modes(r.prims, info.warn)
    _say_arnold_shapes(r.prims, info.warn)


#: Arnold's own shape schemas (arnold-usd's schemas: Arnold nodes as prims) other than the sphere and box that
#: usd_io.geometry.gprims draws: not USD geometry, not drawn.
ARNOLD_SHAPES = ("ArnoldCone", "ArnoldCylinder", "ArnoldDisk", "ArnoldPlane",
                 "ArnoldPolymesh", "ArnoldCurves", "ArnoldPoints", "ArnoldNurbs", "ArnoldImplicit", "ArnoldGinstance",
                 "ArnoldUsd", "ArnoldProcedural", "ArnoldProceduralCustom", "ArnoldAlembic", "ArnoldVolume",
                 "ArnoldVolumeImplicit")


def _say_arnold_shapes(prims, warn) -> None:
    """One warning naming the Arnold shape prims (:data:`ARNOLD_SHAPES`) of the stage: kick draws them, the tracer
    reads USD geometry only."""
    found = [p for p in prims if p.GetTypeName() in ARNOLD_SHAPES]
    if found:
        names = ", ".join(f"{p.GetTypeName()} {p.GetPath()}" for p in found[:4]) + (", ..." if len(found) > 4 else "")
        warn(f"{len(found)} Arnold shape prim(s) ({names}): Arnold's own schema, not USD geometry; not drawn")


def _say_draw_modes(prims, warn) -> None:
    """One warning naming the models whose ``model:drawMode`` Storm applies (a component model always, any other
    model with ``model:applyDrawMode = true``: UsdImaging's draw-mode rule) and that are drawn here in full: the
    stand-ins (cards, bounds, origin) are a viewer's, not drawn by the tracer."""
    found: dict = {}
    for prim in prims:
        if not prim.IsModel() or not prim.HasAPI(UsdGeom.ModelAPI):
            continue
        model = UsdGeom.ModelAPI(prim)
        mode = str(model.ComputeModelDrawMode())
        if mode in ("default", "inherited", ""):
            continue
        if Usd.ModelAPI(prim).IsKind("component") or model.GetModelApplyDrawModeAttr().Get():
            found.setdefault(mode, []).append(str(prim.GetPath()))
    for mode, paths in sorted(found.items()):
        names = ", ".join(paths[:3]) + (", ..." if len(paths) > 3 else "")
        warn(f"model:drawMode {mode!r} on {len(paths)} model(s) ({names}): Storm draws their {mode} stand-in; the "
             "tracer draws the full geometry")


def stage_up_axis(stage, warn) -> str:
    """The stage's upAxis, "Y" or "Z". pxr returns any authored token; others ("X", typos) are not valid USD and
    read as UsdGeom's fallback Y, with one warning (usdrecord's framing treats every non-Y value as Z)."""
    axis = str(UsdGeom.GetStageUpAxis(stage))
    if axis in ("Y", "Z"):
        return axis
    warn(f"upAxis {axis!r} is not Y or Z: read as Y, UsdGeom's fallback")
    return "Y"


def load_stage(path_or_stage, time=None, camera: str | None = None, width: int | None = None,
               height: int | None = None, purposes=DEFAULT_PURPOSES, segments: int = DEFAULT_SEGMENTS,
               default_light: bool = True, variants=(), complexity: str = DEFAULT_COMPLEXITY,
               render_settings_prim: str | None = None, light_units: str = "auto", depth_of_field: bool = True,
               motion_blur: bool = True, fallback_surface: str = "auto", rendering_space: str = "rec709"):
    """Read a USD stage (a path or an open ``Usd.Stage``) into a render-ready :class:`tracer.Scene`.

    time      time code (None: the earliest time, i.e. default values or the first time sample)
    camera    camera prim path (None: the first camera found; no camera: frame the bounds, with a warning)
    width, height  image size; a missing side follows the camera aperture's aspect (width defaults to 960)
    purposes  which ``purpose`` values render (default: default and render)
    segments  tessellation of implicit gprims
    default_light  light a stage that has no lights as usdview does (a camera headlight and a dim dome; a note
              in ``info.notes``); False leaves it unlit (black)
    variants  ``(prim path, variant set, variant)`` selections applied (on the session layer) before reading
    complexity  refinement of subdivision surfaces, as usdrecord's: low (the control cage), medium (one level of
              Catmull-Clark, the default), high (2), veryhigh (3)
    render_settings_prim  a UsdRender RenderSettings prim path (None: the stage's renderSettingsPrimPath):
              its resolution, camera, pixel aspect, conform policy and data window apply where the arguments
              above are None; ``info.render_settings`` keeps its products and AOVs (usd_io.render_settings)
    light_units  "auto": lights in the units of the application that wrote the stage (usd_io.exporters; a note
              names it); "spec": as UsdLux says; or one of usd_io.exporters.UNITS
    depth_of_field  False: the camera is a pinhole whatever its fStop (``--no-dof``; the RenderSettings'
              ``disableDepthOfField`` does the same)
    motion_blur  False: nothing moves across the shutter (``--no-motion-blur``; the RenderSettings'
              ``disableMotionBlur`` does the same)
    fallback_surface  what geometry without a material is drawn with: "auto" Arnold's default standard_surface
              on a stage written for Arnold (usd_io.exporters.written_for_arnold), else Hydra's displayColor
              diffuse; "arnold" or "hydra" either whatever the stage (a stage rendered by kick: Arnold's)
    rendering_space  "rec709": the scene's colour numbers are linear Rec.709 (the tracer's space); "acescg": they
              are ACEScg numbers, as Arnold's default colour manager takes them, and colour textures decoded from
              sRGB are converted into ACEScg (the picture is then in ACEScg: convert it to Rec.709 for display,
              tracer.colorspace.AP1_TO_REC709)

    Returns ``(scene, info)``; ``info.warnings`` lists what was skipped or approximated (each message once).
    Raises :class:`UsdInputError` (a ``ValueError``) for input the user can fix.
    """
    stage = open_stage(path_or_stage)
    label = stage.GetRootLayer().identifier
    for prim_path, vset, value in variants:
        select_variant(stage, prim_path, vset, value)
    purposes = check_purposes(purposes)
    for name, v in (("width", width), ("height", height)):
        if v is not None and (isinstance(v, bool) or int(v) != v or v <= 0):
            raise UsdInputError(f"{label}: image {name} must be a positive integer, got {v!r}")
    tc = stage_time(stage, time)
    warnings_first: list[str] = []
    info = StageInfo(path=label, time=None if time is None or tc.IsDefault() else tc.GetValue(),
                     up_axis=stage_up_axis(stage, lambda m: warnings_first.append(m)),
                     meters_per_unit=meters_per_unit(stage, lambda m: warnings_first.append(m)))
    for w in warnings_first:
        info.warn(w)
    for w in composition_warnings(stage):
        info.warn(w)
    for w in stage_messages.get(id(stage), []):
        info.warn(f"usd: {w}")
    if complexity not in COMPLEXITY:
        raise UsdInputError(f"complexity {complexity!r}: choose from {', '.join(COMPLEXITY)}")
    try:
        r = _Reader(stage, tc, purposes, segments, info, light_units, fallback_surface, rendering_space)
    except ValueError as exc:  # an unknown --light-units value
        raise UsdInputError(f"{label}: {exc}") from None
    r.subdivision_level = COMPLEXITY[complexity]
    with captured_stderr() as said:  # USD's own diagnostics while reading: warnings of ours, not raw lines
        _read_prims(r, stage, tc, purposes, info)
    for line in summarize("".join(said)):  # usd_io.diagnostics: one line per kind, not pxr's raw lines
        info.warn(f"usd: {line}")
    info.materials = dict(r.mats.summary)
    _say_if_empty(r, info)


    _camera(stage, r, info, tc, camera, width, height, render_settings_prim, depth_of_field)
    arnold_render_globals(stage, r.prims, info.warn)  # usd_io.materials.arnold: Arnold backgrounds and atmospheres, named
    if default_light and not info.lights:
        sun, dome = default_lights(r.b.camera)
        r.b.add_light(sun)
        r.b.background = r.b.background + dome
        r.b.ambient = r.b.ambient + dome
        info.default_lighting = True
        info.notes.append("the stage has no lights: lit by a camera headlight and a dim dome as usdview does "
                          "(--no-default-light turns this off)")
    try:
        prims = r.light_prims + [None] * (len(r.b.lights) - len(r.light_prims))
        links = light_links(prims, r.b.object_names, tc)
    except ValueError as exc:
        info.warn(f"light linking: {exc} (lights unlinked)")
        links = []
    try:
        scene = r.b.build()
        # motion blur across the camera's shutter (usd_io.geometry.motion.stage_motion; nothing when it is closed)
        blur = motion_blur and (info.render_settings is None or info.render_settings.motion_blur)
        stage_motion(stage, scene, tc, info.camera, blur, r.subdivision_level, info.warn)
    except ValueError as exc:  # the tracer's validation of what was read (e.g. a NaN material input)
        raise UsdInputError(f"{label}: {exc}") from None
    scene.light_links = links
    scene.object_holdout = holdout_flags(stage, scene.object_names, tc)  # usd_io.holdout: primvars:arnold:matte
    return scene, info

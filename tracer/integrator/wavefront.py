"""The seed's Cast-Ray, as a wavefront over one tile.

Recursion becomes iteration: all rays of a tile at one depth are intersected together (Embree), then named stages
shade every hit and write the rays of the next step, so the recursive colour

    c = (1 − k_m)·c_local + k_m·RayColor(reflected)          (ray type 3, the notes' formula)

becomes: add throughput·(1 − k_m)·c_local to the pixel, and spawn the reflected ray with throughput·k_m, where a
ray's *throughput* is the product of the weights on its path. Glass (transmission weight w_t, ray type 4) splits the
non-mirror remainder (1 − k_m) into a reflected part F and a transmitted part (1 − F) by the dielectric Fresnel factor
F (or, in classic mode, F = 0, and 1 under TIR). The Principled model (``RenderSettings.shading``) adds its GGX
lobes: evaluated for every light sample, and handed to the mirror ray by roughness (:func:`tracer.shading.bsdf.mirror_share`).

One depth of a tile, each stage a kernel over named queues (NamedTuples of arrays):

    Embree closest hits
      → surfaces        (SurfaceQueue: point, frames, the material's parameters after textures and normal map)
      → first hits      (depth 0: the AOVs)
      → emitted         (what the ray sees: the world where it leaves, emission where it hits)
      → direct light    (ShadowQueue: one deferred shadow ray per light sample, with the colour it would add)
      → sky             (ShadowQueue: environment / ambient-visibility rays)
      → spawn secondary (RayQueue of the next depth: reflections, transmissions; and the same depth's rays that
                         pass through alpha < 1, traced again at once)
    → Embree occlusion (shadow rays that stop on alpha < 1 surfaces are continued through them) → add unoccluded.

Every spawned ray leaves its surface through :func:`spawn_ray`, the one place ε is applied.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from .. import optics, vec
from ..accel import alpha
from ..accel.accelerator import Accelerator
from ..geometry.instances import mat3_apply, mat3_apply_transposed, pack_instances, world_emitters
from ..geometry.motion import frames_at_time, pack_motion
from ..geometry.surface import color_at, corner_normals, geometry_of, shading_frame
from ..jit import kernel
from ..lights import linking, sky
from ..lights.emitters import DISTANT, MESH, POINT, SPOT, lamp_hit, pack_lights, sample_light
from ..lights.environment import env_radiance, pack_environment
from ..sampling import rotated_multijitter, uniform1, uniform2_1
from ..scene import Scene
from ..settings import RenderSettings
from ..shading import bsdf, lobes, local as shading
from ..shading.compiler import pack_programs
from ..shading.spaces import object_spaces, set_camera
from ..shading.texture import pack_textures
from ..shading.vm import IN_GENERATED, OP_INPUT, cut as _cut, shade_programs
from . import compose
from . import guides as guide_stage

RAY_TYPES = ("eye", "shadow", "reflection", "transmission", "sky")

#: How light reached the eye, by the path's first secondary ray: "direct" (lit at the eye ray's hit, or background
#: seen directly), "reflection", "transmission". The three ray-type AOVs sum to the beauty.
PATH_TYPES = ("direct", "reflection", "transmission")
_REFLECTION_PATH, _TRANSMISSION_PATH = 1, 2

# Sample streams (independent hash sequences) of one eye sample.
_STREAM_PIXEL = 0
_STREAM_LIGHT = 1  # + depth
_STREAM_SKY = 40  # + depth
_STREAM_GLASS = 200  # + depth: the microfacet normal of rough glass (uniform2_1)
_STREAM_GLASS_PICK = 1000  # + depth: mirror or rough glass for the one reflected ray (uniform1)
#: What the spawn stage writes per rough-glass hit for its light samples (:func:`_glass_light`): α, η_i, η_r, the
#: energy compensation 1/E, the light samples' share of the lamps, the reflected tint (3), the refracted tint (3,
#: × (1 − F)) and the Refraction BSDF's tint (3, no Fresnel).
GLASS_COLUMNS = 14

# What made a ray, for the lamps it sees (the columns of tracer.lights.linking.Links.seen).
RAY_CAMERA, RAY_GLOSSY, RAY_TRANSMISSION = 0, 1, 2

# Slots of the kernel's counter array.
_N_SHADOW, _N_SKY, _N_REFLECTION, _N_TRANSMISSION, _N_TIR = 0, 1, 2, 3, 4


@dataclass
class RayCounts:
    eye: int = 0
    shadow: int = 0
    reflection: int = 0
    transmission: int = 0
    sky: int = 0
    #: Transmission attempts that met total internal reflection (followed the reflection instead). Not a ray type.
    tir: int = 0

    def add(self, other: "RayCounts") -> None:
        for k in RAY_TYPES + ("tir",):
            setattr(self, k, getattr(self, k) + getattr(other, k))

    @property
    def total(self) -> int:
        return sum(getattr(self, k) for k in RAY_TYPES)

    def as_dict(self) -> dict:
        return {k: getattr(self, k) for k in RAY_TYPES} | {"total": self.total, "tir": self.tir}


@dataclass
class TileResult:
    color: np.ndarray  # (S, 3) per eye sample
    alpha: np.ndarray  # (S,)
    depth: np.ndarray  # (S,) distance from the eye (ortho: film plane) to the first hit along the eye ray, inf where none
    normal: np.ndarray  # (S, 3) first-hit shading normal (world space, facing the eye)
    albedo: np.ndarray  # (S, 3) first-hit diffuse colour
    object_id: np.ndarray  # (S,) first-hit object id, -1 where none
    counts: RayCounts = field(default_factory=RayCounts)
    guide_albedo: np.ndarray | None = None  # (S, 3) Cycles' Denoising Albedo (tracer/integrator/guides.py), with guides
    guide_normal: np.ndarray | None = None  # (S, 3) Cycles' Denoising Normal (camera space), with guides
    by_type: np.ndarray | None = None  # (S, 3, 3) colour per PATH_TYPES (with ray_types)
    deepest: np.ndarray | None = None  # (S,) depth of the deepest ray (0 = the eye ray only) (with ray_types)
    compose: np.ndarray | None = None  # (S, compose.COLUMNS) shadow-catcher sums (scenes with a catcher)
    compose_mode: tuple = (False, True)  # (transparent film, approximate shadow catcher) for tracer.integrator.compose
    # (P,) samples each pixel of the tile took (adaptive sampling), when they differ; None: every pixel took its
    # spp. With it the per-sample arrays hold each pixel's samples consecutively, in stratum order, spent[p] of
    # them (tracer.integrator.tiles.write_tile)
    spent: np.ndarray | None = None


class MaterialArrays(NamedTuple):
    """:class:`tracer.Materials` as the kernels read it (float32 / int32 / bool columns, one row per material)."""

    diffuse: np.ndarray
    specular_color: np.ndarray
    exponent: np.ndarray
    k_m: np.ndarray
    mirror_tint: np.ndarray
    transmission: np.ndarray
    transmission_tint: np.ndarray
    ior: np.ndarray
    emission: np.ndarray
    roughness: np.ndarray
    metallic: np.ndarray
    specular: np.ndarray
    specular_tint: np.ndarray
    alpha: np.ndarray
    alpha_threshold: np.ndarray
    normal_strength: np.ndarray
    rough_glass: np.ndarray
    glass_multiscatter: np.ndarray
    vertex_color: np.ndarray
    base_color_texture: np.ndarray
    roughness_texture: np.ndarray
    metallic_texture: np.ndarray
    specular_texture: np.ndarray
    alpha_texture: np.ndarray
    emission_texture: np.ndarray
    normal_texture: np.ndarray
    base_color_channel: np.ndarray
    roughness_channel: np.ndarray
    metallic_channel: np.ndarray
    specular_channel: np.ndarray
    alpha_channel: np.ndarray
    emission_channel: np.ndarray
    normal_channel: np.ndarray
    textured: np.ndarray  # (N,) bool: the material has a program (tracer.shading.vm) the textures stage runs

    @classmethod
    def of(cls, m, has_program: np.ndarray) -> "MaterialArrays":
        f32, i32 = (lambda a: np.ascontiguousarray(a, np.float32)), (lambda a: np.ascontiguousarray(a, np.int32))
        cols = {"textured": np.ascontiguousarray(has_program, np.bool_)}
        for name in cls._fields[:-1]:
            if name == "base_color_texture":
                a = m.diffuse_texture
            else:
                a = getattr(m, name)
            if name.endswith("_texture") or name.endswith("_channel"):
                cols[name] = i32(a)
            elif name == "vertex_color":
                cols[name] = np.ascontiguousarray(a, np.bool_)
            else:
                cols[name] = f32(a)
        return cls(**cols)


class Options(NamedTuple):
    """The settings and world colours the kernels need, as plain scalars."""

    eps: float
    max_depth: int
    shadows: bool
    fresnel: bool
    sky_samples: int
    min_weight: float
    transparent: bool
    seed: int
    needs_light_random: bool
    background: tuple
    ambient: tuple
    principled: bool
    sky_side: int


class RayQueue(NamedTuple):
    """Rays of one depth: origins, unit directions, the weight (throughput) each carries, the eye sample it adds
    to, an optional length limit (None = unbounded) and each ray's time across the shutter (its eye sample's;
    None = no motion blur)."""

    o: np.ndarray
    d: np.ndarray
    weight: np.ndarray
    sample: np.ndarray
    t_max: np.ndarray | None
    mask: np.ndarray | None = None  # Embree ray masks (tracer.lights.linking), None: the rays see every object
    time: np.ndarray | None = None  # each ray's time across the shutter (tracer.geometry.motion), None: no motion blur
    feature: np.ndarray | None = None  # (N, 4) the denoising guides each ray still carries
    #                                    (tracer/integrator/guides.py: P·T rgb, P), None: no guides are made
    kind: np.ndarray | None = None  # (N,) uint8 RAY_CAMERA / RAY_GLOSSY / RAY_TRANSMISSION (which lamps see it:
    #                                 _lamps_seen); None: camera rays at depth 0
    lamp: np.ndarray | None = None  # (N,) float32 the share of the ray's weight that sees lamps (a mirror ray of
    #                                 rough lobes leaves their lamps to the light samples: bsdf.lamp_share); None: 1
    medium: np.ndarray | None = None  # (N,) int32 the carried medium each ray travels in (the material row of
    #                                   Scene.material_volume_carried, -1: none; _carried_media); None: none


class SurfaceQueue(NamedTuple):
    """What each ray of a depth found (the surfaces stage): whether it hit, the point, the geometric normal and
    the shading normal (after the normal map) on the incident side, which face it hit, the material and its
    parameters after texture lookups, and the coverage (alpha after the cut-out threshold)."""

    hit: np.ndarray  # (N,) bool
    p: np.ndarray  # (N, 3) float64
    ng: np.ndarray  # (N, 3) float32
    n: np.ndarray  # (N, 3) float32
    front: np.ndarray  # (N,) bool
    mat: np.ndarray  # (N,) int32
    base: np.ndarray  # (N, 3) float32 base colour (× texture × vertex colour)
    roughness: np.ndarray  # (N,) float32
    metallic: np.ndarray  # (N,) float32
    specular: np.ndarray  # (N,) float32 Specular IOR Level
    cover: np.ndarray  # (N,) float32 alpha in [0, 1]
    emission: np.ndarray  # (N, 3) float32
    textured: np.ndarray  # (N,) int32: the rays whose material has a program (the first _surfaces returns)
    mirror: np.ndarray  # (N, 3) float32: the Principled lobes' share of the mirror ray, g(r)·(their albedo at the
    #                     view angle), written by the direct-light stage from its closure for the spawn stage
    transmission: np.ndarray  # (N,) float32 glass weight of the non-metal part
    # A closure that is a sum of lobes (tracer.shading.lobes; written by the VM, tracer.shading.vm.write_lobes):
    lobes: np.ndarray  # (N,) int32 lobe slots in use; -1: one closure (the parameters above)
    lobe_kind: np.ndarray  # (N, MAX_LOBES) int32 tracer.shading.lobes kind
    lobe_w: np.ndarray  # (N, MAX_LOBES, 3) float32 weight RGB
    lobe_base: np.ndarray  # (N, MAX_LOBES, 3) float32 colour
    lobe_param: np.ndarray  # (N, MAX_LOBES, 4) float32 roughness, metallic, specular level, transmission
    through: np.ndarray  # (N, 3) float32 the colour that passes straight through (lobe hits)
    holdout: np.ndarray  # (N,) float32 the closure's Holdout weight per hit (tracer.integrator.compose reads it; the VM
    #                      writes it for a sum of lobes, tracer.shading.vm.write_lobes; 0 = none)
    mirror_lamp: np.ndarray  # (N, 3) float32: the part of ``mirror`` that sees lamps (bsdf.lamp_share), written with it
    aniso: np.ndarray  # (N, 3) float32: the lobes' anisotropy (tracer.shading.bsdf.anisotropic; 0: isotropic)
    ns: np.ndarray  # (N, 3) float32: the smooth normal before the material's Bump / Normal Map (Cycles' sd->N; the
    #                 light stages' bsdf.bump_shadowing where n differs from it)

    @classmethod
    def empty(cls, n: int) -> "SurfaceQueue":
        f3 = lambda: np.empty((n, 3), np.float32)  # noqa: E731
        f1 = lambda: np.empty(n, np.float32)  # noqa: E731
        k = lobes.MAX_LOBES
        return cls(np.empty(n, np.bool_), np.empty((n, 3), np.float64), f3(), f3(), np.empty(n, np.bool_),
                   np.empty(n, np.int32), f3(), f1(), f1(), f1(), f1(), f3(), np.empty(n, np.int32),
                   f3(), f1(), np.empty(n, np.int32), np.empty((n, k), np.int32),
                   np.empty((n, k, 3), np.float32), np.empty((n, k, 3), np.float32), np.empty((n, k, 4), np.float32),
                   f3(), f1(), f3(), f3(), f3()).reset()

    #: The columns that start at a value (the rest are written before they are read), by field name.
    START = {"mirror": 0.0, "lobes": -1, "holdout": 0.0, "mirror_lamp": 0.0, "aniso": 0.0}

    def reset(self) -> "SurfaceQueue":
        """Set the :data:`START` columns to their start values; returns the queue."""
        for name, value in self.START.items():
            getattr(self, name).fill(value)
        return self

    @classmethod
    def scratch(cls, held: dict, n: int) -> "SurfaceQueue":
        """An :meth:`empty` queue of n rows made of views of ``held["surf"]`` (one thread's queue, kept between
        batches and grown when n exceeds it): the arrays of a fresh queue, allocated for every batch, cost more
        than some of the stages that fill them (page faults on fresh memory)."""
        q = held.get("surf")
        if q is None or len(q.hit) < n:
            q = held["surf"] = cls.empty(n)
        return cls(*(a[:n] for a in q)).reset()

    @property
    def lobe_arrays(self) -> tuple:
        """What the VM writes a lobe closure into (its ``lobe_surf``)."""
        return (self.lobes, self.lobe_kind, self.lobe_w, self.lobe_base, self.lobe_param, self.through,
                self.holdout)


class ShadowQueue(NamedTuple):
    """Deferred shadow (and sky) rays of one depth: each adds ``color`` to its sample if nothing blocks it."""

    o: np.ndarray
    d: np.ndarray
    t_max: np.ndarray
    sample: np.ndarray
    color: np.ndarray
    light: np.ndarray  # light index, -1 for a sky-visibility ray

    @classmethod
    def empty(cls, n: int) -> "ShadowQueue":
        return cls(np.empty((n, 3), np.float32), np.empty((n, 3), np.float32), np.empty(n, np.float32),
                   np.empty(n, np.int32), np.empty((n, 3), np.float32), np.empty(n, np.int32))


class SpawnRecord(NamedTuple):
    """Per-ray facts the kernel records beside its queues, for ``tracer.explain``: for each shadow/sky ray the
    light it samples (-1: sky); for each spawned ray the normal and refractive indices its direction came from."""

    light: np.ndarray  # (shadow capacity,) int32
    normal: np.ndarray  # (next capacity, 3) float32
    eta: np.ndarray  # (next capacity, 2) float32
    tir: np.ndarray  # (next capacity,) bool

    @classmethod
    def empty(cls, n_shadow: int, n_next: int) -> "SpawnRecord":
        return cls(np.empty(n_shadow, np.int32), np.empty((n_next, 3), np.float32), np.empty((n_next, 2), np.float32),
                   np.empty(n_next, np.bool_))


class NextQueue(NamedTuple):
    """Rays the spawn stage writes: the next depth's (reflections from slot 0, transmissions from slot n) and the
    rays that pass straight through alpha < 1 surfaces (traced again at the same depth), with their spawn record."""

    o: np.ndarray
    d: np.ndarray
    weight: np.ndarray
    sample: np.ndarray
    spawned: SpawnRecord
    through_o: np.ndarray
    through_d: np.ndarray
    through_weight: np.ndarray
    through_sample: np.ndarray
    through_t0: np.ndarray  # distance along the eye ray travelled before the pass-through ray
    parent: np.ndarray  # the row of the hit each next ray left (the denoising guides follow it: tracer/integrator/guides.py)
    through_parent: np.ndarray  # the same for the pass-through rays
    lamp: np.ndarray  # each next ray's share of its weight that sees lamps (RayQueue.lamp)

    @classmethod
    def empty(cls, n: int, spawn: bool) -> "NextQueue":
        m = 2 * n if spawn else 0
        return cls(np.empty((m, 3), np.float32), np.empty((m, 3), np.float32), np.empty((m, 3), np.float32),
                   np.empty(m, np.int32), SpawnRecord.empty(0, m), np.empty((n, 3), np.float32),
                   np.empty((n, 3), np.float32), np.empty((n, 3), np.float32), np.empty(n, np.int32),
                   np.empty(n, np.float32), np.empty(m, np.int32), np.empty(n, np.int32), np.empty(m, np.float32))


class Step(NamedTuple):
    """What one depth of :meth:`Integrator.step` did: the hits (t, prim, u, v), the shadow queue and which of its
    rays were blocked, the next depth's rays (the first ``n_reflected`` are reflections) and how they were made."""

    hits: tuple
    shadow: ShadowQueue
    blocked: np.ndarray
    next: RayQueue
    spawned: SpawnRecord
    n_reflected: int


class Guides(NamedTuple):
    """Where the denoising guides of a trace are written (tracer/integrator/guides.py): per eye sample (slot) the albedo and
    the camera-space normal, and the camera's world-to-camera rows."""

    albedo: np.ndarray
    normal: np.ndarray
    cam: np.ndarray


class Tile(NamedTuple):
    """Per-sample outputs a tile's kernels write into."""

    color: np.ndarray
    alpha: np.ndarray
    depth: np.ndarray
    normal: np.ndarray
    albedo: np.ndarray
    object_id: np.ndarray
    compose: np.ndarray = compose.empty(0, False)  # (S, compose.COLUMNS) shadow-catcher sums (scenes with one)


def reads_input(programs, what: int) -> bool:
    """Whether any material's program reads the hit input ``what`` (an ``OP_INPUT`` with ``imm`` = that IN_* code;
    tracer.shading.vm's instruction columns: 0 the op, 8 the immediate)."""
    code = programs.code
    return bool(len(code)) and bool(np.any((code[:, 0] == OP_INPUT) & (code[:, 8] == what)))


class Integrator:
    """Holds what every tile needs: the scene's arrays, its BVH and the settings. ``trace`` is thread-safe: tile
    threads share this object, so everything on it is made in ``__init__`` and only read afterwards, except three
    things, each made safe where it lives: the scratch queues (:meth:`_held`, one set per thread), the camera's
    entry of ``spaces`` (written under ``_camera_lock`` when a session's camera changed, :meth:`_shade`) and the
    transparent-shadow filter's tables (made once under a lock, :func:`tracer.accel.alpha.occluded`, which also gives
    each call its own VM register file). The VM's initial registers ``programs.R0`` are never written: every
    kernel that runs programs copies them into a register file of its call."""

    def __init__(self, scene: Scene, settings: RenderSettings, accel: Accelerator | None = None):
        self.scene = scene
        self.settings = settings
        self.accel = accel if accel is not None else Accelerator(scene)
        eps = settings.epsilon if settings.epsilon is not None else scene.default_epsilon()
        self.eps = np.float32(eps)
        self.geometry = geometry_of(scene)
        m = scene.materials
        #: every material's program (tracer.shading.compiler), and the textures its image ops read
        self.programs, textures = pack_programs(m, scene.textures)
        self.materials = MaterialArrays.of(m, self.programs.has)
        self.textures = pack_textures(textures)
        #: the coordinate spaces programs read (tracer.shading.spaces; the camera's entry refreshed per batch)
        #: the objects' texture spaces (bounds in object space, a pass over every triangle) only when a program
        #: reads Generated coordinates (0.7 s of a 1.5 M-triangle render otherwise: bench.production)
        self.spaces = (object_spaces(scene, texture_spaces=reads_input(self.programs, IN_GENERATED))
                       if self.programs.has.any() else np.zeros((2, 9, 4), np.float64))
        self.instances = pack_instances(scene)
        self.motion = pack_motion(scene)  # None: nothing moves (tracer/geometry/motion.py)
        # instanced prototypes' emitting triangles placed per instance (tracer/geometry/instances.py)
        linked = sorted(getattr(scene, "emitter_links", None) or {})  # emitting objects that are their own light
        emitters = world_emitters(scene, m.emission * m.alpha[:, None], with_objects=bool(linked))
        self.lights = pack_lights(scene.lights, settings.light_samples, emitters, linked)
        #: light and shadow linking, ray visibility (tracer.lights.linking); inactive tables when the scene has none
        self.links = linking.pack(scene, len(self.lights.kind), self.lights.emitter_object)
        self.light_samples = int(np.sum(self.lights.side ** 2))  # shadow rays per shading point, at most
        self.lights_lamps = bool(np.any(self.lights.kind != MESH))  # lights that rough glass samples (_glass_light)
        self.env = pack_environment(scene.environment)
        ambient = scene.ambient
        if scene.environment is not None and not np.any(ambient > 0):
            ambient = scene.environment.average()
        sky = settings.sky_samples
        lit_by_sky = scene.environment is not None or np.any(scene.ambient > 0)
        self.sky_side = max(1, int(round(np.sqrt(sky)))) if sky and lit_by_sky else 0
        self.options = Options(
            eps=float(self.eps), max_depth=int(settings.max_depth), shadows=bool(settings.shadows),
            fresnel=bool(settings.fresnel), sky_samples=int(settings.sky_samples),
            min_weight=float(settings.min_weight), transparent=bool(settings.transparent), seed=int(settings.seed),
            needs_light_random=bool(np.any(self.lights.side > 1)),
            background=tuple(float(c) for c in scene.background), ambient=tuple(float(c) for c in ambient),
            principled=settings.shading == "principled", sky_side=int(self.sky_side))
        used = np.zeros(len(m), bool)
        used[np.unique(scene.material_ids)] = True
        used[self.instances.materials[self.instances.materials >= 0]] = True
        #: Some used material lets light through (alpha < 1 or an alpha texture): shadow rays look through it.
        self.see_through = bool(np.any(used & ((m.alpha < 1) | self.programs.alpha_varies)))
        #: Holdouts and shadow catchers (tracer.integrator.compose)
        self.compose = compose.pack(scene)
        self.volumes = _pack_volumes(getattr(scene, "material_volumes", None), len(m.names))
        self.carried = None  # (M,) bool: media the rays carry (Scene.material_volume_carried), None: none
        carried = getattr(scene, "material_volume_carried", None)
        if self.volumes is not None and carried is not None and np.any(carried):
            self.carried = np.zeros(len(self.volumes), np.bool_)
            c = np.asarray(carried, np.bool_)[:len(self.volumes)]
            self.carried[:len(c)] = c
        self._local = threading.local()
        self._camera_lock = threading.Lock()

    def _held(self) -> dict:
        """This thread's scratch arrays (:meth:`SurfaceQueue.scratch`): tiles trace on threads, each its own."""
        held = getattr(self._local, "held", None)
        if held is None:
            held = self._local.held = {}
        return held

    @property
    def last_depth(self) -> int:
        """The deepest step: max_depth, or one more (collecting only background and emission) with terminal rays."""
        return self.settings.max_depth + (1 if self.settings.terminal_rays else 0)

    def _shade(self, depth: int, o, d, weight, sample, t0, hits, keys, out: "Tile", counts, spawn: bool,
               time=None, feature=None, gd: "Guides | None" = None, kind=None, lamp=None, medium=None):
        """The stages for one batch of rays and their hits: returns (ShadowQueue, NextQueue, n_refl, n_tran,
        n_through, the catcher's shadow rays, the spawned rays' guide features: None, or (reflections,
        transmissions, pass-through rays)), and the spawned rays' carried media (None when no ray carries one:
        reflections, transmissions, pass-through rays)."""
        n = len(o)
        t, prim, u, v, inst = hits
        surf = SurfaceQueue.scratch(self._held(), n)
        it = self.instances
        n_textured = _surfaces(o, d, t, prim, inst, it.normal_matrix, it.materials, u, v, self.geometry,
                               self.materials, surf)
        if self.motion is not None and time is not None:  # what moves is shaded where it is at the ray's time
            frames_at_time(d, prim, inst, u, v, time, self.geometry, self.motion, surf.ng, surf.n, surf.front)
        np.copyto(surf.ns, surf.n)  # the smooth normal, before the programs bump it
        if n_textured:  # the textures stage: the materials' programs (tracer.shading.vm)
            g, m, x, pt = self.geometry, self.materials, self.textures, self.programs
            # one eye sample's footprint, for the mip level of lookups and the bump offsets: read now, as a
            # session's camera and settings change between renders without a new Integrator
            eye, spread, flat = self.scene.camera.sample_footprint(self.settings.width, self.settings.samples)
            with self._camera_lock:  # every tile thread reads ``spaces``: one writer, and only on a change
                set_camera(self.spaces, self.scene.camera)
            shade_programs(surf.textured[:n_textured], prim, u, v, t, inst, d, depth, pt.code, pt.pstart, pt.pbase,
                           pt.outs, pt.R0, np.empty_like(pt.R0), surf.mat, surf.p, surf.ng, surf.n, surf.front,
                           surf.base, surf.roughness, surf.metallic, surf.specular, surf.cover, surf.emission,
                           surf.transmission, m.alpha_threshold, g.uv_sets, g.colors, g.has_colors, g.vertices,
                           g.triangles, g.face_normals, g.object_ids, self.spaces, x.data, x.params, it.linear,
                           it.mirrored, it.object_ids, eye, spread, flat, pt.lobes, surf.lobe_arrays, surf.aniso, surf.ns,
                           float(max(1, int(self.settings.samples))))
        if self.volumes is not None:  # rays leaving a medium: Beer–Lambert and its emission over their length
            weight = _through_media(self.volumes, surf, t, sample, weight, out.color, n, self.carried)
        if medium is not None:  # rays travelling in a carried medium (an inside-out mesh's: _carried_media)
            weight = _in_carried_medium(self.volumes, medium, surf, t, sample, weight, out.color, n)
        split = None  # the eye samples whose first catcher hit is in this batch (tracer.integrator.compose)
        cp = self.compose
        if depth == 0 and (cp.has_holdout or cp.has_catcher):
            weight = weight.copy()  # a holdout passes on only what goes through it
            split = np.zeros(n, np.bool_)
            compose.eye_path(surf, prim, inst, self.geometry.object_ids, self.instances.object_ids, d, sample,
                             weight, cp, self.env, self.options.background, out, out.compose, split)
            split = sample[split] if split.any() else None
        if depth == 0:
            _first_hits(surf, t, prim, inst, self.instances, t0, sample, self.geometry, out)
        _emitted(d, surf, sample, weight, depth, self.options, self.env, out)
        if self.links.any_seen:  # the lamps' shapes this batch's rays meet before their hits
            _lamps_seen(o, d, t, surf.hit, weight, sample, kind if kind is not None else np.zeros(n, np.uint8),
                        lamp if lamp is not None else np.ones(n, np.float32), self.lights, self.links.seen, out)
        shadow = ShadowQueue.empty(n * (self.light_samples + self.sky_side ** 2))
        before = out.color[split] if split is not None else None
        recv = linking.receiver_bits(self.links, prim, inst, self.geometry.object_ids, it.object_ids)
        n_shadow = _direct_light(surf, d, sample, weight, keys, depth, spawn, self.materials, self.lights,
                                 self.options, out, shadow, 0, counts, self.links, recv)
        if self.sky_side:
            n_shadow = _sky(surf, d, sample, weight, keys, depth, spawn, self.materials, self.env, self.options,
                            out, shadow, n_shadow, counts)
        nxt = NextQueue.empty(n, spawn)
        held = self._held()
        glass = held.get("glass")
        if glass is None or len(glass) < n:
            glass = held["glass"] = np.zeros((n, GLASS_COLUMNS), np.float64)
        glass = glass[:n]
        glass[:, 0] = 0.0
        n_refl, n_tran, n_through = _spawn_secondary(surf, d, t, t0, sample, weight, keys, depth, spawn,
                                                     self.materials, self.options, nxt, counts, glass,
                                                     int(self.settings.samples))
        if self.light_samples and self.lights_lamps:  # rough glass: its light samples of the lamps
            rows = np.flatnonzero(glass[:, 0] > 0.0)
            if len(rows):
                q = ShadowQueue.empty(len(rows) * self.light_samples)
                k = _glass_light(rows, surf, d, sample, weight, keys, depth, glass, self.lights, self.links.visible,
                                 self.links.recv_set, recv, self.options, out, q, counts)
                if k:
                    shadow = ShadowQueue(*(np.concatenate((a[:n_shadow], b[:k])) for a, b in zip(shadow, q)))
                    n_shadow += k
        feats = None
        if feature is not None and gd is not None and np.any(feature[:, 3] > 0):  # the denoising guides
            carry = np.empty((n, 3), np.float32)
            guide_stage.features(surf, d, sample, weight, feature, depth, self.materials, self.options, self.env, gd.cam,
                            gd.albedo, gd.normal, carry)
            feats = guide_stage.propagate(feature, carry, [
                (nxt.parent[:n_refl], nxt.weight[:n_refl]), (nxt.parent[n:n + n_tran], nxt.weight[n:n + n_tran]),
                (nxt.through_parent[:n_through], nxt.through_weight[:n_through])])
        shadow = ShadowQueue(*(a[:n_shadow] for a in shadow))
        caught = None  # the shadow rays of split hits (their catcher-only light is added with the occlusion)
        if split is not None:
            caught = self._catcher_rays(out, split, before, sample, shadow, nxt, n, n_refl, n_tran, n_through)
        media = None
        if self.carried is not None:
            media = _carried_media(self.carried, medium, surf, nxt, n, n_refl, n_tran, n_through)
            if medium is not None and len(shadow.o):
                _shadows_in_medium(self.volumes, medium, sample, shadow)
        return shadow, nxt, n_refl, n_tran, n_through, caught, feats, media

    def _catcher_rays(self, out, split, before, sample, shadow, nxt, n, n_refl, n_tran, n_through):
        """The catcher-only light of split hits that the stages added directly, and the world along the rays
        they spawned (tracer.integrator.compose); returns the mask of their shadow rays. Each eye sample has one ray per batch
        at depth 0, so a ray's sample names its hit."""
        mask = np.zeros(len(out.color), np.bool_)
        mask[split] = True
        compose.add_local(out.compose, out.color, before, split)
        bg = self.options.background
        for o_, d_, w_, s_, lo, hi in ((nxt.o, nxt.d, nxt.weight, nxt.sample, 0, n_refl),
                                       (nxt.o, nxt.d, nxt.weight, nxt.sample, n, n + n_tran),
                                       (nxt.through_o, nxt.through_d, nxt.through_weight, nxt.through_sample, 0,
                                        n_through)):
            rows = np.arange(lo, hi, dtype=np.int64)
            rows = rows[mask[s_[lo:hi]]]
            if len(rows):
                compose.add_world(out.compose, s_, w_, d_, rows, self.env, bg)
        return mask[shadow.sample]

    def step(self, depth: int, rays: "RayQueue", keys: np.ndarray, out: "Tile", counts: np.ndarray,
             gd: "Guides | None" = None) -> "Step":
        """One depth of Cast-Ray for a queue of rays: closest hits, shading (adding into ``out`` at each ray's
        sample), the deferred shadow rays and their occlusion, and the queue of next rays (reflections, then
        transmissions; empty past the last depth). Rays that pass through alpha < 1 surfaces are traced again
        within the step (up to ``max_transparent`` surfaces deep). With ``gd`` and ``rays.feature``, the denoising
        guides are written into ``gd`` and the next rays carry theirs (tracer/integrator/guides.py)."""
        n = len(rays.o)
        mask = rays.mask if depth else linking.ray_masks(self.links, 0, n, 0)
        time = rays.time
        hits = self.accel.closest_hits(rays.o, rays.d, rays.t_max, mask=mask, time=time, coherent=True)
        timed = time is not None
        if timed:  # every ray keeps its eye sample's time: looked up by sample
            sample_time = np.zeros(len(out.color), np.float32)
            sample_time[rays.sample] = time
        spawn = depth < self.last_depth
        shadows, refl, tran, caught = [], [], [], []
        o, d, w, smp, t0, h = rays.o, rays.d, rays.weight, rays.sample, np.zeros(n, np.float32), hits
        feat = rays.feature if gd is not None else None
        feats_refl, feats_tran = [], []
        kind = rays.kind if rays.kind is not None else np.zeros(n, np.uint8)
        lamp = rays.lamp if rays.lamp is not None else np.ones(n, np.float32)
        med = rays.medium
        med_refl, med_tran = [], []
        for layer in range(self.settings.max_transparent + 1):
            shadow, nxt, n_refl, n_tran, n_through, c, fs, media = self._shade(
                depth, o, d, w, smp, t0, h, keys, out, counts, spawn, time, feat, gd, kind, lamp, med)
            shadows.append(shadow)
            if media is not None:
                med_refl.append(media[0])
                med_tran.append(media[1])
                med = media[2]
            else:
                med_refl.append(np.full(n_refl, -1, np.int32))
                med_tran.append(np.full(n_tran, -1, np.int32))
                med = None
            if self.compose.has_catcher:
                caught.append(c if c is not None else np.zeros(len(shadow.o), np.bool_))
            m = len(o)
            refl.append((nxt, slice(0, n_refl)))
            tran.append((nxt, slice(m, m + n_tran)))
            if feat is not None:
                feats_refl.append(fs[0] if fs is not None else np.zeros((n_refl, 4), np.float32))
                feats_tran.append(fs[1] if fs is not None else np.zeros((n_tran, 4), np.float32))
                feat = fs[2] if fs is not None else np.zeros((n_through, 4), np.float32)
            if not n_through or layer == self.settings.max_transparent:
                break
            o, d = nxt.through_o[:n_through], nxt.through_d[:n_through]
            kind = kind[nxt.through_parent[:n_through]]  # a ray through alpha stays what it was
            lamp = lamp[nxt.through_parent[:n_through]]
            w, smp, t0 = nxt.through_weight[:n_through], nxt.through_sample[:n_through], nxt.through_t0[:n_through]
            tm = None
            if rays.t_max is not None:  # eye rays stop at the far plane: what is left of their length
                tm = np.maximum(rays.t_max[np.searchsorted(rays.sample, smp)] - t0, 0).astype(np.float32)
            time = sample_time[smp] if timed else None
            h = self.accel.closest_hits(o, d, tm, mask=linking.through_mask(self.links, depth), time=time,
                                        coherent=True)
        shadow = shadows[0] if len(shadows) == 1 else ShadowQueue(*(np.concatenate(c) for c in zip(*shadows)))
        blocked = np.zeros(0, bool)
        if len(shadow.o):
            shadow_time = sample_time[shadow.sample] if timed else None
            masks = linking.shadow_masks(self.links, shadow.light)
            if self.see_through and alpha.usable(self):  # see-through surfaces inside Embree's traversal
                blocked = alpha.occluded(self, shadow, masks, shadow_time)
            else:  # grouped by light, shadow rays from neighbouring points form coherent packets (sky rays do not)
                blocked = self.accel.occluded(shadow.o, shadow.d, shadow.t_max, mask=masks, time=shadow_time,
                                              coherent=not self.sky_side,
                                              order=_by_light(shadow.light, len(self.lights.kind)))
            if self.compose.has_catcher:
                self._catcher_light(out, shadow, np.concatenate(caught), blocked)
            if self.see_through and blocked.any() and not alpha.usable(self):
                blocked = self._through_shadows(shadow, blocked, shadow_time)
            _add_unoccluded(out.color, shadow.sample, shadow.color, blocked)
        parts = refl + tran
        cat = lambda get: np.concatenate([get(q)[s] for q, s in parts])  # noqa: E731
        n_reflected = sum(s.stop - s.start for _, s in refl)
        nxt = RayQueue(o=cat(lambda q: q.o), d=cat(lambda q: q.d), weight=cat(lambda q: q.weight),
                       sample=cat(lambda q: q.sample), t_max=None)
        kinds = np.full(len(nxt.o), RAY_TRANSMISSION, np.uint8)
        kinds[:n_reflected] = RAY_GLOSSY
        nxt = nxt._replace(mask=linking.ray_masks(self.links, depth + 1, len(nxt.o), n_reflected), kind=kinds,
                           lamp=cat(lambda q: q.lamp))
        if gd is not None and rays.feature is not None:
            nxt = nxt._replace(feature=np.concatenate(feats_refl + feats_tran))
        if self.carried is not None:
            media = np.concatenate(med_refl + med_tran).astype(np.int32)
            nxt = nxt._replace(medium=media if np.any(media >= 0) else None)
        if timed:
            nxt = nxt._replace(time=sample_time[nxt.sample])
        spawned = SpawnRecord(light=shadow.light[:0], normal=cat(lambda q: q.spawned.normal),
                              eta=cat(lambda q: q.spawned.eta), tir=cat(lambda q: q.spawned.tir))
        return Step(hits=hits, shadow=shadow, blocked=blocked, next=nxt, spawned=spawned, n_reflected=n_reflected)

    def _catcher_light(self, out, shadow: "ShadowQueue", caught: np.ndarray, blocked: np.ndarray) -> None:
        """The catcher-only light of the split hits' shadow rays: each counts unless a catcher blocks it (before
        transparent shadows scale the colours)."""
        rows = np.flatnonzero(caught)
        if not len(rows):
            return
        hit = blocked[rows].copy()
        if hit.any():
            b = rows[hit]
            hit[hit] = compose.catcher_blocked(self.accel, shadow.o[b], shadow.d[b], shadow.t_max[b], self.compose,
                                               self.geometry.object_ids, self.instances.object_ids,
                                               float(self.eps))
        free = rows[~hit]
        np.add.at(out.compose[:, compose.K0:compose.K0 + 3], shadow.sample[free], shadow.color[free])

    def _through_shadows(self, shadow: "ShadowQueue", blocked: np.ndarray, time=None) -> np.ndarray:
        """Blocked shadow rays whose blockers are alpha < 1 surfaces continue through them, their colour × (1 −
        alpha) each time (Cycles' transparent shadows), up to ``max_transparent`` surfaces."""
        idx = np.flatnonzero(blocked)
        o, d = shadow.o[idx].copy(), shadow.d[idx]
        t_max, color = shadow.t_max[idx].copy(), shadow.color  # colour scaled in place
        pending = np.ones(len(idx), np.bool_)
        masks = linking.shadow_masks(self.links, shadow.light[idx])
        for _ in range(self.settings.max_transparent + 1):
            sel = np.flatnonzero(pending)
            if not len(sel):
                break
            t, prim, u, v, inst = self.accel.closest_hits(o[sel], d[sel], t_max[sel],
                                                          mask=None if masks is None else masks[sel],
                                                          time=None if time is None else time[idx[sel]])
            g, pt, x, it = self.geometry, self.programs, self.textures, self.instances
            _pass_shadow(sel, idx, t, prim, inst, it.materials, it.normal_matrix, u, v, g.material_ids,
                         g.face_normals, self.materials.alpha, self.materials.alpha_threshold, o, d, t_max, color,
                         pending, blocked, self.options.eps, pt.code, pt.pstart, pt.pbase, pt.outs, pt.R0,
                         np.empty_like(pt.R0), g.uv_sets, g.colors, g.has_colors, g.vertices, g.triangles,
                         g.object_ids, self.spaces, x.data, x.params, it.linear, it.mirrored, it.object_ids,
                         pt.lobe_extra)
        return blocked

    def trace(self, origins: np.ndarray, directions: np.ndarray, keys: np.ndarray,
              cancelled=lambda: False, ray_types: bool = False, t_max: np.ndarray | None = None,
              times: np.ndarray | None = None, guides: bool = False) -> TileResult:
        """Trace eye rays (one per sample) to the maximum depth. ``keys`` are unique per sample (for the
        deterministic random streams); ``times`` each eye sample's time across the shutter (motion blur; None:
        none), kept by every ray of its path. With ``ray_types`` the result also holds each sample's colour split by the
        ray type it arrived through (:data:`PATH_TYPES`) and the depth of its deepest ray; with ``guides`` each
        sample's denoising albedo and normal (tracer/integrator/guides.py)."""
        s = self.scene
        n_samples = len(origins)
        # With ray_types, each eye sample owns PATH_TYPES slots and a path's contributions go to the slot of its
        # first secondary ray (as Cycles files light under the first bounce); the slots are summed at the end.
        k = len(PATH_TYPES) if ray_types else 1
        out = Tile(color=np.zeros((n_samples * k, 3), np.float32), alpha=np.ones(n_samples * k, np.float32),
                   depth=np.full(n_samples * k, np.inf, np.float32), normal=np.zeros((n_samples * k, 3), np.float32),
                   albedo=np.zeros((n_samples * k, 3), np.float32), object_id=np.full(n_samples * k, -1, np.int32),
                   compose=compose.empty(n_samples * k, self.compose.has_catcher))
        counts = np.zeros(5, np.int64)
        keys = np.ascontiguousarray(np.repeat(keys, k), np.int64)
        deepest = np.full(n_samples, -1, np.int32)
        gd = None
        if guides:
            gd = Guides(albedo=np.zeros((n_samples * k, 3), np.float32),
                        normal=np.zeros((n_samples * k, 3), np.float32), cam=guide_stage.camera_rows(s.camera))

        rays = RayQueue(o=np.ascontiguousarray(origins, np.float32), d=np.ascontiguousarray(directions, np.float32),
                        weight=np.ones((n_samples, 3), np.float32),
                        sample=np.arange(0, n_samples * k, k, dtype=np.int32),
                        t_max=(t_max if t_max is not None else  # per ray: the camera's clipping planes
                               np.full(n_samples, s.camera.far - s.camera.near, np.float32)
                               if np.isfinite(s.camera.far) else None),
                        time=None if times is None else np.ascontiguousarray(times, np.float32),
                        feature=np.ones((n_samples, 4), np.float32) if guides else None)
        for depth in range(self.last_depth + 1):
            if not len(rays.o) or cancelled():
                break
            if ray_types:
                np.maximum.at(deepest, rays.sample // k, depth)
            step = self.step(depth, rays, keys, out, counts, gd)
            rays = step.next
            if ray_types and depth == 0 and len(rays.o):  # the first secondary rays choose their path's slot
                first = np.where(np.arange(len(rays.o)) < step.n_reflected, _REFLECTION_PATH, _TRANSMISSION_PATH)
                rays = rays._replace(sample=(rays.sample + first).astype(np.int32))

        np.nan_to_num(out.color, copy=False, nan=0.0, posinf=0.0, neginf=0.0)
        np.clip(out.alpha, 0.0, 1.0, out=out.alpha)
        rc = RayCounts(eye=n_samples, shadow=int(counts[_N_SHADOW]), reflection=int(counts[_N_REFLECTION]),
                       transmission=int(counts[_N_TRANSMISSION]), sky=int(counts[_N_SKY]), tir=int(counts[_N_TIR]))
        by_type = out.color.reshape(n_samples, k, 3)
        slots = lambda a: a.reshape(n_samples, k, 3).sum(axis=1) if k > 1 else a  # noqa: E731
        return TileResult(guide_albedo=None if gd is None else slots(gd.albedo),
                          guide_normal=None if gd is None else slots(gd.normal),
                          color=by_type.sum(axis=1) if k > 1 else out.color, alpha=out.alpha[::k],
                          depth=out.depth[::k], normal=out.normal[::k], albedo=out.albedo[::k],
                          object_id=out.object_id[::k], counts=rc, by_type=by_type if k > 1 else None,
                          deepest=deepest if k > 1 else None,
                          compose=out.compose[::k] if self.compose.has_catcher else None,
                          compose_mode=(bool(self.settings.transparent), "shadow_catcher" not in self.settings.aovs))


# ---------------------------------------------------------------------------------------------- helpers
def _pack_volumes(vol, n_materials: int):
    """Scene.material_volumes as (n_materials, 6) float64 (σ ≥ 0, E ≥ 0), or None when no material has a medium."""
    if vol is None:
        return None
    vol = np.asarray(vol, np.float64)
    if vol.ndim != 2 or vol.shape[1] != 6:
        raise ValueError(f"scene.material_volumes must have shape (M, 6), got {vol.shape}")
    out = np.zeros((max(n_materials, len(vol)), 6))
    out[:len(vol)] = np.maximum(np.nan_to_num(vol, nan=0.0, posinf=0.0), 0.0)
    return out if out.any() else None


def _through_media(volumes, surf, t, sample, weight, color, n, carried=None):
    """Rays that hit the back face of an object whose material holds a medium (:attr:`Scene.material_volumes`)
    travelled the length t inside it: their weight × exp(−σ·t), and the medium's emission along that length,
    weight·E/σ·(1 − exp(−σ·t)) (E·t where σ = 0), added to their samples. Returns the new weights. Media the rays
    carry (``carried``: :func:`_in_carried_medium`) are not this rule's."""
    back = surf.hit[:n] & ~surf.front[:n]
    rows = np.flatnonzero(back)
    if not len(rows):
        return weight
    mats = surf.mat[rows]
    v = volumes[np.minimum(mats, len(volumes) - 1)]
    live = (mats < len(volumes)) & (v > 0).any(axis=1)
    if carried is not None:
        live &= ~carried[np.minimum(mats, len(carried) - 1)]
    rows, v = rows[live], v[live]
    if not len(rows):
        return weight
    tt = np.asarray(t, np.float64)[rows][:, None]
    sigma, em = v[:, :3], v[:, 3:]
    att = np.exp(-sigma * tt)
    glow = np.where(sigma > 0, em / np.maximum(sigma, 1e-30) * (1.0 - att), em * tt)
    w = np.asarray(weight, np.float64)[rows]
    np.add.at(color, sample[rows], (w * glow).astype(color.dtype))
    weight = weight.copy()
    weight[rows] = (w * att).astype(weight.dtype)
    return weight


def _segment(volumes, mats, tt, w):
    """Beer–Lambert with emission over lengths ``tt`` ((R, 1)) in the media of material rows ``mats``, for weights
    ``w`` ((R, 3) float64): (attenuated weights, emission added)."""
    v = volumes[mats]
    sigma, em = v[:, :3], v[:, 3:]
    att = np.exp(-sigma * tt)
    glow = np.where(sigma > 0, em / np.maximum(sigma, 1e-30) * (1.0 - att), em * tt)
    return w * att, w * glow


def _in_carried_medium(volumes, medium, surf, t, sample, weight, color, n):
    """Rays travelling in a carried medium (``medium`` ≥ 0) that hit something after t: weight × exp(−σ·t) and the
    medium's emission over t added, as :func:`_through_media`. A ray that leaves the scene in one is not changed:
    Cycles, measured through bpy (an inside-out cube's medium, a white world behind: 1.0; an emitting one, a black
    world: 0), integrates no medium over an infinite segment."""
    med = np.asarray(medium[:n])
    rows = np.flatnonzero((med >= 0) & surf.hit[:n])
    if not len(rows):
        return weight
    tt = np.asarray(t, np.float64)[rows][:, None]
    w, glow = _segment(volumes, med[rows], tt, np.asarray(weight, np.float64)[rows])
    np.add.at(color, sample[rows], glow.astype(color.dtype))
    weight = weight.copy()
    weight[rows] = w.astype(weight.dtype)
    return weight


def _carried_media(carried, medium, surf, nxt, n, n_refl, n_tran, n_through):
    """The carried medium of each spawned ray, as Cycles' volume stack (measured through bpy: an inside-out closed
    cube of Volume Absorption, seen from outside, attenuates the backdrop by exp(−σ·L) over the length L *behind*
    it, and leaves the inside clear; emission: + E·L): a reflected ray keeps its parent's medium; a ray that crosses
    a surface whose material's medium is carried (transmitted, or through alpha) enters it where it crossed the
    front face (against the face's winding normal: for an inside-out mesh, on the way out) and leaves it through a
    back face; other surfaces keep it. Returns (reflections, transmissions, pass-through rays) int32 arrays."""
    med = np.full(n, -1, np.int32) if medium is None else np.asarray(medium[:n], np.int32)
    mats = surf.mat[:n]
    crossed = med.copy()
    hit = surf.hit[:n]
    here = hit & carried[np.clip(mats, 0, len(carried) - 1)] & (mats >= 0) & (mats < len(carried))
    crossed[here & surf.front[:n]] = mats[here & surf.front[:n]]
    crossed[here & ~surf.front[:n]] = -1
    refl = med[nxt.parent[:n_refl]]
    tran = crossed[nxt.parent[n:n + n_tran]] if n_tran else np.zeros(0, np.int32)
    through = crossed[nxt.through_parent[:n_through]]
    return refl, tran, through


def _shadows_in_medium(volumes, medium, sample, shadow):
    """Shadow rays that start in a carried medium: colour × exp(−σ·length) (Cycles' shadow rays are attenuated by
    the volumes they are in, and gather no emission). A shadow ray is matched to its hit's medium by its eye
    sample: where one sample's rays of this batch are in different media, none of its shadow rays is attenuated."""
    n = len(medium)
    med = np.asarray(medium, np.int32)
    if not np.any(med >= 0):
        return
    top = int(max(sample[:n].max(), shadow.sample.max())) + 1
    lo = np.full(top, np.iinfo(np.int32).max, np.int64)
    hi = np.full(top, -2, np.int64)
    np.minimum.at(lo, sample[:n], med)
    np.maximum.at(hi, sample[:n], med)
    one = np.where(lo == hi, hi, -1)
    sm = one[shadow.sample]
    rows = np.flatnonzero(sm >= 0)
    if not len(rows):
        return
    tt = np.asarray(shadow.t_max, np.float64)[rows][:, None]
    tt = np.where(np.isfinite(tt), tt, 0.0)
    w, _ = _segment(volumes, sm[rows], tt, np.asarray(shadow.color, np.float64)[rows])
    shadow.color[rows] = w.astype(shadow.color.dtype)


@kernel(inline=True)
def spawn_ray(p, ng, direction, eps):
    """The origin of a ray leaving surface point p along ``direction``: p moved ε along the geometric normal ng, to
    the side the ray leaves to (the seed's ε; the one place it is applied)."""
    if vec.dot(ng, direction) >= 0.0:
        return vec.madd(p, ng, eps)
    return vec.madd(p, ng, -eps)


@kernel(inline=True)
def shadow_ray(p, ng, l, dist, eps):
    """The shadow ray from surface point p towards a light sample at distance ``dist`` along l (inf: a direction):
    (origin, unit direction, length). It leaves through :func:`spawn_ray` and aims at the sample from there, stopping
    ε short of it: aimed along l from the lifted origin instead, a ray that meets an emitting surface at a grazing
    angle would pass ε·(ng·l)-ish beyond the sample's plane and hit the emitter itself (a floor far from an emissive
    panel went black)."""
    o = spawn_ray(p, ng, l, eps)
    if not math.isfinite(dist):
        return o, l, dist
    to = vec.sub(vec.madd(p, l, dist), o)
    length = vec.length(to)
    return o, vec.scale(to, 1.0 / max(length, 1e-30)), length - eps


@kernel(inline=True)
def _put(qo, qd, qt, qs, qc, ql, j, origin, direction, length, s, c, light):
    """Row j of a :class:`ShadowQueue` (its arrays, passed one by one: a NamedTuple handed to an inlined helper
    costs numba's reference counting on each of its arrays per call)."""
    qo[j, 0], qo[j, 1], qo[j, 2] = origin
    qd[j, 0], qd[j, 1], qd[j, 2] = direction
    qt[j] = length
    qs[j] = s
    qc[j, 0], qc[j, 1], qc[j, 2] = c
    ql[j] = light


@kernel(inline=True)
def _put_ray(no, nd, nw, ns, j, origin, direction, w, s):
    no[j, 0], no[j, 1], no[j, 2] = origin
    nd[j, 0], nd[j, 1], nd[j, 2] = direction
    nw[j, 0], nw[j, 1], nw[j, 2] = w
    ns[j] = s


@kernel(inline=True)
def _put_spawn(rec_n, rec_eta, rec_tir, j, n, eta_i, eta_r, tir):
    """What a spawned ray's direction was computed from (for ``tracer.explain``): the unit normal on the incident
    side, the two refractive indices and whether total internal reflection turned a transmission into it (the
    arrays of a :class:`SpawnRecord`)."""
    rec_n[j, 0], rec_n[j, 1], rec_n[j, 2] = n
    rec_eta[j, 0], rec_eta[j, 1] = eta_i, eta_r
    rec_tir[j] = tir


@kernel(inline=True)
def _local_model(principled, base, m, rough, spec, tint, ior, w_t, k_m, cover, spec_color, exponent, n, d, spawn):
    """The local model at a hit seen along d: (closure, the weight its light is added with, the mirror share g of
    the specular lobes). Principled: weight (1 − k_m)·alpha, the closure holds the metal, dielectric and diffuse
    weights; classic: weight (1 − k_m)(1 − w_t)·alpha, R_d = base·(1 − m), R_s = specular_color·(1 − m) + base·m.
    (Plain values only: a call with the scene's NamedTuples of arrays costs reference counting on each array.)"""
    zero = (0.0, 0.0, 0.0)
    if principled:
        wl = (1.0 - k_m) * cover
        if wl <= 0.0 or (m <= 0.0 and w_t >= 1.0):  # a pure mirror or clear glass: no local light (no lookups)
            return bsdf.classic(zero, zero, 1.0), 0.0, 0.0
        cl = bsdf.principled(base, m, rough, spec, tint, ior, w_t, -vec.dot(n, d))
        g = bsdf.mirror_share(rough) if spawn else 0.0
        return cl, wl, g
    wl = (1.0 - k_m) * (1.0 - w_t) * cover
    if wl <= 0.0:
        return bsdf.classic(zero, zero, 1.0), 0.0, 0.0
    rs = vec.madd(vec.scale(spec_color, 1.0 - m), base, m)
    cl = bsdf.classic(vec.scale(base, 1.0 - m), rs, exponent)
    return cl, wl, 0.0


# ---------------------------------------------------------------------------------------------- stages
@kernel(inline=True)
def _lobes_at(surf, mats, i, n, di, spawn):
    """The lobes (:func:`tracer.shading.lobes.setup`) of hit i of a :class:`SurfaceQueue` whose closure is a sum of lobes,
    and the weight their light is added with (1 − k_m)."""
    mat = surf.mat[i]
    lb = lobes.setup(surf.lobe_kind, surf.lobe_w, surf.lobe_base, surf.lobe_param, i, surf.lobes[i], n, di,
                     vec.row(mats.specular_tint, mat), float(mats.ior[mat]), spawn, vec.row(surf.aniso, i))
    return lb, 1.0 - float(mats.k_m[mat])


@kernel(inline=True)
def _closure_at(surf, mats, i, n, di, principled, spawn):
    """:func:`_local_model` at hit i of a :class:`SurfaceQueue` seen along di, shading normal n (the direct-light and
    sky stages; kernels without reference counting may hand it the NamedTuples)."""
    mat = surf.mat[i]
    cl, wl, g = _local_model(principled, vec.row(surf.base, i), float(surf.metallic[i]), float(surf.roughness[i]),
                             float(surf.specular[i]), vec.row(mats.specular_tint, mat), float(mats.ior[mat]),
                             float(surf.transmission[i]), float(mats.k_m[mat]), float(surf.cover[i]),
                             vec.row(mats.specular_color, mat), float(mats.exponent[mat]), n, di, spawn)
    return bsdf.anisotropic(cl, vec.row(surf.aniso, i), n), wl, g


@kernel(refcounts=False)
def _surfaces(o, d, t, prim, inst, normal_matrix, overrides, u, v, geom, mats, surf):
    """Surfaces stage: per ray, the hit point, its frames and the material's constant parameters (× vertex
    colours); the rays whose material has a program are listed for the textures stage. Returns how many.
    A hit on an instance (``inst`` ≥ 0) finds its frame in object space and takes it to world space by the
    instance's normal matrix (:func:`tracer.geometry.instances.world_frame`), and shades with its material override.
    (The NamedTuples' fields are read into locals before the loop: a field read inside it can cost numba's
    reference counting per ray.)"""
    material_ids = geom.material_ids
    face_normals, normals, corner_ok, has_normals = geom.face_normals, geom.normals, geom.corner_ok, geom.has_normals
    triangles, per_vertex = geom.triangles, geom.normals_per_vertex
    colors, has_colors = geom.colors, geom.has_colors
    diffuse, roughness, metallic, specular = mats.diffuse, mats.roughness, mats.metallic, mats.specular
    alphas, emission, threshold, textured = mats.alpha, mats.emission, mats.alpha_threshold, mats.textured
    vertex_color = mats.vertex_color
    s_hit, s_p, s_ng, s_n, s_front, s_mat = surf.hit, surf.p, surf.ng, surf.n, surf.front, surf.mat
    s_base, s_rough, s_metal, s_spec, s_cover, s_e = (surf.base, surf.roughness, surf.metallic, surf.specular,
                                                       surf.cover, surf.emission)
    s_textured, s_tran, transmission = surf.textured, surf.transmission, mats.transmission
    n_textured = 0
    for i in range(o.shape[0]):
        tri = prim[i]
        s_hit[i] = tri >= 0
        if tri < 0:
            continue
        di = vec.row(d, i)
        ui, vi = float(u[i]), float(v[i])
        p = vec.madd(vec.row(o, i), di, float(t[i]))
        k = inst[i]
        mat = material_ids[tri]
        smooth = has_normals and corner_ok[tri]
        c = tri if smooth else 0  # the corner normals' triangle (read either way: no branch around array reads)
        fn = (float(face_normals[tri, 0]), float(face_normals[tri, 1]), float(face_normals[tri, 2]))
        n0, n1, n2 = corner_normals(normals, triangles, per_vertex and smooth, c)
        if k < 0:
            ng, n, front = shading_frame(fn, smooth, n0, n1, n2, di, ui, vi)
        else:  # an instance: the frame in object space (M⁻¹·d keeps the side), normals to world by (M)⁻ᵀ
            ng_o, n_o, front = shading_frame(fn, smooth, n0, n1, n2, mat3_apply_transposed(normal_matrix, k, di),
                                             ui, vi)
            ng = vec.normalize(mat3_apply(normal_matrix, k, ng_o))
            n = vec.normalize(mat3_apply(normal_matrix, k, n_o))
            if vec.dot(n, ng) <= 0.0:
                n = ng
            if overrides[k] >= 0:
                mat = overrides[k]
        base = vec.row(diffuse, mat)
        if vertex_color[mat]:
            base = vec.mul(base, color_at(colors, has_colors, tri, ui, vi))
        if textured[mat]:
            s_textured[n_textured] = i
            n_textured += 1
        s_p[i, 0], s_p[i, 1], s_p[i, 2] = p
        s_ng[i, 0], s_ng[i, 1], s_ng[i, 2] = ng
        s_n[i, 0], s_n[i, 1], s_n[i, 2] = n
        s_front[i] = front
        s_mat[i] = mat
        s_base[i, 0], s_base[i, 1], s_base[i, 2] = base
        s_rough[i] = min(max(float(roughness[mat]), 0.0), 1.0)
        s_metal[i] = min(max(float(metallic[mat]), 0.0), 1.0)
        s_spec[i] = max(float(specular[mat]), 0.0)
        s_cover[i] = _cut(float(alphas[mat]), float(threshold[mat]))
        s_e[i, 0], s_e[i, 1], s_e[i, 2] = emission[mat, 0], emission[mat, 1], emission[mat, 2]
        s_tran[i] = transmission[mat]
    return n_textured


@kernel(refcounts=False)
def _first_hits(surf, t, prim, inst, itab, t0, sample, geom, out):
    """First-hit stage (depth 0): depth, normal, albedo and object id of the first surface each eye sample sees
    (surfaces cut away by alpha are looked through)."""
    s_hit, s_cover, s_n, s_base = surf.hit, surf.cover, surf.n, surf.base
    o_depth, o_normal, o_albedo, o_id = out.depth, out.normal, out.albedo, out.object_id
    inst_ids, tri_ids = itab.object_ids, geom.object_ids
    for i in range(s_hit.shape[0]):
        s = sample[i]
        if not s_hit[i] or s_cover[i] <= 0.0 or o_id[s] >= 0:
            continue
        o_depth[s] = t[i] + t0[i]
        o_normal[s, 0], o_normal[s, 1], o_normal[s, 2] = s_n[i, 0], s_n[i, 1], s_n[i, 2]
        o_albedo[s, 0], o_albedo[s, 1], o_albedo[s, 2] = s_base[i, 0], s_base[i, 1], s_base[i, 2]
        k = inst[i]
        o_id[s] = tri_ids[prim[i]] if k < 0 else inst_ids[k]


@kernel(refcounts=False)
def _emitted(d, surf, sample, weight, depth, opt, env, out):
    """Emitted stage: what each ray sees itself — the environment (or background) where it leaves the scene (a
    transparent film clears alpha instead, for rays from the eye), the surface's emission × alpha where it hits."""
    s_hit, s_cover, s_e = surf.hit, surf.cover, surf.emission
    o_color, o_alpha = out.color, out.alpha
    env_present, env_data, env_rot = env.present, env.data, env.rot
    clear_alpha = depth == 0 and opt.transparent
    bg = (opt.background[0], opt.background[1], opt.background[2])
    for i in range(s_hit.shape[0]):
        s = sample[i]
        w = vec.row(weight, i)
        if not s_hit[i]:
            if clear_alpha:
                o_alpha[s] -= (w[0] + w[1] + w[2]) / 3.0
                continue
            sky = env_radiance(env_data, env_rot, vec.row(d, i)) if env_present else bg
            for c in range(3):
                o_color[s, c] += w[c] * sky[c]
            continue
        a = s_cover[i]
        if a > 0.0:
            for c in range(3):
                o_color[s, c] += w[c] * a * s_e[i, c]


@kernel(refcounts=False)
def _lamps_seen(o, d, t, hit, weight, sample, kind, lamp, lights, seen, out):
    """Lamps stage: the shapes of the lights (area lights, spheres of point and spot lights with a radius, suns
    with an angle: tracer.lights.emitters.lamp_hit) each ray meets before its hit, as Cycles shows them in mirrors,
    through glass and (when a light's camera visibility is on) to the camera. ``kind`` (per ray) picks the column
    of ``seen`` (Links.seen: the light's factor for camera, glossy, transmission rays; 0: that ray does not see
    it; ``lamp`` (per ray) the share of its weight that sees lamps). Lights do not block each other here: a ray adds
    every lamp before its hit (Cycles shows the nearest)."""
    o_color = out.color
    n_lights = seen.shape[0]
    for i in range(o.shape[0]):
        k = kind[i]
        share = lamp[i]
        if share <= 0.0:
            continue
        t_max = t[i] if hit[i] else math.inf
        oi, di = vec.row(o, i), vec.row(d, i)
        s = sample[i]
        for j in range(n_lights):
            f = seen[j, k] * share
            if f <= 0.0:
                continue
            tl, le = lamp_hit(lights, j, oi, di, t_max)
            if tl < t_max:
                for c in range(3):
                    o_color[s, c] += weight[i, c] * f * le[c]


@kernel(refcounts=False)
def _direct_light(surf, d, sample, weight, keys, depth, spawn, mats, lights, opt, out, shadow, n_shadow, counts,
                  links, recv):
    """Direct-light stage: per hit, every light sample's colour (local model × irradiance), written with its shadow
    ray (p, l, ε, dist) to the shadow queue; and the ambient term where the sky is not sampled. Returns the
    shadow queue's new length. Past max_depth (terminal rays) nothing is lit. Light linking (tracer.lights.linking): light j
    skips a hit whose receiver bits ``recv`` (empty: no linking) lack its set, and gives only the diffuse / glossy
    light it is visible to. (Compiled without reference counting,
    ``kernel(refcounts=False)``: with it, numba's atomic counts on the arrays of the NamedTuples read and handed on
    per ray and per light sample cost 40 % of this stage.)"""
    if depth > opt.max_depth:
        return n_shadow
    eps = opt.eps
    principled, shadows, sky_side, seed = opt.principled, opt.shadows, opt.sky_side, opt.seed
    needs_random = opt.needs_light_random
    s_hit, s_p, s_ng, s_n, s_ns = surf.hit, surf.p, surf.ng, surf.n, surf.ns
    l_kind, l_side = lights.kind, lights.side
    q_o, q_d, q_t, q_s, q_c, q_l = shadow.o, shadow.d, shadow.t_max, shadow.sample, shadow.color, shadow.light
    o_color = out.color
    s_mirror, s_mlamp = surf.mirror, surf.mirror_lamp
    n_lights = l_kind.shape[0]
    linked = recv.shape[0] > 0
    l_recv, l_diffuse, l_glossy, l_seen = links.recv_set, links.diffuse, links.glossy, links.seen
    amb = (opt.ambient[0], opt.ambient[1], opt.ambient[2])
    add_ambient = (amb[0] > 0.0 or amb[1] > 0.0 or amb[2] > 0.0) and sky_side == 0
    s_nl = surf.lobes
    n_new = 0
    for i in range(s_hit.shape[0]):
        if not s_hit[i]:
            continue
        s = sample[i]
        n, di = vec.row(s_n, i), vec.row(d, i)
        ns = vec.row(s_ns, i)
        if principled and s_nl[i] >= 0:  # a sum of lobes (tracer.shading.lobes): its own loop, off the one-closure path
            n_shadow, k_new = _lobe_light(surf, d, i, s, weight, keys, depth, spawn, mats, lights, opt, out, shadow,
                                          n_shadow, links, recv)
            n_new += k_new
            continue
        cl, wl, g = _closure_at(surf, mats, i, n, di, principled, spawn)
        gl = 0.0
        if g > 0.0:  # what the spawn stage's mirror ray takes of the lobes (zeros where there is no closure)
            s_mirror[i, 0], s_mirror[i, 1], s_mirror[i, 2] = vec.scale(bsdf.specular_albedo(cl), g)
            gl = bsdf.lamp_share(cl, g)  # ... and of them, for the lamps it sees
            s_mlamp[i, 0], s_mlamp[i, 1], s_mlamp[i, 2] = vec.scale(bsdf.specular_albedo(cl), gl)
        if wl <= 0.0 or bsdf.is_black(cl):
            continue
        wo = vec.scale(vec.row(weight, i), wl)
        p = (s_p[i, 0], s_p[i, 1], s_p[i, 2])
        ng = vec.row(s_ng, i)
        wi = vec.scale(di, -1.0)
        if add_ambient:  # the notes' ambient term R_a·L_a (and the lobes' albedo × L_a)
            c = shading.ambient(cl.diffuse, amb)
            if principled:
                c = vec.add(c, vec.scale(vec.mul(bsdf.specular_albedo(cl), amb), 1.0 - g))
            for ch in range(3):
                o_color[s, ch] += wo[ch] * c[ch]
        r0, r1 = 0.0, 0.0
        if needs_random:
            r0, r1 = uniform2_1(keys[s], _STREAM_LIGHT + depth, seed)
        for j in range(n_lights):
            if linked and not linking.lights_receiver(l_recv[j], recv[i]):
                continue
            # a light the mirror ray can see (emissive triangles; a lamp's shape, for the nearly smooth lobes) gives
            # the mirror share of the lobes to that ray
            spec_scale = (1.0 - g if l_kind[j] == MESH else 1.0 - gl if l_seen[j, 1] > 0.0 else 1.0) * l_glossy[j]
            for k in range(l_side[j] * l_side[j]):
                l, dist, e = sample_light(lights, j, k, p, r0, r1)
                n_l = vec.dot(n, l)
                if n_l <= 0.0 or vec.dot(ng, l) <= 0.0:
                    continue
                valid, bump_d = bsdf.bump_shadowing(ns, n, l)
                if valid == 0.0:
                    continue
                f = bsdf.evaluate(cl, n, wi, l, n_l, spec_scale)
                dif = l_diffuse[j] * bump_d
                if dif != 1.0:  # the light's diffuse factor (the BSDF at spec_scale 0 is its diffuse part)
                    f = vec.sub(f, vec.scale(bsdf.evaluate(cl, n, wi, l, n_l, 0.0), 1.0 - dif))
                c = vec.mul(wo, vec.mul(f, e))
                if shadows:  # the shadow ray from p to the light sample: counts only if nothing is in between
                    so, sd, st = shadow_ray(p, ng, l, dist, eps)
                    _put(q_o, q_d, q_t, q_s, q_c, q_l, n_shadow, so, sd, st, s, c, j)
                    n_shadow += 1
                    n_new += 1
                else:
                    for ch in range(3):
                        o_color[s, ch] += c[ch]
    counts[_N_SHADOW] += n_new
    return n_shadow


@kernel(refcounts=False)
def _lobe_light(surf, d, i, s, weight, keys, depth, spawn, mats, lights, opt, out, shadow, n_shadow, links, recv):
    """:func:`_direct_light` at hit i whose closure is a sum of lobes (``SurfaceQueue.lobes`` ≥ 0): Σ wᵢ·fᵢ per
    light sample (:func:`tracer.shading.lobes.evaluate`; one shadow ray per sample, lights behind the surface too where it
    has translucent lobes), the lobes' mirror share for the spawn stage, their ambient term. Returns (the shadow
    queue's new length, shadow rays added). (Its own kernel, so that the one-closure loop stays as it was.)"""
    eps = opt.eps
    amb = (opt.ambient[0], opt.ambient[1], opt.ambient[2])
    add_ambient = (amb[0] > 0.0 or amb[1] > 0.0 or amb[2] > 0.0) and opt.sky_side == 0
    q_o, q_d, q_t, q_s, q_c, q_l = shadow.o, shadow.d, shadow.t_max, shadow.sample, shadow.color, shadow.light
    l_kind, l_side = lights.kind, lights.side
    l_recv, l_diffuse, l_glossy = links.recv_set, links.diffuse, links.glossy
    linked = recv.shape[0] > 0
    o_color, s_mirror = out.color, surf.mirror
    n, di = vec.row(surf.n, i), vec.row(d, i)
    ns = vec.row(surf.ns, i)
    lb, wl = _lobes_at(surf, mats, i, n, di, spawn)
    s_mirror[i, 0], s_mirror[i, 1], s_mirror[i, 2] = lobes.mirror_weight(lb)
    s_ml = surf.mirror_lamp
    s_ml[i, 0], s_ml[i, 1], s_ml[i, 2] = lobes.mirror_lamp_weight(lb)
    if wl <= 0.0 or lobes.is_black(lb):
        return n_shadow, 0
    back = vec.max3(lb.translucent) > 0.0  # lights behind the surface reach its translucent lobes
    wo = vec.scale(vec.row(weight, i), wl)
    p = (surf.p[i, 0], surf.p[i, 1], surf.p[i, 2])
    ng = vec.row(surf.ng, i)
    wi = vec.scale(di, -1.0)
    if add_ambient:
        c = lobes.ambient(lb, amb)
        for ch in range(3):
            o_color[s, ch] += wo[ch] * c[ch]
    r0, r1 = 0.0, 0.0
    if opt.needs_light_random:
        r0, r1 = uniform2_1(keys[s], _STREAM_LIGHT + depth, opt.seed)
    n_new = 0
    for j in range(l_kind.shape[0]):
        if linked and not linking.lights_receiver(l_recv[j], recv[i]):
            continue
        mesh = 1 if l_kind[j] == MESH else 2 if links.seen[j, 1] > 0.0 else 0  # the mirror ray sees it
        for k in range(l_side[j] * l_side[j]):
            l, dist, e = sample_light(lights, j, k, p, r0, r1)
            n_l = vec.dot(n, l)
            n_g = vec.dot(ng, l)
            if not ((n_l > 0.0 and n_g > 0.0) or (back and n_l < 0.0 and n_g < 0.0)):
                continue
            valid, bump_d = bsdf.bump_shadowing(ns, n, l)
            if valid == 0.0:
                continue
            c = vec.mul(wo, vec.mul(lobes.evaluate(lb, n, wi, l, n_l, mesh, l_glossy[j], l_diffuse[j] * bump_d), e))
            if opt.shadows:
                so, sd, st = shadow_ray(p, ng, l, dist, eps)
                _put(q_o, q_d, q_t, q_s, q_c, q_l, n_shadow, so, sd, st, s, c, j)
                n_shadow += 1
                n_new += 1
            else:
                for ch in range(3):
                    o_color[s, ch] += c[ch]
    return n_shadow, n_new


@kernel(refcounts=False)
def _sky(surf, d, sample, weight, keys, depth, spawn, mats, env, opt, out, shadow, n_shadow, counts):
    """Sky stage: the world as a light (tracer/lights/sky.py), deferred like shadow rays — an environment by rays drawn
    from its luminance CDF and cosine-weighted (one-sample MIS, local model × radiance / mixture pdf), a constant
    world by cosine-weighted rays that each carry the ambient term; fewer rays at deeper hits that carry less weight.
    Returns the shadow queue's new length."""
    if depth > opt.max_depth:
        return n_shadow
    eps = opt.eps
    principled, seed = opt.principled, opt.seed
    side = opt.sky_side
    amb = (opt.ambient[0], opt.ambient[1], opt.ambient[2])
    has_amb = amb[0] > 0.0 or amb[1] > 0.0 or amb[2] > 0.0
    s_hit, s_p, s_ng, s_n, s_ns = surf.hit, surf.p, surf.ng, surf.n, surf.ns
    env_present, e_data, e_rot, e_rcdf, e_ccdf, e_rpdf, e_cpdf = (env.present, env.data, env.rot, env.row_cdf,
                                                                 env.col_cdf, env.row_pdf, env.col_pdf)
    q_o, q_d, q_t, q_s, q_c, q_l = shadow.o, shadow.d, shadow.t_max, shadow.sample, shadow.color, shadow.light
    o_color = out.color
    n_new = 0
    no_lobes = lobes.none()
    for i in range(s_hit.shape[0]):
        if not s_hit[i]:
            continue
        s = sample[i]
        n, di = vec.row(s_n, i), vec.row(d, i)
        ns = vec.row(s_ns, i)
        cl, wl, g = _closure_at(surf, mats, i, n, di, principled, spawn)
        lb = no_lobes
        nl = surf.lobes[i] if principled else -1
        if nl >= 0:  # a sum of lobes: the sky lights each lobe (as the direct-light stage does), not the blend
            lb, wl = _lobes_at(surf, mats, i, n, di, spawn)
            if wl <= 0.0 or lobes.is_black(lb):
                continue
            diffuse = lobes.diffuse_albedo(lb)
            spec_ambient = lobes.specular_ambient(lb)
        else:
            if wl <= 0.0 or bsdf.is_black(cl):
                continue
            diffuse = cl.diffuse
            spec_ambient = vec.scale(bsdf.specular_albedo(cl), 1.0 - g)
        w_ray = vec.row(weight, i)
        wo = vec.scale(w_ray, wl)
        p = (s_p[i, 0], s_p[i, 1], s_p[i, 2])
        ng = vec.row(s_ng, i)
        wi = vec.scale(di, -1.0)
        r0, r1 = uniform2_1(keys[s], _STREAM_SKY + depth, seed)
        sd = sky.side_at(depth, side, vec.max3(w_ray))
        kk = sd * sd
        tu, tv = vec.orthonormal_basis(n)
        if env_present:  # the mirror ray sees the environment: its share of the lobes is left to it
            for k in range(kk):
                s0, s1 = rotated_multijitter(k, sd, r0, r1)
                dr, pdf = sky.env_direction(e_data, e_rot, e_rcdf, e_ccdf, e_rpdf, e_cpdf, n, tu, tv, s0, s1)
                n_l = vec.dot(n, dr)
                if n_l <= 0.0 or vec.dot(ng, dr) <= 0.0 or pdf <= 0.0:
                    continue
                valid, bump_d = bsdf.bump_shadowing(ns, n, dr)
                if valid == 0.0:
                    continue
                if nl >= 0:  # each lobe's specular part less its mirror share g_i (the mirror ray sees the sky)
                    f = lobes.evaluate(lb, n, wi, dr, n_l, 1, 1.0, bump_d)
                else:
                    f = bsdf.evaluate(cl, n, wi, dr, n_l, 1.0 - g)
                    if bump_d != 1.0:  # the diffuse part (the BSDF at spec_scale 0) under the bump's shadowing
                        f = vec.sub(f, vec.scale(bsdf.evaluate(cl, n, wi, dr, n_l, 0.0), 1.0 - bump_d))
                c = vec.scale(vec.mul(wo, vec.mul(f, env_radiance(e_data, e_rot, dr))), 1.0 / (pdf * kk))
                _put(q_o, q_d, q_t, q_s, q_c, q_l, n_shadow, spawn_ray(p, ng, dr, eps), dr, np.inf, s, c, -1)
                n_shadow += 1
                n_new += 1
            continue
        if not has_amb:
            continue
        if principled:  # the lobes' share of the uniform sky, unshadowed
            c = vec.mul(spec_ambient, amb)
            for ch in range(3):
                o_color[s, ch] += wo[ch] * c[ch]
        c = vec.scale(vec.mul(wo, shading.ambient(diffuse, amb)), 1.0 / kk)
        for k in range(kk):
            s0, s1 = rotated_multijitter(k, sd, r0, r1)
            dr = sky.cosine_direction(n, tu, tv, s0, s1)
            valid, bump_d = bsdf.bump_shadowing(ns, n, dr)
            _put(q_o, q_d, q_t, q_s, q_c, q_l, n_shadow, spawn_ray(p, ng, dr, eps), dr, np.inf, s,
                 vec.scale(c, valid * bump_d), -1)
            n_shadow += 1
        n_new += kk
    counts[_N_SKY] += n_new
    return n_shadow


@kernel(inline=True)
def _glass_random(key, depth, side, seed):
    """The (u1, u2) of a rough-glass hit's microfacet normal. At the first hit (depth 0) a pixel's side² eye samples
    (key = pixel·side² + sample, :func:`tracer.integrator.tiles.pixel_sample`) take the side² points of one
    multi-jittered pattern turned per pixel (:func:`tracer.sampling.rotated_multijitter`), in an order decorrelated
    from their film strata and lens cells: they meet nearly one point of the glass from nearly one direction, and
    stratified microfacet normals spread their rays over the lobe evenly (each point stays uniform: unbiased).
    Deeper hits, where the samples' paths have parted, take the sample's own random pair."""
    nn = side * side
    if depth > 0 or nn <= 1:
        return uniform2_1(key, _STREAM_GLASS + depth, seed)
    r0, r1 = uniform2_1((key // nn) & 0xFFFFFFFF, _STREAM_GLASS, seed)
    k = (nn * 3) // 8 + 1
    while math.gcd(k, nn) != 1:
        k += 1
    return rotated_multijitter(((key % nn) * k) % nn, side, r0, r1)


@kernel(refcounts=False)
def _spawn_secondary(surf, d, t, t0, sample, weight, keys, depth, spawn, mats, opt, nxt, counts, g_rec, side):
    """Spawn stage: per hit, the reflected ray (k_m·mirror_tint + the Principled lobes' mirror share + glass·F),
    the transmitted ray (glass·(1 − F)) and, where alpha < 1, the ray that passes straight through (weight
    1 − alpha, same depth). A sum of lobes (``SurfaceQueue.lobes`` ≥ 0) gives its mirror share, its glass and
    refraction weights (:func:`tracer.shading.lobes.refraction_weights`) and its pass-through colour instead. Returns
    (reflections, transmissions, pass-through rays) written.

    Rough glass (roughness r with α² = r⁴ above bsdf.SINGULAR_ALPHA2; Principled models only): the glass's
    reflected and refracted rays are mirrored and refracted about one GGX microfacet normal drawn from the
    visible normals with the eye sample's key (stream _STREAM_GLASS + depth) and weighted by
    :func:`tracer.optics.rough_dielectric`; where a smooth mirror part also reflects, the one reflected ray is
    either (chosen by their weights' sums, divided by the choice's probability). Lamps: the sampled rays see the
    lamps' shapes with :func:`tracer.shading.bsdf.lamp_share_of` the roughness (nearly smooth glass); the rest of
    the lamps' light is the light samples of :func:`_glass_light`, for which each such hit's interface is written
    to row i of ``g_rec`` (:data:`GLASS_COLUMNS`; column 0, α, stays 0 elsewhere)."""
    n_rays = surf.hit.shape[0]
    eps = opt.eps
    n_refl = 0
    n_tran = 0
    n_through = 0
    rec_n, rec_eta, rec_tir = nxt.spawned.normal, nxt.spawned.eta, nxt.spawned.tir
    n_o, n_d, n_w, n_s = nxt.o, nxt.d, nxt.weight, nxt.sample
    th_o, th_d, th_w, th_s, th_t0 = (nxt.through_o, nxt.through_d, nxt.through_weight, nxt.through_sample,
                                     nxt.through_t0)
    n_par, th_par, n_lamp = nxt.parent, nxt.through_parent, nxt.lamp
    s_mlamp = surf.mirror_lamp
    s_hit, s_mat, s_base, s_metal, s_rough, s_cover, s_p, s_ng, s_n, s_front, s_mirror = (
        surf.hit, surf.mat, surf.base, surf.metallic, surf.roughness, surf.cover, surf.p, surf.ng, surf.n,
        surf.front, surf.mirror)
    m_ior, s_tran, m_km, m_mirror, m_ttint = (mats.ior, surf.transmission, mats.k_m, mats.mirror_tint,
                                              mats.transmission_tint)
    s_nl, s_lk, s_lw, s_lb, s_lp, s_through, m_stint = (surf.lobes, surf.lobe_kind, surf.lobe_w, surf.lobe_base,
                                                        surf.lobe_param, surf.through, mats.specular_tint)
    principled, fresnel, min_weight = opt.principled, opt.fresnel, opt.min_weight
    n_tir = 0
    for i in range(n_rays):
        if not s_hit[i]:
            continue
        s = sample[i]
        w = vec.row(weight, i)
        di = vec.row(d, i)
        p = (s_p[i, 0], s_p[i, 1], s_p[i, 2])
        ng, n = vec.row(s_ng, i), vec.row(s_n, i)
        a = float(s_cover[i])
        nl = s_nl[i] if principled else -1
        if nl >= 0 and a > 0.0:  # a sum of lobes: their Transparent colours (and Principled 1 − alpha) pass through
            wt = vec.mul(w, vec.row(s_through, i))  # (coverage 0: all passes, e.g. a holdout object, tracer.integrator.compose)
        else:  # alpha: 1 − a of the ray continues unchanged behind the surface
            wt = vec.scale(w, 1.0 - a)
        if vec.max3(wt) > min_weight:
            _put_ray(th_o, th_d, th_w, th_s, n_through, spawn_ray(p, ng, di, eps), di, wt, s)
            th_t0[n_through] = t0[i] + t[i]
            th_par[n_through] = i
            n_through += 1
            counts[_N_TRANSMISSION] += 1
        if not spawn or a <= 0.0:
            continue
        mat = s_mat[i]
        k_m = float(m_km[mat])
        w_t = float(s_tran[i])
        mirror = vec.scale(vec.row(m_mirror, mat), k_m)
        mirror_l = mirror  # the part of the mirror weight that sees lamps (k_m: all; lobes: bsdf.lamp_share)
        glass_l = 1.0  # the share of the glass's reflected and refracted rays that sees lamps (smooth: all)
        g_rough = 0.0  # the glass's roughness
        # the dielectric split: the mirror ray takes F·glass_r, the refracted ray (1 − F)·glass_t + glass_t0
        glass_t0 = (0.0, 0.0, 0.0)
        if nl >= 0:  # the lobes' mirror share (direct-light stage) and their glass / refraction weights
            mirror = vec.madd(mirror, vec.row(s_mirror, i), 1.0 - k_m)
            mirror_l = vec.madd(mirror_l, vec.row(s_mlamp, i), 1.0 - k_m)
            glass_r, glass_t, glass_t0 = lobes.refraction_weights(s_lk, s_lw, s_lb, s_lp, i, nl,
                                                                  vec.row(m_stint, mat))
            glass_r, glass_t = vec.scale(glass_r, 1.0 - k_m), vec.scale(glass_t, 1.0 - k_m)
            glass_l = lobes.glass_lamp_share(s_lk, s_lp, i, nl)
            g_rough = lobes.glass_roughness(s_lk, s_lw, s_lb, s_lp, i, nl)
            glass_t0 = vec.scale(glass_t0, 1.0 - k_m)
        else:
            if principled:  # the lobes' mirror share, from the direct-light stage's closure (SurfaceQueue.mirror)
                glass = (1.0 - k_m) * (1.0 - float(s_metal[i])) * w_t
                if glass > 0.0:
                    glass_l = bsdf.lamp_share_of(float(s_rough[i]))
                    g_rough = min(max(float(s_rough[i]), 0.0), 1.0) * float(mats.rough_glass[mat])
                mirror = vec.madd(mirror, vec.row(s_mirror, i), 1.0 - k_m)
                mirror_l = vec.madd(mirror_l, vec.row(s_mlamp, i), 1.0 - k_m)
            else:  # classic: a smooth metal (Principled input) mirrors its base colour, as the notes' k_m·tint
                glass = (1.0 - k_m) * w_t
                m = float(s_metal[i])
                if m > 0.0:
                    g = bsdf.mirror_share(float(s_rough[i]))
                    mirror = vec.madd(mirror, vec.row(s_base, i), (1.0 - k_m) * m * g)
                mirror_l = mirror
            mirror = vec.scale(mirror, a)
            mirror_l = vec.scale(mirror_l, a)
            glass *= a
            # the glass part reflects by Fresnel × its specular tint (a Glass BSDF's Color, as Cycles tints it), as
            # the lobes' PRINCIPLED and GLASS slots do (tracer.shading.lobes.refraction_weights)
            glass_r = vec.scale(vec.row(m_stint, mat), glass) if principled else (glass, glass, glass)
            glass_t = vec.scale(vec.row(m_ttint, mat), glass)
        has_glass = vec.max3(glass_r) > 0.0 or vec.max3(glass_t) > 0.0 or vec.max3(glass_t0) > 0.0
        if not has_glass and vec.max3(mirror) <= 0.0:
            continue
        # Secondary rays where a mirror or glass part exists: reflection and transmission.
        # Interpolated normals can tilt a reflection below the surface: the normal is bent towards ng just enough
        # to keep it above (Cycles' glossy lobes do the same).
        r_n = optics.valid_reflection_normal(di, n, ng)
        r_dir = optics.reflect_dir(di, r_n)
        eta_i, eta_r, tir = 1.0, 1.0, False
        w_refl = vec.mul(w, mirror)
        w_refl_l = vec.mul(w, mirror_l)
        g_alpha = g_rough * g_rough
        if has_glass and g_alpha * g_alpha > bsdf.SINGULAR_ALPHA2:  # rough glass: one sampled microfacet normal
            ior = float(m_ior[mat])
            eta_i, eta_r = (1.0, ior) if s_front[i] else (ior, 1.0)
            u1, u2 = _glass_random(keys[s], depth, side, opt.seed)
            m_n, g_dir, g_r, t_dir, g_t, fr, tir = optics.rough_dielectric(di, n, ng, g_alpha, eta_i, eta_r, u1, u2,
                                                                           fresnel)
            if tir:
                n_tir += 1
            # energy compensation (Multiscatter GGX): the interface's weights over its albedo E(μ, r, η)
            comp = 1.0
            # (the notes' weights, F = 0 but under TIR, are no such interface; nor is single-scattering glass)
            if fresnel and mats.glass_multiscatter[mat] > 0.0:
                comp = 1.0 / max(bsdf.glass_albedo(g_rough, -vec.dot(di, n), eta_r / eta_i), 0.05)
                g_r, g_t = g_r * comp, g_t * comp
            seen_l = bsdf.lamp_share_of(g_rough)  # the share of the lamps the sampled rays see
            if seen_l > 0.9999:  # (roughness 0.1 in float32: no light samples for a share of 1e-13)
                seen_l = 1.0
            if seen_l < 1.0:  # the rest: light samples through the interface (_glass_light)
                g_rec[i, 0], g_rec[i, 1], g_rec[i, 2], g_rec[i, 3], g_rec[i, 4] = g_alpha, eta_i, eta_r, comp, \
                    1.0 - seen_l
                for ch in range(3):
                    g_rec[i, 5 + ch] = glass_r[ch]
                    g_rec[i, 8 + ch] = glass_t[ch]
                    g_rec[i, 11 + ch] = glass_t0[ch]
            w_tran = vec.mul(w, vec.madd(vec.scale(glass_t, (1.0 - fr) * g_t), glass_t0, g_t))
            if vec.max3(w_tran) > min_weight:
                j = n_rays + n_tran
                t_dir = vec.normalize(t_dir)
                _put_ray(n_o, n_d, n_w, n_s, j, spawn_ray(p, ng, t_dir, eps), t_dir, w_tran, s)
                _put_spawn(rec_n, rec_eta, rec_tir, j, m_n, eta_i, eta_r, False)
                n_par[j] = i
                n_lamp[j] = seen_l  # sampled: nearly smooth glass sees lamps so (blurred over its highlight)
                n_tran += 1
            w_glass = vec.mul(w, vec.scale(glass_r, fr * g_r))
            sum_m = w_refl[0] + w_refl[1] + w_refl[2]
            sum_g = w_glass[0] + w_glass[1] + w_glass[2]
            pick_glass = False
            if sum_g > 0.0:
                pick_glass = True
                if sum_m > 0.0:  # one reflected ray: the mirror's or the rough glass's, by their weights
                    p_g = sum_g / (sum_g + sum_m)
                    pick_glass = uniform1(keys[s], _STREAM_GLASS_PICK + depth, opt.seed) < p_g
                    if pick_glass:
                        w_glass = vec.scale(w_glass, 1.0 / p_g)
                    else:
                        w_refl = vec.scale(w_refl, 1.0 / (1.0 - p_g))
                        w_refl_l = vec.scale(w_refl_l, 1.0 / (1.0 - p_g))
                if pick_glass:
                    w_refl, w_refl_l, r_dir, r_n = w_glass, vec.scale(w_glass, seen_l), g_dir, m_n
            tir = tir and pick_glass  # the reflected ray is the glass's total internal reflection
        elif has_glass:
            ior = float(m_ior[mat])
            eta_i, eta_r = (1.0, ior) if s_front[i] else (ior, 1.0)
            t_dir, tir = optics.refract_dir(di, n, eta_i, eta_r)
            t_n = n
            if fresnel:
                fr = optics.fresnel_dielectric_1(-vec.dot(di, n), eta_i, eta_r)
            else:
                fr = 1.0 if tir else 0.0
            w_refl = vec.add(w_refl, vec.mul(w, vec.scale(glass_r, fr)))
            w_refl_l = vec.add(w_refl_l, vec.mul(w, vec.scale(glass_r, fr * glass_l)))
            if tir:
                n_tir += 1
                w_tran = (0.0, 0.0, 0.0)
            else:
                w_tran = vec.mul(w, vec.madd(glass_t0, glass_t, 1.0 - fr))
                if vec.dot(t_dir, ng) >= 0.0:  # the shading normal bent it back out: refract about ng
                    t_dir, tir_ng = optics.refract_dir(di, ng, eta_i, eta_r)
                    t_n = ng
                    if tir_ng:
                        w_tran = (0.0, 0.0, 0.0)
            if vec.max3(w_tran) > min_weight:
                j = n_rays + n_tran
                t_dir = vec.normalize(t_dir)
                _put_ray(n_o, n_d, n_w, n_s, j, spawn_ray(p, ng, t_dir, eps), t_dir, w_tran, s)
                _put_spawn(rec_n, rec_eta, rec_tir, j, t_n, eta_i, eta_r, False)
                n_par[j] = i
                n_lamp[j] = glass_l
                n_tran += 1
        if vec.max3(w_refl) > min_weight:
            r_dir = vec.normalize(r_dir)
            _put_ray(n_o, n_d, n_w, n_s, n_refl, spawn_ray(p, ng, r_dir, eps), r_dir, w_refl, s)
            _put_spawn(rec_n, rec_eta, rec_tir, n_refl, r_n, eta_i, eta_r, tir)
            n_par[n_refl] = i
            total = w_refl[0] + w_refl[1] + w_refl[2]
            n_lamp[n_refl] = min(max((w_refl_l[0] + w_refl_l[1] + w_refl_l[2]) / total, 0.0), 1.0) if total > 0.0 \
                else 1.0
            n_refl += 1
    counts[_N_TIR] += n_tir
    counts[_N_REFLECTION] += n_refl
    counts[_N_TRANSMISSION] += n_tran
    return n_refl, n_tran, n_through


@kernel(refcounts=False)
def _glass_light(rows, surf, d, sample, weight, keys, depth, glass, lights, seen, l_recv, recv, opt, out, shadow,
                 counts):
    """Rough glass's light stage: at each hit of ``rows`` (rough glass the spawn stage recorded in ``glass``,
    :data:`GLASS_COLUMNS`), every lamp's light samples (not emitting meshes, which the sampled rays see) weighted by
    the interface's BSDF (:func:`tracer.optics.rough_dielectric_eval`: reflected on the incident side by the
    reflected tint × F, refracted to the far side by the refracted tint × (1 − F) + the Refraction BSDF's tint), its
    energy compensation, the lamp's glossy / transmission visibility (``seen``: Links.visible, shape or not) and
    the light samples' share (the
    sampled rays see the rest). A point or spot light without radius or a sun without angle, which no ray can see, is all light samples.
    Written to ``shadow`` (0 when shadows are off: added to ``out`` directly); returns how many. The same light as
    the sampled rays would find, in expectation, with far less variance: a small bright lamp seen through rough
    glass is a few of 16 samples' sampled rays, and speckle, but every light sample."""
    eps = opt.eps
    q_o, q_d, q_t, q_s, q_c, q_l = shadow.o, shadow.d, shadow.t_max, shadow.sample, shadow.color, shadow.light
    l_kind = lights.kind
    linked = recv.shape[0] > 0
    o_color = out.color
    fresnel = opt.fresnel
    n_shadow = 0
    for ii in range(rows.shape[0]):
        i = rows[ii]
        s = sample[i]
        alpha, eta_i, eta_r, comp, share = glass[i, 0], glass[i, 1], glass[i, 2], glass[i, 3], glass[i, 4]
        g_r = (glass[i, 5], glass[i, 6], glass[i, 7])
        g_t = (glass[i, 8], glass[i, 9], glass[i, 10])
        g_t0 = (glass[i, 11], glass[i, 12], glass[i, 13])
        w = vec.scale(vec.row(weight, i), comp)
        n, ng, di = vec.row(surf.n, i), vec.row(surf.ng, i), vec.row(d, i)
        p = (surf.p[i, 0], surf.p[i, 1], surf.p[i, 2])
        r0, r1 = 0.0, 0.0
        if opt.needs_light_random:
            r0, r1 = uniform2_1(keys[s], _STREAM_LIGHT + depth, opt.seed)
        for j in range(l_kind.shape[0]):
            kd = l_kind[j]
            if kd == MESH or (linked and not linking.lights_receiver(l_recv[j], recv[i])):
                continue
            f_j = share
            if ((kd == POINT or kd == SPOT) and lights.radius[j] <= 0.0) or (kd == DISTANT and lights.cos_max[j] >= 1.0):
                f_j = 1.0
            for k in range(lights.side[j] * lights.side[j]):
                l, dist, e = sample_light(lights, j, k, p, r0, r1)
                side, value, fr = optics.rough_dielectric_eval(di, l, n, ng, alpha, eta_i, eta_r, fresnel)
                if side == 0 or value <= 0.0:
                    continue
                if side > 0:
                    tint = vec.scale(g_r, fr * value * seen[j, 1] * f_j)
                else:
                    tint = vec.scale(vec.madd(g_t0, g_t, 1.0 - fr), value * seen[j, 2] * f_j)
                c = vec.mul(w, vec.mul(tint, e))
                if c[0] <= 0.0 and c[1] <= 0.0 and c[2] <= 0.0:
                    continue
                if opt.shadows:
                    so, sd, st = shadow_ray(p, ng, l, dist, eps)
                    _put(q_o, q_d, q_t, q_s, q_c, q_l, n_shadow, so, sd, st, s, c, j)
                    n_shadow += 1
                else:
                    for ch in range(3):
                        o_color[s, ch] += c[ch]
    counts[_N_SHADOW] += n_shadow
    return n_shadow


@kernel(refcounts=False)
def _pass_shadow(sel, idx, t, prim, inst, overrides, normal_matrix, u, v, material_ids, face_normals, alphas,
                 threshold, o, d, t_max, color, pending, blocked, eps, code, pstart, pbase, outs, R0, R, uv_sets,
                 colors, has_colors, vertices, triangles, object_ids, bounds, tdata, tparams, linear, mirrored,
                 inst_ids, lobe_extra):
    """One round of transparent shadows: each pending shadow ray's first blocker either stops it (alpha 1) or lets
    1 − alpha of its colour through, the ray continuing behind it; a ray that reaches its light is unblocked. A
    material whose alpha is a program runs it at the blocker (Light Path: a shadow ray)."""
    for j in range(R0.shape[0]):
        R[j] = R0[j]
    geo = (uv_sets, colors, has_colors, vertices, triangles, face_normals, object_ids, bounds, linear, mirrored,
           inst_ids)
    tex = (tdata, tparams)
    for q in range(sel.shape[0]):
        j = sel[q]
        r = idx[j]
        tri = prim[q]
        if tri < 0:  # nothing (left) in the way
            pending[j] = False
            blocked[r] = False
            continue
        dj = vec.row(d, j)
        a, f, p, ng = alpha.blocker(tri, inst[q], float(u[q]), float(v[q]), float(t[q]), vec.row(o, j), dj,
                                    material_ids, overrides, normal_matrix, face_normals, alphas, threshold, code,
                                    pstart, pbase, outs, R, lobe_extra, geo, tex)
        if a >= 1.0:
            pending[j] = False
            continue
        for c in range(3):
            color[r, c] *= f[c]
        o[j, 0], o[j, 1], o[j, 2] = spawn_ray(p, ng, dj, eps)
        t_max[j] = t_max[j] - t[q]


def _by_light(light: np.ndarray, n_lights: int) -> np.ndarray | None:
    """The shadow queue's rows grouped by the light they aim at (sky rays first), each group in queue order; None
    where there is one light (the queue order is that)."""
    if n_lights < 2:
        return None
    order = np.empty(len(light), np.int64)
    _group_rows(light, np.zeros(n_lights + 2, np.int64), order)
    return order


@kernel(refcounts=False)
def _group_rows(key, start, order):
    """order = the rows of ``key`` (values -1 .. len(start) - 3) grouped by value, stably (a counting sort)."""
    for i in range(key.shape[0]):
        start[key[i] + 2] += 1
    for k in range(2, start.shape[0]):
        start[k] += start[k - 1]
    for i in range(key.shape[0]):
        j = key[i] + 1
        order[start[j]] = i
        start[j] += 1


@kernel(refcounts=False)
def _add_unoccluded(color, sample, contrib, blocked):
    """color[sample] += contrib where the shadow (or sky) ray reached its light."""
    for i in range(sample.shape[0]):
        if not blocked[i]:
            s = sample[i]
            for c in range(3):
                color[s, c] += contrib[i, c]

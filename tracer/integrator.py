"""The seed's Cast-Ray, as a wavefront over one tile.

Recursion becomes iteration: all rays of a tile at one depth are intersected together (Embree), then one kernel
shades every hit and writes the rays of the next step, so the recursive colour

    c = (1 − k_m)·c_local + k_m·RayColor(reflected)          (ray type 3, the notes' formula)

becomes: add throughput·(1 − k_m)·c_local to the pixel, and spawn the reflected ray with throughput·k_m, where a
ray's *throughput* is the product of the weights on its path. Glass (transmission weight w_t, ray type 4) splits the
non-mirror remainder (1 − k_m) into a reflected part F and a transmitted part (1 − F) by the dielectric Fresnel factor
F (or, in classic mode, F = 0, and 1 under TIR).

Shadow rays (ray type 2) are deferred: the kernel writes one per light sample that faces the point, together with
the colour it would add; after one batched occlusion query, the unblocked ones are added. One step of a tile is

    Embree closest hits → _shade_hits (kernel) → Embree occlusion → _add_unoccluded (kernel) → next depth.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from . import optics, shading, vec
from .accel import Accelerator
from .jit import kernel
from .environment import env_radiance, env_sample, pack_environment
from .instances import material_id, object_id, pack_instances, world_emitters, world_frame
from .lights import pack_lights, sample_light
from .sampling import multijitter, stratum, uniform2_1
from .scene import Scene
from .settings import RenderSettings
from .surface import geometry_of, hit_uv
from .texture import bilinear, pack_textures

RAY_TYPES = ("eye", "shadow", "reflection", "transmission", "sky")

#: How light reached the eye, by the path's first secondary ray: "direct" (lit at the eye ray's hit, or background
#: seen directly), "reflection", "transmission". The three ray-type AOVs sum to the beauty.
PATH_TYPES = ("direct", "reflection", "transmission")
_REFLECTION_PATH, _TRANSMISSION_PATH = 1, 2

# Sample streams (independent hash sequences) of one eye sample.
_STREAM_PIXEL = 0
_STREAM_LIGHT = 1  # + depth
_STREAM_SKY = 40  # + depth

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
    by_type: np.ndarray | None = None  # (S, 3, 3) colour per PATH_TYPES (with ray_types)
    deepest: np.ndarray | None = None  # (S,) depth of the deepest ray (0 = the eye ray only) (with ray_types)


class MaterialArrays(NamedTuple):
    """:class:`tracer.Materials` as the kernels read it (float32 / int32 columns)."""

    diffuse: np.ndarray
    specular: np.ndarray
    exponent: np.ndarray
    k_m: np.ndarray
    mirror_tint: np.ndarray
    transmission: np.ndarray
    transmission_tint: np.ndarray
    ior: np.ndarray
    emission: np.ndarray
    diffuse_texture: np.ndarray


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


class RayQueue(NamedTuple):
    """Rays of one depth: origins, unit directions, the weight (throughput) each carries, the eye sample it adds
    to, and an optional length limit (None = unbounded)."""

    o: np.ndarray
    d: np.ndarray
    weight: np.ndarray
    sample: np.ndarray
    t_max: np.ndarray | None


class ShadowQueue(NamedTuple):
    """Deferred shadow (and sky) rays of one depth: each adds ``color`` to its sample if nothing blocks it."""

    o: np.ndarray
    d: np.ndarray
    t_max: np.ndarray
    sample: np.ndarray
    color: np.ndarray
    light: np.ndarray  # light index, -1 for a sky-visibility ray


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


class Step(NamedTuple):
    """What one depth of :meth:`Integrator.step` did: the hits (t, prim, u, v), the shadow queue and which of its
    rays were blocked, the next depth's rays (the first ``n_reflected`` are reflections) and how they were made."""

    hits: tuple
    shadow: ShadowQueue
    blocked: np.ndarray
    next: RayQueue
    spawned: SpawnRecord
    n_reflected: int


class Tile(NamedTuple):
    """Per-sample outputs a tile's kernels write into."""

    color: np.ndarray
    alpha: np.ndarray
    depth: np.ndarray
    normal: np.ndarray
    albedo: np.ndarray
    object_id: np.ndarray


class Integrator:
    """Holds what every tile needs: the scene's arrays, its BVH and the settings. ``trace`` is thread-safe."""

    def __init__(self, scene: Scene, settings: RenderSettings, accel: Accelerator | None = None):
        self.scene = scene
        self.settings = settings
        self.accel = accel if accel is not None else Accelerator(scene)
        eps = settings.epsilon if settings.epsilon is not None else scene.default_epsilon()
        self.eps = np.float32(eps)
        self.geometry = geometry_of(scene)
        m = scene.materials
        f32, i32 = (lambda a: np.ascontiguousarray(a, np.float32)), (lambda a: np.ascontiguousarray(a, np.int32))
        self.materials = MaterialArrays(
            diffuse=f32(m.diffuse), specular=f32(m.specular), exponent=f32(m.exponent), k_m=f32(m.k_m),
            mirror_tint=f32(m.mirror_tint), transmission=f32(m.transmission),
            transmission_tint=f32(m.transmission_tint), ior=f32(m.ior), emission=f32(m.emission),
            diffuse_texture=i32(m.diffuse_texture if scene.uvs is not None else np.full(len(m), -1)))
        self.textures = pack_textures(scene.textures)
        self.instances = pack_instances(scene)
        emitters = world_emitters(scene, m.emission)  # instanced prototypes' emitters placed per instance
        self.lights = pack_lights(scene.lights, settings.light_samples, emitters)
        self.light_samples = int(np.sum(self.lights.side ** 2))  # shadow rays per shading point, at most
        self.env = pack_environment(scene.environment)
        ambient = scene.ambient
        if scene.environment is not None and not np.any(ambient > 0):
            ambient = scene.environment.average()
        self.options = Options(
            eps=float(self.eps), max_depth=int(settings.max_depth), shadows=bool(settings.shadows),
            fresnel=bool(settings.fresnel), sky_samples=int(settings.sky_samples),
            min_weight=float(settings.min_weight), transparent=bool(settings.transparent), seed=int(settings.seed),
            needs_light_random=bool(np.any(self.lights.side > 1)),
            background=tuple(float(c) for c in scene.background), ambient=tuple(float(c) for c in ambient))
        sky = settings.sky_samples
        lit_by_sky = scene.environment is not None or np.any(scene.ambient > 0)
        self.sky_side = max(1, int(round(np.sqrt(sky)))) if sky and lit_by_sky else 0

    @property
    def last_depth(self) -> int:
        """The deepest step: max_depth, or one more (collecting only background and emission) with terminal rays."""
        return self.settings.max_depth + (1 if self.settings.terminal_rays else 0)

    def step(self, depth: int, rays: "RayQueue", keys: np.ndarray, out: "Tile", counts: np.ndarray) -> "Step":
        """One depth of Cast-Ray for a queue of rays: closest hits, shading (adding into ``out`` at each ray's
        sample), the deferred shadow rays and their occlusion, and the queue of next rays (reflections, then
        transmissions; empty past the last depth)."""
        n = len(rays.o)
        hits = self.accel.closest_hits(rays.o, rays.d, rays.t_max)
        t, prim, u, v, inst = hits
        # Deferred shadow rays (origin, direction, length, sample, colour) and the next depth's rays
        # (reflections from slot 0, transmissions from slot n).
        cap = n * (self.light_samples + self.sky_side**2)
        so, sd = np.empty((cap, 3), np.float32), np.empty((cap, 3), np.float32)
        sl, ss, sc = np.empty(cap, np.float32), np.empty(cap, np.int32), np.empty((cap, 3), np.float32)
        spawn = depth < self.last_depth
        cap2 = 2 * n if spawn else 0
        no, nd = np.empty((cap2, 3), np.float32), np.empty((cap2, 3), np.float32)
        nw, ns = np.empty((cap2, 3), np.float32), np.empty(cap2, np.int32)
        rec = SpawnRecord.empty(cap, cap2)
        n_shadow, n_refl, n_tran = _shade_hits(
            rays.o, rays.d, t, prim, inst, self.instances, u, v, rays.sample, rays.weight, keys, depth, spawn,
            self.geometry,
            self.materials, self.textures[0], self.textures[1], self.lights, self.env,
            self.sky_side, self.options, out, so, sd, sl, ss, sc, no, nd, nw, ns, counts, rec)
        shadow = ShadowQueue(o=so[:n_shadow], d=sd[:n_shadow], t_max=sl[:n_shadow], sample=ss[:n_shadow],
                             color=sc[:n_shadow], light=rec.light[:n_shadow])
        blocked = np.zeros(0, bool)
        if n_shadow:
            blocked = self.accel.occluded(shadow.o, shadow.d, shadow.t_max)
            _add_unoccluded(out.color, shadow.sample, shadow.color, blocked)
        keep = np.r_[0:n_refl, n:n + n_tran] if n_tran else slice(0, n_refl)
        nxt = RayQueue(o=no[keep], d=nd[keep], weight=nw[keep], sample=ns[keep], t_max=None)
        spawned = SpawnRecord(light=rec.light[:0], normal=rec.normal[keep], eta=rec.eta[keep], tir=rec.tir[keep])
        return Step(hits=hits, shadow=shadow, blocked=blocked, next=nxt, spawned=spawned, n_reflected=n_refl)

    def trace(self, origins: np.ndarray, directions: np.ndarray, keys: np.ndarray,
              cancelled=lambda: False, ray_types: bool = False) -> TileResult:
        """Trace eye rays (one per sample) to the maximum depth. ``keys`` are unique per sample (for the
        deterministic random streams). With ``ray_types`` the result also holds each sample's colour split by the
        ray type it arrived through (:data:`PATH_TYPES`) and the depth of its deepest ray."""
        s = self.scene
        n_samples = len(origins)
        # With ray_types, each eye sample owns PATH_TYPES slots and a path's contributions go to the slot of its
        # first secondary ray (as Cycles files light under the first bounce); the slots are summed at the end.
        k = len(PATH_TYPES) if ray_types else 1
        out = Tile(color=np.zeros((n_samples * k, 3), np.float32), alpha=np.ones(n_samples * k, np.float32),
                   depth=np.full(n_samples * k, np.inf, np.float32), normal=np.zeros((n_samples * k, 3), np.float32),
                   albedo=np.zeros((n_samples * k, 3), np.float32), object_id=np.full(n_samples * k, -1, np.int32))
        counts = np.zeros(5, np.int64)
        keys = np.ascontiguousarray(np.repeat(keys, k), np.int64)
        deepest = np.full(n_samples, -1, np.int32)

        rays = RayQueue(o=np.ascontiguousarray(origins, np.float32), d=np.ascontiguousarray(directions, np.float32),
                        weight=np.ones((n_samples, 3), np.float32),
                        sample=np.arange(0, n_samples * k, k, dtype=np.int32),
                        t_max=(np.full(n_samples, s.camera.far - s.camera.near, np.float32)
                               if np.isfinite(s.camera.far) else None))
        for depth in range(self.last_depth + 1):
            if not len(rays.o) or cancelled():
                break
            if ray_types:
                np.maximum.at(deepest, rays.sample // k, depth)
            step = self.step(depth, rays, keys, out, counts)
            rays = step.next
            if ray_types and depth == 0 and len(rays.o):  # the first secondary rays choose their path's slot
                first = np.where(np.arange(len(rays.o)) < step.n_reflected, _REFLECTION_PATH, _TRANSMISSION_PATH)
                rays = rays._replace(sample=(rays.sample + first).astype(np.int32))

        np.nan_to_num(out.color, copy=False, nan=0.0, posinf=0.0, neginf=0.0)
        rc = RayCounts(eye=n_samples, shadow=int(counts[_N_SHADOW]), reflection=int(counts[_N_REFLECTION]),
                       transmission=int(counts[_N_TRANSMISSION]), sky=int(counts[_N_SKY]), tir=int(counts[_N_TIR]))
        by_type = out.color.reshape(n_samples, k, 3)
        return TileResult(color=by_type.sum(axis=1) if k > 1 else out.color, alpha=out.alpha[::k],
                          depth=out.depth[::k], normal=out.normal[::k], albedo=out.albedo[::k],
                          object_id=out.object_id[::k], counts=rc, by_type=by_type if k > 1 else None,
                          deepest=deepest if k > 1 else None)


@kernel
def _shade_hits(o, d, t, prim, inst, itab, u, v, sample, weight, keys, depth, spawn, geom, mats, tex_data, tex_info,
                lights, env, sky_side, opt, out, so, sd, sl, ss, sc, no, nd, nw, ns, counts,
                rec):
    """Shade one depth's rays of a tile and write the rays they cause; returns (shadow, reflection, transmission)
    counts written into the buffers.

    Per ray: a miss adds the background (or clears alpha of a transparent film); a hit adds its emission, the
    ambient term and, through deferred shadow rays, Σ lights of Lambert + Blinn-Phong, all weighted by
    (1 − k_m)(1 − w_t); then spawns the reflected ray (k_m·tint + glass·F) and the transmitted one (glass·(1 − F)).
    """
    n_rays = o.shape[0]
    eps = opt.eps
    n_shadow = 0
    n_refl = 0
    n_tran = 0
    n_lights = lights.table.shape[0]
    for i in range(n_rays):
        s = sample[i]
        w = vec.row(weight, i)
        tri = prim[i]
        if tri < 0:  # the ray leaves the scene
            if depth == 0 and opt.transparent:
                out.alpha[s] = 0.0
            elif env.present:  # the environment image along the ray
                sky = env_radiance(env, vec.row(d, i))
                for c in range(3):
                    out.color[s, c] += w[c] * sky[c]
            else:
                for c in range(3):
                    out.color[s, c] += w[c] * opt.background[c]
            continue
        di = vec.row(d, i)
        p = vec.madd(vec.row(o, i), di, float(t[i]))
        ng, n, front = world_frame(geom, itab, inst[i], tri, di, float(u[i]), float(v[i]))
        mat = material_id(itab, inst[i], geom.material_ids[tri])
        diffuse = vec.row(mats.diffuse, mat)
        ti = mats.diffuse_texture[mat]
        if ti >= 0:
            st = hit_uv(geom, tri, float(u[i]), float(v[i]))
            diffuse = vec.mul(diffuse, bilinear(tex_data, tex_info, ti, st[0], st[1]))
        k_m = float(mats.k_m[mat])
        w_t = float(mats.transmission[mat])
        opaque = (1.0 - k_m) * (1.0 - w_t)

        if depth == 0:
            out.depth[s] = t[i]
            out.normal[s, 0], out.normal[s, 1], out.normal[s, 2] = n
            out.albedo[s, 0], out.albedo[s, 1], out.albedo[s, 2] = diffuse
            out.object_id[s] = object_id(itab, inst[i], geom.object_ids[tri])

        # Local colour: emission + (1 − k_m)(1 − w_t)·(ambient + Σ lights), only where it carries weight.
        # Terminal rays (past max_depth, Cycles' last bounce) collect emission and background only.
        local = vec.row(mats.emission, mat)
        if opaque > 0.0 and depth <= opt.max_depth:
            wo = vec.scale(w, opaque)
            origin = vec.madd(p, ng, eps)  # shadow rays leave on the incident side, ε along ng
            key = keys[s]
            if env.present and sky_side > 0:  # the environment as a light: importance-sampled by luminance
                kk = sky_side * sky_side
                r0, r1 = uniform2_1(key, _STREAM_SKY + depth, opt.seed)
                for k in range(kk):
                    s0, s1 = multijitter(k, sky_side, r0, r1)
                    dr, pdf = env_sample(env, s0, s1)
                    n_l = vec.dot(n, dr)
                    if n_l <= 0.0 or vec.dot(ng, dr) <= 0.0 or pdf <= 0.0:
                        continue
                    # R_d/π · L(ω)·cos θ / pdf(ω), averaged over the kk samples; counts if the sky is visible
                    c = vec.scale(vec.mul(wo, vec.mul(diffuse, env_radiance(env, dr))), n_l / (np.pi * pdf * kk))
                    _put(so, sd, sl, ss, sc, n_shadow, origin, dr, np.inf, s, c)
                    rec.light[n_shadow] = -1
                    n_shadow += 1
                    counts[_N_SKY] += 1
            elif opt.ambient[0] > 0.0 or opt.ambient[1] > 0.0 or opt.ambient[2] > 0.0:
                amb = shading.ambient(diffuse, opt.ambient)
                if sky_side == 0:
                    local = vec.madd(local, amb, opaque)
                else:  # weight by the visible sky: cosine-weighted hemisphere rays, deferred like shadow rays
                    kk = sky_side * sky_side
                    c = vec.scale(vec.mul(wo, amb), 1.0 / kk)
                    r0, r1 = uniform2_1(key, _STREAM_SKY + depth, opt.seed)
                    tu, tv = vec.orthonormal_basis(n)
                    for k in range(kk):
                        s0, s1 = stratum(k, sky_side, r0, r1)
                        r = np.sqrt(s0)
                        phi = 2.0 * np.pi * s1
                        dr = vec.madd(vec.madd(vec.scale(n, np.sqrt(max(0.0, 1.0 - s0))), tu, r * np.cos(phi)),
                                      tv, r * np.sin(phi))
                        _put(so, sd, sl, ss, sc, n_shadow, origin, dr, np.inf, s, c)
                        rec.light[n_shadow] = -1
                        n_shadow += 1
                    counts[_N_SKY] += kk
            r0, r1 = 0.0, 0.0
            if opt.needs_light_random:
                r0, r1 = uniform2_1(key, _STREAM_LIGHT + depth, opt.seed)
            specular = vec.row(mats.specular, mat)
            has_spec = vec.max3(specular) > 0.0
            exponent = float(mats.exponent[mat])
            for j in range(n_lights):
                for k in range(lights.side[j] * lights.side[j]):
                    l, dist, e = sample_light(lights, j, k, p, r0, r1)
                    n_l = vec.dot(n, l)
                    if n_l <= 0.0 or vec.dot(ng, l) <= 0.0:
                        continue
                    c = shading.lambert(diffuse, e, n_l)
                    if has_spec:
                        h = shading.half_vector(l, vec.scale(di, -1.0))
                        c = vec.add(c, shading.blinn_phong(specular, exponent, n, h, e, n_l))
                    c = vec.mul(wo, c)
                    if opt.shadows:  # the shadow ray (p, l, ε, dist): counts only if nothing is in between
                        _put(so, sd, sl, ss, sc, n_shadow, origin, l, dist - 2.0 * eps, s, c)
                        rec.light[n_shadow] = j
                        n_shadow += 1
                        counts[_N_SHADOW] += 1
                    else:
                        for ch in range(3):
                            out.color[s, ch] += c[ch]
        for ch in range(3):
            out.color[s, ch] += w[ch] * local[ch]

        if not spawn or opaque >= 1.0:
            continue
        # Secondary rays where a mirror or glass part exists: reflection and transmission.
        glass = (1.0 - k_m) * w_t
        mirror = vec.scale(vec.row(mats.mirror_tint, mat), k_m)
        r_dir = optics.reflect_dir(di, n)
        r_n = n
        # Interpolated normals can tilt a reflection below the surface: use the geometric normal there.
        if vec.dot(r_dir, ng) <= 0.0:
            r_dir = optics.reflect_dir(di, ng)
            r_n = ng
        eta_i, eta_r, tir = 1.0, 1.0, False
        w_refl = vec.mul(w, mirror)
        if glass > 0.0:
            ior = float(mats.ior[mat])
            eta_i, eta_r = (1.0, ior) if front else (ior, 1.0)
            t_dir, tir = optics.refract_dir(di, n, eta_i, eta_r)
            t_n = n
            if opt.fresnel:
                fr = optics.fresnel_dielectric_1(-vec.dot(di, n), eta_i, eta_r)
            else:
                fr = 1.0 if tir else 0.0
            w_refl = vec.madd(w_refl, w, glass * fr)
            if tir:
                counts[_N_TIR] += 1
                w_tran = (0.0, 0.0, 0.0)
            else:
                w_tran = vec.scale(vec.mul(w, vec.row(mats.transmission_tint, mat)), glass * (1.0 - fr))
                if vec.dot(t_dir, ng) >= 0.0:  # the shading normal bent it back out: refract about ng
                    t_dir, tir_ng = optics.refract_dir(di, ng, eta_i, eta_r)
                    t_n = ng
                    if tir_ng:
                        w_tran = (0.0, 0.0, 0.0)
            if vec.max3(w_tran) > opt.min_weight:
                j = n_rays + n_tran
                _put_ray(no, nd, nw, ns, j, vec.madd(p, ng, -eps), vec.normalize(t_dir), w_tran, s)
                _put_spawn(rec, j, t_n, eta_i, eta_r, False)
                n_tran += 1
        if vec.max3(w_refl) > opt.min_weight:
            _put_ray(no, nd, nw, ns, n_refl, vec.madd(p, ng, eps), vec.normalize(r_dir), w_refl, s)
            _put_spawn(rec, n_refl, r_n, eta_i, eta_r, tir)
            n_refl += 1
    counts[_N_REFLECTION] += n_refl
    counts[_N_TRANSMISSION] += n_tran
    return n_shadow, n_refl, n_tran


@kernel(inline=True)
def _put(so, sd, sl, ss, sc, j, origin, direction, length, s, c):
    so[j, 0], so[j, 1], so[j, 2] = origin
    sd[j, 0], sd[j, 1], sd[j, 2] = direction
    sl[j] = length
    ss[j] = s
    sc[j, 0], sc[j, 1], sc[j, 2] = c


@kernel(inline=True)
def _put_ray(no, nd, nw, ns, j, origin, direction, w, s):
    no[j, 0], no[j, 1], no[j, 2] = origin
    nd[j, 0], nd[j, 1], nd[j, 2] = direction
    nw[j, 0], nw[j, 1], nw[j, 2] = w
    ns[j] = s


@kernel(inline=True)
def _put_spawn(rec, j, n, eta_i, eta_r, tir):
    """What a spawned ray's direction was computed from (for ``tracer.explain``): the unit normal on the incident
    side, the two refractive indices and whether total internal reflection turned a transmission into it."""
    rec.normal[j, 0], rec.normal[j, 1], rec.normal[j, 2] = n
    rec.eta[j, 0], rec.eta[j, 1] = eta_i, eta_r
    rec.tir[j] = tir


@kernel
def _add_unoccluded(color, sample, contrib, blocked):
    """color[sample] += contrib where the shadow (or sky) ray reached its light."""
    for i in range(sample.shape[0]):
        if not blocked[i]:
            s = sample[i]
            for c in range(3):
                color[s, c] += contrib[i, c]

"""The seed's Cast-Ray, as a wavefront over one tile.

Recursion becomes iteration: all rays of a tile at one depth are intersected together, shaded together, and spawn
the next depth's reflection and transmission rays. Each ray carries the product of the weights on its path
(its *throughput*), so the recursive colour

    c = (1 − k_m)·c_local + k_m·RayColor(reflected)          (ray type 3, the notes' formula)

becomes: add throughput·(1 − k_m)·c_local to the pixel, and spawn the reflected ray with throughput·k_m. Glass
(transmission weight w_t, ray type 4) splits the non-mirror remainder (1 − k_m) into a reflected part F and a
transmitted part (1 − F) by the dielectric Fresnel factor F (or, in classic mode, F = 0, and 1 under TIR).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import optics, sampling, shading
from .accel import NO_HIT, Accelerator
from .scene import Scene
from .settings import RenderSettings
from .texture import sample_bilinear

RAY_TYPES = ("eye", "shadow", "reflection", "transmission", "sky")

# Sample streams (independent hash sequences) of one eye sample.
_STREAM_PIXEL = 0
_STREAM_LIGHT = 1  # + depth
_STREAM_SKY = 40  # + depth


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
class Hits:
    """Surface interactions of a batch of rays that hit something."""

    p: np.ndarray  # (N, 3) hit points
    ng: np.ndarray  # (N, 3) unit geometric normal on the incident side
    n: np.ndarray  # (N, 3) unit shading normal on the incident side
    front: np.ndarray  # (N,) True where the ray hit the triangle's front face (entering a closed object)
    material: np.ndarray  # (N,) material rows
    prim: np.ndarray  # (N,) triangle ids
    t: np.ndarray  # (N,) ray distances


@dataclass
class TileResult:
    color: np.ndarray  # (S, 3) per eye sample
    alpha: np.ndarray  # (S,)
    depth: np.ndarray  # (S,) distance from the eye (ortho: film plane) to the first hit along the eye ray, inf where none
    normal: np.ndarray  # (S, 3) first-hit shading normal (world space, facing the eye)
    albedo: np.ndarray  # (S, 3) first-hit diffuse colour
    object_id: np.ndarray  # (S,) first-hit object id, -1 where none
    counts: RayCounts = field(default_factory=RayCounts)


class Integrator:
    """Holds what every tile needs: the scene, its BVH and the settings. ``trace`` is thread-safe."""

    def __init__(self, scene: Scene, settings: RenderSettings, accel: Accelerator | None = None):
        self.scene = scene
        self.settings = settings
        self.accel = accel if accel is not None else Accelerator(scene)
        self.eps = np.float32(settings.epsilon if settings.epsilon is not None else scene.default_epsilon())
        tri = scene.vertices[scene.triangles]  # (T, 3, 3) float32
        ng = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        ng /= np.maximum(np.sqrt(np.einsum("ij,ij->i", ng, ng)), np.float32(1e-30))[:, None]
        self.face_normals = ng
        self.corner_ok = (np.all(np.any(scene.normals != 0, axis=2), axis=1) if scene.normals is not None else None)
        m = scene.materials
        self.has_textures = bool(len(scene.textures)) and scene.uvs is not None and bool(np.any(m.diffuse_texture >= 0))

    # ------------------------------------------------------------------ geometry at hits
    def surface(self, o, d, t, prim, u, v) -> Hits:
        s = self.scene
        p = o + d * t[:, None]
        ng = self.face_normals[prim]
        front = _dot(d, ng) < 0
        sign = np.where(front, np.float32(1), np.float32(-1))[:, None]
        ng *= sign  # the geometric normal on the incident side
        if s.normals is not None:
            cn = s.normals[prim]  # (N, 3, 3) per-corner shading normals
            n = cn[:, 0] * (1.0 - u - v)[:, None] + cn[:, 1] * u[:, None] + cn[:, 2] * v[:, None]
            ln = np.sqrt(_dot(n, n))
            n *= (sign[:, 0] / np.maximum(ln, 1e-30))[:, None]
            # Unusable normals, or interpolated ones facing away from the geometric side, fall back to ng.
            bad = ~self.corner_ok[prim] | (ln <= 1e-6) | (_dot(n, ng) <= 0)
            if bad.any():
                n[bad] = ng[bad]
        else:
            n = ng
        return Hits(p=p, ng=ng, n=n, front=front, material=s.material_ids[prim], prim=prim, t=t)

    def albedo(self, h: Hits, u, v) -> np.ndarray:
        m = self.scene.materials
        c = m.diffuse[h.material]
        if self.has_textures:
            tex = m.diffuse_texture[h.material]
            for ti in np.unique(tex[tex >= 0]):
                sel = np.flatnonzero(tex == ti)
                uv = self.scene.uvs[h.prim[sel]]
                w0 = (1.0 - u[sel] - v[sel])[:, None]
                st = uv[:, 0] * w0 + uv[:, 1] * u[sel, None] + uv[:, 2] * v[sel, None]
                c[sel] = c[sel] * sample_bilinear(self.scene.textures[ti], st)
        return c

    # ------------------------------------------------------------------ shadow rays and local shading
    def direct_light(self, h: Hits, view: np.ndarray, diffuse, keys, depth, counts: RayCounts) -> np.ndarray:
        """Σ over lights of Lambert + Blinn-Phong, each light sample tested with a shadow ray(p, l, ε, dist)."""
        s, st = self.scene, self.settings
        m = s.materials
        out = np.zeros_like(diffuse)
        if not s.lights or not len(h.p):
            return out
        specular = m.specular[h.material]
        exponent = m.exponent[h.material]
        has_spec = bool(np.any(specular > 0))
        origin = h.p + h.ng * self.eps
        needs_rand = any(light.uses_random(st.light_samples) for light in s.lights)
        rand = sampling.uniform2(keys, _STREAM_LIGHT + depth, st.seed) if needs_rand else None
        for light in s.lights:
            l, dist, e = light.sample(h.p, st.light_samples, rand)  # (K, N, 3), (K, N), (K, N, 3)
            for k in range(l.shape[0]):
                lk = l[k]
                n_l = _dot(h.n, lk)
                idx = np.flatnonzero((n_l > 0) & (_dot(h.ng, lk) > 0))
                if st.shadows and len(idx):
                    counts.shadow += len(idx)
                    blocked = self.accel.occluded(origin[idx], lk[idx], dist[k, idx] - 2 * self.eps)
                    idx = idx[~blocked]
                if not len(idx):
                    continue
                n_l_i = n_l[idx, None]
                irr = e[k, idx]
                c = shading.lambert(n_l_i, diffuse[idx], irr)
                if has_spec:
                    hv = shading.half_vector(lk[idx], view[idx])
                    c += shading.blinn_phong(h.n[idx], hv, n_l_i, specular[idx], exponent[idx], irr)
                out[idx] += c
        return out

    def sky_visibility(self, h: Hits, keys, depth, counts: RayCounts) -> np.ndarray:
        """Cosine-weighted fraction of the hemisphere around n from which a ray escapes the scene."""
        k = self.settings.sky_samples
        n = len(h.p)
        rand = sampling.uniform2(keys, _STREAM_SKY + depth, self.settings.seed)
        from .lights import stratified_grid

        s = stratified_grid(k, rand)  # (K, N, 2)
        kk = s.shape[0]
        a = np.where(np.abs(h.n[:, :1]) < 0.9, np.array([[1.0, 0, 0]], np.float32), np.array([[0, 1.0, 0]], np.float32))
        tu = np.cross(a, h.n)
        tu /= np.linalg.norm(tu, axis=1, keepdims=True)
        tv = np.cross(h.n, tu)
        r = np.sqrt(s[..., 0])
        phi = 2 * np.pi * s[..., 1]
        z = np.sqrt(np.maximum(0.0, 1 - s[..., 0]))
        dirs = (r * np.cos(phi))[..., None] * tu + (r * np.sin(phi))[..., None] * tv + z[..., None] * h.n
        origin = np.broadcast_to(h.p + h.ng * self.eps, (kk, n, 3)).reshape(-1, 3)
        dirs = dirs.reshape(-1, 3).astype(np.float32)
        counts.sky += len(dirs)
        blocked = self.accel.occluded(origin, dirs, np.full(len(dirs), np.inf, np.float32))
        return (1.0 - blocked.reshape(kk, n).mean(axis=0)).astype(np.float32)

    # ------------------------------------------------------------------ the wavefront
    def trace(self, origins: np.ndarray, directions: np.ndarray, keys: np.ndarray,
              cancelled=lambda: False) -> TileResult:
        """Trace eye rays (one per sample) to the maximum depth. ``keys`` are unique per sample (for the
        deterministic random streams)."""
        s, st = self.scene, self.settings
        m = s.materials
        n_samples = len(origins)
        color = np.zeros((n_samples, 3), np.float32)
        counts = RayCounts(eye=n_samples)
        res = TileResult(color=color, alpha=np.ones(n_samples, np.float32),
                         depth=np.full(n_samples, np.inf, np.float32), normal=np.zeros((n_samples, 3), np.float32),
                         albedo=np.zeros((n_samples, 3), np.float32), object_id=np.full(n_samples, -1, np.int32),
                         counts=counts)

        o, d = origins, directions
        sample = np.arange(n_samples)
        weight = np.ones((n_samples, 3), np.float32)
        t_max = None
        if np.isfinite(s.camera.far):
            t_max = np.full(n_samples, s.camera.far - s.camera.near, np.float32)

        last = st.max_depth + (1 if st.terminal_rays else 0)
        for depth in range(last + 1):
            if not len(o) or cancelled():
                break
            t, prim, u, v = self.accel.intersect(o, d, t_max)
            t_max = None
            miss = prim == NO_HIT
            if miss.any():
                if depth == 0 and st.transparent:
                    res.alpha[sample[miss]] = 0.0
                elif np.any(s.background > 0):
                    _accumulate(color, sample[miss], weight[miss] * s.background)
                hit = np.flatnonzero(~miss)
                if not len(hit):
                    break
                o, d, t, prim, u, v = o[hit], d[hit], t[hit], prim[hit], u[hit], v[hit]
                sample, weight = sample[hit], weight[hit]
            h = self.surface(o, d, t, prim, u, v)
            diffuse = self.albedo(h, u, v)
            mat = h.material
            k_m = m.k_m[mat]
            w_t = m.transmission[mat]
            opaque = (1.0 - k_m) * (1.0 - w_t)

            if depth == 0:
                res.depth[sample] = t
                res.normal[sample] = h.n
                res.albedo[sample] = diffuse
                res.object_id[sample] = s.object_ids[prim]

            # Local colour: emission + (1 − k_m)(1 − w_t)·(ambient + Σ lights), only where it carries weight.
            # Terminal rays (past max_depth, Cycles' last bounce) collect emission and background only.
            local = m.emission[mat]
            shade = np.flatnonzero(opaque > 0) if depth <= st.max_depth else np.zeros(0, np.int64)
            if len(shade):
                hs = _subset(h, shade)
                keys_s = keys[sample[shade]]
                diff_s = diffuse[shade]
                c = self.direct_light(hs, -d[shade], diff_s, keys_s, depth, counts)
                if np.any(s.ambient > 0):
                    vis = self.sky_visibility(hs, keys_s, depth, counts) if st.sky_samples else None
                    c += shading.ambient(diff_s, s.ambient, vis)
                local[shade] += opaque[shade, None] * c
            _accumulate(color, sample, weight * local)

            if depth == last:
                break

            # Secondary rays where a mirror or glass part exists: reflection and transmission.
            sec = np.flatnonzero(opaque < 1.0)
            if not len(sec):
                break
            d, p, ng, n, front = d[sec], h.p[sec], h.ng[sec], h.n[sec], h.front[sec]
            weight, sample, mat = weight[sec], sample[sec], mat[sec]
            k_m, w_t = k_m[sec, None], w_t[sec, None]
            glass = (1.0 - k_m) * w_t
            ior = m.ior[mat]
            eta_i = np.where(front, np.float32(1), ior)
            eta_r = np.where(front, ior, np.float32(1))
            t_dir, tir = optics.refract(d, n, eta_i, eta_r)
            if st.fresnel:
                fr = optics.fresnel_dielectric(-_dot(d, n), eta_i, eta_r)[:, None]
            else:
                fr = tir.astype(np.float32)[:, None]
            w_refl = weight * (k_m * m.mirror_tint[mat] + glass * fr)
            w_tran = weight * glass * (1.0 - fr) * m.transmission_tint[mat]
            w_tran[tir] = 0.0
            counts.tir += int(np.count_nonzero(tir & (glass[:, 0] > 0)))

            r_dir = optics.reflect(d, n)
            # Interpolated normals can tilt a reflection below the surface: use the geometric normal there.
            bad = _dot(r_dir, ng) <= 0
            if bad.any():
                r_dir[bad] = optics.reflect(d[bad], ng[bad])
            fix = (_dot(t_dir, ng) >= 0) & ~tir
            if fix.any():
                t_dir[fix], tir_fix = optics.refract(d[fix], ng[fix], eta_i[fix], eta_r[fix])
                w_tran[fix] = np.where(tir_fix[:, None], 0.0, w_tran[fix])

            cut = st.min_weight
            go_r = np.flatnonzero(w_refl.max(axis=1) > cut)
            go_t = np.flatnonzero(w_tran.max(axis=1) > cut)
            counts.reflection += len(go_r)
            counts.transmission += len(go_t)
            o = np.concatenate([p[go_r] + ng[go_r] * self.eps, p[go_t] - ng[go_t] * self.eps])
            d = np.concatenate([r_dir[go_r], t_dir[go_t]])
            d /= np.maximum(np.sqrt(_dot(d, d)), 1e-30)[:, None]
            weight = np.concatenate([w_refl[go_r], w_tran[go_t]])
            sample = np.concatenate([sample[go_r], sample[go_t]])

        np.nan_to_num(color, copy=False, nan=0.0, posinf=0.0, neginf=0.0)
        return res


def _dot(a, b):
    """Row-wise dot product (N,) of (N, 3) arrays."""
    return np.einsum("ij,ij->i", a, b)


def _accumulate(color: np.ndarray, sample: np.ndarray, values: np.ndarray) -> None:
    """color[sample] += values, summing repeated samples (a sample's reflected and transmitted rays)."""
    n = len(color)
    for c in range(3):
        color[:, c] += np.bincount(sample, weights=values[:, c], minlength=n).astype(np.float32)


def _subset(h: Hits, idx: np.ndarray) -> Hits:
    return Hits(p=h.p[idx], ng=h.ng[idx], n=h.n[idx], front=h.front[idx], material=h.material[idx],
                prim=h.prim[idx], t=h.t[idx])

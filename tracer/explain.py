"""``explain_pixel``: the ray tree of one pixel — every eye, shadow, sky, reflection and transmission ray that made it.

It traces exactly the eye samples :func:`tracer.render` traces for that pixel (same hashes, same settings, the same
:meth:`Integrator.step` kernels), one ray per slot instead of one eye sample per slot, so each ray's own contribution
is known. The explained colour (mean over samples of the sum of every ray's contribution) equals the rendered pixel.
With adaptive sampling, the pixel's tile is first traced as the render traces it, to learn how many samples the
pixel took; those are the samples explained.

Each ray is a :class:`Ray`; :meth:`Explanation.to_json` gives the documented JSON form (README, "Explain a pixel").
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from .accel.accelerator import Accelerator
from .clip_planes import clip_eye_rays
from .geometry.instances import world_frame
from .geometry.motion import frames_at_time
from .integrator import adaptive
from .integrator.tiles import listed_eye_rays, tiles_of, timed_eye_rays, trace_tile_adaptive
from .integrator.wavefront import Integrator, RayQueue, Tile
from .jit import kernel
from .lights import linking
from .scene import Scene
from .settings import RenderSettings

RAY_KINDS = ("eye", "shadow", "reflection", "transmission", "sky")


@dataclass
class Hit:
    t: float
    point: np.ndarray
    geometric_normal: np.ndarray  # unit, turned towards the incident side
    shading_normal: np.ndarray  # unit, same side
    object: str
    object_id: int
    material: str
    material_id: int
    front_face: bool

    def to_json(self) -> dict:
        return {"t": float(self.t), "point": _l(self.point), "geometric_normal": _l(self.geometric_normal),
                "shading_normal": _l(self.shading_normal), "object": self.object, "material": self.material,
                "front_face": bool(self.front_face)}


@dataclass
class Ray:
    """One ray of the tree. ``contribution`` is what it adds to the pixel by itself (its hit's emission, ambient
    and, without shadow rays, direct light; a miss's background; an unblocked shadow ray's light), already
    multiplied by ``weight``, the product of the weights on its path."""

    id: int
    parent: int | None
    type: str
    depth: int
    origin: np.ndarray
    direction: np.ndarray
    t_max: float
    weight: np.ndarray
    contribution: np.ndarray = field(default_factory=lambda: np.zeros(3))
    hit: Hit | None = None
    normal: np.ndarray | None = None  # reflection/transmission: the unit normal its direction was computed from
    eta_i: float | None = None
    eta_r: float | None = None
    tir: bool | None = None
    light: int | None = None  # shadow rays
    light_name: str | None = None
    occluded: bool | None = None
    blocker: str | None = None
    time: float | None = None  # eye rays with motion blur: the sample's time across the shutter (0 open, 1 closed)
    events: list = field(default_factory=list)

    def to_json(self) -> dict:
        j = {"id": self.id, "parent": self.parent, "type": self.type, "depth": self.depth,
             "origin": _l(self.origin), "direction": _l(self.direction),
             "t_max": float(self.t_max) if np.isfinite(self.t_max) else None,
             "weight": _l(self.weight), "contribution": _l(self.contribution),
             "hit": self.hit.to_json() if self.hit is not None else None, "events": list(self.events)}
        if self.type == "eye":
            j["lens"] = _l(self.origin)  # the point of the lens (the aperture) the eye ray leaves from
            if self.time is not None:
                j["time"] = float(self.time)
        if self.type in ("reflection", "transmission"):
            j["normal"] = _l(self.normal)
            if self.eta_i is not None:
                j["eta_i"], j["eta_r"], j["tir"] = float(self.eta_i), float(self.eta_r), bool(self.tir)
        if self.type in ("shadow", "sky"):
            j["light"] = self.light_name if self.type == "shadow" else None
            j["occluded"] = bool(self.occluded)
            if self.occluded:
                j["blocker"] = self.blocker
        return j


@dataclass
class Explanation:
    pixel: tuple
    color: np.ndarray  # (3,) scene-linear, the mean over samples of the sum of contributions
    samples: list  # one list of Ray per eye sample, parents before children
    settings: RenderSettings

    def to_json(self) -> dict:
        return {"pixel": [int(self.pixel[0]), int(self.pixel[1])], "color": _l(self.color),
                "samples": [{"rays": [r.to_json() for r in rays]} for rays in self.samples]}

    def rays(self):
        return [r for rays in self.samples for r in rays]


def _adaptive_samples(scene: Scene, settings: RenderSettings, integ: Integrator, x: int, y: int):
    """(o, d, keys, times) of the samples pixel (x, y) takes under adaptive sampling: its tile of
    :func:`tracer.integrator.tiles.tiles_of` traced in rounds as the render does (the count depends on the pixel's
    neighbours), then the pixel's first ``count`` samples of the progressive order."""
    inside = lambda t: t[0] <= x < t[2] and t[1] <= y < t[3]  # noqa: E731
    x0, y0, x1, y1 = next((t for t in tiles_of(settings) if inside(t)), None) or next(
        t for t in tiles_of(settings.with_(region=None)) if inside(t))
    session = SimpleNamespace(scene=scene, integrator=lambda _settings: integ)
    res = trace_tile_adaptive(session, settings, (x0, y0, x1, y1), lambda: False)
    count = settings.samples ** 2 if res.spent is None else int(res.spent[(y - y0) * (x1 - x0) + (x - x0)])
    o, d, keys, times, _ = listed_eye_rays(scene, settings, np.full(count, x), np.full(count, y),
                                           np.arange(count))
    return o, d, keys, times


def explain_pixel(scene: Scene, settings: RenderSettings, x: int, y: int, accel: Accelerator | None = None,
                  integrator: Integrator | None = None) -> Explanation:
    """The ray tree of pixel (x, y) (image pixels, origin top-left) under ``settings``."""

    settings = settings.validate()
    if not (0 <= x < settings.width and 0 <= y < settings.height):
        raise ValueError(f"pixel ({x}, {y}) is outside the {settings.width}x{settings.height} image")
    integ = integrator if integrator is not None else Integrator(scene, settings, accel)
    if adaptive.enabled(settings):
        o, d, keys, times = _adaptive_samples(scene, settings, integ, x, y)
    else:
        o, d, keys, times = timed_eye_rays(scene, settings, x, y, x + 1, y + 1)
    spp = len(o)
    rays_of = [[] for _ in range(spp)]
    t_max = (np.full(spp, scene.camera.far - scene.camera.near, np.float32) if np.isfinite(scene.camera.far)
             else None)
    if scene.camera.clipping_planes:  # as tracer.integrator.tiles.trace_tile does
        o, t_max = clip_eye_rays(scene.camera, o, d, scene.camera.far - scene.camera.near)
    queue = RayQueue(o=o, d=d, weight=np.ones((spp, 3), np.float32), sample=np.arange(spp, dtype=np.int32),
                     t_max=t_max, time=times)
    # Per ray of the queue: its record, and the eye sample it belongs to.
    records = [_ray(rays_of[s], None, "eye", 0, o[s], d[s], queue.t_max[s] if queue.t_max is not None else np.inf,
                    queue.weight[s]) for s in range(spp)]
    if times is not None:
        for s, rec in enumerate(records):
            rec.time = float(times[s])
    root = np.arange(spp)
    counts = np.zeros(5, np.int64)
    for depth in range(integ.last_depth + 1):
        n = len(queue.o)
        if not n:
            break
        out = Tile(color=np.zeros((n, 3), np.float32), alpha=np.ones(n, np.float32),
                   depth=np.full(n, np.inf, np.float32), normal=np.zeros((n, 3), np.float32),
                   albedo=np.zeros((n, 3), np.float32), object_id=np.full(n, -1, np.int32))
        local = queue._replace(sample=np.arange(n, dtype=np.int32))
        step = integ.step(depth, local, np.ascontiguousarray(keys[root], np.int64), out, counts)
        own = out.color.astype(np.float64)
        _record_hits(scene, integ, records, local, step.hits)
        # Shadow and sky rays: children of the ray whose hit they light; their colour counts if unblocked.
        sh = step.shadow
        blockers = _blockers(integ, sh, step.blocked)
        for j in range(len(sh.o)):
            parent = records[sh.sample[j]]
            kind = "sky" if sh.light[j] < 0 else "shadow"
            r = _ray(rays_of[root[sh.sample[j]]], parent.id, kind, depth, sh.o[j], sh.d[j], sh.t_max[j],
                     parent.weight)
            r.occluded = bool(step.blocked[j])
            if kind == "shadow":
                r.light = int(sh.light[j])
                r.light_name = _light_name(scene, r.light)
            if r.occluded:
                r.blocker = blockers[j]
                r.events.append(f"blocked by {r.blocker}")
            else:
                r.contribution = sh.color[j].astype(np.float64)
                own[sh.sample[j]] -= r.contribution
        for i, rec in enumerate(records):
            rec.contribution = own[i]
            if rec.hit is None:
                rec.events.append("transparent background" if (depth == 0 and out.alpha[i] == 0) else
                                  "miss: background")
        # The next rays: reflections first, then transmissions; each a child of the ray that spawned it.
        nxt, sp = step.next, step.spawned
        new_records = []
        for j in range(len(nxt.o)):
            parent = records[nxt.sample[j]]
            kind = "reflection" if j < step.n_reflected else "transmission"
            r = _ray(rays_of[root[nxt.sample[j]]], parent.id, kind, depth + 1, nxt.o[j], nxt.d[j], np.inf,
                     nxt.weight[j])
            r.normal = sp.normal[j].astype(np.float64)
            eta_i, eta_r = float(sp.eta[j, 0]), float(sp.eta[j, 1])
            if (eta_i, eta_r) != (1.0, 1.0) or kind == "transmission":
                r.eta_i, r.eta_r, r.tir = eta_i, eta_r, bool(sp.tir[j])
            if r.tir:
                r.events.append("total internal reflection")
            if depth + 1 > integ.settings.max_depth:
                r.events.append("terminal ray (collects background and emission only)")
            new_records.append(r)
        _annotate_parents(integ, records, new_records, depth)
        root = root[nxt.sample] if len(nxt.o) else root[:0]
        records = new_records
        queue = nxt
    colors = np.array([sum((r.contribution for r in rays), np.zeros(3)) for rays in rays_of])
    return Explanation(pixel=(x, y), color=colors.mean(axis=0), samples=rays_of, settings=settings)


def _ray(bucket, parent, kind, depth, o, d, t_max, weight) -> Ray:
    r = Ray(id=len(bucket), parent=parent, type=kind, depth=depth, origin=np.asarray(o, np.float64),
            direction=np.asarray(d, np.float64), t_max=float(t_max), weight=np.asarray(weight, np.float64))
    bucket.append(r)
    return r


def _record_hits(scene, integ, records, queue, hits):
    t, prim, u, v, inst = hits
    n = len(prim)
    ng, ns, front = np.zeros((n, 3), np.float32), np.zeros((n, 3), np.float32), np.zeros(n, np.bool_)
    _frames(integ.geometry, integ.instances, prim, inst, queue.d, u, v, ng, ns, front)
    if integ.motion is not None and queue.time is not None:  # what moves: its frame at the ray's time
        frames_at_time(queue.d, prim, inst, u, v, queue.time, integ.geometry, integ.motion, ng, ns, front)
    for i, rec in enumerate(records):
        if prim[i] < 0:
            continue
        tri = int(prim[i])
        oid = int(scene.object_ids[tri]) if inst[i] < 0 else int(integ.instances.object_ids[inst[i]])
        mid = int(scene.material_ids[tri])
        if inst[i] >= 0 and integ.instances.materials[inst[i]] >= 0:
            mid = int(integ.instances.materials[inst[i]])
        names = scene.materials.names
        rec.hit = Hit(t=float(t[i]), point=rec.origin + float(t[i]) * rec.direction,
                      geometric_normal=ng[i].astype(np.float64), shading_normal=ns[i].astype(np.float64),
                      object=scene.object_name(oid), object_id=oid,
                      material=names[mid] if mid < len(names) else f"material{mid}", material_id=mid,
                      front_face=bool(front[i]))


@kernel
def _frames(geom, itab, prim, inst, d, u, v, ng_out, n_out, front_out):
    for i in range(prim.shape[0]):
        if prim[i] < 0:
            continue
        ng, n, front = world_frame(geom, itab, inst[i], prim[i], (float(d[i, 0]), float(d[i, 1]), float(d[i, 2])),
                                   float(u[i]), float(v[i]))
        ng_out[i, 0], ng_out[i, 1], ng_out[i, 2] = ng
        n_out[i, 0], n_out[i, 1], n_out[i, 2] = n
        front_out[i] = front


def _blockers(integ, shadow, blocked) -> list:
    """Names of what blocks each blocked shadow ray (its first hit on the segment)."""
    names = [None] * len(shadow.o)
    idx = np.flatnonzero(blocked)
    if len(idx):
        hits = integ.accel.closest_hits(shadow.o[idx], shadow.d[idx], shadow.t_max[idx],  # what its light sees
                                        mask=linking.shadow_masks(integ.links, shadow.light[idx]))
        scene = integ.scene
        for j, p, k in zip(idx, hits.prim, hits.inst):
            oid = int(scene.object_ids[p]) if k < 0 else int(integ.instances.object_ids[k])
            names[j] = scene.object_name(oid) if p >= 0 else "(unknown)"
    return names


def _annotate_parents(integ, records, children, depth):
    """Events on a hit that explain its children: the Fresnel split of glass, the max depth, the weight cut-off."""
    m = integ.scene.materials
    by_parent = {}
    for c in children:
        by_parent.setdefault(c.parent, []).append(c)
    for rec in records:
        if rec.hit is None:
            continue
        tri_mat = rec.hit.material_id
        k_m, w_t = float(m.k_m[tri_mat]), float(m.transmission[tri_mat])
        wants = k_m > 0 or w_t > 0
        kids = by_parent.get(rec.id, [])
        if not wants:
            continue
        if depth >= integ.last_depth:
            rec.events.append("max depth reached: no reflection/transmission rays")
            continue
        kinds = {c.type for c in kids}
        if w_t > 0 and kinds == {"reflection", "transmission"}:
            refl = next(c for c in kids if c.type == "reflection")
            tran = next(c for c in kids if c.type == "transmission")
            rec.events.append(f"Fresnel split: reflection weight {_fmt(refl.weight / np.maximum(rec.weight, 1e-30))}"
                              f", transmission {_fmt(tran.weight / np.maximum(rec.weight, 1e-30))}")
        if ("reflection" not in kinds) or (w_t > 0 and "transmission" not in kinds and
                                           not any(c.tir for c in kids)):
            rec.events.append("weight cut-off: a secondary ray below min_weight was not traced")


def _light_name(scene, j) -> str:
    if j >= len(scene.lights):  # the last light of the kernels' table: every emissive triangle
        return f"emissive meshes (light {j})"
    light = scene.lights[j]
    return f"{getattr(light, 'name', 'light')} (light {j}, {type(light).__name__})"


def _fmt(v) -> str:
    return "(" + ", ".join(f"{float(c):.4g}" for c in np.asarray(v).reshape(-1)) + ")"


def _l(v):
    return [float(c) for c in np.asarray(v, np.float64).reshape(-1)]


def format_tree(ex: Explanation) -> str:
    """The tree as indented text, one line per ray: type, what it hit, distance, weight, what it adds, events."""
    lines = [f"pixel ({ex.pixel[0]}, {ex.pixel[1]}) = {_fmt(ex.color)} scene-linear, mean of {len(ex.samples)} "
             f"eye sample(s)"]
    for s, rays in enumerate(ex.samples):
        lines.append(f"sample {s}:")
        children = {}
        for r in rays:
            children.setdefault(r.parent, []).append(r)

        def walk(r, indent):
            if r.type in ("shadow", "sky"):
                what = (f"to {r.light_name}" if r.type == "shadow" else "to the sky") + \
                       (f": BLOCKED by {r.blocker}" if r.occluded else ": reaches it")
            elif r.hit is not None:
                side = "" if r.hit.front_face else " (from inside)"
                what = f"hits {r.hit.object} [{r.hit.material}]{side} at t={r.hit.t:.4g}"
            else:
                what = "misses: background"
            extra = ""
            if r.type == "transmission" and r.eta_i is not None:
                extra = f"  η {r.eta_i:g}→{r.eta_r:g}"
            if r.time is not None:
                extra = f"  time {r.time:.3f}"
            ev = [e for e in r.events if not (r.type in ("shadow", "sky") and e.startswith("blocked"))
                  and not e.startswith("miss")]
            lines.append(f"{'  ' * indent}{r.type} #{r.id}{extra}: {what}  weight {_fmt(r.weight)}  "
                         f"adds {_fmt(r.contribution)}" + (f"  [{'; '.join(ev)}]" if ev else ""))
            for c in children.get(r.id, []):
                walk(c, indent + 1)

        for r in children.get(None, []):
            walk(r, 1)
    return "\n".join(lines)


# ------------------------------------------------------------------------------------------- drawing the tree
#: Display colours (sRGB-ish, linear values) per ray type: the same in the PNG overlay, USD curves and Blender.
TYPE_COLORS = {"eye": (1.0, 1.0, 1.0), "shadow": (1.0, 0.85, 0.1), "sky": (0.35, 0.75, 1.0),
               "reflection": (1.0, 0.25, 0.8), "transmission": (0.1, 1.0, 0.45)}


def segments(ex: Explanation, scene: Scene, miss_length: float | None = None):
    """World-space segments of every ray: (start (N, 3), end (N, 3), list of Ray). A ray that hits ends at its hit;
    a shadow ray at its light (or, towards a distant light or the sky, after ``miss_length``); a miss after
    ``miss_length`` (default: the scene's bounding-box diagonal)."""
    far = miss_length if miss_length is not None else max(scene.diagonal, 1.0)
    starts, ends, rays = [], [], []
    for r in ex.rays():
        if r.hit is not None:
            length = r.hit.t
        elif r.type == "shadow" and np.isfinite(r.t_max):
            length = r.t_max
        else:
            length = far
        starts.append(r.origin)
        ends.append(r.origin + r.direction * length)
        rays.append(r)
    return np.array(starts).reshape(-1, 3), np.array(ends).reshape(-1, 3), rays


def draw_overlay(ex: Explanation, scene: Scene, rgba: np.ndarray) -> np.ndarray:
    """The image ``rgba`` (H, W, 4, scene-linear) with the pixel marked and the projections of the ray tree drawn
    over it (colours :data:`TYPE_COLORS`); returns a new (H, W, 4) array."""
    out = np.array(rgba, np.float32, copy=True)
    h, w = out.shape[:2]
    cam = scene.camera
    a, b, rays = segments(ex, scene)
    n_steps = 2 * (w + h)
    t = np.linspace(0.0, 1.0, n_steps)[None, :, None]
    for k in np.argsort([RAY_KINDS.index(r.type) for r in rays], kind="stable")[::-1]:
        pts = a[k][None, None] * (1 - t) + b[k][None, None] * t
        pix = cam.project(pts.reshape(-1, 3), w, h)
        ok = (pix[:, 2] > max(cam.near, 1e-6)) & np.all(np.isfinite(pix), axis=1)
        x, y = np.floor(pix[ok, 0]).astype(int), np.floor(pix[ok, 1]).astype(int)
        for dx, dy in ((0, 0), (1, 0), (0, 1), (1, 1)):  # 2-pixel-wide lines
            xx, yy = x + dx, y + dy
            inside = (xx >= 0) & (xx < w) & (yy >= 0) & (yy < h)
            out[yy[inside], xx[inside], :3] = TYPE_COLORS[rays[k].type]
            out[yy[inside], xx[inside], 3] = 1.0
    # The pixel itself: a white square with a dark outline, 5 px across.
    px, py = ex.pixel
    for r, c in ((3, (0.0, 0.0, 0.0)), (2, (1.0, 1.0, 1.0))):
        ys, xs = np.mgrid[py - r:py + r + 1, px - r:px + r + 1]
        ring = (np.abs(ys - py) == r) | (np.abs(xs - px) == r)
        keep = ring & (xs >= 0) & (xs < w) & (ys >= 0) & (ys < h)
        out[ys[keep], xs[keep], :3] = c
        out[ys[keep], xs[keep], 3] = 1.0
    return out

"""Light sources and what they deliver to a surface point.

Every light answers one question for a point p: for each of its K samples, the unit direction l towards the
light, the distance to it (the shadow ray's t_max), and E, the irradiance it delivers on a surface facing it, already
divided by K. The shading of the seed then multiplies E by the BRDF and max(0, n·l); shadow rays decide which
samples count. The light classes validate and hold a light; :func:`pack_lights` turns a scene's lights into one
set of tables, and :func:`sample_light` (a kernel) answers the question for one point and one sample.

Units are Blender's and Cycles' (measured in ``docs/units.md``):

- :class:`PointLight`: radiant ``intensity`` I in W/sr per channel (a Blender point light of power P has
  I = P / 4π). E = I / (r² + R²), Blender's soft falloff for radius R (R = 0: the inverse-square law).
  A radius > 0 gives soft shadows by sampling points on the light's sphere.
- :class:`SpotLight`: a point light whose E is multiplied by smoothstep of the cosine (Blender's spot blend).
- :class:`DistantLight`: ``irradiance`` in W/m² on a surface facing the light (Blender's sun strength).
- :class:`AreaLight`: a one-sided Lambertian rectangle or disk of ``radiance`` Le (W/m²/sr), sampled.
- Emissive triangles (materials with ``emission``): one light made of every emitting triangle of the scene, each a
  two-sided Lambertian emitter of radiance Le = the material's emission (Cycles' Emission shader: colour ×
  strength). Its K samples pick triangles in proportion to their power (area × mean Le) and a uniform point on
  the chosen one; E = Le·cos θ_l·A/(p·r²) per sample (p the triangle's pick probability), averaged over K.
  When some emitting object is light-linked (``Scene.emitter_links``), each linked object's triangles are a MESH
  light of their own (its own slice of the triangle tables and of the CDF) and the unlinked ones one more.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .. import vec
from ..jit import kernel
from ..sampling import rotated_multijitter, stratum


def _vec3(v, name):
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"light {name} must be 3 finite numbers, got {v!r}")
    return a


def _normalize(v, name):
    a = _vec3(v, name)
    n = np.linalg.norm(a)
    if n == 0:
        raise ValueError(f"light {name} must not be the zero vector")
    return a / n


@dataclass
class LightShaping:
    """UsdLux's ShapingAPI as OpenUSD documents it (user guide, "ShapingAPI"), on the emission of any light with a
    position (point, area, cylinder): for an emission direction ω (unit, from the light towards the receiver) at
    θ = acos(ω·axis) off the light's primary ``axis`` (its −Z),

    - cone: 0 beyond ``cone_angle`` (half angle, radians; ≥ π: no cone); inside, × 1 − smoothstep(θ₀, θc, θ) with
      θ₀ = θc·(1 − softness), softness clamped to [0, 1] (0: a hard edge);
    - focus: × lerp(|ω·axis|^focus, focus_tint, 1), per channel (focus ≤ 0: no change; the default tint black
      makes it a cosine-power falloff)."""

    axis: np.ndarray
    cone_angle: float = math.pi
    softness: float = 0.0
    focus: float = 0.0
    focus_tint: np.ndarray = (0.0, 0.0, 0.0)

    def __post_init__(self):
        self.axis = _normalize(self.axis, "shaping axis")
        self.focus_tint = _vec3(self.focus_tint, "focus tint")
        self.cone_angle = float(self.cone_angle)
        self.softness = float(np.clip(self.softness, 0.0, 1.0))
        self.focus = float(self.focus)
        if not (self.cone_angle > 0 and np.isfinite(self.cone_angle)) or not np.isfinite(self.focus):
            raise ValueError(f"light shaping: cone_angle must be > 0 and focus finite, got {self.cone_angle}, "
                             f"{self.focus}")

    def is_identity(self) -> bool:
        return self.cone_angle >= math.pi and self.focus <= 0.0


def _shaping(shaping, name):
    if shaping is not None and not isinstance(shaping, LightShaping):
        raise ValueError(f"light {name}: shaping must be a LightShaping or None, got {shaping!r}")
    return None if shaping is None or shaping.is_identity() else shaping


def _profile(profile, axes, name):
    if profile is None:
        return None, None
    prof = np.asarray(profile, np.float32)
    if prof.ndim != 2 or min(prof.shape) < 2 or not np.all(np.isfinite(prof)) or prof.min() < 0:
        raise ValueError(f"light {name}: profile must be a finite, non-negative (P, T) table")
    axes = np.asarray(axes, np.float64).reshape(3, 3)
    return np.ascontiguousarray(prof), axes / np.linalg.norm(axes, axis=1, keepdims=True)


@dataclass
class PointLight:
    position: np.ndarray
    intensity: np.ndarray
    radius: float = 0.0
    name: str = "point"
    shaping: LightShaping | None = None
    #: An angular intensity table (an IES profile, usd_io/ies.py): (P, T) factors on a regular grid of φ = 0..2π
    #: (rows) and θ = 0..π (columns), θ from ``profile_axes[2]`` (the nadir), φ from ``profile_axes[0]`` towards
    #: ``profile_axes[1]``; the intensity in direction ω is ``intensity`` × the table's bilinear value there.
    profile: np.ndarray | None = None
    profile_axes: np.ndarray | None = None

    def __post_init__(self):
        self.shaping = _shaping(self.shaping, self.name)
        self.profile, self.profile_axes = _profile(self.profile, self.profile_axes, self.name)
        self.position = _vec3(self.position, "position")
        self.intensity = _vec3(self.intensity, "intensity")
        self.radius = float(self.radius)
        if not np.isfinite(self.radius) or self.radius < 0:
            raise ValueError(f"light {self.name}: radius must be >= 0, got {self.radius}")

    def sample_count(self, requested: int) -> int:
        return 1 if self.radius == 0 else max(1, requested)

    def uses_random(self, requested: int) -> bool:
        return self.sample_count(requested) > 1


@dataclass
class SpotLight(PointLight):
    direction: np.ndarray = None
    cone_angle: float = np.pi / 4
    blend: float = 0.15
    name: str = "spot"

    def __post_init__(self):
        super().__post_init__()
        if self.direction is None:
            raise ValueError(f"light {self.name}: a spot light needs a direction")
        self.direction = _normalize(self.direction, "direction")
        self.cone_angle = float(self.cone_angle)
        self.blend = float(self.blend)  # NaN fails the range checks below (comparisons with NaN are False)
        if not (0 < self.cone_angle <= np.pi):
            raise ValueError(f"light {self.name}: cone_angle must be in (0, π], got {self.cone_angle}")
        if not (0 <= self.blend <= 1):
            raise ValueError(f"light {self.name}: blend must be in [0, 1], got {self.blend}")


@dataclass
class DistantLight:
    direction: np.ndarray
    irradiance: np.ndarray
    angle: float = 0.0
    name: str = "sun"

    def __post_init__(self):
        self.direction = _normalize(self.direction, "direction")
        self.irradiance = _vec3(self.irradiance, "irradiance")
        self.angle = float(self.angle)
        if not (0 <= self.angle < np.pi):
            raise ValueError(f"light {self.name}: angle must be in [0, π), got {self.angle}")

    def sample_count(self, requested: int) -> int:
        return 1 if self.angle == 0 else max(1, requested)

    def uses_random(self, requested: int) -> bool:
        return self.sample_count(requested) > 1


@dataclass
class AreaLight:
    """A one-sided Lambertian emitter centred at ``position``, spanning ``size`` along ``u_axis`` and ``v_axis``,
    emitting along ``normal`` (Blender: the light's −Z). ``shape`` is "rect" or "disk" (an ellipse for unequal sizes),
    or "cylinder": UsdLux's CylinderLight, a tube of length ``size[0]`` along ``u_axis`` and diameter ``size[1]``
    emitting outwards from its side (not its end caps), Lambertian at every point of its surface. ``shaping``: an
    optional :class:`LightShaping` (UsdLux's ShapingAPI). ``texture``: an optional (H, W, 3) linear image multiplying a
    rect light's radiance per point (UsdLux's ``texture:file``): u runs from 0 to 1 along ``u_axis``, v along
    ``v_axis``, image row 0 at v = 1 (the top), filtered bilinearly; its light samples and the rays that see it read
    the texture where they meet the light.
    ``spread`` (radians, π = none) narrows the emission as Blender's Spread does (Cycles' soft-box grid,
    :func:`spread_table`): radiance × max((tan(spread/2) − tan θ)·N, 0) at θ from the normal, N keeping the power."""

    position: np.ndarray
    u_axis: np.ndarray
    v_axis: np.ndarray
    normal: np.ndarray
    size: tuple = (1.0, 1.0)
    radiance: np.ndarray = None
    shape: str = "rect"
    name: str = "area"
    spread: float = math.pi
    shaping: LightShaping | None = None
    texture: np.ndarray | None = None
    profile: np.ndarray | None = None  # an IES table, as PointLight's, at every point of the emitter
    profile_axes: np.ndarray | None = None

    def __post_init__(self):
        self.shaping = _shaping(self.shaping, self.name)
        self.profile, self.profile_axes = _profile(self.profile, self.profile_axes, self.name)
        if self.texture is not None:
            tex = np.asarray(self.texture, np.float32)
            if tex.ndim != 3 or tex.shape[2] != 3 or min(tex.shape[:2]) < 1 or not np.all(np.isfinite(tex)):
                raise ValueError(f"light {self.name}: texture must be a finite (H, W, 3) image, got {tex.shape}")
            if self.shape != "rect":
                raise ValueError(f"light {self.name}: only a rect light takes a texture")
            self.texture = np.ascontiguousarray(tex)
        self.position = _vec3(self.position, "position")
        self.spread = float(self.spread)
        if not (0.0 <= self.spread <= math.pi + 1e-6):
            raise ValueError(f"light {self.name}: spread must be in [0, π], got {self.spread}")
        self.u_axis = _normalize(self.u_axis, "u_axis")
        self.v_axis = _normalize(self.v_axis, "v_axis")
        self.normal = _normalize(self.normal, "normal")
        self.size = (float(self.size[0]), float(self.size[1]))
        if not all(np.isfinite(self.size)) or min(self.size) <= 0:
            raise ValueError(f"light {self.name}: size must be > 0, got {self.size}")
        if self.radiance is None:
            raise ValueError(f"light {self.name}: an area light needs a radiance")
        self.radiance = _vec3(self.radiance, "radiance")
        if self.shape not in ("rect", "disk", "cylinder"):
            raise ValueError(f"light {self.name}: shape must be 'rect', 'disk' or 'cylinder', got {self.shape!r}")

    @property
    def area(self) -> float:
        return AreaLight.area_of(self.size, self.shape)

    @staticmethod
    def area_of(size, shape: str = "rect") -> float:
        """The emitting area of a ``size`` (sx, sy) light: a rectangle sx·sy, a disk (ellipse) π/4·sx·sy, a cylinder's
        side π·sy·sx (length sx, diameter sy). The one place this is written (the add-on's power conversion and its
        unnormalized lights use it)."""
        sx, sy = size
        if shape == "cylinder":
            return np.pi * sy * sx
        return sx * sy if shape == "rect" else np.pi / 4 * sx * sy

    def sample_count(self, requested: int) -> int:
        return max(1, requested)

    def uses_random(self, requested: int) -> bool:
        return True


Light = PointLight | SpotLight | DistantLight | AreaLight


def spread_table(spread: float) -> tuple[float, float]:
    """(tan(s/2), N) of an area light's Spread s as Cycles sets them (scene/light.cpp): the attenuation
    max((tan(s/2) − tan θ)·N, 0) keeps the power when ∫ f·cos θ dω = π, i.e. N = 1/(tan(s/2) − s/2) (its series
    3/(s/2)³ below s/2 = 0.05, as Cycles). (0, 0): no spread (s = π); a spread under 1e-3 rad is taken as 1e-3
    (Cycles' s = 0, a light seen only along its normal, cannot be met by sampling the area)."""
    if spread >= math.pi - 1e-6:
        return 0.0, 0.0
    h = max(spread, 1e-3) / 2.0
    t = math.tan(h)
    return t, (1.0 / (t - h) if h > 0.05 else 3.0 / h ** 3)

# ---------------------------------------------------------------------- the packed light tables
#: Light kinds in the packed tables.
POINT, SPOT, DISTANT, RECT, DISK, MESH, CYLINDER = 0, 1, 2, 3, 4, 5, 6


class LightTables(NamedTuple):
    """The scene's lights as the kernels read them, one row per light in each field (the fields a kind does not use
    stay 0); the emissive triangles of the MESH lights (if any: the last rows, each a slice tri_start:tri_end) as
    vertices, radiance and the cumulative distribution of their power within each slice."""

    kind: np.ndarray  # (L,) int64: POINT, SPOT, DISTANT, RECT, DISK, MESH or CYLINDER
    side: np.ndarray  # (L,) int64: √ of the light's sample count
    position: np.ndarray  # (L, 3) float64: point, spot, area centre
    color: np.ndarray  # (L, 3) float64: intensity (W/sr), irradiance (W/m²) or radiance (W/m²/sr)
    radius: np.ndarray  # (L,) float64: point and spot radius, cylinder radius
    direction: np.ndarray  # (L, 3) float64: spot axis, sun direction (travel), area normal (emitting side)
    cos_cone: np.ndarray  # (L,) float64: spot, cos(size/2)
    blend: np.ndarray  # (L,) float64: spot blend
    cos_max: np.ndarray  # (L,) float64: sun, cos(angle/2)
    u_axis: np.ndarray  # (L, 3) float64: area, unit edge directions (cylinder: its axis)
    v_axis: np.ndarray  # (L, 3) float64
    size: np.ndarray  # (L, 2) float64: area, extents along u and v (cylinder: length, diameter)
    area: np.ndarray  # (L,) float64: area, its area
    spread: np.ndarray  # (L, 2) float64: area, (tan(spread/2), N) of :func:`spread_table`; N = 0: no spread
    shaped: np.ndarray  # (L,) int64: 1 where the light has a LightShaping (the four rows below)
    shape_axis: np.ndarray  # (L, 3) float64: its primary axis
    shape_cone: np.ndarray  # (L, 2) float64: (θ₀, θc) of its cone, radians (θc ≥ π: no cone)
    focus: np.ndarray  # (L,) float64: its focus exponent (≤ 0: none)
    focus_tint: np.ndarray  # (L, 3) float64
    tex: np.ndarray  # (M, 3) float32: the textured rect lights' texels, each light's image row-major from the top
    tex_start: np.ndarray  # (L,) int64: a textured light's first row in tex
    tex_size: np.ndarray  # (L, 2) int64: its image's (width, height); (0, 0): not textured
    prof: np.ndarray  # (M,) float32: the profiled lights' tables, each row-major (φ rows, θ columns)
    prof_start: np.ndarray  # (L,) int64: a profiled light's first entry in prof
    prof_size: np.ndarray  # (L, 2) int64: its table's (P, T); (0, 0): no profile
    prof_axes: np.ndarray  # (L, 3, 3) float64: its C0, C90 and nadir axes
    tri: np.ndarray  # (N, 3, 3) float64 emitting triangles, world space
    tri_le: np.ndarray  # (N, 3) float64 their radiance
    tri_cdf: np.ndarray  # (N,) float64 cumulative pick probability (power-proportional) within each light's slice
    tri_start: np.ndarray  # (L,) int64: a MESH light's triangles are rows tri_start:tri_end (its CDF ends at 1)
    tri_end: np.ndarray  # (L,) int64
    emitter_object: np.ndarray  # (L,) int64: a MESH light's object id (-1: the unlinked emitters, or no MESH)


def emitting_triangles(vertices, triangles, material_ids, emission):
    """(tri (N, 3, 3), Le (N, 3)) of the triangles whose material emits."""
    emission = np.asarray(emission, np.float64)
    glowing = np.flatnonzero(emission.max(axis=1) > 0) if len(emission) else np.zeros(0, np.int64)
    sel = np.flatnonzero(np.isin(material_ids, glowing))
    tri = np.asarray(vertices, np.float64)[np.asarray(triangles)[sel]]
    return tri, emission[np.asarray(material_ids)[sel]]


def _canonical_order(tri: np.ndarray) -> np.ndarray:
    """An order of emitting triangles that does not depend on how the scene listed them (flat or instanced, objects
    in any order): by centroid, quantised to 1e-6 of the emitters' extent so that float rounding of the same
    triangle placed two ways does not reorder it. The power CDF maps strata to triangles in this order."""
    c = tri.mean(axis=1)
    extent = float(np.ptp(c, axis=0).max()) if len(c) > 1 else 0.0
    q = np.round(c / (extent * 1e-6)).astype(np.int64) if extent > 0 else np.zeros_like(c, np.int64)
    return np.lexsort((q[:, 2], q[:, 1], q[:, 0]))


def _emitter_groups(tri, tri_le, objects, linked) -> tuple:
    """The emitting triangles with power > 0 as (tri, Le, cdf, groups): triangles of each group contiguous and in
    canonical order, cdf the power CDF within each group (its last entry 1), groups a list of (object id or -1,
    start, end). One group (-1) unless ``linked`` names emitting objects: then each of those its own group, after
    the group of all the others."""
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    power = area * tri_le.mean(axis=1)
    keep = power > 0
    tri, tri_le, power = tri[keep], tri_le[keep], power[keep]
    key = np.full(len(tri), -1, np.int64)
    if objects is not None and len(linked):
        obj = np.asarray(objects, np.int64)[keep]
        own = np.isin(obj, np.asarray(sorted(linked), np.int64))
        key[own] = obj[own]
    rows, groups, cdfs = [], [], []
    start = 0
    for g in np.unique(key):
        sel = np.flatnonzero(key == g)
        sel = sel[_canonical_order(tri[sel])]  # the same emitters listed in another order sample the same points
        c = np.cumsum(power[sel]) / power[sel].sum()
        c[-1:] = 1.0
        rows.append(sel)
        cdfs.append(c)
        groups.append((int(g), start, start + len(sel)))
        start += len(sel)
    order = np.concatenate(rows) if rows else np.zeros(0, np.int64)
    cdf = np.concatenate(cdfs) if cdfs else np.zeros(0, np.float64)
    return tri[order], tri_le[order], cdf, groups


def pack_lights(lights: list, light_samples: int, emitters=None, linked=()) -> LightTables:
    """The lights as a :class:`LightTables`, read by :func:`sample_light`. A light with an extent takes side×side
    stratified samples, side = round(√light_samples). ``emitters`` = (tri (N, 3, 3), Le (N, 3)) or (tri, Le,
    object id (N,)) adds the emissive triangles as one more light (see :func:`emitting_triangles`), or, for the
    object ids in ``linked`` that emit, one light per such object after the one of all the others."""
    tri = np.zeros((0, 3, 3), np.float64)
    tri_le = np.zeros((0, 3), np.float64)
    cdf = np.zeros(0, np.float64)
    groups = []
    if emitters is not None and len(emitters[0]):
        tri, tri_le, cdf, groups = _emitter_groups(
            np.ascontiguousarray(emitters[0], np.float64), np.ascontiguousarray(emitters[1], np.float64),
            emitters[2] if len(emitters) > 2 else None, linked)
    n = len(lights) + len(groups)
    images = [getattr(lt, "texture", None) for lt in lights]
    tex = np.concatenate([im.reshape(-1, 3) for im in images if im is not None] or [np.zeros((1, 3))])
    tex = np.ascontiguousarray(tex, np.float32)
    profiles = [getattr(lt, "profile", None) for lt in lights]
    prof = np.concatenate([p.reshape(-1) for p in profiles if p is not None] or [np.zeros(1)])
    prof = np.ascontiguousarray(prof, np.float32)
    f1, f2, f3 = (lambda: np.zeros(n, np.float64)), (lambda: np.zeros((n, 2))), (lambda: np.zeros((n, 3)))
    t = LightTables(kind=np.zeros(n, np.int64), side=np.ones(n, np.int64), position=f3(), color=f3(), radius=f1(),
                    direction=f3(), cos_cone=f1(), blend=f1(), cos_max=f1(), u_axis=f3(), v_axis=f3(), size=f2(),
                    area=f1(), spread=f2(), shaped=np.zeros(n, np.int64), shape_axis=f3(), shape_cone=f2(),
                    focus=f1(), focus_tint=f3(), tex=tex, tex_start=np.zeros(n, np.int64),
                    tex_size=np.zeros((n, 2), np.int64), prof=prof, prof_start=np.zeros(n, np.int64),
                    prof_size=np.zeros((n, 2), np.int64), prof_axes=np.zeros((n, 3, 3)), tri=tri, tri_le=tri_le, tri_cdf=cdf, tri_start=np.zeros(n, np.int64),
                    tri_end=np.zeros(n, np.int64), emitter_object=np.full(n, -1, np.int64))
    for i, (obj, start, end) in enumerate(groups, start=len(lights)):
        t.kind[i] = MESH
        t.side[i] = max(1, int(round(np.sqrt(max(1, light_samples)))))
        t.tri_start[i], t.tri_end[i], t.emitter_object[i] = start, end, obj
    for i, light in enumerate(lights):
        t.side[i] = max(1, int(round(np.sqrt(light.sample_count(light_samples)))))
        if isinstance(light, PointLight):  # SpotLight included
            t.kind[i] = SPOT if isinstance(light, SpotLight) else POINT
            t.position[i], t.color[i], t.radius[i] = light.position, light.intensity, light.radius
            if t.kind[i] == SPOT:
                t.direction[i], t.cos_cone[i], t.blend[i] = light.direction, np.cos(light.cone_angle), light.blend
        elif isinstance(light, DistantLight):
            t.kind[i] = DISTANT
            t.direction[i], t.color[i], t.cos_max[i] = light.direction, light.irradiance, np.cos(light.angle / 2)
        else:
            t.kind[i] = {"rect": RECT, "disk": DISK, "cylinder": CYLINDER}[light.shape]
            t.position[i], t.color[i], t.direction[i] = light.position, light.radiance, light.normal
            t.u_axis[i], t.v_axis[i], t.size[i], t.area[i] = light.u_axis, light.v_axis, light.size, light.area
            t.spread[i] = spread_table(light.spread)
            if light.shape == "cylinder":
                t.radius[i] = light.size[1] / 2
        if profiles[i] is not None:
            t.prof_start[i] = sum(p.size for p in profiles[:i] if p is not None)
            t.prof_size[i] = profiles[i].shape
            t.prof_axes[i] = light.profile_axes
        if images[i] is not None:
            t.tex_start[i] = sum(im.shape[0] * im.shape[1] for im in images[:i] if im is not None)
            t.tex_size[i] = (images[i].shape[1], images[i].shape[0])
        sh = getattr(light, "shaping", None)
        if sh is not None:
            t.shaped[i], t.shape_axis[i], t.focus[i], t.focus_tint[i] = 1, sh.axis, sh.focus, sh.focus_tint
            t.shape_cone[i] = (sh.cone_angle * (1.0 - sh.softness), sh.cone_angle)
    return t


@kernel(inline=True)
def _sample_emitters(tri, tri_le, cdf, start, end, k, sd, kk, p, r0, r1):
    """Stratum k of the emissive triangles start:end (one MESH light): the first coordinate picks a triangle by the power CDF (its remainder,
    rescaled, and the second place a uniform point on it), E = Le·|cos θ_l|·A/(p_pick·r²)/K (two-sided). The points
    are multi-jittered (side² distinct values of the first coordinate: each triangle of a small emitter gets its own
    strata, and a large one well spread points)."""
    s0, s1 = rotated_multijitter(k, sd, r0, r1)
    lo, hi = start, end - 1
    while lo < hi:  # the first triangle whose cumulative probability exceeds s0
        mid = (lo + hi) // 2
        if cdf[mid] > s0:
            hi = mid
        else:
            lo = mid + 1
    before = cdf[lo - 1] if lo > start else 0.0
    pick = max(cdf[lo] - before, 1e-30)
    u = min(max((s0 - before) / pick, 0.0), 1.0 - 1e-7)
    su = math.sqrt(u)
    a = (tri[lo, 0, 0], tri[lo, 0, 1], tri[lo, 0, 2])
    b = (tri[lo, 1, 0], tri[lo, 1, 1], tri[lo, 1, 2])
    c = (tri[lo, 2, 0], tri[lo, 2, 1], tri[lo, 2, 2])
    e1, e2 = vec.sub(b, a), vec.sub(c, a)
    pt = vec.madd(vec.madd(a, e1, su * (1.0 - s1)), e2, su * s1)
    cr = vec.cross(e1, e2)
    twice_area = vec.length(cr)
    to_l = vec.sub(pt, p)
    d2 = max(vec.dot(to_l, to_l), 1e-30)
    dist = math.sqrt(d2)
    l = vec.scale(to_l, 1.0 / dist)
    cos_l = abs(vec.dot(l, cr)) / max(twice_area, 1e-30)
    le = (tri_le[lo, 0], tri_le[lo, 1], tri_le[lo, 2])
    return l, dist, vec.scale(le, cos_l * 0.5 * twice_area / pick / d2 / kk)


@kernel(inline=True)
def spot_falloff(cos_a, cos_cone, blend):
    """Blender's spot: smoothstep(x), x = (cos α − cos(size/2)) / ((1 − cos(size/2))·blend), in cosine."""
    if blend <= 0.0:
        return 1.0 if cos_a > cos_cone else 0.0
    x = min(max((cos_a - cos_cone) / ((1.0 - cos_cone) * blend), 0.0), 1.0)
    return x * x * (3.0 - 2.0 * x)


@kernel(inline=True)
def light_texel(lights, j, u, v):
    """Light j's texture at (u, v) in [0, 1]² (v = 1 the image's top row), bilinear with the edges clamped; (1, 1, 1)
    for a light without one."""
    w, h = lights.tex_size[j, 0], lights.tex_size[j, 1]
    if w == 0:
        return (1.0, 1.0, 1.0)
    x = min(max(u * w - 0.5, 0.0), w - 1.0)
    y = min(max((1.0 - v) * h - 0.5, 0.0), h - 1.0)
    x0, y0 = int(x), int(y)
    x1, y1 = min(x0 + 1, w - 1), min(y0 + 1, h - 1)
    fx, fy = x - x0, y - y0
    tex = lights.tex
    i00 = lights.tex_start[j] + y0 * w + x0
    i01 = lights.tex_start[j] + y0 * w + x1
    i10 = lights.tex_start[j] + y1 * w + x0
    i11 = lights.tex_start[j] + y1 * w + x1
    w00, w01, w10, w11 = (1.0 - fx) * (1.0 - fy), fx * (1.0 - fy), (1.0 - fx) * fy, fx * fy
    return (w00 * tex[i00, 0] + w01 * tex[i01, 0] + w10 * tex[i10, 0] + w11 * tex[i11, 0],
            w00 * tex[i00, 1] + w01 * tex[i01, 1] + w10 * tex[i10, 1] + w11 * tex[i11, 1],
            w00 * tex[i00, 2] + w01 * tex[i01, 2] + w10 * tex[i10, 2] + w11 * tex[i11, 2])


@kernel(inline=True)
def profile_factor(lights, j, w):
    """Light j's angular intensity table (an IES profile) in the unit emission direction ``w``, bilinear; 1 for a
    light without one."""
    n_p, n_t = lights.prof_size[j, 0], lights.prof_size[j, 1]
    if n_t == 0:
        return 1.0
    cx = w[0] * lights.prof_axes[j, 0, 0] + w[1] * lights.prof_axes[j, 0, 1] + w[2] * lights.prof_axes[j, 0, 2]
    cy = w[0] * lights.prof_axes[j, 1, 0] + w[1] * lights.prof_axes[j, 1, 1] + w[2] * lights.prof_axes[j, 1, 2]
    cz = w[0] * lights.prof_axes[j, 2, 0] + w[1] * lights.prof_axes[j, 2, 1] + w[2] * lights.prof_axes[j, 2, 2]
    t = math.acos(min(max(cz, -1.0), 1.0)) / math.pi * (n_t - 1)
    ph = math.atan2(cy, cx)
    if ph < 0.0:
        ph += 2.0 * math.pi
    p = min(ph / (2.0 * math.pi) * (n_p - 1), n_p - 1.0)
    t0, p0 = min(int(t), n_t - 2), min(int(p), n_p - 2)
    ft, fp = t - t0, p - p0
    base = lights.prof_start[j]
    a = lights.prof[base + p0 * n_t + t0] * (1.0 - ft) + lights.prof[base + p0 * n_t + t0 + 1] * ft
    b = lights.prof[base + (p0 + 1) * n_t + t0] * (1.0 - ft) + lights.prof[base + (p0 + 1) * n_t + t0 + 1] * ft
    return a * (1.0 - fp) + b * fp


@kernel(inline=True)
def shaping_factor(lights, j, w):
    """Light j's :class:`LightShaping` for the unit emission direction ``w`` (from the light towards the receiver),
    per channel: (1, 1, 1) for an unshaped light."""
    if lights.shaped[j] == 0:
        return (1.0, 1.0, 1.0)
    c = vec.dot(w, vec.row(lights.shape_axis, j))
    f = 1.0
    start, cut = lights.shape_cone[j, 0], lights.shape_cone[j, 1]
    if cut < math.pi:
        theta = math.acos(min(max(c, -1.0), 1.0))
        if theta > cut:
            return (0.0, 0.0, 0.0)
        if theta > start:
            x = (theta - start) / (cut - start)
            f = 1.0 - x * x * (3.0 - 2.0 * x)
    focus = lights.focus[j]
    if focus <= 0.0:
        return (f, f, f)
    g = abs(c) ** focus
    return (f * (lights.focus_tint[j, 0] + g * (1.0 - lights.focus_tint[j, 0])),
            f * (lights.focus_tint[j, 1] + g * (1.0 - lights.focus_tint[j, 1])),
            f * (lights.focus_tint[j, 2] + g * (1.0 - lights.focus_tint[j, 2])))


@kernel(inline=True)
def _sample_cylinder(lights, j, k, sd, kk, p, r0, r1):
    """Stratum k of cylinder light j's side seen from p: a point uniform in area on the half of the tube that faces p
    (every point of the tube p can see lies in it), E = Le·cos θ_l·(π·r·length)/r²/K."""
    pos = vec.row(lights.position, j)
    ax = vec.row(lights.u_axis, j)
    radius, length = lights.radius[j], lights.size[j, 0]
    to_p = vec.sub(p, pos)
    perp = vec.madd(to_p, ax, -vec.dot(to_p, ax))
    pl = vec.length(perp)
    if pl > 1e-9 * (vec.length(to_p) + radius):  # (rounding leaves a near-zero perp that is not perpendicular)
        e1 = vec.scale(perp, 1.0 / pl)
    else:
        e1 = vec.orthonormal_basis(ax)[0]
    e2 = vec.cross(ax, e1)
    s0, s1 = stratum(k, sd, r0, r1)
    phi = (s1 - 0.5) * math.pi
    nrm = vec.madd(vec.scale(e1, math.cos(phi)), e2, math.sin(phi))
    pt = vec.madd(vec.madd(pos, ax, (s0 - 0.5) * length), nrm, radius)
    to_l = vec.sub(pt, p)
    d2 = max(vec.dot(to_l, to_l), 1e-30)
    dist = math.sqrt(d2)
    l = vec.scale(to_l, 1.0 / dist)
    cos_l = max(0.0, -vec.dot(l, nrm))
    f = cos_l * math.pi * radius * length / d2 / kk
    return l, dist, vec.scale(vec.row(lights.color, j), f)


@kernel(inline=True)
def _rect_solid_angle_sample(lights, j, p, s0, s1):
    """(a, b, Ω): a point of rect light j, (a, b) ∈ [−½, ½]² along its u and v axes, uniform in the solid angle Ω
    the rectangle subtends at p (Ureña, Fajardo and King 2013, "An area-preserving parametrization for spherical
    rectangles"), for (s0, s1) ∈ [0, 1)². Ω = 0 (and a point uniform in area) where p is (nearly) in its plane."""
    w, h = lights.size[j, 0], lights.size[j, 1]
    ux, vy = vec.row(lights.u_axis, j), vec.row(lights.v_axis, j)
    corner = vec.madd(vec.madd(vec.row(lights.position, j), ux, -0.5 * w), vy, -0.5 * h)
    dd = vec.sub(corner, p)
    x0, y0 = vec.dot(dd, ux), vec.dot(dd, vy)
    z0 = -abs(vec.dot(dd, vec.cross(ux, vy)))
    x1, y1 = x0 + w, y0 + h
    if z0 > -1e-7 * (w + h):
        return s0 - 0.5, s1 - 0.5, 0.0
    n0z = -y0 / math.sqrt(z0 * z0 + y0 * y0)
    n1z = x1 / math.sqrt(z0 * z0 + x1 * x1)
    n2z = y1 / math.sqrt(z0 * z0 + y1 * y1)
    n3z = -x0 / math.sqrt(z0 * z0 + x0 * x0)
    g0 = math.acos(min(max(-n0z * n1z, -1.0), 1.0))
    g1 = math.acos(min(max(-n1z * n2z, -1.0), 1.0))
    g2 = math.acos(min(max(-n2z * n3z, -1.0), 1.0))
    g3 = math.acos(min(max(-n3z * n0z, -1.0), 1.0))
    solid = g0 + g1 + g2 + g3 - 2.0 * math.pi
    if not (solid > 1e-9):
        return s0 - 0.5, s1 - 0.5, 0.0
    au = s0 * solid + 2.0 * math.pi - g2 - g3
    sa = math.sin(au)
    if abs(sa) < 1e-12:
        sa = 1e-12
    fu = (math.cos(au) * n0z - n2z) / sa
    cu = 1.0 / math.sqrt(fu * fu + n0z * n0z)
    if fu < 0.0:
        cu = -cu
    cu = min(max(cu, -1.0), 1.0)
    xu = -(cu * z0) / math.sqrt(max(1.0 - cu * cu, 1e-30))
    xu = min(max(xu, x0), x1)
    d = math.sqrt(xu * xu + z0 * z0)
    h0 = y0 / math.sqrt(d * d + y0 * y0)
    h1 = y1 / math.sqrt(d * d + y1 * y1)
    hv = h0 + s1 * (h1 - h0)
    yv = hv * d / math.sqrt(1.0 - hv * hv) if hv * hv < 1.0 - 1e-9 else y1
    yv = min(max(yv, y0), y1)
    return (xu - x0) / w - 0.5, (yv - y0) / h - 0.5, solid


@kernel(inline=True)
def sample_light(lights, j, k, p, r0, r1):
    """:func:`_sample_light_unshaped` × the light's :func:`shaping_factor` (UsdLux's ShapingAPI) and
    :func:`profile_factor` (its IES profile)."""
    l, dist, e = _sample_light_unshaped(lights, j, k, p, r0, r1)
    if lights.shaped[j] != 0:
        e = vec.mul(e, shaping_factor(lights, j, vec.scale(l, -1.0)))
    if lights.prof_size[j, 1] != 0:  # an IES profile: from a point light's photometric centre (its centre), from
        kd = lights.kind[j]  # the sample on an area light (each of its points emits with the profile)
        w = vec.normalize(vec.sub(p, vec.row(lights.position, j))) if kd == POINT or kd == SPOT else vec.scale(l, -1.0)
        e = vec.scale(e, profile_factor(lights, j, w))
    return l, dist, e


@kernel(inline=True)
def _sample_light_unshaped(lights, j, k, p, r0, r1):
    """Sample ``k`` (of side²) of light ``j`` of a :class:`LightTables` seen from point p: (l, dist, E) with l the
    unit direction to the light, dist the shadow ray's length and E the irradiance on a surface facing the light,
    divided by side². (r0, r1) in [0,1)² rotate the stratified pattern of lights with an extent. (Called from
    kernels compiled without reference counting, ``kernel(refcounts=False)``: a NamedTuple of arrays handed to an
    inlined helper costs nothing there.)"""
    sd = lights.side[j]
    kk = sd * sd
    kd = lights.kind[j]
    if kd == MESH:
        return _sample_emitters(lights.tri, lights.tri_le, lights.tri_cdf, lights.tri_start[j], lights.tri_end[j],
                                k, sd, kk, p, r0, r1)
    if kd == CYLINDER:
        return _sample_cylinder(lights, j, k, sd, kk, p, r0, r1)
    if kd == POINT or kd == SPOT:
        pos = vec.row(lights.position, j)
        radius = lights.radius[j]
        to_c = vec.sub(pos, p)
        d2 = vec.dot(to_c, to_c)
        # Blender's soft falloff: irradiance I / (r² + R²), measured against Cycles.
        inv = 1.0 / (d2 + radius * radius)
        dist = math.sqrt(d2)
        if kd == SPOT:
            cos_a = -vec.dot(to_c, vec.row(lights.direction, j)) / math.sqrt(max(d2, 1e-30))
            inv *= spot_falloff(cos_a, lights.cos_cone[j], lights.blend[j])
        e = vec.scale(vec.row(lights.color, j), inv / kk)
        if kk == 1:
            return vec.scale(to_c, 1.0 / max(dist, 1e-30)), dist, e
        # Soft shadows: stratified points on the disk of the sphere that faces p.
        u, v = vec.orthonormal_basis(vec.scale(to_c, -1.0 / max(dist, 1e-30)))
        s0, s1 = stratum(k, sd, r0, r1)
        r = radius * math.sqrt(s0)
        phi = 2.0 * math.pi * s1
        to_l = vec.sub(vec.madd(vec.madd(pos, u, r * math.cos(phi)), v, r * math.sin(phi)), p)
        ld = vec.length(to_l)
        return vec.scale(to_l, 1.0 / max(ld, 1e-30)), ld, e
    if kd == DISTANT:
        to_light = vec.scale(vec.row(lights.direction, j), -1.0)
        e = vec.scale(vec.row(lights.color, j), 1.0 / kk)
        if kk == 1:
            return to_light, math.inf, e
        # A disk of angular diameter `angle` around the direction to the sun, sampled uniformly in solid angle.
        u, v = vec.orthonormal_basis(to_light)
        s0, s1 = stratum(k, sd, r0, r1)
        cos_t = 1.0 - s0 * (1.0 - lights.cos_max[j])
        sin_t = math.sqrt(max(0.0, 1.0 - cos_t * cos_t))
        phi = 2.0 * math.pi * s1
        l = vec.madd(vec.madd(vec.scale(to_light, cos_t), u, sin_t * math.cos(phi)), v, sin_t * math.sin(phi))
        return l, math.inf, e
    # Area light: a point on the rectangle (uniform in the solid angle it subtends, else in its area), or on the
    # (elliptical) disk by a polar mapping.
    s0, s1 = stratum(k, sd, r0, r1)
    solid = 0.0
    if kd == RECT:
        a, b, solid = _rect_solid_angle_sample(lights, j, p, s0, s1)
    else:
        r = 0.5 * math.sqrt(s0)
        a, b = r * math.cos(2.0 * math.pi * s1), r * math.sin(2.0 * math.pi * s1)
    pt = vec.madd(vec.madd(vec.row(lights.position, j), vec.row(lights.u_axis, j), a * lights.size[j, 0]),
                  vec.row(lights.v_axis, j), b * lights.size[j, 1])
    to_l = vec.sub(pt, p)
    d2 = max(vec.dot(to_l, to_l), 1e-30)
    dist = math.sqrt(d2)
    l = vec.scale(to_l, 1.0 / dist)
    cos_l = max(0.0, -vec.dot(l, vec.row(lights.direction, j)))
    # E from a sample of a Lambertian emitter: Le · cosθ_l · A / r² for a point uniform in area, Le · Ω for one
    # uniform in the solid angle Ω (0 from its back), averaged over the K samples.
    if solid > 0.0:
        f = (solid if cos_l > 0.0 else 0.0) / kk
    else:
        f = cos_l * lights.area[j] / d2 / kk
    norm = lights.spread[j, 1]
    if norm > 0.0 and cos_l > 0.0:  # Blender's Spread: the soft box's grid hides light at angle θ > spread/2
        tan_a = math.sqrt(max(1.0 - cos_l * cos_l, 0.0)) / cos_l
        f *= max((lights.spread[j, 0] - tan_a) * norm, 0.0)
    le = vec.row(lights.color, j)
    if lights.tex_size[j, 0] > 0:  # a textured rect light: its radiance where the sample lies
        le = vec.mul(le, light_texel(lights, j, a + 0.5, b + 0.5))
    return l, dist, vec.scale(le, f)


def hittable(light) -> bool:
    """Whether a ray can meet the light's shape (Cycles intersects these with camera, glossy and transmission rays,
    each as the light's ray visibility allows): an area light, a point or spot light with a radius (a sphere), a
    sun with an angle (a disk in the sky). Radius- and angle-0 lights are points: only light samples see them."""
    if isinstance(light, AreaLight):
        return True
    if isinstance(light, PointLight):  # SpotLight included
        return light.radius > 0.0
    if isinstance(light, DistantLight):
        return light.angle > 0.0
    return False


@kernel(inline=True)
def lamp_hit(lights, j, o, d, t_max):
    """:func:`_lamp_hit_unshaped` × the light's :func:`shaping_factor` towards the ray's origin."""
    t, le = _lamp_hit_unshaped(lights, j, o, d, t_max)
    if lights.shaped[j] != 0 and t < t_max:
        le = vec.mul(le, shaping_factor(lights, j, vec.scale(d, -1.0)))
    if lights.prof_size[j, 1] != 0 and t < t_max:
        le = vec.scale(le, profile_factor(lights, j, vec.scale(d, -1.0)))
    return t, le


@kernel(inline=True)
def _lamp_hit_cylinder(lights, j, o, d, t_max):
    """(t, Le) where the ray meets cylinder light j's side from outside (its end caps and inside emit nothing)."""
    pos = vec.row(lights.position, j)
    ax = vec.row(lights.u_axis, j)
    radius, length = lights.radius[j], lights.size[j, 0]
    oc = vec.sub(o, pos)
    dp = vec.madd(d, ax, -vec.dot(d, ax))
    op = vec.madd(oc, ax, -vec.dot(oc, ax))
    a = vec.dot(dp, dp)
    if a <= 1e-24:
        return math.inf, (0.0, 0.0, 0.0)
    b = vec.dot(op, dp)
    c = vec.dot(op, op) - radius * radius
    disc = b * b - a * c
    if disc < 0.0 or c <= 0.0:  # misses, or starts inside the tube (its inside does not emit)
        return math.inf, (0.0, 0.0, 0.0)
    t = (-b - math.sqrt(disc)) / a
    if not (t > 0.0 and t < t_max) or abs(vec.dot(vec.madd(oc, d, t), ax)) > 0.5 * length:
        return math.inf, (0.0, 0.0, 0.0)
    return t, vec.row(lights.color, j)


@kernel(inline=True)
def _lamp_hit_unshaped(lights, j, o, d, t_max):
    """Where the ray o + t·d (d unit) meets light j's shape before ``t_max``, and the radiance it sees there:
    (t, Le), t = inf when it misses. As Cycles renders a light seen by a ray (measured through bpy, Blender 5.0):

    - area light: one-sided (seen from its emitting side), Le = its radiance P/(π·A) × the Spread attenuation at the
      ray's angle to the normal (:func:`spread_table`, the same factor as its samples);
    - point / spot light of radius R: a sphere, Le = I/(π·R²) (I = P/4π: the sphere's intensity), a spot's × its
      falloff at the direction from the light to the ray's origin;
    - sun of angle a: a disk of angular radius a/2 in the sky (only for a ray that meets nothing, ``t_max`` = inf;
      t = 1e30),
      Le = S/(π·sin²(a/2))."""
    kd = lights.kind[j]
    miss = (math.inf, (0.0, 0.0, 0.0))
    if kd == CYLINDER:
        return _lamp_hit_cylinder(lights, j, o, d, t_max)
    if kd == RECT or kd == DISK:
        nrm = vec.row(lights.direction, j)
        cos_l = -vec.dot(d, nrm)
        if cos_l <= 1e-12:  # parallel, or the back side: area lights emit only along their normal
            return miss
        pos = vec.row(lights.position, j)
        t = vec.dot(vec.sub(pos, o), nrm) / -cos_l
        if not (t > 0.0 and t < t_max):
            return miss
        q = vec.sub(vec.madd(o, d, t), pos)
        a = vec.dot(q, vec.row(lights.u_axis, j)) / lights.size[j, 0]
        b = vec.dot(q, vec.row(lights.v_axis, j)) / lights.size[j, 1]
        if kd == RECT:
            if abs(a) > 0.5 or abs(b) > 0.5:
                return miss
        elif a * a + b * b > 0.25:
            return miss
        f = 1.0
        norm = lights.spread[j, 1]
        if norm > 0.0:
            tan_a = math.sqrt(max(1.0 - cos_l * cos_l, 0.0)) / cos_l
            f = max((lights.spread[j, 0] - tan_a) * norm, 0.0)
        le = vec.row(lights.color, j)
        if lights.tex_size[j, 0] > 0:
            le = vec.mul(le, light_texel(lights, j, a + 0.5, b + 0.5))
        return t, vec.scale(le, f)
    if kd == POINT or kd == SPOT:
        radius = lights.radius[j]
        if radius <= 0.0:
            return miss
        pos = vec.row(lights.position, j)
        oc = vec.sub(o, pos)
        b = vec.dot(oc, d)
        c = vec.dot(oc, oc) - radius * radius
        disc = b * b - c
        if disc < 0.0:
            return miss
        sq = math.sqrt(disc)
        t = -b - sq
        if t <= 0.0:
            t = -b + sq
        if not (t > 0.0 and t < t_max):
            return miss
        f = 1.0 / (math.pi * radius * radius)
        if kd == SPOT:
            f *= spot_falloff(-vec.dot(d, vec.row(lights.direction, j)), lights.cos_cone[j], lights.blend[j])
        return t, vec.scale(vec.row(lights.color, j), f)
    if kd == DISTANT:
        cm = lights.cos_max[j]
        if cm >= 1.0 or t_max < math.inf or -vec.dot(d, vec.row(lights.direction, j)) < cm:
            return miss
        return 1e30, vec.scale(vec.row(lights.color, j), 1.0 / (math.pi * (1.0 - cm * cm)))
    return miss

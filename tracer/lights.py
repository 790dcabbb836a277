"""Light sources and what they deliver to a batch of surface points.

Every light answers one question for points p (N, 3): for each of its K samples, the unit direction l towards the
light, the distance to it (the shadow ray's t_max), and E, the irradiance it delivers on a surface facing it, already
divided by K. The shading of the seed then multiplies E by the BRDF and max(0, n·l); shadow rays decide which
samples count.

Units are Blender's and Cycles' (measured in ``docs/units.md``):

- :class:`PointLight`: radiant ``intensity`` I in W/sr per channel (a Blender point light of power P has
  I = P / 4π). E = I / (r² + R²), Blender's soft falloff for radius R (R = 0: the inverse-square law).
  A radius > 0 gives soft shadows by sampling points on the light's sphere.
- :class:`SpotLight`: a point light whose E is multiplied by smoothstep of the cosine (Blender's spot blend).
- :class:`DistantLight`: ``irradiance`` in W/m² on a surface facing the light (Blender's sun strength).
- :class:`AreaLight`: a one-sided Lambertian rectangle or disk of ``radiance`` Le (W/m²/sr), sampled.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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


def _orthonormal_basis(w):
    """Two unit vectors u, v with (u, v, w) right-handed and orthonormal."""
    a = np.array([1.0, 0.0, 0.0]) if abs(w[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(a, w)
    u /= np.linalg.norm(u)
    return u, np.cross(w, u)


def stratified_grid(count: int, rand: np.ndarray) -> np.ndarray:
    """(K, N, 2) points in [0,1)²: a √K×√K grid of strata, each jittered by the per-point offsets ``rand``.

    The same deterministic per-point offsets rotate the whole pattern (Cranley-Patterson), so neighbouring pixels
    see different sample positions while every render of the same scene sees the same ones.
    """
    side = max(1, int(round(np.sqrt(count))))
    gx, gy = np.meshgrid(np.arange(side), np.arange(side), indexing="ij")
    cells = np.stack([gx.ravel(), gy.ravel()], axis=-1).astype(np.float32)  # (K, 2)
    return ((cells[:, None, :] + rand[None, :, :]) / side) % 1.0


@dataclass
class PointLight:
    position: np.ndarray
    intensity: np.ndarray
    radius: float = 0.0
    name: str = "point"

    def __post_init__(self):
        self.position = _vec3(self.position, "position")
        self.intensity = _vec3(self.intensity, "intensity")
        self.radius = float(self.radius)
        if not np.isfinite(self.radius) or self.radius < 0:
            raise ValueError(f"light {self.name}: radius must be >= 0, got {self.radius}")

    def sample_count(self, requested: int) -> int:
        return 1 if self.radius == 0 else max(1, requested)

    def uses_random(self, requested: int) -> bool:
        return self.sample_count(requested) > 1

    def _falloff(self, to_light, dist2):
        return None

    def sample(self, p: np.ndarray, count: int, rand: np.ndarray):
        k = self.sample_count(count)
        to_center = self.position.astype(np.float32) - p
        d2 = np.einsum("ij,ij->i", to_center, to_center)
        # Blender's soft falloff: irradiance I / (r² + R²), measured against Cycles.
        inv = 1.0 / (d2 + np.float32(self.radius**2))
        f = self._falloff(to_center, d2)  # None = no falloff (point light)
        if f is not None:
            inv = inv * f
        e = inv[:, None] * self.intensity.astype(np.float32)
        if k == 1:
            dist = np.sqrt(d2)
            l = to_center * (1.0 / np.maximum(dist, 1e-30))[:, None]
            return l[None], dist[None], e[None]
        # Soft shadows: stratified points on the disk of the sphere that faces p.
        dist = np.sqrt(d2)
        w = -to_center / np.maximum(dist, 1e-30)[:, None]
        a = np.where(np.abs(w[:, :1]) < 0.9, np.array([[1.0, 0, 0]], np.float32), np.array([[0, 1.0, 0]], np.float32))
        u = np.cross(a, w)
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        v = np.cross(w, u)
        s = stratified_grid(k, rand)
        k = s.shape[0]
        r = self.radius * np.sqrt(s[..., 0])
        phi = 2 * np.pi * s[..., 1]
        pts = (self.position[None, None, :] + (r * np.cos(phi))[..., None] * u[None]
               + (r * np.sin(phi))[..., None] * v[None]).astype(np.float32)
        to_l = pts - p[None]
        ld = np.linalg.norm(to_l, axis=-1)
        l = to_l / np.maximum(ld, 1e-30)[..., None]
        return l, ld, np.broadcast_to(e[None] / k, (k,) + e.shape).copy()


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

    def _falloff(self, to_light, dist2):
        """Blender's spot: smoothstep(x), x = (cos α − cos(size/2)) / ((1 − cos(size/2))·blend), in cosine."""
        cos_a = -(to_light @ self.direction.astype(np.float32)) / np.sqrt(np.maximum(dist2, 1e-30))
        cos_s = np.cos(self.cone_angle)
        if self.blend <= 0:
            return (cos_a > cos_s).astype(np.float32)
        x = np.clip((cos_a - cos_s) / ((1 - cos_s) * self.blend), 0.0, 1.0)
        return (x * x * (3 - 2 * x)).astype(np.float32)


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

    def sample(self, p: np.ndarray, count: int, rand: np.ndarray):
        n = p.shape[0]
        k = self.sample_count(count)
        to_light = -self.direction
        e = np.broadcast_to(self.irradiance.astype(np.float32), (n, 3))
        if k == 1:
            l = np.broadcast_to(to_light.astype(np.float32), (n, 3))
            return l[None], np.full((1, n), np.inf, np.float32), e[None].copy()
        # A disk of angular diameter `angle` around the direction to the sun, sampled uniformly in solid angle.
        u, v = _orthonormal_basis(to_light)
        s = stratified_grid(k, rand)
        k = s.shape[0]
        cos_max = np.cos(self.angle / 2)
        cos_t = 1 - s[..., 0] * (1 - cos_max)
        sin_t = np.sqrt(np.maximum(0, 1 - cos_t**2))
        phi = 2 * np.pi * s[..., 1]
        l = (cos_t[..., None] * to_light + (sin_t * np.cos(phi))[..., None] * u
             + (sin_t * np.sin(phi))[..., None] * v).astype(np.float32)
        return l, np.full((k, n), np.inf, np.float32), np.broadcast_to(e[None] / k, (k, n, 3)).copy()


@dataclass
class AreaLight:
    """A one-sided Lambertian emitter centred at ``position``, spanning ``size`` along ``u_axis`` and ``v_axis``,
    emitting along ``normal`` (Blender: the light's −Z). ``shape`` is "rect" or "disk" (an ellipse for unequal sizes)."""

    position: np.ndarray
    u_axis: np.ndarray
    v_axis: np.ndarray
    normal: np.ndarray
    size: tuple = (1.0, 1.0)
    radiance: np.ndarray = None
    shape: str = "rect"
    name: str = "area"

    def __post_init__(self):
        self.position = _vec3(self.position, "position")
        self.u_axis = _normalize(self.u_axis, "u_axis")
        self.v_axis = _normalize(self.v_axis, "v_axis")
        self.normal = _normalize(self.normal, "normal")
        self.size = (float(self.size[0]), float(self.size[1]))
        if not all(np.isfinite(self.size)) or min(self.size) <= 0:
            raise ValueError(f"light {self.name}: size must be > 0, got {self.size}")
        if self.radiance is None:
            raise ValueError(f"light {self.name}: an area light needs a radiance")
        self.radiance = _vec3(self.radiance, "radiance")
        if self.shape not in ("rect", "disk"):
            raise ValueError(f"light {self.name}: shape must be 'rect' or 'disk', got {self.shape!r}")

    @property
    def area(self) -> float:
        sx, sy = self.size
        return sx * sy if self.shape == "rect" else np.pi / 4 * sx * sy

    def sample_count(self, requested: int) -> int:
        return max(1, requested)

    def uses_random(self, requested: int) -> bool:
        return True

    def sample(self, p: np.ndarray, count: int, rand: np.ndarray):
        s = stratified_grid(self.sample_count(count), rand)
        k = s.shape[0]
        if self.shape == "rect":
            a, b = s[..., 0] - 0.5, s[..., 1] - 0.5
        else:  # concentric-free polar mapping to the unit disk, scaled to the ellipse
            r = 0.5 * np.sqrt(s[..., 0])
            a, b = r * np.cos(2 * np.pi * s[..., 1]), r * np.sin(2 * np.pi * s[..., 1])
        pts = (self.position + (a * self.size[0])[..., None] * self.u_axis
               + (b * self.size[1])[..., None] * self.v_axis).astype(np.float32)
        to_l = pts - p[None]
        d2 = np.maximum(np.einsum("kij,kij->ki", to_l, to_l), 1e-30)
        dist = np.sqrt(d2)
        l = to_l / dist[..., None]
        cos_l = np.maximum(0.0, -(l @ self.normal.astype(np.float32)))
        # E from a sample of a Lambertian emitter: Le · cosθ_l · A / r², averaged over the K samples.
        e = (self.radiance.astype(np.float32) * (cos_l * self.area / d2 / k)[..., None]).astype(np.float32)
        return l.astype(np.float32), dist.astype(np.float32), e


Light = PointLight | SpotLight | DistantLight | AreaLight

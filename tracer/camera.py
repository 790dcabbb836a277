"""Eye rays: the seed's ray type 1, for perspective and orthographic cameras.

The camera follows USD's ``UsdGeom.Camera`` model (Blender's is the same after conversion): it looks down its
local −Z with +Y up; a film window of ``horizontal_aperture`` × ``vertical_aperture`` sits at distance
``focal_length`` (perspective) and is shifted by the aperture offsets (lens shift). For an orthographic camera the
apertures and offsets are the view's width, height and shift in world units.

Image coordinates: pixel (i, j) has its top-left corner at column i, row j; a film position (u, v) in [0, 1]² has
u growing right and v growing up, so row j spans v in [1 − (j+1)/H, 1 − j/H].

Depth of field (a thin lens, Cook 1984, as Cycles models it): with ``lens_radius`` > 0 an eye ray starts at a point
of the aperture (a disk, or a regular polygon of ``aperture_blades`` corners turned by ``aperture_rotation``; x
divided by ``aperture_ratio`` for anamorphic bokeh) and goes through the point where the pinhole ray meets the plane
of focus, ``focus_distance`` in front of the camera along its view axis; points on that plane stay sharp. The
radius comes from an f-number through :func:`lens_radius` (the one conversion; front ends give it the focal length
in scene units). ``lens_radius`` 0 is the pinhole camera of the notes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from . import vec
from .jit import kernel

PERSPECTIVE = "perspective"
ORTHOGRAPHIC = "orthographic"


@dataclass
class Camera:
    camera_to_world: np.ndarray = field(default_factory=lambda: np.eye(4))
    projection: str = PERSPECTIVE
    focal_length: float = 50.0
    horizontal_aperture: float = 36.0
    vertical_aperture: float = 24.0
    horizontal_aperture_offset: float = 0.0
    vertical_aperture_offset: float = 0.0
    near: float = 0.0
    far: float = np.inf
    #: Radius of the thin lens's aperture in scene units (:func:`lens_radius`); 0 = pinhole (no depth of field).
    lens_radius: float = 0.0
    #: Distance of the plane of focus from the camera along its view axis, in scene units (used with a lens).
    focus_distance: float = 0.0
    #: Corners of a polygonal aperture (Blender's Blades; fewer than 3 = round, as Cycles).
    aperture_blades: int = 0
    #: Rotation of the polygonal aperture, radians.
    aperture_rotation: float = 0.0
    #: Anamorphic squeeze: the aperture's x is divided by it (Blender's Ratio; 1 = round bokeh).
    aperture_ratio: float = 1.0
    #: Extra clipping planes (a, b, c, d) in camera space keeping a·x + b·y + c·z + d >= 0 (tracer.clip_planes).
    clipping_planes: tuple = ()
    #: Camera motion (motion blur): (S, 4, 4) camera-to-world matrices at S ≥ 2 evenly spaced times of the shutter,
    #: interpolated as :mod:`tracer.geometry.motion` does; None: the camera stands still at ``camera_to_world``.
    motion: np.ndarray | None = None

    def __post_init__(self):
        m = np.asarray(self.camera_to_world, dtype=np.float64)
        if m.shape != (4, 4) or not np.all(np.isfinite(m)):
            raise ValueError(f"camera_to_world must be a finite 4x4 matrix, got shape {m.shape}")
        if abs(np.linalg.det(m[:3, :3])) < 1e-12:
            raise ValueError("camera_to_world is singular (zero scale?)")
        self.camera_to_world = m
        if self.projection not in (PERSPECTIVE, ORTHOGRAPHIC):
            raise ValueError(f"camera projection must be '{PERSPECTIVE}' or '{ORTHOGRAPHIC}', got {self.projection!r}")
        for name in ("focal_length", "horizontal_aperture", "vertical_aperture"):
            v = float(getattr(self, name))
            if not np.isfinite(v) or v <= 0:
                if name == "focal_length" and self.projection == ORTHOGRAPHIC:
                    setattr(self, name, v if np.isfinite(v) else 1.0)
                    continue
                raise ValueError(f"camera {name} must be a positive finite number, got {v}")
            setattr(self, name, v)
        for name in ("horizontal_aperture_offset", "vertical_aperture_offset", "near"):
            v = float(getattr(self, name))
            if not np.isfinite(v):
                raise ValueError(f"camera {name} must be finite, got {v}")
            setattr(self, name, v)
        self.far = float(self.far)
        if self.near < 0 or not self.far > self.near:
            raise ValueError(f"camera clipping range must satisfy 0 <= near < far, got ({self.near}, {self.far})")
        for name in ("lens_radius", "focus_distance", "aperture_rotation", "aperture_ratio"):
            v = float(getattr(self, name))
            if not np.isfinite(v):
                raise ValueError(f"camera {name} must be finite, got {v}")
            setattr(self, name, v)
        if self.lens_radius < 0:
            raise ValueError(f"camera lens_radius must be >= 0 (0 = pinhole), got {self.lens_radius}")
        if self.lens_radius > 0 and self.focus_distance <= 0:
            raise ValueError(f"camera focus_distance must be > 0 with a lens (lens_radius {self.lens_radius}), got "
                             f"{self.focus_distance}")
        if self.aperture_ratio <= 0:
            raise ValueError(f"camera aperture_ratio must be > 0, got {self.aperture_ratio}")
        self.aperture_blades = int(self.aperture_blades) if self.aperture_blades >= 3 else 0  # < 3: round, as Cycles
        planes = tuple(tuple(float(x) for x in p) for p in self.clipping_planes)
        if any(len(p) != 4 or not np.all(np.isfinite(p)) for p in planes):
            raise ValueError(f"camera clipping_planes must be finite (a, b, c, d) tuples, got {self.clipping_planes}")
        self.clipping_planes = planes
        if self.motion is not None:
            mo = np.asarray(self.motion, np.float64)
            if mo.ndim != 3 or mo.shape[1:] != (4, 4) or len(mo) < 2 or not np.all(np.isfinite(mo)):
                raise ValueError(f"camera motion must be finite (S >= 2, 4, 4) matrices, got shape {mo.shape}")
            if np.any(np.abs(np.linalg.det(mo[:, :3, :3])) < 1e-12):
                raise ValueError("camera motion: a step is singular (zero scale?)")
            self.motion = np.ascontiguousarray(mo)

    @property
    def position(self) -> np.ndarray:
        return self.camera_to_world[:3, 3].copy()

    def film_point(self, u, v):
        """Camera-space film position (x, y) for film coordinates u, v in [0, 1] (u right, v up)."""
        x = (np.asarray(u) - 0.5) * self.horizontal_aperture + self.horizontal_aperture_offset
        y = (np.asarray(v) - 0.5) * self.vertical_aperture + self.vertical_aperture_offset
        return x, y

    def packed(self) -> "CameraTable":
        """The camera as :func:`eye_ray` reads it (a :class:`CameraTable` of plain floats)."""
        m = self.camera_to_world
        return CameraTable(rotation=np.ascontiguousarray(m[:3, :3], np.float64),
                           eye=(float(m[0, 3]), float(m[1, 3]), float(m[2, 3])),
                           focal_length=float(self.focal_length), aperture=(self.horizontal_aperture,
                                                                            self.vertical_aperture),
                           offset=(self.horizontal_aperture_offset, self.vertical_aperture_offset),
                           near=float(self.near), perspective=self.projection == PERSPECTIVE,
                           lens_radius=float(self.lens_radius), focus_distance=float(self.focus_distance),
                           blades=int(self.aperture_blades), blade_rotation=float(self.aperture_rotation),
                           inv_ratio=1.0 / float(self.aperture_ratio))

    def sample_footprint(self, width: int, samples: int = 1) -> tuple:
        """(eye, spread, flat): the width in world units that one of ``samples``×``samples`` eye samples of a pixel
        covers at a point p is ``flat + spread·|p − eye|`` (perspective: the film's width per unit of distance
        over the samples across the image; orthographic: a constant). Texture lookups pick their mip level by it."""
        across = max(1, int(width)) * max(1, int(samples))
        eye = tuple(float(x) for x in self.camera_to_world[:3, 3])
        if self.projection == PERSPECTIVE:
            return eye, self.horizontal_aperture / self.focal_length / across, 0.0
        return eye, 0.0, self.horizontal_aperture / across

    def generate_rays(self, u: np.ndarray, v: np.ndarray, lens: tuple | None = None):
        """World-space eye rays (origins (N, 3), unit directions (N, 3), float32) through film positions u, v
        (array form of :func:`eye_ray`), for lens samples ``lens`` = (a, b) arrays in [0, 1)²; None: the chief rays
        through the lens's centre (the pinhole's rays)."""
        u = np.ascontiguousarray(np.asarray(u, np.float64).reshape(-1))
        v = np.ascontiguousarray(np.broadcast_to(np.asarray(v, np.float64).reshape(-1), u.shape))
        cam = self.packed()
        if lens is None:
            cam, a, b = cam._replace(lens_radius=0.0), np.zeros_like(u), np.zeros_like(u)
        else:
            a = np.ascontiguousarray(np.broadcast_to(np.asarray(lens[0], np.float64).reshape(-1), u.shape))
            b = np.ascontiguousarray(np.broadcast_to(np.asarray(lens[1], np.float64).reshape(-1), u.shape))
        o = np.empty((len(u), 3), np.float32)
        d = np.empty((len(u), 3), np.float32)
        _eye_rays(cam, u, v, a, b, o, d)
        return o, d

    def project(self, points: np.ndarray, width: int, height: int) -> np.ndarray:
        """Pixel coordinates (N, 2) (x right, y down, continuous: pixel (i, j) spans [i, i+1)×[j, j+1)) of world
        points, and their depth along the view axis as a third column. The inverse of :meth:`generate_rays`."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        w2c = np.linalg.inv(self.camera_to_world)
        pc = p @ w2c[:3, :3].T + w2c[:3, 3]
        depth = -pc[:, 2]
        if self.projection == PERSPECTIVE:
            x = pc[:, 0] / depth * self.focal_length
            y = pc[:, 1] / depth * self.focal_length
        else:
            x, y = pc[:, 0], pc[:, 1]
        u = (x - self.horizontal_aperture_offset) / self.horizontal_aperture + 0.5
        v = (y - self.vertical_aperture_offset) / self.vertical_aperture + 0.5
        return np.stack([u * width, (1 - v) * height, depth], axis=-1)

    @classmethod
    def look_at(cls, eye, target, up=(0.0, 1.0, 0.0), **kwargs) -> "Camera":
        """A camera at ``eye`` looking at ``target``, with ``up`` as close to its +Y as possible."""
        eye = np.asarray(eye, dtype=np.float64)
        fwd = np.asarray(target, dtype=np.float64) - eye
        if np.linalg.norm(fwd) == 0:
            raise ValueError("look_at: eye and target coincide")
        z = -fwd / np.linalg.norm(fwd)
        x = np.cross(np.asarray(up, dtype=np.float64), z)
        if np.linalg.norm(x) < 1e-12:
            raise ValueError("look_at: up is parallel to the view direction")
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        m = np.eye(4)
        m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, y, z, eye
        return cls(camera_to_world=m, **kwargs)


class CameraTable(NamedTuple):
    """A camera as the kernels read it: camera-to-world rotation (3, 3) and eye, focal length, apertures (h, v),
    aperture offsets (h, v), near plane, and whether it is a perspective camera."""

    rotation: np.ndarray
    eye: tuple
    focal_length: float
    aperture: tuple
    offset: tuple
    near: float
    perspective: bool
    lens_radius: float
    focus_distance: float
    blades: int
    blade_rotation: float
    inv_ratio: float


def lens_radius(focal_length: float, f_stop: float) -> float:
    """The thin lens's aperture radius f / (2·N) for focal length f (in scene units) and f-number N; N ≤ 0 (USD's
    ``fStop`` 0) or no focal length: 0, a pinhole. Blender: f = lens mm × 10⁻³ (scene units of 1 m, as Cycles);
    USD: f = ``focalLength`` / 10 (tenths of a scene unit). Orthographic cameras (Cycles): f = 1."""
    if not (f_stop > 0 and focal_length > 0):
        return 0.0
    return float(focal_length) / (2.0 * float(f_stop))


@kernel(inline=True)
def aperture_point(blades, rotation, inv_ratio, a, b):
    """A point of the unit aperture for a uniform sample (a, b) in [0, 1)², uniform in area: the unit disk by
    Shirley and Chiu's concentric map (strata stay compact), or a regular polygon of ``blades`` corners on the unit
    circle turned by ``rotation`` (a picks the corner triangle, its remainder and b a uniform point in it); x is
    then scaled by 1/ratio (anamorphic bokeh)."""
    if blades < 3:
        sx, sy = 2.0 * a - 1.0, 2.0 * b - 1.0
        if sx == 0.0 and sy == 0.0:
            return 0.0, 0.0
        if abs(sx) > abs(sy):
            r, phi = sx, 0.25 * math.pi * (sy / sx)
        else:
            r, phi = sy, 0.5 * math.pi - 0.25 * math.pi * (sx / sy)
        return r * math.cos(phi) * inv_ratio, r * math.sin(phi)
    k = math.floor(a * blades)
    w = math.sqrt(a * blades - k)  # the triangle (centre, two adjacent corners): a uniform point in it
    half = math.pi / blades
    px, py = w * math.cos(half), w * math.sin(half) * (2.0 * b - 1.0)
    turn = rotation + 2.0 * k * half  # corners at rotation + (2k ± 1)·π/blades, as Cycles draws them
    c, s_ = math.cos(turn), math.sin(turn)
    return (c * px - s_ * py) * inv_ratio, s_ * px + c * py


@kernel(inline=True)
def eye_ray(cam, u, v, lens_a, lens_b):
    """The eye ray (origin, unit direction) through film position (u, v) of a :meth:`Camera.packed` camera, for
    the lens sample (lens_a, lens_b) in [0, 1)² (unused by a pinhole camera).

    The film point is (x, y) = ((u − ½)·aperture_h + offset_h, (v − ½)·aperture_v + offset_v).
    Perspective: every ray starts at the eye e and goes through the film point (x, y, −f): ray(e, u, 0, ∞).
    Orthographic (the seed's question): every ray has the view direction −Z and starts at the film point itself.
    Rays start at the near clipping plane (camera-space z = −near).
    With a lens (``lens_radius`` > 0), in camera space: the pinhole ray meets the plane of focus z = −F at P; the
    ray starts at the aperture point L = R·:func:`aperture_point` (z = 0, around the eye or the film point) and goes
    through P, starting where it crosses z = −near.
    """
    x = (u - 0.5) * cam.aperture[0] + cam.offset[0]
    y = (v - 0.5) * cam.aperture[1] + cam.offset[1]
    r = cam.rotation
    if cam.lens_radius > 0.0:
        lx, ly = aperture_point(cam.blades, cam.blade_rotation, cam.inv_ratio, lens_a, lens_b)
        lx, ly = lx * cam.lens_radius, ly * cam.lens_radius
        fd = cam.focus_distance
        if cam.perspective:  # film point (x/f, y/f, −1) scaled to z = −F; the lens around the eye
            ox, oy = lx, ly
            dx, dy = x / cam.focal_length * fd - lx, y / cam.focal_length * fd - ly
        else:  # parallel rays through the film point; the lens around it
            ox, oy = x + lx, y + ly
            dx, dy = -lx, -ly
        # camera-space origin at z = −near along the ray (direction (dx, dy, −fd), z-step 1 per unit of t·fd)
        t = cam.near / fd
        c = (ox + dx * t, oy + dy * t, -cam.near)
        w = (dx, dy, -fd)
        o = (cam.eye[0] + r[0, 0] * c[0] + r[0, 1] * c[1] + r[0, 2] * c[2],
             cam.eye[1] + r[1, 0] * c[0] + r[1, 1] * c[1] + r[1, 2] * c[2],
             cam.eye[2] + r[2, 0] * c[0] + r[2, 1] * c[1] + r[2, 2] * c[2])
        wd = (r[0, 0] * w[0] + r[0, 1] * w[1] + r[0, 2] * w[2],
              r[1, 0] * w[0] + r[1, 1] * w[1] + r[1, 2] * w[2],
              r[2, 0] * w[0] + r[2, 1] * w[1] + r[2, 2] * w[2])
        return o, vec.normalize(wd)
    if cam.perspective:
        c = (x / cam.focal_length, y / cam.focal_length, -1.0)  # the film point; z = −1 so ·near lands on the plane
        w = (r[0, 0] * c[0] + r[0, 1] * c[1] + r[0, 2] * c[2],
             r[1, 0] * c[0] + r[1, 1] * c[1] + r[1, 2] * c[2],
             r[2, 0] * c[0] + r[2, 1] * c[1] + r[2, 2] * c[2])
        return vec.madd(cam.eye, w, cam.near), vec.normalize(w)
    c = (x, y, -cam.near)
    o = (cam.eye[0] + r[0, 0] * c[0] + r[0, 1] * c[1] + r[0, 2] * c[2],
         cam.eye[1] + r[1, 0] * c[0] + r[1, 1] * c[1] + r[1, 2] * c[2],
         cam.eye[2] + r[2, 0] * c[0] + r[2, 1] * c[1] + r[2, 2] * c[2])
    return o, vec.normalize((-r[0, 2], -r[1, 2], -r[2, 2]))


@kernel
def _eye_rays(cam, u, v, a, b, o, d):
    for i in range(u.shape[0]):
        oi, di = eye_ray(cam, u[i], v[i], a[i], b[i])
        o[i, 0], o[i, 1], o[i, 2] = oi
        d[i, 0], d[i, 1], d[i, 2] = di


def fit_apertures(horizontal: float, vertical: float, width: int, height: int, policy: str = "expand"):
    """Conform a film window to an image aspect ratio (usdrecord / UsdGeom ``ConformWindow`` policies).

    ``expand`` grows the short side (everything the aperture shows stays visible), ``crop`` shrinks the long side,
    ``horizontal`` / ``vertical`` keep that aperture and derive the other, ``larger`` keeps the horizontal one for
    a landscape image and the vertical one for a portrait image (Blender's sensor fit Auto), ``none`` leaves both
    as they are. ``width``/``height`` may be fractional (a pixel aspect ratio folded in).
    """
    aspect = width / height
    if policy == "larger":
        policy = "horizontal" if aspect >= 1.0 else "vertical"
    if policy == "none":
        return horizontal, vertical
    if policy == "horizontal":
        return horizontal, horizontal / aspect
    if policy == "vertical":
        return vertical * aspect, vertical
    window = horizontal / vertical
    if policy == "expand":
        return (horizontal, horizontal / aspect) if window > aspect else (vertical * aspect, vertical)
    if policy == "crop":
        return (vertical * aspect, vertical) if window > aspect else (horizontal, horizontal / aspect)
    raise ValueError(f"unknown aperture fit policy {policy!r}: use expand, crop, horizontal, vertical, larger or "
                     "none")

"""Eye rays: the seed's ray type 1, for perspective and orthographic cameras.

The camera follows USD's ``UsdGeom.Camera`` model (Blender's is the same after conversion): it looks down its
local −Z with +Y up; a film window of ``horizontal_aperture`` × ``vertical_aperture`` sits at distance
``focal_length`` (perspective) and is shifted by the aperture offsets (lens shift). For an orthographic camera the
apertures and offsets are the view's width, height and shift in world units.

Image coordinates: pixel (i, j) has its top-left corner at column i, row j; a film position (u, v) in [0, 1]² has
u growing right and v growing up, so row j spans v in [1 − (j+1)/H, 1 − j/H].
"""

from __future__ import annotations

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
                           near=float(self.near), perspective=self.projection == PERSPECTIVE)

    def sample_footprint(self, width: int, samples: int = 1) -> tuple:
        """(eye, spread, flat): the width in world units that one of ``samples``×``samples`` eye samples of a pixel
        covers at a point p is ``flat + spread·|p − eye|`` (perspective: the film's width per unit of distance
        over the samples across the image; orthographic: a constant). Texture lookups pick their mip level by it."""
        across = max(1, int(width)) * max(1, int(samples))
        eye = tuple(float(x) for x in self.camera_to_world[:3, 3])
        if self.projection == PERSPECTIVE:
            return eye, self.horizontal_aperture / self.focal_length / across, 0.0
        return eye, 0.0, self.horizontal_aperture / across

    def generate_rays(self, u: np.ndarray, v: np.ndarray):
        """World-space eye rays (origins (N, 3), unit directions (N, 3), float32) through film positions u, v
        (array form of :func:`eye_ray`)."""
        u = np.ascontiguousarray(np.asarray(u, np.float64).reshape(-1))
        v = np.ascontiguousarray(np.broadcast_to(np.asarray(v, np.float64).reshape(-1), u.shape))
        o = np.empty((len(u), 3), np.float32)
        d = np.empty((len(u), 3), np.float32)
        _eye_rays(self.packed(), u, v, o, d)
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


@kernel(inline=True)
def eye_ray(cam, u, v):
    """The eye ray (origin, unit direction) through film position (u, v) of a :meth:`Camera.packed` camera.

    The film point is (x, y) = ((u − ½)·aperture_h + offset_h, (v − ½)·aperture_v + offset_v).
    Perspective: every ray starts at the eye e and goes through the film point (x, y, −f): ray(e, u, 0, ∞).
    Orthographic (the seed's question): every ray has the view direction −Z and starts at the film point itself.
    Rays start at the near clipping plane (camera-space z = −near).
    """
    x = (u - 0.5) * cam.aperture[0] + cam.offset[0]
    y = (v - 0.5) * cam.aperture[1] + cam.offset[1]
    r = cam.rotation
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
def _eye_rays(cam, u, v, o, d):
    for i in range(u.shape[0]):
        oi, di = eye_ray(cam, u[i], v[i])
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

"""A camera's extra clipping planes (UsdGeomCamera ``clippingPlanes``): each (a, b, c, d) in camera space keeps the
points where a·x + b·y + c·z + d ≥ 0 and cuts off the rest, for eye rays only (what the camera sees, not what
reflections or shadows meet).

Along an eye ray p(t) = o + t·d (camera space) a plane's value is f(t) = f₀ + t·f₁, linear in t, so each plane
bounds the ray's valid interval from one side: f₁ > 0 keeps t ≥ −f₀/f₁, f₁ < 0 keeps t ≤ −f₀/f₁, f₁ = 0 keeps all or
nothing by the sign of f₀. :func:`clip_eye_rays` intersects the intervals with [0, the far plane's t] and starts
each ray at its interval's start: geometry outside is not there (the ray sees what lies behind it, or the
background when the interval is empty).
"""

from __future__ import annotations

import numpy as np


def clip_eye_rays(camera, origins: np.ndarray, directions: np.ndarray, t_far: float = np.inf):
    """(origins moved to each ray's first valid point, t_max per ray: the length of its valid interval, 0 where
    it is empty) for world-space eye rays of ``camera`` and its ``clipping_planes``; ``t_far`` the rays' own limit
    (the far plane) before the planes."""
    o = np.asarray(origins, np.float64)
    d = np.asarray(directions, np.float64)
    inv = np.linalg.inv(camera.camera_to_world)
    oc = o @ inv[:3, :3].T + inv[:3, 3]
    dc = d @ inv[:3, :3].T
    lo = np.zeros(len(o))
    hi = np.full(len(o), float(t_far))
    for a, b, c, w in camera.clipping_planes:
        n = np.array([a, b, c], np.float64)
        f0, f1 = oc @ n + w, dc @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -f0 / f1
        lo = np.where(f1 > 0, np.maximum(lo, t), lo)
        hi = np.where(f1 < 0, np.minimum(hi, t), hi)
        hi = np.where((f1 == 0) & (f0 < 0), -1.0, hi)
    t_max = np.maximum(hi - lo, 0.0)
    moved = o + np.where(np.isfinite(lo), lo, 0.0)[:, None] * d
    return moved.astype(np.float32), t_max.astype(np.float32)

"""Implicit gprims (Sphere, Cube, Cylinder, Cone, Capsule, Plane, and the 2024 schemas Cylinder_1 — a truncated
cone of radiusBottom/radiusTop — and Capsule_1, drawn with the mean of its two radii) tessellated to triangles with
exact normals.

``segments`` sets the resolution (around the axis; half as many along it). The shapes follow the UsdGeom
definitions: centred at the origin, ``axis`` X, Y or Z, Cone apex at +height/2, Capsule height without its caps,
Plane double-sided with its normal along ``axis``.
"""

from __future__ import annotations

import numpy as np
from pxr import UsdGeom

from .mesh import MeshData

DEFAULT_SEGMENTS = 48
GPRIM_TYPES = ("Sphere", "Cube", "Cylinder", "Cone", "Capsule", "Plane", "Cylinder_1", "Capsule_1",
               "ArnoldSphere", "ArnoldBox")
#: Arnold's own implicit shapes (arnold-usd's schemas, typed prims USD does not know): drawn as their USD
#: counterparts with Arnold's node defaults (sphere radius 0.5 about ``center``; box from ``min`` to ``max``, ±0.5).
ARNOLD_IMPLICITS = ("ArnoldSphere", "ArnoldBox")


def _arnold_value(prim, name, default, time):
    """An ``arnold:`` input as Arnold reads it: a scalar, or the first element of arnold-usd's one-element arrays."""
    a = prim.GetAttribute(f"arnold:{name}")
    v = a.Get(time) if a and a.HasValue() else None
    if v is None:
        return np.asarray(default, np.float64)
    v = np.asarray(v, np.float64)
    if v.ndim and v.shape[0] >= 1 and (v.ndim == 2 or np.ndim(default) == 0):
        v = v[0]
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{prim.GetPath()}: {prim.GetTypeName()} arnold:{name} is not finite")
    return v


def _axis_matrix(axis: str) -> np.ndarray:
    """Rotation taking the Z-axis shapes built here onto ``axis`` (a cyclic permutation keeps handedness)."""
    if axis == "X":
        return np.array([[0, 0, 1], [1, 0, 0], [0, 1, 0]], np.float64)  # z->x, x->y, y->z
    if axis == "Y":
        return np.array([[0, 1, 0], [0, 0, 1], [1, 0, 0]], np.float64)  # z->y, x->z, y->x
    return np.eye(3)


def _ring(n):
    phi = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.cos(phi), np.sin(phi)


def _lathe(r0, z0, r1, z1, nrm, n):
    """Side band between two rings (radius, z) with the given (radial, axial) normal components: (P, T, N)."""
    c, s = _ring(n)
    bottom = np.stack([r0 * c, r0 * s, np.full(n, z0)], 1)
    top = np.stack([r1 * c, r1 * s, np.full(n, z1)], 1)
    nr, nz = nrm
    normals = np.stack([nr * c, nr * s, np.full(n, nz)], 1)
    i = np.arange(n)
    j = (i + 1) % n
    lower, upper = np.stack([i, j, n + j], 1), np.stack([i, n + j, n + i], 1)
    # A ring of radius 0 (cone apex, capsule pole) makes one of the two triangles of each quad degenerate.
    tris = lower if r1 < 1e-12 else upper if r0 < 1e-12 else np.concatenate([lower, upper])
    return np.concatenate([bottom, top]), tris, np.concatenate([normals, normals])


def _cap(r, z, up, n):
    c, s = _ring(n)
    pts = np.concatenate([[[0, 0, z]], np.stack([r * c, r * s, np.full(n, z)], 1)])
    i = np.arange(n) + 1
    j = (np.arange(n) + 1) % n + 1
    tris = np.stack([np.zeros(n, int), i, j], 1) if up else np.stack([np.zeros(n, int), j, i], 1)
    return pts, tris, np.tile([0.0, 0.0, 1.0 if up else -1.0], (n + 1, 1))


def _merge(parts):
    pts, tris, nrm, off = [], [], [], 0
    for p, t, n in parts:
        pts.append(p)
        tris.append(t + off)
        nrm.append(n)
        off += len(p)
    return np.concatenate(pts), np.concatenate(tris), np.concatenate(nrm)


def _dome(radius, z, sign, segments, rows):
    """The hemisphere of ``radius`` on the plane z, bulging towards ``sign`` (±1): ``rows`` latitude bands from the
    equator to the pole, ``segments`` around, radial normals. (A capsule's ends; a sphere is two.)"""
    theta = np.linspace(0, np.pi / 2, rows + 1)
    ring = radius * np.cos(theta)
    ring[-1] = 0.0  # the pole exactly: every apex of the last band's fan is one point (cos(π/2) is 6e-17, and
    #                 apexes that far apart leave a crack a ray through the pole slips through)
    parts = []
    for a0, a1, r0, r1 in zip(theta[:-1], theta[1:], ring[:-1], ring[1:]):
        z0, z1 = z + sign * radius * np.sin(a0), z + sign * radius * np.sin(a1)
        p, t, _ = _lathe(r0, z0, r1, z1, (1, 0), segments)
        if sign < 0:
            t = t[:, [0, 2, 1]]
        n = p - [0.0, 0.0, z]
        parts.append((p, t, n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)))
    return parts


def sphere(radius, segments=DEFAULT_SEGMENTS):
    """A UV sphere of ``segments`` around and as many latitude bands pole to pole (48: 4 512 triangles)."""
    rows = max(segments // 2, 4)
    return _merge(_dome(radius, 0.0, 1, segments, rows) + _dome(radius, 0.0, -1, segments, rows))


#: The unit cube's corners and its 12 outward-wound triangles.
_CUBE_CORNERS = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                          [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], np.float64)
_CUBE_TRIANGLES = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                            [3, 7, 6], [3, 6, 2], [0, 4, 7], [0, 7, 3], [1, 2, 6], [1, 6, 5]])


def cube(size):
    return _CUBE_CORNERS * (size / 2), _CUBE_TRIANGLES.copy(), None  # flat faces: geometric normals


def cylinder(radius, height, segments=DEFAULT_SEGMENTS):
    h = height / 2
    return _merge([_lathe(radius, -h, radius, h, (1.0, 0.0), segments),
                   _cap(radius, h, True, segments), _cap(radius, -h, False, segments)])


def cone(radius, height, segments=DEFAULT_SEGMENTS):
    h = height / 2
    slant = np.hypot(radius, height)
    side = _lathe(radius, -h, 0.0, h, (height / slant, radius / slant), segments)
    return _merge([side, _cap(radius, -h, False, segments)])


def frustum(r_bottom, r_top, height, segments=DEFAULT_SEGMENTS):
    """UsdGeom's Cylinder_1: a truncated cone from radius ``r_bottom`` at −height/2 to ``r_top`` at +height/2, with
    caps where the radius is not 0 (equal radii: a cylinder; a zero radius: a cone)."""
    h = height / 2
    slant = np.hypot(r_bottom - r_top, height)
    parts = [_lathe(r_bottom, -h, r_top, h, (height / slant, (r_bottom - r_top) / slant), segments)]
    if r_top > 0:
        parts.append(_cap(r_top, h, True, segments))
    if r_bottom > 0:
        parts.append(_cap(r_bottom, -h, False, segments))
    return _merge(parts)


def capsule(radius, height, segments=DEFAULT_SEGMENTS):
    side = _lathe(radius, -height / 2, radius, height / 2, (1.0, 0.0), segments)
    rows = max(segments // 4, 3)
    ends = _dome(radius, height / 2, 1, segments, rows) + _dome(radius, -height / 2, -1, segments, rows)
    return _merge([side] + ends)


def plane(width, length):
    w, l = width / 2, length / 2
    pts = np.array([[-w, -l, 0], [w, -l, 0], [w, l, 0], [-w, l, 0]], np.float64)
    return pts, np.array([[0, 1, 2], [0, 2, 3]]), np.tile([0.0, 0.0, 1.0], (4, 1))


def geom_type(prim) -> str:
    """The prim's type as USD reads it: its schema type, which for a type the stage's plugins do not know is the
    first known entry of the layer's ``fallbackPrimTypes`` (as Storm draws it), else its authored type name."""
    return str(prim.GetPrimTypeInfo().GetSchemaTypeName()) or prim.GetTypeName()


def read_gprim(prim, time, segments=DEFAULT_SEGMENTS) -> MeshData | None:
    """Tessellate a gprim in its object space, or None if the prim is not one of :data:`GPRIM_TYPES`.
    Raises ValueError for a size that is zero, negative or not finite."""
    t = geom_type(prim)

    def g(schema, attr):
        v = getattr(schema(prim), f"Get{attr}Attr")().Get(time)
        if attr != "Axis" and not (v is not None and np.isfinite(v) and v > 0):
            raise ValueError(f"{prim.GetPath()}: {t} {attr.lower()} must be a positive number, got {v}")
        return v

    if t == "Sphere":
        p, tri, n = sphere(g(UsdGeom.Sphere, "Radius"), segments)
        axis = "Z"
    elif t == "Cube":
        p, tri, n = cube(g(UsdGeom.Cube, "Size"))
        axis = "Z"
    elif t == "Cylinder":
        p, tri, n = cylinder(g(UsdGeom.Cylinder, "Radius"), g(UsdGeom.Cylinder, "Height"), segments)
        axis = g(UsdGeom.Cylinder, "Axis")
    elif t == "Cone":
        p, tri, n = cone(g(UsdGeom.Cone, "Radius"), g(UsdGeom.Cone, "Height"), segments)
        axis = g(UsdGeom.Cone, "Axis")
    elif t == "Capsule":
        p, tri, n = capsule(g(UsdGeom.Capsule, "Radius"), g(UsdGeom.Capsule, "Height"), segments)
        axis = g(UsdGeom.Capsule, "Axis")
    elif t == "Cylinder_1":
        c1 = UsdGeom.Cylinder_1(prim)
        rb, rt = (float(a.Get(time)) for a in (c1.GetRadiusBottomAttr(), c1.GetRadiusTopAttr()))
        if not (np.isfinite(rb) and np.isfinite(rt) and rb >= 0 and rt >= 0 and rb + rt > 0):
            raise ValueError(f"{prim.GetPath()}: Cylinder_1 radii must be >= 0 and not both 0, got {rb}, {rt}")
        p, tri, n = frustum(rb, rt, g(UsdGeom.Cylinder_1, "Height"), segments)
        axis = g(UsdGeom.Cylinder_1, "Axis")
    elif t == "Capsule_1":  # radiusTop != radiusBottom: drawn with their mean radius (a warning)
        c1 = UsdGeom.Capsule_1(prim)
        rb, rt = (float(a.Get(time)) for a in (c1.GetRadiusBottomAttr(), c1.GetRadiusTopAttr()))
        if not (np.isfinite(rb) and np.isfinite(rt) and rb > 0 and rt > 0):
            raise ValueError(f"{prim.GetPath()}: Capsule_1 radii must be positive, got {rb}, {rt}")
        p, tri, n = capsule((rb + rt) / 2, g(UsdGeom.Capsule_1, "Height"), segments)
        axis = g(UsdGeom.Capsule_1, "Axis")
    elif t == "ArnoldSphere":
        radius = float(_arnold_value(prim, "radius", 0.5, time))
        if not radius > 0:
            raise ValueError(f"{prim.GetPath()}: ArnoldSphere radius must be a positive number, got {radius}")
        p, tri, n = sphere(radius, segments)
        p = p + _arnold_value(prim, "center", (0.0, 0.0, 0.0), time)
        axis = "Z"
    elif t == "ArnoldBox":
        lo = _arnold_value(prim, "min", (-0.5, -0.5, -0.5), time)
        hi = _arnold_value(prim, "max", (0.5, 0.5, 0.5), time)
        if not np.all(hi > lo):
            raise ValueError(f"{prim.GetPath()}: ArnoldBox max must exceed min, got {lo.tolist()}, {hi.tolist()}")
        p, tri, n = lo + (_CUBE_CORNERS + 1) / 2 * (hi - lo), _CUBE_TRIANGLES.copy(), None
        axis = "Z"
    elif t == "Plane":
        p, tri, n = plane(g(UsdGeom.Plane, "Width"), g(UsdGeom.Plane, "Length"))
        axis = g(UsdGeom.Plane, "Axis")
    else:
        return None
    r = _axis_matrix(axis)
    p = p @ r.T
    n = None if n is None else n @ r.T
    tri = np.asarray(tri, dtype=np.int64)
    return MeshData(points=p, triangles=tri, faces=np.zeros(len(tri), np.int64), n_faces=1, normals=n)

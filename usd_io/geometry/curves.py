"""``UsdGeom.Points`` as spheres and ``UsdGeom.BasisCurves`` as tubes, in object space (one MeshData each).

Points: an icosphere (80 triangles) of diameter ``widths`` per point (constant or per point; unauthored: 1 unit,
Storm's fallback). BasisCurves: each curve's control points joined by 8-sided tubes of diameter ``widths``
(constant, per curve, or per vertex/varying averaged per segment; unauthored: 1 unit). Linear curves are exact;
cubic curves (bezier, bspline, catmullRom) are evaluated into polylines of 8 pieces per segment first
(usd_io.geometry.cubic_curves); other bases follow their control polygon with one warning. ``wrap = periodic`` closes
the loop. Normals are exact (sphere radial, tube radial). No Python loop over points or segments.
"""

from __future__ import annotations

import numpy as np
from pxr import UsdGeom

from .cubic_curves import BASES, cubic_polylines
from .mesh import MeshData

TUBE_SIDES = 8


def _widths(schema, time, n_points, label, what):
    w = schema.GetWidthsAttr().Get(time)
    if w is None or len(w) == 0:
        return None
    w = np.asarray(w, np.float64)
    if not np.all(np.isfinite(w)) or np.any(w < 0):
        raise ValueError(f"{label}: {what} widths must be finite and non-negative")
    return w


def read_points(prim, time) -> MeshData | None:
    label = str(prim.GetPath())
    pts = UsdGeom.Points(prim).GetPointsAttr().Get(time)
    if pts is None or len(pts) == 0:
        return None
    p = np.asarray(pts, np.float64).reshape(-1, 3)
    w = _widths(UsdGeom.Points(prim), time, len(p), label, "points")
    radius = np.full(len(p), 0.5) if w is None else (np.full(len(p), w[0] / 2) if len(w) != len(p) else w / 2)
    import trimesh  # here, not at import: 0.06 s of every start-up for a stage that has no points

    ico = trimesh.creation.icosphere(subdivisions=1)
    unit = np.asarray(ico.vertices, np.float64)
    faces = np.asarray(ico.faces, np.int64)
    nv = len(unit)
    verts = (p[:, None, :] + radius[:, None, None] * unit[None]).reshape(-1, 3)
    tris = (faces[None] + (np.arange(len(p)) * nv)[:, None, None]).reshape(-1, 3)
    normals = np.broadcast_to(unit[None], (len(p), nv, 3)).reshape(-1, 3).copy()
    keep = np.repeat(radius > 0, len(faces))
    point_of_tri = np.repeat(np.arange(len(p)), len(faces))[keep]  # primvars: one "face" per point
    return MeshData(verts, tris[keep], point_of_tri, len(p), normals=normals,
                    source_points=np.repeat(np.arange(len(p)), nv))


def curve_widths(schema, time, n_points, n_curves, label):
    """Control-point widths (P,) of a curves prim: per point as authored (vertex/varying with one value per point),
    per curve repeated over its points, else the first value everywhere; None when unauthored."""
    w = _widths(schema, time, n_points, label, "curve")
    if w is None:
        return None
    if len(w) == n_points:
        return w
    counts = np.asarray(schema.GetCurveVertexCountsAttr().Get(time), np.int64)
    if len(w) == n_curves and len(counts) == n_curves:
        return np.repeat(w, counts)
    return np.full(n_points, w[0])


def read_curves(prim, time) -> MeshData | None:
    label = str(prim.GetPath())
    curves = UsdGeom.BasisCurves(prim)
    pts = curves.GetPointsAttr().Get(time)
    counts = curves.GetCurveVertexCountsAttr().Get(time)
    if pts is None or counts is None or len(pts) == 0 or len(counts) == 0:
        return None
    p = np.asarray(pts, np.float64).reshape(-1, 3)
    counts = np.asarray(counts, np.int64)
    if np.any(counts < 1) or counts.sum() != len(p):
        raise ValueError(f"{label}: curveVertexCounts sum to {counts.sum()}, not the {len(p)} points")
    warnings = []
    wrap = str(curves.GetWrapAttr().Get(time) or "nonperiodic")
    widths = curve_widths(curves, time, len(p), len(counts), label)
    if curves.GetTypeAttr().Get(time) == UsdGeom.Tokens.cubic:
        basis = str(curves.GetBasisAttr().Get(time) or "bezier")
        if basis in BASES:  # the curve itself (usd_io.geometry.cubic_curves), not its control polygon
            p2, counts2, widths2, source = cubic_polylines(p, counts, basis, wrap, widths)
            data = tube_mesh(p2, counts2, widths2, periodic=False)
            if data is not None:  # faces are already the curves (one polyline each); colours: nearest point
                data.source_points = source[data.source_points]
            return data
        warnings.append(f"{label}: cubic {basis} curves drawn as tubes along their control polygon")
    data = tube_mesh(p, counts, widths, wrap == UsdGeom.Tokens.periodic)
    if data is not None:
        data.warnings = warnings
    return data



def tube_mesh(p: np.ndarray, counts: np.ndarray, widths, periodic: bool) -> MeshData | None:
    """Polylines (points ``p`` (P, 3), ``counts`` points per curve) as TUBE_SIDES-sided tubes whose diameter at each
    point is ``widths`` (P,) (None: 1 unit); a segment's radius is the mean of its ends'. ``periodic`` closes each
    curve. No Python loop over segments."""
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    curve_of_point = np.repeat(np.arange(len(counts)), counts)
    a = np.arange(len(p))
    nxt = a + 1
    last = np.cumsum(counts) - 1
    is_last = np.zeros(len(p), bool)
    is_last[last] = True
    if periodic:
        nxt[last] = starts
        seg = np.stack([a, nxt], 1)[counts[curve_of_point] > 1]
    else:
        seg = np.stack([a, nxt], 1)[~is_last]
    if not len(seg):
        return None
    if widths is None:
        r = np.full(len(seg), 0.5)
    else:
        r = (widths[seg[:, 0]] + widths[seg[:, 1]]) / 4
    p0, p1 = p[seg[:, 0]], p[seg[:, 1]]
    d = p1 - p0
    length = np.linalg.norm(d, axis=1)
    ok = (length > 0) & (r > 0)
    p0, p1, d, r, length, seg = p0[ok], p1[ok], d[ok], r[ok], length[ok], seg[ok]
    if not len(p0):
        return None
    d = d / length[:, None]
    helper = np.where(np.abs(d[:, [0]]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    u = np.cross(d, helper)
    u /= np.linalg.norm(u, axis=1)[:, None]
    v = np.cross(d, u)
    ang = np.linspace(0, 2 * np.pi, TUBE_SIDES, endpoint=False)
    ring = np.cos(ang)[None, :, None] * u[:, None] + np.sin(ang)[None, :, None] * v[:, None]  # (S, K, 3)
    verts = np.concatenate([p0[:, None] + r[:, None, None] * ring, p1[:, None] + r[:, None, None] * ring], 1)
    normals = np.concatenate([ring, ring], 1)
    k = np.arange(TUBE_SIDES)
    k1 = (k + 1) % TUBE_SIDES
    quad = np.concatenate([np.stack([k, k1, TUBE_SIDES + k1], 1), np.stack([k, TUBE_SIDES + k1, TUBE_SIDES + k], 1)])
    n_seg = len(p0)
    tris = (quad[None] + (np.arange(n_seg) * 2 * TUBE_SIDES)[:, None, None]).reshape(-1, 3)
    # primvars: a triangle's face is its curve (uniform), a vertex's source point the end of its segment it rings
    faces = np.repeat(curve_of_point[seg[:, 0]], len(quad))
    source = np.concatenate([np.repeat(seg[:, :1], TUBE_SIDES, 1), np.repeat(seg[:, 1:], TUBE_SIDES, 1)], 1)
    return MeshData(verts.reshape(-1, 3), tris, faces, len(counts), normals=normals.reshape(-1, 3),
                    source_points=source.reshape(-1))

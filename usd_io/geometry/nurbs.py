"""``UsdGeom.NurbsPatch`` (with trim curves), ``UsdGeom.NurbsCurves`` and ``UsdGeom.TetMesh`` as triangles.

Rational B-splines are evaluated by the Cox–de Boor recursion (:func:`basis`), vectorised over the sample
parameters: a point is ``Σ N_i(u) w_i P_i / Σ N_i(u) w_i`` (``pointWeights``, 1 where unauthored); a patch is the
tensor product, ``S(u, v) = Σ_ij N_i(u) N_j(v) w_ij P_ij / Σ_ij N_i(u) N_j(v) w_ij`` with points ordered u fastest
(UsdGeomNurbsPatch). Knot vectors are used as authored (so periodic forms, whose authors repeat the first
``order − 1`` points, come out closed); parameters run over ``uRange``/``vRange`` (``ranges`` per curve), or the
knots' valid span ``[k[order−1], k[n]]`` when unauthored.

Primvars of vertex/varying interpolation (one value per control point, e.g. displayColor) are evaluated at every
sample with the same rational basis as the points (``MeshData.point_weights``).

Sampling: :data:`SAMPLES_PER_SPAN` samples per non-empty knot span (at least :data:`MIN_SAMPLES` over a patch
direction), a grid of quads split in two. Normals: area-weighted from the grid (smooth; the patch's own
orientation attribute turns the winding as for meshes).

Trim curves (``trimCurve:*``): each loop is a rational B-spline in (u, v) parameter space with homogeneous points
(u·w, v·w, w), sampled like a curve; a grid triangle is kept when its parameter-space centroid is inside an odd
number of loops (the even–odd rule, as RenderMan and OpenNURBS trim: an outer loop with holes). The trimmed edge is
therefore as fine as the sampling grid (a staircase finer than one grid cell), a documented approximation.

NurbsCurves become tubes (or, with ``widths`` of zero, nothing) through :func:`usd_io.geometry.curves.tube_mesh`, the
same builder BasisCurves use: each curve sampled into a polyline, ``widths`` interpolated along it (constant,
uniform per curve, vertex/varying per control point mapped to the samples by their parameter).

TetMesh: its surface faces (``surfaceFaceVertexIndices`` when authored, else
``UsdGeomTetMesh::ComputeSurfaceFaces``: the faces that belong to one tetrahedron only), as a triangle mesh.
"""

from __future__ import annotations

import numpy as np
from pxr import UsdGeom

from .curves import curve_widths, tube_mesh
from .mesh import MeshData, smooth_normals

SAMPLES_PER_SPAN = 8
MIN_SAMPLES = 16
MAX_SAMPLES = 256


def basis(knots: np.ndarray, order: int, n: int, t: np.ndarray) -> np.ndarray:
    """B-spline basis functions (len(t), n) of ``order`` (degree + 1) over ``knots`` (n + order values) at
    parameters ``t`` (Cox–de Boor; 0/0 = 0). The last parameter of the valid span is evaluated just inside it."""
    k = np.asarray(knots, np.float64)
    t = np.asarray(t, np.float64)
    lo, hi = k[order - 1], k[n]
    t = np.clip(t, lo, hi)
    t = np.where(t >= hi, np.nextafter(hi, lo), t)  # half-open spans: the end is the limit from inside
    # degree 0: indicator of each knot span
    N = ((k[None, :-1] <= t[:, None]) & (t[:, None] < k[None, 1:])).astype(np.float64)
    for p in range(1, order):
        left_den = k[p:-1] - k[:-p - 1]  # k[i+p] - k[i]
        right_den = k[p + 1:] - k[1:-p]  # k[i+p+1] - k[i+1]
        m = N.shape[1] - 1
        a = np.divide(t[:, None] - k[None, :m], left_den[None, :m], out=np.zeros((len(t), m)),
                      where=left_den[None, :m] != 0)
        b = np.divide(k[None, p + 1:p + 1 + m] - t[:, None], right_den[None, :m], out=np.zeros((len(t), m)),
                      where=right_den[None, :m] != 0)
        N = a * N[:, :m] + b * N[:, 1:m + 1]
    return N[:, :n]


def _params(knots, order, n, rng, min_samples=2):
    """Sample parameters over the valid span (or ``rng``): SAMPLES_PER_SPAN per non-empty span."""
    k = np.asarray(knots, np.float64)
    lo, hi = float(k[order - 1]), float(k[n])
    if rng is not None and len(rng) == 2 and np.all(np.isfinite(rng)) and rng[1] > rng[0]:
        lo, hi = max(lo, float(rng[0])), min(hi, float(rng[1]))
    spans = int(np.sum(np.diff(k[order - 1:n + 1]) > 0))
    count = int(np.clip(max(spans, 1) * SAMPLES_PER_SPAN + 1, min_samples, MAX_SAMPLES))
    return np.linspace(lo, hi, count)


def _check(label, what, knots, order, n):
    if order < 1 or n < order:
        raise ValueError(f"{label}: {what} order {order} needs at least that many control points, got {n}")
    if len(knots) != n + order:
        raise ValueError(f"{label}: {what} has {len(knots)} knots; {n} points of order {order} need {n + order}")
    if np.any(np.diff(knots) < 0) or not np.all(np.isfinite(knots)):
        raise ValueError(f"{label}: {what} knots must be finite and non-decreasing")


def _grid_triangles(nu: int, nv: int) -> np.ndarray:
    i, j = np.meshgrid(np.arange(nu - 1), np.arange(nv - 1), indexing="ij")
    a = (j * nu + i).reshape(-1)  # samples ordered u fastest, like the control points
    b, c, d = a + 1, a + 1 + nu, a + nu
    return np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def read_nurbs_patch(prim, time) -> MeshData | None:
    label = str(prim.GetPath())
    patch = UsdGeom.NurbsPatch(prim)
    get = lambda a: a.Get(time)  # noqa: E731
    pts = get(patch.GetPointsAttr())
    nu, nv = get(patch.GetUVertexCountAttr()), get(patch.GetVVertexCountAttr())
    ou, ov = get(patch.GetUOrderAttr()), get(patch.GetVOrderAttr())
    ku, kv = get(patch.GetUKnotsAttr()), get(patch.GetVKnotsAttr())
    if pts is None or not len(pts) or None in (nu, nv, ou, ov, ku, kv):
        return None
    nu, nv, ou, ov = int(nu), int(nv), int(ou), int(ov)
    p = np.asarray(pts, np.float64).reshape(-1, 3)
    if len(p) != nu * nv:
        raise ValueError(f"{label}: NurbsPatch has {len(p)} points for {nu} x {nv} vertices")
    ku, kv = np.asarray(ku, np.float64), np.asarray(kv, np.float64)
    _check(label, "u", ku, ou, nu)
    _check(label, "v", kv, ov, nv)
    w = get(patch.GetPointWeightsAttr())
    w = np.ones(len(p)) if w is None or len(w) != len(p) else np.asarray(w, np.float64)
    if np.any(w <= 0) or not np.all(np.isfinite(w)):
        raise ValueError(f"{label}: NurbsPatch pointWeights must be positive")
    u = _params(ku, ou, nu, get(patch.GetURangeAttr()), MIN_SAMPLES)
    v = _params(kv, ov, nv, get(patch.GetVRangeAttr()), MIN_SAMPLES)
    Nu, Nv = basis(ku, ou, nu, u), basis(kv, ov, nv, v)
    hw = np.concatenate([p * w[:, None], w[:, None]], axis=1).reshape(nv, nu, 4)  # [v, u, xyzw]
    s = np.einsum("ai,bj,jik->bak", Nu, Nv, hw)  # [v sample, u sample, xyzw]: u fastest when flattened
    points = (s[..., :3] / s[..., 3:4]).reshape(-1, 3)
    tris = _grid_triangles(len(u), len(v))
    warnings = []
    counts = get(patch.GetTrimCurveCountsAttr())
    if counts is not None and len(counts):
        try:
            keep = _trim_mask(patch, time, u, v, tris, label)
            tris = tris[keep]
        except ValueError as exc:
            warnings.append(f"{exc} (trim curves ignored)")
    if patch.GetOrientationAttr().Get(time) == UsdGeom.Tokens.leftHanded:
        tris = tris[:, [0, 2, 1]]
    if not len(tris):
        return None
    uv = np.stack(np.meshgrid((u - u[0]) / max(u[-1] - u[0], 1e-30), (v - v[0]) / max(v[-1] - v[0], 1e-30),
                              indexing="xy"), axis=-1).reshape(-1, 2)
    data = MeshData(points, tris, np.zeros(len(tris), np.int64), 1, normals=smooth_normals(points, tris),
                    uvs=uv[tris], warnings=warnings)
    # vertex/varying primvars follow the surface: each sample is the same rational combination of the control
    # points' values as of their positions (usd_io.materials.primvars.gprim_colors reads it)
    wgt = np.einsum("ai,bj,ji->baji", Nu, Nv, w.reshape(nv, nu)).reshape(len(v) * len(u), nv * nu)
    data.point_weights = wgt / wgt.sum(axis=1, keepdims=True)
    return data


def _trim_mask(patch, time, u, v, tris, label) -> np.ndarray:
    """Grid triangles whose (u, v) centroid is inside an odd number of trim loops."""
    get = lambda a: a.Get(time)  # noqa: E731
    counts = np.asarray(get(patch.GetTrimCurveCountsAttr()), np.int64)
    orders = np.asarray(get(patch.GetTrimCurveOrdersAttr()) or [], np.int64)
    vcounts = np.asarray(get(patch.GetTrimCurveVertexCountsAttr()) or [], np.int64)
    knots = np.asarray(get(patch.GetTrimCurveKnotsAttr()) or [], np.float64)
    ranges = get(patch.GetTrimCurveRangesAttr())
    pts = np.asarray(get(patch.GetTrimCurvePointsAttr()) or [], np.float64).reshape(-1, 3)
    n_curves = int(counts.sum())
    if len(orders) != n_curves or len(vcounts) != n_curves or vcounts.sum() != len(pts) \
            or len(knots) != int((vcounts + orders).sum()):
        raise ValueError(f"{label}: trim curve counts, orders, vertex counts, knots and points do not agree")
    grid_u, grid_v = np.meshgrid(u, v, indexing="xy")
    uv = np.stack([grid_u.reshape(-1), grid_v.reshape(-1)], axis=1)
    centre = uv[tris].mean(axis=1)
    inside = np.zeros(len(tris), np.int64)
    pi = ki = ci = 0
    for loop_count in counts:
        poly = []
        for _ in range(int(loop_count)):
            n, o = int(vcounts[ci]), int(orders[ci])
            k = knots[ki:ki + n + o]
            h = pts[pi:pi + n]
            _check(label, "trim curve", k, o, n)
            rng = None if ranges is None or len(ranges) <= ci else np.asarray(ranges[ci], np.float64)
            t = _params(k, o, n, rng, 2)
            B = basis(k, o, n, t)
            hw = B @ h  # homogeneous (u·w, v·w, w)
            if np.any(np.abs(hw[:, 2]) < 1e-12):
                raise ValueError(f"{label}: a trim curve has zero weights")
            poly.append(hw[:, :2] / hw[:, 2:3])
            pi, ki, ci = pi + n, ki + n + o, ci + 1
        inside += _crossings(centre, np.concatenate(poly))
    return inside % 2 == 1


def _crossings(q: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """1 where points ``q`` (M, 2) are inside the closed polygon ``poly`` (K, 2) by the even–odd rule."""
    a, b = poly, np.roll(poly, -1, axis=0)
    qy, qx = q[:, 1:2], q[:, 0:1]
    straddle = (a[None, :, 1] > qy) != (b[None, :, 1] > qy)
    dy = np.where(b[:, 1] - a[:, 1] == 0, 1e-300, b[:, 1] - a[:, 1])
    x_at = a[None, :, 0] + (qy - a[None, :, 1]) * (b[None, :, 0] - a[None, :, 0]) / dy[None]
    return (np.sum(straddle & (qx < x_at), axis=1) % 2).astype(np.int64)


def nurbs_curve_polylines(prim, time):
    """(points (P, 3), counts (C,), widths (P,) or None) of a NurbsCurves prim sampled into polylines."""
    label = str(prim.GetPath())
    nc = UsdGeom.NurbsCurves(prim)
    pts = nc.GetPointsAttr().Get(time)
    counts = nc.GetCurveVertexCountsAttr().Get(time)
    if pts is None or counts is None or not len(pts) or not len(counts):
        return None
    p = np.asarray(pts, np.float64).reshape(-1, 3)
    counts = np.asarray(counts, np.int64)
    if np.any(counts < 1) or counts.sum() != len(p):
        raise ValueError(f"{label}: curveVertexCounts sum to {counts.sum()}, not the {len(p)} points")
    orders = nc.GetOrderAttr().Get(time)
    orders = np.full(len(counts), 4, np.int64) if orders is None or not len(orders) else np.asarray(orders, np.int64)
    if len(orders) != len(counts):
        raise ValueError(f"{label}: {len(orders)} orders for {len(counts)} curves")
    knots = np.asarray(nc.GetKnotsAttr().Get(time) or [], np.float64)
    warnings = []
    if not len(knots):  # Storm draws such curves too: open uniform knots (the curve ends at its end points)
        knots = np.concatenate([_open_uniform(int(n), int(o)) for n, o in zip(counts, orders)])
        warnings.append(f"{label}: NurbsCurves without knots: open uniform knots used")
    if len(knots) != int((counts + orders).sum()):
        raise ValueError(f"{label}: {len(knots)} knots; the curves need {int((counts + orders).sum())}")
    w = nc.GetPointWeightsAttr().Get(time)
    w = np.ones(len(p)) if w is None or len(w) != len(p) else np.asarray(w, np.float64)
    ranges = nc.GetRangesAttr().Get(time)
    per_point_w = curve_widths(nc, time, len(p), len(counts), label)  # (P,) control-point widths or None
    out_p, out_c, out_w = [], [], []
    pi = ki = 0
    for c, (n, o) in enumerate(zip(counts, orders)):
        n, o = int(n), int(o)
        k = knots[ki:ki + n + o]
        _check(label, f"curve {c}", k, o, n)
        rng = None if ranges is None or len(ranges) <= c else np.asarray(ranges[c], np.float64)
        t = _params(k, o, n, rng, 2)
        B = basis(k, o, n, t)
        cw = w[pi:pi + n]
        den = B @ cw
        out_p.append((B @ (p[pi:pi + n] * cw[:, None])) / den[:, None])
        out_c.append(len(t))
        if per_point_w is not None:  # widths follow the control points through the same (non-rational) basis
            out_w.append(B @ per_point_w[pi:pi + n])
        pi, ki = pi + n, ki + n + o
    return (np.concatenate(out_p), np.asarray(out_c, np.int64),
            np.concatenate(out_w) if out_w else None, warnings)


def _open_uniform(n: int, order: int) -> np.ndarray:
    """The clamped uniform knot vector of n points of ``order`` (order equal knots at each end)."""
    inner = np.linspace(0.0, 1.0, max(n - order + 2, 2))
    return np.concatenate([np.zeros(order - 1), inner, np.ones(order - 1)])[: n + order]


def read_nurbs_curves(prim, time) -> MeshData | None:
    got = nurbs_curve_polylines(prim, time)
    if got is None:
        return None
    points, counts, widths, warnings = got
    data = tube_mesh(points, counts, widths, periodic=False)
    if data is not None:
        data.warnings = warnings
    return data


def read_tet_mesh(prim, time) -> MeshData | None:
    label = str(prim.GetPath())
    tm = UsdGeom.TetMesh(prim)
    pts = tm.GetPointsAttr().Get(time)
    if pts is None or not len(pts):
        return None
    p = np.asarray(pts, np.float64).reshape(-1, 3)
    faces = tm.GetSurfaceFaceVertexIndicesAttr().Get(time)
    if faces is None or not len(faces):
        faces = UsdGeom.TetMesh.ComputeSurfaceFaces(tm, time)
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    if not len(f):
        return None
    if f.min() < 0 or f.max() >= len(p):
        raise ValueError(f"{label}: TetMesh faces reference points outside the {len(p)} points")
    if tm.GetOrientationAttr().Get(time) == UsdGeom.Tokens.leftHanded:
        f = f[:, [0, 2, 1]]
    return MeshData(p, f, np.arange(len(f)), len(f), normals=None)

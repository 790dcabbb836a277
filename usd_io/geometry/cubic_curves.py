"""Cubic ``BasisCurves`` (bezier, bspline, catmullRom) evaluated into polylines, so their tubes follow the curve
and not its control polygon.

Each segment is four control points and the basis's 4 × 4 matrix (UsdGeomBasisCurves: bezier steps 3 points per
segment, bspline and catmullRom 1). ``wrap = periodic`` closes bspline/catmullRom curves over their first points;
``pinned`` repeats the end points so the curve reaches them (catmullRom: one phantom point at each end, bspline:
two, as the schema describes). Each segment becomes :data:`SAMPLES` polyline pieces. Per-point values (widths, and
the vertex each sample stands for, for colours) follow: widths through the same basis, colours from the nearest of
the segment's control points.
"""

from __future__ import annotations

import numpy as np

SAMPLES = 8
#: The basis matrices M: a point of a segment is [t³, t², t, 1] · M · [P0, P1, P2, P3].
BASES = {
    "bezier": (np.array([[-1, 3, -3, 1], [3, -6, 3, 0], [-3, 3, 0, 0], [1, 0, 0, 0]], np.float64), 3),
    "bspline": (np.array([[-1, 3, -3, 1], [3, -6, 3, 0], [-3, 0, 3, 0], [1, 4, 1, 0]], np.float64) / 6, 1),
    "catmullRom": (np.array([[-1, 3, -3, 1], [2, -5, 4, -1], [-1, 0, 1, 0], [0, 2, 0, 0]], np.float64) / 2, 1),
}


def segment_indices(n: int, basis: str, wrap: str) -> np.ndarray:
    """(S, 4) control-point indices (into one curve's n points) of its segments; empty when n is too small."""
    _m, step = BASES[basis]
    idx = np.arange(n)
    if wrap == "periodic" and basis != "bezier":
        idx = np.concatenate([idx, idx[:3]])
    elif wrap == "pinned" and basis != "bezier":
        pad = 1 if basis == "catmullRom" else 2
        idx = np.concatenate([np.repeat(idx[:1], pad), idx, np.repeat(idx[-1:], pad)])
    starts = np.arange(0, len(idx) - 3, step)
    return idx[starts[:, None] + np.arange(4)[None]] if len(starts) else np.zeros((0, 4), np.int64)


def cubic_polylines(p: np.ndarray, counts: np.ndarray, basis: str, wrap: str, widths=None):
    """(points (Q, 3), counts per polyline, widths (Q,) or None, nearest control point per sample (Q,)) of cubic
    curves; a curve too short for one segment keeps its control points (a polyline). Open curves (the usual hair
    and guide curves) are evaluated all at once; periodic and pinned ones curve by curve."""
    if wrap not in ("periodic", "pinned") or basis == "bezier":
        return _open_polylines(p, counts, basis, widths)
    return _curve_by_curve(p, counts, basis, wrap, widths)


def _curve_by_curve(p, counts, basis, wrap, widths):
    """cubic_polylines one curve at a time (any wrap; :func:`segment_indices` says which points each segment uses)."""
    m, _step = BASES[basis]
    t = np.linspace(0.0, 1.0, SAMPLES + 1)
    weights = np.stack([t ** 3, t ** 2, t, np.ones_like(t)], axis=1) @ m  # (SAMPLES + 1, 4)
    out_p, out_c, out_w, out_src = [], [], [], []
    start = 0
    for n in counts:
        n = int(n)
        seg = segment_indices(n, basis, wrap) + start
        if not len(seg):
            out_p.append(p[start:start + n])
            out_c.append(n)
            out_w.append(None if widths is None else widths[start:start + n])
            out_src.append(np.arange(start, start + n))
        else:
            pts = np.einsum("sk,nkd->nsd", weights, p[seg])[:, :-1].reshape(-1, 3)  # segment ends shared
            last = np.einsum("k,kd->d", weights[-1], p[seg[-1]])
            out_p.append(np.vstack([pts, last]))
            out_c.append(len(pts) + 1)
            if widths is not None:
                ws = np.einsum("sk,nk->ns", weights, widths[seg])[:, :-1].reshape(-1)
                out_w.append(np.append(ws, weights[-1] @ widths[seg[-1]]))
            near = seg[:, np.clip(np.round(t[:-1] * 3).astype(int), 0, 3)].reshape(-1)
            out_src.append(np.append(near, seg[-1, 3]))
        start += n
    w = None if widths is None else np.concatenate(out_w)
    return np.concatenate(out_p), np.asarray(out_c, np.int64), w, np.concatenate(out_src)


def _open_polylines(p, counts, basis, widths):
    """cubic_polylines of open curves without a Python loop over curves: segment k of a curve starting at point s
    uses points s + step·k … s + step·k + 3; its SAMPLES first samples, plus each curve's end."""
    m, step = BASES[basis]
    t = np.linspace(0.0, 1.0, SAMPLES + 1)
    weights = np.stack([t ** 3, t ** 2, t, np.ones_like(t)], axis=1) @ m  # (SAMPLES + 1, 4)
    counts = np.asarray(counts, np.int64)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    nseg = np.where(counts >= 4, -(-(counts - 3) // step), 0)
    out_n = np.where(nseg > 0, nseg * SAMPLES + 1, counts)  # samples per polyline
    curve_of_seg = np.repeat(np.arange(len(counts)), nseg)
    k = np.arange(len(curve_of_seg)) - np.repeat(np.cumsum(nseg) - nseg, nseg)
    seg = (starts[curve_of_seg] + step * k)[:, None] + np.arange(4)[None]  # (S, 4)
    out_start = np.concatenate([[0], np.cumsum(out_n)[:-1]])
    q = int(out_n.sum())
    pts = np.empty((q, 3))
    src = np.empty(q, np.int64)
    wid = None if widths is None else np.empty(q)
    # sampled curves: SAMPLES samples of every segment, then the curve's end (t = 1 of its last segment)
    rows = (out_start[curve_of_seg] + SAMPLES * k)[:, None] + np.arange(SAMPLES)[None]  # (S, SAMPLES)
    pts[rows] = np.einsum("sk,nkd->nsd", weights[:-1], p[seg])
    near = np.clip(np.round(t[:-1] * 3).astype(np.int64), 0, 3)
    src[rows] = seg[:, near]
    last_seg = np.cumsum(nseg)[nseg > 0] - 1
    ends = out_start[nseg > 0] + out_n[nseg > 0] - 1
    pts[ends] = np.einsum("k,nkd->nd", weights[-1], p[seg[last_seg]])
    src[ends] = seg[last_seg, 3]
    if wid is not None:
        wid[rows] = np.einsum("sk,nk->ns", weights[:-1], widths[seg])
        wid[ends] = widths[seg[last_seg]] @ weights[-1]
    # curves too short for a segment: their control points as they are
    short = np.flatnonzero(nseg == 0)
    if len(short):
        idx = np.concatenate([np.arange(starts[c], starts[c] + counts[c]) for c in short])
        at = np.concatenate([np.arange(out_start[c], out_start[c] + counts[c]) for c in short])
        pts[at], src[at] = p[idx], idx
        if wid is not None:
            wid[at] = widths[idx]
    return pts, out_n, wid, src

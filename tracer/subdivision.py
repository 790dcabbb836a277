"""Catmull-Clark subdivision of polygon meshes, on numpy (usd-core has no OpenSubdiv binding).

``catmull_clark(points, counts, indices, levels)`` refines any polygon mesh (triangles, quads, n-gons) uniformly:
after one level every face of n corners has become n quads. The rules are Catmull and Clark's (1978) as OpenSubdiv
applies them for uniform refinement with ``interpolateBoundary = edgeAndCorner`` (USD's default):

- face point F = the mean of the face's corners;
- edge point: interior edge (two faces) (v0 + v1 + F_a + F_b) / 4; boundary edge (one face) the midpoint;
- vertex point: interior vertex of valence n, V' = (Q + 2R + (n − 3)·V) / n with Q the mean of the adjacent face
  points and R the mean of the incident edges' midpoints; boundary vertex (1·a + 6·V + 1·b) / 8 with a, b its two
  boundary neighbours; a corner (a boundary vertex on a single face) stays where it is.

Non-manifold edges (three or more faces) are treated as boundaries (a crease), as OpenSubdiv does. Creases with
sharpness and semi-sharp corners are not refined here (see :data:`NOT_SUPPORTED`). Every refinement also returns
the source face of each new quad; vertex primvars (``vertex_data``, e.g. a vertex displayColor) refine with the
points by the same (linear) rules, and face-varying data (UVs) refines linearly (face point = the mean of the face's
corners, edge point = the mean of its two corners: OpenSubdiv's ``faceVaryingLinearInterpolation = all``).
Each function is vectorised over all faces (no Python loop per face or vertex).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: What the refinement does not do (the USD reader warns once per mesh that asks for it).
NOT_SUPPORTED = ("creases", "corners", "loop scheme", "interpolateBoundary none/edgeOnly",
                 "faceVaryingLinearInterpolation other than all")


@dataclass
class Refined:
    """One or more levels of refinement: ``points`` (V, 3), all-quad ``indices`` (Q, 4), the original face of each
    quad (``face``), face-varying values per quad corner (``fvar``, (Q, 4, k)) when given."""

    points: np.ndarray
    indices: np.ndarray
    face: np.ndarray
    fvar: np.ndarray | None = None
    vertex_data: np.ndarray | None = None  # (V, k) refined vertex primvars, when given

    @property
    def counts(self) -> np.ndarray:
        return np.full(len(self.indices), 4, np.int32)


def catmull_clark(points, counts, indices, levels: int = 1, fvar=None, vertex_data=None) -> Refined:
    """Refine the mesh ``levels`` times. ``fvar``: optional face-varying values, one row per face-vertex (the order
    of ``indices``), refined linearly with it; ``vertex_data``: optional (V, k) per-vertex values refined with the
    points."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    k = 0
    if vertex_data is not None:
        vd = np.asarray(vertex_data, np.float64).reshape(len(p), -1)
        k = vd.shape[1]
        p = np.concatenate([p, vd], axis=1)
    counts = np.asarray(counts, np.int64)
    idx = np.asarray(indices, np.int64)
    if counts.sum() != len(idx) or np.any(counts < 3):
        raise ValueError("catmull_clark: faceVertexCounts must be >= 3 and sum to len(faceVertexIndices)")
    face = np.arange(len(counts))
    fv = None if fvar is None else np.asarray(fvar, np.float64).reshape(len(idx), -1)
    for _ in range(max(0, int(levels))):
        p, counts, idx, parent, fv = _one_level(p, counts, idx, fv)
        face = face[parent]
    quads = idx.reshape(-1, 4) if len(idx) else np.zeros((0, 4), np.int64)
    return Refined(points=p[:, :3], indices=quads, face=face,
                   fvar=None if fv is None else fv.reshape(len(quads), 4, -1),
                   vertex_data=p[:, 3:] if k else None)


def _one_level(p, counts, idx, fv):
    n_v, n_f = len(p), len(counts)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    corner_face = np.repeat(np.arange(n_f), counts)
    pos_in_face = np.arange(len(idx)) - start[corner_face]
    nxt = start[corner_face] + (pos_in_face + 1) % counts[corner_face]
    prv = start[corner_face] + (pos_in_face - 1) % counts[corner_face]

    # Face points.
    fp = np.zeros((n_f, p.shape[1]))
    np.add.at(fp, corner_face, p[idx])
    fp /= counts[:, None]

    # Edges: one per (min, max) vertex pair; each corner owns the edge to the next corner.
    a, b = idx, idx[nxt]
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo * n_v + hi
    edge_key, corner_edge = np.unique(key, return_inverse=True)
    n_e = len(edge_key)
    e_lo, e_hi = edge_key // n_v, edge_key % n_v
    e_faces = np.bincount(corner_edge, minlength=n_e)
    boundary_edge = e_faces != 2
    e_face_sum = np.zeros((n_e, p.shape[1]))
    np.add.at(e_face_sum, corner_edge, fp[corner_face])
    mid = (p[e_lo] + p[e_hi]) / 2
    ep = mid.copy()
    interior = ~boundary_edge
    ep[interior] = (p[e_lo[interior]] + p[e_hi[interior]] + e_face_sum[interior]) / 4.0

    # Vertex points.
    valence = np.bincount(np.concatenate([e_lo, e_hi]), minlength=n_v)  # incident edges
    n_faces_at = np.bincount(idx, minlength=n_v)
    q = np.zeros((n_v, p.shape[1]))
    np.add.at(q, idx, fp[corner_face])
    q /= np.maximum(n_faces_at, 1)[:, None]
    r = np.zeros((n_v, p.shape[1]))
    np.add.at(r, e_lo, mid)
    np.add.at(r, e_hi, mid)
    r /= np.maximum(valence, 1)[:, None]
    nv = valence.astype(np.float64)[:, None]
    vp = (q + 2 * r + (nv - 3) * p) / np.maximum(nv, 1)
    # Boundary vertices: (a + 6V + b)/8 over their boundary edges; corners (one face) stay.
    b_deg = np.bincount(np.concatenate([e_lo[boundary_edge], e_hi[boundary_edge]]), minlength=n_v)
    b_sum = np.zeros((n_v, p.shape[1]))
    np.add.at(b_sum, e_lo[boundary_edge], p[e_hi[boundary_edge]])
    np.add.at(b_sum, e_hi[boundary_edge], p[e_lo[boundary_edge]])
    on_boundary = b_deg > 0
    smooth_b = b_deg == 2
    vp[on_boundary] = p[on_boundary]  # non-manifold boundaries (b_deg != 2) and corners stay
    vp[smooth_b] = (b_sum[smooth_b] + 6 * p[smooth_b]) / 8
    corner = on_boundary & (n_faces_at == 1)
    vp[corner] = p[corner]
    unused = n_faces_at == 0
    vp[unused] = p[unused]

    # New vertices: [vertex points | edge points | face points]; one quad per old corner:
    # (V_i', E(i, i+1), F, E(i-1, i)).
    new_p = np.concatenate([vp, ep, fp])
    e_off, f_off = n_v, n_v + n_e
    quads = np.stack([idx, e_off + corner_edge, f_off + corner_face, e_off + corner_edge[prv]], axis=1)
    new_fv = None
    if fv is not None:
        f_fv = np.zeros((n_f, fv.shape[1]))
        np.add.at(f_fv, corner_face, fv)
        f_fv /= counts[:, None]
        e_next = (fv + fv[nxt]) / 2  # the corner's own edge, linear in the face's corners
        e_prev = (fv + fv[prv]) / 2
        new_fv = np.stack([fv, e_next, f_fv[corner_face], e_prev], axis=1).reshape(-1, fv.shape[1])
    return new_p, np.full(len(idx), 4, np.int64), quads.reshape(-1), corner_face, new_fv


def limit_normals(points, quads) -> np.ndarray:
    """Smooth per-vertex normals of a refined all-quad mesh: area-weighted face normals (the quads' diagonals'
    cross product), summed at each vertex and normalised."""
    p = np.asarray(points, np.float64)
    q = np.asarray(quads, np.int64)
    n = np.cross(p[q[:, 2]] - p[q[:, 0]], p[q[:, 3]] - p[q[:, 1]])
    vn = np.zeros_like(p)
    for k in range(4):
        np.add.at(vn, q[:, k], n)
    return vn / np.maximum(np.linalg.norm(vn, axis=1, keepdims=True), 1e-30)

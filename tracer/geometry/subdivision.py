"""Subdivision surfaces on numpy: uniform refinement by OpenSubdiv's rules (usd-core has no OpenSubdiv binding).

``refine(points, counts, indices, levels, ...)`` refines a polygon mesh ``levels`` times and returns a
:class:`Refined` mesh: points, faces (quads, or triangles for Loop), the cage face of every refined face, smooth
per-corner normals of the limit surface, and the primvars carried through. Everything is vectorised over faces,
edges and corners (no Python loop per face, edge or vertex: only short loops over levels, valences and columns).
``refine_batch(meshes)`` refines many meshes in a few calls: the meshes of one topology once, as columns of one
refinement (``_refine_stack``), the rest joined into one mesh of disjoint pieces; each gets exactly what
``refine`` gives it alone (a stage's meshes: usd_io.geometry.mesh.read_subdivided).

Schemes (``scheme``, USD's ``subdivisionScheme``):

- ``catmullClark`` (USD's default): any polygons; one level turns a face of n corners into n quads.
- ``loop``: triangles, each split into 4. Faces with more corners are fan-triangulated first (a warning), since
  Loop's rules are defined on triangles only (OpenSubdiv refuses such meshes).
- ``bilinear``: the catmullClark split with linear rules (face centroids, edge midpoints, vertices stay).

The rules are OpenSubdiv's (``sdc/catmarkScheme.h``, ``sdc/loopScheme.h``, ``sdc/crease.cpp``,
``far/topologyRefinerFactory.cpp``), the ones USD's Hydra and Blender's Subdivision Surface modifier use:

- face point: the mean of the face's corners (catmullClark, bilinear).
- edge point: smooth catmullClark (a + b + F0 + F1)/4 (``triangle_rule="smooth"``: OpenSubdiv's weights 0.47 for
  triangles); smooth Loop 3/8 (a + b) + 1/8 (the two opposite corners); an edge of sharpness s ≥ 1 gives the
  midpoint; 0 < s < 1 blends midpoint and smooth point by s.
- vertex point by rule, from the number of sharp incident edges and the vertex sharpness: smooth (0 or 1 sharp
  edges, a "dart") catmullClark ((n − 2)/n) V + (Σ edge neighbours + Σ face points)/n², Loop (1 − nβ) V + β Σ
  neighbours with β = (5/8 − (3/8 + cos(2π/n)/4)²)/n; crease (2 sharp edges) (a + 6V + b)/8 along them; corner
  (3 or more, or a sharp vertex) V. Where a semi-sharp feature decays to smooth in this step, the parent and child
  rules are blended by OpenSubdiv's fractional weight (the mean sharpness of what decays, at most 1).
- sharpness: creases (``creases``: USD's creaseIndices/creaseLengths/creaseSharpnesses) on edges, corners
  (``corners``: cornerIndices/cornerSharpnesses) on vertices; ≥ 10 is infinitely sharp. Each level decrements it
  by one (``crease_method="uniform"``, OpenSubdiv's default and what USD/Hydra and Blender use) or by Chaikin's
  rule (``"chaikin"``: 3/4 of its own sharpness + 1/4 of the mean of the other semi-sharp edges at that end, − 1).
- boundaries (``boundary``, USD's interpolateBoundary): boundary edges are infinitely sharp (a crease along the
  boundary); ``edgeAndCorner`` (USD's default) also pins corners (a vertex on one face only); ``edgeOnly`` does
  not; ``none`` refines as edgeOnly and drops every face touching a boundary vertex (OpenSubdiv tags them as holes)
  unless the boundary edges there are creased to infinity.
- non-manifold input (edges with 3 or more faces, edges two faces walk in the same direction, repeated vertices,
  vertices where several fans of faces meet): made infinitely sharp as OpenSubdiv does, and reported in
  ``Refined.warnings``; it never raises.

Primvars ride along: ``vertex_data`` (V, k) by the points' own rules (USD "vertex"), ``varying_data`` (V, k)
linearly (USD "varying"), ``face_varying`` (values, indices) by face-varying rules (USD "faceVarying"): the values
form their own mesh, cut along seams (where a vertex carries several values), refined by the scheme's rules with
``face_varying_interpolation`` (USD's faceVaryingLinearInterpolation) deciding what stays linear: ``cornersPlus1``
(USD's default: island corners and vertices with 3 or more values), ``cornersOnly``, ``cornersPlus2`` (also darts and
two-value vertices with a corner), ``boundaries`` (linear along seams and boundaries), ``all`` (linear everywhere),
``none`` (smooth everywhere). Uniform primvars follow ``Refined.face``.

Normals: the limit surface's normal at every refined vertex, from OpenSubdiv's limit tangent masks applied to the
last level (smooth: the eigen-tangents around the vertex; crease and corner: per sector of faces between sharp
edges, so a crease gets one normal per side); per corner, so sharp edges stay sharp in shading.
``limit=True`` also moves the points (and vertex primvars) to their limit positions, as Blender's modifier does
with "Use Limit Surface"; by default the points are the refined control points (Hydra's uniform refinement).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

#: OpenSubdiv's infinite sharpness (``Sdc::Crease::SHARPNESS_INFINITE``); USD's ``UsdGeomMesh.SHARPNESS_INFINITE``.
INFINITE = 10.0

SCHEMES = ("catmullClark", "loop", "bilinear")
BOUNDARIES = ("edgeAndCorner", "edgeOnly", "none")
FACE_VARYING = ("cornersPlus1", "cornersOnly", "cornersPlus2", "boundaries", "all", "none")
TRIANGLE_RULES = ("catmullClark", "smooth")
CREASE_METHODS = ("uniform", "chaikin")

_SMOOTH, _CREASE, _CORNER = 0, 2, 3  # vertex rules (a dart is smooth)


# ---------------------------------------------------------------------------------------------------------- API
@dataclass
class Refined:
    """A refined mesh. ``faces`` (N, 4) quads (catmullClark, bilinear) or (N, 3) triangles (loop), cage faces given
    as holes left out; ``face`` (N,) the cage face each comes from; ``normals`` (N, n, 3) unit limit-surface
    normals per face corner (None when not asked); ``vertex_data`` / ``varying_data`` (V, k); ``face_varying`` one
    (N, n, k) array per face-varying input; ``warnings`` what was approximated (non-manifold input, bad creases)."""

    points: np.ndarray
    faces: np.ndarray
    face: np.ndarray
    normals: np.ndarray | None = None
    vertex_data: np.ndarray | None = None
    varying_data: np.ndarray | None = None
    face_varying: list = field(default_factory=list)
    warnings: list = field(default_factory=list)

    @property
    def indices(self) -> np.ndarray:
        return self.faces

    @property
    def counts(self) -> np.ndarray:
        return np.full(len(self.faces), self.faces.shape[1], np.int32)

    @property
    def fvar(self) -> np.ndarray | None:
        """The first face-varying channel (N, n, k), or None."""
        return self.face_varying[0] if self.face_varying else None


def refine(points, counts, indices, levels: int = 1, scheme: str = "catmullClark", *,
           boundary: str = "edgeAndCorner", face_varying_interpolation: str = "cornersPlus1",
           triangle_rule: str = "catmullClark", crease_method: str = "uniform",
           creases=None, corners=None, holes=(), vertex_data=None, varying_data=None, face_varying=(),
           normals: bool = True, limit: bool = False) -> Refined:
    """Refine a polygon mesh uniformly ``levels`` times.

    points        (V, 3) cage points
    counts        (F,) corners per face (USD faceVertexCounts), each ≥ 3
    indices       (Σ counts,) point of each face corner (USD faceVertexIndices)
    levels        refinement levels (0 returns the cage, as quads/triangles only when it already is)
    scheme, boundary, face_varying_interpolation, triangle_rule, crease_method  see the module docstring
    creases       (crease_indices, crease_lengths, crease_sharpnesses): chains of points; one sharpness per chain
                  or one per edge of all chains (USD's creaseIndices/creaseLengths/creaseSharpnesses)
    corners       (corner_indices, corner_sharpnesses) (USD's cornerIndices/cornerSharpnesses)
    holes         cage faces left out of the result (they still shape their neighbours)
    vertex_data   (V, k) refined like the points; varying_data (V, k) refined linearly
    face_varying  a sequence of channels, each ``values`` (Σ counts, k) one per face corner, or ``(values,
                  value_indices)`` with value_indices (Σ counts,) into values (USD's indexed primvars: the indices
                  define which corners share a value). Without indices, corners of one point with equal values
                  share them.
    normals       compute per-corner limit normals
    limit         move points and vertex data to the limit surface
    """
    for name, value, allowed in (("scheme", scheme, SCHEMES), ("boundary", boundary, BOUNDARIES),
                                 ("face_varying_interpolation", face_varying_interpolation, FACE_VARYING),
                                 ("triangle_rule", triangle_rule, TRIANGLE_RULES),
                                 ("crease_method", crease_method, CREASE_METHODS)):
        if value not in allowed:
            raise ValueError(f"subdivision: {name} {value!r}: choose from {', '.join(allowed)}")
    p = np.asarray(points, np.float64).reshape(-1, 3)
    counts = np.asarray(counts, np.int64).reshape(-1)
    idx = np.asarray(indices, np.int64).reshape(-1)
    if counts.sum() != len(idx) or (len(counts) and counts.min() < 3):
        raise ValueError("subdivision: faceVertexCounts must be ≥ 3 and sum to the number of faceVertexIndices")
    if len(idx) and (idx.min() < 0 or idx.max() >= len(p)):
        raise ValueError(f"subdivision: faceVertexIndices reference points outside the {len(p)} points")
    levels = max(0, int(levels))
    n_v = len(p)
    vd = None if vertex_data is None else np.asarray(vertex_data, np.float64).reshape(n_v, -1)
    varying = None if varying_data is None else np.asarray(varying_data, np.float64).reshape(n_v, -1)
    channels = [_channel_input(ch, len(idx)) for ch in face_varying]
    return _refine_stack(p[:, None], counts, idx, levels, scheme, boundary, face_varying_interpolation,
                         triangle_rule, crease_method, creases, corners, holes,
                         None if vd is None else vd[:, None], None if varying is None else varying[:, None],
                         channels, normals, limit)[0]


def _refine_stack(p, counts, idx, levels, scheme, boundary, face_varying_interpolation, triangle_rule,
                  crease_method, creases, corners, holes, vd, varying, channels, normals, limit) -> list[Refined]:
    """:func:`refine` of K meshes of one topology at once: ``p`` (V, K, 3) their points, ``vd`` / ``varying``
    (V, K, k) or None, ``channels`` [(values (M, K·w), value index per corner or None)] (K = 1: any channel;
    K > 1: indexed ones). The topology (levels, edges, sharpness, sectors) is built once; every mesh's points and
    primvars are columns of one array through the same masks (the masks are linear per column), and the limit
    normals are computed for all K meshes in one pass. Returns K :class:`Refined` (views of shared arrays)."""
    warnings: list[str] = []
    n_v, K = p.shape[0], p.shape[1]
    k_vertex = 0 if vd is None else vd.shape[2]
    data = (p if vd is None else np.concatenate([p, vd], axis=2)).reshape(n_v, -1)
    k_var = 0 if varying is None else varying.shape[2]
    varying = None if varying is None else varying.reshape(n_v, -1)

    face_of = np.arange(len(counts))
    if scheme == "loop" and len(counts) and counts.max() > 3:
        warnings.append(f"loop subdivision needs triangles: {int((counts > 3).sum())} face(s) of more corners "
                        "fan-triangulated first")
        counts, idx, corner_src, face_of = _fan_triangulate(counts, idx)
        channels = [(vals, vi[corner_src]) for vals, vi in channels]

    split = "tris" if scheme == "loop" else "quads"
    masks = "linear" if scheme == "bilinear" else scheme
    lvl = _Level.base(n_v, counts, idx)
    hole = np.zeros(len(counts), bool)
    h = np.asarray(holes, np.int64).reshape(-1)
    h = h[(h >= 0) & (h < len(face_of))] if h.size else h
    hole[np.isin(face_of, h)] = True
    if masks != "linear":
        nm_e, nm_v = lvl.non_manifold()
        if nm_e.any() or nm_v.any():
            warnings.append(f"non-manifold topology ({int(nm_e.sum())} edge(s), {int(nm_v.sum())} point(s)) made "
                            "infinitely sharp there, as OpenSubdiv does")
        explicit = lvl.tag_creases(creases, corners, warnings)
        lvl.sharpen(boundary, nm_e, nm_v)
        if boundary == "none":
            hole |= lvl.boundary_holes(explicit)
    fv_levels = []
    for values, vi in channels:
        fl, fdata = _Level.face_varying(lvl, vi, values, face_varying_interpolation, masks)
        fv_levels.append([fl, fdata])
    fv_masks = "linear" if (face_varying_interpolation == "all" or masks == "linear") else masks

    tri_smooth = triangle_rule == "smooth"
    for _ in range(levels):
        child = lvl.refined(split, crease_method)
        data = lvl.interpolate(data, child, masks, tri_smooth)
        if varying is not None:
            varying = lvl.interpolate(varying, child, "linear", False)
        for slot in fv_levels:
            fl, fdata = slot
            fchild = fl.refined(split, crease_method)
            slot[1] = fl.interpolate(fdata, fchild, fv_masks, tri_smooth)
            if face_varying_interpolation == "boundaries":
                fchild.sharpen_fvar_boundaries()
            slot[0] = fchild
        face_of = face_of[lvl.child_face_parent(split)]
        hole = hole[lvl.child_face_parent(split)]
        lvl = child

    n_corner = 4 if split == "quads" else 3
    if levels == 0:
        n_corner = int(lvl.counts.max()) if len(lvl.counts) else n_corner
        if len(lvl.counts) and lvl.counts.min() != n_corner:
            raise ValueError("subdivision: levels=0 of a mixed mesh has no fixed face size; refine at least once")
    faces = lvl.idx.reshape(-1, n_corner)
    d3 = data.reshape(len(data), K, -1)
    nrm = None
    if normals and len(faces):
        if masks == "linear" or levels == 0:
            nrm = _corner_normals_flat(d3[..., :3], faces)
        else:
            nrm = lvl.limit_normals(d3[..., :3], masks).reshape(-1, n_corner, K, 3)
    if limit and levels > 0 and masks != "linear":
        data = lvl.limit_positions(data, masks)
        d3 = data.reshape(len(data), K, -1)
    keep = ~hole
    fvars = [fdata[fl.idx].reshape(-1, n_corner, K, fdata.shape[1] // K)[keep] for fl, fdata in fv_levels]
    faces, face_of = faces[keep], face_of[keep]
    nrm = None if nrm is None else nrm[keep]
    var3 = None if varying is None else varying.reshape(len(varying), K, k_var)
    return [Refined(points=d3[:, k, :3], faces=faces, face=face_of,
                    normals=None if nrm is None else nrm[:, :, k],
                    vertex_data=d3[:, k, 3:3 + k_vertex] if k_vertex else None,
                    varying_data=None if var3 is None else var3[:, k],
                    face_varying=[fv[:, :, k] for fv in fvars], warnings=list(warnings)) for k in range(K)]


def refine_batch(meshes: list[dict]) -> list[Refined]:
    """:func:`refine` of many meshes in few calls: ``meshes`` holds one dict of :func:`refine`'s arguments per
    mesh (``points``, ``counts``, ``indices`` and any keyword); returns what :func:`refine` gives each, the same
    arrays (they may be views of arrays shared by several results).

    - Meshes of one *topology* (the same faceVertexCounts, faceVertexIndices, holes, options and face-varying
      layout; e.g. one asset dressed many times with its points deformed) are refined once: the levels, edges,
      sharpness and normal sectors are built for the first, and every mesh's points and primvars ride through
      them as columns of one array (:func:`_refine_stack`).
    - The remaining meshes with the same options are joined into one mesh of disjoint pieces, refined in one call
      and split again (no rule looks beyond a point's own faces, and points, edges and faces keep their relative
      order, so each piece comes out as it would alone; only the threshold below which a limit normal counts as
      degenerate is then relative to the median over the group rather than the mesh).
    - Creased meshes, loop meshes and groups whose refinement reports anything (non-manifold input, bad input)
      are refined mesh by mesh, so each warning or error names its own mesh."""
    out: list = [None] * len(meshes)
    groups: dict = {}
    for i, m in enumerate(meshes):
        key = _batch_key(m)
        if key is None:
            out[i] = refine(**m)
        else:
            groups.setdefault((key, _topology_key(m)), []).append(i)
    singles: dict = {}
    for (key, _topo), members in groups.items():
        shared = _shared_refine([meshes[i] for i in members]) if len(members) > 1 else None
        if shared is None:
            singles.setdefault(key, []).extend(members)
        else:
            for i, r in zip(members, shared):
                out[i] = r
    for members in singles.values():
        joined = _joined_refine([meshes[i] for i in members]) if len(members) > 1 else None
        if joined is None:
            for i in members:
                out[i] = refine(**meshes[i])
        else:
            for i, r in zip(members, joined):
                out[i] = r
    return out


def _topology_key(m: dict):
    return (len(np.asarray(m["points"]).reshape(-1, 3)), np.asarray(m["counts"], np.int64).tobytes(),
            np.asarray(m["indices"], np.int64).tobytes(), np.asarray(m.get("holes", ()), np.int64).tobytes())


def _shared_refine(meshes: list[dict]) -> list[Refined] | None:
    """Meshes of one topology (:func:`_topology_key`, :func:`_batch_key`) refined as columns of one mesh; None
    where that cannot be done (input refine would reject, face-varying values shared differently, warnings)."""
    m0 = meshes[0]
    opts = {k: m0.get(k, _REFINE_DEFAULTS[k]) for k in _BATCH_OPTIONS}
    for name, allowed in (("scheme", SCHEMES), ("boundary", BOUNDARIES),
                          ("face_varying_interpolation", FACE_VARYING), ("triangle_rule", TRIANGLE_RULES),
                          ("crease_method", CREASE_METHODS)):
        if opts[name] not in allowed:
            return None
    K = len(meshes)
    p = np.stack([np.asarray(m["points"], np.float64).reshape(-1, 3) for m in meshes], axis=1)
    counts = np.asarray(m0["counts"], np.int64).reshape(-1)
    idx = np.asarray(m0["indices"], np.int64).reshape(-1)
    n_v, n_c = len(p), len(idx)
    if counts.sum() != n_c or (len(counts) and counts.min() < 3) or (n_c and (idx.min() < 0 or idx.max() >= n_v)):
        return None

    def stacked(name):
        if m0.get(name) is None:
            return None
        return np.stack([np.asarray(m[name], np.float64).reshape(n_v, -1) for m in meshes], axis=1)

    channels = []
    for j in range(len(m0.get("face_varying", ()))):
        ins = [_channel_input(m["face_varying"][j], n_c) for m in meshes]
        if ins[0][1] is not None:  # indexed: the same indices and value count in every mesh
            vi = ins[0][1]
            if any(len(v) != len(ins[0][0]) or not np.array_equal(i, vi) for v, i in ins):
                return None
            vals = np.stack([v for v, _ in ins], axis=1)
        else:  # unindexed: which corners share a value, per mesh, in one sort; it must agree across meshes
            w = ins[0][0].shape[1]
            rows = np.concatenate([np.repeat(np.arange(K, dtype=np.float64), n_c)[:, None],
                                   np.tile(idx.astype(np.float64), K)[:, None],
                                   np.concatenate([v for v, _ in ins])], axis=1)
            _, first, inv = np.unique(rows, axis=0, return_index=True, return_inverse=True)
            inv = inv.reshape(K, n_c)
            u_start = np.searchsorted(rows[first, 0], np.arange(K + 1))
            ranks = inv - u_start[:K, None]
            if not (ranks == ranks[0]).all():
                return None
            vi = ranks[0]
            n_u = u_start[1] - u_start[0]
            if (np.diff(u_start) != n_u).any():
                return None
            flat = rows[:, 2:]
            vals = np.stack([flat[first[u_start[k]:u_start[k + 1]]] for k in range(K)], axis=1)
            vals = vals.reshape(n_u, K, w)
        channels.append((vals.reshape(len(vals), -1), vi))
    res = _refine_stack(p, counts, idx, max(0, int(opts["levels"])), opts["scheme"], opts["boundary"],
                        opts["face_varying_interpolation"], opts["triangle_rule"], opts["crease_method"],
                        None, None, m0.get("holes", ()), stacked("vertex_data"), stacked("varying_data"), channels,
                        opts["normals"], opts["limit"])
    return None if res[0].warnings else res


_BATCH_OPTIONS = ("levels", "scheme", "boundary", "face_varying_interpolation", "triangle_rule", "crease_method",
                  "normals", "limit")
_REFINE_DEFAULTS = dict(levels=1, scheme="catmullClark", boundary="edgeAndCorner",
                        face_varying_interpolation="cornersPlus1", triangle_rule="catmullClark",
                        crease_method="uniform", normals=True, limit=False)


def _batch_key(m: dict):
    """What meshes must share to be refined together (None: refine this one alone)."""
    opts = tuple(m.get(k, _REFINE_DEFAULTS[k]) for k in _BATCH_OPTIONS)
    if int(opts[0]) < 1 or m.get("scheme", "catmullClark") == "loop":  # loop may fan-triangulate first
        return None
    if m.get("creases") is not None or m.get("corners") is not None:
        return None  # creased meshes are refined one by one (their arrays are checked per mesh)
    widths = []
    for name in ("vertex_data", "varying_data"):
        v = m.get(name)
        widths.append(None if v is None else int(np.asarray(v).reshape(len(np.asarray(m["points"]).reshape(-1, 3)),
                                                                       -1).shape[1]))
    for ch in m.get("face_varying", ()):
        if isinstance(ch, tuple) and len(ch) == 2:
            widths.append(("indexed", int(np.asarray(ch[0]).reshape(len(ch[0]), -1).shape[1])))
        else:
            widths.append(("corner", int(np.asarray(ch).reshape(len(ch), -1).shape[1])))
    return opts + tuple(widths)


def _joined_refine(meshes: list[dict]) -> list[Refined] | None:
    """Refine meshes (same options) as one mesh of disjoint pieces and split the result; None if it warned."""
    pts = [np.asarray(m["points"], np.float64).reshape(-1, 3) for m in meshes]
    cnt = [np.asarray(m["counts"], np.int64).reshape(-1) for m in meshes]
    idx = [np.asarray(m["indices"], np.int64).reshape(-1) for m in meshes]
    for p, c, i in zip(pts, cnt, idx):  # each piece must be valid on its own (refine's own checks)
        if c.sum() != len(i) or (len(c) and c.min() < 3) or (len(i) and (i.min() < 0 or i.max() >= len(p))):
            return None
    n_pts = np.array([len(p) for p in pts])
    n_faces = np.array([len(c) for c in cnt])
    p_off = np.concatenate([[0], np.cumsum(n_pts)])
    f_off = np.concatenate([[0], np.cumsum(n_faces)])
    first = meshes[0]
    kw = {k: first[k] for k in _BATCH_OPTIONS if k in first}
    holes = [np.asarray(m.get("holes", ()), np.int64).reshape(-1) for m in meshes]
    holes = [h[(h >= 0) & (h < n)] + o for h, n, o in zip(holes, n_faces, f_off)]
    if first.get("vertex_data") is not None:
        kw["vertex_data"] = np.concatenate([np.asarray(m["vertex_data"], np.float64).reshape(n, -1)
                                            for m, n in zip(meshes, n_pts)])
    piece = np.repeat(np.arange(len(meshes), dtype=np.float64), n_pts)[:, None]  # which piece a point is of
    k_var = 0
    if first.get("varying_data") is not None:
        var = np.concatenate([np.asarray(m["varying_data"], np.float64).reshape(n, -1) for m, n in zip(meshes, n_pts)])
        k_var = var.shape[1]
        piece = np.concatenate([var, piece], axis=1)
    channels = []
    for j in range(len(first.get("face_varying", ()))):
        chs = [m["face_varying"][j] for m in meshes]
        if isinstance(chs[0], tuple) and len(chs[0]) == 2:
            vals = [np.asarray(c[0], np.float64).reshape(len(c[0]), -1) for c in chs]
            vis = [np.asarray(c[1], np.int64).reshape(-1) for c in chs]
            v_off = np.concatenate([[0], np.cumsum([len(v) for v in vals])])
            if any(len(vi) != len(i) or (len(vi) and (vi.min() < 0 or vi.max() >= len(v)))
                   for vi, i, v in zip(vis, idx, vals)):
                return None
            channels.append((np.concatenate(vals), np.concatenate([vi + o for vi, o in zip(vis, v_off)])))
        else:
            channels.append(np.concatenate([np.asarray(c, np.float64).reshape(len(c), -1) for c in chs]))
    r = refine(np.concatenate(pts), np.concatenate(cnt), np.concatenate([i + o for i, o in zip(idx, p_off)]),
               holes=np.concatenate(holes), varying_data=piece, face_varying=channels, **kw)
    if r.warnings:
        return None
    # split: faces are in cage-face order (so in piece order); points by the piece column, stably
    owner = np.rint(r.varying_data[:, -1]).astype(np.int64)
    order = np.argsort(owner, kind="stable")
    new_index = np.empty(len(order), np.int64)
    new_index[order] = np.arange(len(order))
    pt_start = np.searchsorted(owner[order], np.arange(len(meshes) + 1))
    face_piece = np.searchsorted(f_off, r.face, side="right") - 1
    fc_start = np.searchsorted(face_piece, np.arange(len(meshes) + 1))
    points = r.points[order]
    faces = new_index[r.faces]
    vdata = None if r.vertex_data is None else r.vertex_data[order]
    vary = None if not k_var else r.varying_data[order][:, :k_var]
    out = []
    for k in range(len(meshes)):
        a, b = pt_start[k], pt_start[k + 1]
        fa, fb = fc_start[k], fc_start[k + 1]
        out.append(Refined(points=points[a:b], faces=faces[fa:fb] - a, face=r.face[fa:fb] - f_off[k],
                           normals=None if r.normals is None else r.normals[fa:fb],
                           vertex_data=None if vdata is None else vdata[a:b],
                           varying_data=None if vary is None else vary[a:b],
                           face_varying=[fv[fa:fb] for fv in r.face_varying], warnings=[]))
    return out


def catmull_clark(points, counts, indices, levels: int = 1, fvar=None, vertex_data=None, **options) -> Refined:
    """Catmull-Clark refinement (:func:`refine` with ``scheme="catmullClark"``); ``fvar`` one face-varying channel
    given per face corner."""
    return refine(points, counts, indices, levels, "catmullClark", vertex_data=vertex_data,
                  face_varying=() if fvar is None else (fvar,), **options)


def loop(points, counts, indices, levels: int = 1, **options) -> Refined:
    """Loop refinement (:func:`refine` with ``scheme="loop"``)."""
    return refine(points, counts, indices, levels, "loop", **options)


# ------------------------------------------------------------------------------------------------- helpers
def _scatter(index, values, n):
    """Σ of ``values`` rows per ``index``: (n, k) (np.bincount per column, much faster than np.add.at)."""
    values = np.asarray(values, np.float64)
    if values.ndim == 1:
        return np.bincount(index, values, minlength=n)
    if values.ndim > 2:
        cols = int(np.prod(values.shape[1:]))
        return _scatter(index, values.reshape(len(values), cols), n).reshape((n,) + values.shape[1:])
    return np.stack([np.bincount(index, values[:, j], minlength=n) for j in range(values.shape[1])], axis=1)


def _count(index, n, weights=None):
    return np.bincount(index, weights, minlength=n)


def _channel_input(ch, n_corners):
    """(values (M, k), value index per corner (C,)) of a face-varying channel."""
    if isinstance(ch, tuple) and len(ch) == 2:
        vals = np.asarray(ch[0], np.float64)
        vi = np.asarray(ch[1], np.int64).reshape(-1)
        vals = vals.reshape(len(vals), -1)
        if len(vi) != n_corners or (len(vi) and (vi.min() < 0 or vi.max() >= len(vals))):
            raise ValueError("subdivision: face-varying indices must give one valid value per face corner")
        return vals, vi
    vals = np.asarray(ch, np.float64)
    vals = vals.reshape(len(vals), -1)
    if len(vals) != n_corners:
        raise ValueError(f"subdivision: face-varying values: {len(vals)} for {n_corners} face corners")
    return vals, None


def _fan_triangulate(counts, idx):
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    ntri = counts - 2
    face = np.repeat(np.arange(len(counts)), ntri)
    first = np.concatenate([[0], np.cumsum(ntri)[:-1]])
    k = np.arange(len(face)) - first[face]
    base = starts[face]
    corner_src = np.stack([base, base + k + 1, base + k + 2], axis=1).reshape(-1)
    return np.full(len(face), 3, np.int64), idx[corner_src], corner_src, face


def _decrement(s):
    """OpenSubdiv's uniform sharpness decay: s − 1 (≤ 1 becomes smooth), infinity stays."""
    return np.where(s >= INFINITE, INFINITE, np.where(s > 1.0, s - 1.0, 0.0))


def _cross(a, b):
    """a × b over rows (numpy 1.26's np.cross copies through moveaxis: several times slower)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def _unit(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0), n[..., 0]


def _corner_normals_flat(p, faces):
    """Per-corner normals of each face at each corner ((next − v) × (prev − v)); the face's mean where that
    vanishes. ``p`` (V, K, 3): (F, n, K, 3)."""
    nxt = np.roll(faces, -1, axis=1)
    prv = np.roll(faces, 1, axis=1)
    n = _cross(p[nxt] - p[faces], p[prv] - p[faces])
    un, ln = _unit(n)
    fmean, _ = _unit(n.sum(axis=1))
    return np.where((ln > 1e-30)[..., None], un, fmean[:, None, :])


# ---------------------------------------------------------------------------------------------------- a level
class _Level:
    """One level of the mesh: corners (face-vertex), faces, edges with sharpness, vertex sharpness.

    idx (C,) point of each corner; cf (C,) its face; nxt/prv (C,) the next/previous corner of the same face;
    ce (C,) the edge from the corner to the next one; ev (E, 2) edge end points; e_nf (E,) faces per edge;
    e_sharp (E,), v_sharp (V,) sharpness."""

    def __init__(self, n_v, counts, idx, cf, nxt, prv, ce, ev, e_sharp, v_sharp, e_nf=None, v_nf=None, v_ne=None):
        self.n_v, self.counts, self.idx, self.cf, self.nxt, self.prv = n_v, counts, idx, cf, nxt, prv
        self.ce, self.ev, self.e_sharp, self.v_sharp = ce, ev, e_sharp, v_sharp
        self.n_f, self.n_e, self.n_c = len(counts), len(ev), len(idx)
        # faces per edge, faces and edges per point (given by the parent level when it knows them)
        self.e_nf = np.bincount(ce, minlength=self.n_e) if e_nf is None else e_nf
        self.v_nf = np.bincount(idx, minlength=n_v) if v_nf is None else v_nf
        self.v_ne = np.bincount(ev.reshape(-1), minlength=n_v) if v_ne is None else v_ne

    # ------------------------------------------------------------------ construction
    @classmethod
    def base(cls, n_v, counts, idx):
        n_c = len(idx)
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]]) if len(counts) else np.zeros(0, np.int64)
        cf = np.repeat(np.arange(len(counts)), counts)
        pos = np.arange(n_c) - starts[cf]
        nxt = starts[cf] + (pos + 1) % counts[cf]
        prv = starts[cf] + (pos - 1) % counts[cf]
        a, b = idx, idx[nxt]
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        key = lo * n_v + hi
        degenerate = a == b  # OpenSubdiv makes each degenerate edge an edge of its own
        key[degenerate] = n_v * n_v + np.flatnonzero(degenerate)
        ukey, ce = np.unique(key, return_inverse=True)
        ce = ce.reshape(-1)
        ev = np.empty((len(ukey), 2), np.int64)
        ev[ce, 0], ev[ce, 1] = lo, hi
        lvl = cls(n_v, counts, idx, cf, nxt, prv, ce, ev, np.zeros(len(ukey)), np.zeros(n_v))
        lvl.degenerate_edges = np.zeros(len(ukey), bool)
        lvl.degenerate_edges[ce[degenerate]] = True
        return lvl

    def owners(self):
        """(E, 2) the corners that own each edge (−1 where fewer than two), and whether an edge has more."""
        own = np.full((self.n_e, 2), -1, np.int64)
        c = np.arange(self.n_c)
        own[self.ce, 0] = c  # one owner (the last written)
        second = own[self.ce, 0] != c
        own[self.ce[second], 1] = c[second]
        return own

    def successors(self, own=None):
        """The corner of the same point in the next face counter-clockwise around it (across the edge from the
        previous corner), or −1 at a boundary or non-manifold edge."""
        own = self.owners() if own is None else own
        e_in = self.ce[self.prv]
        a, b = own[e_in, 0], own[e_in, 1]
        other = np.where(a == self.prv, b, a)
        ok = (self.e_nf[e_in] == 2) & (other >= 0)
        ok &= self.idx[np.where(other >= 0, other, 0)] == self.idx  # consistent winding
        return np.where(ok, other, -1)

    def non_manifold(self):
        """(edges, points) OpenSubdiv tags non-manifold: edges with 3+ faces, degenerate edges, edges walked in
        the same direction by both faces or twice by one face; points on them, points repeated in a face, points
        where faces form more than one fan."""
        own = self.owners()
        nm_e = (self.e_nf > 2) | self.degenerate_edges
        two = (self.e_nf == 2) & (own[:, 1] >= 0)
        o0, o1 = own[two, 0], own[two, 1]
        same_dir = self.idx[o0] == self.idx[o1]
        same_face = self.cf[o0] == self.cf[o1]
        nm_e[np.flatnonzero(two)[same_dir | same_face]] = True
        nm_v = np.zeros(self.n_v, bool)
        nm_v[self.ev[nm_e].reshape(-1)] = True
        # a point twice in one face
        key = self.cf * self.n_v + self.idx
        srt = np.sort(key)
        dup = srt[1:][srt[1:] == srt[:-1]]
        nm_v[dup % self.n_v] = True
        # several fans: label each corner with the smallest corner of its chain (pointer doubling both ways)
        succ = self.successors(own)
        succ[nm_v[self.idx]] = -1
        fans = _chain_labels(succ, int(self.v_nf.max(initial=1)))
        heads = _count(self.idx[fans == np.arange(self.n_c)], self.n_v)
        nm_v |= heads > 1
        self.nm_edges = nm_e
        return nm_e, nm_v

    def tag_creases(self, creases, corners, warnings):
        """Edge and vertex sharpness from USD's crease and corner arrays; returns the explicitly infinitely sharp
        edges (for boundary "none")."""
        if creases is not None:
            ci, cl, cs = (np.asarray(x).reshape(-1) for x in creases)
            ci, cl, cs = ci.astype(np.int64), cl.astype(np.int64), cs.astype(np.float64)
            if cl.sum() != len(ci) or (len(cl) and cl.min() < 2):
                warnings.append("creaseLengths do not add up to creaseIndices (creases ignored)")
            elif len(cl):
                chain = np.repeat(np.arange(len(cl)), cl - 1)
                start = np.concatenate([[0], np.cumsum(cl)[:-1]])
                k = np.arange(len(chain)) - np.concatenate([[0], np.cumsum(cl - 1)[:-1]])[chain]
                a, b = ci[start[chain] + k], ci[start[chain] + k + 1]
                if len(cs) == len(cl):
                    s = cs[chain]
                elif len(cs) == len(chain):
                    s = cs
                else:
                    warnings.append(f"{len(cs)} creaseSharpnesses for {len(cl)} creases of {len(chain)} edges "
                                    "(creases ignored)")
                    s = None
                if s is not None:
                    e = self.find_edges(a, b)
                    if (e < 0).any():
                        warnings.append(f"{int((e < 0).sum())} crease segment(s) are not edges of the mesh "
                                        "(ignored)")
                    self.e_sharp[e[e >= 0]] = np.clip(s[e >= 0], 0.0, INFINITE)
        if corners is not None:
            vi, vs = (np.asarray(x).reshape(-1) for x in corners)
            vi, vs = vi.astype(np.int64), vs.astype(np.float64)
            if len(vi) != len(vs):
                warnings.append(f"{len(vs)} cornerSharpnesses for {len(vi)} cornerIndices (corners ignored)")
            else:
                ok = (vi >= 0) & (vi < self.n_v)
                if (~ok).any():
                    warnings.append(f"{int((~ok).sum())} cornerIndices outside the points (ignored)")
                self.v_sharp[vi[ok]] = np.clip(vs[ok], 0.0, INFINITE)
        return self.e_sharp >= INFINITE

    def find_edges(self, a, b):
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        ok = (lo >= 0) & (hi < self.n_v) & (lo != hi)
        key = np.where(ok, lo * self.n_v + hi, -1)
        ekey = self.ev[:, 0] * self.n_v + self.ev[:, 1]
        ekey = np.where(self.degenerate_edges, -2, ekey)
        order = np.argsort(ekey)
        pos = np.clip(np.searchsorted(ekey[order], key), 0, max(len(order) - 1, 0))
        found = ok & (len(order) > 0) & (ekey[order][pos] == key)
        return np.where(found, order[pos], -1)

    def sharpen(self, boundary, nm_e, nm_v):
        """OpenSubdiv's base-level sharpening: boundary and non-manifold edges infinitely sharp; corners (one
        face, two edges) too under edgeAndCorner; non-manifold points unless on an interior non-manifold crease."""
        bnd = self.e_nf < 2
        self.e_sharp[bnd | nm_e] = INFINITE
        if boundary == "edgeAndCorner":
            self.v_sharp[(self.v_nf == 1) & (self.v_ne == 2)] = INFINITE
        nm_edge_count = _count(self.ev[nm_e].reshape(-1), self.n_v)
        bnd_count = _count(self.ev[bnd].reshape(-1), self.n_v)
        crease = (nm_edge_count == 2) & (bnd_count == 0) & (self.v_nf > self.v_ne)
        self.v_sharp[nm_v & ~crease] = INFINITE

    def boundary_holes(self, explicit_inf):
        """Faces OpenSubdiv drops under interpolateBoundary none: those at a boundary point whose boundary edges
        were not all creased to infinity."""
        soft = (self.e_nf == 1) & ~explicit_inf
        bad_v = np.zeros(self.n_v, bool)
        bad_v[self.ev[soft].reshape(-1)] = True
        hole = np.zeros(self.n_f, bool)
        hole[self.cf[bad_v[self.idx]]] = True
        return hole

    @classmethod
    def face_varying(cls, mesh, vi, values, mode, masks):
        """The mesh of a face-varying channel: one vertex per (point, value) pair, cut along seams, with the
        mesh's sharpness and the extra corners ``mode`` makes linear. Returns (level, per-vertex values)."""
        if vi is None:  # unindexed: corners of a point with equal values share them
            per_corner = values
            _, key = np.unique(np.concatenate([mesh.idx[:, None].astype(np.float64), values], axis=1), axis=0,
                               return_inverse=True)
            key = key.reshape(-1)
        else:
            per_corner = values[vi]
            key = mesh.idx * (int(vi.max()) + 1 if len(vi) else 1) + vi
        ukey, first, fidx = np.unique(key, return_index=True, return_inverse=True)
        fidx = fidx.reshape(-1)
        n_fv = len(ukey)
        point = mesh.idx[first]
        data = per_corner[first]
        fl = cls.base(n_fv, mesh.counts, fidx)
        fl.point = point
        if masks == "linear" or mode == "all":
            return fl, data
        # the mesh's sharpness on the matching edges and points
        e_mesh = np.empty(fl.n_e, np.int64)
        e_mesh[fl.ce] = mesh.ce
        fl.e_sharp = mesh.e_sharp[e_mesh].copy()
        fl.v_sharp = mesh.v_sharp[point].copy()
        seam = fl.e_nf < 2
        fl.e_sharp[seam] = INFINITE
        _, nm_v = fl.non_manifold()
        fl.v_sharp[nm_v] = INFINITE
        # what mode makes linear
        nvals = _count(point, mesh.n_v)[point]
        f_bnd = _count(fl.ev[seam].reshape(-1), n_fv)
        m_bnd = _count(mesh.ev[mesh.e_nf < 2].reshape(-1), mesh.n_v)[point]
        mismatch = (nvals > 1) | (f_bnd != m_bnd)
        sharp = np.zeros(n_fv, bool)
        if mode == "boundaries":
            sharp |= f_bnd > 0
        if mode in ("cornersOnly", "cornersPlus1", "cornersPlus2"):
            sharp |= fl.v_nf == 1
        if mode in ("cornersPlus1", "cornersPlus2"):
            sharp |= mismatch & (nvals > 2)
            interior_inf = (fl.e_nf == 2) & (fl.e_sharp >= INFINITE)
            has_inf = _count(fl.ev[interior_inf].reshape(-1), n_fv) > 0
            two = mismatch & (nvals == 2)
            either = _count(point[two & (has_inf | nm_v)], mesh.n_v) > 0
            if mode == "cornersPlus2":
                either |= _count(point[two & (fl.v_nf == 1)], mesh.n_v) > 0
                sharp |= mismatch & (nvals == 1) & (m_bnd == 0)  # darts
            sharp |= two & either[point]
            # a value whose sibling's span is semi-sharp stays sharp as long as that one does
            semi = (fl.e_nf == 2) & (fl.e_sharp > 0) & (fl.e_sharp < INFINITE)
            semi_max = np.zeros(n_fv)
            np.maximum.at(semi_max, fl.ev[semi, 0], fl.e_sharp[semi])
            np.maximum.at(semi_max, fl.ev[semi, 1], fl.e_sharp[semi])
            at_point = np.zeros(mesh.n_v)
            np.maximum.at(at_point, point[two], semi_max[two])
            dependent = two & (semi_max == 0) & (at_point[point] > 0)
            fl.v_sharp[dependent] = np.maximum(fl.v_sharp[dependent], at_point[point[dependent]])
        fl.v_sharp[sharp] = INFINITE
        return fl, data

    def sharpen_fvar_boundaries(self):
        """faceVaryingLinearInterpolation "boundaries": every value on a seam or boundary stays linear."""
        seam = self.e_nf < 2
        self.v_sharp[_count(self.ev[seam].reshape(-1), self.n_v) > 0] = INFINITE

    # ------------------------------------------------------------------ refinement
    def child_sharpness(self, method):
        """(E, 2) sharpness of the child edge at each end of every edge, (V,) child vertex sharpness."""
        s = self.e_sharp
        half = np.repeat(_decrement(s)[:, None], 2, axis=1)
        if method == "chaikin":
            semi = (s > 0) & (s < INFINITE)
            ends = self.ev.reshape(-1)
            sv = np.repeat(np.where(semi, s, 0.0), 2)
            total = _count(ends, self.n_v, sv)
            many = _count(ends, self.n_v, np.repeat(semi, 2).astype(np.float64))
            n_at = many[self.ev]  # (E, 2)
            others = (total[self.ev] - s[:, None]) / np.maximum(n_at - 1, 1)
            chaikin = 0.75 * s[:, None] + 0.25 * others - 1.0
            use = semi[:, None] & (n_at > 1) & (self.v_ne[self.ev] >= 2)
            half = np.where(use, np.where(chaikin > 0, chaikin, 0.0), half)
        return half, _decrement(self.v_sharp)

    def refined(self, split, method):
        """The next level's topology and sharpness."""
        half, v_child = self.child_sharpness(method)
        n_v, n_e, n_f, n_c = self.n_v, self.n_e, self.n_f, self.n_c
        ce, idx, prv = self.ce, self.idx, self.prv
        corners = np.arange(n_c)
        half_out = 2 * ce + (idx == self.ev[ce, 1])  # the half of the corner's edge at its point
        ce_in = ce[prv]
        half_in = 2 * ce_in + (idx == self.ev[ce_in, 1])
        # child edges: the two halves of every edge (lo half, hi half), then one inner edge per corner
        if split == "quads":
            n_corner, n_child_v = 4, n_v + n_e + n_f
            child_idx = np.empty((n_c, 4), np.int64)
            child_idx[:, 0], child_idx[:, 1], child_idx[:, 2], child_idx[:, 3] = idx, n_v + ce, n_v + n_e + self.cf, \
                n_v + ce_in
            child_ce = np.empty((n_c, 4), np.int64)
            child_ce[:, 0], child_ce[:, 1], child_ce[:, 2], child_ce[:, 3] = half_out, 2 * n_e + corners, \
                2 * n_e + prv, half_in
            inner = (n_v + ce, n_v + n_e + self.cf)  # edge point -> face point (already ordered lo < hi)
            inner_v_nf = self.counts
            e_pt_nf, e_pt_ne = 2 * self.e_nf, 2 + self.e_nf
        else:  # triangles: 3 corner triangles and the middle one per face (faces are triangles here)
            n_corner, n_child_v = 3, n_v + n_e
            c3 = corners.reshape(-1, 3)
            child_idx = np.empty((n_f, 4, 3), np.int64)
            child_idx[:, :3, 0] = idx.reshape(-1, 3)
            child_idx[:, :3, 1] = (n_v + ce).reshape(-1, 3)
            child_idx[:, :3, 2] = (n_v + ce_in).reshape(-1, 3)
            child_idx[:, 3, :] = n_v + ce[c3]
            child_ce = np.empty((n_f, 4, 3), np.int64)
            child_ce[:, :3, 0] = half_out.reshape(-1, 3)
            child_ce[:, :3, 1] = 2 * n_e + c3
            child_ce[:, :3, 2] = half_in.reshape(-1, 3)
            child_ce[:, 3, :] = 2 * n_e + c3[:, [1, 2, 0]]
            a, b = n_v + ce, n_v + ce_in  # the inner edge cutting off each corner
            inner = (np.minimum(a, b), np.maximum(a, b))
            inner_v_nf = None
            e_pt_nf, e_pt_ne = 3 * self.e_nf, 2 + 2 * self.e_nf
        child_idx, child_ce = child_idx.reshape(-1), child_ce.reshape(-1)
        n_cc = len(child_idx)
        n_cf = n_cc // n_corner
        cf = np.arange(n_cc) // n_corner
        local = np.arange(n_cc) - cf * n_corner
        nxt = np.where(local == n_corner - 1, -(n_corner - 1), 1) + np.arange(n_cc)
        prvc = np.where(local == 0, n_corner - 1, -1) + np.arange(n_cc)
        ev = np.empty((2 * n_e + n_c, 2), np.int64)
        ev[0:2 * n_e:2, 0], ev[1:2 * n_e:2, 0] = self.ev[:, 0], self.ev[:, 1]
        ev[:2 * n_e, 1] = n_v + np.arange(2 * n_e) // 2
        ev[2 * n_e:, 0], ev[2 * n_e:, 1] = inner
        e_sharp = np.zeros(len(ev))
        e_sharp[:2 * n_e] = half.reshape(-1)
        v_sharp = np.zeros(n_child_v)
        v_sharp[:n_v] = v_child
        e_nf = np.full(len(ev), 2, np.int64)
        e_nf[:2 * n_e] = np.repeat(self.e_nf, 2)
        v_nf = np.concatenate([self.v_nf, e_pt_nf] + ([inner_v_nf] if inner_v_nf is not None else []))
        v_ne = np.concatenate([self.v_ne, e_pt_ne] + ([self.counts] if split == "quads" else []))
        child = _Level(n_child_v, np.full(n_cf, n_corner, np.int64), child_idx, cf, nxt, prvc, child_ce, ev,
                       e_sharp, v_sharp, e_nf=e_nf, v_nf=v_nf, v_ne=v_ne)
        child.degenerate_edges = np.zeros(child.n_e, bool)
        return child

    def child_face_parent(self, split):
        """The parent face of each child face."""
        if split == "quads":
            return self.cf
        return np.repeat(np.arange(self.n_f), 4)

    def rules(self, sharp_edges, v_sharp):
        n_sharp = _count(self.ev[sharp_edges].reshape(-1), self.n_v)
        return np.where((v_sharp > 0) | (n_sharp > 2), _CORNER, np.where(n_sharp == 2, _CREASE, _SMOOTH))

    def interpolate(self, p, child, masks, tri_smooth):
        """The child level's values (child.n_v, k) from this level's ``p`` (n_v, k) by ``masks``
        ("catmullClark", "loop" or "linear")."""
        p = np.asarray(p, np.float64)
        one = p.ndim == 1
        if one:
            p = p[:, None]
        lo, hi = self.ev[:, 0], self.ev[:, 1]
        p_lo, p_hi = np.take(p, lo, axis=0), np.take(p, hi, axis=0)
        mid = 0.5 * (p_lo + p_hi)
        pc = np.take(p, self.idx, axis=0)
        fp = None
        if masks != "loop":
            fp = _scatter(self.cf, pc, self.n_f) / self.counts[:, None]
        if masks == "linear":
            out = [p, mid] + ([fp] if child.n_v > self.n_v + self.n_e else [])
            res = np.concatenate(out)
            return res[:, 0] if one else res

        # edge points
        if masks == "catmullClark":
            fp_c = np.take(fp, self.cf, axis=0)
            fsum = _scatter(self.ce, fp_c, self.n_e)
            nf = np.maximum(self.e_nf, 1)[:, None]
            smooth_e = 0.25 * (p_lo + p_hi) + np.where(nf == 2, 0.25, 0.5 / nf) * fsum
            if tri_smooth and (self.counts == 3).any():
                tri = (self.counts == 3)[self.cf].astype(np.float64)
                n_tri = _count(self.ce, self.n_e, tri)
                fw = 0.5 * ((n_tri * 0.470) + (2 - n_tri) * 0.25)  # mean of the two faces' weights
                vw = 0.5 * (1.0 - 2.0 * fw)
                alt = vw[:, None] * (p_lo + p_hi) + fw[:, None] * fsum
                smooth_e = np.where(((n_tri > 0) & (self.e_nf == 2))[:, None], alt, smooth_e)
        else:  # loop: the corners opposite the edge
            opp = _scatter(self.ce, np.take(pc, self.prv, axis=0), self.n_e)
            nf = np.maximum(self.e_nf, 1)[:, None]
            smooth_e = 0.375 * (p_lo + p_hi) + np.where(nf == 2, 0.125, 0.25 / nf) * opp
        s = self.e_sharp
        half = child.e_sharp[:2 * self.n_e].reshape(-1, 2)
        child_crease = (s >= 1.0) | ((half[:, 0] > 0) & (half[:, 1] > 0))
        alpha = np.where(s <= 0, 0.0, np.where(child_crease, 1.0, np.minimum(s, 1.0)))[:, None]
        ep = alpha * mid + (1.0 - alpha) * smooth_e

        # vertex points
        n = self.v_nf.astype(np.float64)[:, None]
        other_sum = _scatter(lo, p_hi, self.n_v) + _scatter(hi, p_lo, self.n_v)
        if masks == "catmullClark":
            face_sum = _scatter(self.idx, fp_c, self.n_v)
            nn = np.maximum(n, 1.0)
            smooth_v = (nn - 2.0) / nn * p + (other_sum + face_sum) / (nn * nn)
        else:
            nn = np.maximum(n, 1.0)
            beta = (0.625 - (0.375 + 0.25 * np.cos(2 * np.pi / nn)) ** 2) / nn
            smooth_v = (1.0 - nn * beta) * p + beta * other_sum
        sharp_p = s > 0
        sharp_c = half > 0
        rp = self.rules(sharp_p, self.v_sharp)
        rc = self.rules_child(sharp_c, child.v_sharp[:self.n_v])
        crease_p = 0.75 * p + 0.125 * (_scatter(lo[sharp_p], p_hi[sharp_p], self.n_v)
                                       + _scatter(hi[sharp_p], p_lo[sharp_p], self.n_v))
        crease_c = 0.75 * p + 0.125 * (_scatter(lo[sharp_c[:, 0]], p_hi[sharp_c[:, 0]], self.n_v)
                                       + _scatter(hi[sharp_c[:, 1]], p_lo[sharp_c[:, 1]], self.n_v))
        by_rule_p = np.where((rp == _CORNER)[:, None], p, np.where((rp == _CREASE)[:, None], crease_p, smooth_v))
        by_rule_c = np.where((rc == _CORNER)[:, None], p, np.where((rc == _CREASE)[:, None], crease_c, smooth_v))
        # fractional weight where a semi-sharp feature decays in this step
        trans_e = sharp_p[:, None] & ~sharp_c  # (E, 2): parent sharp, child smooth at that end
        t_sum = _count(lo, self.n_v, np.where(trans_e[:, 0], s, 0.0)) + _count(hi, self.n_v,
                                                                              np.where(trans_e[:, 1], s, 0.0))
        t_cnt = _count(lo, self.n_v, trans_e[:, 0].astype(float)) + _count(hi, self.n_v, trans_e[:, 1].astype(float))
        v_decay = (self.v_sharp > 0) & (child.v_sharp[:self.n_v] <= 0)
        t_sum += np.where(v_decay, self.v_sharp, 0.0)
        t_cnt += v_decay
        w = np.minimum(np.where(t_cnt > 0, t_sum / np.maximum(t_cnt, 1), 0.0), 1.0)[:, None]
        vp = np.where(((rp == _SMOOTH) | (rp == rc))[:, None], by_rule_p, w * by_rule_p + (1.0 - w) * by_rule_c)
        vp = np.where((self.v_nf == 0)[:, None], p, vp)  # unused points stay

        res = np.concatenate([vp, ep] + ([fp] if masks == "catmullClark" else []))
        return res[:, 0] if one else res

    def rules_child(self, sharp_half, v_child):
        n_sharp = _count(self.ev[:, 0], self.n_v, sharp_half[:, 0].astype(float)) + \
            _count(self.ev[:, 1], self.n_v, sharp_half[:, 1].astype(float))
        return np.where((v_child > 0) | (n_sharp > 2), _CORNER, np.where(n_sharp == 2, _CREASE, _SMOOTH))

    # ------------------------------------------------------------------ the limit surface
    def limit_positions(self, p, masks):
        """Points moved to the limit surface (OpenSubdiv's limit position masks)."""
        lo, hi = self.ev[:, 0], self.ev[:, 1]
        sharp = self.e_sharp > 0
        rule = self.rules(sharp, self.v_sharp)
        n = np.maximum(self.v_nf.astype(np.float64), 1.0)[:, None]
        other_sum = _scatter(lo, p[hi], self.n_v) + _scatter(hi, p[lo], self.n_v)
        if masks == "catmullClark":
            opp = _scatter(self.idx, p[self.idx[self.nxt[self.nxt]]], self.n_v)
            fw = 1.0 / (n * (n + 5.0))
            smooth = (1.0 - n * 5.0 * fw) * p + 4.0 * fw * other_sum + fw * opp
            smooth = np.where(n == 2, p, smooth)
        else:
            beta = 0.375 + 0.25 * np.cos(2 * np.pi / n)
            gamma = (0.625 - beta * beta) / n
            ew = 1.0 / (n + 3.0 / (8.0 * gamma))
            smooth = (1.0 - n * ew) * p + ew * other_sum
        crease = (2.0 / 3.0) * p + (1.0 / 6.0) * (_scatter(lo[sharp], p[hi[sharp]], self.n_v)
                                                 + _scatter(hi[sharp], p[lo[sharp]], self.n_v))
        out = np.where((rule == _CORNER)[:, None], p, np.where((rule == _CREASE)[:, None], crease, smooth))
        return np.where((self.v_nf == 0)[:, None], p, out)

    def limit_normals(self, p, masks):
        """Unit limit-surface normals per corner (C, K, 3) of K meshes of this topology, points ``p`` (V, K, 3),
        by OpenSubdiv's limit tangent masks: around smooth points
        over the whole ring, around crease and corner points per sector of faces between sharp edges (so each
        side of a crease gets its own normal). Corners are walked around their point counter-clockwise with
        ``successors`` (corner i of a ring: its outgoing edge is the ring's edge i, its face the ring's face i)."""
        succ = self.successors()
        sharp = self.e_sharp > 0
        rule = self.rules(sharp, self.v_sharp)
        idx, nxt, prv = self.idx, self.nxt, self.prv
        cc = masks == "catmullClark"

        K = p.shape[1]

        def corner_normal(c):  # the face's own normal at corner c (fallback and orientation check)
            v = p[idx[c]]
            return _cross(p[idx[nxt[c]]] - v, p[idx[prv[c]]] - v)

        # --- smooth points: the eigen-tangents over the whole ring
        n_sharp = np.bincount(self.ev[sharp].reshape(-1), minlength=self.n_v)
        smooth_v = (rule == _SMOOTH) & (n_sharp == 0) & (self.v_nf == self.v_ne) & (self.v_nf >= 3)
        smooth_v[idx[succ < 0]] = False  # the ring must close
        start = np.full(self.n_v, -1, np.int64)
        start[idx] = np.arange(self.n_c)
        vnormal, ln = np.zeros((self.n_v, K, 3)), np.zeros((self.n_v, K))
        e_of = idx[nxt]  # per corner: the far point of its outgoing edge, and (quads) its far corner
        f_of = idx[nxt[nxt]] if cc else None
        for n in np.unique(self.v_nf[smooth_v]):  # walk every ring of n faces at once, from any corner
            verts = np.flatnonzero(smooth_v & (self.v_nf == n))
            c = start[verts]
            theta = 2.0 * np.pi / n
            j = np.arange(n)
            if cc:
                lam = 5.0 / 16.0 + (np.cos(theta) + np.cos(theta / 2) * np.sqrt(2.0 * (9.0 + np.cos(theta)))) / 16.0
                we1, wf1 = 4.0 * np.cos(j * theta), (np.cos(j * theta) + np.cos((j + 1) * theta)) / (4.0 * lam - 1.0)
                we2, wf2 = np.roll(we1, 1), np.roll(wf1, 1)  # tan2 is tan1 turned by one edge
            else:
                we1, we2 = np.cos(j * theta), np.sin(j * theta)
            t1 = np.zeros((len(verts), K, 3))
            t2 = np.zeros((len(verts), K, 3))
            for k in range(n):
                e = np.take(p, np.take(e_of, c), axis=0)
                t1 += we1[k] * e
                t2 += we2[k] * e
                if cc:
                    fpt = np.take(p, np.take(f_of, c), axis=0)
                    t1 += wf1[k] * fpt
                    t2 += wf2[k] * fpt
                c = np.take(succ, c)
            vnormal[verts], ln[verts] = _unit(_cross(t1, t2))
        out = vnormal[idx]
        weak = smooth_v[:, None] & ~(ln > 1e-9 * np.median(ln[smooth_v], axis=0)) if smooth_v.any() else \
            np.zeros((self.n_v, K), bool)
        if weak.any():  # a degenerate ring: the mean of its faces' normals (per mesh: the median is per mesh)
            wc, wk = np.nonzero(weak[idx])
            v = p[idx[wc], wk]
            wn = _cross(p[idx[nxt[wc]], wk] - v, p[idx[prv[wc]], wk] - v)
            key = idx[wc] * K + wk
            rough = _scatter(key, wn, self.n_v * K)
            out[wc, wk] = _unit(rough[key])[0]

        # --- darts, crease and corner points: per sector of faces between sharp edges (a dart's one sector is its
        # whole ring, from its sharp edge round to it), by the exact eigen-tangents of the sector's subdivision
        rest = ~smooth_v[idx]
        succ_s = np.where(sharp[self.ce[prv]], -1, succ)
        has_pred = np.zeros(self.n_c, bool)
        has_pred[succ_s[succ_s >= 0]] = True
        starts = np.flatnonzero(rest & ~has_pred)
        sector, position = _walk(succ_s, starts, self.n_c)
        in_sec = np.flatnonzero(sector >= 0)
        s_of, pos = sector[in_sec], position[in_sec]
        n_s = len(starts)
        size = np.bincount(s_of, minlength=n_s)  # faces in the sector
        last = np.zeros(n_s, np.int64)
        is_last = pos == size[s_of] - 1
        last[s_of[is_last]] = in_sec[is_last]
        srule = rule[idx[starts]]
        kind = np.where(srule == _CREASE, 1, np.where(srule == _CORNER, 2, 0))  # 0: a dart
        v = p[idx[starts]]
        lead = p[idx[nxt[starts]]]  # the sector's first edge
        trail = p[idx[prv[last]]]  # its last edge (a dart's: its first again)
        nrm = _cross(lead - v, trail - v)  # a pinned corner: the two creases' tangents
        geometric = (kind != 0) & ((size == 1) | ((kind == 2) & (size == 2)))
        key = kind * (size.max(initial=0) + 1) + size
        for g in np.unique(key[~geometric]):
            members = np.flatnonzero(key == g)
            gk, gn = int(kind[members[0]]), int(size[members[0]])
            wv1, we1, wf1, wv2, we2, wf2 = _sector_tangent_masks(masks, gk, gn)
            local = np.full(n_s, -1, np.int64)
            local[members] = np.arange(len(members))
            sel = local[s_of] >= 0
            cs, li, ps = in_sec[sel], local[s_of[sel]], pos[sel]
            ring_e = np.zeros((len(members), len(we1), K, 3))
            ring_e[li, ps] = p[idx[nxt[cs]]]
            if gk != 0:
                ring_e[:, gn] = trail[members]
            t1 = wv1 * v[members] + np.einsum("i,sikj->skj", we1, ring_e)
            t2 = wv2 * v[members] + np.einsum("i,sikj->skj", we2, ring_e)
            if cc:
                ring_f = np.zeros((len(members), gn, K, 3))
                ring_f[li, ps] = p[idx[nxt[nxt[cs]]]]
                t1 += np.einsum("i,sikj->skj", wf1, ring_f)
                t2 += np.einsum("i,sikj->skj", wf2, ring_f)
            nrm[members] = _cross(t1, t2)
        rough = _scatter(s_of, corner_normal(in_sec), n_s)
        out[in_sec] = _checked(nrm, rough)[s_of]

        # anything left (non-manifold points, a sharp point without sharp edges): the mean of its faces' normals
        left = np.flatnonzero(rest & (sector < 0))
        if len(left):
            rough = _scatter(idx[left], corner_normal(left), self.n_v)
            out[left] = _unit(rough[idx[left]])[0]
        return out


@lru_cache(maxsize=None)
def _sector_tangent_masks(masks, kind, n):
    """Limit tangent masks of a sector of ``n`` faces around a point: (vertex weight, edge weights, face weights)
    twice. ``kind`` 0: a dart (the whole ring, edge 0 sharp), 1: a crease sector (edges 0 and n sharp, the point
    on the crease rule), 2: a corner sector (the point pinned). They are the left eigenvectors of the sector's
    own subdivision matrix for its leading eigenvalues below 1 (the characteristic map's tangents): exact for the
    rules above, where OpenSubdiv's Limit() uses the smooth masks at darts and Biermann et al.'s crease masks
    (exact only for sectors of up to 2 faces). Crease and corner sectors keep the crease's own tangent
    (edge 0 − edge n) and add the leading eigenvector not along it."""
    cc = masks == "catmullClark"
    ne = n if kind == 0 else n + 1
    nf = n if cc else 0
    m = 1 + ne + nf
    E = lambda i: 1 + i % ne  # noqa: E731
    F = lambda i: 1 + ne + i  # noqa: E731
    one = np.eye(m)

    def face_point(i):  # quad i of the sector: the point, edge i, its opposite corner, edge i + 1
        return (one[0] + one[E(i)] + one[F(i)] + one[E(i + 1)]) / 4

    S = np.zeros((m, m))
    if kind == 0:
        if cc:
            S[0] = (n - 2) / n * one[0] + sum(one[E(i)] + face_point(i) for i in range(n)) / n ** 2
        else:
            beta = (0.625 - (0.375 + 0.25 * np.cos(2 * np.pi / n)) ** 2) / n
            S[0] = (1 - n * beta) * one[0] + beta * sum(one[E(i)] for i in range(n))
    else:
        S[0] = one[0] if kind == 2 else 0.75 * one[0] + 0.125 * (one[E(0)] + one[E(n)])
    for i in range(ne):
        if i == 0 or (kind != 0 and i == n):  # the sharp edges: midpoints
            S[E(i)] = (one[0] + one[E(i)]) / 2
        elif cc:
            S[E(i)] = (one[0] + one[E(i)]) / 4 + (face_point(i - 1) + face_point(i)) / 4
        else:
            S[E(i)] = 0.375 * (one[0] + one[E(i)]) + 0.125 * (one[E(i - 1)] + one[E(i + 1)])
    for i in range(nf):
        S[F(i)] = face_point(i)
    lam, W = np.linalg.eig(S.T)
    order = np.argsort(-np.abs(lam), kind="stable")
    lam, W = lam[order], W[:, order]
    if kind == 0:
        if abs(lam[1].imag) > 1e-12:  # a complex pair: its real and imaginary parts span the plane
            t1, t2 = W[:, 1].real, W[:, 1].imag
        else:
            t1, t2 = W[:, 1].real, W[:, 2].real
    else:
        t1 = one[E(0)] - one[E(n)]
        for j in range(1, m):
            w = W[:, j].real
            t2 = w - (w @ t1) / (t1 @ t1) * t1
            if np.linalg.norm(t2) > 1e-8 * np.linalg.norm(w):
                break
    split = lambda t: (t[0], t[1:1 + ne].copy(), t[1 + ne:].copy())  # noqa: E731
    return (*split(t1), *split(t2))


def _walk(succ, starts, n):
    """Follow successor links from each start until a chain ends or comes back: (chain id, position) per corner,
    −1 where no chain reaches."""
    chain = np.full(n, -1, np.int64)
    position = np.full(n, -1, np.int64)
    c = np.asarray(starts, np.int64)
    cid = np.arange(len(c))
    k = 0
    while len(c):
        chain[c] = cid
        position[c] = k
        nx = succ[c]
        alive = nx >= 0
        alive[alive] = chain[nx[alive]] < 0
        c, cid = nx[alive], cid[alive]
        k += 1
    return chain, position


def _checked(nrm, rough):
    """Unit normals (S, K, 3), flipped to agree with the rough (area-weighted) normal, the rough one where
    degenerate (against the median length over each mesh's sectors)."""
    un, ln = _unit(nrm)
    ur, _ = _unit(rough)
    bad = ~(ln > 1e-9 * np.median(ln, axis=0)) if len(ln) else ln > 0
    flip = (un * ur).sum(axis=-1) < 0
    un = np.where(flip[..., None], -un, un)
    return np.where(bad[..., None], ur, un)


def _chain_labels(succ, longest):
    """The smallest corner of each chain (path or cycle) the successor links form, by pointer doubling in both
    directions: after r rounds each label covers 2^r − 1 links either way, so log₂ of the longest chain rounds."""
    n = len(succ)
    c = np.arange(n)
    s = np.where(succ >= 0, succ, c)
    pred = c.copy()
    has = succ >= 0
    pred[succ[has]] = c[has]
    label = c.copy()
    reach = 1
    while reach < longest:
        label = np.minimum(label, np.minimum(label[s], label[pred]))
        s, pred = s[s], pred[pred]
        reach = 2 * reach + 1
    return label

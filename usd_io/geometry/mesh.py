"""``UsdGeom.Mesh`` -> triangles with per-corner normals and texture coordinates.

Polygons of any size are fan-triangulated (exact for convex faces). Every primvar interpolation is expanded to
per-corner values through the triangulation's corner table:

    constant     one value for every corner
    uniform      one per face          -> indexed by each triangle's face
    vertex       one per point         -> indexed by the corner's point index
    varying      one per point (meshes: the same as vertex)
    faceVarying  one per face-vertex   -> indexed by the corner's face-vertex position

Indexed primvars are flattened first (``Primvar.ComputeFlattened``; :func:`flattened`: with elementSize 1 where the
authored elementSize does not fit the indices, as Arnold reads MtoA's primvars). ``orientation = leftHanded`` reverses the
winding so the tracer's counter-clockwise front faces match USD's; so does a mirroring (negative determinant)
transform. Subdivision surfaces (``subdivisionScheme`` catmullClark, the USD default, loop or bilinear) are
refined by ``tracer.geometry.subdivision`` to the ``--complexity`` level (:data:`COMPLEXITY`); at level 0 (low) they render
as their control cage with its authored normals, or smooth (area-weighted) ones, as usdview does.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pxr import UsdGeom

from tracer.builder import vertex_values
from tracer.geometry.subdivision import refine, refine_batch
from tracer.heap import trim

#: Interpolations that are one value per point for a mesh.
_PER_POINT = (UsdGeom.Tokens.vertex, UsdGeom.Tokens.varying)


@dataclass
class Triangulation:
    triangles: np.ndarray  # (T, 3) point indices
    corners: np.ndarray  # (T, 3) face-vertex positions (indices into faceVertexIndices)
    faces: np.ndarray  # (T,) face index of each triangle
    n_faces: int
    warnings: list = field(default_factory=list)


def triangulate(counts, indices, n_points: int, holes=(), left_handed=False, label="mesh") -> Triangulation:
    """Fan-triangulate faces given by ``faceVertexCounts`` and ``faceVertexIndices`` (vectorised)."""
    counts = np.asarray(counts, dtype=np.int64).reshape(-1)
    indices = np.asarray(indices, dtype=np.int64).reshape(-1)
    warns = []
    if counts.sum() != len(indices):
        raise ValueError(f"{label}: faceVertexCounts sum to {int(counts.sum())} but there are "
                         f"{len(indices)} faceVertexIndices")
    if len(indices) and (indices.min() < 0 or indices.max() >= n_points):
        raise ValueError(f"{label}: faceVertexIndices reference points outside the {n_points} points")
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]) if len(counts) else np.zeros(0, np.int64)
    keep = counts >= 3
    if (~keep).any():
        warns.append(f"{label}: skipped {int((~keep).sum())} face(s) with fewer than 3 vertices")
    holes = np.asarray(holes, dtype=np.int64).reshape(-1)
    if holes.size:
        holes = holes[(holes >= 0) & (holes < len(counts))]
        keep[holes] = False
        warns.append(f"{label}: {len(holes)} hole face(s) ignored (not cut; holes render as missing faces)")
    ntri = np.where(keep, counts - 2, 0)
    faces = np.repeat(np.arange(len(counts)), ntri)
    # k-th triangle of a face: corners (0, k+1, k+2) of that face.
    first = np.concatenate([[0], np.cumsum(ntri)[:-1]]) if len(ntri) else np.zeros(0, np.int64)
    k = np.arange(len(faces)) - np.repeat(first, ntri)
    base = starts[faces]
    corners = np.stack([base, base + k + 1, base + k + 2], axis=1)
    if left_handed:
        corners = corners[:, [0, 2, 1]]
    return Triangulation(indices[corners], corners, faces, len(counts), warns)


def expand_primvar(values, interpolation, tri: Triangulation, n_points: int, n_face_vertices: int, label: str):
    """Per-corner (T, 3, C) values of a flattened primvar, or None (with a reason) when its size does not fit."""
    v = np.asarray(values, dtype=np.float64)
    if v.ndim == 1:
        v = v[:, None]
    n = len(v)
    if interpolation == UsdGeom.Tokens.constant:
        if n < 1:
            return None, f"{label}: constant primvar has no value"
        return np.broadcast_to(v[0], tri.corners.shape + v.shape[1:]).copy(), None
    if interpolation == UsdGeom.Tokens.uniform:
        if n != tri.n_faces:
            return None, f"{label}: uniform primvar has {n} values for {tri.n_faces} faces"
        return np.repeat(v[tri.faces][:, None, :], 3, axis=1), None
    if interpolation in _PER_POINT:
        if n != n_points:
            return None, f"{label}: {interpolation} primvar has {n} values for {n_points} points"
        return v[tri.triangles], None
    if interpolation == UsdGeom.Tokens.faceVarying:
        if n != n_face_vertices:
            return None, f"{label}: faceVarying primvar has {n} values for {n_face_vertices} face-vertices"
        return v[tri.corners], None
    return None, f"{label}: unknown interpolation {interpolation!r}"


def smooth_normals(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals (V, 3)."""
    p = points[triangles]
    fn = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    corners = triangles.reshape(-1)
    w = np.repeat(fn, 3, axis=0)  # each corner adds its face's (area-weighted) normal to its point
    vn = np.stack([np.bincount(corners, w[:, k], minlength=len(points)) for k in range(3)], axis=1)
    return vn / np.maximum(np.linalg.norm(vn, axis=1, keepdims=True), 1e-30)


@dataclass
class MeshData:
    """A mesh in object space, ready for ``SceneBuilder.add_mesh``."""

    points: np.ndarray
    triangles: np.ndarray
    faces: np.ndarray  # (T,) source face of each triangle (for GeomSubsets and uniform displayColor)
    n_faces: int
    normals: np.ndarray | None = None  # (T, 3, 3) or (V, 3)
    uvs: np.ndarray | None = None  # (T, 3, 2)
    warnings: list = field(default_factory=list)
    corners: np.ndarray | None = None  # (T, 3) face-vertex positions, to expand further primvars (materials)
    n_face_vertices: int = 0
    primvars: dict | None = None  # refined subdivision surfaces: {name: (T, 3, k) per corner} (no corners then)
    source_points: np.ndarray | None = None  # points and curves: (V,) the authored point each vertex stands for
    point_weights: np.ndarray | None = None  # NURBS patches: (V, P) each vertex as a combination of the CVs


def flattened(pv, time):
    """``pv``'s values with its indices applied (``UsdGeom.Primvar.ComputeFlattened``), or None.

    An indexed primvar whose ``elementSize`` does not fit its indices (MtoA writes faceVarying normals and UVs with
    elementSize = a face's corner count and one index per corner: USD's ComputeFlattened refuses it, with a warning
    naming the primvar) is flattened with elementSize 1, one value per index, as Arnold reads it (arnold-usd's
    reader ignores elementSize). A value authored as a scalar rather than an array (Storm reads it as the one
    element of a constant primvar) is a one-element list."""
    vals = pv.ComputeFlattened(time)
    if vals is not None and not pv.GetTypeName().isArray:
        return [vals]  # one value authored as a scalar (``color3f primvars:displayColor = (1, 0, 0)``): one element
    if (vals is None or len(vals) == 0) and pv.IsIndexed() and pv.GetElementSize() > 1:
        raw, idx = pv.Get(time), pv.GetIndices(time)
        if raw is not None and idx is not None and len(raw) and len(idx):
            i = np.asarray(idx, np.int64)
            if i.min() >= 0 and i.max() < len(raw):
                return np.asarray(raw)[i]
    return vals


def _primvar(prim, name):
    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar(name)
    return pv if pv and pv.HasValue() else None


def read_uvs(prim, tri: Triangulation, n_points, n_fv, time, name="st"):
    pv = _primvar(prim, name)
    if pv is None:
        return None, None
    vals = flattened(pv, time)
    if vals is None or len(vals) == 0:
        return None, None
    uv, why = expand_primvar(np.asarray(vals, dtype=np.float64).reshape(len(vals), -1)[:, :2],
                             pv.GetInterpolation(), tri, n_points, n_fv, f"{prim.GetPath()} primvars:{name}")
    return uv, why


from .complexity import COMPLEXITY, DEFAULT_COMPLEXITY  # noqa: E402  (re-exported: usd_io.geometry.mesh.COMPLEXITY)

#: Schemes refined at complexity medium and above (the rest, "none" and unknown tokens, stay polygons).
SUBDIVIDED = (UsdGeom.Tokens.catmullClark, UsdGeom.Tokens.loop, UsdGeom.Tokens.bilinear)


def read_mesh(prim, time, uv_name="st", subdivision_level: int = COMPLEXITY[DEFAULT_COMPLEXITY],
              points=None) -> MeshData | None:
    """The mesh at ``time``; ``points`` replaces the authored points (a skinned cage posed before refinement)."""
    cage = _read_cage(prim, time, points)
    if cage is None:
        return None
    mesh, label, points, counts, indices, left, holes, scheme = cage
    if scheme in SUBDIVIDED and subdivision_level > 0:
        job = _subdivision_job(prim, mesh, points, counts, indices, holes, left, scheme, subdivision_level, time,
                               uv_name, label)
        return None if job is None else job[1](refine(**job[0]))
    return _polygons(prim, mesh, label, points, counts, indices, left, holes, time, uv_name)


def read_subdivided(prims, time, uv_name="st", subdivision_level: int = COMPLEXITY[DEFAULT_COMPLEXITY]) -> dict:
    """:func:`read_mesh` of many subdivision surfaces with one :func:`tracer.geometry.subdivision.refine_batch` (meshes of
    one topology refined once): {prim path: MeshData, None, or the ValueError read_mesh would raise}. Prims that
    are not subdivided at this level are left out (read them with read_mesh)."""
    out, jobs = {}, []
    if subdivision_level <= 0:
        return out
    for prim in prims:
        key = str(prim.GetPath())
        try:
            cage = _read_cage(prim, time, None)
            if cage is None:
                out[key] = None
                continue
            mesh, label, points, counts, indices, left, holes, scheme = cage
            if scheme not in SUBDIVIDED:
                continue
            job = _subdivision_job(prim, mesh, points, counts, indices, holes, left, scheme, subdivision_level,
                                   time, uv_name, label)
        except ValueError as exc:
            out[key] = exc
            continue
        if job is None:
            out[key] = None
        else:
            jobs.append((key, job))
    try:
        refined = refine_batch([request for _, (request, _finish) in jobs])
    except ValueError:  # one bad mesh: each on its own, so the error belongs to that mesh
        refined = []
        for _, (request, _finish) in jobs:
            try:
                refined.append(refine(**request))
            except ValueError as exc:
                refined.append(exc)
    for i, ((key, (_request, finish)), r) in enumerate(zip(jobs, refined)):
        out[key] = r if isinstance(r, ValueError) else finish(r)
        refined[i] = None  # the refinement's shared arrays go once the last mesh of a topology is done
    del refined, jobs
    trim()  # the refinement's temporaries, back to the OS
    return out


def _read_cage(prim, time, points):
    """(mesh, label, points, counts, indices, left-handed, holes, scheme) of a mesh prim, None when empty."""
    mesh = UsdGeom.Mesh(prim)
    label = str(prim.GetPath())
    points = mesh.GetPointsAttr().Get(time) if points is None else points
    counts = mesh.GetFaceVertexCountsAttr().Get(time)
    indices = mesh.GetFaceVertexIndicesAttr().Get(time)
    if points is None or counts is None or indices is None:
        return None
    for what, v in (("points", points), ("faceVertexCounts", counts), ("faceVertexIndices", indices)):
        if not hasattr(v, "__len__"):  # authored with a scalar type (usd-wg schemaTests points_types)
            raise ValueError(f"{label}: {what} is a {type(v).__name__}, not an array")
    if len(points) == 0 or len(counts) == 0:
        return None
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"{label}: points are not 3-vectors (shape {points.shape})")
    if not np.all(np.isfinite(points)):  # before refinement, which would spread the NaN (and warn about it)
        raise ValueError(f"{label}: points with NaN or infinite coordinates")
    left = mesh.GetOrientationAttr().Get(time) == UsdGeom.Tokens.leftHanded
    holes = mesh.GetHoleIndicesAttr().Get(time) or ()
    scheme = mesh.GetSubdivisionSchemeAttr().Get(time) or UsdGeom.Tokens.catmullClark
    return mesh, label, points, counts, indices, left, holes, scheme


def _polygons(prim, mesh, label, points, counts, indices, left, holes, time, uv_name) -> MeshData:
    """A polygon mesh (not refined): fan-triangulated, its authored or smooth normals, its UVs."""
    tri = triangulate(counts, indices, len(points), holes, left, label)
    n_fv = len(indices)
    data = MeshData(points, tri.triangles, tri.faces, tri.n_faces, warnings=list(tri.warnings),
                    corners=tri.corners, n_face_vertices=n_fv)

    # Normals: primvars:normals wins over the normals attribute (UsdGeom rule).
    pv = _primvar(prim, "normals")
    if pv is not None:
        vals, interp = flattened(pv, time), pv.GetInterpolation()
    else:
        attr = mesh.GetNormalsAttr()
        vals = attr.Get(time) if attr.HasValue() else None
        interp = mesh.GetNormalsInterpolation()
    if vals is not None and not hasattr(vals, "__len__"):
        data.warnings.append(f"{label}: normals authored as a {type(vals).__name__}, not an array (ignored)")
        vals = None
    elif vals is not None and len(vals) and np.asarray(vals).reshape(len(vals), -1).shape[1] != 3:
        data.warnings.append(f"{label}: normals are not 3-vectors (ignored)")
        vals = None
    if vals is not None and len(vals):
        n, why = expand_primvar(np.asarray(vals, dtype=np.float64).reshape(-1, 3), interp, tri, len(points), n_fv,
                                f"{label} normals")
        if why:
            data.warnings.append(why + " (ignored)")
        data.normals = n
    elif mesh.GetSubdivisionSchemeAttr().Get(time) != UsdGeom.Tokens.none:
        data.normals = smooth_normals(points, tri.triangles)

    uv, why = read_uvs(prim, tri, len(points), n_fv, time, uv_name)
    if why:
        data.warnings.append(why + " (ignored)")
    data.uvs = uv
    return data


def _subdivision_primvar(prim, name, n_points, n_faces, n_fv, time, label, warnings):
    """(interpolation, values (N, k), indices or None) of a primvar for refinement, or None when absent (a warning
    when its size does not fit its interpolation)."""
    pv = _primvar(prim, name)
    if pv is None:
        return None
    vals = pv.Get(time)
    if vals is None or not hasattr(vals, "__len__") or len(vals) == 0:
        return None
    v = np.asarray(vals, np.float64)
    v = v.reshape(len(v), -1)
    ind = pv.GetIndices(time) if pv.IsIndexed() else None
    ind = None if ind is None or len(ind) == 0 else np.asarray(ind, np.int64)
    interp = pv.GetInterpolation()
    n = len(v) if ind is None else len(ind)
    if ind is not None and (ind.min() < 0 or ind.max() >= len(v)):
        warnings.append(f"{label} primvars:{name}: indices outside its {len(v)} values (ignored)")
        return None
    want = {UsdGeom.Tokens.faceVarying: n_fv, UsdGeom.Tokens.vertex: n_points, UsdGeom.Tokens.varying: n_points,
            UsdGeom.Tokens.uniform: n_faces, UsdGeom.Tokens.constant: n}.get(interp)
    if want is None or n != want:
        warnings.append(f"{label} primvars:{name}: {interp} primvar has {n} values for {want} (ignored)")
        return None
    return interp, v, ind


def _subdivision_job(prim, mesh, points, counts, indices, holes, left, scheme, level, time, uv_name, label):
    """(refine's arguments, finish(refined) -> MeshData) of a subdivision surface, or None when it has no faces.
    A subdivision surface refined ``level`` times by :func:`tracer.geometry.subdivision.refine` with the mesh's own
    subdivision attributes (interpolateBoundary, faceVaryingLinearInterpolation, triangleSubdivisionRule, creases,
    corners, holes); the UV primvar carried through by its interpolation (faceVarying by face-varying rules with
    its indices, vertex like the points, varying linearly); per-corner limit-surface normals. Authored normals are
    ignored, as the USD spec says of subdivision surfaces (one warning per stage)."""

    warnings = []
    counts = np.asarray(counts, np.int64).reshape(-1)
    indices = np.asarray(indices, np.int64).reshape(-1)
    if counts.sum() != len(indices) or (len(indices) and (indices.min() < 0 or indices.max() >= len(points))):
        triangulate(counts, indices, len(points), holes, left, label)  # raises the cage's own error
    n_faces_in, n_fv_in = len(counts), len(indices)
    keep = counts >= 3
    face_ids = np.flatnonzero(keep)
    fv_keep = np.repeat(keep, counts)
    if (~keep).any():
        warnings.append(f"{label}: skipped {int((~keep).sum())} face(s) with fewer than 3 vertices")
        indices, counts = indices[fv_keep], counts[keep]
    if not len(counts):  # malformed, not empty: the reader warns and counts it (usd_io.reader._say_if_empty)
        raise ValueError(f"{label}: all {n_faces_in} face(s) have fewer than 3 vertices")

    def attr(get, default=None):
        a = get()
        v = a.Get(time) if a and a.HasAuthoredValue() else None
        return default if v is None else v

    boundary = attr(mesh.GetInterpolateBoundaryAttr, UsdGeom.Tokens.edgeAndCorner)
    fvli = attr(mesh.GetFaceVaryingLinearInterpolationAttr, UsdGeom.Tokens.cornersPlus1)
    tri_rule = attr(mesh.GetTriangleSubdivisionRuleAttr, UsdGeom.Tokens.catmullClark)
    options = {}
    for name, value, allowed in (("boundary", boundary, ("edgeAndCorner", "edgeOnly", "none")),
                                 ("face_varying_interpolation", fvli,
                                  ("cornersPlus1", "cornersOnly", "cornersPlus2", "boundaries", "all", "none")),
                                 ("triangle_rule", tri_rule, ("catmullClark", "smooth"))):
        if value in allowed:
            options[name] = str(value)
        else:
            warnings.append(f"{label}: unknown {name.replace('_', ' ')} {value!r} (USD's default used)")
    creases = None
    c_idx = attr(mesh.GetCreaseIndicesAttr)
    if c_idx is not None and len(c_idx):
        creases = (np.asarray(c_idx), np.asarray(attr(mesh.GetCreaseLengthsAttr, [])),
                   np.asarray(attr(mesh.GetCreaseSharpnessesAttr, [])))
    corners = None
    k_idx = attr(mesh.GetCornerIndicesAttr)
    if k_idx is not None and len(k_idx):
        corners = (np.asarray(k_idx), np.asarray(attr(mesh.GetCornerSharpnessesAttr, [])))
    hole_set = np.asarray(holes, np.int64).reshape(-1)
    remap = np.full(n_faces_in, -1, np.int64)
    remap[face_ids] = np.arange(len(face_ids))
    hole_set = remap[hole_set[(hole_set >= 0) & (hole_set < n_faces_in)]]
    hole_set = hole_set[hole_set >= 0]

    # every texture-coordinate and colour primvar rides along, each by its own interpolation
    names = _refined_primvar_names(prim, uv_name)
    fvar_names, vertex_cols, varying_cols, per_face, constant = [], [], [], {}, {}
    face_varying, vertex_parts, varying_parts = [], [], []
    for name in names:
        got = _subdivision_primvar(prim, name, len(points), n_faces_in, n_fv_in, time, label, warnings)
        if got is None:
            continue
        interp, vals, ind = got
        flat = vals if ind is None else vals[ind]
        if interp == UsdGeom.Tokens.faceVarying:
            fvar_names.append(name)
            face_varying.append((vals, ind[fv_keep]) if ind is not None else vals[fv_keep])
        elif interp in (UsdGeom.Tokens.vertex, UsdGeom.Tokens.varying):
            parts, cols = (vertex_parts, vertex_cols) if interp == UsdGeom.Tokens.vertex else (varying_parts,
                                                                                                varying_cols)
            start = sum(p.shape[1] for p in parts)
            cols.append((name, slice(start, start + flat.shape[1])))
            parts.append(flat)
        elif interp == UsdGeom.Tokens.uniform:
            per_face[name] = flat[face_ids]
        else:
            constant[name] = flat[0]

    request = dict(points=points, counts=counts, indices=indices, levels=level, scheme=str(scheme), creases=creases,
                   corners=corners, holes=hole_set, face_varying=face_varying,
                   vertex_data=np.concatenate(vertex_parts, axis=1) if vertex_parts else None,
                   varying_data=np.concatenate(varying_parts, axis=1) if varying_parts else None, **options)
    authored_normals = _has_authored_normals(prim, mesh)
    return request, lambda r: _refined_mesh(r, warnings, label, left, fvar_names, vertex_cols, varying_cols,
                                            per_face, constant, uv_name, authored_normals, face_ids, n_faces_in)


def _refined_mesh(r, warnings, label, left, fvar_names, vertex_cols, varying_cols, per_face, constant, uv_name,
                  authored_normals, face_ids, n_faces_in) -> MeshData:
    """The MeshData of a refined subdivision surface: quads split along their shorter diagonal, per-corner limit
    normals and primvars."""
    warnings += [f"{label}: {w}" for w in r.warnings]
    q = r.faces
    n = q.shape[1]
    if n == 4:  # each quad along its shorter diagonal
        p = r.points
        d02 = np.square(p[q[:, 2]] - p[q[:, 0]]).sum(axis=1)
        d13 = np.square(p[q[:, 3]] - p[q[:, 1]]).sum(axis=1)
        local = np.where((d13 < d02)[:, None, None], [[0, 1, 3], [1, 2, 3]], [[0, 1, 2], [0, 2, 3]])
        corner = (np.arange(len(q))[:, None, None] * 4 + local).reshape(-1, 3)  # into the quads' flat corners
    else:
        corner = np.arange(q.size).reshape(-1, 3)
    if left:
        corner = corner[:, [0, 2, 1]]
    triangles = q.reshape(-1)[corner]
    # per vertex where the limit normals agree at every corner of a vertex (no crease): 6 bytes a triangle, not 36
    normals = vertex_values(r.normals, q, len(r.points)) if r.normals is not None and len(q) else None
    normals = r.normals.reshape(-1, 3)[corner] if normals is None else normals
    if left:
        normals = -normals
    face_of = r.face[corner[:, 0] // n]
    primvars = {}
    for name, values in zip(fvar_names, r.face_varying):
        primvars[name] = values.reshape(-1, values.shape[-1])[corner]
    for cols, data in ((vertex_cols, r.vertex_data), (varying_cols, r.varying_data)):
        for name, sl in cols:
            primvars[name] = data[:, sl][triangles]
    for name, values in per_face.items():
        primvars[name] = np.repeat(values[face_of][:, None, :], 3, axis=1)
    for name, value in constant.items():
        primvars[name] = np.broadcast_to(value, triangles.shape + value.shape).copy()
    primvars = {k: v.astype(np.float32) for k, v in primvars.items()}
    uvs = primvars.get(uv_name)
    if uvs is not None and uvs.shape[-1] < 2:
        warnings.append(f"{label} primvars:{uv_name}: fewer than 2 components (ignored)")
        uvs = None
    uvs = None if uvs is None else uvs[..., :2]
    if authored_normals:
        warnings.append(AUTHORED_NORMALS_IGNORED)
    return MeshData(r.points, triangles, face_ids[face_of], n_faces_in, normals=normals, uvs=uvs, warnings=warnings,
                    primvars=primvars)


#: Primvar value types refined with a subdivision surface for materials (texture coordinates and colours).
_REFINED_TYPES = {"texCoord2f[]", "texCoord2d[]", "texCoord2h[]", "float2[]", "double2[]", "half2[]", "color3f[]",
                  "color3d[]", "color3h[]", "color4f[]", "color4d[]", "color4h[]", "float3[]", "float4[]"}


def _refined_primvar_names(prim, uv_name) -> list:
    """The primvars a refined mesh carries per corner: its UV primvar, displayColor/displayOpacity, and every
    texture-coordinate or colour-typed primvar (what materials read: usd_io/materials/primvars.py)."""
    names = [uv_name]
    for pv in UsdGeom.PrimvarsAPI(prim).GetPrimvars():
        n = str(pv.GetPrimvarName())
        if n not in names and pv.HasValue() and (str(pv.GetTypeName()) in _REFINED_TYPES
                                                 or n in ("displayColor", "displayOpacity")):
            names.append(n)
    return names


#: One warning per stage (no prim path, so StageInfo.warn keeps one).
AUTHORED_NORMALS_IGNORED = ("normals authored on subdivision surfaces are ignored, as the USD spec says "
                            "(subdivisionScheme = \"none\" keeps them; --complexity low renders the cage with them)")


def _has_authored_normals(prim, mesh) -> bool:
    pv = _primvar(prim, "normals")
    return pv is not None or mesh.GetNormalsAttr().HasAuthoredValue()

"""``UsdGeom.Mesh`` -> triangles with per-corner normals and texture coordinates.

Polygons of any size are fan-triangulated (exact for convex faces). Every primvar interpolation is expanded to
per-corner values through the triangulation's corner table:

    constant     one value for every corner
    uniform      one per face          -> indexed by each triangle's face
    vertex       one per point         -> indexed by the corner's point index
    varying      one per point (meshes: the same as vertex)
    faceVarying  one per face-vertex   -> indexed by the corner's face-vertex position

Indexed primvars are flattened first (``Primvar.ComputeFlattened``). ``orientation = leftHanded`` reverses the
winding so the tracer's counter-clockwise front faces match USD's; so does a mirroring (negative determinant)
transform. Subdivision surfaces render as their control cage, with smooth (area-weighted) vertex normals when
the mesh has none, since such a cage stands for a smooth surface.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pxr import UsdGeom

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


def _primvar(prim, name):
    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar(name)
    return pv if pv and pv.HasValue() else None


def read_uvs(prim, tri: Triangulation, n_points, n_fv, time, name="st"):
    pv = _primvar(prim, name)
    if pv is None:
        return None, None
    vals = pv.ComputeFlattened(time)
    if vals is None or len(vals) == 0:
        return None, None
    uv, why = expand_primvar(np.asarray(vals, dtype=np.float64).reshape(len(vals), -1)[:, :2],
                             pv.GetInterpolation(), tri, n_points, n_fv, f"{prim.GetPath()} primvars:{name}")
    return uv, why


#: usdrecord/usdview's --complexity names -> uniform refinement levels of subdivision surfaces (Hydra's refineLevel
#: for complexity 1.0, 1.1, 1.2, 1.3).
COMPLEXITY = {"low": 0, "medium": 1, "high": 2, "veryhigh": 3}
DEFAULT_COMPLEXITY = "medium"


def read_mesh(prim, time, uv_name="st", subdivision_level: int = COMPLEXITY[DEFAULT_COMPLEXITY]) -> MeshData | None:
    mesh = UsdGeom.Mesh(prim)
    label = str(prim.GetPath())
    points = mesh.GetPointsAttr().Get(time)
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
    left = mesh.GetOrientationAttr().Get(time) == UsdGeom.Tokens.leftHanded
    holes = mesh.GetHoleIndicesAttr().Get(time) or ()
    scheme = mesh.GetSubdivisionSchemeAttr().Get(time) or UsdGeom.Tokens.catmullClark
    if scheme in (UsdGeom.Tokens.catmullClark, UsdGeom.Tokens.loop) and subdivision_level > 0:
        return _subdivided(prim, mesh, points, counts, indices, holes, left, scheme, subdivision_level, time,
                           uv_name, label)
    tri = triangulate(counts, indices, len(points), holes, left, label)
    n_fv = len(indices)
    data = MeshData(points, tri.triangles, tri.faces, tri.n_faces, warnings=list(tri.warnings),
                    corners=tri.corners, n_face_vertices=n_fv)

    # Normals: primvars:normals wins over the normals attribute (UsdGeom rule).
    pv = _primvar(prim, "normals")
    if pv is not None:
        vals, interp = pv.ComputeFlattened(time), pv.GetInterpolation()
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


def _face_varying(prim, name, counts, indices, n_points, time):
    """A primvar as one value per face-vertex (None if absent or of the wrong size)."""
    pv = _primvar(prim, name)
    if pv is None:
        return None
    vals = pv.ComputeFlattened(time)
    if vals is None or len(vals) == 0:
        return None
    v = np.asarray(vals, np.float64).reshape(len(vals), -1)
    interp = pv.GetInterpolation()
    n_fv = len(indices)
    if interp == UsdGeom.Tokens.faceVarying and len(v) == n_fv:
        return v
    if interp in (UsdGeom.Tokens.vertex, UsdGeom.Tokens.varying) and len(v) == n_points:
        return v[indices]
    if interp == UsdGeom.Tokens.uniform and len(v) == len(counts):
        return np.repeat(v, counts, axis=0)
    if interp == UsdGeom.Tokens.constant:
        return np.repeat(v[:1], n_fv, axis=0)
    return None


def _subdivided(prim, mesh, points, counts, indices, holes, left, scheme, level, time, uv_name, label):
    """A subdivision surface refined ``level`` times (tracer.subdivision.catmull_clark), with its UVs carried
    through and smooth normals of the refined surface. Authored normals are ignored, as the USD spec says for
    subdivision surfaces."""
    from tracer.subdivision import catmull_clark, limit_normals

    warnings = []
    counts = np.asarray(counts, np.int64)
    indices = np.asarray(indices, np.int64)
    if counts.sum() != len(indices) or (len(indices) and (indices.min() < 0 or indices.max() >= len(points))):
        triangulate(counts, indices, len(points), holes, left, label)  # raises the cage's own error
    keep = counts >= 3
    if (~keep).any():
        warnings.append(f"{label}: skipped {int((~keep).sum())} face(s) with fewer than 3 vertices")
        fv_keep = np.repeat(keep, counts)
        indices, counts = indices[fv_keep], counts[keep]
    if scheme == UsdGeom.Tokens.loop:
        warnings.append(f"{label}: loop subdivision refined with Catmull-Clark rules")
    authored = [n for n, a in (("creases", mesh.GetCreaseIndicesAttr()), ("corners", mesh.GetCornerIndicesAttr()))
                if a.HasAuthoredValue() and len(a.Get(time) or ())]
    if authored:
        warnings.append(f"{label}: subdivision {' and '.join(authored)} are not supported (smooth everywhere)")
    boundary = mesh.GetInterpolateBoundaryAttr().Get(time)
    if boundary not in (None, UsdGeom.Tokens.edgeAndCorner):
        warnings.append(f"{label}: interpolateBoundary {boundary} refined as edgeAndCorner")
    st = _face_varying(prim, uv_name, counts, indices, len(points), time)
    r = catmull_clark(points, counts, indices, level, fvar=None if st is None else st[:, :2])
    quads, face = r.indices, np.flatnonzero(keep)[r.face]
    hole_set = np.asarray(holes, np.int64).reshape(-1)
    if hole_set.size:
        alive = ~np.isin(face, hole_set)
        quads, face = quads[alive], face[alive]
        warnings.append(f"{label}: {len(hole_set)} hole face(s) ignored (not cut; holes render as missing faces)")
        uv_q = None if r.fvar is None else r.fvar[alive]
    else:
        uv_q = r.fvar
    order = [[0, 2, 1], [0, 3, 2]] if left else [[0, 1, 2], [0, 2, 3]]
    triangles = np.concatenate([quads[:, order[0]], quads[:, order[1]]], axis=0)
    faces = np.concatenate([face, face])
    uvs = None if uv_q is None else np.concatenate([uv_q[:, order[0]], uv_q[:, order[1]]], axis=0)
    normals = limit_normals(r.points, quads)
    if left:
        normals = -normals
    return MeshData(r.points, triangles, faces, len(np.asarray(counts)) + int((~keep).sum()), normals=normals,
                    uvs=uvs, warnings=warnings)

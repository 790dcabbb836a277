"""What a ray learns where it hits a triangle: the point, the geometric and shading normals, the side it came from.

:class:`Geometry` holds the per-triangle arrays the kernels read (built once per render by :func:`geometry_of`);
:func:`hit_frame` is the per-hit computation.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .. import vec
from ..jit import kernel


class Geometry(NamedTuple):
    face_normals: np.ndarray  # (T, 3) float32 unit geometric normals (counter-clockwise front)
    normals: np.ndarray  # (R, 3) float32 shading normals: rows per vertex (V, 3) or per corner (3T, 3: row 3t + k),
    #                      or (3, 3) zeros (none); :func:`corner_normals` reads a triangle's three
    corner_ok: np.ndarray  # (T,) bool: all three corner normals usable, or (0,)
    material_ids: np.ndarray  # (T,) int32
    object_ids: np.ndarray  # (T,) int32
    has_normals: bool
    has_uvs: bool
    uv_sets: tuple  # (values (S, R, 2) float32, triangles, per_vertex): every UV set (NaN: no coordinates), S ≥ 0,
    #                 rows per vertex or per corner as ``normals``; :func:`uv_corners` reads a triangle's three
    colors: np.ndarray  # (T, 3, 3) float32 per-corner vertex colours, or (0, 3, 3)
    has_colors: bool
    vertices: np.ndarray  # (V, 3) float32
    triangles: np.ndarray  # (T, 3) int32
    normals_per_vertex: bool  # ``normals`` rows are vertices (read through ``triangles``), else corners


def geometry_of(scene) -> Geometry:  # scene: a tracer.Scene
    has_n = scene.normals is not None
    has_uv = scene.uvs is not None
    n_tri = len(scene.triangles)
    face_normals = np.empty((n_tri, 3), np.float32)
    corner_ok = np.empty(n_tri if has_n else 0, np.bool_)
    per_vertex = scene.normals_per_vertex
    # (R, 3) rows either way (a per-corner array viewed flat); none: three zero rows kernels read unused
    normals = scene.normals.reshape(-1, 3) if has_n else np.zeros((3, 3), np.float32)
    _face_frames(scene.vertices, scene.triangles, normals, per_vertex, face_normals, corner_ok)
    has_c = scene.colors is not None
    return Geometry(face_normals=face_normals, normals=normals, corner_ok=corner_ok,
                    material_ids=scene.material_ids, object_ids=scene.object_ids, has_normals=has_n, has_uvs=has_uv,
                    uv_sets=uv_table(scene), colors=scene.colors if has_c else np.zeros((0, 3, 3), np.float32),
                    has_colors=has_c, vertices=scene.vertices, triangles=scene.triangles,
                    normals_per_vertex=per_vertex)


def uv_table(scene) -> tuple:  # scene: a tracer.Scene
    """The kernels' view of ``scene.uv_sets``: (values (S, R, 2), triangles, per_vertex), rows per vertex (V) or
    per corner (3T, row 3t + k); one set is a view, several are stacked."""
    sets = scene.uv_sets
    per_vertex = scene.uvs_per_vertex
    if not sets:
        return np.zeros((0, 3, 2), np.float32), scene.triangles, False
    flat = [a.reshape(-1, 2) for a in sets]
    values = flat[0][None] if len(flat) == 1 else np.ascontiguousarray(np.stack(flat))
    return values, scene.triangles, per_vertex


@kernel(inline=True)
def corner_rows(triangles, per_vertex, tri):
    """The rows of a :class:`Geometry` ``normals`` table that hold triangle ``tri``'s three corners: its vertex
    indices (per-vertex layout) or 3·tri + k (per-corner layout)."""
    if per_vertex:
        return triangles[tri, 0], triangles[tri, 1], triangles[tri, 2]
    return 3 * tri, 3 * tri + 1, 3 * tri + 2


@kernel(inline=True)
def corner_normals(normals, triangles, per_vertex, tri):
    """The three shading normals (n0, n1, n2) at triangle ``tri``'s corners, as plain float tuples (the one place
    the kernels read the normals table)."""
    a, b, c = corner_rows(triangles, per_vertex, tri)
    return ((float(normals[a, 0]), float(normals[a, 1]), float(normals[a, 2])),
            (float(normals[b, 0]), float(normals[b, 1]), float(normals[b, 2])),
            (float(normals[c, 0]), float(normals[c, 1]), float(normals[c, 2])))


@kernel
def _face_frames(vertices, triangles, normals, per_vertex, face_normals, corner_ok):
    """Unit geometric normals (p1 − p0) × (p2 − p0) / ‖·‖ of every triangle, and whether all three of its corner
    shading normals are usable (non-zero; the scene zeroes unusable ones)."""
    for f in range(triangles.shape[0]):
        p0 = vec.row(vertices, triangles[f, 0])
        ng = vec.normalize(vec.cross(vec.sub(vec.row(vertices, triangles[f, 1]), p0),
                                     vec.sub(vec.row(vertices, triangles[f, 2]), p0)))
        face_normals[f, 0], face_normals[f, 1], face_normals[f, 2] = ng
    for f in range(corner_ok.shape[0]):
        ok = True
        for r in corner_rows(triangles, per_vertex, f):
            if normals[r, 0] == 0.0 and normals[r, 1] == 0.0 and normals[r, 2] == 0.0:
                ok = False
        corner_ok[f] = ok


@kernel(inline=True)
def hit_frame(geom, tri, d, u, v):
    """:func:`frame_at` of the scene's :class:`Geometry`."""
    return frame_at(geom.face_normals, geom.normals, geom.corner_ok, geom.has_normals, geom.triangles,
                    geom.normals_per_vertex, tri, d, u, v)


@kernel(inline=True)
def frame_at(face_normals, normals, corner_ok, has_normals, triangles, per_vertex, tri, d, u, v):
    """(ng, n, front) at barycentrics (u, v) of triangle ``tri`` hit by direction d (:func:`shading_frame` of that
    triangle's rows)."""
    smooth = has_normals and corner_ok[tri]
    n0, n1, n2 = corner_normals(normals, triangles, per_vertex and smooth, tri if smooth else 0)
    return shading_frame(vec.row(face_normals, tri), smooth, n0, n1, n2, d, u, v)


@kernel(inline=True)
def shading_frame(face_normal, smooth, n0, n1, n2, d, u, v):
    """(ng, n, front) at barycentrics (u, v) of a triangle of unit normal ``face_normal`` and (where ``smooth``)
    corner normals n0, n1, n2, hit by direction d.

    ng is the unit geometric normal turned to the incident side, n the interpolated shading normal on the same side
    (p = (1 − u − v)·p0 + u·p1 + v·p2); front is True where the ray hit the front face (entering a closed object).
    Unusable corner normals, or interpolated ones facing away from the geometric side, fall back to ng. (Plain
    values in: kernels read the rows themselves, as an array handed to an inlined helper with branches costs
    numba's reference counting per call.)
    """
    ng = face_normal
    front = vec.dot(d, ng) < 0.0
    if not front:
        ng = vec.scale(ng, -1.0)
    n = ng
    if smooth:
        w = 1.0 - u - v
        m = (w * n0[0] + u * n1[0] + v * n2[0], w * n0[1] + u * n1[1] + v * n2[1], w * n0[2] + u * n1[2] + v * n2[2])
        ln = math.sqrt(vec.dot(m, m))
        if ln > 1e-6:
            m = vec.scale(m, (1.0 if front else -1.0) / ln)
            if vec.dot(m, ng) > 0.0:
                n = m
    return ng, n, front


@kernel(inline=True)
def uv_corners(uv_sets, k, tri):
    """The coordinates ((s0, t0), (s1, t1), (s2, t2)) of UV set k at triangle ``tri``'s corners, as stored
    (float32; the one place the kernels read the UV table, :func:`uv_table`). k must be a set that exists."""
    values, triangles, per_vertex = uv_sets
    a, b, c = corner_rows(triangles, per_vertex, tri)
    return ((values[k, a, 0], values[k, a, 1]), (values[k, b, 0], values[k, b, 1]),
            (values[k, c, 0], values[k, c, 1]))


@kernel(inline=True)
def uv_count(uv_sets):
    """How many UV sets the table holds."""
    return uv_sets[0].shape[0]


@kernel(inline=True)
def uv_at(uv_sets, k, tri, u, v):
    """Texture coordinates (s, t) of UV set k at barycentrics (u, v) of triangle ``tri``, and whether the triangle
    has coordinates in that set (False: no such set, or NaN corners)."""
    if k >= uv_count(uv_sets):
        return 0.0, 0.0, False
    w = 1.0 - u - v
    c0, c1, c2 = uv_corners(uv_sets, k, tri)
    s = w * c0[0] + u * c1[0] + v * c2[0]
    t = w * c0[1] + u * c1[1] + v * c2[1]
    return s, t, (s == s and t == t)


@kernel(inline=True)
def hit_uv_set(geom, k, tri, u, v):
    """:func:`uv_at` of the scene's :class:`Geometry`."""
    return uv_at(geom.uv_sets, k, tri, u, v)


@kernel(inline=True)
def hit_color(geom, tri, u, v):
    """Interpolated vertex colour at barycentrics (u, v) of triangle ``tri`` (white without vertex colours)."""
    return color_at(geom.colors, geom.has_colors, tri, u, v)


@kernel(inline=True)
def color_at(colors, has_colors, tri, u, v):
    """:func:`hit_color` on the colour array itself."""
    if not has_colors:
        return 1.0, 1.0, 1.0
    w = 1.0 - u - v
    c = colors
    return (w * c[tri, 0, 0] + u * c[tri, 1, 0] + v * c[tri, 2, 0],
            w * c[tri, 0, 1] + u * c[tri, 1, 1] + v * c[tri, 2, 1],
            w * c[tri, 0, 2] + u * c[tri, 1, 2] + v * c[tri, 2, 2])


@kernel(inline=True)
def tangent_at(uv_sets, vertices, triangles, k, tri, ng):
    """Unit tangent T (direction of increasing s) and bitangent sign of UV set k on triangle ``tri``, from its
    corner positions and coordinates (dp/ds of the triangle's affine UV map); (0, 0, 0) where the UVs are
    degenerate or missing. The sign is +1 where (T, dp/dt) is right-handed about the front-face normal ``ng``."""
    if k >= uv_count(uv_sets):
        return (0.0, 0.0, 0.0), 1.0
    p0 = vec.row(vertices, triangles[tri, 0])
    e1 = vec.sub(vec.row(vertices, triangles[tri, 1]), p0)
    e2 = vec.sub(vec.row(vertices, triangles[tri, 2]), p0)
    c0, c1, c2 = uv_corners(uv_sets, k, tri)
    du1, dv1 = c1[0] - c0[0], c1[1] - c0[1]
    du2, dv2 = c2[0] - c0[0], c2[1] - c0[1]
    det = du1 * dv2 - du2 * dv1
    if not (abs(det) > 1e-20):
        return (0.0, 0.0, 0.0), 1.0
    inv = 1.0 / det
    t = vec.scale(vec.sub(vec.scale(e1, dv2), vec.scale(e2, dv1)), inv)
    b = vec.scale(vec.sub(vec.scale(e2, du1), vec.scale(e1, du2)), inv)
    sign = 1.0 if vec.dot(vec.cross(ng, t), b) >= 0.0 else -1.0
    return vec.normalize(t), sign


@kernel(inline=True)
def areas_at(uv_sets, vertices, triangles, k, tri):
    """(area in UV set k, area in world units) of triangle ``tri`` — their ratio is the texture's scale on it."""
    p0 = vec.row(vertices, triangles[tri, 0])
    e1 = vec.sub(vec.row(vertices, triangles[tri, 1]), p0)
    e2 = vec.sub(vec.row(vertices, triangles[tri, 2]), p0)
    world = 0.5 * vec.length(vec.cross(e1, e2))
    if k >= uv_count(uv_sets):
        return 0.0, world
    c0, c1, c2 = uv_corners(uv_sets, k, tri)
    du1, dv1 = c1[0] - c0[0], c1[1] - c0[1]
    du2, dv2 = c2[0] - c0[0], c2[1] - c0[1]
    uv = 0.5 * abs(du1 * dv2 - du2 * dv1)
    return (uv if uv == uv else 0.0), world

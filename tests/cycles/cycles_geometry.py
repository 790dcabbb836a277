"""Meshes and matrices for the Cycles comparison scenes, in numpy, so Blender and the tracer get the same polygons.

Every mesh is ``(vertices (V, 3), faces [list of vertex-index tuples], face_materials (F,) slot indices)``; faces
are planar (quads of a UV sphere are planar trapezoids), so Blender's triangulation and ours give the same surface.
"""

from __future__ import annotations

import numpy as np


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """4×4 object-to-world matrix of a camera/light at ``eye`` whose −Z looks at ``target`` (+Y towards ``up``)."""
    eye = np.asarray(eye, np.float64)
    z = eye - np.asarray(target, np.float64)
    z /= np.linalg.norm(z)
    x = np.cross(np.asarray(up, np.float64), z)
    if np.linalg.norm(x) < 1e-9:
        x = np.cross(np.array([0.0, 1.0, 0.0]), z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, y, z, eye
    return m


def trs(location=(0, 0, 0), rotation=(0, 0, 0), scale=(1, 1, 1)) -> np.ndarray:
    """Blender's object matrix: translation · Euler XYZ rotation (radians, R = Rz·Ry·Rx) · scale."""
    ax, ay, az = rotation
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    m = np.eye(4)
    m[:3, :3] = rz @ ry @ rx @ np.diag(np.asarray(scale, np.float64))
    m[:3, 3] = location
    return m


def plane(size=(2.0, 2.0), divisions=(1, 1), checker=False):
    """A plane in z = 0 facing +Z, ``size`` in x and y, split into a grid; ``checker`` alternates slots 0 and 1."""
    nx, ny = divisions
    xs = np.linspace(-size[0] / 2, size[0] / 2, nx + 1)
    ys = np.linspace(-size[1] / 2, size[1] / 2, ny + 1)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    verts = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=-1)
    idx = np.arange(gx.size).reshape(nx + 1, ny + 1)
    faces, mats = [], []
    for i in range(nx):
        for j in range(ny):
            faces.append((idx[i, j], idx[i + 1, j], idx[i + 1, j + 1], idx[i, j + 1]))
            mats.append((i + j) % 2 if checker else 0)
    return verts, faces, np.asarray(mats, np.int32)


def uv_sphere(radius=1.0, segments=48, rings=24):
    """Blender's UV sphere layout: poles on ±Z, ``segments`` around, ``rings`` from pole to pole. Outward normals."""
    theta = np.linspace(0, np.pi, rings + 1)[1:-1]  # polar angles of the inner rings
    phi = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring_pts = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1).reshape(-1, 3)
    verts = np.concatenate([[[0, 0, 1]], ring_pts, [[0, 0, -1]]]) * radius
    top, bottom = 0, len(verts) - 1

    def ring(r, s):
        return 1 + r * segments + s % segments

    faces = []
    for s in range(segments):
        faces.append((top, ring(0, s), ring(0, s + 1)))
    for r in range(rings - 2):
        for s in range(segments):
            faces.append((ring(r, s), ring(r + 1, s), ring(r + 1, s + 1), ring(r, s + 1)))
    for s in range(segments):
        faces.append((bottom, ring(rings - 2, s + 1), ring(rings - 2, s)))
    return verts, faces, np.zeros(len(faces), np.int32)


def box(size=(1.0, 1.0, 1.0)):
    """An axis-aligned box centred at the origin, outward-facing quads."""
    h = np.asarray(size, np.float64) / 2
    verts = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], np.float64) * h
    # vertex index = 4·(x>0) + 2·(y>0) + (z>0)
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return verts, faces, np.zeros(6, np.int32)


def prism(size=1.0, depth=1.0):
    """A right-angled isosceles triangular prism (a TIR prism): the right angle at the origin in the x-z plane,
    legs of length ``size`` along +X and +Z, extruded ``depth`` along Y (centred)."""
    tri = np.array([[0, 0], [size, 0], [0, size]], np.float64)
    y0, y1 = -depth / 2, depth / 2
    verts = np.array([[x, y0, z] for x, z in tri] + [[x, y1, z] for x, z in tri])
    faces = [(0, 1, 2), (3, 5, 4), (0, 3, 4, 1), (1, 4, 5, 2), (2, 5, 3, 0)]
    return verts, faces, np.zeros(len(faces), np.int32)


def triangulate(faces) -> tuple[np.ndarray, np.ndarray]:
    """Fan-triangulate polygons; returns (T, 3) triangles and (T,) the face each came from."""
    tris, owner = [], []
    for f, face in enumerate(faces):
        for k in range(1, len(face) - 1):
            tris.append((face[0], face[k], face[k + 1]))
            owner.append(f)
    return np.asarray(tris, np.int64), np.asarray(owner, np.int64)


MESHES = {"plane": plane, "uv_sphere": uv_sphere, "box": box, "prism": prism}


def make_mesh(kind: str, **params):
    if kind not in MESHES:
        raise ValueError(f"unknown mesh kind {kind!r}; choose from {sorted(MESHES)}")
    return MESHES[kind](**params)

"""The coordinate spaces material programs read (:mod:`tracer.shading.vm`): per object, its texture space and its
world-to-object matrix, and the camera's; packed once per render into one float64 array the VM indexes.

    spaces = object_spaces(scene)            # (O + 1, 9, 4); entry O is the camera
    set_camera(spaces, scene.camera)         # refresh the camera entry (a session moves the camera)

Per object id k < O (Cycles' definitions, ``svm_node_tex_coord``):

- rows 0, 1 (x, y, z): the low and high corners of its *texture space*, the bounds of its triangles in object space
  (Blender's automatic texture space; Generated = (object position − low) / (high − low), a flat axis 0.5);
- rows 2–4: the 3×4 matrix from the space its triangles are stored in (world for placed meshes, the prototype's
  space for instanced ones) to object space (the inverse of ``Scene.object_transforms``; Object coordinates);
- row 5: its location (the translation of its matrix; Object Info Location) and, in column 3, Object Info Random:
  Cycles' ``hash_uint2(hash_string(name), 0) / 0xFFFFFFFF`` of its name (what Cycles gives an object that is not a
  dupli; a Blender dupli's random comes from its persistent id, which a tracer scene does not hold);
- rows 6–8 (3×3): the transpose of its object-to-world matrix, which takes a world normal to an object-space one
  (up to length; Image Texture's Box projection).

The camera entry O: rows 0–2 the 3×4 world-to-camera matrix of Cycles' camera space (x right, y up, z forward, so
points in front have z > 0; Camera coordinates), row 3 (horizontal and vertical aperture, their offsets), row 4
(focal length, 1 for a perspective camera): Window = the point's position on the film in [0, 1]² (y up), z = 0.
"""

from __future__ import annotations

import numpy as np

from .procedural.hash import hash_uint2

#: rows of an object's entry
LO, HI, XF, LOC, NRM = 0, 1, 2, 5, 6
#: the camera entry's rows
CAM_XF, CAM_FILM, CAM_LENS = 0, 3, 4


def hash_string(name: str) -> int:
    """Cycles' ``hash_string``: i = i·37 + c over the name's UTF-8 bytes as signed chars (32-bit wrap)."""
    i = 0
    for b in name.encode("utf-8"):
        c = b - 256 if b >= 128 else b
        i = (i * 37 + c) & 0xFFFFFFFF
    return i


def object_random(name: str) -> float:
    """Object Info Random of an object named ``name`` (Cycles, an object that is not a dupli)."""
    return float(np.float32(hash_uint2(hash_string(name), 0)) * np.float32(1.0 / 0xFFFFFFFF))


def object_spaces(scene, texture_spaces: bool = True) -> np.ndarray:
    """(O + 1, 9, 4) float64: every object id's spaces and the camera's (module docstring). ``texture_spaces=False``
    leaves rows LO and HI zero (a pass over every triangle: skip it when no program reads Generated)."""
    ids = [np.asarray(scene.object_ids, np.int64)]
    if scene.instances is not None:
        ids.append(np.asarray(scene.instances.object_ids, np.int64))
    n = max([len(scene.object_names)] + [int(x.max()) + 1 for x in ids if len(x)] + [1])
    out = np.zeros((n + 1, 9, 4), np.float64)
    xf = np.tile(np.eye(4), (n, 1, 1))
    ot = scene.object_transforms
    if ot is not None:
        k = min(len(ot), n)
        xf[:k] = ot[:k]
    out[:n, LOC, :3] = xf[:, :3, 3]
    out[:n, NRM:NRM + 3, :3] = np.transpose(xf[:, :3, :3], (0, 2, 1))
    inv = affine_inverse(xf)  # (an instance's triangles are its prototype's, in that object's space)
    out[:n, XF:XF + 3, :] = inv
    if texture_spaces:
        out[:n, LO:HI + 1, :3] = _texture_spaces(scene, inv, n)
    for k, name in enumerate(scene.object_names[:n]):
        out[k, LOC, 3] = object_random(str(name))
    set_camera(out, scene.camera)
    return out


def affine_inverse(m: np.ndarray) -> np.ndarray:
    """(..., 3, 4): the inverses of affine (..., 4, 4) matrices (bottom row 0 0 0 1), by the adjugate of their 3×3
    part (0 where it is singular). Not ``np.linalg.inv``: numpy's OpenBLAS hands even a 4×4 to its thread pool,
    which on a loaded 2-core machine costs 0.1–4 ms of CPU per call (docs/benchmarks.md), and these run every render
    and every batch."""
    m = np.asarray(m, np.float64)
    r0, r1, r2 = m[..., 0, :3], m[..., 1, :3], m[..., 2, :3]
    c0, c1, c2 = np.cross(r1, r2), np.cross(r2, r0), np.cross(r0, r1)
    det = np.sum(r0 * c0, axis=-1)
    scale = np.divide(1.0, det, out=np.zeros_like(det), where=det != 0.0)
    a = np.stack([c0, c1, c2], axis=-1) * scale[..., None, None]  # columns c0, c1, c2: rows · columns = det·I
    out = np.empty(m.shape[:-2] + (3, 4), np.float64)
    out[..., :3] = a
    out[..., 3] = -np.einsum("...ij,...j->...i", a, m[..., :3, 3])
    return out


def _texture_spaces(scene, w2o: np.ndarray, n: int, chunk: int = 1 << 18) -> np.ndarray:
    """(n, 2, 3): each object's bounds in object space (0 where it has no triangles)."""
    lo = np.full((n, 3), np.inf)
    hi = np.full((n, 3), -np.inf)
    oid = np.asarray(scene.object_ids, np.int64)
    verts = np.asarray(scene.vertices, np.float64)
    for c0 in range(0, len(oid), chunk):  # per chunk of triangles, then per run of one id (meshes are contiguous)
        ids = oid[c0:c0 + chunk]
        tv = verts[scene.triangles[c0:c0 + chunk]]  # (t, 3, 3)
        if scene.object_transforms is not None:
            m = w2o[ids]
            tv = np.einsum("tij,tcj->tci", m[:, :, :3], tv) + m[:, None, :, 3]
        starts = np.concatenate([[0], np.flatnonzero(np.diff(ids)) + 1])
        np.minimum.at(lo, ids[starts], np.minimum.reduceat(tv.min(axis=1), starts, axis=0))
        np.maximum.at(hi, ids[starts], np.maximum.reduceat(tv.max(axis=1), starts, axis=0))
    bad = ~np.isfinite(lo).all(axis=1)
    lo[bad], hi[bad] = 0.0, 0.0
    return np.stack([lo, hi], axis=1)


def camera_space(camera) -> np.ndarray:
    """(9, 4): the camera entry (module docstring)."""
    out = np.zeros((9, 4), np.float64)
    w2c = affine_inverse(np.asarray(camera.camera_to_world, np.float64))
    out[CAM_XF:CAM_XF + 3] = w2c * np.array([[1.0], [1.0], [-1.0]])  # the tracer's camera looks down −z, Cycles' +z
    out[CAM_FILM] = (camera.horizontal_aperture, camera.vertical_aperture, camera.horizontal_aperture_offset,
                     camera.vertical_aperture_offset)
    out[CAM_LENS, :2] = (camera.focal_length, 1.0 if camera.projection == "perspective" else 0.0)
    return out


def set_camera(spaces: np.ndarray, camera) -> None:
    """Write ``camera``'s entry into ``spaces`` (in place, only if it changed)."""
    c = camera_space(camera)
    if not np.array_equal(spaces[-1], c):
        spaces[-1] = c

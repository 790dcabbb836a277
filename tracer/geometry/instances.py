"""Shared-mesh instances: the tables the kernels read to shade a hit on an instance, and their maths.

A :class:`tracer.Scene` may carry :class:`tracer.scene.Instances`: K placements of *prototypes* (objects whose
triangles are in object space and are drawn only through instances). Embree traces them as one instance array over
one BVH per prototype (:mod:`tracer.accel.accelerator`); a hit reports the prototype's triangle row ``prim`` and the instance
index ``inst`` (-1 for a hit on an ordinary, world-space triangle). What the shading then needs, per instance:

- the **normal matrix** N = (M₃ₓ₃)⁻ᵀ, which takes object-space normals to world space (the plain matrix M would
  tilt them under non-uniform scale); its transpose Nᵀ = M⁻¹ takes world directions to object space;
- the **linear part** M₃ₓ₃ (tangents and other surface vectors move with it, unnormalised);
- the instance's **object id** (AOV ``objectid``, names, pass indices) and its optional **material override**;
- whether it **mirrors** (det M < 0): normals need no care (N keeps the outside outside, the same facing that
  :func:`tracer.builder.place_mesh` gets by turning the winding of a flattened copy), but a tangent frame's
  handedness (bitangent = ± n × t) turns.

:func:`world_frame` is :func:`tracer.geometry.surface.hit_frame` for a hit anywhere: on an instance it runs ``hit_frame`` in
object space (the ray direction taken there by M⁻¹ keeps the front/back decision exact, since
d·(N n) = (Nᵀ d)·n), then takes both normals to world space by N.

:func:`world_emitters` gives the light table its emitting triangles in world space: ordinary ones as they are,
and each instance's emitting prototype triangles placed by its matrix (expanded for the light table only; the
BVH keeps the prototype once).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .. import vec
from ..jit import kernel
from .surface import hit_frame


class InstanceTables(NamedTuple):
    """Per-instance arrays the kernels read (all length K; K = 0 for a scene without instances)."""

    normal_matrix: np.ndarray  # (K, 3, 3) float64: (M₃ₓ₃)⁻ᵀ, object-space normal -> world
    linear: np.ndarray  # (K, 3, 3) float64: M₃ₓ₃, object-space vector -> world
    object_ids: np.ndarray  # (K,) int32
    materials: np.ndarray  # (K,) int32 material override, -1 = the prototype's own per-triangle materials
    mirrored: np.ndarray  # (K,) bool: det M₃ₓ₃ < 0


def pack_instances(scene) -> InstanceTables:
    """The :class:`InstanceTables` of ``scene.instances`` (empty tables when it has none)."""
    inst = getattr(scene, "instances", None)
    if inst is None or not len(inst):
        z3 = np.zeros((0, 3, 3), np.float64)
        return InstanceTables(z3, z3, np.zeros(0, np.int32), np.zeros(0, np.int32), np.zeros(0, np.bool_))
    lin = np.ascontiguousarray(inst.transforms[:, :3, :3], np.float64)
    return InstanceTables(normal_matrix=np.ascontiguousarray(np.linalg.inv(lin).transpose(0, 2, 1)),
                          linear=lin, object_ids=inst.object_ids, materials=inst.material_overrides(),
                          mirrored=np.linalg.det(lin) < 0)


@kernel(inline=True)
def mat3_apply(m, k, v):
    """m[k] @ v for a (K, 3, 3) table."""
    return (m[k, 0, 0] * v[0] + m[k, 0, 1] * v[1] + m[k, 0, 2] * v[2],
            m[k, 1, 0] * v[0] + m[k, 1, 1] * v[1] + m[k, 1, 2] * v[2],
            m[k, 2, 0] * v[0] + m[k, 2, 1] * v[1] + m[k, 2, 2] * v[2])


@kernel(inline=True)
def mat3_apply_transposed(m, k, v):
    """m[k]ᵀ @ v for a (K, 3, 3) table."""
    return (m[k, 0, 0] * v[0] + m[k, 1, 0] * v[1] + m[k, 2, 0] * v[2],
            m[k, 0, 1] * v[0] + m[k, 1, 1] * v[1] + m[k, 2, 1] * v[2],
            m[k, 0, 2] * v[0] + m[k, 1, 2] * v[1] + m[k, 2, 2] * v[2])


@kernel(inline=True)
def to_world_normal(tables, inst, n):
    """Object-space normal ``n`` of instance ``inst`` in world space, unit length (by the inverse transpose);
    ``n`` itself where ``inst`` < 0 (a world-space triangle)."""
    if inst < 0:
        return n
    w = mat3_apply(tables.normal_matrix, inst, n)
    ln = math.sqrt(vec.dot(w, w))
    return vec.scale(w, 1.0 / ln) if ln > 0.0 else w


@kernel(inline=True)
def to_object_direction(tables, inst, d):
    """World direction ``d`` in instance ``inst``'s object space: M⁻¹·d = Nᵀ·d (not normalised); ``d`` where
    ``inst`` < 0."""
    if inst < 0:
        return d
    return mat3_apply_transposed(tables.normal_matrix, inst, d)


@kernel(inline=True)
def handedness(tables, inst):
    """-1.0 where instance ``inst`` mirrors (a tangent frame's bitangent sign turns), else 1.0."""
    if inst >= 0 and tables.mirrored[inst]:
        return -1.0
    return 1.0


@kernel(inline=True)
def object_id(tables, inst, fallback):
    """The object id of a hit: instance ``inst``'s own, or ``fallback`` (the triangle's) where ``inst`` < 0."""
    if inst < 0:
        return fallback
    return tables.object_ids[inst]


@kernel(inline=True)
def material_id(tables, inst, fallback):
    """The material row of a hit: instance ``inst``'s override if it has one, else ``fallback`` (the
    triangle's)."""
    if inst < 0:
        return fallback
    m = tables.materials[inst]
    return m if m >= 0 else fallback


@kernel(inline=True)
def world_frame(geom, tables, inst, tri, d, u, v):
    """(ng, n, front) as :func:`tracer.geometry.surface.hit_frame`, in world space, for a hit on triangle row ``tri``
    through instance ``inst`` (-1: a world-space triangle, i.e. exactly ``hit_frame``).

    On an instance the frame is found in object space (direction M⁻¹·d: the same side as in world space) and both
    normals are taken to world space by the normal matrix; an interpolated normal that ends up facing away from
    the world geometric normal falls back to it, as ``hit_frame``'s own rule."""
    if inst < 0:
        return hit_frame(geom, tri, d, u, v)
    ng_o, n_o, front = hit_frame(geom, tri, to_object_direction(tables, inst, d), u, v)
    ng = to_world_normal(tables, inst, ng_o)
    n = to_world_normal(tables, inst, n_o)
    if vec.dot(n, ng) <= 0.0:
        n = ng
    return ng, n, front


# ------------------------------------------------------------------------------------------------ lights
def world_emitters(scene, emission: np.ndarray | None = None, with_objects: bool = False):
    """(tri (N, 3, 3) float64 world-space corners, Le (N, 3)) of every emitting triangle of ``scene``, as
    :func:`tracer.lights.emitters.emitting_triangles` gives them for a flat scene: the ordinary triangles whose material
    emits, then for each instance the emitting triangles of its prototype (with the instance's material override)
    placed by its matrix — vectorised per prototype, no loop over instances. ``emission``: the materials'
    (M, 3) emission (default ``scene.materials.emission``). ``with_objects``: a third array, each triangle's object
    id (an instance's own id for its copies), for per-object light linking of emitters."""
    emission = np.asarray(scene.materials.emission if emission is None else emission, np.float64)
    glowing = emission.max(axis=1) > 0 if len(emission) else np.zeros(0, bool)
    mids = np.asarray(scene.material_ids)
    inst = getattr(scene, "instances", None)
    proto_rows = scene.prototype_rows() if inst is not None and len(inst) else np.zeros(len(mids), bool)
    rows = np.flatnonzero(~proto_rows & (glowing[mids] if len(mids) else np.zeros(0, bool)))
    v = np.asarray(scene.vertices, np.float64)
    tris = [v[scene.triangles[rows]]]
    les = [emission[mids[rows]]]
    objs = [np.asarray(scene.object_ids, np.int64)[rows]]
    if inst is not None and len(inst) and glowing.any():
        overrides = inst.material_overrides()
        oids = np.asarray(scene.object_ids)
        for proto in np.unique(inst.prototypes):
            prow = np.flatnonzero(oids == proto)
            sel = np.flatnonzero(inst.prototypes == proto)
            if not len(prow) or not len(sel):
                continue
            corners = v[scene.triangles[prow]]  # (P, 3, 3) object space
            own = mids[prow]
            ov = overrides[sel]
            # per (instance, triangle): the material it shades with
            mat = np.where(ov[:, None] >= 0, ov[:, None], own[None, :])  # (S, P)
            lit = glowing[mat]
            ki, ti = np.nonzero(lit)
            if not len(ki):
                continue
            m = inst.transforms[sel[ki]]  # (N, 4, 4)
            placed = np.einsum("nij,nkj->nki", m[:, :3, :3], corners[ti]) + m[:, None, :3, 3]
            tris.append(placed)
            les.append(emission[mat[ki, ti]])
            objs.append(np.asarray(inst.object_ids, np.int64)[sel[ki]])
    out = np.concatenate(tris).reshape(-1, 3, 3), np.concatenate(les).reshape(-1, 3)
    return out + (np.concatenate(objs),) if with_objects else out

"""Transparent shadows inside Embree's traversal: an occlusion filter that looks through alpha < 1 surfaces.

A shadow ray is blocked by the first surface of alpha 1 on its segment; each surface of alpha a < 1 it crosses lets
1 − a of its colour through (a sum of lobes: its Transparent colour; Cycles' transparent shadows), and more than
``max_transparent`` of them block it. The tracer used to find those surfaces one at a time: an ``rtcOccluded`` over
all shadow rays, then, for the blocked ones, up to ``max_transparent`` + 1 rounds of closest hits, each a new
traversal from the root plus a pass over the rays (``Integrator._through_shadows``, still the path where the filter
cannot be used). Here one ``rtcOccluded8`` per packet does it all: Embree calls :func:`_occlusion_filter` (a numba
``cfunc``) on every hit of a geometry that may be see-through, the filter evaluates the material's alpha there (the
same :func:`blocker`, the shader VM's ``program_alpha`` included, that the round-by-round loop uses), scales the
ray's colour by what passes and rejects the hit, so the traversal goes on; an opaque hit, or one over the count,
is accepted and ends it. The product of the factors does not depend on the order the hits come in, nor does "more
than ``max_transparent`` surfaces", so the result is the loop's (up to ε: the loop restarts each round ε past the
surface it crossed).

Opaque geometry stays off the filter: it is an *argument* filter (``RTCOccludedArguments.filter``), invoked only on
geometries that enabled it (``rtcSetGeometryEnableFilterFunctionFromArguments``; the accelerator enables it on the
objects whose materials may be see-through, :func:`see_through_objects`) and only by the queries made here — every
other query (closest hits, plain occlusion) passes no arguments and sees those geometries as before.

What the filter reads (Embree 4 ``rtcore_common.h`` / ``rtcore_ray.h``): ``RTCFilterFunctionNArguments`` {int*
valid; void* geometryUserPtr; RTCRayQueryContext* context; RTCRayN* ray; RTCHitN* hit; unsigned N} with the N rays
and hits in SOA layout (ray: org xyz, tnear, dir xyz, time, tfar = the hit's distance, mask, id, flags; hit: Ng xyz,
u, v, primID, geomID, instID[1], instPrimID[1]); for an instanced geometry ray and hit are in object space, so the
filter finds the world ray by its ``id`` (our index of the ray). Our ``RTCRayQueryContext`` (instID[1],
instPrimID[1]: 8 bytes, Embree's instance stack) is followed by our words: the address of the scene tables
(:class:`FilterTables`), the VM's registers, the rays' colours and transparent-surface counts, their world origins
and directions, and ``max_transparent``.

Not used (the round-by-round loop runs instead): scenes with a shadow catcher (its light is counted before
transparency scales the colours), BVHs built at quality "high" (spatial splits may report one hit twice, which
would count a partial surface twice), and objects that became see-through after the accelerator was built.
"""

from __future__ import annotations

import threading
import time as clock
from typing import NamedTuple

import numba
import numpy as np
from numba import carray, types
from numba.core import cgutils
from numba.extending import intrinsic

from .. import jit, vec
from ..geometry.instances import mat3_apply
from ..jit import kernel
from ..shading.compiler import pack_programs
from ..shading.vm import cut, program_alpha
from . import embree

#: Use the filter where it applies (tests switch it off to compare with the round-by-round loop).
ENABLED = True

# RTCOccludedArguments word 0: flags = RTC_RAY_QUERY_FLAG_INCOHERENT (0), feature_mask = RTC_FEATURE_FLAG_ALL.
_ARGS_WORD0 = np.uint64(0xFFFFFFFF << 32)
_NO_INSTANCE = np.uint64(0xFFFFFFFFFFFFFFFF)  # RTCRayQueryContext: instID[0], instPrimID[0] = RTC_INVALID_GEOMETRY_ID
# our words after the RTCRayQueryContext (8 bytes, padded to 16)
_C_TABLE, _C_R, _C_RLEN, _C_COLOR, _C_COUNT, _C_O, _C_D, _C_N, _C_MAXT = 2, 3, 4, 5, 6, 7, 8, 9, 10
_CONTEXT_WORDS = 11
_ARGS_WORDS = 6  # RTCOccludedArguments: flags, feature_mask, context, filter, occluded[, minWidthDistanceFactor]
_ENTRY = 5  # table words per array: address, then up to 4 extents

#: The arrays the filter reads, in table order, with the dtype and rank the kernels see them with (rank 0: a
#: scalar's value; the shader VM's ``execute`` is compiled once for these types: others would compile it again).
TABLE = (("overrides", np.int32, 1), ("normal_matrix", np.float64, 3), ("material_ids", np.int32, 1),
         ("face_normals", np.float32, 2), ("alphas", np.float32, 1), ("threshold", np.float32, 1),
         ("code", np.int32, 2), ("pstart", np.int32, 1), ("pbase", np.int32, 1), ("outs", np.int32, 2),
         ("uv_values", np.float32, 3), ("colors", np.float32, 3), ("has_colors", np.bool_, 0),
         ("vertices", np.float32, 2), ("triangles", np.int32, 2), ("object_ids", np.int32, 1),
         ("spaces", np.float64, 3), ("tdata", np.float32, 2), ("tparams", np.float64, 2), ("linear", np.float64, 3),
         ("mirrored", np.bool_, 1), ("inst_ids", np.int32, 1), ("lobe_extra", np.int32, 2),
         ("slot_start", np.int64, 1), ("slot_rows", np.int32, 1), ("inst_proto", np.int32, 1),
         ("uv_triangles", np.int32, 2), ("uv_per_vertex", np.bool_, 0))


# ---------------------------------------------------------------------------------------------- one blocker
@kernel(inline=True)
def blocker(tri, k, u, v, t, o3, d3, material_ids, overrides, normal_matrix, face_normals, alphas, threshold, code,
            pstart, pbase, outs, R, lobe_extra, geo, tex):
    """A shadow ray o3 + t·d3 meets triangle row ``tri`` (instance ``k``, -1: none) at barycentrics (u, v): the
    surface's coverage a (alpha after the cut-out threshold; a program's alpha is run there, Light Path: a shadow
    ray), the colour factor that passes it (1 − a, or a sum of lobes' Transparent colour), the point and the
    geometric normal facing the ray. Returns (a, (f0, f1, f2), p, ng)."""
    mat = material_ids[tri]
    if k >= 0 and overrides[k] >= 0:
        mat = overrides[k]
    p = vec.madd(o3, d3, t)
    ng = vec.row(face_normals, tri)
    if k >= 0:  # to world space by the instance's normal matrix (tracer.geometry.instances.to_world_normal)
        ng = vec.normalize(mat3_apply(normal_matrix, k, ng))
    front = vec.dot(ng, d3) < 0.0
    if not front:
        ng = vec.scale(ng, -1.0)
    if outs[mat, 4] >= 0:  # OUT_ALPHA: the program's
        a = cut(program_alpha(code, pstart, pbase, outs, R, mat, tri, u, v, p, ng, front, d3, t, k, geo, tex),
                float(threshold[mat]))
    else:
        a = cut(float(alphas[mat]), float(threshold[mat]))
    rt = lobe_extra[mat, 0]
    if rt >= 0:  # a sum of lobes (tracer.shading.lobes): its pass-through colour (Transparent BSDF tints)
        rt += pbase[mat]
        f = (max(R[rt], 0.0), max(R[rt + 1], 0.0), max(R[rt + 2], 0.0))
    else:
        f = (1.0 - a, 1.0 - a, 1.0 - a)
    return a, f, p, ng


# ---------------------------------------------------------------------------------------------- the filter
@intrinsic
def _ptr(typingctx, address):
    """The C pointer at integer ``address`` (for numba's ``carray``)."""
    if not isinstance(address, types.Integer):
        return None

    def codegen(context, builder, sig, args):
        return builder.inttoptr(args[0], cgutils.voidptr_t)

    return types.voidptr(address), codegen


@kernel(inline="always")
def _a1(table, i, dtype):
    e = i * _ENTRY
    return carray(_ptr(table[e]), (table[e + 1],), dtype)


@kernel(inline="always")
def _a2(table, i, dtype):
    e = i * _ENTRY
    return carray(_ptr(table[e]), (table[e + 1], table[e + 2]), dtype)


@kernel(inline="always")
def _a3(table, i, dtype):
    e = i * _ENTRY
    return carray(_ptr(table[e]), (table[e + 1], table[e + 2], table[e + 3]), dtype)


@kernel(inline="always")
def _a4(table, i, dtype):
    e = i * _ENTRY
    return carray(_ptr(table[e]), (table[e + 1], table[e + 2], table[e + 3], table[e + 4]), dtype)


def _occlusion_filter(argp):
    """RTCFilterFunctionN: per valid lane, the hit's surface is evaluated (:func:`blocker`); an opaque one (or one
    past ``max_transparent``) is accepted, which ends the shadow ray as blocked; any other scales the ray's colour
    by what it lets through and is rejected, so Embree looks further."""
    a = carray(argp, (6,), np.uint64)
    n = np.int64(a[5] & np.uint64(0xFFFFFFFF))
    valid = carray(_ptr(a[0]), (n,), np.int32)
    ctx = carray(_ptr(a[2]), (_CONTEXT_WORDS,), np.uint64)
    ray_f = carray(_ptr(a[3]), (12 * n,), np.float32)
    ray_w = carray(_ptr(a[3]), (12 * n,), np.uint32)
    hit_f = carray(_ptr(a[4]), (9 * n,), np.float32)
    hit_w = carray(_ptr(a[4]), (9 * n,), np.uint32)
    table = carray(_ptr(ctx[_C_TABLE]), (len(TABLE) * _ENTRY,), np.uint64)
    R = carray(_ptr(ctx[_C_R]), (ctx[_C_RLEN],), np.float64)
    m = ctx[_C_N]
    color = carray(_ptr(ctx[_C_COLOR]), (m, 3), np.float32)
    count = carray(_ptr(ctx[_C_COUNT]), (m,), np.int32)
    o = carray(_ptr(ctx[_C_O]), (m, 3), np.float32)
    d = carray(_ptr(ctx[_C_D]), (m, 3), np.float32)
    max_t = np.int64(ctx[_C_MAXT])
    overrides = _a1(table, 0, np.int32)
    normal_matrix = _a3(table, 1, np.float64)
    material_ids = _a1(table, 2, np.int32)
    face_normals = _a2(table, 3, np.float32)
    alphas = _a1(table, 4, np.float32)
    threshold = _a1(table, 5, np.float32)
    code = _a2(table, 6, np.int32)
    pstart = _a1(table, 7, np.int32)
    pbase = _a1(table, 8, np.int32)
    outs = _a2(table, 9, np.int32)
    uv_sets = (_a3(table, 10, np.float32), _a2(table, 26, np.int32), table[27 * _ENTRY] != 0)
    geo = (uv_sets, _a3(table, 11, np.float32), table[12 * _ENTRY] != 0,
           _a2(table, 13, np.float32), _a2(table, 14, np.int32), face_normals,
           _a1(table, 15, np.int32), _a3(table, 16, np.float64), _a3(table, 19, np.float64),
           _a1(table, 20, np.bool_), _a1(table, 21, np.int32))
    tex = (_a2(table, 17, np.float32), _a2(table, 18, np.float64))
    lobe_extra = _a2(table, 22, np.int32)
    slot_start = _a1(table, 23, np.int64)
    slot_rows = _a1(table, 24, np.int32)
    inst_proto = _a1(table, 25, np.int32)
    for i in range(n):
        if valid[i] == 0:
            continue
        r = np.int64(ray_w[10 * n + i])  # the ray's id: its row in our arrays
        inst = hit_w[7 * n + i]
        if inst_proto.shape[0] > 0 and inst == embree.ARRAY_GEOM_ID:
            k = np.int64(hit_w[8 * n + i])  # instPrimID: the instance of the array
            obj = np.int64(inst_proto[k])
        else:
            k = np.int64(-1)
            slot = inst if inst != embree.INVALID_ID else hit_w[6 * n + i]
            obj = np.int64(slot) - embree.OBJECT_GEOM_BASE
        row = slot_start[obj] + np.int64(hit_w[5 * n + i])
        if slot_rows.shape[0] > 0:
            row = np.int64(slot_rows[row])
        al, f, _p, _ng = blocker(np.int32(row), np.int32(k), float(hit_f[3 * n + i]), float(hit_f[4 * n + i]),
                                 float(ray_f[8 * n + i]), vec.row(o, r), vec.row(d, r), material_ids, overrides,
                                 normal_matrix, face_normals, alphas, threshold, code, pstart, pbase, outs, R,
                                 lobe_extra, geo, tex)
        if al >= 1.0:
            continue  # opaque: accepted, the ray is blocked
        count[r] += 1
        if count[r] > max_t:
            continue  # one surface too many: blocked, as the loop's last round leaves it
        color[r, 0] *= f[0]
        color[r, 1] *= f[1]
        color[r, 2] *= f[2]
        valid[i] = 0  # looked through: rejected, the traversal goes on


_FILTER = None


def filter_address() -> int:
    """The C address of :func:`_occlusion_filter`, compiled (and cached on disk with the kernels) on first use.

    Made under :data:`tracer.jit._MAKING`, the lock the kernels' dispatchers are made under: tile threads ask for
    it at once, and two compiles would each set ``_FILTER``, the first cfunc (whose address a thread may already
    have handed to Embree) then dropped; numba's global ``CACHE_DIR``, switched for the compile, is switched under
    the same lock by every kernel's first use."""
    global _FILTER
    if _FILTER is None:
        with jit._MAKING:  # tile threads reach this together on a first render
            if _FILTER is None:
                _FILTER = jit.cfunc(types.void(types.voidptr), _occlusion_filter)
    return _FILTER.address


# ---------------------------------------------------------------------------------------------- the query
@kernel
def occluded_through(scene, o, d, tnear, t_max, blocked, masks, time, color, table, R, count, ctx, args,
                     max_transparent, filter_address, q):
    """blocked[i] = shadow ray i meets an opaque surface, or more than ``max_transparent`` see-through ones, on
    [tnear, t_max[i]]; where it does not, color[i] is scaled by what the see-through ones let pass. One
    ``rtcOccludedN`` per packet (``q``: :func:`tracer.accel.embree.query`) with :func:`_occlusion_filter` as the argument
    filter (``masks``, ``time`` as in :func:`tracer.accel.embree.occluded_rays`; ``table``: :class:`FilterTables`).

    ``R`` (this call's register file, a copy of the VM's initial registers), ``count`` (n zeroed int32), ``ctx``
    (:data:`_CONTEXT_WORDS` words) and ``args`` (:data:`_ARGS_WORDS` words), both 16-byte aligned
    (:func:`_words`), are the caller's, one set per call (:func:`occluded`): the filter reaches them only
    through the raw addresses written into ``ctx``, and numba frees an array the kernel itself allocated right
    after the last line that names it, so a kernel-local register file, counter or context would be freed memory
    by the time Embree calls the filter (issue #30: tile threads corrupted each other's heap)."""
    W = q & embree._WIDTH_BITS
    f = embree._aligned(embree.RAY_FIELDS * embree.MAX_PACKET, np.float32)
    w = f.view(np.uint32)
    valid = embree._aligned(embree.MAX_PACKET, np.int32)
    n = o.shape[0]
    ctx[0] = _NO_INSTANCE
    ctx[_C_TABLE] = table.ctypes.data
    ctx[_C_R], ctx[_C_RLEN] = R.ctypes.data, R.shape[0]
    ctx[_C_COLOR], ctx[_C_COUNT] = color.ctypes.data, count.ctypes.data
    ctx[_C_O], ctx[_C_D], ctx[_C_N] = o.ctypes.data, d.ctypes.data, n
    ctx[_C_MAXT] = max_transparent
    args[0] = _ARGS_WORD0 | np.uint64(q & ~np.int64(embree._WIDTH_BITS))  # the query's flags (coherent or not)
    args[1] = ctx.ctypes.data
    args[2] = filter_address
    for start in range(0, n, W):
        count_ = min(W, n - start)
        embree._load_packet(f, w, valid, W, o, d, embree.IN_ORDER, start, count_, tnear, t_max, masks, time)
        embree._occluded(W, valid.ctypes.data, scene, f.ctypes.data, args.ctypes.data)
        for k in range(count_):
            blocked[start + k] = f[embree._TFAR * W + k] < 0.0


def _words(n: int) -> np.ndarray:
    """n zeroed 8-byte words starting 16-byte aligned (Embree's argument structs are RTC_ALIGN(16))."""
    raw = np.zeros(n + 2, np.uint64)
    off = ((16 - raw.ctypes.data % 16) % 16) // 8
    return raw[off:off + n]


# ---------------------------------------------------------------------------------------------- Python side
def see_through_materials(scene) -> np.ndarray:
    """Per material: may let light through (alpha < 1, or an alpha its program computes)."""

    m = scene.materials
    programs, _ = pack_programs(m, scene.textures)  # cached on the table: the integrator's call reuses it
    return np.asarray(m.alpha < 1) | programs.alpha_varies


def see_through_objects(scene, see=None) -> np.ndarray:
    """The object ids whose triangles may be see-through: a see-through material on one of their rows, or (for a
    prototype) on an instance's material override."""
    see = see_through_materials(scene) if see is None else see
    if not see.any() or not len(scene.triangles):
        return np.zeros(0, np.int64)
    ids = [np.unique(scene.object_ids[see[scene.material_ids]])]
    inst = scene.instances
    if inst is not None and inst.materials is not None:
        over = np.asarray(inst.materials)
        sel = over >= 0
        sel[sel] = see[over[sel]]
        ids.append(np.unique(inst.prototypes[sel]))
    return np.unique(np.concatenate(ids)).astype(np.int64)


class FilterTables:
    """The scene arrays the filter reads, as a table of (address, extents) words; holds the arrays alive."""

    def __init__(self, it, accel):
        g, m, pt, x, inst = it.geometry, it.materials, it.programs, it.textures, it.instances
        arrays = dict(overrides=inst.materials, normal_matrix=inst.normal_matrix, material_ids=g.material_ids,
                      face_normals=g.face_normals, alphas=m.alpha, threshold=m.alpha_threshold, code=pt.code,
                      pstart=pt.pstart, pbase=pt.pbase, outs=pt.outs, uv_values=g.uv_sets[0],
                      uv_triangles=g.uv_sets[1], uv_per_vertex=g.uv_sets[2], colors=g.colors,
                      has_colors=g.has_colors, vertices=g.vertices, triangles=g.triangles, object_ids=g.object_ids,
                      spaces=it.spaces, tdata=x.data, tparams=x.params, linear=inst.linear, mirrored=inst.mirrored,
                      inst_ids=inst.object_ids, lobe_extra=pt.lobe_extra, slot_start=accel._start,
                      slot_rows=accel._rows, inst_proto=accel._inst_proto)
        self.accel_arrays = (accel._start, accel._rows, accel._inst_proto)  # replaced by the accelerator's edits
        self.arrays = []
        self.table = np.zeros(len(TABLE) * _ENTRY, np.uint64)
        for i, (name, dtype, ndim) in enumerate(TABLE):
            a = np.asarray(arrays[name])
            if ndim == 0:  # a scalar: its value
                self.table[i * _ENTRY] = int(a)
                continue
            if a.dtype != dtype or a.ndim != ndim or not a.flags.c_contiguous:
                raise TypeError(f"tracer.accel.alpha: {name} is {a.dtype} {a.shape}, the filter reads {np.dtype(dtype)} "
                                f"of rank {ndim}, C-contiguous")
            self.arrays.append(a)
            self.table[i * _ENTRY] = a.ctypes.data
            self.table[i * _ENTRY + 1:i * _ENTRY + 1 + ndim] = a.shape


class _Prepared(NamedTuple):
    usable: bool
    tables: FilterTables | None


_PREPARING = threading.Lock()


def _prepared(it) -> _Prepared:
    """Whether the filter serves integrator ``it`` and, if so, its :class:`FilterTables`: made once, by the first
    tile thread that asks, under a lock, and published whole in one assignment; the tables are made again (same
    lock) when the accelerator's row tables were replaced by a session edit. Every tile thread of a render asks at
    once, so a check-then-set without the lock would build the tables several times over, each thread then holding
    a different table while the integrator keeps the last one."""
    state = it.__dict__.get("_alpha")
    if state is not None and _current(state, it.accel):
        return state
    with _PREPARING:
        state = it.__dict__.get("_alpha")
        if state is None or not _current(state, it.accel):
            ok = _usable(it)
            state = _Prepared(ok, FilterTables(it, it.accel) if ok else None)
            it.__dict__["_alpha"] = state
    return state


def _current(state: _Prepared, accel) -> bool:
    """The tables still point at the accelerator's row tables (a session edit replaces them)."""
    return state.tables is None or all(a is b for a, b in zip(state.tables.accel_arrays, (
        accel._start, accel._rows, accel._inst_proto)))


def _usable(it) -> bool:
    accel = it.accel
    filtered = getattr(accel, "filtered", None)
    ok = ENABLED and filtered is not None and not it.compose.has_catcher and accel.quality != "high"
    if ok:
        see = np.asarray(it.materials.alpha < 1) | it.programs.alpha_varies
        ok = bool(np.isin(see_through_objects(it.scene, see), filtered).all())
    return ok


def usable(it) -> bool:
    """The filter gives this integrator's shadow rays the round-by-round loop's answer: every object that may be
    see-through has it enabled in the accelerator, no shadow catcher, no spatial splits."""
    return _prepared(it).usable


def occluded(it, shadow, masks, time) -> np.ndarray:
    """The shadow rays' blocked mask, their colours (``shadow.color``, float32 C-contiguous) scaled in place by
    the see-through surfaces they cross (:func:`occluded_through`). Thread-safe: the tables are shared read-only,
    and the register file, counters and Embree context the filter writes or reads by address are this call's."""
    accel = it.accel
    n = len(shadow.o)
    blocked = np.zeros(n, bool)
    tables = _prepared(it).tables
    o = np.ascontiguousarray(shadow.o, np.float32)
    d = np.ascontiguousarray(shadow.d, np.float32)
    tm = np.ascontiguousarray(np.minimum(shadow.t_max, embree.T_FAR_MAX), np.float32)
    if shadow.color.dtype != np.float32 or not shadow.color.flags.c_contiguous:
        raise TypeError("tracer.accel.alpha.occluded: shadow colours must be C-contiguous float32 (scaled in place)")
    registers = it.programs.R0.copy()  # the VM writes its registers: one file per call, never R0 itself
    count = np.zeros(n, np.int32)
    ctx, args = _words(_CONTEXT_WORDS), _words(_ARGS_WORDS)
    q = embree.query(coherent=False)
    start = clock.perf_counter()
    occluded_through(accel._top.handle, o, d, np.float32(0.0), tm, blocked, embree.ray_masks(masks), embree.ray_times(time),
                     shadow.color, tables.table, registers, count, ctx, args,
                     np.int64(it.settings.max_transparent), np.uint64(filter_address()), q)
    embree.library().check()
    accel._account(start, "OCCLUDED", o, d, tm, q)
    return blocked

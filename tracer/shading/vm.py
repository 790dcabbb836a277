"""The shader VM: compiled material programs (:mod:`tracer.shading.compiler`) evaluated per hit, in numba.

A program is a run of fixed-width instructions ``[op, dst, a, b, c, d, e, f, imm]`` (int32, :data:`WIDTH` words)
over a float64 register file. Operands a–f are register numbers relative to the material's register base, except
where an op's description below says otherwise (texture index, UV set); ``imm`` holds the node's enum (operation,
blend mode, clamp flags). Constants are registers too, written once per stage call from the packed initial register
file, so the per-hit loop reads and writes registers only: no Python, no allocation, no reference counting (the
stage kernels are compiled with ``kernel(refcounts=False)`` and take every array as its own argument).

A vector or colour occupies three consecutive registers; an image lookup writes four (r, g, b, a). A program ends
with its outputs in registers the material's row of ``outs`` names (:data:`OUT_SLOTS`; -1 = the row's constant).

Inputs a program reads at a hit (``OP_INPUT``, ``imm`` one of the ``IN_*`` codes): position, shading and true
normals, incoming direction, UVs of any set, object coordinates and generated ones (object space, and the position
within the object's texture space), camera and window coordinates (the spaces of :mod:`tracer.shading.spaces`),
vertex colour, backfacing, the ray's depth and length (Light Path), object info (location, random, index). ``b`` = 1 or 2 reads them at the bump offset points set up by ``OP_BUMP_SETUP`` (register ``c``):
the hit moved one footprint along two tangent directions, its barycentrics moved with it, as Cycles' Bump node
evaluates its height input at P + dPdx and P + dPdy.
"""

from __future__ import annotations

import math

import numpy as np

from .. import vec
from ..colorspace import REC709_LUMINANCE
from ..geometry.instances import mat3_apply, mat3_apply_transposed
from ..geometry.surface import areas_at, tangent_at, uv_at
from ..jit import kernel
from ..optics import valid_reflection_normal
from .bsdf import dielectric_albedo
from . import ops

# Opcodes, hit inputs and closure outputs: the node table's (tracer.shading.nodes; numba reads these globals as
# constants). The branches of execute and _procedural follow its OPS rows (tests/test_shader_vm.py checks them).
from .nodes import (IN_BACKFACING, IN_CAMERA, IN_COLOR, IN_COLOR_ALPHA, IN_GENERATED, IN_INCOMING,  # noqa: E402,F401
                    IN_IS_CAMERA, IN_IS_REFLECTION, IN_IS_SHADOW, IN_NORMAL, IN_OBJ_INDEX, IN_OBJ_LOCATION,
                    IN_OBJ_RANDOM, IN_OBJECT, IN_PARAMETRIC, IN_POSITION, IN_RAY_DEPTH, IN_RAY_LENGTH, IN_REFLECTION,
                    IN_TANGENT, IN_TRUE_NORMAL, IN_UV, IN_WINDOW, OP_AFFINE2, OP_AVG, OP_BLACKBODY, OP_BRICK, OP_BRIGHT,
                    OP_BUMP, OP_BUMP_SETUP, OP_CHECKER, OP_CLAMP, OP_COMB_COLOR, OP_COMBINE, OP_COPY, OP_CURVE,
                    OP_FRESNEL, OP_GAMMA, OP_GRADIENT, OP_HSV, OP_IMAGE, OP_INPUT, OP_INVERT, OP_LAYER_WEIGHT, OP_LUM,
                    OP_MAGIC, OP_MAP_RANGE, OP_MAP_RANGE_V, OP_MAPPING, OP_MATH, OP_MIX_C, OP_MIX_F, OP_MIX_V,
                    OP_MIX_VN, OP_MX_NOISE, OP_NAMES, OP_NOISE, OP_NOP, OP_NORMAL_MAP, OP_NORMALIZE_N, OP_RAMP,
                    OP_SELECT, OP_SEP_COLOR, OP_VMATH, OP_VORONOI, OP_VROTATE, OP_VTRANSFORM, OP_WAVE, OP_WAVELENGTH,
                    OP_WHITE_NOISE, OUT_ALPHA, OUT_ANISO, OUT_BASE, OUT_EMIT, OUT_METAL, OUT_NORMAL, OUT_ROUGH, OUT_SLOTS,
                    OUT_SMOOTH, OUT_SPEC, OUT_TRANS, WIDTH)
from .procedural import color as pcolor, mx_noise as pmx, noise as pnoise, patterns as ppat, voronoi as pvor
from .spaces import CAM_FILM, CAM_LENS, CAM_XF, HI, LO, LOC, NRM, XF
from .texture import lookup_at, texel_density

_LUM_R, _LUM_G, _LUM_B = REC709_LUMINANCE


@kernel
def _bary_at(vertices, triangles, tri, u, v):
    """Object-space position at barycentrics (u, v) of triangle ``tri``."""
    w = 1.0 - u - v
    a, b, c = triangles[tri, 0], triangles[tri, 1], triangles[tri, 2]
    return (w * vertices[a, 0] + u * vertices[b, 0] + v * vertices[c, 0],
            w * vertices[a, 1] + u * vertices[b, 1] + v * vertices[c, 1],
            w * vertices[a, 2] + u * vertices[b, 2] + v * vertices[c, 2])


@kernel(inline=True)
def _affine(spaces, k, row, x):
    """The 3×4 matrix at rows row…row+2 of ``spaces[k]`` applied to the point x."""
    return (spaces[k, row, 0] * x[0] + spaces[k, row, 1] * x[1] + spaces[k, row, 2] * x[2] + spaces[k, row, 3],
            spaces[k, row + 1, 0] * x[0] + spaces[k, row + 1, 1] * x[1] + spaces[k, row + 1, 2] * x[2]
            + spaces[k, row + 1, 3],
            spaces[k, row + 2, 0] * x[0] + spaces[k, row + 2, 1] * x[1] + spaces[k, row + 2, 2] * x[2]
            + spaces[k, row + 2, 3])


@kernel(inline=True)
def _affine3(spaces, k, row, x):
    """The 3×3 part at rows row…row+2 of ``spaces[k]`` applied to the direction x."""
    return (spaces[k, row, 0] * x[0] + spaces[k, row, 1] * x[1] + spaces[k, row, 2] * x[2],
            spaces[k, row + 1, 0] * x[0] + spaces[k, row + 1, 1] * x[1] + spaces[k, row + 1, 2] * x[2],
            spaces[k, row + 2, 0] * x[0] + spaces[k, row + 2, 1] * x[1] + spaces[k, row + 2, 2] * x[2])


@kernel
def _project(x, y, z, kind):
    """Image Texture's Sphere (2) and Tube (3) projections of a point of the [0, 1]³ box (Cycles' ``map_to_sphere``,
    ``map_to_tube`` after ``texco_remap_square``); Environment Texture's equirectangular map of a direction (4,
    Cycles' ``direction_to_equirectangular``)."""
    if kind == 4:
        if x == 0.0 and y == 0.0 and z == 0.0:
            return 0.5, 0.5
        return -math.atan2(y, x) / (2.0 * math.pi) + 0.5, math.atan2(z, math.hypot(x, y)) / math.pi + 0.5
    x, y, z = 2.0 * x - 1.0, 2.0 * y - 1.0, 2.0 * z - 1.0
    if kind == 2:
        ln = math.sqrt(x * x + y * y + z * z)
        if ln <= 0.0:
            return 0.0, 0.0
        u = 0.0 if x == 0.0 and y == 0.0 else 0.5 - math.atan2(x, y) / (2.0 * math.pi)
        return u, 1.0 - math.acos(min(max(z / ln, -1.0), 1.0)) / math.pi
    ln = math.sqrt(x * x + y * y)
    if ln <= 0.0:
        return 0.0, 0.0
    return (1.0 - math.atan2(x / ln, y / ln) / math.pi) * 0.5, (z + 1.0) * 0.5


@kernel
def _box_lookup(tdata, tparams, ti, co, nrm, blend, lod):
    """Image Texture's Box projection (Cycles' ``svm_node_tex_image_box``): the three axis-aligned lookups of the
    point ``co`` weighted by the object-space normal ``nrm``, blended over ``blend``."""
    ax, ay, az = abs(nrm[0]), abs(nrm[1]), abs(nrm[2])
    sm = ax + ay + az
    if sm > 0.0:
        ax, ay, az = ax / sm, ay / sm, az / sm
    wx = wy = wz = 0.0
    limit = 0.5 * (1.0 + blend)
    if ax > limit * (ax + ay) and ax > limit * (ax + az):
        wx = 1.0
    elif ay > limit * (ax + ay) and ay > limit * (ay + az):
        wy = 1.0
    elif az > limit * (ax + az) and az > limit * (ay + az):
        wz = 1.0
    elif blend > 0.0:
        if az < (1.0 - limit) * (ay + ax):
            wx = min(max((ax / (ax + ay) - 0.5 * (1.0 - blend)) / blend, 0.0), 1.0)
            wy = 1.0 - wx
        elif ax < (1.0 - limit) * (ay + az):
            wy = min(max((ay / (ay + az) - 0.5 * (1.0 - blend)) / blend, 0.0), 1.0)
            wz = 1.0 - wy
        elif ay < (1.0 - limit) * (ax + az):
            wx = min(max((ax / (ax + az) - 0.5 * (1.0 - blend)) / blend, 0.0), 1.0)
            wz = 1.0 - wx
        else:
            wx = ((2.0 - limit) * ax + (limit - 1.0)) / (2.0 * limit - 1.0)
            wy = ((2.0 - limit) * ay + (limit - 1.0)) / (2.0 * limit - 1.0)
            wz = ((2.0 - limit) * az + (limit - 1.0)) / (2.0 * limit - 1.0)
    else:
        wx = 1.0
    r = g = b = al = 0.0
    for k in range(3):
        wk = wx if k == 0 else (wy if k == 1 else wz)
        if wk <= 0.0:
            continue
        if k == 0:
            s_, t_ = (1.0 - co[1] if nrm[0] < 0.0 else co[1]), co[2]
        elif k == 1:
            s_, t_ = (1.0 - co[0] if nrm[1] > 0.0 else co[0]), co[2]
        else:
            s_, t_ = (1.0 - co[1] if nrm[2] > 0.0 else co[1]), co[0]
        c = lookup_at(tdata, tparams, ti, s_, t_, s_ == s_ and t_ == t_, lod)
        r += wk * c[0]
        g += wk * c[1]
        b += wk * c[2]
        al += wk * c[3]
    return r, g, b, al


@kernel(inline="always")
def make_hit(tri, u, v, p, n, ng, front, d, t_len, depth, k_inst, footprint, shadow, eye, fpx):
    """The ``hit`` tuple :func:`execute` reads, with one set of element types whoever builds it (the surfaces'
    textures stage, shadow rays' alpha, the world), so that ``execute`` is compiled once: int32 triangle and
    instance, float32 barycentrics, normals, direction and ray length, float64 position, footprint and eye, and
    ``fpx`` = a pixel's footprint over ``footprint`` (the eye samples across a pixel: Cycles' bump offsets are its
    Filter Width × the pixel's ray differential)."""
    return (np.int32(tri), np.float32(u), np.float32(v), (np.float64(p[0]), np.float64(p[1]), np.float64(p[2])),
            (np.float32(n[0]), np.float32(n[1]), np.float32(n[2])),
            (np.float32(ng[0]), np.float32(ng[1]), np.float32(ng[2])), np.bool_(front),
            (np.float32(d[0]), np.float32(d[1]), np.float32(d[2])), np.float32(t_len), np.int64(depth),
            np.int32(k_inst), np.float64(footprint), np.bool_(shadow),
            (np.float64(eye[0]), np.float64(eye[1]), np.float64(eye[2])), np.float64(fpx))


@kernel(inline=True)
def execute(code, pc0, pc1, R, base, hit, geo, tex):
    """Run instructions pc0..pc1 of ``code`` for one hit, registers ``R[base + …]``. ``hit`` = (tri, u, v, p, n, ng,
    front, d, ray length, depth, instance, footprint, shadow ray?, eye), ``geo`` = (uv_sets, colors, has_colors,
    vertices, triangles, face_normals, object_ids, spaces (tracer.shading.spaces), linear, mirrored, instance object ids), ``tex`` =
    (texel data, texture params). (Tuples: Python passes a call of more than 30 arguments as *args, which numba
    cannot inline; the callers are compiled without reference counting, so the tuples cost nothing.)"""
    tri, u, v, p, n, ng, front, d, t_len, depth, k_inst, footprint, shadow, eye, fpx = hit
    uv_sets, colors, has_colors, vertices, triangles, face_normals, object_ids, spaces, linear, mirrored, inst_ids = geo
    tdata, tparams = tex
    k_read, uv_area, world_area = -1, 0.0, 0.0  # the UV set whose areas were last read (lookups mostly share one)
    for pc in range(pc0, pc1):
        op = code[pc, 0]
        o = base + code[pc, 1]
        a = base + code[pc, 2]
        b = base + code[pc, 3]
        c = base + code[pc, 4]
        imm = code[pc, 8]
        if op == OP_MATH:
            x = ops.math_op(imm & 255, R[a], R[b], R[c])
            if imm & 256:
                x = min(max(x, 0.0), 1.0)
            R[o] = x
        elif op == OP_VMATH:
            s = R[base + code[pc, 5]]
            x0, x1, x2, x3 = ops.vmath_op(imm, R[a], R[a + 1], R[a + 2], R[b], R[b + 1], R[b + 2], R[c], R[c + 1],
                                          R[c + 2], s)
            R[o], R[o + 1], R[o + 2], R[o + 3] = x0, x1, x2, x3
        elif op == OP_MIX_F:
            f = R[a]
            if imm & 1:
                f = min(max(f, 0.0), 1.0)
            R[o] = (1.0 - f) * R[b] + f * R[c]
        elif op == OP_MIX_V:
            f = R[a]
            if imm & 1:
                f = min(max(f, 0.0), 1.0)
            for j in range(3):
                R[o + j] = (1.0 - f) * R[b + j] + f * R[c + j]
        elif op == OP_MIX_VN:
            for j in range(3):
                f = R[a + j]
                if imm & 1:
                    f = min(max(f, 0.0), 1.0)
                R[o + j] = (1.0 - f) * R[b + j] + f * R[c + j]
        elif op == OP_MIX_C:
            f = R[a]
            if imm & 256:
                f = min(max(f, 0.0), 1.0)
            x0, x1, x2 = ops.mix_blend(imm & 255, f, R[b], R[b + 1], R[b + 2], R[c], R[c + 1], R[c + 2])
            if imm & 512:
                x0, x1, x2 = min(max(x0, 0.0), 1.0), min(max(x1, 0.0), 1.0), min(max(x2, 0.0), 1.0)
            R[o], R[o + 1], R[o + 2] = x0, x1, x2
        elif op == OP_LUM:
            R[o] = _LUM_R * R[a] + _LUM_G * R[a + 1] + _LUM_B * R[a + 2]
        elif op == OP_AVG:
            R[o] = (R[a] + R[a + 1] + R[a + 2]) / 3.0
        elif op == OP_COMBINE:
            x0, x1, x2 = R[a], R[b], R[c]
            R[o], R[o + 1], R[o + 2] = x0, x1, x2
        elif op == OP_COPY:
            for j in range(imm):
                R[o + j] = R[a + j]
        elif op == OP_SELECT:  # o = a if R[c] > 0.5 else b, width imm
            src = a if R[c] > 0.5 else b
            for j in range(imm):
                R[o + j] = R[src + j]
        elif op == OP_INPUT:
            _input(R, o, imm, code[pc, 2], code[pc, 3], base + code[pc, 4], hit, geo)
        elif op == OP_IMAGE:  # imm: projection (0 flat, 1 box: blend in register d, 2 sphere, 3 tube,
            #                   4 equirectangular of a direction: Environment Texture)
            ti = code[pc, 3]
            lod = 0.0
            k_fp = code[pc, 4]
            if k_fp >= 0 and footprint > 0.0:
                if k_fp != k_read:
                    uv_area, world_area = areas_at(uv_sets, vertices, triangles, k_fp, tri)
                    k_read = k_fp
                texels = footprint * texel_density(tparams, ti, uv_area, world_area)
                lod = math.log2(texels) if texels > 1.0 else 0.0
            if imm == 1:
                nb = _affine3(spaces, object_ids[tri], NRM, n) if k_inst < 0 else \
                    mat3_apply_transposed(linear, k_inst, n)  # the object-space normal (its direction)
                x0, x1, x2, x3 = _box_lookup(tdata, tparams, ti, (R[a], R[a + 1], R[a + 2]), nb,
                                             R[base + code[pc, 5]], lod)
            else:
                s_, t_ = R[a], R[a + 1]
                if imm >= 2:
                    s_, t_ = _project(R[a], R[a + 1], R[a + 2], imm)
                x0, x1, x2, x3 = lookup_at(tdata, tparams, ti, s_, t_, s_ == s_ and t_ == t_, lod)
            R[o], R[o + 1], R[o + 2], R[o + 3] = x0, x1, x2, x3
        elif op == OP_CHECKER:  # Cycles' svm_checker: Color1 where the cell parities differ
            sc = R[base + code[pc, 5]]
            px = (R[a] * sc + 0.000001) * 0.999999
            py = (R[a + 1] * sc + 0.000001) * 0.999999
            pz = (R[a + 2] * sc + 0.000001) * 0.999999
            xi, yi, zi = int(abs(math.floor(px))), int(abs(math.floor(py))), int(abs(math.floor(pz)))
            first = (xi % 2 == yi % 2) == (zi % 2 != 0)
            src = b if first else c
            R[o], R[o + 1], R[o + 2] = R[src], R[src + 1], R[src + 2]
            R[o + 3] = 1.0 if first else 0.0
        elif op == OP_NORMAL_MAP:  # imm: space (0 tangent: UV set c; object, world, Blender object / world)
            R[o], R[o + 1], R[o + 2] = _normal_map((R[a], R[a + 1], R[a + 2]), R[b], imm, code[pc, 4], hit, geo)
        elif op == OP_BUMP_SETUP:
            _bump_setup(R, o, tri, u, v, ng, footprint * fpx * R[a], k_inst, vertices, triangles, linear)
        elif op == OP_BUMP:
            _bump(R, o, R[a], R[b], R[c], R[base + code[pc, 5]], R[base + code[pc, 6]], base + code[pc, 7],
                  base + imm, ng)
        elif op == OP_RAMP:
            ops.ramp(R, o, R[a], b, code[pc, 4], code[pc, 8])
        elif op == OP_CURVE:
            ops.curve(R, o, a, b, code[pc, 4], R[base + code[pc, 5]], imm)
        elif op == OP_MAPPING:
            ops.mapping(R, o, a, b, c, base + code[pc, 5], imm)
        elif op == OP_HSV:
            x0, x1, x2 = ops.hue_sat(R[b], R[c], R[base + code[pc, 5]], R[base + code[pc, 6]], R[a], R[a + 1],
                                     R[a + 2])
            R[o], R[o + 1], R[o + 2] = x0, x1, x2
        elif op == OP_GAMMA:
            g = R[b]
            R[o], R[o + 1], R[o + 2] = ops.gamma(R[a], g), ops.gamma(R[a + 1], g), ops.gamma(R[a + 2], g)
        elif op == OP_BRIGHT:
            x0, x1, x2 = ops.bright_contrast(R[a], R[a + 1], R[a + 2], R[b], R[c])
            R[o], R[o + 1], R[o + 2] = x0, x1, x2
        elif op == OP_INVERT:
            f = R[b]
            R[o], R[o + 1], R[o + 2] = ((1.0 - f) * R[a] + f * (1.0 - R[a]), (1.0 - f) * R[a + 1] + f * (1.0 - R[a + 1]),
                                        (1.0 - f) * R[a + 2] + f * (1.0 - R[a + 2]))
        elif op == OP_SEP_COLOR:
            x0, x1, x2 = R[a], R[a + 1], R[a + 2]
            if imm == 1:
                x0, x1, x2 = ops.rgb_to_hsv(x0, x1, x2)
            elif imm == 2:
                x0, x1, x2 = ops.rgb_to_hsl(x0, x1, x2)
            R[o], R[o + 1], R[o + 2] = x0, x1, x2
        elif op == OP_COMB_COLOR:
            x0, x1, x2 = R[a], R[b], R[c]
            if imm == 1:
                x0, x1, x2 = ops.hsv_to_rgb(x0, x1, x2)
            elif imm == 2:
                x0, x1, x2 = ops.hsl_to_rgb(x0, x1, x2)
            R[o], R[o + 1], R[o + 2] = x0, x1, x2
        elif op == OP_MAP_RANGE:
            R[o] = ops.map_range_clamp(imm & 255, R[a], R[b], R[c], R[base + code[pc, 5]], R[base + code[pc, 6]],
                                       R[base + code[pc, 7]], (imm & 256) != 0)
        elif op == OP_MAP_RANGE_V:
            for j in range(3):
                R[o + j] = ops.map_range_clamp(imm & 255, R[a + j], R[b + j], R[c + j], R[base + code[pc, 5] + j],
                                               R[base + code[pc, 6] + j], R[base + code[pc, 7] + j],
                                               (imm & 256) != 0)
        elif op == OP_CLAMP:
            lo, hi = R[b], R[c]
            if imm == 1 and lo > hi:
                lo, hi = hi, lo
            R[o] = min(max(R[a], lo), hi)
        elif op == OP_FRESNEL:
            if imm == 2:  # a coat's albedo, roughness c (Cycles: on the valid specular reflection normal)
                nf = valid_reflection_normal(d, (R[b], R[b + 1], R[b + 2]), ng)
                R[o] = dielectric_albedo(R[c], abs(vec.dot(d, nf)), max(R[a], 1.0))
            else:
                R[o] = _fresnel(R[a], (R[b], R[b + 1], R[b + 2]), d, front)
        elif op == OP_LAYER_WEIGHT:
            _layer_weight(R, o, R[a], (R[b], R[b + 1], R[b + 2]), d, front)
        elif op == OP_VROTATE:
            ops.vrotate(R, o, a, b, c, base + code[pc, 5], base + code[pc, 6], imm)
        elif op == OP_AFFINE2:  # (s, t) -> M (s, t, 1), M the six constants at b
            s_, t_ = R[a], R[a + 1]
            R[o] = R[b] * s_ + R[b + 1] * t_ + R[b + 2]
            R[o + 1] = R[b + 3] * s_ + R[b + 4] * t_ + R[b + 5]
            R[o + 2] = R[a + 2]
        elif op == OP_VTRANSFORM:
            R[o], R[o + 1], R[o + 2] = _vtransform((R[a], R[a + 1], R[a + 2]), imm, hit, geo)
        elif op >= OP_NOISE:  # procedural textures (tracer.shading.procedural): a = vector, b = parameter block
            _procedural(R, op, o, a, b, imm)
        elif op == OP_NORMALIZE_N:  # a normal output: unit, on the incident side (else the shading normal)
            x = (R[a], R[a + 1], R[a + 2])
            ln = math.sqrt(vec.dot(x, x))
            if ln > 0.0 and vec.dot(x, ng) > 0.0:
                x = vec.scale(x, 1.0 / ln)
            else:
                x = n
            R[o], R[o + 1], R[o + 2] = x


@kernel(inline="call")
def _procedural(R, op, o, a, b, imm):
    """A procedural texture node (tracer.shading.procedural, Cycles' algorithms) at the vector R[a…], its other inputs the
    block R[b…] (per op below), its enums in ``imm`` (4 bits each, low first)."""
    e0, e1, e2, e3 = imm & 15, (imm >> 4) & 15, (imm >> 8) & 15, (imm >> 12) & 15
    p3 = (R[a], R[a + 1], R[a + 2])
    if op == OP_NOISE:  # block: W, Scale, Detail, Roughness, Lacunarity, Offset, Gain, Distortion; e0 dim, e1 type,
        #                 e2 normalize, e3 colour wanted
        p4 = (p3[0], p3[1], p3[2], R[b]) if e0 != 1 else (R[b], 0.0, 0.0, 0.0)
        if e3:
            f, c = pnoise.noise_texture(p4, e0, e1, R[b + 1], R[b + 2], R[b + 3], R[b + 4], R[b + 5], R[b + 6],
                                        R[b + 7], e2 != 0)
            R[o], R[o + 1], R[o + 2], R[o + 3] = f, c[0], c[1], c[2]
        elif e0 == 3 and e1 == pnoise.FBM and R[b + 7] == 0.0:  # the common case, without the dispatch
            R[o] = pnoise.fbm3(p3[0], p3[1], p3[2], R[b + 1], R[b + 2], R[b + 3], R[b + 4], e2 != 0)
        else:
            R[o] = pnoise.noise_value(p4, e0, e1, R[b + 1], R[b + 2], R[b + 3], R[b + 4], R[b + 5], R[b + 6],
                                      R[b + 7], e2 != 0)
    elif op == OP_VORONOI:  # block: W, Scale, Detail, Roughness, Lacunarity, Smoothness, Exponent, Randomness;
        #                     e0 dim, e1 feature, e2 metric, e3 normalize -> Distance, Color, Position, W, Radius
        p4 = (p3[0], p3[1], p3[2], R[b]) if e0 != 1 else (R[b], 0.0, 0.0, 0.0)
        d, c, pos, w, rad = pvor.voronoi_texture(p4, e0, e1, e2, R[b + 1], R[b + 2], R[b + 3], R[b + 4], R[b + 5],
                                                 R[b + 6], R[b + 7], e3 != 0)
        R[o] = d
        R[o + 1], R[o + 2], R[o + 3] = c
        R[o + 4], R[o + 5], R[o + 6] = pos
        R[o + 7], R[o + 8] = w, rad
    elif op == OP_WAVE:  # block: Scale, Distortion, Detail, Detail Scale, Detail Roughness, Phase Offset;
        #                  e0 type, e1 direction, e2 profile -> Fac
        R[o] = ppat.wave(p3, e0, e1, e2, R[b], R[b + 1], R[b + 2], R[b + 3], R[b + 4], R[b + 5])
    elif op == OP_MAGIC:  # block: Scale, Distortion; e0 depth -> Color, Fac
        c = ppat.magic(p3, e0, R[b], R[b + 1])
        R[o], R[o + 1], R[o + 2] = c
        R[o + 3] = (c[0] + c[1] + c[2]) / 3.0
    elif op == OP_GRADIENT:  # e0 type -> Fac
        R[o] = ppat.gradient(p3, e0)
    elif op == OP_BRICK:  # block: Color1 (3), Color2 (3), Mortar (3), Scale, Mortar Size, Mortar Smooth, Bias,
        #                   Brick Width, Row Height, offset, offset frequency, squash, squash frequency -> Color, Fac
        c, f = ppat.brick_color(p3, (R[b], R[b + 1], R[b + 2]), (R[b + 3], R[b + 4], R[b + 5]),
                                (R[b + 6], R[b + 7], R[b + 8]), R[b + 9], R[b + 10], R[b + 11], R[b + 12], R[b + 13],
                                R[b + 14], R[b + 15], int(R[b + 16]), R[b + 17], int(R[b + 18]))
        R[o], R[o + 1], R[o + 2] = c
        R[o + 3] = f
    elif op == OP_WHITE_NOISE:  # block: W; e0 dim -> Value, Color
        x, c = ppat.white_noise(p3, R[b], e0)
        R[o] = x
        R[o + 1], R[o + 2], R[o + 3] = c
    elif op == OP_BLACKBODY:
        R[o], R[o + 1], R[o + 2] = pcolor.blackbody(R[a])
    elif op == OP_WAVELENGTH:
        R[o], R[o + 1], R[o + 2] = pcolor.wavelength(R[a])
    elif op == OP_MX_NOISE:  # block: amplitude (4), pivot, octaves, lacunarity, diminish, jitter; e0 kind,
        #                      e1 dimensions, e2 output width, e3 style -> x, y, z, w
        R[o], R[o + 1], R[o + 2], R[o + 3] = pmx.mx_noise(e0, e1, e2, e3, p3[0], p3[1], p3[2], R[b], R[b + 1],
                                                          R[b + 2], R[b + 3], R[b + 4], R[b + 5], R[b + 6],
                                                          R[b + 7], R[b + 8])


@kernel(inline=True)
def _input(R, o, what, arg, variant, setup, hit, geo):
    """An ``OP_INPUT``: a value of the hit into R[o…] (``hit``, ``geo``: :func:`execute`'s)."""
    tri, u, v, p, n, ng, front, d, t_len, depth, k_inst, footprint, shadow, eye, fpx = hit
    uv_sets, colors, has_colors, vertices, triangles, face_normals, object_ids, spaces, linear, mirrored, inst_ids = geo
    if variant > 0:  # the bump offset points: barycentrics and world position moved by the setup's offsets
        j = 2 * (variant - 1)
        u = u + R[setup + j]
        v = v + R[setup + j + 1]
        q = 4 + 3 * (variant - 1)
        p = (p[0] + R[setup + q], p[1] + R[setup + q + 1], p[2] + R[setup + q + 2])
    x = (0.0, 0.0, 0.0)
    if tri < 0:  # the world (shade_directions): P is the direction, as Cycles' background; no surface inputs
        if what == IN_POSITION or what == IN_GENERATED or what == IN_OBJECT:
            x = p
        elif what == IN_NORMAL or what == IN_TRUE_NORMAL:
            x = n
        elif what == IN_INCOMING:
            x = (-d[0], -d[1], -d[2])
        elif what == IN_IS_CAMERA:
            x = (1.0, 0.0, 0.0)
        R[o], R[o + 1], R[o + 2] = x
        return
    if what == IN_POSITION:
        x = p
    elif what == IN_NORMAL:
        x = n
    elif what == IN_TRUE_NORMAL:
        x = ng
    elif what == IN_INCOMING:
        x = (-d[0], -d[1], -d[2])
    elif what == IN_UV:
        s, t, ok = uv_at(uv_sets, arg, tri, u, v)
        x = (s, t, 0.0) if ok else (np.nan, np.nan, 0.0)
    elif what == IN_GENERATED or what == IN_OBJECT:  # object space (tracer.shading.spaces); Generated: in its bounds
        po = _bary_at(vertices, triangles, tri, u, v)
        oid = object_ids[tri]
        x = _affine(spaces, oid, XF, po)
        if what == IN_GENERATED:
            lo = (spaces[oid, LO, 0], spaces[oid, LO, 1], spaces[oid, LO, 2])
            hi = (spaces[oid, HI, 0], spaces[oid, HI, 1], spaces[oid, HI, 2])
            # a flat axis sits in the middle of its texture space (Blender sizes it 1 about the centre)
            x = ((x[0] - lo[0]) / (hi[0] - lo[0]) if hi[0] > lo[0] else 0.5,
                 (x[1] - lo[1]) / (hi[1] - lo[1]) if hi[1] > lo[1] else 0.5,
                 (x[2] - lo[2]) / (hi[2] - lo[2]) if hi[2] > lo[2] else 0.5)
    elif what == IN_OBJ_LOCATION:  # the instance's translation, or the object's
        if k_inst >= 0:
            po = _bary_at(vertices, triangles, tri, u, v)
            m = mat3_apply(linear, k_inst, po)
            x = (p[0] - m[0], p[1] - m[1], p[2] - m[2])
        else:
            oid = object_ids[tri]
            x = (spaces[oid, LOC, 0], spaces[oid, LOC, 1], spaces[oid, LOC, 2])
    elif what == IN_BACKFACING:
        x = (0.0 if front else 1.0, 0.0, 0.0)
    elif what == IN_PARAMETRIC:
        x = (1.0 - u - v, u, 0.0)
    elif what == IN_COLOR:
        if has_colors:
            w = 1.0 - u - v
            x = (w * colors[tri, 0, 0] + u * colors[tri, 1, 0] + v * colors[tri, 2, 0],
                 w * colors[tri, 0, 1] + u * colors[tri, 1, 1] + v * colors[tri, 2, 1],
                 w * colors[tri, 0, 2] + u * colors[tri, 1, 2] + v * colors[tri, 2, 2])
        else:
            x = (1.0, 1.0, 1.0)
    elif what == IN_COLOR_ALPHA:
        x = (1.0, 0.0, 0.0)
    elif what == IN_OBJ_RANDOM or what == IN_OBJ_INDEX:
        oid = object_ids[tri] if k_inst < 0 else inst_ids[k_inst]
        x = (spaces[oid, LOC, 3] if what == IN_OBJ_RANDOM else float(oid), 0.0, 0.0)
    elif what == IN_RAY_DEPTH:
        x = (float(depth), 0.0, 0.0)
    elif what == IN_RAY_LENGTH:
        x = (t_len, 0.0, 0.0)
    elif what == IN_IS_CAMERA:
        x = (1.0 if depth == 0 and not shadow else 0.0, 0.0, 0.0)
    elif what == IN_IS_REFLECTION:
        x = (1.0 if depth > 0 and not shadow else 0.0, 0.0, 0.0)
    elif what == IN_IS_SHADOW:
        x = (1.0 if shadow else 0.0, 0.0, 0.0)
    elif what == IN_TANGENT:
        tg, sign = tangent_at(uv_sets, vertices, triangles, arg, tri, vec.row(face_normals, tri))
        if k_inst >= 0:
            tg = vec.normalize(mat3_apply(linear, k_inst, tg))
        x = tg
    elif what == IN_CAMERA or what == IN_WINDOW:  # Cycles' camera space; Window: the film position, y up
        cam = spaces.shape[0] - 1
        x = _affine(spaces, cam, CAM_XF, p)
        if what == IN_WINDOW:
            z = x[2] / spaces[cam, CAM_LENS, 0] if spaces[cam, CAM_LENS, 1] > 0.0 else 1.0
            z = z if z != 0.0 else 1e-30
            x = ((x[0] / z - spaces[cam, CAM_FILM, 2]) / spaces[cam, CAM_FILM, 0] + 0.5,
                 (x[1] / z - spaces[cam, CAM_FILM, 3]) / spaces[cam, CAM_FILM, 1] + 0.5, 0.0)
    elif what == IN_REFLECTION:
        dn = vec.dot(d, n)
        x = (d[0] - 2.0 * dn * n[0], d[1] - 2.0 * dn * n[1], d[2] - 2.0 * dn * n[2])
    R[o], R[o + 1], R[o + 2] = x


@kernel
def _inverse3(m):
    """The inverse of a 3×3 matrix (rows as tuples; 0 if singular)."""
    a, b, c = m
    c0 = vec.cross(b, c)
    c1 = vec.cross(c, a)
    c2 = vec.cross(a, b)
    det = vec.dot(a, c0)
    inv = 1.0 / det if det != 0.0 else 0.0
    return ((c0[0] * inv, c1[0] * inv, c2[0] * inv), (c0[1] * inv, c1[1] * inv, c2[1] * inv),
            (c0[2] * inv, c1[2] * inv, c2[2] * inv))


@kernel
def _rows(spaces, k, row):
    return ((spaces[k, row, 0], spaces[k, row, 1], spaces[k, row, 2]),
            (spaces[k, row + 1, 0], spaces[k, row + 1, 1], spaces[k, row + 1, 2]),
            (spaces[k, row + 2, 0], spaces[k, row + 2, 1], spaces[k, row + 2, 2]))


@kernel
def _cols(spaces, k, row):
    return ((spaces[k, row, 0], spaces[k, row + 1, 0], spaces[k, row + 2, 0]),
            (spaces[k, row, 1], spaces[k, row + 1, 1], spaces[k, row + 2, 1]),
            (spaces[k, row, 2], spaces[k, row + 1, 2], spaces[k, row + 2, 2]))


@kernel
def _object_matrices(hit, geo):
    """The hit object's matrix M (object to world, rows), its inverse and its translation."""
    tri, u, v, p, n, ng, front, d, t_len, depth, k_inst, footprint, shadow, eye, fpx = hit
    uv_sets, colors, has_colors, vertices, triangles, face_normals, object_ids, spaces, linear, mirrored, inst_ids = geo
    if k_inst >= 0:
        m = ((linear[k_inst, 0, 0], linear[k_inst, 0, 1], linear[k_inst, 0, 2]),
             (linear[k_inst, 1, 0], linear[k_inst, 1, 1], linear[k_inst, 1, 2]),
             (linear[k_inst, 2, 0], linear[k_inst, 2, 1], linear[k_inst, 2, 2]))
        po = _bary_at(vertices, triangles, tri, u, v)
        return m, _inverse3(m), vec.sub(p, ops.rot(m, po))
    oid = object_ids[tri]
    return (_cols(spaces, oid, NRM), _rows(spaces, oid, XF),  # NRM's rows hold Mᵀ, XF's M⁻¹
            (spaces[oid, LOC, 0], spaces[oid, LOC, 1], spaces[oid, LOC, 2]))


@kernel
def _normal_map(col, strength, space, k_uv, hit, geo):
    """Blender's Normal Map node (Cycles' ``svm_node_normal_map``): the colour as 2·c − 1 in tangent space (x along
    the UV tangent, y along sign·(N × T), z along the front-face shading normal, all in object space, then to world
    by the normal matrix), object space (by the normal matrix), world space, or Blender's object / world convention
    (y and z negated); flipped for a back face; Strength scales the tangent-space x, y (z = mix(1, z, saturate(s)))
    or, in the other spaces, blends linearly from the shading normal. The value itself, as Cycles gives it: a normal facing away from the viewer is
    left to the closure input (OP_NORMALIZE_N)."""
    tri, u, v, p, n, ng, front, d, t_len, depth, k_inst, footprint, shadow, eye, fpx = hit
    uv_sets, colors, has_colors, vertices, triangles, face_normals, object_ids, spaces, linear, mirrored, inst_ids = geo
    c = (2.0 * col[0] - 1.0, 2.0 * col[1] - 1.0, 2.0 * col[2] - 1.0)
    side = 1.0 if front else -1.0
    if space == 0:  # in object space, as Cycles (its tangents and normals are object-space attributes)
        if k_uv < 0:
            return n
        tg, sign = tangent_at(uv_sets, vertices, triangles, k_uv, tri, vec.row(face_normals, tri))
        m, mi, t = _object_matrices(hit, geo)
        if k_inst < 0:  # a placed mesh's triangles are in world space: its tangent and handedness to object space
            tg = ops.rot(mi, tg)
            if vec.dot(mi[0], vec.cross(mi[1], mi[2])) < 0.0:
                sign = -sign
        no = ops.rot_t(m, vec.scale(n, side))
        no = vec.scale(no, 1.0 / max(math.sqrt(vec.dot(no, no)), 1e-30))
        tg = vec.sub(tg, vec.scale(no, vec.dot(no, tg)))
        if vec.dot(tg, tg) < 1e-24:
            return n
        tg = vec.normalize(tg)
        b = vec.scale(vec.cross(no, tg), sign)
        # Strength in the tangent frame, as Cycles: x, y scaled, z = mix(1, z, saturate(strength)) (for a strength
        # above 1 not the linear blend from the normal, which tips the normal below the surface)
        st = min(max(strength, 0.0), 1.0)
        c = (c[0] * strength, c[1] * strength, 1.0 + (c[2] - 1.0) * st)
        x = ops.rot_t(mi, vec.madd(vec.madd(vec.scale(tg, c[0]), b, c[1]), no, c[2]))
        x = vec.scale(x, side)
    else:
        if space >= 3:
            c = (c[0], -c[1], -c[2])
        x = c
        if space == 1 or space == 3:
            m, mi, t = _object_matrices(hit, geo)
            x = ops.rot_t(mi, c)
        ln = math.sqrt(vec.dot(x, x))
        if ln == 0.0:
            return n
        x = vec.scale(x, side / ln)
    if space != 0 and strength != 1.0:  # object / world space: the linear blend from the normal
        x = vec.madd(n, vec.sub(x, n), max(strength, 0.0))
    ln = math.sqrt(vec.dot(x, x))
    return vec.scale(x, 1.0 / ln) if ln > 0.0 else n


@kernel
def _vtransform(x, imm, hit, geo):
    """Blender's Vector Transform (Cycles' ``svm_node_vector_transform``): imm = type (0 vector, 1 point, 2 normal)
    + 4·from + 16·to (0 world, 1 object, 2 camera). Points move by the full matrix, vectors by its 3×3 part, normals
    by its inverse transpose (normalised)."""
    tri, u, v, p, n, ng, front, d, t_len, depth, k_inst, footprint, shadow, eye, fpx = hit
    uv_sets, colors, has_colors, vertices, triangles, face_normals, object_ids, spaces, linear, mirrored, inst_ids = geo
    kind, src, dst = imm & 3, (imm >> 2) & 3, (imm >> 4) & 3
    if src == dst:
        return x
    m, mi, t = _object_matrices(hit, geo)
    cam = spaces.shape[0] - 1
    c = _rows(spaces, cam, CAM_XF)  # world to camera (rotation rows)
    ct = (spaces[cam, CAM_XF, 3], spaces[cam, CAM_XF + 1, 3], spaces[cam, CAM_XF + 2, 3])
    # to world
    if src == 1:
        if kind == 0:
            x = ops.rot(m, x)
        elif kind == 1:
            x = vec.add(ops.rot(m, x), t)
        else:
            x = ops.rot_t(mi, x)
    elif src == 2:
        x = ops.rot_t(c, vec.sub(x, ct) if kind == 1 else x)
    # from world
    if dst == 1:
        if kind == 0:
            x = ops.rot(mi, x)
        elif kind == 1:
            x = ops.rot(mi, vec.sub(x, t))
        else:
            x = ops.rot_t(m, x)
    elif dst == 2:
        x = ops.rot(c, x)
        if kind == 1:
            x = vec.add(x, ct)
    if kind == 2:
        ln = math.sqrt(vec.dot(x, x))
        if ln > 0.0:
            x = vec.scale(x, 1.0 / ln)
    return x


@kernel(refcounts=False)
def _bump_setup(R, o, tri, u, v, ng, footprint, k_inst, vertices, triangles, linear):
    """The two bump offsets: world offsets dPdx, dPdy of length ``footprint`` (the caller's: the Bump node's Filter
    Width × the pixel's footprint, as Cycles' ``bump_filter_width`` × dP) along an orthonormal tangent pair of
    the true normal, and the barycentric shifts (du, dv) that move the hit by them on its triangle. R[o…o+9] =
    du₁, dv₁, du₂, dv₂, dPdx (3), dPdy (3)."""
    a, b, c = triangles[tri, 0], triangles[tri, 1], triangles[tri, 2]
    p0 = vec.row(vertices, a)
    e1 = vec.sub(vec.row(vertices, b), p0)
    e2 = vec.sub(vec.row(vertices, c), p0)
    if k_inst >= 0:
        e1 = mat3_apply(linear, k_inst, e1)
        e2 = mat3_apply(linear, k_inst, e2)
    fp = footprint if footprint > 0.0 else 1e-3
    tu, tv = vec.orthonormal_basis(ng)
    dx = vec.scale(tu, fp)
    dy = vec.scale(tv, fp)
    g11, g12, g22 = vec.dot(e1, e1), vec.dot(e1, e2), vec.dot(e2, e2)
    det = g11 * g22 - g12 * g12
    inv = 1.0 / det if det != 0.0 else 0.0
    for j in range(2):
        dp = dx if j == 0 else dy
        r1, r2 = vec.dot(e1, dp), vec.dot(e2, dp)
        R[o + 2 * j] = (g22 * r1 - g12 * r2) * inv
        R[o + 2 * j + 1] = (g11 * r2 - g12 * r1) * inv
    R[o + 4], R[o + 5], R[o + 6] = dx
    R[o + 7], R[o + 8], R[o + 9] = dy


@kernel(refcounts=False)
def _bump(R, o, h0, hx, hy, strength, distance, nrm, setup, ng):
    """Cycles' Bump node (``svm_node_set_bump``): the surface gradient of the height from its values at P,
    P + dPdx, P + dPdy (the offsets of the ``OP_BUMP_SETUP`` at register ``setup``; Invert is a negated distance)."""
    dpx = (R[setup + 4], R[setup + 5], R[setup + 6])
    dpy = (R[setup + 7], R[setup + 8], R[setup + 9])
    nin = (R[nrm], R[nrm + 1], R[nrm + 2])
    rx = vec.cross(dpy, nin)
    ry = vec.cross(nin, dpx)
    det = vec.dot(dpx, rx)
    surfgrad = vec.add(vec.scale(rx, hx - h0), vec.scale(ry, hy - h0))
    dist = distance
    sgn = 1.0 if det >= 0.0 else -1.0
    out = vec.normalize(vec.sub(vec.scale(nin, abs(det)), vec.scale(surfgrad, dist * sgn)))
    st = max(strength, 0.0)
    out = vec.normalize(vec.add(vec.scale(out, st), vec.scale(nin, 1.0 - st)))
    if not (vec.dot(out, ng) > 0.0):
        out = nin
    R[o], R[o + 1], R[o + 2] = out











@kernel
def _fresnel_dielectric_cos(cosi, eta):
    """Cycles' ``fresnel_dielectric_cos``."""
    c = abs(cosi)
    g = eta * eta - 1.0 + c * c
    if g > 0.0:
        g = math.sqrt(g)
        a = (g - c) / (g + c)
        b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
        return 0.5 * a * a * (1.0 + b * b)
    return 1.0


@kernel
def _fresnel(ior, nrm, d, front):
    """Blender's Fresnel node (``svm_node_fresnel``): η = ior on the front face, 1/ior on the back."""
    eta = max(ior, 1e-5)
    eta = eta if front else 1.0 / eta
    cosi = -vec.dot(d, nrm)
    return _fresnel_dielectric_cos(cosi, eta)


@kernel(refcounts=False)
def _layer_weight(R, o, blend, nrm, d, front):
    """Blender's Layer Weight node (``svm_node_layer_weight``): Fresnel and Facing outputs."""
    b = max(blend, 0.0)
    eta = max(1.0 - b, 1e-5)
    eta = 1.0 / eta if front else eta
    cosi = -vec.dot(d, nrm)
    R[o] = _fresnel_dielectric_cos(cosi, eta)
    f = abs(cosi)
    if b != 0.5:
        bb = min(max(b, 0.0), 1.0 - 1e-5)
        bb = 2.0 * bb if bb < 0.5 else 0.5 / (1.0 - bb)
        f = f ** bb
    R[o + 1] = 1.0 - f


# ---------------------------------------------------------------------------------------------- the stage
@kernel(refcounts=False)
def shade_programs(rays, prim, u, v, t, inst, d, depth, code, pstart, pbase, outs, R0, R, s_mat, s_p, s_ng, s_n,
                   s_front, s_base, s_rough, s_metal, s_spec, s_cover, s_e, s_tran, threshold, uv_sets, colors,
                   has_colors, vertices, triangles, face_normals, object_ids, spaces, tdata, tparams, linear,
                   mirrored, inst_ids, eye, spread, flat, lobe_prog, lobe_surf, s_aniso, s_ns, px_samples):
    """The textures stage: for the listed rays (their material has a program), run it and write its outputs over
    the constants the surfaces stage wrote. ``R`` is this call's register file (``R0`` copied in once).
    ``lobe_prog`` = (kinds (M, MAX_LOBES), slot registers (M, MAX_LOBES, 6), (through, holdout) registers (M, 2))
    of the materials whose closure is a sum of lobes (:mod:`tracer.shading.lobes`); ``lobe_surf`` = the SurfaceQueue's
    (lobes, lobe_kind, lobe_w, lobe_base, lobe_param, through, holdout) they are written to."""
    for j in range(R0.shape[0]):
        R[j] = R0[j]
    geo = (uv_sets, colors, has_colors, vertices, triangles, face_normals, object_ids, spaces, linear, mirrored,
           inst_ids)
    tex = (tdata, tparams)
    for q in range(rays.shape[0]):
        i = rays[q]
        tri, mat = prim[i], s_mat[i]
        ui, vi = float(u[i]), float(v[i])
        p = (s_p[i, 0], s_p[i, 1], s_p[i, 2])
        n = vec.row(s_n, i)
        ng = vec.row(s_ng, i)
        di = vec.row(d, i)
        k_inst = inst[i]
        footprint = flat + spread * vec.length(vec.sub(p, eye))
        if k_inst >= 0:  # the instance scales the prototype's triangles: footprint in object units
            lk = linear
            det = abs(lk[k_inst, 0, 0] * (lk[k_inst, 1, 1] * lk[k_inst, 2, 2] - lk[k_inst, 1, 2] * lk[k_inst, 2, 1])
                      - lk[k_inst, 0, 1] * (lk[k_inst, 1, 0] * lk[k_inst, 2, 2] - lk[k_inst, 1, 2] * lk[k_inst, 2, 0])
                      + lk[k_inst, 0, 2] * (lk[k_inst, 1, 0] * lk[k_inst, 2, 1] - lk[k_inst, 1, 1] * lk[k_inst, 2, 0]))
            footprint /= max(det, 1e-30) ** (1.0 / 3.0)
        rb = pbase[mat]
        hit = make_hit(tri, ui, vi, p, n, ng, s_front[i], di, t[i], depth, k_inst, footprint, False, eye, px_samples)
        execute(code, pstart[mat], pstart[mat + 1], R, rb, hit, geo, tex)
        r = outs[mat, OUT_BASE]
        if r >= 0:
            s_base[i, 0], s_base[i, 1], s_base[i, 2] = (max(R[rb + r], 0.0), max(R[rb + r + 1], 0.0),
                                                        max(R[rb + r + 2], 0.0))
        r = outs[mat, OUT_ROUGH]
        if r >= 0:
            s_rough[i] = min(max(R[rb + r], 0.0), 1.0)
        r = outs[mat, OUT_METAL]
        if r >= 0:
            s_metal[i] = min(max(R[rb + r], 0.0), 1.0)
        r = outs[mat, OUT_SPEC]
        if r >= 0:
            s_spec[i] = max(R[rb + r], 0.0)
        r = outs[mat, OUT_ALPHA]
        if r >= 0:
            s_cover[i] = cut(R[rb + r], float(threshold[mat]))
        r = outs[mat, OUT_EMIT]
        if r >= 0:
            s_e[i, 0], s_e[i, 1], s_e[i, 2] = R[rb + r], R[rb + r + 1], R[rb + r + 2]  # unclamped, as Cycles
        r = outs[mat, OUT_NORMAL]
        if r >= 0:
            s_n[i, 0], s_n[i, 1], s_n[i, 2] = R[rb + r], R[rb + r + 1], R[rb + r + 2]
        r = outs[mat, OUT_TRANS]
        if r >= 0:
            s_tran[i] = min(max(R[rb + r], 0.0), 1.0)
        r = outs[mat, OUT_ANISO]
        if r >= 0:
            s_aniso[i, 0], s_aniso[i, 1], s_aniso[i, 2] = R[rb + r], R[rb + r + 1], R[rb + r + 2]
        r = outs[mat, OUT_SMOOTH]
        if r >= 0:  # the Displacement output's bump: the smooth normal (Cycles' SetNormal), s_ns
            s_ns[i, 0], s_ns[i, 1], s_ns[i, 2] = R[rb + r], R[rb + r + 1], R[rb + r + 2]
        if lobe_prog[2][mat, 0] >= 0:
            write_lobes(R, rb, mat, i, lobe_prog, lobe_surf)


@kernel(inline=True)
def write_lobes(R, rb, mat, i, lobe_prog, lobe_surf):
    """The closure's lobe slots of hit i from material ``mat``'s registers (weights and colours clamped at 0,
    roughness, metallic and transmission to [0, 1]); ``lobes`` = the number of slots (-1, the surfaces stage's
    value, marks the one-closure path)."""
    kinds, slots, extra = lobe_prog
    s_nl, s_lk, s_lw, s_lb, s_lp, s_through, s_holdout = lobe_surf
    nl = 0
    for k in range(kinds.shape[1]):
        kind = kinds[mat, k]
        if kind < 0:
            break
        s_lk[i, k] = kind
        rw, rc = rb + slots[mat, k, 0], rb + slots[mat, k, 1]
        for c in range(3):
            s_lw[i, k, c] = max(R[rw + c], 0.0)
            s_lb[i, k, c] = max(R[rc + c], 0.0)
        s_lp[i, k, 0] = min(max(R[rb + slots[mat, k, 2]], 0.0), 1.0)
        s_lp[i, k, 1] = min(max(R[rb + slots[mat, k, 3]], 0.0), 1.0)
        s_lp[i, k, 2] = max(R[rb + slots[mat, k, 4]], 0.0)
        s_lp[i, k, 3] = min(max(R[rb + slots[mat, k, 5]], 0.0), 1.0)
        nl += 1
    s_nl[i] = nl
    r = extra[mat, 0]
    if r >= 0:
        s_through[i, 0], s_through[i, 1], s_through[i, 2] = (max(R[rb + r], 0.0), max(R[rb + r + 1], 0.0),
                                                             max(R[rb + r + 2], 0.0))
    else:
        s_through[i, 0], s_through[i, 1], s_through[i, 2] = 0.0, 0.0, 0.0
    r = extra[mat, 1]
    s_holdout[i] = max(R[rb + r], 0.0) if r >= 0 else 0.0


@kernel(inline=True)
def cut(a, threshold):
    """Coverage from alpha: clamped to [0, 1]; a cut-out (threshold > 0) gives 0 below the threshold, else 1."""
    if threshold > 0.0:
        return 1.0 if a >= threshold else 0.0
    return min(max(a, 0.0), 1.0)


@kernel(inline=True)
def program_alpha(code, pstart, pbase, outs, R, mat, tri, u, v, p, ng, front, d, t_len, k_inst, geo, tex):
    """The alpha a material's program gives at a hit seen by a shadow ray (Light Path: Is Shadow Ray = 1; ``geo``,
    ``tex``: :func:`execute`'s)."""
    rb = pbase[mat]
    hit = make_hit(tri, u, v, p, ng, ng, front, d, t_len, 1, k_inst, 0.0, True, p, 1.0)
    execute(code, pstart[mat], pstart[mat + 1], R, rb, hit, geo, tex)
    return R[rb + outs[mat, OUT_ALPHA]]


@kernel(refcounts=False)
def shade_directions(code, pstart, pbase, outs, R0, R, mat, dirs, out, tdata, tparams, uv_sets, colors, has_colors,
                     vertices, triangles, face_normals, object_ids, spaces, linear, mirrored, inst_ids, depth, front):
    """A world's program (material ``mat``) for every direction of ``dirs`` (N, 3) float32: its emission into
    ``out`` (N, 3) (the world's Background colour × strength; the surface inputs read as Cycles' background: P =
    Generated = Object = the direction, N = −direction). The hit is built with the element types
    :func:`shade_programs` gives :func:`execute` (int32 triangle and instance, float32 barycentrics, ray length,
    normals and direction, float64 position), so that one compiled ``execute`` serves it and the shadow rays'
    :func:`program_alpha` (:func:`make_hit`)."""
    for j in range(R0.shape[0]):
        R[j] = R0[j]
    geo = (uv_sets, colors, has_colors, vertices, triangles, face_normals, object_ids, spaces, linear, mirrored,
           inst_ids)
    tex = (tdata, tparams)
    rb = pbase[mat]
    r = outs[mat, OUT_EMIT]
    none = np.int32(-1)
    zero, far = np.float32(0.0), np.float32(np.inf)  # float32 barycentrics and ray length, as the hits'
    eye = (0.0, 0.0, 0.0)
    for i in range(dirs.shape[0]):
        di = vec.row(dirs, i)  # float32, as a ray's direction
        nb = (-di[0], -di[1], -di[2])  # float32, as the surfaces stage's normals
        p = (np.float64(di[0]), np.float64(di[1]), np.float64(di[2]))  # float64, as its positions
        hit = make_hit(none, zero, zero, p, nb, nb, front, di, far, depth, none, 0.0, False, eye, 1.0)
        execute(code, pstart[mat], pstart[mat + 1], R, rb, hit, geo, tex)
        out[i, 0], out[i, 1], out[i, 2] = R[rb + r], R[rb + r + 1], R[rb + r + 2]

"""Motion blur (Cook 1984's distribution in time): the shutter, a time per eye sample, and transforms that move.

**Time.** A render with motion traces every eye sample at one time τ in [0, 1] across the shutter interval (0 =
shutter open, 1 = closed); every ray of its path (shadow, reflection, transmission, sky) keeps that time. The N²
eye samples of a pixel take the N² strata of [0, 1) in an order decorrelated from their film and lens strata
(:func:`time_sample`; a stream of its own), so a pixel's samples always cover the whole shutter. An optional
shutter curve (Blender's) weights the times: τ is drawn through the inverse of its cumulative integral.

**What moves** (:class:`Motion`, ``Scene.motion``; the front ends sample it at S times evenly spaced across the
shutter, step k at τ_k = k/(S − 1), as Embree spaces time steps):

- objects: per moving object id, S matrices that take its *stored* (world-space) triangles to where they are at
  step k: D_k = M(t_k)·M_stored⁻¹ (identity at the time the mesh was placed);
- instances: per instance, S object-to-world matrices (all instances get S steps once any moves);
- deforming meshes: per-step vertex positions (S, V, 3) of the scene's vertex array (every vertex; rows of
  static objects repeat), for the objects listed as deforming;
- the camera: ``Camera.motion`` (S, 4, 4) camera-to-world matrices.

**Interpolation** is Embree's quaternion decomposition (``rtcSetGeometryTransformQuaternion``), the one rule for
intersection *and* shading: each matrix is split into M = T·R·S (T a translation, R a rotation as a unit
quaternion, S upper triangular: scale and skew; :func:`decompose`); between two steps T and S are interpolated
linearly and the quaternion by shortest-arc slerp (:func:`matrix_at`), so a rotating object turns along its arc
instead of shrinking along the chord, and the normals shaded at time τ are those of the object Embree hit. Vertex
steps are interpolated linearly (as Embree does). Cycles decomposes with a polar split (R·stretch) instead of
QR; both give the same motion for rotations, translations and uniform scales.

Everything here costs nothing when a scene has no motion: ``Scene.motion`` is None, the camera's ``motion`` None,
and the kernels take their static path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ..jit import kernel
from ..sampling import uniform1
from .surface import corner_normals, shading_frame

#: Sample stream of the eye samples' times (film jitter: stream 0, lens: 61).
STREAM_TIME = 67
#: Rows of a decomposed transform (RTCQuaternionDecomposition's 16 floats, in its order).
DEC = 16
#: Cosine above which two quaternions are interpolated linearly and normalised (Embree's threshold).
SLERP_LINEAR_COS = 0.9995


# ---------------------------------------------------------------------------------------------- the shutter
#: Blender's ``render.motion_blur_position``: where the shutter interval sits around the frame.
SHUTTER_POSITIONS = ("START", "CENTER", "END")


def blender_shutter(shutter: float, position: str = "CENTER") -> tuple[float, float]:
    """(open, close) in frames relative to the current frame for Blender's ``motion_blur_shutter`` (the interval's
    length in frames) and ``motion_blur_position``: CENTER [−s/2, s/2], START [0, s], END [−s, 0] (Cycles)."""
    s = max(float(shutter), 0.0)
    if position == "START":
        return 0.0, s
    if position == "END":
        return -s, 0.0
    if position != "CENTER":
        raise ValueError(f"shutter position must be one of {SHUTTER_POSITIONS}, got {position!r}")
    return -0.5 * s, 0.5 * s


def step_times(open_: float, close: float, steps: int) -> np.ndarray:
    """The S times (relative to the frame, in the front end's unit) of the motion steps: evenly from open to close
    (step k at τ_k = k/(S − 1) of the shutter)."""
    return np.linspace(float(open_), float(close), int(steps))


def curve_table(values, size: int = 256) -> np.ndarray:
    """The inverse cumulative distribution of a shutter curve: ``values`` (the curve's weight at evenly spaced times
    from open to close, ≥ 0) → (size,) float32 times τ at evenly spaced quantiles, so a uniform u gives τ with
    density ∝ the curve (Cycles' shutter table). A flat curve gives the identity."""
    w = np.clip(np.asarray(values, np.float64).reshape(-1), 0.0, None)
    if len(w) < 2 or not w.sum() > 0:
        return np.linspace(0.0, 1.0, size).astype(np.float32)
    x = np.linspace(0.0, 1.0, len(w))
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(x))])
    cdf /= cdf[-1]
    return np.interp(np.linspace(0.0, 1.0, size), cdf, x).astype(np.float32)


@kernel(inline=True)
def time_sample(px, py, s, n, width, seed, key, table):
    """Time τ in [0, 1] of sample s of pixel (px, py): the pixel's N² samples take the N² strata of [0, 1), stratum
    (s·k) mod N² (k ≈ 0.38·N², coprime to it: neither the film's row-major strata nor the lens's order), jittered
    by the sample's own random number and turned per pixel (Cranley-Patterson); one sample per pixel takes its own
    random time. ``table`` (the shutter curve's :func:`curve_table`, or empty for a flat curve) then warps it."""
    nn = n * n
    if nn == 1:
        t = uniform1(key, STREAM_TIME, seed)
    else:
        k = (nn * 3) // 8 + 1
        while math.gcd(k, nn) != 1:
            k += 1
        r = uniform1((py * width + px) & 0xFFFFFFFF, STREAM_TIME + 1, seed)
        t = (((s * k) % nn) + uniform1(key, STREAM_TIME, seed)) / nn + r
        t -= math.floor(t)
    m = table.shape[0]
    if m > 1:
        x = t * (m - 1)
        i = min(int(x), m - 2)
        f = x - i
        t = (1.0 - f) * table[i] + f * table[i + 1]
    return t


# ---------------------------------------------------------------------------------------------- what moves
@dataclass
class Motion:
    """What moves across the shutter, at S evenly spaced steps (module docstring).

    steps            S ≥ 2
    object_ids       (M,) int32 moving objects (their stored triangles are world space)
    object_motion    (M, S, 4, 4) float64: D_k, stored triangles → step k
    instance_motion  optional (K, S, 4, 4) float64 object-to-world matrices of every instance of ``Scene.instances``
    vertices         optional (S, V, 3) float32: every scene vertex at each step (deformation)
    deforming        (D,) int32 object ids whose triangles read ``vertices`` (the others stay as stored)
    curve            (C,) float32 shutter table (:func:`curve_table`); empty: a flat (box) shutter
    """

    steps: int
    object_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    object_motion: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 4, 4)))
    instance_motion: np.ndarray | None = None
    vertices: np.ndarray | None = None
    deforming: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    curve: np.ndarray = field(default_factory=lambda: np.zeros(0, np.float32))

    def validate(self, n_vertices: int, n_instances: int) -> None:
        s = int(self.steps)
        if s < 2:
            raise ValueError(f"scene.motion.steps must be >= 2 (open and close), got {s}")
        self.steps = s
        self.object_ids = np.ascontiguousarray(np.asarray(self.object_ids).reshape(-1), np.int32)
        m = np.asarray(self.object_motion, np.float64)
        if m.shape != (len(self.object_ids), s, 4, 4) or not np.isfinite(m).all():
            raise ValueError(f"scene.motion.object_motion must be finite ({len(self.object_ids)}, {s}, 4, 4), got "
                             f"{m.shape}")
        self.object_motion = np.ascontiguousarray(m)
        if self.instance_motion is not None:
            im = np.asarray(self.instance_motion, np.float64)
            if im.shape != (n_instances, s, 4, 4) or not np.isfinite(im).all():
                raise ValueError(f"scene.motion.instance_motion must be finite ({n_instances}, {s}, 4, 4), got "
                                 f"{im.shape}")
            self.instance_motion = np.ascontiguousarray(im)
        if self.vertices is not None:
            v = np.asarray(self.vertices, np.float32)
            if v.shape != (s, n_vertices, 3) or not np.isfinite(v).all():
                raise ValueError(f"scene.motion.vertices must be finite ({s}, {n_vertices}, 3), got {v.shape}")
            self.vertices = np.ascontiguousarray(v)
        self.deforming = np.ascontiguousarray(np.asarray(self.deforming).reshape(-1), np.int32)
        if len(self.deforming) and self.vertices is None:
            raise ValueError("scene.motion.deforming names objects but scene.motion.vertices is None")
        self.curve = np.ascontiguousarray(np.asarray(self.curve, np.float32).reshape(-1))

    @property
    def moves(self) -> bool:
        """Some object, instance or mesh moves (else only the camera may, with this shutter curve)."""
        return bool(len(self.object_ids) or self.instance_motion is not None or len(self.deforming))

    @property
    def empty(self) -> bool:
        return not self.moves and not len(self.curve)


# ---------------------------------------------------------------------------------------------- decomposition
def _quaternion(r: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions (w, x, y, z) of (..., 3, 3) rotation matrices (Shepperd's method)."""
    r = np.asarray(r, np.float64)
    out = np.empty(r.shape[:-2] + (4,))
    tr = r[..., 0, 0] + r[..., 1, 1] + r[..., 2, 2]
    cand = np.stack([tr, r[..., 0, 0], r[..., 1, 1], r[..., 2, 2]], axis=-1)
    best = np.argmax(cand, axis=-1)
    for b in range(4):
        sel = best == b
        if not sel.any():
            continue
        m = r[sel]
        if b == 0:
            w = 0.5 * np.sqrt(1.0 + tr[sel])
            q = np.stack([w, (m[:, 2, 1] - m[:, 1, 2]) / (4 * w), (m[:, 0, 2] - m[:, 2, 0]) / (4 * w),
                          (m[:, 1, 0] - m[:, 0, 1]) / (4 * w)], axis=-1)
        else:
            i = b - 1
            j, k = (i + 1) % 3, (i + 2) % 3
            s = 0.5 * np.sqrt(np.maximum(1.0 + m[:, i, i] - m[:, j, j] - m[:, k, k], 1e-300))
            q = np.empty((len(m), 4))
            q[:, 0] = (m[:, k, j] - m[:, j, k]) / (4 * s)
            q[:, 1 + i] = s
            q[:, 1 + j] = (m[:, j, i] + m[:, i, j]) / (4 * s)
            q[:, 1 + k] = (m[:, k, i] + m[:, i, k]) / (4 * s)
        out[sel] = q
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def decompose(matrices) -> np.ndarray:
    """(..., 4, 4) affine matrices → (..., 16) float64 records in ``RTCQuaternionDecomposition``'s order: scale x y
    z, skew xy xz yz, shift x y z (0), quaternion r i j k, translation x y z, with M = T·R·S: the linear part split
    by a QR decomposition into a rotation R (det +1; a mirroring M keeps its sign in S's diagonal) and an upper
    triangular S. Consecutive steps' quaternions are put on the same hemisphere (the shorter arc)."""
    m = np.asarray(matrices, np.float64)
    lead = m.shape[:-2]
    flat = m.reshape(-1, 4, 4)
    q_mat, r_mat = np.linalg.qr(flat[:, :3, :3])
    sign = np.sign(np.diagonal(r_mat, axis1=1, axis2=2))
    sign[sign == 0] = 1.0
    q_mat = q_mat * sign[:, None, :]  # positive diagonal of S ...
    r_mat = r_mat * sign[:, :, None]
    flip = np.linalg.det(q_mat) < 0  # ... unless that leaves a reflection in R: move it into S's last row
    q_mat[flip, :, 2] *= -1
    r_mat[flip, 2, :] *= -1
    quat = _quaternion(q_mat)
    out = np.zeros((len(flat), DEC))
    out[:, 0], out[:, 1], out[:, 2] = r_mat[:, 0, 0], r_mat[:, 1, 1], r_mat[:, 2, 2]
    out[:, 3], out[:, 4], out[:, 5] = r_mat[:, 0, 1], r_mat[:, 0, 2], r_mat[:, 1, 2]
    out[:, 9:13] = quat
    out[:, 13:16] = flat[:, :3, 3]
    out = out.reshape(lead + (DEC,))
    if len(lead) and lead[-1] > 1:  # steps along the second-to-last axis: shortest arcs between neighbours
        q = out[..., 9:13]
        for k in range(1, lead[-1]):
            dot = np.sum(q[..., k, :] * q[..., k - 1, :], axis=-1)
            q[..., k, :] *= np.where(dot < 0, -1.0, 1.0)[..., None]
    return out


@kernel(inline=True)
def _slerp(a0, a1, a2, a3, b0, b1, b2, b3, f):
    """Embree's quaternion slerp (common/math/quaternion.h): the shorter arc, linear and normalised when the two
    are within acos(0.9995)."""
    c = a0 * b0 + a1 * b1 + a2 * b2 + a3 * b3
    if c < 0.0:
        b0, b1, b2, b3, c = -b0, -b1, -b2, -b3, -c
    if c > SLERP_LINEAR_COS:
        q0, q1, q2, q3 = a0 + f * (b0 - a0), a1 + f * (b1 - a1), a2 + f * (b2 - a2), a3 + f * (b3 - a3)
    else:
        phi = f * math.acos(min(c, 1.0))
        p0, p1, p2, p3 = c * a0 - b0, c * a1 - b1, c * a2 - b2, c * a3 - b3
        lp = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2 + p3 * p3)
        s, co = math.sin(phi) / lp, math.cos(phi)
        q0, q1, q2, q3 = co * a0 - s * p0, co * a1 - s * p1, co * a2 - s * p2, co * a3 - s * p3
    ln = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    return q0 / ln, q1 / ln, q2 / ln, q3 / ln


@kernel(inline=True)
def affine_at(dec, row, tau):
    """The 3×4 matrix (rows as three 4-tuples) of decomposed steps ``dec[row]`` ((S, 16)) at time τ ∈ [0, 1]:
    step interval found, S and T lerped, the quaternion slerped (:func:`_slerp`), M = T·R·S."""
    steps = dec.shape[1]
    x = min(max(tau, 0.0), 1.0) * (steps - 1)
    k = min(int(x), steps - 2)
    f = x - k
    a = dec[row, k]
    b = dec[row, k + 1]
    sx, sy, sz = a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), a[2] + f * (b[2] - a[2])
    kxy, kxz, kyz = a[3] + f * (b[3] - a[3]), a[4] + f * (b[4] - a[4]), a[5] + f * (b[5] - a[5])
    hx, hy, hz = a[6] + f * (b[6] - a[6]), a[7] + f * (b[7] - a[7]), a[8] + f * (b[8] - a[8])
    tx, ty, tz = a[13] + f * (b[13] - a[13]), a[14] + f * (b[14] - a[14]), a[15] + f * (b[15] - a[15])
    w, i, j, kk = _slerp(a[9], a[10], a[11], a[12], b[9], b[10], b[11], b[12], f)
    # rotation matrix of the unit quaternion (w, i, j, k)
    r00, r01, r02 = 1 - 2 * (j * j + kk * kk), 2 * (i * j - w * kk), 2 * (i * kk + w * j)
    r10, r11, r12 = 2 * (i * j + w * kk), 1 - 2 * (i * i + kk * kk), 2 * (j * kk - w * i)
    r20, r21, r22 = 2 * (i * kk - w * j), 2 * (j * kk + w * i), 1 - 2 * (i * i + j * j)
    # R·S with S = [[sx, kxy, kxz, hx], [0, sy, kyz, hy], [0, 0, sz, hz]]
    row0 = (r00 * sx, r00 * kxy + r01 * sy, r00 * kxz + r01 * kyz + r02 * sz,
            r00 * hx + r01 * hy + r02 * hz + tx)
    row1 = (r10 * sx, r10 * kxy + r11 * sy, r10 * kxz + r11 * kyz + r12 * sz,
            r10 * hx + r11 * hy + r12 * hz + ty)
    row2 = (r20 * sx, r20 * kxy + r21 * sy, r20 * kxz + r21 * kyz + r22 * sz,
            r20 * hx + r21 * hy + r22 * hz + tz)
    return row0, row1, row2


@kernel
def _matrices_at(dec, rows, taus, out):
    for i in range(rows.shape[0]):
        r0, r1, r2 = affine_at(dec, rows[i], taus[i])
        for c in range(4):
            out[i, 0, c], out[i, 1, c], out[i, 2, c] = r0[c], r1[c], r2[c]
        out[i, 3, 0], out[i, 3, 1], out[i, 3, 2], out[i, 3, 3] = 0.0, 0.0, 0.0, 1.0


def matrix_at(dec: np.ndarray, tau) -> np.ndarray:
    """The 4×4 matrices at times ``tau`` of decomposed steps ``dec`` ((S, 16) one transform, or (N, S, 16) with
    one τ each): array form of :func:`affine_at`."""
    d = np.ascontiguousarray(np.asarray(dec, np.float64))
    one = d.ndim == 2
    d = d[None] if one else d
    taus = np.ascontiguousarray(np.broadcast_to(np.asarray(tau, np.float64).reshape(-1), (len(d),)))
    out = np.empty((len(d), 4, 4))
    _matrices_at(d, np.arange(len(d), dtype=np.int64), taus, out)
    return out[0] if one else out


# ---------------------------------------------------------------------------------------------- kernel tables
class MotionTables(NamedTuple):
    """What the shading reads to place a hit at its ray's time (empty arrays where nothing moves)."""

    object_row: np.ndarray  # (O,) int32: object id → row of object_dec, -1 = static
    object_dec: np.ndarray  # (M, S, 16) float64
    instance_dec: np.ndarray  # (K, S, 16) float64, or (0, S, 16)
    vertices: np.ndarray  # (S, V, 3) float32 vertex steps, or (0, 0, 3)
    deforming: np.ndarray  # (O,) bool, or (0,)


def pack_motion(scene) -> MotionTables | None:
    """The :class:`MotionTables` of ``scene.motion`` (None without motion: the kernels' static path)."""
    mo = getattr(scene, "motion", None)
    if mo is None or not mo.moves:
        return None
    n_obj = int(max(scene.object_ids.max(initial=-1), mo.object_ids.max(initial=-1),
                    mo.deforming.max(initial=-1))) + 1
    row = np.full(max(n_obj, 1), -1, np.int32)
    row[mo.object_ids] = np.arange(len(mo.object_ids), dtype=np.int32)
    s = mo.steps
    deforming = np.zeros(max(n_obj, 1), np.bool_)
    deforming[mo.deforming] = True
    return MotionTables(object_row=row, object_dec=np.ascontiguousarray(decompose(mo.object_motion).reshape(-1, s, DEC)),
                        instance_dec=(np.ascontiguousarray(decompose(mo.instance_motion)) if mo.instance_motion
                                      is not None else np.zeros((0, s, DEC))),
                        vertices=mo.vertices if mo.vertices is not None else np.zeros((0, 0, 3), np.float32),
                        deforming=deforming)


@kernel(inline=True)
def _normal_rows(r0, r1, r2):
    """The cofactor matrix of the 3×3 part (rows r0..r2 of a 3×4), signed by its determinant: the inverse
    transpose up to a positive factor (normals are renormalised), and (its transpose / det) the inverse."""
    a, b, c = r0[0], r0[1], r0[2]
    d, e, f = r1[0], r1[1], r1[2]
    g, h, i = r2[0], r2[1], r2[2]
    c00, c01, c02 = e * i - f * h, f * g - d * i, d * h - e * g
    c10, c11, c12 = c * h - b * i, a * i - c * g, b * g - a * h
    c20, c21, c22 = b * f - c * e, c * d - a * f, a * e - b * d
    det = a * c00 + b * c01 + c * c02
    return (c00, c01, c02), (c10, c11, c12), (c20, c21, c22), det


@kernel(inline=True)
def _apply3(r0, r1, r2, v):
    return (r0[0] * v[0] + r0[1] * v[1] + r0[2] * v[2], r1[0] * v[0] + r1[1] * v[1] + r1[2] * v[2],
            r2[0] * v[0] + r2[1] * v[1] + r2[2] * v[2])


@kernel(inline=True)
def _apply3_t(r0, r1, r2, v):
    return (r0[0] * v[0] + r1[0] * v[1] + r2[0] * v[2], r0[1] * v[0] + r1[1] * v[1] + r2[1] * v[2],
            r0[2] * v[0] + r1[2] * v[1] + r2[2] * v[2])


@kernel(inline=True)
def _unit(v):
    ln = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return (v[0] / ln, v[1] / ln, v[2] / ln) if ln > 0.0 else v


@kernel(inline=True)
def place_ray(dec, row, tau, o, d):
    """A ray (origin ``o``, direction ``d``) placed by row ``row`` of ``dec`` at time ``tau``: the origin as a
    point, the direction as a vector, made unit again."""
    r0, r1, r2 = affine_at(dec, row, tau)
    p = _apply3(r0, r1, r2, o)
    return (p[0] + r0[3], p[1] + r1[3], p[2] + r2[3]), _unit(_apply3(r0, r1, r2, d))


@kernel(inline=True)
def _lerp_vertex(vsteps, k, index, f):
    """Vertex ``index`` between steps k and k + 1 at fraction f (Embree's linear vertex motion)."""
    return ((1.0 - f) * vsteps[k, index, 0] + f * vsteps[k + 1, index, 0],
            (1.0 - f) * vsteps[k, index, 1] + f * vsteps[k + 1, index, 1],
            (1.0 - f) * vsteps[k, index, 2] + f * vsteps[k + 1, index, 2])


@kernel(refcounts=False)
def frames_at_time(d, prim, inst, u, v, time, geom, tables, s_ng, s_n, s_front):
    """The surfaces stage's frames (geometric and shading normal, front face) of hits on what moves, recomputed at
    each ray's time τ (the static frames ``tracer.integrator.wavefront._surfaces`` wrote stay for everything else):

    - a moving object: D(τ) (:func:`affine_at`) takes its stored triangles to where the ray met them, so the frame
      is found in stored space (direction D⁻¹·d: the same side) and its normals taken out by D⁻ᵀ;
    - a moving instance: the same with its object-to-world M(τ);
    - a deforming object: the face normal of its corners interpolated at τ (the corner normals as stored)."""
    face_normals, normals, corner_ok, has_normals = geom.face_normals, geom.normals, geom.corner_ok, geom.has_normals
    object_ids, triangles, per_vertex = geom.object_ids, geom.triangles, geom.normals_per_vertex
    object_row, object_dec, instance_dec = tables.object_row, tables.object_dec, tables.instance_dec
    vsteps, deforming = tables.vertices, tables.deforming
    has_inst = instance_dec.shape[0] > 0
    for i in range(d.shape[0]):
        tri = prim[i]
        if tri < 0:
            continue
        k = inst[i]
        oid = object_ids[tri]
        if k >= 0:
            if not has_inst:
                continue
            dec, row = instance_dec, k
        else:
            if oid < deforming.shape[0] and deforming[oid]:
                row = -2
            elif oid < object_row.shape[0] and object_row[oid] >= 0:
                row = object_row[oid]
            else:
                continue
            dec = object_dec
        di = (float(d[i, 0]), float(d[i, 1]), float(d[i, 2]))
        ui, vi = float(u[i]), float(v[i])
        smooth = has_normals and corner_ok[tri]
        c = tri if smooth else 0
        n0, n1, n2 = corner_normals(normals, triangles, per_vertex and smooth, c)
        if row == -2:  # deforming: the corners at τ, as Embree interpolates the vertex steps
            steps = vsteps.shape[0]
            x = min(max(float(time[i]), 0.0), 1.0) * (steps - 1)
            ks = min(int(x), steps - 2)
            f = x - ks
            p0 = _lerp_vertex(vsteps, ks, triangles[tri, 0], f)
            p1 = _lerp_vertex(vsteps, ks, triangles[tri, 1], f)
            p2 = _lerp_vertex(vsteps, ks, triangles[tri, 2], f)
            e1 = (p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2])
            e2 = (p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2])
            fn = _unit((e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]))
            ng, n, front = shading_frame(fn, smooth, n0, n1, n2, di, ui, vi)
        else:
            fn = (float(face_normals[tri, 0]), float(face_normals[tri, 1]), float(face_normals[tri, 2]))
            r0, r1, r2 = affine_at(dec, row, float(time[i]))
            c0, c1, c2, det = _normal_rows(r0, r1, r2)
            sg = 1.0 if det >= 0.0 else -1.0
            d_in = _apply3_t(c0, c1, c2, di)  # ∝ M⁻¹·d (Cᵀ = det·M⁻¹)
            ng_o, n_o, front = shading_frame(fn, smooth, n0, n1, n2, (sg * d_in[0], sg * d_in[1], sg * d_in[2]),
                                             ui, vi)
            ng = _unit(_apply3(c0, c1, c2, (sg * ng_o[0], sg * ng_o[1], sg * ng_o[2])))
            n = _unit(_apply3(c0, c1, c2, (sg * n_o[0], sg * n_o[1], sg * n_o[2])))
            if n[0] * ng[0] + n[1] * ng[1] + n[2] * ng[2] <= 0.0:
                n = ng
        s_ng[i, 0], s_ng[i, 1], s_ng[i, 2] = ng
        s_n[i, 0], s_n[i, 1], s_n[i, 2] = n
        s_front[i] = front

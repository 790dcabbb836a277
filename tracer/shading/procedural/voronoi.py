"""Cycles' Voronoi Texture (Worley noise): every feature, metric and dimension, with Blender 4's fractal octaves.

Followed: ``intern/cycles/kernel/svm/voronoi.h`` (Blender 5.0) and the manual's Voronoi Texture page. The space is
cut into unit cells; each cell holds one point at cell + randomness · hash(cell): ``hash_float_to_float`` of a 1D
cell, the PCG hash ``hash_int{n}_to_float{n}`` of an n-D cell's integer coordinates (Blender 5.0; older Cycles hashed
float cells), see :mod:`.hash`; its colour is another hash of the cell. Features:

- F1 / F2: the distance to the nearest / second-nearest point, that point's cell colour and position (3×3×… cells);
- Smooth F1: Inigo Quilez' smooth minimum over the 5×5×… cells, smoothness/2 as its width;
- Distance to Edge: to the nearest bisector between the nearest point and another (the 3×3 window);
- N-Sphere Radius: half the distance from the nearest point to its own nearest point.

Metrics: Euclidean, Manhattan, Chebychev, Minkowski (exponent); 1D always |Δ|. Fractal (Blender ≥ 4.0): octaves up to
``ceil(detail)`` at scale lacunarityⁱ and amplitude roughnessⁱ, blended with lerps as Cycles does, normalised by the
summed amplitude × the largest possible distance. The algorithms are written once for 1-4 D on 4-tuples whose unused
components are zero (the neighbour loops collapse to one cell on unused axes).

VM entry point: :func:`voronoi_texture` (``p`` = (x, y, z, w) with the 1D texture reading p[0] = W). Returns
``(distance, (r, g, b), (px, py, pz), w_out, radius)``. :func:`voronoi_texture_array` is the numpy form.
"""

from __future__ import annotations

import math

import numpy as np

from ...jit import kernel
from .hash import (hash_float_to_float, hash_float_to_float3, hash_int2_to_float2, hash_int3_to_float3,
                   hash_int4_to_float4)
from .noise import _points4

F1, F2, SMOOTH_F1, DISTANCE_TO_EDGE, N_SPHERE_RADIUS = 0, 1, 2, 3, 4
FEATURES = {"F1": F1, "F2": F2, "SMOOTH_F1": SMOOTH_F1, "DISTANCE_TO_EDGE": DISTANCE_TO_EDGE,
            "N_SPHERE_RADIUS": N_SPHERE_RADIUS}
EUCLIDEAN, MANHATTAN, CHEBYCHEV, MINKOWSKI = 0, 1, 2, 3
METRICS = {"EUCLIDEAN": EUCLIDEAN, "MANHATTAN": MANHATTAN, "CHEBYCHEV": CHEBYCHEV, "MINKOWSKI": MINKOWSKI}
FLT_MAX = 3.4028234663852886e38


@kernel(inline="call")
def _add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3])


@kernel(inline="call")
def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3])


@kernel(inline="call")
def _scale(a, s):
    return (a[0] * s, a[1] * s, a[2] * s, a[3] * s)


@kernel(inline="call")
def _lerp4(a, b, t):
    return ((1.0 - t) * a[0] + t * b[0], (1.0 - t) * a[1] + t * b[1], (1.0 - t) * a[2] + t * b[2],
            (1.0 - t) * a[3] + t * b[3])


@kernel(inline="call")
def _lerp3(a, b, t):
    return ((1.0 - t) * a[0] + t * b[0], (1.0 - t) * a[1] + t * b[1], (1.0 - t) * a[2] + t * b[2])


@kernel(inline="call")
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]


@kernel
def distance(a, b, dim, metric, exponent):
    """Voronoi distance of two points (unused components zero); 1D is |b − a| whatever the metric."""
    d = _sub(a, b)
    if dim == 1:
        return abs(d[0])
    if metric == MANHATTAN:
        return abs(d[0]) + abs(d[1]) + abs(d[2]) + abs(d[3])
    if metric == CHEBYCHEV:
        return max(max(abs(d[0]), abs(d[1])), max(abs(d[2]), abs(d[3])))
    if metric == MINKOWSKI:
        s = 0.0
        for i in range(dim):
            s += abs(d[i]) ** exponent
        return s ** (1.0 / exponent)
    return math.sqrt(_dot(d, d))


@kernel
def cell_point(cell, dim):
    """The cell's random point offset in [0, 1]^dim: 1D hash_float_to_float of the cell, n-D the PCG hash
    hash_int{n}_to_float{n} of its integer coordinates (Blender 5.0)."""
    if dim == 1:
        return (hash_float_to_float(cell[0]), 0.0, 0.0, 0.0)
    if dim == 2:
        h = hash_int2_to_float2(int(cell[0]), int(cell[1]))
        return (h[0], h[1], 0.0, 0.0)
    if dim == 3:
        h3 = hash_int3_to_float3(int(cell[0]), int(cell[1]), int(cell[2]))
        return (h3[0], h3[1], h3[2], 0.0)
    return hash_int4_to_float4(int(cell[0]), int(cell[1]), int(cell[2]), int(cell[3]))


@kernel
def cell_color(cell, dim):
    """The cell's colour: 1D hash_float_to_float3; 2D the 3D PCG hash of (x, y, 0); 3D/4D the first three
    components of the PCG hash of the cell."""
    if dim == 1:
        return hash_float_to_float3(cell[0])
    if dim == 2:
        return hash_int3_to_float3(int(cell[0]), int(cell[1]), 0)
    if dim == 3:
        return hash_int3_to_float3(int(cell[0]), int(cell[1]), int(cell[2]))
    h = hash_int4_to_float4(int(cell[0]), int(cell[1]), int(cell[2]), int(cell[3]))
    return (h[0], h[1], h[2])


@kernel(inline="call")
def _span(dim, axis, r):
    """The neighbour offsets on ``axis``: -r..r where the axis is used, 0 elsewhere (as range bounds)."""
    return (-r, r + 1) if axis < dim else (0, 1)


@kernel(inline="call")
def _floor4(p):
    return (math.floor(p[0]), math.floor(p[1]), math.floor(p[2]), math.floor(p[3]))


@kernel
def voronoi_f1_f2(coord, dim, second, randomness, metric, exponent):
    """F1 (second=False) or F2 of one octave: (distance, colour, point position in texture space)."""
    cell = _floor4(coord)
    local = _sub(coord, cell)
    d1, d2 = FLT_MAX, FLT_MAX
    o1 = o2 = (0.0, 0.0, 0.0, 0.0)
    q1 = q2 = (0.0, 0.0, 0.0, 0.0)
    a0, a1 = _span(dim, 0, 1)
    b0, b1 = _span(dim, 1, 1)
    c0, c1 = _span(dim, 2, 1)
    e0, e1 = _span(dim, 3, 1)
    for u in range(e0, e1):
        for k in range(c0, c1):
            for j in range(b0, b1):
                for i in range(a0, a1):
                    off = (float(i), float(j), float(k), float(u))
                    pt = _add(off, _scale(cell_point(_add(cell, off), dim), randomness))
                    d = distance(pt, local, dim, metric, exponent)
                    if d < d1:
                        d2, o2, q2 = d1, o1, q1
                        d1, o1, q1 = d, off, pt
                    elif d < d2:
                        d2, o2, q2 = d, off, pt
    if second:
        return d2, cell_color(_add(cell, o2), dim), _add(q2, cell)
    return d1, cell_color(_add(cell, o1), dim), _add(q1, cell)


@kernel(inline="call")
def _smoothstep01(x):
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    return x * x * (3.0 - 2.0 * x)


@kernel
def voronoi_smooth_f1(coord, dim, smoothness, randomness, metric, exponent):
    """Smooth F1 of one octave (5×5×… cells, the smooth minimum of Inigo Quilez)."""
    cell = _floor4(coord)
    local = _sub(coord, cell)
    sd = 0.0
    sc = (0.0, 0.0, 0.0)
    sp = (0.0, 0.0, 0.0, 0.0)
    h = -1.0
    a0, a1 = _span(dim, 0, 2)
    b0, b1 = _span(dim, 1, 2)
    c0, c1 = _span(dim, 2, 2)
    e0, e1 = _span(dim, 3, 2)
    for u in range(e0, e1):
        for k in range(c0, c1):
            for j in range(b0, b1):
                for i in range(a0, a1):
                    off = (float(i), float(j), float(k), float(u))
                    pt = _add(off, _scale(cell_point(_add(cell, off), dim), randomness))
                    d = distance(pt, local, dim, metric, exponent)
                    h = 1.0 if h == -1.0 else _smoothstep01(0.5 + 0.5 * (sd - d) / smoothness)
                    corr = smoothness * h * (1.0 - h)
                    sd = (1.0 - h) * sd + h * d - corr
                    corr /= 1.0 + 3.0 * smoothness
                    c = cell_color(_add(cell, off), dim)
                    sc = _lerp3(sc, c, h)
                    sc = (sc[0] - corr, sc[1] - corr, sc[2] - corr)
                    sp = _lerp4(sp, pt, h)
                    sp = (sp[0] - corr, sp[1] - corr, sp[2] - corr, sp[3] - corr)
    # Cycles subtracts the correction from every component of the position, unused ones included; those stay 0.
    if dim < 4:
        sp = (sp[0], sp[1] if dim >= 2 else 0.0, sp[2] if dim >= 3 else 0.0, 0.0)
    return sd, sc, _add(cell, sp)


@kernel
def voronoi_distance_to_edge(coord, dim, randomness):
    """Distance to the nearest cell edge of one octave (Euclidean; Cycles ignores the metric here)."""
    cell = _floor4(coord)
    local = _sub(coord, cell)
    if dim == 1:
        mid = hash_float_to_float(cell[0]) * randomness
        left = -1.0 + hash_float_to_float(cell[0] - 1.0) * randomness
        right = 1.0 + hash_float_to_float(cell[0] + 1.0) * randomness
        return min(abs((mid + left) / 2.0 - local[0]), abs((mid + right) / 2.0 - local[0]))
    a0, a1 = _span(dim, 0, 1)
    b0, b1 = _span(dim, 1, 1)
    c0, c1 = _span(dim, 2, 1)
    e0, e1 = _span(dim, 3, 1)
    closest = (0.0, 0.0, 0.0, 0.0)
    dmin = FLT_MAX
    for u in range(e0, e1):
        for k in range(c0, c1):
            for j in range(b0, b1):
                for i in range(a0, a1):
                    off = (float(i), float(j), float(k), float(u))
                    v = _sub(_add(off, _scale(cell_point(_add(cell, off), dim), randomness)), local)
                    d = _dot(v, v)
                    if d < dmin:
                        dmin, closest = d, v
    dmin = FLT_MAX
    for u in range(e0, e1):
        for k in range(c0, c1):
            for j in range(b0, b1):
                for i in range(a0, a1):
                    off = (float(i), float(j), float(k), float(u))
                    v = _sub(_add(off, _scale(cell_point(_add(cell, off), dim), randomness)), local)
                    perp = _sub(v, closest)
                    pp = _dot(perp, perp)
                    if pp > 0.0001:
                        dmin = min(dmin, _dot(_scale(_add(closest, v), 0.5), _scale(perp, 1.0 / math.sqrt(pp))))
    return dmin


@kernel
def voronoi_n_sphere_radius(coord, dim, randomness):
    """Half the Euclidean distance from the nearest point to the point nearest to it."""
    cell = _floor4(coord)
    local = _sub(coord, cell)
    a0, a1 = _span(dim, 0, 1)
    b0, b1 = _span(dim, 1, 1)
    c0, c1 = _span(dim, 2, 1)
    e0, e1 = _span(dim, 3, 1)
    closest = (0.0, 0.0, 0.0, 0.0)
    closest_off = (0.0, 0.0, 0.0, 0.0)
    dmin = FLT_MAX
    for u in range(e0, e1):
        for k in range(c0, c1):
            for j in range(b0, b1):
                for i in range(a0, a1):
                    off = (float(i), float(j), float(k), float(u))
                    pt = _add(off, _scale(cell_point(_add(cell, off), dim), randomness))
                    d = distance(pt, local, dim, EUCLIDEAN, 1.0)
                    if d < dmin:
                        dmin, closest, closest_off = d, pt, off
    dmin = FLT_MAX
    other = (0.0, 0.0, 0.0, 0.0)
    for u in range(e0, e1):
        for k in range(c0, c1):
            for j in range(b0, b1):
                for i in range(a0, a1):
                    if i == 0 and j == 0 and k == 0 and u == 0:
                        continue
                    off = _add((float(i), float(j), float(k), float(u)), closest_off)
                    pt = _add(off, _scale(cell_point(_add(cell, off), dim), randomness))
                    d = distance(closest, pt, dim, EUCLIDEAN, 1.0)
                    if d < dmin:
                        dmin, other = d, pt
    return distance(other, closest, dim, EUCLIDEAN, 1.0) / 2.0


@kernel
def _octave(coord, dim, feature, smoothness, randomness, metric, exponent):
    if feature == F2:
        return voronoi_f1_f2(coord, dim, True, randomness, metric, exponent)
    if feature == SMOOTH_F1 and smoothness != 0.0:
        return voronoi_smooth_f1(coord, dim, smoothness, randomness, metric, exponent)
    return voronoi_f1_f2(coord, dim, False, randomness, metric, exponent)


@kernel
def max_distance(dim, feature, metric, exponent, randomness):
    """The largest F1 (F2: twice it) distance, the normalisation of Cycles (0.5 + 0.5 randomness per axis)."""
    a = 0.5 + 0.5 * randomness
    corner = (a, a if dim >= 2 else 0.0, a if dim >= 3 else 0.0, a if dim >= 4 else 0.0)
    d = distance((0.0, 0.0, 0.0, 0.0), corner, dim, metric, exponent)
    return d * 2.0 if feature == F2 else d


@kernel
def fractal_voronoi(coord, dim, feature, detail, roughness, lacunarity, smoothness, exponent, randomness, metric,
                    normalize, scale):
    """Blender 4's fractal F1/F2/Smooth F1: (distance, colour, position (4-tuple, texture space / scale))."""
    maxd = max_distance(dim, feature, metric, exponent, randomness)
    amplitude, max_amplitude, octave_scale = 1.0, 0.0, 1.0
    dist = 0.0
    col = (0.0, 0.0, 0.0)
    pos = (0.0, 0.0, 0.0, 0.0)
    zero_input = detail == 0.0 or roughness == 0.0
    n = int(math.ceil(detail))
    for i in range(n + 1):
        od, oc, op = _octave(_scale(coord, octave_scale), dim, feature, smoothness, randomness, metric, exponent)
        if zero_input:
            max_amplitude, dist, col, pos = 1.0, od, oc, op
            break
        if i <= detail:
            max_amplitude += amplitude
            dist += od * amplitude
            col = (col[0] + oc[0] * amplitude, col[1] + oc[1] * amplitude, col[2] + oc[2] * amplitude)
            pos = _lerp4(pos, _scale(op, 1.0 / octave_scale), amplitude)
            octave_scale *= lacunarity
            amplitude *= roughness
        else:
            rem = detail - math.floor(detail)
            if rem != 0.0:
                max_amplitude = (1.0 - rem) * max_amplitude + rem * (max_amplitude + amplitude)
                dist = (1.0 - rem) * dist + rem * (dist + od * amplitude)
                col = _lerp3(col, (col[0] + oc[0] * amplitude, col[1] + oc[1] * amplitude,
                                   col[2] + oc[2] * amplitude), rem)
                pos = _lerp4(pos, _lerp4(pos, _scale(op, 1.0 / octave_scale), amplitude), rem)
    if normalize:
        dist /= max_amplitude * maxd
        col = (col[0] / max_amplitude, col[1] / max_amplitude, col[2] / max_amplitude)
    inv = 1.0 / scale if scale != 0.0 else 0.0
    return dist, col, _scale(pos, inv)


@kernel
def fractal_voronoi_distance_to_edge(coord, dim, detail, roughness, lacunarity, randomness, normalize):
    """Blender 4's fractal Distance to Edge (octaves combined by a lerped minimum)."""
    maxd = 0.5 + 0.5 * randomness
    amplitude, max_amplitude, octave_scale, dist = 1.0, maxd, 1.0, 8.0
    zero_input = detail == 0.0 or roughness == 0.0
    n = int(math.ceil(detail))
    for i in range(n + 1):
        od = voronoi_distance_to_edge(_scale(coord, octave_scale), dim, randomness)
        if zero_input:
            dist = od
            break
        if i <= detail:
            max_amplitude = (1.0 - amplitude) * max_amplitude + amplitude * (maxd / octave_scale)
            dist = (1.0 - amplitude) * dist + amplitude * min(dist, od / octave_scale)
            octave_scale *= lacunarity
            amplitude *= roughness
        else:
            rem = detail - math.floor(detail)
            if rem != 0.0:
                lerp_amp = (1.0 - amplitude) * max_amplitude + amplitude * (maxd / octave_scale)
                max_amplitude = (1.0 - rem) * max_amplitude + rem * lerp_amp
                lerp_d = (1.0 - amplitude) * dist + amplitude * min(dist, od / octave_scale)
                dist = (1.0 - rem) * dist + rem * min(dist, lerp_d)
    if normalize:
        dist /= max_amplitude
    return dist


@kernel
def voronoi_texture(p, dim, feature, metric, scale, detail, roughness, lacunarity, smoothness, exponent,
                    randomness, normalize):
    """Cycles' Voronoi Texture node (``svm_node_tex_voronoi``) on p = (x, y, z, w); the 1D texture reads p[0] (W).

    Returns (distance, (r, g, b), (px, py, pz), w_out, radius): the outputs the feature defines, zeros elsewhere
    (Distance to Edge: distance only; N-Sphere Radius: radius only)."""
    detail = min(max(detail, 0.0), 15.0)
    roughness = min(max(roughness, 0.0), 1.0)
    randomness = min(max(randomness, 0.0), 1.0)
    smoothness = min(max(smoothness / 2.0, 0.0), 0.5)
    scale = float(scale)
    coord = (float(p[0]) * scale, float(p[1]) * scale, float(p[2]) * scale, float(p[3]) * scale)
    if dim < 4:  # the components a dimension does not read are exactly zero
        coord = (coord[0], coord[1] if dim >= 2 else 0.0, coord[2] if dim >= 3 else 0.0, 0.0)
    zero3 = (0.0, 0.0, 0.0)
    if feature == DISTANCE_TO_EDGE:
        d = fractal_voronoi_distance_to_edge(coord, dim, detail, roughness, lacunarity, randomness, normalize)
        return d, zero3, zero3, 0.0, 0.0
    if feature == N_SPHERE_RADIUS:
        return 0.0, zero3, zero3, 0.0, voronoi_n_sphere_radius(coord, dim, randomness)
    d, c, pos = fractal_voronoi(coord, dim, feature, detail, roughness, lacunarity, smoothness, exponent,
                                randomness, metric, normalize, scale)
    if dim == 1:  # a 1D position lives in W
        return d, c, zero3, pos[0], 0.0
    return d, c, (pos[0], pos[1], pos[2]), pos[3], 0.0


# ---------------------------------------------------------------------------------------------- numpy form
@kernel
def _voronoi_rows(pts, dim, feature, metric, params, normalize, dist, col, pos, w_out, radius):
    for i in range(pts.shape[0]):
        p = (pts[i, 0], pts[i, 1], pts[i, 2], pts[i, 3])
        d, c, q, w, r = voronoi_texture(p, dim, feature, metric, params[0], params[1], params[2], params[3],
                                        params[4], params[5], params[6], normalize)
        dist[i], w_out[i], radius[i] = d, w, r
        col[i, 0], col[i, 1], col[i, 2] = c
        pos[i, 0], pos[i, 1], pos[i, 2] = q


def voronoi_texture_array(vector, w=0.0, *, dimensions=3, feature="F1", distance="EUCLIDEAN", scale=5.0,
                          detail=0.0, roughness=0.5, lacunarity=2.0, smoothness=1.0, exponent=0.5,
                          randomness=1.0, normalize=False):
    """The Voronoi Texture node over arrays (Blender's defaults). ``vector`` (..., 3), ``w`` (...) or scalar.
    Returns a dict of float32 arrays: "Distance", "Color" (..., 3), "Position" (..., 3), "W", "Radius"."""
    if dimensions not in (1, 2, 3, 4):
        raise ValueError(f"voronoi dimensions must be 1-4, got {dimensions}")
    if feature not in FEATURES:
        raise ValueError(f"unknown voronoi feature {feature!r}; choose from {sorted(FEATURES)}")
    if distance not in METRICS:
        raise ValueError(f"unknown voronoi distance {distance!r}; choose from {sorted(METRICS)}")

    shape, pts = _points4(vector, w, dimensions)
    n = len(pts)
    dist, w_out, radius = np.empty(n), np.empty(n), np.empty(n)
    col, pos = np.empty((n, 3)), np.empty((n, 3))
    params = np.array([scale, detail, roughness, lacunarity, smoothness, exponent, randomness], np.float64)
    _voronoi_rows(pts, dimensions, FEATURES[feature], METRICS[distance], params, bool(normalize), dist, col, pos,
                  w_out, radius)
    f = np.float32
    return {"Distance": dist.reshape(shape).astype(f), "Color": col.reshape(shape + (3,)).astype(f),
            "Position": pos.reshape(shape + (3,)).astype(f), "W": w_out.reshape(shape).astype(f),
            "Radius": radius.reshape(shape).astype(f)}

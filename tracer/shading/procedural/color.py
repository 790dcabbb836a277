"""Cycles' colour nodes that are tables or spectra: Blackbody, Wavelength, Color Ramp, curves; and the numpy forms
(``*_array``) of every colour node, for tests and front ends.

The per-hit colour maths (HSV/HSL, Hue/Saturation/Value, RGB to BW, Mix's blend modes) is written once, in
:mod:`tracer.shading.ops`, which the VM runs and the compiler folds with; the ``*_array`` forms here call those same
functions, so the tests that compare them with Cycles (tests/test_procedural.py, tests/cycles/) prove the VM's code.

Followed (Blender 5.0): ``kernel/svm/math_util.h`` + ``kernel/tables.h`` (Blackbody's piecewise fit, the CIE 1931
colour-matching table of Wavelength), ``kernel/svm/wavelength.h``, ``kernel/svm/ramp.h`` (table lookups of Color Ramp
and the curve nodes), and Blender's ``blenkernel/intern/colorband.cc`` (how a Color Ramp is sampled into Cycles'
257-entry table: interpolations constant/linear/ease/cardinal/b-spline, colour modes RGB/HSV/HSL with near/far/cw/ccw
hue) with ``blenlib``'s own HSV/HSL (which differ in detail from Cycles').

Colours are 3-tuples in the scene-linear space, linear Rec.709 (Blender's default working space): Blackbody's fit
is Rec.709, Wavelength goes XYZ → Rec.709 (:mod:`tracer.colorspace`), RGB to BW uses its luminance weights.

Curves (RGB Curves, Vector Curves, Float Curve): Cycles never sees Blender's Bézier curve, only a 257-entry table
that Blender samples with ``CurveMapping.evaluate`` over [min x, max x] of the curves' points; the front end bakes
that table (:func:`curve_table_points` says where), and :func:`rgb_curves` / :func:`float_curve` read it as Cycles
does (linear between entries, optional linear extrapolation).
"""

from __future__ import annotations

import math

import numpy as np

from ...colorspace import REC709_LUMINANCE, XYZ_TO_REC709
from ...jit import kernel
from .. import ops

#: Size of the tables Blender samples a Color Ramp or a curve into for Cycles in Blender 5.0: 257 entries
#: (Blender's CM_TABLE + 1; measured: 257 matches Cycles to 130-160 dB, the 256 of older Cycles to 27-108 dB).
RAMP_TABLE_SIZE = 257

# Blackbody: Cycles' fit of the Planckian locus in Rec.709, a/T + bT + c for R and G, a cubic in T for B, on 7
# temperature ranges split at these temperatures (kernel/tables.h, Lukas Stockner's fit).
_BB_SPLITS = (965.0, 1167.0, 1449.0, 1902.0, 3315.0, 6365.0)
_BB_R = np.array([[1.61919106e+03, -2.05010916e-03, 5.02995757e+00], [2.48845471e+03, -1.11330907e-03, 3.22621544e+00],
                  [3.34143193e+03, -4.86551192e-04, 1.76486769e+00], [4.09461742e+03, -1.27446582e-04, 7.25731635e-01],
                  [4.67028036e+03, 2.91258199e-05, 1.26703442e-01], [4.59509185e+03, 2.87495649e-05, 1.50345020e-01],
                  [3.78717450e+03, 9.35907826e-06, 3.99075871e-01]], np.float32).astype(np.float64)
_BB_G = np.array([[-4.88999748e+02, 6.04330754e-04, -7.55807526e-02], [-7.55994277e+02, 3.16730098e-04, 4.78306139e-01],
                  [-1.02363977e+03, 1.20223470e-04, 9.36662319e-01], [-1.26571316e+03, 4.87340896e-06, 1.27054498e+00],
                  [-1.42529332e+03, -4.01150431e-05, 1.43972784e+00], [-1.17554822e+03, -2.16378048e-05, 1.30408023e+00],
                  [-5.00799571e+02, -4.59832026e-06, 1.09098763e+00]], np.float32).astype(np.float64)
_BB_B = np.array([[5.96945309e-11, -4.85742887e-08, -9.70622247e-05, -4.07936148e-03],
                  [2.40430366e-11, 5.55021075e-08, -1.98503712e-04, 2.89312858e-02],
                  [-1.40949732e-11, 1.89878968e-07, -3.56632824e-04, 9.10767778e-02],
                  [-3.61460868e-11, 2.84822009e-07, -4.93211319e-04, 1.56723440e-01],
                  [-1.97075738e-11, 1.75359352e-07, -2.50542825e-04, -2.22783266e-02],
                  [-1.61997957e-13, -1.64216008e-08, 3.86216271e-04, -7.38077418e-01],
                  [6.72650283e-13, -2.73078809e-08, 4.24098264e-04, -7.52335691e-01]], np.float32).astype(np.float64)
_BB_HOT = (0.8262954810464208, 0.9945080501520986, 1.566307710274283)  # T >= 12000 K
_BB_COLD = (5.413294490189271, -0.20319390035873933, -0.0822535242887164)  # T < 800 K

# CIE 1931 2° colour-matching functions x̄ ȳ z̄, 380..780 nm in 5 nm steps (4 decimals, as Cycles tabulates them).
_CIE = np.array([
    0.0014, 0.0000, 0.0065, 0.0022, 0.0001, 0.0105, 0.0042, 0.0001, 0.0201, 0.0076, 0.0002, 0.0362, 0.0143, 0.0004,
    0.0679, 0.0232, 0.0006, 0.1102, 0.0435, 0.0012, 0.2074, 0.0776, 0.0022, 0.3713, 0.1344, 0.0040, 0.6456, 0.2148,
    0.0073, 1.0391, 0.2839, 0.0116, 1.3856, 0.3285, 0.0168, 1.6230, 0.3483, 0.0230, 1.7471, 0.3481, 0.0298, 1.7826,
    0.3362, 0.0380, 1.7721, 0.3187, 0.0480, 1.7441, 0.2908, 0.0600, 1.6692, 0.2511, 0.0739, 1.5281, 0.1954, 0.0910,
    1.2876, 0.1421, 0.1126, 1.0419, 0.0956, 0.1390, 0.8130, 0.0580, 0.1693, 0.6162, 0.0320, 0.2080, 0.4652, 0.0147,
    0.2586, 0.3533, 0.0049, 0.3230, 0.2720, 0.0024, 0.4073, 0.2123, 0.0093, 0.5030, 0.1582, 0.0291, 0.6082, 0.1117,
    0.0633, 0.7100, 0.0782, 0.1096, 0.7932, 0.0573, 0.1655, 0.8620, 0.0422, 0.2257, 0.9149, 0.0298, 0.2904, 0.9540,
    0.0203, 0.3597, 0.9803, 0.0134, 0.4334, 0.9950, 0.0087, 0.5121, 1.0000, 0.0057, 0.5945, 0.9950, 0.0039, 0.6784,
    0.9786, 0.0027, 0.7621, 0.9520, 0.0021, 0.8425, 0.9154, 0.0018, 0.9163, 0.8700, 0.0017, 0.9786, 0.8163, 0.0014,
    1.0263, 0.7570, 0.0011, 1.0567, 0.6949, 0.0010, 1.0622, 0.6310, 0.0008, 1.0456, 0.5668, 0.0006, 1.0026, 0.5030,
    0.0003, 0.9384, 0.4412, 0.0002, 0.8544, 0.3810, 0.0002, 0.7514, 0.3210, 0.0001, 0.6424, 0.2650, 0.0000, 0.5419,
    0.2170, 0.0000, 0.4479, 0.1750, 0.0000, 0.3608, 0.1382, 0.0000, 0.2835, 0.1070, 0.0000, 0.2187, 0.0816, 0.0000,
    0.1649, 0.0610, 0.0000, 0.1212, 0.0446, 0.0000, 0.0874, 0.0320, 0.0000, 0.0636, 0.0232, 0.0000, 0.0468, 0.0170,
    0.0000, 0.0329, 0.0119, 0.0000, 0.0227, 0.0082, 0.0000, 0.0158, 0.0057, 0.0000, 0.0114, 0.0041, 0.0000, 0.0081,
    0.0029, 0.0000, 0.0058, 0.0021, 0.0000, 0.0041, 0.0015, 0.0000, 0.0029, 0.0010, 0.0000, 0.0020, 0.0007, 0.0000,
    0.0014, 0.0005, 0.0000, 0.0010, 0.0004, 0.0000, 0.0007, 0.0002, 0.0000, 0.0005, 0.0002, 0.0000, 0.0003, 0.0001,
    0.0000, 0.0002, 0.0001, 0.0000, 0.0002, 0.0001, 0.0000, 0.0001, 0.0000, 0.0000, 0.0001, 0.0000, 0.0000, 0.0001,
    0.0000, 0.0000, 0.0000, 0.0000, 0.0000], np.float32).astype(np.float64).reshape(81, 3)
#: Wavelength's empirical scale (Cycles: keeps every component ≤ 1).
_WAVELENGTH_SCALE = 1.0 / 2.52


# ---------------------------------------------------------------------------------------------- Cycles' HSV / HSL
@kernel
def blackbody_rec709(t):
    """Cycles' blackbody colour in Rec.709 before clamping (svm_math_blackbody_color_rec709): a fit whose
    luminance is about 1 (it is not normalised to white at 6500 K: there it is (1.043, 0.984, 1.035))."""
    if t >= 12000.0:
        return _BB_HOT
    if t < 800.0:
        return _BB_COLD
    i = 0
    for split in _BB_SPLITS:
        if t >= split:
            i += 1
    t_inv = 1.0 / t
    r = _BB_R[i, 0] * t_inv + _BB_R[i, 1] * t + _BB_R[i, 2]
    g = _BB_G[i, 0] * t_inv + _BB_G[i, 1] * t + _BB_G[i, 2]
    b = ((_BB_B[i, 0] * t + _BB_B[i, 1]) * t + _BB_B[i, 2]) * t + _BB_B[i, 3]
    return (r, g, b)


@kernel
def blackbody(temperature):
    """The Blackbody node (K -> linear Rec.709 colour, negative components clamped to 0)."""
    r, g, b = blackbody_rec709(temperature)
    return (max(r, 0.0), max(g, 0.0), max(b, 0.0))


@kernel
def wavelength(nm):
    """The Wavelength node: CIE 1931 x̄ȳz̄ at ``nm`` (linear between the 5 nm samples, black outside 380-780 nm)
    -> linear Rec.709, scaled by 1/2.52, negative components clamped to 0."""
    ii = (nm - 380.0) * (1.0 / 5.0)
    i = int(ii) if ii > -1.0 else -1  # C's float-to-int truncation
    if i < 0 or i >= 80:
        return (0.0, 0.0, 0.0)
    f = ii - i
    x = (1.0 - f) * _CIE[i, 0] + f * _CIE[i + 1, 0]
    y = (1.0 - f) * _CIE[i, 1] + f * _CIE[i + 1, 1]
    z = (1.0 - f) * _CIE[i, 2] + f * _CIE[i + 1, 2]
    m = XYZ_TO_REC709
    r = (m[0][0] * x + m[0][1] * y + m[0][2] * z) * _WAVELENGTH_SCALE
    g = (m[1][0] * x + m[1][1] * y + m[1][2] * z) * _WAVELENGTH_SCALE
    b = (m[2][0] * x + m[2][1] * y + m[2][2] * z) * _WAVELENGTH_SCALE
    return (max(r, 0.0), max(g, 0.0), max(b, 0.0))


# ---------------------------------------------------------------------------------------------- Color Ramp
CONSTANT, LINEAR_I, EASE, CARDINAL, B_SPLINE = 0, 1, 2, 3, 4
RAMP_INTERPOLATIONS = {"CONSTANT": CONSTANT, "LINEAR": LINEAR_I, "EASE": EASE, "CARDINAL": CARDINAL,
                       "B_SPLINE": B_SPLINE}
RAMP_RGB, RAMP_HSV, RAMP_HSL = 0, 1, 2
RAMP_COLOR_MODES = {"RGB": RAMP_RGB, "HSV": RAMP_HSV, "HSL": RAMP_HSL}
HUE_NEAR, HUE_FAR, HUE_CW, HUE_CCW = 0, 1, 2, 3
RAMP_HUE_INTERPOLATIONS = {"NEAR": HUE_NEAR, "FAR": HUE_FAR, "CW": HUE_CW, "CCW": HUE_CCW}


def _bli_rgb_to_hsv(r, g, b):
    """Blender's blenlib rgb_to_hsv (used by Color Ramp's HSV mode; not Cycles')."""
    k = 0.0
    if g < b:
        g, b = b, g
        k = -1.0
    min_gb = b
    if r < g:
        r, g = g, r
        k = -2.0 / 6.0 - k
        min_gb = min(g, b)
    chroma = r - min_gb
    return abs(k + (g - b) / (6.0 * chroma + 1e-20)), chroma / (r + 1e-20), r


def _bli_hsv_to_rgb(h, s, v):
    nr = min(max(abs(h * 6.0 - 3.0) - 1.0, 0.0), 1.0)
    ng = min(max(2.0 - abs(h * 6.0 - 2.0), 0.0), 1.0)
    nb = min(max(2.0 - abs(h * 6.0 - 4.0), 0.0), 1.0)
    return ((nr - 1.0) * s + 1.0) * v, ((ng - 1.0) * s + 1.0) * v, ((nb - 1.0) * s + 1.0) * v


def _bli_rgb_to_hsl(r, g, b):
    cmax, cmin = max(r, g, b), min(r, g, b)
    lum = min(1.0, (cmax + cmin) / 2.0)
    if cmax == cmin:
        return 0.0, 0.0, lum
    d = cmax - cmin
    s = d / (2.0 - cmax - cmin) if lum > 0.5 else d / (cmax + cmin)
    if cmax == r:
        h = (g - b) / d + (6.0 if g < b else 0.0)
    elif cmax == g:
        h = (b - r) / d + 2.0
    else:
        h = (r - g) / d + 4.0
    return h / 6.0, s, lum


def _bli_hsl_to_rgb(h, s, lum):
    nr = min(max(abs(h * 6.0 - 3.0) - 1.0, 0.0), 1.0)
    ng = min(max(2.0 - abs(h * 6.0 - 2.0), 0.0), 1.0)
    nb = min(max(2.0 - abs(h * 6.0 - 4.0), 0.0), 1.0)
    chroma = (1.0 - abs(2.0 * lum - 1.0)) * s
    return (nr - 0.5) * chroma + lum, (ng - 0.5) * chroma + lum, (nb - 0.5) * chroma + lum


def _hue_interp(mode, mfac, fac, h1, h2):
    """Blender's colorband_hue_interp: the hue path NEAR / FAR / CW / CCW between two stops."""
    h1 = h1 if h1 < 1.0 else h1 - 1.0
    h2 = h2 if h2 < 1.0 else h2 - 1.0
    way = 0
    if mode == HUE_NEAR:
        way = 1 if (h1 < h2 and h2 - h1 > 0.5) else 2 if (h1 > h2 and h2 - h1 < -0.5) else 0
    elif mode == HUE_FAR:
        way = 1 if h1 == h2 else 1 if (h1 < h2 and h2 - h1 < 0.5) else 2 if (h1 > h2 and h2 - h1 > -0.5) else 0
    elif mode == HUE_CCW:
        way = 2 if h1 > h2 else 0
    elif mode == HUE_CW:
        way = 1 if h1 < h2 else 0
    if way == 0:
        return mfac * h1 + fac * h2
    h = mfac * (h1 + 1.0) + fac * h2 if way == 1 else mfac * h1 + fac * (h2 + 1.0)
    return h if h < 1.0 else h - 1.0


def _spline_weights(t, cardinal):
    """Blender's key_curve_position_weights: KEY_CARDINAL (tension 0.71) or KEY_BSPLINE."""
    t2, t3 = t * t, t * t * t
    if cardinal:
        fc = 0.71
        return (-fc * t3 + 2.0 * fc * t2 - fc * t, (2.0 - fc) * t3 + (fc - 3.0) * t2 + 1.0,
                (fc - 2.0) * t3 + (3.0 - 2.0 * fc) * t2 + fc * t, fc * t3 - fc * t2)
    return (-0.16666666 * t3 + 0.5 * t2 - 0.5 * t + 0.16666666, 0.5 * t3 - t2 + 0.66666666,
            -0.5 * t3 + 0.5 * t2 + 0.5 * t + 0.16666666, 0.16666666 * t3)


def colorband_evaluate(positions, colors, x, interpolation="LINEAR", color_mode="RGB", hue_interpolation="NEAR"):
    """Blender's BKE_colorband_evaluate: the ramp's RGBA at ``x`` from its stops (positions sorted ascending,
    colors (N, 4)). Interpolations and colour modes as Blender's Color Ramp; HSV/HSL modes interpolate linearly."""
    pos = [float(p) for p in positions]
    cols = [tuple(float(c) for c in col[:4]) for col in colors]
    n = len(pos)
    if n == 0:
        raise ValueError("a color ramp needs at least one stop")
    mode = RAMP_COLOR_MODES[color_mode]
    ipo = RAMP_INTERPOLATIONS[interpolation] if mode == RAMP_RGB else LINEAR_I
    simple = ipo in (LINEAR_I, EASE, CONSTANT)
    if n == 1 or (x <= pos[0] and simple):
        return cols[0]
    a = 0
    while a < n and not pos[a] > x:
        a += 1
    # cbd1 = the first stop right of x (a virtual copy at 1 past the end), cbd2 = the one before it
    if a == n:
        i2 = n - 1
        p1, c1 = 1.0, cols[n - 1]
        p2, c2 = pos[i2], cols[i2]
    elif a == 0:
        p1, c1 = pos[0], cols[0]
        p2, c2 = 0.0, cols[0]
        i2 = -1
    else:
        p1, c1 = pos[a], cols[a]
        p2, c2 = pos[a - 1], cols[a - 1]
        i2 = a - 1
    if a == n and simple:
        return c2
    if ipo == CONSTANT:
        return c2
    if p2 != p1:
        fac = (x - p1) / (p2 - p1)
    else:
        fac = 0.0 if a != n else 1.0
    if ipo in (B_SPLINE, CARDINAL):
        c0 = c1 if a >= n - 1 else cols[a + 1]
        c3 = c2 if a < 2 else cols[a - 2]
        fac = min(max(fac, 0.0), 1.0)
        t = _spline_weights(fac, ipo == CARDINAL)
        return tuple(min(max(t[3] * c3[k] + t[2] * c2[k] + t[1] * c1[k] + t[0] * c0[k], 0.0), 1.0) for k in range(4))
    if ipo == EASE:
        f2 = fac * fac
        fac = 3.0 * f2 - 2.0 * f2 * fac
    mfac = 1.0 - fac
    alpha = mfac * c1[3] + fac * c2[3]
    if mode == RAMP_RGB:
        return tuple(mfac * c1[k] + fac * c2[k] for k in range(3)) + (alpha,)
    to_hue, from_hue = (_bli_rgb_to_hsv, _bli_hsv_to_rgb) if mode == RAMP_HSV else (_bli_rgb_to_hsl, _bli_hsl_to_rgb)
    h1, h2 = to_hue(*c1[:3]), to_hue(*c2[:3])
    h = _hue_interp(RAMP_HUE_INTERPOLATIONS[hue_interpolation], mfac, fac, h1[0], h2[0])
    return from_hue(h, mfac * h1[1] + fac * h2[1], mfac * h1[2] + fac * h2[2]) + (alpha,)


def color_ramp_table(positions, colors, interpolation="LINEAR", color_mode="RGB", hue_interpolation="NEAR",
                     size=RAMP_TABLE_SIZE) -> np.ndarray:
    """The (size, 4) float32 table Blender hands Cycles for a Color Ramp: the ramp sampled at i / (size − 1)."""
    return np.array([colorband_evaluate(positions, colors, i / (size - 1), interpolation, color_mode,
                                        hue_interpolation) for i in range(size)], np.float32)


@kernel(inline="call")
def _entry(table, i, k):
    return float(table[i, k]) if k < table.shape[1] else 0.0


@kernel(inline="call")
def _extrap(table, i0, i1, k, s):
    t0 = _entry(table, i0, k)
    return t0 + (t0 - _entry(table, i1, k)) * s


@kernel(inline="call")
def _interp(table, i, j, k, t):
    a = _entry(table, i, k)
    return a if t == 0.0 else (1.0 - t) * a + t * _entry(table, j, k)


@kernel
def ramp_lookup(table, f, interpolate, extrapolate):
    """Cycles' rgb_ramp_lookup on a (N, C) table at f in [0, 1]: entry int(f·(N−1)), linear to the next one when
    ``interpolate`` (a Color Ramp with CONSTANT interpolation does not); outside [0, 1] either clamped or, with
    ``extrapolate``, continued along the end segment. Returns a 4-tuple (unused channels 0)."""
    n = table.shape[0]
    if (f < 0.0 or f > 1.0) and extrapolate:
        if f < 0.0:
            i0, i1, g = 0, 1, -f
        else:
            i0, i1, g = n - 1, n - 2, f - 1.0
        s = g * (n - 1)
        return (_extrap(table, i0, i1, 0, s), _extrap(table, i0, i1, 1, s), _extrap(table, i0, i1, 2, s),
                _extrap(table, i0, i1, 3, s))
    f = min(max(f, 0.0), 1.0) * (n - 1)
    if f != f:
        f = 0.0
    i = min(max(int(f), 0), n - 1)
    t = f - i
    if not interpolate or t <= 0.0:
        t = 0.0
    j = min(i + 1, n - 1)
    return (_interp(table, i, j, 0, t), _interp(table, i, j, 1, t), _interp(table, i, j, 2, t),
            _interp(table, i, j, 3, t))


@kernel
def color_ramp(table, fac, interpolate):
    """The Color Ramp node on its baked (N, 4) table: ((r, g, b), alpha). ``interpolate`` = not CONSTANT."""
    c = ramp_lookup(table, fac, interpolate, False)
    return (c[0], c[1], c[2]), c[3]


# ---------------------------------------------------------------------------------------------- curves
def curve_table_points(min_x, max_x, size=RAMP_TABLE_SIZE) -> np.ndarray:
    """Where Blender samples a curve mapping for Cycles: min_x + i / (size − 1) · (max_x − min_x). min_x / max_x are
    the smallest first-point x and largest last-point x over the curves (C, R, G, B for RGB Curves; X, Y, Z for
    Vector Curves). RGB Curves' table row i is (R(C(t)), G(C(t)), B(C(t))); Vector Curves' (X(t), Y(t), Z(t))."""
    return (np.float32(min_x) + np.arange(size, dtype=np.float32) / np.float32(size - 1)
            * (np.float32(max_x) - np.float32(min_x)))


@kernel
def rgb_curves(table, color, fac, min_x, max_x, extrapolate):
    """RGB Curves and Vector Curves (Cycles' svm_node_curves): each component c looks up its own column at
    (c − min_x) / (max_x − min_x), interpolated; the result mixed with the input by fac."""
    rng = max_x - min_x
    r = ramp_lookup(table, (color[0] - min_x) / rng, True, extrapolate)[0]
    g = ramp_lookup(table, (color[1] - min_x) / rng, True, extrapolate)[1]
    b = ramp_lookup(table, (color[2] - min_x) / rng, True, extrapolate)[2]
    return ((1.0 - fac) * color[0] + fac * r, (1.0 - fac) * color[1] + fac * g, (1.0 - fac) * color[2] + fac * b)


@kernel
def float_curve(table, value, fac, min_x, max_x, extrapolate):
    """Float Curve (Cycles' svm_node_curve) on its (N, 1) table."""
    v = ramp_lookup(table, (value - min_x) / (max_x - min_x), True, extrapolate)[0]
    return (1.0 - fac) * value + fac * v


# ---------------------------------------------------------------------------------------------- numpy forms
def _rows(c):
    c = np.asarray(c, np.float64)
    return c.shape[:-1], np.ascontiguousarray(c[..., :3].reshape(-1, 3))


@kernel
def _hsv_rows(cols, params, out):
    for i in range(cols.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = ops.hue_sat(params[i, 0], params[i, 1], params[i, 2], params[i, 3],
                                                      cols[i, 0], cols[i, 1], cols[i, 2])


def hue_saturation_value_array(color, hue=0.5, saturation=1.0, value=1.0, fac=1.0):
    shape, cols = _rows(color)
    params = np.ascontiguousarray(np.stack([np.broadcast_to(np.asarray(x, np.float64), shape).reshape(-1)
                                            for x in (hue, saturation, value, fac)], -1))
    out = np.empty_like(cols)
    _hsv_rows(cols, params, out)
    return out.reshape(shape + (3,)).astype(np.float32)


@kernel
def _conv_rows(cols, mode, out):
    for i in range(cols.shape[0]):
        x, y, z = cols[i, 0], cols[i, 1], cols[i, 2]
        if mode == 0:
            r = ops.rgb_to_hsv(x, y, z)
        elif mode == 1:
            r = ops.hsv_to_rgb(x, y, z)
        elif mode == 2:
            r = ops.rgb_to_hsl(x, y, z)
        else:
            r = ops.hsl_to_rgb(x, y, z)
        out[i, 0], out[i, 1], out[i, 2] = r


def convert_array(color, conversion):
    """Separate/Combine Color's conversions over (..., 3): "rgb_to_hsv", "hsv_to_rgb", "rgb_to_hsl", "hsl_to_rgb"."""
    modes = {"rgb_to_hsv": 0, "hsv_to_rgb": 1, "rgb_to_hsl": 2, "hsl_to_rgb": 3}
    shape, cols = _rows(color)
    out = np.empty_like(cols)
    _conv_rows(cols, modes[conversion], out)
    return out.reshape(shape + (3,)).astype(np.float32)


@kernel
def _scalar_rows(x, mode, out):
    for i in range(x.shape[0]):
        c = blackbody(x[i]) if mode == 0 else wavelength(x[i])
        out[i, 0], out[i, 1], out[i, 2] = c


def blackbody_array(temperature):
    t = np.asarray(temperature, np.float64)
    out = np.empty((t.size, 3))
    _scalar_rows(np.ascontiguousarray(t.reshape(-1)), 0, out)
    return out.reshape(t.shape + (3,)).astype(np.float32)


def wavelength_array(nm):
    t = np.asarray(nm, np.float64)
    out = np.empty((t.size, 3))
    _scalar_rows(np.ascontiguousarray(t.reshape(-1)), 1, out)
    return out.reshape(t.shape + (3,)).astype(np.float32)


def rgb_to_bw_array(color):
    c = np.asarray(color, np.float64)[..., :3]
    return (c @ np.asarray(REC709_LUMINANCE)).astype(np.float32)


@kernel
def _mix_rows(blend, fac, a, b, clamp_factor, clamp_result, out):
    for i in range(a.shape[0]):
        t = min(max(fac[i], 0.0), 1.0) if clamp_factor else fac[i]
        x, y, z = ops.mix_blend(blend, t, a[i, 0], a[i, 1], a[i, 2], b[i, 0], b[i, 1], b[i, 2])
        if clamp_result:
            x, y, z = min(max(x, 0.0), 1.0), min(max(y, 0.0), 1.0), min(max(z, 0.0), 1.0)
        out[i, 0], out[i, 1], out[i, 2] = x, y, z


def mix_color_array(blend_type, fac, a, b, clamp_factor=True, clamp_result=False):
    """The Mix node (Color) over arrays: a, b (..., 3), fac (...) or scalar."""
    shape = np.broadcast_shapes(np.shape(a)[:-1], np.shape(b)[:-1], np.shape(fac))
    aa = np.ascontiguousarray(np.broadcast_to(np.asarray(a, np.float64)[..., :3], shape + (3,)).reshape(-1, 3))
    bb = np.ascontiguousarray(np.broadcast_to(np.asarray(b, np.float64)[..., :3], shape + (3,)).reshape(-1, 3))
    ff = np.ascontiguousarray(np.broadcast_to(np.asarray(fac, np.float64), shape).reshape(-1))
    out = np.empty_like(aa)
    _mix_rows(ops.BLEND_TYPES.index(blend_type), ff, aa, bb, bool(clamp_factor), bool(clamp_result), out)
    return out.reshape(shape + (3,)).astype(np.float32)


@kernel
def _mix_vector_rows(fac, a, b, clamp_factor, out):
    for i in range(a.shape[0]):
        for j in range(3):
            t = min(max(fac[i, j], 0.0), 1.0) if clamp_factor else fac[i, j]
            out[i, j] = (1.0 - t) * a[i, j] + t * b[i, j]


def mix_vector_array(fac, a, b, clamp_factor=True):
    """The Mix node (Vector) over arrays: fac (...) uniform or (..., 3) non-uniform; a, b (..., 3)."""
    fac = np.asarray(fac, np.float64)
    if fac.ndim < np.ndim(a):
        fac = fac[..., None]
    shape = np.broadcast_shapes(np.shape(a)[:-1], np.shape(b)[:-1], fac.shape[:-1])
    ff, aa, bb = (np.ascontiguousarray(np.broadcast_to(np.asarray(x, np.float64)[..., :3] if x is not fac else
                                                       np.broadcast_to(fac, fac.shape[:-1] + (3,)), shape + (3,))
                                       .reshape(-1, 3)) for x in (fac, a, b))
    out = np.empty_like(aa)
    _mix_vector_rows(ff, aa, bb, bool(clamp_factor), out)
    return out.reshape(shape + (3,)).astype(np.float32)


def mix_float_array(fac, a, b, clamp_factor=True):
    """The Mix node (Float) over arrays (numpy; the VM's mix_f instruction)."""
    t = np.asarray(fac, np.float64)
    t = np.clip(t, 0.0, 1.0) if clamp_factor else t
    return (np.asarray(a, np.float64) * (1.0 - t) + np.asarray(b, np.float64) * t).astype(np.float32)


@kernel
def _ramp_rows(table, fac, interpolate, out):
    for i in range(fac.shape[0]):
        c = ramp_lookup(table, fac[i], interpolate, False)
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = c


def color_ramp_array(fac, table, interpolate=True):
    """Color Ramp lookups over an array of factors -> (..., 4) RGBA."""
    f = np.asarray(fac, np.float64)
    out = np.empty((f.size, 4))
    _ramp_rows(np.ascontiguousarray(table, np.float64), np.ascontiguousarray(f.reshape(-1)), bool(interpolate), out)
    return out.reshape(f.shape + (4,)).astype(np.float32)


@kernel
def _curve_rows(table, cols, fac, min_x, max_x, extrapolate, out):
    for i in range(cols.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = rgb_curves(table, (cols[i, 0], cols[i, 1], cols[i, 2]), fac, min_x,
                                                     max_x, extrapolate)


def rgb_curves_array(color, table, fac=1.0, min_x=0.0, max_x=1.0, extrapolate=True):
    """RGB / Vector Curves over (..., 3) with the baked (N, 3) table."""
    shape, cols = _rows(color)
    out = np.empty_like(cols)
    _curve_rows(np.ascontiguousarray(table, np.float64), cols, float(fac), float(min_x), float(max_x),
                bool(extrapolate), out)
    return out.reshape(shape + (3,)).astype(np.float32)


@kernel
def _float_curve_rows(table, vals, fac, min_x, max_x, extrapolate, out):
    for i in range(vals.shape[0]):
        out[i] = float_curve(table, vals[i], fac, min_x, max_x, extrapolate)


def float_curve_array(value, table, fac=1.0, min_x=0.0, max_x=1.0, extrapolate=True):
    v = np.asarray(value, np.float64)
    out = np.empty(v.size)
    tab = np.ascontiguousarray(np.asarray(table, np.float64).reshape(len(table), -1))
    _float_curve_rows(tab, np.ascontiguousarray(v.reshape(-1)), float(fac), float(min_x), float(max_x),
                      bool(extrapolate), out)
    return out.reshape(v.shape).astype(np.float32)

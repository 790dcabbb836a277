"""The scalar maths of the shader VM's nodes, as Cycles defines them (``kernel/svm/math_util.h``,
``color_util.h``, ``mix.h``, ``map_range.h``, ``ramp.h``): one numba function per node family, called by the VM per
hit (:mod:`tracer.shading.vm`) and, from Python, by the compiler to fold constants (so a folded node and an evaluated
one cannot disagree). Operation codes are the positions of Blender's enum names in
:data:`tracer.shading.graph.ENUMS`.
"""

from __future__ import annotations

import math

from .. import vec
from ..jit import kernel

# math.operation codes (ENUMS["math.operation"] order)
(M_ADD, M_SUBTRACT, M_MULTIPLY, M_DIVIDE, M_MULTIPLY_ADD, M_POWER, M_LOGARITHM, M_SQRT, M_INVERSE_SQRT, M_ABSOLUTE,
 M_EXPONENT, M_MINIMUM, M_MAXIMUM, M_LESS_THAN, M_GREATER_THAN, M_SIGN, M_COMPARE, M_SMOOTH_MIN, M_SMOOTH_MAX,
 M_ROUND, M_FLOOR, M_CEIL, M_TRUNC, M_FRACT, M_MODULO, M_FLOORED_MODULO, M_WRAP, M_SNAP, M_PINGPONG, M_SINE,
 M_COSINE, M_TANGENT, M_ARCSINE, M_ARCCOSINE, M_ARCTANGENT, M_ARCTAN2, M_SINH, M_COSH, M_TANH, M_RADIANS,
 M_DEGREES) = range(41)

# vector_math.operation codes
(V_ADD, V_SUBTRACT, V_MULTIPLY, V_DIVIDE, V_MULTIPLY_ADD, V_CROSS_PRODUCT, V_PROJECT, V_REFLECT, V_REFRACT,
 V_FACEFORWARD, V_DOT_PRODUCT, V_DISTANCE, V_LENGTH, V_SCALE, V_NORMALIZE, V_ABSOLUTE, V_POWER, V_SIGN, V_MINIMUM,
 V_MAXIMUM, V_FLOOR, V_CEIL, V_FRACTION, V_MODULO, V_WRAP, V_SNAP, V_SINE, V_COSINE, V_TANGENT) = range(29)

#: Mix Color's blend modes (Blender's names; the codes are their positions)
BLEND_TYPES = ("MIX", "DARKEN", "MULTIPLY", "BURN", "LIGHTEN", "SCREEN", "DODGE", "ADD", "OVERLAY", "SOFT_LIGHT",
               "LINEAR_LIGHT", "DIFFERENCE", "EXCLUSION", "SUBTRACT", "DIVIDE", "HUE", "SATURATION", "COLOR", "VALUE")
(B_MIX, B_DARKEN, B_MULTIPLY, B_BURN, B_LIGHTEN, B_SCREEN, B_DODGE, B_ADD, B_OVERLAY, B_SOFT_LIGHT, B_LINEAR_LIGHT,
 B_DIFFERENCE, B_EXCLUSION, B_SUBTRACT, B_DIVIDE, B_HUE, B_SATURATION, B_COLOR, B_VALUE) = range(19)


@kernel(inline=True)
def safe_divide(a, b):
    return a / b if b != 0.0 else 0.0


@kernel(inline=True)
def _safe_pow(a, b):
    if a < 0.0 and b != math.floor(b):
        return 0.0
    if a == 0.0 and b < 0.0:
        return 0.0
    return a ** b


@kernel(inline=True)
def _fract(a):
    return a - math.floor(a)


@kernel(inline=True)
def _wrap(v, hi, lo):
    r = hi - lo
    return v - r * math.floor((v - lo) / r) if r != 0.0 else lo


@kernel(inline=True)
def _smoothmin(a, b, c):
    if c != 0.0:
        h = max(c - abs(a - b), 0.0) / c
        return min(a, b) - h * h * h * c * (1.0 / 6.0)
    return min(a, b)


@kernel(inline=True)
def _sign(a):
    return 1.0 if a > 0.0 else (-1.0 if a < 0.0 else 0.0)


@kernel(inline=True)
def _fmod(a, b):
    if b == 0.0:
        return 0.0
    q = a / b
    return a - (math.floor(q) if q >= 0.0 else math.ceil(q)) * b  # C's fmod: the quotient truncated


@kernel
def math_op(op, a, b, c):
    """Blender's Math node (``svm_math``), operation code ``op``."""
    if op == M_ADD:
        return a + b
    if op == M_SUBTRACT:
        return a - b
    if op == M_MULTIPLY:
        return a * b
    if op == M_DIVIDE:
        return safe_divide(a, b)
    if op == M_MULTIPLY_ADD:
        return a * b + c
    if op == M_POWER:
        return _safe_pow(a, b)
    if op == M_LOGARITHM:
        return math.log(a) / math.log(b) if a > 0.0 and b > 0.0 and b != 1.0 else 0.0
    if op == M_SQRT:
        return math.sqrt(a) if a > 0.0 else 0.0
    if op == M_INVERSE_SQRT:
        return 1.0 / math.sqrt(a) if a > 0.0 else 0.0
    if op == M_ABSOLUTE:
        return abs(a)
    if op == M_EXPONENT:
        return math.exp(min(a, 700.0))
    if op == M_MINIMUM:
        return min(a, b)
    if op == M_MAXIMUM:
        return max(a, b)
    if op == M_LESS_THAN:
        return 1.0 if a < b else 0.0
    if op == M_GREATER_THAN:
        return 1.0 if a > b else 0.0
    if op == M_SIGN:
        return _sign(a)
    if op == M_COMPARE:
        return 1.0 if abs(a - b) <= max(c, 1e-5) else 0.0
    if op == M_SMOOTH_MIN:
        return _smoothmin(a, b, c)
    if op == M_SMOOTH_MAX:
        return -_smoothmin(-a, -b, c)
    if op == M_ROUND:
        return math.floor(a + 0.5)
    if op == M_FLOOR:
        return math.floor(a)
    if op == M_CEIL:
        return math.ceil(a)
    if op == M_TRUNC:
        return math.floor(a) if a >= 0.0 else math.ceil(a)
    if op == M_FRACT:
        return _fract(a)
    if op == M_MODULO:
        return _fmod(a, b)
    if op == M_FLOORED_MODULO:
        return a - math.floor(a / b) * b if b != 0.0 else 0.0
    if op == M_WRAP:
        return _wrap(a, b, c)
    if op == M_SNAP:
        return math.floor(safe_divide(a, b)) * b
    if op == M_PINGPONG:
        return abs(_fract((a - b) / (b * 2.0)) * b * 2.0 - b) if b != 0.0 else 0.0
    if op == M_SINE:
        return math.sin(a)
    if op == M_COSINE:
        return math.cos(a)
    if op == M_TANGENT:
        return math.tan(a)
    if op == M_ARCSINE:
        return math.asin(min(max(a, -1.0), 1.0))
    if op == M_ARCCOSINE:
        return math.acos(min(max(a, -1.0), 1.0))
    if op == M_ARCTANGENT:
        return math.atan(a)
    if op == M_ARCTAN2:
        return math.atan2(a, b)
    if op == M_SINH:
        return math.sinh(min(max(a, -700.0), 700.0))
    if op == M_COSH:
        return math.cosh(min(max(a, -700.0), 700.0))
    if op == M_TANH:
        return math.tanh(a)
    if op == M_RADIANS:
        return a * (math.pi / 180.0)
    if op == M_DEGREES:
        return a * (180.0 / math.pi)
    return 0.0


@kernel(inline=True)
def _normalize(x, y, z):
    ln = math.sqrt(x * x + y * y + z * z)
    if ln > 0.0:
        return x / ln, y / ln, z / ln
    return 0.0, 0.0, 0.0


@kernel
def vmath_op(op, a0, a1, a2, b0, b1, b2, c0, c1, c2, s):
    """Blender's Vector Math node (``svm_vector_math``): (x, y, z, value)."""
    if op == V_ADD:
        return a0 + b0, a1 + b1, a2 + b2, 0.0
    if op == V_SUBTRACT:
        return a0 - b0, a1 - b1, a2 - b2, 0.0
    if op == V_MULTIPLY:
        return a0 * b0, a1 * b1, a2 * b2, 0.0
    if op == V_DIVIDE:
        return safe_divide(a0, b0), safe_divide(a1, b1), safe_divide(a2, b2), 0.0
    if op == V_MULTIPLY_ADD:
        return a0 * b0 + c0, a1 * b1 + c1, a2 * b2 + c2, 0.0
    if op == V_CROSS_PRODUCT:
        return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0, 0.0
    if op == V_PROJECT:
        l2 = b0 * b0 + b1 * b1 + b2 * b2
        k = (a0 * b0 + a1 * b1 + a2 * b2) / l2 if l2 != 0.0 else 0.0
        return b0 * k, b1 * k, b2 * k, 0.0
    if op == V_REFLECT:
        n0, n1, n2 = _normalize(b0, b1, b2)
        d = 2.0 * (a0 * n0 + a1 * n1 + a2 * n2)
        return a0 - d * n0, a1 - d * n1, a2 - d * n2, 0.0
    if op == V_REFRACT:
        n0, n1, n2 = _normalize(b0, b1, b2)
        ni = n0 * a0 + n1 * a1 + n2 * a2
        k = 1.0 - s * s * (1.0 - ni * ni)
        if k < 0.0:
            return 0.0, 0.0, 0.0, 0.0
        f = s * ni + math.sqrt(k)
        return s * a0 - f * n0, s * a1 - f * n1, s * a2 - f * n2, 0.0
    if op == V_FACEFORWARD:
        if c0 * b0 + c1 * b1 + c2 * b2 < 0.0:
            return a0, a1, a2, 0.0
        return -a0, -a1, -a2, 0.0
    if op == V_DOT_PRODUCT:
        return 0.0, 0.0, 0.0, a0 * b0 + a1 * b1 + a2 * b2
    if op == V_DISTANCE:
        return 0.0, 0.0, 0.0, math.sqrt((a0 - b0) ** 2 + (a1 - b1) ** 2 + (a2 - b2) ** 2)
    if op == V_LENGTH:
        return 0.0, 0.0, 0.0, math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    if op == V_SCALE:
        return a0 * s, a1 * s, a2 * s, 0.0
    if op == V_NORMALIZE:
        x, y, z = _normalize(a0, a1, a2)
        return x, y, z, 0.0
    if op == V_ABSOLUTE:
        return abs(a0), abs(a1), abs(a2), 0.0
    if op == V_POWER:
        return _safe_pow(a0, b0), _safe_pow(a1, b1), _safe_pow(a2, b2), 0.0
    if op == V_SIGN:
        return _sign(a0), _sign(a1), _sign(a2), 0.0
    if op == V_MINIMUM:
        return min(a0, b0), min(a1, b1), min(a2, b2), 0.0
    if op == V_MAXIMUM:
        return max(a0, b0), max(a1, b1), max(a2, b2), 0.0
    if op == V_FLOOR:
        return math.floor(a0), math.floor(a1), math.floor(a2), 0.0
    if op == V_CEIL:
        return math.ceil(a0), math.ceil(a1), math.ceil(a2), 0.0
    if op == V_FRACTION:
        return _fract(a0), _fract(a1), _fract(a2), 0.0
    if op == V_MODULO:
        return _fmod(a0, b0), _fmod(a1, b1), _fmod(a2, b2), 0.0
    if op == V_WRAP:
        return _wrap(a0, b0, c0), _wrap(a1, b1, c1), _wrap(a2, b2, c2), 0.0
    if op == V_SNAP:
        return (math.floor(safe_divide(a0, b0)) * b0, math.floor(safe_divide(a1, b1)) * b1,
                math.floor(safe_divide(a2, b2)) * b2, 0.0)
    if op == V_SINE:
        return math.sin(a0), math.sin(a1), math.sin(a2), 0.0
    if op == V_COSINE:
        return math.cos(a0), math.cos(a1), math.cos(a2), 0.0
    if op == V_TANGENT:
        return math.tan(a0), math.tan(a1), math.tan(a2), 0.0
    return 0.0, 0.0, 0.0, 0.0


# ---------------------------------------------------------------------------------------------- colour
@kernel
def rgb_to_hsv(r, g, b):
    """Cycles' ``rgb_to_hsv``."""
    cmax = max(r, max(g, b))
    cmin = min(r, min(g, b))
    cdelta = cmax - cmin
    v = cmax
    if cmax != 0.0:
        s = cdelta / cmax
    else:
        s = 0.0
    h = 0.0
    if s != 0.0:
        cr, cg, cb = (cmax - r) / cdelta, (cmax - g) / cdelta, (cmax - b) / cdelta
        if r == cmax:
            h = cb - cg
        elif g == cmax:
            h = 2.0 + cr - cb
        else:
            h = 4.0 + cg - cr
        h /= 6.0
        if h < 0.0:
            h += 1.0
    return h, s, v


@kernel
def hsv_to_rgb(h, s, v):
    """Cycles' ``hsv_to_rgb``."""
    if s == 0.0:
        return v, v, v
    if h == 1.0:
        h = 0.0
    h *= 6.0
    i = math.floor(h)
    f = h - i
    p = v * (1.0 - s)
    q = v * (1.0 - s * f)
    t = v * (1.0 - s * (1.0 - f))
    if i == 0.0:
        return v, t, p
    if i == 1.0:
        return q, v, p
    if i == 2.0:
        return p, v, t
    if i == 3.0:
        return p, q, v
    if i == 4.0:
        return t, p, v
    return v, p, q


@kernel
def rgb_to_hsl(r, g, b):
    """Cycles' ``rgb_to_hsl``."""
    cmax = max(r, max(g, b))
    cmin = min(r, min(g, b))
    l = min(1.0, (cmax + cmin) / 2.0)  # noqa: E741
    if cmax == cmin:
        return 0.0, 0.0, l
    d = cmax - cmin
    s = d / (2.0 - cmax - cmin) if l > 0.5 else d / (cmax + cmin)
    if cmax == r:
        h = (g - b) / d + (6.0 if g < b else 0.0)
    elif cmax == g:
        h = (b - r) / d + 2.0
    else:
        h = (r - g) / d + 4.0
    return h / 6.0, s, l


@kernel
def hsl_to_rgb(h, s, l):  # noqa: E741
    """Cycles' ``hsl_to_rgb``."""
    nr = min(max(abs(h * 6.0 - 3.0) - 1.0, 0.0), 1.0)
    ng = min(max(2.0 - abs(h * 6.0 - 2.0), 0.0), 1.0)
    nb = min(max(2.0 - abs(h * 6.0 - 4.0), 0.0), 1.0)
    chroma = (1.0 - abs(2.0 * l - 1.0)) * s
    return (nr - 0.5) * chroma + l, (ng - 0.5) * chroma + l, (nb - 0.5) * chroma + l


@kernel(inline=True)
def _lerp(a, b, t):
    return (1.0 - t) * a + t * b


@kernel(inline=True)
def _dodge(c1, c2, t):
    if c1 != 0.0:
        tmp = 1.0 - t * c2
        if tmp <= 0.0:
            return 1.0
        tmp = c1 / tmp
        return 1.0 if tmp > 1.0 else tmp
    return c1


@kernel(inline=True)
def _burn(c1, c2, t):
    tmp = (1.0 - t) + t * c2
    if tmp <= 0.0:
        return 0.0
    tmp = 1.0 - (1.0 - c1) / tmp
    return min(max(tmp, 0.0), 1.0)


@kernel(inline=True)
def _overlay(c1, c2, t):
    tm = 1.0 - t
    if c1 < 0.5:
        return c1 * (tm + 2.0 * t * c2)
    return 1.0 - (tm + 2.0 * t * (1.0 - c2)) * (1.0 - c1)


@kernel
def mix_blend(op, t, r1, g1, b1, r2, g2, b2):
    """Blender's Mix Color blend modes (``svm_mix``, color_util.h) of colour 1 and colour 2 by factor t."""
    tm = 1.0 - t
    if op == B_MIX:
        return _lerp(r1, r2, t), _lerp(g1, g2, t), _lerp(b1, b2, t)
    if op == B_ADD:
        return r1 + t * r2, g1 + t * g2, b1 + t * b2
    if op == B_MULTIPLY:
        return r1 * (tm + t * r2), g1 * (tm + t * g2), b1 * (tm + t * b2)
    if op == B_SCREEN:
        return (1.0 - (tm + t * (1.0 - r2)) * (1.0 - r1), 1.0 - (tm + t * (1.0 - g2)) * (1.0 - g1),
                1.0 - (tm + t * (1.0 - b2)) * (1.0 - b1))
    if op == B_OVERLAY:
        return _overlay(r1, r2, t), _overlay(g1, g2, t), _overlay(b1, b2, t)
    if op == B_SUBTRACT:
        return r1 - t * r2, g1 - t * g2, b1 - t * b2
    if op == B_DIVIDE:
        return (tm * r1 + t * r1 / r2 if r2 != 0.0 else r1, tm * g1 + t * g1 / g2 if g2 != 0.0 else g1,
                tm * b1 + t * b1 / b2 if b2 != 0.0 else b1)
    if op == B_DIFFERENCE:
        return _lerp(r1, abs(r1 - r2), t), _lerp(g1, abs(g1 - g2), t), _lerp(b1, abs(b1 - b2), t)
    if op == B_EXCLUSION:
        return (max(_lerp(r1, r1 + r2 - 2.0 * r1 * r2, t), 0.0), max(_lerp(g1, g1 + g2 - 2.0 * g1 * g2, t), 0.0),
                max(_lerp(b1, b1 + b2 - 2.0 * b1 * b2, t), 0.0))
    if op == B_DARKEN:
        return _lerp(r1, min(r1, r2), t), _lerp(g1, min(g1, g2), t), _lerp(b1, min(b1, b2), t)
    if op == B_LIGHTEN:
        return _lerp(r1, max(r1, r2), t), _lerp(g1, max(g1, g2), t), _lerp(b1, max(b1, b2), t)
    if op == B_DODGE:
        return _dodge(r1, r2, t), _dodge(g1, g2, t), _dodge(b1, b2, t)
    if op == B_BURN:
        return _burn(r1, r2, t), _burn(g1, g2, t), _burn(b1, b2, t)
    if op == B_SOFT_LIGHT:
        sr, sg, sb = 1.0 - (1.0 - r2) * (1.0 - r1), 1.0 - (1.0 - g2) * (1.0 - g1), 1.0 - (1.0 - b2) * (1.0 - b1)
        return (tm * r1 + t * ((1.0 - r1) * r2 * r1 + r1 * sr), tm * g1 + t * ((1.0 - g1) * g2 * g1 + g1 * sg),
                tm * b1 + t * ((1.0 - b1) * b2 * b1 + b1 * sb))
    if op == B_LINEAR_LIGHT:
        return r1 + t * (2.0 * r2 - 1.0), g1 + t * (2.0 * g2 - 1.0), b1 + t * (2.0 * b2 - 1.0)
    if op == B_HUE:
        h2, s2, v2 = rgb_to_hsv(r2, g2, b2)
        if s2 != 0.0:
            h, s, v = rgb_to_hsv(r1, g1, b1)
            x, y, z = hsv_to_rgb(h2, s, v)
            return _lerp(r1, x, t), _lerp(g1, y, t), _lerp(b1, z, t)
        return r1, g1, b1
    if op == B_SATURATION:
        h, s, v = rgb_to_hsv(r1, g1, b1)
        if s != 0.0:
            h2, s2, v2 = rgb_to_hsv(r2, g2, b2)
            return hsv_to_rgb(h, tm * s + t * s2, v)
        return r1, g1, b1
    if op == B_VALUE:
        h, s, v = rgb_to_hsv(r1, g1, b1)
        h2, s2, v2 = rgb_to_hsv(r2, g2, b2)
        return hsv_to_rgb(h, s, tm * v + t * v2)
    if op == B_COLOR:
        h2, s2, v2 = rgb_to_hsv(r2, g2, b2)
        if s2 != 0.0:
            h, s, v = rgb_to_hsv(r1, g1, b1)
            x, y, z = hsv_to_rgb(h2, s2, v)
            return _lerp(r1, x, t), _lerp(g1, y, t), _lerp(b1, z, t)
        return r1, g1, b1
    return r1, g1, b1


@kernel
def hue_sat(hue, sat, val, fac, r, g, b):
    """Blender's Hue/Saturation/Value node (``svm_node_hsv``)."""
    h, s, v = rgb_to_hsv(r, g, b)
    h = _fract(h + hue + 0.5)
    s = min(max(s * sat, 0.0), 1.0)
    v = v * val
    x, y, z = hsv_to_rgb(h, s, v)
    return (max(fac * x + (1.0 - fac) * r, 0.0), max(fac * y + (1.0 - fac) * g, 0.0),
            max(fac * z + (1.0 - fac) * b, 0.0))


@kernel(inline=True)
def bright_contrast(r, g, b, bright, contrast):
    """Blender's Bright/Contrast node (``svm_brightness``)."""
    a = 1.0 + contrast
    bb = bright - contrast * 0.5
    return max(a * r + bb, 0.0), max(a * g + bb, 0.0), max(a * b + bb, 0.0)


@kernel(inline=True)
def gamma(c, g):
    """Blender's Gamma node: c^g where c > 0."""
    return c ** g if c > 0.0 else c


# ---------------------------------------------------------------------------------------------- map range
@kernel(inline=True)
def _smoothstep(e0, e1, x):
    if x < e0:
        return 0.0
    if x >= e1:
        return 1.0
    t = (x - e0) / (e1 - e0)
    return (3.0 - 2.0 * t) * (t * t)


@kernel
def map_range(kind, value, from_min, from_max, to_min, to_max, steps):
    """Blender's Map Range (``svm_map_range``) before its clamp: kind 0 linear, 1 stepped, 2 smoothstep, 3
    smootherstep."""
    if from_max == from_min:
        return 0.0
    if kind == 0:
        f = (value - from_min) / (from_max - from_min)
    elif kind == 1:
        f = (value - from_min) / (from_max - from_min)
        f = math.floor(f * (steps + 1.0)) / steps if steps > 0.0 else 0.0
    elif kind == 2:
        if from_min > from_max:
            f = 1.0 - _smoothstep(from_max, from_min, value)
        else:
            f = _smoothstep(from_min, from_max, value)
    else:
        if from_min > from_max:
            x = min(max((value - from_max) / (from_min - from_max), 0.0), 1.0)
            f = 1.0 - x * x * x * (x * (x * 6.0 - 15.0) + 10.0)
        else:
            x = min(max((value - from_min) / (from_max - from_min), 0.0), 1.0)
            f = x * x * x * (x * (x * 6.0 - 15.0) + 10.0)
    return to_min + f * (to_max - to_min)


@kernel
def map_range_clamp(kind, value, from_min, from_max, to_min, to_max, steps, clamp):
    r = map_range(kind, value, from_min, from_max, to_min, to_max, steps)
    if clamp and kind < 2:
        lo, hi = min(to_min, to_max), max(to_min, to_max)
        r = min(max(r, lo), hi)
    return r



# ---------------------------------------------------------------------------------------------- on the register file
@kernel(refcounts=False)
def ramp(R, o, f, table, size, interpolate):
    """Color Ramp: Cycles' ``rgb_ramp_lookup`` on the (size, 4) RGBA table at R[table…] (Blender's 257 samples of
    the ramp, made by tracer.shading.procedural.color.color_ramp_table): entry int(f·(size − 1)) of f clamped to [0, 1],
    linear to the next unless the ramp is CONSTANT."""
    x = min(max(f, 0.0), 1.0) * (size - 1)
    if x != x:
        x = 0.0
    i = min(max(int(x), 0), size - 1)
    t = x - i if interpolate else 0.0
    j = min(i + 1, size - 1)
    for k in range(4):
        a = R[table + 4 * i + k]
        R[o + k] = a if t <= 0.0 else (1.0 - t) * a + t * R[table + 4 * j + k]


@kernel(refcounts=False)
def _curve_lookup(R, table, size, x, ch):
    """Curve channel ``ch`` of a baked table at R[table…]: header (x_min, x_max, channels), then ``size`` samples
    per channel over [x_min, x_max], linear between samples and extrapolated from the end slopes (Cycles'
    ``rgb_ramp_lookup`` with extrapolation)."""
    lo, hi = R[table], R[table + 1]
    first = table + 3 + ch * size
    f = (x - lo) / (hi - lo) * (size - 1) if hi > lo else 0.0
    if f < 0.0:
        return R[first] + (R[first] - R[first + 1]) * (-f)
    if f > size - 1:
        return R[first + size - 1] + (R[first + size - 1] - R[first + size - 2]) * (f - (size - 1))
    i = min(int(f), size - 2)
    t = f - i
    return (1.0 - t) * R[first + i] + t * R[first + i + 1]


@kernel(refcounts=False)
def curve(R, o, a, table, size, fac, kind):
    """RGB Curves (kind 0: the combined curve after each channel's, channels 3 then 0–2 in the table), Vector
    Curves (1: x, y, z) and Float Curve (2), blended with the input by ``fac``."""
    if kind == 2:
        x = R[a]
        y = _curve_lookup(R, table, size, x, 0)
        R[o] = (1.0 - fac) * x + fac * y
        return
    for j in range(3):
        x = R[a + j]
        if kind == 0:
            y = _curve_lookup(R, table, size, _curve_lookup(R, table, size, x, j + 1), 0)
        else:
            y = _curve_lookup(R, table, size, x, j)
        R[o + j] = (1.0 - fac) * x + fac * y


@kernel
def euler(rx, ry, rz):
    """Blender's XYZ Euler rotation matrix rows (R = Rz·Ry·Rx)."""
    cx, sx, cy, sy, cz, sz = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry), math.cos(rz), math.sin(rz)
    return ((cy * cz, sx * sy * cz - cx * sz, cx * sy * cz + sx * sz),
            (cy * sz, sx * sy * sz + cx * cz, cx * sy * sz - sx * cz),
            (-sy, sx * cy, cx * cy))


@kernel
def rot(m, v):
    return (vec.dot(m[0], v), vec.dot(m[1], v), vec.dot(m[2], v))


@kernel
def rot_t(m, v):
    return (m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2], m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
            m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2])


@kernel(refcounts=False)
def mapping(R, o, a, loc, rot_r, scl, kind):
    """Blender's Mapping node (``svm_mapping``): 0 point, 1 texture, 2 vector, 3 normal."""
    v = (R[a], R[a + 1], R[a + 2])
    lv = (R[loc], R[loc + 1], R[loc + 2])
    sv = (R[scl], R[scl + 1], R[scl + 2])
    m = euler(R[rot_r], R[rot_r + 1], R[rot_r + 2])
    if kind == 0:
        x = vec.add(rot(m, vec.mul(v, sv)), lv)
    elif kind == 1:
        w = rot_t(m, vec.sub(v, lv))
        x = (safe_divide(w[0], sv[0]), safe_divide(w[1], sv[1]), safe_divide(w[2], sv[2]))
    elif kind == 2:
        x = rot(m, vec.mul(v, sv))
    else:
        w = rot(m, (safe_divide(v[0], sv[0]), safe_divide(v[1], sv[1]), safe_divide(v[2], sv[2])))
        ln = math.sqrt(vec.dot(w, w))
        x = vec.scale(w, 1.0 / ln) if ln > 0.0 else w
    R[o], R[o + 1], R[o + 2] = x


@kernel
def _axis_angle(v, axis, angle):
    ln = math.sqrt(vec.dot(axis, axis))
    if ln == 0.0:
        return v
    k = vec.scale(axis, 1.0 / ln)
    c, s = math.cos(angle), math.sin(angle)
    return vec.add(vec.add(vec.scale(v, c), vec.scale(vec.cross(k, v), s)), vec.scale(k, vec.dot(k, v) * (1.0 - c)))


@kernel(refcounts=False)
def vrotate(R, o, a, center, axis, angle_r, rot_r, imm):
    """Blender's Vector Rotate (``svm_node_vector_rotate``): imm = type (0 axis-angle, 1–3 X/Y/Z, 4 Euler) + 8·invert."""
    kind, inv = imm & 7, (imm & 8) != 0
    v = (R[a], R[a + 1], R[a + 2])
    cen = (R[center], R[center + 1], R[center + 2])
    w = vec.sub(v, cen)
    ang = R[angle_r] * (-1.0 if inv else 1.0)
    if kind == 4:
        m = euler(R[rot_r], R[rot_r + 1], R[rot_r + 2])
        w = rot_t(m, w) if inv else rot(m, w)
    elif kind == 0:
        w = _axis_angle(w, (R[axis], R[axis + 1], R[axis + 2]), ang)
    else:
        ax = (1.0 if kind == 1 else 0.0, 1.0 if kind == 2 else 0.0, 1.0 if kind == 3 else 0.0)
        w = _axis_angle(w, ax, ang)
    R[o], R[o + 1], R[o + 2] = vec.add(w, cen)

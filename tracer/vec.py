"""3-vectors as tuples of floats, for the scalar code inside kernels: (x, y, z) in, (x, y, z) out."""

from __future__ import annotations

import math

from .jit import kernel


@kernel(inline="always")
def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@kernel(inline="always")
def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@kernel(inline="always")
def mul(a, b):
    """Component-wise product (colours)."""
    return (a[0] * b[0], a[1] * b[1], a[2] * b[2])


@kernel(inline="always")
def scale(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


@kernel(inline="always")
def madd(a, b, s):
    """a + s·b."""
    return (a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2])


@kernel(inline="always")
def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@kernel(inline="always")
def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@kernel(inline="always")
def length(a):
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@kernel(inline="always")
def normalize(a):
    """a / ‖a‖ (the zero vector stays zero)."""
    n = math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
    s = 1.0 / n if n > 1e-30 else 0.0
    return (a[0] * s, a[1] * s, a[2] * s)


@kernel(inline="always")
def max3(a):
    return max(a[0], max(a[1], a[2]))


@kernel(inline="always")
def row(arr, i):
    """Row i of an (N, 3) array as a float tuple."""
    return (float(arr[i, 0]), float(arr[i, 1]), float(arr[i, 2]))


@kernel(inline="always")
def orthonormal_basis(w):
    """Two unit vectors u, v with (u, v, w) right-handed and orthonormal (w unit)."""
    a = (1.0, 0.0, 0.0) if abs(w[0]) < 0.9 else (0.0, 1.0, 0.0)
    u = normalize(cross(a, w))
    return u, cross(w, u)

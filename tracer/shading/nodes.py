"""The node table: every shader node and every VM instruction, each written once.

Cycles' SVM keeps a node's facts in one place (its class in ``scene/shader_nodes.cpp``, its opcode in
``svm_types.h``, its kernel in ``kernel/svm/``); here one module holds, per entry:

- **a VM instruction** (:data:`OPS`, one :class:`Op` row each): its name, its opcode (the row's position: the
  ``OP_*`` constants and :data:`OP_NAMES` are made from the rows), the width of what it writes (:meth:`Op.width`),
  and its constant-folding function (``fold``: the instruction evaluated on a register file, through the same numba
  functions the VM runs, :mod:`tracer.shading.ops`; None for an instruction that reads the hit). The compiler folds
  any instruction whose operands are all constants by its row's ``fold`` (:meth:`tracer.shading.compiler.Compiler.op`);
  ``tests/test_shader_vm.py`` runs every ``fold`` against the VM itself.
- **an IR node type** (:data:`NODE_TYPES`, one :class:`NodeType` per ``@node``/``define``): its sockets (kinds and
  defaults), its parameters, its lowering (the function under ``@node``, which writes the node's instructions through
  the compiler ``c``) and the Cycles comparison that proves it (``proof``).

Adding a node is one ``@node`` entry here (sockets, parameters, lowering), plus, if it needs a new instruction, one
:class:`Op` row and its branch in :func:`tracer.shading.vm.execute` (numba compiles dispatch as branches; the test
``test_vm_dispatch_follows_the_op_table`` checks the branches against the rows).

Also here, since every layer reads them: the socket kinds and the conversions between them (:func:`convert_constant`,
the one rule the compiler and the add-on apply), the parameter enumerations (:data:`ENUMS`), the hit inputs
(``IN_*``) and the closure outputs a program writes (:data:`OUTPUTS`).

Imports: :mod:`tracer.shading.ops`, :mod:`tracer.shading.procedural` (enums), :mod:`tracer.shading.materials` (Principled defaults),
:mod:`tracer.colorspace`. It is imported by :mod:`tracer.shading.graph` (the IR), :mod:`tracer.shading.vm` (opcodes)
and :mod:`tracer.shading.compiler` / :mod:`tracer.shading.closures` (lowering); it imports none of them.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Callable, NamedTuple

import numpy as np

from ..colorspace import REC709_LUMINANCE
from . import ops
from .materials import PRINCIPLED_DEFAULTS
from .procedural import color as pcolor, mx_noise as pmx, noise as pnoise, patterns as ppat, voronoi as pvor

# ============================================================================================== sockets
FLOAT, VECTOR, COLOR, CLOSURE = "float", "vector", "color", "closure"
KINDS = (FLOAT, VECTOR, COLOR, CLOSURE)


class Implicit(NamedTuple):
    """The default of an input that, unlinked, reads a value of the hit (not a constant)."""

    what: str


NORMAL, UV, GENERATED, POSITION, TANGENT = (Implicit("normal"), Implicit("uv"), Implicit("generated"),
                                             Implicit("position"), Implicit("tangent"))
IMPLICIT = (NORMAL, UV, GENERATED, POSITION, TANGENT)


class Socket(NamedTuple):
    name: str
    kind: str
    default: object = None  # float, 3-tuple, an Implicit, or None (closures: nothing connected = black)


def convert_constant(v, src: str, dst: str):
    """A constant of kind ``src`` as kind ``dst``, as Blender converts a link between kinds: colour → float is the
    luminance (:data:`tracer.colorspace.REC709_LUMINANCE`), vector → float the mean of x, y, z, float →
    colour/vector (f, f, f), colour ↔ vector as is. (The VM's ``lum``/``avg``/``combine`` instructions are the same
    rule per hit; the compiler folds them to this.)"""
    if dst == FLOAT:
        if np.ndim(v) == 0:
            return float(v)
        v = tuple(float(x) for x in np.ravel(v))[:3]
        if src == COLOR:
            return REC709_LUMINANCE[0] * v[0] + REC709_LUMINANCE[1] * v[1] + REC709_LUMINANCE[2] * v[2]
        return (v[0] + v[1] + v[2]) / 3.0
    if np.ndim(v) == 0:
        return (float(v),) * 3
    return tuple(float(x) for x in np.ravel(v))[:3]


# ============================================================================================== values
class Reg(NamedTuple):
    """A value in registers r … r + n − 1 (``uv``: the UV set its coordinates came from, for the mip footprint)."""

    r: int
    n: int
    uv: int = -1
    src: object = None  # (TextureUse, coordinates, (projection, blend)) of an image lookup's colour: a constant scale
    #                     folds into it


def is_const(x) -> bool:
    """A value known at compile time (a float or a tuple; a :class:`Reg` is per hit)."""
    return not isinstance(x, Reg)


def vec3(x):
    """A constant as a 3-tuple of floats."""
    if np.ndim(x) == 0:
        return (float(x),) * 3
    return tuple(float(c) for c in tuple(x)[:3])


def part(x, start: int, n: int = 1):
    """Registers start … start + n − 1 of a result (a Reg, or a folded constant)."""
    if isinstance(x, Reg):
        return Reg(x.r + start, n)
    vals = (x,) if np.ndim(x) == 0 else tuple(x)
    return float(vals[start]) if n == 1 else tuple(float(v) for v in vals[start:start + n])


class TextureUse(NamedTuple):
    """What an image op reads: an ImageRef with the UsdUVTexture scale/bias/fallback, or a scene texture."""

    image: object  # tracer.shading.graph.ImageRef | None
    scene_index: int
    scale: tuple = (1.0, 1.0, 1.0, 1.0)
    bias: tuple = (0.0, 0.0, 0.0, 0.0)
    fallback: tuple = (1.0, 1.0, 1.0, 1.0)


# ============================================================================================== VM instructions
#: Words per instruction: op, dst, a, b, c, d, e, f, imm.
WIDTH = 9


class Op(NamedTuple):
    """One VM instruction (its opcode is its position in :data:`OPS`). ``out``: the registers it writes, a number
    or a function of ``imm``; ``fold(R, o, a, b, c, d, e, f, imm)``: the instruction on a register file (its
    fields as in the program: registers, or raw where the VM reads them raw), None where it reads the hit;
    ``doc``: its operands."""

    name: str
    out: object
    fold: Callable | None
    doc: str

    def width(self, imm: int = 0) -> int:
        return self.out(imm) if callable(self.out) else self.out


def _fold_math(R, o, a, b, c, d, e, f, imm):
    x = ops.math_op(imm & 255, R[a], R[b], R[c])
    R[o] = min(max(x, 0.0), 1.0) if imm & 256 else x


def _fold_vmath(R, o, a, b, c, d, e, f, imm):
    R[o:o + 4] = ops.vmath_op(imm, R[a], R[a + 1], R[a + 2], R[b], R[b + 1], R[b + 2], R[c], R[c + 1], R[c + 2],
                              R[d])


def _fold_mix_n(n, per_channel):
    def fold(R, o, a, b, c, d, e, f, imm):
        for j in range(n):
            t = R[a + j] if per_channel else R[a]
            if imm & 1:
                t = min(max(t, 0.0), 1.0)
            R[o + j] = (1.0 - t) * R[b + j] + t * R[c + j]
    return fold


def _fold_mix_c(R, o, a, b, c, d, e, f, imm):
    t = min(max(R[a], 0.0), 1.0) if imm & 256 else R[a]
    x = ops.mix_blend(imm & 255, t, R[b], R[b + 1], R[b + 2], R[c], R[c + 1], R[c + 2])
    R[o:o + 3] = [min(max(v, 0.0), 1.0) for v in x] if imm & 512 else x


def _fold_lum(R, o, a, b, c, d, e, f, imm):
    R[o] = REC709_LUMINANCE[0] * R[a] + REC709_LUMINANCE[1] * R[a + 1] + REC709_LUMINANCE[2] * R[a + 2]


def _fold_avg(R, o, a, b, c, d, e, f, imm):
    R[o] = (R[a] + R[a + 1] + R[a + 2]) / 3.0


def _fold_combine(R, o, a, b, c, d, e, f, imm):
    R[o:o + 3] = R[a], R[b], R[c]


def _fold_checker(R, o, a, b, c, d, e, f, imm):
    sc = R[d]
    xi, yi, zi = (int(abs(np.floor((R[a + j] * sc + 0.000001) * 0.999999))) for j in range(3))
    first = (xi % 2 == yi % 2) == (zi % 2 != 0)
    src = b if first else c
    R[o:o + 4] = R[src], R[src + 1], R[src + 2], 1.0 if first else 0.0


def _fold_hsv(R, o, a, b, c, d, e, f, imm):
    R[o:o + 3] = ops.hue_sat(R[b], R[c], R[d], R[e], R[a], R[a + 1], R[a + 2])


def _fold_gamma(R, o, a, b, c, d, e, f, imm):
    R[o:o + 3] = [ops.gamma(R[a + j], R[b]) for j in range(3)]


def _fold_bright(R, o, a, b, c, d, e, f, imm):
    R[o:o + 3] = ops.bright_contrast(R[a], R[a + 1], R[a + 2], R[b], R[c])


def _fold_invert(R, o, a, b, c, d, e, f, imm):
    t = R[b]
    R[o:o + 3] = [(1.0 - t) * R[a + j] + t * (1.0 - R[a + j]) for j in range(3)]


def _fold_sep_color(R, o, a, b, c, d, e, f, imm):
    x = (R[a], R[a + 1], R[a + 2])
    R[o:o + 3] = ops.rgb_to_hsv(*x) if imm == 1 else ops.rgb_to_hsl(*x) if imm == 2 else x


def _fold_comb_color(R, o, a, b, c, d, e, f, imm):
    x = (R[a], R[b], R[c])
    R[o:o + 3] = ops.hsv_to_rgb(*x) if imm == 1 else ops.hsl_to_rgb(*x) if imm == 2 else x


def _fold_map_range(R, o, a, b, c, d, e, f, imm):
    R[o] = ops.map_range_clamp(imm & 255, R[a], R[b], R[c], R[d], R[e], R[f], (imm & 256) != 0)


def _fold_map_range_v(R, o, a, b, c, d, e, f, imm):
    for j in range(3):
        R[o + j] = ops.map_range_clamp(imm & 255, R[a + j], R[b + j], R[c + j], R[d + j], R[e + j], R[f + j],
                                       (imm & 256) != 0)


def _fold_clamp(R, o, a, b, c, d, e, f, imm):
    lo, hi = R[b], R[c]
    if imm == 1 and lo > hi:
        lo, hi = hi, lo
    R[o] = min(max(R[a], lo), hi)


def _fold_copy(R, o, a, b, c, d, e, f, imm):
    R[o:o + imm] = R[a:a + imm]


def _fold_select(R, o, a, b, c, d, e, f, imm):
    src = a if R[c] > 0.5 else b
    R[o:o + imm] = R[src:src + imm]


def _fold_affine2(R, o, a, b, c, d, e, f, imm):
    s, t = R[a], R[a + 1]
    R[o:o + 3] = R[b] * s + R[b + 1] * t + R[b + 2], R[b + 3] * s + R[b + 4] * t + R[b + 5], R[a + 2]


#: Every VM instruction, in opcode order. Procedural textures (handled by tracer.shading.vm._procedural) come last,
#: from ``noise`` on.
OPS: tuple[Op, ...] = (
    Op("nop", 0, None, "nothing"),
    Op("math", 1, _fold_math, "Math: a, b, c; imm = operation | 256·clamp"),
    Op("vmath", 4, _fold_vmath, "Vector Math: vectors a, b, c, scale d; imm = operation -> vector, value"),
    Op("mix_f", 1, _fold_mix_n(1, False), "Mix (float): factor a, A b, B c; imm = clamp factor"),
    Op("mix_v", 3, _fold_mix_n(3, False), "Mix (vector, uniform): factor a, A b, B c; imm = clamp factor"),
    Op("mix_vn", 3, _fold_mix_n(3, True), "Mix (vector, non-uniform): factor vector a, A b, B c; imm = clamp factor"),
    Op("mix_c", 3, _fold_mix_c, "Mix (colour): factor a, A b, B c; imm = blend | 256·clamp factor | 512·clamp result"),
    Op("lum", 1, _fold_lum, "colour a -> float: its luminance"),
    Op("avg", 1, _fold_avg, "vector a -> float: the mean of its components"),
    Op("combine", 3, _fold_combine, "floats a, b, c -> a vector"),
    Op("input", 3, None, "a value of the hit: imm = IN_*, a = argument (UV set), b = variant (bump offset point), "
                         "c = the bump setup's registers"),
    Op("image", 4, None, "image lookup at a: b = texture index (raw), c = UV set of the footprint (raw), d = box "
                         "blend; imm = projection -> RGBA"),
    Op("checker", 4, _fold_checker, "Checker: vector a, Color1 b, Color2 c, scale d -> colour, fac"),
    Op("normal_map", 3, None, "Normal Map: colour a, strength b, UV set c (raw); imm = space"),
    Op("bump_setup", 10, None, "the bump offsets of the hit (du, dv ×2, dPdx, dPdy), a = Filter Width (× the pixel)"),
    Op("bump", 3, None, "Bump: heights a, b, c, strength d, distance e, normal f; imm = the setup's register"),
    Op("ramp", 4, lambda R, o, a, b, c, d, e, f, imm: ops.ramp(R, o, R[a], b, c, imm),
       "Color Ramp: fac a, table b, c entries (raw); imm = interpolate -> RGBA"),
    Op("curve", lambda imm: 1 if imm == 2 else 3, lambda R, o, a, b, c, d, e, f, imm: ops.curve(R, o, a, b, c, R[d],
                                                                                                  imm),
       "RGB / Vector / Float Curves: value a, table b, c samples (raw), fac d; imm = kind"),
    Op("mapping", 3, lambda R, o, a, b, c, d, e, f, imm: ops.mapping(R, o, a, b, c, d, imm),
       "Mapping: vector a, location b, rotation c, scale d; imm = type"),
    Op("hsv", 3, _fold_hsv, "Hue/Saturation/Value: colour a, hue b, saturation c, value d, fac e"),
    Op("gamma", 3, _fold_gamma, "Gamma: colour a, gamma b"),
    Op("bright", 3, _fold_bright, "Bright/Contrast: colour a, bright b, contrast c"),
    Op("invert", 3, _fold_invert, "Invert: colour a, fac b"),
    Op("sep_color", 3, _fold_sep_color, "Separate Color: colour a; imm = mode (RGB, HSV, HSL)"),
    Op("comb_color", 3, _fold_comb_color, "Combine Color: a, b, c; imm = mode (RGB, HSV, HSL)"),
    Op("map_range", 1, _fold_map_range, "Map Range: value a, from b…c, to d…e, steps f; imm = type | 256·clamp"),
    Op("clamp", 1, _fold_clamp, "Clamp: value a, min b, max c; imm = type"),
    Op("fresnel", 1, None, "Fresnel: IOR a, normal b; imm 2: a coat's albedo (IOR a, normal b, roughness c)"),
    Op("layer_weight", 2, None, "Layer Weight: blend a, normal b -> Fresnel, Facing"),
    Op("vrotate", 3, lambda R, o, a, b, c, d, e, f, imm: ops.vrotate(R, o, a, b, c, d, e, imm),
       "Vector Rotate: vector a, centre b, axis c, angle d, rotation e; imm = type | 8·invert"),
    Op("copy", lambda imm: imm, _fold_copy, "a copied, imm registers wide"),
    Op("affine2", 3, _fold_affine2, "(s, t) of a through the 2×3 matrix at b"),
    Op("map_range_v", 3, _fold_map_range_v, "Map Range (vector): as map_range on vectors"),
    Op("select", lambda imm: imm, _fold_select, "a if c > 0.5 else b, imm registers wide"),
    Op("normalize_n", 3, None, "a normal output: unit, on the incident side, else the shading normal"),
    Op("vtransform", 3, None, "Vector Transform: vector a; imm = type | 4·from | 16·to"),
    # ------------------------------------------------ procedural textures: vector a, the block of other inputs at b
    Op("noise", lambda imm: 4 if (imm >> 12) & 15 else 1, None,
       "Noise: block W, Scale, Detail, Roughness, Lacunarity, Offset, Gain, Distortion; imm = dim | 16·type | "
       "256·normalize | 4096·colour wanted -> Fac (, Color)"),
    Op("voronoi", 9, None, "Voronoi: block W, Scale, Detail, Roughness, Lacunarity, Smoothness, Exponent, Randomness;"
                           " imm = dim | 16·feature | 256·metric | 4096·normalize -> Distance, Color, Position, W, "
                           "Radius"),
    Op("wave", 1, None, "Wave: block Scale, Distortion, Detail, Detail Scale, Detail Roughness, Phase Offset"),
    Op("magic", 4, None, "Magic: block Scale, Distortion; imm = depth -> Color, Fac"),
    Op("gradient", 1, None, "Gradient: imm = type -> Fac"),
    Op("brick", 4, None, "Brick: block Color1, Color2, Mortar, Scale, … -> Color, Fac"),
    Op("white_noise", 4, None, "White Noise: block W; imm = dim -> Value, Color"),
    Op("blackbody", 3, lambda R, o, a, b, c, d, e, f, imm: R.__setitem__(slice(o, o + 3), pcolor.blackbody(R[a])),
       "Blackbody: temperature a"),
    Op("wavelength", 3, lambda R, o, a, b, c, d, e, f, imm: R.__setitem__(slice(o, o + 3), pcolor.wavelength(R[a])),
       "Wavelength: nm a"),
    Op("mx_noise", 4, None, "MaterialX noises: block amplitude (4), pivot, octaves, lacunarity, diminish, jitter; "
                            "imm = kind | 16·dimensions | 256·width | 4096·style -> x, y, z, w"),
)
#: Each instruction's name, by opcode.
OP_NAMES = tuple(op.name for op in OPS)
#: Opcode of each instruction name.
OPCODE = {op.name: k for k, op in enumerate(OPS)}
assert len(OPCODE) == len(OPS), "two instructions with one name"
(OP_NOP, OP_MATH, OP_VMATH, OP_MIX_F, OP_MIX_V, OP_MIX_VN, OP_MIX_C, OP_LUM, OP_AVG, OP_COMBINE, OP_INPUT,
 OP_IMAGE, OP_CHECKER, OP_NORMAL_MAP, OP_BUMP_SETUP, OP_BUMP, OP_RAMP, OP_CURVE, OP_MAPPING, OP_HSV, OP_GAMMA,
 OP_BRIGHT, OP_INVERT, OP_SEP_COLOR, OP_COMB_COLOR, OP_MAP_RANGE, OP_CLAMP, OP_FRESNEL, OP_LAYER_WEIGHT,
 OP_VROTATE, OP_COPY, OP_AFFINE2, OP_MAP_RANGE_V, OP_SELECT, OP_NORMALIZE_N, OP_VTRANSFORM, OP_NOISE, OP_VORONOI,
 OP_WAVE, OP_MAGIC, OP_GRADIENT, OP_BRICK, OP_WHITE_NOISE, OP_BLACKBODY, OP_WAVELENGTH,
 OP_MX_NOISE) = (OPCODE[n] for n in OP_NAMES)  # the names numba's branches read (checked against OPS below)
assert all(globals()[f"OP_{op.name.upper()}"] == k for k, op in enumerate(OPS)), "OP_* out of step with OPS"

#: The hit inputs an ``input`` instruction reads (its imm).
(IN_POSITION, IN_NORMAL, IN_TRUE_NORMAL, IN_INCOMING, IN_UV, IN_GENERATED, IN_OBJECT, IN_BACKFACING, IN_PARAMETRIC,
 IN_COLOR, IN_COLOR_ALPHA, IN_OBJ_LOCATION, IN_OBJ_RANDOM, IN_OBJ_INDEX, IN_RAY_DEPTH, IN_RAY_LENGTH, IN_IS_CAMERA,
 IN_IS_REFLECTION, IN_IS_TRANSMISSION, IN_IS_SHADOW, IN_TANGENT, IN_CAMERA, IN_WINDOW, IN_REFLECTION,
 IN_MAT_INDEX, IN_ZERO) = range(26)

#: The closure inputs a program writes (its row of ``outs``) and their widths: base colour, roughness, metallic,
#: specular level, alpha, emission, shading normal, transmission, anisotropy, and the smooth normal the Displacement
#: output's bump sets (Cycles' SetNormal: the sd->N the light stages' bump shadowing measures a bump from).
OUTPUTS = (("base", 3), ("roughness", 1), ("metallic", 1), ("specular", 1), ("alpha", 1), ("emission", 3),
           ("normal", 3), ("transmission", 1), ("aniso", 3), ("smooth", 3))
OUT_SLOTS = tuple(name for name, _n in OUTPUTS)
OUT_WIDTH = dict(OUTPUTS)
(OUT_BASE, OUT_ROUGH, OUT_METAL, OUT_SPEC, OUT_ALPHA, OUT_EMIT, OUT_NORMAL, OUT_TRANS, OUT_ANISO,
 OUT_SMOOTH) = range(len(OUTPUTS))


# ============================================================================================== node types
class NodeType(NamedTuple):
    """One node type of the IR: inputs and outputs (:class:`Socket`), parameters {name: default} (enums: the first
    of the tuple in :data:`ENUMS` is the default when the value is None here), its lowering
    ``lower(compiler, node, variant) -> {output: value}`` (None: a closure or the output, which
    :mod:`tracer.shading.closures` reads) and the test that compares it with Cycles (``proof``)."""

    inputs: tuple
    outputs: tuple
    params: dict
    lower: Callable | None = None
    proof: str = ""

    def input(self, name: str) -> Socket | None:
        return next((s for s in self.inputs if s.name == name), None)

    def output(self, name: str) -> Socket | None:
        return next((s for s in self.outputs if s.name == name), None)


#: Every node type of the IR, in the order of the entries below.
NODE_TYPES: dict[str, NodeType] = {}
_CYCLES_NODES = "tests/cycles/test_cycles_nodes.py"
_CYCLES_OPS = "tests/cycles/test_cycles_shader_ops.py"
_CYCLES_PROC = "tests/cycles/test_cycles_procedural.py"


def define(type_name: str, inputs, outputs, proof: str = "", lower=None, **params) -> NodeType:
    """Add the entry of a node type (no lowering: closures and the output)."""
    if type_name in NODE_TYPES:
        raise ValueError(f"node type {type_name!r} defined twice")
    nt = NODE_TYPES[type_name] = NodeType(tuple(inputs), tuple(outputs), params, lower, proof)
    return nt


def node(type_name: str, inputs, outputs, proof: str = _CYCLES_NODES, **params):
    """The entry of a node type whose lowering is the decorated function."""
    def wrap(fn):
        define(type_name, inputs, outputs, proof, fn, **params)
        return fn
    return wrap


def _f(name, d=0.0):
    return Socket(name, FLOAT, float(d))


def _v(name, d=(0.0, 0.0, 0.0)):
    return Socket(name, VECTOR, d if isinstance(d, Implicit) else tuple(float(x) for x in d))


def _c(name, d=(0.8, 0.8, 0.8)):
    return Socket(name, COLOR, tuple(float(x) for x in d))


def _s(name):
    return Socket(name, CLOSURE, None)


_N = _v("Normal", NORMAL)

#: Enumerations of parameters (the first is the default). Names and members are Blender's (RNA enum identifiers).
ENUMS = {
    "math.operation": ("ADD", "SUBTRACT", "MULTIPLY", "DIVIDE", "MULTIPLY_ADD", "POWER", "LOGARITHM", "SQRT",
                       "INVERSE_SQRT", "ABSOLUTE", "EXPONENT", "MINIMUM", "MAXIMUM", "LESS_THAN", "GREATER_THAN",
                       "SIGN", "COMPARE", "SMOOTH_MIN", "SMOOTH_MAX", "ROUND", "FLOOR", "CEIL", "TRUNC", "FRACT",
                       "MODULO", "FLOORED_MODULO", "WRAP", "SNAP", "PINGPONG", "SINE", "COSINE", "TANGENT", "ARCSINE",
                       "ARCCOSINE", "ARCTANGENT", "ARCTAN2", "SINH", "COSH", "TANH", "RADIANS", "DEGREES"),
    "vector_math.operation": ("ADD", "SUBTRACT", "MULTIPLY", "DIVIDE", "MULTIPLY_ADD", "CROSS_PRODUCT", "PROJECT",
                              "REFLECT", "REFRACT", "FACEFORWARD", "DOT_PRODUCT", "DISTANCE", "LENGTH", "SCALE",
                              "NORMALIZE", "ABSOLUTE", "POWER", "SIGN", "MINIMUM", "MAXIMUM", "FLOOR", "CEIL",
                              "FRACTION", "MODULO", "WRAP", "SNAP", "SINE", "COSINE", "TANGENT"),
    "mix_color.blend_type": ops.BLEND_TYPES,
    "map_range.interpolation_type": ("LINEAR", "STEPPED", "SMOOTHSTEP", "SMOOTHERSTEP"),
    "clamp.clamp_type": ("MINMAX", "RANGE"),
    "color_mode": ("RGB", "HSV", "HSL"),
    "rgb_ramp.interpolation": ("LINEAR", "CONSTANT", "EASE", "CARDINAL", "B_SPLINE"),
    "mapping.vector_type": ("POINT", "TEXTURE", "VECTOR", "NORMAL"),
    "vector_rotate.rotation_type": ("AXIS_ANGLE", "X_AXIS", "Y_AXIS", "Z_AXIS", "EULER_XYZ"),
    "vector_transform.vector_type": ("VECTOR", "POINT", "NORMAL"),
    "space": ("WORLD", "OBJECT", "CAMERA"),
    "normal_map.space": ("TANGENT", "OBJECT", "WORLD", "BLENDER_OBJECT", "BLENDER_WORLD"),
    "image_texture.projection": ("FLAT", "BOX", "SPHERE", "TUBE"),
    "image_texture.interpolation": ("Linear", "Closest", "Cubic", "Smart"),
    "extension": ("REPEAT", "EXTEND", "CLIP", "MIRROR"),
    "distribution": ("MULTI_GGX", "GGX", "BECKMANN", "ASHIKHMIN_SHIRLEY"),
}


def _enum(key: str, value) -> int:
    """The position of an enum parameter's value in :data:`ENUMS` (None: the first, its default)."""
    names = ENUMS[key]
    if value is None:
        return 0
    try:
        return names.index(str(value).upper() if key != "image_texture.interpolation" else str(value))
    except ValueError:
        raise ValueError(f"{key}: unknown value {value!r}; one of {names}") from None


class _Lazy(dict):
    """Outputs computed on first use (input nodes: only the outputs a graph reads emit an op)."""

    def __init__(self, makers: dict):
        super().__init__()
        self._makers = makers

    def __missing__(self, key):
        v = self._makers[key]()
        self[key] = v
        return v


def _with_wrap(img, wrap: str):
    if img.wrap_s == wrap and img.wrap_t == wrap:
        return img
    out = replace(img, wrap_s=wrap, wrap_t=wrap)
    out.pixels = img.pixels
    return out


def transform2d_matrix(scale=(1.0, 1.0), rotation=0.0, translation=(0.0, 0.0)) -> np.ndarray:
    """The (3, 3) matrix of a UsdTransform2d on (s, t, 1): T · R · S (scale, then rotate CCW in degrees, then
    translate), the spec's ``in · scale · rotate + translation``."""
    if not math.isfinite(rotation):
        return np.full((3, 3), np.nan)
    c, s = math.cos(math.radians(rotation)), math.sin(math.radians(rotation))
    S = np.diag([scale[0], scale[1], 1.0])
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    T = np.array([[1.0, 0.0, translation[0]], [0.0, 1.0, translation[1]], [0.0, 0.0, 1.0]])
    return T @ R @ S


# ---------------------------------------------------------------- the entries
define('material_output', [_s("Surface"), _v("Displacement")], [])


define('principled_bsdf', [(_c if np.ndim(d) else _f)(k, d) for k, d in PRINCIPLED_DEFAULTS.items()] + [
      _N, _f("Coat Weight"), _f("Coat Roughness", 0.03), _f("Coat IOR", 1.5), _c("Coat Tint", (1, 1, 1)),
      _v("Coat Normal", NORMAL), _f("Sheen Weight"), _f("Sheen Roughness", 0.5), _c("Sheen Tint", (1, 1, 1)),
      _f("Subsurface Weight"), _f("Anisotropic"), _f("Anisotropic Rotation"), _v("Tangent", TANGENT),
      _f("Alpha Threshold")],  # Alpha Threshold: USD's opacityThreshold (not in Blender)
      [_s("BSDF")], transmission_tint=None, distribution="MULTI_GGX",
      proof='tests/cycles/test_cycles_addon_materials.py, tests/cycles/test_cycles_usd_materials.py')


define('diffuse_bsdf', [_c("Color"), _f("Roughness"), _N], [_s("BSDF")], proof='tests/cycles/test_cycles_nodes.py (closures)')


define('glossy_bsdf', [_c("Color"), _f("Roughness", 0.5), _f("Anisotropy"), _f("Rotation"), _N,
                       _v("Tangent", TANGENT)],
      [_s("BSDF")], distribution="MULTI_GGX", proof='tests/cycles/test_cycles_nodes.py (closures)')


define('glass_bsdf', [_c("Color", (1, 1, 1)), _f("Roughness"), _f("IOR", 1.5), _N], [_s("BSDF")],
      distribution="MULTI_GGX", proof='tests/cycles/test_cycles_nodes.py (closures)')


define('refraction_bsdf', [_c("Color", (1, 1, 1)), _f("Roughness"), _f("IOR", 1.5), _N], [_s("BSDF")],
      distribution="GGX", proof='tests/cycles/test_cycles_nodes.py (closures)')


define('translucent_bsdf', [_c("Color"), _N], [_s("BSDF")], proof='tests/cycles/test_cycles_nodes.py (closures)')


define('sheen_bsdf', [_c("Color"), _f("Roughness", 0.5), _N], [_s("BSDF")], distribution="MICROFIBER",
       proof='tests/test_blender_fidelity.py (sheen)')


define('transparent_bsdf', [_c("Color", (1, 1, 1))], [_s("BSDF")], proof='tests/cycles/test_cycles_nodes.py (closures)')


define('emission', [_c("Color", (1, 1, 1)), _f("Strength", 1.0)], [_s("Emission")], proof='tests/cycles/test_cycles_nodes.py (closures)')


define('holdout', [], [_s("Holdout")], proof='tests/cycles/test_cycles_compose.py')


define('mix_closure', [_f("Fac", 0.5), _s("Shader"), _s("Shader_001")], [_s("Shader")], proof='tests/cycles/test_cycles_nodes.py (closures)')


define('add_closure', [_s("Shader"), _s("Shader_001")], [_s("Shader")], proof='tests/cycles/test_cycles_nodes.py (closures)')


@node('value', [], [_f("Value")], value=0.0)
def _value(cx, node, var):
    return {"Value": float(node.param("value"))}


@node('color', [], [_c("Color")], value=(0.8, 0.8, 0.8))
def _color(cx, node, var):
    return {"Color": vec3(node.param("value"))}


@node('texture_coordinate', [], [_v("Generated"), _v("Normal"), _v("UV"), _v("Object"), _v("Camera"),
      _v("Window"), _v("Reflection")], from_object=None)
def _texture_coordinate(cx, node, var):
    if node.param("from_object"):
        cx.warn(node.name + "obj", f"Texture Coordinate {node.name!r}: From Object is not supported (the "
                                     "hit's own object is used)")
    out = {"Generated": lambda: cx.hit(IN_GENERATED, variant=var),
           "Normal": lambda: cx.hit(IN_NORMAL), "UV": lambda: cx.uv("", var),
           "Object": lambda: cx.hit(IN_OBJECT, variant=var), "Camera": lambda: cx.hit(IN_CAMERA),
           "Window": lambda: cx.hit(IN_WINDOW), "Reflection": lambda: cx.hit(IN_REFLECTION)}
    return _Lazy(out)


@node('geometry', [], [_v("Position"), _v("Normal"), _v("Tangent"), _v("True Normal"), _v("Incoming"),
      _v("Parametric"), _f("Backfacing"), _f("Pointiness"), _f("Random Per Island")])
def _geometry(cx, node, var):
    def one(what):
        return lambda: Reg(cx.hit(what).r, 1) if not cx.estimate else 0.0
    out = {"Position": lambda: cx.hit(IN_POSITION, variant=var), "Normal": lambda: cx.hit(IN_NORMAL),
           "Tangent": lambda: radial_tangent(cx, "Z", var), "True Normal": lambda: cx.hit(IN_TRUE_NORMAL),
           "Incoming": lambda: cx.hit(IN_INCOMING), "Parametric": lambda: cx.hit(IN_PARAMETRIC, variant=var),
           "Backfacing": one(IN_BACKFACING), "Pointiness": lambda: cx._stand_in(node, "Pointiness", 0.5),
           "Random Per Island": lambda: cx._stand_in(node, "Random Per Island", 0.0)}
    return _Lazy(out)


@node('object_info', [], [_v("Location"), _c("Color"), _f("Alpha"), _f("Object Index"), _f("Material Index"),
      _f("Random")])
def _object_info(cx, node, var):
    def one(what):
        return lambda: Reg(cx.hit(what).r, 1) if not cx.estimate else 0.0
    return _Lazy({"Location": lambda: cx.hit(IN_OBJ_LOCATION), "Color": lambda: (1.0, 1.0, 1.0),
                  "Alpha": lambda: 1.0, "Object Index": one(IN_OBJ_INDEX),
                  "Material Index": lambda: cx._stand_in(node, "Material Index", 0.0),
                  "Random": one(IN_OBJ_RANDOM)})


@node('light_path', [], [_f(n) for n in ("Is Camera Ray", "Is Shadow Ray", "Is Diffuse Ray", "Is Glossy Ray",
      "Is Singular Ray", "Is Reflection Ray", "Is Transmission Ray",
      "Ray Length", "Ray Depth", "Diffuse Depth", "Glossy Depth",
      "Transparent Depth", "Transmission Depth")])
def _light_path(cx, node, var):
    def one(what):
        return lambda: Reg(cx.hit(what).r, 1) if not cx.estimate else (1.0 if what == IN_IS_CAMERA
                                                                             else 0.0)
    return _Lazy({"Is Camera Ray": one(IN_IS_CAMERA), "Is Shadow Ray": one(IN_IS_SHADOW),
                  "Is Diffuse Ray": lambda: 0.0, "Is Glossy Ray": one(IN_IS_REFLECTION),
                  "Is Singular Ray": one(IN_IS_REFLECTION), "Is Reflection Ray": one(IN_IS_REFLECTION),
                  "Is Transmission Ray": lambda: 0.0, "Ray Length": one(IN_RAY_LENGTH),
                  "Ray Depth": one(IN_RAY_DEPTH), "Diffuse Depth": lambda: 0.0,
                  "Glossy Depth": one(IN_RAY_DEPTH), "Transparent Depth": lambda: 0.0,
                  "Transmission Depth": lambda: 0.0})


@node('uvmap', [], [_v("UV")], attribute="")
def _uvmap(cx, node, var):
    return {"UV": cx.uv(node.param("attribute") or "", var)}


@node('attribute', [], [_c("Color"), _v("Vector"), _f("Fac"), _f("Alpha")], attribute="",
      attribute_type="GEOMETRY")
def _attribute(cx, node, var):
    name = node.param("attribute") or ""
    if node.param("attribute_type") not in (None, "GEOMETRY"):
        cx.warn(node.name, f"Attribute {node.name!r}: {node.param('attribute_type')} attributes are not "
                             "supported; white is used")
        return {"Color": (1.0, 1.0, 1.0), "Vector": (1.0, 1.0, 1.0), "Fac": 1.0, "Alpha": 1.0}
    # (the name test first: asking uv_index for a name reserves a UV set for it, which no mesh would fill)
    if name and name in getattr(cx.uv_index, "names", ()) and cx.uv_index(name) is not None:
        uvv = cx.uv(name, var)
        return {"Color": uvv, "Vector": uvv, "Fac": cx.convert(uvv, VECTOR, FLOAT), "Alpha": 1.0}
    if name not in cx.vertex_colors:
        cx.vertex_colors.append(name)
    c = cx.hit(IN_COLOR, variant=var)
    # Fac: the mean of the components, as Cycles' svm_node_attr_store (not the colour's luminance)
    return {"Color": c, "Vector": c, "Fac": cx.convert(c, VECTOR, FLOAT), "Alpha": 1.0}


@node('vertex_color', [], [_c("Color"), _f("Alpha")], layer_name="")
def _vertex_color(cx, node, var):
    name = node.param("layer_name") or ""
    if name not in cx.vertex_colors:
        cx.vertex_colors.append(name)
    return _Lazy({"Color": lambda: cx.hit(IN_COLOR, variant=var), "Alpha": lambda: 1.0})


@node('fresnel', [_f("IOR", 1.5), _N], [_f("Fac")])
def _fresnel(cx, node, var):
    ior, n = cx.inp(node, "IOR", FLOAT, var), cx.inp(node, "Normal", VECTOR, var)
    if cx.estimate:
        return {"Fac": float(ops.math_op(ops.M_POWER, (float(ior) - 1) / (float(ior) + 1), 2.0, 0.0))
                if is_const(ior) else 0.04}
    return {"Fac": cx.op("fresnel", [(ior, 1), (n, 3)])}


@node('layer_weight', [_f("Blend", 0.5), _N], [_f("Fresnel"), _f("Facing")])
def _layer_weight(cx, node, var):
    b, n = cx.inp(node, "Blend", FLOAT, var), cx.inp(node, "Normal", VECTOR, var)
    if cx.estimate:
        return {"Fresnel": 0.1, "Facing": 0.3}
    r = cx.op("layer_weight", [(b, 1), (n, 3)])
    return {"Fresnel": Reg(r.r, 1), "Facing": Reg(r.r + 1, 1)}


def radial_tangent(cx, axis: str = "Z", var: int = 0):
    """Cycles' radial tangent about the object's ``axis`` (``svm_node_tangent``; Z: ``primitive_tangent``, the
    Geometry node's Tangent and the default of a BSDF's Tangent input): axis × (Generated − ½) taken to world space
    as a normal, then made normal to N: N × normalize(T × N)."""
    if cx.estimate:
        return (1.0, 0.0, 0.0)
    g = cx.vmath(ops.V_SUBTRACT, cx.hit(IN_GENERATED, variant=var), (0.5, 0.5, 0.5))[0]
    a = {"X": (1.0, 0.0, 0.0), "Y": (0.0, -1.0, 0.0)}.get(str(axis).upper(), (0.0, 0.0, 1.0))
    t = cx.vmath(ops.V_CROSS_PRODUCT, a, g)[0]  # X: (0, −z, y), Y: (−z, 0, x), Z: (−y, x, 0) of Generated − ½
    t = cx.op("vtransform", [(t, 3)], imm=2 | 1 << 2)  # a normal, object to world
    n = cx.hit(IN_NORMAL)
    return cx.vmath(ops.V_CROSS_PRODUCT, n, cx.vmath(ops.V_NORMALIZE, cx.vmath(ops.V_CROSS_PRODUCT, t, n)[0])[0])[0]


@node('tangent', [], [_v("Tangent")], direction_type="UV_MAP", uv_map="", axis="Z")
def _tangent(cx, node, var):
    if str(node.param("direction_type") or "UV_MAP").upper() == "RADIAL":
        return {"Tangent": radial_tangent(cx, node.param("axis") or "Z", var)}
    k = cx.uv_index(node.param("uv_map") or "") or 0
    return {"Tangent": cx.hit(IN_TANGENT, arg=k)}


@node('environment_texture', [_v("Vector", GENERATED)], [_c("Color"), _f("Alpha")], image=None,
      projection="EQUIRECTANGULAR", interpolation="Linear")
def _environment_texture(cx, node, var):  # a world's: the equirectangular map of the direction
    img = node.param("image")
    if img is None or str(node.param("projection")).upper() != "EQUIRECTANGULAR":
        cx.warn(node.name, f"Environment Texture {node.name!r}: "
                             f"{'no image' if img is None else 'Mirror Ball projection is not evaluated'}; "
                             "black is used")
        return {"Color": (0.0, 0.0, 0.0), "Alpha": 0.0}
    coord = cx.inp(node, "Vector", VECTOR, var)
    c, a = cx._rgba_out(cx.image(TextureUse(img, -1), coord, node.name, 4))
    return {"Color": c, "Alpha": a}


@node('image_texture', [_v("Vector", UV)], [_c("Color"), _f("Alpha")], image=None, projection="FLAT",
      projection_blend=0.0, interpolation="Linear", extension=None)
def _image_texture(cx, node, var):
    img = node.param("image")
    if img is None:
        cx.warn(node.name, f"Image Texture {node.name!r} has no image; black is used")
        return {"Color": (0.0, 0.0, 0.0), "Alpha": 0.0}
    ext = node.param("extension")
    if ext is not None:
        wrap = {"REPEAT": "repeat", "EXTEND": "clamp", "CLIP": "black", "MIRROR": "mirror"}[str(ext).upper()]
        img = _with_wrap(img, wrap)
    coord = cx.inp(node, "Vector", VECTOR, var)
    proj = ("FLAT", "BOX", "SPHERE", "TUBE").index(str(node.param("projection") or "FLAT").upper())
    c, a = cx._rgba_out(cx.image(TextureUse(img, -1), coord, node.name, proj,
                                     float(node.param("projection_blend") or 0.0)))
    return {"Color": c, "Alpha": a}


@node('checker_texture', [_v("Vector", GENERATED), _c("Color1"), _c("Color2", (0.2, 0.2, 0.2)),
      _f("Scale", 5.0)], [_c("Color"), _f("Fac")])
def _checker_texture(cx, node, var):
    v = cx.inp(node, "Vector", VECTOR, var)
    c1, c2, sc = (cx.inp(node, k, None, var) for k in ("Color1", "Color2", "Scale"))
    if cx.estimate and is_const(c1) and is_const(c2):
        return {"Color": tuple(0.5 * (a + b) for a, b in zip(vec3(c1), vec3(c2))), "Fac": 0.5}
    r = cx.op("checker", [(v, 3), (c1, 3), (c2, 3), (sc, 1)])
    return {"Color": part(r, 0, 3), "Fac": part(r, 3)}


@node('noise_texture', [_v("Vector", GENERATED), _f("W"), _f("Scale", 5.0), _f("Detail", 2.0),
      _f("Roughness", 0.5), _f("Lacunarity", 2.0), _f("Offset"), _f("Gain", 1.0),
      _f("Distortion")], [_f("Fac"), _c("Color")], noise_dimensions="3D", noise_type="FBM",
      normalize=True, proof=_CYCLES_PROC + ', ' + _CYCLES_NODES)
def _noise_texture(cx, node, var):
    dim = int(str(node.param("noise_dimensions"))[0])
    kind = pnoise.NOISE_TYPES[str(node.param("noise_type")).upper()]
    if cx.estimate:
        return {"Fac": 0.5, "Color": (0.5, 0.5, 0.5)}
    names = ["W", "Scale", "Detail", "Roughness", "Lacunarity", "Offset", "Gain", "Distortion"]
    imm = dim | kind << 4 | int(bool(node.param("normalize"))) << 8
    made = {}

    def colour():  # the full node (three times the work of Fac alone: Cycles' noise_value vs noise_texture)
        if "c" not in made:
            made["c"] = cx._proc("noise", node, var, names, imm | 1 << 12)
        return made["c"]

    def fac():
        if "c" in made:
            return Reg(made["c"].r, 1)
        return Reg(cx._proc("noise", node, var, names, imm).r, 1)
    return _Lazy({"Fac": fac, "Color": lambda: Reg(colour().r + 1, 3)})


@node('voronoi_texture', [_v("Vector", GENERATED), _f("W"), _f("Scale", 5.0), _f("Detail"), _f("Roughness", 0.5),
      _f("Lacunarity", 2.0), _f("Smoothness", 1.0), _f("Exponent", 0.5),
      _f("Randomness", 1.0)],
      [_f("Distance"), _c("Color"), _v("Position"), _f("W"), _f("Radius")],
      voronoi_dimensions="3D", feature="F1", distance="EUCLIDEAN", normalize=False, proof=_CYCLES_PROC + ', ' + _CYCLES_NODES)
def _voronoi_texture(cx, node, var):
    dim = int(str(node.param("voronoi_dimensions"))[0])
    feat = pvor.FEATURES[str(node.param("feature")).upper()]
    metric = pvor.METRICS[str(node.param("distance")).upper()]
    if cx.estimate:
        return {"Distance": 0.5, "Color": (0.5, 0.5, 0.5), "Position": (0.5, 0.5, 0.5), "W": 0.5, "Radius": 0.5}
    r = cx._proc("voronoi", node, var, ["W", "Scale", "Detail", "Roughness", "Lacunarity", "Smoothness",
                                              "Exponent", "Randomness"],
                   dim | feat << 4 | metric << 8 | int(bool(node.param("normalize"))) << 12)
    return {"Distance": Reg(r.r, 1), "Color": Reg(r.r + 1, 3), "Position": Reg(r.r + 4, 3), "W": Reg(r.r + 7, 1),
            "Radius": Reg(r.r + 8, 1)}


@node('wave_texture', [_v("Vector", GENERATED), _f("Scale", 5.0), _f("Distortion"), _f("Detail", 2.0),
      _f("Detail Scale", 1.0), _f("Detail Roughness", 0.5), _f("Phase Offset")],
      [_c("Color"), _f("Fac")], wave_type="BANDS", bands_direction="X", rings_direction="X",
      wave_profile="SIN", proof=_CYCLES_PROC + ', ' + _CYCLES_NODES)
def _wave_texture(cx, node, var):
    kind = ppat.WAVE_TYPES[str(node.param("wave_type")).upper()]
    dirs = ppat.BANDS_DIRECTIONS if kind == ppat.BANDS else ppat.RINGS_DIRECTIONS
    direction = dirs[str(node.param("bands_direction" if kind == ppat.BANDS else "rings_direction")).upper()]
    prof = ppat.WAVE_PROFILES[str(node.param("wave_profile")).upper()]
    if cx.estimate:
        return {"Fac": 0.5, "Color": (0.5, 0.5, 0.5)}
    r = cx._proc("wave", node, var, ["Scale", "Distortion", "Detail", "Detail Scale", "Detail Roughness",
                                           "Phase Offset"], kind | direction << 4 | prof << 8)
    return {"Fac": r, "Color": cx.convert(r, FLOAT, COLOR)}


@node('magic_texture', [_v("Vector", GENERATED), _f("Scale", 5.0), _f("Distortion", 1.0)], [_c("Color"), _f("Fac")],
      turbulence_depth=2, proof=_CYCLES_PROC + ', ' + _CYCLES_NODES)
def _magic_texture(cx, node, var):
    if cx.estimate:
        return {"Fac": 0.5, "Color": (0.5, 0.5, 0.5)}
    r = cx._proc("magic", node, var, ["Scale", "Distortion"], int(node.param("turbulence_depth")) & 15)
    return {"Color": Reg(r.r, 3), "Fac": Reg(r.r + 3, 1)}


@node('gradient_texture', [_v("Vector", GENERATED)], [_c("Color"), _f("Fac")], gradient_type="LINEAR", proof=_CYCLES_PROC + ', ' + _CYCLES_NODES)
def _gradient_texture(cx, node, var):
    kind = ppat.GRADIENT_TYPES[str(node.param("gradient_type")).upper()]
    if cx.estimate:
        return {"Fac": 0.5, "Color": (0.5, 0.5, 0.5)}
    r = cx._proc("gradient", node, var, [], kind)
    return {"Fac": r, "Color": cx.convert(r, FLOAT, COLOR)}


@node('brick_texture', [_v("Vector", GENERATED), _c("Color1"), _c("Color2", (0.2, 0.2, 0.2)),
      _c("Mortar", (0.0, 0.0, 0.0)), _f("Scale", 5.0), _f("Mortar Size", 0.02),
      _f("Mortar Smooth", 0.1), _f("Bias"), _f("Brick Width", 0.5), _f("Row Height", 0.25)],
      [_c("Color"), _f("Fac")], offset=0.5, offset_frequency=2, squash=1.0, squash_frequency=2, proof=_CYCLES_PROC + ', ' + _CYCLES_NODES)
def _brick_texture(cx, node, var):
    if cx.estimate:
        c1, c2 = cx.inp(node, "Color1", None, var), cx.inp(node, "Color2", None, var)
        mean = tuple(0.5 * (a + b) for a, b in zip(vec3(c1), vec3(c2))) if is_const(c1) and is_const(c2) \
            else (0.5, 0.5, 0.5)
        return {"Color": mean, "Fac": 0.1}
    names = ["Color1", "Color2", "Mortar", "Scale", "Mortar Size", "Mortar Smooth", "Bias", "Brick Width",
             "Row Height"]
    vals = [cx.inp(node, n, None, var) for n in names] + [
        float(node.param("offset")), float(node.param("offset_frequency")), float(node.param("squash")),
        float(node.param("squash_frequency"))]
    v = cx.inp(node, "Vector", VECTOR, var)
    blk = cx.block(cx._flat(vals))
    r = cx.op("brick", [(v, 3), blk.r], raw={"reads": [(blk.r, blk.n)]})
    return {"Color": Reg(r.r, 3), "Fac": Reg(r.r + 3, 1)}


@node('white_noise_texture', [_v("Vector", GENERATED), _f("W")], [_f("Value"), _c("Color")],
      noise_dimensions="3D", proof=_CYCLES_PROC + ', ' + _CYCLES_NODES)
def _white_noise_texture(cx, node, var):
    dim = int(str(node.param("noise_dimensions"))[0])
    if cx.estimate:
        return {"Value": 0.5, "Color": (0.5, 0.5, 0.5)}
    r = cx._proc("white_noise", node, var, ["W"], dim)
    return {"Value": Reg(r.r, 1), "Color": Reg(r.r + 1, 3)}


@node('mix_color', [_f("Factor", 0.5), _c("A", (0.5, 0.5, 0.5)), _c("B", (0.5, 0.5, 0.5))], [_c("Result")],
      blend_type="MIX", use_clamp=False, use_clamp_result=False, proof=_CYCLES_OPS)
def _mix_color(cx, node, var):
    blend = _enum("mix_color.blend_type", node.param("blend_type"))
    f, a, b = (cx.inp(node, "Factor", FLOAT, var), cx.inp(node, "A", COLOR, var),
               cx.inp(node, "B", COLOR, var))
    clamp_f, clamp_r = bool(node.param("use_clamp")), bool(node.param("use_clamp_result"))
    if blend == ops.B_MIX and not clamp_r and is_const(f) and (not clamp_f or 0.0 <= float(f) <= 1.0) and not (
            is_const(a) and is_const(b)):
        return {"Result": cx.lerp3(a, b, f)}
    return {"Result": cx.op("mix_c", [(f, 1), (a, 3), (b, 3)],
                            imm=blend | (256 if clamp_f else 0) | (512 if clamp_r else 0))}


@node('mix_float', [_f("Factor", 0.5), _f("A"), _f("B")], [_f("Result")], use_clamp=True)
def _mix_float(cx, node, var):
    f, a, b = cx.inp(node, "Factor", FLOAT, var), cx.inp(node, "A", FLOAT, var), cx.inp(node, "B", FLOAT, var)
    return {"Result": cx.op("mix_f", [(f, 1), (a, 1), (b, 1)], imm=int(bool(node.param("use_clamp"))))}


@node('mix_vector', [_f("Factor", 0.5), _v("A"), _v("B")], [_v("Result")], use_clamp=True)
def _mix_vector(cx, node, var):
    f, a, b = (cx.inp(node, "Factor", FLOAT, var), cx.inp(node, "A", VECTOR, var),
               cx.inp(node, "B", VECTOR, var))
    return {"Result": cx.op("mix_v", [(f, 1), (a, 3), (b, 3)], imm=int(bool(node.param("use_clamp"))))}


@node('mix_vector_non_uniform', [_v("Factor", (0.5, 0.5, 0.5)), _v("A"), _v("B")], [_v("Result")],
      use_clamp=True)
def _mix_vector_non_uniform(cx, node, var):
    f, a, b = (cx.inp(node, "Factor", VECTOR, var), cx.inp(node, "A", VECTOR, var),
               cx.inp(node, "B", VECTOR, var))
    return {"Result": cx.op("mix_vn", [(f, 3), (a, 3), (b, 3)], imm=int(bool(node.param("use_clamp"))))}


@node('invert', [_f("Fac", 1.0), _c("Color", (0.0, 0.0, 0.0))], [_c("Color")])
def _invert(cx, node, var):
    f, c = cx.inp(node, "Fac", FLOAT, var), cx.inp(node, "Color", COLOR, var)
    return {"Color": cx.op("invert", [(c, 3), (f, 1)])}


@node('gamma', [_c("Color", (1, 1, 1)), _f("Gamma", 1.0)], [_c("Color")])
def _gamma(cx, node, var):
    c, g = cx.inp(node, "Color", COLOR, var), cx.inp(node, "Gamma", FLOAT, var)
    return {"Color": cx.op("gamma", [(c, 3), (g, 1)])}


@node('brightness_contrast', [_c("Color", (1, 1, 1)), _f("Bright"), _f("Contrast")], [_c("Color")])
def _brightness_contrast(cx, node, var):
    c, br, co = (cx.inp(node, "Color", COLOR, var), cx.inp(node, "Bright", FLOAT, var),
                 cx.inp(node, "Contrast", FLOAT, var))
    return {"Color": cx.op("bright", [(c, 3), (br, 1), (co, 1)])}


@node('hsv', [_f("Hue", 0.5), _f("Saturation", 1.0), _f("Value", 1.0), _f("Fac", 1.0), _c("Color")],
      [_c("Color")], proof=_CYCLES_PROC + ', ' + _CYCLES_NODES)
def _hsv(cx, node, var):
    h, s, v, f, c = (cx.inp(node, k, None, var) for k in ("Hue", "Saturation", "Value", "Fac", "Color"))
    return {"Color": cx.op("hsv", [(c, 3), (h, 1), (s, 1), (v, 1), (f, 1)])}


def _curve_node(cx, node, var, kind, inp_name, out_name, fac_name):
    table = np.asarray(node.param("curves"), np.float64) if node.param("curves") is not None else None
    x = cx.inp(node, inp_name, None, var)
    fac = cx.inp(node, fac_name, FLOAT, var)
    if table is None:
        return {out_name: x}
    lo, hi = (float(x) for x in node.param("range"))
    k = cx.e.const((lo, hi, float(table.shape[1])) + tuple(table.T.reshape(-1)))
    n = 1 if kind == 2 else 3
    return {out_name: cx.op("curve", [(x, n), (k, 3 + table.size), table.shape[0], (fac, 1)], imm=kind)}


@node('rgb_curves', [_f("Fac", 1.0), _c("Color", (1, 1, 1))], [_c("Color")], curves=None, range=(0.0, 1.0))
def _rgb_curves(cx, node, var):
    return _curve_node(cx, node, var, 0, "Color", "Color", "Fac")


@node('rgb_ramp', [_f("Fac", 0.5)], [_c("Color"), _f("Alpha")], ramp=None, interpolation="LINEAR",
      color_mode="RGB", hue_interpolation="NEAR", proof=_CYCLES_PROC + ', ' + _CYCLES_NODES)
def _rgb_ramp(cx, node, var):
    ramp = node.param("ramp")
    interp = str(node.param("interpolation") or "LINEAR").upper()
    f = cx.inp(node, "Fac", FLOAT, var)
    if not ramp:
        return {"Color": (0.0, 0.0, 0.0), "Alpha": 1.0}
    stops = sorted(((float(p), tuple(float(x) for x in (tuple(c) + (1.0,))[:4])) for p, c in ramp),
                   key=lambda s: s[0])
    table = pcolor.color_ramp_table([p for p, _c in stops], [c for _p, c in stops], interp,
                                    str(node.param("color_mode") or "RGB").upper(),
                                    str(node.param("hue_interpolation") or "NEAR").upper())
    k = cx.e.const(tuple(np.asarray(table, np.float64).reshape(-1)))
    r = cx.op("ramp", [(f, 1), (k, table.size), len(table)], imm=int(interp != "CONSTANT"))
    return {"Color": part(r, 0, 3), "Alpha": part(r, 3)}


@node('blackbody', [_f("Temperature", 1500.0)], [_c("Color")], proof=_CYCLES_PROC + ', ' + _CYCLES_NODES)
def _blackbody(cx, node, var):
    return {"Color": cx.op("blackbody", [(cx.inp(node, "Temperature", FLOAT, var), 1)])}


@node('wavelength', [_f("Wavelength", 500.0)], [_c("Color")], proof=_CYCLES_PROC + ', ' + _CYCLES_NODES)
def _wavelength(cx, node, var):
    return {"Color": cx.op("wavelength", [(cx.inp(node, "Wavelength", FLOAT, var), 1)])}


@node('rgb_to_bw', [_c("Color", (0.5, 0.5, 0.5))], [_f("Val")])
def _rgb_to_bw(cx, node, var):  # whatever feeds it is a colour first (a vector as is), then its luminance
    return {"Val": cx.convert(cx.inp(node, "Color", COLOR, var), COLOR, FLOAT)}


@node('separate_color', [_c("Color")], [_f("Red"), _f("Green"), _f("Blue")], color_mode="RGB")
def _separate_color(cx, node, var):
    mode = _enum("color_mode", node.param("color_mode"))
    c = cx.inp(node, "Color", COLOR, var)
    if mode:
        c = cx.op("sep_color", [(c, 3)], imm=mode)
    return {"Red": part(c, 0), "Green": part(c, 1), "Blue": part(c, 2)}


@node('combine_color', [_f("Red"), _f("Green"), _f("Blue")], [_c("Color")], color_mode="RGB")
def _combine_color(cx, node, var):
    mode = _enum("color_mode", node.param("color_mode"))
    x, y, z = (cx.inp(node, s, FLOAT, var) for s in ("Red", "Green", "Blue"))
    return {"Color": cx.op("comb_color", [(x, 1), (y, 1), (z, 1)], imm=mode)}


@node('separate_xyz', [_v("Vector")], [_f("X"), _f("Y"), _f("Z")])
def _separate_xyz(cx, node, var):
    v = cx.inp(node, "Vector", VECTOR, var)
    return {"X": part(v, 0), "Y": part(v, 1), "Z": part(v, 2)}


@node('combine_xyz', [_f("X"), _f("Y"), _f("Z")], [_v("Vector")])
def _combine_xyz(cx, node, var):
    return {"Vector": cx.op("combine", [(cx.inp(node, s, FLOAT, var), 1) for s in "XYZ"])}


@node('math', [_f("Value", 0.5), _f("Value_001", 0.5), _f("Value_002", 0.5)], [_f("Value")], operation="ADD",
      use_clamp=False, proof=_CYCLES_OPS)
def _math(cx, node, var):
    op = _enum("math.operation", node.param("operation"))
    a, b, c = (cx.inp(node, s, FLOAT, var) for s in ("Value", "Value_001", "Value_002"))
    return {"Value": cx.math(op, a, b, c, bool(node.param("use_clamp")))}


@node('vector_math', [_v("Vector"), _v("Vector_001"), _v("Vector_002"), _f("Scale", 1.0)],
      [_v("Vector"), _f("Value")], operation="ADD", proof=_CYCLES_OPS)
def _vector_math(cx, node, var):
    op = _enum("vector_math.operation", node.param("operation"))
    a, b, c = (cx.inp(node, s, VECTOR, var) for s in ("Vector", "Vector_001", "Vector_002"))
    s = cx.inp(node, "Scale", FLOAT, var) if op in (ops.V_SCALE, ops.V_REFRACT) else 1.0
    if op == ops.V_REFRACT:
        s = cx.inp(node, "Scale", FLOAT, var)  # Blender's IOR socket of Refract is the Scale socket
    v, x = cx.vmath(op, a, b, c, s)
    return {"Vector": v, "Value": x}


@node('map_range', [_f("Value", 1.0), _f("From Min"), _f("From Max", 1.0), _f("To Min"), _f("To Max", 1.0),
      _f("Steps", 4.0)], [_f("Result")], interpolation_type="LINEAR", clamp=True, proof=_CYCLES_OPS)
def _map_range(cx, node, var):
    kind = _enum("map_range.interpolation_type", node.param("interpolation_type"))
    xs = [cx.inp(node, k, FLOAT, var) for k in ("Value", "From Min", "From Max", "To Min", "To Max", "Steps")]
    return {"Result": cx.op("map_range", [(x, 1) for x in xs], imm=kind | (256 if node.param("clamp") else 0))}


@node('vector_map_range', [_v("Vector"), _v("From Min"), _v("From Max", (1, 1, 1)), _v("To Min"),
      _v("To Max", (1, 1, 1)), _v("Steps", (4, 4, 4))], [_v("Vector")],
      interpolation_type="LINEAR", clamp=True)
def _vector_map_range(cx, node, var):
    kind = _enum("map_range.interpolation_type", node.param("interpolation_type"))
    xs = [cx.inp(node, k, VECTOR, var) for k in ("Vector", "From Min", "From Max", "To Min", "To Max", "Steps")]
    return {"Vector": cx.op("map_range_v", [(x, 3) for x in xs], imm=kind | (256 if node.param("clamp") else 0))}


@node('clamp', [_f("Value", 1.0), _f("Min"), _f("Max", 1.0)], [_f("Result")], clamp_type="MINMAX", proof=_CYCLES_OPS)
def _clamp(cx, node, var):
    kind = _enum("clamp.clamp_type", node.param("clamp_type"))
    x, lo, hi = (cx.inp(node, k, FLOAT, var) for k in ("Value", "Min", "Max"))
    return {"Result": cx.op("clamp", [(x, 1), (lo, 1), (hi, 1)], imm=kind)}


@node('float_curve', [_f("Factor", 1.0), _f("Value", 1.0)], [_f("Value")], curves=None, range=(0.0, 1.0))
def _float_curve(cx, node, var):
    return _curve_node(cx, node, var, 2, "Value", "Value", "Factor")


@node('vector_curves', [_f("Fac", 1.0), _v("Vector")], [_v("Vector")], curves=None, range=(0.0, 1.0))
def _vector_curves(cx, node, var):
    return _curve_node(cx, node, var, 1, "Vector", "Vector", "Fac")


@node('mapping', [_v("Vector"), _v("Location"), _v("Rotation"), _v("Scale", (1, 1, 1))], [_v("Vector")],
      vector_type="POINT")
def _mapping(cx, node, var):
    kind = _enum("mapping.vector_type", node.param("vector_type"))
    v = cx.inp(node, "Vector", VECTOR, var)
    loc, rot, scl = (cx.inp(node, k, VECTOR, var) for k in ("Location", "Rotation", "Scale"))
    if kind >= 2:
        loc = (0.0, 0.0, 0.0)
    if is_const(loc) and is_const(rot) and is_const(scl) and vec3(loc) == (0.0,) * 3 and \
            vec3(rot) == (0.0,) * 3 and vec3(scl) == (1.0,) * 3 and kind != 3:
        return {"Vector": v}
    return {"Vector": cx.op("mapping", [(v, 3), (loc, 3), (rot, 3), (scl, 3)], imm=kind,
                            uv=v.uv if isinstance(v, Reg) else -1)}


@node('vector_rotate', [_v("Vector"), _v("Center"), _v("Axis", (0, 0, 1)), _f("Angle"), _v("Rotation")],
      [_v("Vector")], rotation_type="AXIS_ANGLE", invert=False)
def _vector_rotate(cx, node, var):
    kind = _enum("vector_rotate.rotation_type", node.param("rotation_type"))
    xs = [cx.inp(node, k, None, var) for k in ("Vector", "Center", "Axis", "Angle", "Rotation")]
    return {"Vector": cx.op("vrotate", [(xs[0], 3), (xs[1], 3), (xs[2], 3), (xs[3], 1), (xs[4], 3)],
                            imm=kind | (8 if node.param("invert") else 0))}


@node('vector_transform', [_v("Vector", (0.5, 0.5, 0.5))], [_v("Vector")], vector_type="VECTOR",
      convert_from="WORLD", convert_to="OBJECT")
def _vector_transform(cx, node, var):
    kind = _enum("vector_transform.vector_type", node.param("vector_type"))
    src, dst = _enum("space", node.param("convert_from")), _enum("space", node.param("convert_to"))
    v = cx.inp(node, "Vector", VECTOR, var)
    if src == dst:
        return {"Vector": v}
    if cx.estimate:
        return {"Vector": v if is_const(v) else (0.0, 0.0, 0.0)}
    return {"Vector": cx.op("vtransform", [(v, 3)], imm=kind | src << 2 | dst << 4)}


@node('normal_map', [_f("Strength", 1.0), _c("Color", (0.5, 0.5, 1.0))], [_v("Normal")], space="TANGENT",
      uv_map="")
def _normal_map(cx, node, var):
    space = _enum("normal_map.space", node.param("space"))
    strength, col = cx.inp(node, "Strength", FLOAT, var), cx.inp(node, "Color", COLOR, var)
    if cx.estimate:
        return {"Normal": (0.0, 0.0, 1.0)}
    if space == 0 and is_const(col) and np.allclose(vec3(col), (0.5, 0.5, 1.0)):
        return {"Normal": cx.hit(IN_NORMAL)}
    k = -1
    if space == 0:
        uv_map = node.param("uv_map")
        k = uv_map if isinstance(uv_map, (int, np.integer)) else cx.uv_index(uv_map or "")
        if k is None:
            cx.warn(node.name + "uv", f"Normal Map {node.name!r}: UV map {uv_map!r} is not known; the default "
                                        "one is used")
            k = 0
    return {"Normal": cx.op("normal_map", [(col, 3), (strength, 1), int(k)], imm=space)}


@node('bump', [_f("Strength", 1.0), _f("Distance", 1.0), _f("Filter Width", 0.1), _f("Height", 1.0), _N],
      [_v("Normal")], invert=False, proof=_CYCLES_OPS)
def _bump(cx, node, var):
    nrm = cx.inp(node, "Normal", VECTOR, var)
    if cx.estimate:
        return {"Normal": (0.0, 0.0, 1.0)}
    h0 = cx.inp(node, "Height", FLOAT, 0)
    if is_const(h0):
        return {"Normal": nrm}
    cx.bump_filter_width(cx.inp(node, "Filter Width", FLOAT, 0))  # before the offset heights read the offsets
    hx, hy = cx.inp(node, "Height", FLOAT, 1), cx.inp(node, "Height", FLOAT, 2)
    strength, dist = cx.inp(node, "Strength", FLOAT, var), cx.inp(node, "Distance", FLOAT, var)
    if node.param("invert"):
        dist = cx.math(ops.M_MULTIPLY, dist, -1.0)
    setup = cx.bump_setup()
    return {"Normal": cx.op("bump", [(h0, 1), (hx, 1), (hy, 1), (strength, 1), (dist, 1), (nrm, 3)],
                                  imm=setup.r, raw={"reads": [(setup.r, 10)]})}


@node('displacement', [_f("Height"), _f("Midlevel", 0.5), _f("Scale", 1.0), _N], [_v("Displacement")],
      space="OBJECT")
def _displacement(cx, node, var):
    h, mid, sc = (cx.inp(node, k, FLOAT, var) for k in ("Height", "Midlevel", "Scale"))
    nrm = cx.inp(node, "Normal", VECTOR, var)
    amount = cx.math(ops.M_MULTIPLY, cx.math(ops.M_SUBTRACT, h, mid), sc)
    return {"Displacement": cx.scale3(nrm, amount)}


# MaterialX's noise2d/3d, fractal2d/3d, cellnoise2d/3d, worleynoise2d/3d (tracer.shading.procedural.mx_noise): kind

# perlin | cell | worley | fractal, dimensions 2 | 3, width 1-4 (float, vector2, vector3/color3, vector4/color4),

# style 0 distance | 1 solid (worley). Value = x, Vector = (x, y, z), W = w of the node's result.

@node('mx_noise', [_v("Vector", GENERATED), _v("Amplitude", (1, 1, 1)), _f("Amplitude W", 1.0), _f("Pivot"),
      _f("Octaves", 3.0), _f("Lacunarity", 2.0), _f("Diminish", 0.5), _f("Jitter", 1.0)],
      [_f("Value"), _v("Vector"), _f("W")], kind="perlin", dimensions=3, width=1, style=0, proof='tests/test_usd_mtlx.py (MaterialX reference values)')
def _mx_noise(cx, node, var):
    """MaterialX's noise nodes (tracer.shading.procedural.mx_noise); one op, all outputs."""
    if cx.estimate:
        return {"Value": 0.5, "Vector": (0.5, 0.5, 0.5), "W": 0.5}
    imm = (pmx.KINDS.index(str(node.param("kind"))) | int(node.param("dimensions")) << 4
           | int(node.param("width")) << 8 | int(node.param("style")) << 12)
    r = cx._proc("mx_noise", node, var, ["Amplitude", "Amplitude W", "Pivot", "Octaves", "Lacunarity",
                                               "Diminish", "Jitter"], imm)
    return {"Value": Reg(r.r, 1), "Vector": Reg(r.r, 3), "W": Reg(r.r + 3, 1)}


# UsdUVTexture: image (an ImageRef, wrap from it), st, scale/bias per channel, fallback where the mesh has no

# coordinates. Outputs r, g, b, a and rgb as in the spec.

@node('usd_uv_texture', [_v("st", UV)], [_f("r"), _f("g"), _f("b"), _f("a"), _c("rgb")], image=None,
      scale=(1.0, 1.0, 1.0, 1.0), bias=(0.0, 0.0, 0.0, 0.0), fallback=(0.0, 0.0, 0.0, 1.0), proof='tests/cycles/test_cycles_usd_materials.py')
def _usd_uv_texture(cx, node, var):
    img = node.param("image")
    fb = tuple(float(x) for x in node.param("fallback"))
    if img is None:
        return {"r": fb[0], "g": fb[1], "b": fb[2], "a": fb[3], "rgb": fb[:3]}
    coord = cx.inp(node, "st", VECTOR, var)
    use = TextureUse(img, -1, tuple(float(x) for x in node.param("scale")),
                     tuple(float(x) for x in node.param("bias")), fb)
    rgba = cx.image(use, coord, node.name)
    if is_const(rgba):
        return {"r": rgba[0], "g": rgba[1], "b": rgba[2], "a": rgba[3], "rgb": tuple(rgba[:3])}
    return {"r": Reg(rgba.r, 1), "g": Reg(rgba.r + 1, 1), "b": Reg(rgba.r + 2, 1), "a": Reg(rgba.r + 3, 1),
            "rgb": Reg(rgba.r, 3)}


# UsdTransform2d: in · scale · rotate (degrees, counter-clockwise) + translation, on (s, t)

# (internal) a row's P_texture column: Scene.textures[index] read in its own UV set with its own transform,

# scale, bias and fallback — how rows of the table API become programs

@node('scene_texture', [], [_c("Color"), _f("Alpha")], index=0, uv_set=0, proof='tests/cycles/test_cycles_images.py')
def _scene_texture(cx, node, var):
    k_tex, uv_set = node.param("index"), node.param("uv_set")
    coord = cx.uv(int(uv_set), var) if not cx.estimate else (0.5, 0.5, 0.0)
    rgba = cx.image(TextureUse(None, int(k_tex)), coord, node.name) if not cx.estimate else \
        cx._scene_mean(int(k_tex))
    c, a = cx._rgba_out(rgba)
    return {"Color": c, "Alpha": a}


# (or ``matrix``: the 3 × 3 on (s, t, 1) of a chain of them, composed)

@node('usd_transform2d', [_v("in", UV)], [_v("result")], scale=(1.0, 1.0), rotation=0.0,
      translation=(0.0, 0.0), matrix=None, proof='tests/cycles/test_cycles_usd_materials.py')
def _usd_transform2d(cx, node, var):
    v = cx.inp(node, "in", VECTOR, var)
    m = node.param("matrix")
    if m is None:
        m = transform2d_matrix(node.param("scale"), float(node.param("rotation")), node.param("translation"))
    m = np.asarray(m, np.float64)
    if is_const(v):
        s, t = vec3(v)[:2]
        return {"result": (m[0, 0] * s + m[0, 1] * t + m[0, 2], m[1, 0] * s + m[1, 1] * t + m[1, 2], 0.0)}
    if np.allclose(m, np.eye(3)):
        return {"result": v}
    k = cx.e.const(tuple(m[:2].reshape(-1)))
    return {"result": cx.op("affine2", [(v, 3), (k, 6)], uv=v.uv)}

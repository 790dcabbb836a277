"""Compiling a material's graph (:mod:`tracer.shader_graph`) into a VM program (:mod:`tracer.shader_vm`).

    compiled = compile_graph(graph, warn, uv_index)   # once per material
    compiled.row      the material's constant row (tracer.Materials fields)
    compiled.program  None when every closure input folded to a constant, else the bytecode

What the compiler does, in order:

1. **Closures flatten** into a weighted list of lobes (Mix / Add Shader trees of any depth), which become the tracer's
   closure inputs (:data:`tracer.shader_vm.OUT_SLOTS`: one blended Principled set) and, where one closure cannot hold
   the tree (several reflecting lobes, a Glossy, Glass-beside-something, Translucent, Refraction, Holdout or tinted
   Transparent leaf), lobe slots (:mod:`tracer.lobes`): :mod:`tracer.shader_closures` does both.
2. **Outputs** are registers: each closure input's (``outs``) and each lobe slot's (``Program.lobes``).
3. **Constants fold**: every op whose operands are constants is evaluated at compile time by the same numba
   functions the VM runs (:mod:`tracer.shader_ops`), so a graph whose outputs are constants compiles to zero ops
   and its constant row; only what varies per hit is emitted. Identical ops are emitted once (CSE) and ops whose
   results nothing reads are dropped (dead-node elimination; nodes no output reaches are never visited).
4. **Bump**: the Height sub-program is emitted three times, at the hit and at the two offset points of
   ``OP_BUMP_SETUP`` (inputs that do not move with the point are shared by CSE). The Displacement output is read as
   bump of height N·displacement (one warning).

The row's constants for outputs that vary per hit are what the program gives with every image lookup replaced by
its image's mean and every hit input by a neutral value (so lights and summaries see a representative emission).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from . import shader_ops as ops
from . import shader_vm as vm
from .lobes import MAX_LOBES
from .shader_closures import ClosureLowering, LobeSlots
from .shader_graph import (CLOSURE, COLOR, ENUMS, FLOAT, IMPLICIT, NODE_TYPES, VECTOR, Graph, ImageRef, Implicit,
                           Node, Out)


class Reg(NamedTuple):
    """A value in registers r … r + n − 1 (``uv``: the UV set its coordinates came from, for the mip footprint)."""

    r: int
    n: int
    uv: int = -1
    src: object = None  # (TextureUse, coordinates, (projection, blend)) of an image lookup's colour: a constant scale
    #                     folds into it


def _is_const(x) -> bool:
    return not isinstance(x, Reg)


def _vec(x):
    """A constant as a 3-tuple of floats."""
    if np.ndim(x) == 0:
        return (float(x),) * 3
    return tuple(float(c) for c in tuple(x)[:3])


class TextureUse(NamedTuple):
    """What an image op reads: an ImageRef with the UsdUVTexture scale/bias/fallback, or a scene texture."""

    image: ImageRef | None
    scene_index: int
    scale: tuple = (1.0, 1.0, 1.0, 1.0)
    bias: tuple = (0.0, 0.0, 0.0, 0.0)
    fallback: tuple = (1.0, 1.0, 1.0, 1.0)


@dataclass
class Program:
    """One material's bytecode: ``code`` (n, WIDTH) int32 with registers relative to the material's base, the
    initial register file ``init`` (constants), ``outs`` (8,) the register of each closure input (-1: the row's
    constant), and the textures its image ops name by position (``TextureUse``)."""

    code: np.ndarray
    init: np.ndarray
    outs: np.ndarray
    textures: list
    lobes: LobeSlots | None = None  # the closure's lobe slots (tracer.shader_closures), None: one closure

    @property
    def n_ops(self) -> int:
        return len(self.code)

    def disassemble(self) -> str:
        lines = []
        for row in self.code:
            lines.append(f"{vm.OP_NAMES[row[0]]:>12} " + " ".join(str(int(x)) for x in row[1:]))
        return "\n".join(lines)


@dataclass
class Compiled:
    row: dict
    program: Program | None
    vertex_colors: list = field(default_factory=list)  # Color Attribute / colour primvar names read ('' = default)
    uv_maps: list = field(default_factory=list)  # UV map names read ('' = the default set)


# ---------------------------------------------------------------------------------------------- the emitter
class _Emitter:
    def __init__(self):
        self.code: list[list[int]] = []
        self.reads: list[list[tuple]] = []  # per op: (register, width) it reads
        self.widths: list[int] = []
        self.init: list[float] = []
        self._consts: dict = {}
        self._cse: dict = {}

    def alloc(self, n: int) -> int:
        r = len(self.init)
        self.init.extend([0.0] * n)
        return r

    def const(self, value) -> Reg:
        vals = tuple(float(x) for x in np.ravel(value))
        if vals not in self._consts:
            r = self.alloc(len(vals))
            self.init[r:r + len(vals)] = vals
            self._consts[vals] = r
        return Reg(self._consts[vals], len(vals))

    def reg(self, x, n: int) -> int:
        """Register of value x as n wide (a constant is materialised)."""
        if isinstance(x, Reg):
            return x.r
        return self.const(_vec(x) if n == 3 else (x if np.ndim(x) else float(x))).r

    def emit(self, op: int, width: int, operands: list, imm: int = 0, uv: int = -1, raw: dict | None = None) -> Reg:
        """One instruction: ``operands`` fill fields a..f in order, each (value, width) or an int (raw);
        returns its result registers (CSE: an identical instruction is emitted once)."""
        fields = []
        reads = []
        for item in operands:
            if isinstance(item, tuple) and len(item) == 2 and not isinstance(item[0], (int, np.integer)) or \
                    (isinstance(item, tuple) and isinstance(item[0], Reg)):
                x, n = item
                r = self.reg(x, n)
                fields.append(r)
                reads.append((r, n))
            else:
                fields.append(int(item))
        fields += [0] * (6 - len(fields))
        key = (op, tuple(fields), imm)
        if key in self._cse:
            return Reg(self._cse[key], width, uv)
        dst = self.alloc(width)
        self.code.append([op, dst] + fields + [imm])
        self.reads.append(reads + (raw or {}).get("reads", []))
        self.widths.append(width)
        self._cse[key] = dst
        return Reg(dst, width, uv)

    def finish(self, outs: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """Drop ops nothing reads (backwards liveness from ``outs``); the code and the initial registers."""
        live = set()
        for r, n in outs:
            live.update(range(r, r + n))
        keep = [False] * len(self.code)
        for i in range(len(self.code) - 1, -1, -1):
            dst, w = self.code[i][1], self.widths[i]
            if any(x in live for x in range(dst, dst + w)):
                keep[i] = True
                for r, n in self.reads[i]:
                    live.update(range(r, r + n))
        code = np.array([c for c, k in zip(self.code, keep) if k], np.int32).reshape(-1, vm.WIDTH)
        return code, np.array(self.init, np.float64)


def _enum(key: str, value, default_first=True) -> int:
    names = ENUMS[key]
    if value is None:
        return 0
    try:
        return names.index(str(value).upper() if key != "image_texture.interpolation" else str(value))
    except ValueError:
        raise ValueError(f"{key}: unknown value {value!r}; one of {names}") from None


# ---------------------------------------------------------------------------------------------- the compiler
class Compiler(ClosureLowering):
    """Lowers one graph (see the module docstring). ``estimate``: image lookups read their image's mean and hit
    inputs neutral values, so everything folds (the row's representative constants)."""

    def __init__(self, graph: Graph, warn=None, uv_index=None, estimate: bool = False):
        self.g = graph
        self._warn = warn
        self._said: set = set()
        self.uv_index = uv_index or (lambda name: 0 if not name else None)
        self.estimate = estimate
        self.e = _Emitter()
        self._memo: dict = {}
        self.textures: list[TextureUse] = []
        self._tex_index: dict = {}
        self._bump_setup: Reg | None = None
        self.vertex_colors: list = []
        self.uv_maps: list = []

    def warn(self, key: str, message: str) -> None:
        if key not in self._said:
            self._said.add(key)
            if self._warn is not None:
                self._warn(f"material {self.g.name!r}: {message}")

    # ------------------------------------------------------------------ values
    def val(self, ref: Out, kind: str, variant: int = 0):
        node = self.g.node(ref)
        src_kind = NODE_TYPES[node.type].output(ref.socket).kind
        key = (node.id, variant)
        if key not in self._memo:
            self._memo[key] = self.lower(node, variant)
        x = self._memo[key][ref.socket]
        return self.convert(x, src_kind, kind)

    def convert(self, x, src: str, dst: str):
        if src == dst or {src, dst} <= {VECTOR, COLOR}:
            return x
        if dst == FLOAT:
            if _is_const(x):
                v = _vec(x)
                return (0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2]) if src == COLOR else sum(v) / 3.0
            return self.e.emit(vm.OP_LUM if src == COLOR else vm.OP_AVG, 1, [(x, 3)])
        if src == FLOAT:  # to a vector / colour
            if _is_const(x):
                return (float(x),) * 3
            return self.e.emit(vm.OP_COMBINE, 3, [(x, 1), (x, 1), (x, 1)])
        return x

    def inp(self, node: Node, name: str, kind: str | None = None, variant: int = 0):
        sock = NODE_TYPES[node.type].input(name)
        kind = kind or sock.kind
        x = self.g.input_value(node, name)
        if isinstance(x, Out):
            return self.val(x, kind, variant)
        if isinstance(x, Implicit):
            return self.implicit(x, variant)
        if kind == FLOAT:
            return float(np.ravel(x)[0]) if np.ndim(x) else float(x)
        return _vec(x)

    def implicit(self, what: Implicit, variant: int = 0):
        if what.what == "normal":
            return self.hit(vm.IN_NORMAL)
        if what.what == "uv":
            return self.uv("", variant)
        if what.what == "generated":
            return self.hit(vm.IN_GENERATED, variant=variant)
        if what.what == "position":
            return self.hit(vm.IN_POSITION, variant=variant)
        return self.hit(vm.IN_TANGENT, arg=0)

    def hit(self, what: int, arg: int = 0, variant: int = 0, uv: int = -1):
        """An OP_INPUT (in estimate mode: a neutral constant)."""
        if self.estimate:
            return {vm.IN_NORMAL: (0.0, 0.0, 1.0), vm.IN_TRUE_NORMAL: (0.0, 0.0, 1.0), vm.IN_INCOMING: (0.0, 0.0, 1.0),
                    vm.IN_COLOR: (1.0, 1.0, 1.0), vm.IN_UV: (0.5, 0.5, 0.0), vm.IN_GENERATED: (0.5, 0.5, 0.5),
                    vm.IN_COLOR_ALPHA: (1.0, 0.0, 0.0), vm.IN_IS_CAMERA: (1.0, 0.0, 0.0)}.get(what, (0.0, 0.0, 0.0))
        setup = 0
        if variant > 0:
            setup = self.bump_setup().r
        return self.e.emit(vm.OP_INPUT, 3, [arg, variant, setup], imm=what, uv=uv,
                           raw={"reads": [(setup, 10)] if variant else []})

    def uv(self, name, variant: int = 0):
        if isinstance(name, (int, np.integer)):
            k = int(name)
        else:
            if name not in self.uv_maps:
                self.uv_maps.append(name)
            k = self.uv_index(name)
            if k is None:
                self.warn(f"uv {name}", f"UV map {name!r} is not known; the default one is used")
                k = 0
        return self.hit(vm.IN_UV, arg=k, variant=variant, uv=k)

    def bump_setup(self) -> Reg:
        if self._bump_setup is None:
            self._bump_setup = self.e.emit(vm.OP_BUMP_SETUP, 10, [])
        return self._bump_setup

    def scalar(self, x) -> tuple:
        return (x, 1)

    def v3(self, x) -> tuple:
        return (x, 3)

    # ------------------------------------------------------------------ generic helpers (folding)
    def math(self, op: int, a, b=0.0, c=0.0, clamp=False):
        if _is_const(a) and _is_const(b) and _is_const(c):
            x = float(ops.math_op(int(op), float(a), float(b), float(c)))
            return min(max(x, 0.0), 1.0) if clamp else x
        if op == ops.M_MULTIPLY and not clamp:
            if _is_const(a) and float(a) == 1.0:
                return b
            if _is_const(b) and float(b) == 1.0:
                return a
            if (_is_const(a) and float(a) == 0.0) or (_is_const(b) and float(b) == 0.0):
                return 0.0
        if op == ops.M_ADD and not clamp:
            if _is_const(a) and float(a) == 0.0:
                return b
            if _is_const(b) and float(b) == 0.0:
                return a
        return self.e.emit(vm.OP_MATH, 1, [(a, 1), (b, 1), (c, 1)], imm=int(op) | (256 if clamp else 0))

    def vmath(self, op: int, a, b=(0.0, 0.0, 0.0), c=(0.0, 0.0, 0.0), s=1.0):
        """(vector, value) of a Vector Math op."""
        if all(_is_const(x) for x in (a, b, c, s)):
            r = ops.vmath_op(int(op), *_vec(a), *_vec(b), *_vec(c), float(s))
            return tuple(float(x) for x in r[:3]), float(r[3])
        if op == ops.V_MULTIPLY:
            if _is_const(a) and _vec(a) == (1.0, 1.0, 1.0):
                return b, 0.0
            if _is_const(b) and _vec(b) == (1.0, 1.0, 1.0):
                return a, 0.0
            img, k = (a, b) if _is_const(b) else (b, a) if _is_const(a) else (None, None)
            if isinstance(img, Reg) and img.src is not None and img.src[0].image is not None:
                # an image × a constant: one lookup, its scale and bias scaled (a scene texture keeps its own)
                use, coord, proj = img.src
                k = _vec(k) + (1.0,)
                use = use._replace(scale=tuple(s * x for s, x in zip(use.scale, k)),
                                   bias=tuple(b_ * x for b_, x in zip(use.bias, k)),
                                   fallback=tuple(f * x for f, x in zip(use.fallback, k)))
                r = self.image(use, coord, "", *proj)
                return Reg(r.r, 3, src=r.src), 0.0
        if op == ops.V_SCALE and _is_const(s) and float(s) == 1.0:
            return a, 0.0
        r = self.e.emit(vm.OP_VMATH, 4, [(a, 3), (b, 3), (c, 3), (s, 1)], imm=int(op),
                        uv=a.uv if isinstance(a, Reg) else -1)
        return Reg(r.r, 3, r.uv), Reg(r.r + 3, 1)

    def mul3(self, a, b):
        return self.vmath(ops.V_MULTIPLY, a, b)[0]

    def scale3(self, a, s):
        if _is_const(s) and not _is_const(a):
            return self.mul3(a, _vec(s))
        if _is_const(a) and not _is_const(s):
            return self.mul3(self.convert(s, FLOAT, VECTOR), a)
        return self.vmath(ops.V_SCALE, a, s=s)[0]

    def add3(self, a, b):
        if _is_const(a) and _vec(a) == (0.0, 0.0, 0.0):
            return b
        if _is_const(b) and _vec(b) == (0.0, 0.0, 0.0):
            return a
        return self.vmath(ops.V_ADD, a, b)[0]

    def lerp(self, a, b, f):
        """(1 − f)·a + f·b of scalars."""
        if _is_const(f):
            f = float(f)
            if f <= 0.0:
                return a
            if f >= 1.0:
                return b
        if _is_const(a) and _is_const(b) and float(a) == float(b):
            return a
        if _is_const(f) and _is_const(a) and _is_const(b):
            return (1 - f) * float(a) + f * float(b)
        return self.e.emit(vm.OP_MIX_F, 1, [(f, 1), (a, 1), (b, 1)]) if not _is_const(f) or not (
            _is_const(a) and _is_const(b)) else (1 - f) * a + f * b

    def lerp3(self, a, b, f):
        if _is_const(f):
            f = float(f)
            if f <= 0.0:
                return a
            if f >= 1.0:
                return b
            if _is_const(a) and _is_const(b):
                return tuple((1 - f) * x + f * y for x, y in zip(_vec(a), _vec(b)))
        if _is_const(a) and _is_const(b) and _vec(a) == _vec(b):
            return a
        return self.e.emit(vm.OP_MIX_V, 3, [(f, 1), (a, 3), (b, 3)])

    # ------------------------------------------------------------------ nodes
    def lower(self, node: Node, variant: int) -> dict:
        fn = getattr(self, f"_n_{node.type}", None)
        if fn is None:
            self.warn(node.type + node.name, f"node {node.name!r} ({node.type}) is not evaluated by the tracer yet; "
                                             "its outputs read 0")
            out = {}
            for s in NODE_TYPES[node.type].outputs:
                out[s.name] = self.hit(vm.IN_NORMAL) if s.name == "Normal" else (0.0 if s.kind == FLOAT
                                                                                  else (0.0, 0.0, 0.0))
            return out
        return fn(node, variant)

    def _n_value(self, node, var):
        return {"Value": float(node.param("value"))}

    def _n_color(self, node, var):
        return {"Color": _vec(node.param("value"))}

    def _n_math(self, node, var):
        op = _enum("math.operation", node.param("operation"))
        a, b, c = (self.inp(node, s, FLOAT, var) for s in ("Value", "Value_001", "Value_002"))
        return {"Value": self.math(op, a, b, c, bool(node.param("use_clamp")))}

    def _n_vector_math(self, node, var):
        op = _enum("vector_math.operation", node.param("operation"))
        a, b, c = (self.inp(node, s, VECTOR, var) for s in ("Vector", "Vector_001", "Vector_002"))
        s = self.inp(node, "Scale", FLOAT, var) if op in (ops.V_SCALE, ops.V_REFRACT) else 1.0
        if op == ops.V_REFRACT:
            s = self.inp(node, "Scale", FLOAT, var)  # Blender's IOR socket of Refract is the Scale socket
        v, x = self.vmath(op, a, b, c, s)
        return {"Vector": v, "Value": x}

    def _n_separate_xyz(self, node, var):
        v = self.inp(node, "Vector", VECTOR, var)
        if _is_const(v):
            return dict(zip("XYZ", _vec(v)))
        return {"X": Reg(v.r, 1), "Y": Reg(v.r + 1, 1), "Z": Reg(v.r + 2, 1)}

    def _combine(self, x, y, z):
        if _is_const(x) and _is_const(y) and _is_const(z):
            return (float(x), float(y), float(z))
        return self.e.emit(vm.OP_COMBINE, 3, [(x, 1), (y, 1), (z, 1)])

    def _n_combine_xyz(self, node, var):
        return {"Vector": self._combine(*(self.inp(node, s, FLOAT, var) for s in "XYZ"))}

    def _n_separate_color(self, node, var):
        mode = _enum("color_mode", node.param("color_mode"))
        c = self.inp(node, "Color", COLOR, var)
        if _is_const(c):
            v = _vec(c)
            if mode == 1:
                v = ops.rgb_to_hsv(*v)
            elif mode == 2:
                v = ops.rgb_to_hsl(*v)
            return dict(zip(("Red", "Green", "Blue"), (float(x) for x in v)))
        if mode:
            c = self.e.emit(vm.OP_SEP_COLOR, 3, [(c, 3)], imm=mode)
        return {"Red": Reg(c.r, 1), "Green": Reg(c.r + 1, 1), "Blue": Reg(c.r + 2, 1)}

    def _n_combine_color(self, node, var):
        mode = _enum("color_mode", node.param("color_mode"))
        x, y, z = (self.inp(node, s, FLOAT, var) for s in ("Red", "Green", "Blue"))
        if _is_const(x) and _is_const(y) and _is_const(z):
            v = (float(x), float(y), float(z))
            if mode == 1:
                v = ops.hsv_to_rgb(*v)
            elif mode == 2:
                v = ops.hsl_to_rgb(*v)
            return {"Color": tuple(float(a) for a in v)}
        return {"Color": self.e.emit(vm.OP_COMB_COLOR, 3, [(x, 1), (y, 1), (z, 1)], imm=mode)}

    def _n_rgb_to_bw(self, node, var):  # whatever feeds it is a colour first (a vector as is), then its luminance
        return {"Val": self.convert(self.inp(node, "Color", COLOR, var), COLOR, FLOAT)}

    def _n_mix_float(self, node, var):
        f, a, b = self.inp(node, "Factor", FLOAT, var), self.inp(node, "A", FLOAT, var), self.inp(node, "B", FLOAT, var)
        if node.param("use_clamp") and _is_const(f):
            f = min(max(float(f), 0.0), 1.0)
        if _is_const(f) and _is_const(a) and _is_const(b):
            return {"Result": (1 - f) * a + f * b}
        return {"Result": self.e.emit(vm.OP_MIX_F, 1, [(f, 1), (a, 1), (b, 1)], imm=int(bool(node.param("use_clamp"))))}

    def _n_mix_vector(self, node, var):
        f, a, b = (self.inp(node, "Factor", FLOAT, var), self.inp(node, "A", VECTOR, var),
                   self.inp(node, "B", VECTOR, var))
        clamp = bool(node.param("use_clamp"))
        if _is_const(f) and _is_const(a) and _is_const(b):
            f = min(max(float(f), 0.0), 1.0) if clamp else float(f)
            return {"Result": tuple((1 - f) * x + f * y for x, y in zip(_vec(a), _vec(b)))}
        return {"Result": self.e.emit(vm.OP_MIX_V, 3, [(f, 1), (a, 3), (b, 3)], imm=int(clamp))}

    def _n_mix_vector_non_uniform(self, node, var):
        f, a, b = (self.inp(node, "Factor", VECTOR, var), self.inp(node, "A", VECTOR, var),
                   self.inp(node, "B", VECTOR, var))
        clamp = bool(node.param("use_clamp"))
        if _is_const(f) and _is_const(a) and _is_const(b):
            ff = [min(max(x, 0.0), 1.0) if clamp else x for x in _vec(f)]
            return {"Result": tuple((1 - t) * x + t * y for t, x, y in zip(ff, _vec(a), _vec(b)))}
        return {"Result": self.e.emit(vm.OP_MIX_VN, 3, [(f, 3), (a, 3), (b, 3)], imm=int(clamp))}

    def _n_mix_color(self, node, var):
        blend = _enum("mix_color.blend_type", node.param("blend_type"))
        f, a, b = (self.inp(node, "Factor", FLOAT, var), self.inp(node, "A", COLOR, var),
                   self.inp(node, "B", COLOR, var))
        clamp_f, clamp_r = bool(node.param("use_clamp")), bool(node.param("use_clamp_result"))
        if _is_const(f) and _is_const(a) and _is_const(b):
            t = min(max(float(f), 0.0), 1.0) if clamp_f else float(f)
            r = ops.mix_blend(int(blend), t, *_vec(a), *_vec(b))
            r = tuple(min(max(float(x), 0.0), 1.0) if clamp_r else float(x) for x in r)
            return {"Result": r}
        if blend == ops.B_MIX and not clamp_r and _is_const(f) and (not clamp_f or 0.0 <= float(f) <= 1.0):
            return {"Result": self.lerp3(a, b, f)}
        return {"Result": self.e.emit(vm.OP_MIX_C, 3, [(f, 1), (a, 3), (b, 3)],
                                      imm=blend | (256 if clamp_f else 0) | (512 if clamp_r else 0))}

    def _n_invert(self, node, var):
        f, c = self.inp(node, "Fac", FLOAT, var), self.inp(node, "Color", COLOR, var)
        if _is_const(f) and _is_const(c):
            return {"Color": tuple((1 - f) * x + f * (1 - x) for x in _vec(c))}
        return {"Color": self.e.emit(vm.OP_INVERT, 3, [(c, 3), (f, 1)])}

    def _n_gamma(self, node, var):
        c, g = self.inp(node, "Color", COLOR, var), self.inp(node, "Gamma", FLOAT, var)
        if _is_const(c) and _is_const(g):
            return {"Color": tuple(float(ops.gamma(float(x), float(g))) for x in _vec(c))}
        return {"Color": self.e.emit(vm.OP_GAMMA, 3, [(c, 3), (g, 1)])}

    def _n_brightness_contrast(self, node, var):
        c, br, co = (self.inp(node, "Color", COLOR, var), self.inp(node, "Bright", FLOAT, var),
                     self.inp(node, "Contrast", FLOAT, var))
        if _is_const(c) and _is_const(br) and _is_const(co):
            return {"Color": tuple(float(x) for x in ops.bright_contrast(*_vec(c), float(br), float(co)))}
        return {"Color": self.e.emit(vm.OP_BRIGHT, 3, [(c, 3), (br, 1), (co, 1)])}

    def _n_hsv(self, node, var):
        h, s, v, f, c = (self.inp(node, k, None, var) for k in ("Hue", "Saturation", "Value", "Fac", "Color"))
        if all(_is_const(x) for x in (h, s, v, f, c)):
            return {"Color": tuple(float(x) for x in ops.hue_sat(float(h), float(s), float(v), float(f), *_vec(c)))}
        return {"Color": self.e.emit(vm.OP_HSV, 3, [(c, 3), (h, 1), (s, 1), (v, 1), (f, 1)])}

    def _n_map_range(self, node, var):
        kind = _enum("map_range.interpolation_type", node.param("interpolation_type"))
        xs = [self.inp(node, k, FLOAT, var) for k in ("Value", "From Min", "From Max", "To Min", "To Max", "Steps")]
        clamp = bool(node.param("clamp"))
        if all(_is_const(x) for x in xs):
            return {"Result": float(ops.map_range_clamp(kind, *(float(x) for x in xs), clamp))}
        return {"Result": self.e.emit(vm.OP_MAP_RANGE, 1, [(x, 1) for x in xs], imm=kind | (256 if clamp else 0))}

    def _n_vector_map_range(self, node, var):
        kind = _enum("map_range.interpolation_type", node.param("interpolation_type"))
        xs = [self.inp(node, k, VECTOR, var) for k in ("Vector", "From Min", "From Max", "To Min", "To Max", "Steps")]
        clamp = bool(node.param("clamp"))
        if all(_is_const(x) for x in xs):
            cols = list(zip(*(_vec(x) for x in xs)))
            return {"Vector": tuple(float(ops.map_range_clamp(kind, *c, clamp)) for c in cols)}
        return {"Vector": self.e.emit(vm.OP_MAP_RANGE_V, 3, [(x, 3) for x in xs], imm=kind | (256 if clamp else 0))}

    def _n_clamp(self, node, var):
        kind = _enum("clamp.clamp_type", node.param("clamp_type"))
        x, lo, hi = (self.inp(node, k, FLOAT, var) for k in ("Value", "Min", "Max"))
        if _is_const(x) and _is_const(lo) and _is_const(hi):
            lo, hi = float(lo), float(hi)
            if kind == 1 and lo > hi:
                lo, hi = hi, lo
            return {"Result": min(max(float(x), lo), hi)}
        return {"Result": self.e.emit(vm.OP_CLAMP, 1, [(x, 1), (lo, 1), (hi, 1)], imm=kind)}

    def _n_mapping(self, node, var):
        kind = _enum("mapping.vector_type", node.param("vector_type"))
        v = self.inp(node, "Vector", VECTOR, var)
        loc, rot, scl = (self.inp(node, k, VECTOR, var) for k in ("Location", "Rotation", "Scale"))
        if kind >= 2:
            loc = (0.0, 0.0, 0.0)
        if _is_const(loc) and _is_const(rot) and _is_const(scl) and _vec(loc) == (0.0,) * 3 and \
                _vec(rot) == (0.0,) * 3 and _vec(scl) == (1.0,) * 3 and kind != 3:
            return {"Vector": v}
        r = self.e.emit(vm.OP_MAPPING, 3, [(v, 3), (loc, 3), (rot, 3), (scl, 3)], imm=kind,
                        uv=v.uv if isinstance(v, Reg) else -1)
        if all(_is_const(x) for x in (v, loc, rot, scl)):
            return {"Vector": self._fold(r, 3)}
        return {"Vector": r}

    def _n_vector_transform(self, node, var):
        kind = _enum("vector_transform.vector_type", node.param("vector_type"))
        src, dst = _enum("space", node.param("convert_from")), _enum("space", node.param("convert_to"))
        v = self.inp(node, "Vector", VECTOR, var)
        if src == dst:
            return {"Vector": v}
        if self.estimate:
            return {"Vector": v if _is_const(v) else (0.0, 0.0, 0.0)}
        return {"Vector": self.e.emit(vm.OP_VTRANSFORM, 3, [(v, 3)], imm=kind | src << 2 | dst << 4)}

    def _n_vector_rotate(self, node, var):
        kind = _enum("vector_rotate.rotation_type", node.param("rotation_type"))
        xs = [self.inp(node, k, None, var) for k in ("Vector", "Center", "Axis", "Angle", "Rotation")]
        r = self.e.emit(vm.OP_VROTATE, 3, [(xs[0], 3), (xs[1], 3), (xs[2], 3), (xs[3], 1), (xs[4], 3)],
                        imm=kind | (8 if node.param("invert") else 0))
        return {"Vector": self._fold(r, 3) if all(_is_const(x) for x in xs) else r}

    def _fold(self, r: Reg, n: int):
        """Evaluate the op just emitted, whose operands are all constants, with the VM's own function for it, and
        take it back out of the program."""
        op = self.e.code.pop()
        self.e.reads.pop()
        self.e.widths.pop()
        self.e._cse = {k: v for k, v in self.e._cse.items() if v != r.r}
        R = np.array(self.e.init, np.float64)
        o, a, b, c, d, e_, f_, imm = op[1:]
        if op[0] == vm.OP_RAMP:
            vm._ramp(R, o, R[a], b, c, imm)
        elif op[0] == vm.OP_CURVE:
            vm._curve(R, o, a, b, c, R[d], imm)
        elif op[0] == vm.OP_MAPPING:
            vm._mapping(R, o, a, b, c, d, imm)
        elif op[0] == vm.OP_VROTATE:
            vm._vrotate(R, o, a, b, c, d, e_, imm)
        else:
            raise AssertionError(vm.OP_NAMES[op[0]])
        vals = tuple(float(x) for x in R[o:o + n])
        return vals if n > 1 else vals[0]

    def _n_fresnel(self, node, var):
        ior, n = self.inp(node, "IOR", FLOAT, var), self.inp(node, "Normal", VECTOR, var)
        if self.estimate:
            return {"Fac": float(ops.math_op(ops.M_POWER, (float(ior) - 1) / (float(ior) + 1), 2.0, 0.0))
                    if _is_const(ior) else 0.04}
        return {"Fac": self.e.emit(vm.OP_FRESNEL, 1, [(ior, 1), (n, 3)])}

    def _n_layer_weight(self, node, var):
        b, n = self.inp(node, "Blend", FLOAT, var), self.inp(node, "Normal", VECTOR, var)
        if self.estimate:
            return {"Fresnel": 0.1, "Facing": 0.3}
        r = self.e.emit(vm.OP_LAYER_WEIGHT, 2, [(b, 1), (n, 3)])
        return {"Fresnel": Reg(r.r, 1), "Facing": Reg(r.r + 1, 1)}

    # ------------------------------------------------------------------ inputs
    def _n_texture_coordinate(self, node, var):
        if node.param("from_object"):
            self.warn(node.name + "obj", f"Texture Coordinate {node.name!r}: From Object is not supported (the "
                                         "hit's own object is used)")
        out = {"Generated": lambda: self.hit(vm.IN_GENERATED, variant=var),
               "Normal": lambda: self.hit(vm.IN_NORMAL), "UV": lambda: self.uv("", var),
               "Object": lambda: self.hit(vm.IN_OBJECT, variant=var), "Camera": lambda: self.hit(vm.IN_CAMERA),
               "Window": lambda: self.hit(vm.IN_WINDOW), "Reflection": lambda: self.hit(vm.IN_REFLECTION)}
        return _Lazy(out)

    def _n_geometry(self, node, var):
        def one(what):
            return lambda: Reg(self.hit(what).r, 1) if not self.estimate else 0.0
        out = {"Position": lambda: self.hit(vm.IN_POSITION, variant=var), "Normal": lambda: self.hit(vm.IN_NORMAL),
               "Tangent": lambda: self.hit(vm.IN_TANGENT, arg=0), "True Normal": lambda: self.hit(vm.IN_TRUE_NORMAL),
               "Incoming": lambda: self.hit(vm.IN_INCOMING), "Parametric": lambda: self.hit(vm.IN_PARAMETRIC, variant=var),
               "Backfacing": one(vm.IN_BACKFACING), "Pointiness": lambda: self._stand_in(node, "Pointiness", 0.5),
               "Random Per Island": lambda: self._stand_in(node, "Random Per Island", 0.0)}
        return _Lazy(out)

    def _stand_in(self, node, what, value):
        self.warn(node.name + what, f"{what} ({node.name!r}) is not available; {value} is used")
        return value

    def _n_object_info(self, node, var):
        def one(what):
            return lambda: Reg(self.hit(what).r, 1) if not self.estimate else 0.0
        return _Lazy({"Location": lambda: self.hit(vm.IN_OBJ_LOCATION), "Color": lambda: (1.0, 1.0, 1.0),
                      "Alpha": lambda: 1.0, "Object Index": one(vm.IN_OBJ_INDEX),
                      "Material Index": lambda: self._stand_in(node, "Material Index", 0.0),
                      "Random": one(vm.IN_OBJ_RANDOM)})

    def _n_light_path(self, node, var):
        def one(what):
            return lambda: Reg(self.hit(what).r, 1) if not self.estimate else (1.0 if what == vm.IN_IS_CAMERA
                                                                                 else 0.0)
        return _Lazy({"Is Camera Ray": one(vm.IN_IS_CAMERA), "Is Shadow Ray": one(vm.IN_IS_SHADOW),
                      "Is Diffuse Ray": lambda: 0.0, "Is Glossy Ray": one(vm.IN_IS_REFLECTION),
                      "Is Singular Ray": one(vm.IN_IS_REFLECTION), "Is Reflection Ray": one(vm.IN_IS_REFLECTION),
                      "Is Transmission Ray": lambda: 0.0, "Ray Length": one(vm.IN_RAY_LENGTH),
                      "Ray Depth": one(vm.IN_RAY_DEPTH), "Diffuse Depth": lambda: 0.0,
                      "Glossy Depth": one(vm.IN_RAY_DEPTH), "Transparent Depth": lambda: 0.0,
                      "Transmission Depth": lambda: 0.0})

    def _n_uvmap(self, node, var):
        return {"UV": self.uv(node.param("attribute") or "", var)}

    def _n_vertex_color(self, node, var):
        name = node.param("layer_name") or ""
        if name not in self.vertex_colors:
            self.vertex_colors.append(name)
        return _Lazy({"Color": lambda: self.hit(vm.IN_COLOR, variant=var), "Alpha": lambda: 1.0})

    def _n_attribute(self, node, var):
        name = node.param("attribute") or ""
        if node.param("attribute_type") not in (None, "GEOMETRY"):
            self.warn(node.name, f"Attribute {node.name!r}: {node.param('attribute_type')} attributes are not "
                                 "supported; white is used")
            return {"Color": (1.0, 1.0, 1.0), "Vector": (1.0, 1.0, 1.0), "Fac": 1.0, "Alpha": 1.0}
        if self.uv_index(name) is not None and name and name in getattr(self.uv_index, "names", ()):
            uvv = self.uv(name, var)
            return {"Color": uvv, "Vector": uvv, "Fac": self.convert(uvv, VECTOR, FLOAT), "Alpha": 1.0}
        if name not in self.vertex_colors:
            self.vertex_colors.append(name)
        c = self.hit(vm.IN_COLOR, variant=var)
        return {"Color": c, "Vector": c, "Fac": self.convert(c, COLOR, FLOAT), "Alpha": 1.0}

    def _n_tangent(self, node, var):
        k = self.uv_index(node.param("uv_map") or "") or 0
        return {"Tangent": self.hit(vm.IN_TANGENT, arg=k)}

    # ------------------------------------------------------------------ textures
    def _texture(self, use: TextureUse) -> int:
        key = (use.image.key() if use.image is not None else None, use.scene_index, use.scale, use.bias,
               use.fallback)
        if key not in self._tex_index:
            self._tex_index[key] = len(self.textures)
            self.textures.append(use)
        return self._tex_index[key]

    def image(self, use: TextureUse, coord, node_name: str, projection: int = 0, blend: float = 0.0):
        """RGBA Reg (4 wide) of an image lookup at ``coord`` (in estimate mode: the image's mean); ``projection``
        0 flat, 1 box (its ``blend``), 2 sphere, 3 tube (Image Texture's)."""
        if self.estimate:
            return _mean_rgba(use)
        if _is_const(coord):
            self.warn(node_name + "const", f"texture {node_name!r} reads constant coordinates")
        k = self._texture(use)
        uv = coord.uv if isinstance(coord, Reg) and projection == 0 else -1
        r = self.e.emit(vm.OP_IMAGE, 4, [(coord, 3), k, uv, (blend, 1)], imm=projection)
        return Reg(r.r, 4, src=(use, coord, (projection, blend)))

    def _rgba_out(self, rgba):
        if _is_const(rgba):
            return tuple(rgba[:3]), float(rgba[3])
        return Reg(rgba.r, 3, src=rgba.src), Reg(rgba.r + 3, 1)

    def _n_image_texture(self, node, var):
        img = node.param("image")
        if img is None:
            self.warn(node.name, f"Image Texture {node.name!r} has no image; black is used")
            return {"Color": (0.0, 0.0, 0.0), "Alpha": 0.0}
        ext = node.param("extension")
        if ext is not None:
            wrap = {"REPEAT": "repeat", "EXTEND": "clamp", "CLIP": "black", "MIRROR": "mirror"}[str(ext).upper()]
            img = _with_wrap(img, wrap)
        coord = self.inp(node, "Vector", VECTOR, var)
        proj = ("FLAT", "BOX", "SPHERE", "TUBE").index(str(node.param("projection") or "FLAT").upper())
        c, a = self._rgba_out(self.image(TextureUse(img, -1), coord, node.name, proj,
                                         float(node.param("projection_blend") or 0.0)))
        return {"Color": c, "Alpha": a}

    def _n_environment_texture(self, node, var):  # a world's: the equirectangular map of the direction
        img = node.param("image")
        if img is None or str(node.param("projection")).upper() != "EQUIRECTANGULAR":
            self.warn(node.name, f"Environment Texture {node.name!r}: "
                                 f"{'no image' if img is None else 'Mirror Ball projection is not evaluated'}; "
                                 "black is used")
            return {"Color": (0.0, 0.0, 0.0), "Alpha": 0.0}
        coord = self.inp(node, "Vector", VECTOR, var)
        c, a = self._rgba_out(self.image(TextureUse(img, -1), coord, node.name, 4))
        return {"Color": c, "Alpha": a}

    def _n_usd_uv_texture(self, node, var):
        img = node.param("image")
        fb = tuple(float(x) for x in node.param("fallback"))
        if img is None:
            return {"r": fb[0], "g": fb[1], "b": fb[2], "a": fb[3], "rgb": fb[:3]}
        coord = self.inp(node, "st", VECTOR, var)
        use = TextureUse(img, -1, tuple(float(x) for x in node.param("scale")),
                         tuple(float(x) for x in node.param("bias")), fb)
        rgba = self.image(use, coord, node.name)
        if _is_const(rgba):
            return {"r": rgba[0], "g": rgba[1], "b": rgba[2], "a": rgba[3], "rgb": tuple(rgba[:3])}
        return {"r": Reg(rgba.r, 1), "g": Reg(rgba.r + 1, 1), "b": Reg(rgba.r + 2, 1), "a": Reg(rgba.r + 3, 1),
                "rgb": Reg(rgba.r, 3)}

    def _n_scene_texture(self, node, var):
        from .shader_graph import ImageRef  # noqa: F401  (documentation: scene textures are tracer.Texture)
        k_tex, uv_set = node.param("index"), node.param("uv_set")
        coord = self.uv(int(uv_set), var) if not self.estimate else (0.5, 0.5, 0.0)
        rgba = self.image(TextureUse(None, int(k_tex)), coord, node.name) if not self.estimate else \
            self._scene_mean(int(k_tex))
        c, a = self._rgba_out(rgba)
        return {"Color": c, "Alpha": a}

    def _scene_mean(self, k):
        t = self.scene_textures[k] if getattr(self, "scene_textures", None) is not None else None
        if t is None:
            return (1.0, 1.0, 1.0, 1.0)
        m = t.rgba().reshape(-1, 4).mean(0) * np.asarray(t.scale) + np.asarray(t.bias)
        return tuple(float(x) for x in m)

    def _n_usd_transform2d(self, node, var):
        v = self.inp(node, "in", VECTOR, var)
        m = node.param("matrix")
        if m is None:
            m = transform2d_matrix(node.param("scale"), float(node.param("rotation")), node.param("translation"))
        m = np.asarray(m, np.float64)
        if _is_const(v):
            s, t = _vec(v)[:2]
            return {"result": (m[0, 0] * s + m[0, 1] * t + m[0, 2], m[1, 0] * s + m[1, 1] * t + m[1, 2], 0.0)}
        if np.allclose(m, np.eye(3)):
            return {"result": v}
        k = self.e.const(tuple(m[:2].reshape(-1)))
        return {"result": self.e.emit(vm.OP_AFFINE2, 3, [(v, 3), (k, 6)], uv=v.uv)}

    def _n_checker_texture(self, node, var):
        v = self.inp(node, "Vector", VECTOR, var)
        c1, c2, sc = (self.inp(node, k, None, var) for k in ("Color1", "Color2", "Scale"))
        if self.estimate or _is_const(v):
            if _is_const(v) and not self.estimate:
                p = [(x * float(sc) + 1e-6) * 0.999999 for x in _vec(v)] if _is_const(sc) else None
                if p is not None and _is_const(c1) and _is_const(c2):
                    xi, yi, zi = (int(abs(np.floor(x))) for x in p)
                    first = (xi % 2 == yi % 2) == (zi % 2 != 0)
                    return {"Color": _vec(c1 if first else c2), "Fac": 1.0 if first else 0.0}
            if _is_const(c1) and _is_const(c2):
                return {"Color": tuple(0.5 * (a + b) for a, b in zip(_vec(c1), _vec(c2))), "Fac": 0.5}
        r = self.e.emit(vm.OP_CHECKER, 4, [(v, 3), (c1, 3), (c2, 3), (sc, 1)])
        return {"Color": Reg(r.r, 3), "Fac": Reg(r.r + 3, 1)}

    def _n_rgb_ramp(self, node, var):
        from .procedural.color import color_ramp_table
        ramp = node.param("ramp")
        interp = str(node.param("interpolation") or "LINEAR").upper()
        f = self.inp(node, "Fac", FLOAT, var)
        if not ramp:
            return {"Color": (0.0, 0.0, 0.0), "Alpha": 1.0}
        stops = sorted(((float(p), tuple(float(x) for x in (tuple(c) + (1.0,))[:4])) for p, c in ramp),
                       key=lambda s: s[0])
        table = color_ramp_table([p for p, _c in stops], [c for _p, c in stops], interp,
                                 str(node.param("color_mode") or "RGB").upper(),
                                 str(node.param("hue_interpolation") or "NEAR").upper())
        k = self.e.const(tuple(np.asarray(table, np.float64).reshape(-1)))
        r = self.e.emit(vm.OP_RAMP, 4, [(f, 1), (k, table.size), len(table)], imm=int(interp != "CONSTANT"))
        if _is_const(f):
            rgba = self._fold(r, 4)
            return {"Color": tuple(rgba[:3]), "Alpha": rgba[3]}
        return {"Color": Reg(r.r, 3), "Alpha": Reg(r.r + 3, 1)}

    def _curve_node(self, node, var, kind, inp_name, out_name, fac_name):
        table = np.asarray(node.param("curves"), np.float64) if node.param("curves") is not None else None
        x = self.inp(node, inp_name, None, var)
        fac = self.inp(node, fac_name, FLOAT, var)
        if table is None:
            return {out_name: x}
        lo, hi = (float(x) for x in node.param("range"))
        size = table.shape[0]
        k = self.e.const((lo, hi, float(table.shape[1])) + tuple(table.T.reshape(-1)))
        n = 1 if kind == 2 else 3
        r = self.e.emit(vm.OP_CURVE, n, [(x, n), (k, 3 + table.size), size, (fac, 1)], imm=kind)
        if _is_const(x) and _is_const(fac):
            return {out_name: self._fold(r, n)}
        return {out_name: r}

    def _n_rgb_curves(self, node, var):
        return self._curve_node(node, var, 0, "Color", "Color", "Fac")

    def _n_vector_curves(self, node, var):
        return self._curve_node(node, var, 1, "Vector", "Vector", "Fac")

    def _n_float_curve(self, node, var):
        return self._curve_node(node, var, 2, "Value", "Value", "Factor")

    # ------------------------------------------------------------------ procedural textures (tracer.procedural)
    def block(self, values: list) -> Reg:
        """Consecutive registers holding ``values`` (constants written once, per-hit values copied in)."""
        flat = []
        for x in values:
            flat += list(_vec(x)) if (not isinstance(x, Reg) and np.ndim(x)) else [x]
        if all(_is_const(x) for x in flat):
            return self.e.const(tuple(float(x) for x in flat))
        base = self.e.alloc(len(flat))
        for j, x in enumerate(flat):
            if _is_const(x):
                self.e.init[base + j] = float(x)
            else:
                self.e.code.append([vm.OP_COPY, base + j, x.r, 0, 0, 0, 0, 0, 1])
                self.e.reads.append([(x.r, 1)])
                self.e.widths.append(1)
        return Reg(base, len(flat))

    def _flat(self, values):
        out = []
        for x in values:
            if isinstance(x, Reg) and x.n == 3:
                out += [Reg(x.r + j, 1) for j in range(3)]
            else:
                out.append(x)
        return out

    def _proc(self, op, node, var, names, imm, width):
        if self.estimate:
            return None
        vec_in = self.inp(node, "Vector", VECTOR, var) if "Vector" in [s.name for s in NODE_TYPES[node.type].inputs] \
            else 0.0
        blk = self.block(self._flat([self.inp(node, n, None, var) for n in names]))
        raw = {"reads": [(blk.r, blk.n)]}
        return self.e.emit(op, width, [(vec_in, 3), blk.r], imm=imm, raw=raw)

    def _n_noise_texture(self, node, var):
        from .procedural import noise as pn
        dim = int(str(node.param("noise_dimensions"))[0])
        kind = pn.NOISE_TYPES[str(node.param("noise_type")).upper()]
        if self.estimate:
            return {"Fac": 0.5, "Color": (0.5, 0.5, 0.5)}
        names = ["W", "Scale", "Detail", "Roughness", "Lacunarity", "Offset", "Gain", "Distortion"]
        imm = dim | kind << 4 | int(bool(node.param("normalize"))) << 8
        made = {}

        def colour():  # the full node (three times the work of Fac alone: Cycles' noise_value vs noise_texture)
            if "c" not in made:
                made["c"] = self._proc(vm.OP_NOISE, node, var, names, imm | 1 << 12, 4)
            return made["c"]

        def fac():
            if "c" in made:
                return Reg(made["c"].r, 1)
            return Reg(self._proc(vm.OP_NOISE, node, var, names, imm, 1).r, 1)
        return _Lazy({"Fac": fac, "Color": lambda: Reg(colour().r + 1, 3)})

    def _n_mx_noise(self, node, var):
        """MaterialX's noise nodes (tracer.procedural.mx_noise); one op, all outputs."""
        from .procedural import mx_noise as mxn
        if self.estimate:
            return {"Value": 0.5, "Vector": (0.5, 0.5, 0.5), "W": 0.5}
        imm = (mxn.KINDS.index(str(node.param("kind"))) | int(node.param("dimensions")) << 4
               | int(node.param("width")) << 8 | int(node.param("style")) << 12)
        r = self._proc(vm.OP_MX_NOISE, node, var, ["Amplitude", "Amplitude W", "Pivot", "Octaves", "Lacunarity",
                                                   "Diminish", "Jitter"], imm, 4)
        return {"Value": Reg(r.r, 1), "Vector": Reg(r.r, 3), "W": Reg(r.r + 3, 1)}

    def _n_voronoi_texture(self, node, var):
        from .procedural import voronoi as pv
        dim = int(str(node.param("voronoi_dimensions"))[0])
        feat = pv.FEATURES[str(node.param("feature")).upper()]
        metric = pv.METRICS[str(node.param("distance")).upper()]
        if self.estimate:
            return {"Distance": 0.5, "Color": (0.5, 0.5, 0.5), "Position": (0.5, 0.5, 0.5), "W": 0.5, "Radius": 0.5}
        r = self._proc(vm.OP_VORONOI, node, var, ["W", "Scale", "Detail", "Roughness", "Lacunarity", "Smoothness",
                                                  "Exponent", "Randomness"],
                       dim | feat << 4 | metric << 8 | int(bool(node.param("normalize"))) << 12, 9)
        return {"Distance": Reg(r.r, 1), "Color": Reg(r.r + 1, 3), "Position": Reg(r.r + 4, 3), "W": Reg(r.r + 7, 1),
                "Radius": Reg(r.r + 8, 1)}

    def _n_wave_texture(self, node, var):
        from .procedural import patterns as pp
        kind = pp.WAVE_TYPES[str(node.param("wave_type")).upper()]
        dirs = pp.BANDS_DIRECTIONS if kind == pp.BANDS else pp.RINGS_DIRECTIONS
        direction = dirs[str(node.param("bands_direction" if kind == pp.BANDS else "rings_direction")).upper()]
        prof = pp.WAVE_PROFILES[str(node.param("wave_profile")).upper()]
        if self.estimate:
            return {"Fac": 0.5, "Color": (0.5, 0.5, 0.5)}
        r = self._proc(vm.OP_WAVE, node, var, ["Scale", "Distortion", "Detail", "Detail Scale", "Detail Roughness",
                                               "Phase Offset"], kind | direction << 4 | prof << 8, 1)
        return {"Fac": r, "Color": self.convert(r, FLOAT, COLOR)}

    def _n_magic_texture(self, node, var):
        if self.estimate:
            return {"Fac": 0.5, "Color": (0.5, 0.5, 0.5)}
        r = self._proc(vm.OP_MAGIC, node, var, ["Scale", "Distortion"], int(node.param("turbulence_depth")) & 15, 4)
        return {"Color": Reg(r.r, 3), "Fac": Reg(r.r + 3, 1)}

    def _n_gradient_texture(self, node, var):
        from .procedural import patterns as pp
        kind = pp.GRADIENT_TYPES[str(node.param("gradient_type")).upper()]
        if self.estimate:
            return {"Fac": 0.5, "Color": (0.5, 0.5, 0.5)}
        r = self._proc(vm.OP_GRADIENT, node, var, [], kind, 1)
        return {"Fac": r, "Color": self.convert(r, FLOAT, COLOR)}

    def _n_brick_texture(self, node, var):
        if self.estimate:
            c1, c2 = self.inp(node, "Color1", None, var), self.inp(node, "Color2", None, var)
            mean = tuple(0.5 * (a + b) for a, b in zip(_vec(c1), _vec(c2))) if _is_const(c1) and _is_const(c2) \
                else (0.5, 0.5, 0.5)
            return {"Color": mean, "Fac": 0.1}
        names = ["Color1", "Color2", "Mortar", "Scale", "Mortar Size", "Mortar Smooth", "Bias", "Brick Width",
                 "Row Height"]
        vals = [self.inp(node, n, None, var) for n in names] + [
            float(node.param("offset")), float(node.param("offset_frequency")), float(node.param("squash")),
            float(node.param("squash_frequency"))]
        v = self.inp(node, "Vector", VECTOR, var)
        blk = self.block(self._flat(vals))
        r = self.e.emit(vm.OP_BRICK, 4, [(v, 3), blk.r], raw={"reads": [(blk.r, blk.n)]})
        return {"Color": Reg(r.r, 3), "Fac": Reg(r.r + 3, 1)}

    def _n_white_noise_texture(self, node, var):
        dim = int(str(node.param("noise_dimensions"))[0])
        if self.estimate:
            return {"Value": 0.5, "Color": (0.5, 0.5, 0.5)}
        r = self._proc(vm.OP_WHITE_NOISE, node, var, ["W"], dim, 4)
        return {"Value": Reg(r.r, 1), "Color": Reg(r.r + 1, 3)}

    def _n_blackbody(self, node, var):
        from .procedural import color as pc
        t = self.inp(node, "Temperature", FLOAT, var)
        if _is_const(t):
            return {"Color": tuple(float(x) for x in pc.blackbody(float(t)))}
        return {"Color": self.e.emit(vm.OP_BLACKBODY, 3, [(t, 1)])}

    def _n_wavelength(self, node, var):
        from .procedural import color as pc
        t = self.inp(node, "Wavelength", FLOAT, var)
        if _is_const(t):
            return {"Color": tuple(float(x) for x in pc.wavelength(float(t)))}
        return {"Color": self.e.emit(vm.OP_WAVELENGTH, 3, [(t, 1)])}

    # ------------------------------------------------------------------ normals
    def _n_normal_map(self, node, var):
        space = _enum("normal_map.space", node.param("space"))
        strength, col = self.inp(node, "Strength", FLOAT, var), self.inp(node, "Color", COLOR, var)
        if self.estimate:
            return {"Normal": (0.0, 0.0, 1.0)}
        if space == 0 and _is_const(col) and np.allclose(_vec(col), (0.5, 0.5, 1.0)):
            return {"Normal": self.hit(vm.IN_NORMAL)}
        k = -1
        if space == 0:
            uv_map = node.param("uv_map")
            k = uv_map if isinstance(uv_map, (int, np.integer)) else self.uv_index(uv_map or "")
            if k is None:
                self.warn(node.name + "uv", f"Normal Map {node.name!r}: UV map {uv_map!r} is not known; the default "
                                            "one is used")
                k = 0
        return {"Normal": self.e.emit(vm.OP_NORMAL_MAP, 3, [(col, 3), (strength, 1), int(k)], imm=space)}

    def _n_bump(self, node, var):
        nrm = self.inp(node, "Normal", VECTOR, var)
        if self.estimate:
            return {"Normal": (0.0, 0.0, 1.0)}
        h0 = self.inp(node, "Height", FLOAT, 0)
        if _is_const(h0):
            return {"Normal": nrm}
        hx, hy = self.inp(node, "Height", FLOAT, 1), self.inp(node, "Height", FLOAT, 2)
        strength, dist = self.inp(node, "Strength", FLOAT, var), self.inp(node, "Distance", FLOAT, var)
        if node.param("invert"):
            dist = self.math(ops.M_MULTIPLY, dist, -1.0)
        setup = self.bump_setup()
        return {"Normal": self.e.emit(vm.OP_BUMP, 3, [(h0, 1), (hx, 1), (hy, 1), (strength, 1), (dist, 1), (nrm, 3)],
                                      imm=setup.r, raw={"reads": [(setup.r, 10)]})}

    def _n_displacement(self, node, var):
        h, mid, sc = (self.inp(node, k, FLOAT, var) for k in ("Height", "Midlevel", "Scale"))
        nrm = self.inp(node, "Normal", VECTOR, var)
        amount = self.math(ops.M_MULTIPLY, self.math(ops.M_SUBTRACT, h, mid), sc)
        return {"Displacement": self.scale3(nrm, amount)}


def transform2d_matrix(scale=(1.0, 1.0), rotation=0.0, translation=(0.0, 0.0)) -> np.ndarray:
    """The (3, 3) matrix of a UsdTransform2d on (s, t, 1): T · R · S (scale, then rotate CCW in degrees, then
    translate), the spec's ``in · scale · rotate + translation``."""
    import math
    if not math.isfinite(rotation):
        return np.full((3, 3), np.nan)
    c, s = math.cos(math.radians(rotation)), math.sin(math.radians(rotation))
    S = np.diag([scale[0], scale[1], 1.0])
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    T = np.array([[1.0, 0.0, translation[0]], [0.0, 1.0, translation[1]], [0.0, 0.0, 1.0]])
    return T @ R @ S


class _Lazy(dict):
    """Outputs computed on first use (input nodes: only the outputs a graph reads emit an op)."""

    def __init__(self, makers: dict):
        super().__init__()
        self._makers = makers

    def __missing__(self, key):
        v = self._makers[key]()
        self[key] = v
        return v


def _with_wrap(img: ImageRef, wrap: str) -> ImageRef:
    if img.wrap_s == wrap and img.wrap_t == wrap:
        return img
    from dataclasses import replace
    out = replace(img, wrap_s=wrap, wrap_t=wrap)
    out.pixels = img.pixels
    return out


def _mean_rgba(use: TextureUse) -> tuple:
    if use.image is None:
        return (1.0, 1.0, 1.0, 1.0)
    try:
        px = use.image.rgba()
    except (ValueError, OSError):
        return tuple(use.fallback)
    m = px.reshape(-1, 4).mean(0) * np.asarray(use.scale) + np.asarray(use.bias)
    return tuple(float(x) for x in m)


# ---------------------------------------------------------------------------------------------- entry points
_SLOT_WIDTH = {"base": 3, "roughness": 1, "metallic": 1, "specular": 1, "alpha": 1, "emission": 3, "normal": 3,
               "transmission": 1}


def compile_graph(graph: Graph, warn=None, uv_index=None, scene_textures=None, row: bool = True) -> Compiled:
    """Compile ``graph`` (module docstring). ``uv_index(name)`` -> UV set index (None: unknown); ``warn``: one
    call per problem, naming the material and node. ``row=False``: the program only (no estimate of the row's
    constants, which reads every image's mean)."""
    c = Compiler(graph, warn, uv_index)
    c.scene_textures = scene_textures
    vals, extras = c.outputs()
    if row:
        est = Compiler(graph, None, uv_index, estimate=True)
        est.scene_textures = scene_textures
        row = _row(est.outputs()[0], extras)
    else:
        row = {}
    outs = np.full(len(vm.OUT_SLOTS), -1, np.int32)
    live = []
    for k, slot in enumerate(vm.OUT_SLOTS):
        x = vals[slot]
        if x is None or _is_const(x):
            continue
        n = _SLOT_WIDTH[slot]
        if slot == "normal":
            x = c.e.emit(vm.OP_NORMALIZE_N, 3, [(x, 3)])
        outs[k] = x.r
        live.append((x.r, n))
    slots = c.lobe_slots
    if slots is not None:
        live += slots.live
    program = None
    if live:
        code, init = c.e.finish(live)
        images = code[:, 0] == vm.OP_IMAGE  # the textures the kept lookups read, renumbered
        used = sorted(set(code[images, 3].tolist()))
        code[images, 3] = np.searchsorted(np.asarray(used, np.int32), code[images, 3])
        program = Program(code=code, init=init, outs=outs, textures=[c.textures[k] for k in used], lobes=slots)
    return Compiled(row=row, program=program, vertex_colors=c.vertex_colors, uv_maps=c.uv_maps)


def _row(vals: dict, extras: dict) -> dict:
    def f(x):
        return float(x) if not isinstance(x, Reg) else 0.0

    def v(x):
        return _vec(x) if not isinstance(x, Reg) else (0.0, 0.0, 0.0)

    base = v(vals["base"])
    row = dict(base_color=tuple(max(x, 0.0) for x in base), roughness=min(max(f(vals["roughness"]), 0.0), 1.0),
               metallic=min(max(f(vals["metallic"]), 0.0), 1.0), specular=max(f(vals["specular"]), 0.0),
               alpha=min(max(f(vals["alpha"]), 0.0), 1.0),
               emission=tuple(max(x, 0.0) for x in v(vals["emission"])),
               transmission=min(max(f(vals["transmission"]), 0.0), 1.0), ior=float(extras["ior"]) if
               extras["ior"] > 0 else 1.5, specular_tint=tuple(extras["specular_tint"]),
               alpha_threshold=float(extras["alpha_threshold"]))
    if row["transmission"] > 0 or extras["transmission_tint"] is not None:
        row["transmission_tint"] = tuple(extras["transmission_tint"] or row["base_color"])
    return row


def add_graph(builder, graph: Graph, warn=None, uv_index=None, name: str | None = None) -> int:
    """Compile ``graph`` and add its material row to a :class:`tracer.SceneBuilder`: its constant row, and the
    graph itself (with its UV map names resolved by ``uv_index``) where something varies per hit. Returns the
    row index."""
    compiled = compile_graph(graph, warn, uv_index)
    fields = dict(compiled.row)
    if compiled.program is not None or any(n.type == "holdout" for n in graph.nodes.values()):  # tracer.compose
        fields["program"] = BoundGraph(graph, _uv_table(compiled.uv_maps, uv_index))
    return builder.add_material(name or graph.name, **fields)


class BoundGraph(NamedTuple):
    """A material's graph as a row of :class:`tracer.Materials` holds it: the graph and its UV map names'
    indices in ``Scene.uv_sets``."""

    graph: Graph
    uv_sets: dict

    def uv_index(self, name):
        if isinstance(name, (int, np.integer)):
            return int(name)
        return self.uv_sets.get(name, 0 if not name else None)


def _uv_table(names, uv_index) -> dict:
    out = {}
    for n in names:
        k = uv_index(n) if uv_index is not None else (0 if not n else None)
        if k is not None:
            out[n] = int(k)
    return out


# ---------------------------------------------------------------------------------------------- the scene's table
class ProgramTable(NamedTuple):
    """Every material's program as the kernels read them: instructions ``code`` (registers relative to the
    material's base ``pbase``; material m runs code[pstart[m]:pstart[m + 1]]), the initial register file ``R0``
    (all materials' constants), ``outs`` (N, 8) each closure input's register (-1: the row's constant), ``has``
    (N,) bool: the material has a program; its closure's lobe slots (:class:`tracer.shader_closures.LobeSlots`)
    ``lobe_kind`` (N, MAX_LOBES) (-1: unused), ``lobe_out`` (N, MAX_LOBES, 6) their registers, ``lobe_extra``
    (N, 2) the pass-through colour's and holdout weight's registers (-1: the material has one closure)."""

    code: np.ndarray
    pstart: np.ndarray
    pbase: np.ndarray
    outs: np.ndarray
    R0: np.ndarray
    has: np.ndarray
    lobe_kind: np.ndarray
    lobe_out: np.ndarray
    lobe_extra: np.ndarray

    @property
    def lobes(self) -> tuple:
        """(lobe_kind, lobe_out, lobe_extra): the VM's ``lobe_prog``."""
        return self.lobe_kind, self.lobe_out, self.lobe_extra

    @property
    def alpha_varies(self) -> np.ndarray:
        return self.outs[:, vm.OUT_ALPHA] >= 0


def row_graph(m, i: int, textures: list) -> Graph:
    """The graph of row ``i`` of a :class:`tracer.Materials` table whose ``P_texture`` columns read textures:
    each textured parameter is its constant × the lookup (a scalar reads one channel, or the luminance for rgb;
    a colour reads rgb, or one channel as grey), the normal map through ``normal_map``."""
    tex, ch = m.texture_slots()
    g = Graph(m.names[i] if i < len(m.names) else f"material{i}")

    def value(j, colour: bool):
        ti, c = int(tex[i, j]), int(ch[i, j])
        node = g.add("scene_texture", index=ti, uv_set=int(textures[ti].uv_set))
        if c < 0:
            return node["Color"]
        if c == 3:
            x = node["Alpha"]
        else:
            x = g.add("separate_color", {"Color": node["Color"]})[("Red", "Green", "Blue")[c]]
        return g.add("combine_color", {"Red": x, "Green": x, "Blue": x})["Color"] if colour else x

    def colour(j, const):
        if tex[i, j] < 0:
            return tuple(float(x) for x in const)
        return g.add("vector_math", {"Vector": value(j, True), "Vector_001": tuple(float(x) for x in const)},
                     operation="MULTIPLY")["Vector"]

    def scalar(j, const):
        if tex[i, j] < 0:
            return float(const)
        return g.add("math", {"Value": value(j, False), "Value_001": float(const)}, operation="MULTIPLY")["Value"]

    base = colour(0, m.diffuse[i])
    if tex[i, 0] >= 0 and m.vertex_color[i]:
        base = g.add("vector_math", {"Vector": base, "Vector_001": g.add("vertex_color")["Color"]},
                     operation="MULTIPLY")["Vector"]
    inputs = {"Base Color": base, "Roughness": scalar(1, m.roughness[i]), "Metallic": scalar(2, m.metallic[i]),
              "Specular IOR Level": scalar(3, m.specular[i]), "Alpha": scalar(4, m.alpha[i]),
              "Emission Color": colour(5, m.emission[i]), "Emission Strength": 1.0}
    if tex[i, 6] >= 0:
        v = value(6, True)
        half = g.add("vector_math", {"Vector": v, "Vector_001": (0.5, 0.5, 0.5), "Vector_002": (0.5, 0.5, 0.5)},
                     operation="MULTIPLY_ADD")["Vector"]
        nm = g.add("normal_map", {"Color": half, "Strength": float(m.normal_strength[i])},
                   uv_map=int(textures[int(tex[i, 6])].uv_set))
        inputs["Normal"] = nm["Normal"]
    g.output(g.add("principled_bsdf", inputs)["BSDF"])
    return g


def pack_programs(m, textures: list) -> tuple[ProgramTable, list]:
    """(the :class:`ProgramTable` of a Materials table, the textures its image ops read: ``textures`` followed by
    those the graphs' ImageRefs add). Kept on the table while its graphs, texture columns and the constants
    they multiply are the same (a session renders again without compiling again)."""
    from .texture import as_texture

    textures = [as_texture(t) for t in textures]
    tex_slots, ch = m.texture_slots()
    key = (tuple(id(t) for t in textures), tuple(id(p) for p in (getattr(m, "programs", None) or ())),
           tex_slots.tobytes(), ch.tobytes(), *(np.asarray(getattr(m, k)).tobytes() for k in (
               "diffuse", "roughness", "metallic", "specular", "alpha", "emission", "normal_strength",
               "vertex_color")))
    cached = m.__dict__.get("_program_cache")
    if cached is not None and cached[0] == key:
        return cached[1], list(cached[2])
    table, out = _pack_programs(m, textures)
    m.__dict__["_program_cache"] = (key, table, out)
    return table, list(out)


def _pack_programs(m, textures: list) -> tuple[ProgramTable, list]:
    from .texture import Texture

    n = len(m)
    tex_slots, _ = m.texture_slots()
    programs = getattr(m, "programs", None) or [None] * n
    out_textures = list(textures)
    added: dict = {}
    codes, inits = [], []
    pstart = np.zeros(n + 1, np.int32)
    pbase = np.zeros(n, np.int32)
    outs = np.full((n, len(vm.OUT_SLOTS)), -1, np.int32)
    has = np.zeros(n, np.bool_)
    lobe_kind = np.full((n, MAX_LOBES), -1, np.int32)
    lobe_out = np.zeros((n, MAX_LOBES, 6), np.int32)
    lobe_extra = np.full((n, 2), -1, np.int32)
    n_code = n_reg = 0
    for i in range(n):
        pstart[i] = n_code
        bound = programs[i]
        if bound is not None:
            prog = compile_graph(bound.graph, None, bound.uv_index, textures, row=False).program
        elif (tex_slots[i] >= 0).any():
            prog = compile_graph(row_graph(m, i, textures), None, lambda name: name if isinstance(name, int) else 0,
                                 textures, row=False).program
        else:
            prog = None
        if prog is None:
            continue
        index = []
        for use in prog.textures:
            if use.image is None:
                index.append(use.scene_index)
                continue
            key = (use.image.key(), use.scale, use.bias, use.fallback)
            if key not in added:
                added[key] = len(out_textures)
                out_textures.append(Texture(image=use.image.rgba(), wrap_s=use.image.wrap_s,
                                            wrap_t=use.image.wrap_t, scale=use.scale, bias=use.bias,
                                            fallback=use.fallback, interpolation=use.image.interpolation))
            index.append(added[key])
        code = prog.code.copy()
        image_ops = code[:, 0] == vm.OP_IMAGE
        code[image_ops, 3] = np.asarray(index, np.int32)[code[image_ops, 3]] if image_ops.any() else code[image_ops, 3]
        codes.append(code)
        inits.append(prog.init)
        pbase[i] = n_reg
        outs[i] = prog.outs
        has[i] = True
        if prog.lobes is not None:
            lobe_kind[i], lobe_out[i], lobe_extra[i] = prog.lobes.kinds, prog.lobes.regs, prog.lobes.extra
        n_code += len(code)
        n_reg += len(prog.init)
    pstart[n] = n_code
    code = np.concatenate(codes) if codes else np.zeros((0, vm.WIDTH), np.int32)
    R0 = np.concatenate(inits) if inits else np.zeros(1, np.float64)
    return ProgramTable(np.ascontiguousarray(code, np.int32), pstart, pbase, outs, np.ascontiguousarray(R0),
                        has, lobe_kind, lobe_out, lobe_extra), out_textures

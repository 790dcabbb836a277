"""Compiling a material's graph (:mod:`tracer.shading.graph`) into a VM program (:mod:`tracer.shading.vm`).

    compiled = compile_graph(graph, warn, uv_index)   # once per material
    compiled.row      the material's constant row (tracer.Materials fields)
    compiled.program  None when every closure input folded to a constant, else the bytecode

What the compiler does, in order:

1. **Closures flatten** into a weighted list of lobes (Mix / Add Shader trees of any depth), which become the tracer's
   closure inputs (:data:`tracer.shader_N.OUT_SLOTS`: one blended Principled set) and, where one closure cannot hold
   the tree (several reflecting lobes, a Glossy, Glass-beside-something, Translucent, Refraction, Holdout or tinted
   Transparent leaf), lobe slots (:mod:`tracer.shading.lobes`): :mod:`tracer.shading.closures` does both.
2. **Outputs** are registers: each closure input's (``outs``) and each lobe slot's (``Program.lobes``).
3. **Constants fold**: every op whose operands are constants is evaluated at compile time by the same numba
   functions the VM runs (:mod:`tracer.shading.ops`), so a graph whose outputs are constants compiles to zero ops
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

from . import nodes as N, ops
from .closures import ClosureLowering, LobeSlots
from .graph import Graph, Implicit, Node, Out
from .lobes import MAX_LOBES
from .nodes import transform2d_matrix  # noqa: F401  (re-exported: the USD readers' UsdTransform2d)
from .nodes import (COLOR, FLOAT, NODE_TYPES, OPCODE, OPS, VECTOR, Reg, TextureUse, convert_constant,
                    is_const as _is_const, vec3 as _vec)
from .principled import row_surface
from .texture import Texture, as_texture


@dataclass
class Program:
    """One material's bytecode: ``code`` (n, WIDTH) int32 with registers relative to the material's base, the
    initial register file ``init`` (constants), ``outs`` (8,) the register of each closure input (-1: the row's
    constant), and the textures its image ops name by position (``TextureUse``)."""

    code: np.ndarray
    init: np.ndarray
    outs: np.ndarray
    textures: list
    lobes: LobeSlots | None = None  # the closure's lobe slots (tracer.shading.closures), None: one closure

    @property
    def n_ops(self) -> int:
        return len(self.code)

    def disassemble(self) -> str:
        lines = []
        for row in self.code:
            lines.append(f"{N.OP_NAMES[row[0]]:>12} " + " ".join(str(int(x)) for x in row[1:]))
        return "\n".join(lines)


@dataclass
class Compiled:
    row: dict
    program: Program | None
    vertex_colors: list = field(default_factory=list)  # Color Attribute / colour primvar names read ('' = default)
    uv_maps: list = field(default_factory=list)  # UV map names read ('' = the default set)


# ---------------------------------------------------------------------------------------------- the emitter
def _operand(item) -> bool:
    """An operand that is a value: (value, width), not a raw int."""
    return isinstance(item, tuple) and (isinstance(item[0], Reg) or (
        len(item) == 2 and not isinstance(item[0], (int, np.integer))))


class _Emitter:
    def __init__(self):
        self.code: list[list[int]] = []
        self.reads: list[list[tuple]] = []  # per op: (register, width) it reads
        self.widths: list[int] = []
        self.init: list[float] = []
        self._consts: dict = {}
        self._cse: dict = {}
        self.varying: set = set()  # registers an instruction writes (the rest are constants)

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

    def is_const(self, x) -> bool:
        """A value known now: a float or tuple, or a Reg of constant registers."""
        return not isinstance(x, Reg) or not any(r in self.varying for r in range(x.r, x.r + x.n))

    def fields(self, operands: list) -> tuple[list, list]:
        """(fields a..f, the (register, width) each reads) of ``operands``: each (value, width), or an int (raw)."""
        fields = []
        reads = []
        for item in operands:
            if _operand(item):
                x, n = item
                r = self.reg(x, n)
                fields.append(r)
                reads.append((r, n))
            else:
                fields.append(int(item))
        fields += [0] * (6 - len(fields))
        return fields, reads

    def emit(self, op: int, width: int, operands: list, imm: int = 0, uv: int = -1, raw: dict | None = None) -> Reg:
        """One instruction: ``operands`` fill fields a..f in order (:meth:`fields`); returns its result registers
        (CSE: an identical instruction is emitted once)."""
        fields, reads = self.fields(operands)
        key = (op, tuple(fields), imm)
        if key in self._cse:
            return Reg(self._cse[key], width, uv)
        dst = self.alloc(width)
        self.varying.update(range(dst, dst + width))
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
        code = np.array([c for c, k in zip(self.code, keep) if k], np.int32).reshape(-1, N.WIDTH)
        return code, np.array(self.init, np.float64)


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
        self._bump_fw: float | None = None
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
        """A value of socket kind ``src`` as kind ``dst`` (:func:`tracer.shading.nodes.convert_constant`'s rule;
        per hit by the lum / avg / combine instructions)."""
        if src == dst or {src, dst} <= {VECTOR, COLOR}:
            return x
        if _is_const(x):
            return convert_constant(x, src, dst)
        if dst == FLOAT:
            return self.op("lum" if src == COLOR else "avg", [(x, 3)])
        if src == FLOAT:  # to a vector / colour
            return self.op("combine", [(x, 1), (x, 1), (x, 1)])
        return x

    def op(self, name: str, operands: list, imm: int = 0, uv: int = -1, raw: dict | None = None):
        """The instruction ``name`` of :data:`tracer.shading.nodes.OPS` on ``operands`` (:meth:`_Emitter.fields`),
        as many registers wide as its row says; folded to a constant by its row's ``fold`` when every operand is
        one (a float for one register, else a tuple)."""
        spec = OPS[OPCODE[name]]
        width = spec.width(imm)
        reads = (raw or {}).get("reads", [])
        if spec.fold is not None and all(self.e.is_const(item[0]) for item in operands if _operand(item)) and \
                all(self.e.is_const(Reg(r, n)) for r, n in reads):
            fields, _reads = self.e.fields(operands)
            o = len(self.e.init)
            R = np.zeros(o + width, np.float64)
            R[:o] = self.e.init
            spec.fold(R, o, *fields, imm)
            vals = tuple(float(x) for x in R[o:o + width])
            return vals[0] if width == 1 else vals
        return self.e.emit(OPCODE[name], width, operands, imm, uv, raw)

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
            return self.hit(N.IN_NORMAL)
        if what.what == "uv":
            return self.uv("", variant)
        if what.what == "generated":
            return self.hit(N.IN_GENERATED, variant=variant)
        if what.what == "position":
            return self.hit(N.IN_POSITION, variant=variant)
        return self.hit(N.IN_TANGENT, arg=0)

    def hit(self, what: int, arg: int = 0, variant: int = 0, uv: int = -1):
        """An OP_INPUT (in estimate mode: a neutral constant)."""
        if self.estimate:
            return {N.IN_NORMAL: (0.0, 0.0, 1.0), N.IN_TRUE_NORMAL: (0.0, 0.0, 1.0), N.IN_INCOMING: (0.0, 0.0, 1.0),
                    N.IN_COLOR: (1.0, 1.0, 1.0), N.IN_UV: (0.5, 0.5, 0.0), N.IN_GENERATED: (0.5, 0.5, 0.5),
                    N.IN_COLOR_ALPHA: (1.0, 0.0, 0.0), N.IN_IS_CAMERA: (1.0, 0.0, 0.0)}.get(what, (0.0, 0.0, 0.0))
        setup = 0
        if variant > 0:
            setup = self.bump_setup().r
        return self.op("input", [arg, variant, setup], imm=what, uv=uv,
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
        return self.hit(N.IN_UV, arg=k, variant=variant, uv=k)

    def bump_filter_width(self, fw) -> None:
        """The Filter Width of the program's bump offsets (Cycles': × the pixel's ray differential): the first Bump
        node's, set before its offset heights are read (one set of offsets per program: a later Bump node of another
        width is warned about and shares the first's; a linked width reads as Blender's default 0.1)."""
        w = float(fw) if _is_const(fw) else 0.1
        if self._bump_fw is None:
            self._bump_fw = w
        elif abs(self._bump_fw - w) > 1e-9:
            self.warn("bump filter width", f"Bump nodes of different Filter Width: {self._bump_fw:g} is used for all")

    def bump_setup(self) -> Reg:
        if self._bump_setup is None:
            fw = self._bump_fw if self._bump_fw is not None else 0.1  # the Displacement bump's: Cycles' default
            self._bump_setup = self.op("bump_setup", [(max(fw, 1e-6), 1)])
        return self._bump_setup

    def scalar(self, x) -> tuple:
        return (x, 1)

    def v3(self, x) -> tuple:
        return (x, 3)

    # ------------------------------------------------------------------ generic helpers (folding)
    def math(self, op: int, a, b=0.0, c=0.0, clamp=False):
        """A Math op (folded where its operands are constants; x·1, x·0, x + 0 simplified)."""
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
        return self.op("math", [(a, 1), (b, 1), (c, 1)], imm=int(op) | (256 if clamp else 0))

    def vmath(self, op: int, a, b=(0.0, 0.0, 0.0), c=(0.0, 0.0, 0.0), s=1.0):
        """(vector, value) of a Vector Math op."""
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
        r = self.op("vmath", [(a, 3), (b, 3), (c, 3), (s, 1)], imm=int(op), uv=a.uv if isinstance(a, Reg) else -1)
        return (Reg(r.r, 3, r.uv), Reg(r.r + 3, 1)) if isinstance(r, Reg) else (r[:3], r[3])

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
        return self.op("mix_f", [(f, 1), (a, 1), (b, 1)])

    def lerp3(self, a, b, f):
        if _is_const(f):
            f = float(f)
            if f <= 0.0:
                return a
            if f >= 1.0:
                return b
        if _is_const(a) and _is_const(b) and _vec(a) == _vec(b):
            return a
        return self.op("mix_v", [(f, 1), (a, 3), (b, 3)])

    # ------------------------------------------------------------------ nodes
    def lower(self, node: Node, variant: int) -> dict:
        """The outputs of ``node`` (its entry's lowering in :data:`tracer.shading.nodes.NODE_TYPES`)."""
        fn = NODE_TYPES[node.type].lower
        if fn is None:
            self.warn(node.type + node.name, f"node {node.name!r} ({node.type}) is not evaluated by the tracer yet; "
                                             "its outputs read 0")
            out = {}
            for s in NODE_TYPES[node.type].outputs:
                out[s.name] = self.hit(N.IN_NORMAL) if s.name == "Normal" else (0.0 if s.kind == FLOAT
                                                                                  else (0.0, 0.0, 0.0))
            return out
        return fn(self, node, variant)

    # ------------------------------------------------------------------ inputs
    def _stand_in(self, node, what, value):
        self.warn(node.name + what, f"{what} ({node.name!r}) is not available; {value} is used")
        return value

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
        r = self.op("image", [(coord, 3), k, uv, (blend, 1)], imm=projection)
        return Reg(r.r, 4, src=(use, coord, (projection, blend)))

    def _rgba_out(self, rgba):
        if _is_const(rgba):
            return tuple(rgba[:3]), float(rgba[3])
        return Reg(rgba.r, 3, src=rgba.src), Reg(rgba.r + 3, 1)

    def _scene_mean(self, k):
        t = self.scene_textures[k] if getattr(self, "scene_textures", None) is not None else None
        if t is None:
            return (1.0, 1.0, 1.0, 1.0)
        m = t.rgba().reshape(-1, 4).mean(0) * np.asarray(t.scale) + np.asarray(t.bias)
        return tuple(float(x) for x in m)

    # ------------------------------------------------------------------ procedural textures (tracer.shading.procedural)
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
                self.e.code.append([N.OP_COPY, base + j, x.r, 0, 0, 0, 0, 0, 1])
                self.e.varying.add(base + j)
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

    def _proc(self, op: str, node, var, names, imm):
        if self.estimate:
            return None
        vec_in = self.inp(node, "Vector", VECTOR, var) if "Vector" in [s.name for s in NODE_TYPES[node.type].inputs] \
            else 0.0
        blk = self.block(self._flat([self.inp(node, n, None, var) for n in names]))
        raw = {"reads": [(blk.r, blk.n)]}
        return self.op(op, [(vec_in, 3), blk.r], imm=imm, raw=raw)

    # ------------------------------------------------------------------ normals


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
    outs = np.full(len(N.OUT_SLOTS), -1, np.int32)
    live = []
    for k, slot in enumerate(N.OUT_SLOTS):
        x = vals.get(slot)
        if x is None or _is_const(x):
            continue
        n = N.OUT_WIDTH[slot]
        if slot in ("normal", "smooth"):
            x = c.op("normalize_n", [(x, 3)])
        outs[k] = x.r
        live.append((x.r, n))
    slots = c.lobe_slots
    if slots is not None:
        live += slots.live
    program = None
    if live:
        code, init = c.e.finish(live)
        images = code[:, 0] == N.OP_IMAGE  # the textures the kept lookups read, renumbered
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
    if not extras.get("glass_multiscatter", True):  # single-scattering rough glass (Cycles' GGX, Beckmann)
        row["glass_multiscatter"] = 0.0
    if row["transmission"] > 0 or extras["transmission_tint"] is not None:
        # a Principled's glass tints each refraction by √(base colour), as Cycles' does (in and out: the base colour)
        row["transmission_tint"] = tuple(extras["transmission_tint"] or (x ** 0.5 for x in row["base_color"]))
    return row


def add_graph(builder, graph: Graph, warn=None, uv_index=None, name: str | None = None) -> int:
    """Compile ``graph`` and add its material row to a :class:`tracer.SceneBuilder`: its constant row, and the
    graph itself (with its UV map names resolved by ``uv_index``) where something varies per hit. Returns the
    row index."""
    compiled = compile_graph(graph, warn, uv_index)
    fields = dict(compiled.row)
    if compiled.program is not None or any(n.type == "holdout" for n in graph.nodes.values()):  # tracer.integrator.compose
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
    (N,) bool: the material has a program; its closure's lobe slots (:class:`tracer.shading.closures.LobeSlots`)
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
        return self.outs[:, N.OUT_ALPHA] >= 0


def pack_programs(m, textures: list) -> tuple[ProgramTable, list]:
    """(the :class:`ProgramTable` of a Materials table, the textures its image ops read: ``textures`` followed by
    those the graphs' ImageRefs add). Kept on the table while its graphs, texture columns and the constants
    they multiply are the same (a session renders again without compiling again)."""
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
    n = len(m)
    tex_slots, _ = m.texture_slots()
    programs = getattr(m, "programs", None) or [None] * n
    out_textures = list(textures)
    added: dict = {}
    codes, inits = [], []
    pstart = np.zeros(n + 1, np.int32)
    pbase = np.zeros(n, np.int32)
    outs = np.full((n, len(N.OUT_SLOTS)), -1, np.int32)
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
            graph = row_surface(m, i, textures).graph(m.names[i] if i < len(m.names) else f"material{i}")
            prog = compile_graph(graph, None, lambda name: name if isinstance(name, int) else 0, textures,
                                 row=False).program
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
        image_ops = code[:, 0] == N.OP_IMAGE
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
    code = np.concatenate(codes) if codes else np.zeros((0, N.WIDTH), np.int32)
    R0 = np.concatenate(inits) if inits else np.zeros(1, np.float64)
    return ProgramTable(np.ascontiguousarray(code, np.int32), pstart, pbase, outs, np.ascontiguousarray(R0),
                        has, lobe_kind, lobe_out, lobe_extra), out_textures

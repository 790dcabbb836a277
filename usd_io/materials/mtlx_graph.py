"""MaterialX node networks (``ND_*`` shaders in USD, or nodes of a ``.mtlx`` document translated by
:mod:`usd_io.materials.mtlx`) written into the tracer's shader graph (:mod:`tracer.shading.graph`), with MaterialX's own
definitions.

Every node is read against its node definition (:func:`usd_io.materials.mtlx.nodedef`: the standard libraries and each
document's own ``<nodedef>`` s): unconnected inputs take the definition's value, or its ``defaultgeomprop``
(``UV0`` the default UV set, ``Pobject``/``Pworld`` the position, ``Nobject``/``Nworld`` the normal, ``Tworld`` the
tangent). A node this module translates natively becomes IR nodes, reusing Cycles' where the semantics are the
same; a node whose definition is implemented by a node graph (``ramp4``, ``hsvadjust``, ``place2d``, a document's
custom node) is expanded through that graph, its ``interfacename`` inputs reading the outer node's inputs, to any
depth. Anything else prints one warning naming the node and reads as its definition's default output.

Natively, with MaterialX's semantics (its GLSL reference implementation):

    noise2d/3d, fractal2d/3d, cellnoise2d/3d, worleynoise2d/3d   ``mx_noise`` (tracer.shading.procedural.mx_noise)
    image, tiledimage      ``usd_uv_texture`` on any texcoord network; tiledimage: texcoord · uvtiling − uvoffset
    add, subtract, multiply, divide, modulo (floored), power, min, max, clamp, absval, floor, ceil, sign, sqrt,
    exp, ln, sin, cos, tan, asin, acos, atan2, invert (amount − in)   ``math`` / ``vector_math``, channel by channel
    mix (bg·(1 − mix) + fg·mix, no clamp), ifgreater, ifgreatereq, ifequal (exact comparisons)
    ramplr/ramptb (clamped texcoord), splitlr/splittb (a step at ``center``), remap (no clamp), smoothstep
    dotproduct, normalize, magnitude, crossproduct, luminance (``lumacoeffs``, ACEScg's by default),
    rgbtohsv/hsvtorgb (hue wraps), convert, extract, separate2/3/4, combine2/3/4, swizzle, constant, dot
    position, normal, tangent, texcoord, geompropvalue (a vector2 primvar as a UV set, others as the mesh's colour
    primvar), geomcolor
    normalmap (tangent space, ``scale`` on x and y), bump (height · scale along the normal: Cycles' Bump node with
    Distance = scale, which is the same first-order normal N − scale·∇h)

A value is a :class:`V`: its MaterialX type and an IR value (a constant or a link) of one lane (float, integer,
boolean) or three (vector2 with z = 0, vector3, color3); color4/vector4 carry their fourth lane separately.
"""

from __future__ import annotations

import math

import MaterialX as mx
import numpy as np
from pxr import Sdf, UsdShade

from tracer.shading.compiler import Compiler
from tracer.shading.graph import Graph, Out
from tracer.shading.nodes import FLOAT, VECTOR

from . import mtlx, network as net
from .arnold_patterns import graph_node as arnold_node
from .primvars import DEFAULT_UV
from .shade_types import WIDTH, V
from .texture_assets import authoring_layer


def _py(v):
    """A MaterialX or USD value as a float or a tuple of floats."""
    if hasattr(v, "asTuple"):
        v = v.asTuple()
    if isinstance(v, (bool, int, float, np.floating, np.integer)):
        return float(v)
    try:
        return tuple(float(x) for x in v)
    except TypeError:
        return v


def _default_geomprop(inp) -> str | None:
    """The ``defaultgeomprop`` of the node-graph interface input that ``inp`` (a UsdShade input without a value)
    is connected to, through nested graphs (:mod:`usd_io.materials.mtlx` writes it as custom data)."""
    seen = 0
    while inp and seen < 16:
        seen += 1
        sources = inp.GetConnectedSources()[0] if inp.HasConnectedSource() else []
        if not sources or sources[0].sourceType != UsdShade.AttributeType.Input:
            return None
        src = sources[0].source.GetInput(sources[0].sourceName)
        gp = src.GetAttr().GetCustomData().get("mtlx:defaultgeomprop") if src else None
        if gp:
            return str(gp)
        inp = src
    return None


class UsdNode:
    """A node of a UsdShade network (its inputs followed through NodeGraph interfaces)."""

    def __init__(self, shader: UsdShade.Shader, time=None):
        self.s, self.time = shader, time
        self.sid = net.shader_id(shader)
        self.key = self.name = str(shader.GetPath())

    def input(self, name: str):
        a, is_out = net.producer(self.s, name)
        if a is None:
            gp = _default_geomprop(self.s.GetInput(name))
            return ("geomprop", gp) if gp else None
        if is_out:
            return ("link", UsdNode(UsdShade.Shader(a.GetPrim()), self.time), UsdShade.Output(a).GetBaseName())
        v = a.Get() if self.time is None else a.Get(self.time)
        if v is None:  # an interface input with no value
            gp = a.GetCustomData().get("mtlx:defaultgeomprop") or _default_geomprop(self.s.GetInput(name))
            return ("geomprop", str(gp)) if gp else None
        return ("const", v, a, a.GetColorSpace())


class MxNode:
    """A node of a node graph that implements ``outer``'s node definition (a library's or a document's)."""

    def __init__(self, node, outer):
        self.n, self.outer = node, outer
        nd = node.getNodeDef()
        self.sid = nd.getName() if nd else f"ND_{node.getCategory()}_{node.getType()}"
        self.key = f"{outer.key}/{node.getNamePath()}"
        self.name = f"{outer.name} ({node.getNamePath()})"

    def input(self, name: str):
        inp = self.n.getInput(name)
        if inp is None:
            return None
        if inp.getNodeName():
            up = self.n.getParent().getNode(inp.getNodeName())
            return None if up is None else ("link", MxNode(up, self.outer), inp.getOutputString() or "out")
        if inp.getInterfaceName():
            return ("outer", self.outer, inp.getInterfaceName())
        if not inp.getValueString():
            return None
        if inp.getType() == "filename":  # tokens substituted, relative to its document
            return ("const", mtlx.file_value(inp), None, inp.getActiveColorSpace())
        return ("const", inp.getValue(), None, inp.getActiveColorSpace())


class Outs:
    """A translated value seen as a lookup's node by :meth:`tracer.shading.principled.PrincipledSurface.graph`: outputs
    ``rgb`` (three lanes), ``r``, ``g``, ``b`` and ``a``."""

    def __init__(self, tr: "Translator", v: V):
        self.tr, self.v = tr, v

    def __getitem__(self, key):
        if key == "rgb":
            return self.tr.lanes3(self.v)
        if key == "a":
            return self.v.w if self.v.wide == 4 else 1.0
        return self.tr.lane(self.v, "rgb".index(key))


class Translator:
    """Writes MaterialX values into one IR graph ``g`` (one per material; nodes shared between the inputs)."""

    def __init__(self, table, g, label: str, needs, time=None):
        self.table, self.g, self.label, self.needs, self.time = table, g, label, needs, time
        self._cache: dict = {}
        self._warned: set = set()

    # ------------------------------------------------------------------ plumbing
    def unknown_space(self, space: str) -> None:
        self.warn(f"space {space}", f"MaterialX colour space {space!r} is not one MaterialX's colour management "
                                    "knows (values read as linear Rec.709)")

    def warn(self, key: str, message: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            self.table.warn(f"{self.label}: {message}")

    def add(self, type_, inputs=None, out=None, **params):
        node = self.g.add(type_, inputs or {}, **params)
        return node[out] if out else node

    def math(self, op, a, b=0.0, c=0.0):
        return self.add("math", {"Value": a, "Value_001": b, "Value_002": c}, "Value", operation=op)

    def vmath(self, op, a, b=(0.0, 0.0, 0.0), c=(0.0, 0.0, 0.0), out="Vector"):
        return self.add("vector_math", {"Vector": a, "Vector_001": b, "Vector_002": c}, out, operation=op)

    def lane(self, v: V, i: int):
        """Lane ``i`` (0–3) of a value as a float."""
        if i == 3:
            return v.w if v.wide == 4 else 0.0
        if v.wide == 1:
            return v.x
        if not hasattr(v.x, "node"):
            return float(tuple(v.x)[i])
        return self.add("separate_xyz", {"Vector": v.x}, "XYZ"[i])

    def lanes3(self, v: V):
        """The first three lanes as a vector (a float broadcast)."""
        if v.wide == 1 and not hasattr(v.x, "node"):
            return (float(v.x),) * 3
        return v.x

    def pack(self, t: str, parts: list) -> V:
        """A value of type ``t`` from its lanes (floats or links)."""
        n = WIDTH.get(t, 1)
        if n == 1:
            return V(t, parts[0])
        xyz = list(parts[:3]) + [0.0] * (3 - min(3, len(parts)))
        if n == 2:
            xyz[2] = 0.0
        if all(not hasattr(p, "node") for p in xyz):
            x = tuple(float(p) for p in xyz)
        else:
            x = self.add("combine_xyz", {"X": xyz[0], "Y": xyz[1], "Z": xyz[2]}, "Vector")
        return V(t, x, parts[3] if n == 4 and len(parts) > 3 else 1.0)

    def flat2(self, v: V) -> V:
        """A vector2 with its third lane 0 (the convention every vector2 value keeps): a float operand broadcast
        over three lanes (``uv − 0.5``) would leave −0.5 there, and a dot product or length would count it."""
        if v.t != "vector2" or v.wide != 2:
            return v
        if not hasattr(v.x, "node"):
            x = tuple(float(c) for c in v.x)
            return V(v.t, (x[0], x[1], 0.0), v.w)
        return V(v.t, self.vmath("MULTIPLY", v.x, (1.0, 1.0, 0.0)), v.w)

    def cast(self, v: V, t: str) -> V:
        """``v`` as type ``t``: a float broadcast, a vector cut to its lanes, color3 ↔ vector3 as is."""
        if v.t == t or t not in WIDTH or v.t not in WIDTH:
            return V(t, v.x, v.w) if t in WIDTH else v
        n, m = WIDTH[t], v.wide
        if m == 1:
            if n == 1:
                return V(t, v.x)
            if n == 2:
                return self.pack(t, [v.x, v.x])
            return V(t, self.lanes3(v), v.x if n == 4 else 1.0)
        if n == 1:
            return V(t, self.lane(v, 0))
        if n == 2 and m > 2:
            return self.pack(t, [self.lane(v, 0), self.lane(v, 1)])
        return V(t, v.x, v.w if m == 4 else 1.0)

    def const(self, value, t: str) -> V:
        value = _py(value)
        n = WIDTH.get(t, 1)
        if isinstance(value, str) or value is None:
            return V(t, 0.0 if n == 1 else (0.0, 0.0, 0.0), 1.0)
        vals = list(np.ravel(value).astype(float)) if np.ndim(value) else [float(value)]
        if n == 1:
            return V(t, vals[0])
        if len(vals) == 1:
            vals = vals * n
        vals = (vals + [0.0] * 4)[:4]
        xyz = (vals[0], vals[1], vals[2] if n > 2 else 0.0)
        return V(t, xyz, vals[3] if n == 4 else 1.0)

    # ------------------------------------------------------------------ nodes
    def out(self, view, output: str = "out") -> V:
        """The value of output ``output`` of a node (cached: each node is written once)."""
        key = (view.key, output)
        if key not in self._cache:
            self._cache[key] = self._node(view, output)
        return self._cache[key]

    def _node(self, view, output: str) -> V:
        if view.sid.startswith("arnold:") and isinstance(view, UsdNode):  # Arnold patterns (usd_io.materials.arnold_patterns)
            return arnold_node(self, view, output)
        nd = mtlx.nodedef(view.sid) if view.sid.startswith("ND_") or view.sid else None
        if nd is None:
            self.warn(view.key, f"MaterialX node {view.name} ({view.sid or 'no shader id'}) has no node definition "
                                "(read as 0)")
            return V("float", 0.0)
        outs = nd.getActiveOutputs()
        o = nd.getActiveOutput(output) or (outs[0] if outs else None)
        t = o.getType() if o is not None else "float"
        c = _Ctx(self, view, nd)
        fn = getattr(self, f"_n_{nd.getNodeString()}", None)
        if fn is not None:
            return self.flat2(self.cast(fn(c, t, output), t))
        impl = nd.getImplementation()
        if isinstance(impl, mx.NodeGraph):
            go = impl.getOutput(output) or (impl.getOutputs()[0] if impl.getOutputs() else None)
            inner = impl.getNode(go.getNodeName()) if go is not None and go.getNodeName() else None
            if inner is not None:
                return self.cast(self.out(MxNode(inner, view), go.getOutputString() or "out"), t)
            if go is not None and go.getInterfaceName():
                return self.cast(c.i(go.getInterfaceName()), t)
        default = o.getDefaultValue() if o is not None and o.hasAttribute("default") else None
        self.warn(view.key, f"MaterialX node {view.name} ({nd.getName()}) is not supported (read as "
                            f"{_py(default) if default is not None else 0})")
        if o is not None and o.getAttribute("defaultinput"):
            return self.cast(c.i(o.getAttribute("defaultinput")), t)
        return self.const(default if default is not None else 0.0, t)

    # geometric defaults
    def geomprop(self, name: str, t: str) -> V:
        if name in ("UV0", "UV"):
            return self.cast(V("vector2", self.uvmap("")), t)
        if name.startswith("UV") and name[2:].isdigit():
            return self.cast(V("vector2", self.uvmap(f"st{name[2:]}")), t)
        if name in ("Pobject", "Pmodel"):
            return V(t, self.add("texture_coordinate", out="Object"))
        if name == "Pworld":
            return V(t, self.add("geometry", out="Position"))
        if name == "Nobject":
            return V(t, self.add("texture_coordinate", out="Normal"))
        if name in ("Nworld",):
            return V(t, self.add("geometry", out="Normal"))
        if name.startswith("T"):
            return V(t, self.add("geometry", out="Tangent"))
        if name.startswith("B"):
            n, tg = self.add("geometry", out="Normal"), self.add("geometry", out="Tangent")
            return V(t, self.vmath("CROSS_PRODUCT", n, tg))
        self.warn(f"geomprop {name}", f"MaterialX default geometric property {name!r} is not supported (0 used)")
        return self.const(0.0, t)

    def uvmap(self, name: str):
        k = self.table.uv_set_index(name or None)
        self.needs.uv_sets.add(self.table.uv_set_names[k] if name else DEFAULT_UV)
        return self.add("uvmap", out="UV", attribute=name)

    # ---- noise
    def _noise(self, c, t, kind, dims, coord):
        v = self.lanes3(c.i(coord, "vector3" if dims == 3 else "vector2"))
        n = WIDTH.get(t, 1)
        inputs = {"Vector": v}
        if c.has("amplitude"):
            amp = c.i("amplitude")
            inputs["Amplitude"] = self.lanes3(amp)
            inputs["Amplitude W"] = amp.w if amp.wide == 4 else (amp.x if amp.wide == 1 else 1.0)
        for socket, name in (("Pivot", "pivot"), ("Octaves", "octaves"), ("Lacunarity", "lacunarity"),
                             ("Diminish", "diminish"), ("Jitter", "jitter")):
            if c.has(name):
                inputs[socket] = c.f(name)
        style = int(c.uniform("style", 0) or 0)
        node = self.add("mx_noise", inputs, kind=kind, dimensions=dims, width=n, style=style)
        if n == 1:
            return V(t, node["Value"])
        return V(t, node["Vector"], node["W"])

    def _n_noise2d(self, c, t, o):
        return self._noise(c, t, "perlin", 2, "texcoord")

    def _n_noise3d(self, c, t, o):
        return self._noise(c, t, "perlin", 3, "position")

    def _n_fractal2d(self, c, t, o):
        return self._noise(c, t, "fractal", 2, "texcoord")

    def _n_fractal3d(self, c, t, o):
        return self._noise(c, t, "fractal", 3, "position")

    def _n_cellnoise2d(self, c, t, o):
        return self._noise(c, t, "cell", 2, "texcoord")

    def _n_cellnoise3d(self, c, t, o):
        return self._noise(c, t, "cell", 3, "position")

    def _n_worleynoise2d(self, c, t, o):
        return self._noise(c, t, "worley", 2, "texcoord")

    def _n_worleynoise3d(self, c, t, o):
        return self._noise(c, t, "worley", 3, "position")

    # ---- images
    def _graph_image_lookup(self, c, t):
        """The lookup of an ``image`` inside a node graph implementation (triplanarprojection's): its file comes
        through the interface from the USD shader's input (colour space and layer from that attribute)."""
        r, a = c.view.input("file"), None
        while r is not None and r[0] == "outer":
            outer, key = r[1], r[2]
            r = outer.input(key)
            if r is None:  # the instance does not author it: its definition's default file
                ond = mtlx.nodedef(outer.sid)
                d = ond.getActiveInput(key) if ond is not None else None
                if d is not None and d.getType() == "filename" and d.getValueString():
                    r = ("const", mtlx.file_value(d), None, d.getActiveColorSpace())
        if r is None or r[0] != "const" or not isinstance(r[1], Sdf.AssetPath):
            return None
        a = r[2]  # a USD attribute, or None for a file named inside a node graph implementation or its definition
        space = a.GetColorSpace() if a is not None else r[3]
        default = self.const(_py(c.uniform("default", 0.0)), "color3").x
        wrap = [net.MX_ADDRESS.get(str(c.uniform(f"{k}addressmode", "periodic")), "repeat") for k in "uv"]
        return net.TextureLookup(node=c.view.name, asset=r[1], channel=0 if WIDTH.get(t, 1) == 1 else -1, uv=None,
                                 transform=np.eye(3), scale=(1.0, 1.0, 1.0, 1.0), bias=(0.0, 0.0, 0.0, 0.0),
                                 fallback=tuple(default) + (1.0,), wrap_s=wrap[0], wrap_t=wrap[1],
                                 colorspace=mtlx.texture_colorspace(space)[0],
                                 layer=authoring_layer(a) if a is not None else None)

    def _n_image(self, c, t, o, tiled=False):
        lk = net.mx_image_lookup(c.view.s) if isinstance(c.view, UsdNode) else self._graph_image_lookup(c, t)
        if lk is None:
            self.warn(c.view.key, f"MaterialX image {c.view.name}: no file (its default is used)")
            return c.i("default")
        lk.uv, lk.transform = None, np.eye(3)
        lk.notes = [n for n in lk.notes if not n.startswith("texcoord")]
        uvl, fallback = self.table._texture(lk, self.label, c.view.name, self.needs)
        if uvl is None:
            return self.const(fallback, t) if WIDTH.get(t, 1) > 1 else V(t, float(fallback[0]))
        st = c.i("texcoord", "vector2")
        if tiled:  # NG_tiledimage: ((uv · uvtiling − uvoffset) / realworldimagesize) · realworldtilesize
            tiling, offset = c.i("uvtiling", "vector2"), c.i("uvoffset", "vector2")
            st = V("vector2", self.vmath("SUBTRACT", self.vmath("MULTIPLY", st.x, tiling.x), offset.x))
            image, tile = c.i("realworldimagesize", "vector2"), c.i("realworldtilesize", "vector2")
            if hasattr(image.x, "node") or hasattr(tile.x, "node") or \
                    not np.allclose(np.asarray(tile.x[:2]) / np.asarray(image.x[:2]), 1.0):
                size = self.vmath("DIVIDE", self.lanes3(tile), self.vmath("MAXIMUM", self.lanes3(image), (1e-9,) * 3))
                st = V("vector2", self.vmath("MULTIPLY", st.x, size))
        st_x = st.x
        if not np.allclose(uvl.transform, np.eye(3)):
            st_x = self.add("usd_transform2d", {"in": st_x}, "result", matrix=np.asarray(uvl.transform))
        node = self.add("usd_uv_texture", {"st": st_x}, image=uvl.image, scale=tuple(uvl.scale),
                        bias=tuple(uvl.bias), fallback=tuple(uvl.fallback), name=uvl.label)
        if WIDTH.get(t, 1) == 1:
            return V(t, node["r"])
        return V(t, node["rgb"], node["a"])

    def _n_tiledimage(self, c, t, o):
        return self._n_image(c, t, o, tiled=True)

    # ---- arithmetic
    def _lanewise(self, t, op, *vals):
        """A float Math operation applied lane by lane (a float operand broadcast)."""
        n = WIDTH.get(t, 1)
        if n == 1:
            return V(t, self.math(op, *[v.x if v.wide == 1 else self.lane(v, 0) for v in vals]))
        parts = []
        for i in range(n):
            parts.append(self.math(op, *[v.x if v.wide == 1 else self.lane(v, i) for v in vals]))
        return self.pack(t, parts)

    def _binary(self, c, t, op, vop, a="in1", b="in2"):
        x, y = c.i(a), c.i(b)
        if WIDTH.get(t, 1) == 1 or vop is None:
            return self._lanewise(t, op, x, y)
        xyz = self.vmath(vop, self.lanes3(x), self.lanes3(y))
        w = self.math(op, x.w if x.wide == 4 else x.x, y.w if y.wide == 4 else (y.x if y.wide == 1 else 0.0)) \
            if WIDTH[t] == 4 else 1.0
        return V(t, xyz, w)

    def _n_add(self, c, t, o):
        return self._binary(c, t, "ADD", "ADD")

    def _n_subtract(self, c, t, o):
        return self._binary(c, t, "SUBTRACT", "SUBTRACT")

    def _n_multiply(self, c, t, o):
        return self._binary(c, t, "MULTIPLY", "MULTIPLY")

    def _n_divide(self, c, t, o):
        return self._binary(c, t, "DIVIDE", "DIVIDE")

    def _n_modulo(self, c, t, o):
        return self._binary(c, t, "FLOORED_MODULO", None)

    def _n_power(self, c, t, o):
        return self._binary(c, t, "POWER", "POWER")

    def _n_min(self, c, t, o):
        return self._binary(c, t, "MINIMUM", "MINIMUM")

    def _n_max(self, c, t, o):
        return self._binary(c, t, "MAXIMUM", "MAXIMUM")

    def _n_atan2(self, c, t, o):  # MaterialX: atan(iny, inx)
        return self._lanewise(t, "ARCTAN2", c.i("iny"), c.i("inx"))

    def _n_clamp(self, c, t, o):
        lo = self._lanewise(t, "MAXIMUM", c.i("in"), c.i("low"))
        return self._lanewise(t, "MINIMUM", lo, c.i("high"))

    def _n_invert(self, c, t, o):
        return self._lanewise(t, "SUBTRACT", c.i("amount"), c.i("in"))

    def _unary(self, c, t, op):
        return self._lanewise(t, op, c.i("in"))

    _n_absval = lambda self, c, t, o: self._unary(c, t, "ABSOLUTE")  # noqa: E731
    _n_floor = lambda self, c, t, o: self._unary(c, t, "FLOOR")  # noqa: E731
    _n_ceil = lambda self, c, t, o: self._unary(c, t, "CEIL")  # noqa: E731
    _n_sign = lambda self, c, t, o: self._unary(c, t, "SIGN")  # noqa: E731
    _n_sqrt = lambda self, c, t, o: self._unary(c, t, "SQRT")  # noqa: E731
    _n_exp = lambda self, c, t, o: self._unary(c, t, "EXPONENT")  # noqa: E731
    _n_sin = lambda self, c, t, o: self._unary(c, t, "SINE")  # noqa: E731
    _n_cos = lambda self, c, t, o: self._unary(c, t, "COSINE")  # noqa: E731
    _n_tan = lambda self, c, t, o: self._unary(c, t, "TANGENT")  # noqa: E731
    _n_asin = lambda self, c, t, o: self._unary(c, t, "ARCSINE")  # noqa: E731
    _n_acos = lambda self, c, t, o: self._unary(c, t, "ARCCOSINE")  # noqa: E731

    def _n_ln(self, c, t, o):
        return self._lanewise(t, "LOGARITHM", c.i("in"), V("float", math.e))

    # ---- mixing and conditions
    def mix(self, t, bg: V, fg: V, f: V) -> V:
        """bg·(1 − f) + fg·f (no clamp), lane by lane when f is not a float."""
        if f.wide != 1:
            return self.pack(t, [self.add("mix_float", {"Factor": self.lane(f, i), "A": self.lane(bg, i),
                                                        "B": self.lane(fg, i)}, "Result", use_clamp=False)
                                 for i in range(WIDTH.get(t, 1))])
        if WIDTH.get(t, 1) == 1:
            return V(t, self.add("mix_float", {"Factor": f.x, "A": bg.x, "B": fg.x}, "Result", use_clamp=False))
        xyz = self.add("mix_vector", {"Factor": f.x, "A": self.lanes3(bg), "B": self.lanes3(fg)}, "Result",
                       use_clamp=False)
        w = self.add("mix_float", {"Factor": f.x, "A": bg.w, "B": fg.w}, "Result", use_clamp=False) \
            if WIDTH[t] == 4 else 1.0
        return V(t, xyz, w)

    def _n_mix(self, c, t, o):
        return self.mix(t, c.i("bg"), c.i("fg"), c.i("mix"))

    def _cond(self, c, t, kind):
        a, b = c.f("value1"), c.f("value2")
        if kind == "gt":
            f = self.math("GREATER_THAN", a, b)
        elif kind == "ge":
            f = self.math("SUBTRACT", 1.0, self.math("LESS_THAN", a, b))
        else:
            f = self.math("SUBTRACT", 1.0, self.math("ADD", self.math("LESS_THAN", a, b),
                                                     self.math("GREATER_THAN", a, b)))
        return self.mix(t, c.i("in2", t), c.i("in1", t), V("float", f))

    def _n_ifgreater(self, c, t, o):
        return self._cond(c, t, "gt")

    def _n_ifgreatereq(self, c, t, o):
        return self._cond(c, t, "ge")

    def _n_ifequal(self, c, t, o):
        return self._cond(c, t, "eq")

    def _ramp(self, c, t, lane, lo, hi):
        s = self.add("clamp", {"Value": self.lane(c.i("texcoord", "vector2"), lane), "Min": 0.0, "Max": 1.0},
                     "Result")
        return self.mix(t, c.i(lo), c.i(hi), V("float", s))

    def _n_ramplr(self, c, t, o):
        return self._ramp(c, t, 0, "valuel", "valuer")

    def _n_ramptb(self, c, t, o):
        return self._ramp(c, t, 1, "valueb", "valuet")

    def _split(self, c, t, lane, lo, hi):
        x = self.lane(c.i("texcoord", "vector2"), lane)
        f = self.math("SUBTRACT", 1.0, self.math("LESS_THAN", x, c.f("center")))  # x >= center
        return self.mix(t, c.i(lo), c.i(hi), V("float", f))

    def _n_splitlr(self, c, t, o):
        return self._split(c, t, 0, "valuel", "valuer")

    def _n_splittb(self, c, t, o):
        return self._split(c, t, 1, "valueb", "valuet")

    def _n_remap(self, c, t, o):
        x, lo, hi, olo, ohi = (c.i(k) for k in ("in", "inlow", "inhigh", "outlow", "outhigh"))
        if WIDTH.get(t, 1) == 1:
            return V(t, self.add("map_range", {"Value": x.x, "From Min": lo.x, "From Max": hi.x, "To Min": olo.x,
                                               "To Max": ohi.x}, "Result", clamp=False))
        xyz = self.add("vector_map_range", {"Vector": self.lanes3(x), "From Min": self.lanes3(lo),
                                            "From Max": self.lanes3(hi), "To Min": self.lanes3(olo),
                                            "To Max": self.lanes3(ohi)}, "Vector", clamp=False)
        return V(t, xyz, x.w)

    def _n_smoothstep(self, c, t, o):
        x, lo, hi = c.i("in"), c.i("low"), c.i("high")
        parts = [self._smoothstep(self.lane(x, i) if x.wide > 1 else x.x, self.lane(lo, i) if lo.wide > 1 else lo.x,
                                  self.lane(hi, i) if hi.wide > 1 else hi.x)
                 for i in range(WIDTH.get(t, 1))]
        return self.pack(t, parts)

    def _smoothstep(self, x, lo, hi):
        """MaterialX's smoothstep as its GLSL implementation writes it (mx_smoothstep_float): 1 where x ≥ high, else
        0 where x ≤ low, else the Hermite of (x − low)/(high − low). With low > high that is a rising step at high
        (OSL's built-in rises too, at low); Blender's Map Range, on its own, would fall there."""
        mid = self.add("map_range", {"Value": x, "From Min": lo, "From Max": hi}, "Result",
                       interpolation_type="SMOOTHSTEP", clamp=False)
        at_hi = self.math("SUBTRACT", 1.0, self.math("LESS_THAN", x, hi))  # x ≥ high
        above_lo = self.math("GREATER_THAN", x, lo)  # x > low
        return self.math("ADD", at_hi, self.math("MULTIPLY", self.math("SUBTRACT", 1.0, at_hi),
                                                 self.math("MULTIPLY", above_lo, mid)))

    # ---- vectors
    def _n_dotproduct(self, c, t, o):
        a, b = c.i("in1"), c.i("in2")
        d = self.vmath("DOT_PRODUCT", self.lanes3(a), self.lanes3(b), out="Value")
        if a.wide == 4:
            d = self.math("MULTIPLY_ADD", a.w, b.w, d)
        return V("float", d)

    def _n_normalize(self, c, t, o):
        return V(t, self.vmath("NORMALIZE", self.lanes3(c.i("in"))))

    def _n_magnitude(self, c, t, o):
        return V("float", self.vmath("LENGTH", self.lanes3(c.i("in")), out="Value"))

    def _n_crossproduct(self, c, t, o):
        return V(t, self.vmath("CROSS_PRODUCT", self.lanes3(c.i("in1")), self.lanes3(c.i("in2"))))

    def _n_luminance(self, c, t, o):
        x = c.i("in")
        lum = self.vmath("DOT_PRODUCT", self.lanes3(x), self.lanes3(c.i("lumacoeffs")), out="Value")
        return V(t, lum, x.w)

    def _n_rgbtohsv(self, c, t, o):
        x = c.i("in")
        sep = self.add("separate_color", {"Color": self.lanes3(x)}, color_mode="HSV")
        return V(t, self.add("combine_xyz", {"X": sep["Red"], "Y": sep["Green"], "Z": sep["Blue"]}, "Vector"), x.w)

    def _n_hsvtorgb(self, c, t, o):
        x = c.i("in")
        h = self.math("FRACT", self.lane(x, 0))  # MaterialX's hsvtorgb is periodic in hue
        col = self.add("combine_color", {"Red": h, "Green": self.lane(x, 1), "Blue": self.lane(x, 2)}, "Color",
                       color_mode="HSV")
        return V(t, col, x.w)

    def _n_convert(self, c, t, o):
        x = c.i("in")
        if x.wide == 1 and WIDTH.get(t, 1) == 2:
            return self.pack(t, [x.x, x.x])
        return self.cast(x, t)

    def _n_extract(self, c, t, o):
        return V("float", self.lane(c.i("in"), int(c.uniform("index", 0) or 0)))

    def _n_switch(self, c, t, o):
        """in{which + 1}: a constant ``which`` picks its input; a connected one selects per hit (in1 below 1,
        in2 below 2, ... MaterialX's switch on floor(which), clamped to the inputs the definition has)."""
        which = c.view.input("which")
        while which is not None and which[0] == "outer":
            which = which[1].input(which[2])
        n = len([i for i in c.nd.getActiveInputs() if i.getName().startswith("in")]) or 1
        if which is None or which[0] != "link":
            k = int(_py(c.uniform("which", 0)) or 0)
            return c.i(f"in{min(max(k, 0), n - 1) + 1}", t)
        w = c.f("which")
        out = c.i("in1", t)
        for k in range(1, n):  # from in1 upwards: which >= k takes in(k+1)
            out = self.mix(t, out, c.i(f"in{k + 1}", t),
                           V("float", self.math("SUBTRACT", 1.0, self.math("LESS_THAN", w, float(k)))))
        return out

    def _n_blackbody(self, c, t, o):
        """The colour of a black body at ``temperature`` K (the tracer's Blackbody node, Cycles' table; MaterialX
        normalises its own fit the same way, to a luminance of 1 at the white point)."""
        return V(t, self.add("blackbody", {"Temperature": c.f("temperature")}, "Color"))

    def _n_artistic_ior(self, c, t, o):
        """Gulbrandsen's artist-friendly metallic Fresnel (outputs ``ior`` and ``extinction``), lane by lane:
        r = clamp(reflectivity, 0, 0.99), n = g·(1 − r)/(1 + r) + (1 − g)·(1 + √r)/(1 − √r),
        k = √(((n + 1)²·r − (n − 1)²)/(1 − r))."""
        r = self._lanewise("color3", "MINIMUM", self._lanewise("color3", "MAXIMUM", c.i("reflectivity"),
                                                                V("float", 0.0)), V("float", 0.99))
        g = c.i("edge_color")
        lanes = []
        for i in range(3):
            ri, gi = self.lane(r, i), self.lane(g, i)
            sr = self.math("SQRT", ri)
            n_min = self.math("DIVIDE", self.math("SUBTRACT", 1.0, ri), self.math("ADD", 1.0, ri))
            n_max = self.math("DIVIDE", self.math("ADD", 1.0, sr), self.math("SUBTRACT", 1.0, sr))
            n = self.math("ADD", self.math("MULTIPLY", gi, n_min),
                          self.math("MULTIPLY", self.math("SUBTRACT", 1.0, gi), n_max))
            if o == "extinction":
                np1, nm1 = self.math("ADD", n, 1.0), self.math("SUBTRACT", n, 1.0)
                k2 = self.math("DIVIDE", self.math("SUBTRACT", self.math("MULTIPLY", self.math("MULTIPLY", np1, np1),
                                                                               ri), self.math("MULTIPLY", nm1, nm1)),
                               self.math("SUBTRACT", 1.0, ri))
                lanes.append(self.math("SQRT", self.math("MAXIMUM", k2, 0.0)))
            else:
                lanes.append(n)
        return self.pack("color3", lanes)

    # ---- more arithmetic, logic and vectors (MaterialX's GLSL implementations)
    _n_fract = lambda self, c, t, o: self._unary(c, t, "FRACT")  # noqa: E731
    _n_round = lambda self, c, t, o: self._unary(c, t, "ROUND")  # noqa: E731

    def _n_and(self, c, t, o):
        return V(t, self.math("MULTIPLY", c.f("in1"), c.f("in2")))

    def _n_or(self, c, t, o):
        return V(t, self.math("MAXIMUM", c.f("in1"), c.f("in2")))

    def _n_not(self, c, t, o):
        return V(t, self.math("SUBTRACT", 1.0, c.f("in")))

    def _n_rotate2d(self, c, t, o):
        """(cos·x + sin·y, −sin·x + cos·y), ``amount`` in degrees (mx_rotate_vector2)."""
        v, a = c.i("in", "vector2"), self.math("RADIANS", c.f("amount"))
        sa, ca = self.math("SINE", a), self.math("COSINE", a)
        x, y = self.lane(v, 0), self.lane(v, 1)
        return self.pack(t, [self.math("ADD", self.math("MULTIPLY", ca, x), self.math("MULTIPLY", sa, y)),
                             self.math("SUBTRACT", self.math("MULTIPLY", ca, y), self.math("MULTIPLY", sa, x))])

    def _n_rotate3d(self, c, t, o):
        """in·cos + (in × axis)·sin + axis·(axis·in)·(1 − cos), axis normalised, ``amount`` in degrees."""
        v = self.lanes3(c.i("in", "vector3"))
        axis = self.vmath("NORMALIZE", self.lanes3(c.i("axis", "vector3")))
        a = self.math("RADIANS", c.f("amount"))
        sa, ca = self.math("SINE", a), self.math("COSINE", a)
        r = self.vmath("MULTIPLY", v, self._splat(ca))
        r = self.vmath("ADD", r, self.vmath("MULTIPLY", self.vmath("CROSS_PRODUCT", v, axis), self._splat(sa)))
        d = self.vmath("DOT_PRODUCT", axis, v, out="Value")
        r = self.vmath("ADD", r, self.vmath("MULTIPLY", axis, self._splat(self.math("MULTIPLY", d,
                                                                                    self.math("SUBTRACT", 1.0, ca)))))
        return V(t, r)

    def _splat(self, f):
        return (float(f),) * 3 if not hasattr(f, "node") else self.add("combine_xyz", {"X": f, "Y": f, "Z": f},
                                                                        "Vector")

    def _n_viewdirection(self, c, t, o):
        """The direction from the eye to the point (the negated Incoming of the hit)."""
        return V(t, self.vmath("MULTIPLY", self.add("geometry", out="Incoming"), (-1.0, -1.0, -1.0)))

    def _n_bitangent(self, c, t, o):
        return self.geomprop("Bworld", t)

    def _n_roughness_anisotropy(self, c, t, o):
        """α = clamp(r², ε, 1), stretched by the anisotropy (mx_roughness_anisotropy): (α / a, α·a), a = √(1 −
        clamp(anisotropy, 0, 0.98))."""
        r = c.f("roughness")
        alpha = self.math("MINIMUM", self.math("MAXIMUM", self.math("MULTIPLY", r, r), 1e-8), 1.0)
        an = c.f("anisotropy")
        if not hasattr(an, "node") and float(an) <= 0.0:
            return self.pack(t, [alpha, alpha])
        aspect = self.math("SQRT", self.math("SUBTRACT", 1.0, self.math("MINIMUM", self.math("MAXIMUM", an, 0.0),
                                                                         0.98)))
        return self.pack(t, [self.math("MINIMUM", self.math("DIVIDE", alpha, aspect), 1.0),
                             self.math("MULTIPLY", alpha, aspect)])

    def _n_roughness_dual(self, c, t, o):
        v = c.i("roughness", "vector2")
        x = self.lane(v, 0)
        y = self.lane(v, 1)
        if not hasattr(y, "node") and float(y) < 0:
            y = x
        sq = [self.math("MINIMUM", self.math("MAXIMUM", self.math("MULTIPLY", q, q), 1e-8), 1.0) for q in (x, y)]
        return self.pack(t, sq)

    def _transform(self, c, t, o):
        a, b = str(c.uniform("fromspace", "") or ""), str(c.uniform("tospace", "") or "")
        if a != b:
            self.warn(c.view.key, f"MaterialX {c.view.name}: a transform from {a!r} to {b!r} space is read as the "
                                  "identity")
        return c.i("in", t)

    _n_transformpoint = _n_transformvector = _n_transformnormal = _transform

    def _pass_through(self, c, t, o, what):
        self.warn(c.view.key, f"MaterialX {c.view.name}: {what}")
        return c.i("in", t) if c.has("in") else self.const(0.0, t)

    def _n_blur(self, c, t, o):
        return self._pass_through(c, t, o, "blur is not rendered (its input unblurred: the same mean colour)")

    def _n_heighttonormal(self, c, t, o):
        self.warn(c.view.key, f"MaterialX {c.view.name}: heighttonormal is not rendered (a flat normal)")
        return self.const((0.5, 0.5, 1.0), t)

    def _n_time(self, c, t, o):
        self.warn(c.view.key, f"MaterialX {c.view.name}: time is read as 0")
        return V(t, 0.0)

    def _n_frame(self, c, t, o):
        self.warn(c.view.key, f"MaterialX {c.view.name}: frame is read as 1")
        return V(t, 1.0)

    # ---- compositing (MaterialX's GLSL, lane by lane: the blend mixed with bg by ``mix``)
    def _blend(self, c, t, fn, alpha_lane=True):
        fg, bg, m = c.i("fg", t), c.i("bg", t), c.f("mix")
        parts = []
        for i in range(WIDTH.get(t, 1)):
            f_, b_ = self.lane(fg, i), self.lane(bg, i)
            r = fn(f_, b_, fg, bg, i)
            parts.append(self.math("ADD", self.math("MULTIPLY", m, r),
                                   self.math("MULTIPLY", self.math("SUBTRACT", 1.0, m), b_)))
        return self.pack(t, parts)

    def _n_plus(self, c, t, o):
        return self._blend(c, t, lambda f, b, *_: self.math("ADD", b, f))

    def _n_minus(self, c, t, o):
        return self._blend(c, t, lambda f, b, *_: self.math("SUBTRACT", b, f))

    def _n_difference(self, c, t, o):
        return self._blend(c, t, lambda f, b, *_: self.math("ABSOLUTE", self.math("SUBTRACT", b, f)))

    def _n_screen(self, c, t, o):
        return self._blend(c, t, lambda f, b, *_: self.math("SUBTRACT", 1.0, self.math(
            "MULTIPLY", self.math("SUBTRACT", 1.0, f), self.math("SUBTRACT", 1.0, b))))

    def _n_burn(self, c, t, o):
        return self._blend(c, t, lambda f, b, *_: self.math("SUBTRACT", 1.0, self.math(
            "DIVIDE", self.math("SUBTRACT", 1.0, b), f)))

    def _n_dodge(self, c, t, o):
        return self._blend(c, t, lambda f, b, *_: self.math("DIVIDE", b, self.math("SUBTRACT", 1.0, f)))

    def _n_over(self, c, t, o):
        return self._blend(c, t, lambda f, b, fg, bg, i: self.math("ADD", f, self.math(
            "MULTIPLY", b, self.math("SUBTRACT", 1.0, self.lane(fg, 3)))))

    def _n_in(self, c, t, o):
        return self._blend(c, t, lambda f, b, fg, bg, i: self.math("MULTIPLY", f, self.lane(bg, 3)))

    def _n_mask(self, c, t, o):
        return self._blend(c, t, lambda f, b, fg, bg, i: self.math("MULTIPLY", b, self.lane(fg, 3)))

    def _n_out(self, c, t, o):
        return self._blend(c, t, lambda f, b, fg, bg, i: self.math("MULTIPLY", f, self.math(
            "SUBTRACT", 1.0, self.lane(bg, 3))))

    def _n_matte(self, c, t, o):
        def fn(f, b, fg, bg, i):
            fa = self.lane(fg, 3)
            ff = self.math("MULTIPLY", f, fa) if i < 3 else f
            return self.math("ADD", ff, self.math("MULTIPLY", b, self.math("SUBTRACT", 1.0, fa)))
        return self._blend(c, t, fn)

    def _n_disjointover(self, c, t, o):
        def fn(f, b, fg, bg, i):
            fa, ba = self.lane(fg, 3), self.lane(bg, 3)
            if i == 3:
                return self.math("MINIMUM", self.math("ADD", fa, ba), 1.0)
            over = self.math("GREATER_THAN", self.math("ADD", fa, ba), 1.0)
            x = self.math("DIVIDE", self.math("SUBTRACT", 1.0, fa), ba)
            scaled = self.math("ADD", f, self.math("MULTIPLY", b, x))
            return self.add("mix_float", {"Factor": over, "A": self.math("ADD", f, b), "B": scaled}, "Result",
                            use_clamp=False)
        return self._blend(c, t, fn)

    def _n_inside(self, c, t, o):
        return self._lanewise(t, "MULTIPLY", c.i("in"), c.i("mask"))

    def _n_outside(self, c, t, o):
        m = c.i("mask")
        return self._lanewise(t, "MULTIPLY", c.i("in"), V(m.t, self.math("SUBTRACT", 1.0, m.x)) if m.wide == 1
                              else m)

    def _n_premult(self, c, t, o):
        x = c.i("in")
        return V(t, self.vmath("MULTIPLY", self.lanes3(x), self._splat(x.w)), x.w)

    def _n_unpremult(self, c, t, o):
        x = c.i("in")
        return V(t, self.vmath("DIVIDE", self.lanes3(x), self._splat(x.w)), x.w)

    def _n_constant(self, c, t, o):
        return c.i("value")

    def _n_dot(self, c, t, o):
        return c.i("in")

    def _separate(self, c, t, o):
        x = c.i("in")
        return V("float", self.lane(x, "xyzw".index(o[-1]) if o[-1] in "xyzw" else "rgba".index(o[-1])))

    _n_separate2 = _n_separate3 = _n_separate4 = _separate

    def _combine(self, c, t, o):
        names = [i.getName() for i in c.nd.getActiveInputs()]
        ins = [c.i(n) for n in names]
        if len(ins) == 2 and ins[0].wide == 3:  # combine4 from (vector3/color3, float)
            return V(t, ins[0].x, ins[1].x)
        return self.pack(t, [v.x if v.wide == 1 else self.lane(v, 0) for v in ins])

    _n_combine2 = _n_combine3 = _n_combine4 = _combine

    def _n_swizzle(self, c, t, o):
        x = c.i("in")
        chans = str(c.uniform("channels", "") or "")
        parts = []
        for ch in chans:
            parts.append(float(ch) if ch in "01" else self.lane(x, ("xyzw".index(ch) if ch in "xyzw"
                                                                    else "rgba".index(ch)) if ch in "xyzwrgba" else 0))
        return self.pack(t, parts or [0.0])

    # ---- geometry
    def _n_position(self, c, t, o):
        return self.geomprop("Pworld" if str(c.uniform("space", "object")) == "world" else "Pobject", t)

    def _n_normal(self, c, t, o):
        return self.geomprop("Nworld" if str(c.uniform("space", "object")) == "world" else "Nobject", t)

    def _n_tangent(self, c, t, o):
        return self.geomprop("Tworld", t)

    def _n_texcoord(self, c, t, o):
        k = int(c.uniform("index", 0) or 0)
        return self.cast(V("vector2", self.uvmap("" if k == 0 else f"st{k}")), t)

    def _n_geompropvalue(self, c, t, o):
        name = str(c.uniform("geomprop", "") or "")
        if t == "vector2":
            return V(t, self.uvmap(name))
        default = c.i("default")
        self.needs.color = (name, tuple(self.lanes3(default))) if not hasattr(default.x, "node") else \
            (name, (0.0, 0.0, 0.0))
        col = self.add("vertex_color", out="Color", layer_name=name)
        return self.cast(V("color3", col), t)

    def _n_geomcolor(self, c, t, o):
        self.needs.color = self.needs.color or ("displayColor", (1.0, 1.0, 1.0))
        return self.cast(V("color3", self.add("vertex_color", out="Color", layer_name="")), t)

    def _n_normalmap(self, c, t, o):
        if c.view.input("normal") is not None:
            self.warn(c.view.key + "n", f"MaterialX normalmap {c.view.name}: a connected normal is not supported "
                                        "(the shading normal is used)")
        x, s = c.i("in", "vector3"), c.i("scale")
        sxy = (s.x, s.x, 1.0) if s.wide == 1 and not hasattr(s.x, "node") else \
            (self.pack("vector3", [self.lane(s, 0), self.lane(s, 1 if s.wide > 1 else 0), 1.0]).x)
        tangent = self.vmath("MULTIPLY", self.vmath("MULTIPLY_ADD", self.lanes3(x), (2.0, 2.0, 2.0),
                                                    (-1.0, -1.0, -1.0)), sxy)
        colour = self.vmath("MULTIPLY_ADD", tangent, (0.5, 0.5, 0.5), (0.5, 0.5, 0.5))
        return V(t, self.add("normal_map", {"Color": colour, "Strength": 1.0}, "Normal", space="TANGENT"))

    def _n_bump(self, c, t, o):
        inputs = {"Height": c.f("height"), "Distance": c.f("scale"), "Strength": 1.0}
        if c.view.input("normal") is not None:
            inputs["Normal"] = self.lanes3(c.i("normal", "vector3"))
        return V(t, self.add("bump", inputs, "Normal"))


class _Ctx:
    """One node being translated: its inputs as values of their definition's types."""

    def __init__(self, tr: Translator, view, nd):
        self.tr, self.view, self.nd = tr, view, nd

    def has(self, name: str) -> bool:
        return self.nd.getActiveInput(name) is not None

    def uniform(self, name: str, default):
        """A uniform (string/integer) input's value: authored, else the definition's."""
        r, nd, key = self.view.input(name), self.nd, name
        while r is not None and r[0] == "outer":  # through node-graph interfaces (the outer node's definition)
            nd, key = mtlx.nodedef(r[1].sid) or nd, r[2]
            r = r[1].input(r[2])
        if r is not None and r[0] == "const":
            return r[1]
        d = nd.getActiveInput(key)
        return d.getValue() if d is not None and d.getValueString() else default

    def i(self, name: str, t: str | None = None) -> V:
        d = self.nd.getActiveInput(name)
        t = t or (d.getType() if d is not None else "float")
        r = self.view.input(name)
        if r is not None and r[0] == "link":
            return self.tr.cast(self.tr.out(r[1], r[2]), t)
        if r is not None and r[0] == "outer":
            outer = r[1]
            ond = mtlx.nodedef(outer.sid)
            return self.tr.cast(_Ctx(self.tr, outer, ond).i(r[2]), t) if ond is not None else self.tr.const(0.0, t)
        if r is not None and r[0] == "geomprop":  # a node graph's input with no value: its defaultgeomprop
            return self.tr.geomprop(r[1], t)
        if r is not None and r[0] == "const":
            if t in ("color3", "color4") and len(r) > 3 and r[3]:  # a colour in a named colour space
                return self.tr.const(mtlx.linear_colour(r[1], r[3], self.tr.unknown_space), t)
            return self.tr.const(r[1], t)
        if d is not None and d.getDefaultGeomPropString():
            return self.tr.geomprop(d.getDefaultGeomPropString(), t)
        if d is not None and d.getValueString():
            return self.tr.const(d.getValue(), t)
        return self.tr.const(0.0, t)

    def f(self, name: str):
        v = self.i(name)
        return v.x if v.wide == 1 else self.tr.lane(v, 0)


class _Varying(Exception):
    """A network being folded reads something that varies per hit (an image, a UV set)."""


class _FoldTable:
    """The material table as a network being folded sees it: no textures, no UV sets; a warning (a node read as
    its default, an unknown colour space) stops the folding, so that the network is translated again with it."""

    def __init__(self, table):
        self.time = table.time
        self.warned = False

    def warn(self, message: str) -> None:
        self.warned = True

    def uv_set_index(self, name):
        raise _Varying

    @property
    def uv_set_names(self):
        raise _Varying

    def _texture(self, *args, **kw):
        raise _Varying


class _NoNeeds:
    def __init__(self):
        self.uv_sets: set = set()
        self.color = None


def constant_value(table, lookup):
    """The value of the network ``lookup`` (a :class:`usd_io.materials.network.GraphLookup`) when it varies nowhere
    — constants, and maths, conversions and switches of constants — folded by the shader compiler exactly as the
    tracer would evaluate it (a float or a tuple); None when anything in it varies per hit (a texture coordinate, a
    position, an image, a noise)."""
    g = Graph("fold")
    quiet = _FoldTable(table)
    tr = Translator(quiet, g, "", _NoNeeds(), table.time)
    try:
        v = tr.out(UsdNode(lookup.shader, table.time), lookup.output)
    except _Varying:
        return None
    except Exception:  # noqa: BLE001 — whatever the translator cannot fold is translated as a network
        return None
    if quiet.warned:
        return None
    if v.wide == 1 and not isinstance(v.x, Out) and not hasattr(v.x, "node"):
        return float(v.x)
    if v.wide > 1 and not isinstance(v.x, Out) and not hasattr(v.x, "node"):
        return tuple(float(x) for x in v.x)
    c = Compiler(g)
    try:
        x = c.val(v.x, FLOAT if v.wide == 1 else VECTOR)
    except Exception:  # noqa: BLE001
        return None
    if not c.e.is_const(x):
        return None
    if hasattr(x, "r") and hasattr(x, "n"):  # a register of constants
        vals = [float(c.e.init[k]) for k in range(x.r, x.r + x.n)]
    else:
        vals = [float(e) for e in np.ravel(x)]
    return vals[0] if v.wide == 1 else tuple(vals[:3])


class MxProgram:
    """A MaterialX network driving one surface input (:class:`usd_io.materials.network.GraphLookup`), written into
    the material's graph when :meth:`tracer.shading.principled.PrincipledSurface.graph` writes it (as one of its lookups:
    ``write(g, translators) -> (outputs, UV map name)``). ``translators`` is the writer's, one per graph: the
    networks of one material share one :class:`Translator` (nodes written once), and nothing is kept on the
    Graph."""

    def __init__(self, table, lookup, label: str, name: str, needs):
        self.table, self.lookup, self.label, self.name, self.needs = table, lookup, label, name, needs

    @property
    def label_text(self) -> str:
        return f"MaterialX {self.lookup.node}"

    def __repr__(self):
        return self.label_text

    def translator(self, g, translators: dict) -> Translator:
        key = id(self.table)
        if key not in translators:
            translators[key] = Translator(self.table, g, self.label, self.needs, self.table.time)
        return translators[key]

    def value(self, g, translators: dict) -> V:
        tr = self.translator(g, translators)
        v = tr.out(UsdNode(self.lookup.shader, self.table.time), self.lookup.output)
        k = np.broadcast_to(np.asarray(self.lookup.scale, np.float64), (3,))  # a weight, or an RGB factor
        if not np.allclose(k, 1.0):
            if v.wide == 3:
                v = V(v.t, tr.vmath("MULTIPLY", v.x, tuple(float(x) for x in k)))
            else:
                v = tr._lanewise(v.t, "MULTIPLY", v, V("float", float(k.mean())))
        return v

    def write(self, g, translators: dict):
        return Outs(self.translator(g, translators), self.value(g, translators)), ""

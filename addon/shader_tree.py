"""Blender shader node trees -> the tracer's shader graph IR (:mod:`tracer.shading.graph`), with Cycles' semantics.

    graph = material_graph(material, warn, images)      # the evaluated material (from the depsgraph)

What Cycles' own export does before its ``ShaderGraph::simplify``, this module does once per material:

- **The active Material Output** for Cycles (``NodeTree.get_output_node("CYCLES")``: target All or Cycles).
- **Node groups** are inlined to any depth: a Group Output socket is followed into the group's active Group Output
  node, a Group Input socket out to the group node's input (its value on the group node where unlinked). A value
  crossing a group boundary is converted to the interface socket's type, as Cycles' proxy nodes convert it.
- **Reroutes** are followed; **muted nodes** are Blender's pass-through (``Node.internal_links``: the output reads
  the input linked to it, else the socket it feeds keeps its own value); **muted and invalid links** are absent;
  **frames** are layout only.
- A colour or float linked into a shader socket becomes an Emission of strength 1 (Cycles' implicit conversion).
- Every node maps to IR nodes of the same meaning (:data:`HANDLERS`); a few are written as small IR sub-graphs
  (Light Falloff, Camera Data, Normal, Texture Coordinate from another object). Curves are baked from
  ``CurveMapping.evaluate`` into the 256-sample tables Cycles bakes; a Color Ramp keeps its stops, interpolation and
  colour modes (the tracer builds Blender's ramp table from them).
- Anything else: **one warning per material naming the node**, and Blender's mute pass-through as the stand-in
  (the output reads the input Blender would pass through, else the receiving socket's own value); an unsupported
  shader stands in as a Diffuse BSDF of its colour. docs/addon.md lists every node and its stand-in.

Images are shared per export (``images``: image name -> (H, W, 4) linear pixels, the decoding of
:func:`addon.nodes.image_rgba`), each wrapped once per Extension in an :class:`~tracer.shading.graph.ImageRef`.
"""

from __future__ import annotations

import numpy as np

from .bundled import tracer_module
from .nodes import _read_rgba as read_rgba
from .nodes import image_rgba
from .udim import tile_pixels, tiled_atlas

_ir = tracer_module("shading.graph")
CLOSURE, COLOR, FLOAT, NODE_TYPES, VECTOR = _ir.CLOSURE, _ir.COLOR, _ir.FLOAT, _ir.NODE_TYPES, _ir.VECTOR
Graph, ImageRef, Out, constant_material = _ir.Graph, _ir.ImageRef, _ir.Out, _ir.constant_material
#: A constant of one socket kind as another (Blender's implicit conversions; the tracer's one rule).
convert_constant = _ir.convert_constant

#: Blender socket type -> IR kind (None: a socket type no shader program carries).
KIND = {"VALUE": FLOAT, "INT": FLOAT, "BOOLEAN": FLOAT, "VECTOR": VECTOR, "RGBA": COLOR, "SHADER": CLOSURE}
#: Samples of a baked curve or ramp table (Cycles' RAMP_TABLE_SIZE).
TABLE_SIZE = 256
#: Blender's Extension -> ImageRef wrap.
WRAP = {"REPEAT": "repeat", "EXTEND": "clamp", "CLIP": "black", "MIRROR": "mirror"}


class Value:
    """A resolved socket value: ``v`` is an IR link (:class:`Out`) or a constant (float / 3-tuple) of ``kind``."""

    __slots__ = ("v", "kind")

    def __init__(self, v, kind):
        self.v, self.kind = v, kind

    @property
    def linked(self) -> bool:
        return isinstance(self.v, Out)


#: "Nothing arrives": the receiving socket keeps its own value (its default, or the IR's implicit input).
UNSET = None


def socket_constant(sock):
    """The constant of an unlinked Blender socket (colours without alpha), or None for a socket without one."""
    if not hasattr(sock, "default_value"):
        return None
    v = sock.default_value
    try:
        t = tuple(float(x) for x in v)
    except TypeError:
        return float(v)
    return (t + (0.0, 0.0, 0.0))[:3]


class Translator:
    """Translates one Blender node tree into one :class:`Graph`; warns at most once per node."""

    def __init__(self, label: str, warn, images: dict | None = None):
        self.label = label
        self.g = Graph(label)
        self._warn = warn
        self._said: set = set()
        self.images = images if images is not None else {}
        self._memo: dict = {}
        self._refs: dict = {}  # (image name, wrap, interpolation) -> ImageRef
        self._active: list = []  # (context, node) being translated (cycles are broken, not followed)

    def warn(self, node, message: str, key: str = "") -> None:
        k = (getattr(node, "name", str(node)), key)
        if k not in self._said:
            self._said.add(k)
            self._warn(f"{self.label}: {message}")

    # ------------------------------------------------------------------ sockets
    def input(self, sock, ctx: tuple, boundary: bool = False) -> Value | None:
        """The value arriving at Blender input ``sock`` in group context ``ctx`` (the group nodes entered, outer
        first); UNSET when nothing arrives and the socket's value is implicit (hidden: a texture's Vector, a
        Normal). ``boundary``: a group node's input, whose unlinked value is its constant even where hidden."""
        link = next((lk for lk in sock.links if lk.is_valid and not lk.is_muted
                     and getattr(lk.from_socket, "enabled", True)), None) if sock.is_linked else None
        if link is not None:
            v = self.output(link.from_node, link.from_socket, ctx)
            if v is not UNSET:
                return v
        kind = KIND.get(sock.type)
        if kind is None or kind == CLOSURE:
            return UNSET
        if getattr(sock, "hide_value", False) and not boundary:
            return UNSET
        c = socket_constant(sock)
        return UNSET if c is None else Value(c, kind)

    def output(self, node, sock, ctx: tuple) -> Value | None:
        """The value of Blender output ``sock`` of ``node`` in context ``ctx``."""
        kind = KIND.get(sock.type)
        if node.bl_idname == "NodeReroute":
            return self.input(node.inputs[0], ctx)
        if node.mute:
            return self.passthrough(node, sock, ctx)
        if node.bl_idname == "NodeGroupInput":
            if not ctx:
                return UNSET
            group = ctx[-1]
            outer = next((s for s in group.inputs if s.identifier == sock.identifier), None)
            return UNSET if outer is None else self.coerce(self.input(outer, ctx[:-1], boundary=True), kind)
        if node.bl_idname == "ShaderNodeGroup":
            return self.group_output(node, sock, ctx)
        key = (tuple(n.as_pointer() for n in ctx), node.as_pointer())
        if key in self._active:
            self.warn(node, f"node {node.name!r} feeds itself (a cycle); the link is dropped", "cycle")
            return UNSET
        if key not in self._memo:
            self._active.append(key)
            try:
                self._memo[key] = self.translate(node, ctx)
            finally:
                self._active.pop()
        outs = self._memo[key]
        v = outs.get(sock.identifier, outs.get(sock.name, UNSET))
        return v

    def passthrough(self, node, sock, ctx: tuple) -> Value | None:
        """Blender's mute behaviour: the input an internal link joins to ``sock``, converted to its type."""
        for il in node.internal_links:
            if il.to_socket.identifier == sock.identifier:
                return self.coerce(self.input(il.from_socket, ctx, boundary=True), KIND.get(sock.type))
        return UNSET

    def group_output(self, node, sock, ctx: tuple) -> Value | None:
        tree = node.node_tree
        if tree is None:
            self.warn(node, f"group node {node.name!r} has no node tree; its outputs keep the sockets' values")
            return UNSET
        outs = [n for n in tree.nodes if n.bl_idname == "NodeGroupOutput"]
        out = next((n for n in outs if n.is_active_output), outs[0] if outs else None)
        if out is None:
            return UNSET
        inner = next((s for s in out.inputs if s.identifier == sock.identifier), None)
        if inner is None:
            return UNSET
        return self.coerce(self.input(inner, ctx + (node,), boundary=True), KIND.get(sock.type))

    def coerce(self, v: Value | None, kind: str | None) -> Value | None:
        """``v`` converted to ``kind`` where a group boundary / muted node changes the type (constants at once, links
        through an identity node of the new kind so that the IR's link conversion applies there)."""
        if v is UNSET or kind is None or v.kind == kind or kind == CLOSURE or v.kind == CLOSURE:
            return v
        if not v.linked:
            return Value(convert_constant(v.v, v.kind, kind), kind)
        if kind == FLOAT:
            n = self.g.add("math", {"Value": v.v, "Value_001": 0.0}, operation="ADD")
            return Value(n["Value"], FLOAT)
        if kind == VECTOR:
            n = self.g.add("vector_math", {"Vector": v.v, "Vector_001": (0.0, 0.0, 0.0)}, operation="ADD")
            return Value(n["Vector"], VECTOR)
        n = self.g.add("mix_color", {"Factor": 0.0, "A": v.v}, blend_type="MIX")
        return Value(n["Result"], COLOR)

    # ------------------------------------------------------------------ nodes
    def translate(self, node, ctx: tuple) -> dict:
        """{Blender output identifier: Value} of one node."""
        fn = HANDLERS.get(node.bl_idname)
        if fn is None:
            return self.unsupported(node, ctx)
        return fn(self, node, ctx)

    def name(self, node, ctx) -> str:
        return "/".join([n.name for n in ctx] + [node.name])

    def add(self, node, ctx, ir_type: str, sockets: dict | None = None, outputs: dict | None = None,
            **params) -> dict:
        """An IR node of ``ir_type`` for Blender ``node``: each enabled Blender input whose identifier (or
        ``sockets[identifier]``) names an IR input is resolved and set; returns {Blender output identifier: Value}
        for the outputs whose identifier (or ``outputs[identifier]``) the IR node has."""
        nt = NODE_TYPES[ir_type]
        sockets = sockets or {}
        inputs = {}
        for s in node.inputs:
            if not getattr(s, "enabled", True):
                continue
            target = sockets.get(s.identifier, s.identifier)
            isock = nt.input(target) if target else None
            if isock is None:
                continue
            v = self.input(s, ctx)
            if v is UNSET:
                continue
            inputs[target] = self.to_ir(v, isock.kind, node, s)
        n = self.g.add(ir_type, {k: v for k, v in inputs.items() if v is not UNSET}, name=self.name(node, ctx),
                       **params)
        return self.outs(node, n, outputs)

    def to_ir(self, v: Value, kind: str, node, sock):
        """What an IR input of ``kind`` receives from ``v``: a link (the IR converts kinds), a constant of its kind,
        or an Emission closure for a value linked into a shader socket."""
        if kind == CLOSURE:
            if v.kind == CLOSURE:
                return v.v
            e = self.g.add("emission", {"Color": v.v if v.linked else convert_constant(v.v, v.kind, COLOR),
                                        "Strength": 1.0})
            return e["Emission"]
        if v.kind == CLOSURE:
            return UNSET
        return v.v if v.linked else convert_constant(v.v, v.kind, kind)

    def outs(self, node, n, outputs: dict | None = None) -> dict:
        nt = NODE_TYPES[n.type]
        outputs = outputs or {}
        res = {}
        for s in node.outputs:
            target = outputs.get(s.identifier, s.identifier)
            osock = nt.output(target) if target else None
            if osock is not None:
                res[s.identifier] = Value(n[target], osock.kind)
        return res

    def value_of(self, node, ctx, identifier: str, kind: str) -> Value | None:
        """The value at ``node``'s input ``identifier`` as ``kind`` (a constant or link), UNSET if none arrives."""
        s = next((s for s in node.inputs if s.identifier == identifier), None)
        return UNSET if s is None else self.coerce(self.input(s, ctx), kind)

    def unsupported(self, node, ctx) -> dict:
        """One warning; Blender's mute pass-through for every output (a shader: Diffuse of its colour)."""
        res = {}
        closure = [s for s in node.outputs if s.type == "SHADER"]
        if closure:
            col = self.value_of(node, ctx, "Color", COLOR) or self.value_of(node, ctx, "Base Color", COLOR)
            col = col or Value((0.8, 0.8, 0.8), COLOR)
            self.warn(node, f"shader {node.name!r} ({node.bl_idname}) is not supported; a Diffuse BSDF of its "
                            "colour stands in")
            d = self.g.add("diffuse_bsdf", {"Color": col.v}, name=self.name(node, ctx))
            for s in closure:
                res[s.identifier] = Value(d["BSDF"], CLOSURE)
            return res
        self.warn(node, f"node {node.name!r} ({node.bl_idname}) is not supported; its outputs pass through "
                        "as Blender's muted node (else the receiving sockets keep their values)")
        for s in node.outputs:
            v = self.passthrough(node, s, ctx)
            if v is not UNSET:
                res[s.identifier] = v
        return res

    # ------------------------------------------------------------------ images
    def image_ref(self, node, image, extension: str = "REPEAT", interpolation: str = "Linear"):
        if image is None:
            return None
        if image.name not in self.images:
            try:
                self.images[image.name] = image_rgba(image)
            except Exception as exc:  # missing file, unreadable pixels
                self.images[image.name] = None
                self.warn(node, f"image {image.name!r} not loaded ({exc}); magenta stands in, as in Cycles",
                          "load")
        px = self.images[image.name]
        if px is None:
            return None
        source = getattr(image, "source", "FILE")
        if source in ("SEQUENCE", "MOVIE"):
            self.warn(node, f"image {image.name!r} ({source}): its first frame is used", "source")
        elif source == "TILED":  # a projection (Box, Sphere, Tube; a world's) reads uv in [0, 1]: tile 1001
            first = min((int(t.number) for t in image.tiles), default=1001)
            if first != 1001:
                self.warn(node, f"image {image.name!r} (TILED): this projection reads only tile 1001's square, "
                                f"which the set lacks; its first tile ({first}) is used", "source")
        wrap = WRAP.get(extension, "repeat")
        key = (image.name, wrap, interpolation)
        if key not in self._refs:
            self._refs[key] = ImageRef(pixels=px, wrap_s=wrap, wrap_t=wrap, interpolation=interpolation.lower(),
                                       label=image.name)
        return self._refs[key]

    def tiled_ref(self, node, image, extension: str = "REPEAT", interpolation: str = "Linear"):
        """(ImageRef of the atlas of a tiled image's tiles (clamped), the coefficients of the tile set -> atlas map
        (:func:`tracer.shading.udim.udim_atlas_padded`)), or None when no tile could be read (one warning; magenta
        stands in). :mod:`addon.udim` reads the tiles (once per image) and lays them out (once per Extension)."""
        key = ("udim", image.name)
        if key not in self.images:
            try:
                tiles, notes = tile_pixels(image, read_rgba)
                if not tiles:
                    raise ValueError(f"none of its tiles could be read ({'; '.join(notes) or 'no tiles'})")
            except Exception as exc:  # noqa: BLE001  (no tile readable)
                self.images[key] = None
                self.warn(node, f"tiled image {image.name!r} not loaded ({exc}); magenta stands in, as in Cycles",
                          "load")
            else:
                self.images[key] = tiles
                for n in notes:
                    self.warn(node, f"tiled image {image.name!r}: {n}", n)
        if self.images[key] is None:
            return None
        wrap = WRAP.get(extension, "repeat")
        smooth = interpolation != "Closest"
        akey = ("udim", image.name, wrap, smooth)
        if akey not in self.images:
            atlas, coeffs, notes = tiled_atlas(self.images[key], wrap, smooth)
            self.images[akey] = (atlas, coeffs)
            for n in notes:
                self.warn(node, f"tiled image {image.name!r}: {n}", n)
        atlas, coeffs = self.images[akey]
        rkey = (akey, interpolation)
        if rkey not in self._refs:
            self._refs[rkey] = ImageRef(pixels=atlas, wrap_s="clamp", wrap_t="clamp",
                                        interpolation=interpolation.lower(), label=image.name)
        return self._refs[rkey], coeffs


# ---------------------------------------------------------------------------------------------- node handlers
def _simple(ir_type, sockets=None, outputs=None, params=()):
    """A handler for a node that maps one to one (enum/bool properties ``params`` copied by name)."""
    def handler(t: Translator, node, ctx):
        return t.add(node, ctx, ir_type, sockets, outputs, **{p: getattr(node, p) for p in params})
    return handler


_PRINCIPLED_IGNORED = {"Diffuse Roughness": 0.0, "Thin Film Thickness": 0.0}


def _principled(t: Translator, node, ctx):
    for name, neutral in _PRINCIPLED_IGNORED.items():
        s = node.inputs.get(name)
        if s is not None and (s.is_linked or abs(float(s.default_value) - neutral) > 1e-6):
            t.warn(node, f"Principled BSDF {node.name!r}: {name} is not supported (ignored)", name)
    return t.add(node, ctx, "principled_bsdf")


def _bsdf(ir_type, distribution=False):
    def handler(t: Translator, node, ctx):
        params = {}
        if distribution:
            d = node.distribution
            params["distribution"] = d if d in ("MULTI_GGX", "GGX", "BECKMANN", "ASHIKHMIN_SHIRLEY") else "GGX"
        return t.add(node, ctx, ir_type, **params)
    return handler


def _sheen(t: Translator, node, ctx):
    """Sheen BSDF (Blender 4+; Velvet before): microfiber or Ashikhmin, as Cycles (tracer.sheen)."""
    d = getattr(node, "distribution", "MICROFIBER")
    return t.add(node, ctx, "sheen_bsdf", distribution=d if d in ("MICROFIBER", "ASHIKHMIN") else "MICROFIBER")


def _subsurface(t: Translator, node, ctx):
    """Subsurface Scattering: a Diffuse BSDF of its Color (Cycles' picture at Whitted-limited paths is within a few
    per cent of it: the light that travels under the surface is what a Whitted tracer lacks; one warning)."""
    t.warn(node, f"Subsurface Scattering {node.name!r} is rendered as diffuse reflection of its Color (the "
                 "scattering radius is not modelled)")
    return t.add(node, ctx, "diffuse_bsdf", {"Scale": None, "Radius": None, "IOR": None, "Roughness": None,
                                             "Anisotropy": None}, {"BSSRDF": "BSDF"})


def _volume_shader(t: Translator, node, ctx):
    """A volume shader (Absorption, Scatter, Principled Volume) reached from a Surface socket: Cycles evaluates
    nothing of it there (a volume closure has no surface part); the Volume output is addon/volume.py's."""
    return {}


def _value(t, node, ctx):
    return {node.outputs[0].identifier: Value(float(node.outputs[0].default_value), FLOAT)}


def _rgb(t, node, ctx):
    return {node.outputs[0].identifier: Value(socket_constant(node.outputs[0]), COLOR)}


def _texcoord(t: Translator, node, ctx):
    if getattr(node, "from_instancer", False):
        t.warn(node, f"Texture Coordinate {node.name!r}: From Instancer is not supported (the instance's own "
                     "coordinates are used)", "instancer")
    res = t.add(node, ctx, "texture_coordinate")
    ob = node.object
    if ob is not None:  # Object output in another object's space: Mapping (Texture) of the world position
        loc, rot, scale = ob.matrix_world.decompose()
        geo = t.g.add("geometry", name=t.name(node, ctx) + ".position")
        m = t.g.add("mapping", {"Vector": geo["Position"], "Location": tuple(loc),
                                "Rotation": tuple(rot.to_euler("XYZ")), "Scale": tuple(scale)},
                    name=t.name(node, ctx) + ".object", vector_type="TEXTURE")
        res["Object"] = Value(m["Vector"], VECTOR)
    return res


def _geometry(t, node, ctx):
    for s in node.outputs:
        if s.is_linked and s.identifier in ("Pointiness", "Random Per Island"):
            t.warn(node, f"Geometry {node.name!r}: {s.identifier} is not available; "
                         f"{0.5 if s.identifier == 'Pointiness' else 0.0} stands in", s.identifier)
    res = t.add(node, ctx, "geometry")
    res["Pointiness"] = Value(0.5, FLOAT)  # a flat surface's pointiness
    res["Random Per Island"] = Value(0.0, FLOAT)
    return res


def _light_path(t, node, ctx):
    res = t.add(node, ctx, "light_path")
    res.setdefault("Is Volume Scatter Ray", Value(0.0, FLOAT))
    res.setdefault("Portal Depth", Value(0.0, FLOAT))
    return res


#: UV-set names that carry a colour attribute's alpha (the tracer keeps RGB per corner): ALPHA_UV + kind + ":" +
#: attribute name, kind "vc" (Color Attribute node: a missing attribute's alpha is 0) or "attr" (Attribute node:
#: 1). addon/model.py fills these sets with (alpha, 0) per corner from the mesh.
ALPHA_UV = "\u241fwhitted-alpha:"


def alpha_uv_name(kind: str, attribute: str) -> str:
    return f"{ALPHA_UV}{kind}:{attribute}"


def _alpha_output(t: Translator, node, ctx, kind: str, attribute: str) -> Value:
    """A colour attribute's alpha, read through its pseudo UV set (:data:`ALPHA_UV`)."""
    uv = t.g.add("uvmap", attribute=alpha_uv_name(kind, attribute), name=t.name(node, ctx) + ".alpha_uv")
    x = t.g.add("separate_xyz", {"Vector": uv["UV"]}, name=t.name(node, ctx) + ".alpha")
    return Value(x["X"], FLOAT)


def _attribute(t, node, ctx):
    if node.attribute_type != "GEOMETRY":
        t.warn(node, f"Attribute {node.name!r}: {node.attribute_type} attributes are not supported; white stands "
                     "in", "type")
        return {"Color": Value((1.0, 1.0, 1.0), COLOR), "Vector": Value((1.0, 1.0, 1.0), VECTOR),
                "Fac": Value(1.0, FLOAT), "Alpha": Value(1.0, FLOAT)}
    res = t.add(node, ctx, "attribute", attribute=node.attribute_name, attribute_type="GEOMETRY")
    if node.outputs["Alpha"].is_linked:
        res["Alpha"] = _alpha_output(t, node, ctx, "attr", node.attribute_name)
    return res


def _vertex_color(t, node, ctx):
    """Color Attribute: its colour per corner, and its alpha (0 where the mesh lacks it, as Cycles)."""
    res = t.add(node, ctx, "vertex_color", layer_name=node.layer_name)
    if node.outputs["Alpha"].is_linked:
        res["Alpha"] = _alpha_output(t, node, ctx, "vc", node.layer_name)
    return res


def _uvmap(t, node, ctx):
    if getattr(node, "from_instancer", False):
        t.warn(node, f"UV Map {node.name!r}: From Instancer is not supported", "instancer")
    return t.add(node, ctx, "uvmap", attribute=node.uv_map)


def _tangent(t, node, ctx):
    return t.add(node, ctx, "tangent", direction_type=node.direction_type, uv_map=node.uv_map, axis=node.axis)


def _ambient_occlusion(t, node, ctx):
    t.warn(node, f"Ambient Occlusion {node.name!r} is not evaluated by a Whitted tracer; AO = 1 and its colour "
                 "passes through")
    col = t.value_of(node, ctx, "Color", COLOR) or Value((1.0, 1.0, 1.0), COLOR)
    return {"Color": col, "AO": Value(1.0, FLOAT)}


def _wireframe(t, node, ctx):
    t.warn(node, f"Wireframe {node.name!r} is not supported; 0 (no edge) stands in")
    return {"Fac": Value(0.0, FLOAT)}


def _bevel(t, node, ctx):
    t.warn(node, f"Bevel {node.name!r} is not supported; its Normal input passes through")
    n = t.value_of(node, ctx, "Normal", VECTOR)
    if n is UNSET:
        n = Value(t.g.add("geometry", name=t.name(node, ctx))["Normal"], VECTOR)
    return {"Normal": n}


def _camera_data(t, node, ctx):
    """View Vector = normalize(P in camera space), View Z Depth = its z, View Distance = its length (Cycles'
    svm_node_camera), from the Camera texture coordinates."""
    nm = t.name(node, ctx)
    cam = t.g.add("texture_coordinate", name=nm + ".camera")["Camera"]
    norm = t.g.add("vector_math", {"Vector": cam}, name=nm + ".view_vector", operation="NORMALIZE")
    length = t.g.add("vector_math", {"Vector": cam}, name=nm + ".distance", operation="LENGTH")
    z = t.g.add("separate_xyz", {"Vector": cam}, name=nm + ".z")
    return {"View Vector": Value(norm["Vector"], VECTOR), "View Z Depth": Value(z["Z"], FLOAT),
            "View Distance": Value(length["Value"], FLOAT)}


def _normal(t, node, ctx):
    """Normal node: its direction (the output's own value, normalised) and Dot = direction · normalize(input)."""
    d = np.asarray(socket_constant(node.outputs["Normal"]), np.float64)
    d = tuple(float(x) for x in (d / np.linalg.norm(d) if np.linalg.norm(d) > 0 else d))
    nin = t.value_of(node, ctx, "Normal", VECTOR) or Value((0.0, 0.0, 1.0), VECTOR)
    nm = t.name(node, ctx)
    unit = t.g.add("vector_math", {"Vector": nin.v}, name=nm + ".in", operation="NORMALIZE")
    dot = t.g.add("vector_math", {"Vector": unit["Vector"], "Vector_001": d}, name=nm + ".dot",
                  operation="DOT_PRODUCT")
    return {"Normal": Value(d, VECTOR), "Dot": Value(dot["Value"], FLOAT)}


def _light_falloff(t, node, ctx):
    """Cycles' svm_node_light_falloff on a surface: Quadratic = S, Linear = S·L, Constant = S·L², each times
    L² / (smooth + L²) when Smooth > 0 (L = the ray's length)."""
    nm = t.name(node, ctx)
    s = t.value_of(node, ctx, "Strength", FLOAT) or Value(100.0, FLOAT)
    smooth = t.value_of(node, ctx, "Smooth", FLOAT) or Value(0.0, FLOAT)
    length = t.g.add("light_path", name=nm + ".path")["Ray Length"]

    def mul(a, b, tag):
        return t.g.add("math", {"Value": a, "Value_001": b}, name=nm + tag, operation="MULTIPLY")["Value"]
    l2 = mul(length, length, ".l2")
    strength = s.v
    if smooth.linked or float(smooth.v) > 0.0:
        den = t.g.add("math", {"Value": smooth.v, "Value_001": l2}, name=nm + ".den", operation="ADD")["Value"]
        f = t.g.add("math", {"Value": l2, "Value_001": den}, name=nm + ".smooth", operation="DIVIDE")["Value"]
        strength = mul(strength, f, ".s")
    return {"Quadratic": Value(strength, FLOAT) if isinstance(strength, Out) else Value(float(strength), FLOAT),
            "Linear": Value(mul(strength, length, ".linear"), FLOAT),
            "Constant": Value(mul(strength, l2, ".constant"), FLOAT)}


#: What Cycles renders for an image it cannot read (TEX_IMAGE_MISSING_R/G/B/A): magenta, alpha 1.
MISSING_IMAGE = (1.0, 0.0, 1.0)


def _image(t: Translator, node, ctx):
    img = node.image
    if img is not None and getattr(img, "source", "FILE") == "TILED" and node.projection == "FLAT":
        return _tiled_image(t, node, ctx)
    ref = t.image_ref(node, node.image, node.extension, node.interpolation)
    if ref is None:
        if node.image is None:
            t.warn(node, f"Image Texture {node.name!r} has no image; magenta stands in, as in Cycles", "none")
        return {"Color": Value(MISSING_IMAGE, COLOR), "Alpha": Value(1.0, FLOAT)}
    return t.add(node, ctx, "image_texture", image=ref, projection=node.projection,
                 projection_blend=float(node.projection_blend), interpolation=node.interpolation,
                 extension=node.extension)


def _tiled_image(t: Translator, node, ctx):
    """An Image Texture of a tiled (UDIM) image, Flat projection, as Cycles reads it (kernel_image_udim_map: the
    tile ⌊u⌋ + 10·⌊v⌋, read at the fraction with the node's Extension; outside the set, magenta): the padded atlas
    of :func:`tracer.shading.udim.udim_atlas_padded` read at its map of the Vector (the UV map where unlinked),
    five Vector Math nodes: i = min(⌊max(X, 0)⌋, (U, V)), then X·a + (i·b + c). (Cycles truncates: uv in (−1, 0)
    reads tile 1001 wrapped where this reads its border and then magenta.)"""
    got = t.tiled_ref(node, node.image, node.extension, node.interpolation)
    if got is None:
        return {"Color": Value(MISSING_IMAGE, COLOR), "Alpha": Value(1.0, FLOAT)}
    ref, k = got
    nm = t.name(node, ctx)
    v = t.value_of(node, ctx, "Vector", VECTOR)
    if v is UNSET:
        v = Value(t.g.add("uvmap", name=nm + ".uv")["UV"], VECTOR)

    def vmath(op, a, b, c=None, tag=""):
        inputs = {"Vector": a, "Vector_001": b}
        if c is not None:
            inputs["Vector_002"] = c
        return t.g.add("vector_math", inputs, name=nm + ".udim_" + tag, operation=op)["Vector"]
    (n_u, n_v), (a_s, a_t), (b_s, b_t), (c_s, c_t) = k["tiles"], k["scale"], k["tile"], k["offset"]
    i = vmath("MAXIMUM", v.v, (0.0, 0.0, 0.0), tag="max")
    i = vmath("FLOOR", i, (0.0, 0.0, 0.0), tag="floor")
    i = vmath("MINIMUM", i, (float(n_u), float(n_v), 0.0), tag="min")
    r = vmath("MULTIPLY_ADD", i, (b_s, b_t, 0.0), (c_s, c_t, 0.0), tag="tile")
    # (the constant first: the lookup then carries no UV set and reads level 0, plain bilinear as Cycles' images;
    # a UV set's texel density would price the whole atlas, and a coarser level blends the cells' borders)
    st = vmath("MULTIPLY_ADD", (a_s, a_t, 0.0), v.v, r, tag="st")
    n = t.g.add("image_texture", {"Vector": st}, name=nm, image=ref, projection="FLAT",
                projection_blend=float(node.projection_blend), interpolation=node.interpolation,
                extension="EXTEND")
    return t.outs(node, n)


def _environment(t: Translator, node, ctx):
    ref = t.image_ref(node, node.image, "REPEAT", node.interpolation)
    if ref is None:
        if node.image is None:
            t.warn(node, f"Environment Texture {node.name!r} has no image; magenta stands in, as in Cycles", "none")
        return {"Color": Value(MISSING_IMAGE, COLOR), "Alpha": Value(1.0, FLOAT)}
    return t.add(node, ctx, "environment_texture", image=ref, projection=node.projection,
                 interpolation=node.interpolation)


def _background(t: Translator, node, ctx):
    """A world's surface: its colour × strength is what rays that leave the scene see (an emission closure)."""
    return t.add(node, ctx, "emission", outputs={"Background": "Emission"})


def _mix(t: Translator, node, ctx):
    dt = node.data_type
    if dt == "FLOAT":
        return t.add(node, ctx, "mix_float", {"Factor_Float": "Factor", "A_Float": "A", "B_Float": "B"},
                     {"Result_Float": "Result"}, use_clamp=bool(node.clamp_factor))
    if dt == "VECTOR":
        if node.factor_mode == "NON_UNIFORM":
            return t.add(node, ctx, "mix_vector_non_uniform",
                         {"Factor_Vector": "Factor", "A_Vector": "A", "B_Vector": "B"},
                         {"Result_Vector": "Result"}, use_clamp=bool(node.clamp_factor))
        return t.add(node, ctx, "mix_vector", {"Factor_Float": "Factor", "A_Vector": "A", "B_Vector": "B"},
                     {"Result_Vector": "Result"}, use_clamp=bool(node.clamp_factor))
    if dt == "RGBA":
        return t.add(node, ctx, "mix_color", {"Factor_Float": "Factor", "A_Color": "A", "B_Color": "B"},
                     {"Result_Color": "Result"}, blend_type=node.blend_type, use_clamp=bool(node.clamp_factor),
                     use_clamp_result=bool(node.clamp_result))
    return t.unsupported(node, ctx)


def _mix_rgb(t, node, ctx):
    """The legacy MixRGB node: its factor is always clamped (Cycles' svm_mix), Clamp clamps the result."""
    return t.add(node, ctx, "mix_color", {"Fac": "Factor", "Color1": "A", "Color2": "B"}, {"Color": "Result"},
                 blend_type=node.blend_type, use_clamp=True, use_clamp_result=bool(node.use_clamp))


def curve_table(mapping, curves: int, *, combined: bool = False) -> tuple[np.ndarray, tuple]:
    """((TABLE_SIZE, k) samples, (x_min, x_max)) of a CurveMapping as Cycles bakes it (blender/shader.cpp,
    curvemapping_*_to_array): the range spans [0, 1] and every curve's first and last point; RGB Curves
    (``combined``) sample each channel after the combined curve, R(C(x)), and get an identity column 0 in front
    (the VM applies column 0 after the channel's)."""
    mapping.initialize()
    lo, hi = 0.0, 1.0
    n = 4 if combined else curves
    for i in range(n):
        pts = mapping.curves[i].points
        lo, hi = min(lo, pts[0].location[0]), max(hi, pts[-1].location[0])
    xs = lo + (hi - lo) * np.arange(TABLE_SIZE) / (TABLE_SIZE - 1)
    cols = []
    if combined:
        c = mapping.curves[3]
        inner = [mapping.evaluate(c, float(x)) for x in xs]
        cols.append(xs)
        for i in range(3):
            cols.append([mapping.evaluate(mapping.curves[i], y) for y in inner])
    else:
        for i in range(curves):
            cols.append([mapping.evaluate(mapping.curves[i], float(x)) for x in xs])
    return np.asarray(cols, np.float64).T.copy(), (float(lo), float(hi))


def _curves(ir_type, curves, combined=False):
    def handler(t: Translator, node, ctx):
        table, rng = curve_table(node.mapping, curves, combined=combined)
        return t.add(node, ctx, ir_type, curves=table, range=rng)  # range: the table's x range
    return handler


def _color_ramp(t, node, ctx):
    """Color Ramp: its stops, interpolation, colour mode and hue interpolation (the tracer builds Blender's table
    from them, as Cycles does)."""
    cr = node.color_ramp
    stops = [(float(e.position), tuple(float(x) for x in e.color)) for e in cr.elements]
    return t.add(node, ctx, "rgb_ramp", ramp=stops, interpolation=cr.interpolation, color_mode=cr.color_mode,
                 hue_interpolation=cr.hue_interpolation)


def _map_range(t, node, ctx):
    if node.data_type == "FLOAT_VECTOR":
        return t.add(node, ctx, "vector_map_range",
                     {"Vector": "Vector", "From_Min_FLOAT3": "From Min", "From_Max_FLOAT3": "From Max",
                      "To_Min_FLOAT3": "To Min", "To_Max_FLOAT3": "To Max", "Steps_FLOAT3": "Steps",
                      "Value": None, "From Min": None, "From Max": None, "To Min": None, "To Max": None,
                      "Steps": None},
                     {"Vector": "Vector", "Result": None},
                     interpolation_type=node.interpolation_type, clamp=bool(node.clamp))
    return t.add(node, ctx, "map_range", {"Vector": None}, {"Vector": None},
                 interpolation_type=node.interpolation_type, clamp=bool(node.clamp))


def _separate_color(t, node, ctx):
    return t.add(node, ctx, "separate_color", color_mode=node.mode)


def _combine_color(t, node, ctx):
    return t.add(node, ctx, "combine_color", color_mode=node.mode)


def _legacy_color(ir_type, mode, sockets, outputs):
    def handler(t, node, ctx):
        return t.add(node, ctx, ir_type, sockets, outputs, color_mode=mode)
    return handler


def _world_only(t, node, ctx):
    t.warn(node, f"{node.bl_label} {node.name!r} belongs in a world; black stands in on a surface")
    return {s.identifier: Value((0.0, 0.0, 0.0), COLOR) for s in node.outputs}


def _displacement_warned(t, node, ctx):
    t.warn(node, f"Vector Displacement {node.name!r} is not supported (no displacement)")
    return {"Displacement": Value((0.0, 0.0, 0.0), VECTOR)}


HANDLERS = {
    # shaders
    "ShaderNodeBsdfPrincipled": _principled,
    "ShaderNodeBsdfDiffuse": _bsdf("diffuse_bsdf"),
    "ShaderNodeBsdfGlossy": _bsdf("glossy_bsdf", True),
    "ShaderNodeBsdfAnisotropic": _bsdf("glossy_bsdf", True),
    "ShaderNodeBsdfGlass": _bsdf("glass_bsdf", True),
    "ShaderNodeBsdfRefraction": _bsdf("refraction_bsdf", True),
    "ShaderNodeBsdfTranslucent": _bsdf("translucent_bsdf"),
    "ShaderNodeBsdfSheen": _sheen,
    "ShaderNodeVolumeAbsorption": _volume_shader,
    "ShaderNodeVolumeScatter": _volume_shader,
    "ShaderNodeVolumePrincipled": _volume_shader,
    "ShaderNodeSubsurfaceScattering": _subsurface,
    "ShaderNodeBsdfTransparent": _bsdf("transparent_bsdf"),
    "ShaderNodeEmission": _bsdf("emission"),
    "ShaderNodeHoldout": _bsdf("holdout"),
    "ShaderNodeMixShader": _simple("mix_closure"),
    "ShaderNodeAddShader": _simple("add_closure"),
    # inputs
    "ShaderNodeValue": _value,
    "ShaderNodeRGB": _rgb,
    "ShaderNodeTexCoord": _texcoord,
    "ShaderNodeNewGeometry": _geometry,
    "ShaderNodeObjectInfo": _simple("object_info"),
    "ShaderNodeAttribute": _attribute,
    "ShaderNodeVertexColor": _vertex_color,
    "ShaderNodeUVMap": _uvmap,
    "ShaderNodeLayerWeight": _simple("layer_weight"),
    "ShaderNodeFresnel": _simple("fresnel"),
    "ShaderNodeLightPath": _light_path,
    "ShaderNodeTangent": _tangent,
    "ShaderNodeWireframe": _wireframe,
    "ShaderNodeAmbientOcclusion": _ambient_occlusion,
    "ShaderNodeBevel": _bevel,
    "ShaderNodeCameraData": _camera_data,
    "ShaderNodeNormal": _normal,
    "ShaderNodeLightFalloff": _light_falloff,
    # textures
    "ShaderNodeTexImage": _image,
    "ShaderNodeTexChecker": _simple("checker_texture"),
    "ShaderNodeTexNoise": _simple("noise_texture", params=("noise_dimensions", "noise_type", "normalize")),
    "ShaderNodeTexVoronoi": _simple("voronoi_texture", params=("voronoi_dimensions", "feature", "distance",
                                                               "normalize")),
    "ShaderNodeTexWave": _simple("wave_texture", params=("wave_type", "bands_direction", "rings_direction",
                                                         "wave_profile")),
    "ShaderNodeTexMagic": _simple("magic_texture", params=("turbulence_depth",)),
    "ShaderNodeTexGradient": _simple("gradient_texture", params=("gradient_type",)),
    "ShaderNodeTexBrick": _simple("brick_texture", params=("offset", "offset_frequency", "squash",
                                                           "squash_frequency")),
    "ShaderNodeTexWhiteNoise": _simple("white_noise_texture", params=("noise_dimensions",)),
    "ShaderNodeTexEnvironment": _environment,
    "ShaderNodeBackground": _background,
    "ShaderNodeTexSky": _world_only,
    # colour
    "ShaderNodeMix": _mix,
    "ShaderNodeMixRGB": _mix_rgb,
    "ShaderNodeHueSaturation": _simple("hsv"),
    "ShaderNodeGamma": _simple("gamma"),
    "ShaderNodeInvert": _simple("invert"),
    "ShaderNodeBrightContrast": _simple("brightness_contrast"),
    "ShaderNodeRGBCurve": _curves("rgb_curves", 4, combined=True),
    "ShaderNodeVectorCurve": _curves("vector_curves", 3),
    "ShaderNodeFloatCurve": _curves("float_curve", 1),
    # vector
    "ShaderNodeMapping": _simple("mapping", params=("vector_type",)),
    "ShaderNodeBump": _simple("bump", params=("invert",)),
    "ShaderNodeNormalMap": _simple("normal_map", params=("space", "uv_map")),
    "ShaderNodeVectorMath": _simple("vector_math", params=("operation",)),
    "ShaderNodeVectorRotate": _simple("vector_rotate", params=("rotation_type", "invert")),
    "ShaderNodeVectorTransform": _simple("vector_transform", params=("vector_type", "convert_from", "convert_to")),
    "ShaderNodeDisplacement": _simple("displacement", params=("space",)),
    "ShaderNodeVectorDisplacement": _displacement_warned,
    # converter
    "ShaderNodeMath": _simple("math", params=("operation", "use_clamp")),
    "ShaderNodeMapRange": _map_range,
    "ShaderNodeClamp": _simple("clamp", params=("clamp_type",)),
    "ShaderNodeValToRGB": _color_ramp,
    "ShaderNodeCombineXYZ": _simple("combine_xyz"),
    "ShaderNodeSeparateXYZ": _simple("separate_xyz"),
    "ShaderNodeCombineColor": _combine_color,
    "ShaderNodeSeparateColor": _separate_color,
    "ShaderNodeCombineRGB": _legacy_color("combine_color", "RGB", {"R": "Red", "G": "Green", "B": "Blue"},
                                          {"Image": "Color"}),
    "ShaderNodeSeparateRGB": _legacy_color("separate_color", "RGB", {"Image": "Color"},
                                           {"R": "Red", "G": "Green", "B": "Blue"}),
    "ShaderNodeCombineHSV": _legacy_color("combine_color", "HSV", {"H": "Red", "S": "Green", "V": "Blue"}, {}),
    "ShaderNodeSeparateHSV": _legacy_color("separate_color", "HSV", {}, {"H": "Red", "S": "Green", "V": "Blue"}),
    "ShaderNodeRGBToBW": _simple("rgb_to_bw"),
    "ShaderNodeBlackbody": _simple("blackbody"),
    "ShaderNodeWavelength": _simple("wavelength"),
}


# ---------------------------------------------------------------------------------------------- entry points
def output_node(tree):
    """The Material Output Cycles renders: the active one among target All / Cycles (Blender's rule)."""
    try:
        out = tree.get_output_node("CYCLES")
    except (AttributeError, TypeError):
        out = None
    if out is not None:
        return out
    outs = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"
            and getattr(n, "target", "ALL") in ("ALL", "CYCLES")]
    return next((n for n in outs if n.is_active_output), outs[0] if outs else None)


def tree_graph(tree, label: str, warn, images: dict | None = None) -> Graph | None:
    """The graph of a material node tree, or None when it has no Material Output for Cycles."""
    out = output_node(tree)
    if out is None:
        return None
    t = Translator(label, warn, images)
    surface = t.input(out.inputs["Surface"], ())
    disp = t.input(out.inputs["Displacement"], ()) if "Displacement" in out.inputs else UNSET
    surf = UNSET if surface is UNSET else t.to_ir(surface, CLOSURE, out, out.inputs["Surface"])
    d = disp.v if (disp is not UNSET and disp.linked) else None
    t.g.output(surf if isinstance(surf, Out) else None, d)
    return t.g


def material_graph(material, warn, images: dict | None = None) -> Graph:
    """The shader graph of a Blender material (see the module docstring). A material without a node tree or
    without a Material Output is its viewport colour, metallic and roughness, as Cycles renders it."""
    label = f"material {material.name!r}"
    tree = material.node_tree
    g = tree_graph(tree, label, warn, images) if tree is not None else None
    if g is None:
        if tree is not None:
            warn(f"{label}: no Material Output for Cycles; its viewport colour is used")
        return constant_material(material.name, **{"Base Color": tuple(material.diffuse_color[:3]),
                                                   "Metallic": float(material.metallic),
                                                   "Roughness": float(material.roughness)})
    return g


def world_graph(world, warn, images: dict | None = None) -> Graph | None:
    """The shader graph of a Blender world's node tree (its Background is an emission closure: colour × strength is
    what rays that leave the scene see), or None without a World Output for Cycles."""
    tree = world.node_tree if world is not None else None
    if tree is None:
        return None
    outs = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputWorld"
            and getattr(n, "target", "ALL") in ("ALL", "CYCLES")]
    out = next((n for n in outs if n.is_active_output), outs[0] if outs else None)
    if out is None:
        return None
    t = Translator(f"world {world.name!r}", warn, images)
    surface = t.input(out.inputs["Surface"], ())
    surf = UNSET if surface is UNSET else t.to_ir(surface, CLOSURE, out, out.inputs["Surface"])
    t.g.output(surf if isinstance(surf, Out) else None, None)
    return t.g


__all__ = ["material_graph", "tree_graph", "world_graph", "output_node", "Translator", "HANDLERS", "curve_table"]


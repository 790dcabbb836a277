"""The shader graph IR: what a material *is* for the tracer, and the one contract every front end writes.

A material is a :class:`Graph` of :class:`Node` s. Each node has a type (a key of :data:`NODE_TYPES`, named as
Cycles names its nodes: ``principled_bsdf``, ``math``, ``image_texture``…), typed input sockets holding a constant
or a link to another node's output, typed outputs, and parameters (enums such as a Math node's operation, images,
ramps). Socket names are Blender's (= Cycles' UI names: ``"Base Color"``, ``"Fac"``); where Blender gives two sockets
one name, the second is written with Blender's identifier suffix (``"Value_001"``, ``"Shader_001"``). Exactly one
``material_output`` node says what the surface is (``Surface``, a closure) and optionally ``Displacement``.

    g = Graph("brick")
    tex = g.add("image_texture", image=ImageRef(path="bricks.png", colorspace="srgb"))
    bsdf = g.add("principled_bsdf", {"Base Color": tex["Color"], "Roughness": 0.6})
    g.output(bsdf["BSDF"])

The tracer compiles a graph once (:mod:`tracer.shading.compiler`: constants folded, dead nodes dropped, closures
flattened into a weighted sum of lobes) and evaluates what is left per hit (:mod:`tracer.shading.vm`).

Socket kinds (:data:`FLOAT`, :data:`VECTOR`, :data:`COLOR`, :data:`CLOSURE`). A link between kinds converts as
Blender does (:func:`convert_constant`): colour → float is the luminance (tracer.colorspace), vector → float the mean of x, y, z,
float → colour/vector (f, f, f), colour ↔ vector as is; a closure links only to a closure. Colours are RGB (alpha is
a separate float output, as in Blender).

Implicit inputs: an unlinked input whose default is one of :data:`IMPLICIT` reads that value of the hit instead of
a constant (``NORMAL``: the shading normal; ``UV``: the default UV map; ``GENERATED``: generated coordinates;
``POSITION``; ``TANGENT``). Unlinked Normal inputs of BSDFs are the shading normal; an Image Texture's unlinked
Vector is the default UV map; procedural textures' is Generated — as in Blender.

What the front ends do, and what they leave to the tracer:

- **Node groups, reroutes, muted nodes and frames are the front end's business**: the IR has none of them. A front
  end inlines a group (its Group Input defaults become constants of the inner nodes it feeds), follows reroutes to
  their source and replaces a muted node by Blender's pass-through (the first input of the output's kind, else the
  output's default). The IR is what Cycles would see after its own ``ShaderGraph::simplify`` of those.
- **Images** are :class:`ImageRef` parameters (a file or decoded pixels, colour space, wrap, interpolation), the one
  texture reference type of every front end; an :class:`ImageRef` is loaded once however many nodes share it.
- **Nodes the front end cannot translate**: it warns once naming the node and writes what it stands in for (a
  ``value``/``color`` node, or the socket's constant). A node type in :data:`NODE_TYPES` that this tracer's VM does
  not evaluate yet is reported by the compiler (one warning naming it; its outputs read 0 / black / the hit's
  normal for a normal).
- **Principled defaults** are :data:`tracer.shading.materials.PRINCIPLED_DEFAULTS` (Blender 4/5's), used for every
  unlinked, unset Principled input; ``f0_from_ior`` lives in :mod:`tracer.shading.materials` only.

The USD front end writes UsdPreviewSurface as ``principled_bsdf`` (its reading of the spec is its own) and its
texture nodes as ``usd_uv_texture`` (UsdUVTexture: scale, bias, fallback where the mesh has no coordinates) fed by
``uvmap`` (a primvar reader) through ``usd_transform2d``; MaterialX ``image``/``tiledimage`` and ``normalmap`` as
``usd_uv_texture`` / ``normal_map``.

Node types and their sockets are :data:`NODE_TYPES`, the entries of the node table :mod:`tracer.shading.nodes`
(documented with their meaning in docs/materials-api.md).
"""

from __future__ import annotations

import itertools
import os
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from .nodes import (CLOSURE, COLOR, ENUMS, FLOAT, GENERATED, IMPLICIT, KINDS, NODE_TYPES, NORMAL,  # noqa: F401
                    POSITION, TANGENT, UV, VECTOR, Implicit, NodeType, Socket, convert_constant)
from .texture import load_texture

# Node types, their sockets, parameters and lowering: tracer.shading.nodes (the node table), re-exported here as the
# IR's vocabulary.


@dataclass(eq=False)
class ImageRef:
    """The one texture reference of every front end: an image and how it is addressed.

    path         file read through OpenImageIO at first use (or None when ``pixels`` are given)
    pixels       (H, W, 4) float32 scene-linear, straight alpha, row 0 = top (front ends that decode themselves)
    colorspace   "auto" (8-bit RGB/RGBA files sRGB, others linear: :func:`tracer.shading.texture.decode_image`) |
                 "srgb" | "raw" — for ``path`` only
    wrap_s, wrap_t   "repeat" | "clamp" | "mirror" | "black" (Blender's REPEAT, EXTEND, MIRROR, CLIP)
    interpolation    "linear" | "closest" | "cubic" | "smart" (tracer.shading.texture: Smart reads as Cubic)
    label        for messages

    Two references to one file with the same colour space share pixels (a process-wide cache by path)."""

    path: str | None = None
    pixels: np.ndarray | None = None
    colorspace: str = "auto"
    wrap_s: str = "repeat"
    wrap_t: str = "repeat"
    interpolation: str = "linear"
    label: str = ""

    def rgba(self) -> np.ndarray:
        """(H, W, 4) float32 linear pixels (loaded once)."""
        if self.pixels is None:
            if not self.path:
                raise ValueError(f"image {self.label!r}: neither a path nor pixels")
            key = (os.path.abspath(self.path), self.colorspace)
            if key not in _PIXELS:
                _PIXELS[key] = load_texture(self.path, self.colorspace, channels=4)
            self.pixels = _PIXELS[key]
        return self.pixels

    def key(self) -> tuple:
        """Identity for sharing one tracer texture between lookups."""
        return (id(self.rgba()), self.wrap_s, self.wrap_t, self.interpolation)


_PIXELS: dict = {}


class Out(NamedTuple):
    """A link source: output ``socket`` of node ``node`` (a node id of the graph)."""

    node: int
    socket: str


_ids = itertools.count()


@dataclass(eq=False)
class Node:
    type: str
    inputs: dict = field(default_factory=dict)  # socket name -> constant or Out (unset: the type's default)
    params: dict = field(default_factory=dict)
    name: str = ""
    id: int = -1

    def __getitem__(self, socket: str) -> Out:
        nt = NODE_TYPES[self.type]
        if nt.output(socket) is None:
            raise KeyError(f"node {self.name or self.type!r} ({self.type}) has no output {socket!r}; "
                           f"outputs: {[s.name for s in nt.outputs]}")
        return Out(self.id, socket)

    def param(self, name: str):
        """A parameter's value, its type's default where unset."""
        if name in self.params:
            return self.params[name]
        return NODE_TYPES[self.type].params.get(name)


class Graph:
    """A material's node graph (see the module docstring)."""

    def __init__(self, name: str = ""):
        self.name = name
        self.nodes: dict[int, Node] = {}
        self._output: Node | None = None

    def add(self, type: str, inputs: dict | None = None, name: str = "", **params) -> Node:
        """Add a node of ``type`` with input constants / links (``Out``) and parameters; returns it."""
        nt = NODE_TYPES.get(type)
        if nt is None:
            raise ValueError(f"{self.name}: unknown node type {type!r}")
        inputs = dict(inputs or {})
        for k, v in inputs.items():
            self._check_input(type, name, k, v)
        for k in params:
            if k not in nt.params:
                raise ValueError(f"{self.name}: node {name or type!r} ({type}) has no parameter {k!r}; parameters: "
                                 f"{sorted(nt.params)}")
        node = Node(type, inputs, dict(params), name or f"{type}.{len(self.nodes)}", next(_ids))
        self.nodes[node.id] = node
        if type == "material_output":
            self._output = node
        return node

    def link(self, src: Out, node: Node, socket: str) -> None:
        """Link ``src`` to input ``socket`` of ``node`` (same checks as :meth:`add`)."""
        self._check_input(node.type, node.name, socket, src)
        node.inputs[socket] = src

    def _check_input(self, type: str, name: str, k: str, v) -> None:
        nt = NODE_TYPES[type]
        sock = nt.input(k)
        if sock is None:
            raise ValueError(f"{self.name}: node {name or type!r} ({type}) has no input {k!r}; inputs: "
                             f"{[s.name for s in nt.inputs]}")
        if isinstance(v, Out):
            if v.node not in self.nodes:
                raise ValueError(f"{self.name}: input {k!r} of {name or type!r} links to a node not in the graph")
            src = NODE_TYPES[self.nodes[v.node].type].output(v.socket)
            if src is None:
                raise ValueError(f"{self.name}: {self.nodes[v.node].type} has no output {v.socket!r}")
            if (src.kind == CLOSURE) != (sock.kind == CLOSURE):
                raise ValueError(f"{self.name}: {name or type!r}.{k} ({sock.kind}) cannot take "
                                 f"{self.nodes[v.node].type}.{v.socket} ({src.kind})")
        elif sock.kind == CLOSURE and v is not None:
            raise ValueError(f"{self.name}: closure input {k!r} of {name or type!r} takes a link or None")

    def output(self, surface: Out | None, displacement: Out | None = None) -> Node:
        """Add the material output (Surface closure, optional Displacement)."""
        inputs = {"Surface": surface}
        if displacement is not None:
            inputs["Displacement"] = displacement
        return self.add("material_output", inputs, name="Material Output")

    @property
    def output_node(self) -> Node | None:
        return self._output

    def node(self, ref: Out | int) -> Node:
        return self.nodes[ref.node if isinstance(ref, Out) else ref]

    def input_value(self, node: Node, socket: str):
        """A node input: its link (Out), its constant, or the type's default (possibly an :class:`Implicit`)."""
        if socket in node.inputs:
            return node.inputs[socket]
        return NODE_TYPES[node.type].input(socket).default

    def __repr__(self):
        return f"Graph({self.name!r}, {len(self.nodes)} nodes)"


def constant_material(name: str = "", **principled) -> Graph:
    """A graph of one ``principled_bsdf`` with constant inputs (Blender socket names) — the simplest material."""
    g = Graph(name)
    g.output(g.add("principled_bsdf", principled)["BSDF"])
    return g

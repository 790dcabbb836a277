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

The tracer compiles a graph once (:mod:`tracer.shader_compile`: constants folded, dead nodes dropped, closures
flattened into a weighted sum of lobes) and evaluates what is left per hit (:mod:`tracer.shader_vm`).

Socket kinds (:data:`FLOAT`, :data:`VECTOR`, :data:`COLOR`, :data:`CLOSURE`). A link between kinds converts as
Blender does: colour → float is the Rec.709 luminance (0.2126, 0.7152, 0.0722), vector → float the mean of x, y, z,
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
- **Principled defaults** are :data:`tracer.materials.PRINCIPLED_DEFAULTS` (Blender 4/5's), used for every
  unlinked, unset Principled input; ``f0_from_ior`` lives in :mod:`tracer.materials` only.

The USD front end writes UsdPreviewSurface as ``principled_bsdf`` (its reading of the spec is its own) and its
texture nodes as ``usd_uv_texture`` (UsdUVTexture: scale, bias, fallback where the mesh has no coordinates) fed by
``uvmap`` (a primvar reader) through ``usd_transform2d``; MaterialX ``image``/``tiledimage`` and ``normalmap`` as
``usd_uv_texture`` / ``normal_map``.

Node types and their sockets are :data:`NODE_TYPES` (documented with their meaning in docs/materials-api.md).
"""

from __future__ import annotations

import itertools
import os
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from .materials import PRINCIPLED_DEFAULTS

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


class NodeType(NamedTuple):
    """One node type: inputs and outputs (:class:`Socket`) and parameters {name: default} (enums: the first of the
    tuple in :data:`ENUMS` is the default when the value is None here)."""

    inputs: tuple
    outputs: tuple
    params: dict

    def input(self, name: str) -> Socket | None:
        return next((s for s in self.inputs if s.name == name), None)

    def output(self, name: str) -> Socket | None:
        return next((s for s in self.outputs if s.name == name), None)


def _f(name, d=0.0):
    return Socket(name, FLOAT, float(d))


def _v(name, d=(0.0, 0.0, 0.0)):
    return Socket(name, VECTOR, d if isinstance(d, Implicit) else tuple(float(x) for x in d))


def _c(name, d=(0.8, 0.8, 0.8)):
    return Socket(name, COLOR, tuple(float(x) for x in d))


def _s(name):
    return Socket(name, CLOSURE, None)


def _t(inputs, outputs, **params):
    return NodeType(tuple(inputs), tuple(outputs), params)


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
    "mix_color.blend_type": ("MIX", "DARKEN", "MULTIPLY", "BURN", "LIGHTEN", "SCREEN", "DODGE", "ADD", "OVERLAY",
                             "SOFT_LIGHT", "LINEAR_LIGHT", "DIFFERENCE", "EXCLUSION", "SUBTRACT", "DIVIDE", "HUE",
                             "SATURATION", "COLOR", "VALUE"),
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

#: Every node type of the IR. Procedural textures (noise, voronoi, wave, magic, gradient, brick, white noise),
#: blackbody and wavelength follow Blender's sockets; their evaluation is :mod:`tracer.procedural`'s.
NODE_TYPES: dict[str, NodeType] = {
    # ---------------------------------------------------------------- output
    "material_output": _t([_s("Surface"), _v("Displacement")], []),
    # ---------------------------------------------------------------- closures
    "principled_bsdf": _t([(_c if np.ndim(d) else _f)(k, d) for k, d in PRINCIPLED_DEFAULTS.items()] + [
                          _N, _f("Coat Weight"), _f("Sheen Weight"), _f("Subsurface Weight"), _f("Anisotropic"),
                           _f("Alpha Threshold")],  # Alpha Threshold: USD's opacityThreshold (not in Blender)
                          [_s("BSDF")], transmission_tint=None),  # None: the base colour tints (Cycles)
    "diffuse_bsdf": _t([_c("Color"), _f("Roughness"), _N], [_s("BSDF")]),
    "glossy_bsdf": _t([_c("Color"), _f("Roughness", 0.5), _f("Anisotropy"), _f("Rotation"), _N],
                      [_s("BSDF")], distribution="MULTI_GGX"),
    "glass_bsdf": _t([_c("Color", (1, 1, 1)), _f("Roughness"), _f("IOR", 1.5), _N], [_s("BSDF")],
                     distribution="MULTI_GGX"),
    "refraction_bsdf": _t([_c("Color", (1, 1, 1)), _f("Roughness"), _f("IOR", 1.5), _N], [_s("BSDF")],
                          distribution="GGX"),
    "translucent_bsdf": _t([_c("Color"), _N], [_s("BSDF")]),
    "transparent_bsdf": _t([_c("Color", (1, 1, 1))], [_s("BSDF")]),
    "emission": _t([_c("Color", (1, 1, 1)), _f("Strength", 1.0)], [_s("Emission")]),
    "holdout": _t([], [_s("Holdout")]),
    "mix_closure": _t([_f("Fac", 0.5), _s("Shader"), _s("Shader_001")], [_s("Shader")]),
    "add_closure": _t([_s("Shader"), _s("Shader_001")], [_s("Shader")]),
    # ---------------------------------------------------------------- inputs
    "value": _t([], [_f("Value")], value=0.0),
    "color": _t([], [_c("Color")], value=(0.8, 0.8, 0.8)),
    "texture_coordinate": _t([], [_v("Generated"), _v("Normal"), _v("UV"), _v("Object"), _v("Camera"),
                                  _v("Window"), _v("Reflection")], from_object=None),
    "geometry": _t([], [_v("Position"), _v("Normal"), _v("Tangent"), _v("True Normal"), _v("Incoming"),
                        _v("Parametric"), _f("Backfacing"), _f("Pointiness"), _f("Random Per Island")]),
    "object_info": _t([], [_v("Location"), _c("Color"), _f("Alpha"), _f("Object Index"), _f("Material Index"),
                           _f("Random")]),
    "light_path": _t([], [_f(n) for n in ("Is Camera Ray", "Is Shadow Ray", "Is Diffuse Ray", "Is Glossy Ray",
                                          "Is Singular Ray", "Is Reflection Ray", "Is Transmission Ray",
                                          "Ray Length", "Ray Depth", "Diffuse Depth", "Glossy Depth",
                                          "Transparent Depth", "Transmission Depth")]),
    "uvmap": _t([], [_v("UV")], attribute=""),  # attribute: the UV map / primvar name, "" = the default one
    "attribute": _t([], [_c("Color"), _v("Vector"), _f("Fac"), _f("Alpha")], attribute="",
                    attribute_type="GEOMETRY"),
    "vertex_color": _t([], [_c("Color"), _f("Alpha")], layer_name=""),  # "" = the mesh's active colour
    "fresnel": _t([_f("IOR", 1.5), _N], [_f("Fac")]),
    "layer_weight": _t([_f("Blend", 0.5), _N], [_f("Fresnel"), _f("Facing")]),
    "tangent": _t([], [_v("Tangent")], direction_type="UV_MAP", uv_map=""),
    # ---------------------------------------------------------------- textures
    "environment_texture": _t([_v("Vector", GENERATED)], [_c("Color"), _f("Alpha")], image=None,
                              projection="EQUIRECTANGULAR", interpolation="Linear"),
    "image_texture": _t([_v("Vector", UV)], [_c("Color"), _f("Alpha")], image=None, projection="FLAT",
                        projection_blend=0.0, interpolation="Linear", extension=None),
    "checker_texture": _t([_v("Vector", GENERATED), _c("Color1"), _c("Color2", (0.2, 0.2, 0.2)),
                           _f("Scale", 5.0)], [_c("Color"), _f("Fac")]),
    "noise_texture": _t([_v("Vector", GENERATED), _f("W"), _f("Scale", 5.0), _f("Detail", 2.0),
                         _f("Roughness", 0.5), _f("Lacunarity", 2.0), _f("Offset"), _f("Gain", 1.0),
                         _f("Distortion")], [_f("Fac"), _c("Color")], noise_dimensions="3D", noise_type="FBM",
                        normalize=True),
    "voronoi_texture": _t([_v("Vector", GENERATED), _f("W"), _f("Scale", 5.0), _f("Detail"), _f("Roughness", 0.5),
                           _f("Lacunarity", 2.0), _f("Smoothness", 1.0), _f("Exponent", 0.5),
                           _f("Randomness", 1.0)],
                          [_f("Distance"), _c("Color"), _v("Position"), _f("W"), _f("Radius")],
                          voronoi_dimensions="3D", feature="F1", distance="EUCLIDEAN", normalize=False),
    "wave_texture": _t([_v("Vector", GENERATED), _f("Scale", 5.0), _f("Distortion"), _f("Detail", 2.0),
                        _f("Detail Scale", 1.0), _f("Detail Roughness", 0.5), _f("Phase Offset")],
                       [_c("Color"), _f("Fac")], wave_type="BANDS", bands_direction="X", rings_direction="X",
                       wave_profile="SIN"),
    "magic_texture": _t([_v("Vector", GENERATED), _f("Scale", 5.0), _f("Distortion", 1.0)], [_c("Color"), _f("Fac")],
                        turbulence_depth=2),
    "gradient_texture": _t([_v("Vector", GENERATED)], [_c("Color"), _f("Fac")], gradient_type="LINEAR"),
    "brick_texture": _t([_v("Vector", GENERATED), _c("Color1"), _c("Color2", (0.2, 0.2, 0.2)),
                         _c("Mortar", (0.0, 0.0, 0.0)), _f("Scale", 5.0), _f("Mortar Size", 0.02),
                         _f("Mortar Smooth", 0.1), _f("Bias"), _f("Brick Width", 0.5), _f("Row Height", 0.25)],
                        [_c("Color"), _f("Fac")], offset=0.5, offset_frequency=2, squash=1.0, squash_frequency=2),
    "white_noise_texture": _t([_v("Vector", GENERATED), _f("W")], [_f("Value"), _c("Color")],
                              noise_dimensions="3D"),
    # ---------------------------------------------------------------- colour
    "mix_color": _t([_f("Factor", 0.5), _c("A", (0.5, 0.5, 0.5)), _c("B", (0.5, 0.5, 0.5))], [_c("Result")],
                    blend_type="MIX", use_clamp=False, use_clamp_result=False),
    "mix_float": _t([_f("Factor", 0.5), _f("A"), _f("B")], [_f("Result")], use_clamp=True),
    "mix_vector": _t([_f("Factor", 0.5), _v("A"), _v("B")], [_v("Result")], use_clamp=True),
    "mix_vector_non_uniform": _t([_v("Factor", (0.5, 0.5, 0.5)), _v("A"), _v("B")], [_v("Result")],
                                 use_clamp=True),
    "invert": _t([_f("Fac", 1.0), _c("Color", (0.0, 0.0, 0.0))], [_c("Color")]),
    "gamma": _t([_c("Color", (1, 1, 1)), _f("Gamma", 1.0)], [_c("Color")]),
    "brightness_contrast": _t([_c("Color", (1, 1, 1)), _f("Bright"), _f("Contrast")], [_c("Color")]),
    "hsv": _t([_f("Hue", 0.5), _f("Saturation", 1.0), _f("Value", 1.0), _f("Fac", 1.0), _c("Color")],
              [_c("Color")]),
    "rgb_curves": _t([_f("Fac", 1.0), _c("Color", (1, 1, 1))], [_c("Color")], curves=None, range=(0.0, 1.0)),
    "rgb_ramp": _t([_f("Fac", 0.5)], [_c("Color"), _f("Alpha")], ramp=None, interpolation="LINEAR",
                   color_mode="RGB", hue_interpolation="NEAR"),
    "blackbody": _t([_f("Temperature", 1500.0)], [_c("Color")]),
    "wavelength": _t([_f("Wavelength", 500.0)], [_c("Color")]),
    "rgb_to_bw": _t([_c("Color", (0.5, 0.5, 0.5))], [_f("Val")]),
    "separate_color": _t([_c("Color")], [_f("Red"), _f("Green"), _f("Blue")], color_mode="RGB"),
    "combine_color": _t([_f("Red"), _f("Green"), _f("Blue")], [_c("Color")], color_mode="RGB"),
    # ---------------------------------------------------------------- vector / converter
    "separate_xyz": _t([_v("Vector")], [_f("X"), _f("Y"), _f("Z")]),
    "combine_xyz": _t([_f("X"), _f("Y"), _f("Z")], [_v("Vector")]),
    "math": _t([_f("Value", 0.5), _f("Value_001", 0.5), _f("Value_002", 0.5)], [_f("Value")], operation="ADD",
               use_clamp=False),
    "vector_math": _t([_v("Vector"), _v("Vector_001"), _v("Vector_002"), _f("Scale", 1.0)],
                      [_v("Vector"), _f("Value")], operation="ADD"),
    "map_range": _t([_f("Value", 1.0), _f("From Min"), _f("From Max", 1.0), _f("To Min"), _f("To Max", 1.0),
                     _f("Steps", 4.0)], [_f("Result")], interpolation_type="LINEAR", clamp=True),
    "vector_map_range": _t([_v("Vector"), _v("From Min"), _v("From Max", (1, 1, 1)), _v("To Min"),
                            _v("To Max", (1, 1, 1)), _v("Steps", (4, 4, 4))], [_v("Vector")],
                           interpolation_type="LINEAR", clamp=True),
    "clamp": _t([_f("Value", 1.0), _f("Min"), _f("Max", 1.0)], [_f("Result")], clamp_type="MINMAX"),
    "float_curve": _t([_f("Factor", 1.0), _f("Value", 1.0)], [_f("Value")], curves=None, range=(0.0, 1.0)),
    "vector_curves": _t([_f("Fac", 1.0), _v("Vector")], [_v("Vector")], curves=None, range=(0.0, 1.0)),
    "mapping": _t([_v("Vector"), _v("Location"), _v("Rotation"), _v("Scale", (1, 1, 1))], [_v("Vector")],
                  vector_type="POINT"),
    "vector_rotate": _t([_v("Vector"), _v("Center"), _v("Axis", (0, 0, 1)), _f("Angle"), _v("Rotation")],
                        [_v("Vector")], rotation_type="AXIS_ANGLE", invert=False),
    "vector_transform": _t([_v("Vector", (0.5, 0.5, 0.5))], [_v("Vector")], vector_type="VECTOR",
                           convert_from="WORLD", convert_to="OBJECT"),
    "normal_map": _t([_f("Strength", 1.0), _c("Color", (0.5, 0.5, 1.0))], [_v("Normal")], space="TANGENT",
                     uv_map=""),
    "bump": _t([_f("Strength", 1.0), _f("Distance", 1.0), _f("Filter Width", 0.1), _f("Height", 1.0), _N],
               [_v("Normal")], invert=False),
    "displacement": _t([_f("Height"), _f("Midlevel", 0.5), _f("Scale", 1.0), _N], [_v("Displacement")],
                       space="OBJECT"),
    # ---------------------------------------------------------------- USD / MaterialX
    # MaterialX's noise2d/3d, fractal2d/3d, cellnoise2d/3d, worleynoise2d/3d (tracer.procedural.mx_noise): kind
    # perlin | cell | worley | fractal, dimensions 2 | 3, width 1-4 (float, vector2, vector3/color3, vector4/color4),
    # style 0 distance | 1 solid (worley). Value = x, Vector = (x, y, z), W = w of the node's result.
    "mx_noise": _t([_v("Vector", GENERATED), _v("Amplitude", (1, 1, 1)), _f("Amplitude W", 1.0), _f("Pivot"),
                    _f("Octaves", 3.0), _f("Lacunarity", 2.0), _f("Diminish", 0.5), _f("Jitter", 1.0)],
                   [_f("Value"), _v("Vector"), _f("W")], kind="perlin", dimensions=3, width=1, style=0),
    # UsdUVTexture: image (an ImageRef, wrap from it), st, scale/bias per channel, fallback where the mesh has no
    # coordinates. Outputs r, g, b, a and rgb as in the spec.
    "usd_uv_texture": _t([_v("st", UV)], [_f("r"), _f("g"), _f("b"), _f("a"), _c("rgb")], image=None,
                         scale=(1.0, 1.0, 1.0, 1.0), bias=(0.0, 0.0, 0.0, 0.0), fallback=(0.0, 0.0, 0.0, 1.0)),
    # UsdTransform2d: in · scale · rotate (degrees, counter-clockwise) + translation, on (s, t)
    # (internal) a row's P_texture column: Scene.textures[index] read in its own UV set with its own transform,
    # scale, bias and fallback — how rows of the table API become programs
    "scene_texture": _t([], [_c("Color"), _f("Alpha")], index=0, uv_set=0),
    # (or ``matrix``: the 3 × 3 on (s, t, 1) of a chain of them, composed)
    "usd_transform2d": _t([_v("in", UV)], [_v("result")], scale=(1.0, 1.0), rotation=0.0,
                          translation=(0.0, 0.0), matrix=None),
}


@dataclass(eq=False)
class ImageRef:
    """The one texture reference of every front end: an image and how it is addressed.

    path         file read through OpenImageIO at first use (or None when ``pixels`` are given)
    pixels       (H, W, 4) float32 scene-linear, straight alpha, row 0 = top (front ends that decode themselves)
    colorspace   "auto" (8/16-bit files sRGB, float files linear) | "srgb" | "raw" — for ``path`` only
    wrap_s, wrap_t   "repeat" | "clamp" | "mirror" | "black" (Blender's REPEAT, EXTEND, MIRROR, CLIP)
    interpolation    "linear" | "closest" | "cubic" | "smart" (tracer.texture: Smart reads as Cubic)
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
                from .texture import load_texture
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

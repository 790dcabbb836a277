"""The values a UsdShade network reads as (a leaf of the material readers: everything here imports only pxr, numpy
and :mod:`usd_io.materials.texture_assets`).

    Const, TextureLookup, PrimvarLookup, GraphLookup, Unsupported    what drives a surface input
                                      (:func:`usd_io.materials.network.source` decides which)
    producer, value, floats, shader_id, varname, file_layer          reading one input of one node
    transform2d_matrix                a UsdTransform2d as a 3×3 matrix
    V, WIDTH                          a typed value of a translated network (MaterialX, Arnold patterns) in the IR

:mod:`usd_io.materials.network` re-exports them: the surface readers write ``net.Const`` and so on. Imports flow one
way: shade_types → arnold_patterns → shade_network → preview_ranges / omnipbr / arnold → surfaces → material, with
mtlx_graph (MaterialX) loaded by material only when a network needs it (tests/test_imports.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from pxr import Sdf, UsdShade

from .texture_assets import authoring_layer

#: UsdUVTexture output name -> channel (-1 = the rgb triple).
CHANNELS = {"r": 0, "g": 1, "b": 2, "a": 3, "rgb": -1, "rgba": -1}
#: UsdUVTexture input fallbacks of the spec.
UV_TEXTURE_DEFAULTS = dict(scale=(1.0, 1.0, 1.0, 1.0), bias=(0.0, 0.0, 0.0, 0.0), fallback=(0.0, 0.0, 0.0, 1.0),
                           wrapS="useMetadata", wrapT="useMetadata", sourceColorSpace="auto")
PRIMVAR_READERS = ("UsdPrimvarReader_float", "UsdPrimvarReader_float2", "UsdPrimvarReader_float3",
                   "UsdPrimvarReader_float4", "UsdPrimvarReader_normal", "UsdPrimvarReader_point",
                   "UsdPrimvarReader_vector")
#: MaterialX address modes -> UsdUVTexture wrap tokens.
MX_ADDRESS = {"periodic": "repeat", "clamp": "clamp", "mirror": "mirror", "constant": "black"}


@dataclass
class Const:
    value: object


@dataclass
class TextureLookup:
    node: str  # the UsdUVTexture prim's path (for messages)
    asset: Sdf.AssetPath | None
    channel: int  # 0..3, or -1 for rgb
    uv: str | None  # primvar name of the st chain; None = the mesh's default texture coordinates
    transform: np.ndarray  # (3, 3) affine on (s, t, 1)
    scale: tuple
    bias: tuple
    fallback: tuple
    wrap_s: str
    wrap_t: str
    colorspace: str  # sourceColorSpace token: "auto", "sRGB" or "raw"
    notes: list = field(default_factory=list)  # things on the st chain that were not understood
    layer: object = None  # the Sdf.Layer that authored the file path (anchors UDIM tiles and backslash paths)


@dataclass
class PrimvarLookup:
    node: str
    name: str
    fallback: object
    reader: str  # the shader id


@dataclass
class GraphLookup:
    """A MaterialX network (a node with a node definition) driving an input: :class:`usd_io.materials.mtlx_graph.MxProgram`
    writes it; ``scale`` multiplies its value (a surface's weight)."""

    node: str
    shader: object
    output: str
    fallback: object
    scale: float = 1.0


@dataclass
class Unsupported:
    node: str
    shader_id: str
    fallback: object


def shader_id(s) -> str:
    sid = s.GetShaderId() if s else None
    return str(sid) if sid else ""


def producer(shader: UsdShade.Shader, name: str):
    """(attribute, is_output) that gives the value of input ``name``, or (None, False)."""
    inp = shader.GetInput(name)
    if not inp:
        return None, False
    attrs = inp.GetValueProducingAttributes()
    if not attrs:
        return None, False
    a = attrs[0]
    return a, UsdShade.Output.IsOutput(a)


def value(shader: UsdShade.Shader, name: str, default=None, time=None):
    """An input's own value (following interface connections); ``default`` when unauthored or node-driven."""
    a, is_out = producer(shader, name)
    if a is None or is_out:
        return default
    v = a.Get() if time is None else a.Get(time)
    return default if v is None else v


def floats(v, n: int, default) -> tuple:
    """``v`` as a tuple of ``n`` floats (scalars broadcast, longer values cut, shorter padded from ``default``)."""
    try:
        a = np.asarray(v, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        return tuple(float(x) for x in default)
    if a.size == 0:
        return tuple(float(x) for x in default)
    if a.size == 1:
        a = np.repeat(a, n)
    if a.size >= n:
        return tuple(float(x) for x in a[:n])
    return tuple(float(x) for x in a) + tuple(float(x) for x in list(default)[a.size:n])


def varname(node, time) -> str:
    v = value(node, "varname", "", time)  # string since spec 2.3; token in older files (McUsd)
    return str(v) if v else ""


def file_layer(node, time, name="file"):
    """The layer that authored a texture node's ``file`` (through interface connections)."""
    a, is_out = producer(node, name)
    return None if a is None or is_out else authoring_layer(a)


def transform2d_matrix(scale=(1.0, 1.0), rotation=0.0, translation=(0.0, 0.0)) -> np.ndarray:
    """The (3, 3) matrix of a UsdTransform2d on (s, t, 1): T · R · S (scale, then rotate CCW in degrees, then
    translate), the spec's ``in · scale · rotate + translation``."""
    if not math.isfinite(rotation):
        return np.full((3, 3), np.nan)  # the caller warns and ignores a non-finite transform
    c, s = math.cos(math.radians(rotation)), math.sin(math.radians(rotation))
    S = np.diag([scale[0], scale[1], 1.0])
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    T = np.array([[1.0, 0.0, translation[0]], [0.0, 1.0, translation[1]], [0.0, 0.0, 1.0]])
    return T @ R @ S


#: Lanes of each MaterialX type.
WIDTH = {"float": 1, "integer": 1, "boolean": 1, "vector2": 2, "vector3": 3, "color3": 3, "vector4": 4,
         "color4": 4}


@dataclass
class V:
    """A MaterialX value: ``t`` its type, ``x`` its first lane (1-wide types) or its first three (an IR constant
    tuple or a link), ``w`` the fourth lane of color4/vector4."""

    t: str
    x: object
    w: object = 1.0

    @property
    def wide(self) -> int:
        return WIDTH.get(self.t, 1)

"""Reading a UsdPreviewSurface input through its shading network: a constant, a texture lookup or a primvar.

``source(shader, "roughness")`` follows the input's connections (through NodeGraph outputs and Material interface
inputs, ``UsdShade.Input.GetValueProducingAttributes``) and returns one of

    Const(value)                      an authored or fallback value (also: a node's input that is not connected)
    TextureLookup(...)                a ``UsdUVTexture`` read through one of its outputs (r, g, b, a or rgb), or a
                                      MaterialX ``image``/``tiledimage`` (a ``normalmap`` over one: scale 2, bias −1)
    PrimvarLookup(name, fallback)     a ``UsdPrimvarReader_float/float2/float3/float4`` (e.g. displayColor)
    GraphLookup(node, output)         any other MaterialX node with a node definition (noise, ramps, maths...):
                                      written as IR nodes by :mod:`usd_io.materials.mtlx_graph`
    Unsupported(node id, fallback)    any other node (the caller warns once and uses the fallback)

The texture-coordinate chain of a ``UsdUVTexture`` (its ``st`` input) is folded into the lookup: the primvar name of
the ``UsdPrimvarReader_float2`` at its end, and one 3×3 affine matrix on (s, t, 1) for the ``UsdTransform2d`` nodes
on the way. UsdPreviewSurface spec, Transform2d: ``result = in · scale · rotate + translation`` (scale first, then
the counter-clockwise rotation in degrees, then the translation), so the matrix is T · R · S. Chains of several
Transform2d nodes compose (the one nearest the primvar reader applies first).

The value types and the one-input readers are :mod:`usd_io.materials.shade_types` (re-exported here).

A ``UsdUVTexture`` whose ``st`` is not connected reads the mesh's default texture coordinates (``uv = None``): see
:func:`usd_io.geometry.mesh.default_uv_name` for the rule.
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf, UsdShade

from .arnold_patterns import upstream as arnold_upstream
from .mtlx import nodedef, texture_colorspace
from .shade_types import (CHANNELS, MX_ADDRESS, PRIMVAR_READERS, UV_TEXTURE_DEFAULTS, WIDTH, Const,  # noqa: F401
                          GraphLookup, PrimvarLookup, TextureLookup, Unsupported, V, file_layer, floats, producer,
                          shader_id, transform2d_matrix, value, varname)

#: MaterialX image nodes (``ND_image_color3``, ``ND_tiledimage_float``, ...) read as texture lookups.
MX_IMAGES = ("ND_image_", "ND_tiledimage_")


def source(shader: UsdShade.Shader, name: str, fallback, time=None):
    """What drives input ``name`` of ``shader``: Const, TextureLookup, PrimvarLookup or Unsupported."""
    a, is_out = producer(shader, name)
    if a is None:
        return Const(fallback)
    if not is_out:
        v = a.Get() if time is None else a.Get(time)
        return Const(fallback if v is None else v)
    node = UsdShade.Shader(a.GetPrim())
    out_name = UsdShade.Output(a).GetBaseName()
    sid = shader_id(node)
    if sid == "UsdUVTexture" or sid.startswith("ND_UsdUVTexture"):
        return texture_lookup(node, out_name, time)
    if sid in PRIMVAR_READERS or sid.startswith("ND_UsdPrimvarReader"):
        return PrimvarLookup(str(node.GetPath()), varname(node, time), value(node, "fallback", None, time), sid)
    if sid.startswith(MX_IMAGES) and _mx_texcoord(node, [], time)[0] != _COMPUTED:
        return mx_image_lookup(node, time)
    if sid.startswith("ND_normalmap"):
        got = mx_normal_map(node, fallback, time)
        if not isinstance(got, Unsupported):
            return got
    if sid.startswith("ND_") and nodedef(sid) is not None:
        return GraphLookup(str(node.GetPath()), node, out_name, fallback)
    if sid.startswith("arnold:"):  # Arnold's image, user-data and pattern nodes (usd_io.materials.arnold_patterns)
        got = arnold_upstream(node, out_name, fallback, time)
        if got is not None:
            return got
    return Unsupported(str(node.GetPath()), sid or a.GetPrim().GetTypeName(), value(node, "fallback", fallback, time))


def mx_image_lookup(node: UsdShade.Shader, time=None) -> TextureLookup:
    """A MaterialX ``image``/``tiledimage`` node as a texture lookup (MaterialX, like USD, puts uv (0, 0) at the
    image's lower left). A float image reads its red channel; colour and vector ones rgb. The ``file`` input's
    colour space (:func:`usd_io.mtlx.texture_colorspace`): ``srgb_texture`` is sRGB, none or a linear Rec.709 name
    raw, any other MaterialX space read raw and transformed into linear Rec.709.
    ``tiledimage``: uv · uvtiling − uvoffset."""
    sid = shader_id(node)
    kind = sid.rsplit("_", 1)[-1]
    file_input = node.GetInput("file")
    space = file_input.GetAttr().GetColorSpace() if file_input else ""
    cs, note = texture_colorspace(space)  # srgb_texture, linear, or MaterialX's transform after a raw read
    notes: list = [note] if note else []
    uv, m = _mx_texcoord(node, notes, time)
    uv = None if uv == _COMPUTED else uv
    if sid.startswith("ND_tiledimage_"):
        tiling = floats(value(node, "uvtiling", (1.0, 1.0), time), 2, (1.0, 1.0))
        offset = floats(value(node, "uvoffset", (0.0, 0.0), time), 2, (0.0, 0.0))
        m = np.array([[tiling[0], 0.0, -offset[0]], [0.0, tiling[1], -offset[1]], [0.0, 0.0, 1.0]]) @ m
    default = floats(value(node, "default", (0.0,), time), 3 if kind != "float" else 1, (0.0, 0.0, 0.0))
    fallback = (tuple(default) * 3)[:3] + (1.0,)
    asset = value(node, "file", None, time)
    wrap = [MX_ADDRESS.get(str(value(node, f"{a}addressmode", "periodic", time)), "repeat") for a in "uv"]
    return TextureLookup(node=str(node.GetPath()), asset=asset if isinstance(asset, Sdf.AssetPath) else None,
                         channel=0 if kind == "float" else -1, uv=uv, transform=m, scale=(1.0, 1.0, 1.0, 1.0),
                         bias=(0.0, 0.0, 0.0, 0.0), fallback=fallback, wrap_s=wrap[0], wrap_t=wrap[1],
                         colorspace=cs, notes=notes, layer=file_layer(node, time))


def mx_normal_map(node: UsdShade.Shader, fallback, time=None):
    """A MaterialX ``normalmap`` node over an image: the image as a tangent-space normal map, texel·2 − 1 (its
    ``scale`` on x and y). Anything else upstream is Unsupported."""
    up = source(node, "in", (0.5, 0.5, 1.0), time)
    if not isinstance(up, TextureLookup) or str(value(node, "space", "tangent", time)) != "tangent" or \
            producer(node, "normal")[0] is not None:
        return Unsupported(str(node.GetPath()), shader_id(node), fallback)
    k = floats(value(node, "scale", 1.0, time), 1, (1.0,))[0]
    up.scale = (2.0 * k, 2.0 * k, 2.0, 1.0)
    up.bias = (-k, -k, -1.0, 0.0)
    return up


def _mx_texcoord(node, notes: list, time):
    """(uv primvar name or None, identity) for a MaterialX image's ``texcoord`` input."""
    a, is_out = producer(node, "texcoord")
    if a is None or not is_out:
        return None, np.eye(3)
    up = UsdShade.Shader(a.GetPrim())
    sid = shader_id(up)
    if sid.startswith("ND_texcoord_") and int(value(up, "index", 0, time) or 0) == 0:
        return None, np.eye(3)
    if sid.startswith("ND_geompropvalue_"):
        return (str(value(up, "geomprop", "", time) or "") or None), np.eye(3)
    if sid in PRIMVAR_READERS or sid.startswith("ND_UsdPrimvarReader"):
        return (varname(up, time) or None), np.eye(3)
    notes.append(f"texcoord driven by {sid or up.GetPrim().GetTypeName()!r} (the mesh's texture coordinates are used)")
    return _COMPUTED, np.eye(3)


#: :func:`_mx_texcoord`'s answer for a texcoord computed by a network (the image is then read by usd_io.materials.mtlx_graph).
_COMPUTED = "<computed>"


def texture_lookup(node: UsdShade.Shader, output: str, time=None) -> TextureLookup:
    d = UV_TEXTURE_DEFAULTS
    asset = value(node, "file", None, time)
    channel = CHANNELS.get(output, -1)
    notes = []
    if output not in CHANNELS:
        notes.append(f"output {output!r} is not one of r, g, b, a, rgb (rgb used)")
    uv, m = _st_chain(node, notes, time)
    return TextureLookup(
        node=str(node.GetPath()), asset=asset if isinstance(asset, Sdf.AssetPath) else None, channel=channel,
        uv=uv, transform=m,
        scale=floats(value(node, "scale", d["scale"], time), 4, d["scale"]),
        bias=floats(value(node, "bias", d["bias"], time), 4, d["bias"]),
        fallback=floats(value(node, "fallback", d["fallback"], time), 4, d["fallback"]),
        wrap_s=str(value(node, "wrapS", d["wrapS"], time)), wrap_t=str(value(node, "wrapT", d["wrapT"], time)),
        colorspace=str(value(node, "sourceColorSpace", d["sourceColorSpace"], time)), notes=notes,
        layer=file_layer(node, time))


def _st_chain(tex: UsdShade.Shader, notes: list, time):
    """(uv primvar name or None, (3, 3) matrix) of a UsdUVTexture's st input."""
    m = np.eye(3)
    node, inp = tex, "st"
    for _ in range(16):  # a chain, not a loop
        a, is_out = producer(node, inp)
        if a is None:
            return None, m
        if not is_out:
            notes.append(f"st is a constant {a.Get()} (the mesh's texture coordinates are used)")
            return None, m
        up = UsdShade.Shader(a.GetPrim())
        sid = shader_id(up)
        if sid == "UsdTransform2d":
            step = transform2d_matrix(floats(value(up, "scale", (1.0, 1.0), time), 2, (1.0, 1.0)),
                                      float(value(up, "rotation", 0.0, time) or 0.0),
                                      floats(value(up, "translation", (0.0, 0.0), time), 2, (0.0, 0.0)))
            m = m @ step  # the node nearer the texture applies last
            node, inp = up, "in"
            continue
        if sid in PRIMVAR_READERS or sid.startswith("ND_UsdPrimvarReader"):
            name = varname(up, time)
            return (name or None), m
        notes.append(f"st driven by {sid or up.GetPrim().GetTypeName()!r}, not a primvar reader or UsdTransform2d "
                     "(the mesh's texture coordinates are used)")
        return None, m
    notes.append("st chain too long (the mesh's texture coordinates are used)")
    return None, m

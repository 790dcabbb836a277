"""Arnold shaders as arnold-usd and Houdini/Maya write them (``info:id = "arnold:…"``, usually on
``outputs:arnold:surface``), read into the same fields as MaterialX and UsdPreviewSurface.

Surfaces:

    arnold:standard_surface   MaterialX Standard Surface (the same inputs and defaults: Arnold's own shader is the
                              definition MaterialX copied), read by ``MaterialTable.materialx``
    arnold:openpbr_surface    MaterialX OpenPBR, the same way
    arnold:lambert            base colour Kd · Kd_color (defaults 0.7, white), no specular
    arnold:standard           (Arnold 4's) base colour Kd · Kd_color, specular level Ks (0 → none)
    arnold:flat               unlit ``color``: written as emission (black diffuse): it shows its colour whatever the
                              light; as an emitter it also lights its surroundings a little (documented)

Nodes upstream of an input (``shade_network.source`` asks :func:`upstream`):

    arnold:image              a texture lookup: ``filename``; ``uvset`` (empty: the mesh's default UVs);
                              uv · (sscale, tscale) + (soffset, toffset); ``sflip``/``tflip`` (s → 1 − s);
                              ``multiply``/``offset`` as scale/bias; ``swrap``/``twrap`` (periodic → repeat,
                              clamp, mirror, black); ``color_space`` ("sRGB", "linear"/"Raw" → raw, else auto)
    arnold:user_data_rgb      a primvar read (``attribute``, fallback ``default``): vertex colour
    arnold:user_data_float    the same, one channel
    arnold:flat, checkerboard, ramp_rgb, ramp_float, color_correct, color_jitter
                              written into the material's shader graph (``usd_io.arnold_patterns``)

Anything else upstream is ``Unsupported`` (one warning naming the node; the input's value is used). A pattern
node (or ``arnold:image``) connected as the surface itself is drawn as Arnold draws it: its colour, unlit (as
``arnold:flat``).
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf

from . import shade_network as net
from .arnold_patterns import PATTERNS

#: Arnold surface ids read as a MaterialX family (a key of ``material.MX_SURFACES``).
AS_MATERIALX = {"arnold:standard_surface": "standard_surface", "arnold:openpbr_surface": "open_pbr_surface"}
SIMPLE_SURFACES = ("arnold:lambert", "arnold:standard", "arnold:flat") + PATTERNS[1:] + ("arnold:image",)
_WRAP = {"periodic": "repeat", "clamp": "clamp", "mirror": "mirror", "black": "black", "file": "useMetadata"}


def is_arnold(shader) -> bool:
    return net.shader_id(shader).startswith("arnold:")


def simple_surface(table, s, label: str, needs):
    """(fields) of arnold:lambert / standard / flat; None for other ids."""
    sid = net.shader_id(s)
    t = table.model()
    if sid in PATTERNS[1:] or sid == "arnold:image":  # a colour node as the surface: unlit, like arnold:flat
        t.update(base_color=(0.0, 0.0, 0.0), specular=0.0)
        src = upstream(s, "rgb", (1.0, 1.0, 1.0), table.time)
        table._colour_input(t, "emission", src, (1.0, 1.0, 1.0), label, "color", needs)
        return t
    num = lambda name, d: float(net.floats(net.value(s, name, d, table.time), 1, (d,))[0])  # noqa: E731
    if sid == "arnold:flat":
        t.update(base_color=(0.0, 0.0, 0.0), specular=0.0)
        table._colour_input(t, "emission", net.source(s, "color", (1.0, 1.0, 1.0), table.time), (1.0, 1.0, 1.0),
                            label, "color", needs)
        return t
    if sid in ("arnold:lambert", "arnold:standard"):
        kd = num("Kd", 0.7)
        src = net.source(s, "Kd_color", (1.0, 1.0, 1.0), table.time)
        if isinstance(src, net.Const):
            src = net.Const(tuple(kd * c for c in net.floats(src.value, 3, (1.0, 1.0, 1.0))))
        elif isinstance(src, net.TextureLookup):
            src.scale = tuple(kd * c for c in src.scale[:3]) + (src.scale[3],)
        if isinstance(src, net.PrimvarLookup):
            needs.color = (src.name, net.floats(src.fallback, 3, (1.0, 1.0, 1.0)))
            t.update(base_color=(kd, kd, kd), vertex_color=True)
        else:
            table._colour_input(t, "base_color", src, (kd, kd, kd), label, "Kd_color", needs)
        ks = num("Ks", 0.0) if sid == "arnold:standard" else 0.0
        t.update(specular=float(np.clip(ks, 0.0, 1.0)), roughness=float(np.clip(num("specular_roughness", 0.467),
                                                                                  0.0, 1.0)), metallic=0.0)
        return t
    return None


def upstream(node, output: str, fallback, time):
    """What an Arnold node upstream of an input reads as (TextureLookup, PrimvarLookup), or None."""
    sid = net.shader_id(node)
    if sid in PATTERNS:
        return net.GraphLookup(str(node.GetPath()), node, output, fallback)
    if sid == "arnold:image":
        return image_lookup(node, output, time)
    if sid in ("arnold:user_data_rgb", "arnold:user_data_rgba", "arnold:user_data_float"):
        name = str(net.value(node, "attribute", "", time) or "")
        default = net.value(node, "default", fallback, time)
        return net.PrimvarLookup(str(node.GetPath()), name, default, sid) if name else None
    return None


def image_lookup(node, output: str, time) -> net.TextureLookup:
    v = lambda name, d: net.value(node, name, d, time)  # noqa: E731
    f = lambda name, d: float(net.floats(v(name, d), 1, (d,))[0])  # noqa: E731
    asset = v("filename", None)
    space = str(v("color_space", "auto") or "auto")
    colorspace = "sRGB" if space.lower() == "srgb" else "raw" if space.lower() in ("linear", "raw") else "auto"
    ss, ts, so, to = f("sscale", 1.0), f("tscale", 1.0), f("soffset", 0.0), f("toffset", 0.0)
    m = np.array([[ss, 0.0, so], [0.0, ts, to], [0.0, 0.0, 1.0]])
    if bool(v("sflip", False)):
        m = np.array([[-1.0, 0.0, 1.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]) @ m
    if bool(v("tflip", False)):
        m = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 1.0], [0.0, 0.0, 1.0]]) @ m
    mult = net.floats(v("multiply", (1.0, 1.0, 1.0)), 3, (1.0, 1.0, 1.0))
    off = net.floats(v("offset", (0.0, 0.0, 0.0)), 3, (0.0, 0.0, 0.0))
    missing = net.floats(v("missing_texture_color", (0.0, 0.0, 0.0, 1.0)), 4, (0.0, 0.0, 0.0, 1.0))
    uvset = str(v("uvset", "") or "")
    return net.TextureLookup(
        node=str(node.GetPath()), asset=asset if isinstance(asset, Sdf.AssetPath) else None,
        channel=net.CHANNELS.get(output, -1), uv=uvset or None, transform=m, scale=tuple(mult) + (1.0,),
        bias=tuple(off) + (0.0,), fallback=missing, wrap_s=_WRAP.get(str(v("swrap", "periodic")), "repeat"),
        wrap_t=_WRAP.get(str(v("twrap", "periodic")), "repeat"), colorspace=colorspace,
        layer=net.file_layer(node, time, "filename"))


#: Arnold render globals (``arnold:global:NAME`` on a RenderSettings prim, naming an ArnoldNodeGraph) that draw
#: something, and what this tracer does without them.
RENDER_GLOBALS = {"background": "rays that leave the scene see the stage's dome or background instead",
                  "atmosphere": "no participating medium is rendered"}


def render_globals(stage, prims, warn) -> None:
    """One warning per Arnold background/atmosphere shader a RenderSettings prim names (``arnold:global:background``
    = "/sky_graph", whose ``outputs:background`` is e.g. an ``arnold:physical_sky``): Arnold-only content this
    tracer does not draw. ``prims``: the stage's prims as the reader traversed them."""
    from pxr import UsdShade

    for prim in prims:
        if prim.GetTypeName() != "RenderSettings":
            continue
        for name, instead in RENDER_GLOBALS.items():
            a = prim.GetAttribute(f"arnold:global:{name}")
            path = a.Get() if a else None
            if not path or not Sdf.Path.IsValidPathString(str(path)):
                continue
            graph = stage.GetPrimAtPath(str(path))
            out = graph.GetAttribute(f"outputs:{name}") if graph else None
            srcs = out.GetConnections() if out else []
            shader = UsdShade.Shader(stage.GetPrimAtPath(srcs[0].GetPrimPath())) if srcs else None
            sid = net.shader_id(shader) if shader else ""
            warn(f"{prim.GetPath()}: Arnold {name} {path}{f' ({sid})' if sid else ''} is not supported: {instead}")

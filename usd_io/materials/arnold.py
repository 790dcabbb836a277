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

Nodes upstream of an input (``arnold:image``, ``arnold:user_data_*`` and the pattern nodes) are read by
:mod:`usd_io.materials.arnold_patterns`; anything else upstream is ``Unsupported`` (one warning naming the node; the input's
value is used). A pattern node (or ``arnold:image``) connected as the surface itself is drawn as Arnold draws it: its
colour, unlit (as ``arnold:flat``).

Geometry without a material, on a stage written for Arnold (``usd_io.exporters.written_for_arnold``), is drawn with Arnold's
own fallback (:data:`DEFAULT_SURFACE`, ``MaterialTable.display_color``) instead of Hydra's plain displayColor: arnold-usd's reader
(``UsdArnoldReader::GetDefaultShader``) gives it a ``standard_surface`` with every default (base 0.8, specular 1 at
IOR 1.5, specular_roughness 0.2) whose ``base_color`` is a ``user_data_rgb`` reading ``displayColor``, white
without one.
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf, UsdShade

from . import network as net
from .arnold_patterns import PATTERNS, upstream

#: Arnold surface ids read as a MaterialX family (a key of ``usd_io.mtlx_surfaces.READERS``).
AS_MATERIALX = {"arnold:standard_surface": "standard_surface", "arnold:openpbr_surface": "open_pbr_surface"}
SIMPLE_SURFACES = ("arnold:lambert", "arnold:standard", "arnold:flat") + PATTERNS[1:] + ("arnold:image",)


def is_arnold(shader) -> bool:
    return net.shader_id(shader).startswith("arnold:")


def simple_surface(table, s, label: str, needs):
    """The PrincipledSurface of arnold:lambert / standard / flat; None for other ids."""
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
        if sid == "arnold:standard" and num("emission", 0.0) != 0.0:  # Arnold 4's standard: emission × colour
            em = num("emission", 0.0)
            src = net.source(s, "emission_color", (1.0, 1.0, 1.0), table.time)
            if isinstance(src, net.Const):
                src = net.Const(tuple(em * c for c in net.floats(src.value, 3, (1.0, 1.0, 1.0))))
            elif isinstance(src, net.TextureLookup):
                src.scale = tuple(em * c for c in src.scale[:3]) + (src.scale[3],)
            elif em != 1.0:
                table.warn(f"{label}: emission {em} × a connected emission_color: the colour is read unscaled")
            table._colour_input(t, "emission", src, (em, em, em), label, "emission_color", needs)
        ks = num("Ks", 0.0) if sid == "arnold:standard" else 0.0
        t.update(specular=float(np.clip(ks, 0.0, 1.0)), roughness=float(np.clip(num("specular_roughness", 0.467),
                                                                                  0.0, 1.0)), metallic=0.0)
        return t
    return None


#: Arnold's fallback surface (``UsdArnoldReader::GetDefaultShader``: standard_surface with its defaults) in the
#: reader's fields: base 0.8 × base_color (displayColor as vertex colour, white without one), Standard Surface's
#: specular 1 at IOR 1.5 (the Principled level 0.5) and specular_roughness 0.2, no metal.
DEFAULT_SURFACE = dict(base_color=(0.8, 0.8, 0.8), specular=0.5, roughness=0.2, ior=1.5, metallic=0.0)


#: Arnold render globals (``arnold:global:NAME`` on a RenderSettings prim, naming an ArnoldNodeGraph) that draw
#: something, and what this tracer does without them.
RENDER_GLOBALS = {"background": "rays that leave the scene see the stage's dome or background instead",
                  "atmosphere": "no participating medium is rendered"}


def render_globals(stage, prims, warn) -> None:
    """One warning per Arnold background/atmosphere shader a RenderSettings prim names (``arnold:global:background``
    = "/sky_graph", whose ``outputs:background`` is e.g. an ``arnold:physical_sky``): Arnold-only content this
    tracer does not draw. ``prims``: the stage's prims as the reader traversed them."""
    for prim in prims:
        if prim.GetTypeName() != "RenderSettings":
            continue
        a = prim.GetAttribute("arnold:global:aov_shaders")
        shaders = a.Get() if a else None
        if shaders:  # Arnold runs these on every surface (they may overwrite the beauty): not run here
            warn(f"{prim.GetPath()}: Arnold aov_shaders {shaders} are not run: the AOVs they write (and a beauty "
                 "they overwrite) show the surfaces' own shading")
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

"""Arnold nodes upstream of a surface input (``shade_network.source`` asks :func:`upstream`):

    arnold:image              a texture lookup: ``filename``; ``uvset`` (empty: the mesh's default UVs);
                              uv · (sscale, tscale) + (soffset, toffset); ``sflip``/``tflip`` (s → 1 − s);
                              ``multiply``/``offset`` as scale/bias; ``swrap``/``twrap`` (periodic → repeat,
                              clamp, mirror, black); ``color_space`` ("sRGB", "linear"/"Raw" → raw, else auto)
    arnold:user_data_rgb      a primvar read (``attribute``, fallback ``default``): vertex colour
    arnold:user_data_float    the same, one channel
    the pattern nodes below   a ``GraphLookup``: written into the material's shader graph (:mod:`tracer.shading.graph`)
                              through the same translator as MaterialX networks
                              (:class:`usd_io.materials.mtlx_graph.Translator`), which asks :func:`graph_node` for the value

Inputs take Arnold's defaults when unauthored; an input connected to another node reads that node (an Arnold
pattern, a MaterialX node); an output named ``r``/``g``/``b``/``a`` (or ``x``/``y``/``z``) is that lane.

    arnold:flat          its ``color`` (a flat shader used as a colour: Arnold's shaders are all connectable)
    arnold:checkerboard  s = 2·(u·u_frequency + u_offset), t = 2·(v·v_frequency + v_offset) (the ``uvset``'s UVs;
                         two cells per period): color2 where ⌊s⌋ + ⌊t⌋ is even, else color1 (as Arnold's
                         references show, test_1590 and test_0055: 2f cells per unit, color2 on the cell at the UV
                         origin; for an even cell count the same as color1 there with v flipped);
                         ``contrast`` c moves both colours towards their mean (c = 0: the mean). Not modelled:
                         ``filter_strength``/``filter_offset`` (Arnold's anti-aliasing of the edges)
    arnold:ramp_rgb      the keys ``position``/``color`` (ramp_float: ``value``) at a coordinate by ``type``: custom
    arnold:ramp_float    (the ``input``), u, v, diagonal ((u + v)/2), circular (2·distance from (0.5, 0.5)), box
                         (2·the larger of |u − 0.5|, |v − 0.5|); ``wrap_uvs``: the fraction. ``interpolation`` per
                         key: 0 constant, 1 linear, 2 smooth (catmull-rom), 3 b-spline; one ramp carries one
                         (the most common key's; one warning when they differ). Any other type: one warning, v
    arnold:color_correct ``input`` → gamma (c^(1/gamma)) → hue_shift (a fraction of a turn) and saturation (HSV) →
                         contrast about contrast_pivot → exposure (·2^exposure) → multiply → add → invert, mixed
                         with the input by ``mask``
    arnold:color_jitter  its ``input``, un-jittered (one warning): the random gain/hue/saturation per object, face
                         or user-data value come from Arnold's own hash, which is not published
    arnold:image         a texture lookup (:func:`image_lookup`); arnold:user_data_rgb/float a primvar

Any other Arnold node upstream reads as its input's fallback, named in one warning.
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf

from . import shade_types as net
from .shade_types import V

#: Arnold nodes :func:`graph_node` writes into the graph.
PATTERNS = ("arnold:flat", "arnold:checkerboard", "arnold:ramp_rgb", "arnold:ramp_float", "arnold:color_correct",
            "arnold:color_jitter")
#: ramp interpolation ids -> the tracer's rgb_ramp interpolation.
RAMP_INTERPOLATION = {0: "CONSTANT", 1: "LINEAR", 2: "CARDINAL", 3: "B_SPLINE"}
_LANES = {"r": 0, "g": 1, "b": 2, "a": 3, "x": 0, "y": 1, "z": 2}
#: arnold:image swrap/twrap -> UsdUVTexture wrap tokens.
_WRAP = {"periodic": "repeat", "clamp": "clamp", "mirror": "mirror", "black": "black", "file": "useMetadata"}


def upstream(node, output: str, fallback, time):
    """What an Arnold node upstream of an input reads as (TextureLookup, PrimvarLookup, GraphLookup for a pattern),
    or None (:func:`usd_io.materials.network.source` asks)."""
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


def _input(tr, view, name: str, t: str, default):
    """Input ``name`` as a value of type ``t``: the node it is connected to, its authored value, or ``default``."""
    r = view.input(name)
    if r is not None and r[0] == "link":
        return tr.cast(tr.out(r[1], r[2]), t)
    if r is not None and r[0] == "const":
        return tr.const(r[1], t)
    return tr.const(default, t)


def _uniform(view, name: str, default):
    r = view.input(name)
    return r[1] if r is not None and r[0] == "const" else default


def _uv(tr, view):
    return V("vector2", tr.uvmap(str(_uniform(view, "uvset", "") or "")))


def graph_node(tr, view, output: str):
    """The value (a ``mtlx_graph.V``) of output ``output`` of the Arnold node ``view`` (a ``mtlx_graph.UsdNode``)."""
    kind = view.sid.split(":", 1)[1]
    fn = _NODES.get(kind)
    if fn is None:
        v = _other(tr, view)
    else:
        v = fn(tr, view)
    if output in _LANES:
        return V("float", tr.lane(v, _LANES[output]))
    return v


def _other(tr, view):
    """An Arnold image or user-data node inside a pattern network, else one warning and black."""
    got = upstream(view.s, "rgb", (0.0, 0.0, 0.0), tr.time)
    if isinstance(got, net.TextureLookup):
        uvl, fallback = tr.table._texture(got, tr.label, view.name, tr.needs)
        if uvl is None:
            return tr.const(fallback, "color4")
        st = tr.uvmap(got.uv or "")
        if not np.allclose(uvl.transform, np.eye(3)):
            st = tr.add("usd_transform2d", {"in": st}, "result", matrix=np.asarray(uvl.transform))
        node = tr.add("usd_uv_texture", {"st": st}, image=uvl.image, scale=tuple(uvl.scale), bias=tuple(uvl.bias),
                      fallback=tuple(uvl.fallback), name=uvl.label)
        return V("color4", node["rgb"], node["a"])
    if isinstance(got, net.PrimvarLookup):
        default = net.floats(got.fallback, 3, (0.0, 0.0, 0.0))
        tr.needs.color = (got.name, default)
        return V("color3", tr.add("vertex_color", out="Color", layer_name=got.name))
    tr.warn(view.key, f"Arnold node {view.name} ({view.sid}) is not supported (read as black)")
    return tr.const((0.0, 0.0, 0.0), "color3")


def _flat(tr, view):
    return _input(tr, view, "color", "color3", (1.0, 1.0, 1.0))


def _checkerboard(tr, view):
    uv = _uv(tr, view)
    f = lambda name, d: _input(tr, view, name, "float", d).x  # noqa: E731
    s = tr.math("MULTIPLY_ADD", tr.lane(uv, 0), f("u_frequency", 1.0), f("u_offset", 0.0))
    t = tr.math("MULTIPLY_ADD", tr.lane(uv, 1), f("v_frequency", 1.0), f("v_offset", 0.0))
    # two cells per period: frequency f draws 2f cells per unit of UV (arnold-usd's test_1590, frequency 4 on a
    # 0..1 plane: 8 × 8 cells; test_0055, frequency 1: 2 × 2), color2 on the cell at the UV origin (both references)
    s, t = tr.math("MULTIPLY", s, 2.0), tr.math("MULTIPLY", t, 2.0)
    odd = tr.math("FLOORED_MODULO", tr.math("ADD", tr.math("ADD", tr.math("FLOOR", s), tr.math("FLOOR", t)), 1.0),
                  2.0)
    c1 = _input(tr, view, "color1", "color3", (1.0, 1.0, 1.0))
    c2 = _input(tr, view, "color2", "color3", (0.0, 0.0, 0.0))
    contrast = _input(tr, view, "contrast", "float", 1.0)
    if not (isinstance(contrast.x, float) and contrast.x == 1.0):
        mean = tr.mix("color3", c1, c2, V("float", 0.5))
        c1, c2 = tr.mix("color3", mean, c1, contrast), tr.mix("color3", mean, c2, contrast)
    return tr.mix("color3", c1, c2, V("float", odd))


def _ramp_coordinate(tr, view):
    """The ramp's lookup coordinate by its ``type``."""
    kind = str(_uniform(view, "type", "custom") or "custom")
    if kind == "custom":
        x = _input(tr, view, "input", "float", 0.0).x
    else:
        uv = _uv(tr, view)
        u, v = tr.lane(uv, 0), tr.lane(uv, 1)
        if str(_uniform(view, "wrap_uvs", False)).lower() in ("1", "true"):
            u, v = tr.math("FRACT", u), tr.math("FRACT", v)
        du, dv = tr.math("SUBTRACT", u, 0.5), tr.math("SUBTRACT", v, 0.5)
        if kind == "u":
            x = u
        elif kind == "diagonal":
            x = tr.math("MULTIPLY", tr.math("ADD", u, v), 0.5)
        elif kind == "circular":
            x = tr.math("MULTIPLY", tr.math("SQRT", tr.math("ADD", tr.math("MULTIPLY", du, du),
                                                             tr.math("MULTIPLY", dv, dv))), 2.0)
        elif kind == "box":
            x = tr.math("MULTIPLY", tr.math("MAXIMUM", tr.math("ABSOLUTE", du), tr.math("ABSOLUTE", dv)), 2.0)
        else:
            if kind != "v":
                tr.warn(view.key + "type", f"Arnold ramp {view.name}: type {kind!r} is not supported (read as 'v')")
            x = v
    return x


def _ramp(tr, view, values: str, t: str):
    pos = [float(p) for p in (_uniform(view, "position", None) or [])]
    vals = _uniform(view, values, None)
    vals = [] if vals is None else [tuple(net.floats(c, 3, (0.0, 0.0, 0.0))) for c in vals]
    n = min(len(pos), len(vals))
    if n == 0:
        tr.warn(view.key, f"Arnold ramp {view.name} has no keys (read as black)")
        return tr.const(0.0, t)
    interp = [int(i) for i in (_uniform(view, "interpolation", None) or [1] * n)][:n] or [1]
    common = max(set(interp), key=interp.count)
    if len(set(interp)) > 1:
        tr.warn(view.key + "interp", f"Arnold ramp {view.name}: keys with different interpolations "
                                     f"{sorted(set(interp))} are read with one ({common})")
    mode = RAMP_INTERPOLATION.get(common)
    if mode is None:
        tr.warn(view.key + "mode", f"Arnold ramp {view.name}: interpolation {common} is not supported (linear)")
        mode = "LINEAR"
    ramp = sorted(((pos[i], vals[i] + (1.0,)) for i in range(n)), key=lambda k: k[0])
    node = tr.add("rgb_ramp", {"Fac": _ramp_coordinate(tr, view)}, "Color", ramp=ramp, interpolation=mode)
    return tr.cast(V("color3", node), t)


def _color_correct(tr, view):
    x = _input(tr, view, "input", "color4", (0.0, 0.0, 0.0, 1.0))
    c = V("color3", x.x)
    f = lambda name, d: _input(tr, view, name, "float", d)  # noqa: E731
    gamma = f("gamma", 1.0)
    if not _is(gamma, 1.0):
        c = V("color3", tr.add("gamma", {"Color": c.x, "Gamma": tr.math("DIVIDE", 1.0, gamma.x)}, "Color"))
    hue, sat = f("hue_shift", 0.0), f("saturation", 1.0)
    if not (_is(hue, 0.0) and _is(sat, 1.0)):
        c = V("color3", tr.add("hsv", {"Color": c.x, "Hue": tr.math("ADD", hue.x, 0.5), "Saturation": sat.x,
                                       "Value": 1.0, "Fac": 1.0}, "Color"))
    contrast, pivot = f("contrast", 1.0), f("contrast_pivot", 0.18)
    if not _is(contrast, 1.0):
        c = tr._lanewise("color3", "ADD", tr._lanewise("color3", "MULTIPLY",
                                                       tr._lanewise("color3", "SUBTRACT", c, pivot), contrast), pivot)
    exposure = f("exposure", 0.0)
    if not _is(exposure, 0.0):
        c = tr._lanewise("color3", "MULTIPLY", c, V("float", tr.math("POWER", 2.0, exposure.x)))
    c = tr._lanewise("color3", "MULTIPLY", c, _input(tr, view, "multiply", "color3", (1.0, 1.0, 1.0)))
    c = tr._lanewise("color3", "ADD", c, _input(tr, view, "add", "color3", (0.0, 0.0, 0.0)))
    if str(_uniform(view, "invert", 0)).lower() in ("1", "true"):
        c = tr._lanewise("color3", "SUBTRACT", V("float", 1.0), c)
    mask = f("mask", 1.0)
    if not _is(mask, 1.0):
        c = tr.mix("color3", V("color3", x.x), c, mask)
    return V("color4", c.x, x.w)


def _color_jitter(tr, view):
    tr.warn(view.key, f"Arnold color_jitter {view.name}: the random jitter is not applied (Arnold's hash is not "
                      "published); its input is used")
    return _input(tr, view, "input", "color3", (0.0, 0.0, 0.0))


def _is(v, value: float) -> bool:
    return not hasattr(v.x, "node") and float(np.ravel(v.x)[0]) == value


_NODES = {"flat": _flat, "checkerboard": _checkerboard, "ramp_rgb": lambda tr, v: _ramp(tr, v, "color", "color3"),
          "ramp_float": lambda tr, v: _ramp(tr, v, "value", "float"), "color_correct": _color_correct,
          "color_jitter": _color_jitter}

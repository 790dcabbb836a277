"""The Principled field description of a surface (docs/materials-api.md's table columns, with texture lookups) as a
shader graph: how the front ends that describe a material by fields write the IR.

    graph = graph_from_fields(name, fields, texture)

``fields`` holds the table's columns by name (``base_color``, ``roughness``, ``metallic``, ``specular``, ``alpha``,
``alpha_threshold``, ``emission``, ``ior``, ``transmission``, ``transmission_tint``, ``normal_strength``,
``vertex_color``), and for a parameter P read from a texture ``P_texture`` (the front end's lookup object) and
``P_channel`` (−1 rgb — a scalar parameter then reads its luminance —, 0..3 one channel, a colour reads it as
grey). ``texture(graph, lookup)`` adds the lookup's node (a ``usd_uv_texture``: outputs r, g, b, a, rgb) and
returns (node, UV map name). The parameter is its constant × the lookup, as the table's texture columns defined it;
the normal map is a ``normal_map`` node fed value/2 + 1/2 (the lookup gives the tangent-space normal itself).
"""

from __future__ import annotations

import numpy as np

from .materials import PRINCIPLED_DEFAULTS as _P
from .shader_graph import Graph

#: Each field's value where ``fields`` leaves it out: the Principled BSDF's defaults (tracer.materials, Blender's),
#: emission being Emission Color × Emission Strength.
FIELD_DEFAULTS = {"base_color": _P["Base Color"], "roughness": _P["Roughness"], "metallic": _P["Metallic"],
                  "specular": _P["Specular IOR Level"], "alpha": _P["Alpha"], "ior": _P["IOR"],
                  "transmission": _P["Transmission Weight"],
                  "emission": tuple(c * _P["Emission Strength"] for c in _P["Emission Color"])}


def graph_from_fields(name: str, f: dict, texture=None, color_attribute: str = "", base_default=None) -> Graph:
    """One ``principled_bsdf`` graph of the fields ``f`` (module docstring); a field left out is its
    :data:`FIELD_DEFAULTS` value (``base_default``: a front end's own base colour, e.g. UsdPreviewSurface's)."""
    d = dict(FIELD_DEFAULTS, **({"base_color": base_default} if base_default is not None else {}))
    g = Graph(name)
    nodes: dict = {}

    def tex(lk):
        if id(lk) not in nodes:
            nodes[id(lk)] = texture(g, lk)
        return nodes[id(lk)]

    def value(key, colour):
        lk, ch = f[f"{key}_texture"], int(f.get(f"{key}_channel", -1))
        node = tex(lk)[0]
        if ch < 0:
            return node["rgb"]
        x = node["rgba"[ch]]
        return g.add("combine_color", {"Red": x, "Green": x, "Blue": x})["Color"] if colour else x

    def colour(key, default):
        const = tuple(float(x) for x in np.broadcast_to(np.asarray(f.get(key, default), np.float64), (3,)))
        if f.get(f"{key}_texture") is None:
            return const
        return g.add("vector_math", {"Vector": value(key, True), "Vector_001": const}, operation="MULTIPLY")["Vector"]

    def scalar(key, default):
        const = float(f.get(key, default))
        if f.get(f"{key}_texture") is None:
            return const
        return g.add("math", {"Value": value(key, False), "Value_001": const}, operation="MULTIPLY")["Value"]

    base = colour("base_color", d["base_color"])
    vc = f.get("vertex_color")
    if vc is not None and vc is not False:
        layer = color_attribute if vc is True else str(vc)
        col = g.add("vertex_color", layer_name=layer)["Color"]
        base = g.add("vector_math", {"Vector": base, "Vector_001": col}, operation="MULTIPLY")["Vector"]
    inputs = {"Base Color": base, "Roughness": scalar("roughness", d["roughness"]),
              "Metallic": scalar("metallic", d["metallic"]), "Specular IOR Level": scalar("specular", d["specular"]),
              "Alpha": scalar("alpha", d["alpha"]), "Emission Color": colour("emission", d["emission"]),
              "Emission Strength": 1.0, "IOR": float(f.get("ior", d["ior"])),
              "Transmission Weight": float(f.get("transmission", d["transmission"])),
              "Alpha Threshold": float(f.get("alpha_threshold", 0.0))}
    if f.get("normal_texture") is not None:
        node, uv_map = tex(f["normal_texture"])
        half = g.add("vector_math", {"Vector": node["rgb"], "Vector_001": (0.5, 0.5, 0.5),
                                     "Vector_002": (0.5, 0.5, 0.5)}, operation="MULTIPLY_ADD")["Vector"]
        inputs["Normal"] = g.add("normal_map", {"Color": half, "Strength": float(f.get("normal_strength", 1.0))},
                                 uv_map=uv_map)["Normal"]
    params = {}
    if f.get("transmission_tint") is not None:
        params["transmission_tint"] = tuple(float(x) for x in np.broadcast_to(f["transmission_tint"], (3,)))
    elif float(f.get("transmission", d["transmission"])) > 0:
        params["transmission_tint"] = (1.0, 1.0, 1.0)
    g.output(g.add("principled_bsdf", inputs, **params)["BSDF"])
    return g

"""A surface described as the Principled BSDF's inputs, some read from lookups, and the one function that writes it
as a shader graph (the IR of :mod:`tracer.shading.graph`, the one contract the compiler reads).

Front ends that read parameter-style surfaces (UsdPreviewSurface, MaterialX's Standard Surface / OpenPBR / glTF PBR /
Disney, Arnold's standard, OmniPBR: ``usd_io.materials``; the tracer API's texture columns: :func:`row_surface`)
fill one :class:`PrincipledSurface` and call :meth:`PrincipledSurface.graph`. Blender trees and MaterialX closure
networks write graphs themselves.

A parameter P read from a lookup (:meth:`PrincipledSurface.read`) is its constant × the lookup: a colour reads the
lookup's rgb, or one channel as grey; a scalar reads one channel, or the rgb's Rec.709 luminance. A lookup is any
object with ``write(g, memo) -> (outputs, uv_map)``: ``outputs[k]`` for k in "rgb", "r", "g", "b", "a" gives a
socket (or a constant), ``uv_map`` names the UV map a normal map's tangents follow, and ``memo`` is one dict per
graph the lookups may share state in (the USD reader's MaterialX translators). The normal map is the lookup
``normal``: its rgb is the tangent-space normal itself, fed to a ``normal_map`` node as value/2 + 1/2.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from .graph import Graph
from .materials import PRINCIPLED_DEFAULTS as _P, f0_from_ior

#: Parameters that may be read from a lookup, and which of them are colours.
LOOKUP_PARAMS = ("base_color", "roughness", "metallic", "specular", "alpha", "emission", "normal")
_COLOURS = ("base_color", "emission")


def _rgb(x) -> tuple:
    return tuple(float(v) for v in np.broadcast_to(np.asarray(x, np.float64), (3,)))


@dataclass(eq=False)
class PrincipledSurface:
    """The Principled BSDF's inputs (Blender's defaults, :data:`tracer.shading.materials.PRINCIPLED_DEFAULTS`),
    named as the material table names them, and what the BSDF has no input for:

    - ``emission``: Emission Color × Emission Strength;
    - ``vertex_color``: False, True (the colour primvar the caller names), or an attribute name; it multiplies
      the base colour;
    - ``transmission_tint``: the refracted colour (None: white, where there is transmission);
    - ``layers``: coats over the BSDF, top first (:func:`_layered`);
    - ``normal_graph``: a lookup whose ``value(g, memo).x`` is a world-space normal (a MaterialX normal network);
    - ``closure``: a lookup whose ``write(g, memo)`` is the whole surface closure (the parameters are then unused).
    """

    base_color: tuple = _P["Base Color"]
    roughness: float = _P["Roughness"]
    metallic: float = _P["Metallic"]
    specular: float = _P["Specular IOR Level"]
    specular_tint: tuple | None = None
    alpha: float = _P["Alpha"]
    alpha_threshold: float = 0.0
    emission: tuple = tuple(c * _P["Emission Strength"] for c in _P["Emission Color"])
    ior: float = _P["IOR"]
    transmission: float = _P["Transmission Weight"]
    transmission_tint: tuple | None = None
    sheen: float = 0.0
    sheen_tint: tuple = (1.0, 1.0, 1.0)
    sheen_roughness: float = 0.5
    normal_strength: float = 1.0
    vertex_color: bool | str = False
    layers: list = field(default_factory=list)
    normal_graph: object = None
    closure: object = None
    lookups: dict = field(default_factory=dict)  # parameter -> (lookup, channel: -1 rgb, 0..3 one channel)

    def update(self, **values) -> "PrincipledSurface":
        """Set several inputs by name (a name the surface has no input for is an error)."""
        names = {f.name for f in fields(self)}
        for k, v in values.items():
            if k not in names or k == "lookups":
                raise TypeError(f"PrincipledSurface has no input {k!r}")
            setattr(self, k, v)
        return self

    def read(self, param: str, lookup, channel: int = -1) -> None:
        """Read ``param`` from ``lookup`` (times its constant; the normal map replaces the normal)."""
        if param not in LOOKUP_PARAMS:
            raise ValueError(f"{param!r} cannot read a lookup (one of {', '.join(LOOKUP_PARAMS)})")
        self.lookups[param] = (lookup, int(channel))

    def lookup(self, param: str):
        """(lookup, channel) of ``param``, or None when it is a constant."""
        return self.lookups.get(param)

    def summary(self) -> dict:
        """What differs from the Principled defaults, for ``whitted info``: the inputs, each lookup as
        ``P_texture`` (its label) and ``P_channel``."""
        blank = PrincipledSurface()
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "lookups" or (not isinstance(v, (list, np.ndarray)) and v is getattr(blank, f.name)):
                continue
            if isinstance(v, list):
                if v:
                    out[f.name] = [dict(x) for x in v]
            elif f.name in ("closure", "normal_graph"):
                out[f.name] = repr(v)
            elif isinstance(v, (bool, str)):
                out[f.name] = v
            elif np.ndim(v):
                if not np.array_equal(v, getattr(blank, f.name)):
                    out[f.name] = tuple(round(float(x), 4) for x in np.ravel(v))
            elif v != getattr(blank, f.name):
                out[f.name] = round(float(v), 4)
        for p, (lk, ch) in self.lookups.items():
            out[f"{p}_texture"] = getattr(lk, "label", None) or repr(lk)
            if p != "normal":
                out[f"{p}_channel"] = ch
        return out

    # ------------------------------------------------------------------ the IR
    def graph(self, name: str, color_primvar: str = "displayColor") -> Graph:
        """This surface as one shader graph: a ``principled_bsdf`` (under its ``layers``), each lookup written
        once, a parameter read from a lookup as its constant × the lookup."""
        g = Graph(name)
        memo: dict = {}
        if self.closure is not None:
            g.output(self.closure.write(g, memo))
            return g
        written: dict = {}  # id(lookup) -> (outputs, uv_map): each lookup written once

        def outputs(lk):
            if id(lk) not in written:
                written[id(lk)] = lk.write(g, memo)
            return written[id(lk)]

        def value(param, colour):
            lk, ch = self.lookups[param]
            outs = outputs(lk)[0]
            if ch < 0:
                return outs["rgb"]
            x = outs["rgba"[ch]]
            return g.add("combine_color", {"Red": x, "Green": x, "Blue": x})["Color"] if colour else x

        def colour(param):
            const = _rgb(getattr(self, param))
            if param not in self.lookups:
                return const
            return g.add("vector_math", {"Vector": value(param, True), "Vector_001": const},
                         operation="MULTIPLY")["Vector"]

        def scalar(param):
            const = float(getattr(self, param))
            if param not in self.lookups:
                return const
            return g.add("math", {"Value": value(param, False), "Value_001": const}, operation="MULTIPLY")["Value"]

        base = colour("base_color")
        if self.vertex_color is not False and self.vertex_color is not None:
            layer = color_primvar if self.vertex_color is True else str(self.vertex_color)
            col = g.add("vertex_color", layer_name=layer)["Color"]
            base = g.add("vector_math", {"Vector": base, "Vector_001": col}, operation="MULTIPLY")["Vector"]
        inputs = {"Base Color": base, "Roughness": scalar("roughness"), "Metallic": scalar("metallic"),
                  "Specular IOR Level": scalar("specular"), "Alpha": scalar("alpha"),
                  "Emission Color": colour("emission"), "Emission Strength": 1.0, "IOR": float(self.ior),
                  "Transmission Weight": float(self.transmission), "Alpha Threshold": float(self.alpha_threshold)}
        if "normal" in self.lookups:
            outs, uv_map = outputs(self.lookups["normal"][0])
            half = g.add("vector_math", {"Vector": outs["rgb"], "Vector_001": (0.5, 0.5, 0.5),
                                         "Vector_002": (0.5, 0.5, 0.5)}, operation="MULTIPLY_ADD")["Vector"]
            inputs["Normal"] = g.add("normal_map", {"Color": half, "Strength": float(self.normal_strength)},
                                     uv_map=uv_map)["Normal"]
        if self.specular_tint is not None:
            inputs["Specular Tint"] = _rgb(self.specular_tint)
        if float(self.sheen or 0.0) > 0:  # the Principled sheen layer (tracer.shading.sheen, microfiber)
            inputs.update({"Sheen Weight": float(self.sheen), "Sheen Tint": _rgb(self.sheen_tint),
                           "Sheen Roughness": float(self.sheen_roughness)})
        params = {}
        if self.transmission_tint is not None:
            params["transmission_tint"] = _rgb(self.transmission_tint)
        elif float(self.transmission) > 0:
            params["transmission_tint"] = (1.0, 1.0, 1.0)
        bsdf = g.add("principled_bsdf", inputs, **params)
        if self.normal_graph is not None:  # a world-space normal network: the Principled BSDF's Normal
            g.link(self.normal_graph.value(g, memo).x, bsdf, "Normal")
        g.output(_layered(g, bsdf["BSDF"], self.layers, float(self.ior)))
        return g


def _layered(g: Graph, base, layers, ior: float):
    """``base`` under ``layers`` (top first), each as MaterialX's layer(top, base) = top + base·(1 − the top's
    albedo): a ``dielectric`` layer (weight, roughness, ior) is a Principled lobe with a black base whose Fresnel
    curve is the layer's IOR (its Specular IOR Level 0.5·F0(layer)/F0(ior) against the material's ``ior``, which
    the lobes share), the base weighted by 1 − weight·Fresnel(layer IOR, n·v); a ``glossy`` layer (weight, colour,
    roughness) a constant-Fresnel GGX lobe of that colour, the base weighted by 1 − weight·mean(colour)."""
    out = base
    for layer in reversed(list(layers)):
        w = float(np.clip(layer.get("weight", 1.0), 0.0, 1.0))
        if w <= 0:
            continue
        r = float(np.clip(layer.get("roughness", 0.0), 0.0, 1.0))
        if layer["kind"] == "dielectric":
            lior = float(layer.get("ior", 1.5))
            level = 0.5 * f0_from_ior(lior) / max(f0_from_ior(ior), 1e-9)
            top = g.add("principled_bsdf", {"Base Color": (0.0, 0.0, 0.0), "Metallic": 0.0, "Roughness": r,
                                            "Specular IOR Level": float(level), "IOR": ior})["BSDF"]
            fr = g.add("fresnel", {"IOR": lior})["Fac"]
            albedo = g.add("math", {"Value": fr, "Value_001": w}, operation="MULTIPLY")["Value"]
        else:
            colour = _rgb(layer.get("colour", (0.04,) * 3))
            top = g.add("glossy_bsdf", {"Color": colour, "Roughness": r})["BSDF"]
            albedo = w * float(np.mean(colour))
        keep = g.add("math", {"Value": 1.0, "Value_001": albedo}, operation="SUBTRACT")["Value"] \
            if not isinstance(albedo, float) else 1.0 - albedo
        under = g.add("mix_closure", {"Fac": keep, "Shader_001": out})["Shader"]
        above = g.add("mix_closure", {"Fac": w, "Shader_001": top})["Shader"] if w < 1 else top
        out = g.add("add_closure", {"Shader": above, "Shader_001": under})["Shader"]
    return out


# ---------------------------------------------------------------------------------------------- the table's lookups
class _TextureOutputs:
    """A ``scene_texture`` node's outputs as a lookup's: rgb is its Color, r/g/b a separate_color of it (written
    when asked), a its Alpha."""

    def __init__(self, g: Graph, node):
        self.g, self.node, self.split = g, node, None

    def __getitem__(self, key):
        if key == "rgb":
            return self.node["Color"]
        if key == "a":
            return self.node["Alpha"]
        if self.split is None:
            self.split = self.g.add("separate_color", {"Color": self.node["Color"]})
        return self.split[("Red", "Green", "Blue")["rgb".index(key)]]


@dataclass(frozen=True)
class SceneTextureLookup:
    """A lookup of ``Scene.textures[index]`` in UV set ``uv_set`` (the material table's ``P_texture`` columns)."""

    index: int
    uv_set: int = 0

    @property
    def label(self) -> str:
        return f"Scene.textures[{self.index}]"

    def write(self, g: Graph, memo: dict):
        return _TextureOutputs(g, g.add("scene_texture", index=self.index, uv_set=self.uv_set)), self.uv_set


def row_surface(m, i: int, textures: list) -> PrincipledSurface:
    """Row ``i`` of a :class:`tracer.Materials` table whose ``P_texture`` columns read textures, as a surface:
    the row's constants, each textured column read from its texture (vertex colour where the base colour is
    textured: an untextured row's vertex colour is the table's own column)."""
    tex, ch = m.texture_slots()
    s = PrincipledSurface(base_color=_rgb(m.diffuse[i]), roughness=float(m.roughness[i]),
                          metallic=float(m.metallic[i]), specular=float(m.specular[i]), alpha=float(m.alpha[i]),
                          emission=_rgb(m.emission[i]), normal_strength=float(m.normal_strength[i]),
                          vertex_color="" if tex[i, 0] >= 0 and m.vertex_color[i] else False)
    for j, param in enumerate(LOOKUP_PARAMS):
        if tex[i, j] >= 0:
            ti = int(tex[i, j])
            s.read(param, SceneTextureLookup(ti, int(textures[ti].uv_set)), int(ch[i, j]))
    return s

"""MaterialX closures (``BSDF``/``EDF``-typed nodes: MaterialX's pbrlib) written as the tracer's closure IR, so
that a surface built from them — pbrlib's ``surface`` node, the Lama layering nodes, a document's own surface
definitions, any node graph of BSDFs — renders instead of falling back to grey. Families with a reader of their
own (:mod:`usd_io.materials.mtlx_surfaces`) are read there; this is everything else.

Each node is read against its definition, as :mod:`usd_io.materials.mtlx_graph` reads value nodes (whose translator this
shares: colours, weights and roughness are IR values, constant or per hit); a closure node without a handler here
is expanded through its node-graph implementation (Lama's nodes, a document's ``<nodegraph nodedef=...>``), any
other warns once and contributes nothing. A closure comes back with an estimate of its directional albedo, which
``layer`` needs:

    oren_nayar_diffuse_bsdf, burley_diffuse_bsdf   Diffuse BSDF (color × weight; Lambert)            albedo: 0
    translucent_bsdf          Translucent BSDF                                                        0
    dielectric_bsdf           R: a Principled lobe with a black base, its Fresnel curve of ``ior``,   F(ior, n·v)
                              Specular Tint ``tint``; T: Refraction BSDF; RT: Glass BSDF (tint); as
                              the top of a layer its R part only (its transmission lights the base)
    conductor_bsdf            a Principled metal of F0 = the conductor's normal-incidence Fresnel of  F0
                              (ior, extinction) (its F82 tint white: Schlick's curve)
    generalized_schlick_bsdf  R: color90 = 1 a Principled metal of F0 = color0 (Schlick), else a     mean(color0)
                              Glossy BSDF of colour color0; T/RT: Glass BSDF tinted by color0
    sheen_bsdf                Sheen BSDF (microfiber), its albedo the lobe's mean albedo × colour
    thin film                 not rendered (one warning)
    subsurface_bsdf           Diffuse BSDF of its colour (one warning)
    layer(top, base)          top + base × (1 − albedo(top))                                         combined
    layer(top, VDF)           a surface over its interior medium: the top whole (its transmission     top's
                              rendered, unless it is itself a layer's top); the medium's absorption
                              and scattering are not rendered (one warning when they are not zero)
    mix(fg, bg, mix), add, multiply (by a float or colour)   Mix Shader / Add Shader (a colour factor by its mean)
    uniform_edf               Emission (color); other EDFs: their base or colour (one warning)
    surface(bsdf, edf, opacity)   bsdf + edf, mixed with Transparent by 1 − opacity

Roughness: MaterialX's BSDFs take α (the vector2 of roughness_anisotropy); the IR's is √α (α = r², as Cycles').
Anisotropy is rendered isotropic (the mean of the two α).
"""

from __future__ import annotations

import MaterialX as mx
import numpy as np

from tracer.shading import sheen

from . import mtlx
from .mtlx_graph import MxNode, Translator, UsdNode, _Ctx
from .shade_types import V


class Closures:
    """Writes the closures upstream of a surface shader into the material's graph, through ``tr`` (a
    :class:`usd_io.materials.mtlx_graph.Translator`)."""

    def __init__(self, tr):
        self.tr, self.g = tr, tr.g
        self._cache: dict = {}
        self.on_top = 0  # > 0 while the top of a layer is written: its transmission feeds the base (R only)

    # ------------------------------------------------------------------ plumbing
    def add_closures(self, a, b):
        if a is None:
            return b
        if b is None:
            return a
        return self.tr.add("add_closure", {"Shader": a, "Shader_001": b}, "Shader")

    def scaled(self, out, w):
        """Closure ``out`` × weight ``w`` (a float or an IR float)."""
        if out is None:
            return None
        if not hasattr(w, "node"):
            w = float(w)
            if w == 1.0:
                return out
            if w <= 0.0:
                return None
        return self.tr.add("mix_closure", {"Fac": w, "Shader_001": out}, "Shader")

    def fmul(self, a, b):
        if not hasattr(a, "node") and not hasattr(b, "node"):
            return float(a) * float(b)
        return self.tr.math("MULTIPLY", a, b)

    def fadd(self, a, b):
        if not hasattr(a, "node") and not hasattr(b, "node"):
            return float(a) + float(b)
        return self.tr.math("ADD", a, b)

    def one_minus(self, a):
        return 1.0 - float(a) if not hasattr(a, "node") else self.tr.math("SUBTRACT", 1.0, a)

    def mean3(self, v: V):
        """The mean of a colour (a float stays)."""
        if v.wide == 1:
            return v.x
        if not hasattr(v.x, "node"):
            return float(np.mean(v.x))
        return self.tr.math("MULTIPLY", self.tr.vmath("DOT_PRODUCT", v.x, (1.0, 1.0, 1.0), out="Value"), 1 / 3)

    def roughness(self, c, name="roughness"):
        """√α of a vector2 roughness (the mean of its two lanes)."""
        v = c.i(name, "vector2")
        a = v.x
        if not hasattr(a, "node"):
            return float(np.sqrt(max(0.5 * (a[0] + a[1]), 0.0)))
        mean = self.tr.math("MULTIPLY", self.tr.math("ADD", self.tr.lane(v, 0), self.tr.lane(v, 1)), 0.5)
        return self.tr.math("SQRT", self.tr.math("MAXIMUM", mean, 0.0))

    def closure_input(self, c, name):
        """(IR closure or None, albedo estimate) of a BSDF/EDF input of node ``c`` (through node-graph
        interfaces to the outer node's input)."""
        r = c.view.input(name)
        while r is not None and r[0] == "outer":
            r = r[1].input(r[2])
        if r is None or r[0] != "link":
            return None, 0.0
        return self.node(r[1], r[2])

    # ------------------------------------------------------------------ nodes
    def node(self, view, output: str = "out"):
        """(IR closure or None, albedo estimate) of a closure node's output."""
        key = (view.key, output, self.on_top > 0)
        if key in self._cache:
            return self._cache[key]
        nd = mtlx.nodedef(view.sid)
        got = (None, 0.0)
        if nd is None:
            self.tr.warn(view.key, f"MaterialX closure {view.name} ({view.sid}) has no node definition (nothing "
                                   "rendered)")
        else:
            fn = getattr(self, f"_c_{nd.getNodeString()}", None)
            c = _Ctx(self.tr, view, nd)
            if fn is not None:
                got = fn(c)
            else:
                impl = nd.getImplementation()
                go = None
                if isinstance(impl, mx.NodeGraph):
                    go = impl.getOutput(output) or (impl.getOutputs()[0] if impl.getOutputs() else None)
                inner = impl.getNode(go.getNodeName()) if go is not None and go.getNodeName() else None
                if inner is not None:
                    got = self.node(MxNode(inner, view), go.getOutputString() or "out")
                else:
                    self.tr.warn(view.key, f"MaterialX closure {view.name} ({nd.getName()}) is not supported "
                                           "(nothing rendered)")
        self._cache[key] = got
        return got

    def _c_surface(self, c):
        bsdf, alb = self.closure_input(c, "bsdf")
        edf, _a = self.closure_input(c, "edf")
        out = self.add_closures(bsdf, edf)
        op = c.f("opacity")
        if not hasattr(op, "node") and float(op) >= 1.0:
            return out, alb
        clear = self.tr.add("transparent_bsdf", {"Color": (1.0, 1.0, 1.0)}, "BSDF")
        return self.tr.add("mix_closure", {"Fac": op, "Shader": clear, "Shader_001": out}, "Shader"), alb

    def _c_surface_unlit(self, c):
        """MaterialX's OSL mx_surface_unlit (the ray-traced implementation): with t = clamp(transmission, 0, 1),
        (1 − t) · emission · emission_color emitted and t · transmission_color passing through; ``opacity`` mixes
        the whole with a clear surface."""
        e = self.tr.lanes3(c.i("emission_color"))
        tw = c.f("transmission")
        varies = hasattr(tw, "node")
        tw = self.tr.math("MINIMUM", self.tr.math("MAXIMUM", tw, 0.0), 1.0) if varies else \
            float(np.clip(float(tw), 0.0, 1.0))
        out = self.tr.add("emission", {"Color": e, "Strength": self.fmul(c.f("emission"), self.one_minus(tw))},
                          "Emission")
        if varies or tw > 0:
            col = self.tr.vmath("MULTIPLY", self.tr.lanes3(c.i("transmission_color")), self.tr._splat(tw))
            out = self.add_closures(out, self.tr.add("transparent_bsdf", {"Color": col}, "BSDF"))
        op = c.f("opacity")
        if hasattr(op, "node") or float(op) < 1.0:
            clear = self.tr.add("transparent_bsdf", {"Color": (1.0, 1.0, 1.0)}, "BSDF")
            out = self.tr.add("mix_closure", {"Fac": op, "Shader": clear, "Shader_001": out}, "Shader")
        return out, 0.0

    def _diffuse(self, c):
        out = self.tr.add("diffuse_bsdf", {"Color": self.tr.lanes3(c.i("color"))}, "BSDF")
        return self.scaled(out, c.f("weight")), 0.0

    _c_oren_nayar_diffuse_bsdf = _c_burley_diffuse_bsdf = _diffuse

    def _c_translucent_bsdf(self, c):
        out = self.tr.add("translucent_bsdf", {"Color": self.tr.lanes3(c.i("color"))}, "BSDF")
        return self.scaled(out, c.f("weight")), 0.0

    def _c_subsurface_bsdf(self, c):
        self.tr.warn(c.view.key, f"MaterialX {c.view.name}: subsurface is rendered as a diffuse surface of its colour")
        return self._diffuse(c)

    def _c_sheen_bsdf(self, c):
        """The tracer's Sheen BSDF (microfiber: Zeltner et al., MaterialX's own default mode); its albedo for a
        layer: weight × mean(colour) × the lobe's mean albedo at its roughness."""
        col, r, w = c.i("color"), c.f("roughness"), c.f("weight")
        out = self.tr.add("sheen_bsdf", {"Color": self.tr.lanes3(col), "Roughness": r}, "BSDF",
                          distribution="MICROFIBER")
        e = sheen.mean_albedo(sheen.MICROFIBER, float(r)) if not hasattr(r, "node") else 0.15
        return self.scaled(out, w), self.fmul(self.fmul(self.mean3(col), e), w)

    def _c_chiang_hair_bsdf(self, c):
        self.tr.warn(c.view.key, f"MaterialX {c.view.name}: hair BSDFs are not rendered")
        return None, 0.0

    def _thin_film(self, c):
        if c.has("thinfilm_thickness"):
            t = c.f("thinfilm_thickness")
            if hasattr(t, "node") or float(t) > 0:
                self.tr.warn(c.view.key + "tf", f"MaterialX {c.view.name}: thin-film interference is not rendered")

    def _c_dielectric_bsdf(self, c):
        self._thin_film(c)
        w, r = c.f("weight"), self.roughness(c)
        ior = c.f("ior")  # a network: the shader compiler reads its constant estimate (one warning there)
        if not hasattr(ior, "node"):
            ior = float(ior) if float(ior) > 0 else 1.5
        tint = self.tr.lanes3(c.i("tint"))
        mode = str(c.uniform("scatter_mode", "R"))
        if mode == "T" and self.on_top:  # transmission through a layer's top is the base's light: nothing here
            return None, 0.0
        if mode == "R" or self.on_top:
            out = self.tr.add("principled_bsdf", {"Base Color": (0.0, 0.0, 0.0), "Metallic": 0.0, "Roughness": r,
                                                  "Specular IOR Level": 0.5, "IOR": ior,
                                                  "Specular Tint": tint if not hasattr(tint, "node") else
                                                  (1.0, 1.0, 1.0)}, "BSDF")
            fr = self.tr.add("fresnel", {"IOR": ior}, "Fac")
            return self.scaled(out, w), self.fmul(fr, w)
        kind = "refraction_bsdf" if mode == "T" else "glass_bsdf"
        out = self.tr.add(kind, {"Color": tint, "Roughness": r, "IOR": ior}, "BSDF")
        return self.scaled(out, w), 1.0

    def _c_conductor_bsdf(self, c):
        self._thin_film(c)
        w, r = c.f("weight"), self.roughness(c)
        n, k = c.i("ior", "color3"), c.i("extinction", "color3")
        if hasattr(n.x, "node") or hasattr(k.x, "node"):
            f0 = self._f0_network(n, k)
        else:
            nn, kk = np.asarray(n.x, np.float64), np.asarray(k.x, np.float64)
            f0 = tuple(float(x) for x in ((nn - 1) ** 2 + kk ** 2) / np.maximum((nn + 1) ** 2 + kk ** 2, 1e-9))
        out = self.tr.add("principled_bsdf", {"Base Color": f0, "Metallic": 1.0, "Roughness": r}, "BSDF")
        alb = float(np.mean(f0)) if not hasattr(f0, "node") else 0.9
        return self.scaled(out, w), self.fmul(alb, w)

    def _f0_network(self, n: V, k: V):
        """((n − 1)² + k²)/((n + 1)² + k²) lane by lane in the IR."""
        tr = self.tr
        nm = tr.vmath("SUBTRACT", n.x, (1.0, 1.0, 1.0))
        np_ = tr.vmath("ADD", n.x, (1.0, 1.0, 1.0))
        k2 = tr.vmath("MULTIPLY", k.x, k.x)
        top = tr.vmath("ADD", tr.vmath("MULTIPLY", nm, nm), k2)
        bottom = tr.vmath("ADD", tr.vmath("MULTIPLY", np_, np_), k2)
        return tr.vmath("DIVIDE", top, bottom)

    def _c_generalized_schlick_bsdf(self, c):
        self._thin_film(c)
        w, r = c.f("weight"), self.roughness(c)
        c0, c90 = c.i("color0"), c.i("color90")
        mode = str(c.uniform("scatter_mode", "R"))
        col0 = self.tr.lanes3(c0)
        if mode != "R":
            kind = "refraction_bsdf" if mode == "T" else "glass_bsdf"
            out = self.tr.add(kind, {"Color": col0, "Roughness": r, "IOR": 1.5}, "BSDF")
            return self.scaled(out, w), 1.0
        white90 = not hasattr(c90.x, "node") and np.allclose(c90.x, 1.0)
        if white90:  # Schlick from color0 to white: the Principled metal's Fresnel with a white F82 tint
            out = self.tr.add("principled_bsdf", {"Base Color": col0, "Metallic": 1.0, "Roughness": r}, "BSDF")
        else:
            if not (not hasattr(c90.x, "node") and np.allclose(c90.x, c0.x if not hasattr(c0.x, "node") else -1)):
                self.tr.warn(c.view.key + "90", f"MaterialX {c.view.name}: color90 is rendered as color0 (a "
                                                "constant Fresnel)")
            out = self.tr.add("glossy_bsdf", {"Color": col0, "Roughness": r}, "BSDF")
        return self.scaled(out, w), self.fmul(self.mean3(c0), w)

    def upstream(self, c, name):
        """(view, output) of the node feeding input ``name`` of ``c`` (through node-graph interfaces), or None."""
        r = c.view.input(name)
        while r is not None and r[0] == "outer":
            r = r[1].input(r[2])
        return (r[1], r[2]) if r is not None and r[0] == "link" else None

    def _medium(self, c, view) -> None:
        """A VDF under a transmissive surface (its interior): named in one warning when it absorbs or scatters."""
        nd = mtlx.nodedef(view.sid)
        if nd is None:
            return
        m = _Ctx(self.tr, view, nd)
        for name in ("absorption", "scattering"):
            if m.has(name):
                v = m.i(name, "vector3").x
                if hasattr(v, "node") or np.any(np.abs(np.asarray(v, np.float64)) > 0):
                    self.tr.warn(view.key, f"MaterialX {view.name}: the interior medium ({nd.getNodeString()}, its "
                                           "absorption and scattering) is not rendered (the surface over it is)")
                    return

    def _c_layer(self, c):
        up = self.upstream(c, "base")
        nd = mtlx.nodedef(up[0].sid) if up is not None else None
        if nd is not None and nd.getType() == "VDF":
            # a surface over its interior medium (MaterialX: a transmissive dielectric_bsdf layered over a VDF):
            # the top whole, its transmission included — unless this is itself the top of a layer, whose
            # transmission is the light that reaches that layer's base
            self._medium(c, up[0])
            return self.closure_input(c, "top")
        self.on_top += 1
        try:
            top, a_top = self.closure_input(c, "top")
        finally:
            self.on_top -= 1
        base, a_base = self.closure_input(c, "base")
        if top is None:
            return base, a_base
        under = self.scaled(base, self.one_minus(a_top)) if base is not None else None
        return self.add_closures(top, under), self.fadd(a_top, self.fmul(self.one_minus(a_top), a_base))

    def _c_mix(self, c):
        fg, a_fg = self.closure_input(c, "fg")
        bg, a_bg = self.closure_input(c, "bg")
        f = c.f("mix")
        if fg is None and bg is None:
            return None, 0.0
        out = self.tr.add("mix_closure", {"Fac": f, "Shader": bg, "Shader_001": fg}, "Shader")
        return out, self.fadd(self.fmul(self.one_minus(f), a_bg), self.fmul(f, a_fg))

    def _c_add(self, c):
        a, aa = self.closure_input(c, "in1")
        b, ab = self.closure_input(c, "in2")
        return self.add_closures(a, b), self.fadd(aa, ab)

    def _c_multiply(self, c):
        a, aa = self.closure_input(c, "in1")
        k = c.i("in2")
        if k.wide > 1 and not (not hasattr(k.x, "node") and np.ptp(k.x) < 1e-6):
            self.tr.warn(c.view.key, f"MaterialX {c.view.name}: a closure times a colour is rendered times its mean")
        m = self.mean3(k)
        return self.scaled(a, m), self.fmul(aa, m)

    def _c_uniform_edf(self, c):
        return self.tr.add("emission", {"Color": self.tr.lanes3(c.i("color")), "Strength": 1.0}, "Emission"), 0.0

    def _edf_base(self, c):
        self.tr.warn(c.view.key, f"MaterialX {c.view.name}: rendered as a uniform emitter")
        if c.has("base"):
            return self.closure_input(c, "base")
        return self._c_uniform_edf(c)

    _c_conical_edf = _c_measured_edf = _c_generalized_schlick_edf = _edf_base


class MxClosureProgram:
    """A material whose surface is a closure network (the ``closure`` field of
    :meth:`tracer.shading.principled.PrincipledSurface.graph`): ``write(g, translators)`` returns the surface's IR closure."""

    def __init__(self, table, shader, label: str, needs):
        self.table, self.shader, self.label, self.needs = table, shader, label, needs
        self.label_text = f"MaterialX closures of {shader.GetPath()}"

    def __repr__(self):
        return self.label_text

    def write(self, g, translators: dict):
        key = id(self.table)
        if key not in translators:
            translators[key] = Translator(self.table, g, self.label, self.needs, self.table.time)
        tr = translators[key]
        out, _alb = Closures(tr).node(UsdNode(self.shader, self.table.time), "out")
        return out

"""The closure side of the shader compiler: a material's Mix Shader / Add Shader tree as a weighted list of lobes,
lowered to the tracer's closure inputs and, where one closure cannot hold it, to lobe slots (:mod:`tracer.shading.lobes`).

1. **Closures flatten** into a weighted list of lobes: ``mix_closure`` (Fac) gives (1 − Fac)·A + Fac·B,
   ``add_closure`` A + B, to any depth; weights are values like any other (constant or per hit).
2. **Each lobe** is read as a Principled set (for the one-closure outputs) and a lobe kind (for the slots):

   ============== ===================================================================================
   principled     its inputs (emission = Emission Color × Strength; Alpha mixes with transparency)
                  Coat Weight > 0: two lobes, the BSDF under its coat (:meth:`ClosureLowering._coated`)
   diffuse        base = Color, specular 0, roughness 1                        (slot DIFFUSE)
   glossy         base = Color, metallic 1, roughness (Anisotropy: the hit's ``aniso``), specular 1 for Multiscatter GGX,
                  0 for single scattering (GGX, Beckmann, Ashikhmin-Shirley)  (slot GLOSSY)
   glass          transmission 1, reflection and refraction tinted by Color, ior, roughness (GGX sampled)
                                                                                (slot GLASS)
   refraction     as glass without its reflection                               (slot REFRACTION)
   translucent    as diffuse, lit from behind                                   (slot TRANSLUCENT)
   sheen          Sheen BSDF (microfiber / Ashikhmin, tracer.shading.sheen)     (slot SHEEN)
                  blended as a diffuse of Color × its mean albedo; a Principled BSDF's Sheen Weight adds a
                  SHEEN slot of weight × Sheen Tint after its own, which lays it over the Principled lobe
   transparent    coverage: its weight × Color passes straight through
   emission       emission += weight × Color × Strength, reflects nothing
   holdout        a black, opaque surface; its weight is the hit's ``holdout`` (tracer.integrator.compose: alpha)
   ============== ===================================================================================

3. **The one-closure outputs** (:data:`tracer.shading.nodes.OUTPUTS`) blend the lobes' parameters: transparency
   T = Σ transparent weights × mean(Color) + Σ wᵢ(1 − alphaᵢ); alpha = 1 − T; emission = Σ wᵢ·Eᵢ / alpha (the
   tracer adds emission × alpha); the reflecting lobes' weights sᵢ = wᵢ·alphaᵢ give base = Σ sᵢ·baseᵢ / alpha,
   specular level likewise, roughness, metallic and transmission as sᵢ-weighted means. Exact for one lobe with
   transparency or emission; they are what AOVs, coverage, shadows through the surface and emission read.
4. **Lobe slots** (:func:`ClosureLowering.slots`): a tree with two or more reflecting lobes, or a Glossy,
   Translucent, Refraction, Holdout or tinted Transparent leaf, also gets up to :data:`tracer.shading.lobes.MAX_LOBES`
   slots of (kind, weight RGB, colour, roughness, metallic, specular, transmission), the pass-through colour
   Σ transparent wⱼ·Colorⱼ + Σ wᵢ(1 − alphaᵢ) and the holdout weight, which the direct-light and spawn stages use
   in place of the blended closure. More reflecting lobes than slots: the lightest are merged into one Principled
   lobe of blended parameters (one warning).
"""

from __future__ import annotations

import numpy as np

from . import lobes as L, ops
from . import sheen as _sheen
from .graph import Node, Out
from .nodes import FLOAT, IN_INCOMING, IN_NORMAL, VECTOR, is_const, radial_tangent, vec3

_KIND = {"principled_bsdf": L.PRINCIPLED, "diffuse_bsdf": L.DIFFUSE, "glossy_bsdf": L.GLOSSY, "glass_bsdf": L.GLASS,
         "refraction_bsdf": L.REFRACTION, "translucent_bsdf": L.TRANSLUCENT, "sheen_bsdf": L.SHEEN}
#: Sheen BSDF distribution -> the SHEEN slot's P_METAL (tracer.shading.sheen).
_SHEEN_DIST = {"MICROFIBER": _sheen.MICROFIBER, "ASHIKHMIN": _sheen.ASHIKHMIN}


class LobeSlots:
    """A material's lobe slots as registers: ``kinds`` (MAX_LOBES,) int32 (-1: unused), ``regs`` (MAX_LOBES, 6)
    the registers of weight (3), colour (3), roughness, metallic, specular, transmission; ``extra`` (2,) the
    registers of the pass-through colour (3) and the holdout weight."""

    def __init__(self, kinds, regs, extra, live):
        self.kinds, self.regs, self.extra, self.live = kinds, regs, extra, live


class ClosureLowering:
    """The closure methods of :class:`tracer.shading.compiler.Compiler`."""

    def closure(self, ref, weight=1.0) -> list:
        """[(weight, lobe node)] of a closure output (a flattened Mix / Add Shader tree)."""
        if ref is None:
            return []
        node = self.g.node(ref)
        if node.type == "mix_closure":
            f = self.inp(node, "Fac", FLOAT)
            if is_const(f):
                f = min(max(float(f), 0.0), 1.0)
            a, b = (self.g.input_value(node, s) for s in ("Shader", "Shader_001"))
            wa = self.math(ops.M_MULTIPLY, weight, self.math(ops.M_SUBTRACT, 1.0, f))
            wb = self.math(ops.M_MULTIPLY, weight, f)
            out = []
            if not (is_const(wa) and wa == 0.0):
                out += self.closure(a, wa)
            if not (is_const(wb) and wb == 0.0):
                out += self.closure(b, wb)
            return out
        if node.type == "add_closure":
            return sum((self.closure(self.g.input_value(node, s), weight) for s in ("Shader", "Shader_001")), [])
        if node.type == "principled_bsdf":
            cw = self.inp(node, "Coat Weight")
            if not (is_const(cw) and float(cw) <= 0.0):
                return self._coated(node, weight, cw)
        return [(weight, node)]

    def _coated(self, node: Node, weight, cw) -> list:
        """A Principled BSDF with a coat, as Cycles' ``principled_bsdf_emission`` layers it: the BSDF (weight
        W·(1 − c·F_coat(μ)), its colour × mix(1, Coat Tint^(1/cos θ_t), c)) under a dielectric GGX lobe of weight
        W·c (Coat Roughness, Coat IOR: a Principled lobe with a black base whose Specular IOR Level gives the coat's
        F0 against the BSDF's IOR, as :func:`tracer.shading.principled._layered` writes MaterialX coats). F_coat is
        Cycles' estimate of the coat's albedo at the view angle (:func:`tracer.shading.bsdf.dielectric_albedo`, on
        the valid specular-reflection normal). The lobes share one normal: a linked Coat Normal is used only where
        Normal is not linked (else the warning of differing normals)."""
        m = self.math
        cw = self.math(ops.M_MINIMUM, cw, 1.0) if not is_const(cw) else min(float(cw), 1.0)
        lb = self.lobe(node)
        cior = max(self._const_in(node, "Coat IOR", 1.5), 1.0)
        cn = self._normal_in_named(node, "Coat Normal")
        normal = cn if cn is not None else lb["normal"]
        nrm = normal if normal is not None else self.hit(IN_NORMAL)
        if self.estimate:
            fr = ((cior - 1.0) / (cior + 1.0)) ** 2
        else:
            fr = self.op("fresnel", [(cior, 1), (nrm, 3), (self.inp(node, "Coat Roughness"), 1)], imm=2)
        base_w = m(ops.M_MULTIPLY, weight, m(ops.M_SUBTRACT, 1.0, m(ops.M_MULTIPLY, cw, fr)))
        tint = self.inp(node, "Coat Tint")
        if not (is_const(tint) and vec3(tint) == (1.0, 1.0, 1.0)):
            if self.estimate:
                cos_t = 1.0
            else:
                cos_i = self.vmath(ops.V_DOT_PRODUCT, self.hit(IN_INCOMING), nrm)[1]
                sin2 = m(ops.M_MULTIPLY, m(ops.M_SUBTRACT, 1.0, m(ops.M_MULTIPLY, cos_i, cos_i)), 1.0 / (cior * cior))
                cos_t = m(ops.M_SQRT, m(ops.M_MAXIMUM, m(ops.M_SUBTRACT, 1.0, sin2), 1e-6))
            depth = m(ops.M_DIVIDE, 1.0, cos_t)
            t = self.vmath(ops.V_MAXIMUM, tint)[0]
            t = self.vmath(ops.V_POWER, t, self.convert(depth, FLOAT, VECTOR))[0]
            t = self.lerp3((1.0, 1.0, 1.0), t, cw)
            lb = dict(lb, base=self.mul3(lb["base"], t), colour=self.mul3(lb["colour"], t))
        if lb["normal"] is None and cn is not None:
            lb["normal"] = cn
        ior = float(lb["ior"]) if is_const(lb["ior"]) else 1.5
        f0 = ((ior - 1.0) / (ior + 1.0)) ** 2
        level = 0.5 * ((cior - 1.0) / (cior + 1.0)) ** 2 / max(f0, 1e-9)
        coat = dict(lb, base=(0.0, 0.0, 0.0), colour=(0.0, 0.0, 0.0), metallic=0.0, transmission=0.0,
                    roughness=self.inp(node, "Coat Roughness"), specular=level, emission=(0.0, 0.0, 0.0),
                    normal=normal, sheen=None, lk=L.PRINCIPLED, tint=None)
        return [(base_w, lb), (m(ops.M_MULTIPLY, weight, cw), coat)]

    def lobe(self, node: Node) -> dict:
        """The Principled set of one lobe: base, roughness, metallic, specular, transmission, alpha, emission,
        normal (values), and constants ior, tint, specular_tint, threshold; ``kind`` (surface, transparent,
        emission, holdout), ``lk`` its slot kind (:mod:`tracer.shading.lobes`, None: no slot), ``colour`` (the slot's
        colour), ``through`` (a transparent lobe's Color)."""
        t = node.type
        zero3 = (0.0, 0.0, 0.0)
        lb = dict(kind="surface", base=zero3, roughness=0.5, metallic=0.0, specular=0.0, transmission=0.0, alpha=1.0,
                  emission=zero3, normal=None, ior=1.5, tint=None, specular_tint=(1.0, 1.0, 1.0), threshold=0.0,
                  lk=_KIND.get(t), colour=zero3, through=zero3)
        if t == "principled_bsdf":
            lb.update(base=self.inp(node, "Base Color"), roughness=self.inp(node, "Roughness"),
                      metallic=self.inp(node, "Metallic"), specular=self.inp(node, "Specular IOR Level"),
                      transmission=self.inp(node, "Transmission Weight"), alpha=self.inp(node, "Alpha"),
                      emission=self.scale3(self.inp(node, "Emission Color"), self.inp(node, "Emission Strength")),
                      normal=self._normal_in(node), ior=self._const_in(node, "IOR", 1.5),
                      threshold=self._const_in(node, "Alpha Threshold", 0.0))
            lb["colour"] = lb["base"]
            st = self.g.input_value(node, "Specular Tint")
            if isinstance(st, Out):
                self.warn(node.name + "st", f"Principled BSDF {node.name!r}: a linked Specular Tint is read as white")
            else:
                lb["specular_tint"] = vec3(st)
            w = self.g.input_value(node, "Subsurface Weight")
            if isinstance(w, Out) or float(w) > 0:  # Blender 4+: subsurface replaces the diffuse, same colour
                self.warn(node.name + "Subsurface", f"Principled BSDF {node.name!r}: subsurface scattering is "
                          "rendered as diffuse reflection of the Base Color (the scattering radius is not modelled)")
            w = self.g.input_value(node, "Sheen Weight")
            if isinstance(w, Out) or float(w) > 0:  # the sheen layer: a SHEEN slot after this lobe (outputs)
                lb["sheen"] = (self.inp(node, "Sheen Weight"), self.inp(node, "Sheen Tint"),
                               self.inp(node, "Sheen Roughness"))
            tint = node.params.get("transmission_tint")
            if tint is not None:
                lb["tint"] = vec3(tint)
            lb["aniso"] = self.anisotropy(node, "Anisotropic", "Anisotropic Rotation", lb["normal"], glossy=False)
            lb["multiscatter"] = (node.params.get("distribution") or "MULTI_GGX") == "MULTI_GGX"
        elif t == "sheen_bsdf":
            dist = _SHEEN_DIST.get(node.params.get("distribution") or "MICROFIBER", _sheen.MICROFIBER)
            lb.update(self._sheen_lobe(self.inp(node, "Color"), self.inp(node, "Roughness"), dist, layer=False),
                      normal=self._normal_in(node))
        elif t in ("diffuse_bsdf", "translucent_bsdf"):
            lb.update(base=self.inp(node, "Color"), roughness=1.0, normal=self._normal_in(node))
            lb["colour"] = lb["base"]
        elif t == "glossy_bsdf":
            # P_SPEC: multiscatter GGX (1) or single scattering (0: Cycles' GGX loses the light that scatters twice)
            multi = (node.params.get("distribution") or "MULTI_GGX") == "MULTI_GGX"
            lb.update(base=self.inp(node, "Color"), metallic=1.0, roughness=self.inp(node, "Roughness"),
                      specular=1.0 if multi else 0.0, normal=self._normal_in(node))
            lb["colour"] = lb["base"]
            lb["aniso"] = self.anisotropy(node, "Anisotropy", "Rotation", lb["normal"], glossy=True)
        elif t in ("glass_bsdf", "refraction_bsdf"):
            r = self.inp(node, "Roughness")  # rough: microfacets sampled per ray (tracer.optics.rough_dielectric)
            col = self.g.input_value(node, "Color")
            if isinstance(col, Out):
                self.warn(node.name + "c", f"{node.name!r}: a linked glass colour is read as its constant estimate")
            colour = vec3(self._estimate_of(node, "Color")) if isinstance(col, Out) else vec3(col)
            lb.update(base=colour, transmission=1.0, roughness=r, specular=0.5, ior=self._const_in(node, "IOR", 1.5),
                      tint=colour, normal=self._normal_in(node), colour=colour)
            if t == "glass_bsdf":  # Cycles' Glass BSDF tints its Fresnel reflection by Color too (Refraction has none)
                lb["specular_tint"] = colour
            # Multiscatter GGX keeps the energy; GGX, Beckmann and the Refraction BSDF are single scattering
            lb["multiscatter"] = (node.params.get("distribution") or "MULTI_GGX") == "MULTI_GGX"
        elif t == "transparent_bsdf":
            lb.update(kind="transparent", through=self.inp(node, "Color"))
        elif t == "emission":
            lb.update(kind="emission", emission=self.scale3(self.inp(node, "Color"), self.inp(node, "Strength")))
        elif t == "holdout":
            lb.update(kind="holdout")  # black; its weight is the hit's holdout (tracer.integrator.compose cuts the alpha)
        else:
            self.warn(node.name, f"shader {node.name!r} ({t}) is not supported; a grey diffuse surface is used")
            lb.update(base=(0.8, 0.8, 0.8), roughness=1.0, lk=L.DIFFUSE, colour=(0.8, 0.8, 0.8))
        return lb

    def anisotropy(self, node: Node, amount: str, rotation: str, normal, glossy: bool):
        """The ``aniso`` output of a Principled (``glossy`` False) or Glossy BSDF: the axis its GGX lobe is stretched
        along × (1 − aspect) (:func:`tracer.shading.bsdf.anisotropic`), or None (isotropic). As Cycles' closure.h:
        the Tangent input turned by 2π·rotation about the normal; the Principled BSDF stretches α by
        1/aspect along it, aspect = √(1 − 0.9·Anisotropic); the Glossy BSDF (Anisotropy in [−0.99, 0.99]) by
        1/(1 + Anisotropy) along it where negative, by 1/(1 − Anisotropy) across it where positive. An unlinked
        Tangent is Cycles' default: the radial tangent about the object's Z axis from Generated coordinates."""
        an = self.inp(node, amount)
        if self.estimate or (is_const(an) and float(an) == 0.0) or (not glossy and is_const(an) and float(an) < 0):
            return None
        m = self.math
        nrm = normal if normal is not None else self.hit(IN_NORMAL)
        t = self.g.input_value(node, "Tangent")
        if isinstance(t, Out):
            t = self.val(t, VECTOR)
        else:  # Cycles links an unlinked Tangent to Geometry ▸ Tangent: the radial tangent about Z
            t = radial_tangent(self)
        rot = self.inp(node, rotation)
        if not (is_const(rot) and float(rot) == 0.0):
            angle = m(ops.M_MULTIPLY, rot, 2.0 * np.pi)
            t = self.op("vrotate", [(t, 3), ((0.0, 0.0, 0.0), 3), (nrm, 3), (angle, 1), ((0.0, 0.0, 0.0), 3)], imm=0)
        if glossy:  # |Anisotropy| ≤ 0.99; positive: the lobe is stretched across the tangent
            an = m(ops.M_MINIMUM, m(ops.M_MAXIMUM, an, -0.99), 0.99) if not is_const(an) else \
                min(max(float(an), -0.99), 0.99)
            across = self.vmath(ops.V_CROSS_PRODUCT, nrm, t)[0]
            pos = m(ops.M_GREATER_THAN, an, 0.0) if not is_const(an) else float(float(an) > 0)
            axis = self.lerp3(t, across, pos)
            k = m(ops.M_ABSOLUTE, an) if not is_const(an) else abs(float(an))
        else:  # 1 − aspect, aspect = √(1 − 0.9·Anisotropic)
            an = m(ops.M_MINIMUM, m(ops.M_MAXIMUM, an, 0.0), 1.0) if not is_const(an) else min(float(an), 1.0)
            k = m(ops.M_SUBTRACT, 1.0, m(ops.M_SQRT, m(ops.M_SUBTRACT, 1.0, m(ops.M_MULTIPLY, an, 0.9))))
            axis = t
        unit = self.vmath(ops.V_NORMALIZE, axis)[0]
        return self.scale3(unit, k)

    def _sheen_lobe(self, colour, roughness, dist: int, layer: bool) -> dict:
        """A SHEEN lobe's fields: in the slots its colour, roughness, distribution (P_METAL) and layer flag (P_SPEC);
        blended (one-closure outputs) a diffuse of colour × its mean albedo (the constant roughness's, else ½'s)."""
        r = float(roughness) if is_const(roughness) else 0.5
        e = _sheen.mean_albedo(dist, r)
        return dict(base=self.scale3(colour, e), roughness=1.0, metallic=0.0, specular=0.0, transmission=0.0,
                    lk=L.SHEEN, colour=colour, p_rough=roughness, p_metal=float(dist), p_spec=1.0 if layer else 0.0,
                    sheen_layer=layer)

    def _estimate_of(self, node, name):
        c = type(self)(self.g, None, self.uv_index, estimate=True)
        return c.inp(node, name)

    def _const_in(self, node, name, default):
        x = self.g.input_value(node, name)
        if isinstance(x, Out):
            self.warn(node.name + name, f"{node.name!r}: a linked {name} is read as its constant estimate")
            return float(self._estimate_of(node, name))
        return float(x)

    def _normal_in(self, node):
        return self._normal_in_named(node, "Normal")

    def _normal_in_named(self, node, name):
        x = self.g.input_value(node, name)
        if isinstance(x, Out):
            return self.val(x, VECTOR)
        return None

    def outputs(self) -> tuple[dict, dict]:
        """(values per closure input slot, constant row extras); the lobe slots, if any, in ``self.lobe_slots``."""
        out = self.g.output_node
        surface = self.g.input_value(out, "Surface") if out is not None else None
        disp = self.g.input_value(out, "Displacement") if out is not None else None
        lobes = []
        for w, n in self.closure(surface):
            lb = n if isinstance(n, dict) else self.lobe(n)  # a coat's two lobes come as dicts (_coated)
            lobes.append((w, lb))
            if lb.get("sheen") is not None:  # the Principled sheen: a layer lobe right after its own
                sw, tint, rough = lb["sheen"]
                layer = dict(lb, **self._sheen_lobe(tint, rough, _sheen.MICROFIBER, layer=True))
                layer.update(sheen=None, emission=(0.0, 0.0, 0.0))
                lobes.append((self.math(ops.M_MULTIPLY, w, sw), layer))
        smooth = None
        if isinstance(disp, Out):
            self.warn("displacement", "Displacement is rendered as bump (the surface is not moved)")
            smooth = self._displacement_bump(disp, None)  # Cycles: the bump of the Geometry normal sets sd->N
            lobes = [(w, dict(lb, normal=smooth if lb["normal"] is None else
                              self._displacement_bump(disp, lb["normal"]))) for w, lb in lobes]
        vals, extras = self.combine(lobes)
        vals["aniso"] = self._aniso(lobes)
        vals["smooth"] = smooth
        self.lobe_slots = self.slots(lobes)
        return vals, extras

    def _aniso(self, lobes: list):
        """The hit's anisotropy: the first anisotropic lobe's (every GGX lobe of the hit takes it; one warning when
        another lobe is isotropic or differs)."""
        found = [lb["aniso"] for _w, lb in lobes if lb.get("aniso") is not None]
        if not found:
            return None
        glossy = [lb for _w, lb in lobes if lb["kind"] == "surface" and lb["lk"] in (L.PRINCIPLED, L.GLOSSY)]
        if len(found) < len(glossy) or len({id(x) for x in found}) > 1:
            self.warn("aniso", "GGX lobes of different anisotropy: the first anisotropic lobe's is used for all")
        return found[0]

    def _displacement_bump(self, disp: Out, normal):
        nrm = normal if normal is not None else self.hit(IN_NORMAL)
        if self.estimate:
            return nrm
        hs = []
        for var in range(3):
            d = self.val(disp, VECTOR, var)
            hs.append(self.vmath(ops.V_DOT_PRODUCT, d, self.hit(IN_NORMAL))[1])
        if all(is_const(h) for h in hs):
            return nrm
        setup = self.bump_setup()
        return self.op("bump", [(hs[0], 1), (hs[1], 1), (hs[2], 1), (1.0, 1), (1.0, 1), (nrm, 3)],
                           imm=setup.r, raw={"reads": [(setup.r, 10)]})

    def _mean(self, c):
        """The mean of a colour (a transparent lobe's share of coverage)."""
        if is_const(c):
            return sum(vec3(c)) / 3.0
        return self.convert(c, VECTOR, FLOAT)

    def combine(self, lobes: list) -> tuple[dict, dict]:
        """The one-closure outputs of a weighted lobe list (module docstring, 3)."""
        zero3 = (0.0, 0.0, 0.0)
        extras = dict(ior=1.5, transmission_tint=None, specular_tint=(1.0, 1.0, 1.0), alpha_threshold=0.0)
        if not lobes:  # nothing connected: black (as Cycles)
            return dict(base=zero3, roughness=0.5, metallic=0.0, specular=0.0, alpha=1.0, emission=zero3,
                        normal=None, transmission=0.0), extras
        surf = [(w, lb) for w, lb in lobes if lb["kind"] in ("surface", "holdout")]
        for _w, lb in surf:
            extras["specular_tint"] = lb["specular_tint"]
            extras["alpha_threshold"] = max(extras["alpha_threshold"], lb["threshold"])
        glass = [(w, lb) for w, lb in surf if not (is_const(lb["transmission"]) and lb["transmission"] == 0.0)]
        if glass:
            extras["ior"] = glass[0][1]["ior"]
            tints = [lb["tint"] for _w, lb in glass]
            extras["transmission_tint"] = tints[0]
            extras["glass_multiscatter"] = glass[0][1].get("multiscatter", True)
        elif surf:
            extras["ior"] = surf[0][1]["ior"]
        normals = [lb["normal"] for _w, lb in surf if lb["normal"] is not None]
        normal = normals[0] if normals else None
        if len({id(x) if not is_const(x) else vec3(x) for x in normals}) > 1:
            self.warn("normals", "lobes with different normals: the first lobe's normal is used for all")
        if len(lobes) == 1:
            w, lb = lobes[0]
            if lb["kind"] == "transparent":
                return dict(base=zero3, roughness=0.5, metallic=0.0, specular=0.0,
                            alpha=self.math(ops.M_SUBTRACT, 1.0, self._mean(lb["through"]), clamp=True),
                            emission=zero3, normal=None, transmission=0.0), extras
            if lb["kind"] == "emission":
                return dict(base=zero3, roughness=0.5, metallic=0.0, specular=0.0, alpha=1.0,
                            emission=self.scale3(lb["emission"], w), normal=None, transmission=0.0), extras
            if is_const(w) and float(w) == 1.0:
                return {k: lb[k] for k in ("base", "roughness", "metallic", "specular", "alpha", "emission",
                                           "transmission")} | {"normal": normal}, extras
        # several lobes (or a weighted one): transparency, emission sum, weighted parameters
        m = self.math
        transp = 0.0
        emis = zero3
        s_w = []
        for w, lb in lobes:
            if lb["kind"] == "transparent":
                transp = m(ops.M_ADD, transp, m(ops.M_MULTIPLY, w, self._mean(lb["through"])))
                continue
            emis = self.add3(emis, self.scale3(lb["emission"], w))
            if lb["kind"] == "emission":
                continue
            sw = m(ops.M_MULTIPLY, w, lb["alpha"])
            transp = m(ops.M_ADD, transp, m(ops.M_MULTIPLY, w, m(ops.M_SUBTRACT, 1.0, lb["alpha"])))
            s_w.append((sw, lb))
        alpha = m(ops.M_SUBTRACT, 1.0, transp, clamp=True)
        inv_alpha = m(ops.M_DIVIDE, 1.0, alpha)
        base, spec, rough, metal, tran = zero3, 0.0, 0.0, 0.0, 0.0
        # sheen lobes add their albedo's worth of diffuse colour and leave the other parameters to the rest
        for sw, lb in s_w:
            if lb["lk"] == L.SHEEN:
                base = self.add3(base, self.scale3(lb["base"], sw))
        s_w = [x for x in s_w if x[1]["lk"] != L.SHEEN] or [(sw, dict(lb, base=zero3)) for sw, lb in s_w]
        total = 0.0
        for sw, _lb in s_w:
            total = m(ops.M_ADD, total, sw)
        inv_total = m(ops.M_DIVIDE, 1.0, total)
        for sw, lb in s_w:
            base = self.add3(base, self.scale3(lb["base"], sw))
            spec = m(ops.M_ADD, spec, m(ops.M_MULTIPLY, sw, lb["specular"]))
            rough = m(ops.M_ADD, rough, m(ops.M_MULTIPLY, sw, lb["roughness"]))
            metal = m(ops.M_ADD, metal, m(ops.M_MULTIPLY, sw, lb["metallic"]))
            tran = m(ops.M_ADD, tran, m(ops.M_MULTIPLY, sw, lb["transmission"]))
        return dict(base=self.scale3(base, inv_alpha), specular=m(ops.M_MULTIPLY, spec, inv_alpha),
                    roughness=m(ops.M_MULTIPLY, rough, inv_total) if s_w else 0.5,
                    metallic=m(ops.M_MULTIPLY, metal, inv_total), transmission=m(ops.M_MULTIPLY, tran, inv_total),
                    alpha=alpha, emission=self.scale3(emis, inv_alpha), normal=normal), extras

    # ------------------------------------------------------------------ lobe slots
    def slots(self, lobes: list) -> LobeSlots | None:
        """The lobe slots of a weighted lobe list (module docstring, 4), or None where one closure holds it."""
        if self.estimate:
            return None
        refl = [(w, lb) for w, lb in lobes if lb["kind"] == "surface"]
        special = any(lb["lk"] in (L.GLOSSY, L.TRANSLUCENT, L.REFRACTION, L.SHEEN) for _w, lb in refl) or any(
            lb["kind"] == "holdout" or (lb["kind"] == "transparent" and not (
                is_const(lb["through"]) and vec3(lb["through"]) == (1.0, 1.0, 1.0))) for _w, lb in lobes)
        if len(refl) < 2 and not special and (not refl or _exact_as_a_row(*refl[0])):
            return None
        m = self.math
        through, holdout = (0.0, 0.0, 0.0), 0.0
        slots = []
        for w, lb in lobes:
            if lb["kind"] == "transparent":
                through = self.add3(through, self.scale3(lb["through"], w))
            elif lb["kind"] == "holdout":
                holdout = m(ops.M_ADD, holdout, w)
            elif lb["kind"] == "surface":
                a = lb["alpha"]
                if not (is_const(a) and float(a) == 1.0):
                    through = self.add3(through, self.convert(m(ops.M_MULTIPLY, w, m(ops.M_SUBTRACT, 1.0, a)),
                                                              FLOAT, VECTOR))
                slots.append((m(ops.M_MULTIPLY, w, a), lb))
        if len(slots) > L.MAX_LOBES:
            slots = self._merge(slots)
        kinds = np.full(L.MAX_LOBES, -1, np.int32)
        regs = np.zeros((L.MAX_LOBES, 6), np.int32)
        live = []
        for k, (w, lb) in enumerate(slots):
            kinds[k] = lb["lk"]
            vals = [(self.convert(w, FLOAT, VECTOR), 3), (lb["colour"], 3), (lb.get("p_rough", lb["roughness"]), 1),
                    (lb.get("p_metal", lb["metallic"]), 1), (lb.get("p_spec", lb["specular"]), 1),
                    (lb["transmission"], 1)]
            for j, (x, n) in enumerate(vals):
                regs[k, j] = self.e.reg(x, n)
                live.append((int(regs[k, j]), n))
        extra = np.array([self.e.reg(through, 3), self.e.reg(holdout, 1)], np.int32)
        live += [(int(extra[0]), 3), (int(extra[1]), 1)]
        return LobeSlots(kinds, regs, extra, live)

    def _merge(self, slots: list) -> list:
        """More reflecting lobes than slots: the lightest (by constant weight; a per-hit weight counts as ½) are
        blended into one Principled lobe of weight-averaged parameters (one warning)."""
        self.warn("lobes", f"{len(slots)} reflecting BSDFs: the lightest are merged into one blended lobe "
                           f"(the tracer keeps {L.MAX_LOBES})")
        est = [float(w) if is_const(w) else 0.5 for w, _lb in slots]
        order = sorted(range(len(slots)), key=lambda k: -est[k])
        slots = [(w, dict(lb, p_spec=0.0) if lb.get("sheen_layer") else lb) for w, lb in slots]  # order changes
        keep = [slots[k] for k in order[:L.MAX_LOBES - 1]]
        rest = [slots[k] for k in order[L.MAX_LOBES - 1:]]
        m = self.math
        total = 0.0
        for w, _lb in rest:
            total = m(ops.M_ADD, total, w)
        inv = m(ops.M_DIVIDE, 1.0, total)
        blend = dict(rest[0][1], lk=L.PRINCIPLED, colour=(0.0, 0.0, 0.0), roughness=0.0, metallic=0.0, specular=0.0,
                     transmission=0.0)
        for w, lb in rest:
            f = m(ops.M_MULTIPLY, w, inv)
            blend["colour"] = self.add3(blend["colour"], self.scale3(lb["colour"], f))
            for key in ("roughness", "metallic", "specular", "transmission"):
                blend[key] = m(ops.M_ADD, blend[key], m(ops.M_MULTIPLY, f, lb[key]))
        return keep + [(total, blend)]


def _is(x, value: float) -> bool:
    return is_const(x) and float(x) == value


def _exact_as_a_row(w, lb: dict) -> bool:
    """Whether one reflecting lobe of weight ``w`` is exactly the material row :meth:`ClosureLowering.combine`
    makes of it: at weight 1 always; at another weight only a lobe without specular (w·base is the diffuse). A
    weighted specular lobe needs its slot: a row would scale F0 by w, while Fresnel still rises to 1 at grazing
    angles (Mix Shader with one input left empty: Cycles scales the whole lobe)."""
    return _is(w, 1.0) or (_is(lb["specular"], 0.0) and _is(lb["metallic"], 0.0))

"""MaterialX surface shaders -> the tracer's Principled model, as MaterialX's own node-graph implementations
(``libraries/bxdf/*.mtlx``) define them.

Every family below is read input by input against its node definition (an unauthored input is the definition's
default). Each input is a constant (a colour in a named colour space converted into linear Rec.709:
:func:`usd_io.materials.mtlx.linear_colour`), a MaterialX image or any MaterialX network
(:mod:`usd_io.materials.mtlx_graph`). An input whose effect is not rendered, or rendered approximately, prints one
warning naming it (``<material>: MaterialX <family> input <name> ...``), once per material.

The layers MaterialX stacks with ``layer(top, base)`` (base × (1 − the top's directional albedo) + top) are written
as lobes over the Principled base (:meth:`tracer.shading.principled.PrincipledSurface.graph`, ``layers``): a *dielectric*
layer is a Principled lobe with a black base (its Fresnel curve of the layer's IOR, its roughness), the base weighted by
1 − weight·F(IOR, n·v) (a Fresnel node: the layer's albedo at the view angle, exact for a smooth layer); a *glossy*
layer is a constant-Fresnel GGX lobe (Disney's scaled generalized Schlick), the base weighted by 1 − weight·its
mean colour. A colour that multiplies everything under a layer (a coat's absorption) is folded into the colours of
the base: its diffuse and metal colour, its specular tint, its transmission tint and its emission.

standard_surface (``NG_standard_surface_surfaceshader_100``)
    base colour = base · base_color (metal reflectivity and diffuse alike), metalness, specular_roughness
    (coat_affect_roughness mixes it towards 1), specular (the Principled level 0.5·specular: F0 = F0(specular_IOR)
    · specular · specular_color) and specular_color (the specular tint; for a metal the F82 tint that matches
    MaterialX's artistic_ior conductor at 82° with edge colour specular_color · specular), transmission (tinted
    by transmission_color), emission · emission_color, opacity (its luminance), normal. coat: a dielectric layer
    (coat, coat_IOR, coat_roughness) over everything, whose coat_color (mixed by coat) tints what is under it;
    coat_affect_color raises the diffuse colour to 1 + coat · coat_affect_color. subsurface: rendered as the
    diffuse colour mix(base · base_color, subsurface_color, subsurface) (warned). sheen (sheen_color,
    sheen_roughness): the Principled sheen layer (the tracer's microfiber sheen). Not rendered (warned):
    thin film, anisotropy, diffuse_roughness (Oren-Nayar rendered as Lambert), transmission depth/scatter/
    dispersion/extra roughness, thin_walled.
open_pbr_surface (``open_pbr_surface_surfaceshader``)
    base colour = base_weight · base_color, base_metalness, specular_weight (the Principled level
    0.5 · specular_weight), specular_color (specular tint, and the metal's F82 tint as in OpenPBR), specular_ior,
    specular_roughness (coat-affected as OpenPBR's graph: mix(r, min(1, (2c⁴ + r⁴))^¼, coat_weight)),
    transmission_weight/color, emission_luminance · emission_color, geometry_opacity, geometry_normal. coat: a
    dielectric layer (coat_weight, coat_ior, coat_roughness), coat_color's absorption and the coat darkening
    (1 − K)/(1 − E_base·K), K = 1 − (1 − F0(coat_ior))/coat_ior², mixed by coat_weight · coat_darkening, on the
    base. subsurface_weight: the diffuse colour towards subsurface_color (warned). fuzz: the Principled sheen
    layer. Not rendered (warned):
    thin film, anisotropy, base_diffuse_roughness, transmission depth/scatter/dispersion, thin walled.
gltf_pbr (``IMPL_gltf_pbr_surfaceshader``)
    base_color, metallic, roughness, normal, transmission (tinted by base_color), ior; the dielectric's
    generalized Schlick F0 = min(F0(ior) · specular_color, 1) · specular is the Principled level 0.5 · specular
    with tint specular_color; emissive · emissive_strength; alpha by alpha_mode (0 opaque, 1 MASK: a cut-out at
    alpha_cutoff, 2 BLEND: alpha). clearcoat: a dielectric layer (IOR 1.5, clearcoat_roughness). occlusion is
    ignored (a ray tracer shadows). sheen_color: the Principled sheen of weight max(sheen_color), its colour
    normalised, roughness sheen_roughness² (MaterialX's graph). Not rendered (warned): iridescence, thickness
    and attenuation (volume), anisotropy, dispersion.
disney_principled (``NG_disney_principled``)
    the diffuse (Burley: Lambert at normal incidence, rendered as Lambert) and the metal (Schlick from baseColor)
    as the Principled base (baseColor, metallic, roughness), specTrans its transmission (rough by the roughness, tinted by
    baseColor, ior); the dielectric specular — MaterialX's generalized Schlick of weight 0.08 · specular with F0 =
    mix(1, baseColor, specularTint) and F90 = 1, so F ≈ 0.08 · specular · F0 at every angle — a glossy layer of
    that colour and the roughness, over the non-metal part; clearcoat a glossy layer 0.04 · clearcoat, roughness
    1 − clearcoatGloss; sheen the Principled sheen of colour mix(1, baseColor, sheenTint). Not rendered
    (warned): subsurface (rendered as the diffuse),
    anisotropic.
surface_unlit (``ND_surface_unlit``)
    emission · emission_color, nothing reflected, and opacity; with a transmission (or any network) MaterialX's
    OSL closure reading (usd_io.materials.mtlx_closures): (1 − t) of the emission, t · transmission_color passing
    through.
"""

from __future__ import annotations

import numpy as np

from tracer import colorspace
from tracer.shading.materials import f0_from_ior
from tracer.shading.principled import PrincipledSurface

from . import mtlx, mtlx_graph
from . import network as net

#: Node-definition names (or their prefix) of each family.
FAMILIES = {"standard_surface": "ND_standard_surface_surfaceshader", "open_pbr_surface": "ND_open_pbr_surface",
            "gltf_pbr": "ND_gltf_pbr_surfaceshader", "disney_principled": "ND_disney_principled",
            "surface_unlit": "ND_surface_unlit"}


def family_of(sid: str) -> str | None:
    for fam, nd in FAMILIES.items():
        if sid.startswith(nd) or sid == fam:
            return fam
    return None


#: Arnold shaders read against the MaterialX definition of their own interface: Arnold's standard_surface is
#: MaterialX's version 1.0.0 (base 0.8, base_color white: Arnold's defaults), not the library's default 1.0.1
#: (base 1, base_color 0.8), which differs wherever only one of the two is authored.
ARNOLD_NODEDEFS = {"arnold:standard_surface": "ND_standard_surface_surfaceshader_100"}


def _nodedef_for(sid: str, family: str):
    sid = ARNOLD_NODEDEFS.get(sid, sid)
    nd = mtlx.nodedef(sid) if sid.startswith("ND_") else None
    if nd is None:  # an Arnold shader of the same interface, or a versionless id: the library's default version
        lib = mtlx.definitions()
        for cand in lib.getMatchingNodeDefs(family):
            if cand.getType() == "surfaceshader":
                return cand
    return nd


class Inputs:
    """One MaterialX surface shader's inputs, read against its node definition."""

    def __init__(self, table, s, label: str, needs, family: str):
        self.table, self.s, self.label, self.needs, self.family = table, s, label, needs, family
        self.nd = _nodedef_for(net.shader_id(s), family)
        self.time = table.time
        self._folded: dict = {}

    def warn(self, message: str) -> None:
        self.table.warn(f"{self.label}: MaterialX {self.family} {message}")

    def default(self, name: str, fallback=0.0):
        d = self.nd.getActiveInput(name) if self.nd is not None else None
        if d is None or not d.getValueString():
            return fallback
        v = d.getValue()
        if isinstance(v, (bool, int, float)):
            return float(v)
        try:
            return tuple(float(x) for x in (v.asTuple() if hasattr(v, "asTuple") else v))
        except TypeError:
            return v

    def connected(self, name: str) -> bool:
        """Driven by a network that varies (one that folds to a constant reads as that constant)."""
        a, is_out = net.producer(self.s, name)
        return a is not None and is_out and not isinstance(self.src(name), net.Const)

    def src(self, name: str, fallback=None):
        """What drives ``name`` (usd_io.materials.network's sources), a constant colour in its colour space
        converted; a network that varies nowhere as the constant it folds to
        (:func:`usd_io.materials.mtlx_graph.constant_value`)."""
        default = self.default(name, fallback if fallback is not None else 0.0)
        got = net.source(self.s, name, default, self.time)
        if isinstance(got, net.GraphLookup):
            key = (name, got.node, got.output)
            if key not in self._folded:
                self._folded[key] = mtlx_graph.constant_value(self.table, got)
            if self._folded[key] is not None:
                return net.Const(self._folded[key])
        if isinstance(got, net.Const) and got.value is not default:
            a, _o = net.producer(self.s, name)
            if a is not None and str(a.GetTypeName()) in ("color3f", "color4f", "color3d", "color4d"):
                got = net.Const(mtlx.linear_colour(got.value, a.GetColorSpace(), self.warn_space))
        return got

    def warn_space(self, space: str) -> None:
        self.warn(f"colour space {space!r} is not one MaterialX's colour management knows (values read as "
                  "linear Rec.709)")

    def const(self, name: str, fallback=0.0):
        """A constant input (a float or a tuple); a connected one is read as its fallback with one warning."""
        got = self.src(name, fallback)
        if isinstance(got, net.Const):
            v = got.value
        else:
            v = self.default(name, fallback)
            self.warn(f"input {name} driven by a network is read as its default {v} (only a constant is read)")
        if v is None:
            return fallback
        flat = np.ravel(np.asarray(v, np.float64)) if not isinstance(v, str) else None
        if flat is None or flat.size == 0:
            return fallback
        return float(flat[0]) if flat.size == 1 else tuple(float(x) for x in flat[:3])

    def c3(self, name: str, fallback=(1.0, 1.0, 1.0)) -> np.ndarray:
        return np.asarray(net.floats(self.const(name, fallback), 3, fallback), np.float64)

    def f(self, name: str, fallback=0.0) -> float:
        return float(net.floats(self.const(name, fallback), 1, (fallback,))[0])

    def differs(self, name: str) -> bool:
        """Connected, or authored with a value other than its definition's default."""
        if self.connected(name):
            return True
        a, _o = net.producer(self.s, name)
        if a is None:
            return False
        v = a.Get() if self.time is None else a.Get(self.time)
        if v is None:
            return False
        d = self.default(name, None)
        try:
            return not np.allclose(np.ravel(np.asarray(v, np.float64)), np.ravel(np.asarray(d, np.float64)))
        except (TypeError, ValueError):
            return str(v) != str(d)

    def weight_on(self, name: str) -> bool:
        """A weight that is connected or a non-zero constant."""
        return self.connected(name) or self.f(name, 0.0) != 0.0

    def dropped(self, names, what: str = "is not rendered") -> None:
        for name in names:
            if self.differs(name):
                self.warn(f"input {name} {what}")


# ---------------------------------------------------------------------------------------------- helpers
def scaled(src, k):
    """A colour source multiplied by ``k`` (a float or an RGB triple)."""
    k3 = np.broadcast_to(np.asarray(k, np.float64), (3,))
    if np.allclose(k3, 1.0):
        return src
    if isinstance(src, net.Const):
        v = np.asarray(net.floats(src.value, 3, (1.0, 1.0, 1.0)))
        return net.Const(tuple(float(x) for x in v * k3))
    if isinstance(src, net.TextureLookup):
        src.scale = tuple(float(a * b) for a, b in zip(src.scale[:3], k3)) + (src.scale[3],)
        return src
    if isinstance(src, net.GraphLookup):
        prev = np.broadcast_to(np.asarray(src.scale, np.float64), (3,))
        src.scale = tuple(float(x) for x in prev * k3)
        return src
    return src


def _colour(t, key, inputs: Inputs, src, default, name):
    if isinstance(src, net.PrimvarLookup) and key == "base_color":  # the vertex colour times the base colour
        # (another input, e.g. emission_color, reads the primvar through the table: PrimvarColour on that input)
        inputs.needs.color = (src.name, net.floats(src.fallback, 3, default))
        t.update(**{key: tuple(default)}, vertex_color=True)
        return
    inputs.table._colour_input(t, key, src, default, inputs.label, name, inputs.needs)


def _scalar(t, key, inputs: Inputs, name, default):
    inputs.table._scalar_input(t, key, inputs.src(name, default), default, inputs.label, name, inputs.needs)


def artistic_ior(r, g):
    """Gulbrandsen's artist-friendly metallic Fresnel (MaterialX's artistic_ior): (n, k) per channel from the
    reflectivity r (clamped to 0.99) and the edge colour g."""
    r = np.clip(np.asarray(r, np.float64), 0.0, 0.99)
    g = np.asarray(g, np.float64)
    sr = np.sqrt(r)
    n_min = (1 - r) / (1 + r)
    n_max = (1 + sr) / (1 - sr)
    n = g * n_min + (1 - g) * n_max
    k2 = ((n + 1) ** 2 * r - (n - 1) ** 2) / (1 - r)
    return n, np.sqrt(np.maximum(k2, 0.0))


def conductor_fresnel(cos_t, n, k):
    """Unpolarised Fresnel reflectance of a conductor of complex index n + ik (per channel)."""
    c2 = cos_t * cos_t
    s2 = 1 - c2
    n2, k2 = n * n, k * k
    t0 = n2 - k2 - s2
    a2b2 = np.sqrt(t0 * t0 + 4 * n2 * k2)
    t1 = a2b2 + c2
    a = np.sqrt(np.maximum(0.5 * (a2b2 + t0), 0.0))
    t2 = 2 * a * cos_t
    rs = (t1 - t2) / (t1 + t2)
    t3 = c2 * a2b2 + s2 * s2
    t4 = t2 * s2
    rp = rs * (t3 - t4) / (t3 + t4)
    return 0.5 * (rp + rs)


def f82_tint(reflectivity, edge, scale=(1.0, 1.0, 1.0)):
    """The Principled F82 tint that makes its metal, of F0 = scale · reflectivity, meet scale × MaterialX's
    artistic_ior conductor (reflectivity, edge colour) at cos θ = 1/7: scale·F_c(1/7) / Schlick(F0, 1/7)
    (clamped to [0, 1], as the Principled BSDF clamps its tint). ``scale``: what multiplies the whole metal (a
    coat's absorption)."""
    n, k = artistic_ior(reflectivity, edge)
    scale = np.asarray(scale, np.float64)
    f0 = np.clip(scale * np.asarray(reflectivity, np.float64), 0.0, 1.0)
    c = 1.0 / 7.0
    schlick = f0 + (1 - f0) * (1 - c) ** 5
    return tuple(float(x) for x in np.clip(scale * conductor_fresnel(c, n, k) / np.maximum(schlick, 1e-6), 0, 1))


def _sheen(t, inp: Inputs, weight: str, colour: str, rough: str, rough_default: float) -> None:
    """A sheen layer (Standard Surface's sheen, OpenPBR's fuzz) as the Principled sheen (microfiber: the tracer's
    sheen lobe over the base); constants only, a network read as its constant with one warning."""
    if not inp.weight_on(weight):
        return
    w = inp.f(weight, 0.0) if not inp.connected(weight) else 1.0
    if any(inp.connected(n) for n in (weight, colour, rough)):
        inp.warn(f"input {weight}/{colour}/{rough} driven by a network is read as its constant")
    t.update(sheen=float(np.clip(w, 0.0, 1.0)), sheen_tint=tuple(float(x) for x in inp.c3(colour)),
             sheen_roughness=float(np.clip(inp.f(rough, rough_default), 0.0, 1.0)))


def _coat(t: PrincipledSurface, inp: Inputs, weight: float, roughness: tuple, ior: tuple, normal: str) -> None:
    """A coat of ``weight`` > 0 as a dielectric layer over the surface (``roughness``, ``ior``: (input name,
    its default)), the tint under it white (:func:`white_tint_under_coat`); its own normal input is warned."""
    if weight <= 0:
        return
    t.layers = [dict(kind="dielectric", weight=weight, roughness=inp.f(*roughness), ior=inp.f(*ior) or ior[1])]
    white_tint_under_coat(t)
    if inp.differs(normal):
        inp.warn(f"input {normal} is not rendered (the coat uses the surface's normal)")


def white_tint_under_coat(t: PrincipledSurface) -> None:
    """A coat's lobe shares the material's specular tint (the tracer's lobes have one tint and one IOR per
    material), and a coat reflects white: under a coat the tint is white, a dielectric base's tint kept as its
    Specular IOR Level × the tint's luminance, a metal's F82 tint dropped (its F0, which carries the coat's
    absorption, rises to white only at grazing angles, where the coat reflects most of the light anyway)."""
    tint, t.specular_tint = t.specular_tint, None
    if tint is None:
        return
    if float(t.metallic) < 1.0:
        t.specular = float(np.clip(t.specular * _lum(tint), 0.0, 1.0))


def _lum(c) -> float:
    return colorspace.luminance(np.broadcast_to(np.asarray(c, np.float64), (3,)))


# ---------------------------------------------------------------------------------------------- families
def standard_surface(inp: Inputs) -> PrincipledSurface:
    t = inp.table.model()
    base_w = inp.f("base", 0.8)
    metal = float(np.clip(inp.f("metalness", 0.0), 0.0, 1.0)) if not inp.connected("metalness") else None
    coat = inp.f("coat", 0.0) if not inp.connected("coat") else None
    if coat is None:
        inp.warn("input coat driven by a network is read as 0 (only a constant coat is rendered)")
        coat = 0.0
    coat = float(np.clip(coat, 0.0, 1.0))
    atten = (1 - coat) + coat * inp.c3("coat_color") if coat > 0 else np.ones(3)

    # base colour: base · base_color (× the coat's absorption); subsurface mixed in as a diffuse colour
    base = scaled(inp.src("base_color"), base_w * atten)
    sub = inp.f("subsurface", 0.0) if not inp.connected("subsurface") else 1.0
    if sub > 0:
        inp.warn("input subsurface is rendered as a diffuse surface of subsurface_color (no scattering inside)")
        sc = inp.src("subsurface_color")
        if isinstance(base, net.Const) and isinstance(sc, net.Const):
            b = np.asarray(net.floats(base.value, 3, (1.0, 1.0, 1.0)))
            s_ = np.asarray(net.floats(sc.value, 3, (1.0, 1.0, 1.0))) * atten
            base = net.Const(tuple(float(x) for x in (1 - sub) * b + sub * s_))
        elif sub >= 0.5:
            base = scaled(sc, atten)
    affect = inp.f("coat_affect_color", 0.0) * coat
    if affect > 0 and isinstance(base, net.Const):
        b = np.maximum(np.asarray(net.floats(base.value, 3, (1.0, 1.0, 1.0))) / np.maximum(atten, 1e-9), 0.0)
        base = net.Const(tuple(float(x) for x in b ** (1 + affect) * atten))
    elif affect > 0:
        inp.warn("input coat_affect_color over a network is not rendered")
    _colour(t, "base_color", inp, base, (1.0, 1.0, 1.0), "base_color")

    # specular: the level, the tint (a metal's F82 tint from MaterialX's artistic_ior)
    spec = inp.f("specular", 1.0) if not inp.connected("specular") else 1.0
    if inp.connected("specular"):
        inp.warn("input specular driven by a network is read as 1")
    t.specular = 0.5 * float(np.clip(spec, 0.0, 2.0))
    tint = inp.c3("specular_color") * atten
    if metal is not None and metal > 0 and isinstance(inp.src("base_color"), net.Const):
        f82 = np.asarray(f82_tint(inp.c3("base_color") * base_w, inp.c3("specular_color") * spec, atten))
        tint = f82 if metal >= 1 else (1 - metal) * tint + metal * f82
    t.specular_tint = tuple(float(x) for x in np.maximum(tint, 0.0))  # a wide-gamut colour may come out < 0
    if metal is None:
        _scalar(t, "metallic", inp, "metalness", 0.0)
    else:
        t.metallic = metal
    rough_src = inp.src("specular_roughness", 0.2)
    car = inp.f("coat_affect_roughness", 0.0) * coat * inp.f("coat_roughness", 0.1)
    if car > 0 and isinstance(rough_src, net.Const):
        r = float(net.floats(rough_src.value, 1, (0.2,))[0])
        rough_src = net.Const((1 - car) * r + car)
    inp.table._scalar_input(t, "roughness", rough_src, 0.2, inp.label, "specular_roughness", inp.needs)
    t.ior = inp.f("specular_IOR", 1.5) or 1.5

    trans = inp.f("transmission", 0.0) if not inp.connected("transmission") else 0.0
    if inp.connected("transmission"):
        inp.warn("input transmission driven by a network is read as 0")
    if trans > 0:
        t.transmission = float(np.clip(trans, 0.0, 1.0))
        t.transmission_tint = tuple(float(x) for x in inp.c3("transmission_color") * atten)
    em = inp.src("emission", 0.0)
    if not (isinstance(em, net.Const) and float(net.floats(em.value, 1, (0.0,))[0]) == 0.0):
        w = float(net.floats(em.value, 1, (0.0,))[0]) if isinstance(em, net.Const) else 1.0
        if not isinstance(em, net.Const):
            inp.warn("input emission driven by a network is read as 1")
        _colour(t, "emission", inp, scaled(inp.src("emission_color"), w * atten), (0.0, 0.0, 0.0), "emission_color")
    _opacity(t, inp, "opacity")
    inp.table._normal_input(t, net.source(inp.s, "normal", None, inp.time), inp.label, "normal", inp.needs,
                            (0.0, 0.0, 0.0))
    _coat(t, inp, coat, ("coat_roughness", 0.1), ("coat_IOR", 1.5), "coat_normal")
    _sheen(t, inp, "sheen", "sheen_color", "sheen_roughness", 0.3)
    inp.dropped(["thin_film_thickness"], "is not rendered (no thin-film interference)")
    inp.dropped(["specular_anisotropy", "coat_anisotropy"], "is rendered isotropic")
    inp.dropped(["diffuse_roughness"], "is rendered as Lambert (no Oren-Nayar roughness)")
    if trans > 0:
        inp.dropped(["transmission_depth", "transmission_scatter", "transmission_dispersion",
                     "transmission_extra_roughness"], "is not rendered")
    inp.dropped(["thin_walled"], "is not rendered")
    return t


def _opacity(t, inp: Inputs, name: str, scalar: bool = False) -> None:
    src = inp.src(name, 1.0 if scalar else (1.0, 1.0, 1.0))
    if isinstance(src, net.Const):
        v = net.floats(src.value, 3, (1.0, 1.0, 1.0))
        a = float(np.clip(v[0] if scalar else _lum(v), 0.0, 1.0))
        if a < 1:
            t.alpha = a
        return
    inp.table._scalar_input(t, "alpha", src, 1.0, inp.label, name, inp.needs)


def open_pbr_surface(inp: Inputs) -> PrincipledSurface:
    t = inp.table.model()
    base_w = inp.f("base_weight", 1.0)
    metal = float(np.clip(inp.f("base_metalness", 0.0), 0.0, 1.0)) if not inp.connected("base_metalness") else None
    coat = float(np.clip(inp.f("coat_weight", 0.0), 0.0, 1.0)) if not inp.connected("coat_weight") else 0.0
    if inp.connected("coat_weight"):
        inp.warn("input coat_weight driven by a network is read as 0 (only a constant coat is rendered)")
    spec_w = inp.f("specular_weight", 1.0) if not inp.connected("specular_weight") else 1.0
    sub = inp.f("subsurface_weight", 0.0) if not inp.connected("subsurface_weight") else 0.0
    atten = np.ones(3)
    if coat > 0:
        atten = (1 - coat) + coat * inp.c3("coat_color")
        darkening = inp.f("coat_darkening", 1.0) * coat
        if darkening > 0:
            ior_c = inp.f("coat_ior", 1.6) or 1.6
            k = 1 - (1 - f0_from_ior(ior_c)) / (ior_c * ior_c)
            m = metal if metal is not None else 0.0
            e_base = m * inp.c3("base_color", (0.8, 0.8, 0.8)) * spec_w + (1 - m) * (
                (1 - sub) * inp.c3("base_color", (0.8, 0.8, 0.8)) + sub * inp.c3("subsurface_color", (0.8,) * 3))
            dark = (1 - k) / np.maximum(1 - e_base * k, 1e-6)
            atten = atten * ((1 - darkening) + darkening * dark)
    base = scaled(inp.src("base_color", (0.8, 0.8, 0.8)), base_w * atten)
    if sub > 0:
        inp.warn("input subsurface_weight is rendered as a diffuse surface of subsurface_color (no scattering)")
        sc = inp.src("subsurface_color", (0.8, 0.8, 0.8))
        if isinstance(base, net.Const) and isinstance(sc, net.Const):
            b = np.asarray(net.floats(base.value, 3, (0.8,) * 3))
            s_ = np.asarray(net.floats(sc.value, 3, (0.8,) * 3)) * atten
            base = net.Const(tuple(float(x) for x in (1 - sub) * b + sub * s_))
    if metal is not None and metal > 0 and spec_w != 1.0:
        inp.warn("input specular_weight on a metal is rendered as a darker base colour")
    _colour(t, "base_color", inp, base, (0.8, 0.8, 0.8), "base_color")
    if metal is None:
        _scalar(t, "metallic", inp, "base_metalness", 0.0)
    else:
        t.metallic = metal
    t.specular = 0.5 * float(np.clip(spec_w, 0.0, 2.0))
    tint = inp.c3("specular_color") * atten
    if metal is not None and metal > 0 and coat > 0 and isinstance(inp.src("base_color", (0.8,) * 3), net.Const):
        # OpenPBR's metal is F82-tinted already; the coat's absorption folded into F0 needs the tint rescaled
        r = np.clip(inp.c3("base_color", (0.8,) * 3) * base_w, 0.0, 1.0)
        s82 = (6.0 / 7.0) ** 5
        f0 = np.clip(r * atten, 0.0, 1.0)
        metal_tint = np.clip(inp.c3("specular_color") * atten * (r + (1 - r) * s82) / (f0 + (1 - f0) * s82), 0, 1)
        tint = (1 - metal) * tint + metal * metal_tint
    t.specular_tint = tuple(float(x) for x in np.maximum(tint, 0.0))
    r_src = inp.src("specular_roughness", 0.3)
    if coat > 0 and isinstance(r_src, net.Const):
        r = float(net.floats(r_src.value, 1, (0.3,))[0])
        cr = inp.f("coat_roughness", 0.0)
        affected = min(1.0, 2 * cr ** 4 + r ** 4) ** 0.25
        r_src = net.Const((1 - coat) * r + coat * affected)
    inp.table._scalar_input(t, "roughness", r_src, 0.3, inp.label, "specular_roughness", inp.needs)
    t.ior = inp.f("specular_ior", 1.5) or 1.5
    trans = inp.f("transmission_weight", 0.0) if not inp.connected("transmission_weight") else 0.0
    if trans > 0:
        t.transmission = float(np.clip(trans, 0.0, 1.0))
        t.transmission_tint = tuple(float(x) for x in inp.c3("transmission_color") * atten)
        inp.dropped(["transmission_depth", "transmission_scatter", "transmission_dispersion_scale"],
                    "is not rendered")
    lum = inp.src("emission_luminance", 0.0)
    if not (isinstance(lum, net.Const) and float(net.floats(lum.value, 1, (0.0,))[0]) == 0.0):
        w = float(net.floats(lum.value, 1, (0.0,))[0]) if isinstance(lum, net.Const) else 1.0
        if not isinstance(lum, net.Const):
            inp.warn("input emission_luminance driven by a network is read as 1")
        if coat > 0:  # emission seen through the coat: tinted by coat_color, less what the coat reflects
            w_c = (1 - coat) + coat * inp.c3("coat_color") * (1 - f0_from_ior(inp.f("coat_ior", 1.6) or 1.6))
        else:
            w_c = np.ones(3)
        _colour(t, "emission", inp, scaled(inp.src("emission_color"), w * w_c), (0.0, 0.0, 0.0), "emission_color")
    _opacity(t, inp, "geometry_opacity", scalar=True)
    inp.table._normal_input(t, net.source(inp.s, "geometry_normal", None, inp.time), inp.label, "geometry_normal",
                            inp.needs, (0.0, 0.0, 0.0))
    _coat(t, inp, coat, ("coat_roughness", 0.0), ("coat_ior", 1.6), "geometry_coat_normal")
    _sheen(t, inp, "fuzz_weight", "fuzz_color", "fuzz_roughness", 0.5)
    inp.dropped(["thin_film_weight"], "is not rendered (no thin-film interference)")
    inp.dropped(["specular_roughness_anisotropy", "coat_roughness_anisotropy"], "is rendered isotropic")
    inp.dropped(["base_diffuse_roughness"], "is rendered as Lambert (no Oren-Nayar roughness)")
    inp.dropped(["geometry_thin_walled"], "is not rendered")
    return t


def gltf_pbr(inp: Inputs) -> PrincipledSurface:
    t = inp.table.model()
    _colour(t, "base_color", inp, inp.src("base_color"), (1.0, 1.0, 1.0), "base_color")
    _scalar(t, "metallic", inp, "metallic", 1.0)
    _scalar(t, "roughness", inp, "roughness", 1.0)
    spec = inp.f("specular", 1.0) if not inp.connected("specular") else 1.0
    if inp.connected("specular"):
        inp.warn("input specular driven by a network is read as 1")
    t.specular = 0.5 * float(np.clip(spec, 0.0, 1.0))
    ior = inp.f("ior", 1.5) or 1.5
    t.ior = ior
    sc = inp.c3("specular_color")
    f0 = f0_from_ior(ior)
    t.specular_tint = tuple(float(x) for x in np.maximum(np.minimum(f0 * sc, 1.0), 0.0) / max(f0, 1e-9))
    trans = inp.f("transmission", 0.0) if not inp.connected("transmission") else 0.0
    if trans > 0:
        t.transmission = float(np.clip(trans, 0.0, 1.0))
    em = scaled(inp.src("emissive", (0.0, 0.0, 0.0)), inp.f("emissive_strength", 1.0))
    _colour(t, "emission", inp, em, (0.0, 0.0, 0.0), "emissive")
    mode = int(inp.f("alpha_mode", 0.0))
    if mode == 1:
        _scalar(t, "alpha", inp, "alpha", 1.0)
        t.alpha_threshold = inp.f("alpha_cutoff", 0.5)
    elif mode == 2:
        _scalar(t, "alpha", inp, "alpha", 1.0)
    inp.table._normal_input(t, net.source(inp.s, "normal", None, inp.time), inp.label, "normal", inp.needs,
                            (0.0, 0.0, 0.0))
    cc = float(np.clip(inp.f("clearcoat", 0.0), 0.0, 1.0)) if not inp.connected("clearcoat") else 0.0
    if inp.connected("clearcoat"):
        inp.warn("input clearcoat driven by a network is read as 0")
    if cc > 0:
        t.layers = [dict(kind="dielectric", weight=cc, roughness=inp.f("clearcoat_roughness", 0.0), ior=1.5)]
        if inp.differs("clearcoat_normal"):
            inp.warn("input clearcoat_normal is not rendered (the coat uses the surface's normal)")
    sc = inp.c3("sheen_color", (0.0, 0.0, 0.0))
    if float(sc.max()) > 0:  # MaterialX's glTF graph: weight max(sheen_color), colour normalised, roughness squared
        t.update(sheen=float(sc.max()), sheen_tint=tuple(float(x) for x in sc / sc.max()),
                 sheen_roughness=inp.f("sheen_roughness", 0.0) ** 2)
        if inp.connected("sheen_color") or inp.connected("sheen_roughness"):
            inp.warn("input sheen_color/sheen_roughness driven by a network is read as its constant")
    inp.dropped(["iridescence"], "is not rendered (no thin-film interference)")
    inp.dropped(["thickness", "attenuation_distance"], "is not rendered (no volume absorption)")
    inp.dropped(["anisotropy_strength"], "is rendered isotropic")
    inp.dropped(["dispersion"], "is not rendered")
    if inp.differs("occlusion"):
        inp.table.warn(f"{inp.label}: MaterialX gltf_pbr input occlusion is ignored (a ray tracer shadows)")
    return t


def disney_principled(inp: Inputs) -> PrincipledSurface:
    t = inp.table.model()
    _colour(t, "base_color", inp, inp.src("baseColor", (0.16, 0.16, 0.16)), (0.16, 0.16, 0.16), "baseColor")
    metal_src = inp.src("metallic", 0.0)
    inp.table._scalar_input(t, "metallic", metal_src, 0.0, inp.label, "metallic", inp.needs)
    _scalar(t, "roughness", inp, "roughness", 0.5)
    t.specular = 0.0  # the dielectric specular is the glossy layer below
    t.ior = inp.f("ior", 1.5) or 1.5
    trans = inp.f("specTrans", 0.0) if not inp.connected("specTrans") else 0.0
    if trans > 0:
        t.transmission = float(np.clip(trans, 0.0, 1.0))
    metal = float(net.floats(metal_src.value, 1, (0.0,))[0]) if isinstance(metal_src, net.Const) else 0.0
    spec = inp.f("specular", 0.5)
    layers = []
    if spec > 0 and metal < 1:
        f0 = (1 - inp.f("specularTint", 0.0)) + inp.f("specularTint", 0.0) * inp.c3("baseColor", (0.16,) * 3)
        colour = 0.08 * spec * f0 * (1 - metal)
        r = inp.f("roughness", 0.5)
        layers.append(dict(kind="glossy", weight=1.0, colour=tuple(float(x) for x in colour), roughness=r))
    cc = inp.f("clearcoat", 0.0)
    if cc > 0:
        layers.insert(0, dict(kind="glossy", weight=1.0, colour=(0.04 * cc,) * 3,
                              roughness=1.0 - inp.f("clearcoatGloss", 1.0)))
    if layers:
        t.layers = layers
    if inp.weight_on("subsurface"):
        inp.warn("input subsurface is rendered as the diffuse (no scattering inside)")
    sh = inp.f("sheen", 0.0)
    if sh > 0:  # MaterialX's Disney graph: sheen_bsdf of colour mix(1, baseColor, sheenTint)
        tint = (1 - inp.f("sheenTint", 0.5)) + inp.f("sheenTint", 0.5) * inp.c3("baseColor", (0.16,) * 3)
        t.update(sheen=sh, sheen_tint=tuple(float(x) for x in tint), sheen_roughness=0.3)
    inp.dropped(["anisotropic"], "is rendered isotropic")
    return t


def surface_unlit(inp: Inputs) -> PrincipledSurface:
    t = inp.table.model(base_color=(0.0, 0.0, 0.0), specular=0.0, metallic=0.0)
    em = scaled(inp.src("emission_color"), inp.f("emission", 1.0))
    _colour(t, "emission", inp, em, (1.0, 1.0, 1.0), "emission_color")
    a = float(np.clip(inp.f("opacity", 1.0), 0.0, 1.0))  # (a transmission: the closure reading, read())
    if a < 1:
        t.alpha = a
    return t


READERS = {"standard_surface": standard_surface, "open_pbr_surface": open_pbr_surface, "gltf_pbr": gltf_pbr,
           "disney_principled": disney_principled, "surface_unlit": surface_unlit}


def read(table, s, fields: PrincipledSurface | None, label: str, needs,
         family: str | None = None) -> PrincipledSurface | None:
    """The surface of a MaterialX surface shader ``s`` (None: not read, with a warning). With a UsdPreviewSurface
    beside it (``fields``) only what the preview surface cannot say is taken from it: transmission, its colour and
    the IOR."""
    sid = net.shader_id(s)
    family = family or family_of(sid)
    if family is None:
        nd = mtlx.nodedef(sid) if sid.startswith("ND_") else None
        if fields is None and nd is not None and nd.getType() == "surfaceshader":  # pbrlib closures: mtlx_closures
            from .mtlx_closures import MxClosureProgram

            return table.model(closure=MxClosureProgram(table, s, label, needs))
        if fields is None:
            table.warn(f"{label}: MaterialX shader {sid!r} is not supported")
        return fields
    inp = Inputs(table, s, label, needs, family)
    if fields is None and family == "surface_unlit" and (any(inp.connected(n) for n in (
            "emission", "emission_color", "transmission", "transmission_color", "opacity"))
            or inp.f("transmission", 0.0) > 0):
        from .mtlx_closures import MxClosureProgram  # networks, a coloured transmission: the closure reading

        return table.model(closure=MxClosureProgram(table, s, label, needs))
    if fields is None:
        return READERS[family](inp)
    out = fields
    names = {"standard_surface": ("transmission", "transmission_color", "specular_IOR"),
             "open_pbr_surface": ("transmission_weight", "transmission_color", "specular_ior"),
             "gltf_pbr": ("transmission", "base_color", "ior")}.get(family)
    if names is None:
        return out
    trans = inp.f(names[0], 0.0)
    if trans > 0:
        out.transmission = float(np.clip(trans, 0, 1))
        out.transmission_tint = tuple(float(x) for x in inp.c3(names[1]))
    if net.value(s, names[2], None, table.time) is not None:
        ior = inp.f(names[2], 1.5)
        if ior > 0:
            out.ior = ior
    return out


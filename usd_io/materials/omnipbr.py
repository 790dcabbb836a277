"""NVIDIA's OmniPBR (``outputs:mdl:surface`` → a Shader with ``info:mdl:sourceAsset`` = OmniPBR.mdl) read from its
documented inputs, without the .mdl file, into the fields UsdPreviewSurface and MaterialX produce.

Inputs (OmniPBR.mdl's names and defaults; an input's ``customData["default"]``, which Kit writes, wins over the
table below):

    diffuse_color_constant (0.2)   base colour; ``diffuse_texture`` replaces it (sRGB unless its colorSpace says
    albedo_brightness (1)          otherwise); base colour = (texture or constant) · albedo_brightness · diffuse_tint
    diffuse_tint (1, 1, 1)
    reflection_roughness_constant (0.5)     roughness = lerp(constant, texture, influence): a texture read when
    reflection_roughness_texture_influence (0)   influence > 0 (influence 1: the texture; in between: the texture
    reflectionroughness_texture                  with scale/bias carrying the lerp)
    metallic_constant (0), metallic_texture_influence (0), metallic_texture     the same
    enable_ORM_texture (false), ORM_texture   occlusion (r, ignored), roughness (g), metallic (b), raw
    specular_level (0.5)           Principled specular level (OmniPBR's F0 = 0.08 · level, the Principled one
                                   0.08 · level too)
    normalmap_texture, bump_factor (1)   tangent-space normal map, raw, (texel·2 − 1) with x, y · bump_factor
    enable_emission (false), emissive_color (1, 0.1, 0.1), emissive_color_texture, emissive_intensity (40):
                                   emission = colour · intensity · 2^KIT_EV (usd_io.exporters: Kit's nits to the
                                   tracer's units, the same factor as Kit's lights)
    enable_opacity (false), opacity_constant (1), enable_opacity_texture, opacity_texture, opacity_threshold (0)
                                   cut-out coverage (alpha, with the threshold; 0 = blended)
    texture_translate (0, 0), texture_rotate (0°), texture_scale (1, 1)   one uv transform for every texture,
                                   applied as UsdTransform2d's scale → rotate → translate
    project_uvw, world_or_object, detail textures, clearcoat, anisotropy: warned when set.

OmniPBR_Opacity and OmniGlass: OmniGlass (glass_color, glass_ior, frosting_roughness) reads as transmission 1
with that tint and ior.
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf

from ..exporters import KIT_EV
from . import network as net

#: The inputs read, with OmniPBR.mdl's defaults.
DEFAULTS = dict(diffuse_color_constant=(0.2, 0.2, 0.2), albedo_brightness=1.0, diffuse_tint=(1.0, 1.0, 1.0),
                reflection_roughness_constant=0.5, reflection_roughness_texture_influence=0.0,
                metallic_constant=0.0, metallic_texture_influence=0.0, specular_level=0.5, enable_ORM_texture=False,
                bump_factor=1.0, enable_emission=False, emissive_color=(1.0, 0.1, 0.1), emissive_intensity=40.0,
                enable_opacity=False, opacity_constant=1.0, enable_opacity_texture=False, opacity_threshold=0.0,
                texture_translate=(0.0, 0.0), texture_rotate=0.0, texture_scale=(1.0, 1.0))
IGNORED = ("project_uvw", "world_or_object", "enable_clearcoat", "detail_texture", "detail_normalmap_texture",
           "anisotropy_constant", "anisotropy_texture")


def mdl_subidentifier(shader) -> str:
    """'OmniPBR', 'OmniGlass', … of an MDL shader (its sourceAsset subIdentifier, else the file stem), or ''."""
    prim = shader.GetPrim()
    if str(prim.GetAttribute("info:implementationSource").Get() or "") != "sourceAsset":
        return ""
    sub = prim.GetAttribute("info:mdl:sourceAsset:subIdentifier").Get()
    if sub:
        return str(sub)
    asset = prim.GetAttribute("info:mdl:sourceAsset").Get()
    path = asset.path if isinstance(asset, Sdf.AssetPath) else str(asset or "")
    return path.rsplit("/", 1)[-1].rsplit(".", 1)[0]


def is_omnipbr(shader) -> bool:
    return mdl_subidentifier(shader) in ("OmniPBR", "OmniPBR_Opacity", "OmniPBR_ClearCoat", "OmniGlass")


def _value(s, name, time):
    """An input's value (through interface connections), its customData default, else the table's."""
    default = DEFAULTS.get(name)
    inp = s.GetInput(name)
    if inp:
        cd = inp.GetAttr().GetCustomDataByKey("default")
        if cd is not None and not isinstance(cd, Sdf.AssetPath):
            default = cd
    return net.value(s, name, default, time)


def _asset(s, name, time):
    v = net.value(s, name, None, time)
    return v if isinstance(v, Sdf.AssetPath) and v.path else None


def _lookup(s, name, time, uv_matrix, colorspace, channel=-1, scale=(1.0, 1.0, 1.0, 1.0),
            bias=(0.0, 0.0, 0.0, 0.0)):
    """A TextureLookup of the asset-valued input ``name`` (the input's colorSpace metadata wins), or None."""
    asset = _asset(s, name, time)
    if asset is None:
        return None
    inp = s.GetInput(name)
    space = inp.GetAttr().GetColorSpace() if inp else ""
    cs = {"sRGB": "sRGB", "raw": "raw"}.get(str(space), colorspace)
    return net.TextureLookup(node=f"{s.GetPath()}.inputs:{name}", asset=asset, channel=channel, uv=None,
                             transform=uv_matrix.copy(), scale=tuple(scale), bias=tuple(bias),
                             fallback=(0.0, 0.0, 0.0, 1.0), wrap_s="repeat", wrap_t="repeat", colorspace=cs,
                             layer=net.file_layer(s, None, name))


def read_omnipbr(table, s, label: str, needs):
    """The PrincipledSurface of an OmniPBR / OmniGlass shader."""
    time = table.time
    val = lambda name: _value(s, name, time)  # noqa: E731
    num = lambda name: float(net.floats(val(name), 1, (DEFAULTS.get(name, 0.0),))[0])  # noqa: E731
    rgb = lambda name: net.floats(val(name), 3, DEFAULTS.get(name, (0.0, 0.0, 0.0)))  # noqa: E731
    t = table.model()
    if mdl_subidentifier(s) == "OmniGlass":
        t.update(base_color=(1.0, 1.0, 1.0), transmission=1.0, specular=0.5, metallic=0.0,
                 transmission_tint=net.floats(net.value(s, "glass_color", (1.0, 1.0, 1.0), time), 3, (1, 1, 1)),
                 ior=float(net.floats(net.value(s, "glass_ior", 1.491, time), 1, (1.491,))[0]),
                 roughness=float(np.clip(net.floats(net.value(s, "frosting_roughness", 0.0, time), 1, (0.0,))[0],
                                         0, 1)))
        return t
    m = net.transform2d_matrix(net.floats(val("texture_scale"), 2, (1.0, 1.0)), num("texture_rotate"),
                               net.floats(val("texture_translate"), 2, (0.0, 0.0)))
    # base colour
    gain = np.asarray(rgb("diffuse_tint")) * num("albedo_brightness")
    tex = _lookup(s, "diffuse_texture", time, m, "sRGB", scale=tuple(gain) + (1.0,))
    base = tex if tex is not None else net.Const(tuple(np.asarray(rgb("diffuse_color_constant")) * gain))
    table._colour_input(t, "base_color", base, DEFAULTS["diffuse_color_constant"], label, "diffuse_color_constant",
                        needs)
    # roughness and metallic: constant, own texture, or the ORM texture's g / b
    orm = bool(val("enable_ORM_texture"))
    for key, const, infl, own, orm_channel in (("roughness", "reflection_roughness_constant",
                                                "reflection_roughness_texture_influence",
                                                "reflectionroughness_texture", 1),
                                               ("metallic", "metallic_constant", "metallic_texture_influence",
                                                "metallic_texture", 2)):
        c, k = num(const), float(np.clip(num(infl), 0.0, 1.0))
        lk = None
        if k > 0:
            lk = (_lookup(s, "ORM_texture", time, m, "raw", orm_channel) if orm else None) or \
                 _lookup(s, own, time, m, "raw", 0)
        if lk is not None:  # lerp(c, texel, k) = texel·k + c·(1 − k)
            ch = lk.channel
            lk.scale = tuple(k if i == ch else 1.0 for i in range(4))
            lk.bias = tuple(c * (1 - k) if i == ch else 0.0 for i in range(4))
            table._scalar_input(t, key, lk, c, label, own, needs)
        else:
            setattr(t, key, float(np.clip(c, 0.0, 1.0)))
    t.specular = float(max(num("specular_level"), 0.0))
    # normal map
    nm = _lookup(s, "normalmap_texture", time, m, "raw")
    if nm is not None:
        k = num("bump_factor")
        nm.scale, nm.bias = (2.0 * k, 2.0 * k, 2.0, 1.0), (-k, -k, -1.0, 0.0)
        table._normal_input(t, nm, label, "normalmap_texture", needs, (0.0, 0.0, 1.0))
    # emission
    if bool(val("enable_emission")):
        gain = num("emissive_intensity") * 2.0 ** KIT_EV
        etex = _lookup(s, "emissive_color_texture", time, m, "sRGB",
                       scale=tuple(np.asarray(rgb("emissive_color")) * gain) + (1.0,))
        esrc = etex if etex is not None else net.Const(tuple(np.asarray(rgb("emissive_color")) * gain))
        table._colour_input(t, "emission", esrc, (0.0, 0.0, 0.0), label, "emissive_color", needs)
    # opacity: a cut-out coverage
    if bool(val("enable_opacity")):
        threshold = float(np.clip(num("opacity_threshold"), 0.0, 1.0))
        otex = _lookup(s, "opacity_texture", time, m, "raw", 0) if bool(val("enable_opacity_texture")) else None
        if otex is not None:
            table._scalar_input(t, "alpha", otex, 1.0, label, "opacity_texture", needs)
        else:
            t.alpha = float(np.clip(num("opacity_constant"), 0.0, 1.0))
        t.alpha_threshold = threshold
    for name in IGNORED:
        inp = s.GetInput(name)
        if inp and inp.GetAttr().HasAuthoredValue() and inp.Get(time) not in (None, False, 0, 0.0, ""):
            table.warn(f"{label}: OmniPBR {name} is not supported (ignored)")
    return t

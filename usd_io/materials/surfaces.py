"""Surfaces other than UsdPreviewSurface: which reader a material's surface shader goes to.

``MaterialTable.convert`` reads a UsdPreviewSurface (``outputs:surface``) and MaterialX (``outputs:mtlx:surface``)
itself. Anything else comes here, in this order:

    1. Arnold (``outputs:arnold:surface``, or an ``arnold:*`` shader on any surface output): usd_io.materials.arnold
    2. a MaterialX Standard Surface / OpenPBR node on the universal ``outputs:surface``: the MaterialX reading
    3. MDL (``outputs:mdl:surface``) OmniPBR / OmniGlass: usd_io.materials.omnipbr
    4. nothing understood (another renderer's shader, or no surface at all): one warning naming the material and
       the shader, and the prim's displayColor as vertex colour (Hydra's fallback material: 0.5 grey only where the
       prim has no displayColor either) — never a silent 18 % grey.
"""

from __future__ import annotations

from pxr import UsdShade

from . import arnold, network as net, omnipbr

#: MaterialX surfaces: input names and the defaults of their node definitions (base colour = weight × colour).
MX_SURFACES = {
    "open_pbr_surface": dict(weight="base_weight", weight_default=1.0, base="base_color",
                             base_default=(0.8, 0.8, 0.8), metal="base_metalness", rough="specular_roughness",
                             rough_default=0.3, normal="geometry_normal", trans="transmission_weight",
                             ior="specular_ior", tint="transmission_color", spec="specular_weight",
                             dropped=("coat_weight", "emission_luminance", "subsurface_weight", "fuzz_weight")),
    "standard_surface": dict(weight="base", weight_default=0.8, base="base_color", base_default=(1.0, 1.0, 1.0),
                             metal="metalness", rough="specular_roughness", rough_default=0.2, normal="normal",
                             trans="transmission", ior="specular_IOR", tint="transmission_color",
                             emission="emission", emission_color="emission_color", spec="specular",
                             dropped=("coat", "subsurface", "sheen")),
}


#: displayColor read as the fallback material's vertex colour (Hydra's 0.5 grey where a prim has none).
DISPLAY_COLOR_FALLBACK = (0.5, 0.5, 0.5)


def other_surface(table, mat, preview, label: str, needs):
    """(fields) for a material whose surface is not a UsdPreviewSurface or outputs:mtlx:surface MaterialX."""
    candidates = [preview] if preview else []
    for context in ("arnold", "mdl"):
        s, _, _ = mat.ComputeSurfaceSource(context)
        if s and all(s.GetPath() != c.GetPath() for c in candidates):
            candidates.append(s)
    for out in mat.GetSurfaceOutputs():  # any other render context (ri, glslfx, ...): named in the warning
        for src in out.GetConnectedSources()[0]:
            s = UsdShade.Shader(src.source.GetPrim())
            if s and all(s.GetPath() != c.GetPath() for c in candidates):
                candidates.append(s)
    for s in candidates:
        sid = net.shader_id(s)
        if sid in arnold.AS_MATERIALX or any(f in sid for f in MX_SURFACES):
            return table.materialx(s, {}, label, needs, family=arnold.AS_MATERIALX.get(sid))
        if sid in arnold.SIMPLE_SURFACES:
            return arnold.simple_surface(table, s, label, needs)
        if omnipbr.is_omnipbr(s):
            return omnipbr.read_omnipbr(table, s, label, needs)
    names = ", ".join(f"{s.GetPath()} ({net.shader_id(s) or omnipbr.mdl_subidentifier(s) or s.GetPrim().GetTypeName()})"
                      for s in candidates) or "no surface shader"
    table.warn(f"{label}: surface {names} is not supported; rendered with the prim's displayColor")
    needs.color = ("displayColor", DISPLAY_COLOR_FALLBACK)
    return table.model(base_color=(1.0, 1.0, 1.0), vertex_color=True, specular=0.0)

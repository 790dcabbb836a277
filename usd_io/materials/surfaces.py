"""Surfaces other than UsdPreviewSurface: which reader a material's surface shader goes to.

``MaterialTable.convert`` reads a UsdPreviewSurface (``outputs:surface``) and MaterialX (``outputs:mtlx:surface``)
itself. Anything else comes here, in this order:

    1. Arnold (``outputs:arnold:surface``, or an ``arnold:*`` shader on any surface output): usd_io.materials.arnold
    2. a MaterialX surface (usd_io.materials.mtlx_surfaces: Standard Surface, OpenPBR, glTF PBR, Disney
       Principled, surface_unlit) on the universal ``outputs:surface``: the MaterialX reading
    3. MDL (``outputs:mdl:surface``) OmniPBR / OmniGlass: usd_io.materials.omnipbr
    4. nothing understood (another renderer's shader, or no surface at all): one warning naming the material and
       the shader, and the prim's displayColor as vertex colour (Hydra's fallback material: 0.5 grey only where the
       prim has no displayColor either) — never a silent 18 % grey.
"""

from __future__ import annotations

from pxr import UsdShade

from . import arnold, network as net, omnipbr
from .mtlx_surfaces import family_of as mtlx_family

#: displayColor read as the fallback material's vertex colour (Hydra's 0.5 grey where a prim has none).
DISPLAY_COLOR_FALLBACK = (0.5, 0.5, 0.5)


def other_surface(table, mat, preview, label: str, needs):
    """The PrincipledSurface of a material whose surface is not a UsdPreviewSurface or outputs:mtlx:surface MaterialX."""
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
        if sid in arnold.AS_MATERIALX or mtlx_family(sid):
            return table.materialx(s, None, label, needs, family=arnold.AS_MATERIALX.get(sid))
        if sid in arnold.SIMPLE_SURFACES:
            return arnold.simple_surface(table, s, label, needs)
        if omnipbr.is_omnipbr(s):
            return omnipbr.read_omnipbr(table, s, label, needs)
    names = ", ".join(f"{s.GetPath()} ({net.shader_id(s) or omnipbr.mdl_subidentifier(s) or s.GetPrim().GetTypeName()})"
                      for s in candidates) or "no surface shader"
    table.warn(f"{label}: surface {names} is not supported; rendered with the prim's displayColor")
    needs.color = ("displayColor", DISPLAY_COLOR_FALLBACK)
    return table.model(base_color=(1.0, 1.0, 1.0), vertex_color=True, specular=0.0)

"""``UsdShade`` materials -> rows of the tracer's material table.

Binding resolution is USD's: ``UsdShade.MaterialBindingAPI.ComputeBoundMaterial`` (direct and collection-based
bindings, binding strength, inheritance down the namespace) with purpose ``full`` (falling back to all-purpose),
then ``preview``; ``GeomSubset`` face sets of family ``materialBind`` override the prim's material on their faces.
Unbound geometry uses ``primvars:displayColor`` (constant or uniform; other interpolations are averaged).

UsdPreviewSurface mapping (one formula each; see docs/usd.md):

    diffuse       = diffuseColor (× the UsdUVTexture on it, scaled by its ``scale``; ``bias`` is ignored)
    specular R_s  = specularColor if useSpecularWorkflow else F0 = ((ior − 1)/(ior + 1))²
    exponent      = tracer.roughness_to_exponent(roughness)      (e = 2/r⁴ − 2, Walter et al. 2007)
    k_m           = metallic (metallic workflow only), mirror_tint = diffuseColor (a metal tints what it reflects)
    transmission  = 1 − opacity (refraction with ``ior``); with opacityThreshold > 0 it is a cut-out instead:
                    opacity < threshold -> fully transmissive with ior 1 (rays pass straight through)
    emission      = emissiveColor

A MaterialX OpenPBR (``ND_open_pbr_surface_surfaceshader``) or Standard Surface shader on
``outputs:mtlx:surface`` supplies ``transmission_weight``/``transmission`` (-> transmission),
``specular_ior``/``specular_IOR`` (-> ior) and ``transmission_color`` (-> transmission_tint): the only way a
Blender glass survives its USD export. Without a UsdPreviewSurface, base colour, metalness and specular roughness
come from it as well.
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf, UsdGeom, UsdShade

from tracer.texture import load_texture

FALLBACK_DIFFUSE = (0.18, 0.18, 0.18)  # UsdPreviewSurface's diffuseColor fallback
DEFAULT_DISPLAY = (0.5, 0.5, 0.5)  # Hydra's colour for geometry with neither material nor displayColor


def _f0(ior: float) -> float:
    return float(((ior - 1.0) / (ior + 1.0)) ** 2)


def _value(shader: UsdShade.Shader, name: str, default=None):
    """An input's value, following connections to interface inputs; (shader, output) if driven by a node."""
    inp = shader.GetInput(name)
    if not inp:
        return default
    attrs = inp.GetValueProducingAttributes()
    if not attrs:
        return default
    a = attrs[0]
    if UsdShade.Output.IsOutput(a):
        return UsdShade.Shader(a.GetPrim())
    v = a.Get()
    return default if v is None else v


def _num(shader, name, default):
    v = _value(shader, name, default)
    if isinstance(v, UsdShade.Shader):  # driven by a node we do not evaluate: take the node's own fallback
        v = _value(v, "fallback", _value(v, "value", default))
    try:
        return float(v) if np.ndim(v) == 0 else tuple(float(x) for x in v)
    except (TypeError, ValueError):
        return default


def _rgb(shader, name, default):
    v = _num(shader, name, default)
    v = np.asarray(v, dtype=np.float64).reshape(-1)
    return tuple(np.resize(v, 3)) if v.size else tuple(default)


class MaterialTable:
    """Converts and caches materials into a :class:`tracer.SceneBuilder`; records what each maps to."""

    def __init__(self, builder, time, warn):
        self.b = builder
        self.time = time
        self.warn = warn
        self.by_path: dict[str, tuple[int, str]] = {}  # material path -> (row, uv primvar name)
        self.summary: dict[str, dict] = {}  # material name -> tracer fields (for `whitted info`)
        self._textures: dict[str, int] = {}

    # ------------------------------------------------------------------ binding
    @staticmethod
    def bound_material(prim):
        api = UsdShade.MaterialBindingAPI(prim)
        for purpose in (UsdShade.Tokens.full, UsdShade.Tokens.preview):
            mat, _rel = api.ComputeBoundMaterial(purpose)
            if mat:
                return mat
        return None

    def for_prim(self, prim, n_faces: int, faces: np.ndarray):
        """(per-triangle material rows or one row, uv primvar name) for a gprim whose triangles come from
        ``faces``. GeomSubset bindings win on their faces; the prim's own binding (or displayColor) covers the
        rest and is not created at all when the subsets cover every face."""
        per_face = np.full(n_faces, -1, np.int64)
        uv = "st"
        subsets = UsdShade.MaterialBindingAPI(prim).GetMaterialBindSubsets() if prim.IsA(UsdGeom.Mesh) else []
        for subset in subsets:
            if subset.GetElementTypeAttr().Get() != UsdGeom.Tokens.face:
                continue
            smat = self.bound_material(subset.GetPrim())
            if smat is None:
                continue
            srow, suv = self.material(smat)
            idx = np.asarray(subset.GetIndicesAttr().Get(self.time) or [], dtype=np.int64)
            per_face[idx[(idx >= 0) & (idx < n_faces)]] = srow
            uv = suv if suv != "st" else uv
        if subsets and np.all(per_face >= 0):
            return per_face[faces], uv
        mat = self.bound_material(prim)
        if mat is not None:
            row, puv = self.material(mat)
            uv = puv if puv != "st" else uv
        else:
            row = self.display_color(prim, faces, n_faces)
        if not np.any(per_face >= 0):
            return row, uv
        tri_rows = per_face[faces]
        return np.where(tri_rows >= 0, tri_rows, row), uv

    # ------------------------------------------------------------------ displayColor
    def display_color(self, prim, faces, n_faces):
        pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor")
        vals = pv.ComputeFlattened(self.time) if pv and pv.HasValue() else None
        if vals is None or len(vals) == 0:
            return self._row_for_colour(DEFAULT_DISPLAY)
        c = np.asarray(vals, dtype=np.float64).reshape(-1, 3)
        interp = pv.GetInterpolation()
        if interp == UsdGeom.Tokens.uniform and len(c) == n_faces:
            uniq, inv = np.unique(np.round(c, 4), axis=0, return_inverse=True)
            if len(uniq) <= 1024:
                rows = np.array([self._row_for_colour(u) for u in uniq])
                return rows[inv.reshape(-1)][faces]
        if interp != UsdGeom.Tokens.constant and len(c) > 1:
            self.warn(f"{prim.GetPath()}: displayColor with {interp} interpolation is averaged "
                      "(the tracer has no vertex colours)")
        return self._row_for_colour(c.mean(axis=0) if interp != UsdGeom.Tokens.constant else c[0])

    def _row_for_colour(self, rgb):
        rgb = tuple(round(float(x), 4) for x in rgb)
        name = f"displayColor{rgb}"
        fields = dict(diffuse=rgb)
        self.summary.setdefault(name, fields)
        return self.b.add_material(name, **fields)

    # ------------------------------------------------------------------ UsdShade.Material
    def material(self, mat: UsdShade.Material):
        key = str(mat.GetPath())
        if key in self.by_path:
            return self.by_path[key]
        fields, uv = self.convert(mat)
        row = self.b.add_material(key, **fields)
        self.summary[key] = {k: (tuple(round(float(x), 4) for x in v) if np.ndim(v) else
                                 (round(float(v), 4) if isinstance(v, float) else v)) for k, v in fields.items()}
        self.by_path[key] = (row, uv)
        return row, uv

    def convert(self, mat: UsdShade.Material):
        """Tracer material fields and the uv primvar name for one material."""
        preview, _, _ = mat.ComputeSurfaceSource()
        mtlx, _, _ = mat.ComputeSurfaceSource("mtlx")
        if mtlx and mtlx.GetPath() == (preview.GetPath() if preview else None):
            mtlx = None  # no mtlx-specific output: ComputeSurfaceSource fell back to the universal one
        fields, uv = {}, "st"
        if preview and _shader_id(preview) == "UsdPreviewSurface":
            fields, uv = self.preview_surface(preview)
        elif preview and not mtlx:
            self.warn(f"{mat.GetPath()}: surface shader {_shader_id(preview)!r} is not supported; using grey")
            fields = dict(diffuse=FALLBACK_DIFFUSE)
        if mtlx:
            fields = self.materialx(mtlx, fields, str(mat.GetPath()))
        if not fields:
            fields = dict(diffuse=FALLBACK_DIFFUSE)
        return fields, uv

    def preview_surface(self, s: UsdShade.Shader):
        t = dict(diffuse=FALLBACK_DIFFUSE)
        uv = "st"
        dc = _value(s, "diffuseColor", FALLBACK_DIFFUSE)
        if isinstance(dc, UsdShade.Shader):
            tex, scale, uv = self.uv_texture(dc)
            if tex is not None:
                t["diffuse_texture"] = tex
                t["diffuse"] = scale
            else:
                t["diffuse"] = _rgb(dc, "fallback", FALLBACK_DIFFUSE)
        else:
            t["diffuse"] = _rgb(s, "diffuseColor", FALLBACK_DIFFUSE)
        metallic = float(np.clip(_num(s, "metallic", 0.0), 0, 1))
        rough = float(np.clip(_num(s, "roughness", 0.5), 0, 1))
        ior = float(_num(s, "ior", 1.5))
        ior = ior if ior > 0 else 1.5
        opacity = float(np.clip(_num(s, "opacity", 1.0), 0, 1))
        threshold = float(_num(s, "opacityThreshold", 0.0))
        if int(_num(s, "useSpecularWorkflow", 0)):
            t["specular"] = _rgb(s, "specularColor", (0.0, 0.0, 0.0))
        else:
            t["specular"] = (_f0(ior),) * 3
        t["roughness"] = rough
        if metallic > 0 and not int(_num(s, "useSpecularWorkflow", 0)):  # metallic is ignored in that workflow
            t["k_m"] = metallic
            t["mirror_tint"] = t["diffuse"] if "diffuse_texture" not in t else (1.0, 1.0, 1.0)
        if threshold > 0:
            if opacity < threshold:
                t.update(transmission=1.0, ior=1.0)
        elif opacity < 1:
            t["transmission"] = 1.0 - opacity
        t.setdefault("ior", ior)
        em = _rgb(s, "emissiveColor", (0.0, 0.0, 0.0))
        if any(em):
            t["emission"] = em
        return t, uv

    def uv_texture(self, tex: UsdShade.Shader):
        """(texture index or None, scale rgb, uv primvar name) of a UsdUVTexture node."""
        if _shader_id(tex) != "UsdUVTexture":
            self.warn(f"{tex.GetPath()}: diffuseColor driven by {_shader_id(tex)!r}, not UsdUVTexture; "
                      "using its fallback")
            return None, None, "st"
        asset = _value(tex, "file")
        path = asset.resolvedPath if isinstance(asset, Sdf.AssetPath) else ""
        scale = _rgb(tex, "scale", (1.0, 1.0, 1.0, 1.0))
        uv = "st"
        st = _value(tex, "st")
        if isinstance(st, UsdShade.Shader):
            name = _value(st, "varname", "st")
            uv = str(name) if name else "st"
        if not path:
            shown = asset.path if isinstance(asset, Sdf.AssetPath) else asset
            self.warn(f"{tex.GetPath()}: texture {shown!r} not found; using the fallback colour")
            return None, None, uv
        if path not in self._textures:
            cs = str(_value(tex, "sourceColorSpace", "auto"))
            cs = {"sRGB": "srgb", "raw": "raw"}.get(cs, "auto")
            try:
                self._textures[path] = self.b.add_texture(load_texture(path, cs))
            except ValueError as exc:
                self.warn(f"{tex.GetPath()}: {exc}; using the fallback colour")
                return None, None, uv
        return self._textures[path], scale, uv

    def materialx(self, s: UsdShade.Shader, fields: dict, label: str) -> dict:
        sid = _shader_id(s)
        if "open_pbr_surface" in sid:
            names = dict(base="base_color", metal="base_metalness", rough="specular_roughness",
                         trans="transmission_weight", ior="specular_ior", tint="transmission_color")
        elif "standard_surface" in sid:
            names = dict(base="base_color", metal="metalness", rough="specular_roughness",
                         trans="transmission", ior="specular_IOR", tint="transmission_color")
        else:
            if not fields:
                self.warn(f"{label}: MaterialX shader {sid!r} is not supported")
            return fields
        out = dict(fields)
        if not fields:  # no UsdPreviewSurface: take the basics from MaterialX
            base = _rgb(s, names["base"], (0.8, 0.8, 0.8))
            ior = float(_num(s, names["ior"], 1.5))
            out.update(diffuse=base, roughness=float(_num(s, names["rough"], 0.3)), specular=(_f0(ior),) * 3)
            metal = float(_num(s, names["metal"], 0.0))
            if metal > 0:
                out.update(k_m=min(metal, 1.0), mirror_tint=base)
        trans = _num(s, names["trans"], None)
        if trans is not None and float(trans) > 0:
            out["transmission"] = float(np.clip(trans, 0, 1))
            out["transmission_tint"] = _rgb(s, names["tint"], (1.0, 1.0, 1.0))
        ior = _num(s, names["ior"], None)
        if ior is not None and float(ior) > 0:
            out["ior"] = float(ior)
        return out


def _shader_id(s: UsdShade.Shader) -> str:
    sid = s.GetShaderId() if s else None
    return str(sid) if sid else ""


"""``UsdShade`` materials -> rows of the tracer's material table (+ textures, UV sets and vertex colours).

Binding resolution is USD's: ``UsdShade.MaterialBindingAPI.ComputeBoundMaterial`` (direct and collection-based
bindings, binding strength, inheritance down the namespace) with purpose ``full`` (falling back to all-purpose),
then ``preview``; ``GeomSubset`` face sets of family ``materialBind`` override the prim's material on their faces.
Unbound geometry shows ``primvars:displayColor`` (any interpolation, as a vertex colour; 0.5 grey without one).

UsdPreviewSurface -> the tracer's Principled model (docs/materials-api.md), input by input; every input may be a
constant, a ``UsdUVTexture`` output (r, g, b, a or rgb; scale, bias, wrap, colour space, UsdTransform2d, UV set:
see :mod:`usd_io.materials.network`) or, for diffuseColor, a colour primvar reader (vertex colour):

    diffuseColor        base_color (texture or vertex colour replaces the constant, as a connection does in USD)
    metallic            metallic                         (metallic workflow; ignored in the specular workflow)
    roughness           roughness
    useSpecularWorkflow + specularColor: F0 = specularColor (its mean; one warning if it is coloured), written as the
                        Principled specular level 0.5·F0 / F0(ior), or as an ior giving F0 when that level passes 1
    ior                 ior (F0 = ((ior − 1)/(ior + 1))², the Principled default specular level 0.5)
    opacity             opacityThreshold > 0: a cut-out (alpha_threshold; opacity < threshold is not there at all).
                        threshold 0 and a texture: alpha blending (the texture's alpha or channel as coverage).
                        threshold 0 and a constant < 1: transmission = 1 − opacity, refracting with ior (the spec's
                        "transparent but still specular"; how Blender's glass survives its USD export)
    emissiveColor       emission (constant or texture; emissive triangles light the scene)
    normal              normal map, tangent space, +Y up (OpenGL, the spec's and glTF's), value = texel·scale + bias;
                        8-bit maps carry scale (2, 2, 2, 1), bias (−1, −1, −1, 0); DirectX-style maps author a
                        negative green scale (McUsd) and come out right through the same formula
    clearcoat           not supported: one warning when > 0 or connected
    occlusion           ignored (a ray tracer shadows for itself): one note when authored
    displacement        not supported: one warning when connected or ≠ 0

A MaterialX surface shader on ``outputs:mtlx:surface`` (or on the universal output) — Standard Surface, OpenPBR,
glTF PBR, Disney Principled, surface_unlit — is read by :mod:`usd_io.materials.mtlx_surfaces` as MaterialX's own
node-graph implementations define it (its coats as layers over the Principled base,
:class:`tracer.shading.principled.PrincipledSurface`'s ``layers``), any other (pbrlib's ``surface``, Lama, a document's own) by :mod:`usd_io.materials.mtlx_closures` as a
closure network; beside a UsdPreviewSurface only transmission, its colour and the IOR come from it (the only way a
Blender glass survives its USD export). MaterialX's own UsdPreviewSurface node (``ND_UsdPreviewSurface_surfaceshader``)
is a UsdPreviewSurface. ``.mtlx`` documents referenced from USD are translated by :mod:`usd_io.materials.mtlx`
before any of this sees them.

Any other surface (Arnold's, NVIDIA's OmniPBR, or one nothing reads) goes to :mod:`usd_io.materials.surfaces`; an
unread one shows the prim's displayColor with a warning, never a silent 18 % grey. Everything dropped or
approximated prints one warning naming the material and the input or node.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pxr import UsdGeom, UsdShade

from tracer.shading.compiler import add_graph
from tracer.shading.graph import ImageRef
from tracer.shading.materials import f0_from_ior as _f0_from_ior
from tracer.shading.principled import PrincipledSurface

from . import network as net
from .preview_ranges import clamp_preview_inputs
from .primvars import DEFAULT_UV, find_primvar, mesh_primvars
from .mtlx_surfaces import read as read_mtlx_surface
from ..exporters import written_for_arnold
from .arnold import DEFAULT_SURFACE as ARNOLD_DEFAULT_SURFACE
from .surfaces import other_surface
from .texture_assets import open_texture
from .texture_files import TextureCache, resolve_wrap

FALLBACK_DIFFUSE = (0.18, 0.18, 0.18)  # UsdPreviewSurface's diffuseColor fallback
DEFAULT_DISPLAY = (0.5, 0.5, 0.5)  # Hydra's colour for geometry with neither material nor displayColor

#: UsdPreviewSurface inputs and their spec fallbacks.
PREVIEW_DEFAULTS = dict(diffuseColor=FALLBACK_DIFFUSE, emissiveColor=(0.0, 0.0, 0.0), useSpecularWorkflow=0,
                        specularColor=(0.0, 0.0, 0.0), metallic=0.0, roughness=0.5, clearcoat=0.0,
                        clearcoatRoughness=0.01, opacity=1.0, opacityThreshold=0.0, ior=1.5,
                        normal=(0.0, 0.0, 1.0), displacement=0.0, occlusion=1.0)


def f0_from_ior(ior: float) -> float:
    """UsdPreviewSurface's F0 of a dielectric (:func:`tracer.shading.materials.f0_from_ior`, the one formula)."""
    return float(_f0_from_ior(ior))


@dataclass(eq=False)
class UVLookup:
    """A UsdUVTexture (or MaterialX image) lookup as the reader resolved it, before it is written as IR nodes:
    the image (:class:`tracer.shading.graph.ImageRef`, wrap resolved), the UV primvar (None = the default set),
    the composed UsdTransform2d matrix and the spec's scale, bias and fallback."""

    image: object
    uv: str | None
    transform: np.ndarray
    scale: tuple
    bias: tuple
    fallback: tuple
    label: str = ""

    def write(self, g, memo: dict):
        """Its IR nodes in ``g`` (a lookup of tracer.shading.principled): a ``usd_uv_texture`` node read at the
        ``uvmap`` of its primvar through ``usd_transform2d``; (the node, the UV map name)."""
        uv = self.uv if self.uv not in (None, "st") else ""
        st = g.add("uvmap", attribute=uv)["UV"]
        if not np.allclose(self.transform, np.eye(3)):
            st = g.add("usd_transform2d", {"in": st}, matrix=np.asarray(self.transform, np.float64))["result"]
        node = g.add("usd_uv_texture", {"st": st}, image=self.image, scale=tuple(self.scale), bias=tuple(self.bias),
                     fallback=tuple(self.fallback), name=self.label)
        return node, uv


@dataclass
class PrimvarColour:
    """A lookup (tracer.shading.principled) of the mesh's colour primvar ``name`` (its vertex colour, Scene.colors):
    what a primvar reader or Arnold's user_data_rgb upstream of a colour input other than the base colour (an
    arnold:flat's color, an emission) reads."""

    name: str

    def write(self, g, memo: dict):
        col = g.add("vertex_color", layer_name=self.name)
        rgb = g.add("separate_color", {"Color": col["Color"]})
        return dict(rgb=col["Color"], r=rgb["Red"], g=rgb["Green"], b=rgb["Blue"], a=col["Alpha"]), None


def ior_from_f0(f0: float) -> float:
    """The inverse of :func:`f0_from_ior`."""
    r = float(np.sqrt(np.clip(f0, 0.0, 0.999)))
    return (1.0 + r) / (1.0 - r)


@dataclass
class MeshNeeds:
    """What a mesh must supply for its materials: UV sets by name (DEFAULT_UV = its default set) and a colour
    primvar (name, fallback) read as vertex colour."""

    uv_sets: set = field(default_factory=set)
    color: tuple | None = None

    def merge(self, other: "MeshNeeds", warn, label: str) -> None:
        self.uv_sets |= other.uv_sets
        if other.color is not None:
            if self.color is not None and self.color[0] != other.color[0]:
                warn(f"{label}: materials read two colour primvars ({self.color[0]!r}, {other.color[0]!r}); "
                     f"only {self.color[0]!r} is used (one vertex colour per mesh)")
            else:
                self.color = other.color


class MaterialTable:
    """Converts and caches materials into a :class:`tracer.SceneBuilder`; records what each maps to."""

    def __init__(self, builder, time, warn):
        self.b = builder
        self.time = time
        self.warn = warn
        self.by_path: dict[str, tuple[int, MeshNeeds]] = {}  # material path -> (row, needs)
        self.summary: dict[str, dict] = {}  # material name -> tracer fields (for `whitted info`)
        self.files = TextureCache()
        self._textures: dict = {}  # lookup key -> UVLookup
        self._images: dict = {}  # (pixels id, wraps) -> ImageRef (one tracer texture per image and wrap)
        self.uv_set_names: list[str] = [DEFAULT_UV]  # index in Scene.uv_sets
        self.writer = self  # ``writer.add_material(name, fields)``: what usd_io.reader calls
        self._primvar_cache: dict = {}
        self._defaults: dict = {}  # fallback surfaces made once: name -> row
        self._arnold_stage: bool | None = None  # usd_io.exporters.written_for_arnold, asked at the first unbound prim

    # ------------------------------------------------------------------ binding
    @staticmethod
    def bound_material(prim):
        api = UsdShade.MaterialBindingAPI(prim)
        for purpose in (UsdShade.Tokens.full, UsdShade.Tokens.preview):
            mat, _rel = api.ComputeBoundMaterial(purpose)
            if mat:
                return mat
        return None

    def for_prim(self, prim, n_faces: int, faces: np.ndarray, display_color_given: bool = False):
        """(per-triangle material rows or one row, MeshNeeds) for a gprim whose triangles come from ``faces``.
        GeomSubset bindings win on their faces; the prim's own binding (or displayColor) covers the rest and is
        not created at all when the subsets cover every face. ``display_color_given``: a PointInstancer gives the
        prim a displayColor per instance (unbound, it reads one even without its own)."""
        per_face = np.full(n_faces, -1, np.int64)
        needs = MeshNeeds()
        label = str(prim.GetPath())
        subsets = UsdShade.MaterialBindingAPI(prim).GetMaterialBindSubsets() if prim.IsA(UsdGeom.Mesh) else []
        for subset in subsets:
            if subset.GetElementTypeAttr().Get() != UsdGeom.Tokens.face:
                continue
            smat = self.bound_material(subset.GetPrim())
            if smat is None:
                continue
            srow, sneeds = self.material(smat)
            idx = np.asarray(subset.GetIndicesAttr().Get(self.time) or [], dtype=np.int64)
            per_face[idx[(idx >= 0) & (idx < n_faces)]] = srow
            needs.merge(sneeds, self.warn, label)
        if subsets and np.all(per_face >= 0):
            return per_face[faces], needs
        mat = self.bound_material(prim)
        if mat is not None:
            row, pneeds = self.material(mat)
        else:
            row, pneeds = self.display_color(prim, display_color_given)
        needs.merge(pneeds, self.warn, label)
        if not np.any(per_face >= 0):
            return row, needs
        tri_rows = per_face[faces]
        return np.where(tri_rows >= 0, tri_rows, row), needs

    def mesh_inputs(self, prim, data, rows, needs: MeshNeeds):
        """(per-triangle material rows, add_mesh keywords: UV sets and vertex colours) for one mesh."""
        key = None
        if prim.IsInstanceProxy():  # instances share their prototype's primvars: expand them once
            key = (str(prim.GetPrimInPrototype().GetPath()), id(data), frozenset(needs.uv_sets), needs.color,
                   self.instance_colour_source(prim, needs))
        if key is not None and key in self._primvar_cache:
            uv_sets, colors = self._primvar_cache[key]
        else:
            uv_sets, colors = mesh_primvars(prim, data, needs, self.uv_set_names, self.time, self.warn)
            if key is not None:
                self._primvar_cache[key] = (uv_sets, colors)
        kw = {}
        if uv_sets:
            kw["uv_sets"] = uv_sets
            if 0 in uv_sets:
                kw["uvs"] = uv_sets[0]
        if colors is not None:
            kw["colors"] = colors
        return rows, kw

    @staticmethod
    def instance_colour_source(prim, needs: MeshNeeds):
        """For an instance proxy: the path of the prim outside its prototype that gives it its colour primvar (a
        constant primvar inherited from the instanceable prim or above it: each native instance its own value, as
        Hydra and Arnold read it), else None (the prototype's own value, shared by every instance)."""
        if needs.color is None or not prim.IsInstanceProxy():
            return None
        pv = find_primvar(prim, needs.color[0])
        if pv is None:
            return None
        owner = pv.GetAttr().GetPrim()
        return str(owner.GetPath()) if not owner.IsInstanceProxy() else None

    def uv_set_index(self, name: str | None) -> int:
        """Index in Scene.uv_sets of a texture's UV primvar (None and "st" read the mesh's default set 0)."""
        key = DEFAULT_UV if name in (None, "", "st") else name
        if key not in self.uv_set_names:
            self.uv_set_names.append(key)
        return self.uv_set_names.index(key)

    # ------------------------------------------------------------------ displayColor
    def display_color(self, prim, given: bool = False):
        """Unbound geometry: displayColor as a vertex colour (any interpolation), on a plain diffuse surface; on a
        stage written for Arnold, Arnold's fallback standard_surface (usd_io.materials.arnold.DEFAULT_SURFACE)."""
        if self._arnold_stage is None:  # asked once per table (one stage)
            self._arnold_stage = written_for_arnold(prim.GetStage()) is not None
        if self._arnold_stage:
            return self._arnold_default(), MeshNeeds(color=("displayColor", (1.0, 1.0, 1.0)))
        pv = find_primvar(prim, "displayColor")  # inherited from ancestors as UsdGeomPrimvarsAPI says
        if pv is None and not given:
            return self._plain("displayColor(none)", DEFAULT_DISPLAY), MeshNeeds()
        op = UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayOpacity")
        if op and op.HasValue():
            vals = np.asarray(op.ComputeFlattened(self.time) or [1.0], np.float64)
            if np.any(vals < 1):
                self.warn(f"{prim.GetPath()}: displayOpacity is not supported (rendered opaque)")
        row = self._plain("displayColor", (1.0, 1.0, 1.0), vertex_color=True)
        return row, MeshNeeds(color=("displayColor", DEFAULT_DISPLAY))

    def _arnold_default(self) -> int:
        name = "arnold:default_surface"
        if name not in self._defaults:
            surface = self.model(vertex_color=True, **ARNOLD_DEFAULT_SURFACE)
            self.summary.setdefault(name, surface.summary())
            self._defaults[name] = self.add_material(name, surface, MeshNeeds(color=("displayColor", (1.0, 1.0, 1.0))))
        return self._defaults[name]

    def _plain(self, name, rgb, **extra):
        surface = self.model(base_color=tuple(float(x) for x in rgb), specular=0.0, **extra)
        self.summary.setdefault(name, surface.summary())
        return self.add_material(name, surface)

    # ------------------------------------------------------------------ UsdShade.Material
    def material(self, mat: UsdShade.Material):
        key = str(mat.GetPath())
        if key in self.by_path:
            return self.by_path[key]
        surface, needs = self.convert(mat)
        row = self.add_material(key, surface, needs)
        self.summary[key] = surface.summary()
        self.by_path[key] = (row, needs)
        return row, needs

    def convert(self, mat: UsdShade.Material):
        """(the material's :class:`PrincipledSurface`, its MeshNeeds)."""
        preview, _, _ = mat.ComputeSurfaceSource()
        mtlx, _, _ = mat.ComputeSurfaceSource("mtlx")
        if mtlx and mtlx.GetPath() == (preview.GetPath() if preview else None):
            mtlx = None  # no mtlx-specific output: ComputeSurfaceSource fell back to the universal one
        fields, needs = None, MeshNeeds()
        label = str(mat.GetPath())
        if mtlx and is_preview_surface(mtlx) and not (preview and is_preview_surface(preview)):
            preview, mtlx = mtlx, None  # MaterialX's UsdPreviewSurface node: the same inputs, the same reading
        if preview and is_preview_surface(preview):
            fields, needs = self.preview_surface(preview, label)
        if mtlx:
            fields = self.materialx(mtlx, fields, label, needs)
        if fields is None:  # Arnold, MDL OmniPBR, or nothing understood (displayColor + a warning): usd_io.materials.surfaces
            fields = other_surface(self, mat, preview, label, needs)
        return fields, needs

    # ------------------------------------------------------------------ UsdPreviewSurface
    def preview_surface(self, s: UsdShade.Shader, label: str):
        """(PrincipledSurface, MeshNeeds) of one UsdPreviewSurface."""
        t = self.model()
        needs = MeshNeeds()
        src = {name: net.source(s, name, default, self.time) for name, default in PREVIEW_DEFAULTS.items()}
        src = clamp_preview_inputs(src, label, self.warn)  # the spec's ranges (usd_io.materials.preview_ranges)

        # diffuseColor -> base colour
        d = src["diffuseColor"]
        if isinstance(d, net.PrimvarLookup):
            fb = net.floats(d.fallback, 3, (0.0, 0.0, 0.0)) if d.fallback is not None else (0.0, 0.0, 0.0)
            needs.color = (d.name, fb)
            t.update(base_color=(1.0, 1.0, 1.0), vertex_color=True)
        else:
            self._colour_input(t, "base_color", d, FALLBACK_DIFFUSE, label, "diffuseColor", needs)

        spec_wf = int(self._const(src["useSpecularWorkflow"], 0, label, "useSpecularWorkflow") or 0)
        ior = float(self._const(src["ior"], 1.5, label, "ior"))
        if not (np.isfinite(ior) and ior > 0):
            ior = 1.5
        t.ior = ior
        self._scalar_input(t, "roughness", src["roughness"], 0.5, label, "roughness", needs)
        if spec_wf:
            if not _is_default(src["metallic"], 0.0):
                self.warn(f"{label}: metallic is ignored with useSpecularWorkflow = 1 (as the spec says)")
            sc = src["specularColor"]
            if not isinstance(sc, net.Const):
                self.warn(f"{label}: specularColor driven by {self._what(sc)} is not supported "
                          "(its fallback is used)")
            rgb = np.asarray(net.floats(self._fallback_of(sc, (0.0, 0.0, 0.0)), 3, (0.0, 0.0, 0.0)))
            if np.ptp(rgb) > 1e-3:
                self.warn(f"{label}: coloured specularColor {tuple(np.round(rgb, 3))} is used as its mean "
                          "(the Principled model has a grey dielectric F0)")
            f0 = float(np.clip(rgb.mean(), 0.0, 1.0))
            level = 0.5 * f0 / max(f0_from_ior(ior), 1e-9)
            if level <= 1.0:
                t.specular = level
            else:
                t.specular = 0.5
                t.ior = ior_from_f0(f0)
            t.metallic = 0.0
        else:
            t.specular = 0.5
            self._scalar_input(t, "metallic", src["metallic"], 0.0, label, "metallic", needs)

        # opacity
        threshold = float(self._const(src["opacityThreshold"], 0.0, label, "opacityThreshold"))
        op = src["opacity"]
        if isinstance(op, net.Const):
            opacity = float(np.clip(net.floats(op.value, 1, (1.0,))[0], 0.0, 1.0))
            if threshold > 0:
                t.alpha = 0.0 if opacity < threshold else 1.0
            elif opacity < 1:
                t.transmission = 1.0 - opacity
        else:
            self._scalar_input(t, "alpha", op, 1.0, label, "opacity", needs)
            t.alpha_threshold = max(threshold, 0.0)

        self._colour_input(t, "emission", src["emissiveColor"], (0.0, 0.0, 0.0), label, "emissiveColor", needs)

        self._normal_input(t, src["normal"], label, "normal", needs, (0.0, 0.0, 1.0))

        # what the model leaves out
        if not _is_default(src["clearcoat"], 0.0):
            self.warn(f"{label}: clearcoat is not supported (dropped)")
        if not _is_default(src["occlusion"], 1.0):
            self.warn(f"{label}: occlusion is ignored (a ray tracer computes its own shadowing)")
        if not _is_default(src["displacement"], 0.0):
            self.warn(f"{label}: displacement is not supported (dropped)")
        return t, needs

    # ------------------------------------------------------------------ inputs
    def _normal_input(self, t, n, label, name, needs, neutral):
        """A tangent-space normal map (a texture lookup whose scale and bias give the normal); a constant equal
        to ``neutral`` (or unauthored) is nothing; anything else warns."""
        if isinstance(n, net.TextureLookup):
            idx, _const = self._texture(n, label, name, needs)
            if idx is not None:
                t.read("normal", idx)
        elif isinstance(n, net.GraphLookup):  # a MaterialX normalmap/bump network: a world-space normal
            t.normal_graph = self._graph(n, label, name, needs)
        elif isinstance(n, net.Const):
            if n.value is not None and not np.allclose(net.floats(n.value, 3, neutral), neutral):
                self.warn(f"{label}: a constant {name} {tuple(n.value)} is not supported (ignored)")
        else:
            self.warn(f"{label}: {name} driven by {self._what(n)} is not supported (ignored)")

    def _what(self, src) -> str:
        if isinstance(src, net.PrimvarLookup):
            return f"{src.reader} {src.node!r} (primvar {src.name!r})"
        if isinstance(src, net.Unsupported):
            return f"{src.shader_id!r} node {src.node!r}"
        if isinstance(src, net.TextureLookup):
            return f"UsdUVTexture {src.node!r}"
        return "a value"

    @staticmethod
    def _fallback_of(src, default):
        if isinstance(src, net.Const):
            return src.value
        if isinstance(src, net.TextureLookup):
            return src.fallback
        v = getattr(src, "fallback", None)
        return default if v is None else v

    def _const(self, src, default, label, name):
        """A constant-only input (a connection to a node is not supported: one warning, the node's fallback)."""
        if isinstance(src, net.Const):
            return net.floats(src.value, 1, (default,))[0]
        self.warn(f"{label}: {name} driven by {self._what(src)} is not supported (constant {default} used)")
        return default

    def _graph(self, src, label, name, needs):
        # here, not at import: mtlx_graph loads the MaterialX library, which a stage without networks never needs
        from .mtlx_graph import MxProgram

        return MxProgram(self, src, label, name, needs)

    def _scalar_input(self, t, key, src, default, label, name, needs):
        if isinstance(src, net.Const):
            setattr(t, key, float(net.floats(src.value, 1, (default,))[0]))
            return
        if isinstance(src, net.GraphLookup):
            setattr(t, key, 1.0)
            t.read(key, self._graph(src, label, name, needs), 0)
            return
        if isinstance(src, net.TextureLookup):
            idx, const = self._texture(src, label, name, needs)
            if idx is not None:
                setattr(t, key, 1.0)
                t.read(key, idx, src.channel if src.channel >= 0 else 0)
                return
            setattr(t, key, float(const[src.channel if src.channel >= 0 else 0]))
            return
        fb = self._fallback_of(src, default)
        self.warn(f"{label}: {name} driven by {self._what(src)} is not supported (fallback {fb} used)")
        setattr(t, key, float(net.floats(fb, 1, (default,))[0]))

    def _colour_input(self, t, key, src, default, label, name, needs):
        if isinstance(src, net.Const):
            setattr(t, key, net.floats(src.value, 3, default))
            return
        if isinstance(src, net.GraphLookup):
            setattr(t, key, (1.0, 1.0, 1.0))
            t.read(key, self._graph(src, label, name, needs), -1)
            return
        if isinstance(src, net.TextureLookup):
            idx, const = self._texture(src, label, name, needs)
            if idx is not None:
                setattr(t, key, (1.0, 1.0, 1.0))
                t.read(key, idx, src.channel)  # -1 = rgb; a single channel is read as grey
                return
            c = const[src.channel] if src.channel >= 0 else None
            setattr(t, key, (c, c, c) if c is not None else tuple(const[:3]))
            return
        if isinstance(src, net.PrimvarLookup) and (needs.color is None or needs.color[0] == src.name):
            # the mesh's vertex colour (one colour primvar per mesh: MeshNeeds), its fallback where it has none
            needs.color = (src.name, net.floats(src.fallback, 3, default) if src.fallback is not None else default)
            setattr(t, key, (1.0, 1.0, 1.0))
            t.read(key, PrimvarColour(src.name), -1)
            return
        fb = self._fallback_of(src, default)
        self.warn(f"{label}: {name} driven by {self._what(src)} is not supported (fallback {fb} used)")
        setattr(t, key, net.floats(fb, 3, default))

    def _texture(self, lk: net.TextureLookup, label: str, name: str, needs: MeshNeeds):
        """(texture index, None) for a readable UsdUVTexture; (None, its fallback as 4 floats) otherwise, with one
        warning. Textures are shared between inputs that read one node the same way."""
        for note in lk.notes:
            self.warn(f"{lk.node}: {note}")
        for what, default in (("scale", net.UV_TEXTURE_DEFAULTS["scale"]), ("bias", net.UV_TEXTURE_DEFAULTS["bias"]),
                              ("fallback", net.UV_TEXTURE_DEFAULTS["fallback"])):
            if not np.all(np.isfinite(getattr(lk, what))):
                self.warn(f"{lk.node}: {what} {getattr(lk, what)} is not finite (the spec's {default} used)")
                setattr(lk, what, tuple(default))
        if not np.all(np.isfinite(lk.transform)):
            self.warn(f"{lk.node}: its UsdTransform2d is not finite (ignored)")
            lk.transform = np.eye(3)
        asset = lk.asset
        if asset is None or not asset.path:
            self.warn(f"{label}: {name} texture {lk.node!r} has no file; its fallback {lk.fallback} is used")
            return None, lk.fallback
        cs = lk.colorspace if lk.colorspace in ("sRGB", "raw") or lk.colorspace.startswith("mx:") else "auto"
        if lk.colorspace not in ("sRGB", "raw", "auto") and not lk.colorspace.startswith("mx:"):
            self.warn(f"{lk.node}: unknown sourceColorSpace {lk.colorspace!r} (auto used)")
        got = open_texture(lk, cs, self.files, self.warn, label, name)  # UDIM sets, backslashes: texture_assets
        if got is None:
            return None, lk.fallback
        f, udim_m = got
        lk.transform = udim_m @ lk.transform
        wrap_s = resolve_wrap(lk.wrap_s, f.wrap_meta[0], lk.node, self.warn)
        wrap_t = resolve_wrap(lk.wrap_t, f.wrap_meta[1], lk.node, self.warn)
        uv_set = self.uv_set_index(lk.uv)
        needs.uv_sets.add(self.uv_set_names[uv_set])
        key = (id(f.pixels), wrap_s, wrap_t, uv_set, lk.transform.round(9).tobytes(), lk.scale, lk.bias, lk.fallback)
        if key not in self._textures:
            ikey = (id(f.pixels), wrap_s, wrap_t)
            if ikey not in self._images:
                self._images[ikey] = ImageRef(pixels=f.pixels, wrap_s=wrap_s, wrap_t=wrap_t,
                                              label=f"{asset.path} ({lk.node})")
            self._textures[key] = UVLookup(self._images[ikey], lk.uv, lk.transform, lk.scale, lk.bias, lk.fallback,
                                           label=f"{asset.path} ({lk.node})")
        return self._textures[key], None

    # ------------------------------------------------------------------ the tracer's model
    @staticmethod
    def model(**inputs) -> PrincipledSurface:
        """A new surface description (tracer.shading.principled): the Principled BSDF's defaults but
        UsdPreviewSurface's diffuseColor fallback, then ``inputs``; written as IR by :meth:`add_material`."""
        return PrincipledSurface(base_color=FALLBACK_DIFFUSE).update(**inputs)

    def add_material(self, name: str, surface: PrincipledSurface, needs: MeshNeeds | None = None) -> int:
        """Write one surface as a shader graph (tracer.shading.graph) and add its row (tracer.shading.compiler)."""
        color = needs.color[0] if needs is not None and needs.color is not None else "displayColor"
        return add_graph(self.b, surface.graph(name, color), self.warn, self.uv_set_index, name=name)

    # ------------------------------------------------------------------ MaterialX
    def materialx(self, s: UsdShade.Shader, fields: PrincipledSurface | None, label: str, needs: MeshNeeds,
                  family=None) -> PrincipledSurface | None:
        """A MaterialX surface shader (Standard Surface, OpenPBR, glTF PBR, Disney Principled, surface_unlit, or a
        closure network): :mod:`usd_io.materials.mtlx_surfaces`. With a UsdPreviewSurface beside it (``fields``)
        only transmission, its colour and the IOR come from it."""
        return read_mtlx_surface(self, s, fields, label, needs, family)


#: Shader ids of UsdPreviewSurface: its own, and MaterialX's node definition of it (what usdMtlx writes for a
#: ``<UsdPreviewSurface>`` in a .mtlx document, e.g. on ``outputs:mtlx:surface``).
PREVIEW_SURFACE_IDS = ("UsdPreviewSurface", "ND_UsdPreviewSurface_surfaceshader")


def is_preview_surface(shader) -> bool:
    return net.shader_id(shader) in PREVIEW_SURFACE_IDS


def _is_default(src, default) -> bool:
    """Whether an input is left at its default (unconnected, and equal to ``default``)."""
    if not isinstance(src, net.Const):
        return False
    return bool(np.allclose(net.floats(src.value, 1, (default,))[0], default))

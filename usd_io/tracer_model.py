"""Writing what usd_io read into the tracer's material model — the Principled model of docs/materials-api.md
(``tracer.Texture``, ``Scene.uv_sets``, ``Scene.colors``, ``tracer.Environment``) when the tracer has it, else the
classic table (diffuse + one diffuse texture) with the rest lowered exactly where possible and approximated, with
one warning each, where not.

The material reader (:mod:`usd_io.material`) describes each material in the Principled model's fields, with
:class:`TextureSpec` for texture lookups; this module is the only place that knows which model the tracer
carries. Lowering to the classic table:

    base_color texture  its pixels baked with channel, scale and bias (exact: bilinear filtering commutes with an
                        affine map); its UsdTransform2d and UV set baked into each triangle's corner UVs (exact:
                        an affine map of the UVs commutes with barycentric interpolation). Wrap modes other than
                        repeat: one warning when the UVs actually leave [0, 1]
    roughness/metallic/emission textures   the texture's mean (after scale and bias), one warning
    alpha/normal textures                  dropped, one warning
    DomeLight textures  tracer.Environment whenever the tracer has it (independently of the material model)
    vertex colours      flat per triangle (the mean of its corners), one warning when they vary within triangles
    specular level s    R_s = F0(ior)·2s; metallic m -> k_m = m with mirror_tint = base colour
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import tracer

#: The tracer carries the Principled model (materials-core): texture objects, UV sets, vertex colours, environment.
PRINCIPLED = hasattr(tracer, "Texture") and hasattr(tracer, "Environment")
#: The tracer has a lat-long environment (tracer.Environment: Cycles' equirect frame, world -> environment rotation).
HAS_ENVIRONMENT = hasattr(tracer, "Environment")


@dataclass
class TextureSpec:
    """One UsdUVTexture lookup: decoded RGBA pixels and how they are read."""

    pixels: np.ndarray  # (H, W, 4) float32 linear
    wrap_s: str
    wrap_t: str
    uv_set: int
    transform: np.ndarray  # (3, 3) on (s, t, 1)
    scale: tuple
    bias: tuple
    fallback: tuple
    label: str = ""

    def values(self, channel: int) -> np.ndarray:
        """Texel values after scale and bias: (H, W, 3) for channel −1 (rgb), else (H, W) for one channel."""
        if channel < 0:
            return self.pixels[..., :3] * np.float32(self.scale[:3]) + np.float32(self.bias[:3])
        return self.pixels[..., channel] * np.float32(self.scale[channel]) + np.float32(self.bias[channel])


TEXTURE_KEYS = ("base_color", "roughness", "metallic", "specular", "alpha", "emission", "normal")


class ModelWriter:
    """Adds materials and textures to a SceneBuilder in the model the tracer has; lowers meshes' UVs and colours."""

    def __init__(self, builder, warn):
        self.b = builder
        self.warn = warn
        self.rich: dict[int, tuple[str, dict]] = {}  # row -> (name, Principled fields)
        self._tex_index: dict[int, int] = {}  # id(TextureSpec) -> builder texture index
        self._specs: list = []  # keep specs alive (ids stay unique)
        self._colour_rows: dict = {}

    # ------------------------------------------------------------------ materials
    def add_material(self, name: str, fields: dict) -> int:
        if PRINCIPLED:
            out = {}
            for k, v in fields.items():
                out[k] = self._texture_index(v) if isinstance(v, TextureSpec) else v
            row = self.b.add_material(name, **out)
        else:
            row = self.b.add_material(name, **self._classic(name, fields))
        self.rich.setdefault(row, (name, dict(fields)))
        return row

    def _texture_index(self, spec: TextureSpec) -> int:
        key = id(spec)
        if key not in self._tex_index:
            self._specs.append(spec)
            t = tracer.Texture(image=spec.pixels, wrap_s=spec.wrap_s, wrap_t=spec.wrap_t, uv_set=spec.uv_set,
                               transform=spec.transform, scale=spec.scale, bias=spec.bias, fallback=spec.fallback)
            self._tex_index[key] = self.b.add_texture(t)
        return self._tex_index[key]

    def _classic(self, name: str, f: dict) -> dict:
        """Principled fields -> the classic table (see the module docstring)."""
        def const(key, default):
            v = f.get(key, default)
            tex = f.get(f"{key}_texture")
            if isinstance(tex, TextureSpec):
                ch = f.get(f"{key}_channel", -1)
                mean = tex.values(ch).reshape(-1, 3 if ch < 0 else 1).mean(axis=0)
                if key != "base_color":
                    self.warn(f"{name}: a texture on {key} is not supported by this tracer (its mean "
                              f"{tuple(np.round(np.atleast_1d(mean), 3))} used)")
                return np.asarray(v, np.float64) * (mean if ch < 0 or np.ndim(v) == 0 else mean[0])
            return np.asarray(v, np.float64)

        base = np.broadcast_to(np.asarray(f.get("base_color", (0.8, 0.8, 0.8)), float), (3,))
        out = dict(diffuse=tuple(float(x) for x in base))
        tex = f.get("base_color_texture")
        if isinstance(tex, TextureSpec):
            ch = f.get("base_color_channel", -1)
            img = tex.values(ch)
            if img.ndim == 2:
                img = np.repeat(img[..., None], 3, axis=2)
            out["diffuse_texture"] = self.b.add_texture(np.ascontiguousarray(np.maximum(img, 0), np.float32))
        ior = float(f.get("ior", 1.5))
        level = float(np.ravel(const("specular", 0.5))[0])
        f0 = ((ior - 1) / (ior + 1)) ** 2 * 2 * level
        out["specular"] = (f0, f0, f0)
        out["roughness"] = float(np.clip(np.ravel(const("roughness", 0.5))[0], 0, 1))
        metallic = float(np.clip(np.ravel(const("metallic", 0.0))[0], 0, 1))
        if metallic > 0:
            out["k_m"] = metallic
            out["mirror_tint"] = out["diffuse"] if "diffuse_texture" not in out else (1.0, 1.0, 1.0)
        if f.get("transmission", 0) > 0:
            out["transmission"] = float(f["transmission"])
            out["transmission_tint"] = tuple(f.get("transmission_tint", (1.0, 1.0, 1.0)))
        out["ior"] = ior
        alpha, threshold = f.get("alpha", 1.0), float(f.get("alpha_threshold", 0.0))
        if isinstance(f.get("alpha_texture"), TextureSpec):
            self.warn(f"{name}: a texture on opacity (cut-out / alpha) is not supported by this tracer "
                      "(rendered opaque)")
        elif float(alpha) < 1:
            if threshold > 0 or float(alpha) == 0:  # not there: rays pass straight through
                out.update(transmission=1.0, ior=1.0, transmission_tint=(1.0, 1.0, 1.0))
            else:
                out["transmission"] = 1.0 - float(alpha)
        em = np.broadcast_to(const("emission", (0.0, 0.0, 0.0)), (3,))
        if np.any(em):
            out["emission"] = tuple(float(x) for x in em)
        if isinstance(f.get("normal_texture"), TextureSpec):
            self.warn(f"{name}: normal maps are not supported by this tracer (ignored)")
        return out

    # ------------------------------------------------------------------ meshes
    def mesh_kwargs(self, label: str, rows, n_tri: int, uv_sets: dict, colors):
        """(per-triangle material rows, ``add_mesh`` keywords) for a mesh whose materials read the per-corner
        ``uv_sets`` {index: (T, 3, 2)} and ``colors`` (T, 3, 3) or None."""
        if PRINCIPLED:
            kw = {}
            if uv_sets:
                kw["uv_sets"] = uv_sets
                if 0 in uv_sets:
                    kw["uvs"] = uv_sets[0]
            if colors is not None:
                kw["colors"] = colors
            return rows, kw
        rows = np.broadcast_to(np.asarray(rows, np.int64), (n_tri,)).copy() if np.ndim(rows) else \
            np.full(n_tri, int(rows), np.int64)
        uvs = None
        for row in np.unique(rows):
            name, f = self.rich.get(int(row), ("", {}))
            tex = f.get("base_color_texture")
            sel = rows == row
            if f.get("vertex_color") and colors is not None:
                rows[sel] = self._flat_colour_rows(label, int(row), colors[sel])
            if not isinstance(tex, TextureSpec):
                continue
            src = uv_sets.get(tex.uv_set)
            if src is None:
                continue
            if uvs is None:
                uvs = np.zeros((n_tri, 3, 2), np.float32) if 0 not in uv_sets else uv_sets[0].copy()
            m = np.asarray(tex.transform, np.float64)
            st = src[sel].astype(np.float64)
            st = st @ m[:2, :2].T + m[:2, 2]
            uvs[sel] = st
            outside = (st < -1e-6) | (st > 1 + 1e-6)
            for axis, wrap in ((0, tex.wrap_s), (1, tex.wrap_t)):
                if wrap != "repeat" and outside[..., axis].any():
                    self.warn(f"{name}: wrap mode {wrap!r} is not supported by this tracer (repeat used)")
        kw = {}
        if uvs is not None:
            kw["uvs"] = uvs
        elif 0 in uv_sets:
            kw["uvs"] = uv_sets[0]
        return rows, kw

    def _flat_colour_rows(self, label: str, row: int, corner_colours: np.ndarray) -> np.ndarray:
        """Material rows for triangles whose vertex colours the classic table cannot carry: one row per distinct
        (rounded) triangle colour, the base colour multiplied by it."""
        c = np.asarray(corner_colours, np.float64)
        if np.abs(c - c.mean(axis=1, keepdims=True)).max(initial=0) > 1e-4:
            self.warn(f"{label}: vertex colours are flat per triangle (the mean of its corners) in this tracer")
        tri = np.round(c.mean(axis=1), 3)
        uniq, inv = np.unique(tri, axis=0, return_inverse=True)
        name, f = self.rich[row]
        out = np.empty(len(uniq), np.int64)
        for i, col in enumerate(uniq):
            key = (row, tuple(col))
            if key not in self._colour_rows:
                g = dict(f)
                g["vertex_color"] = False
                g["base_color"] = tuple(np.asarray(f.get("base_color", (1, 1, 1)), float) * col)
                self._colour_rows[key] = self.add_material(f"{name}{tuple(float(x) for x in col)}", g)
            out[i] = self._colour_rows[key]
        return out[inv.reshape(-1)]

"""Writing what usd_io read into the tracer's material model — the Principled model of docs/materials-api.md
(``tracer.Texture``, ``Scene.uv_sets``, ``Scene.colors``): the material reader (:mod:`usd_io.material`) describes
each material in the model's fields, with :class:`TextureSpec` for texture lookups, and this module hands them to
the scene builder as they are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import tracer



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
        self._tex_index: dict[int, int] = {}  # id(TextureSpec) -> builder texture index
        self._specs: list = []  # keep specs alive (ids stay unique)

    # ------------------------------------------------------------------ materials
    def add_material(self, name: str, fields: dict) -> int:
        out = {k: self._texture_index(v) if isinstance(v, TextureSpec) else v for k, v in fields.items()}
        row = self.b.add_material(name, **out)
        return row

    def _texture_index(self, spec: TextureSpec) -> int:
        key = id(spec)
        if key not in self._tex_index:
            self._specs.append(spec)
            t = tracer.Texture(image=spec.pixels, wrap_s=spec.wrap_s, wrap_t=spec.wrap_t, uv_set=spec.uv_set,
                               transform=spec.transform, scale=spec.scale, bias=spec.bias, fallback=spec.fallback)
            self._tex_index[key] = self.b.add_texture(t)
        return self._tex_index[key]

    # ------------------------------------------------------------------ meshes
    def mesh_kwargs(self, label: str, rows, n_tri: int, uv_sets: dict, colors):
        """(per-triangle material rows, ``add_mesh`` keywords) for a mesh whose materials read the per-corner
        ``uv_sets`` {index: (T, 3, 2)} and ``colors`` (T, 3, 3) or None."""
        kw = {}
        if uv_sets:
            kw["uv_sets"] = uv_sets
            if 0 in uv_sets:
                kw["uvs"] = uv_sets[0]
        if colors is not None:
            kw["colors"] = colors
        return rows, kw

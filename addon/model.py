"""The Principled description of :mod:`addon.nodes` written into the material model the tracer carries.

The reader describes every material in the Principled model's fields (docs/materials-api.md); this module is the
one place that knows which model the bundled tracer has. Until the tracer carries per-parameter textures, UV
sets and vertex colours, the description is lowered onto the classic table (diffuse + one diffuse texture),
exactly where that is possible and with one warning per material where it is not:

    base colour texture   kept (its pixels × the constant); the Mapping node and the UV map it reads are baked into
                          each triangle's corner UVs (exact: an affine map of the UVs commutes with barycentric
                          interpolation); Extension Mirror becomes a 2×2 mirrored tile read at half scale (exact);
                          Clip / Extend: one warning when the UVs actually leave [0, 1] (repeat is used)
    vertex colours        flat per triangle (the mean of its corners, one material row per distinct colour), one
                          warning when they vary within triangles
    roughness, metallic, specular, emission textures   the texture's mean, one warning
    alpha / normal textures   dropped (opaque, shading normals), one warning
    metallic m            k_m = m with mirror_tint = base colour; specular level s: R_s = F0(ior)·2s
"""

from __future__ import annotations

import numpy as np

from .nodes import TextureRef, read_material

#: Blender's default surface (no material): 0.8 grey, Principled defaults.
DEFAULT_FIELDS = {"base_color": (0.8, 0.8, 0.8), "roughness": 0.5, "specular": 0.5, "ior": 1.5}


def f0_specular(ior: float, level: float) -> float:
    """R_s of a dielectric: F0 = ((η − 1)/(η + 1))², × 2·level (Specular IOR Level 0.5 keeps F0)."""
    f0 = ((ior - 1.0) / (ior + 1.0)) ** 2 if ior > 0 else 0.0
    return float(f0 * 2.0 * max(level, 0.0))


class MaterialWriter:
    """Reads each Blender material once and adds its row(s); lowers each mesh's UVs and vertex colours."""

    def __init__(self, builder, warnings: list):
        self.b = builder
        self.warnings = warnings
        self.images: dict = {}  # image name -> (H, W, 4) pixels (shared by materials and the world)
        self.fields: dict[int, tuple[str, dict]] = {}  # row -> (material name, Principled fields)
        self._rows: dict[str, int] = {}
        self._textures: dict = {}
        self._colour_rows: dict = {}
        self.default_row = self._add("__default__", dict(DEFAULT_FIELDS))

    def warn(self, message: str) -> None:
        self.warnings.append(message)

    # ------------------------------------------------------------------ materials
    def row(self, material) -> int:
        if material is None:
            return self.default_row
        if material.name not in self._rows:
            self._rows[material.name] = self._add(material.name, read_material(material, self.warn, self.images))
        return self._rows[material.name]

    def _add(self, name: str, f: dict) -> int:
        row = self.b.add_material(name, **self._classic(name, f))
        self.fields.setdefault(row, (name, f))
        return row

    def _texture(self, tex: TextureRef, channel: int) -> int:
        key = (id(tex.pixels), channel, tex.wrap == "mirror", tex.scale, tex.bias)
        if key not in self._textures:
            img = tex.values(channel)
            if img.ndim == 2:
                img = np.repeat(img[..., None], 3, axis=2)
            if tex.wrap == "mirror":  # one period of a mirrored texture, read at half scale (see mesh_inputs)
                top = np.concatenate([img, img[:, ::-1]], axis=1)
                img = np.concatenate([top[::-1], top], axis=0)
            self._textures[key] = (self.b.add_texture(np.ascontiguousarray(np.maximum(img, 0), np.float32)), tex)
        return self._textures[key][0]

    def _classic(self, name: str, f: dict) -> dict:
        """Principled fields -> a classic material row (see the module docstring)."""
        label = f"material {name!r}"

        def value(key, default):
            v = np.asarray(f.get(key, default), np.float64)
            tex = f.get(f"{key}_texture")
            if not isinstance(tex, TextureRef):
                return v
            ch = f.get(f"{key}_channel", -1)
            mean = tex.values(ch).reshape(-1, 3 if ch < 0 else 1).mean(axis=0)
            self.warn(f"{label}: a texture on {key} ({tex.label!r}) is not supported by this tracer; its mean "
                      f"{tuple(np.round(np.atleast_1d(mean), 3))} is used")
            return v * (mean if v.ndim else float(mean[0]))

        base = np.broadcast_to(np.asarray(f.get("base_color", (0.8, 0.8, 0.8)), np.float64), (3,))
        out: dict = {"diffuse": tuple(map(float, base))}
        tex = f.get("base_color_texture")
        if isinstance(tex, TextureRef):
            out["diffuse_texture"] = self._texture(tex, f.get("base_color_channel", -1))
        ior = float(f.get("ior", 1.5))
        level = float(np.ravel(value("specular", 0.5))[0])
        out["specular"] = (f0_specular(ior, level),) * 3
        out["roughness"] = float(np.clip(np.ravel(value("roughness", 0.5))[0], 0, 1))
        metallic = float(np.clip(np.ravel(value("metallic", 0.0))[0], 0, 1))
        out["k_m"] = metallic
        out["mirror_tint"] = out["diffuse"] if "diffuse_texture" not in out else (1.0, 1.0, 1.0)
        transmission = float(f.get("transmission", 0.0))
        out["ior"] = ior
        if transmission > 0:
            out["transmission"] = transmission
            out["transmission_tint"] = out["diffuse"]
        em = np.broadcast_to(value("emission", (0.0, 0.0, 0.0)), (3,))
        out["emission"] = tuple(float(x) for x in np.maximum(em, 0))
        alpha, threshold = float(f.get("alpha", 1.0)), float(f.get("alpha_threshold", 0.0))
        if isinstance(f.get("alpha_texture"), TextureRef):
            self.warn(f"{label}: a texture on Alpha ({f['alpha_texture'].label!r}) is not supported by this "
                      "tracer (rendered opaque)")
        elif alpha < 1.0:
            if transmission > 0:
                self.warn(f"{label}: Alpha together with Transmission is not supported; Alpha ignored")
            elif threshold > 0 or alpha == 0.0:
                if alpha < threshold or alpha == 0.0:  # cut away: rays pass straight through
                    out.update(transmission=1.0, ior=1.0, transmission_tint=(1.0, 1.0, 1.0), specular=(0, 0, 0),
                               diffuse=(0.0, 0.0, 0.0), k_m=0.0)
            else:  # blend: a pass-through share 1 − alpha
                out.update(transmission=1.0 - alpha, ior=1.0, transmission_tint=(1.0, 1.0, 1.0))
        if isinstance(f.get("normal_texture"), TextureRef):
            self.warn(f"{label}: normal maps ({f['normal_texture'].label!r}) are not supported by this tracer "
                      "(shading normals kept)")
        return out

    # ------------------------------------------------------------------ meshes
    def mesh_inputs(self, label: str, rows, g: dict):
        """(per-triangle material rows, per-corner UVs or None) for a mesh of ``mesh_arrays`` ``g`` whose triangles
        use material ``rows``: textures' UV maps and Mapping transforms baked into the UVs, vertex colours into
        per-triangle rows."""
        n = len(g["triangles"])
        rows = np.broadcast_to(np.asarray(rows, np.int64), (n,)).copy()
        layers, default = g.get("uv_layers", {}), g.get("uv_default")
        uvs = layers.get(default) if default is not None else None
        baked = None
        for row in np.unique(rows):
            name, f = self.fields.get(int(row), ("", {}))
            sel = rows == row
            vc = f.get("vertex_color")
            if vc is not None:
                colours = g.get("colors", {})
                key = vc or g.get("color_default")
                if key in colours:
                    rows[sel] = self._flat_colour_rows(label, int(row), colours[key][sel])
                else:
                    self.warn(f"material {name!r} on {label!r}: Color Attribute {vc or '(active)'!r} not found "
                              "on the mesh (white used)")
            tex = f.get("base_color_texture")
            if not isinstance(tex, TextureRef):
                continue
            src = layers.get(tex.uv_map or default)
            if src is None:
                if layers:
                    self.warn(f"material {name!r} on {label!r}: UV map {tex.uv_map!r} not found; the active one "
                              "is used")
                    src = uvs
                if src is None:
                    continue
            m = np.asarray(tex.transform, np.float64)
            st = src[sel].astype(np.float64) @ m[:2, :2].T + m[:2, 2]
            if tex.wrap == "mirror":
                st = st * 0.5
            elif tex.wrap != "repeat" and ((st < -1e-6) | (st > 1 + 1e-6)).any():
                self.warn(f"material {name!r}: Extension {tex.wrap!r} of {tex.label!r} is not supported by this "
                          "tracer (repeat used)")
            if baked is None:
                baked = uvs.copy() if uvs is not None else np.zeros((n, 3, 2), np.float32)
            baked[sel] = st
        return rows, (baked if baked is not None else uvs)

    def _flat_colour_rows(self, label: str, row: int, corner: np.ndarray) -> np.ndarray:
        c = np.asarray(corner[..., :3], np.float64)
        if np.abs(c - c.mean(axis=1, keepdims=True)).max(initial=0) > 1e-4:
            self.warn(f"{label}: vertex colours are flat per triangle (the mean of its corners) in this tracer")
        tri = np.round(c.mean(axis=1), 3)
        uniq, inv = np.unique(tri, axis=0, return_inverse=True)
        name, f = self.fields[row]
        out = np.empty(len(uniq), np.int64)
        for i, col in enumerate(uniq):
            key = (row, tuple(col))
            if key not in self._colour_rows:
                g = dict(f)
                g.pop("vertex_color", None)
                g["base_color"] = tuple(np.asarray(f.get("base_color", (1, 1, 1)), float) * col)
                self._colour_rows[key] = self._add(f"{name}{tuple(float(x) for x in col)}", g)
            out[i] = self._colour_rows[key]
        return out[np.ravel(inv)]

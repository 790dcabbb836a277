"""The material table: one row per material, struct of arrays. Every column is documented once here; the exact
contract front ends write against is ``docs/materials-api.md``.

One row describes a surface for both local models (``RenderSettings.shading``):

- "principled" (default): the Principled BSDF's diffuse + GGX specular (:mod:`tracer.shading.bsdf`), from ``diffuse``
  (base colour), ``metallic``, ``roughness``, ``specular`` (Specular IOR Level), ``specular_tint`` and ``ior``;
- "classic": the notes' Lambert + Blinn-Phong (:mod:`tracer.shading.local`) from R_d = ``diffuse``·(1 − metallic),
  R_s = ``specular_color``·(1 − metallic) + base colour·metallic and ``exponent``.

Columns (N = number of materials):

- ``diffuse``        (N, 3) base colour; R_d (and R_a) of the notes. ``base_color`` is the same column
- ``specular``       (N,) Principled "Specular IOR Level": dielectric F0 = ((ior − 1)/(ior + 1))² · 2·specular
                     (0.5 keeps F0 from ior, 0 = no highlight)
- ``specular_tint``  (N, 3) colour of the dielectric F0 (Cycles' Specular Tint; the F82 tint of metals)
- ``specular_color`` (N, 3) R_s of the classic model (derived as F0·2·specular·tint when not given)
- ``roughness``      (N,) Principled roughness r (GGX α = r²)
- ``exponent``       (N,) the Blinn-Phong e of the classic model (derived from roughness when not given)
- ``rough_glass``    (N,) 1: the glass part (transmission) is rough by ``roughness`` ("principled" shading: one
  sampled GGX microfacet normal per ray, tracer.optics.rough_dielectric); 0: smooth. Default: 1 where
  ``roughness`` is given, 0 where it is derived from ``exponent`` (the seed's glass stays smooth)
- ``glass_multiscatter`` (N,) 1: rough glass keeps the light its microfacets scatter more than once (Cycles'
  Multiscatter GGX, the default: the interface's weights over its albedo, tracer.shading.ggx_glass); 0: single
  scattering, which loses it (Cycles' GGX and Beckmann glass, and every Refraction BSDF)
- ``metallic``       (N,) metal weight: a GGX lobe with the base colour as F0 (F82-tint Fresnel)
- ``k_m``            the notes' mirror weight: (1 − k_m)·c + k_m·mirror_tint·RayColor(reflected)
- ``mirror_tint``    colour the k_m reflected RayColor is multiplied by
- ``transmission``   weight of the transmission (refraction) part of the non-mirror, non-metal remainder
- ``transmission_tint`` colour the transmitted RayColor is multiplied by
- ``ior``            η of the material (the outside is η = 1)
- ``emission``       (N, 3) radiance Le the surface emits (colour × strength; both sides): seen by rays, and its
                     triangles are lights
- ``alpha``          (N,) coverage: 1 − alpha of the light passes straight through (Cycles' Alpha, a Transparent
                     BSDF mix); ``alpha_threshold`` > 0 makes it a cut-out (alpha < threshold: not there, else opaque)
- ``normal_strength`` (N,) blend between the shading normal (0) and the normal map's (1) (Blender's Strength)
- ``vertex_color``   (N,) bool: the base colour is multiplied by ``Scene.colors``

Texture lookups, per parameter P in :data:`TEXTURE_PARAMS`: ``P_texture`` (N,) int, an index into
``Scene.textures`` or -1, and ``P_channel`` (N,) int: -1 = rgb (for a scalar parameter: its Rec.709 luminance), 0..3 =
that channel (a colour parameter reads it as grey). A lookup *multiplies* the constant column (base colour,
roughness, metallic, specular, alpha, emission); the normal map's value is a tangent-space normal (OpenGL
convention: +X along increasing s, +Y along increasing t, +Z out of the surface) and must read rgb.
``diffuse_texture`` is ``base_color_texture``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Upper bound for the Blinn-Phong exponent; roughness 0 would otherwise give infinity.
MAX_EXPONENT = 1.0e4

#: Parameters that may read a texture, in the order of the kernels' texture-slot table.
TEXTURE_PARAMS = ("base_color", "roughness", "metallic", "specular", "alpha", "emission", "normal")
#: Colour parameters (a single channel is read as grey); the others are scalars.
COLOR_PARAMS = ("base_color", "emission", "normal")


#: The Principled BSDF's defaults (Blender 4/5, = Cycles'), written once: every front end and the IR's
#: ``principled_bsdf`` node use these for inputs a file leaves unset (tracer.shading.graph).
PRINCIPLED_DEFAULTS = {
    "Base Color": (0.8, 0.8, 0.8), "Metallic": 0.0, "Roughness": 0.5, "IOR": 1.5, "Alpha": 1.0,
    "Specular IOR Level": 0.5, "Specular Tint": (1.0, 1.0, 1.0), "Transmission Weight": 0.0,
    "Emission Color": (1.0, 1.0, 1.0), "Emission Strength": 0.0,
}


def roughness_to_exponent(roughness):
    """Blinn-Phong exponent e from a roughness r in [0, 1].

    With α = r² (the perceptual-roughness convention of UsdPreviewSurface and the Principled BSDF), the Blinn-Phong
    lobe that matches a Beckmann distribution of slope α has e = 2/α² − 2 (Walter et al. 2007, eq. 30).
    Clamped to [0, MAX_EXPONENT].
    """
    r = np.clip(np.asarray(roughness, dtype=np.float64), 0.0, 1.0)
    alpha2 = np.maximum(r**4, 2.0 / (MAX_EXPONENT + 2.0))
    return np.clip(2.0 / alpha2 - 2.0, 0.0, MAX_EXPONENT).astype(np.float32)


def exponent_to_roughness(exponent):
    """Inverse of :func:`roughness_to_exponent`: r = (2 / (e + 2))^¼."""
    e = np.clip(np.asarray(exponent, dtype=np.float64), 0.0, MAX_EXPONENT)
    return np.clip((2.0 / (e + 2.0)) ** 0.25, 0.0, 1.0).astype(np.float32)


def f0_from_ior(ior):
    """Normal-incidence reflectance of a dielectric: F0 = ((η − 1)/(η + 1))² (the one place it is written)."""
    ior = np.asarray(ior, np.float64)
    return ((ior - 1.0) / (ior + 1.0)) ** 2


def _rgb_column(values, n, name):
    a = np.asarray(values, dtype=np.float32)
    if a.ndim == 0 or a.shape == (1,):
        a = np.full((n, 3), a.reshape(()), np.float32)
    if a.ndim == 1 and a.shape == (3,):
        a = np.broadcast_to(a, (n, 3))
    if a.shape != (n, 3):
        raise ValueError(f"materials.{name} must have shape ({n}, 3), got {a.shape}")
    return np.ascontiguousarray(a)


def _scalar_column(values, n, name, dtype=np.float32):
    a = np.asarray(values, dtype=dtype)
    if a.ndim == 0:
        a = np.full(n, a, dtype=dtype)
    if a.shape != (n,):
        raise ValueError(f"materials.{name} must have shape ({n},), got {a.shape}")
    return np.ascontiguousarray(a)


_RGB = ("diffuse", "specular_color", "specular_tint", "mirror_tint", "transmission_tint", "emission")
_FLOAT = ("specular", "roughness", "exponent", "metallic", "k_m", "transmission", "ior", "alpha", "alpha_threshold",
          "normal_strength", "rough_glass", "glass_multiscatter")
_INT = tuple(f"{p}_texture" for p in TEXTURE_PARAMS if p != "base_color") + ("diffuse_texture",) + \
    tuple(f"{p}_channel" for p in TEXTURE_PARAMS)


@dataclass
class Materials:
    """Material table (struct of arrays; columns in the module docstring). Build one with :meth:`from_list`."""

    diffuse: np.ndarray
    specular_color: np.ndarray
    exponent: np.ndarray
    k_m: np.ndarray
    mirror_tint: np.ndarray
    transmission: np.ndarray
    transmission_tint: np.ndarray
    ior: np.ndarray
    emission: np.ndarray
    diffuse_texture: np.ndarray
    names: list[str] = field(default_factory=list)
    specular: np.ndarray | None = None
    specular_tint: np.ndarray | None = None
    roughness: np.ndarray | None = None
    metallic: np.ndarray | None = None
    alpha: np.ndarray | None = None
    alpha_threshold: np.ndarray | None = None
    normal_strength: np.ndarray | None = None
    vertex_color: np.ndarray | None = None
    roughness_texture: np.ndarray | None = None
    metallic_texture: np.ndarray | None = None
    specular_texture: np.ndarray | None = None
    alpha_texture: np.ndarray | None = None
    emission_texture: np.ndarray | None = None
    normal_texture: np.ndarray | None = None
    base_color_channel: np.ndarray | None = None
    roughness_channel: np.ndarray | None = None
    metallic_channel: np.ndarray | None = None
    specular_channel: np.ndarray | None = None
    alpha_channel: np.ndarray | None = None
    emission_channel: np.ndarray | None = None
    normal_channel: np.ndarray | None = None
    rough_glass: np.ndarray | None = None
    glass_multiscatter: np.ndarray | None = None
    #: per row: None, or the material's graph (:class:`tracer.shading.compiler.BoundGraph`) when something in it
    #: varies per hit; the kernels run it compiled (tracer.shading.vm), the columns hold its constants
    programs: list | None = None

    def __post_init__(self):
        self._fill_defaults()

    def __len__(self) -> int:
        return int(np.asarray(self.diffuse).shape[0])

    # the Principled names of the seed's columns
    @property
    def base_color(self) -> np.ndarray:
        return self.diffuse

    @property
    def base_color_texture(self) -> np.ndarray:
        return self.diffuse_texture

    def _fill_defaults(self) -> None:
        """Columns left None take their defaults, derived from the classic columns where the meaning overlaps."""
        n = len(self)
        if self.rough_glass is None:  # a given roughness makes the glass rough; one derived from e does not
            self.rough_glass = np.full(n, 0.0 if self.roughness is None else 1.0, np.float32)
        if self.glass_multiscatter is None:
            self.glass_multiscatter = np.ones(n, np.float32)
        if self.roughness is None:
            self.roughness = exponent_to_roughness(self.exponent)
        if self.specular_tint is None:
            self.specular_tint = np.ones((n, 3), np.float32)
        if self.specular is None:  # from R_s: the level whose F0 is R_s's largest channel
            rs = np.asarray(self.specular_color, np.float64).reshape(n, 3).max(axis=1)
            self.specular = (rs / np.maximum(2.0 * f0_from_ior(np.asarray(self.ior, np.float64)), 1e-12)
                             ).astype(np.float32)
        for name, default, dtype in (("metallic", 0.0, np.float32), ("alpha", 1.0, np.float32),
                                     ("alpha_threshold", 0.0, np.float32), ("normal_strength", 1.0, np.float32),
                                     ("vertex_color", False, np.bool_)):
            if getattr(self, name) is None:
                setattr(self, name, np.full(n, default, dtype))
        for name in _INT:
            if getattr(self, name) is None:
                setattr(self, name, np.full(n, -1, np.int32))

    @classmethod
    def from_list(cls, rows: list[dict]) -> "Materials":
        """Build the table from a list of dicts of the fields in the module docstring; missing keys take
        :data:`DEFAULT_MATERIAL` values or are derived (docs/materials-api.md, "Defaults and derived columns").

        Accepted spellings: ``base_color`` = ``diffuse``, ``base_color_texture`` = ``diffuse_texture``; ``roughness``
        and/or ``exponent``; ``specular`` as a number (the Specular IOR Level) or, as in earlier versions, as a
        colour (the classic R_s = ``specular_color``).
        """
        if not rows:
            rows = [dict(DEFAULT_MATERIAL)]
        known = set(DEFAULT_MATERIAL) | set(_OPTIONAL) | {"base_color", "base_color_texture", "name", "program"}
        cols: dict[str, list] = {k: [] for k in list(DEFAULT_MATERIAL) + list(_OPTIONAL)}
        names = []
        programs = [row.get("program") for row in rows]
        for i, row in enumerate(rows):
            label = f"material {i} ({row.get('name', f'material{i}')})"
            unknown = set(row) - known
            if unknown:
                raise ValueError(f"{label}: unknown field(s) {sorted(unknown)}; known: {sorted(known)}")
            row = {k: v for k, v in row.items() if k != "program"}
            for alias, canonical in (("base_color", "diffuse"), ("base_color_texture", "diffuse_texture")):
                if alias in row:
                    if canonical in row:
                        raise ValueError(f"{label}: give {alias} or {canonical}, not both (the same column)")
                    row[canonical] = row.pop(alias)
            if "specular" in row and np.size(row["specular"]) == 3:  # the classic R_s colour
                if "specular_color" in row:
                    raise ValueError(f"{label}: a colour 'specular' is the classic R_s; with specular_color "
                                     "given, specular must be the Specular IOR Level (one number)")
                row["specular_color"] = row.pop("specular")
            elif "specular" in row and np.size(row["specular"]) != 1:
                raise ValueError(f"{label}: specular must be one number (Specular IOR Level) or a colour (R_s)")
            merged = dict(DEFAULT_MATERIAL)
            merged.update({k: v for k, v in row.items() if k in DEFAULT_MATERIAL})
            ior = float(np.asarray(merged["ior"], np.float64).reshape(-1)[0])
            rough = row.get("roughness")
            if rough is not None and "exponent" not in row:
                merged["exponent"] = float(roughness_to_exponent(rough))
            if rough is None:
                rough = float(exponent_to_roughness(merged["exponent"]))
            tint = np.broadcast_to(np.asarray(row.get("specular_tint", (1.0, 1.0, 1.0)), np.float64), (3,))
            level = row.get("specular")
            if level is None:
                rs = np.asarray(merged["specular_color"], np.float64)
                mx = float(np.max(rs)) if rs.size else 0.0
                f0 = float(f0_from_ior(ior))
                level = mx / (2.0 * f0) if mx > 0 and f0 > 0 else 0.0
                if "specular_tint" not in row and mx > 0:
                    tint = np.broadcast_to(rs, (3,)) / mx
            elif "specular_color" not in row:  # the classic rendition of a Principled row
                merged["specular_color"] = tuple(float(f0_from_ior(ior)) * 2.0 * float(level) * tint)
            opt = dict(_OPTIONAL, roughness=rough, specular=level, specular_tint=tuple(tint),
                       rough_glass=0.0 if row.get("roughness") is None else 1.0)
            opt.update({k: v for k, v in row.items() if k in _OPTIONAL and k not in ("roughness", "specular",
                                                                                      "specular_tint")})
            for k in DEFAULT_MATERIAL:
                cols[k].append(merged[k])
            for k in _OPTIONAL:
                cols[k].append(opt[k])
            names.append(str(row.get("name", f"material{i}")))
        n = len(rows)
        kw = {}
        for k in cols:
            if k in _RGB:
                kw[k] = _rgb_column(cols[k], n, k)
            elif k == "vertex_color":
                kw[k] = _scalar_column([bool(v) for v in cols[k]], n, k, np.bool_)
            elif k in _INT:
                kw[k] = _scalar_column(cols[k], n, k, np.int32)
            else:
                kw[k] = _scalar_column(cols[k], n, k)
        return cls(names=names, programs=programs if any(p is not None for p in programs) else None, **kw)

    def texture_slots(self) -> tuple[np.ndarray, np.ndarray]:
        """((N, 7) texture indices, (N, 7) channels) in the order of :data:`TEXTURE_PARAMS`."""
        tex = np.stack([self.diffuse_texture] + [getattr(self, f"{p}_texture") for p in TEXTURE_PARAMS[1:]], axis=1)
        ch = np.stack([getattr(self, f"{p}_channel") for p in TEXTURE_PARAMS], axis=1)
        return np.ascontiguousarray(tex, np.int32), np.ascontiguousarray(ch, np.int32)

    def validate(self, n_textures: int = 0) -> None:
        """Check every column's shape and range; raise ``ValueError`` naming the material and the field."""
        self._fill_defaults()
        n = len(self)
        if self.programs is not None and len(self.programs) != n:
            raise ValueError(f"materials.programs must have {n} entries (None or a graph), got {len(self.programs)}")
        for name in _RGB:
            setattr(self, name, _rgb_column(getattr(self, name), n, name))
        for name in _FLOAT:
            setattr(self, name, _scalar_column(getattr(self, name), n, name))
        for name in _INT:
            setattr(self, name, _scalar_column(getattr(self, name), n, name, np.int32))
        self.vertex_color = _scalar_column(self.vertex_color, n, "vertex_color", np.bool_)
        for name in _RGB + _FLOAT:
            a = getattr(self, name)
            if not np.all(np.isfinite(a)):
                bad = int(np.flatnonzero(~np.isfinite(a).reshape(n, -1).all(axis=1))[0])
                raise ValueError(f"material {bad} ({self._name(bad)}): {name} is NaN or infinite")
        if np.any(self.ior <= 0):
            bad = int(np.flatnonzero(self.ior <= 0)[0])
            raise ValueError(f"material {bad} ({self._name(bad)}): ior must be > 0, got {float(self.ior[bad])}")
        for name in ("k_m", "transmission", "roughness", "metallic", "alpha", "alpha_threshold"):
            a = getattr(self, name)
            if np.any((a < 0) | (a > 1)):
                bad = int(np.flatnonzero((a < 0) | (a > 1))[0])
                raise ValueError(f"material {bad} ({self._name(bad)}): {name} must be in [0, 1], got {float(a[bad])}")
        for name in ("exponent", "specular", "normal_strength"):
            a = getattr(self, name)
            if np.any(a < 0):
                bad = int(np.flatnonzero(a < 0)[0])
                raise ValueError(f"material {bad} ({self._name(bad)}): {name} must be >= 0, got {float(a[bad])}")
        for name in ("diffuse", "specular_color", "specular_tint", "mirror_tint", "transmission_tint", "emission"):
            a = getattr(self, name)
            if np.any(a < 0):
                bad = int(np.flatnonzero((a < 0).any(axis=1))[0])
                raise ValueError(f"material {bad} ({self._name(bad)}): {name} must not be negative, "
                                 f"got {a[bad].tolist()}")
        tex, ch = self.texture_slots()
        for j, p in enumerate(TEXTURE_PARAMS):
            field_name = "diffuse_texture" if p == "base_color" else f"{p}_texture"
            t, c = tex[:, j], ch[:, j]
            if np.any((t < -1) | (t >= n_textures)):
                bad = int(np.flatnonzero((t < -1) | (t >= n_textures))[0])
                raise ValueError(f"material {bad} ({self._name(bad)}): {field_name} {int(t[bad])} "
                                 f"is not an index into the scene's {n_textures} texture(s)")
            if np.any((c < -1) | (c > 3)):
                bad = int(np.flatnonzero((c < -1) | (c > 3))[0])
                raise ValueError(f"material {bad} ({self._name(bad)}): {p}_channel must be -1 (rgb) or 0..3, "
                                 f"got {int(c[bad])}")
        bad_normal = (self.normal_texture >= 0) & (self.normal_channel != -1)
        if np.any(bad_normal):
            bad = int(np.flatnonzero(bad_normal)[0])
            raise ValueError(f"material {bad} ({self._name(bad)}): a normal map reads rgb (normal_channel -1), "
                             f"got {int(self.normal_channel[bad])}")

    def _name(self, i: int) -> str:
        return self.names[i] if i < len(self.names) else f"material{i}"


#: Field defaults of the seed's columns: a grey Lambertian surface with no highlight, mirror, transmission or emission.
DEFAULT_MATERIAL = {
    "diffuse": (0.8, 0.8, 0.8),
    "specular_color": (0.0, 0.0, 0.0),
    "exponent": 50.0,
    "k_m": 0.0,
    "mirror_tint": (1.0, 1.0, 1.0),
    "transmission": 0.0,
    "transmission_tint": (1.0, 1.0, 1.0),
    "ior": 1.5,
    "emission": (0.0, 0.0, 0.0),
    "diffuse_texture": -1,
}

#: Defaults of the Principled columns (``roughness``, ``specular`` and ``specular_tint`` are derived from the
#: classic columns when not given: docs/materials-api.md).
_OPTIONAL = {
    "specular": 0.0,
    "specular_tint": (1.0, 1.0, 1.0),
    "roughness": 0.5,
    "metallic": 0.0,
    "alpha": 1.0,
    "alpha_threshold": 0.0,
    "normal_strength": 1.0,
    "rough_glass": 0.0,
    "glass_multiscatter": 1.0,
    "vertex_color": False,
    **{f"{p}_texture": -1 for p in TEXTURE_PARAMS if p != "base_color"},
    **{f"{p}_channel": -1 for p in TEXTURE_PARAMS},
}

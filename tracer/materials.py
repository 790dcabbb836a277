"""The material table: one row per material, struct of arrays.

Each field names the seed's symbol it feeds:

- ``diffuse``       R_d (and R_a, the ambient reflectance), linear RGB albedo
- ``specular``      R_s, the Blinn-Phong specular colour (0 = no highlight)
- ``exponent``      e, the Blinn-Phong exponent, from roughness by :func:`roughness_to_exponent`
- ``k_m``           the mirror weight of the notes: (1 - k_m)·c + k_m·RayColor
- ``mirror_tint``   colour the reflected RayColor is multiplied by (a metal's base colour; 1 otherwise)
- ``transmission``  weight of the transmission (refraction) part of the non-mirror remainder
- ``transmission_tint`` colour the transmitted RayColor is multiplied by
- ``ior``           η of the material (the outside is η = 1)
- ``emission``      radiance Le the surface emits (both sides): seen by the eye, and its triangles are lights
- ``diffuse_texture`` index into ``Scene.textures`` multiplying ``diffuse``, or -1
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Upper bound for the Blinn-Phong exponent; roughness 0 would otherwise give infinity.
MAX_EXPONENT = 1.0e4


def roughness_to_exponent(roughness):
    """Blinn-Phong exponent e from a roughness r in [0, 1].

    With α = r² (the perceptual-roughness convention of UsdPreviewSurface and the Principled BSDF), the Blinn-Phong
    lobe that matches a Beckmann distribution of slope α has e = 2/α² − 2 (Walter et al. 2007, eq. 30).
    Clamped to [0, MAX_EXPONENT].
    """
    r = np.clip(np.asarray(roughness, dtype=np.float64), 0.0, 1.0)
    alpha2 = np.maximum(r**4, 2.0 / (MAX_EXPONENT + 2.0))
    return np.clip(2.0 / alpha2 - 2.0, 0.0, MAX_EXPONENT).astype(np.float32)


def _rgb_column(values, n, name):
    a = np.asarray(values, dtype=np.float32)
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


@dataclass
class Materials:
    """Material table (struct of arrays). Build one with :meth:`from_list` for convenience."""

    diffuse: np.ndarray
    specular: np.ndarray
    exponent: np.ndarray
    k_m: np.ndarray
    mirror_tint: np.ndarray
    transmission: np.ndarray
    transmission_tint: np.ndarray
    ior: np.ndarray
    emission: np.ndarray
    diffuse_texture: np.ndarray
    names: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return int(self.diffuse.shape[0])

    @classmethod
    def from_list(cls, rows: list[dict]) -> "Materials":
        """Build the table from a list of dicts; missing keys take :data:`DEFAULT_MATERIAL` values.

        Accepts ``roughness`` in place of ``exponent`` (mapped by :func:`roughness_to_exponent`).
        """
        if not rows:
            rows = [dict(DEFAULT_MATERIAL)]
        known = set(DEFAULT_MATERIAL) | {"roughness", "name"}
        cols: dict[str, list] = {k: [] for k in DEFAULT_MATERIAL}
        names = []
        for i, row in enumerate(rows):
            unknown = set(row) - known
            if unknown:
                raise ValueError(f"material {i}: unknown field(s) {sorted(unknown)}; known: {sorted(known)}")
            merged = dict(DEFAULT_MATERIAL)
            merged.update({k: v for k, v in row.items() if k in DEFAULT_MATERIAL})
            if "roughness" in row and "exponent" not in row:
                merged["exponent"] = float(roughness_to_exponent(row["roughness"]))
            for k in cols:
                cols[k].append(merged[k])
            names.append(str(row.get("name", f"material{i}")))
        n = len(rows)
        return cls(
            diffuse=_rgb_column(cols["diffuse"], n, "diffuse"),
            specular=_rgb_column(cols["specular"], n, "specular"),
            exponent=_scalar_column(cols["exponent"], n, "exponent"),
            k_m=_scalar_column(cols["k_m"], n, "k_m"),
            mirror_tint=_rgb_column(cols["mirror_tint"], n, "mirror_tint"),
            transmission=_scalar_column(cols["transmission"], n, "transmission"),
            transmission_tint=_rgb_column(cols["transmission_tint"], n, "transmission_tint"),
            ior=_scalar_column(cols["ior"], n, "ior"),
            emission=_rgb_column(cols["emission"], n, "emission"),
            diffuse_texture=_scalar_column(cols["diffuse_texture"], n, "diffuse_texture", np.int32),
            names=names,
        )

    def validate(self, n_textures: int = 0) -> None:
        n = len(self)
        for name in ("diffuse", "specular", "mirror_tint", "transmission_tint", "emission"):
            _rgb_column(getattr(self, name), n, name)
        for name in ("exponent", "k_m", "transmission", "ior"):
            _scalar_column(getattr(self, name), n, name)
        for name in ("diffuse", "specular", "exponent", "k_m", "mirror_tint", "transmission",
                     "transmission_tint", "ior", "emission"):
            a = getattr(self, name)
            if not np.all(np.isfinite(a)):
                bad = int(np.flatnonzero(~np.isfinite(a).reshape(n, -1).all(axis=1))[0])
                raise ValueError(f"material {bad} ({self._name(bad)}): {name} is NaN or infinite")
        if np.any(self.ior <= 0):
            bad = int(np.flatnonzero(self.ior <= 0)[0])
            raise ValueError(f"material {bad} ({self._name(bad)}): ior must be > 0, got {float(self.ior[bad])}")
        for name in ("k_m", "transmission"):
            a = getattr(self, name)
            if np.any((a < 0) | (a > 1)):
                bad = int(np.flatnonzero((a < 0) | (a > 1))[0])
                raise ValueError(f"material {bad} ({self._name(bad)}): {name} must be in [0, 1], got {float(a[bad])}")
        if np.any(self.exponent < 0):
            raise ValueError("materials: exponent must be >= 0")
        tex = self.diffuse_texture
        if np.any((tex < -1) | (tex >= n_textures)):
            bad = int(np.flatnonzero((tex < -1) | (tex >= n_textures))[0])
            raise ValueError(f"material {bad} ({self._name(bad)}): diffuse_texture {int(tex[bad])} "
                             f"is not an index into the scene's {n_textures} texture(s)")

    def _name(self, i: int) -> str:
        return self.names[i] if i < len(self.names) else f"material{i}"


#: Field defaults: a grey Lambertian surface with no highlight, mirror, transmission or emission.
DEFAULT_MATERIAL = {
    "diffuse": (0.8, 0.8, 0.8),
    "specular": (0.0, 0.0, 0.0),
    "exponent": 50.0,
    "k_m": 0.0,
    "mirror_tint": (1.0, 1.0, 1.0),
    "transmission": 0.0,
    "transmission_tint": (1.0, 1.0, 1.0),
    "ior": 1.5,
    "emission": (0.0, 0.0, 0.0),
    "diffuse_texture": -1,
}

"""Image textures: the :class:`Texture` a material parameter reads, loading through OpenImageIO, and the kernels'
lookup (UV set, affine UV transform, wrap mode per axis, filter, scale and bias).

Orientation (the one convention of the whole tracer, as OpenImageIO reads a file and as Blender and USD address
it): s runs left to right, t bottom to top; the image's row 0 is its *top* row. A lookup at (s, t) reads the point
x = s·W − 0.5, y = (1 − t)·H − 0.5 in texel coordinates (texel centres at integers), bilinearly; or, as Cycles'
other interpolations: "closest" reads texel (⌊s·W⌋, ⌊(1 − t)·H⌋), "cubic" the uniform cubic B-spline of the 4 × 4
texels around (x, y) (Cycles' CPU ``interp_cubic``; Blender's Smart reads as Cubic).

Channels: a texture holds 1–4 channels and every lookup returns four, r g b a, as UsdUVTexture defines them:
1 channel -> (x, x, x, 1), 2 -> (x, x, x, y) (luminance + alpha), 3 -> (r, g, b, 1), 4 -> (r, g, b, a).
The value a material parameter gets is texel · ``scale`` + ``bias`` (per channel), then the parameter's channel
choice (``Materials.<param>_channel``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ..colorspace import srgb_to_linear
from ..jit import kernel

#: Wrap modes, their kernel codes: repeat (tile), clamp (edge texels continue; Blender's Extend), mirror (tile,
#: every other copy flipped) and black (0 in every channel outside [0, 1]; Blender's Clip).
WRAP_MODES = ("repeat", "clamp", "mirror", "black")
_REPEAT, _CLAMP, _MIRROR, _BLACK = 0, 1, 2, 3
#: Interpolations (module docstring), their kernel codes.
INTERPOLATIONS = ("linear", "closest", "cubic")
_LINEAR, _CLOSEST, _CUBIC = 0, 1, 2


@dataclass
class Texture:
    """One image lookup a material parameter can read (see ``docs/materials-api.md``).

    image      (H, W, C) float32 scene-linear values, C in 1..4 (front ends decode the colour space at load:
               :func:`load_texture`); row 0 is the top of the picture
    wrap_s, wrap_t   "repeat" | "clamp" | "mirror" | "black", per axis
    uv_set     index into ``Scene.uv_sets`` (0 = ``Scene.uvs``)
    transform  (3, 3) affine map applied to (s, t, 1) before the lookup (UsdTransform2d, Blender's Mapping node)
    scale, bias  (4,) value = texel·scale + bias per channel (UsdUVTexture's scale and bias)
    fallback   (4,) the value where a surface has no coordinates in ``uv_set`` (scale and bias not applied); the
               default 1 leaves the parameter at its constant (UsdUVTexture's own default is (0, 0, 0, 1): front ends
               pass the value their file format specifies)
    interpolation  "linear" | "closest" | "cubic" (module docstring; "smart" is read as "cubic")
    """

    image: np.ndarray
    wrap_s: str = "repeat"
    wrap_t: str = "repeat"
    uv_set: int = 0
    transform: np.ndarray = field(default_factory=lambda: np.eye(3))
    scale: tuple = (1.0, 1.0, 1.0, 1.0)
    bias: tuple = (0.0, 0.0, 0.0, 0.0)
    fallback: tuple = (1.0, 1.0, 1.0, 1.0)
    interpolation: str = "linear"

    def __post_init__(self):
        self.validate()

    def validate(self, label: str = "texture") -> "Texture":
        img = np.asarray(self.image)
        if img.ndim == 2:
            img = img[..., None]
        if img.ndim != 3 or not (1 <= img.shape[2] <= 4) or img.shape[0] < 1 or img.shape[1] < 1:
            raise ValueError(f"{label}: image must have shape (H, W, C) with C in 1..4, got {np.shape(self.image)}")
        img = np.ascontiguousarray(img, dtype=np.float32)
        if not np.isfinite(img).all():
            img = np.nan_to_num(img, nan=0.0, posinf=0.0, neginf=0.0)
        self.image = img  # the same array when it needs no change: the mip chain cached for it stays valid
        for axis in ("wrap_s", "wrap_t"):
            if getattr(self, axis) not in WRAP_MODES:
                raise ValueError(f"{label}: {axis} must be one of {', '.join(WRAP_MODES)}, got {getattr(self, axis)!r}")
        if isinstance(self.uv_set, bool) or not isinstance(self.uv_set, (int, np.integer)) or self.uv_set < 0:
            raise ValueError(f"{label}: uv_set must be an integer >= 0, got {self.uv_set!r}")
        self.uv_set = int(self.uv_set)
        interp = "cubic" if str(self.interpolation).lower() == "smart" else str(self.interpolation).lower()
        if interp not in INTERPOLATIONS:
            raise ValueError(f"{label}: interpolation must be one of {', '.join(INTERPOLATIONS)}, got "
                             f"{self.interpolation!r}")
        self.interpolation = interp
        m = np.asarray(self.transform, np.float64)
        if m.shape != (3, 3) or not np.all(np.isfinite(m)):
            raise ValueError(f"{label}: transform must be a finite 3x3 matrix (affine on (s, t, 1))")
        self.transform = m
        for name in ("scale", "bias", "fallback"):
            v = np.asarray(getattr(self, name), np.float64).reshape(-1)
            if v.shape == (1,):
                v = np.repeat(v, 4)
            if v.shape != (4,) or not np.all(np.isfinite(v)):
                raise ValueError(f"{label}: {name} must be 4 finite numbers, got {getattr(self, name)!r}")
            setattr(self, name, tuple(float(x) for x in v))
        return self

    # A Texture reads like its image where code expects the bare arrays of earlier versions.
    @property
    def shape(self):
        return self.image.shape

    def __array__(self, dtype=None, copy=None):
        return self.image if dtype is None else self.image.astype(dtype)

    def __getitem__(self, index):
        return self.image[index]

    def mip_chain(self) -> list:
        """:func:`mip_chain` of :meth:`rgba`, computed once per image (kept while ``image`` is the same array)."""
        cached = self.__dict__.get("_mips")
        if cached is None or cached[0] is not self.image:
            cached = (self.image, mip_chain(self.rgba()))
            self.__dict__["_mips"] = cached
        return cached[1]

    def rgba(self) -> np.ndarray:
        """(H, W, 4) float32: the image's channels expanded as UsdUVTexture defines them (module docstring)."""
        img = self.image
        c = img.shape[2]
        if c == 4:
            return img
        one = np.ones(img.shape[:2] + (1,), np.float32)
        if c == 1:
            return np.concatenate([img, img, img, one], axis=2)
        if c == 2:
            return np.concatenate([img[..., :1]] * 3 + [img[..., 1:]], axis=2)
        return np.concatenate([img, one], axis=2)


def as_texture(t, label: str = "texture") -> Texture:
    """A :class:`Texture` from a Texture or a bare (H, W, C) array (wrapped with the defaults)."""
    if isinstance(t, Texture):
        return t.validate(label)
    return Texture(image=np.asarray(t))


#: Colour-space tokens of an image file, case-insensitive: decode r, g, b through the sRGB curve, keep the values,
#: or choose by the file (:func:`decode_image`).
COLORSPACES = ("auto", "srgb", "raw", "linear")
_OIIO_WRAP = {"periodic": "repeat", "clamp": "clamp", "mirror": "mirror", "black": "black", "default": "",
              "repeat": "repeat"}


class DecodedImage(NamedTuple):
    """One image file decoded: ``rgba`` (H, W, 4) float32 linear, straight alpha, row 0 the top of the picture;
    ``srgb`` whether r, g, b went through the sRGB curve; ``wrap_meta`` the file's own wrap modes (s, t) as
    :data:`WRAP_MODES` names, "" where it has none (TIFF/OpenEXR/TX ``wrapmodes``)."""

    rgba: np.ndarray
    srgb: bool
    wrap_meta: tuple


def decode_image(path: str, colorspace: str = "auto", label: str | None = None) -> DecodedImage:
    """Read an image file with OpenImageIO: the one decoder of the tracer, the USD reader and the API.

    - channels: 1 -> (v, v, v, 1); 2 -> (v, v, v, a); 3 -> (r, g, b, 1); 4+ -> (r, g, b, a);
    - colour is straight (unassociated) alpha: OIIO would otherwise premultiply PNG colour by its alpha and darken
      the edges of every cut-out;
    - ``colorspace`` "srgb" decodes r, g, b through the sRGB curve (alpha never); "raw"/"linear" keeps the values;
      **"auto" is sRGB for 8-bit files of 3 or 4 channels and raw otherwise**: Storm's rule
      (``HioOIIO_Image::IsColorSpaceSRGB``), the UsdPreviewSurface spec's fallback for a file without colour
      metadata. One-channel maps (roughness, masks), 16-bit and float files stay linear. (Blender decides per image
      with its own colour-space setting, which the add-on reads; it never asks for "auto".)
    - NaN and ±Inf texels become 0.

    ValueError (naming ``label``, default the path) when the file cannot be read or the colour space is unknown."""
    import OpenImageIO as oiio

    label = label or str(path)
    space = str(colorspace).lower()
    if space not in COLORSPACES:
        raise ValueError(f"texture {label}: colour space {colorspace!r} is not one of {', '.join(COLORSPACES)}")
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)
    buf = oiio.ImageBuf(str(path), 0, 0, config)
    if buf.has_error:
        raise ValueError(f"cannot read texture {label}: {buf.geterror().strip()}")
    spec = buf.spec()
    px = buf.get_pixels(oiio.FLOAT)
    if px is None or np.size(px) == 0:
        raise ValueError(f"cannot read texture {label}: no pixels")
    px = np.asarray(px, np.float32).reshape(spec.height, spec.width, spec.nchannels)
    n = px.shape[2]
    one = np.ones_like(px[..., :1])
    if n == 1:
        rgba = np.concatenate([px, px, px, one], axis=2)
    elif n == 2:
        rgba = np.concatenate([px[..., :1]] * 3 + [px[..., 1:2]], axis=2)
    elif n == 3:
        rgba = np.concatenate([px, one], axis=2)
    else:
        rgba = px[..., :4]
    eight_bit = spec.format.basetype in (oiio.UINT8, oiio.INT8)
    srgb = space == "srgb" or (space == "auto" and eight_bit and n in (3, 4))
    rgba = np.nan_to_num(rgba, nan=0.0, posinf=0.0, neginf=0.0).astype(np.float32)
    if srgb:
        rgba[..., :3] = srgb_to_linear(rgba[..., :3])
    wraps = str(spec.get_string_attribute("wrapmodes", "")).split(",")
    wrap_meta = tuple(_OIIO_WRAP.get(w.strip().lower(), "") for w in (wraps + wraps)[:2])
    return DecodedImage(np.ascontiguousarray(rgba), srgb, wrap_meta)


def load_texture(path: str, colorspace: str = "auto", channels: int = 3) -> np.ndarray:
    """An image file (:func:`decode_image`) as (H, W, ``channels``) linear float32: 3 RGB, 4 RGBA (straight
    alpha, 1 for images without one)."""
    return np.ascontiguousarray(decode_image(path, colorspace).rgba[..., :channels])


# ---------------------------------------------------------------------------------------------- kernels' form
class TextureTables(NamedTuple):
    """The scene's textures as the kernels read them: every image's RGBA texels in one array, and one row of
    parameters per texture (columns :data:`PARAM_COLUMNS`). Two arrays, not one per field: a kernel that hands
    many arrays to a helper pays numba's reference counting for each, per call (about 5 ns per array)."""

    data: np.ndarray  # (P, 4) float32
    params: np.ndarray  # (n, len(PARAM_COLUMNS)) float64


#: The columns of ``TextureTables.params``: first texel row, height, width, wrap codes (s, t), UV set, whether the
#: UV transform is the identity, its first two rows (6), scale (4), bias (4), fallback (4), and the number of mip
#: levels stored after the image (level k is ⌈h/2^k⌉ × ⌈w/2^k⌉ texels, the 2 × 2 box average of level k − 1), the
#: interpolation code.
PARAM_COLUMNS = ("first", "height", "width", "wrap_s", "wrap_t", "uv_set", "identity",
                 "m00", "m01", "m02", "m10", "m11", "m12") + tuple(f"{k}{c}" for k in ("scale", "bias", "fallback")
                                                              for c in "rgba") + ("levels", "interpolation")
_FIRST, _H, _W, _WRAP_S, _WRAP_T, _UV_SET, _IDENTITY, _XFORM = 0, 1, 2, 3, 4, 5, 6, 7
_SCALE, _BIAS, _FALLBACK, _LEVELS, _INTERP = 13, 17, 21, 25, 26


def mip_chain(rgba: np.ndarray) -> list:
    """The image and its mip levels down to 1 × 1: each level the 2 × 2 box average of the one before (an odd row
    or column is repeated first), so a lookup whose footprint covers 2^k texels reads one filtered texel."""
    levels = [np.asarray(rgba, np.float32)]
    while levels[-1].shape[0] > 1 or levels[-1].shape[1] > 1:
        a = levels[-1]
        if a.shape[0] % 2:
            a = np.concatenate([a, a[-1:]], axis=0)
        if a.shape[1] % 2:
            a = np.concatenate([a, a[:, -1:]], axis=1)
        levels.append(0.25 * (a[0::2, 0::2] + a[1::2, 0::2] + a[0::2, 1::2] + a[1::2, 1::2]))
    return levels


def pack_textures(textures: list) -> TextureTables:
    """A :class:`TextureTables` of :class:`Texture` objects (or bare arrays), each with its mip chain."""
    tex = [as_texture(t) for t in textures]
    params = np.zeros((len(tex), len(PARAM_COLUMNS)), np.float64)
    offset = 0
    rows = []
    for i, t in enumerate(tex):
        h, w = t.image.shape[:2]
        chain = t.mip_chain()
        params[i, _FIRST:_UV_SET + 1] = (offset, h, w, WRAP_MODES.index(t.wrap_s), WRAP_MODES.index(t.wrap_t),
                                         t.uv_set)
        params[i, _IDENTITY] = np.array_equal(t.transform, np.eye(3))
        params[i, _XFORM:_XFORM + 6] = np.asarray(t.transform, np.float64)[:2].reshape(-1)
        params[i, _SCALE:_SCALE + 4], params[i, _BIAS:_BIAS + 4] = t.scale, t.bias
        params[i, _FALLBACK:_FALLBACK + 4] = t.fallback
        params[i, _LEVELS] = len(chain)
        params[i, _INTERP] = INTERPOLATIONS.index(t.interpolation)
        rows.extend(level.reshape(-1, 4) for level in chain)
        offset += sum(level.shape[0] * level.shape[1] for level in chain)
    data = np.concatenate(rows) if rows else np.zeros((0, 4), np.float32)
    return TextureTables(np.ascontiguousarray(data, np.float32), params)


@kernel(inline=True)
def _wrap(i, n, mode):
    """Texel index i on an axis of n texels under a wrap mode; -1 = outside (black)."""
    if mode == _REPEAT:
        if 0 <= i < n:
            return i
        return i % n
    if mode == _CLAMP:
        return min(max(i, 0), n - 1)
    if mode == _MIRROR:
        j = i % (2 * n)
        return j if j < n else 2 * n - 1 - j
    return i if 0 <= i < n else -1


@kernel(inline=True)
def bilinear4(data, first, h, w, s, t, wrap_s, wrap_t):
    """Bilinear lookup at (s, t) (s right, t up; row 0 = top) of the h×w texture whose texels start at row
    ``first`` of ``data``, with the given wrap codes: an (r, g, b, a) tuple. Texels outside a "black" texture
    weigh 0. (Inlined: after a call numba cannot prune the reference counting of the NamedTuple fields a caller
    reads next, about 100 ns of atomic operations per lookup.)"""
    x = s * w - 0.5
    y = (1.0 - t) * h - 0.5
    xf = math.floor(x)
    yf = math.floor(y)
    fx = x - xf
    fy = y - yf
    ix, iy = int(xf), int(yf)
    x0 = _wrap(ix, w, wrap_s)
    x1 = _wrap(ix + 1, w, wrap_s)
    y0 = _wrap(iy, h, wrap_t)
    y1 = _wrap(iy + 1, h, wrap_t)
    wx0, wx1, wy0, wy1 = 1.0 - fx, fx, 1.0 - fy, fy
    if x0 < 0:
        x0, wx0 = 0, 0.0
    if x1 < 0:
        x1, wx1 = 0, 0.0
    if y0 < 0:
        y0, wy0 = 0, 0.0
    if y1 < 0:
        y1, wy1 = 0, 0.0
    r0 = first + y0 * w
    r1 = first + y1 * w
    a00, a01, a10, a11 = r0 + x0, r0 + x1, r1 + x0, r1 + x1
    w00, w01, w10, w11 = wx0 * wy0, wx1 * wy0, wx0 * wy1, wx1 * wy1
    return (w00 * data[a00, 0] + w01 * data[a01, 0] + w10 * data[a10, 0] + w11 * data[a11, 0],
            w00 * data[a00, 1] + w01 * data[a01, 1] + w10 * data[a10, 1] + w11 * data[a11, 1],
            w00 * data[a00, 2] + w01 * data[a01, 2] + w10 * data[a10, 2] + w11 * data[a11, 2],
            w00 * data[a00, 3] + w01 * data[a01, 3] + w10 * data[a10, 3] + w11 * data[a11, 3])


@kernel(inline=True)
def closest4(data, first, h, w, s, t, wrap_s, wrap_t):
    """Cycles' Closest: texel (⌊s·w⌋, ⌊(1 − t)·h⌋) (row 0 = top), wrapped; 0 outside a "black" texture."""
    x = _wrap(int(math.floor(s * w)), w, wrap_s)
    y = _wrap(int(math.floor((1.0 - t) * h)), h, wrap_t)
    if x < 0 or y < 0:
        return 0.0, 0.0, 0.0, 0.0
    a = first + y * w + x
    return data[a, 0], data[a, 1], data[a, 2], data[a, 3]


@kernel(inline=True)
def _spline(f):
    """The uniform cubic B-spline weights of the 4 texels around a point at fraction f past the second."""
    return ((((-1.0 / 6.0) * f + 0.5) * f - 0.5) * f + 1.0 / 6.0, ((0.5 * f - 1.0) * f) * f + 2.0 / 3.0,
            ((-0.5 * f + 0.5) * f + 0.5) * f + 1.0 / 6.0, (1.0 / 6.0) * f * f * f)


@kernel
def bicubic4(data, first, h, w, s, t, wrap_s, wrap_t):
    """Cycles' Cubic (``interp_cubic``): the B-spline of the 4 × 4 texels around (s·w − ½, (1 − t)·h − ½), texels
    outside a "black" texture 0."""
    x = s * w - 0.5
    y = (1.0 - t) * h - 0.5
    xf, yf = math.floor(x), math.floor(y)
    wx, wy = _spline(x - xf), _spline(y - yf)
    ix, iy = int(xf) - 1, int(yf) - 1
    r = g = b = a = 0.0
    for j in range(4):
        yy = _wrap(iy + j, h, wrap_t)
        if yy < 0:
            continue
        for i in range(4):
            xx = _wrap(ix + i, w, wrap_s)
            if xx < 0:
                continue
            k = first + yy * w + xx
            f = wx[i] * wy[j]
            r += f * data[k, 0]
            g += f * data[k, 1]
            b += f * data[k, 2]
            a += f * data[k, 3]
    return r, g, b, a


@kernel(inline=True)
def _level(data, params, index, level, s, t):
    """A lookup in mip level ``level`` of texture ``index``, with its interpolation."""
    p = params
    first, h, w = int(p[index, _FIRST]), int(p[index, _H]), int(p[index, _W])
    for _ in range(level):
        first += h * w
        h, w = (h + 1) // 2, (w + 1) // 2
    ws, wt, mode = int(p[index, _WRAP_S]), int(p[index, _WRAP_T]), int(p[index, _INTERP])
    if mode == _CLOSEST:
        return closest4(data, first, h, w, s, t, ws, wt)
    if mode == _CUBIC:
        return bicubic4(data, first, h, w, s, t, ws, wt)
    return bilinear4(data, first, h, w, s, t, ws, wt)


@kernel(inline=True)
def lookup_at(data, params, index, s, t, has_uv, lod=0.0):
    """The value texture ``index`` gives at texture coordinates (s, t) of its UV set: the transform applied,
    wrapped, filtered, × scale + bias; ``fallback`` where the surface has no coordinates (``has_uv`` False). An
    (r, g, b, a) tuple. (The two arrays of a :class:`TextureTables`.) ``lod`` = log2 of the lookup's footprint in
    texels of the full image: below ½ the image itself is read (bilinear), above it the nearest mip level, so a
    minified texture is averaged instead of aliased. (One level, not a trilinear blend of two: the blend doubled
    the lookups' cost for a difference the anti-aliasing samples average away.)"""
    p = params
    if not has_uv:
        return p[index, _FALLBACK], p[index, _FALLBACK + 1], p[index, _FALLBACK + 2], p[index, _FALLBACK + 3]
    if p[index, _IDENTITY] == 0.0:
        m = _XFORM
        s, t = (p[index, m] * s + p[index, m + 1] * t + p[index, m + 2],
                p[index, m + 3] * s + p[index, m + 4] * t + p[index, m + 5])
    level = min(int(lod + 0.5), int(p[index, _LEVELS]) - 1) if lod > 0.5 else 0
    c = _level(data, params, index, level, s, t)
    return (c[0] * p[index, _SCALE] + p[index, _BIAS], c[1] * p[index, _SCALE + 1] + p[index, _BIAS + 1],
            c[2] * p[index, _SCALE + 2] + p[index, _BIAS + 2], c[3] * p[index, _SCALE + 3] + p[index, _BIAS + 3])


@kernel(inline=True)
def texel_density(params, index, uv_area, world_area):
    """Texels of texture ``index``'s full image per unit of world length on a triangle whose UV area and world
    area are given (isotropic: √(texel area / world area))."""
    if world_area <= 0.0:
        return 0.0
    return math.sqrt(abs(uv_area) * params[index, _H] * params[index, _W] / world_area)


@kernel(inline=True)
def lookup(tex, index, s, t, has_uv):
    """:func:`lookup_at` of a :class:`TextureTables`."""
    return lookup_at(tex.data, tex.params, index, s, t, has_uv)


@kernel
def _lookup_rows(tex, index, st, out):
    for i in range(st.shape[0]):
        s, t = st[i, 0], st[i, 1]
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = lookup(tex, index, s, t, s == s and t == t)


def sample_texture(texture, st: np.ndarray) -> np.ndarray:
    """(N, 4) values of a :class:`Texture` (or bare array) at (N, 2) texture coordinates: the array form of the
    kernels' :func:`lookup` (NaN coordinates = none: the fallback)."""
    tex = pack_textures([texture])
    st = np.ascontiguousarray(st, dtype=np.float64).reshape(-1, 2)
    out = np.empty((len(st), 4), np.float32)
    _lookup_rows(tex, 0, st, out)
    return out


def sample_bilinear(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear lookup of (N, 2) texture coordinates (u right, v up, repeat wrapping) in an (H, W, 3) image."""
    return sample_texture(np.asarray(image)[..., :3], uv)[:, :3]

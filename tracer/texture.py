"""Image textures: the :class:`Texture` a material parameter reads, loading through OpenImageIO, and the kernels'
lookup (UV set, affine UV transform, wrap mode per axis, bilinear filter, scale and bias).

Orientation (the one convention of the whole tracer, as OpenImageIO reads a file and as Blender and USD address
it): s runs left to right, t bottom to top; the image's row 0 is its *top* row. A lookup at (s, t) reads the point
x = s·W − 0.5, y = (1 − t)·H − 0.5 in texel coordinates (texel centres at integers), bilinearly.

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

from .jit import kernel

#: Wrap modes, their kernel codes: repeat (tile), clamp (edge texels continue; Blender's Extend), mirror (tile,
#: every other copy flipped) and black (0 in every channel outside [0, 1]; Blender's Clip).
WRAP_MODES = ("repeat", "clamp", "mirror", "black")
_REPEAT, _CLAMP, _MIRROR, _BLACK = 0, 1, 2, 3


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
    """

    image: np.ndarray
    wrap_s: str = "repeat"
    wrap_t: str = "repeat"
    uv_set: int = 0
    transform: np.ndarray = field(default_factory=lambda: np.eye(3))
    scale: tuple = (1.0, 1.0, 1.0, 1.0)
    bias: tuple = (0.0, 0.0, 0.0, 0.0)
    fallback: tuple = (1.0, 1.0, 1.0, 1.0)

    def __post_init__(self):
        self.validate()

    def validate(self, label: str = "texture") -> "Texture":
        img = np.asarray(self.image)
        if img.ndim == 2:
            img = img[..., None]
        if img.ndim != 3 or not (1 <= img.shape[2] <= 4) or img.shape[0] < 1 or img.shape[1] < 1:
            raise ValueError(f"{label}: image must have shape (H, W, C) with C in 1..4, got {np.shape(self.image)}")
        self.image = np.ascontiguousarray(np.nan_to_num(img.astype(np.float32, copy=False), nan=0.0, posinf=0.0,
                                                        neginf=0.0))
        for axis in ("wrap_s", "wrap_t"):
            if getattr(self, axis) not in WRAP_MODES:
                raise ValueError(f"{label}: {axis} must be one of {', '.join(WRAP_MODES)}, got {getattr(self, axis)!r}")
        if isinstance(self.uv_set, bool) or not isinstance(self.uv_set, (int, np.integer)) or self.uv_set < 0:
            raise ValueError(f"{label}: uv_set must be an integer >= 0, got {self.uv_set!r}")
        self.uv_set = int(self.uv_set)
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


def srgb_to_linear(c):
    """The sRGB electro-optical transfer function (IEC 61966-2-1), per channel."""
    c = np.asarray(c, dtype=np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def linear_to_srgb(c):
    """Inverse of :func:`srgb_to_linear` (Blender's "Standard" view transform); input clipped to [0, 1]."""
    c = np.clip(np.asarray(c, dtype=np.float32), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * np.power(c, 1 / 2.4) - 0.055).astype(np.float32)


def load_texture(path: str, colorspace: str = "auto", channels: int = 3) -> np.ndarray:
    """Read an image with OpenImageIO as (H, W, ``channels``) linear float32 (``channels`` 3: RGB as before; 4: RGBA
    with straight alpha, 1 for images without one). ``colorspace``: "auto" (8/16-bit integer files are sRGB, float
    files linear), "srgb" or "raw"/"linear". Alpha is never colour-decoded."""
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(str(path))
    if buf.has_error:
        raise ValueError(f"cannot read texture {path}: {buf.geterror()}")
    spec = buf.spec()
    pixels = buf.get_pixels(oiio.FLOAT)
    if pixels is None or pixels.size == 0:
        raise ValueError(f"cannot read texture {path}: no pixels")
    pixels = np.asarray(pixels, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels)
    alpha = np.ones(pixels.shape[:2] + (1,), np.float32)
    if spec.nchannels == 1:
        rgb = np.repeat(pixels, 3, axis=2)
    elif spec.nchannels == 2:
        rgb, alpha = np.repeat(pixels[..., :1], 3, axis=2), pixels[..., 1:2]
    else:
        rgb = pixels[..., :3]
        if spec.nchannels >= 4:
            alpha = pixels[..., 3:4]
    is_float = spec.format.basetype in (oiio.FLOAT, oiio.HALF, oiio.DOUBLE)
    if colorspace == "srgb" or (colorspace == "auto" and not is_float):
        rgb = srgb_to_linear(rgb)
    out = rgb if channels == 3 else np.concatenate([rgb, alpha], axis=2)
    return np.ascontiguousarray(np.nan_to_num(out), dtype=np.float32)


# ---------------------------------------------------------------------------------------------- kernels' form
class TextureTables(NamedTuple):
    """The scene's textures as the kernels read them: every image's RGBA texels in one array, and per texture its
    (first texel, height, width), wrap codes, UV set, UV transform rows and scale / bias / fallback."""

    data: np.ndarray  # (P, 4) float32
    info: np.ndarray  # (n, 3) int64 first, h, w
    wrap: np.ndarray  # (n, 2) int64 codes for s and t
    uv_set: np.ndarray  # (n,) int64
    xform: np.ndarray  # (n, 2, 3) float64 the first two rows of the (3, 3) transform
    identity: np.ndarray  # (n,) bool: transform is the identity
    scale: np.ndarray  # (n, 4) float32
    bias: np.ndarray  # (n, 4) float32
    fallback: np.ndarray  # (n, 4) float32


def pack_textures(textures: list) -> TextureTables:
    """A :class:`TextureTables` of :class:`Texture` objects (or bare arrays)."""
    tex = [as_texture(t) for t in textures]
    n = len(tex)
    info = np.zeros((n, 3), np.int64)
    offset = 0
    for i, t in enumerate(tex):
        info[i] = (offset, t.image.shape[0], t.image.shape[1])
        offset += t.image.shape[0] * t.image.shape[1]
    data = (np.concatenate([t.rgba().reshape(-1, 4) for t in tex]) if n else np.zeros((0, 4), np.float32))
    wrap = np.array([[WRAP_MODES.index(t.wrap_s), WRAP_MODES.index(t.wrap_t)] for t in tex], np.int64).reshape(n, 2)
    xform = np.array([t.transform[:2] for t in tex], np.float64).reshape(n, 2, 3)
    identity = np.array([np.array_equal(t.transform, np.eye(3)) for t in tex], np.bool_).reshape(n)
    f32 = lambda name: np.array([getattr(t, name) for t in tex], np.float32).reshape(n, 4)  # noqa: E731
    return TextureTables(np.ascontiguousarray(data, np.float32), info, wrap,
                         np.array([t.uv_set for t in tex], np.int64).reshape(n), xform, identity,
                         f32("scale"), f32("bias"), f32("fallback"))


@kernel(inline=True)
def _wrap(i, n, mode):
    """Texel index i on an axis of n texels under a wrap mode; -1 = outside (black)."""
    if mode == _REPEAT:
        return i % n
    if mode == _CLAMP:
        return min(max(i, 0), n - 1)
    if mode == _MIRROR:
        j = i % (2 * n)
        return j if j < n else 2 * n - 1 - j
    return i if 0 <= i < n else -1


@kernel(inline=True)
def _texel(data, first, w, x, y, c):
    if x < 0 or y < 0:
        return 0.0
    return data[first + y * w + x, c]


@kernel
def bilinear4(data, first, h, w, s, t, wrap_s, wrap_t):
    """Bilinear lookup at (s, t) (s right, t up; row 0 = top) of the h×w texture whose texels start at row
    ``first`` of ``data``, with the given wrap codes: an (r, g, b, a) tuple. (Not inlined: one array argument, so
    the call is cheap and the kernels that use it compile quickly.)"""
    x = s * w - 0.5
    y = (1.0 - t) * h - 0.5
    xf = math.floor(x)
    yf = math.floor(y)
    fx = x - xf
    fy = y - yf
    x0 = _wrap(int(xf), w, wrap_s)
    x1 = _wrap(int(xf) + 1, w, wrap_s)
    y0 = _wrap(int(yf), h, wrap_t)
    y1 = _wrap(int(yf) + 1, h, wrap_t)
    w00 = (1.0 - fx) * (1.0 - fy)
    w01 = fx * (1.0 - fy)
    w10 = (1.0 - fx) * fy
    w11 = fx * fy
    return (w00 * _texel(data, first, w, x0, y0, 0) + w01 * _texel(data, first, w, x1, y0, 0)
            + w10 * _texel(data, first, w, x0, y1, 0) + w11 * _texel(data, first, w, x1, y1, 0),
            w00 * _texel(data, first, w, x0, y0, 1) + w01 * _texel(data, first, w, x1, y0, 1)
            + w10 * _texel(data, first, w, x0, y1, 1) + w11 * _texel(data, first, w, x1, y1, 1),
            w00 * _texel(data, first, w, x0, y0, 2) + w01 * _texel(data, first, w, x1, y0, 2)
            + w10 * _texel(data, first, w, x0, y1, 2) + w11 * _texel(data, first, w, x1, y1, 2),
            w00 * _texel(data, first, w, x0, y0, 3) + w01 * _texel(data, first, w, x1, y0, 3)
            + w10 * _texel(data, first, w, x0, y1, 3) + w11 * _texel(data, first, w, x1, y1, 3))


@kernel(inline=True)
def bilinear(data, info, index, s, t):
    """RGB of a repeat-wrapped bilinear lookup (the seed's texture read): an (r, g, b) tuple."""
    c = bilinear4(data, info[index, 0], info[index, 1], info[index, 2], s, t, _REPEAT, _REPEAT)
    return c[0], c[1], c[2]


@kernel(inline=True)
def lookup(tex, index, s, t, has_uv):
    """The value texture ``index`` of a :class:`TextureTables` gives at texture coordinates (s, t) of its UV set:
    the transform applied, wrapped, filtered, × scale + bias; ``fallback`` where the surface has no coordinates
    (``has_uv`` False). An (r, g, b, a) tuple."""
    if not has_uv:
        f = tex.fallback
        return float(f[index, 0]), float(f[index, 1]), float(f[index, 2]), float(f[index, 3])
    if not tex.identity[index]:
        m = tex.xform
        s, t = (m[index, 0, 0] * s + m[index, 0, 1] * t + m[index, 0, 2],
                m[index, 1, 0] * s + m[index, 1, 1] * t + m[index, 1, 2])
    c = bilinear4(tex.data, tex.info[index, 0], tex.info[index, 1], tex.info[index, 2], s, t, tex.wrap[index, 0],
                  tex.wrap[index, 1])
    sc, b = tex.scale, tex.bias
    return (c[0] * sc[index, 0] + b[index, 0], c[1] * sc[index, 1] + b[index, 1],
            c[2] * sc[index, 2] + b[index, 2], c[3] * sc[index, 3] + b[index, 3])


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

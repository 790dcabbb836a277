"""Image textures: loading through OpenImageIO and bilinear lookups with repeat wrapping."""

from __future__ import annotations

import math

import numpy as np

from .jit import kernel


def srgb_to_linear(c):
    """The sRGB electro-optical transfer function (IEC 61966-2-1), per channel."""
    c = np.asarray(c, dtype=np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def linear_to_srgb(c):
    """Inverse of :func:`srgb_to_linear` (Blender's "Standard" view transform); input clipped to [0, 1]."""
    c = np.clip(np.asarray(c, dtype=np.float32), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * np.power(c, 1 / 2.4) - 0.055).astype(np.float32)


def load_texture(path: str, colorspace: str = "auto") -> np.ndarray:
    """Read an image with OpenImageIO as (H, W, 3) linear float32. ``colorspace``: "auto" (8/16-bit integer files
    are sRGB, float files linear), "srgb" or "raw"/"linear"."""
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(str(path))
    if buf.has_error:
        raise ValueError(f"cannot read texture {path}: {buf.geterror()}")
    spec = buf.spec()
    pixels = buf.get_pixels(oiio.FLOAT)
    if pixels is None or pixels.size == 0:
        raise ValueError(f"cannot read texture {path}: no pixels")
    pixels = np.asarray(pixels, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels)
    if spec.nchannels == 1:
        pixels = np.repeat(pixels, 3, axis=2)
    elif spec.nchannels == 2:
        pixels = np.repeat(pixels[..., :1], 3, axis=2)
    rgb = pixels[..., :3]
    is_float = spec.format.basetype in (oiio.FLOAT, oiio.HALF, oiio.DOUBLE)
    if colorspace == "srgb" or (colorspace == "auto" and not is_float):
        rgb = srgb_to_linear(rgb)
    return np.ascontiguousarray(np.nan_to_num(rgb), dtype=np.float32)


def pack_textures(textures: list):
    """All textures in one (P, 3) float32 array plus an (n, 3) int64 table of (first row, height, width), for kernels."""
    info = np.zeros((len(textures), 3), np.int64)
    offset = 0
    for i, tex in enumerate(textures):
        info[i] = (offset, tex.shape[0], tex.shape[1])
        offset += tex.shape[0] * tex.shape[1]
    data = (np.concatenate([np.asarray(t, np.float32)[..., :3].reshape(-1, 3) for t in textures])
            if textures else np.zeros((0, 3), np.float32))
    return np.ascontiguousarray(data), info


@kernel(inline=True)
def bilinear(data, info, index, s, t):
    """Bilinear lookup of texture ``index`` of a :func:`pack_textures` pair at (s, t) (s right, t up, repeat
    wrapping): an (r, g, b) tuple."""
    first, h, w = info[index, 0], info[index, 1], info[index, 2]
    x = s * w - 0.5
    y = (1.0 - t) * h - 0.5
    xf = math.floor(x)
    yf = math.floor(y)
    fx = x - xf
    fy = y - yf
    x0 = int(xf) % w
    y0 = int(yf) % h
    x1 = (x0 + 1) % w
    y1 = (y0 + 1) % h
    w00 = (1.0 - fx) * (1.0 - fy)
    w01 = fx * (1.0 - fy)
    w10 = (1.0 - fx) * fy
    w11 = fx * fy
    a, b, c, d = first + y0 * w + x0, first + y0 * w + x1, first + y1 * w + x0, first + y1 * w + x1
    return (w00 * data[a, 0] + w01 * data[b, 0] + w10 * data[c, 0] + w11 * data[d, 0],
            w00 * data[a, 1] + w01 * data[b, 1] + w10 * data[c, 1] + w11 * data[d, 1],
            w00 * data[a, 2] + w01 * data[b, 2] + w10 * data[c, 2] + w11 * data[d, 2])


@kernel
def _bilinear_rows(data, info, uv, out):
    for i in range(uv.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = bilinear(data, info, 0, uv[i, 0], uv[i, 1])


def sample_bilinear(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear lookup of (N, 2) texture coordinates (u right, v up, repeat wrapping) in an (H, W, 3) image."""
    data, info = pack_textures([image])
    uv = np.ascontiguousarray(uv, dtype=np.float64).reshape(-1, 2)
    out = np.empty((len(uv), 3), np.float32)
    _bilinear_rows(data, info, uv, out)
    return out

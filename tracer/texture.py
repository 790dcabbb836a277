"""Image textures: loading through OpenImageIO and bilinear lookups with repeat wrapping."""

from __future__ import annotations

import numpy as np


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


def sample_bilinear(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear lookup of (N, 2) texture coordinates (u right, v up, repeat wrapping) in an (H, W, 3) image."""
    h, w = image.shape[:2]
    x = uv[:, 0] * w - 0.5
    y = (1.0 - uv[:, 1]) * h - 0.5
    x0 = np.floor(x)
    y0 = np.floor(y)
    fx = (x - x0)[:, None].astype(np.float32)
    fy = (y - y0)[:, None].astype(np.float32)
    x0 = x0.astype(np.int64) % w
    y0 = y0.astype(np.int64) % h
    x1 = (x0 + 1) % w
    y1 = (y0 + 1) % h
    top = image[y0, x0] * (1 - fx) + image[y0, x1] * fx
    bottom = image[y1, x0] * (1 - fx) + image[y1, x1] * fx
    return top * (1 - fy) + bottom * fy

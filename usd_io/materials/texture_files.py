"""Texture files named by USD asset paths -> linear float pixels, as UsdUVTexture reads them.

Resolution is USD's (``Sdf.AssetPath.resolvedPath``, the default Ar resolver), so anchored paths, search paths and
files inside a ``.usdz`` package work alike. OpenImageIO cannot read inside a zip: a package-relative path
(``/a/b.usdz[textures/c.png]``) is read through ``Ar`` (``ArResolver.OpenAsset``, which knows nested packages) into
a temporary file that OIIO then decodes; the file is removed at once.

UsdUVTexture conventions (UsdPreviewSurface spec 2.5); the decoding is the tracer's one decoder's,
:func:`tracer.shading.texture.decode_image`, whose rules are these:

- channels: 1 channel -> (v, v, v, 1); 2 channels -> (v, v, v, a); 3 -> (r, g, b, 1); 4 -> (r, g, b, a). Images
  are returned with 4 channels, so every output (r, g, b, a, rgb) means the same in every file.
- ``sourceColorSpace``: ``sRGB`` decodes r, g, b through the sRGB curve (alpha is never decoded); ``raw`` keeps the values; ``auto`` is sRGB for 8-bit files of 3 or 4 channels and raw otherwise,
  Storm's rule (``HioOIIO_Image::IsColorSpaceSRGB``; the spec's fallback when a file has no colour metadata, and
  OIIO labels every 8-bit PNG/JPEG sRGB, grey ones too): one-channel maps (roughness, masks) stay linear.
- ``wrapS/wrapT = useMetadata``: the file's ``wrapmodes`` metadata (TIFF/OpenEXR/TX; ``periodic`` = repeat), else
  **repeat** (see docs/usd.md: the spec says black, but Blender, Arnold and the usd-wg assets expect repeat).
- 8-bit values become [0, 1] before scale and bias (OIIO's FLOAT conversion), as the spec's outputs say.
- colour is straight (unassociated) alpha, as the spec says of every UsdPreviewSurface input: OIIO would otherwise
  premultiply PNG colour by its alpha and darken the edges of every cut-out.
"""

from __future__ import annotations

import os
import tempfile

import numpy as np
from pxr import Ar

from tracer.colorspace import to_lin_rec709
from tracer.shading.texture import WRAP_MODES as WRAPS, decode_image


class TextureFile:
    """One decoded image: ``pixels`` (H, W, 4) float32 linear (row 0 is the top of the image), its wrap metadata and
    whether the ``auto`` colour space found it to be sRGB."""

    def __init__(self, pixels: np.ndarray, wrap_meta: tuple, srgb: bool, label: str, mip_levels: int = 1):
        self.pixels, self.wrap_meta, self.srgb, self.label = pixels, wrap_meta, srgb, label
        self.mip_levels = mip_levels  # MIP levels authored in the file (level 0 is the one read)


def authored_mip_levels(path: str) -> int:
    """How many MIP levels the file at ``path`` holds when its coarser levels are authored content of their own
    (a level's mean colour more than 2/255 from level 0's: testUsdImagingGLMipmap's authoredMips.tex), else 1 (one
    level, or a pyramid filtered from level 0 as ``maketx`` writes it; also when the file cannot be asked)."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(path)
    if inp is None:
        return 1
    try:
        means = []
        while inp.seek_subimage(0, len(means)):
            px = inp.read_image(0, len(means), 0, min(3, inp.spec().nchannels), "float")
            if px is None:
                return 1
            means.append(np.asarray(px, np.float64).reshape(-1, np.asarray(px).shape[-1]).mean(axis=0))
        if len(means) > 1 and max(float(np.abs(m - means[0]).max()) for m in means[1:]) > 2 / 255:
            return len(means)
        return 1
    finally:
        inp.close()


def read_texture_file(resolved: str, colorspace: str = "auto", label: str | None = None) -> TextureFile:
    """Decode ``resolved`` (a resolved USD asset path) as UsdUVTexture does (the tracer's one decoder,
    :func:`tracer.shading.texture.decode_image`). ValueError when it cannot be read."""
    label = label or resolved
    mx_space = colorspace[3:] if colorspace.startswith("mx:") else None  # a MaterialX colour space: raw, then its
    colorspace = "raw" if mx_space else colorspace  # transform into linear Rec.709 (tracer.colorspace)
    colorspace = colorspace if colorspace in ("sRGB", "raw") else "auto"  # the spec's tokens; anything else: auto
    if Ar.IsPackageRelativePath(resolved):
        image = _read_packaged(resolved, colorspace, label)
    else:
        if not os.path.isfile(resolved):
            raise ValueError(f"cannot read texture {label}: no such file")
        image = decode_image(resolved, colorspace, label)
    mips = 1 if Ar.IsPackageRelativePath(resolved) else authored_mip_levels(resolved)
    rgba = image.rgba
    if mx_space:
        rgba = np.array(rgba, np.float32)
        rgba[..., :3] = to_lin_rec709(rgba[..., :3], mx_space).astype(np.float32)
    return TextureFile(rgba, image.wrap_meta, image.srgb, label, mips)


def _read_packaged(resolved: str, colorspace: str, label: str):
    """Read a file inside a package (.usdz) through Ar and decode it from a temporary copy."""
    asset = Ar.GetResolver().OpenAsset(Ar.ResolvedPath(resolved))
    if asset is None:
        raise ValueError(f"cannot read texture {label}: not found in its package")
    data = asset.GetBuffer()
    if not data:
        raise ValueError(f"cannot read texture {label}: empty file in its package")
    inner = Ar.SplitPackageRelativePathInner(resolved)[1]
    suffix = os.path.splitext(inner)[1] or ".img"
    fd, tmp = tempfile.mkstemp(prefix="whitted-tex-", suffix=suffix)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(bytes(data))
        return decode_image(tmp, colorspace, label)
    finally:
        os.unlink(tmp)


def resolve_wrap(token: str, meta: str, label: str, warn) -> str:
    """A UsdUVTexture wrap token -> one of WRAPS (``useMetadata``: the file's own, else repeat)."""
    if token in WRAPS:
        return token
    if token != "useMetadata":
        warn(f"{label}: unknown wrap mode {token!r} (repeat used)")
        return "repeat"
    return meta if meta in WRAPS else "repeat"


class TextureCache:
    """Decoded files by (resolved path, colour space), so a file read by several nodes is decoded once and its
    pixels are one array. ``working``: None (the tracer's linear Rec.709), or a 3 × 3 matrix from linear Rec.709
    into the space the scene's colour numbers are in, applied to the colour textures decoded from sRGB (raw and
    linear data stay as they are): load_stage(rendering_space="acescg") reads a stage in Arnold's ACEScg, where a
    colour texture is converted into the rendering space and a constant is taken as it is."""

    def __init__(self, working: np.ndarray | None = None):
        self._files: dict = {}
        self.working = None if working is None else np.asarray(working, np.float32)

    def get(self, resolved: str, colorspace: str, label: str) -> TextureFile:
        key = (resolved, colorspace)
        if key not in self._files:
            try:
                got = read_texture_file(resolved, colorspace, label)
                if self.working is not None and got.srgb:
                    px = np.array(got.pixels, np.float32)
                    px[..., :3] = px[..., :3] @ self.working.T
                    got = TextureFile(np.ascontiguousarray(px), got.wrap_meta, got.srgb, got.label, got.mip_levels)
                self._files[key] = got
            except ValueError as exc:
                self._files[key] = exc
        hit = self._files[key]
        if isinstance(hit, Exception):
            raise hit
        return hit

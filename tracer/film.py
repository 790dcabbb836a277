"""The film: box-filtered pixels from samples, AOVs, and image files through OpenImageIO.

PNG (8-bit) and other display formats are written through the sRGB transfer function (Blender's "Standard" view);
EXR, HDR and TIFF-float stay scene-linear. Files are written to a temporary name and renamed, so an interrupted
write never leaves a half-written image.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass, field

import numpy as np

from .colorspace import linear_to_srgb, srgb_to_linear

LINEAR_EXTENSIONS = (".exr", ".hdr")


@dataclass
class Image:
    """A rendered frame: ``rgba`` (H, W, 4) float32 scene-linear, AOVs by name, ray counts and timings."""

    rgba: np.ndarray
    aovs: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)

    @property
    def rgb(self) -> np.ndarray:
        return self.rgba[..., :3]

    def save(self, path: str, **kwargs) -> None:
        write_image(path, self.rgba, **kwargs)


def box_filter(values: np.ndarray, spp: int) -> np.ndarray:
    """Average consecutive groups of ``spp`` samples (samples of one pixel are stored together). With one sample per
    pixel the samples themselves are returned (not a copy)."""
    if spp == 1:
        return values
    return values.reshape((-1, spp) + values.shape[1:]).mean(axis=1)


def majority(ids: np.ndarray, spp: int, limit: int = 16) -> np.ndarray:
    """Per pixel, the id seen by most of its samples (ties: the smaller id); at most ``limit`` samples vote."""
    return vote(ids.reshape(-1, spp)[:, :limit])


def vote(g: np.ndarray, ok: np.ndarray | None = None) -> np.ndarray:
    """Per row of ``g`` (P, L), the id most of its entries hold (ties: the smaller id); ``ok`` (P, L), where given,
    says which entries vote (adaptive sampling: a pixel's samples, fewer than L)."""
    same = g[:, :, None] == g[:, None, :]
    if ok is None:
        votes = same.sum(axis=2)
    else:
        votes = np.where(ok, (same & ok[:, None, :]).sum(axis=2), 0)
    best = np.max(votes, axis=1, keepdims=True)
    return np.where(votes == best, g, np.iinfo(np.int32).max).min(axis=1).astype(np.int32)


def to_display(rgba: np.ndarray) -> np.ndarray:
    """sRGB-encoded 8-bit RGBA from scene-linear floats (colour channels only; alpha stays linear)."""
    out = np.empty(rgba.shape, np.float32)
    out[..., :3] = linear_to_srgb(rgba[..., :3])
    out[..., 3:] = np.clip(rgba[..., 3:], 0, 1)
    return np.round(out * 255.0).astype(np.uint8)


#: Heat-map colours (display sRGB, "inferno"-like: black → purple → orange → pale yellow) at evenly spaced stops.
_HEAT_STOPS = np.array([[0, 0, 4], [87, 16, 110], [188, 55, 84], [249, 142, 9], [252, 255, 164]], np.float64) / 255


def heat_map(values: np.ndarray, vmax: float | None = None) -> np.ndarray:
    """(H, W) values -> (H, W, 3) scene-linear colours of a heat map (0 black, ``vmax`` pale yellow; negative
    values, e.g. "nothing traced", black). For PNG pictures of integer AOVs such as ``raydepth``."""
    v = np.asarray(values, np.float64)
    top = float(vmax if vmax is not None else max(1.0, np.nanmax(v) if v.size else 1.0))
    x = np.clip(np.nan_to_num(v / top), 0, 1) * (len(_HEAT_STOPS) - 1)
    i = np.minimum(x.astype(int), len(_HEAT_STOPS) - 2)
    f = (x - i)[..., None]
    srgb = _HEAT_STOPS[i] * (1 - f) + _HEAT_STOPS[i + 1] * f

    return srgb_to_linear(srgb).astype(np.float32)


#: The temporary files of writes in progress (:func:`temp_file`): a process interrupted mid-write (SIGINT in the
#: command line) removes them with :func:`remove_temp_files`, wherever the interrupt landed.
_TEMP_FILES: set = set()


def temp_file(path: str, ext: str) -> str:
    """A new empty temporary file next to ``path`` (``.whitted-*ext``, the same directory: the final rename stays
    on one filesystem), registered until :func:`finish_temp` renames or removes it. ValueError naming ``path``."""
    directory = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(directory):
        raise ValueError(f"{path}: directory {directory} does not exist")
    try:
        fd, tmp = tempfile.mkstemp(prefix=".whitted-", suffix=ext, dir=directory)
    except OSError as exc:
        raise ValueError(f"{path}: cannot write into {directory} ({exc.strerror})") from None
    os.close(fd)
    _TEMP_FILES.add(tmp)
    return tmp


def finish_temp(tmp: str, path: str | None) -> None:
    """Rename the written temporary file ``tmp`` to ``path`` (mkstemp's 0600 widened to the usual permissions);
    ``path`` None, or any failure: remove it. Either way it leaves the registry."""
    try:
        if path is not None:
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(tmp, 0o666 & ~umask)
            try:
                os.replace(tmp, path)
            except OSError as exc:
                raise ValueError(f"{path}: cannot write ({exc.strerror})") from None
    finally:
        _TEMP_FILES.discard(tmp)
        if os.path.exists(tmp):
            os.unlink(tmp)


def remove_temp_files() -> None:
    """Remove every temporary file of a write still in progress (an interrupted process)."""
    for tmp in list(_TEMP_FILES):
        _TEMP_FILES.discard(tmp)
        try:
            os.unlink(tmp)
        except OSError:
            pass


def check_space(path: str, nbytes: int) -> None:
    """ValueError unless the filesystem of ``path``'s directory has ``nbytes`` free for an unprivileged writer
    (``os.statvfs``: f_bavail · f_frsize). Called with the image's uncompressed size, an upper bound of what any
    of the formats writes, so a full disk is one clear error before the write, not a truncated file (some
    encoders do not report a failed write: libpng through OpenImageIO wrote a cut PNG and said nothing, libjpeg
    exits the process)."""
    try:
        st = os.statvfs(os.path.dirname(os.path.abspath(path)))
    except (OSError, AttributeError):
        return
    free = st.f_bavail * st.f_frsize
    if free < nbytes:
        raise ValueError(f"{path}: not enough space on the output disk ({free} bytes free, the image needs up to "
                         f"{nbytes})")


_PNG_END = b"\x00\x00\x00\x00IEND\xaeB`\x82"


def check_png_complete(tmp: str, path: str) -> None:
    """ValueError unless the PNG written to ``tmp`` ends with its IEND chunk: OpenImageIO's PNG writer does not
    report a failed write (a full disk, a file size limit), and a cut file would be renamed into place."""
    try:
        with open(tmp, "rb") as f:
            f.seek(0, os.SEEK_END)
            f.seek(max(0, f.tell() - len(_PNG_END)))
            tail = f.read()
    except OSError as exc:
        raise ValueError(f"{path}: write failed ({exc.strerror})") from None
    if tail != _PNG_END:
        raise ValueError(f"{path}: write failed (the PNG was cut short: is the output disk full?)")


#: PNG encoding (docs/benchmarks.md, "PNG writes"): zlib level 1 with libpng's "none" row filter (PNG_FILTER_NONE =
#: 8): a 1920×1080 render encodes in about half the CPU time of the default (level 6, adaptive filters) for files
#: about a third larger; the pixels are the same (PNG is lossless).
PNG_COMPRESSION_LEVEL = 1
PNG_FILTER_NONE = 8


def write_image(path: str, pixels: np.ndarray, channel_names=None, float32: bool = False) -> None:
    """Write (H, W, C) float pixels: linear for EXR/HDR, sRGB 8-bit otherwise. Atomic (temp file + rename).
    EXR is half float unless ``float32`` (AOVs: object ids and depths beyond half's exact range)."""
    import OpenImageIO as oiio

    path = os.fspath(path)
    pixels = np.nan_to_num(np.asarray(pixels, dtype=np.float32), nan=0.0, posinf=0.0, neginf=0.0)
    if pixels.ndim == 2:
        pixels = pixels[..., None]
    h, w, c = pixels.shape
    ext = os.path.splitext(path)[1].lower()
    if not ext:
        raise ValueError(f"{path}: the output needs a file extension (.png, .exr, ...)")
    if c == 4 and not keeps_alpha(ext):  # RGB-only formats (Radiance .hdr, JPEG): the colour, without alpha
        pixels, c = pixels[..., :3], 3
    linear = ext in LINEAR_EXTENSIONS
    if linear:
        data, fmt = pixels, oiio.HALF if ext == ".exr" and not float32 else oiio.FLOAT
    else:
        if c in (3, 4):
            data = to_display(pixels if c == 4 else np.concatenate([pixels, np.ones((h, w, 1), np.float32)], -1))
            data = data[..., :c]
        else:
            data = np.round(np.clip(pixels, 0, 1) * 255).astype(np.uint8)
        fmt = oiio.UINT8
    spec = oiio.ImageSpec(w, h, c, fmt)
    if ext == ".png":  # fast zlib, no per-row filter search: half the encode time of libpng's default (6, adaptive)
        spec.attribute("png:compressionLevel", PNG_COMPRESSION_LEVEL)
        spec.attribute("png:filter", PNG_FILTER_NONE)
    if channel_names:
        spec.channelnames = tuple(channel_names)
    check_space(path, data.nbytes)
    tmp = temp_file(path, ext)
    done = None
    try:
        out = oiio.ImageOutput.create(tmp)
        if out is None:
            raise ValueError(f"{path}: OpenImageIO cannot write '{ext}' files ({oiio.geterror()})")
        if not out.open(tmp, spec):
            msg = out.geterror()
            raise ValueError(f"{path}: cannot open for writing ({msg})")
        ok = out.write_image(data)
        closed = out.close()
        if not ok or not closed:
            raise ValueError(f"{path}: write failed ({out.geterror()})")
        if ext == ".png":
            check_png_complete(tmp, path)
        done = path
    finally:
        finish_temp(tmp, done)


def keeps_alpha(ext: str) -> bool:
    """Whether OpenImageIO's writer of file type ``ext`` (".png", ...) stores an alpha channel (its
    ``supports("alpha")``: Radiance HDR and JPEG do not; an unknown type says True and fails when written)."""
    import OpenImageIO as oiio

    out = oiio.ImageOutput.create(ext.lstrip(".").lower())
    return out is None or bool(out.supports("alpha"))


def read_image(path: str) -> np.ndarray:
    """Read an image as (H, W, C) float32 (as stored: PNG values are sRGB-encoded in [0, 1])."""
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(os.fspath(path))
    if buf.has_error:
        raise ValueError(f"cannot read {path}: {buf.geterror()}")
    spec = buf.spec()
    return np.asarray(buf.get_pixels(oiio.FLOAT), np.float32).reshape(spec.height, spec.width, spec.nchannels)

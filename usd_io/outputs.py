"""What a render writes, the same wherever it runs (a local render, the farm's client, a farm worker with
``--worker-writes``), and the one user-error type of the command line.

:class:`Outputs` is the image post-processing and the files of one render: the exposure, the AOVs (EXR next to
the image; ``raydepth`` also as a heat-map PNG scaled to the max depth). :func:`frame_path` names each frame of
an output pattern. Bad input anywhere in ``usd_io`` is :class:`usd_io.UsdInputError` (``BadInput`` is the same
class): one line on stderr and exit 2 from the CLI.
"""

from __future__ import annotations

import os
import re
import sys
from dataclasses import dataclass

import numpy as np

from .errors import UsdInputError

#: The command line's name for :class:`usd_io.UsdInputError` (the same class: there is one user-error type).
BadInput = UsdInputError

#: Image types the outputs can be written as.
OUTPUT_TYPES = (".png", ".exr", ".jpg", ".jpeg", ".tif", ".tiff", ".hdr")


@dataclass(frozen=True)
class Outputs:
    """How an image becomes files: ``exposure`` in stops (pixels × 2^EV), the ``aovs`` written next to it,
    ``max_depth`` the top of the ``raydepth`` heat map, ``max_samples`` (the N×N budget) of the ``sample_count``
    one."""

    aovs: tuple = ()
    exposure: float = 0.0
    max_depth: int | None = None
    max_samples: int | None = None
    denoise: bool = False

    @classmethod
    def of(cls, settings, exposure: float = 0.0) -> "Outputs":
        """The outputs of a render with ``settings`` (its AOVs, max depth and whether it denoises) at ``exposure``
        (checked finite)."""
        if not np.isfinite(exposure):
            raise BadInput(f"--exposure must be a finite number, got {exposure}")
        return cls(aovs=tuple(settings.aovs), exposure=float(exposure), max_depth=settings.max_depth,
                   max_samples=settings.samples ** 2, denoise=bool(settings.denoise))

    def expose(self, image) -> None:
        """The exposure applied to ``image`` in place (colour only; alpha and AOVs stay)."""
        if self.exposure:
            image.rgba[..., :3] *= np.float32(2.0 ** self.exposure)

    def stream(self, out: str, width: int, height: int):
        """For a PNG ``out``: a :class:`tracer.png_stream.StreamedPNG` to hand to ``tracer.render`` as ``on_tile``
        (the picture is encoded band by band while the render runs, this exposure applied); None otherwise, and for
        a render that denoises (its pixels change once the whole frame is done)."""
        if os.path.splitext(out)[1].lower() != ".png" or self.denoise:
            return None
        from tracer.png_stream import StreamedPNG  # the tracer loads after the flags are checked (start-up)

        try:
            return StreamedPNG(out, width, height, scale=np.float32(2.0 ** self.exposure))
        except ValueError as exc:
            raise BadInput(str(exc)) from None

    def write(self, image, out: str, stream=None) -> None:
        """Expose ``image`` (in place) and write it and its AOVs to ``out`` (atomically, as tracer.film writes);
        with ``stream`` (:meth:`stream`'s, fed by the render) the picture is what the stream wrote."""
        if stream is not None:
            try:
                stream.finish(image)  # before the exposure below: the stream applies it itself
            except ValueError as exc:
                raise BadInput(str(exc)) from None
        self.expose(image)
        write_outputs(image, out, self.aovs, max_depth=self.max_depth, max_samples=self.max_samples,
                      picture=stream is None)


def warn(message: str) -> None:
    """One ``whitted: warning:`` line on stderr."""
    print(f"whitted: warning: {message}", file=sys.stderr)


def print_warnings(info) -> None:
    """A stage's notes and warnings (``StageInfo``), one line each on stderr."""
    for n in getattr(info, "notes", ()):
        print(f"whitted: note: {n}", file=sys.stderr)
    for w in info.warnings:
        warn(w)


def frame_path(pattern: str, frame: float | None, many: bool) -> str:
    """The output path of ``frame``: ``#`` runs replaced by the zero-padded frame number, or (``many`` frames and
    no ``#``) ``.####`` inserted before the extension; a single frame (or ``frame`` None) keeps ``pattern``."""
    if frame is None:
        return pattern
    label = lambda width: (f"{int(frame):0{width}d}" if float(frame).is_integer()  # noqa: E731
                           else f"{frame:0{width + 4}.3f}".rstrip("0"))
    if re.search(r"#+", pattern):
        return re.sub(r"#+", lambda m: label(len(m.group(0))), pattern, count=1) if many else pattern
    if not many:
        return pattern
    root, ext = os.path.splitext(pattern)
    return f"{root}.{label(4)}{ext}"


def output_for(pattern: str, scene: str) -> str:
    """The output path of one scene: ``{stem}`` -> file name without extension, ``{name}`` -> with it."""
    base = os.path.basename(scene)
    return pattern.replace("{stem}", os.path.splitext(base)[0]).replace("{name}", base)


def product_path(name: str, directory: str | None = None, anywhere: bool = False) -> str:
    """Where a RenderProduct's ``productName`` is written. The name comes from the stage, and a stage may be
    anyone's (a survey of downloaded assets, a farm's queue), so it is joined to ``directory`` (default: the
    current directory) and must stay inside it: a name whose real path (``os.path.realpath``: ``..``, an absolute
    path and symbolic links resolved) leaves the directory is a :class:`BadInput`, unless ``anywhere``
    (``--allow-product-paths``: a trusted pipeline's stage writes where it says)."""
    base = os.path.realpath(directory or os.curdir)
    path = os.path.join(base, name)
    if anywhere:
        return path
    real = os.path.realpath(path)
    if real == base or os.path.commonpath([real, base]) != base:
        where = f"--output-dir {directory}" if directory else f"the output directory {base}"
        raise BadInput(f"RenderProduct productName {name!r} leaves {where}; refusing to write {real} "
                       "(--allow-product-paths writes products where the stage says)")
    return path


def aov_path(image_path: str, aov: str) -> str:
    root, _ext = os.path.splitext(image_path)
    return f"{root}.{aov}.exr"


def check_output(path: str, types=OUTPUT_TYPES):
    """A clear UsdInputError unless ``path`` has one of ``types`` and its directory exists."""
    ext = os.path.splitext(path)[1].lower()
    if ext not in types:
        raise BadInput(f"{path}: unsupported output type {ext or '(none)'!r}; use "
                       f"{', '.join(t for t in types if t not in ('.jpeg', '.tiff'))}")
    directory = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(directory):
        raise BadInput(f"{path}: output directory {directory} does not exist")


def write_outputs(image, out, aovs, max_depth: int | None = None, picture: bool = True,
                  max_samples: int | None = None) -> None:
    """The image (unless ``picture`` is False: written already) and its AOVs (EXR next to it; ``raydepth`` also as a
    heat-map PNG scaled to ``max_depth``, ``sample_count`` to ``max_samples``)."""
    try:
        if picture:
            _save(image, out)
        for name in aovs:
            a = image.aovs[name]
            a = a[..., None] if a.ndim == 2 else a
            _write_aov(aov_path(out, name), a.astype(np.float32))
            if name == "raydepth":  # and a heat-map picture of it (black: eye rays only; yellow: max depth)
                from tracer.film import heat_map  # (start-up: as in stream)

                _write_aov(aov_path(out, name)[:-4] + ".png", heat_map(a[..., 0], max_depth))
            if name == "sample_count":  # black: no samples; yellow: the whole N×N budget
                from tracer.film import heat_map  # (start-up: as in stream)

                _write_aov(aov_path(out, name)[:-4] + ".png", heat_map(a[..., 0], max_samples))
    except ValueError as exc:  # unwritable output (the tracer's film names the file and the reason)
        raise BadInput(str(exc)) from None


def _save(image, out: str) -> None:
    """PNG/TIFF/EXR keep alpha; formats without it (JPEG, Radiance HDR) get RGB (tracer.film.write_image)."""
    image.save(out)


def _write_aov(path, pixels):
    from tracer import write_image  # (start-up: as in stream)

    write_image(path, np.nan_to_num(pixels, posinf=0.0, neginf=0.0), float32=True)

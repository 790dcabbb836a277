"""PNG files written while the render runs: finished bands of rows are encoded on a writer thread.

:class:`StreamedPNG` is handed to :func:`tracer.render` as its ``on_tile`` callback. Tiles arrive row by row
(:func:`tracer.integrator.tiles.tiles_of`); once every tile of a band of rows is in the film, the band is queued, and a
writer thread turns it into 8-bit sRGB and passes it to libpng through OpenImageIO (``write_scanlines``, which
runs without the GIL), while the tile threads trace the next rows. When the render returns only the last band is
left to encode. The file is the one :func:`tracer.film.write_image` writes (same OpenImageIO settings, same
bytes: tests/test_png_stream.py), written to a temporary name and renamed when complete.

The 8-bit conversion is :func:`tracer.film.to_display` (the sRGB transfer function, rounded), evaluated once per
code instead of once per pixel: it is monotonic, so the code of a value is the number of the 255 thresholds
(:func:`display_thresholds`, the smallest float32 reaching each code, found by bisection over float32 bit patterns
through ``to_display`` itself) at or below it; NaN and ±inf are 0, as ``write_image``'s ``nan_to_num`` makes them.
A kernel does that per pixel without the GIL: 8 comparisons instead of numpy's ``clip``/``power``/``where``/
``round`` passes over fresh 33 MB temporaries (0.3 s CPU per 1080p frame in a fresh process, most of it page
faults).
"""

from __future__ import annotations

import os
import queue
import threading

import numpy as np

from .film import (PNG_COMPRESSION_LEVEL, PNG_FILTER_NONE, check_png_complete, check_space, finish_temp, temp_file,
                   to_display)
from .jit import kernel

_THRESHOLDS: tuple | None = None


def display_thresholds() -> tuple[np.ndarray, np.ndarray]:
    """(colour, alpha): for each code k = 1..255 the smallest float32 v in [0, 1] with ``to_display(v) >= k``
    (colour channels through the sRGB curve, alpha linear), each a sorted (255,) float32 array."""
    global _THRESHOLDS
    if _THRESHOLDS is None:
        codes = np.arange(1, 256)
        lo = np.zeros((255, 4), np.int64)  # float32 bit patterns: for v >= 0 they order as the values do
        hi = np.full((255, 4), np.float32(1.0).view(np.int32), np.int64)
        while np.any(lo < hi):
            mid = (lo + hi) // 2
            reached = to_display(mid.astype(np.int32).view(np.float32)) >= codes[:, None]
            hi = np.where(reached, mid, hi)
            lo = np.where(reached, lo, mid + 1)
        t = lo.astype(np.int32).view(np.float32)
        _THRESHOLDS = (np.ascontiguousarray(t[:, 0]), np.ascontiguousarray(t[:, 3]))
    return _THRESHOLDS


@kernel(inline=True)
def _code(v, t):
    """Number of thresholds ``t`` (sorted) at or below ``v``; NaN and ±inf give 0."""
    if not (v > -np.inf and v < np.inf):
        return 0
    lo, hi = 0, t.shape[0]
    while lo < hi:
        mid = (lo + hi) >> 1
        if t[mid] <= v:
            lo = mid + 1
        else:
            hi = mid
    return lo


@kernel(refcounts=False)
def encode_rows(rgba, y0, y1, scale, colour_t, alpha_t, out):
    """out[0:y1-y0] = 8-bit sRGB RGBA of rgba[y0:y1] with the colour scaled by ``scale`` (float32, the exposure)."""
    w = rgba.shape[1]
    for y in range(y0, y1):
        for x in range(w):
            for c in range(3):
                out[y - y0, x, c] = _code(rgba[y, x, c] * scale, colour_t)
            out[y - y0, x, 3] = _code(rgba[y, x, 3], alpha_t)


def to_display_fast(rgba: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """:func:`tracer.film.to_display` of an (H, W, 4) float32 image (colour × ``scale``), by :func:`encode_rows`."""
    rgba = np.ascontiguousarray(rgba, np.float32)
    out = np.empty(rgba.shape, np.uint8)
    colour_t, alpha_t = display_thresholds()
    encode_rows(rgba, 0, rgba.shape[0], np.float32(scale), colour_t, alpha_t, out)
    return out


class StreamedPNG:
    """An RGBA PNG of a ``width`` × ``height`` render written band by band as tiles finish (``on_tile``), the colour
    multiplied by ``scale`` (float32; an exposure of EV stops is 2^EV). :meth:`finish` writes what is left and
    renames the file into place; :meth:`abort` removes it. Errors say which file (ValueError), as write_image."""

    def __init__(self, path: str, width: int, height: int, scale: float = 1.0):
        import OpenImageIO as oiio

        self.path = os.fspath(path)
        self.width, self.height = int(width), int(height)
        self.scale = np.float32(scale)
        check_space(self.path, self.width * self.height * 4)  # 8-bit RGBA uncompressed: a bound of the file
        self._tmp = temp_file(self.path, ".png")
        self._spec = oiio.ImageSpec(self.width, self.height, 4, oiio.UINT8)
        self._spec.attribute("png:compressionLevel", PNG_COMPRESSION_LEVEL)
        self._spec.attribute("png:filter", PNG_FILTER_NONE)
        self._out = None  # opened on the writer thread: OpenImageIO's first open sets itself up (20-90 ms)
        self._thresholds = display_thresholds()
        self._row_filled = np.zeros(self.height, np.int64)  # pixels of each row in the film so far
        self._next = 0  # first row not yet queued
        self._image = None
        self._queue: queue.Queue = queue.Queue()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._write_bands, name="whitted-png", daemon=True)
        self._thread.start()

    def on_tile(self, image, tile) -> None:
        """``tracer.render``'s callback: queue the rows that every tile has now reached."""
        x0, y0, x1, y1 = tile
        self._image = image
        self._row_filled[y0:y1] += x1 - x0
        end = self._next
        while end < self.height and self._row_filled[end] >= self.width:
            end += 1
        if end > self._next:
            self._queue.put((image.rgba, self._next, end))
            self._next = end

    def _open(self) -> None:
        import OpenImageIO as oiio

        self._out = oiio.ImageOutput.create(self._tmp)
        if self._out is None or not self._out.open(self._tmp, self._spec):
            msg = self._out.geterror() if self._out is not None else oiio.geterror()
            self._out = None
            raise ValueError(f"{self.path}: cannot open for writing ({msg})")

    def _write_bands(self) -> None:
        colour_t, alpha_t = self._thresholds
        try:
            self._open()
        except BaseException as exc:  # noqa: BLE001 — reported by finish() on the caller's thread
            self._error = exc
        while True:
            item = self._queue.get()
            if item is None:
                return
            if self._error is not None:
                continue
            rgba, y0, y1 = item
            try:
                band = np.empty((y1 - y0, self.width, 4), np.uint8)
                encode_rows(rgba, y0, y1, self.scale, colour_t, alpha_t, band)
                if not self._out.write_scanlines(y0, y1, 0, band):
                    raise ValueError(f"{self.path}: write failed ({self._out.geterror()})")
            except BaseException as exc:  # noqa: BLE001 — reported by finish() on the caller's thread
                self._error = exc

    def finish(self, image) -> None:
        """Write the rows not yet written (all of ``image``'s from the first one missing), close, rename."""
        if self._next < self.height:
            self._queue.put((np.ascontiguousarray(image.rgba, np.float32), self._next, self.height))
            self._next = self.height
        self._queue.put(None)
        self._thread.join()
        done = None
        try:
            if self._error is not None:
                if self._out is not None:
                    _quiet_close(self._out)
                raise self._error if isinstance(self._error, ValueError) else ValueError(
                    f"{self.path}: write failed ({self._error})")
            if not self._out.close():
                raise ValueError(f"{self.path}: write failed ({self._out.geterror()})")
            check_png_complete(self._tmp, self.path)
            done = self.path
        finally:
            finish_temp(self._tmp, done)

    def abort(self) -> None:
        """Stop writing and remove the temporary file (a render that failed or was cancelled)."""
        if self._thread.is_alive():
            self._error = self._error or RuntimeError("aborted")
            self._queue.put(None)
            self._thread.join()
        try:
            if self._out is not None:
                _quiet_close(self._out)
        except Exception:  # noqa: BLE001 — best effort: the file is removed next
            pass
        finish_temp(self._tmp, None)


def _quiet_close(out) -> None:
    """Close an OpenImageIO output whose file is dropped anyway, without libpng's complaint about it on the
    process's stderr ("No IDATs written into file": an abort before the first row), which would be a second
    line after the command line's one."""
    import sys

    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):
        out.close()
        return
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
            out.close()
    finally:
        os.dup2(saved, 2)
        os.close(saved)

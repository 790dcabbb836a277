"""Open Image Denoise: numpy in, numpy out, through our own ctypes binding to OIDN 2's C API.

:func:`denoise` filters a noisy HDR picture with OIDN's "RT" filter, guided by an albedo and a normal image as Cycles
feeds it (``intern/cycles/integrator/denoiser_oidn.cpp``): ``hdr`` on, ``srgb`` off, and by default the guides
prefiltered first with the same filter ("accurate", Cycles' default) and then trusted as clean (``cleanAux``).
:func:`denoise_image` denoises a rendered :class:`tracer.film.Image` in place from its ``denoising_albedo`` /
``denoising_normal`` AOVs (tracer/integrator/guides.py computes them as Cycles' Denoising Data passes): always a whole frame
(or the render region), never a tile, since the filter looks across tile borders.

Why a binding of our own (docs/benchmarks.md, "Denoising"): the C API we need is eight functions, and a ctypes
binding loads whichever OIDN 2 library is at hand, with no compiled code of ours. Where the library comes from, in
order:

1. ``$WHITTED_OIDN_LIBRARY`` (a path to the library file);
2. the folders the host names (:func:`add_search_dir`: inside Blender, the add-on names Blender's own library
   folder, whose OIDN Blender has loaded already);
3. the ``pyoidn`` wheel (``pip install 'whitted[denoise]'``: OIDN 2.5 for Linux x86-64, Windows x86-64, macOS x86-64
   and arm64), found by file, not imported;
4. the ``bpy`` module's ``bpy/lib`` (Blender's OIDN; found by file: the tracer never imports bpy);
5. a system library (``ctypes.util.find_library``).

Only the CPU device is used (a GPU device would first have to be probed, which costs more than a CPU denoise of a
preview). A library that cannot be found or loaded raises :class:`DenoiseUnavailable` with one clear message.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import glob
import importlib.util
import os
import sys
import threading
import time

import numpy as np

#: Environment variable naming the OIDN library to use before any other.
LIBRARY_ENV = "WHITTED_OIDN_LIBRARY"
#: The AOVs that guide the denoiser (tracer/integrator/guides.py): Cycles' Denoising Albedo and Denoising Normal.
GUIDE_AOVS = ("denoising_albedo", "denoising_normal")
#: OIDN major version the binding is written for (oidn.h of OIDN 2.x).
REQUIRED_MAJOR = 2
#: Prefilter modes of the guides, Cycles' names: "accurate" filters albedo and normal with the RT filter first and
#: then trusts them as clean; "none" trusts them as they are; "fast" hands them to the filter as noisy.
PREFILTERS = ("accurate", "none", "fast")
#: OIDN filter qualities (OIDNQuality); Cycles' final renders use "high", its viewport "balanced".
QUALITIES = {"default": 0, "fast": 4, "balanced": 5, "high": 6}

_DEVICE_TYPE_CPU = 1
_FORMAT_FLOAT3 = 3
_ERROR_NAMES = ("none", "unknown", "invalid argument", "invalid operation", "out of memory", "unsupported hardware",
                "cancelled")

#: Folders the add-on adds (Blender's own library folder): searched after the pyoidn wheel.
_extra_dirs: list[str] = []

_P, _S, _I, _B, _STR = ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int, ctypes.c_bool, ctypes.c_char_p
_SIGNATURES = {  # name: (restype, argtypes), from include/OpenImageDenoise/oidn.h (OIDN 2.x)
    "oidnNewDevice": (_P, [_I]),
    "oidnCommitDevice": (None, [_P]),
    "oidnReleaseDevice": (None, [_P]),
    "oidnSetDeviceBool": (None, [_P, _STR, _B]),
    "oidnSetDeviceInt": (None, [_P, _STR, _I]),
    "oidnGetDeviceInt": (_I, [_P, _STR]),
    "oidnGetDeviceError": (_I, [_P, ctypes.POINTER(ctypes.c_char_p)]),
    "oidnNewFilter": (_P, [_P, _STR]),
    "oidnReleaseFilter": (None, [_P]),
    "oidnSetSharedFilterImage": (None, [_P, _STR, _P, _I, _S, _S, _S, _S, _S]),
    "oidnSetFilterBool": (None, [_P, _STR, _B]),
    "oidnSetFilterInt": (None, [_P, _STR, _I]),
    "oidnCommitFilter": (None, [_P]),
    "oidnExecuteFilter": (None, [_P]),
}


class DenoiseUnavailable(RuntimeError):
    """No usable Open Image Denoise library (the message says where it looked and how to get one)."""


class DenoiseError(RuntimeError):
    """OIDN reported an error while denoising (its code and message)."""


def add_search_dir(path: str) -> None:
    """Look for the OIDN library in ``path`` too (the add-on names Blender's library folder)."""
    if path and path not in _extra_dirs:
        _extra_dirs.append(path)


def _patterns() -> tuple:
    if sys.platform == "win32":
        return ("OpenImageDenoise.dll",)
    if sys.platform == "darwin":
        return ("libOpenImageDenoise.2.dylib", "libOpenImageDenoise.2.*.dylib", "libOpenImageDenoise.dylib")
    return ("libOpenImageDenoise.so.2", "libOpenImageDenoise.so.2.*", "libOpenImageDenoise.so")


def _package_dir(name: str) -> str | None:
    """The folder of an installed package, found without importing it (pyoidn loads its library and cffi on
    import; bpy is Blender)."""
    try:
        spec = importlib.util.find_spec(name)
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.submodule_search_locations:
        return None
    return list(spec.submodule_search_locations)[0]


def search_dirs() -> list:
    """Folders searched for the library, in order (after ``$WHITTED_OIDN_LIBRARY``)."""
    dirs = list(_extra_dirs)  # the host's own first (inside Blender, the OIDN Blender has loaded already)
    pyoidn = _package_dir("pyoidn")
    if pyoidn:  # the wheel's own OIDN: lib/ on Linux and macOS, bin/ on Windows
        dirs += [os.path.join(pyoidn, "oidn", "bin"), os.path.join(pyoidn, "oidn", "lib")]
    bpy = _package_dir("bpy")
    if bpy:  # the bpy module (Blender as a Python module) ships Blender's libraries in bpy/lib
        dirs.append(os.path.join(bpy, "lib"))
    return [d for d in dirs if os.path.isdir(d)]


def find_library() -> str:
    """Path of an OIDN 2 library (module docstring for the order), or :class:`DenoiseUnavailable`."""
    env = os.environ.get(LIBRARY_ENV)
    if env:
        if os.path.isfile(env):
            return env
        raise DenoiseUnavailable(f"{LIBRARY_ENV}={env!r} is not a file")
    dirs = search_dirs()
    for d in dirs:
        for pattern in _patterns():
            found = sorted(glob.glob(os.path.join(d, pattern)))
            if found:
                return found[0]
    system = ctypes.util.find_library("OpenImageDenoise")
    if system:
        return system
    raise DenoiseUnavailable(
        "denoising needs Open Image Denoise 2, which was not found: pip install 'whitted[denoise]' (the pyoidn "
        f"wheel), or set {LIBRARY_ENV} to the library's path (Blender ships one). Looked in: "
        + (", ".join(dirs) if dirs else "no pyoidn or bpy package, no system library"))


class _Library:
    """The loaded library, its CPU device (made once per process), and the lock that serialises its use (OIDN
    serialises calls on one device anyway)."""

    def __init__(self, path: str):
        t0 = time.perf_counter()
        try:
            if sys.platform == "win32":  # its DLLs (core, devices, TBB) sit beside it: search that folder too
                os.add_dll_directory(os.path.dirname(os.path.abspath(path)))
                lib = ctypes.CDLL(path, winmode=0)
            else:
                lib = ctypes.CDLL(path)
        except OSError as exc:
            raise DenoiseUnavailable(f"cannot load Open Image Denoise from {path}: {exc}") from None
        for name, (res, args) in _SIGNATURES.items():
            try:
                fn = getattr(lib, name)
            except AttributeError:
                raise DenoiseUnavailable(f"{path} is not Open Image Denoise {REQUIRED_MAJOR}.x (no {name})") from None
            fn.restype, fn.argtypes = res, args
        self.lib, self.path = lib, path
        #: CPU devices by thread count (None: OIDN's own count, all cores), each made on first use: OIDN fixes a
        #: device's ``numThreads`` when it is committed, so a render on N threads denoises on a device of N.
        self.devices: dict = {}
        self._devices_lock = threading.Lock()
        self.device = self.device_for(None)
        self.version = int(lib.oidnGetDeviceInt(self.device, b"version"))  # e.g. 20303 for 2.3.3
        if self.version // 10000 != REQUIRED_MAJOR:
            raise DenoiseUnavailable(f"{path} is Open Image Denoise {self.version_string}, not {REQUIRED_MAJOR}.x")
        self.load_seconds = time.perf_counter() - t0
        self.lock = threading.Lock()

    def device_for(self, threads: int | None):
        """The CPU device that runs OIDN's filters on ``threads`` threads (None or 0: OIDN's default, every core;
        ``$OIDN_NUM_THREADS``, where set, still wins as OIDN has it), made and committed once per count."""
        key = int(threads) if threads and threads > 0 else None
        with self._devices_lock:
            device = self.devices.get(key)
            if device is None:
                device = self.devices[key] = self._new_device(key)
        return device

    def _new_device(self, key: int | None):
        lib = self.lib
        device = lib.oidnNewDevice(_DEVICE_TYPE_CPU)
        if not device:
            raise DenoiseUnavailable(f"Open Image Denoise ({self.path}) made no CPU device: {self._error(None)}")
        lib.oidnSetDeviceBool(device, b"setAffinity", False)  # as Cycles: do not pin threads (Blender's own)
        if key is not None:
            lib.oidnSetDeviceInt(device, b"numThreads", key)  # as Cycles' denoiser does with the render's threads
        lib.oidnCommitDevice(device)
        err = self._error(device)
        if err:
            lib.oidnReleaseDevice(device)
            raise DenoiseError(f"Open Image Denoise failed making the CPU device ({err})")
        return device

    def threads_of(self, threads: int | None = None) -> int:
        """The thread count the device for ``threads`` runs on, as OIDN reports it after committing it."""
        return int(self.lib.oidnGetDeviceInt(self.device_for(threads), b"numThreads"))

    @property
    def version_string(self) -> str:
        return f"{self.version // 10000}.{self.version // 100 % 100}.{self.version % 100}"

    def _error(self, device) -> str:
        msg = ctypes.c_char_p()
        code = self.lib.oidnGetDeviceError(device, ctypes.byref(msg))
        text = msg.value.decode("utf-8", "replace") if msg.value else ""
        return f"{_ERROR_NAMES[code] if 0 <= code < len(_ERROR_NAMES) else code}: {text}" if code else ""

    def check(self, what: str, device=None) -> None:
        err = self._error(device or self.device)
        if err:
            raise DenoiseError(f"Open Image Denoise failed {what} ({err})")

    def run(self, inputs: dict, output: np.ndarray, *, hdr: bool, clean_aux: bool, quality: int,
            threads: int | None = None) -> None:
        """One RT filter over shared (H, W, 3) float32 images (``inputs`` by OIDN name, ``output`` written), on the
        device of ``threads`` threads (:meth:`device_for`)."""
        lib = self.lib
        h, w = output.shape[:2]
        device = self.device_for(threads)
        filt = lib.oidnNewFilter(device, b"RT")
        if not filt:
            self.check("making a filter", device)
            raise DenoiseError("Open Image Denoise made no RT filter")
        try:
            for name, img in list(inputs.items()) + [("output", output)]:
                lib.oidnSetSharedFilterImage(filt, name.encode(), img.ctypes.data, _FORMAT_FLOAT3, w, h, 0, 0, 0)
            if "color" in inputs:
                lib.oidnSetFilterBool(filt, b"hdr", bool(hdr))
                lib.oidnSetFilterBool(filt, b"srgb", False)
                lib.oidnSetFilterBool(filt, b"cleanAux", bool(clean_aux))
            if quality:
                lib.oidnSetFilterInt(filt, b"quality", int(quality))
            lib.oidnCommitFilter(filt)
            self.check("setting up the filter", device)
            lib.oidnExecuteFilter(filt)
            self.check("filtering", device)
        finally:
            lib.oidnReleaseFilter(filt)


_LIBRARY: _Library | None = None
_LOAD_LOCK = threading.Lock()


def library() -> _Library:
    """The loaded library (once per process), or :class:`DenoiseUnavailable`."""
    global _LIBRARY
    if _LIBRARY is None:
        with _LOAD_LOCK:
            if _LIBRARY is None:
                _LIBRARY = _Library(find_library())
    return _LIBRARY


def check() -> None:
    """Raise :class:`DenoiseUnavailable` (one clear message) unless denoising can run here."""
    library()


def available() -> bool:
    """Whether an OIDN 2 library loads here."""
    try:
        library()
    except DenoiseUnavailable:
        return False
    return True


def version() -> str:
    """The loaded OIDN's version, "2.3.3"."""
    return library().version_string


def _plane(a, shape, name: str, lo=None, hi=None) -> np.ndarray:
    """A contiguous float32 (H, W, 3) copy of ``a`` with non-finite values 0 (and clipped to [lo, hi])."""
    a = np.asarray(a, np.float32)
    if a.ndim != 3 or a.shape[2] < 3 or a.shape[:2] != shape:
        raise ValueError(f"denoise: {name} must be (H, W, 3) like the colour {shape}, got {a.shape}")
    out = np.nan_to_num(a[..., :3], nan=0.0, posinf=0.0, neginf=0.0)
    if lo is not None or hi is not None:
        np.clip(out, lo, hi, out=out)
    return np.ascontiguousarray(out)


def denoise(color, albedo=None, normal=None, hdr: bool = True, *, prefilter: str = "accurate",
            quality: str = "high", threads: int | None = None) -> np.ndarray:
    """The denoised picture: ``color`` (H, W, 3) or (H, W, 4) scene-linear, guided by ``albedo`` (H, W, 3, values
    clipped to [0, 1]) and ``normal`` (H, W, 3, any space, [-1, 1]) when given, as Cycles feeds OIDN. Returns
    float32 of the same shape; a fourth (alpha) channel passes through unchanged; no NaN or Inf in the result
    (non-finite inputs count as 0). ``hdr``: the colour is HDR (True for rendered scene-linear light; False for
    [0, 1] values). ``prefilter`` (:data:`PREFILTERS`) and ``quality`` (:data:`QUALITIES`) as Cycles' Denoise
    panel. ``threads``: the filter's thread count (OIDN's ``numThreads``; None: every core), as a render's
    ``--threads``. Raises :class:`DenoiseUnavailable` without a library."""
    if prefilter not in PREFILTERS:
        raise ValueError(f"denoise: prefilter must be one of {', '.join(PREFILTERS)}, got {prefilter!r}")
    if quality not in QUALITIES:
        raise ValueError(f"denoise: quality must be one of {', '.join(QUALITIES)}, got {quality!r}")
    c = np.asarray(color)
    if c.ndim != 3 or c.shape[2] not in (3, 4):
        raise ValueError(f"denoise: color must be (H, W, 3) or (H, W, 4), got {c.shape}")
    out = np.array(c, np.float32)
    h, w = c.shape[:2]
    if h == 0 or w == 0:
        return out
    rgb = _plane(c, (h, w), "color", lo=0.0 if hdr else None)
    inputs = {"color": rgb}
    if normal is not None and albedo is None:  # OIDN takes a normal only beside an albedo: Cycles' fake one
        albedo = np.full((h, w, 3), 0.5, np.float32)
    if albedo is not None:
        inputs["albedo"] = _plane(albedo, (h, w), "albedo", 0.0, 1.0)
    if normal is not None:
        inputs["normal"] = _plane(normal, (h, w), "normal", -1.0, 1.0)
    lib = library()
    q = QUALITIES[quality]
    result = np.empty_like(rgb)
    with lib.lock:
        if prefilter == "accurate":  # the guides filtered first, in place, each by itself (Cycles' Accurate)
            for name in ("albedo", "normal"):
                if name in inputs:
                    guide = inputs[name]
                    lib.run({name: guide}, guide, hdr=False, clean_aux=False, quality=q, threads=threads)
        lib.run(inputs, result, hdr=hdr, clean_aux=prefilter != "fast", quality=q, threads=threads)
    out[..., :3] = np.nan_to_num(result, nan=0.0, posinf=0.0, neginf=0.0)
    return out


def denoise_image(image, settings, *, prefilter: str = "accurate", quality: str = "high") -> None:
    """Denoise a rendered image in place, guided by its ``denoising_albedo`` / ``denoising_normal`` AOVs: the
    render region (``settings.region``) or the whole frame, never tile by tile. The guides stay among the AOVs
    only where ``settings.aovs`` asks for them. The filter runs on ``settings.threads`` threads (all cores when
    unset), as the render did. ``image.stats["denoise"]`` records the library, its thread count and the time."""
    t0 = time.perf_counter()
    x0, y0, x1, y1 = settings.region or (0, 0, image.rgba.shape[1], image.rgba.shape[0])
    aovs = image.aovs
    albedo, normal = aovs.get("denoising_albedo"), aovs.get("denoising_normal")
    win = (slice(y0, y1), slice(x0, x1))
    image.rgba[win] = denoise(image.rgba[win], None if albedo is None else albedo[win],
                              None if normal is None else normal[win], prefilter=prefilter, quality=quality,
                              threads=settings.threads)
    for name in GUIDE_AOVS:
        if name not in settings.aovs:
            aovs.pop(name, None)
    lib = library()
    image.stats["denoise"] = {"seconds": time.perf_counter() - t0, "oidn": lib.version_string,
                              "library": lib.path, "prefilter": prefilter, "quality": quality,
                              "threads": lib.threads_of(settings.threads)}

"""Our binding to Embree 4's C API: the shared library the ``embreex`` wheel vendors, loaded with ctypes, and called
from numba kernels without the GIL.

Why not embreex's own Python API: it copies geometry element by element into Embree buffers (1 M triangles:
0.67 s before the BVH build even starts), and exposes neither instancing, geometry updates, build quality nor the
ray's ``tnear``. Here the vertex and index arrays are numpy arrays Embree reads in place
(``rtcSetSharedGeometryBuffer``), objects are instances of their own meshes (``RTC_GEOMETRY_TYPE_INSTANCE``), an
object's move is a matrix update, and the ray queries are plain C calls made from compiled loops.

What is used of the API, with the layouts of ``include/embree4/rtcore_*.h`` (Embree 4.x, built with the defaults
``RTC_MAX_INSTANCE_LEVEL_COUNT = 1`` and ``RTC_GEOMETRY_INSTANCE_ARRAY`` on, as the embreex wheels are):

- ``RTCRay`` (48 bytes, 16-aligned): org_x, org_y, org_z, tnear, dir_x, dir_y, dir_z, time, tfar (float32),
  mask, id, flags (uint32);
- ``RTCHit`` (48 bytes, 16-aligned): Ng_x, Ng_y, Ng_z, u, v (float32), primID, geomID, instID[1],
  instPrimID[1] (uint32), padding; ``RTCRayHit`` = RTCRay + RTCHit = 96 bytes;
- ``RTCRayHitN`` / ``RTCRayN`` for N = 4, 8, 16 (aligned to 4·N bytes): the same fields as arrays of N lanes
  (structure of arrays), 21·N / 12·N words; ``RTCRayHit`` / ``RTCRay`` are that layout at N = 1 (padded to 24 / 12
  words), so one loop serves every width (:data:`QUERY_WIDTHS`);
- ``rtcIntersectN(valid, scene, rayhitN, args)`` / ``rtcOccludedN(valid, scene, rayN, args)`` (and ``rtcIntersect1``
  / ``rtcOccluded1`` without ``valid``) with ``args`` an ``RTCIntersectArguments`` (= ``RTCOccludedArguments``):
  flags (RTC_RAY_QUERY_FLAG_INCOHERENT or _COHERENT), feature mask (all), and NULL context, filter and callback, so
  Embree uses its own ``RTCRayQueryContext`` and the context's layout is not ours to keep in step with the library.
  Coherent packets (eye rays, mirror and glass rays, shadow rays grouped by light) take Embree's frustum traversal.

The kernels (:func:`intersect_rays`, :func:`occluded_rays`) call ``rtcIntersect*`` / ``rtcOccluded*`` as numba
external functions, through LLVM symbols of our own names (``whitted_embree_rtcIntersect16``, ...) that the loader
binds to this library's function addresses — never through the plain ``rtc*`` names, which inside Blender resolve
to Blender's own Embree — so they compile once and are cached on disk like every other kernel; the scene handle and struct pointers are passed as
pointer-sized integers (the same registers as pointers on every 64-bit ABI Embree supports).

Errors: Embree's error callback records each error; every call made through this module checks the record and
raises :class:`EmbreeError` (code name and Embree's message). A library that cannot be found or loaded, or is not
Embree 4, raises :class:`EmbreeUnavailable` with the places it looked.
"""

from __future__ import annotations

import ctypes
import glob
import os
import sys
import threading

import numpy as np
from numba import types

from ..jit import kernel

#: Embree major version the layouts above are written for; minor versions up from this one are accepted.
REQUIRED_VERSION = (4, 0)
#: Environment variable naming the Embree library to use instead of the bundled one.
LIBRARY_ENV = "WHITTED_EMBREE_LIBRARY"

INVALID_ID = 0xFFFFFFFF  # RTC_INVALID_GEOMETRY_ID
MASK_ALL = 0xFFFFFFFF  # a geometry / ray mask with every bit set
#: The ray mask of a batch whose rays see every geometry (the kernels' ``masks`` argument).
ALL_RAYS = np.full(1, MASK_ALL, np.uint32)
#: Largest finite ray length handed to Embree (inf would be fine for Embree; this keeps recorded rays finite).
T_FAR_MAX = np.float32(3.0e38)
_NONE_F32 = np.zeros(0, np.float32)


def ray_times(time) -> np.ndarray:
    """The rays' times as the query kernels take them (float32; empty = no motion, time 0)."""
    return _NONE_F32 if time is None else np.ascontiguousarray(time, np.float32)


def ray_masks(mask) -> np.ndarray:
    """The rays' masks as the query kernels take them (one for all: :data:`ALL_RAYS`)."""
    if mask is None:
        return ALL_RAYS
    return np.ascontiguousarray(np.asarray(mask, np.uint32).reshape(-1))

# enum values (rtcore_common.h, rtcore_device.h, rtcore_buffer.h, rtcore_geometry.h, rtcore_scene.h)
DEVICE_PROPERTY_VERSION = 0
DEVICE_PROPERTY_VERSION_MAJOR = 1
DEVICE_PROPERTY_VERSION_MINOR = 2
DEVICE_PROPERTY_VERSION_PATCH = 3
DEVICE_PROPERTY_NATIVE_RAY = {4: 32, 8: 33, 16: 34}  # RTC_DEVICE_PROPERTY_NATIVE_RAY{4,8,16}_SUPPORTED
FORMAT_UINT = 0x5001
FORMAT_UINT3 = 0x5003
FORMAT_FLOAT3 = 0x9003
FORMAT_FLOAT3X4_COLUMN_MAJOR = 0x9234
FORMAT_QUATERNION_DECOMPOSITION = 0xB001  # RTCQuaternionDecomposition records (16 floats, 64 bytes)
BUFFER_TYPE_INDEX = 0
BUFFER_TYPE_VERTEX = 1
BUFFER_TYPE_TRANSFORM = 23
GEOMETRY_TYPE_TRIANGLE = 0
GEOMETRY_TYPE_INSTANCE = 121
GEOMETRY_TYPE_INSTANCE_ARRAY = 122  # Embree >= 4.3
BUILD_QUALITY = {"low": 0, "medium": 1, "high": 2, "refit": 3}
SCENE_FLAG_NONE, SCENE_FLAG_DYNAMIC, SCENE_FLAG_COMPACT, SCENE_FLAG_ROBUST = 0, 1, 2, 4
ERROR_NAMES = {0: "RTC_ERROR_NONE", 1: "RTC_ERROR_UNKNOWN", 2: "RTC_ERROR_INVALID_ARGUMENT",
               3: "RTC_ERROR_INVALID_OPERATION", 4: "RTC_ERROR_OUT_OF_MEMORY", 5: "RTC_ERROR_UNSUPPORTED_CPU",
               6: "RTC_ERROR_CANCELLED", 7: "RTC_ERROR_LEVEL_ZERO_RAYTRACING_SUPPORT_MISSING"}


class EmbreeUnavailable(RuntimeError):
    """The Embree 4 library could not be found or loaded (the message lists where it was looked for)."""


class BuildCancelled(RuntimeError):
    """A BVH build was stopped because its ``cancelled`` callback returned True."""


class EmbreeError(RuntimeError):
    """Embree reported an error through its error callback (``code`` is the RTCError value)."""

    def __init__(self, code: int, message: str):
        self.code = code
        super().__init__(f"Embree {ERROR_NAMES.get(code, code)}: {message}")


# ---------------------------------------------------------------------------------------------- finding the library
def _patterns() -> list[str]:
    """File-name patterns of Embree 4 on this platform (the wheels rename vendored libraries with a hash)."""
    if sys.platform == "win32":
        return ["embree4*.dll"]
    if sys.platform == "darwin":
        return ["libembree4*.dylib"]
    return ["libembree4*.so*"]


def _search_dirs() -> list[str]:
    """Where the embreex wheel keeps its vendored Embree, for every site-packages on ``sys.path``.

    auditwheel (Linux) and delvewheel (Windows) put vendored libraries in ``embreex.libs/`` beside the package,
    delocate (macOS) in ``embreex/.dylibs/``; older Windows wheels put the DLLs in the package folder itself.
    Found through ``sys.path`` rather than by importing embreex (its extension modules are not needed)."""
    dirs = []
    for base in sys.path:
        base = base or os.getcwd()
        for sub in ("embreex.libs", os.path.join("embreex", ".dylibs"), "embreex", "embreex4.libs",
                    os.path.join("embreex4", ".dylibs")):
            d = os.path.join(base, sub)
            if os.path.isdir(d) and d not in dirs:
                dirs.append(d)
    return dirs


def find_library() -> str:
    """Path of the Embree 4 shared library: ``$WHITTED_EMBREE_LIBRARY`` if set, else the one vendored by the
    embreex wheel. Raises :class:`EmbreeUnavailable` naming every place it looked."""
    env = os.environ.get(LIBRARY_ENV)
    if env:
        if os.path.isfile(env):
            return env
        raise EmbreeUnavailable(f"{LIBRARY_ENV}={env!r} is not a file")
    dirs = _search_dirs()
    for d in dirs:
        for pattern in _patterns():
            found = sorted(glob.glob(os.path.join(d, pattern)))
            if found:
                return found[0]
    looked = ", ".join(dirs) if dirs else "no embreex.libs / embreex/.dylibs folder on sys.path"
    raise EmbreeUnavailable(
        f"the Embree 4 library ({' or '.join(_patterns())}) was not found; install the embreex wheel "
        f"(pip install embreex) or set {LIBRARY_ENV} to the library's path. Looked in: {looked}")


# ---------------------------------------------------------------------------------------------- the library
_ERROR_FUNC = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_int, ctypes.c_char_p)
_PROGRESS_FUNC = ctypes.CFUNCTYPE(ctypes.c_bool, ctypes.c_void_p, ctypes.c_double)
ERROR_CANCELLED = 6
_P, _UI, _I, _S = ctypes.c_void_p, ctypes.c_uint, ctypes.c_int, ctypes.c_size_t
_SIGNATURES = {  # name: (restype, argtypes)
    "rtcNewDevice": (_P, [ctypes.c_char_p]),
    "rtcReleaseDevice": (None, [_P]),
    "rtcGetDeviceProperty": (ctypes.c_ssize_t, [_P, _I]),
    "rtcGetDeviceError": (_I, [_P]),
    "rtcSetDeviceErrorFunction": (None, [_P, _ERROR_FUNC, _P]),
    "rtcNewScene": (_P, [_P]),
    "rtcReleaseScene": (None, [_P]),
    "rtcSetSceneFlags": (None, [_P, _I]),
    "rtcSetSceneBuildQuality": (None, [_P, _I]),
    "rtcCommitScene": (None, [_P]),
    "rtcSetSceneProgressMonitorFunction": (None, [_P, _PROGRESS_FUNC, _P]),
    "rtcAttachGeometryByID": (None, [_P, _P, _UI]),
    "rtcAttachGeometry": (_UI, [_P, _P]),
    "rtcDetachGeometry": (None, [_P, _UI]),
    "rtcNewGeometry": (_P, [_P, _I]),
    "rtcReleaseGeometry": (None, [_P]),
    "rtcCommitGeometry": (None, [_P]),
    "rtcSetGeometryBuildQuality": (None, [_P, _I]),
    "rtcSetSharedGeometryBuffer": (None, [_P, _I, _UI, _I, _P, _S, _S, _S]),
    "rtcUpdateGeometryBuffer": (None, [_P, _I, _UI]),
    "rtcSetGeometryInstancedScene": (None, [_P, _P]),
    "rtcSetGeometryInstancedScenes": (None, [_P, _P, _S]),
    "rtcSetGeometryTransform": (None, [_P, _UI, _I, _P]),
    "rtcSetGeometryTimeStepCount": (None, [_P, _UI]),
    "rtcSetGeometryTransformQuaternion": (None, [_P, _UI, _P]),
    "rtcGetGeometryTransform": (None, [_P, ctypes.c_float, _I, _P]),
    "rtcSetGeometryMask": (None, [_P, _UI]),
    "rtcSetGeometryEnableFilterFunctionFromArguments": (None, [_P, ctypes.c_bool]),
    "rtcGetSceneBounds": (None, [_P, _P]),
}


#: Embree functions the kernels call, and the prefix of the LLVM symbols they are bound to.
_KERNEL_FUNCTIONS = tuple(f"rtc{q}{w}" for w in (1, 4, 8, 16) for q in ("Intersect", "Occluded"))
_KERNEL_PREFIX = "whitted_embree_"


class _Library:
    """The loaded library, its one device, and the error record the callback fills."""

    def __init__(self, path: str):
        self.path = path
        try:
            if sys.platform == "win32":  # TBB sits beside embree4.dll: let the loader find it there
                os.add_dll_directory(os.path.dirname(os.path.abspath(path)))
            self.lib = ctypes.CDLL(path)
        except OSError as exc:
            raise EmbreeUnavailable(f"the Embree library {path} could not be loaded: {exc}") from exc
        for name, (res, args) in _SIGNATURES.items():
            try:
                fn = getattr(self.lib, name)
            except AttributeError as exc:
                raise EmbreeUnavailable(f"{path} is not an Embree 4 library (no {name})") from exc
            fn.restype, fn.argtypes = res, args
        # Kernels call rtcIntersect*/rtcOccluded* through LLVM symbols of our own names bound to this library's
        # functions: not the plain rtc* names, which the process may already resolve to another Embree (Blender's
        # bpy module links its own libembree4; calling its rtcIntersect8 on our scene would crash).
        import llvmlite.binding as llvm

        for name in _KERNEL_FUNCTIONS:
            llvm.add_symbol(_KERNEL_PREFIX + name, ctypes.cast(getattr(self.lib, name), ctypes.c_void_p).value)
        self._errors: list = []
        self._errors_lock = threading.Lock()
        self.device = self.lib.rtcNewDevice(None)
        if not self.device:
            raise EmbreeUnavailable(f"{path}: rtcNewDevice failed (error {self.lib.rtcGetDeviceError(None)}); "
                                    "is this CPU supported by Embree (SSE2 at least)?")
        self._callback = _ERROR_FUNC(self._on_error)  # kept: ctypes callbacks must outlive their registration
        self.lib.rtcSetDeviceErrorFunction(self.device, self._callback, None)
        prop = self.lib.rtcGetDeviceProperty
        self.version = (prop(self.device, DEVICE_PROPERTY_VERSION_MAJOR), prop(self.device,
                        DEVICE_PROPERTY_VERSION_MINOR), prop(self.device, DEVICE_PROPERTY_VERSION_PATCH))
        if self.version[0] != REQUIRED_VERSION[0] or self.version[:2] < REQUIRED_VERSION:
            found = ".".join(map(str, self.version))
            raise EmbreeUnavailable(f"{path} is Embree {found}; the tracer's binding needs Embree "
                                    f"{REQUIRED_VERSION[0]}.x (>= {REQUIRED_VERSION[0]}.{REQUIRED_VERSION[1]})")
        #: the widest packet this CPU traces natively (16 with AVX-512, 8 with AVX, 4 with SSE/NEON): a wider one
        #: is traced one ray at a time inside Embree
        self.packet = max([w for w, p in DEVICE_PROPERTY_NATIVE_RAY.items() if prop(self.device, p)], default=8)

    def _on_error(self, _user, code, message):
        # Called by Embree on the thread where the error happened; Python exceptions cannot cross the C frames
        # in between, so the error is recorded here and raised by check() when the call returns.
        with self._errors_lock:
            self._errors.append((int(code), (message or b"").decode("utf-8", "replace")))

    def check(self) -> None:
        """Raise the first error Embree reported since the last check (and forget the others)."""
        if self._errors:
            with self._errors_lock:
                errors, self._errors = self._errors, []
            if errors:
                raise EmbreeError(*errors[0])

    def call(self, name: str, *args):
        """``rtc<Name>(*args)``, then raise what Embree reported during it."""
        result = getattr(self.lib, name)(*args)
        self.check()
        return result


_LIBRARY: _Library | None = None
_LIBRARY_LOCK = threading.Lock()


def library() -> _Library:
    """The Embree library and device, loaded on first use (raises :class:`EmbreeUnavailable`)."""
    global _LIBRARY
    if _LIBRARY is None:
        with _LIBRARY_LOCK:
            if _LIBRARY is None:
                _LIBRARY = _Library(find_library())
    return _LIBRARY


def version() -> str:
    """The loaded Embree's version, e.g. "4.4.0"."""
    return ".".join(map(str, library().version))


# ---------------------------------------------------------------------------------------------- buffers
def padded(a: np.ndarray, dtype) -> np.ndarray:
    """A C-contiguous, 16-byte aligned copy of 2-D ``a`` as ``dtype`` with 16 spare bytes after its last row:
    Embree reads the last vertex / index triple with a 16-byte load. The rows returned are a view of the first
    ``len(a)`` rows of that buffer."""
    a = np.asarray(a)
    n, k = a.shape
    itemsize = np.dtype(dtype).itemsize
    raw = np.empty(n * k * itemsize + 16 + 16, np.uint8)
    off = (-raw.ctypes.data) % 16
    out = raw[off:off + n * k * itemsize + 16].view(dtype)[:n * k].reshape(n, k)
    out[...] = a
    return out


# ---------------------------------------------------------------------------------------------- scenes
class EmbreeScene:
    """An ``RTCScene``. ``flags``: RTC_SCENE_FLAG_*; ``quality``: "low" | "medium" | "high"."""

    def __init__(self, quality: str = "medium", flags: int = SCENE_FLAG_NONE):
        self._lib = library()
        self.handle = self._lib.call("rtcNewScene", self._lib.device)
        if not self.handle:
            raise EmbreeError(4, "rtcNewScene returned NULL")
        self._lib.call("rtcSetSceneFlags", self.handle, flags)
        self._lib.call("rtcSetSceneBuildQuality", self.handle, BUILD_QUALITY[quality])
        self.quality = quality
        self._geometries: dict[int, "Geometry"] = {}

    def attach(self, geometry: "Geometry", geom_id: int) -> None:
        self._lib.call("rtcAttachGeometryByID", self.handle, geometry.handle, int(geom_id))
        self._geometries[int(geom_id)] = geometry

    def detach(self, geom_id: int) -> None:
        if int(geom_id) in self._geometries:
            self._lib.call("rtcDetachGeometry", self.handle, int(geom_id))
            del self._geometries[int(geom_id)]

    def commit(self, cancelled=None) -> None:
        """Build (or update) the BVH: only geometries changed since the last commit are rebuilt.

        ``cancelled``: a callable Embree polls while it builds (its progress monitor, on its build threads); True
        stops the build and raises :class:`BuildCancelled` (the scene is then left uncommitted)."""
        if cancelled is None:
            self._lib.call("rtcCommitScene", self.handle)
            return

        def progress(_ptr, _fraction):
            try:
                return not cancelled()
            except Exception:  # an exception cannot cross Embree's frames: treat it as "go on"
                return True

        monitor = _PROGRESS_FUNC(progress)
        self._lib.lib.rtcSetSceneProgressMonitorFunction(self.handle, monitor, None)
        try:
            self._lib.call("rtcCommitScene", self.handle)
        except EmbreeError as exc:
            if exc.code == ERROR_CANCELLED:
                raise BuildCancelled("Embree build cancelled") from None
            raise
        finally:
            self._lib.lib.rtcSetSceneProgressMonitorFunction(self.handle, _PROGRESS_FUNC(0), None)

    def bounds(self) -> np.ndarray:
        b = np.zeros(8, np.float32)
        self._lib.call("rtcGetSceneBounds", self.handle, b.ctypes.data)
        return np.stack([b[:3], b[4:7]])

    def release(self) -> None:
        if self.handle:
            self._lib.call("rtcReleaseScene", self.handle)
            self.handle = None
            self._geometries.clear()

    def __del__(self):
        try:
            self.release()
        except Exception:  # interpreter shutdown: the library may be gone
            pass


class Geometry:
    """An ``RTCGeometry`` (released with this object; a scene it is attached to keeps its own reference)."""

    def __init__(self, kind: int):
        self._lib = library()
        self.handle = self._lib.call("rtcNewGeometry", self._lib.device, kind)
        # Embree 4's default geometry mask is 1; all ones lets a ray of any mask (tracer.lights.linking) see it
        self._lib.call("rtcSetGeometryMask", self.handle, MASK_ALL)

    def set_mask(self, mask: int) -> None:
        """The rays this geometry is seen by: those whose mask ANDs non-zero with ``mask`` (then commit)."""
        self._lib.call("rtcSetGeometryMask", self.handle, int(mask) & MASK_ALL)
        self.commit()

    def enable_argument_filter(self) -> None:
        """Let the filter function a query passes in its arguments see this geometry's hits (tracer/accel/alpha.py)."""
        self._lib.call("rtcSetGeometryEnableFilterFunctionFromArguments", self.handle, True)

    def commit(self) -> None:
        self._lib.call("rtcCommitGeometry", self.handle)

    def release(self) -> None:
        if self.handle:
            self._lib.call("rtcReleaseGeometry", self.handle)
            self.handle = None

    def __del__(self):
        try:
            self.release()
        except Exception:
            pass


class TriangleGeometry(Geometry):
    """A triangle mesh over shared numpy buffers: float32 (V, 3) vertices and int32 (T, 3) indices, each a
    :func:`padded` buffer or consecutive rows of one (Embree reads 16 bytes at the last element, so the buffer must
    go on for 4 bytes after it). Embree reads them in place; this object keeps them alive."""

    def __init__(self, vertices: np.ndarray, triangles: np.ndarray, quality: str = "medium"):
        super().__init__(GEOMETRY_TYPE_TRIANGLE)
        self._lib.call("rtcSetGeometryBuildQuality", self.handle, BUILD_QUALITY[quality])
        self.set_buffers(vertices, triangles)
        self.commit()

    def set_buffers(self, vertices: np.ndarray, triangles: np.ndarray) -> None:
        for a, what in ((vertices, "vertices"), (triangles, "triangles")):
            if not a.flags.c_contiguous or a.ctypes.data % 4 or a.ndim != 2 or a.shape[1] != 3 or a.itemsize != 4:
                raise ValueError(f"{what} must be a contiguous (N, 3) 4-byte buffer from tracer.accel.embree.padded "
                                 "(or rows of one)")
        self.vertices, self.triangles = vertices, triangles
        self._lib.call("rtcSetSharedGeometryBuffer", self.handle, BUFFER_TYPE_VERTEX, 0, FORMAT_FLOAT3,
                       vertices.ctypes.data, 0, 12, len(vertices))
        self._lib.call("rtcSetSharedGeometryBuffer", self.handle, BUFFER_TYPE_INDEX, 0, FORMAT_UINT3,
                       triangles.ctypes.data, 0, 12, len(triangles))

    def set_vertex_steps(self, steps: list) -> None:
        """Motion blur: the mesh's vertices at S ≥ 2 evenly spaced times of the shutter (each a :func:`padded`
        (V, 3) float32 buffer, the same rows as ``vertices``), one vertex buffer slot per time step; Embree
        interpolates linearly between them by the ray's time. Commits the geometry."""
        self.vertex_steps = list(steps)  # kept alive with the geometry
        self._lib.call("rtcSetGeometryTimeStepCount", self.handle, len(self.vertex_steps))
        for k, v in enumerate(self.vertex_steps):
            self._lib.call("rtcSetSharedGeometryBuffer", self.handle, BUFFER_TYPE_VERTEX, k, FORMAT_FLOAT3,
                           v.ctypes.data, 0, 12, len(v))
        self._lib.call("rtcSetSharedGeometryBuffer", self.handle, BUFFER_TYPE_INDEX, 0, FORMAT_UINT3,
                       self.triangles.ctypes.data, 0, 12, len(self.triangles))
        self.commit()

    def vertices_changed(self) -> None:
        """The vertex buffer's contents were changed in place: refit/rebuild this mesh at the next commit."""
        self._lib.call("rtcUpdateGeometryBuffer", self.handle, BUFFER_TYPE_VERTEX, 0)
        self.commit()


class InstanceGeometry(Geometry):
    """An instance of an :class:`EmbreeScene` with a 4×4 object-to-world matrix."""

    def __init__(self, scene: EmbreeScene, matrix=None):
        super().__init__(GEOMETRY_TYPE_INSTANCE)
        self.scene = scene  # kept alive with the instance
        self._lib.call("rtcSetGeometryInstancedScene", self.handle, scene.handle)
        self.set_transform(np.eye(4) if matrix is None else matrix)

    def set_transform(self, matrix) -> None:
        m = np.asarray(matrix, np.float64)
        xfm = np.ascontiguousarray(m[:3, :4].T, np.float32)  # 3x4 column-major: four columns of 3
        self._lib.call("rtcSetGeometryTransform", self.handle, 0, FORMAT_FLOAT3X4_COLUMN_MAJOR, xfm.ctypes.data)
        self.commit()

    def set_motion(self, decomposed: np.ndarray) -> None:
        """Motion blur: S ≥ 2 transforms at evenly spaced times of the shutter, as (S, 16) quaternion
        decompositions (:func:`tracer.geometry.motion.decompose`); Embree interpolates them by the ray's time (T and S
        linearly, the rotation by slerp). Commits the geometry."""
        dec = padded(np.asarray(decomposed, np.float64).reshape(-1, 16), np.float32)
        self._lib.call("rtcSetGeometryTimeStepCount", self.handle, len(dec))
        for k in range(len(dec)):
            self._lib.call("rtcSetGeometryTransformQuaternion", self.handle, k, dec[k].ctypes.data)
        self.commit()

    def transform_at(self, time: float) -> np.ndarray:
        """The 4×4 matrix Embree places this instance with at ``time`` (``rtcGetGeometryTransform``)."""
        xfm = np.zeros(12, np.float32)
        self._lib.call("rtcGetGeometryTransform", self.handle, float(time), FORMAT_FLOAT3X4_COLUMN_MAJOR,
                       xfm.ctypes.data)
        m = np.eye(4)
        m[:3, :4] = xfm.reshape(4, 3).T
        return m


def column_major_3x4(matrices) -> np.ndarray:
    """(K, 4, 4) object-to-world matrices (column vectors) as Embree's ``RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR``
    records: (K, 12) float32, the four columns of the upper 3×4 block, in a :func:`padded` buffer."""
    m = np.asarray(matrices, np.float64).reshape(-1, 4, 4)
    return padded(m[:, :3, :4].transpose(0, 2, 1).reshape(-1, 12), np.float32)


class InstanceArrayGeometry(Geometry):
    """``RTC_GEOMETRY_TYPE_INSTANCE_ARRAY`` (Embree >= 4.3): K instances of a few :class:`EmbreeScene` s in one
    geometry, over shared numpy buffers: ``transforms`` (K, 12) float32 from :func:`column_major_3x4` and
    ``scene_index`` (K,) uint32 (which of ``scenes`` instance k places). A hit on instance k reports this
    geometry's id as ``instID`` and k as ``instPrimID``. Python does no work per instance: a scene of 50 000
    instances is two shared buffers and one geometry."""

    def __init__(self, scenes: list, scene_index: np.ndarray, transforms: np.ndarray, quality: str = "medium"):
        if library().version[:2] < (4, 3):
            raise EmbreeUnavailable(f"instance arrays need Embree >= 4.3, this is {version()}")
        super().__init__(GEOMETRY_TYPE_INSTANCE_ARRAY)
        self._lib.call("rtcSetGeometryBuildQuality", self.handle, BUILD_QUALITY[quality])
        self.set_scenes(scenes)
        self.set_buffers(scene_index, transforms)
        self.commit()

    def set_scenes(self, scenes: list) -> None:
        self.scenes = list(scenes)  # kept alive with the array
        handles = (ctypes.c_void_p * max(1, len(self.scenes)))(*[s.handle for s in self.scenes])
        self._lib.call("rtcSetGeometryInstancedScenes", self.handle, handles, len(self.scenes))

    def set_buffers(self, scene_index: np.ndarray, transforms: np.ndarray) -> None:
        k = len(transforms)
        if transforms.shape != (k, 12) or transforms.dtype != np.float32 or not transforms.flags.c_contiguous:
            raise ValueError("transforms must be (K, 12) float32 records from tracer.accel.embree.column_major_3x4")
        idx = padded(np.asarray(scene_index, np.uint32).reshape(-1, 1), np.uint32)
        if len(idx) != k:
            raise ValueError(f"scene_index has {len(idx)} entries for {k} transforms")
        self.transforms, self.scene_index = transforms, idx
        self._lib.call("rtcSetSharedGeometryBuffer", self.handle, BUFFER_TYPE_INDEX, 0, FORMAT_UINT,
                       idx.ctypes.data, 0, 4, k)
        self._lib.call("rtcSetSharedGeometryBuffer", self.handle, BUFFER_TYPE_TRANSFORM, 0,
                       FORMAT_FLOAT3X4_COLUMN_MAJOR, transforms.ctypes.data, 0, 48, k)

    def set_motion(self, decomposed: np.ndarray) -> None:
        """Motion blur: every instance's S ≥ 2 transforms at evenly spaced times of the shutter, (K, S, 16)
        quaternion decompositions (:func:`tracer.geometry.motion.decompose`), one shared transform buffer slot per time
        step (``RTC_FORMAT_QUATERNION_DECOMPOSITION``). Commits the geometry."""
        dec = np.asarray(decomposed, np.float64)
        k, s = dec.shape[:2]
        self.motion_steps = [padded(dec[:, j], np.float32) for j in range(s)]  # kept alive with the array
        self._lib.call("rtcSetGeometryTimeStepCount", self.handle, s)
        for j, buf in enumerate(self.motion_steps):
            self._lib.call("rtcSetSharedGeometryBuffer", self.handle, BUFFER_TYPE_TRANSFORM, j,
                           FORMAT_QUATERNION_DECOMPOSITION, buf.ctypes.data, 0, 64, k)
        self._lib.call("rtcSetSharedGeometryBuffer", self.handle, BUFFER_TYPE_INDEX, 0, FORMAT_UINT,
                       self.scene_index.ctypes.data, 0, 4, k)
        self.commit()

    def transforms_changed(self) -> None:
        """Rows of the shared transform buffer were changed in place: the next top-level commit sees them."""
        self._lib.call("rtcUpdateGeometryBuffer", self.handle, BUFFER_TYPE_TRANSFORM, 0)
        self.commit()


# ---------------------------------------------------------------------------------------------- ray queries
#: Packet widths the kernels call: ``rtcIntersect1`` / ``4`` / ``8`` / ``16`` (and ``rtcOccluded*``). The tracer uses
#: the CPU's widest native packet (``library().packet``); measured on the bench scenes' recorded rays (AVX-512, one
#: thread, docs/benchmarks.md): 16 lanes trace 25-35 % faster than one ray per call, 1-4 % faster than 8 lanes.
QUERY_WIDTHS = (1, 4, 8, 16)
MAX_PACKET = 16
#: RTC_RAY_QUERY_FLAG_COHERENT in a query: Embree traces each packet's rays of one octant together through the BVH
#: (a frustum), for rays that start close and point alike (eye rays, mirror and glass rays of neighbouring pixels,
#: shadow rays grouped by light): eye rays 2.5-3× faster than incoherent packets.
COHERENT = 1 << 16
_WIDTH_BITS = 0xFFFF
# Word of each field in RTCRayHitN = RTCRayN + RTCHitN, in rows of N lanes (× N): the ray's 12 fields, then the
# hit's Ng_x, Ng_y, Ng_z, u, v, primID, geomID, instID[1], instPrimID[1].
_ORG_X, _ORG_Y, _ORG_Z, _TNEAR, _DIR_X, _DIR_Y, _DIR_Z, _TIME, _TFAR, _MASK, _ID, _FLAGS = range(12)
_U, _V, _PRIM, _GEOM, _INST, _INST_PRIM = 15, 16, 17, 18, 19, 20
RAY_FIELDS, RAYHIT_FIELDS = 12, 21  # RTCRayN and RTCRayHitN are this many × N words (RTCRayHit: padded to 24)
_ARGS_WORDS = 12  # RTCIntersectArguments: flags, feature_mask, 3 pointers (and minWidthDistanceFactor), padded

_sig3 = types.void(types.intp, types.intp, types.intp)
_sig4 = types.void(types.intp, types.intp, types.intp, types.intp)
# void rtcIntersectN(const int* valid, RTCScene, RTCRayHitN*, RTCIntersectArguments*); rtcOccludedN alike;
# rtcIntersect1(RTCScene, RTCRayHit*, RTCIntersectArguments*) has no valid mask.
_rtcIntersect1 = types.ExternalFunction(_KERNEL_PREFIX + "rtcIntersect1", _sig3)
_rtcOccluded1 = types.ExternalFunction(_KERNEL_PREFIX + "rtcOccluded1", _sig3)
_rtcIntersect4 = types.ExternalFunction(_KERNEL_PREFIX + "rtcIntersect4", _sig4)
_rtcOccluded4 = types.ExternalFunction(_KERNEL_PREFIX + "rtcOccluded4", _sig4)
_rtcIntersect8 = types.ExternalFunction(_KERNEL_PREFIX + "rtcIntersect8", _sig4)
_rtcOccluded8 = types.ExternalFunction(_KERNEL_PREFIX + "rtcOccluded8", _sig4)
_rtcIntersect16 = types.ExternalFunction(_KERNEL_PREFIX + "rtcIntersect16", _sig4)
_rtcOccluded16 = types.ExternalFunction(_KERNEL_PREFIX + "rtcOccluded16", _sig4)


def query(coherent: bool = False, width: int | None = None) -> int:
    """The kernels' ``query`` argument: the packet width (default: the CPU's widest native one) and whether the
    rays are coherent (:data:`COHERENT`)."""
    width = library().packet if width is None else int(width)
    if width not in QUERY_WIDTHS:
        raise ValueError(f"packet width must be one of {QUERY_WIDTHS}, got {width}")
    return width | (COHERENT if coherent else 0)


@kernel(inline=True, refcounts=True)
def _aligned(n, dtype):
    """A work array of n 4-byte words starting 64-byte aligned (RTCRayHit16 and its valid mask need it)."""
    raw = np.empty(n + 16, dtype)
    off = ((64 - raw.ctypes.data % 64) % 64) // 4
    return raw[off:off + n]


@kernel(inline=True, refcounts=True)
def _query_args(q):
    """An RTCIntersectArguments (= RTCOccludedArguments) for query ``q``: its flags, every feature, NULL pointers."""
    a = _aligned(_ARGS_WORDS, np.uint32)
    a[:] = 0
    a[0] = q & ~np.int64(_WIDTH_BITS)
    a[1] = MASK_ALL
    return a


@kernel(inline=True)
def _load_packet(f, w, valid, W, o, d, order, start, count, tnear, t_max, masks, time):
    """Lanes 0..count-1 of a W-lane packet get rays start..start+count-1 (through ``order`` when it is not empty;
    t_max empty: unbounded; ``masks``: one ray mask per ray, or one for all; ``time`` empty: time 0, no motion
    blur); the rest are switched off."""
    bounded = t_max.shape[0] > 0
    per_ray = masks.shape[0] > 1
    timed = time.shape[0] > 0
    ordered = order.shape[0] > 0
    for k in range(W):
        if k < count:
            i = order[start + k] if ordered else start + k
            valid[k] = -1
            f[_ORG_X * W + k], f[_ORG_Y * W + k], f[_ORG_Z * W + k] = o[i, 0], o[i, 1], o[i, 2]
            f[_DIR_X * W + k], f[_DIR_Y * W + k], f[_DIR_Z * W + k] = d[i, 0], d[i, 1], d[i, 2]
            f[_TFAR * W + k] = t_max[i] if bounded else np.inf
            f[_TIME * W + k] = time[i] if timed else 0.0
            w[_ID * W + k] = i
            w[_MASK * W + k] = masks[i] if per_ray else masks[0]
        else:
            valid[k] = 0
            f[_ORG_X * W + k], f[_ORG_Y * W + k], f[_ORG_Z * W + k] = 0.0, 0.0, 0.0
            f[_DIR_X * W + k], f[_DIR_Y * W + k], f[_DIR_Z * W + k] = 0.0, 0.0, 1.0
            f[_TFAR * W + k] = 0.0
            f[_TIME * W + k] = 0.0
            w[_ID * W + k] = 0
            w[_MASK * W + k] = 0
        f[_TNEAR * W + k] = tnear
        w[_FLAGS * W + k] = 0


@kernel(inline=True)
def _intersect(W, valid, scene, rayhit, args):
    if W == 16:
        _rtcIntersect16(valid, scene, rayhit, args)
    elif W == 8:
        _rtcIntersect8(valid, scene, rayhit, args)
    elif W == 4:
        _rtcIntersect4(valid, scene, rayhit, args)
    else:
        _rtcIntersect1(scene, rayhit, args)


@kernel(inline=True)
def _occluded(W, valid, scene, ray, args):
    if W == 16:
        _rtcOccluded16(valid, scene, ray, args)
    elif W == 8:
        _rtcOccluded8(valid, scene, ray, args)
    elif W == 4:
        _rtcOccluded4(valid, scene, ray, args)
    else:
        _rtcOccluded1(scene, ray, args)


#: Geometry ids in a top-level scene: the instance array (if any) is geometry 0, object i is geometry i + 1.
ARRAY_GEOM_ID = 0
OBJECT_GEOM_BASE = 1
#: The ``order`` of a batch traced in its own order.
IN_ORDER = np.zeros(0, np.int64)


@kernel
def intersect_rays(scene, o, d, tnear, t_max, slot_start, slot_rows, inst_proto, t_out, prim_out, inst_out,
                   u_out, v_out, masks, time, order, q):
    """Closest hits of rays (o, d) at times ``time`` (empty: 0; each ray's motion-blur time in [0, 1]) on
    [tnear, t_max[i]] (t_max empty: unbounded) against the top-level scene
    ``scene`` (an RTCScene handle), in packets of ``q``'s width (:func:`query`), ``order`` giving which rays share a
    packet (empty: consecutive ones). Writes t (inf on a miss), the hit's row, the
    instance index (``inst_out``: k for a hit on instance k of the instance array, else -1) and the barycentrics
    u, v. ``masks``: the rays' Embree masks, one per ray or one for all (:data:`ALL_RAYS`: every geometry).

    Rows: object i is top-level geometry i + :data:`OBJECT_GEOM_BASE` (a triangle geometry, or an instance of its
    own scene); the instance array is geometry :data:`ARRAY_GEOM_ID`, and its instance k places the mesh of object
    ``inst_proto[k]`` (a prototype). The row of primitive ``primID`` of object i is
    ``slot_rows[slot_start[i] + primID]`` (``slot_start[i] + primID`` when ``slot_rows`` is empty); -1 on a miss."""
    W = q & _WIDTH_BITS
    args = _query_args(q)
    f = _aligned(24 * MAX_PACKET, np.float32)
    w = f.view(np.uint32)
    valid = _aligned(MAX_PACKET, np.int32)
    indirect = slot_rows.shape[0] > 0
    has_array = inst_proto.shape[0] > 0
    ordered = order.shape[0] > 0
    n = o.shape[0]
    for start in range(0, n, W):
        count = min(W, n - start)
        _load_packet(f, w, valid, W, o, d, order, start, count, tnear, t_max, masks, time)
        for k in range(W):
            w[_GEOM * W + k] = INVALID_ID
            w[_INST * W + k] = INVALID_ID
        _intersect(W, valid.ctypes.data, scene, f.ctypes.data, args.ctypes.data)
        for k in range(count):
            i = order[start + k] if ordered else start + k
            if w[_GEOM * W + k] == INVALID_ID:
                t_out[i] = np.inf
                prim_out[i] = -1
                inst_out[i] = -1
                u_out[i] = 0.0
                v_out[i] = 0.0
                continue
            inst = w[_INST * W + k]
            if has_array and inst == ARRAY_GEOM_ID:
                instance = np.int64(w[_INST_PRIM * W + k])
                obj = np.int64(inst_proto[instance])
                inst_out[i] = instance
            else:
                slot = inst if inst != INVALID_ID else w[_GEOM * W + k]
                obj = np.int64(slot) - OBJECT_GEOM_BASE
                inst_out[i] = -1
            row = slot_start[obj] + np.int64(w[_PRIM * W + k])
            prim_out[i] = slot_rows[row] if indirect else row
            t_out[i] = f[_TFAR * W + k]
            u_out[i] = f[_U * W + k]
            v_out[i] = f[_V * W + k]


@kernel
def occluded_rays(scene, o, d, tnear, t_max, blocked, masks, time, order, q):
    """blocked[i] = something lies on ray i between tnear and t_max[i] at its time (shadow rays), in packets as
    :func:`intersect_rays` makes them (``order``, ``q``); ``masks`` and ``time`` as there."""
    W = q & _WIDTH_BITS
    args = _query_args(q)
    f = _aligned(12 * MAX_PACKET, np.float32)
    w = f.view(np.uint32)
    valid = _aligned(MAX_PACKET, np.int32)
    ordered = order.shape[0] > 0
    n = o.shape[0]
    for start in range(0, n, W):
        count = min(W, n - start)
        _load_packet(f, w, valid, W, o, d, order, start, count, tnear, t_max, masks, time)
        _occluded(W, valid.ctypes.data, scene, f.ctypes.data, args.ctypes.data)
        for k in range(count):
            i = order[start + k] if ordered else start + k
            blocked[i] = f[_TFAR * W + k] < 0.0  # Embree sets tfar to -inf where the ray is occluded

"""Where compiled kernels live, and when they are still good: one content key per kernel, in the user's cache folder.

numba's own cache (``cache=True``) keeps a function's machine code beside its source file and trusts it while that
one file's modification time and size are unchanged. That is wrong for the tracer three ways: a kernel that calls a
helper from another module keeps running stale machine code after the helper changed; the extension folder of the
Blender add-on is replaced on every update, taking the kernels with it; and kernels compiled ahead of time for
another copy of the same sources are never found, since their files' times differ. Here instead:

- **A content key per kernel** (:func:`content_key`): a hash of what decides its machine code: its bytecode and
  constants, the options it is compiled with, the values of the globals it reads (numbers, tuples, arrays), the
  keys of the kernels it calls (recursively), and for any other object it reaches from the tracer's modules
  (a class, an ``intrinsic``) that module's source. So an edit recompiles only the kernels that reach what changed;
  a file that no kernel reaches (the CLI's settings, the USD reader) recompiles nothing. numba, llvmlite, numpy and
  Python versions are part of every key.
- **One folder per user** (:func:`cache_root`): ``$WHITTED_KERNEL_CACHE``, else ``$XDG_CACHE_HOME/whitted/kernels``
  (``~/.cache/whitted/kernels``; ``%LOCALAPPDATA%`` on Windows, ``~/Library/Caches`` on macOS), never inside the
  package. Files are named ``<module>.<function>-<key>``, so versions live side by side and an update that did not
  touch a kernel reuses it; older keys of a kernel beyond the newest :data:`KEEP` are removed when a new one is
  written.
- **Kernels shipped ahead** (:func:`use_bundle`): a folder of kernels compiled for a portable CPU baseline
  (:data:`BASELINE_CPU`, see ``python -m tracer.kernel_bundle``), e.g. inside the Blender add-on's zip. A kernel
  missing from the user's folder is copied from there when the machine has every feature the baseline needs, and
  loaded; machine code tuned for this CPU is compiled only where no bundle has the kernel.

Loading reads the cached machine code without numba's full target set-up (:meth:`KernelCache.load_overload`): the
first refresh of numba's CPU target imports some forty numba modules (typed containers, np.random, ...), 90 ms of a
0.7 s render; compiling still gets it, since numba's compiler refreshes the target itself.
"""

from __future__ import annotations

import hashlib
import inspect
import json
import os
import shutil
import sys
import threading
import time
import types as pytypes

import numba
import numba.core.event
import numpy as np
from numba.core.caching import CompileResultCacheImpl, FunctionCache, _CacheLocator

#: Environment variable naming the kernel cache folder (a render farm's shared disk, a test's temporary folder).
CACHE_ENV = "WHITTED_KERNEL_CACHE"
#: The CPU that kernels shipped ahead are compiled for (LLVM's name, ``NUMBA_CPU_NAME``): x86-64-v3 is every x86-64
#: CPU with AVX2 and FMA since 2013 (Haswell, Zen 1). docs/benchmarks.md has the measured cost against host tuning.
BASELINE_CPU = "x86-64-v3"
#: LLVM feature names the baseline needs from the host (x86-64-v2 and v3 levels of the x86-64 psABI).
BASELINE_FEATURES = ("cx16", "popcnt", "sse4.1", "sse4.2", "ssse3", "sahf", "avx", "avx2", "bmi", "bmi2", "f16c",
                     "fma", "lzcnt", "movbe", "xsave")
#: Keys kept per kernel: the newest few (a CLI and an add-on of different versions on one machine keep theirs).
KEEP = 3
#: The file in a bundle folder that says what its kernels were compiled for.
MANIFEST = "bundle.json"

_TOOLS = (f"py{sys.version_info[0]}.{sys.version_info[1]}", f"numba {numba.__version__}",
          f"llvmlite {__import__('llvmlite').__version__}", f"numpy {'.'.join(np.__version__.split('.')[:2])}")


def cache_root() -> str:
    """The folder this user's kernels are stored in (created on first save)."""
    base = os.environ.get(CACHE_ENV)
    if not base:
        if sys.platform == "win32":
            base = os.path.join(os.environ.get("LOCALAPPDATA") or os.path.expanduser("~"), "whitted", "kernels")
        elif sys.platform == "darwin":
            base = os.path.expanduser("~/Library/Caches/whitted/kernels")
        else:
            base = os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "whitted",
                                "kernels")
    return os.path.join(base, _flavour())


def _flavour() -> str:
    """The sub-folder for this Python and numba (machine code of one never loads into another)."""
    return f"numba-{numba.__version__}-py{sys.version_info[0]}{sys.version_info[1]}"


# ---------------------------------------------------------------------------------------------- content keys
_KEYS: dict = {}
_LOCAL: dict = {}
_FILES: dict = {}
_KEYS_LOCK = threading.RLock()


def content_key(fn, options: dict | None = None) -> str:
    """The content key of kernel function ``fn`` compiled with numba ``options`` (hex sha256; see the module): its
    own content and that of every kernel it reaches, as a set (so cycles and the order kernels are first used in
    make no difference)."""
    with _KEYS_LOCK:
        memo = (fn, tuple(sorted((options or {}).items())))
        key = _KEYS.get(memo)
        if key is None:
            parts, todo, seen = [], [memo], {memo}
            while todo:
                f, o = todo.pop()
                digest, calls = _local(f, o)
                parts.append(digest)
                for k in calls:
                    m = (k._fn, tuple(sorted(k._opts.items())))
                    if m not in seen:
                        seen.add(m)
                        todo.append(m)
            h = hashlib.sha256(repr((_TOOLS, memo[1])).encode())
            h.update(_local(*memo)[0])
            for d in sorted(parts):
                h.update(d)
            key = _KEYS[memo] = h.hexdigest()
        return key


def _local(fn, options: tuple) -> tuple:
    """(digest of what ``fn`` itself holds, the kernels it names), memoised."""
    memo = (fn, options)
    got = _LOCAL.get(memo)
    if got is None:
        h = hashlib.sha256(repr(options).encode())
        calls: list = []
        _feed_function(h, fn, set(), calls)
        got = _LOCAL[memo] = (h.digest(), calls)
    return got


def _code_names(code) -> set:
    names = set(code.co_names)
    for c in code.co_consts:
        if isinstance(c, pytypes.CodeType):
            names |= _code_names(c)
    return names


def _feed_code(h, code) -> None:
    h.update(code.co_code)
    h.update(repr((code.co_names, code.co_varnames, code.co_freevars, code.co_argcount)).encode())
    for c in code.co_consts:
        if isinstance(c, pytypes.CodeType):
            _feed_code(h, c)
        else:
            h.update(repr(c).encode())


def _feed_function(h, fn, visiting: set, calls: list) -> None:
    h.update(f"{_rel(fn.__module__)}.{fn.__qualname__}".encode())
    code = fn.__code__
    _feed_code(h, code)
    h.update(repr(fn.__defaults__).encode())
    names = _code_names(code)
    for cell in fn.__closure__ or ():
        _feed_value(h, cell.cell_contents, names, visiting, calls)
    g = fn.__globals__
    for name in sorted(names):
        if name in g:
            h.update(name.encode())
            _feed_value(h, g[name], names, visiting, calls)


def _feed_value(h, v, names: set, visiting: set, calls: list) -> None:
    """What of global ``v`` can change the machine code of a kernel that reads it."""
    if getattr(type(v), "is_tracer_kernel", False):  # a tracer.jit.Kernel (tracer.jit imports this module)
        h.update(f"{_rel(v.__module__)}.{v.__qualname__}".encode())
        calls.append(v)
        return
    if isinstance(v, (bool, int, float, complex, str, bytes, type(None), np.generic)):
        h.update(repr(v).encode())
    elif isinstance(v, (tuple, list, frozenset)):
        h.update(f"{type(v).__name__}{len(v)}".encode())
        for x in v:
            _feed_value(h, x, names, visiting, calls)
    elif isinstance(v, np.ndarray):
        h.update(repr((v.dtype.str, v.shape)).encode())
        h.update(hashlib.sha256(np.ascontiguousarray(v).tobytes()).digest())
    elif isinstance(v, pytypes.ModuleType):
        h.update(_rel(v.__name__).encode())
        if _ours(v.__name__) and id(v) not in visiting:
            visiting.add(id(v))
            for name in sorted(names):
                if name in vars(v):
                    h.update(name.encode())
                    _feed_value(h, vars(v)[name], names, visiting, calls)
            visiting.discard(id(v))
    elif isinstance(v, numba.core.dispatcher.Dispatcher):
        h.update(f"{_rel(v.py_func.__module__)}.{v.py_func.__qualname__}".encode())
        _feed_source(h, v.py_func.__module__)
    else:
        module = getattr(v, "__module__", None) or getattr(type(v), "__module__", "")
        h.update(f"{_rel(module)}:{type(v).__qualname__}:{getattr(v, '__qualname__', '')}".encode())
        if _ours(module):
            _feed_source(h, module)  # a class, an intrinsic, a NamedTuple: its whole module, to be safe


#: This tracer's package: ``tracer`` in the repository, ``bl_ext.<repo>.whitted.tracer`` inside Blender's extension.
_PKG = __name__.rsplit(".", 1)[0]


def _ours(module: str | None) -> bool:
    return bool(module) and (module == _PKG or module.startswith(_PKG + "."))


def _rel(module: str) -> str:
    """A tracer module's name as in the repository (``tracer.integrator.wavefront``), wherever this copy is imported from:
    keys and file names are the same for the add-on's copy, a bundle built from the repository and the CLI."""
    return "tracer" + module[len(_PKG):] if _ours(module) else module


def _feed_source(h, module: str) -> None:
    digest = _FILES.get(module)
    if digest is None:
        mod = sys.modules.get(module)
        try:
            with open(inspect.getfile(mod), "rb") as f:
                digest = hashlib.sha256(f.read()).digest()
        except (TypeError, OSError):
            digest = module.encode()
        _FILES[module] = digest
    h.update(digest)


# ---------------------------------------------------------------------------------------------- the cache
class _Locator(_CacheLocator):
    """numba's cache locator for one kernel: the user's folder, the content key as the 'source stamp'."""

    def __init__(self, py_func, key: str):
        self._py_file = inspect.getfile(py_func)
        self._key = key
        self._path = cache_root()

    def ensure_cache_path(self):
        os.makedirs(self._path, exist_ok=True)

    def get_cache_path(self):
        return self._path

    def get_source_stamp(self):
        return self._key

    def get_disambiguator(self):
        return self._key[:16]

    @classmethod
    def from_function(cls, py_func, py_file):  # only made by _Impl, with the key
        return None


class _Impl(CompileResultCacheImpl):
    def __init__(self, py_func, key: str):  # noqa: D107 (numba's __init__ searches locators; ours is known)
        self._lineno = py_func.__code__.co_firstlineno
        self._locator = _Locator(py_func, key)
        # the full module name: what the cache pickles (argument types, the function's module) names it, so a copy
        # of the tracer imported under another name (inside Blender: bl_ext.<repo>.whitted.tracer) has its own files
        self._filename_base = f"{py_func.__module__}.{py_func.__qualname__}-{key[:16]}.py".replace("<", "").replace(
            ">", "")


class KernelCache(FunctionCache):
    """numba's on-disk cache of one kernel, keyed by :func:`content_key`, in :func:`cache_root`, with shipped
    kernels (:func:`use_bundle`) as a second source."""

    _impl_class = None

    def __init__(self, py_func, options: dict):
        from numba.core.caching import IndexDataCacheFile

        self._name = repr(py_func)
        self._py_func = py_func
        self._key = content_key(py_func, options)
        self._impl = _Impl(py_func, self._key)
        self._cache_path = self._impl.locator.get_cache_path()
        self._cache_file = IndexDataCacheFile(cache_path=self._cache_path, filename_base=self._impl.filename_base,
                                              source_stamp=self._key)
        self.enable()

    def load_overload(self, sig, target_context):
        """The cached machine code of ``sig``, or None: then numba compiles it, and this process holds the kernel's
        lock until :meth:`save_overload` (another process that misses it too waits, then loads it)."""
        from numba.core.runtime import rtsys

        rtsys.initialize(target_context)  # what numba's target refresh would do for a load (see the module)
        data = self._load_overload(sig, target_context)
        if data is None and not _BUNDLE and not _BUNDLE_TRIED:
            _BUNDLE_TRIED.append(use_bundle(PACKAGED))  # an installed package's own kernels (see PACKAGED)
        if data is None and _seed_from_bundle(self._impl.filename_base, self._cache_path):
            data = self._load_overload(sig, target_context)
        if data is None and _lock(self._cache_path, self._impl.filename_base):
            data = self._load_overload(sig, target_context)  # saved while this process waited for the lock
            if data is not None:
                _unlock(self._impl.filename_base)
        return data

    def _load_overload(self, sig, target_context):
        """This CPU's machine code, else the bundle's baseline code (when a bundle is in use; see use_bundle)."""
        if not self._enabled:
            return None
        key = self._index_key(sig, target_context.codegen())
        try:
            data = self._cache_file.load(key)
            if data is None and _BUNDLE.get("magic"):
                data = self._cache_file.load(key[:1] + (_BUNDLE["magic"],) + key[2:])
            return None if data is None else self._impl.rebuild(target_context, data)
        except Exception as exc:  # an unreadable or foreign entry is a miss: the kernel compiles (said once)
            if not _WARNED:
                _WARNED.append(exc)
                print(f"whitted: ignoring an unreadable kernel cache entry in {self._cache_path} ({exc})",
                      file=sys.stderr)
            return None

    def _save_overload(self, sig, data):
        try:
            super()._save_overload(sig, data)
            _prune(self._cache_path, self._impl.filename_base)
        finally:
            _unlock(self._impl.filename_base)


# ---------------------------------------------------------------------------------------------- one compile per unit
# Two processes that fill one cache at once (the render and its helper, tracer/kernel_plan.py; two renders started
# together) would compile every unit both miss twice. A process that misses a kernel takes its lock file
# (``<kernel>.lock`` beside its index, an advisory flock that the system drops when the process ends), looks in the
# cache again, and keeps the lock while it compiles and saves. A kernel never waits for itself or for a kernel it
# calls while holding a caller's lock in the other direction (kernels do not recurse), so two processes cannot
# deadlock; a lock held longer than LOCK_WAIT seconds (a process stopped in a debugger) is ignored.
LOCK_WAIT = 120.0
_HELD: dict = {}

try:
    import fcntl
except ImportError:  # Windows: no locks (two processes may compile a unit twice; each result is whole)
    fcntl = None


def _lock(folder: str, base: str) -> bool:
    """Take kernel ``base``'s lock, waiting while another process holds it; True when this process holds it."""
    if fcntl is None or base in _HELD:
        return False
    try:
        os.makedirs(folder, exist_ok=True)
        fd = os.open(os.path.join(folder, base + ".lock"), os.O_CREAT | os.O_RDWR, 0o644)
    except OSError:
        return False
    deadline = time.monotonic() + LOCK_WAIT
    while True:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            break
        except BlockingIOError:
            if time.monotonic() > deadline:
                os.close(fd)
                return False
            time.sleep(0.01)
        except OSError:
            os.close(fd)
            return False
    _HELD[base] = fd
    return True


def _unlock(base: str) -> None:
    fd = _HELD.pop(base, None)
    if fd is not None:
        os.close(fd)  # closing the file drops its flock


class _ReleaseOnFailure(numba.core.event.Listener):
    """A compile that raised never reaches save_overload: drop its lock then."""

    def on_start(self, event):
        pass

    def on_end(self, event):
        cache = getattr(event.data.get("dispatcher"), "_cache", None)
        # numba 0.68's Event.is_failed is inverted (True when there is no exception): read the details themselves
        if getattr(event, "_exc_details", None) is not None and isinstance(cache, KernelCache):
            _unlock(cache._impl.filename_base)


numba.core.event.register("numba:compile", _ReleaseOnFailure())


# ---------------------------------------------------------------------------------------------- shipped kernels
_BUNDLE: dict = {}
_BUNDLE_TRIED: list = []
_WARNED: list = []
#: Kernels shipped inside the installed package: a wheel built after ``python -m tracer.kernel_bundle
#: tracer/kernels`` carries them (pyproject.toml's package data), and they are used, where this CPU can run them,
#: the first time a kernel is missing from the user's cache. A checkout has none (the folder is not in git).
PACKAGED = os.path.join(os.path.dirname(os.path.abspath(__file__)), "kernels")


def use_bundle(folder: str) -> bool:
    """Use the kernels shipped in ``folder`` (made by ``python -m tracer.kernel_bundle``) where this machine can run
    them: kernels missing from the user's cache are copied from there on first use and loaded; a kernel the bundle
    lacks is compiled for this CPU as usual. Returns False (nothing changes) where the folder does not fit this
    Python, numba and CPU."""
    path = os.path.join(folder, _flavour())
    try:
        with open(os.path.join(path, MANIFEST)) as f:
            manifest = json.load(f)
    except (OSError, ValueError):
        return False
    if not host_runs(manifest.get("features", ())):
        return False
    from numba.core.registry import cpu_target

    host = tuple(cpu_target.target_context.codegen().magic_tuple())
    if host[0] != manifest["magic"][0]:
        return False
    _BUNDLE.update(folder=path, magic=tuple(manifest["magic"]))
    return True


def host_runs(features) -> bool:
    """This CPU has every LLVM feature named (e.g. :data:`BASELINE_FEATURES`)."""
    from llvmlite import binding as ll

    try:
        have = ll.get_host_cpu_features()
    except RuntimeError:
        return False
    return all(have.get(f, False) for f in features)


def _seed_from_bundle(base: str, into: str) -> bool:
    """Copy kernel ``base``'s index and data files from the bundle in use into the user's folder, unless that
    folder already has an index for it. True when something was copied."""
    src = _BUNDLE.get("folder")
    if not src or os.path.exists(os.path.join(into, base + ".nbi")):
        return False
    if not os.path.exists(os.path.join(src, base + ".nbi")):
        return False
    try:
        os.makedirs(into, exist_ok=True)
        names = [n for n in os.listdir(src) if n.startswith(base + ".")]
        for n in sorted(names, key=lambda n: n.endswith(".nbi")):  # the index last: it names the data files
            tmp = os.path.join(into, f".{n}.{os.getpid()}.tmp")
            shutil.copyfile(os.path.join(src, n), tmp)
            os.replace(tmp, os.path.join(into, n))
    except OSError:
        return False
    return True


def _prune(folder: str, base: str) -> None:
    """Remove the files of this kernel's older keys beyond the newest :data:`KEEP` (best effort)."""
    stem = base.rsplit("-", 1)[0] + "-"
    try:
        entries = [e for e in os.scandir(folder) if e.name.startswith(stem) and e.name.endswith(".nbi")]
    except OSError:
        return
    if len(entries) <= KEEP:
        return
    entries.sort(key=lambda e: e.stat().st_mtime, reverse=True)
    for e in entries[KEEP:]:
        old = e.name[:-len(".nbi")]
        for f in os.scandir(folder):
            if f.name.startswith(old + "."):
                try:
                    os.unlink(f.path)
                except OSError:
                    pass

"""How the tracer's kernels are compiled: numba, ahead of the first use, cached on disk, without the GIL.

Every hot loop of the tracer (one iteration per ray or per hit) is a numba function: the per-ray maths stays in
plain scalar Python that reads like the notes, and runs at compiled speed on the tile threads. ``kernel`` is the
one decorator they all use:

- ``cache=True``: compiled machine code is stored in ``NUMBA_CACHE_DIR`` when that is set, else in
  ``tracer/__pycache__/kernels-<hash>``, else, where that folder is not writable, in the user's cache directory;
  only the first render on a machine pays the compilation (about 10 s for all kernels). ``<hash>`` is a hash of
  every tracer source file: numba's own cache check looks only at the file a kernel is defined in, so a kernel
  that inlines a function from another module (the integrator calls ``optics.reflect_dir``) would otherwise keep
  running stale machine code after that module changed;
- ``nogil=True``: tiles run their kernels in parallel on the render thread pool;
- ``error_model="numpy"``: a division by zero gives inf/NaN as numpy would (the integrator clears non-finite
  pixels) instead of raising, and lets loops compile without the checks.

No ``fastmath``: it would let the compiler assume there are no NaN/Inf, and the tracer relies on inf (misses,
distant lights) behaving as IEEE says.
"""

from __future__ import annotations

import functools
import hashlib
import os
import threading

import numba
from numba.core.caching import FunctionCache

_OPTIONS = dict(cache=True, nogil=True, error_model="numpy")


def _cache_dir() -> str | None:
    """Where this version of the tracer's sources keeps its kernels (None: ``NUMBA_CACHE_DIR`` decides)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    here = os.path.dirname(os.path.abspath(__file__))
    h = hashlib.sha1()
    for name in sorted(_sources(here)):  # subpackages too: the VM inlines tracer.procedural's functions
        with open(os.path.join(here, name), "rb") as f:
            h.update(name.encode() + b"\0" + f.read())
    leaf = f"kernels-{h.hexdigest()[:16]}"
    _prune(os.path.join(here, "__pycache__"), leaf)
    for base in (os.path.join(here, "__pycache__"),
                 os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "whitted")):
        try:
            os.makedirs(os.path.join(base, leaf), exist_ok=True)
            if os.access(os.path.join(base, leaf), os.W_OK):
                return os.path.join(base, leaf)
        except OSError:
            continue
    return None


def _sources(here: str) -> list:
    """Every .py file under ``here`` (relative paths), subpackages included."""
    out = []
    for root, dirs, files in os.walk(here):
        dirs[:] = [d for d in dirs if d != "__pycache__"]
        out += [os.path.relpath(os.path.join(root, f), here) for f in files if f.endswith(".py")]
    return out


def _prune(base: str, keep: str, versions: int = 3) -> None:
    """Remove kernel folders of older source versions beyond the newest few (best effort)."""
    import shutil

    try:
        old = sorted((e for e in os.scandir(base) if e.is_dir() and e.name.startswith("kernels-") and e.name != keep),
                     key=lambda e: e.stat().st_mtime, reverse=True)
    except OSError:
        return
    for e in old[versions:]:
        shutil.rmtree(e.path, ignore_errors=True)


_CACHE_DIR = _cache_dir()
#: Written into the kernel cache folder once :func:`tracer.compile_kernels` has compiled every kernel there.
_WARM_MARKER = ".all-kernels-compiled"


def kernels_cached() -> bool:
    """True where an earlier process compiled every kernel of these sources into the cache (loading them is then
    quick, and a warm-up render would only cost time). False with ``NUMBA_CACHE_DIR``, which numba manages."""
    return _CACHE_DIR is not None and os.path.exists(os.path.join(_CACHE_DIR, _WARM_MARKER))


def mark_kernels_cached() -> None:
    """Record that every kernel is in the cache (called by :func:`tracer.compile_kernels`)."""
    if _CACHE_DIR is not None:
        try:
            with open(os.path.join(_CACHE_DIR, _WARM_MARKER), "w") as f:
                f.write("numba cache complete\n")
        except OSError:
            pass


class _KernelCache(FunctionCache):
    """numba's on-disk cache of one kernel, loading a cached specialisation without numba's full target set-up.

    numba's ``Cache.load_overload`` refreshes the CPU target before every load: the first time in a process that
    imports some forty modules of numba (typed containers, np.random, polynomials, datetime, ...) and installs
    their typing and lowering registries, 90 ms of a 0.7 s ``whitted render`` of one sphere. Machine code loaded
    from the cache needs none of it, only numba's runtime (NRT, initialised here as the refresh would); compiling
    still gets it all, since numba's compiler refreshes the target itself before typing anything
    (``compiler.compile_extra``), as does a lowering lookup that misses (``BaseContext.get_function``)."""

    def load_overload(self, sig, target_context):
        from numba.core.runtime import rtsys

        rtsys.initialize(target_context)
        with self._guard_against_spurious_io_errors():
            return self._load_overload(sig, target_context)


#: numba versions whose cache has the two internals :class:`_KernelCache` relies on (else numba's own is kept).
_LIGHT_LOADS = all(hasattr(FunctionCache, name) for name in ("_load_overload", "_guard_against_spurious_io_errors"))


def kernel(fn=None, *, inline: bool = False, refcounts: bool = True):
    """Compile ``fn`` with the tracer's options; ``inline=True`` for small helpers called from other kernels.

    ``refcounts=False`` for a per-ray stage that allocates nothing: numba's runtime (NRT) is left out of it, so the
    arrays it reads are borrowed from the caller for the call and no reference counting is emitted at all
    (numba's ``_nrt`` flag). numba counts references to every array an inlined helper is handed, atomically, and
    cannot prune them across branches: after moving NamedTuples out of the helpers' arguments, what was left cost
    the textures stage 20 % and the other stages 3-10 % (docs/benchmarks.md). A kernel that allocates (np.empty
    …) fails to compile with this set, at once.

    The numba dispatcher is made when the kernel is first used (:class:`Kernel`), not at import: a render uses
    about 20 of the tracer's ~370 kernels, and making a dispatcher costs 0.2 ms."""
    opts = dict(_OPTIONS, inline="always") if inline else dict(_OPTIONS)
    if not refcounts:
        opts["_nrt"] = False

    def wrap(f):
        return Kernel(f, opts)

    return wrap(fn) if fn is not None else wrap


_MAKING = threading.RLock()


def _dispatcher(f, opts: dict):
    """numba's dispatcher of ``f``, caching into this source version's folder."""
    with _MAKING:  # numba picks a function's cache location when it is decorated, from its global config
        saved = numba.config.CACHE_DIR
        if _CACHE_DIR is not None:
            numba.config.CACHE_DIR = _CACHE_DIR
        try:
            dispatcher = numba.njit(**opts)(f)
        finally:
            numba.config.CACHE_DIR = saved
    if _LIGHT_LOADS and type(getattr(dispatcher, "_cache", None)) is FunctionCache:
        dispatcher._cache.__class__ = _KernelCache
    return dispatcher


class Kernel:
    """A tracer kernel: ``fn`` and its numba options, its dispatcher made on first use (a call from Python, or numba
    typing a kernel that calls it) and everything else forwarded to it (``signatures``, ``py_func``, ...).

    numba types a global by its ``_numba_type_`` and inlines a callee by its ``targetoptions`` and ``py_func``
    (duck-typed in both places), so a kernel that calls this one compiles as with the dispatcher itself; machine
    code loaded from the cache never looks at its callees at all."""

    def __init__(self, fn, opts: dict):
        functools.update_wrapper(self, fn)
        self._fn, self._opts, self._made = fn, opts, None

    @property
    def dispatcher(self):
        """numba's dispatcher of this kernel (made now if it was not)."""
        made = self._made
        if made is None:
            with _MAKING:
                if self._made is None:
                    self._made = _dispatcher(self._fn, self._opts)
                made = self._made
        return made

    @property
    def _numba_type_(self):
        return self.dispatcher._numba_type_

    def __call__(self, *args, **kwargs):
        return self.dispatcher(*args, **kwargs)

    def __getattr__(self, name):
        if name.startswith("__") or name in ("_fn", "_opts", "_made"):  # not set yet (copy, pickle), or dunder
            raise AttributeError(name)
        return getattr(self.dispatcher, name)

    def __reduce__(self):  # pickled by reference, as its module's attribute
        return self.__qualname__

    def __repr__(self):
        return f"<tracer kernel {self.__module__}.{self.__qualname__}>"

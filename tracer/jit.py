"""How the tracer's kernels are compiled: numba, in small units, cached on disk by content, without the GIL.

Every hot loop of the tracer (one iteration per ray or per hit) is a numba function: the per-ray maths stays in
plain scalar Python that reads like the notes, and runs at compiled speed on the tile threads. ``kernel`` is the
one decorator they all use, in three kinds:

- ``@kernel``: a stage called from Python (a tile's eye rays, the direct-light stage, ...).
- ``@kernel(inline=True)``: a helper called from other kernels (a BSDF, a light's sample, a noise). It is its own
  compile unit, compiled once per argument types however many kernels call it; LLVM inlines it into its callers
  where that pays (numba links a callee's optimised IR into each caller before optimising the caller). It gets no
  Python wrapper (a call from Python, as tests make, compiles a separate Python-callable copy on demand) and no
  reference counting (``refcounts=False``) unless it says otherwise.
- ``@kernel(inline="always")``: numba copies the function's IR into every caller before typing it. Only for tiny
  leaf helpers (tracer/vec.py's vector maths): numba types an inlined body again at every call site, so a large
  one multiplies the compile time (a 2 000-line inlined stage took 54 s to compile; docs/benchmarks.md).

Options of every kernel:

- cached on disk by content (:mod:`tracer.kernel_cache`): each kernel's key covers the modules and values it
  reaches, in the user's cache folder; kernels shipped ahead for a CPU baseline are loaded from there;
- ``nogil=True``: tiles run their kernels in parallel on the render thread pool;
- ``error_model="numpy"``: a division by zero gives inf/NaN as numpy would (the integrator clears non-finite
  pixels) instead of raising, and lets loops compile without the checks.

No ``fastmath``: it would let the compiler assume there are no NaN/Inf, and the tracer relies on inf (misses,
distant lights) behaving as IEEE says.
"""

from __future__ import annotations

import functools
import os
import threading

import numba
import numba.core.event

from . import kernel_cache

_OPTIONS = dict(nogil=True, error_model="numpy")
#: A helper's unit: no Python or C wrapper (only kernels call it).
_HELPER = dict(no_cpython_wrapper=True, no_cfunc_wrapper=True)

#: Written into the kernel cache folder once :func:`tracer.compile_kernels` has compiled every kernel there.
_WARM_MARKER = ".all-kernels-compiled"


def sources_digest() -> str:
    """A digest of this version of the tracer's sources (any edit under tracer/ makes a new one)."""
    import hashlib

    here = os.path.dirname(os.path.abspath(__file__))
    h = hashlib.sha256()
    for root, dirs, files in sorted(os.walk(here)):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        for name in sorted(f for f in files if f.endswith(".py")):
            with open(os.path.join(root, name), "rb") as f:
                h.update(os.path.relpath(os.path.join(root, name), here).encode() + b"\0" + f.read())
    return h.hexdigest()[:16]


def _marker() -> str:
    """The marker of this version of the tracer's sources."""
    return os.path.join(kernel_cache.cache_root(), f"{_WARM_MARKER}-{sources_digest()}")


def kernels_cached() -> bool:
    """True where an earlier process compiled every kernel of these sources into the cache (loading them is then
    quick, and a warm-up render would only cost time)."""
    return os.path.exists(_marker())


def mark_kernels_cached() -> None:
    """Record that every kernel is in the cache (called by :func:`tracer.compile_kernels`)."""
    try:
        os.makedirs(kernel_cache.cache_root(), exist_ok=True)
        with open(_marker(), "w") as f:
            f.write("numba cache complete\n")
    except OSError:
        pass


def kernel(fn=None, *, inline: bool | str = False, refcounts: bool | None = None):
    """Compile ``fn`` with the tracer's options: a stage (default), a helper unit (``inline=True``) or an inlined
    leaf (``inline="always"``); see the module.

    ``refcounts=False`` for code that allocates nothing: numba's runtime (NRT) is left out of it, so the arrays it
    reads are borrowed from the caller for the call and no reference counting is emitted at all (numba's ``_nrt``
    flag). numba counts references to every array a function is handed, atomically, and cannot prune them across
    branches: for the stages that cost 3-20 % (docs/benchmarks.md). A kernel that allocates (np.empty …) fails to
    compile with this set, at once. Default: on for stages, off for helpers; a helper that allocates or returns an
    array says ``refcounts=True`` (its caller owns what it returns).

    The numba dispatcher is made when the kernel is first used (:class:`Kernel`), not at import: a render uses a
    fraction of the tracer's kernels, and making a dispatcher costs 0.2 ms."""
    if inline not in (False, True, "always", "call"):
        raise ValueError(f"kernel(inline={inline!r}): False, True, 'call' or 'always'")
    # forceinline and _nrt set either way: numba hands an unset one down from the kernel whose compile triggers this
    opts = dict(_OPTIONS, forceinline=inline is True)
    if inline == "always":
        opts["inline"] = "always"
    elif inline:
        opts.update(_HELPER)
    opts["_nrt"] = not (refcounts is False or (refcounts is None and inline in (True, "call")))

    def wrap(f):
        return Kernel(f, opts)

    return wrap(fn) if fn is not None else wrap


_MAKING = threading.RLock()


class CompileProgress(numba.core.event.Listener):
    """Calls ``report(units_done, kernel_name, seconds)`` as numba finishes each of the tracer's compile units, on
    whichever thread compiles it (for a front end's status line: the first render of a new version compiles what
    it uses, a unit at a time). Use as a context manager around the work, or :meth:`install` for the process."""

    def __init__(self, report):
        self.report, self.done, self._start = report, 0, None

    def on_start(self, event):
        if self._start is None:
            import time

            self._start = time.perf_counter()

    def on_end(self, event):
        import time

        f = getattr(event.data.get("dispatcher"), "py_func", None)
        if f is None or not kernel_cache._ours(f.__module__):
            return
        self.done += 1
        self.report(self.done, f"{f.__module__.removeprefix('tracer.')}.{f.__qualname__}",
                    time.perf_counter() - self._start)

    def install(self):
        numba.core.event.register("numba:compile", self)
        return self

    def uninstall(self):
        numba.core.event.unregister("numba:compile", self)

    def __enter__(self):
        return self.install()

    def __exit__(self, *exc):
        self.uninstall()


def _dispatcher(f, opts: dict):
    """numba's dispatcher of ``f``, cached by content (:class:`tracer.kernel_cache.KernelCache`)."""
    dispatcher = numba.njit(**opts)(f)
    if opts.get("inline") != "always":  # an inlined body is never compiled on its own
        dispatcher._cache = kernel_cache.KernelCache(f, opts)
    if opts.get("no_cpython_wrapper"):
        _compile_unliteral(dispatcher)
    return dispatcher


def _compile_unliteral(dispatcher) -> None:
    """A helper is compiled for the plain types of its arguments, not once per constant a caller passes: numba
    types a constant argument as a literal (``Literal[int](0)``) and compiles a kernel called from other kernels
    once per literal value (``lobes._slot`` was compiled four times, for slots 0-3). The constant still reaches the
    machine code, since LLVM inlines the helper into its caller and folds it there."""
    from numba.core import types

    get_call_template = dispatcher.get_call_template

    def plain(args, kws):
        return get_call_template(tuple(types.unliteral(a) for a in args),
                                 {k: types.unliteral(v) for k, v in kws.items()})

    dispatcher.get_call_template = plain


def cfunc(signature, fn):
    """``numba.cfunc(signature)(fn)`` with the tracer's options (a C callback, e.g. Embree's filter), cached by
    content like the kernels. ``signature``: a numba signature such as ``types.void(types.voidptr)``."""
    from numba.core.ccallback import CFunc

    opts = dict(error_model="numpy")
    made = CFunc(fn, (signature.args, signature.return_type), locals={}, options=opts)
    made._cache = kernel_cache.KernelCache(fn, dict(opts, cfunc=str(signature)))
    made.compile()
    return made


class Kernel:
    """A tracer kernel: ``fn`` and its numba options, its dispatcher made on first use (a call from Python, or numba
    typing a kernel that calls it) and everything else forwarded to it (``signatures``, ``py_func``, ...).

    numba types a global by its ``_numba_type_`` and inlines a callee by its ``targetoptions`` and ``py_func``
    (duck-typed in both places), so a kernel that calls this one compiles as with the dispatcher itself; machine
    code loaded from the cache never looks at its callees at all."""

    #: How :mod:`tracer.kernel_cache` tells a kernel among a function's globals (it does not import this module).
    is_tracer_kernel = True

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
        """A call from Python. A helper unit has no Python wrapper: its Python-callable copy is compiled (and cached)
        on the first such call, as tests make them."""
        if not self._opts.get("no_cpython_wrapper"):
            return self.dispatcher(*args, **kwargs)
        py = self.__dict__.get("_py")
        if py is None:
            with _MAKING:
                opts = {k: v for k, v in self._opts.items() if k not in _HELPER}
                py = self.__dict__.setdefault("_py", _dispatcher(self._fn, opts))
        return py(*args, **kwargs)

    def __getattr__(self, name):
        if name.startswith("__") or name in ("_fn", "_opts", "_made", "_py"):  # not set yet (copy, pickle), or dunder
            raise AttributeError(name)
        return getattr(self.dispatcher, name)

    def __reduce__(self):  # pickled by reference, as its module's attribute
        return self.__qualname__

    def __repr__(self):
        return f"<tracer kernel {self.__module__}.{self.__qualname__}>"

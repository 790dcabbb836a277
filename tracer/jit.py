"""How the tracer's kernels are compiled: numba, ahead of the first use, cached on disk, without the GIL.

Every hot loop of the tracer (one iteration per ray or per hit) is a numba function: the per-ray maths stays in
plain scalar Python that reads like the notes, and runs at compiled speed on the tile threads. ``kernel`` is the
one decorator they all use:

- ``cache=True``: compiled machine code is stored in ``NUMBA_CACHE_DIR`` when that is set, else next to the module
  (``__pycache__``), else, where that folder is not writable, in the user's cache directory; only the first render
  on a machine pays the compilation (about 10 s for all kernels);
- ``nogil=True``: tiles run their kernels in parallel on the render thread pool;
- ``error_model="numpy"``: a division by zero gives inf/NaN as numpy would (the integrator clears non-finite
  pixels) instead of raising, and lets loops compile without the checks.

No ``fastmath``: it would let the compiler assume there are no NaN/Inf, and the tracer relies on inf (misses,
distant lights) behaving as IEEE says.
"""

from __future__ import annotations

import numba

_OPTIONS = dict(cache=True, nogil=True, error_model="numpy")


def kernel(fn=None, *, inline: bool = False):
    """Compile ``fn`` with the tracer's options; ``inline=True`` for small helpers called from other kernels."""
    opts = dict(_OPTIONS, inline="always") if inline else _OPTIONS

    def wrap(f):
        return numba.njit(**opts)(f)

    return wrap(fn) if fn is not None else wrap

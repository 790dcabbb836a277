"""Give freed memory back to the operating system (glibc's ``malloc_trim``), where loading has just freed a lot.

Loading a large stage allocates and frees many mid-sized arrays (per-mesh pieces, refinement temporaries). glibc
keeps freed chunks below its (dynamic, up to 32 MB) mmap threshold in the process heap, so the resident size stays
at its high-water mark although the memory is free: on the kitchen set (bench/kitchen.py) 0.36 GB of a 0.78 GB
process after ``load_stage``. ``trim()`` returns such free pages (``madvise``); a no-op where there is no glibc.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import sys

_TRIM = None


def trim() -> None:
    """Release free heap memory to the OS (a few ms; call after dropping large temporaries)."""
    global _TRIM
    if _TRIM is None:
        _TRIM = False
        if sys.platform.startswith("linux"):
            try:
                _TRIM = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").malloc_trim
                _TRIM.argtypes, _TRIM.restype = [ctypes.c_size_t], ctypes.c_int
            except (OSError, AttributeError):
                _TRIM = False
    if _TRIM:
        _TRIM(0)

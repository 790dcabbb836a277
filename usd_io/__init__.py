"""USD stage -> :class:`tracer.Scene`, and the ``whitted`` command line.

    from usd_io import load_stage
    scene, info = load_stage("shot.usda", time=1001, camera="/World/Cam", width=640)

Imports ``tracer`` and ``pxr`` (usd-core) on first use of a name (PEP 562), so ``whitted --version`` and
``whitted`` without arguments answer without loading them. The feature table is in ``docs/usd.md``.
"""

from __future__ import annotations

import importlib

_EXPORTS = {"StageInfo": "reader", "load_stage": "reader", "UsdInputError": "errors"}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'usd_io' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value

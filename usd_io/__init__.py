"""USD stage -> :class:`tracer.Scene`, and the ``whitted`` command line.

    from usd_io import load_stage
    scene, info = load_stage("shot.usda", time=1001, camera="/World/Cam", width=640)

Imports ``tracer`` and ``pxr`` (usd-core). The feature table is in ``docs/usd.md``.
"""

from .reader import StageInfo, load_stage
from .stage import UsdInputError

__all__ = ["StageInfo", "UsdInputError", "load_stage"]

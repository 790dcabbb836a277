"""Stage metadata read with the type it was authored with.

``UsdGeom.GetStageMetersPerUnit`` asks for a ``double`` and pxr raises ``Tf.ErrorException`` when a layer holds
another type (tinyusdz and some exporters write ``metersPerUnit`` as a ``float`` in .usdc). The layer's own
field is read instead, whatever its numeric type; a value that is not a positive number is UsdGeom's fallback
0.01 with one warning.
"""

from __future__ import annotations

import math

from pxr import UsdGeom

FALLBACK_METERS_PER_UNIT = 0.01  # UsdGeom's fallback (centimetres)


def meters_per_unit(stage, warn) -> float:
    try:
        return float(UsdGeom.GetStageMetersPerUnit(stage))
    except Exception:  # pxr's Tf.ErrorException: authored with another type than double
        pass
    value = None
    for layer in (stage.GetSessionLayer(), stage.GetRootLayer()):
        if layer is not None and layer.pseudoRoot.HasInfo("metersPerUnit"):
            value = layer.pseudoRoot.GetInfo("metersPerUnit")
            break
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if math.isfinite(v) and v > 0:
        return v
    warn(f"metersPerUnit {value!r} is not a positive number: read as {FALLBACK_METERS_PER_UNIT} (UsdGeom's "
         "fallback)")
    return FALLBACK_METERS_PER_UNIT

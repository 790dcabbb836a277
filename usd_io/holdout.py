"""Holdouts from USD: ``primvars:arnold:matte`` (bool, constant; inherited from an ancestor as constant primvars
are), the one convention real files carry (Arnold's USD schema; Houdini and production pipelines author it to
turn objects into holdouts). USD has no renderer-neutral holdout or shadow-catcher schema, so shadow catchers are
not read from USD. A matte object is a holdout object in the tracer (``Scene.object_holdout``, tracer.integrator.compose)."""

from __future__ import annotations

import numpy as np
from pxr import UsdGeom

MATTE = "arnold:matte"


def holdout_flags(stage, object_names: list, time) -> np.ndarray | None:
    """(O,) bool per object id from the prims its name is the path of (``path[...]`` for a PointInstancer's
    pieces: the instancer's); None when no object is a matte."""
    out = np.zeros(len(object_names), bool)
    seen: dict = {}
    for i, name in enumerate(object_names):
        path = str(name).split("[", 1)[0]
        if not path.startswith("/"):
            continue
        if path not in seen:
            prim = stage.GetPrimAtPath(path)
            value = False
            if prim and prim.IsValid():
                pv = UsdGeom.PrimvarsAPI(prim).FindPrimvarWithInheritance(MATTE)
                value = bool(pv and pv.HasValue() and pv.Get(time))
            seen[path] = value
        out[i] = seen[path]
    return out if out.any() else None

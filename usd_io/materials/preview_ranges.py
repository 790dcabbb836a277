"""UsdPreviewSurface inputs outside the spec's ranges are clamped into them, with one warning per material and input.

Another renderer draws ``roughness = 1.05`` (Storm clamps in its shader); refusing the whole stage would be worse
than the small change of look. The ranges (UsdPreviewSurface specification, the inputs' documented domains):

    roughness, clearcoatRoughness, metallic, clearcoat, opacity, opacityThreshold    [0, 1]
    diffuseColor, emissiveColor, specularColor                                    each channel >= 0
    ior                                                                           > 0 (else the fallback 1.5)

Only constants are clamped here; texture texels are clamped where they are read (the tracer's shading).
"""

from __future__ import annotations

import numpy as np

from . import network as net

UNIT_INTERVAL = ("roughness", "clearcoatRoughness", "metallic", "clearcoat", "opacity", "opacityThreshold")
NON_NEGATIVE_COLOURS = ("diffuseColor", "emissiveColor", "specularColor")


def clamp_preview_inputs(src: dict, label: str, warn) -> dict:
    """``src`` (input name -> :mod:`usd_io.materials.network` source) with out-of-range constants clamped."""
    out = dict(src)
    for name in UNIT_INTERVAL:
        c = out.get(name)
        if not isinstance(c, net.Const) or c.value is None:
            continue
        v = net.floats(c.value, 1, (np.nan,))[0]
        if np.isfinite(v) and not 0.0 <= v <= 1.0:
            clamped = float(np.clip(v, 0.0, 1.0))
            warn(f"{label}: {name} {v:g} is outside the UsdPreviewSurface range [0, 1] (clamped to {clamped:g})")
            out[name] = net.Const(clamped)
    for name in NON_NEGATIVE_COLOURS:
        c = out.get(name)
        if not isinstance(c, net.Const) or c.value is None:
            continue
        rgb = np.asarray(net.floats(c.value, 3, (0.0, 0.0, 0.0)))
        if np.all(np.isfinite(rgb)) and np.any(rgb < 0):
            clamped = tuple(float(x) for x in np.maximum(rgb, 0.0))
            warn(f"{label}: {name} {tuple(float(x) for x in rgb)} has negative channels (clamped to {clamped})")
            out[name] = net.Const(clamped)
    return out

"""Blender's render passes and the tracer's AOVs: one table (issue #31).

Each row is a tracer AOV (``tracer.settings.AOV_NAMES``) that Blender has a render pass for: the pass as
``RenderEngine.register_pass`` takes it (name, channels, channel ids, type) and the checkbox that asks for it (a
property of the view layer, of the view layer's Cycles settings, or of ``scene.whitted``). The engine registers the
passes (addon/engine.py), F12's settings ask the tracer for the AOVs (addon/export.py), the tile writer fills the
passes and the Passes panel draws the checkboxes (addon/ui.py), all from :data:`PASSES`.

    depth           Depth                  view layer: use_pass_z                 (Blender's Z: camera distance)
    normal          Normal                 view layer: use_pass_normal
    objectid        Object Index           view layer: use_pass_object_index      ("IndexOB" before Blender 5.0)
    shadow_catcher  Shadow Catcher         Cycles' view layer: use_pass_shadow_catcher (one checkbox for both
                                           engines: Cycles' own setting)
    sample_count    Debug Sample Count     Cycles' view layer: pass_debug_sample_count (as Cycles writes it: the
                                           samples a pixel took divided by the most it may take, N×N)
    direct, reflection, transmission, raydepth
                    Whitted Direct, ...    scene.whitted.ray_type_passes (tracer.settings.RAY_TYPE_AOVS)
    denoising_albedo, denoising_normal
                    Denoising Albedo,      Cycles' view layer: denoising_store_passes ("Denoising Data", one
                    Denoising Normal       checkbox for both engines: Cycles' own setting)

``albedo`` has no Blender pass here (Blender's Diffuse Color is Cycles' own split; the CLI writes it).
"""

from __future__ import annotations

from typing import NamedTuple

import bpy

from .bundled import tracer


class Pass(NamedTuple):
    aov: str  #: the tracer AOV
    name: str  #: Blender's pass name
    channels: int
    chan_id: str
    type: str
    owner: str  #: who holds the checkbox: "layer" (the ViewLayer), "cycles" (view_layer.cycles), "whitted" (scene.whitted)
    prop: str  #: the checkbox's property
    label: str | None = None  #: its label in Whitted's Passes panel (None: not drawn there)

    @property
    def register_args(self) -> tuple:
        """(name, channels, chan_id, type): ``RenderEngine.register_pass``'s arguments after scene and layer."""
        return self.name, self.channels, self.chan_id, self.type


#: Blender 5.0 names the object index pass "Object Index" (Cycles writes it so); older versions "IndexOB".
OBJECT_INDEX = "Object Index" if bpy.app.version >= (5, 0, 0) else "IndexOB"
_RAY_TYPE = {"direct": ("Whitted Direct", 3, "RGB", "COLOR"), "reflection": ("Whitted Reflection", 3, "RGB", "COLOR"),
             "transmission": ("Whitted Transmission", 3, "RGB", "COLOR"),
             "raydepth": ("Whitted Ray Depth", 1, "X", "VALUE")}

#: Every pass, in the order they are registered and asked for.
PASSES: tuple = (
    Pass("depth", "Depth", 1, "Z", "VALUE", "layer", "use_pass_z", "Depth"),
    Pass("normal", "Normal", 3, "XYZ", "VECTOR", "layer", "use_pass_normal", "Normal"),
    Pass("objectid", OBJECT_INDEX, 1, "X", "VALUE", "layer", "use_pass_object_index", "Object Index"),
    Pass("shadow_catcher", "Shadow Catcher", 3, "RGB", "COLOR", "cycles", "use_pass_shadow_catcher"),
    Pass("sample_count", "Debug Sample Count", 1, "X", "VALUE", "cycles", "pass_debug_sample_count", "Sample Count"),
    Pass("denoising_albedo", "Denoising Albedo", 3, "RGB", "COLOR", "cycles", "denoising_store_passes",
         "Denoising Data"),
    Pass("denoising_normal", "Denoising Normal", 3, "XYZ", "VECTOR", "cycles", "denoising_store_passes",
         "Denoising Data"),
) + tuple(Pass(aov, *_RAY_TYPE[aov], "whitted", "ray_type_passes", "") for aov in tracer.settings.RAY_TYPE_AOVS)
#: {tracer AOV: its Pass}.
BY_AOV = {p.aov: p for p in PASSES}


def _holder(p: Pass, view_layer, props):
    if p.owner == "layer":
        return view_layer
    if p.owner == "cycles":
        return getattr(view_layer, "cycles", None)  # Cycles' view-layer settings (absent without Cycles)
    return props


def asked(view_layer, props) -> tuple:
    """The passes the view layer (and ``scene.whitted``, ``props``; None: unregistered) ask for, in order."""
    return tuple(p for p in PASSES
                 if _holder(p, view_layer, props) is not None and bool(getattr(_holder(p, view_layer, props), p.prop,
                                                                                False)))


def checkboxes(view_layer, props) -> list:
    """(holder, property, label) of each checkbox Whitted's Passes panel draws, once each (label "" = the
    property's own name)."""
    out, seen = [], set()
    for p in PASSES:
        if p.label is None or (p.owner, p.prop) in seen or _holder(p, view_layer, props) is None:
            continue
        seen.add((p.owner, p.prop))
        out.append((_holder(p, view_layer, props), p.prop, p.label))
    return out

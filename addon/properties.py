"""Scene settings of the Whitted engine: ``scene.whitted`` (a PointerProperty), shown in the Render properties.

Every property is made from the :class:`tracer.RenderSettings` field of the same name (its ``Setting``'s
``blender`` label, help, bounds, choices and ``ui`` options; tracer/settings.py): nothing about a setting is
written here, so a setting added there with a ``blender`` label appears in the add-on by itself.
:func:`settings_kwargs` reads them back (``none_as``: the stored value meaning None, e.g. Threads 0 = all cores).
A setting with a ``toggle`` also gets its checkbox (Noise Threshold: ``use_adaptive_sampling``, as Cycles'), off
by default; unticked, the setting is its field's default (0: adaptive sampling off).
"""

from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty

from .bundled import tracer

SETTINGS = tracer.settings.SETTINGS


def blender_property(name: str):
    """The ``bpy.props`` property of RenderSettings field ``name`` (which has a ``blender`` label)."""
    s = SETTINGS[name]
    default = tracer.settings.default_of(name) if s.blender_default is None else s.blender_default
    value = s.none_as if default is None else default
    if s.toggle:  # the value the property holds when its checkbox is ticked (the checkbox says whether it applies)
        value = s.toggle[2]
    desc = s.help[:1].upper() + s.help[1:] + (f" ({s.unit})" if s.unit else "")
    opts = dict(s.ui)
    if isinstance(value, bool):
        return BoolProperty(name=s.blender, description=desc, default=value)
    if s.choices:
        return EnumProperty(name=s.blender, description=desc, default=value,
                            items=[(c, c.title(), f"{s.blender}: {c}") for c in s.choices])
    lo = s.lo if s.none_as is None or s.lo is None else min(s.lo, s.none_as)
    if name in tracer.settings.INT_FIELDS:
        return IntProperty(name=s.blender, description=desc, default=value, min=int(lo), **opts)
    return FloatProperty(name=s.blender, description=desc, default=value, min=float(lo), **opts)


def settings_kwargs(props) -> dict:
    """RenderSettings keyword arguments of the scene's ``scene.whitted`` properties."""
    out = {}
    for name, s in SETTINGS.items():
        if s.blender is None:
            continue
        v = getattr(props, name)
        if s.toggle and not getattr(props, s.toggle[0]):
            v = tracer.settings.default_of(name)
        out[name] = None if s.none_as is not None and v == s.none_as else v
    return out


def toggle_property(name: str):
    """The checkbox of RenderSettings field ``name``'s ``toggle`` (off: the field's default)."""
    s = SETTINGS[name]
    return BoolProperty(name=s.toggle[1], default=False, description=f"Use {s.toggle[1]}: " + s.help)


#: Add-on properties that are not render settings: the ray-type passes (which AOVs the view layer gets), and the
#: viewport's denoising (Cycles' Sampling > Viewport > Denoise and its Start Sample: off by default, as in Cycles;
#: addon/viewport.py).
EXTRA = {"ray_type_passes": BoolProperty(
    name="Ray-Type Passes", description="Passes Whitted Direct / Reflection / Transmission (the beauty split by "
    "each path's first secondary ray; they sum to Combined) and Whitted Ray Depth (deepest ray per pixel)"),
    "preview_denoise": BoolProperty(
        name="Viewport Denoise", default=False,
        description="Denoise the viewport's passes with Open Image Denoise (guided by the albedo) once they have "
        "the Start Sample's samples per pixel"),
    "preview_denoise_start": IntProperty(
        name="Start Sample", default=1, min=1, soft_max=9,
        description="Samples per pixel a viewport pass has before it is denoised (the passes have 1, 4 and 9)")}

WhittedSceneSettings = type("WhittedSceneSettings", (bpy.types.PropertyGroup,), {
    "__annotations__": {**{n: blender_property(n) for n, s in SETTINGS.items() if s.blender},
                        **{s.toggle[0]: toggle_property(n) for n, s in SETTINGS.items() if s.blender and s.toggle},
                        **EXTRA},
    "__doc__": "Whitted's render settings (one per tracer.RenderSettings field with a Blender label)."})


def settings_of(scene) -> "WhittedSceneSettings | None":
    """The scene's Whitted settings, or None where the property group is not registered."""
    return getattr(scene, "whitted", None)


def register():
    bpy.utils.register_class(WhittedSceneSettings)
    bpy.types.Scene.whitted = PointerProperty(type=WhittedSceneSettings)


def unregister():
    if hasattr(bpy.types.Scene, "whitted"):
        del bpy.types.Scene.whitted
    bpy.utils.unregister_class(WhittedSceneSettings)

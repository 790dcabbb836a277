"""Scene settings of the Whitted engine: ``scene.whitted`` (a PointerProperty), shown in the Render properties."""

from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty


class WhittedSceneSettings(bpy.types.PropertyGroup):
    samples: IntProperty(
        name="Samples", description="N for N×N stratified anti-aliasing samples per pixel (box filter)",
        default=2, min=1, soft_max=8, max=64)
    max_depth: IntProperty(
        name="Max Depth", description="Maximum recursion depth of reflection and transmission rays",
        default=8, min=0, max=64)
    shading: EnumProperty(
        name="Shading", description="Local model each light sample is weighted by",
        items=[("principled", "Principled", "Cycles' Principled BSDF: diffuse + GGX specular (matches Cycles)"),
               ("classic", "Classic", "The notes' Lambert + Blinn-Phong")], default="principled")
    max_transparent: IntProperty(
        name="Transparent Max Bounces", description="Alpha < 1 and cut-out surfaces a ray may pass through (not "
        "counted in Max Depth), as Cycles' Transparent bounces", default=8, min=0, max=1024)
    epsilon: FloatProperty(
        name="Epsilon", description="Offset of spawned rays; 0 = automatic (5e-5 of the scene size)",
        default=0.0, min=0.0, soft_max=0.01, precision=6, subtype="DISTANCE")
    fresnel: BoolProperty(
        name="Fresnel", description="Dielectric Fresnel weighting of glass (as Cycles); off = the classic fixed "
        "weights of Whitted's notes", default=True)
    shadows: BoolProperty(name="Shadows", description="Cast shadow rays towards the lights", default=True)
    threads: IntProperty(name="Threads", description="Worker threads; 0 = all cores", default=0, min=0, max=1024)
    light_samples: IntProperty(
        name="Light Samples", description="Samples per light with an extent (point radius, sun angle, area "
        "lights); rounded to N×N", default=16, min=1, max=1024)
    sky_samples: IntProperty(
        name="Sky Visibility Samples", description="Hemisphere shadow rays weighting the world (ambient) light "
        "by sky visibility, as Cycles does; 0 = Whitted's unoccluded ambient term", default=0, min=0, max=1024)
    terminal_rays: BoolProperty(
        name="Terminal Bounce", description="Trace one more bounce past Max Depth that collects only the world "
        "colour and emission, as Cycles' last bounce does; off = the notes' hard cut-off", default=False)
    ray_type_passes: BoolProperty(
        name="Ray-Type Passes", description="Passes Whitted Direct / Reflection / Transmission (the beauty split by "
        "each path's first secondary ray; they sum to Combined) and Whitted Ray Depth (deepest ray per pixel)",
        default=False)


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

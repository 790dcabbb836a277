"""The Whitted settings panel, and Blender's standard panels opened to the engine through ``COMPAT_ENGINES``."""

from __future__ import annotations

import bpy

from . import passes
from .bundled import tracer

ENGINE = "WHITTED"
SETTINGS = tracer.settings.SETTINGS

#: Standard panels that make sense for a Whitted render: output and format, colour management, camera, light,
#: material and world surfaces (the EEVEE ones draw the node inputs, so users edit the Principled BSDF as usual).
STANDARD_PANELS = (
    "RENDER_PT_format", "RENDER_PT_format_presets", "RENDER_PT_frame_range", "RENDER_PT_color_management",
    "RENDER_PT_color_management_curves", "RENDER_PT_color_management_display_settings",
    "RENDER_PT_color_management_white_balance", "RENDER_PT_output", "RENDER_PT_encoding",
    "RENDER_PT_post_processing", "RENDER_PT_stamp",
    "DATA_PT_context_camera", "DATA_PT_lens", "DATA_PT_camera", "DATA_PT_camera_display",
    "DATA_PT_context_light", "DATA_PT_light", "DATA_PT_EEVEE_light", "DATA_PT_EEVEE_light_distance",
    "DATA_PT_spot", "DATA_PT_preview",
    "MATERIAL_PT_preview", "EEVEE_MATERIAL_PT_context_material", "EEVEE_MATERIAL_PT_surface",
    "MATERIAL_PT_viewport",
    "WORLD_PT_context_world", "EEVEE_WORLD_PT_surface", "WORLD_PT_viewport_display",
    "OBJECT_PT_relations",
    "DATA_PT_context_mesh", "DATA_PT_normals", "DATA_PT_uv_texture", "DATA_PT_vertex_groups",
    "VIEWLAYER_PT_layer",
)


def compat_panels():
    """The standard panel classes above that exist in this Blender and carry ``COMPAT_ENGINES``."""
    out = []
    for name in STANDARD_PANELS:
        cls = getattr(bpy.types, name, None)
        if cls is not None and hasattr(cls, "COMPAT_ENGINES"):
            out.append(cls)
    return out


def draw_settings(layout, props, panel: str) -> None:
    """Every ``scene.whitted`` property whose setting is drawn under ``panel`` (``Setting.panel``,
    tracer/settings.py), in field order: a new setting shows up by itself. A setting with a ``toggle`` is drawn
    as Cycles draws Noise Threshold (checkbox, then the value, greyed out when unticked); one ``active_with``
    such a setting is greyed out with it."""
    for name, s in SETTINGS.items():
        if s.blender is None or s.panel != panel:
            continue
        if s.toggle:
            row = layout.row(heading=s.toggle[1])
            row.prop(props, s.toggle[0], text="")
            sub = row.row()
            sub.active = getattr(props, s.toggle[0])
            sub.prop(props, name, text="")
        elif s.active_with:
            row = layout.row()
            row.active = getattr(props, SETTINGS[s.active_with].toggle[0])
            row.prop(props, name)
        else:
            layout.prop(props, name)


class _Panel:
    """What every Whitted panel shares: Render Properties, shown for the Whitted engine, property split."""

    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES

    def draw(self, context):
        self.layout.use_property_split = True
        self.layout.use_property_decorate = False
        self.draw_content(context, self.layout)


class WHITTED_PT_render(_Panel, bpy.types.Panel):
    bl_label = "Whitted"

    def draw_content(self, context, layout):
        props = context.scene.whitted
        for heading in ("Sampling", "Rays"):
            draw_settings(layout.column(heading=heading), props, heading)
        col = layout.column(heading="Denoise")  # Cycles' Render and Viewport Denoise checkboxes
        draw_settings(col, props, "Denoise")
        col.prop(props, "preview_denoise", text="Viewport")
        sub = col.column()
        sub.active = props.preview_denoise
        sub.prop(props, "preview_denoise_start")
        col = layout.column(heading="Film")
        col.prop(context.scene.render, "film_transparent", text="Transparent")
        col = layout.column(heading="Passes")
        for holder, prop, label in passes.checkboxes(context.view_layer, props):  # addon/passes.py
            if label:
                col.prop(holder, prop, text=label)
            else:
                col.prop(holder, prop)


class WHITTED_PT_performance(_Panel, bpy.types.Panel):
    """Render Properties → Performance, laid out as Cycles' (Threads; Final Render → Persistent Data)."""

    bl_label = "Performance"
    bl_options = {"DEFAULT_CLOSED"}

    def draw_content(self, context, layout):
        draw_settings(layout, context.scene.whitted, "Performance")


class WHITTED_PT_performance_final_render(_Panel, bpy.types.Panel):
    """Persistent Data (``RenderSettings.use_persistent_data``, Blender's own setting, as Cycles shows it): keep
    the prepared scene between F12 renders and sync only what changed (addon/sync.py)."""

    bl_label = "Final Render"
    bl_parent_id = "WHITTED_PT_performance"

    def draw_content(self, context, layout):
        layout.column().prop(context.scene.render, "use_persistent_data", text="Persistent Data")


#: The headings of the panels above, where each Blender setting must be drawn.
HEADINGS = ("Sampling", "Rays", "Denoise", "Performance")

PANELS = (WHITTED_PT_render, WHITTED_PT_performance, WHITTED_PT_performance_final_render)
_added: list = []


def register():
    for cls in PANELS:
        bpy.utils.register_class(cls)
    for cls in compat_panels():
        if ENGINE not in cls.COMPAT_ENGINES:
            cls.COMPAT_ENGINES.add(ENGINE)
            _added.append(cls)


def unregister():
    for cls in _added:
        cls.COMPAT_ENGINES.discard(ENGINE)
    _added.clear()
    for cls in reversed(PANELS):
        bpy.utils.unregister_class(cls)

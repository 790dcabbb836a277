"""The Whitted settings panel, and Blender's standard panels opened to the engine through ``COMPAT_ENGINES``."""

from __future__ import annotations

import bpy

ENGINE = "WHITTED"

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


class WHITTED_PT_render(bpy.types.Panel):
    bl_label = "Whitted"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        props = context.scene.whitted
        col = layout.column(heading="Sampling")
        col.prop(props, "samples", text="Samples (N×N)")
        col.prop(props, "light_samples")
        col.prop(props, "sky_samples")
        col.prop(props, "terminal_rays")
        col = layout.column(heading="Rays")
        col.prop(props, "max_depth")
        col.prop(props, "max_transparent")
        col.prop(props, "shading")
        col.prop(props, "epsilon")
        col.prop(props, "fresnel")
        col.prop(props, "shadows")
        col = layout.column(heading="Film")
        col.prop(context.scene.render, "film_transparent", text="Transparent")
        col = layout.column(heading="Passes")
        layer = context.view_layer
        col.prop(layer, "use_pass_z", text="Depth")
        col.prop(layer, "use_pass_normal", text="Normal")
        col.prop(layer, "use_pass_object_index", text="Object Index")
        col.prop(props, "ray_type_passes")


class WHITTED_PT_performance(bpy.types.Panel):
    """Render Properties → Performance, laid out as Cycles' (Threads; Final Render → Persistent Data)."""

    bl_label = "Performance"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    bl_options = {"DEFAULT_CLOSED"}
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.prop(context.scene.whitted, "threads")


class WHITTED_PT_performance_final_render(bpy.types.Panel):
    """Persistent Data (``RenderSettings.use_persistent_data``, Blender's own setting, as Cycles shows it): keep
    the prepared scene between F12 renders and sync only what changed (addon/sync.py)."""

    bl_label = "Final Render"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    bl_parent_id = "WHITTED_PT_performance"
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.column().prop(context.scene.render, "use_persistent_data", text="Persistent Data")


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

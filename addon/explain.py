"""Explain Pixel in Blender: the ray tree of one pixel as curve objects in a "Whitted rays" collection.

The operator exports the evaluated scene as F12 does, traces the pixel's eye samples with the tracer's
``explain_pixel`` (the same samples F12 traces), adds one curve object per ray type (coloured as in
``whitted explain --png``), and puts the text tree in the report and in a Text datablock "Whitted ray tree".
"Clear Rays" removes the collection in one click.
"""

from __future__ import annotations

import bpy
import numpy as np

from . import export
from .export import tracer

COLLECTION = "Whitted rays"
TEXT = "Whitted ray tree"
#: Bevel radius of the ray curves, as a fraction of the scene's size.
BEVEL_FRACTION = 0.002


def cursor_pixel(bpy_scene, point) -> tuple[int, int]:
    """The pixel (x, y), top-left origin, where the scene camera sees the world point ``point``."""
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector

    w, h = export.render_size(bpy_scene)
    co = world_to_camera_view(bpy_scene, bpy_scene.camera, Vector(point))
    return int(np.floor(co.x * w)), int(np.floor((1.0 - co.y) * h))


def explain(context, x: int, y: int):
    """Export the scene, explain pixel (x, y); returns (explanation, tracer scene)."""
    depsgraph = context.evaluated_depsgraph_get()
    bpy_scene = depsgraph.scene
    settings = export.settings_from_scene(bpy_scene, view_layer=depsgraph.view_layer).with_(region=None, aovs=())
    if not (0 <= x < settings.width and 0 <= y < settings.height):
        raise ValueError(f"pixel ({x}, {y}) is outside the {settings.width}x{settings.height} render")
    clear_rays()  # earlier ray curves are not part of the scene being explained
    depsgraph = context.evaluated_depsgraph_get()
    scene, _warnings = export.scene_from_depsgraph(depsgraph, width=settings.width, height=settings.height)
    return tracer.explain.explain_pixel(scene, settings, x, y), scene


def clear_rays() -> None:
    coll = bpy.data.collections.get(COLLECTION)
    if coll is None:
        return
    for obj in list(coll.objects):
        data = obj.data
        bpy.data.objects.remove(obj, do_unlink=True)
        if data is not None and data.users == 0:
            bpy.data.curves.remove(data)
    bpy.data.collections.remove(coll)


def add_ray_objects(context, ex, scene) -> list:
    """One curve object per ray type holding a two-point poly spline per ray; returns the objects."""
    clear_rays()
    coll = bpy.data.collections.new(COLLECTION)
    coll.hide_render = True  # drawn in the viewport, never rendered (the export skips them too: RAYS_PROPERTY)
    context.scene.collection.children.link(coll)
    a, b, rays = tracer.explain.segments(ex, scene)
    objs = []
    for kind in tracer.explain.RAY_KINDS:
        idx = [i for i, r in enumerate(rays) if r.type == kind]
        if not idx:
            continue
        curve = bpy.data.curves.new(f"Whitted {kind} rays", "CURVE")
        curve.dimensions = "3D"
        curve.bevel_depth = max(scene.diagonal, 1e-3) * BEVEL_FRACTION
        for i in idx:
            spline = curve.splines.new("POLY")
            spline.points.add(1)
            spline.points.foreach_set("co", np.concatenate([np.append(a[i], 1.0), np.append(b[i], 1.0)]))
        mat = _type_material(kind)
        curve.materials.append(mat)
        obj = bpy.data.objects.new(f"Whitted {kind} rays", curve)
        obj.color = (*tracer.explain.TYPE_COLORS[kind], 1.0)
        obj["whitted_ray_ids"] = [int(rays[i].id) for i in idx]
        obj[export.RAYS_PROPERTY] = True
        coll.objects.link(obj)
        objs.append(obj)
    return objs


def _type_material(kind):
    name = f"Whitted {kind} ray"
    mat = bpy.data.materials.get(name) or bpy.data.materials.new(name)
    colour = (*tracer.explain.TYPE_COLORS[kind], 1.0)
    mat.diffuse_color = colour  # the viewport's solid mode
    return mat


class WHITTED_OT_explain_pixel(bpy.types.Operator):
    """Trace one pixel and show every ray that made it as curves in the "Whitted rays" collection"""

    bl_idname = "whitted.explain_pixel"
    bl_label = "Explain Pixel"
    bl_options = {"REGISTER", "UNDO"}

    x: bpy.props.IntProperty(name="X", min=0, description="Pixel column, from the left")
    y: bpy.props.IntProperty(name="Y", min=0, description="Pixel row, from the top")
    use_cursor: bpy.props.BoolProperty(name="At 3D Cursor", default=False,
                                       description="Explain the pixel where the scene camera sees the 3D cursor")

    @classmethod
    def poll(cls, context):
        return context.scene is not None and context.scene.camera is not None

    def execute(self, context):
        x, y = self.x, self.y
        if self.use_cursor:
            x, y = cursor_pixel(context.scene, context.scene.cursor.location)
        try:
            ex, scene = explain(context, x, y)
        except ValueError as exc:
            self.report({"ERROR"}, f"Whitted: {exc}")
            return {"CANCELLED"}
        add_ray_objects(context, ex, scene)
        text = tracer.explain.format_tree(ex)
        block = bpy.data.texts.get(TEXT) or bpy.data.texts.new(TEXT)
        block.from_string(text)
        self.report({"INFO"}, text)
        return {"FINISHED"}


class WHITTED_OT_clear_rays(bpy.types.Operator):
    """Remove the "Whitted rays" collection made by Explain Pixel"""

    bl_idname = "whitted.clear_rays"
    bl_label = "Clear Rays"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        clear_rays()
        return {"FINISHED"}


class WHITTED_PT_explain(bpy.types.Panel):
    bl_label = "Explain Pixel"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    bl_parent_id = "WHITTED_PT_render"
    bl_options = {"DEFAULT_CLOSED"}
    COMPAT_ENGINES = {"WHITTED"}

    def draw(self, context):
        layout = self.layout
        wm = context.window_manager
        row = layout.row(align=True)
        row.prop(wm, "whitted_explain_x", text="X")
        row.prop(wm, "whitted_explain_y", text="Y")
        op = layout.operator(WHITTED_OT_explain_pixel.bl_idname, icon="LIGHT_SUN")
        op.x, op.y = wm.whitted_explain_x, wm.whitted_explain_y
        op = layout.operator(WHITTED_OT_explain_pixel.bl_idname, text="Explain Pixel at 3D Cursor",
                             icon="PIVOT_CURSOR")
        op.use_cursor = True
        layout.operator(WHITTED_OT_clear_rays.bl_idname, icon="TRASH")


_CLASSES = (WHITTED_OT_explain_pixel, WHITTED_OT_clear_rays, WHITTED_PT_explain)


def register():
    bpy.types.WindowManager.whitted_explain_x = bpy.props.IntProperty(name="X", min=0)
    bpy.types.WindowManager.whitted_explain_y = bpy.props.IntProperty(name="Y", min=0)
    for cls in _CLASSES:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
    del bpy.types.WindowManager.whitted_explain_x
    del bpy.types.WindowManager.whitted_explain_y

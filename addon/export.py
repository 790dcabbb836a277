"""Blender's evaluated depsgraph -> ``tracer.Scene``: the add-on's core, pure (no render engine needed).

    scene, warnings = scene_from_depsgraph(bpy.context.evaluated_depsgraph_get())
    image = tracer.render(scene, settings_from_scene(bpy.context.scene))

What is read (everything from the *evaluated* depsgraph, so modifiers, geometry nodes, collection instances and
particles are included):

- Geometry: every visible instance of ``depsgraph.object_instances`` whose object has a mesh (meshes after
  modifiers, curves, text, metaballs, surfaces through ``Object.to_mesh``), as loop triangles with split/custom
  normals (``Mesh.corner_normals``), the active UV map and per-face materials; ``instance.matrix_world`` places it.
  Each instance is its own object (object id); the tracer's ``objectid`` AOV maps to Blender's Object Index
  through ``scene.object_pass_indices``. Many instances of one mesh (Geometry Nodes, collection instances,
  particles) share it: one object-space prototype, and a ``tracer.Instances`` row per instance (add_objects).
- Camera: Blender's exact camera model (DESIGN.md, "Blender's camera model"): sensor fit, lens, shift,
  orthographic scale, clip start/end.
- Lights, in Blender's units: point P W -> intensity P/(4π)·colour, radius = ``shadow_soft_size``; spot: the same
  with cone half-angle ``spot_size/2`` and ``spot_blend``; sun strength S -> irradiance S·colour, ``angle``; area
  power P -> radiance P/(π·A)·colour (A in world units, emitting along the light's -Z; its Spread as Cycles' soft box;
  a Portal is skipped: it only guides Cycles' world sampling). ``2^exposure`` multiplies; a light's own node tree
  (Emission Color × Strength, a Light Falloff's Quadratic as its Strength) multiplies its colour.
- Ray visibility and linking (:func:`links_from_blender`): each object's ``visible_camera`` / ``visible_glossy`` /
  ``visible_transmission`` / ``visible_shadow`` as ``scene.object_visibility``; each light's
  ``light_linking.receiver_collection`` / ``blocker_collection`` (include / exclude states), ``use_shadow`` and
  ``visible_diffuse`` / ``visible_glossy`` / ``visible_camera`` / ``visible_transmission`` as ``scene.light_links``
  (tracer/lights/linking.py): an area light, a point or spot light with a radius and a sun with an angle are seen
  in mirrors (glossy) and through glass (transmission), and by the camera only with its Camera visibility on, as
  Cycles shows them (tracer.lights.emitters.lamp_hit).
- World: :func:`addon.world.world_from_blender` (Background colour × strength, an Environment Texture as
  ``tracer.Environment``, anything else baked to a lat-long image by Cycles).
- Materials: node trees translated by :mod:`addon.shader_tree` into the tracer's shader graph, compiled into rows
  by :mod:`addon.model` (the node table is in docs/addon.md); a Volume output as a homogeneous medium
  (:mod:`addon.volume`, ``scene.material_volumes``).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .bundled import tracer, tracer_module

from . import passes
from .model import Corners, MaterialWriter
from .motion import apply_motion, sample_motion
from .nodes import image_rgba
from .world import world_from_blender

#: Object types that become triangles through ``Object.to_mesh``.
GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "META", "FONT"}


# ---------------------------------------------------------------------------------------------------- materials
def image_pixels(image) -> np.ndarray:
    """(H, W, 3) scene-linear float32 pixels of a Blender image, top row first (see :func:`nodes.image_rgba`)."""
    return np.ascontiguousarray(image_rgba(image)[..., :3])


# ---------------------------------------------------------------------------------------------------- geometry
def mesh_arrays(mesh, attributes=()) -> dict:
    """Object-space triangle arrays of a Blender mesh: vertices (V, 3), triangles (T, 3), per-corner normals
    (T, 3, 3) from ``corner_normals`` (split/custom normals, flat faces included), per-corner UVs (T, 3, 2) of
    every UV map by name (``uv_layers``; ``uv_default`` = the active render map, ``uvs`` its UVs or None),
    per-corner RGBA (T, 3, 4) of every point- or corner-domain Color Attribute (``colors``; ``color_default`` =
    the render colour), per-triangle material slot indices (T,). All numpy (``foreach_get``), no Python loop
    over vertices.

    ``attributes``: names a material reads (Attribute node) that are not Color Attributes: any generic attribute
    of that name, on any domain and of any numeric type, is read into ``colors`` too, as Cycles reads it
    (:func:`attribute_corners`); ``attributes_read`` records the names asked for."""
    mesh.calc_loop_triangles()
    nv, nt = len(mesh.vertices), len(mesh.loop_triangles)
    verts = np.empty(nv * 3, np.float32)
    mesh.vertices.foreach_get("co", verts)
    tris = np.empty(nt * 3, np.int32)
    mesh.loop_triangles.foreach_get("vertices", tris)
    loops = np.empty(nt * 3, np.int32)
    mesh.loop_triangles.foreach_get("loops", loops)
    mat = np.empty(nt, np.int32)
    mesh.loop_triangles.foreach_get("material_index", mat)
    nl = len(mesh.loops)
    if hasattr(mesh, "corner_normals"):  # Blender 4.1+
        cn = np.empty(len(mesh.corner_normals) * 3, np.float32)
        mesh.corner_normals.foreach_get("vector", cn)
    else:  # pragma: no cover - Blender < 4.1
        mesh.calc_normals_split()
        cn = np.empty(nl * 3, np.float32)
        mesh.loops.foreach_get("normal", cn)
    normals = cn.reshape(-1, 3)[loops].reshape(nt, 3, 3)
    layers, default = {}, None
    if nl:
        for layer in mesh.uv_layers:
            uv = np.empty(nl * 2, np.float32)
            layer.data.foreach_get("uv", uv)
            layers[layer.name] = uv.reshape(-1, 2)[loops].reshape(nt, 3, 2)
            if layer.active_render or default is None:
                default = layer.name
    colors, color_default = {}, None
    attrs = getattr(mesh, "color_attributes", ())
    for attr in attrs:
        if attr.domain not in ("POINT", "CORNER") or attr.data_type not in ("FLOAT_COLOR", "BYTE_COLOR"):
            continue
        c = np.empty(len(attr.data) * 4, np.float32)
        attr.data.foreach_get("color", c)  # scene linear for both data types
        c = c.reshape(-1, 4)
        colors[attr.name] = (c[tris] if attr.domain == "POINT" else c[loops].reshape(-1, 4)).reshape(nt, 3, 4)
    if colors:
        render = getattr(attrs, "default_color_name", "") or getattr(attrs, "active_color_name", "")
        color_default = render if render in colors else next(iter(colors))
    tri_faces = None
    for name in attributes:
        if not name or name in colors or name in layers:
            continue
        attr = getattr(mesh, "attributes", {}).get(name)
        if attr is None:
            continue
        if tri_faces is None:
            tri_faces = np.empty(nt, np.int32)
            mesh.loop_triangles.foreach_get("polygon_index", tri_faces)
        c = attribute_corners(mesh, attr, tris, loops, tri_faces)
        if c is not None:
            colors[name] = c
    return {"vertices": verts.reshape(nv, 3), "triangles": tris.reshape(nt, 3), "normals": normals,
            "uvs": layers.get(default), "uv_layers": layers, "uv_default": default, "colors": colors,
            "color_default": color_default, "material_index": mat, "attributes_read": frozenset(attributes)}


#: Generic attribute types -> (the ``foreach_get`` property, components): what an Attribute node can read.
ATTRIBUTE_TYPES = {"FLOAT": ("value", 1, np.float32), "INT": ("value", 1, np.int32), "INT8": ("value", 1, np.int32),
                   "BOOLEAN": ("value", 1, bool), "FLOAT2": ("vector", 2, np.float32),
                   "INT32_2D": ("value", 2, np.int32), "FLOAT_VECTOR": ("vector", 3, np.float32),
                   "FLOAT_COLOR": ("color", 4, np.float32), "BYTE_COLOR": ("color", 4, np.float32),
                   "QUATERNION": ("value", 4, np.float32)}


def attribute_corners(mesh, attr, tris: np.ndarray, loops: np.ndarray, tri_faces: np.ndarray):
    """Per-corner RGBA (T, 3, 4) of a generic attribute as Cycles' Attribute node reads it (measured: Blender's
    sync): a float f as (f, f, f), a 2D vector as (x, y, 0), a 3D vector as it is, a colour with its alpha (else 1);
    point, corner and face domains as they are, an edge-domain value averaged over each vertex's edges (Blender's
    edge -> point interpolation). None for a type or domain that has no such reading."""
    kind = ATTRIBUTE_TYPES.get(attr.data_type)
    if kind is None or attr.domain not in ("POINT", "EDGE", "FACE", "CORNER"):
        return None
    prop, k, dtype = kind
    n = len(attr.data)
    raw = np.empty(n * k, dtype)
    try:
        attr.data.foreach_get(prop, raw)
    except (TypeError, RuntimeError):
        try:  # a bpy whose buffer checks refuse the dtype: the slow, sequence path
            raw = np.asarray([getattr(d, prop) for d in attr.data], np.float64).reshape(-1)
        except (TypeError, AttributeError):
            return None
    raw = raw.reshape(n, k).astype(np.float32)
    rgba = np.zeros((n, 4), np.float32)
    rgba[:, 3] = 1.0
    if k == 1:
        rgba[:, :3] = raw
    elif k == 4 and prop == "color":
        rgba[:] = raw
    else:
        rgba[:, :min(k, 3)] = raw[:, :3]
    nt = len(tri_faces)
    if attr.domain == "POINT":
        out = rgba[tris]
    elif attr.domain == "CORNER":
        out = rgba[loops]
    elif attr.domain == "FACE":
        out = np.repeat(rgba[tri_faces], 3, axis=0)
    else:  # EDGE: the mean over the edges that meet at each vertex
        ev = np.empty(len(mesh.edges) * 2, np.int32)
        mesh.edges.foreach_get("vertices", ev)
        ev = ev.reshape(-1, 2)
        acc = np.zeros((len(mesh.vertices), 4), np.float64)
        cnt = np.zeros(len(mesh.vertices), np.float64)
        for side in (0, 1):
            np.add.at(acc, ev[:, side], rgba)
            np.add.at(cnt, ev[:, side], 1.0)
        out = (acc / np.maximum(cnt, 1.0)[:, None]).astype(np.float32)[tris]
    return np.ascontiguousarray(out.reshape(nt, 3, 4), np.float32)


def _object_mesh_arrays(obj, depsgraph, attributes=()):
    mesh = obj.to_mesh(preserve_all_data_layers=False, depsgraph=depsgraph)
    try:
        return None if mesh is None else mesh_arrays(mesh, attributes)
    finally:
        obj.to_mesh_clear()


# ---------------------------------------------------------------------------------------------------- camera
#: Blender's sensor fit -> the tracer's aperture fit policy (tracer.camera.fit_apertures) and the sensor side used.
SENSOR_FIT = {"AUTO": ("larger", "sensor_width"), "HORIZONTAL": ("horizontal", "sensor_width"),
              "VERTICAL": ("vertical", "sensor_height")}


def camera_from_blender(cam_obj, width: int, height: int, pixel_aspect: float = 1.0) -> "tracer.Camera":
    """A tracer camera reproducing Blender's projection of ``cam_obj`` on a width × height image.

    E = sensor/lens (perspective) or ortho_scale (orthographic), the window on the fitted side (Blender's sensor
    fit as :func:`tracer.camera.fit_apertures`' policy, :data:`SENSOR_FIT`; the aspect includes the pixel aspect);
    the shift moves the window by shift·E. In tracer terms (focal length f = lens for perspective, 1 for
    orthographic): apertures W·f, H·f, offsets shift·E·f.
    """
    cam = cam_obj.data
    policy, side = SENSOR_FIT[cam.sensor_fit]
    if cam.type == "ORTHO":
        e, f, ortho = cam.ortho_scale, 1.0, True
    elif cam.type == "PERSP":
        e, f, ortho = getattr(cam, side) / cam.lens, cam.lens, False
    else:
        raise ValueError(f"camera {cam_obj.name!r}: {cam.type} cameras are not supported (perspective and "
                         "orthographic only)")
    w_ap, h_ap = tracer.fit_apertures(e, e, width * pixel_aspect, height, policy)
    m = np.array(cam_obj.matrix_world, dtype=np.float64)
    m[:3, :3] /= np.linalg.norm(m[:3, :3], axis=0, keepdims=True)  # Blender ignores the camera's scale
    return window_camera(m, ortho, f, (w_ap, h_ap), (cam.shift_x * e, cam.shift_y * e), cam.clip_start,
                         cam.clip_end, lens=depth_of_field(cam, m))


def camera_dof_on(cam) -> bool:
    """Blender's Camera > Depth of Field checkbox (``cam``: camera data): RenderSettings.depth_of_field of a
    render through it (:func:`settings_from_scene`). Camera-shaped stand-ins without ``dof``: off."""
    dof = getattr(cam, "dof", None)
    return bool(dof is not None and dof.use_dof)


def motion_blur_on(bpy_scene) -> bool:
    """Blender's Render > Motion Blur checkbox: RenderSettings.motion_blur (:func:`settings_from_scene`)."""
    return bool(getattr(bpy_scene.render, "use_motion_blur", False))


def depth_of_field(cam, m: np.ndarray) -> dict:
    """The thin lens of a Blender camera with Depth of Field on (``tracer.Camera`` fields; {} when off), as Cycles
    reads it: radius from the f-stop and the lens in metres (scene units of 1 m; orthographic: focal length 1),
    focus distance along the view axis to the focus object's origin, else the Focus Distance; blades, rotation
    and ratio as they are."""
    if not camera_dof_on(cam):
        return {}
    dof = cam.dof
    f = 1.0 if cam.type == "ORTHO" else cam.lens * 1e-3
    focus = float(dof.focus_distance)
    if dof.focus_object is not None:
        target = np.array(dof.focus_object.matrix_world, dtype=np.float64)[:3, 3]
        focus = abs(float(np.dot(m[:3, 3] - target, m[:3, 2])))
    return dict(lens_radius=tracer.lens_radius(f, max(float(dof.aperture_fstop), 1e-5)),
                focus_distance=max(focus, 1e-6), aperture_blades=int(dof.aperture_blades),
                aperture_rotation=float(dof.aperture_rotation), aperture_ratio=float(dof.aperture_ratio))


def viewport_camera(rv3d) -> "tracer.Camera":
    """A tracer camera from the 3D view's view and projection matrices (OpenGL convention): the window is 2/P[0,0]
    × 2/P[1,1] at distance 1, shifted by the projection's offsets (P[0,2], P[1,2] perspective; −P[0,3], −P[1,3]
    orthographic), in units of the window's half size."""
    view = np.array(rv3d.view_matrix, dtype=np.float64)
    proj = np.array(rv3d.window_matrix, dtype=np.float64)
    ortho = not rv3d.is_perspective
    shift = (-proj[0, 3], -proj[1, 3]) if ortho else (proj[0, 2], proj[1, 2])
    return window_camera(np.linalg.inv(view), ortho, 1.0, (2.0 / proj[0, 0], 2.0 / proj[1, 1]),
                         (shift[0] / proj[0, 0], shift[1] / proj[1, 1]))


def window_camera(camera_to_world, ortho: bool, f: float, window, shift, near=None, far=None,
                  lens=None) -> "tracer.Camera":
    """The one place a Blender camera becomes a ``tracer.Camera``: a film ``window`` (W, H) and its ``shift`` in
    units of the focal length ``f`` (1 for orthographic), i.e. apertures W·f, H·f and offsets shift·f; ``lens``
    the thin lens's fields (:func:`depth_of_field`)."""
    clip = {} if near is None else {"near": near, "far": far}
    return tracer.Camera(camera_to_world=camera_to_world, projection=tracer.ORTHOGRAPHIC if ortho else
                         tracer.PERSPECTIVE, focal_length=f, horizontal_aperture=window[0] * f,
                         vertical_aperture=window[1] * f, horizontal_aperture_offset=shift[0] * f,
                         vertical_aperture_offset=shift[1] * f, **clip, **(lens or {}))


# ---------------------------------------------------------------------------------------------------- lights
def light_from_blender(obj, warnings: list):
    """A tracer light for a Blender light object (None for unsupported types), in Blender's power units.

    ``normalize`` off (Blender's USD importer sets it) stops Cycles dividing the power by the emitter's size, so the
    light is brighter by that size (measured against Cycles, tests/cycles/test_cycles_units.py): area lights × the
    area A, point and spot lights × 4π·radius², sun × π·(angle/2)² (:func:`unnormalized_factor`)."""
    light = obj.data
    m = np.array(obj.matrix_world, dtype=np.float64)
    pos = m[:3, 3]
    axis_z = m[:3, 2]
    colour = np.asarray(light.color[:3], np.float64) * 2.0 ** float(getattr(light, "exposure", 0.0))
    power = float(light.energy)
    name = obj.name
    colour = colour * light_node_factor(light, name, warnings)
    if not getattr(light, "normalize", True):
        power *= unnormalized_factor(light, m)
    if light.type in ("POINT", "SPOT"):
        intensity = colour * power / (4.0 * math.pi)
        radius = float(light.shadow_soft_size)
        if not getattr(light, "use_soft_falloff", True) and radius > 0:
            warnings.append(f"light {name!r}: Soft Falloff off is not modelled; using the soft falloff")
        if light.type == "POINT":
            return tracer.PointLight(position=pos, intensity=intensity, radius=radius, name=name)
        return tracer.SpotLight(position=pos, intensity=intensity, radius=radius, name=name, direction=-axis_z,
                                cone_angle=min(float(light.spot_size) / 2.0, math.pi),
                                blend=float(np.clip(light.spot_blend, 0.0, 1.0)))
    if light.type == "SUN":
        return tracer.DistantLight(direction=-axis_z, irradiance=colour * power,
                                   angle=min(float(light.angle), math.pi - 1e-6), name=name)
    if light.type == "AREA":
        if getattr(getattr(light, "cycles", None), "is_portal", False):
            warnings.append(f"light {name!r}: a Portal guides Cycles' sampling of the world and emits nothing; "
                            "skipped")
            return None
        (sx, sy), shape = area_shape(light, m)
        area = tracer.AreaLight.area_of((sx, sy), shape)
        if area <= 0:
            warnings.append(f"light {name!r}: zero-size area light skipped")
            return None
        return tracer.AreaLight(position=pos, u_axis=m[:3, 0], v_axis=m[:3, 1], normal=-axis_z, size=(sx, sy),
                                radiance=colour * power / (math.pi * area), shape=shape, name=name,
                                spread=min(max(float(getattr(light, "spread", math.pi)), 0.0), math.pi))
    warnings.append(f"light {name!r}: {light.type} lights are not supported")
    return None


def light_node_factor(light, name: str, warnings: list) -> np.ndarray:
    """What a light's own node tree (Use Nodes, Cycles) multiplies its colour by: the Emission at its Light Output,
    Color × Strength (constants; a Light Falloff's Quadratic output is its Strength, the light's own falloff). (1,
    1, 1) without a tree; anything else is named in one warning and left at 1."""
    tree = getattr(light, "node_tree", None)
    if tree is None or not getattr(light, "use_nodes", False):
        return np.ones(3)
    outs = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputLight"
            and getattr(n, "target", "ALL") in ("ALL", "CYCLES")]
    out = next((n for n in outs if n.is_active_output), outs[0] if outs else None)
    if out is None or not out.inputs["Surface"].is_linked:
        return np.ones(3) if out is None else np.zeros(3)
    em = out.inputs["Surface"].links[0].from_node
    if em.bl_idname != "ShaderNodeEmission" or em.inputs["Color"].is_linked:
        warnings.append(f"light {name!r}: its node tree is not read (only a constant Emission is); plain light used")
        return np.ones(3)
    strength = em.inputs["Strength"]
    s = float(strength.default_value)
    if strength.is_linked:
        link = strength.links[0]
        src = link.from_node
        if src.bl_idname == "ShaderNodeLightFalloff" and not src.inputs["Strength"].is_linked:
            s = float(src.inputs["Strength"].default_value)
            if link.from_socket.name != "Quadratic":
                warnings.append(f"light {name!r}: Light Falloff {link.from_socket.name} is rendered as Quadratic "
                                "(the light's own falloff)")
        else:
            warnings.append(f"light {name!r}: a linked Emission Strength in its node tree is read as "
                            f"{s:g}")
    return np.asarray(em.inputs["Color"].default_value[:3], np.float64) * s


def area_shape(light, m: np.ndarray) -> tuple[tuple[float, float], str]:
    """A Blender area light's world-space size (sx, sy) (``size``/``size_y`` × the matrix's axis lengths) and the
    tracer's shape ("rect" for Square/Rectangle, "disk" for Disk/Ellipse)."""
    sx = float(light.size) * np.linalg.norm(m[:3, 0])
    sy = float(light.size_y if light.shape in ("RECTANGLE", "ELLIPSE") else light.size) * np.linalg.norm(m[:3, 1])
    return (sx, sy), "disk" if light.shape in ("DISK", "ELLIPSE") else "rect"


def unnormalized_factor(light, m: np.ndarray) -> float:
    """How much brighter Cycles renders a light with ``normalize`` off: its emitter's size (area A of an area light
    in world units; 4π·r² of a point/spot sphere; π·(angle/2)² of the sun's disk), 1 for zero-size emitters."""
    if light.type in ("POINT", "SPOT"):
        r = float(light.shadow_soft_size)
        return 4.0 * math.pi * r * r if r > 0 else 1.0
    if light.type == "SUN":
        a = float(light.angle) / 2.0
        return math.pi * a * a if a > 0 else 1.0
    if light.type == "AREA":
        area = tracer.AreaLight.area_of(*area_shape(light, m))
        return area if area > 0 else 1.0
    return 1.0


# ---------------------------------------------------------------------------------------------------- world
# world_from_blender (addon/world.py): Background colour, Environment Texture, or a Cycles bake of the world.


# ---------------------------------------------------------------------------------------------------- the scene
def render_size(bpy_scene) -> tuple[int, int]:
    """Image size in pixels: resolution × resolution percentage."""
    r = bpy_scene.render
    pct = r.resolution_percentage / 100.0
    return max(1, int(r.resolution_x * pct)), max(1, int(r.resolution_y * pct))


class ExportCancelled(Exception):
    """Raised by :func:`scene_from_depsgraph` / :func:`export_objects` when their ``cancelled()`` returned True
    (Esc during an F12's export)."""


class ExportedObject(NamedTuple):
    """One visible geometry instance of the depsgraph, before it is placed in the world.

    ``key`` names it across depsgraph evaluations (object, instancing parent, ``persistent_id``): the scene sync
    (addon/sync.py) diffs exports by it. ``geometry`` is the :func:`mesh_arrays` dict, shared by every instance of
    one mesh (and kept in the geometry cache), ``material`` its per-triangle material rows and ``corners`` its UV
    sets and vertex colours (:class:`addon.model.Corners`, shared too where the instances share mesh and
    materials), ``matrix`` the 4×4 object-to-world matrix."""

    key: tuple
    name: str
    geometry: dict
    material: np.ndarray
    corners: Corners
    matrix: np.ndarray
    pass_index: int
    #: The matrix keeps handedness (det > 0); False: it mirrors.
    right_handed: bool = True


#: How many instances :func:`export_objects` handles between two polls of ``cancelled``.
POLL_EVERY = 256


def export_objects(depsgraph, writer: MaterialWriter, warnings: list, lights: list, *,
                   geometry_cache: dict | None = None, cancelled=None):
    """Yield an :class:`ExportedObject` per visible geometry instance of ``depsgraph.object_instances`` (and
    append its lights to ``lights``). Triangle arrays are read once per evaluated mesh (``geometry_cache``: kept
    between calls, see :func:`forget_geometry`); material rows and UVs once per mesh and material slots, so the
    instances of one mesh share their arrays. ``cancelled()`` is polled every :data:`POLL_EVERY` instances and
    before each mesh is read; True raises :class:`ExportCancelled`."""
    default_mat = writer.default_row
    geometry: dict = {}
    inputs: dict = {}
    for count, inst in enumerate(depsgraph.object_instances):
        if cancelled is not None and count % POLL_EVERY == 0 and cancelled():
            raise ExportCancelled("export cancelled")
        obj = inst.object
        if obj.type == "LIGHT":
            if not inst.show_self:
                continue
            light = light_from_blender(_Placed(obj, inst.matrix_world), warnings)
            if light is not None:
                lights.append(light)
            continue
        if obj.type not in GEOMETRY_TYPES or not inst.show_self or obj.get(RAYS_PROPERTY):
            continue
        slots = tuple(writer.row(s.material) for s in obj.material_slots)
        wanted = writer.attribute_names(slots)  # generic attributes the materials read by name
        key = obj.data.as_pointer() if obj.type == "MESH" and obj.data is not None else obj.as_pointer()
        key = (key, obj.original.name if obj.type != "MESH" else "")
        named = _geometry_key(obj)
        if key not in geometry:
            if geometry_cache is not None and named in geometry_cache:
                geometry[key] = geometry_cache[named]
            else:
                if cancelled is not None and cancelled():
                    raise ExportCancelled("export cancelled")
                geometry[key] = _object_mesh_arrays(obj, depsgraph, wanted)
                if geometry_cache is not None:
                    geometry_cache[named] = geometry[key]
        g = geometry[key]
        if g is not None and not wanted <= g.get("attributes_read", frozenset()):  # other materials, more names
            g = geometry[key] = _object_mesh_arrays(obj, depsgraph, wanted | g.get("attributes_read", frozenset()))
            if geometry_cache is not None:
                geometry_cache[named] = g
        if g is None or not len(g["triangles"]):
            continue
        mw = inst.matrix_world
        world = np.array(mw, dtype=np.float64)
        # mathutils' C calls (numpy's det and max cost ~10 µs per instance) into the tracer's one rule, scaled by the
        # longest axis.
        m3 = mw.to_3x3()
        det = m3.determinant()
        if tracer.scene.singular(det, max(m3.to_scale())):
            warnings.append(f"object {obj.name!r}: zero scale (nothing to render); skipped")
            continue
        if (key, slots) not in inputs:  # material rows and baked UVs: once per mesh and slot materials
            if slots:
                mats = np.asarray(slots, np.int32)[np.clip(g["material_index"], 0, len(slots) - 1)]
            else:
                mats = default_mat
            inputs[key, slots] = writer.mesh_inputs(obj.name, mats, g)
        mats, corners = inputs[key, slots]
        if inst.is_instance:
            parent = inst.parent.original.name if inst.parent else ""
            name = f"{obj.name}@{parent}#{inst.random_id & 0xFFFF:04x}"
            ident = (obj.original.name, parent, tuple(inst.persistent_id))
        else:
            name, ident = obj.name, (obj.original.name, "", ())
        yield ExportedObject(ident, name, g, mats, corners, world, int(obj.pass_index), det > 0)


def add_objects(b: "tracer.SceneBuilder", objects: list) -> list[np.ndarray]:
    """Add exported objects to a scene builder in their order, one object id each; returns, per object, the matrix
    its vertices were placed with *beyond* the recorded transform (identity: every object's own matrix is recorded
    in ``scene.object_transforms``, so a move is ``Session.set_transform(id, matrix_world)``).

    Instances of one mesh with the same materials (Geometry-Nodes and collection instances, particles) are not
    copied: when at least :data:`BATCH_MIN` objects share the mesh arrays, material rows and corner data (UV sets,
    colours), the mesh is added once in object space as a prototype (its object id after all exported objects, so
    the exported objects keep ids 0..N−1 in order) and each object becomes an instance of it
    (``SceneBuilder.add_instances``: their matrices stacked into one (K, 4, 4) array, no per-instance mesh work;
    mirrored and non-uniformly scaled ones included — the tracer shades instances with the inverse transpose)."""
    groups: dict[tuple, list[int]] = {}
    for i, o in enumerate(objects):
        groups.setdefault((id(o.geometry), id(o.material), id(o.corners)), []).append(i)
    instanced = {i for members in groups.values() if len(members) >= BATCH_MIN for i in members}
    first = len(b.object_names)
    for i, o in enumerate(objects):
        if i in instanced:  # an id and a name now, the instance once its prototype exists (below)
            b.object_names.append(o.name)
        else:
            b.add_mesh(o.geometry["vertices"], o.geometry["triangles"], material=o.material, name=o.name,
                       transform=o.matrix, normals=o.geometry["normals"], **o.corners.kwargs())
    for members in groups.values():
        if len(members) < BATCH_MIN:
            continue
        o = objects[members[0]]
        proto = b.add_mesh(o.geometry["vertices"], o.geometry["triangles"], material=o.material,
                           name=f"{o.name} (instanced mesh)", normals=o.geometry["normals"], **o.corners.kwargs())
        b.add_instances(proto, np.stack([objects[i].matrix for i in members]),
                        object_ids=first + np.asarray(members, np.int32))
    return [np.eye(4) for _ in objects]


#: At least this many instances of one mesh (same materials) become instances of one shared mesh.
BATCH_MIN = 8


def scene_from_depsgraph(depsgraph, *, width: int | None = None, height: int | None = None,
                         camera: "tracer.Camera | None" = None, geometry_cache: dict | None = None,
                         cancelled=None, objects: list | None = None,
                         materials: dict | None = None, frame_set=None) -> tuple["tracer.Scene", list[str]]:
    """Build a :class:`tracer.Scene` from an evaluated depsgraph; returns it and a list of warnings.

    width/height default to the scene's render size (resolution × percentage) and matter only for the camera's
    sensor fit. ``camera`` overrides the scene camera (the viewport uses this). ``geometry_cache`` (a dict the
    caller keeps) holds each object's triangle arrays between calls, keyed by object and mesh name; drop the
    entries of changed objects with :func:`forget_geometry` (the viewport does, from ``depsgraph.updates``).
    ``cancelled()`` (e.g. the render engine's ``test_break``) is polled during the export: True raises
    :class:`ExportCancelled`. ``objects``, a list, receives the :class:`ExportedObject` of each tracer object id
    in order (addon/sync.py keeps them); ``materials``, a dict, receives each Blender material's Principled fields
    by name (addon/sync.py re-reads only the materials an update names). The returned scene carries
    ``scene.object_pass_indices`` (int32 per tracer object id: Blender's ``Object.pass_index``). With Motion Blur
    on, the scene is evaluated again at the shutter's sub-frames (:mod:`addon.motion`; ``frame_set``: the render
    engine's ``frame_set``, default the scene's) for ``scene.motion`` and the camera's motion.
    """
    bpy_scene = depsgraph.scene_eval if hasattr(depsgraph, "scene_eval") else depsgraph.scene
    warnings: list[str] = []
    # Motion blur: F12 and Explain Pixel; not the viewport (it passes a camera) nor a synced session (``objects``:
    # its edits have no motion)
    blur = motion_blur_on(bpy_scene)
    if blur and objects is not None and camera is None:
        warnings.append("motion blur is not rendered with Persistent Data (turn it off for motion blur)")
    blur = blur and camera is None and objects is None
    rw, rh = render_size(bpy_scene)
    width, height = width or rw, height or rh
    b = tracer.SceneBuilder()
    writer = MaterialWriter(b, warnings)
    exported = list(export_objects(depsgraph, writer, warnings, b.lights, geometry_cache=geometry_cache,
                                   cancelled=cancelled))
    add_objects(b, exported)
    if objects is not None:
        objects.extend(exported)
    if materials is not None:
        materials.update({name: f for name, f in writer.fields.values()})
    if cancelled is not None and cancelled():
        raise ExportCancelled("export cancelled")

    if camera is None:
        camera = scene_camera(bpy_scene, width, height)
    b.camera = camera
    b.background, b.ambient, b.environment = world_from_blender(bpy_scene.world, warnings, writer.images)
    pass_indices = np.zeros(len(b.object_names), np.int32)  # prototypes (ids after the objects'): 0
    pass_indices[:len(exported)] = [o.pass_index for o in exported]
    b.object_pass_indices = pass_indices
    scene = b.build()
    scene.material_volumes = material_volumes(writer, len(scene.materials.names))
    scene.material_volume_carried = material_volume_carried(writer, len(scene.materials.names))
    scene.object_visibility, scene.light_links, scene.emitter_links = links_from_blender(
        depsgraph, exported, scene.lights, len(b.object_names), warnings)
    scene.object_holdout, scene.object_shadow_catcher = compose_flags(depsgraph, exported, len(b.object_names))
    if blur:  # last: it evaluates the scene at other sub-frames (and puts the frame back)
        apply_motion(scene, exported, sample_motion(depsgraph, exported, warnings, frame_set))
    return scene, warnings


def material_volumes(writer: MaterialWriter, n_materials: int) -> np.ndarray | None:
    """``Scene.material_volumes`` of the materials a writer read (a material's Volume output: addon/volume.py), or
    None when none holds a medium."""
    rows = {r: v for r, v in writer.volumes.items() if r not in writer.open_media}
    if not rows:
        return None
    vols = np.zeros((n_materials, 6), np.float32)
    for row, v in rows.items():
        vols[row] = v
    return vols


def material_volume_carried(writer: MaterialWriter, n_materials: int) -> np.ndarray | None:
    """``Scene.material_volume_carried``: the media on inside-out closed meshes (addon.model, ``_open_media``), or
    None."""
    rows = [r for r in writer.carried_media if r in writer.volumes and r not in writer.open_media]
    if not rows:
        return None
    out = np.zeros(n_materials, np.bool_)
    out[rows] = True
    return out


def links_from_blender(depsgraph, exported: list, lights: list, n_objects: int, warnings: list) -> tuple:
    """(``scene.object_visibility`` or None, ``scene.light_links``, ``scene.emitter_links``) for the exported
    objects (object id i = ``exported[i]``) and lights (matched to their Blender objects by name): Object ▸
    Visibility ▸ Ray Visibility and Cycles' light / shadow linking (a collection's objects and child collections,
    each included or excluded: only included objects when there are any, minus the excluded; everything but the
    excluded otherwise), of lamps and of mesh objects (an emissive mesh's links; every exported id of the object
    gets them, the tracer ignores those that do not emit)."""
    linking = tracer_module("lights.linking")  # (here, not at import: it loads the kernel machinery)
    ray_visibility = (("visible_camera", linking.CAMERA), ("visible_glossy", linking.GLOSSY),
                      ("visible_transmission", linking.TRANSMISSION), ("visible_shadow", linking.SHADOW))
    by_name = {o.name: o for o in depsgraph.objects}
    ids: dict[str, list[int]] = {}
    for i, o in enumerate(exported):
        ids.setdefault(o.key[0], []).append(i)
    visibility = np.full(n_objects, linking.ALL_VISIBLE, np.uint8)
    for name, members in ids.items():
        obj = by_name.get(name)
        if obj is None:
            continue
        bits = sum(bit for attr, bit in ray_visibility if getattr(obj, attr, True))
        visibility[members] = bits

    def members(collection):
        if collection is None:
            return None
        include, exclude = set(), set()
        # collection_objects[i] / collection_children[i] hold the state of objects[i] / children[i]
        for entry, objects in [(e, (o,)) for e, o in zip(collection.collection_objects, collection.objects)] + \
                [(e, c.all_objects) for e, c in zip(collection.collection_children, collection.children)]:
            target = exclude if entry.light_linking.link_state == "EXCLUDE" else include
            for obj in objects:
                target.update(ids.get(obj.name, ()))
        if not include and not exclude:
            return None
        chosen = include if include else set(range(len(exported)))
        return np.array(sorted(chosen - exclude), np.int64)

    links = []
    for light in lights:
        obj = by_name.get(light.name)
        link = linking.LightLink()
        if obj is not None:
            ll = getattr(obj, "light_linking", None)
            if ll is not None:
                link.receivers, link.blockers = members(ll.receiver_collection), members(ll.blocker_collection)
            link.cast_shadow = bool(getattr(obj.data, "use_shadow", True))
            link.diffuse = float(bool(getattr(obj, "visible_diffuse", True)))
            link.glossy = float(bool(getattr(obj, "visible_glossy", True)))
            # the lamp's shape as camera and refraction rays see it (Cycles' defaults: camera off, transmission on)
            link.camera = float(bool(getattr(obj, "visible_camera", False)))
            link.transmission = float(bool(getattr(obj, "visible_transmission", True)))
        links.append(link)
    if all(k.is_default() for k in links):
        links = []
    emitter_links = {}
    for name, object_ids in ids.items():
        ll = getattr(by_name.get(name), "light_linking", None)
        if ll is not None and (ll.receiver_collection or ll.blocker_collection):
            link = linking.LightLink(receivers=members(ll.receiver_collection),
                                     blockers=members(ll.blocker_collection))
            if not link.is_default():
                emitter_links.update({i: link for i in object_ids})
    if np.all(visibility == linking.ALL_VISIBLE):
        visibility = None
    return visibility, links, emitter_links


def compose_flags(depsgraph, exported: list, n: int) -> tuple:
    """Per tracer object id (None where no object has it): holdout (the object's Holdout or its collection's, as
    ``Object.holdout_get`` answers for the view layer) and shadow catcher (``Object.is_shadow_catcher``); an
    instance takes its object's flags (tracer.integrator.compose)."""
    hold, catch = np.zeros(n, bool), np.zeros(n, bool)
    view_layer = getattr(depsgraph, "view_layer", None)
    seen: dict = {}
    for i, o in enumerate(exported):
        name = o.key[0]
        if name not in seen:
            ob = depsgraph.objects.get(name)
            ob = ob.original if ob is not None else None
            h = bool(ob is not None and (getattr(ob, "is_holdout", False)
                                         or (view_layer is not None and ob.holdout_get(view_layer=view_layer))))
            seen[name] = (h, bool(ob is not None and getattr(ob, "is_shadow_catcher", False)))
        hold[i], catch[i] = seen[name]
    return (hold if hold.any() else None), (catch if catch.any() else None)


def scene_camera(bpy_scene, width: int, height: int) -> "tracer.Camera":
    """The scene camera as a tracer camera for a width × height image (a clear error when there is none)."""
    cam_obj = bpy_scene.camera
    if cam_obj is None:
        raise ValueError("the scene has no active camera: add one and set it as the scene camera")
    return camera_from_blender(cam_obj, width, height,
                               bpy_scene.render.pixel_aspect_x / bpy_scene.render.pixel_aspect_y)


def _geometry_key(obj) -> tuple:
    """A name key for an object's evaluated triangles that stays valid between depsgraph evaluations."""
    return (obj.original.name, obj.data.name if obj.data is not None else "", obj.type)


def forget_geometry(cache: dict, ids) -> None:
    """Drop the cached triangles of the changed IDs (objects or meshes, from ``depsgraph.updates``); any other kind
    of geometry change (a node group, a collection) empties the cache."""
    for id_ in ids:
        kind = type(getattr(id_, "original", id_)).__name__
        name = id_.name
        if kind not in ("Object", "Mesh"):
            cache.clear()
            return
        for key in [k for k in cache if name in (k[0], k[1])]:
            del cache[key]


#: Custom property marking Explain Pixel's ray curves (addon/explain.py): shown in the viewport, never traced.
RAYS_PROPERTY = "whitted_rays"


class _Placed:
    """An object seen through an instance: its data with the instance's world matrix."""

    def __init__(self, obj, matrix_world):
        self.data = obj.data
        self.name = obj.name
        self.matrix_world = matrix_world


def settings_from_scene(bpy_scene, view_layer=None) -> "tracer.RenderSettings":
    """Render settings from a Blender scene: ``scene.whitted`` (every property addon/properties.py made from a
    RenderSettings field; the defaults where unregistered), the render size
    (resolution × percentage), the render border as ``region``, Film > Transparent, and the AOVs the view layer
    and ``scene.whitted.ray_type_passes`` ask for (addon/passes.py: the one pass ↔ AOV table). Blender's own
    switches are ``depth_of_field`` (the scene camera's Depth of Field, :func:`camera_dof_on`) and ``motion_blur``
    (Render > Motion Blur, :func:`motion_blur_on`): the export reads them through the same two functions."""
    r = bpy_scene.render
    w, h = render_size(bpy_scene)
    props = getattr(bpy_scene, "whitted", None)
    kw = {}
    if props is not None:
        from .properties import settings_kwargs  # here: properties imports bpy, which export alone does not need

        kw = settings_kwargs(props)
    region = border_region(bpy_scene) if r.use_border else None
    layer = view_layer if view_layer is not None else (bpy_scene.view_layers[0] if bpy_scene.view_layers else None)
    aovs = [p.aov for p in passes.asked(layer, props)]
    cam = bpy_scene.camera
    dof = camera_dof_on(cam.data) if cam is not None and cam.type == "CAMERA" else False
    return tracer.RenderSettings(width=w, height=h, transparent=bool(r.film_transparent), region=region,
                                 aovs=tuple(aovs), depth_of_field=dof, motion_blur=motion_blur_on(bpy_scene),
                                 **kw).validate()


def border_region(bpy_scene) -> tuple[int, int, int, int]:
    """Blender's render border as a tracer region (x0, y0, x1, y1), top-left origin. Blender converts the border
    fractions (bottom-left origin) to pixels by truncation."""
    r = bpy_scene.render
    w, h = render_size(bpy_scene)
    x0, x1 = int(r.border_min_x * w), int(r.border_max_x * w)
    ymin, ymax = int(r.border_min_y * h), int(r.border_max_y * h)
    x1 = max(x1, x0 + 1)
    ymax = max(ymax, ymin + 1)
    return (min(x0, w - 1), h - min(ymax, h), min(x1, w), h - min(ymin, h - 1))

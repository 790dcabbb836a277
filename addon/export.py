"""Blender's evaluated depsgraph -> ``tracer.Scene``: the add-on's core, pure (no render engine needed).

    scene, warnings = scene_from_depsgraph(bpy.context.evaluated_depsgraph_get())
    image = tracer.render(scene, settings_from_scene(bpy.context.scene))

What is read (everything from the *evaluated* depsgraph, so modifiers, geometry nodes, collection instances and
particles are included):

- Geometry: every visible instance of ``depsgraph.object_instances`` whose object has a mesh (meshes after
  modifiers, curves, text, metaballs, surfaces through ``Object.to_mesh``), as loop triangles with split/custom
  normals (``Mesh.corner_normals``), the active UV map and per-face materials; ``instance.matrix_world`` places it.
  Each instance is its own object (object id); the tracer's ``objectid`` AOV maps to Blender's Object Index
  through ``scene.object_pass_indices``.
- Camera: Blender's exact camera model (DESIGN.md, "Blender's camera model"): sensor fit, lens, shift,
  orthographic scale, clip start/end.
- Lights, in Blender's units: point P W -> intensity P/(4π)·colour, radius = ``shadow_soft_size``; spot: the same
  with cone half-angle ``spot_size/2`` and ``spot_blend``; sun strength S -> irradiance S·colour, ``angle``; area
  power P -> radiance P/(π·A)·colour (A in world units, emitting along the light's -Z). ``2^exposure`` multiplies.
- World: the Background node's Color × Strength (or ``world.color``) -> ``scene.background`` and ``scene.ambient``.
- Materials: see :func:`material_from_blender` (the Principled BSDF mapping).
"""

from __future__ import annotations

import math

import numpy as np

try:  # inside the installed extension the tracer is bundled next to this module
    from . import tracer
except ImportError:  # the repository's ``addon`` package uses the top-level tracer
    import tracer

#: Blender's default surface (no material): 0.8 grey, Principled defaults.
DEFAULT_SURFACE = {"diffuse": (0.8, 0.8, 0.8), "specular": (0.04, 0.04, 0.04), "roughness": 0.5}
#: Object types that become triangles through ``Object.to_mesh``.
GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "META", "FONT"}


def specular_f0(ior: float, specular_ior_level: float) -> float:
    """The Blinn-Phong specular colour R_s of a dielectric Principled BSDF.

    R_s = F0 · 2·level with F0 = ((η − 1)/(η + 1))², the normal-incidence Fresnel reflectance: Blender's
    Specular IOR Level scales F0 so that 0.5 keeps it, 0 removes the highlight and 1 doubles it.
    """
    f0 = ((ior - 1.0) / (ior + 1.0)) ** 2 if ior > 0 else 0.0
    return float(f0 * 2.0 * max(specular_ior_level, 0.0))


# ---------------------------------------------------------------------------------------------------- materials
def _node_tree(idblock):
    """The node tree of a material or world if it uses nodes (Blender 5.0 always does; ``use_nodes`` is
    deprecated there)."""
    import bpy

    if bpy.app.version < (5, 0, 0) and not idblock.use_nodes:
        return None
    return idblock.node_tree


def _input(node, *names):
    """The first of ``names`` that is an input socket of ``node`` (names changed across Blender versions)."""
    for n in names:
        sock = node.inputs.get(n)
        if sock is not None:
            return sock
    return None


def _value(node, *names, default=0.0):
    sock = _input(node, *names)
    if sock is None:
        return default
    v = sock.default_value
    try:
        return tuple(float(x) for x in v)
    except TypeError:
        return float(v)


def _linked_node(sock):
    if sock is None or not sock.is_linked:
        return None
    link = sock.links[0]
    node = link.from_node
    while node.type == "REROUTE" and node.inputs[0].is_linked:
        node = node.inputs[0].links[0].from_node
    return node


def _output_node(tree):
    outs = [n for n in tree.nodes if n.type == "OUTPUT_MATERIAL"]
    active = [n for n in outs if n.is_active_output and n.target in ("ALL", "CYCLES")]
    return (active or [n for n in outs if n.target in ("ALL", "CYCLES")] or outs or [None])[0]


def image_pixels(image) -> np.ndarray:
    """(H, W, 3) scene-linear float32 pixels of a Blender image, top row first (the tracer's texture layout).

    ``Image.pixels`` holds float images linear and byte images as stored, so byte images in an sRGB colour
    space are decoded with the sRGB transfer function; Non-Color data stays as is.
    """
    w, h = image.size
    c = image.channels
    if w == 0 or h == 0:
        raise ValueError(f"image {image.name!r} has no pixels (missing file?)")
    buf = np.empty(w * h * c, np.float32)
    image.pixels.foreach_get(buf)
    px = buf.reshape(h, w, c)[::-1]
    if c == 1:
        rgb = np.repeat(px, 3, axis=2)
    else:
        rgb = px[..., :3] if c >= 3 else np.repeat(px[..., :1], 3, axis=2)
    space = image.colorspace_settings.name.lower()
    if not image.is_float and "srgb" in space:
        rgb = tracer.texture.srgb_to_linear(rgb)
    return np.ascontiguousarray(rgb, dtype=np.float32)


def material_from_blender(material, textures: dict, builder, warnings: list) -> dict:
    """Material row (tracer fields) for a Blender material.

    Principled BSDF mapping (documented in docs/addon.md):

    ============================  =====================================================================
    Base Color                    ``diffuse`` (an Image Texture on it: ``diffuse_texture``, diffuse = 1)
    Metallic m                    ``k_m`` = m, ``mirror_tint`` = base colour
    Roughness r                   ``exponent`` = roughness_to_exponent(r)
    IOR η, Specular IOR Level s   ``specular`` = ((η−1)/(η+1))²·2s × Specular Tint, ``ior`` = η
    Transmission Weight w         ``transmission`` = w, ``transmission_tint`` = base colour
    Alpha a < 1                   pass-through: ``transmission`` = 1 − a with ``ior`` = 1 (no bending)
    Emission Color × Strength     ``emission``
    ============================  =====================================================================

    Diffuse BSDF and Emission shaders map to the obvious rows. Anything else falls back to the material's viewport
    colour (``diffuse_color``) with one warning.
    """
    name = material.name
    fallback = {"diffuse": tuple(material.diffuse_color[:3]), "specular": (0.0, 0.0, 0.0),
                "k_m": float(getattr(material, "metallic", 0.0)),
                "roughness": float(getattr(material, "roughness", 0.5))}
    tree = _node_tree(material)
    if tree is None:
        return fallback
    out = _output_node(tree)
    shader = _linked_node(out.inputs.get("Surface")) if out is not None else None
    if shader is None:
        warnings.append(f"material {name!r}: no surface shader connected to the Material Output; "
                        "using its viewport colour")
        return fallback
    if shader.type == "BSDF_DIFFUSE":
        return {"diffuse": _value(shader, "Color")[:3], "specular": (0.0, 0.0, 0.0)}
    if shader.type == "EMISSION":
        col = np.asarray(_value(shader, "Color")[:3]) * _value(shader, "Strength", default=1.0)
        return {"diffuse": (0.0, 0.0, 0.0), "emission": tuple(col)}
    if shader.type != "BSDF_PRINCIPLED":
        warnings.append(f"material {name!r}: unsupported shader {shader.bl_idname}; using its viewport colour")
        return fallback

    row: dict = {}
    base_sock = _input(shader, "Base Color")
    base = np.asarray(_value(shader, "Base Color", default=(0.8, 0.8, 0.8, 1.0))[:3], np.float32)
    tex_node = _linked_node(base_sock)
    if tex_node is not None:
        if tex_node.type == "TEX_IMAGE" and tex_node.image is not None:
            key = tex_node.image.name
            if key not in textures:
                try:
                    textures[key] = builder.add_texture(image_pixels(tex_node.image))
                except Exception as exc:  # missing file, unreadable pixels: keep the flat colour
                    warnings.append(f"material {name!r}: image {key!r} not loaded ({exc})")
                    textures[key] = None
            if textures[key] is not None:
                row["diffuse_texture"] = textures[key]
                base = np.ones(3, np.float32)
                if tex_node.inputs["Vector"].is_linked:
                    warnings.append(f"material {name!r}: texture coordinates of {key!r} come from nodes; "
                                    "the active UV map is used")
        else:
            warnings.append(f"material {name!r}: Base Color is driven by {tex_node.bl_idname}, which is not "
                            "supported; using the socket's colour")
    row["diffuse"] = tuple(base)

    metallic = float(np.clip(_value(shader, "Metallic"), 0.0, 1.0))
    roughness = float(np.clip(_value(shader, "Roughness", default=0.5), 0.0, 1.0))
    ior = float(_value(shader, "IOR", default=1.5))
    ior = ior if ior > 0 else 1.5
    level = float(_value(shader, "Specular IOR Level", "Specular", default=0.5))
    tint = _value(shader, "Specular Tint", default=(1.0, 1.0, 1.0, 1.0))
    tint = np.asarray(tint[:3] if isinstance(tint, tuple) else (1.0, 1.0, 1.0), np.float32)
    transmission = float(np.clip(_value(shader, "Transmission Weight", "Transmission"), 0.0, 1.0))
    alpha = float(np.clip(_value(shader, "Alpha", default=1.0), 0.0, 1.0))
    emission = np.asarray(_value(shader, "Emission Color", "Emission", default=(0.0, 0.0, 0.0, 1.0))[:3])
    emission = emission * float(_value(shader, "Emission Strength", default=1.0))

    row["k_m"] = metallic
    row["mirror_tint"] = tuple(base) if "diffuse_texture" not in row else (1.0, 1.0, 1.0)
    row["roughness"] = roughness
    row["specular"] = tuple(np.clip(specular_f0(ior, level) * tint, 0.0, None))
    row["ior"] = ior
    row["transmission"] = transmission
    row["transmission_tint"] = tuple(base)
    row["emission"] = tuple(np.maximum(emission, 0.0))
    if alpha < 1.0 and transmission == 0.0:
        row["transmission"] = 1.0 - alpha
        row["transmission_tint"] = (1.0, 1.0, 1.0)
        row["ior"] = 1.0
    elif alpha < 1.0:
        warnings.append(f"material {name!r}: Alpha together with Transmission is not supported; Alpha ignored")
    return row


# ---------------------------------------------------------------------------------------------------- geometry
def mesh_arrays(mesh) -> dict:
    """Object-space triangle arrays of a Blender mesh: vertices (V, 3), triangles (T, 3), per-corner normals
    (T, 3, 3) from ``corner_normals`` (split/custom normals, flat faces included), per-corner UVs (T, 3, 2) of
    the active UV map or None, per-triangle material slot indices (T,)."""
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
    uvs = None
    layer = mesh.uv_layers.active
    if layer is not None and nl:
        uv = np.empty(nl * 2, np.float32)
        layer.data.foreach_get("uv", uv)
        uvs = uv.reshape(-1, 2)[loops].reshape(nt, 3, 2)
    return {"vertices": verts.reshape(nv, 3), "triangles": tris.reshape(nt, 3), "normals": normals,
            "uvs": uvs, "material_index": mat}


def _object_mesh_arrays(obj, depsgraph):
    mesh = obj.to_mesh(preserve_all_data_layers=False, depsgraph=depsgraph)
    try:
        return None if mesh is None else mesh_arrays(mesh)
    finally:
        obj.to_mesh_clear()


# ---------------------------------------------------------------------------------------------------- camera
def camera_from_blender(cam_obj, width: int, height: int, pixel_aspect: float = 1.0) -> "tracer.Camera":
    """A tracer camera reproducing Blender's projection of ``cam_obj`` on a width × height image.

    E = sensor/lens (perspective) or ortho_scale (orthographic); A = RX/RY (× pixel aspect). The fitted side is
    the larger one for AUTO (sensor_width), the width for HORIZONTAL (sensor_width), the height for VERTICAL
    (sensor_height); W = E if the width is fitted else E·A, H = E if the height is fitted else E/A; the shift moves
    the window by shift·E. In tracer terms (focal length f = lens for perspective, 1 for orthographic):
    apertures W·f, H·f, offsets shift·E·f.
    """
    cam = cam_obj.data
    aspect = width * pixel_aspect / height
    fit = cam.sensor_fit
    if fit == "AUTO":
        fit_width = aspect >= 1.0
        sensor = cam.sensor_width
    elif fit == "HORIZONTAL":
        fit_width, sensor = True, cam.sensor_width
    else:
        fit_width, sensor = False, cam.sensor_height
    if cam.type == "ORTHO":
        e, f, projection = cam.ortho_scale, 1.0, tracer.ORTHOGRAPHIC
    elif cam.type == "PERSP":
        e, f, projection = sensor / cam.lens, cam.lens, tracer.PERSPECTIVE
    else:
        raise ValueError(f"camera {cam_obj.name!r}: {cam.type} cameras are not supported (perspective and "
                         "orthographic only)")
    w_ap = e if fit_width else e * aspect
    h_ap = e if not fit_width else e / aspect
    m = np.array(cam_obj.matrix_world, dtype=np.float64)
    m[:3, :3] /= np.linalg.norm(m[:3, :3], axis=0, keepdims=True)  # Blender ignores the camera's scale
    return tracer.Camera(camera_to_world=m, projection=projection, focal_length=f,
                         horizontal_aperture=w_ap * f, vertical_aperture=h_ap * f,
                         horizontal_aperture_offset=cam.shift_x * e * f,
                         vertical_aperture_offset=cam.shift_y * e * f,
                         near=cam.clip_start, far=cam.clip_end)


# ---------------------------------------------------------------------------------------------------- lights
def light_from_blender(obj, warnings: list):
    """A tracer light for a Blender light object (None for unsupported types), in Blender's power units."""
    light = obj.data
    m = np.array(obj.matrix_world, dtype=np.float64)
    pos = m[:3, 3]
    axis_z = m[:3, 2]
    colour = np.asarray(light.color[:3], np.float64) * 2.0 ** float(getattr(light, "exposure", 0.0))
    power = float(light.energy)
    name = obj.name
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
        ux, uy = m[:3, 0], m[:3, 1]
        sx = float(light.size) * np.linalg.norm(ux)
        shape = light.shape
        sy = float(light.size_y if shape in ("RECTANGLE", "ELLIPSE") else light.size) * np.linalg.norm(uy)
        disk = shape in ("DISK", "ELLIPSE")
        area = math.pi / 4.0 * sx * sy if disk else sx * sy
        if area <= 0:
            warnings.append(f"light {name!r}: zero-size area light skipped")
            return None
        return tracer.AreaLight(position=pos, u_axis=ux, v_axis=uy, normal=-axis_z, size=(sx, sy),
                                radiance=colour * power / (math.pi * area), shape="disk" if disk else "rect",
                                name=name)
    warnings.append(f"light {name!r}: {light.type} lights are not supported")
    return None


# ---------------------------------------------------------------------------------------------------- world
def world_colour(world, warnings: list) -> np.ndarray:
    """Colour × strength of the world: the Background node feeding the World Output, else ``world.color``."""
    if world is None:
        return np.zeros(3, np.float32)
    tree = _node_tree(world)
    if tree is not None:
        outs = [n for n in tree.nodes if n.type == "OUTPUT_WORLD"]
        active = [n for n in outs if n.is_active_output] or outs
        if active:
            bg = _linked_node(active[0].inputs.get("Surface"))
            if bg is not None and bg.type == "BACKGROUND":
                if bg.inputs["Color"].is_linked:
                    warnings.append(f"world {world.name!r}: textured backgrounds are not supported; "
                                    "using the Background node's colour")
                c = np.asarray(bg.inputs["Color"].default_value[:3], np.float32)
                return (c * float(bg.inputs["Strength"].default_value)).astype(np.float32)
            if bg is not None:
                warnings.append(f"world {world.name!r}: unsupported world shader {bg.bl_idname}; "
                                "using the world's viewport colour")
            elif active:
                return np.zeros(3, np.float32)
    return np.asarray(world.color[:3], np.float32)


# ---------------------------------------------------------------------------------------------------- the scene
def render_size(bpy_scene) -> tuple[int, int]:
    """Image size in pixels: resolution × resolution percentage."""
    r = bpy_scene.render
    pct = r.resolution_percentage / 100.0
    return max(1, int(r.resolution_x * pct)), max(1, int(r.resolution_y * pct))


def scene_from_depsgraph(depsgraph, *, width: int | None = None, height: int | None = None,
                         camera: "tracer.Camera | None" = None) -> tuple["tracer.Scene", list[str]]:
    """Build a :class:`tracer.Scene` from an evaluated depsgraph; returns it and a list of warnings.

    width/height default to the scene's render size (resolution × percentage) and matter only for the camera's
    sensor fit. ``camera`` overrides the scene camera (the viewport uses this). The returned scene carries
    ``scene.object_pass_indices`` (int32 per tracer object id: Blender's ``Object.pass_index``).
    """
    bpy_scene = depsgraph.scene_eval if hasattr(depsgraph, "scene_eval") else depsgraph.scene
    warnings: list[str] = []
    rw, rh = render_size(bpy_scene)
    width, height = width or rw, height or rh
    b = tracer.SceneBuilder()
    default_mat = b.add_material("__default__", **DEFAULT_SURFACE)
    materials: dict[str, int] = {}
    textures: dict[str, int | None] = {}
    geometry: dict[int, dict | None] = {}
    pass_indices: list[int] = []

    def material_index(mat):
        if mat is None:
            return default_mat
        if mat.name not in materials:
            row = material_from_blender(mat, textures, b, warnings)
            materials[mat.name] = b.add_material(mat.name, **row)
        return materials[mat.name]

    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type == "LIGHT":
            if not inst.show_self:
                continue
            light = light_from_blender(_Placed(obj, inst.matrix_world), warnings)
            if light is not None:
                b.add_light(light)
            continue
        if obj.type not in GEOMETRY_TYPES or not inst.show_self or obj.get(RAYS_PROPERTY):
            continue
        key = obj.data.as_pointer() if obj.type == "MESH" and obj.data is not None else obj.as_pointer()
        key = (key, obj.original.name if obj.type != "MESH" else "")
        if key not in geometry:
            geometry[key] = _object_mesh_arrays(obj, depsgraph)
        g = geometry[key]
        if g is None or not len(g["triangles"]):
            continue
        world = np.array(inst.matrix_world, dtype=np.float64)
        det = np.linalg.det(world[:3, :3])
        if not np.isfinite(det) or abs(det) <= 1e-12 * np.abs(world[:3, :3]).max() ** 3:
            warnings.append(f"object {obj.name!r}: zero scale (nothing to render); skipped")
            continue
        tris, normals, uvs = g["triangles"], g["normals"], g["uvs"]  # add_mesh un-mirrors negative scales
        slots = [material_index(s.material) for s in obj.material_slots]
        if slots:
            table = np.asarray(slots, np.int32)
            mats = table[np.clip(g["material_index"], 0, len(slots) - 1)]
        else:
            mats = default_mat
        name = obj.name if not inst.is_instance else f"{obj.name}@{inst.parent.name if inst.parent else ''}" \
                                                       f"#{inst.random_id & 0xFFFF:04x}"
        b.add_mesh(g["vertices"], tris, material=mats, name=name, transform=world, normals=normals, uvs=uvs)
        pass_indices.append(int(obj.pass_index))

    if camera is None:
        cam_obj = bpy_scene.camera
        if cam_obj is None:
            raise ValueError("the scene has no active camera: add one and set it as the scene camera")
        camera = camera_from_blender(cam_obj, width, height,
                                     bpy_scene.render.pixel_aspect_x / bpy_scene.render.pixel_aspect_y)
    b.camera = camera
    colour = world_colour(bpy_scene.world, warnings)
    b.background = colour
    b.ambient = colour
    b.object_pass_indices = np.asarray(pass_indices, np.int32)
    return b.build(), warnings


#: Custom property marking Explain Pixel's ray curves (addon/explain.py): shown in the viewport, never traced.
RAYS_PROPERTY = "whitted_rays"


class _Placed:
    """An object seen through an instance: its data with the instance's world matrix."""

    def __init__(self, obj, matrix_world):
        self.data = obj.data
        self.name = obj.name
        self.matrix_world = matrix_world


def settings_from_scene(bpy_scene, view_layer=None) -> "tracer.RenderSettings":
    """Render settings from a Blender scene: ``scene.whitted`` (defaults where unregistered), the render size
    (resolution × percentage), the render border as ``region``, Film > Transparent, and the AOVs the view layer
    asks for (Z -> depth, Normal -> normal, Object Index -> objectid)."""
    r = bpy_scene.render
    w, h = render_size(bpy_scene)
    props = getattr(bpy_scene, "whitted", None)
    kw = {}
    if props is not None:
        kw = dict(samples=props.samples, max_depth=props.max_depth, epsilon=props.epsilon or None,
                  fresnel=props.fresnel, shadows=props.shadows, threads=props.threads or None,
                  light_samples=props.light_samples, sky_samples=props.sky_samples,
                  terminal_rays=props.terminal_rays)
    region = border_region(bpy_scene) if r.use_border else None
    aovs = []
    layer = view_layer if view_layer is not None else (bpy_scene.view_layers[0] if bpy_scene.view_layers else None)
    if layer is not None:
        if layer.use_pass_z:
            aovs.append("depth")
        if layer.use_pass_normal:
            aovs.append("normal")
        if layer.use_pass_object_index:
            aovs.append("objectid")
    if props is not None and props.ray_type_passes:
        aovs.extend(tracer.settings.RAY_TYPE_AOVS)
    return tracer.RenderSettings(width=w, height=h, transparent=bool(r.film_transparent), region=region,
                                 aovs=tuple(aovs), **kw).validate()


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

"""Scene-building helpers for tests that use Blender through the ``bpy`` module (shared by the add-on and the
Cycles test suites; keep these signatures stable).

bpy is imported lazily inside each function, so importing this module never needs Blender. Conventions:
Blender's world (Z up, metres); colours are scene-linear RGB triples; angles in radians; every ``add_*`` returns
the new object and links it into the active scene.

    from blender_kit import scene as bs
    scene = bs.reset()
    bs.add_camera((0, -6, 2), target=(0, 0, 0.5), lens=50)
    bs.add_point_light((3, -3, 5), power=1000)
    bs.add_uv_sphere((0, 0, 1), 1.0, material=bs.principled_material("red", **{"Base Color": (0.8, 0.1, 0.1)}))
    bs.set_cycles_whitted(scene, samples=64)
    image = bs.render_exr(scene)          # {"rgba": (H, W, 4) linear float32, "Depth": ..., ...}
"""

from __future__ import annotations

import math
import os
import tempfile

import numpy as np

# ---------------------------------------------------------------------------------------------------- scene


def reset(size=(160, 120), percentage: int = 100):
    """Empty factory scene (no objects, no world), Standard view transform, the given render size.
    Returns ``bpy.context.scene``."""
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = percentage
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.render.dither_intensity = 0.0
    return scene


def _link(obj):
    import bpy

    bpy.context.scene.collection.objects.link(obj)
    return obj


def look_at_rotation(location, target, up_axis: str = "Y"):
    """Euler rotation that points an object's −Z at ``target`` with its local +Y as up (cameras and lights)."""
    from mathutils import Vector

    d = Vector(target) - Vector(location)
    if d.length == 0:
        raise ValueError("look_at_rotation: location and target coincide")
    return d.to_track_quat("-Z", up_axis).to_euler()


def add_camera(location=(0.0, -6.0, 2.0), target=(0.0, 0.0, 0.0), *, rotation=None, lens: float = 50.0,
               sensor_width: float = 36.0, sensor_height: float = 24.0, sensor_fit: str = "AUTO",
               shift=(0.0, 0.0), ortho_scale: float | None = None, clip_start: float = 0.1,
               clip_end: float = 1000.0, name: str = "Camera", make_active: bool = True):
    """A perspective camera (orthographic when ``ortho_scale`` is given) looking at ``target`` (or with an explicit
    Euler ``rotation``); it becomes the scene camera."""
    import bpy

    data = bpy.data.cameras.new(name)
    data.lens, data.sensor_width, data.sensor_height, data.sensor_fit = lens, sensor_width, sensor_height, sensor_fit
    data.shift_x, data.shift_y = shift
    data.clip_start, data.clip_end = clip_start, clip_end
    if ortho_scale is not None:
        data.type = "ORTHO"
        data.ortho_scale = ortho_scale
    obj = _link(bpy.data.objects.new(name, data))
    obj.location = location
    obj.rotation_euler = rotation if rotation is not None else look_at_rotation(location, target)
    if make_active:
        bpy.context.scene.camera = obj
    return obj


def _light(kind, name, location, target, color, energy, rotation=None):
    import bpy

    data = bpy.data.lights.new(name, kind)
    data.color = color
    data.energy = energy
    obj = _link(bpy.data.objects.new(name, data))
    obj.location = location
    if rotation is not None:
        obj.rotation_euler = rotation
    elif target is not None:
        obj.rotation_euler = look_at_rotation(location, target)
    return obj


def add_point_light(location, power: float = 1000.0, color=(1.0, 1.0, 1.0), radius: float = 0.0,
                    name: str = "Point"):
    """Point light of ``power`` watts; radius 0 (Blender's default is 0.1) makes it the Whitted point light."""
    obj = _light("POINT", name, location, None, color, power)
    obj.data.shadow_soft_size = radius
    return obj


def add_sun(direction=(0.0, 0.0, -1.0), strength: float = 3.0, color=(1.0, 1.0, 1.0), angle: float = 0.0,
            name: str = "Sun"):
    """Sun of ``strength`` W/m² shining along ``direction`` (the direction light travels)."""
    d = np.asarray(direction, float)
    obj = _light("SUN", name, tuple(-d * 10), tuple(-d * 10 + d), color, strength)
    obj.data.angle = angle
    return obj


def add_spot_light(location, target=(0.0, 0.0, 0.0), power: float = 1000.0, size: float = math.radians(45),
                   blend: float = 0.15, color=(1.0, 1.0, 1.0), radius: float = 0.0, name: str = "Spot"):
    """Spot light (``size`` = full cone angle in radians, Blender's spot_size) aimed at ``target``."""
    obj = _light("SPOT", name, location, target, color, power)
    obj.data.spot_size, obj.data.spot_blend, obj.data.shadow_soft_size = size, blend, radius
    return obj


def add_area_light(location, target=(0.0, 0.0, 0.0), power: float = 100.0, size: float = 1.0,
                   size_y: float | None = None, shape: str = "SQUARE", color=(1.0, 1.0, 1.0), name: str = "Area"):
    """Area light (emits along its −Z, aimed at ``target``); shape SQUARE, RECTANGLE, DISK or ELLIPSE."""
    obj = _light("AREA", name, location, target, color, power)
    obj.data.shape, obj.data.size = shape, size
    if size_y is not None:
        obj.data.size_y = size_y
    return obj


def _mesh_object(name, mesh, location, material, smooth):
    import bpy

    if smooth:
        mesh.shade_smooth()
    if material is not None:
        mesh.materials.append(material)
    obj = _link(bpy.data.objects.new(name, mesh))
    obj.location = location
    return obj


def _bmesh_mesh(name, build):
    import bmesh
    import bpy

    bm = bmesh.new()
    bm.loops.layers.uv.new("UVMap")  # calc_uvs=True fills the first UV layer
    build(bm)
    mesh = bpy.data.meshes.new(name)
    bm.to_mesh(mesh)
    bm.free()
    return mesh


def add_uv_sphere(location=(0.0, 0.0, 0.0), radius: float = 1.0, *, segments: int = 48, rings: int = 24,
                  material=None, smooth: bool = True, name: str = "Sphere"):
    """UV sphere (smooth shaded by default) with a UV map."""
    import bmesh

    mesh = _bmesh_mesh(name, lambda bm: bmesh.ops.create_uvsphere(
        bm, u_segments=segments, v_segments=rings, radius=radius, calc_uvs=True))
    return _mesh_object(name, mesh, location, material, smooth)


def add_plane(location=(0.0, 0.0, 0.0), size: float = 2.0, *, material=None, name: str = "Plane"):
    """Square plane of edge ``size`` facing +Z, with a UV map (0..1)."""
    import bmesh

    mesh = _bmesh_mesh(name, lambda bm: bmesh.ops.create_grid(
        bm, x_segments=1, y_segments=1, size=size / 2, calc_uvs=True))
    return _mesh_object(name, mesh, location, material, False)


def add_cube(location=(0.0, 0.0, 0.0), size: float = 2.0, *, material=None, smooth: bool = False,
             name: str = "Cube"):
    """Cube of edge ``size`` (Blender's default cube has size 2), with a UV map."""
    import bmesh

    mesh = _bmesh_mesh(name, lambda bm: bmesh.ops.create_cube(bm, size=size, calc_uvs=True))
    return _mesh_object(name, mesh, location, material, smooth)


def principled_material(name: str = "Material", **inputs):
    """A node material whose Principled BSDF has the given inputs, keyed by socket name (``**{"Base Color":
    (r, g, b), "Metallic": 1.0, "Transmission Weight": 1.0}``); RGB triples get alpha 1. Python-friendly aliases:
    base_color, metallic, roughness, ior, transmission, alpha, emission_color, emission_strength,
    specular (= Specular IOR Level)."""
    import bpy

    aliases = {"base_color": "Base Color", "metallic": "Metallic", "roughness": "Roughness", "ior": "IOR",
               "transmission": "Transmission Weight", "alpha": "Alpha", "emission_color": "Emission Color",
               "emission_strength": "Emission Strength", "specular": "Specular IOR Level"}
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    bsdf = principled_node(mat)
    for key, value in inputs.items():
        sock = bsdf.inputs[aliases.get(key, key)]
        if isinstance(value, (tuple, list)) and len(value) == 3 and len(sock.default_value) == 4:
            value = tuple(value) + (1.0,)
        sock.default_value = value
    if "Base Color" in inputs or "base_color" in inputs:
        mat.diffuse_color = tuple(bsdf.inputs["Base Color"].default_value)
    return mat


def node_material(name: str):
    """A node material holding only its Material Output: (material, node tree, output node)."""
    import bpy

    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    nt = mat.node_tree
    for n in list(nt.nodes):
        if n.type != "OUTPUT_MATERIAL":
            nt.nodes.remove(n)
    return mat, nt, next(n for n in nt.nodes if n.type == "OUTPUT_MATERIAL")


def shader_material(name: str, node_type: str, **inputs):
    """A node material whose surface is one shader node of ``node_type`` (e.g. "ShaderNodeBsdfGlass") with the
    given inputs by socket name (RGB triples get alpha 1); returns (material, node)."""
    mat, nt, out = node_material(name)
    node = nt.nodes.new(node_type)
    for key, value in inputs.items():
        sock = node.inputs[key]
        if isinstance(value, (tuple, list)) and len(value) == 3 and len(sock.default_value) == 4:
            value = tuple(value) + (1.0,)
        sock.default_value = value
    nt.links.new(node.outputs[0], out.inputs["Surface"])
    return mat, node


def principled_node(material):
    """The material's Principled BSDF node."""
    for node in material.node_tree.nodes:
        if node.type == "BSDF_PRINCIPLED":
            return node
    raise ValueError(f"material {material.name!r} has no Principled BSDF")


def set_world(color=(0.05, 0.05, 0.05), strength: float = 1.0):
    """A world whose Background node has this colour and strength (also ``world.color``)."""
    import bpy

    scene = bpy.context.scene
    world = scene.world or bpy.data.worlds.new("World")
    scene.world = world
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    world.color = color
    bg = next((n for n in world.node_tree.nodes if n.type == "BACKGROUND"), None)
    if bg is None:
        bg = world.node_tree.nodes.new("ShaderNodeBackground")
        out = next(n for n in world.node_tree.nodes if n.type == "OUTPUT_WORLD")
        world.node_tree.links.new(bg.outputs[0], out.inputs["Surface"])
    bg.inputs["Color"].default_value = tuple(color) + (1.0,)
    bg.inputs["Strength"].default_value = strength
    return world


# ---------------------------------------------------------------------------------------------------- Cycles
def set_cycles_whitted(scene=None, samples: int = 64, max_depth: int = 8, *, seed: int = 0):
    """Tell Cycles to render what a Whitted tracer renders: :func:`blender_kit.cycles.whitted_cycles_settings` (every
    setting explained there), plus point-light radius 0 and sun angle 0 on the lights now in the scene."""
    import bpy

    from blender_kit.cycles import whitted_cycles_settings

    scene = scene or bpy.context.scene
    whitted_cycles_settings(scene, depth=max_depth, samples=samples, seed=seed)
    for obj in scene.objects:
        if obj.type == "LIGHT":
            if obj.data.type in ("POINT", "SPOT"):
                obj.data.shadow_soft_size = 0.0
            elif obj.data.type == "SUN":
                obj.data.angle = 0.0
    return scene


#: Blender 5.0 writes some passes under new names; read_exr reports them under the classic ones.
PASS_ALIASES = {"Object Index": "IndexOB", "Material Index": "IndexMA", "Z": "Depth"}


def plain_whitted(scene, denoise: bool = False) -> None:
    """Whitted's F12 without its Denoise (Render Properties > Denoise is on by default, as Cycles' is): the plain
    render the comparisons and benchmarks measure, as ``whitted_cycles_settings`` turns Cycles' denoiser off. A scene
    without the add-on's settings is left alone."""
    props = getattr(scene, "whitted", None)
    if props is not None:
        props.denoise = bool(denoise)


def read_exr(path) -> dict:
    """A (multilayer) EXR as linear float32 arrays by pass: ``{"rgba": (H, W, 4), "Depth": (H, W),
    "Normal": (H, W, 3), "IndexOB": (H, W), ...}``; single-layer files give just "rgba"."""
    import OpenImageIO as oiio

    first = oiio.ImageBuf(os.fspath(path))
    if first.has_error:
        raise ValueError(f"cannot read {path}: {first.geterror()}")
    # Blender writes multilayer EXRs as multi-part files: one part (OIIO subimage) per pass.
    arrays, names = [], []
    for sub in range(max(1, first.nsubimages)):
        buf = oiio.ImageBuf(os.fspath(path), sub, 0) if sub else first
        spec = buf.spec()
        arrays.append(np.asarray(buf.get_pixels(oiio.FLOAT), np.float32).reshape(spec.height, spec.width,
                                                                                 spec.nchannels))
        names += list(spec.channelnames)
    px = np.concatenate(arrays, axis=-1)
    groups: dict[str, list[int]] = {}
    for i, n in enumerate(names):
        parts = n.split(".")
        key = parts[-2] if len(parts) >= 2 else ""
        groups.setdefault(key, []).append(i)
    out = {}
    for key, idx in groups.items():
        arr = px[..., idx]
        if key in ("", "Combined", "Image"):
            order = [names[i].split(".")[-1] for i in idx]
            rgba = np.ones(arr.shape[:2] + (4,), np.float32)
            for j, ch in enumerate("RGBA"):
                if ch in order:
                    rgba[..., j] = arr[..., order.index(ch)]
            out["rgba"] = rgba
        else:
            out[PASS_ALIASES.get(key, key)] = arr[..., 0] if arr.shape[-1] == 1 else arr
    return out


def render_exr(scene=None, path: str | None = None, *, engine: str | None = None, passes=(),
               denoise: bool = False) -> dict:
    """F12 into a 32-bit EXR (multilayer when ``passes`` name any of "Depth", "Normal", "IndexOB") and read it back
    with :func:`read_exr`. ``engine`` switches the render engine first ("CYCLES", "WHITTED"). The file goes to
    ``path`` or a fresh temporary directory. Whitted's Denoise (on in a new scene, as Cycles' is) is set to
    ``denoise``: off, the plain render that tests compare pixel for pixel (:func:`plain_whitted`)."""
    import bpy

    scene = scene or bpy.context.scene
    if engine is not None:
        scene.render.engine = engine
    plain_whitted(scene, denoise)
    layer = scene.view_layers[0]
    layer.use_pass_z = "Depth" in passes
    layer.use_pass_normal = "Normal" in passes
    layer.use_pass_object_index = "IndexOB" in passes
    s = scene.render.image_settings
    multilayer = bool(passes)
    if hasattr(s, "media_type"):
        s.media_type = "MULTI_LAYER_IMAGE" if multilayer else "IMAGE"
    s.file_format = "OPEN_EXR_MULTILAYER" if multilayer else "OPEN_EXR"
    s.color_mode = "RGBA"
    s.color_depth = "32"
    if path is None:  # a temporary file, removed once read
        with tempfile.TemporaryDirectory(prefix="whitted-bpy-") as tmp:
            return render_exr(scene, os.path.join(tmp, "render.exr"), engine=None, passes=passes)
    scene.render.filepath = path
    scene.render.use_file_extension = False
    bpy.ops.render.render(write_still=True)
    if not os.path.exists(path):
        raise RuntimeError(f"render_exr: Blender wrote no image to {path}")
    return read_exr(path)


def render_cycles_exr(scene=None, path: str | None = None, *, samples: int = 64, passes=()) -> dict:
    """:func:`set_cycles_whitted` then :func:`render_exr` with Cycles."""
    scene = set_cycles_whitted(scene, samples=samples)
    return render_exr(scene, path, passes=passes)

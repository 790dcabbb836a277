"""Blender's world -> the tracer's background, ambient and :class:`tracer.Environment`.

- Background node with a constant colour: ``background = ambient = colour × strength``, no environment.
- Environment Texture (equirectangular) feeding the Background colour, optionally through a Mapping node
  (Point/Texture: its rotation) and Texture Coordinate Generated/Object: the image as a lat-long environment in
  Blender's orientation (the tracer's mapping is Cycles' ``direction_to_equirectangular``).
- Anything else a world can be (gradients, noise on the direction, mixes of backgrounds, a linked strength, an
  Environment Texture behind other nodes): the world's node tree is translated like a material's
  (addon/shader_tree.py, Background as the emission) and **evaluated by the tracer's shader VM per direction**
  into a :data:`PROGRAM_SIZE` lat-long environment (tracer.shading.world), cached by the tree's hash.
- What the VM does not evaluate (Sky Texture, Light Path, a Mirror Ball environment, …): **baked with Blender
  itself** — Cycles renders the world alone through an equirectangular panoramic camera at
  the world's origin looking along +X with +Z up (:data:`BAKE_SIZE`, :data:`BAKE_SAMPLES`), which is exactly the
  tracer's lat-long layout, and the image becomes the environment. Bakes are cached in memory by a hash of the
  world's node tree (node types, their settings, socket values, links, image names), so re-exports (viewport,
  animation frames that do not change the world) do not bake again. Inside a running render (F12 with Whitted,
  where Blender cannot start a second render) the bake runs in a background Blender process
  (``bpy.app.binary_path -b``) on a copy of the world; where neither is possible the world's mean colour is used
  with one warning.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import tempfile

import numpy as np

from .nodes import read_world
from .shader_tree import world_graph

from .bundled import tracer, tracer_module

#: Size (width, height) of a baked world: 2:1 lat-long, 0.7° per texel. Measured on the Sky Texture scene: 256 × 128
#: blurs the horizon (36.9 dB against Cycles), 512 × 256 gives 42.4 dB; a bake takes about 4–7 s on 2 shared cores,
#: most of it Blender's sky precomputation, once per world change. A sun disc smaller than a texel is blurred.
BAKE_SIZE = (512, 256)
#: Cycles samples per texel of a bake (the box filter averages the texel's solid angle).
BAKE_SAMPLES = 16
_BAKES: dict[str, np.ndarray] = {}


def world_from_blender(world, warnings: list, images: dict | None = None):
    """(background (3,), ambient (3,), environment or None) of a Blender world."""
    images = {} if images is None else images
    w = read_world(world, warnings.append, images)
    if "environment" in w:
        tex = w["environment"]
        env = tracer.Environment(image=tex.pixels[..., :3], strength=w["strength"], rotation=w["rotation"])
        return np.asarray(w["color"], np.float32), env.average().astype(np.float32), env
    if "unreadable" in w:
        image = program_world(world, images)
        if image is not None:
            env = tracer.Environment(image=image)
            mean = env.average().astype(np.float32)
            return mean, mean, env
        try:
            image = bake_world(world)
        except Exception as exc:  # no way to render here: say so, keep the best colour
            warnings.append(f"world {world.name!r}: node {w['unreadable']!r} needs a bake, which failed ({exc}); "
                            f"using the world colour")
            c = np.asarray(w["color"], np.float32)
            return c, c, None
        env = tracer.Environment(image=image)
        mean = env.average().astype(np.float32)
        return mean, mean, env
    c = np.asarray(w["color"], np.float32)
    return c, c, None


# ---------------------------------------------------------------------------------------------------- the VM
#: Size of a world evaluated by the VM (tracer.shading.world): 0.35° per texel.
PROGRAM_SIZE = (1024, 512)


def program_world(world, images: dict, size=PROGRAM_SIZE) -> np.ndarray | None:
    """The world's tree evaluated by the tracer's shader VM per direction (a lat-long image), or None when a node
    in it is not evaluated there (Sky Texture, Light Path, …: then Blender bakes it). Cached like a bake."""
    key = f"vm-{world_hash(world)}-{size}"
    if key not in _BAKES:
        said: list = []
        try:
            g = world_graph(world, said.append, images)
        except Exception as exc:  # noqa: BLE001 - an untranslatable tree is the bake's job
            said.append(str(exc))
            g = None
        image = None
        if g is not None and not said:
            image = tracer_module("shading.world").world_image(g, size[0], size[1])
        _BAKES[key] = image
    return _BAKES[key]


# ---------------------------------------------------------------------------------------------------- baking
def world_hash(world) -> str:
    """A hash of everything in the world's node tree that changes its picture."""
    h = hashlib.sha256()
    tree = world.node_tree
    h.update(repr(tuple(world.color)).encode())
    if tree is None:
        return h.hexdigest()[:24]
    for node in sorted(tree.nodes, key=lambda n: n.name):
        h.update(f"{node.name}|{node.bl_idname}|{getattr(node, 'mute', False)}".encode())
        for prop in node.bl_rna.properties:
            if prop.is_readonly or prop.type in ("POINTER", "COLLECTION") or prop.identifier in (
                    "name", "label", "location", "width", "height", "select", "show_options", "show_preview",
                    "hide", "show_texture", "color", "use_custom_color", "location_absolute", "warning_propagation"):
                continue
            try:
                h.update(f"{prop.identifier}={getattr(node, prop.identifier)!r}".encode())
            except Exception:  # noqa: BLE001 - a property that cannot be read does not change the picture
                pass
        image = getattr(node, "image", None)
        if image is not None:
            h.update(f"image={image.name}|{image.filepath}|{tuple(image.size)}|{image.is_dirty}".encode())
        for sock in node.inputs:
            v = getattr(sock, "default_value", None)
            try:
                v = tuple(v)
            except TypeError:
                pass
            h.update(f"{sock.identifier}={v!r}".encode())
    for link in tree.links:
        h.update(f"{link.from_node.name}.{link.from_socket.identifier}->{link.to_node.name}."
                 f"{link.to_socket.identifier}|{link.is_muted}".encode())
    return h.hexdigest()[:24]


def bake_world(world, size=BAKE_SIZE, samples: int = BAKE_SAMPLES) -> np.ndarray:
    """(H, W, 3) scene-linear lat-long image of the world, rendered by Cycles (cached by :func:`world_hash`)."""
    import bpy

    key = f"{world_hash(world)}-{size}-{samples}"
    if key not in _BAKES:
        with tempfile.TemporaryDirectory(prefix="whitted-world-") as tmp:
            out = os.path.join(tmp, "world.exr")
            if not bpy.app.is_job_running("RENDER"):
                render_world_latlong(world.name, out, size[0], size[1], samples)
            else:
                _bake_in_background(world, tmp, out, size, samples)
            _BAKES[key] = tracer.read_image(out)[..., :3].astype(np.float32)
    return _BAKES[key]


def render_world_latlong(world_name: str, out: str, width: int, height: int, samples: int) -> None:
    """Render the world ``world_name`` (in bpy.data) alone to a lat-long EXR with Cycles: a temporary scene with
    only a panoramic equirectangular camera at the origin looking along +X, +Z up (u = 0.5 looks along +X, the top
    row is the zenith: the tracer's Environment layout). Standalone (runs in a background Blender too)."""
    import math as m

    import bpy as b

    scene = b.data.scenes.new("whitted world bake")
    cam_data = b.data.cameras.new("whitted world bake")
    cam = b.data.objects.new("whitted world bake", cam_data)
    try:
        scene.world = b.data.worlds[world_name]
        scene.collection.objects.link(cam)
        cam_data.type = "PANO"
        cam_data.panorama_type = "EQUIRECTANGULAR"
        cam_data.latitude_min, cam_data.latitude_max = -m.pi / 2, m.pi / 2
        cam_data.longitude_min, cam_data.longitude_max = -m.pi, m.pi
        cam.rotation_euler = (m.pi / 2, 0.0, -m.pi / 2)  # -Z onto +X, +Y (up) onto +Z
        scene.camera = cam
        r = scene.render
        r.engine = "CYCLES"
        r.resolution_x, r.resolution_y, r.resolution_percentage = int(width), int(height), 100
        r.film_transparent = False
        c = scene.cycles
        c.device = "CPU"
        c.samples = int(samples)
        c.use_adaptive_sampling = False
        c.use_denoising = False
        c.pixel_filter_type = "BOX"
        c.filter_width = 1.0
        c.film_exposure = 1.0
        scene.view_settings.view_transform = "Standard"
        scene.view_settings.look = "None"
        scene.view_settings.exposure = 0.0
        scene.view_settings.gamma = 1.0
        s = r.image_settings
        if hasattr(s, "media_type"):
            s.media_type = "IMAGE"
        s.file_format = "OPEN_EXR"
        s.color_depth = "32"
        s.color_mode = "RGB"
        r.filepath = out
        r.use_file_extension = False
        b.ops.render.render(write_still=True, scene=scene.name)
    finally:
        b.data.objects.remove(cam)
        b.data.cameras.remove(cam_data)
        b.data.scenes.remove(scene)


def _bake_in_background(world, tmp: str, out: str, size, samples: int) -> None:
    """Inside a running render: write the world to a .blend and render it in a background Blender process."""
    import inspect

    import bpy

    exe = bpy.app.binary_path
    if not exe or not os.path.exists(exe):
        raise RuntimeError("a render is running and no Blender executable is available for a background bake")
    blend = os.path.join(tmp, "world.blend")
    bpy.data.libraries.write(blend, {world}, fake_user=True)
    script = (inspect.getsource(render_world_latlong) +
              f"\nrender_world_latlong({world.name!r}, {out!r}, {int(size[0])}, {int(size[1])}, {int(samples)})\n")
    done = subprocess.run([exe, "-b", "--factory-startup", blend, "--python-expr", script],
                          capture_output=True, text=True, timeout=300)
    if done.returncode != 0 or not os.path.exists(out):
        tail = (done.stderr or done.stdout).strip().splitlines()[-1:] or ["no output"]
        raise RuntimeError(f"background Blender exited with {done.returncode}: {tail[0]}")


"""Blender world node trees -> the tracer's environment description, and Blender images -> linear pixels.

    world = read_world(world, warn, images)      # addon/world.py turns it into a tracer.Environment or a bake
    pixels = image_rgba(image)                   # (H, W, 4) scene-linear float32, top row first

Materials are not read here: :mod:`addon.shader_tree` translates every material node tree into the tracer's shader
graph (docs/addon.md). A world is read as a Background node of a constant colour, or of an equirectangular
Environment / Image Texture (optionally through Texture Coordinate and a Mapping node's rotation); anything else
is returned as ``{"unreadable": node}`` for :mod:`addon.world` to bake with Cycles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .bundled import tracer_module
from .image_cache import cached_pixels

srgb_to_linear = tracer_module("colorspace").srgb_to_linear

#: What Cycles renders for an image it cannot read (TEX_IMAGE_MISSING_R/G/B): magenta.
MISSING_IMAGE = (1.0, 0.0, 1.0)

#: Blender's Extension (Image Texture) -> the tracer's wrap mode.
WRAP = {"REPEAT": "repeat", "EXTEND": "clamp", "CLIP": "black", "MIRROR": "mirror"}


@dataclass
class TextureRef:
    """One texture lookup as the reader found it: pixels and how they are addressed.

    pixels     (H, W, 4) float32, scene linear (colour space decoded here), straight alpha, top row first
    wrap       "repeat" | "clamp" | "mirror" | "black" (the Image Texture's Extension)
    uv_map     name of the UV map, '' = the mesh's active render UV map
    transform  (3, 3) affine map on (u, v, 1): the Mapping node (Point) in front of the texture
    scale, bias  (4,): value = texel·scale + bias (normal maps: 2, −1)
    label      the node's name for messages
    """

    pixels: np.ndarray
    wrap: str = "repeat"
    uv_map: str = ""
    transform: np.ndarray = field(default_factory=lambda: np.eye(3))
    scale: tuple = (1.0, 1.0, 1.0, 1.0)
    bias: tuple = (0.0, 0.0, 0.0, 0.0)
    label: str = ""

    def values(self, channel: int) -> np.ndarray:
        """Texel values after scale and bias: (H, W, 3) for channel −1, else (H, W)."""
        s, b = np.float32(self.scale), np.float32(self.bias)
        if channel < 0:
            return self.pixels[..., :3] * s[:3] + b[:3]
        return self.pixels[..., channel] * s[channel] + b[channel]


class Reader:
    """Reads one world tree; collects at most one warning per key."""

    def __init__(self, owner: str, warn, images: dict):
        self.owner = owner
        self._warn = warn
        self.images = images  # image name -> (H, W, 4) pixels, shared by the whole export
        self._said: set = set()

    def warn(self, key: str, message: str) -> None:
        if key not in self._said:
            self._said.add(key)
            self._warn(f"{self.owner}: {message}")

    def image_texture(self, node) -> TextureRef | None:
        """An Image Texture node's pixels (loaded once per image) and wrap mode."""
        img = node.image
        if img is None:
            self.warn(node.name, f"Image Texture {node.name!r} has no image; using the socket's value")
            return None
        if img.name not in self.images:
            try:
                self.images[img.name] = image_rgba(img)
            except Exception as exc:  # missing file, unreadable pixels
                self.images[img.name] = None
                self.warn(img.name, f"image {img.name!r} not loaded ({exc}); magenta stands in, as in Cycles")
        pixels = self.images[img.name]
        if pixels is None:
            return None
        return TextureRef(pixels=pixels, wrap=WRAP.get(node.extension, "repeat"), label=node.name)


# ---------------------------------------------------------------------------------------------- world
def read_world(world, warn, images: dict) -> dict:
    """{"color": (3,) colour × strength} or {"environment": TextureRef, "strength": s, "rotation": (3, 3)
    world -> environment, "color": mean colour}, or {"unreadable": node} for setups only a bake can read."""
    if world is None:
        return {"color": np.zeros(3, np.float32)}
    r = Reader(f"world {world.name!r}", warn, images)
    tree = world.node_tree
    if tree is None:
        return {"color": np.asarray(world.color[:3], np.float32)}
    out = output_node(tree, "OUTPUT_WORLD")
    bg = linked(out.inputs.get("Surface"))[0] if out is not None else None
    if out is None:
        return {"color": np.asarray(world.color[:3], np.float32)}
    if bg is None:
        return {"color": np.zeros(3, np.float32)}
    if bg.bl_idname != "ShaderNodeBackground":
        return {"unreadable": bg.name, "color": np.asarray(world.color[:3], np.float32)}
    strength_sock = _input(bg, "Strength")
    if strength_sock.is_linked:
        return {"unreadable": linked(strength_sock)[0].name, "color": np.asarray(world.color[:3], np.float32)}
    strength = float(strength_sock.default_value)
    col_sock = _input(bg, "Color")
    src, out_name = linked(col_sock)
    const = np.asarray(col_sock.default_value[:3], np.float32)
    if src is None:
        return {"color": const * strength}
    if src.bl_idname in ("ShaderNodeTexEnvironment", "ShaderNodeTexImage") and out_name == "Color":
        if src.bl_idname == "ShaderNodeTexEnvironment" and src.projection != "EQUIRECTANGULAR":
            return {"unreadable": src.name, "color": const * strength}
        if src.image is None:
            return {"unreadable": src.name, "color": const * strength}
        rotation, ok = world_vector(_input(src, "Vector"))
        if not ok:
            return {"unreadable": src.name, "color": const * strength}
        tex = r.image_texture(src) if src.bl_idname == "ShaderNodeTexImage" else _env_texture(r, src)
        if tex is None:  # a file Blender could not read: Cycles' missing-image magenta
            return {"color": np.array(MISSING_IMAGE, np.float32) * strength}
        mean = tex.values(-1).reshape(-1, 3).mean(0)
        return {"environment": tex, "strength": strength, "rotation": rotation, "color": mean * strength,
                "image_texture": src.bl_idname == "ShaderNodeTexImage"}
    return {"unreadable": src.name, "color": const * strength}



def _env_texture(r: Reader, node) -> TextureRef | None:
    img = node.image
    if img.name not in r.images:
        try:
            r.images[img.name] = image_rgba(img)
        except Exception as exc:
            r.images[img.name] = None
            r.warn(img.name, f"image {img.name!r} not loaded ({exc}); magenta stands in, as in Cycles")
    px = r.images[img.name]
    return None if px is None else TextureRef(pixels=px, wrap="repeat", label=node.name)



def world_vector(sock) -> tuple[np.ndarray, bool]:
    """(3, 3) world -> environment rotation of an environment lookup's Vector input: unlinked or Texture
    Coordinate Generated/Object = identity; a Mapping node's rotation (its inverse for Texture type); anything
    else is not readable (False)."""
    node, out = linked(sock) if sock is not None else (None, None)
    if node is None:
        return np.eye(3), True
    if node.bl_idname == "ShaderNodeTexCoord" and out in ("Generated", "Object"):
        return np.eye(3), True
    if node.bl_idname == "ShaderNodeMapping":
        inner, ok = world_vector(_input(node, "Vector"))
        rot = _euler(np.asarray(_default(_input(node, "Rotation"), (0, 0, 0)), np.float64))
        if node.vector_type == "TEXTURE":
            rot = rot.T
        return rot @ inner, ok
    return np.eye(3), False



# ---------------------------------------------------------------------------------------------- helpers
def linked(sock):
    """(from node, from socket name) of a linked input, reroutes and muted links skipped; (None, None) if none."""
    if sock is None or not sock.is_linked:
        return None, None
    link = sock.links[0]
    if getattr(link, "is_muted", False):
        return None, None
    node, out = link.from_node, link.from_socket.name
    while node.bl_idname == "NodeReroute":
        if not node.inputs[0].is_linked:
            return None, None
        link = node.inputs[0].links[0]
        node, out = link.from_node, link.from_socket.name
    return node, out



def output_node(tree, kind: str):
    outs = [n for n in tree.nodes if n.type == kind]
    active = [n for n in outs if n.is_active_output and getattr(n, "target", "ALL") in ("ALL", "CYCLES")]
    return (active or [n for n in outs if getattr(n, "target", "ALL") in ("ALL", "CYCLES")] or outs or [None])[0]



def _input(node, *names):
    for n in names:
        s = node.inputs.get(n)
        if s is not None and getattr(s, "enabled", True):
            return s
    return None



def _default(sock, default):
    if sock is None or not hasattr(sock, "default_value"):
        return default
    v = sock.default_value
    try:
        return tuple(float(x) for x in v)
    except TypeError:
        return float(v)



def _euler(xyz) -> np.ndarray:
    """Blender's XYZ Euler rotation matrix (R = Rz·Ry·Rx)."""
    x, y, z = xyz
    cx, sx, cy, sy, cz, sz = math.cos(x), math.sin(x), math.cos(y), math.sin(y), math.cos(z), math.sin(z)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx



def image_rgba(image) -> np.ndarray:
    """(H, W, 4) scene-linear float32 pixels of a Blender image, top row first, straight alpha; read once per file
    version across renders (:mod:`addon.image_cache`: read-only arrays)."""
    return cached_pixels(image, _read_rgba)


def _read_rgba(image) -> np.ndarray:
    """:func:`image_rgba` read from Blender.

    ``Image.pixels`` holds float images linear (Blender converts at load) and byte images as stored, so byte
    images are decoded from their colour space: sRGB with the sRGB transfer function; Non-Color / Linear as is."""
    w, h = image.size
    c = image.channels
    if w == 0 or h == 0:
        raise ValueError(f"image {image.name!r} has no pixels (missing file?)")
    buf = np.empty(w * h * c, np.float32)
    image.pixels.foreach_get(buf)
    px = buf.reshape(h, w, c)[::-1]
    out = np.ones((h, w, 4), np.float32)
    if c >= 3:
        out[..., :3] = px[..., :3]
    else:
        out[..., :3] = px[..., :1]
    if c in (2, 4):
        out[..., 3] = px[..., -1]
    space = image.colorspace_settings.name.lower()
    if not image.is_float and "srgb" in space:
        out[..., :3] = srgb_to_linear(out[..., :3])
    return np.ascontiguousarray(np.nan_to_num(out), dtype=np.float32)

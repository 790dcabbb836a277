"""Blender shader node trees -> the tracer's Principled material description (docs/materials-api.md fields).

    fields, world = read_material(material, warn), read_world(world, warn)

One small function per node type. A material is read once (not per mesh); the result is a plain dict of the
Principled model's fields, in which any parameter P may be a constant ``P`` plus a lookup ``P_texture``
(a :class:`TextureRef`) and ``P_channel`` (−1 = rgb, 0..3 = one channel):

    base_color (3)  roughness  metallic  specular (Specular IOR Level; 0.5 = F0 from ior)  ior  transmission
    alpha (Cycles' blend; Blender sets no threshold)  emission (3, colour × strength)  normal_texture + normal_strength
    vertex_color (a Color Attribute name, '' = the active one, or None)  k_m (mirror weight of smooth metals)

What each node maps to, and what is approximated, is the table in docs/addon.md. Anything the reader cannot
follow produces ONE warning per material naming the node and falls back to the best constant it can find (the
socket's own value, the mean of a checker's colours, a shader's colour), never a silent drop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

try:  # inside the installed extension the tracer is bundled next to this module
    from .tracer.texture import srgb_to_linear
except ImportError:  # the repository's ``addon`` package uses the top-level tracer
    from tracer.texture import srgb_to_linear

#: Luminance weights Blender uses when a colour socket feeds a float socket (Rec.709, its default scene linear).
LUMINANCE = np.array([0.2126, 0.7152, 0.0722], np.float32)
#: Blender's Extension (Image Texture) -> the tracer's wrap mode.
WRAP = {"REPEAT": "repeat", "EXTEND": "clamp", "CLIP": "black", "MIRROR": "mirror"}
#: Resolution (texels per checker period, per axis) of a baked Checker Texture.
CHECKER_TEXELS = 64


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
    """Reads one node tree; collects at most one warning per unsupported node (or input)."""

    def __init__(self, owner: str, warn, images: dict):
        self.owner = owner
        self._warn = warn
        self.images = images  # image name -> (H, W, 4) pixels, shared by the whole export
        self._said: set = set()
        self.viewport_colour = (0.8, 0.8, 0.8)

    def warn(self, key: str, message: str) -> None:
        if key not in self._said:
            self._said.add(key)
            self._warn(f"{self.owner}: {message}")

    # ------------------------------------------------------------------ socket values
    def colour(self, sock, default=(0.8, 0.8, 0.8)):
        """(constant rgb, TextureRef | None, vertex-colour name | None) of a colour socket."""
        if sock is None:
            return np.asarray(default, np.float32), None, None
        node, out = linked(sock)
        const = np.asarray(_default(sock, default)[:3], np.float32)
        if node is None:
            return const, None, None
        fn = COLOUR_NODES.get(node.bl_idname)
        if fn is None:
            self.warn(node.name, f"node {node.name!r} ({node.bl_idname}) on {sock.name} is not supported; "
                                 f"using the socket's colour {tuple(np.round(const, 3))}")
            return const, None, None
        return fn(self, node, out, const)

    def scalar(self, sock, default=0.0):
        """(constant, TextureRef | None, channel) of a float socket; a colour texture feeding it becomes its
        luminance (as Blender converts colour to float)."""
        if sock is None:
            return float(default), None, 0
        const = float(_default(sock, default))
        node, out = linked(sock)
        if node is None:
            return const, None, 0
        if node.bl_idname == "ShaderNodeTexImage":
            tex = self.image_texture(node)
            if tex is None:
                return const, None, 0
            if out == "Alpha":
                return 1.0, tex, 3
            lum = np.repeat((tex.pixels[..., :3] @ LUMINANCE)[..., None], 4, axis=2)
            return 1.0, replace(tex, pixels=np.ascontiguousarray(lum)), 0
        if node.bl_idname in ("ShaderNodeSeparateColor", "ShaderNodeSeparateRGB"):
            src = _input(node, "Color", "Image")
            c, tex, _vc = self.colour(src)
            ch = {"Red": 0, "R": 0, "Green": 1, "G": 1, "Blue": 2, "B": 2}.get(out, 0)
            if getattr(node, "mode", "RGB") != "RGB":
                self.warn(node.name, f"node {node.name!r}: Separate Color in {node.mode} mode is read as RGB")
            return (1.0, tex, ch) if tex is not None else (float(c[ch]), None, 0)
        if node.bl_idname == "ShaderNodeValue":
            return float(node.outputs[0].default_value), None, 0
        self.warn(node.name, f"node {node.name!r} ({node.bl_idname}) on {sock.name} is not supported; "
                             f"using the socket's value {const:.3g}")
        return const, None, 0

    # ------------------------------------------------------------------ textures
    def image_texture(self, node) -> TextureRef | None:
        img = node.image
        if img is None:
            self.warn(node.name, f"Image Texture {node.name!r} has no image (pink in Cycles); using the socket's "
                                 "value")
            return None
        if img.name not in self.images:
            try:
                self.images[img.name] = image_rgba(img)
            except Exception as exc:  # missing file, unreadable pixels
                self.images[img.name] = None
                self.warn(img.name, f"image {img.name!r} not loaded ({exc}); using the socket's value")
        pixels = self.images[img.name]
        if pixels is None:
            return None
        if node.projection != "FLAT":
            self.warn(node.name + "proj", f"Image Texture {node.name!r}: {node.projection} projection is read as "
                                          "Flat")
        if node.interpolation not in ("Linear", "Smart", "Cubic"):
            self.warn(node.name + "interp", f"Image Texture {node.name!r}: {node.interpolation} interpolation "
                                            "is read as Linear")
        uv_map, transform = self.vector(_input(node, "Vector"), node.name)
        return TextureRef(pixels=pixels, wrap=WRAP.get(node.extension, "repeat"), uv_map=uv_map,
                          transform=transform, label=node.name)

    def vector(self, sock, label) -> tuple[str, np.ndarray]:
        """(UV map name, (3, 3) transform) of a texture's Vector input: unlinked = active UV; UV Map node;
        Texture Coordinate's UV; Mapping nodes (Point, Texture) composed in front."""
        node, out = linked(sock) if sock is not None else (None, None)
        if node is None:
            return "", np.eye(3)
        if node.bl_idname == "ShaderNodeMapping":
            uv_map, inner = self.vector(_input(node, "Vector"), label)
            return uv_map, mapping_matrix(node, self) @ inner
        if node.bl_idname == "ShaderNodeUVMap":
            return node.uv_map, np.eye(3)
        if node.bl_idname == "ShaderNodeTexCoord" and out == "UV":
            return "", np.eye(3)
        what = f"{node.bl_idname}.{out}" if out else node.bl_idname
        self.warn(node.name, f"texture coordinates {what} ({node.name!r}) for {label!r} are not supported; "
                             "the active UV map is used")
        return "", np.eye(3)


# ---------------------------------------------------------------------------------------------- colour nodes
def _tex_image_colour(r: Reader, node, out, const):
    tex = r.image_texture(node)
    if tex is None:
        return const, None, None
    if out == "Alpha":
        a = np.repeat(tex.pixels[..., 3:4], 4, axis=2)
        return np.ones(3, np.float32), replace(tex, pixels=np.ascontiguousarray(a)), None
    return np.ones(3, np.float32), tex, None


def _color_attribute(r: Reader, node, out, const):
    if out == "Alpha":
        r.warn(node.name, f"Color Attribute {node.name!r}: its Alpha output is not supported; using 1")
        return np.ones(3, np.float32), None, None
    return np.ones(3, np.float32), None, node.layer_name


def _checker(r: Reader, node, out, const):
    c1, _t1, _v1 = r.colour(_input(node, "Color1"), (0.8, 0.8, 0.8))
    c2, _t2, _v2 = r.colour(_input(node, "Color2"), (0.2, 0.2, 0.2))
    scale = float(_default(_input(node, "Scale"), 5.0))
    vec = _input(node, "Vector")
    src, src_out = linked(vec)
    uv_source = src is not None and (src.bl_idname in ("ShaderNodeUVMap", "ShaderNodeMapping")
                                     or (src.bl_idname == "ShaderNodeTexCoord" and src_out == "UV"))
    if out == "Fac" or not uv_source or not math.isfinite(scale) or scale <= 0:
        mean = (c1 + c2) / 2
        r.warn(node.name, f"Checker Texture {node.name!r} on generated/object coordinates (or its Fac) is not "
                          f"supported; using the mean of its colours {tuple(np.round(mean, 3))}")
        return mean, None, None
    uv_map, transform = r.vector(vec, node.name)
    return np.ones(3, np.float32), checker_texture(c1, c2, scale, uv_map, transform, node.name), None


def _mix_rgb(r: Reader, node, out, const):
    """Mix Color (Mix node, RGBA, Mix blend) of a constant factor: lerp when at most one side is textured."""
    fac_sock = _input(node, "Factor", "Fac")
    fac = float(np.clip(_default(fac_sock, 0.5), 0, 1))
    if getattr(node, "data_type", "RGBA") != "RGBA" or getattr(node, "blend_type", "MIX") != "MIX" \
            or (fac_sock is not None and fac_sock.is_linked):
        r.warn(node.name, f"node {node.name!r} (Mix {getattr(node, 'blend_type', '')} with a linked or non-colour "
                          "factor) is not supported; using its A colour")
        fac = 0.0
    socks = [s for s in node.inputs if s.type == "RGBA" and s.enabled]
    (a, ta, va), (b, tb, vb) = r.colour(socks[0]), r.colour(socks[1])
    if (ta is None and va is None) and (tb is None and vb is None):
        return (1 - fac) * a + fac * b, None, None
    if fac in (0.0, 1.0):
        return (a, ta, va) if fac == 0.0 else (b, tb, vb)
    r.warn(node.name + "mix", f"node {node.name!r}: a textured colour mixed by {fac:.2f} is read as the textured "
                              "side scaled by its weight plus nothing of the other")
    return ((1 - fac) * a, ta, va) if (ta is not None or va is not None) else (fac * b, tb, vb)


COLOUR_NODES = {
    "ShaderNodeTexImage": _tex_image_colour,
    "ShaderNodeVertexColor": _color_attribute,
    "ShaderNodeAttribute": lambda r, n, o, c: ((np.ones(3, np.float32), None, n.attribute_name)
                                               if n.attribute_type == "GEOMETRY" else
                                               _unsupported(r, n, c)),
    "ShaderNodeTexChecker": _checker,
    "ShaderNodeMix": _mix_rgb,
    "ShaderNodeRGB": lambda r, n, o, c: (np.asarray(n.outputs[0].default_value[:3], np.float32), None, None),
}


def _unsupported(r: Reader, node, const):
    r.warn(node.name, f"node {node.name!r} ({node.bl_idname}) is not supported; using the socket's colour")
    return const, None, None


# ---------------------------------------------------------------------------------------------- shader nodes
def _principled(r: Reader, node) -> dict:
    f: dict = {}
    base, tex, vc = r.colour(_input(node, "Base Color"))
    f["base_color"] = tuple(float(x) for x in base)
    if tex is not None:
        f["base_color_texture"], f["base_color_channel"] = tex, -1
    if vc is not None:
        f["vertex_color"] = vc
    for key, names, default in (("roughness", ("Roughness",), 0.5), ("metallic", ("Metallic",), 0.0),
                                ("specular", ("Specular IOR Level", "Specular"), 0.5), ("alpha", ("Alpha",), 1.0)):
        v, t, ch = r.scalar(_input(node, *names), default)
        f[key] = float(np.clip(v, 0.0, 1.0 if key != "specular" else np.inf))
        if t is not None:
            f[f"{key}_texture"], f[f"{key}_channel"] = t, ch
    ior = float(_default(_input(node, "IOR"), 1.5))
    f["ior"] = ior if math.isfinite(ior) and ior > 0 else 1.5
    f["transmission"] = float(np.clip(_default(_input(node, "Transmission Weight", "Transmission"), 0.0), 0, 1))
    tint = _default(_input(node, "Specular Tint"), (1.0, 1.0, 1.0, 1.0))
    if np.ndim(tint) and np.any(np.abs(np.asarray(tint[:3]) - 1) > 1e-6):
        r.warn("Specular Tint", f"Principled BSDF {node.name!r}: Specular Tint is not supported (white used)")
    ecol, etex, _evc = r.colour(_input(node, "Emission Color", "Emission"), (0.0, 0.0, 0.0))
    estr, strtex, _ = r.scalar(_input(node, "Emission Strength"), 1.0)
    if strtex is not None:
        r.warn("Emission Strength", f"Principled BSDF {node.name!r}: a texture on Emission Strength is not "
                                    "supported; using the socket's value")
    f["emission"] = tuple(float(x) for x in np.maximum(ecol * estr, 0.0))
    if etex is not None and estr > 0:
        f["emission_texture"], f["emission_channel"] = etex, -1
    _normal(r, node, f)
    for name in ("Coat Weight", "Sheen Weight", "Subsurface Weight"):
        if float(_default(_input(node, name), 0.0)) > 0:
            r.warn(name, f"Principled BSDF {node.name!r}: {name} is not supported (ignored)")
    return f


def _normal(r: Reader, node, f: dict) -> None:
    sock = _input(node, "Normal")
    src, _out = linked(sock)
    if src is None:
        return
    if src.bl_idname == "ShaderNodeNormalMap":
        if src.space != "TANGENT":
            r.warn(src.name, f"Normal Map {src.name!r}: {src.space} space is not supported (ignored)")
            return
        tex_node, out = linked(_input(src, "Color"))
        tex = r.image_texture(tex_node) if tex_node is not None and tex_node.bl_idname == "ShaderNodeTexImage" \
            else None
        if tex is None:
            if tex_node is not None:
                r.warn(src.name + "c", f"Normal Map {src.name!r}: its Color comes from {tex_node.bl_idname} "
                                       "(not an Image Texture); ignored")
            return
        if src.uv_map:
            tex = replace(tex, uv_map=src.uv_map)
        f["normal_texture"] = replace(tex, scale=(2.0, 2.0, 2.0, 1.0), bias=(-1.0, -1.0, -1.0, 0.0))
        f["normal_channel"] = -1
        f["normal_strength"] = float(_default(_input(src, "Strength"), 1.0))
        return
    r.warn(src.name, f"node {src.name!r} ({src.bl_idname}) on Normal is not supported (shading normals kept)")


def _diffuse(r: Reader, node) -> dict:
    c, tex, vc = r.colour(_input(node, "Color"))
    f = {"base_color": tuple(map(float, c)), "specular": 0.0, "roughness": 1.0, "metallic": 0.0}
    if tex is not None:
        f["base_color_texture"], f["base_color_channel"] = tex, -1
    if vc is not None:
        f["vertex_color"] = vc
    _normal(r, node, f)
    return f


def _glossy(r: Reader, node) -> dict:
    """Glossy BSDF = a metal of that colour (Principled metallic 1, F0 = colour)."""
    c, tex, vc = r.colour(_input(node, "Color"))
    rough, rtex, rch = r.scalar(_input(node, "Roughness"), 0.5)
    f = {"base_color": tuple(map(float, c)), "metallic": 1.0, "roughness": float(np.clip(rough, 0, 1))}
    if tex is not None:
        f["base_color_texture"], f["base_color_channel"] = tex, -1
    if rtex is not None:
        f["roughness_texture"], f["roughness_channel"] = rtex, rch
    _normal(r, node, f)
    return f


def _glass(r: Reader, node) -> dict:
    c, tex, _vc = r.colour(_input(node, "Color"), (1.0, 1.0, 1.0))
    rough = float(np.clip(_default(_input(node, "Roughness"), 0.0), 0, 1))
    ior = float(_default(_input(node, "IOR"), 1.5))
    if rough > 0.05:
        r.warn(node.name + "r", f"Glass BSDF {node.name!r}: roughness {rough:.2f} is rendered as smooth glass")
    if tex is not None:
        r.warn(node.name + "t", f"Glass BSDF {node.name!r}: a textured colour is not supported (its mean used)")
        c = c * tex.values(-1).reshape(-1, 3).mean(0)
    return {"base_color": tuple(map(float, c)), "transmission": 1.0, "metallic": 0.0, "roughness": rough,
            "ior": ior if ior > 0 else 1.5}


def _emission(r: Reader, node) -> dict:
    c, tex, _vc = r.colour(_input(node, "Color"), (1.0, 1.0, 1.0))
    s, stex, _ = r.scalar(_input(node, "Strength"), 1.0)
    f = {"base_color": (0.0, 0.0, 0.0), "specular": 0.0, "emission": tuple(map(float, np.maximum(c * s, 0)))}
    if tex is not None:
        f["emission_texture"], f["emission_channel"] = tex, -1
    return f


def _transparent(r: Reader, node) -> dict:
    c, _tex, _vc = r.colour(_input(node, "Color"), (1.0, 1.0, 1.0))
    if np.any(np.abs(c - 1) > 1e-6):
        r.warn(node.name, f"Transparent BSDF {node.name!r}: a tinted colour is read as fully transparent")
    return {"base_color": (0.0, 0.0, 0.0), "alpha": 0.0, "specular": 0.0}


def _mix_shader(r: Reader, node) -> dict:
    """Mix Shader: the two sides' fields mixed by the factor. A constant factor lerps every constant (colours,
    roughness, metallic, transmission, emission, alpha); a texture only one side has stays with its weight folded
    into the constant. A Transparent side mixed by a texture (Blender's cut-out pattern) becomes an alpha texture."""
    fac_sock = _input(node, "Fac", "Factor")
    fac, ftex, fch = r.scalar(fac_sock, 0.5)
    shaders = [s for s in node.inputs if s.type == "SHADER"]
    a, b = (shader_fields(r, linked(s)[0]) for s in shaders[:2])
    if ftex is not None:
        if b.get("alpha", 1.0) == 0.0 and "alpha_texture" not in a:  # fac 1 = transparent
            inv = replace(ftex, scale=tuple(-s for s in ftex.scale), bias=tuple(1 - x for x in ftex.bias))
            return dict(a, alpha=1.0, alpha_texture=inv, alpha_channel=fch)
        if a.get("alpha", 1.0) == 0.0 and "alpha_texture" not in b:  # fac 0 = transparent: alpha = fac
            return dict(b, alpha=1.0, alpha_texture=ftex, alpha_channel=fch)
        mean = float(np.mean(ftex.values(fch)))
        r.warn(node.name, f"Mix Shader {node.name!r}: a textured factor is read as its mean {mean:.3f}")
        fac = mean
    return mix_fields(a, b, float(np.clip(fac, 0, 1)))


def mix_fields(a: dict, b: dict, t: float) -> dict:
    """(1 − t)·a + t·b of two field dicts, key by key (the defaults of the Principled model fill gaps)."""
    if t <= 0.0:
        return dict(a)
    if t >= 1.0:
        return dict(b)
    out: dict = {}
    for k in set(a) | set(b):
        if k.endswith("_channel") or k == "vertex_color":
            out[k] = a.get(k, b.get(k))
            continue
        if k.endswith("_texture"):
            out[k] = a.get(k, b.get(k))
            continue
        va = np.asarray(a.get(k, DEFAULTS.get(k, 0.0)), np.float64)
        vb = np.asarray(b.get(k, DEFAULTS.get(k, 0.0)), np.float64)
        if k == "ior":
            out[k] = float(va if a.get("transmission", 0) >= b.get("transmission", 0) else vb)
            continue
        v = (1 - t) * va + t * vb
        out[k] = tuple(map(float, v)) if v.ndim else float(v)
    # a texture only one side has: its weight goes into that parameter's constant multiplier
    for k in [k for k in out if k.endswith("_texture")]:
        p = k[: -len("_texture")]
        side_a = k in a
        w = (1 - t) if side_a else t
        other = np.asarray((b if side_a else a).get(p, DEFAULTS.get(p, 0.0)), np.float64)
        mine = np.asarray((a if side_a else b).get(p, DEFAULTS.get(p, 0.0)), np.float64)
        if k in a and k in b:
            continue
        if p in ("base_color", "emission") and np.allclose(other, 0):
            v = w * mine
            out[p] = tuple(map(float, v)) if v.ndim else float(v)
    return out


DEFAULTS = {"base_color": (0.8, 0.8, 0.8), "roughness": 0.5, "metallic": 0.0, "specular": 0.5, "alpha": 1.0,
            "emission": (0.0, 0.0, 0.0), "transmission": 0.0, "ior": 1.5}

SHADER_NODES = {
    "ShaderNodeBsdfPrincipled": _principled,
    "ShaderNodeBsdfDiffuse": _diffuse,
    "ShaderNodeBsdfGlossy": _glossy,
    "ShaderNodeBsdfAnisotropic": _glossy,
    "ShaderNodeBsdfGlass": _glass,
    "ShaderNodeEmission": _emission,
    "ShaderNodeBsdfTransparent": _transparent,
    "ShaderNodeMixShader": _mix_shader,
}


def shader_fields(r: Reader, node) -> dict:
    """Fields of the shader ``node`` (None = nothing connected: black, as Cycles renders it)."""
    if node is None:
        return {"base_color": (0.0, 0.0, 0.0), "specular": 0.0}
    fn = SHADER_NODES.get(node.bl_idname)
    if fn is not None:
        return fn(r, node)
    colour = None
    for name in ("Color", "Base Color"):
        sock = _input(node, name)
        if sock is not None:
            colour = r.colour(sock)[0]
            break
    if colour is None:
        colour = np.asarray(r.viewport_colour, np.float32)
    r.warn(node.name, f"shader {node.name!r} ({node.bl_idname}) is not supported; using a diffuse surface of "
                      f"its colour {tuple(np.round(colour, 3))}")
    return {"base_color": tuple(map(float, colour)), "specular": 0.0}


def read_material(material, warn, images: dict) -> dict:
    """The Principled fields of a Blender material (see the module docstring)."""
    r = Reader(f"material {material.name!r}", warn, images)
    r.viewport_colour = tuple(material.diffuse_color[:3])
    tree = material.node_tree
    fallback = {"base_color": tuple(material.diffuse_color[:3]), "metallic": float(material.metallic),
                "roughness": float(material.roughness)}
    if tree is None:
        return fallback
    out = output_node(tree, "OUTPUT_MATERIAL")
    shader = linked(out.inputs.get("Surface"))[0] if out is not None else None
    if shader is None:
        warn(f"material {material.name!r}: no surface shader connected to the Material Output; using its "
             "viewport colour")
        return fallback
    f = shader_fields(r, shader)  # alpha is Cycles' stochastic blend: no threshold (EEVEE's Clip mode is not Cycles')
    if out is not None and out.inputs.get("Displacement") is not None and out.inputs["Displacement"].is_linked:
        r.warn("Displacement", "Displacement on the Material Output is not supported (ignored)")
    return f


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
        if tex is None:
            return {"color": const * strength}
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
            r.warn(img.name, f"image {img.name!r} not loaded ({exc})")
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


def mapping_matrix(node, r: Reader | None = None) -> np.ndarray:
    """(3, 3) affine map on (u, v, 1) of a Mapping node fed UVs (w = 0).

    Point: v' = T + R·(S ⊙ v); Texture: v' = S⁻¹ ⊙ (R⁻¹·(v − T)) (Blender's definitions). The image texture reads
    v'.xy, so the (x, y) rows and (u, v) columns of the 4×4 affine map are exact for flat UVs."""
    loc = np.asarray(_default(_input(node, "Location"), (0, 0, 0)), np.float64)
    rot = _euler(np.asarray(_default(_input(node, "Rotation"), (0, 0, 0)), np.float64))
    scale = np.asarray(_default(_input(node, "Scale"), (1, 1, 1)), np.float64)
    kind = node.vector_type
    m = np.eye(4)
    if kind == "POINT":
        m[:3, :3] = rot @ np.diag(scale)
        m[:3, 3] = loc
    elif kind == "TEXTURE":
        with np.errstate(divide="ignore"):
            inv_s = np.where(scale != 0, 1.0 / np.where(scale != 0, scale, 1), 0.0)
        m[:3, :3] = np.diag(inv_s) @ rot.T
        m[:3, 3] = -(m[:3, :3] @ loc)
    else:  # VECTOR / NORMAL: no translation
        if r is not None:
            r.warn(node.name, f"Mapping {node.name!r}: {kind} type on texture coordinates is read without its "
                              "location")
        m[:3, :3] = rot @ np.diag(scale)
    out = np.eye(3)
    out[:2, :2] = m[:2, :2]
    out[:2, 2] = m[:2, 3]
    return out


def image_rgba(image) -> np.ndarray:
    """(H, W, 4) scene-linear float32 pixels of a Blender image, top row first, straight alpha.

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


def checker_texture(c1, c2, scale: float, uv_map: str, transform: np.ndarray, label: str) -> TextureRef:
    """Blender's Checker Texture on UVs as an image: one period (2×2 cells of 1/scale) at CHECKER_TEXELS texels
    per cell side, repeat-wrapped, with the scale folded into the transform. Cycles' rule (svm_checker): at
    p = (v·scale + 1e-6)·0.999999 the cell is Color1 where ⌊p.x⌋ and ⌊p.y⌋ have different parity (z = 0)."""
    n = CHECKER_TEXELS
    centre = (np.arange(2 * n) + 0.5) / n  # texel centres in cell units over one period [0, 2)
    xi = np.floor(centre)[None, :].astype(int)
    yi = np.floor(centre)[::-1, None].astype(int)  # top row first: image rows run down in v
    c1_mask = (xi % 2) != (yi % 2)
    img = np.where(c1_mask[..., None], np.asarray(c1, np.float32), np.asarray(c2, np.float32))
    img = np.concatenate([img, np.ones(img.shape[:2] + (1,), np.float32)], axis=2)
    s = np.diag([scale / 2.0, scale / 2.0, 1.0])  # period 2 cells = 2/scale UV units
    return TextureRef(pixels=np.ascontiguousarray(img, np.float32), wrap="repeat", uv_map=uv_map,
                      transform=s @ transform, label=label)

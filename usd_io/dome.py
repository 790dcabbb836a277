"""A ``DomeLight``'s ``inputs:texture:file`` -> a lat-long environment for the tracer.

Orientation. UsdLux's DomeLight follows the OpenEXR lat-long convention with its pole on the dome's local +Y: the
image's left edge is longitude +π, its right edge −π, its top row latitude +π/2; latitude 0 / longitude 0 is the
local +Z axis and longitude +π/2 the local +X axis. So in dome-local coordinates a direction d = (x, y, z) reads

    u = 0.5 − atan2(x, z) / 2π,   v_from_top = 0.5 − asin(y) / π           (image centre = local +Z)

Cycles' (and Blender's) equirectangular lookup — the one ``tracer.Environment`` uses — has its pole on +Z and its
image centre on +X: u = 0.5 − atan2(d_y, d_x) / 2π, top row = +Z. The two agree when (x_e, y_e, z_e) = (z, x, y), a
cyclic permutation P (a proper rotation). The environment's world -> environment rotation is therefore

    R = P · Dᵀ · (Rx(90°)ᵀ when the pole is Z)

with D the dome prim's world rotation (scale and translation removed). ``DomeLight_1.poleAxis`` = "Z", or "scene" on
a Z-up stage, first turns the dome by +90° about X (local +Y onto +Z); the plain ``DomeLight`` schema always has
its pole on +Y, whatever the stage's up axis (as Storm and Blender's importer read it).

Checked against Cycles rendering Blender 5.0's import of the same stages (tests/cycles/test_cycles_usd_materials.py,
the camera's rays from pxr's frustum, this rotation and a numpy equirect lookup): 91 dB for a Y-up DomeLight, plain
and turned 70° about Y; 74 dB for a DomeLight on a Z-up stage and a DomeLight_1 with poleAxis Y. A DomeLight_1 with
poleAxis Z is where Blender's importer differs (11 dB: its top row lands on the horizon, not on +Z); we follow the
schema text (the top pole on +Z), checked in closed form by tests/test_usd_materials.py.

Brightness: the texture is multiplied by intensity · 2^exposure · color (× colour temperature), the light colour
every UsdLux light uses (``usd_io.lights.light_colour``). ``texture:format`` latlong, or automatic with a 2:1
image, is read; mirroredBall, angular and cubeMapVerticalCross are not (one warning; the image's average colour
lights the scene instead).
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf, UsdGeom, UsdLux

import tracer

from .materials.texture_files import read_texture_file

#: Dome-local (pole +Y, centre +Z) -> Cycles equirect frame (pole +Z, centre +X).
USD_TO_CYCLES = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
#: +90° about X: the pole (+Y) onto +Z, for a Z pole.
POLE_Z = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def _rotation_only(m: np.ndarray) -> np.ndarray:
    """The rotation part of a 4×4 column-vector matrix (polar decomposition; a mirror is kept as a reflection)."""
    u, _s, vt = np.linalg.svd(np.asarray(m, np.float64)[:3, :3])
    return u @ vt


def pole_is_z(prim) -> bool:
    if prim.GetTypeName() != "DomeLight_1":
        return False
    pole = UsdLux.DomeLight_1(prim).GetPoleAxisAttr().Get() or "scene"
    if pole == "scene":
        return UsdGeom.GetStageUpAxis(prim.GetStage()) == UsdGeom.Tokens.z
    return pole == "Z"


def world_to_environment(prim, world: np.ndarray) -> np.ndarray:
    """(3, 3) rotation taking world directions to the Cycles-convention lat-long frame of this dome."""
    d = _rotation_only(world)
    if pole_is_z(prim):
        d = d @ POLE_Z
    return USD_TO_CYCLES @ d.T


def dome_texture(prim, world: np.ndarray, time, colour: np.ndarray, warn):
    """(image, rotation, average) of a dome's texture: ``image`` (H, W, 3) linear × ``colour`` and ``rotation``
    (3, 3) world -> environment for a readable lat-long texture (``average`` its mean colour); a 1×1 image (Blender's
    world colour) or an unsupported format gives only ``average``; no texture, or an unreadable one (one warning),
    gives (None, None, None)."""
    lux = UsdLux.DomeLight(prim) if prim.GetTypeName() != "DomeLight_1" else UsdLux.DomeLight_1(prim)
    attr = lux.GetTextureFileAttr()
    asset = attr.Get(time) if attr.HasAuthoredValue() else None
    name = str(prim.GetPath())
    if not isinstance(asset, Sdf.AssetPath) or not asset.path:
        return None, None, None
    if not asset.resolvedPath:
        warn(f"{name}: dome texture {asset.path!r} not found; using the dome's colour")
        return None, None, None
    try:
        tex = read_texture_file(asset.resolvedPath, "auto", asset.path)
    except ValueError as exc:
        warn(f"{name}: {exc}; using the dome's colour")
        return None, None, None
    rgb = tex.pixels[..., :3] * np.asarray(colour, np.float32)
    average = rgb.reshape(-1, 3).mean(axis=0).astype(np.float64)
    fmt = str(lux.GetTextureFormatAttr().Get(time) or "automatic")
    h, w = rgb.shape[:2]
    if w * h == 1:
        return None, None, average
    if fmt == "latlong" or (fmt == "automatic" and w == 2 * h):
        return np.ascontiguousarray(rgb, np.float32), world_to_environment(prim, world), average
    why = (f"texture:format {fmt!r} is not supported" if fmt != "automatic"
           else f"texture:format automatic with a {w}x{h} image (not a 2:1 lat-long)")
    warn(f"{name}: {why}; the dome is lit by the texture's average colour")
    return None, None, average


def environment(parts: dict):
    """``tracer.Environment`` from :func:`dome_texture`'s image and rotation."""
    return tracer.Environment(image=parts["image"], strength=1.0, rotation=parts["rotation"])

"""``UsdLux`` lights -> tracer lights, in the units Blender's USD exporter writes (measured against Cycles).

Let I = intensity · 2^exposure · color (per channel, × the colour temperature, see below). Blender writes a point
light of power P as a SphereLight with I = P/π, normalize = 1; Cycles' radiant intensity is P/4π. Hence:

    SphereLight  normalize = 1 (or radius 0):  tracer PointLight.intensity = I/4 W/sr
                 normalize = 0, radius R > 0:  the surface radiance is I, so the intensity is I·πR² W/sr
                 (the same light as a normalized one of I·4πR², i.e. normalize divides by the surface area)
                 radius -> soft shadows unless treatAsPoint; ShapingAPI cone -> SpotLight(cone_angle =
                 shaping:cone:angle in degrees (half angle), blend = shaping:cone:softness)
    DistantLight as the spec says (any stage not written by Blender): ``angle`` is the angular diameter in
                 degrees; with normalize = 0 ``intensity`` is the radiance of the sun's disk, so the irradiance is
                 E = I·Ω, Ω = 2π(1 − cos(angle/2)) (the schema defaults 50000 and 0.53° give E = 3.36 W/m²); with
                 normalize = 1 (or angle 0) it is the irradiance itself, E = I.
                 Blender's exporter (root layer ``doc = "Blender v…"``) writes sun strength S as I = S/4 with
                 normalize = 1 and *half* the angle: for those stages E = 4·I and the diameter is 2·angle
                 (measured against Cycles; see docs/usd.md "Two readings of DistantLight").
    RectLight    radiance Le = I/A with normalize = 1 (A = width·height), else Le = I (Blender: I = P/π)
    DiskLight    the same with A = π·radius²
    DomeLight    the world: Scene.background = I (× the texture's average colour if it has one) and
                 Scene.ambient = I · inputs:diffuse (the diffuse multiplier scales only the lighting)

Colour temperature: applied only when ``enableColorTemperature`` is on *and* ``colorTemperature`` is authored.
Blender writes ``enableColorTemperature = 1`` on every light without a temperature, meaning "no tint"; USD's
6500 K fallback would tint every light by (1.04, 0.98, 1.03). An authored temperature is USD's blackbody colour
divided by its 6500 K value, so 6500 K is white as in Blender.

Light world transforms scale them: a sphere's radius by the mean axis scale, a rect/disk's size along its axes.
Lights see the camera-space units of the stage (no metersPerUnit conversion), like the geometry.
"""

from __future__ import annotations

import numpy as np
from pxr import UsdLux

from tracer import AreaLight, DistantLight, PointLight, SpotLight
from tracer.texture import load_texture

LIGHT_TYPES = ("SphereLight", "DistantLight", "RectLight", "DiskLight", "DomeLight", "CylinderLight")
SPEC, BLENDER = "spec", "blender"
_WHITE_6500 = np.asarray(UsdLux.BlackbodyTemperatureAsRgb(6500.0), dtype=np.float64)


def light_units(stage) -> str:
    """``"blender"`` for a stage whose root layer Blender's USD exporter wrote (its ``doc`` is "Blender vX.Y.Z"),
    else ``"spec"``. Only DistantLight differs between the two readings (the other lights Blender writes as the
    spec says; the Cycles suite holds that)."""
    layer = stage.GetRootLayer()
    doc = (layer.documentation or "").strip()
    creator = str((layer.customLayerData or {}).get("creator", ""))
    return BLENDER if doc.startswith("Blender v") or creator.startswith("Blender") else SPEC


def _get(attr, time, default):
    v = attr.Get(time) if attr else None
    return default if v is None else v


def light_colour(prim, time) -> np.ndarray:
    """intensity · 2^exposure · color (· the colour temperature, where authored), per channel."""
    api = UsdLux.LightAPI(prim)
    i = float(_get(api.GetIntensityAttr(), time, 1.0))
    e = float(_get(api.GetExposureAttr(), time, 0.0))
    c = np.asarray(_get(api.GetColorAttr(), time, (1.0, 1.0, 1.0)), dtype=np.float64)
    rgb = i * 2.0 ** e * c
    temp_attr = api.GetColorTemperatureAttr()
    if _get(api.GetEnableColorTemperatureAttr(), time, False) and temp_attr.HasAuthoredValue():
        t = float(temp_attr.Get(time))
        rgb = rgb * np.asarray(UsdLux.BlackbodyTemperatureAsRgb(t)) / _WHITE_6500
    return rgb


def _finite(v: float, what: str) -> float:
    """``v`` as a float; ValueError (the reader warns and skips the light) when it is NaN or infinite."""
    v = float(v)
    if not np.isfinite(v):
        raise ValueError(f"{what} is {v}")
    return v


def _normalized(prim, time) -> bool:
    return bool(_get(UsdLux.LightAPI(prim).GetNormalizeAttr(), time, False))


def _axis_scales(m):
    return np.linalg.norm(m[:3, :3], axis=0)


def distant_irradiance(rgb, angle_deg: float, normalize: bool, units: str = SPEC):
    """(irradiance E per channel, full angular diameter in radians) of a DistantLight of colour ``rgb``
    (intensity · 2^exposure · color) and authored ``angle`` in degrees, under the ``units`` reading."""
    if units == BLENDER:
        return 4.0 * rgb, float(np.radians(2 * angle_deg))
    diameter = float(np.radians(angle_deg))
    if normalize or diameter <= 0:
        return rgb, diameter
    solid_angle = 2 * np.pi * (1 - np.cos(min(diameter, 2 * np.pi) / 2))
    return rgb * solid_angle, diameter


def convert_light(prim, world: np.ndarray, time, warn, units: str = SPEC):
    """(kind, tracer light or None, world dict or None) for one UsdLux prim; ``units`` from :func:`light_units`."""
    t = prim.GetTypeName()
    name = str(prim.GetPath())
    rgb = light_colour(prim, time)
    pos = world[:3, 3]
    down = -world[:3, 2]  # the light's −Z
    if t == "SphereLight":
        lux = UsdLux.SphereLight(prim)
        r = _finite(_get(lux.GetRadiusAttr(), time, 0.5), "radius") * float(np.mean(_axis_scales(world)))
        point = bool(_get(lux.GetTreatAsPointAttr(), time, False))
        if _normalized(prim, time) or r <= 0:
            intensity = rgb / 4.0
        else:
            intensity = rgb * np.pi * r * r
        radius = 0.0 if point else r
        shaping = UsdLux.ShapingAPI(prim)
        cone = shaping.GetShapingConeAngleAttr() if prim.HasAPI(UsdLux.ShapingAPI) else None
        focus = shaping.GetShapingFocusAttr() if prim.HasAPI(UsdLux.ShapingAPI) else None
        if focus and focus.HasAuthoredValue() and float(focus.Get(time) or 0) != 0:
            warn(f"{name}: ShapingAPI shaping:focus is not supported (ignored)")
        ies = shaping.GetShapingIesFileAttr() if prim.HasAPI(UsdLux.ShapingAPI) else None
        if ies and ies.HasAuthoredValue():
            warn(f"{name}: ShapingAPI IES profile is not supported (ignored)")
        if cone and cone.HasAuthoredValue():
            angle = _finite(cone.Get(time), "shaping:cone:angle")
            soft = _finite(_get(shaping.GetShapingConeSoftnessAttr(), time, 0.0), "shaping:cone:softness")
            if 0 < angle < 180:
                return "spot", SpotLight(position=pos, intensity=intensity, radius=radius, direction=down,
                                         cone_angle=np.radians(angle), blend=float(np.clip(soft, 0, 1)),
                                         name=name), None
        return "point", PointLight(position=pos, intensity=intensity, radius=radius, name=name), None
    if t == "DistantLight":
        lux = UsdLux.DistantLight(prim)
        angle = _finite(_get(lux.GetAngleAttr(), time, 0.53), "angle")
        irradiance, diameter = distant_irradiance(rgb, angle, _normalized(prim, time), units)
        return "distant", DistantLight(direction=down, irradiance=irradiance,
                                       angle=float(np.clip(diameter, 0, np.pi - 1e-6)), name=name), None
    if t == "CylinderLight":
        # A tube along its local X of `length` and `radius`: emitted as a spherical light of the same power
        # at its centre (Φ = L·π·A for a Lambertian surface of area A = 2πrl; normalize divides by A).
        lux = UsdLux.CylinderLight(prim)
        sx, sy, sz = _axis_scales(world)
        length = _finite(_get(lux.GetLengthAttr(), time, 1.0), "length") * sx
        r = _finite(_get(lux.GetRadiusAttr(), time, 0.5), "radius") * float(np.sqrt(sy * sz))
        if _normalized(prim, time) or r <= 0 or length <= 0:
            power = rgb * np.pi
        else:
            power = rgb * np.pi * 2 * np.pi * r * length
        warn(f"{name}: CylinderLight rendered as a point light of the same power")
        return "point", PointLight(position=pos, intensity=power / (4 * np.pi), radius=max(r, 0.0), name=name), None
    if t in ("RectLight", "DiskLight"):
        sx, sy, _ = _axis_scales(world)
        if t == "RectLight":
            lux = UsdLux.RectLight(prim)
            size = (float(_get(lux.GetWidthAttr(), time, 1.0)) * sx, float(_get(lux.GetHeightAttr(), time, 1.0)) * sy)
            shape = "rect"
            if lux.GetTextureFileAttr().HasAuthoredValue():
                warn(f"{name}: RectLight texture:file is not supported (uniform colour used)")
        else:
            r = float(_get(UsdLux.DiskLight(prim).GetRadiusAttr(), time, 0.5))
            size, shape = (2 * r * sx, 2 * r * sy), "disk"
        if not (np.all(np.isfinite(size)) and min(size) > 0):
            warn(f"{name}: {t} of zero or non-finite size {size} skipped")
            return "area", None, None
        area = size[0] * size[1] if shape == "rect" else np.pi / 4 * size[0] * size[1]
        radiance = rgb / area if _normalized(prim, time) else rgb
        return "area", AreaLight(position=pos, u_axis=world[:3, 0], v_axis=world[:3, 1], normal=down,
                                 size=size, radiance=radiance, shape=shape, name=name), None
    if t == "DomeLight":
        lux = UsdLux.DomeLight(prim)
        colour = rgb
        tex_attr = lux.GetTextureFileAttr()
        asset = tex_attr.Get(time) if tex_attr.HasAuthoredValue() else None
        if asset is not None and asset.path:
            if asset.resolvedPath:
                try:
                    colour = rgb * load_texture(asset.resolvedPath, "auto").reshape(-1, 3).mean(axis=0)
                except ValueError as exc:
                    warn(f"{name}: {exc}; using the dome's colour")
            else:
                warn(f"{name}: dome texture {asset.path!r} not found; using the dome's colour")
        diffuse = float(_get(UsdLux.LightAPI(prim).GetDiffuseAttr(), time, 1.0))
        return "dome", None, dict(background=colour, ambient=colour * diffuse)
    warn(f"{name}: light type {t} is not supported (skipped)")
    return "unsupported", None, None


#: usdview / usdrecord light a stage that has no lights with one light at the camera (UsdAppUtils FrameRecorder:
#: GlfSimpleLight at the camera position, diffuse 1, no falloff) plus a small ambient. Here: a distant light along
#: the view direction whose irradiance π makes a white Lambertian surface facing the camera show its albedo
#: (Storm's N·L·diffuse), and a dim uniform dome (ambient L_a = 0.1; usdview's default dome is off and its
#: ambient term 0.2 × 0.01 would leave faces turned away from the camera black). The background stays black, as
#: usdrecord's clear colour.
DEFAULT_CAMERA_LIGHT_IRRADIANCE = np.pi
DEFAULT_DOME_AMBIENT = 0.1


def default_lights(camera):
    """(camera light, ambient colour) for a stage without lights, seen by ``camera`` (a tracer.Camera)."""
    forward = -np.asarray(camera.camera_to_world, np.float64)[:3, 2]
    light = DistantLight(direction=forward, irradiance=np.full(3, DEFAULT_CAMERA_LIGHT_IRRADIANCE),
                         angle=0.0, name="default camera light")
    return light, np.full(3, DEFAULT_DOME_AMBIENT, np.float32)

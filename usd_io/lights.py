"""``UsdLux`` lights -> tracer lights, as the UsdLux spec reads them, which is also how Blender's USD exporter
writes them (measured against Cycles) except for one light, the sun (see "Which reading" below).

Let I = intensity · 2^exposure · color (per channel, × the colour temperature, see below). Blender writes a point
light of power P as a SphereLight with I = P/π, normalize = 1; Cycles' radiant intensity is P/4π. Hence:

    SphereLight  normalize = 1 (or radius 0):  tracer PointLight.intensity = I/4 W/sr
                 normalize = 0, radius R > 0:  the surface radiance is I, so the intensity is I·πR² W/sr
                 (the same light as a normalized one of I·4πR², i.e. normalize divides by the surface area)
                 radius -> soft shadows unless treatAsPoint; ShapingAPI cone -> SpotLight(cone_angle =
                 shaping:cone:angle in degrees (half angle), blend = shaping:cone:softness)
    (Arnold's own units, ``units = "arnold"``, usd_io.exporters: a normalized or radius-0 SphereLight has
    radiant intensity I W/sr (four times the spec's), ``primvars:arnold:radius`` overriding the radius; a
    DistantLight E = I whatever its angle and normalize (UsdLux's fallback intensity read as the spec's).
    Measured on arnold-usd's references, which are sRGB-encoded 8-bit: one distant light of I = 1 on a cube of
    albedo 0.4 gives 100/255 = sRGB(0.4/π).)
    DistantLight spec: ``angle`` is the angular diameter of the sun's disk (default 0.53°) and I its radiance, so
                 the irradiance is E = I·Ω with Ω = 2π(1 − cos(angle/2)) the disk's solid angle (the schema
                 default I = 50 000 gives E = 3.36 W/m², a sane sun); ``normalize`` = 1 makes E = I.
                 angle = 0 (a delta sun, which the spec leaves at E = 0) takes E = I, the normalized limit.
                 Blender's exporter: sun strength S written as I = S/4 with normalize = 1 and angle = half the
                 diameter, so E = 4·I and the diameter is 2·angle.
    CylinderLight  a point light of the same power Φ = π·I·2πrl (normalize: π·I) at its centre, with a warning
    RectLight    radiance Le = I/A with normalize = 1 (A = width·height), else Le = I (Blender: I = P/π)
    DiskLight    the same with A = π·radius²
    DomeLight    the world: a lat-long texture becomes Scene.environment (usd_io/dome.py: orientation, format);
                 without one, Scene.background = I and Scene.ambient = I · inputs:diffuse; Arnold's
                 ``primvars:arnold:camera = w`` (Arnold's light parameter ``camera``: lights the scene, seen by the
                 camera × w; 0 unseen): background I·w

Which reading: a stage whose root layer says it was written by Blender (``doc = "Blender v…"``, what
Blender's exporter writes) takes Blender's sun; every other stage the spec's. For every other light type the two
readings agree: a SphereLight with normalize = 1 has radiant intensity I/4 under the spec (radiance I over the
sphere's area 4πR², seen as a disk of πR²) and Blender's point light of power P = π·I has P/4π = I/4; a normalized
RectLight/DiskLight has radiance I/A under both.

Colour temperature: applied only when ``enableColorTemperature`` is on *and* ``colorTemperature`` is authored.
Blender writes ``enableColorTemperature = 1`` on every light without a temperature, meaning "no tint"; USD's
6500 K fallback would tint every light by (1.04, 0.98, 1.03). An authored temperature is USD's blackbody colour
divided by its 6500 K value, so 6500 K is white as in Blender.

Linking (:func:`light_links`, tracer/lights/linking.py): ``collection:lightLink`` (the objects a light lights) and
``collection:shadowLink`` (the objects that shadow it), UsdCollectionAPI membership as pxr computes it
(``ComputeMembershipQuery`` / ``IsPathIncluded``: includeRoot, includes, excludes, expansion rule, membership
expressions) over each object's prim path (a PointInstancer's instances: the instancer's path);
``inputs:shadow:enable`` (ShadowAPI) = cast shadows; ``inputs:diffuse`` / ``inputs:specular`` multiply the light's
diffuse / specular (glossy) response. Ray visibility of objects has no renderer-neutral USD form (purpose visibility
is not ray visibility): it is not read.

Light world transforms scale them: a sphere's radius by the mean axis scale, a rect/disk's size along its axes.
Lights see the camera-space units of the stage (no metersPerUnit conversion), like the geometry.
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf, UsdGeom, UsdLux

from tracer import AreaLight, DistantLight, LightShaping, PointLight, SpotLight
from tracer.lights.linking import LightLink

from .dome import dome_texture
from .ies import read_ies, solid_angle_mean
from .materials.texture_files import read_texture_file
from .exporters import KIT_EV, NITS_TO_W_PER_M2, detect

LIGHT_TYPES = ("SphereLight", "DistantLight", "RectLight", "DiskLight", "DomeLight", "DomeLight_1", "CylinderLight")
_WHITE_6500 = np.asarray(UsdLux.BlackbodyTemperatureAsRgb(6500.0), dtype=np.float64)


def _get(attr, time, default):
    """An input's value; an unauthored ``inputs:NAME`` falls back to ``NAME`` as UsdLux spelt it before 21.02
    (OpenUSD's own testenv still has such lights: ``radius``, ``exposure``, ``intensity`` without the prefix)."""
    if attr and attr.GetName().startswith("inputs:") and not attr.HasAuthoredValue():
        legacy = attr.GetPrim().GetAttribute(attr.GetName()[len("inputs:"):])
        if legacy and legacy.HasAuthoredValue():
            attr = legacy
    v = attr.Get(time) if attr else None
    return default if v is None else v


def authored(prim, name: str) -> bool:
    """Whether the stage authors light input ``name``: ``inputs:NAME``, or ``NAME`` as UsdLux spelt it before
    21.02 (see :func:`_get`). The evidence every exporter unit guess needs (docs/usd.md, "Two readings"): an
    unauthored input reads UsdLux's fallback, a number no exporter wrote, so no exporter's units apply to it."""
    for n in (f"inputs:{name}", name):
        a = prim.GetAttribute(n)
        if a and a.HasAuthoredValue():
            return True
    return False


def light_colour(prim, time) -> np.ndarray:
    """intensity · 2^exposure · color (· the colour temperature, where authored), per channel."""
    api = UsdLux.LightAPI(prim)
    i = float(_get(api.GetIntensityAttr(), time, 1.0))
    e = float(_get(api.GetExposureAttr(), time, 0.0))
    c = np.asarray(_get(api.GetColorAttr(), time, (1.0, 1.0, 1.0)), dtype=np.float64)
    rgb = i * 2.0 ** e * c
    temp_attr = api.GetColorTemperatureAttr()
    if not temp_attr.HasAuthoredValue() and prim.GetAttribute("colorTemperature").HasAuthoredValue():
        temp_attr = prim.GetAttribute("colorTemperature")  # the pre-21.02 name (see _get)
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


def blender_authored(stage) -> bool:
    """Whether the stage's root layer was written by Blender's USD exporter (``doc = "Blender v…"``)."""
    w = detect(stage)
    return w is not None and w.units.startswith("blender")


def sun_irradiance(rgb, angle_deg: float, normalize: bool, blender: bool):
    """(irradiance per channel, angular diameter in radians) of a DistantLight (see the module docstring)."""
    if blender:
        return 4.0 * rgb, float(np.clip(np.radians(2 * angle_deg), 0, np.pi - 1e-6))
    diameter = float(np.clip(np.radians(angle_deg), 0, np.pi - 1e-6))
    if normalize:
        return rgb, diameter
    omega = 2 * np.pi * (1 - np.cos(diameter / 2))
    return rgb * omega, diameter


def convert_light(prim, world: np.ndarray, time, warn, blender: bool = False, units: str | None = None,
                  textures=None):
    """(kind, tracer light or None, world dict or None) for one UsdLux prim in ``units`` (usd_io.exporters.UNITS:
    the writer's light units; None: "blender" when ``blender`` else "spec"). ``textures``: the reader's
    ``TextureCache`` (a RectLight's texture:file read in the stage's rendering space), or None."""
    units = units or ("blender" if blender else "spec")
    _warn_filters(prim, warn)
    if units not in ("spec", "arnold") and not authored(prim, "intensity"):
        units = "spec"  # the writer's units are about the numbers it wrote: a fallback intensity is UsdLux's
    blender = units == "blender"
    t = prim.GetTypeName()
    name = str(prim.GetPath())
    rgb = light_colour(prim, time)
    if units == "kit":
        rgb = rgb * 2.0 ** KIT_EV
    if units in ("blender-legacy", "blender-nits"):
        got = _old_blender(t, prim, world, time, rgb, units, warn)
        if got is not None:
            return got
    pos = world[:3, 3]
    down = -world[:3, 2]  # the light's −Z
    if t == "SphereLight":
        lux = UsdLux.SphereLight(prim)
        r = _finite(_get(lux.GetRadiusAttr(), time, 0.5), "radius")
        point = bool(_get(lux.GetTreatAsPointAttr(), time, False))
        normalized = _normalized(prim, time)
        if units == "arnold" and point:
            # arnold-usd reads inputs:radius and inputs:normalize only when treatAsPoint is off: a treatAsPoint
            # light is Arnold's point_light with its defaults, radius 0 and normalize on (unless the primvar below)
            r, normalized, point = 0.0, True, False
        arnold_r = prim.GetAttribute("primvars:arnold:radius") if units == "arnold" else None
        if arnold_r and arnold_r.HasAuthoredValue():  # Arnold's own parameter wins (arnold-usd reads it last)
            r = _finite(arnold_r.Get(time), "primvars:arnold:radius")
        r *= float(np.mean(_axis_scales(world)))
        if units == "arnold" and (normalized or r <= 0):
            intensity = rgb  # Arnold's point light: E = I/d² at distance d (the spec's I/4 W/sr is a quarter)
        elif normalized or r <= 0:
            intensity = rgb / 4.0
        else:
            intensity = rgb * np.pi * r * r
        radius = 0.0 if point else r
        profile, axes = _ies_profile(prim, world, time, warn) if units != "blender" else (None, None)
        if profile is not None and units == "arnold":  # arnold-usd: a photometric_light, whatever the cone says,
            # whose nadir is its local −Y (as Arnold's photometric_light aims, a ceiling fixture: test_0140's beam)
            axes = np.stack([world[:3, 0], -world[:3, 2], -world[:3, 1]])
            return "point", PointLight(position=pos, intensity=intensity, radius=radius, name=name, profile=profile,
                                       profile_axes=axes), None
        if units not in ("arnold", "blender"):  # the spec's ShapingAPI (cone, softness, focus, focus tint)
            return "point", PointLight(position=pos, intensity=intensity, radius=radius, name=name,
                                       shaping=_light_shaping(prim, time, down, warn, ies_read=True),
                                       profile=profile, profile_axes=axes), None
        shaping = UsdLux.ShapingAPI(prim)
        cone = shaping.GetShapingConeAngleAttr() if prim.HasAPI(UsdLux.ShapingAPI) else None
        focus = shaping.GetShapingFocusAttr() if prim.HasAPI(UsdLux.ShapingAPI) else None
        if focus and focus.HasAuthoredValue() and float(focus.Get(time) or 0) != 0:
            warn(f"{name}: ShapingAPI shaping:focus is not supported on this exporter's spot lights (ignored)")
        if units == "blender":
            _warn_ies(prim, time, warn)
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
        irradiance, diameter = sun_irradiance(rgb, angle, _normalized(prim, time), blender)
        if blender and not authored(prim, "angle"):  # Blender's half angle is for an angle it wrote
            diameter = float(np.clip(np.radians(angle), 0, np.pi - 1e-6))
        if not blender and angle <= 0:  # a delta sun: the limit the normalized reading gives
            irradiance = rgb
        if units == "arnold" and authored(prim, "intensity"):  # Arnold's distant light: E = I whatever its angle
            irradiance = rgb  # (normalize ignored). UsdLux's fallback 50 000 is read as the spec's (E = 3.36 for
            # 0.53°): arnold-usd's references of lights without an intensity (test_2254, test_2268) are lit so
        return "distant", DistantLight(direction=down, irradiance=irradiance, angle=diameter, name=name), None
    if t == "CylinderLight":
        # A tube along its local X of `length` and `radius`, emitting from its side (UsdLux: not its end caps) with
        # radiance I (normalize: I over the side's area 2πrl).
        lux = UsdLux.CylinderLight(prim)
        sx, sy, sz = _axis_scales(world)
        length = _finite(_get(lux.GetLengthAttr(), time, 1.0), "length") * sx
        r = _finite(_get(lux.GetRadiusAttr(), time, 0.5), "radius") * float(np.sqrt(sy * sz))
        if not (length > 0 and r > 0):
            warn(f"{name}: CylinderLight of zero length or radius skipped")
            return "area", None, None
        size = (length, 2 * r)
        radiance = rgb / AreaLight.area_of(size, "cylinder") if _normalized(prim, time) else rgb
        shaping = None if units == "blender" else _light_shaping(prim, time, down, warn, ies_read=True)
        profile, axes = _ies_profile(prim, world, time, warn) if units != "blender" else (None, None)
        if units == "blender":
            _warn_ies(prim, time, warn)
        return "area", AreaLight(position=pos, u_axis=world[:3, 0], v_axis=world[:3, 1], normal=down, size=size,
                                 radiance=radiance, shape="cylinder", name=name, shaping=shaping, profile=profile,
                                 profile_axes=axes), None
    if t in ("RectLight", "DiskLight"):
        sx, sy, _ = _axis_scales(world)
        if t == "RectLight":
            lux = UsdLux.RectLight(prim)
            size = (float(_get(lux.GetWidthAttr(), time, 1.0)) * sx, float(_get(lux.GetHeightAttr(), time, 1.0)) * sy)
            shape = "rect"
            texture = _rect_texture(prim, lux, time, warn, textures)
        else:
            r = float(_get(UsdLux.DiskLight(prim).GetRadiusAttr(), time, 0.5))
            size, shape, texture = (2 * r * sx, 2 * r * sy), "disk", None
        if not (np.all(np.isfinite(size)) and min(size) > 0):
            warn(f"{name}: {t} of zero or non-finite size {size} skipped")
            return "area", None, None
        area = AreaLight.area_of(size, shape)
        radiance = rgb / area if _normalized(prim, time) else rgb
        shaping = None if units == "blender" else _light_shaping(prim, time, down, warn, ies_read=True)
        profile, axes = _ies_profile(prim, world, time, warn) if units != "blender" else (None, None)
        if units == "blender":
            _warn_ies(prim, time, warn)
        if units == "arnold":
            spread = prim.GetAttribute("primvars:arnold:spread")
            if spread and spread.HasAuthoredValue() and float(spread.Get(time)) != 1.0:
                warn(f"{name}: Arnold's spread {float(spread.Get(time)):g} is not supported (a Lambertian emitter)")
        # The texture's u: UsdLux (OpenUSD 25.05, Arnold's usdlux_version 25.05) shows the image unmirrored to an
        # eye facing the light's emitting side, whose right is the light's −X; Arnold's own reading mirrors it
        # (arnold-usd's test_2434.1 / .2, "Rect-lights display in (non-)mirror-image").
        u_axis = world[:3, 0] if texture is None or units == "arnold" else -world[:3, 0]
        return "area", AreaLight(position=pos, u_axis=u_axis, v_axis=world[:3, 1], normal=down, size=size,
                                 radiance=radiance, shape=shape, name=name, shaping=shaping, texture=texture,
                                 profile=profile, profile_axes=axes), None
    if t in ("DomeLight", "DomeLight_1"):
        return _dome(prim, world, time, rgb, warn)
    warn(f"{name}: light type {t} is not supported (skipped)")
    return "unsupported", None, None


def _warn_filters(prim, warn) -> None:
    """One warning for what shapes a light beyond UsdLux's own inputs and is not applied: UsdLux light filters
    (``light:filters``) and Arnold's light shaders (``primvars:arnold:shaders``: filters such as gobos and barn
    doors, a dome's colour shader such as physical_sky)."""
    rel = prim.GetRelationship("light:filters") or prim.GetRelationship("filters")
    targets = rel.GetTargets() if rel else []
    shaders = prim.GetAttribute("primvars:arnold:shaders")
    named = [str(t) for t in targets]
    if shaders and shaders.HasAuthoredValue() and shaders.Get():
        named.append(f"Arnold light shaders {shaders.Get()} (primvars:arnold:shaders)")
    if named:
        warn(f"{prim.GetPath()}: {', '.join(named)} not applied (the light as its UsdLux inputs say)")


def _rect_texture(prim, lux, time, warn, textures):
    """A RectLight's ``texture:file`` as an (H, W, 3) linear image (the tracer multiplies the radiance by it), or
    None: no file (an empty path), or one that cannot be read (one warning; the light's uniform colour is used)."""
    attr = lux.GetTextureFileAttr()
    asset = attr.Get(time) if attr.HasAuthoredValue() else None
    if not isinstance(asset, Sdf.AssetPath) or not asset.path:
        return None
    name = str(prim.GetPath())
    if not asset.resolvedPath:
        warn(f"{name}: RectLight texture {asset.path!r} not found (uniform colour used)")
        return None
    try:
        got = (textures.get(asset.resolvedPath, "auto", asset.path) if textures is not None
               else read_texture_file(asset.resolvedPath, "auto", asset.path))
    except ValueError as exc:
        warn(f"{name}: {exc} (uniform colour used)")
        return None
    return np.ascontiguousarray(got.pixels[..., :3], np.float32)


def _warn_ies(prim, time, warn):
    """One warning for an IES profile (``shaping:ies:file`` naming a file; an empty path is no profile) on a light
    that does not read it (Blender's exporter units)."""
    if not prim.HasAPI(UsdLux.ShapingAPI):
        return
    ies = UsdLux.ShapingAPI(prim).GetShapingIesFileAttr()
    v = ies.Get(time) if ies.HasAuthoredValue() else None
    if v is not None and v.path:
        warn(f"{prim.GetPath()}: ShapingAPI IES profile {v.path} is not read in this exporter's units (ignored)")


def _ies_profile(prim, world, time, warn):
    """(table, axes) of the light's IES profile (``shaping:ies:file``; usd_io/ies.py) for a point light, or
    (None, None). The table is the file's candela values in W/sr (÷ 683 lm/W), multiplying the light's intensity,
    or with ``shaping:ies:normalize`` over their mean on the sphere (the light's power kept). Evidence for the
    first: arnold-usd's test_0140 and test_1316 (photometric lights, peaks 31 325 cd and 159 cd) match their
    references where neither is clipped at reference/ours = 1.48e-3 and 1.46e-3 × the peak candela (1/683 =
    1.464e-3); the second: test_2477.1 (38 → 40 dB). The axes are the light's +X (C0), +Y (C90) and −Z (nadir)."""
    if not prim.HasAPI(UsdLux.ShapingAPI):
        return None, None
    api = UsdLux.ShapingAPI(prim)
    attr = api.GetShapingIesFileAttr()
    asset = attr.Get(time) if attr.HasAuthoredValue() else None
    if not isinstance(asset, Sdf.AssetPath) or not asset.path:
        return None, None
    name = str(prim.GetPath())
    if not asset.resolvedPath:
        warn(f"{name}: IES profile {asset.path!r} not found (the light is unshaped)")
        return None, None
    try:
        table = read_ies(asset.resolvedPath)
    except ValueError as exc:
        warn(f"{name}: IES profile {asset.path!r}: {exc} (the light is unshaped)")
        return None, None
    scale = float(_get(api.GetShapingIesAngleScaleAttr(), time, 0.0))
    if scale != 0.0:
        warn(f"{name}: shaping:ies:angleScale {scale:g} is not supported (the profile's own angles used)")
    if bool(_get(api.GetShapingIesNormalizeAttr(), time, False)):
        table = table / solid_angle_mean(table)
    else:
        table = table * NITS_TO_W_PER_M2
    return table, np.stack([world[:3, 0], world[:3, 1], -world[:3, 2]])


def _light_shaping(prim, time, axis, warn, ies_read=False) -> LightShaping | None:
    """The light's ShapingAPI as a :class:`tracer.lights.emitters.LightShaping` about ``axis`` (the light's −Z), or
    None: the cone only where ``shaping:cone:angle`` is authored (arnold-usd reads it so; the schema's fallback 90°
    would cut a sphere light's back half), softness, focus and focus tint as OpenUSD documents them."""
    if not prim.HasAPI(UsdLux.ShapingAPI):
        return None
    api = UsdLux.ShapingAPI(prim)
    if not ies_read:
        _warn_ies(prim, time, warn)
    cone = api.GetShapingConeAngleAttr()
    if not cone.HasAuthoredValue() and prim.GetAttribute("shaping:cone:angle").HasAuthoredValue():
        cone = prim.GetAttribute("shaping:cone:angle")  # the pre-21.02 name (see _get)
    angle = _finite(cone.Get(time), "shaping:cone:angle") if cone.HasAuthoredValue() else 180.0
    soft = _finite(_get(api.GetShapingConeSoftnessAttr(), time, 0.0), "shaping:cone:softness")
    focus = _finite(_get(api.GetShapingFocusAttr(), time, 0.0), "shaping:focus")
    tint = np.asarray(_get(api.GetShapingFocusTintAttr(), time, (0.0, 0.0, 0.0)), np.float64)
    if angle <= 0:
        warn(f"{prim.GetPath()}: shaping:cone:angle {angle:g} <= 0 ignored")
        angle = 180.0
    shaping = LightShaping(axis=axis, cone_angle=np.radians(min(angle, 180.0)), softness=soft, focus=max(focus, 0.0),
                           focus_tint=tint)
    return None if shaping.is_identity() else shaping


def _old_blender(t, prim, world, time, rgb, units, warn):
    """Lights of Blender 2.83–3.1 (I = P/100, no normalize) and 3.2–3.6 (nits), converted to the tracer's units
    from the power P (W) or strength S (W/m²) the Blender scene had (usd_io.exporters documents both exporters).
    None for types these exporters never wrote (read as the spec says)."""
    K = NITS_TO_W_PER_M2
    name = str(prim.GetPath())
    pos, down = world[:3, 3], -world[:3, 2]
    legacy = units == "blender-legacy"
    if t == "SphereLight":
        r = _finite(_get(UsdLux.SphereLight(prim).GetRadiusAttr(), time, 0.5), "radius")
        power = 100.0 * rgb if legacy else rgb * K * 4 * np.pi * r * r
        radius = r * float(np.mean(_axis_scales(world)))
        shaping = UsdLux.ShapingAPI(prim)
        cone = shaping.GetShapingConeAngleAttr() if prim.HasAPI(UsdLux.ShapingAPI) else None
        if cone and cone.HasAuthoredValue() and 0 < float(cone.Get(time)) < 180:
            if not legacy:  # the nits exporter divided a spot by its cone's solid angle share, 2πr²(1 − cos θ)
                theta = np.radians(float(cone.Get(time)))
                power = rgb * K * 2 * np.pi * r * r * (1 - np.cos(theta))
            soft = float(_get(shaping.GetShapingConeSoftnessAttr(), time, 0.0))
            return "spot", SpotLight(position=pos, intensity=power / (4 * np.pi), radius=radius, direction=down,
                                     cone_angle=np.radians(float(cone.Get(time))), blend=float(np.clip(soft, 0, 1)),
                                     name=name), None
        return "point", PointLight(position=pos, intensity=power / (4 * np.pi), radius=radius, name=name), None
    if t in ("RectLight", "DiskLight"):
        sx, sy, _ = _axis_scales(world)
        if t == "RectLight":
            lux = UsdLux.RectLight(prim)
            w, h = float(_get(lux.GetWidthAttr(), time, 1.0)), float(_get(lux.GetHeightAttr(), time, 1.0))
            size, shape, area, written_area = (w * sx, h * sy), "rect", w * h, w * h
        else:
            r = float(_get(UsdLux.DiskLight(prim).GetRadiusAttr(), time, 0.5))
            size, shape, area, written_area = (2 * r * sx, 2 * r * sy), "disk", np.pi * r * r, 2 * np.pi * r * r
        if not (np.all(np.isfinite(size)) and min(size) > 0):
            return None
        power = 100.0 * rgb if legacy else rgb * K * written_area
        return "area", AreaLight(position=pos, u_axis=world[:3, 0], v_axis=world[:3, 1], normal=down, size=size,
                                 radiance=power / (np.pi * area), shape=shape, name=name), None
    if t == "DistantLight":
        angle = _finite(_get(UsdLux.DistantLight(prim).GetAngleAttr(), time, 0.0), "angle")
        radians = legacy and authored(prim, "angle")  # legacy: radians, where the exporter wrote the angle
        diameter = float(np.clip(angle if radians else np.radians(angle), 0, np.pi - 1e-6))
        irradiance = rgb if legacy else rgb * K
        return "distant", DistantLight(direction=down, irradiance=irradiance, angle=diameter, name=name), None
    if t in ("DomeLight", "DomeLight_1") and not legacy:  # the world's strength S written as S · 683
        return _dome(prim, world, time, rgb * K, warn)
    return None


def _dome(prim, world, time, rgb, warn):
    name = str(prim.GetPath())
    diffuse = float(_get(UsdLux.LightAPI(prim).GetDiffuseAttr(), time, 1.0))
    image, rotation, average = dome_texture(prim, world, time, rgb, warn)  # usd_io/dome.py
    colour = rgb if average is None else average
    env = None
    if image is not None:
        env = dict(image=image, rotation=rotation)
        if diffuse != 1.0:
            warn(f"{name}: inputs:diffuse = {diffuse} is not supported with a dome texture (1 used)")
    background = colour
    seen = _camera_weight(prim, time)
    if seen != 1.0:  # Arnold's light parameter `camera`: the dome lights the scene, the camera sees it × seen
        if env is None:
            background = colour * seen
        else:
            warn(f"{name}: primvars:arnold:camera = {seen:g} (the camera sees the dome × {seen:g}) is not supported "
                 "with a dome texture (the dome is seen as it lights)")
    return "dome", None, dict(background=background, ambient=colour * diffuse, environment=env)


def _camera_weight(prim, time) -> float:
    """Arnold's ``primvars:arnold:camera``: the weight of a light's contribution to camera rays (a float, 1 when
    not authored; 0 hides it from the camera, 0.1 shows it at a tenth)."""
    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar("arnold:camera")
    v = pv.Get(time) if pv and pv.HasAuthoredValue() else None
    try:
        w = float(v) if v is not None else 1.0
    except (TypeError, ValueError):
        return 1.0
    return max(w, 0.0) if np.isfinite(w) else 1.0


def _arnold_camera_visibility(prim, time) -> float:
    """How the camera sees a light's shape: UsdLux has no camera visibility (0, as before), but Arnold's light
    parameter ``camera`` (``primvars:arnold:camera = w``: its contribution to camera rays, × w) shows it, unless
    ``primvars:arnold:visibility:camera`` is off (arnold-usd reads both when authored)."""
    vis = UsdGeom.PrimvarsAPI(prim).GetPrimvar("arnold:visibility:camera")
    if vis and vis.HasAuthoredValue() and not vis.Get(time):
        return 0.0
    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar("arnold:camera")
    return _camera_weight(prim, time) if pv and pv.HasAuthoredValue() else 0.0


#: The default lighting of a stage without lights, as usdview/usdrecord light one: a headlight along the camera's
#: view (irradiance π: a white Lambertian surface facing the camera shows its albedo) and a dim dome (ambient).
DEFAULT_HEADLIGHT_IRRADIANCE = np.pi
DEFAULT_DOME = 0.1


def default_lights(camera) -> tuple:
    """(headlight, dome colour) for a stage with no lights, attached to the tracer ``camera``."""
    forward = -np.asarray(camera.camera_to_world, np.float64)[:3, 2]
    sun = DistantLight(direction=forward, irradiance=(DEFAULT_HEADLIGHT_IRRADIANCE,) * 3, angle=0.0,
                       name="default camera light")
    return sun, np.full(3, DEFAULT_DOME, np.float32)


def _members(collection, paths: list) -> np.ndarray | None:
    """Indices of ``paths`` the collection includes; None for a collection of everything (its fallback: includeRoot
    and nothing else authored), so an unlinked light costs no membership queries."""
    if not collection:
        return None
    authored = (collection.GetIncludesRel().GetTargets() or collection.GetExcludesRel().GetTargets()
                or collection.GetMembershipExpressionAttr().HasAuthoredValue())
    if not authored and collection.GetIncludeRootAttr().Get() is not False:
        return None
    query = collection.ComputeMembershipQuery()
    return np.array([i for i, p in enumerate(paths) if query.IsPathIncluded(Sdf.Path(p))], np.int64)


def light_links(prims: list, object_names: list, time) -> list:
    """One :class:`tracer.lights.linking.LightLink` per light prim (None: a light of no prim, e.g. the default light);
    ``object_names`` are the scene's object names, prim paths (``path[...]`` for a PointInstancer's pieces and
    instances). Empty when no light is linked."""
    paths = [str(n).split("[", 1)[0] if str(n).startswith("/") else "/" for n in object_names]
    links = []
    for prim in prims:
        link = LightLink()
        if prim is not None:
            lux = UsdLux.LightAPI(prim)
            link.receivers = _members(lux.GetLightLinkCollectionAPI(), paths)
            link.blockers = _members(lux.GetShadowLinkCollectionAPI(), paths)
            link.cast_shadow = bool(_get(UsdLux.ShadowAPI(prim).GetShadowEnableAttr(), time, True))
            link.diffuse = _finite(float(_get(lux.GetDiffuseAttr(), time, 1.0)), "inputs:diffuse")
            link.glossy = _finite(float(_get(lux.GetSpecularAttr(), time, 1.0)), "inputs:specular")
            link.camera = _arnold_camera_visibility(prim, time)
        links.append(link)
    return [] if all(k.is_default() for k in links) else links

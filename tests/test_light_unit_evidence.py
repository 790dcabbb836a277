"""Exporter unit guesses apply only to what the exporter authored (issue #30; docs/usd.md, "Two readings").

usd_io/exporters.py guesses who wrote a stage (Blender by version, Omniverse Kit) and reads its lights in that
writer's units. A guess is about the numbers the writer wrote: a light whose intensity is not authored (in either
spelling: ``inputs:intensity``, or ``intensity`` as UsdLux spelt it before 21.02) carries UsdLux's fallback, which
no exporter chose, and must read as the spec says. usd-wg's NormalsTextureBiasAndScale (Kit metadata, a
DistantLight with no intensity) rendered near black when Kit's 2^-9 scaled the fallback.

Each rule gets a stage with and without an authored intensity; the independent check is the spec's own reading of
the same light (the stage without the writer's metadata), not the code's inverse."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux

from usd_io import load_stage
from usd_io.exporters import KIT_EV, NITS_TO_W_PER_M2

KIT = {"omni_layer": {"name": "root"}}
SUN_OMEGA_1DEG = 2 * np.pi * (1 - np.cos(np.radians(0.5)))  # the solid angle of a 1° (diameter) sun


def stage(writer=None, light="distant", intensity=None, old_spelling=False, exposure=None, angle=None):
    """A floor, a camera and one light; ``writer``: "kit" (Kit's customLayerData) or a Blender ``doc`` string."""
    s = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(s, "Z")
    if writer == "kit":
        s.GetRootLayer().customLayerData = KIT
    elif writer:
        s.GetRootLayer().documentation = writer
    cam = UsdGeom.Camera.Define(s, "/Cam")
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 10))
    floor = UsdGeom.Mesh.Define(s, "/Floor")
    floor.CreatePointsAttr([(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)])
    floor.CreateFaceVertexCountsAttr([4])
    floor.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    kind = {"distant": UsdLux.DistantLight, "sphere": UsdLux.SphereLight, "dome": UsdLux.DomeLight}[light]
    lt = kind.Define(s, "/Light")
    if light == "sphere":
        lt.CreateRadiusAttr(0.1)
        lt.AddTranslateOp().Set(Gf.Vec3d(0, 0, 2))
    prim = lt.GetPrim()
    if intensity is not None:
        if old_spelling:  # `float intensity = 3000`, as Kit-written samples have it
            prim.CreateAttribute("intensity", Sdf.ValueTypeNames.Float).Set(float(intensity))
        else:
            UsdLux.LightAPI(prim).CreateIntensityAttr(float(intensity))
    if exposure is not None:
        UsdLux.LightAPI(prim).CreateExposureAttr(float(exposure))
    if angle is not None:
        prim.CreateAttribute("angle" if old_spelling else "inputs:angle", Sdf.ValueTypeNames.Float).Set(angle)
    return s


def light_of(s, units="auto"):
    """The tracer light the stage's one light became (a DomeLight: the scene, whose background it sets)."""
    scene, info = load_stage(s, width=16, height=16, light_units=units)
    light = info.lights[0][2]
    return scene if isinstance(light, dict) or light is None else light


def value(light):
    for name in ("irradiance", "intensity", "radiance", "background"):
        if hasattr(light, name):
            return np.asarray(getattr(light, name), float)
    raise AssertionError(light)


# ---------------------------------------------------------------------------------------------- Omniverse Kit
def test_kit_distant_light_without_intensity_is_lit_as_the_spec_says():
    """NormalsTextureBiasAndScale's pattern: Kit metadata, an angle, no intensity: the spec's E = 50000·Ω."""
    kit = value(light_of(stage("kit", angle=1.0)))
    spec = value(light_of(stage(None, angle=1.0)))
    np.testing.assert_allclose(kit, spec, rtol=1e-6)
    np.testing.assert_allclose(kit, 50000 * SUN_OMEGA_1DEG, rtol=1e-3)  # 11.96 W/m², not × 2^-9


def test_kit_old_spelling_intensity_is_read_and_scaled():
    """`float intensity = 3000` (pre-21.02, no `inputs:`) with `float angle = 1`: 3000 · Ω · 2^-9."""
    kit = value(light_of(stage("kit", intensity=3000, old_spelling=True, angle=1.0)))
    np.testing.assert_allclose(kit, 3000 * SUN_OMEGA_1DEG * 2.0 ** KIT_EV, rtol=1e-3)


def test_kit_authored_intensity_is_scaled():
    kit = value(light_of(stage("kit", intensity=3000, angle=1.0)))
    np.testing.assert_allclose(kit, 3000 * SUN_OMEGA_1DEG * 2.0 ** KIT_EV, rtol=1e-3)


def test_kit_sphere_light_with_only_an_exposure_keeps_the_spec():
    """The exposure is authored, the intensity is UsdLux's fallback 1: no Kit number to scale."""
    kit = value(light_of(stage("kit", light="sphere", exposure=3.0)))
    spec = value(light_of(stage(None, light="sphere", exposure=3.0)))
    np.testing.assert_allclose(kit, spec, rtol=1e-6)
    authored = value(light_of(stage("kit", light="sphere", intensity=8.0, exposure=3.0)))
    np.testing.assert_allclose(authored, value(light_of(stage(None, light="sphere", intensity=8.0, exposure=3.0)))
                               * 2.0 ** KIT_EV, rtol=1e-6)


def test_kit_dome_without_intensity_keeps_the_spec():
    kit = light_of(stage("kit", light="dome")).background
    spec = light_of(stage(None, light="dome")).background
    np.testing.assert_allclose(kit, spec, rtol=1e-6)
    dome = light_of(stage("kit", light="dome", intensity=512.0)).background
    np.testing.assert_allclose(dome, 512 * 2.0 ** KIT_EV, rtol=1e-6)


# ---------------------------------------------------------------------------------------------- Blender
def test_blender_sun_without_intensity_keeps_the_spec():
    """Blender ≥ 4 reads a sun as E = 4·I with diameter 2·angle: only for the intensity and angle it wrote."""
    b = value(light_of(stage("Blender v4.2.0", angle=1.0)))
    np.testing.assert_allclose(b, value(light_of(stage(None, angle=1.0))), rtol=1e-6)
    authored = light_of(stage("Blender v4.2.0", intensity=0.75, angle=1.0))
    np.testing.assert_allclose(value(authored), 3.0, rtol=1e-6)
    np.testing.assert_allclose(authored.angle, np.radians(2.0), rtol=1e-6)


@pytest.mark.parametrize("doc", ["Blender v3.1.2", "Blender v3.4.1"])
def test_old_blender_sphere_without_intensity_keeps_the_spec(doc):
    """2.83–3.1 (P/100) and 3.2–3.6 without a dome (the same): a lamp with no intensity is UsdLux's fallback."""
    b = value(light_of(stage(doc, light="sphere")))
    np.testing.assert_allclose(b, value(light_of(stage(None, light="sphere"))), rtol=1e-6)
    authored = value(light_of(stage(doc, light="sphere", intensity=10.0)))
    np.testing.assert_allclose(authored, 1000 / (4 * np.pi), rtol=1e-6)  # P = 100·I = 1000 W


def test_blender_nits_dome_without_intensity_keeps_the_spec():
    b = light_of(stage("Blender v3.4.1", light="dome")).background
    np.testing.assert_allclose(b, light_of(stage(None, light="dome")).background, rtol=1e-6)
    authored = light_of(stage("Blender v3.4.1", light="dome", intensity=683.0)).background
    np.testing.assert_allclose(authored, 683 * NITS_TO_W_PER_M2, rtol=1e-5)

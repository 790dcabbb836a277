"""Light units (docs/units.md): the same light rendered by Cycles and by the tracer, through both front ends.

A grey Lambertian floor seen from above; the ratio of mean linear radiance, ours / Cycles, must be 1 within
UNIT_RATIO_TOL for every conversion (point, point with radius, spot, sun, area rectangle and disk, colour and
exposure).
"""

import math

import numpy as np
import pytest

import cycles_harness as H
from cycles_geometry import look_at, trs
from cycles_scenes import GREY, camera, floor, point, scene, spot, sun
from cycles_thresholds import UNIT_RATIO_TOL

pytestmark = pytest.mark.cycles


def area(name, location, power, shape, size, color=(1, 1, 1)):
    return dict(name=name, type="AREA", matrix=np.asarray(look_at(location, (location[0], location[1], 0.0),
                                                                  up=(0, 1, 0))).tolist(),
                energy=power, color=list(color), shape=shape, size=list(size))


LIGHTS = {
    "point": point("L", (0.5, -0.3, 3.0), 800.0),
    "point_radius": point("L", (0.5, -0.3, 3.0), 800.0, radius=0.5),
    "point_colour_exposure": dict(point("L", (0.5, -0.3, 3.0), 300.0, color=(0.9, 0.5, 0.2)), exposure=1.0),
    "spot_blend": spot("L", (0.0, -1.0, 4.0), (0.3, 0.2, 0.0), 1500.0, math.radians(40), 0.4),
    "sun": sun("L", (0.4, -0.5, 1.0), 2.5),
    "area_square": area("L", (0.3, 0.2, 2.0), 400.0, "SQUARE", (1.0, 1.0)),
    "area_disk": area("L", (0.3, 0.2, 2.0), 400.0, "ELLIPSE", (1.5, 0.8)),
}


def units_scene(key):
    return scene(f"units_{key}", camera=camera((0.0, -0.01, 6.0), (0.0, 0.0, 0.0), lens=30.0, up=(0, 1, 0)),
                 materials={"grey": GREY}, objects=[floor(size=12.0)], lights=[LIGHTS[key]], depth=0, samples=64,
                 ours_samples=2, width=96, height=72)


@pytest.mark.parametrize("front_end", ["addon", "usd"])
@pytest.mark.parametrize("key", list(LIGHTS))
def test_light_units_match_cycles(bpy_module, tmp_path, key, front_end):
    desc = units_scene(key)
    ref = H.cycles_reference(desc)["rgb"]
    ours = H.render_ours(desc, front_end, workdir=str(tmp_path), light_samples=64).rgb
    ratio = ours.reshape(-1, 3).mean(0) / ref.reshape(-1, 3).mean(0)
    print(f"[cycles] units {key} [{front_end}]: ours/Cycles per channel {np.round(ratio, 4).tolist()}")
    if np.any(np.abs(ratio - 1) > UNIT_RATIO_TOL):
        paths = H.save_comparison(str(tmp_path), f"units_{key}", ours, ref)
        pytest.fail(f"{key} [{front_end}]: ours/Cycles = {ratio.tolist()} (tolerance {UNIT_RATIO_TOL}); {paths}")


#: Lights with ``normalize`` off (Blender's USD importer sets it so): the power is no longer divided by the
#: emitter's area (area lights), sphere cross-section (point and spot radius) or the sun disk's size.
UNNORMALIZED = {
    "area_square_unnormalized": dict(LIGHTS["area_square"], energy=150.0, size=[0.6, 0.6], normalize=False),
    "area_disk_unnormalized": dict(LIGHTS["area_disk"], energy=150.0, size=[0.8, 0.5], normalize=False),
    "point_radius_unnormalized": dict(LIGHTS["point_radius"], energy=800.0, radius=0.3, normalize=False),
    "spot_radius_unnormalized": dict(LIGHTS["spot_blend"], radius=0.4, normalize=False),
    "sun_angle_unnormalized": dict(LIGHTS["sun"], angle=0.3, normalize=False),
}


@pytest.mark.parametrize("key", list(UNNORMALIZED))
def test_unnormalized_lights_match_cycles(bpy_module, tmp_path, key):
    LIGHTS[key] = UNNORMALIZED[key]
    try:
        desc = units_scene(key)
    finally:
        del LIGHTS[key]
    ref = H.cycles_reference(desc)["rgb"]
    ours = H.render_ours(desc, "addon", workdir=str(tmp_path), light_samples=64).rgb
    ratio = ours.reshape(-1, 3).mean(0) / ref.reshape(-1, 3).mean(0)
    print(f"[cycles] units {key} [addon]: ours/Cycles per channel {np.round(ratio, 4).tolist()}")
    if np.any(np.abs(ratio - 1) > UNIT_RATIO_TOL):
        paths = H.save_comparison(str(tmp_path), f"units_{key}", ours, ref)
        pytest.fail(f"{key} [addon]: ours/Cycles = {ratio.tolist()} (tolerance {UNIT_RATIO_TOL}); {paths}")

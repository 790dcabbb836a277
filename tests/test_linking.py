"""Light linking, shadow linking and ray visibility (tracer/lights/linking.py): the Embree masks against closed-form hits,
and renders of a lit floor against the closed form E = I·cos θ / r² (a Lambert floor of albedo ρ reads ρ/π·E)."""

from __future__ import annotations

import numpy as np
import pytest

from tracer import Camera, PointLight, RenderSettings, SceneBuilder
from tracer.accel.accelerator import Accelerator
from tracer.lights.linking import ALL_VISIBLE, CAMERA, GLOSSY, SHADOW, LightLink, pack
from tracer import render


def _stack(visibility=None, links=None):
    """Object 0: the unit right triangle at z = 0; object 1: the same at z = -1."""
    b = SceneBuilder()
    tri_v, tri_f = [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]
    b.add_mesh(tri_v, tri_f, name="top")
    b.add_mesh(np.array(tri_v, float) - (0, 0, 1), tri_f, name="bottom")
    b.camera = Camera.look_at((0, 0, 5), (0, 0, 0))
    b.add_light(PointLight(position=(0, 0, 3), intensity=(1, 1, 1)))
    b.add_light(PointLight(position=(0, 0, 4), intensity=(1, 1, 1)))
    scene = b.build()
    scene.object_visibility = visibility
    scene.light_links = links or []
    return scene


_O = np.array([[0.2, 0.3, 2.0]], np.float32)
_D = np.array([[0, 0, -1]], np.float32)


@pytest.mark.parametrize("instanced", [False, True])
def test_masks_hide_an_object_from_one_ray_type(instanced):
    """The top triangle seen by everything but the camera: a camera ray passes through to the bottom one (t = 3),
    a glossy ray and a shadow ray stop at the top one (t = 2)."""
    scene = _stack(visibility=np.array([ALL_VISIBLE & ~CAMERA, ALL_VISIBLE], np.uint8))
    acc = Accelerator(scene, instanced=instanced)
    assert acc.closest_hits(_O, _D, mask=np.array([CAMERA], np.uint32)).t[0] == pytest.approx(3.0)
    assert acc.closest_hits(_O, _D, mask=np.array([GLOSSY], np.uint32)).t[0] == pytest.approx(2.0)
    assert acc.closest_hits(_O, _D).t[0] == pytest.approx(2.0)  # no mask: every object
    assert acc.occluded(_O, _D, np.array([2.5], np.float32), mask=np.array([1 << 3], np.uint32)).tolist() == [True]


@pytest.mark.parametrize("instanced", [False, True])
def test_shadow_linking_masks_per_ray(instanced):
    """Light 0's blockers are the bottom triangle only: its shadow ray over the top one is free, light 1's (all
    blockers) is blocked; an object that casts no shadow blocks no light; a light that casts no shadow is never
    blocked."""
    scene = _stack(visibility=np.array([ALL_VISIBLE, ALL_VISIBLE & ~SHADOW], np.uint8),
                   links=[LightLink(blockers=[1]), LightLink(), ])
    links = pack(scene, 2)
    acc = Accelerator(scene, instanced=instanced)
    o, d = np.repeat(_O, 4, 0), np.repeat(_D, 4, 0)
    t_max = np.array([2.5, 2.5, 3.5, 3.5], np.float32)
    light = np.array([0, 1, 0, 1])
    blocked = acc.occluded(o, d, t_max, mask=links.shadow_mask[light])
    # light 0 over the top triangle: not a blocker; light 1: blocked; light 0 down to the bottom triangle: it is
    # light 0's blocker, but casts no shadow; light 1 down past both: the top one blocks it
    assert blocked.tolist() == [False, True, False, True]
    scene2 = _stack(links=[LightLink(cast_shadow=False), LightLink()])
    acc2 = Accelerator(scene2, instanced=instanced)
    links2 = pack(scene2, 2)
    assert acc2.occluded(o[:2], d[:2], t_max[:2], mask=links2.shadow_mask[[0, 1]]).tolist() == [False, True]


def test_no_linking_packs_inactive():
    links = pack(_stack(), 2)
    assert not links.masked and not links.visibility and not links.receivers
    links = pack(_stack(visibility=np.full(2, ALL_VISIBLE, np.uint8)), 2)
    assert not links.masked  # everything visible: no masks at all
    with pytest.raises(ValueError, match="object id 7"):
        pack(_stack(links=[LightLink(receivers=[7]), LightLink()]), 2)


def _floor(links=None, card=None, lid=False):
    """A grey floor (object 0) under two point lights above its centre, I = 10 and 20 W/sr at heights 2 and 4
    (E = 2.5 and 1.25 W/m² there); with ``card`` (its visibility bits) a small card (object 1) at height 1 between
    them and the centre (with ``lid`` another card, object 2, at height 3). An orthographic camera looks straight
    down at the centre."""
    b = SceneBuilder()
    m = b.add_material("grey", diffuse=(0.5, 0.5, 0.5))
    b.add_mesh([[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]], [[0, 1, 2], [0, 2, 3]], material=m, name="floor")
    if card is not None:
        b.add_mesh([[-0.3, -0.3, 1], [0.3, -0.3, 1], [0.3, 0.3, 1], [-0.3, 0.3, 1]], [[0, 1, 2], [0, 2, 3]],
                   material=m, name="card")
    if lid:
        b.add_mesh([[-0.3, -0.3, 3], [0.3, -0.3, 3], [0.3, 0.3, 3], [-0.3, 0.3, 3]], [[0, 1, 2], [0, 2, 3]],
                   material=m, name="lid")
    b.camera = Camera.look_at((0, 0, 6), (0, 0, 0), up=(0, 1, 0), projection="orthographic",
                              horizontal_aperture=0.02, vertical_aperture=0.02)
    b.add_light(PointLight(position=(0, 0, 2), intensity=(10, 10, 10)))
    b.add_light(PointLight(position=(0, 0, 4), intensity=(20, 20, 20)))
    scene = b.build()
    scene.light_links = links or []
    if card is not None:
        scene.object_visibility = np.array([ALL_VISIBLE, card] + [HIDDEN] * lid, np.uint8)
    return scene


def _centre(scene):
    return float(render(scene, RenderSettings(width=4, height=4, samples=1, max_depth=0)).rgb.mean())


HIDDEN = ALL_VISIBLE & ~CAMERA  # seen by reflections and shadow rays, not by the camera


@pytest.mark.parametrize("links, card, share", [
    (None, HIDDEN & ~SHADOW, 1.0),  # a card seen by no eye and no shadow ray changes nothing
    (None, HIDDEN, 0.0),  # the same card casting shadows: the centre is in the shadow of both lights
    ([LightLink(blockers=[0]), LightLink()], HIDDEN, 2.5 / 3.75),  # light 0 not shadowed by the card
    ([LightLink(), LightLink(cast_shadow=False)], HIDDEN, 1.25 / 3.75),  # light 1 casts no shadow
    ([LightLink(receivers=[]), LightLink()], None, 1.25 / 3.75),  # light 0 lights no object
    ([LightLink(), LightLink(receivers=[0])], None, 1.0),  # light 1 lights the floor: all of it
    ([LightLink(diffuse=False), LightLink()], None, 1.25 / 3.75),  # light 0 gives no diffuse light
])
def test_linked_floor_against_the_inverse_square_law(links, card, share):
    """The floor's centre under linked lights, as the share of its unlinked brightness the closed form gives
    (E = I/r²: 2.5 from light 0, 1.25 from light 1)."""
    full = _centre(_floor())
    assert full > 0.1
    assert _centre(_floor(links, card)) == pytest.approx(share * full, rel=1e-4, abs=1e-6)


# ------------------------------------------------------------------------------------------ USD, `whitted render`
def _usd_stage(path, linked: bool, card: bool):
    """The lit floor as a USD stage: two SphereLights of radius 0 on one line from the floor's centre, A at
    (2, 0, 2) and B at (4, 0, 4) with intensities 10 and 20 (E ∝ I/r²: 1.25 and 0.625, so A gives 2/3), and a card
    on that line at (1, 0, 1), out of the top-down orthographic camera's view. ``linked``: A's shadowLink excludes
    the card, B's lightLink includes only the card (it lights no floor)."""
    from pxr import Gf, Usd, UsdGeom, UsdLux

    s = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(s, "Z")
    cam = UsdGeom.Camera.Define(s, "/Cam")
    cam.CreateProjectionAttr("orthographic")
    cam.CreateHorizontalApertureAttr(0.2)
    cam.CreateVerticalApertureAttr(0.2)
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 6))

    def quad(name, half, z, x=0.0):
        m = UsdGeom.Mesh.Define(s, name)
        m.CreatePointsAttr([(x - half, -half, z), (x + half, -half, z), (x + half, half, z), (x - half, half, z)])
        m.CreateFaceVertexCountsAttr([4])
        m.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
        return m

    quad("/Floor", 3.0, 0.0)
    if card:
        quad("/Card", 0.2, 1.0, x=1.0)
    lights = []
    for name, pos, intensity in (("/A", (2, 0, 2), 10.0), ("/B", (4, 0, 4), 20.0)):
        light = UsdLux.SphereLight.Define(s, name)
        light.CreateRadiusAttr(0.0)
        light.CreateIntensityAttr(intensity)
        light.AddTranslateOp().Set(Gf.Vec3d(*pos))
        lights.append(UsdLux.LightAPI(light.GetPrim()))
    if linked:
        lights[0].GetShadowLinkCollectionAPI().ExcludePath("/Card")
        receivers = lights[1].GetLightLinkCollectionAPI()
        receivers.CreateIncludeRootAttr().Set(False)
        receivers.IncludePath("/Card")
    s.Save()


def test_usd_links_through_whitted_render(tmp_path):
    """`whitted render` of a stage whose light A ignores the card's shadow and whose light B lights only the card:
    the floor's centre gets A's light alone, 2/3 of the unlinked card-free floor (rendered through load_stage)."""
    from tracer import read_image
    from usd_io import load_stage
    from usd_io.cli import main  # `whitted render`, in this process (the script adds only its fast exit)

    _usd_stage(tmp_path / "linked.usda", linked=True, card=True)
    _usd_stage(tmp_path / "free.usda", linked=False, card=False)
    out = tmp_path / "linked.exr"
    assert main(["render", str(tmp_path / "linked.usda"), "-o", str(out), "--width", "4", "--height", "4", "--aa",
                 "1", "--quiet"]) == 0
    linked = float(read_image(str(out))[..., :3].mean())
    scene, _ = load_stage(str(tmp_path / "free.usda"), width=4, height=4)
    free = float(render(scene, RenderSettings(width=4, height=4, samples=1)).rgb.mean())
    assert free > 0.01
    assert linked == pytest.approx(free * 2.0 / 3.0, rel=2e-3)


def test_links_for_other_lights_are_dropped_with_a_warning():
    """A session's new light list leaves the old links behind: they are not applied to the wrong lights."""
    scene = _stack(links=[LightLink(receivers=[]), LightLink()])
    scene.lights = scene.lights[:1]
    with pytest.warns(UserWarning, match="rendered unlinked"):
        assert not pack(scene, 1).receivers


def test_explain_names_only_the_lights_blockers():
    """Explain Pixel reports a shadow ray as blocked by what its light's shadow rays see: the card shadows light 1
    (all blockers) and not light 0 (linked to the floor only); light 1 linked to the lid above the card is blocked
    by the lid, not by the card its ray meets first."""
    from tracer import explain_pixel

    scene = _floor([LightLink(blockers=[0]), LightLink()], HIDDEN)
    tree = explain_pixel(scene, RenderSettings(width=4, height=4, samples=1, max_depth=0), 2, 2)
    shadows = [(r.light, r.occluded, r.blocker) for r in tree.samples[0] if r.type == "shadow"]
    assert shadows == [(0, False, None), (1, True, "card")]
    scene = _floor([LightLink(), LightLink(blockers=[2])], HIDDEN, lid=True)
    tree = explain_pixel(scene, RenderSettings(width=4, height=4, samples=1, max_depth=0), 2, 2)
    shadows = [(r.light, r.occluded, r.blocker) for r in tree.samples[0] if r.type == "shadow"]
    assert shadows == [(0, True, "card"), (1, True, "lid")]


# ------------------------------------------------------------------------------------------ emissive meshes
def _glowing_floor(emit=(5.0, 5.0), links=None):
    """The floor (object 0) under one point light (I = 10 W/sr at height 2: E = 2.5 at the centre) and two
    emissive panels (objects 1 and 2, radiance ``emit``), off to the sides at height 1.5, clear of the light's
    shadow ray and the orthographic camera's view; ``links``: ``scene.emitter_links``."""
    b = SceneBuilder()
    m = b.add_material("grey", diffuse=(0.5, 0.5, 0.5))
    b.add_mesh([[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]], [[0, 1, 2], [0, 2, 3]], material=m, name="floor")
    for x, le in zip((-1.0, 1.0), emit):
        glow = b.add_material(f"glow{x}", diffuse=(0, 0, 0), emission=(le,) * 3)
        b.add_mesh([[x - 0.3, -0.3, 1.5], [x + 0.3, -0.3, 1.5], [x + 0.3, 0.3, 1.5], [x - 0.3, 0.3, 1.5]],
                   [[0, 1, 2], [0, 2, 3]], material=glow, name=f"panel{x}")
    b.camera = Camera.look_at((0, 0, 6), (0, 0, 0), up=(0, 1, 0), projection="orthographic",
                              horizontal_aperture=0.02, vertical_aperture=0.02)
    b.add_light(PointLight(position=(0, 0, 2), intensity=(10, 10, 10)))
    scene = b.build()
    scene.emitter_links = links or {}
    return scene


def _lit(scene):
    return float(render(scene, RenderSettings(width=4, height=4, samples=1, max_depth=0, light_samples=4)).rgb.mean())


def test_linked_emitter_lights_only_its_receivers():
    """An emissive panel linked away from the floor leaves it as lit by the other lights alone (the same render
    as with that panel dark), one linked to the floor lights it as unlinked; each emitting object is then its own
    MESH light, the unlinked ones one light as without linking."""
    lamp = 0.5 / np.pi * 2.5  # the point light alone: ρ/π·I/r²
    both, one = _lit(_glowing_floor()), _lit(_glowing_floor(emit=(0.0, 5.0)))
    assert both > 1.1 * one and one > 1.1 * lamp  # each panel adds light to the centre
    assert _lit(_glowing_floor(emit=(0.0, 0.0))) == pytest.approx(lamp, rel=1e-4)
    # panel 1 (object 1) lights only panel 2: the floor reads the lamp and panel 2, exactly as with panel 1 dark
    assert _lit(_glowing_floor(links={1: LightLink(receivers=[2])})) == pytest.approx(one, rel=1e-9)
    assert _lit(_glowing_floor(links={1: LightLink(receivers=[2]), 2: LightLink(receivers=[])})) == \
        pytest.approx(lamp, rel=1e-4)
    # linked to the floor (include): as unlinked, within the noise of sampling the panels as two lights
    assert _lit(_glowing_floor(links={1: LightLink(receivers=[0])})) == pytest.approx(both, rel=0.02)

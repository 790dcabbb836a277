"""Scene descriptions for the Cycles comparisons: plain, JSON-hashable dicts that say what is in a scene.

One description feeds three builders (``harness.build_bpy`` for Blender/Cycles and the add-on, ``build_direct`` for
a tracer scene made straight from the numbers, and Blender's USD export for the USD reader), and its content hash
keys the cached Cycles reference. Units are Blender's: lights in W (sun: W/m²), materials are Principled BSDF inputs.

Every image scene isolates one thing; ``IMAGE_SCENES`` lists them for the tests and the gallery.
"""

from __future__ import annotations

import copy
import math

import numpy as np

from cycles_geometry import look_at, trs

WIDTH, HEIGHT = 160, 120


def _m(a) -> list:
    return np.asarray(a, np.float64).round(12).tolist()


# ---------------------------------------------------------------- materials (Principled BSDF inputs)
def lambert(color):
    """Pure Lambert in Cycles: Principled with Specular IOR Level 0 (DESIGN.md, measured)."""
    return dict(base_color=list(color), roughness=0.5, specular_ior_level=0.0)


def mirror(color=(1.0, 1.0, 1.0)):
    return dict(base_color=list(color), metallic=1.0, roughness=0.0, specular_ior_level=0.0)


def glass(ior, color=(1.0, 1.0, 1.0)):
    return dict(base_color=list(color), transmission=1.0, roughness=0.0, ior=ior)


def emissive(color, strength=1.0):
    return dict(base_color=[0.0, 0.0, 0.0], specular_ior_level=0.0, emission_color=list(color),
                emission_strength=strength)


# ---------------------------------------------------------------- parts
def camera(eye, target, *, lens=35.0, sensor_width=36.0, sensor_height=24.0, sensor_fit="AUTO", shift=(0.0, 0.0),
           kind="PERSP", ortho_scale=6.0, up=(0, 0, 1)):
    return dict(matrix=_m(look_at(eye, target, up)), type=kind, lens=lens, sensor_width=sensor_width,
                sensor_height=sensor_height, sensor_fit=sensor_fit, shift_x=shift[0], shift_y=shift[1],
                ortho_scale=ortho_scale)


def obj(name, kind, material, *, matrix=None, params=None, smooth=False, pass_index=1, materials=None):
    return dict(name=name, mesh=dict(kind=kind, params=params or {}), matrix=_m(matrix if matrix is not None
                                                                                  else np.eye(4)),
                materials=materials or [material], smooth=smooth, pass_index=pass_index)


def sphere(name, center, radius, material, pass_index, segments=64, rings=32):
    return obj(name, "uv_sphere", material, matrix=trs(center, scale=(radius,) * 3),
               params=dict(segments=segments, rings=rings), smooth=True, pass_index=pass_index)


def floor(name="Floor", size=8.0, material="grey", pass_index=1, checker=None, divisions=(1, 1), z=0.0):
    if checker:
        return obj(name, "plane", None, matrix=trs((0, 0, z)), params=dict(size=(size, size), divisions=divisions,
                                                                        checker=True),
                   materials=list(checker), pass_index=pass_index)
    return obj(name, "plane", material, matrix=trs((0, 0, z)), params=dict(size=(size, size)), pass_index=pass_index)


def point(name, location, power, color=(1, 1, 1), radius=0.0):
    return dict(name=name, type="POINT", matrix=_m(trs(location)), energy=power, color=list(color), radius=radius)


def spot(name, location, target, power, size, blend, color=(1, 1, 1)):
    return dict(name=name, type="SPOT", matrix=_m(look_at(location, target)), energy=power, color=list(color),
                radius=0.0, spot_size=size, spot_blend=blend)


def sun(name, direction_to_sun, strength, color=(1, 1, 1)):
    d = np.asarray(direction_to_sun, np.float64)
    return dict(name=name, type="SUN", matrix=_m(look_at(d, (0, 0, 0))), energy=strength, color=list(color),
                angle=0.0)


def scene(name, *, camera, objects, materials, lights=(), world=(0.0, 0.0, 0.0), world_strength=1.0, depth=4,
          width=WIDTH, height=HEIGHT, samples=64, ours_samples=6, sky_samples=0, note=""):
    """``samples`` = Cycles samples per pixel for the reference; ``ours_samples`` = N for our N×N; ``depth`` = our
    max_depth = Cycles' glossy and transmission bounces."""
    return dict(name=name, camera=camera, objects=list(objects), materials=dict(materials), lights=list(lights),
                world=dict(color=list(world), strength=world_strength), depth=depth, width=width, height=height,
                samples=samples, ours_samples=ours_samples, sky_samples=sky_samples, note=note)


def variant(desc, **changes):
    d = copy.deepcopy(desc)
    d.update(changes)
    return d


# ---------------------------------------------------------------- the image scenes
GREY = lambert((0.8, 0.8, 0.8))
CAM = camera((0.0, -7.0, 3.2), (0.0, 0.0, 0.7))


def _emissive_flat():
    mats = {"red": emissive((0.9, 0.1, 0.1)), "green": emissive((0.1, 0.8, 0.2)), "blue": emissive((0.2, 0.3, 1.0)),
            "floor": emissive((0.3, 0.3, 0.3))}
    return scene("emissive_flat", camera=CAM, materials=mats, objects=[
        floor(material="floor", size=6.0, pass_index=1),
        sphere("Red", (-1.6, 0.5, 1.0), 1.0, "red", 2),
        obj("Green", "box", "green", matrix=trs((1.4, 0.8, 0.75), (0, 0, 0.5), (1.5, 1.5, 1.5)), pass_index=3),
        sphere("Blue", (0.1, -1.4, 0.5), 0.5, "blue", 4)], depth=0, samples=16,
        note="eye rays only: emission, no lights; tests coverage of each pixel")


def _emission_light():
    mats = dict(BASE_MATS, glow=emissive((1.0, 0.9, 0.7), strength=6.0))
    return scene("emission_light", camera=CAM, materials=mats, objects=_base_objects() + [
        obj("Panel", "box", "glow", matrix=trs((0.0, 0.3, 3.2), (0, 0, 0), (2.0, 1.2, 0.05)), pass_index=5)],
        depth=0, samples=64,
        note="an emissive panel is the only light: mesh emission lights the floor and casts soft shadows")


def _emission_grazing():
    """A floor lit by an emissive panel out to the horizon: far from the panel, shadow rays reach it at grazing
    angles (they once overshot the panel's plane by their own ε offset and were blocked by the emitter itself)."""
    mats = dict(BASE_MATS, glow=emissive((1.0, 1.0, 1.0), strength=4.0))
    return scene("emission_grazing", camera=camera((0.0, -9.0, 1.5), (0.0, 4.0, 0.3)), materials=mats, objects=[
        floor(size=40.0, pass_index=1),
        obj("Panel", "plane", "glow", matrix=trs((0.0, 0.0, 2.0), (math.pi, 0, 0)), params=dict(size=(2.0, 2.0)),
            pass_index=5)],
        depth=0, samples=128, note="an emissive panel facing down lights a 40 m floor: grazing shadow rays")


def _environment():
    """A lat-long world seen directly (sky, landmarks) and in a mirror ball (turned and flipped in the mirror)."""
    mats = dict(BASE_MATS, mirror=mirror((0.9, 0.9, 0.9)))
    d = scene("environment", camera=camera((3.0, -6.0, 1.6), (0.0, 0.0, 1.2), lens=24.0), materials=mats,
              objects=[floor(material="grey", pass_index=1, size=4.0),
                       sphere("Ball", (0.0, 0.0, 1.2), 1.0, "mirror", 2)],
              depth=2, samples=64, sky_samples=64,
              note="an equirectangular environment: background, mirror reflections, importance-sampled sky light")
    d["world"]["texture"] = "landmarks"
    d["front_ends"] = ["addon", "direct"]  # Blender's USD export writes the dome; usd_io reads it on its own branch
    return d


def _base_objects(mat="grey"):
    return [floor(material=mat, pass_index=1),
            sphere("Ball", (-0.9, 0.3, 1.0), 1.0, "white", 2),
            obj("Block", "box", "blue", matrix=trs((1.4, -0.4, 0.6), (0, 0, 0.6), (1.2, 1.2, 1.2)), pass_index=3)]


BASE_MATS = {"grey": GREY, "white": lambert((0.85, 0.85, 0.85)), "blue": lambert((0.15, 0.3, 0.8))}


def _point_shadow():
    return scene("point_shadow", camera=CAM, materials=BASE_MATS, objects=_base_objects(),
                 lights=[point("Key", (2.5, -2.0, 5.0), 1500.0)], depth=0, samples=32,
                 note="one point light, radius 0: inverse-square falloff, Lambert, hard shadows")


def _sun():
    return scene("sun", camera=CAM, materials=BASE_MATS, objects=_base_objects(),
                 lights=[sun("Sun", (-1.0, -0.6, 1.4), 3.0)], depth=0, samples=32,
                 note="a sun of strength 3 W/m², angle 0: constant irradiance, parallel hard shadows")


def _spot():
    return scene("spot", camera=CAM, materials=BASE_MATS, objects=_base_objects(),
                 lights=[spot("Spot", (0.5, -2.5, 6.0), (0.0, 0.5, 0.0), 2500.0, math.radians(45), 0.3)],
                 depth=0, samples=32, note="a spot of 45° with blend 0.3: the smoothstep-in-cosine edge")


def _several_lights():
    return scene("several_lights", camera=CAM, materials=BASE_MATS, objects=_base_objects(), lights=[
        point("Warm", (3.0, -2.0, 4.0), 900.0, color=(1.0, 0.7, 0.4)),
        point("Cool", (-3.5, -1.0, 3.0), 700.0, color=(0.4, 0.6, 1.0)),
        sun("Sun", (0.3, 1.0, 1.2), 0.8),
        spot("Spot", (0.0, -3.0, 5.0), (0.3, 0.0, 0.0), 1200.0, math.radians(30), 0.5)],
        depth=0, samples=64, note="two coloured points, a sun and a spot: shadows add up light by light")


def _world(sky_samples=64):
    return scene("world", camera=CAM, materials=BASE_MATS, objects=_base_objects(), world=(0.35, 0.5, 0.8),
                 world_strength=1.0, depth=0, samples=128, sky_samples=sky_samples,
                 note="world colour only: Cycles shadows the sky; ours samples sky visibility")


def _mirror():
    mats = dict(BASE_MATS, mirror=mirror(), red=lambert((0.8, 0.1, 0.1)))
    return scene("mirror", camera=CAM, materials=mats, objects=[
        floor(checker=("grey", "red"), divisions=(8, 8), pass_index=1),
        sphere("Mirror", (-0.6, 0.6, 1.2), 1.2, "mirror", 2),
        obj("Block", "box", "blue", matrix=trs((1.7, -0.8, 0.5), (0, 0, 0.4)), pass_index=3)],
        lights=[point("Key", (2.0, -3.0, 5.0), 1500.0)], depth=4, samples=32,
        note="a perfect mirror ball (metallic 1, roughness 0 ⇔ k_m = 1) over a checker floor")


def _gold_coarse_sphere():
    """A coarse smooth-shaded gold ball under a spot and a sky: near its silhouette the interpolated normals send
    mirror directions below the faces; Cycles bends those normals (ensure_valid_specular_reflection)."""
    mats = dict(BASE_MATS, gold=dict(base_color=[1.0, 0.766, 0.336], metallic=1.0, roughness=0.0,
                                     specular_ior_level=0.5), red=lambert((0.8, 0.1, 0.1)))
    return scene("gold_coarse_sphere", camera=CAM, materials=mats, objects=[
        floor(checker=("grey", "red"), divisions=(8, 8), pass_index=1),
        sphere("Gold", (0.0, 0.5, 1.2), 1.2, "gold", 2, segments=12, rings=6)],
        lights=[spot("Spot", (0.5, -2.5, 6.0), (0.0, 0.5, 0.0), 2500.0, math.radians(45), 0.3)],
        world=(0.3, 0.4, 0.6), depth=4, samples=128, sky_samples=64,
        note="a 12×6 smooth gold ball: reflections off interpolated normals near the rim stay above the surface")


def _metallic_half():
    mats = dict(BASE_MATS, half=dict(base_color=[0.9, 0.9, 0.9], metallic=0.5, roughness=0.0,
                                     specular_ior_level=0.0), red=lambert((0.8, 0.1, 0.1)))
    return scene("metallic_half", camera=CAM, materials=mats, objects=[
        floor(checker=("grey", "red"), divisions=(8, 8), pass_index=1),
        sphere("Half", (-0.6, 0.6, 1.2), 1.2, "half", 2),
        obj("Block", "box", "blue", matrix=trs((1.7, -0.8, 0.5), (0, 0, 0.4)), pass_index=3)],
        lights=[point("Key", (2.0, -3.0, 5.0), 1500.0)], depth=4, samples=32,
        note="metallic 0.5, roughness 0, Specular IOR Level 0 ⇔ k_m = 0.5 with tint = base colour (F82 tint "
             "reflectance of a 0.9 metal rises to 1 at grazing angles)")


def _metallic_half_dielectric():
    d = _metallic_half()
    d["materials"]["half"] = dict(d["materials"]["half"], specular_ior_level=0.5, roughness=0.3)
    d["name"] = "metallic_half_dielectric"
    d["note"] = ("inherent difference: metallic 0.5, roughness 0.3 with Cycles' default dielectric lobe "
                 "(GGX + Fresnel layering) vs our Blinn-Phong highlight and k_m = 0.5 mirror")
    return d


def _checker_backdrop(mats):
    mats.update(black=lambert((0.05, 0.05, 0.05)), white=lambert((0.9, 0.9, 0.9)))
    return obj("Backdrop", "plane", None, matrix=trs((0, 2.5, 2.0), (math.pi / 2, 0, 0)),
               params=dict(size=(10.0, 6.0), divisions=(20, 12), checker=True), materials=["black", "white"],
               pass_index=1)


def _glass_sphere(ior=1.5, name="glass_sphere"):
    mats = {"glass": glass(ior)}
    back = _checker_backdrop(mats)
    return scene(name, camera=camera((0, -6.0, 2.0), (0, 0, 2.0), lens=50), materials=mats, objects=[
        back, sphere("Glass", (0.0, 0.0, 2.0), 1.0, "glass", 2)],
        lights=[sun("Sun", (0.0, -1.0, 0.3), 3.0)], depth=8, samples=512,
        note=f"a glass sphere of IOR {ior} before a checker wall: refraction and Fresnel")


def _water_sphere():
    d = _glass_sphere(1.33, "water_sphere")
    return d


def _glass_slab():
    mats = {"glass": glass(1.5)}
    back = _checker_backdrop(mats)
    return scene("glass_slab", camera=camera((0, -6.0, 2.0), (0, 0, 2.0), lens=50), materials=mats, objects=[
        back, obj("Slab", "box", "glass", matrix=trs((0, 0, 2.0), (0, 0, 0.5), (2.0, 0.4, 1.6)), pass_index=2)],
        lights=[sun("Sun", (0.0, -1.0, 0.3), 3.0)], depth=8, samples=512,
        note="a rotated glass slab (IOR 1.5) shifts the checker edges sideways")


def _tir_prism():
    mats = {"glass": glass(1.5)}
    back = _checker_backdrop(mats)
    m = trs((-0.7, 0.0, 1.3), (0, 0, 0), (1.6, 1.6, 1.6))
    return scene("tir_prism", camera=camera((0, -6.0, 2.0), (0, 0, 2.0), lens=50), materials=mats, objects=[
        back, obj("Prism", "prism", "glass", matrix=m, params=dict(size=1.0, depth=1.0), pass_index=2)],
        lights=[sun("Sun", (0.0, -1.0, 0.3), 3.0)], depth=8, samples=512,
        note="a right-angle glass prism: total internal reflection at the hypotenuse")


def _interreflection(depth, world=(0.0, 0.0, 0.0), name=None):
    mats = dict(BASE_MATS, mirror=mirror(), glass=glass(1.5), red=lambert((0.8, 0.1, 0.1)))
    return scene(name or f"interreflection_d{depth}", camera=camera((0.0, -7.0, 2.5), (0.0, 0.0, 1.0)),
                 materials=mats, objects=[
                     floor(checker=("grey", "red"), divisions=(8, 8), pass_index=1),
                     sphere("Mirror", (-1.1, 0.4, 1.0), 1.0, "mirror", 2),
                     sphere("Glass", (1.1, -0.2, 1.0), 1.0, "glass", 3),
                     obj("MirrorWall", "plane", "mirror", matrix=trs((0, 2.2, 1.5), (math.pi / 2, 0, 0)),
                         params=dict(size=(6.0, 3.0)), pass_index=4)],
                 lights=[point("Key", (2.0, -3.0, 5.0), 1500.0)], world=world, depth=depth,
                 samples=256, sky_samples=16 if any(world) else 0,
                 note=f"mirror ↔ glass inter-reflection cut at depth {depth}" + (
                     "" if not any(world) else " under a sky: Cycles traces one more ray past the bounce limit "
                     "that still collects the world colour (inherent difference)"))


def _orthographic():
    return scene("orthographic", camera=camera((3.0, -6.0, 5.0), (0, 0, 0.5), kind="ORTHO", ortho_scale=7.0),
                 materials=BASE_MATS, objects=_base_objects(), lights=[point("Key", (2.5, -2.0, 5.0), 1500.0)],
                 depth=0, samples=32, note="an orthographic camera (ortho_scale 7): parallel eye rays")


def _whitted_1980():
    mats = {"red": lambert((0.75, 0.05, 0.03)), "yellow": lambert((0.8, 0.7, 0.05)), "mirror": mirror(),
            "glass": glass(1.5)}
    return scene("whitted_1980", camera=camera((0.0, -4.5, 2.0), (0.0, 3.0, 1.0), lens=35.0),
                 materials=mats, objects=[
                     obj("Floor", "plane", None, matrix=trs((0, 6, 0)), params=dict(size=(12.0, 18.0),
                         divisions=(12, 18), checker=True), materials=["red", "yellow"], pass_index=1),
                     sphere("MirrorSphere", (-1.0, 4.2, 1.25), 1.25, "mirror", 2),
                     sphere("GlassSphere", (0.9, 1.6, 1.35), 0.85, "glass", 3)],
                 lights=[point("Key", (-4.0, -3.0, 9.0), 1500.0), point("Fill", (6.0, -1.0, 6.0), 900.0)],
                 world=(0.12, 0.32, 0.85), world_strength=0.5, depth=6, samples=128, sky_samples=16,
                 note="Whitted's 1980 picture: mirror and glass balls over a checker floor under a blue sky")


GOLD = (1.0, 0.766, 0.336)
#: The Principled lobes, each seen on three spheres under one point light with max bounces 0 (direct light only):
#: what the local model must reproduce whatever the roughness (issue 10: ≥ 40 dB each, cycles_thresholds.LOBE_PSNR_MIN).
LOBES = {
    "lobe_dielectric": ("dielectric GGX lobe, Specular IOR Level 0.5 (F0 from IOR 1.5), roughness 0.15 / 0.4 / 0.8",
                        [dict(base_color=(0.8, 0.2, 0.1), roughness=r) for r in (0.15, 0.4, 0.8)]),
    "lobe_metal": ("metal lobe (F82 tint Fresnel, gold base colour), roughness 0.2 / 0.35 / 0.6",
                   [dict(base_color=GOLD, metallic=1.0, roughness=r) for r in (0.2, 0.35, 0.6)]),
    "lobe_specular_level": ("Specular IOR Level 0 / 1, IOR 1.33 / 2.0 at roughness 0.3",
                            [dict(base_color=(0.1, 0.3, 0.8), roughness=0.3, specular_ior_level=0.0),
                             dict(base_color=(0.1, 0.3, 0.8), roughness=0.3, specular_ior_level=1.0),
                             dict(base_color=(0.1, 0.3, 0.8), roughness=0.3, ior=2.0)]),
    "lobe_mixed": ("metallic 0.5, Blender's default surface, a rough dark plastic",
                   [dict(base_color=GOLD, metallic=0.5, roughness=0.45), dict(base_color=(0.8, 0.8, 0.8)),
                    dict(base_color=(0.05, 0.05, 0.05), roughness=0.6, specular_ior_level=0.5)]),
}


def _lobe(name):
    note, params = LOBES[name]
    mats = dict(grey=GREY, **{f"m{i}": p for i, p in enumerate(params)})
    balls = [sphere(f"Ball{i}", (-2.2 + 2.2 * i, 0.0, 1.0), 0.95, f"m{i}", 2 + i) for i in range(3)]
    return scene(name, camera=camera((0.0, -7.5, 2.6), (0.0, 0.0, 0.9)), materials=mats,
                 objects=[floor(pass_index=1)] + balls, lights=[point("Key", (1.5, -4.0, 5.0), 700.0)],
                 depth=0, samples=32, note=f"direct light on Principled materials: {note}")


def image_scenes() -> dict:
    scenes = [_emissive_flat(), _emission_light(), _emission_grazing(), _environment(), _point_shadow(), _sun(), _spot(), _several_lights(), _world(), _mirror(),
              _metallic_half(), _metallic_half_dielectric(), _gold_coarse_sphere(), _glass_sphere(), _water_sphere(), _glass_slab(),
              _tir_prism()] + [_interreflection(d) for d in (1, 2, 4, 8)] + [
        _interreflection(1, world=(0.35, 0.5, 0.8), name="interreflection_sky_d1"), _orthographic(), _whitted_1980()] + [
        _lobe(n) for n in LOBES]
    return {s["name"]: s for s in scenes}


IMAGE_SCENES = image_scenes()

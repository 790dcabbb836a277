"""The Principled BSDF's coat and anisotropic GGX (issue #32), against closed forms and Cycles through bpy.

- **Coat** (Coat Weight, Roughness, IOR, Tint): the BSDF under a dielectric GGX lobe, weighted by
  1 − c·F_coat(μ) and tinted by mix(1, Coat Tint^(1/cos θ_t), c), as Cycles' ``principled_bsdf_emission``
  (tracer/shading/closures.py ``_coated``). A white furnace has a closed form: a white Lambert base under a smooth
  coat of IOR η shows F(μ, η) + (1 − F)·tint^(1/cos θ_t).
- **Anisotropy** (Anisotropic, Anisotropic Rotation, Tangent; Glossy / Metallic BSDF Anisotropy): α_x = r²/a,
  α_y = r²·a with a = √(1 − 0.9·anisotropic) about the tangent turned by 2π·rotation around the normal.

Every scene is built here with bpy (no third-party file is read).
"""

from __future__ import annotations

import math
import os
import sys

import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "cycles"))
sys.path.insert(0, HERE)

import cycles_harness as H  # noqa: E402

from blender_kit import scene as bs  # noqa: E402
from test_blender_fidelity import ours_render, source_of  # noqa: E402

pytestmark = pytest.mark.blender

COAT_IOR = 1.5
TINT = (0.9, 0.5, 0.2)
VIEW = math.radians(60.0)  # the furnace camera's angle from the plane's normal


# ---------------------------------------------------------------------------------------------------- coat
def coat_furnace_scene(size=(16, 16)):
    """A white Lambert Principled (Specular IOR Level 0) under a smooth coat (weight 1, IOR 1.5, tint ``TINT``) on a
    plane seen at 60° from its normal by an orthographic camera, under a uniform white world of radiance 1."""
    import bpy

    scene = bs.reset(size)
    d = 5.0
    bs.add_camera((0.0, -d * math.sin(VIEW), d * math.cos(VIEW)), target=(0.0, 0.0, 0.0), ortho_scale=1.0)
    bs.set_world((1.0, 1.0, 1.0))
    mat, p = bs.shader_material("Coated", "ShaderNodeBsdfPrincipled", **{
        "Base Color": (1.0, 1.0, 1.0), "Specular IOR Level": 0.0, "Roughness": 1.0, "Coat Weight": 1.0,
        "Coat Roughness": 0.0, "Coat IOR": COAT_IOR, "Coat Tint": TINT})
    bs.add_plane((0.0, 0.0, 0.0), 40.0, material=mat)
    bpy.context.view_layer.update()
    return scene


def coat_furnace_closed_form() -> np.ndarray:
    """F(μ, η) + (1 − F)·tint^(1/cos θ_t): the coat's Fresnel reflection of the world, and the white base's (all of
    the world, attenuated by the coat's Fresnel and its tint along the refracted path)."""
    from tracer.shading import bsdf

    mu = math.cos(VIEW)
    f = float(bsdf.fresnel_dielectric(mu, COAT_IOR))
    cos_t = math.sqrt(1.0 - (1.0 - mu * mu) / COAT_IOR ** 2)
    return f + (1.0 - f) * np.asarray(TINT) ** (1.0 / cos_t)


def test_a_coat_in_a_white_furnace_is_fresnel_over_a_tinted_base(bpy_module):
    ours, warnings = ours_render(coat_furnace_scene(), samples=2)
    assert not [w for w in warnings if "Coat" in w], warnings
    np.testing.assert_allclose(ours.mean(axis=(0, 1)), coat_furnace_closed_form(), rtol=0.01)


@pytest.mark.cycles
def test_cycles_coat_in_a_white_furnace_is_the_same_closed_form(bpy_module):
    ref = H.cycles_render("coat_furnace", coat_furnace_scene, source_of(coat_furnace_scene), dict(depth=8, samples=256))
    np.testing.assert_allclose(ref.mean(axis=(0, 1)), coat_furnace_closed_form(), rtol=0.01)


def rough_coat_furnace_scene(base: float, size=(16, 16)):
    """The furnace above with a rough coat (roughness 0.6, IOR 1.5, untinted) over a grey ``base`` Lambert, seen at
    57° from the normal."""
    import bpy

    scene = bs.reset(size)
    d, view = 5.0, 1.0
    bs.add_camera((0.0, -d * math.sin(view), d * math.cos(view)), target=(0.0, 0.0, 0.0), ortho_scale=1.0)
    bs.set_world((1.0, 1.0, 1.0))
    mat, p = bs.shader_material("RoughCoat", "ShaderNodeBsdfPrincipled", **{
        "Base Color": (base, base, base), "Specular IOR Level": 0.0, "Roughness": 1.0, "Coat Weight": 1.0,
        "Coat Roughness": 0.6, "Coat IOR": 1.5})
    bs.add_plane((0.0, 0.0, 0.0), 40.0, material=mat)
    bpy.context.view_layer.update()
    return scene


@pytest.mark.cycles
@pytest.mark.parametrize("base", [0.0, 1.0])
def test_a_rough_coat_in_a_white_furnace_matches_cycles(bpy_module, base):
    """What a rough coat takes from the layers below is its single-scattering albedo E·F (Cycles' coat is GGX, not
    multiscatter): Cycles 0.998 over white at 57°; the smooth Fresnel gave 0.976. Over black the coat's own
    reflection: 0.052 in Cycles, 0.054 in ours (our coat lobe is multiscatter GGX)."""
    ref = H.cycles_render(f"rough_coat_furnace_{base}", lambda: rough_coat_furnace_scene(base),
                          source_of(rough_coat_furnace_scene) + str(base), dict(depth=8, samples=256))
    ours, _warnings = ours_render(rough_coat_furnace_scene(base), samples=2)
    np.testing.assert_allclose(ours.mean(axis=(0, 1)), ref.mean(axis=(0, 1)), atol=0.005)


def layered_sphere_scene(kind: str, size=(72, 72)):
    """A smooth UV sphere over a grey floor, a point light from the front-left and a rim light from behind, a dim
    grey world. ``kind``: "coat" (dark red rough dielectric, Coat Weight 1, Coat Roughness 0.1), "coat_tint"
    (a grey dielectric, Coat Weight 0.8, Coat Tint orange, Coat IOR 1.8), "aniso" (a metal of roughness 0.4,
    Anisotropic 0.9 about the default tangent), "aniso_rot" (the same about the UV tangent turned a quarter;
    "aniso_rot8" an eighth, which tells the turn's sense),
    "glossy_aniso" (a Glossy BSDF, roughness 0.35, Anisotropy 0.7)."""
    import bpy

    scene = bs.reset(size)
    bs.add_camera((0.0, -5.0, 0.8), target=(0.0, 0.0, 0.0), lens=50.0)
    bs.add_point_light((-3.0, -3.0, 3.0), power=600.0)
    bs.add_point_light((1.5, 4.0, 2.0), power=900.0, name="Rim")
    bs.set_world((0.05, 0.05, 0.05))
    bs.add_plane((0.0, 0.0, -1.0), 10.0, material=bs.principled_material("Floor", base_color=(0.4, 0.4, 0.4),
                                                                          specular=0.0))
    mat, nt, out = bs.node_material(kind)
    if kind == "glossy_aniso":
        g = nt.nodes.new("ShaderNodeBsdfGlossy")
        g.inputs["Color"].default_value = (0.9, 0.8, 0.6, 1.0)
        g.inputs["Roughness"].default_value = 0.35
        g.inputs["Anisotropy"].default_value = 0.7
        nt.links.new(g.outputs[0], out.inputs["Surface"])
    else:
        p = nt.nodes.new("ShaderNodeBsdfPrincipled")
        if kind == "coat":
            p.inputs["Base Color"].default_value = (0.5, 0.05, 0.05, 1.0)
            p.inputs["Roughness"].default_value = 0.6
            p.inputs["Coat Weight"].default_value = 1.0
            p.inputs["Coat Roughness"].default_value = 0.1
        elif kind == "coat_tint":
            p.inputs["Base Color"].default_value = (0.7, 0.7, 0.7, 1.0)
            p.inputs["Roughness"].default_value = 0.5
            p.inputs["Coat Weight"].default_value = 0.8
            p.inputs["Coat IOR"].default_value = 1.8
            p.inputs["Coat Roughness"].default_value = 0.05
            p.inputs["Coat Tint"].default_value = (1.0, 0.6, 0.2, 1.0)
        else:
            p.inputs["Base Color"].default_value = (0.9, 0.9, 0.92, 1.0)
            p.inputs["Metallic"].default_value = 1.0
            p.inputs["Roughness"].default_value = 0.4
            p.inputs["Anisotropic"].default_value = 0.9
            if kind in ("aniso_rot", "aniso_rot8"):
                p.inputs["Anisotropic Rotation"].default_value = 0.25 if kind == "aniso_rot" else 0.125
                t = nt.nodes.new("ShaderNodeTangent")
                t.direction_type = "UV_MAP"
                nt.links.new(t.outputs[0], p.inputs["Tangent"])
        nt.links.new(p.outputs[0], out.inputs["Surface"])
    bs.add_uv_sphere((0.0, 0.0, 0.0), 1.0, segments=96, rings=48, material=mat)
    bpy.context.view_layer.update()
    return scene


#: PSNR bars of the spheres (measured 2026-12-05: coat 41.9 dB, coat_tint 39.9 dB; aniso 31.9, aniso_rot 31.3,
#: aniso_rot8 31.5 (17.9 with the turn's sense reversed), glossy_aniso 30.2 dB, each 21.1-21.7 dB rendered isotropic: the rest is the floor seen in the roughness-0.4 metal,
#: a sharp mirror image in ours, a blurred one in Cycles). The MAE bar is loose: the
#: point lights' highlights in the smooth coats are one or two pixels of radiance 20-260, which 4 samples per pixel
#: land differently from Cycles' 256 (they are most of the MAE; the PSNR on clipped sRGB does not see them).
SPHERE_BARS = {"coat": 39.0, "coat_tint": 37.5, "aniso": 30.5, "aniso_rot": 30.0, "aniso_rot8": 30.0, "glossy_aniso": 29.0}
SPHERE_MAE = 0.08


@pytest.mark.cycles
@pytest.mark.parametrize("kind", list(SPHERE_BARS))
def test_coat_and_anisotropy_spheres_match_cycles(bpy_module, tmp_path, kind):
    ref = H.cycles_render(f"layered_{kind}", lambda: layered_sphere_scene(kind),
                          source_of(layered_sphere_scene, bs.node_material) + kind, dict(depth=2, samples=256))
    ours, warnings = ours_render(layered_sphere_scene(kind))
    m = H.metrics(ours, ref)
    print(f"[cycles] layered_{kind}: {m['psnr']:.2f} dB, mean ours/Cycles {m['mean_ours'] / m['mean_cycles']:.3f}")
    assert not [w for w in warnings if "Coat" in w or "anisotrop" in w.lower()], warnings
    H.check_images({"name": f"layered_{kind}"}, ours, ref, tmp_path, min_psnr=SPHERE_BARS[kind], max_mae=SPHERE_MAE)


# ---------------------------------------------------------------------------------------------------- tangents
def tangent_probe_scene(size=(96, 48)):
    """Four UV spheres (one turned and stretched) emitting ½·Tangent + ½ of a Tangent node, Radial about X, Y and
    Z, and of Geometry ▸ Tangent (Cycles' default tangent of an anisotropic BSDF): the tangent frames the anisotropic
    lobes turn about, seen directly."""
    import bpy

    scene = bs.reset(size)
    bs.add_camera((0.0, -9.0, 0.0), target=(0.0, 0.0, 0.0), lens=50.0)
    bs.set_world((0.0, 0.0, 0.0))
    for k, what in enumerate(("X", "Y", "Z", "GEOMETRY")):
        mat, nt, out = bs.node_material(f"tangent_{what}")
        if what == "GEOMETRY":
            src = nt.nodes.new("ShaderNodeNewGeometry").outputs["Tangent"]
        else:
            tn = nt.nodes.new("ShaderNodeTangent")
            tn.direction_type = "RADIAL"
            tn.axis = what
            src = tn.outputs["Tangent"]
        vm = nt.nodes.new("ShaderNodeVectorMath")
        vm.operation = "MULTIPLY_ADD"
        vm.inputs[1].default_value = (0.5, 0.5, 0.5)
        vm.inputs[2].default_value = (0.5, 0.5, 0.5)
        em = nt.nodes.new("ShaderNodeEmission")
        nt.links.new(src, vm.inputs[0])
        nt.links.new(vm.outputs[0], em.inputs["Color"])
        nt.links.new(em.outputs[0], out.inputs["Surface"])
        ob = bs.add_uv_sphere((-3.3 + 2.2 * k, 0.0, 0.0), 0.9, segments=64, rings=32, material=mat)
        if k == 1:
            ob.rotation_euler = (0.4, 0.3, 0.7)
            ob.scale = (1.0, 0.7, 1.2)
    bpy.context.view_layer.update()
    return scene


@pytest.mark.cycles
def test_radial_tangents_match_cycles(bpy_module, tmp_path):
    """The Tangent node's Radial X / Y / Z and the Geometry node's Tangent (before: the UV tangent, with a warning
    for Radial)."""
    ref = H.cycles_render("tangent_probes", tangent_probe_scene, source_of(tangent_probe_scene, bs.node_material),
                          dict(depth=0, samples=16))
    ours, warnings = ours_render(tangent_probe_scene(), depth=0)
    assert not warnings, warnings
    H.check_images({"name": "tangent_probes"}, ours, ref, tmp_path, min_psnr=35.0, max_mae=0.01)

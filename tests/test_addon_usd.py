"""The same Blender scene two ways: through the add-on (depsgraph -> tracer.Scene) and through Blender's USD
exporter + usd_io (bpy.ops.wm.usd_export -> usd_io.reader.load_stage). For the features both paths carry
(meshes with smooth normals, base colour, metallic mirror, roughness, emission, a point light, the perspective
camera, the world colour) the pictures must agree.

Tolerance: PIXEL_AGREEMENT of the pixels within PIXEL_TOLERANCE (linear RGB, max over channels); the coverage of
the object-id AOV within COVERAGE_TOLERANCE. The paths may differ legitimately only by float32 round-off of the
exported transforms (USD stores translate/rotateXYZ/scale), which can move a silhouette edge across a sample
position; measured: max |Δ| = 0 on this scene (every pixel identical). The materials use Specular IOR Level 0.5,
which Blender's exporter drops and both front ends then map to F0 = 0.04. Blender's exporter drops Transmission,
so glass is not compared.
"""

from __future__ import annotations

import numpy as np
import pytest

from blender_kit import scene as bs

import bpy  # noqa: E402  (the test extra installs bpy; a missing bpy must fail, not skip)

from addon import export  # noqa: E402

PIXEL_TOLERANCE = 2e-3
PIXEL_AGREEMENT = 0.995
COVERAGE_TOLERANCE = 0.005


def build_scene():
    scene = bs.reset((96, 72))
    bs.add_camera((1.0, -7.0, 2.5), target=(0, 0, 0.8), lens=40)
    bs.add_point_light((3, -4, 6), power=3000)
    bs.add_plane(size=12, material=bs.principled_material("Ground", base_color=(0.6, 0.5, 0.3)))
    bs.add_uv_sphere((-1.1, 0.5, 1.0), 1.0, material=bs.principled_material("Mirror", base_color=(0.9, 0.9, 0.9),
                                                                            metallic=1.0, roughness=0.0))
    bs.add_uv_sphere((1.2, -0.3, 0.7), 0.7, material=bs.principled_material("Red", base_color=(0.7, 0.1, 0.1),
                                                                            roughness=0.4))
    bs.add_cube((0.3, 2.0, 0.5), 1.0, material=bs.principled_material("Glow", base_color=(0.0, 0.0, 0.0),
                                                                      emission_color=(0.2, 0.8, 0.3),
                                                                      emission_strength=2.0))
    bs.set_world((0.05, 0.08, 0.12), strength=1.0)
    return scene


def test_addon_and_usd_export_give_the_same_pixels(bpy_module, tmp_path):
    from tracer import RenderSettings
    from tracer import render
    from usd_io.reader import load_stage

    scene = build_scene()
    ours, warnings = export.scene_from_depsgraph(bpy.context.evaluated_depsgraph_get())
    assert not warnings
    usd_path = str(tmp_path / "scene.usda")
    bpy.ops.wm.usd_export(filepath=usd_path)
    theirs, info = load_stage(usd_path, width=96, height=72)
    settings = RenderSettings(width=96, height=72, samples=2, aovs=("objectid",))
    a, b = render(ours, settings), render(theirs, settings)
    diff = np.abs(a.rgb - b.rgb).max(axis=-1)
    print(f"usd roundtrip: max |Δ| {diff.max():.4f}, mean {diff.mean():.5f}, "
          f"within {PIXEL_TOLERANCE}: {(diff <= PIXEL_TOLERANCE).mean():.4f}; warnings {info.warnings}")
    assert (diff <= PIXEL_TOLERANCE).mean() >= PIXEL_AGREEMENT
    assert a.stats["rays"]["reflection"] > 0 and b.stats["rays"]["reflection"] > 0
    assert a.stats["rays"]["shadow"] > 0 and a.rgb.mean() > 0.02  # a lit picture, not two black ones
    assert abs((a.aovs["objectid"] >= 0).mean() - (b.aovs["objectid"] >= 0).mean()) <= COVERAGE_TOLERANCE

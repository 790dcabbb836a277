"""Transparent shadows and cut-outs tested inside Embree's traversal (tracer/accel/alpha.py) against closed forms and
against the tracer's own round-by-round loop (the path it replaces, still used where the filter cannot be).

Scenes: a grey floor (Lambert only: Specular 0) under horizontal cards, lit by a sun straight down (irradiance E,
no sky, no ambient), seen from the side below the cards, so the eye rays never cross a card and each floor pixel is
base/π · E · (what the sun's shadow ray lets through). Cards: constant alpha a (each lets 1 − a through), or an
alpha texture cut in two halves (0 on the left, 1 on the right: the left lets everything through)."""

from __future__ import annotations

import numpy as np
import pytest

import tracer
import tracer.accel.accelerator
from tracer.accel import alpha
from tracer.integrator import wavefront as integrator
from tracer.camera import Camera
from tracer.lights.emitters import DistantLight

E = 3.0  # the sun's irradiance, W/m²
BASE = 0.5  # the floor's albedo
SIZE = (48, 32)


def card_quad(z, half=2.0):
    v = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]], np.float32)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    return v, np.array([[0, 1, 2], [0, 2, 3]], np.int32), uv


def card_scene(alphas=(0.5, 0.5, 0.5), *, textured=False, instanced=False, extra_opaque=False):
    """Cards at heights 1, 2, 3, … above a 12 m floor, each with alpha ``alphas[i]`` (textured: the left half cut
    away by an alpha texture, the right half opaque, times the alpha)."""
    b = tracer.SceneBuilder()
    floor = b.add_material("floor", diffuse=(BASE,) * 3, specular=0.0, roughness=1.0)
    fv = np.array([[-6, -6, 0], [6, -6, 0], [6, 6, 0], [-6, 6, 0]], np.float32)
    b.add_mesh(fv, np.array([[0, 1, 2], [0, 2, 3]], np.int32), material=floor, name="floor")
    tex = None
    if textured:
        img = np.ones((4, 8, 4), np.float32)
        img[:, :4, 3] = 0.0  # left half cut away (texel centres: bilinear blends only across the middle)
        tex = b.add_texture(tracer.Texture(image=img, wrap_s="clamp", wrap_t="clamp"))
    mats = []
    for i, a in enumerate(alphas):
        fields = dict(diffuse=(0.2, 0.6, 0.2), specular=0.0, alpha=float(a))
        if tex is not None:
            fields.update(alpha_texture=tex, alpha_channel=3)
        mats.append(b.add_material(f"card{i}", **fields))
    if instanced:
        v, f, uv = card_quad(0.0)
        proto = b.add_mesh(v, f, material=mats[0], name="card", uvs=uv)
        xf = np.repeat(np.eye(4)[None], len(alphas), 0)
        xf[:, 2, 3] = np.arange(1, len(alphas) + 1)
        b.add_instances(proto, xf, materials=np.array(mats, np.int32))
    else:
        for i, m in enumerate(mats):
            v, f, uv = card_quad(float(i + 1))
            b.add_mesh(v, f, material=m, name=f"card{i}", uvs=uv)
    if extra_opaque:  # an opaque slab high above one corner: blocks whatever the cards let through there
        v, f, uv = card_quad(8.0, half=0.8)
        b.add_mesh(v + np.float32([1.5, 1.5, 0]), f, material=floor, name="slab")
    b.add_light(DistantLight(direction=(0, 0, -1), irradiance=(E,) * 3))
    b.camera = Camera.look_at((0, -9, 0.6), (0, 0, 0), up=(0, 0, 1), focal_length=35)
    return b.build()


def render(scene, monkeypatch, filtered, **kw):
    monkeypatch.setattr(alpha, "ENABLED", filtered)
    s = tracer.RenderSettings(width=SIZE[0], height=SIZE[1], samples=1, max_depth=1, sky_samples=0, threads=1, **kw)
    return tracer.render(scene, s)


def lit(n_passing):
    """The floor's radiance under the sun through cards that let ``n_passing`` through (a factor)."""
    return BASE / np.pi * E * n_passing


def floor_row(image):
    """The picture's middle row, red channel (the floor seen under the cards, from x = -4 to 4 m or so)."""
    return image.rgba[SIZE[1] // 2, :, 0]


def both(scene, monkeypatch, **kw):
    """The render with the filter and with the round-by-round loop; the first must not have run the loop."""
    calls = []
    loop = integrator.Integrator._through_shadows
    monkeypatch.setattr(integrator.Integrator, "_through_shadows",
                        lambda self, *a, **k: calls.append(1) or loop(self, *a, **k))
    filtered = render(scene, monkeypatch, True, **kw)
    assert not calls, "the filter was not used"
    rounds = render(scene, monkeypatch, False, **kw)
    assert calls, "the loop was not used"
    return filtered, rounds


@pytest.mark.parametrize("instanced", [False, True])
def test_partial_cards_let_the_product_through(monkeypatch, instanced):
    """Three cards of alpha 0.3, 0.5, 0.8 over the floor: the sun passes 0.7·0.5·0.2 of its light, the same
    through the filter and the loop, flat or instanced."""
    scene = card_scene((0.3, 0.5, 0.8), instanced=instanced)
    filtered, rounds = both(scene, monkeypatch)
    row = floor_row(filtered)
    under = row[SIZE[0] // 2 - 4:SIZE[0] // 2 + 4]
    np.testing.assert_allclose(under, lit(0.7 * 0.5 * 0.2), rtol=1e-4)
    np.testing.assert_allclose(row[0], lit(1.0), rtol=1e-4)  # beside the cards: the full sun
    np.testing.assert_allclose(filtered.rgba, rounds.rgba, atol=1e-6)


@pytest.mark.parametrize("instanced", [False, True])
def test_cut_out_halves_and_an_opaque_blocker(monkeypatch, instanced):
    """Alpha-textured cards (left half cut away, right half alpha 0.5): under the left half the floor gets the
    whole sun, under the right half 0.5³ of it, and nothing under the opaque slab above one corner."""
    scene = card_scene((1.0, 0.5, 0.5), textured=True, instanced=instanced, extra_opaque=True)
    filtered, rounds = both(scene, monkeypatch)
    row = floor_row(filtered)
    c = SIZE[0] // 2
    np.testing.assert_allclose(row[c - 8:c - 3], lit(1.0), rtol=1e-4)
    np.testing.assert_allclose(row[c + 5:c + 7], 0.0, atol=1e-6)  # card 1 (alpha 1 on the right) is opaque
    np.testing.assert_allclose(filtered.rgba, rounds.rgba, atol=1e-6)


def test_more_surfaces_than_max_transparent_block(monkeypatch):
    """Three cards of alpha 0.5: with max_transparent 2 the third blocks the sun (as Cycles' transparent bounce
    limit does), with 3 the floor gets 0.5³."""
    scene = card_scene((0.5, 0.5, 0.5))
    c = SIZE[0] // 2
    for max_t, want in ((2, 0.0), (3, lit(0.125))):
        filtered, rounds = both(scene, monkeypatch, max_transparent=max_t)
        np.testing.assert_allclose(floor_row(filtered)[c - 4:c + 4], want, rtol=1e-4, atol=1e-7)
        np.testing.assert_allclose(filtered.rgba, rounds.rgba, atol=1e-6)


def test_opaque_scenes_keep_their_geometry_off_the_filter():
    """Only objects with a see-through material enable the filter (the rest stay on plain rtcOccluded)."""
    scene = card_scene((1.0, 0.5))
    acc = tracer.accel.accelerator.Accelerator(scene)
    names = [scene.object_names[i] for i in acc.filtered]
    assert names == ["card1"], names

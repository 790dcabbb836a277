"""Adaptive sampling (issue #33): Cycles' noise threshold over a pixel's N×N budget, spent in rounds.

What is proven here: a flat lit floor takes fewer samples than a soft shadow's edge (the ``sample_count`` AOV); the
pixels that take more than the first round come in whole 3×3 blocks (the dilation); threshold 0 and a budget every
pixel spends are the fixed-count image bit for bit (the film divides each pixel by its own count); the pixels are the
same for 1 and 2 threads, for tiles rendered one by one in reverse, and whichever round traced a sample; the adaptive
image is as close to a converged reference as the full-budget one (PSNR); explain traces the samples the render
took; and the sample order's prefixes are stratified.
"""

from __future__ import annotations

import numpy as np
import pytest

import tracer
from tracer import PointLight, RenderSettings
from tracer.integrator import adaptive
from tracer.sampling import progressive_order, sample_class_a

from tracer_scenes import lit_sphere_on_floor

#: N = 8: a 64-sample budget, enough for rounds (first 8, then steps of 4); one light sample per eye sample, so a
#: soft shadow's edge is noisy and the lit floor is not.
BASE = RenderSettings(width=64, height=48, samples=8, light_samples=1, sky_samples=0, threads=1, tile_size=32)
ADAPTIVE = BASE.with_(adaptive_threshold=0.01, adaptive_min_samples=8)
#: The full-budget and the adaptive image against a 64 × 16 light samples reference: the adaptive one may lose
#: this much PSNR (measured: 0.02 dB, 49.41 against 49.44) while taking less than MAX_SHARE of the budget
#: (measured: 0.21).
PSNR_LOSS_DB = 1.0
MAX_SHARE = 0.5


@pytest.fixture(scope="module")
def scene():
    b = lit_sphere_on_floor()
    b.lights[0] = PointLight(position=(3.0, -2.0, 6.0), intensity=(50.0,) * 3, radius=1.0)  # a soft shadow
    return b.build()


@pytest.fixture(scope="module")
def renders(scene):
    aovs = ("sample_count", "objectid")
    with tracer.Session(scene) as s:
        return {"adaptive": s.render(ADAPTIVE.with_(aovs=aovs)), "full": s.render(BASE.with_(aovs=aovs)),
                "reference": s.render(BASE.with_(light_samples=16, aovs=aovs)),
                "unshadowed": s.render(BASE.with_(light_samples=16, shadows=False, aovs=aovs))}


def psnr(a, b):
    return 10 * np.log10(1.0 / np.mean((a - b) ** 2))


def test_flat_lit_floor_takes_fewer_samples_than_a_soft_shadow_edge(renders):
    ref, free = renders["reference"], renders["unshadowed"]
    floor = ref.aovs["objectid"] == 0
    inner = floor.copy()  # floor pixels whose 3×3 neighbours are floor too (no silhouette, no horizon)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            inner &= np.roll(floor, (dy, dx), axis=(0, 1))
    inner[[0, -1], :] = inner[:, [0, -1]] = False
    lit = free.rgb[..., 0]
    ratio = np.where(lit > 0, ref.rgb[..., 0] / np.maximum(lit, 1e-12), 0)  # the light's visible fraction
    edge = inner & (ratio > 0.15) & (ratio < 0.85)
    flat = inner & (ratio > 0.995)
    for dy in (-2, -1, 0, 1, 2):  # and nothing but lit floor within two pixels
        for dx in (-2, -1, 0, 1, 2):
            flat &= np.roll(inner & (ratio > 0.995), (dy, dx), axis=(0, 1))
    assert edge.sum() >= 20 and flat.sum() >= 200, (edge.sum(), flat.sum())
    count = renders["adaptive"].aovs["sample_count"]
    assert count.min() >= 8 and count.max() <= 64
    assert count[flat].mean() < 0.5 * count[edge].mean(), (count[flat].mean(), count[edge].mean())
    assert count[flat].mean() < 16 and count[edge].mean() > 32
    assert (renders["full"].aovs["sample_count"] == 64).all()


def test_adaptive_image_is_as_close_to_the_reference_as_the_full_budget(renders):
    ref = renders["reference"].rgb
    full, ad = renders["full"], renders["adaptive"]
    share = ad.aovs["sample_count"].mean() / 64
    assert ad.stats["samples_per_pixel"] == pytest.approx(ad.aovs["sample_count"].mean())
    assert share < MAX_SHARE, share
    assert psnr(ad.rgb, ref) > psnr(full.rgb, ref) - PSNR_LOSS_DB, (psnr(ad.rgb, ref), psnr(full.rgb, ref))
    assert psnr(ad.rgb, full.rgb) > 40
    assert np.array_equal(ad.rgba[..., 3], full.rgba[..., 3])  # alpha divided by each pixel's own count too


def test_pixels_beyond_the_first_round_come_in_whole_3x3_blocks(renders):
    """Each pixel that took another round was, or had a neighbour that was, not converged (Cycles' dilation): the
    set is its own morphological opening by a 3×3 square, inside each tile."""
    count = renders["adaptive"].aovs["sample_count"]
    first = adaptive.schedule(ADAPTIVE).first
    more = count > first
    assert 0 < more.sum() < more.size
    ts = ADAPTIVE.tile_size
    for y0 in range(0, count.shape[0], ts):
        for x0 in range(0, count.shape[1], ts):
            m = more[y0:y0 + ts, x0:x0 + ts]
            pad = np.pad(m, 1, constant_values=True)  # outside the tile does not hold a pixel back
            core = np.ones_like(m)
            for dy in (0, 1, 2):
                for dx in (0, 1, 2):
                    core &= pad[dy:dy + m.shape[0], dx:dx + m.shape[1]]
            assert np.array_equal(adaptive.dilate(core), m), (x0, y0)


def test_dilation_is_cycles_3x3_box_inside_the_tile():
    one = np.zeros((5, 6), bool)
    one[2, 3] = True
    want = np.zeros((5, 6), bool)
    want[1:4, 2:5] = True
    assert np.array_equal(adaptive.dilate(one), want)
    corner = np.zeros((4, 4), bool)
    corner[0, 0] = True
    assert adaptive.dilate(corner).sum() == 4  # clipped at the tile's edge
    sched = adaptive.schedule(ADAPTIVE)
    count = np.full(20, 8)
    total = np.full((20, 3), 0.5 * 8)  # every pixel's mean 0.5, over all its samples and over class A alone
    half = np.full((20, 3), 0.5 * 4)
    half[7] = 0.9 * 4  # but pixel 7 of a 4×5 tile (row 1, column 2): its halves disagree
    going = adaptive.still_sampling(sched, total, count, half, count // 2, (4, 5)).reshape(4, 5)
    assert going[0:3, 1:4].all() and going.sum() == 9
    spent = adaptive.still_sampling(sched, total * 8, np.full(20, 64), half * 8, np.full(20, 32), (4, 5))
    assert not spent.any()  # the budget is spent: nothing samples on


def test_threshold_zero_and_a_full_budget_are_the_fixed_count_image_bit_for_bit(scene):
    aovs = ("sample_count", "depth", "normal", "albedo", "objectid", "direct", "reflection", "transmission",
            "raydepth")
    small = BASE.with_(width=40, height=30, samples=4, tile_size=16, aovs=aovs)
    with tracer.Session(scene) as s:
        fixed = s.render(small)
        off = s.render(small.with_(adaptive_threshold=0.0, adaptive_min_samples=8))
        every = s.render(small.with_(adaptive_threshold=0.01, adaptive_min_samples=16))  # min = the budget
    assert not adaptive.enabled(small) and adaptive.enabled(small.with_(adaptive_threshold=0.01))
    for other in (off, every):
        assert np.array_equal(other.rgba, fixed.rgba)
        for name in aovs:
            assert np.array_equal(other.aovs[name], fixed.aovs[name]), name
    assert (every.aovs["sample_count"] == 16).all()


def test_same_pixels_for_any_thread_count_tile_order_and_round(scene):
    st = ADAPTIVE.with_(width=48, height=36, tile_size=16, aovs=("sample_count",))
    with tracer.Session(scene) as s:
        one = s.render(st.with_(threads=1))
        two = s.render(st.with_(threads=2))
        assert np.array_equal(one.rgba, two.rgba)
        assert np.array_equal(one.aovs["sample_count"], two.aovs["sample_count"])
        for tile in reversed(tracer.tiles_of(st)):  # tile by tile, last first (the farm's tasks)
            x0, y0, x1, y1 = tile
            part = tracer.render_tile(s, st, tile)
            assert np.array_equal(part.rgba, one.rgba[y0:y1, x0:x1])
        # Other rounds (a later first check, so other pixels stop elsewhere): a pixel that took as many samples
        # took the same ones, whichever round traced them.
        other = s.render(st.with_(adaptive_min_samples=20))
    same = other.aovs["sample_count"] == one.aovs["sample_count"]
    assert same.sum() > 100
    assert np.array_equal(other.rgba[same], one.rgba[same])


def test_explain_traces_the_samples_the_adaptive_render_took(scene):
    st = ADAPTIVE.with_(width=32, height=24, tile_size=16, aovs=("sample_count",))
    image = tracer.render(scene, st)
    count = image.aovs["sample_count"]
    lit = image.rgba[..., 0] > 0.005
    for pick in (count == count.max(), count == count.min()):
        y, x = np.argwhere(pick & lit)[0]
        ex = tracer.explain_pixel(scene, st, int(x), int(y))
        assert len(ex.samples) == count[y, x]
        assert ex.color == pytest.approx(image.rgba[y, x, :3], rel=1e-5, abs=1e-7)


def test_progressive_order_prefixes_are_stratified():
    for n in (1, 2, 3, 4, 5, 6, 8, 16):
        order = progressive_order(n)
        assert sorted(order) == list(range(n * n)), n
    for n in (4, 8, 16):  # a power of two: the first 4^j strata cover a 2^j × 2^j grid, one each
        order = progressive_order(n)
        j = 1
        while (1 << j) <= n:
            q = 1 << j
            cells = {((s // n) * q // n, (s % n) * q // n) for s in order[:q * q]}
            assert len(cells) == q * q, (n, q)
            j += 1
    a = sample_class_a(np.arange(64))
    assert all(a[i:i + 4].sum() == 2 for i in range(0, 64, 4))  # two of each class in every block of 4


def test_schedule_follows_cycles_min_samples():
    assert adaptive.min_samples(RenderSettings(samples=16, adaptive_threshold=0.01)) == 64
    assert adaptive.min_samples(RenderSettings(samples=16, adaptive_threshold=0.1)) == 32
    assert adaptive.min_samples(RenderSettings(samples=4, adaptive_threshold=0.01)) == 16  # at most the budget
    assert adaptive.min_samples(RenderSettings(samples=8, adaptive_threshold=0.01, adaptive_min_samples=2)) == 4
    sched = adaptive.schedule(RenderSettings(samples=16, adaptive_threshold=0.1))
    assert (sched.budget, sched.first, sched.step) == (256, 32, 16)


@pytest.mark.parametrize("transparent", [True, False])
def test_shadow_catcher_means_are_over_the_samples_taken(scene, transparent):
    """Cycles' Combined and Shadow Catcher pass (tracer.integrator.compose) average each pixel's samples: with
    adaptive sampling, over the slots it traced. A budget every pixel spends gives the fixed-count pixels (to
    float rounding: the masked mean sums in another order); fewer samples, pixels close to them."""
    st = BASE.with_(width=40, height=30, samples=4, tile_size=16, transparent=transparent, aovs=("shadow_catcher",))
    scene.object_shadow_catcher = np.array([True, False])  # the floor catches the ball's soft shadow
    try:
        with tracer.Session(scene) as s:
            fixed = s.render(st)
            every = s.render(st.with_(adaptive_threshold=0.01, adaptive_min_samples=16))
            fewer = s.render(st.with_(adaptive_threshold=0.05, adaptive_min_samples=4, aovs=("shadow_catcher",
                                                                                          "sample_count")))
    finally:
        scene.object_shadow_catcher = None
    np.testing.assert_allclose(every.rgba, fixed.rgba, atol=1e-6)
    np.testing.assert_allclose(every.aovs["shadow_catcher"], fixed.aovs["shadow_catcher"], atol=1e-6)
    assert fewer.aovs["sample_count"].min() == 4 and fewer.aovs["sample_count"].mean() < 12
    catcher = fewer.aovs["shadow_catcher"]
    assert catcher.min() >= -1e-4 and catcher.max() <= 1 + 1e-4  # (a ratio: float rounding around 1)
    assert psnr(fewer.rgba, fixed.rgba) > 35 and psnr(catcher, fixed.aovs["shadow_catcher"]) > 30


def test_denoising_guides_are_means_over_the_samples_taken(scene):
    """The denoiser's guides (Cycles' Denoising Albedo / Normal) average each pixel's own samples, and a denoised
    adaptive render is closer to the converged reference than the noisy one."""
    from tracer import denoise

    guides = ("denoising_albedo", "denoising_normal", "sample_count")
    st = BASE.with_(width=40, height=30, samples=4, tile_size=16, aovs=guides)
    with tracer.Session(scene) as s:
        fixed = s.render(st)
        fewer = s.render(st.with_(adaptive_threshold=0.05, adaptive_min_samples=4))
        try:
            denoise.check()
        except denoise.DenoiseUnavailable:
            denoised = None
        else:
            denoised = True
            # ≈ 4 samples a pixel, at 96×72 (at 40×30 OIDN's own error outweighs the noise it removes, as it does
            # near 48 dB: fixed counts alike)
            noisy = st.with_(width=96, height=72, tile_size=32, samples=3, adaptive_threshold=0.2,
                             adaptive_min_samples=4, aovs=())
            reference = s.render(noisy.with_(samples=8, light_samples=16, adaptive_threshold=0.0))
            pair = s.render(noisy), s.render(noisy.with_(denoise=True))
    assert fewer.aovs["sample_count"].mean() < 12
    for name in guides[:2]:
        assert np.isfinite(fewer.aovs[name]).all()
        assert psnr(fewer.aovs[name], fixed.aovs[name]) > 30, name
    if denoised is not None:  # measured: 45.26 dB noisy, 45.43 denoised
        assert psnr(pair[1].rgb, reference.rgb) > psnr(pair[0].rgb, reference.rgb), (psnr(pair[1].rgb, reference.rgb),
                                                                                     psnr(pair[0].rgb, reference.rgb))

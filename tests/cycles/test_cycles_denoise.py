"""The denoiser's guides against Cycles' own: the Denoising Albedo and Denoising Normal passes (view layer >
Passes > Denoising Data) of scenes whose first non-specular hit lies behind mirrors and glass, through the
tracer's API (the scene built from the numbers) and through F12 of the add-on (Blender's passes, the Combined
denoised), issue #33.

Cycles takes one random ray per bounce, so its passes are noisy where the chain splits (glass); ours are their
expectation (tracer/integrator/guides.py). The bars are in cycles_thresholds.py."""

import os

import numpy as np
import pytest

import cycles_harness as H
import cycles_thresholds as T
from cycles_scenes import IMAGE_SCENES, variant

pytestmark = pytest.mark.cycles

#: Small versions of scenes where the guides must follow the specular chain: mirror and glass balls under a sky
#: (the world seen in the mirror is albedo too), a mirror wall and glass at depth 4, a glass sphere before a
#: checker wall, rough Principled lobes (the 25 % rule), an emissive panel (emission is albedo).
GUIDE_SCENES = ("whitted_1980", "interreflection_d4", "glass_sphere", "lobe_mixed", "emission_light")


def _desc(name):
    return variant(IMAGE_SCENES[name], width=96, height=72, samples=64)


def _normal_psnr(a, b) -> float:
    """PSNR of two normal images over their range [-1, 1] (peak-to-peak 2)."""
    mse = float(np.mean((np.asarray(a, np.float64) - b) ** 2))
    return float("inf") if mse == 0 else 10 * np.log10(4.0 / mse)


def _check(name, albedo, normal, ref, tmp_path, label):
    pa, pn = H.psnr_srgb(albedo, ref["albedo"]), _normal_psnr(normal, ref["normal"])
    print(f"[cycles] {name}{label}: Denoising Albedo {pa:.2f} dB (≥ {T.GUIDE_ALBEDO_PSNR_MIN}), "
          f"Denoising Normal {pn:.2f} dB (≥ {T.GUIDE_NORMAL_PSNR_MIN})")
    if pa < T.GUIDE_ALBEDO_PSNR_MIN or pn < T.GUIDE_NORMAL_PSNR_MIN:
        paths = H.save_comparison(str(tmp_path), f"{name}-albedo", albedo, ref["albedo"])
        paths += H.save_comparison(str(tmp_path), f"{name}-normal", normal * 0.5 + 0.5, ref["normal"] * 0.5 + 0.5)
        raise AssertionError(f"{name}{label}: albedo {pa:.2f} dB, normal {pn:.2f} dB; images: {', '.join(paths)}")


@pytest.mark.parametrize("name", GUIDE_SCENES)
def test_guides_match_cycles_denoising_passes(bpy_module, tmp_path, name):
    desc = _desc(name)
    ref = H.cycles_reference(desc, kind="denoising")
    ours = H.render_ours(desc, "direct", aovs=("denoising_albedo", "denoising_normal"))
    _check(name, ours.aovs["denoising_albedo"], ours.aovs["denoising_normal"], ref, tmp_path, "")


def test_f12_writes_the_denoising_passes_and_denoises_combined(bpy_module, tmp_path):
    """F12 with Render Properties > Denoise on and the view layer's Denoising Data: Blender's Denoising Albedo and
    Denoising Normal passes hold the guides (as Cycles' own), Combined is the denoised picture."""
    import addon
    from addon import engine

    desc = _desc("whitted_1980")
    ref = H.cycles_reference(desc, kind="denoising")
    addon.register()
    try:
        sc = H.build_bpy(desc)
        sc.render.engine = "WHITTED"
        w = sc.whitted
        assert w.denoise, "Denoise is on for F12 by default, as in Cycles"
        w.samples, w.max_depth, w.sky_samples = desc["ours_samples"], desc["depth"], desc["sky_samples"]
        sc.view_layers[0].cycles.denoising_store_passes = True
        engine.WhittedRenderEngine.last_render = None
        path = os.path.join(str(tmp_path), "f12.exr")
        H.render_multilayer(sc, path)
        stats = engine.WhittedRenderEngine.last_render.stats
        chans = H._read_exr_channels(path)
        albedo = np.stack([H._channel(chans, f"Denoising Albedo.{c}") for c in "RGB"], axis=-1)
        normal = np.stack([H._channel(chans, f"Denoising Normal.{c}") for c in "XYZ"], axis=-1)
        combined = np.stack([H._channel(chans, f"Combined.{c}") for c in "RGB"], axis=-1)
        _check("whitted_1980", albedo, normal, ref, tmp_path, " [F12]")
        assert stats["denoise"]["oidn"].startswith("2.")
        w.denoise = False  # the same render without the filter: Combined differs, the passes do not
        H.render_multilayer(sc, path)
        chans = H._read_exr_channels(path)
        noisy = np.stack([H._channel(chans, f"Combined.{c}") for c in "RGB"], axis=-1)
        assert "denoise" not in engine.WhittedRenderEngine.last_render.stats
        assert not np.allclose(noisy, combined, atol=1e-4)
        np.testing.assert_array_equal(np.stack([H._channel(chans, f"Denoising Albedo.{c}") for c in "RGB"], -1),
                                      albedo)
        # both are close to Cycles' converged beauty (the filter changed noise, not the picture)
        beauty = H.cycles_reference(desc)["rgb"]
        assert H.psnr_srgb(combined, beauty) > H.psnr_srgb(noisy, beauty) - 1.0
    finally:
        bpy_module.ops.wm.read_factory_settings(use_empty=True)
        addon.unregister()

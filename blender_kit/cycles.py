"""Cycles as the reference renderer of a Whitted tracer: the settings that make it one (shared by the Cycles
comparison tests and the benchmarks)."""

from __future__ import annotations


def whitted_cycles_settings(scene, *, depth: int, samples: int, seed: int = 0) -> None:
    """Configure Cycles to reproduce a Whitted ray tracer. Every setting and why:

    - device CPU: the reference must not depend on a GPU; CI has none.
    - samples, adaptive sampling off, denoising off: a plain Monte-Carlo average, converged enough by ``samples``
      (measured per scene), not reshaped by a denoiser or an adaptive noise threshold.
    - fixed ``seed``: the same reference every time (and a stable cache).
    - max_bounces = depth, glossy and transmission bounces = depth: our ``max_depth`` counts secondary rays the same
      way (a mirror seen by the camera is one glossy bounce); diffuse bounces 0 and volume bounces 0: Whitted has no
      indirect diffuse light.
    - caustics (reflective, refractive) off and blur_glossy 0: no light paths through specular chains to lights
      (Whitted's shadow rays are blocked by glass) and no roughening of sharp reflections.
    - sample_clamp_direct/indirect 0: no clamping of bright samples (it would bias the mean).
    - light_sampling_threshold 0 and light tree off: every light is sampled however dim, without the tree's
      importance heuristics (several point lights must add up exactly).
    - pixel filter BOX with width 1: each pixel averages its own square, like our N×N stratified box filter.
    - view transform Standard, look None, exposure 0, gamma 1, film exposure 1, display sRGB: PNGs encode with the
      plain sRGB curve we use; EXRs stay scene-linear.
    The film's transparency is left as the scene has it (Film > Transparent is a user choice both engines honour).
    """
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = int(samples)
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.seed = int(seed)
    c.use_animated_seed = False
    c.max_bounces = int(depth)
    c.diffuse_bounces = 0
    c.glossy_bounces = int(depth)
    c.transmission_bounces = int(depth)
    c.volume_bounces = 0
    c.transparent_max_bounces = max(8, int(depth))
    c.caustics_reflective = False
    c.caustics_refractive = False
    c.blur_glossy = 0.0
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.light_sampling_threshold = 0.0
    c.use_light_tree = False
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    c.film_exposure = 1.0
    scene.render.use_persistent_data = False
    scene.display_settings.display_device = "sRGB"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0

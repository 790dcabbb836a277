"""Adaptive sampling, as Cycles' (``film_adaptive_sampling_convergence_check`` and its two dilation passes, and the
schedule of ``Integrator::get_adaptive_sampling``): which pixels of a tile take more samples after each round.

A pixel's budget stays the N×N samples of ``RenderSettings.samples``; with ``adaptive_threshold`` > 0 it takes
them in rounds, in the progressive order of :func:`tracer.sampling.progressive_order` (its sample k is the same
stratum, jitter, lens position and time whichever round traces it: :func:`tracer.integrator.tiles.pixel_stratum`),
and stops once its noise estimate is below the threshold. The estimate is Cycles': the pixel's mean I over all its
samples against the mean A over the half of them in class A (:func:`tracer.sampling.sample_class_a`),
error = Σ_rgb |I − A| / (10⁻⁴ + √(Σ_rgb I)) (Σ I instead of its root above 1), compared with 5 × the
threshold (Cycles' scale: a threshold means what it means in Cycles). A pixel that has not converged keeps its 3×3
neighbours sampling too (Cycles' x then y filter). The tile loop that runs the rounds is
:func:`tracer.integrator.tiles.trace_tile`; everything here is numpy on a tile's pixels (no loop per pixel).

Rounds and dilation stay inside one tile of :func:`tracer.integrator.tiles.tiles_of` (as Cycles filters inside its
work tile), so the pixels depend on the tile grid (the settings' tile size and region) but never on the thread
count, the order tiles finish in, or a farm splitting the frame along the same grid.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..settings import RenderSettings

#: Cycles multiplies the user's threshold by 5 before comparing ("makes the threshold more similar to what it was
#: before"); ours is compared the same way so that a threshold means the same in both renderers.
THRESHOLD_SCALE = 5.0
#: The divisor's ε of Cycles' error (no division by zero on black pixels).
EPSILON = 1e-4


class Schedule(NamedTuple):
    """The rounds of a tile: every pixel first takes ``first`` samples, then each pixel still sampling takes
    ``step`` more per round, up to ``budget`` (N²). ``threshold`` is the user's (unscaled)."""

    budget: int
    first: int
    step: int
    min_samples: int
    threshold: float


def enabled(settings: RenderSettings) -> bool:
    """Whether ``settings`` sample adaptively (a threshold > 0, and a budget a round can split)."""
    return settings.adaptive_threshold > 0 and settings.samples > 1


def min_samples(settings: RenderSettings) -> int:
    """Samples every pixel takes before it may stop: ``adaptive_min_samples``, or Cycles' automatic value
    max(4, ⌈16 / threshold^0.3⌉) (0.1 → 32, 0.01 → 64); at least 4, at most the budget N²."""
    nn = settings.samples ** 2
    t = settings.adaptive_threshold
    m = settings.adaptive_min_samples or math.ceil(16.0 / t ** 0.3)
    return min(nn, max(4, m))


def schedule(settings: RenderSettings) -> Schedule:
    """The rounds for ``settings``. Cycles checks every 16 samples; a Whitted budget is often 16 to 256 samples,
    so the step is N²/16 rounded up to a multiple of 4 (whole blocks of the order: each holds two samples of each
    class), between 4 and 16. The first check comes once ``min_samples`` are taken, at a multiple of the step."""
    nn = settings.samples ** 2
    step = min(16, max(4, 4 * math.ceil(nn / 64)))
    m = min_samples(settings)
    first = min(nn, step * math.ceil(m / step))
    return Schedule(budget=nn, first=first, step=step, min_samples=m, threshold=float(settings.adaptive_threshold))


def errors(total: np.ndarray, count: np.ndarray, total_a: np.ndarray, count_a: np.ndarray) -> np.ndarray:
    """Cycles' per-pixel error of (P, 3) colour sums over all samples (``total``, ``count`` of them) and over the
    class-A samples (``total_a``, ``count_a``): Σ|I − A| / (ε + √ΣI), with ΣI instead of its root above 1
    ("anything with R+G+B > 1 is highly exposed")."""
    i = total / np.maximum(count, 1)[:, None]
    a = total_a / np.maximum(count_a, 1)[:, None]
    diff = np.abs(i - a).sum(axis=1)
    intensity = i.sum(axis=1)
    norm = np.where(intensity < 1.0, np.sqrt(np.maximum(intensity, 0.0)), intensity)
    return diff / (EPSILON + norm)


def dilate(unconverged: np.ndarray) -> np.ndarray:
    """(h, w) bool: a pixel not converged marks its 8 neighbours too, as Cycles' ``film_adaptive_sampling_filter_x``
    then ``_y`` (a 1-pixel box dilation along x, then along y of that: 3×3), inside the tile."""
    x = unconverged.copy()
    x[:, 1:] |= unconverged[:, :-1]
    x[:, :-1] |= unconverged[:, 1:]
    y = x.copy()
    y[1:, :] |= x[:-1, :]
    y[:-1, :] |= x[1:, :]
    return y


def still_sampling(sched: Schedule, total, count, total_a, count_a, shape) -> np.ndarray:
    """(P,) bool: the pixels of a tile of ``shape`` (h, w) that take another round: not converged (their own
    estimate, or a neighbour's, is at or above the threshold) and below the budget."""
    err = errors(total, count, total_a, count_a)
    unconverged = ~(err < sched.threshold * THRESHOLD_SCALE)
    return dilate(unconverged.reshape(shape)).reshape(-1) & (count < sched.budget)


def sample_list(pixels: np.ndarray, start: np.ndarray, stop: np.ndarray):
    """The samples a round traces: for each pixel of ``pixels`` its positions ``start`` ≤ k < ``stop`` in the
    progressive order. Returns (pixel, k) per sample, a pixel's samples consecutive (int64)."""
    m = (stop - start).astype(np.int64)
    pix = np.repeat(pixels.astype(np.int64), m)
    first = np.cumsum(m) - m
    k = np.arange(int(m.sum()), dtype=np.int64) - np.repeat(first, m) + np.repeat(start.astype(np.int64), m)
    return pix, k

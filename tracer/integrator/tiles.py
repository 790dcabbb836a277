"""The tile loop under :class:`tracer.Session`: tiles on a thread pool, eye rays per tile, the film written.

Each tile is traced independently with sample patterns keyed by pixel, so images do not depend on the number of
threads or on tile order. Memory per tile is bounded by ``tile_size² × samples²`` rays. With adaptive sampling
(:mod:`.adaptive`) a tile is traced in rounds (:func:`trace_tile_adaptive`) and the film averages each pixel over
the samples it took (:func:`write_tile`). :func:`render_session` is
:meth:`tracer.Session.render`; :func:`render_tile` one tile of it (the farm's tasks); :func:`tracer.render` makes a
session for one render. This module never imports the session (it takes one), so the session sits above it.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..camera import eye_ray
from ..clip_planes import clip_eye_rays
from ..denoise import check as check_denoiser
from ..denoise import denoise_image
from ..film import Image, box_filter, majority, vote
from ..geometry.motion import decompose, place_ray, time_sample
from ..jit import kernel
from ..sampling import multijitter, progressive_order, sample_class_a, uniform1, uniform2_1
from ..scene import Scene
from ..settings import GUIDE_AOVS, RAY_TYPE_AOVS, RenderSettings
from . import adaptive, compose
from .wavefront import PATH_TYPES, NextQueue, RayCounts, ShadowQueue, SurfaceQueue


class RenderCancelled(Exception):
    """Raised by :func:`render` when its ``cancelled`` callback returned True; carries the partial image (None if
    it came before any pixel, while the Embree scene was being built)."""

    def __init__(self, image: Image):
        super().__init__("render cancelled")
        self.image = image


def tiles_of(settings: RenderSettings):
    """Tile rectangles (x0, y0, x1, y1) covering the render region, row by row from the top."""
    x0, y0, x1, y1 = settings.region or (0, 0, settings.width, settings.height)
    ts = settings.tile_size
    return [(x, y, min(x + ts, x1), min(y + ts, y1)) for y in range(y0, y1, ts) for x in range(x0, x1, ts)]


@kernel(inline=True)
def pixel_sample(px, py, s, n, width, height, seed):
    """Film position (u, v) and hash key of sample s of pixel (px, py) under N×N stratified sampling.

    The key is unique per sample (pixel·N² + s, modulo 2³²); with N = 1 the single sample goes through the pixel
    centre, otherwise it is jittered inside its stratum by the key's stream-0 random numbers.
    """
    key = ((py * width + px) * (n * n) + s) & 0xFFFFFFFF
    if n == 1:
        jx, jy = 0.5, 0.5
    else:
        r0, r1 = uniform2_1(key, 0, seed)
        jx, jy = ((s % n) + r0) / n, ((s // n) + r1) / n
    return (px + jx) / width, 1.0 - (py + jy) / height, key


#: Sample stream of the lens positions (pixel_sample uses stream 0 for the film jitter).
_STREAM_LENS = 61


@kernel(inline=True)
def lens_sample(px, py, s, n, width, seed, key):
    """Lens position (a, b) in [0, 1)² of sample s of pixel (px, py): the pixel's N² samples take the N² cells of a
    multi-jittered pattern, turned per pixel (Cranley-Patterson), in an order decorrelated from their film strata
    (cell (s·k) mod N², k coprime to N²); one sample per pixel takes the sample's own random pair."""
    nn = n * n
    if nn == 1:
        return uniform2_1(key, _STREAM_LENS, seed)
    r0, r1 = uniform2_1((py * width + px) & 0xFFFFFFFF, _STREAM_LENS, seed)
    k = (nn * 5) // 8 + 1  # about nn/φ: neighbouring film strata land far apart on the lens
    while math.gcd(k, nn) != 1:
        k += 1
    return multijitter((s * k) % nn, n, r0, r1)


@kernel
def _tile_samples(x0, y0, x1, y1, n, width, height, seed, u, v, keys):
    i = 0
    for py in range(y0, y1):
        for px in range(x0, x1):
            for s in range(n * n):
                u[i], v[i], keys[i] = pixel_sample(px, py, s, n, width, height, seed)
                i += 1


@kernel
def _tile_eye_rays(cam, x0, y0, x1, y1, n, width, height, seed, o, d, keys):
    i = 0
    for py in range(y0, y1):
        for px in range(x0, x1):
            for s in range(n * n):
                u, v, key = pixel_sample(px, py, s, n, width, height, seed)
                keys[i] = key
                a, b = 0.0, 0.0
                if cam.lens_radius > 0.0:
                    a, b = lens_sample(px, py, s, n, width, seed, key)
                oi, di = eye_ray(cam, u, v, a, b)
                o[i, 0], o[i, 1], o[i, 2] = oi
                d[i, 0], d[i, 1], d[i, 2] = di
                i += 1


@kernel
def _tile_eye_rays_timed(cam, cam_dec, table, x0, y0, x1, y1, n, width, height, seed, o, d, keys, times):
    """:func:`_tile_eye_rays` with a time per sample (:func:`tracer.geometry.motion.time_sample`); with camera motion
    (``cam_dec`` (1, S, 16), ``cam`` then the camera in its own space) each ray is placed by the camera's matrix
    at its time."""
    moving = cam_dec.shape[0] > 0
    i = 0
    for py in range(y0, y1):
        for px in range(x0, x1):
            for s in range(n * n):
                u, v, key = pixel_sample(px, py, s, n, width, height, seed)
                keys[i] = key
                a, b = 0.0, 0.0
                if cam.lens_radius > 0.0:
                    a, b = lens_sample(px, py, s, n, width, seed, key)
                tau = time_sample(px, py, s, n, width, seed, key, table)
                times[i] = tau
                oi, di = eye_ray(cam, u, v, a, b)
                if moving:
                    oi, di = place_ray(cam_dec, 0, tau, oi, di)
                o[i, 0], o[i, 1], o[i, 2] = oi
                d[i, 0], d[i, 1], d[i, 2] = di
                i += 1


#: Sample stream of each pixel's turn of the progressive order (adaptive sampling).
_STREAM_ORDER = 63


@kernel(inline=True)
def pixel_stratum(px, py, k, n, width, seed, order):
    """The stratum s (the index :func:`pixel_sample` takes) of pixel (px, py)'s k-th sample under adaptive
    sampling: position k of the progressive order ``order`` (:func:`tracer.sampling.progressive_order`), turned per
    pixel so that neighbouring pixels start in different strata: k XOR r when N² is a power of two (an aligned
    block of a (0, 2)-sequence stays a net), else (k + r) mod N², r a random position per pixel. A function of the
    pixel and k alone: the round that traces a sample does not change it."""
    nn = n * n
    r = min(int(uniform1((py * width + px) & 0xFFFFFFFF, _STREAM_ORDER, seed) * nn), nn - 1)
    if nn & (nn - 1) == 0:
        return order[k ^ r]
    return order[(k + r) % nn]


@kernel
def _list_eye_rays(cam, cam_dec, table, timed, xs, ys, ks, order, n, width, height, seed, o, d, keys, times, strata):
    """Eye rays of a list of samples (pixel (xs[i], ys[i]), position ks[i] of the progressive order): the rays,
    keys and times :func:`_tile_eye_rays_timed` (``timed``) or :func:`_tile_eye_rays` gives the same stratum, and
    the stratum itself (``strata``: where the sample sits among its pixel's N² in the film's layout)."""
    moving = cam_dec.shape[0] > 0
    for i in range(xs.shape[0]):
        px, py = xs[i], ys[i]
        s = pixel_stratum(px, py, ks[i], n, width, seed, order)
        strata[i] = s
        u, v, key = pixel_sample(px, py, s, n, width, height, seed)
        keys[i] = key
        a, b = 0.0, 0.0
        if cam.lens_radius > 0.0:
            a, b = lens_sample(px, py, s, n, width, seed, key)
        oi, di = eye_ray(cam, u, v, a, b)
        if timed:
            tau = time_sample(px, py, s, n, width, seed, key, table)
            times[i] = tau
            if moving:
                oi, di = place_ray(cam_dec, 0, tau, oi, di)
        o[i, 0], o[i, 1], o[i, 2] = oi
        d[i, 0], d[i, 1], d[i, 2] = di


def listed_eye_rays(scene: Scene, settings: RenderSettings, xs: np.ndarray, ys: np.ndarray, ks: np.ndarray):
    """Adaptive sampling's eye rays: the samples at positions ``ks`` of the progressive order of pixels
    (``xs``, ``ys``). Returns (o, d, keys, times, strata): as :func:`timed_eye_rays` gives them for the same
    strata (times None for a scene without motion), and each sample's stratum."""
    count = len(xs)
    o, d, keys = np.empty((count, 3), np.float32), np.empty((count, 3), np.float32), np.empty(count, np.int64)
    strata = np.empty(count, np.int64)
    timed = has_motion(scene)
    times = np.empty(count if timed else 0, np.float32)
    packed, cam_dec, table = _motion_inputs(scene) if timed else (scene.camera.packed(), _NO_CAMERA_MOTION,
                                                                  _NO_CURVE)
    _list_eye_rays(packed, cam_dec, table, timed, np.ascontiguousarray(xs, np.int64),
                   np.ascontiguousarray(ys, np.int64), np.ascontiguousarray(ks, np.int64),
                   progressive_order(settings.samples), settings.samples, settings.width, settings.height,
                   settings.seed, o, d, keys, times, strata)
    return o, d, keys, (times if timed else None), strata


def eye_samples(settings: RenderSettings, x0: int, y0: int, x1: int, y1: int):
    """Film positions (u, v) and hash keys of the N×N stratified samples of every pixel in a tile (array form of
    :func:`pixel_sample`). Samples of one pixel are consecutive."""
    count = (x1 - x0) * (y1 - y0) * settings.samples**2
    u, v, keys = np.empty(count), np.empty(count), np.empty(count, np.int64)
    _tile_samples(x0, y0, x1, y1, settings.samples, settings.width, settings.height, settings.seed, u, v, keys)
    return u, v, keys.astype(np.uint32)


def eye_rays(scene: Scene, settings: RenderSettings, x0: int, y0: int, x1: int, y1: int):
    """Eye-ray origins and directions (float32) and sample keys of a tile: :func:`eye_samples` through
    :func:`tracer.camera.eye_ray` in one pass."""
    count = (x1 - x0) * (y1 - y0) * settings.samples**2
    o, d, keys = np.empty((count, 3), np.float32), np.empty((count, 3), np.float32), np.empty(count, np.int64)
    _tile_eye_rays(scene.camera.packed(), x0, y0, x1, y1, settings.samples, settings.width, settings.height,
                   settings.seed, o, d, keys)
    return o, d, keys


_NO_CURVE = np.zeros(0, np.float32)
_NO_CAMERA_MOTION = np.zeros((0, 2, 16))


def _motion_inputs(scene: Scene):
    """(packed camera, camera motion (1, S, 16) or none, shutter curve table) of a scene with motion: with camera
    motion the rays are made in camera space, then placed by the camera at each ray's time."""
    cam = scene.camera
    packed, cam_dec = cam.packed(), _NO_CAMERA_MOTION
    if cam.motion is not None:
        packed = packed._replace(rotation=np.eye(3), eye=(0.0, 0.0, 0.0))
        cam_dec = np.ascontiguousarray(decompose(cam.motion)[None])
    table = scene.motion.curve if scene.motion is not None and len(scene.motion.curve) else _NO_CURVE
    return packed, cam_dec, table


def has_motion(scene: Scene) -> bool:
    """Whether ``scene`` has motion blur: something moves across the shutter (``Scene.motion``) or the camera."""
    return getattr(scene, "motion", None) is not None or scene.camera.motion is not None


def timed_eye_rays(scene: Scene, settings: RenderSettings, x0: int, y0: int, x1: int, y1: int):
    """:func:`eye_rays` and each sample's time across the shutter: (o, d, keys, times); times is None (and the
    rays are :func:`eye_rays`') when nothing moves, so a static scene pays nothing for motion blur."""
    if not has_motion(scene):
        return (*eye_rays(scene, settings, x0, y0, x1, y1), None)
    count = (x1 - x0) * (y1 - y0) * settings.samples**2
    o, d, keys = np.empty((count, 3), np.float32), np.empty((count, 3), np.float32), np.empty(count, np.int64)
    times = np.empty(count, np.float32)
    packed, cam_dec, table = _motion_inputs(scene)
    _tile_eye_rays_timed(packed, cam_dec, table, x0, y0, x1, y1, settings.samples, settings.width, settings.height,
                         settings.seed, o, d, keys, times)
    return o, d, keys, times


@kernel(refcounts=False)
def _write_rgba(rgba, color, alpha, x0, y0, tw, th, spp):
    """rgba[y0:y0+th, x0:x0+tw] = the box-filtered colour and alpha of a tile's samples (``spp`` consecutive per
    pixel), summed in float32 in sample order and divided by spp, as :func:`tracer.film.box_filter` does; without
    the GIL (the numpy form, a strided copy per channel, held the main thread 0.06 s per 1080p frame)."""
    n = np.float32(spp)
    for r in range(th):
        for c in range(tw):
            i = (r * tw + c) * spp
            cr, cg, cb, ca = color[i, 0], color[i, 1], color[i, 2], alpha[i]
            for k in range(1, spp):
                cr += color[i + k, 0]
                cg += color[i + k, 1]
                cb += color[i + k, 2]
                ca += alpha[i + k]
            px = rgba[y0 + r, x0 + c]
            px[0], px[1], px[2], px[3] = cr / n, cg / n, cb / n, ca / n


@kernel(refcounts=False)
def _write_rgba_spent(rgba, color, alpha, x0, y0, tw, th, starts, spent):
    """:func:`_write_rgba` of adaptive sampling's layout: pixel p's ``spent[p]`` samples from ``starts[p]`` on,
    summed in float32 in stratum order and divided by their count."""
    for r in range(th):
        for c in range(tw):
            p = r * tw + c
            i = starts[p]
            cr, cg, cb, ca = color[i, 0], color[i, 1], color[i, 2], alpha[i]
            for k in range(1, spent[p]):
                cr += color[i + k, 0]
                cg += color[i + k, 1]
                cb += color[i + k, 2]
                ca += alpha[i + k]
            n = np.float32(spent[p])
            px = rgba[y0 + r, x0 + c]
            px[0], px[1], px[2], px[3] = cr / n, cg / n, cb / n, ca / n


def write_tile(image: Image, res, tile, spp: int) -> None:
    """Box-filter a tile's samples into the image and its AOVs. With adaptive sampling (``res.spent``: pixels that
    took different counts) each pixel averages the samples it took."""
    if res.spent is not None:
        return _write_tile_spent(image, res, tile)
    x0, y0, x1, y1 = tile
    th, tw = y1 - y0, x1 - x0
    _write_rgba(image.rgba, res.color, res.alpha, x0, y0, tw, th, spp)
    aovs = image.aovs
    if res.compose is not None:  # shadow catchers: Cycles' Combined (the matte) and Shadow Catcher pass
        rgba, catcher = compose.composite(res.color, res.alpha, res.compose, spp, *res.compose_mode)
        image.rgba[y0:y1, x0:x1] = rgba.reshape(th, tw, 4)
        if "shadow_catcher" in aovs:
            aovs["shadow_catcher"][y0:y1, x0:x1] = catcher.reshape(th, tw, 3)
    if "depth" in aovs:
        hit = np.isfinite(res.depth).reshape(-1, spp)
        dsum = np.where(hit, res.depth.reshape(-1, spp), 0).sum(axis=1)
        nhit = hit.sum(axis=1)
        aovs["depth"][y0:y1, x0:x1] = np.where(nhit > 0, dsum / np.maximum(nhit, 1), np.inf).reshape(th, tw)
    if "normal" in aovs:
        nm = box_filter(res.normal, spp)
        nm = nm / np.maximum(np.linalg.norm(nm, axis=1, keepdims=True), 1e-30)
        aovs["normal"][y0:y1, x0:x1] = nm.reshape(th, tw, 3)
    if "albedo" in aovs:
        aovs["albedo"][y0:y1, x0:x1] = box_filter(res.albedo, spp).reshape(th, tw, 3)
    if "objectid" in aovs:
        aovs["objectid"][y0:y1, x0:x1] = majority(res.object_id, spp).reshape(th, tw)
    for i, name in enumerate(PATH_TYPES):
        if name in aovs:
            aovs[name][y0:y1, x0:x1] = box_filter(res.by_type[:, i], spp).reshape(th, tw, 3)
    if "raydepth" in aovs:
        aovs["raydepth"][y0:y1, x0:x1] = res.deepest.reshape(th, tw, spp).max(axis=2)
    if "denoising_albedo" in aovs:  # the denoiser's guides: the mean over the pixel's samples, as Cycles' passes
        aovs["denoising_albedo"][y0:y1, x0:x1] = box_filter(res.guide_albedo, spp).reshape(th, tw, 3)
    if "denoising_normal" in aovs:
        aovs["denoising_normal"][y0:y1, x0:x1] = box_filter(res.guide_normal, spp).reshape(th, tw, 3)
    if "sample_count" in aovs:
        aovs["sample_count"][y0:y1, x0:x1] = spp


#: Samples of a pixel that vote for its object id (tracer.film.majority's limit).
_VOTERS = 16


def _write_tile_spent(image: Image, res, tile) -> None:
    """:func:`write_tile` of pixels that took different counts (``res.spent``), each pixel's samples consecutive:
    the same means, over each pixel's own samples."""
    x0, y0, x1, y1 = tile
    th, tw = y1 - y0, x1 - x0
    spent = res.spent
    starts = np.cumsum(spent) - spent
    _write_rgba_spent(image.rgba, res.color, res.alpha, x0, y0, tw, th, starts, spent)
    mean = lambda a: np.add.reduceat(a, starts, axis=0) / spent[:, None].astype(np.float32)  # noqa: E731
    aovs = image.aovs
    if res.compose is not None:
        rgba, catcher = compose.composite(res.color, res.alpha, res.compose, 0, *res.compose_mode, spent=spent)
        image.rgba[y0:y1, x0:x1] = rgba.reshape(th, tw, 4)
        if "shadow_catcher" in aovs:
            aovs["shadow_catcher"][y0:y1, x0:x1] = catcher.reshape(th, tw, 3)
    if "depth" in aovs:
        hit = np.isfinite(res.depth)
        dsum = np.add.reduceat(np.where(hit, res.depth, 0), starts)
        nhit = np.add.reduceat(hit.astype(np.int32), starts)
        aovs["depth"][y0:y1, x0:x1] = np.where(nhit > 0, dsum / np.maximum(nhit, 1), np.inf).reshape(th, tw)
    if "normal" in aovs:
        nm = np.add.reduceat(res.normal, starts, axis=0)
        nm = nm / np.maximum(np.linalg.norm(nm, axis=1, keepdims=True), 1e-30)
        aovs["normal"][y0:y1, x0:x1] = nm.reshape(th, tw, 3)
    if "albedo" in aovs:
        aovs["albedo"][y0:y1, x0:x1] = mean(res.albedo).reshape(th, tw, 3)
    if "objectid" in aovs:  # the first _VOTERS samples of each pixel vote
        j = np.arange(_VOTERS)
        ok = j[None, :] < spent[:, None]
        g = res.object_id[np.where(ok, starts[:, None] + j[None, :], starts[:, None])]
        aovs["objectid"][y0:y1, x0:x1] = vote(g, ok).reshape(th, tw)
    for i, name in enumerate(PATH_TYPES):
        if name in aovs:
            aovs[name][y0:y1, x0:x1] = mean(res.by_type[:, i]).reshape(th, tw, 3)
    if "raydepth" in aovs:
        aovs["raydepth"][y0:y1, x0:x1] = np.maximum.reduceat(res.deepest, starts).reshape(th, tw)
    if "denoising_albedo" in aovs:  # the denoiser's guides, over the samples the pixel took
        aovs["denoising_albedo"][y0:y1, x0:x1] = mean(res.guide_albedo).reshape(th, tw, 3)
    if "denoising_normal" in aovs:
        aovs["denoising_normal"][y0:y1, x0:x1] = mean(res.guide_normal).reshape(th, tw, 3)
    if "sample_count" in aovs:
        aovs["sample_count"][y0:y1, x0:x1] = spent.reshape(th, tw)


def empty_aovs(settings: RenderSettings, h: int, w: int) -> dict:
    """The AOV arrays ``settings.aovs`` asks for, (h, w[, 3]), filled with their "nothing here" value."""
    aovs = {}
    if "depth" in settings.aovs:
        aovs["depth"] = np.full((h, w), np.inf, np.float32)
    if "normal" in settings.aovs:
        aovs["normal"] = np.zeros((h, w, 3), np.float32)
    if "albedo" in settings.aovs:
        aovs["albedo"] = np.zeros((h, w, 3), np.float32)
    if "objectid" in settings.aovs:
        aovs["objectid"] = np.full((h, w), -1, np.int32)
    for name in PATH_TYPES:
        if name in settings.aovs:
            aovs[name] = np.zeros((h, w, 3), np.float32)
    if "raydepth" in settings.aovs:
        aovs["raydepth"] = np.full((h, w), -1, np.int32)
    if "shadow_catcher" in settings.aovs:  # 1 where no catcher is seen (tracer.integrator.compose)
        aovs["shadow_catcher"] = np.ones((h, w, 3), np.float32)
    if uses_guides(settings):  # the denoiser's guides (kept for it even when not asked for as outputs)
        for name in GUIDE_AOVS:
            aovs[name] = np.zeros((h, w, 3), np.float32)
    if "sample_count" in settings.aovs:  # 0 where nothing was rendered
        aovs["sample_count"] = np.zeros((h, w), np.int32)
    return aovs


def uses_ray_types(settings: RenderSettings) -> bool:
    """Whether the integrator must split colours by ray type (a ray-type AOV is asked for)."""
    return any(a in RAY_TYPE_AOVS for a in settings.aovs)


def uses_guides(settings: RenderSettings) -> bool:
    """Whether the integrator must make the denoising guides (tracer/integrator/guides.py): to denoise, or asked for."""
    return bool(settings.denoise) or any(a in GUIDE_AOVS for a in settings.aovs)


#: Shadow-ray slots a batch of eye samples may fill at one depth: each shading point queues up to the
#: integrator's light samples plus sky samples, 48 bytes each (tracer.integrator.wavefront.ShadowQueue). 2^19 slots ≈ 25 MB
#: per tile thread; a 128 px tile at AA 2 with three lights of 16 samples and 16 sky samples had 4 M (200 MB).
SHADOW_SLOTS = 1 << 19


class RenderTooLarge(ValueError):
    """A render whose estimated memory (:func:`memory_estimate`) is more than the machine has available."""


def memory_estimate(settings: RenderSettings) -> dict:
    """Bytes a render with ``settings`` allocates, by part (an estimate for refusing impossible sizes up front,
    not a measurement): "image" the RGBA float32 film; "aovs" the AOV arrays (:func:`empty_aovs`'s, per pixel);
    "output" the writer's copies (:func:`tracer.film.write_image`: a float32 copy without NaN, then for 8-bit
    files the display conversion's float32 and uint8 arrays: 36 bytes a pixel); "tiles" per tile thread the tile's eye samples with their per-sample outputs, one batch of rays' surface
    and next-ray queues (reflections and transmissions: twice the batch) and the shadow queue of
    :data:`SHADOW_SLOTS` (twice: a depth's layers are joined into one copy). The queues' row sizes are read from
    their definitions in :mod:`tracer.integrator.wavefront`. The scene and its BVH are not counted (the caller holds them)."""
    settings = settings.validate()
    row = lambda q: sum(a.nbytes for a in q if isinstance(a, np.ndarray)) + sum(  # noqa: E731
        row(a) for a in q if isinstance(a, tuple))
    px = settings.width * settings.height
    aov_px = sum(a.nbytes for a in empty_aovs(settings, 1, 1).values())
    k = len(PATH_TYPES) if uses_ray_types(settings) else 1
    tile_samples = settings.tile_size ** 2 * settings.samples ** 2
    per_sample = (3 * 4 * 2 + 8 + 4) + k * (12 + 4 + 4 + 12 + 12 + 4 + 8)  # eye o, d, key, time; Tile outputs, keys
    batch = 2 * min(tile_samples, max(1024, SHADOW_SLOTS))
    per_thread = (tile_samples * per_sample + batch * (row(SurfaceQueue.empty(1)) + row(NextQueue.empty(1, True)))
                  + 2 * SHADOW_SLOTS * row(ShadowQueue.empty(1)))
    threads = min(settings.threads or os.cpu_count() or 1, len(tiles_of(settings)))
    return {"image": 16 * px, "aovs": aov_px * px, "output": 36 * px, "tiles": threads * per_thread}


def available_memory() -> int | None:
    """Bytes the machine can give a process now: ``MemAvailable`` of /proc/meminfo (Linux: free memory plus
    what the kernel can reclaim), else the physical memory (``os.sysconf``); None where neither is known."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def format_bytes(n: float) -> str:
    """1536 -> '1.5 KiB', 3.2e9 -> '3.0 GiB'."""
    for unit in ("bytes", "KiB", "MiB", "GiB", "TiB"):
        if n < 1024 or unit == "TiB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1024.0
    return f"{n:.1f} TiB"


def describe_memory(settings: RenderSettings) -> str:
    """'about 1.2 GiB (image 0.5 GiB, aovs 0 bytes, output 0.5 GiB, tiles 0.2 GiB)' for ``settings``."""
    need = memory_estimate(settings)
    parts = ", ".join(f"{k} {format_bytes(v)}" for k, v in need.items() if v)
    return f"about {format_bytes(sum(need.values()))} ({parts})"


def check_memory(settings: RenderSettings, available: int | None = None) -> None:
    """Raise :class:`RenderTooLarge` when a render with ``settings`` needs more memory (:func:`memory_estimate`)
    than ``available`` (default: :func:`available_memory`; unknown: no check), before anything is allocated."""
    available = available_memory() if available is None else available
    need = sum(memory_estimate(settings).values())
    if available is not None and need > available:
        raise RenderTooLarge(f"a {settings.width}x{settings.height} render needs {describe_memory(settings)}, "
                             f"more than the {format_bytes(available)} this machine has available")


def trace_batches(integ, o, d, keys, cancelled, ray_types=False, t_max=None, times=None, guides=False):
    """``integ.trace`` over a tile's eye samples in consecutive batches of at most :data:`SHADOW_SLOTS` shadow
    slots, joined into one :class:`~tracer.integrator.wavefront.TileResult`. Each sample's path is traced within one batch
    and its rays keep their relative order, so the result equals one call's bit for bit."""
    per_point = max(1, int(integ.light_samples) + int(integ.sky_side) ** 2)
    batch = max(1024, SHADOW_SLOTS // per_point)
    n = len(o)
    if n <= batch:
        return integ.trace(o, d, keys, cancelled, ray_types=ray_types, t_max=t_max, times=times, guides=guides)
    parts = []
    for a in range(0, n, batch):
        b = min(a + batch, n)
        parts.append(integ.trace(o[a:b], d[a:b], keys[a:b], cancelled, ray_types=ray_types,
                                 t_max=None if t_max is None else t_max[a:b],
                                 times=None if times is None else times[a:b], guides=guides))
    return _joined_results(parts)


def _joined_results(parts):
    """One TileResult of consecutive batches' results (per-sample arrays joined, ray counts summed)."""
    first = parts[0]
    counts = RayCounts()
    for r in parts:
        counts.add(r.counts)
    join = lambda name: None if getattr(first, name) is None else np.concatenate(  # noqa: E731
        [getattr(r, name) for r in parts])
    return dataclasses.replace(first, color=join("color"), alpha=join("alpha"), depth=join("depth"),
                               normal=join("normal"), albedo=join("albedo"), object_id=join("object_id"),
                               counts=counts, by_type=join("by_type"), deepest=join("deepest"),
                               compose=join("compose"), guide_albedo=join("guide_albedo"),
                               guide_normal=join("guide_normal"))


def trace_eye(session, settings: RenderSettings, o, d, keys, times, cancelled):
    """Trace eye samples (o, d, keys, times) through the session's integrator, as a tile's: the camera's clipping
    planes, batches of bounded memory, depth measured from the eye. The per-sample :class:`TileResult`."""
    integ = session.integrator(settings)
    cam = session.scene.camera
    t_max = None
    if cam.clipping_planes:  # each ray's valid interval (tracer.clip_planes): origin moved to its start
        o, t_max = clip_eye_rays(cam, o, d, cam.far - cam.near)
    res = trace_batches(integ, o, d, keys, cancelled, ray_types=uses_ray_types(settings), t_max=t_max, times=times,
                        guides=uses_guides(settings))
    if cam.near > 0 or cam.clipping_planes:  # depth is measured from the eye (the film plane for orthographic)
        rel = o - cam.position.astype(np.float32)
        res.depth += (np.linalg.norm(rel, axis=1) if cam.projection == "perspective"
                      else rel @ -cam.camera_to_world[:3, 2].astype(np.float32))
    return res


def trace_tile(session, settings: RenderSettings, tile, cancelled=None):
    """Trace one tile's eye samples through the session's integrator: the per-sample :class:`TileResult` (with
    adaptive sampling, in rounds: :func:`trace_tile_adaptive`)."""
    cancelled = cancelled or (lambda: False)
    if adaptive.enabled(settings):
        return trace_tile_adaptive(session, settings, tile, cancelled)
    x0, y0, x1, y1 = tile
    o, d, keys, times = timed_eye_rays(session.scene, settings, x0, y0, x1, y1)
    return trace_eye(session, settings, o, d, keys, times, cancelled)


def trace_tile_adaptive(session, settings: RenderSettings, tile, cancelled):
    """Adaptive sampling of one tile (:mod:`tracer.integrator.adaptive`): every pixel takes the schedule's first
    samples, then rounds of ``step`` more for the pixels still sampling, each pixel's k-th sample always the same
    (:func:`pixel_stratum`). The result holds each pixel's samples consecutively in stratum order and ``spent``,
    how many; when every pixel took all N², it is the fixed-count result itself (``spent`` None)."""
    x0, y0, x1, y1 = tile
    tw, th = x1 - x0, y1 - y0
    npx = tw * th
    sched = adaptive.schedule(settings)
    count = np.zeros(npx, np.int64)
    count_a = np.zeros(npx, np.int64)
    total = np.zeros((npx, 3))
    total_a = np.zeros((npx, 3))
    parts, pixel_of, stratum_of = [], [], []
    pixels = np.arange(npx)
    stop = np.full(npx, sched.first, np.int64)
    while True:
        pix, k = adaptive.sample_list(pixels, count[pixels], stop)
        o, d, keys, times, strata = listed_eye_rays(session.scene, settings, x0 + pix % tw, y0 + pix // tw, k)
        res = trace_eye(session, settings, o, d, keys, times, cancelled)
        parts.append(res)
        pixel_of.append(pix)
        stratum_of.append(strata)
        cls_a = sample_class_a(k)
        for c in range(3):
            total[:, c] += np.bincount(pix, weights=res.color[:, c], minlength=npx)
            total_a[:, c] += np.bincount(pix[cls_a], weights=res.color[cls_a, c], minlength=npx)
        count_a += np.bincount(pix[cls_a], minlength=npx)
        count[pixels] = stop
        if cancelled():
            break
        pixels = np.flatnonzero(adaptive.still_sampling(sched, total, count, total_a, count_a, (th, tw)))
        if not len(pixels):
            break
        stop = np.minimum(count[pixels] + sched.step, sched.budget)
    res = _joined_results(parts) if len(parts) > 1 else parts[0]
    order = np.lexsort((np.concatenate(stratum_of), np.concatenate(pixel_of)))  # by pixel, then stratum
    res = _taken(res, order)
    if not (count == sched.budget).all():
        res.spent = count.astype(np.int32)
    return res


def _taken(res, order):
    """``res`` with its per-sample arrays in ``order``."""
    take = lambda name: None if getattr(res, name) is None else getattr(res, name)[order]  # noqa: E731
    return dataclasses.replace(res, **{name: take(name) for name in ("color", "alpha", "depth", "normal", "albedo",
                                                                     "object_id", "by_type", "deepest", "compose",
                                                                     "guide_albedo", "guide_normal")})


def render_tile(session, settings: RenderSettings, tile) -> Image:
    """The pixels of one tile (x0, y0, x1, y1) of ``session``'s image under ``settings``: an
    :class:`~tracer.film.Image` of the tile's size (its AOVs too), identical to that rectangle of a whole
    :meth:`tracer.Session.render`. Thread-safe: call it from several threads for different tiles.

    With adaptive sampling the rectangle is traced in the parts of :func:`tiles_of`'s tiles it covers (the rounds
    and their dilation run per tile): a rectangle made of whole tiles (the farm's) is identical to a whole render,
    one that cuts tiles may sample the pixels near the cut differently."""
    settings = settings.validate()
    x0, y0, x1, y1 = (int(c) for c in tile)
    if not (0 <= x0 < x1 <= settings.width and 0 <= y0 < y1 <= settings.height):
        raise ValueError(f"tile {tile} must lie inside {settings.width}x{settings.height} and be non-empty")
    th, tw = y1 - y0, x1 - x0
    img = Image(rgba=np.zeros((th, tw, 4), np.float32), aovs=empty_aovs(settings, th, tw))
    parts = [(x0, y0, x1, y1)]
    if adaptive.enabled(settings):
        parts = [(max(a, x0), max(b, y0), min(c, x1), min(d, y1)) for a, b, c, d in tiles_of(settings)
                 if a < x1 and c > x0 and b < y1 and d > y0]
    counts = RayCounts()
    for part in parts:
        res = trace_tile(session, settings, part)
        write_tile(img, res, (part[0] - x0, part[1] - y0, part[2] - x0, part[3] - y0), settings.samples**2)
        counts.add(res.counts)
    img.stats = {"rays": counts.as_dict()}
    return img


def render_session(session, settings: RenderSettings | None = None, *, on_tile=None, cancelled=None,
                   started: float | None = None) -> Image:
    """:meth:`tracer.Session.render`: every tile of ``settings`` on a thread pool, written into one image."""
    settings = (settings or RenderSettings()).validate()
    check_memory(settings)  # an impossible size is one clear error, not numpy's allocation failure midway
    if settings.denoise:  # no OIDN library: DenoiseUnavailable now, not after the render
        check_denoiser()
    cancelled = cancelled or (lambda: False)
    start = started if started is not None else time.perf_counter()
    scene = session.scene
    accel = session.accel
    build_time = session.stats["build_seconds"] if started is not None else 0.0
    integ = session.integrator(settings)
    w, h = settings.width, settings.height
    spp = settings.samples**2
    image = Image(rgba=np.zeros((h, w, 4), np.float32))
    image.aovs = empty_aovs(settings, h, w)
    counts = RayCounts()
    isect_before = accel.seconds

    def work(tile):
        if cancelled():
            return None
        return trace_tile(session, settings, tile, cancelled)

    tiles = tiles_of(settings)
    threads = settings.threads or os.cpu_count() or 1
    bar = None
    if settings.progress:
        from tqdm import tqdm

        bar = tqdm(total=len(tiles), unit="tile", desc="whitted", leave=False)
    was_cancelled = False
    pool = ThreadPoolExecutor(max_workers=threads) if threads > 1 else None
    results = pool.map(work, tiles) if pool is not None else map(work, tiles)
    try:
        for tile, res in zip(tiles, results):
            if res is None or cancelled():
                was_cancelled = True
                break
            write_tile(image, res, tile, spp)
            counts.add(res.counts)
            if bar is not None:
                bar.update(1)
            if on_tile is not None:
                on_tile(image, tile)
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
    if bar is not None:
        bar.close()
    elapsed = time.perf_counter() - start
    pixels = sum((t[2] - t[0]) * (t[3] - t[1]) for t in tiles)
    image.stats = {"rays": counts.as_dict(), "samples_per_pixel": counts.eye / max(pixels, 1), "seconds": elapsed,
                   "bvh_seconds": build_time, "threads": threads,
                   "rays_per_second": counts.total / elapsed if elapsed > 0 else 0.0, "epsilon": float(integ.eps),
                   "triangles": len(scene.triangles), "intersect_seconds": accel.seconds - isect_before}
    if getattr(accel, "record", False):
        image.stats["ray_batches"] = accel.batches
    if was_cancelled:
        raise RenderCancelled(image)
    if settings.denoise:  # the whole frame (or region) at once: the filter looks across tile borders
        denoise_image(image, settings, prefilter=guide_prefilter(scene))
        image.stats["seconds"] = time.perf_counter() - start
        if on_tile is not None:  # the frame changed everywhere: hand it over once more, whole
            on_tile(image, settings.region or (0, 0, w, h))
    return image


def guide_prefilter(scene: Scene) -> str:
    """How the denoiser treats the guides (tracer.denoise.PREFILTERS): "none" (trusted as clean, one filter) when
    the eye samples see the scene without a lens or motion, where the guides are the anti-aliased first hits and
    carry no noise; "accurate" (filtered first, Cycles' default) when depth of field or motion blur makes them
    noisy. docs/benchmarks.md ("Denoising"): the prefilter costs two more filters."""
    return "accurate" if scene.camera.lens_radius > 0 or has_motion(scene) else "none"

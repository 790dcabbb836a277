"""``tracer.render(scene, settings)``: tiles on a thread pool, eye rays per tile, film out.

Each tile is traced independently with sample patterns keyed by pixel, so images do not depend on the number of
threads or on tile order. Memory per tile is bounded by ``tile_size² × samples²`` rays.
"""

from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from . import sampling
from .accel import Accelerator
from .film import Image, box_filter, majority
from .integrator import Integrator, RayCounts
from .scene import Scene
from .settings import RenderSettings


class RenderCancelled(Exception):
    """Raised by :func:`render` when its ``cancelled`` callback returned True; carries the partial image."""

    def __init__(self, image: Image):
        super().__init__("render cancelled")
        self.image = image


def tiles_of(settings: RenderSettings):
    """Tile rectangles (x0, y0, x1, y1) covering the render region, row by row from the top."""
    x0, y0, x1, y1 = settings.region or (0, 0, settings.width, settings.height)
    ts = settings.tile_size
    return [(x, y, min(x + ts, x1), min(y + ts, y1)) for y in range(y0, y1, ts) for x in range(x0, x1, ts)]


def eye_samples(settings: RenderSettings, x0: int, y0: int, x1: int, y1: int):
    """Film positions (u, v) and hash keys of the N×N stratified samples of every pixel in a tile.

    Samples of one pixel are consecutive. With N = 1 the single sample goes through the pixel centre.
    """
    n = settings.samples
    spp = n * n
    py, px = np.mgrid[y0:y1, x0:x1]
    pixel = (py.astype(np.int64) * settings.width + px).reshape(-1, 1)
    s = np.arange(spp)[None, :]
    keys = (pixel * spp + s).reshape(-1).astype(np.uint64) & np.uint64(0xFFFFFFFF)
    keys = keys.astype(np.uint32)
    if n == 1:
        jx = jy = np.full(keys.shape, 0.5, np.float32)
    else:
        r = sampling.uniform2(keys, 0, settings.seed)
        jx = (np.tile(np.arange(spp) % n, len(pixel)) + r[:, 0]) / n
        jy = (np.tile(np.arange(spp) // n, len(pixel)) + r[:, 1]) / n
    pxs = np.repeat(px.reshape(-1), spp)
    pys = np.repeat(py.reshape(-1), spp)
    u = (pxs + jx) / settings.width
    v = 1.0 - (pys + jy) / settings.height
    return u, v, keys


def write_tile(image: Image, res, tile, spp: int) -> None:
    """Box-filter a tile's samples into the image and its AOVs."""
    x0, y0, x1, y1 = tile
    th, tw = y1 - y0, x1 - x0
    image.rgba[y0:y1, x0:x1, :3] = box_filter(res.color, spp).reshape(th, tw, 3)
    image.rgba[y0:y1, x0:x1, 3] = box_filter(res.alpha, spp).reshape(th, tw)
    aovs = image.aovs
    if "depth" in aovs:
        hit = np.isfinite(res.depth).reshape(-1, spp)
        dsum = np.where(hit, res.depth.reshape(-1, spp), 0).sum(axis=1)
        nhit = hit.sum(axis=1)
        aovs["depth"][y0:y1, x0:x1] = np.where(nhit > 0, dsum / np.maximum(nhit, 1), np.inf).reshape(th, tw)
    if "normal" in aovs:
        nm = box_filter(res.normal, spp)
        nm /= np.maximum(np.linalg.norm(nm, axis=1, keepdims=True), 1e-30)
        aovs["normal"][y0:y1, x0:x1] = nm.reshape(th, tw, 3)
    if "albedo" in aovs:
        aovs["albedo"][y0:y1, x0:x1] = box_filter(res.albedo, spp).reshape(th, tw, 3)
    if "objectid" in aovs:
        aovs["objectid"][y0:y1, x0:x1] = majority(res.object_id, spp).reshape(th, tw)


def render(scene: Scene, settings: RenderSettings | None = None, *, on_tile=None, cancelled=None) -> Image:
    """Render ``scene`` and return an :class:`~tracer.film.Image`.

    on_tile(image, (x0, y0, x1, y1)) is called after each tile is written (in the calling thread), for progressive
    display; cancelled() is polled between tiles and depths, and a True ends the render with :class:`RenderCancelled`.
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"render() expects a tracer.Scene, got {type(scene).__name__}")
    settings = (settings or RenderSettings()).validate()
    cancelled = cancelled or (lambda: False)
    start = time.perf_counter()
    accel = Accelerator(scene, record=bool(settings.extra.get("record_rays")))
    build_time = time.perf_counter() - start
    integ = Integrator(scene, settings, accel)
    w, h = settings.width, settings.height
    spp = settings.samples**2
    image = Image(rgba=np.zeros((h, w, 4), np.float32))
    aovs = {}
    if "depth" in settings.aovs:
        aovs["depth"] = np.full((h, w), np.inf, np.float32)
    if "normal" in settings.aovs:
        aovs["normal"] = np.zeros((h, w, 3), np.float32)
    if "albedo" in settings.aovs:
        aovs["albedo"] = np.zeros((h, w, 3), np.float32)
    if "objectid" in settings.aovs:
        aovs["objectid"] = np.full((h, w), -1, np.int32)
    image.aovs = aovs
    counts = RayCounts()

    def work(tile):
        if cancelled():
            return None
        x0, y0, x1, y1 = tile
        u, v, keys = eye_samples(settings, x0, y0, x1, y1)
        o, d = scene.camera.generate_rays(u, v)
        res = integ.trace(o, d, keys, cancelled)
        if scene.camera.near > 0:  # depth is measured from the eye (the film plane for orthographic cameras)
            cam = scene.camera
            start = (np.linalg.norm(o - cam.position.astype(np.float32), axis=1) if cam.projection == "perspective"
                     else np.float32(cam.near))
            res.depth += start
        return res

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
    image.stats = {"rays": counts.as_dict(), "seconds": elapsed, "bvh_seconds": build_time, "threads": threads,
                   "rays_per_second": counts.total / elapsed if elapsed > 0 else 0.0, "epsilon": float(integ.eps),
                   "triangles": len(scene.triangles), "intersect_seconds": accel.seconds}
    if accel.record:
        image.stats["ray_batches"] = accel.batches
    if was_cancelled:
        raise RenderCancelled(image)
    return image

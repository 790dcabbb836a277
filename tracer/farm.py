"""Render farms on Dask: frames and tiles as Dask tasks, for any scene source.

The tracer does not know where scenes come from, so a farm job names a *scene source*: a small picklable object
with ``load(frame) -> (Scene, RenderSettings)`` (``usd_io.farm.UsdSource`` reads a USD stage) and, optionally,
``scene_key(frame)``: a key that is equal for frames whose scenes are equal (a still stage's frames) and changes when
the scene's files change. Workers load the scene themselves and keep it prepared (:func:`prepare`: the scene and a
:class:`tracer.Session`, its Embree scene and packed tables) for the tasks that share it — every tile of a frame,
and every frame with the same ``scene_key`` — so nothing is read, exported or built again for them. The client only
submits, assembles and writes:

    >>> from dask.distributed import Client
    >>> from tracer.farm import render_frames
    >>> from usd_io.farm import UsdSource  # a front end's scene source: the tracer itself never imports usd_io
    >>> client = Client("tcp://scheduler:8786")
    >>> for frame, image in render_frames(client, UsdSource("/shared/shot.usd", width=1920), range(1, 241)):
    ...     image.save(f"/shared/out.{int(frame):04d}.png")

With ``assets`` (bytes the source can unpack, e.g. a .usdz package of a stage and its dependencies), the package
is sent to every worker once and the workers read it instead of a shared path.

Pixels are those of a local render, bit for bit: sample patterns are keyed by pixel, and a tile renders its pixels
exactly as the whole frame would. A worker that dies mid-task has its task run again elsewhere (Dask's scheduler does
that, up to ``distributed.scheduler.allowed-failures`` times); a task that raises (a scene problem) fails once, with
its error, and is not retried.
"""

from __future__ import annotations

import collections
import multiprocessing
import threading
import time
from dataclasses import dataclass, replace

import numpy as np

from .denoise import check as check_denoiser
from .denoise import denoise_image
from .film import Image
from .settings import RenderSettings

#: Tile edge of a split frame: big enough that per-task overhead (a few ms) is small against the tile's work.
DEFAULT_FARM_TILE = 512

#: Prepared scenes a worker keeps (frames or sources beyond this are loaded again).
WORKER_CACHE_SIZE = 2


#: Dask settings for workers that render (applied to the clusters ``local:N`` starts; for a cluster of your own, start
#: its workers with them, e.g. ``DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED=False``, and without
#: ``MALLOC_TRIM_THRESHOLD_`` in their environment). Measured (docs/benchmarks.md, "Farm"):
#:
#: - Dask's nannies start workers with ``MALLOC_TRIM_THRESHOLD_=65536``, so glibc hands every freed block above
#:   64 kB back to the kernel and the next tile's arrays fault in fresh pages: 3× the page faults of a plain process
#:   (78 k against 26 k per 480×270 frame of the 1980 scene) and 0.07-0.1 s more system CPU per frame (10 %).
#:   The workers keep the other variables Dask sets (one OpenMP/BLAS thread) and glibc's own, adaptive threshold;
#:   the tracer trims its heap itself where a load frees much (``tracer.heap.trim``).
#: - Dask's statistical profiler samples every task thread's stack each 10 ms, and its event-loop and system
#:   monitors tick every 20 and 500 ms: 0.5 s of worker CPU beside 8 such frames.
#: - Where the platform has it, workers fork from a forkserver that has imported Dask once, instead of each starting
#:   a fresh interpreter and importing it (spawn): 0.5-1 s less CPU for a ``whitted render --scheduler local:2``.
WORKER_CONFIG = {
    "distributed.nanny.pre-spawn-environ": {"OMP_NUM_THREADS": 1, "MKL_NUM_THREADS": 1, "OPENBLAS_NUM_THREADS": 1},
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "500ms",
    "distributed.admin.system-monitor.interval": "2s",
}
if "forkserver" in multiprocessing.get_all_start_methods():
    WORKER_CONFIG["distributed.worker.multiprocessing-method"] = "forkserver"


def local_cluster(n_workers: int, **options):
    """A Dask ``LocalCluster`` of ``n_workers`` one-thread worker processes on 127.0.0.1 (dashboard on a free port),
    configured with :data:`WORKER_CONFIG`, and its client -> (client, cluster)."""
    import logging

    import dask
    from dask.distributed import Client, LocalCluster

    kw = dict(n_workers=n_workers, threads_per_worker=1, processes=True, host="127.0.0.1",
              dashboard_address="127.0.0.1:0", silence_logs=logging.ERROR)
    kw.update(options)
    with dask.config.set(WORKER_CONFIG):
        cluster = LocalCluster(**kw)
        return Client(cluster), cluster


class FarmError(RuntimeError):
    """A frame or tile that failed on the farm for a reason that retrying will not fix (its message says which)."""


@dataclass(frozen=True)
class FrameResult:
    frame: object
    image: Image | None
    error: str | None = None


# ---------------------------------------------------------------------------------------------------- worker side
@dataclass
class Prepared:
    """A worker's prepared frame: the scene and settings a source loaded, and the :class:`tracer.Session` (Embree
    scene and packed tables) that renders it. ``reused``: False (loaded and built for this frame), ``"scene"`` (an
    earlier frame's scene and session, the source's key said they are the same) or ``"accel"`` (loaded again, but
    equal to the previous frame's scene except for the camera: its Embree scene is shared)."""

    scene: object
    settings: RenderSettings
    session: object
    renderer: "_TileRenderer"
    reused: object = False


_cache: "collections.OrderedDict" = collections.OrderedDict()  # (source token, scene key) -> Prepared
_last: dict = {}  # source token -> the Prepared loaded last for it (camera-only changes share its Embree scene)
_cache_lock = threading.Lock()
_key_locks: dict = {}  # one loader at a time per key (a frame's tile tasks on a multi-threaded worker)


def scene_key(source, frame):
    """What identifies the scene ``source`` loads at ``frame``: the source's own ``scene_key(frame)`` when it has one
    (equal keys promise equal scenes and settings: a stage without time samples gives every frame one key, and the
    key changes when the stage's files change), else the frame itself (loaded once per frame)."""
    own = getattr(source, "scene_key", None)
    return ("frame", frame) if own is None else ("source", own(frame))


def prepare(source, frame) -> Prepared:
    """The worker's :class:`Prepared` for ``source`` at ``frame``, kept in an LRU of :data:`WORKER_CACHE_SIZE`
    entries per worker process, so the frames and tiles that share a scene read the stage and build the Embree
    scene once. A frame whose scene differs from the last one loaded for this source only by its camera (a camera
    moving through a still set) shares that frame's Embree scene; any other difference builds its own."""
    token = _token(source)
    key = (token, scene_key(source, frame))
    with _cache_lock:
        hit = _cache.get(key)
        if hit is not None:
            _cache.move_to_end(key)
            return replace(hit, reused="scene")
        lock = _key_locks.setdefault(key, threading.Lock())
    with lock:
        with _cache_lock:
            hit = _cache.get(key)
        if hit is not None:
            return replace(hit, reused="scene")
        entry = _load(source, frame, token)
        with _cache_lock:
            _cache[key] = entry
            _cache.move_to_end(key)
            _last[token] = entry
            while len(_cache) > WORKER_CACHE_SIZE:
                (old_token, _), old = _cache.popitem(last=False)
                if _last.get(old_token) is old:  # hold no scene the LRU has let go
                    del _last[old_token]
            _key_locks.pop(key, None)
    return entry


def _load(source, frame, token) -> Prepared:
    from .session import Session

    scene, settings = source.load(frame)
    if settings.threads is None:  # share the machine with the worker's other task slots
        settings = settings.with_(threads=_threads_per_task())
    with _cache_lock:
        last = _last.get(token)
    if last is not None and same_except_camera(last.scene, scene):
        session = Session(scene, accel=last.session.accel, instanced=False)
        return Prepared(scene, settings, session, _TileRenderer(session), "accel")
    session = Session(scene, instanced=False)
    return Prepared(scene, settings, session, _TileRenderer(session))


def prepared(source, frame):
    """(scene, settings, tile renderer) of :func:`prepare` (the former interface)."""
    p = prepare(source, frame)
    return p.scene, p.settings, p.renderer


def forget() -> None:
    """Drop every prepared scene of this worker (tests; a worker that must free its memory)."""
    with _cache_lock:
        _cache.clear()
        _last.clear()


def same_except_camera(a, b) -> bool:
    """True when scenes ``a`` and ``b`` are equal in every field but the camera (arrays element by element, NaNs
    equal): then an Embree scene and packed tables built for one serve the other."""
    from dataclasses import fields as dc_fields

    if type(a) is not type(b):
        return False
    return all(_equal(getattr(a, f.name), getattr(b, f.name)) for f in dc_fields(a) if f.name != "camera")


def _equal(x, y) -> bool:
    if x is y:
        return True
    if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
        if not (isinstance(x, np.ndarray) and isinstance(y, np.ndarray)) or x.shape != y.shape or x.dtype != y.dtype:
            return False
        return bool(np.array_equal(x, y, equal_nan=x.dtype.kind in "fc"))
    if type(x) is not type(y):
        return False
    if isinstance(x, (list, tuple)):
        return len(x) == len(y) and all(_equal(p, q) for p, q in zip(x, y))
    if isinstance(x, dict):
        return x.keys() == y.keys() and all(_equal(x[k], y[k]) for k in x)
    from dataclasses import fields as dc_fields, is_dataclass

    if is_dataclass(x):
        return all(_equal(getattr(x, f.name), getattr(y, f.name)) for f in dc_fields(x))
    if hasattr(x, "__dict__"):
        return _equal(vars(x), vars(y))
    try:
        return bool(x == y)
    except (TypeError, ValueError):  # something that does not compare: not known to be equal
        return False


def _threads_per_task() -> int:
    import os

    try:
        from dask.distributed import get_worker

        slots = get_worker().state.nthreads
    except (ImportError, ValueError, AttributeError):  # not on a Dask worker
        slots = 1
    return max(1, (os.cpu_count() or 1) // max(1, slots))


def render_frame_task(source, frame, assets=None, write=None) -> Image | None:
    """Dask task: one whole frame, as the local ``tracer.render`` would give it; with ``write`` (a picklable
    ``write(image, frame)``), the worker writes it itself and returns None (nothing travels back)."""
    t0, c0 = time.perf_counter(), time.thread_time()
    p = prepare(_with_assets(source, assets), frame)
    t1, c1 = time.perf_counter(), time.thread_time()
    image = p.session.render(p.settings.with_(progress=False))
    image.stats.pop("ray_batches", None)
    # wall seconds, and CPU seconds of the task's thread (all of the render's with one thread per task)
    image.stats["farm"] = {"prepare_seconds": t1 - t0, "render_seconds": time.perf_counter() - t1,
                           "prepare_cpu": c1 - c0, "render_cpu": time.thread_time() - c1, "reused": p.reused}
    if write is not None:
        write(image, frame)
        return None
    return image


def render_tile_task(source, frame, tile, assets=None) -> tuple:
    """Dask task: the pixels of ``tile`` = (x0, y0, x1, y1) of one frame -> (tile, rgba, aovs)."""
    p = prepare(_with_assets(source, assets), frame)
    rgba, aovs = p.renderer.tile(p.settings, tile)
    return tile, rgba, aovs


class _TileRenderer:
    """Renders pixel rectangles of one prepared session into tile-sized arrays (memory bounded by the tile)."""

    def __init__(self, session):
        self.session = session
        self.scene = session.scene

    def tile(self, settings: RenderSettings, tile):
        """(rgba, aovs) of the rectangle ``tile``: :func:`tracer.integrator.tiles.render_tile`, as a local render
        traces it (adaptive sampling's rounds per tile of the renderer's grid, which the farm's tiles follow)."""
        from .integrator.tiles import render_tile

        img = render_tile(self.session, settings, tile)
        return img.rgba, img.aovs


# ---------------------------------------------------------------------------------------------------- client side
def frame_tiles(settings: RenderSettings, tile_size: int = DEFAULT_FARM_TILE) -> list:
    """Tile rectangles of a split frame, aligned to the renderer's own tile grid (so every pixel is traced in the
    same tile-relative order as locally; pixels do not depend on it, but this keeps the work per task even)."""
    step = max(settings.tile_size, (tile_size // settings.tile_size) * settings.tile_size)
    x0, y0, x1, y1 = settings.region or (0, 0, settings.width, settings.height)
    return [(x, y, min(x + step, x1), min(y + step, y1)) for y in range(y0, y1, step) for x in range(x0, x1, step)]


def render_frames(client, source, frames, *, assets=None, write=None, on_result=None):
    """Render ``frames`` of ``source`` as one Dask task each; yields :class:`FrameResult` in completion order.

    With ``write`` (a picklable ``write(image, frame)`` run on the worker, e.g. to a shared filesystem), results carry
    no image: nothing but the task's status returns to the client, which then costs nothing per frame.

    Only finished frames are held on the client (each is released from the cluster as soon as it arrives). A frame
    whose task raised yields a result with ``error`` set (once: tasks are not retried for their own errors)."""
    from dask.distributed import as_completed

    shipped = _ship(client, assets)
    futures = {}
    for frame in frames:
        fut = client.submit(render_frame_task, source, frame, shipped, write, key=f"whitted-frame-{_token(source)}-{frame}",
                            pure=False)
        futures[fut] = frame
    for fut in as_completed(list(futures)):
        frame = futures.pop(fut)
        try:
            result = FrameResult(frame, fut.result())
        except Exception as exc:  # noqa: BLE001 — the task's own error, reported per frame
            result = FrameResult(frame, None, _one_line(exc))
        fut.release()
        if on_result is not None:
            on_result(result)
        yield result


def render_tiled(client, source, frame=None, *, tile_size: int = DEFAULT_FARM_TILE, assets=None,
                 on_tile=None) -> Image:
    """Render one frame split into tile tasks and assemble it on the client.

    Tiles stream back as they finish and are copied into the image at once, so the client holds the image plus the
    tiles in transit, not every task's result. Raises :class:`FarmError` if a tile fails. With
    ``settings.denoise`` the tiles bring the denoiser's guides and the client denoises the assembled frame (the
    filter looks across tile borders: never tile by tile)."""
    from dask.distributed import as_completed

    shipped = _ship(client, assets)
    settings = client.submit(_settings_task, source, frame, shipped, pure=False).result()
    if settings.denoise:  # the client denoises the assembled frame: no library here is an error before the tiles
        check_denoiser()
    tiles = frame_tiles(settings, tile_size)
    h, w = settings.height, settings.width
    from .integrator.tiles import empty_aovs

    image = Image(rgba=np.zeros((h, w, 4), np.float32), aovs=empty_aovs(settings, h, w))
    start = time.perf_counter()
    futs = [client.submit(render_tile_task, source, frame, t, shipped, key=f"whitted-tile-{_token(source)}-{frame}-{t}",
                          pure=False) for t in tiles]
    for fut in as_completed(futs):
        try:
            (x0, y0, x1, y1), rgba, aovs = fut.result()
        except Exception as exc:  # noqa: BLE001
            for f in futs:
                f.cancel()
            raise FarmError(f"frame {frame}: a tile failed: {_one_line(exc)}") from None
        fut.release()
        image.rgba[y0:y1, x0:x1] = rgba
        for name, a in aovs.items():
            image.aovs[name][y0:y1, x0:x1] = a
        if on_tile is not None:
            on_tile((x0, y0, x1, y1))
    image.stats = {"seconds": time.perf_counter() - start, "tiles": len(tiles)}
    if settings.denoise:
        prefilter = client.submit(_prefilter_task, source, frame, shipped, pure=False).result()
        denoise_image(image, settings, prefilter=prefilter)
        image.stats["seconds"] = time.perf_counter() - start
    return image


def _settings_task(source, frame, assets=None) -> RenderSettings:
    return prepared(_with_assets(source, assets), frame)[1]


def _prefilter_task(source, frame, assets=None) -> str:
    """How the client's denoise treats the frame's guides (tracer.integrator.tiles.guide_prefilter of the worker's
    scene)."""
    from .integrator.tiles import guide_prefilter

    return guide_prefilter(prepared(_with_assets(source, assets), frame)[0])


def _with_assets(source, assets):
    """A source reading the shipped package ``assets`` (bytes) instead of its own path, when one was shipped."""
    return source if assets is None else source.unpacked(assets)


def _ship(client, assets):
    """Send a package's bytes to every worker once; tasks receive it as an argument (None: nothing shipped)."""
    if assets is None:
        return None
    return client.scatter(assets, broadcast=True, hash=True)


def _token(source) -> str:
    from dask.base import tokenize

    return tokenize(source)


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text

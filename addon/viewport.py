"""The viewport's Rendered mode without freezing Blender: a long-lived session traced on a background thread, the
latest finished pass drawn.

:class:`ViewportRender` owns one worker thread and one :class:`tracer.Session`. ``view_update`` hands it the
edits :class:`addon.sync.SceneSync` made from ``depsgraph.updates`` (:meth:`ViewportRender.edit`; the first one
is a rebuild from a full export), ``view_draw`` hands it the current view camera and size
(:meth:`ViewportRender.set_view`) and draws whatever frame is ready (:meth:`ViewportRender.latest`) — neither
ever traces or edits the session: the worker applies the edits between two passes, so a camera move costs no
scene work at all and a material edit only a repack.

With viewport denoising on (:meth:`ViewportRender.set_denoise`: Render Properties > Denoise > Viewport, as Cycles'),
each full-resolution pass with at least the Start Sample's samples per pixel is denoised before it is shown, as
Cycles' viewport does it: Open Image Denoise guided by the albedo only, guides not prefiltered, "balanced" quality
(Cycles' viewport defaults), on the worker thread.

The worker refines progressively: coarse pixels first (:func:`levels`: as Cycles' viewport, the first pass is about
:data:`START_RESOLUTION` pixels across, at least every 8th pixel; then every 4th, 2nd pixel, then all), then more
anti-aliasing samples (:data:`AA_PASSES`), each pass a fixed N×N per pixel (the scene's adaptive sampling is for
F12: a pass of at most 3×3 samples leaves a round nothing to skip). Any change (camera, size, edits, settings)
cancels the pass in flight (the tracer polls ``cancelled`` between tiles and depths) and starts again from the
coarsest level. Each finished pass replaces the frame and calls ``on_frame`` (the engine's ``tag_redraw``: as
Cycles' session does from its thread, it only sets a flag Blender's main loop polls).
"""

from __future__ import annotations

import collections
import threading
import time
from dataclasses import dataclass

import numpy as np

from . import kernels
from .export import tracer
from .sync import Edit, apply_edits

#: Pixel-size factors of the refinement passes, coarse to full resolution, for viewports up to 512 pixels across
#: (:func:`levels` starts coarser in larger ones).
LEVELS = (8, 4, 2, 1)
#: The first pass is about this many pixels across (Cycles' viewport "start resolution" does the same: 64).
START_RESOLUTION = 64
#: N×N anti-aliasing of the passes after the full-resolution one.
AA_PASSES = (2, 3)
#: Embree build quality of the viewport's session: builds (and rebuilds after edits) fastest.
QUALITY = "low"
#: Embree layout of the viewport's session (tracer.Session(instanced=...)): every object an instance of its own BVH,
#: so a move is a matrix and an edited mesh rebuilds only its BVH (docs/benchmarks.md: measured against flat).
INSTANCED = True


@dataclass
class Frame:
    """A finished pass: scene-linear RGBA (h, w, 4) for a view of ``size`` at ``level``, with ``samples`` N×N.
    ``changed`` is when the change it shows reached the worker (time.perf_counter), ``done`` when it finished."""

    rgba: np.ndarray
    key: tuple
    level: int
    samples: int
    generation: int
    changed: float = 0.0
    done: float = 0.0
    #: Whether the pass was denoised (:meth:`ViewportRender.set_denoise`).
    denoised: bool = False
    #: The pixels as the GPU texture wants them (bottom row first, flat float32), made on the worker thread so
    #: view_draw only uploads them.
    flat: np.ndarray | None = None


class ViewportRender:
    """Progressive rendering of one viewport on a worker thread (see the module docstring)."""

    def __init__(self, on_frame=None, settings: "tracer.RenderSettings | None" = None, quality: str = QUALITY,
                 instanced: bool = INSTANCED):
        self.on_frame = on_frame or (lambda: None)
        self.quality = quality
        self.instanced = instanced
        self._lock = threading.Condition()
        self._edits: list = []
        self._settings = settings or tracer.RenderSettings()
        self._denoise: int | None = None  # samples per pixel from which a full-resolution pass is denoised
        self._camera = None
        self._size = None
        self._generation = 0
        self._changed = time.perf_counter()
        self._frame: Frame | None = None
        self._stop = False
        self.session: "tracer.Session | None" = None
        #: Set when edits could not be applied (the session was dropped): the caller's sync must export everything
        #: again (engine.view_update resets it).
        self.lost = False
        self.passes_done = 0
        #: (generation, level, samples, changed, done) of the recent passes, for benchmarks and tests.
        self.history: collections.deque = collections.deque(maxlen=512)
        self.edits_applied: list[str] = []
        self.errors: list[str] = []
        self._thread = threading.Thread(target=self._run, name="whitted-viewport", daemon=True)
        self._thread.start()

    # ---------------------------------------------------------------------------------------------- main thread
    def edit(self, edits: list) -> None:
        """Session edits (from :meth:`addon.sync.SceneSync.update`) for the worker to apply before its next pass;
        restarts the refinement. An empty list changes nothing."""
        if not edits:
            return
        with self._lock:
            self._edits.extend(edits)
            self._restart()

    def set_scene(self, scene: "tracer.Scene", settings: "tracer.RenderSettings | None" = None) -> None:
        """A whole new scene (a new session is built on the worker), and optionally settings."""
        with self._lock:
            self._edits = [Edit("rebuild", (scene,))]
            if settings is not None:
                self._settings = settings
            self._restart()

    def set_settings(self, settings: "tracer.RenderSettings") -> bool:
        """New render settings (samples, depth, ...); restarts only if they differ. Returns True if it did."""
        with self._lock:
            if settings == self._settings:
                return False
            self._settings = settings
            self._restart()
            return True

    def set_denoise(self, start: int | None) -> bool:
        """Denoise each full-resolution pass with at least ``start`` samples per pixel (None: none); restarts only
        if it differs. Returns True if it did."""
        start = None if start is None else max(1, int(start))
        with self._lock:
            if start == self._denoise:
                return False
            self._denoise = start
            self._restart()
            return True

    def set_view(self, camera: "tracer.Camera", size: tuple) -> bool:
        """The view to render; restarts only when it differs from the current one. Returns True if it did."""
        key = _view_key(camera, size)
        with self._lock:
            if self._camera is not None and _view_key(self._camera, self._size) == key:
                return False
            self._camera, self._size = camera, tuple(size)
            self._restart()
            return True

    def latest(self) -> Frame | None:
        """The newest finished pass (possibly of an earlier view: drawn until a new one is ready), or None."""
        with self._lock:
            return self._frame

    def stop(self) -> None:
        with self._lock:
            self._stop = True
            self._generation += 1
            self._lock.notify_all()
        if self._thread is not threading.current_thread():
            self._thread.join(timeout=10)
        if self.session is not None and not self._thread.is_alive():
            self.session.close()
            self.session = None

    def wait_until_converged(self, timeout: float = 60.0) -> bool:
        """Block until the last pass of the current view is done (for tests and benchmarks)."""
        with self._lock:
            return self._lock.wait_for(lambda: self._converged() or self._stop, timeout=timeout) and not self._stop

    def first_pass_seconds(self) -> float | None:
        """For the current generation: seconds from the change to its first (coarsest) finished pass."""
        with self._lock:
            gen = self._generation
            for g, level, samples, changed, done in self.history:
                if g == gen:
                    return done - changed
        return None

    def wait_for(self, predicate, timeout: float = 60.0) -> bool:
        """Block until ``predicate(latest frame)`` holds for a frame of the current generation (tests, benchmarks)."""
        def ok():
            f = self._frame
            return self._stop or (f is not None and f.generation == self._generation and predicate(f))

        with self._lock:
            return self._lock.wait_for(ok, timeout=timeout) and not self._stop

    # ---------------------------------------------------------------------------------------------- worker
    def _restart(self):
        self._generation += 1
        self._changed = time.perf_counter()
        self._lock.notify_all()

    def _converged(self):
        f = self._frame
        return (f is not None and f.generation == self._generation and f.level == 1
                and f.samples == AA_PASSES[-1])

    def _ready(self):
        return (self.session is not None or self._edits) and self._camera is not None and self._size is not None

    @staticmethod
    def passes(size=(0, 0)):
        """(level, samples) of every refinement pass of a ``size`` viewport, in order."""
        return [(level, 1) for level in levels(size)] + [(1, n) for n in AA_PASSES]

    def _run(self):
        # a first use of this version: the kernels are prepared in a separate process (addon/kernels.py)
        if not kernels.wait(cancelled=lambda: self._stop):
            return
        while True:
            with self._lock:
                self._lock.wait_for(lambda: self._stop or (self._ready() and (self._edits or not self._converged())))
                if self._stop:
                    return
                gen, camera, size, base, changed, start = (self._generation, self._camera, self._size,
                                                           self._settings, self._changed, self._denoise)
                edits, self._edits = self._edits, []
            if edits:
                try:
                    self.session = apply_edits(self.session, edits, quality=self.quality,
                                               instanced=self.instanced, cancelled=lambda: self._stop)
                    self.edits_applied.extend(e.kind for e in edits)
                except tracer.RenderCancelled:  # stopped while building: the viewport is closing
                    continue
                except Exception as exc:  # keep the message; the sync must start again from a full export
                    self.session = None
                    self.lost = True
                    self._fail(exc, gen)
                    continue
            session = self.session
            if session is None:
                continue
            if session.scene.camera is not camera:
                session.update_camera(camera)
            passes = self.passes(size)
            for index, (level, samples) in enumerate(passes):
                f = self._frame
                if f is not None and f.generation == gen and index <= passes.index((f.level, f.samples)):
                    continue  # (woken up without a change: passes already done)
                if self._generation != gen:
                    break
                w, h = max(1, size[0] // level), max(1, size[1] // level)
                denoise = start is not None and level == 1 and samples * samples >= start
                # Fixed counts: each pass is a whole N×N (1, 2, 3), too few samples for adaptive sampling's rounds
                settings = base.with_(width=w, height=h, samples=samples, region=None, progress=False,
                                      aovs=("denoising_albedo",) if denoise else (), denoise=False,
                                      adaptive_threshold=0.0)
                try:
                    image = session.render(settings, cancelled=lambda g=gen: self._generation != g)
                    if denoise:
                        denoise = self._denoised(image, settings.threads)
                except tracer.RenderCancelled:
                    break
                except Exception as exc:  # never let the thread die silently: keep the message, show nothing new
                    self._fail(exc, gen)
                    break
                flat = np.ascontiguousarray(image.rgba[::-1], np.float32).reshape(-1)
                with self._lock:
                    if self._generation != gen:
                        break
                    self._frame = Frame(rgba=image.rgba, key=_view_key(camera, size), level=level, samples=samples,
                                        generation=gen, changed=changed, done=time.perf_counter(), flat=flat,
                                        denoised=denoise)
                    self.passes_done += 1
                    self.history.append((gen, level, samples, changed, self._frame.done))
                    self._lock.notify_all()
                try:
                    self.on_frame()
                except Exception:  # the engine may be gone (viewport closed): nothing to tell
                    pass

    def _denoised(self, image, threads: int | None = None) -> bool:
        """Denoise a pass in place as Cycles' viewport does (albedo guide, no prefilter, balanced quality), on the
        render's ``threads``; False, with the reason printed once, where no OIDN library loads (the noisy pass is
        shown)."""
        try:
            image.rgba[:] = tracer.denoise.denoise(image.rgba, image.aovs["denoising_albedo"], prefilter="fast",
                                                   quality="balanced", threads=threads)
            return True
        except tracer.denoise.DenoiseUnavailable as exc:
            if str(exc) not in self.errors:
                self.errors.append(str(exc))
                print(f"Whitted viewport: {exc}")
            return False

    def _fail(self, exc, gen):
        self.errors.append(str(exc))
        print(f"Whitted viewport: {exc}")
        with self._lock:
            self._lock.wait_for(lambda: self._generation != gen or self._stop)


def levels(size) -> tuple:
    """Pixel-size factors of the refinement passes of a ``size`` viewport: powers of two from the one that makes
    the first pass about :data:`START_RESOLUTION` pixels across (at least 8) down to 1."""
    first = LEVELS[0]
    while max(size) / first > 1.5 * START_RESOLUTION:
        first *= 2
    out = []
    while first >= 1:
        out.append(first)
        first //= 2
    return tuple(out)


def _view_key(camera, size) -> tuple:
    return (tuple(size), camera.projection, tuple(np.round(np.asarray(camera.camera_to_world).ravel(), 7)),
            round(camera.focal_length, 7), round(camera.horizontal_aperture, 7), round(camera.vertical_aperture, 7),
            round(camera.horizontal_aperture_offset, 7), round(camera.vertical_aperture_offset, 7))

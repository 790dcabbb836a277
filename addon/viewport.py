"""The viewport's Rendered mode without freezing Blender: tracing on a background thread, drawing the latest frame.

:class:`ViewportRender` owns one worker thread. ``view_update`` hands it a freshly exported scene (only when the
depsgraph reports a change other than the view itself), ``view_draw`` hands it the current view camera and size and
draws whatever frame is ready — it never traces. The thread refines progressively: coarse pixels first
(:data:`LEVELS`: every 8th, 4th, 2nd pixel, then all), then more anti-aliasing samples (:data:`AA_PASSES`); any
change (camera, size, scene, settings) cancels the pass in flight (the tracer polls ``cancelled`` between tiles
and depths) and starts again from the coarsest level. Each finished pass replaces the frame and calls
``on_frame`` (the engine's ``tag_redraw``, as Cycles' session does from its thread).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from .export import tracer

#: Pixel-size factors of the refinement passes, coarse to full resolution.
LEVELS = (8, 4, 2, 1)
#: N×N anti-aliasing of the passes after the full-resolution one.
AA_PASSES = (2, 3)


@dataclass
class Frame:
    """A finished pass: scene-linear RGBA (h, w, 4) for a view of ``size`` at ``level``, with ``samples`` N×N."""

    rgba: np.ndarray
    key: tuple
    level: int
    samples: int
    generation: int


class ViewportRender:
    """Progressive rendering of one viewport on a worker thread (see the module docstring)."""

    def __init__(self, on_frame=None, settings: "tracer.RenderSettings | None" = None):
        self.on_frame = on_frame or (lambda: None)
        self._lock = threading.Condition()
        self._scene = None
        self._settings = settings or tracer.RenderSettings()
        self._camera = None
        self._size = None
        self._generation = 0
        self._frame: Frame | None = None
        self._stop = False
        self.passes_done = 0
        self.errors: list[str] = []
        self._accel = None  # (scene, its Accelerator): kept while only the view changes
        self._thread = threading.Thread(target=self._run, name="whitted-viewport", daemon=True)
        self._thread.start()

    # ---------------------------------------------------------------------------------------------- main thread
    def set_scene(self, scene: "tracer.Scene", settings: "tracer.RenderSettings | None" = None) -> None:
        """A new exported scene (and settings): restart the refinement."""
        with self._lock:
            self._scene = scene
            if settings is not None:
                self._settings = settings
            self._restart()

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
            self._thread.join(timeout=5)

    def wait_until_converged(self, timeout: float = 60.0) -> bool:
        """Block until the last pass of the current view is done (for tests and benchmarks)."""
        with self._lock:
            return self._lock.wait_for(lambda: self._converged() or self._stop, timeout=timeout) and not self._stop

    # ---------------------------------------------------------------------------------------------- worker
    def _restart(self):
        self._generation += 1
        self._lock.notify_all()

    def _converged(self):
        f = self._frame
        return (f is not None and f.generation == self._generation and f.level == 1
                and f.samples == AA_PASSES[-1])

    def _passes(self):
        return [(level, 1) for level in LEVELS] + [(1, n) for n in AA_PASSES]

    def _run(self):
        while True:
            with self._lock:
                self._lock.wait_for(lambda: self._stop or (self._ready() and not self._converged()))
                if self._stop:
                    return
                gen, scene, camera, size, base = (self._generation, self._scene, self._camera, self._size,
                                                  self._settings)
            if self._accel is None or self._accel[0] is not scene:  # one BVH per exported scene, built here
                try:
                    self._accel = (scene, tracer.accel.Accelerator(scene))
                except Exception as exc:  # keep the message; wait for the next change
                    self._fail(exc, gen)
                    continue
                done = self._frame.level if self._frame is not None and self._frame.generation == gen else None
            for level, samples in self._passes():
                if done is not None and (level, samples) <= (self._frame.level, self._frame.samples):
                    continue
                if self._generation != gen:
                    break
                w, h = max(1, size[0] // level), max(1, size[1] // level)
                settings = base.with_(width=w, height=h, samples=samples, region=None, aovs=(), progress=False)
                scene.camera = camera
                try:
                    image = tracer.render(scene, settings, cancelled=lambda g=gen: self._generation != g,
                                          accel=self._accel[1])
                except tracer.RenderCancelled:
                    break
                except Exception as exc:  # never let the thread die silently: keep the message, show nothing new
                    self._fail(exc, gen)
                    break
                with self._lock:
                    if self._generation != gen:
                        break
                    self._frame = Frame(rgba=image.rgba, key=_view_key(camera, size), level=level, samples=samples,
                                        generation=gen)
                    self.passes_done += 1
                    self._lock.notify_all()
                try:
                    self.on_frame()
                except Exception:  # the engine may be gone (viewport closed): nothing to tell
                    pass

    def _fail(self, exc, gen):
        self.errors.append(str(exc))
        print(f"Whitted viewport: {exc}")
        with self._lock:
            self._lock.wait_for(lambda: self._generation != gen or self._stop)

    def _ready(self):
        return self._scene is not None and self._camera is not None and self._size is not None


def _view_key(camera, size) -> tuple:
    return (tuple(size), camera.projection, tuple(np.round(np.asarray(camera.camera_to_world).ravel(), 7)),
            round(camera.focal_length, 7), round(camera.horizontal_aperture, 7), round(camera.vertical_aperture, 7),
            round(camera.horizontal_aperture_offset, 7), round(camera.vertical_aperture_offset, 7))

"""The Whitted render engine: F12 exports the evaluated depsgraph and traces it, tile by tile, into Blender's
render result (with Persistent Data on, it keeps the session and syncs only what changed, addon/sync.py); the
viewport's Rendered shading keeps a session on a worker thread and draws its newest progressive pass
(addon/viewport.py), where a GPU context exists, and fails soft where it does not.

The last final render's tracer statistics (ray counts per type, timings) and export warnings are kept in
``WhittedRenderEngine.last_render`` (a :class:`RenderReport`), for tests and for the curious; tests stop a render
as Esc would with ``WhittedRenderEngine.break_hook``.
"""

from __future__ import annotations

import queue
import threading
import time
import weakref
from dataclasses import dataclass

import bpy
import numpy as np

from . import export, kernels, passes, sync, viewport
from .bundled import tracer
from .export import viewport_camera

#: Blender pass name, channels, channel ids, type — for each tracer AOV (from the one table, addon/passes.py).
PASSES = {p.aov: p.register_args for p in passes.PASSES}
#: Depth Blender writes where nothing was hit.
NO_DEPTH = 1.0e10
#: Seconds between two polls of Esc (``test_break``) while the tracer builds and traces (:meth:`_Job.run`).
POLL_SECONDS = 0.05


class WhittedRenderEngine(bpy.types.RenderEngine):
    bl_idname = "WHITTED"
    bl_label = "Whitted"
    bl_use_preview = True
    bl_use_shading_nodes_custom = False
    bl_use_eevee_viewport = False

    #: What the last final render (of any instance) did: a :class:`RenderReport`.
    last_render: "RenderReport" = None
    #: Test seam: a callable polled with ``test_break`` (True ends the render as Esc would). None in normal use.
    break_hook = None

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._view = None  # the viewport's worker (addon/viewport.py) and its scene sync
        self._sync = None
        self._final_session = None  # F12 with Persistent Data: the session kept between renders, and its sync
        self._final_sync = None

    # ---------------------------------------------------------------------------------------------- passes
    def update_render_passes(self, scene=None, renderlayer=None):
        self.register_pass(scene, renderlayer, "Combined", 4, "RGBA", "COLOR")
        for p in passes.asked(renderlayer, getattr(scene, "whitted", None)):
            self.register_pass(scene, renderlayer, *p.register_args)

    # ---------------------------------------------------------------------------------------------- F12
    def render(self, depsgraph):
        """F12 and the material preview: three paths, as Cycles has them. A preview renders a small, cheap image;
        a final render exports the scene and traces it (:func:`tracer.render`: Esc reaches the export, the Embree
        build and the tiles); with Persistent Data the session is kept and only changes are synced."""
        if self.is_preview:
            return self._render_preview(depsgraph)
        if depsgraph.scene.render.use_persistent_data:
            return self._render_persistent(depsgraph)
        self._drop_final_session()
        return self._render_final(depsgraph)

    def _render_preview(self, depsgraph):
        """The material preview: at most 2×2 samples, 4 light samples, depth 4, no AOVs; a grey image on error."""
        s = export.settings_from_scene(depsgraph.scene, view_layer=depsgraph.view_layer)
        job = _Job(self, depsgraph, s.with_(samples=min(s.samples, 2), light_samples=4, sky_samples=0,
                                            max_depth=min(s.max_depth, 4), region=None, aovs=(), denoise=False))
        try:
            scene, _ = export.scene_from_depsgraph(depsgraph, width=job.settings.width, height=job.settings.height,
                                                   cancelled=job.cancelled)
            job.run(lambda: tracer.render(scene, job.settings, on_tile=job.tile_writer(scene),
                                          cancelled=job.cancelled))
        except (export.ExportCancelled, tracer.RenderCancelled):
            if not job.tiles_written:  # (Blender 5.0 crashes on a result no tile was written into)
                self._write_empty(job.settings, job.layer)
        except Exception as exc:  # a scene we cannot export: say why, show grey
            self.report({"ERROR"}, f"Whitted: {exc}")
            self._fill_preview(export.render_size(depsgraph.scene))

    def _render_final(self, depsgraph):
        """F12: export the evaluated depsgraph, build its Embree scene and render it (a :class:`tracer.Session`
        for one render, laid out as :func:`tracer.render` lays it out). Esc is looked at right before and right
        after the build, besides while it runs: a build that finishes as Esc comes traces nothing."""
        job = _Job(self, depsgraph)
        try:
            scene, warnings = export.scene_from_depsgraph(depsgraph, width=job.settings.width,
                                                          height=job.settings.height, cancelled=job.cancelled,
                                                          frame_set=self.frame_set)
        except export.ExportCancelled:
            return job.stopped("export")
        except Exception as exc:  # a scene we cannot export: say why, leave an empty result
            return self.report({"ERROR"}, f"Whitted: {exc}")
        job.exported(warnings)
        if not job.ready():
            return
        try:
            session = job.run(lambda: tracer.Session(scene, instanced=False, cancelled=job.cancelled))
        except tracer.RenderCancelled:
            return job.stopped("build")
        except Exception as exc:
            self._write_empty(job.settings, job.layer)
            return self.report({"ERROR"}, f"Whitted: {exc}")
        try:
            if job.cancelled():  # Esc as the build finished: nothing traced
                return job.stopped("build")
            job.extra["bvh_seconds"] = session.stats["build_seconds"]
            job.trace(lambda on_tile: session.render(job.settings, on_tile=on_tile, cancelled=job.cancelled),
                      scene)
        finally:
            session.close()

    def _render_persistent(self, depsgraph):
        """F12 with Persistent Data (Render Properties > Performance > Final Render, as Cycles): Blender keeps this
        engine between F12s, and the session with it; ``depsgraph.updates`` says what changed since the last."""
        job = _Job(self, depsgraph)
        first = self._final_sync is None
        self.update_stats("", "Whitted: exporting scene" if first else "Whitted: syncing changes (Persistent Data)")
        if first:
            self._final_sync = sync.SceneSync(quality="medium")
        stage = "export"
        try:
            edits = self._final_sync.update(depsgraph, width=job.settings.width, height=job.settings.height,
                                            cancelled=job.cancelled)
            if job.cancelled():
                raise export.ExportCancelled("export cancelled")
            stage = "build"
            kept = self._final_session
            self._final_session = job.run(lambda: sync.apply_edits(kept, edits, quality="medium",
                                                                   cancelled=job.cancelled))
            if job.cancelled():  # Esc right after the build: nothing traced, the (complete) session kept
                return job.stopped("build")
        except (export.ExportCancelled, tracer.RenderCancelled):  # Esc: nothing traced, nothing half-synced kept
            self._drop_final_session()
            return job.stopped(stage)
        except Exception as exc:
            self._drop_final_session()
            return self.report({"ERROR"}, f"Whitted: {exc}")
        session, synced = self._final_session, self._final_sync
        job.exported(synced.warnings, synced.pass_indices, sync=dict(synced.stats),
                     bvh_seconds=session.stats["build_seconds"])
        job.trace(lambda on_tile: session.render(job.settings, on_tile=on_tile, cancelled=job.cancelled),
                  session.scene)

    def _write_empty(self, settings, layer_name):
        """A black result for a render stopped before its first tile (Blender 5.0 crashes writing a result no
        tile was ever written into)."""
        x0, y0, x1, y1 = settings.region or (0, 0, settings.width, settings.height)
        result = self.begin_result(0, 0, x1 - x0, y1 - y0, layer=layer_name)
        self.end_result(result)

    def _drop_final_session(self):
        if self._final_session is not None:
            self._final_session.close()
        self._final_session = None
        self._final_sync = None

    def _fill_preview(self, size):
        """Fallback for the material preview: a flat mid-grey image, so the preview never shows garbage."""
        w, h = size
        result = self.begin_result(0, 0, w, h)
        rgba = np.tile(np.array([0.18, 0.18, 0.18, 1.0], np.float32), w * h)
        result.layers[0].passes["Combined"].rect.foreach_set(rgba)
        self.end_result(result)

    def _record(self, report: "RenderReport") -> None:
        type(self).last_render = report

    # ---------------------------------------------------------------------------------------------- viewport
    def view_update(self, context, depsgraph):
        """A depsgraph change (view changes only reach view_draw): turn ``depsgraph.updates`` into session edits
        on this (the main) thread, since bpy data is not thread-safe (addon/sync.py), and hand them to the worker
        thread, which applies them between two passes and traces (addon/viewport.py). Never traces here."""
        try:
            region = context.region
            camera = viewport_camera(context.region_data)
            if self._view is None:
                self._view = viewport.ViewportRender(on_frame=_redraw_callback(self))
                self._sync = sync.SceneSync(quality=viewport.QUALITY, track_camera=False)
            if self._view.lost:  # the worker could not apply earlier edits: start again from a full export
                self._view.lost = False
                self._sync.reset()
            edits = self._sync.update(depsgraph, width=region.width, height=region.height, camera=camera)
            self._view.set_settings(viewport_settings(depsgraph.scene))
            self._view.set_denoise(viewport_denoise(depsgraph.scene))
            self._view.edit(edits)
        except Exception as exc:  # never crash Blender from the viewport
            print(f"Whitted viewport: {exc}")

    def view_draw(self, context, depsgraph):
        """Draw the newest finished pass; tell the worker about the current view (it restarts if it moved).
        Never traces, never touches the session."""
        try:
            if self._view is None:
                self.view_update(context, depsgraph)
                if self._view is None:
                    return
            region = context.region
            self._view.set_view(viewport_camera(context.region_data), (region.width, region.height))
            frame = self._view.latest()
            if frame is not None:
                self._draw_frame(frame, region, depsgraph)
        except Exception as exc:  # no GPU context (background mode) or anything else: fail soft
            print(f"Whitted viewport: {exc}")

    def _draw_frame(self, frame, region, depsgraph):
        import gpu
        from gpu_extras.presets import draw_texture_2d

        if getattr(self, "_texture_of", None) is not frame:  # upload each finished pass once
            h, w = frame.rgba.shape[:2]
            data = frame.flat  # bottom row first, flat float32: prepared by the worker thread
            self._texture = gpu.types.GPUTexture((w, h), format="RGBA32F",
                                                 data=gpu.types.Buffer("FLOAT", data.size, data))
            self._texture_of = frame
        gpu.state.blend_set("ALPHA_PREMULT")
        self.bind_display_space_shader(depsgraph.scene)
        draw_texture_2d(self._texture, (0, 0), region.width, region.height)
        self.unbind_display_space_shader()
        gpu.state.blend_set("NONE")

    def __del__(self):
        try:
            v = getattr(self, "_view", None)
            s = getattr(self, "_final_session", None)
        except ReferenceError:  # Blender freed the engine's RNA first (at unregister): Python keeps nothing to stop
            return
        if v is not None:
            v.stop()
        if s is not None:
            s.close()


@dataclass(frozen=True)
class RenderReport:
    """What a final render did: the tracer's statistics (``image.stats``: rays per type, seconds; plus
    ``export_seconds``, ``bvh_seconds``, ``persistent``, ``sync``, ``tiles_written``, and ``cancelled: True`` when Esc
    stopped it after some tiles were written; or ``{"cancelled": True, "cancelled_in": "export" | "kernels" | "build" |
    "tiles"}`` when Esc stopped it before a tile was written: then the result is black) and the export's warnings."""

    stats: dict
    warnings: tuple = ()


class _Job:
    """One render of the engine: its settings, Esc (``test_break``, and ``break_hook`` in tests), and the tiles
    written into Blender's render result as they finish.

    Blender's API is called only from the thread Blender called ``render()`` on. The tracer's work (the Embree build
    and the tiles) runs on a helper thread (:meth:`run`) while that thread polls Esc every :data:`POLL_SECONDS` and
    writes the finished tiles: so Esc is seen during a long build or a long first tile, not only when the tracer
    next asks, and no tile is written once Esc was seen."""

    def __init__(self, engine, depsgraph, settings=None):
        self.engine = engine
        self.layer = depsgraph.view_layer.name
        self.settings = settings or export.settings_from_scene(depsgraph.scene, view_layer=depsgraph.view_layer)
        self.persistent = bool(depsgraph.scene.render.use_persistent_data) and not engine.is_preview
        self.warnings: list = []
        self.pass_indices = None
        self.extra: dict = {}
        self._stop = False
        self._main = threading.current_thread()
        self._t0 = time.perf_counter()
        self.export_seconds = 0.0
        self.tiles_written = 0
        self._tiles: queue.SimpleQueue = queue.SimpleQueue()  # tiles the tracer finished, for this thread to write

    def cancelled(self) -> bool:
        # Only the render thread asks Blender (test_break); the tracer's threads read the flag it sets.
        if not self._stop and threading.current_thread() is self._main:
            hook = type(self.engine).break_hook
            self._stop = bool(self.engine.test_break() or (hook is not None and hook()))
        return self._stop

    def run(self, work):
        """``work()`` (a build or a render: it calls :meth:`cancelled` and the tile writer) on a helper thread; this
        thread polls Esc meanwhile and writes the tiles it hands over, until Esc (then it writes no more) or the end.
        Returns what ``work`` returned, or raises what it raised (``RenderCancelled`` after Esc: the tracer polls the
        flag between objects, inside Embree's builds, between tiles and between depths, so it ends promptly)."""
        done = object()
        box = {}

        def body():
            try:
                box["value"] = work()
            except BaseException as exc:  # handed to the render thread, raised there
                box["error"] = exc
            finally:
                self._tiles.put(done)

        helper = threading.Thread(target=body, name="whitted-render", daemon=True)
        helper.start()
        try:
            while True:
                try:
                    item = self._tiles.get(timeout=POLL_SECONDS)
                except queue.Empty:
                    item = None
                if self.cancelled():  # Esc: the queued and later tiles are dropped, the helper winds down
                    if item is done:
                        break
                    continue
                if item is done:
                    break
                if item is not None:
                    self._write_tile(*item)
        except BaseException:
            self._stop = True  # (a failed tile write, say) the helper stops at its next poll
            raise
        finally:
            helper.join()
        if "error" in box:
            raise box["error"]
        return box.get("value")

    def stopped(self, stage: str) -> None:
        """Esc before the first tile (in the export or the Embree build): a black result, and the report."""
        self.engine._write_empty(self.settings, self.layer)
        self.engine._record(RenderReport({"cancelled": True, "cancelled_in": stage}))

    def exported(self, warnings, pass_indices=None, **stats) -> None:
        """The scene is exported (or synced): its warnings reported, ``stats`` kept for the report."""
        self.export_seconds = time.perf_counter() - self._t0
        self.warnings, self.pass_indices, self.extra = list(warnings), pass_indices, stats
        for w in self.warnings:
            self.engine.report({"WARNING"}, f"Whitted: {w}")

    def ready(self) -> bool:
        """The kernels are ready and Esc was not pressed (else the render is recorded as stopped: False).

        The first render of a new version waits for the kernels, prepared in a separate process since the add-on
        was enabled (addon/kernels.py); sleeping here keeps Blender responsive and Esc works."""
        if not kernels.wait(cancelled=self.cancelled, on_status=lambda text: self.engine.update_stats("", text)):
            self.stopped("kernels")
            return False
        if self.cancelled():  # Esc before the Embree build (or before the tiles of a kept session): nothing traced
            self.stopped("build")
            return False
        return True

    def trace(self, run, scene) -> None:
        """``run(on_tile)`` renders (a session's render); the report is recorded."""
        engine = self.engine
        if not self.ready():
            return
        engine.update_stats("", f"Whitted: tracing {len(scene.triangles):,} triangles, {len(scene.lights)} lights")
        try:
            on_tile = self.tile_writer(scene)
            image = self.run(lambda: run(on_tile))
        except tracer.RenderCancelled as stopped:
            if stopped.image is None or not self.tiles_written:  # in the build, or before a tile was written
                return self.stopped("build" if stopped.image is None else "tiles")
            image = stopped.image
            image.stats["cancelled"] = True
        except Exception as exc:
            if not self.tiles_written:
                self.engine._write_empty(self.settings, self.layer)
            return engine.report({"ERROR"}, f"Whitted: render failed: {exc}")
        if self._stop and "cancelled" not in image.stats:  # Esc after the last tile was traced, before it was written
            if not self.tiles_written:
                return self.stopped("tiles")
            image.stats["cancelled"] = True
        stats = dict(image.stats, export_seconds=self.export_seconds, persistent=self.persistent,
                     tiles_written=self.tiles_written, **self.extra)
        engine._record(RenderReport(stats, tuple(self.warnings)))
        engine.update_stats("", f"Whitted: {stats['rays']['total']:,} rays in {stats['seconds']:.2f} s")

    def tile_writer(self, scene):
        """``on_tile(image, tile)`` for the tracer (on :meth:`run`'s helper thread): the tile's pixels and passes,
        copied, handed to the render thread, which writes them into Blender's result (:meth:`_write_tile`)."""
        settings = self.settings
        pass_indices = self.pass_indices if self.pass_indices is not None else scene.object_pass_indices
        if pass_indices is None:
            pass_indices = np.arange(len(scene.object_names), dtype=np.int32)
        self._tiles_total = len(tracer.tiles_of(settings))

        def on_tile(image, tile):
            if self._stop:
                return
            tx0, ty0, tx1, ty1 = tile
            layers = {"Combined": np.ascontiguousarray(image.rgba[ty0:ty1, tx0:tx1][::-1], np.float32)}
            for aov, (pname, _, _, _) in PASSES.items():
                if aov not in image.aovs:
                    continue
                data = image.aovs[aov][ty0:ty1, tx0:tx1][::-1]
                if aov == "depth":
                    data = _tile_z(scene.camera, image.aovs["depth"], tile, settings.width, settings.height)[::-1]
                elif aov == "objectid":
                    ids = data
                    data = np.zeros(ids.shape, np.float32)
                    ok = (ids >= 0) & (ids < len(pass_indices))
                    data[ok] = pass_indices[ids[ok]]
                elif aov == "sample_count":  # Cycles' Debug Sample Count: the share of the N×N budget taken
                    data = data.astype(np.float32) / np.float32(settings.samples ** 2)
                layers[pname] = np.ascontiguousarray(data, np.float32)
            self._tiles.put((tile, layers))

        return on_tile

    def _write_tile(self, tile, layers) -> None:
        """One finished tile into Blender's render result (on the render thread), and the progress."""
        engine = self.engine
        x0, y0, x1, y1 = self.settings.region or (0, 0, self.settings.width, self.settings.height)
        tx0, ty0, tx1, ty1 = tile
        # Result coordinates: relative to the border, y up from the bottom.
        result = engine.begin_result(tx0 - x0, y1 - ty1, tx1 - tx0, ty1 - ty0, layer=self.layer)
        try:
            passes = result.layers[0].passes
            for pname, data in layers.items():
                p = passes.get(pname)
                if p is not None:
                    p.rect.foreach_set(data.reshape(-1))
        finally:
            engine.end_result(result)
        self.tiles_written += 1
        engine.update_progress(min(1.0, self.tiles_written / max(self._tiles_total, 1)))
        engine.update_stats("", f"Whitted: tile {self.tiles_written}/{self._tiles_total}")


def viewport_settings(bpy_scene) -> "tracer.RenderSettings":
    """The viewport's render settings: the scene's, with 4 samples per extended light (the passes refine the
    anti-aliasing themselves); F12's Denoise does not apply (the viewport has its own: :func:`viewport_denoise`)."""
    return export.settings_from_scene(bpy_scene).with_(light_samples=4, region=None, aovs=(), denoise=False)


def viewport_denoise(bpy_scene) -> int | None:
    """The samples per pixel a viewport pass has before it is denoised (Render Properties > Denoise > Viewport and
    its Start Sample, as Cycles' viewport denoising), or None: not denoised."""
    props = getattr(bpy_scene, "whitted", None)
    if props is None or not props.preview_denoise:
        return None
    return int(props.preview_denoise_start)


def _redraw_callback(engine):
    """``engine.tag_redraw`` for the worker thread, holding the engine weakly (so Blender can free it and its
    ``__del__`` stop the worker). tag_redraw only sets a flag (RE_ENGINE_DO_DRAW) that Blender's main loop polls
    to redraw the region, as Cycles' session sets it from its own thread; the call holds the GIL, so it cannot
    race with Blender invalidating the engine (then it raises ReferenceError, and there is nothing to redraw)."""
    ref = weakref.ref(engine)

    def tag():
        e = ref()
        if e is None:
            return
        try:
            e.tag_redraw()
        except ReferenceError:
            pass

    return tag


def _tile_z(camera, distance, tile, width, height):
    """Blender's Depth pass for one tile: the tracer's hit distance (from the eye, or the film plane of an
    orthographic camera, along each pixel's centre ray) projected on the camera's view axis (−Z); NO_DEPTH where
    nothing was hit."""
    x0, y0, x1, y1 = tile
    py, px = np.mgrid[y0:y1, x0:x1]
    u = ((px + 0.5) / width).reshape(-1)
    v = (1.0 - (py + 0.5) / height).reshape(-1)
    _, d = camera.generate_rays(u, v)
    fwd = -camera.camera_to_world[:3, 2] / np.linalg.norm(camera.camera_to_world[:3, 2])
    cos = (d @ fwd).reshape(y1 - y0, x1 - x0)
    dist = distance[y0:y1, x0:x1]
    return np.where(np.isfinite(dist), dist * cos, NO_DEPTH).astype(np.float32)


def blender_library_dirs() -> list:
    """Where this Blender keeps its shared libraries (its Open Image Denoise among them): lib/ beside the binary
    (Linux), blender.shared/ (Windows), Contents/Resources/lib (macOS)."""
    import os

    base = os.path.dirname(bpy.app.binary_path or "")
    if not base:
        return []
    return [os.path.join(base, "lib"), os.path.join(base, "blender.shared"), base,
            os.path.normpath(os.path.join(base, "..", "Resources", "lib"))]


def register():
    for d in blender_library_dirs():  # F12's Denoise uses Blender's own OIDN (tracer/denoise.py)
        tracer.denoise.add_search_dir(d)
    bpy.utils.register_class(WhittedRenderEngine)
    # Shipped kernels where they fit; the rest prepared in a child process, never in Blender's (addon/kernels.py).
    kernels.start()


def unregister():
    kernels.stop()
    bpy.utils.unregister_class(WhittedRenderEngine)

"""The Whitted render engine: F12 exports the evaluated depsgraph and traces it, tile by tile, into Blender's
render result (with Persistent Data on, it keeps the session and syncs only what changed, addon/sync.py); the
viewport's Rendered shading keeps a session on a worker thread and draws its newest progressive pass
(addon/viewport.py), where a GPU context exists, and fails soft where it does not.

The last final render's tracer statistics (ray counts per type, timings) are kept in :data:`LAST_STATS` and on
``WhittedRenderEngine.last_stats``, for tests and for the curious.
"""

from __future__ import annotations

import threading
import time
import weakref

import bpy
import numpy as np

from . import export, sync, viewport

tracer = export.tracer

#: Tracer statistics of the last final render (``image.stats``: rays per type, seconds, ...), or None.
LAST_STATS: dict | None = None
#: Warnings of the last final render's scene export.
LAST_WARNINGS: list[str] = []
#: Test seam: a callable polled with ``test_break`` (True ends the render as Esc would). None in normal use.
break_hook = None

#: Blender pass name, channels, channel ids, type — for each tracer AOV.
PASSES = {
    "depth": ("Depth", 1, "Z", "VALUE"),
    "normal": ("Normal", 3, "XYZ", "VECTOR"),
    # Blender 5.0 names the object index pass "Object Index" (Cycles writes it so); older versions "IndexOB".
    "objectid": ("Object Index" if bpy.app.version >= (5, 0, 0) else "IndexOB", 1, "X", "VALUE"),
    # With scene.whitted.ray_type_passes (tracer.settings.RAY_TYPE_AOVS):
    "direct": ("Whitted Direct", 3, "RGB", "COLOR"),
    "reflection": ("Whitted Reflection", 3, "RGB", "COLOR"),
    "transmission": ("Whitted Transmission", 3, "RGB", "COLOR"),
    "raydepth": ("Whitted Ray Depth", 1, "X", "VALUE"),
}
#: Depth Blender writes where nothing was hit.
NO_DEPTH = 1.0e10


class WhittedRenderEngine(bpy.types.RenderEngine):
    bl_idname = "WHITTED"
    bl_label = "Whitted"
    bl_use_preview = True
    bl_use_shading_nodes_custom = False
    bl_use_eevee_viewport = False

    last_stats: dict | None = None

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._view = None  # the viewport's worker (addon/viewport.py) and its scene sync
        self._sync = None
        self._final_session = None  # F12 with Persistent Data: the session kept between renders, and its sync
        self._final_sync = None

    # ---------------------------------------------------------------------------------------------- passes
    def update_render_passes(self, scene=None, renderlayer=None):
        self.register_pass(scene, renderlayer, "Combined", 4, "RGBA", "COLOR")
        if renderlayer.use_pass_z:
            self.register_pass(scene, renderlayer, *PASSES["depth"])
        if renderlayer.use_pass_normal:
            self.register_pass(scene, renderlayer, *PASSES["normal"])
        if renderlayer.use_pass_object_index:
            self.register_pass(scene, renderlayer, *PASSES["objectid"])
        props = getattr(scene, "whitted", None)
        if props is not None and props.ray_type_passes:
            for aov in tracer.settings.RAY_TYPE_AOVS:
                self.register_pass(scene, renderlayer, *PASSES[aov])

    # ---------------------------------------------------------------------------------------------- F12
    def render(self, depsgraph):
        global LAST_STATS, LAST_WARNINGS
        bpy_scene = depsgraph.scene
        layer_name = depsgraph.view_layer.name
        stop = [False]
        main_thread = threading.current_thread()

        def cancelled():
            # Blender's API is only called from the thread that runs render(); the tracer's worker threads
            # read the flag (the tracer polls on the calling thread after every tile as well).
            if not stop[0] and threading.current_thread() is main_thread:
                stop[0] = bool(self.test_break() or (break_hook is not None and break_hook()))
            return stop[0]

        # Persistent Data (Render Properties > Performance > Final Render, as Cycles): Blender keeps this engine
        # between F12s, and the session with it; depsgraph.updates says what changed since the last one.
        persistent = bool(bpy_scene.render.use_persistent_data) and not self.is_preview
        if not persistent:
            self._drop_final_session()
        sync_stats = None
        stage = "export"
        try:
            settings = export.settings_from_scene(bpy_scene, view_layer=depsgraph.view_layer)
            if self.is_preview:
                settings = settings.with_(samples=min(settings.samples, 2), light_samples=4, sky_samples=0,
                                          max_depth=min(settings.max_depth, 4), region=None, aovs=())
            t0 = time.perf_counter()
            self.update_stats("", "Whitted: exporting scene" if self._final_sync is None or not persistent
                              else "Whitted: syncing changes (Persistent Data)")
            if persistent:
                if self._final_sync is None:
                    self._final_sync = sync.SceneSync(quality="medium")
                edits = self._final_sync.update(depsgraph, width=settings.width, height=settings.height,
                                                cancelled=cancelled)
                if cancelled():
                    raise export.ExportCancelled("export cancelled")
                stage = "build"
                self._final_session = sync.apply_edits(self._final_session, edits, quality="medium",
                                                       cancelled=cancelled)
                session = self._final_session
                warnings, pass_indices = self._final_sync.warnings, self._final_sync.pass_indices
                sync_stats = dict(self._final_sync.stats)
            else:
                scene, warnings = export.scene_from_depsgraph(depsgraph, width=settings.width,
                                                              height=settings.height, cancelled=cancelled)
                pass_indices = scene.object_pass_indices
                stage = "build"  # what tracer.render(scene) builds, made here so Esc reaches the BVH build too
                session = tracer.Session(scene, instanced=False, cancelled=cancelled)
            scene = session.scene
        except (export.ExportCancelled, tracer.RenderCancelled):  # Esc: nothing traced, nothing half-synced kept
            self._drop_final_session()
            self._write_empty(settings, layer_name)
            if not self.is_preview:
                LAST_STATS = {"cancelled": True, "cancelled_in": stage}
                type(self).last_stats = LAST_STATS
            return
        except Exception as exc:  # a scene we cannot export: say why, leave an empty result
            self._drop_final_session()
            self.report({"ERROR"}, f"Whitted: {exc}")
            if self.is_preview:
                self._fill_preview(settings_or_size=self._size_of(bpy_scene))
            return
        if not self.is_preview:
            LAST_WARNINGS = list(warnings)
            for w in warnings:
                self.report({"WARNING"}, f"Whitted: {w}")
        export_s = time.perf_counter() - t0
        x0, y0, x1, y1 = settings.region or (0, 0, settings.width, settings.height)
        tiles_total = len(tracer.tiles_of(settings))
        done = [0]
        if pass_indices is None:
            pass_indices = np.arange(len(scene.object_names), dtype=np.int32)

        def write(image, tile):
            tx0, ty0, tx1, ty1 = tile
            tw, th = tx1 - tx0, ty1 - ty0
            # Result coordinates: relative to the border, y up from the bottom.
            rx, ry = tx0 - x0, (y1 - ty1)
            result = self.begin_result(rx, ry, tw, th, layer=layer_name)
            try:
                passes = result.layers[0].passes
                rgba = image.rgba[ty0:ty1, tx0:tx1][::-1]
                passes["Combined"].rect.foreach_set(np.ascontiguousarray(rgba, np.float32).reshape(-1))
                for aov, (pname, _, _, _) in PASSES.items():
                    p = passes.get(pname)
                    if p is None or aov not in image.aovs:
                        continue
                    data = image.aovs[aov][ty0:ty1, tx0:tx1][::-1]
                    if aov == "depth":
                        data = _tile_z(scene.camera, image.aovs["depth"], tile, settings.width,
                                       settings.height)[::-1]
                    elif aov == "objectid":
                        ids = data
                        idx = np.zeros(ids.shape, np.float32)
                        ok = (ids >= 0) & (ids < len(pass_indices))
                        idx[ok] = pass_indices[ids[ok]]
                        data = idx
                    p.rect.foreach_set(np.ascontiguousarray(data, np.float32).reshape(-1))
            finally:
                self.end_result(result)

        def on_tile(image, tile):
            write(image, tile)
            done[0] += 1
            self.update_progress(min(1.0, done[0] / max(tiles_total, 1)))
            self.update_stats("", f"Whitted: tile {done[0]}/{tiles_total}")

        # The first render on a machine compiles the tracer's kernels (numba, cached on disk afterwards); the
        # add-on started that on a thread when it was enabled, so this mostly waits for it or returns at once.
        self.update_stats("", "Whitted: preparing kernels (the first render on this machine compiles them, ~10 s)")
        tracer.compile_kernels()
        self.update_stats("", f"Whitted: tracing {len(scene.triangles):,} triangles, {len(scene.lights)} lights")
        try:
            image = session.render(settings, on_tile=on_tile, cancelled=cancelled)
        except tracer.RenderCancelled as stopped:
            image = stopped.image
            image.stats["cancelled"] = True
        except Exception as exc:
            self.report({"ERROR"}, f"Whitted: render failed: {exc}")
            return
        finally:
            if not persistent:
                session.close()
        if not self.is_preview:
            image.stats["export_seconds"] = export_s
            image.stats["bvh_seconds"] = session.stats["build_seconds"]
            image.stats["persistent"] = persistent
            if sync_stats is not None:
                image.stats["sync"] = sync_stats
            LAST_STATS = dict(image.stats)
            type(self).last_stats = LAST_STATS
            rays = image.stats["rays"]
            self.update_stats("", f"Whitted: {rays['total']:,} rays in {image.stats['seconds']:.2f} s")

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

    @staticmethod
    def _size_of(bpy_scene):
        return export.render_size(bpy_scene)

    def _fill_preview(self, settings_or_size):
        """Fallback for the material preview: a flat mid-grey image, so the preview never shows garbage."""
        w, h = settings_or_size
        result = self.begin_result(0, 0, w, h)
        rgba = np.tile(np.array([0.18, 0.18, 0.18, 1.0], np.float32), w * h)
        result.layers[0].passes["Combined"].rect.foreach_set(rgba)
        self.end_result(result)

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
        v = getattr(self, "_view", None)
        if v is not None:
            v.stop()
        s = getattr(self, "_final_session", None)
        if s is not None:
            s.close()


def viewport_settings(bpy_scene) -> "tracer.RenderSettings":
    """The viewport's render settings: the scene's, with 4 samples per extended light (the passes refine the
    anti-aliasing themselves)."""
    return export.settings_from_scene(bpy_scene).with_(light_samples=4, region=None, aovs=())


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


def viewport_camera(rv3d) -> "tracer.Camera":
    """A tracer camera from the 3D view's view and projection matrices (OpenGL convention)."""
    view = np.array(rv3d.view_matrix, dtype=np.float64)
    proj = np.array(rv3d.window_matrix, dtype=np.float64)
    c2w = np.linalg.inv(view)
    w_ap, h_ap = 2.0 / proj[0, 0], 2.0 / proj[1, 1]
    if rv3d.is_perspective:
        return tracer.Camera(camera_to_world=c2w, focal_length=1.0, horizontal_aperture=w_ap,
                             vertical_aperture=h_ap, horizontal_aperture_offset=proj[0, 2] / proj[0, 0],
                             vertical_aperture_offset=proj[1, 2] / proj[1, 1])
    return tracer.Camera(camera_to_world=c2w, projection=tracer.ORTHOGRAPHIC, focal_length=1.0,
                         horizontal_aperture=w_ap, vertical_aperture=h_ap,
                         horizontal_aperture_offset=-proj[0, 3] / proj[0, 0],
                         vertical_aperture_offset=-proj[1, 3] / proj[1, 1])


def register():
    bpy.utils.register_class(WhittedRenderEngine)
    # Compile (first run on this machine) or load the kernels now, off the UI thread, so the first F12 or
    # viewport does not freeze Blender for the ~10 s of a first compile.
    threading.Thread(target=_prepare_kernels, name="whitted-compile", daemon=True).start()


def _prepare_kernels():
    try:
        tracer.compile_kernels()
    except Exception as exc:  # reported again, in context, by the first render that needs them
        print(f"Whitted: preparing the kernels failed: {exc}")


def unregister():
    bpy.utils.unregister_class(WhittedRenderEngine)

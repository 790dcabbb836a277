"""Esc in F12 (issue #30): pressed before the Embree build, during it, during the first tile and between tiles, the
Whitted engine ends the render cleanly (no traceback, no error report, no tile written after Esc was seen, only
the tiles in flight finish their current ray depth), and the next F12 in the same Blender is complete and
identical to a render that was never interrupted.

Esc is simulated as Blender delivers it, through ``RenderEngine.test_break``: the engine polls it together with
its ``break_hook`` test seam (bpy's RNA methods cannot be patched), which starts returning True at a chosen moment. To make "during the build" and "during the first tile" exact rather than a race,
the moment is an instrumented call (the Embree scene's commit, the first ray-depth step of a tile) that presses
Esc and then waits until the engine has seen it (at most WAIT seconds): an engine that does not poll Esc while the
tracer works is caught there, as the ray-depth steps it keeps tracing afterwards.

Bounds, and why:
- THREADS 2: two tiles may be in flight when Esc comes; each may finish the depth step it is in, no more.
- TILE 32 on a 128×96 image: 12 tiles, so "the render stopped early" is a count of tiles, not a timing.
"""

from __future__ import annotations

import threading

import numpy as np
import pytest

from blender_kit import scene as bs

import bpy  # noqa: E402

import addon  # noqa: E402
import tracer  # noqa: E402
from addon import engine, export  # noqa: E402
from tracer.accel import embree
from tracer.integrator import tiles  # noqa: E402
from tracer.integrator import wavefront as integrator  # noqa: E402

THREADS = 2
TILE = 32
SIZE = (128, 96)
N_TILES = (SIZE[0] // TILE) * (SIZE[1] // TILE)
WAIT = 10.0  # seconds an instrumented phase waits for the engine to see Esc (never reached by a polling engine)


@pytest.fixture(scope="module")
def whitted():
    addon.register()
    yield engine
    addon.unregister()


def esc_scene():
    """A mirror ball and a glass ball over a ground plane, a point light: several ray depths per tile."""
    scene = bs.reset(SIZE)
    bs.add_camera((0, -7, 1.5), target=(0, 0, 0.8), lens=40)
    bs.add_point_light((3, -4, 6), power=2000)
    bs.add_plane(size=20, material=bs.principled_material("Ground", base_color=(0.6, 0.5, 0.3), specular=0.0))
    bs.add_uv_sphere((-1.1, 0, 1.0), 1.0, segments=32, rings=16,
                     material=bs.principled_material("Mirror", metallic=1.0, roughness=0.0))
    bs.add_uv_sphere((1.1, 0, 1.0), 1.0, segments=32, rings=16,
                     material=bs.principled_material("Glass", transmission=1.0, roughness=0.0, ior=1.5))
    bs.set_world((0.1, 0.2, 0.6))
    scene.render.engine = "WHITTED"
    scene.whitted.threads = THREADS
    scene.whitted.samples = 1
    return scene


class Esc:
    """Instruments one F12: presses Esc at a phase; records Blender API calls and the tracer's work around it."""

    def __init__(self, monkeypatch):
        self.pressed = False
        self.seen = threading.Event()  # test_break returned True
        self.waited = []  # per instrumented press: whether the engine saw Esc within WAIT
        self.traced_tiles = 0  # tiles the tracer finished and handed to the engine
        self.steps_after_seen = 0  # ray-depth steps begun (on any thread) after the engine saw Esc
        self.steps_after_press_here = 0  # ... after the press, on the thread that pressed it in a step or commit
        self.tiles_started_after_seen = 0
        self.force_full = False  # Persistent Data: the next sync exports everything (a rebuild)
        self._presser = None
        self.commits = 0
        self.mp = monkeypatch
        cls = engine.WhittedRenderEngine
        esc = self

        def test_break():  # Blender's RenderEngine.test_break answers through the engine's break_hook seam
            if esc.pressed:
                esc.seen.set()
            return esc.pressed

        monkeypatch.setattr(cls, "break_hook", staticmethod(test_break))
        real_settings = export.settings_from_scene
        monkeypatch.setattr(export, "settings_from_scene",
                            lambda *a, **k: real_settings(*a, **k).with_(tile_size=TILE))
        real_step = integrator.Integrator.step

        def step(integ, *a, **k):
            if esc.seen.is_set():
                esc.steps_after_seen += 1
            if esc.pressed and esc._presser is threading.current_thread():
                esc.steps_after_press_here += 1
            if esc.phase == "first tile" and not esc.pressed:
                esc.press()  # Esc as the first tile begins tracing: it may finish this depth, no more
            return real_step(integ, *a, **k)

        monkeypatch.setattr(integrator.Integrator, "step", step)
        real_trace_tile = tiles.trace_tile

        def trace_tile(*a, **k):
            if esc.seen.is_set():
                esc.tiles_started_after_seen += 1
            return real_trace_tile(*a, **k)

        monkeypatch.setattr(tiles, "trace_tile", trace_tile)
        real_commit = embree.EmbreeScene.commit

        def commit(scene, cancelled=None):
            esc.commits += 1
            if cancelled is not None and esc.phase == "build" and not esc.pressed:
                esc.press()  # Esc while Embree builds: the build may stop or finish, no tile may follow
            return real_commit(scene, cancelled)

        monkeypatch.setattr(embree.EmbreeScene, "commit", commit)
        real_export = export.scene_from_depsgraph

        def scene_from_depsgraph(*a, **k):
            out = real_export(*a, **k)
            if esc.phase == "before build":
                esc.pressed = True  # Esc between the export's last poll and the Embree build
            return out

        monkeypatch.setattr(export, "scene_from_depsgraph", scene_from_depsgraph)
        real_update = addon.sync.SceneSync.update

        def update(sync, depsgraph, **k):
            if esc.force_full:
                return sync.full(depsgraph, **k)
            return real_update(sync, depsgraph, **k)

        monkeypatch.setattr(addon.sync.SceneSync, "update", update)
        real_write = tiles.write_tile

        def write_tile(*a, **k):
            out = real_write(*a, **k)
            esc.traced_tiles += 1
            if esc.phase == "between tiles" and not esc.pressed and esc.traced_tiles == 3:
                esc.pressed = True  # Esc once the third tile is finished and handed to the engine
            return out

        monkeypatch.setattr(tiles, "write_tile", write_tile)
        self.phase = None

    def press(self):
        """Esc now; a tracer thread then waits until the engine has seen it (the render thread cannot wait for
        itself: there the engine polls at the tracer's next question anyway)."""
        self.pressed = True
        self._presser = threading.current_thread()
        if threading.current_thread() is not threading.main_thread():
            self.waited.append(self.seen.wait(WAIT))

    def f12(self, phase, tmp_path):
        """One F12 with Esc at ``phase`` (None: no Esc); the picture Blender wrote, and the report."""
        self.phase, self.pressed = phase, False
        self.seen.clear()
        self.traced_tiles = 0
        self.waited.clear()
        self.steps_after_seen = self.steps_after_press_here = self.tiles_started_after_seen = self.commits = 0
        self._presser = None
        scene = bpy.context.scene
        engine.WhittedRenderEngine.last_render = None
        path = str(tmp_path / f"f12_{(phase or 'full').replace(' ', '_')}.exr")
        out = bs.render_exr(scene, path)
        self.phase, self.force_full = None, False
        report = engine.WhittedRenderEngine.last_render
        assert report is not None, "the engine recorded no render"
        return out["rgba"], report.stats


def written_tiles(rgba, reference):
    """Indices (row by row from the top, the tracer's order) of the tiles Blender's result holds: each tile is
    either all black (never written) or identical to the uninterrupted render; anything else is a half-written
    tile and fails."""
    written = []
    for i, (y, x) in enumerate((y, x) for y in range(0, SIZE[1], TILE) for x in range(0, SIZE[0], TILE)):
        got, ref = rgba[y:y + TILE, x:x + TILE], reference[y:y + TILE, x:x + TILE]  # (the EXR's rows: top first)
        if got.any():
            np.testing.assert_array_equal(got, ref, err_msg=f"tile {i} is half-written or wrong")
            written.append(i)
    return written


def check_stopped(esc, rgba, stats, reference, out):
    """The common promises of an Esc'd F12; the tiles written."""
    assert "Traceback" not in out and "Whitted: render failed" not in out, out
    assert esc.seen.is_set(), "the engine never asked test_break after Esc"
    assert all(esc.waited), "the engine did not see Esc while the tracer worked (it polls only between tiles)"
    assert stats.get("cancelled") is True, stats
    tiles = written_tiles(rgba, reference)
    # Nothing written after Esc: only tiles the tracer had finished before it, in order from the first.
    assert tiles == list(range(len(tiles))) and len(tiles) <= (3 if esc.phase == "between tiles" else 0), \
        (esc.phase, tiles, stats)
    # Promptly: the tiles in flight finish at most the ray depth they are in (and a tile that slipped past its
    # start check in the instant Esc was seen stops after one); the thread Esc came on goes no deeper.
    assert esc.steps_after_seen <= THREADS, esc.steps_after_seen
    assert esc.tiles_started_after_seen <= THREADS, esc.tiles_started_after_seen
    if esc.phase in ("build", "first tile"):
        assert esc.steps_after_press_here == 0, f"{esc.steps_after_press_here} ray depths traced after Esc"
    return tiles


@pytest.mark.parametrize("phase", ["before build", "build", "first tile", "between tiles"])
@pytest.mark.parametrize("persistent", [False, True], ids=["oneoff", "persistent"])
def test_esc_then_next_f12_is_complete(bpy_module, whitted, monkeypatch, tmp_path, capfd, persistent, phase):
    scene = esc_scene()
    scene.render.use_persistent_data = persistent
    esc = Esc(monkeypatch)
    try:
        reference, full = esc.f12(None, tmp_path)
        assert not full.get("cancelled") and full["rays"]["eye"] == SIZE[0] * SIZE[1]
        assert full["rays"]["reflection"] > 0 and full["rays"]["transmission"] > 0
        assert written_tiles(reference, reference) == list(range(N_TILES)) and reference[..., 3].min() == 1.0
        # (with Persistent Data the kept session is synced, not rebuilt: the build phases need a full export)
        esc.force_full = persistent and phase in ("before build", "build")
        rgba, stats = esc.f12(phase, tmp_path)
        esc.phase = phase
        tiles = check_stopped(esc, rgba, stats, reference, "".join(capfd.readouterr()))
        if phase in ("before build", "build", "first tile"):
            assert not tiles and stats["cancelled_in"] in {"before build": ("export", "build"), "build": ("build",),
                                                           "first tile": ("build", "tiles")}[phase], stats
        if phase == "before build":
            assert esc.commits == 0, "the Embree scene was built after Esc"
        if tiles:
            assert stats["rays"]["eye"] < SIZE[0] * SIZE[1] and stats.get("tiles_written", len(tiles)) == len(tiles)
        # The next F12 in the same Blender is complete and identical to the uninterrupted one.
        again, stats = esc.f12(None, tmp_path)
        assert not stats.get("cancelled") and stats["rays"]["eye"] == SIZE[0] * SIZE[1], stats
        np.testing.assert_array_equal(again, reference)
    finally:
        scene.render.use_persistent_data = False
    out = "".join(capfd.readouterr())
    assert "Traceback" not in out, out


class _Rect:
    def __init__(self, store, key):
        self.store, self.key = store, key

    def foreach_set(self, data):
        self.store[self.key] = np.array(data, np.float32)


class _PreviewEngine:
    """A stand-in for the engine Blender makes for a material preview (bpy cannot start one headless): records the
    results written, in the engine's own preview code."""

    is_preview = True
    break_hook = None
    _render_preview = engine.WhittedRenderEngine._render_preview
    _write_empty = engine.WhittedRenderEngine._write_empty
    _fill_preview = engine.WhittedRenderEngine._fill_preview

    def __init__(self, esc_after=None):
        self.results, self.reports, self.esc_after = [], [], esc_after

    def test_break(self):
        return self.esc_after is not None and len(self.results) >= self.esc_after

    def begin_result(self, x, y, w, h, layer=None):
        store = {}
        self.results.append(((x, y, w, h), store))

        class Pass:
            def __init__(self, name):
                self.rect = _Rect(store, name)

        passes = {"Combined": Pass("Combined")}
        return type("Result", (), {"layers": [type("Layer", (), {"passes": passes})]})()

    def end_result(self, result):
        pass

    def update_progress(self, value):
        pass

    def update_stats(self, a, b):
        pass

    def report(self, kind, text):
        self.reports.append((kind, text))


def test_material_preview_writes_every_tile_or_stops_at_esc(bpy_module, whitted, monkeypatch):
    """The material preview path goes through the same helper thread: every tile is written when nothing stops it;
    Esc after the first tile stops it with no later tile (and no half-written one)."""
    esc_scene()
    real_settings = export.settings_from_scene
    monkeypatch.setattr(export, "settings_from_scene", lambda *a, **k: real_settings(*a, **k).with_(tile_size=TILE))
    depsgraph = bpy.context.evaluated_depsgraph_get()
    whole = _PreviewEngine()
    whole._render_preview(depsgraph)
    assert not whole.reports and len(whole.results) == N_TILES
    assert all(store["Combined"].size == w * h * 4 and store["Combined"].any() for (_, _, w, h), store in whole.results)
    stopped = _PreviewEngine(esc_after=1)
    stopped._render_preview(depsgraph)
    assert not stopped.reports and len(stopped.results) == 1
    assert np.array_equal(stopped.results[0][1]["Combined"], whole.results[0][1]["Combined"])

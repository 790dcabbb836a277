"""The viewport without a GPU: the worker thread converges to the F12 pixels, restarts from the coarsest level when
the view moves, traces only on its own thread; the viewport camera agrees with Blender's own projection; the
export cache reuses unchanged meshes; view_draw puts the newest pass on screen upright (stand-ins for ``gpu``) and
fails soft without a GPU."""

from __future__ import annotations

import sys
import threading
import time
import types

import numpy as np
import pytest

from blender_kit import scene as bs

import bpy  # noqa: E402

import addon  # noqa: E402
from addon import engine, export, viewport  # noqa: E402
import tracer  # noqa: E402

from tracer_scenes import lit_sphere_on_floor  # noqa: E402

SIZE = (48, 32)
#: A moved object is an Embree instance in the session, triangles moved in world space in a fresh render: float32
#: rounding may differ by this much (tests/test_session.py measures it).
PIXEL_TOLERANCE = 1e-3


@pytest.fixture()
def scene():
    return lit_sphere_on_floor().build()


def _camera(x=0.0):
    return tracer.Camera.look_at((x, -8, 3), (0, 0, 0.8), up=(0, 0, 1), focal_length=35.0,
                                 horizontal_aperture=36.0, vertical_aperture=24.0)


def test_progressive_passes_converge_to_the_final_render(scene):
    frames = []
    vr = viewport.ViewportRender(settings=tracer.RenderSettings(light_samples=4))
    vr.on_frame = lambda: frames.append(vr.latest())
    try:
        vr.set_scene(scene)
        vr.set_view(_camera(), SIZE)
        assert vr.wait_until_converged(600)
        last = vr.latest()
        assert [(f.level, f.samples) for f in frames] == \
            [(lv, 1) for lv in viewport.LEVELS] + [(1, n) for n in viewport.AA_PASSES]
        assert frames[0].rgba.shape[:2] == (SIZE[1] // 8, SIZE[0] // 8)
        scene.camera = _camera()
        final = tracer.render(scene, tracer.RenderSettings(width=SIZE[0], height=SIZE[1], light_samples=4,
                                                           samples=viewport.AA_PASSES[-1]))
        np.testing.assert_array_equal(last.rgba, final.rgba)
        # what view_draw uploads: the same pixels, bottom row first (the GPU texture's origin)
        np.testing.assert_array_equal(last.flat.reshape(last.rgba.shape), last.rgba[::-1])
    finally:
        vr.stop()


class _Spy:
    """Records which thread calls the tracer (renders, session builds and edits)."""

    def __init__(self, monkeypatch):
        self.calls = []
        targets = [(tracer, "render"), (tracer.Session, "render"), (tracer.Session, "__init__")]
        targets += [(tracer.Session, name) for name in ("update_camera", "update_materials", "update_lights",
                                                        "update_world", "set_transform", "update_mesh",
                                                        "add_object", "remove_object")]
        for owner, name in targets:
            real = getattr(owner, name)

            def spy(*a, _real=real, _name=name, **k):
                self.calls.append((_name, threading.current_thread().name))
                return _real(*a, **k)

            monkeypatch.setattr(owner, name, spy)

    def threads(self):
        return {t for _, t in self.calls}


def test_a_view_change_restarts_from_the_coarsest_level_and_traces_off_the_ui_thread(scene, monkeypatch):
    spy = _Spy(monkeypatch)
    frames = []
    vr = viewport.ViewportRender(settings=tracer.RenderSettings(light_samples=4))
    vr.on_frame = lambda: frames.append(vr.latest())
    try:
        vr.set_scene(scene)
        vr.set_view(_camera(), SIZE)
        assert vr.wait_until_converged(600)
        assert not vr.set_view(_camera(), SIZE)  # the same view: nothing restarts
        n, built = len(frames), [c for c in spy.calls if c[0] == "__init__"]
        assert vr.set_view(_camera(1.0), SIZE)
        assert vr.wait_until_converged(600)
        moved = frames[n:]
        assert moved[0].level == viewport.LEVELS[0] and moved[-1].level == 1
        assert all(f.key != frames[n - 1].key for f in moved)
        # a camera move touches nothing but the camera: no new session, no edit but update_camera
        assert [c for c in spy.calls if c[0] == "__init__"] == built
        assert {c[0] for c in spy.calls} <= {"render", "__init__", "update_camera"}
        # set_view / latest / edit (all view_draw and view_update call) never trace or edit the session
        for _ in range(50):
            vr.set_view(_camera(2.0), SIZE)
            vr.latest()
        assert spy.threads() == {"whitted-viewport"}
        assert not vr.errors
    finally:
        vr.stop()


def test_edits_are_applied_by_the_worker_between_passes_and_converge_to_the_edited_scene(scene, monkeypatch):
    """A material edit and an object move (what view_update hands over) restart the refinement; the last pass
    equals a fresh render of the edited scene."""
    from addon.sync import Edit

    spy = _Spy(monkeypatch)
    frames = []
    vr = viewport.ViewportRender(settings=tracer.RenderSettings(light_samples=4))
    vr.on_frame = lambda: frames.append(vr.latest())
    try:
        vr.set_scene(scene)
        vr.set_view(_camera(), SIZE)
        assert vr.wait_until_converged(600)
        before = vr.latest()
        red = tracer.SceneBuilder()
        red.add_material("grey", diffuse=(0.8, 0.1, 0.1))
        ball = scene.object_names.index("ball")
        moved = np.eye(4)
        moved[:3, 3] = (0.7, 0.0, 0.2)
        n = len(frames)
        vr.edit([Edit("materials", (tracer.Materials.from_list(red.materials), [])),
                 Edit("transform", (ball, moved))])
        assert vr.wait_until_converged(600)
        after = frames[n:]
        assert after[0].level == viewport.LEVELS[0] and after[0].generation > before.generation
        assert vr.edits_applied == ["rebuild", "materials", "transform"]
        assert {t for name, t in spy.calls if name in ("update_materials", "set_transform")} == {"whitted-viewport"}
        edited = tracer.Session(scene)
        edited.update_materials(tracer.Materials.from_list(red.materials), [])
        edited.set_transform(ball, moved)
        edited.update_camera(_camera())
        want = tracer.render(edited.scene, tracer.RenderSettings(width=SIZE[0], height=SIZE[1], light_samples=4,
                                                                 samples=viewport.AA_PASSES[-1]))
        got = vr.latest().rgba
        assert np.abs(got - want.rgba).max() < PIXEL_TOLERANCE
        assert np.abs(got - before.rgba).max() > 0.1  # (the edit is visible)
    finally:
        vr.stop()


def test_viewport_camera_matches_blenders_projection():
    """A stand-in RegionView3D built from a camera's own matrices: the tracer's eye ray through the (u, v) Blender's
    ``world_to_camera_view`` gives a world point passes through that point."""
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector

    bs.reset(size=(64, 40))
    cam = bs.add_camera((2.0, -7.0, 3.0), (0.0, 0.0, 0.5), lens=40.0)
    cam.data.shift_x, cam.data.shift_y = 0.1, -0.05
    scene = bpy.context.scene
    depsgraph = bpy.context.evaluated_depsgraph_get()
    for ortho in (False, True):
        cam.data.type = "ORTHO" if ortho else "PERSP"
        cam.data.ortho_scale = 5.0
        depsgraph.update()
        rv3d = types.SimpleNamespace(view_matrix=cam.matrix_world.inverted(),
                                     window_matrix=cam.calc_matrix_camera(depsgraph, x=64, y=40),
                                     is_perspective=not ortho)
        tc = engine.viewport_camera(rv3d)
        rng = np.random.default_rng(3)
        for p in rng.uniform(-2, 2, (20, 3)):
            co = world_to_camera_view(scene, cam, Vector(p))
            o, d = tc.generate_rays(np.array([co.x]), np.array([co.y]))
            closest = o[0] + np.dot(p - o[0], d[0]) * d[0]
            assert np.linalg.norm(closest - p) < 1e-4, (ortho, p)


def test_export_cache_reuses_unchanged_meshes():
    bs.reset(size=(32, 24))
    a = bs.add_uv_sphere((0, 0, 1), 1.0, name="A")
    bs.add_cube((3, 0, 1), 1.0, name="B")
    bs.add_camera((0, -8, 3), (0, 0, 0))
    cache = {}
    dg = bpy.context.evaluated_depsgraph_get()
    export.scene_from_depsgraph(dg, geometry_cache=cache)
    before = {k: v for k, v in cache.items()}
    a.location.x += 1.0  # a transform: the mesh arrays stay valid
    dg.update()
    moved, _ = export.scene_from_depsgraph(dg, geometry_cache=cache)
    assert all(cache[k] is before[k] for k in before)
    oid = moved.object_names.index("A")
    xs = moved.vertices[moved.triangles[moved.object_ids == oid]][..., 0]
    assert abs(xs.mean() - 1.0) < 0.05  # the moved sphere, from the cached arrays and the new matrix
    mesh = a.data  # a geometry edit: forget A, keep B
    mesh.vertices[0].co.z += 0.5
    mesh.update()
    dg.update()
    export.forget_geometry(cache, [a])
    assert any(k[0] == "B" for k in cache) and not any(k[0] == "A" for k in cache)
    export.scene_from_depsgraph(dg, geometry_cache=cache)
    assert any(k[0] == "A" for k in cache)


# ------------------------------------------------------------------------------------ view_draw, without a GPU
Q = 16  # texture and viewport size in pixels: four 8×8 quadrants of one colour each
QUADRANTS = {"top-left": (0.9, 0.1, 0.1), "top-right": (0.1, 0.8, 0.1), "bottom-left": (0.1, 0.2, 0.9),
             "bottom-right": (0.7, 0.7, 0.1)}


def _quadrant_image():
    img = np.zeros((Q, Q, 3), np.float32)  # row 0 = the top of the picture
    h = Q // 2
    img[:h, :h], img[:h, h:] = QUADRANTS["top-left"], QUADRANTS["top-right"]
    img[h:, :h], img[h:, h:] = QUADRANTS["bottom-left"], QUADRANTS["bottom-right"]
    return img


def _fake_gpu(monkeypatch, drawn):
    """Stand-ins for the ``gpu`` module and ``gpu_extras.presets``: record what the engine would put on screen."""

    class Buffer:
        def __init__(self, fmt, size, data):
            self.values = np.array(data, np.float32).reshape(-1)[:size].copy()

    class GPUTexture:
        def __init__(self, size, format=None, data=None):
            self.size, self.values = tuple(size), data.values

    gpu = types.ModuleType("gpu")
    gpu.types = types.SimpleNamespace(GPUTexture=GPUTexture, Buffer=Buffer)
    gpu.state = types.SimpleNamespace(blend_set=lambda *a: None)
    presets = types.ModuleType("gpu_extras.presets")
    presets.draw_texture_2d = lambda texture, position, width, height: drawn.append((texture, position, width,
                                                                                    height))
    monkeypatch.setitem(sys.modules, "gpu", gpu)
    monkeypatch.setitem(sys.modules, "gpu_extras", types.ModuleType("gpu_extras"))
    monkeypatch.setitem(sys.modules, "gpu_extras.presets", presets)


def _engine_without_blender():
    """The engine's own methods on a plain object that stands in for the RenderEngine Blender would create (the bpy
    module cannot instantiate one); Blender's display-shader calls are no-ops, tag_redraw counts."""
    methods = {k: v for k, v in vars(engine.WhittedRenderEngine).items()
               if callable(v) and k not in ("__init__", "__new__")}
    methods.update(tag_redraw=lambda self: setattr(self, "redraws", self.redraws + 1),
                   bind_display_space_shader=lambda self, scene: None, unbind_display_space_shader=lambda self: None)
    fake = type("ViewportEngine", (), methods)()
    fake._view, fake.redraws = None, 0
    return fake


@pytest.fixture()
def registered():
    addon.register()
    yield
    addon.unregister()


def test_view_draw_puts_the_view_on_screen_upright_and_fails_soft_without_a_gpu(registered, monkeypatch, capsys,
                                                                                  tmp_path):
    """What Rendered shading shows: an ortho view straight down on a plane textured with four coloured quadrants.
    Without a GPU (background mode) view_draw prints one message and returns; with stand-ins for ``gpu`` it draws
    every pass over the whole region, and the full-resolution pass shows each quadrant where the texture has it
    (a missing bottom-up flip for the GPU texture, or a flipped or mirrored viewport camera, goes red)."""
    path = str(tmp_path / "quadrants.exr")
    tracer.write_image(path, _quadrant_image())
    bs.reset(size=(Q, Q))
    mat = bs.principled_material("Quadrants", **{"Specular IOR Level": 0.0})
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = bpy.data.images.load(path)
    mat.node_tree.links.new(tex.outputs["Color"], bs.principled_node(mat).inputs["Base Color"])
    bs.add_plane((0, 0, 0), 2.0, material=mat)
    cam = bs.add_camera((0, 0, 5), (0, 0, 0), rotation=(0.0, 0.0, 0.0), ortho_scale=2.0)
    bs.set_world((1.0, 1.0, 1.0), 1.0)  # ambient 1, no lights: each pixel shows its texel
    depsgraph = bpy.context.evaluated_depsgraph_get()
    rv3d = types.SimpleNamespace(view_matrix=cam.matrix_world.inverted(),
                                 window_matrix=cam.calc_matrix_camera(depsgraph, x=Q, y=Q), is_perspective=False)
    context = types.SimpleNamespace(region=types.SimpleNamespace(width=Q, height=Q), region_data=rv3d)
    fake = _engine_without_blender()
    try:
        said = ""
        deadline = time.monotonic() + 600  # a hang guard for a broken worker, not a speed check
        while time.monotonic() < deadline:  # the real gpu module, no GPU context: a ready pass fails to draw softly
            fake.view_draw(context, depsgraph)
            said += capsys.readouterr().out
            if said:
                break
            time.sleep(0.2)
        assert said.count("\n") == 1 and said.startswith("Whitted viewport: "), said
        drawn = []
        _fake_gpu(monkeypatch, drawn)
        full = None
        while time.monotonic() < deadline + 600:  # until the worker's full-resolution pass is drawn
            fake.view_draw(context, depsgraph)
            full = next((t for t, *_ in drawn if t.size == (Q, Q)), None)
            if full is not None:
                break
            time.sleep(0.2)
        assert full is not None, f"no full-resolution pass drawn; {capsys.readouterr().out[-500:]}"
        assert fake.redraws >= 1  # the worker asked Blender to redraw when a pass finished
        assert all(pos == (0, 0) and (w, h) == (Q, Q) for _, pos, w, h in drawn)  # every pass fills the region
        screen = full.values.reshape(Q, Q, 4)[::-1]  # GPU textures are bottom row first; row 0 = top of the view
        inner = [slice(1, Q // 2 - 1), slice(Q // 2 + 1, Q - 1)]  # away from bilinear blending at the seams
        for (ri, ci), name in zip([(0, 0), (0, 1), (1, 0), (1, 1)], QUADRANTS):
            block = screen[inner[ri], inner[ci]]
            np.testing.assert_allclose(block[..., :3], np.broadcast_to(QUADRANTS[name], block[..., :3].shape),
                                       atol=2e-3, err_msg=name)
            assert np.all(block[..., 3] == 1.0)
    finally:
        if fake._view is not None:
            fake._view.stop()
def test_the_redraw_callback_holds_the_engine_weakly_and_outlives_it():
    """The worker's on_frame: tag_redraw on the engine while it lives; it does not keep the engine alive (so its
    __del__ can stop the worker), and an engine Blender already freed (ReferenceError) is not an error."""
    import gc

    calls = []

    class Engine:
        def tag_redraw(self):
            calls.append(1)

    class Freed:
        def tag_redraw(self):
            raise ReferenceError("StructRNA of type WhittedRenderEngine has been removed")

    e = Engine()
    tag = engine._redraw_callback(e)
    tag()
    assert calls == [1]
    del e
    gc.collect()
    tag()  # the engine is gone: nothing to redraw, nothing raised
    assert calls == [1]
    engine._redraw_callback(Freed())()


def test_viewport_settings_follow_the_scene_without_region_or_passes():
    bs.reset(size=(64, 48))
    scene = bpy.context.scene
    scene.render.use_border = True
    scene.view_layers[0].use_pass_z = True
    st = engine.viewport_settings(scene)
    assert st.region is None and st.aovs == () and st.light_samples == 4
    assert st.max_depth == export.settings_from_scene(scene).max_depth


def test_an_edit_the_session_refuses_asks_for_a_full_export(scene):
    from addon.sync import Edit

    vr = viewport.ViewportRender(settings=tracer.RenderSettings(light_samples=4))
    try:
        vr.set_scene(scene)
        vr.set_view(_camera(), SIZE)
        assert vr.wait_until_converged(600)
        vr.edit([Edit("transform", (999, np.eye(4)))])  # no such object: the session raises KeyError
        for _ in range(200):
            if vr.lost:
                break
            threading.Event().wait(0.01)
        assert vr.lost and vr.session is None and vr.errors
        vr.set_scene(scene)  # what view_update sends after SceneSync.reset(): a rebuild
        assert vr.wait_until_converged(600) and vr.session is not None
    finally:
        vr.stop()


def test_viewport_denoises_full_resolution_passes_from_the_start_sample(scene):
    """Viewport denoising (Render Properties > Denoise > Viewport, Start Sample 4): the coarse passes and the
    1-sample full-resolution pass are shown as traced, the passes with 4 and 9 samples per pixel denoised as
    Cycles' viewport does (albedo guide, no prefilter, balanced quality)."""
    from tracer import denoise as dn

    frames = []
    vr = viewport.ViewportRender(settings=tracer.RenderSettings(light_samples=4))
    vr.on_frame = lambda: frames.append(vr.latest())
    try:
        assert vr.set_denoise(4) and not vr.set_denoise(4)  # a change restarts; the same value does not
        vr.set_scene(scene)
        vr.set_view(_camera(), SIZE)
        assert vr.wait_until_converged(600)
        assert [(f.level, f.samples, f.denoised) for f in frames] == \
            [(lv, 1, False) for lv in viewport.LEVELS] + [(1, n, n * n >= 4) for n in viewport.AA_PASSES]
        scene.camera = _camera()
        settings = tracer.RenderSettings(width=SIZE[0], height=SIZE[1], light_samples=4,
                                         samples=viewport.AA_PASSES[-1], aovs=("denoising_albedo",))
        plain = tracer.render(scene, settings)
        expected = dn.denoise(plain.rgba, plain.aovs["denoising_albedo"], prefilter="fast", quality="balanced")
        np.testing.assert_allclose(frames[-1].rgba, expected, atol=1e-5)
        assert not np.allclose(frames[-1].rgba, plain.rgba, atol=1e-4)
    finally:
        vr.stop()


def test_viewport_denoise_follows_the_scene_properties(registered):
    bs.reset(size=(64, 48))
    scene = bpy.context.scene
    assert scene.whitted.denoise and not scene.whitted.preview_denoise  # F12 on, viewport off: Cycles' defaults
    assert engine.viewport_denoise(scene) is None
    assert engine.viewport_settings(scene).denoise is False  # F12's checkbox is not the viewport's
    scene.whitted.preview_denoise = True
    scene.whitted.preview_denoise_start = 9
    assert engine.viewport_denoise(scene) == 9

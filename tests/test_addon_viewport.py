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

from tests import blender_support as bs

import bpy  # noqa: E402

import addon  # noqa: E402
from addon import engine, export, viewport  # noqa: E402
import tracer  # noqa: E402

from tracer_scenes import lit_sphere_on_floor  # noqa: E402

SIZE = (48, 32)


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
    finally:
        vr.stop()


def test_a_view_change_restarts_from_the_coarsest_level_and_traces_off_the_ui_thread(scene, monkeypatch):
    threads = []
    real = tracer.render

    def spy(*a, **k):
        threads.append(threading.current_thread().name)
        return real(*a, **k)

    monkeypatch.setattr(tracer, "render", spy)
    frames = []
    vr = viewport.ViewportRender(settings=tracer.RenderSettings(light_samples=4))
    vr.on_frame = lambda: frames.append(vr.latest())
    try:
        vr.set_scene(scene)
        vr.set_view(_camera(), SIZE)
        assert vr.wait_until_converged(600)
        assert not vr.set_view(_camera(), SIZE)  # the same view: nothing restarts
        n = len(frames)
        assert vr.set_view(_camera(1.0), SIZE)
        assert vr.wait_until_converged(600)
        moved = frames[n:]
        assert moved[0].level == viewport.LEVELS[0] and moved[-1].level == 1
        assert all(f.key != frames[n - 1].key for f in moved)
        assert set(threads) == {"whitted-viewport"}  # set_view / latest (what view_draw calls) never trace
        assert not vr.errors
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

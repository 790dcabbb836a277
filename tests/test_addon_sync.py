"""The add-on's scene sync (addon/sync.py) and the F12 paths that use it, through the bpy module:

- each kind of Blender edit becomes exactly its session edit (a camera move nothing else, a material a repack, a
  move a transform, ...) and the edited session renders what a fresh export of the edited scene renders;
- Geometry-Nodes instances placed in one vectorised batch give the pixels of one-by-one placement, and follow
  their instancer's moves as transforms;
- Persistent Data: the second F12 reuses the session (its stats say which edits it synced) with the pixels of an
  F12 without it;
- Esc during the export stops it (nothing traced).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from blender_kit import scatter
from blender_kit import scene as bs

import bpy  # noqa: E402

import addon  # noqa: E402
from addon import engine, export, sync  # noqa: E402
import tracer  # noqa: E402

SETTINGS = tracer.RenderSettings(width=64, height=48, samples=1, light_samples=1, threads=2)
#: Objects moved by set_transform are Embree instances in the session where a fresh export has moved triangles:
#: float32 rounding may differ this much on a few pixels (tests/test_session.py measures it: ≤ 3.3e-3 on 0.014 %).
PIXEL_TOLERANCE = 5e-3
MOVED_PIXELS_FRACTION = 0.005


@pytest.fixture(scope="module")
def whitted():
    addon.register()
    yield engine
    addon.unregister()


def _scene():
    bs.reset(size=(64, 48))
    red = bs.principled_material("red", **{"Base Color": (0.8, 0.1, 0.1)})
    bs.add_uv_sphere((0, 0, 1), 1.0, material=red, name="A", segments=24, rings=12)
    bs.add_cube((2.5, 0, 1), 1.0, name="B")
    bs.add_plane((0, 0, 0), 10.0, name="Floor")
    bs.add_camera((0, -8, 3), (0, 0, 0.5))
    bs.add_point_light((3, -3, 5), power=800, name="Key")
    bs.set_world((0.1, 0.1, 0.2))
    return red


class _Driver:
    """What view_update does, driven by Blender's depsgraph_update_post handler (which sees depsgraph.updates as
    view_update does): the sync's edits, applied to one session."""

    def __init__(self, track_camera=True):
        self.sync = sync.SceneSync(track_camera=track_camera)
        self.session = None
        self(bpy.context.scene, bpy.context.evaluated_depsgraph_get())  # the first view_update: a full export
        bpy.app.handlers.depsgraph_update_post.append(self)

    def __call__(self, scene, depsgraph):
        self.edits = self.sync.update(depsgraph)
        self.session = sync.apply_edits(self.session, self.edits)

    def step(self, change):
        self.edits = []
        change()
        bpy.context.view_layer.update()
        return [e.kind for e in self.edits]

    def close(self):
        bpy.app.handlers.depsgraph_update_post.remove(self)
        if self.session is not None:
            self.session.close()


def _fresh():
    scene, _ = export.scene_from_depsgraph(bpy.context.evaluated_depsgraph_get())
    return tracer.render(scene, SETTINGS).rgba


def _close(got, want):
    off = np.abs(got - want) > PIXEL_TOLERANCE
    return off.mean() <= MOVED_PIXELS_FRACTION and np.abs(got - want).max() < 0.2


def test_each_blender_edit_becomes_only_its_session_edit():
    red = _scene()
    d = _Driver()
    try:
        assert [e.kind for e in d.edits] == ["rebuild"]
        assert d.step(lambda: None) == []
        np.testing.assert_array_equal(d.session.render(SETTINGS).rgba, _fresh())
        a, b = bpy.data.objects["A"], bpy.data.objects["B"]
        oid = {name: i for i, name in enumerate(d.session.scene.object_names)}

        def check(kinds, change):
            got = d.step(change)
            assert got == kinds, (kinds, got)
            assert _close(d.session.render(SETTINGS).rgba, _fresh())

        check(["transform"], lambda: setattr(a, "location", (0.5, 0.3, 1.2)))
        assert d.edits[0].args[0] == oid["A"]
        check(["materials"], lambda: bs.principled_node(red).inputs["Base Color"].__setattr__(
            "default_value", (0.1, 0.8, 0.1, 1)))

        def geometry():
            b.data.vertices[0].co.z += 0.5
            b.data.update()
        check(["mesh"], geometry)
        assert d.edits[0].args[0] == oid["B"]
        check(["lights"], lambda: setattr(bpy.data.objects["Key"].data, "energy", 300))
        check(["world"], lambda: bs.set_world((0.3, 0.1, 0.1)))
        check(["add"], lambda: bs.add_cube((-2.5, 0, 1), 0.8, name="C"))
        check(["remove"], lambda: setattr(bpy.data.objects["C"], "hide_viewport", True))
        check(["camera"], lambda: setattr(bpy.data.objects["Camera"], "location", (1, -8, 3)))
        # a new material on an object: the table grows, that object's material ids change (its mesh only)
        blue = bs.principled_material("blue", **{"Base Color": (0.1, 0.1, 0.8)})
        check(["materials", "mesh"], lambda: b.data.materials.append(blue))
        assert d.edits[1].args[0] == oid["B"]
    finally:
        d.close()


def test_an_update_reads_again_only_what_it_names(monkeypatch):
    """Cycles' sync_recalc: a material edit reads that material's node tree only and walks no instance (issue #22:
    every update once re-read every node tree and walked every instance); a pass-index edit walks the objects and
    reads no material."""
    from addon import model

    red = _scene()
    bpy.data.objects["B"].data.materials.append(bs.principled_material("green", **{"Base Color": (0.1, 0.8, 0.1)}))
    d = _Driver()
    read, walked = [], []
    real_read, real_walk = model.read_material, export.export_objects
    monkeypatch.setattr(model, "read_material", lambda mat, *a, **k: read.append(mat.name) or real_read(mat, *a, **k))
    monkeypatch.setattr(export, "export_objects", lambda *a, **k: walked.append(1) or real_walk(*a, **k))
    try:
        assert d.step(lambda: bs.principled_node(red).inputs["Base Color"].__setattr__(
            "default_value", (0.1, 0.1, 0.9, 1))) == ["materials"]
        assert read == ["red"] and walked == []
        assert _close(d.session.render(SETTINGS).rgba, _fresh())
        read.clear()
        a = bpy.data.objects["A"]
        d.step(lambda: setattr(a, "pass_index", 5))
        oid = d.session.scene.object_names.index("A")
        assert walked and read == [] and d.sync.pass_indices[oid] == 5
    finally:
        d.close()


def test_the_viewport_sync_leaves_the_camera_to_the_view():
    _scene()
    d = _Driver(track_camera=False)
    try:
        assert d.step(lambda: setattr(bpy.data.objects["Camera"], "location", (1, -8, 3))) == []
    finally:
        d.close()


def _scatter(nx=6, ny=5, name="Scatter"):
    """A plane whose Geometry Nodes put a rotated, scaled icosphere (a material set on it) on each grid point."""
    paint = bs.principled_material("paint", **{"Base Color": (0.2, 0.5, 0.8)})
    return scatter.add(scatter.graph(name, size=(6.0, 4.0), points=(nx, ny), material=paint), (0, 0, 1))


def test_geometry_nodes_instances_batched_equal_one_by_one_and_move_as_transforms(monkeypatch):
    bs.reset(size=(64, 48))
    host = _scatter()
    bs.add_plane((0, 0, 0), 20.0, name="Floor")
    bs.add_camera((0, -9, 6), (0, 0, 1))
    bs.add_point_light((3, -3, 8), power=1500)
    dg = bpy.context.evaluated_depsgraph_get()
    objects = []
    batched, _ = export.scene_from_depsgraph(dg, objects=objects)
    assert sum(o.key[0] != "Floor" for o in objects) == 30
    # one shared mesh (a prototype after the 31 objects) and 30 instances of it, with their own object ids
    assert batched.instances is not None and len(batched.instances) == 30
    assert sorted(batched.instances.object_ids.tolist()) == [i for i, o in enumerate(objects) if o.key[0] != "Floor"]
    monkeypatch.setattr(export, "BATCH_MIN", 10**9)
    one_by_one, _ = export.scene_from_depsgraph(dg)
    monkeypatch.undo()
    assert one_by_one.instances is None and len(batched.triangles) * 10 < len(one_by_one.triangles)
    ids = dataclasses.replace(SETTINGS, aovs=("objectid",))
    a, b = tracer.render(batched, ids), tracer.render(one_by_one, ids)
    assert _close(a.rgba, b.rgba)
    assert (a.aovs["objectid"] == b.aovs["objectid"]).mean() > 0.995

    d = _Driver()
    try:
        kinds = d.step(lambda: setattr(host, "location", (0.4, 0.5, 1.3)))
        assert kinds == ["transform"] * 30
        assert _close(d.session.render(SETTINGS).rgba, _fresh())
        kinds = d.step(lambda: setattr(host, "rotation_euler", (0.0, 0.0, 0.3)))  # again, from the moved place
        assert kinds == ["transform"] * 30
        assert _close(d.session.render(SETTINGS).rgba, _fresh())
        # the instanced mesh itself edited in the node tree: one edit of the shared mesh, not 30 copies
        ico = next(n for n in host.modifiers["Scatter"].node_group.nodes if n.bl_idname == "GeometryNodeMeshIcoSphere")
        kinds = d.step(lambda: setattr(ico.inputs["Radius"], "default_value", 0.2))
        assert kinds == ["mesh"], kinds
        assert len(d.session.scene.instances) == 30
        assert _close(d.session.render(SETTINGS).rgba, _fresh())
    finally:
        d.close()


# ------------------------------------------------------------------------------------------------ F12 paths
@pytest.fixture()
def f12(whitted, tmp_path):
    """F12 into an EXR. The output settings are set once, before the first render: setting them (or the engine)
    again makes Blender free the persistent render data, as it should when a user changes them."""
    path = str(tmp_path / "f12.exr")
    first = [True]

    def render():
        if first[0]:
            bs.render_exr(bpy.context.scene, path, engine="WHITTED")
            first[0] = False
        else:
            bpy.ops.render.render(write_still=True)
        return bs.read_exr(path)["rgba"], engine.WhittedRenderEngine.last_render.stats

    return render


def test_persistent_data_reuses_the_session_with_the_same_pixels(f12):
    _scene()
    scene = bpy.context.scene
    scene.whitted.samples = 1
    scene.render.use_persistent_data = True
    try:
        first, stats = f12()
        assert stats["persistent"] and stats["sync"]["edits"] == {"rebuild": 1}
        bpy.data.objects["Camera"].location = (1.0, -8.0, 3.2)
        moved, stats = f12()
        assert stats["sync"]["edits"] == {"camera": 1}  # nothing else re-exported or rebuilt
        again, stats = f12()
        assert stats["sync"]["edits"] == {}
        np.testing.assert_array_equal(again, moved)
        bpy.data.objects["A"].location = (0.6, 0.0, 1.1)
        obj_moved, stats = f12()
        assert stats["sync"]["edits"] == {"transform": 1}
        scene.render.use_persistent_data = False
        fresh, stats = f12()
        assert not stats["persistent"] and "sync" not in stats
        assert _close(obj_moved, fresh)
        bpy.data.objects["A"].location = (0.0, 0.0, 1.0)
        back, _ = f12()
        bpy.data.objects["Camera"].location = (1.0, -8.0, 3.2)
        np.testing.assert_array_equal(back, moved)  # (the same state, one without persistent data)
    finally:
        scene.render.use_persistent_data = False


def test_persistent_data_follows_animation_frames(f12):
    _scene()
    scene = bpy.context.scene
    scene.whitted.samples = 1
    a = bpy.data.objects["A"]
    a.location = (0.0, 0.0, 1.0)
    a.keyframe_insert("location", frame=1)
    a.location = (1.0, 0.5, 1.5)
    a.keyframe_insert("location", frame=10)
    scene.render.use_persistent_data = True
    try:
        scene.frame_set(1)
        f12()
        scene.frame_set(5)
        frame5, stats = f12()
        assert stats["sync"]["edits"] == {"transform": 1}
        scene.render.use_persistent_data = False
        fresh5, _ = f12()
        assert _close(frame5, fresh5)
    finally:
        scene.render.use_persistent_data = False


def test_esc_during_export_stops_it(whitted, monkeypatch):
    """Esc (test_break) is polled while the depsgraph's instances are exported: the render stops there."""
    bs.reset(size=(32, 24))
    mesh = bs.add_cube((0, 0, 0), 0.2, name="Box0").data
    for i in range(1, 200):
        obj = bpy.data.objects.new(f"Box{i}", mesh)
        obj.location = (i % 20 * 0.3 - 3, 0, i // 20 * 0.3)
        bpy.context.scene.collection.objects.link(obj)
    bs.add_camera((0, -10, 2), (0, 0, 1.5))
    bpy.context.scene.render.engine = "WHITTED"
    polls = []
    monkeypatch.setattr(export, "POLL_EVERY", 16)
    monkeypatch.setattr(engine.WhittedRenderEngine, "break_hook", lambda: polls.append(1) or len(polls) >= 3)
    for persistent in (False, True):
        polls.clear()
        bpy.context.scene.render.use_persistent_data = persistent
        engine.WhittedRenderEngine.last_render = None
        bpy.ops.render.render()
        assert engine.WhittedRenderEngine.last_render.stats == {"cancelled": True, "cancelled_in": "export"}
        assert len(polls) == 3  # stopped at the third poll, 32 instances in: not after the 200
    bpy.context.scene.render.use_persistent_data = False


def test_esc_during_the_embree_build_stops_it(whitted, monkeypatch, tmp_path):
    """Esc once the scene is exported, while the session's Embree scene is built (the build polls between objects
    and inside Embree's builds): nothing is traced, and Blender still writes the (black) image."""
    bs.reset(size=(32, 24))
    bs.add_uv_sphere((0, 0, 1), 1.0, name="A")
    bs.add_cube((2.5, 0, 1), 1.0, name="B")
    bs.add_camera((0, -8, 3), (0, 0, 0.5))
    scene = bpy.context.scene
    scene.render.engine = "WHITTED"
    scene.render.image_settings.file_format = "PNG"
    building = [False]
    real = tracer.Session.__init__

    def init(self, *a, **k):
        building[0] = True
        return real(self, *a, **k)

    monkeypatch.setattr(tracer.Session, "__init__", init)
    monkeypatch.setattr(engine.WhittedRenderEngine, "break_hook", lambda: building[0])
    for persistent in (False, True):
        building[0] = False
        scene.render.use_persistent_data = persistent
        scene.render.filepath = str(tmp_path / f"esc{int(persistent)}.png")
        engine.WhittedRenderEngine.last_render = None
        bpy.ops.render.render(write_still=True)
        assert engine.WhittedRenderEngine.last_render.stats == {"cancelled": True, "cancelled_in": "build"}
        assert (tmp_path / f"esc{int(persistent)}.png").exists()
    scene.render.use_persistent_data = False

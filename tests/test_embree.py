"""Our Embree 4 binding (tracer/accel/embree.py): struct layouts against closed-form hits, instances, tnear/tfar,
errors raised as exceptions, and a clear message when the library cannot be found or is not Embree 4."""

from __future__ import annotations

import ctypes
import glob
import os

import numpy as np
import pytest

from tracer.accel import embree
from tracer import Camera, Materials, Scene, SceneBuilder
from tracer.accel.accelerator import Accelerator


def _triangle_scene(instanced, transforms=None):
    """Two objects: the unit right triangle in z = 0 (object 0) and the same one at z = -1 (object 1)."""
    b = SceneBuilder()
    tri_v, tri_f = [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]
    b.add_mesh(tri_v, tri_f, name="top")
    b.add_mesh(np.array(tri_v, float) - (0, 0, 1), tri_f, name="bottom")
    b.camera = Camera.look_at((0, 0, 5), (0, 0, 0))
    scene = b.build()
    return scene, Accelerator(scene, instanced=instanced)


@pytest.mark.parametrize("instanced", [False, True])
def test_hit_fields_match_the_closed_form(instanced):
    """A ray straight down at (x, y) hits the triangle at t = height, with barycentrics u = x, v = y: checks the
    RTCRayHit layout (tfar, u, v, primID, geomID / instID) read back by the kernel."""
    scene, acc = _triangle_scene(instanced)
    o = np.array([[0.2, 0.3, 2.0], [0.6, 0.1, 2.0], [0.9, 0.9, 2.0]], np.float32)
    d = np.tile(np.array([0, 0, -1], np.float32), (3, 1))
    t, prim, u, v = acc.intersect(o, d)
    np.testing.assert_allclose(t[:2], [2.0, 2.0], rtol=1e-6)
    np.testing.assert_allclose(u[:2], [0.2, 0.6], atol=1e-6)
    np.testing.assert_allclose(v[:2], [0.3, 0.1], atol=1e-6)
    assert prim.tolist() == [0, 0, -1] and np.isinf(t[2])
    # Bounded rays (t_max) and a tnear past the first triangle reach the second one (row 1, object 1).
    t, prim, _, _ = acc.intersect(o[:1], d[:1], t_min=2.5)
    assert prim.tolist() == [1] and t[0] == pytest.approx(3.0)
    t, prim, _, _ = acc.intersect(o[:1], d[:1], np.array([1.9], np.float32))
    assert prim.tolist() == [-1]
    assert acc.occluded(o, d, np.array([2.1, 1.9, 10.0], np.float32)).tolist() == [True, False, False]
    assert acc.occluded(o[:1], d[:1], np.array([10.0], np.float32), t_min=3.5).tolist() == [False]


def test_instance_transform_moves_hits_and_maps_rows():
    """Object 0 lifted by an instance matrix: the ray meets it 0.5 higher; rows still index scene.triangles."""
    scene, acc = _triangle_scene(True)
    acc.set_transform(0, _lifted(0.5))
    o = np.array([[0.2, 0.3, 2.0]], np.float32)
    d = np.array([[0, 0, -1]], np.float32)
    t, prim, u, v = acc.intersect(o, d)
    assert prim.tolist() == [0]
    assert t[0] == pytest.approx(1.5) and u[0] == pytest.approx(0.2) and v[0] == pytest.approx(0.3)
    # Rotate object 1 by 90 degrees about z around the origin: the point (0.2, 0.3) is now outside it, while
    # (-0.3, 0.2) is where (0.2, 0.3) went.
    r = np.eye(4)
    r[:2, :2] = [[0, -1], [1, 0]]
    acc.set_transform(1, r)
    acc.set_transform(0, _lifted(5.0))  # object 0 above the rays' origins, out of the way
    t, prim, u, v = acc.intersect(np.array([[-0.3, 0.2, 2.0], [0.2, 0.3, 2.0]], np.float32), np.tile(d, (2, 1)))
    assert prim.tolist() == [1, -1] and t[0] == pytest.approx(3.0)
    assert u[0] == pytest.approx(0.2) and v[0] == pytest.approx(0.3)


def _lifted(z):
    m = np.eye(4)
    m[2, 3] = z
    return m


def test_unsorted_object_ids_map_back_to_their_rows():
    """Objects whose triangles are interleaved in scene.triangles still report the right row."""
    b = SceneBuilder()
    quads = []
    for k in range(3):
        v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float) + (2.0 * k, 0, 0)
        quads.append(v)
    b.camera = Camera.look_at((0, 0, 5), (0, 0, 0))
    verts = np.concatenate(quads)
    tris = np.array([[0, 1, 2], [4, 5, 6], [8, 9, 10], [0, 2, 3], [4, 6, 7], [8, 10, 11]])
    scene = Scene(vertices=verts, triangles=tris, materials=Materials.from_list([{}]), camera=b.camera,
                  object_ids=np.array([0, 1, 2, 0, 1, 2]))
    for instanced in (False, True):
        acc = Accelerator(scene, instanced=instanced)
        xs = np.array([[0.7, 0.2], [0.2, 0.7], [2.7, 0.2], [2.2, 0.7], [4.7, 0.2], [4.2, 0.7]])
        o = np.column_stack([xs, np.full(6, 1.0)]).astype(np.float32)
        _, prim, _, _ = acc.intersect(o, np.tile(np.array([0, 0, -1], np.float32), (6, 1)))
        assert prim.tolist() == [0, 3, 1, 4, 2, 5]


def test_embree_errors_become_exceptions():
    """Embree reports a misaligned shared buffer through its error callback: the call raises EmbreeError with
    Embree's code and message instead of printing and going on."""
    lib = embree.library()
    geom = embree.Geometry(embree.GEOMETRY_TYPE_TRIANGLE)
    buf = np.zeros(64, np.uint8)
    with pytest.raises(embree.EmbreeError, match="RTC_ERROR_INVALID_OPERATION.*4 bytes aligned"):
        lib.call("rtcSetSharedGeometryBuffer", geom.handle, embree.BUFFER_TYPE_VERTEX, 0, embree.FORMAT_FLOAT3,
                 buf.ctypes.data + 1, 0, 12, 3)
    # ... and the error does not linger into the next, valid call.
    v = embree.padded(np.zeros((3, 3), np.float32), np.float32)
    lib.call("rtcSetSharedGeometryBuffer", geom.handle, embree.BUFFER_TYPE_VERTEX, 0, embree.FORMAT_FLOAT3,
             v.ctypes.data, 0, 12, 3)
    with pytest.raises(embree.EmbreeError, match="RTC_ERROR_INVALID_ARGUMENT"):
        embree.EmbreeScene(quality="medium").attach(geom, 0xFFFFFFFF)  # the invalid geometry id


def test_version_is_checked():
    major, minor, _ = embree.library().version
    assert (major, minor) >= embree.REQUIRED_VERSION and major == 4
    assert embree.version().startswith("4.")


def test_missing_library_says_where_it_looked(monkeypatch, tmp_path):
    monkeypatch.delenv(embree.LIBRARY_ENV, raising=False)
    monkeypatch.setattr("sys.path", [str(tmp_path)])
    with pytest.raises(embree.EmbreeUnavailable, match=f"not found.*pip install embreex.*{embree.LIBRARY_ENV}"):
        embree.find_library()
    # The wheel's layouts on the three platforms are all searched.
    for sub in ("embreex.libs", os.path.join("embreex", ".dylibs")):
        (tmp_path / sub).mkdir(parents=True)
    with pytest.raises(embree.EmbreeUnavailable, match="embreex.libs.*dylibs"):
        embree.find_library()
    monkeypatch.setenv(embree.LIBRARY_ENV, str(tmp_path / "nope.so"))
    with pytest.raises(embree.EmbreeUnavailable, match="is not a file"):
        embree.find_library()


def test_vendored_library_is_found_on_each_platform_layout(monkeypatch, tmp_path):
    monkeypatch.delenv(embree.LIBRARY_ENV, raising=False)
    layouts = {"linux": ("embreex.libs", "libembree4-4aef3270.so.4"),
               "darwin": (os.path.join("embreex", ".dylibs"), "libembree4.4.dylib"),
               "win32": ("embreex.libs", "embree4-0b3a8d41.dll")}
    for platform, (sub, name) in layouts.items():
        root = tmp_path / platform
        (root / sub).mkdir(parents=True)
        (root / sub / name).write_bytes(b"")
        monkeypatch.setattr("sys.platform", platform)
        monkeypatch.setattr("sys.path", [str(root)])
        assert embree.find_library() == str(root / sub / name)


def test_a_library_that_is_not_embree_4_is_refused():
    """Loading another shared library (the TBB that ships beside Embree) fails with a clear message."""
    libdir = os.path.dirname(embree.library().path)
    other = [p for p in glob.glob(os.path.join(libdir, "*")) if "embree" not in os.path.basename(p)]
    assert other
    with pytest.raises(embree.EmbreeUnavailable, match="not an Embree 4 library"):
        embree._Library(other[0])
    with pytest.raises(embree.EmbreeUnavailable, match="could not be loaded"):
        embree._Library(__file__)


@pytest.mark.parametrize("lanes", embree.QUERY_WIDTHS)
def test_packet_layout_matches_the_header(lanes):
    """The kernels' word offsets agree with RTCRayHit (one ray) and RTCRayHit4/8/16 as rtcore_ray.h declares them
    (laid out by ctypes; RTCRay and RTCHit are 16-byte aligned, the packets 4·N-byte aligned)."""
    row = (lambda t: t * lanes) if lanes > 1 else (lambda t: t)  # noqa: E731

    class RTCRay(ctypes.Structure):
        _fields_ = ([(n, row(ctypes.c_float)) for n in ("org_x", "org_y", "org_z", "tnear", "dir_x", "dir_y",
                                                         "dir_z", "time", "tfar")]
                    + [(n, row(ctypes.c_uint)) for n in ("mask", "id", "flags")])

    class RTCHit(ctypes.Structure):  # RTC_MAX_INSTANCE_LEVEL_COUNT = 1, RTC_GEOMETRY_INSTANCE_ARRAY on
        _fields_ = ([(n, row(ctypes.c_float)) for n in ("Ng_x", "Ng_y", "Ng_z", "u", "v")]
                    + [(n, row(ctypes.c_uint)) for n in ("primID", "geomID")]
                    + [("instID", row(ctypes.c_uint) * 1), ("instPrimID", row(ctypes.c_uint) * 1)])

    align = max(16, 4 * lanes)
    ray_size = ctypes.sizeof(RTCRay)
    hit_size = -(-ctypes.sizeof(RTCHit) // align) * align  # padded to its alignment
    assert ray_size == 4 * embree.RAY_FIELDS * lanes and ray_size % align == 0
    assert ray_size + hit_size <= 4 * 24 * embree.MAX_PACKET  # the kernels' work buffer holds it
    field = lambda f: getattr(RTCRay, f).offset // (4 * lanes)  # noqa: E731
    hit = lambda f: (ray_size + getattr(RTCHit, f).offset) // (4 * lanes)  # noqa: E731
    assert [field(f) for f in ("org_x", "org_y", "org_z", "tnear", "dir_x", "dir_y", "dir_z", "time", "tfar",
                               "mask", "id", "flags")] == list(range(12))
    assert (hit("u"), hit("v"), hit("primID"), hit("geomID"), hit("instID"), hit("instPrimID")) == (
        embree._U, embree._V, embree._PRIM, embree._GEOM, embree._INST, embree._INST_PRIM)


@pytest.mark.parametrize("width", embree.QUERY_WIDTHS)
@pytest.mark.parametrize("coherent", [False, True])
def test_every_packet_width_finds_the_same_hits(width, coherent):
    """One ray per call, packets of 4, 8 and 16, coherent or not: the closed-form hits of rays fanned at a wall of
    two triangles (z = 1 for x < 0, z = 2 for x ≥ 0), 37 rays (partial last packets), every third one cut short
    before the wall, shadow rays too; a bad lane offset or packet width would scramble them."""
    b = SceneBuilder()
    b.add_mesh([[-5, -5, 1], [0, -5, 1], [0, 5, 1], [-5, 5, 1]], [[0, 1, 2], [0, 2, 3]], name="left")
    b.add_mesh([[0, -5, 2], [5, -5, 2], [5, 5, 2], [0, 5, 2]], [[0, 1, 2], [0, 2, 3]], name="right")
    b.camera = Camera.look_at((0, 0, 5), (0, 0, 0))
    acc = Accelerator(b.build())
    x = (np.linspace(-4, 4, 37) + 0.05).astype(np.float32)  # no ray on the seam
    o = np.stack([x, 0.1 * x, np.full_like(x, 10)], 1).astype(np.float32)
    d = np.tile(np.array([0, 0, -1], np.float32), (37, 1))
    t_max = np.where(np.arange(37) % 3 == 0, 5.0, np.inf).astype(np.float32)
    expect_t = np.where(x < 0, 9.0, 8.0)
    short = t_max < expect_t
    expect_t[short] = np.inf
    t, prim, u, v, inst = (np.empty(37, np.float32), np.empty(37, np.int32), np.empty(37, np.int32),
                           np.empty(37, np.float32), np.empty(37, np.float32))
    q = embree.query(coherent, width)
    order = np.arange(37)[::-1].copy()  # packets made in reverse: results still land on their own rows
    embree.intersect_rays(acc._top.handle, o, d, np.float32(0), t_max, acc._start, acc._rows, acc._inst_proto, t,
                          prim, inst, u, v, embree.ALL_RAYS, np.zeros(0, np.float32), order, q)
    np.testing.assert_allclose(t, expect_t)
    assert np.all((prim[~short] >= 2) == (x[~short] >= 0)) and np.all(prim[short] == -1)
    blocked = np.empty(37, np.bool_)
    embree.occluded_rays(acc._top.handle, o, d, np.float32(0), t_max, blocked, embree.ALL_RAYS,
                         np.zeros(0, np.float32), embree.IN_ORDER, q)
    assert np.array_equal(blocked, ~short)


def test_instance_array_hits_report_the_prototype_row_and_the_instance():
    """Three instances of the unit right triangle (the prototype, object 1, in object space) lifted to z = 1, 2, 3
    (the third also turned 90° about z) and a world-space triangle at z = 0 (object 0): closed-form t, row and
    instance index, the barycentrics in the prototype's own corners."""
    b = SceneBuilder()
    tri_v, tri_f = [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]
    b.add_mesh(tri_v, tri_f, name="ground")
    proto = b.add_mesh(tri_v, tri_f, name="proto")
    turn = _lifted(3.0)
    turn[:2, :2] = [[0, -1], [1, 0]]
    ids = b.add_instances(proto, np.stack([_lifted(1.0), _lifted(2.0), turn]))
    b.camera = Camera.look_at((0, 0, 5), (0, 0, 0))
    scene = b.build()
    for instanced in (False, True):
        acc = Accelerator(scene, instanced=instanced)
        o = np.array([[0.2, 0.3, 10.0], [0.2, 0.3, 10.0], [0.2, 0.3, 10.0], [-0.3, 0.2, 10.0], [0.5, 0.6, 10.0]],
                     np.float32)
        d = np.tile(np.array([0, 0, -1], np.float32), (5, 1))
        hits = acc.closest_hits(o, d)
        hits2 = acc.closest_hits(o[1:2], d[1:2], t_min=8.5)  # past instance 1 (z = 2): instance 0 (z = 1)
        hits3 = acc.closest_hits(o[2:3], d[2:3], t_min=9.5)  # past both: the ground
        assert hits.inst.tolist()[:4] == [1, 1, 1, 2] and hits.prim.tolist()[:4] == [1, 1, 1, 1]
        np.testing.assert_allclose(hits.t[:4], [8.0, 8.0, 8.0, 7.0], rtol=1e-6)
        # the turned instance: (-0.3, 0.2) is (0.2, 0.3) of the prototype
        np.testing.assert_allclose([hits.u[3], hits.v[3]], [0.2, 0.3], atol=1e-6)
        assert hits.prim[4] == -1 and hits.inst[4] == -1 and np.isinf(hits.t[4])
        assert hits2.inst.tolist() == [0] and hits2.prim.tolist() == [1] and hits2.t[0] == pytest.approx(9.0)
        assert hits3.prim.tolist() == [0] and hits3.inst.tolist() == [-1] and hits3.t[0] == pytest.approx(10.0)
        assert acc.occluded(o[:1], d[:1], np.array([8.5], np.float32)).tolist() == [True]
        assert acc.occluded(o[:1], d[:1], np.array([7.5], np.float32)).tolist() == [False]
        # moving one instance rewrites its transform row only
        acc.set_instance_transforms([1], _lifted(4.0)[None])
        assert acc.closest_hits(o[:1], d[:1]).t[0] == pytest.approx(6.0)
        acc.close()
    assert scene.instances.object_ids.tolist() == ids.tolist() == [2, 3, 4]

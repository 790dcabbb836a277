"""Bad input raises clear errors that name the problem, not numpy tracebacks."""

import numpy as np
import pytest

from tracer import Camera, DistantLight, Materials, PointLight, RenderSettings, Scene, SceneBuilder, SpotLight
from tracer import render

TRI = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)


def scene(**overrides):
    kw = dict(vertices=TRI, triangles=[[0, 1, 2]], materials=Materials.from_list([{}]), camera=Camera())
    kw.update(overrides)
    return Scene(**kw)


def test_nan_vertex_names_the_vertex():
    v = TRI.copy()
    v[1, 2] = np.nan
    with pytest.raises(ValueError, match=r"vertex 1 has a NaN or infinite"):
        scene(vertices=v)


def test_infinite_vertex():
    v = TRI.copy()
    v[2, 0] = np.inf
    with pytest.raises(ValueError, match="vertex 2"):
        scene(vertices=v)


def test_out_of_range_index():
    with pytest.raises(ValueError, match=r"triangle 0 has index \[0, 1, 7\] outside the 3 vertices"):
        scene(triangles=[[0, 1, 7]])


def test_negative_index():
    with pytest.raises(ValueError, match="outside"):
        scene(triangles=[[0, -1, 2]])


@pytest.mark.parametrize("ior", [0.0, -1.5])
def test_ior_must_be_positive(ior):
    with pytest.raises(ValueError, match=r"ior must be > 0"):
        scene(materials=Materials.from_list([{"name": "bad glass", "ior": ior}]))


def test_material_id_out_of_range():
    with pytest.raises(ValueError, match="uses material 3"):
        scene(material_ids=[3])


def test_unknown_material_field_is_named():
    with pytest.raises(ValueError, match=r"unknown field\(s\) \['colour'\]"):
        Materials.from_list([{"colour": (1, 0, 0)}])


def test_k_m_out_of_range():
    with pytest.raises(ValueError, match=r"k_m must be in \[0, 1\]"):
        scene(materials=Materials.from_list([{"k_m": 1.5}]))


def test_degenerate_triangles_are_skipped_with_a_warning():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]], np.float32)
    with pytest.warns(UserWarning, match="skipped 1 degenerate"):
        s = scene(vertices=v, triangles=[[0, 1, 2], [0, 1, 3]], material_ids=[0, 0], object_ids=[0, 1])
    assert len(s.triangles) == 1 and s.skipped_triangles == 1 and s.object_ids.tolist() == [0]


def test_wrong_shapes():
    with pytest.raises(ValueError, match=r"vertices must have shape \(V, 3\)"):
        scene(vertices=np.zeros((3, 2)))
    with pytest.raises(ValueError, match=r"normals must have shape \(3, 3\) \(per vertex\) or \(1, 3, 3\)"):
        scene(normals=np.zeros((2, 3)))


def test_lights_validate():
    with pytest.raises(ValueError, match="position must be 3 finite numbers"):
        PointLight(position=(0, np.nan, 0), intensity=(1, 1, 1))
    with pytest.raises(ValueError, match="radius must be >= 0"):
        PointLight(position=(0, 0, 0), intensity=(1, 1, 1), radius=-1)
    with pytest.raises(ValueError, match="zero vector"):
        DistantLight(direction=(0, 0, 0), irradiance=(1, 1, 1))
    with pytest.raises(ValueError, match="blend must be in"):
        SpotLight(position=(0, 0, 0), intensity=(1, 1, 1), direction=(0, 0, -1), blend=2)


@pytest.mark.parametrize("field,value,msg", [("width", 0, "width must be an integer >= 1"),
                                             ("samples", 0, "samples"), ("max_depth", -1, "max_depth"),
                                             ("epsilon", -1.0, "epsilon"), ("aovs", ("velocity",), "unknown AOV")])
def test_bad_settings(field, value, msg):
    with pytest.raises(ValueError, match=msg):
        render(scene(), RenderSettings(samples=1, width=8, height=8).with_(**{field: value}))


def test_render_wants_a_scene():
    with pytest.raises(TypeError, match="expects a tracer.Scene"):
        render({"vertices": TRI})


def test_empty_scene_renders_the_background():
    b = SceneBuilder()
    b.camera = Camera()
    b.background = np.array([0.25, 0.5, 1.0], np.float32)
    img = render(b.build(), RenderSettings(samples=1, width=4, height=3))
    np.testing.assert_allclose(img.rgb, np.broadcast_to([0.25, 0.5, 1.0], (3, 4, 3)))


def test_write_to_missing_directory_fails_cleanly(tmp_path):
    img = render(scene(), RenderSettings(samples=1, width=4, height=4))
    with pytest.raises(ValueError, match="does not exist"):
        img.save(tmp_path / "nope" / "x.png")
    with pytest.raises(ValueError, match="extension"):
        img.save(tmp_path / "noext")
    assert list(tmp_path.iterdir()) == []


def test_mirroring_transform_keeps_front_faces_outside():
    b = SceneBuilder()
    b.camera = Camera()
    mirror = np.diag([-1.0, 1.0, 1.0, 1.0])
    b.add_mesh(TRI, [[0, 1, 2]], transform=mirror, normals=np.tile([0.0, 0.0, 1.0], (3, 1)))
    s = b.build()
    tri = s.vertices[s.triangles[0]]
    face_normal = np.cross(tri[1] - tri[0], tri[2] - tri[0])
    assert face_normal[2] > 0  # the winding was turned back: still facing +z like its shading normals
    with pytest.raises(ValueError, match="singular"):
        b.add_mesh(TRI, [[0, 1, 2]], transform=np.diag([0.0, 1.0, 1.0, 1.0]))


def test_nan_area_light_size_is_rejected():
    from tracer import AreaLight

    with pytest.raises(ValueError, match="size"):
        AreaLight(position=(0, 0, 1), u_axis=(1, 0, 0), v_axis=(0, 1, 0), normal=(0, 0, -1), size=(np.nan, 1.0),
                  radiance=(1, 1, 1))


def _big_soup(n=150_000, seed=3):
    """n random triangles (more rows than one thread takes: the validation passes split them across cores),
    with known degenerate ones, unusable normals and infinite UVs planted; one unreferenced far vertex."""
    rng = np.random.default_rng(seed)
    v = rng.uniform(-1, 1, (3 * n + 1, 3)).astype(np.float32)
    v[-1] = (500, 500, 500)  # referenced by no triangle: not in the bounds
    t = np.arange(3 * n, dtype=np.int32).reshape(n, 3)
    flat = rng.choice(n, 900, replace=False)
    v[t[flat[:300], 2]] = v[t[flat[:300], 0]]  # a repeated point
    v[t[flat[300:600], 2]] = 2 * v[t[flat[300:600], 1]] - v[t[flat[300:600], 0]]  # collinear: p2 = p1 + (p1 - p0)
    t[flat[600:], 1] = t[flat[600:], 0]  # a repeated index
    nr = rng.normal(size=(n, 3, 3)).astype(np.float32) * rng.uniform(0.1, 10, (n, 3, 1)).astype(np.float32)
    nr[7, 1] = 0
    nr[8, 2] = (np.nan, 1, 0)
    uv = rng.random((n, 3, 2)).astype(np.float32)
    uv[9, 0, 1] = np.inf
    return v, t, nr, uv, flat


def test_validation_passes_on_many_triangles_match_closed_forms():
    """Scene.validate's per-triangle passes (numba, split across threads) against the definitions in float64
    numpy: exactly the planted zero-area triangles dropped (collinear ones in float32 may be off by rounding: their
    area is tested against 1e-14 of the diagonal², as numpy says), normals of unit length (zero where unusable),
    infinite UVs as NaN, bounds of the referenced vertices only; the caller's arrays untouched."""
    v, t, nr, uv, flat = _big_soup()
    nr_in, uv_in = nr.copy(), uv.copy()
    tri = v[t].astype(np.float64)
    area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    used = v[np.unique(t)].astype(np.float64)  # the diagonal: of what the triangles reference
    diag = np.linalg.norm(used.max(0) - used.min(0))
    keep = area2 > 1e-14 * diag**2
    assert (~keep).sum() >= 600 and not keep[flat[:300]].any() and not keep[flat[600:]].any()
    with pytest.warns(UserWarning, match="degenerate"):
        s = scene(vertices=v, triangles=t, normals=nr, uvs=uv)
    np.testing.assert_array_equal(nr, nr_in)  # validation copied what it was handed, did not write over it
    np.testing.assert_array_equal(uv, uv_in)
    np.testing.assert_array_equal(s.triangles, t[keep])
    assert s.skipped_triangles == (~keep).sum()
    drawn = v[np.unique(t[keep])].astype(np.float64)
    np.testing.assert_array_equal(s.bounds, [drawn.min(0), drawn.max(0)])
    want = nr_in.astype(np.float64)
    length = np.linalg.norm(want, axis=-1, keepdims=True)
    ok = np.isfinite(length) & (length > 0)
    want = np.where(ok, want / np.where(ok, length, 1), 0)[keep]
    np.testing.assert_allclose(s.normals, want, atol=1e-6)
    assert (s.normals[np.searchsorted(np.flatnonzero(keep), 7), 1] == 0).all()
    kept_uv = uv_in[keep]
    assert np.isnan(s.uvs[np.searchsorted(np.flatnonzero(keep), 9), 0, 1])
    np.testing.assert_array_equal(np.isnan(s.uvs), np.isinf(kept_uv))


def test_builder_builds_twice_and_hands_its_arrays_over():
    """SceneBuilder.build joins its pieces (freeing them) and keeps the joined arrays: a second build() gives the
    same scene, meshes added after it come on top; the normals the builder hands over are normalised in place
    without touching the caller's arrays."""
    b = SceneBuilder()
    m = b.add_material("m")
    n1 = np.tile(np.array([[0.0, 0.0, 3.0]]), (3, 1))
    b.add_mesh(TRI, [[0, 1, 2]], material=m, normals=n1, uvs=np.zeros((3, 2)))
    b.add_mesh(TRI + 2, [[0, 1, 2]], material=m, colors=np.ones((3, 3)) * 0.5)
    b.camera = Camera()
    first, second = b.build(), b.build()
    assert n1[0, 2] == 3.0
    for name in ("vertices", "triangles", "normals", "colors", "material_ids", "object_ids"):
        np.testing.assert_array_equal(getattr(first, name), getattr(second, name), err_msg=name)
    np.testing.assert_array_equal(first.uvs, second.uvs)
    np.testing.assert_allclose(first.corner_normals()[0], [[0, 0, 1]] * 3)
    assert np.isnan(first.corner_uvs()[1]).all() and (first.colors[0] == 1).all() and (first.colors[1] == 0.5).all()
    b.add_mesh(TRI + 4, [[0, 1, 2]], material=m, uvs=np.ones((3, 2)))
    third = b.build()
    assert len(third.triangles) == 3 and third.triangles[2].min() == 6
    np.testing.assert_array_equal(third.corner_uvs()[:2], first.corner_uvs(), strict=False)
    assert (third.corner_uvs()[2] == 1).all() and (third.corner_normals()[2] == 0).all()


def _smooth_textured_ball(hard_box: bool):
    """A UV sphere with per-vertex normals and UVs, a checker base colour and a bumpy normal map (UV lookups and
    tangents), and optionally a box with flat (per-face) normals: a hard edge."""
    import trimesh

    b = SceneBuilder()
    checks = np.kron((np.indices((8, 8)).sum(axis=0) % 2)[..., None] * [0.8, 0.2, 0.1] + 0.1, np.ones((4, 4, 1)))
    bumps = np.zeros((32, 32, 3)) + [0.5, 0.5, 1.0]
    bumps[..., 0] += 0.3 * np.sin(np.arange(32) / 2.0)[None, :]
    m = b.add_material("m", diffuse=(1, 1, 1), diffuse_texture=b.add_texture(checks.astype(np.float32)),
                       normal_texture=b.add_texture(bumps.astype(np.float32)), specular=0.5, roughness=0.3)
    ball = trimesh.creation.uv_sphere(radius=1.0, count=[24, 24])
    uv = np.stack([np.arctan2(ball.vertices[:, 1], ball.vertices[:, 0]) / (2 * np.pi) + 0.5,
                   np.arccos(np.clip(ball.vertices[:, 2], -1, 1)) / np.pi], axis=1)
    b.add_mesh(ball.vertices, ball.faces, material=m, normals=ball.vertices, uvs=uv[ball.faces], name="ball")
    if hard_box:
        box = trimesh.creation.box(extents=(0.8, 0.8, 0.8))
        b.add_mesh(box.vertices + [1.6, 0, 0], box.faces, material=m, name="box",
                   normals=np.repeat(box.face_normals[:, None], 3, axis=1))
    b.add_light(PointLight(position=(3, -4, 5), intensity=(200.0,) * 3))
    b.camera = Camera.look_at((0.5, -5, 1), (0.5, 0, 0), up=(0, 0, 1), focal_length=35.0)
    return b.build()


@pytest.mark.parametrize("hard_box", [False, True])
def test_per_vertex_normals_and_uvs_draw_what_per_corner_ones_draw(hard_box):
    """SceneBuilder stores normals and UVs per vertex where every corner of a vertex agrees (6 + 4 bytes per
    triangle on a closed mesh instead of 36 + 24); a mesh with a hard edge keeps the scene's normals per corner.
    The same scene given per corner (the layout before) renders bit for bit the same picture."""
    s = _smooth_textured_ball(hard_box)
    assert s.normals_per_vertex != hard_box and s.uvs_per_vertex
    assert s.normals.shape == ((len(s.triangles), 3, 3) if hard_box else (len(s.vertices), 3))
    def again(normals, uv_sets):  # both validated once more (normalising a unit normal may move its last bit)
        return Scene(vertices=s.vertices, triangles=s.triangles, materials=s.materials, camera=s.camera,
                     lights=s.lights, textures=s.textures, material_ids=s.material_ids, object_ids=s.object_ids,
                     normals=normals, uv_sets=uv_sets)

    corners = again(s.corner_normals(), [s.corner_uvs(k) for k in range(len(s.uv_sets))])
    assert not corners.normals_per_vertex and not corners.uvs_per_vertex
    st = RenderSettings(width=48, height=36, samples=1, aovs=("normal",))
    a, b = render(again(s.normals, list(s.uv_sets)), st), render(corners, st)
    np.testing.assert_array_equal(a.rgba, b.rgba)
    np.testing.assert_array_equal(a.aovs["normal"], b.aovs["normal"])
    assert len(np.unique(np.round(a.rgba[..., 0], 2))) > 10  # textured and shaded, not flat

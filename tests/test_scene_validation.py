"""Bad input raises clear errors that name the problem, not numpy tracebacks."""

import numpy as np
import pytest

from tracer import (Camera, DistantLight, Materials, PointLight, RenderSettings, Scene, SceneBuilder, SpotLight,
                    render)

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
    with pytest.raises(ValueError, match=r"normals must have shape \(1, 3, 3\)"):
        scene(normals=np.zeros((3, 3)))


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

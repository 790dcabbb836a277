"""addon.export: Blender's evaluated depsgraph -> tracer.Scene, checked value by value (no rendering).

Blender is the reference for every number: its own camera projection (world_to_camera_view), its light units
(DESIGN.md "Measured facts"), and its evaluated geometry (modifiers, instances).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from blender_kit import scene as bs

import bpy  # noqa: E402  (the test extra installs bpy; a missing bpy must fail, not skip)

from addon import export  # noqa: E402  (needs bpy)


def depsgraph():
    return bpy.context.evaluated_depsgraph_get()


CAMERAS = [
    dict(lens=50, sensor_fit="AUTO", size=(160, 90)),
    dict(lens=35, sensor_fit="AUTO", size=(90, 160), shift=(0.1, -0.2)),
    dict(lens=28, sensor_fit="HORIZONTAL", size=(90, 160), sensor_width=30),
    dict(lens=80, sensor_fit="VERTICAL", size=(160, 90), sensor_height=20, shift=(-0.15, 0.05)),
    dict(ortho_scale=7.0, sensor_fit="AUTO", size=(120, 160), shift=(0.2, 0.1)),
    dict(ortho_scale=5.0, sensor_fit="VERTICAL", size=(160, 100)),
]


@pytest.mark.parametrize("cfg", CAMERAS, ids=lambda c: f"{c.get('ortho_scale', c.get('lens'))}-{c['sensor_fit']}"
                         f"-{c['size'][0]}x{c['size'][1]}")
def test_camera_matches_blender_projection(bpy_module, cfg):
    """Points project to the same image positions as Blender's own world_to_camera_view (to 1e-5 of the frame)."""
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector

    cfg = dict(cfg)
    size = cfg.pop("size")
    scene = bs.reset(size, percentage=50)
    cam = bs.add_camera((3.0, -7.0, 2.5), target=(0.3, 0.2, 0.4), **cfg)
    bpy.context.view_layer.update()
    w, h = export.render_size(scene)
    assert (w, h) == (size[0] // 2, size[1] // 2)
    tcam = export.camera_from_blender(cam, w, h)
    rng = np.random.default_rng(1)
    pts = rng.uniform(-2, 2, (50, 3))
    ours = tcam.project(pts, w, h)
    ref = np.array([tuple(world_to_camera_view(scene, cam, Vector(p))) for p in pts])
    np.testing.assert_allclose(ours[:, 0] / w, ref[:, 0], atol=1e-5)
    np.testing.assert_allclose(1.0 - ours[:, 1] / h, ref[:, 1], atol=1e-5)
    if "ortho_scale" not in cfg:
        np.testing.assert_allclose(ours[:, 2], ref[:, 2], rtol=1e-5)


def test_lights_in_blender_units(bpy_module):
    bs.reset()
    bs.add_camera()
    bs.add_point_light((1, 2, 3), power=1000, color=(1.0, 0.5, 0.25), radius=0.2)
    bs.add_sun((0.0, 0.6, -0.8), strength=3.0, angle=0.1)
    spot = bs.add_spot_light((0, 0, 4), target=(0, 0, 0), power=500, size=math.radians(60), blend=0.3)
    area = bs.add_area_light((0, -3, 3), target=(0, 0, 0), power=200, size=2.0, size_y=0.5, shape="RECTANGLE")
    area.scale = (2.0, 1.0, 1.0)
    disk = bs.add_area_light((3, 0, 3), target=(0, 0, 0), power=100, size=1.0, shape="DISK", name="Disk")
    disk.data.energy = 100
    disk.data.exposure = 1.0
    bs.add_plane()
    scene, warnings = export.scene_from_depsgraph(depsgraph())
    by_name = {l.name: l for l in scene.lights}
    p = by_name["Point"]
    np.testing.assert_allclose(p.position, (1, 2, 3), atol=1e-6)
    np.testing.assert_allclose(p.intensity, np.array([1.0, 0.5, 0.25]) * 1000 / (4 * math.pi), rtol=1e-6)
    assert p.radius == pytest.approx(0.2)
    sun = by_name["Sun"]
    np.testing.assert_allclose(sun.direction, np.array([0.0, 0.6, -0.8]), atol=1e-6)
    np.testing.assert_allclose(sun.irradiance, 3.0, rtol=1e-6)
    assert sun.angle == pytest.approx(0.1)
    s = by_name["Spot"]
    np.testing.assert_allclose(s.direction, (0, 0, -1), atol=1e-6)
    assert s.cone_angle == pytest.approx(math.radians(30)) and s.blend == pytest.approx(0.3)
    np.testing.assert_allclose(s.intensity, 500 / (4 * math.pi), rtol=1e-6)
    a = by_name["Area"]
    assert a.shape == "rect" and a.size == pytest.approx((4.0, 0.5))
    np.testing.assert_allclose(a.radiance, 200 / (math.pi * 2.0), rtol=1e-6)
    to_target = -np.array(area.location) / np.linalg.norm(area.location)
    np.testing.assert_allclose(a.normal, to_target, atol=1e-6)  # emits along its -Z, towards what it aims at
    d = by_name["Disk"]
    assert d.shape == "disk"
    np.testing.assert_allclose(d.radiance, 2.0 * 100 / (math.pi * math.pi / 4), rtol=1e-6)  # exposure 1: ×2
    assert not warnings


def test_world_materials_and_fallback_warning(bpy_module):
    bs.reset()
    bs.add_camera()
    bs.set_world((0.2, 0.3, 0.4), strength=2.0)
    mat = bs.principled_material("P", base_color=(0.5, 0.25, 0.1), metallic=0.3, roughness=0.2, ior=1.45,
                                 specular=0.8, transmission=0.6, emission_color=(1.0, 0.5, 0.0),
                                 emission_strength=3.0)
    bs.add_uv_sphere(material=mat)
    odd = bpy.data.materials.new("Odd")
    odd.diffuse_color = (0.1, 0.9, 0.2, 1.0)
    if bpy.app.version < (5, 0, 0):
        odd.use_nodes = True
    nodes = odd.node_tree.nodes
    for n in list(nodes):
        if n.type == "BSDF_PRINCIPLED":
            nodes.remove(n)
    toon = nodes.new("ShaderNodeBsdfToon")
    toon.inputs["Color"].default_value = (0.1, 0.9, 0.2, 1.0)  # the colour Cycles shows: the best available
    odd.diffuse_color = (0.5, 0.5, 0.5, 1.0)
    out = next(n for n in nodes if n.type == "OUTPUT_MATERIAL")
    odd.node_tree.links.new(toon.outputs[0], out.inputs["Surface"])
    bs.add_cube((3, 0, 0), material=odd)
    scene, warnings = export.scene_from_depsgraph(depsgraph())
    np.testing.assert_allclose(scene.background, (0.4, 0.6, 0.8), rtol=1e-6)
    np.testing.assert_allclose(scene.ambient, (0.4, 0.6, 0.8), rtol=1e-6)
    m = scene.materials
    i = m.names.index("P")
    np.testing.assert_allclose(m.diffuse[i], (0.5, 0.25, 0.1), rtol=1e-6)
    # the Principled inputs as they are (the tracer's Principled model; no mirror weight of the notes)
    assert m.metallic[i] == pytest.approx(0.3) and m.k_m[i] == 0.0
    assert m.roughness[i] == pytest.approx(0.2) and m.specular[i] == pytest.approx(0.8)
    assert m.ior[i] == pytest.approx(1.45) and m.transmission[i] == pytest.approx(0.6)
    # a Principled's glass tints each refraction by sqrt(Base Color), as Cycles' (in and out: the base colour;
    # measured through bpy in tests/test_rough_glass.py::test_principled_glass_tints_by_the_square_root_...)
    np.testing.assert_allclose(m.transmission_tint[i], np.sqrt((0.5, 0.25, 0.1)), rtol=1e-6)
    np.testing.assert_allclose(m.emission[i], (3.0, 1.5, 0.0), rtol=1e-6)
    j = m.names.index("Odd")
    np.testing.assert_allclose(m.diffuse[j], (0.1, 0.9, 0.2), rtol=1e-6)
    assert len([w for w in warnings if "Odd" in w]) == 1


def test_modifiers_normals_uvs_and_per_face_materials(bpy_module):
    bs.reset()
    bs.add_camera()
    red = bs.principled_material("Red", base_color=(1, 0, 0))
    blue = bs.principled_material("Blue", base_color=(0, 0, 1))
    cube = bs.add_cube(material=red)
    cube.data.materials.append(blue)
    cube.data.polygons[0].material_index = 1
    cube.modifiers.new("sub", "SUBSURF").levels = 1
    sphere = bs.add_uv_sphere((4, 0, 0), 1.0, segments=16, rings=8)
    scene, _ = export.scene_from_depsgraph(depsgraph())
    names = scene.object_names
    cube_tris = scene.object_ids == names.index("Cube")
    assert cube_tris.sum() == 6 * 4 * 2  # subdivided once: 24 quads after the modifier, not 12 triangles
    mats = np.unique(scene.material_ids[cube_tris])
    assert {scene.materials.names[k] for k in mats} == {"Red", "Blue"}
    sph = scene.object_ids == names.index("Sphere")
    # smooth shading: corner normals point away from the centre (radial), not along the face normal
    corners = scene.vertices[scene.triangles[sph]] - np.array([4.0, 0, 0])
    radial = corners / np.linalg.norm(corners, axis=-1, keepdims=True)
    assert np.einsum("tcx,tcx->tc", scene.corner_normals(sph), radial).min() > 0.999
    assert scene.uvs is not None and np.ptp(scene.corner_uvs(0, sph)[..., 0]) > 0.9
    assert sphere.name in names


def test_instances_and_pass_index(bpy_module):
    bs.reset()
    bs.add_camera()
    coll = bpy.data.collections.new("Src")
    bpy.context.scene.collection.children.link(coll)
    src = bs.add_cube(size=0.5, name="Src")
    bpy.context.scene.collection.objects.unlink(src)
    coll.objects.link(src)
    src.pass_index = 7
    coll.hide_render = False
    for k in range(3):
        empty = bpy.data.objects.new(f"Inst{k}", None)
        empty.instance_type = "COLLECTION"
        empty.instance_collection = coll
        empty.location = (2.0 * (k + 1), 0, 0)
        bpy.context.scene.collection.objects.link(empty)
    scene, _ = export.scene_from_depsgraph(depsgraph())
    assert len(scene.object_names) == 4  # the source cube and three collection instances
    centres = sorted(float(scene.vertices[scene.triangles[scene.object_ids == i]].mean(axis=(0, 1))[0])
                     for i in range(4))
    np.testing.assert_allclose(centres, [0.0, 2.0, 4.0, 6.0], atol=1e-5)
    assert list(scene.object_pass_indices) == [7, 7, 7, 7]


def test_mirrored_objects_keep_outward_front_faces_and_zero_scale_is_skipped(bpy_module):
    """A negative scale turns the triangles' winding; the export turns it back so the geometric normal (which
    decides entering vs leaving glass) still points out of the object. A zero-scaled object is skipped, not a
    LinAlgError."""
    bs.reset()
    bs.add_camera()
    mirrored = bs.add_uv_sphere((3, 0, 0), 1.0, segments=16, rings=8)
    mirrored.name = "Mirrored"
    mirrored.scale = (-1.0, 1.0, 1.0)
    hidden = bs.add_cube((-3, 0, 0))
    hidden.name = "Hidden"
    hidden.scale = (0.0, 0.0, 0.0)
    scene, warnings = export.scene_from_depsgraph(depsgraph())
    assert scene.object_names == ["Mirrored"]
    assert any("Hidden" in w for w in warnings)
    p = scene.vertices[scene.triangles].astype(np.float64)
    ng = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    outward = p.mean(axis=1) - np.array([3.0, 0.0, 0.0])
    assert np.einsum("ij,ij->i", ng, outward).min() > 0
    # the shading normals still agree with the geometric ones
    assert np.einsum("tcx,tx->tc", scene.corner_normals().astype(np.float64), ng).min() > 0


def test_settings_from_scene(bpy_module):
    import addon

    addon.register()
    try:
        scene = bs.reset((200, 100), percentage=50)
        scene.whitted.samples, scene.whitted.max_depth, scene.whitted.epsilon = 3, 4, 0.001
        scene.whitted.fresnel, scene.whitted.shadows, scene.whitted.threads = False, False, 2
        scene.whitted.shading, scene.whitted.max_transparent = "classic", 3
        scene.render.film_transparent = True
        scene.render.use_border = True
        scene.render.border_min_x, scene.render.border_max_x = 0.25, 0.5
        scene.render.border_min_y, scene.render.border_max_y = 0.0, 0.5
        scene.view_layers[0].use_pass_z = True
        s = export.settings_from_scene(scene)
        assert (s.width, s.height, s.samples, s.max_depth) == (100, 50, 3, 4) and s.epsilon == pytest.approx(0.001)
        assert (s.fresnel, s.shadows, s.threads, s.transparent) == (False, False, 2, True)
        assert (s.shading, s.max_transparent) == ("classic", 3)
        assert s.region == (25, 25, 50, 50)  # bottom half of the image, second quarter from the left
        assert s.aovs == ("depth",)
    finally:
        addon.unregister()


def test_blenders_own_switches_are_the_depth_of_field_and_motion_blur_settings(bpy_module):
    """Blender's Camera > Depth of Field and Render > Motion Blur checkboxes are RenderSettings.depth_of_field and
    motion_blur (what ``whitted render --no-dof/--no-motion-blur`` set), both off in a new Blender scene."""
    import addon

    addon.register()
    try:
        scene = bs.reset((40, 20))
        assert export.settings_from_scene(scene).depth_of_field is False  # no camera: no lens
        bs.add_camera()
        s = export.settings_from_scene(scene)
        assert (s.depth_of_field, s.motion_blur) == (False, False)
        scene.camera.data.dof.use_dof = True
        scene.render.use_motion_blur = True
        s = export.settings_from_scene(scene)
        assert (s.depth_of_field, s.motion_blur) == (True, True)
    finally:
        addon.unregister()

"""Issue #32, Blender part: the patterns that made third-party .blend files render wrongly against Cycles
(tools/blender_fidelity.py measures the files; docs/fidelity.md, "Blender scenes against Cycles"), each rebuilt
here with bpy (no third-party file is read) and held to a closed form where one exists, else to Cycles.

- **Area lights**: irradiance from a one-sided rectangular Lambertian emitter (Lambert's polygon formula) and its
  Spread, Cycles' soft-box grid ``max((tan(s/2) − tan θ)·N, 0)``, N = 1/(tan(s/2) − s/2), which keeps the power.
  A room under a narrow-spread ceiling light leaves its walls dark; a Portal lights nothing itself.
- **Attributes** (Attribute / Color Attribute nodes), as Cycles reads them (measured with emission probes): a
  name the mesh lacks reads black (Color Attribute Alpha 0, Attribute Alpha 1); any generic attribute of that
  name on any domain is read (a face-domain float: one value per face, "speckled"); a UV map's name reads
  (u, v, 0); Fac is the mean of the components.
- **Missing images** (a file that is not there: glTF test scenes name an HDR they do not ship): Cycles renders
  them magenta, in a material and in the world.
- **Media** (a material's Volume output): Volume Absorption inside glass attenuates what is seen through it by
  Beer–Lambert over the length inside, exp(−(1 − Color)·Density·t), and Emission inside adds E/σ·(1 − exp(−σ·t)):
  against the closed form through a sphere of IOR 1 (no refraction) and against Cycles.
- **Sheen** (Sheen BSDF Ashikhmin = the old Velvet, Sheen BSDF microfiber, Principled Sheen Weight): the lobe
  as Cycles evaluates it (tracer.shading.sheen), not a Diffuse stand-in (3× too bright); **subsurface** (Principled weight,
  Subsurface Scattering node) as diffuse of its colour: spheres against Cycles.
- **World colour behind procedural materials** (pattern 4): a render (F12) sees what Cycles sees: the world's
  Background colour × strength where rays leave, and no object hidden from renders (a backdrop plane with
  ``hide_render``, as the plaster/water material library files carry, is drawn in the viewport only).
- **glTF-style meshes**: one mesh, one material per primitive, each reading its own Color Attribute, and a
  Color Attribute's alpha cutting the surface out (the glTF importer's vertex-colour alpha).
"""

from __future__ import annotations

import functools
import math
import os
import sys

import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "cycles"))

import cycles_harness as H  # noqa: E402

from blender_kit import scene as bs  # noqa: E402

pytestmark = pytest.mark.blender


# ---------------------------------------------------------------------------------------------------- helpers
def ours_render(scene, samples: int = 4, depth: int = 4, light_samples: int = 64):
    """Our render of the current bpy scene through the add-on's export (as F12 reads it)."""
    import bpy

    import tracer
    from addon import export

    ts, warnings = export.scene_from_depsgraph(bpy.context.evaluated_depsgraph_get())
    w, h = export.render_size(scene)
    settings = tracer.RenderSettings(width=w, height=h, samples=samples, max_depth=depth,
                                     light_samples=light_samples, sky_samples=16, seed=0)
    return tracer.render(ts, settings).rgb, warnings


def diffuse_material(name, colour):
    import bpy

    mat = bpy.data.materials.new(name)
    nt = mat.node_tree
    for n in list(nt.nodes):
        if n.type != "OUTPUT_MATERIAL":
            nt.nodes.remove(n)
    out = next(n for n in nt.nodes if n.type == "OUTPUT_MATERIAL")
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = tuple(colour) + (1.0,)
    nt.links.new(d.outputs[0], out.inputs["Surface"])
    return mat


def source_of(*functions) -> str:
    """The source of a scene's builders: the key of its cached Cycles reference (an edit elsewhere in this file
    keeps the references)."""
    import inspect

    return "".join(inspect.getsource(f) for f in functions)


# ---------------------------------------------------------------------------------------------------- area lights
ALBEDO = 0.5
FLOOR = 4.0  # the floor's edge, m; the orthographic top view sees all of it
LIGHT_POWER = 200.0
LIGHT_TILT = math.radians(50)


def area_floor_scene(spread: float = math.pi, size=(64, 64)):
    """A diffuse floor (albedo 0.5) seen straight down by an orthographic camera, under a 1 m square area light
    at (0, 0, 1) turned 50° about +Y (its emitting side, local −Z, leans towards −X: the floor beyond the light's
    plane, at +X, is behind it), with Spread ``spread``."""
    import bpy

    scene = bs.reset(size)
    bs.add_camera((0.0, 0.0, 5.0), target=(0.0, 0.0, 0.0), ortho_scale=FLOOR)
    bs.set_world((0.0, 0.0, 0.0))
    bs.add_plane((0.0, 0.0, 0.0), FLOOR, material=diffuse_material("Floor", (ALBEDO,) * 3))
    light = bs.add_area_light((0.0, 0.0, 1.0), power=LIGHT_POWER, size=1.0)
    light.rotation_euler = (0.0, -LIGHT_TILT, 0.0)
    light.data.spread = spread
    bpy.context.view_layer.update()
    return scene, light


def light_frame(light):
    m = np.array(light.matrix_world, np.float64)
    return m[:3, 3], m[:3, 0], m[:3, 1], -m[:3, 2]  # centre, u, v, emitting normal (local −Z)


def spread_factor(cos_l: np.ndarray, spread: float) -> np.ndarray:
    """Cycles' area light spread (kernel/light/area.h, area_light_spread_attenuation): the share of a soft box's
    grid not hidden at angle θ from the normal, (tan(s/2) − tan θ)·N, normalised so that the light's power is kept:
    ∫ f·cos θ dω over the hemisphere = π gives N = 1 / (tan(s/2) − s/2)."""
    if spread >= math.pi - 1e-6:
        return np.ones_like(cos_l)
    h = spread / 2
    tan_a = np.sqrt(np.maximum(1 - cos_l ** 2, 0)) / np.maximum(cos_l, 1e-9)
    return np.maximum((math.tan(h) - tan_a) / (math.tan(h) - h), 0.0)


def closed_form_floor(light, spread: float, size=(64, 64), n: int = 96) -> np.ndarray:
    """Outgoing radiance a/π·E of the floor at each pixel centre, E integrated over the light (n × n midpoints of
    the square): Le·f(θ_l)·cos θ_s·cos θ_l / r² with Le = P/(π·A), one-sided (cos θ_l ≤ 0 gives nothing). Without
    spread this is Lambert's polygon formula to 1e-4 (checked below)."""
    c, u, v, nl = light_frame(light)
    w, h = size
    xs = (np.arange(w) + 0.5) / w * FLOOR - FLOOR / 2
    ys = FLOOR / 2 - (np.arange(h) + 0.5) / h * FLOOR
    px, py = np.meshgrid(xs, ys)
    p = np.stack([px, py, np.zeros_like(px)], -1).reshape(-1, 1, 3)
    g = (np.arange(n) + 0.5) / n - 0.5
    gu, gv = np.meshgrid(g, g)
    q = (c + gu.reshape(-1, 1) * u + gv.reshape(-1, 1) * v).reshape(1, -1, 3)
    d = q - p
    r2 = np.sum(d * d, -1)
    r = np.sqrt(r2)
    cos_s = np.maximum(d[..., 2] / r, 0.0)
    cos_l = np.maximum(-(d @ nl) / r, 0.0)
    le = LIGHT_POWER / (math.pi * 1.0)
    e = le * np.mean(spread_factor(cos_l, spread) * cos_s * cos_l / r2, axis=1) * 1.0  # × A = 1 m²
    return (ALBEDO / math.pi * e).reshape(h, w)


def lambert_polygon(p: np.ndarray, corners: np.ndarray, normal=(0.0, 0.0, 1.0)) -> float:
    """Lambert's formula: the irradiance from a unit-radiance polygon at p (normal ``normal``), Σ γ_i·n·(r_i ×
    r_{i+1})/|r_i × r_{i+1}| / 2 over its edges (γ_i the angle the edge subtends)."""
    n = np.asarray(normal, np.float64)
    total = 0.0
    for i in range(len(corners)):
        a, b = corners[i] - p, corners[(i + 1) % len(corners)] - p
        cr = np.cross(a, b)
        gamma = math.atan2(np.linalg.norm(cr), np.dot(a, b))
        total += gamma * np.dot(n, cr) / np.linalg.norm(cr)
    return abs(total) / 2


def test_the_floor_closed_form_is_lamberts_polygon_formula(bpy_module):
    """The numerical integral used for the closed form agrees with Lambert's exact polygon formula (no spread)."""
    _scene, light = area_floor_scene()
    c, u, v, _nl = light_frame(light)
    corners = np.array([c - u / 2 - v / 2, c + u / 2 - v / 2, c + u / 2 + v / 2, c - u / 2 + v / 2])
    img = closed_form_floor(light, math.pi, n=200)
    for x, y in ((10, 32), (32, 32), (20, 50)):
        p = np.array([(x + 0.5) / 64 * FLOOR - FLOOR / 2, FLOOR / 2 - (y + 0.5) / 64 * FLOOR, 0.0])
        facing = np.dot(p - c, -np.array(light.matrix_world)[:3, 2]) > 0
        exact = ALBEDO / math.pi * LIGHT_POWER / math.pi * lambert_polygon(p, corners) if facing else 0.0
        assert img[y, x] == pytest.approx(exact, rel=2e-3, abs=1e-5)


def _region_check(ours, expected, label):
    """Ours against the closed form: the lit region's mean within 2 %, the dark region (where the closed form is
    < 0.1 % of its peak) dark, and PSNR ≥ 35 dB."""
    lit = expected > 0.05 * expected.max()
    dark = expected < 1e-3 * expected.max()
    mean_ratio = float(ours[lit].mean() / expected[lit].mean())
    assert mean_ratio == pytest.approx(1.0, abs=0.02), f"{label}: lit mean ours/closed form {mean_ratio:.3f}"
    assert float(ours[dark].max()) < 0.01 * float(expected.max()) + 1e-4, \
        f"{label}: {int((ours[dark] > 1e-3).sum())} pixels lit where the closed form is dark"
    p = H.psnr_srgb(np.repeat(ours[..., None], 3, -1), np.repeat(expected[..., None], 3, -1))
    assert p >= 35.0, f"{label}: {p:.1f} dB against the closed form"


@pytest.mark.parametrize("spread_deg", [180, 60])
def test_area_light_on_a_floor_matches_the_closed_form(bpy_module, spread_deg):
    """Ours against the closed form, one-sided, with Blender's Spread (60°: a narrow soft box)."""
    spread = math.radians(spread_deg)
    scene, light = area_floor_scene(spread)
    expected = closed_form_floor(light, spread)
    ours, warnings = ours_render(scene)
    assert not warnings, warnings
    _region_check(ours.mean(-1), expected, f"ours, spread {spread_deg}°")


@pytest.mark.cycles
@pytest.mark.parametrize("spread_deg", [180, 60])
def test_cycles_area_light_on_a_floor_matches_the_closed_form(bpy_module, spread_deg):
    """Cycles against the same closed form: which of the two renderers is right (both, after the spread fix)."""
    spread = math.radians(spread_deg)

    def build():
        return area_floor_scene(spread)[0]

    ref = H.cycles_render(f"area_floor_spread{spread_deg}", build, source_of(area_floor_scene, diffuse_material),
                          dict(depth=0, samples=512))
    _scene, light = area_floor_scene(spread)
    _region_check(ref.mean(-1), closed_form_floor(light, spread), f"Cycles, spread {spread_deg}°")


def room_scene(size=(96, 72)):
    """A closed 4 × 4 × 2.5 m room (grey diffuse walls, seen from inside by a 24 mm camera in a corner) under a 0.6 m
    ceiling light with a 70° Spread, and a Portal (an area light marked as one) in front of one wall under a black
    world: Cycles lights the floor under the lamp and leaves the walls dark; the portal emits nothing."""
    import bmesh
    import bpy

    scene = bs.reset(size)
    bs.set_world((0.0, 0.0, 0.0))
    mesh = bs._bmesh_mesh("Room", lambda bm: bmesh.ops.create_cube(bm, size=1.0, calc_uvs=True))
    room = bs._mesh_object("Room", mesh, (0.0, 0.0, 1.25), diffuse_material("Walls", (0.6, 0.6, 0.6)), False)
    room.scale = (4.0, 4.0, 2.5)
    lamp = bs.add_area_light((0.5, 0.5, 2.45), target=(0.5, 0.5, 0.0), power=60.0, size=0.6, name="Lamp")
    lamp.data.spread = math.radians(70)
    portal = bs.add_area_light((0.0, 1.9, 1.3), target=(0.0, 0.0, 1.3), power=500.0, size=1.2, name="Portal")
    portal.data.cycles.is_portal = True
    bs.add_camera((-1.8, -1.8, 1.9), target=(0.6, 0.6, 0.6), lens=18.0)
    bpy.context.view_layer.update()
    return scene


def test_a_portal_is_not_a_lamp(bpy_module):
    """A Portal only guides Cycles' sampling of the world: it is not exported as a light (one warning)."""
    import bpy

    from addon import export

    room_scene()
    ts, warnings = export.scene_from_depsgraph(bpy.context.evaluated_depsgraph_get())
    assert [lt.name for lt in ts.lights] == ["Lamp"]
    assert any("Portal" in w and "emits nothing" in w for w in warnings), warnings


@pytest.mark.cycles
def test_a_room_under_a_narrow_spread_lamp_matches_cycles(bpy_module, tmp_path):
    """The room against Cycles: the walls outside the lamp's 70° spread stay dark in both (before the spread and
    the portal were read, ours lit them and the portal lit the room: 2.2 dB)."""
    ref = H.cycles_render("room_spread_portal", room_scene, source_of(room_scene, diffuse_material),
                          dict(depth=0, samples=256))
    scene = room_scene()
    ours, _warnings = ours_render(scene)
    H.check_images({"name": "room_spread_portal"}, ours, ref, tmp_path, min_psnr=33.0, max_mae=0.004)


# ---------------------------------------------------------------------------------------------------- attributes
def grid_object(name, location, size=1.8, n=6, material=None):
    import bmesh

    mesh = bs._bmesh_mesh(name, lambda bm: bmesh.ops.create_grid(bm, x_segments=n, y_segments=n, size=size / 2,
                                                                   calc_uvs=True))
    return bs._mesh_object(name, mesh, location, material, False)


def attribute_scene(size=(80, 80)):
    """Four 6 × 6-quad tiles seen from above under a sun, each a Diffuse BSDF whose colour comes from an
    attribute: 'Col' (not on the mesh: Cycles reads black), 'speckle' (a face-domain float, a value per face),
    'UVMap' (a UV map's name: (u, v, 0)); the fourth is Mix Shader(Transparent, Diffuse) by the Alpha of a Color
    Attribute 'Gone' the mesh lacks (alpha 0: Cycles sees the red floor through it)."""
    import bpy

    scene = bs.reset(size)
    bs.add_camera((0.0, 0.0, 5.0), target=(0.0, 0.0, 0.0), ortho_scale=4.0)
    bs.set_world((0.0, 0.0, 0.0))
    bs.add_sun((0.0, 0.0, -1.0), strength=3.0)
    floor = bs.principled_material("Red", base_color=(0.7, 0.1, 0.1), specular=0.0)
    grid_object("Floor", (0.0, 0.0, -0.3), size=4.0, n=1, material=floor)
    spots = {"Col": (-1.0, 1.0), "speckle": (1.0, 1.0), "UVMap": (-1.0, -1.0), "Gone": (1.0, -1.0)}
    rng = np.random.default_rng(7)
    for attr, (x, y) in spots.items():
        mat, nt, out = bs.node_material(f"reads {attr}")
        diff = nt.nodes.new("ShaderNodeBsdfDiffuse")
        if attr == "Gone":
            node = nt.nodes.new("ShaderNodeVertexColor")
            node.layer_name = attr
            diff.inputs["Color"].default_value = (0.2, 0.5, 0.9, 1.0)
            mix = nt.nodes.new("ShaderNodeMixShader")
            transparent = nt.nodes.new("ShaderNodeBsdfTransparent")
            nt.links.new(node.outputs["Alpha"], mix.inputs["Fac"])
            nt.links.new(transparent.outputs[0], mix.inputs[1])
            nt.links.new(diff.outputs[0], mix.inputs[2])
            nt.links.new(mix.outputs[0], out.inputs["Surface"])
        else:
            node = nt.nodes.new("ShaderNodeAttribute")
            node.attribute_name = attr
            nt.links.new(node.outputs["Color"], diff.inputs["Color"])
            nt.links.new(diff.outputs[0], out.inputs["Surface"])
        ob = grid_object(f"tile {attr}", (x, y, 0.0), material=mat)
        if attr == "speckle":
            a = ob.data.attributes.new("speckle", "FLOAT", "FACE")
            a.data.foreach_set("value", rng.uniform(0.05, 0.9, len(a.data)).astype(np.float32))
    bpy.context.view_layer.update()
    return scene


def gltf_scene(size=(96, 72)):
    """A glTF import's shapes: one mesh (a cube) of two primitives, each with its own material reading its own
    Color Attribute ('Color' on points, 'Color.001' on corners), beside a cube whose Principled Alpha is its Color
    Attribute's alpha (0 on the upper vertices: its top fades out), in front of a red wall, under a point light."""
    import bmesh
    import bpy

    scene = bs.reset(size)
    bs.set_world((0.02, 0.02, 0.02))
    bs.add_point_light((2.0, -4.0, 5.0), power=1500.0)
    bs.add_camera((0.5, -7.0, 3.0), target=(0.5, 0.0, 0.3), lens=40.0)
    wall = bs.principled_material("Wall", base_color=(0.8, 0.1, 0.1), specular=0.0)
    bs.add_plane((0.5, 2.5, 1.0), 8.0, material=wall, name="Wall").rotation_euler = (math.pi / 2, 0, 0)
    bs.add_plane((0.5, 0.0, -1.0), 8.0, material=bs.principled_material("Floor", base_color=(0.5, 0.5, 0.5),
                                                                        specular=0.0), name="Floor")
    mats = []
    for i, attr in enumerate(("Color", "Color.001")):
        mat, nt, out = bs.node_material(f"primitive {i}")
        bsdf = nt.nodes.new("ShaderNodeBsdfPrincipled")
        bsdf.inputs["Specular IOR Level"].default_value = 0.0
        vc = nt.nodes.new("ShaderNodeVertexColor")
        vc.layer_name = attr
        nt.links.new(vc.outputs["Color"], bsdf.inputs["Base Color"])
        nt.links.new(bsdf.outputs[0], out.inputs["Surface"])
        mats.append(mat)
    mesh = bs._bmesh_mesh("Primitives", lambda bm: bmesh.ops.create_cube(bm, size=1.6, calc_uvs=True))
    for m in mats:
        mesh.materials.append(m)
    fn = np.empty(len(mesh.polygons) * 3, np.float32)
    mesh.polygons.foreach_get("normal", fn)
    fn = fn.reshape(-1, 3)  # the top and the sides facing ±X are primitive 1, the front and back primitive 0
    mesh.polygons.foreach_set("material_index", (np.abs(fn[:, 1]) < 0.5).astype(np.int32))
    c0 = mesh.color_attributes.new("Color", "FLOAT_COLOR", "POINT")
    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    c0.data.foreach_set("color", np.concatenate([0.5 + 0.3 * np.sign(co), np.ones((len(co), 1))], 1)
                        .astype(np.float32).ravel())
    c1 = mesh.color_attributes.new("Color.001", "FLOAT_COLOR", "CORNER")
    c1.data.foreach_set("color", np.tile(np.array([0.9, 0.8, 0.1, 1.0], np.float32), len(c1.data)))
    bs._mesh_object("Primitives", mesh, (-1.0, 0.0, 0.0), None, False)
    mat, nt, out = bs.node_material("vertex alpha")
    bsdf = nt.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    vc = nt.nodes.new("ShaderNodeVertexColor")
    nt.links.new(vc.outputs["Color"], bsdf.inputs["Base Color"])
    nt.links.new(vc.outputs["Alpha"], bsdf.inputs["Alpha"])
    nt.links.new(bsdf.outputs[0], out.inputs["Surface"])
    mesh = bs._bmesh_mesh("Faded", lambda bm: bmesh.ops.create_cube(bm, size=1.6, calc_uvs=True))
    mesh.materials.append(mat)
    ca = mesh.color_attributes.new("Col", "FLOAT_COLOR", "POINT")
    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    alpha = (co.reshape(-1, 3)[:, 2] < 0).astype(np.float32)
    ca.data.foreach_set("color", np.stack([np.full_like(alpha, 0.2), np.full_like(alpha, 0.4),
                                           np.full_like(alpha, 0.9), alpha], 1).ravel())
    bs._mesh_object("Faded", mesh, (1.8, 0.0, 0.0), None, False)
    bpy.context.view_layer.update()
    return scene


@pytest.mark.cycles
@pytest.mark.parametrize("name", ["attributes", "gltf_primitives"])
def test_attribute_scenes_match_cycles(bpy_module, tmp_path, name):
    build = {"attributes": attribute_scene, "gltf_primitives": gltf_scene}[name]
    ref = H.cycles_render(f"attr_{name}", build, source_of(build, bs.node_material, grid_object),
                          dict(depth=2, samples=64))
    scene = build()
    ours, warnings = ours_render(scene)
    H.check_images({"name": name}, ours, ref, tmp_path, min_psnr=35.0, max_mae=0.006)


# ---------------------------------------------------------------------------------------------------- images
def missing_image(name):
    """An image datablock naming a file that is not there (as a .blend whose textures were not shipped)."""
    import bpy

    img = bpy.data.images.new(name, 4, 4)
    img.source = "FILE"
    img.filepath = os.path.join(os.sep, "nonexistent-whitted-test", name)
    img.reload()
    return img


def missing_image_scene(size=(64, 48)):
    """A sphere whose Base Color is an Image Texture of a file that does not exist, under a world whose
    Environment Texture names another missing file (the world lights the sphere too), and a point light."""
    import bpy

    scene = bs.reset(size)
    bs.add_camera((0.0, -5.0, 0.0), target=(0.0, 0.0, 0.0), lens=50.0)
    bs.add_point_light((3.0, -3.0, 4.0), power=500.0)
    mat = bs.principled_material("Textured", specular=0.0)
    nt = mat.node_tree
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = missing_image("no_such_texture.png")
    nt.links.new(tex.outputs["Color"], bs.principled_node(mat).inputs["Base Color"])
    bs.add_uv_sphere((0.0, 0.0, 0.0), 1.0, material=mat)
    world = bs.set_world((0.05, 0.05, 0.05), strength=0.5)
    env = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = missing_image("no_such_sky.hdr")
    bg = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
    world.node_tree.links.new(env.outputs["Color"], bg.inputs["Color"])
    return scene


@pytest.mark.cycles
def test_missing_images_are_magenta_as_in_cycles(bpy_module, tmp_path):
    ref = H.cycles_render("missing_images", missing_image_scene, source_of(missing_image_scene, missing_image),
                          dict(depth=2, samples=64))
    ours, warnings = ours_render(missing_image_scene())
    assert sum("magenta" in w for w in warnings) == 2, warnings
    H.check_images({"name": "missing_images"}, ours, ref, tmp_path, min_psnr=35.0, max_mae=0.006)


def udim_scene_for_cycles():
    """tests/test_addon_texture.py's UDIM scene (tiles 1001 red, 1002 blue, 1011 green, 1012 absent, UVs over
    u, v ∈ [0, 2]), its tile files in a folder of the cache directory."""
    import test_addon_texture as T

    return T.udim_scene(os.path.join(H.CACHE_DIR, "udim-tiles"))


@pytest.mark.cycles
def test_udim_tiles_as_in_cycles(bpy_module, tmp_path):
    """A tiled image reads each tile where its number puts it, as Cycles does (and the absent tile magenta)."""
    import test_addon_texture as T

    ref = H.cycles_render("udim_tiles", udim_scene_for_cycles,
                          source_of(udim_scene_for_cycles, T.udim_scene, T.udim_image, T.udim_expected),
                          dict(depth=2, samples=16))
    np.testing.assert_allclose(ref[2:14, 2:14], T.udim_expected()[2:14, 2:14], atol=0.02)  # Cycles: 1011 green
    ours, warnings = ours_render(udim_scene_for_cycles(), samples=4, depth=2)
    assert not warnings, warnings
    H.check_images({"name": "udim_tiles"}, ours, ref, tmp_path, min_psnr=35.0, max_mae=0.006)


# ---------------------------------------------------------------------------------------------------- media
VOLUME_COLOUR = (0.3, 0.6, 0.9)
VOLUME_DENSITY = 1.5
VOLUME_EMISSION = (0.4, 0.2, 0.05)
BACKDROP = 0.8


def medium_scene(emission: bool = False, ior: float = 1.0, size=(64, 64)):
    """A glass sphere (r = 1, white Glass BSDF, IOR ``ior``) holding Volume Absorption (Color (0.3, 0.6, 0.9),
    Density 1.5) (+ Emission (0.4, 0.2, 0.05) in the volume), seen orthographically against an emissive backdrop of
    0.8 behind it, in a black world."""
    import bpy

    scene = bs.reset(size)
    bs.add_camera((0.0, -5.0, 0.0), target=(0.0, 0.0, 0.0), ortho_scale=2.4)
    bs.set_world((0.0, 0.0, 0.0))
    back, nt, out = bs.node_material("Backdrop")
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = (BACKDROP, BACKDROP, BACKDROP, 1.0)
    nt.links.new(em.outputs[0], out.inputs["Surface"])
    bs.add_plane((0.0, 3.0, 0.0), 8.0, material=back, name="Backdrop").rotation_euler = (math.pi / 2, 0, 0)
    glass, nt, out = bs.node_material("Juice glass")
    g = nt.nodes.new("ShaderNodeBsdfGlass")
    g.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    g.inputs["Roughness"].default_value = 0.0
    g.inputs["IOR"].default_value = ior
    nt.links.new(g.outputs[0], out.inputs["Surface"])
    ab = nt.nodes.new("ShaderNodeVolumeAbsorption")
    ab.inputs["Color"].default_value = VOLUME_COLOUR + (1.0,)
    ab.inputs["Density"].default_value = VOLUME_DENSITY
    vol = ab.outputs[0]
    if emission:
        ve = nt.nodes.new("ShaderNodeEmission")
        ve.inputs["Color"].default_value = VOLUME_EMISSION + (1.0,)
        ve.inputs["Strength"].default_value = 1.0
        add = nt.nodes.new("ShaderNodeAddShader")
        nt.links.new(ab.outputs[0], add.inputs[0])
        nt.links.new(ve.outputs[0], add.inputs[1])
        vol = add.outputs[0]
    nt.links.new(vol, out.inputs["Volume"])
    bs.add_uv_sphere((0.0, 0.0, 0.0), 1.0, segments=96, rings=48, material=glass)
    bpy.context.view_layer.update()
    return scene


def medium_closed_form(emission: bool, size=(64, 64)) -> tuple[np.ndarray, np.ndarray]:
    """(expected (H, W, 3), mask of pixels well inside the sphere): backdrop·exp(−σL) + E/σ·(1 − exp(−σL)),
    L = 2·√(1 − r²) the chord through the pixel centre."""
    w, h = size
    xs = ((np.arange(w) + 0.5) / w - 0.5) * 2.4
    zs = (0.5 - (np.arange(h) + 0.5) / h) * 2.4
    x, z = np.meshgrid(xs, zs)
    r2 = x * x + z * z
    chord = 2 * np.sqrt(np.maximum(1 - r2, 0))[..., None]
    sigma = (1 - np.array(VOLUME_COLOUR)) * VOLUME_DENSITY
    att = np.exp(-sigma * chord)
    out = BACKDROP * att
    if emission:
        out = out + np.array(VOLUME_EMISSION) / sigma * (1 - att)
    return out, r2 < 0.85 ** 2


@pytest.mark.parametrize("emission", [False, True])
def test_a_medium_in_glass_is_beer_lambert(bpy_module, emission):
    """Through a sphere of IOR 1 (no bending, no reflection) the pixels inside its outline hold the closed form: 1 %
    on the mean, 3 % each (the sphere is 96 × 48 flat facets: near the outline its chords differ from the true
    sphere's by up to 2 %)."""
    scene = medium_scene(emission)
    ours, warnings = ours_render(scene, samples=2)
    assert not warnings, warnings
    expected, inside = medium_closed_form(emission)
    ratio = ours[inside] / expected[inside]
    assert np.abs(np.mean(ratio, 0) - 1).max() < 0.01 and np.abs(ratio - 1).max() < 0.03, \
        f"ours / closed form: mean {np.mean(ratio, 0)}, range {ratio.min():.3f} .. {ratio.max():.3f}"


@pytest.mark.cycles
@pytest.mark.parametrize("emission", [False, True])
def test_cycles_medium_in_glass_is_the_same_closed_form(bpy_module, emission):
    """Cycles holds the same closed form (its Whitted-limited render: 1 % on the mean, 5 % each with its noise)."""
    ref = H.cycles_render(f"medium_ior1_{'glow' if emission else 'juice'}", lambda: medium_scene(emission),
                          source_of(medium_scene, bs.node_material) + str(emission), dict(depth=4, samples=128))
    expected, inside = medium_closed_form(emission)
    ratio = ref[inside] / expected[inside]
    assert np.abs(np.mean(ratio, 0) - 1).max() < 0.01 and np.abs(ratio - 1).max() < 0.05, \
        f"Cycles / closed form: mean {np.mean(ratio, 0)}, range {ratio.min():.3f} .. {ratio.max():.3f}"


@pytest.mark.cycles
@pytest.mark.parametrize("emission", [False, True])
def test_juice_and_glow_glass_match_cycles(bpy_module, tmp_path, emission):
    """Real glass (IOR 1.45) with the medium: refraction, Fresnel and Beer–Lambert against Cycles (before the
    Volume output was read: 2.3× / 0.5× the luminance in the material library survey)."""
    name = f"medium_ior145_{'glow' if emission else 'juice'}"
    ref = H.cycles_render(name, lambda: medium_scene(emission, 1.45), source_of(medium_scene, bs.node_material) +
                          str(emission), dict(depth=8, samples=256))
    ours, _warnings = ours_render(medium_scene(emission, 1.45), depth=8)
    H.check_images({"name": name}, ours, ref, tmp_path, min_psnr=35.0, max_mae=0.01)


# ---------------------------------------------------------------------------------------------------- sheen
def sheen_scene(kind: str, size=(72, 72)):
    """A smooth sphere of one material over a grey floor, lit by a point light from the front-left and a rim light
    from behind (where sheen shows), in a dim grey world. ``kind``: "velvet" (Sheen BSDF, Ashikhmin, roughness
    0.3), "microfiber" (Sheen BSDF, roughness 0.4), "microfiber_mix" (Mix 0.5 of a dark Diffuse and a microfiber
    sheen), "principled_sheen" (Principled, dark red base, Sheen Weight 1, tint white, roughness 0.3),
    "principled_sss" (Subsurface Weight 1, scale 0.05) or "sss_node" (Subsurface Scattering node)."""
    import bpy

    scene = bs.reset(size)
    bs.add_camera((0.0, -5.0, 0.8), target=(0.0, 0.0, 0.0), lens=50.0)
    bs.add_point_light((-3.0, -3.0, 3.0), power=600.0)
    bs.add_point_light((1.5, 4.0, 2.0), power=900.0, name="Rim")
    bs.set_world((0.03, 0.03, 0.03))
    bs.add_plane((0.0, 0.0, -1.0), 10.0, material=bs.principled_material("Floor", base_color=(0.4, 0.4, 0.4),
                                                                          specular=0.0))
    colour = (0.8, 0.3, 0.5, 1.0)
    mat, nt, out = bs.node_material(kind)
    if kind in ("velvet", "microfiber", "microfiber_mix"):
        sh = nt.nodes.new("ShaderNodeBsdfSheen")
        sh.distribution = "ASHIKHMIN" if kind == "velvet" else "MICROFIBER"
        sh.inputs["Color"].default_value = colour
        sh.inputs["Roughness"].default_value = 0.3 if kind == "velvet" else 0.4
        shader = sh.outputs[0]
        if kind == "microfiber_mix":
            diff = nt.nodes.new("ShaderNodeBsdfDiffuse")
            diff.inputs["Color"].default_value = (0.1, 0.05, 0.08, 1.0)
            mix = nt.nodes.new("ShaderNodeMixShader")
            nt.links.new(diff.outputs[0], mix.inputs[1])
            nt.links.new(sh.outputs[0], mix.inputs[2])
            shader = mix.outputs[0]
        nt.links.new(shader, out.inputs["Surface"])
    elif kind == "sss_node":
        n = nt.nodes.new("ShaderNodeSubsurfaceScattering")
        n.inputs["Color"].default_value = colour
        n.inputs["Scale"].default_value = 0.05
        nt.links.new(n.outputs[0], out.inputs["Surface"])
    else:
        p = nt.nodes.new("ShaderNodeBsdfPrincipled")
        p.inputs["Specular IOR Level"].default_value = 0.0
        if kind == "principled_sheen":
            p.inputs["Base Color"].default_value = (0.15, 0.02, 0.03, 1.0)
            p.inputs["Sheen Weight"].default_value = 1.0
            p.inputs["Sheen Roughness"].default_value = 0.3
        else:
            p.inputs["Base Color"].default_value = colour
            p.inputs["Subsurface Weight"].default_value = 1.0
            p.inputs["Subsurface Scale"].default_value = 0.05
        nt.links.new(p.outputs[0], out.inputs["Surface"])
    bs.add_uv_sphere((0.0, 0.0, 0.0), 1.0, segments=96, rings=48, material=mat)
    bpy.context.view_layer.update()
    return scene


#: PSNR bars of the sheen / subsurface spheres (measured, see the test).
SHEEN_BARS = {"velvet": 36.0, "microfiber": 37.0, "microfiber_mix": 38.0, "principled_sheen": 36.0,
              "principled_sss": 34.0, "sss_node": 34.0}


@pytest.mark.cycles
@pytest.mark.parametrize("kind", list(SHEEN_BARS))
def test_sheen_and_subsurface_spheres_match_cycles(bpy_module, tmp_path, kind):
    """Velvet is Cycles' analytic lobe (exact up to noise); microfiber is the LTC lobe with our measured table
    (tools/sheen_table.py); subsurface is diffuse of its colour (Cycles' Whitted-limited picture is within a few
    per cent: light carried under the surface towards the shadow side)."""
    ref = H.cycles_render(f"sheen_{kind}", lambda: sheen_scene(kind), source_of(sheen_scene, bs.node_material) + kind,
                          dict(depth=2, samples=256))
    ours, _warnings = ours_render(sheen_scene(kind))
    m = H.metrics(ours, ref)
    print(f"[cycles] sheen_{kind}: {m['psnr']:.2f} dB, mean ours/Cycles {m['mean_ours'] / m['mean_cycles']:.3f}")
    H.check_images({"name": f"sheen_{kind}"}, ours, ref, tmp_path, min_psnr=SHEEN_BARS[kind], max_mae=0.01)


# ---------------------------------------------------------------------------------------------------- world
def world_backdrop_scene(size=(80, 60)):
    """A noise-textured sphere under a world of colour (0.2, 0.25, 0.3) × strength 1.5, a sun, and a red emissive
    backdrop behind it that is hidden from renders (Object ▸ Visibility ▸ Renders off)."""
    import bpy

    scene = bs.reset(size)
    bs.add_camera((0.0, -6.0, 1.0), target=(0.0, 0.0, 0.0), lens=50.0)
    bs.set_world((0.2, 0.25, 0.3), 1.5)
    bs.add_sun((0.5, 0.6, -0.6), strength=2.0)
    mat, nt, out = bs.node_material("Plaster")
    bsdf = nt.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 4.0
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    nt.links.new(noise.outputs["Fac"], ramp.inputs["Fac"])
    nt.links.new(ramp.outputs["Color"], bsdf.inputs["Base Color"])
    nt.links.new(bsdf.outputs[0], out.inputs["Surface"])
    bs.add_uv_sphere((0.0, 0.0, 0.0), 1.2, material=mat)
    back, nt, out = bs.node_material("Backdrop")
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = (0.8, 0.1, 0.1, 1.0)
    nt.links.new(em.outputs[0], out.inputs["Surface"])
    plane = bs.add_plane((0.0, 4.0, 0.0), 20.0, material=back, name="BG")
    plane.rotation_euler = (math.pi / 2, 0.0, 0.0)
    plane.hide_render = True
    bpy.context.view_layer.update()
    return scene


@pytest.fixture
def whitted_engine(bpy_module):
    import addon

    addon.register()
    yield
    addon.unregister()


@pytest.mark.cycles
def test_world_colour_behind_a_procedural_material_matches_cycles_in_a_render(whitted_engine, tmp_path):
    """F12 with the add-on's engine (the render depsgraph: BG is not there) against Cycles. Ours through the
    viewport's depsgraph would draw the red backdrop: that, not the world colour, was the "background differs"."""
    from addon import engine

    ref = H.cycles_render("world_backdrop", world_backdrop_scene, source_of(world_backdrop_scene, bs.node_material),
                          dict(depth=2, samples=128))
    scene = world_backdrop_scene()
    scene.whitted.samples = 4
    ours = bs.render_exr(scene, engine="WHITTED")["rgba"][..., :3]
    assert engine.WhittedRenderEngine.last_render is not None
    H.check_images({"name": "world_backdrop"}, ours, ref, tmp_path, min_psnr=35.0, max_mae=0.006)
    corner = ours[:4, :4].reshape(-1, 3).mean(0)
    assert np.allclose(corner, np.array([0.2, 0.25, 0.3]) * 1.5, rtol=0.01), corner


def test_a_synced_session_follows_a_changed_medium(bpy_module):
    """Persistent Data / the viewport (addon/sync.py): changing a Volume Absorption's density re-exports the scene
    with the new medium (the material edit alone would keep the old one)."""
    import bpy

    from addon import sync

    medium_scene()
    s = sync.SceneSync()
    first = s.update(bpy.context.evaluated_depsgraph_get())
    vols = first[0].args[0].material_volumes
    row = int(np.flatnonzero(vols[:, :3].any(1))[0])
    assert np.allclose(vols[row, :3], (1 - np.array(VOLUME_COLOUR)) * VOLUME_DENSITY)
    mat = bpy.data.materials["Juice glass"]
    next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeVolumeAbsorption").inputs["Density"]\
        .default_value = 0.5
    edits = s.update(bpy.context.evaluated_depsgraph_get())
    assert [e.kind for e in edits] == ["rebuild"]
    assert np.allclose(edits[0].args[0].material_volumes[row, :3], (1 - np.array(VOLUME_COLOUR)) * 0.5)


# ---------------------------------------------------------------------------------------------------- light nodes
def light_nodes_scene(size=(64, 48)):
    """A grey cube under a point light (colour (0.5, 1, 0), 100 W, radius 0.1) whose own node tree is Emission
    (red) with its Strength from a Light Falloff's Quadratic output (Strength 3), as the glTF exporter's lamp test
    file has it: Cycles lights the cube red, × 3."""
    import bpy

    scene = bs.reset(size)
    bs.add_camera((4.0, -5.0, 3.0), target=(0.0, 0.0, 0.0), lens=50.0)
    bs.set_world((0.05, 0.05, 0.05))
    bs.add_cube((0.0, 0.0, 0.0), 2.0, material=bs.principled_material("Grey", base_color=(0.6, 0.6, 0.6),
                                                                       specular=0.0))
    light = bs.add_point_light((3.0, -2.0, 4.0), power=100.0, color=(0.5, 1.0, 0.0), radius=0.1)
    data = light.data
    data.use_nodes = True
    nt = data.node_tree
    em = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeEmission")
    em.inputs["Color"].default_value = (1.0, 0.0, 0.0, 1.0)
    fall = nt.nodes.new("ShaderNodeLightFalloff")
    fall.inputs["Strength"].default_value = 3.0
    nt.links.new(fall.outputs["Quadratic"], em.inputs["Strength"])
    bpy.context.view_layer.update()
    return scene


@pytest.mark.cycles
def test_a_lights_own_node_tree_matches_cycles(bpy_module, tmp_path):
    ref = H.cycles_render("light_nodes", light_nodes_scene, source_of(light_nodes_scene), dict(depth=2, samples=128))
    ours, warnings = ours_render(light_nodes_scene())
    assert not warnings, warnings
    H.check_images({"name": "light_nodes"}, ours, ref, tmp_path, min_psnr=35.0, max_mae=0.006)


# ---------------------------------------------------------------------------------------------------- glossy GGX
def glossy_furnace_scene(distribution: str, roughness: float = 1.0, size=(16, 16)):
    """A white Glossy BSDF (``distribution``, ``roughness``) on a plane seen straight down (μ = 1) by an orthographic
    camera, under a uniform white world of radiance 1: a white furnace. The glTF importer's old "glTF Metallic
    Roughness" group (gltf/05_metallic_sphere_light) builds its metal from such a Glossy BSDF, distribution GGX."""
    import bpy

    scene = bs.reset(size)
    bs.add_camera((0.0, 0.0, 5.0), target=(0.0, 0.0, 0.0), ortho_scale=1.0)
    bs.set_world((1.0, 1.0, 1.0))
    mat, g = bs.shader_material("Glossy", "ShaderNodeBsdfGlossy", Color=(1.0, 1.0, 1.0), Roughness=roughness)
    g.distribution = distribution
    bs.add_plane((0.0, 0.0, 0.0), 40.0, material=mat)
    bpy.context.view_layer.update()
    return scene


def glossy_furnace_closed_form(distribution: str, roughness: float = 1.0) -> float:
    """What the white furnace shows: single-scattering GGX reflects its directional albedo E(μ, r) (the light that
    scatters twice among the microfacets is lost), Multiscatter GGX all of it."""
    from tracer.shading import bsdf

    return 1.0 if distribution == "MULTI_GGX" else float(bsdf.table2(bsdf._E, roughness, 1.0))


@pytest.mark.parametrize("distribution", ["GGX", "MULTI_GGX"])
def test_a_glossy_bsdf_in_a_white_furnace_keeps_its_distribution(bpy_module, distribution):
    """gltf/05_metallic_sphere_light came out 1.7× Cycles': every Glossy BSDF was multiscatter GGX, and a GGX one
    (single scattering) of roughness 1 reflects 0.31 of a uniform world head-on, not 1."""
    ours, _ = ours_render(glossy_furnace_scene(distribution), samples=2)
    np.testing.assert_allclose(ours.mean(axis=(0, 1)), glossy_furnace_closed_form(distribution), rtol=0.01)


@pytest.mark.cycles
@pytest.mark.parametrize("distribution", ["GGX", "MULTI_GGX"])
def test_cycles_glossy_bsdf_in_a_white_furnace_is_the_same_closed_form(bpy_module, distribution):
    ref = H.cycles_render(f"glossy_furnace_{distribution}", lambda: glossy_furnace_scene(distribution),
                          source_of(glossy_furnace_scene), dict(depth=8, samples=256))
    np.testing.assert_allclose(ref.mean(axis=(0, 1)), glossy_furnace_closed_form(distribution), rtol=0.01)


def test_a_medium_on_an_open_mesh_is_dropped(bpy_module):
    """A water plane with Volume Absorption and Emission has no inside: its medium is not rendered (one warning);
    before, rays meeting the plane's back face gained its emission over their whole length (the water file: 4 dB)."""
    import bpy

    from addon import export

    medium_scene(emission=True)
    glass = bpy.data.materials["Juice glass"]
    bs.add_plane((0.0, 0.0, -1.5), 4.0, material=glass, name="Water")
    ts, warnings = export.scene_from_depsgraph(bpy.context.evaluated_depsgraph_get())
    assert ts.material_volumes is None
    assert any("not closed" in w and "'Water'" in w for w in warnings), warnings


def inside_out_medium_scene(emission: bool = False, flip: bool = True, world: float = 0.0, backdrop: bool = True,
                             size=(48, 48)):
    """The juice glass of :func:`medium_scene` (IOR 1, Volume Absorption (+ Emission)) on a cube of side 2 at the
    origin whose normals point inwards (``flip``; the water file's box), seen by a 50 mm camera from 8 m, the
    emissive backdrop 3 m behind the cube's far face (``backdrop``), a world of ``world``."""
    import bmesh
    import bpy

    scene = medium_scene(emission=emission, size=size)
    sphere = next(o for o in scene.objects if o.type == "MESH" and o.name != "Backdrop")
    glass = sphere.data.materials[0]
    bpy.data.objects.remove(sphere)
    back = bpy.data.objects["Backdrop"]
    if backdrop:
        back.location, back.scale = (0.0, 4.0, 0.0), (3.0, 3.0, 3.0)
    else:
        bpy.data.objects.remove(back)
    bs.set_world((world, world, world))
    cube = bs.add_cube((0.0, 0.0, 0.0), 2.0, material=glass, name="Water box")
    if flip:
        bm = bmesh.new()
        bm.from_mesh(cube.data)
        bmesh.ops.reverse_faces(bm, faces=bm.faces[:])
        bm.to_mesh(cube.data)
        bm.free()
    cam = scene.camera
    cam.location = (0.0, -8.0, 0.0)
    cam.data.type, cam.data.lens = "PERSP", 50.0
    bpy.context.view_layer.update()
    return scene


def inside_out_closed_form(emission: bool, length: float) -> np.ndarray:
    """The backdrop seen through a medium over ``length``: backdrop·exp(−σL) (+ E/σ·(1 − exp(−σL)))."""
    sigma = (1 - np.array(VOLUME_COLOUR)) * VOLUME_DENSITY
    att = np.exp(-sigma * length)
    out = BACKDROP * att
    return out + np.array(VOLUME_EMISSION) / sigma * (1 - att) if emission else out


#: Cycles through bpy (Blender 5.0, 16 samples; the cube of side 2, the backdrop 3 behind it): an inside-out cube
#: attenuates over the 3 m behind it (its inside stays clear), a cube with outward normals over its 2 m inside.
INSIDE_OUT_LENGTH, OUTWARD_LENGTH = 3.0, 2.0


@pytest.mark.parametrize("emission", [False, True])
def test_a_medium_on_an_inside_out_mesh_is_carried_out_of_it(bpy_module, emission):
    """The water file's inside-out box: Cycles' volume stack enters the medium where a ray crosses a face against
    its normal, on the way out of the box, and keeps it to the backdrop (measured: exp(−3σ)·0.8 to 4 digits, with
    emission + E·3 when σ = 0; an outward box exp(−2σ)). Ours dropped the medium (warned): the plain backdrop."""
    ours, warnings = ours_render(inside_out_medium_scene(emission), samples=2)
    assert not warnings, warnings
    centre = ours[20:28, 20:28].reshape(-1, 3)
    expected = inside_out_closed_form(emission, INSIDE_OUT_LENGTH)
    np.testing.assert_allclose(centre.mean(0), expected, rtol=0.01)
    np.testing.assert_allclose(ours[1:3, 1:3].reshape(-1, 3).mean(0), BACKDROP, rtol=0.01)  # beside the box: clear
    outward, _ = ours_render(inside_out_medium_scene(emission, flip=False), samples=2)
    np.testing.assert_allclose(outward[20:28, 20:28].reshape(-1, 3).mean(0),
                               inside_out_closed_form(emission, OUTWARD_LENGTH), rtol=0.01)


def test_a_carried_medium_leaves_the_world_unchanged(bpy_module):
    """A ray that leaves the scene in a carried medium (no backdrop, a white world) keeps its weight: Cycles
    (measured) integrates no medium over an infinite segment: the world, 1.0, through the box."""
    ours, warnings = ours_render(inside_out_medium_scene(False, world=1.0, backdrop=False), samples=2)
    np.testing.assert_allclose(ours[20:28, 20:28].reshape(-1, 3).mean(0), 1.0, rtol=0.01)


@pytest.mark.cycles
def test_cycles_carries_an_inside_out_mesh_medium_out_of_it(bpy_module):
    """Cycles' side of the closed forms above (the measurement the rule rests on)."""
    for emission, flip, length in ((False, True, INSIDE_OUT_LENGTH), (True, True, INSIDE_OUT_LENGTH),
                                   (False, False, OUTWARD_LENGTH)):
        build = functools.partial(inside_out_medium_scene, emission, flip)
        ref = H.cycles_render(f"inside_out_medium_{emission}_{flip}", build,
                              source_of(inside_out_medium_scene, medium_scene, bs.node_material), dict(depth=8, samples=16))
        np.testing.assert_allclose(ref[20:28, 20:28].reshape(-1, 3).mean(0), inside_out_closed_form(emission, length),
                                   rtol=0.01)


# ---------------------------------------------------------------------------------------------------- the survey tool
def test_the_survey_tool_measures_a_scene_and_a_material_library(bpy_module, tmp_path, monkeypatch):
    """tools/blender_fidelity.py on two files written here: a scene without a camera (framed by the tool) and a
    material library (materials, no geometry: each on the tool's sphere); rows with PSNR and a side-by-side each,
    a contact sheet under 300 KB."""
    import json

    import bpy

    sys.path.insert(0, os.path.join(os.path.dirname(HERE), "tools"))
    import blender_fidelity as BF

    monkeypatch.setattr(BF, "CACHE", str(tmp_path / "cache"))
    bs.reset((64, 48))
    bs.add_point_light((2.0, -3.0, 4.0), power=500.0)
    bs.add_cube((0.0, 0.0, 0.0), 1.0, material=bs.principled_material("Red", base_color=(0.8, 0.1, 0.1)))
    scene_file = str(tmp_path / "scene.blend")
    bpy.ops.wm.save_as_mainfile(filepath=scene_file)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    for name, colour in (("Blue", (0.1, 0.2, 0.8)), ("Green", (0.1, 0.7, 0.2))):
        bs.principled_material(name, base_color=colour).use_fake_user = True
    lib_file = str(tmp_path / "library.blend")
    bpy.ops.wm.save_as_mainfile(filepath=lib_file)
    out = tmp_path / "out"
    try:
        assert BF.main([scene_file, lib_file, "--width", "48", "--samples", "16", "--aa", "2", "--out", str(out),
                        "--jsonl", str(tmp_path / "rows.jsonl"), "--sheet", str(tmp_path / "sheet.png")]) == 0
    finally:  # the tool registers the add-on to render with it
        import addon

        if hasattr(bpy.types.Scene, "whitted"):
            addon.unregister()
    rows = [json.loads(x) for x in open(tmp_path / "rows.jsonl")]
    assert [r["name"] for r in rows] == ["library.blend::Blue", "library.blend::Green", "scene.blend"]
    assert all(r["psnr"] > 25 and os.path.exists(r["png"]) for r in rows), rows
    assert os.path.getsize(tmp_path / "sheet.png") < 300_000


def test_a_coloured_glass_bsdf_tints_its_reflection_too():
    """Cycles' Glass BSDF weighs both its Fresnel reflection and its refraction by Color. A red glass ball (Color
    (1, 0.1, 0.1), IOR 1.45) in a uniform green world, seen head-on: the centre's green is the world's 0.6 × (the
    tinted reflection c·F₀ + the tinted way through, c²(1 − F₀)², + the internal bounces), 0.0076 (Cycles 256
    samples: 0.0076). Ours reflected the world white (0.026, 3.4×) before: found by the equal-quality bench's
    third-party dice (coloured glass, 35.4 dB → docs/benchmarks.md)."""
    import bpy

    bs.reset((48, 48))
    mat, _glass = bs.shader_material("Red glass", "ShaderNodeBsdfGlass", Color=(1.0, 0.1, 0.1), Roughness=0.0,
                                     IOR=1.45)
    bs.add_uv_sphere((0, 0, 0), 1.0, segments=64, rings=32, material=mat)
    bs.set_world((0.2, 0.6, 0.2), 1.0)
    bs.add_camera((0, -4, 0), (0, 0, 0), lens=50)
    img, _ = ours_render(bpy.context.scene, samples=2, depth=8)
    f0 = ((1.45 - 1.0) / (1.45 + 1.0)) ** 2
    c = 0.1
    through = c * c * (1 - f0) ** 2 / (1 - (c * f0) ** 2)  # in, out, and the light bouncing inside (tinted each time)
    expected = 0.6 * (c * f0 + through)
    centre = img[22:26, 22:26, 1].mean()
    assert centre == pytest.approx(expected, rel=0.05), (centre, expected)
    assert img[22:26, 22:26, 0].mean() == pytest.approx(0.2, rel=0.02)  # red passes: (F₀ + (1 − F₀)²…) × 0.2


# ---------------------------------------------------------------------------------------------------- bump
def bumped_scene(kind: str, size=(64, 64)):
    """A plane seen from above under a sun 30° above the horizon and a dim grey world, its normal tilted by stripes:
    "bump_diffuse" (a Diffuse BSDF, Bump of Wave bands, Distance 1), "normal_map_principled" (a Principled BSDF,
    roughness 0.5, a Normal Map of colours mixed by the Wave bands: a striped normal map, as glTF's clearcoat test
    scene), "bump_sphere" (a smooth sphere under the same bump: the smooth normal is not the face's) or
    "displacement_bump" (the Diffuse plane with the Wave bands as its Displacement output, method Bump) or
    "normal_map_strength_2" (the normal-mapped Principled plane at Strength 2, as glTF's clearcoat scene) or
    "noise_filter_width_1" (the Diffuse plane bumped by a Noise finer than a pixel, Distance 0.1, Filter Width 1: the
    library's Concrete)."""
    import bpy

    scene = bs.reset(size)
    bs.add_camera((0.0, -0.001, 6.0), target=(0.0, 0.0, 0.0), lens=50.0)
    e = math.radians(30.0)
    bs.add_sun((0.0, math.cos(e), -math.sin(e)), strength=3.0)
    bs.set_world((0.1, 0.1, 0.1))
    mat, nt, out = bs.node_material(kind)
    if kind.startswith("normal_map"):
        shader = nt.nodes.new("ShaderNodeBsdfPrincipled")
        shader.inputs["Base Color"].default_value = (0.8, 0.8, 0.8, 1.0)
        shader.inputs["Roughness"].default_value = 0.5
    else:
        shader = nt.nodes.new("ShaderNodeBsdfDiffuse")
        shader.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    nt.links.new(shader.outputs[0], out.inputs["Surface"])
    wave = nt.nodes.new("ShaderNodeTexWave")
    wave.inputs["Scale"].default_value = 2.0
    if kind == "noise_filter_width_1":
        wave = nt.nodes.new("ShaderNodeTexNoise")  # (its Fac is the height below)
        wave.inputs["Scale"].default_value = 60.0
    if kind == "displacement_bump":
        disp = nt.nodes.new("ShaderNodeDisplacement")
        disp.inputs["Scale"].default_value = 1.0  # (the node's default is 0.1: a faint bump)
        nt.links.new(wave.outputs["Fac"], disp.inputs["Height"])
        nt.links.new(disp.outputs[0], out.inputs["Displacement"])
        mat.displacement_method = "BUMP"
    elif kind.startswith("normal_map"):
        mix = nt.nodes.new("ShaderNodeMix")
        mix.data_type = "RGBA"
        mix.inputs["A"].default_value = (0.1, 0.5, 0.6, 1.0)
        mix.inputs["B"].default_value = (0.9, 0.5, 0.6, 1.0)
        nt.links.new(wave.outputs["Fac"], mix.inputs["Factor"])
        nm = nt.nodes.new("ShaderNodeNormalMap")
        nm.inputs["Strength"].default_value = 2.0 if kind == "normal_map_strength_2" else 1.0
        nt.links.new(mix.outputs["Result"], nm.inputs["Color"])
        nt.links.new(nm.outputs[0], shader.inputs["Normal"])
    else:
        bump = nt.nodes.new("ShaderNodeBump")
        bump.inputs["Distance"].default_value = 1.0
        if kind == "noise_filter_width_1":
            bump.inputs["Distance"].default_value = 0.1
            bump.inputs["Filter Width"].default_value = 1.0
        nt.links.new(wave.outputs["Fac"], bump.inputs["Height"])
        nt.links.new(bump.outputs[0], shader.inputs["Normal"])
    if kind == "bump_sphere":
        bs.add_uv_sphere((0.0, 0.0, 0.0), 1.5, segments=96, rings=48, material=mat)
    else:
        bs.add_plane((0.0, 0.0, 0.0), 4.0, material=mat)
    bpy.context.view_layer.update()
    return scene


#: (PSNR bar, mean ours / Cycles within, MAE bar) of the bumped scenes. Measured 2026-12-05: 35.5, 45.3, 38.8 dB (means
#: 0.997, 1.006, 1.001); without the bump shadowing 20.7, 22.1, 27.1 dB (1.41, 1.32, 1.14×). A tangent-space normal
#: map at Strength 2: 39.0 dB, 1.029 (3.56× with Strength as a linear blend from the normal, which tips it below).
#: The bump offsets are Filter Width × the pixel's footprint (Cycles' × dP), not one eye sample's: the wave plane and
#: sphere 43.8, 43.5 dB (35.5, 38.8 before); a sub-pixel Noise at Filter Width 1: 26.8 dB, 1.004 (24.7 dB, 0.912×).
#: The Displacement output's bump sets Cycles' smooth normal (SetNormal: sd->N), so no bump shadowing follows from it:
#: 30.2 dB, 1.115× (measured with it: 24.0 dB, 0.786×). Under the sun alone (a black world) it is 43.2 dB, 0.998×:
#: the 11 % is the world's light on the steeply tilted normals, not yet traced to its line in Cycles (issue #32).
BUMP_BARS = {"bump_diffuse": (32.0, 0.03, 0.015), "normal_map_principled": (40.0, 0.03, 0.01),
             "bump_sphere": (34.0, 0.03, 0.01), "displacement_bump": (28.0, 0.13, 0.03),
             "normal_map_strength_2": (36.0, 0.045, 0.01), "noise_filter_width_1": (25.5, 0.05, 0.05)}


@pytest.mark.cycles
@pytest.mark.parametrize("kind", list(BUMP_BARS))
def test_bumped_surfaces_match_cycles(bpy_module, tmp_path, kind):
    """Cycles' ``bump_shadowing_term`` (closure/bsdf.h): where the material bumps or normal-maps the shading normal N
    away from the smooth normal Ns, a diffuse lobe's light is × G₁ of GGX at α² = tan²(Ns, N)/8 and |Ns·l|, and no
    closure takes light from the side of the smooth surface that N is not on. Without it the bumped plane under a 30°
    sun was 1.41× Cycles' mean, the normal-mapped one 1.32× (issue #32: rough plaster 1.39×, cobblestone 1.36×)."""
    ref = H.cycles_render(f"bumped_{kind}", lambda: bumped_scene(kind), source_of(bumped_scene, bs.node_material) + kind,
                          dict(depth=2, samples=64))
    ours, _warnings = ours_render(bumped_scene(kind))
    m = H.metrics(ours, ref)
    ratio = m["mean_ours"] / m["mean_cycles"]
    print(f"[cycles] bumped_{kind}: {m['psnr']:.2f} dB, mean ours/Cycles {ratio:.3f}")
    bar, within, mae = BUMP_BARS[kind]
    assert abs(ratio - 1.0) <= within, ratio
    H.check_images({"name": f"bumped_{kind}"}, ours, ref, tmp_path, min_psnr=bar, max_mae=mae)

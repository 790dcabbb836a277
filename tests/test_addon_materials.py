"""The add-on's material translation (addon/shader_tree.py compiled by the tracer), its writer (addon/model.py),
image decoding and world baking (addon/nodes.py, addon/world.py),
checked against closed forms and the values put into the scene. The pictures are
compared with Cycles in tests/cycles/test_cycles_addon_materials.py."""

from __future__ import annotations

import numpy as np
import pytest

from blender_kit import scene as bs

import bpy  # noqa: E402  (the test extra installs bpy; a missing bpy must fail, not skip)

from addon import export, nodes, shader_tree, world  # noqa: E402
from tracer.shading.compiler import compile_graph  # noqa: E402


def depsgraph():
    return bpy.context.evaluated_depsgraph_get()


def node_material(name):
    mat = bpy.data.materials.new(name)
    nt = mat.node_tree
    out = next(n for n in nt.nodes if n.type == "OUTPUT_MATERIAL")
    bsdf = next(n for n in nt.nodes if n.type == "BSDF_PRINCIPLED")
    return mat, nt, out, bsdf


def image(name, pixels, *, float_buffer=True, colorspace="Linear Rec.709"):
    h, w = pixels.shape[:2]
    img = bpy.data.images.new(name, w, h, alpha=True, float_buffer=float_buffer)
    img.colorspace_settings.name = colorspace
    img.pixels.foreach_set(np.ascontiguousarray(pixels[::-1], np.float32).ravel())
    return img


def read(mat):
    """The material's graph (addon.shader_tree) compiled by the tracer: (constant row, warnings)."""
    warnings = []
    graph = shader_tree.material_graph(mat, warnings.append, {})
    uv_sets = {"": 0}
    row = compile_graph(graph, warnings.append, lambda n: uv_sets.setdefault(n or "", len(uv_sets))).row
    return row, warnings, graph


def test_unsupported_nodes_warn_once_each_and_keep_the_best_colour(bpy_module):
    bs.reset()
    bs.add_camera()
    mat, nt, out, bsdf = node_material("Odd")
    bsdf.inputs["Base Color"].default_value = (0.2, 0.4, 0.6, 1)
    ao = nt.nodes.new("ShaderNodeAmbientOcclusion")  # a stand-in: its colour passes through
    ao.name = "My AO"
    ao.inputs["Color"].default_value = (0.2, 0.4, 0.6, 1)
    nt.links.new(ao.outputs["Color"], bsdf.inputs["Base Color"])
    wire = nt.nodes.new("ShaderNodeWireframe")
    wire.name = "My Wire"
    nt.links.new(wire.outputs["Fac"], bsdf.inputs["Metallic"])
    bs.add_cube((0, 0, 0), material=mat)
    bs.add_cube((3, 0, 0), material=mat, name="Cube2")  # the same material twice: still one warning per node
    scene, warnings = export.scene_from_depsgraph(depsgraph())
    i = scene.materials.names.index("Odd")
    np.testing.assert_allclose(scene.materials.diffuse[i], (0.2, 0.4, 0.6), rtol=1e-6)
    assert len([w for w in warnings if "My AO" in w]) == 1, warnings
    assert len([w for w in warnings if "My Wire" in w]) == 1, warnings


def test_mix_shader_mixes_parameters(bpy_module):
    mat, nt, out, bsdf = node_material("Mix")
    bsdf.inputs["Base Color"].default_value = (1, 0, 0, 1)
    bsdf.inputs["Roughness"].default_value = 0.2
    glossy = nt.nodes.new("ShaderNodeBsdfGlossy")
    glossy.inputs["Color"].default_value = (0, 0, 1, 1)
    glossy.inputs["Roughness"].default_value = 0.6
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.25
    nt.links.new(bsdf.outputs[0], mix.inputs[1])
    nt.links.new(glossy.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    f, warnings, _graph = read(mat)
    assert not warnings
    np.testing.assert_allclose(f["base_color"], (0.75, 0, 0.25))
    assert f["roughness"] == pytest.approx(0.75 * 0.2 + 0.25 * 0.6)
    assert f["metallic"] == pytest.approx(0.25)


def test_image_colour_spaces(bpy_module):
    """Byte images decode from their colour space (sRGB: the IEC 61966-2-1 curve; Non-Color: as stored); float
    images are linear already."""
    px = np.full((2, 2, 4), 0.5, np.float32)
    srgb = nodes.image_rgba(image("s", px, float_buffer=False, colorspace="sRGB"))
    raw = nodes.image_rgba(image("r", px, float_buffer=False, colorspace="Non-Color"))
    flt = nodes.image_rgba(image("f", px))
    byte = round(0.5 * 255) / 255  # a byte image stores 8 bits
    np.testing.assert_allclose(srgb[0, 0, :3], ((byte + 0.055) / 1.055) ** 2.4, atol=1e-6)
    np.testing.assert_allclose(raw[0, 0, :3], byte, atol=1e-6)
    np.testing.assert_allclose(flt[0, 0, :3], 0.5, atol=1e-7)
    assert srgb[0, 0, 3] == pytest.approx(byte, abs=1e-6)  # alpha is never colour-decoded


@pytest.mark.parametrize("domain", ["POINT", "CORNER"])
def test_color_attributes_reach_each_triangle(bpy_module, domain):
    """Point- and corner-domain Color Attributes reach the scene per corner (``Scene.colors``), each triangle's
    corners holding exactly the colours Blender stores at its vertices / loops; the material multiplies them in."""
    import bmesh

    bs.reset()
    bs.add_camera()
    mat, nt, out, bsdf = node_material("VC")
    attr = nt.nodes.new("ShaderNodeVertexColor")
    nt.links.new(attr.outputs["Color"], bsdf.inputs["Base Color"])
    mesh = bs._bmesh_mesh("G", lambda bm: bmesh.ops.create_grid(bm, x_segments=2, y_segments=1, size=1.0,
                                                                  calc_uvs=True))
    obj = bs._mesh_object("G", mesh, (0, 0, 0), mat, False)
    col = mesh.color_attributes.new("Paint", "FLOAT_COLOR", domain)
    n = len(col.data)
    rgba = np.stack([np.linspace(0.1, 0.9, n), np.linspace(0.9, 0.2, n), np.full(n, 0.5), np.ones(n)], -1)
    col.data.foreach_set("color", rgba.astype(np.float32).ravel())
    scene, warnings = export.scene_from_depsgraph(depsgraph())
    mesh.calc_loop_triangles()
    for k, tri in enumerate(mesh.loop_triangles):
        idx = tri.vertices if domain == "POINT" else tri.loops
        np.testing.assert_allclose(scene.colors[k], rgba[list(idx), :3], atol=1e-6)
        bound = scene.materials.programs[scene.material_ids[k]]  # the material's graph reads the colour per hit
        assert any(n.type == "vertex_color" for n in bound.graph.nodes.values())
    assert obj is not None


def test_normal_map_is_described_tangent_space_opengl(bpy_module):
    mat, nt, out, bsdf = node_material("Bumpy")
    img = image("n", np.full((2, 2, 4), 0.5, np.float32), colorspace="Non-Color")
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = img
    nmap = nt.nodes.new("ShaderNodeNormalMap")
    nmap.inputs["Strength"].default_value = 0.7
    nmap.uv_map = "Detail"
    nt.links.new(tex.outputs["Color"], nmap.inputs["Color"])
    nt.links.new(nmap.outputs["Normal"], bsdf.inputs["Normal"])
    _f, warnings, graph = read(mat)
    assert not warnings
    nm = next(n for n in graph.nodes.values() if n.type == "normal_map")
    assert nm.params["space"] == "TANGENT" and nm.params["uv_map"] == "Detail"
    assert nm.inputs["Strength"] == pytest.approx(0.7)
    assert graph.node(nm.inputs["Color"]).type == "image_texture"


def test_world_bake_is_cached_by_the_node_tree(bpy_module, monkeypatch):
    """A world nobody can read (a Sky Texture: not evaluated by the VM) is baked once per distinct node tree;
    changing a value bakes again."""
    w = bpy.data.worlds.new("W")
    bg = next(n for n in w.node_tree.nodes if n.type == "BACKGROUND")
    sky = w.node_tree.nodes.new("ShaderNodeTexSky")
    w.node_tree.links.new(sky.outputs["Color"], bg.inputs["Color"])
    calls = []

    def fake_render(name, out, width, height, samples):
        calls.append(name)
        import tracer
        tracer.write_image(out, np.full((height, width, 3), 0.25, np.float32))

    monkeypatch.setattr(world, "render_world_latlong", fake_render)
    monkeypatch.setattr(world, "_BAKES", {})
    warnings = []
    bgc, amb, env = world.world_from_blender(w, warnings)
    world.world_from_blender(w, warnings)
    assert len(calls) == 1 and env is not None
    np.testing.assert_allclose(amb, 0.25, rtol=1e-5)
    bg.inputs["Strength"].default_value = 2.0
    world.world_from_blender(w, warnings)
    assert len(calls) == 2


def test_world_of_procedural_nodes_is_evaluated_by_the_vm(bpy_module, monkeypatch):
    """A Gradient (Linear, on the unlinked Vector: Generated = the direction) × Background strength 2 is evaluated by
    the shader VM per direction, no bake: each texel is 2·clamp(x, 0, 1) of its direction (closed form)."""
    w = bpy.data.worlds.new("W")
    bg = next(n for n in w.node_tree.nodes if n.type == "BACKGROUND")
    bg.inputs["Strength"].default_value = 2.0
    grad = w.node_tree.nodes.new("ShaderNodeTexGradient")
    w.node_tree.links.new(grad.outputs["Color"], bg.inputs["Color"])

    def no_bake(*_args):
        raise AssertionError("baked")

    monkeypatch.setattr(world, "render_world_latlong", no_bake)
    monkeypatch.setattr(world, "_BAKES", {})
    warnings = []
    _bgc, _amb, env = world.world_from_blender(w, warnings)
    assert env is not None and not warnings
    from tracer.shading.world import latlong_directions

    h, wd = env.image.shape[:2]
    want = 2.0 * np.clip(latlong_directions(wd, h)[:, 0], 0.0, 1.0).reshape(h, wd)
    np.testing.assert_allclose(env.image[..., 0] * env.strength, want, atol=1e-5)


def test_principled_defaults_are_blenders():
    """The Principled defaults written once (tracer.shading.materials.PRINCIPLED_DEFAULTS) are those of Blender's own
    Principled BSDF node (read from bpy, the independent reference), and a surface that leaves a parameter out (the
    add-on's default surface, a USD reader's description) gets that default: Specular IOR Level 0.5, i.e. the
    dielectric F0 of IOR 1.5, ((1.5 − 1)/(1.5 + 1))² = 0.04 (before: 0.0, no highlight at all); the USD reader's
    base colour is UsdPreviewSurface's own fallback, 0.18."""
    from addon.model import default_surface
    from tracer.shading.materials import PRINCIPLED_DEFAULTS, f0_from_ior
    from usd_io.materials.table import MaterialTable

    mat, _nt, _out, bsdf = node_material("defaults")
    for name, want in PRINCIPLED_DEFAULTS.items():
        got = bsdf.inputs[name].default_value
        got = tuple(got)[:3] if hasattr(got, "__len__") else got
        np.testing.assert_allclose(got, want, atol=1e-6, err_msg=name)
    row = compile_graph(default_surface("empty")).row
    assert row["specular"] == 0.5 and row["roughness"] == 0.5 and row["metallic"] == 0.0 and row["ior"] == 1.5
    assert row["base_color"] == pytest.approx((0.8, 0.8, 0.8)) and row["emission"] == (0.0, 0.0, 0.0)
    usd = compile_graph(MaterialTable.model().graph("empty")).row
    assert usd == dict(row, base_color=pytest.approx((0.18, 0.18, 0.18)))
    assert 2.0 * row["specular"] * f0_from_ior(row["ior"]) == pytest.approx(((1.5 - 1.0) / (1.5 + 1.0)) ** 2)
    from addon.model import MaterialWriter
    from tracer import SceneBuilder

    b = SceneBuilder()
    w = MaterialWriter(b, [])
    default = b.materials[w.default_row]
    assert default["specular"] == 0.5 and default["roughness"] == 0.5 and default["ior"] == 1.5

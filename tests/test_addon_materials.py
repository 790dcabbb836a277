"""The add-on's node-tree reader (addon/nodes.py), its lowering (addon/model.py) and world baking (addon/world.py),
checked against Blender's own math (mathutils), closed forms and the values put into the scene. The pictures are
compared with Cycles in tests/cycles/test_cycles_addon_materials.py."""

from __future__ import annotations

import math

import numpy as np
import pytest

from blender_kit import scene as bs

import bpy  # noqa: E402  (the test extra installs bpy; a missing bpy must fail, not skip)
from mathutils import Euler, Matrix, Vector  # noqa: E402

from addon import export, nodes, world  # noqa: E402


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
    warnings = []
    return nodes.read_material(mat, warnings.append, {}), warnings


@pytest.mark.parametrize("kind", ["POINT", "TEXTURE"])
def test_mapping_matches_blender_math(bpy_module, kind):
    """The Mapping node's UV transform equals mathutils' Matrix.LocRotScale (Point) or its inverse (Texture)
    applied to (u, v, 0): a wrong Euler order, sign or composition order fails."""
    mat, nt, _out, _bsdf = node_material("M")
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.vector_type = kind
    loc, rot, scale = (0.3, -0.7, 0.2), (0.4, -0.25, 1.1), (1.7, 0.6, 1.3)
    mapping.inputs["Location"].default_value = loc
    mapping.inputs["Rotation"].default_value = rot
    mapping.inputs["Scale"].default_value = scale
    m = nodes.mapping_matrix(mapping)
    ref = Matrix.LocRotScale(Vector(loc), Euler(rot, "XYZ"), Vector(scale))
    if kind == "TEXTURE":
        ref = ref.inverted()
    rng = np.random.default_rng(3)
    for u, v in rng.uniform(-2, 2, (6, 2)):
        want = ref @ Vector((u, v, 0.0))
        got = m @ np.array([u, v, 1.0])
        np.testing.assert_allclose(got[:2], (want.x, want.y), atol=1e-5)  # mathutils is float32


def test_unsupported_nodes_warn_once_each_and_keep_the_best_colour(bpy_module):
    bs.reset()
    bs.add_camera()
    mat, nt, out, bsdf = node_material("Odd")
    bsdf.inputs["Base Color"].default_value = (0.2, 0.4, 0.6, 1)
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.name = "My Noise"
    nt.links.new(noise.outputs["Color"], bsdf.inputs["Base Color"])
    bump = nt.nodes.new("ShaderNodeBump")
    bump.name = "My Bump"
    nt.links.new(bump.outputs["Normal"], bsdf.inputs["Normal"])
    bs.add_cube((0, 0, 0), material=mat)
    bs.add_cube((3, 0, 0), material=mat, name="Cube2")  # the same material twice: still one warning per node
    scene, warnings = export.scene_from_depsgraph(depsgraph())
    i = scene.materials.names.index("Odd")
    np.testing.assert_allclose(scene.materials.diffuse[i], (0.2, 0.4, 0.6), rtol=1e-6)
    assert len([w for w in warnings if "My Noise" in w]) == 1, warnings
    assert len([w for w in warnings if "My Bump" in w]) == 1, warnings


def test_cutout_patterns_read_the_alpha_texture(bpy_module):
    """Blender's two cut-out patterns: image Alpha on the Principled Alpha, and Mix Shader(Transparent, BSDF) with
    the image alpha as factor; both give alpha = the texture's alpha channel (transparent where it is 0)."""
    px = np.zeros((4, 4, 4), np.float32)
    px[..., :3] = 0.5
    px[:2, :, 3] = 1.0  # top half opaque
    img = image("leaf", px)
    mat, nt, out, bsdf = node_material("Direct")
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = img
    nt.links.new(tex.outputs["Alpha"], bsdf.inputs["Alpha"])
    f, _ = read(mat)
    np.testing.assert_allclose(f["alpha_texture"].values(f["alpha_channel"]), px[..., 3])

    mat2, nt, out, bsdf = node_material("Mixed")
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = img
    mix = nt.nodes.new("ShaderNodeMixShader")
    transparent = nt.nodes.new("ShaderNodeBsdfTransparent")
    nt.links.new(tex.outputs["Alpha"], mix.inputs["Fac"])
    nt.links.new(transparent.outputs[0], mix.inputs[1])
    nt.links.new(bsdf.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    f, warnings = read(mat2)
    assert not warnings
    np.testing.assert_allclose(f["alpha_texture"].values(f["alpha_channel"]), px[..., 3])
    # the other order (BSDF at factor 0): alpha = 1 - factor
    nt.links.new(bsdf.outputs[0], mix.inputs[1])
    nt.links.new(transparent.outputs[0], mix.inputs[2])
    f, _ = read(mat2)
    np.testing.assert_allclose(f["alpha_texture"].values(f["alpha_channel"]), 1 - px[..., 3])


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
    f, warnings = read(mat)
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
        assert scene.materials.vertex_color[scene.material_ids[k]]
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
    f, warnings = read(mat)
    assert not warnings
    t = f["normal_texture"]
    assert f["normal_strength"] == pytest.approx(0.7) and t.uv_map == "Detail"
    np.testing.assert_allclose(t.values(-1)[0, 0], 0.0, atol=1e-6)  # 0.5 grey is the unperturbed normal


def test_checker_bake_follows_cycles_rule(bpy_module):
    """The baked checker: Color1 where ⌊u·s⌋ and ⌊v·s⌋ have different parity (Cycles' svm_checker at z = 0)."""
    tex = nodes.checker_texture(np.array([1.0, 0, 0]), np.array([0, 0, 1.0]), 4.0, "", np.eye(3), "c")
    h, w = tex.pixels.shape[:2]
    for u, v in ((0.1, 0.1), (0.3, 0.1), (0.1, 0.3), (0.3, 0.3), (0.6, 0.85)):
        s, t, _ = tex.transform @ np.array([u, v, 1.0])
        x, y = int((s % 1) * w), int((1 - t % 1) * h)
        c1 = (math.floor(u * 4) % 2) != (math.floor(v * 4) % 2)
        np.testing.assert_allclose(tex.pixels[y, x, :3], (1, 0, 0) if c1 else (0, 0, 1))


def test_world_bake_is_cached_by_the_node_tree(bpy_module, monkeypatch):
    """A world nobody can read is baked once per distinct node tree; changing a value bakes again."""
    w = bpy.data.worlds.new("W")
    bg = next(n for n in w.node_tree.nodes if n.type == "BACKGROUND")
    grad = w.node_tree.nodes.new("ShaderNodeTexGradient")
    w.node_tree.links.new(grad.outputs["Color"], bg.inputs["Color"])
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

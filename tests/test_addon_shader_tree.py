"""addon/shader_tree.py: Blender node trees -> the tracer's shader graph IR, checked on the graph itself (no render):
group inlining to any depth with Group Input defaults, muted nodes as Blender's pass-through, reroutes, the active
Material Output, implicit conversions, and warnings named once. The pictures are compared with Cycles in
tests/cycles/test_cycles_nodes.py."""

from __future__ import annotations

import numpy as np
import pytest

import bpy  # noqa: E402  (the test extra installs bpy)

from addon import shader_tree as st  # noqa: E402
from tracer.shading.graph import Out  # noqa: E402


@pytest.fixture
def tree(bpy_module):
    mat = bpy.data.materials.new("M")
    nt = mat.node_tree
    for n in list(nt.nodes):
        if n.type != "OUTPUT_MATERIAL":
            nt.nodes.remove(n)
    out = next(n for n in nt.nodes if n.type == "OUTPUT_MATERIAL")
    emit = nt.nodes.new("ShaderNodeEmission")
    nt.links.new(emit.outputs[0], out.inputs["Surface"])
    return mat, nt, emit


def translate(mat):
    warnings = []
    return st.material_graph(mat, warnings.append), warnings


def source(g, node, socket):
    """(IR node, output socket) linked to ``node``'s input, or the constant there."""
    v = node.inputs.get(socket)
    return (g.node(v), v.socket) if isinstance(v, Out) else v


def only(g, type_):
    nodes = [n for n in g.nodes.values() if n.type == type_]
    assert len(nodes) == 1, [n.type for n in g.nodes.values()]
    return nodes[0]


def group(name, body):
    """A shader node group with a float input X (default 0.25), a float input K (default 2) and a colour output."""
    g = bpy.data.node_groups.new(name, "ShaderNodeTree")
    x = g.interface.new_socket("X", in_out="INPUT", socket_type="NodeSocketFloat")
    x.default_value = 0.25
    k = g.interface.new_socket("K", in_out="INPUT", socket_type="NodeSocketFloat")
    k.default_value = 2.0
    g.interface.new_socket("Out", in_out="OUTPUT", socket_type="NodeSocketColor")
    gi, go = g.nodes.new("NodeGroupInput"), g.nodes.new("NodeGroupOutput")
    body(g, gi, go)
    return g


def test_nested_groups_inline_with_defaults(tree):
    """Three levels of groups: the innermost Math reads the outer group node's linked X through two Group Inputs,
    and K from the middle group node's own (unlinked) value, not the interface default."""
    mat, nt, emit = tree

    def inner(g, gi, go):
        m = g.nodes.new("ShaderNodeMath")
        m.operation = "MULTIPLY"
        g.links.new(gi.outputs["X"], m.inputs[0])
        g.links.new(gi.outputs["K"], m.inputs[1])
        g.links.new(m.outputs[0], go.inputs["Out"])

    g0 = group("Inner", inner)

    def middle(g, gi, go):
        n = g.nodes.new("ShaderNodeGroup")
        n.node_tree = g0
        n.inputs["K"].default_value = 3.5
        g.links.new(gi.outputs["X"], n.inputs["X"])
        g.links.new(n.outputs["Out"], go.inputs["Out"])

    g1 = group("Middle", middle)

    def outer(g, gi, go):
        n = g.nodes.new("ShaderNodeGroup")
        n.node_tree = g1
        g.links.new(gi.outputs["X"], n.inputs["X"])
        g.links.new(n.outputs["Out"], go.inputs["Out"])

    g2 = group("Outer", outer)
    top = nt.nodes.new("ShaderNodeGroup")
    top.node_tree = g2
    val = nt.nodes.new("ShaderNodeValue")
    val.outputs[0].default_value = 0.6
    tc = nt.nodes.new("ShaderNodeTexCoord")
    sep = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(tc.outputs["UV"], sep.inputs[0])
    nt.links.new(sep.outputs["X"], top.inputs["X"])
    nt.links.new(top.outputs["Out"], emit.inputs["Color"])
    g, warnings = translate(mat)
    assert not warnings
    m = only(g, "math")
    assert m.params["operation"] == "MULTIPLY"
    assert m.name == "Group/Group/Group/Math"  # three group nodes entered
    src = source(g, m, "Value")
    assert src[0].type == "separate_xyz" and src[1] == "X"
    assert m.inputs["Value_001"] == pytest.approx(3.5)  # the middle group node's value, not K's default 2
    # the float output crosses into the colour interface socket: an identity colour node (Blender's conversion)
    e = only(g, "emission")
    conv, sock = source(g, e, "Color")
    assert conv.type == "mix_color" and conv.inputs["Factor"] == 0.0 and sock == "Result"
    assert source(g, conv, "A")[0] is m


def test_unlinked_group_input_reads_the_group_nodes_value(tree):
    mat, nt, emit = tree

    def body(g, gi, go):
        m = g.nodes.new("ShaderNodeMath")
        m.operation = "ADD"
        g.links.new(gi.outputs["X"], m.inputs[0])
        g.links.new(gi.outputs["K"], m.inputs[1])
        g.links.new(m.outputs[0], go.inputs["Out"])

    n = nt.nodes.new("ShaderNodeGroup")
    n.node_tree = group("G", body)
    n.inputs["X"].default_value = 0.125
    nt.links.new(n.outputs["Out"], emit.inputs["Color"])
    g, _ = translate(mat)
    m = only(g, "math")
    assert m.inputs["Value"] == pytest.approx(0.125) and m.inputs["Value_001"] == pytest.approx(2.0)


def test_muted_node_passes_its_input_through(tree):
    """A muted Invert and a muted Hue/Saturation/Value pass their Color input on (Blender's internal links); a
    reroute in front is followed; a muted link is no link."""
    mat, nt, emit = tree
    rgb = nt.nodes.new("ShaderNodeTexChecker")
    rr = nt.nodes.new("NodeReroute")
    inv = nt.nodes.new("ShaderNodeInvert")
    hsv = nt.nodes.new("ShaderNodeHueSaturation")
    inv.mute = hsv.mute = True
    nt.links.new(rgb.outputs["Color"], rr.inputs[0])
    nt.links.new(rr.outputs[0], inv.inputs["Color"])
    nt.links.new(inv.outputs[0], hsv.inputs["Color"])
    nt.links.new(hsv.outputs[0], emit.inputs["Color"])
    lk = nt.links.new(rgb.outputs["Fac"], emit.inputs["Strength"])
    lk.is_muted = True
    emit.inputs["Strength"].default_value = 3.0
    g, warnings = translate(mat)
    assert not warnings
    assert {n.type for n in g.nodes.values()} == {"checker_texture", "emission", "material_output"}
    e = only(g, "emission")
    assert source(g, e, "Color") == (only(g, "checker_texture"), "Color")
    assert e.inputs["Strength"] == pytest.approx(3.0)


def test_muted_node_without_internal_link_leaves_the_socket_value(tree):
    """A muted node whose output has no internal link (Value feeds nothing through) gives the receiving socket its
    own value."""
    mat, nt, emit = tree
    geo = nt.nodes.new("ShaderNodeNewGeometry")
    geo.mute = True
    nt.links.new(geo.outputs["Backfacing"], emit.inputs["Strength"])
    emit.inputs["Strength"].default_value = 0.7
    g, _ = translate(mat)
    assert only(g, "emission").inputs["Strength"] == pytest.approx(0.7)
    assert not [n for n in g.nodes.values() if n.type == "geometry"]


def test_active_cycles_output_is_used(tree):
    """Of two Material Outputs, the active one for Cycles/All is rendered; an EEVEE-only output is not."""
    mat, nt, emit = tree
    eevee = nt.nodes.new("ShaderNodeOutputMaterial")
    eevee.target = "EEVEE"
    diff = nt.nodes.new("ShaderNodeBsdfDiffuse")
    nt.links.new(diff.outputs[0], eevee.inputs["Surface"])
    nt.nodes.active = eevee
    eevee.is_active_output = True
    g, _ = translate(mat)
    assert source(g, g.output_node, "Surface")[0].type == "emission"


def test_colour_into_a_shader_socket_is_an_emission(tree):
    mat, nt, emit = tree
    out = next(n for n in nt.nodes if n.type == "OUTPUT_MATERIAL")
    rgb = nt.nodes.new("ShaderNodeRGB")
    rgb.outputs[0].default_value = (0.2, 0.4, 0.6, 1.0)
    tc = nt.nodes.new("ShaderNodeTexCoord")
    nt.links.new(tc.outputs["UV"], out.inputs["Surface"])
    g, _ = translate(mat)
    e, sock = source(g, g.output_node, "Surface")
    assert e.type == "emission" and source(g, e, "Color")[0].type == "texture_coordinate"


def test_unsupported_node_warns_once_and_passes_through(tree):
    """A node without a translation (Shader to RGB) warns once per material naming it, however many sockets read
    it; Ambient Occlusion warns and passes its colour on."""
    mat, nt, emit = tree
    ao = nt.nodes.new("ShaderNodeAmbientOcclusion")
    ao.inputs["Color"].default_value = (0.3, 0.5, 0.7, 1.0)
    nt.links.new(ao.outputs["Color"], emit.inputs["Color"])
    nt.links.new(ao.outputs["AO"], emit.inputs["Strength"])
    g, warnings = translate(mat)
    assert len(warnings) == 1 and "'Ambient Occlusion'" in warnings[0] and "material 'M'" in warnings[0]
    e = only(g, "emission")
    assert e.inputs["Color"] == pytest.approx((0.3, 0.5, 0.7))
    assert e.inputs["Strength"] == pytest.approx(1.0)


def test_stand_in_for_unknown_shader_is_diffuse_of_its_colour(tree):
    mat, nt, emit = tree
    out = next(n for n in nt.nodes if n.type == "OUTPUT_MATERIAL")
    toon = nt.nodes.new("ShaderNodeBsdfToon")
    toon.inputs["Color"].default_value = (0.9, 0.1, 0.2, 1.0)
    nt.links.new(toon.outputs[0], out.inputs["Surface"])
    mix = nt.nodes.new("ShaderNodeMixShader")
    g, warnings = translate(mat)
    assert len(warnings) == 1 and "Toon" in warnings[0]
    d, _ = source(g, g.output_node, "Surface")
    assert d.type == "diffuse_bsdf" and d.inputs["Color"] == pytest.approx((0.9, 0.1, 0.2))
    del mix


def test_mix_node_modes_map_to_their_ir_types(tree):
    mat, nt, emit = tree
    kinds = []
    prev = None
    for dt, mode in (("FLOAT", "UNIFORM"), ("VECTOR", "UNIFORM"), ("VECTOR", "NON_UNIFORM"), ("RGBA", "UNIFORM")):
        m = nt.nodes.new("ShaderNodeMix")
        m.data_type, m.factor_mode = dt, mode
        if dt == "RGBA":
            m.blend_type, m.clamp_result = "OVERLAY", True
        if prev is not None:
            nt.links.new(prev, next(s for s in m.inputs if s.enabled and s.name == "A"))
        prev = next(s for s in m.outputs if s.enabled)
        kinds.append(dt)
    nt.links.new(prev, emit.inputs["Color"])
    g, warnings = translate(mat)
    assert not warnings
    types = sorted(n.type for n in g.nodes.values() if n.type.startswith("mix"))
    assert types == ["mix_color", "mix_float", "mix_vector", "mix_vector_non_uniform"]
    c = only(g, "mix_color")
    assert c.params["blend_type"] == "OVERLAY" and c.params["use_clamp_result"] is True


def test_curves_are_sampled_as_blender_evaluates_them(tree):
    """RGB Curves: the table holds R(C(x)) per channel over [0, 1], as CurveMapping.evaluate gives them."""
    mat, nt, emit = tree
    cv = nt.nodes.new("ShaderNodeRGBCurve")
    cm = cv.mapping
    cm.curves[3].points.new(0.5, 0.8)  # combined
    cm.curves[0].points.new(0.4, 0.1)  # red
    cm.update()
    nt.links.new(cv.outputs[0], emit.inputs["Color"])
    g, _ = translate(mat)
    node = only(g, "rgb_curves")
    table, (lo, hi) = node.params["curves"], node.params["range"]
    assert table.shape == (st.TABLE_SIZE, 4) and (lo, hi) == (0.0, 1.0)
    cm.initialize()
    for i in (0, 57, 128, 200, 255):
        x = i / (st.TABLE_SIZE - 1)
        assert table[i, 0] == pytest.approx(x)
        c = cm.evaluate(cm.curves[3], x)
        assert table[i, 1] == pytest.approx(cm.evaluate(cm.curves[0], c), abs=1e-6)
        assert table[i, 3] == pytest.approx(cm.evaluate(cm.curves[2], c), abs=1e-6)


def test_ramp_keeps_its_stops_and_modes(tree):
    mat, nt, emit = tree
    r = nt.nodes.new("ShaderNodeValToRGB")
    r.color_ramp.elements.new(0.3).color = (0.1, 0.9, 0.2, 1.0)
    r.color_ramp.color_mode, r.color_ramp.hue_interpolation = "HSV", "FAR"
    r.color_ramp.interpolation = "EASE"
    nt.links.new(r.outputs[0], emit.inputs["Color"])
    g, _ = translate(mat)
    node = only(g, "rgb_ramp")
    assert [p for p, _c in node.params["ramp"]] == pytest.approx([0.0, 0.3, 1.0])
    assert node.params["ramp"][1][1] == pytest.approx((0.1, 0.9, 0.2, 1.0))
    assert (node.params["interpolation"], node.params["color_mode"], node.params["hue_interpolation"]) == \
        ("EASE", "HSV", "FAR")


def test_texture_coordinate_from_object_is_a_mapping_of_position(tree):
    """Object coordinates of another object: its inverse transform applied to the world position, which equals
    mathutils' matrix_world.inverted() for a loc/rot/scale matrix."""
    from mathutils import Euler, Matrix, Vector

    mat, nt, emit = tree
    empty = bpy.data.objects.new("Ref", None)
    bpy.context.scene.collection.objects.link(empty)
    empty.location, empty.rotation_euler, empty.scale = (1.0, -2.0, 0.5), Euler((0.3, -0.4, 1.1)), (2.0, 0.5, 1.5)
    bpy.context.view_layer.update()
    tc = nt.nodes.new("ShaderNodeTexCoord")
    tc.object = empty
    nt.links.new(tc.outputs["Object"], emit.inputs["Color"])
    g, _ = translate(mat)
    m = only(g, "mapping")
    assert m.params["vector_type"] == "TEXTURE" and source(g, m, "Vector")[0].type == "geometry"
    # Blender's Mapping (Texture): v' = S^-1 (R^-1 (v - T)), R from the XYZ Euler rotation
    loc, rot, scale = (np.asarray(m.inputs[k]) for k in ("Location", "Rotation", "Scale"))
    p = Vector((0.3, 0.7, -0.2))
    r = Euler(tuple(rot), "XYZ").to_matrix()
    ours = np.asarray(r.inverted() @ (p - Vector(tuple(loc)))) / scale
    assert ours == pytest.approx(np.asarray(empty.matrix_world.inverted() @ p), abs=1e-5)
    del Matrix

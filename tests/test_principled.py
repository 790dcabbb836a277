"""The one writer of parameter-style surfaces (tracer.shading.principled): a typed record whose names are checked,
and the same graph whichever front end describes the surface."""

import pytest

from tracer import Materials
from tracer.shading.compiler import compile_graph
from tracer.shading.principled import PrincipledSurface, row_surface


def test_an_input_the_bsdf_does_not_have_is_an_error_not_a_dropped_key():
    """A reader's typo (``roughnes``) was a dict key nobody read; the record refuses it."""
    with pytest.raises(TypeError, match="roughnes"):
        PrincipledSurface().update(roughnes=0.2)
    with pytest.raises(ValueError, match="ior"):
        PrincipledSurface().read("ior", object())


def test_constants_fold_to_the_row_the_bsdf_defaults_give():
    """Left out, each input is Blender's Principled default (Specular IOR Level 0.5: F0 0.04 at IOR 1.5); set,
    the row carries it; a constant surface compiles to no program at all."""
    c = compile_graph(PrincipledSurface().graph("d"))
    assert c.program is None
    assert c.row["base_color"] == pytest.approx((0.8, 0.8, 0.8)) and c.row["specular"] == 0.5
    s = PrincipledSurface().update(base_color=(0.1, 0.2, 0.3), roughness=0.25, metallic=1.0, ior=1.33)
    row = compile_graph(s.graph("s")).row
    assert row["base_color"] == pytest.approx((0.1, 0.2, 0.3)) and row["roughness"] == 0.25
    assert row["metallic"] == 1.0 and row["ior"] == pytest.approx(1.33)


def test_the_api_texture_columns_are_written_by_the_same_writer():
    """A Materials row whose roughness reads channel 1 of texture 0 is the record's constant × that lookup: one
    scene_texture node, one channel split, one multiply feeding the Principled BSDF's Roughness."""
    m = Materials.from_list([dict(diffuse=(0.5, 0.5, 0.5), roughness=0.6, roughness_texture=0, roughness_channel=1)])

    class Tex:
        uv_set = 0

    s = row_surface(m, 0, [Tex()])
    assert s.roughness == pytest.approx(0.6) and set(s.lookups) == {"roughness"}
    g = s.graph("row")
    kinds = sorted(n.type for n in g.nodes.values())
    assert kinds.count("scene_texture") == 1 and kinds.count("separate_color") == 1 and kinds.count("math") == 1
    bsdf = next(n for n in g.nodes.values() if n.type == "principled_bsdf")
    mul = g.nodes[bsdf.inputs["Roughness"].node]  # linked to the multiply, not a constant
    assert mul.type == "math" and mul.inputs["Value_001"] == pytest.approx(0.6)
    split = g.nodes[mul.inputs["Value"].node]
    assert split.type == "separate_color" and mul.inputs["Value"].socket == "Green"

"""tools/fidelity_mtlx.py (issue #32, the MaterialX corpus): the measure and the reference's adaptations, on small
inputs written here (no third-party file is read; MaterialX's own code generator is the installed package's).

- CIEDE2000 against Sharma, Wu & Dalal's published test pairs (2005), and linear Rec.709 -> L*a*b* at its white;
- a graph output becomes a material the way MaterialX's test renderers show it (unlit colour, a BSDF on a surface);
- the OSL MaterialX generates is adapted to Cycles: the default UV and tangent as linked parameters in the shader
  body (the sphere's own in functions), GGX as ``multi_ggx`` (MaterialX's GGX is energy-compensated), a surface
  over a medium (``layer(bsdf, vdf)``) as the surface.
"""

from __future__ import annotations

import os
import re
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tools"))

import fidelity_mtlx as F  # noqa: E402

#: (Lab1, Lab2, ΔE00) from Sharma, Wu & Dalal, "The CIEDE2000 color-difference formula", Table 1 (pairs 1, 7, 13,
#: 17, 25, 34).
SHARMA = [((50.0, 2.6772, -79.7751), (50.0, 0.0, -82.7485), 2.0425),
          ((50.0, 0.0, 0.0), (50.0, -1.0, 2.0), 2.3669),
          ((50.0, 2.4900, -0.0010), (50.0, -2.4900, 0.0011), 7.2195),
          ((50.0, 2.5, 0.0), (73.0, 25.0, -18.0), 27.1492),
          ((60.2574, -34.0099, 36.2677), (60.4626, -34.1751, 39.4387), 1.2644),
          ((2.0776, 0.0795, -1.1350), (0.9033, -0.0636, -0.5514), 0.9082)]


@pytest.mark.parametrize("lab1,lab2,want", SHARMA)
def test_ciede2000_matches_the_published_pairs(lab1, lab2, want):
    assert F.delta_e2000(lab1, lab2) == pytest.approx(want, abs=1e-4)


def test_lab_of_linear_rec709():
    np.testing.assert_allclose(F.srgb_linear_to_lab((1.0, 1.0, 1.0)), (100.0, 0.0, 0.0), atol=1e-9)
    np.testing.assert_allclose(F.srgb_linear_to_lab((0.18, 0.18, 0.18))[0], 49.496, atol=1e-2)


def _doc(text):
    import MaterialX as mx

    doc = mx.createDocument()
    mx.readFromXmlString(doc, text)
    doc.setDataLibrary(F._library())
    return doc


def test_graph_outputs_become_materials():
    """A float output: convert to color3, the emission of a surface_unlit; a BSDF output: pbrlib's surface."""
    doc = _doc("""<?xml version="1.0"?><materialx version="1.39">
  <nodegraph name="g">
    <constant name="k" type="float"><input name="value" type="float" value="0.25" /></constant>
    <output name="v" type="float" nodename="k" />
    <oren_nayar_diffuse_bsdf name="d" type="BSDF" />
    <output name="b" type="BSDF" nodename="d" />
  </nodegraph></materialx>""")
    made = dict(F.wrap_outputs(doc))
    assert sorted(made.values()) == ["g/b", "g/v"]
    shaders = {m.getName(): m.getInput("surfaceshader").getConnectedNode().getCategory()
               for m in doc.getMaterialNodes()}
    assert sorted(shaders.values()) == ["surface", "surface_unlit"]


def test_the_osl_is_adapted_to_cycles(tmp_path):
    path = str(tmp_path / "m.mtlx")
    with open(path, "w") as f:
        f.write("""<?xml version="1.0"?><materialx version="1.39">
  <image name="img" type="color3"><input name="file" type="filename" value="x.png" /></image>
  <standard_surface name="SR" type="surfaceshader">
    <input name="base_color" type="color3" nodename="img" /><input name="metalness" type="float" value="1" />
  </standard_surface>
  <surfacematerial name="M" type="material"><input name="surfaceshader" type="surfaceshader" nodename="SR" />
  </surfacematerial></materialx>""")
    src = F.osl_source(path, "M")
    body = src[src.index("\nshader M"):]
    assert "vector mx_uvmap" in body and "mx_uvmap[0]" in body  # the linked UV map in the shader body
    assert "vector2(u,v)" not in src.replace(" ", "") and '"ggx"' not in src and '"multi_ggx"' in src
    assert "#include" not in src and "#pragma once" not in src


def test_the_reference_renders_subsurface_and_translucency_as_cycles_nodes_do(tmp_path):
    """Blender 5.0's Cycles renders MaterialX's subsurface_bssrdf white (the albedo weight is missing) with its radius
    scaled by 1/(4π), and has no translucent_bsdf (black): the adapted code is what its own nodes render."""
    path = str(tmp_path / "m.mtlx")
    with open(path, "w") as f:
        f.write("""<?xml version="1.0"?><materialx version="1.39">
  <standard_surface name="SR" type="surfaceshader">
    <input name="subsurface" type="float" value="1" /><input name="thin_walled" type="boolean" value="false" />
    <input name="subsurface_color" type="color3" value="0.8, 0.1, 0.1" />
  </standard_surface>
  <surfacematerial name="M" type="material"><input name="surfaceshader" type="surfaceshader" nodename="SR" />
  </surfacematerial></materialx>""")
    src = F.osl_source(path, "M")
    assert "albedo * subsurface_bssrdf(N, albedo, radius * (4.0 * M_PI), anisotropy)" in src
    assert re.search(r"\btranslucent_bsdf\(", src) is None and "* translucent(" in src

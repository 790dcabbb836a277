"""tracer/colorspace.py's colour spaces against closed forms: each matrix into linear Rec.709 derived from its
space's primaries and white point (RGB -> XYZ from the chromaticities, Bradford adaptation to D65 where the white
differs: ACES' for AP1), and against the values MaterialX's own colour management library holds (the installed
MaterialX package's ``libraries/cmlib``, the definitions its code generators use)."""

from __future__ import annotations

import numpy as np
import pytest

from tracer import colorspace

BRADFORD = np.array([[0.8951, 0.2664, -0.1614], [-0.7502, 1.7135, 0.0367], [0.0389, -0.0685, 1.0296]])
D65 = (0.3127, 0.3290)
ACES_WHITE = (0.32168, 0.33767)
REC709 = [(0.64, 0.33), (0.30, 0.60), (0.15, 0.06)]
AP1 = [(0.713, 0.293), (0.165, 0.830), (0.128, 0.044)]
ADOBE = [(0.64, 0.33), (0.21, 0.71), (0.15, 0.06)]
P3 = [(0.680, 0.320), (0.265, 0.690), (0.150, 0.060)]


def _xyz(x, y):
    return np.array([x / y, 1.0, (1 - x - y) / y])


def rgb_to_xyz(primaries, white):
    p = np.array([_xyz(*c) for c in primaries]).T
    return p * np.linalg.solve(p, _xyz(*white))


def bradford(src, dst):
    s, d = BRADFORD @ _xyz(*src), BRADFORD @ _xyz(*dst)
    return np.linalg.inv(BRADFORD) @ np.diag(d / s) @ BRADFORD


def to_rec709(primaries, white):
    return np.linalg.inv(rgb_to_xyz(REC709, D65)) @ bradford(white, D65) @ rgb_to_xyz(primaries, white)


@pytest.mark.parametrize("name,primaries,white,tol", [
    ("AP1_TO_REC709", AP1, ACES_WHITE, 1e-9),
    ("ADOBERGB_TO_REC709", ADOBE, D65, 1e-7),
    ("DISPLAYP3_TO_REC709", P3, D65, 2e-5),  # MaterialX's P3 matrix is rounded to 5 digits
])
def test_matrices_follow_from_the_primaries(name, primaries, white, tol):
    np.testing.assert_allclose(np.array(getattr(colorspace, name)), to_rec709(primaries, white), atol=tol)


def _cmlib_matrix(space):
    import MaterialX as mx

    lib = mx.createDocument()
    mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), lib)
    ng = lib.getNodeGraph(f"NG_{space}_to_lin_rec709_color3")
    for node in ng.getNodes():
        if node.getType() == "matrix33":
            v = [float(x) for x in node.getInput("value").getValueString().split(",")]
            return np.array(v).reshape(3, 3).T  # MaterialX: row vectors (v · M); ours: column vectors (M · v)
    return None


@pytest.mark.parametrize("space,name", [("acescg", "AP1_TO_REC709"), ("lin_adobergb", "ADOBERGB_TO_REC709"),
                                        ("lin_displayp3", "DISPLAYP3_TO_REC709")])
def test_matrices_are_materialx_s(space, name):
    np.testing.assert_allclose(np.array(getattr(colorspace, name)), _cmlib_matrix(space), atol=1e-8)


def test_transfer_functions():
    """srgb_texture: the sRGB curve (linear segment below 0.04045); g22/g18/rec709_display: pure powers (MaterialX's
    definitions, not the piecewise Rec.709 OETF); adobergb: 563/256."""
    x = np.array([0.02, 0.2, 0.7])
    np.testing.assert_allclose(colorspace.to_lin_rec709(np.stack([x] * 3, -1), "srgb_texture")[:, 0],
                               np.where(x > 0.04045, ((x + 0.055) / 1.055) ** 2.4, x / 12.92))
    for space, g in (("g22_rec709", 2.2), ("g18_rec709", 1.8), ("rec709_display", 2.4), ("gamma22", 2.2)):
        np.testing.assert_allclose(colorspace.to_lin_rec709(np.stack([x] * 3, -1), space)[:, 0], x ** g)
    grey = np.array([0.5, 0.5, 0.5])
    np.testing.assert_allclose(colorspace.to_lin_rec709(grey, "adobergb"), 0.5 ** (563 / 256), rtol=1e-6)

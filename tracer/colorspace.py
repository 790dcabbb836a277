"""Colour facts written once: the scene-linear space's luminance weights, its XYZ matrix, and the colour spaces
MaterialX names, converted into it.

The tracer's scene-linear space is linear Rec.709 (Blender's default working space). Its luminance weights are the
Y row of the Rec.709 (D65) → CIE XYZ matrix, (0.2126729, 0.7151522, 0.0721750): what Cycles' ``rgb_to_y`` holds
(``ShaderManager::init_xyz_transforms``; Blender's OCIO config gives the same to 4 digits, its ``luma`` line the
rounded 0.2126, 0.7152, 0.0722). Every colour → float conversion uses them: RGB to BW, a colour linked into a float
socket, a colour given for a float input, the environment's importance-sampling luminance.

The sRGB transfer function (IEC 61966-2-1) both ways: textures stored as sRGB are decoded with it, and PNG output
is encoded with it (Blender's "Standard" view transform).

A leaf module (numpy only): the tracer, the USD reader and the add-on all read it.
"""

from __future__ import annotations

import numpy as np

#: Linear Rec.709 luminance weights (Cycles' rgb_to_y for the default working space).
REC709_LUMINANCE = (0.2126729, 0.7151522, 0.0721750)
#: CIE XYZ (D65) -> linear Rec.709 (sRGB primaries), as Cycles' xyz_to_rgb for the default working space.
XYZ_TO_REC709 = ((3.2404542, -1.5371385, -0.4985314),
                 (-0.9692660, 1.8760108, 0.0415560),
                 (0.0556434, -0.2040259, 1.0572252))


def luminance(rgb) -> float:
    """The luminance of one linear Rec.709 colour (a 3-sequence)."""
    return REC709_LUMINANCE[0] * float(rgb[0]) + REC709_LUMINANCE[1] * float(rgb[1]) + REC709_LUMINANCE[2] * float(
        rgb[2])


def srgb_to_linear(c):
    """The sRGB electro-optical transfer function (IEC 61966-2-1), per channel."""
    c = np.asarray(c, dtype=np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def linear_to_srgb(c):
    """Inverse of :func:`srgb_to_linear` (Blender's "Standard" view transform); input clipped to [0, 1]."""
    c = np.clip(np.asarray(c, dtype=np.float32), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * np.power(c, 1 / 2.4) - 0.055).astype(np.float32)


# ---------------------------------------------------------------------------------------------- colour spaces
# MaterialX's colour spaces (its default colour management system: libraries/cmlib, with the name remapping of
# MaterialXGenShader/DefaultColorManagementSystem.cpp), each into the tracer's scene-linear linear Rec.709. A space
# is a transfer function (decoding: encoded -> linear) followed by a primaries matrix (column vectors: rows are
# the output channels). The matrices are MaterialX's cmlib values; tests/test_colorspace.py derives them from the
# spaces' chromaticities (Bradford adaptation of the ACES white to D65 for AP1).

#: ACEScg (AP1 primaries, ACES white) -> linear Rec.709 (D65), Bradford-adapted: MaterialX's acescg_to_lin_rec709.
AP1_TO_REC709 = ((1.705050992658, -0.621792120657, -0.083258872001),
                 (-0.130256417507, 1.140804736575, -0.010548319068),
                 (-0.024003356805, -0.128968976065, 1.15297233287))
#: Linear Adobe RGB (1998) (D65) -> linear Rec.709: MaterialX's lin_adobergb_to_lin_rec709.
ADOBERGB_TO_REC709 = ((1.39835574, -0.398355744, 0.0),
                      (0.0, 1.0, 0.0),
                      (0.0, -0.0429289893, 1.04292899))
#: Linear Display P3 (D65) -> linear Rec.709: MaterialX's lin_displayp3_to_lin_rec709.
DISPLAYP3_TO_REC709 = ((1.22493029, -0.22492968, 0.00000006),
                       (-0.04205868, 1.04205894, -0.00000001),
                       (-0.01964128, -0.07864794, 1.09828925))

#: MaterialX colour space -> (transfer: None linear, "srgb" the sRGB curve, or a gamma; matrix or None).
MATERIALX_SPACES = {
    "lin_rec709": (None, None),
    "srgb_texture": ("srgb", None),
    "g18_rec709": (1.8, None),
    "g22_rec709": (2.2, None),
    "rec709_display": (2.4, None),
    "acescg": (None, AP1_TO_REC709),
    "g22_ap1": (2.2, AP1_TO_REC709),
    "lin_adobergb": (None, ADOBERGB_TO_REC709),
    "adobergb": (563.0 / 256.0, ADOBERGB_TO_REC709),
    "lin_displayp3": (None, DISPLAYP3_TO_REC709),
    "srgb_displayp3": ("srgb", DISPLAYP3_TO_REC709),
}
#: Legacy and ASWF colour-interop names MaterialX reads as the spaces above.
MATERIALX_ALIASES = {"gamma18": "g18_rec709", "gamma22": "g22_rec709", "gamma24": "rec709_display",
                     "lin_ap1": "acescg", "lin_ap1_scene": "acescg", "lin_rec709_scene": "lin_rec709",
                     "lin_p3d65_scene": "lin_displayp3", "lin_adobergb_scene": "lin_adobergb",
                     "srgb_rec709_scene": "srgb_texture", "g22_rec709_scene": "g22_rec709",
                     "g18_rec709_scene": "g18_rec709", "g22_ap1_scene": "g22_ap1",
                     "srgb_p3d65_scene": "srgb_displayp3", "g22_adobergb_scene": "adobergb"}
#: Names that mean "no conversion" (a data texture, or the working space itself).
NO_CONVERSION = ("", "none", "raw", "lin_rec709")


def materialx_space(name: str) -> str | None:
    """The MaterialX colour space ``name`` is read as (aliases resolved), or None when MaterialX's default colour
    management does not know it (it then converts nothing; the caller warns)."""
    name = MATERIALX_ALIASES.get(name, name)
    return name if name in MATERIALX_SPACES else None


def to_lin_rec709(rgb, space: str):
    """Colours (..., 3) in MaterialX colour space ``space`` as linear Rec.709 (numpy float64). A name MaterialX
    does not know, and the no-conversion names, return the values unchanged."""
    x = np.asarray(rgb, np.float64)
    known = materialx_space(space)
    if known is None or known == "lin_rec709":
        return x
    transfer, matrix = MATERIALX_SPACES[known]
    if transfer == "srgb":  # srgb_to_linear's curve, in float64
        x = np.where(x > 0.04045, ((np.maximum(x, 0.0) + 0.055) / 1.055) ** 2.4, x / 12.92)
    elif transfer is not None:
        x = np.maximum(x, 0.0) ** transfer
    if matrix is not None:
        x = x @ np.asarray(matrix, np.float64).T
    return x

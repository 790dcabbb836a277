"""Colour facts written once: the scene-linear space's luminance weights and its XYZ matrix.

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

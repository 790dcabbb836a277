"""tools/blank_grey_sweep.py (issue #32: 0 silent greys, 0 blank frames): what it calls a blank frame and a grey
surface, on panels written here."""

from __future__ import annotations

import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tools"))

import blank_grey_sweep as sweep  # noqa: E402


def _panels():
    ref = np.tile(np.array([1.0, 0.5, 0.1], np.float32), (16, 16, 1))  # Storm's orange clear colour
    ref[4:12, 4:12] = (0.8, 0.1, 0.1)  # a red square
    ours = np.zeros((16, 16, 3), np.float32)
    return ref, ours


def test_a_frame_of_one_colour_is_blank_where_the_reference_is_not():
    ref, ours = _panels()
    assert sweep.judge(ref, ours)["blank"]
    assert not sweep.judge(np.zeros_like(ref), ours)["blank"]  # both empty: not a blank frame of ours
    ours[4:12, 4:12] = (0.7, 0.1, 0.1)
    assert not sweep.judge(ref, ours)["blank"]


def test_a_grey_surface_where_the_reference_is_coloured_is_grey():
    ref, ours = _panels()
    ours[4:12, 4:12] = 0.5  # the fallback grey
    assert sweep.judge(ref, ours)["grey"] == 1.0
    ours[4:12, 4:12] = (0.6, 0.1, 0.1)
    assert sweep.judge(ref, ours)["grey"] == 0.0


def test_a_white_line_blended_with_the_background_is_not_grey():
    """Storm's one-pixel white curves on its orange clear colour are orange-tinted: not a coloured surface."""
    ref, ours = _panels()
    ref[:] = (1.0, 0.5, 0.1)
    ref[8, 2:14] = (1.0, 0.8, 0.6)  # a white line blended with orange
    ours[7:10, 2:14] = 1.0  # our white ribbon
    assert not (sweep.judge(ref, ours)["grey"] or 0)

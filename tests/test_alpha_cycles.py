"""The alpha-cut leaf tree of bench/leaves.py (Geometry Nodes instancing leaf cards whose image alpha cuts them
out), small, through the add-on against Cycles, and the transparent-shadow filter (tracer/accel/alpha.py) against the
round-by-round loop it replaced on the same exported scene.

Lit by the sun alone (a black world), so Cycles' reference has only anti-aliasing noise: its leaf edges are jittered
over each pixel, ours are strata; both see the leaves' and the shadows' partial alpha at the image's bilinear edges.
Bars: LEAF_PSNR_MIN / LEAF_MAE_MAX against Cycles (measured 38.5 dB / 0.0016 for both variants, the filter and
the loop alike), FILTER_PSNR_MIN / FILTER_MAE_MAX between the filter and the loop (measured 58.5 dB / 0.00004: the
loop restarts each round ε past the card it crossed and so skips a card that crosses it within ε; about 2 % of
the pixels differ, by one of their 16 samples' shadow)."""

from __future__ import annotations

import inspect
import os
import sys

import pytest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "cycles"))
import cycles_harness as H  # noqa: E402

from bench import leaves as L  # noqa: E402

pytestmark = pytest.mark.cycles

SIZE = (64, 48)
PARAMS = dict(depth=2, samples=64, leaves=500)
#: Leaf edges: dozens of sub-pixel alpha edges per pixel row, which Cycles jitters and we stratify (AA 4×4).
LEAF_PSNR_MIN = 36.0
LEAF_MAE_MAX = 0.003
FILTER_PSNR_MIN = 50.0
FILTER_MAE_MAX = 1e-4


def build(variant):
    return lambda: L.build_scene(SIZE[0], SIZE[1], variant, PARAMS["leaves"], sky=0.0)


@pytest.mark.parametrize("variant", ["principled", "mix"])
def test_leaf_tree_matches_cycles_and_the_loop(bpy_module, tmp_path, monkeypatch, variant):
    import tracer
    from addon import export
    from tracer.accel import alpha

    source = inspect.getsource(L) + inspect.getsource(build)
    ref = H.cycles_render(f"leaves_{variant}", build(variant), source, PARAMS)
    build(variant)()
    scene, warnings = export.scene_from_depsgraph(bpy_module.context.evaluated_depsgraph_get())
    assert not warnings, warnings
    settings = tracer.RenderSettings(width=SIZE[0], height=SIZE[1], samples=4, max_depth=PARAMS["depth"])
    images = {}
    for filtered in (True, False):
        monkeypatch.setattr(alpha, "ENABLED", filtered)
        images[filtered] = tracer.render(scene, settings).rgb
    same = H.metrics(images[True], images[False])
    assert same["psnr"] >= FILTER_PSNR_MIN and same["mae"] <= FILTER_MAE_MAX, same
    H.check_images({"name": f"leaves_{variant}"}, images[True], ref, tmp_path, min_psnr=LEAF_PSNR_MIN,
                   max_mae=LEAF_MAE_MAX, label=" [addon]")

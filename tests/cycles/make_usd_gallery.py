"""Regenerate docs/gallery_usd.md and docs/gallery/usd_*.jpg: ours | Cycles (Blender's USD importer) | difference for
the UsdPreviewSurface / DomeLight stages of test_cycles_usd_materials.py that the tracer's material model carries.

    .venv/bin/python tests/cycles/make_usd_gallery.py
"""

from __future__ import annotations

import os
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(HERE), os.path.dirname(os.path.dirname(HERE))]

import numpy as np  # noqa: E402

import cycles_harness as H  # noqa: E402
import test_cycles_usd_materials as T  # noqa: E402
from cycles_thresholds import usd_material_bar  # noqa: E402
from cycles_usd_import import cycles_reference_usd  # noqa: E402


def main():
    import OpenImageIO as oiio

    out = os.path.join(H.ROOT, "docs")
    gdir = os.path.join(out, "gallery")
    os.makedirs(gdir, exist_ok=True)
    rows = []
    with tempfile.TemporaryDirectory(prefix="whitted-usd-gallery-") as tmp:
        for name, build in T.SCENES.items():
            path = T.S.as_blender_writes(build(os.path.join(tmp, name)))
            ref = cycles_reference_usd(path, name, T.SIZE, T.SIZE, T.CYCLES_SAMPLES, depth=2)["rgb"]
            ours, _info = T.render_ours(path)
            m = H.metrics(ours, ref)
            gap = np.ones((ours.shape[0], 2, 3))
            strip = np.concatenate([ours, gap, ref, gap, np.abs(ours - ref) * 4.0], 1)
            strip = np.repeat(np.repeat(strip, 2, 0), 2, 1)
            srgb = np.round(H.linear_to_srgb(strip) * 255).astype(np.uint8)
            p = os.path.join(gdir, f"{name}.jpg")
            spec = oiio.ImageSpec(srgb.shape[1], srgb.shape[0], 3, oiio.UINT8)
            spec.attribute("Compression", "jpeg:88")
            o = oiio.ImageOutput.create(p)
            o.open(p, spec)
            o.write_image(srgb)
            o.close()
            rows.append((name, m))
            print(f"{name}: PSNR {m['psnr']:.2f} dB, MAE {m['mae']:.5f}", flush=True)
    lines = ["# Gallery: USD materials against Cycles through Blender's USD importer", "",
             "Each stage (tests/usd_material_stages.py, tests/cycles/test_cycles_usd_materials.py) is read by "
             "`usd_io` for **ours** and imported by `bpy.ops.wm.usd_import` for **Cycles** (Whitted-equivalent "
             f"settings); then **|difference| × 4**. {T.SIZE}×{T.SIZE}, shown ×2, Blender {H.blender_version()}. "
             "Regenerate with `.venv/bin/python tests/cycles/make_usd_gallery.py`.", "",
             "| stage | PSNR (dB) | MAE | bar |", "|---|---|---|---|"]
    for name, m in rows:
        bar = usd_material_bar(name)
        if m is None:
            lines.append(f"| {name} | – | – | needs the Principled material model |")
        else:
            lines.append(f"| {name} | {m['psnr']:.2f} | {m['mae']:.5f} | ≥ {bar['psnr']:g} dB, ≤ {bar['mae']:g} |")
    lines.append("")
    for name, m in rows:
        if m is not None:
            lines += [f"### {name}", "", f"![{name}](gallery/{name}.jpg)", ""]
    with open(os.path.join(out, "gallery_usd.md"), "w") as f:
        f.write("\n".join(lines))
    print(f"wrote {os.path.join(out, 'gallery_usd.md')}")


if __name__ == "__main__":
    main()

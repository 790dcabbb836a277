"""Regenerate docs/gallery.md and docs/gallery/*.jpg: ours | Cycles | difference per image scene, with metrics.

    .venv/bin/python tests/cycles/make_gallery.py [--front-end addon|usd|direct]

Uses the same scenes, cache and harness as the tests (cold references are rendered, then cached).
"""

from __future__ import annotations

import argparse
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(os.path.dirname(HERE))]

import numpy as np  # noqa: E402

import cycles_harness as H  # noqa: E402
from cycles_scenes import IMAGE_SCENES  # noqa: E402
from cycles_thresholds import image_bar  # noqa: E402


def comparison_strip(ours, ref):
    """ours | Cycles | |difference| × 4, with 2-pixel white gaps."""
    gap = np.ones((ours.shape[0], 2, 3))
    return np.concatenate([ours, gap, ref, gap, np.abs(ours - ref) * 4.0], 1)


def write_strip(path, strip):
    import OpenImageIO as oiio

    srgb = np.round(H.linear_to_srgb(strip) * 255).astype(np.uint8)
    spec = oiio.ImageSpec(srgb.shape[1], srgb.shape[0], 3, oiio.UINT8)
    spec.attribute("Compression", "jpeg:88")
    out = oiio.ImageOutput.create(path)
    out.open(path, spec)
    out.write_image(srgb)
    out.close()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--front-end", default="addon", choices=H.FRONT_ENDS)
    ap.add_argument("--out", default=os.path.join(H.ROOT, "docs"))
    args = ap.parse_args(argv)

    gdir = os.path.join(args.out, "gallery")
    os.makedirs(gdir, exist_ok=True)
    rows = []
    for name, desc in IMAGE_SCENES.items():
        ref = H.cycles_reference(desc)["rgb"]
        ours = H.render_ours(desc, args.front_end).rgb
        m = H.metrics(ours, ref)
        bar = image_bar(name)
        strip = comparison_strip(ours, ref)
        write_strip(os.path.join(gdir, f"{name}.jpg"), strip)
        ok = m["psnr"] >= bar["psnr"] and m["mae"] <= bar["mae"]
        rows.append((name, desc, m, bar, ok))
        print(f"{name}: PSNR {m['psnr']:.2f} dB, MAE {m['mae']:.5f} {'ok' if ok else 'FAIL'}", flush=True)
    lines = ["# Gallery: the tracer against Blender Cycles", "",
             f"Each row: **ours** (front end `{args.front_end}`) | **Cycles** (Whitted-equivalent settings, "
             "`tests/cycles/cycles_harness.py`) | **|difference| × 4**, all linear images shown through the sRGB "
             f"curve, {IMAGE_SCENES['point_shadow']['width']}×{IMAGE_SCENES['point_shadow']['height']}. "
             "PSNR on sRGB, MAE in linear light; the bar is in `tests/cycles/cycles_thresholds.py`. "
             f"Blender {H.blender_version()}. Regenerate with `.venv/bin/python tests/cycles/make_gallery.py`.", "",
             "| scene | PSNR (dB) | MAE | bar | Cycles spp | ours spp | what it isolates |",
             "|---|---|---|---|---|---|---|"]
    for name, desc, m, bar, ok in rows:
        lines.append(f"| [{name}](#{name.replace('_', '-')}) | {m['psnr']:.2f} | {m['mae']:.5f} | "
                     f"≥ {bar['psnr']:g} dB, ≤ {bar['mae']:g} {'✓' if ok else '✗'} | {desc['samples']} | "
                     f"{desc['ours_samples']}² | {desc['note']} |")
    lines.append("")
    for name, desc, m, bar, ok in rows:
        lines += [f"### {name}", "", f"{desc['note']}. PSNR {m['psnr']:.2f} dB, MAE {m['mae']:.5f}, "
                  f"max depth {desc['depth']}.", "", f"![{name}](gallery/{name}.jpg)", ""]
    if args.front_end == "addon":  # node-tree scenes exist only through the add-on
        from test_cycles_addon_materials import gallery_lines
        lines += gallery_lines(gdir, lambda path, ours, ref: write_strip(path, comparison_strip(ours, ref)))
    with open(os.path.join(args.out, "gallery.md"), "w") as f:
        f.write("\n".join(lines))
    total = sum(os.path.getsize(os.path.join(gdir, p)) for p in os.listdir(gdir))
    print(f"wrote {os.path.join(args.out, 'gallery.md')} and {len(rows)} images ({total / 1024:.0f} KB)")


if __name__ == "__main__":
    main()

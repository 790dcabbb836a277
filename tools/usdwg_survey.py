"""Survey: render every usd-wg asset file and put ours beside the assets' own thumbnails.

    python tools/usdwg_survey.py ASSETS_DIR [--out /tmp/usdwg_survey] [--sheet docs/images/usdwg_contact.jpg]
                                 [--only WORD ...] [--timeout 120] [--width 128] [--sheet-only]

ASSETS_DIR is a checkout (or ``git archive``) of github.com/usd-wg/assets; nothing is downloaded. Every
``.usd/.usda/.usdc/.usdz`` under ``full_assets/`` and ``test_assets/`` is rendered by its own process,
``whitted render FILE -o OUT.png --width 128 --threads 1``, with a time limit. For each file the exit code, wall time
and every stderr line are recorded (``OUT_DIR/results.json``) and flagged:

    traceback   a Python traceback on stderr
    hang        killed at the time limit
    stray       a stderr line not in the ``whitted: ...`` form (progress lines ``OUT: WxH, ...`` are the CLI's own)
    black/white exit 0 and every pixel black (≤ 1/255) or white (≥ 254/255)
    nan         the CLI's warning that pixels were not finite (they are written black)
    exit        an exit code other than 0 and 2, or exit 2 with more than one error line

A summary table is printed. Then the contact sheet: for every file with a thumbnail or screenshot of its own
(``thumbnails/STEM.png``, ``screenshots/STEM.png``, ``STEM.png``/``.jpg`` next to it, ``thumbnail.png`` for the
file named after its directory, or ``screenshots|media/STEM_*.png|jpg``), ours (left) beside theirs (right), labelled, as one JPEG written by OpenImageIO.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
USD_EXTENSIONS = (".usd", ".usda", ".usdc", ".usdz")
IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg")
SUBDIRS = ("full_assets", "test_assets")
PROGRESS = re.compile(r"^\S+: \d+x\d+, [\d,]+ triangles, ")  # the CLI's one summary line per image


# ---------------------------------------------------------------------------------------------------- finding files
def asset_files(assets: str, only=()) -> list[str]:
    """Every USD file under full_assets/ and test_assets/, relative to ``assets``, sorted."""
    found = []
    for sub in SUBDIRS:
        for dirpath, _dirs, names in os.walk(os.path.join(assets, sub)):
            for name in names:
                if name.lower().endswith(USD_EXTENSIONS):
                    found.append(os.path.relpath(os.path.join(dirpath, name), assets))
    found.sort()
    return [f for f in found if not only or any(w in f for w in only)]


def thumbnail_for(path: str) -> str | None:
    """The asset's own picture of ``path`` (an absolute USD file path), or None."""
    folder, name = os.path.split(path)
    stem = os.path.splitext(name)[0]
    candidates = [os.path.join(folder, sub, stem + ext) for sub in ("thumbnails", "screenshots", "Screenshots", "")
                  for ext in IMAGE_EXTENSIONS]
    if stem == os.path.basename(folder):
        candidates += [os.path.join(folder, "thumbnail" + ext) for ext in IMAGE_EXTENSIONS]
    for sub in ("thumbnails", "screenshots", "Screenshots", "media"):  # STEM_<renderer>.jpg
        d = os.path.join(folder, sub)
        names = sorted(os.listdir(d)) if os.path.isdir(d) else []
        candidates += [os.path.join(d, n) for n in names
                       if n.startswith(stem + "_") and n.lower().endswith(IMAGE_EXTENSIONS)]
    return next((c for c in candidates if os.path.isfile(c)), None)


# ---------------------------------------------------------------------------------------------------- rendering
def whitted_command() -> list[str]:
    exe = os.path.join(os.path.dirname(sys.executable), "whitted")
    return [exe] if os.path.exists(exe) else [sys.executable, "-m", "usd_io.cli"]


def render_one(src: str, out_png: str, width: int, timeout: float) -> dict:
    """Run one render process; its exit code (None: killed at the time limit), wall time and stderr lines."""
    cmd = whitted_command() + ["render", src, "-o", out_png, "--width", str(width), "--threads", "1"]
    t0 = time.monotonic()
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=ROOT)
        code, err = p.returncode, p.stderr
    except subprocess.TimeoutExpired as exc:
        code = None
        err = exc.stderr.decode(errors="replace") if isinstance(exc.stderr, bytes) else (exc.stderr or "")
    return dict(exit=code, seconds=round(time.monotonic() - t0, 2),
                stderr=[ln for ln in err.splitlines() if ln.strip()])


def read_rgb(path: str) -> np.ndarray | None:
    """An image as float (H, W, 3) in 0..1 (display values), or None when it cannot be read."""
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(path)
    if buf.has_error:
        return None
    px = np.asarray(buf.get_pixels(oiio.FLOAT), np.float32)
    if px.ndim == 2:
        px = px[..., None]
    if px.shape[2] in (1, 2):  # grey, grey + alpha
        px = np.concatenate([np.repeat(px[..., :1], 3, axis=2), px[..., 1:]], axis=2)
    rgb, alpha = px[..., :3], (px[..., 3:4] if px.shape[2] >= 4 else None)
    if alpha is not None:  # composite over the sheet's grey, so transparent thumbnails stay readable
        rgb = rgb * alpha + 0.2 * (1.0 - alpha)
    return rgb


def flags_of(result: dict, image: np.ndarray | None) -> list[str]:
    """The survey's flags for one file (see the module docstring)."""
    lines, code = result["stderr"], result["exit"]
    flags = []
    if any("Traceback (most recent call last)" in ln for ln in lines):
        flags.append("traceback")
    if code is None:
        flags.append("hang")
    if any(not (ln.startswith("whitted: ") or PROGRESS.match(ln)) for ln in lines):
        flags.append("stray")
    if any(ln.startswith("whitted: warning:") and "not finite" in ln and "pixel" in ln for ln in lines):
        flags.append("nan")
    errors = [ln for ln in lines if ln.startswith("whitted: ") and not ln.startswith("whitted: warning:")]
    if code not in (0, 2, None) or (code == 2 and len(errors) != 1):
        flags.append("exit")
    if code == 0:
        if image is None:
            flags.append("no-image")
        elif float(image.max()) <= 1 / 255:
            flags.append("black")
        elif float(image.min()) >= 254 / 255:
            flags.append("white")
    return flags


def survey(assets: str, files: list[str], out_dir: str, width: int, timeout: float) -> list[dict]:
    results = []
    for i, rel in enumerate(files, 1):
        out_png = os.path.join(out_dir, "renders", rel.replace(os.sep, "__") + ".png")
        os.makedirs(os.path.dirname(out_png), exist_ok=True)
        if os.path.exists(out_png):
            os.remove(out_png)
        r = render_one(os.path.join(assets, rel), out_png, width, timeout)
        image = read_rgb(out_png) if r["exit"] == 0 and os.path.exists(out_png) else None
        r.update(file=rel, render=out_png if image is not None else None, flags=flags_of(r, image))
        results.append(r)
        print(f"[{i}/{len(files)}] {rel}: exit {r['exit']}, {r['seconds']} s {' '.join(r['flags'])}", flush=True)
    return results


def summary(results: list[dict]) -> str:
    """The table: one line per file that exits non-zero, is flagged or warns; then the totals."""
    rows = [f"{'exit':>4} {'s':>6} {'warn':>4}  {'flags':<16} file"]
    for r in results:
        warns = sum(ln.startswith("whitted: warning:") for ln in r["stderr"])
        rows.append(f"{str(r['exit']):>4} {r['seconds']:>6.1f} {warns:>4}  {','.join(r['flags']) or '-':<16} "
                    f"{r['file']}")
        if r["exit"] != 0:
            rows += [f"{'':>33}{ln}" for ln in r["stderr"] if not ln.startswith("whitted: warning:")][:3]
    codes: dict = {}
    for r in results:
        codes[r["exit"]] = codes.get(r["exit"], 0) + 1
    flagged: dict = {}
    for r in results:
        for f in r["flags"]:
            flagged[f] = flagged.get(f, 0) + 1
    slow = max(results, key=lambda r: r["seconds"]) if results else None
    rows.append("")
    rows.append(f"{len(results)} files; exit codes " + ", ".join(f"{k}: {v}" for k, v in sorted(
        codes.items(), key=lambda kv: (kv[0] is None, kv[0] or 0))))
    rows.append("flags: " + (", ".join(f"{k} {v}" for k, v in sorted(flagged.items())) or "none"))
    rows.append(f"files with warnings: {sum(any(ln.startswith('whitted: warning:') for ln in r['stderr']) for r in results)}")
    if slow:
        rows.append(f"slowest: {slow['file']} {slow['seconds']} s")
    return "\n".join(rows)


# ---------------------------------------------------------------------------------------------------- contact sheet
def fit_tile(rgb: np.ndarray, size: int) -> np.ndarray:
    """``rgb`` scaled (box filter, aspect kept) into a size × size tile on dark grey."""
    import OpenImageIO as oiio

    h, w = rgb.shape[:2]
    s = size / max(h, w)
    nw, nh = max(1, round(w * s)), max(1, round(h * s))
    src = oiio.ImageBuf(np.ascontiguousarray(rgb, np.float32))
    small = oiio.ImageBufAlgo.resize(src, roi=oiio.ROI(0, nw, 0, nh, 0, 1, 0, 3))
    tile = np.full((size, size, 3), 0.12, np.float32)
    y0, x0 = (size - nh) // 2, (size - nw) // 2
    tile[y0:y0 + nh, x0:x0 + nw] = np.asarray(small.get_pixels(oiio.FLOAT)).reshape(nh, nw, 3)
    return tile


def label_strip(text: str, width: int, height: int) -> np.ndarray:
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(oiio.ImageSpec(width, height, 3, oiio.FLOAT))
    oiio.ImageBufAlgo.render_text(buf, 3, height - 4, text, height - 5, "", (0.9, 0.9, 0.9))
    return np.asarray(buf.get_pixels(oiio.FLOAT)).reshape(height, width, 3)


def short_label(rel: str, chars: int) -> str:
    parts = rel.split("/")
    text = "/".join(parts[-2:]) if len(parts) > 1 else rel
    return text if len(text) <= chars else "…" + text[-(chars - 1):]


def pairs_of(assets: str, results: list[dict]) -> list[tuple[str, str | None, str]]:
    """(label, our render or None, their picture) for every file with a picture of its own."""
    out = []
    for r in results:
        theirs = thumbnail_for(os.path.join(assets, r["file"]))
        if theirs:
            out.append((r["file"], r.get("render"), theirs))
    return out


def contact_sheet(pairs, tile: int, columns: int, label_h: int = 13) -> np.ndarray:
    """Pairs (ours | theirs) in a grid, each with its label underneath; a missing render is a red tile."""
    pair_w, gap = 2 * tile + 2, 4
    cells = []
    for label, ours, theirs in pairs:
        a = read_rgb(ours) if ours else None
        a = fit_tile(a, tile) if a is not None else np.tile(np.float32([0.45, 0.05, 0.05]), (tile, tile, 1))
        b = read_rgb(theirs)
        b = fit_tile(b, tile) if b is not None else np.zeros((tile, tile, 3), np.float32)
        row = np.concatenate([a, np.ones((tile, 2, 3), np.float32), b], axis=1)
        cells.append(np.concatenate([row, label_strip(short_label(label, pair_w // 6), pair_w, label_h)], axis=0))
    rows = -(-len(cells) // columns)
    cell_h = tile + label_h
    sheet = np.zeros((rows * (cell_h + gap), columns * (pair_w + gap), 3), np.float32)
    for i, cell in enumerate(cells):
        y, x = (i // columns) * (cell_h + gap), (i % columns) * (pair_w + gap)
        sheet[y:y + cell_h, x:x + pair_w] = cell
    return sheet


def write_jpeg(path: str, pixels: np.ndarray, quality: int) -> None:
    import OpenImageIO as oiio

    data = np.round(np.clip(pixels, 0, 1) * 255).astype(np.uint8)
    h, w = data.shape[:2]
    spec = oiio.ImageSpec(w, h, 3, oiio.UINT8)
    spec.attribute("CompressionQuality", quality)
    spec.attribute("Compression", f"jpeg:{quality}")
    out = oiio.ImageOutput.create(path)
    if out is None or not out.open(path, spec):
        raise SystemExit(f"usdwg_survey: cannot write {path}: {oiio.geterror()}")
    out.write_image(data)
    out.close()


def write_sheet(path: str, sheet: np.ndarray, max_bytes: int) -> int:
    """The sheet as a JPEG under ``max_bytes`` (the quality lowered step by step); returns the quality used."""
    for quality in (85, 80, 75, 70, 65, 60, 55, 50):
        write_jpeg(path, sheet, quality)
        if os.path.getsize(path) <= max_bytes:
            break
    return quality


# ---------------------------------------------------------------------------------------------------- main
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("assets", help="the usd-wg assets directory (holding full_assets/ and test_assets/)")
    ap.add_argument("--out", default="/tmp/usdwg_survey", help="renders and results.json go here")
    ap.add_argument("--sheet", default=os.path.join(ROOT, "docs", "images", "usdwg_contact.jpg"))
    ap.add_argument("--png", help="also write the sheet as a PNG (to look at it)")
    ap.add_argument("--only", nargs="*", default=(), help="only files whose path contains one of these words")
    ap.add_argument("--timeout", type=float, default=120.0)
    ap.add_argument("--width", type=int, default=128)
    ap.add_argument("--tile", type=int, default=88, help="contact-sheet tile size in pixels")
    ap.add_argument("--columns", type=int, default=7, help="pairs per contact-sheet row")
    ap.add_argument("--max-kb", type=int, default=400)
    ap.add_argument("--sheet-only", action="store_true", help="rebuild the sheet from OUT/results.json")
    args = ap.parse_args(argv)
    if not all(os.path.isdir(os.path.join(args.assets, s)) for s in SUBDIRS):
        print(f"usdwg_survey: {args.assets} holds no full_assets/ and test_assets/", file=sys.stderr)
        return 2
    os.makedirs(args.out, exist_ok=True)
    results_path = os.path.join(args.out, "results.json")
    if args.sheet_only:
        with open(results_path) as f:
            results = json.load(f)
    else:
        results = survey(args.assets, asset_files(args.assets, args.only), args.out, args.width, args.timeout)
        with open(results_path, "w") as f:
            json.dump(results, f, indent=1)
    print(summary(results))
    pairs = pairs_of(args.assets, results)
    if pairs and args.sheet:
        sheet = contact_sheet(pairs, args.tile, args.columns)
        quality = write_sheet(args.sheet, sheet, args.max_kb * 1024)
        if args.png:
            import OpenImageIO as oiio

            oiio.ImageBuf(np.ascontiguousarray(sheet)).write(args.png, oiio.UINT8)
        print(f"contact sheet: {len(pairs)} pairs -> {args.sheet} ({os.path.getsize(args.sheet) // 1024} KB, "
              f"JPEG quality {quality})")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Sweep for silent greys and blank frames (issue #32: "0 silent greys, 0 blank frames") over the side-by-side
images the fidelity harnesses write, and over usd-wg's survey renders.

    python tools/blank_grey_sweep.py openusd ROWS.jsonl SIDE_BY_SIDE_DIR [...]   (tools/fidelity.py: Storm | ours | masks)
    python tools/blank_grey_sweep.py arnold ROWS.jsonl SIDE_BY_SIDE_DIR [...]    (tools/fidelity.py arnold: ref | ours | diff)
    python tools/blank_grey_sweep.py usdwg SURVEY_OUT_DIR                         (tools/usdwg_survey.py's results.json)

Per frame (the side-by-side split in thirds; both panels sRGB-encoded 8-bit):

    blank  ours is one colour (every pixel within 2/255 of the first) and the reference is not
    grey   of the pixels where ours and the reference both show something other than their own background (the
           most frequent colour of each panel; eroded by a pixel, so that edges and one-pixel lines blended with the
           background do not count), at least 25 % are neutral in ours (max − min of R, G, B < 0.03)
           and coloured in the reference (> 0.15): a surface drawn in a fallback grey where the reference has a
           colour. Listed with the row's warnings, so a grey that was announced is told from a silent one.

usd-wg has no reference: a frame is listed when our render is one colour (blank), when the survey flagged it
(black/white, exit, ...) or when the CLI refused the stage (exit 2); its warning and error lines are shown. Prints one line per listed frame and the counts.
"""

from __future__ import annotations

import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from fidelity import read_rgb  # noqa: E402  (a sibling script, as tools/fidelity.py imports its own)

UNIFORM = 2 / 255
NEUTRAL, COLOURED, GREY_SHARE = 0.03, 0.15, 0.25


def uniform(img: np.ndarray) -> bool:
    flat = img.reshape(-1, img.shape[-1])
    return bool(np.all(np.abs(flat - flat[0]).max(axis=0) <= UNIFORM))


def background_mask(img: np.ndarray) -> np.ndarray:
    """Pixels other than the panel's most frequent colour (its background), at 8 bits."""
    q = np.round(img * 255).astype(np.int32)
    keys = (q[..., 0] << 16) | (q[..., 1] << 8) | q[..., 2]
    values, counts = np.unique(keys, return_counts=True)
    return keys != values[np.argmax(counts)]


def erode(mask: np.ndarray) -> np.ndarray:
    """``mask`` without the pixels that have a neighbour (8-connected) outside it."""
    h, w = mask.shape
    pad = np.pad(mask, 1, constant_values=False)
    return np.all([pad[y:y + h, x:x + w] for y in range(3) for x in range(3)], axis=0)


def chroma(img: np.ndarray) -> np.ndarray:
    return img.max(axis=-1) - img.min(axis=-1)


def judge(ref: np.ndarray, ours: np.ndarray) -> dict:
    """{"blank": bool, "grey": share or None} of one pair of panels (sRGB-encoded, same size)."""
    out = {"blank": uniform(ours) and not uniform(ref), "grey": None}
    both = erode(background_mask(ref)) & erode(background_mask(ours))  # interiors: not edges blended with the
    # background (Storm's one-pixel curves on its orange clear colour are orange-tinted white)
    if both.sum() >= 16:
        share = float(np.mean((chroma(ours[both]) < NEUTRAL) & (chroma(ref[both]) > COLOURED)))
        out["grey"] = round(share, 3)
    return out


def panels(path: str):
    img = read_rgb(path)
    w = img.shape[1] // 3
    return img[:, :w], img[:, w:2 * w]


def sweep_rows(kind: str, jsonl: str, folder: str) -> list[dict]:
    listed = []
    for line in open(jsonl):
        row = json.loads(line)
        if kind == "openusd":
            if row.get("iou") is None:
                continue
            path = os.path.join(folder, os.path.splitext(row["baseline"])[0] + ".png")
            name = f"{row['test']} {row['baseline']}"
        else:
            path = os.path.join(folder, row["test"] + ".png")
            name = f"{row['test']} {row.get('title', '')}"
        if not os.path.exists(path):
            continue
        ref, ours = panels(path)
        got = judge(ref, ours)
        warnings = row.get("warning_texts", row.get("warnings"))
        nwarn = len(warnings) if isinstance(warnings, list) else (warnings or 0)
        if got["blank"] or (got["grey"] or 0) >= GREY_SHARE or row.get("refused"):
            listed.append(dict(name=name, blank=got["blank"], grey=got["grey"], warnings=nwarn,
                               refused=row.get("refused"), texts=warnings if isinstance(warnings, list) else None))
    return listed


def sweep_usdwg(folder: str) -> list[dict]:
    results = json.load(open(os.path.join(folder, "results.json")))
    listed = []
    for r in results if isinstance(results, list) else results.values():
        png = r.get("render")
        flags = list(r.get("flags") or [])
        if r.get("exit") == 2:
            flags.append("refused")  # exit 2: the CLI's one error line (bad input, or nothing drawn)
        blank = bool(png and os.path.exists(png) and uniform(read_rgb(png)))
        if blank or flags:
            listed.append(dict(name=r.get("file"), blank=blank, flags=flags, warnings=len(r.get("stderr", [])),
                               texts=[ln for ln in r.get("stderr", []) if "warning" in ln or "error" in ln][:6]))
    return listed


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if len(argv) < 2 or argv[0] not in ("openusd", "arnold", "usdwg"):
        print(__doc__.split("\n\n")[1], file=sys.stderr)
        return 2
    kind = argv[0]
    if kind == "usdwg":
        listed = sweep_usdwg(argv[1])
    else:
        listed = []
        for jsonl, folder in zip(argv[1::2], argv[2::2]):
            listed += sweep_rows(kind, jsonl, folder)
    for item in listed:
        tags = [t for t in ("blank" if item.get("blank") else "",
                            f"grey {item['grey']:.0%}" if (item.get("grey") or 0) >= GREY_SHARE else "",
                            "refused" if item.get("refused") else "",
                            ",".join(item.get("flags") or [])) if t]
        print(f"{item['name']:70s} {' '.join(tags):24s} warnings: {item.get('warnings', '')}")
        for t in (item.get("texts") or [])[:4]:
            print(f"    {t[:160]}")
    print(f"{len(listed)} frames listed: {sum(bool(i.get('blank')) for i in listed)} blank, "
          f"{sum((i.get('grey') or 0) >= GREY_SHARE for i in listed)} grey")
    return 0


if __name__ == "__main__":
    sys.exit(main())

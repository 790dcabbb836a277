"""How many Cycles samples give "the same anti-aliasing quality" as ours: ``python -m bench.calibrate``.

Ours at N×N samples is deterministic: its only error is aliasing, measured as the RMS difference (sRGB PNG values in
[0, 1]) between our N×N image and our own 8×8 image. Cycles at S samples has aliasing *and* Monte Carlo noise (glass
picks reflection or refraction per sample, lights and the world are sampled); its error is the RMS difference to its
own converged image (``--reference`` samples). The matching count is the smallest S (powers of 4) whose error is no
larger than ours. Measured at a small size (aliasing error per pixel shrinks with resolution, noise does not, so the
count found here is, if anything, generous to Cycles at 1920×1080).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from . import scenes
from .harness import SCENE_DIR, run_cycles, run_ours


def _read(path):
    import OpenImageIO as oiio

    return oiio.ImageBuf(str(path)).get_pixels(oiio.FLOAT)[..., :3]


def rms(a, b) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)))


def calibrate(scene: str, width: int, height: int, threads: int, ours_n: int = 1, reference: int = 256,
              candidates=(1, 4, 16, 64), work: Path = SCENE_DIR) -> dict:
    work.mkdir(parents=True, exist_ok=True)
    base = dict(width=width, height=height, threads=threads, runs=1, max_depth=8)
    img = {}
    for n in (ours_n, 8):
        p = work / f"cal_{scene}_ours{n}.png"
        run_ours(SimpleNamespace(**base, samples=n), scene, record=False, image=str(p))
        img[f"ours{n}"] = _read(p)
    ours_err = rms(img[f"ours{ours_n}"], img["ours8"])
    cyc = {}
    for s in (*candidates, reference):
        p = work / f"cal_{scene}_cycles{s}.png"
        r = run_cycles(SimpleNamespace(**base, cycles_samples=s), scene, image=str(p))
        cyc[s] = (_read(p), r["seconds"])
    errs = {s: rms(cyc[s][0], cyc[reference][0]) for s in candidates}
    match = next((s for s in candidates if errs[s] <= ours_err), None)
    return {"scene": scene, "size": f"{width}x{height}", "ours_samples": ours_n, "ours_error": ours_err,
            "cycles_error": errs, "reference": reference, "match": match}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default=",".join(scenes.SCENES))
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=90)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--samples", type=int, default=1, help="our N×N")
    ap.add_argument("--reference", type=int, default=256)
    a = ap.parse_args(argv)
    for s in a.scenes.split(","):
        r = calibrate(s, a.width, a.height, a.threads, a.samples, a.reference)
        print(json.dumps(r), flush=True)


if __name__ == "__main__":
    main()

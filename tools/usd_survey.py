"""Survey: read and render every USD stage under some directories, in-process, and count what goes wrong.

    python tools/usd_survey.py DIR [DIR ...] [--out /tmp/usd_survey] [--per-dir 4] [--width 64]
                               [--sheet sheet.png [--sheet-rows 16]] [--compare OTHER/results.jsonl]
                               [--timeout 600]

Nothing is downloaded: DIRs are checkouts the user made (e.g. OpenUSD's testenv stages, arnold-usd's testsuite,
tinyusdz's tests, usd-wg/assets). Every ``.usd/.usda/.usdc/.usdz`` file is a candidate; at most ``--per-dir`` per
directory (sorted; layers referenced by a test's stage sit beside it). A worker process runs
``usd_io.load_stage`` and ``tracer.render`` on each file and records, per file (``OUT/results.jsonl``):

    unreadable  pxr itself cannot open the file (not counted against us)
    traceback   any exception other than UsdInputError (a crash)
    refusal     UsdInputError on a file pxr opens
    blank       every pixel the same colour although the stage has visible gprims with points (a Mesh: and faces)
                or a size, or a PointInstancer with prototypes, protoIndices and positions (:func:`has_gprims`)
    empty       0 triangles although it has such gprims
    grey        a material no reader understood, drawn in a fallback grey (18 % or 50 %) with no warning naming it
    volumes     (not a fault) the stage's only gprims are volumes or particle fields, which the tracer does not
                render; counted apart, and a fault (``silent``) unless one warning line says so
    said        (not a fault) a blank or empty frame the scene says is right, counted apart with its ``reason``:
                a warning names what it lacks (:data:`SAID`: an Arnold background or atmosphere, points that are
                not finite), no eye ray meets a gprim (``out of view``: the objectid AOV is empty, e.g. a 1.5-unit
                torus seen from 4 700 units), or gprims are in view and every pixel is below 1/255 (``dark``: the
                authored lights do not reach them); the summary lists each with its reason for a person to check

Workers are restarted (and the file counted as ``hang``) when one file takes longer than ``--timeout`` seconds in
total for the chunk. The summary prints the counts; ``--compare`` prints them beside another run's. The contact
sheet (``--sheet``, a PNG) shows the renders of flagged files first, labelled, for a person to look at.

The same tool, pointed at main's checkout on PYTHONPATH, gives the "before" numbers.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

USD_EXTENSIONS = (".usd", ".usda", ".usdc", ".usdz")
FLAGS = ("traceback", "refusal", "blank", "empty", "grey", "silent", "hang", "volumes", "said")
#: Warning texts that name what a uniform frame lacks (content of the authoring renderer only): reason.
SAID = {"Arnold background": "Arnold-only background/atmosphere (warned)",
        "Arnold atmosphere": "Arnold-only background/atmosphere (warned)",
        "NaN or infinite coordinates": "points with NaN or infinite coordinates (warned, skipped)"}
#: Gprim types the tracer documents as not rendered (usd_io.reader: one warning line when they are all a stage has).
NOT_DRAWN = ("Volume", "ParticleField3DGaussianSplat", "ParticleField")


def stage_files(dirs, per_dir: int) -> list[str]:
    out = []
    for d in dirs:
        for dirpath, dirnames, names in os.walk(d):
            dirnames.sort()
            picked = sorted(n for n in names if n.lower().endswith(USD_EXTENSIONS))[:per_dir]
            out += [os.path.join(dirpath, n) for n in picked]
    return out


# ---------------------------------------------------------------------------------------------------- worker
def has_gprims(stage) -> bool:
    """Whether the stage has a gprim a renderer should draw: active, defined, visible at the earliest time, of
    purpose default or render, with points (point-based gprims; a Mesh also faces) or a size (implicit ones), and
    not under a PointInstancer (prototypes are drawn as its instances); or a PointInstancer with the prototypes,
    protoIndices and positions its schema requires (OpenUSD's pi_bad_schema_input expects an empty image)."""
    from pxr import Usd, UsdGeom

    t = Usd.TimeCode.EarliestTime()
    instancers = []
    for prim in stage.Traverse(Usd.TraverseInstanceProxies()):
        if any(prim.GetPath().HasPrefix(p) for p in instancers):
            continue
        img = UsdGeom.Imageable(prim)
        if prim.IsA(UsdGeom.PointInstancer):
            instancers.append(prim.GetPath())
            pi = UsdGeom.PointInstancer(prim)
            needs = (pi.GetPrototypesRel().GetForwardedTargets(), pi.GetProtoIndicesAttr().Get(t),
                     pi.GetPositionsAttr().Get(t))
            if all(v is not None and len(v) for v in needs) and img.ComputeVisibility(t) != UsdGeom.Tokens.invisible \
                    and any(_drawable_below(stage.GetPrimAtPath(p)) for p in needs[0]):
                return True
            continue
        if not prim.IsA(UsdGeom.Gprim) or prim.GetTypeName() in NOT_DRAWN:
            continue
        if img.ComputeVisibility(t) == UsdGeom.Tokens.invisible or img.ComputePurpose() not in ("default", "render"):
            continue
        if prim.IsA(UsdGeom.PointBased):
            pts = UsdGeom.PointBased(prim).GetPointsAttr().Get(t)
            if pts is None or len(pts) == 0:
                continue
        if prim.IsA(UsdGeom.Mesh) and not len(UsdGeom.Mesh(prim).GetFaceVertexCountsAttr().Get(t) or []):
            continue
        return True
    return False


def _drawable_below(prim) -> bool:
    """Whether a prototype holds a gprim the tracer draws (not only volumes or particle fields)."""
    from pxr import Usd, UsdGeom

    return bool(prim) and any(p.IsA(UsdGeom.Gprim) and p.GetTypeName() not in NOT_DRAWN
                              for p in Usd.PrimRange(prim, Usd.TraverseInstanceProxies()))


def silently_grey(info, stage) -> list[str]:
    """Materials no reader understood and no warning names, drawn in a fallback grey: their fields are only a grey
    ``base_color`` (what the reader wrote for a surface it could not read; a UsdPreviewSurface left at its 0.18
    fallback has roughness, ior, … as well, and is the spec's grey, not a silent one)."""
    greys = []
    for name, fields in info.materials.items():
        bc = fields.get("base_color")
        if set(fields) != {"base_color"} or not (isinstance(bc, tuple) and len(bc) == 3):
            continue
        if not (np.allclose(bc, 0.18, atol=1e-4) or np.allclose(bc, 0.5)) or name.startswith("displayColor"):
            continue
        if not any(name in w for w in info.warnings):
            greys.append(name)
    return greys


def blank_reason(scene, info, image) -> str | None:
    """Why a uniform (or empty) frame is what the scene says, or None: a warning naming what it lacks
    (:data:`SAID`); no eye ray meeting a gprim (the objectid AOV, rendered once more); or gprims in view but every
    pixel darker than 1/255 (the authored lights do not reach what the camera sees)."""
    from tracer import RenderSettings
    from tracer import render

    for w in info.warnings:
        for key, reason in SAID.items():
            if key in w:
                return reason
    if not len(scene.triangles):
        return None
    ids = render(scene, RenderSettings(width=info.width, height=info.height, samples=1, threads=1,
                                       aovs=("objectid",))).aovs["objectid"]
    if int(ids.max()) < 0:
        return "out of view (no eye ray meets a gprim)"
    if float(image.max()) < 1 / 255:
        if any("not found" in w for w in info.warnings):
            return "dark (gprims in view, every pixel < 1/255: a texture is missing, warned, its fallback black)"
        return "dark (gprims in view, every pixel < 1/255: the authored lights do not reach them)"
    return None


def examine(path: str, width: int, png: str | None) -> dict:
    from pxr import Usd

    from tracer import RenderSettings
    from tracer import render
    from usd_io import UsdInputError, load_stage

    rec = dict(file=path, flags=[], warnings=0)
    try:
        with open(os.devnull, "w") as devnull:  # pxr's own diagnostics on fd 2 are not ours
            saved = os.dup(2)
            os.dup2(devnull.fileno(), 2)
            try:
                stage = Usd.Stage.Open(path)
            finally:
                os.dup2(saved, 2)
                os.close(saved)
    except Exception:
        stage = None
    if stage is None:
        rec["flags"].append("unreadable")
        return rec
    gprims = has_gprims(stage)  # visible gprims with geometry: only then is a blank frame or 0 triangles wrong
    rec["gprims"] = gprims
    only_volumes = not gprims and any(p.GetTypeName() in NOT_DRAWN for p in stage.Traverse())
    try:
        scene, info = load_stage(path, width=width)
        image = render(scene, RenderSettings(width=info.width, height=info.height, samples=1, threads=1)).rgb
    except UsdInputError as exc:
        rec["flags"].append("refusal")
        rec["error"] = str(exc)[:300]
        return rec
    except Exception as exc:  # noqa: BLE001  (the survey counts crashes)
        import traceback

        rec["flags"].append("traceback")
        rec["error"] = "".join(traceback.format_exception_only(type(exc), exc)).strip()[:300]
        return rec
    rec["warnings"] = len(info.warnings)
    rec["notes"] = [n for n in info.notes][:3]
    rec["triangles"] = int(sum(n for _p, n in info.meshes))
    if only_volumes:
        rec["flags"].append("volumes")
        if not any("only gprims are" in w for w in info.warnings):
            rec["flags"].append("silent")
    empty = gprims and rec["triangles"] == 0
    blank = gprims and float(np.ptp(image.reshape(-1, 3), axis=0).max()) < 1 / 255
    reason = blank_reason(scene, info, image) if empty or blank else None
    if reason:
        rec["flags"].append("said")
        rec["reason"] = reason
    else:
        rec["flags"] += ["empty"] * empty + ["blank"] * blank
    grey = silently_grey(info, stage)
    if grey:
        rec["flags"].append("grey")
        rec["grey"] = grey[:5]
    if png:
        from tracer import Image

        Image(np.concatenate([image, np.ones(image.shape[:2] + (1,), np.float32)], axis=2)).save(png)
        rec["png"] = png
    return rec


def worker(list_file: str, out_jsonl: str, width: int, png_dir: str) -> None:
    files = [ln.rstrip("\n") for ln in open(list_file) if ln.strip()]
    for i, path in enumerate(files):
        png = os.path.join(png_dir, f"{abs(hash(path)) % 10**10:010d}.png") if png_dir else None
        t0 = time.monotonic()
        rec = examine(path, width, png)
        rec["seconds"] = round(time.monotonic() - t0, 2)
        with open(out_jsonl, "a") as f:
            f.write(json.dumps(rec) + "\n")


# ---------------------------------------------------------------------------------------------------- driver
def run(files: list[str], out: str, width: int, timeout: float) -> list[dict]:
    os.makedirs(os.path.join(out, "renders"), exist_ok=True)
    jsonl = os.path.join(out, "results.jsonl")
    done = {}
    if os.path.exists(jsonl):
        for ln in open(jsonl):
            r = json.loads(ln)
            done[r["file"]] = r
    todo = [f for f in files if f not in done]
    while todo:
        lst = os.path.join(out, "todo.txt")
        open(lst, "w").write("\n".join(todo) + "\n")
        cmd = [sys.executable, os.path.abspath(__file__), "--worker", lst, jsonl, str(width),
               os.path.join(out, "renders")]
        last = len(done)
        p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        t_last = time.monotonic()
        while p.poll() is None:
            time.sleep(0.5)
            n = sum(1 for _ in open(jsonl)) if os.path.exists(jsonl) else 0
            if n != last:
                last, t_last = n, time.monotonic()
                print(f"\r{n}/{len(files)}", end="", file=sys.stderr, flush=True)
            elif time.monotonic() - t_last > timeout:
                p.kill()
                p.wait()
                break
        done = {}
        for ln in open(jsonl) if os.path.exists(jsonl) else ():
            r = json.loads(ln)
            done[r["file"]] = r
        todo = [f for f in files if f not in done]
        if todo and p.returncode not in (0, None):  # the worker died or hung on todo[0]
            with open(jsonl, "a") as f:
                f.write(json.dumps(dict(file=todo[0], flags=["hang" if p.returncode < 0 else "traceback"],
                                        error=f"worker exit {p.returncode}")) + "\n")
            done[todo[0]] = True
            todo = todo[1:]
    print(file=sys.stderr)
    return [json.loads(ln) for ln in open(jsonl) if json.loads(ln)["file"] in set(files)]


def counts(results: list[dict]) -> dict:
    c = {k: 0 for k in ("files", "unreadable") + FLAGS}
    c["files"] = len(results)
    for r in results:
        for f in r["flags"]:
            c[f] = c.get(f, 0) + 1
    return c


def summary(results: list[dict], root: str, compare: list[dict] | None = None) -> str:
    rows = []
    for r in results:
        bad = [f for f in r["flags"] if f != "unreadable"]
        if bad:
            rows.append(f"{','.join(bad):<18} {os.path.relpath(r['file'], root)}  {r.get('error', '')[:120]}"
                        f"{r.get('reason', '')}"
                        f"{' grey: ' + ', '.join(r['grey']) if r.get('grey') else ''}")
    c = counts(results)
    rows.append("")
    if compare is not None:
        b = counts(compare)
        rows.append(f"{'':<12} {'before':>7} {'after':>7}")
        rows += [f"{k:<12} {b.get(k, 0):>7} {c.get(k, 0):>7}" for k in c]
    else:
        rows.append(", ".join(f"{k} {v}" for k, v in c.items()))
    return "\n".join(rows)


def contact_sheet(results: list[dict], root: str, path: str, tile: int = 64, columns: int = 12,
                  compare: list[dict] | None = None, rows: int = 16) -> None:
    """Flagged renders first (``!``), then those whose flags changed since ``compare`` (``*``: e.g. blank before,
    drawn now), then the rest, each labelled; as a PNG."""
    import OpenImageIO as oiio

    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from usdwg_survey import fit_tile, label_strip, read_rgb

    before = {r["file"]: set(r["flags"]) for r in compare or ()}
    flagged = lambda r: bool([f for f in r["flags"] if f != "unreadable"])  # noqa: E731
    changed = lambda r: r["file"] in before and before[r["file"]] != set(r["flags"])  # noqa: E731
    ordered = sorted((r for r in results if r.get("png") and os.path.exists(r["png"])),
                     key=lambda r: (not flagged(r), not changed(r), r["file"]))
    cells = []
    for r in ordered[: columns * rows]:
        rgb = read_rgb(r["png"])
        t = fit_tile(rgb, tile) if rgb is not None else np.zeros((tile, tile, 3), np.float32)
        mark = "!" if flagged(r) else "*" if changed(r) else ""
        name = os.path.basename(r["file"])
        if os.path.basename(os.path.dirname(r["file"])) == "data":  # arnold-usd's tests: the folder says which
            name = os.path.basename(os.path.dirname(os.path.dirname(r["file"]))) or name
        label = mark + name[:18]
        cells.append(np.concatenate([t, label_strip(label, tile, 11)], axis=0))
    if not cells:
        return
    rows = -(-len(cells) // columns)
    h, w = cells[0].shape[:2]
    sheet = np.zeros((rows * (h + 2), columns * (w + 2), 3), np.float32)
    for i, cell in enumerate(cells):
        y, x = (i // columns) * (h + 2), (i % columns) * (w + 2)
        sheet[y:y + h, x:x + w] = cell
    oiio.ImageBuf(np.ascontiguousarray(sheet, np.float32)).write(path, oiio.UINT8)  # PNG display values already


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--worker"]:
        worker(argv[1], argv[2], int(argv[3]), argv[4])
        return 0
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dirs", nargs="+")
    ap.add_argument("--out", default="/tmp/usd_survey")
    ap.add_argument("--per-dir", type=int, default=4)
    ap.add_argument("--width", type=int, default=64)
    ap.add_argument("--timeout", type=float, default=300.0)
    ap.add_argument("--sheet", help="contact sheet PNG")
    ap.add_argument("--sheet-rows", type=int, default=16, help="rows of 12 renders on the contact sheet")
    ap.add_argument("--compare", help="another run's results.jsonl: counts side by side")
    args = ap.parse_args(argv)
    files = stage_files(args.dirs, args.per_dir)
    results = run(files, args.out, args.width, args.timeout)
    compare = None
    if args.compare:
        compare = [json.loads(ln) for ln in open(args.compare)]
    root = os.path.commonpath([os.path.abspath(d) for d in args.dirs])
    print(summary(results, root, compare))
    if args.sheet:
        contact_sheet(results, root, args.sheet, compare=compare, rows=args.sheet_rows)
        print(f"contact sheet -> {args.sheet}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

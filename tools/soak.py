"""Soak: render every stage of a corpus many times, at several thread counts, under CPU load, and count faults.

    python tools/soak.py CORPUS_DIR_OR_FILES ... [--runs 10] [--threads 1,2,8] [--width 96] [--hog | --no-hog]
                         [--timeout S] [--seed 0] [--json out.json] [--command "PROGRAM ARGS"] [--keep DIR]

Every ``.usd/.usda/.usdc/.usdz`` file named, or found under a directory named (recursively, sorted), is a stage.
Each stage is rendered ``--runs`` times with each ``--threads`` count, every render in its own process
(``python -m usd_io.cli render STAGE -o OUT.exr --width W --threads T --seed S --quiet``), so a segfault is a
signal the tool sees, not the tool's own death. The EXR (linear float) goes to a temporary folder, removed at the
end (``--keep DIR`` writes there instead and keeps them). While the renders run, a CPU hog (a child process spinning
on one core) competes with them, unless ``--no-hog``; the tool starts and stops it.

Counted per stage:

    crashes    the render process was killed by a signal (by name: SIGSEGV, SIGABRT, ...)
    hangs      it ran longer than the timeout (``--timeout`` seconds, else 10x the stage's first render, at least
               60 s) and was killed
    errors     it exited with a non-zero code, or wrote no readable image
    nonfinite  the image holds NaN or infinite values (renders with any are counted once each)
    unequal    the image differs from the stage's first image (same seed: the renderer is deterministic for any
               thread count, so every pixel must be identical)

A per-stage table and the totals are printed; ``--json`` writes them with a row per render (the tail of stderr of
a failed render is kept: the children run with PYTHONFAULTHANDLER=1, so a crash shows its threads' stacks).
``--command`` replaces the render program (split like a shell line; the render arguments above are appended), e.g.
to test the tool with a child that kills itself. The children inherit the environment (``WHITTED_KERNEL_CACHE``).

Exit codes: 0 every count is 0; 1 some count is not; 2 bad input (one line on stderr).
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter

import numpy as np

USD_EXTENSIONS = (".usd", ".usda", ".usdc", ".usdz")
COUNTS = ("crashes", "hangs", "errors", "nonfinite", "unequal")
#: Floor of the automatic per-render timeout (seconds): a first render that was quick must not make a slow,
#: loaded machine look like a hang.
MIN_TIMEOUT = 60.0
TIMEOUT_FACTOR = 10.0
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


class BadInput(Exception):
    pass


def stage_files(paths) -> list[str]:
    """The stages named, or under the directories named (sorted, each once)."""
    out = []
    for p in paths:
        if os.path.isdir(p):
            for dirpath, dirnames, names in os.walk(p):
                dirnames.sort()
                out += [os.path.join(dirpath, n) for n in sorted(names) if n.lower().endswith(USD_EXTENSIONS)]
        elif os.path.isfile(p):
            if not p.lower().endswith(USD_EXTENSIONS):
                raise BadInput(f"{p}: not a USD file ({', '.join(USD_EXTENSIONS)})")
            out.append(p)
        else:
            raise BadInput(f"{p}: no such file or directory")
    out = list(dict.fromkeys(os.path.abspath(p) for p in out))
    if not out:
        raise BadInput(f"no USD stage ({', '.join(USD_EXTENSIONS)}) in {' '.join(paths)}")
    return out


def parse_threads(text: str) -> list[int]:
    try:
        counts = [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        counts = []
    if not counts or min(counts) < 1:
        raise BadInput(f"--threads {text!r}: expected positive integers separated by commas, e.g. 1,2,8")
    return counts


def render_command(args, stage: str, out: str, threads: int) -> list[str]:
    prog = shlex.split(args.command) if args.command else [sys.executable, "-m", "usd_io.cli"]
    return prog + ["render", stage, "-o", out, "--width", str(args.width), "--threads", str(threads),
                   "--seed", str(args.seed), "--quiet"]


def child_env() -> dict:
    env = dict(os.environ, PYTHONFAULTHANDLER="1")
    # The children import this checkout's usd_io/tracer, wherever the tool is run from.
    env["PYTHONPATH"] = os.pathsep.join([ROOT] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    return env


def run_one(cmd: list[str], timeout: float | None) -> dict:
    """Run a render child in its own process group; its outcome: returncode, signal, hang, seconds, stderr."""
    t0 = time.monotonic()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=child_env(),
                            start_new_session=True)
    hang = False
    try:
        _, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        hang = True
        os.killpg(proc.pid, signal.SIGKILL)
        _, err = proc.communicate()
    except BaseException:  # Ctrl-C: the child is in its own session, so it would not get the signal
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        raise
    rc = proc.returncode
    sig = signal.Signals(-rc).name if rc < 0 and not hang else None
    return {"returncode": rc, "signal": sig, "hang": hang, "seconds": round(time.monotonic() - t0, 3),
            "stderr": err.decode("utf-8", "replace")[-4000:]}


def read_image(path: str):
    """Pixels of an image file as float32 (H, W, C), or None when it is missing or unreadable."""
    if not os.path.isfile(path):
        return None
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(path)
    if inp is None:
        return None
    try:
        px = inp.read_image(oiio.FLOAT)
    finally:
        inp.close()
    return None if px is None else np.asarray(px, np.float32)


def check_render(row: dict, out: str, reference):
    """Add the image checks to ``row``; the pixels (the stage's reference when it has none yet)."""
    px = read_image(out)
    if px is None:
        row["error"] = "no readable image" if row["returncode"] == 0 else f"exit code {row['returncode']}"
        return None
    bad = int(np.count_nonzero(~np.isfinite(px)))
    if bad:
        row["nonfinite"] = bad
    if reference is not None:
        if px.shape != reference.shape:
            row["unequal"] = f"shape {px.shape} != {reference.shape}"
        elif not np.array_equal(px, reference, equal_nan=True):
            diff = np.abs(np.nan_to_num(px) - np.nan_to_num(reference))
            row["unequal"] = {"pixels": int(np.count_nonzero(diff.max(axis=-1) > 0)),
                              "max_abs": float(diff.max())}
    return px


def classify(row: dict) -> str | None:
    """The count a render adds to (one per render, the worst first), or None when it is clean."""
    if row["signal"]:
        return "crashes"
    if row["hang"]:
        return "hangs"
    if row.get("error") or row["returncode"] != 0:
        return "errors"
    if row.get("nonfinite"):
        return "nonfinite"
    if row.get("unequal"):
        return "unequal"
    return None


def start_hog():
    """A child process spinning on one core until killed."""
    return subprocess.Popen([sys.executable, "-c", "while True: pass"], start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def stop_hog(hog) -> None:
    if hog is not None and hog.poll() is None:
        hog.kill()
        hog.wait()


def soak_stage(args, stage: str, threads: list[int], folder: str, log) -> dict:
    """All renders of one stage: runs x threads. Returns its summary with a row per render."""
    rows, reference, timeout = [], None, args.timeout
    name = os.path.splitext(os.path.basename(stage))[0]
    for run in range(args.runs):
        for t in threads:
            out = os.path.join(folder, f"{name}.r{run}.t{t}.exr")
            row = {"run": run, "threads": t, **run_one(render_command(args, stage, out, t), timeout)}
            if not row["signal"] and not row["hang"]:
                px = check_render(row, out, reference)
                if reference is None and px is not None and row["returncode"] == 0:
                    reference = px
                    row["reference"] = True
            if timeout is None and row["returncode"] == 0:
                timeout = max(MIN_TIMEOUT, TIMEOUT_FACTOR * row["seconds"])
            if not args.keep and os.path.exists(out):
                os.remove(out)
            row["count"] = classify(row)
            if row["count"] is None or row["count"] in ("nonfinite", "unequal"):
                row.pop("stderr", None)
            rows.append(row)
            log(f"  {name} run {run + 1}/{args.runs} threads {t}: {row['seconds']:.1f} s "
                f"{row['count'] or 'ok'}{' ' + row['signal'] if row['signal'] else ''}")
    counts = Counter(r["count"] for r in rows if r["count"])
    return {"stage": stage, "renders": len(rows), **{k: counts.get(k, 0) for k in COUNTS},
            "signals": dict(Counter(r["signal"] for r in rows if r["signal"])),
            "median_seconds": float(np.median([r["seconds"] for r in rows])), "rows": rows}


def totals(stages: list[dict]) -> dict:
    sig = Counter()
    for s in stages:
        sig.update(s["signals"])
    return {"stages": len(stages), "renders": sum(s["renders"] for s in stages),
            **{k: sum(s[k] for s in stages) for k in COUNTS}, "signals": dict(sig)}


def print_table(stages: list[dict], total: dict, args, threads) -> None:
    w = max([len(os.path.basename(s["stage"])) for s in stages] + [5])
    head = f"{'stage':<{w}} {'renders':>7} " + " ".join(f"{k:>9}" for k in COUNTS) + f" {'median s':>8}  signals"
    print(head)
    print("-" * len(head))
    for s in stages:
        sigs = ", ".join(f"{k} x{v}" for k, v in s["signals"].items())
        print(f"{os.path.basename(s['stage']):<{w}} {s['renders']:>7} " + " ".join(f"{s[k]:>9}" for k in COUNTS)
              + f" {s['median_seconds']:>8.2f}  {sigs}")
    print("-" * len(head))
    sigs = ", ".join(f"{k} x{v}" for k, v in total["signals"].items()) or "none"
    print(f"{total['stages']} stages, {total['renders']} renders ({args.runs} runs x threads {threads}, width "
          f"{args.width}, hog {'on' if args.hog else 'off'}): crashes {total['crashes']} (signals: {sigs}), "
          f"hangs {total['hangs']}, errors {total['errors']}, non-finite {total['nonfinite']}, "
          f"unequal repeats {total['unequal']}")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="soak.py", description=__doc__.split("\n\n")[0])
    p.add_argument("paths", nargs="+", metavar="CORPUS", help="USD files or directories searched for them")
    p.add_argument("--runs", type=int, default=10, help="renders per stage and thread count (default 10)")
    p.add_argument("--threads", default="1,2,8", help="thread counts, comma-separated (default 1,2,8)")
    p.add_argument("--width", type=int, default=96, help="image width in pixels (default 96)")
    p.add_argument("--seed", type=int, default=0, help="the renders' --seed (default 0)")
    p.add_argument("--hog", action=argparse.BooleanOptionalAction, default=True,
                   help="run a CPU hog (one spinning core) during the renders (default on)")
    p.add_argument("--timeout", type=float, default=None,
                   help=f"seconds per render before it counts as a hang (default {TIMEOUT_FACTOR:g}x the stage's "
                        f"first render, at least {MIN_TIMEOUT:g})")
    p.add_argument("--json", metavar="OUT.json", help="write the summary and a row per render here")
    p.add_argument("--command", help="render program replacing 'python -m usd_io.cli' (shell-split)")
    p.add_argument("--keep", metavar="DIR", help="write the EXRs here and keep them")
    return p


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise BadInput(message)


def main(argv=None) -> int:
    parser = build_parser()
    parser.__class__ = _Parser
    hog = None
    try:
        args = parser.parse_args(argv)
        threads = parse_threads(args.threads)
        if args.runs < 1 or args.width < 1 or (args.timeout is not None and args.timeout <= 0):
            raise BadInput("--runs and --width must be at least 1, --timeout positive")
        if args.command is not None and not shlex.split(args.command):
            raise BadInput("--command is empty")
        stages = stage_files(args.paths)
    except BadInput as e:
        print(f"soak.py: {e}", file=sys.stderr)
        return 2
    folder = args.keep or tempfile.mkdtemp(prefix="whitted_soak_")
    os.makedirs(folder, exist_ok=True)
    results = []
    try:
        if args.hog:
            hog = start_hog()
        for stage in stages:
            print(f"{stage}", file=sys.stderr, flush=True)
            results.append(soak_stage(args, stage, threads, folder,
                                      lambda s: print(s, file=sys.stderr, flush=True)))
    finally:
        stop_hog(hog)
        if not args.keep:
            shutil.rmtree(folder, ignore_errors=True)
    total = totals(results)
    print_table(results, total, args, threads)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"settings": {"runs": args.runs, "threads": threads, "width": args.width, "seed": args.seed,
                                    "hog": args.hog, "timeout": args.timeout, "command": args.command},
                       "totals": total, "stages": results}, f, indent=1)
    return 1 if any(total[k] for k in COUNTS) else 0


if __name__ == "__main__":
    sys.exit(main())

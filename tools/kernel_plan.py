"""``python -m tools.kernel_plan``: make tracer/kernel_plan.json again (see tracer/kernel_plan.py).

Renders the bundled example (what ``make render`` renders) with an empty kernel cache in a child process, recording
the stages it compiles, in order, with their argument types, and writes the plan. Run it after changing a stage's
arguments (tests/test_kernel_plan.py says when the shipped plan no longer covers the bundled example)."""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = ["examples/whitted_1980.usda"]

CHILD = r"""
import json, os, sys
from tracer.kernel_plan import Recorder
import usd_io.cli as cli
out, scenes = sys.argv[1], sys.argv[2:]
with Recorder() as rec:
    for scene in scenes:
        code = cli.main(["render", scene, "-o", os.path.join(os.path.dirname(out), "plan.png"), "--quiet"])
        if code:
            sys.exit(f"rendering {scene} failed ({code})")
with open(out, "w") as f:
    json.dump(rec.document(scenes), f, indent=1)
    f.write("\n")
"""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=os.path.join(ROOT, "tracer", "kernel_plan.json"))
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, WHITTED_KERNEL_CACHE=os.path.join(tmp, "kernels"), WHITTED_COMPILE_PROCESSES="0",
                   PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
        plan = os.path.join(tmp, "plan.json")
        subprocess.run([sys.executable, "-c", CHILD, plan, *SCENES], env=env, cwd=ROOT, check=True)
        with open(plan) as f:
            doc = json.load(f)
        with open(args.out, "w") as f:
            json.dump(doc, f, indent=1)
            f.write("\n")
    print(f"{args.out}: {len(doc['stages'])} stages, {doc['units']} units, from {', '.join(SCENES)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

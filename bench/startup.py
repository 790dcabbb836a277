"""``python -m bench.startup``: start-up and batch overhead of the ``whitted`` CLI (issue #11).

Measures, warm (kernels already cached, the run repeated), the wall time of ``whitted render`` of a one-sphere
stage at 64×64 as a fresh process, how much of it is ``import usd_io.cli`` plus its lazy imports, and the
per-file overhead of a batch (``whitted render a.usda b.usda ... -o out/{stem}.png``: (T(N) − T(1)) / (N − 1)).
Prints the median of REPEAT runs; no assertions (docs/benchmarks.md records the numbers).
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
REPEAT = 5
BATCH = 10
STAGE = '#usda 1.0\ndef Sphere "Ball" {}\n'


def _run(args):
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    t = time.perf_counter()
    subprocess.run([sys.executable, "-c", "import sys; from usd_io.cli import main; sys.exit(main())", *args],
                   check=True, env=env, capture_output=True)
    return time.perf_counter() - t


def _median(fn):
    return statistics.median(fn() for _ in range(REPEAT))


def main():
    with tempfile.TemporaryDirectory() as d:
        files = []
        for i in range(BATCH):
            p = os.path.join(d, f"ball{i}.usda")
            with open(p, "w") as f:
                f.write(STAGE)
            files.append(p)
        out = os.path.join(d, "{stem}.png")
        common = ["--width", "64", "--quiet"]
        _run(["render", files[0], "-o", out, *common])  # warm the kernel cache
        python = _median(lambda: _run(["--version"]))
        one = _median(lambda: _run(["render", files[0], "-o", out, *common]))
        many = _median(lambda: _run(["render", *files, "-o", out, *common]))
    env = dict(os.environ, PYTHONPATH=ROOT)
    imports = statistics.median(float(subprocess.run(
        [sys.executable, "-c", "import time; t = time.perf_counter(); import usd_io.reader, tracer.render; "
                               "print(time.perf_counter() - t)"], env=env, capture_output=True, text=True,
        check=True).stdout) for _ in range(REPEAT))
    print(f"python + argparse (whitted --version): {python:.2f} s")
    print(f"imports (usd_io.reader, tracer.render):  {imports:.2f} s")
    print(f"one 64x64 sphere, fresh process, warm:   {one:.2f} s")
    print(f"batch of {BATCH}: {many:.2f} s -> {(many - one) / (BATCH - 1):.3f} s per extra file")


if __name__ == "__main__":
    main()

"""Start-up shortcuts of the ``whitted`` command (issue #11) keep every behaviour:

- ``usd_io.cli.run`` (the console script) ends the process with ``os._exit`` after joining threads, running atexit
  handlers and flushing: same exit codes, same messages, the image complete, as ``sys.exit(main())``;
- ``tracer.kernel_cache.KernelCache`` loads cached kernels without numba's full target refresh: the pixels are the same,
  and a kernel that is not in the cache still compiles in a process that only loaded from it.
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from tracer import read_image

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
STAGE = ('#usda 1.0\n(\n    upAxis = "Z"\n)\ndef Sphere "Ball" {}\n'
         'def SphereLight "Key" {\n    float inputs:intensity = 5\n}\n')
ENTRIES = {"run": "from usd_io.cli import run; run()",
           "main": "import sys; from usd_io.cli import main; sys.exit(main())"}


def _python(code, *args, env=None):
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""), **(env or {}))
    return subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True, cwd=ROOT,
                          env=env, timeout=300)


@pytest.fixture(scope="module")
def ball(tmp_path_factory):
    path = tmp_path_factory.mktemp("startup") / "ball.usda"
    path.write_text(STAGE)
    return path


def test_run_and_main_give_the_same_image_messages_and_exit_code(ball, tmp_path):
    results = {}
    for name, code in ENTRIES.items():
        out = tmp_path / f"{name}.png"
        r = _python(code, "render", ball, "-o", out, "--width", "32", "--aov", "depth")
        assert r.returncode == 0, r.stderr
        results[name] = (r.stderr.replace(str(out), "OUT"), read_image(str(out)),
                         read_image(str(tmp_path / f"{name}.depth.exr")))
        assert not [p for p in os.listdir(tmp_path) if p.startswith(".") or p.endswith(".tmp")]  # renamed
    (err_run, img_run, depth_run), (err_main, img_main, depth_main) = results["run"], results["main"]
    assert "OUT: 32x" in err_run
    assert err_run.splitlines()[-1] == err_main.splitlines()[-1].replace(
        err_main.splitlines()[-1].split(" in ")[-1], err_run.splitlines()[-1].split(" in ")[-1])
    assert np.array_equal(img_run, img_main) and np.array_equal(depth_run, depth_main)


@pytest.mark.parametrize("args, says", [
    (["render", "{missing}", "-o", "{out}"], "no such file"),
    (["render", "{bad}", "-o", "{out}"], "{bad}"),
    (["render", "{ball}", "-o", "{out}", "--width", "0"], "--width must be an integer >= 1"),
    (["render", "{ball}", "-o", "{tmp}/no/such/dir/x.png"], "does not exist"),
    (["render"], "the following arguments are required"),
])
def test_run_bad_input_is_one_line_and_exit_2(ball, tmp_path, args, says):
    bad = tmp_path / "bad.usda"
    bad.write_text("#usda 1.0\ndef Sphere \"Ball\" {\n")  # unterminated
    names = dict(ball=ball, bad=bad, missing=tmp_path / "missing.usda", out=tmp_path / "o.png", tmp=tmp_path)
    r = _python(ENTRIES["run"], *(a.format(**names) for a in args))
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("whitted: error:") and says.format(**names) in lines[0], r.stderr
    assert "Traceback" not in r.stderr and not (tmp_path / "o.png").exists()


def test_run_version_help_and_stdout_are_flushed(tmp_path):
    r = _python(ENTRIES["run"], "--version")
    assert r.returncode == 0 and r.stdout.startswith("whitted ") and not r.stderr
    r = _python(ENTRIES["run"], "render", "--help")
    assert r.returncode == 0 and "--output" in r.stdout and not r.stderr


def test_run_info_output_reaches_a_pipe(ball):
    r = _python(ENTRIES["run"], "info", ball)  # stdout is a pipe (block-buffered): run() flushes it
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("stage: ") and "materials (" in r.stdout


def test_run_runs_atexit_handlers_and_joins_threads(ball, tmp_path):
    flag = tmp_path / "atexit.txt"
    code = ("import atexit, sys, threading, time\n"
            f"atexit.register(lambda: open({str(flag)!r}, 'a').write('atexit\\n'))\n"
            f"threading.Thread(target=lambda: (time.sleep(0.3), open({str(flag)!r}, 'a').write('thread\\n'))).start()\n"
            "from usd_io.cli import run\nrun()")
    r = _python(code, "render", ball, "-o", tmp_path / "x.png", "--width", "8", "--quiet")
    assert r.returncode == 0, r.stderr
    assert flag.read_text() == "thread\natexit\n"


def test_tracer_kernels_use_the_content_keyed_cache_with_the_light_loader():
    import tracer.integrator.wavefront
    import tracer.jit
    from tracer.kernel_cache import KernelCache

    kernels = [k for k in vars(tracer.integrator.wavefront).values()
               if isinstance(k, tracer.jit.Kernel) and k._opts.get("inline") != "always"]
    assert kernels
    assert all(type(k.dispatcher._cache) is KernelCache for k in kernels)


def test_a_process_that_loaded_kernels_without_refresh_still_compiles_new_ones(ball, tmp_path):
    """Render (every kernel from the cache, numba's registries never installed), then compile a kernel of a new
    signature and a fresh non-cached function using numpy and math: the compiler installs what it needs itself."""
    code = (
        "import sys, math, numpy as np, numba\n"
        "from usd_io.reader import load_stage\n"
        "from tracer import RenderSettings, render\n"
        "scene, info = load_stage(sys.argv[1], width=16)\n"
        "a = render(scene, RenderSettings(width=info.width, height=info.height, progress=False)).rgba\n"
        "import numba.core.cpu as cpu\n"
        "@numba.njit\n"
        "def f(x):\n"
        "    return np.sqrt(x).sum() + math.hypot(3.0, 4.0) + np.random.random() * 0\n"
        "assert f(np.full(4, 4.0, np.float32)) == 13.0\n"
        "from tracer.vec import dot\n"
        "assert dot((1.0, 2.0, 3.0), (1.0, 1.0, 1.0)) == 6.0\n"
        "b = render(scene, RenderSettings(width=info.width, height=info.height, progress=False)).rgba\n"
        "assert np.array_equal(a, b)\n"
        "print('ok')\n")
    r = _python(code, ball)
    assert r.returncode == 0 and r.stdout.strip().endswith("ok"), r.stderr[-3000:]


def test_png_write_errors_name_the_file(tmp_path):
    from tracer import write_image

    with pytest.raises(ValueError, match="does not exist"):
        write_image(tmp_path / "no" / "x.png", np.zeros((2, 2, 4), np.float32))
    (tmp_path / "d.png").mkdir()
    with pytest.raises(ValueError, match="d.png: cannot write"):
        write_image(tmp_path / "d.png", np.zeros((2, 2, 4), np.float32))
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".whitted-")]


def test_fast_png_compression_keeps_every_pixel(tmp_path):
    """PNGs are written at zlib's fastest level without row filters (tracer.film): still lossless. The 8-bit
    values read back (by OpenImageIO and, independently, by zlib + the PNG layout) are the sRGB encoding of the
    pixels, by the standard's closed form, to the code value (an opaque render: OpenImageIO un-premultiplies
    colours where alpha < 1)."""
    import struct
    import zlib

    from tracer import write_image

    rng = np.random.default_rng(1)
    h, w = 90, 160
    rgba = np.concatenate([rng.random((h, w, 3)) ** 2.2, np.ones((h, w, 1))], -1).astype(np.float32)  # opaque
    rgba[10:40, 20:90, :3] = 0.18  # flat areas (what compression works on) next to noise
    path = tmp_path / "x.png"
    write_image(path, rgba)
    c = rgba[..., :3].astype(np.float64)
    srgb = np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)
    want = np.round(np.concatenate([srgb, rgba[..., 3:]], -1) * 255)
    raw = path.read_bytes()
    chunks, at = {}, 8
    while at < len(raw):
        n, kind = struct.unpack(">I4s", raw[at:at + 8])
        chunks.setdefault(kind, b"")
        chunks[kind] += raw[at + 8:at + 8 + n]
        at += 12 + n
    assert struct.unpack(">IIBB", chunks[b"IHDR"][:10]) == (w, h, 8, 6)  # 8-bit RGBA
    rows = np.frombuffer(zlib.decompress(chunks[b"IDAT"]), np.uint8).reshape(h, 1 + 4 * w)
    assert (rows[:, 0] == 0).all()  # no row filter: the bytes are the pixels
    got = rows[:, 1:].reshape(h, w, 4).astype(np.float64)
    assert np.abs(got - want).max() <= 1 and (got[..., 3] == want[..., 3]).all()

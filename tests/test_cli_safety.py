"""The command line facing stages it did not write and inputs it cannot honour (issue #30): RenderProduct paths
stay inside the output directory, impossible image sizes are refused before anything is allocated, RGB-only
formats get RGB, ``--purposes`` takes one value. Every refusal is one ``whitted: error:`` line and exit 2, and
leaves no file behind. Stages are built here (pxr); nothing is downloaded."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom, UsdLux, UsdRender

from tracer import read_image

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def whitted(*args, cwd=None):
    cmd = [sys.executable, "-c", "from usd_io.cli import run; run()", *map(str, args)]  # as the whitted script
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run(cmd, capture_output=True, text=True, cwd=cwd or ROOT, env=env, timeout=300)


def one_line_error(res, *needles):
    assert res.returncode == 2, (res.returncode, res.stderr)
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("whitted: error:"), res.stderr
    for n in needles:
        assert n in lines[0], lines[0]


def ball_stage(path, products=()):
    """A lit ball seen by a camera; with ``products``, RenderSettings (16 × 16) with one RenderProduct per name."""
    s = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(s, "Z")
    cam = UsdGeom.Camera.Define(s, "/Cam")
    cam.CreateHorizontalApertureAttr(4.0)
    cam.CreateVerticalApertureAttr(4.0)
    cam.CreateFocalLengthAttr(5.0)
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 8))
    UsdGeom.Sphere.Define(s, "/Ball")
    UsdLux.DistantLight.Define(s, "/Sun").CreateIntensityAttr(1.0)
    if products:
        rs = UsdRender.Settings.Define(s, "/Render/Settings")
        rs.CreateResolutionAttr(Gf.Vec2i(16, 16))
        rs.CreateCameraRel().SetTargets(["/Cam"])
        targets = []
        for i, name in enumerate(products):
            p = UsdRender.Product.Define(s, f"/Render/P{i}")
            p.CreateProductNameAttr(name)
            targets.append(p.GetPath())
        rs.CreateProductsRel().SetTargets(targets)
        s.SetMetadata("renderSettingsPrimPath", "/Render/Settings")
    s.GetRootLayer().Save()
    return str(path)


# ---------------------------------------------------------------------------------------------- product paths
@pytest.fixture
def work(tmp_path):
    """tmp/work (the current directory of the render, two levels down) and tmp/outside, with a file there."""
    w = tmp_path / "a" / "work"
    w.mkdir(parents=True)
    (tmp_path / "outside").mkdir()
    (tmp_path / "outside" / "keep.png").write_bytes(b"not an image")
    return w


@pytest.mark.parametrize("kind", ["dotdot", "absolute", "symlink", "overwrite"])
def test_a_product_name_that_leaves_the_output_directory_is_refused(work, tmp_path, kind):
    outside = tmp_path / "outside"
    if kind == "symlink":
        os.symlink(outside, work / "link")
    name = {"dotdot": "../../outside/x.png", "absolute": str(outside / "x.png"), "symlink": "link/x.png",
            "overwrite": str(outside / "keep.png")}[kind]
    stage = ball_stage(work / "s.usda", products=(name,))
    res = whitted("render", stage, "--quiet", cwd=work)
    one_line_error(res, "productName", "--allow-product-paths")
    assert sorted(os.listdir(outside)) == ["keep.png"]
    assert (outside / "keep.png").read_bytes() == b"not an image"
    assert not [f for f in os.listdir(work) if f.endswith(".png")]


def test_a_later_product_that_leaves_stops_the_stage_before_anything_renders(work, tmp_path):
    stage = ball_stage(work / "s.usda", products=("first.png", "../../outside/second.png"))
    one_line_error(whitted("render", stage, "--quiet", cwd=work), "second.png")
    assert not (work / "first.png").exists() and not (tmp_path / "outside" / "second.png").exists()


def test_products_inside_the_output_directory_are_written(work, tmp_path):
    (work / "renders").mkdir()
    stage = ball_stage(work / "s.usda", products=("renders/in.png",))
    res = whitted("render", stage, "--quiet", cwd=work)
    assert res.returncode == 0, res.stderr
    assert read_image(str(work / "renders" / "in.png")).shape[:2] == (16, 16)
    out = tmp_path / "elsewhere"  # --output-dir: relative names land there, the same rule applies
    out.mkdir()
    assert whitted("render", stage, "--quiet", "--output-dir", out, cwd=work).returncode == 2  # no renders/ there
    (out / "renders").mkdir()
    res = whitted("render", stage, "--quiet", "--output-dir", out, cwd=work)
    assert res.returncode == 0 and (out / "renders" / "in.png").exists(), res.stderr
    bad = ball_stage(work / "bad.usda", products=("../in.png",))
    one_line_error(whitted("render", bad, "--quiet", "--output-dir", out, cwd=work), "--output-dir")


def test_allow_product_paths_writes_where_the_stage_says(work, tmp_path):
    stage = ball_stage(work / "s.usda", products=("../../outside/x.png",))
    res = whitted("render", stage, "--quiet", "--allow-product-paths", cwd=work)
    assert res.returncode == 0, res.stderr
    assert read_image(str(tmp_path / "outside" / "x.png")).shape[:2] == (16, 16)


def test_product_flags_need_products(work):
    stage = ball_stage(work / "s.usda")
    one_line_error(whitted("render", stage, "-o", work / "o.png", "--allow-product-paths", cwd=work), "-o")
    one_line_error(whitted("render", stage, "--output-dir", work / "nope", "--quiet", cwd=work), "nope")


# ---------------------------------------------------------------------------------------------- small defects
def test_purposes_before_the_scene_leave_the_scene_alone(tmp_path):
    """`--purposes render SCENE` rendered nothing: the flag took several values and swallowed SCENE."""
    stage = ball_stage(tmp_path / "s.usda")
    out = tmp_path / "p.png"
    res = whitted("render", "--purposes", "default,render", stage, "-o", out, "--width", 16, "--quiet")
    assert res.returncode == 0 and out.exists(), res.stderr
    helptext = whitted("render", "--help").stdout
    assert "--purposes P[,P...]" in helptext and "space" not in helptext.split("--purposes", 1)[1][:200]


def test_hdr_output_is_written_as_rgb(tmp_path):
    """`-o h.hdr` is offered by the error message; Radiance HDR has no alpha, so the colour is written (OIIO)."""
    import OpenImageIO as oiio

    stage = ball_stage(tmp_path / "s.usda")
    for ext in (".hdr", ".jpg"):
        out = tmp_path / f"h{ext}"
        res = whitted("render", stage, "-o", out, "--width", 16, "--quiet")
        assert res.returncode == 0, res.stderr
        spec = oiio.ImageInput.open(str(out)).spec()
        assert (spec.width, spec.nchannels) == (16, 3)
    hdr = read_image(str(tmp_path / "h.hdr"))
    exr = tmp_path / "h.exr"
    assert whitted("render", stage, "-o", exr, "--width", 16, "--quiet").returncode == 0
    np.testing.assert_allclose(hdr, read_image(str(exr))[..., :3], rtol=0.02, atol=1e-3)  # RGBE vs half


def test_readme_names_every_top_level_flag():
    readme = open(os.path.join(ROOT, "README.md")).read()
    assert "whitted --version" in readme
    res = whitted("--version")
    assert res.returncode == 0 and res.stdout.startswith("whitted ")


# ---------------------------------------------------------------------------------------------- sizes
def test_an_impossible_size_is_refused_before_anything_is_allocated(tmp_path):
    """`--width 100000 --height 100000` gave numpy's `_ArrayMemoryError: 149 GiB` traceback and a libpng error."""
    stage = ball_stage(tmp_path / "s.usda")
    out = tmp_path / "big.png"
    res = whitted("render", stage, "-o", out, "--width", 100000, "--height", 100000, "--quiet")
    one_line_error(res, "100000x100000", "GiB", "available")
    assert "Traceback" not in res.stderr
    assert os.listdir(tmp_path) == ["s.usda"]  # no image, no temporary file
    res = whitted("explain", stage, "--pixel", 0, 0, "--width", 100000, "--height", 100000, "--png",
                  tmp_path / "e.png")  # explain's picture: the same one line
    one_line_error(res, "100000x100000")
    assert os.listdir(tmp_path) == ["s.usda"]


def test_the_api_raises_a_clear_error_for_an_impossible_size():
    import tracer
    from tracer.integrator.tiles import check_memory, memory_estimate

    b = tracer.SceneBuilder()
    b.add_mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32), np.array([[0, 1, 2]]))
    b.camera = tracer.Camera.look_at((0, 0, 5), (0, 0, 0), up=(0, 1, 0))
    with pytest.raises(tracer.RenderTooLarge, match="100000x100000"):
        tracer.render(b.build(), tracer.RenderSettings(width=100000, height=100000))
    small = tracer.RenderSettings(width=64, height=48)
    check_memory(small, available=10**15)
    with pytest.raises(ValueError, match="more than the 1000 bytes"):
        check_memory(small, available=1000)
    assert sum(memory_estimate(small).values()) > 0


def test_the_estimate_counts_what_a_render_allocates_for_its_image_and_aovs():
    """Independent of the estimate's arithmetic: the film and AOV arrays a real render returns."""
    import tracer
    from tracer.integrator.tiles import memory_estimate

    b = tracer.SceneBuilder()
    b.add_mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32), np.array([[0, 1, 2]]))
    b.camera = tracer.Camera.look_at((0, 0, 5), (0, 0, 0), up=(0, 1, 0))
    s = tracer.RenderSettings(width=40, height=30, samples=1, aovs=("depth", "normal", "objectid", "direct"))
    image = tracer.render(b.build(), s)
    est = memory_estimate(s)
    assert est["image"] == image.rgba.nbytes
    assert est["aovs"] == sum(a.nbytes for a in image.aovs.values())


def test_info_prints_the_memory_estimate(tmp_path):
    stage = ball_stage(tmp_path / "s.usda", products=("x.png",))
    res = whitted("info", stage)
    assert res.returncode == 0, res.stderr
    line = [ln for ln in res.stdout.splitlines() if ln.startswith("memory:")]
    assert len(line) == 1 and "16x16" in line[0] and "available" in line[0], res.stdout


# ---------------------------------------------------------------------------------------------- faults
def _limited(limit):
    """A child's preexec: files larger than ``limit`` bytes cannot be written (EFBIG: Python ignores SIGXFSZ), the
    way a full disk refuses the rest of a file."""
    import resource

    def pre():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    return pre


@pytest.mark.parametrize("ext", [".png", ".exr", ".tif"])
def test_a_write_that_runs_out_of_room_is_one_line_and_no_file(tmp_path, ext):
    """Before: the streamed PNG was cut at the limit and renamed into place with exit 0."""
    stage = ball_stage(tmp_path / "s.usda")
    assert whitted("render", stage, "-o", tmp_path / f"warm{ext}", "--width", 256, "--quiet").returncode == 0
    os.unlink(tmp_path / f"warm{ext}")
    out = tmp_path / f"full{ext}"
    cmd = [sys.executable, "-c", "from usd_io.cli import run; run()", "render", str(stage), "-o", str(out),
           "--width", "256", "--quiet"]
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    res = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300, preexec_fn=_limited(1000))
    one_line_error(res, str(out), "write")
    assert sorted(os.listdir(tmp_path)) == ["s.usda"]


def test_a_full_disk_is_refused_before_writing(tmp_path, monkeypatch):
    """The free space is checked against the uncompressed image (statvfs), for every format (libjpeg would exit the
    process on a failed write, OpenImageIO's PNG writer would not notice)."""
    import tracer
    from tracer import film

    real = os.statvfs

    class Full:
        def __init__(self, st):
            self.f_frsize, self.f_bavail = st.f_frsize, 1

    monkeypatch.setattr(film.os, "statvfs", lambda p: Full(real(p)))
    for ext in (".jpg", ".png", ".exr"):
        with pytest.raises(ValueError, match="not enough space"):
            tracer.write_image(str(tmp_path / f"x{ext}"), np.ones((64, 64, 4), np.float32))
    assert os.listdir(tmp_path) == []


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only directories")
def test_a_read_only_output_directory_is_one_line(tmp_path):
    stage = ball_stage(tmp_path / "s.usda")
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        one_line_error(whitted("render", stage, "-o", ro / "x.png", "--width", 16, "--quiet"), "cannot write")
        assert os.listdir(ro) == []
    finally:
        ro.chmod(0o755)


@pytest.mark.parametrize("wait", [0.0, 0.5])
def test_sigint_removes_the_temporary_image(tmp_path, wait):
    """SIGINT while the picture is being written (the streamed PNG's temporary file exists from the start): exit 130,
    one line, nothing left in the output directory. Before: the temporary file stayed when the interrupt came
    between its creation and the render, and libpng added a line about the aborted file."""
    import glob
    import signal
    import time

    stage = ball_stage(tmp_path / "s.usda")
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    assert whitted("render", stage, "-o", out_dir / "warm.png", "--width", 16, "--quiet").returncode == 0
    os.unlink(out_dir / "warm.png")
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    # SIGINT as a terminal sends it: a test run in the background of a non-interactive shell (as CI may be)
    # inherits SIGINT ignored, and Python then installs no KeyboardInterrupt handler
    p = subprocess.Popen([sys.executable, "-c", "from usd_io.cli import run; run()", "render", str(stage), "-o",
                          str(out_dir / "big.png"), "--width", "2000", "--aa", "4", "--quiet"], env=env,
                         stderr=subprocess.PIPE, text=True,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    while not glob.glob(str(out_dir / ".whitted-*")) and p.poll() is None:
        time.sleep(0.005)
    assert p.poll() is None, "the render ended before it could be interrupted"
    time.sleep(wait)
    p.send_signal(signal.SIGINT)
    err = p.communicate(timeout=300)[1]
    assert p.returncode == 130, err
    assert [ln for ln in err.splitlines() if ln.strip()] == ["whitted: interrupted"], err
    assert os.listdir(out_dir) == []

"""Render farm on Dask (tracer.farm, usd_io.farm, ``whitted render --scheduler``): the same files as a local render,
bit for bit, for frames and for a frame split into tiles; a worker killed mid-run; scene errors reported once."""

from __future__ import annotations

import os
import signal
import sys
import time

import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom, UsdLux

from tracer import read_image
from tracer import render

distributed = pytest.importorskip("distributed", reason="the farm needs dask[distributed] (test extra)")

FRAMES = "1:8"


def _stage(path, frames=8):
    s = Usd.Stage.CreateNew(str(path))
    ball = UsdGeom.Sphere.Define(s, "/Ball")
    op = ball.AddTranslateOp()
    op.Set(Gf.Vec3d(-2, 0, 0), 1.0)
    op.Set(Gf.Vec3d(2, 0, 0), float(frames))
    return _set(s)


def _set(s):
    """A camera looking down at a floor, a sphere light; the stage saved, its path returned."""
    _dress(s)
    s.GetRootLayer().Save()
    return s.GetRootLayer().identifier


def _dress(s):
    """The camera, floor and light every stage here has."""
    UsdGeom.SetStageUpAxis(s, "Z")
    cam = UsdGeom.Camera.Define(s, "/Cam")
    cam.CreateHorizontalApertureAttr(4.0)
    cam.CreateVerticalApertureAttr(3.0)
    cam.CreateFocalLengthAttr(5.0)
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 8))
    floor = UsdGeom.Cube.Define(s, "/Floor")
    floor.AddTranslateOp().Set(Gf.Vec3d(0, 0, -2))
    floor.AddScaleOp().Set(Gf.Vec3f(6, 6, 0.5))
    light = UsdLux.SphereLight.Define(s, "/Light")
    light.CreateIntensityAttr(300.0)
    light.AddTranslateOp().Set(Gf.Vec3d(2, 2, 6))
    return cam


@pytest.fixture(scope="module")
def anim(tmp_path_factory):
    return _stage(tmp_path_factory.mktemp("farm") / "anim.usda")


@pytest.fixture(scope="module")
def client():
    from dask.distributed import Client, LocalCluster

    import logging

    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address="127.0.0.1:0", silence_logs=logging.ERROR)
    c = Client(cluster)
    yield c
    c.close()
    cluster.close()


def _cli(*args):
    from usd_io.cli import main

    return main([str(a) for a in args])


def test_frames_on_two_workers_give_the_local_files(anim, tmp_path, capsys):
    local, farm, shared = tmp_path / "local", tmp_path / "farm", tmp_path / "shared"
    for d in (local, farm, shared):
        d.mkdir()
    common = ("--frames", FRAMES, "--width", 64, "--spp", 2, "--aov", "depth", "--quiet")
    assert _cli("render", anim, "-o", local / "f.####.png", *common) == 0
    assert _cli("render", anim, "-o", farm / "f.####.png", *common, "--scheduler", "local:2") == 0
    assert _cli("render", anim, "-o", shared / "f.####.png", *common, "--scheduler", "local:2",
                "--worker-writes") == 0  # the workers write to the (here: local, i.e. shared) directory
    names = sorted(os.listdir(local))
    assert len(names) == 16 and names == sorted(os.listdir(farm)) == sorted(os.listdir(shared))  # 8 + 8 AOVs
    for other in (farm, shared):
        for n in names:
            if n.endswith(".png"):
                assert (local / n).read_bytes() == (other / n).read_bytes(), other / n
            else:  # OpenEXR stamps the write time (capDate) in the header: compare the pixels
                assert np.array_equal(read_image(local / n), read_image(other / n)), other / n
    # The ball moves: the frames differ from each other (the farm did not render one frame eight times).
    assert (farm / "f.0001.png").read_bytes() != (farm / "f.0008.png").read_bytes()


def test_a_frame_split_into_four_tiles_equals_the_single_process_frame(anim, client):
    from tracer.farm import frame_tiles, render_tiled
    from usd_io.farm import UsdSource

    settings = dict(samples=2, max_depth=4, aovs=("depth", "objectid", "normal", "reflection", "raydepth"))
    source = UsdSource(path=anim, width=200, height=150, settings=settings)
    scene, st = source.load(3.0)
    assert len(frame_tiles(st, 128)) == 4
    tiled = render_tiled(client, source, 3.0, tile_size=128)
    whole = render(scene, st)
    assert np.array_equal(tiled.rgba, whole.rgba)
    for name in settings["aovs"]:
        assert np.array_equal(tiled.aovs[name], whole.aovs[name]), name
    assert tiled.rgba[..., :3].max() > 0.05  # a lit picture, not an empty one


def test_shipped_assets_render_the_same_frame(anim, client, tmp_path):
    """--ship-assets: workers read a .usdz the client built (here the original path is hidden from them)."""
    from tracer.farm import render_frames
    from usd_io.farm import UsdSource, package_assets

    source = UsdSource(path=anim, width=48, settings=dict(samples=1))
    expected = render(*source.load(2.0))
    hidden = UsdSource(path=str(tmp_path / "not-on-the-workers.usda"), width=48, settings=dict(samples=1))
    (res,) = list(render_frames(client, hidden, [2.0], assets=package_assets(anim)))
    assert res.error is None
    assert np.array_equal(res.image.rgba, expected.rgba)


def test_scene_errors_fail_each_frame_once_with_their_message(anim, tmp_path, capsys):
    code = _cli("render", anim, "-o", tmp_path / "f.####.png", "--frames", "1:3", "--width", 32,
                "--camera", "/NoSuchCamera", "--scheduler", "local:1", "--quiet")
    err = capsys.readouterr().err
    assert code == 2
    lines = [ln for ln in err.splitlines() if ln.startswith("whitted: error: frame")]
    assert len(lines) == 3 and all("/NoSuchCamera" in ln for ln in lines), err
    assert "Traceback" not in err
    assert not list(tmp_path.glob("f.*"))


@pytest.mark.parametrize("address", ["foo", "local:0", "tls://127.0.0.1:1"])
def test_bad_scheduler_is_one_line_exit_2(anim, tmp_path, capsys, address):
    assert _cli("render", anim, "-o", tmp_path / "x.png", "--scheduler", address) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("whitted: error: --scheduler"), err


def test_a_worker_killed_mid_run_still_completes_every_frame(tmp_path):
    """SIGKILL one of two workers while it renders: Dask reschedules its task on the other (restarted) worker."""
    from dask.distributed import Client, LocalCluster

    import logging

    from tracer.farm import render_frames
    from usd_io.farm import UsdSource

    path = _stage(tmp_path / "slow.usda")
    source = UsdSource(path=path, width=240, settings=dict(samples=3))
    frames = [float(f) for f in range(1, 9)]
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address="127.0.0.1:0", silence_logs=logging.CRITICAL)
    client = Client(cluster)
    try:
        pids = client.run(os.getpid)
        killed = []

        def kill_a_busy_worker(result):
            if killed:
                return
            deadline = time.monotonic() + 120  # generous: a loaded machine may be slow to start the next task
            while time.monotonic() < deadline:
                busy = [w for w, keys in client.processing().items() if keys and w in pids]
                if busy:
                    os.kill(pids[busy[0]], signal.SIGKILL)
                    killed.append(busy[0])
                    return
                time.sleep(0.01)

        results = {r.frame: r for r in render_frames(client, source, frames, on_result=kill_a_busy_worker)}
        assert killed, "no worker was busy after the first frame: the test did not exercise a failure"
        assert sorted(results) == frames
        assert all(r.error is None for r in results.values()), [r.error for r in results.values()]
        for f in (frames[1], frames[-1]):
            assert np.array_equal(results[f].image.rgba, render(*source.load(f)).rgba)
    finally:
        client.close()
        cluster.close()


def _switch_stage(path):
    """A stage whose picture depends on a variant (the ball left or right) and on the proxy purpose (a cube)."""
    s = Usd.Stage.CreateNew(str(path))
    sw = UsdGeom.Xform.Define(s, "/Sw").GetPrim()
    looks = sw.GetVariantSets().AddVariantSet("look")
    for name, x in (("left", -2.0), ("right", 2.0)):
        looks.AddVariant(name)
        looks.SetVariantSelection(name)
        with looks.GetVariantEditContext():
            UsdGeom.Sphere.Define(s, "/Sw/Ball").AddTranslateOp().Set(Gf.Vec3d(x, 0, 0))
    looks.SetVariantSelection("left")
    proxy = UsdGeom.Cube.Define(s, "/Proxy")
    proxy.CreatePurposeAttr(UsdGeom.Tokens.proxy)
    proxy.AddTranslateOp().Set(Gf.Vec3d(0, 2, 0))
    return _set(s)


def test_the_farm_takes_every_flag_a_local_render_takes(tmp_path, client):
    """Issue #22's drift: the farm once ignored --variant, read --purposes render,proxy as one unknown purpose,
    and --worker-writes skipped --exposure and --max-depth (the raydepth heat map's scale)."""
    stage = _switch_stage(tmp_path / "switch.usda")
    dirs = {k: tmp_path / k for k in ("local", "default", "farm", "shared")}
    for d in dirs.values():
        d.mkdir()
    flags = ("--frames", "1:2", "--width", 48, "--aa", 1, "--variant", "/Sw:look=right", "--purposes",
             "default,render,proxy", "--exposure", 1, "--max-depth", 2, "--aov", "raydepth", "--shading",
             "classic", "--quiet")
    assert _cli("render", stage, "-o", dirs["local"] / "f.####.png", *flags) == 0
    assert _cli("render", stage, "-o", dirs["default"] / "f.####.png", "--frames", "1:2", "--width", 48,
                "--aa", 1, "--quiet") == 0
    farm = client.scheduler.address  # the running test cluster
    assert _cli("render", stage, "-o", dirs["farm"] / "f.####.png", *flags, "--scheduler", farm) == 0
    assert _cli("render", stage, "-o", dirs["shared"] / "f.####.png", *flags, "--scheduler", farm,
                "--worker-writes") == 0
    local = read_image(dirs["local"] / "f.0001.png")
    assert not np.array_equal(local, read_image(dirs["default"] / "f.0001.png"))  # the flags change the picture
    names = sorted(os.listdir(dirs["local"]))
    assert names == ["f.0001.png", "f.0001.raydepth.exr", "f.0001.raydepth.png",
                     "f.0002.png", "f.0002.raydepth.exr", "f.0002.raydepth.png"]
    for other in (dirs["farm"], dirs["shared"]):
        assert sorted(os.listdir(other)) == names
        for n in names:
            assert np.array_equal(read_image(dirs["local"] / n), read_image(other / n)), other / n


# ------------------------------------------------------------------------------------ the worker's prepared scenes
def _text(ball=None, ball_moves=False, camera_moves=False) -> str:
    """A stage's .usda text: the ball still at x = ``ball``, or moving over frames 1..8, or still with the camera
    moving (a fly-through of a still set)."""
    s = Usd.Stage.CreateInMemory()
    cam = _dress(s)
    op = UsdGeom.Sphere.Define(s, "/Ball").AddTranslateOp()
    if ball_moves:
        op.Set(Gf.Vec3d(-2, 0, 0), 1.0)
        op.Set(Gf.Vec3d(2, 0, 0), 8.0)
    else:
        op.Set(Gf.Vec3d(ball, 0, 0))
    if camera_moves:
        pan = cam.AddTranslateOp(opSuffix="pan")
        pan.Set(Gf.Vec3d(0, 0, 0), 1.0)
        pan.Set(Gf.Vec3d(1.5, 0.5, 0), 8.0)
    return s.GetRootLayer().ExportToString()


def _reference(tmp_path, text, frame):
    """The local render of a stage with this text at ``frame``, read from a file of its own (so nothing a worker
    cache holds can be what it shows)."""
    from usd_io import load_stage

    path = tmp_path / f"reference-{abs(hash((text, frame)))}.usda"
    path.write_text(text)
    scene, info = load_stage(str(path), time=frame, width=48)
    return render(scene, _SETTINGS.with_(width=info.width, height=info.height)).rgba


def _worker_frame(source, frame):
    """One frame through the worker's task, in this process (the worker-side cache is this process's)."""
    from tracer.farm import render_frame_task

    image = render_frame_task(source, frame)
    return image.rgba, image.stats["farm"]["reused"]


from tracer import RenderSettings  # noqa: E402

_SETTINGS = RenderSettings(samples=1, threads=1)


@pytest.fixture
def fresh_worker():
    from tracer.farm import forget

    forget()
    yield
    forget()


def test_a_worker_reads_a_changed_stage_again(tmp_path, fresh_worker):
    """The stage file is rewritten between two frames (same size: only its time stamp and contents differ): the
    second frame shows the new file, not the scene prepared from the old one."""
    from usd_io.farm import UsdSource

    before, after = _text(ball=-2.0), _text(ball=-1.0)
    assert len(before) == len(after) and before != after
    path = tmp_path / "shot.usda"
    path.write_text(before)
    source = UsdSource(path=str(path), width=48, settings=_SETTINGS)
    first, reused = _worker_frame(source, 1.0)
    assert reused is False and np.array_equal(first, _reference(tmp_path, before, 1.0))
    again, reused = _worker_frame(source, 2.0)  # a still stage: frame 2 is frame 1's prepared scene
    assert reused == "scene" and np.array_equal(again, first)
    time.sleep(0.05)
    path.write_text(after)
    changed, reused = _worker_frame(source, 3.0)
    expected = _reference(tmp_path, after, 3.0)
    assert not np.array_equal(expected, first)  # the edit shows in the picture
    assert reused is False and np.array_equal(changed, expected)


def test_a_worker_renders_each_frame_of_an_animated_stage(tmp_path, fresh_worker):
    """Time samples: every frame is read at its own time (the ball moves); frames the cache has seen are reused."""
    from usd_io.farm import UsdSource

    text = _text(ball_moves=True)
    path = tmp_path / "anim.usda"
    path.write_text(text)
    source = UsdSource(path=str(path), width=48, settings=_SETTINGS)
    images = {}
    for f in (1.0, 4.0, 8.0):
        images[f], reused = _worker_frame(source, f)
        assert reused is False, f  # the geometry moved: nothing to share
        assert np.array_equal(images[f], _reference(tmp_path, text, f)), f
    assert not np.array_equal(images[1.0], images[8.0])
    again, reused = _worker_frame(source, 8.0)  # the last frame is still prepared
    assert reused == "scene" and np.array_equal(again, images[8.0])


def test_a_moving_camera_shares_the_embree_scene_and_renders_each_view(tmp_path, fresh_worker):
    """Only the camera is animated: each frame is read, its Embree scene is the previous frame's, and each frame
    equals its local render."""
    from usd_io.farm import UsdSource

    text = _text(ball=-2.0, camera_moves=True)
    path = tmp_path / "fly.usda"
    path.write_text(text)
    source = UsdSource(path=str(path), width=48, settings=_SETTINGS)
    first, reused = _worker_frame(source, 1.0)
    assert reused is False and np.array_equal(first, _reference(tmp_path, text, 1.0))
    last, reused = _worker_frame(source, 8.0)
    assert reused == "accel" and np.array_equal(last, _reference(tmp_path, text, 8.0))
    assert not np.array_equal(first, last)


def test_workers_keep_a_still_stage_prepared_across_frames(tmp_path, client):
    """On the farm: after a worker's first frame of a still stage, its frames reuse the prepared scene."""
    from tracer.farm import render_frames
    from usd_io.farm import UsdSource

    path = tmp_path / "still.usda"
    path.write_text(_text(ball=-2.0))
    source = UsdSource(path=str(path), width=48, settings=_SETTINGS)
    expected = _reference(tmp_path, _text(ball=-2.0), 1.0)
    results = list(render_frames(client, source, [float(f) for f in range(1, 7)]))
    assert all(r.error is None and np.array_equal(r.image.rgba, expected) for r in results)
    reused = [r.image.stats["farm"]["reused"] for r in results]
    assert reused.count(False) <= 2 and reused.count("scene") >= 4, reused  # one load per worker at most


def test_a_stage_animated_by_value_clips_is_read_per_frame(tmp_path, fresh_worker):
    """The stage's own layer has no time samples; its ball moves through a value clip: every frame its own."""
    from pxr import Sdf

    from usd_io.farm import UsdSource

    clip = Usd.Stage.CreateNew(str(tmp_path / "clip.usda"))
    op = UsdGeom.Sphere.Define(clip, "/Ball").AddTranslateOp()
    op.Set(Gf.Vec3d(-2, 0, 0), 1.0)
    op.Set(Gf.Vec3d(2, 0, 0), 8.0)
    clip.GetRootLayer().Save()
    s = Usd.Stage.CreateInMemory()
    _dress(s)
    ball = UsdGeom.Sphere.Define(s, "/Ball")
    ball.AddTranslateOp()
    clips = Usd.ClipsAPI(ball.GetPrim())
    clips.SetClipAssetPaths([Sdf.AssetPath("./clip.usda")])
    clips.SetClipPrimPath("/Ball")
    clips.SetClipActive([(1.0, 0)])
    clips.SetClipTimes([(1.0, 1.0), (8.0, 8.0)])
    text = s.GetRootLayer().ExportToString()
    path = tmp_path / "clipped.usda"
    path.write_text(text)
    source = UsdSource(path=str(path), width=48, settings=_SETTINGS)
    first, _ = _worker_frame(source, 1.0)
    last, reused = _worker_frame(source, 8.0)
    assert reused is False and not np.array_equal(first, last)
    assert np.array_equal(first, _reference(tmp_path, text, 1.0))
    assert np.array_equal(last, _reference(tmp_path, text, 8.0))


def test_a_tiled_frame_is_denoised_whole_on_the_client(anim, client):
    """--denoise on a frame split into tiles: the tiles bring the noisy pixels and the denoiser's guides, and the
    client denoises the assembled frame, which equals a local denoised render; denoising tile by tile would not
    (the filter looks across the tile borders)."""
    from tracer import denoise as dn
    from tracer.farm import frame_tiles, render_tiled
    from usd_io.farm import UsdSource

    settings = dict(samples=1, max_depth=2, light_samples=4, denoise=True, tile_size=32)
    source = UsdSource(path=anim, width=128, height=96, settings=settings)
    scene, st = source.load(3.0)
    tiles = frame_tiles(st, 64)
    assert len(tiles) == 4
    tiled = render_tiled(client, source, 3.0, tile_size=64)
    whole = render(scene, st)
    assert "denoise" in tiled.stats and "denoise" in whole.stats
    np.testing.assert_allclose(tiled.rgba, whole.rgba, atol=1e-5)
    assert not tiled.aovs  # the guides were for the filter only
    noisy = render(scene, st.with_(denoise=False, aovs=dn.GUIDE_AOVS))
    per_tile = noisy.rgba.copy()
    for x0, y0, x1, y1 in tiles:
        win = (slice(y0, y1), slice(x0, x1))
        per_tile[win] = dn.denoise(noisy.rgba[win], noisy.aovs["denoising_albedo"][win],
                                   noisy.aovs["denoising_normal"][win])
    seam = np.abs(per_tile - whole.rgba)[60:68, :, :3].max()  # rows around the horizontal tile border
    assert seam > 1e-3, seam

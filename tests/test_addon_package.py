"""The extension zips: `python -m addon.build` runs Blender's own builder (blender_ext.py build --split-platforms)
and writes one zip per platform (Linux x64, Windows x64, macOS arm64), each with that platform's embreex, numba
and llvmlite wheels (pinned to versions that fit Blender 5.0's numpy) and a manifest saying so; the Linux zip
installs through Blender's own extension machinery into a temporary user directory (BLENDER_USER_RESOURCES),
registers, renders with its bundled tracer and wheels, and unregisters cleanly. Blender reads
BLENDER_USER_RESOURCES at start-up, so this runs in a fresh process.

The Linux zip is built once per module from the wheel cache (.cache/wheels, filled by pip on the first run). What
the builder puts in every platform's zip (the macOS one included) is checked on a build from a temporary cache of
stand-in wheels under the real file names, and the wheel fetching against a temporary cache with pip replaced, so
those tests need no network."""

from __future__ import annotations

import importlib.metadata
import io
import json
import os
import subprocess
import sys
import tomllib
import zipfile

import pytest
from packaging.requirements import Requirement

from addon import build

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGES = {"embreex", "numba", "llvmlite"}
#: Blender platform -> how its wheels' platform tag reads.
PLATFORM_TAG = {"linux-x64": lambda tag: tag.startswith("manylinux") and tag.endswith("_x86_64"),
                "windows-x64": lambda tag: tag == "win_amd64",
                "macos-arm64": lambda tag: tag.startswith("macosx_") and tag.endswith("_arm64")}

SCRIPT = r'''
import json, os, subprocess, sys
import bpy
import numpy
zip_path, png, PROBE = sys.argv[1:4]
bpy.ops.wm.read_factory_settings(use_empty=False)
res = bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
def engines():
    return sorted(c.bl_idname for c in bpy.types.RenderEngine.__subclasses__()
                  if hasattr(c, "bl_idname") and getattr(c, "is_registered", False))
mod = sys.modules["bl_ext.user_default.whitted"]
out = {"install": sorted(res), "engines_after_install": engines(), "addon_file": mod.__file__,
       "tracer_file": mod.export.tracer.__file__,
       "enabled": "bl_ext.user_default.whitted" in bpy.context.preferences.addons.keys()}
site = os.path.join(bpy.utils.user_resource("EXTENSIONS"), ".local", "lib",
                    "python%d.%d" % sys.version_info[:2], "site-packages")
out["site"] = site
out["wheels_installed"] = {name: os.path.isdir(os.path.join(site, name)) for name in ("embreex", "numba", "llvmlite")}
out["dist_infos"] = sorted(n for n in os.listdir(site) if n.endswith(".dist-info")) if os.path.isdir(site) else []
# Blender appends its wheel directory to sys.path, behind this environment's own numba: run the bundled numba and
# llvmlite in a bare interpreter that sees only them and Blender's numpy (the one bpy brought).
probe = subprocess.run(
    [sys.executable, "-S", "-c", PROBE, site, os.path.dirname(os.path.dirname(numpy.__file__))],
    capture_output=True, text=True, timeout=600)
out["probe"] = probe.stdout.strip().splitlines()[-1:] + [probe.stderr[-1500:]]
print("INSTALLED " + json.dumps(out), flush=True)
scene = bpy.context.scene
scene.render.engine = "WHITTED"
scene.render.resolution_percentage = 4
scene.render.filepath = png
scene.render.image_settings.file_format = "PNG"
bpy.ops.render.render(write_still=True)
out["stats"] = mod.engine.WhittedRenderEngine.last_render.stats["rays"]
out["kernels"] = {"compiled_in_child": mod.kernels._state.done, "child_error": mod.kernels._state.error,
                  "in_extension": sorted(os.path.relpath(os.path.join(d, f), os.path.dirname(mod.__file__))
                                         for d, _, fs in os.walk(os.path.dirname(mod.__file__)) for f in fs
                                         if f.endswith((".nbi", ".nbc")))}
bpy.ops.preferences.addon_disable(module="bl_ext.user_default.whitted")
out["engines_after_disable"] = engines()
out["scene_prop_after_disable"] = hasattr(bpy.types.Scene, "whitted")
print("RESULT " + json.dumps(out))
'''
PROBE = r'''
import json, sys
sys.path[:0] = sys.argv[1:3]
import llvmlite, numba, numpy
double = numba.njit("float64(float64)")(lambda x: 2.0 * x)
print(json.dumps({"numba": [numba.__version__, numba.__file__], "llvmlite": [llvmlite.__version__, llvmlite.__file__],
                  "numpy": numpy.__version__, "double": double(1.25)}))
'''


@pytest.fixture(scope="module")
def zip_path(tmp_path_factory):
    return build.build(str(tmp_path_factory.mktemp("dist")), platforms=("linux-x64",))["linux-x64"]


#: The wheels pip downloads for the pins (addon/build.py: WHEELS), by Blender platform: their real file names.
WHEEL_FILES = {
    "linux-x64": ["embreex-4.4.0.post1-cp311-cp311-manylinux_2_27_x86_64.manylinux_2_28_x86_64.whl",
                  "numba-0.68.1-cp311-cp311-manylinux_2_27_x86_64.manylinux_2_28_x86_64.whl",
                  "llvmlite-0.50.0-cp311-cp311-manylinux_2_27_x86_64.manylinux_2_28_x86_64.whl"],
    "windows-x64": ["embreex-4.4.0.post1-cp311-cp311-win_amd64.whl", "numba-0.68.1-cp311-cp311-win_amd64.whl",
                    "llvmlite-0.50.0-cp311-cp311-win_amd64.whl"],
    "macos-arm64": ["embreex-4.4.0.post1-cp311-cp311-macosx_13_0_arm64.whl",
                    "numba-0.68.1-cp311-cp311-macosx_12_0_arm64.whl",
                    "llvmlite-0.50.0-cp311-cp311-macosx_12_0_arm64.whl"],
}


def _effective_manifest(z):
    """The manifest Blender reads from a split zip: ``[build.generated]`` replaces platforms and wheels."""
    manifest = tomllib.loads(z.read("blender_manifest.toml").decode())
    generated = manifest.get("build", {}).get("generated", {})
    return dict(manifest, **{k: generated[k] for k in ("platforms", "wheels") if k in generated}), manifest


def check_zip(path, platform):
    """One platform's zip, as Blender's builder wrote it: the add-on and the tracer, exactly the manifest's wheels
    for that platform (one cp311 wheel per package at its pin), the manifest's fields."""
    with zipfile.ZipFile(path) as z:
        names = set(z.namelist())
        manifest, source = _effective_manifest(z)
        text = z.read("blender_manifest.toml").decode()
        tracer_render = z.read("tracer/render.py")
    assert {"__init__.py", "engine.py", "export.py", "properties.py", "ui.py", "sync.py", "viewport.py",
            "tracer/__init__.py", "tracer/integrator/wavefront.py", "tracer/session.py"} <= names
    assert "build.py" not in names and not any("__pycache__" in n for n in names)
    assert manifest["id"] == "whitted" and manifest["type"] == "add-on"
    assert manifest["schema_version"] == "1.0.0" and manifest["blender_version_min"] == "4.2.0"
    assert manifest["platforms"] == [platform]
    # the manifest lists exactly the wheels the zip carries, each once
    carried = sorted(n for n in names if n.startswith("wheels/"))
    listed = [w.removeprefix("./") for w in manifest["wheels"]]
    assert sorted(listed) == carried and len(set(listed)) == len(listed)
    pins = dict(build.WHEELS)
    got = {}
    for name in carried:
        package, version, python_tag, abi_tag, platform_tag = name.removeprefix("wheels/")[:-4].split("-")
        assert PLATFORM_TAG[platform](platform_tag) and (python_tag, abi_tag) == ("cp311", "cp311"), name
        assert package not in got, f"two {package} wheels for {platform}"
        got[package] = version
    assert got == pins and set(pins) == PACKAGES, platform
    # the source manifest (before the generated table) lists the wheels of every platform built, as the committed
    # manifest does for all of them
    with open(os.path.join(ROOT, "addon", "blender_manifest.toml"), "rb") as f:
        committed = tomllib.load(f)["wheels"]
    assert set(manifest["wheels"]) <= set(source["wheels"]) <= set(committed)
    # one tracer in the repository: the zip's copy is made at build time, byte for byte
    assert tracer_render == open(os.path.join(ROOT, "tracer", "render.py"), "rb").read()
    return manifest, text, carried


def test_linux_zip_contents(zip_path):
    check_zip(zip_path, "linux-x64")


def test_blenders_builder_makes_one_zip_per_platform_with_its_wheels(tmp_path, monkeypatch):
    """What the builder includes for each platform, the macOS one above all (no network: stand-in wheels under the
    real file names): its manifest names macos-arm64 and exactly the three macOS arm64 wheels, and says the
    minimum macOS they need (13.0: embreex publishes only macosx_13_0_arm64)."""
    cache = tmp_path / "wheels"
    cache.mkdir()
    for files in WHEEL_FILES.values():
        for name in files:
            with zipfile.ZipFile(cache / name, "w") as whl:
                whl.writestr("stand-in.txt", name)
    calls = []
    monkeypatch.setattr(build.subprocess, "run", _no_pip(calls, build.subprocess.run))
    zips = build.build(str(tmp_path / "dist"), offline=True, cache=str(cache), kernels=False)
    assert set(zips) == set(WHEEL_FILES) and not [c for c in calls if "pip" in c]
    assert sorted(os.listdir(tmp_path / "dist")) == [f"whitted-0.1.0-{p.replace('-', '_')}.zip" for p in
                                                     sorted(WHEEL_FILES)]
    for platform, path in zips.items():
        manifest, text, carried = check_zip(path, platform)
        assert carried == sorted(f"wheels/{n}" for n in WHEEL_FILES[platform])
    with zipfile.ZipFile(zips["linux-x64"]) as z, open(os.path.join(ROOT, "addon", "blender_manifest.toml"),
                                                         "rb") as f:
        assert _effective_manifest(z)[1]["wheels"] == tomllib.load(f)["wheels"]  # the committed list is current
    _, text, carried = check_zip(zips["macos-arm64"], "macos-arm64")
    assert build.macos_minimum(carried) == "13.0"
    assert "# macOS: 13.0 or newer" in text
    with open(os.path.join(ROOT, "addon", "blender_manifest.toml"), encoding="utf-8") as f:
        assert "# macOS: 13.0 or newer" in f.read()  # (the committed manifest and README say the same)


def _no_pip(calls, real):
    def run(cmd, *a, **k):
        calls.append(" ".join(cmd))
        if "pip" in cmd:
            raise AssertionError("offline build ran pip")
        return real(cmd, *a, **k)
    return run


def test_builder_errors_are_clear(tmp_path, monkeypatch):
    monkeypatch.setenv("BLENDER_EXT_PY", str(tmp_path / "missing.py"))
    with pytest.raises(build.BuildError, match="BLENDER_EXT_PY=.*missing.py is not a file"):
        build.blender_ext_script()
    monkeypatch.delenv("BLENDER_EXT_PY")
    assert build.blender_ext_script().endswith(os.path.join("bl_pkg", "cli", "blender_ext.py"))


def test_extension_installs_registers_renders_and_unregisters(zip_path, tmp_path):
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "blender_user"),
               WHITTED_KERNEL_CACHE=str(tmp_path / "kernel_cache"))  # an empty cache: the zip's kernels or nothing
    png = str(tmp_path / "f12.png")
    proc = subprocess.run([sys.executable, "-c", SCRIPT, zip_path, png, PROBE], env=env, capture_output=True, text=True,
                          timeout=1200, cwd=str(tmp_path))  # a hang guard: kernels compile cold in Blender
    installed = [l for l in proc.stdout.splitlines() if l.startswith("INSTALLED ")]
    assert installed, proc.stdout[-2000:] + proc.stderr[-2000:]
    out = json.loads(installed[-1][len("INSTALLED "):])
    # the wheels first (they are in place before the render): Blender installed this platform's three, and the
    # bundled numba + llvmlite import and compile against Blender's numpy
    assert out["wheels_installed"] == {"embreex": True, "numba": True, "llvmlite": True}
    pins = dict(build.WHEELS)
    for package in ("numba", "llvmlite"):
        assert f"{package}-{pins[package]}.dist-info" in out["dist_infos"]
    assert out["probe"][0].startswith("{"), out["probe"]
    probe = json.loads(out["probe"][0])
    for package in ("numba", "llvmlite"):
        version, file = probe[package]
        assert version == pins[package] and file.startswith(out["site"]), (package, probe)
    assert probe["numpy"] == importlib.metadata.version("numpy") and probe["double"] == 2.5
    # then the render and the unregistering
    lines = [l for l in proc.stdout.splitlines() if l.startswith("RESULT ")]
    assert proc.returncode == 0 and lines, proc.stdout[-2000:] + proc.stderr[-2000:]
    out = json.loads(lines[-1][len("RESULT "):])
    assert out["install"] == ["FINISHED"] and out["enabled"]
    assert "WHITTED" in out["engines_after_install"]
    user_dir = str(tmp_path / "blender_user")
    assert out["addon_file"].startswith(user_dir) and out["tracer_file"].startswith(user_dir)  # bundled tracer
    assert out["stats"]["eye"] > 0 and os.path.getsize(png) > 0
    assert "WHITTED" not in out["engines_after_disable"] and not out["scene_prop_after_disable"]
    # the kernels: shipped in the zip for this CPU family (kernels/), copied into the user's kernel cache by a child
    # process at register, none compiled there; nothing was written into the extension folder besides the zip's own
    k = out["kernels"]
    assert k["child_error"] is None and k["compiled_in_child"] == 0, k
    assert k["in_extension"] and all(f.startswith("kernels" + os.sep) for f in k["in_extension"]), k
    with zipfile.ZipFile(zip_path) as z:
        shipped = {n.split("/")[-1] for n in z.namelist() if n.startswith("kernels/") and n.endswith(".nbi")}
    cached = {f for _, _, fs in os.walk(tmp_path / "kernel_cache") for f in fs if f.endswith(".nbi")}
    assert cached and cached <= shipped and all(f.startswith("bl_ext.user_default.whitted.tracer.") for f in cached)


def _wheel_metadata(zip_path, package, platform_tag):
    with zipfile.ZipFile(zip_path) as z:
        name = next(n for n in z.namelist() if n.startswith(f"wheels/{package}-") and platform_tag in n)
        with zipfile.ZipFile(io.BytesIO(z.read(name))) as whl:
            meta = next(n for n in whl.namelist() if n.endswith(".dist-info/METADATA"))
            return whl.read(meta).decode()


def test_pinned_numba_fits_blender_numpy_and_bundled_llvmlite(zip_path):
    """The numba pin accepts the numpy Blender 5.0 ships (the one bpy 5.0.1 brings) and the bundled llvmlite."""
    numpy_version = importlib.metadata.version("numpy")
    bpy_numpy = [Requirement(r) for r in importlib.metadata.requires("bpy") if Requirement(r).name == "numpy"]
    assert bpy_numpy and all(r.specifier.contains(numpy_version) for r in bpy_numpy)
    llvmlite_version = dict(build.WHEELS)["llvmlite"]
    for platform_tag in ("manylinux",):
        requires = [Requirement(line.split(":", 1)[1].strip())
                    for line in _wheel_metadata(zip_path, "numba", platform_tag).splitlines()
                    if line.startswith("Requires-Dist:")]
        by_name = {r.name: r for r in requires if r.marker is None}
        assert by_name["numpy"].specifier.contains(numpy_version), (by_name["numpy"], numpy_version)
        # every numpy bpy allows (>=1.26,<2) is allowed by numba too
        assert all(by_name["numpy"].specifier.contains(v) for v in ("1.26.0", "1.26.4"))
        assert by_name["llvmlite"].specifier.contains(llvmlite_version, prereleases=True), by_name["llvmlite"]


def _fake_pip(calls, fail=False, wheel_name=None):
    def run(cmd, capture_output, text):
        calls.append(cmd)
        if fail:
            return subprocess.CompletedProcess(cmd, 1, "", "ERROR: No matching distribution found")
        dest = cmd[cmd.index("-d") + 1]
        package, version = cmd[cmd.index("download") + 1].split("==")
        tag = cmd[cmd.index("--platform") + 1]
        open(os.path.join(dest, wheel_name or f"{package}-{version}-cp311-cp311-{tag}.whl"), "wb").close()
        return subprocess.CompletedProcess(cmd, 0, "", "")
    return run


def test_fetch_passes_every_platform_tag_and_caches(tmp_path, monkeypatch):
    cache = str(tmp_path / "wheels")
    calls = []
    monkeypatch.setattr(build.subprocess, "run", _fake_pip(calls))
    wheels = build.fetch_wheels(["linux-x64", "windows-x64"], cache=cache)
    assert len(calls) == len(wheels) == 2 * len(build.WHEELS)
    for cmd in calls:
        assert cmd[:4] == [sys.executable, "-m", "pip", "download"]
        assert {"--no-deps", "--only-binary=:all:"} <= set(cmd) and cmd[cmd.index("--python-version") + 1] == "3.11"
        tags = [cmd[i + 1] for i, a in enumerate(cmd) if a == "--platform"]
        assert tags in (list(build.PLATFORMS["linux-x64"][0]), ["win_amd64"])
    linux_tags = [cmd[i + 1] for cmd in calls[:1] for i, a in enumerate(cmd) if a == "--platform"]
    assert {"manylinux_2_28_x86_64", "manylinux2014_x86_64"} <= set(linux_tags)
    assert [os.path.basename(w).split("-")[0] for w in wheels] == [p for p, _ in build.WHEELS] * 2
    # the second time everything comes from the cache, also offline
    calls.clear()
    assert build.fetch_wheels(["linux-x64", "windows-x64"], cache=cache, offline=True) == wheels and not calls


def test_find_wheel_matches_package_version_and_platform(tmp_path):
    cache = tmp_path
    for name in ("llvmlite-0.50.0-cp311-cp311-manylinux2014_x86_64.whl",
                 "llvmlite-0.49.0-cp311-cp311-win_amd64.whl",   # other version
                 "llvmlite-0.50.0-cp312-cp312-win_amd64.whl",   # other Python
                 "numba-0.68.1-cp311-cp311-macosx_11_0_arm64.whl"):
        (cache / name).touch()
    assert os.path.basename(build.find_wheel("llvmlite", "0.50.0", "linux-x64", str(cache))) == \
        "llvmlite-0.50.0-cp311-cp311-manylinux2014_x86_64.whl"
    assert build.find_wheel("llvmlite", "0.50.0", "windows-x64", str(cache)) is None
    assert build.find_wheel("numba", "0.68.1", "linux-x64", str(cache)) is None
    assert build.find_wheel("numba", "0.68.1", "windows-x64", str(cache)) is None


def test_fetch_errors_say_what_is_missing(tmp_path, monkeypatch):
    calls = []
    monkeypatch.setattr(build.subprocess, "run", _fake_pip(calls))
    # offline with an empty cache: no pip, and the message names package, version, platform and cache
    with pytest.raises(build.BuildError, match=r"no numba 0\.68\.1 wheel for windows-x64 in .* --offline"):
        build.fetch_wheel("numba", "0.68.1", "windows-x64", cache=str(tmp_path), offline=True)
    with pytest.raises(build.BuildError, match="unknown platform 'macos-x64'"):
        build.fetch_wheel("numba", "0.68.1", "macos-x64", cache=str(tmp_path))
    assert not calls
    # pip fails: the message carries the command, pip's words and the by-hand way out
    monkeypatch.setattr(build.subprocess, "run", _fake_pip(calls, fail=True))
    with pytest.raises(build.BuildError) as exc:
        build.fetch_wheel("llvmlite", "0.50.0", "linux-x64", cache=str(tmp_path))
    msg = str(exc.value)
    assert "llvmlite 0.50.0 wheel for linux-x64" in msg and "--platform manylinux_2_28_x86_64" in msg
    assert "No matching distribution" in msg and f"into {tmp_path} by hand" in msg
    # pip succeeds but leaves a wheel for the wrong platform: still an error, not a wrong zip
    monkeypatch.setattr(build.subprocess, "run",
                        _fake_pip(calls, wheel_name="llvmlite-0.50.0-cp311-cp311-win_amd64.whl"))
    with pytest.raises(build.BuildError, match="llvmlite 0.50.0 wheel for linux-x64"):
        build.fetch_wheel("llvmlite", "0.50.0", "linux-x64", cache=str(tmp_path))
    # build() stops before writing a zip when a wheel is missing offline
    with pytest.raises(build.BuildError, match="embreex"):
        build.build(str(tmp_path / "dist"), offline=True, cache=str(tmp_path / "empty"))
    assert not (tmp_path / "dist").exists()

"""Build the Blender extension, one zip per platform, with Blender's own extension builder:
``python -m addon.build dist`` writes ``dist/whitted-<version>-linux_x64.zip``, ``-windows_x64.zip`` and
``-macos_arm64.zip``.

The source is staged in a temporary directory (the manifest with the wheel list filled in, the add-on modules, a
copy of ``tracer/`` — the repository keeps one tracer — and ``wheels/``) and handed to
``blender_ext.py build --split-platforms``, the builder Blender ships (``bpy/<version>/scripts/addons_core/bl_pkg/
cli/blender_ext.py``, inside the bpy wheel of the test extra; ``BLENDER_EXT_PY`` overrides). It validates the
manifest as Blender's extension platform does and writes, per platform, a zip with that platform's wheels and a
``[build.generated]`` table naming them. The wheels are those Blender's Python lacks: ``embreex`` (its Embree 4
library, which tracer/accel/embree.py loads), ``numba`` and ``llvmlite`` (the tracer's JIT kernels). Blender 5.0 ships numpy (1.26.x, as bpy 5.0.1 requires ``numpy>=1.26,<2``)
and OpenImageIO; its Python is 3.11. The versions are pinned in ``WHEELS``; the numba pin must accept Blender's
numpy and the llvmlite pin must be the one that numba wants. Wheels are downloaded once with pip into
``.cache/wheels`` and reused offline afterwards:

    pip download PACKAGE==VERSION --no-deps --only-binary=:all: --python-version 3.11 --platform TAG [...]

with the ``--platform`` tags of ``PLATFORMS`` (Linux: manylinux up to glibc 2.28, the baseline of Blender 5.0 and
of its bpy wheel).
"""

from __future__ import annotations

import argparse
import glob
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ADDON = os.path.join(ROOT, "addon")
TRACER = os.path.join(ROOT, "tracer")
CACHE = os.path.join(ROOT, ".cache", "wheels")
#: Blender 4.2-5.0 run Python 3.11 (the bpy 5.0.1 wheel is cp311).
PYTHON_VERSION = "3.11"
#: The wheels bundled for every platform: (package, pinned version). numba 0.68.1 needs numpy>=1.22,<2.6 (Blender
#: 5.0: numpy 1.26) and llvmlite>=0.50,<0.51; pyproject's ``numba>=0.60`` resolves to the same pair.
WHEELS = (
    ("embreex", "4.4.0.post1"),
    ("numba", "0.68.1"),
    ("llvmlite", "0.50.0"),
)
#: Blender platform -> (pip --platform tags, all passed at once; wheel file-name platform pattern).
#: Linux wheels are tagged manylinux_2_27/_2_28 (numba, llvmlite, embreex) or manylinux2014 = manylinux_2_17
#: (older llvmlite releases); any of them runs where Blender 5.0 (glibc 2.28) runs.
PLATFORMS = {
    "linux-x64": (("manylinux_2_28_x86_64", "manylinux_2_27_x86_64", "manylinux_2_17_x86_64",
                   "manylinux2014_x86_64"), "*manylinux*x86_64.whl"),
    "windows-x64": (("win_amd64",), "*win_amd64.whl"),
    # Apple silicon: embreex publishes macosx_13_0_arm64, numba and llvmlite macosx_12_0_arm64 (pip picks the
    # newest tag it is given that a wheel has).
    "macos-arm64": (("macosx_14_0_arm64", "macosx_13_0_arm64", "macosx_12_0_arm64", "macosx_11_0_arm64"),
                    "*macosx_*_arm64.whl"),
}
#: Add-on files that stay out of the zip.
EXCLUDE = {"build.py"}
#: The extension builder inside the bpy wheel, relative to the bpy package.
BLENDER_EXT = os.path.join("*", "scripts", "addons_core", "bl_pkg", "cli", "blender_ext.py")


class BuildError(RuntimeError):
    pass


def find_wheel(package: str, version: str, platform: str, cache: str = CACHE) -> str | None:
    """The cached cp311 wheel of ``package==version`` for a Blender platform, or None."""
    name = re.sub(r"[-_.]+", "_", package)  # wheel file names spell the project name with underscores
    pattern = os.path.join(cache, f"{glob.escape(name)}-{glob.escape(version)}-cp311-{PLATFORMS[platform][1]}")
    found = sorted(glob.glob(pattern))
    return found[-1] if found else None


def fetch_wheel(package: str, version: str, platform: str, cache: str = CACHE, offline: bool = False) -> str:
    """The cached wheel of ``package==version`` for a Blender platform, downloaded with pip when missing (unless
    offline)."""
    if platform not in PLATFORMS:
        raise BuildError(f"unknown platform {platform!r}; choose from {', '.join(PLATFORMS)}")
    wheel = find_wheel(package, version, platform, cache)
    if wheel:
        return wheel
    if offline:
        raise BuildError(f"no {package} {version} wheel for {platform} in {cache} and --offline was given")
    os.makedirs(cache, exist_ok=True)
    cmd = [sys.executable, "-m", "pip", "download", f"{package}=={version}", "--no-deps", "--only-binary=:all:",
           "--python-version", PYTHON_VERSION]
    for tag in PLATFORMS[platform][0]:
        cmd += ["--platform", tag]
    cmd += ["-d", cache, "-q"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wheel = find_wheel(package, version, platform, cache)
    if proc.returncode != 0 or not wheel:
        raise BuildError(
            f"could not get the {package} {version} wheel for {platform} (Python {PYTHON_VERSION}).\n"
            f"  command: {' '.join(cmd)}\n  pip said: {(proc.stderr or proc.stdout).strip()[-600:]}\n"
            f"Put the wheel into {cache} by hand to build offline.")
    return wheel


def fetch_wheels(platforms, cache: str = CACHE, offline: bool = False) -> list[str]:
    """Every wheel of ``WHEELS`` for every platform (platform by platform), fetched as ``fetch_wheel`` does."""
    return [fetch_wheel(package, version, p, cache, offline) for p in platforms for package, version in WHEELS]


def manifest_text(wheels: list[str], platforms: list[str]) -> str:
    """The repository's manifest with ``wheels`` and ``platforms`` set to what this zip carries."""
    with open(os.path.join(ADDON, "blender_manifest.toml"), encoding="utf-8") as f:
        text = f.read()
    listed = "".join(f'  "./wheels/{os.path.basename(w)}",\n' for w in wheels)
    text, n = re.subn(r"(?ms)^wheels = \[.*?^\]\n", f"wheels = [\n{listed}]\n", text)
    if n != 1:
        raise BuildError("blender_manifest.toml: no `wheels = [...]` list to fill in")
    text, n = re.subn(r"(?m)^platforms = \[.*\]$", "platforms = [" + ", ".join(f'"{p}"' for p in platforms) + "]",
                      text)
    if n != 1:
        raise BuildError("blender_manifest.toml: no `platforms = [...]` line to fill in")
    macos = macos_minimum(wheels)
    line = (f"# macOS: {macos} or newer (the oldest macOS every bundled macos-arm64 wheel supports)\n"
            if macos else "# macOS: not bundled\n")
    text, n = re.subn(r"(?m)^# macOS: .*\n", line, text)
    if n != 1:
        raise BuildError("blender_manifest.toml: no `# macOS: ...` line to fill in")
    tomllib.loads(text)  # still valid TOML
    return text


def macos_minimum(wheels) -> str | None:
    """The oldest macOS all the given macOS wheels run on: the highest ``macosx_X_Y`` of their platform tags
    (e.g. embreex 4.4.0.post1 is macosx_13_0_arm64 -> "13.0"), or None without macOS wheels."""
    found = [tuple(int(x) for x in m.groups())
             for w in wheels for m in [re.search(r"macosx_(\d+)_(\d+)_", os.path.basename(w))] if m]
    return "{}.{}".format(*max(found)) if found else None


def _package_files(top: str):
    for dirpath, dirnames, filenames in os.walk(top):
        dirnames[:] = sorted(d for d in dirnames if d != "__pycache__" and not d.startswith("."))
        for name in sorted(filenames):
            if name.endswith((".pyc", ".pyo")) or name.startswith("."):
                continue
            yield os.path.join(dirpath, name)


def blender_ext_script() -> str:
    """Path of Blender's extension builder: ``BLENDER_EXT_PY``, else the one in the installed bpy wheel."""
    path = os.environ.get("BLENDER_EXT_PY")
    if path:
        if not os.path.isfile(path):
            raise BuildError(f"BLENDER_EXT_PY={path} is not a file")
        return path
    spec = importlib.util.find_spec("bpy")  # finds the package without importing (starting) Blender
    if spec is None or not spec.submodule_search_locations:
        raise BuildError("Blender's extension builder (blender_ext.py) comes with the bpy wheel: "
                         "pip install -e '.[test]' (or set BLENDER_EXT_PY to a blender_ext.py)")
    for top in spec.submodule_search_locations:
        found = sorted(glob.glob(os.path.join(top, BLENDER_EXT)))
        if found:
            return found[-1]
    raise BuildError(f"no {BLENDER_EXT} inside the bpy package at {list(spec.submodule_search_locations)}")


def stage(directory: str, wheels: list[str], platforms: list[str]) -> None:
    """Lay out the extension's source in ``directory`` as blender_ext.py builds it: the manifest (wheel list and
    platforms filled in), the add-on modules, ``tracer/``, ``wheels/``."""
    with open(os.path.join(directory, "blender_manifest.toml"), "w", encoding="utf-8") as f:
        f.write(manifest_text(wheels, platforms))
    for src in _package_files(ADDON):
        rel = os.path.relpath(src, ADDON)
        if rel in EXCLUDE or rel == "blender_manifest.toml":
            continue
        _copy(src, os.path.join(directory, rel))
    for src in _package_files(TRACER):
        if src.endswith(".py"):
            _copy(src, os.path.join(directory, "tracer", os.path.relpath(src, TRACER)))
    for w in wheels:
        _copy(w, os.path.join(directory, "wheels", os.path.basename(w)))


def _copy(src, dst):
    os.makedirs(os.path.dirname(dst), exist_ok=True)
    shutil.copyfile(src, dst)


#: Blender platforms whose zip carries kernels compiled ahead (tracer/kernel_bundle.py), for the baseline CPU of
#: tracer.kernel_cache.BASELINE_CPU; they can only be compiled on such a machine (this one: x86-64 Linux).
KERNEL_PLATFORMS = ("linux-x64",)
#: The name Blender imports an extension's bundled tracer by when it is installed into the default repository.
EXTENSION_TRACER = "bl_ext.user_default.whitted.tracer"


def _kernels_here(platform: str) -> bool:
    import platform as host

    return platform in KERNEL_PLATFORMS and sys.platform.startswith("linux") and host.machine() in ("x86_64", "AMD64")


def build(out_dir: str = "dist", platforms=tuple(PLATFORMS), offline: bool = False, cache: str = CACHE,
          kernels: bool = True) -> dict:
    """Write one extension zip per platform into ``out_dir`` (removing older whitted zips there) with Blender's
    builder; returns {platform: zip path}. The Linux zip then gets the kernels compiled ahead (``kernels/``,
    :func:`add_kernels`; ``kernels=False`` leaves them out)."""
    platforms = list(platforms)
    wheels = fetch_wheels(platforms, cache=cache, offline=offline)
    script = blender_ext_script()
    with open(os.path.join(ADDON, "blender_manifest.toml"), "rb") as f:
        manifest = tomllib.load(f)
    with tempfile.TemporaryDirectory(prefix="whitted-ext-") as tmp:
        src, out = os.path.join(tmp, "source"), os.path.join(tmp, "out")
        os.makedirs(src)
        os.makedirs(out)
        stage(src, wheels, platforms)
        cmd = [sys.executable, script, "build", "--source-dir", src, "--output-dir", out, "--split-platforms"]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        made = {p: os.path.join(out, f"{manifest['id']}-{manifest['version']}-{p.replace('-', '_')}.zip")
                for p in platforms}
        if proc.returncode != 0 or not all(os.path.isfile(z) for z in made.values()):
            raise BuildError(f"Blender's extension builder failed:\n  command: {' '.join(cmd)}\n"
                             f"  it said: {(proc.stdout + proc.stderr).strip()[-1500:]}")
        os.makedirs(out_dir, exist_ok=True)
        for old in glob.glob(os.path.join(out_dir, f"{manifest['id']}-*.zip")):
            os.unlink(old)
        result = {}
        for p, z in made.items():
            if kernels and _kernels_here(p):
                add_kernels(z, os.path.join(src, "tracer"), os.path.join(tmp, "kernels"))
            result[p] = os.path.join(out_dir, os.path.basename(z))
            shutil.move(z, result[p])
    return result


def add_kernels(zip_path: str, tracer_dir: str, work: str) -> dict:
    """Compile the staged tracer's kernels for the baseline CPU (tracer/kernel_bundle.py) as Blender will import
    it, and add them to the zip under ``kernels/`` (Blender's builder takes no per-platform files, so they are
    added to the Linux zip it wrote). Returns the bundle's manifest."""
    import zipfile

    from tracer import kernel_bundle  # here: building a zip without kernels never loads the tracer (numba)

    manifest = kernel_bundle.build(work, package=EXTENSION_TRACER, tracer_dir=tracer_dir)
    with zipfile.ZipFile(zip_path, "a", compression=zipfile.ZIP_DEFLATED) as z:
        for d, _, files in os.walk(work):
            for name in sorted(files):
                path = os.path.join(d, name)
                z.write(path, "kernels/" + os.path.relpath(path, work).replace(os.sep, "/"))
    return manifest


def main(argv=None):
    ap = argparse.ArgumentParser(description="Build the Whitted Blender extension: one zip per platform")
    ap.add_argument("out_dir", nargs="?", default="dist")
    ap.add_argument("--platform", action="append", choices=sorted(PLATFORMS),
                    help="Blender platform(s) to bundle the wheels for (default: all)")
    ap.add_argument("--offline", action="store_true", help="use cached wheels only, never run pip")
    ap.add_argument("--no-kernels", action="store_true", help="leave the kernels compiled ahead out of the Linux zip")
    args = ap.parse_args(argv)
    try:
        paths = build(args.out_dir, args.platform or tuple(PLATFORMS), offline=args.offline,
                      kernels=not args.no_kernels)
    except BuildError as exc:
        print(f"addon.build: {exc}", file=sys.stderr)
        return 1
    for platform, path in paths.items():
        print(f"{path} ({os.path.getsize(path) / 1e6:.1f} MB, {platform})")
    return 0


if __name__ == "__main__":
    sys.exit(main())

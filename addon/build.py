"""Build the Blender extension zip: ``python -m addon.build dist`` writes ``dist/whitted-<version>.zip``.

The zip holds the manifest, the add-on modules, a copy of ``tracer/`` (copied in at build time; the repository
keeps one tracer) and the wheels Blender's Python lacks, for each platform: ``embreex`` (Embree), ``numba`` and
``llvmlite`` (the tracer's JIT kernels). Blender 5.0 ships numpy (1.26.x, as bpy 5.0.1 requires ``numpy>=1.26,<2``)
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
import os
import re
import subprocess
import sys
import tomllib
import zipfile

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
}
#: Add-on files that stay out of the zip.
EXCLUDE = {"build.py"}


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
    tomllib.loads(text)  # still valid TOML
    return text


def _package_files(top: str):
    for dirpath, dirnames, filenames in os.walk(top):
        dirnames[:] = sorted(d for d in dirnames if d != "__pycache__" and not d.startswith("."))
        for name in sorted(filenames):
            if name.endswith((".pyc", ".pyo")) or name.startswith("."):
                continue
            yield os.path.join(dirpath, name)


def build(out_dir: str = "dist", platforms=tuple(PLATFORMS), offline: bool = False, cache: str = CACHE) -> str:
    """Write the extension zip into ``out_dir`` (removing older whitted zips there); returns its path."""
    platforms = list(platforms)
    wheels = fetch_wheels(platforms, cache=cache, offline=offline)
    with open(os.path.join(ADDON, "blender_manifest.toml"), "rb") as f:
        manifest = tomllib.load(f)
    os.makedirs(out_dir, exist_ok=True)
    for old in glob.glob(os.path.join(out_dir, f"{manifest['id']}-*.zip")):
        os.unlink(old)
    path = os.path.join(out_dir, f"{manifest['id']}-{manifest['version']}.zip")
    tmp = path + ".part"
    with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED) as z:
        z.writestr("blender_manifest.toml", manifest_text(wheels, platforms))
        for f in _package_files(ADDON):
            rel = os.path.relpath(f, ADDON)
            if rel in EXCLUDE or rel == "blender_manifest.toml":
                continue
            z.write(f, rel)
        for f in _package_files(TRACER):
            if f.endswith(".py"):
                z.write(f, os.path.join("tracer", os.path.relpath(f, TRACER)))
        for w in wheels:  # wheels are zips already: store them
            z.write(w, os.path.join("wheels", os.path.basename(w)), compress_type=zipfile.ZIP_STORED)
    os.replace(tmp, path)
    return path


def main(argv=None):
    ap = argparse.ArgumentParser(description="Build the Whitted Blender extension zip")
    ap.add_argument("out_dir", nargs="?", default="dist")
    ap.add_argument("--platform", action="append", choices=sorted(PLATFORMS),
                    help="Blender platform(s) to bundle the wheels for (default: all)")
    ap.add_argument("--offline", action="store_true", help="use cached wheels only, never run pip")
    args = ap.parse_args(argv)
    try:
        path = build(args.out_dir, args.platform or tuple(PLATFORMS), offline=args.offline)
    except BuildError as exc:
        print(f"addon.build: {exc}", file=sys.stderr)
        return 1
    print(f"{path} ({os.path.getsize(path) / 1e6:.1f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

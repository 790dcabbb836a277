"""Build the Blender extension zip: ``python -m addon.build dist`` writes ``dist/whitted-<version>.zip``.

The zip holds the manifest, the add-on modules, a copy of ``tracer/`` (copied in at build time; the repository
keeps one tracer) and the embreex wheels Blender's Python lacks (Blender 5.0 ships numpy and OpenImageIO; its
Python is 3.11). Wheels are downloaded once with pip into ``.cache/wheels`` and reused offline afterwards:

    pip download embreex==VERSION --no-deps --only-binary=:all: --python-version 3.11 --platform PLATFORM
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
EMBREEX_VERSION = "4.4.0.post1"
#: Blender platform -> (pip --platform tag, wheel file-name pattern).
PLATFORMS = {
    "linux-x64": ("manylinux_2_28_x86_64", "*manylinux*x86_64.whl"),
    "windows-x64": ("win_amd64", "*win_amd64.whl"),
}
#: Add-on files that stay out of the zip.
EXCLUDE = {"build.py"}


class BuildError(RuntimeError):
    pass


def find_wheel(platform: str, cache: str = CACHE) -> str | None:
    pattern = os.path.join(cache, f"embreex-{EMBREEX_VERSION}-cp311-{PLATFORMS[platform][1]}")
    found = sorted(glob.glob(pattern))
    return found[-1] if found else None


def fetch_wheel(platform: str, cache: str = CACHE, offline: bool = False) -> str:
    """The cached embreex wheel for a Blender platform, downloaded with pip when missing (unless offline)."""
    if platform not in PLATFORMS:
        raise BuildError(f"unknown platform {platform!r}; choose from {', '.join(PLATFORMS)}")
    wheel = find_wheel(platform, cache)
    if wheel:
        return wheel
    if offline:
        raise BuildError(f"no embreex {EMBREEX_VERSION} wheel for {platform} in {cache} and --offline was given")
    os.makedirs(cache, exist_ok=True)
    cmd = [sys.executable, "-m", "pip", "download", f"embreex=={EMBREEX_VERSION}", "--no-deps",
           "--only-binary=:all:", "--python-version", PYTHON_VERSION, "--platform", PLATFORMS[platform][0],
           "-d", cache, "-q"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wheel = find_wheel(platform, cache)
    if proc.returncode != 0 or not wheel:
        raise BuildError(
            f"could not get the embreex {EMBREEX_VERSION} wheel for {platform} (Python {PYTHON_VERSION}).\n"
            f"  command: {' '.join(cmd)}\n  pip said: {(proc.stderr or proc.stdout).strip()[-600:]}\n"
            f"Put the wheel into {cache} by hand to build offline.")
    return wheel


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


def build(out_dir: str = "dist", platforms=tuple(PLATFORMS), offline: bool = False) -> str:
    """Write the extension zip into ``out_dir`` (removing older whitted zips there); returns its path."""
    platforms = list(platforms)
    wheels = [fetch_wheel(p, offline=offline) for p in platforms]
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
                    help="Blender platform(s) to bundle embreex for (default: all)")
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

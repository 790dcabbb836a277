"""The extension zip: `python -m addon.build` output installs through Blender's own extension machinery into a
temporary user directory (BLENDER_USER_RESOURCES), registers, renders with its bundled tracer and embreex wheel,
and unregisters cleanly. Blender reads BLENDER_USER_RESOURCES at start-up, so this runs in a fresh process."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tomllib
import zipfile

import pytest

from addon import build

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

SCRIPT = r'''
import json, os, sys
import bpy
zip_path, png = sys.argv[1], sys.argv[2]
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
out["wheel_installed"] = os.path.isdir(os.path.join(site, "embreex"))
scene = bpy.context.scene
scene.render.engine = "WHITTED"
scene.render.resolution_percentage = 4
scene.render.filepath = png
scene.render.image_settings.file_format = "PNG"
bpy.ops.render.render(write_still=True)
out["stats"] = mod.engine.LAST_STATS["rays"]
bpy.ops.preferences.addon_disable(module="bl_ext.user_default.whitted")
out["engines_after_disable"] = engines()
out["scene_prop_after_disable"] = hasattr(bpy.types.Scene, "whitted")
print("RESULT " + json.dumps(out))
'''


@pytest.fixture(scope="module")
def zip_path(tmp_path_factory):
    return build.build(str(tmp_path_factory.mktemp("dist")))


def test_zip_contents(zip_path):
    with zipfile.ZipFile(zip_path) as z:
        names = set(z.namelist())
        manifest = tomllib.loads(z.read("blender_manifest.toml").decode())
    assert {"__init__.py", "engine.py", "export.py", "properties.py", "ui.py", "tracer/__init__.py",
            "tracer/integrator.py"} <= names
    assert "build.py" not in names and not any("__pycache__" in n for n in names)
    assert manifest["id"] == "whitted" and manifest["type"] == "add-on"
    assert manifest["schema_version"] == "1.0.0" and manifest["blender_version_min"] == "4.2.0"
    for wheel in manifest["wheels"]:
        assert wheel.removeprefix("./") in names
    assert any("manylinux" in w for w in manifest["wheels"])
    # one tracer in the repository: the zip's copy is made at build time, byte for byte
    with zipfile.ZipFile(zip_path) as z:
        assert z.read("tracer/render.py") == open(os.path.join(ROOT, "tracer", "render.py"), "rb").read()


def test_extension_installs_registers_renders_and_unregisters(zip_path, tmp_path):
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "blender_user"))
    png = str(tmp_path / "f12.png")
    proc = subprocess.run([sys.executable, "-c", SCRIPT, zip_path, png], env=env, capture_output=True, text=True,
                          timeout=300, cwd=str(tmp_path))
    lines = [l for l in proc.stdout.splitlines() if l.startswith("RESULT ")]
    assert proc.returncode == 0 and lines, proc.stdout[-2000:] + proc.stderr[-2000:]
    out = json.loads(lines[-1][len("RESULT "):])
    assert out["install"] == ["FINISHED"] and out["enabled"]
    assert "WHITTED" in out["engines_after_install"]
    user_dir = str(tmp_path / "blender_user")
    assert out["addon_file"].startswith(user_dir) and out["tracer_file"].startswith(user_dir)  # bundled tracer
    assert out["wheel_installed"]
    assert out["stats"]["eye"] > 0 and os.path.getsize(png) > 0
    assert "WHITTED" not in out["engines_after_disable"] and not out["scene_prop_after_disable"]

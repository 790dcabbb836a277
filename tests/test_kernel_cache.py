"""Kernels are cached by content, per kernel, in the user's cache folder (tracer/kernel_cache.py, tracer/jit.py).

An edit recompiles only what depends on it: each kernel's key covers its own code and values and every kernel it
reaches, so editing a file that no kernel reaches changes no key, and editing one noise function changes the keys
of the kernels that call it and no others. These run on a copy of tracer/ in a temporary folder, in child
processes (the keys of the copy are those of the original: file places are not part of a key), and check the keys
against an independent reading of the sources: which modules import what (ast).
"""

from __future__ import annotations

import ast
import json
import os
import shutil
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

KEYS = r'''
import importlib, json, pkgutil, sys
sys.path.insert(0, sys.argv[1])
import tracer
from tracer.jit import Kernel
from tracer.kernel_cache import content_key
out = {}
for info in pkgutil.walk_packages(tracer.__path__, "tracer."):
    module = importlib.import_module(info.name)
    for name, obj in vars(module).items():
        if isinstance(obj, Kernel) and obj.__module__ == module.__name__ and obj._opts.get("inline") != "always":
            out[f"{info.name}.{name}"] = content_key(obj._fn, obj._opts)
print(json.dumps(out))
'''


def _keys(tree) -> dict:
    r = subprocess.run([sys.executable, "-c", KEYS, str(tree)], capture_output=True, text=True, timeout=300,
                       cwd=str(tree))
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.fixture
def tree(tmp_path):
    shutil.copytree(os.path.join(ROOT, "tracer"), tmp_path / "tracer", ignore=shutil.ignore_patterns("__pycache__"))
    return tmp_path


def _importers(tree, target: str) -> set:
    """Modules of the copy that import ``target`` directly or through other tracer modules (from the sources)."""
    graph = {}
    base = tree / "tracer"
    for path in base.rglob("*.py"):
        rel = path.relative_to(tree).with_suffix("")
        name = ".".join(rel.parts).removesuffix(".__init__")
        package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
        deps = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                mod = node.module or ""
                if node.level:
                    parts = package.split(".")
                    mod = ".".join(parts[:len(parts) - node.level + 1] + ([mod] if mod else []))
                deps.add(mod)
                deps.update(f"{mod}.{a.name}" for a in node.names)
            elif isinstance(node, ast.Import):
                deps.update(a.name for a in node.names)
        graph[name] = deps
    reach = {target}
    changed = True
    while changed:
        changed = False
        for name, deps in graph.items():
            if name not in reach and deps & reach:
                reach.add(name)
                changed = True
    return reach


def test_editing_a_file_that_no_kernel_reaches_changes_no_key(tree):
    before = _keys(tree)
    assert len(before) > 300
    for name in ("settings.py", "farm.py", "explain.py"):
        with open(tree / "tracer" / name, "a") as f:
            f.write("\n\ndef _an_edit():\n    return 'a new function and a comment'  # edited\n")
    assert _keys(tree) == before


def test_editing_one_noise_function_changes_only_the_keys_of_the_kernels_that_reach_it(tree):
    before = _keys(tree)
    path = tree / "tracer" / "shading" / "procedural" / "noise.py"
    text = path.read_text()
    i = text.index("def perlin3(")
    j = text.index('"""', text.index('"""', i) + 3) + 3  # after perlin3's docstring
    path.write_text(text[:j] + "\n    _edited = 1.0" + text[j:])
    after = _keys(tree)
    changed = {k for k in before if before[k] != after[k]}
    # the edited kernel, the noise functions that call it, the VM that calls them and the stages above the VM
    assert {"tracer.shading.procedural.noise.perlin3", "tracer.shading.procedural.noise.noise_texture",
            "tracer.shading.vm._procedural", "tracer.shading.vm.execute", "tracer.shading.vm.shade_programs"} <= changed
    # ... and nothing in a module that does not import noise.py, directly or through others
    reach = _importers(tree, "tracer.shading.procedural.noise")
    outside = {k for k in changed if k.rsplit(".", 1)[0] not in reach}
    assert not outside, outside
    for k in ("tracer.integrator.wavefront._direct_light", "tracer.integrator.wavefront._spawn_secondary", "tracer.integrator.tiles._tile_eye_rays",
              "tracer.accel.embree.intersect_rays", "tracer.shading.bsdf.principled", "tracer.shading.procedural.voronoi.voronoi_texture"):
        assert before[k] == after[k], k
    assert len(changed) < len(before) // 4


RENDER = r'''
import json, sys
sys.path.insert(0, sys.argv[1])
import numpy as np
import tracer
from tracer.jit import CompileProgress
b = tracer.SceneBuilder()
m = b.add_material("red", diffuse=(0.8, 0.1, 0.1))
b.add_mesh(np.array([[-1, -1, 0], [1, -1, 0], [0, 1, 0]], float), np.array([[0, 1, 2]]), material=m)
b.add_light(tracer.PointLight(position=(0, 0, 3), intensity=(5, 5, 5)))
b.camera = tracer.Camera.look_at((0, -3, 3), (0, 0, 0), up=(0, 0, 1))
progress = CompileProgress(lambda *a: None)
with progress:
    img = tracer.render(b.build(), tracer.RenderSettings(width=8, height=8, samples=1, threads=1))
print(json.dumps({"units": progress.done, "sum": float(img.rgba[..., :3].sum())}))
'''


def _render(tree, cache) -> dict:
    env = dict(os.environ, WHITTED_KERNEL_CACHE=str(cache))
    r = subprocess.run([sys.executable, "-c", RENDER, str(tree)], capture_output=True, text=True, timeout=900,
                       env=env, cwd=str(tree))
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_a_second_process_loads_every_kernel_and_an_edit_elsewhere_recompiles_nothing(tree, tmp_path):
    cache = tmp_path / "kernels"
    first = _render(tree, cache)
    assert first["units"] > 20 and first["sum"] > 0  # cold: compiled into the (empty) cache
    files = [f for f in os.listdir(next(cache.iterdir())) if f.endswith(".nbi")]
    assert files and all(f.startswith("tracer.") for f in files)  # one file per kernel, named after it
    again = _render(tree, cache)
    assert again == dict(first, units=0)
    with open(tree / "tracer" / "settings.py", "a") as f:
        f.write("\n# an edit of a file that defines no kernel\n")
    assert _render(tree, cache) == dict(first, units=0)


def test_an_installed_package_with_its_kernels_compiles_nothing(tree, tmp_path):
    """A package built with kernels inside (``tracer/kernels/``, tracer.kernel_cache.PACKAGED) renders from an empty
    user cache without compiling: the kernels are copied from the package into the cache and loaded."""
    built = tmp_path / "built"
    first = _render(tree, built)
    assert first["units"] > 20
    flavour = next(built.iterdir()).name
    packaged = tree / "tracer" / "kernels" / flavour
    shutil.copytree(built / flavour, packaged, ignore=shutil.ignore_patterns(".*", "*.lock"))
    from numba.core.registry import cpu_target

    magic = list(cpu_target.target_context.codegen().magic_tuple())
    (packaged / "bundle.json").write_text(json.dumps({"magic": magic, "features": []}))
    user = tmp_path / "user"
    assert _render(tree, user) == dict(first, units=0)
    assert any(f.endswith(".nbi") for f in os.listdir(user / flavour))  # copied into the user's cache


def test_a_bundle_is_refused_where_it_does_not_fit(tmp_path):
    from tracer import kernel_cache

    folder = tmp_path / "bundle" / kernel_cache._flavour()
    folder.mkdir(parents=True)
    assert not kernel_cache.use_bundle(str(tmp_path / "bundle"))  # no manifest
    manifest = {"magic": ["x86_64-unknown-linux-gnu", "x86-64-v3", ""], "features": ["no-such-feature"]}
    (folder / kernel_cache.MANIFEST).write_text(json.dumps(manifest))
    assert not kernel_cache.use_bundle(str(tmp_path / "bundle"))  # a CPU feature this machine lacks
    assert not kernel_cache._BUNDLE


def test_helpers_have_no_python_wrapper_yet_python_calls_work():
    from tracer import optics, vec
    from tracer.jit import Kernel

    assert isinstance(optics.reflect_dir, Kernel) and optics.reflect_dir._opts.get("no_cpython_wrapper")
    assert optics.reflect_dir((1.0, -1.0, 0.0), (0.0, 1.0, 0.0)) == (1.0, 1.0, 0.0)  # the seed's d - 2(d.n)n
    assert vec.dot((1.0, 2.0, 3.0), (1.0, 1.0, 1.0)) == 6.0

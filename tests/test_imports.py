"""The import graph of tracer/, usd_io/ and addon/ has no cycles (issue #31): every ``import`` counted, at module
top and inside functions (an import written inside a function to dodge a cycle is still a cycle), read statically
with ``ast``. Imports inside functions remain only where they defer a heavy or optional package (pxr, bpy, numba,
MaterialX, dask, OpenImageIO) for start-up time; those are outside the three packages and not in this graph. The
few imports of the three packages still written inside a function are listed in ``DEFERRED``, each with its reason.

``LAYERS`` is the architecture of the tree (README "Where things live"): each package's modules and subpackages in
layers, bottom first. A module imports only from its own layer or one below; an import that points up fails
:func:`test_imports_flow_down_the_layers`."""

from __future__ import annotations

import ast
import os

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGES = ("tracer", "usd_io", "addon")

#: Each package's layers, bottom first: a module imports only from its own layer or one below it. An entry names a
#: module or a subpackage (all of its modules). tracer/ comes below usd_io/ and addon/ (the tracer imports neither).
LAYERS: dict = {
    "tracer": [
        # leaves: the vector maths, the numba kernels and their cache, settings and colour facts
        {"tracer.settings", "tracer.vec", "tracer.colorspace", "tracer.sampling", "tracer.heap", "tracer.optics",
         "tracer.jit", "tracer.kernel_cache", "tracer.kernel_bundle"},
        {"tracer.geometry", "tracer.camera", "tracer.clip_planes", "tracer.lights"},
        {"tracer.shading"},  # the VM reads surface attributes (geometry)
        {"tracer.scene", "tracer.scene_kernels", "tracer.builder"},  # the container of all of the above
        {"tracer.accel", "tracer.film", "tracer.png_stream", "tracer.denoise"},
        {"tracer.integrator"},
        # the front doors
        {"tracer", "tracer.render", "tracer.session", "tracer.farm", "tracer.explain", "tracer.warmup",
         "tracer.kernel_plan"},
    ],
    "usd_io": [
        {"usd_io", "usd_io.errors", "usd_io.diagnostics", "usd_io.exporters", "usd_io.layer_metadata",
         "usd_io.holdout", "usd_io.render_settings"},
        {"usd_io.geometry"},
        {"usd_io.materials"},
        {"usd_io.stage", "usd_io.dome", "usd_io.lights", "usd_io.camera"},
        {"usd_io.reader"},
        {"usd_io.outputs", "usd_io.request", "usd_io.explain", "usd_io.farm", "usd_io.cli"},
    ],
}
#: Packages in order: tracer below usd_io below addon.
PACKAGE_ORDER = ("tracer", "usd_io", "addon")


#: Imports of the three packages still written inside a function, each for a reason that is not a cycle (start-up
#: time, or a package the importer must not load for its other callers). A new one fails the test (put the import
#: at the module's top, or give it a reason here); a listed one that is gone fails too (the list only shrinks).
DEFERRED: dict = {
    # the `whitted` command answers --version, --help and a bad flag before pxr, numba or the tracer load
    ("usd_io.cli", "tracer"): "start-up", ("usd_io.cli", "tracer.jit"): "start-up",
    ("usd_io.cli", "tracer.png_stream"): "start-up", ("usd_io.cli", "tracer.render"): "start-up",
    ("usd_io.cli", "tracer.integrator.tiles"): "start-up", ("usd_io.cli", "usd_io.explain"): "start-up (pxr, the tracer)",
    ("usd_io.cli", "usd_io.farm"): "dask only with --scheduler", ("usd_io.cli", "usd_io.render_settings"): "pxr",
    ("usd_io.cli", "usd_io.stage"): "pxr", ("usd_io.cli", "tracer.kernel_plan"): "start-up",
    ("usd_io.cli", "tracer.denoise"): "start-up",
    ("usd_io.outputs", "tracer"): "start-up", ("usd_io.outputs", "tracer.film"): "start-up",
    ("usd_io.outputs", "tracer.png_stream"): "start-up",
    ("usd_io.request", "usd_io.reader"): "start-up (pxr, the tracer: the CLI parses flags with request.py)",
    # MaterialX loads only for a material with a MaterialX network
    ("usd_io.materials.table", "usd_io.materials.mtlx_graph"): "MaterialX",
    ("usd_io.materials.mtlx_surfaces", "usd_io.materials.mtlx_closures"): "MaterialX",
    # properties.py imports bpy; export.py also runs where only its scene conversion is wanted
    ("addon.export", "addon.properties"): "bpy",
    # building a zip without kernels does not load the tracer (numba)
    ("addon.build", "tracer"): "numba", ("addon.build", "tracer.kernel_bundle"): "numba",
    # files of the kernel and farm work, not edited in the cycle work (issue #31)
    ("tracer.farm", "tracer.integrator.tiles"): "dask workers", ("tracer.farm", "tracer.session"): "dask workers",
    ("usd_io.farm", "tracer"): "dask workers", ("usd_io.farm", "tracer.farm"): "dask workers",
    ("usd_io.farm", "usd_io.stage"): "dask workers",
}


def modules() -> dict[str, str]:
    """{module name: file} of the three packages."""
    out = {}
    for pkg in PACKAGES:
        for root, dirs, files in os.walk(os.path.join(ROOT, pkg)):
            dirs[:] = sorted(d for d in dirs if d != "__pycache__")
            for f in sorted(files):
                if f.endswith(".py"):
                    rel = os.path.relpath(os.path.join(root, f), ROOT)[:-3].replace(os.sep, ".")
                    out[rel.removesuffix(".__init__")] = os.path.join(root, f)
    return out


def _imports(deferred_only: bool = False) -> dict[str, set]:
    """{module: the modules of the three packages it imports}; ``deferred_only``: only imports written inside a
    function."""
    mods = modules()
    graph = {m: set() for m in mods}
    for m, path in mods.items():
        package = m if path.endswith("__init__.py") else m.rsplit(".", 1)[0]
        with open(path, encoding="utf-8") as f:
            tree = ast.parse(f.read(), path)
        if deferred_only:
            nodes = [n for fn in ast.walk(tree) if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef))
                     for n in ast.walk(fn)]
        else:
            nodes = list(ast.walk(tree))
        for node in nodes:
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")
                    base = base[:len(base) - (node.level - 1)]
                    src = ".".join(base + ([node.module] if node.module else []))
                else:
                    src = node.module or ""
                targets = [src] + [f"{src}.{a.name}" for a in node.names]
            for t in targets:
                while t and t not in mods:  # a name imported from a module: the module
                    t = t.rsplit(".", 1)[0] if "." in t else ""
                if t and t != m and not (m.startswith(t + ".") and t in PACKAGES):  # a package's own __init__
                    graph[m].add(t)
    return graph


def import_graph() -> dict[str, set]:
    """{module: the modules of the three packages it imports}, top-level and function-level imports alike."""
    return _imports()


def deferred_imports() -> set:
    """(module, imported module) for every import of one of the three packages written inside a function."""
    return {(m, t) for m, ts in _imports(deferred_only=True).items() for t in ts}


def cycles(graph: dict[str, set]) -> set:
    """The strongly connected components of more than one module (Tarjan), each a sorted tuple."""
    index, low, stack, on, out = {}, {}, [], set(), set()
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.add(tuple(sorted(comp)))

    import sys
    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 10000))
    try:
        for v in sorted(graph):
            if v not in index:
                visit(v)
    finally:
        sys.setrecursionlimit(limit)
    return out


def test_no_import_cycles():
    found = cycles(import_graph())
    assert not found, "import cycles: " + "; ".join(" <-> ".join(c) for c in sorted(found))


def layer_of(module: str) -> tuple:
    """(package rank, layer index) of a module: its longest LAYERS entry."""
    pkg = module.split(".")[0]
    best = None
    for i, layer in enumerate(LAYERS.get(pkg, [])):
        for entry in layer:
            if (module == entry or module.startswith(entry + ".")) and (best is None or len(entry) > len(best[1])):
                best = (i, entry)
    if best is None and pkg in LAYERS:
        raise AssertionError(f"{module} is in no layer of LAYERS: put it in one")
    return PACKAGE_ORDER.index(pkg), best[0] if best else 0


def upward_imports(graph: dict) -> list:
    """(importer, imported) pairs that point up the layers."""
    return sorted((m, t) for m, ts in graph.items() for t in ts if layer_of(t) > layer_of(m))


def test_imports_flow_down_the_layers():
    up = upward_imports(import_graph())
    assert not up, "imports that point up the layers (move the shared piece down): " + \
        "; ".join(f"{a} -> {b}" for a, b in up)


def test_an_upward_import_is_caught():
    """The layer check fails on an import it should refuse: geometry reaching up into the scene container."""
    assert upward_imports({"tracer.geometry.instances": {"tracer.scene"}}) == [
        ("tracer.geometry.instances", "tracer.scene")]
    assert upward_imports({"tracer.shading.vm": {"usd_io.reader"}})
    assert not upward_imports({"tracer.scene": {"tracer.geometry.instances"}})


def test_imports_inside_functions_have_a_reason():
    """An import of tracer/, usd_io/ or addon/ written inside a function is listed in DEFERRED with its reason."""
    found = deferred_imports()
    new = found - set(DEFERRED)
    assert not new, "imports inside functions (move them to the module's top): " + \
        "; ".join(f"{a} -> {b}" for a, b in sorted(new))
    gone = set(DEFERRED) - found
    assert not gone, f"now at module top, remove them from DEFERRED: {sorted(gone)}"


def test_the_graph_sees_function_level_imports(tmp_path, monkeypatch):
    """The reader counts an import written inside a function (a cycle dodged that way is still found)."""
    g = import_graph()
    assert "tracer.shading.compiler" in g["tracer.integrator.wavefront"]  # a top-level `from ..shading.compiler import`
    assert "usd_io.materials.mtlx_graph" in g["usd_io.materials.table"]  # written inside MaterialTable._graph


@pytest.mark.parametrize("pkg", PACKAGES)
def test_packages_are_read(pkg):
    assert any(m.startswith(pkg + ".") for m in import_graph())


def test_each_subpackage_says_what_it_holds_and_may_import():
    """Every subpackage's docstring names what it holds and what it may import (the layers, in words)."""
    for m, path in modules().items():
        if path.endswith("__init__.py") and m.count(".") == 1:
            with open(path, encoding="utf-8") as f:
                doc = ast.get_docstring(ast.parse(f.read())) or ""
            assert "May import" in doc, f"{m}/__init__.py: say what it holds and what it may import"

"""MaterialX documents referenced from USD (``references = @looks.mtlx@</MaterialX/Materials>``).

usd-core has no ``usdMtlx`` file format plugin, so such a reference does not compose. This module translates a
``.mtlx`` document into an in-memory USD layer the way usdMtlx lays it out (the subset the reader understands:
``/MaterialX/Materials/<surfacematerial>`` Material prims whose ``outputs:mtlx:surface`` connects to a child
Shader ``ND_<category>_surfaceshader``; each node graph the shader reads copied into the Material as a NodeGraph
of ``ND_<category>_<type>`` Shaders) and points the stage's references at it, in memory — no file is written and
the stage's own files are not changed on disk.

Values keep their MaterialX types (float, color3, vector2/3/4, filename, ...); ``filename`` inputs become asset
paths made absolute against the document's folder (and ``fileprefix``); an input's ``colorspace`` becomes the
attribute's ``colorSpace``. Documents that cannot be parsed stay unresolved (the composition warning names them).
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET

from pxr import Sdf

#: MaterialX type -> Sdf value type.
TYPES = {"float": Sdf.ValueTypeNames.Float, "integer": Sdf.ValueTypeNames.Int, "boolean": Sdf.ValueTypeNames.Bool,
         "color3": Sdf.ValueTypeNames.Color3f, "color4": Sdf.ValueTypeNames.Color4f,
         "vector2": Sdf.ValueTypeNames.Float2, "vector3": Sdf.ValueTypeNames.Float3,
         "vector4": Sdf.ValueTypeNames.Float4, "filename": Sdf.ValueTypeNames.Asset,
         "string": Sdf.ValueTypeNames.String, "surfaceshader": Sdf.ValueTypeNames.Token}
NOT_NODES = {"input", "output", "nodegraph", "nodedef", "surfacematerial", "look", "materialassign", "collection",
             "geominfo", "token", "variant", "variantset", "implementation", "typedef", "backdrop", "propertyset"}

#: Translated documents by absolute path (layers must stay alive while stages reference them).
_LAYERS: dict[str, Sdf.Layer | None] = {}


def _value(mx_type: str, text: str, base_dir: str):
    if mx_type == "filename":
        return Sdf.AssetPath(text if os.path.isabs(text) else os.path.normpath(os.path.join(base_dir, text)))
    if mx_type == "string":
        return text
    if mx_type == "boolean":
        return text.strip().lower() == "true"
    nums = [float(x) for x in text.replace(",", " ").split()]
    if mx_type == "integer":
        return int(nums[0])
    return nums[0] if len(nums) == 1 else tuple(nums)


def _file_prefix(elem, parents) -> str:
    for e in [elem, *reversed(parents)]:
        if e.get("fileprefix"):
            return e.get("fileprefix")
    return ""


class _Writer:
    def __init__(self, root, base_dir: str):
        self.root, self.base_dir = root, base_dir
        self.layer = Sdf.Layer.CreateAnonymous(".usda")
        self.graphs = {g.get("name"): g for g in root.findall("nodegraph")}
        self.nodes = {n.get("name"): n for n in root if n.tag not in NOT_NODES}

    def prim(self, path: Sdf.Path, type_name: str) -> Sdf.PrimSpec:
        Sdf.CreatePrimInLayer(self.layer, path)
        spec = self.layer.GetPrimAtPath(path)
        spec.specifier = Sdf.SpecifierDef
        spec.typeName = type_name
        return spec

    def attr(self, spec, name, mx_type):
        return Sdf.AttributeSpec(spec, name, TYPES.get(mx_type, Sdf.ValueTypeNames.Token))

    def shader(self, parent: Sdf.Path, node, scope: dict, graph_path: Sdf.Path | None, parents) -> Sdf.Path:
        """One node as a Shader under ``parent``; its upstream nodes (by ``nodename`` in ``scope``) too."""
        path = parent.AppendChild(node.get("name"))
        if self.layer.GetPrimAtPath(path):
            return path
        spec = self.prim(path, "Shader")
        ident = Sdf.AttributeSpec(spec, "info:id", Sdf.ValueTypeNames.Token, variability=Sdf.VariabilityUniform)
        ident.default = f"ND_{node.tag}_{node.get('type')}"
        self.attr(spec, "outputs:out" if node.get("type") != "surfaceshader" else "outputs:surface",
                  node.get("type"))
        for inp in node.findall("input"):
            self.input(spec, path, inp, scope, graph_path, [*parents, node])
        return path

    def input(self, spec, owner: Sdf.Path, inp, scope: dict, graph_path, parents) -> None:
        mx_type = inp.get("type", "float")
        a = self.attr(spec, f"inputs:{inp.get('name')}", mx_type)
        if inp.get("colorspace"):
            a.SetInfo("colorSpace", inp.get("colorspace"))
        if inp.get("nodename") and inp.get("nodename") in scope:
            up = self.shader(owner.GetParentPath() if graph_path is None else graph_path,
                             scope[inp.get("nodename")], scope, graph_path, parents)
            a.connectionPathList.Prepend(up.AppendProperty(_out_name(scope[inp.get("nodename")])))
        elif inp.get("nodegraph") and inp.get("nodegraph") in self.graphs:
            g = self.graph(owner.GetParentPath(), self.graphs[inp.get("nodegraph")], parents)
            a.connectionPathList.Prepend(g.AppendProperty(f"outputs:{inp.get('output') or 'out'}"))
        elif inp.get("value") is not None:
            text = inp.get("value")
            if mx_type == "filename":
                text = _file_prefix(inp, parents) + text
            try:
                a.default = _value(mx_type, text, self.base_dir)
            except (ValueError, IndexError):
                pass

    def graph(self, parent: Sdf.Path, g, parents) -> Sdf.Path:
        path = parent.AppendChild(g.get("name"))
        if self.layer.GetPrimAtPath(path):
            return path
        spec = self.prim(path, "NodeGraph")
        scope = {n.get("name"): n for n in g if n.tag not in NOT_NODES}
        for out in g.findall("output"):
            a = self.attr(spec, f"outputs:{out.get('name')}", out.get("type", "float"))
            node = scope.get(out.get("nodename"))
            if node is not None:
                up = self.shader(path, node, scope, path, [*parents, g])
                a.connectionPathList.Prepend(up.AppendProperty(_out_name(node)))
        return path

    def material(self, m) -> None:
        path = Sdf.Path("/MaterialX/Materials").AppendChild(m.get("name"))
        spec = self.prim(path, "Material")
        out = Sdf.AttributeSpec(spec, "outputs:mtlx:surface", Sdf.ValueTypeNames.Token)
        for inp in m.findall("input"):
            node = self.nodes.get(inp.get("nodename"))
            if inp.get("type") == "surfaceshader" and node is not None:
                sh = self.shader(path, node, self.nodes, None, [m])
                out.connectionPathList.Prepend(sh.AppendProperty("outputs:surface"))

    def translate(self) -> Sdf.Layer:
        self.prim(Sdf.Path("/MaterialX"), "Scope")
        self.prim(Sdf.Path("/MaterialX/Materials"), "Scope")
        for m in self.root.findall("surfacematerial"):
            self.material(m)
        return self.layer


def _out_name(node) -> str:
    return "outputs:surface" if node.get("type") == "surfaceshader" else "outputs:out"


def translate(path: str) -> Sdf.Layer | None:
    """The in-memory USD layer of a ``.mtlx`` document (cached by path), or None when it cannot be read."""
    path = os.path.abspath(path)
    if path not in _LAYERS:
        try:
            root = ET.parse(path).getroot()
            _LAYERS[path] = _Writer(root, os.path.dirname(path)).translate() if root.tag == "materialx" else None
        except (OSError, ET.ParseError):
            _LAYERS[path] = None
    return _LAYERS[path]


def _mtlx_items(items, layer) -> tuple[list, bool]:
    """(the list with every .mtlx reference pointed at its translation, whether anything changed)."""
    out, changed = [], False
    for ref in items:
        if ref.assetPath.lower().endswith(".mtlx"):
            translated = translate(layer.ComputeAbsolutePath(ref.assetPath))
            if translated is not None:
                ref = Sdf.Reference(translated.identifier, ref.primPath, ref.layerOffset, ref.customData)
                changed = True
        out.append(ref)
    return out, changed


def resolve_mtlx_references(stage) -> int:
    """Point every ``.mtlx`` reference in the stage's layers at its in-memory translation; returns how many
    prim specs changed (the stage recomposes them)."""
    specs = []
    for layer in stage.GetUsedLayers():
        if layer.anonymous:
            continue
        layer.Traverse(Sdf.Path.absoluteRootPath,
                       lambda p, layer=layer: specs.append((layer, p)) if p.IsPrimPath() or p.IsPrimVariantSelectionPath() else None)
    changed = 0
    with Sdf.ChangeBlock():
        for layer, p in specs:
            spec = layer.GetPrimAtPath(p)
            if spec is None or not spec.hasReferences:
                continue
            refs = spec.referenceList
            for which in ("explicitItems", "prependedItems", "appendedItems"):
                items, hit = _mtlx_items(list(getattr(refs, which)), layer)
                if hit:
                    setattr(refs, which, items)
                    changed += 1
    return changed

"""MaterialX documents referenced from USD (``references = @looks.mtlx@</MaterialX/Materials>``), and the node
definitions every MaterialX network is read against.

usd-core has no ``usdMtlx`` file format plugin, so such a reference does not compose. This module reads a
``.mtlx`` document with the MaterialX library (``pip install MaterialX``: XIncludes, version upgrades, node
definitions), translates it into an in-memory USD layer the way usdMtlx lays it out (``/MaterialX/Materials/<m>``
Material prims whose ``outputs:mtlx:surface`` connects to a child Shader; each node graph the shader reads copied
into the Material as a NodeGraph of Shaders, its interface inputs as NodeGraph inputs) and points the stage's
references at it, in memory — no file is written and the stage's own files are not changed on disk.

Each Shader's ``info:id`` is the name of the node definition MaterialX resolves for the node (``ND_add_color3FA``,
``ND_noise3d_float``, or a document's own ``<nodedef>``); a node with several outputs gets one ``outputs:<name>``
each. Values keep their MaterialX types; ``filename`` values are resolved as MaterialX resolves them (the
``fileprefix`` of the input or of any ancestor element) and made absolute against the file that authored them (an
XIncluded file's own folder); a value with a ``unit`` is converted into the unit its node definition declares,
else (a distance) into the stage's own (its metres per unit, MaterialX's "scene unit"); an input's active colour
space (its own or an ancestor's ``colorspace``) becomes the attribute's ``colorSpace``; a node graph input's
``defaultgeomprop`` its custom data ``mtlx:defaultgeomprop``; an input naming a document-level ``<output>``
(``output`` alone) a connection to the node that output passes on. Documents that cannot be parsed stay unresolved
(the composition warning names them).

:func:`nodedef` finds a node definition by name among the standard libraries and the definitions of every document
read so far (their ``<nodedef>`` s and the ``<nodegraph nodedef=...>`` s implementing them):
:mod:`usd_io.materials.mtlx_graph` reads networks against it.
"""

from __future__ import annotations

import os

import numpy as np
from pxr import Gf, Sdf, Tf

from tracer import colorspace

from ..layer_metadata import meters_per_unit as stage_meters_per_unit

#: MaterialX type -> Sdf value type.
TYPES = {"float": Sdf.ValueTypeNames.Float, "integer": Sdf.ValueTypeNames.Int, "boolean": Sdf.ValueTypeNames.Bool,
         "color3": Sdf.ValueTypeNames.Color3f, "color4": Sdf.ValueTypeNames.Color4f,
         "vector2": Sdf.ValueTypeNames.Float2, "vector3": Sdf.ValueTypeNames.Float3,
         "vector4": Sdf.ValueTypeNames.Float4, "filename": Sdf.ValueTypeNames.Asset,
         "string": Sdf.ValueTypeNames.String, "surfaceshader": Sdf.ValueTypeNames.Token,
         "matrix33": Sdf.ValueTypeNames.Matrix3d, "matrix44": Sdf.ValueTypeNames.Matrix4d}

#: MaterialX types whose values may carry a unit.
UNIT_TYPES = ("float", "vector2", "vector3", "vector4")
#: Translated documents by absolute path (layers must stay alive while stages reference them).
_LAYERS: dict[tuple[str, float], Sdf.Layer | None] = {}
_LIB: dict = {}


def _library() -> mx.Document:
    """The standard data libraries (stdlib, pbrlib, bxdf: Standard Surface, OpenPBR, UsdPreviewSurface)."""
    import MaterialX as mx  # in the three functions that read documents: a stage without .mtlx never loads it

    if "std" not in _LIB:
        lib = mx.createDocument()
        mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), lib)
        _LIB["std"] = lib
        _LIB["docs"] = mx.createDocument()  # the documents' own definitions
        _LIB["docs"].setDataLibrary(lib)
    return _LIB["std"]


def definitions() -> mx.Document:
    """A document whose nodedef lookups see the libraries and every read document's own definitions."""
    _library()
    return _LIB["docs"]


def linear_colour(value, space: str, unknown=None):
    """A colour value authored in MaterialX colour space ``space`` (an input's ``colorspace``, its own or
    inherited: what :func:`translate` writes as the attribute's ``colorSpace``) as linear Rec.709, the tracer's
    working space (:func:`tracer.colorspace.to_lin_rec709`, MaterialX's own colour transforms). A space MaterialX's
    default colour management does not know is left as is and reported through ``unknown(space)``; a value that
    is not a colour (a scalar, a string) is returned unchanged."""
    space = str(space or "")
    if space in colorspace.NO_CONVERSION or value is None or isinstance(value, str):
        return value
    if colorspace.materialx_space(space) is None:
        if unknown is not None:
            unknown(space)
        return value
    v = np.asarray(value.asTuple() if hasattr(value, "asTuple") else value, np.float64).reshape(-1)
    if v.size not in (3, 4):
        return value
    rgb = colorspace.to_lin_rec709(v[:3], space)
    return tuple(float(x) for x in rgb) + tuple(float(x) for x in v[3:])


def texture_colorspace(space: str) -> tuple[str, str | None]:
    """How a MaterialX image whose file is in colour space ``space`` is decoded (usd_io.materials.texture_files): "sRGB"
    (srgb_texture: the sRGB curve), "raw" (no space, a linear Rec.709 alias, or a data texture), "mx:<space>" (read
    raw, then MaterialX's transform into linear Rec.709), with a note for a space MaterialX does not know (read
    raw, as MaterialX's own renderers read it)."""
    space = str(space or "")
    if space in colorspace.NO_CONVERSION:
        return "raw", None
    known = colorspace.materialx_space(space)
    if known is None:
        return "raw", f"colour space {space!r} is not one MaterialX's colour management knows (read as linear)"
    if known == "srgb_texture":
        return "sRGB", None
    if known == "lin_rec709":
        return "raw", None
    return f"mx:{known}", None


def nodedef(name: str):
    """The node definition called ``name`` (None when neither the libraries nor a read document define it)."""
    return definitions().getNodeDef(name) or None


def _register(doc: mx.Document) -> None:
    """Copy a document's own node definitions and their node-graph implementations into :func:`definitions`."""
    defs = definitions()
    for nd in doc.getNodeDefs():
        if not defs.getChild(nd.getName()):
            copy = defs.addNodeDef(nd.getName(), nd.getType(), nd.getNodeString())
            copy.copyContentFrom(nd)
            copy.setSourceUri(nd.getActiveSourceUri())  # relative file names stay relative to their document
    for ng in doc.getNodeGraphs():
        if ng.getNodeDefString() and not defs.getChild(ng.getName()):
            copy = defs.addNodeGraph(ng.getName())
            copy.copyContentFrom(ng)
            copy.setSourceUri(ng.getActiveSourceUri())


def read_document(path: str) -> mx.Document:
    """A ``.mtlx`` file read with its XIncludes (relative to its folder), upgraded to the library's version and
    resolved against the standard libraries."""
    import MaterialX as mx

    doc = mx.createDocument()
    mx.readFromXmlFile(doc, path, mx.FileSearchPath(os.path.dirname(path)))
    doc.setDataLibrary(_library())
    _register(doc)
    return doc


def _value(mx_type: str, text: str, base_dir: str):
    if mx_type == "filename":
        text = text.replace("\\", "/") if "\\" in text and not os.path.exists(text) else text
        return Sdf.AssetPath(text if os.path.isabs(text) else os.path.normpath(os.path.join(base_dir, text)))
    if mx_type == "string":
        return text
    if mx_type == "boolean":
        return text.strip().lower() == "true"
    nums = [float(x) for x in text.replace(",", " ").split()]
    if mx_type == "integer":
        return int(nums[0])
    if mx_type in ("matrix33", "matrix44"):  # row-major rows, as MaterialX writes them
        n = 3 if mx_type == "matrix33" else 4
        rows = [nums[i * n:(i + 1) * n] for i in range(n)]
        return Gf.Matrix3d(*rows) if n == 3 else Gf.Matrix4d(*rows)
    return nums[0] if len(nums) == 1 else tuple(nums)


def file_value(inp) -> Sdf.AssetPath:
    """A ``filename`` input's value as MaterialX resolves it (its ``fileprefix`` and the ``[token]`` s of its node,
    of its node graph and of the node definition that graph implements substituted) and made absolute against the
    document that authored it; resolved when the file exists."""
    src = inp.getActiveSourceUri()
    path = _value("filename", inp.getResolvedValueString(), os.path.dirname(src) if src else os.getcwd()).path
    return Sdf.AssetPath(path, path) if os.path.exists(path) else Sdf.AssetPath(path)


def _nodedef_name(node) -> str:
    nd = node.getNodeDef()
    return nd.getName() if nd else f"ND_{node.getCategory()}_{node.getType()}"


def _outputs(node) -> list:
    """(name, type) of a node's outputs: its definition's (several for separate3 & co.), else ``out``."""
    if node.getType() == "surfaceshader":
        return [("surface", "surfaceshader")]
    nd = node.getNodeDef()
    outs = [(o.getName(), o.getType()) for o in nd.getActiveOutputs()] if nd else []
    return outs if len(outs) > 1 else [("out", node.getType())]


def _out_prop(node, output: str) -> str:
    if node.getType() == "surfaceshader":
        return "outputs:surface"
    return f"outputs:{output or 'out'}"


def unit_scales(unittype: str) -> dict[str, float]:
    """The units of a MaterialX unit type (``distance``: metres per unit; ``angle``: degrees per unit), from the
    standard libraries' ``<unitdef>`` s and the read documents' own."""
    key = f"units {unittype}"
    if key not in _LIB:
        scales = {}
        for doc in (_library(), definitions()):
            for ud in doc.getUnitDefs():
                if ud.getUnitType() == unittype:
                    for u in ud.getUnits():
                        try:
                            scales[u.getName()] = float(u.getAttribute("scale"))
                        except ValueError:
                            pass
        _LIB[key] = scales
    return _LIB[key]


def unit_factor(inp, node, meters_per_unit: float) -> float:
    """What a value authored in ``inp``'s ``unit`` is multiplied by (MaterialX's "Units"): converted into the
    unit its node definition declares for that input, else, for a distance, into the scene's unit (the stage's
    metres per unit). 1 when there is no unit or nothing to convert to."""
    unit = inp.getUnit()
    if not unit:
        return 1.0
    nd = node.getNodeDef() if node is not None and hasattr(node, "getNodeDef") else None
    ndi = nd.getActiveInput(inp.getName()) if nd is not None else None
    unittype = inp.getUnitType() or (ndi.getUnitType() if ndi is not None else "")
    scales = unit_scales(unittype) if unittype else {}
    if unit not in scales:
        return 1.0
    target = ndi.getUnit() if ndi is not None and ndi.getUnit() in scales else None
    if target is not None:
        return scales[unit] / scales[target]
    if unittype == "distance" and meters_per_unit > 0:
        return scales[unit] / meters_per_unit
    return 1.0


class _Writer:
    def __init__(self, doc, base_dir: str, meters_per_unit: float = 1.0):
        self.doc, self.base_dir, self.meters_per_unit = doc, base_dir, meters_per_unit
        self.layer = Sdf.Layer.CreateAnonymous(".usda")

    def prim(self, path: Sdf.Path, type_name: str) -> Sdf.PrimSpec:
        Sdf.CreatePrimInLayer(self.layer, path)
        spec = self.layer.GetPrimAtPath(path)
        spec.specifier = Sdf.SpecifierDef
        spec.typeName = type_name
        return spec

    @staticmethod
    def attr(spec, name, mx_type):
        return Sdf.AttributeSpec(spec, name, TYPES.get(mx_type, Sdf.ValueTypeNames.Token))

    def shader(self, parent: Sdf.Path, node, graph_path: Sdf.Path | None) -> Sdf.Path:
        """One node as a Shader under ``parent``; its upstream nodes (in the node's own scope) too."""
        path = parent.AppendChild(node.getName())
        if self.layer.GetPrimAtPath(path):
            return path
        spec = self.prim(path, "Shader")
        ident = Sdf.AttributeSpec(spec, "info:id", Sdf.ValueTypeNames.Token, variability=Sdf.VariabilityUniform)
        ident.default = _nodedef_name(node)
        for name, mx_type in _outputs(node):
            self.attr(spec, f"outputs:{name}", mx_type)
        for inp in node.getInputs():
            self.input(spec, path, inp, graph_path)
        return path

    def input(self, spec, owner: Sdf.Path, inp, graph_path) -> None:
        """One input: a connection to a node of its scope or to a document-level node graph, an interface
        connection to its node graph's input, or a value."""
        mx_type = inp.getType() or "float"
        a = self.attr(spec, f"inputs:{inp.getName()}", mx_type)
        space = inp.getActiveColorSpace()
        if space:
            a.SetInfo("colorSpace", space)
        if inp.getDefaultGeomPropString():  # a node graph's interface input: read where no value is authored
            a.SetInfo("customData", {"mtlx:defaultgeomprop": inp.getDefaultGeomPropString()})
        scope = inp.getParent().getParent()  # the node's node graph or the document
        up = scope.getNode(inp.getNodeName()) if inp.getNodeName() else None
        output = inp.getOutputString()
        if up is None and not inp.getNodeName() and not inp.getNodeGraphString() and output:
            # output="name" alone: an <output> element of the node's scope (a document-level output), which names
            # the node (and the node's output) it passes on
            o = scope.getOutput(output) if hasattr(scope, "getOutput") else None
            if o is not None and o.getNodeName():
                up, output = scope.getNode(o.getNodeName()), o.getOutputString()
        if up is not None:
            where = owner.GetParentPath() if graph_path is None else graph_path
            p = self.shader(where, up, graph_path)
            a.connectionPathList.Prepend(p.AppendProperty(_out_prop(up, output)))
            return
        if inp.getNodeGraphString():
            g = self.doc.getNodeGraph(inp.getNodeGraphString())
            if g is not None:
                root = owner.GetParentPath() if graph_path is None else graph_path.GetParentPath()
                gp = self.graph(root, g)
                a.connectionPathList.Prepend(gp.AppendProperty(f"outputs:{inp.getOutputString() or 'out'}"))
            return
        if inp.getInterfaceName() and graph_path is not None:
            a.connectionPathList.Prepend(graph_path.AppendProperty(f"inputs:{inp.getInterfaceName()}"))
            return
        spec_node = inp.getParent()  # the node (or node graph) whose input this is: its definition's unit
        if inp.getInterfaceName() and graph_path is None:  # a top-level node reading a document-level input
            top = self.doc.getInput(inp.getInterfaceName())
            if top is not None and top.getValueString():
                inp = top
        if inp.getValueString():
            text = inp.getResolvedValueString() if mx_type == "filename" else inp.getValueString()
            src = inp.getActiveSourceUri()
            base = os.path.dirname(src) if src and os.path.isabs(src) else self.base_dir
            try:
                value = _value(mx_type, text, base)
                k = unit_factor(inp, spec_node, self.meters_per_unit) if mx_type in UNIT_TYPES else 1.0
                if k != 1.0:
                    value = value * k if isinstance(value, float) else tuple(x * k for x in value)
                a.default = value
            except (ValueError, IndexError, TypeError, Tf.ErrorException):  # a value USD cannot hold: unauthored
                pass

    def graph(self, parent: Sdf.Path, g) -> Sdf.Path:
        path = parent.AppendChild(g.getName())
        if self.layer.GetPrimAtPath(path):
            return path
        spec = self.prim(path, "NodeGraph")
        for inp in g.getInputs():  # the graph's interface
            self.input(spec, path, inp, None)
        for out in g.getOutputs():
            a = self.attr(spec, f"outputs:{out.getName()}", out.getType() or "float")
            node = g.getNode(out.getNodeName()) if out.getNodeName() else None
            if node is not None:
                up = self.shader(path, node, path)
                a.connectionPathList.Prepend(up.AppendProperty(_out_prop(node, out.getOutputString())))
        return path

    def material(self, m) -> None:
        path = Sdf.Path("/MaterialX/Materials").AppendChild(m.getName())
        spec = self.prim(path, "Material")
        out = Sdf.AttributeSpec(spec, "outputs:mtlx:surface", Sdf.ValueTypeNames.Token)
        for inp in m.getInputs():
            node = inp.getConnectedNode()
            # the front surface only: a backsurfaceshader (two-sided materials) is not one of usdMtlx's outputs
            if inp.getType() == "surfaceshader" and node is not None and inp.getName() == "surfaceshader":
                g = self.doc.getNodeGraph(inp.getNodeGraphString()) if inp.getNodeGraphString() else None
                if g is not None and g.getOutput(inp.getOutputString() or "out") is not None:
                    # a shader inside a node graph: the graph (its interface feeds the shader), its output
                    gp = self.graph(path, g)
                    out.connectionPathList.Prepend(gp.AppendProperty(f"outputs:{inp.getOutputString() or 'out'}"))
                    continue
                sh = self.shader(path, node, None)
                out.connectionPathList.Prepend(sh.AppendProperty("outputs:surface"))

    def translate(self) -> Sdf.Layer:
        self.prim(Sdf.Path("/MaterialX"), "Scope")
        self.prim(Sdf.Path("/MaterialX/Materials"), "Scope")
        for m in self.doc.getMaterialNodes():
            self.material(m)
        return self.layer


def translate(path: str, meters_per_unit: float = 1.0) -> Sdf.Layer | None:
    """The in-memory USD layer of a ``.mtlx`` document for a stage of ``meters_per_unit`` (the scene unit values
    with a distance ``unit`` are converted into; cached by both), or None when it cannot be read."""
    import MaterialX as mx

    key = (os.path.abspath(path), float(meters_per_unit))
    if key not in _LAYERS:
        try:
            _LAYERS[key] = _Writer(read_document(key[0]), os.path.dirname(key[0]), key[1]).translate()
        except (mx.Exception, mx.ExceptionFileMissing, mx.ExceptionParseError, mx.ExceptionFoundCycle,
                mx.ExceptionOrphanedElement, OSError, ValueError):  # a missing .mtlx: USD's own error names it
            _LAYERS[key] = None
    return _LAYERS[key]


def _mtlx_items(items, layer, meters_per_unit: float) -> tuple[list, bool]:
    """(the list with every .mtlx reference pointed at its translation, whether anything changed)."""
    out, changed = [], False
    for ref in items:
        if ref.assetPath.lower().endswith(".mtlx"):
            translated = translate(layer.ComputeAbsolutePath(ref.assetPath), meters_per_unit)
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
    mpu = stage_meters_per_unit(stage, lambda _msg: None)  # MaterialX's "scene unit"; the reader warns of a bad one
    with Sdf.ChangeBlock():
        for layer, p in specs:
            spec = layer.GetPrimAtPath(p)
            if spec is None or not spec.hasReferences:
                continue
            refs = spec.referenceList
            for which in ("explicitItems", "prependedItems", "appendedItems"):
                items, hit = _mtlx_items(list(getattr(refs, which)), layer, mpu)
                if hit:
                    setattr(refs, which, items)
                    changed += 1
    return changed

"""The materials :mod:`addon.shader_tree` translates, written as the tracer's shader graphs (tracer.shading.graph, the
IR of docs/materials-api.md) and compiled into rows (tracer.shading.compiler.add_graph).

Every material is a graph (written as it is), the default surface (no material) too: one ``principled_bsdf`` with
Blender's defaults (:func:`default_surface`). What a material's nodes become (addon/shader_tree.py):

    every parameter       its constant and, where a texture feeds it, a ``tracer.Texture`` (pixels shared by every
                          lookup of one image; wrap from the Extension; the Mapping node as the texture's UV
                          transform; scale/bias for normal maps) read in the UV set of the UV map its node names
    UV maps               UV set 0 is each mesh's active render map (a texture with no UV Map node); every other
                          map name a texture reads gets the next set index, filled per mesh by that name (a mesh
                          without it: the active map, one warning)
    vertex colours        ``Scene.colors`` from the Color Attribute the material names ('' = the mesh's render
                          colour), multiplied into the base colour per corner
    metallic, roughness   as they are: the tracer's Principled model splits a smooth lobe to the mirror ray itself;
                          ``k_m`` stays 0 (the seed's mirror weight is for scenes written for the notes)
    transmission          glass tinted by the base colour, as Cycles' Principled BSDF
"""

from __future__ import annotations

import numpy as np

from typing import NamedTuple

from .shader_tree import material_graph

from .bundled import tracer_module

add_graph = tracer_module("shading.compiler").add_graph
Graph = tracer_module("shading.graph").Graph


def default_surface(name: str = "__default__") -> Graph:
    """Blender's surface for geometry without a material: a Principled BSDF left at its defaults
    (tracer.shading.materials.PRINCIPLED_DEFAULTS, Blender's own)."""
    g = Graph(name)
    g.output(g.add("principled_bsdf")["BSDF"])
    return g


class Corners(NamedTuple):
    """A mesh's per-corner data for ``SceneBuilder.add_mesh``: UV sets {index: (T, 3, 2)} and colours (T, 3, 3)."""

    uv_sets: dict
    colors: np.ndarray | None = None

    def kwargs(self) -> dict:
        return {"uv_sets": self.uv_sets or None, "colors": self.colors}

    def repeated(self, k: int, mirrored: bool) -> "Corners":
        """The data of K instances of the mesh, corners turned as a mirroring placement turns them."""
        def rep(a):
            a = np.broadcast_to(a, (k,) + a.shape).reshape((-1,) + a.shape[1:])
            return a[:, [0, 2, 1]] if mirrored else a
        return Corners({i: rep(a) for i, a in self.uv_sets.items()},
                       None if self.colors is None else rep(self.colors))


NO_CORNERS = Corners({})


class MaterialWriter:
    """Reads each Blender material once and adds its row; gives each mesh its UV sets and vertex colours."""

    def __init__(self, builder, warnings: list):
        self.b = builder
        self.warnings = warnings
        self.images: dict = {}  # image name -> (H, W, 4) pixels (shared by materials and the world)
        self.fields: dict[int, tuple[str, dict]] = {}  # row -> (material name, {"graph": its Graph})
        self.uv_sets: dict[str, int] = {"": 0}  # UV map name ('' = the mesh's active render map) -> UV set
        self._rows: dict[str, int] = {}
        self._said: set = set()
        self.default_row = self._add("__default__", default_surface())

    def warn(self, message: str) -> None:
        if message not in self._said:
            self._said.add(message)
            self.warnings.append(message)

    # ------------------------------------------------------------------ materials
    def row(self, material) -> int:
        if material is None:
            return self.default_row
        if material.name not in self._rows:
            self._rows[material.name] = self._add(material.name, material_graph(material, self.warn, self.images))
        return self._rows[material.name]

    def _add(self, name: str, graph) -> int:
        if isinstance(graph, dict):  # what self.fields keeps of a graph (addon/sync.py hands it back)
            graph = graph["graph"]
        row = add_graph(self.b, graph, self.warn, self.uv_index, name=name)
        self.fields.setdefault(row, (name, {"graph": graph}))
        return row

    def uv_index(self, name) -> int:
        """UV set index of a UV map name ('' = the mesh's active render map, set 0); new names get the next."""
        if isinstance(name, (int, np.integer)):
            return int(name)
        return self.uv_sets.setdefault(name or "", len(self.uv_sets))

    # ------------------------------------------------------------------ meshes
    def mesh_inputs(self, label: str, rows, g: dict):
        """(per-triangle material rows, :class:`Corners`) for a mesh of ``mesh_arrays`` ``g`` whose triangles use
        material ``rows``: the UV maps its materials' textures read, as UV sets, and the Color Attribute they name."""
        n = len(g["triangles"])
        rows = np.broadcast_to(np.asarray(rows, np.int64), (n,)).copy()
        layers, default = g.get("uv_layers", {}), g.get("uv_default")
        active = layers.get(default) if default is not None else None
        sets = {}
        if active is not None:
            sets[0] = active
        for name, k in self.uv_sets.items():
            if not name:
                continue
            if name in layers:
                sets[k] = layers[name]
            elif active is not None and self._reads_uv_set(rows, k):
                self.warn(f"{label}: UV map {name!r} not found; the active one ({default!r}) is used")
                sets[k] = active
        colors, chosen = None, None
        for row in np.unique(rows):
            name, f = self.fields.get(int(row), ("", {}))
            vc = _graph_color(f["graph"]) if "graph" in f else None
            if vc is None:
                continue
            attr = vc or g.get("color_default")
            if chosen is not None and attr != chosen:
                self.warn(f"{label}: materials read different Color Attributes ({chosen!r}, {attr!r}); "
                          f"{chosen!r} is used for all")
                continue
            if attr not in g.get("colors", {}):
                self.warn(f"material {name!r} on {label!r}: Color Attribute {vc or '(active)'!r} not found "
                          "on the mesh (white used)")
                continue
            chosen = attr
            colors = np.ascontiguousarray(g["colors"][attr][..., :3], np.float32)
        return rows, Corners(sets, colors)

    def _reads_uv_set(self, rows, k: int) -> bool:
        """Does a material among ``rows`` read a texture in UV set k?"""
        for row in np.unique(rows):
            _, f = self.fields.get(int(row), ("", {}))
            if "graph" in f and k in _graph_uv_sets(f["graph"], self.uv_sets):
                return True
        return False


def _graph_color(graph: Graph):
    """The Color Attribute name a graph reads ('' = the active one), or None."""
    for node in graph.nodes.values():
        if node.type == "vertex_color":
            return node.param("layer_name") or ""
        if node.type == "attribute" and node.param("attribute_type") in (None, "GEOMETRY"):
            return node.param("attribute") or ""
    return None


def _graph_uv_sets(graph: Graph, uv_sets: dict) -> set:
    names = {n.param("attribute") or "" for n in graph.nodes.values() if n.type == "uvmap"}
    names |= {n.param("uv_map") or "" for n in graph.nodes.values() if n.type == "normal_map"}
    return {uv_sets[n] for n in names if n in uv_sets}

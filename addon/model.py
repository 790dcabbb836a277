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
    vertex colours        ``Scene.colors``: per triangle, the attribute its material names (a Color Attribute, or
                          any generic attribute an Attribute node names; '' = the mesh's render colour); one
                          the mesh lacks reads black, as in Cycles
    metallic, roughness   as they are: the tracer's Principled model splits a smooth lobe to the mirror ray itself;
                          ``k_m`` stays 0 (the seed's mirror weight is for scenes written for the notes)
    transmission          glass tinted by the base colour, as Cycles' Principled BSDF
"""

from __future__ import annotations

import numpy as np

from typing import NamedTuple

from .shader_tree import ALPHA_UV, material_graph
from .volume import volume_of

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
        self.volumes: dict[int, np.ndarray] = {}  # row -> (σ RGB, E RGB) of its Volume output (addon/volume.py)
        self.open_media: set = set()  # rows whose medium is on a mesh that is not closed (dropped)
        self.carried_media: set = set()  # rows whose medium is on an inside-out closed mesh (carried by the rays)
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
            vol = volume_of(material, self.warn)
            if vol is not None:
                self.volumes[self._rows[material.name]] = vol
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
            if name.startswith(ALPHA_UV):  # a colour attribute's alpha (addon/shader_tree.py, ALPHA_UV)
                if self._reads_uv_set(rows, k):
                    sets[k] = _alpha_set(name, g, n)
                continue
            if name in layers:
                sets[k] = layers[name]
            elif active is not None and self._reads_uv_set(rows, k):
                self.warn(f"{label}: UV map {name!r} not found; the active one ({default!r}) is used")
                sets[k] = active
        colors = self._colors(label, rows, g)
        if self.volumes:
            self._open_media(label, rows, g)
        return rows, Corners(sets, colors)

    def _open_media(self, label: str, rows, g: dict) -> None:
        """A medium needs a closed mesh (Cycles: "volumes need closed meshes"): a mesh with open edges (a water
        plane) has no inside; its material's medium is dropped, one warning. A closed mesh turned inside out (a
        water box whose normals point in) is what Cycles' volume stack makes of it, measured through bpy: a ray
        enters the medium where it crosses a face against its normal, i.e. on its way *out* of the box, and
        carries it until it crosses one of the mesh's faces again (the box's inside stays clear): the material's
        medium is carried by the rays (``tracer.Scene.material_volume_carried``)."""
        media = set(int(r) for r in np.unique(rows)) & self.volumes.keys()
        media -= self.open_media
        if not media:
            return
        if closed_mesh(g):
            return
        if closed_mesh(g, inside_out=True):
            self.carried_media.update(media)
            return
        for row in media:
            self.open_media.add(row)
            self.warn(f"material {self.fields.get(row, ('?',))[0]!r}: its Volume output is on {label!r}, a mesh "
                      "that is not closed; the medium is not rendered (a volume needs a closed mesh)")

    def attribute_names(self, rows) -> frozenset:
        """The attribute names the materials of ``rows`` read by name (Attribute and Color Attribute nodes; '' =
        the render colour is not a name): :func:`addon.export.mesh_arrays` reads those that are not Color
        Attributes from the mesh's generic attributes."""
        names = set()
        for row in set(int(r) for r in np.atleast_1d(rows)):
            _, f = self.fields.get(row, ("", {}))
            if "graph" in f:
                names.update(n for n in _graph_colors(f["graph"]) if n)
        return frozenset(names)

    def _colors(self, label: str, rows: np.ndarray, g: dict):
        """(T, 3, 3) per-corner colours: each triangle gets the attribute *its* material reads (materials of one
        mesh may read different ones: a glTF import names one per primitive), as Cycles' Attribute / Color Attribute
        nodes read it; an attribute the mesh does not have reads black, as in Cycles (measured: Color (0, 0, 0),
        Fac 0). None when no material of the mesh reads one."""
        have = g.get("colors", {})
        chosen = {}
        for row in np.unique(rows):
            name, f = self.fields.get(int(row), ("", {}))
            names = _graph_colors(f["graph"]) if "graph" in f else []
            if not names:
                continue
            if len(set(names)) > 1:
                self.warn(f"material {name!r}: reads several attributes ({', '.join(repr(n) for n in names)}); "
                          f"{names[0] or '(active)'!r} is used for all of them")
            attr = names[0] or g.get("color_default")
            if attr in g.get("uv_layers", {}) and attr not in have:  # an Attribute node naming a UV map: (u, v, 0)
                uv = g["uv_layers"][attr]
                have = dict(have, **{attr: np.concatenate([uv, np.zeros(uv.shape[:2] + (1,), np.float32)], -1)})
            if attr not in have:
                self.warn(f"material {name!r} on {label!r}: attribute {names[0] or '(active Color Attribute)'!r} "
                          "is not on the mesh; it reads black, as in Cycles")
                attr = None
            chosen[int(row)] = attr
        if not chosen:
            return None
        out = np.zeros((len(rows), 3, 3), np.float32)
        for row, attr in chosen.items():
            if attr is not None:
                sel = rows == row
                out[sel] = have[attr][sel][..., :3]
        return out

    def _reads_uv_set(self, rows, k: int) -> bool:
        """Does a material among ``rows`` read a texture in UV set k?"""
        for row in np.unique(rows):
            _, f = self.fields.get(int(row), ("", {}))
            if "graph" in f and k in _graph_uv_sets(f["graph"], self.uv_sets):
                return True
        return False


def closed_mesh(g: dict, inside_out: bool = False) -> bool:
    """The mesh bounds a volume with its normals outwards: every edge of its triangles (vertices welded by position:
    importers split them at seams) is shared by exactly two, and the signed volume is positive (``inside_out``:
    negative, the normals inwards). Cached in ``g``."""
    if inside_out:
        return closed_mesh(g, False) is False and g.get("closed_edges", False)
    if "closed" not in g:
        v = np.asarray(g["vertices"], np.float64)
        t = np.asarray(g["triangles"], np.int64)
        ok = len(t) > 0
        if ok:
            span = float(np.ptp(v, axis=0).max()) or 1.0
            _, weld = np.unique(np.round(v / (span * 1e-6)).astype(np.int64), axis=0, return_inverse=True)
            w = weld.reshape(-1)[t]
            e = np.sort(np.concatenate([w[:, [0, 1]], w[:, [1, 2]], w[:, [2, 0]]]), axis=1)
            _, counts = np.unique(e[:, 0] * (int(w.max()) + 1) + e[:, 1], return_counts=True)
            ok = bool(np.all(counts == 2))
            g["closed_edges"] = ok
            if ok:
                a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
                ok = float(np.einsum("ij,ij->", a, np.cross(b, c))) > 0.0
        g["closed"] = ok
    return g["closed"]


def _alpha_set(name: str, g: dict, n: int) -> np.ndarray:
    """(T, 3, 2) UV set of a colour attribute's alpha (x; y = 0) for pseudo UV map ``name``: the alpha of the
    attribute (a generic one without alpha: 1); where the mesh lacks it, 0 for a Color Attribute node and 1 for an
    Attribute node (Cycles, measured)."""
    kind, _, attr = name[len(ALPHA_UV):].partition(":")
    c = g.get("colors", {}).get(attr or g.get("color_default"))
    out = np.zeros((n, 3, 2), np.float32)
    if c is not None:
        out[..., 0] = c[..., 3]
    elif kind == "attr":
        out[..., 0] = 1.0
    return out


def _graph_colors(graph: Graph) -> list:
    """The attribute names a graph reads through Attribute (Geometry type) and Color Attribute nodes, in node order
    ('' = the render Color Attribute); [] when it reads none."""
    out = []
    for node in graph.nodes.values():
        if node.type == "vertex_color":
            out.append(node.param("layer_name") or "")
        elif node.type == "attribute" and node.param("attribute_type") in (None, "GEOMETRY"):
            out.append(node.param("attribute") or "")
    return out


def _graph_uv_sets(graph: Graph, uv_sets: dict) -> set:
    names = {n.param("attribute") or "" for n in graph.nodes.values() if n.type == "uvmap"}
    names |= {n.param("uv_map") or "" for n in graph.nodes.values() if n.type == "normal_map"}
    return {uv_sets[n] for n in names if n in uv_sets}

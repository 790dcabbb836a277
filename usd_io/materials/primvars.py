"""Per-mesh primvars a material reads: texture coordinate sets and a vertex colour.

Texture coordinates. Each UV set a material names gets one index in ``Scene.uv_sets`` for the whole stage; set 0 is
the *default* set of each mesh, used by every UsdUVTexture whose ``st`` is not connected, and by those that read
``st`` by name. The rule for a mesh's default set (docs/usd.md):

    primvars:st if the mesh has it; otherwise its only texture-coordinate primvar (a 2-component float/double/half
    primvar, e.g. Maya's ``map1`` in the usd-wg Vehicles); with several and no ``st``, the first one whose role is
    texCoord, in name order (one warning naming the choice).

A mesh without the primvar a texture reads gets (0, 0) there, the fallback of UsdPrimvarReader_float2, as in Storm.

Vertex colour. A ``UsdPrimvarReader_float3`` (or ``_float4``, first three components) on diffuseColor reads a
colour primvar — most often ``displayColor`` — of any interpolation (constant, uniform, vertex, varying,
faceVarying, indexed), expanded per corner into ``Scene.colors``; without the primvar, the reader's fallback.
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf, Usd, UsdGeom

from ..geometry.mesh import Triangulation, expand_primvar, flattened

#: The name of UV set 0 in ``Scene.uv_sets``: each mesh's default set (st, or its only UV primvar: the rule above).
DEFAULT_UV = "<default>"

_UV_TYPES = {Sdf.ValueTypeNames.TexCoord2fArray, Sdf.ValueTypeNames.TexCoord2dArray,
             Sdf.ValueTypeNames.TexCoord2hArray, Sdf.ValueTypeNames.Float2Array, Sdf.ValueTypeNames.Double2Array,
             Sdf.ValueTypeNames.Half2Array}
_TEXCOORD = {Sdf.ValueTypeNames.TexCoord2fArray, Sdf.ValueTypeNames.TexCoord2dArray,
             Sdf.ValueTypeNames.TexCoord2hArray}


def uv_primvar_names(prim) -> list:
    """Names of the 2-component array primvars of a prim that hold values (texCoord role first, then by name)."""
    found = []
    for pv in UsdGeom.PrimvarsAPI(prim).GetPrimvars():
        if pv.GetTypeName() in _UV_TYPES and pv.HasValue():
            found.append((pv.GetTypeName() not in _TEXCOORD, pv.GetPrimvarName()))
    return [str(n) for _role, n in sorted(found)]


def default_uv_name(prim, warn=None) -> str | None:
    """The primvar a mesh's default UV set comes from (see the module docstring), or None."""
    names = uv_primvar_names(prim)
    if "st" in names:
        return "st"
    if not names:
        return None
    if len(names) > 1 and warn is not None:
        warn(f"{prim.GetPath()}: no primvars:st and several texture-coordinate primvars {names}; "
             f"textures without an st connection read {names[0]!r}")
    return names[0]


def corner_values(prim, name: str, tri, n_points: int, n_face_vertices: int, time, width: int):
    """A primvar of any interpolation as per-corner (T, 3, width) float32, or (None, reason)."""
    pv = find_primvar(prim, name)
    if pv is None:
        return None, None
    vals = flattened(pv, time)
    if vals is None or len(vals) == 0:
        return None, None
    v = np.asarray(vals, dtype=np.float64).reshape(len(vals), -1)
    if v.shape[1] < width:
        v = np.concatenate([v, np.repeat(v[:, -1:], width - v.shape[1], axis=1)], axis=1)
    out, why = expand_primvar(v[:, :width], pv.GetInterpolation(), tri, n_points, n_face_vertices,
                              f"{prim.GetPath()} primvars:{name}")
    return (None if out is None else out.astype(np.float32)), why


def find_primvar(prim, name):
    """``primvars:name`` of the prim, or a constant one inherited from an ancestor (UsdGeomPrimvarsAPI's
    inheritance: displayColor authored on an Xform colours the gprims below it); None without a value."""
    pv = UsdGeom.PrimvarsAPI(prim).FindPrimvarWithInheritance(name)
    return pv if pv and pv.HasValue() else None


def gprim_colors(prim, data, name, fallback, time, warn):
    """Per-corner (T, 3, 3) colours of a gprim that is not a Mesh: constant everywhere; on Points and curves, per
    point (vertex, varying; on Points every non-constant interpolation is per point) through the vertices' source
    points and per curve (uniform) through the triangles' faces; on implicit shapes, non-constant values are averaged
    (one warning)."""
    pv = find_primvar(prim, name)
    vals = flattened(pv, time) if pv is not None else None
    n_tri = len(data.triangles)
    if vals is None or not len(vals):
        return np.broadcast_to(np.asarray(fallback, np.float32), (n_tri, 3, 3)).copy()
    v = np.asarray(vals, np.float64).reshape(len(vals), -1)
    v = np.concatenate([v, np.repeat(v[:, -1:], max(0, 3 - v.shape[1]), axis=1)], axis=1)[:, :3]
    interp = pv.GetInterpolation()
    source = getattr(data, "source_points", None)
    n_points = None if source is None or not len(source) else int(source.max()) + 1
    weights = getattr(data, "point_weights", None)
    if len(v) == 1 or interp == UsdGeom.Tokens.constant:
        out = np.broadcast_to(v[0], (n_tri, 3, 3))
    elif weights is not None and len(v) == weights.shape[1] and interp in (UsdGeom.Tokens.vertex,
                                                                            UsdGeom.Tokens.varying):
        out = (weights @ v)[data.triangles]  # a NURBS patch: the values blended like the points
    elif source is not None and len(v) == n_points and (interp in (UsdGeom.Tokens.vertex, UsdGeom.Tokens.varying)
                                                         or prim.IsA(UsdGeom.Points)):
        out = v[source[data.triangles]]
    elif interp == UsdGeom.Tokens.uniform and len(v) == data.n_faces and source is not None:
        out = np.repeat(v[data.faces][:, None], 3, axis=1)
    else:
        if np.ptp(v, axis=0).max() > 0:
            warn(f"{prim.GetPath()}: primvars:{name} with {interp} interpolation ({len(v)} values) on a "
                 f"{prim.GetTypeName()} is averaged")
        out = np.broadcast_to(v.mean(axis=0), (n_tri, 3, 3))
    return np.ascontiguousarray(out, np.float32)


def mesh_primvars(prim, data, needs, uv_set_names: list, time, warn):
    """(uv_sets {set index: (T, 3, 2)}, colors (T, 3, 3) or None): the per-corner primvars a mesh's materials read
    (set 0, the mesh's default set, always). Gprims (no primvars) give a constant colour fallback only."""
    colors = None
    refined = getattr(data, "primvars", None)
    if refined is not None:  # a refined subdivision surface: its primvars came through the refinement (mesh.py)
        return _refined_primvars(prim, refined, len(data.triangles), needs, uv_set_names, warn)
    if not prim.IsA(UsdGeom.Mesh) or getattr(data, "corners", None) is None:
        if needs.color is not None:
            colors = gprim_colors(prim, data, *needs.color, time, warn)
        # a refined subdivision surface carries its st through the refinement (usd_io/geometry/mesh.py): that is set 0
        sets = {} if getattr(data, "uvs", None) is None else {0: np.asarray(data.uvs, np.float32)}
        name = default_uv_name(prim, warn) if not sets and prim.IsA(UsdGeom.Curves) else None
        if name:  # curves' st per curve (uniform) or per point, the way their colours are read
            sets[0] = gprim_colors(prim, data, name, (0.0, 0.0, 0.0), time, warn)[..., :2].astype(np.float32)
        _absent_coordinates(prim, sets, needs, uv_set_names, len(data.triangles), warn)
        return sets, colors
    tri = Triangulation(data.triangles, data.corners, data.faces, data.n_faces)
    n_points, n_fv = len(data.points), data.n_face_vertices
    sets = {}
    for name in needs.uv_sets | {uv_set_names[0]}:
        index = uv_set_names.index(name)
        pv_name = default_uv_name(prim, warn) if index == 0 else name
        if pv_name is None:
            continue
        if pv_name == "st" and data.uvs is not None:  # read_mesh expanded it already
            sets[index] = np.asarray(data.uvs, np.float32)
            continue
        uv, why = corner_values(prim, pv_name, tri, n_points, n_fv, time, 2)
        if why:
            warn(f"{why} (ignored)")
        if uv is not None:
            sets[index] = uv
    _absent_coordinates(prim, sets, needs, uv_set_names, len(data.triangles), warn)
    if needs.color is not None:
        name, fallback = needs.color
        colors, why = corner_values(prim, name, tri, n_points, n_fv, time, 3)
        if why:
            warn(f"{why} (its fallback is used)")
        if colors is None:
            colors = np.broadcast_to(np.asarray(fallback, np.float32), (len(data.triangles), 3, 3)).copy()
    return sets, colors


def _absent_coordinates(prim, sets: dict, needs, uv_set_names: list, n_triangles: int, warn) -> None:
    """A texture's coordinates the gprim does not have (an implicit Sphere, a mesh without ``primvars:st``) read
    (0, 0): the value a UsdPrimvarReader_float2 gives for an absent primvar (its fallback) and UsdUVTexture's
    own ``st`` default — the texel at the image's corner, as Storm shows it, not the texture's fallback colour.
    Named in one warning."""
    missing = [name for name in sorted(needs.uv_sets) if uv_set_names.index(name) not in sets]
    if not missing:
        return
    for name in missing:
        sets[uv_set_names.index(name)] = np.zeros((n_triangles, 3, 2), np.float32)
    shown = ", ".join("st" if n == DEFAULT_UV else n for n in missing)
    warn(f"{prim.GetPath()}: no texture coordinates ({shown}) for its material's textures: read at (0, 0), "
         "a primvar reader's fallback")


def _refined_primvars(prim, refined: dict, n_triangles: int, needs, uv_set_names: list, warn):
    """``mesh_primvars`` of a refined subdivision surface, from its per-corner refined primvars."""
    sets = {}
    for name in needs.uv_sets | {uv_set_names[0]}:
        index = uv_set_names.index(name)
        pv_name = default_uv_name(prim, warn) if index == 0 else name
        if pv_name in refined and refined[pv_name].shape[-1] >= 2:
            sets[index] = np.ascontiguousarray(refined[pv_name][..., :2], np.float32)
    colors = None
    if needs.color is not None:
        name, fallback = needs.color
        if name in refined:
            c = refined[name]
            colors = np.concatenate([c, np.repeat(c[..., -1:], max(0, 3 - c.shape[-1]), axis=-1)], axis=-1)[..., :3]
            colors = np.ascontiguousarray(colors, np.float32)
        else:  # not refined: absent, or a constant one inherited from an ancestor
            pv = find_primvar(prim, name)
            vals = flattened(pv, Usd.TimeCode.Default()) if pv is not None and pv.GetInterpolation() == "constant" else None
            c = fallback if vals is None or not len(vals) else (tuple(np.ravel(vals[0])) * 3)[:3]
            colors = np.broadcast_to(np.asarray(c, np.float32), (n_triangles, 3, 3)).copy()
    return sets, colors


def replicate_corners(mats: np.ndarray, extra: dict) -> dict:
    """``mesh_primvars`` output for K instances (``mats`` (K, 4, 4)): per-corner arrays repeated, with the corner
    order turned where a matrix mirrors (as ``instancing.replicate`` turns the triangles)."""
    k = len(mats)
    flip = np.linalg.det(np.asarray(mats)[:, :3, :3]) < 0

    def rep(a):
        r = np.repeat(np.asarray(a)[None], k, axis=0)
        r[flip] = r[flip][:, :, [0, 2, 1]]
        return r.reshape((-1,) + r.shape[2:])

    out = {}
    if "uv_sets" in extra:
        out["uv_sets"] = {i: rep(a) for i, a in extra["uv_sets"].items()}
        if 0 in out["uv_sets"]:
            out["uvs"] = out["uv_sets"][0]
    elif extra.get("uvs") is not None:
        out["uvs"] = rep(extra["uvs"])
    if "colors" in extra:
        out["colors"] = rep(extra["colors"])
    return out

"""Catmull-Clark subdivision (tracer.subdivision) against closed forms and Blender's Subdivision Surface modifier,
and subdivision surfaces read from USD (usd_io: --complexity)."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom, UsdLux

from tracer import RenderSettings, render
from tracer.subdivision import catmull_clark

CUBE_V = np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], float)
CUBE_F = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]


def _same_points(a, b, tol=1e-4):
    d = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=-1)
    return d.min(axis=1).max() < tol and d.min(axis=0).max() < tol


def test_cube_level_one_closed_form():
    """Corners (n = 3): V' = (Q + 2R)/3 = 5/9 of the corner; edge points (v0 + v1 + F_a + F_b)/4; face centres."""
    r = catmull_clark(CUBE_V, [4] * 6, np.ravel(CUBE_F), 1)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * 5 / 9
    edges = np.array([p for p in ([0.75 * s, 0.75 * t, 0] for s in (-1, 1) for t in (-1, 1))] +
                     [[0.75 * s, 0, 0.75 * t] for s in (-1, 1) for t in (-1, 1)] +
                     [[0, 0.75 * s, 0.75 * t] for s in (-1, 1) for t in (-1, 1)])
    faces = np.concatenate([np.eye(3), -np.eye(3)])
    assert r.indices.shape == (24, 4) and len(r.points) == 26
    assert _same_points(r.points, np.concatenate([corners, edges, faces]), 1e-12)


def test_a_flat_grid_stays_flat_and_keeps_its_corners():
    n = 3
    g = np.array([[x, y, 0.0] for y in range(n + 1) for x in range(n + 1)])
    f = [[y * (n + 1) + x, y * (n + 1) + x + 1, (y + 1) * (n + 1) + x + 1, (y + 1) * (n + 1) + x]
         for y in range(n) for x in range(n)]
    r = catmull_clark(g, [4] * len(f), np.ravel(f), 2)
    assert np.all(r.points[:, 2] == 0)
    for c in ([0, 0, 0], [n, 0, 0], [0, n, 0], [n, n, 0]):  # edgeAndCorner: corners stay put
        assert np.min(np.linalg.norm(r.points - c, axis=1)) < 1e-12
    # a boundary vertex (1, 0) moves by the (1, 6, 1)/8 rule: its neighbours are (0, 0) and (2, 0): it stays
    assert np.min(np.linalg.norm(r.points - [1, 0, 0], axis=1)) < 1e-12


def test_face_varying_uvs_refine_linearly():
    """A single unit square with uv = (x, y): one level keeps its corners, puts edge points at the midpoints and
    the face point at the centre, so the (linearly refined) uv of every new corner equals its position."""
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    r = catmull_clark(v, [4], [0, 1, 2, 3], 1, fvar=v[:, :2] * 1.0)
    assert r.fvar.shape == (4, 4, 2)
    np.testing.assert_allclose(r.fvar, r.points[r.indices][..., :2], atol=1e-12)
    # and vertex data refines with the points by the same rules
    r2 = catmull_clark(v, [4], [0, 1, 2, 3], 1, vertex_data=v[:, :1] * 2.0)
    np.testing.assert_allclose(r2.vertex_data[:, 0], 2.0 * r2.points[:, 0], atol=1e-12)


def _blender_subsurf(verts, faces, levels):
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    mesh = bpy.data.meshes.new("cage")
    mesh.from_pydata([tuple(map(float, p)) for p in verts], [], [list(map(int, f)) for f in faces])
    mesh.update()
    obj = bpy.data.objects.new("cage", mesh)
    bpy.context.scene.collection.objects.link(obj)
    mod = obj.modifiers.new("subsurf", "SUBSURF")
    mod.subdivision_type = "CATMULL_CLARK"
    mod.levels = mod.render_levels = levels
    mod.use_limit_surface = False  # the refined control points, not their limit positions
    mod.boundary_smooth = "PRESERVE_CORNERS"  # USD's interpolateBoundary = edgeAndCorner
    mod.use_creases = False
    dg = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(dg).to_mesh()
    pts = np.array([v.co[:] for v in ev.vertices])
    obj.evaluated_get(dg).to_mesh_clear()
    return pts


def _bumpy_grid(n=4):
    g = np.array([[x, y, 0.3 * np.sin(x) * np.cos(y)] for y in range(n + 1) for x in range(n + 1)], float)
    f = [[y * (n + 1) + x, y * (n + 1) + x + 1, (y + 1) * (n + 1) + x + 1, (y + 1) * (n + 1) + x]
         for y in range(n) for x in range(n)]
    return g, f


def _mixed():
    """A pentagon, a triangle and quads sharing edges, with a boundary."""
    v = np.array([[0, 0, 0], [2, 0, 0.2], [3, 1, 0], [1.5, 2, 0.4], [-0.5, 1.2, 0], [3, 3, 0.3], [1, 3.5, 0],
                  [-1, 3, 0.2]], float)
    f = [[0, 1, 2, 3, 4], [2, 5, 3], [3, 5, 6], [4, 3, 6, 7]]
    return v, f


@pytest.mark.parametrize("level", [1, 2])
@pytest.mark.parametrize("cage", ["cube", "bumpy_grid", "mixed"])
def test_same_points_as_blenders_subdivision_surface_modifier(cage, level):
    verts, faces = {"cube": (CUBE_V, CUBE_F), "bumpy_grid": _bumpy_grid(), "mixed": _mixed()}[cage]
    counts = [len(f) for f in faces]
    ours = catmull_clark(verts, counts, np.concatenate(faces), level).points
    theirs = _blender_subsurf(verts, faces, level)
    assert len(ours) == len(theirs)
    assert _same_points(ours, theirs, 1e-4)


def _stage(path, up="Y", scheme=None):
    s = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(s, up)
    m = UsdGeom.Mesh.Define(s, "/Asset/Cube")
    m.CreatePointsAttr([Gf.Vec3f(*p) for p in CUBE_V])
    m.CreateFaceVertexCountsAttr([4] * 6)
    m.CreateFaceVertexIndicesAttr([int(i) for i in np.ravel(CUBE_F)])
    if scheme:
        m.CreateSubdivisionSchemeAttr(scheme)
    s.GetRootLayer().Save()
    return str(path)


def test_usd_subdivision_surfaces_refine_by_complexity(tmp_path):
    """USD's default subdivisionScheme is catmullClark: medium refines once (24 quads), high twice (96); a mesh
    marked "none" stays its cage; the refined cube is rounder (its corners pulled in)."""
    from usd_io import load_stage

    path = _stage(tmp_path / "cube.usda")
    tris = {c: len(load_stage(path, width=8, complexity=c)[0].triangles) for c in ("low", "medium", "high")}
    assert tris == {"low": 12, "medium": 48, "high": 192}
    flat = _stage(tmp_path / "flat.usda", scheme="none")
    assert len(load_stage(flat, width=8, complexity="high")[0].triangles) == 12
    scene, _ = load_stage(path, width=8, complexity="high")
    assert np.abs(scene.vertices).max() < 0.95  # the cage's corners at 1 are pulled towards the limit surface


def test_a_y_up_unlit_subdivided_stage_renders_lit_and_smooth(tmp_path):
    """The issue's acceptance stage: Y-up, no lights (the default headlight), a subdivided mesh: a lit, finite
    picture whose silhouette is rounder than the cage's."""
    from usd_io import load_stage

    path = _stage(tmp_path / "asset.usda")
    img = {}
    for c in ("low", "high"):
        scene, info = load_stage(path, width=48, height=48, complexity=c)
        assert info.default_lighting
        img[c] = render(scene, RenderSettings(width=48, height=48, samples=1)).rgba
    for a in img.values():
        assert np.all(np.isfinite(a)) and a[..., :3].max() > 0.3
    covered = {c: (a[..., :3].max(axis=-1) > 0.12).sum() for c, a in img.items()}
    assert covered["high"] < covered["low"]  # the rounded shape covers fewer pixels than the cube cage

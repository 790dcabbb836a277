"""``python -m bench.subdivision``: uniform refinement of a 100 k-face cage (issue #11), ours against peers in the
same run.

Cages: a bumpy 317×317 quad grid (100 489 quads, with a boundary) and the same grid split into 100 352 triangles
(224×224×2). Ours: ``tracer.geometry.subdivision.refine`` at levels 1 and 2 (Catmull-Clark with per-corner limit normals,
again with a face-varying UV channel; Loop with normals). Peers: Blender's Subdivision Surface modifier
(OpenSubdiv in C++, on all cores; levels 1 and 2, limit surface off, through bpy: the depsgraph evaluation of the
modifier, normals included) and trimesh's ``remesh.subdivide_loop`` (numpy, no normals). The median of REPEAT
runs; prints seconds and ratios, no assertions (docs/benchmarks.md records the numbers).
"""

from __future__ import annotations

import statistics
import time

import numpy as np

REPEAT = 3


def quad_grid(n=317):
    xs = np.arange(n + 1, dtype=np.float64)
    x, y = np.meshgrid(xs, xs)
    v = np.stack([x.ravel(), y.ravel(), 0.1 * np.sin(x.ravel() * 0.3) * np.cos(y.ravel() * 0.2)], 1)
    i = np.arange(n)
    a = (i[None, :] + (n + 1) * i[:, None]).ravel()
    return v, np.stack([a, a + 1, a + n + 2, a + n + 1], 1)


def tri_grid(n=224):
    v, q = quad_grid(n)
    return v, np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])


def _median(fn):
    times = []
    for _ in range(REPEAT):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def ours(v, f, level, scheme="catmullClark", uv=False):
    from tracer.geometry.subdivision import refine

    fv = (v[f.ravel(), :2] / v[:, :2].max(),) if uv else ()
    return _median(lambda: refine(v, np.full(len(f), f.shape[1]), f.ravel(), level, scheme, face_varying=fv))


def blender(v, f, level):
    """Blender's modifier: the evaluation of a fresh depsgraph after setting the level (None without bpy)."""
    try:
        import bpy
    except ImportError:
        return None
    bpy.ops.wm.read_factory_settings(use_empty=True)
    mesh = bpy.data.meshes.new("cage")
    mesh.vertices.add(len(v))
    mesh.vertices.foreach_set("co", v.astype(np.float32).ravel())
    mesh.loops.add(f.size)
    mesh.loops.foreach_set("vertex_index", f.astype(np.int32).ravel())
    mesh.polygons.add(len(f))
    mesh.polygons.foreach_set("loop_start", (np.arange(len(f)) * f.shape[1]).astype(np.int32))
    mesh.update(calc_edges=True)
    obj = bpy.data.objects.new("cage", mesh)
    bpy.context.scene.collection.objects.link(obj)
    mod = obj.modifiers.new("subsurf", "SUBSURF")
    mod.use_limit_surface = False
    times = []
    for _ in range(REPEAT):
        mod.levels = 0
        bpy.context.view_layer.update()
        mod.levels = level
        t = time.perf_counter()
        bpy.context.view_layer.update()
        ev = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
        n_faces = len(ev.data.polygons)
        times.append(time.perf_counter() - t)
    assert n_faces == len(f) * 4 ** level
    return statistics.median(times)


def trimesh_loop(v, f, level):
    import trimesh.remesh

    return _median(lambda: trimesh.remesh.subdivide_loop(v, f, iterations=level))


def main():
    qv, qf = quad_grid()
    tv, tf = tri_grid()
    print(f"Catmull-Clark, {len(qf):,} quads (bumpy grid)")
    for level in (1, 2):
        a, b, c = ours(qv, qf, level), ours(qv, qf, level, uv=True), blender(qv, qf, level)
        peer = "Blender n/a" if c is None else f"Blender's modifier {c:6.2f} s  (ours / Blender {a / c:4.1f}×)"
        print(f"  level {level} ({len(qf) * 4 ** level:>9,} quads): ours {a:6.2f} s, with UVs {b:6.2f} s;  {peer}")
    print(f"Loop, {len(tf):,} triangles")
    for level in (1, 2):
        a, c = ours(tv, tf, level, "loop"), trimesh_loop(tv, tf, level)
        print(f"  level {level} ({len(tf) * 4 ** level:>9,} triangles): ours {a:6.2f} s (normals included);  "
              f"trimesh {c:6.2f} s (no normals)  (ours / trimesh {a / c:4.1f}×)")


if __name__ == "__main__":
    main()

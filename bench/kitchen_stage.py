"""A synthetic production-like "kitchen set" USD stage (issue #23), generated, never downloaded.

1 788 subdivision meshes (catmullClark, USD's default scheme) in a room: cabinets, doors, drawers, handles, knobs,
cups, bottles, fruit, chair legs, counter tops, walls and towels, each family a few *topologies* shared by many
meshes whose points differ (each mesh scaled and bent differently: same faceVertexCounts/Indices, own points), as
in a set dressed from a library of assets. Quads, with triangles at sphere poles and n-gon caps on cylinders;
open grids have boundaries; most meshes carry a faceVarying ``st``; plates are native instances (instanceable
references to one prototype). Six UsdPreviewSurface materials, a camera, two sphere lights and a distant light.

    write_kitchen(path)  ->  dict of counts (meshes, cage triangles, distinct topologies)

About 540 k cage triangles (each quad counts as two, an n-gon as n − 2), ≈ 2.2 M after one level of
refinement (complexity medium), ≈ 8.7 M after two (high).
"""

from __future__ import annotations

import numpy as np


# ------------------------------------------------------------------------------------------------ topologies
def _grid(nu, nv, closed_u=False):
    """Quads of an nu × nv grid of cells over (nu or nu+1) × (nv+1) points: (counts, indices)."""
    pu = nu if closed_u else nu + 1
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = i * (nv + 1) + j
    b = ((i + 1) % pu) * (nv + 1) + j
    quads = np.stack([a, b, b + 1, a + 1], -1).reshape(-1, 4)
    return quads


def box(nx, ny, nz):
    """A closed box of nx × ny × nz cells per side (quads), points in [-0.5, 0.5]³, welded."""
    pts, faces = [], []
    base = 0
    for axis in range(3):
        for sign in (-1, 1):
            u, v = [a for a in range(3) if a != axis]
            nu, nv = (nx, ny, nz)[u], (nx, ny, nz)[v]
            q = _grid(nu, nv)
            s, t = np.meshgrid(np.linspace(-0.5, 0.5, nu + 1), np.linspace(-0.5, 0.5, nv + 1), indexing="ij")
            p = np.zeros((s.size, 3))
            p[:, u], p[:, v], p[:, axis] = s.ravel(), t.ravel(), 0.5 * sign
            if sign < 0:
                q = q[:, ::-1]
            if (axis == 1):  # keep outward winding: the (u, v) frame of the y faces is left-handed
                q = q[:, ::-1]
            pts.append(p)
            faces.append(q + base)
            base += len(p)
    p = np.concatenate(pts)
    f = np.concatenate(faces)
    key = np.round(p * 4096).astype(np.int64)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    return p[first], np.full(len(f), 4), inverse.reshape(-1)[f].ravel()


def cylinder(seg, rows, caps=2):
    """A cylinder of ``seg`` sides and ``rows`` rows, radius 0.5, height 1 (z in [0, 1]); ``caps`` n-gons."""
    ang = 2 * np.pi * np.arange(seg) / seg
    z = np.linspace(0, 1, rows + 1)
    p = np.stack([np.repeat(0.5 * np.cos(ang), rows + 1), np.repeat(0.5 * np.sin(ang), rows + 1),
                  np.tile(z, seg)], 1)
    q = _grid(seg, rows, closed_u=True)
    counts = [np.full(len(q), 4)]
    idx = [q.ravel()]
    ring0 = np.arange(seg) * (rows + 1)
    if caps >= 1:
        counts.append([seg])
        idx.append(ring0[::-1])
    if caps >= 2:
        counts.append([seg])
        idx.append(ring0 + rows)
    return p, np.concatenate(counts), np.concatenate(idx)


def torus(seg, ring, r=0.35, t=0.12):
    u = 2 * np.pi * np.arange(seg) / seg
    v = 2 * np.pi * np.arange(ring) / ring
    uu, vv = np.meshgrid(u, v, indexing="ij")
    p = np.stack([(r + t * np.cos(vv)) * np.cos(uu), (r + t * np.cos(vv)) * np.sin(uu), t * np.sin(vv)], -1)
    i, j = np.meshgrid(np.arange(seg), np.arange(ring), indexing="ij")
    a = i * ring + j
    b = ((i + 1) % seg) * ring + j
    q = np.stack([a, b, b - j + (j + 1) % ring, a - j + (j + 1) % ring], -1).reshape(-1, 4)
    return p.reshape(-1, 3), np.full(len(q), 4), q.ravel()


def sphere(seg, bands):
    """A UV sphere: quads, triangle fans at the poles."""
    th = np.pi * np.arange(1, bands) / bands
    ph = 2 * np.pi * np.arange(seg) / seg
    t, f = np.meshgrid(th, ph, indexing="ij")
    p = np.concatenate([[[0, 0, 0.5]], np.stack([0.5 * np.sin(t) * np.cos(f), 0.5 * np.sin(t) * np.sin(f),
                                                  0.5 * np.cos(t)], -1).reshape(-1, 3), [[0, 0, -0.5]]])
    n_rings = bands - 1
    ring = lambda k: 1 + k * seg + np.arange(seg)  # noqa: E731
    counts, idx = [], []
    top = np.stack([np.zeros(seg, int), ring(0), np.roll(ring(0), -1)], 1)
    counts.append(np.full(seg, 3))
    idx.append(top.ravel())
    for k in range(n_rings - 1):
        a, b = ring(k), ring(k + 1)
        q = np.stack([a, b, np.roll(b, -1), np.roll(a, -1)], 1)
        counts.append(np.full(seg, 4))
        idx.append(q.ravel())
    last = len(p) - 1
    bot = np.stack([np.full(seg, last), np.roll(ring(n_rings - 1), -1), ring(n_rings - 1)], 1)
    counts.append(np.full(seg, 3))
    idx.append(bot.ravel())
    return p, np.concatenate(counts), np.concatenate(idx)


def grid(nu, nv):
    s, t = np.meshgrid(np.linspace(-0.5, 0.5, nu + 1), np.linspace(-0.5, 0.5, nv + 1), indexing="ij")
    p = np.stack([s.ravel(), t.ravel(), np.zeros(s.size)], 1)
    q = _grid(nu, nv)
    return p, np.full(len(q), 4), q.ravel()


# family: (count, topology variants, scale range (x, y, z), material, uv?, z on floor?)
FAMILIES = [
    ("cabinet", 120, [lambda: box(8, 6, 6), lambda: box(6, 6, 8)], (0.6, 0.6, 0.9), "wood", True),
    ("door", 240, [lambda: box(6, 4, 1), lambda: box(4, 6, 1)], (0.45, 0.03, 0.6), "paint", True),
    ("handle", 360, [lambda: torus(12, 8), lambda: torus(12, 8, 0.3, 0.1)], (0.12, 0.12, 0.12), "steel", False),
    ("knob", 200, [lambda: sphere(12, 6)], (0.05, 0.05, 0.05), "steel", False),
    ("cup", 180, [lambda: cylinder(24, 6, 1), lambda: cylinder(24, 6, 2)], (0.09, 0.09, 0.11), "ceramic", True),
    ("bottle", 120, [lambda: cylinder(24, 12, 2)], (0.08, 0.08, 0.3), "glass", True),
    ("fruit", 150, [lambda: sphere(20, 10), lambda: sphere(16, 10)], (0.09, 0.09, 0.09), "fruit", False),
    ("counter", 40, [lambda: grid(40, 16)], (2.4, 0.7, 1.0), "stone", True),
    ("leg", 200, [lambda: box(2, 2, 12)], (0.05, 0.05, 0.8), "wood", True),
    ("towel", 18, [lambda: grid(30, 30)], (0.5, 0.5, 1.0), "cloth", True),
]
PLATES = 160  # native instances of one plate (a 32-sided, 4-row cylinder with both caps)
MATERIALS = {"wood": (0.45, 0.28, 0.15, 0.6, 0.0), "paint": (0.8, 0.82, 0.78, 0.4, 0.0),
             "steel": (0.7, 0.7, 0.72, 0.25, 1.0), "ceramic": (0.9, 0.9, 0.88, 0.2, 0.0),
             "glass": (0.3, 0.6, 0.35, 0.05, 0.0), "fruit": (0.8, 0.3, 0.1, 0.5, 0.0),
             "stone": (0.35, 0.35, 0.38, 0.5, 0.0), "cloth": (0.2, 0.3, 0.7, 0.9, 0.0)}


def _bent(p, rng, scale):
    """Per-mesh points: scaled, with a smooth random bend and bulge (same topology, different points)."""
    s = np.asarray(scale) * rng.uniform(0.8, 1.2, 3)
    q = p * s
    k = rng.uniform(-0.15, 0.15, 3)
    q = q + k[None, :] * np.sin(np.pi * (p[:, [2, 0, 1]] + 0.5)) * s.min()
    return q


def _st(p, counts, indices):
    """An unindexed faceVarying st: a planar projection of each face-vertex's point."""
    return p[indices][:, :2].astype(np.float32)


def write_kitchen(path: str, seed: int = 23) -> dict:
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade, Vt

    rng = np.random.default_rng(seed)
    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.Xform.Define(stage, "/Kitchen")
    mats = {}
    for name, (r, g, b, rough, metal) in MATERIALS.items():
        m = UsdShade.Material.Define(stage, f"/Kitchen/Looks/{name}")
        sh = UsdShade.Shader.Define(stage, f"/Kitchen/Looks/{name}/pbr")
        sh.CreateIdAttr("UsdPreviewSurface")
        sh.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(r, g, b))
        sh.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(rough)
        sh.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(metal)
        if name == "glass":
            sh.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(0.4)
        m.CreateSurfaceOutput().ConnectToSource(sh.ConnectableAPI(), "surface")
        mats[name] = m

    def mesh_at(path, p, counts, idx, uv):
        mesh = UsdGeom.Mesh.Define(stage, path)
        mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(p, np.float32)))
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(counts, np.int32)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(idx, np.int32)))
        if uv:
            pv = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                         UsdGeom.Tokens.faceVarying)
            pv.Set(Vt.Vec2fArray.FromNumpy(_st(p, counts, idx)))
        return mesh

    n_meshes = n_tris = 0
    topologies = set()
    side = 12.0
    for fam, count, variants, scale, mat, uv in FAMILIES:
        shapes = [v() for v in variants]
        for k in range(count):
            p0, counts, idx = shapes[k % len(shapes)]
            topologies.add((fam, k % len(shapes)))
            x, y = rng.uniform(-side / 2, side / 2, 2)
            xf = UsdGeom.Xform.Define(stage, f"/Kitchen/{fam}/{fam}_{k:04d}")
            xf.AddTranslateOp().Set(Gf.Vec3d(x, y, scale[2] / 2 if fam not in ("counter", "towel") else 0.9))
            xf.AddRotateZOp().Set(float(rng.uniform(0, 360)))
            mesh = mesh_at(f"/Kitchen/{fam}/{fam}_{k:04d}/geo", _bent(p0, rng, scale), counts, idx, uv)
            UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(mats[mat])
            n_meshes += 1
            n_tris += int((counts - 2).sum())
    # plates: native instances of one prototype
    stage.CreateClassPrim("/Prototypes")
    UsdGeom.Xform.Define(stage, "/Prototypes/Plate")
    pp, pc, pi = cylinder(32, 4, 2)
    pm = mesh_at("/Prototypes/Plate/geo", pp * [0.25, 0.25, 0.02], pc, pi, True)
    UsdShade.MaterialBindingAPI.Apply(pm.GetPrim()).Bind(mats["ceramic"])
    for k in range(PLATES):
        prim = stage.DefinePrim(f"/Kitchen/plates/plate_{k:04d}", "Xform")
        prim.GetReferences().AddInternalReference("/Prototypes/Plate")
        prim.SetInstanceable(True)
        UsdGeom.Xformable(prim).AddTranslateOp().Set(Gf.Vec3d(*rng.uniform(-side / 2, side / 2, 2), 0.95))
        n_meshes += 1
        n_tris += int((pc - 2).sum())
    topologies.add(("plate", 0))

    cam = UsdGeom.Camera.Define(stage, "/Camera")
    cam.AddTranslateOp().Set(Gf.Vec3d(0, -side * 0.95, side * 0.55))
    cam.AddRotateXOp().Set(60.0)
    cam.CreateFocalLengthAttr(18.0)
    for i, (x, y) in enumerate(((-3, -2), (3, 2))):
        light = UsdLux.SphereLight.Define(stage, f"/Lights/lamp{i}")
        light.AddTranslateOp().Set(Gf.Vec3d(x, y, 3.0))
        light.CreateRadiusAttr(0.2)
        light.CreateIntensityAttr(300.0)
    sun = UsdLux.DistantLight.Define(stage, "/Lights/sun")
    sun.AddRotateXYZOp().Set(Gf.Vec3f(35, 10, 20))
    sun.CreateIntensityAttr(2.0)
    stage.GetRootLayer().Save()
    return {"meshes": n_meshes, "cage_triangles": n_tris, "topologies": len(topologies)}


if __name__ == "__main__":
    import sys
    import time

    t = time.perf_counter()
    print(write_kitchen(sys.argv[1] if len(sys.argv) > 1 else "/tmp/kitchen.usdc"),
          f"{time.perf_counter() - t:.1f} s")

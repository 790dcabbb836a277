"""Measure Cycles' microfiber Sheen BSDF (Zeltner et al. 2022, as Cycles 5.0 evaluates it from its LTC table)
and write the tracer's table of it, ``tracer/shading/sheen_table_data.py``.

    python tools/sheen_table.py [--out tracer/shading/sheen_table_data.py] [--size 96] [--suns 40]

Cycles evaluates the sheen lobe as albedo(μ, r) × D(ω_o), D the linearly transformed cosine
D = z·a² / (π·((a·x + b·z)² + (a·y)² + z²)²) in the frame (T, B, N) with T towards the view direction; a, b and
the albedo are looked up in a table it does not expose. This tool measures them through bpy, with no data taken
from Cycles' sources: a row of spheres (one per roughness, Sheen BSDF of white colour, casting no shadows) seen
orthographically,

- (the furnace) planes tilted to each view cosine μ under a white world of radiance 1, none hiding the world from
  another: each plane's radiance is the directional albedo E(μ, r);
- under a sun from ``--suns`` directions (a Fibonacci spiral over the sphere): each pixel is E(μ, r)·D(ω_o) × the
  sun's strength, for its (view, light) pair in its own frame;

and fits (a, b) per roughness and μ by least squares on D (E from the furnace). The table is MU × ROUGHNESS; the
tracer resamples it to its grids and interpolates bilinearly (tracer/shading/sheen.py).
"""

from __future__ import annotations

import argparse
import math
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.append(ROOT)

#: Roughness grid (Cycles clamps the roughness to [1e-3, 1]).
ROUGHNESS = (0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)
SPACING = 2.5


def build(size: int, world: float, sun=None, distribution: str = "MICROFIBER"):
    import bpy

    from blender_kit import scene as bs

    n = len(ROUGHNESS)
    scene = bs.reset((size * n, size))
    bs.add_camera((SPACING * (n - 1) / 2, -10.0, 0.0), target=(SPACING * (n - 1) / 2, 0.0, 0.0),
                  ortho_scale=SPACING * n)
    bs.set_world((world, world, world), 1.0)
    for k, r in enumerate(ROUGHNESS):
        mat = bpy.data.materials.new(f"sheen {r}")
        nt = mat.node_tree
        for node in list(nt.nodes):
            if node.type != "OUTPUT_MATERIAL":
                nt.nodes.remove(node)
        out = next(node for node in nt.nodes if node.type == "OUTPUT_MATERIAL")
        sh = nt.nodes.new("ShaderNodeBsdfSheen")
        sh.distribution = distribution
        sh.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
        sh.inputs["Roughness"].default_value = r
        nt.links.new(sh.outputs[0], out.inputs["Surface"])
        ob = bs.add_uv_sphere((SPACING * k, 0.0, 0.0), 1.0, segments=128, rings=64, material=mat)
        ob.visible_shadow = False
        ob.cycles.shadow_terminator_geometry_offset = 0.0
        ob.cycles.shadow_terminator_offset = 0.0
    if sun is not None:
        bs.add_sun(tuple(sun), strength=1.0)
    return scene


#: The furnace's view cosines: one tilted plane per (μ, roughness) cell.
FURNACE_MU = tuple(float(x) for x in np.r_[0.03, np.arange(1, 17) / 16])
CELL = 32


def build_furnace():
    """Planes tilted to each view cosine of FURNACE_MU (rows) for each roughness (columns), seen orthographically
    under a white world of radiance 1; no plane hides the world from another (their ray visibility is the camera's
    only), each stretched along its tilt so that its picture is a full cell."""
    import bpy

    from blender_kit import scene as bs

    nr, nm = len(ROUGHNESS), len(FURNACE_MU)
    scene = bs.reset((CELL * nr, CELL * nm))
    bs.add_camera((nr / 2 - 0.5, -10.0, -(nm / 2 - 0.5)), target=(nr / 2 - 0.5, 0.0, -(nm / 2 - 0.5)),
                  ortho_scale=float(max(nr, nm)))
    bs.set_world((1.0, 1.0, 1.0), 1.0)
    for k, r in enumerate(ROUGHNESS):
        mat = bpy.data.materials.new(f"sheen {r}")
        nt = mat.node_tree
        for node in list(nt.nodes):
            if node.type != "OUTPUT_MATERIAL":
                nt.nodes.remove(node)
        out = next(node for node in nt.nodes if node.type == "OUTPUT_MATERIAL")
        sh = nt.nodes.new("ShaderNodeBsdfSheen")
        sh.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
        sh.inputs["Roughness"].default_value = r
        nt.links.new(sh.outputs[0], out.inputs["Surface"])
        for j, mu in enumerate(FURNACE_MU):
            ob = bs.add_plane((float(k), 0.0, -float(j)), 0.9, material=mat, name=f"p{k}_{j}")
            # the plane faces −Y (the camera) tilted up by θ: n = (0, −μ, sin θ); stretched 1/μ along the tilt
            ob.rotation_euler = (math.pi / 2 - math.acos(mu), 0.0, 0.0)
            ob.scale = (1.0, 1.0 / max(mu, 1e-3), 1.0)
            for attr in ("visible_diffuse", "visible_glossy", "visible_transmission", "visible_shadow"):
                setattr(ob, attr, False)
    return scene


def furnace_table(img: np.ndarray) -> np.ndarray:
    """(len(FURNACE_MU), len(ROUGHNESS)) mean radiance of each cell's middle (the plane's interior)."""
    out = np.zeros((len(FURNACE_MU), len(ROUGHNESS)))
    q = CELL // 4
    for j in range(len(FURNACE_MU)):
        for k in range(len(ROUGHNESS)):
            out[j, k] = img[j * CELL + q:(j + 1) * CELL - q, k * CELL + q:(k + 1) * CELL - q].mean()
    return out


def render(scene, samples: int) -> np.ndarray:
    from blender_kit import scene as bs

    bs.set_cycles_whitted(scene, samples=samples, max_depth=1)
    return bs.render_exr(scene, engine="CYCLES")["rgba"][..., :3].mean(-1)


def pixel_normals(size: int):
    """Per pixel of one sphere's square (size × size): (normal (size, size, 3), inside mask); camera along +Y."""
    half = SPACING / 2
    c = ((np.arange(size) + 0.5) / size - 0.5) * 2 * half
    x, z = np.meshgrid(c, -c)
    r2 = x * x + z * z
    inside = r2 < 0.97 ** 2
    y = -np.sqrt(np.maximum(1 - r2, 0))
    return np.stack([x, y, z], -1), inside


def ltc(local: np.ndarray, a, b) -> np.ndarray:
    x, y, z = local[..., 0], local[..., 1], local[..., 2]
    len2 = (a * x + b * z) ** 2 + (a * y) ** 2 + z ** 2
    return np.maximum(z, 0) * a * a / (math.pi * len2 * len2)


def fit(samples_local: np.ndarray, values: np.ndarray) -> tuple[float, float, float, float]:
    """(a, b, A, rms relative residual) minimising Σ (A·D(ω; a, b) − value)² (A by least squares for each (a, b))
    over a log grid of a and a grid of b, refined twice around the best. A is the albedo Cycles weights the lobe
    by (its table's); D is clipped to the upper hemisphere, so the furnace sees A·∫D ≤ A."""
    best = (1.0, 0.0, 0.0, np.inf)
    a_grid, b_grid = np.exp(np.linspace(math.log(0.02), math.log(30), 90)), np.linspace(-6, 6, 121)
    for _ in range(3):
        for a in a_grid:
            m = ltc(samples_local[:, None, :], a, b_grid[None, :])  # (N, nb)
            amp = np.sum(m * values[:, None], 0) / np.maximum(np.sum(m * m, 0), 1e-30)
            res = np.sqrt(np.mean((amp * m - values[:, None]) ** 2, axis=0)) / max(np.mean(values), 1e-9)
            j = int(np.argmin(res))
            if res[j] < best[3]:
                best = (float(a), float(b_grid[j]), float(amp[j]), float(res[j]))
        a0, b0 = best[0], best[1]
        a_grid = a0 * np.exp(np.linspace(-0.2, 0.2, 41))
        b_grid = b0 + np.linspace(-0.2, 0.2, 41) * max(abs(b0), 0.05)
    return best


def measure_suns(size: int, suns: int) -> dict:
    """Per lit pixel of the sun-lit spheres: its view cosine μ, the light direction in its frame (T, B, N) and its
    radiance (the sun's strength is 1), per roughness."""
    normals, inside = pixel_normals(size)
    mu = -normals[..., 1]
    wi = np.array([0.0, -1.0, 0.0])
    t_vec = wi - normals * mu[..., None]  # T towards the view direction, B = N × wi (Cycles' frame)
    t_vec /= np.maximum(np.linalg.norm(t_vec, axis=-1, keepdims=True), 1e-9)
    b_vec = np.cross(normals, wi)
    b_vec /= np.maximum(np.linalg.norm(b_vec, axis=-1, keepdims=True), 1e-9)
    data = {k: ([], [], []) for k in range(len(ROUGHNESS))}
    golden = math.pi * (3 - math.sqrt(5))
    for s in range(suns):
        zc = 1 - 2 * (s + 0.5) / suns
        rr = math.sqrt(1 - zc * zc)
        wo = np.array([rr * math.cos(golden * s), rr * math.sin(golden * s), zc])
        if wo[1] > 0.95:  # straight from behind: nothing the camera sees is lit
            continue
        img = render(build(size, 0.0, sun=-wo), 16)
        local = np.stack([t_vec @ wo, b_vec @ wo, normals @ wo], -1)
        lit = inside & (local[..., 2] > 0.02)
        for k in range(len(ROUGHNESS)):
            px = img[:, k * size:(k + 1) * size]
            data[k][0].append(mu[lit])
            data[k][1].append(local[lit])
            data[k][2].append(px[lit])
        print(f"sun {s + 1}/{suns}", flush=True)
    return {f"{name}{k}": np.concatenate(v[i]) for k, v in data.items() for i, name in enumerate(("mu", "local", "value"))}


def fit_tables(furnace: np.ndarray, suns: dict, min_mu: float = 0.22):
    """(albedo A, a, b, rms) on (len(FURNACE_MU), len(ROUGHNESS)), fitted per roughness on the sun-lit pixels
    within ±1/32 of each μ ≥ ``min_mu`` (sphere pixels nearer the outline are partly background). Below it, and
    where too few pixels are lit, a and b are held from the nearest fitted μ and A is the furnace's albedo there
    times the nearest fitted A/furnace ratio."""
    nm, nr = len(FURNACE_MU), len(ROUGHNESS)
    a_tab, b_tab, alb, rms = np.ones((nm, nr)), np.zeros((nm, nr)), np.zeros((nm, nr)), np.full((nm, nr), np.nan)
    for k in range(nr):
        mu, loc, val = suns[f"mu{k}"], suns[f"local{k}"], suns[f"value{k}"]
        for j, m in enumerate(FURNACE_MU):
            if furnace[j, k] < 1e-4 or m < min_mu:
                continue
            sel = np.abs(mu - m) < 1 / 32
            if sel.sum() < 50 or np.mean(val[sel]) <= 1e-6:
                continue
            a_tab[j, k], b_tab[j, k], alb[j, k], rms[j, k] = fit(loc[sel], val[sel])
        good = np.flatnonzero(np.isfinite(rms[:, k]))
        for j in range(nm):
            if not np.isfinite(rms[j, k]):
                if len(good):
                    g = good[np.argmin(np.abs(good - j))]
                    a_tab[j, k], b_tab[j, k] = a_tab[g, k], b_tab[g, k]
                    alb[j, k] = furnace[j, k] * alb[g, k] / max(furnace[g, k], 1e-9)
                else:
                    alb[j, k] = furnace[j, k]
    return alb, a_tab, b_tab, rms


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=os.path.join(ROOT, "tracer", "shading", "sheen_table_data.py"))
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--suns", type=int, default=24)
    ap.add_argument("--furnace-samples", type=int, default=256)
    ap.add_argument("--raw", default=None, help="keep (or reuse, when it exists) the measurements in this .npz")
    args = ap.parse_args(argv)
    if args.raw and os.path.exists(args.raw):
        raw = dict(np.load(args.raw))
    else:
        raw = measure_suns(args.size, args.suns)
        raw["furnace"] = furnace_table(render(build_furnace(), args.furnace_samples))
        if args.raw:
            np.savez_compressed(args.raw, **raw)
    albedo, a_tab, b_tab, rms = fit_tables(raw["furnace"], raw)
    np.set_printoptions(precision=3, suppress=True, linewidth=200)
    print("albedo\n", albedo, "\na\n", a_tab, "\nb\n", b_tab, "\nrms\n", rms)
    with open(args.out, "w") as f:
        f.write('"""Cycles\' microfiber Sheen BSDF as measured through bpy by tools/sheen_table.py (do not edit: run it '
                'again).\n\nMU: view cosines, ROUGHNESS: sheen roughness; ALBEDO, A, B: (MU, ROUGHNESS) tables of the '
                'directional\nalbedo and the LTC parameters (tracer.shading.sheen); RMS: each fit\'s relative residual (nan: '
                'not fitted, held\nfrom the nearest fitted view cosine).\n"""\n\n')
        f.write("import numpy as np\n\nnan = np.nan\n\n")
        f.write(f"MU = np.array({list(FURNACE_MU)})\n")
        f.write(f"ROUGHNESS = np.array({list(ROUGHNESS)})\n")
        for name, tab in (("ALBEDO", albedo), ("A", a_tab), ("B", b_tab), ("RMS", rms)):
            f.write(f"{name} = np.array({np.round(tab, 5).tolist()})\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

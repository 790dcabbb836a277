"""Mutation check: does the test suite notice when the notes' equations are wrong?

    python tools/mutation_check.py [--list] [--check] [--only WORD ...]

Each mutation below is one deliberate bug in tracer/optics.py, tracer/shading/local.py, the texture lookup or the glass
weights. For each, the repository is copied to a scratch directory, the bug applied there, and the tests that
guard that code run (pytest, fresh numba cache). A mutation is *killed* when a test fails. The kill rate is
printed at the end and recorded in docs/testing.md. Nothing in the working tree is touched.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: The tests that guard the mutated code (fast: no Cycles references, no Blender).
TESTS = ["tests/test_adaptive.py", "tests/test_optics.py", "tests/test_closed_forms.py", "tests/test_bsdf.py", "tests/test_render.py", "tests/test_explain.py",
         "tests/test_usd_lights.py", "tests/test_environment.py", "tests/test_emitters.py"]

#: (name, file, original text, mutated text). Each original must occur in the file exactly once.
MUTATIONS = [
    ("reflect: 2(d·n) -> 1.9(d·n)", "tracer/optics.py",
     "return vec.madd(d, n, -2.0 * vec.dot(d, n))", "return vec.madd(d, n, -1.9 * vec.dot(d, n))"),
    ("reflect: sign of the normal term", "tracer/optics.py",
     "return vec.madd(d, n, -2.0 * vec.dot(d, n))", "return vec.madd(d, n, 2.0 * vec.dot(d, n))"),
    ("refract: TIR test inverted at the boundary", "tracer/optics.py",
     "if radicand < 0.0:", "if radicand < 0.01:"),
    ("refract: η ratio inverted", "tracer/optics.py",
     "ratio = eta_i / eta_r\n    d_n", "ratio = eta_r / eta_i\n    d_n"),
    ("refract: + cos θ_r n", "tracer/optics.py",
     "t = vec.sub(vec.scale(vec.madd(d, n, -d_n), ratio), vec.scale(n, cos_r))",
     "t = vec.add(vec.scale(vec.madd(d, n, -d_n), ratio), vec.scale(n, cos_r))"),
    ("fresnel: R_p dropped", "tracer/optics.py",
     "return 0.5 * (r_s * r_s + r_p * r_p)", "return r_s * r_s"),
    ("lambert: 1/π dropped", "tracer/shading/local.py",
     "INV_PI * max(n_dot_l, 0.0))", "max(n_dot_l, 0.0))"),
    ("lambert: cosine dropped", "tracer/shading/local.py",
     "INV_PI * max(n_dot_l, 0.0))", "INV_PI)"),
    ("blinn-phong: normalisation (e+8)/8π -> (e+2)/8π", "tracer/shading/local.py",
     "lobe = (exponent + 8.0) * (1.0 / (8.0 * math.pi))", "lobe = (exponent + 2.0) * (1.0 / (8.0 * math.pi))"),
    ("ambient: R_a·L_a halved", "tracer/shading/local.py",
     "return vec.mul(diffuse, ambient_radiance)", "return vec.scale(vec.mul(diffuse, ambient_radiance), 0.5)"),
    ("texture: flipped vertically", "tracer/shading/texture.py",
     "y = (1.0 - t) * h - 0.5", "y = t * h - 0.5"),
    ("texture: s and t swapped", "tracer/shading/texture.py",
     "x = s * w - 0.5\n    y = (1.0 - t) * h - 0.5", "x = (1.0 - t) * w - 0.5\n    y = s * h - 0.5"),
    ("texture: nearest instead of bilinear", "tracer/shading/texture.py",
     "fx = x - xf\n    fy = y - yf", "fx = 0.0\n    fy = 0.0"),
    ("classic glass weights 0 -> 0.5", "tracer/integrator/wavefront.py",
     "fr = 1.0 if tir else 0.0", "fr = 1.0 if tir else 0.5"),
    ("transmission ray leaves on the incident side (ε sign)", "tracer/integrator/wavefront.py",
     "spawn_ray(p, ng, t_dir, eps), t_dir", "spawn_ray(p, ng, r_dir, eps), t_dir"),
    # Added with the second round (see docs/testing.md): more of the seed's equations and their neighbours.
    ("fresnel: η_i and η_r swapped", "tracer/optics.py",
     "ratio = eta_i / eta_r\n    sin2_r", "ratio = eta_r / eta_i\n    sin2_r"),
    ("refract: tangential part not scaled by η_i/η_r", "tracer/optics.py",
     "vec.scale(vec.madd(d, n, -d_n), ratio)", "vec.madd(d, n, -d_n)"),
    ("blinn-phong: max(0, n·l) weight dropped", "tracer/shading/local.py",
     "lobe * max(n_dot_l, 0.0))", "lobe)"),
    ("blinn-phong: half vector not normalised", "tracer/shading/local.py",
     "return vec.normalize(vec.add(l, v))", "return vec.add(l, v)"),
    ("blinn-phong: half vector from the ray direction, not towards the eye", "tracer/shading/bsdf.py",
     "h = shading.half_vector(l, wi)", "h = shading.half_vector(l, vec.scale(wi, -1.0))"),
    ("texture: half-texel offset dropped", "tracer/shading/texture.py",
     "x = s * w - 0.5\n    y = (1.0 - t) * h - 0.5", "x = s * w\n    y = (1.0 - t) * h"),
    ("texture: clamp instead of repeat wrapping", "tracer/shading/texture.py",
     "            return i\n        return i % n", "            return i\n        return min(max(i, 0), n - 1)"),
    ("sRGB encoding with exponent 1/2.2 instead of 1/2.4", "tracer/colorspace.py",
     "np.power(c, 1 / 2.4)", "np.power(c, 1 / 2.2)"),
    ("environment mirrored left-right (u = 0.5 + atan2/2π)", "tracer/lights/environment.py",
     "u = 0.5 - math.atan2(e[1], e[0])", "u = 0.5 + math.atan2(e[1], e[0])"),
    ("environment upside down", "tracer/lights/environment.py",
     "t = 0.5 + math.asin(", "t = 0.5 - math.asin("),
    ("reflection ray starts below the surface (ε sign)", "tracer/integrator/wavefront.py",
     "spawn_ray(p, ng, r_dir, eps), r_dir", "spawn_ray(p, ng, di, eps), r_dir"),
    ("spawn_ray: ε to the side the ray does not leave to", "tracer/integrator/wavefront.py",
     "if vec.dot(ng, direction) >= 0.0:", "if vec.dot(ng, direction) < 0.0:"),
    ("shadow ray runs past the light", "tracer/integrator/wavefront.py",
     "return o, vec.scale(to, 1.0 / max(length, 1e-30)), length - eps",
     "return o, vec.scale(to, 1.0 / max(length, 1e-30)), np.inf"),
    ("mirror: local colour not weighted by (1 − k_m) (classic)", "tracer/integrator/wavefront.py",
     "wl = (1.0 - k_m) * (1.0 - w_t) * cover", "wl = (1.0 - w_t) * cover"),
    ("mirror: local colour not weighted by (1 − k_m) (principled)", "tracer/integrator/wavefront.py",
     "wl = (1.0 - k_m) * cover", "wl = cover"),
    ("mirror: tint ignored", "tracer/integrator/wavefront.py",
     "mirror = vec.scale(vec.row(m_mirror, mat), k_m)", "mirror = (k_m, k_m, k_m)"),
    ("glass: transmission tint ignored", "tracer/integrator/wavefront.py",
     "glass_t = vec.scale(vec.row(m_ttint, mat), glass)", "glass_t = (glass, glass, glass)"),
    # Third round: the Principled model (tracer/shading/bsdf.py), guarded by tests/test_bsdf.py's closed forms.
    ("ggx: Smith masking-shadowing dropped", "tracer/shading/bsdf.py",
     "(math.pi * t * t * 4.0 * cl.mu * (1.0 + cl.lambda_mu + _lambda(a2, n_l)))",
     "(math.pi * t * t * 4.0 * cl.mu)"),
    ("ggx: D without its 1/π", "tracer/shading/bsdf.py",
     "common = a2 * spec_scale / (math.pi * t * t * 4.0", "common = a2 * spec_scale / (t * t * 4.0"),
    ("ggx: α = r instead of r²", "tracer/shading/bsdf.py",
     "μ = n·wi.\"\"\"\n    r = min(max(roughness, 0.0), 1.0)\n    alpha = r * r\n",
     "μ = n·wi.\"\"\"\n    r = min(max(roughness, 0.0), 1.0)\n    alpha = r\n"),
    ("principled: multiple scattering off", "tracer/shading/bsdf.py",
     "    return (1.0 + f0 * missing, 1.0 + f1 * missing, 1.0 + f2 * missing)", "    return (1.0, 1.0, 1.0)"),
    ("principled: diffuse not darkened under the specular layer", "tracer/shading/bsdf.py",
     "        layer = min(max(1.0 - vec.max3(alb), 0.0), 1.0)", "        layer = 1.0"),
    ("normal map: bitangent sign flipped (DirectX read as OpenGL)", "tracer/shading/bsdf.py",
     "    b = vec.scale(vec.cross(nf, tg), sign)", "    b = vec.scale(vec.cross(nf, tg), -sign)"),
    ("area light: the emitter's cosine dropped", "tracer/lights/emitters.py",
     "f = cos_l * lights.area[j] / d2 / kk", "f = lights.area[j] / d2 / kk"),
    # Fourth round: adaptive sampling (issue #33), guarded by tests/test_adaptive.py.
    ("adaptive: no dilation of unconverged pixels", "tracer/integrator/adaptive.py",
     "    return dilate(unconverged.reshape(shape)).reshape(-1) & (count < sched.budget)",
     "    return unconverged & (count < sched.budget)"),
    ("adaptive: the film divides by the tile's first pixel's count", "tracer/integrator/tiles.py",
     "            n = np.float32(spent[p])\n", "            n = np.float32(spent[0])\n"),
    ("adaptive: a pixel's sample positions restart each round", "tracer/integrator/adaptive.py",
     " + np.repeat(start.astype(np.int64), m)", ""),
]


def _copy_repo(dest):
    ignore = shutil.ignore_patterns(".git", ".venv", "__pycache__", ".cache", ".pytest_cache", "dist", "build",
                                    "*.egg-info", "bench")
    shutil.copytree(ROOT, dest, ignore=ignore)


#: Mutations of a convention written in more than one function (a lookup and its sampling inverse, the bilinear and
#: bicubic texel positions): every copy is changed, as a wrong convention would be.
EVERY_COPY = {"texture: flipped vertically", "texture: s and t swapped", "texture: half-texel offset dropped",
              "environment mirrored left-right (u = 0.5 + atan2/2π)", "environment upside down"}


def applies(name: str, count: int) -> bool:
    """The original text occurs as the mutation expects: once, or at least once for an EVERY_COPY mutation."""
    return count >= 1 if name in EVERY_COPY else count == 1


def run_one(name, path, old, new, python, tests, verbose=False):
    with tempfile.TemporaryDirectory(prefix="whitted-mutant-") as tmp:
        repo = os.path.join(tmp, "repo")
        _copy_repo(repo)
        target = os.path.join(repo, path)
        text = open(target).read()
        if not applies(name, text.count(old)):
            return name, "stale", f"the original text occurs {text.count(old)} times in {path}"
        with open(target, "w") as f:
            f.write(text.replace(old, new))
        env = dict(os.environ, PYTHONPATH=repo, NUMBA_CACHE_DIR=os.path.join(tmp, "numba"))
        t0 = time.perf_counter()
        r = subprocess.run([python, "-m", "pytest", "-x", "-q", "-p", "no:randomly", "-p", "no:cacheprovider",
                            *tests], cwd=repo, env=env, capture_output=True, text=True)
        took = time.perf_counter() - t0
        failed = [ln for ln in r.stdout.splitlines() if ln.startswith("FAILED")]
        if verbose:
            print(r.stdout[-2000:])
        if r.returncode == 0:
            return name, "SURVIVED", f"{took:.0f} s"
        if r.returncode == 1:
            return name, "killed", (failed[0].split(" - ")[0].replace("FAILED ", "") if failed else "") + \
                f" ({took:.0f} s)"
        return name, "error", r.stdout[-300:] + r.stderr[-300:]


def main(argv=None):
    ap = argparse.ArgumentParser(prog="tools/mutation_check.py")
    ap.add_argument("--list", action="store_true", help="list the mutations and exit")
    ap.add_argument("--check", action="store_true",
                    help="only check that each mutation's original text still occurs exactly once (after a refactor)")
    ap.add_argument("--only", nargs="+", help="run only mutations whose name contains one of these words")
    ap.add_argument("--verbose", action="store_true")
    a = ap.parse_args(argv)
    muts = [m for m in MUTATIONS if not a.only or any(w in m[0] for w in a.only)]
    if a.list:
        for m in muts:
            print(f"{m[1]}: {m[0]}")
        return 0
    if a.check:
        stale = [(m[0], m[1], open(os.path.join(ROOT, m[1])).read().count(m[2])) for m in muts]
        stale = [x for x in stale if not applies(x[0], x[2])]
        for name, path, count in stale:
            print(f"stale: {name}: the original text occurs {count} times in {path}")
        print(f"{len(muts) - len(stale)}/{len(muts)} mutations apply")
        return 1 if stale else 0
    results = []
    for m in muts:
        res = run_one(*m, python=sys.executable, tests=TESTS, verbose=a.verbose)
        print(f"{res[1]:>8}  {res[0]}  {res[2]}", flush=True)
        results.append(res)
    killed = sum(r[1] == "killed" for r in results)
    valid = sum(r[1] in ("killed", "SURVIVED") for r in results)
    print(f"kill rate: {killed}/{valid} = {killed / max(valid, 1):.0%}")
    if valid < len(results):
        print(f"{len(results) - valid} mutation(s) did not apply or errored: update MUTATIONS to the code")
    return 0 if killed == valid == len(results) else 1


if __name__ == "__main__":
    sys.exit(main())

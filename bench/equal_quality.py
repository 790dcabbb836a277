"""Equal quality (issue #33): the CPU time each renderer needs to reach a PSNR against a converged Cycles reference.

``python -m bench.equal_quality [--scenes a,b] [--blend DIR_OR_FILE ...] [--threads 2] [--targets 35,40]
[--json out.json] [--svg DIR] [--sheet SHEET.jpg]``

Each lab scene is built once in Blender (``blender_kit``: the objects, lights, world and camera the Cycles comparison
tests use), in this process. Cycles renders it with the Whitted light paths (``blender_kit.cycles``:
diffuse bounces 0, caustics off, box filter, ...), ours renders the add-on's export of the same depsgraph
(``addon.export.scene_from_depsgraph``), both on the same ``--threads``. The reference is Cycles at
``--reference-samples`` without adaptive sampling (cached under ``.cache/equal_quality/``, keyed by the scene, size,
samples and Blender version), with a seed the sweep does not use; a second reference with another seed says how
converged it is.

Each renderer is swept over its quality knob, every render timed in process CPU seconds (``time.process_time``,
which counts every thread: the machine is shared, so wall time is printed but not compared) and scored in
PSNR of the sRGB-encoded image against the reference (as tests/cycles do):

- ours, fixed: N×N samples per pixel, N = 1 … 16;
- ours, adaptive: budgets N×N, N = 3 … 16, each at noise thresholds 0.2, 0.05 and 0.01, min samples 4;
- Cycles, fixed: 1 … 1024 samples, adaptive sampling off;
- Cycles, adaptive: budgets 16 … 1024 samples at the same thresholds, min samples 4 (Cycles checks first after 16);
- ours, adaptive + OIDN: as ours adaptive with ``denoise`` (tracer/denoise.py: Open Image Denoise with the albedo
  and normal guides, the whole frame after the tiles, inside the timed render);
- Cycles, adaptive + OIDN: as Cycles adaptive with Open Image Denoise (CPU; albedo and normal guides, accurate
  prefilter), Blender's default final-render denoiser.

**Third-party scenes** (``--blend``: .blend files or folders searched for them, as ``tools/blender_fidelity.py``
takes them; nothing is downloaded, and the lab scenes need none): each file's scene as it is saved, prepared as the
fidelity survey prepares it (``tools/blender_fidelity.prepare_scene``: :data:`FILE_WIDTH` px wide at the file's
aspect, Film > Transparent off, a framing camera where the file has none), at depth :data:`FILE_DEPTH`; named by
its path under the folder given, without ``.blend``. Ours renders what F12 exports: the add-on's export of the
*render* depsgraph (render modifier levels, objects hidden from renders left out), caught from one F12 with the
add-on's engine (:func:`ours_scene_f12`), then timed as ``tracer.render`` like the lab scenes. Files with nothing
to render (material libraries) are skipped. ``--modes`` narrows the sweep (a third-party file takes the same modes).

A mode's curve is its best PSNR for the time (the points sorted by CPU time, each kept when it beats every faster
one: the best setting of the knobs at that cost); its time to a target is where that curve first reaches it,
interpolated linearly in PSNR against log time with the point before. ``--svg DIR`` draws one plot per scene
(PSNR against CPU time, log scale), hand-written SVG (no plotting package in the environment); ``--sheet`` a
contact sheet (JPEG, under 300 KB): per scene the reference, and ours adaptive + OIDN and Cycles adaptive + OIDN at
the first render of their curves that reaches the first target.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CACHE = os.path.join(ROOT, ".cache", "equal_quality")
WIDTH, HEIGHT = 160, 120
#: Ours' quality knobs: N for N×N (fixed); budgets N and thresholds (adaptive).
OURS_N = (1, 2, 3, 4, 6, 8, 11, 16)
OURS_BUDGETS = (3, 4, 6, 8, 11, 16)
THRESHOLDS = (0.2, 0.05, 0.01)
MIN_SAMPLES = 4
#: Cycles' samples (fixed) and its budgets with adaptive sampling.
CYCLES_SAMPLES = (1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 1024)
CYCLES_BUDGETS = (16, 32, 64, 128, 256, 512, 1024)
TARGETS = (35.0, 40.0)
#: Third-party scenes (``--blend``): width in pixels (the height from the file's aspect) and depth, as the fidelity
#: survey renders them (tools/blender_fidelity.py).
FILE_WIDTH, FILE_DEPTH = 160, 8
#: Third-party scenes by name (their path under the folder given, without ``.blend``): the file's path.
FILES: dict = {}
#: The references' seeds: not the sweep's (0), whose first samples a reference of the same seed would share.
REFERENCE_SEEDS = (101, 102)
#: A render is repeated (its least CPU time kept: the machine is shared) until REPEAT_SECONDS of CPU are spent,
#: at most REPEATS times.
REPEATS, REPEAT_SECONDS = 3, 1.0
MODES = ("ours fixed", "ours adaptive", "ours adaptive+oidn", "cycles fixed", "cycles adaptive",
         "cycles adaptive+oidn")


# ---------------------------------------------------------------------------------------------------- scenes
def _objects(bs, floor_mat=None):
    """The tests' base set: a grey floor, a white ball and a blue block (tests/cycles/cycles_scenes.py)."""
    grey = floor_mat or bs.principled_material("Grey", base_color=(0.8, 0.8, 0.8), specular=0.0)
    bs.add_plane(size=8.0, material=grey, name="Floor")
    bs.add_uv_sphere((-0.9, 0.3, 1.0), 1.0, segments=64, rings=32, name="Ball",
                     material=bs.principled_material("White", base_color=(0.85, 0.85, 0.85), specular=0.0))
    block = bs.add_cube((1.4, -0.4, 0.6), 1.2, name="Block",
                        material=bs.principled_material("Blue", base_color=(0.15, 0.3, 0.8), specular=0.0))
    block.rotation_euler = (0.0, 0.0, 0.6)


def _camera(bs, **kw):
    bs.add_camera((0.0, -7.0, 3.2), (0.0, 0.0, 0.7), lens=35.0, **kw)


def scene_soft_shadow(bs):
    """A point light of radius 0.5: soft shadows (noise at the shadow's edge)."""
    _objects(bs)
    bs.add_point_light((2.5, -2.0, 5.0), 1500.0, radius=0.5)
    _camera(bs)


def scene_area(bs):
    """A 2 m square area light overhead: wide penumbrae."""
    _objects(bs)
    bs.add_area_light((1.0, -1.5, 4.0), (0.0, 0.0, 0.0), power=600.0, size=2.0)
    _camera(bs)


def scene_sky(bs):
    """Only the world's colour: the sky's light, shadowed (Cycles shadows the world; ours samples its visibility)."""
    _objects(bs)
    bs.set_world((0.35, 0.5, 0.8), 1.0)
    _camera(bs)


def scene_dof(bs):
    """Three balls in depth under a hard point light, the camera focused on the middle one at f/1.4."""
    grey = bs.principled_material("Grey", base_color=(0.8, 0.8, 0.8), specular=0.0)
    bs.add_plane(size=12.0, material=grey, name="Floor")
    for i, (x, y) in enumerate(((-1.8, -2.0), (0.0, 0.5), (1.8, 3.0))):
        bs.add_uv_sphere((x, y, 0.8), 0.8, segments=64, rings=32, name=f"Ball{i}",
                         material=bs.principled_material(f"M{i}", base_color=(0.8, 0.3 + 0.2 * i, 0.2),
                                                         specular=0.0))
    bs.add_point_light((2.5, -3.0, 5.0), 1500.0)
    cam = bs.add_camera((0.0, -7.0, 2.2), (0.0, 0.5, 0.8), lens=50.0)
    cam.data.dof.use_dof = True
    cam.data.dof.focus_distance = float(np.linalg.norm(np.subtract((0.0, -7.0, 2.2), (0.0, 0.5, 0.8))))
    cam.data.dof.aperture_fstop = 1.4


def scene_glass_mirror(bs):
    """A mirror ball and a glass ball on a grey floor under an area light: soft shadows seen directly, in the
    mirror and through the glass (Whitted's ray types under a light with an extent)."""
    grey = bs.principled_material("Grey", base_color=(0.8, 0.8, 0.8), specular=0.0)
    bs.add_plane(size=8.0, material=grey, name="Floor")
    bs.add_uv_sphere((-1.0, 0.4, 1.0), 1.0, segments=64, rings=32, name="Mirror",
                     material=bs.principled_material("Mirror", base_color=(1.0, 1.0, 1.0), metallic=1.0,
                                                     roughness=0.0))
    bs.add_uv_sphere((1.1, -0.6, 0.8), 0.8, segments=64, rings=32, name="Glass",
                     material=bs.principled_material("Glass", base_color=(1.0, 1.0, 1.0), transmission=1.0,
                                                     roughness=0.0, ior=1.5))
    lamp = bs.add_area_light((0.5, -1.5, 4.5), (0.0, 0.0, 0.0), power=800.0, size=1.5)
    # Whitted's light paths: a lamp is not a surface, so neither renderer sees it in the mirror or through the
    # glass (Cycles shows a Blender light to glossy and transmission rays; measured: 31.5 dB with it, the lamp's
    # reflection being 98 % of the squared error)
    lamp.visible_glossy = lamp.visible_transmission = False
    bs.set_world((0.05, 0.05, 0.08), 1.0)
    _camera(bs)


def scene_whitted(bs):
    """Whitted's 1980 picture (bench/scenes.py's ``whitted``): point lights of radius 0, mirror, glass, a checker
    floor and a blue sky: the noise is the anti-aliasing and the sky's shadowed light."""
    from . import cycles as bench_cycles
    from . import scenes

    bench_cycles.build_blender_scene(scenes.build("whitted"), WIDTH, HEIGHT, 16, 2)


SCENES = {"soft_shadow": scene_soft_shadow, "area": scene_area, "sky": scene_sky, "dof": scene_dof,
          "glass_mirror": scene_glass_mirror, "whitted": scene_whitted}
#: Our max depth (= Cycles' glossy and transmission bounces) per scene.
DEPTH = {"glass_mirror": 6, "whitted": 8}


def depth_of(name: str) -> int:
    return FILE_DEPTH if name in FILES else DEPTH.get(name, 4)


def size_of(sc) -> tuple:
    """(width, height) of the scene's render."""
    r = sc.render
    return (r.resolution_x * r.resolution_percentage // 100, r.resolution_y * r.resolution_percentage // 100)


def _fidelity():
    """tools/blender_fidelity.py (a script, not a package): its scene preparation is the survey's."""
    import importlib.util

    mod = sys.modules.get("whitted_blender_fidelity")
    if mod is None:
        spec = importlib.util.spec_from_file_location("whitted_blender_fidelity",
                                                      os.path.join(ROOT, "tools", "blender_fidelity.py"))
        mod = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = mod
        spec.loader.exec_module(mod)
    return mod


def blend_scenes(inputs: list) -> dict:
    """{name: path} of the .blend files under ``inputs`` (files or folders), named by their path under the folder
    given without ``.blend`` (``gltf/04_lights``)."""
    return {rel[:-len(".blend")] if rel.endswith(".blend") else rel: path
            for path, rel in _fidelity().blend_files(list(inputs))}


def build(name: str):
    """The Blender scene ``name``, Standard view, WIDTH × HEIGHT (a third-party file: :data:`FILE_WIDTH` wide at its
    aspect); returns bpy.context.scene."""
    import bpy

    from blender_kit import scene as bs

    if name in FILES:
        bpy.ops.wm.open_mainfile(filepath=FILES[name], load_ui=False)
        sc = bpy.context.scene
        _fidelity().prepare_scene(sc, FILE_WIDTH)
        sc.view_settings.view_transform = "Standard"
        return sc
    if name == "whitted":
        SCENES[name](bs)
    else:
        bs.reset((WIDTH, HEIGHT))
        SCENES[name](bs)
    sc = bpy.context.scene
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = WIDTH, HEIGHT, 100
    sc.view_settings.view_transform = "Standard"
    return sc


# ---------------------------------------------------------------------------------------------------- renderers
def cycles_setup(sc, *, samples: int, threads: int, threshold: float = 0.0, oidn: bool = False, seed: int = 0,
                 depth: int = 4) -> None:
    from blender_kit.cycles import whitted_cycles_settings

    whitted_cycles_settings(sc, depth=depth, samples=samples, seed=seed)
    c = sc.cycles
    c.use_adaptive_sampling = threshold > 0
    if threshold > 0:
        c.adaptive_threshold = threshold
        c.adaptive_min_samples = MIN_SAMPLES
    c.use_denoising = oidn
    if oidn:
        c.denoiser = "OPENIMAGEDENOISE"
        c.denoising_input_passes = "RGB_ALBEDO_NORMAL"
        c.denoising_prefilter = "ACCURATE"
        if hasattr(c, "denoising_use_gpu"):
            c.denoising_use_gpu = False
    sc.render.threads_mode = "FIXED"
    sc.render.threads = threads
    s = sc.render.image_settings
    if hasattr(s, "media_type"):
        s.media_type = "IMAGE"
    s.file_format, s.color_mode, s.color_depth = "OPEN_EXR", "RGBA", "32"


def timed(run):
    """(result, CPU seconds, wall seconds) of ``run()``: the least CPU time of up to :data:`REPEATS` runs (and that
    run's wall time), repeated while less than :data:`REPEAT_SECONDS` were spent."""
    best, spent, n = None, 0.0, 0
    while n < REPEATS and (n == 0 or spent < REPEAT_SECONDS):
        c0, w0 = time.process_time(), time.perf_counter()
        value = run()
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        spent, n = spent + cpu, n + 1
        if best is None or cpu < best[1]:
            best = (value, cpu, wall)
    return best


def cycles_render(sc) -> tuple[np.ndarray, float, float]:
    """(linear RGB, CPU seconds, wall seconds) of one F12 with the scene's settings (the timed part is the render
    operator alone; the result is read back after)."""
    import bpy
    import OpenImageIO as oiio

    _, cpu, wall = timed(lambda: bpy.ops.render.render(write_still=False))
    with tempfile.TemporaryDirectory(prefix="whitted-eq-") as tmp:
        path = os.path.join(tmp, "r.exr")
        bpy.data.images["Render Result"].save_render(filepath=path, scene=sc)
        buf = oiio.ImageBuf(path)
        spec = buf.spec()
        px = np.asarray(buf.get_pixels(oiio.FLOAT), np.float32).reshape(spec.height, spec.width, -1)[..., :3]
    return px, cpu, wall


def ours_scene(sc):
    import bpy

    from addon import export

    depsgraph = bpy.context.evaluated_depsgraph_get()
    w, h = size_of(sc)
    scene, warnings = export.scene_from_depsgraph(depsgraph, width=w, height=h)
    dof = export.camera_dof_on(sc.camera.data)
    return scene, warnings, dof


def ours_scene_f12(sc):
    """What F12 with the add-on's engine exports (the render depsgraph: render modifier levels, objects hidden from
    renders left out): caught from one F12 at 1 sample whose export is kept, the engine's own trace untimed."""
    import addon
    from addon import engine, export

    if not hasattr(sc, "whitted"):
        addon.register()
    caught = {}
    real = export.scene_from_depsgraph

    def catch(depsgraph, **kw):
        caught["result"] = real(depsgraph, **kw)
        return caught["result"]

    engine_prev, samples_prev, denoise_prev = sc.render.engine, sc.whitted.samples, sc.whitted.denoise
    sc.render.engine, sc.whitted.samples = "WHITTED", 1
    sc.whitted.denoise = False
    export.scene_from_depsgraph = catch
    try:
        import bpy

        bpy.ops.render.render(write_still=False)
    finally:
        export.scene_from_depsgraph = real
        sc.render.engine, sc.whitted.samples, sc.whitted.denoise = engine_prev, samples_prev, denoise_prev
    if "result" not in caught:
        report = engine.WhittedRenderEngine.last_render
        raise RuntimeError(f"F12 exported nothing ({report})")
    scene, warnings = caught["result"]
    return scene, warnings, export.camera_dof_on(sc.camera.data)


def ours_render(scene, settings) -> tuple[np.ndarray, float, float, float]:
    """(linear RGB, CPU seconds, wall seconds, samples per pixel) of one tracer.render (Embree build included)."""
    import tracer

    img, cpu, wall = timed(lambda: tracer.render(scene, settings))
    return img.rgb.copy(), cpu, wall, float(img.stats["samples_per_pixel"])


# ---------------------------------------------------------------------------------------------------- metrics
def psnr_srgb(a: np.ndarray, b: np.ndarray) -> float:
    """PSNR in dB of two linear images after the sRGB transfer function (clipped to [0, 1], peak 1), as
    tests/cycles/cycles_harness.py computes it."""
    from tracer.colorspace import linear_to_srgb

    mse = float(np.mean((linear_to_srgb(np.clip(a, 0, 1)) - linear_to_srgb(np.clip(b, 0, 1))) ** 2))
    return float("inf") if mse == 0 else 10 * math.log10(1.0 / mse)


def frontier(points: list) -> list:
    """The best PSNR for the time: ``points`` [(seconds, psnr), ...] sorted by time, each kept when it beats every
    faster one."""
    out = []
    for t, p in sorted(points):
        if not out or p > out[-1][1]:
            out.append((t, p))
    return out


def time_to(points: list, target: float):
    """CPU seconds at which the :func:`frontier` of ``points`` first reaches ``target`` dB (interpolated in log
    time with the point before), or None."""
    pts = frontier(points)
    for i, (t, p) in enumerate(pts):
        if p >= target:
            if i == 0:
                return t
            t0, p0 = pts[i - 1]
            if p0 >= target or p == p0:
                return t
            f = (target - p0) / (p - p0)
            return math.exp(math.log(t0) + f * (math.log(t) - math.log(t0)))
    return None


# ---------------------------------------------------------------------------------------------------- the sweep
def reference(name: str, samples: int, threads: int, seed: int) -> np.ndarray:
    """Cycles at ``samples`` without adaptive sampling (cached)."""
    import bpy

    size = (FILE_WIDTH,) if name in FILES else (WIDTH, HEIGHT)
    key = hashlib.sha256(json.dumps([name, *size, samples, seed, depth_of(name),
                                     bpy.app.version_string, _source_of(name)]).encode()).hexdigest()[:16]
    path = os.path.join(CACHE, f"{name.replace('/', '__')}-{samples}-{seed}-{key}.npy")
    if os.path.exists(path):
        return np.load(path)
    sc = build(name)
    cycles_setup(sc, samples=samples, threads=threads, seed=seed, depth=depth_of(name))
    px, cpu, _ = cycles_render(sc)
    os.makedirs(CACHE, exist_ok=True)
    np.save(path, px)
    print(f"  reference {name} seed {seed}: {samples} samples in {cpu:.1f} s CPU", flush=True)
    return px


def _source_of(name: str) -> str:
    import inspect

    if name in FILES:
        return _fidelity().file_digest(FILES[name]) + inspect.getsource(_fidelity().prepare_scene)
    return inspect.getsource(SCENES[name]) + inspect.getsource(_objects)


def sweep(name: str, threads: int, ref_samples: int, targets=TARGETS, modes=MODES) -> dict:
    import tracer

    ref = reference(name, ref_samples, threads, REFERENCE_SEEDS[0])
    ref2 = reference(name, ref_samples, threads, REFERENCE_SEEDS[1])
    depth = depth_of(name)
    out = {"scene": name, "reference_samples": ref_samples, "reference_psnr": psnr_srgb(ref2, ref),
           "curves": {m: [] for m in modes}}
    sc = build(name)
    w, h = size_of(sc)
    scene, warnings, dof = ours_scene_f12(sc) if name in FILES else ours_scene(sc)
    base = tracer.RenderSettings(width=w, height=h, threads=threads, max_depth=depth, depth_of_field=dof,
                                 transparent=bool(sc.render.film_transparent))
    out["warnings"], out["size"] = warnings, [w, h]
    images = {m: [] for m in modes}  # each render's picture, for the contact sheet
    ours_render(scene, base.with_(samples=2))  # kernels loaded before anything is timed
    ours_render(scene, base.with_(samples=3, adaptive_threshold=0.1, adaptive_min_samples=4))
    if "ours adaptive+oidn" in modes:
        ours_render(scene, base.with_(samples=3, adaptive_threshold=0.1, adaptive_min_samples=4, denoise=True))
    runs = []
    if "ours fixed" in modes:
        runs += [("ours fixed", {"N": n}, base.with_(samples=n)) for n in OURS_N]
    if "ours adaptive" in modes:
        runs += [("ours adaptive", {"N": n, "threshold": t},
                  base.with_(samples=n, adaptive_threshold=t, adaptive_min_samples=MIN_SAMPLES))
                 for n in OURS_BUDGETS for t in THRESHOLDS]
    if "ours adaptive+oidn" in modes:
        runs += [("ours adaptive+oidn", {"N": n, "threshold": t},
                  base.with_(samples=n, adaptive_threshold=t, adaptive_min_samples=MIN_SAMPLES, denoise=True))
                 for n in OURS_BUDGETS for t in THRESHOLDS]
    for mode, knob, settings in runs:
        px, cpu, wall, spp = ours_render(scene, settings)
        out["curves"][mode].append(dict(knob, cpu=cpu, wall=wall, spp=spp, psnr=psnr_srgb(px, ref)))
        images[mode].append(px)
        print(f"  {name:13s} {mode:22s} {knob} {cpu:7.2f} s CPU {wall:6.2f} s  {spp:6.1f} spp  "
              f"{out['curves'][mode][-1]['psnr']:.2f} dB", flush=True)
    cyc = []
    if "cycles fixed" in modes:
        cyc += [("cycles fixed", {"samples": s}, dict(samples=s)) for s in CYCLES_SAMPLES]
    if "cycles adaptive" in modes:
        cyc += [("cycles adaptive", {"samples": b, "threshold": t}, dict(samples=b, threshold=t))
                for b in CYCLES_BUDGETS for t in THRESHOLDS]
    if "cycles adaptive+oidn" in modes:
        cyc += [("cycles adaptive+oidn", {"samples": b, "threshold": t}, dict(samples=b, threshold=t, oidn=True))
                for b in CYCLES_BUDGETS for t in THRESHOLDS]
    for mode, knob, kw in cyc:
        sc = build(name)
        cycles_setup(sc, threads=threads, depth=depth, **kw)
        px, cpu, wall = cycles_render(sc)
        out["curves"][mode].append(dict(knob, cpu=cpu, wall=wall, psnr=psnr_srgb(px, ref)))
        images[mode].append(px)
        print(f"  {name:13s} {mode:22s} {knob} {cpu:7.2f} s CPU {wall:6.2f} s  "
              f"{out['curves'][mode][-1]['psnr']:.2f} dB", flush=True)
    out["time_to"] = {f"{target:g}": {m: time_to([(p["cpu"], p["psnr"]) for p in c], target)
                                      for m, c in out["curves"].items()} for target in targets}
    out["best_psnr"] = {m: max((p["psnr"] for p in c), default=None) for m, c in out["curves"].items()}
    out["pictures"] = {"reference": ref}  # not written to the JSON: the contact sheet's
    for m, c in out["curves"].items():
        i = first_reaching(c, targets[0]) if c else None
        if i is not None:
            out["pictures"][m] = images[m][i]
    return out


def first_reaching(curve: list, target: float):
    """Index in ``curve`` of the first render of its :func:`frontier` that reaches ``target`` dB, or None."""
    order = sorted(range(len(curve)), key=lambda i: (curve[i]["cpu"], curve[i]["psnr"]))
    best = -math.inf
    for i in order:
        if curve[i]["psnr"] > best:
            best = curve[i]["psnr"]
            if best >= target:
                return i
    return None


# ---------------------------------------------------------------------------------------------------- output
#: The like-for-like pairs whose ratio the table gives: (ours, Cycles).
PAIRS = (("ours adaptive", "cycles adaptive"), ("ours adaptive+oidn", "cycles adaptive+oidn"))


def table(results: list, target: float) -> str:
    """Markdown: per scene, the CPU seconds each mode needs to reach ``target`` dB, and ours ÷ Cycles per pair."""
    modes = [m for m in MODES if any(r["curves"].get(m) for r in results)]
    pairs = [p for p in PAIRS if p[0] in modes and p[1] in modes]
    head = ("| scene | reference (2 seeds) | " + " | ".join(modes) + "".join(f" | {a} ÷ {b}" for a, b in pairs)
            + " |")
    lines = [head, "|" + "---|" * (len(modes) + len(pairs) + 2)]
    for r in results:
        tt = r["time_to"][f"{target:g}"]
        cells = []
        for m in modes:
            t = tt.get(m)
            cells.append("—" if not r["curves"].get(m) else
                         (f"{t:.2f} s" if t is not None else f"not reached ({r['best_psnr'][m]:.1f} dB)"))
        for a, b in pairs:
            ta, tb = tt.get(a), tt.get(b)
            cells.append(f"{ta / tb:.2f}" if ta and tb else "—")
        lines.append(f"| {r['scene']} | {r['reference_psnr']:.1f} dB | " + " | ".join(cells) + " |")
    return "\n".join(lines)


COLOURS = {"ours fixed": "#9ecae1", "ours adaptive": "#08519c", "ours adaptive+oidn": "#08306b",
           "cycles fixed": "#fdae6b",
           "cycles adaptive": "#d94801", "cycles adaptive+oidn": "#7f2704"}


def svg_plot(r: dict, targets, path: str) -> None:
    """PSNR against CPU seconds (log) for every mode of one scene: each mode's frontier (line) and every render
    (faint dots), the targets as dashed lines."""
    w, h, ml, mr, mt, mb = 560, 340, 56, 170, 28, 44
    pts = [(p["cpu"], p["psnr"]) for c in r["curves"].values() for p in c]
    t_lo = 10 ** math.floor(math.log10(min(t for t, _ in pts)))
    t_hi = 10 ** math.ceil(math.log10(max(t for t, _ in pts)))
    p_lo, p_hi = 5 * math.floor(min(p for _, p in pts) / 5), 5 * math.ceil(max(p for _, p in pts) / 5 + 0.01)
    span = math.log10(t_hi) - math.log10(t_lo)
    x = lambda t: ml + (math.log10(t) - math.log10(t_lo)) / span * (w - ml - mr)  # noqa: E731
    y = lambda p: mt + (p_hi - p) / (p_hi - p_lo) * (h - mt - mb)  # noqa: E731
    s = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" '
         f'font-size="11"><rect width="{w}" height="{h}" fill="white"/>',
         f'<text x="{ml}" y="16" font-size="13">{r["scene"]}: PSNR against Cycles\' reference vs CPU time</text>']
    e = int(math.log10(t_lo))
    while 10 ** e <= t_hi * 1.0001:
        xx = x(10 ** e)
        s.append(f'<line x1="{xx:.1f}" y1="{mt}" x2="{xx:.1f}" y2="{h - mb}" stroke="#ddd"/>'
                 f'<text x="{xx:.1f}" y="{h - mb + 14}" text-anchor="middle">{10 ** e:g} s</text>')
        e += 1
    for p in range(int(p_lo), int(p_hi) + 1, 5):
        s.append(f'<line x1="{ml}" y1="{y(p):.1f}" x2="{w - mr}" y2="{y(p):.1f}" stroke="#ddd"/>'
                 f'<text x="{ml - 6}" y="{y(p) + 4:.1f}" text-anchor="end">{p} dB</text>')
    for target in targets:
        if p_lo <= target <= p_hi:
            s.append(f'<line x1="{ml}" y1="{y(target):.1f}" x2="{w - mr}" y2="{y(target):.1f}" stroke="#444" '
                     f'stroke-dasharray="4 3"/>')
    for k, (m, c) in enumerate(r["curves"].items()):
        if not c:
            continue
        every = [(p["cpu"], p["psnr"]) for p in c]
        line = frontier(every)
        d = " ".join(f"{x(t):.1f},{y(p):.1f}" for t, p in line)
        col = COLOURS[m]
        s += [f'<circle cx="{x(t):.1f}" cy="{y(p):.1f}" r="1.8" fill="{col}" fill-opacity="0.35"/>' for t, p in every]
        s.append(f'<polyline points="{d}" fill="none" stroke="{col}" stroke-width="2"/>')
        s += [f'<circle cx="{x(t):.1f}" cy="{y(p):.1f}" r="2.5" fill="{col}"/>' for t, p in line]
        ly = mt + 14 + 18 * k
        s.append(f'<line x1="{w - mr + 10}" y1="{ly - 4}" x2="{w - mr + 30}" y2="{ly - 4}" stroke="{col}" '
                 f'stroke-width="2"/><text x="{w - mr + 36}" y="{ly}">{m}</text>')
    s.append(f'<text x="{(ml + w - mr) / 2:.0f}" y="{h - 8}" text-anchor="middle">CPU seconds (log)</text></svg>')
    with open(path, "w") as f:
        f.write("\n".join(s))


def info_of(a, targets, load, start) -> dict:
    return {"threads": a.threads, "targets": targets, "loadavg_start": load, "loadavg_end": os.getloadavg(),
            "seconds": time.perf_counter() - start, "cpus": os.cpu_count(), "reference_samples": a.reference_samples,
            "modes": a.modes.split(","), "utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime())}


def _write_json(path: str, info: dict, results: list) -> None:
    with open(path, "w") as f:
        json.dump({"info": info, "results": [{k: v for k, v in r.items() if k != "pictures"} for r in results]},
                  f, indent=1)


def _renderable(name: str) -> bool:
    import bpy

    build(name)
    return bool(_fidelity().renderable(bpy.context.scene))


SHEET_MODES = ("reference", "ours adaptive+oidn", "cycles adaptive+oidn")


def contact_sheet(path: str, results: list, max_bytes: int = 300_000) -> None:
    """Per scene a row: Cycles' reference | ours adaptive + OIDN | Cycles adaptive + OIDN, each at the first render
    of its curve that reached the first target (grey where none did), every tile :data:`FILE_WIDTH` wide, sRGB; two
    scenes a row; a JPEG whose quality drops (a PNG: halved) until it is under ``max_bytes``."""
    import OpenImageIO as oiio

    from tracer.colorspace import linear_to_srgb

    tw = FILE_WIDTH
    th = max(round(tw * r["pictures"]["reference"].shape[0] / r["pictures"]["reference"].shape[1]) for r in results)
    per_row, gap = 2, 6
    rows = math.ceil(len(results) / per_row)
    cw = len(SHEET_MODES) * (tw + 2) + gap
    sheet = np.ones((rows * (th + 2), per_row * cw, 3), np.float32)
    for k, r in enumerate(results):
        y0, x0 = (k // per_row) * (th + 2), (k % per_row) * cw
        for j, m in enumerate(SHEET_MODES):
            px = r["pictures"].get(m)
            tile = np.full((th, tw, 3), 0.5, np.float32)
            if px is not None:
                h, w = px.shape[:2]
                ys = (np.arange(th) * h / th).astype(int)
                xs = (np.arange(tw) * w / tw).astype(int)
                img = np.asarray(linear_to_srgb(np.clip(px, 0, 1)), np.float32)[ys][:, xs]
                tile[:] = 0.0
                hh = min(th, round(tw * h / w))
                tile[:hh] = img[:hh]
            sheet[y0:y0 + th, x0 + j * (tw + 2):x0 + j * (tw + 2) + tw] = tile
    img = (np.clip(sheet, 0, 1) * 255 + 0.5).astype(np.uint8)
    jpeg = path.lower().endswith((".jpg", ".jpeg"))
    for step in range(6):  # a JPEG loses quality, a PNG size, until the file is under max_bytes
        quality, k = 90 - 10 * step, (1 if jpeg else 2 ** step)
        px = np.ascontiguousarray(img[::k, ::k])
        spec = oiio.ImageSpec(px.shape[1], px.shape[0], 3, oiio.UINT8)
        if jpeg:
            spec.attribute("compression", f"jpeg:{quality}")
        out = oiio.ImageOutput.create(path)
        out.open(path, spec)
        out.write_image(px)
        out.close()
        if os.path.getsize(path) <= max_bytes:
            break
    print(f"contact sheet: {path} ({os.path.getsize(path) // 1024} KB): " +
          ", ".join(f"{i + 1}={r['scene']}" for i, r in enumerate(results)))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default=None, help="comma-separated: " + ", ".join(SCENES) + " and the names of "
                    "--blend's files (default: every lab scene and every file)")
    ap.add_argument("--blend", nargs="*", default=[], help="third-party .blend files or folders searched for them")
    ap.add_argument("--lab", action=argparse.BooleanOptionalAction, default=True,
                    help="with --blend and no --scenes: the lab scenes too (default)")
    ap.add_argument("--modes", default=",".join(MODES))
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--targets", default=",".join(f"{t:g}" for t in TARGETS), help="PSNR targets in dB")
    ap.add_argument("--reference-samples", type=int, default=4096)
    ap.add_argument("--json")
    ap.add_argument("--svg", help="directory for one PSNR-vs-time plot per scene")
    ap.add_argument("--sheet", help="contact sheet (JPEG): reference | ours adaptive+oidn | Cycles adaptive+oidn")
    a = ap.parse_args(argv)
    sys.path.insert(0, ROOT)
    FILES.update(blend_scenes(a.blend))
    names = (a.scenes.split(",") if a.scenes else (list(SCENES) if a.lab or not FILES else []) + list(FILES))
    unknown = [n for n in names if n not in SCENES and n not in FILES]
    if unknown:
        ap.error(f"unknown scenes: {', '.join(unknown)}")
    targets = tuple(float(t) for t in a.targets.split(","))
    load = os.getloadavg()
    start = time.perf_counter()
    results = []
    for n in names:
        if n in FILES and not _renderable(n):
            print(f"  {n}: nothing to render (a material library?): skipped", flush=True)
            continue
        results.append(sweep(n, a.threads, a.reference_samples, targets, tuple(a.modes.split(","))))
        if a.json:  # after every scene: a long run interrupted keeps what it measured
            _write_json(a.json, info_of(a, targets, load, start), results)
    info = info_of(a, targets, load, start)
    print(f"\nload average {load[0]:.2f} at the start, {info['loadavg_end'][0]:.2f} at the end "
          f"({os.cpu_count()} CPUs)")
    for target in targets:
        print(f"\ntime to {target:g} dB (CPU seconds):\n")
        print(table(results, target))
    if a.json:
        _write_json(a.json, info, results)
    if a.sheet:
        contact_sheet(a.sheet, results)
    if a.svg:
        os.makedirs(a.svg, exist_ok=True)
        for r in results:
            svg_plot(r, targets, os.path.join(a.svg, r["scene"].replace("/", "__") + ".svg"))


if __name__ == "__main__":
    main()

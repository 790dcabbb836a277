"""Fidelity against Cycles for third-party Blender files (issue #32, the Blender corpus): each .blend rendered by
Cycles (limited to a Whitted tracer's light paths) and by the add-on, compared by PSNR.

    python tools/blender_fidelity.py FILE_OR_DIR [...] [--out DIR] [--jsonl OUT.jsonl] [--width 160]
                                     [--samples 128] [--aa 4] [--depth 8] [--only SUBSTR[,SUBSTR...]]
                                     [--sheet SHEET.png] [--compare BEFORE.jsonl]

Nothing is downloaded: the files are given (a directory is searched for ``*.blend``). Two kinds of file:

- **scenes** (a file with something to render): the file's scene as it is saved: its camera (a file without one is
  framed by :func:`frame_camera`: 50 mm from the front-right-above, the bounding sphere of the visible geometry
  filling the narrower side), lights, world and materials; the render size scaled to ``--width`` at the file's
  aspect; Film > Transparent off on both sides (the world colour is part of the picture).
- **material libraries** (materials but no geometry: a library to append from): every material (users or fake
  user) on its own in :func:`material_scene`: a smooth UV sphere over a checker floor, a point light, an area light
  and a dim grey world, 96 × 96 ("each on a sphere against Cycles").

Cycles renders with :func:`blender_kit.cycles.whitted_cycles_settings` (diffuse bounces 0, caustics off, box filter:
the light paths a Whitted tracer has) at ``--samples`` and ``--depth``; lights keep their size (the tracer samples
area lights, point radii and sun angles). References are cached in ``.cache/blender-fidelity`` by a hash of the file,
the material and the settings. Ours: F12 with the add-on's engine (registered here)
with ``--aa`` and ``--depth``. Metrics (linear images): PSNR on sRGB (clipped, peak 1), MAE,
and ours/Cycles mean luminance; a side-by-side (Cycles | ours | |difference| × 4) per row in ``--out``.

``--compare BEFORE.jsonl`` prints each row's PSNR before and after and the medians; ``--sheet`` writes a contact
sheet of the worst rows (Cycles | ours), a PNG kept under 300 KB.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import sys
import time
import traceback

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:  # after PYTHONPATH: another checkout's tracer/addon there measures that checkout
    sys.path.append(ROOT)

CACHE = os.environ.get("WHITTED_FIDELITY_CACHE", os.path.join(ROOT, ".cache", "blender-fidelity"))
#: Bump when the reference scenes change (the material scene, the framing camera).
VERSION = 1
GEOMETRY = {"MESH", "CURVE", "SURFACE", "META", "FONT", "CURVES", "POINTCLOUD", "VOLUME"}
MATERIAL_SIZE = (96, 96)


# ---------------------------------------------------------------------------------------------------- metrics
def srgb(x: np.ndarray) -> np.ndarray:
    x = np.clip(np.asarray(x, np.float64), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((srgb(a) - srgb(b)) ** 2))
    return 99.0 if mse <= 1e-10 else 10.0 * math.log10(1.0 / mse)


def luminance(x: np.ndarray) -> float:
    return float(np.mean(np.asarray(x, np.float64)[..., :3] @ np.array([0.2126, 0.7152, 0.0722])))


def metrics(ours: np.ndarray, ref: np.ndarray) -> dict:
    lo, lr = luminance(ours), luminance(ref)
    return {"psnr": round(psnr(ours, ref), 2),
            "mae": round(float(np.mean(np.abs(np.asarray(ours, np.float64) - ref))), 5),
            "ratio": round(lo / lr, 3) if lr > 1e-6 else None}


# ---------------------------------------------------------------------------------------------------- scenes
def renderable(scene) -> list:
    return [o for o in scene.objects if o.type in GEOMETRY and o.visible_get() and not o.hide_render]


def frame_camera(scene):
    """A 50 mm camera from the front-right-above ((1, −1, 0.7) from the centre) that fits the bounding sphere of the
    visible geometry (evaluated: modifiers and instances included) into the narrower side of the image."""
    import bpy
    from mathutils import Vector

    dg = bpy.context.evaluated_depsgraph_get()
    pts = []
    for inst in dg.object_instances:
        ob = inst.object
        if ob.type not in GEOMETRY:
            continue
        m = inst.matrix_world
        pts += [m @ Vector(c) for c in ob.bound_box]
    if not pts:
        pts = [Vector((-1, -1, -1)), Vector((1, 1, 1))]
    arr = np.array([tuple(p) for p in pts])
    lo, hi = arr.min(0), arr.max(0)
    centre, radius = (lo + hi) / 2, max(float(np.linalg.norm(hi - lo)) / 2, 1e-3)
    data = bpy.data.cameras.new("fidelity camera")
    data.lens, data.sensor_width = 50.0, 36.0
    half = math.atan(18.0 / 50.0) * min(1.0, scene.render.resolution_y / scene.render.resolution_x)
    dist = radius / math.sin(half)
    data.clip_start, data.clip_end = dist * 1e-3, dist * 10
    cam = bpy.data.objects.new("fidelity camera", data)
    d = Vector((1.0, -1.0, 0.7)).normalized()
    cam.location = Vector(centre) + d * dist
    cam.rotation_euler = (-d).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(cam)
    scene.camera = cam


def prepare_scene(scene, width: int) -> None:
    r = scene.render
    aspect = (r.resolution_y * r.pixel_aspect_y) / max(r.resolution_x * r.pixel_aspect_x, 1)
    r.resolution_x, r.resolution_y, r.resolution_percentage = width, max(1, round(width * aspect)), 100
    r.pixel_aspect_x = r.pixel_aspect_y = 1.0
    r.film_transparent = False
    r.use_border = False
    if scene.camera is None or scene.camera.type != "CAMERA":
        frame_camera(scene)


def material_scene(path: str, name: str):
    """A fresh scene with the library's material ``name`` on a smooth UV sphere (r = 1) over a checker floor, lit by
    a 1000 W point light and a 200 W 1 m square area light, in a grey world of 0.05; 96 × 96."""
    import bpy

    from blender_kit import scene as bs

    scene = bs.reset(MATERIAL_SIZE)
    with bpy.data.libraries.load(path, link=False) as (src, dst):
        dst.materials = [name]
    mat = dst.materials[0]
    bs.add_uv_sphere((0, 0, 0), 1.0, segments=64, rings=32, material=mat)
    floor, nt, out = _checker_material()
    bs.add_plane((0, 0, -1.0), 12.0, material=floor, name="Floor")
    bs.add_point_light((3.0, -4.0, 5.0), power=1000.0)
    bs.add_area_light((-4.0, -2.0, 3.0), target=(0, 0, 0), power=200.0, size=1.0)
    bs.add_camera((0.0, -5.0, 1.5), target=(0.0, 0.0, -0.1), lens=50)
    bs.set_world((0.05, 0.05, 0.05))
    return scene


def _checker_material():
    import bpy

    mat = bpy.data.materials.new("fidelity floor")
    nt = mat.node_tree
    bsdf = next(n for n in nt.nodes if n.type == "BSDF_PRINCIPLED")
    out = next(n for n in nt.nodes if n.type == "OUTPUT_MATERIAL")
    chk = nt.nodes.new("ShaderNodeTexChecker")
    chk.inputs["Scale"].default_value = 6.0
    chk.inputs["Color1"].default_value = (0.7, 0.7, 0.7, 1)
    chk.inputs["Color2"].default_value = (0.15, 0.15, 0.15, 1)
    coord = nt.nodes.new("ShaderNodeTexCoord")
    nt.links.new(coord.outputs["UV"], chk.inputs["Vector"])
    nt.links.new(chk.outputs["Color"], bsdf.inputs["Base Color"])
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    bsdf.inputs["Roughness"].default_value = 1.0
    return mat, nt, out


def library_materials(path: str) -> list[str]:
    import bpy

    return sorted(m.name for m in bpy.data.materials if (m.users or m.use_fake_user) and not m.is_grease_pencil
                  and m.name != "Dots Stroke")


# ---------------------------------------------------------------------------------------------------- renders
def file_digest(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()[:16]


def cycles_image(scene, key: str, args) -> np.ndarray:
    """Cycles' render of ``scene`` (cached by ``key``), (H, W, 3) linear."""
    import bpy

    from blender_kit import scene as bs
    from blender_kit.cycles import whitted_cycles_settings

    os.makedirs(CACHE, exist_ok=True)
    path = os.path.join(CACHE, key + ".exr")
    if not os.path.exists(path):
        whitted_cycles_settings(scene, depth=args.depth, samples=args.samples)
        scene.render.film_transparent = False
        tmp = path + f".{os.getpid()}.tmp.exr"
        bs.render_exr(scene, tmp, engine="CYCLES")
        os.replace(tmp, path)
        bpy.context.view_layer.update()
    return bs.read_exr(path)["rgba"][..., :3]


def ours_image(scene, args) -> tuple[np.ndarray, list, float]:
    """Our render of ``scene`` as a user gets it: F12 with the registered Whitted engine (the render depsgraph:
    objects hidden from renders stay out), ``--aa`` and ``--depth`` in the scene's Whitted settings."""
    import addon
    from addon import engine
    from blender_kit import scene as bs

    if not hasattr(scene, "whitted"):
        addon.register()
    scene.whitted.samples = args.aa
    scene.whitted.max_depth = args.depth
    scene.render.film_transparent = False
    engine.WhittedRenderEngine.last_render = None
    t0 = time.perf_counter()
    out = bs.render_exr(scene, engine="WHITTED")
    seconds = time.perf_counter() - t0
    report = engine.WhittedRenderEngine.last_render
    return out["rgba"][..., :3], list(report.warnings) if report is not None else ["no render report"], seconds


def side_by_side(path: str, ref: np.ndarray, ours: np.ndarray) -> None:
    import OpenImageIO as oiio

    diff = np.abs(ours.astype(np.float64) - ref) * 4
    sheet = srgb(np.concatenate([ref, ours, diff], axis=1))
    h, w = sheet.shape[:2]
    out = oiio.ImageBuf(oiio.ImageSpec(w, h, 3, oiio.UINT8))
    out.set_pixels(oiio.ROI(0, w, 0, h), (sheet * 255 + 0.5).astype(np.uint8))
    out.write(path)


def measure(label: str, scene, key: str, args) -> dict:
    ref = cycles_image(scene, key, args)
    ours, warnings, seconds = ours_image(scene, args)
    row = {"name": label, **metrics(ours, ref), "seconds": round(seconds, 2), "warnings": warnings[:12]}
    if args.out:
        os.makedirs(args.out, exist_ok=True)
        png = os.path.join(args.out, label.replace("/", "__").replace(" ", "_") + ".png")
        side_by_side(png, ref, ours)
        row["png"] = png
    return row


def survey_file(path: str, rel: str, args) -> list[dict]:
    import bpy

    bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
    scene = bpy.context.scene
    digest = file_digest(path)
    settings = f"v{VERSION}-{bpy.app.version_string}-w{args.width}-s{args.samples}-d{args.depth}"
    if renderable(scene):
        prepare_scene(scene, args.width)
        key = hashlib.sha256(f"{digest}|{settings}".encode()).hexdigest()[:20]
        return [measure(rel, scene, f"{os.path.basename(rel)}-{key}", args)]
    rows = []
    for name in library_materials(path):
        if args.only_material and not any(s in name for s in args.only_material):
            continue
        scene = material_scene(path, name)
        key = hashlib.sha256(f"{digest}|{name}|{settings}".encode()).hexdigest()[:20]
        rows.append(measure(f"{rel}::{name}", scene, f"mat-{key}", args))
    return rows


def blend_files(inputs: list[str]) -> list[tuple[str, str]]:
    out = []
    for p in inputs:
        if os.path.isdir(p):
            base = os.path.dirname(os.path.abspath(p).rstrip("/"))
            for dirpath, _dirs, files in os.walk(p):
                for f in sorted(files):
                    if f.endswith(".blend"):
                        full = os.path.join(dirpath, f)
                        out.append((full, os.path.relpath(full, base)))
        else:
            out.append((p, os.path.basename(p)))
    return sorted(out, key=lambda t: t[1])


# ---------------------------------------------------------------------------------------------------- reports
def contact_sheet(path: str, rows: list[dict], n: int = 24, cols: int = 4, max_bytes: int = 300_000) -> None:
    """The ``n`` worst rows' side-by-sides (Cycles | ours, the difference dropped), tiled ``cols`` across, each
    labelled by its row number in the printed table; shrunk until the PNG is under ``max_bytes``."""
    import OpenImageIO as oiio

    worst = sorted((r for r in rows if r.get("png") and os.path.exists(r["png"])), key=lambda r: r["psnr"])[:n]
    if not worst:
        return
    tiles = []
    for r in worst:
        buf = oiio.ImageBuf(r["png"])
        px = np.asarray(buf.get_pixels(oiio.UINT8)).reshape(buf.spec().height, buf.spec().width, -1)[..., :3]
        w3 = px.shape[1] // 3
        tiles.append(px[:, :2 * w3])
    th = max(t.shape[0] for t in tiles)
    tw = max(t.shape[1] for t in tiles)
    rows_n = math.ceil(len(tiles) / cols)
    sheet = np.full((rows_n * (th + 4), cols * (tw + 4), 3), 255, np.uint8)
    for i, t in enumerate(tiles):
        y, x = (i // cols) * (th + 4), (i % cols) * (tw + 4)
        sheet[y:y + t.shape[0], x:x + t.shape[1]] = t
    scale = 1.0
    while True:
        img = sheet if scale == 1.0 else sheet[::int(round(1 / scale)), ::int(round(1 / scale))]
        out = oiio.ImageBuf(oiio.ImageSpec(img.shape[1], img.shape[0], 3, oiio.UINT8))
        out.set_pixels(oiio.ROI(0, img.shape[1], 0, img.shape[0]), np.ascontiguousarray(img))
        out.write(path)
        if os.path.getsize(path) <= max_bytes or scale < 0.3:
            break
        scale /= 2
    print(f"contact sheet: {path} ({os.path.getsize(path) // 1024} KB): " +
          ", ".join(f"{i + 1}={r['name']}" for i, r in enumerate(worst)))


def summary(rows: list[dict], before: dict | None = None) -> None:
    good = [r for r in rows if "psnr" in r]
    for i, r in enumerate(sorted(good, key=lambda r: r["psnr"])):
        was = before.get(r["name"], {}).get("psnr") if before else None
        prev = f"{was:6.2f} -> " if was is not None else ""
        print(f"{i + 1:3d} {prev}{r['psnr']:6.2f} dB  ratio {r['ratio']}  {r['name']}")
    for r in rows:
        if "error" in r:
            print(f"ERR {r['name']}: {r['error']}")
    ps = np.array([r["psnr"] for r in good])
    if len(ps):
        print(f"rows {len(ps)}: median {np.median(ps):.1f} dB, >= 30 dB {int((ps >= 30).sum())}, "
              f">= 33 dB {int((ps >= 33).sum())}, < 20 dB {int((ps < 20).sum())}")
    if before:
        common = [r for r in good if r["name"] in before and "psnr" in before[r["name"]]]
        if common:
            b = np.array([before[r["name"]]["psnr"] for r in common])
            a = np.array([r["psnr"] for r in common])
            print(f"common {len(common)}: median before {np.median(b):.1f} -> after {np.median(a):.1f} dB; "
                  f"< 20 dB {int((b < 20).sum())} -> {int((a < 20).sum())}; >= 30 dB {int((b >= 30).sum())} -> "
                  f"{int((a >= 30).sum())}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("inputs", nargs="+")
    ap.add_argument("--out", default=None, help="side-by-side PNGs here")
    ap.add_argument("--jsonl", default=None)
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--samples", type=int, default=128, help="Cycles samples per pixel")
    ap.add_argument("--aa", type=int, default=4, help="our N×N samples per pixel")
    ap.add_argument("--depth", type=int, default=8)
    ap.add_argument("--only", default="", help="comma-separated substrings of the file paths to run")
    ap.add_argument("--only-material", default="", help="comma-separated substrings of library material names")
    ap.add_argument("--sheet", default=None)
    ap.add_argument("--compare", default=None)
    args = ap.parse_args(argv)
    args.only_material = [s for s in args.only_material.split(",") if s]
    only = [s for s in args.only.split(",") if s]
    files = [(p, rel) for p, rel in blend_files(args.inputs) if not only or any(s in rel for s in only)]
    rows = []
    sink = open(args.jsonl, "w") if args.jsonl else None
    for path, rel in files:
        try:
            got = survey_file(path, rel, args)
        except Exception as exc:  # noqa: BLE001 - one bad file does not stop the survey
            traceback.print_exc()
            got = [{"name": rel, "error": f"{type(exc).__name__}: {exc}"}]
        for r in got:
            print(json.dumps({k: v for k, v in r.items() if k != "warnings"}), flush=True)
            rows.append(r)
            if sink:
                sink.write(json.dumps(r) + "\n")
                sink.flush()
    if sink:
        sink.close()
    before = None
    if args.compare:
        with open(args.compare) as f:
            before = {r["name"]: r for r in map(json.loads, f) if r}
    summary(rows, before)
    if args.sheet:
        contact_sheet(args.sheet, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())

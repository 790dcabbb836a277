"""Fidelity against references (issue #32), first corpus: OpenUSD's imaging tests with an exact camera, against
Storm's baseline PNGs, by silhouette IoU.

    python tools/fidelity.py OPENUSD_CHECKOUT [--out /tmp/fidelity] [--only NAME[,NAME...]] [--no-dof]
                             [--aa 2] [--jsonl OUT.jsonl]
    python tools/fidelity.py materialx MATERIALX_CHECKOUT ...   (the MaterialX corpus: tools/fidelity_mtlx.py)
    python tools/fidelity.py arnold ARNOLD_USD_CHECKOUT ...     (arnold-usd's test suite: tools/fidelity_arnold.py)

Nothing is downloaded: OPENUSD_CHECKOUT is a checkout (or an extracted copy) of OpenUSD holding
``pxr/usdImaging/usdImagingGL/CMakeLists.txt`` and its ``testenv``. Every ``pxr_register_test`` there whose
``testUsdImagingGLBasicDrawing`` command names a ``-camera`` (the exact-camera tests: the stage's own camera, not
Storm's ``-frameAll`` framing) is a candidate; the scene-index duplicates, the volume tests (volumes are not drawn),
AOV visualisations and the display/data-window framing tests are left out (:func:`wanted`). Each test is rendered
in-process (``usd_io.load_stage`` + ``tracer.render``) at each of its ``-times`` with its camera conformed to the
baseline's aspect as the test app conforms it (``-windowPolicy``, default matchVertically: the vertical aperture
kept; passed to the reader as a RenderSettings' aspectRatioConformPolicy on the session layer), at the size of its
baseline image, with a transparent film, one sample through each pixel centre (:data:`DEFAULT_AA`), at the test's
``-times`` (else the default time, as the app draws), with the purposes the app shows, and compared:

    silhouette  at half coverage: ours alpha >= 0.5 (the pixel centre covered); Storm's: pixels other than the test's clear colour
                (``-clear``, else testUsdImagingGLBasicDrawing's default orange (1, 0.5, 0.1)) as the PNG stores it,
                and at least half as far from it as the furthest pixel within 2 px (:func:`storm_mask`: Storm's
                multisampled edges)
    IoU         |ours ∩ Storm's| / |ours ∪ Storm's|

and a side-by-side PNG is written to ``OUT`` (Storm's baseline | ours | the masks: white both, red ours only,
green Storm's only). One JSON line per image goes to ``--jsonl``; the summary prints one row per image.

``--frame-all`` measures the ``-frameAll`` tests without a camera instead, each seen as the test app frames it
(:func:`frame_all_camera`), a separate table. ``--no-dof`` renders without depth of field (Storm draws none). ``--storm-approximations`` explains misses that are
Storm's: it draws implicit gprims with Storm's 10 segments around and each NurbsPatch as its control hull. Pointed at main's checkout on PYTHONPATH, the same
tool gives the "before" figures.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shlex
import sys
import time

import numpy as np

#: testUsdImagingGLBasicDrawing's clear colour when the test gives no ``-clear`` (UsdImagingGL_UnitTestGLDrawing).
DEFAULT_CLEAR = (1.0, 0.5, 0.1)
THRESHOLD = 0.5 / 255  # 8-bit: any other value
#: Samples per pixel side of our render. One sample, through the pixel centre (tracer.integrator.tiles.pixel_sample
#: with N = 1), answers "is this pixel at least half covered?" exactly for an edge straight across the pixel: the
#: centre is covered iff the edge leaves at least half of the pixel on the surface's side. N×N jittered samples
#: thresholded at 0.5 answer it with their noise: an edge 0.48 px into a pixel (Mipmap_017) reads ≥ 0.5 whenever the
#: stratum holding it has all its samples inside (0.923⁴ = 73 % of such pixels at 4×4, 32 % at 5×5).
DEFAULT_AA = 1


#: Exact-camera tests whose baseline has no silhouette to compare (listed in the summary with the reason, not
#: rendered): a visible DomeLight fills Storm's background, or the test composites several frames into one image.
UNMEASURED = {"visible dome": "a textured DomeLight fills Storm's background: no clear colour, no silhouette",
              "-presentComposite": "the test composites its -times into one image (frames accumulate)",
              "-clipPlane": "an OpenGL clip plane of the test app (-clipPlane), not in the stage",
              "points": "-shading points: Storm draws each vertex as a point, no surface",
              "-unloadedAsBounds": "the test app opens the stage unloaded and draws payloads as boxes",
              "-presentDisabled": "the test app presents nothing (-presentDisabled): the baseline is black"}


def unmeasured(test: dict) -> str | None:
    if not os.path.exists(test["stage"]):
        return "the test's stage is not in the snapshot (its TESTENV folder is absent)"
    if "-presentComposite" in test["cmd"]:
        return UNMEASURED["-presentComposite"]
    argv = test["cmd"].split()
    if "-clipPlane" in argv:
        return UNMEASURED["-clipPlane"]
    if "-unloadedAsBounds" in argv:
        return UNMEASURED["-unloadedAsBounds"]
    if "-presentDisabled" in argv:
        return UNMEASURED["-presentDisabled"]
    if "-shading" in argv and argv[argv.index("-shading") + 1:][:1] == ["points"]:
        return UNMEASURED["points"]
    text = open(test["stage"], errors="replace").read() if test["stage"].endswith(".usda") else ""
    if re.search(r"def DomeLight\b", text) and "inputs:texture:file" in text:
        return UNMEASURED["visible dome"]
    return None


def wanted(name: str, cmd: str, frame_all: bool = False) -> bool:
    """An exact-camera test (``-camera``), or with ``frame_all`` a ``-frameAll`` test without one (the test app
    frames the stage itself: :func:`frame_all_camera`)."""
    argv = cmd.split()
    if "SceneIndex" in name or "testUsdImagingGLBasicDrawing" not in cmd:
        return False
    if ("-camera" in argv) == frame_all or (frame_all and "-frameAll" not in argv):
        return False
    return not any(k in cmd for k in ("volumeRaymarching", "-rendererAov depth", "-dataWindow", "-displayWindow"))


def _purposes(opt: dict) -> tuple:
    """The purposes the test app draws (UsdImagingGLRenderParams: guides hidden, proxy shown, render hidden unless
    ``-guidesPurpose``/``-proxyPurpose``/``-renderPurpose`` say otherwise), as load_stage's purposes."""
    shown = {"guide": False, "proxy": True, "render": False}
    for flag, purpose in (("-guidesPurpose", "guide"), ("-proxyPurpose", "proxy"), ("-renderPurpose", "render")):
        if flag in opt:
            shown[purpose] = opt[flag][:1] == ["show"]
    return ("default",) + tuple(p for p in ("render", "proxy", "guide") if shown[p])


def _complexity_suffix(c: float) -> str:
    """``-complexities``' baseline suffix: C++ ``std::stringstream << float`` (1.0 -> "1", 1.1 -> "1.1")."""
    return format(c, "g")


def tests_of(root: str, frame_all: bool = False) -> list[dict]:
    """The exact-camera tests of usdImagingGL's CMakeLists.txt (commented-out ones too: their baselines exist);
    with ``frame_all`` the ``-frameAll`` tests without a camera instead (one entry per ``-complexities`` value)."""
    gl = os.path.join(root, "pxr", "usdImaging", "usdImagingGL")
    text = open(os.path.join(gl, "CMakeLists.txt")).read()
    text = re.sub(r"^#", "", text, flags=re.M)
    out = []
    for name, cmd, rest in re.findall(r'pxr_register_test\((\S+)\s+COMMAND\s+"([^"]*)"(.*?)\n\)', text, re.S):
        if not wanted(name, cmd, frame_all):
            continue
        argv = shlex.split(cmd)
        opt = {}
        i = 1
        while i < len(argv):
            a = argv[i]
            if a.startswith("-") and not re.match(r"-\d", a):
                vals = []
                j = i + 1
                while j < len(argv) and (not argv[j].startswith("-") or re.match(r"-\d", argv[j])):
                    vals.append(argv[j])
                    j += 1
                opt[a] = vals
                i = j
            else:
                i += 1
        env = re.search(r"TESTENV\s+(\S+)", rest)
        testenv = os.path.join(gl, "testenv", env.group(1) if env else name)
        stage = os.path.join(testenv, opt["-stage"][0])
        write = opt["-write"][0]
        times = [float(t) for t in opt.get("-times", [])]
        clear = tuple(float(c) for c in opt["-clear"][:3]) if "-clear" in opt else DEFAULT_CLEAR
        complexities = [(float(c), "_" + _complexity_suffix(float(c))) for c in opt.get("-complexities", [])] or \
            [(float(opt.get("-complexity", ["1.0"])[0]), "")]
        for complexity, suffix in complexities:
            stem, ext = os.path.splitext(write)
            stem += suffix
            images = []
            for t in (list(dict.fromkeys(times)) or [None]):
                base = os.path.join(testenv, "baseline", stem + ext if t is None else f"{stem}_{int(t):03d}{ext}")
                images.append((t, base))
            out.append(dict(name=name + suffix, stage=stage, camera=opt["-camera"][0] if "-camera" in opt else None,
                            images=images, clear=clear, complexity=complexity, purposes=_purposes(opt),
                            window_policy=opt.get("-windowPolicy", ["matchVertically"])[0], cmd=cmd))
    seen, unique = set(), []
    for t in out:  # one row per (stage, camera, baseline)
        key = (t["stage"], t["camera"], tuple(b for _t, b in t["images"]))
        if key not in seen:
            seen.add(key)
            unique.append(t)
    return unique


class Unmeasured(Exception):
    """A baseline without a silhouette to compare (:data:`UNMEASURED`)."""


def read_rgb(path: str) -> np.ndarray:
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(path)
    px = buf.get_pixels(oiio.FLOAT)
    if px is None or px.size == 0:
        raise ValueError(f"{path}: unreadable ({oiio.geterror()})")
    return np.asarray(px, np.float32)[..., :3]


def written_clear(rgb: np.ndarray, clear) -> np.ndarray:
    """The clear colour as the baseline stores it (8-bit: (1, 0.5, 0.1) is written (255, 128, 25)): the most
    frequent colour within 3/255 of ``clear``, else ``clear``."""
    flat = rgb.reshape(-1, 3)
    close = flat[np.abs(flat - np.asarray(clear, np.float32)).max(axis=1) <= 3 / 255]
    if not len(close):
        return np.asarray(clear, np.float32)
    values, counts = np.unique(np.round(close * 255), axis=0, return_counts=True)
    return (values[np.argmax(counts)] / 255).astype(np.float32)


def storm_mask(rgb: np.ndarray, clear) -> np.ndarray:
    """Storm's silhouette at half coverage, as ours (alpha >= 0.5): a pixel that is not the clear colour as
    written (:func:`written_clear`; Storm writes it exactly where nothing is drawn, so dark texels against a
    black clear count) and at least half as far from it as the furthest pixel within 2 px (an edge pixel Storm's
    multisampling blended with the clear colour holds that share of the surface's colour; only pixels next to
    the clear colour are such edges)."""
    d = np.abs(rgb - written_clear(rgb, clear)).max(axis=2)
    h, w = d.shape
    pad = np.pad(d, 2, mode="edge")
    near = np.max([pad[y:y + h, x:x + w] for y in range(5) for x in range(5)], axis=0)
    drawn = d > THRESHOLD
    pd = np.pad(drawn, 1, mode="edge")
    edge = drawn & ~(pd[:-2, 1:-1] & pd[2:, 1:-1] & pd[1:-1, :-2] & pd[1:-1, 2:])  # next to the clear colour
    return drawn & (~edge | (d >= 0.5 * near))


def uniform(rgba: np.ndarray) -> bool:
    """A blank frame: every pixel the same colour and alpha (nothing drawn, or a surface filling it flat)."""
    flat = np.asarray(rgba).reshape(-1, rgba.shape[-1])
    return bool(np.all(np.abs(flat - flat[0]).max(axis=0) <= THRESHOLD))


def iou(a: np.ndarray, b: np.ndarray) -> float:
    union = np.count_nonzero(a | b)
    return 1.0 if union == 0 else np.count_nonzero(a & b) / union


def _complexity(c: float) -> str:
    return "low" if c < 1.1 else "medium" if c < 1.2 else "high" if c < 1.3 else "veryhigh"


#: testUsdImagingGLBasicDrawing's ``-windowPolicy`` (CameraUtilConformWindowPolicy; default matchVertically) as
#: UsdRender's aspectRatioConformPolicy: how the camera's aperture meets the baseline's aspect.
WINDOW_POLICY = {"matchVertically": "adjustApertureWidth", "matchHorizontally": "adjustApertureHeight",
                 "fit": "expandAperture", "crop": "cropAperture", "dontConform": "adjustPixelAspectRatio"}


def reference_camera(path, camera: str, policy: str):
    """The stage at ``path`` (or an open stage) with a RenderSettings on its session layer that conforms ``camera``
    as the test app does (its window policy, :data:`WINDOW_POLICY`): (stage, settings prim path). The stage's own
    layers are not touched."""
    from pxr import Sdf, Usd, UsdRender

    stage = Usd.Stage.Open(path) if isinstance(path, str) else path
    with Usd.EditContext(stage, stage.GetSessionLayer()):
        rs = UsdRender.Settings.Define(stage, "/FidelityReference")
        rs.CreateCameraRel().SetTargets([Sdf.Path(camera)])
        rs.CreateAspectRatioConformPolicyAttr(WINDOW_POLICY[policy])
    return stage, "/FidelityReference"


#: testUsdImagingGLBasicDrawing's -frameAll view: GfFrustum::SetPerspective(60, width / height, 1, 100000).
FRAME_ALL_FOV = 60.0
FRAME_ALL_CLIPPING = (1.0, 100000.0)


def frame_all_camera(stage, purposes, width: int, height: int, path: str = "/FidelityFrameAll") -> str:
    """The test app's ``-frameAll`` view as a camera on the session layer (testUsdImagingGLBasicDrawing.cpp,
    InitTest and DrawTest): the world bound of the pseudo-root by ``UsdGeomBBoxCache(UsdTimeCode::Default(),
    purposes, useExtentHints=true)``, aligned; the view translated by −centre and pushed back by the bound's
    diagonal; for a Z-up stage the translation's y and z swapped (−cx, −cz, −cy − size) after a −90° turn about
    X, exactly as the app does (so a Z-up stage whose centre is off y = 0 is seen from 2·cy + size away, not
    size); a 60° vertical field of view at the image's aspect, clipping 1–100000. Returns the camera's path."""
    from pxr import Gf, Usd, UsdGeom

    bound = UsdGeom.BBoxCache(Usd.TimeCode.Default(), list(purposes), True).ComputeWorldBound(
        stage.GetPseudoRoot()).ComputeAlignedRange()
    lo, hi = bound.GetMin(), bound.GetMax()
    centre = (lo + hi) / 2.0
    size = (hi - lo).GetLength()
    if UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z:
        translate = Gf.Vec3d(-centre[0], -centre[2], -centre[1] - size)
    else:
        translate = Gf.Vec3d(-centre[0], -centre[1], -centre[2] - size)
    translate = Gf.Vec3d(*(float(np.float32(v)) for v in translate))  # the app keeps it in a float[3]
    view = Gf.Matrix4d(1.0).SetTranslate(translate)  # rotations 0: the app's _rotate stays 0
    if UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z:
        view = Gf.Matrix4d().SetRotate(Gf.Rotation(Gf.Vec3d(1, 0, 0), -90.0)) * view
    vertical = 20.0
    focal = vertical / 2 / np.tan(np.radians(FRAME_ALL_FOV) / 2)
    with Usd.EditContext(stage, stage.GetSessionLayer()):
        cam = UsdGeom.Camera.Define(stage, path)
        cam.AddTransformOp().Set(view.GetInverse())
        cam.CreateFocalLengthAttr(float(focal))
        cam.CreateVerticalApertureAttr(vertical)
        cam.CreateHorizontalApertureAttr(vertical * width / height)
        cam.CreateClippingRangeAttr(Gf.Vec2f(*FRAME_ALL_CLIPPING))
    return path


def nurbs_as_hulls(stage, time) -> None:
    """Each NurbsPatch drawn as Storm draws it: the quad mesh of its control points (UsdImaging's NurbsPatch
    adapter does not evaluate the surface), on the session layer. Explanatory only (``--storm-approximations``)."""
    from pxr import Usd, UsdGeom

    t = Usd.TimeCode(time) if time is not None else Usd.TimeCode.Default()
    with Usd.EditContext(stage, stage.GetSessionLayer()):
        for prim in [p for p in stage.Traverse() if p.IsA(UsdGeom.NurbsPatch)]:
            patch = UsdGeom.NurbsPatch(prim)
            nu, nv = patch.GetUVertexCountAttr().Get(), patch.GetVVertexCountAttr().Get()
            hull = UsdGeom.Mesh.Define(stage, prim.GetPath().GetParentPath().AppendChild(prim.GetName() + "_hull"))
            hull.CreatePointsAttr(patch.GetPointsAttr().Get(t))
            hull.CreateFaceVertexIndicesAttr([j * nu + i + k for j in range(nv - 1) for i in range(nu - 1)
                                              for k in (0, 1, nu + 1, nu)])
            hull.CreateFaceVertexCountsAttr([4] * ((nu - 1) * (nv - 1)))
            hull.CreateSubdivisionSchemeAttr("none")
            hull.CreateDoubleSidedAttr(True)
            hull.GetPrim().CreateAttribute("xformOpOrder", prim.GetAttribute("xformOpOrder").GetTypeName()).Set(
                prim.GetAttribute("xformOpOrder").Get())
            for op in UsdGeom.Xformable(prim).GetOrderedXformOps():
                a = op.GetAttr()
                hull.GetPrim().CreateAttribute(a.GetName(), a.GetTypeName()).Set(a.Get(t))
            prim.SetActive(False)


def app_time(t):
    """The time code the test app draws at: each ``-times`` value, else ``UsdTimeCode::Default()`` (the app's -999),
    where an attribute with only time samples reads its fallback, not its first sample."""
    from pxr import Usd

    return Usd.TimeCode.Default() if t is None else Usd.TimeCode(float(t))


def render_one(test: dict, t, size, aa: int, dof: bool, segments=None, hulls=False):
    import tracer
    from usd_io.reader import load_stage

    from pxr import Usd

    h, w = size
    purposes = test.get("purposes", ("default", "proxy"))
    camera = test["camera"]
    stage = Usd.Stage.Open(test["stage"])
    if camera is None:  # -frameAll: the test app's own view
        camera = frame_all_camera(stage, purposes, w, h)
    stage, settings_prim = reference_camera(stage, camera, test["window_policy"])
    if hulls:
        nurbs_as_hulls(stage, t)
    kw = dict(time=app_time(t), camera=camera, width=w, height=h, complexity=_complexity(test["complexity"]),
              render_settings_prim=settings_prim, purposes=purposes)
    if not dof:
        kw["depth_of_field"] = False
    if segments:
        kw["segments"] = segments
    scene, info = load_stage(stage, **kw)
    settings = tracer.RenderSettings(width=info.width, height=info.height, samples=aa, transparent=True,
                                     light_samples=1, sky_samples=0, max_depth=1)
    image = render_quiet(scene, settings)
    return np.asarray(image.rgba, np.float32), info


def render_quiet(scene, settings):
    import tracer

    return tracer.render(scene, settings)


def side_by_side(path: str, storm: np.ndarray, ours_rgba: np.ndarray, a: np.ndarray, b: np.ndarray) -> None:
    from tracer.film import Image, write_image  # noqa: F401 (written through OpenImageIO)
    import OpenImageIO as oiio

    ours = np.clip(ours_rgba[..., :3], 0, 1) ** (1 / 2.2)
    masks = np.zeros_like(storm)
    masks[a & b] = 1
    masks[a & ~b] = (1, 0, 0)
    masks[~a & b] = (0, 1, 0)
    sheet = np.concatenate([storm, ours, masks], axis=1)
    spec = oiio.ImageSpec(sheet.shape[1], sheet.shape[0], 3, oiio.UINT8)
    out = oiio.ImageBuf(spec)
    out.set_pixels(oiio.ROI(0, sheet.shape[1], 0, sheet.shape[0]), (np.clip(sheet, 0, 1) * 255 + 0.5).astype(np.uint8))
    out.write(path)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["materialx"]:  # the MaterialX corpus (tools/fidelity_mtlx.py)
        sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
        import fidelity_mtlx

        return fidelity_mtlx.main(argv[1:])
    if argv[:1] == ["arnold"]:  # arnold-usd's test suite against Arnold's references (tools/fidelity_arnold.py)
        sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
        import fidelity_arnold

        return fidelity_arnold.main(argv[1:])
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("openusd")
    p.add_argument("--out", default="/tmp/fidelity")
    p.add_argument("--only", default="", help="comma-separated test names or stage file names")
    p.add_argument("--no-dof", action="store_true", help="render without depth of field (Storm draws none)")
    p.add_argument("--aa", type=int, default=DEFAULT_AA,
                   help="N×N samples per pixel (default 1: the pixel centre decides half coverage; see DEFAULT_AA)")
    p.add_argument("--storm-approximations", action="store_true",
                   help="draw as Storm approximates (an explanatory run, not the figures): implicit gprims with 10 "
                   "segments around (Storm's at complexity 1.0) and each NurbsPatch as its control hull")
    p.add_argument("--frame-all", action="store_true",
                   help="the -frameAll tests without a camera (the test app's own view: frame_all_camera) instead "
                   "of the exact-camera ones")
    p.add_argument("--jsonl", default=None)
    p.add_argument("--list", action="store_true")
    args = p.parse_args(argv)
    tests = tests_of(args.openusd, args.frame_all)
    if args.only:
        keep = set(args.only.split(","))
        tests = [t for t in tests if t["name"] in keep or os.path.basename(t["stage"]) in keep]
    if args.list:
        for t in tests:
            print(t["name"], os.path.basename(t["stage"]), t["camera"], [os.path.basename(b) for _t, b in t["images"]])
        return 0
    os.makedirs(args.out, exist_ok=True)
    rows = []
    for test in tests:
        skip = unmeasured(test)
        for t, base in test["images"]:
            row = dict(test=test["name"], stage=os.path.basename(test["stage"]), time=t,
                       baseline=os.path.basename(base), table="frameAll" if test["camera"] is None else "camera")
            start = time.perf_counter()
            try:
                if skip:
                    raise Unmeasured(skip)
                if not os.path.exists(base):
                    raise Unmeasured("no baseline image in the snapshot")
                storm = read_rgb(base)
                approx = args.storm_approximations
                rgba, info = render_one(test, t, storm.shape[:2], args.aa, not args.no_dof, 10 if approx else None,
                                        approx)
                a, b = rgba[..., 3] >= 0.5, storm_mask(storm, test["clear"])
                row.update(iou=round(iou(a, b), 4), ours_px=int(a.sum()), storm_px=int(b.sum()),
                           size=list(storm.shape[:2][::-1]), warnings=len(info.warnings),
                           warning_texts=[w[:200] for w in info.warnings[:8]],
                           blank_ours=bool(uniform(rgba)), blank_storm=bool(not b.any()))
                if info.nothing_drawn:  # `whitted render` exits 2 on this stage (usd_io.reader._say_if_empty)
                    row["refused"] = info.nothing_drawn
                if "-shading wire " in test["cmd"] + " ":
                    row["shading"] = "wire"  # Storm draws the edges only: its silhouette is lines
                side_by_side(os.path.join(args.out, os.path.splitext(row["baseline"])[0] + ".png"), storm, rgba, a, b)
            except Unmeasured as why:
                row.update(iou=None, unmeasured=str(why))
            except Exception as exc:  # noqa: BLE001 — a row per failure, the survey goes on
                row.update(iou=None, error=f"{type(exc).__name__}: {exc}"[:300])
            row["seconds"] = round(time.perf_counter() - start, 1)
            rows.append(row)
            shown = format(row["iou"], ".4f") if row.get("iou") is not None else \
                ("unmeasured: " + row["unmeasured"] if "unmeasured" in row else "ERR " + row["error"])
            print(f"{row['stage']:40s} {row['baseline']:58s} {shown}", flush=True)
            if args.jsonl:
                with open(args.jsonl, "a") as f:
                    f.write(json.dumps(row) + "\n")
    ok = [r for r in rows if r.get("iou") is not None]
    print(f"{len(ok)} images measured ({len(rows) - len(ok)} not: "
          f"{sum('unmeasured' in r for r in rows)} unmeasured, {sum('error' in r for r in rows)} errors); "
          f"IoU >= 0.95: {sum(r['iou'] >= 0.95 for r in ok)}; >= 0.9: {sum(r['iou'] >= 0.9 for r in ok)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Fidelity against references (issue #32), the Arnold corpus: arnold-usd's test suite (``testsuite/test_NNNN``)
against the reference images Arnold rendered (``ref/reference.tif``: 8-bit, sRGB-encoded, for most tests).

    python tools/fidelity.py arnold ARNOLD_USD_CHECKOUT [--out /tmp/fidelity-arnold] [--only test_0200,...]
                                    [--aa 3] [--jsonl OUT.jsonl] [--sheet SHEET.png] [--list]
                                    [--rendering-space arnold|rec709]

Nothing is downloaded: ARNOLD_USD_CHECKOUT is a checkout (or extracted copy) of Autodesk/arnold-usd holding
``testsuite/``. A test is a candidate when its README's ``PARAMS`` name a USD ``scene`` (the suite's CMake
(cmake/utils/test.cmake) renders ``data/<scene>`` with ``kick -r 160 120 -sm lambert ... <kick_params>``; tests
without a ``scene`` render ``test.ass``, an Arnold scene this tracer does not read), the scene and a reference
image exist, and the stage has a camera (kick's ``-c`` when given, else a RenderSettings' camera, else the first
camera: the one Arnold's USD reader creates first). Each is rendered in-process (``usd_io.load_stage`` +
``tracer.render``, the stage opened from a mirror of kick's run directory: :func:`kick_layout`) at the
reference's size, at kick's ``-frame`` (else the stage's default time), through that
camera conformed as Arnold conforms it (its ``fov`` is horizontal: the horizontal aperture is kept, UsdRender's
adjustApertureHeight, written on a RenderSettings on the session layer), with no default light (Arnold adds none),
a black background (Arnold's) and the lights in Arnold's units (``light_units="arnold"``, usd_io.exporters; the
spec's where the RenderSettings set ``arnold:global:usdlux_version``) and Arnold's default shader on unbound
geometry (kick gives every stage arnold-usd's ``_default_arnold_shader``, Arnold content or not), and compared
with the reference read as Arnold wrote it (:func:`reference_linear`: float outputs linear; integer outputs in
the narrow colour space, sRGB-encoded unless the stage names a linear one; ``reference_encoding`` in the JSONL
says which and why). Our colour numbers are read as Arnold's rendering space (:func:`rendering_space`: ACEScg,
Arnold's default, unless the stage sets one; colour textures converted into it), so an integer reference is
compared with our render converted to Rec.709 primaries (``--rendering-space rec709`` compares the numbers as they
are):

    psnr      10·log10(1 / MSE) over R, G, B of both images' **linear** values clamped to [0, 1] (an 8-bit
              reference decoded from sRGB holds min(linear, 1); float references are clamped the same way).
    psnr_srgb the same after the sRGB transfer function (how a viewer sees the pair; for reference only)
    psnr_other_reading  ours against the reference read the other way (sRGB-encoded <-> linear), a diagnostic
    de        ΔE2000 between the mean colours (linear, clamped, as sRGB-primaries Lab) of the pixels either image
              covers (reference alpha ≥ 0.5 or our object id; only ours where the reference is opaque everywhere,
              as it is where a dome is seen): a missing environment does not hide a wrong albedo
    iou       silhouette IoU of reference alpha ≥ 0.5 against the pixels whose majority sample hit an object

``OUT/<test>.png`` is the side-by-side pair (reference | ours | 4 × |difference|, sRGB-encoded for viewing);
``--jsonl`` gets one JSON line per test; ``--sheet`` a contact sheet (reference | ours, worst PSNR first) small
enough to commit. The summary prints one row per test, then the median PSNR and the count at ≥ 25 dB.
"""

from __future__ import annotations

import argparse
import ast
import json
import os
import re
import shlex
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from fidelity_mtlx import delta_e2000, read_rgba, srgb_linear_to_lab  # noqa: E402

USD_EXT = (".usd", ".usda", ".usdc", ".usdz")
TARGET_DB = 25.0


def params_of(readme: str) -> dict:
    """The README's ``PARAMS: {...}`` as a dict ({} when absent or unreadable)."""
    m = re.search(r"PARAMS\s*:\s*(\{.*\})", readme, re.S)
    if not m:
        return {}
    try:
        got = ast.literal_eval(m.group(1))
    except (ValueError, SyntaxError):
        got = {}
        for key in ("scene", "kick_params"):
            k = re.search(rf"'{key}'\s*:\s*'([^']*)'", m.group(1))
            if k:
                got[key] = k.group(1)
    return got if isinstance(got, dict) else {}


def kick_options(kick_params: str) -> dict:
    """kick's ``-c CAMERA``, ``-frame F`` and ``-r W H`` from the test's ``kick_params``."""
    argv = shlex.split(kick_params or "")
    out = {}
    for i, a in enumerate(argv):
        if a == "-c" and i + 1 < len(argv):
            out["camera"] = argv[i + 1]
        elif a == "-frame" and i + 1 < len(argv):
            out["frame"] = float(argv[i + 1])
        elif a == "-r" and i + 2 < len(argv):
            out["size"] = (int(argv[i + 1]), int(argv[i + 2]))
    return out


def tests_of(root: str) -> list[dict]:
    """Every test of ``root/testsuite`` whose scene is a USD file with a reference image (see the module doc);
    ``skip`` holds the reason when it is not rendered."""
    suite = os.path.join(root, "testsuite") if os.path.isdir(os.path.join(root, "testsuite")) else root
    out = []
    for name in sorted(os.listdir(suite)):
        d = os.path.join(suite, name)
        readme = os.path.join(d, "README")
        if not name.startswith("test_") or not os.path.isfile(readme):
            continue
        params = params_of(open(readme, errors="replace").read())
        scene = str(params.get("scene", "test.ass"))
        if not scene.lower().endswith(USD_EXT):
            continue
        ref = os.path.join(d, str(params.get("reference_image", "ref/reference.tif")))
        if not os.path.isfile(ref):
            alt = [os.path.join(d, "ref", f) for f in sorted(os.listdir(os.path.join(d, "ref")))
                   if f.startswith("reference.") and f.rsplit(".", 1)[-1] in ("tif", "exr", "png", "jpg")] \
                if os.path.isdir(os.path.join(d, "ref")) else []
            ref = alt[0] if alt else ref
        test = dict(name=name, stage=os.path.join(d, "data", scene), reference=ref,
                    title=open(readme, errors="replace").read().strip().split("\n")[0][:80],
                    **kick_options(str(params.get("kick_params", ""))))
        if not os.path.isfile(test["stage"]):
            test["skip"] = "scene file absent from the checkout"
        elif not os.path.isfile(ref):
            test["skip"] = "no reference image"
        out.append(test)
    return out


def find_camera(stage, wanted: str | None):
    """kick's camera, else the RenderSettings' camera, else the first camera in traversal order (None: none)."""
    from pxr import Usd, UsdGeom, UsdRender

    if wanted:
        p = stage.GetPrimAtPath(wanted)
        return wanted if p and p.IsA(UsdGeom.Camera) else None
    first = None
    for prim in stage.Traverse(Usd.TraverseInstanceProxies()):
        if prim.IsA(UsdRender.Settings):
            targets = UsdRender.Settings(prim).GetCameraRel().GetForwardedTargets()
            if targets and stage.GetPrimAtPath(targets[0]):
                return str(targets[0])
        if first is None and prim.IsA(UsdGeom.Camera):
            first = str(prim.GetPath())
    return first


#: Colour spaces of Arnold's OCIO config (and raw names) that are linear: an integer output in one of them holds
#: linear values. In Arnold's config "sRGB" names the linear Rec.709 space (kick says so for test_1459, which sets
#: color_space_narrow = "sRGB": 'narrow color space "sRGB" is linear, and will cause banding').
LINEAR_SPACES = ("srgb", "linear", "raw", "acescg", "aces2065-1", "scene-linear rec.709-srgb", "lin_srgb",
                 "lin_rec709", "linear rec.709 (srgb)", "utility - linear - srgb")


def narrow_color_space(stage) -> tuple[str | None, str]:
    """(the colour space Arnold writes integer outputs in when the stage says, or None: the default, why): a
    RenderProduct's ``arnold:color_space`` / ``arnold:driver_*:color_space`` other than "" and "auto", else the
    colour manager's ``color_space_narrow`` set on a RenderSettings (``arnold:color_manager:color_space_narrow``,
    ``arnold:global:color_space_narrow``). A colour manager prim that no RenderSettings names is not Arnold's
    options.color_manager and changes nothing."""
    from pxr import Usd

    for prim in stage.Traverse(Usd.TraverseInstanceProxies()):
        for attr in prim.GetAttributes():
            name = attr.GetName()
            if not attr.HasAuthoredValue():
                continue
            value = attr.Get()
            if not isinstance(value, str) or value.strip().lower() in ("", "auto"):
                continue
            driver_space = name.startswith("arnold:driver") and name.endswith(":color_space")
            if prim.GetTypeName() == "RenderProduct" and (name == "arnold:color_space" or driver_space):
                return value, f"{prim.GetPath()}.{name}"
            if prim.GetTypeName() == "RenderSettings" and name in ("arnold:color_manager:color_space_narrow",
                                                                   "arnold:global:color_space_narrow"):
                return value, f"{prim.GetPath()}.{name}"
    return None, ""


def image_format(path: str):
    """The OpenImageIO TypeDesc of an image file's pixels (None: unreadable)."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(path)
    if not inp:
        return None
    fmt = inp.spec().format
    inp.close()
    return fmt


def is_float(fmt) -> bool:
    import OpenImageIO as oiio

    return fmt is not None and fmt.basetype in (oiio.HALF, oiio.FLOAT, oiio.DOUBLE)


def reference_linear(path: str, stage_path: str) -> tuple[np.ndarray, str, str]:
    """(the reference's linear RGBA, "linear" or "srgb": how Arnold encoded it, why). Arnold's colour manager (the
    logs of every reference: color_manager_ocio with Arnold's own config) writes **float** outputs (EXR, float
    TIFF) linear and **integer** ones (the 8-bit TIFFs of kick's ``-o testrender.tif``, JPEG) in its narrow colour
    space, sRGB-encoded by default; a stage whose render product or colour manager names a linear space
    (:data:`LINEAR_SPACES`) gets linear integers. A rule from the file's format and the stage's settings: never
    "whichever matches better"."""
    import OpenImageIO as oiio
    from pxr import Usd

    rgba = read_rgba(path)
    fmt = image_format(path)
    if is_float(fmt):
        return rgba, "linear", f"a {fmt} image: Arnold writes float outputs linear"
    space, where = narrow_color_space(Usd.Stage.Open(stage_path))
    if space is not None and space.strip().lower() in LINEAR_SPACES:
        return rgba, "linear", f"integer output in {space!r}, a linear space ({where})"
    rgba[..., :3] = srgb_decode(np.clip(rgba[..., :3], 0.0, 1.0))
    return rgba, "srgb", (f"integer ({fmt}) output in {space!r} ({where})" if space else
                          f"integer ({fmt}) output: Arnold's default narrow colour space, sRGB")


#: Names of linear Rec.709 in Arnold's OCIO config (and the raw names): a rendering space that needs no conversion.
REC709_SPACES = ("srgb", "lin_srgb", "lin_rec709", "linear rec.709 (srgb)", "scene-linear rec.709-srgb",
                 "utility - linear - srgb", "raw")


def rendering_space(stage) -> tuple[str, str]:
    """("acescg" or "rec709", why): the colour space Arnold shaded the test in. Arnold's default colour manager
    (color_manager_ocio with Arnold's own config) renders in ACEScg: every reference log says 'rendering color
    space is "ACEScg"'. Colour constants (shader inputs, light colours, displayColor, user data) are ACEScg numbers
    there (load_stage(rendering_space="acescg") reads them so and converts colour textures into ACEScg, as
    Arnold does), and an integer output is converted to Rec.709 primaries before its sRGB encoding, so a saturated
    constant comes out more saturated than the same numbers read as Rec.709. A stage whose RenderSettings set the
    colour manager's ``color_space_linear`` renders in that space: "sRGB" is linear Rec.709 in Arnold's config
    (test_1459), and a name the config lacks ("linear", test_1868) makes kick ignore colour spaces."""
    from pxr import Usd

    for prim in stage.Traverse(Usd.TraverseInstanceProxies()):
        if prim.GetTypeName() != "RenderSettings":
            continue
        for name in ("arnold:color_manager:color_space_linear", "arnold:global:color_space_linear"):
            attr = prim.GetAttribute(name)
            value = attr.Get() if attr and attr.HasAuthoredValue() else None
            if isinstance(value, str) and value.strip():
                space = "acescg" if value.strip().lower() == "acescg" else "rec709"
                return space, f"{prim.GetPath()}.{name} = {value!r}"
    return "acescg", "Arnold's default colour manager renders in ACEScg"


def to_output_space(rgba: np.ndarray, space: str, integer: bool) -> np.ndarray:
    """Our render (its colour numbers read as Arnold's rendering space) in the reference's space: an integer output
    of an ACEScg render is converted to Rec.709 primaries (tracer.colorspace.AP1_TO_REC709); a float output stays in
    the rendering space (its driver's "auto" colour space), as does a Rec.709 render."""
    from tracer.colorspace import AP1_TO_REC709

    if space != "acescg" or not integer:
        return rgba
    out = np.array(rgba, np.float32, copy=True)
    out[..., :3] = out[..., :3] @ np.asarray(AP1_TO_REC709, np.float32).T
    return out


def arnold_camera(path: str, camera: str, pixel_aspect: float | None, data_window=None):
    """The stage with a RenderSettings on its session layer: ``camera``, Arnold's conform (the horizontal
    aperture kept), the stage's pixel aspect when its own RenderSettings gives one, and its data window
    (:func:`stage_data_window`: (resolution, dataWindowNDC), which kick renders as a region of that resolution)."""
    from pxr import Gf, Sdf, Usd, UsdRender

    stage = Usd.Stage.Open(path)
    with Usd.EditContext(stage, stage.GetSessionLayer()):
        rs = UsdRender.Settings.Define(stage, "/FidelityArnold")
        rs.CreateCameraRel().SetTargets([Sdf.Path(camera)])
        rs.CreateAspectRatioConformPolicyAttr("adjustApertureHeight")
        if pixel_aspect:
            rs.CreatePixelAspectRatioAttr(float(pixel_aspect))
        if data_window is not None:
            rs.CreateResolutionAttr(Gf.Vec2i(*data_window[0]))
            rs.CreateDataWindowNDCAttr(Gf.Vec4f(*data_window[1]))
    return stage, "/FidelityArnold"


def stage_data_window(stage):
    """((width, height), dataWindowNDC) of the stage's RenderSettings when it authors a data window other than the
    whole image, else None."""
    from pxr import UsdRender

    for prim in stage.Traverse():
        if prim.IsA(UsdRender.Settings):
            rs = UsdRender.Settings(prim)
            dw, res = rs.GetDataWindowNDCAttr(), rs.GetResolutionAttr()
            if dw and dw.HasAuthoredValue() and tuple(dw.Get()) != (0.0, 0.0, 1.0, 1.0) and res.Get() is not None:
                return tuple(int(x) for x in res.Get()), tuple(float(x) for x in dw.Get())
    return None


def stage_pixel_aspect(stage) -> float | None:
    from pxr import UsdRender

    for prim in stage.Traverse():
        if prim.IsA(UsdRender.Settings):
            a = UsdRender.Settings(prim).GetPixelAspectRatioAttr()
            if a and a.HasAuthoredValue():
                return float(a.Get())
    return None


def kick_layout(stage_path: str, root: str) -> str:
    """The stage as kick opens it: the suite runs each test in a directory holding its ``data/`` files, beside the
    suite's ``common/`` (testsuite/SConscript copies it), so a relative asset ``../common/bricks.png`` names
    ``testsuite/common``. Mirrored under ``root`` with symbolic links (nothing copied); the mirrored stage path."""
    data = os.path.dirname(stage_path)
    test_dir = os.path.dirname(data)
    suite = os.path.dirname(test_dir)
    run = os.path.join(root, os.path.basename(test_dir))
    os.makedirs(run, exist_ok=True)
    for name in os.listdir(data):
        link = os.path.join(run, name)
        if not os.path.lexists(link):
            os.symlink(os.path.join(data, name), link)
    common = os.path.join(root, "common")
    if os.path.isdir(os.path.join(suite, "common")) and not os.path.lexists(common):
        os.symlink(os.path.join(suite, "common"), common)
    return os.path.join(run, os.path.basename(stage_path))


def render_ours(test: dict, size, aa: int, layout_root: str | None = None, rendering_space: str = "rec709"):
    import tracer
    from pxr import Usd
    from usd_io.exporters import arnold_usdlux_version
    from usd_io.reader import load_stage

    h, w = size
    path = kick_layout(test["stage"], layout_root) if layout_root else test["stage"]
    probe = Usd.Stage.Open(path)
    camera = find_camera(probe, test.get("camera"))
    if camera is None:
        raise NoCamera("the stage has no camera" + (f" {test['camera']}" if test.get("camera") else ""))
    window = stage_data_window(probe)  # kick renders the region of the stage's resolution its data window says
    stage, settings_prim = arnold_camera(path, camera, stage_pixel_aspect(probe), window)
    units = "spec" if arnold_usdlux_version(probe) else "arnold"  # kick reads every stage in Arnold's units
    size_args = dict(width=w, height=h) if window is None else {}
    scene, info = load_stage(stage, time=test.get("frame"), camera=camera, **size_args,
                             render_settings_prim=settings_prim, default_light=False, light_units=units,
                             fallback_surface="arnold",  # kick: Arnold's default shader on unbound geometry
                             rendering_space=rendering_space)
    if (info.height, info.width) != (h, w):
        raise ValueError(f"the data window {window} renders {info.width}x{info.height}, the reference is {w}x{h}")
    settings = tracer.RenderSettings(width=w, height=h, samples=aa, transparent=False, light_samples=4,
                                     sky_samples=8, max_depth=6, aovs=("objectid",))
    image = tracer.render(scene, settings)
    rgba = np.asarray(image.rgba, np.float32)
    oid = np.asarray(image.aovs["objectid"]) if getattr(image, "aovs", None) else None
    return rgba, (oid >= 0) if oid is not None else rgba[..., 3] >= 0.5, info, camera


class NoCamera(Exception):
    """The stage has no camera to render through (not measured)."""


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((a - b) ** 2))
    return 99.0 if mse <= 1e-12 else 10.0 * np.log10(1.0 / mse)


def srgb(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def srgb_decode(x: np.ndarray) -> np.ndarray:
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def compare(ref: np.ndarray, ours: np.ndarray, covered: np.ndarray) -> dict:
    r, o = np.clip(ref[..., :3], 0, 1), np.clip(ours[..., :3], 0, 1)
    a, b = ref[..., 3] >= 0.5, covered
    union = (a | b) if not a.all() else b  # an opaque reference (a background Arnold sees): our objects
    out = dict(psnr=round(psnr(r, o), 2), psnr_srgb=round(psnr(srgb(r), srgb(o)), 2),
               iou=round(float(np.count_nonzero(a & b) / max(np.count_nonzero(union), 1)), 4) if union.any() else 1.0)
    if union.any():
        mr, mo = r[union].mean(axis=0), o[union].mean(axis=0)
        out.update(de=round(float(delta_e2000(srgb_linear_to_lab(mr), srgb_linear_to_lab(mo))), 2),
                   mean_ref=[round(float(v), 4) for v in mr], mean_ours=[round(float(v), 4) for v in mo])
    return out


def write_png(path: str, rgb01: np.ndarray) -> None:
    import OpenImageIO as oiio

    d = os.path.dirname(path)
    if d:
        os.makedirs(d, exist_ok=True)
    h, w = rgb01.shape[:2]
    out = oiio.ImageBuf(oiio.ImageSpec(w, h, 3, oiio.UINT8))
    out.set_pixels(oiio.ROI(0, w, 0, h), (np.clip(rgb01, 0, 1) * 255 + 0.5).astype(np.uint8))
    out.write(path)


def side_by_side(path: str, ref: np.ndarray, ours: np.ndarray) -> None:
    r, o = np.clip(ref[..., :3], 0, 1), np.clip(ours[..., :3], 0, 1)
    write_png(path, np.concatenate([srgb(r), srgb(o), np.clip(4 * np.abs(r - o), 0, 1)], axis=1))


def contact_sheet(path: str, rows, per_row: int = 6, tile: int = 80, limit: int = 0) -> None:
    """reference | ours per measured test, worst PSNR first, each image shrunk to ``tile`` pixels wide (sRGB);
    a red bar over a pair below 25 dB, green at or above."""
    done = sorted([r for r in rows if r.get("_ref") is not None], key=lambda r: r["psnr"])
    if limit > 0:
        done = done[:limit]
    if not done:
        return
    pad = 3
    tall = lambda r: min(int(round(tile * r["_ref"].shape[0] / r["_ref"].shape[1])), 2 * tile)  # noqa: E731
    rows_h = [max(tall(r) for r in done[k:k + per_row]) for k in range(0, len(done), per_row)]
    sheet = np.full((sum(h + 2 * pad for h in rows_h), per_row * (2 * tile + 2 * pad), 3), 0.12, np.float32)

    def shrink(img):
        h, w = img.shape[:2]
        ys = (np.arange(int(round(tile * h / w))) * h / (tile * h / w)).astype(int).clip(0, h - 1)[:2 * tile]
        xs = (np.arange(tile) * w / tile).astype(int).clip(0, w - 1)
        return srgb(img[ys][:, xs, :3])

    for k, r in enumerate(done):
        y, x = divmod(k, per_row)
        y0, x0 = sum(h + 2 * pad for h in rows_h[:y]) + pad, x * (2 * tile + 2 * pad) + pad
        a, b = shrink(r["_ref"]), shrink(r["_ours"])
        sheet[y0:y0 + a.shape[0], x0:x0 + tile] = a
        sheet[y0:y0 + b.shape[0], x0 + tile:x0 + 2 * tile] = b
        sheet[y0 - pad + 1:y0, x0:x0 + 2 * tile] = (0.2, 0.8, 0.3) if r["psnr"] >= TARGET_DB else (0.9, 0.2, 0.2)
    write_png(path, sheet)


def summary(rows) -> str:
    ok = [r for r in rows if r.get("psnr") is not None]
    if not ok:
        return "nothing measured"
    p = np.array([r["psnr"] for r in ok])
    de = [r["de"] for r in ok if r.get("de") is not None]
    return (f"{len(ok)} tests measured ({len(rows) - len(ok)} not: "
            f"{sum('skip' in r for r in rows)} skipped, {sum('error' in r for r in rows)} errors); "
            f"median PSNR {np.median(p):.2f} dB (sRGB-encoded {np.median([r['psnr_srgb'] for r in ok]):.2f}); "
            f">= {TARGET_DB:.0f} dB: {int((p >= TARGET_DB).sum())}; >= 30 dB: {int((p >= 30).sum())}; "
            f"median dE00 of the covered mean colour {np.median(de):.2f}; "
            f"median IoU {np.median([r['iou'] for r in ok]):.3f}")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("arnold_usd", help="a checkout of Autodesk/arnold-usd (or its extracted testsuite/)")
    p.add_argument("--out", default="/tmp/fidelity-arnold")
    p.add_argument("--only", default="", help="comma-separated test names (test_0200,...)")
    p.add_argument("--aa", type=int, default=3, help="N×N samples per pixel")
    p.add_argument("--jsonl", default=None)
    p.add_argument("--sheet", default=None, help="contact sheet PNG (reference | ours, worst first)")
    p.add_argument("--sheet-limit", type=int, default=0, help="only the worst N pairs on the sheet")
    p.add_argument("--rendering-space", choices=("arnold", "rec709"), default="arnold",
                   help="arnold: our colour numbers read as Arnold's rendering space (ACEScg unless the stage sets "
                        "one: rendering_space()); rec709: as Rec.709 (no conversion)")
    p.add_argument("--list", action="store_true")
    p.add_argument("--summary-of", default=None, metavar="JSONL", help="print the summary of an earlier run's JSONL")
    args = p.parse_args(argv)
    if args.summary_of:
        rows = [json.loads(line) for line in open(args.summary_of)]
        print(summary(list({r["test"]: r for r in rows}.values())))
        return 0
    tests = tests_of(args.arnold_usd)
    if args.only:
        keep = set(args.only.split(","))
        tests = [t for t in tests if t["name"] in keep]
    if args.list:
        for t in tests:
            print(t["name"], os.path.relpath(t["stage"], os.path.dirname(os.path.dirname(t["stage"]))),
                  t.get("camera", ""), t.get("frame", ""), t.get("skip", ""))
        return 0
    os.makedirs(args.out, exist_ok=True)
    rows = []
    for test in tests:
        row = dict(test=test["name"], stage=os.path.basename(test["stage"]), title=test["title"])
        start = time.perf_counter()
        try:
            if "skip" in test:
                raise NoCamera(test["skip"])
            ref, encoding, why = reference_linear(test["reference"], test["stage"])
            other = srgb(ref[..., :3]) if encoding == "srgb" else srgb_decode(np.clip(ref[..., :3], 0, 1))
            from pxr import Usd
            space, space_why = (rendering_space(Usd.Stage.Open(test["stage"])) if args.rendering_space == "arnold"
                                else ("rec709", "--rendering-space rec709"))
            ours, covered, info, camera = render_ours(test, ref.shape[:2], args.aa,
                                                      layout_root=os.path.join(args.out, "kick-layout"),
                                                      rendering_space=space)
            ours = to_output_space(ours, space, integer=not is_float(image_format(test["reference"])))
            row.update(camera=camera, frame=test.get("frame"), size=[ref.shape[1], ref.shape[0]],
                       reference_encoding=encoding, reference_encoding_why=why, rendering_space=space,
                       rendering_space_why=space_why,
                       **compare(ref, ours, covered), warnings=list(info.warnings),
                       psnr_other_reading=round(psnr(np.clip(other, 0, 1), np.clip(ours[..., :3], 0, 1)), 2))
            side_by_side(os.path.join(args.out, test["name"] + ".png"), ref, ours)
            row["_ref"], row["_ours"] = ref, ours
        except NoCamera as why:
            row.update(skip=str(why))
        except Exception as exc:  # noqa: BLE001 — a row per failure, the run goes on
            row.update(error=f"{type(exc).__name__}: {exc}"[:300])
        row["seconds"] = round(time.perf_counter() - start, 1)
        rows.append(row)
        shown = (f"{row['psnr']:6.2f} dB  dE {row.get('de', float('nan')):5.1f}  IoU {row['iou']:.3f}  "
                 f"warnings {len(row['warnings'])}") if "psnr" in row else \
            ("skip: " + row["skip"] if "skip" in row else "ERR " + row["error"])
        print(f"{row['test']:14s} {row['stage']:22s} {shown}", flush=True)
        if args.jsonl:
            with open(args.jsonl, "a") as f:
                f.write(json.dumps({k: v for k, v in row.items() if not k.startswith("_")}) + "\n")
    if args.sheet:
        contact_sheet(args.sheet, rows, limit=args.sheet_limit)
    print(summary(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())

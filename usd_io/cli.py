"""The ``whitted`` command line: ``whitted render`` (USD -> PNG/EXR) and ``whitted info``.

    whitted render SCENE [SCENE ...] -o OUT.png|.exr|.jpg|.tif [--camera PRIM_PATH] [--width|--imageWidth W]
                   [--height H] [--aa N] [--max-depth D] [--frames A:B[xS] | --time T] [--purposes P[,P...]]
                   [--variant /Prim:set=value ...] [--no-default-light|--disableCameraLight] [--exposure EV]
                   [--transparent] [--threads N] [--aov depth,normal,albedo,objectid] [--quiet]
    whitted info SCENE [--time T] [--variant /Prim:set=value ...]
    whitted warmup    (compile the tracer's kernels once, e.g. at install time)
    whitted --version

Several scenes render in one process (kernels and imports loaded once) to an output pattern with ``{stem}``;
a scene that fails is reported on one line and the rest go on; the exit code is then 2.

Exit codes: 0 success; 2 bad input, with one line on stderr naming the file and what is wrong; 1 an internal
fault (with a traceback). Images are written to a temporary file and renamed (tracer.film). AOVs go next to the
image: ``out.png`` -> ``out.depth.exr``, ``out.normal.exr``, ``out.albedo.exr``, ``out.objectid.exr`` (linear EXR).
With ``--frames``, ``#`` runs in the output name are replaced by the zero-padded frame number
(``out.####.png``); without them, ``.####`` is inserted before the extension.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import traceback
import warnings

import numpy as np

EXIT_OK, EXIT_FAULT, EXIT_BAD_INPUT = 0, 1, 2


class BadInput(Exception):
    """User-fixable input problem: one line on stderr, exit 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse's own errors are bad input too: one line, exit 2
        m = re.match(r"argument command: invalid choice: '([^']*)' \(choose from (.*)\)", message)
        if m:
            raise BadInput(f"unknown command {m.group(1)!r}: choose from {m.group(2).replace(chr(39), '')}")
        if "required: command" in message:
            raise BadInput("a command is required: whitted render SCENE -o OUT.png | whitted info SCENE")
        raise BadInput(message if self.prog == "whitted" else f"{self.prog}: {message}")


def parse_frames(text: str) -> list[float]:
    """``A:B`` or ``A:BxS`` (inclusive, step S > 0) or a single ``A`` -> time codes."""
    m = re.fullmatch(r"\s*(-?[\d.]+)\s*(?::\s*(-?[\d.]+)\s*(?:x\s*([\d.]+))?)?\s*", text or "")
    try:
        if not m:
            raise ValueError
        a = float(m.group(1))
        b = float(m.group(2)) if m.group(2) is not None else a
        s = float(m.group(3)) if m.group(3) is not None else 1.0
    except ValueError:
        raise BadInput(f"--frames {text!r}: expected A:B or A:BxS (numbers)") from None
    if not (np.isfinite(a) and np.isfinite(b) and np.isfinite(s)) or s <= 0:
        raise BadInput(f"--frames {text!r}: the step must be a positive number")
    if b < a:
        raise BadInput(f"--frames {text!r}: the end frame {b:g} is before the start frame {a:g}")
    n = int(np.floor((b - a) / s + 1e-9)) + 1
    if n > 100000:
        raise BadInput(f"--frames {text!r}: {n} frames is too many")
    return [a + i * s for i in range(n)]


def frame_path(pattern: str, frame: float, many: bool) -> str:
    label = lambda width: (f"{int(frame):0{width}d}" if float(frame).is_integer()  # noqa: E731
                           else f"{frame:0{width + 4}.3f}".rstrip("0"))
    if re.search(r"#+", pattern):
        return re.sub(r"#+", lambda m: label(len(m.group(0))), pattern, count=1)
    if not many:
        return pattern
    root, ext = os.path.splitext(pattern)
    return f"{root}.{label(4)}{ext}"


def aov_path(image_path: str, aov: str) -> str:
    root, _ext = os.path.splitext(image_path)
    return f"{root}.{aov}.exr"


def check_output(path: str):
    ext = os.path.splitext(path)[1].lower()
    if ext not in (".png", ".exr", ".jpg", ".jpeg", ".tif", ".tiff", ".hdr"):
        raise BadInput(f"{path}: unsupported output type {ext or '(none)'!r}; use .png, .exr, .jpg, .tif or .hdr")
    directory = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(directory):
        raise BadInput(f"{path}: output directory {directory} does not exist")


def _parse_aovs(text):
    from tracer import AOV_NAMES

    if not text:
        return ()
    names = tuple(a.strip() for a in text.split(",") if a.strip())
    bad = [a for a in names if a not in AOV_NAMES]
    if bad:
        raise BadInput(f"--aov: unknown AOV(s) {', '.join(bad)}; choose from {', '.join(AOV_NAMES)}")
    return names


def split_purposes(values) -> list[str]:
    """``--purposes`` takes space- or comma-separated names (``render proxy`` or ``render,proxy``)."""
    return [p.strip() for v in values for p in v.split(",") if p.strip()]


def _version() -> str:
    try:
        from importlib.metadata import version

        return version("whitted")
    except Exception:  # noqa: BLE001 — running from a source tree that was never installed
        return "0.1.0 (source tree)"


def _variant(text: str):
    """``/Prim:set=value`` -> (prim path, set, value)."""
    m = re.fullmatch(r"\s*(/[^:=\s]*)\s*:\s*([^=\s]+)\s*=\s*(\S+)\s*", text or "")
    if not m:
        raise argparse.ArgumentTypeError(f"{text!r}: expected /Prim/Path:variantSet=variant")
    return m.group(1), m.group(2), m.group(3)


class _VersionAction(argparse.Action):
    """``--version``, looked up only when asked for: ``importlib.metadata`` costs 20 ms on every start otherwise."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS,
                 help="show program's version number and exit"):
        super().__init__(option_strings=option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        parser._print_message(f"whitted {_version()}\n", sys.stdout)
        parser.exit()


#: Deprecated spellings still accepted (scripts call them): old flag -> (new flag, note). Each prints ONE warning.
DEPRECATED = {"--spp": ("--aa", "--spp N meant N×N samples per pixel")}


def _add_render_flags(r) -> None:
    """Every ``whitted render`` flag, in one place (other branches add theirs here: one ``add_argument`` each)."""
    from tracer.settings import DEFAULT_AA, SHADING_MODELS

    from .complexity import COMPLEXITY, DEFAULT_COMPLEXITY

    r.add_argument("scenes", nargs="+", metavar="SCENE", help="USD file(s) (.usd, .usda, .usdc, .usdz)")
    r.add_argument("-o", "--output", required=True,
                   help="output image (.png/.jpg/.tif sRGB 8-bit, .exr linear half); several scenes need {stem} "
                        "(or {name}) in it, e.g. thumbs/{stem}.png")
    r.add_argument("--camera", "--cam", help="camera prim path (default: the first camera in the stage)")
    r.add_argument("--width", "--imageWidth", "-w", dest="width", type=int,
                   help="image width (default 960, or from --height and the aperture)")
    r.add_argument("--height", type=int, help="image height (default: from the width and the camera aperture)")
    r.add_argument("--aa", type=int, default=None,
                   help=f"anti-aliasing: N×N stratified samples per pixel (default {DEFAULT_AA})")
    r.add_argument("--spp", dest="spp_deprecated", type=int, help=argparse.SUPPRESS)
    r.add_argument("--max-depth", type=int, default=8, help="maximum reflection/refraction depth (default 8)")
    r.add_argument("--shading", choices=SHADING_MODELS, default=SHADING_MODELS[0],
                   help="local model: principled (Cycles' Principled BSDF: diffuse + GGX, the default) or classic "
                        "(the notes' Lambert + Blinn-Phong)")
    r.add_argument("--frames", "-f", help="time codes A:B or A:BxS; output pattern out.####.png")
    r.add_argument("--time", type=float, help="one time code to render (default: the earliest)")
    r.add_argument("--purposes", nargs="+", default=["default", "render"],
                   help="purposes to render, space- or comma-separated (default: default render)")
    r.add_argument("--variant", action="append", type=_variant, default=[], metavar="/PRIM:SET=VALUE",
                   help="select a variant before reading (repeatable)")
    r.add_argument("--complexity", "-c", choices=list(COMPLEXITY), default=DEFAULT_COMPLEXITY,
                   help="subdivision surfaces: low = the control cage, medium = 1 level of Catmull-Clark (default), "
                   "high = 2, veryhigh = 3 (usdrecord's names)")
    r.add_argument("--no-default-light", "--disableCameraLight", dest="no_default_light", action="store_true",
                   help="leave a stage without lights unlit (default: a camera headlight and a dim dome, as usdview)")
    r.add_argument("--exposure", type=float, default=0.0, help="exposure in stops: pixels × 2^EV (default 0)")
    r.add_argument("--transparent", action="store_true",
                   help="alpha 0 where eye rays see only background (PNG/EXR/TIFF alpha; Blender's Film > Transparent)")
    r.add_argument("--threads", type=int, help="worker threads (default: all cores)")
    r.add_argument("--aov", help="extra outputs (float32 EXR): comma-separated depth,normal,albedo,objectid, and "
                   "direct,reflection,transmission (the beauty by first secondary ray), raydepth (EXR + heat-map PNG)")
    r.add_argument("--quiet", "-q", action="store_true", help="no progress bar or summary")
    r.add_argument("--scheduler", help="render on a Dask cluster: tcp://HOST:PORT, tls://HOST:PORT, a scheduler "
                   "file, or local:N (N local worker processes); frames are tasks, a single frame splits into tiles")
    r.add_argument("--worker-writes", action="store_true", help="with --scheduler: workers write the frames "
                   "themselves (OUT must be on a filesystem they share); default: the client writes every file")
    r.add_argument("--ship-assets", action="store_true", help="with --scheduler: send the stage and its resolved "
                   "assets to the workers as a .usdz (default: workers read SCENE's path on a shared filesystem)")


def build_parser() -> argparse.ArgumentParser:
    ap = _Parser(prog="whitted", description="Render USD stages with a Whitted-style ray tracer.")
    ap.add_argument("--version", action=_VersionAction)
    sub = ap.add_subparsers(dest="command", required=True, parser_class=_Parser)
    _add_render_flags(sub.add_parser("render", help="render USD stages to PNG/EXR/JPEG/TIFF"))
    e = sub.add_parser("explain", help="the ray tree of one pixel: every ray that made it (tree, JSON, USD, PNG)")
    e.add_argument("scene", help="USD file")
    e.add_argument("--pixel", nargs=2, type=int, required=True, metavar=("X", "Y"),
                   help="image pixel, origin top-left (the same image as render's --width/--height)")
    e.add_argument("--camera", help="camera prim path (default: the first camera in the stage)")
    e.add_argument("--frame", type=float, help="time code (default: the stage's default time)")
    e.add_argument("--width", type=int, help="image width (default 960, or from --height and the aperture)")
    e.add_argument("--height", type=int, help="image height")
    e.add_argument("--spp", type=int, default=2, help="N for N×N samples per pixel, as render (default 2)")
    e.add_argument("--max-depth", type=int, default=8, help="maximum reflection/refraction depth (default 8)")
    e.add_argument("--purposes", nargs="+", default=["default", "render"])
    e.add_argument("--no-default-light", "--disableCameraLight", dest="no_default_light", action="store_true",
                   help="leave a stage without lights unlit")
    e.add_argument("--complexity", choices=["low", "medium", "high", "veryhigh"], default="medium",
                   help="subdivision surfaces, as render's --complexity")
    e.add_argument("--json", help="write the tree as JSON (format in README)")
    e.add_argument("--usd", help="write the tree as BasisCurves + camera over the stage (.usda)")
    e.add_argument("--png", help="write the rendered image with the pixel marked and the rays drawn")
    sub.add_parser("warmup", help="compile the tracer's kernels now (once per install; renders then start at once)")
    i = sub.add_parser("info", help="list cameras, lights, meshes and materials of a USD stage")
    i.add_argument("scene")
    i.add_argument("--time", type=float, help="time code (default: earliest)")
    i.add_argument("--purposes", nargs="+", default=["default", "render"])
    i.add_argument("--variant", action="append", type=_variant, default=[], metavar="/PRIM:SET=VALUE")
    return ap


def warn(message: str) -> None:
    print(f"whitted: warning: {message}", file=sys.stderr)


def _print_warnings(info):
    for n in getattr(info, "notes", ()):
        print(f"whitted: note: {n}", file=sys.stderr)
    for w in info.warnings:
        warn(w)


def _check_args(args) -> None:
    for name in ("width", "height"):
        v = getattr(args, name)
        if v is not None and v <= 0:
            raise BadInput(f"{', '.join(args.scenes)}: image {name} must be positive, got {v}")
    if args.spp_deprecated is not None:
        warn("--spp is deprecated: use --aa N (N×N samples per pixel, the same meaning)")
        if args.aa is None:
            args.aa = args.spp_deprecated
    if args.aa is None:
        from tracer.settings import DEFAULT_AA

        args.aa = DEFAULT_AA
    for name, lo in (("aa", 1), ("max_depth", 0), ("threads", 1)):
        v = getattr(args, name)
        if v is not None and v < lo:
            raise BadInput(f"--{name.replace('_', '-')} must be >= {lo}, got {v}")
    if not np.isfinite(args.exposure):
        raise BadInput(f"--exposure must be a finite number, got {args.exposure}")
    for flag in ("ship_assets", "worker_writes"):
        if getattr(args, flag) and not args.scheduler:
            raise BadInput(f"--{flag.replace('_', '-')} needs --scheduler")
    if args.frames and args.time is not None:
        raise BadInput("--frames and --time are exclusive")
    if len(args.scenes) > 1 and not re.search(r"\{(stem|name)\}", args.output):
        raise BadInput(f"{len(args.scenes)} scenes need {{stem}} or {{name}} in the output name, "
                       f"e.g. thumbs/{{stem}}.png (got {args.output})")


def output_for(pattern: str, scene: str) -> str:
    """The output path of one scene: ``{stem}`` -> file name without extension, ``{name}`` -> with it."""
    base = os.path.basename(scene)
    return pattern.replace("{stem}", os.path.splitext(base)[0]).replace("{name}", base)


def cmd_render(args) -> int:
    _check_args(args)
    aovs = _parse_aovs(args.aov)
    frames = parse_frames(args.frames) if args.frames else [args.time]
    failed = 0
    for scene_path in args.scenes:
        out = output_for(args.output, scene_path)
        try:
            check_output(out)
            if render_file(scene_path, out, frames, aovs, args) != EXIT_OK:
                failed += 1
        except (BadInput, ValueError) as exc:  # UsdInputError is a ValueError
            if len(args.scenes) == 1:
                raise
            print(f"whitted: error: {' '.join(str(exc).split())}", file=sys.stderr)
            failed += 1
        except Exception as exc:  # noqa: BLE001 — a batch goes on; the fault is named on one line
            if len(args.scenes) == 1:
                raise
            print(f"whitted: error: {scene_path}: internal error {type(exc).__name__}: "
                  f"{' '.join(str(exc).split())}", file=sys.stderr)
            failed += 1
    if failed:
        if len(args.scenes) > 1:
            print(f"whitted: {failed} of {len(args.scenes)} scenes failed", file=sys.stderr)
        return EXIT_BAD_INPUT
    return EXIT_OK


_kernels_ready = False


def render_file(scene_path: str, output: str, frames, aovs, args) -> int:
    """Render one scene (all its frames) to ``output``; BadInput/UsdInputError for what the user can fix.
    Returns the exit code (a farm reports failed frames itself and returns 2)."""
    global _kernels_ready
    from .stage import open_stage

    stage = open_stage(scene_path)  # a file that is not a stage says so before anything waits for the kernels
    if args.scheduler:  # the farm reads the scene and output from its own copy of the arguments
        return _render_on_farm(argparse.Namespace(**dict(vars(args), scene=scene_path, output=output)), frames, aovs)
    from tracer.settings import RenderSettings

    from .reader import load_stage
    many = len(frames) > 1
    for frame in frames:
        scene, info = load_stage(stage, time=frame, camera=args.camera, width=args.width, height=args.height,
                                 purposes=split_purposes(args.purposes), default_light=not args.no_default_light,
                                 variants=args.variant, complexity=args.complexity)
        if frame == frames[0]:
            _print_warnings(info)
        settings = RenderSettings(width=info.width, height=info.height, samples=args.aa, max_depth=args.max_depth,
                                  threads=args.threads, aovs=aovs, progress=not args.quiet,
                                  transparent=args.transparent, shading=args.shading)
        from tracer import render

        if not _kernels_ready:  # after the input has been checked: bad input stays one line
            from tracer.jit import kernels_cached

            if not kernels_cached():  # a warm cache loads each kernel as the render first uses it
                _compile_kernels(quiet=args.quiet)
            _kernels_ready = True
        image = render(scene, settings)
        _warn_not_finite(image.rgba, scene_path)
        if args.exposure:
            image.rgba[..., :3] *= np.float32(2.0 ** args.exposure)
        out = frame_path(output, frame, many) if frame is not None and many else output
        write_outputs(image, out, aovs, max_depth=args.max_depth)
        if not args.quiet:
            s = image.stats
            print(f"{out}: {info.width}x{info.height}, {len(scene.triangles):,} triangles, "
                  f"{s['rays']['total']:,} rays in {s['seconds']:.2f} s", file=sys.stderr)
    if info.nothing_drawn:  # gprims that gave no triangle: written, but not a success (usd_io.reader)
        print(f"whitted: error: {scene_path}: {info.nothing_drawn}", file=sys.stderr)
        return EXIT_BAD_INPUT
    return EXIT_OK


def _warn_not_finite(rgba: np.ndarray, scene_path: str) -> None:
    """One warning when the renderer produced NaN/inf pixels (the film writes them black, silently)."""
    bad = int(np.count_nonzero(~np.all(np.isfinite(rgba), axis=-1)))
    if bad:
        warn(f"{scene_path}: {bad} pixel(s) not finite (NaN or inf; written black)")


def _save(image, out: str) -> None:
    """PNG/TIFF/EXR keep alpha; JPEG has none (RGB only)."""
    from tracer import write_image

    ext = os.path.splitext(out)[1].lower()
    if ext in (".jpg", ".jpeg"):
        write_image(out, image.rgba[..., :3])
    else:
        image.save(out)


def write_outputs(image, out, aovs, max_depth: int | None = None) -> None:
    """The image and its AOVs (EXR next to it; ``raydepth`` also as a heat-map PNG scaled to ``max_depth``)."""
    try:
        _save(image, out)
        for name in aovs:
            a = image.aovs[name]
            a = a[..., None] if a.ndim == 2 else a
            _write_aov(aov_path(out, name), a.astype(np.float32))
            if name == "raydepth":  # and a heat-map picture of it (black: eye rays only; yellow: max depth)
                from tracer.film import heat_map

                _write_aov(aov_path(out, name)[:-4] + ".png", heat_map(a[..., 0], max_depth))
    except ValueError as exc:  # unwritable output (the tracer's film names the file and the reason)
        raise BadInput(str(exc)) from None


def _render_on_farm(args, frames, aovs) -> int:
    """--scheduler: the same frames and files on a Dask cluster (usd_io.farm)."""
    from .farm import FarmInputError, render_on_farm

    settings = dict(samples=args.aa, max_depth=args.max_depth, threads=args.threads, aovs=aovs,
                    transparent=args.transparent, shading=args.shading)
    output = args.output
    name = (lambda f: frame_path(output, f, len(frames) > 1) if f is not None and len(frames) > 1 else output)

    def write(image, out):
        if args.exposure:
            image.rgba[..., :3] *= np.float32(2.0 ** args.exposure)
        write_outputs(image, out, aovs, max_depth=args.max_depth)

    try:
        return render_on_farm(args, frames, settings, name, write)
    except FarmInputError as exc:
        raise BadInput(str(exc)) from None


def _compile_kernels(quiet: bool) -> None:
    """Compile (first run on a machine) or load the tracer's kernels, saying so when that takes a while."""
    import threading

    from tracer import compile_kernels

    notice = threading.Timer(1.0, lambda: print("whitted: compiling the tracer's kernels (first run on this machine "
                                                "only, about 10 s)", file=sys.stderr, flush=True))
    if not quiet:
        notice.start()
    try:
        compile_kernels()
    finally:
        notice.cancel()


def _write_aov(path, pixels):
    from tracer import write_image

    write_image(path, np.nan_to_num(pixels, posinf=0.0, neginf=0.0), float32=True)


def cmd_info(args) -> int:
    from .reader import load_stage

    scene, info = load_stage(args.scene, time=args.time, purposes=split_purposes(args.purposes), width=160,
                             variants=args.variant)
    out = sys.stdout
    print(f"stage: {info.path}", file=out)
    print(f"upAxis: {info.up_axis}, metersPerUnit: {info.meters_per_unit:g}", file=out)
    print(f"cameras ({len(info.cameras)}):", file=out)
    for c in info.cameras:
        print(f"  {c}{'  (default)' if c == info.camera else ''}", file=out)
    if info.camera is None:
        print("  (none: a default camera frames the bounds)", file=out)
    print(f"lights ({len(info.lights)}):", file=out)
    for path, kind, light in info.lights:
        print(f"  {path}: {kind} -> {_describe_light(light)}", file=out)
    print(f"meshes ({len(info.meshes)}, {sum(n for _, n in info.meshes):,} triangles):", file=out)
    for path, n in info.meshes:
        print(f"  {path}: {n:,} triangles", file=out)
    print(f"materials ({len(info.materials)}):", file=out)
    for name, fields in info.materials.items():
        print(f"  {name} -> " + ", ".join(f"{k}={v}" for k, v in fields.items()), file=out)
    _print_warnings(info)
    return EXIT_OK


def _value(v) -> str:
    if isinstance(v, str):
        return v
    try:
        return str(np.round(np.asarray(v, float), 4).tolist())
    except (TypeError, ValueError):  # anything else a light may carry (shape names, tuples of mixed types)
        return repr(v)


def _describe_light(light) -> str:
    if isinstance(light, dict):
        return ", ".join(f"{k}={_value(v)}" for k, v in light.items())
    fields = {k: v for k, v in vars(light).items() if k != "name"}
    parts = [f"{k}={_value(v)}" for k, v in fields.items()]
    return f"{type(light).__name__}(" + ", ".join(parts) + ")"


def cmd_explain(args) -> int:
    from .explain import cmd_explain as run

    return run(args)


def cmd_warmup(args) -> int:
    """``whitted warmup``: compile (or load) every tracer kernel into the on-disk cache, as the first render on a
    machine would; run it after installing so that no render pays the compile."""
    import time

    from tracer.jit import kernels_cached

    start = time.perf_counter()
    was = kernels_cached()
    _compile_kernels(quiet=True)
    print(f"whitted: kernels {'were already compiled' if was else 'compiled'} "
          f"({time.perf_counter() - start:.1f} s)", file=sys.stderr)
    return 0


_COMMANDS = {"render": cmd_render, "info": cmd_info, "explain": cmd_explain, "warmup": cmd_warmup}


def main(argv=None) -> int:
    from .errors import UsdInputError

    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser()
    if not argv:
        parser.print_usage(sys.stderr)
        print("whitted: error: a command is required: whitted render SCENE -o OUT.png | whitted info SCENE "
              "(whitted render --help for all options)", file=sys.stderr)
        return EXIT_BAD_INPUT
    try:
        args = parser.parse_args(argv)
        with warnings.catch_warnings():
            warnings.simplefilter("default")
            # every Python warning (numpy, OIIO, ...) in the one `whitted: warning:` form, not raw UserWarning lines
            warnings.showwarning = lambda message, category, *a, **k: warn(str(message))
            code = _COMMANDS[args.command](args)
    except (BadInput, UsdInputError) as exc:
        print(f"whitted: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("whitted: interrupted", file=sys.stderr)
        return 130
    except SystemExit as exc:  # --help
        return int(exc.code or 0)
    except Exception:  # noqa: BLE001 — a real fault: show where
        traceback.print_exc()
        return EXIT_FAULT
    return code


def run() -> None:
    """The ``whitted`` command: :func:`main`, then exit without Python's teardown of the interpreter (freeing pxr's,
    numba's and LLVM's module state: 0.15 s of a 0.8 s render). What an ordinary exit does that matters is done
    first: non-daemon threads are joined, atexit handlers run, stdout and stderr are flushed; images were written
    and renamed by then."""
    import atexit
    import threading

    code = main()
    shutdown = getattr(threading, "_shutdown", None)  # what Py_Finalize calls first: joins non-daemon threads
    if shutdown is not None:
        shutdown()
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, AttributeError):  # closed or replaced streams: nothing left to write
            pass
    os._exit(code)


if __name__ == "__main__":
    run()

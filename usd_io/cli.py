"""The ``whitted`` command line: ``whitted render`` (USD -> PNG/EXR), ``whitted explain`` and ``whitted info``.

    whitted render SCENE [SCENE ...] -o OUT.png|.exr|.jpg|.tif [--frames A:B[xS]] [STAGE FLAGS] [SETTINGS FLAGS]
                   [--exposure EV] [--quiet] [--scheduler ADDRESS [--worker-writes] [--ship-assets]]
    whitted explain SCENE --pixel X Y [--json OUT.json] [--usd OUT.usda] [--png OUT.png] [STAGE FLAGS] [SETTINGS FLAGS]
    whitted info SCENE [STAGE FLAGS]
    whitted warmup    (compile the tracer's kernels once, e.g. at install time)
    whitted --version

STAGE FLAGS are the fields of :class:`usd_io.request.StageRequest` (--time/--frame, --camera, --purposes,
--variant, --complexity, --no-default-light), SETTINGS FLAGS one per :class:`tracer.RenderSettings` field (--width,
--height, --aa, --max-depth, --shading, ... : ``whitted render --help``), both made from their definitions in
usd_io/request.py and tracer/settings.py: every command takes the same ones.

Several scenes render in one process (kernels and imports loaded once) to an output pattern with ``{stem}``;
a scene that fails is reported on one line and the rest go on; the exit code is then 2.

Exit codes: 0 success; 2 bad input (:class:`usd_io.UsdInputError`), with one line on stderr naming the file and
what is wrong; 1 an internal fault (with a traceback). Images are written to a temporary file and renamed
(tracer.film); what is written is usd_io/outputs.py. AOVs go next to the image: ``out.png`` ->
``out.depth.exr``, ... (linear EXR). With ``--frames``, ``#`` runs in the output name are replaced by the
zero-padded frame number (``out.####.png``); without them, ``.####`` is inserted before the extension.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import re
import sys
import traceback
import warnings
from dataclasses import dataclass

import numpy as np

from .errors import UsdInputError
from .outputs import BadInput, Outputs, check_output, frame_path, output_for, print_warnings, product_path, warn
from .request import StageRequest, add_request_flags, add_settings_flags, settings_from_args, split_purposes

__all__ = ["main", "run", "build_parser", "parse_frames", "BadInput", "UsdInputError", "split_purposes",
           "frame_path", "output_for"]

EXIT_OK, EXIT_FAULT, EXIT_BAD_INPUT = 0, 1, 2


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


def _version() -> str:
    try:
        from importlib.metadata import version

        return version("whitted")
    except Exception:  # noqa: BLE001 — running from a source tree that was never installed
        return "0.1.0 (source tree)"


class _VersionAction(argparse.Action):
    """``--version``, looked up only when asked for: ``importlib.metadata`` costs 20 ms on every start otherwise."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS,
                 help="show program's version number and exit"):
        super().__init__(option_strings=option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        parser._print_message(f"whitted {_version()}\n", sys.stdout)
        parser.exit()


def add_render_flags(p) -> None:
    """What ``render`` and ``explain`` share: the stage request's flags, one flag per render setting, and the
    exposure (both generated from their one definition, usd_io/request.py and tracer/settings.py)."""
    add_request_flags(p)
    add_settings_flags(p)
    p.add_argument("--exposure", type=float, default=0.0, help="exposure in stops: pixels × 2^EV (default 0)")
    p.add_argument("--quiet", "-q", action="store_true", help="no progress bar or summary")


def _add_render_command(r) -> None:
    r.add_argument("scenes", nargs="+", metavar="SCENE", help="USD file(s) (.usd, .usda, .usdc, .usdz)")
    r.add_argument("-o", "--output",
                   help="output image (.png/.jpg/.tif sRGB 8-bit, .exr linear half); several scenes need {stem} "
                        "(or {name}) in it, e.g. thumbs/{stem}.png; default: the stage's RenderProduct "
                        "productName")
    r.add_argument("--output-dir", metavar="DIR",
                   help="without -o: the directory the stage's RenderProduct productNames are written in (default: "
                   "the current directory); a productName that leaves it (.., an absolute path, a symbolic link) "
                   "is refused")
    r.add_argument("--allow-product-paths", action="store_true",
                   help="without -o: write each RenderProduct where its productName says, even outside the output "
                   "directory (for stages from a trusted pipeline)")
    r.add_argument("--frames", "-f", help="time codes A:B or A:BxS; output pattern out.####.png")
    add_render_flags(r)
    r.add_argument("--scheduler", help="render on a Dask cluster: tcp://HOST:PORT, tls://HOST:PORT, a scheduler "
                   "file, or local:N (N local worker processes); frames are tasks, a single frame splits into tiles")
    r.add_argument("--worker-writes", action="store_true", help="with --scheduler: workers write the frames "
                   "themselves (OUT must be on a filesystem they share); default: the client writes every file")
    r.add_argument("--ship-assets", action="store_true", help="with --scheduler: send the stage and its resolved "
                   "assets to the workers as a .usdz (default: workers read SCENE's path on a shared filesystem)")


def _add_explain_command(e) -> None:
    e.add_argument("scene", help="USD file")
    e.add_argument("--pixel", nargs=2, type=int, required=True, metavar=("X", "Y"),
                   help="image pixel, origin top-left (the same image as render's --width/--height)")
    add_render_flags(e)
    e.add_argument("--json", help="write the tree as JSON (format in README)")
    e.add_argument("--usd", help="write the tree as BasisCurves + camera over the stage (.usda)")
    e.add_argument("--png", help="write the rendered image (with --exposure) with the pixel marked and the rays "
                   "drawn")


def build_parser() -> argparse.ArgumentParser:
    ap = _Parser(prog="whitted", description="Render USD stages with a Whitted-style ray tracer.")
    ap.add_argument("--version", action=_VersionAction)
    sub = ap.add_subparsers(dest="command", required=True, parser_class=_Parser)
    _add_render_command(sub.add_parser("render", help="render USD stages to PNG/EXR/JPEG/TIFF"))
    _add_explain_command(sub.add_parser("explain", help="the ray tree of one pixel: every ray that made it "
                                                        "(tree, JSON, USD, PNG)"))
    sub.add_parser("warmup", help="compile the tracer's kernels now (once per install; renders then start at once)")
    i = sub.add_parser("info", help="list cameras, lights, meshes and materials of a USD stage")
    i.add_argument("scene")
    add_request_flags(i)
    return ap


def _check_args(args) -> None:
    for flag in ("ship_assets", "worker_writes"):
        if getattr(args, flag) and not args.scheduler:
            raise BadInput(f"--{flag.replace('_', '-')} needs --scheduler")
    for flag in ("output_dir", "allow_product_paths"):
        if getattr(args, flag) and args.output:
            raise BadInput(f"--{flag.replace('_', '-')} is for RenderProduct outputs: it cannot be used with -o")
    if args.output_dir and not os.path.isdir(args.output_dir):
        raise BadInput(f"--output-dir {args.output_dir}: no such directory")
    if args.frames and args.time is not None:
        raise BadInput("--frames and --time are exclusive")
    if len(args.scenes) > 1 and not re.search(r"\{(stem|name)\}", args.output or ""):
        raise BadInput(f"{len(args.scenes)} scenes need {{stem}} or {{name}} in the output name, "
                       f"e.g. thumbs/{{stem}}.png (got {args.output})")


def cmd_render(args) -> int:
    _check_args(args)
    try:  # every setting checked (against its bounds) before any stage is read
        settings = settings_from_args(args, progress=not args.quiet)
    except UsdInputError as exc:
        raise BadInput(f"{', '.join(args.scenes)}: {exc}") from None
    if settings.denoise:  # without an OIDN library: one line and exit 2, before any stage is read
        _check_denoiser()
    outputs = Outputs.of(settings, args.exposure)
    options = RenderOptions.from_args(args)
    frames = parse_frames(args.frames) if args.frames else [args.time]
    global _helper
    if not options.scheduler:  # a cold kernel cache is filled by two processes (tracer/kernel_plan.py)
        from tracer import kernel_plan

        _helper = kernel_plan.start()
    try:
        return _render_scenes(args, settings, outputs, options, frames)
    finally:
        if _helper is not None:
            _helper.stop()
            _helper = None


def _render_scenes(args, settings, outputs, options, frames) -> int:
    failed = 0
    for scene_path in args.scenes:
        try:
            if args.output:
                check_output(out := output_for(args.output, scene_path))
            stage = open_stage(scene_path)  # once: its products, each product's render and every frame read it
            if not args.output:
                check_output(out := _product_output(args, scene_path, stage))
            request = StageRequest.from_args(args, scene_path)
            jobs = [(request, out)] + ([] if args.output else _more_products(args, request, stage))
            for _r, check_out in jobs[1:]:
                check_output(check_out)
            for job_request, job_out in jobs:  # without -o: every RenderProduct (usd_io.render_settings)
                if render_file(job_request, settings, job_out, frames, outputs, options, stage) != EXIT_OK:
                    failed += 1
        except ValueError as exc:  # UsdInputError (BadInput) is a ValueError
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


def _check_denoiser() -> None:
    """BadInput unless Open Image Denoise loads here (``--denoise``; tracer.denoise says where it looked)."""
    from tracer.denoise import DenoiseUnavailable, check  # (ctypes only: OIDN itself loads here, once)

    try:
        check()
    except DenoiseUnavailable as exc:
        raise BadInput(f"--denoise: {exc}") from None


_kernels_ready = False
_helper = None  # the second compiling process of this render (tracer.kernel_plan.Helper), while it runs


@dataclass(frozen=True)
class RenderOptions:
    """How ``whitted render`` runs, besides the stage request, the settings and the outputs: progress output, and
    the Dask scheduler with its two options (None: render here)."""

    quiet: bool = False
    scheduler: str | None = None
    worker_writes: bool = False
    ship_assets: bool = False

    @classmethod
    def from_args(cls, args) -> "RenderOptions":
        return cls(**{f.name: getattr(args, f.name) for f in dataclasses.fields(cls)})


def open_stage(path: str):
    """The stage at ``path`` (usd_io.stage.open_stage: a file that is not a stage says so here, before anything
    waits for the kernels)."""
    from .stage import open_stage as _open  # here: pxr loads after the flags are checked (start-up)

    return _open(path)


def render_file(request: StageRequest, settings, output: str, frames, outputs: Outputs, options: RenderOptions,
                stage=None) -> int:
    """Render one stage (all its frames) to ``output``; UsdInputError for what the user can fix. ``stage``: the
    stage already opened from ``request.path`` (else it is opened here). Returns the exit code (a farm reports
    failed frames itself and returns 2)."""
    if stage is None:
        stage = open_stage(request.path)
    if options.scheduler:
        from .farm import FarmOptions, render_on_farm

        farm = FarmOptions(options.scheduler, worker_writes=options.worker_writes, ship_assets=options.ship_assets,
                           quiet=options.quiet)
        return render_on_farm(request, settings, frames, output, outputs, farm)
    from tracer import render

    many = len(frames) > 1
    for frame in frames:
        scene, info = request.at(frame).read(stage)
        if frame == frames[0]:
            print_warnings(info)
            settings, outputs = _render_vars(info, settings, outputs)
        if frame == frames[0]:  # an impossible size is refused before the kernels, the PNG stream or the film
            check_size(request.path, settings.with_(width=info.width, height=info.height))
        _prepare_kernels(options.quiet)
        out = frame_path(output, frame, many)
        stream = outputs.stream(out, info.width, info.height)  # a PNG is encoded while the tiles are traced
        try:
            image = render(scene, settings.with_(width=info.width, height=info.height),
                           on_tile=stream.on_tile if stream is not None else None)
        except BaseException:
            if stream is not None:
                stream.abort()
            raise
        _warn_not_finite(image.rgba, request.path)
        outputs.write(image, out, stream)
        if not options.quiet:
            s = image.stats
            print(f"{out}: {info.width}x{info.height}, {len(scene.triangles):,} triangles, "
                  f"{s['rays']['total']:,} rays in {s['seconds']:.2f} s", file=sys.stderr)
    if info.nothing_drawn:  # gprims that gave no triangle: written, but not a success (usd_io.reader)
        print(f"whitted: error: {request.path}: {info.nothing_drawn}", file=sys.stderr)
        return EXIT_BAD_INPUT
    return EXIT_OK


def check_size(scene_path: str, settings) -> None:
    """BadInput when the render needs more memory than the machine has (tracer.integrator.tiles.check_memory's estimate)."""
    from tracer.integrator.tiles import RenderTooLarge, check_memory

    try:
        check_memory(settings)
    except RenderTooLarge as exc:
        raise BadInput(f"{scene_path}: {exc} (use a smaller --width/--height)") from None


def _product_output(args, scene_path: str, stage) -> str:
    """Without ``-o``: the first productName of the stage's RenderSettings (usd_io.render_settings)."""
    from .render_settings import product_names

    names = product_names(stage, getattr(args, "render_settings_prim", None))
    if not names:
        raise BadInput(f"{scene_path}: -o OUT is required (the stage has no RenderProduct with a productName)")
    return _confined(args, scene_path, names[0])


def _confined(args, scene_path: str, name: str) -> str:
    """A productName's output path, inside ``--output-dir`` unless ``--allow-product-paths`` (outputs.product_path)."""
    try:
        return product_path(name, args.output_dir, args.allow_product_paths)
    except BadInput as exc:
        raise BadInput(f"{scene_path}: {exc}") from None


def _more_products(args, request, stage) -> list:
    """(request, output path) of the RenderProducts after the first: each renders with its own camera, size and
    RenderVars (``--render-settings`` naming the product prim)."""
    from .render_settings import products

    more = products(stage, request.render_settings_prim)[1:]
    return [(dataclasses.replace(request, render_settings_prim=prim), _confined(args, request.path, name))
            for name, prim in more]


def _render_vars(info, settings, outputs):
    """The stage's UsdRender RenderVars as AOVs when ``--aov`` asked for none (usd_io.render_settings)."""
    spec = info.render_settings
    if spec is None or not spec.aovs or settings.aovs:
        return settings, outputs
    return settings.with_(aovs=tuple(spec.aovs)), dataclasses.replace(outputs, aovs=tuple(spec.aovs))


def _prepare_kernels(quiet: bool) -> None:
    """Kernels are compiled as the render first uses them (only those it uses: tracer/jit.py) and loaded from the
    cache after that. Where this version's kernels are not all cached yet, say so and count the compile units as
    they finish (once per process)."""
    global _kernels_ready
    if _kernels_ready:
        return
    _kernels_ready = True
    from tracer.jit import kernels_cached

    if quiet or kernels_cached():
        return
    import time

    from tracer.jit import CompileProgress

    last = [0.0]

    def report(done, name, seconds):
        if seconds - last[0] >= 2.0 or done == 1:
            last[0] = seconds
            helper = _helper
            print(f"whitted: compiling kernels (first use of this version on this machine, then cached): "
                  f"{compile_status(done, seconds, helper)}, last {name}", file=sys.stderr, flush=True)

    CompileProgress(report).install()


def compile_status(done: int, seconds: float, helper=None) -> str:
    """``97 of about 130 units in 9 s, about 4 s left (2 processes)``: the units compiled by this process and its
    helper against the plan's total (tracer/kernel_plan.py), and the time left at the rate so far; without a
    helper, the units done so far."""
    if helper is None or not helper.total:
        return f"{done} units in {seconds:.0f} s"
    done += helper.units()
    if done >= helper.total:
        return f"{done} units in {seconds:.0f} s (2 processes)"
    left = seconds / max(done, 1) * (helper.total - done)
    return f"{done} of about {helper.total} units in {seconds:.0f} s, about {left:.0f} s left (2 processes)"


def _warn_not_finite(rgba: np.ndarray, scene_path: str) -> None:
    """One warning when the renderer produced NaN/inf pixels (the film writes them black, silently)."""
    if np.isfinite(rgba.min()) and np.isfinite(rgba.max()):  # NaN propagates through both: 2 ms, no temporaries
        return
    bad = int(np.count_nonzero(~np.all(np.isfinite(rgba), axis=-1)))
    if bad:
        warn(f"{scene_path}: {bad} pixel(s) not finite (NaN or inf; written black)")


def _compile_kernels(quiet: bool) -> None:
    """Compile (or load) every kernel of every render path, counting compile units on stderr unless ``quiet``."""
    from tracer import compile_kernels
    from tracer.jit import CompileProgress

    def report(done, name, seconds):
        print(f"\rwhitted: compiling kernels: {done} done, {seconds:.0f} s ({name})\033[K", end="",
              file=sys.stderr, flush=True)

    progress = CompileProgress(report if not quiet else (lambda *a: None))
    with progress:
        compile_kernels()
        from tracer.png_stream import to_display_fast

        to_display_fast(np.zeros((1, 1, 4), np.float32))  # the PNG stream's kernel (usd_io.outputs.Outputs.stream)
    if progress.done and not quiet:
        print(file=sys.stderr)


def cmd_info(args) -> int:
    scene, info = StageRequest.from_args(args).read()
    out = sys.stdout
    print(f"stage: {info.path}", file=out)
    print(f"upAxis: {info.up_axis}, metersPerUnit: {info.meters_per_unit:g}", file=out)
    print(f"cameras ({len(info.cameras)}):", file=out)
    for c in info.cameras:
        print(f"  {c}{'  (default)' if c == info.camera else ''}", file=out)
    if info.camera is None:
        print("  (none: a default camera frames the bounds)", file=out)
    rs = info.render_settings
    if rs is not None:  # UsdRender (usd_io.render_settings)
        print(f"render settings: {rs.path}: {info.width}x{info.height}, {rs.conform}, products "
              f"{', '.join(rs.products) or 'none'}, AOVs {', '.join(rs.aovs) or 'none'}", file=out)
    from tracer import RenderSettings
    from tracer.integrator.tiles import available_memory, describe_memory, format_bytes

    size = RenderSettings(width=info.width, height=info.height)
    free = available_memory()
    print(f"memory: a {info.width}x{info.height} render at the default settings needs {describe_memory(size)}"
          + (f"; {format_bytes(free)} available" if free is not None else ""), file=out)
    print(f"lights ({len(info.lights)}):", file=out)
    for path, kind, light in info.lights:
        print(f"  {path}: {kind} -> {_describe_light(light)}", file=out)
    print(f"meshes ({len(info.meshes)}, {sum(n for _, n in info.meshes):,} triangles):", file=out)
    for path, n in info.meshes:
        print(f"  {path}: {n:,} triangles", file=out)
    print(f"materials ({len(info.materials)}):", file=out)
    for name, fields in info.materials.items():
        print(f"  {name} -> " + ", ".join(f"{k}={v}" for k, v in fields.items()), file=out)
    print_warnings(info)
    return EXIT_OK


def _value(v) -> str:
    if isinstance(v, str):
        return v
    if v is None:
        return "none"
    if hasattr(v, "cone_angle"):  # a LightShaping
        return (f"(cone {np.degrees(v.cone_angle):.4g}°, softness {v.softness:.4g}, focus {v.focus:.4g}, "
                f"tint {_value(v.focus_tint)})")
    if isinstance(v, np.ndarray) and v.ndim == 3:  # a light's texture
        return f"{v.shape[1]}x{v.shape[0]} image"
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
    _compile_kernels(quiet=not sys.stderr.isatty())
    print(f"whitted: kernels {'were already compiled' if was else 'compiled'} "
          f"({time.perf_counter() - start:.1f} s)", file=sys.stderr)
    return 0


_COMMANDS = {"render": cmd_render, "info": cmd_info, "explain": cmd_explain, "warmup": cmd_warmup}


def main(argv=None) -> int:
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
    except UsdInputError as exc:
        print(f"whitted: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        film = sys.modules.get("tracer.film")  # loaded once anything was written
        if film is not None:  # wherever the interrupt landed, no half-written .whitted-* file stays behind
            film.remove_temp_files()
        print("whitted: interrupted", file=sys.stderr)
        return 130
    except SystemExit as exc:  # --help
        return int(exc.code or 0)
    except Exception as exc:  # noqa: BLE001 — a real fault: show where
        tiles = sys.modules.get("tracer.integrator.tiles")
        if tiles is not None and isinstance(exc, tiles.RenderTooLarge):  # a size no command can render (explain)
            print(f"whitted: error: {' '.join(str(exc).split())}", file=sys.stderr)
            return EXIT_BAD_INPUT
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

"""What the command line asks for, each part defined once: the stage request and the render settings.

:class:`StageRequest` is which stage to read and how (path, time, camera, the image size asked for, purposes,
variants, complexity, the default light). The CLI builds it once (:meth:`StageRequest.from_args`) and hands it
to ``render``, ``explain``, ``info`` and the farm (:class:`usd_io.farm.UsdSource` *is* a StageRequest, so a worker
reads the stage exactly as a local render does). :func:`add_settings_flags` makes one flag per
:class:`tracer.RenderSettings` field from its metadata (tracer/settings.py) and :func:`settings_from_args` reads
them back: render, explain and the farm take the same flags and get the same settings.

Adding a request field is a one-place change: a field of :class:`StageRequest` with its :func:`request_field`
(the flag's names and argparse options; ``parse`` turns the flag's value into the field's). :func:`add_request_flags`
makes the flag for every command, :meth:`StageRequest.from_args` reads it, :meth:`StageRequest.read` passes it to
:func:`usd_io.load_stage` under the field's name (which the reader must then take). For example::

    render_settings_prim: str | None = request_field(None, "--render-settings", metavar="PRIM",
                                                help="the UsdRender.Settings prim to render with")

A field with ``flags=()`` takes the flag of the RenderSettings field of the same name (width, height: the size
asked for; the stage's camera aperture decides the missing side; depth_of_field, motion_blur: whether the reader
takes the camera's lens and shutter). This module imports neither pxr nor the
tracer's kernels: the parser is built before anything heavy loads.
"""

from __future__ import annotations

import argparse
import dataclasses
import re
from dataclasses import dataclass, field, fields

from tracer.settings import INT_FIELDS, SETTINGS, RenderSettings, default_of

from .errors import UsdInputError
from .exporters import UNITS
from .geometry.complexity import COMPLEXITY, DEFAULT_COMPLEXITY
from .outputs import warn


def request_field(default, *flags, parse=None, **options):
    """A :class:`StageRequest` field: its command-line ``flags`` (argparse ``options``: help, metavar, action...)
    and ``parse`` (flag value -> field value; None: as it is)."""
    return field(default=default, metadata={"flags": flags, "options": options, "parse": parse})


def split_purposes(values) -> tuple[str, ...] | None:
    """``--purposes`` takes one comma-separated value (``render,proxy,guide``). One value, not several separated
    by spaces: a flag that takes several swallows the scene path after it (``--purposes render SCENE``). A list
    (the API's) is accepted, each item comma-separated too."""
    if values is None:
        return None
    if isinstance(values, str):
        values = [values]
    return tuple(p.strip() for v in values for p in v.split(",") if p.strip())


def parse_variant(text: str):
    """``/Prim:set=value`` -> (prim path, set, value)."""
    m = re.fullmatch(r"\s*(/[^:=\s]*)\s*:\s*([^=\s]+)\s*=\s*(\S+)\s*", text or "")
    if not m:
        raise argparse.ArgumentTypeError(f"{text!r}: expected /Prim/Path:variantSet=variant")
    return m.group(1), m.group(2), m.group(3)


@dataclass(frozen=True)
class StageRequest:
    """A USD stage and how to read it: everything :func:`usd_io.load_stage` takes (see the module docstring)."""

    path: str
    time: float | None = request_field(None, "--time", "--frame", type=float, metavar="T",
                                       help="time code (default: the earliest; the stage's default values)")
    camera: str | None = request_field(None, "--camera", "--cam", metavar="PRIM",
                                       help="camera prim path (default: the first camera in the stage)")
    width: int | None = request_field(None)
    height: int | None = request_field(None)
    depth_of_field: bool | None = request_field(None)  # --dof/--no-dof: the camera's lens (tracer.settings)
    motion_blur: bool | None = request_field(None)  # --motion-blur/--no-motion-blur: the camera's shutter
    purposes: tuple | None = request_field(None, "--purposes", parse=split_purposes, metavar="P[,P...]",
                                           help="purposes to render, comma-separated, e.g. render,proxy,guide "
                                           "(default: default,render)")
    variants: tuple = request_field((), "--variant", action="append", type=parse_variant, metavar="/PRIM:SET=VALUE",
                                    parse=lambda v: tuple(v or ()),
                                    help="select a variant before reading (repeatable)")
    complexity: str = request_field(DEFAULT_COMPLEXITY, "--complexity", "-c", choices=list(COMPLEXITY),
                                    help="subdivision surfaces: low = the control cage, medium = 1 level of "
                                    "Catmull-Clark (default), high = 2, veryhigh = 3 (usdrecord's names)")
    default_light: bool = request_field(True, "--no-default-light", "--disableCameraLight", action="store_false",
                                        help="leave a stage without lights unlit (default: a camera headlight "
                                        "and a dim dome, as usdview)")
    render_settings_prim: str | None = request_field(None, "--render-settings", metavar="PRIM",
                                                     help="the UsdRender RenderSettings prim to render with "
                                                     "(default: the stage's renderSettingsPrimPath): resolution, "
                                                     "camera, pixel aspect, conform policy, data window, RenderVars "
                                                     "as AOVs")
    light_units: str = request_field("auto", "--light-units", choices=["auto", *UNITS],
                                     help="auto (default): lights in the units of the application that wrote the "
                                     "stage (Blender by version, Omniverse Kit; a note says which); spec: as "
                                     "UsdLux says (docs/usd.md, \"Two readings\")")

    @classmethod
    def from_args(cls, args, path: str | None = None) -> "StageRequest":
        """The request of parsed ``args`` (made by :func:`add_request_flags`) for the stage at ``path`` (default:
        ``args.scene``)."""
        values = {}
        for f in fields(StageRequest):
            if f.name == "path" or not hasattr(args, f.name):
                continue
            v = getattr(args, f.name)
            parse = f.metadata["parse"]
            values[f.name] = parse(v) if parse is not None else v
        return cls(path=path if path is not None else args.scene, **values)

    def at(self, time) -> "StageRequest":
        """This request at another time code."""
        return dataclasses.replace(self, time=time)

    def read(self, stage=None):
        """``usd_io.load_stage`` of this request (``stage``: the stage already opened from ``path``) ->
        (tracer.Scene, StageInfo). Fields left at None take the reader's defaults."""
        from .reader import load_stage  # here: the reader loads pxr and the tracer, which parsing flags does not

        kw = {f.name: getattr(self, f.name) for f in fields(StageRequest)
              if f.name != "path" and getattr(self, f.name) is not None}
        return load_stage(stage if stage is not None else self.path, **kw)


def add_request_flags(parser) -> None:
    """The flags of every :class:`StageRequest` field that has its own (the others come with the settings')."""
    for f in fields(StageRequest):
        flags = f.metadata.get("flags") if f.metadata else None
        if flags:
            parser.add_argument(*flags, dest=f.name, default=f.default if f.default != () else None,
                                **f.metadata["options"])


def add_settings_flags(parser) -> None:
    """One flag per :class:`tracer.RenderSettings` field that has one (its ``Setting.flag``), from the field's
    metadata: type from the default, choices, bounds and unit in the help. Every flag defaults to None (= the
    field's default, or for width/height the stage's camera aperture)."""
    for name, s in SETTINGS.items():
        if s.flag is None:
            continue
        default = default_of(name)
        unit = f" [{s.unit}]" if s.unit else ""
        shown = "from the camera aperture" if name in ("width", "height") else \
            ("unset" if default is None else (",".join(default) or "none") if isinstance(default, tuple) else default)
        help_text = f"{s.help}{unit} (default {shown})"
        kw = dict(dest=name, default=None, help=help_text.replace("%", "%%"))
        if isinstance(default, bool):
            kw["action"] = argparse.BooleanOptionalAction
        elif isinstance(default, tuple):
            kw.update(type=_comma_list(s.flag, s.choices), metavar=s.metavar)
        elif s.choices:
            kw["choices"] = s.choices
        else:
            kw.update(type=_number(s.flag, name), metavar=s.metavar)
        parser.add_argument(s.flag, *s.aliases, **kw)
    parser.add_argument("--spp", dest="spp_deprecated", type=int, help=argparse.SUPPRESS)  # the old --aa: warns


def settings_from_args(args, **overrides):
    """The :class:`tracer.RenderSettings` the flags of :func:`add_settings_flags` ask for (flags not given keep
    the field's default; ``overrides``, e.g. the image size the stage resolved, win), validated: a value out of
    its bounds is a :class:`usd_io.UsdInputError` naming the flag."""
    if getattr(args, "spp_deprecated", None) is not None:
        warn("--spp is deprecated: use --aa N (N×N samples per pixel, the same meaning)")
        if getattr(args, "samples", None) is None:
            args.samples = args.spp_deprecated
    kw = {name: getattr(args, name) for name, s in SETTINGS.items()
          if s.flag is not None and getattr(args, name, None) is not None}
    kw.update(overrides)
    try:
        return RenderSettings(**kw).validate()
    except ValueError as exc:  # "settings.max_depth must be ..." -> "--max-depth must be ..."
        message = re.sub(r"\bsettings\.(\w+)", lambda m: SETTINGS[m.group(1)].flag or m.group(0)
                         if m.group(1) in SETTINGS else m.group(0), str(exc))
        raise UsdInputError(message) from None


def _number(flag: str, name: str):
    cast = int if name in INT_FIELDS else float

    def parse(text):
        try:
            return cast(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {'an integer' if cast is int else 'a number'}")

    parse.__name__ = cast.__name__  # argparse names the type in its message
    return parse


def _comma_list(flag: str, choices: tuple):
    def parse(text):
        names = tuple(a.strip() for a in (text or "").split(",") if a.strip())
        bad = [a for a in names if a not in choices]
        if bad:
            raise argparse.ArgumentTypeError(f"unknown value(s) {', '.join(bad)}; choose from {', '.join(choices)}")
        return names

    return parse

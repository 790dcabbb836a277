"""Render settings: everything about *how* to trace, nothing about *what*.

:class:`RenderSettings` is the one definition of every setting. Each field carries a :class:`Setting` in its
metadata (as Mitsuba documents each plugin parameter once): help text, unit, bounds, choices, how it appears as a
command-line flag and as a Blender property, and whether the session's packed tables depend on it. Everything
else is generated from it or checked against it:

- :meth:`RenderSettings.validate` reads the bounds and choices;
- ``usd_io/request.py`` makes the ``whitted render/explain/info`` flags and reads them back into one
  :class:`RenderSettings` (which the farm's ``UsdSource`` carries to its workers);
- ``addon/properties.py`` makes the Blender properties (``scene.whitted``) and ``addon/export.py`` reads them back;
- :func:`integrator_key` (``tracer.Session``'s cache of the packed tables) takes the ``rebuilds_integrator`` fields.

Adding a setting is a one-place change: a field here with its :func:`setting` (tests/test_settings.py walks every
field through the CLI, the add-on, the session key and the farm source).
"""

from __future__ import annotations

import math
from dataclasses import MISSING, dataclass, field, fields, replace

AOV_NAMES = ("depth", "normal", "albedo", "objectid", "direct", "reflection", "transmission", "raydepth",
             "shadow_catcher", "denoising_albedo", "denoising_normal", "sample_count")
#: The denoiser's guides (tracer/integrator/guides.py), Cycles' Denoising Albedo and Denoising Normal passes: made whenever
#: ``RenderSettings.denoise`` is on, written as AOVs when asked.
GUIDE_AOVS = ("denoising_albedo", "denoising_normal")
#: AOVs that split the beauty by the ray type light arrived through (they sum to it), and the deepest ray per pixel.
RAY_TYPE_AOVS = ("direct", "reflection", "transmission", "raydepth")
#: Local illumination models (RenderSettings.shading): the Principled BSDF's diffuse + GGX specular evaluated per
#: light sample (matches Cycles), or the notes' Lambert + Blinn-Phong.
SHADING_MODELS = ("principled", "classic")
#: The one default anti-aliasing level (N for N×N samples per pixel) of RenderSettings, the CLI's --aa, the add-on
#: and `make render`.
DEFAULT_AA = 2


@dataclass(frozen=True)
class Setting:
    """What one :class:`RenderSettings` field means and where it appears (the field's ``metadata["setting"]``).

    ``lo``/``hi``: the valid range (None: unbounded; ``lo_open``/``hi_open``: the bound itself is not valid);
    ``choices``: the valid values (for a tuple field: of each item). ``flag``: the command line's flag
    (``aliases`` too; a bool becomes ``--flag/--no-flag``); None: not a flag, and ``cli_from`` says where the CLI
    takes it from. ``blender``: the Blender property's label (``panel``: the heading it is drawn under in Render
    Properties, addon/ui.py; ``ui``: its extra options, ``soft_max``, ``precision``, ``subtype``; ``none_as``: the
    value a property stores for None, e.g. 0 = automatic; ``toggle``: (checkbox property, its label, the value
    the property starts at) for a setting Blender shows as a checkbox and a value, as Cycles' Noise Threshold: the
    checkbox off gives the field's default; ``active_with``: the field whose checkbox greys this one out); None:
    not a property, and ``blender_from`` says where the add-on takes it from; ``blender_default``: the property's
    default where Blender's differs from the API's (None: the field's own; Denoise is on for F12 as in Cycles, off
    for the API and the CLI). ``rebuilds_integrator``: the session's packed tables
    (the Integrator's ``Options``, its light table) depend on it, so a change makes a new Integrator; any other
    setting is read per render."""

    help: str
    unit: str = ""
    lo: float | None = None
    lo_open: bool = False
    hi: float | None = None
    hi_open: bool = False
    choices: tuple = ()
    flag: str | None = None
    aliases: tuple = ()
    metavar: str | None = None
    cli_from: str = ""
    blender: str | None = None
    panel: str = ""
    ui: tuple = ()
    none_as: object = None
    toggle: tuple = ()
    active_with: str = ""
    blender_from: str = ""
    blender_default: object = None
    rebuilds_integrator: bool = False


def setting(default, help: str, *, factory=None, **meta):
    """A :class:`RenderSettings` field with its :class:`Setting` (keyword arguments as Setting's)."""
    md = {"setting": Setting(help=help, **meta)}
    if factory is not None:
        return field(default_factory=factory, metadata=md)
    return field(default=default, metadata=md)


@dataclass
class RenderSettings:
    # 960: usdrecord's --imageWidth default, which the CLI keeps; the CLI's height follows the camera's aperture
    width: int = setting(960, "image width", unit="px", lo=1, flag="--width", aliases=("--imageWidth", "-w"),
                         metavar="W", blender_from="the render resolution × percentage")
    height: int = setting(540, "image height (the CLI: from the camera aperture's aspect)", unit="px", lo=1,
                          flag="--height", metavar="H", blender_from="the render resolution × percentage")
    samples: int = setting(DEFAULT_AA, "anti-aliasing: N×N stratified samples per pixel (box filter); 1 = one ray "
                           "through each pixel centre", unit="N", lo=1, flag="--aa", metavar="N",
                           blender="Samples", panel="Sampling", ui=(("soft_max", 8), ("max", 64)))
    adaptive_threshold: float = setting(0.0, "adaptive sampling's noise threshold (Cycles' Noise Threshold, the "
                                        "same scale): a pixel stops taking samples of its N×N budget once its noise "
                                        "estimate is below it; 0.01 is Cycles' default, higher is faster and noisier; "
                                        "0 = off (every pixel takes all N×N)", lo=0, hi=1, flag="--adaptive-threshold",
                                        metavar="T", blender="Noise Threshold", panel="Sampling",
                                        toggle=("use_adaptive_sampling", "Noise Threshold", 0.01),
                                        ui=(("soft_min", 0.001), ("precision", 4)))
    adaptive_min_samples: int = setting(0, "adaptive sampling: samples every pixel takes before it may stop "
                                        "(at most N×N); 0 = automatic, Cycles' rule max(4, ⌈16 / threshold^0.3⌉)",
                                        lo=0, flag="--adaptive-min-samples", metavar="N", blender="Min Samples",
                                        panel="Sampling", active_with="adaptive_threshold", ui=(("max", 4096),))
    max_depth: int = setting(8, "maximum recursion depth of reflection/transmission rays (0 = eye and shadow rays "
                             "only)", lo=0, flag="--max-depth", metavar="D", rebuilds_integrator=True,
                             blender="Max Depth", panel="Rays", ui=(("max", 64),))
    epsilon: float | None = setting(None, "offset of spawned rays; unset = automatic (tracer.Scene.default_epsilon: "
                                    "5e-5 of the scene size)", unit="scene units", lo=0, lo_open=True,
                                    flag="--epsilon", rebuilds_integrator=True, blender="Epsilon", panel="Rays",
                                    none_as=0.0, ui=(("soft_max", 0.01), ("precision", 6), ("subtype", "DISTANCE")))
    fresnel: bool = setting(True, "dielectric Fresnel weighting of glass (as Cycles); off = the notes' fixed "
                            "weights", flag="--fresnel", rebuilds_integrator=True, blender="Fresnel", panel="Rays")
    shadows: bool = setting(True, "cast shadow rays towards the lights; off lights every surface as if nothing "
                            "were in the way", flag="--shadows", rebuilds_integrator=True, blender="Shadows",
                            panel="Rays")
    light_samples: int = setting(16, "samples per light with an extent (point radius, sun angle, area lights); "
                                 "rounded to N×N", lo=1, flag="--light-samples", metavar="N",
                                 rebuilds_integrator=True, blender="Light Samples", panel="Sampling",
                                 ui=(("max", 1024),))
    sky_samples: int = setting(16, "shadow rays per shading point towards the world (an environment's bright "
                               "parts and the cosine-weighted sky; fewer at deeper hits that carry less weight), so "
                               "the world casts shadows as in Cycles; rounded to N×N; 0 = the notes' flat, unshadowed "
                               "ambient term", lo=0, flag="--sky-samples", metavar="N", rebuilds_integrator=True,
                               blender="Sky Visibility Samples", panel="Sampling", ui=(("max", 1024),))
    terminal_rays: bool = setting(False, "one more reflection/transmission bounce past the max depth that collects "
                                  "only background and emission (Cycles' last bounce); off = the notes' hard "
                                  "cut-off", flag="--terminal-rays", rebuilds_integrator=True,
                                  blender="Terminal Bounce", panel="Sampling")
    shading: str = setting("principled", "local model: principled (Cycles' Principled BSDF: diffuse + GGX) or "
                           "classic (the notes' Lambert + Blinn-Phong)", choices=SHADING_MODELS, flag="--shading",
                           rebuilds_integrator=True, blender="Shading", panel="Rays")
    max_transparent: int = setting(8, "surfaces with alpha < 1 (or cut-outs) one ray may pass through (Cycles' "
                                   "Transparent Max Bounces); not counted in the max depth", lo=0,
                                   flag="--max-transparent", metavar="N", blender="Transparent Max Bounces",
                                   panel="Rays", ui=(("max", 1024),))
    min_weight: float = setting(1e-3, "paths whose accumulated weight falls below this stop (deterministic "
                                "cut-off)", lo=0, hi=1, hi_open=True, flag="--min-weight", rebuilds_integrator=True,
                                blender_from="the default (not in the add-on's panel)")
    transparent: bool = setting(False, "missed eye rays get alpha 0 and no background colour (Blender's Film > "
                                "Transparent)", flag="--transparent", rebuilds_integrator=True,
                                blender_from="Film > Transparent")
    depth_of_field: bool = setting(True, "depth of field of a camera with a lens (USD: fStop > 0 with a "
                                   "focusDistance, unless the RenderSettings' disableDepthOfField; Blender: the "
                                   "camera's Depth of Field); off = every camera is a pinhole, as Storm draws it "
                                   "(many exporters write fStop 5.6 on every camera). Read by the front ends as they "
                                   "build the scene's camera", flag="--dof",
                                   blender_from="the scene camera's Camera > Depth of Field checkbox")
    motion_blur: bool = setting(True, "motion blur across the camera's shutter (USD: shutter:open/close, unless the "
                                "RenderSettings' disableMotionBlur; Blender: Render > Motion Blur); off = everything "
                                "where it is at the frame. Read by the front ends as they build the scene",
                                flag="--motion-blur", blender_from="Render > Motion Blur")
    denoise: bool = setting(False, "denoise the finished frame with Open Image Denoise, guided by the albedo and "
                            "normal at the first non-specular hit (Cycles' Denoising Data passes; the "
                            "denoising_albedo / denoising_normal AOVs); the whole frame at once, never tile by tile. "
                            "Needs an OIDN 2 library: pip install 'whitted[denoise]' (Blender ships its own)",
                            flag="--denoise", blender="Denoise", panel="Denoise", blender_default=True)
    tile_size: int = setting(128, "pixel tile edge; memory is bounded by tile size × samples", unit="px", lo=4,
                             flag="--tile-size", metavar="PX", blender_from="the default (Blender shows no tiles)")
    threads: int | None = setting(None, "worker threads, the denoiser's too; unset = all cores (images are identical "
                                  "for any count)",
                                  lo=1, flag="--threads", metavar="N", blender="Threads", panel="Performance",
                                  none_as=0, ui=(("max", 1024),))
    aovs: tuple = setting((), "extra outputs (float32 EXR next to the image): depth, normal, albedo, objectid, and "
                          "direct, reflection, transmission (the beauty by the path's first secondary ray; they "
                          "sum to it), raydepth (deepest ray per pixel: EXR + heat-map PNG), shadow_catcher (Cycles' "
                          "Shadow Catcher pass; with it, Combined leaves the catchers' shadows out), denoising_albedo, "
                          "denoising_normal (the denoiser's guides: Cycles' Denoising Data passes, the normal in "
                          "camera space), sample_count (samples each pixel took: N×N, or fewer with adaptive "
                          "sampling; EXR + heat-map PNG)", choices=AOV_NAMES,
                          flag="--aov", metavar="A[,A...]",
                          blender_from="the view layer's passes (Z, Normal, Object Index, Denoising Data, Cycles' "
                          "Debug Sample Count) and Ray-Type Passes")
    region: tuple | None = setting(None, "render only this pixel rectangle (x0, y0, x1, y1), top-left origin, "
                                   "exclusive upper bounds", cli_from="not on the command line (the API; the "
                                   "farm's tiles)", blender_from="the render border")
    seed: int = setting(0, "seed of the deterministic sample patterns", lo=0, flag="--seed",
                        rebuilds_integrator=True, blender_from="the default (not in the add-on's panel)")
    progress: bool = setting(False, "a tqdm progress bar on stderr", cli_from="on unless --quiet",
                             blender_from="off (Blender shows its own progress)")
    extra: dict = setting(None, "internal switches (record_rays: keep the ray batches for the benchmarks)",
                          factory=dict, cli_from="not on the command line", blender_from="not in the add-on")

    def validate(self) -> "RenderSettings":
        for f in fields(self):
            _check(f.name, getattr(self, f.name), f.default, f.metadata["setting"])
        if self.region is not None:
            x0, y0, x1, y1 = (int(c) for c in self.region)
            if not (0 <= x0 < x1 <= self.width and 0 <= y0 < y1 <= self.height):
                raise ValueError(f"settings.region {self.region} must lie inside {self.width}x{self.height} "
                                 "and be non-empty")
        return self

    def with_(self, **changes) -> "RenderSettings":
        return replace(self, **changes)


def spec(name: str) -> Setting:
    """The :class:`Setting` of field ``name``."""
    return SETTINGS[name]


#: Field name -> its :class:`Setting`, in field order.
SETTINGS = {f.name: f.metadata["setting"] for f in fields(RenderSettings)}


def default_of(name: str):
    """The default value of field ``name``."""
    f = next(f for f in fields(RenderSettings) if f.name == name)
    return f.default if f.default_factory is MISSING else f.default_factory()


def integrator_key(settings: RenderSettings) -> tuple:
    """The settings a session's packed tables (its Integrator) depend on: the ``rebuilds_integrator`` fields."""
    return tuple(getattr(settings, name) for name in INTEGRATOR_FIELDS)


#: Fields the Integrator's packed tables depend on (everything else it reads per render).
INTEGRATOR_FIELDS = tuple(name for name, s in SETTINGS.items() if s.rebuilds_integrator)


def _check(name: str, v, default, s: Setting) -> None:
    """One field against its :class:`Setting`: type (from the default), bounds, choices."""
    if v is None and default is None:
        return
    if isinstance(default, bool):
        if v not in (True, False):  # bool, numpy's bool_, 0/1
            raise ValueError(f"settings.{name} must be True or False, got {v!r}")
        return
    if s.choices and isinstance(default, tuple):
        unknown = [a for a in v if a not in s.choices]
        if unknown:
            raise ValueError(f"unknown {'AOV' if name == 'aovs' else name}(s) {unknown}; choose from "
                             f"{', '.join(s.choices)}")
        return
    if s.choices:
        if v not in s.choices:
            raise ValueError(f"settings.{name} must be one of {', '.join(s.choices)}, got {v!r}")
        return
    integral = name in INT_FIELDS
    if integral and (isinstance(v, bool) or not isinstance(v, int)):
        raise ValueError(f"settings.{name} must be an integer >= {s.lo:g}, got {v!r}")
    if not integral and s.lo is not None:
        try:
            ok = math.isfinite(v)
        except TypeError:
            ok = False
        if not ok:
            raise ValueError(f"settings.{name} must be a finite number, got {v!r}")
    lo_ok = s.lo is None or (v > s.lo if s.lo_open else v >= s.lo)
    hi_ok = s.hi is None or (v < s.hi if s.hi_open else v <= s.hi)
    if lo_ok and hi_ok:
        return
    if integral:
        raise ValueError(f"settings.{name} must be an integer >= {s.lo:g}, got {v!r}")
    interval = (f"{'(' if s.lo_open else '['}{s.lo:g}, {'inf' if s.hi is None else f'{s.hi:g}'}"
                f"{')' if s.hi_open or s.hi is None else ']'}")
    raise ValueError(f"settings.{name} must be in {interval}, got {v!r}")


#: Fields whose values are integers (from the annotations).
INT_FIELDS = {f.name for f in fields(RenderSettings) if str(f.type).split(" ")[0] == "int"}

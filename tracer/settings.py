"""Render settings: everything about *how* to trace, nothing about *what*."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

AOV_NAMES = ("depth", "normal", "albedo", "objectid", "direct", "reflection", "transmission", "raydepth")
#: AOVs that split the beauty by the ray type light arrived through (they sum to it), and the deepest ray per pixel.
RAY_TYPE_AOVS = ("direct", "reflection", "transmission", "raydepth")
#: Local illumination models (RenderSettings.shading): the Principled BSDF's diffuse + GGX specular evaluated per
#: light sample (matches Cycles), or the notes' Lambert + Blinn-Phong.
SHADING_MODELS = ("principled", "classic")
#: The one default anti-aliasing level (N for N×N samples per pixel) of RenderSettings, the CLI's --aa, the add-on
#: and `make render`.
DEFAULT_AA = 2


@dataclass
class RenderSettings:
    width: int = 640
    height: int = 480
    #: N for N×N stratified samples per pixel (box filter). 1 = one ray through each pixel centre.
    samples: int = DEFAULT_AA
    #: Maximum recursion depth of reflection/transmission rays (0 = eye rays and shadow rays only).
    max_depth: int = 8
    #: ε for spawned rays; None = :meth:`tracer.Scene.default_epsilon`.
    epsilon: float | None = None
    #: Dielectric Fresnel weighting of glass (matches Cycles); False = the notes' fixed weights ("classic").
    fresnel: bool = True
    #: Cast shadow rays; False lights every surface as if nothing were in the way.
    shadows: bool = True
    #: Samples per light for lights with an extent (point radius > 0, sun angle > 0, area lights); rounded to N×N.
    light_samples: int = 16
    #: Hemisphere shadow rays per shading point to weight the ambient term by sky visibility (0 = the classic,
    #: unoccluded ambient term; Cycles shadows its world light, so matching it needs e.g. 64).
    sky_samples: int = 0
    #: Trace one more reflection/transmission bounce past max_depth that collects only background and emission
    #: (what Cycles' last bounce does); False = the notes' hard cut-off.
    terminal_rays: bool = False
    #: Local model: "principled" (Principled diffuse + GGX specular, as Cycles) or "classic" (the notes' Lambert +
    #: Blinn-Phong). See README, "Conventions".
    shading: str = "principled"
    #: Surfaces with alpha < 1 (or cut-outs) one ray may pass through before it stops (Cycles' Transparent Max
    #: Bounces, default 8); passing through does not count towards max_depth.
    max_transparent: int = 8
    #: Paths whose accumulated weight falls below this stop early (Russian roulette-free cut-off; deterministic).
    min_weight: float = 1e-3
    #: Missed eye rays get alpha 0 and no background colour (Blender's Film > Transparent).
    transparent: bool = False
    #: Pixel tile edge; memory is bounded by tile size × samples, not by the image size.
    tile_size: int = 128
    #: Worker threads (None = all cores). Images are identical for any thread count.
    threads: int | None = None
    #: Arbitrary-output variables to produce besides the colour: any of depth, normal, albedo, objectid, and the
    #: ray-type AOVs direct, reflection, transmission (colour by the path's first secondary ray; they sum to the
    #: beauty) and raydepth (the deepest ray of the pixel's samples: 0 = eye rays only).
    aovs: tuple = ()
    #: Render only this pixel rectangle (x0, y0, x1, y1), top-left origin, exclusive upper bounds.
    region: tuple | None = None
    #: Seed of the deterministic sample patterns.
    seed: int = 0
    #: Show a tqdm progress bar on stderr.
    progress: bool = False
    extra: dict = field(default_factory=dict)

    def validate(self) -> "RenderSettings":
        def positive_int(name, lo=1):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < lo:
                raise ValueError(f"settings.{name} must be an integer >= {lo}, got {v!r}")

        positive_int("width")
        positive_int("height")
        positive_int("samples")
        positive_int("max_depth", 0)
        positive_int("light_samples")
        positive_int("sky_samples", 0)
        positive_int("tile_size", 4)
        positive_int("max_transparent", 0)
        if self.shading not in SHADING_MODELS:
            raise ValueError(f"settings.shading must be one of {', '.join(SHADING_MODELS)}, got {self.shading!r}")
        if self.threads is not None:
            positive_int("threads")
        if self.epsilon is not None and not (self.epsilon > 0 and self.epsilon < float("inf")):
            raise ValueError(f"settings.epsilon must be a positive finite number, got {self.epsilon!r}")
        if not (0 <= self.min_weight < 1):
            raise ValueError(f"settings.min_weight must be in [0, 1), got {self.min_weight!r}")
        unknown = [a for a in self.aovs if a not in AOV_NAMES]
        if unknown:
            raise ValueError(f"unknown AOV(s) {unknown}; choose from {', '.join(AOV_NAMES)}")
        if self.region is not None:
            x0, y0, x1, y1 = (int(c) for c in self.region)
            if not (0 <= x0 < x1 <= self.width and 0 <= y0 < y1 <= self.height):
                raise ValueError(f"settings.region {self.region} must lie inside {self.width}x{self.height} "
                                 "and be non-empty")
        return self

    def with_(self, **changes) -> "RenderSettings":
        return replace(self, **changes)

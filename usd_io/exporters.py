"""Which application wrote a stage, and the light units it meant (docs/usd.md, "Two readings").

UsdLux leaves units loose, and exporters filled the gap differently. The root layer's metadata names the writer:

    doc = "Blender v3.1.2" (Blender's exporter writes this)     Blender, by version
    customLayerData.creator = "Blender …"                          Blender (version from the string when present)
    customLayerData with omni_layer / cameraSettings / renderSettings["rtx:…"] or
        doc / creator naming Omniverse or Kit                     Omniverse Kit

and each writer maps to one set of units (:data:`UNITS`), applied by ``usd_io.lights.convert_light``:

    spec           the UsdLux reading (every other stage, and ``--light-units spec``)
    blender        Blender ≥ 4.0: the spec's except the sun (E = 4·I, diameter = 2·angle)
    blender-nits   Blender 3.2 – 3.6 stages **with a DomeLight**: intensities in nits (the "convert light to nits"
                   export of Blender's USD branch builds, 1 W/m² = 683 nits, i.e. nits · 0.0014641 = W/m²): a point
                   of power P was written P / (0.0014641 · 4πr²), a rect P / (0.0014641 · w·h), a disk
                   P / (0.0014641 · 2πr²), a sun S / 0.0014641 and the world's strength S as a DomeLight of S · 683
    blender-legacy Blender 2.83 – 3.1, and 3.2 – 3.6 stages without a DomeLight (the released exporter kept
                   ``energy / 100`` until 4.0 and wrote no world): intensity = P / 100 for points, spots and area
                   lights (no normalize), the sun's strength as is with its angle in radians written as degrees
    arnold         a stage written for Arnold (:func:`written_for_arnold`) without ``arnold:global:usdlux_version``
                   on its RenderSettings: Arnold's own light units, which arnold-usd passes through unchanged
                   (intensity, exposure, normalize, radius) and Arnold's core reads as its legacy lights do
                   unless usdlux_version is set: a distant light of I gives irradiance E = I whatever its angle
                   and normalize (the spec's I·Ω for an unnormalized angle), a point (sphere) light of radius 0 or
                   normalized E = I/d² at distance d (radiant intensity I; the spec's I/4); the radius is
                   ``primvars:arnold:radius`` when authored (Arnold's parameter wins). Rect, disk and dome
                   lights: as the spec (radiance I, normalized I/A)
    kit            Omniverse Kit: every intensity (and OmniPBR's emissive_intensity) × 2^KIT_EV (−9 EV: Kit's
                   lights are in nits seen through an auto-exposed camera; −9 EV matches its previews)

Evidence: the metadata above says who wrote the stage, and each light's own authored intensity
(``inputs:intensity`` or the pre-21.02 ``intensity``: ``usd_io.lights.authored``) says the writer chose that
number. A light without one carries UsdLux's fallback, no writer's value, and is read as the spec says under any
writer (so a guess can never darken what the writer did not write); the angle rules likewise need an authored
angle.

Sources (read with the team's search tools, not copied): Blender's ``source/blender/io/usd/intern/
usd_writer_light.cc`` at three points of its history — ``energy / 100.0f`` ("the reverse of the versioning code in
light_emission_unify()"), then ``convert_light_to_nits`` with ``nits_to_energy_scale_factor`` (area factors 4πr²,
w·h, 2πr², and ``nits_to_watts_per_meter_sq = 0.0014641``) and ``world_material_to_dome_light`` writing
``strength · watts_per_meter_sq_to_nits`` in ``usd_light_convert.cc``, then ``energy / M_PI`` with
``normalize = true`` and the sun's ``energy / 4.0f`` ("approximately matches Karma"). The version boundaries are
those of the stages surveyed in issue #21.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

#: Omniverse Kit: intensities (lights, OmniPBR emissive_intensity) are scaled by 2^KIT_EV.
KIT_EV = -9.0
#: Blender's nits_to_watts_per_meter_sq (1 / 683).
NITS_TO_W_PER_M2 = 0.0014641
UNITS = ("spec", "blender", "blender-nits", "blender-legacy", "kit", "arnold")
#: Authored property-name prefixes only Arnold's writers (arnold-usd, Solaris' Arnold, MtoA, ...) write.
ARNOLD_PREFIXES = ("arnold:", "primvars:arnold:", "outputs:arnold:")


@dataclass(frozen=True)
class Writer:
    name: str  # e.g. "Blender 3.1.2", "Omniverse Kit"
    units: str  # one of UNITS


def _blender_units(version: tuple | None) -> str:
    if version is None or version >= (4, 0):
        return "blender"
    if version >= (3, 2):
        return "blender-nits"
    return "blender-legacy"


def detect(stage) -> Writer | None:
    """The application that wrote the stage's root layer, or None when its metadata does not say."""
    layer = stage.GetRootLayer()
    doc = str(layer.documentation or "")
    data = dict(layer.customLayerData or {})
    creator = str(data.get("creator", "") or "")
    for text in (doc, creator):
        m = re.match(r"\s*Blender(?: v)?\s*(\d+)\.(\d+)(?:\.(\d+))?", text)
        if m:
            version = tuple(int(x) for x in m.groups() if x is not None)
            return Writer(f"Blender {'.'.join(map(str, version))}", _blender_units(version))
        if text.strip().startswith("Blender"):
            return Writer("Blender", "blender")
    render = data.get("renderSettings") or {}
    kit_keys = isinstance(render, dict) and any(str(k).startswith("rtx:") for k in render)
    if "omni_layer" in data or kit_keys or re.search(r"omniverse|\bkit\b", doc + " " + creator, re.I):
        return Writer("Omniverse Kit", "kit")
    why = written_for_arnold(stage)
    if why is not None and arnold_usdlux_version(stage) is None:
        return Writer(f"Arnold ({why})", "arnold")
    return None


def written_for_arnold(stage) -> str | None:
    """What says ``stage`` was written for Arnold (the first piece found, e.g.
    "/Render/settings.arnold:global:AA_samples"), or None: a prim typed ``Arnold*`` (Arnold's USD schemas), an
    authored property named ``arnold:*`` (render settings, node parameters), ``primvars:arnold:*`` (per-object
    Arnold parameters) or ``outputs:arnold:*`` (a material's Arnold surface), or a shader whose ``info:id`` is
    ``arnold:*``. One traversal that stops at the first piece: callers keep the answer."""
    from pxr import Usd  # here: request.py reads UNITS for the CLI's flags before pxr is loaded

    found = None
    ranges = [stage.Traverse()] + [Usd.PrimRange(p) for p in stage.GetPrototypes()]  # each prim once, not per instance
    for prim in (p for r in ranges for p in r):
        if prim.GetTypeName().startswith("Arnold"):
            found = f"{prim.GetPath()} ({prim.GetTypeName()})"
            break
        name = next((n for n in prim.GetAuthoredPropertyNames() if n.startswith(ARNOLD_PREFIXES)), None)
        if name is not None:
            found = f"{prim.GetPath()}.{name}"
            break
        sid = prim.GetAttribute("info:id").Get() if prim.HasAttribute("info:id") else None
        if sid is not None and str(sid).startswith("arnold:"):
            found = f"{prim.GetPath()} ({sid})"
            break
    return found


def arnold_usdlux_version(stage) -> str | None:
    """A RenderSettings' ``arnold:global:usdlux_version`` when authored and not 0/empty: Arnold then reads the
    lights as UsdLux says (its USDLux compatibility mode), not in its own units."""
    from pxr import Usd  # here: as written_for_arnold

    for prim in stage.Traverse():
        if prim.GetTypeName() == "RenderSettings":
            a = prim.GetAttribute("arnold:global:usdlux_version")
            v = a.Get() if a and a.HasAuthoredValue() else None
            if v not in (None, "", 0, "0") and str(v).strip().lower() != "none":  # "None": Arnold's own reading
                return str(v)
    return None


def _has_dome(stage) -> bool:
    """Whether the stage holds a DomeLight: only the nits-writing branch builds exported Blender's world."""
    from pxr import Usd  # here: request.py reads UNITS for the CLI's flags before pxr is loaded

    return any(p.GetTypeName() in ("DomeLight", "DomeLight_1") for p in stage.Traverse(Usd.TraverseInstanceProxies()))


def light_units(stage, mode: str = "auto") -> tuple[str, str | None]:
    """(units, note): ``mode`` "auto" guesses from :func:`detect` (a note naming the writer and the conversion
    when it is not the spec's); "spec" (``--light-units spec``) or any of :data:`UNITS` forces those units."""
    if mode != "auto":
        if mode not in UNITS:
            raise ValueError(f"light units {mode!r}: choose auto or one of {', '.join(UNITS)}")
        return mode, None
    w = detect(stage)
    if w is None or w.units == "spec":
        return "spec", None
    if w.units == "blender-nits" and not _has_dome(stage):  # a released 3.2–3.6 build: energy / 100, no world
        w = Writer(w.name, "blender-legacy")
    what = {"blender": "its sun as E = 4·I",
            "blender-nits": "its intensities from nits (× 0.0014641, areas as its exporter computed them)",
            "blender-legacy": "its intensities as power / 100 (P = 100·I) and its sun angle in radians",
            "kit": f"its intensities × 2^{KIT_EV:g} (−9 EV)",
            "arnold": "a distant light's E = I whatever its angle, a point light's intensity I (not the spec's "
                      "I/4), primvars:arnold:radius"}[w.units]
    if w.units == "arnold":
        return w.units, (f"lights read in Arnold's own units (the stage is written for Arnold: {w.name[8:-1]}): "
                         f"{what} (docs/usd.md, \"Two readings\"; --light-units spec reads them as UsdLux says)")
    return w.units, (f"lights read in the units of {w.name}'s exporter: {what} (docs/usd.md, \"Two readings\"; "
                     "--light-units spec reads them as UsdLux says)")

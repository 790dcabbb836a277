"""UsdRender: ``RenderSettings`` / ``RenderProduct`` / ``RenderVar`` -> image size, camera, conform, data window,
output files and AOVs.

Which settings: the prim passed (``--render-settings PRIM``, usdrecord's flag), else the stage's
``renderSettingsPrimPath`` metadatum, else none. A product's own resolution, camera, pixelAspectRatio,
aspectRatioConformPolicy, dataWindowNDC and switches override the settings' (UsdRenderSettingsBase). The picture is the first
product's; ``--render-settings`` may also name a RenderProduct prim, which then renders with its own overrides on
top of the settings that list it. Without ``-o`` the CLI writes every product: each is rendered with its own
camera, size and RenderVars and written to its productName (``RenderSpec.product_paths`` lists them).

    resolution              image width and height (``--width``/``--height`` win when given)
    camera                  the camera rendered (``--camera`` wins)
    pixelAspectRatio        width of a pixel over its height: the image aspect is resX · par / resY
    aspectRatioConformPolicy  how the camera's aperture meets the image aspect (UsdRender's five):
        expandAperture        grow the aperture's short side (all the aperture shows stays in; the fallback)
        cropAperture          shrink its long side
        adjustApertureWidth   keep the vertical aperture, derive the horizontal
        adjustApertureHeight  keep the horizontal aperture, derive the vertical
        adjustPixelAspectRatio  keep both; the pixels stretch (non-square) to fit
    dataWindowNDC           (xmin, ymin, xmax, ymax) of the image in NDC (0, 0 lower left): only that part is
                            rendered, as an image of that part's size (the aperture and offsets cropped to it);
                            a window reaching beyond 0..1 renders the overscan (the aperture widened alike)
    disableDepthOfField     every camera a pinhole (as ``--no-dof``: ``RenderSpec.depth_of_field``)
    disableMotionBlur       no motion blur (as ``--no-motion-blur``; also the deprecated ``instantaneousShutter``:
                            ``RenderSpec.motion_blur``)
    products                ``productName`` of each product: the files written (``--output`` wins)
    RenderVars              ``sourceName`` mapped to the tracer's AOVs where one exists (:data:`RENDER_VAR_AOVS`);
                            ``color``/``Ci``/``rgba`` is the beauty; others warn once

Without RenderSettings the camera's aperture meets the image by the same rule with the fallback policy
(expandAperture), as Arnold and the UsdRender spec do.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
from pxr import Sdf, Usd, UsdRender

from tracer.settings import AOV_NAMES

from .errors import UsdInputError

#: UsdRender conform policies -> tracer.fit_apertures policies.
CONFORM = {"expandAperture": "expand", "cropAperture": "crop", "adjustApertureWidth": "vertical",
           "adjustApertureHeight": "horizontal", "adjustPixelAspectRatio": "none"}
DEFAULT_CONFORM = "expandAperture"
#: RenderVar sourceName (lower case) -> tracer AOV ("" = the beauty): every AOV by its own name
#: (tracer.settings.AOV_NAMES), and the other renderers' names for some.
RENDER_VAR_AOVS = {**{a: a for a in AOV_NAMES}, "color": "", "ci": "", "rgba": "", "rgb": "", "beauty": "",
                   "z": "depth", "n": "normal", "neye": "normal", "primid": "objectid", "id": "objectid",
                   "diffuse_albedo": "albedo"}


@dataclass
class RenderSpec:
    path: str
    resolution: tuple | None = None
    camera: str | None = None
    pixel_aspect: float = 1.0
    conform: str = DEFAULT_CONFORM
    data_window: tuple = (0.0, 0.0, 1.0, 1.0)
    depth_of_field: bool = True  # not disableDepthOfField
    motion_blur: bool = True  # not disableMotionBlur (nor the deprecated instantaneousShutter)
    products: list = field(default_factory=list)  # productName strings
    aovs: list = field(default_factory=list)  # tracer AOV names the rendered product's RenderVars map to
    product_paths: list = field(default_factory=list)  # every product's prim path, in order


def find_settings(stage, path, warn):
    """The RenderSettings prim: ``path``, else the stage's renderSettingsPrimPath, else None. UsdInputError for a
    ``path`` that is neither a RenderSettings nor a RenderProduct prim (for a product: the settings that list it,
    the stage's first)."""
    label = stage.GetRootLayer().identifier
    if path:
        if not Sdf.Path.IsValidPathString(path) or not Sdf.Path(path).IsAbsolutePath():
            raise UsdInputError(f"{label}: --render-settings {path!r} is not an absolute prim path")
        prim = stage.GetPrimAtPath(path)
        if prim and prim.IsA(UsdRender.Product):
            own = [UsdRender.Settings(p) for p in stage.Traverse() if p.IsA(UsdRender.Settings)
                   and prim.GetPath() in UsdRender.Settings(p).GetProductsRel().GetForwardedTargets()]
            if not own:
                raise UsdInputError(f"{label}: --render-settings {path}: no RenderSettings lists this product")
            default = UsdRender.Settings.GetStageRenderSettings(stage)
            return next((x for x in own if default and x.GetPath() == default.GetPath()), own[0])
        if not prim or not prim.IsA(UsdRender.Settings):
            found = [str(p.GetPath()) for p in stage.Traverse() if p.IsA(UsdRender.Settings)]
            raise UsdInputError(f"{label}: --render-settings {path}: no RenderSettings prim there "
                                f"(the stage has: {', '.join(found) or 'none'})")
        return UsdRender.Settings(prim)
    s = UsdRender.Settings.GetStageRenderSettings(stage)
    if s:
        return s
    meta = stage.GetMetadata("renderSettingsPrimPath") if stage.HasMetadata("renderSettingsPrimPath") else ""
    if meta:
        warn(f"renderSettingsPrimPath {meta} is not a RenderSettings prim (ignored)")
    return None


def read_render_settings(stage, path, time, warn) -> RenderSpec | None:
    settings = find_settings(stage, path, warn)
    if settings is None:
        return None
    products = [UsdRender.Product(stage.GetPrimAtPath(p)) for p in settings.GetProductsRel().GetForwardedTargets()]
    products = [p for p in products if p]
    spec = RenderSpec(path=str(settings.GetPath()), product_paths=[str(p.GetPath()) for p in products])
    chosen = next((p for p in products if path and str(p.GetPath()) == path), products[0] if products else None)
    for base in [settings] + ([chosen] if chosen else []):  # the product's own opinions override the settings'
        _read_base(base, spec, time, authored_only=base is not settings)
    for product in products:
        name = product.GetProductNameAttr().Get(time)
        if name:
            spec.products.append(str(name))
        if product is not chosen:
            continue
        for v in product.GetOrderedVarsRel().GetForwardedTargets():
            var = UsdRender.Var(stage.GetPrimAtPath(v))
            if not var:
                continue
            source = str(var.GetSourceNameAttr().Get(time) or v.name)
            aov = RENDER_VAR_AOVS.get(source.lower())
            if aov is None:
                warn(f"{v}: RenderVar {source!r} has no counterpart in the tracer's AOVs (not written)")
            elif aov and aov not in spec.aovs:
                spec.aovs.append(aov)
    if spec.conform not in CONFORM:
        warn(f"{spec.path}: aspectRatioConformPolicy {spec.conform!r} is not one of UsdRender's "
             f"({', '.join(CONFORM)}): {DEFAULT_CONFORM} used")
        spec.conform = DEFAULT_CONFORM
    x0, y0, x1, y1 = spec.data_window
    if not (np.all(np.isfinite(spec.data_window)) and x0 < x1 and y0 < y1):  # beyond 0..1: overscan (UsdRender)
        warn(f"{spec.path}: dataWindowNDC {spec.data_window} is not a window (xmin < xmax, ymin < ymax) "
             "(the whole image is rendered)")
        spec.data_window = (0.0, 0.0, 1.0, 1.0)
    if not (np.isfinite(spec.pixel_aspect) and spec.pixel_aspect > 0):
        warn(f"{spec.path}: pixelAspectRatio {spec.pixel_aspect} is not positive (1 used)")
        spec.pixel_aspect = 1.0
    return spec


def _read_base(base, spec: RenderSpec, time, authored_only: bool) -> None:
    def get(attr):
        return attr.Get(time) if (attr.HasAuthoredValue() or not authored_only) else None

    res = get(base.GetResolutionAttr())
    if res is not None and res[0] > 0 and res[1] > 0:
        spec.resolution = (int(res[0]), int(res[1]))
    targets = base.GetCameraRel().GetForwardedTargets()
    if targets:
        spec.camera = str(targets[0])
    par = get(base.GetPixelAspectRatioAttr())
    if par is not None:
        spec.pixel_aspect = float(par)
    pol = get(base.GetAspectRatioConformPolicyAttr())
    if pol is not None:
        spec.conform = str(pol)
    dw = get(base.GetDataWindowNDCAttr())
    if dw is not None:
        spec.data_window = tuple(float(x) for x in dw)
    off = get(base.GetDisableDepthOfFieldAttr())
    if off is not None:
        spec.depth_of_field = not off
    blur = [get(a) for a in (base.GetDisableMotionBlurAttr(), base.GetInstantaneousShutterAttr())]
    if any(v is not None for v in blur):
        spec.motion_blur = not any(blur)


def product_names(stage, path=None) -> list[str]:
    """The productName of every RenderProduct of the RenderSettings ``path`` (or the stage's), in order; the CLI
    writes the picture to the first when ``-o`` is not given. Relative names are relative to the working
    directory, as usdrecord and the renderers' own command lines take them."""
    return [name for name, _p in products(stage, path)]


def products(stage, path=None) -> list[tuple[str, str]]:
    """(productName, product prim path) of every RenderProduct with a name, in order (see :func:`product_names`):
    the CLI renders each (its camera, size, RenderVars) when ``-o`` is not given."""
    tc = Usd.TimeCode.EarliestTime()
    spec = read_render_settings(stage, path, tc, lambda _m: None)
    if spec is None:
        return []
    out = []
    for p in spec.product_paths:
        name = UsdRender.Product(stage.GetPrimAtPath(p)).GetProductNameAttr().Get(tc)
        if name:
            out.append((str(name), p))
    return out


def crop_to_data_window(camera, width: int, height: int, window):
    """(camera, width, height) rendering only ``window`` (NDC xmin, ymin, xmax, ymax; y up) of the full image:
    the apertures shrink to the window and the offsets move to its centre; the image is the window's pixels."""
    x0, y0, x1, y1 = window
    if (x0, y0, x1, y1) == (0.0, 0.0, 1.0, 1.0):
        return camera, width, height
    h, v = camera.horizontal_aperture, camera.vertical_aperture
    w2 = max(1, int(round(width * (x1 - x0))))
    h2 = max(1, int(round(height * (y1 - y0))))
    cam = dataclasses.replace(
        camera, horizontal_aperture=h * (x1 - x0), vertical_aperture=v * (y1 - y0),
        horizontal_aperture_offset=camera.horizontal_aperture_offset + h * ((x0 + x1) / 2 - 0.5),
        vertical_aperture_offset=camera.vertical_aperture_offset + v * ((y0 + y1) / 2 - 0.5))
    return cam, w2, h2

"""Whitted: a Whitted-style ray tracer on Embree.

    from tracer import Camera, PointLight, RenderSettings, SceneBuilder, render
    image = render(scene, RenderSettings(width=640, height=480, samples=2))
    image.save("out.png")

Names are imported on first use (PEP 562): ``import tracer`` alone costs nothing, so the command line's
``--version``, ``--help`` and argument errors answer at once; numba, Embree and OpenImageIO load when the first
name that needs them is used.
"""

from __future__ import annotations

import importlib
import sys
import types

#: Public name -> the module that defines it.
_EXPORTS = {
    "SceneBuilder": "builder",
    "ORTHOGRAPHIC": "camera", "PERSPECTIVE": "camera", "Camera": "camera", "fit_apertures": "camera",
    "lens_radius": "camera",
    "Environment": "lights.environment",
    "explain_pixel": "explain",
    "Image": "film", "read_image": "film", "write_image": "film",
    "RAY_TYPES": "integrator.wavefront",
    "AreaLight": "lights.emitters", "DistantLight": "lights.emitters", "PointLight": "lights.emitters",
    "SpotLight": "lights.emitters", "LightShaping": "lights.emitters",
    "DEFAULT_MATERIAL": "shading.materials", "Materials": "shading.materials",
    "roughness_to_exponent": "shading.materials",
    "render": "render", "RenderCancelled": "integrator.tiles", "RenderTooLarge": "integrator.tiles",
    "render_tile": "integrator.tiles", "tiles_of": "integrator.tiles",
    "Instances": "scene", "Scene": "scene",
    "Session": "session",
    "AOV_NAMES": "settings", "SHADING_MODELS": "settings", "RenderSettings": "settings",
    "Texture": "shading.texture",
    "compile_kernels": "warmup",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is not None:
        value = getattr(importlib.import_module(f".{module}", __name__), name)
    else:  # a submodule used as an attribute (tracer.explain.TYPE_COLORS)
        try:
            value = importlib.import_module(f".{name}", __name__)
        except ModuleNotFoundError:
            raise AttributeError(f"module 'tracer' has no attribute {name!r}") from None
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_EXPORTS))


class _Package(types.ModuleType):
    """``tracer.render`` is both a submodule and the package's main function. Importing the submodule makes Python
    bind it on the package; the function is bound instead (as the eager ``from .render import render`` did), so
    ``tracer.render(scene, settings)`` works whatever was imported first. ``from tracer.render import ...`` and
    ``importlib.import_module("tracer.render")`` still give the module."""

    def __setattr__(self, name, value):
        if name == "render" and isinstance(value, types.ModuleType):
            value = value.render
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package

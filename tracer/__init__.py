"""Whitted: a Whitted-style ray tracer on Embree.

    from tracer import Camera, PointLight, RenderSettings, SceneBuilder, render
    image = render(scene, RenderSettings(width=640, height=480, samples=2))
    image.save("out.png")
"""

from .builder import SceneBuilder
from .camera import ORTHOGRAPHIC, PERSPECTIVE, Camera, fit_apertures
from .environment import Environment
from .explain import explain_pixel
from .film import Image, read_image, write_image
from .integrator import RAY_TYPES
from .lights import AreaLight, DistantLight, PointLight, SpotLight
from .materials import DEFAULT_MATERIAL, Materials, roughness_to_exponent
from .render import RenderCancelled, render, render_tile, tiles_of
from .scene import Instances, Scene
from .session import Session
from .settings import AOV_NAMES, SHADING_MODELS, RenderSettings
from .texture import Texture
from .warmup import compile_kernels

__all__ = [
    "AOV_NAMES", "AreaLight", "Camera", "DEFAULT_MATERIAL", "DistantLight", "Environment", "Image", "Instances", "Materials", "ORTHOGRAPHIC",
    "PERSPECTIVE", "PointLight", "RAY_TYPES", "RenderCancelled", "RenderSettings", "Scene", "SceneBuilder", "Session",
    "SHADING_MODELS", "SpotLight", "Texture", "compile_kernels", "explain_pixel", "fit_apertures", "read_image", "render",
    "render_tile", "roughness_to_exponent", "tiles_of",
    "write_image",
]

"""UsdPreviewSurface networks and DomeLight textures against Cycles, through Blender's own USD importer: each stage
(one real-file pattern, built in tests/usd_material_stages.py) is imported into Blender and rendered by Cycles at the
Whitted-equivalent settings, and read by usd_io for our render. Small images (64 px), one scene per pattern."""

from __future__ import annotations

import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # tests/: the shared stages

import numpy as np
import pytest
from pxr import Gf, UsdGeom, UsdLux

import cycles_harness as H
import usd_material_stages as S
from cycles_thresholds import usd_material_bar
from cycles_usd_import import cycles_reference_usd
from tracer import RenderSettings
from tracer import render
from usd_io import load_stage

pytestmark = pytest.mark.cycles

SIZE = 64
CYCLES_SAMPLES = 64
OURS_SAMPLES = 4  # 4×4 stratified


def _normal_map(d):
    import test_usd_materials as T

    path, _n, _l = T._normal_stage(d, "normal_map_dx", (0.35, 0.45, 0.82), (0.3, 0.55, 0.78), dx_style=True)
    _use_perspective(path)
    return path


def _use_perspective(path):
    """Swap the orthographic camera of a closed-form stage for the perspective one Blender imports."""
    from pxr import Usd

    s = Usd.Stage.Open(path)
    s.RemovePrim("/Cam")
    S.camera(s, ortho=False)
    s.Save()


def _cutout(d):
    import test_usd_materials as T

    path, _ = T._cutout_stage(d, 0.5)
    _use_perspective(path)
    return path


def _vertex_colour(d, interp="vertex"):
    import test_usd_materials as T

    path, _ = T._grid_stage(d, interp, True)
    _use_perspective(path)
    return path


def _dome(d, rot_y=0.0, up="Y"):
    """A lat-long sky of smooth, direction-unique colours, seen directly by a camera looking up and sideways."""
    import OpenImageIO as oiio

    os.makedirs(d, exist_ok=True)
    w, h = 128, 64
    lon = math.pi - (np.arange(w) + 0.5) / w * 2 * math.pi
    lat = math.pi / 2 - (np.arange(h) + 0.5) / h * math.pi
    lo, la = np.meshgrid(lon, lat)
    img = np.stack([0.5 + 0.45 * np.sin(lo), 0.5 + 0.45 * np.sin(la), 0.5 + 0.45 * np.cos(lo)], -1) * 0.8
    out = oiio.ImageOutput.create(os.path.join(d, "sky.exr"))
    out.open(os.path.join(d, "sky.exr"), oiio.ImageSpec(w, h, 3, "float"))
    out.write_image(np.ascontiguousarray(img, np.float32))
    out.close()
    s = S.new_stage(os.path.join(d, "dome.usda"), up=up)
    dome = UsdLux.DomeLight.Define(s, "/Dome")
    dome.CreateTextureFileAttr("./sky.exr")
    dome.CreateTextureFormatAttr("latlong")
    if rot_y:
        UsdGeom.Xformable(dome).AddRotateYOp().Set(rot_y)
    cam = UsdGeom.Camera.Define(s, "/Cam")
    cam.CreateFocalLengthAttr(10.0)
    cam.CreateHorizontalApertureAttr(20.0)
    cam.CreateVerticalApertureAttr(20.0)
    cam.CreateClippingRangeAttr(Gf.Vec2f(0.01, 100.0))
    upv = Gf.Vec3d(0, 1, 0) if up == "Y" else Gf.Vec3d(0, 0, 1)
    target = Gf.Vec3d(0.8, 0.5, 0.3) if up == "Y" else Gf.Vec3d(0.8, -0.3, 0.5)
    UsdGeom.Xformable(cam).AddTransformOp().Set(Gf.Matrix4d().SetLookAt(Gf.Vec3d(0, 0, 0), target, upv).GetInverse())
    return S.save(s)



SCENES = {
    # UsdTransform2d (rotation, non-uniform scale, translation) on a diffuse texture, sRGB
    "usd_texture_transform2d": lambda d: S.textured_quad_stage(d, "t2d", ortho=False, transform=(30, (2, 0.7),
                                                                                                 (0.15, -0.3))),
    # usd-wg Vehicles: UVs in primvars:map1 and no st connection
    "usd_texture_no_st_map1": lambda d: S.textured_quad_stage(d, "nost", ortho=False, st_reader=None, uv_name="map1",
                                                              uvs=((1, 0), (1, 1), (0, 1), (0, 0))),
    # emissiveColor from a texture (nothing else lights the quad)
    "usd_emissive_texture": lambda d: S.textured_quad_stage(d, "emit", ortho=False, emissive=True),
    # McUsd plant cards: opacity from the texture alpha with opacityThreshold 0.5, a red quad behind
    "usd_cutout": _cutout,
    # McUsd normal maps: DirectX-style green, undone by scale (2, −2, 2, 1) / bias (−1, 1, −1, 0)
    "usd_normal_map_dx": _normal_map,
    # Teapot 'Ceramic': UsdPrimvarReader_float3 of a vertex displayColor on diffuseColor
    "usd_vertex_colour": _vertex_colour,
    # the same reader on a uniform (per-face) displayColor
    "usd_face_colour": lambda d: _vertex_colour(d, "uniform"),
    # DomeLight lat-long texture seen directly (Y-up stage; and the dome turned about Y)
    "usd_dome_texture": lambda d: _dome(d),
    "usd_dome_texture_rotated": lambda d: _dome(d, rot_y=70.0),
}


def render_ours(path, size=SIZE, samples=OURS_SAMPLES, depth=0):
    scene, info = load_stage(path, width=size, height=size)
    img = render(scene, RenderSettings(width=size, height=size, samples=samples, max_depth=max(depth, 2), seed=0))
    return img.rgb, info


@pytest.mark.parametrize("name", list(SCENES))
def test_usd_material_matches_cycles(bpy_module, tmp_path, name):
    path = S.as_blender_writes(SCENES[name](str(tmp_path / name)))
    ref = cycles_reference_usd(path, name, SIZE, SIZE, CYCLES_SAMPLES, depth=2)
    ours, info = render_ours(path)
    bar = usd_material_bar(name)
    desc = dict(name=name)
    H.check_images(desc, ours, ref["rgb"], tmp_path, min_psnr=bar["psnr"], max_mae=bar["mae"], label=" [usd-import]")


def test_usd_material_comparison_can_fail(bpy_module, tmp_path):
    """A texture flipped upside down (st t → 1 − t) must fail the bar against Blender's import of the unflipped
    stage: the comparison sees orientation."""
    path = S.as_blender_writes(SCENES["usd_texture_transform2d"](str(tmp_path / "ok")))
    ref = cycles_reference_usd(path, "usd_texture_transform2d", SIZE, SIZE, CYCLES_SAMPLES, depth=2)
    from pxr import Usd

    s = Usd.Stage.Open(path)
    pv = UsdGeom.PrimvarsAPI(s.GetPrimAtPath("/Quad")).GetPrimvar("st")
    pv.Set([Gf.Vec2f(u, 1 - v) for u, v in pv.Get()])
    s.Save()
    ours, _ = render_ours(path)
    with pytest.raises(AssertionError, match="PSNR|MAE"):
        H.check_images(dict(name="flipped"), ours, ref["rgb"], tmp_path, min_psnr=usd_material_bar("x")["psnr"],
                       max_mae=usd_material_bar("x")["mae"])


def _equirect_lookup(image: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Cycles' equirectangular lookup (measured in Blender 5.0: image centre = +X, u = 0.5 − atan2(y, x)/2π,
    top row = +Z), bilinear with wrap in u: an independent numpy reference for the environment's frame."""
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    u = 0.5 - np.arctan2(d[..., 1], d[..., 0]) / (2 * math.pi)
    v = np.arccos(np.clip(d[..., 2], -1, 1)) / math.pi  # from the top
    h, w = image.shape[:2]
    x, y = u * w - 0.5, v * h - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    yy0, yy1 = np.clip(y0, 0, h - 1), np.clip(y0 + 1, 0, h - 1)
    xx0, xx1 = x0 % w, (x0 + 1) % w
    return ((1 - fx) * (1 - fy) * image[yy0, xx0] + fx * (1 - fy) * image[yy0, xx1]
            + (1 - fx) * fy * image[yy1, xx0] + fx * fy * image[yy1, xx1])


@pytest.mark.parametrize("name", ["usd_dome_texture", "usd_dome_texture_rotated"])
def test_dome_orientation_matches_blender_import(bpy_module, tmp_path, name):
    """usd_io/dome.py's world -> environment rotation, applied to the stage camera's rays (pxr's own frustum) and
    looked up in Cycles' equirect convention (numpy), against Cycles rendering Blender's import of the same dome:
    checks the UsdLux/OpenEXR-vs-Cycles orientation today, whatever environment the tracer has."""
    import OpenImageIO as oiio
    from pxr import Usd

    from usd_io.dome import world_to_environment
    from usd_io.geometry.xform import Transforms

    path = SCENES[name](str(tmp_path / name))
    ref = cycles_reference_usd(path, name, SIZE, SIZE, CYCLES_SAMPLES, depth=2)["rgb"]
    stage = Usd.Stage.Open(path)
    t = Usd.TimeCode.Default()
    dome = stage.GetPrimAtPath("/Dome")
    rot = world_to_environment(dome, Transforms(t).world(dome))
    sky = np.asarray(oiio.ImageBuf(os.path.join(os.path.dirname(path), "sky.exr")).get_pixels(oiio.FLOAT))[..., :3]
    frustum = UsdGeom.Camera(stage.GetPrimAtPath("/Cam")).GetCamera(t).frustum
    k = 4  # 4×4 samples per pixel
    offs = (np.arange(SIZE * k) + 0.5) / (SIZE * k) * 2 - 1
    dirs = np.array([[list(frustum.ComputePickRay(Gf.Vec2d(x, -y)).direction) for x in offs] for y in offs])
    pred = _equirect_lookup(sky, dirs @ rot.T)
    ours = pred.reshape(SIZE, k, SIZE, k, 3).mean(axis=(1, 3))
    H.check_images(dict(name=name), ours.astype(np.float32), ref, tmp_path, min_psnr=usd_material_bar(name)["psnr"],
                   max_mae=usd_material_bar(name)["mae"], label=" [dome rotation, numpy lookup]")
    wrong = _equirect_lookup(sky, dirs).reshape(SIZE, k, SIZE, k, 3).mean(axis=(1, 3))  # no rotation at all
    assert H.metrics(wrong.astype(np.float32), ref)["psnr"] < 25

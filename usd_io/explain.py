"""``whitted explain --usd``: a pixel's ray tree as USD ``BasisCurves`` beside the stage it explains.

One linear curve per ray segment under ``/WhittedRays/<type>`` (colour per ray type as ``displayColor``, width by
the ray's weight), the camera the pixel was rendered from as ``/WhittedRays/Camera``, and the original stage as a
sublayer, so ``usdview`` or Blender opens the rays inside the scene.
"""

from __future__ import annotations

import json
import os

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, Vt

from tracer import render, write_image
from tracer.camera import ORTHOGRAPHIC
from tracer.explain import RAY_KINDS, TYPE_COLORS, draw_overlay, explain_pixel, format_tree, segments

from .outputs import BadInput, Outputs, check_output, print_warnings
from .request import StageRequest, settings_from_args

#: Curve widths: a ray of weight 1 is this fraction of the scene's size wide; thinner with less weight.
WIDTH_FRACTION = 0.004


def write_ray_tree(ex, scene, path: str, stage_path: str | None = None) -> None:
    """Write ``ex`` (a :class:`tracer.explain.Explanation` of ``scene``) to the USD file ``path``."""
    stage = Usd.Stage.CreateInMemory()
    layer = stage.GetRootLayer()
    if stage_path:
        rel = os.path.relpath(os.path.abspath(stage_path), os.path.dirname(os.path.abspath(path)))
        layer.subLayerPaths.append(rel)
    root = UsdGeom.Xform.Define(stage, "/WhittedRays")
    stage.SetDefaultPrim(root.GetPrim())
    a, b, rays = segments(ex, scene)
    size = max(scene.diagonal, 1e-3)
    for kind in RAY_KINDS:
        idx = [i for i, r in enumerate(rays) if r.type == kind]
        if not idx:
            continue
        curves = UsdGeom.BasisCurves.Define(stage, f"/WhittedRays/{kind}")
        curves.CreateTypeAttr(UsdGeom.Tokens.linear)
        pts = np.stack([a[idx], b[idx]], axis=1).reshape(-1, 3)
        curves.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts.astype(np.float32)))
        curves.CreateCurveVertexCountsAttr(Vt.IntArray([2] * len(idx)))
        weight = np.array([float(np.max(rays[i].weight)) for i in idx])
        widths = size * WIDTH_FRACTION * np.clip(np.sqrt(np.maximum(weight, 0)), 0.15, 1.0)
        curves.CreateWidthsAttr(Vt.FloatArray(np.repeat(widths, 2).astype(np.float32).tolist()))
        curves.SetWidthsInterpolation(UsdGeom.Tokens.vertex)
        curves.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(*TYPE_COLORS[kind])]))
        ids = UsdGeom.PrimvarsAPI(curves).CreatePrimvar("whitted:rayId", Sdf.ValueTypeNames.IntArray,
                                                        UsdGeom.Tokens.uniform)
        ids.Set(Vt.IntArray([int(rays[i].id) for i in idx]))
    _camera(stage, scene.camera)
    layer.customLayerData = {"whitted:pixel": Vt.IntArray(list(ex.pixel)),
                             "whitted:color": Gf.Vec3f(*map(float, ex.color))}
    layer.Export(path)


def _camera(stage, cam) -> None:
    uc = UsdGeom.Camera.Define(stage, "/WhittedRays/Camera")
    uc.AddTransformOp().Set(Gf.Matrix4d(np.asarray(cam.camera_to_world, float).T.tolist()))
    ortho = cam.projection == ORTHOGRAPHIC
    scale = 10.0 if ortho else 1.0  # USD orthographic apertures are in tenths of a stage unit
    uc.CreateProjectionAttr(UsdGeom.Tokens.orthographic if ortho else UsdGeom.Tokens.perspective)
    uc.CreateFocalLengthAttr(float(cam.focal_length))
    uc.CreateHorizontalApertureAttr(float(cam.horizontal_aperture) * scale)
    uc.CreateVerticalApertureAttr(float(cam.vertical_aperture) * scale)
    uc.CreateHorizontalApertureOffsetAttr(float(cam.horizontal_aperture_offset) * scale)
    uc.CreateVerticalApertureOffsetAttr(float(cam.vertical_aperture_offset) * scale)
    far = cam.far if np.isfinite(cam.far) else 1e6
    uc.CreateClippingRangeAttr(Gf.Vec2f(max(cam.near, 1e-3), float(far)))


def cmd_explain(args) -> int:
    """``whitted explain SCENE --pixel X Y``: the tree on stdout, and the JSON / USD / PNG files asked for. Takes
    render's stage and settings flags (usd_io/request.py), so the explained colour is the pixel ``whitted render``
    writes with the same flags (before ``--exposure``, which only the ``--png`` picture gets)."""
    for out, exts in ((args.json, (".json",)), (args.usd, (".usda", ".usd", ".usdc")), (args.png, (".png",))):
        if out is not None:
            check_output(out, exts)
    settings = settings_from_args(args)  # every flag checked before the stage is read
    outputs = Outputs.of(settings, args.exposure)
    request = StageRequest.from_args(args)
    scene, info = request.read()
    settings = settings.with_(width=info.width, height=info.height)
    x, y = args.pixel
    if not (0 <= x < info.width and 0 <= y < info.height):
        raise BadInput(f"--pixel {x} {y} is outside the {info.width}x{info.height} image")
    ex = explain_pixel(scene, settings, x, y)
    print(format_tree(ex))
    if args.json:
        _atomic_text(args.json, json.dumps(ex.to_json(), indent=1))
    if args.usd:
        write_ray_tree(ex, scene, args.usd, stage_path=request.path)
    if args.png:
        image = render(scene, settings.with_(progress=False))
        outputs.expose(image)
        write_image(args.png, draw_overlay(ex, scene, image.rgba))
    print_warnings(info)
    return 0


def _atomic_text(path, text) -> None:
    tmp = f"{path}.{os.getpid()}.part"
    with open(tmp, "w") as f:
        f.write(text + "\n")
    os.replace(tmp, path)

"""The Cycles comparison harness: build a scene description in Blender, render a Whitted-equivalent Cycles reference
(cached by content hash), build the same scene for the tracer through a front end, render ours, and compare.

    desc = scenes.IMAGE_SCENES["point_shadow"]
    ref = cycles_reference(desc)                # {"rgb": (H, W, 3) linear, "seconds": ...}
    ours = render_ours(desc, "direct")          # tracer.Image
    m = metrics(ours.rgb, ref["rgb"])           # {"psnr": dB on sRGB, "mae": linear}

Front ends (how "ours" gets its tracer.Scene from the description):
- ``direct``: :func:`build_direct`, numbers straight into ``tracer.SceneBuilder`` (no Blender involved);
- ``addon``: the Blender scene built by :func:`build_bpy`, converted by ``addon.export.scene_from_depsgraph``;
- ``usd``:   the same Blender scene written by ``bpy.ops.wm.usd_export`` and read by ``usd_io.reader.load_stage``
  (Blender writes no orthographic camera and drops Transmission: :func:`patch_usd` authors those in the USD file,
  the way a USD user would).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import time
from types import SimpleNamespace

import numpy as np

import tracer

from cycles_geometry import make_mesh, triangulate

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CACHE_DIR = os.environ.get("WHITTED_CYCLES_CACHE", os.path.join(ROOT, ".cache", "cycles-refs"))
#: Bump to invalidate every cached reference (a change in how scenes are built in Blender).
HARNESS_VERSION = 3

FRONT_ENDS = ("direct", "addon", "usd")
#: Timing log of Cycles renders in this process (name, kind, seconds, cached) for the runtime report.
CYCLES_LOG: list = []


# ====================================================================== Blender side
from blender_kit.cycles import whitted_cycles_settings  # noqa: E402  (shared with the benchmarks)


def bpy():
    import bpy as _bpy

    return _bpy


def _principled(mat, p: dict) -> None:
    nodes = mat.node_tree.nodes
    bsdf = nodes.get("Principled BSDF")
    inputs = {"base_color": "Base Color", "metallic": "Metallic", "roughness": "Roughness", "ior": "IOR",
              "specular_ior_level": "Specular IOR Level", "transmission": "Transmission Weight",
              "emission_color": "Emission Color", "emission_strength": "Emission Strength"}
    for key, value in p.items():
        if key not in inputs:
            raise ValueError(f"material {mat.name}: unknown Principled input {key!r}")
        socket = bsdf.inputs[inputs[key]]
        socket.default_value = (list(value) + [1.0])[:4] if isinstance(value, (list, tuple)) else value


def build_bpy(desc: dict):
    """Build the description as a fresh Blender scene (factory settings, empty). Returns the bpy scene."""
    b = bpy()
    from mathutils import Matrix

    b.ops.wm.read_factory_settings(use_empty=True)
    sc = b.context.scene
    sc.render.resolution_x, sc.render.resolution_y = desc["width"], desc["height"]
    sc.render.resolution_percentage = 100
    mats = {}
    for name, p in desc["materials"].items():
        m = b.data.materials.new(name)
        if m.node_tree is None:
            m.use_nodes = True
        _principled(m, p)
        mats[name] = m
    for o in desc["objects"]:
        verts, faces, face_mat = make_mesh(o["mesh"]["kind"], **o["mesh"]["params"])
        me = b.data.meshes.new(o["name"])
        me.from_pydata(verts.tolist(), [], [list(map(int, f)) for f in faces])
        for mname in o["materials"]:
            me.materials.append(mats[mname])
        me.polygons.foreach_set("material_index", face_mat.astype(np.int32))
        if o["smooth"]:
            me.shade_smooth()
            # Exact analytic normals for spheres (our meshes are unit spheres in object space): both renderers then
            # interpolate the very same corner normals.
            if o["mesh"]["kind"] == "uv_sphere":
                n = verts / np.linalg.norm(verts, axis=1, keepdims=True)
                me.normals_split_custom_set_from_vertices(n.tolist())
        me.update()
        ob = b.data.objects.new(o["name"], me)
        ob.matrix_world = Matrix(o["matrix"])
        ob.pass_index = o["pass_index"]
        # Cycles offsets shadow rays of smooth meshes to hide the shadow terminator; Whitted offsets by ε only.
        ob.cycles.shadow_terminator_geometry_offset = 0.0
        ob.cycles.shadow_terminator_offset = 0.0
        sc.collection.objects.link(ob)
    for li in desc["lights"]:
        ld = b.data.lights.new(li["name"], li["type"])
        ld.energy = li["energy"]
        ld.color = li["color"]
        if li["type"] in ("POINT", "SPOT"):
            ld.shadow_soft_size = li.get("radius", 0.0)
        if li["type"] == "SPOT":
            ld.spot_size = li["spot_size"]
            ld.spot_blend = li["spot_blend"]
        if li["type"] == "SUN":
            ld.angle = li.get("angle", 0.0)
        if li["type"] == "AREA":
            ld.shape = li["shape"]
            ld.size, ld.size_y = li["size"]
        ld.exposure = li.get("exposure", 0.0)
        ld.normalize = li.get("normalize", True)  # off: as Blender's USD importer sets it
        lo = b.data.objects.new(li["name"], ld)
        lo.matrix_world = Matrix(li["matrix"])
        sc.collection.objects.link(lo)
    c = desc["camera"]
    cd = b.data.cameras.new("Camera")
    cd.type = c["type"]
    cd.lens = c["lens"]
    cd.sensor_width, cd.sensor_height, cd.sensor_fit = c["sensor_width"], c["sensor_height"], c["sensor_fit"]
    cd.shift_x, cd.shift_y = c["shift_x"], c["shift_y"]
    cd.ortho_scale = c["ortho_scale"]
    cd.clip_start, cd.clip_end = 1e-3, 1e4
    co = b.data.objects.new("Camera", cd)
    co.matrix_world = Matrix(c["matrix"])
    sc.collection.objects.link(co)
    sc.camera = co
    if c.get("dof"):  # depth of field: f-stop, focus object (by name) or distance, blades, rotation, ratio
        d = c["dof"]
        cd.dof.use_dof = True
        cd.dof.aperture_fstop = d["fstop"]
        cd.dof.focus_distance = d.get("distance", 10.0)
        if d.get("object"):
            cd.dof.focus_object = b.data.objects[d["object"]]
        cd.dof.aperture_blades = d.get("blades", 0)
        cd.dof.aperture_rotation = d.get("rotation", 0.0)
        cd.dof.aperture_ratio = d.get("ratio", 1.0)
    w = b.data.worlds.new("World")
    if w.node_tree is None:
        w.use_nodes = True
    bg = w.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = list(desc["world"]["color"]) + [1.0]
    bg.inputs["Strength"].default_value = desc["world"]["strength"]
    if desc["world"].get("texture"):  # a lat-long environment image (procedural, see environment_image)
        tex = w.node_tree.nodes.new("ShaderNodeTexEnvironment")
        tex.image = environment_image_block(desc["world"]["texture"])
        w.node_tree.links.new(tex.outputs["Color"], bg.inputs["Color"])
    sc.world = w
    whitted_cycles_settings(sc, depth=desc["depth"], samples=desc["samples"])
    sc.render.film_transparent = False  # missed rays show the world colour, as our background does
    return sc


def environment_image(name: str) -> np.ndarray:
    """The procedural lat-long test environments, (H, W, 3) linear. "landmarks": a blue sky darkening to the
    zenith over a brown ground, a red patch where u = 0.5 (+X in Blender's mapping), a green one at u = 0.25 (+Y),
    a yellow one at the zenith's row, so a mirrored, flipped or turned lookup shows."""
    if name != "landmarks":
        raise ValueError(f"unknown environment {name!r}")
    h, w = 64, 128
    rows, cols = np.mgrid[0:h, 0:w]
    t = 1 - (rows + 0.5) / h  # 1 at the top (zenith)
    img = np.where((t > 0.5)[..., None], np.stack([0.25 - 0.2 * (t - 0.5), 0.45 - 0.3 * (t - 0.5),
                                                   0.9 - 0.4 * (t - 0.5)], -1),
                   np.stack([0.25 + 0 * t, 0.15 + 0 * t, 0.08 + 0 * t], -1))
    u = (cols + 0.5) / w
    img[(np.abs(u - 0.5) < 0.06) & (np.abs(t - 0.6) < 0.1)] = (1.5, 0.1, 0.1)
    img[(np.abs(u - 0.25) < 0.06) & (np.abs(t - 0.6) < 0.1)] = (0.1, 1.2, 0.1)
    img[(t > 0.9) & (u < 0.1)] = (1.4, 1.3, 0.1)
    return img.astype(np.float32)


def environment_image_block(name: str):
    """The environment image as a Blender image (float, linear), written once to the cache directory."""
    path = os.path.join(CACHE_DIR, f"env-{name}.exr")
    if not os.path.exists(path):
        os.makedirs(CACHE_DIR, exist_ok=True)
        tracer.write_image(path, environment_image(name))
    img = bpy().data.images.load(path, check_existing=True)
    img.colorspace_settings.name = "Linear Rec.709"
    return img


def blender_version() -> str:
    return bpy().app.version_string


def content_hash(*parts) -> str:
    blob = json.dumps([HARNESS_VERSION, blender_version(), *parts], sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:24]


def _read_exr_channels(path: str) -> dict:
    import OpenImageIO as oiio

    first = oiio.ImageBuf(path)
    if first.has_error:
        raise ValueError(f"cannot read {path}: {first.geterror()}")
    out = {}
    for sub in range(max(1, first.nsubimages)):  # Blender writes one part (OIIO subimage) per pass
        buf = oiio.ImageBuf(path, sub, 0) if sub else first
        spec = buf.spec()
        px = np.asarray(buf.get_pixels(oiio.FLOAT), np.float32).reshape(spec.height, spec.width, spec.nchannels)
        out.update({name: px[..., i] for i, name in enumerate(spec.channelnames)})
    return out


def _channel(chans: dict, suffix: str) -> np.ndarray:
    hits = [k for k in chans if k.endswith(suffix)]
    if len(hits) != 1:
        raise ValueError(f"expected one channel ending in {suffix!r}, found {hits} among {sorted(chans)}")
    return chans[hits[0]]


def cached_exr(stem: str, render, log: tuple) -> tuple[str, float, bool]:
    """The one cache of Cycles references: ``CACHE_DIR/{stem}.exr`` (``stem`` ends in a content hash), made by
    ``render(tmp_path)`` when it is missing (written under a temporary name, renamed once complete). ``log`` (name,
    kind) goes to :data:`CYCLES_LOG`. Returns (path, seconds rendering, whether it was cached)."""
    os.makedirs(CACHE_DIR, exist_ok=True)
    path = os.path.join(CACHE_DIR, f"{stem}.exr")
    cached = os.path.exists(path)
    seconds = 0.0
    if not cached:
        tmp = path + f".{os.getpid()}.tmp.exr"
        t0 = time.perf_counter()
        render(tmp)
        seconds = time.perf_counter() - t0
        os.replace(tmp, path)
    CYCLES_LOG.append((*log, seconds, cached))
    return path, seconds, cached


def render_multilayer(sc, path: str) -> None:
    """F12 of ``sc`` into a 32-bit multilayer OpenEXR at ``path``."""
    sc.render.image_settings.media_type = "MULTI_LAYER_IMAGE"  # Blender 5: multilayer OpenEXR
    sc.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
    sc.render.image_settings.color_depth = "32"
    sc.render.filepath = path
    bpy().ops.render.render(write_still=True)


def cycles_render(name: str, build, source: str, params: dict) -> np.ndarray:
    """Cycles' render (H, W, 3 linear) of the Blender scene ``build()`` makes, with the Whitted settings at
    ``params``' depth and samples, cached by ``name``, the builder's ``source`` and ``params``; Blender is reset
    to an empty scene afterwards (the add-on scenes' references)."""
    from blender_kit import scene as bs

    def render(tmp):
        scene = build()
        whitted_cycles_settings(scene, depth=params["depth"], samples=params["samples"])
        bs.render_exr(scene, tmp)

    path, _, _ = cached_exr(f"{name}-{content_hash(name, source, params)}", render, (name, "beauty"))
    bpy().ops.wm.read_factory_settings(use_empty=True)
    return bs.read_exr(path)["rgba"][..., :3]


def cycles_reference(desc: dict, *, kind: str = "beauty") -> dict:
    """The Cycles render of ``desc``, from the cache or rendered now.

    kind "beauty": ``desc["samples"]`` samples, box filter 1 px: {"rgb"} linear.
    kind "ids": 1 sample through the pixel centre (filter width 0.01 px): {"rgb"}; for per-pixel first-hit
    comparisons (ids travel as emission colours: bpy 5.0 writes no IndexOB pass into the multilayer EXR headless).
    kind "denoising": the beauty's settings with the view layer's Denoising Data stored (Cycles' denoiser itself
    stays off): {"rgb", "albedo", "normal"}, the Denoising Albedo and Denoising Normal passes (camera space).
    """
    if kind not in ("beauty", "ids", "denoising"):
        raise ValueError(f"unknown reference kind {kind!r}")

    def render(tmp):
        sc = build_bpy(desc)
        if kind == "ids":
            sc.cycles.samples = 1
            sc.cycles.filter_width = 0.01
        if kind == "denoising":
            sc.view_layers[0].cycles.denoising_store_passes = True
        render_multilayer(sc, tmp)

    path, seconds, cached = cached_exr(f"{desc['name']}-{kind}-{content_hash(desc, kind)}", render,
                                       (desc["name"], kind))
    chans = _read_exr_channels(path)
    out = {"rgb": np.stack([_channel(chans, f"Combined.{c}") for c in "RGB"], axis=-1), "seconds": seconds,
           "cached": cached, "path": path}
    if kind == "denoising":
        out["albedo"] = np.stack([_channel(chans, f"Denoising Albedo.{c}") for c in "RGB"], axis=-1)
        out["normal"] = np.stack([_channel(chans, f"Denoising Normal.{c}") for c in "XYZ"], axis=-1)
    return out


# ====================================================================== tracer side
def tracer_material(p: dict) -> dict:
    """Principled BSDF inputs -> tracer material fields: the tracer carries the Principled model, so they are the
    same parameters (docs/materials-api.md); transmission is tinted by the base colour, as in Cycles."""
    base = tuple(float(x) for x in np.asarray(p.get("base_color", (0.8, 0.8, 0.8)), np.float64)[:3])
    emission = np.asarray(p.get("emission_color", (0, 0, 0)), np.float64)[:3] * float(p.get("emission_strength", 0))
    return dict(base_color=base, specular=float(p.get("specular_ior_level", 0.5)),
                roughness=float(p.get("roughness", 0.5)), metallic=float(p.get("metallic", 0.0)),
                transmission=float(p.get("transmission", 0.0)), transmission_tint=base,
                ior=float(p.get("ior", 1.5)), emission=tuple(emission))


def camera_from_description(c: dict, width: int, height: int) -> tracer.Camera:
    """The description's camera through the add-on's own conversion (addon.export.camera_from_blender, on an
    object shaped like Blender's: the clip range build_bpy gives the Blender camera)."""
    from addon.export import camera_from_blender

    data = SimpleNamespace(clip_start=1e-3, clip_end=1e4, **{k: c[k] for k in (
        "type", "lens", "sensor_width", "sensor_height", "sensor_fit", "shift_x", "shift_y", "ortho_scale")})
    return camera_from_blender(SimpleNamespace(data=data, matrix_world=c["matrix"], name="Camera"), width, height)


def light_from_description(li: dict):
    """The description's light through the add-on's own conversion (addon.export.light_from_blender, on an object
    shaped like Blender's, with build_bpy's values and Blender's defaults)."""
    from addon.export import light_from_blender

    data = SimpleNamespace(type=li["type"], energy=li["energy"], color=li["color"],
                           shadow_soft_size=li.get("radius", 0.0), spot_size=li.get("spot_size", 0.0),
                           spot_blend=li.get("spot_blend", 0.0), angle=li.get("angle", 0.0),
                           shape=li.get("shape", "SQUARE"), size=li.get("size", (1.0, 1.0))[0],
                           size_y=li.get("size", (1.0, 1.0))[1], exposure=li.get("exposure", 0.0),
                           normalize=li.get("normalize", True), use_soft_falloff=True)
    warnings: list = []
    light = light_from_blender(SimpleNamespace(data=data, matrix_world=li["matrix"], name=li["name"]), warnings)
    if light is None:
        raise ValueError(f"light {li['name']}: {warnings}")
    return light


def build_direct(desc: dict) -> tracer.Scene:
    """The description straight into a tracer.Scene: meshes and materials as numbers, the camera and lights through
    the add-on's conversions (docs/units.md) without a Blender scene."""
    b = tracer.SceneBuilder()
    mat_index = {name: b.add_material(name, **tracer_material(p)) for name, p in desc["materials"].items()}
    for o in desc["objects"]:
        verts, faces, face_mat = make_mesh(o["mesh"]["kind"], **o["mesh"]["params"])
        tris, owner = triangulate(faces)
        slots = np.asarray([mat_index[m] for m in o["materials"]])
        normals = None
        if o["smooth"] and o["mesh"]["kind"] == "uv_sphere":
            normals = verts / np.linalg.norm(verts, axis=1, keepdims=True)
        b.add_mesh(verts, tris, material=slots[face_mat[owner]], name=o["name"], transform=np.asarray(o["matrix"]),
                   normals=normals)
    for li in desc["lights"]:
        b.add_light(light_from_description(li))
    b.camera = camera_from_description(desc["camera"], desc["width"], desc["height"])
    world = np.asarray(desc["world"]["color"], np.float32) * desc["world"]["strength"]
    b.background = world
    b.ambient = world
    if desc["world"].get("texture"):
        b.environment = tracer.Environment(environment_image(desc["world"]["texture"]),
                                           strength=desc["world"]["strength"])
        b.ambient = b.environment.average()
    return b.build()


def build_addon(desc: dict) -> tracer.Scene:
    from addon.export import scene_from_depsgraph

    sc = build_bpy(desc)
    depsgraph = bpy().context.evaluated_depsgraph_get()
    scene, _warnings = scene_from_depsgraph(depsgraph, width=desc["width"], height=desc["height"])
    return scene


def patch_usd(path: str, desc: dict) -> None:
    """Author in Blender's USD what its exporter leaves out, as a USD user would: Transmission (as opacity 0 with
    the IOR kept, UsdPreviewSurface's glass), Specular IOR Level 0 (UsdPreviewSurface has no specular level: a
    Lambert-only surface is useSpecularWorkflow 1 with specularColor 0) and an orthographic camera."""
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade

    stage = Usd.Stage.Open(path)
    glassy = {n for n, p in desc["materials"].items() if p.get("transmission", 0) > 0}
    # (not for metals: with useSpecularWorkflow 1 UsdPreviewSurface ignores metallic)
    lambert = {n for n, p in desc["materials"].items() if p.get("specular_ior_level", 0.5) == 0
               and p.get("metallic", 0) == 0 and p.get("transmission", 0) == 0}
    for prim in stage.Traverse():
        if prim.IsA(UsdShade.Shader):
            sh = UsdShade.Shader(prim)
            mat_name = prim.GetParent().GetName()
            if sh.GetIdAttr().Get() != "UsdPreviewSurface":
                continue
            if mat_name in glassy:
                sh.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(0.0)
            if mat_name in lambert:
                sh.CreateInput("useSpecularWorkflow", Sdf.ValueTypeNames.Int).Set(1)
                sh.CreateInput("specularColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0.0, 0.0, 0.0))
    c = desc["camera"]
    if c["type"] == "ORTHO":
        cams = [p for p in stage.Traverse() if p.GetName() == "Camera"]
        if cams:
            cam_prim = cams[0]
            target = cam_prim if cam_prim.IsA(UsdGeom.Camera) else cam_prim.GetChildren()[0] if \
                cam_prim.GetChildren() else None
            path_c = (cam_prim.GetPath().AppendChild("Camera") if target is None or not target.IsA(UsdGeom.Camera)
                      else target.GetPath())
            cam = UsdGeom.Camera.Define(stage, path_c)
            cam.CreateProjectionAttr("orthographic")
            aspect = desc["width"] / desc["height"]
            e = c["ortho_scale"]
            w, h = (e, e / aspect) if desc["width"] >= desc["height"] else (e * aspect, e)
            cam.CreateHorizontalApertureAttr(w * 10)
            cam.CreateVerticalApertureAttr(h * 10)
            cam.CreateHorizontalApertureOffsetAttr(c["shift_x"] * e * 10)
            cam.CreateVerticalApertureOffsetAttr(c["shift_y"] * e * 10)
            cam.CreateClippingRangeAttr(Gf.Vec2f(1e-3, 1e4))
    stage.Save()


def build_usd(desc: dict, workdir: str) -> tracer.Scene:
    from usd_io.reader import load_stage

    build_bpy(desc)
    path = os.path.join(workdir, f"{desc['name']}.usda")
    bpy().ops.wm.usd_export(filepath=path)
    patch_usd(path, desc)
    scene, _info = load_stage(path, width=desc["width"], height=desc["height"])
    return scene


def build_ours(desc: dict, front_end: str, workdir: str | None = None) -> tracer.Scene:
    if front_end == "direct":
        return build_direct(desc)
    if front_end == "addon":
        return build_addon(desc)
    if front_end == "usd":
        if workdir is not None:
            return build_usd(desc, workdir)
        import tempfile

        with tempfile.TemporaryDirectory(prefix="whitted-usd-") as tmp:  # the scene is in memory once loaded
            return build_usd(desc, tmp)
    raise ValueError(f"unknown front end {front_end!r}; choose from {FRONT_ENDS}")


def ours_settings(desc: dict, **changes) -> tracer.RenderSettings:
    s = tracer.RenderSettings(width=desc["width"], height=desc["height"], samples=desc["ours_samples"],
                              max_depth=desc["depth"], sky_samples=desc["sky_samples"], seed=0)
    return s.with_(**changes)


def render_ours(desc: dict, front_end: str = "direct", workdir: str | None = None, **changes) -> tracer.Image:
    return tracer.render(build_ours(desc, front_end, workdir), ours_settings(desc, **changes))


# ====================================================================== metrics
def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    x = np.clip(np.asarray(x, np.float64), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def psnr_srgb(a: np.ndarray, b: np.ndarray) -> float:
    """PSNR in dB of two linear images after the sRGB transfer function (clipped to [0, 1], peak 1)."""
    mse = float(np.mean((linear_to_srgb(a) - linear_to_srgb(b)) ** 2))
    return float("inf") if mse == 0 else 10 * math.log10(1.0 / mse)


def mae_linear(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.mean(np.abs(np.asarray(a, np.float64) - np.asarray(b, np.float64))))


def metrics(ours_rgb: np.ndarray, ref_rgb: np.ndarray) -> dict:
    if ours_rgb.shape != ref_rgb.shape:
        raise ValueError(f"image shapes differ: ours {ours_rgb.shape}, Cycles {ref_rgb.shape}")
    return {"psnr": psnr_srgb(ours_rgb, ref_rgb), "mae": mae_linear(ours_rgb, ref_rgb),
            "mean_ours": float(np.mean(ours_rgb)), "mean_cycles": float(np.mean(ref_rgb))}


def pass_index_map(scene: tracer.Scene, desc: dict, object_ids: np.ndarray) -> np.ndarray:
    """Our object-id AOV translated to Blender pass indices (by object name; -1 / unknown -> 0 = background)."""
    by_name = {o["name"]: o["pass_index"] for o in desc["objects"]}
    lut = np.zeros(len(scene.object_names) + 1, np.int32)
    for i, name in enumerate(scene.object_names):
        lut[i] = by_name.get(name, by_name.get(name.split("/")[-1], 0))
    ids = np.asarray(object_ids)
    return np.where(ids >= 0, lut[np.clip(ids, 0, len(lut) - 1)], 0)


def id_agreement(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.mean(np.asarray(a) == np.asarray(b)))


# ====================================================================== failure artefacts
def save_comparison(directory: str, name: str, ours_rgb: np.ndarray, ref_rgb: np.ndarray, gain: float = 4.0) -> list:
    """ours, Cycles and |difference|·gain as sRGB PNGs in ``directory``; returns the paths."""
    os.makedirs(directory, exist_ok=True)
    paths = []
    diff = np.abs(ours_rgb.astype(np.float64) - ref_rgb) * gain
    for tag, img in (("ours", ours_rgb), ("cycles", ref_rgb), ("diff", diff)):
        p = os.path.join(str(directory), f"{name}-{tag}.png")
        tracer.write_image(p, np.asarray(img, np.float32))
        paths.append(p)
    return paths


def check_images(desc: dict, ours_rgb: np.ndarray, ref_rgb: np.ndarray, tmp_path, *, min_psnr: float,
                 max_mae: float, label: str = "") -> dict:
    """Assert PSNR and MAE; on failure write ours/Cycles/difference images to ``tmp_path`` and name them."""
    m = metrics(ours_rgb, ref_rgb)
    ok = m["psnr"] >= min_psnr and m["mae"] <= max_mae
    print(f"[cycles] {desc['name']}{label}: PSNR {m['psnr']:.2f} dB (≥ {min_psnr}), MAE {m['mae']:.5f} "
          f"(≤ {max_mae}), mean ours {m['mean_ours']:.4f} Cycles {m['mean_cycles']:.4f}")
    if not ok:
        paths = save_comparison(str(tmp_path), desc["name"] + label.replace(" ", "_"), ours_rgb, ref_rgb)
        raise AssertionError(f"{desc['name']}{label}: PSNR {m['psnr']:.2f} dB (need ≥ {min_psnr}), "
                             f"MAE {m['mae']:.5f} (need ≤ {max_mae}); images: {', '.join(paths)}")
    return m

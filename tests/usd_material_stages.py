"""Small USD stages for the material tests, each reproducing one pattern of real files (usd-wg assets), written
into a directory with their textures. Shared by tests/test_usd_materials.py (closed-form checks) and
tests/cycles/test_cycles_usd_materials.py (Cycles through Blender's USD importer).

The common set-up: a 2×2 quad in z = 0 (st (0,0) at its lower-left corner (−1,−1), (1,1) at (1,1)), an
orthographic camera above it that sees exactly [−1, 1]² (or a perspective one for Blender, which imports no
orthographic camera), and a DistantLight straight down of intensity π and angle 0: irradiance E = I = π (the spec's
delta sun, docs/usd.md), so a Lambertian surface of albedo a has radiance a·E/π = a. (Blender's importer reads every
DistantLight as a sun of strength 4·I: the Cycles tests mark their stages as Blender-written, which our reader
then reads the same way, and quarter the intensity: as_blender_writes.) Materials use the specular workflow with
specularColor 0, a Lambert surface in both renderers (Blender's importer sets Specular Tint = specularColor).
"""

from __future__ import annotations

import math
import os

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade

#: 4 × 4 blocks of distinct colours, 16 × 16 texels each (row 0 = top of the image as seen on a monitor).
BLOCK = 16
BLOCKS = np.array([[[0.9, 0.1, 0.1], [0.1, 0.9, 0.1], [0.1, 0.1, 0.9], [0.9, 0.9, 0.1]],
                   [[0.9, 0.1, 0.9], [0.1, 0.9, 0.9], [0.5, 0.5, 0.5], [0.9, 0.5, 0.1]],
                   [[0.1, 0.5, 0.9], [0.5, 0.9, 0.1], [0.9, 0.1, 0.5], [0.3, 0.1, 0.1]],
                   [[0.1, 0.3, 0.1], [0.1, 0.1, 0.3], [0.9, 0.9, 0.9], [0.2, 0.2, 0.2]]])


def write_png(path: str, rgba8: np.ndarray) -> str:
    import OpenImageIO as oiio

    a = np.ascontiguousarray(rgba8, np.uint8)
    if a.ndim == 2:
        a = a[..., None]
    out = oiio.ImageOutput.create(path)
    out.open(path, oiio.ImageSpec(a.shape[1], a.shape[0], a.shape[2], "uint8"))
    out.write_image(a)
    out.close()
    return path


def block_texture(path: str, alpha_left: bool = False) -> np.ndarray:
    """Write the 64×64 block texture as an 8-bit PNG holding the *sRGB encoding* of BLOCKS; returns the linear
    block colours (4, 4, 3) that an sRGB read gives back (quantised as the file holds them)."""
    from tracer.colorspace import linear_to_srgb, srgb_to_linear

    enc = np.round(linear_to_srgb(BLOCKS) * 255).astype(np.uint8)
    img = np.repeat(np.repeat(enc, BLOCK, axis=0), BLOCK, axis=1)
    alpha = np.full(img.shape[:2] + (1,), 255, np.uint8)
    if alpha_left:
        alpha[:, : img.shape[1] // 2] = 0
    write_png(path, np.concatenate([img, alpha], axis=2))
    return srgb_to_linear(enc / 255.0).astype(np.float64)


def new_stage(path: str, up: str = "Z") -> Usd.Stage:
    s = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(s, up)
    UsdGeom.SetStageMetersPerUnit(s, 1.0)
    return s


def camera(stage, ortho: bool = True, height: float = 4.0):
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    if ortho:
        cam.CreateProjectionAttr("orthographic")
        cam.CreateHorizontalApertureAttr(20.0)  # tenths of a unit: 2 × 2 units
        cam.CreateVerticalApertureAttr(20.0)
    else:  # field of view 2·atan(1/height): the quad fills the frame
        cam.CreateProjectionAttr("perspective")
        cam.CreateFocalLengthAttr(float(height) * 10.0)
        cam.CreateHorizontalApertureAttr(20.0)
        cam.CreateVerticalApertureAttr(20.0)
    cam.CreateClippingRangeAttr(Gf.Vec2f(0.01, 100.0))
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, height))
    return cam


def sun(stage, intensity: float = math.pi, tilt_deg=(0.0, 0.0)):
    """A DistantLight along −Z, turned by tilt_deg = (about X, about Y) degrees."""
    d = UsdLux.DistantLight.Define(stage, "/Sun")
    d.CreateIntensityAttr(float(intensity))
    d.CreateAngleAttr(0.0)
    if any(tilt_deg):
        d.AddRotateXYZOp().Set(Gf.Vec3f(float(tilt_deg[0]), float(tilt_deg[1]), 0.0))
    return d


def quad(stage, path="/Quad", z=0.0, uv_name="st", uvs=((0, 0), (1, 0), (1, 1), (0, 1)), size=1.0):
    m = UsdGeom.Mesh.Define(stage, path)
    m.CreatePointsAttr([(-size, -size, z), (size, -size, z), (size, size, z), (-size, size, z)])
    m.CreateFaceVertexCountsAttr([4])
    m.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    m.CreateSubdivisionSchemeAttr("none")
    m.CreateNormalsAttr([(0, 0, 1)] * 4)
    m.SetNormalsInterpolation("vertex")
    if uv_name:
        pv = UsdGeom.PrimvarsAPI(m).CreatePrimvar(uv_name, Sdf.ValueTypeNames.TexCoord2fArray,
                                                   UsdGeom.Tokens.faceVarying)
        pv.Set([Gf.Vec2f(*u) for u in uvs])
    return m


def preview(stage, path="/Looks/M", lambert=True, **values):
    """A Material with a UsdPreviewSurface; ``values`` are constant inputs (name -> (type, value))."""
    mat = UsdShade.Material.Define(stage, path)
    ps = UsdShade.Shader.Define(stage, f"{path}/Surface")
    ps.CreateIdAttr("UsdPreviewSurface")
    if lambert:
        ps.CreateInput("useSpecularWorkflow", Sdf.ValueTypeNames.Int).Set(1)
        ps.CreateInput("specularColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0, 0, 0))
    for name, (tname, v) in values.items():
        ps.CreateInput(name, tname).Set(v)
    mat.CreateSurfaceOutput().ConnectToSource(ps.ConnectableAPI(), "surface")
    return mat, ps


def uv_texture(stage, mat_path, name, file, st_reader=None, **inputs):
    """A UsdUVTexture; ``st_reader`` a primvar name for a UsdPrimvarReader_float2 (None: st unconnected)."""
    tx = UsdShade.Shader.Define(stage, f"{mat_path}/{name}")
    tx.CreateIdAttr("UsdUVTexture")
    tx.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(file)
    types = dict(scale=Sdf.ValueTypeNames.Float4, bias=Sdf.ValueTypeNames.Float4,
                 fallback=Sdf.ValueTypeNames.Float4)
    for k, v in inputs.items():
        tx.CreateInput(k, types.get(k, Sdf.ValueTypeNames.Token)).Set(v)
    if st_reader is not None:
        rd = UsdShade.Shader.Define(stage, f"{mat_path}/{name}Reader")
        rd.CreateIdAttr("UsdPrimvarReader_float2")
        rd.CreateInput("varname", Sdf.ValueTypeNames.String).Set(st_reader)
        rd.CreateOutput("result", Sdf.ValueTypeNames.Float2)
        tx.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(rd.ConnectableAPI(), "result")
    return tx


def transform2d(stage, tex, mat_path, rotation, scale, translation):
    """Insert a UsdTransform2d between a texture's st reader and the texture."""
    st = tex.GetInput("st")
    (src, out_name, _t), = [(s.source, s.sourceName, s.sourceType) for s in st.GetConnectedSources()[0]]
    t2 = UsdShade.Shader.Define(stage, f"{mat_path}/Transform")
    t2.CreateIdAttr("UsdTransform2d")
    t2.CreateInput("in", Sdf.ValueTypeNames.Float2).ConnectToSource(src, out_name)
    t2.CreateInput("rotation", Sdf.ValueTypeNames.Float).Set(float(rotation))
    t2.CreateInput("scale", Sdf.ValueTypeNames.Float2).Set(Gf.Vec2f(*scale))
    t2.CreateInput("translation", Sdf.ValueTypeNames.Float2).Set(Gf.Vec2f(*translation))
    st.ConnectToSource(t2.ConnectableAPI(), "result")
    return t2


def connect(ps, name, tname, tex, output):
    ps.CreateInput(name, tname).ConnectToSource(tex.ConnectableAPI(), output)


def bind(prim_schema, mat):
    UsdShade.MaterialBindingAPI.Apply(prim_schema.GetPrim()).Bind(mat)


# ---------------------------------------------------------------- closed forms
def pixel_points(n: int) -> np.ndarray:
    """World (x, y) of the pixel centres of an n × n orthographic view of [−1, 1]² (row 0 at the top)."""
    c = -1 + (np.arange(n) + 0.5) * 2 / n
    x, y = np.meshgrid(c, -c)
    return np.stack([x, y], axis=-1)


def block_lookup(st: np.ndarray, blocks: np.ndarray, wrap: str = "repeat", margin: float = 0.0):
    """The block colour at texture coordinates st (..., 2) under a wrap mode, and a mask of the points that are at
    least ``margin`` (in st units) inside a block (where bilinear filtering cannot reach a neighbour)."""
    s, t = st[..., 0], st[..., 1]
    nb = blocks.shape[0]

    def wrap1(x):
        if wrap == "repeat":
            return x - np.floor(x)
        if wrap == "mirror":
            f = np.mod(x, 2.0)
            return np.where(f > 1, 2 - f, f)
        return x

    ws, wt = wrap1(s), wrap1(t)
    inside = (ws >= 0) & (ws <= 1) & (wt >= 0) & (wt <= 1)
    cs, ct = np.clip(ws, 0, 1 - 1e-9), np.clip(wt, 0, 1 - 1e-9)
    col = np.floor(cs * nb).astype(int)
    row = np.floor((1 - ct) * nb).astype(int).clip(0, nb - 1)  # st t up, image rows down
    colour = blocks[row, col]
    if wrap == "black":
        colour = np.where(inside[..., None], colour, 0.0)
    fs, ft = cs * nb - col, (1 - ct) * nb - row
    ok = (np.minimum(fs, 1 - fs) >= margin * nb) & (np.minimum(ft, 1 - ft) >= margin * nb)
    if wrap in ("clamp", "black"):
        # outside the unit square a clamped lookup is the edge texel: safe when away from the block edges along
        # the clamped axis only; black is safe away from the square's border
        ok_s = np.where((s < 0) | (s > 1), np.abs(np.clip(s, 0, 1) - s) >= margin, np.minimum(fs, 1 - fs) >= margin * nb)
        ok_t = np.where((t < 0) | (t > 1), np.abs(np.clip(t, 0, 1) - t) >= margin,
                        np.minimum(ft, 1 - ft) >= margin * nb)
        ok = ok_s & ok_t
    return colour, ok


def as_blender_writes(path: str) -> str:
    """Mark a stage as written by Blender (root layer doc "Blender v…") and quarter its /Sun's intensity: Blender's
    importer reads any DistantLight as sun strength 4·I, and our reader reads Blender-written stages that way too,
    so both renderers then see E = π, as the closed-form stages do."""
    s = Usd.Stage.Open(path)
    s.GetRootLayer().documentation = "Blender v5.0.1 (test stage, Blender's sun units)"
    sun_prim = s.GetPrimAtPath("/Sun")
    if sun_prim:
        attr = UsdLux.DistantLight(sun_prim).GetIntensityAttr()
        attr.Set(float(attr.Get()) / 4.0)
    s.GetRootLayer().Save()
    return path


def save(stage) -> str:
    stage.GetRootLayer().Save()
    return stage.GetRootLayer().realPath


def textured_quad_stage(d: str, name: str, *, ortho=True, st_reader="st", uv_name="st",
                        uvs=((0, 0), (1, 0), (1, 1), (0, 1)), transform=None, wrap=None, emissive=False,
                        alpha_left=False) -> str:
    """The block texture on a lit quad (diffuseColor) or as its emission (diffuse black, no light)."""
    os.makedirs(d, exist_ok=True)
    block_texture(os.path.join(d, "blocks.png"), alpha_left=alpha_left)
    s = new_stage(os.path.join(d, f"{name}.usda"))
    camera(s, ortho=ortho)
    q = quad(s, uv_name=uv_name, uvs=uvs)
    mat, ps = preview(s)
    kw = dict(sourceColorSpace="sRGB")
    if wrap:
        kw.update(wrapS=wrap, wrapT=wrap)
    tex = uv_texture(s, "/Looks/M", "Tex", "./blocks.png", st_reader=st_reader, **kw)
    if transform is not None:
        transform2d(s, tex, "/Looks/M", *transform)
    if emissive:
        ps.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0, 0, 0))
        connect(ps, "emissiveColor", Sdf.ValueTypeNames.Color3f, tex, "rgb")
    else:
        connect(ps, "diffuseColor", Sdf.ValueTypeNames.Color3f, tex, "rgb")
        sun(s)
    bind(q, mat)
    return save(s)

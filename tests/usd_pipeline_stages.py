"""Stages for tests/test_usd_pipeline.py (issue #21): the patterns third-party pipelines write, built with pxr."""

from __future__ import annotations

import struct

from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, UsdSkel


def new_stage(up="Z"):
    s = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(s, up)
    return s


def add_camera(stage, path="/Cam", eye=(0, 0, 10), h=3.6, v=2.4, focal=5.0, rotate_x=0.0, rotate_z=0.0):
    """A perspective camera at ``eye`` looking down −z, turned ``rotate_x`` degrees about x (90: looking +y), then
    ``rotate_z`` about z."""
    cam = UsdGeom.Camera.Define(stage, path)
    cam.CreateFocalLengthAttr(focal)
    cam.CreateHorizontalApertureAttr(h)
    cam.CreateVerticalApertureAttr(v)
    cam.AddTranslateOp().Set(Gf.Vec3d(*eye))
    if rotate_z:
        cam.AddRotateZOp().Set(rotate_z)
    if rotate_x:
        cam.AddRotateXOp().Set(rotate_x)
    return cam


def quad(stage, path, z=0.0, half=1.0):
    m = UsdGeom.Mesh.Define(stage, path)
    m.CreatePointsAttr([(-half, -half, z), (half, -half, z), (half, half, z), (-half, half, z)])
    m.CreateFaceVertexCountsAttr([4])
    m.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    m.CreateSubdivisionSchemeAttr("none")
    return m


def float_meters_per_unit_usdc(path, value=0.5):
    """A .usdc whose ``metersPerUnit`` is a ``float`` (as tinyusdz writes it): pxr writes a double that a float
    represents exactly inline in the value rep; the rep's type byte is turned from Double (9) to Float (8)."""
    s = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(s, "Z")
    UsdGeom.SetStageMetersPerUnit(s, value)
    UsdGeom.Sphere.Define(s, "/Ball")
    add_camera(s)
    s.GetRootLayer().Save()
    bits = struct.unpack("<I", struct.pack("<f", value))[0]
    as_double = struct.pack("<Q", (1 << 62) | (9 << 48) | bits)
    as_float = struct.pack("<Q", (1 << 62) | (8 << 48) | bits)
    data = open(path, "rb").read()
    assert data.count(as_double) == 1
    open(path, "wb").write(data.replace(as_double, as_float))
    return path


def blend_shape_stage(with_joints=False, inbetween=False):
    """A unit quad in a SkelRoot with one blend shape ``up`` lifting points 2 and 3 by (0, 0, 1); the animation's
    weight is 0 at time 0 and 1 at time 1. No joint influences unless ``with_joints``. ``inbetween``: an
    inbetween at weight 0.5 lifting them by 0.8 (so weight 0.5 lifts by 0.8, not 0.5)."""
    s = new_stage()
    add_camera(s, eye=(0, -8, 0.5), rotate_x=90.0)  # looking +y at the quad's edge
    root = UsdSkel.Root.Define(s, "/Root")
    skel = UsdSkel.Skeleton.Define(s, "/Root/Skel")
    anim = UsdSkel.Animation.Define(s, "/Root/Skel/Anim")
    if with_joints:
        skel.CreateJointsAttr(["j"])
        skel.CreateBindTransformsAttr([Gf.Matrix4d(1)])
        skel.CreateRestTransformsAttr([Gf.Matrix4d(1)])
        anim.CreateJointsAttr(["j"])
        anim.CreateTranslationsAttr().Set([Gf.Vec3f(0, 3, 0)])
        anim.CreateRotationsAttr().Set([Gf.Quatf(1, 0, 0, 0)])
        anim.CreateScalesAttr().Set([Gf.Vec3h(1, 1, 1)])
    else:
        skel.CreateJointsAttr([])
    anim.CreateBlendShapesAttr(["up"])
    w = anim.CreateBlendShapeWeightsAttr()
    w.Set([0.0], 0.0)
    w.Set([1.0], 1.0)
    UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets([anim.GetPath()])
    mesh = quad(s, "/Root/M")
    binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skel.GetPath()])
    binding.CreateBlendShapesAttr(["up"])
    shape = UsdSkel.BlendShape.Define(s, "/Root/M/up")
    shape.CreateOffsetsAttr([Gf.Vec3f(0, 0, 1), Gf.Vec3f(0, 0, 1)])
    shape.CreatePointIndicesAttr([2, 3])
    if inbetween:
        ib = shape.CreateInbetween("half")
        ib.SetWeight(0.5)
        ib.SetOffsets([Gf.Vec3f(0, 0, 0.8), Gf.Vec3f(0, 0, 0.8)])
    binding.CreateBlendShapeTargetsRel().SetTargets([shape.GetPath()])
    if with_joints:
        binding.CreateJointIndicesPrimvar(constant=True, elementSize=1).Set([0])
        binding.CreateJointWeightsPrimvar(constant=True, elementSize=1).Set([1.0])
        binding.CreateGeomBindTransformAttr(Gf.Matrix4d(1))
    assert root
    return s


def preview_material(stage, path, **inputs):
    """A Material with a UsdPreviewSurface whose inputs are ``inputs`` (floats or 3-tuples)."""
    mat = UsdShade.Material.Define(stage, path)
    sh = UsdShade.Shader.Define(stage, f"{path}/Surface")
    sh.CreateIdAttr("UsdPreviewSurface")
    for name, v in inputs.items():
        typ = Sdf.ValueTypeNames.Color3f if isinstance(v, tuple) else Sdf.ValueTypeNames.Float
        sh.CreateInput(name, typ).Set(Gf.Vec3f(*v) if isinstance(v, tuple) else v)
    mat.CreateSurfaceOutput().ConnectToSource(sh.ConnectableAPI(), "surface")
    return mat


def bind(prim, mat):
    UsdShade.MaterialBindingAPI.Apply(prim.GetPrim() if hasattr(prim, "GetPrim") else prim).Bind(mat)


# ---------------------------------------------------------------- instancing patterns
def point_instancer(stage, path, protos, positions, indices=None, **attrs):
    """A PointInstancer at ``path`` over prototype paths ``protos`` at ``positions`` (prototype 0 unless
    ``indices``); ``attrs``: ids, invisibleIds, ..."""
    pi = UsdGeom.PointInstancer.Define(stage, path)
    pi.CreatePrototypesRel().SetTargets([Sdf.Path(p) for p in protos])
    pi.CreateProtoIndicesAttr([0] * len(positions) if indices is None else indices)
    pi.CreatePositionsAttr([Gf.Vec3f(*p) for p in positions])
    for k, v in attrs.items():
        getattr(pi, f"Create{k}Attr")(v)
    return pi


def cube(stage, path, size=1.0):
    c = UsdGeom.Cube.Define(stage, path)
    c.CreateSizeAttr(size)
    return c


def instancer_under_over():
    """Prototypes under an ``over`` (not drawn on their own): two unit cubes at x = 0 and 3."""
    s = new_stage()
    point_instancer(s, "/PI", ["/Protos/Box"], [(0, 0, 0), (3, 0, 0)])
    cube(s, "/Protos/Box")
    s.GetPrimAtPath("/Protos").SetSpecifier(Sdf.SpecifierOver)  # Define wrote a def for the parent
    return s


def nested_instancers():
    """An instancer whose prototype is an instancer (3 cubes along x, 2 apart), itself placed at y = 0 and 5 and
    the outer moved to z = 1: 6 cubes."""
    s = new_stage()
    outer = point_instancer(s, "/Outer", ["/Outer/Protos/Inner"], [(0, 0, 0), (0, 5, 0)])
    UsdGeom.Xformable(outer).AddTranslateOp().Set(Gf.Vec3d(0, 0, 1))
    UsdGeom.Scope.Define(s, "/Outer/Protos")
    point_instancer(s, "/Outer/Protos/Inner", ["/Outer/Protos/Inner/P/Box"], [(0, 0, 0), (2, 0, 0), (4, 0, 0)])
    UsdGeom.Scope.Define(s, "/Outer/Protos/Inner/P")
    cube(s, "/Outer/Protos/Inner/P/Box")
    return s


def native_instance_of_instancer():
    """Two native instances (at y = 0 and 4) of an asset that holds an instancer of two cubes (x = 0 and 2)."""
    s = new_stage()
    asset = s.CreateClassPrim("/Asset")
    point_instancer(s, "/Asset/PI", ["/Asset/PI/P/Box"], [(0, 0, 0), (2, 0, 0)])
    UsdGeom.Scope.Define(s, "/Asset/PI/P")
    cube(s, "/Asset/PI/P/Box")
    for name, y in (("A", 0), ("B", 4)):
        x = UsdGeom.Xform.Define(s, f"/{name}")
        x.GetPrim().GetInherits().AddInherit(asset.GetPath())
        x.GetPrim().SetInstanceable(True)
        x.AddTranslateOp().Set(Gf.Vec3d(0, y, 0))
    return s


def deep_mixed_instancing():
    """Every pattern at once, three levels deep, animated:
    native instances /I0 (y = 0) and /I1 (y = 10) of /Asset, which holds PointInstancer /Asset/Outer (positions
    time-sampled: x = 0 and 20 at time 0, x = 0 and 30 at time 1) whose prototype is an instanceable prim
    /Asset/Outer/Protos/Row (under an ``over``) referencing /RowAsset: a PointInstancer of cubes at x = 0, 2, 4
    with ids [7, 8, 9] and invisibleIds [8]. Cubes: 2 natives × 2 outer × 2 visible = 8."""
    s = new_stage()
    row = s.CreateClassPrim("/RowAsset")
    point_instancer(s, "/RowAsset/Inner", ["/RowAsset/Inner/P/Box"], [(0, 0, 0), (2, 0, 0), (4, 0, 0)],
                    Ids=[7, 8, 9], InvisibleIds=[8])
    UsdGeom.Scope.Define(s, "/RowAsset/Inner/P")
    cube(s, "/RowAsset/Inner/P/Box")
    asset = s.CreateClassPrim("/Asset")
    outer = point_instancer(s, "/Asset/Outer", ["/Asset/Outer/Protos/Row"], [(0, 0, 0), (20, 0, 0)])
    outer.GetPositionsAttr().Set([Gf.Vec3f(0, 0, 0), Gf.Vec3f(20, 0, 0)], 0.0)
    outer.GetPositionsAttr().Set([Gf.Vec3f(0, 0, 0), Gf.Vec3f(30, 0, 0)], 1.0)
    r = UsdGeom.Xform.Define(s, "/Asset/Outer/Protos/Row").GetPrim()
    r.GetInherits().AddInherit(row.GetPath())
    r.SetInstanceable(True)
    s.GetPrimAtPath("/Asset/Outer/Protos").SetSpecifier(Sdf.SpecifierOver)
    for name, y in (("I0", 0), ("I1", 10)):
        x = UsdGeom.Xform.Define(s, f"/{name}")
        x.GetPrim().GetInherits().AddInherit(asset.GetPath())
        x.GetPrim().SetInstanceable(True)
        x.AddTranslateOp().Set(Gf.Vec3d(0, y, 0))
    return s


# ---------------------------------------------------------------- NURBS and tetrahedra
def nurbs_patch_stage(weights=None, trim_hole=False):
    """A bilinear-in-v, quadratic-in-u NurbsPatch. With ``weights`` (1, √½, 1) on its u rows the u direction is an
    exact quarter circle of radius 2 about the z axis (the classic rational quadratic arc), swept from z = 0 to 3:
    every point of the surface is at distance 2 from the axis. ``trim_hole``: an outer loop around the whole
    parameter square and an inner square loop (0.25..0.75)² (a hole) as linear trim curves."""
    s = new_stage()
    patch = UsdGeom.NurbsPatch.Define(s, "/Patch")
    arc = [(2, 0), (2, 2), (0, 2)]
    pts = [(x, y, z) for z in (0.0, 3.0) for (x, y) in arc]  # u fastest
    patch.CreatePointsAttr(pts)
    patch.CreateUVertexCountAttr(3)
    patch.CreateVVertexCountAttr(2)
    patch.CreateUOrderAttr(3)
    patch.CreateVOrderAttr(2)
    patch.CreateUKnotsAttr([0, 0, 0, 1, 1, 1])
    patch.CreateVKnotsAttr([0, 0, 1, 1])
    patch.CreateURangeAttr(Gf.Vec2d(0, 1))
    patch.CreateVRangeAttr(Gf.Vec2d(0, 1))
    if weights is not None:
        patch.CreatePointWeightsAttr(list(weights) * 2)
    if trim_hole:
        outer = [(0, 0), (1, 0), (1, 1), (0, 1), (0, 0)]
        inner = [(0.25, 0.25), (0.75, 0.25), (0.75, 0.75), (0.25, 0.75), (0.25, 0.25)]
        patch.CreateTrimCurveCountsAttr([1, 1])
        patch.CreateTrimCurveOrdersAttr([2, 2])
        patch.CreateTrimCurveVertexCountsAttr([5, 5])
        knots = [0, 0, 1, 2, 3, 4, 4]
        patch.CreateTrimCurveKnotsAttr(knots + knots)
        patch.CreateTrimCurveRangesAttr([Gf.Vec2d(0, 4), Gf.Vec2d(0, 4)])
        patch.CreateTrimCurvePointsAttr([Gf.Vec3d(u, v, 1) for u, v in outer + inner])
    return s


def nurbs_curve_stage(width=0.4):
    """One cubic NurbsCurve whose control polygon is a straight line along x from 0 to 6, width ``width``."""
    s = new_stage()
    nc = UsdGeom.NurbsCurves.Define(s, "/Curve")
    nc.CreatePointsAttr([(0, 0, 0), (2, 0, 0), (4, 0, 0), (6, 0, 0)])
    nc.CreateCurveVertexCountsAttr([4])
    nc.CreateOrderAttr([4])
    nc.CreateKnotsAttr([0, 0, 0, 0, 1, 1, 1, 1])
    nc.CreateRangesAttr([Gf.Vec2d(0, 1)])
    nc.CreateWidthsAttr([width])
    nc.SetWidthsInterpolation("constant")
    return s


def tet_stage():
    """Two tetrahedra sharing a face: the surface is the 6 outer faces (the shared one is inside)."""
    s = new_stage()
    tm = UsdGeom.TetMesh.Define(s, "/Tets")
    tm.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1)])
    tm.CreateTetVertexIndicesAttr([Gf.Vec4i(0, 1, 2, 3), Gf.Vec4i(1, 2, 3, 4)])
    return s


# ---------------------------------------------------------------- texture paths
def emissive_texture_quad(d, file_path, uvs, tiles):
    """An emissive quad (2 × 2 units, seen by an orthographic camera that fills the frame with it) whose emission is
    a UsdUVTexture reading ``file_path``; ``tiles`` maps relative file names to a flat 8-bit RGB colour, written as
    4 × 4 PNGs. Returns the stage's path."""
    import os

    import numpy as np

    import usd_material_stages as ms

    for name, rgb in tiles.items():
        os.makedirs(os.path.dirname(os.path.join(d, name)) or d, exist_ok=True)
        ms.write_png(os.path.join(d, name), np.tile(np.asarray(rgb, np.uint8), (4, 4, 1)))
    s = ms.new_stage(os.path.join(d, "stage.usda"))
    ms.camera(s, ortho=True)
    q = ms.quad(s, uvs=uvs)
    mat, ps = ms.preview(s)
    ps.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0, 0, 0))
    tex = ms.uv_texture(s, "/Looks/M", "Tex", file_path, st_reader="st", sourceColorSpace="raw")
    ms.connect(ps, "emissiveColor", Sdf.ValueTypeNames.Color3f, tex, "rgb")
    ms.bind(q, mat)
    return ms.save(s)


# ---------------------------------------------------------------- primvars
def inherited_display_color(subdivided=False):
    """displayColor (0.9, 0.2, 0.1) authored only on the Xform /Group; a quad and a sphere below it."""
    s = new_stage()
    add_camera(s, eye=(0, 0, 10))
    g = UsdGeom.Xform.Define(s, "/Group")
    UsdGeom.PrimvarsAPI(g).CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray,
                                         UsdGeom.Tokens.constant).Set([Gf.Vec3f(0.9, 0.2, 0.1)])
    q = quad(s, "/Group/Quad", half=1.5)
    q.CreateSubdivisionSchemeAttr("catmullClark" if subdivided else "none")
    ball = UsdGeom.Sphere.Define(s, "/Group/Ball")
    ball.AddTranslateOp().Set(Gf.Vec3d(2.5, 0, 0))
    ball.CreateRadiusAttr(0.5)
    return s


def coloured_points(interpolation="vertex"):
    """Three points of width 1 along x (x = −2, 0, 2), per-point displayColor red, green, blue."""
    s = new_stage()
    add_camera(s, eye=(0, 0, 10))
    pts = UsdGeom.Points.Define(s, "/Points")
    pts.CreatePointsAttr([(-2, 0, 0), (0, 0, 0), (2, 0, 0)])
    pts.CreateWidthsAttr([1.0, 1.0, 1.0])
    pv = UsdGeom.PrimvarsAPI(pts).CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray, interpolation)
    pv.Set([Gf.Vec3f(1, 0, 0), Gf.Vec3f(0, 1, 0), Gf.Vec3f(0, 0, 1)])
    return s


def coloured_curves(interpolation):
    """Two linear curves (y = 0 and y = 2), each of two segments along x (−2 → 0 → 2), width 0.5;
    displayColor per vertex (red, green, blue on each) or per curve (uniform: red, blue)."""
    s = new_stage()
    add_camera(s, eye=(0, 1, 10))
    c = UsdGeom.BasisCurves.Define(s, "/Curves")
    c.CreateTypeAttr("linear")
    c.CreatePointsAttr([(-2, 0, 0), (0, 0, 0), (2, 0, 0), (-2, 2, 0), (0, 2, 0), (2, 2, 0)])
    c.CreateCurveVertexCountsAttr([3, 3])
    c.CreateWidthsAttr([0.5])
    c.SetWidthsInterpolation("constant")
    values = {"vertex": [(1, 0, 0), (0, 1, 0), (0, 0, 1)] * 2, "uniform": [(1, 0, 0), (0, 0, 1)]}[interpolation]
    pv = UsdGeom.PrimvarsAPI(c).CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray, interpolation)
    pv.Set([Gf.Vec3f(*v) for v in values])
    return s


# ---------------------------------------------------------------- other renderers' surfaces
def lit_quad_with(shader_id, inputs, output="surface", display_color=None, mdl=None):
    """A 6 × 6 quad facing a camera at z = 10, lit head-on by a normalised DistantLight of irradiance 2, bound to a
    material whose ``outputs:<output>`` is one shader (``info:id`` = shader_id, or an MDL sourceAsset ``mdl``)
    with ``inputs`` {name: (Sdf type, value)}."""
    s = new_stage()
    add_camera(s, eye=(0, 0, 10))
    from pxr import UsdLux

    sun = UsdLux.DistantLight.Define(s, "/Sun")
    sun.CreateIntensityAttr(2.0)
    sun.CreateNormalizeAttr(True)
    q = quad(s, "/Q", half=3.0)
    if display_color is not None:
        q.CreateDisplayColorAttr([display_color])
    mat = UsdShade.Material.Define(s, "/M")
    sh = UsdShade.Shader.Define(s, "/M/S")
    if mdl:
        sh.SetSourceAsset(Sdf.AssetPath(f"{mdl}.mdl"), "mdl")
        sh.SetSourceAssetSubIdentifier(mdl, "mdl")
    else:
        sh.CreateIdAttr(shader_id)
    for name, (typ, v) in inputs.items():
        sh.CreateInput(name, typ).Set(v)
    ctx = output.split(":")[0] if ":" in output else UsdShade.Tokens.universalRenderContext
    mat.CreateSurfaceOutput(ctx).ConnectToSource(sh.ConnectableAPI(), "out")
    bind(q, mat)
    return s


# ---------------------------------------------------------------- Arnold-only content (issue #21's survey)
def arnold_camera_stage(matrix=None, position=None, look_at=None, fov=None):
    """A USD Camera left at the origin (no xformOps, its default 50 mm lens) carrying an Arnold placement as
    arnold-usd/MtoA write it (``primvars:arnold:matrix`` / ``position`` / ``look_at`` / ``fov``, arrays of motion
    keys), and a 2 × 2 quad facing +z centred at (10, 0, 0), lit head-on; nothing else."""
    from pxr import UsdLux

    s = new_stage()
    cam = UsdGeom.Camera.Define(s, "/Cam")
    pv = UsdGeom.PrimvarsAPI(cam.GetPrim())
    T = Sdf.ValueTypeNames
    if matrix is not None:
        pv.CreatePrimvar("arnold:matrix", T.Matrix4dArray).Set([Gf.Matrix4d(*matrix)])
    if position is not None:
        pv.CreatePrimvar("arnold:position", T.Vector3fArray).Set([Gf.Vec3f(*position)])
    if look_at is not None:
        pv.CreatePrimvar("arnold:look_at", T.Vector3fArray).Set([Gf.Vec3f(*look_at)])
    if fov is not None:
        pv.CreatePrimvar("arnold:fov", T.FloatArray).Set([fov])
    sun = UsdLux.DistantLight.Define(s, "/Sun")
    sun.CreateIntensityAttr(2.0)
    sun.CreateNormalizeAttr(True)
    q = quad(s, "/Q", half=1.0)
    q.AddTranslateOp().Set(Gf.Vec3d(10, 0, 0))
    return s


def arnold_uv_quad(surface_id, inputs, nodes=()):
    """A 2 × 2 quad with ``st`` running 0..1 across it (u along +x, v along +y), seen head-on by a camera whose
    aperture it exactly fills, bound to a material whose ``outputs:arnold:surface`` is the shader ``/M/S``
    (``surface_id``, ``inputs`` {name: (type, value or "/M/Node.outputs:out" to connect)}); ``nodes``: more shaders
    (path, id, inputs) the same way. No light: Arnold's flat and pattern surfaces are unlit."""
    s = new_stage()
    add_camera(s, eye=(0, 0, 10), h=2.0, v=2.0, focal=10.0)
    q = quad(s, "/Q", half=1.0)
    st = UsdGeom.PrimvarsAPI(q.GetPrim()).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                         UsdGeom.Tokens.vertex)
    st.Set([(0, 0), (1, 0), (1, 1), (0, 1)])
    mat = UsdShade.Material.Define(s, "/M")
    for path, sid, ins in ((("/M/S", surface_id, inputs),) + tuple(nodes)):
        sh = UsdShade.Shader.Define(s, path)
        sh.CreateIdAttr(sid)
        sh.CreateOutput("out", Sdf.ValueTypeNames.Color3f)
    for path, sid, ins in ((("/M/S", surface_id, inputs),) + tuple(nodes)):
        sh = UsdShade.Shader(s.GetPrimAtPath(path))
        for name, (typ, v) in ins.items():
            if isinstance(v, str) and v.startswith("/"):
                sh.CreateInput(name, typ).ConnectToSource(Sdf.Path(v))
            else:
                sh.CreateInput(name, typ).Set(v)
    mat.CreateSurfaceOutput("arnold").ConnectToSource(UsdShade.Shader(s.GetPrimAtPath("/M/S")).ConnectableAPI(),
                                                      "out")
    bind(q, mat)
    return s


def arnold_render_globals_stage():
    """A lit quad and a RenderSettings whose ``arnold:global:background`` / ``atmosphere`` name ArnoldNodeGraphs of
    a ``physical_sky`` and a ``fog`` (as Houdini's Solaris writes them)."""
    from pxr import UsdLux

    s = new_stage()
    add_camera(s)
    UsdLux.DistantLight.Define(s, "/Sun").CreateIntensityAttr(2.0)
    quad(s, "/Q", half=3.0)
    rs = s.DefinePrim("/Render/Settings", "RenderSettings")
    for name, sid in (("background", "arnold:physical_sky"), ("atmosphere", "arnold:fog")):
        rs.CreateAttribute(f"arnold:global:{name}", Sdf.ValueTypeNames.String).Set(f"/{name}_graph")
        g = s.DefinePrim(f"/{name}_graph", "ArnoldNodeGraph")
        sh = UsdShade.Shader.Define(s, f"/{name}_graph/node")
        sh.CreateIdAttr(sid)
        g.CreateAttribute(f"outputs:{name}", Sdf.ValueTypeNames.Token).AddConnection(
            Sdf.Path(f"/{name}_graph/node.outputs:out"))
    return s


def curves_with_st(interpolation="uniform"):
    """Two vertical linear BasisCurves (width 0.6) at x = −1 and x = +1 whose ``st`` is (0.25, 0.25) on the left
    curve and (0.75, 0.25) on the right one (per curve, or the same on each of its points), seen head-on, bound to
    an Arnold checkerboard surface of frequency 1 (two cells per unit, color2 at the UV origin): the left curve in
    color2, the right one in color1."""
    s = new_stage()
    add_camera(s, eye=(0, 0, 10))
    c = UsdGeom.BasisCurves.Define(s, "/C")
    c.CreateTypeAttr("linear")
    c.CreateCurveVertexCountsAttr([2, 2])
    c.CreatePointsAttr([(-1, -1, 0), (-1, 1, 0), (1, -1, 0), (1, 1, 0)])
    c.CreateWidthsAttr([0.6])
    c.SetWidthsInterpolation(UsdGeom.Tokens.constant)
    st = UsdGeom.PrimvarsAPI(c.GetPrim()).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, interpolation)
    st.Set([(0.25, 0.25), (0.75, 0.25)] if interpolation == "uniform" else [(0.25, 0.25)] * 2 + [(0.75, 0.25)] * 2)
    mat = UsdShade.Material.Define(s, "/M")
    sh = UsdShade.Shader.Define(s, "/M/S")
    sh.CreateIdAttr("arnold:checkerboard")
    sh.CreateInput("color1", Sdf.ValueTypeNames.Color3f).Set((0.9, 0.1, 0.1))
    sh.CreateInput("color2", Sdf.ValueTypeNames.Color3f).Set((0.1, 0.2, 0.8))
    sh.CreateInput("u_frequency", Sdf.ValueTypeNames.Float).Set(1.0)
    mat.CreateSurfaceOutput("arnold").ConnectToSource(sh.ConnectableAPI(), "out")
    bind(c, mat)
    return s

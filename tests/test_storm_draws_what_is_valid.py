"""Storm draws what is valid (issue #32, OpenUSD's imaging tests rebuilt as small stages written here):

- a PointInstancer without one of its required inputs (``prototypes`` targets, ``protoIndices``, ``positions``) is
  not added to Storm's render index, with one warning naming it (UsdImagingPointInstancerAdapter); the rest of the
  stage is drawn (testUsdImagingGLPointInstancer_pi_bad_schema_input: Storm's baseline is the empty frame). Before,
  the stage was refused ("gave 0 triangles: nothing is drawn", exit 2) and two of the three got no warning;
- a Skeleton is drawn as UsdSkelImaging's bone mesh (UsdSkelImagingComputeBonePoints: per bone a four-sided
  pyramid, tip at the child joint, base at the parent joint 0.1 × the bone's length out along the parent's two
  axes least aligned with the bone) when its purpose is shown; unauthored it is a guide
  (UsdSkelImagingSkeletonAdapter::GetPurpose) (testUsdImagingGLSkeleton, ``-guidesPurpose show``: before, nothing
  was drawn and the frame was the background).
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt

import tracer
from usd_io.reader import load_stage


def _cube(stage, path):
    cube = UsdGeom.Mesh.Define(stage, path)
    cube.CreatePointsAttr([(-0.5, -0.5, 0.5), (0.5, -0.5, 0.5), (-0.5, 0.5, 0.5), (0.5, 0.5, 0.5),
                           (-0.5, 0.5, -0.5), (0.5, 0.5, -0.5), (-0.5, -0.5, -0.5), (0.5, -0.5, -0.5)])
    cube.CreateFaceVertexCountsAttr([4] * 6)
    cube.CreateFaceVertexIndicesAttr([0, 1, 3, 2, 2, 3, 5, 4, 4, 5, 7, 6, 6, 7, 1, 0, 1, 7, 5, 3, 6, 0, 2, 4])
    cube.CreateSubdivisionSchemeAttr("none")
    return cube


def _bad_instancers(stage):
    """pi_bad_schema_input's three cases: each PointInstancer lacks one required input."""
    _cube(stage, "/prototypes/Cube")
    stage.GetPrimAtPath("/prototypes").SetActive(False)
    for name, missing in (("NoPrototypes", "prototypes"), ("NoProtoIndices", "protoIndices"),
                          ("NoPositions", "positions")):
        pi = UsdGeom.PointInstancer.Define(stage, f"/Bad{name}")
        proto = stage.DefinePrim(f"/Bad{name}/protos/proto1")
        proto.GetReferences().AddInternalReference("/prototypes")
        proto.SetActive(True)
        if missing != "prototypes":
            pi.CreatePrototypesRel().SetTargets([proto.GetPath()])
        if missing != "protoIndices":
            pi.CreateProtoIndicesAttr([0, 0])
        if missing != "positions":
            pi.CreatePositionsAttr([(-2, 0, 0), (2, 0, 0)])


@pytest.mark.parametrize("with_valid_prim", [False, True])
def test_a_point_instancer_missing_a_required_input_is_named_once_and_the_rest_is_drawn(with_valid_prim):
    stage = Usd.Stage.CreateInMemory()
    _bad_instancers(stage)
    if with_valid_prim:
        _cube(stage, "/Valid")
    _scene, info = load_stage(stage, width=32, height=24)
    assert info.nothing_drawn is None  # not refused: Storm draws the empty frame (or the valid cube)
    for name, missing in (("NoPrototypes", "prototypes"), ("NoProtoIndices", "protoIndices"),
                          ("NoPositions", "positions")):
        said = [w for w in info.warnings if f"/Bad{name}" in w]
        assert len(said) == 1 and f"'{missing}'" in said[0] and "not drawn" in said[0], info.warnings
    drawn = dict(info.meshes)
    assert drawn.get("/Valid", 0) == (12 if with_valid_prim else 0)
    assert not any(drawn.get(f"/Bad{n}") for n in ("NoPrototypes", "NoProtoIndices", "NoPositions"))


def test_an_empty_but_authored_input_is_valid():
    """Storm only checks that the inputs have a value: authored empty arrays (or time samples) are valid, and
    draw nothing without a warning about the schema."""
    stage = Usd.Stage.CreateInMemory()
    _cube(stage, "/prototypes/Cube")
    pi = UsdGeom.PointInstancer.Define(stage, "/Empty")
    pi.CreatePrototypesRel().SetTargets(["/prototypes/Cube"])
    pi.CreateProtoIndicesAttr([])
    pi.CreatePositionsAttr([])
    _scene, info = load_stage(stage, width=16, height=16)
    assert not [w for w in info.warnings if "required" in w], info.warnings


def _skeleton(stage, purpose=None, colour=(1, 0, 0)):
    """A three-joint chain: A at the origin, B 2 up (+Y), C 1 along +X from B; the SkelRoot 10 back along −Z."""
    root = UsdSkel.Root.Define(stage, "/Char")
    skel = UsdSkel.Skeleton.Define(stage, "/Char/Skel")
    skel.CreateJointsAttr(["A", "A/B", "A/B/C"])
    rest = [Gf.Matrix4d(1).SetTranslate(Gf.Vec3d(0, 0, 0)), Gf.Matrix4d(1).SetTranslate(Gf.Vec3d(0, 2, 0)),
            Gf.Matrix4d(1).SetTranslate(Gf.Vec3d(1, 0, 0))]
    skel.CreateRestTransformsAttr(Vt.Matrix4dArray(rest))
    skel.CreateBindTransformsAttr(Vt.Matrix4dArray([Gf.Matrix4d(1), Gf.Matrix4d(1).SetTranslate(Gf.Vec3d(0, 2, 0)),
                                                    Gf.Matrix4d(1).SetTranslate(Gf.Vec3d(1, 2, 0))]))
    UsdGeom.Xformable(root).AddTranslateOp().Set(Gf.Vec3d(0, 0, -10))
    if colour is not None:
        UsdGeom.PrimvarsAPI(skel).CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray,
                                                UsdGeom.Tokens.constant).Set([colour])
    if purpose:
        skel.CreatePurposeAttr(purpose)
    return skel


def test_a_skeleton_is_drawn_as_storms_bone_mesh_when_guides_are_shown():
    from usd_io.geometry.skel import bone_mesh

    stage = Usd.Stage.CreateInMemory()
    skel = _skeleton(stage)
    _scene, info = load_stage(stage, width=32, height=32, purposes=("default", "proxy", "guide"))
    assert dict(info.meshes).get("/Char/Skel") == 8  # two bones, four triangles each (the base is open)
    points, triangles = bone_mesh(skel, Usd.TimeCode.Default())
    # bone A->B: length 2 along +Y, so the base is out along A's X and Z axes by 0.2; tip at B (skeleton space)
    np.testing.assert_allclose(points[:5], [(0, 2, 0), (0.2, 0, 0.2), (0.2, 0, -0.2), (-0.2, 0, -0.2),
                                            (-0.2, 0, 0.2)], atol=1e-6)
    # bone B->C: length 1 along +X from B, so the base is out along B's Y and Z axes by 0.1; tip at C
    np.testing.assert_allclose(points[5:], [(1, 2, 0), (0, 2.1, 0.1), (0, 2.1, -0.1), (0, 1.9, -0.1),
                                            (0, 1.9, 0.1)], atol=1e-6)
    np.testing.assert_array_equal(triangles, [(0, 2, 1), (0, 3, 2), (0, 4, 3), (0, 1, 4),
                                              (5, 7, 6), (5, 8, 7), (5, 9, 8), (5, 6, 9)])


def test_a_skeleton_is_a_guide_unless_its_purpose_says_otherwise():
    stage = Usd.Stage.CreateInMemory()
    _skeleton(stage)
    _scene, info = load_stage(stage, width=16, height=16)  # default and render: no guides
    assert "/Char/Skel" not in dict(info.meshes)
    stage = Usd.Stage.CreateInMemory()
    _skeleton(stage, purpose="default")
    _scene, info = load_stage(stage, width=16, height=16)
    assert dict(info.meshes).get("/Char/Skel") == 8


def test_the_bone_mesh_is_drawn_in_the_skeletons_display_colour():
    """Seen head-on from the stage's default framing, the bones are red (the skeleton's displayColor)."""
    stage = Usd.Stage.CreateInMemory()
    _skeleton(stage, purpose="default", colour=(1, 0, 0))
    scene, info = load_stage(stage, width=48, height=48)
    img = tracer.render(scene, tracer.RenderSettings(width=48, height=48, samples=1, transparent=True)).rgba
    img = np.asarray(img)
    covered = img[..., 3] > 0.99
    assert covered.sum() > 20
    rgb = img[covered][:, :3]
    assert np.all(rgb[:, 0] > 4 * np.maximum(rgb[:, 1], rgb[:, 2]) + 1e-3)


@pytest.mark.parametrize("kind", ["Sphere", "Mesh", "SubdivMesh", "Skeleton"])
def test_a_display_colour_authored_as_one_colour_not_an_array_colours_the_prim(kind):
    """``color3f primvars:displayColor = (1, 0, 0)`` (a single value: skeleton.usda writes its bones' colour so;
    on an ancestor Xform it is inherited by the gprims below) is drawn red by Storm. Before, its three numbers were
    read as three colours and the first, (1, 1, 1), drawn: a white surface, no warning."""
    stage = Usd.Stage.CreateInMemory()
    holder = UsdGeom.Xform.Define(stage, "/X")
    if kind == "Sphere":
        UsdGeom.Sphere.Define(stage, "/X/G")
    elif kind == "Skeleton":
        holder = _skeleton(stage, purpose="default", colour=None)
    else:
        mesh = UsdGeom.Mesh.Define(stage, "/X/G")
        mesh.CreatePointsAttr([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])
        mesh.CreateFaceVertexCountsAttr([4])
        mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
        mesh.CreateSubdivisionSchemeAttr("catmullClark" if kind == "SubdivMesh" else "none")
    UsdGeom.PrimvarsAPI(holder).CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3f,
                                              UsdGeom.Tokens.constant).Set(Gf.Vec3f(1, 0, 0))
    scene, _info = load_stage(stage, width=32, height=32)
    img = np.asarray(tracer.render(scene, tracer.RenderSettings(width=32, height=32, samples=1,
                                                                 transparent=True)).rgba)
    rgb = img[img[..., 3] > 0.99][:, :3]
    assert len(rgb) > 4
    assert np.all(rgb[:, 0] > 4 * np.maximum(rgb[:, 1], rgb[:, 2]) + 1e-3), rgb[:4]


def test_a_directly_instanced_gprim_is_not_drawn_and_named_once():
    """A gprim that is itself instanceable (``def "pCube1" (instanceable = true references = </Cube>)`` with
    ``/Cube`` a Cube: instancedCubes2NoInstancing.usda) is skipped by UsdImaging's instance adapter with a warning
    ("put the prim under an Xform, and instance the Xform parent"); Storm's baseline draws only the uninstanced
    /Cube. Before, each instance was drawn (IoU 0.08 against the baseline)."""
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.Cube.Define(stage, "/Cube")
    for i in range(2):
        inst = stage.DefinePrim(f"/Cubes/pCube{i}")
        inst.GetReferences().AddInternalReference("/Cube")
        inst.SetInstanceable(True)
        UsdGeom.Xformable(inst).AddTranslateOp().Set(Gf.Vec3d(3 * (i + 1), 0, 0))
    _scene, info = load_stage(stage, width=16, height=16)
    assert list(dict(info.meshes)) == ["/Cube"]
    for i in range(2):
        said = [w for w in info.warnings if f"/Cubes/pCube{i}" in w]
        assert len(said) == 1 and "directly instanced" in said[0], info.warnings
    # only such instances: not refused, the empty frame
    stage.GetPrimAtPath("/Cube").SetActive(False)
    stage2 = Usd.Stage.CreateInMemory()
    UsdGeom.Cube.Define(stage2, "/Proto").GetPrim().SetSpecifier(Sdf.SpecifierClass)
    inst = stage2.DefinePrim("/Inst")
    inst.GetReferences().AddInternalReference("/Proto")
    inst.SetInstanceable(True)
    _scene, info = load_stage(stage2, width=16, height=16)
    assert info.nothing_drawn is None and not info.meshes


def test_a_model_draw_mode_storm_would_apply_is_named_in_one_warning():
    """``model:drawMode = "cards"`` (or bounds, origin) on a component model, or on any model with
    ``model:applyDrawMode = true``, makes Storm draw a stand-in (testUsdImagingGLCards); the tracer draws the full
    geometry, and says so in one warning naming the mode and the models. Before: silence."""
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.Xform.Define(stage, "/World")
    Usd.ModelAPI(stage.GetPrimAtPath("/World")).SetKind("group")
    for name, kind, apply in (("A", "component", False), ("B", "assembly", True), ("C", "assembly", False)):
        s = UsdGeom.Sphere.Define(stage, f"/World/{name}")
        Usd.ModelAPI(s.GetPrim()).SetKind(kind)
        model = UsdGeom.ModelAPI.Apply(s.GetPrim())
        model.CreateModelDrawModeAttr("cards")
        if apply:
            model.CreateModelApplyDrawModeAttr(True)
    _scene, info = load_stage(stage, width=16, height=16)
    said = [w for w in info.warnings if "drawMode" in w]
    assert len(said) == 1 and "cards" in said[0] and "/World/A" in said[0] and "/World/B" in said[0], said
    assert "/World/C" not in said[0]
    assert sorted(dict(info.meshes)) == ["/World/A", "/World/B", "/World/C"]  # still drawn in full


def test_arnold_shape_prims_are_named_in_one_warning():
    """Arnold's own shape schemas other than its sphere and box (``def ArnoldCurves``, ``ArnoldPolymesh``, an
    ``ArnoldUsd`` procedural: arnold-usd's ArnoldUsd tests) are not USD geometry and are not drawn; one warning
    names them (before: nothing said)."""
    stage = Usd.Stage.CreateInMemory()
    stage.DefinePrim("/a", "ArnoldCurves")
    stage.DefinePrim("/b", "ArnoldPolymesh")
    stage.DefinePrim("/c", "ArnoldUsd")
    stage.DefinePrim("/graph", "ArnoldNodeGraph")  # not a shape: read by the material reader, not named here
    UsdGeom.Cube.Define(stage, "/Cube")
    _scene, info = load_stage(stage, width=16, height=16)
    said = [w for w in info.warnings if "ArnoldCurves" in w or "ArnoldPolymesh" in w or "ArnoldUsd" in w]
    assert len(said) == 1 and all(p in said[0] for p in ("/a", "/b", "/c")) and "/graph" not in said[0], said
    assert dict(info.meshes) == {"/Cube": 12}


def test_arnold_aov_shaders_are_named_in_one_warning():
    """``arnold:global:aov_shaders`` on a RenderSettings (arnold-usd test_0236: an aov_write_rgba of a utility shader
    that overwrites the beauty) runs Arnold shaders on every surface; the tracer does not, and says so once. Before:
    silence, and a grey picture where Arnold's is coloured."""
    from pxr import UsdRender

    stage = Usd.Stage.CreateInMemory()
    UsdGeom.Cube.Define(stage, "/Cube")
    stage.DefinePrim("/materials/aov_shaders", "ArnoldNodeGraph")
    rs = UsdRender.Settings.Define(stage, "/Render/settings")
    rs.GetPrim().CreateAttribute("arnold:global:aov_shaders", Sdf.ValueTypeNames.String).Set("/materials/aov_shaders")
    _scene, info = load_stage(stage, width=16, height=16)
    said = [w for w in info.warnings if "aov_shaders" in w]
    assert len(said) == 1 and "/materials/aov_shaders" in said[0], info.warnings


def test_arnold_sphere_and_box_are_drawn_with_arnolds_defaults_and_their_xform_ops():
    """``ArnoldSphere`` (arnold:radius, a float or arnold-usd's one-element array; Arnold's default 0.5;
    arnold:center) and ``ArnoldBox`` (arnold:min/max, default ±0.5) are Arnold's own implicit shapes (arnold-usd
    test_0149 "Read usdGeom xformops on Arnold schemas", 0173, 1718): drawn as their USD counterparts, placed by
    their xformOps (USD's XformCache skips the ops of a prim whose type it does not know). Before: not drawn,
    nothing said, a blank frame."""
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.Xform.Define(stage, "/X").AddTranslateOp().Set(Gf.Vec3d(0, 0, 5))
    a = stage.DefinePrim("/X/a", "ArnoldSphere")
    a.CreateAttribute("arnold:radius", Sdf.ValueTypeNames.FloatArray).Set([2])
    a.CreateAttribute("xformOp:translate", Sdf.ValueTypeNames.Double3).Set(Gf.Vec3d(10, 0, 0))
    a.CreateAttribute("xformOpOrder", Sdf.ValueTypeNames.TokenArray).Set(["xformOp:translate"])
    stage.DefinePrim("/b", "ArnoldBox")
    scene, info = load_stage(stage, width=16, height=16)
    assert sorted(dict(info.meshes)) == ["/X/a", "/b"]
    assert not [w for w in info.warnings if "Arnold shape" in w]
    v = np.asarray(scene.vertices)
    far = v[v[:, 0] > 5]
    np.testing.assert_allclose([far.min(axis=0), far.max(axis=0)], [(8, -2, 3), (12, 2, 7)], atol=1e-6)
    near = v[v[:, 0] <= 5]
    np.testing.assert_allclose([near.min(axis=0), near.max(axis=0)], [(-0.5,) * 3, (0.5,) * 3], atol=1e-6)


@pytest.mark.parametrize("emission,colour,expected", [(1.0, (1, 0, 0), (1, 0, 0)), (0.5, (0, 1, 0), (0, 0.5, 0)),
                                                      (0.0, (1, 0, 0), (0, 0, 0))])
def test_arnolds_legacy_standard_shader_emits(emission, colour, expected):
    """Arnold 4's ``arnold:standard`` emits ``emission`` × ``emission_color`` (arnold-usd test_0050 "Kick USD file":
    a red emitting sphere, no light). Before: its Kd/Ks were read and its emission dropped without a word, a black
    frame. Seen unlit (no light, black world), the sphere is its emission."""
    from pxr import UsdShade

    stage = Usd.Stage.CreateInMemory()
    sphere = UsdGeom.Sphere.Define(stage, "/S")
    mat = UsdShade.Material.Define(stage, "/M")
    sh = UsdShade.Shader.Define(stage, "/M/std")
    sh.CreateIdAttr("arnold:standard")
    sh.CreateInput("emission", Sdf.ValueTypeNames.Float).Set(emission)
    sh.CreateInput("emission_color", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*colour))
    sh.CreateInput("Kd", Sdf.ValueTypeNames.Float).Set(0.0)
    mat.CreateSurfaceOutput("arnold").ConnectToSource(sh.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(sphere.GetPrim()).Bind(mat)
    scene, _info = load_stage(stage, width=16, height=16, default_light=False)
    img = np.asarray(tracer.render(scene, tracer.RenderSettings(width=16, height=16, samples=1)).rgba)
    np.testing.assert_allclose(img[8, 8, :3], expected, atol=1e-3)


def test_an_emission_colour_read_from_a_primvar_emits_the_primvar():
    """Standard Surface's ``emission_color`` from a primvar (Arnold's ``user_data_rgb`` of ``Pref``: arnold-usd
    test_1625, a rainbow torus, no light) emits the primvar's colour. Before, a primvar on any input but the base
    colour set that input to its default (emission black) and coloured the base instead: a black frame, silently.
    Unlit, the quad is its primvar colour: red at one corner, green at another."""
    from pxr import UsdShade

    stage = Usd.Stage.CreateInMemory()
    mesh = UsdGeom.Mesh.Define(stage, "/Q")
    mesh.CreatePointsAttr([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])
    mesh.CreateFaceVertexCountsAttr([4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    mesh.CreateSubdivisionSchemeAttr("none")
    UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("Pref", Sdf.ValueTypeNames.Float3Array, UsdGeom.Tokens.vertex).Set(
        [(1, 0, 0), (1, 0, 0), (0, 1, 0), (0, 1, 0)])
    mat = UsdShade.Material.Define(stage, "/M")
    ss = UsdShade.Shader.Define(stage, "/M/ss")
    ss.CreateIdAttr("arnold:standard_surface")
    ss.CreateInput("base", Sdf.ValueTypeNames.Float).Set(0.0)
    ss.CreateInput("specular", Sdf.ValueTypeNames.Float).Set(0.0)
    ss.CreateInput("emission", Sdf.ValueTypeNames.Float).Set(1.0)
    ud = UsdShade.Shader.Define(stage, "/M/ud")
    ud.CreateIdAttr("arnold:user_data_rgb")
    ud.CreateInput("attribute", Sdf.ValueTypeNames.String).Set("Pref")
    ss.CreateInput("emission_color", Sdf.ValueTypeNames.Color3f).ConnectToSource(ud.ConnectableAPI(), "rgb")
    mat.CreateSurfaceOutput("arnold").ConnectToSource(ss.ConnectableAPI(), "shader")
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(mat)
    scene, _info = load_stage(stage, width=32, height=32, default_light=False)
    img = np.asarray(tracer.render(scene, tracer.RenderSettings(width=32, height=32, samples=1)).rgba)[..., :3]
    covered = img[img.max(axis=-1) > 0.05]
    assert len(covered) > 100
    bottom, top = img[img.shape[0] * 3 // 4, 16], img[img.shape[0] // 4, 16]  # y = -0.5 (red side), y = 0.5
    assert bottom[0] > 0.5 and bottom[1] < 0.5 and top[1] > 0.5 and top[0] < 0.5, (bottom, top)


def test_lights_and_arnold_shapes_in_instancer_prototypes_are_named_not_refused():
    """A PointInstancer whose prototypes are lights (arnold-usd test_1705 "Light instances", 2641) or Arnold
    procedurals (1588, 2064) draws nothing here; one warning per instancer names them. Before: silence, and a stage
    with nothing else was refused ("gave 0 triangles", exit 2)."""
    from pxr import UsdLux

    stage = Usd.Stage.CreateInMemory()
    for name, make in (("Lights", lambda p: UsdLux.SphereLight.Define(stage, p)),
                       ("Procs", lambda p: stage.DefinePrim(p, "ArnoldUsd"))):
        pi = UsdGeom.PointInstancer.Define(stage, f"/{name}")
        make(f"/{name}/protos/p")
        pi.CreatePrototypesRel().SetTargets([f"/{name}/protos/p"])
        pi.CreateProtoIndicesAttr([0, 0])
        pi.CreatePositionsAttr([(0, 0, 0), (2, 0, 0)])
    _scene, info = load_stage(stage, width=16, height=16)
    assert info.nothing_drawn is None
    for name, what in (("Lights", "SphereLight"), ("Procs", "ArnoldUsd")):
        said = [w for w in info.warnings if w.startswith(f"/{name}:")]
        assert len(said) == 1 and what in said[0] and "not drawn" in said[0], info.warnings


def test_a_prim_type_usd_does_not_know_is_drawn_as_its_fallback_prim_type():
    """The layer's ``fallbackPrimTypes`` (``UnknownSphere = ["Sphere"]``: OpenUSD's fallbacks1.usda) makes USD read
    a prim of an unknown type as its fallback schema, which Storm draws. Before: "UnknownSphere is not supported
    (skipped)"."""
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.ImportFromString('''#usda 1.0
(
    fallbackPrimTypes = {
        token[] UnknownSphere = ["Sphere"]
        token[] UnknownCone = ["Cone"]
    }
)
def UnknownSphere "S"
{
    double radius = 2
}
def UnknownCone "C"
{
}
''')
    stage = Usd.Stage.Open(layer)
    scene, info = load_stage(stage, width=16, height=16)
    drawn = dict(info.meshes)
    assert set(drawn) == {"/S", "/C"} and not [w for w in info.warnings if "not supported" in w], info.warnings
    assert np.abs(np.asarray(scene.vertices)).max() == pytest.approx(2.0, rel=1e-3)


def test_an_authored_purpose_below_a_hidden_purpose_is_its_own():
    """A prim's purpose is its authored one, else its nearest ancestor's authored one (UsdGeomImageable's
    ComputePurpose); a child that authors ``default`` under a ``render`` Xform is drawn when render is hidden, as
    Storm draws it (OpenUSD's InheritedPurposes.usd). Before: the subtree was pruned at the render Xform (IoU 0.54
    against the baseline)."""
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.Xform.Define(stage, "/R").CreatePurposeAttr("render")
    UsdGeom.Sphere.Define(stage, "/R/Inherits")  # render, inherited
    UsdGeom.Sphere.Define(stage, "/R/Own").CreatePurposeAttr("default")
    UsdGeom.Xform.Define(stage, "/R/Scope")
    UsdGeom.Sphere.Define(stage, "/R/Scope/Proxy").CreatePurposeAttr("proxy")
    UsdGeom.Xform.Define(stage, "/G").CreatePurposeAttr("guide")
    UsdGeom.Cube.Define(stage, "/G/Default").CreatePurposeAttr("default")
    _scene, info = load_stage(stage, width=16, height=16, purposes=("default", "proxy"))
    assert sorted(dict(info.meshes)) == ["/G/Default", "/R/Own", "/R/Scope/Proxy"]
    _scene, info = load_stage(stage, width=16, height=16, purposes=("default", "render"))
    assert sorted(dict(info.meshes)) == ["/G/Default", "/R/Inherits", "/R/Own"]


def test_arnold_camera_shaders_are_named_in_one_warning():
    """``primvars:arnold:filtermap`` / ``uv_remap`` on a camera (arnold-usd test_1499: a checkerboard filter map
    darkens Arnold's picture) are Arnold camera shaders the tracer does not run; one warning names them. Before:
    silence."""
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.Cube.Define(stage, "/Cube")
    cam = UsdGeom.Camera.Define(stage, "/cam")
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 10))
    for name in ("filtermap", "uv_remap"):
        cam.GetPrim().CreateAttribute(f"primvars:arnold:{name}", Sdf.ValueTypeNames.String).Set("/materials/graph")
    _scene, info = load_stage(stage, camera="/cam", width=16, height=16)
    said = [w for w in info.warnings if "filtermap" in w]
    assert len(said) == 1 and "uv_remap" in said[0] and "/cam" in said[0], info.warnings


def test_a_texture_with_authored_mip_levels_is_named_once(tmp_path):
    """A texture file whose MIP levels are authored (OpenUSD's testUsdImagingGLMipmap: authoredMips.tex, each level
    its own colour) shows Storm the level its screen footprint selects; the tracer reads level 0, and now says so
    once per file. Before: silence (the sweep's Mipmap_010/014/017 "grey" frames: level 0 where Storm shows the
    coloured coarse levels)."""
    import OpenImageIO as oiio
    from pxr import UsdShade

    def image(name, size, value):
        buf = oiio.ImageBuf(oiio.ImageSpec(size, size, 3, oiio.UINT8))
        buf.set_pixels(oiio.ROI(0, size, 0, size), np.full((size, size, 3), value, np.uint8))
        return buf

    for name, size in (("l1.png", 2), ("l2.png", 1)):
        image(name, size, 50).write(str(tmp_path / name))
    path = str(tmp_path / "mips.tif")  # levels 4, 2 and 1 px: 200/255 grey, then authored 50/255 ones (maketx)
    config = oiio.ImageSpec()
    config.attribute("maketx:mipimages", f"{tmp_path / 'l1.png'};{tmp_path / 'l2.png'}")
    assert oiio.ImageBufAlgo.make_texture(oiio.MakeTxTexture, image("l0", 4, 200), path, config)
    plain = str(tmp_path / "plain.tif")  # a pyramid filtered from its level 0: no warning
    assert oiio.ImageBufAlgo.make_texture(oiio.MakeTxTexture, image("l0", 4, 200), plain)
    from usd_io.materials.texture_files import authored_mip_levels
    assert authored_mip_levels(plain) == 1 and authored_mip_levels(path) == 3
    stage = Usd.Stage.CreateInMemory()
    mesh = UsdGeom.Mesh.Define(stage, "/Q")
    mesh.CreatePointsAttr([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])
    mesh.CreateFaceVertexCountsAttr([4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex).Set(
        [(0, 0), (1, 0), (1, 1), (0, 1)])
    mat = UsdShade.Material.Define(stage, "/M")
    ps = UsdShade.Shader.Define(stage, "/M/ps")
    ps.CreateIdAttr("UsdPreviewSurface")
    tex = UsdShade.Shader.Define(stage, "/M/tex")
    tex.CreateIdAttr("UsdUVTexture")
    tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(path)
    ps.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(tex.ConnectableAPI(), "rgb")
    mat.CreateSurfaceOutput().ConnectToSource(ps.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(mat)
    _scene, info = load_stage(stage, width=16, height=16)
    said = [w for w in info.warnings if "MIP" in w]
    assert len(said) == 1 and "mips.tif" in said[0] and "3" in said[0], info.warnings

"""A :class:`bench.scenes.BenchScene` as a USD stage (pxr), for the ``whitted`` CLI and other USD renderers.

Z up, metres. Meshes live under ``/Scene/Prototypes`` (inactive as geometry: ``purpose`` guide is not used; each is
a ``Mesh`` inside an ``Xform`` made invisible) and every instance is an ``Xform`` with a 4×4 transform whose child
references its prototype's ``Xform``, ``instanceable = true`` so USD shares them (a gprim is never itself
instanceable: Storm and the reader skip such a prim). Materials are ``UsdPreviewSurface``:
diffuseColor, specularColor (specular workflow; the metallic workflow with metallic = k_m for mirrors), roughness,
opacity = 1 − transmission, ior.
Point lights are ``SphereLight`` with ``treatAsPoint``, intensity = 4·I (Blender's export: P/π with P = 4π·I).
The world is a ``DomeLight`` of the background colour; USD has one world light, so the stage's ambient term is the
background colour (the Python scenes use a dimmer ambient), and UsdPreviewSurface cannot express our mirror's dark
local part (see the comment below): renders of the .usda are brighter than the Python scenes, with the same geometry.
"""

from __future__ import annotations

import numpy as np

from .scenes import BenchScene


def write_usd(bs: BenchScene, path: str, width: int = 1920, height: int = 1080) -> str:
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade, Vt

    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/Scene")
    stage.SetDefaultPrim(root.GetPrim())

    looks = []
    for k, m in enumerate(bs.materials):
        mat = UsdShade.Material.Define(stage, f"/Scene/Looks/M{k}_{m['name']}")
        sh = UsdShade.Shader.Define(stage, mat.GetPath().AppendChild("Surface"))
        sh.CreateIdAttr("UsdPreviewSurface")
        # In the metallic workflow the base colour also tints the reflection (a metal's colour), so a mirror's
        # diffuseColor is its mirror tint; its small local diffuse part becomes that colour too.
        base = m.get("mirror_tint", (1.0,) * 3) if m.get("k_m", 0.0) > 0 else m.get("diffuse", (0.8,) * 3)
        sh.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*base))
        # UsdPreviewSurface ignores metallic in the specular workflow: mirrors use the metallic one.
        sh.CreateInput("useSpecularWorkflow", Sdf.ValueTypeNames.Int).Set(0 if m.get("k_m", 0.0) > 0 else 1)
        sh.CreateInput("specularColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*m.get("specular", (0.0,) * 3)))
        sh.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(float(m.get("roughness", 0.5)))
        sh.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(float(m.get("k_m", 0.0)))
        sh.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(1.0 - float(m.get("transmission", 0.0)))
        sh.CreateInput("ior", Sdf.ValueTypeNames.Float).Set(float(m.get("ior", 1.5)))
        mat.CreateSurfaceOutput().ConnectToSource(sh.ConnectableAPI(), "surface")
        looks.append(mat)

    protos = []
    for k, mesh in enumerate(bs.meshes):
        p = f"/Scene/Prototypes/{mesh.name}"
        proto = UsdGeom.Xform.Define(stage, p)  # instanceable prims hold their gprim: a gprim itself is not instanced
        um = UsdGeom.Mesh.Define(stage, f"{p}/Mesh")
        um.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.asarray(mesh.vertices, np.float32)))
        um.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(mesh.faces), 3, np.int32)))
        um.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.asarray(mesh.faces, np.int32).ravel()))
        um.CreateSubdivisionSchemeAttr("none")
        if mesh.normals is not None:
            um.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(np.asarray(mesh.normals, np.float32)))
            um.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
        if np.ndim(mesh.material) > 0:
            mats = np.asarray(mesh.material)
            for u in np.unique(mats):
                sub = UsdGeom.Subset.CreateGeomSubset(um, f"mat{int(u)}", UsdGeom.Tokens.face,
                                                      Vt.IntArray.FromNumpy(np.flatnonzero(mats == u).astype(np.int32)),
                                                      UsdShade.Tokens.materialBind)
                UsdShade.MaterialBindingAPI.Apply(sub.GetPrim()).Bind(looks[int(u)])
        UsdGeom.Imageable(proto).MakeInvisible()
        protos.append(p)

    for k, inst in enumerate(bs.instances):
        x = UsdGeom.Xform.Define(stage, f"/Scene/World/I{k}_{bs.meshes[inst.mesh].name}")
        x.AddTransformOp().Set(Gf.Matrix4d(np.asarray(inst.transform, float).T.tolist()))  # USD: row vectors
        body = stage.DefinePrim(x.GetPath().AppendChild("Geom"))
        body.GetReferences().AddInternalReference(protos[inst.mesh])
        UsdGeom.Imageable(body).CreateVisibilityAttr(UsdGeom.Tokens.inherited)
        mat = bs.instance_material(inst)
        if np.ndim(mat) == 0:
            UsdShade.MaterialBindingAPI.Apply(x.GetPrim()).Bind(looks[int(mat)])
        body.SetInstanceable(np.ndim(mat) == 0 and len(bs.instances) > len(bs.meshes))

    for light in bs.lights:
        sl = UsdLux.SphereLight.Define(stage, f"/Scene/Lights/{light.name}")
        i = np.asarray(light.intensity, float)
        peak = float(i.max())
        sl.CreateIntensityAttr(4.0 * peak)
        sl.CreateColorAttr(Gf.Vec3f(*(i / max(peak, 1e-30))))
        sl.CreateRadiusAttr(0.0)
        sl.CreateTreatAsPointAttr(True)
        UsdGeom.Xformable(sl).AddTranslateOp().Set(Gf.Vec3d(*light.position))

    cam = bs.camera(width, height)
    uc = UsdGeom.Camera.Define(stage, "/Scene/Camera")
    uc.AddTransformOp().Set(Gf.Matrix4d(cam.camera_to_world.T.tolist()))
    uc.CreateFocalLengthAttr(cam.focal_length / 10.0)  # tenths of a stage unit, as Blender writes
    uc.CreateHorizontalApertureAttr(cam.horizontal_aperture / 10.0)
    uc.CreateVerticalApertureAttr(cam.vertical_aperture / 10.0)

    dome = UsdLux.DomeLight.Define(stage, "/Scene/Lights/World")
    dome.CreateColorAttr(Gf.Vec3f(*bs.background))
    dome.CreateIntensityAttr(1.0)
    stage.GetRootLayer().Save()
    return path

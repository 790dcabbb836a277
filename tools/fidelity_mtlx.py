"""Fidelity against references (issue #32), MaterialX corpus: every material of MaterialX's example and test-suite
documents on a sphere under a dome, against a ray-traced OSL reference, compared on the sphere's mean colour.

    python tools/fidelity.py materialx MATERIALX_CHECKOUT [--out /tmp/fidelity_mtlx] [--only SUBSTR[,SUBSTR...]]
                             [--size 64] [--aa 3] [--spp 128] [--spp-unlit 16] [--refs DIR] [--no-graphs]
                             [--jsonl OUT.jsonl] [--sheet OUT.png]

Nothing is downloaded: MATERIALX_CHECKOUT is a checkout (or an extracted copy) of MaterialX holding
``resources/Materials/{Examples,TestSuite}`` and ``resources/Images``.

**The corpus.** Each ``surfacematerial`` of every ``.mtlx`` under ``Examples`` and ``TestSuite`` (a document that
does not parse, or whose image files are absent from the checkout, is listed as unmeasured with the reason). Its
family is its surface shader's node category (``standard_surface``, ``open_pbr_surface``, ``gltf_pbr``,
``disney_principled``, ``UsdPreviewSurface``, ``surface_unlit``, ...), the Lama test documents are ``lama``, the
nprlib ones ``npr``, anything else authored from pbrlib closures (``surface`` and documents' own definitions) is
``pbrlib``.

**The scene** (one definition, :func:`scene_spec`, for both renderers; Z up): a UV sphere of radius 1 at the origin
(a mesh with its own normals and texture coordinates: the same vertices, normals and UVs in both renderers), a
camera at (0, −4, 0) looking along +Y (50 mm lens, 36 mm square aperture), and a dome whose radiance depends on
elevation only (:func:`dome_radiance`: 0.2 at the nadir, 0.5 at the horizon, 1 at the zenith, neutral), so its
orientation cannot differ between the two.

**Ours.** The material's document is referenced from a USD stage (``references = @doc.mtlx@</MaterialX/Materials/
NAME>``, usd_io.materials.mtlx translating it) bound to the sphere, with a DomeLight of the dome's lat-long EXR, and
rendered in-process (``usd_io.load_stage`` + ``tracer.render``) at ``--size`` with ``--aa``×``--aa`` samples.

**The reference.** MaterialX's own OSL code generator (``MaterialX.PyMaterialXGenOsl``, the library's
implementation of every node and closure, its colour management to ``lin_rec709`` and its unit system) writes the
material as an OSL shader, which Cycles (bpy 5.0, OSL shading on the CPU, path traced at ``--spp`` samples, default
light paths) renders on the same sphere under the same dome (:mod:`fidelity_mtlx_cycles`, in its own process).
Adaptations of the generated code: ``vector2(u, v)`` (the default texture coordinates: Cycles' ``u, v`` on a
triangle are barycentric) and ``normalize(dPdu)`` (the default tangent) read two shader parameters the reference's
material links to a UV Map node and a UV-map Tangent node (a script's ``getattribute`` finds no mesh attribute
Cycles was not asked to load); GGX closures use Cycles' ``multi_ggx`` (MaterialX's GLSL/MSL implementations
compensate GGX's multiple-scattering energy loss, Cycles' OSL closures only for that distribution name; a white
conductor at roughness 0.9 reflects 0.47 of a white furnace with plain ``ggx``); and ``layer(bsdf, vdf)`` is the
bsdf alone (Cycles renders MaterialX's surface-over-medium layering black: 5.0 registers no ``anisotropic_vdf``;
neither renderer measures the medium); ``subsurface_bssrdf`` is weighted by its albedo and its radius × 4π, and
``translucent_bsdf`` is ``albedo * translucent(N)`` (:func:`cycles_closures`: Blender 5.0's Cycles renders the first
white and lacks the second; ``tools/fidelity_mtlx_sss_check.py`` holds both against Cycles' own nodes).
Inside the generated functions (out of the parameters' scope) the UV and tangent are the sphere's own
parameterisation. Image lookups are flipped vertically as MaterialX's OSL renders do (``fileTextureVerticalFlip``).
References are cached by the hash of the shader source and the scene (``--refs``).

**The measure.** Over the pixels both renders fully cover (alpha = 1 in both, eroded by one pixel) the mean linear
Rec.709 colour of each, converted to CIE L*a*b* (D65, Y = 1 for the dome's zenith white) and compared by
**CIEDE2000** (ΔE00). A material is *within* when ΔE00 ≤ 5. One JSON line per material goes to ``--jsonl``; the
summary gives the share within ΔE 5 and the median ΔE per family; ``OUT/pairs/`` holds one side-by-side PNG per
material (reference | ours, tone-mapped by a 2.2 gamma) and ``--sheet`` writes a contact sheet (reference |
ours per material, worst first).
"""

from __future__ import annotations

import argparse
import glob
import hashlib
import json
import math
import os
import re
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
#: Bump when the scene or the reference's set-up changes (invalidates cached references).
SCENE_VERSION = 5
WITHIN = 5.0


# ---------------------------------------------------------------------------------------------- the scene
def sphere_mesh(nu: int = 96, nv: int = 48):
    """(points (n, 3), face counts, face vertex indices, uvs (n, 2), normals (n, 3)) of a UV sphere of radius 1:
    u = azimuth / 2π from +X towards +Y, v = 0 at the south pole (−Z) to 1 at the north pole; the seam column and
    the poles are duplicated vertices, so every attribute is per vertex."""
    pts, uvs = [], []
    for j in range(nv + 1):
        theta = math.pi * j / nv  # from the south pole
        z = -math.cos(theta)
        r = math.sin(theta)
        for i in range(nu + 1):
            u = i / nu
            if j in (0, nv):
                u = (i + 0.5) / nu
            phi = 2 * math.pi * u
            pts.append((r * math.cos(phi), r * math.sin(phi), z))
            uvs.append((u, j / nv))
    pts = np.asarray(pts, np.float64)
    pts[:nu + 1] = (0.0, 0.0, -1.0)
    pts[-(nu + 1):] = (0.0, 0.0, 1.0)
    counts, idx = [], []
    row = nu + 1
    for j in range(nv):
        for i in range(nu):
            a, b, c, d = j * row + i, j * row + i + 1, (j + 1) * row + i + 1, (j + 1) * row + i
            if j == 0:
                counts.append(3)
                idx += [a, c, d]
            elif j == nv - 1:
                counts.append(3)
                idx += [a, b, d]
            else:
                counts.append(4)
                idx += [a, b, c, d]
    return pts, counts, idx, np.asarray(uvs, np.float64), pts.copy()


def dome_radiance(z):
    """The dome's radiance towards direction elevation sin = z: 0.5 + 0.5 z above the horizon, 0.5 + 0.3 z below."""
    z = np.asarray(z, np.float64)
    return np.where(z >= 0, 0.5 + 0.5 * z, 0.5 + 0.3 * z)


def write_dome(path: str, w: int = 256, h: int = 128) -> str:
    """The dome as a lat-long EXR (top row = the pole): rows at latitude π/2 − π(y + ½)/h."""
    import OpenImageIO as oiio

    if os.path.exists(path):
        return path
    lat = math.pi / 2 - math.pi * (np.arange(h) + 0.5) / h
    col = dome_radiance(np.sin(lat)).astype(np.float32)
    img = np.repeat(np.repeat(col[:, None, None], w, axis=1), 3, axis=2)
    spec = oiio.ImageSpec(w, h, 3, oiio.FLOAT)
    buf = oiio.ImageBuf(spec)
    buf.set_pixels(oiio.ROI(0, w, 0, h), img)
    tmp = path + ".tmp.exr"
    buf.write(tmp)
    os.replace(tmp, path)
    return path


CAMERA = dict(location=(0.0, -4.0, 0.0), focal_mm=50.0, aperture_mm=36.0)


def scene_spec(size: int, dome: str) -> dict:
    return dict(size=size, dome=dome, camera=CAMERA, version=SCENE_VERSION)


def write_stage(path: str, mtlx: str, material: str, dome: str) -> str:
    """The USD stage of one material: the sphere bound to ``material`` of ``mtlx`` (usdMtlx's layout), the dome,
    the camera."""
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade

    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    pts, counts, idx, uvs, nrm = sphere_mesh()
    mesh = UsdGeom.Mesh.Define(stage, "/World/Sphere")
    mesh.CreatePointsAttr([Gf.Vec3f(*p) for p in pts])
    mesh.CreateFaceVertexCountsAttr(counts)
    mesh.CreateFaceVertexIndicesAttr(idx)
    mesh.CreateNormalsAttr([Gf.Vec3f(*n) for n in nrm])
    mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
    st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex)
    st.Set([Gf.Vec2f(*t) for t in uvs])
    looks = stage.DefinePrim("/World/Looks/M")
    looks.GetReferences().AddReference(os.path.abspath(mtlx), Sdf.Path("/MaterialX/Materials").AppendChild(material))
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(UsdShade.Material(looks))
    cam = UsdGeom.Camera.Define(stage, "/World/Camera")
    cam.CreateFocalLengthAttr(CAMERA["focal_mm"])
    cam.CreateHorizontalApertureAttr(CAMERA["aperture_mm"])
    cam.CreateVerticalApertureAttr(CAMERA["aperture_mm"])
    cam.CreateClippingRangeAttr(Gf.Vec2f(0.01, 1000))
    x = UsdGeom.Xformable(cam)
    x.AddTranslateOp().Set(Gf.Vec3d(*CAMERA["location"]))
    x.AddRotateXOp().Set(90.0)
    dl = UsdLux.DomeLight.Define(stage, "/World/Dome")
    dl.CreateIntensityAttr(1.0)
    dl.CreateTextureFileAttr(Sdf.AssetPath(os.path.abspath(dome)))
    dl.CreateTextureFormatAttr("latlong")
    UsdGeom.Xformable(dl).AddRotateXOp().Set(90.0)  # the dome's pole (+Y) onto the stage's +Z
    stage.SetDefaultPrim(stage.GetPrimAtPath("/World"))
    stage.GetRootLayer().Save()
    return path


# ---------------------------------------------------------------------------------------------- the corpus
_LIB = []


def _library():
    import MaterialX as mx

    if not _LIB:
        lib = mx.createDocument()
        mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), lib)
        _LIB.append(lib)
    return _LIB[0]


def family_of(rel: str, shader) -> str:
    if "/lama/" in rel:
        return "lama"
    if rel.startswith("TestSuite/nprlib"):
        return "npr"
    cat = shader.getCategory() if shader is not None else "none"
    if cat in ("standard_surface", "open_pbr_surface", "gltf_pbr", "disney_principled", "UsdPreviewSurface",
               "surface_unlit"):
        return cat
    return "pbrlib"


#: Graph-output types wrapped as a material (:func:`wrap_outputs`), and how.
WRAP_UNLIT = ("color3", "color4", "float", "vector2", "vector3", "vector4", "integer", "boolean")


def wrap_outputs(doc) -> list[tuple[str, str]]:
    """Each output of the document's own node graphs (and the document's top-level outputs) as a material, the way
    MaterialX's test renderers show them: a surfaceshader as is, a BSDF or EDF through a ``surface`` node, a value
    through ``convert`` to color3 as the ``emission_color`` of a ``surface_unlit``. Returns [(material, output
    path)]; outputs of other types (displacement, volume, strings, matrices) are not wrapped."""
    made = []
    import MaterialX as mx

    own = [c for c in doc.getChildren() if isinstance(c, mx.NodeGraph) and not c.getNodeDefString()]
    outputs = [(ng, o) for ng in own for o in ng.getOutputs()]
    outputs += [(None, o) for o in doc.getOutputs()]
    for ng, out in outputs:
        t = out.getType()
        tag = f"{ng.getName()}_{out.getName()}" if ng is not None else out.getName()
        base = doc.createValidChildName(f"fid_{tag}")

        def connect(inp, ng=ng, out=out):
            if ng is not None:
                inp.setNodeGraphString(ng.getName())
                inp.setOutputString(out.getName())
            elif out.getNodeName():
                inp.setNodeName(out.getNodeName())
                if out.getOutputString():
                    inp.setOutputString(out.getOutputString())
            else:
                return False
            return True

        if t == "surfaceshader":
            shader = None
        elif t in ("BSDF", "EDF"):
            shader = doc.addNode("surface", base + "_surface", "surfaceshader")
            if not connect(shader.addInput("bsdf" if t == "BSDF" else "edf", t)):
                doc.removeNode(shader.getName())
                continue
        elif t in WRAP_UNLIT:
            shader = doc.addNode("surface_unlit", base + "_unlit", "surfaceshader")
            emission = shader.addInput("emission_color", "color3")
            if t == "color3":
                ok = connect(emission)
            else:
                conv = doc.addNode("convert", base + "_convert", "color3")
                ok = connect(conv.addInput("in", t)) and conv.getNodeDef() is not None
                emission.setNodeName(conv.getName())
                if not ok:
                    doc.removeNode(conv.getName())
            if not ok:
                doc.removeNode(shader.getName())
                continue
        else:
            continue
        mat = doc.addMaterialNode(base)
        inp = mat.addInput("surfaceshader", "surfaceshader")
        if shader is None:
            if not connect(inp):
                doc.removeNode(mat.getName())
                continue
        else:
            inp.setNodeName(shader.getName())
        made.append((mat.getName(), f"{ng.getName() + '/' if ng is not None else ''}{out.getName()}"))
    return made


def missing_files(doc, material) -> list[str]:
    """Image files a material of a flattened document reads that do not exist (UDIM sets by their first tile):
    the file inputs of the nodes upstream of it and of every node graph it reads, whole."""
    import MaterialX as mx

    seen, files, todo = set(), [], [material]
    while todo:
        elem = todo.pop()
        if elem is None or elem.getNamePath() in seen:
            continue
        seen.add(elem.getNamePath())
        for sub in ([elem] + list(elem.traverseTree())) if isinstance(elem, mx.NodeGraph) else [elem]:
            if not isinstance(sub, mx.Node):
                continue
            for inp in sub.getInputs():
                if inp.getType() == "filename" and inp.getValueString():
                    files.append(inp.getResolvedValueString())
                if inp.getNodeName() and not isinstance(elem, mx.NodeGraph):
                    todo.append(sub.getParent().getNode(inp.getNodeName()))
                if inp.getNodeGraphString():
                    todo.append(doc.getNodeGraph(inp.getNodeGraphString()))
    missing = []
    for f in files:
        f = f.replace("<UDIM>", "1001")
        if os.path.basename(f).startswith("invalid."):
            continue  # image_default.mtlx: a missing file on purpose (the node's default value is the test)
        if not os.path.isabs(f) or not os.path.exists(f):  # flattenFilenames made every found file absolute
            missing.append(os.path.basename(f))
    return sorted(set(missing))


def prepare(path: str, root: str, out_dir: str, rel: str, graphs: bool):
    """The document as both renderers read it: its file names made absolute against its folder and the checkout's
    root (the search path MaterialX's test renderers use), XIncludes inlined, and with ``graphs`` its graph
    outputs wrapped as materials (:func:`wrap_outputs`). Returns (written path, document, wrapped outputs)."""
    import MaterialX as mx

    doc = mx.createDocument()
    mx.readFromXmlFile(doc, path, mx.FileSearchPath(os.path.dirname(path)))
    search = mx.FileSearchPath(os.path.dirname(path))
    search.append(root)
    mx.flattenFilenames(doc, search)
    doc.setDataLibrary(_library())
    wrapped = wrap_outputs(doc) if graphs else []
    dest = os.path.join(out_dir, "docs", rel)
    os.makedirs(os.path.dirname(dest), exist_ok=True)
    opts = mx.XmlWriteOptions()
    opts.writeXIncludeEnable = False
    mx.writeToXmlFile(doc, dest, opts)
    return dest, doc, wrapped


#: TestSuite folders that hold no renderable materials of their own (options, light rigs).
SKIP = ("TestSuite/_options.mtlx", "TestSuite/lights/")


def corpus(root: str, out_dir: str, only=(), graphs: bool = True) -> list[dict]:
    """The materials of the checkout's Examples and TestSuite documents (one dict per material), and with
    ``graphs`` the TestSuite's graph outputs wrapped as materials (family ``graph:<folder>``)."""
    import MaterialX as mx

    lib = _library()
    base = os.path.join(root, "resources", "Materials")
    rows = []
    for path in sorted(glob.glob(os.path.join(base, "Examples", "**", "*.mtlx"), recursive=True) +
                       sorted(glob.glob(os.path.join(base, "TestSuite", "**", "*.mtlx"), recursive=True))):
        rel = os.path.relpath(path, base)
        if rel.startswith(SKIP) or "/libraries/" in rel:
            continue  # definitions included by other documents
        if only and not any(o in rel for o in only) and not any(":" in o for o in only):
            continue
        try:
            dest, doc, wrapped = prepare(path, root, out_dir, rel, graphs and rel.startswith("TestSuite/"))
        except Exception as exc:  # noqa: BLE001
            rows.append(dict(file=rel, material=None, family="?", unmeasured=f"does not parse: {exc}"[:200]))
            continue
        doc.setDataLibrary(lib)
        wrapped_names = dict(wrapped)
        folder = "/".join(rel.split("/")[1:3]) if rel.count("/") >= 2 else rel.split("/")[1]
        for m in doc.getMaterialNodes():
            shader = None
            for i in m.getInputs():
                if i.getType() == "surfaceshader":
                    shader = i.getConnectedNode()
            if m.getName() in wrapped_names:
                fam, kind = f"graph:{folder}", "graph"
            else:
                fam, kind = family_of(rel, shader), "material"
            row = dict(file=rel, path=dest, material=m.getName(), family=fam, kind=kind,
                       output=wrapped_names.get(m.getName()),
                       shader=shader.getCategory() if shader is not None else None)
            if only and not any(o in f"{rel}:{m.getName()}" for o in only):
                continue
            gone = missing_files(doc, m)
            if shader is None and kind == "material":
                row["unmeasured"] = "no surface shader connected"
            elif gone:
                row["unmeasured"] = f"images absent from the checkout: {', '.join(gone)}"
            rows.append(row)
    return rows


# ---------------------------------------------------------------------------------------------- OSL reference
INCLUDE_DIR_PARTS = ("libraries", "stdlib", "genosl", "include")

#: Cycles' OSL globals differ from MaterialX's test renderer (module docstring): the default UV set and tangent come
#: in as two shader parameters the reference's material links (a UV Map node and a UV-map Tangent node): Cycles
#: loads a mesh attribute only for the nodes that ask for it, so a script's getattribute("geom:uv") finds nothing.
#: Inside the generated functions (node-graph implementations) the parameters are out of scope: there the sphere's
#: own parameterisation (u the azimuth / 2π, v the polar angle / π from −Z; the tangent along increasing u).
CYCLES_PARAMS = "\n    vector mx_uvmap = vector(0.0, 0.0, 0.0),\n    vector mx_tangent = vector(1.0, 0.0, 0.0),"
CYCLES_PRELUDE = """
vector2 mx_cycles_sphere_uv() {
    point o = transform("object", P);
    float a = atan2(o[1], o[0]) / (2.0 * M_PI);
    return vector2(a < 0.0 ? a + 1.0 : a, acos(clamp(-o[2] / max(length(o), 1e-9), -1.0, 1.0)) / M_PI);
}
vector mx_cycles_sphere_tangent() {
    point o = transform("object", P);
    vector t = vector(-o[1], o[0], 0.0);
    if (length(t) < 1e-6) t = vector(1.0, 0.0, 0.0);
    return normalize(transform("object", "world", t));
}
"""


def _inline(src: str, inc: str, seen: set) -> str:
    out = []
    for line in src.splitlines():
        m = re.match(r'\s*#include\s+"([^"]+)"', line)
        if m and os.path.exists(os.path.join(inc, m.group(1))):
            if m.group(1) not in seen:
                seen.add(m.group(1))
                out.append(_inline(open(os.path.join(inc, m.group(1))).read(), inc, seen))
            continue
        out.append(line)
    return "\n".join(out)


def osl_source(path: str, material: str) -> str:
    """MaterialX's OSL for one material of a document, adapted to Cycles (module docstring)."""
    import MaterialX as mx
    from MaterialX import PyMaterialXGenOsl as gen_osl
    from MaterialX import PyMaterialXGenShader as gen_shader

    lib = _library()
    doc = mx.createDocument()
    mx.readFromXmlFile(doc, path, mx.FileSearchPath(os.path.dirname(path)))
    doc.setDataLibrary(lib)  # file names are absolute already (:func:`prepare`)
    gen = gen_osl.OslShaderGenerator.create()
    ctx = gen_shader.GenContext(gen)
    ctx.registerSourceCodeSearchPath(mx.getDefaultDataSearchPath())
    opts = ctx.getOptions()
    opts.targetColorSpaceOverride = "lin_rec709"
    opts.fileTextureVerticalFlip = True
    opts.targetDistanceUnit = "meter"
    cms = gen_shader.DefaultColorManagementSystem.create(gen.getTarget())
    cms.loadLibrary(lib)
    gen.setColorManagementSystem(cms)
    units = gen_shader.UnitSystem.create(gen.getTarget())
    registry = mx.UnitConverterRegistry.create()
    registry.addUnitConverter(lib.getUnitTypeDef("distance"),
                              mx.LinearUnitConverter.create(lib.getUnitTypeDef("distance")))
    registry.addUnitConverter(lib.getUnitTypeDef("angle"), mx.LinearUnitConverter.create(lib.getUnitTypeDef("angle")))
    units.loadLibrary(lib)
    units.setUnitConverterRegistry(registry)
    gen.setUnitSystem(units)
    node = doc.getNode(material)
    shader = gen.generate(material, node, ctx)
    src = shader.getSourceCode(gen_shader.PIXEL_STAGE)
    inc = os.path.join(os.path.dirname(mx.__file__), *INCLUDE_DIR_PARTS)
    src = _inline(src, inc, set()).replace("#pragma once", "")
    # after the includes' definitions, before the first use: just before the first function using vector2
    src = src.replace("#define M_FLOAT_EPS", CYCLES_PRELUDE + "\n#define M_FLOAT_EPS", 1)
    head = re.search(r"\nshader\s+\w+\s*(\[\[.*?\]\])?\s*\(", src, re.S)
    if head is not None:  # the shader body reads the parameters, the functions before it the sphere's own
        body, funcs = src[head.end():], src[:head.end()]
        funcs = re.sub(r"vector2\(\s*u\s*,\s*v\s*\)", "mx_cycles_sphere_uv()", funcs)
        funcs = re.sub(r"normalize\(\s*dPdu\s*\)", "mx_cycles_sphere_tangent()", funcs)
        body = re.sub(r"vector2\(\s*u\s*,\s*v\s*\)", "vector2(mx_uvmap[0], mx_uvmap[1])", body)
        body = re.sub(r"normalize\(\s*dPdu\s*\)", "normalize(mx_tangent)", body)
        src = funcs + CYCLES_PARAMS + body
    src = src.replace('"ggx"', '"multi_ggx"')  # MaterialX's GGX is energy-compensated; Cycles' only as multi_ggx
    # layer(bsdf, vdf) (a transmissive surface over its interior medium): Cycles' OSL renders it black; the surface
    # alone is what both renderers can draw (the medium's absorption is measured by neither)
    for vdf in re.findall(r"\bVDF\s+(\w+)\s*=", src):
        src = re.sub(r"layer\(\s*(\w+)\s*,\s*" + vdf + r"\s*\)", r"\1", src)
    return cycles_closures(src)


def cycles_closures(src: str) -> str:
    """MaterialX's subsurface and translucent closures as Blender 5.0's Cycles renders them right.

    Its ``subsurface_bssrdf`` set-up neither weights the closure by its albedo (its random walk divides the albedo
    out again: every colour rendered white) nor reads the radius as the mean free path (the random walk scales it
    by 1/(4π)); Cycles fixed both after 5.0 (commit e5f4164, "Removing legacy scaling of the subsurface radius to
    match MaterialX", which also weights by the albedo). Here: ``albedo * subsurface_bssrdf(N, albedo, radius·4π,
    …)``, which renders as Cycles' own Subsurface Scattering node (random walk, IOR 1.4, roughness 1) of that
    colour and radius·4π. ``translucent_bsdf`` is not registered in 5.0 (black): ``albedo * translucent(N)``, the
    same Lambertian transmission."""
    src = re.sub(r"\bsubsurface_bssrdf\(\s*N\s*,\s*albedo\s*,\s*radius\s*,",
                 "albedo * subsurface_bssrdf(N, albedo, radius * (4.0 * M_PI),", src)
    return re.sub(r"\btranslucent_bsdf\(\s*(\w+)\s*,\s*(\w+)\s*\)", r"(\2) * translucent(\1)", src)


def reference_jobs(rows, spec, refs_dir, spp: int, spp_unlit: int):
    """For each measurable row: its OSL source written once by content hash, and the EXR path of its reference
    (rendered when missing)."""
    os.makedirs(refs_dir, exist_ok=True)
    jobs = []
    for row in rows:
        if "unmeasured" in row:
            continue
        try:
            src = osl_source(row["path"], row["material"])
        except Exception as exc:  # noqa: BLE001 — a row, the survey goes on
            row["ref_error"] = f"OSL generation: {type(exc).__name__}: {exc}"[:300]
            continue
        n = spp_unlit if row.get("shader") == "surface_unlit" else spp
        key = hashlib.sha256((src + json.dumps(dict(spec, spp=n), sort_keys=True)).encode()).hexdigest()[:20]
        osl = os.path.join(refs_dir, f"{key}.osl")
        if not os.path.exists(osl):
            with open(osl, "w") as f:
                f.write(src)
        row["ref"] = os.path.join(refs_dir, f"{key}.exr")
        if os.path.exists(row["ref"] + ".fail"):
            row["ref_error"] = "the OSL shader does not compile in Cycles"
        elif not os.path.exists(row["ref"]):
            jobs.append(dict(osl=osl, out=row["ref"], spp=spp_unlit if row.get("shader") == "surface_unlit" else spp))
    return jobs


def render_references(jobs, spec, spp: int, log=None) -> None:
    """Render missing references in a bpy process (tools/fidelity_mtlx_cycles.py); a job whose shader crashes
    Cycles' OSL compiler (the process dies, its ``.started`` marker left) is marked ``.fail`` and the rest go on in
    a new process."""
    pts, counts, idx, uvs, nrm = sphere_mesh()
    mesh = dict(points=pts.tolist(), counts=counts, indices=idx, uvs=uvs.tolist(), normals=nrm.tolist())
    todo = [j for j in jobs if not os.path.exists(j["out"] + ".fail")]
    while todo:
        job_file = os.path.join(os.path.dirname(todo[0]["out"]), f"jobs-{os.getpid()}.json")
        with open(job_file, "w") as f:
            json.dump(dict(jobs=todo, spec=spec, spp=spp, mesh=mesh), f)
        cmd = [sys.executable, os.path.join(HERE, "fidelity_mtlx_cycles.py"), job_file]
        subprocess.run(cmd, check=False, stdout=log or subprocess.DEVNULL, stderr=subprocess.STDOUT)
        os.remove(job_file)
        for j in todo:
            if os.path.exists(j["out"] + ".started"):
                os.replace(j["out"] + ".started", j["out"] + ".fail")
        left = [j for j in todo if not os.path.exists(j["out"]) and not os.path.exists(j["out"] + ".fail")]
        if len(left) == len(todo):
            break
        todo = left


# ---------------------------------------------------------------------------------------------- the measure
def srgb_linear_to_lab(rgb) -> np.ndarray:
    """Linear Rec.709 -> CIE L*a*b* (D65 white, Y = 1 at L* = 100)."""
    m = np.array([[0.4124564, 0.3575761, 0.1804375], [0.2126729, 0.7151522, 0.0721750],
                  [0.0193339, 0.1191920, 0.9503041]])
    xyz = m @ np.asarray(rgb, np.float64)
    white = m @ np.ones(3)
    t = xyz / white
    d = 6 / 29
    f = np.where(t > d ** 3, np.cbrt(t), t / (3 * d * d) + 4 / 29)
    return np.array([116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])])


def delta_e2000(lab1, lab2) -> float:
    """CIEDE2000 (Sharma, Wu & Dalal 2005)."""
    L1, a1, b1 = lab1
    L2, a2, b2 = lab2
    c1, c2 = math.hypot(a1, b1), math.hypot(a2, b2)
    cm = (c1 + c2) / 2
    g = 0.5 * (1 - math.sqrt(cm ** 7 / (cm ** 7 + 25 ** 7)))
    a1p, a2p = (1 + g) * a1, (1 + g) * a2
    c1p, c2p = math.hypot(a1p, b1), math.hypot(a2p, b2)
    h1p = math.degrees(math.atan2(b1, a1p)) % 360
    h2p = math.degrees(math.atan2(b2, a2p)) % 360
    dL = L2 - L1
    dC = c2p - c1p
    if c1p * c2p == 0:
        dh = 0.0
    elif abs(h2p - h1p) <= 180:
        dh = h2p - h1p
    elif h2p - h1p > 180:
        dh = h2p - h1p - 360
    else:
        dh = h2p - h1p + 360
    dH = 2 * math.sqrt(c1p * c2p) * math.sin(math.radians(dh / 2))
    Lm = (L1 + L2) / 2
    cmp_ = (c1p + c2p) / 2
    if c1p * c2p == 0:
        hm = h1p + h2p
    elif abs(h1p - h2p) <= 180:
        hm = (h1p + h2p) / 2
    elif h1p + h2p < 360:
        hm = (h1p + h2p + 360) / 2
    else:
        hm = (h1p + h2p - 360) / 2
    t = (1 - 0.17 * math.cos(math.radians(hm - 30)) + 0.24 * math.cos(math.radians(2 * hm))
         + 0.32 * math.cos(math.radians(3 * hm + 6)) - 0.20 * math.cos(math.radians(4 * hm - 63)))
    d_theta = 30 * math.exp(-(((hm - 275) / 25) ** 2))
    rc = 2 * math.sqrt(cmp_ ** 7 / (cmp_ ** 7 + 25 ** 7))
    sl = 1 + 0.015 * (Lm - 50) ** 2 / math.sqrt(20 + (Lm - 50) ** 2)
    sc = 1 + 0.045 * cmp_
    sh = 1 + 0.015 * cmp_ * t
    rt = -math.sin(math.radians(2 * d_theta)) * rc
    return math.sqrt((dL / sl) ** 2 + (dC / sc) ** 2 + (dH / sh) ** 2 + rt * (dC / sc) * (dH / sh))


def sphere_mask(a_ref: np.ndarray, a_ours: np.ndarray) -> np.ndarray:
    m = (a_ref >= 0.999) & (a_ours >= 0.999)
    p = np.pad(m, 1)
    return m & p[:-2, 1:-1] & p[2:, 1:-1] & p[1:-1, :-2] & p[1:-1, 2:]


def compare(ref_rgba: np.ndarray, ours_rgba: np.ndarray) -> dict:
    mask = sphere_mask(ref_rgba[..., 3], ours_rgba[..., 3])
    if mask.sum() < 10:
        return dict(error="the sphere covers fewer than 10 pixels in one of the renders")
    mr = ref_rgba[..., :3][mask].mean(axis=0)
    mo = ours_rgba[..., :3][mask].mean(axis=0)
    de = delta_e2000(srgb_linear_to_lab(mr), srgb_linear_to_lab(mo))
    return dict(de=round(float(de), 2), ref_mean=[round(float(x), 4) for x in mr],
                ours_mean=[round(float(x), 4) for x in mo], pixels=int(mask.sum()))


def read_rgba(path: str) -> np.ndarray:
    """An image as (H, W, 4) float32 values as stored (no colour conversion); RGB gets alpha 1, a deep EXR
    (arnold-usd's test_1306) its samples composited front to back."""
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(path)
    if buf.spec().deep:
        buf = oiio.ImageBufAlgo.flatten(buf)
    px = buf.get_pixels(oiio.FLOAT)
    if px is None or px.size == 0:
        raise ValueError(f"{path}: unreadable ({oiio.geterror()})")
    px = np.asarray(px, np.float32)
    if px.shape[2] == 3:
        px = np.concatenate([px, np.ones(px.shape[:2] + (1,), np.float32)], axis=2)
    return px[..., :4]


def render_ours(stage_path: str, size: int, aa: int):
    import tracer
    from usd_io.reader import load_stage

    scene, info = load_stage(stage_path, width=size, height=size)
    settings = tracer.RenderSettings(width=size, height=size, samples=aa, transparent=True, sky_samples=4,
                                     max_depth=8, terminal_rays=True)
    image = tracer.render(scene, settings)
    return np.asarray(image.rgba, np.float32), info


# ---------------------------------------------------------------------------------------------- output
def _tonemap(rgb):
    return np.clip(np.clip(rgb, 0, None) ** (1 / 2.2), 0, 1)


def write_png(path: str, rgb01: np.ndarray) -> None:
    import OpenImageIO as oiio

    os.makedirs(os.path.dirname(path), exist_ok=True)
    h, w = rgb01.shape[:2]
    out = oiio.ImageBuf(oiio.ImageSpec(w, h, 3, oiio.UINT8))
    out.set_pixels(oiio.ROI(0, w, 0, h), (np.clip(rgb01, 0, 1) * 255 + 0.5).astype(np.uint8))
    out.write(path)


def contact_sheet(path: str, rows, per_row: int = 8, tile: int = 48, limit: int = 0) -> None:
    """Pairs (reference | ours) of the measured rows, worst ΔE first, small: one tile per image (the first
    ``limit`` pairs when ``limit`` > 0); a red bar over a pair beyond ΔE 5, green within."""
    import OpenImageIO as oiio

    done = [r for r in rows if r.get("de") is not None and r.get("_ref") is not None]
    done.sort(key=lambda r: -r["de"])
    if limit > 0:
        done = done[:limit]
    if not done:
        return
    n = len(done)
    cols = per_row
    lines = (n + cols - 1) // cols
    pad = 2
    w = cols * (2 * tile + pad * 2)
    h = lines * (tile + pad * 2)
    sheet = np.full((h, w, 3), 0.12, np.float32)

    def shrink(img):
        s = img.shape[0] // tile
        img = img[:s * tile, :s * tile, :3]
        return img.reshape(tile, s, tile, s, 3).mean(axis=(1, 3))

    for k, r in enumerate(done):
        y, x = divmod(k, cols)
        y0, x0 = y * (tile + 2 * pad) + pad, x * (2 * tile + 2 * pad) + pad
        sheet[y0:y0 + tile, x0:x0 + tile] = _tonemap(shrink(r["_ref"]))
        sheet[y0:y0 + tile, x0 + tile:x0 + 2 * tile] = _tonemap(shrink(r["_ours"]))
        bad = r["de"] > WITHIN
        sheet[y0 - pad + 1:y0, x0:x0 + 2 * tile] = (0.9, 0.2, 0.2) if bad else (0.2, 0.8, 0.3)
    spec = oiio.ImageSpec(w, h, 3, oiio.UINT8)
    out = oiio.ImageBuf(spec)
    out.set_pixels(oiio.ROI(0, w, 0, h), (sheet * 255 + 0.5).astype(np.uint8))
    out.write(path)


def summarise(rows) -> str:
    """Per family (materials) and per test-suite folder (graph outputs): how many, how many measured, how many
    within ΔE00 5, the median ΔE00; then the shares."""
    lines = []
    for kind, title in (("material", "materials"), ("graph", "graph outputs")):
        part = [r for r in rows if r.get("kind", "material") == kind]
        if not part:
            continue
        lines.append(f"{title:28s} {'count':>5s} {'measured':>8s} {'<=5':>5s} {'median dE00':>11s}")
        for fam in sorted({r["family"] for r in part}) + ["all"]:
            rs = [r for r in part if fam in ("all", r["family"])]
            m = [r["de"] for r in rs if r.get("de") is not None]
            med = f"{np.median(m):.1f}" if m else "-"
            lines.append(f"{fam:28s} {len(rs):5d} {len(m):8d} {sum(d <= WITHIN for d in m):5d} {med:>11s}")
        ok = [r for r in part if r.get("de") is not None]
        if ok:
            n = sum(r["de"] <= WITHIN for r in ok)
            lines.append(f"{title} within dE00 5: {n} of {len(ok)} measured ({100 * n / len(ok):.0f} %)")
        lines.append("")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="fidelity.py materialx", description=__doc__.split("\n\n")[0])
    p.add_argument("materialx")
    p.add_argument("--out", default="/tmp/fidelity_mtlx")
    p.add_argument("--refs", default=os.path.join(ROOT, ".cache", "fidelity-mtlx-refs"))
    p.add_argument("--only", default="", help="comma-separated substrings of 'file:material'")
    p.add_argument("--size", type=int, default=64)
    p.add_argument("--aa", type=int, default=3)
    p.add_argument("--spp", type=int, default=128, help="Cycles samples per pixel of the references")
    p.add_argument("--spp-unlit", type=int, default=16, help="... of surface_unlit materials (emission only)")
    p.add_argument("--jsonl", default=None)
    p.add_argument("--sheet", default=None, help="contact sheet PNG (reference | ours, worst first)")
    p.add_argument("--sheet-tile", type=int, default=48, help="contact sheet tile size in pixels")
    p.add_argument("--sheet-limit", type=int, default=0, help="at most this many pairs on the sheet (0: all)")
    p.add_argument("--sheet-materials", action="store_true", help="the sheet shows materials only, not graphs")
    p.add_argument("--list", action="store_true")
    p.add_argument("--no-graphs", action="store_true", help="materials only (not the TestSuite's graph outputs)")
    args = p.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    rows = corpus(args.materialx, args.out, [o for o in args.only.split(",") if o], not args.no_graphs)
    if args.list:
        for r in rows:
            print(r["family"], r["file"], r["material"], r.get("unmeasured", ""))
        return 0
    os.makedirs(args.out, exist_ok=True)
    os.makedirs(args.refs, exist_ok=True)
    dome = write_dome(os.path.join(args.refs, "dome.exr"))
    spec = scene_spec(args.size, os.path.basename(dome))
    jobs = reference_jobs(rows, spec, args.refs, args.spp, args.spp_unlit)
    t0 = time.perf_counter()
    with open(os.path.join(args.out, "cycles.log"), "w") as log:
        render_references(jobs, dict(spec, dome=dome), args.spp, log)
    print(f"{len(jobs)} references rendered in {time.perf_counter() - t0:.0f} s", flush=True)
    stages = os.path.join(args.out, "stages")
    os.makedirs(stages, exist_ok=True)
    for k, row in enumerate(rows):
        name = f"{row['file']}:{row['material']}"
        if "unmeasured" not in row and "ref_error" not in row:
            start = time.perf_counter()
            try:
                ref = read_rgba(row["ref"])
                stage = write_stage(os.path.join(stages, f"{k:03d}.usda"), row["path"], row["material"], dome)
                ours, info = render_ours(stage, args.size, args.aa)
                row.update(compare(ref, ours))
                row["warnings"] = list(info.warnings)
                row["_ref"], row["_ours"] = ref, ours
                pair = os.path.join(args.out, "pairs", re.sub(r"[^\w.-]+", "_", name) + ".png")
                write_png(pair, np.concatenate([_tonemap(ref[..., :3]), _tonemap(ours[..., :3])], axis=1))
                row["pair"] = os.path.relpath(pair, args.out)
            except Exception as exc:  # noqa: BLE001 — a row per failure
                row["error"] = f"{type(exc).__name__}: {exc}"[:300]
            row["seconds"] = round(time.perf_counter() - start, 1)
        shown = (f"dE00 {row['de']:6.2f}" if row.get("de") is not None else
                 row.get("unmeasured") or row.get("ref_error") or row.get("error") or "?")
        print(f"{row['family']:18s} {name:80s} {shown}", flush=True)
        if args.jsonl:
            with open(args.jsonl, "a") as f:
                f.write(json.dumps({k: v for k, v in row.items() if not k.startswith("_") and k != "path"}) + "\n")
    print(summarise(rows))
    if args.sheet:
        shown = [r for r in rows if not args.sheet_materials or r.get("kind") == "material"]
        contact_sheet(args.sheet, shown, per_row=10, tile=args.sheet_tile, limit=args.sheet_limit)
    return 0


if __name__ == "__main__":
    sys.path.insert(0, ROOT)
    sys.exit(main())

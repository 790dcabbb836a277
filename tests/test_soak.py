"""tools/soak.py: a clean tiny corpus gives 0 of every count (exit 0); a render child that segfaults is counted as a
crash with its signal's name (exit 1); bad input is one line and exit 2."""

from __future__ import annotations

import json
import os
import shlex
import subprocess
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SOAK = os.path.join(ROOT, "tools", "soak.py")

CAMERA_AND_LIGHT = """
    def Camera "Camera"
    {
        float focalLength = 35
        float horizontalAperture = 36
        double3 xformOp:translate = (0, -6, 1)
        float3 xformOp:rotateXYZ = (85, 0, 0)
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]
    }

    def SphereLight "Light"
    {
        float inputs:intensity = 300
        float inputs:radius = 0.2
        double3 xformOp:translate = (2, -3, 4)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
"""

SPHERE = """#usda 1.0
(
    defaultPrim = "World"
    upAxis = "Z"
)

def Xform "World"
{
    def Sphere "Ball"
    {
        double radius = 1
        color3f[] primvars:displayColor = [(0.8, 0.3, 0.1)]
    }
""" + CAMERA_AND_LIGHT + "}\n"

# A quad with a checker-alpha texture as a cut-out (opacityThreshold) in front of three instanced spheres.
CUTOUT_INSTANCES = """#usda 1.0
(
    defaultPrim = "World"
    upAxis = "Z"
)

def Xform "World"
{
    def Material "Cut"
    {
        token outputs:surface.connect = </World/Cut/Surface.outputs:surface>

        def Shader "Surface"
        {
            uniform token info:id = "UsdPreviewSurface"
            color3f inputs:diffuseColor = (0.2, 0.6, 0.2)
            float inputs:opacity.connect = </World/Cut/Tex.outputs:a>
            float inputs:opacityThreshold = 0.5
            token outputs:surface
        }

        def Shader "St"
        {
            uniform token info:id = "UsdPrimvarReader_float2"
            string inputs:varname = "st"
            float2 outputs:result
        }

        def Shader "Tex"
        {
            uniform token info:id = "UsdUVTexture"
            asset inputs:file = @./checker.png@
            float2 inputs:st.connect = </World/Cut/St.outputs:result>
            float outputs:a
            float3 outputs:rgb
        }
    }

    def Mesh "Leaf" (
        prepend apiSchemas = ["MaterialBindingAPI"]
    )
    {
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [(-2, -2, -1), (2, -2, -1), (2, -2, 3), (-2, -2, 3)]
        texCoord2f[] primvars:st = [(0, 0), (1, 0), (1, 1), (0, 1)] (
            interpolation = "vertex"
        )
        rel material:binding = </World/Cut>
        uniform token subdivisionScheme = "none"
    }

    def PointInstancer "Balls"
    {
        point3f[] positions = [(-1.5, 0, 0), (0, 0.5, 0), (1.5, 0, 0)]
        int[] protoIndices = [0, 0, 0]
        rel prototypes = </World/Balls/Protos/Ball>

        def Scope "Protos"
        {
            def Sphere "Ball"
            {
                double radius = 0.6
                color3f[] primvars:displayColor = [(0.7, 0.7, 0.9)]
            }
        }
    }
""" + CAMERA_AND_LIGHT + "}\n"


def write_corpus(folder) -> list[str]:
    import OpenImageIO as oiio

    folder.mkdir()
    y, x = np.mgrid[0:32, 0:32]
    checker = np.ones((32, 32, 4), np.uint8) * 200
    checker[..., 3] = np.where(((x // 8) + (y // 8)) % 2 == 0, 255, 0)
    out = oiio.ImageOutput.create(str(folder / "checker.png"))
    out.open(str(folder / "checker.png"), oiio.ImageSpec(32, 32, 4, oiio.UINT8))
    out.write_image(checker)
    out.close()
    (folder / "sphere.usda").write_text(SPHERE)
    (folder / "cutout_instances.usda").write_text(CUTOUT_INSTANCES)
    return [str(folder / "sphere.usda"), str(folder / "cutout_instances.usda")]


def soak(*args, timeout=300):
    return subprocess.run([sys.executable, SOAK, *map(str, args)], capture_output=True, text=True, timeout=timeout,
                          env=dict(os.environ, PYTHONPATH=ROOT))


def test_clean_corpus_counts_nothing(tmp_path):
    write_corpus(tmp_path / "corpus")
    keep = tmp_path / "keep"
    r = soak(tmp_path / "corpus", "--runs", 2, "--threads", "1,2", "--width", 32, "--no-hog",
             "--json", tmp_path / "out.json", "--keep", keep)
    assert r.returncode == 0, r.stdout + r.stderr
    d = json.loads((tmp_path / "out.json").read_text())
    assert d["totals"] == {"stages": 2, "renders": 8, "crashes": 0, "hangs": 0, "errors": 0, "nonfinite": 0,
                           "unequal": 0, "signals": {}}
    assert [os.path.basename(s["stage"]) for s in d["stages"]] == ["cutout_instances.usda", "sphere.usda"]
    # The pictures are not blank: the comparison compared something (and the cut-out lets the balls through).
    import OpenImageIO as oiio

    for name in ("sphere", "cutout_instances"):
        px = oiio.ImageInput.open(str(keep / f"{name}.r1.t2.exr"))
        a = px.read_image(oiio.FLOAT)
        px.close()
        assert a.shape[1] == 32 and np.ptp(a[..., :3]) > 0.05
    assert "crashes 0" in r.stdout and "unequal repeats 0" in r.stdout


def test_crash_is_counted_with_its_signal(tmp_path):
    stages = write_corpus(tmp_path / "corpus")
    crash = f"{shlex.quote(sys.executable)} -c 'import os, signal; os.kill(os.getpid(), signal.SIGSEGV)'"
    r = soak(stages[0], "--runs", 2, "--threads", "1,2", "--width", 32, "--no-hog", "--command", crash,
             "--json", tmp_path / "out.json")
    assert r.returncode == 1, r.stdout + r.stderr
    d = json.loads((tmp_path / "out.json").read_text())
    assert d["totals"]["crashes"] == 4 and d["totals"]["signals"] == {"SIGSEGV": 4}
    assert all(row["count"] == "crashes" and row["signal"] == "SIGSEGV" for row in d["stages"][0]["rows"])
    assert "SIGSEGV" in r.stdout


def test_hang_is_counted_and_killed(tmp_path):
    stages = write_corpus(tmp_path / "corpus")
    sleep = f"{shlex.quote(sys.executable)} -c 'import time; time.sleep(60)'"
    r = soak(stages[0], "--runs", 1, "--threads", "1", "--no-hog", "--timeout", 0.5, "--command", sleep,
             "--json", tmp_path / "out.json", timeout=30)
    assert r.returncode == 1
    assert json.loads((tmp_path / "out.json").read_text())["totals"]["hangs"] == 1


def test_unequal_pictures_are_counted(monkeypatch):
    monkeypatch.syspath_prepend(os.path.join(ROOT, "tools"))
    import soak as soak_mod

    ref = np.zeros((4, 4, 4), np.float32)
    row = {"returncode": 0, "signal": None, "hang": False}
    other = ref.copy()
    other[1, 2, 0] = 1e-7
    monkeypatch.setattr(soak_mod, "read_image", lambda path: other)
    soak_mod.check_render(row, "x.exr", ref)
    assert row["unequal"] == {"pixels": 1, "max_abs": float(np.float32(1e-7))}
    assert soak_mod.classify(row) == "unequal"


def test_bad_input_is_one_line_and_exit_2(tmp_path):
    for args in ([tmp_path / "missing"], [tmp_path, "--threads", "0"], [tmp_path]):
        r = soak(*args)
        assert r.returncode == 2 and r.stderr.count("\n") == 1 and r.stdout == "", (args, r.stderr)

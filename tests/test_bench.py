"""Smoke test of the benchmark harness (bench/): output format only, no timing assertions.

One quick run on the tiny scene (64×36, one run, Cycles at 4 spp) checks that every peer either reports numbers or
says why it was skipped, that the ray counts add up, and that the markdown report has its sections.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench import harness, povray, scenes  # noqa: E402


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    work = tmp_path_factory.mktemp("bench")
    out = work / "report.md"
    proc = subprocess.run([sys.executable, "-m", "bench", "--quick", "--out", str(out), "--workdir", str(work)],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout, out.read_text(), work


def test_quick_run_prints_every_peer(quick):
    stdout, _, _ = quick
    assert "### tiny" in stdout
    for peer in ("whitted (ours", "POV-Ray", "Cycles", "raw embreex replay"):
        assert re.search(r"^\| " + re.escape(peer), stdout, re.M), f"no row for {peer}"
    if shutil.which("povray") is None:
        assert "skipping POV-Ray" in stdout and "povray not installed" in stdout
    else:
        assert re.search(r"^\| POV-Ray [\d.]+\S* \(AA off\) \| [\d.]+ s \| 1 \| [\d.]+×", stdout, re.M)
    assert re.search(r"^\| Cycles [\d.]+ \(4 spp\) \| [\d.]+ s \| 1 \| [\d.]+×", stdout, re.M)
    assert re.search(r"End-to-end rays/s vs raw embreex: \*\*\d+ %\*\*", stdout)
    assert re.search(r"intersection [\d.]+ s \(\d+ %\), shading -?[\d.]+ s \(-?\d+ %\), overhead", stdout)
    assert re.search(r"Peak memory at 256×144: [\d.]+ GB", stdout)


def test_quick_run_ray_counts_add_up(quick):
    _, _, work = quick
    import json

    saved = json.loads((work / "results.json").read_text())
    (r,) = saved["results"]
    rays = r["ours"]["rays"]
    per_type = sum(rays[k] for k in ("eye", "shadow", "reflection", "transmission", "sky"))
    assert rays["total"] == per_type > 0
    assert rays["eye"] == 64 * 36  # one eye ray per pixel at 1×1 samples
    # The replay traced exactly the rays the integrator counted.
    assert r["ours"]["replay"]["rays"] == rays["total"] == r["ours"]["recorded_rays"]
    assert r["ours"]["maxrss"] > 10 * 2**20
    assert r["ours"]["triangles"] == scenes.build("tiny").triangle_count


def test_report_markdown_sections(quick):
    _, md, work = quick
    for heading in ("# Benchmarks", "## Machine", "## Results", "### tiny", "## Peak memory at 8K"):
        assert heading in md
    assert re.search(r"- CPU: .+\(\d+ logical cores visible\)", md)
    assert "| renderer | median wall | runs | ratio to ours | rays/s | peak RSS | note |" in md
    # --report-only rebuilds the same tables from results.json.
    again = work / "again.md"
    harness.main(["--quick", "--report-only", "--out", str(again), "--workdir", str(work)])
    strip = lambda s: re.sub(r"Command: .*", "", s)  # noqa: E731
    assert strip(again.read_text()) == strip(md)


def test_bench_scene_matches_example():
    """The bench's whitted scene is the example's 1980 scene: same triangles, materials and lights."""
    sys.path.insert(0, str(ROOT / "examples"))
    import whitted_1980

    ours = scenes.to_tracer(scenes.whitted(), 1920, 1080)
    ex = whitted_1980.build_scene()
    np.testing.assert_allclose(np.sort(ours.vertices[ours.triangles].reshape(-1, 9), axis=0),
                               np.sort(ex.vertices[ex.triangles].reshape(-1, 9), axis=0), atol=1e-5)
    np.testing.assert_allclose(ours.materials.diffuse, ex.materials.diffuse)
    np.testing.assert_allclose(ours.materials.k_m, ex.materials.k_m)
    assert [tuple(light.position) for light in ours.lights] == [tuple(light.position) for light in ex.lights]


def test_povray_sdl_has_same_triangles(tmp_path):
    bs = scenes.build("tiny")
    sdl = povray.write_sdl(bs, str(tmp_path / "tiny.pov"), 64, 36)
    text = Path(sdl).read_text()
    faces = [int(n) for n in re.findall(r"face_indices \{ (\d+),", text)]
    per_mesh = {k: len(m.faces) for k, m in enumerate(bs.meshes)}
    assert faces == list(per_mesh.values())
    assert len(re.findall(r"^object \{ M\d+", text, re.M)) == len(bs.instances)
    assert text.count("light_source") == len(bs.lights)
    assert "reflection { 0, 1 fresnel on }" in text and "ior 1.5" in text


def test_usd_stage_has_same_triangles_and_lights(tmp_path):
    """bench/usd.py's stage, read back by usd_io, holds the bench scene's triangles, lights, mirror and glass."""
    from bench import usd
    from usd_io import load_stage

    bs = scenes.build("tiny")
    path = usd.write_usd(bs, str(tmp_path / "tiny.usda"), 64, 36)
    got, _ = load_stage(path, width=64, height=36)
    ref = scenes.to_tracer(bs, 64, 36)
    assert len(got.triangles) == len(ref.triangles)
    np.testing.assert_allclose(np.sort(got.vertices[got.triangles].reshape(-1, 9), axis=0),
                               np.sort(ref.vertices[ref.triangles].reshape(-1, 9), axis=0), atol=1e-4)
    np.testing.assert_allclose(sorted(tuple(lt.position) for lt in got.lights),
                               sorted(tuple(lt.position) for lt in ref.lights), atol=1e-6)
    np.testing.assert_allclose([lt.intensity for lt in got.lights], [lt.intensity for lt in ref.lights], rtol=1e-4)
    # Every triangle keeps its kind of material: mirror, glass or neither.
    kind = lambda s: np.round(s.materials.k_m[s.material_ids], 3) + 10 * s.materials.transmission[s.material_ids]  # noqa: E731
    np.testing.assert_allclose(np.sort(kind(got)), np.sort(kind(ref)))

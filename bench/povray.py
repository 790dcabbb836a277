"""POV-Ray 3.7 SDL for a :class:`bench.scenes.BenchScene`, and running ``povray``.

Same triangles: every mesh becomes one ``mesh2`` (smooth meshes carry their normals) declared once; every instance
is an ``object`` of it with a ``matrix`` and a texture, so POV-Ray instances where we flatten.

Mapping of our model (``tracer.shading.local``) onto POV-Ray's finish, with our light of intensity I (W/sr) written as a
``light_source`` of colour I/(2π) and ``fade_distance 1 fade_power 2`` (POV-Ray's attenuation 2/(1 + d²) ≈ 2/d², so
a surface facing it receives I/(π d²) = E/π, our Lambert term R_d/π·E):

- diffuse R_d → ``pigment rgb (1−k_m)·R_d``, ``diffuse 1`` (``brilliance 1``: the cosine law)
- ambient L_a·R_d → ``global_settings { ambient_light L_a }``, ``ambient`` = pigment (``ambient 1``)
- Blinn-Phong R_s·(e+8)/(8π)·(n·h)^e → ``specular (1−k_m)·R_s·(e+8)/8 roughness 1/e`` (POV-Ray's specular is Blinn's
  (n·h)^(1/roughness) without our cosine factor, so grazing highlights differ)
- mirror k_m·tint·Reflect → ``reflection { rgb k_m·tint }`` with the local part scaled by (1−k_m) as above
- glass → ``pigment rgbf 1`` (local part 0, as ours), ``reflection { 0, 1 fresnel on } conserve_energy``,
  ``interior { ior η }``.

What differs and cannot be mapped: POV-Ray's shadow rays pass through glass (filtered shadows) where ours stop;
its recursion limit ``max_trace_level`` counts the eye ray (so 9 = our depth 8); ``adc_bailout`` is set to our
``min_weight``.
"""

from __future__ import annotations

import io
import os
import re
import shutil
import subprocess
import tempfile
import time

import numpy as np

from tracer.shading.materials import roughness_to_exponent

from .scenes import BenchScene


def povray_binary() -> str | None:
    """Path of the ``povray`` executable, or None when POV-Ray is not installed."""
    return shutil.which("povray")


def povray_version() -> str:
    exe = povray_binary()
    if exe is None:
        return "not installed"
    p = subprocess.run([exe, "--version"], capture_output=True, text=True)
    m = re.search(r"POV-Ray\s+([\d.]+\S*)", p.stdout + p.stderr)
    return m.group(1) if m else "unknown"


def _v(a) -> str:
    return "<" + ",".join(f"{float(x):.9g}" for x in a) + ">"


def _rows(arr: np.ndarray, fmt: str) -> str:
    """Rows of ``arr`` as ``fmt`` joined by ",\\n" (fast enough for millions of rows)."""
    return ",\n".join(map(fmt.__mod__, map(tuple, arr.tolist())))


def texture(m: dict) -> str:
    """A POV-Ray texture for one of our material dicts."""
    km = float(m.get("k_m", 0.0))
    wt = float(m.get("transmission", 0.0))
    diffuse = np.asarray(m.get("diffuse", (0.8, 0.8, 0.8)), float)
    spec = np.asarray(m.get("specular", (0.0, 0.0, 0.0)), float)
    e = float(m["exponent"]) if "exponent" in m else float(roughness_to_exponent(m.get("roughness", 0.5)))
    local = (1 - km) * (1 - wt)
    tint = np.asarray(m.get("mirror_tint", (1.0, 1.0, 1.0)), float)
    if wt > 0:
        ttint = np.asarray(m.get("transmission_tint", (1.0, 1.0, 1.0)), float)
        pig = f"rgbf <{ttint[0]:.6g},{ttint[1]:.6g},{ttint[2]:.6g},{wt:.6g}>"
    else:
        pig = "rgb " + _v(local * diffuse)
    s = float(np.mean(spec)) * local * (e + 8) / 8
    fin = [f"diffuse {1.0 if local > 0 else 0.0}", "ambient 1" if local > 0 else "ambient 0", "brilliance 1"]
    if s > 0 and e > 0:
        fin.append(f"specular {s:.6g} roughness {1.0 / e:.6g}")
    refl = []
    if km > 0:
        refl.append(f"rgb {_v(km * tint)}")
    if wt > 0:
        fin.append("reflection { 0, 1 fresnel on } conserve_energy")
    elif refl:
        fin.append("reflection { " + refl[0] + " }")
    return f"texture {{ pigment {{ {pig} }} finish {{ {' '.join(fin)} }} }}"


def interior(m: dict) -> str:
    return f"interior {{ ior {float(m.get('ior', 1.5)):.6g} }}" if float(m.get("transmission", 0)) > 0 else ""


def mesh2(mesh, materials) -> str:
    """``mesh2`` body of one mesh; per-face materials become a texture_list."""
    out = io.StringIO()
    v = np.asarray(mesh.vertices, np.float64)
    f = np.asarray(mesh.faces, np.int64)
    out.write(f"mesh2 {{\n vertex_vectors {{ {len(v)},\n{_rows(v, '<%.7g,%.7g,%.7g>')} }}\n")
    if mesh.normals is not None:
        out.write(f" normal_vectors {{ {len(v)},\n{_rows(np.asarray(mesh.normals, float), '<%.6g,%.6g,%.6g>')} }}\n")
    per_face = np.ndim(mesh.material) > 0
    if per_face:
        used = np.unique(mesh.material)
        remap = {int(u): i for i, u in enumerate(used)}
        out.write(f" texture_list {{ {len(used)},\n")
        for u in used:
            out.write("  " + texture(materials[int(u)]) + "\n")
        out.write(" }\n")
        idx = np.array([remap[int(x)] for x in np.asarray(mesh.material)], np.int64)
        out.write(f" face_indices {{ {len(f)},\n{_rows(np.column_stack([f, idx]), '<%d,%d,%d>,%d')} }}\n")
    else:
        out.write(f" face_indices {{ {len(f)},\n{_rows(f, '<%d,%d,%d>')} }}\n")
    out.write("}\n")
    return out.getvalue()


def write_sdl(bs: BenchScene, path: str, width: int, height: int, max_depth: int = 8, min_weight: float = 1e-3) -> str:
    """Write ``bs`` as a POV-Ray scene file; returns ``path``."""
    cam = bs.camera(width, height)
    m = cam.camera_to_world
    x, y, z, eye = m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3]
    # Ray through screen point (sx, sy) ∈ [−½, ½]²: direction + sx·right + sy·up. Explicit vectors keep our
    # right-handed world (POV-Ray only assumes left-handedness for look_at and its defaults).
    right = x * cam.horizontal_aperture / cam.focal_length
    up = y * cam.vertical_aperture / cam.focal_length
    with open(path, "w") as fh:
        fh.write(f"// {bs.name}: generated by bench/povray.py — {bs.triangle_count} triangles\n#version 3.7;\n")
        fh.write(f"global_settings {{ assumed_gamma 1.0 max_trace_level {max_depth + 1} adc_bailout {min_weight:g} "
                 f"ambient_light rgb {_v(bs.ambient)} }}\n")
        fh.write(f"background {{ rgb {_v(bs.background)} }}\n")
        fh.write(f"camera {{ perspective location {_v(eye)} direction {_v(-z)} right {_v(right)} up {_v(up)} }}\n")
        for light in bs.lights:
            c = np.asarray(light.intensity) / (2 * np.pi)
            fh.write(f"light_source {{ {_v(light.position)} color rgb {_v(c)} fade_distance 1 fade_power 2 }}\n")
        for k, mesh in enumerate(bs.meshes):
            fh.write(f"#declare M{k} = ")
            fh.write(mesh2(mesh, bs.materials))
        for inst in bs.instances:
            mesh = bs.meshes[inst.mesh]
            t = np.asarray(inst.transform, float)
            # POV-Ray's matrix is row-vector convention: the 3×3 transposed, then the translation.
            vals = list(t[:3, :3].T.reshape(-1)) + list(t[:3, 3])
            mat = bs.instance_material(inst)
            tex = "" if np.ndim(mat) > 0 else texture(bs.materials[int(mat)])
            inter = "" if np.ndim(mat) > 0 else interior(bs.materials[int(mat)])
            fh.write(f"object {{ M{inst.mesh} {tex} {inter} matrix <{','.join(f'{v:.9g}' for v in vals)}> }}\n")
    return path


def parse_times(text: str) -> dict:
    """POV-Ray's own 'Parse Time' / 'Trace Time' etc. (seconds) from its stderr report."""
    out = {}
    for key, label in (("parse", "Parse Time"), ("bounding", "Bounding Time"), ("trace", "Trace Time")):
        m = re.search(label + r":.*?\(([\d.]+) seconds\)", text)
        if m:
            out[key] = float(m.group(1))
    m = re.search(r"Peak memory used:\s+(\d+) bytes", text)
    if m:
        out["peak_memory"] = int(m.group(1))
    return out


def render(sdl: str, out_png: str, width: int, height: int, threads: int) -> dict:
    """Run POV-Ray once (AA off); returns wall seconds, max RSS (bytes) and POV-Ray's own phase times."""
    exe = povray_binary()
    if exe is None:
        raise FileNotFoundError("povray is not installed (apt-get install povray)")
    cmd = [exe, f"+I{sdl}", f"+O{out_png}", f"+W{width}", f"+H{height}", "-A", f"+WT{threads}", "-D", "-P",
           "+FN", "-V", "+GA"]
    # Output goes to a temporary file (not a pipe) so POV-Ray never blocks on a full pipe while we wait4() for it.
    with tempfile.TemporaryFile(mode="w+") as log:
        start = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
        log.seek(0)
        text = log.read()
    if proc.returncode != 0:
        raise RuntimeError(f"povray failed ({proc.returncode}): {text[-2000:]}")
    return {"seconds": wall, "maxrss": usage.ru_maxrss * 1024, **parse_times(text)}

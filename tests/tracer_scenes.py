"""Small scenes built with the tracer's Python API, for tests that need no Blender or USD."""

from __future__ import annotations

import numpy as np
import trimesh

from tracer import Camera, PointLight, SceneBuilder


def sphere(b: SceneBuilder, center, radius, material, name, count=48):
    m = trimesh.creation.uv_sphere(radius=radius, count=[count, count])
    return b.add_mesh(m.vertices + np.asarray(center, float), m.faces, material=material, name=name,
                      normals=m.vertices / radius)


def quad(b: SceneBuilder, center, size, material, name, normal_axis=2):
    """A square of edge ``size`` centred at ``center``, facing +axis (z by default)."""
    h = size / 2
    pts = np.array([[-h, -h], [h, -h], [h, h], [-h, h]])
    v = np.zeros((4, 3))
    axes = [a for a in range(3) if a != normal_axis]
    v[:, axes[0]], v[:, axes[1]] = pts[:, 0], pts[:, 1]
    if normal_axis == 1:  # keep counter-clockwise winding when seen from +axis
        v = v[::-1]
    v += np.asarray(center, float)
    return b.add_mesh(v, [[0, 1, 2], [0, 2, 3]], material=material, name=name)


def lit_sphere_on_floor(light_pos=(3.0, -2.0, 6.0), intensity=50.0):
    """A grey sphere on a large grey floor, one point light, camera looking at it from −y. Z up."""
    b = SceneBuilder()
    grey = b.add_material("grey", diffuse=(0.8, 0.8, 0.8))
    quad(b, (0, 0, 0), 40.0, grey, "floor")
    sphere(b, (0, 0, 1), 1.0, grey, "ball")
    b.add_light(PointLight(position=light_pos, intensity=(intensity,) * 3))
    b.camera = Camera.look_at((0, -8, 3), (0, 0, 0.8), up=(0, 0, 1), focal_length=35.0,
                              horizontal_aperture=36.0, vertical_aperture=27.0)
    return b

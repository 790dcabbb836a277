"""Image textures through the add-on keep their orientation: an asymmetric image on a plane seen from above by an
orthographic camera renders as the image itself (Blender stores image pixels bottom row first; a flip or a
transpose in the export shows here)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from blender_kit import scene as bs

import bpy  # noqa: E402

import addon  # noqa: E402
from tracer import write_image  # noqa: E402

N = 8


@pytest.fixture(scope="module")
def registered():
    addon.register()
    yield
    addon.unregister()


def _image():
    rows, cols = np.mgrid[0:N, 0:N]
    img = np.stack([(cols + 0.5) / N, (rows + 0.5) / N, np.zeros((N, N))], axis=-1).astype(np.float32)
    img[0, 0, 2] = 1.0  # top-left marker
    return img


def test_image_texture_orientation_through_the_addon(registered, tmp_path):
    path = str(tmp_path / "asym.exr")
    write_image(path, _image())  # linear EXR, row 0 = the top of the picture
    bs.reset(size=(N, N))
    mat = bs.principled_material("Textured", **{"Specular IOR Level": 0.0})
    tree = mat.node_tree
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = bpy.data.images.load(path)
    tex.interpolation = "Linear"
    tree.links.new(tex.outputs["Color"], bs.principled_node(mat).inputs["Base Color"])
    bs.add_plane((0, 0, 0), 2.0, material=mat)  # UVs 0..1 over x, y in [-1, 1]
    cam = bs.add_camera((0, 0, 5), (0, 0, 0), rotation=(0.0, 0.0, 0.0))
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = 2.0
    bs.set_world((1.0, 1.0, 1.0), 1.0)  # ambient 1, no lights: each pixel shows its texel
    scene = bpy.context.scene
    scene.render.engine = "WHITTED"
    scene.whitted.samples = 1
    out = bs.render_exr(scene, engine="WHITTED")["rgba"][..., :3]
    np.testing.assert_allclose(out, _image(), atol=2e-3)

"""Image textures through the add-on keep their orientation: an asymmetric image on a plane seen from above by an
orthographic camera renders as the image itself (Blender stores image pixels bottom row first; a flip or a
transpose in the export shows here)."""

from __future__ import annotations

import math
import os

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


# ---------------------------------------------------------------------------------------------------- UDIM
#: The tiles of :func:`udim_image`: tile number -> colour (linear; 0 and 1 survive the 8-bit sRGB files exactly).
TILES = {1001: (1.0, 0.0, 0.0), 1002: (0.0, 0.0, 1.0), 1011: (0.0, 1.0, 0.0)}
MAGENTA = (1.0, 0.0, 1.0)  # Cycles' missing image, and the place of the tile the set lacks (1012)


def udim_image(folder: str, size: int = 32):
    """A tiled image of flat-colour tiles 1001 red, 1002 blue and 1011 green (no 1012), each tile a generated
    image saved as ``folder/rgb.<n>.png`` and the set loaded as Blender does (tile 1001, source TILED)."""
    os.makedirs(folder, exist_ok=True)
    for n, colour in TILES.items():
        im = bpy.data.images.new(f"tile{n}", size, size)
        im.generated_color = tuple(colour) + (1.0,)
        im.filepath_raw = os.path.join(folder, f"rgb.{n}.png")
        im.file_format = "PNG"
        im.save()
        bpy.data.images.remove(im)
    img = bpy.data.images.load(os.path.join(folder, "rgb.1001.png"))
    img.source = "TILED"
    return img


def udim_scene(folder: str, size=(32, 32), interpolation: str = "Linear"):
    """A 2 m plane whose UVs span u, v ∈ [0, 2] (tiles 1001, 1002, 1011 and the absent 1012), seen straight down
    by an orthographic camera, under a white world: each pixel shows its texel."""
    scene = bs.reset(size)
    mat = bs.principled_material("Tiled", **{"Specular IOR Level": 0.0})
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = udim_image(folder)
    tex.interpolation = interpolation
    mat.node_tree.links.new(tex.outputs["Color"], bs.principled_node(mat).inputs["Base Color"])
    plane = bs.add_plane((0, 0, 0), 2.0, material=mat)
    for loop in plane.data.uv_layers.active.data:
        loop.uv = (2.0 * loop.uv[0], 2.0 * loop.uv[1])
    cam = bs.add_camera((0, 0, 5), (0, 0, 0), rotation=(0.0, 0.0, 0.0))
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = 2.0
    bs.set_world((1.0, 1.0, 1.0), 1.0)
    return scene


def udim_expected(size=(32, 32)) -> np.ndarray:
    """The picture of :func:`udim_scene`: quadrants bottom-left 1001, bottom-right 1002, top-left 1011, top-right
    the absent tile (magenta)."""
    w, h = size
    out = np.empty((h, w, 3), np.float32)
    out[h // 2:, :w // 2], out[h // 2:, w // 2:] = TILES[1001], TILES[1002]
    out[:h // 2, :w // 2], out[:h // 2, w // 2:] = TILES[1011], MAGENTA
    return out


def test_udim_tiles_through_the_addon(registered, tmp_path):
    """Every tile of a tiled image is read where its number puts it (not the first tile everywhere), the absent
    tile magenta, through F12."""
    scene = udim_scene(str(tmp_path / "tiles"))
    scene.render.engine = "WHITTED"
    scene.whitted.samples = 1
    out = bs.render_exr(scene, engine="WHITTED")["rgba"][..., :3]
    # each tile filters within itself (its own Extension past its edges, as Cycles): the seams stay sharp
    np.testing.assert_allclose(out, udim_expected(), atol=2e-3)
    assert len([im for im in bpy.data.images if im.name.startswith("rgb.")]) == 1  # the tiles' loads are removed


def test_udim_tiles_packed_and_generated(registered, tmp_path):
    """Packed tiles are read from their packed bytes (the files gone); a generated tile from Blender's buffer."""
    from addon import export

    folder = str(tmp_path / "tiles")
    udim_scene(folder, size=(8, 8), interpolation="Closest")
    img = bpy.data.images["rgb.1001.png"]
    img.pack()
    for n in TILES:
        os.remove(os.path.join(folder, f"rgb.{n}.png"))
    ts, warnings = export.scene_from_depsgraph(bpy.context.evaluated_depsgraph_get())
    assert not warnings, warnings
    from tracer import RenderSettings, render

    out = render(ts, RenderSettings(width=8, height=8, samples=1, max_depth=2, seed=0)).rgb
    np.testing.assert_allclose(out, udim_expected((8, 8)), atol=2e-3)

    gen = bpy.data.images.new("Generated", 4, 4, tiled=True)
    gen.tiles[0].generated_color = (0.0, 1.0, 0.0, 1.0)
    bpy.data.materials["Tiled"].node_tree.nodes["Image Texture"].image = gen
    ts, warnings = export.scene_from_depsgraph(bpy.context.evaluated_depsgraph_get())
    out = render(ts, RenderSettings(width=8, height=8, samples=1, max_depth=2, seed=0)).rgb
    np.testing.assert_allclose(out[4:, :4], np.broadcast_to((0.0, 1.0, 0.0), (4, 4, 3)), atol=2e-3)


def test_udim_tiles_without_new_datablocks(registered, tmp_path, monkeypatch):
    """Where Blender refuses new datablocks (a viewport's drawing), the tiles are decoded by OpenImageIO: the same
    picture."""
    from addon import export
    from tracer import RenderSettings, render

    udim_scene(str(tmp_path / "tiles"), size=(8, 8), interpolation="Closest")

    def refuse(*_a, **_k):
        raise RuntimeError("can't modify blend data in this state")
    import addon.udim

    monkeypatch.setattr(addon.udim, "new_image", refuse)
    ts, warnings = export.scene_from_depsgraph(bpy.context.evaluated_depsgraph_get())
    assert not warnings, warnings
    out = render(ts, RenderSettings(width=8, height=8, samples=1, max_depth=2, seed=0)).rgb
    np.testing.assert_allclose(out, udim_expected((8, 8)), atol=2e-3)

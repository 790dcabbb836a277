"""Blender images are read once per file version across renders (addon.image_cache, issue #23): the same file
twice gives the kept pixels without reading Blender's ``Image.pixels`` again; a file changed on disk (new
modification time) gives the new pixels, as a fresh Blender load of that file does."""

from __future__ import annotations

import os

import numpy as np
import pytest

from blender_kit import scene as bs  # noqa: F401 — sets up bpy's path

import bpy  # noqa: E402

from addon import image_cache, nodes  # noqa: E402
from tracer import write_image  # noqa: E402


@pytest.fixture
def counted(monkeypatch):
    reads = []
    read = nodes._read_rgba
    monkeypatch.setattr(nodes, "_read_rgba", lambda image: (reads.append(image.name), read(image))[1])
    image_cache.clear()
    yield reads
    image_cache.clear()


def test_an_image_file_is_read_once_and_again_when_it_changes(tmp_path, counted):
    path = str(tmp_path / "t.exr")
    first = np.full((4, 6, 3), 0.25, np.float32)
    write_image(path, first)
    img = bpy.data.images.load(path)
    a = nodes.image_rgba(img)
    b = nodes.image_rgba(img)
    assert counted == [img.name] and b is a and not a.flags.writeable
    np.testing.assert_allclose(a[..., :3], 0.25, atol=1e-3)
    second = np.full((4, 6, 3), 0.75, np.float32)
    write_image(path, second)
    st = os.stat(path)
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns + 2_000_000_000))  # a later save, whatever the clock's grain
    c = nodes.image_rgba(img)
    assert counted == [img.name] * 2
    fresh = bpy.data.images.load(path, check_existing=False)  # what Blender reads from the file now
    np.testing.assert_allclose(c, nodes._read_rgba(fresh), atol=1e-6)
    np.testing.assert_allclose(c[..., :3], 0.75, atol=1e-3)


def test_images_without_a_file_are_read_every_time(counted):
    img = bpy.data.images.new("generated", 4, 4)
    nodes.image_rgba(img)
    nodes.image_rgba(img)
    assert counted == ["generated", "generated"]

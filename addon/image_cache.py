"""Decoded Blender images kept across renders: each image file is read (``Image.pixels`` + colour decoding) once.

Reading a 2K texture through ``Image.pixels`` and decoding sRGB costs 0.1-0.3 s, every F12 and every export
(issue #23: a glTF helmet spent about 2 s exporting its textures before a 1 s render). :func:`cached_pixels` keeps
the decoded pixels by datablock (``name_full``) and stamps them with what can change them: the resolved file path,
its modification time and size, the colour space and alpha mode. A stamp that no longer matches reads again
(after ``Image.reload()`` when the file changed on disk, which Blender does not notice by itself). Images without
a file of their own (generated, packed, edited in Blender and not saved) are read every time. Cached arrays are
read-only (a caller that wrote into one would change every later render); the cache holds at most
:data:`MAX_BYTES`, oldest first out.
"""

from __future__ import annotations

import os
from collections import OrderedDict

#: Upper bound of the decoded pixels kept (bytes); the least recently used go first.
MAX_BYTES = 1 << 30

_CACHE: "OrderedDict[str, tuple]" = OrderedDict()  # name_full -> (stamp, pixels)


def stamp(image):
    """What the pixels of ``image`` depend on, or None when it has no unchanged file of its own (read it afresh)."""
    if getattr(image, "source", "FILE") != "FILE" or getattr(image, "packed_file", None) is not None \
            or getattr(image, "is_dirty", False):
        return None
    try:
        import bpy

        path = bpy.path.abspath(image.filepath, library=image.library)
        st = os.stat(path)
    except (OSError, ValueError, AttributeError):
        return None
    return (os.path.normpath(path), st.st_mtime_ns, st.st_size, image.colorspace_settings.name,
            getattr(image, "alpha_mode", ""))


def cached_pixels(image, read):
    """``read(image)``'s pixels, read once per file version (see the module's docstring)."""
    key = getattr(image, "name_full", image.name)
    now = stamp(image)
    hit = _CACHE.get(key)
    if now is not None and hit is not None and hit[0] == now:
        _CACHE.move_to_end(key)
        return hit[1]
    if hit is not None:
        del _CACHE[key]
        if now is not None and hit[0][:3] != now[:3]:  # the file changed on disk: Blender still holds the old one
            image.reload()
    pixels = read(image)
    if now is not None:
        pixels.setflags(write=False)
        _CACHE[key] = (now, pixels)
        _evict()
    return pixels


def _evict() -> None:
    total = sum(p.nbytes for _, p in _CACHE.values())
    while total > MAX_BYTES and len(_CACHE) > 1:
        _, (_, p) = _CACHE.popitem(last=False)
        total -= p.nbytes


def clear() -> None:
    """Forget every cached image (tests)."""
    _CACHE.clear()

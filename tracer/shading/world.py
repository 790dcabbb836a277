"""A world's shader graph evaluated by the material VM per direction: the lat-long environment it gives.

    image = world_image(graph, width, height, warn)   # (height, width, 3) scene-linear, or None

The graph is a world's node tree (a front end writes its Background node as an ``emission`` closure: colour ×
strength is what a ray that leaves the scene sees). Its program runs once per texel centre direction of the
tracer's :class:`tracer.Environment` layout (u = 0.5 looks along +X, the top row is the zenith; Cycles'
``direction_to_equirectangular``), with the inputs Cycles gives a background: Position = Generated = Object = the
direction, Normal = −direction. Returns None when the graph's compiler warned (a node it does not evaluate): the
front end then keeps its other way of reading the world.
"""

from __future__ import annotations

import numpy as np

from . import vm
from .compiler import compile_graph
from .texture import Texture, pack_textures


def latlong_directions(width: int, height: int) -> np.ndarray:
    """(height·width, 3) unit directions of the texel centres of a lat-long image (the Environment's layout)."""
    u = (np.arange(width) + 0.5) / width
    v = 1.0 - (np.arange(height) + 0.5) / height  # row 0 = the top = the zenith
    phi = (0.5 - u) * 2.0 * np.pi  # u = 0.5 - atan2(y, x) / 2π
    theta = (v - 0.5) * np.pi  # v = asin(z) / π + 0.5
    ph, th = np.meshgrid(phi, theta)
    d = np.stack([np.cos(th) * np.cos(ph), np.cos(th) * np.sin(ph), np.sin(th)], axis=-1)
    return np.ascontiguousarray(d.reshape(-1, 3), np.float64)


def world_image(graph, width: int, height: int, warn=None) -> np.ndarray | None:
    """The (height, width, 3) float32 lat-long image of a world graph (module docstring), or None if it cannot be
    evaluated (``warn`` receives the compiler's message naming the node)."""
    said: list = []
    compiled = compile_graph(graph, said.append, row=False)
    if said:
        if warn is not None:
            for m in said:
                warn(m)
        return None
    prog = compiled.program
    if prog is None or prog.outs[vm.OUT_EMIT] < 0:  # a constant world
        e = compile_graph(graph, None).row.get("emission", (0.0, 0.0, 0.0))
        return np.broadcast_to(np.asarray(e, np.float32), (height, width, 3)).copy()
    textures = [Texture(image=u.image.rgba(), wrap_s=u.image.wrap_s, wrap_t=u.image.wrap_t, scale=u.scale,
                        bias=u.bias, fallback=u.fallback, interpolation=u.image.interpolation)
                for u in prog.textures]
    tex = pack_textures(textures)
    code = np.ascontiguousarray(prog.code, np.int32)
    outs = np.ascontiguousarray(prog.outs[None], np.int32)
    pstart = np.array([0, len(code)], np.int32)
    pbase = np.zeros(1, np.int32)
    R0 = np.ascontiguousarray(prog.init, np.float64)
    dirs = np.ascontiguousarray(latlong_directions(width, height), np.float32)
    out = np.empty((len(dirs), 3), np.float64)
    f32, i32 = np.float32, np.int32  # the dtypes of tracer.geometry.surface.Geometry / InstanceTables: one compiled execute
    vm.shade_directions(code, pstart, pbase, outs, R0, np.empty_like(R0), 0, dirs, out, tex.data, tex.params,
                        (np.zeros((0, 3, 2), f32), np.zeros((0, 3), i32), False), np.zeros((0, 3, 3), f32), False, np.zeros((0, 3), f32),
                        np.zeros((0, 3), i32), np.zeros((0, 3), f32), np.zeros(0, i32), np.zeros((2, 9, 4)),
                        np.zeros((0, 3, 3)), np.zeros(0, np.bool_), np.zeros(0, i32), 0, True)
    img = np.nan_to_num(out.reshape(height, width, 3), nan=0.0, posinf=0.0, neginf=0.0)
    return img.astype(np.float32)

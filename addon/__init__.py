"""Whitted as a Blender render engine (a Blender 4.2+ extension; see blender_manifest.toml and docs/addon.md).

Works both as the installed extension (the tracer is bundled next to this file: ``from . import tracer``) and as
the repository's ``addon`` package (the top-level ``tracer``). ``register()`` adds the scene settings, the render
engine ``WHITTED`` and its panels; ``unregister()`` removes them again. Submodules are imported on use, so
``python -m addon.build`` runs without Blender's ``bpy``.
"""

from __future__ import annotations

import importlib

_MODULES = ("properties", "engine", "ui", "explain")


def _modules():
    return [importlib.import_module(f"{__name__}.{name}") for name in _MODULES]


def register():
    for m in _modules():
        m.register()


def unregister():
    for m in reversed(_modules()):
        m.unregister()

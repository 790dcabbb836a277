"""Shared pytest fixtures. Blender-specific helpers live in blender_kit/scene.py (bpy is imported lazily)."""

from __future__ import annotations

import os
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)
# The suite's kernels go to the checkout's own cache (cold in a fresh clone, as CI's is; shared by the test
# processes, Blender children included), not to the user's ~/.cache/whitted/kernels.
os.environ.setdefault("WHITTED_KERNEL_CACHE", os.path.join(ROOT, ".cache", "kernels"))


@pytest.fixture
def bpy_module():
    """The bpy module with Blender reset to an empty factory scene (bpy holds global state)."""
    import bpy  # the test extra installs it; a missing bpy fails the suite rather than skipping it

    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy

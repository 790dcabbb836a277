"""The tracer the add-on uses, decided in this one place: inside the installed extension it is bundled next to the
add-on (``addon/build.py`` copies ``tracer/`` in), in the repository it is the top-level ``tracer`` package.

    from .bundled import tracer, tracer_module
    add_graph = tracer_module("shading.compiler").add_graph
"""

import importlib

try:  # inside the installed extension the tracer is bundled next to this module
    from . import tracer
except ImportError:  # the repository's ``addon`` package uses the top-level tracer
    import tracer



def tracer_module(name: str):
    """The submodule ``name`` of that tracer (``tracer_module("shading.graph")``)."""
    return importlib.import_module(f"{tracer.__name__}.{name}")


__all__ = ["tracer", "tracer_module"]

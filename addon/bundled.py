"""The tracer the add-on uses, decided in this one place: inside the installed extension it is bundled next to the
add-on (``addon/build.py`` copies ``tracer/`` in), in the repository it is the top-level ``tracer`` package.

    from .bundled import tracer
"""

try:  # inside the installed extension the tracer is bundled next to this module
    from . import tracer
except ImportError:  # the repository's ``addon`` package uses the top-level tracer
    import tracer

__all__ = ["tracer"]

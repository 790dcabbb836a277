"""The one exception bad USD input raises (a module of its own: the command line catches it without importing pxr)."""


class UsdInputError(ValueError):
    """Bad input that the user can fix (missing file, not USD, unknown camera...). ``str()`` is one line."""

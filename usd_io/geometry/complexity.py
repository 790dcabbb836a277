"""usdrecord/usdview's ``--complexity`` names and the subdivision levels they mean (a module of its own so that the
command line builds its parser without importing pxr)."""

#: usdrecord/usdview's --complexity names -> uniform refinement levels of subdivision surfaces (Hydra's refineLevel
#: for complexity 1.0, 1.1, 1.2, 1.3).
COMPLEXITY = {"low": 0, "medium": 1, "high": 2, "veryhigh": 3}
DEFAULT_COMPLEXITY = "medium"

"""``tracer.render(scene, settings)``: a :class:`tracer.Session` made for one render (the tile loop is
:mod:`tracer.integrator.tiles`, under the session).
"""

from __future__ import annotations

import time

from .accel.accelerator import Accelerator
from .film import Image
from .integrator.tiles import RenderCancelled, render_session, render_tile, tiles_of  # noqa: F401 — their former home
from .scene import Scene
from .session import Session
from .settings import RenderSettings


def render(scene: Scene, settings: RenderSettings | None = None, *, on_tile=None, cancelled=None,
           accel=None) -> Image:
    """Render ``scene`` and return an :class:`~tracer.film.Image`: a :class:`tracer.Session` made for one render.

    on_tile(image, (x0, y0, x1, y1)) is called after each tile is written (in the calling thread), for progressive
    display; cancelled() is polled while the Embree scene is built and then between tiles and depths, and a True
    ends the render with :class:`RenderCancelled` (its ``image`` the tiles done so far, or None when it came
    during the build). ``accel``: an :class:`~tracer.accel.accelerator.Accelerator` already built over this scene (kept for
    callers that hold one; a :class:`tracer.Session` is the way to keep a prepared scene across renders).
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"render() expects a tracer.Scene, got {type(scene).__name__}")
    settings = (settings or RenderSettings()).validate()
    start = time.perf_counter()
    if settings.extra.get("record_rays"):
        accel = Accelerator(scene, record=True)
    session = Session(scene, accel=accel, instanced=False, cancelled=cancelled)
    try:
        return render_session(session, settings, on_tile=on_tile, cancelled=cancelled, started=start)
    finally:
        if accel is None:
            session.close()

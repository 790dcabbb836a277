"""Cameras: ``UsdGeom.Camera`` -> :class:`tracer.Camera`, image size, aperture conform, and a default framing.

Units. USD gives focalLength and apertures in tenths of a stage unit (the "mm" convention); for a perspective
camera only their ratio matters, so they pass through unchanged. Orthographic apertures and offsets are the view's
size in tenths of a stage unit, so they are multiplied by 0.1 to get the tracer's world units.

Conform policy: UsdRender's (``aspectRatioConformPolicy`` of the stage's RenderSettings, usd_io.render_settings),
and without RenderSettings its fallback, expandAperture, as Arnold renders a stage camera (usdrecord's
MatchVertically crops a 16:9 aperture rendered at 4:3 to a 1.33x zoom). The image height defaults to
``width / (horizontalAperture / verticalAperture)``, so nothing is conformed unless both width and height are given.
"""

from __future__ import annotations

import numpy as np
from pxr import Gf, Sdf, UsdGeom

from tracer import ORTHOGRAPHIC, PERSPECTIVE, Camera, fit_apertures
from tracer.camera import lens_radius
from tracer.settings import default_of

from .geometry.xform import to_numpy
from .stage import UsdInputError

#: UsdRender's fallback aspectRatioConformPolicy (expandAperture), as Arnold renders a stage camera: the
#: aperture's short side grows until it has the image's aspect (usd_io.render_settings has all five policies).
CONFORM_POLICY = "expand"
#: The image width when neither side is asked for: tracer.RenderSettings' (usdrecord's 960).
DEFAULT_WIDTH = default_of("width")
#: USD's default apertures (35 mm academy, in tenths of a unit) and focal length, for the framing camera.
DEFAULT_APERTURE = (20.955, 15.2908)
DEFAULT_FOCAL = 50.0


def read_camera(prim, time):
    """Raw camera values at ``time`` (world transform, projection, USD-unit apertures).

    Raises :class:`UsdInputError` for apertures (or a perspective focal length) that are not positive and finite,
    and for a transform with NaN/Inf.
    """
    cam = UsdGeom.Camera(prim)
    gf = cam.GetCamera(time)
    ortho = gf.projection == gf.Orthographic
    checked = [("horizontalAperture", gf.horizontalAperture), ("verticalAperture", gf.verticalAperture)]
    if not ortho:
        checked.append(("focalLength", gf.focalLength))
    for name, v in checked:
        if not (np.isfinite(v) and v > 0):
            raise UsdInputError(f"{prim.GetPath()}: camera {name} must be a positive number, got {v:g}")
    c2w = to_numpy(gf.transform)
    if not np.all(np.isfinite(c2w)):
        raise UsdInputError(f"{prim.GetPath()}: camera transform has NaN or infinite values")
    return dict(
        path=str(prim.GetPath()),
        camera_to_world=c2w,
        projection=ORTHOGRAPHIC if ortho else PERSPECTIVE,
        focal_length=float(gf.focalLength),
        horizontal_aperture=float(gf.horizontalAperture),
        vertical_aperture=float(gf.verticalAperture),
        horizontal_aperture_offset=float(gf.horizontalApertureOffset),
        vertical_aperture_offset=float(gf.verticalApertureOffset),
        near=float(gf.clippingRange.min),
        far=float(gf.clippingRange.max),
        clipping_planes=[tuple(float(x) for x in p) for p in (cam.GetClippingPlanesAttr().Get(time) or [])],
        f_stop=float(gf.fStop),
        focus_distance=float(gf.focusDistance),
    )


def fold_depth_of_field(raw: dict, warn, enabled: bool = True, note=None) -> dict:
    """UsdGeomCamera's depth of field: ``fStop`` 0 (the default) is a pinhole; with fStop > 0 the plane of focus is
    ``focusDistance`` stage units away. A positive fStop with no focus distance is ignored with one warning.
    ``enabled`` False (``--no-dof``, or the RenderSettings' ``disableDepthOfField``) makes every camera a pinhole
    (``note`` receives one line when that drops a lens)."""
    out = dict(raw)
    if not enabled:
        if out.get("f_stop", 0.0) > 0 and note is not None:
            note(f"{raw['path']}: fStop {out['f_stop']:g} ignored: depth of field is off")
        out["f_stop"] = 0.0
        return out
    if out.get("f_stop", 0.0) > 0 and not out.get("focus_distance", 0.0) > 0:
        warn(f"{raw['path']}: fStop {out['f_stop']:g} without a positive focusDistance: depth of field ignored")
        out["f_stop"] = 0.0
    return out


def _arnold_primvar(prim, name: str, time):
    """``primvars:arnold:NAME`` as authored, its first motion key when it is an array (Arnold's motion keys span
    the shutter); None when not authored."""
    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar(f"arnold:{name}")
    v = pv.Get(time) if pv and pv.HasAuthoredValue() else None
    if v is None:
        return None
    if isinstance(v, Gf.Matrix4d):
        return v
    if hasattr(v, "__len__") and len(v) and not isinstance(v, (str, Gf.Vec3f, Gf.Vec3d, Gf.Vec2f)):
        v = v[0]
    return v


def arnold_placement(prim, time):
    """(camera_to_world, horizontal fov in degrees or None, the primvars that placed it) of an Arnold camera written into a USD Camera's
    primvars (arnold-usd and MtoA/HtoA exports keep ``persp_camera`` parameters USD has no attribute for as
    ``primvars:arnold:*``), or None when it has none. Arnold places a camera by its ``matrix`` applied to the
    look-at frame of ``position`` → ``look_at`` with ``up`` (defaults: the origin, −Z, +Y: the identity)."""
    names = ("matrix", "position", "look_at", "up", "fov")
    got = {n: _arnold_primvar(prim, n, time) for n in names}
    if got["matrix"] is None and got["position"] is None and got["look_at"] is None:
        return None
    m = np.eye(4) if got["matrix"] is None else to_numpy(Gf.Matrix4d(got["matrix"]))
    vec = lambda v, d: np.asarray(d if v is None else tuple(v), np.float64)  # noqa: E731
    eye, target, up = vec(got["position"], (0, 0, 0)), vec(got["look_at"], (0, 0, -1)), vec(got["up"], (0, 1, 0))
    fwd = target - eye
    x = np.cross(up, -fwd)
    if np.linalg.norm(fwd) == 0 or np.linalg.norm(x) < 1e-12 or not np.all(np.isfinite(m)):
        return None
    z = -fwd / np.linalg.norm(fwd)
    x /= np.linalg.norm(x)
    frame = np.eye(4)
    frame[:3, 0], frame[:3, 1], frame[:3, 2], frame[:3, 3] = x, np.cross(z, x), z, eye
    fov = got["fov"]
    fov = float(fov) if fov is not None and np.isfinite(float(fov)) and 0 < float(fov) < 180 else None
    return m @ frame, fov, [n for n in names[:4] if got[n] is not None]


def fold_arnold_camera(raw: dict, prim, time, note) -> dict:
    """A camera USD leaves at the origin (no transform: its world matrix is the identity) that carries an Arnold
    placement (:func:`arnold_placement`) is placed as Arnold places it, with its ``fov`` (horizontal) setting the
    focal length against the horizontal aperture; ``note`` receives one line saying so. Any other camera is as
    USD says."""
    if raw["projection"] == ORTHOGRAPHIC:
        return _arnold_screen_window(raw, prim, time, note)
    if not np.allclose(raw["camera_to_world"], np.eye(4)) or raw["projection"] != PERSPECTIVE:
        return raw
    placed = arnold_placement(prim, time)
    if placed is None:
        return raw
    out = dict(raw, camera_to_world=placed[0])
    said = "primvars:arnold:" + "/".join(placed[2])
    if placed[1] is not None:
        out["focal_length"] = raw["horizontal_aperture"] / 2 / np.tan(np.radians(placed[1]) / 2)
        said += f" and its fov {placed[1]:g}°"
    note(f"{raw['path']}: the USD camera has no transform; placed by its Arnold {said}")
    return out


def _arnold_screen_window(raw: dict, prim, time, note) -> dict:
    """An orthographic camera with Arnold's ``screen_window_min``/``max`` (``primvars:arnold:*``, read by arnold-usd
    after the USD camera, whose aperture its ortho_camera ignores): Arnold's ortho_camera shows x from min.x to max.x
    in scene units (the y extent follows the image's aspect), so the horizontal aperture is (max.x − min.x) and its
    offset (max.x + min.x)/2, in USD's tenths of a unit (the vertical ones scaled alike)."""
    lo, hi = _arnold_primvar(prim, "screen_window_min", time), _arnold_primvar(prim, "screen_window_max", time)
    if lo is None or hi is None:
        return raw
    lo, hi = np.asarray(tuple(lo), np.float64), np.asarray(tuple(hi), np.float64)
    if lo.shape != (2,) or hi.shape != (2,) or not np.all(np.isfinite(lo) & np.isfinite(hi)) or np.any(hi <= lo):
        return raw
    out = dict(raw, horizontal_aperture=10.0 * (hi[0] - lo[0]), horizontal_aperture_offset=5.0 * (hi[0] + lo[0]),
               vertical_aperture=10.0 * (hi[1] - lo[1]), vertical_aperture_offset=5.0 * (hi[1] + lo[1]))
    note(f"{raw['path']}: orthographic, framed by its Arnold screen window x {lo[0]:g}..{hi[0]:g}")
    return out


def lens_of(raw: dict) -> dict:
    """The thin lens's ``tracer.Camera`` fields of a camera read by :func:`read_camera` (none for a pinhole): the
    radius from ``fStop`` and the focal length in stage units (``focalLength`` is in tenths of one)."""
    radius = lens_radius(raw["focal_length"] * 0.1, raw.get("f_stop", 0.0))
    if radius <= 0 or not raw.get("focus_distance", 0.0) > 0:
        return {}
    return dict(lens_radius=radius, focus_distance=raw["focus_distance"])


def fold_clipping_planes(raw: dict, warn) -> dict:
    """``clippingPlanes`` (a, b, c, d) in camera space keep the points where a·x + b·y + c·z + d >= 0
    (UsdGeomCamera).
    A plane parallel to the image plane (a = b = 0) is a depth bound on depth = −z: c < 0 keeps depth >= d/c (it
    raises ``near``), c > 0 keeps depth <= d/c (it lowers ``far``) — what the tracer's near/far planes do. Oblique
    planes stay planes: the tracer clips each eye ray to the interval they keep (tracer.clip_planes)."""
    out = dict(raw)
    oblique = []
    for a, b, c, d in raw.get("clipping_planes", ()):
        if abs(a) > 1e-9 * abs(c) or abs(b) > 1e-9 * abs(c) or c == 0:
            if a or b or c:
                oblique.append((a, b, c, d))
            elif d < 0:  # 0·x + d >= 0 keeps nothing
                warn(f"{raw['path']}: clipping plane {(a, b, c, d)} cuts off everything (ignored)")
        elif c < 0:  # c·z >= −d, z <= −d/c: depth >= d/c
            out["near"] = max(out["near"], d / c)
        else:  # z >= −d/c: depth <= d/c
            out["far"] = min(out["far"], d / c)
    out["clipping_planes"] = oblique
    return out


def image_size(raw: dict, width=None, height=None, pixel_aspect: float = 1.0) -> tuple[int, int]:
    """Resolve the image size: missing sides follow the aperture aspect (pixels ``pixel_aspect`` wide per unit of
    height); the default width is :data:`DEFAULT_WIDTH`."""
    aspect = raw["horizontal_aperture"] / raw["vertical_aperture"] / pixel_aspect
    if width is None and height is None:
        width = DEFAULT_WIDTH
    if width is None:
        width = max(1, int(round(height * aspect)))
    if height is None:
        height = max(1, int(round(width / aspect)))
    return int(width), int(height)


def to_tracer(raw: dict, width: int, height: int, policy: str = CONFORM_POLICY, pixel_aspect: float = 1.0) -> Camera:
    """The tracer's camera for an image of width × height pixels, each ``pixel_aspect`` wide per unit of height:
    the aperture conformed to the image aspect by ``policy`` (tracer.fit_apertures; "none" leaves it, so the
    pixels stretch)."""
    h, v = fit_apertures(raw["horizontal_aperture"], raw["vertical_aperture"], width * pixel_aspect, height,
                         policy)
    ho, vo = raw["horizontal_aperture_offset"], raw["vertical_aperture_offset"]
    scale = 0.1 if raw["projection"] == ORTHOGRAPHIC else 1.0
    near = max(0.0, raw["near"])
    far = raw["far"] if raw["far"] > near else np.inf
    return Camera(camera_to_world=raw["camera_to_world"], projection=raw["projection"],
                  focal_length=raw["focal_length"], horizontal_aperture=h * scale, vertical_aperture=v * scale,
                  horizontal_aperture_offset=ho * scale, vertical_aperture_offset=vo * scale, near=near, far=far,
                  clipping_planes=tuple(raw.get("clipping_planes", ())), **lens_of(raw))


def framing_distance(bounds: np.ndarray, up_axis: str, half_fov: float) -> float:
    """usdrecord's distance from the bounds' centre to the eye (UsdAppUtils FrameRecorder,
    ``_ComputeCameraToFrameStage``): the front face's half-diagonal over tan(half FOV), plus half the depth."""
    lo, hi = np.asarray(bounds, dtype=np.float64)
    dim = hi - lo
    face, depth = ((dim[0], dim[1]), dim[2]) if up_axis != "Z" else ((dim[0], dim[2]), dim[1])
    radius = max(float(np.hypot(*face)) / 2, 1e-3)
    return radius / np.tan(half_fov) + depth / 2


#: Below this share of the bounds' largest axis-aligned projected area, the front view is edge-on.
EDGE_ON_FRACTION = 0.03


def framing_view(bounds: np.ndarray, up_axis: str):
    """(direction from the bounds' centre to the eye, up vector, name, front share): the view the default camera
    takes. usdrecord's front view (−Z with Y up, +Y with Z up) unless the front face of the bounds covers less than
    :data:`EDGE_ON_FRACTION` of the largest of the three axis-aligned faces (a ground plane, a wall seen from its
    side): then the documented oblique view from front-right-above, the direction (right + up + back)/√3
    (azimuth 45°, elevation 35.3°, the isometric angle), which sees every face of the box."""
    lo, hi = np.asarray(bounds, dtype=np.float64)
    dim = np.maximum(hi - lo, 0.0)
    if up_axis == "Z":
        up, back, right = np.array([0.0, 0.0, 1.0]), np.array([0.0, -1.0, 0.0]), np.array([1.0, 0.0, 0.0])
        front = dim[0] * dim[2]
    else:
        up, back, right = np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
        front = dim[0] * dim[1]
    largest = max(dim[0] * dim[1], dim[1] * dim[2], dim[0] * dim[2])
    share = 1.0 if largest <= 0 else float(front / largest)
    if share >= EDGE_ON_FRACTION:
        return back, up, "the front", share
    return (right + up + back) / np.sqrt(3.0), up, "front-right-above (isometric)", share


def framing_camera(bounds: np.ndarray, up_axis: str, width: int, height: int):
    """(camera, note): the default camera of a stage without one, and a line saying which view it took.

    The view is :func:`framing_view`'s. From the front it is usdrecord's (UsdAppUtils FrameRecorder): a 50 mm
    perspective camera looking at the bounds' centre, backed off to frame the front face
    (:func:`framing_distance`; usdrecord divides by the horizontal FOV and crops tall scenes; this uses the
    narrower of the image's two FOVs, so nothing is cut off). From the oblique view it backs off to frame the
    bounding sphere. ``render``, ``explain`` and the farm all get their default camera here (through
    ``load_stage``)."""
    lo, hi = np.asarray(bounds, dtype=np.float64)
    center = (lo + hi) / 2
    direction, up, name, share = framing_view(bounds, up_axis)
    hv, vv = fit_apertures(*DEFAULT_APERTURE, width, height, "expand")
    half_fov = float(np.arctan(min(hv, vv) / 2 / DEFAULT_FOCAL))
    if name == "the front":
        dist = framing_distance(bounds, up_axis, half_fov)
        note = "framed from the front (usdrecord's view)"
    else:
        radius = max(float(np.linalg.norm(hi - lo)) / 2, 1e-3)
        dist = radius / np.sin(half_fov)
        note = (f"framed from {name}: the front view would see the stage edge-on ({100 * share:.1f} % of its "
                "largest side)")
    eye = center + direction * dist
    camera = Camera.look_at(eye, center, up=up, focal_length=DEFAULT_FOCAL, horizontal_aperture=hv,
                            vertical_aperture=vv, near=dist * 1e-4, far=np.inf)
    return camera, note


def find_camera(stage, path=None, prims=None):
    """The camera prim to use: ``path`` (error if it is not a camera), else the stage's first camera in
    traversal order (usdrecord picks the primary camera the same way), else None."""
    if path:
        if not Sdf.Path.IsValidPathString(path) or not Sdf.Path(path).IsAbsolutePath():
            raise UsdInputError(f"{stage.GetRootLayer().identifier}: camera path {path!r} is not an absolute "
                                "prim path")
        prim = stage.GetPrimAtPath(path)
        if not prim or not prim.IsValid():
            raise UsdInputError(f"{stage.GetRootLayer().identifier}: no prim at camera path {path}")
        if not prim.IsA(UsdGeom.Camera):
            raise UsdInputError(f"{stage.GetRootLayer().identifier}: {path} is a {prim.GetTypeName() or 'typeless'}"
                                " prim, not a Camera")
        return prim
    for prim in prims or ():
        if prim.IsA(UsdGeom.Camera):
            return prim
    return None

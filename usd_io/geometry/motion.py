"""Motion blur from a stage: the shutter interval and what moves across it (xforms, deforming points, point
instancers), sampled at :data:`MOTION_STEPS` times into ``tracer.Scene.motion``.

Imports :mod:`usd_io.geometry.xform` (matrices), :mod:`usd_io.geometry.instancing` (instancers' motion) and :mod:`usd_io.geometry.mesh`
(deformed points); none of them imports this module.
"""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdGeom

import tracer
import tracer.geometry.motion

from .instancing import instancer_motion
from .mesh import read_mesh
from .xform import to_numpy, transform_points

# ---------------------------------------------------------------------------------------------- motion blur
#: Motion steps across the shutter (open, middle, close), as Blender's default; a rotation between two steps is
#: interpolated along its arc (tracer.geometry.motion), so three steps carry any turn below 180° per half shutter.
MOTION_STEPS = 3


def shutter_interval(camera_prim, time=None):
    """(open, close) time offsets from the frame of the render camera's ``shutter:open``/``shutter:close``
    (UsdGeomCamera: frame-relative, in time codes; both 0 by default, i.e. no motion blur), or None when there is
    no interval: open >= close, or no camera. UsdRender has no shutter of its own: the camera's interval is the
    one, and the RenderSettings can only turn it off (``disableMotionBlur``, or the deprecated
    ``instantaneousShutter``: usd_io.render_settings reads them into ``RenderSpec.motion_blur``), as
    ``--no-motion-blur`` does; :func:`stage_motion` takes the two together."""
    if camera_prim is None or not camera_prim.IsValid() or not camera_prim.IsA(UsdGeom.Camera):
        return None
    t = time if time is not None else Usd.TimeCode.Default()
    cam = UsdGeom.Camera(camera_prim)
    open_, close = cam.GetShutterOpenAttr().Get(t), cam.GetShutterCloseAttr().Get(t)
    if open_ is None or close is None or not float(close) > float(open_):
        return None
    return float(open_), float(close)


def _moves(m: np.ndarray) -> bool:
    return not np.allclose(m, m[:1], atol=1e-9, rtol=0)


def _deformed_points(prim, times, base, level):
    """Per step the mesh's points (object space) at each time — authored time samples, or ``velocities`` and
    ``accelerations`` from the base sample (UsdGeom.PointBased.ComputePointsAtTime) — refined and triangulated as
    the reader does, or None when the points do not move."""

    pb = UsdGeom.PointBased(prim)
    pts = [pb.ComputePointsAtTime(Usd.TimeCode(t), base) for t in times]
    if any(p is None for p in pts):
        return None
    arrays = [np.asarray(p, np.float64) for p in pts]
    if any(a.shape != arrays[0].shape for a in arrays) or not _moves(np.stack(arrays)):
        return None
    out = []
    for t, a in zip(times, arrays):
        data = read_mesh(prim, Usd.TimeCode(t), "st", level, points=a)
        if data is None:
            return None
        out.append(data)
    return out


def stage_motion(stage, scene, time, camera_path, motion_blur=True, subdivision_level=1, warn=print) -> None:
    """Motion blur of a stage read at ``time``: with ``motion_blur`` on (``--motion-blur`` and not the
    RenderSettings' ``disableMotionBlur``) and a shutter interval (:func:`shutter_interval`), every prim's
    world matrix (``UsdGeom.XformCache``) at :data:`MOTION_STEPS` times across it — objects as
    ``scene.motion`` steps relative to where they were placed, native instances as instance steps, the camera as
    ``Camera.motion`` — and meshes whose points move (time samples, ``velocities``/``accelerations``) as vertex
    steps. Changes ``scene`` in place; nothing when the shutter is closed."""
    base = time if time is not None else Usd.TimeCode.Default()
    cam_prim = stage.GetPrimAtPath(camera_path) if camera_path else None
    interval = shutter_interval(cam_prim, base) if motion_blur else None
    if interval is None:
        return
    if base.IsEarliestTime():  # no --time: the shutter opens about the stage's first frame (0 without a range)
        base = Usd.TimeCode(stage.GetStartTimeCode() if stage.HasAuthoredTimeCodeRange() else 0.0)
    frame = base.GetValue() if not base.IsDefault() else 0.0
    times = tracer.geometry.motion.step_times(frame + interval[0], frame + interval[1], MOTION_STEPS)
    caches = [UsdGeom.XformCache(Usd.TimeCode(t)) for t in times]

    def world(prim):
        return np.stack([to_numpy(c.GetLocalToWorldTransform(prim)) for c in caches])

    cam_steps = world(cam_prim)
    cam_steps[:, :3, :3] /= np.linalg.norm(cam_steps[:, :3, :3], axis=1, keepdims=True)
    if _moves(cam_steps):
        scene.camera.motion = cam_steps
        scene.camera.__post_init__()
    names = scene.object_names
    inst = scene.instances
    protos = set(inst.prototypes.tolist()) if inst is not None else set()
    placed = scene.object_transforms
    object_ids, object_motion, deforming, vertices = [], [], [], None
    present = set(np.unique(scene.object_ids).tolist())
    for oid in sorted(present - protos):
        prim = stage.GetPrimAtPath(names[oid]) if oid < len(names) and names[oid].startswith("/") else None
        if prim is None or not prim.IsValid():
            continue
        steps = world(prim)
        m0 = placed[oid] if placed is not None and oid < len(placed) else steps[len(steps) // 2]
        if prim.IsA(UsdGeom.Mesh):
            data = _deformed_points(prim, times, base, subdivision_level)
            rows = np.flatnonzero(scene.object_ids == oid)
            if data is not None and all(len(d.triangles) == len(rows) for d in data):
                if vertices is None:
                    vertices = np.repeat(scene.vertices[None], len(times), axis=0)
                corners = scene.triangles[rows].reshape(-1)
                for k, d in enumerate(data):
                    tri = d.triangles.reshape(-1)
                    vertices[k, corners] = transform_points(steps[k], np.asarray(d.points, np.float64)[tri])
                deforming.append(oid)
                continue
            if data is not None:
                warn(f"{prim.GetPath()}: its points move but its topology changes across the shutter "
                     "(no deformation blur)")
        if _moves(steps):
            object_ids.append(oid)
            object_motion.append(steps @ np.linalg.inv(m0))
    instance_motion = None
    if inst is not None:
        for row, steps in instancer_motion(stage, names, inst.object_ids, times, base).items():
            if _moves(steps):
                if instance_motion is None:
                    instance_motion = np.repeat(inst.transforms[:, None], len(times), axis=1)
                instance_motion[row] = steps
        for row, oid in enumerate(inst.object_ids.tolist()):
            name = names[oid] if oid < len(names) else ""
            prim = stage.GetPrimAtPath(name) if name.startswith("/") and "[" not in name else None
            if prim is None or not prim.IsValid():
                continue
            steps = world(prim)
            if _moves(steps):
                if instance_motion is None:
                    instance_motion = np.repeat(inst.transforms[:, None], len(times), axis=1)
                instance_motion[row] = steps
    s = len(times)
    scene.motion = tracer.geometry.motion.Motion(
        steps=s, object_ids=np.asarray(object_ids, np.int32),
        object_motion=np.stack(object_motion) if object_motion else np.zeros((0, s, 4, 4)),
        instance_motion=instance_motion, vertices=vertices, deforming=np.asarray(deforming, np.int32))
    scene.validate_motion()

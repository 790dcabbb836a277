"""Blender's motion blur → ``_motion().Motion`` and camera motion, sampled as Cycles samples it.

With Render Properties → Motion Blur on (``render.use_motion_blur``, off by default), the shutter is
``motion_blur_shutter`` frames long and sits at ``motion_blur_position`` (START / CENTER / END) around the current
frame (:func:`_motion().blender_shutter`). The scene is evaluated at S sub-frames evenly spread over it
(``frame_set(frame, subframe=...)``: the render engine's own, so the render depsgraph follows) and, per step:

- every exported object's ``matrix_world`` (object motion; Cycles' object property ``use_motion_blur`` off keeps
  an object still), by the same key the export names it with;
- the scene camera's ``matrix_world`` (camera motion);
- for objects whose mesh deforms (``Object.is_deform_modified`` and Cycles' ``use_deform_motion``, on by
  default), the evaluated mesh's vertices placed in the world (deformation blur; a step whose mesh has a different
  topology leaves the object undeformed, as Cycles does).

S = 2·``motion_steps`` + 1 (the largest over moving objects; Cycles' object property, default 1 → 3 steps, the
middle one at the frame for the CENTER shutter). The shutter curve (``motion_blur_shutter_curve``) weights the
times when it is not flat. The frame is put back afterwards.
"""

from __future__ import annotations

import math

import numpy as np

from .bundled import tracer_module

#: Sub-frame samples of a non-flat shutter curve.
CURVE_SAMPLES = 64


def _motion():
    """tracer.geometry.motion (here, not at import: it loads the kernel machinery)."""
    return tracer_module("geometry.motion")


def _cycles(obj, name, default):
    c = getattr(obj, "cycles", None)
    return getattr(c, name, default) if c is not None else default


def _shutter_curve(render) -> np.ndarray:
    """The shutter curve as a :func:`_motion().curve_table` (empty when it is flat: the default)."""
    cm = getattr(render, "motion_blur_shutter_curve", None)
    if cm is None:
        return np.zeros(0, np.float32)
    try:
        cm.initialize()
        curve = cm.curves[0]
        values = np.array([cm.evaluate(curve, x) for x in np.linspace(0.0, 1.0, CURVE_SAMPLES)])
    except (AttributeError, IndexError, RuntimeError):
        return np.zeros(0, np.float32)
    if np.allclose(values, values[0]):
        return np.zeros(0, np.float32)
    return _motion().curve_table(values)


def _key(inst) -> tuple:
    """The export's name of a depsgraph instance (addon.export.export_objects' ExportedObject.key)."""
    obj = inst.object
    if inst.is_instance:
        parent = inst.parent.original.name if inst.parent else ""
        return (obj.original.name, parent, tuple(inst.persistent_id))
    return (obj.original.name, "", ())


def _camera_matrix(cam_obj, depsgraph) -> np.ndarray:
    m = np.array(cam_obj.evaluated_get(depsgraph).matrix_world, np.float64)
    m[:3, :3] /= np.linalg.norm(m[:3, :3], axis=0, keepdims=True)  # Blender ignores the camera's scale
    return m


def _world_vertices(obj, matrix) -> np.ndarray | None:
    mesh = obj.to_mesh(preserve_all_data_layers=False)
    try:
        if mesh is None:
            return None
        v = np.empty(len(mesh.vertices) * 3, np.float32)
        mesh.vertices.foreach_get("co", v)
    finally:
        obj.to_mesh_clear()
    v = v.reshape(-1, 3).astype(np.float64)
    return v @ matrix[:3, :3].T + matrix[:3, 3]


def sample_motion(depsgraph, exported: list, warnings: list, frame_set=None):
    """Per exported object its S matrices (or None), per deforming object its S world-space vertex arrays, the
    camera's S matrices and the shutter table — or None when motion blur is off. ``frame_set(frame, subframe)``:
    the render engine's (default: the scene's)."""
    scene = depsgraph.scene
    r = scene.render
    if not getattr(r, "use_motion_blur", False):
        return None
    open_, close = _motion().blender_shutter(r.motion_blur_shutter, r.motion_blur_position)
    if not close > open_:
        return None
    moving = {o.key for o in exported}
    steps = 3
    for inst in depsgraph.object_instances:
        if _key(inst) in moving and _cycles(inst.object, "use_motion_blur", True):
            steps = max(steps, 2 * int(_cycles(inst.object, "motion_steps", 1)) + 1)
    frame, sub = scene.frame_current, scene.frame_subframe
    frame_set = frame_set or scene.frame_set
    times = _motion().step_times(frame + sub + open_, frame + sub + close, steps)
    mats = {k: [] for k in moving}
    verts: dict = {}
    cams = []
    cam_obj = scene.camera
    try:
        for t in times:
            whole = math.floor(t)
            frame_set(int(whole), subframe=float(t - whole))
            for inst in depsgraph.object_instances:
                k = _key(inst)
                if k not in mats:
                    continue
                obj = inst.object
                if not _cycles(obj, "use_motion_blur", True):
                    continue
                m = np.array(inst.matrix_world, np.float64)
                mats[k].append(m)
                if (not inst.is_instance and obj.type == "MESH" and _cycles(obj, "use_deform_motion", True)
                        and obj.is_deform_modified(scene, "RENDER")):
                    verts.setdefault(k, []).append(_world_vertices(obj, m))
            if cam_obj is not None:
                cams.append(_camera_matrix(cam_obj, depsgraph))
    finally:
        frame_set(int(frame), subframe=float(sub))
    objects = {k: np.stack(v) for k, v in mats.items() if len(v) == steps}
    deform = {}
    for k, vs in verts.items():
        if len(vs) == steps and all(v is not None and v.shape == vs[0].shape for v in vs):
            deform[k] = np.stack(vs)
        elif vs:
            warnings.append(f"object {k[0]!r}: its mesh changes topology across the shutter; no deformation blur")
    camera = np.stack(cams) if len(cams) == steps else None
    return {"steps": steps, "objects": objects, "deform": deform, "camera": camera, "curve": _shutter_curve(r)}


def _moves(m: np.ndarray) -> bool:
    return not np.allclose(m, m[:1], atol=1e-9, rtol=0)


def apply_motion(scene, exported: list, sampled) -> None:
    """Put ``sample_motion``'s result into ``scene`` (built by addon.export from ``exported``, object id i =
    ``exported[i]`` unless it became an instance): ``scene.motion`` and ``scene.camera.motion``."""
    if sampled is None:
        return
    s = sampled["steps"]
    if sampled["camera"] is not None and _moves(sampled["camera"]):
        scene.camera.motion = sampled["camera"]
        scene.camera.__post_init__()
    inst = scene.instances
    inst_row = {}
    if inst is not None:
        inst_row = {int(o): r for r, o in enumerate(inst.object_ids.tolist())}
    object_ids, object_motion, instance_motion = [], [], None
    vertices, deforming = None, []
    for i, o in enumerate(exported):
        steps = sampled["objects"].get(o.key)
        if i in inst_row:
            if steps is not None and _moves(steps):
                if instance_motion is None:
                    instance_motion = np.repeat(inst.transforms[:, None], s, axis=1)
                instance_motion[inst_row[i]] = steps
            continue
        placed = np.asarray(o.matrix, np.float64)
        world = sampled["deform"].get(o.key)
        if world is not None and _moves(world):
            rows = np.flatnonzero(scene.object_ids == i)
            if len(rows) == len(o.geometry["triangles"]):  # no triangle dropped: corner k of row j is mesh corner k
                if vertices is None:
                    vertices = np.repeat(scene.vertices[None], s, axis=0)
                corners = scene.triangles[rows].reshape(-1)
                vertices[:, corners] = world[:, o.geometry["triangles"].reshape(-1)]
                deforming.append(i)
                continue
        if steps is not None and _moves(steps):
            object_ids.append(i)
            object_motion.append(steps @ np.linalg.inv(placed))
    motion = _motion().Motion(
        steps=s, object_ids=np.asarray(object_ids, np.int32),
        object_motion=np.stack(object_motion) if object_motion else np.zeros((0, s, 4, 4)),
        instance_motion=instance_motion, vertices=vertices, deforming=np.asarray(deforming, np.int32),
        curve=sampled["curve"])
    scene.motion = motion
    scene.validate_motion()

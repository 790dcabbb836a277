"""Light linking, shadow linking and ray visibility: which objects a light lights, which objects its shadow rays
see, and which rays see an object (Blender's Object ▸ Visibility ▸ Ray Visibility and Light/Shadow Linking, UsdLux
``collection:lightLink`` / ``collection:shadowLink`` and ``inputs:shadow:enable``).

The scene carries them as plain data:

- ``Scene.object_visibility``: (O,) uint8 per object id, the bits :data:`CAMERA` (eye rays and what passes through
  alpha from them), :data:`GLOSSY` (mirror / specular reflection rays), :data:`TRANSMISSION` (refraction rays) and
  :data:`SHADOW` (casts shadows: shadow rays and sky-visibility rays see it). None = every object seen by every ray.
- ``Scene.light_links``: one :class:`LightLink` per light of ``Scene.lights`` (or an empty list): the receivers it
  lights, the blockers its shadow rays see, whether it casts shadows at all, and whether it gives diffuse / glossy
  light (Blender light ``visible_diffuse`` / ``visible_glossy``: Cycles drops the diffuse / glossy closures from
  that light's samples).
- ``Scene.emitter_links``: {object id: :class:`LightLink`} for emitting objects that are linked (Blender's light
  linking on an emissive mesh): each such object's triangles become a MESH light of their own
  (:func:`tracer.lights.emitters.pack_lights`), linked like a lamp; the unlinked emitters stay one light, never linked.

How the tracer spends them (:func:`pack`):

- Ray visibility and shadow linking are Embree *masks*: every top-level geometry gets a 32-bit mask, every ray one
  too, and Embree skips a geometry whose mask ANDs to zero with the ray's. Bits 0-2 are the ray types above; bit
  3 + k is *blocker set* k, set 0 being "every object that casts shadows", 1.. the distinct blocker sets of the
  lights (up to :data:`MAX_BLOCKER_SETS`). A shadow ray of light j carries the single bit of its light's set (0 when
  the light casts no shadow: nothing blocks it). So a shadow ray never meets a non-blocker: no re-tracing, no
  filter callback, the same one Embree query as without linking.
- Light linking is a bitmask per object: bit r set = the object is in *receiver set* r (the distinct receiver sets
  of the lights, up to 64 in one uint64). The direct-light stage skips light j at a hit whose object lacks bit
  ``recv_set[j]`` (-1: the light lights everything).

A scene without any of these packs to "inactive" tables and costs nothing: every geometry keeps the all-ones mask,
every ray the constant all-ones mask, the direct-light stage tests one boolean per hit.

Limits: the instance array (``Scene.instances``) is one Embree geometry, so all its instances share one mask (the
union of their objects' masks, with one warning when they differ); the light of the unlinked emitting triangles
is never linked; a ray that passes through an alpha < 1 surface keeps the mask of a camera
ray at depth 0 and of "glossy or transmission" deeper.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..jit import kernel
from . import emitters

#: Ray visibility bits of ``Scene.object_visibility`` (and the low bits of the Embree masks).
CAMERA, GLOSSY, TRANSMISSION, SHADOW = 1, 2, 4, 8
ALL_VISIBLE = CAMERA | GLOSSY | TRANSMISSION | SHADOW
#: Embree mask bit of blocker set 0 (SHADOW); blocker set k is bit SHADOW_BIT + k.
SHADOW_BIT = 3
MAX_BLOCKER_SETS = 32 - SHADOW_BIT
MAX_RECEIVER_SETS = 64
#: The mask of a geometry (or ray) that sees (is seen by) everything.
MASK_ALL = 0xFFFFFFFF


@dataclass
class LightLink:
    """Linking of one light. ``receivers``: object ids it lights (None: all); ``blockers``: object ids whose shadows
    it casts (None: every object that casts shadows); ``cast_shadow``: False = its shadow rays are never blocked;
    ``diffuse`` / ``glossy``: factors of its diffuse / glossy (specular) light (Blender's visibility: 1 or 0;
    UsdLux ``inputs:diffuse`` / ``inputs:specular``)."""

    receivers: np.ndarray | None = None
    blockers: np.ndarray | None = None
    cast_shadow: bool = True
    diffuse: float = 1.0
    glossy: float = 1.0
    #: factors of the light's shape as camera and refraction rays see it (Blender's ``visible_camera`` /
    #: ``visible_transmission``: 1 or 0; Cycles' defaults, measured: hidden from the camera, seen through glass). Its
    #: shape in mirrors is its glossy light: ``glossy``. (Only lights with a shape: tracer.lights.emitters.hittable)
    camera: float = 0.0
    transmission: float = 1.0

    def is_default(self) -> bool:
        return (self.receivers is None and self.blockers is None and self.cast_shadow and self.diffuse == 1.0
                and self.glossy == 1.0 and self.camera == 0.0 and self.transmission == 1.0)


class Links(NamedTuple):
    """What the integrator reads (:func:`pack`). ``receivers``: any light linked to receivers; ``recv_set`` (L,)
    int64 per light of the light tables (-1: lights all); ``object_recv`` (O,) uint64 receiver-set bits per object
    id; ``diffuse`` / ``glossy`` (L,) float64 0/1 factors; ``shadow_mask`` (L + 1,) uint32, the Embree mask of light
    j's shadow rays, the last entry the sky rays' (so ``shadow_mask[light]`` with light -1 reads it);
    ``visibility``: the ray-type masks are needed (some object hidden from some ray type); ``masked``: geometry masks
    are set (visibility or shadow linking); ``object_mask`` (O,) uint32 per object id and ``array_mask`` (the
    instance array's) when masked. ``seen`` (L, 3) float64: per light, the factor of its shape as camera, mirror
    (glossy) and refraction rays see it (0 for lights without a shape and for MESH lights, which are geometry);
    ``any_seen``: some light's shape is seen by some ray type. ``visible`` (L, 3): the same factors for every light,
    shape or not (what rough glass's light samples of a lamp take: tracer.integrator.wavefront._glass_light)."""

    receivers: bool
    recv_set: np.ndarray
    object_recv: np.ndarray
    diffuse: np.ndarray
    glossy: np.ndarray
    shadow_mask: np.ndarray
    visibility: bool
    masked: bool
    object_mask: np.ndarray
    array_mask: int
    seen: np.ndarray
    any_seen: bool
    visible: np.ndarray


def _object_count(scene) -> int:
    n = int(scene.object_ids.max()) + 1 if len(scene.object_ids) else 0
    if scene.instances is not None and len(scene.instances):
        n = max(n, int(scene.instances.object_ids.max()) + 1, int(scene.instances.prototypes.max()) + 1)
    return max(n, len(scene.object_names))


def _ids(a, n_objects: int, what: str) -> np.ndarray | None:
    if a is None:
        return None
    ids = np.unique(np.asarray(a, np.int64).reshape(-1))
    if len(ids) and (ids[0] < 0 or ids[-1] >= n_objects):
        raise ValueError(f"scene.light_links: {what} names object id {int(ids[0] if ids[0] < 0 else ids[-1])}, "
                         f"outside the scene's {n_objects} objects")
    return ids


def _sets(members: list, limit: int, what: str) -> tuple[list, np.ndarray]:
    """Distinct id sets (None = all) → (the distinct sets, the set index per light, -1 for None)."""
    distinct: list = []
    index = np.full(len(members), -1, np.int64)
    for j, ids in enumerate(members):
        if ids is None:
            continue
        for k, d in enumerate(distinct):
            if np.array_equal(d, ids):
                index[j] = k
                break
        else:
            if len(distinct) == limit:
                warnings.warn(f"light linking: more than {limit} distinct {what} sets; the light "
                              f"{j} lights/shadows as if unlinked", stacklevel=3)
                continue
            distinct.append(ids)
            index[j] = len(distinct) - 1
    return distinct, index


def pack(scene, n_lights: int, emitter_object: np.ndarray | None = None) -> Links:
    """The scene's visibility and links as :class:`Links` for ``n_lights`` lights of the light tables: the scene's
    lights, then its MESH lights, ``emitter_object`` (L,) naming each one's object (``LightTables.emitter_object``;
    -1, or None for all: the unlinked emitters). The receiver and blocker sets are numbered over the lamps' links
    then ``scene.emitter_links`` by object id, whatever emits: the accelerator's masks (packed without the light
    tables) agree with the integrator's."""
    n_obj = _object_count(scene)
    links = list(getattr(scene, "light_links", None) or [])
    if links and len(links) != len(scene.lights):  # e.g. a Session's update_lights: the links were for other lights
        warnings.warn(f"light linking: scene.light_links has {len(links)} entries for {len(scene.lights)} lights; "
                      "the lights are rendered unlinked", stacklevel=2)
        links = []
    emitter_links = dict(getattr(scene, "emitter_links", None) or {})
    # entries: the lamps' links, then the emitters' by object id; row_entry: each light-table row's entry (-1: none)
    entries = links + [emitter_links[o] for o in sorted(emitter_links)]
    for j, link in enumerate(entries):
        if not isinstance(link, LightLink):
            raise ValueError(f"scene.light_links / emitter_links entry {j} is not a tracer.lights.linking.LightLink")
    vis = getattr(scene, "object_visibility", None)
    if vis is not None:
        vis = np.asarray(vis)
        if vis.ndim != 1 or (vis.size and not np.issubdtype(vis.dtype, np.integer)):
            raise ValueError(f"scene.object_visibility must be a 1-D integer array, got shape {vis.shape}")
        full = np.full(n_obj, ALL_VISIBLE, np.uint32)
        full[:min(len(vis), n_obj)] = vis[:n_obj] & ALL_VISIBLE
        vis = full
    row_entry = np.full(n_lights, -1, np.int64)
    row_entry[:len(links)] = np.arange(len(links))
    if emitter_object is not None:
        where = {o: len(links) + e for e, o in enumerate(sorted(emitter_links))}
        for j, o in enumerate(np.asarray(emitter_object)[:n_lights]):
            if o >= 0 and j >= len(scene.lights):
                row_entry[j] = where.get(int(o), -1)
    receivers = [_ids(k.receivers, n_obj, "receivers") for k in entries]
    blockers = [_ids(k.blockers, n_obj, "blockers") for k in entries]
    recv_sets, entry_recv = _sets(receivers, MAX_RECEIVER_SETS, "receiver")
    block_sets, entry_block = _sets(blockers, MAX_BLOCKER_SETS - 1, "blocker")
    recv_set = np.where(row_entry >= 0, entry_recv[np.maximum(row_entry, 0)] if len(entries) else -1, -1)
    block_set = np.where(row_entry >= 0, entry_block[np.maximum(row_entry, 0)] if len(entries) else -1, -1)

    object_recv = np.zeros(n_obj, np.uint64)
    for r, ids in enumerate(recv_sets):
        object_recv[ids] |= np.uint64(1) << np.uint64(r)
    diffuse = np.ones(n_lights, np.float64)
    glossy = np.ones(n_lights, np.float64)
    shadow_mask = np.full(n_lights + 1, 1 << SHADOW_BIT, np.uint32)
    for j in np.flatnonzero(row_entry >= 0):
        link = entries[row_entry[j]]
        diffuse[j], glossy[j] = float(link.diffuse), float(link.glossy)
        if not link.cast_shadow:
            shadow_mask[j] = 0
        elif block_set[j] >= 0:
            shadow_mask[j] = 1 << (SHADOW_BIT + 1 + int(block_set[j]))
    hidden = vis is not None and bool(np.any(vis != ALL_VISIBLE))
    masked = hidden or bool(block_sets) or any(not k.cast_shadow for k in entries)
    object_mask = np.zeros(0, np.uint32)
    array_mask = MASK_ALL
    if masked:
        v = vis if vis is not None else np.full(n_obj, ALL_VISIBLE, np.uint32)
        object_mask = v.astype(np.uint32)  # bits 0-3: the ray types and blocker set 0
        casts = (v & SHADOW) != 0
        for k, ids in enumerate(block_sets):
            object_mask[ids[casts[ids]]] |= np.uint32(1 << (SHADOW_BIT + 1 + k))
        inst = scene.instances
        if inst is not None and len(inst):
            m = object_mask[inst.object_ids]
            if np.any(m != m[0]):
                warnings.warn("ray visibility / shadow linking: the instanced objects differ; all instances of "
                              "the instance array use the union of their settings", stacklevel=2)
            array_mask = int(np.bitwise_or.reduce(m))
    seen = np.zeros((n_lights, 3), np.float64)  # camera, glossy (mirror), transmission (refraction)
    visible = np.zeros((n_lights, 3), np.float64)
    for j, light in enumerate(list(scene.lights)[:n_lights]):
        link = entries[row_entry[j]] if row_entry[j] >= 0 else LightLink()
        visible[j] = (float(link.camera), float(link.glossy), float(link.transmission))
        if emitters.hittable(light):
            seen[j] = visible[j]
    return Links(receivers=bool(recv_sets), recv_set=recv_set, object_recv=object_recv, diffuse=diffuse,
                 glossy=glossy, shadow_mask=shadow_mask, visibility=hidden, masked=masked,
                 object_mask=object_mask, array_mask=array_mask, seen=seen, any_seen=bool(np.any(seen > 0)),
                 visible=visible)


@kernel(inline=True)
def lights_receiver(recv_set, bits):
    """A light of receiver set ``recv_set`` (-1: it lights everything) lights an object of receiver ``bits``."""
    return recv_set < 0 or ((bits >> np.uint64(recv_set)) & np.uint64(1)) != np.uint64(0)


def receiver_bits(links: Links, prim: np.ndarray, inst: np.ndarray, object_ids: np.ndarray,
                  instance_object_ids: np.ndarray) -> np.ndarray:
    """Per ray of a batch, the receiver-set bits of the object it hit (uint64; 0 on a miss); empty when no light
    is linked to receivers (the direct-light stage then lights everything)."""
    if not links.receivers:
        return np.zeros(0, np.uint64)
    hit = prim >= 0
    obj = np.where(hit, object_ids[np.maximum(prim, 0)], 0)
    if len(instance_object_ids):
        on_inst = hit & (inst >= 0)
        obj = np.where(on_inst, instance_object_ids[np.maximum(inst, 0)], obj)
    bits = links.object_recv[obj]
    bits[~hit] = 0
    return bits


def ray_masks(links: Links, depth: int, n: int, n_reflected: int) -> np.ndarray | None:
    """The Embree masks of a batch of n rays of ``depth`` (the first ``n_reflected`` reflections, the rest
    transmissions): None when no object is hidden from any ray type (every ray sees everything)."""
    if not links.visibility:
        return None
    if depth == 0:
        return np.full(1, CAMERA, np.uint32)
    m = np.full(n, TRANSMISSION, np.uint32)
    m[:n_reflected] = GLOSSY
    return m


def through_mask(links: Links, depth: int) -> np.ndarray | None:
    """The mask of rays passing through alpha < 1 surfaces at ``depth`` (see the module's limits)."""
    if not links.visibility:
        return None
    return np.full(1, CAMERA if depth == 0 else GLOSSY | TRANSMISSION, np.uint32)


def shadow_masks(links: Links, light: np.ndarray) -> np.ndarray | None:
    """The Embree mask of each shadow ray (light index per ray, -1 = sky): None when every shadow ray sees every
    shadow caster and no object hides from shadows."""
    if not links.masked:
        return None
    return np.ascontiguousarray(links.shadow_mask[light])

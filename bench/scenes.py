"""The benchmark scenes, built in Python (no downloads), in one renderer-neutral form.

A :class:`BenchScene` holds meshes in object space, instances of them (mesh index + object-to-world 4×4), a material
table (the fields of :func:`tracer.SceneBuilder.add_material`), point lights, a camera and the world colours. The
writers turn it into a :class:`tracer.Scene` (:func:`to_tracer`, instances flattened), POV-Ray SDL
(:mod:`bench.povray`), USD (:mod:`bench.usd`) and a Blender scene for Cycles (:mod:`bench.cycles`), so every
renderer traces the same triangles.

Scenes:

- ``whitted``   Whitted's 1980 picture (``examples/whitted_1980.py``): checkered floor, a mirror and a glass sphere
  (64×64 UV spheres), two point lights, blue sky.
- ``heavy``     ≈ 1 M triangles: a mirror and a glass icosphere (subdivision 7, 327 680 triangles each), a diffuse
  torus (≈ 330 k triangles), a floor, three point lights.
- ``instances`` 2 500 instances (50 × 50 grid) of a 320-triangle icosphere, each scaled, rotated and coloured
  differently, every 7th a mirror and every 11th glass, on a floor, two lights (800 k triangles flattened).
- ``tiny``      a small smoke-test scene (a mirror, a glass ball and two instanced diffuse balls on a floor).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import trimesh

from tracer import Camera, PointLight, SceneBuilder
from tracer.camera import fit_apertures

SCENES = ("whitted", "heavy", "instances")
ALL_SCENES = SCENES + ("tiny",)


@dataclass
class Mesh:
    name: str
    vertices: np.ndarray  # (V, 3) object space
    faces: np.ndarray  # (F, 3)
    normals: np.ndarray | None = None  # (V, 3) smooth shading normals, or None for flat shading
    material: int | np.ndarray = 0  # one index or (F,) per face


@dataclass
class Instance:
    mesh: int
    transform: np.ndarray = field(default_factory=lambda: np.eye(4))  # object -> world, p' = M @ p
    material: int | None = None  # overrides a single-material mesh's material


@dataclass
class BenchScene:
    name: str
    meshes: list
    instances: list
    materials: list  # dicts: name + SceneBuilder.add_material fields (diffuse, specular, roughness, k_m, ...)
    lights: list  # tracer.PointLight
    eye: tuple
    target: tuple
    up: tuple = (0.0, 0.0, 1.0)
    focal_length: float = 35.0
    horizontal_aperture: float = 36.0
    background: tuple = (0.0, 0.0, 0.0)
    ambient: tuple = (0.0, 0.0, 0.0)

    @property
    def triangle_count(self) -> int:
        return int(sum(len(self.meshes[i.mesh].faces) for i in self.instances))

    def camera(self, width: int, height: int) -> Camera:
        """The camera with its vertical aperture fitted to the image aspect (horizontal aperture kept)."""
        h, v = fit_apertures(self.horizontal_aperture, 1.0, width, height, policy="horizontal")
        return Camera.look_at(self.eye, self.target, up=self.up, focal_length=self.focal_length,
                              horizontal_aperture=h, vertical_aperture=v)

    def instance_material(self, inst: Instance) -> int | np.ndarray:
        return self.meshes[inst.mesh].material if inst.material is None else inst.material


def to_tracer(bs: BenchScene, width: int, height: int, instanced: bool = False):
    """``bs`` as a :class:`tracer.Scene` for a ``width`` × ``height`` image: every instance flattened into world
    triangles, or (``instanced``) each mesh placed more than once stored once and drawn through
    :meth:`tracer.SceneBuilder.add_instances` (the same picture: tests/test_instances.py)."""
    b = SceneBuilder()
    for m in bs.materials:
        b.add_material(**m)
    uses = np.bincount([i.mesh for i in bs.instances], minlength=len(bs.meshes))
    shared = {}
    for k, inst in enumerate(bs.instances):
        mesh = bs.meshes[inst.mesh]
        if instanced and uses[inst.mesh] > 1 and np.ndim(mesh.material) == 0:
            shared.setdefault(inst.mesh, []).append(inst)
            continue
        b.add_mesh(mesh.vertices, mesh.faces, material=bs.instance_material(inst), name=f"{mesh.name}_{k}",
                   transform=inst.transform, normals=mesh.normals)
    for index, insts in shared.items():
        mesh = bs.meshes[index]
        proto = b.add_mesh(mesh.vertices, mesh.faces, material=mesh.material, name=mesh.name, normals=mesh.normals)
        b.add_instances(proto, np.stack([i.transform for i in insts]),
                        materials=np.array([-1 if i.material is None else i.material for i in insts]))
    for light in bs.lights:
        b.add_light(light)
    b.camera = bs.camera(width, height)
    b.background = np.array(bs.background, np.float32)
    b.ambient = np.array(bs.ambient, np.float32)
    return b.build()


# ---------------------------------------------------------------------------------------------- building blocks
def _uv_sphere(name, radius, material, count=64, center=(0.0, 0.0, 0.0)):
    m = trimesh.creation.uv_sphere(radius=radius, count=[count, count])
    return Mesh(name, m.vertices + np.asarray(center), m.faces, m.vertices / radius, material)


def _icosphere(name, radius, material, subdivisions, center=(0.0, 0.0, 0.0)):
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return Mesh(name, m.vertices + np.asarray(center), m.faces, m.vertices / radius, material)


def _checker_floor(name, red, yellow, extent, square=1.0):
    """Quads of ``square`` size (two triangles each), alternating materials; mirrors examples/whitted_1980.py."""
    (x0, x1), (y0, y1) = extent
    gx, gy = np.meshgrid(np.arange(x0, x1, square), np.arange(y0, y1, square), indexing="ij")
    gx, gy = gx.ravel(), gy.ravel()
    corners = np.stack([np.stack([gx, gy], -1), np.stack([gx + square, gy], -1),
                        np.stack([gx + square, gy + square], -1), np.stack([gx, gy + square], -1)], axis=1)
    verts = np.concatenate([corners, np.zeros(corners.shape[:2] + (1,))], axis=-1).reshape(-1, 3)
    q = np.arange(len(gx))[:, None] * 4
    faces = np.concatenate([q + [0, 1, 2], q + [0, 2, 3]], axis=0)
    parity = ((np.floor(gx / square) + np.floor(gy / square)) % 2).astype(int)
    mats = np.where(np.concatenate([parity, parity]) == 0, red, yellow).astype(np.int32)
    return Mesh(name, verts, faces, None, mats)


def _identity(n):
    return [Instance(i) for i in range(n)]


# ---------------------------------------------------------------------------------------------- the scenes
SKY = (0.12, 0.32, 0.85)
#: Point-light radiant intensity in W/sr, as examples/whitted_1980.py.
LIGHT_INTENSITY = 120.0


def whitted() -> BenchScene:
    """Whitted's 1980 picture, the same as ``examples/whitted_1980.py`` (kept in step by tests/test_bench.py)."""
    mats = [
        dict(name="Red", diffuse=(0.75, 0.05, 0.03), specular=(0.04,) * 3, roughness=0.5),
        dict(name="Yellow", diffuse=(0.8, 0.7, 0.05), specular=(0.04,) * 3, roughness=0.5),
        dict(name="Mirror", diffuse=(0.05, 0.05, 0.05), specular=(0.5,) * 3, roughness=0.15, k_m=0.85),
        dict(name="Glass", diffuse=(0.0, 0.0, 0.0), specular=(0.5,) * 3, roughness=0.1, transmission=1.0, ior=1.5),
    ]
    meshes = [_checker_floor("Floor", 0, 1, ((-6, 6), (-3, 15))),
              _uv_sphere("MirrorSphere", 1.25, 2, center=(-1.0, 4.2, 1.25)),
              _uv_sphere("GlassSphere", 0.85, 3, center=(0.9, 1.6, 1.35))]
    lights = [PointLight(position=(-4.0, -3.0, 9.0), intensity=(LIGHT_INTENSITY,) * 3, name="Key"),
              PointLight(position=(6.0, -1.0, 6.0), intensity=(0.6 * LIGHT_INTENSITY,) * 3, name="Fill")]
    return BenchScene("whitted", meshes, _identity(3), mats, lights, eye=(0.0, -4.5, 2.0), target=(0.0, 3.0, 1.0),
                      background=SKY, ambient=tuple(0.15 * c for c in SKY))


def heavy() -> BenchScene:
    """≈ 1 M triangles: two subdivision-7 icospheres (mirror, glass) and a dense torus on a floor."""
    mats = [
        dict(name="Floor", diffuse=(0.6, 0.6, 0.55), specular=(0.04,) * 3, roughness=0.5),
        dict(name="Mirror", diffuse=(0.05, 0.05, 0.05), specular=(0.5,) * 3, roughness=0.15, k_m=0.85),
        dict(name="Glass", diffuse=(0.0, 0.0, 0.0), specular=(0.5,) * 3, roughness=0.1, transmission=1.0, ior=1.5),
        dict(name="Torus", diffuse=(0.2, 0.35, 0.7), specular=(0.2,) * 3, roughness=0.3),
    ]
    torus = trimesh.creation.torus(major_radius=1.0, minor_radius=0.35, major_sections=576, minor_sections=288)
    # Torus normals: from the tube's centre circle to the vertex.
    ring = torus.vertices.copy()
    ring[:, 2] = 0.0
    ring /= np.linalg.norm(ring, axis=1, keepdims=True)
    tn = torus.vertices - ring * 1.0
    tn /= np.linalg.norm(tn, axis=1, keepdims=True)
    rot = trimesh.transformations.rotation_matrix(np.radians(60), [1, 0, 0])
    tv = trimesh.transform_points(torus.vertices, rot) + [0.0, 5.0, 1.3]
    tn = tn @ rot[:3, :3].T
    floor = Mesh("Floor", np.array([[-10, -5, 0], [10, -5, 0], [10, 20, 0], [-10, 20, 0]], float),
                 np.array([[0, 1, 2], [0, 2, 3]]), None, 0)
    meshes = [floor, _icosphere("MirrorBall", 1.2, 1, 7, center=(-1.8, 3.5, 1.2)),
              _icosphere("GlassBall", 0.9, 2, 7, center=(1.2, 1.5, 0.9)),
              Mesh("Torus", tv, torus.faces, tn, 3)]
    lights = [PointLight(position=(-4.0, -3.0, 9.0), intensity=(100.0,) * 3, name="Key"),
              PointLight(position=(6.0, -1.0, 6.0), intensity=(60.0,) * 3, name="Fill"),
              PointLight(position=(0.0, 12.0, 5.0), intensity=(40.0,) * 3, name="Back")]
    return BenchScene("heavy", meshes, _identity(4), mats, lights, eye=(0.0, -4.5, 2.2), target=(0.0, 3.5, 1.0),
                      background=(0.05, 0.05, 0.08), ambient=(0.02, 0.02, 0.03))


def instances(grid: int = 50, subdivisions: int = 2) -> BenchScene:
    """``grid``² instances of one icosphere, each its own scale, rotation and material."""
    rng = np.random.default_rng(1980)
    colours = [(0.8, 0.2, 0.1), (0.1, 0.6, 0.2), (0.15, 0.3, 0.8), (0.85, 0.75, 0.1)]
    mats = [dict(name="Floor", diffuse=(0.5, 0.5, 0.5), specular=(0.04,) * 3, roughness=0.5)]
    mats += [dict(name=f"Paint{i}", diffuse=c, specular=(0.1,) * 3, roughness=0.35) for i, c in enumerate(colours)]
    mirror = len(mats)
    mats.append(dict(name="Mirror", diffuse=(0.05, 0.05, 0.05), specular=(0.5,) * 3, roughness=0.15, k_m=0.85))
    glass = len(mats)
    mats.append(dict(name="Glass", diffuse=(0.0, 0.0, 0.0), specular=(0.5,) * 3, roughness=0.1,
                     transmission=1.0, ior=1.5))
    floor = Mesh("Floor", np.array([[-40, -10, 0], [40, -10, 0], [40, 80, 0], [-40, 80, 0]], float),
                 np.array([[0, 1, 2], [0, 2, 3]]), None, 0)
    ball = _icosphere("Ball", 1.0, 1, subdivisions)
    insts = [Instance(0)]
    spacing = 1.2
    for k in range(grid * grid):
        i, j = divmod(k, grid)
        s = rng.uniform(0.25, 0.5, 3)
        r = trimesh.transformations.random_rotation_matrix(rng.random(3))
        m = r @ np.diag([s[0], s[1], s[2], 1.0])
        m[:3, 3] = [(i - grid / 2 + 0.5) * spacing, j * spacing, s.max()]
        mat = mirror if k % 7 == 0 else glass if k % 11 == 0 else 1 + k % len(colours)
        insts.append(Instance(1, m, mat))
    lights = [PointLight(position=(-10.0, -5.0, 15.0), intensity=(400.0,) * 3, name="Key"),
              PointLight(position=(12.0, 20.0, 10.0), intensity=(250.0,) * 3, name="Fill")]
    return BenchScene("instances", [floor, ball], insts, mats, lights, eye=(0.0, -8.0, 7.0),
                      target=(0.0, 18.0, 0.0), focal_length=30.0, background=SKY,
                      ambient=tuple(0.1 * c for c in SKY))


def tiny() -> BenchScene:
    """A few hundred triangles with every material kind and an instanced mesh: the smoke test's scene."""
    mats = [dict(name="Floor", diffuse=(0.6, 0.6, 0.6), specular=(0.04,) * 3, roughness=0.5),
            dict(name="Mirror", diffuse=(0.05, 0.05, 0.05), specular=(0.5,) * 3, roughness=0.15, k_m=0.85),
            dict(name="Glass", diffuse=(0.0, 0.0, 0.0), specular=(0.5,) * 3, roughness=0.1, transmission=1.0,
                 ior=1.5),
            dict(name="Red", diffuse=(0.8, 0.1, 0.1), specular=(0.1,) * 3, roughness=0.3)]
    floor = Mesh("Floor", np.array([[-5, -5, 0], [5, -5, 0], [5, 10, 0], [-5, 10, 0]], float),
                 np.array([[0, 1, 2], [0, 2, 3]]), None, 0)
    meshes = [floor, _icosphere("MirrorBall", 1.0, 1, 2, center=(-1.0, 3.0, 1.0)),
              _icosphere("GlassBall", 0.7, 2, 2, center=(1.0, 1.5, 0.7)), _icosphere("Ball", 0.4, 3, 1)]
    t1, t2 = np.eye(4), np.eye(4)
    t1[:3, 3] = (1.8, 4.0, 0.4)
    t2[:3, 3] = (-2.5, 1.5, 0.4)
    insts = _identity(3) + [Instance(3, t1), Instance(3, t2)]
    lights = [PointLight(position=(-4.0, -3.0, 9.0), intensity=(100.0,) * 3, name="Key"),
              PointLight(position=(6.0, -1.0, 6.0), intensity=(60.0,) * 3, name="Fill")]
    return BenchScene("tiny", meshes, insts, mats, lights, eye=(0.0, -4.5, 2.0), target=(0.0, 3.0, 0.8),
                      background=SKY, ambient=tuple(0.15 * c for c in SKY))


BUILDERS = {"whitted": whitted, "heavy": heavy, "instances": instances, "tiny": tiny}


def build(name: str) -> BenchScene:
    if name not in BUILDERS:
        raise ValueError(f"unknown bench scene {name!r}; choose from {', '.join(BUILDERS)}")
    return BUILDERS[name]()

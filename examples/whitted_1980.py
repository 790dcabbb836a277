"""Whitted's 1980 picture, built with the tracer's Python API: a mirror sphere and a glass sphere over a red and
yellow checkered floor, under two point lights and a blue sky. Z is up (Blender's and Blender-exported USD's axis).

    python examples/whitted_1980.py -o whitted.png
"""

from __future__ import annotations

import argparse

import numpy as np
import trimesh

from tracer import Camera, PointLight, RenderSettings, SceneBuilder, render

SKY = (0.12, 0.32, 0.85)
#: Point-light radiant intensity in W/sr (a Blender point light of P watts has P / 4π).
LIGHT_INTENSITY = 120.0


def checker_floor(b: SceneBuilder, red: int, yellow: int, extent=((-6, 6), (-3, 15)), square=1.0):
    (x0, x1), (y0, y1) = extent
    xs = np.arange(x0, x1, square)
    ys = np.arange(y0, y1, square)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    gx, gy = gx.ravel(), gy.ravel()
    corners = np.stack([
        np.stack([gx, gy], -1), np.stack([gx + square, gy], -1),
        np.stack([gx + square, gy + square], -1), np.stack([gx, gy + square], -1)], axis=1)  # (Q, 4, 2)
    verts = np.concatenate([corners, np.zeros(corners.shape[:2] + (1,))], axis=-1).reshape(-1, 3)
    q = np.arange(len(gx))[:, None] * 4
    tris = np.concatenate([q + [0, 1, 2], q + [0, 2, 3]], axis=0)
    parity = ((np.floor(gx / square) + np.floor(gy / square)) % 2).astype(int)
    mats = np.where(np.concatenate([parity, parity]) == 0, red, yellow)
    b.add_mesh(verts, tris, material=mats, name="Floor", normals=np.tile([0.0, 0.0, 1.0], (len(verts), 1)))


def sphere(b: SceneBuilder, center, radius, material, name, count=64):
    m = trimesh.creation.uv_sphere(radius=radius, count=[count, count])
    b.add_mesh(m.vertices + np.asarray(center), m.faces, material=material, name=name, normals=m.vertices / radius)


def build_scene() -> "tracer.Scene":
    b = SceneBuilder()
    red = b.add_material("Red", diffuse=(0.75, 0.05, 0.03), specular=(0.04,) * 3, roughness=0.5)
    yellow = b.add_material("Yellow", diffuse=(0.8, 0.7, 0.05), specular=(0.04,) * 3, roughness=0.5)
    mirror = b.add_material("Mirror", diffuse=(0.05, 0.05, 0.05), specular=(0.5,) * 3, roughness=0.15, k_m=0.85)
    glass = b.add_material("Glass", diffuse=(0.0, 0.0, 0.0), specular=(0.5,) * 3, roughness=0.1,
                           transmission=1.0, ior=1.5)
    checker_floor(b, red, yellow)
    sphere(b, (-1.0, 4.2, 1.25), 1.25, mirror, "MirrorSphere")
    sphere(b, (0.9, 1.6, 1.35), 0.85, glass, "GlassSphere")
    b.add_light(PointLight(position=(-4.0, -3.0, 9.0), intensity=(LIGHT_INTENSITY,) * 3, name="Key"))
    b.add_light(PointLight(position=(6.0, -1.0, 6.0), intensity=(0.6 * LIGHT_INTENSITY,) * 3, name="Fill"))
    b.camera = Camera.look_at((0.0, -4.5, 2.0), (0.0, 3.0, 1.0), up=(0, 0, 1), focal_length=35.0,
                              horizontal_aperture=36.0, vertical_aperture=20.25)
    b.background = np.array(SKY, np.float32)
    b.ambient = np.array(SKY, np.float32) * 0.15
    return b.build()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--output", default="whitted.png")
    ap.add_argument("--width", type=int, default=960)
    ap.add_argument("--height", type=int, default=540)
    ap.add_argument("--spp", type=int, default=2, help="N for N×N anti-aliasing samples")
    ap.add_argument("--threads", type=int, default=None)
    args = ap.parse_args(argv)
    scene = build_scene()
    image = render(scene, RenderSettings(width=args.width, height=args.height, samples=args.spp,
                                         threads=args.threads, progress=True))
    image.save(args.output)
    s = image.stats
    print(f"{args.output}: {args.width}x{args.height}, {s['rays']['total']:,} rays in {s['seconds']:.2f} s "
          f"({s['rays_per_second'] / 1e6:.2f} M rays/s)")


if __name__ == "__main__":
    main()

"""tracer.shading.procedural against closed forms and independent references (the Cycles comparison is
tests/cycles/test_cycles_procedural.py; these catch a broken building block without Blender)."""

from __future__ import annotations

import colorsys

import numpy as np
import pytest

from tracer.shading.procedural import color, noise, patterns, voronoi

RNG = np.random.default_rng(7)


def test_perlin_noise_vanishes_on_the_lattice():
    """Gradient noise is zero at integer points: normalised fBM of one octave is exactly 0.5 there, in every
    dimension, and not elsewhere."""
    pts = RNG.integers(-50, 50, (200, 3)).astype(np.float64)
    for dim in (1, 2, 3, 4):
        fac, _ = noise.noise_texture_array(pts, pts[:, 0] + 3.0, dimensions=dim, scale=1.0, detail=0.0)
        assert np.all(fac == 0.5), dim
        off, _ = noise.noise_texture_array(pts + 0.37, pts[:, 0] + 3.37, dimensions=dim, scale=1.0, detail=0.0)
        assert np.mean(off == 0.5) < 0.05, dim


def test_noise_value_is_the_textures_fac():
    """noise_value (the Fac-only entry point the VM calls when Color is unused) equals noise_texture's Fac."""
    from tracer.jit import kernel

    @kernel
    def both(pts, out):
        for i in range(pts.shape[0]):
            p = (pts[i, 0], pts[i, 1], pts[i, 2], pts[i, 0] * 0.3)
            for dim in range(1, 5):
                f, c = noise.noise_texture(p, dim, noise.HETERO_TERRAIN, 2.0, 3.3, 0.6, 2.1, 0.4, 1.2, 0.7, True)
                out[i, dim - 1, 0] = f
                out[i, dim - 1, 1] = noise.noise_value(p, dim, noise.HETERO_TERRAIN, 2.0, 3.3, 0.6, 2.1, 0.4, 1.2,
                                                       0.7, True)

    out = np.empty((100, 4, 2))
    both(RNG.uniform(-3, 3, (100, 3)), out)
    assert np.array_equal(out[..., 0], out[..., 1])


def test_fbm3_is_the_general_3d_fbm():
    """fbm3 (the VM's path for an undistorted 3D fBM) gives noise_value's value to the bit, whole and fractional
    detail, normalised or not, on scattered points (every gradient of the lattice)."""
    from tracer.jit import kernel

    @kernel
    def both(pts, out):
        for i in range(pts.shape[0]):
            p = (pts[i, 0], pts[i, 1], pts[i, 2], 0.0)
            for k, (detail, norm) in enumerate(((0.0, True), (2.0, True), (2.6, True), (3.4, False))):
                out[i, k, 0] = noise.noise_value(p, 3, noise.FBM, 3.7, detail, 0.6, 2.2, 0.0, 1.0, 0.0, norm)
                out[i, k, 1] = noise.fbm3(p[0], p[1], p[2], 3.7, detail, 0.6, 2.2, norm)

    out = np.empty((500, 4, 2))
    both(RNG.uniform(-40, 40, (500, 3)), out)
    assert np.array_equal(out[..., 0], out[..., 1])


def test_gradient_closed_forms():
    p = RNG.uniform(-1.5, 1.5, (500, 3))
    x, y, z = p.T
    r = np.sqrt(x * x + y * y + z * z)
    expect = {"LINEAR": x, "QUADRATIC": np.maximum(x, 0) ** 2, "DIAGONAL": (x + y) / 2,
              "EASING": 3 * np.clip(x, 0, 1) ** 2 - 2 * np.clip(x, 0, 1) ** 3,
              "RADIAL": np.arctan2(y, x) / (2 * np.pi) + 0.5, "SPHERICAL": np.maximum(0.999999 - r, 0),
              "QUADRATIC_SPHERE": np.maximum(0.999999 - r, 0) ** 2}
    for kind, e in expect.items():
        np.testing.assert_allclose(patterns.gradient_array(p, gradient_type=kind), np.clip(e, 0, 1), atol=1e-6,
                                   err_msg=kind)


def test_hsv_hsl_match_colorsys():
    c = RNG.uniform(0, 1, (300, 3))
    hsv = np.array([colorsys.rgb_to_hsv(*row) for row in c])
    hls = np.array([colorsys.rgb_to_hls(*row) for row in c])
    np.testing.assert_allclose(color.convert_array(c, "rgb_to_hsv"), hsv, atol=1e-6)
    np.testing.assert_allclose(color.convert_array(c, "rgb_to_hsl"), hls[:, [0, 2, 1]], atol=1e-6)
    np.testing.assert_allclose(color.convert_array(hsv, "hsv_to_rgb"), c, atol=1e-6)
    np.testing.assert_allclose(color.convert_array(hls[:, [0, 2, 1]], "hsl_to_rgb"), c, atol=1e-6)


def test_mix_closed_forms():
    a, b = RNG.uniform(0, 1, (100, 3)), RNG.uniform(0.05, 1, (100, 3))
    t = RNG.uniform(0, 1, 100)[:, None]
    cases = {"MIX": (1 - t) * a + t * b, "MULTIPLY": (1 - t) * a + t * a * b, "ADD": a + t * b,
             "SCREEN": 1 - ((1 - t) + t * (1 - b)) * (1 - a), "DIFFERENCE": (1 - t) * a + t * np.abs(a - b),
             "LINEAR_LIGHT": a + t * (2 * b - 1), "DIVIDE": (1 - t) * a + t * a / b}
    for blend, e in cases.items():
        np.testing.assert_allclose(color.mix_color_array(blend, t[:, 0], a, b), e, atol=1e-6, err_msg=blend)


def test_color_ramp_linear_and_constant():
    stops = [0.2, 0.7]
    cols = [(1.0, 0.0, 0.5, 1.0), (0.0, 1.0, 0.5, 0.0)]
    f = np.linspace(0, 1, 101)
    lin = color.color_ramp_array(f, color.color_ramp_table(stops, cols, "LINEAR"))
    s = np.clip((f - 0.2) / 0.5, 0, 1)[:, None]
    np.testing.assert_allclose(lin, (1 - s) * np.array(cols[0]) + s * np.array(cols[1]), atol=2e-3)
    const = color.color_ramp_array(f, color.color_ramp_table(stops, cols, "CONSTANT"), interpolate=False)
    assert np.all(const[f < 0.69][:, 0] == 1.0) and np.all(const[f > 0.71][:, 1] == 1.0)


def test_wavelength_and_blackbody_shapes():
    # black outside the table; like Cycles, 375-380 nm still reads the first entry (C truncates -0.x to 0)
    assert np.all(color.wavelength_array([300.0, 374.0, 780.0, 900.0]) == 0)
    assert color.wavelength_array([379.0]).max() > 0
    green, red, blue = color.wavelength_array([530.0, 650.0, 450.0])
    assert green.argmax() == 1 and red.argmax() == 0 and blue.argmax() == 2
    warm, white, cold = color.blackbody_array([2000.0, 6500.0, 11000.0])
    assert warm[0] > warm[1] > warm[2] and cold[2] > cold[0]
    np.testing.assert_allclose(white, (1.0426, 0.9841, 1.0353), atol=2e-3)  # Cycles: not normalised to white


@pytest.mark.parametrize("dim", [1, 2, 3, 4])
def test_voronoi_without_randomness_is_the_distance_to_the_lattice(dim):
    """Randomness 0 puts every cell's point on its integer corner: F1 is the distance to the nearest integer point
    (per metric), F2 ≥ F1, smooth F1 ≤ F1."""
    p = RNG.uniform(-3, 3, (300, 3))
    w = RNG.uniform(-3, 3, 300)
    q = np.concatenate([p, w[:, None]], -1)[:, :dim] if dim > 1 else w[:, None]
    d = np.abs(q - np.round(q))
    expect = {"EUCLIDEAN": np.sqrt((d * d).sum(-1)), "MANHATTAN": d.sum(-1), "CHEBYCHEV": d.max(-1)}
    for metric, e in expect.items():
        out = voronoi.voronoi_texture_array(p, w, dimensions=dim, distance=metric, scale=1.0, randomness=0.0)
        np.testing.assert_allclose(out["Distance"], e if dim > 1 else d[:, 0], atol=1e-5, err_msg=metric)
    f1 = voronoi.voronoi_texture_array(p, w, dimensions=dim, scale=1.0)["Distance"]
    f2 = voronoi.voronoi_texture_array(p, w, dimensions=dim, feature="F2", scale=1.0)["Distance"]
    sm = voronoi.voronoi_texture_array(p, w, dimensions=dim, feature="SMOOTH_F1", scale=1.0)["Distance"]
    assert np.all(f2 >= f1) and np.all(sm <= f1 + 1e-6)


def test_float32_registers_give_the_float64_values():
    """A VM with a float32 register file passes float32 arguments: the fractal loops (which reassign the point)
    must still compile, and give the float64 result of the same float32 inputs to float32 precision."""
    from tracer.jit import kernel

    @kernel
    def run(regs, out):
        for i in range(regs.shape[0]):
            p = (regs[i, 0], regs[i, 1], regs[i, 2], regs[i, 3])
            out[i, 0] = noise.noise_value(p, 4, noise.HYBRID_MULTIFRACTAL, regs[i, 4], regs[i, 5], regs[i, 6],
                                          regs[i, 7], regs[i, 6], regs[i, 5], regs[i, 4], True)
            out[i, 1] = voronoi.voronoi_texture(p, 3, voronoi.F2, voronoi.MANHATTAN, regs[i, 4], regs[i, 5],
                                                regs[i, 6], regs[i, 7], regs[i, 6], regs[i, 5], regs[i, 6], True)[0]

    regs = RNG.uniform(0.1, 3.0, (40, 8)).astype(np.float32)
    out32, out64 = np.empty((40, 2)), np.empty((40, 2))
    run(regs, out32)
    run(regs.astype(np.float64), out64)
    np.testing.assert_allclose(out32, out64, rtol=1e-5, atol=1e-6)

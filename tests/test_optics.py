"""The seed's optics: reflection r = d − 2(d·n)n and Snell's-law transmission with total internal reflection."""

import numpy as np
import pytest

from tracer.optics import fresnel_dielectric, reflect, refract

N_UP = np.array([0.0, 0.0, 1.0])


def incident(theta_deg):
    """Unit direction travelling down onto the z = 0 plane at angle θ_i from the normal +z, in the xz-plane."""
    t = np.radians(theta_deg)
    return np.array([np.sin(t), 0.0, -np.cos(t)])


def sin_angle_from_normal(v, n):
    return np.linalg.norm(np.cross(v, n), axis=-1) / np.linalg.norm(v, axis=-1)


def random_pairs(rng, k):
    n = rng.normal(size=(k, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    d = rng.normal(size=(k, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d = np.where(np.sum(d * n, axis=1, keepdims=True) > 0, -d, d)  # incident side: d·n ≤ 0
    return d, n


def test_normal_incidence_passes_straight_through():
    t, tir = refract(np.array([0.0, 0.0, -1.0]), N_UP, 1.0, 1.5)
    assert not tir
    np.testing.assert_allclose(t, [0.0, 0.0, -1.0], atol=1e-12)


@pytest.mark.parametrize("eta_r", [1.33, 1.5])
def test_45_degrees_into_water_and_glass(eta_r):
    d = incident(45.0)
    t, tir = refract(d, N_UP, 1.0, eta_r)
    assert not tir
    expected_sin = np.sin(np.radians(45.0)) / eta_r
    assert sin_angle_from_normal(-t, N_UP) == pytest.approx(expected_sin, abs=1e-9)
    assert t[2] < 0 and t[0] > 0  # continues downward, same side of the normal as it came
    assert np.linalg.norm(t) == pytest.approx(1.0, abs=1e-12)


def test_critical_angle_leaving_glass():
    critical = np.degrees(np.arcsin(1.0 / 1.5))
    below, above = incident(critical - 0.5), incident(critical + 0.5)
    t_below, tir_below = refract(below, N_UP, 1.5, 1.0)
    _, tir_above = refract(above, N_UP, 1.5, 1.0)
    assert not tir_below and tir_above
    assert sin_angle_from_normal(-t_below, N_UP) == pytest.approx(1.5 * np.sin(np.radians(critical - 0.5)), abs=1e-9)


def test_tir_is_exactly_beyond_the_critical_angle():
    """Snell's law has no solution where η_i·sin θ_i > η_r (sin θ_r would exceed 1): the critical angle, computed
    here from the angle between d and n, independently of the notes' square-root form."""
    rng = np.random.default_rng(1)
    d, n = random_pairs(rng, 20000)
    eta_i = rng.uniform(1.0, 2.4, size=len(d))
    eta_r = rng.uniform(1.0, 2.4, size=len(d))
    _, tir = refract(d, n, eta_i, eta_r)
    sin_i = np.linalg.norm(np.cross(d, n), axis=1)
    margin = eta_i * sin_i - eta_r
    clear = np.abs(margin) > 1e-9  # leave out the float ties at the critical angle itself
    np.testing.assert_array_equal(tir[clear], margin[clear] > 0)
    assert tir.any() and (~tir).any()


def test_snell_unit_length_and_coplanarity_on_random_directions():
    rng = np.random.default_rng(2)
    d, n = random_pairs(rng, 20000)
    eta_i = rng.choice([1.0, 1.33, 1.5], size=len(d))
    eta_r = rng.choice([1.0, 1.33, 1.5, 2.4], size=len(d))
    t, tir = refract(d, n, eta_i, eta_r)
    ok = ~tir
    t, d_, n_ = t[ok], d[ok], n[ok]
    np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1.0, atol=1e-9)
    sin_i = sin_angle_from_normal(d_, n_)
    sin_r = sin_angle_from_normal(t, n_)
    np.testing.assert_allclose(eta_i[ok] * sin_i, eta_r[ok] * sin_r, atol=1e-6)
    # d, n and t lie in one plane: t · (d × n) = 0
    np.testing.assert_allclose(np.sum(t * np.cross(d_, n_), axis=1), 0.0, atol=1e-9)
    # the transmitted ray crosses the surface
    assert np.all(np.sum(t * n_, axis=1) < 0)


def test_reflection_law_and_unit_length():
    rng = np.random.default_rng(3)
    d, n = random_pairs(rng, 10000)
    r = reflect(d, n)
    np.testing.assert_allclose(np.sum(r * r, axis=1), 1.0, atol=1e-12)
    # angle of incidence = angle of reflection, and r is on the normal's side
    np.testing.assert_allclose(np.sum(r * n, axis=1), -np.sum(d * n, axis=1), atol=1e-12)
    # coplanar, and the tangential component is preserved
    np.testing.assert_allclose(np.sum(r * np.cross(d, n), axis=1), 0.0, atol=1e-12)
    np.testing.assert_allclose(r - np.sum(r * n, 1, keepdims=True) * n, d - np.sum(d * n, 1, keepdims=True) * n,
                               atol=1e-12)


def test_reflect_matches_the_notes_first_form():
    # The notes derive r = −d + 2(d − (d·n)n) ... = d − 2(d·n)n: check the second equality on the seed's symbols.
    d, n = incident(30.0), N_UP
    first = d - 2 * (d @ n) * n
    np.testing.assert_allclose(reflect(d, n), first)
    np.testing.assert_allclose(reflect(d, n), [d[0], 0.0, -d[2]])


def test_fresnel_limits():
    assert fresnel_dielectric(1.0, 1.0, 1.5) == pytest.approx(0.04, abs=1e-6)  # ((n-1)/(n+1))²
    assert fresnel_dielectric(0.0, 1.0, 1.5) == pytest.approx(1.0, abs=1e-6)  # grazing
    assert fresnel_dielectric(np.cos(np.radians(60)), 1.5, 1.0) == 1.0  # beyond the critical angle: TIR
    # Symmetry: entering or leaving at corresponding angles reflects the same fraction.
    ti = np.radians(30.0)
    tr = np.arcsin(np.sin(ti) / 1.5)
    assert fresnel_dielectric(np.cos(ti), 1.0, 1.5) == pytest.approx(fresnel_dielectric(np.cos(tr), 1.5, 1.0), abs=1e-6)


@pytest.mark.parametrize("angle", [20.0, 45.0, 56.31, 70.0, 85.0])
def test_fresnel_matches_the_angle_form_of_fresnels_equations(angle):
    """R = (R_s + R_p)/2 with R_s = sin²(θi−θt)/sin²(θi+θt), R_p = tan²(θi−θt)/tan²(θi+θt) (Hecht 4.42-4.43),
    a different form from the implementation's cosines; at Brewster's angle (56.31° for n = 1.5) R_p vanishes."""
    ti = np.radians(angle)
    tt = np.arcsin(np.sin(ti) / 1.5)
    r_s = (np.sin(ti - tt) / np.sin(ti + tt)) ** 2
    r_p = (np.tan(ti - tt) / np.tan(ti + tt)) ** 2
    assert fresnel_dielectric(np.cos(ti), 1.0, 1.5) == pytest.approx((r_s + r_p) / 2, abs=1e-6)
    if angle == 56.31:
        assert r_p < 1e-8


def test_valid_reflection_normal_lifts_grazing_reflections_to_the_threshold():
    """Cycles' rule for glossy lobes on smooth-shaded meshes: a shading normal whose mirror direction would go
    below the true surface is tilted towards the geometric normal until r·ng = min(0.9·(wi·ng), 0.01) exactly,
    staying in the plane of n and ng; a normal whose reflection is already above the surface is kept."""
    from tracer.optics import valid_reflection_normal

    rng = np.random.default_rng(7)
    ng = (0.0, 0.0, 1.0)
    bent = 0
    for _ in range(400):
        wi = rng.normal(size=3)
        wi[2] = abs(wi[2]) * rng.uniform(0.02, 1.0)
        wi /= np.linalg.norm(wi)
        n = rng.normal(size=3)
        n[2] = abs(n[2]) + 0.05
        n /= np.linalg.norm(n)
        d = tuple(-wi)
        r = reflect(np.array(d), n)
        got = np.array(valid_reflection_normal(d, tuple(n), ng))
        t = min(0.9 * wi[2], 0.01)
        assert np.linalg.norm(got) == pytest.approx(1.0, abs=1e-9)
        if r[2] >= t:
            np.testing.assert_allclose(got, n, atol=0)
            continue
        bent += 1
        assert reflect(np.array(d), got)[2] == pytest.approx(t, abs=1e-7)
        assert abs(np.dot(np.cross(n, ng), got)) < 1e-9  # in the plane of n and ng
        assert got[2] > n[2]  # towards ng
    assert bent > 50

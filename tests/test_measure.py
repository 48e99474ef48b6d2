"""Measurements: Love–Weber sign and magnitude, fabric, rattlers, g2, histogram."""
import math

import numpy as np

from dem import neighbours
from dem.contact_law import ContactLaw
from dem.integrator import dynamics, evaluate_forces
from dem.measure import g2_exact, measure, normal_histogram, rattler_mask, Contacts
from dem.state import new_state


def square_lattice(k=6, spacing=0.99, r=0.5):
    """k x k discs on a square lattice, overlapping their 4 neighbours by 1 - spacing."""
    g = (np.stack(np.meshgrid(np.arange(k), np.arange(k), indexing="ij"), -1).reshape(-1, 2) + 0.5) / k
    h = np.diag([k * spacing, k * spacing])
    st = new_state(np.full(k * k, r), g, h)
    law = ContactLaw(kn=1e3, e=0.5, mu=0.5)
    dyn = dynamics(law, st.mass.min(), 1e-3)
    neighbours.rebuild(st, dyn.skin)
    evaluate_forces(st, dyn)
    return st, law


def test_love_weber_is_compressive_negative_with_the_closed_form_pressure():
    st, law = square_lattice()
    m = measure(st, law)
    # each disc: 2 contacts (x and y) counted once, fn = kn δ, |l| = spacing
    fn, l, area = law.kn * 0.01, 0.99, 0.99**2
    assert m["sxx"] < 0 and m["syy"] < 0 and m["P"] > 0
    assert math.isclose(m["sxx"], -fn * l / area, rel_tol=1e-12)
    assert math.isclose(m["sxx"], m["syy"], rel_tol=1e-12) and abs(m["sxy"]) < 1e-12
    assert np.allclose(st.stress, [m["sxx"], m["syy"], m["sxy"]], rtol=1e-12)


def test_fabric_of_the_square_lattice():
    st, law = square_lattice()
    m = measure(st, law)
    # 4 contacts per disc along x and y: z = 4, A = 4/π; the 4th harmonic is invisible to
    # the second-order fabric, so B = 0
    assert m["z"] == 4 and math.isclose(m["A"], 4 / math.pi) and abs(m["Bc"]) < 1e-12
    assert math.isclose(m["trF_V"], 4 * math.pi * 0.25 / 0.99**2, rel_tol=1e-12)
    theta, p = normal_histogram(Contacts(st).n, st.n)
    assert math.isclose(np.sum(p) * (theta[1] - theta[0]), 4.0)


def test_rattlers_are_removed_repeatedly():
    # a chain 0-1-2 hanging off a triangle 3-4-5: 0 has one contact, then 1, then 2
    i = np.array([0, 1, 2, 3, 4, 3])
    j = np.array([1, 2, 3, 4, 5, 5])
    assert rattler_mask(6, i, j, 2).tolist() == [True, True, True, False, False, False]


def test_g2_exact_reproduces_seed_002_values():
    bid = np.r_[np.full(1000, 0.25), np.full(1000, 0.75)]
    assert round(g2_exact(bid), 3) == 1.223
    uni = 0.5 * (0.5 + (np.arange(100_000) + 0.5) / 100_000)
    assert round(g2_exact(uni), 3) == 1.085
    assert math.isclose(g2_exact(np.full(10, 0.5)), 1.0)


def _sheared(profile, n=1600, gamma=0.02, seed=4):
    """A random configuration displaced by u = gamma * profile(s) (reduced s at start)."""
    from dem.measure import localization_index

    rng = np.random.default_rng(seed)
    s0 = rng.random((n, 2))
    h = np.diag([40.0, 40.0])
    st = new_state(np.full(n, 0.5), s0, h)
    st.s = s0 + np.linalg.solve(h, (gamma * profile(s0)).T).T
    return localization_index(st, s0, h), math.isqrt(n // 64)


def test_localization_index_is_zero_for_affine_and_sqrt_g_minus_1_for_a_one_row_band():
    affine, _ = _sheared(lambda s: np.stack([40.0 * s[:, 1], 0.0 * s[:, 1]], 1))
    assert affine < 1e-9
    # all the shear in the middle row of cells (G = 5: reduced y in [0.4, 0.6])
    band, g = _sheared(lambda s: np.stack([40.0 * np.clip(s[:, 1] - 0.4, 0.0, 0.2), 0.0 * s[:, 1]], 1))
    assert g == 5 and abs(band - math.sqrt(g - 1)) < 1e-9


def test_localization_index_sees_a_diagonal_band():
    # a band along the diagonal of the cell (a row-bin profile would average it out):
    # displacement along (1, 1) ramping across the strip 0 <= s_x - s_y < 0.2
    def diag(s):
        t = np.clip(np.mod(s[:, 0] - s[:, 1], 1.0) / 0.2, 0.0, 1.0)
        return 8.0 * np.stack([t, t], 1)

    band, _ = _sheared(diag)
    noise, _ = _sheared(lambda s: np.random.default_rng(1).normal(size=s.shape) * 2.0
                        + np.stack([40.0 * s[:, 1], 0.0 * s[:, 1]], 1))
    assert band > 1.0 and noise < 0.5


def _harmonic_contacts(theta, f0, a_n, theta_n, a_t, theta_t):
    """Normals at angles θ and forces on the closed form of Rothenburg & Bathurst (1989):
    fn = f0 [1 + a_n cos 2(θ - θn)], and the tangential force on j (= -ft of
    :class:`dem.measure.Contacts`) = -f0 a_t sin 2(θ - θt)."""
    normals = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    fn = f0 * (1.0 + a_n * np.cos(2.0 * (theta - theta_n)))
    ft = f0 * a_t * np.sin(2.0 * (theta - theta_t))
    return normals, fn, ft


def test_force_anisotropy_recovers_the_closed_form_on_anisotropic_normals():
    from dem.measure import force_anisotropy

    rng = np.random.default_rng(3)
    # normals crowded around 30°, in both orientations of each pair (θ and θ + π)
    theta = np.r_[rng.normal(np.pi / 6, 0.6, 500), np.pi + rng.normal(np.pi / 6, 0.6, 500)]
    got = force_anisotropy(*_harmonic_contacts(theta, 2.5, 0.4, 0.7, 0.15, -1.2))
    assert math.isclose(got["f0"], 2.5, rel_tol=1e-12)
    assert math.isclose(got["a_n"], 0.4, rel_tol=1e-12) and math.isclose(got["theta_n"], 0.7)
    assert math.isclose(got["a_t"], 0.15, rel_tol=1e-12)
    assert math.isclose(got["theta_t"], -1.2, rel_tol=1e-12)


def test_stress_force_fabric_relation_is_exact_for_uniform_normals():
    """With isotropic normals and harmonic forces the Love–Weber deviator is exactly
    ½ (a_n d(θn) + a_t d(θt)) P, d(θ) = (cos 2θ, sin 2θ) (Rothenburg & Bathurst 1989)."""
    from dem.measure import force_anisotropy

    theta = (np.arange(720) + 0.25) * 2 * np.pi / 720
    normals, fn, ft = _harmonic_contacts(theta, 1.0, 0.3, 0.4, 0.1, 0.9)
    t = np.stack([-normals[:, 1], normals[:, 0]], axis=1)
    f_on_i = -fn[:, None] * normals + ft[:, None] * t
    sigma = np.einsum("ci,cj->ij", f_on_i, 0.9 * normals)       # branch length 0.9, V = 1
    sigma = 0.5 * (sigma + sigma.T)
    p = -0.5 * np.trace(sigma)
    dev = np.array([0.5 * (sigma[0, 0] - sigma[1, 1]), sigma[0, 1]])
    fa = force_anisotropy(normals, fn, ft)
    pred = 0.5 * sum(fa[a] * np.array([np.cos(2 * fa[th]), np.sin(2 * fa[th])])
                     for a, th in (("a_n", "theta_n"), ("a_t", "theta_t")))
    # compression positive: the compressive deviator is -dev
    assert np.allclose(-dev / p, pred, atol=1e-12)


def test_force_anisotropy_of_a_stress_free_assembly_is_zero():
    from dem.measure import force_anisotropy

    theta = np.linspace(0, np.pi, 10)
    normals, fn, ft = _harmonic_contacts(theta, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert all(v == 0.0 for v in force_anisotropy(normals, fn, ft).values())
    assert force_anisotropy(normals[:2], fn[:2] + 1, ft[:2])["a_n"] == 0.0

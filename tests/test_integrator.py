"""Time stepping: energy conservation (acceptance 2), the energy balance, threads, dt limit."""
import math
from dataclasses import replace

import numba
import numpy as np
import pytest

from conftest import make_dynamics
from dem import integrator, neighbours, threads
from dem.contact_law import STYLES, ContactLaw
from dem.integrator import Control, TimeStepError, advance, evaluate_forces, stable_fraction, time_step
from dem.measure import energies, love_weber
from dem.state import new_state


def test_frictionless_undamped_energy_drift_below_1e6_over_1e5_steps(packing_frictionless):
    st = packing_frictionless.copy()
    dyn = make_dynamics(st, mu=0.0, e=1.0, fraction=0.02)
    st.v[:] = np.random.default_rng(0).normal(size=st.v.shape) * 1e-3
    st.acc[:] = 0.0
    evaluate_forces(st, dyn)
    e0 = energies(st, dyn.law)["E_total"]
    advance(st, dyn, 100_000)
    assert abs(energies(st, dyn.law)["E_total"] / e0 - 1.0) < 1e-6


def _balance_error(packing, fraction, style=STYLES[0]):
    st = packing.copy()
    st.acc[:] = 0.0
    dyn = make_dynamics(st, mu=0.5, e=0.5, gdot=1e-2, fraction=fraction)
    dyn = replace(dyn, law=replace(dyn.law, style=style))
    evaluate_forces(st, dyn)
    e0 = energies(st, dyn.law)
    ctl = Control(np.array([0.0, -1e-2, 0.0, 0.0]), np.array([True, False, False, False]),
                  np.array([-1.0, -1.0, 0.0]), np.array([-1.0, -1.0, 0.0]))
    advance(st, dyn, int(round(2000 / fraction)), ctl)  # 20% axial strain
    e1 = energies(st, dyn.law)
    assert e1["W_external"] > 0 and e1["D_friction"] > 0 and e1["D_damping"] > 0
    return abs(e1["E_total"] - e0["E_total"]) / e1["W_external"]


@pytest.mark.parametrize("style", STYLES)
def test_energy_balance_closes_under_biaxial_loading(packing_frictional, style):
    # friction, damping, servo and cell deformation all active. The books close to 1e-5 of
    # the external work at the default dt and at half of it (measured 3.5e-6, 2.3e-6);
    # booking a contact's first and last step from δ = 0 instead of the real gap left an
    # O(dt) error (2.7e-3 at 0.1). hooke/history: the tangential dashpot's work booked as
    # damping
    for fraction in (0.1, 0.05):
        assert _balance_error(packing_frictional, fraction, style) < 1e-5


def test_kernel_stress_is_the_love_weber_stress(packing_frictional):
    st = packing_frictional.copy()
    dyn = make_dynamics(st)
    st.v[:] = np.random.default_rng(2).normal(size=st.v.shape) * 0.01
    evaluate_forces(st, dyn)
    assert np.allclose(st.stress, love_weber(st), rtol=1e-12, atol=1e-14)
    p = -0.5 * (st.stress[0] + st.stress[1])
    assert abs(p - 1.0) < 0.01 and p > 0  # compression: P > 0, σxx, σyy < 0
    assert st.stress[0] < 0 and st.stress[1] < 0


def _tiled(st, k):
    """The packing repeated k x k times in a k times larger cell (at rest, no histories)."""
    offsets = np.array([(a, b) for b in range(k) for a in range(k)], float)
    s = ((st.s % 1.0)[None, :, :] + offsets[:, None, :]).reshape(-1, 2) / k
    out = new_state(np.tile(st.radius, k * k), s, st.h * k)
    neighbours.rebuild(out, 0.2)
    return out


def test_parallel_and_serial_runs_are_bitwise_equal(packing_frictional):
    # 3 x 3 copies of the packing: more discs and pairs than one chunk of either pass
    tiled = _tiled(packing_frictional, 3)
    assert tiled.n > integrator.CHUNK and tiled.n_pairs > 2 * integrator.CHUNK
    tiled.v[:] = np.random.default_rng(5).normal(size=tiled.v.shape) * 0.01
    results = []
    for nt in (1, numba.config.NUMBA_NUM_THREADS):
        st = tiled.copy()
        dyn = make_dynamics(st, gdot=1e-2)
        ctl = Control(np.array([0.0, -1e-2, 0.5e-2, 0.0]), np.array([True, False, False, False]),
                      np.array([-1.0, -1.0, 0.0]), np.array([-1.0, -1.0, 0.0]))
        with threads.using(nt):
            results.append(advance(st, dyn, 3000, ctl))
    a, b = results
    for name, arr in a.arrays().items():
        assert np.array_equal(arr, b.arrays()[name]), name


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs two numba threads")
def test_the_dem_runs_on_its_own_thread_count_and_restores_numbas(packing_frictional,
                                                                    monkeypatch):
    seen = []

    def kernel(nsteps, *args):
        seen.append(numba.get_num_threads())
        return nsteps, integrator.OK

    monkeypatch.setattr(integrator, "advance_kernel", kernel)
    before = numba.get_num_threads()
    numba.set_num_threads(2)
    try:
        st = packing_frictional.copy()
        advance(st, make_dynamics(st), 10)
        with threads.using(2):
            advance(st, make_dynamics(st), 10)
        assert numba.get_num_threads() == 2
    finally:
        numba.set_num_threads(before)
    assert seen == [1, 2]
    assert threads.get_threads() == 1


@pytest.mark.parametrize("n", [0, -1, 2.5, 10_000])
def test_a_bad_dem_thread_count_is_refused_with_the_range(n):
    with pytest.raises(ValueError, match=r"DEM threads .* out of range; accepted 1 to \d+"):
        threads.set_threads(n)


def test_time_step_above_stability_limit_is_refused():
    law = ContactLaw(kn=1e4, kt_ratio=0.5, e=0.5)
    limit = stable_fraction(law)
    assert 0.1 < limit < 0.5
    assert time_step(law, 1.0, limit) == pytest.approx(limit * 1e-2)
    with pytest.raises(TimeStepError, match=rf"fraction {1.01 * limit} .*accepted range \(0, "):
        time_step(law, 1.0, 1.01 * limit)


def _reference_forces(st, law, dt):
    """Forces, torques, contact stress · V and the new tangential histories of every
    touching pair, found by brute force over all pairs and images and evaluated from the
    contact law as documented (:mod:`dem.contact_law`), in plain Python."""
    kn, kt, beta, mu = law.kn, law.kt, law.beta, law.mu
    hooke = law.style == "hooke/history"
    gamma_n = 2 * beta * math.sqrt(kn / (0.5 * st.mass.mean()))     # LAMMPS's, a mean pair
    x = st.s @ st.h.T
    hist = {(int(i), int(j), int(a), int(b)): st.pair_hist[q].copy()
            for q, ((i, j), (a, b)) in enumerate(zip(st.pair_ij[:st.n_pairs],
                                                      st.pair_shift[:st.n_pairs]))}
    force, torque = np.zeros((st.n, 2)), np.zeros(st.n)
    sigma_v, new_hist = np.zeros(3), {}
    for i in range(st.n):
        for j in range(i + 1, st.n):
            for a in (-1, 0, 1):
                for b in (-1, 0, 1):
                    l = x[j] + st.h @ np.array([a, b]) - x[i]
                    dist = math.hypot(l[0], l[1])
                    ri, rj = st.radius[i], st.radius[j]
                    if dist >= ri + rj:
                        continue
                    n = l / dist
                    t = np.array([-n[1], n[0]])
                    delta = ri + rj - dist
                    li, lj = (ri, rj) if hooke else (ri - delta / 2, rj - delta / 2)
                    w = st.L @ l + st.v[j] - st.v[i] - (st.omega[i] * li + st.omega[j] * lj) * t
                    m_eff = st.mass[i] * st.mass[j] / (st.mass[i] + st.mass[j])
                    gamma = m_eff * gamma_n if hooke else 2 * beta * math.sqrt(m_eff * kn)
                    fn = max(0.0, kn * delta - gamma * (w @ n))
                    trial = hist.get((i, j, a, b), np.zeros(5))[0] + (w @ t) * dt
                    fdt = 0.5 * gamma * (w @ t) if hooke else 0.0
                    ft = max(-mu * fn, min(mu * fn, kt * trial + fdt))
                    xi = (ft - fdt) / kt
                    f = -fn * n + ft * t
                    force[i] += f
                    force[j] -= f
                    torque[i] += li * ft
                    torque[j] += lj * ft
                    sigma_v += [f[0] * l[0], f[1] * l[1], 0.5 * (f[0] * l[1] + f[1] * l[0])]
                    new_hist[(i, j, a, b)] = (xi, delta, abs(kt * trial + fdt) > mu * fn)
    return force, torque, sigma_v, new_hist


@pytest.mark.parametrize("style", STYLES)
def test_one_step_of_forces_and_histories_matches_a_plain_python_evaluation(packing_frictional,
                                                                              style):
    # a sheared frictional packing (contacts sticking, sliding, closing and opening):
    # the optimized pair and disc passes against the contact law evaluated pair by pair
    st = packing_frictional.copy()
    dyn = make_dynamics(st, gdot=1e-2)
    dyn = replace(dyn, law=replace(dyn.law, style=style))
    ctl = Control(np.array([0.0, -1e-2, 0.5e-2, 0.0]), np.array([True, False, False, False]),
                  np.array([-1.0, -1.0, 0.0]), np.array([-1.0, -1.0, 0.0]))
    advance(st, dyn, 300, ctl)
    st.v += np.random.default_rng(3).normal(size=st.v.shape) * 0.02
    st.omega += np.random.default_rng(4).normal(size=st.n) * 0.05
    force, torque, sigma_v, new_hist = _reference_forces(st, dyn.law, dyn.dt)
    assert len(new_hist) > 200 and sum(slid for _, _, slid in new_hist.values()) > 5
    kn, kt, beta, mu, mu_roll = dyn.law.kernel_params()
    const = integrator.pair_constants(st.pair_ij, st.n_pairs, st.radius, st.mass, kn, beta,
                                      dyn.law.gamma_n(float(st.mass.mean())),
                                      dyn.law.tangential_damping)
    ps = integrator.pair_forces(st.h, st.L, st.s, st.v, st.omega, st.radius, const, st.pair_ij,
                                st.pair_shift, st.pair_hist, st.pair_f, st.n_pairs, kn, kt, mu,
                                mu_roll, dyn.law.arm_offset, dyn.dt)
    none = np.zeros((2, 2))
    integrator.disc_pass(st.pair_f, st.row_ptr, st.inc_ptr, st.inc, st.force, st.torque,
                         st.v.copy(), st.omega.copy(), st.s, st.s_ref, st.mass, st.inv_mass,
                         st.inv_inertia, st.L, st.L, none, none, 0.0, 0.0, True, False)
    scale = np.abs(force).max()
    assert np.allclose(st.force, force, rtol=0, atol=1e-11 * scale)
    assert np.allclose(st.torque, torque, rtol=0, atol=1e-11 * scale)
    assert np.allclose(ps[:3], sigma_v, rtol=1e-11, atol=1e-11 * np.abs(sigma_v).max())
    got = {}
    for q in range(st.n_pairs):
        key = (int(st.pair_ij[q, 0]), int(st.pair_ij[q, 1]), int(st.pair_shift[q, 0]),
               int(st.pair_shift[q, 1]))
        if st.pair_hist[q, 3] != 0.0:
            got[key] = (st.pair_hist[q, 0], st.pair_hist[q, 3])
        else:
            assert not np.any(st.pair_hist[q])      # apart: no history left
    assert got.keys() == new_hist.keys()
    for key, (xi, d, _) in new_hist.items():
        assert abs(got[key][0] - xi) <= 1e-10 * dyn.law.mu * dyn.law.kn * d / dyn.law.kt + 1e-18
        assert abs(got[key][1] - d) <= 1e-12


def _reference_trajectory(st, law, dt, L, nsteps):
    """(s, v', ω) after ``nsteps`` steps of the module doc's velocity Verlet with a
    prescribed L (kick, Cayley map of the cell, drift, forces, kick), the forces from the
    contact law in numpy over the state's pair list, kept fixed (wide enough for the run)."""
    n = st.n_pairs
    i, j, shift = st.pair_ij[:n, 0], st.pair_ij[:n, 1], st.pair_shift[:n].astype(float)
    ri, rj = st.radius[i], st.radius[j]
    gamma = 2 * law.beta * np.sqrt(st.mass[i] * st.mass[j] / (st.mass[i] + st.mass[j]) * law.kn)
    xi = st.pair_hist[:n, 0].copy()
    s, h, v, w = st.s.copy(), st.h.copy(), st.v.copy(), st.omega.copy()

    def forces(xi, step):
        l = (s[j] + shift - s[i]) @ h.T
        dist = np.hypot(l[:, 0], l[:, 1])
        touching = dist < ri + rj
        nrm = l / dist[:, None]
        t = np.stack([-nrm[:, 1], nrm[:, 0]], axis=1)
        delta = ri + rj - dist
        li, lj = ri - delta / 2, rj - delta / 2
        rel = l @ L.T + v[j] - v[i] - (w[i] * li + w[j] * lj)[:, None] * t
        vn, vt = np.sum(rel * nrm, axis=1), np.sum(rel * t, axis=1)
        fn = np.where(touching, np.maximum(0.0, law.kn * delta - gamma * vn), 0.0)
        cap = law.mu * fn / law.kt
        xi = np.where(touching, np.clip(xi + vt * step, -cap, cap), 0.0)
        f = -fn[:, None] * nrm + law.kt * xi[:, None] * t
        force, torque = np.zeros((st.n, 2)), np.zeros(st.n)
        np.add.at(force, i, f)
        np.add.at(force, j, -f)
        np.add.at(torque, i, li * law.kt * xi)
        np.add.at(torque, j, lj * law.kt * xi)
        return force, torque, xi

    force, torque, _ = forces(xi, 0.0)
    a = np.eye(2) - 0.5 * dt * L
    cayley = np.linalg.solve(a, np.eye(2) + 0.5 * dt * L)
    for _ in range(nsteps):
        v = v + 0.5 * dt * (force / st.mass[:, None] - v @ L.T)
        w = w + 0.5 * dt * torque * st.inv_inertia
        h_new = cayley @ h
        s = s + dt * v @ np.linalg.inv(0.5 * (h + h_new)).T
        h = h_new
        force, torque, xi = forces(xi, dt)
        v = v + 0.5 * dt * (force / st.mass[:, None] - v @ L.T)
        w = w + 0.5 * dt * torque * st.inv_inertia
    return s, v, w


def test_a_thousand_steps_of_shear_match_a_numpy_velocity_verlet(packing_frictional):
    # the optimized step (fused passes, live-pair compaction, list rebuilds) against the
    # module doc's scheme written out in numpy: the same trajectory to rounding. Rounding
    # differences grow about e-fold per 100 steps in this dense packing (measured 6e-13
    # in s, 1e-9 relative in v' and ω after 1000 steps, 3e-5 relative after 3000)
    st = packing_frictional.copy()
    dyn = make_dynamics(st, gdot=1e-2)
    neighbours.rebuild(st, 0.6)                   # a list for the reference's whole run
    st.v[:] = np.random.default_rng(6).normal(size=st.v.shape) * 0.01
    L = np.array([[2e-3, 1e-2], [0.0, -3e-3]])
    st.L[:] = L
    evaluate_forces(st, dyn)
    image0 = st.image.copy()
    s, v, w = _reference_trajectory(st, dyn.law, dyn.dt, L, 1000)
    ctl = Control(np.array([L[0, 0], L[1, 1], L[0, 1], L[1, 0]]), np.zeros(4, bool),
                  np.zeros(3), np.zeros(3))
    advance(st, dyn, 1000, ctl)
    assert st.rebuilds > packing_frictional.rebuilds + 1
    assert np.abs(st.s + st.image - image0 - s).max() < 1e-9
    assert np.abs(st.v - v).max() < 1e-6 * np.abs(v).max()
    assert np.abs(st.omega - w).max() < 1e-6 * np.abs(w).max()

"""Time stepping: energy conservation (acceptance 2), the energy balance, threads, dt limit."""
import numba
import numpy as np
import pytest

from conftest import make_dynamics
from dem import integrator, threads
from dem.contact_law import ContactLaw
from dem.integrator import Control, TimeStepError, advance, evaluate_forces, stable_fraction, time_step
from dem.measure import energies, love_weber


def test_frictionless_undamped_energy_drift_below_1e6_over_1e5_steps(packing_frictionless):
    st = packing_frictionless.copy()
    dyn = make_dynamics(st, mu=0.0, e=1.0, fraction=0.02)
    st.v[:] = np.random.default_rng(0).normal(size=st.v.shape) * 1e-3
    st.acc[:] = 0.0
    evaluate_forces(st, dyn)
    e0 = energies(st, dyn.law)["E_total"]
    advance(st, dyn, 100_000)
    assert abs(energies(st, dyn.law)["E_total"] / e0 - 1.0) < 1e-6


def _balance_error(packing, fraction):
    st = packing.copy()
    st.acc[:] = 0.0
    dyn = make_dynamics(st, mu=0.5, e=0.5, gdot=1e-2, fraction=fraction)
    evaluate_forces(st, dyn)
    e0 = energies(st, dyn.law)
    ctl = Control(np.array([0.0, -1e-2, 0.0, 0.0]), np.array([True, False, False, False]),
                  np.array([-1.0, -1.0, 0.0]), np.array([-1.0, -1.0, 0.0]))
    advance(st, dyn, int(round(2000 / fraction)), ctl)  # 20% axial strain
    e1 = energies(st, dyn.law)
    assert e1["W_external"] > 0 and e1["D_friction"] > 0 and e1["D_damping"] > 0
    return abs(e1["E_total"] - e0["E_total"]) / e1["W_external"]


def test_energy_balance_closes_under_biaxial_loading(packing_frictional):
    # friction, damping, servo and cell deformation all active. The books close to 1e-5 of
    # the external work at the default dt and at half of it (measured 3.5e-6, 2.3e-6);
    # booking a contact's first and last step from δ = 0 instead of the real gap left an
    # O(dt) error (2.7e-3 at 0.1)
    for fraction in (0.1, 0.05):
        assert _balance_error(packing_frictional, fraction) < 1e-5


def test_kernel_stress_is_the_love_weber_stress(packing_frictional):
    st = packing_frictional.copy()
    dyn = make_dynamics(st)
    st.v[:] = np.random.default_rng(2).normal(size=st.v.shape) * 0.01
    evaluate_forces(st, dyn)
    assert np.allclose(st.stress, love_weber(st), rtol=1e-12, atol=1e-14)
    p = -0.5 * (st.stress[0] + st.stress[1])
    assert abs(p - 1.0) < 0.01 and p > 0  # compression: P > 0, σxx, σyy < 0
    assert st.stress[0] < 0 and st.stress[1] < 0


def test_parallel_and_serial_runs_are_bitwise_equal(packing_frictional):
    results = []
    for nt in (1, numba.config.NUMBA_NUM_THREADS):
        st = packing_frictional.copy()
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

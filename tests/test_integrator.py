"""Time stepping: energy conservation (acceptance 2), the energy balance, threads, dt limit."""
import numba
import numpy as np
import pytest

from conftest import make_dynamics
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
    # friction, damping, servo and cell deformation all active. The books close to a few
    # 1e-3 of the external work at the default dt and the error is O(dt) (slip and damping
    # work are evaluated with the end-of-step contact geometry): halving dt halves it
    coarse = _balance_error(packing_frictional, 0.1)
    fine = _balance_error(packing_frictional, 0.05)
    assert coarse < 5e-3 and fine < 0.65 * coarse


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
    threads = numba.config.NUMBA_NUM_THREADS
    results = []
    for nt in (1, threads):
        numba.set_num_threads(nt)
        st = packing_frictional.copy()
        dyn = make_dynamics(st, gdot=1e-2)
        ctl = Control(np.array([0.0, -1e-2, 0.5e-2, 0.0]), np.array([True, False, False, False]),
                      np.array([-1.0, -1.0, 0.0]), np.array([-1.0, -1.0, 0.0]))
        results.append(advance(st, dyn, 3000, ctl))
    numba.set_num_threads(threads)
    a, b = results
    for name, arr in a.arrays().items():
        assert np.array_equal(arr, b.arrays()[name]), name


def test_time_step_above_stability_limit_is_refused():
    law = ContactLaw(kn=1e4, kt_ratio=0.5, e=0.5)
    limit = stable_fraction(law)
    assert 0.1 < limit < 0.5
    assert time_step(law, 1.0, limit) == pytest.approx(limit * 1e-2)
    with pytest.raises(TimeStepError, match=rf"fraction {1.01 * limit} .*accepted range \(0, "):
        time_step(law, 1.0, 1.01 * limit)

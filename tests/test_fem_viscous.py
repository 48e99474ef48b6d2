"""Duvaut–Lions regularization: relaxation law, limits, consistent tangent, bad input."""
import math

import numpy as np
import pytest

from contfab.fem.material import TierMaterial
from contfab.fem.solver import NewtonOptions
from contfab.fem.viscous import blend, elastic_stiffness
from contfab.params import default_params

PHI, PSI = 30.0, 0.0


def _material():
    params = default_params().with_tier(0).replace("tier0", phi_deg=PHI, psi_deg=PSI) \
        .replace("regularization", p_ref=1.0)
    return TierMaterial(params, tier=0, apex_stiffness=0.0)


def _step(m, stress, state, de, spin, k):
    res = m.update(stress, state, de, spin)
    return res if math.isinf(k) else blend(res, stress, state, de, spin, elastic_stiffness(m), k)


def _overstressed():
    """One point at p = 1 loaded far beyond the cone (R = 0.9 > sin 30° · 1)."""
    return np.array([[-1.0 + 0.9, -1.0 - 0.9, 0.0]]), np.zeros((1, 1))


def test_relaxation_at_fixed_strain_decays_as_exp_minus_t_over_tau():
    """At fixed strain dσ/dt = -(σ - σ̄)/τ with σ̄ fixed (the cone return keeps its
    target along the return line), so the overstress decays as e^{-t/τ}; backward Euler
    over steps Δt reaches it at first order in Δt."""
    tau, horizon = 0.1, 0.3
    m = _material()
    zero = np.zeros((1, 3)), np.zeros(1)
    target = m.update(*_overstressed(), *zero).stress
    errors = []
    for steps in (20, 40, 80):
        stress, state = _overstressed()
        for _ in range(steps):
            res = _step(m, stress, state, *zero, horizon / steps / tau)
            stress, state = res.stress, res.state
        over = np.linalg.norm(stress - target) / np.linalg.norm(_overstressed()[0] - target)
        errors.append(abs(over - math.exp(-horizon / tau)))
    assert errors[-1] < 0.01
    orders = np.log2(np.array(errors[:-1]) / errors[1:])
    assert np.all(np.abs(orders - 1.0) < 0.1)


def test_limits_are_the_inviscid_and_the_elastic_update():
    m = _material()
    stress, state = _overstressed()
    de, spin = np.array([[-1e-3, 2e-3, 1e-3]]), np.array([0.05])
    inviscid = m.update(stress, state, de, spin).stress
    assert np.allclose(_step(m, stress, state, de, spin, 1e12).stress, inviscid, atol=1e-10)
    d, t = 0.9 * np.cos(0.1), 0.9 * np.sin(0.1)     # the deviator (0.9, 0) turned by 2 · 0.05
    elastic = np.array([[-1 + d, -1 - d, t]]) + de @ elastic_stiffness(m).T
    assert np.allclose(_step(m, stress, state, de, spin, 1e-12).stress, elastic, atol=1e-10)


@pytest.mark.parametrize("k", [0.3, 3.0, 30.0])
def test_tangent_and_spin_tangent_match_central_differences(k):
    m = _material()
    stress, state = np.array([[-1.0 + 0.4, -1.0 - 0.4, 0.2]]), np.zeros((1, 1))
    de, spin = np.array([[-2e-3, 1e-3, 3e-3]]), np.array([0.02])
    res = _step(m, stress, state, de, spin, k)
    h = 1e-7
    fd = np.empty((3, 3))
    for j in range(3):
        e = np.zeros((1, 3))
        e[0, j] = h
        fd[:, j] = (_step(m, stress, state, de + e, spin, k).stress
                    - _step(m, stress, state, de - e, spin, k).stress)[0] / (2 * h)
    assert res.status[0] == 1
    assert np.allclose(res.tangent[0], fd, rtol=1e-5, atol=1e-5 * np.abs(fd).max())
    g = m.spin_tangent(stress, state, de, spin, res)[0]
    g_fd = (_step(m, stress, state, de, spin + h, k).stress
            - _step(m, stress, state, de, spin - h, k).stress)[0] / (2 * h)
    assert np.allclose(g, g_fd, rtol=1e-5, atol=1e-6)


def test_bad_viscous_options_are_clear_errors():
    with pytest.raises(ValueError, match="relaxation_time = 0.0 is outside the accepted range"):
        NewtonOptions(relaxation_time=0.0)
    with pytest.raises(ValueError, match="ratio k = dt/tau = 0"):
        m = _material()
        _step(m, *_overstressed(), np.zeros((1, 3)), np.zeros(1), 0.0)

"""Tier 1 on a biaxial path: convergence to the rigid-plastic limit as λ grows (the note in
cone.py), the closed-form stress at yield, dense/loose states reaching the critical state
(acceptance 2), and quadratic Newton convergence of the mixed-control step with the
consistent tangent (acceptance 5)."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from contfab.models import tiers
from contfab.models.cone import friction_angles
from contfab.params import default_params

P0 = 1.0
C0 = np.array([0.83, 0.79])          # dense and loose around c* = 0.81 (default parameters)


def biaxial(params, de_yy, n_steps, record=False):
    """Biaxial compression: σxx = -P0 held, Δεyy prescribed, Δγxy = 0, no spin.

    Δεxx of each step is solved by Newton with the tangent entry ∂σxx/∂Δεxx, from the
    previous step's value. Returns the stress and state after each step and the residual
    sequences |σxx + P0| of every step."""
    n = len(C0)
    stress = np.tile([-P0, -P0, 0.0], (n, 1))
    state = np.stack([np.zeros(n), C0], 1)
    x = np.zeros(n)
    stresses, states, residuals = [], [], []
    scale = P0 + params.array(1)[0] * abs(de_yy)         # round-off scale of the trial stress
    for _ in range(n_steps):
        seq = []
        for _ in range(12):
            de = np.stack([x, np.full(n, de_yy), np.zeros(n)], 1)
            res = tiers.update(1, stress, state, de, np.zeros(n), params)
            r = res.stress[:, 0] + P0
            seq.append(np.abs(r))
            if np.all(np.abs(r) <= 1e-14 * scale):
                break
            x = x - r / res.tangent[:, 0, 0]
        assert np.all(res.status >= 0)
        residuals.append(seq)
        stress, state = res.stress, res.state
        if record:
            stresses.append(stress)
            states.append(state)
    return np.array(stresses), np.array(states), residuals


def rigid_plastic_c(params, eps_yy):
    """Rigid-plastic limit: coaxial flow with σxx the minor compression gives
    Δγ = -2Δεyy/(1 - sin ψ), so d ln c/dεyy = 2 sin ψ(c)/(1 - sin ψ(c))."""
    prm = params.array(1)

    def rate(_, y):
        s = np.sin(friction_angles(y[0], *prm[2:])[1])
        return [y[0] * 2 * s / (1 - s)]

    return np.array([solve_ivp(rate, (0, eps_yy), [c], rtol=1e-12, atol=1e-14).y[0, -1] for c in C0])


def test_results_converge_at_first_order_in_one_over_lambda():
    base = default_params()
    steps, de = 200, -0.05 / 200
    finals = {}
    for lam in (1e2, 1e3, 1e4, 1e6):
        stresses, states, _ = biaxial(base.replace("regularization", lam=lam), de, steps, record=True)
        finals[lam] = states[-1, :, 1], stresses[-1, :, 1]
        # at yield the stress is the rigid-plastic one for the current c, at any λ:
        # σyy = -P0 (1 + sin φ)/(1 - sin φ)
        prm = base.array(1)
        sphi = np.sin([friction_angles(c, *prm[2:])[0] for c in states[-1, :, 1]])
        assert stresses[-1, :, 1] == pytest.approx(-P0 * (1 + sphi) / (1 - sphi), rel=1e-12)
    c_ref, s_ref = finals[1e6]
    errors = [np.abs(finals[lam][0] - c_ref) for lam in (1e2, 1e3, 1e4)]
    orders = np.log10(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all((orders > 0.9) & (orders < 1.1)), orders
    s_err = [np.abs(finals[lam][1] - s_ref) for lam in (1e2, 1e3, 1e4)]
    assert np.all(np.log10(np.array(s_err[:-1]) / np.array(s_err[1:])) > 0.9)
    # the λ -> ∞ run matches the rigid-plastic ODE up to the backward-Euler step error
    # (first order in the step: 7e-6 here, measured), far below the λ = 1e2 error
    c_rp = rigid_plastic_c(base, -0.05)
    assert np.all(np.abs(c_ref - c_rp) < 2e-5)
    assert np.all(errors[0] > 50 * np.abs(c_ref - c_rp))


def test_dense_and_loose_reach_the_critical_state():
    params = default_params()
    stresses, states, _ = biaxial(params, -1e-3, 2000, record=True)
    c = states[:, :, 1]
    p = -0.5 * (stresses[:, :, 0] + stresses[:, :, 1])
    r = 0.5 * np.abs(stresses[:, :, 0] - stresses[:, :, 1])
    ratio = r / p
    c_star = params.tier1.c_star
    sin_star = np.sin(np.radians(params.tier1.phi_star_deg))
    # dense dilates (c falls) and softens; loose contracts (c rises) and hardens
    assert np.all(np.diff(c[:, 0]) <= 0) and np.all(np.diff(c[:, 1]) >= 0)
    peak = np.argmax(ratio[:, 0])
    assert ratio[peak, 0] > sin_star + 0.05 and np.all(np.diff(ratio[peak:, 0]) <= 1e-15)
    assert np.all(np.diff(ratio[5:, 1]) >= -1e-15)
    # both end at c* with R/P = sin φ*, to 1e-6
    assert c[-1] == pytest.approx([c_star, c_star], abs=1e-6)
    assert ratio[-1] == pytest.approx([sin_star, sin_star], abs=1e-6)


def test_mixed_control_newton_converges_quadratically():
    params = default_params()
    _, _, residuals = biaxial(params, -2.5e-4, 40)
    plastic_steps = [np.array(seq) for seq in residuals[5:]]
    for seq in plastic_steps:
        assert len(seq) <= 4
        for k in range(len(seq) - 1):
            if np.all(seq[k] > 1e-11):                  # above round-off: quadratic
                assert np.all(seq[k + 1] <= 10 * seq[k] ** 2 + 1e-12)

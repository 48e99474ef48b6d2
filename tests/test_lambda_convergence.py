"""Tier 1 on a biaxial path: convergence to the rigid-plastic limit as λ grows (the note in
cone.py), run by the material-point driver; the closed-form stress at yield; the
rigid-plastic ODE for c. (Acceptance 2 and 5 live in test_material_point.py.)"""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from contfab import material_point as mp
from contfab.models.cone import tier1_angles
from conftest import fixed_params
from dem.paths import parse_path

C0 = (0.83, 0.79)          # dense and loose around c* = 0.81 (default parameters)
STRAIN = 0.05
BIAXIAL = parse_path({"name": "biaxial_short", "stage": [
    {"name": "compress", "length": STRAIN, "output_every": STRAIN / 10,
     "L": {"yy": -1.0, "xy": 0.0, "yx": 0.0}, "sigma": {"xx": -1.0}}]})


def rigid_plastic_c(params, eps_yy):
    """Rigid-plastic limit: coaxial flow with σxx the minor compression gives
    Δγ = -2Δεyy/(1 - sin ψ), so d ln c/dεyy = 2 sin ψ(c)/(1 - sin ψ(c))."""
    prm = params.array(1)

    def rate(_, y):
        s = np.sin(tier1_angles(y[0], prm)[1])
        return [y[0] * 2 * s / (1 - s)]

    return np.array([solve_ivp(rate, (0, eps_yy), [c], rtol=1e-12, atol=1e-14).y[0, -1] for c in C0])


def test_results_converge_at_first_order_in_one_over_lambda():
    base = fixed_params()
    prm = base.array(1)
    finals = {}
    for lam in (1e2, 1e3, 1e4, 1e6):
        params = base.replace("regularization", lam=lam)
        runs = [mp.run_path(BIAXIAL, params, 1, increment=STRAIN / 200, state0={"c": c})
                for c in C0]
        c_end = np.array([r["c_p"][-1] for r in runs])
        syy_end = np.array([r["syy"][-1] for r in runs])
        finals[lam] = c_end, syy_end
        # at yield the stress is the rigid-plastic one for the current c, at any λ:
        # σyy = -P0 (1 + sin φ)/(1 - sin φ) (to the driver's tolerance on σxx = -P0, 1e-12)
        sphi = np.sin([tier1_angles(c, prm)[0] for c in c_end])
        assert syy_end == pytest.approx(-(1 + sphi) / (1 - sphi), rel=1e-11)
    c_ref, s_ref = finals[1e6]
    errors = [np.abs(finals[lam][0] - c_ref) for lam in (1e2, 1e3, 1e4)]
    orders = np.log10(np.array(errors[:-1]) / np.array(errors[1:]))
    s_err = [np.abs(finals[lam][1] - s_ref) for lam in (1e2, 1e3, 1e4)]
    s_orders = np.log10(np.array(s_err[:-1]) / np.array(s_err[1:]))
    c_rp = rigid_plastic_c(base, -STRAIN)
    for k, c0 in enumerate(C0):
        print(f"\nc0 = {c0}: |c_p(λ) - c_p(1e6)| at λ = 1e2, 1e3, 1e4: "
              f"{', '.join(f'{e[k]:.3g}' for e in errors)} (orders {orders[0][k]:.3f}, "
              f"{orders[1][k]:.3f}); |σyy(λ) - σyy(1e6)|: {', '.join(f'{e[k]:.3g}' for e in s_err)} "
              f"(orders {s_orders[0][k]:.3f}, {s_orders[1][k]:.3f}); λ = 1e6 against the "
              f"rigid-plastic ODE: {abs(c_ref[k] - c_rp[k]):.2g}")
    assert np.all((orders > 0.9) & (orders < 1.1)), orders
    assert np.all(s_orders > 0.9)
    # the λ -> ∞ run matches the rigid-plastic ODE up to the backward-Euler step error
    # (first order in the step: 7e-6 here, measured), far below the λ = 1e2 error
    assert np.all(np.abs(c_ref - c_rp) < 2e-5)
    assert np.all(errors[0] > 50 * np.abs(c_ref - c_rp))

"""Robustness of the tier 0/1 update: the zero-dilatancy apex trap (docs/theory.md §4) and
the no-NaN rule (no NaN/inf for extreme inputs; failed points reported, inputs returned)."""
import numpy as np
import pytest

from contfab.models import tiers
from contfab.params import BULK, SHEAR
from test_cone import STATUS_APEX, STATUS_FACE, STATUS_FAILED, angles, make_params, pr


# --------------------------------------------------------------------------- ψ = 0 at the apex

def _trap_points(tier):
    """Tier 0 with ψ = 0, and tier 1 at c = c* (ψ(c*) = 0)."""
    params = make_params(tier, phi=30.0, psi=0.0, phi_star=30.0, c_star=0.8)
    state = np.zeros((1, 1)) if tier == 0 else np.array([[0.0, 0.8]])
    return params, state


@pytest.mark.parametrize("tier", [0, 1])
def test_zero_dilatancy_apex_is_deterministic_under_round_off(tier):
    """σ_n = 0 and an isochoric shear increment: P_tr = 0 up to round-off, exactly the face/
    apex boundary for ψ = 0. Perturbing the volumetric strain by a few ulps must neither
    change the stress (it is 0 to round-off) nor flip the tangent between finite and zero."""
    params, state = _trap_points(tier)
    n = 41
    ulp = np.spacing(1e-3)
    dstrain = np.tile([1e-3, -1e-3, 2e-3], (n, 1))
    dstrain[:, 0] += np.arange(-20, 21) * ulp
    res = tiers.update(tier, np.zeros((n, 3)), np.repeat(state, n, 0), dstrain, np.zeros(n), params)
    k = params.array(tier)[BULK]
    assert np.all(np.abs(res.stress) <= 100 * k * ulp)
    assert set(res.status) <= {STATUS_FACE, STATUS_APEX}
    ref = res.tangent[n // 2]
    assert np.linalg.norm(ref) > k                  # the face's limit, not zero
    assert np.allclose(res.tangent, ref, rtol=1e-9, atol=1e-9 * k)


@pytest.mark.parametrize("tier", [0, 1])
@pytest.mark.parametrize("p_goal", [0.0, 1e-9, 1e-3, 1.0])
@pytest.mark.parametrize("start", [0.0, 1e-19, -1e-19])
def test_zero_dilatancy_mixed_newton_at_the_free_surface_converges(tier, p_goal, start):
    """A material point at σ = 0 sheared (Δγxy = 2e-3) while its volumetric strain e
    (Δεxx = Δεyy = e) is solved so that P reaches p_goal: the global-Newton situation of a
    free surface with ψ = 0. Newton with the consistent tangent must converge in a few
    iterations from starts on the face/apex boundary, never stall on a zero pivot or cycle."""
    params, state = _trap_points(tier)
    e = start
    history = []
    for _ in range(6):
        de = np.array([[e, e, 2e-3]])
        res = tiers.update(tier, np.zeros((1, 3)), state, de, np.zeros(1), params)
        assert res.status[0] != STATUS_FAILED
        resid = pr(res.stress)[0][0] - p_goal
        history.append(resid)
        if abs(resid) <= 1e-12 * max(p_goal, params.p_ref):
            break
        slope = -0.5 * (res.tangent[0, 0, 0] + res.tangent[0, 0, 1]
                        + res.tangent[0, 1, 0] + res.tangent[0, 1, 1])      # dP/de
        assert slope < 0.0, (history, res.tangent[0])
        e -= resid / slope
    assert abs(history[-1]) <= 1e-12 * max(p_goal, params.p_ref), history
    assert len(history) <= 3, history


# --------------------------------------------------------------------------- acceptance 7

EXTREME_LAMBDA = [1e-2, 1e3, 1e12]


@pytest.mark.parametrize("tier", [0, 1])
@pytest.mark.parametrize("lam", EXTREME_LAMBDA)
@pytest.mark.parametrize("phi", [0.5, 60.0, 89.0])
def test_no_nan_or_failure_for_extreme_inputs(tier, lam, phi):
    psi = min(phi, 30.0) * 0.5
    params = make_params(tier, lam=lam, phi=phi, psi=psi, phi_star=phi, phi_min=min(phi, 1.0),
                         phi_max=max(phi, 60.0),
                         nu=0.0, dphi=100.0, dpsi=200.0)
    rng = np.random.default_rng(11)
    n = 600
    directions = rng.standard_normal((n, 3))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    size = rng.choice([1e-12, 1e-6, 1e-1, 0.0], n)
    dstrain = directions * size[:, None]
    kind = rng.integers(0, 4, n)
    p = np.choose(kind, [np.zeros(n), np.full(n, 1e-30), np.full(n, 1.0), np.full(n, 1e8)])
    r = p * np.sin(np.radians(phi)) * rng.uniform(0, 1, n)
    two = rng.uniform(0, 2 * np.pi, n)
    stress = np.stack([-p + r * np.cos(two), -p - r * np.cos(two), r * np.sin(two)], 1)
    state = np.zeros((n, 1)) if tier == 0 else np.stack([np.zeros(n), rng.uniform(0.6, 0.95, n)], 1)
    dspin = rng.choice([0.0, 1e-12, 1e-1, 3.0], n)
    res = tiers.update(tier, stress, state, dstrain, dspin, params)
    assert np.all(res.status != STATUS_FAILED)
    for a in (res.stress, res.state, res.tangent):
        assert np.all(np.isfinite(a))
    pp, rr = pr(res.stress)
    sphi = angles(params, tier, res.state[:, -1])[0]
    mag = np.abs(stress).max(axis=1) + 2 * params.array(tier)[BULK] * np.abs(dstrain).max(axis=1)
    assert np.all(rr - sphi * pp <= 1e-10 * np.abs(pp) + 1e-15 * mag)
    assert np.all(pp >= 0.0)                          # a cohesionless cone carries no tension


@pytest.mark.parametrize("tier", [0, 1])
def test_failed_points_return_inputs_and_the_rest_is_unaffected(tier):
    params = make_params(tier)
    n = 6
    stress = np.tile([-1.0, -1.2, 0.1], (n, 1))
    state = np.zeros((n, 1)) if tier == 0 else np.tile([0.3, 0.8], (n, 1))
    dstrain = np.tile([-1e-3, 2e-3, 0.0], (n, 1))
    dspin = np.zeros(n)
    dstrain[1, 0] = np.nan
    dspin[2] = np.inf
    dstrain[3, 2] = -np.inf
    if tier == 1:
        state[4, 1] = 1.0                             # c outside (0, 1)
    res = tiers.update(tier, stress, state, dstrain, dspin, params)
    bad = [1, 2, 3] + ([4] if tier == 1 else [])
    assert list(res.failed) == bad
    assert np.array_equal(res.stress[bad], stress[bad]) and np.array_equal(res.state[bad], state[bad])
    k, g = params.array(tier)[[BULK, SHEAR]]
    assert np.allclose(res.tangent[bad], [[k + g, k - g, 0], [k - g, k + g, 0], [0, 0, g]])
    good = [i for i in range(n) if i not in bad]
    ref = tiers.update(tier, stress[:1], state[:1], dstrain[:1], dspin[:1], params)
    assert np.all(res.status[good] == STATUS_FACE)
    assert np.array_equal(res.stress[good], np.repeat(ref.stress, len(good), 0))
    assert np.all(np.isfinite(res.tangent))


def test_bad_array_shapes_are_clear_errors():
    params = make_params(1)
    with pytest.raises(ValueError, match=r"state_n has shape \(2, 1\), expected \(2, 2\)"):
        tiers.update(1, np.zeros((2, 3)), np.zeros((2, 1)), np.zeros((2, 3)), np.zeros(2), params)
    with pytest.raises(ValueError, match=r"stress_n has shape \(3,\), expected \(n, 3\)"):
        tiers.update(0, np.zeros(3), np.zeros((1, 1)), np.zeros((1, 3)), np.zeros(1), params)


def test_large_batches_run_in_parallel_and_agree_with_small_ones():
    """Above PARALLEL_MIN_POINTS the kernel uses the thread pool: same results, reusing `out`."""
    params = make_params(1)
    rng = np.random.default_rng(2)
    n = tiers.PARALLEL_MIN_POINTS + 10
    p = rng.uniform(0.5, 2, n)
    stress = np.stack([-p, -p * 1.4, 0.1 * p], 1)
    state = np.stack([np.zeros(n), rng.uniform(0.75, 0.85, n)], 1)
    dstrain = 1e-3 * rng.standard_normal((n, 3))
    dspin = 1e-3 * rng.standard_normal(n)
    out = tiers.allocate(1, n)
    big = tiers.update(1, stress, state, dstrain, dspin, params, out=out)
    assert big is out
    small = tiers.update(1, stress[:100], state[:100], dstrain[:100], dspin[:100], params)
    assert np.array_equal(big.stress[:100], small.stress)
    assert np.array_equal(big.tangent[:100], small.tangent)
    with pytest.raises(ValueError, match="out is sized for"):
        tiers.update(1, stress[:5], state[:5], dstrain[:5], dspin[:5], params, out=out)

"""Tier 2 update (the cone whose axis follows the fabric): each property against something
independent of the kernel — tier 1's closed-form update, central differences of the whole
update, the yield function from its definition (conftest.cone_yield), the exact rotation,
the admissible set of Roux & Radjaï 2001, the step-size order of backward Euler, and the
apex's closed form."""
import numpy as np
import pytest

from conftest import cone_yield, model_params, stress_at
from contfab.models import tiers
from contfab.models.cone import STATUS_APEX, STATUS_ELASTIC, STATUS_FACE, STATUS_FAILED
from contfab.models.fabric_cone import STATUS_PROJECTED
from contfab.tensors import rotate
from dem.conventions import admissibility_margin

LAWS = ("relaxation", "balance")
VARIANTS = {"relaxation": {"fabric_law": "relaxation"}, "balance": {"fabric_law": "balance"},
            "relaxation, speed and dilation": {"fabric_law": "relaxation", "relax_rate": 60.0,
                                               "fabric_speed": 3.0, "fabric_dilation": 40.0}}
"""The fabric laws, and the relaxation law with its largest speed and acceleration by
dilation (the shipped form), whose rate depends on the increment's direction."""


def _random_points(rng, n, ratio=0.6, b_ratio=0.5):
    """(stress, state) of n points: P in [0.5, 2], R/P in [0, ratio] along a random axis
    (inside and beyond the cone), c in [0.78, 0.84] (loose to dense around c* = 0.81),
    A in [0.8, 1.1], B/A in [0, b_ratio] along a random θp (admissible)."""
    c = rng.uniform(0.78, 0.84, n)
    a = rng.uniform(0.8, 1.1, n)
    b = a * rng.uniform(0.0, b_ratio, n)
    theta_p = rng.uniform(0.0, np.pi, n)
    state = np.column_stack([rng.uniform(0.0, 1.0, n), c, a, b * np.cos(2 * theta_p),
                             b * np.sin(2 * theta_p)])
    p = rng.uniform(0.5, 2.0, n)
    r = p * rng.uniform(0.0, ratio, n)
    alpha = rng.uniform(0.0, np.pi, n)
    stress = np.column_stack([-p + r * np.cos(2 * alpha), -p - r * np.cos(2 * alpha),
                              r * np.sin(2 * alpha)])
    return stress, state


def _random_increments(rng, n, lo, hi):
    """Strain increments of random direction and log-uniform size in [10^lo, 10^hi], and
    spins of the same size."""
    d = rng.standard_normal((n, 3))
    size = 10.0 ** rng.uniform(lo, hi, n)
    return d / np.linalg.norm(d, axis=1)[:, None] * size[:, None], rng.standard_normal(n) * size


def _random_update(law, seed, n, increments):
    """The tier-2 update of ``n`` random points (:func:`_random_points`) of fabric-law
    variant ``law`` under ``increments(rng, n)`` -> (Δε, Δω); returns (params, stress,
    state, Δε, Δω, result)."""
    params = model_params(**VARIANTS[law])
    rng = np.random.default_rng(seed)
    stress, state = _random_points(rng, n)
    de, dw = increments(rng, n)
    return params, stress, state, de, dw, tiers.update(2, stress, state, de, dw, params)


def _norm(stress):
    return np.linalg.norm(stress, axis=-1)


@pytest.mark.parametrize("law", LAWS)
def test_without_fabric_weight_and_dilatancy_slope_tier2_is_tier1(law):
    # w = 0, k_d = 0: the cone's axis is 0 and its radius and dilatancy are tier 1's, so
    # stress, c, gp, the tangent and the status are those of tier 1's closed-form update
    # (contfab.models.cone), whatever the fabric does. Measured (run with -s): stress
    # 1.3e-12 of |σ|, c 5.1e-15, gp 3.4e-15, tangent 7.7e-13 of K (2000 points: elastic,
    # face and apex); the stress is tier 2's local solve's tolerance (NEWTON_TOL = 1e-12).
    params = model_params(fabric_weight=0.0, dilatancy_fabric=0.0, fabric_law=law)
    rng = np.random.default_rng(0)
    n = 2000
    stress, state = _random_points(rng, n)
    de, dw = _random_increments(rng, n, -5.0, -2.0)
    two = tiers.update(2, stress, state, de, dw, params)
    one = tiers.update(1, stress, state[:, :2], de, dw, params.with_tier(1))
    bulk = params.array(2)[0]
    status2 = np.where(two.status == STATUS_PROJECTED, STATUS_FACE, two.status)
    assert np.array_equal(status2, one.status)
    assert {STATUS_ELASTIC, STATUS_FACE, STATUS_APEX} <= set(one.status.tolist())
    scale = np.maximum(_norm(stress), _norm(one.stress))
    d_stress = np.max(np.abs(two.stress - one.stress).max(axis=1) / scale)
    d_c, d_gp = (np.max(np.abs(two.state[:, k] - one.state[:, k])) for k in (1, 0))
    d_tangent = np.max(np.abs(two.tangent - one.tangent)) / bulk
    print(f"\n{law}: {n} points, elastic/face/apex {np.bincount(one.status, minlength=3).tolist()}; "
          f"|tier 2 - tier 1|: stress {d_stress:.2g} of |σ|, c {d_c:.2g}, gp {d_gp:.2g}, "
          f"tangent {d_tangent:.2g} of K")
    assert d_stress < 1e-10 and d_c < 1e-13 and d_gp < 1e-13 and d_tangent < 1e-10


@pytest.mark.parametrize("law", VARIANTS)
def test_consistent_tangent_matches_central_differences_at_plastic_points(law):
    # Anisotropic fabrics (B/A up to 0.5) at random angles to the stress: the flow is
    # along s + Pα, not coaxial with σ. Central differences with h = 1e-5 |Δε| of the
    # whole update. Measured: <= 7.5e-11 of the largest entry (115 face points).
    params, stress, state, de, dw, res = _random_update(
        law, 1, 200, lambda rng, n: (1e-3 * rng.standard_normal((n, 3)), 1e-3 * rng.standard_normal(n)))
    face = np.flatnonzero(res.status == STATUS_FACE)
    assert face.size > 80
    # non-coaxial: the fabric's direction is away from the stress's principal axis
    theta_s = 0.5 * np.arctan2(stress[face, 2], 0.5 * (stress[face, 0] - stress[face, 1]))
    theta_p = 0.5 * np.arctan2(state[face, 4], state[face, 3])
    b_ratio = np.hypot(state[face, 3], state[face, 4]) / state[face, 2]
    assert np.sum((np.abs(np.sin(2 * (theta_s - theta_p))) > 0.5) & (b_ratio > 0.2)) > 20
    h = 1e-5 * np.abs(de[face]).max(axis=1)
    fd = np.empty((face.size, 3, 3))
    for j in range(3):
        e = np.zeros((face.size, 3))
        e[:, j] = h
        plus = tiers.update(2, stress[face], state[face], de[face] + e, dw[face], params)
        minus = tiers.update(2, stress[face], state[face], de[face] - e, dw[face], params)
        assert np.all(plus.status == STATUS_FACE) and np.all(minus.status == STATUS_FACE)
        fd[:, :, j] = (plus.stress - minus.stress) / (2.0 * h[:, None])
    err = np.abs(fd - res.tangent[face]).max(axis=(1, 2)) / np.abs(res.tangent[face]).max(axis=(1, 2))
    print(f"\n{law}: {face.size} face points, |T - central differences| <= {err.max():.2g} "
          f"of the largest entry (median {np.median(err):.2g})")
    assert err.max() < 1e-8, err.max()


@pytest.mark.parametrize("law", VARIANTS)
def test_every_plastic_result_lies_on_its_own_yield_surface(law):
    # f(σ_{n+1}; c_{n+1}, q_{n+1}) = 0 from the yield function's definition, to 1e-9 of |σ|,
    # with Δγ >= 0 (measured: 8e-13).
    n = 2000
    params, stress, state, de, dw, res = _random_update(
        law, 2, n, lambda rng, n: _random_increments(rng, n, -5.0, -2.0))
    plastic = np.isin(res.status, (STATUS_FACE, STATUS_PROJECTED))
    assert plastic.sum() > 0.4 * n
    f = np.abs(cone_yield(params, res.stress[plastic], res.state[plastic]))
    print(f"\n{law}: {plastic.sum()} plastic of {n}, max |f|/|σ| {np.max(f / _norm(res.stress[plastic])):.2g}, "
          f"min Δγ {np.min(res.state[plastic, 0] - state[plastic, 0]):.2g}")
    assert np.max(f / _norm(res.stress[plastic])) < 1e-9
    assert np.all(res.state[plastic, 0] - state[plastic, 0] >= 0.0)
    # and every elastic result inside the cone, every result finite
    elastic = res.status == STATUS_ELASTIC
    assert np.all(cone_yield(params, res.stress[elastic], res.state[elastic])
                  <= 1e-10 * _norm(res.stress[elastic]))
    assert np.all(np.isfinite(res.stress)) and np.all(np.isfinite(res.state))


def test_rigid_rotation_turns_stress_and_fabric_and_changes_nothing_else():
    # Δε = 0, a spin Δω: σ' = Q σ Qᵀ, θp' = θp + Δω, A, B and R/P unchanged, rigid (status 0)
    # — from states inside the cone and on it (the plastic results of a first update).
    params = model_params()
    rng = np.random.default_rng(3)
    n = 500
    stress, state = _random_points(rng, n)
    de, dw = _random_increments(rng, n, -4.0, -2.5)
    first = tiers.update(2, stress, state, de, dw, params)
    assert np.sum(first.status == STATUS_FACE) > 0.3 * n
    ok = first.status != STATUS_APEX
    stress, state = first.stress[ok], first.state[ok]
    spin = rng.uniform(-7.0, 7.0, ok.sum())
    res = tiers.update(2, stress, state, np.zeros((ok.sum(), 3)), spin, params)
    assert np.all(res.status == STATUS_ELASTIC)
    exact = np.column_stack(rotate(stress[:, 0], stress[:, 1], stress[:, 2], spin))
    d_stress = np.max(np.abs(res.stress - exact).max(axis=1) / _norm(stress))
    b0, b1 = np.hypot(state[:, 3], state[:, 4]), np.hypot(res.state[:, 3], res.state[:, 4])
    turn = 0.5 * (np.arctan2(res.state[:, 4], res.state[:, 3])
                  - np.arctan2(state[:, 4], state[:, 3])) - spin

    def ratio(s):
        return np.hypot(0.5 * (s[:, 0] - s[:, 1]), s[:, 2]) / (-0.5 * (s[:, 0] + s[:, 1]))
    d_ratio = np.max(np.abs(ratio(res.stress) - ratio(stress)))
    print(f"\n{ok.sum()} points ({np.sum(first.status[ok] == STATUS_FACE)} on the cone), "
          f"|Δω| <= 7: σ - QσQᵀ {d_stress:.2g} of |σ|, gp, c, A bitwise "
          f"{np.array_equal(res.state[:, :3], state[:, :3])}, |ΔB|/B {np.max(np.abs(b1 - b0) / b0):.2g}, "
          f"|sin 2(Δθp - Δω)| {np.max(np.abs(np.sin(2.0 * turn))):.2g}, Δ(R/P) {d_ratio:.2g}")
    assert d_stress < 1e-14 and d_ratio < 1e-14
    assert np.array_equal(res.state[:, :3], state[:, :3])              # gp, c, A
    assert np.max(np.abs(b1 - b0) / b0) < 1e-15
    assert np.max(np.abs(np.sin(2.0 * turn))) < 1e-13 and np.all(np.cos(2.0 * turn) > 0)


def _update_cutting(params, stress, state, de, dw, depth=0):
    """tiers.update as a caller uses it: a failed point redoes its step as two halves (the
    contract's step cutting), and stays failed (with its input) if either half fails.
    Returns (stress, state, status)."""
    res = tiers.update(2, stress, state, de, dw, params)
    s, q, status = res.stress.copy(), res.state.copy(), res.status.copy()
    failed = np.flatnonzero(status == STATUS_FAILED)
    if failed.size and depth < 10:
        half = _update_cutting(params, stress[failed], state[failed], 0.5 * de[failed],
                               0.5 * dw[failed], depth + 1)
        full = _update_cutting(params, half[0], half[1], 0.5 * de[failed], 0.5 * dw[failed],
                               depth + 1)
        s[failed], q[failed], status[failed] = full
        lost = failed[half[2] == STATUS_FAILED]
        s[lost], q[lost], status[lost] = stress[lost], state[lost], STATUS_FAILED
    return s, q, status


@pytest.mark.parametrize("law", LAWS)
def test_fabric_stays_admissible_on_random_large_increments(law):
    # 100 points x 100 steps of strain increments 0.3 % to 30 % in random directions with
    # spins from B/A = 0.31, every step's fabric inside 0 <= B <= A, (π/6) A + (√3/4) B <= 1 (Roux & Radjaï
    # 2001, eqs 1.14-1.15).
    params = model_params(fabric_law=law)
    rng = np.random.default_rng(4)
    n = 100
    stress = np.tile(stress_at(1.0, 0.0, 0.0), (n, 1))
    state = np.tile([0.0, 0.81, 3.0 / np.pi, 0.3, 0.0], (n, 1))
    counts = np.zeros(5, dtype=int)
    margin = np.inf
    for _ in range(100):
        de, dw = _random_increments(rng, n, -2.5, -0.5)
        stress, state, status = _update_cutting(params, stress, state, de, dw)
        counts += np.bincount(status + 1, minlength=5)
        assert np.all(np.isfinite(stress)) and np.all(np.isfinite(state))
        margin = min(margin, admissibility_margin(state[:, 2], np.hypot(state[:, 3], state[:, 4])).min())
        assert margin >= 0.0
        # keep the walk where the model lives: c in [0.7, 0.9], P in (1e-3, 10) (10 = 1 % of K)
        state[:, 1] = np.clip(state[:, 1], 0.7, 0.9)
        p = -0.5 * (stress[:, 0] + stress[:, 1])
        stress[p > 10.0] *= (10.0 / p[p > 10.0])[:, None]
        stress[p < 1e-3] = stress_at(1.0, 0.0, 0.0)
    print(f"\n{law}: failed (after cutting)/elastic/face/apex/projected {counts.tolist()}, "
          f"min admissibility margin {margin:.3g}")
    assert counts[1 + STATUS_FACE] + counts[1 + STATUS_PROJECTED] > 0.3 * counts.sum()
    if law == "relaxation":
        assert counts[1 + STATUS_PROJECTED] == 0          # admissible by construction


def _monotonic_run(params, n):
    """σ and (c, A, Bc, Bs) after the strain 0.05 (0.3, -1, 0.5) in n equal steps, from an
    anisotropic fabric at 34° to the loading (the fabric turns and the cone moves)."""
    stress = stress_at(1.0, 0.2, 0.0)[None, :]
    state = np.array([[0.0, 0.82, 0.95, 0.2 * np.cos(1.2), 0.2 * np.sin(1.2)]])
    de = (0.05 / n * np.array([0.3, -1.0, 0.5]))[None, :]
    for _ in range(n):
        res = tiers.update(2, stress, state, de, np.zeros(1), params)
        assert res.status[0] in (STATUS_FACE, STATUS_PROJECTED)
        stress, state = res.stress, res.state
    return np.concatenate([stress[0] / np.abs(stress[0]).max(), state[0, 1:]])


@pytest.mark.parametrize("law", LAWS)
def test_backward_euler_is_first_order_in_the_step(law):
    # Halving the step halves the error: the differences of successive halvings fall by 2
    # (measured orders 0.992-0.998).
    params = model_params(fabric_law=law)
    runs = [_monotonic_run(params, n) for n in (25, 50, 100, 200, 400)]
    diffs = np.array([np.abs(runs[i] - runs[i + 1]).max() for i in range(len(runs) - 1)])
    orders = np.log2(diffs[:-1] / diffs[1:])
    print(f"\n{law}, n = 25..400: differences {', '.join(f'{d:.3g}' for d in diffs)}, "
          f"orders {', '.join(f'{o:.3f}' for o in orders)}")
    assert np.all((orders > 0.95) & (orders < 1.05)), orders


def test_bad_input_fails_with_its_input_returned_and_no_nan():
    params = model_params()
    bulk, shear = params.array(2)[:2]
    good_s = stress_at(1.0, 0.3, 0.2)
    good_q = np.array([0.0, 0.81, 0.95, 0.1, 0.05])

    def q(**kw):
        out = good_q.copy()
        for k, v in kw.items():
            out[("gp", "c", "A", "Bc", "Bs").index(k)] = v
        return out
    rows = [(np.array([np.nan, -1.0, 0.0]), good_q, np.zeros(3), 0.0),
            (good_s, q(A=np.inf), np.zeros(3), 0.0),
            (good_s, q(Bs=np.nan), np.zeros(3), 0.0),
            (good_s, good_q, np.array([0.0, np.nan, 0.0]), 0.0),
            (good_s, good_q, np.zeros(3), np.nan),
            (good_s, q(c=0.0), np.array([-1e-3, 1e-3, 0.0]), 0.0),
            (good_s, q(c=1.0), np.array([-1e-3, 1e-3, 0.0]), 0.0),
            (good_s, q(c=1.2), np.zeros(3), 0.0),
            (good_s, q(A=0.0), np.array([-1e-3, 1e-3, 0.0]), 0.0),
            (good_s, q(A=-0.5), np.zeros(3), 0.0)]
    stress, state, de, dw = (np.array(x) for x in zip(*rows))
    res = tiers.update(2, stress, state, de, dw, params)
    assert np.all(res.status == STATUS_FAILED)
    assert np.array_equal(res.stress, stress, equal_nan=True)
    assert np.array_equal(res.state, state, equal_nan=True)
    assert np.all(np.isfinite(res.tangent))
    assert res.tangent == pytest.approx(np.broadcast_to(
        [[bulk + shear, bulk - shear, 0], [bulk - shear, bulk + shear, 0], [0, 0, shear]],
        res.tangent.shape))
    # finite inputs never give NaN: the rows with a bad c or A but finite numbers
    finite = np.all(np.isfinite(stress), axis=1) & np.all(np.isfinite(state), axis=1)
    assert np.all(np.isfinite(res.stress[finite])) and np.all(np.isfinite(res.state[finite]))


@pytest.mark.parametrize("b_ratio", [0.0, 0.2])
def test_isotropic_extension_from_a_small_pressure_returns_to_the_apex(b_ratio):
    # Loose (c = 0.77 < c*: sin ψ = -0.056) with a fabric weaker than the critical one
    # (B/A <= 0.2 < b_c = 0.25): D = sin ψ + k_d (|α| - w b_c) < 0, a contracting flow. An
    # isotropic extension past P = 0 then cannot end on the cone's face: σ = 0, all of
    # C⁻¹σ_tr plastic, c = c_n exp(P_tr/K), zero tangent (closed form).
    params = model_params()
    bulk = params.array(2)[0]
    p0 = 1e-3
    stress = stress_at(p0, 0.0, 0.0)[None, :]
    a = 0.95
    state = np.array([[0.1, 0.77, a, b_ratio * a * np.cos(0.8), b_ratio * a * np.sin(0.8)]])
    e = 1e-6                                   # P_tr = p0 - 2 K e = -1e-3
    res = tiers.update(2, stress, state, np.array([[e, e, 0.0]]), np.zeros(1), params)
    assert res.status[0] == STATUS_APEX
    assert np.all(res.stress == 0.0) and np.all(res.tangent == 0.0)
    p_trial = p0 - 2.0 * bulk * e
    assert res.state[0, 1] == pytest.approx(0.77 * np.exp(p_trial / bulk), rel=1e-14)
    assert res.state[0, 0] == pytest.approx(0.1, rel=1e-14)   # no deviatoric plastic strain
    assert admissibility_margin(res.state[0, 2], np.hypot(res.state[0, 3], res.state[0, 4])) >= 0

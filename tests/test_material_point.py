"""The material-point driver (contfab.material_point): mixed control, the exact control
Jacobian, stress-control accuracy on every standard path, stop conditions, step cutting,
and the physics of the tier-1 critical state, the quadratic Newton, the step-size order
per tier (strain path, not time parametrization) and the rotation path."""
import dataclasses
import math

import numpy as np
import pytest

from contfab import material_point as mp
from contfab.models import tiers
from contfab.models.cone import tier1_angles
from contfab.params import ParamError
from conftest import fixed_params
from dem.paths import COMPONENTS, STRESS_INDEX, Path, load_path, parse_path, standard_paths

TIERS = sorted(tiers.KERNELS)
"""Every registered tier (a new tier joins these tests when it registers)."""


def stage_path(name, length, output_every, L, sigma=None, until=None):
    stage = {"name": name, "length": length, "output_every": output_every, "L": L}
    if sigma:
        stage["sigma"] = sigma
    if until:
        stage["until"] = until
    return parse_path({"name": name, "stage": [stage]})


def biaxial(length, output_every):
    """Compression along y at σxx = -P0 (the standard biaxial stage, any length)."""
    return stage_path("biaxial", length, output_every, {"yy": -1.0, "xy": 0.0, "yx": 0.0},
                      {"xx": -1.0})


def simple_shear(length, output_every):
    """Simple shear at σyy = -P0 (the standard forward stage, any length)."""
    return stage_path("simple_shear", length, output_every, {"xx": 0.0, "xy": 1.0, "yx": 0.0},
                      {"yy": -1.0})


# --------------------------------------------------------------------------- the control Jacobian

@pytest.mark.parametrize("tier", TIERS)
def test_control_jacobian_matches_central_differences_including_the_spin(tier):
    """∂σ/∂ΔL from the tangent and the objectivity identity S = W(σ) - T W(Δε), against
    central differences of the whole update (spin included), at elastic and plastic points."""
    params = fixed_params()
    rng = np.random.default_rng(3)
    state = tiers.initial_state(tier, params, 1)
    if tier == 2:                  # an anisotropic fabric, B = 0.2 at θp = 30°: it rotates too
        state[0, 3:] = 0.2 * np.cos(np.radians(60)), 0.2 * np.sin(np.radians(60))
    checked = set()
    for _ in range(40):
        p = rng.uniform(0.5, 2.0)
        sphi = np.sin(np.radians(params.tier1.phi_star_deg))
        r = rng.uniform(0.0, 0.99) * sphi * p
        a = rng.uniform(0, np.pi)
        stress = np.array([-p + r * np.cos(2 * a), -p - r * np.cos(2 * a), r * np.sin(2 * a)])
        dl = rng.normal(0.0, 2e-3, 4)
        h = 1e-7

        def sigma(dl):
            res = tiers.update(tier, stress[None], state, (mp.STRAIN_OF_L @ dl)[None],
                               np.array([mp.SPIN_OF_L @ dl]), params)
            return res.stress[0], res.tangent[0], int(res.status[0])

        s, t, status = sigma(dl)
        if status not in (0, 1):
            continue
        checked.add(status)
        jac = mp.control_jacobian(s, t, mp.STRAIN_OF_L @ dl)
        fd = np.stack([(sigma(dl + h * e)[0] - sigma(dl - h * e)[0]) / (2 * h)
                       for e in np.eye(4)], axis=1)
        assert np.allclose(jac, fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())
    assert checked == {0, 1}


# --------------------------------------------------------------------------- acceptance 5

def assert_quadratic(residuals, floor=1e-13):
    """Residuals above round-off converge quadratically: r_{k+1} <= 10 r_k² / r_0 at every
    iteration, and the last measured order log(r_{k+1}/r_k)/log(r_k/r_{k-1}) is > 1.8."""
    r = np.array([x for x in residuals if x > floor])
    assert len(r) >= 3 and residuals[-1] < 1e-11, residuals
    assert np.all(r[1:] <= 10 * r[:-1] ** 2 / r[0]), residuals
    lr = np.log(r[-3:])
    assert (lr[2] - lr[1]) / (lr[1] - lr[0]) > 1.8, residuals


@pytest.mark.parametrize("tier", TIERS)
def test_mixed_control_newton_converges_quadratically(tier):
    """One mixed-control increment (Δε_yy = -1e-3 prescribed) of a dense point 1 % into
    biaxial compression (yielding; tiers 1, 2: softening, c evolving; tier 2 with its cone
    following the evolving fabric), Newton with the consistent tangent from a zero guess of
    the unknowns. Residuals max |σ - σ*| (units of P0) per iteration, measured (run with -s):

    * σxx held (unknown ΔL_xx): tier 0 0.31, 0 (the face return is linear in it: exact in
      one step); tier 1 0.29, 6.1e-4, 2.7e-9, 3.3e-16; tier 2 0.33, 5.6e-4, 1.6e-9, 3.3e-16.
    * σxx and σxy held (unknowns ΔL_xx and ΔL_xy, which also spins the point: the Jacobian's
      spin column): tier 0 0.31, 0.048, 1.8e-3, 6.8e-6, 4.8e-11, 2.2e-16; tier 1 0.29,
      0.047, 1.5e-3, 3.4e-6, 7.6e-12, 3.3e-16 (last order 2.1); tier 2 0.33, 0.050, 2.3e-3,
      1.4e-5, 2.5e-10, 2.2e-16."""
    params = fixed_params()
    start = mp.run_path(biaxial(0.01, 0.01), params, tier,
                        state0=None if tier == 0 else {"c": 0.83})
    dl = np.array([0.0, -1e-3, 0.0, 0.0])
    for unknown, target in (([True, False, False, False], [-1.0, 0.0, 0.0]),
                            ([True, False, True, False], [-1.0, 0.0, 0.1])):
        sol = mp.solve_increment(tier, params, start.stress, start.state, dl, np.array(unknown),
                                 np.array(target))
        print(f"\ntier {tier}, unknowns {[c for c, u in zip(COMPONENTS, unknown) if u]}: "
              f"residuals {', '.join(f'{r:.2g}' for r in sol.residuals)}")
        assert sol.converged and sol.status == 1
        if tier == 0 and len(sol.residuals) == 2:    # linear in the unknown: one exact step
            assert sol.residuals[-1] < 1e-15
        else:
            assert_quadratic(sol.residuals)
    assert sol.dl[2] > 0 and len(sol.residuals) == 6


# --------------------------------------------------------------------------- stress control

def stress_targets(path, result):
    """(rows, targets) of every row after a stage's start: the path's target for that row,
    from the stage-start stress (the previous stage's last row) — as the path defines it."""
    tau, stage = result["tau"], result["stage"]
    stress = np.stack([result["sxx"], result["syy"], result["sxy"]], 1)
    rows, targets = [], []
    start = 0
    for i in range(1, len(tau)):
        if stage[i] != stage[i - 1]:
            start = i - 1
        st = path.stages[stage[i]]
        progress = (tau[i] - tau[start]) / st.length
        rows.append(i)
        targets.append(st.stress_target(stress[start], progress))
    return np.array(rows), np.array(targets)


@pytest.mark.parametrize("tier", TIERS)
@pytest.mark.parametrize("lam", [1e3, 1e6])
def test_stress_targets_hold_on_every_standard_path(tier, lam):
    params = fixed_params().replace("regularization", lam=lam)
    # the documented tolerance at stresses <= 4 P0 and strain increments <= 2Δτ: 1.7e-13
    # (λ = 1e3), 3e-11 (λ = 1e6: round-off of trial stresses of order E_reg Δε ~ 1e3 P0)
    bound = mp.RTOL * 4 + mp.ROUNDOFF * (4 + lam * 2 * mp.DEFAULT_INCREMENT)
    checked = 0
    for name in standard_paths():
        for path in load_path(name).expand():
            res = mp.run_path(path, params, tier)
            rows, targets = stress_targets(path, res)
            stress = np.stack([res["sxx"], res["syy"], res["sxy"]], 1)[rows]
            for k, st in enumerate(path.stages):
                mask = res["stage"][rows] == k
                comps = sorted({STRESS_INDEX[c] for c, s in zip(COMPONENTS, st.stress_controlled)
                                if s})
                err = np.abs(stress[mask][:, comps] - targets[mask][:, comps])
                assert np.all(err <= bound), (name, err.max())
                checked += mask.sum() * len(comps)
    assert checked > 1000


@pytest.mark.parametrize("tier", TIERS)
def test_isotropic_ramp_and_probes_inside_the_cone_are_elastic_closed_form(tier):
    """Inside the cone the regularization is the whole response: ε_v = -ΔP/K on the
    isotropic ramp (4 P0 and back), and each stress probe gives Δε = C⁻¹Δσ."""
    params = fixed_params()
    k_bulk, g = params.regularization.moduli()
    res = mp.run_path("isotropic_compression", params, tier)
    loaded = np.argmin(np.abs(res["tau"] - 0.05))
    assert res["eps_v"][loaded] == pytest.approx(-3.0 / k_bulk, rel=1e-12)
    assert abs(res["eps_v"][-1]) < 1e-15 and np.all(res["gp"] == 0.0)
    for probe in mp.run_family("stress_probes", params, tier):
        ds = np.array([probe["sxx"][-1] + 1, probe["syy"][-1] + 1])
        de = np.array([probe["eps_xx"][-1], probe["eps_yy"][-1]])
        compliance = np.linalg.inv([[k_bulk + g, k_bulk - g], [k_bulk - g, k_bulk + g]])
        assert de == pytest.approx(compliance @ ds, rel=1e-10, abs=1e-16)
        assert probe["tau"][0] == 0.0 and probe["sxx"][0] == -1.0


# --------------------------------------------------------------------------- acceptance 2

def test_tier1_dense_and_loose_reach_the_critical_state():
    """Biaxial compression to 200% axial strain: dense (c0 = 0.83) dilates and softens,
    loose (0.79) contracts and hardens, both end at c_p = c*, R/P = sin φ* to 1e-6; the
    reported packing fraction c is the kinematic one, c0 exp(-ε_v), at every row."""
    params = fixed_params()
    path = biaxial(2.0, 0.01)
    c_star = params.tier1.c_star
    sin_star = np.sin(np.radians(params.tier1.phi_star_deg))
    dense = mp.run_path(path, params, 1, state0={"c": 0.83})
    loose = mp.run_path(path, params, 1, state0={"c": 0.79})
    for name, res in (("dense", dense), ("loose", loose)):
        print(f"\n{name} (c0 = {res['c_p'][0]:.2f}): at -εyy = {-res['eps_yy'][-1]:.2f} "
              f"c_p - c* = {res['c_p'][-1] - c_star:.2g}, R/P - sin φ* = "
              f"{res['RP'][-1] - sin_star:.2g}; peak R/P {res['RP'].max():.4f} "
              f"(sin φ* = {sin_star:.4f}), ε_v at the end {res['eps_v'][-1]:+.4f}")
    for res in (dense, loose):
        assert res["c_p"][-1] == pytest.approx(c_star, abs=1e-6)
        assert res["RP"][-1] == pytest.approx(sin_star, abs=1e-6)
        # c = c_p exp((P - p_ref)/K) is the DEM's c = c0 exp(-ε_v): the plastic volume change
        # moves c_p, the elastic one -ΔP/K the rest (λ = 1000, ν = 0 here: K = 500)
        assert res["c"] == pytest.approx(res["c"][0] * np.exp(-res["eps_v"]), rel=1e-12)
        assert res["c"][-1] - res["c_p"][-1] == pytest.approx(
            c_star * np.expm1((res["P"][-1] - 1.0) / params.regularization.moduli()[0]), rel=1e-6)
    assert np.all(np.diff(dense["c_p"]) <= 0) and np.all(np.diff(loose["c_p"]) >= 0)
    assert np.all(np.diff(dense["eps_v"][1:]) > -1e-12)       # dilates
    assert np.all(np.diff(loose["eps_v"][1:]) < 1e-12)        # contracts
    peak = np.argmax(dense["RP"])
    assert dense["RP"][peak] > sin_star + 0.05                 # peak, then softening
    assert np.all(np.diff(dense["RP"][peak:]) <= 1e-15)
    assert np.all(np.diff(loose["RP"][1:]) >= -1e-15) and loose["RP"][1] < sin_star - 0.05
    # the stress ratio is the yield one of the current c at every row past the first
    prm = params.array(1)
    for res in (dense, loose):
        sphi = np.sin([tier1_angles(c, prm)[0] for c in res["c_p"][2:]])
        assert res["RP"][2:] == pytest.approx(sphi, rel=1e-10)


# --------------------------------------------------------------------------- acceptance 6

def increment_orders(path, tier, h0, columns, levels=4, params=None, **kw):
    """Orders log2(e_k / e_{k+1}) of the differences e_k = max |X_{h/2^k} - X_{h/2^(k+1)}|
    over all rows (the rows coincide: increments divide the output interval)."""
    runs = [mp.run_path(path, params, tier, increment=h0 / 2**k, **kw) for k in range(levels)]
    errors = np.array([max(np.max(np.abs(a[c] - b[c])) for c in columns)
                       for a, b in zip(runs[:-1], runs[1:])])
    return np.log2(errors[:-1] / errors[1:]), errors


STRESS = ("sxx", "syy", "sxy")
FABRIC = ("A", "Bc", "Bs")
DENSE = {"c": 0.83}


ORDER_CASES = {
    # tier: (path, increment, compared columns, start state): a path where the
    # integration error is not zero (tier 0's return is exact on proportional paths)
    0: (simple_shear(0.01, 5e-4), 2.5e-4, STRESS, None),
    1: (biaxial(0.05, 2.5e-3), 1.25e-3, STRESS + ("c",), DENSE),
    2: (biaxial(0.05, 2.5e-3), 1.25e-3, STRESS + ("c",) + FABRIC, DENSE),
}


@pytest.mark.parametrize("tier", TIERS)
def test_halving_the_increment_converges_at_first_order(tier):
    """Backward Euler promises first order: measured 1.00, 1.00 (tier 0, simple shear),
    0.99, 0.99 (tier 1, dense biaxial), 0.99, 0.99 (tier 2, dense biaxial, the cone
    following the fabric)."""
    path, h0, columns, state0 = ORDER_CASES[tier]
    orders, errors = increment_orders(path, tier, h0, columns, state0=state0,
                                      params=fixed_params())
    print(f"\ntier {tier} ({path.name}, increments {h0:g}/2^k, k = 0..3; columns "
          f"{', '.join(columns)}): differences {', '.join(f'{e:.3g}' for e in errors)}, "
          f"orders {', '.join(f'{o:.3f}' for o in orders)}")
    assert np.all(np.abs(orders - 1.0) < 0.05), (orders, errors)


def test_tier0_is_exact_on_a_proportional_path():
    """Biaxial compression keeps tier 0's stress fixed on the cone once it yields: the
    return is exact there, whatever the increment (differences at round-off)."""
    _, errors = increment_orders(biaxial(0.01, 5e-4), 0, 5e-4, STRESS + ("eps_xx",), levels=3)
    assert np.all(errors < 1e-12)


def state_columns(tier):
    return STRESS + ("eps_xx", "eps_yy", "gamma", "gp") + tuple(
        k for k in ("c",) + FABRIC if k in tiers.STATE_NAMES[tier])


@pytest.mark.parametrize("tier", TIERS)
def test_rate_scaled_path_gives_the_same_rows(tier):
    """Rate independence: the same strain path traversed twice as fast in τ (rates x2,
    lengths and output intervals /2, increments /2) gives identical states at every row."""
    slow = stage_path("slow", 0.2, 0.01, {"xx": 0.3, "xy": 1.0, "yx": 0.0}, {"yy": -1.0})
    fast = stage_path("fast", 0.1, 0.005, {"xx": 0.6, "xy": 2.0, "yx": 0.0}, {"yy": -1.0})
    a = mp.run_path(slow, fixed_params(), tier, increment=1e-3, state0=ORDER_CASES[tier][3])
    b = mp.run_path(fast, fixed_params(), tier, increment=5e-4, state0=ORDER_CASES[tier][3])
    print(f"\ntier {tier}: path at twice the rate, max |difference| over {len(a['tau'])} rows "
          f"and the columns {', '.join(state_columns(tier))}: "
          f"{max(np.max(np.abs(a[c] - b[c])) for c in state_columns(tier)):.2g}")
    for col in state_columns(tier):
        assert b[col] == pytest.approx(a[col], rel=1e-12, abs=1e-14), col
    assert b["tau"] == pytest.approx(a["tau"] / 2, rel=1e-12)


def split(stage, pieces):
    """The strain path of ``stage`` as stages at other rates: ``pieces`` of (rate factor,
    driving strain); each piece's τ-length is strain / factor, one output row at its end."""
    return Path(name="split", stages=tuple(
            dataclasses.replace(stage, name=f"x{f:g}", rates=tuple(f * r for r in stage.rates),
                                length=e / f, output_every=e / f, until=())
            for f, e in pieces))


@pytest.mark.parametrize("tier", TIERS)
def test_nonuniform_increments_converge_to_the_same_curve(tier):
    """The order-test path (a driving strain ε) as one stage (uniform increments), and as
    three stages at rates 4, 1/2 and 2 over ε/4, ε/4, ε/2 with the same Δτ (increments 4h,
    h/2, 2h in strain): the states at the pieces' ends differ at first order in h."""
    path, h0, columns, state0 = ORDER_CASES[tier]
    stage = path.stages[0]
    total = stage.length
    pieces = split(stage, [(4.0, total / 4), (0.5, total / 4), (2.0, total / 2)])
    ends = np.cumsum([total / 4, total / 4, total / 2])
    diffs = []
    for k in range(4):
        h = h0 / 2**k
        a = mp.run_path(pieces, fixed_params(), tier, increment=h / 4, state0=state0)
        b = mp.run_path(path, fixed_params(), tier, increment=h, state0=state0)
        rows = [int(np.argmin(np.abs(b["tau"] - e))) for e in ends]
        assert b["tau"][rows] == pytest.approx(ends, rel=1e-12)
        diffs.append(max(np.max(np.abs(a[c][1:] - b[c][rows])) for c in columns))
    orders = np.log2(np.array(diffs[:-1]) / np.array(diffs[1:]))
    print(f"\ntier {tier}: three pieces at rates 4, 1/2, 2 against one uniform stage, "
          f"h = {h0:g}/2^k: differences {', '.join(f'{d:.3g}' for d in diffs)}, orders "
          f"{', '.join(f'{o:.3f}' for o in orders)}")
    # measured: tier 0 1.10, 1.05, 1.03; tiers 1, 2 within 0.02 of 1
    assert np.all(np.abs(orders - 1.0) < 0.15) and abs(orders[-1] - 1.0) < 0.05, (orders, diffs)


# --------------------------------------------------------------------------- the rotation path

def test_tier1_rotation_below_the_cone_is_rigid_up_to_the_regularization():
    """Rotating the principal axes at R/P = 0.3 < sin φ: no plastic strain at any λ, and
    the strain (all elastic) falls as 1/λ."""
    peak = {}
    for lam in (1e3, 1e4, 1e5):
        res = mp.run_path("axes_rotation", fixed_params().replace("regularization", lam=lam), 1)
        assert np.all(res["gp"] == 0.0) and np.all(res["c_p"] == res["c_p"][0])
        strain = np.stack([res["eps_xx"], res["eps_yy"], res["eps_xy"]], 1)
        peak[lam] = np.abs(strain).max()
    # order 1 in 1/λ: λ·peak = 0.30014, 0.300014, 0.3000014 (measured; the deviator
    # stage alone gives 0.3/λ, the rotation adds O(1/λ²))
    assert np.log10(peak[1e3] / peak[1e4]) == pytest.approx(1.0, abs=1e-3)
    assert np.log10(peak[1e4] / peak[1e5]) == pytest.approx(1.0, abs=1e-3)
    assert peak[1e5] * 1e5 == pytest.approx(0.3, rel=1e-4)


def test_axes_rotation_at_fixed_p_and_r_flows_with_a_fabric_where_tier1_is_rigid():
    """Acceptance 3 on the standard path (stress control, contfab point axes_rotation):
    R/P = 0.3 below tier 1's sin φ* = 0.375, principal axes turned by 90°. Tier 1 stays
    rigid (gp = 0). Tier 2 starts with a fabric along the ramp's compression axis (B = 0.35
    at θp = 90°: the cone's axis α = w B/A = 0.18 along it, its radius sin φ* - w b_c =
    0.25): rigid on the deviator ramp (|s + Pα| = 0.12 P), it flows as the axes turn away
    from the fabric (|s + Pα| would reach 0.48 P at 90°). Measured (run with -s): gp =
    0.357, B -> 0.117, θp -> -58.8°."""
    params = fixed_params()
    t1 = mp.run_path("axes_rotation", params, 1)
    t2 = mp.run_path("axes_rotation", params, 2, state0={"Bc": -0.35, "Bs": 0.0})
    ramp = t2["stage"] == 0
    print(f"\naxes rotation at R/P = 0.3: tier 1 gp = {t1['gp'][-1]:.3g}; tier 2 gp = "
          f"{t2['gp'][ramp][-1]:.3g} after the deviator ramp, {t2['gp'][-1]:.4f} after the "
          f"rotation, B {t2['B'][0]:.3f} -> {t2['B'][-1]:.3f}, θp "
          f"{np.degrees(t2['theta_p'][0]):.1f}° -> {np.degrees(t2['theta_p'][-1]):.1f}°; "
          f"R/P held to {np.abs(t2['RP'] - np.where(ramp, t2['RP'], 0.3)).max():.2g}")
    assert np.all(t1["gp"] == 0.0)
    assert np.all(t2["gp"][ramp] == 0.0) and t2["gp"][-1] > 0.02
    assert np.abs(t2["RP"][~ramp] - 0.3).max() < 1e-9 and np.abs(t2["P"] - 1.0)[~ramp].max() < 1e-9
    assert t2.stats["cuts"] == 0


# --------------------------------------------------------------------------- stops, cutting

def test_stop_condition_is_located_inside_the_increment():
    """A stage stopped by until c = 0.82 on the dense dilating branch ends at c = 0.82
    (to 1e-10 of its change over an increment), whatever the increment."""
    path = stage_path("to_ratio", 1.0, 0.05, {"yy": -1.0, "xy": 0.0, "yx": 0.0},
                      {"xx": -1.0}, until={"c": 0.82})
    ends = []
    for h in (2e-3, 7e-4):
        res = mp.run_path(path, fixed_params(), 1, increment=h, state0={"c": 0.83})
        assert res.stats["stops"] == ["until c"]
        assert res["c"][-1] == pytest.approx(0.82, abs=1e-12)
        ends.append(res["eps_yy"][-1])
    assert ends[0] == pytest.approx(ends[1], rel=0.05)      # the same strain, to O(h)


@pytest.mark.parametrize("phi, increment", [(22.0, 1e-2), (15.8, 1e-3)])
def test_unreachable_stress_target_is_a_clear_error_with_the_partial_history(phi, increment):
    """σyy ramped to -3 P0 at σxx = -P0 asks for R/P = 0.5 > sin φ (tier 0). At φ = 15.8°
    the unknown strain ran away to -4e14 at the apex (σ = 0) and its round-off allowance
    passed the residual: a silently wrong history, until TOL_CAP."""
    path = stage_path("too_far", 0.1, 0.01, {"xy": 0.0, "yx": 0.0},
                      {"xx": -1.0, "yy": {"target": -3.0, "ramp": True}})
    params = fixed_params().replace("tier0", phi_deg=phi)
    with pytest.raises(mp.IntegrationError) as err:
        mp.run_path(path, params, 0, increment=increment)
    msg = str(err.value)
    assert "stage 0 ('too_far')" in msg and "min_increment" in msg
    assert "yield cone" in msg and err.value.partial is not None
    partial = err.value.partial
    assert partial["RP"][-1] < np.sin(np.radians(phi)) + 1e-9 and len(partial["tau"]) >= 2


def test_step_cutting_recovers_from_a_failed_update(monkeypatch):
    """A failure (status -1) at one increment is cut and retried; the run completes and
    matches the uncut run."""
    calls = {"n": 0}
    real = tiers.update

    def flaky(tier, *args, **kw):
        out = real(tier, *args, **kw)
        calls["n"] += 1
        if calls["n"] == 40:
            out.status[0] = -1
        return out

    ref = mp.run_path("biaxial", fixed_params(), 1)
    monkeypatch.setattr(tiers, "update", flaky)
    res = mp.run_path("biaxial", fixed_params(), 1)
    assert res.stats["cuts"] == 1
    assert res["syy"][-1] == pytest.approx(ref["syy"][-1], rel=1e-9)


# --------------------------------------------------------------------------- bad input

@pytest.mark.parametrize("kwargs, words", [
    ({"tier": 7}, ["tier = 7", "accepted"]),
    ({"increment": 0.0}, ["increment = 0.0", "(0, inf)"]),
    ({"increment": 1e-3, "min_increment": 1e-2}, ["min_increment", "(0, increment]"]),
    ({"state0": {"c": 1.2}}, ["c = 1.2", "(0, 1)"]),
    ({"state0": {"zz": 0.5}}, ["zz", "accepted"]),
    ({"stress0": [1.0, np.nan, 0.0]}, ["stress0", "finite"]),
])
def test_bad_options_are_clear_errors(kwargs, words):
    with pytest.raises(ValueError) as err:
        mp.run_path("biaxial", fixed_params(), **{"tier": 1, **kwargs})
    for w in words:
        assert w in str(err.value)


def test_stop_on_a_quantity_the_tier_does_not_carry_is_refused_before_running():
    path = stage_path("to_fabric", 0.1, 0.01, {"yy": -1.0}, {"xx": -1.0}, until={"B": 0.1})
    with pytest.raises(ValueError, match=r"until.B is not a quantity of tier 1 .*no fabric"):
        mp.run_path(path, fixed_params(), 1)


def test_probe_family_needs_run_family_and_unknown_path_names_the_standard_ones():
    with pytest.raises(ValueError, match="probe family"):
        mp.run_path("stress_probes")
    with pytest.raises(ValueError, match="unknown loading path 'nope'.*biaxial"):
        mp.run_path("nope")
    with pytest.raises(ParamError):
        mp.run_path("biaxial", tier=-1)

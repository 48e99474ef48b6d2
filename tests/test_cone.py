"""Tiers 0/1 return on the cone (acceptance 1): yield, flow rule, c update, consistent tangent.

Every update is checked against the model's equations, recomputed here from the
outputs alone: the plastic strain is Δεp = Δε - C⁻¹(σ - Qσ_nQᵀ). Tolerances: the
acceptance figures (f <= 1e-10·P, dilatancy to 1e-10, tangent to 1e-6 relative against
central finite differences) plus a floor at round-off of the magnitudes that enter the
recomputation (stated next to each check).
"""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.optimize import fsolve

from contfab.models import tiers
from contfab.models.cone import friction_angles, tier1_angles
from contfab.params import BULK, SHEAR, SIN_PHI, SIN_PSI, Params

STATUS_FAILED, STATUS_ELASTIC, STATUS_FACE, STATUS_APEX = -1, 0, 1, 2


# --------------------------------------------------------------------------- helpers

def make_params(tier, lam=1e3, p_ref=1.0, nu=0.0, phi=30.0, psi=0.0, phi_star=25.0, dphi=200.0,
                dpsi=300.0, c_star=0.8, phi_min=1.0, phi_max=60.0):
    return Params.from_dict({
        "tier": tier,
        "regularization": {"lambda": lam, "p_ref": p_ref, "nu": nu},
        "tier0": {"phi_deg": phi, "psi_deg": psi},
        "tier1": {"phi_star_deg": phi_star, "dphi_dc_deg": dphi, "dpsi_dc_deg": dpsi,
                  "c_star": c_star, "phi_min_deg": phi_min, "phi_max_deg": phi_max},
        "initial": {"c0": c_star},
    })


def angles(params, tier, c):
    """(sin φ, sin ψ, piece) at each c; piece identifies the smooth piece of φ(c), ψ(c)."""
    if tier == 0:
        prm = params.array(0)
        n = len(c)
        return np.full(n, prm[SIN_PHI]), np.full(n, prm[SIN_PSI]), np.zeros((n, 2))
    prm = params.array(1)
    out = np.array([tier1_angles(ci, prm) for ci in c])
    return np.sin(out[:, 0]), np.sin(out[:, 1]), out[:, 2:]


def rotate_np(s, w):
    """Q σ Qᵀ with Q the rotation by w, written independently of the kernel's helper."""
    out = np.empty_like(s)
    for i, (si, wi) in enumerate(zip(s, w)):
        q = np.array([[np.cos(wi), -np.sin(wi)], [np.sin(wi), np.cos(wi)]])
        m = q @ np.array([[si[0], si[2]], [si[2], si[1]]]) @ q.T
        out[i] = m[0, 0], m[1, 1], m[0, 1]
    return out


def pr(s):
    """(P, R) of Voigt stresses."""
    return -0.5 * (s[:, 0] + s[:, 1]), np.hypot(0.5 * (s[:, 0] - s[:, 1]), s[:, 2])


def moduli(params, tier):
    prm = params.array(tier)
    return prm[BULK], prm[SHEAR]


def plastic_strain(params, tier, stress_n, dstrain, dspin, stress):
    """Δεp = Δε - C⁻¹(σ - Qσ_nQᵀ) (Voigt, engineering shear)."""
    k, g = moduli(params, tier)
    ds = stress - rotate_np(stress_n, dspin)
    el = np.stack([(ds[:, 0] + ds[:, 1]) / (4 * k) + (ds[:, 0] - ds[:, 1]) / (4 * g),
                   (ds[:, 0] + ds[:, 1]) / (4 * k) - (ds[:, 0] - ds[:, 1]) / (4 * g),
                   ds[:, 2] / g], axis=1)
    return dstrain - el


def fd_tangent(tier, params, stress_n, state_n, dstrain, dspin, h):
    """Central differences of the stress in each strain component; also the ± outputs."""
    d = np.empty((len(h), 3, 3))
    sides = []
    for j in range(3):
        e = np.zeros_like(dstrain)
        e[:, j] = h
        plus = tiers.update(tier, stress_n, state_n, dstrain + e, dspin, params)
        minus = tiers.update(tier, stress_n, state_n, dstrain - e, dspin, params)
        d[:, :, j] = (plus.stress - minus.stress) / (2 * h[:, None])
        sides += [plus, minus]
    return d, sides


def check_update(tier, params, stress_n, state_n, dstrain, dspin, figures=None):
    """Run one update and assert acceptance 1 on every point; return per-status counts.

    ``figures`` (a dict, optional) accumulates the worst measured values: f/P on the face,
    |tr Δεp - sin ψ (Δεp1 - Δεp2)| / (Δεp1 - Δεp2) on the face, the tangent's relative
    (Frobenius) error against central differences, and the number of points checked."""
    res = tiers.update(tier, stress_n, state_n, dstrain, dspin, params)
    k, g = moduli(params, tier)
    assert np.all(res.status != STATUS_FAILED)
    assert np.all(np.isfinite(res.stress)) and np.all(np.isfinite(res.tangent))
    c_n = state_n[:, 1] if tier == 1 else np.ones(len(dspin))
    c = res.state[:, 1] if tier == 1 else c_n
    sphi, spsi, piece = angles(params, tier, c)
    p, r = pr(res.stress)
    mag = np.abs(stress_n).max(axis=1) + 2 * (k + g) * np.abs(dstrain).max(axis=1)

    # yield: f <= 1e-10 P, floor 1e-15 of the stress magnitudes summed into the trial
    f = r - sphi * p
    assert np.all(f <= 1e-10 * np.abs(p) + 1e-15 * mag)
    apex = res.status == STATUS_APEX
    assert np.all(res.stress[apex] == 0.0)

    # flow rule, from the outputs alone; floor: round-off of Δε - C⁻¹Δσ
    ep = plastic_strain(params, tier, stress_n, dstrain, dspin, res.stress)
    tr = ep[:, 0] + ep[:, 1]
    diff = 2 * np.hypot(0.5 * (ep[:, 0] - ep[:, 1]), 0.5 * ep[:, 2])     # Δεp1 - Δεp2
    floor = 1e-13 * (np.abs(dstrain).max(axis=1) + (np.abs(stress_n).max(axis=1)
                                                    + np.abs(res.stress).max(axis=1)) / g)
    face = res.status == STATUS_FACE
    elastic = res.status == STATUS_ELASTIC
    assert np.all(np.abs(tr - spsi * diff)[face] <= (1e-10 * diff + floor)[face])
    # coaxial: the plastic deviator along the stress deviator (unit vectors, cross product)
    n_s = np.stack([0.5 * (res.stress[:, 0] - res.stress[:, 1]), res.stress[:, 2]], 1)
    n_e = np.stack([0.5 * (ep[:, 0] - ep[:, 1]), 0.5 * ep[:, 2]], 1)
    cross = n_s[:, 0] * n_e[:, 1] - n_s[:, 1] * n_e[:, 0]
    dot = np.sum(n_s * n_e, axis=1)
    assert np.all((np.abs(cross) <= 1e-9 * r * diff + r * floor)[face])
    assert np.all((dot >= 0)[face])
    # apex: all trial strain plastic, in the normal cone of g: tr >= sin ψ (Δεp1 - Δεp2)
    assert np.all((tr - spsi * diff)[apex] >= -(1e-10 * diff + floor)[apex])
    assert np.all(np.abs(ep[elastic]).max(axis=1, initial=0.0) <= floor[elastic])
    # state: gp += Δεp1 - Δεp2; tier 1: c = c_n exp(-tr Δεp)
    assert np.all(np.abs(res.state[:, 0] - state_n[:, 0] - diff) <= 1e-9 * diff + floor)
    if tier == 1:
        # (+ 1e-15: a few roundings of c, carried as c_n·Πexp(step), and of c/c_n in the log)
        assert np.all(np.abs(np.log(c / c_n) + tr) <= 1e-12 * diff + floor + 1e-15)

    # tangent vs central differences where the branch (and the piece of φ(c), ψ(c)) is the
    # same on both sides; step 1e-7 of the strain scale of the point (truncation error
    # ~ step², round-off ~ 1e-16/step: both <= 1e-8 relative where measured)
    h = 1e-7 * (np.abs(dstrain).max(axis=1) + np.abs(stress_n).max(axis=1) / g)
    d_fd, sides = fd_tangent(tier, params, stress_n, state_n, dstrain, dspin, h)
    same = np.ones(len(h), bool)
    for s in sides:
        same &= s.status == res.status
        if tier == 1:
            same &= np.all(angles(params, 1, s.state[:, 1])[2] == piece, axis=1)
    err = np.linalg.norm(res.tangent - d_fd, axis=(1, 2))
    scale = np.linalg.norm(d_fd, axis=(1, 2))
    bad = same & (err > 1e-6 * scale)
    assert not bad.any(), (err / np.maximum(scale, 1e-300))[bad]
    if figures is not None:
        loaded = face & (p > 0)
        rel_tangent = np.where(scale > 0, err / np.maximum(scale, 1e-300), err)
        # apex: σ = 0 exactly; f/P has no meaning there (0/0), f = 0 is counted as such
        for key, values in (("f/P", (f / np.where(loaded, p, 1.0))[loaded]),
                            ("|f|/P", (np.abs(f) / np.where(loaded, p, 1.0))[loaded]),
                            ("dilatancy", (np.abs(tr - spsi * diff) / np.where(face, diff, 1.0))[face]),
                            # where Δεp1 - Δεp2 >= 1e-3 of the strain magnitude the stored σ's
                            # rounding (1e-16 |σ|/G in Δεp) cannot reach 1e-10 of it
                            ("dilatancy resolved", (np.abs(tr - spsi * diff) / np.where(
                                face, diff, 1.0))[face & (diff >= 1e-3 * floor / 1e-13)]),
                            ("tangent", rel_tangent[same])):
            figures[key] = max(figures.get(key, -np.inf), float(np.max(values, initial=-np.inf)))
        counts = figures.setdefault("points", np.zeros(3, int))
        counts += [np.sum((res.status == s) & same) for s in (0, 1, 2)]
        figures["pure tension"] = figures.get("pure tension", 0) + int(np.sum(
            (dstrain[:, 0] == dstrain[:, 1]) & (dstrain[:, 0] > 0) & (dstrain[:, 2] == 0) & same))
        figures["apex start"] = figures.get("apex start", 0) + int(np.sum(
            np.all(stress_n == 0, axis=1) & same))
    return {s: int(np.sum((res.status == s) & same)) for s in (0, 1, 2)}


def random_points(rng, tier, params, n, pure_tension=0):
    """Stresses inside / on the cone / at the apex, increments from 1e-3 to 1e3 elastic
    strains in random directions (including dominant isotropic tension), small spins; then
    ``pure_tension`` more points driven by pure isotropic extension (Δε = e (1, 1, 0) exactly,
    no spin) from the same kinds of stress, the apex included (drawn after the first n, which
    stay the same whatever ``pure_tension``)."""
    k, g = moduli(params, tier)
    p_ref = params.p_ref
    c_n = np.clip(params.tier1.c_star + rng.uniform(-0.08, 0.08, n), 0.05, 0.99)
    sphi = angles(params, tier, c_n)[0]
    p = p_ref * 10 ** rng.uniform(-2, 1, n)
    u = rng.choice([0.0, 1.0, -1.0], n, p=[0.2, 0.4, 0.4])
    u = np.where(u < 0, rng.uniform(0, 1, n), u)          # on the cone (1), inside, isotropic (0)
    r = u * sphi * p
    two = rng.uniform(0, 2 * np.pi, n)
    stress = np.stack([-p + r * np.cos(two), -p - r * np.cos(two), r * np.sin(two)], 1)
    stress[rng.random(n) < 0.1] = 0.0                       # at the apex
    direction = rng.standard_normal((n, 3))
    tension = rng.random(n) < 0.15
    direction[tension] = [1.0, 1.0, 0.0] + 0.2 * direction[tension]
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    dstrain = direction * (p_ref / g) * 10 ** rng.uniform(-3, 3, n)[:, None]
    dspin = 1e-2 * rng.standard_normal(n)
    state = np.zeros((n, 1)) if tier == 0 else np.stack([np.zeros(n), c_n], 1)
    if pure_tension:
        s2, q2, _, _ = random_points(rng, tier, params, pure_tension)
        s2[rng.random(pure_tension) < 0.3] = 0.0                  # more of them at the apex
        e = (p_ref / g) * 10 ** rng.uniform(-3, 3, pure_tension)
        de2 = np.stack([e, e, np.zeros(pure_tension)], 1)
        return (np.concatenate([stress, s2]), np.concatenate([state, q2]),
                np.concatenate([dstrain, de2]), np.concatenate([dspin, np.zeros(pure_tension)]))
    return stress, state, dstrain, dspin


phi_deg = st.floats(0.5, 60.0)
psi_fraction = st.one_of(st.sampled_from([-1.0, 0.0, 1.0]), st.floats(-1.0, 1.0))
log_lam = st.floats(1.0, 6.0)
log_pref = st.floats(-3.0, 3.0)
nu = st.floats(-0.5, 0.1)


@settings(max_examples=120, deadline=None)
@given(phi_deg, psi_fraction, log_lam, log_pref, nu, st.integers(0, 2**32 - 1))
def test_tier0_return_yield_flow_tangent(phi, t, log_lam, log_pref, nu, seed):
    params = make_params(0, lam=10**log_lam, p_ref=10**log_pref, nu=nu, phi=phi, psi=t * phi)
    points = random_points(np.random.default_rng(seed), 0, params, 48, pure_tension=8)
    check_update(0, params, *points)


@settings(max_examples=120, deadline=None)
@given(phi_deg, st.floats(0.0, 600.0), st.floats(0.0, 1000.0), st.floats(0.5, 0.9),
       st.floats(0.0, 1.0), st.floats(0.0, 1.0), log_lam, log_pref, nu, st.integers(0, 2**32 - 1))
def test_tier1_return_yield_flow_c_tangent(phi_star, dphi, dpsi, c_star, u_min, u_max, log_lam,
                                           log_pref, nu, seed):
    params = make_params(1, lam=10**log_lam, p_ref=10**log_pref, nu=nu, phi_star=phi_star,
                         dphi=dphi, dpsi=dpsi, c_star=c_star,
                         phi_min=max(0.1, u_min * phi_star), phi_max=phi_star + u_max * (70 - phi_star))
    points = random_points(np.random.default_rng(seed), 1, params, 48, pure_tension=8)
    check_update(1, params, *points)


@pytest.mark.parametrize("tier", [0, 1])
def test_every_branch_is_checked(tier):
    """The generated points reach the elastic, face and apex branches, each FD-checked."""
    params = make_params(tier, psi=10.0)
    counts = check_update(tier, params, *random_points(np.random.default_rng(7), tier, params, 400))
    assert min(counts.values()) >= 20, counts


def test_acceptance_1_figures_over_the_stated_domain():
    """Acceptance 1's figures on a fixed sweep (the hypothesis tests above search the same
    domain at random): tiers 0 and 1, φ (tier 1: φ*) from 0.5° to 60°, ψ from -φ to φ (tier 1:
    ψ(c) sweeps through its clamps at ±φ(c)), λ from 1e2 to 1e6, stresses inside, on the cone
    and at the apex, increments of every direction, pure isotropic extension included.
    Prints the worst f/P, dilatancy error and tangent error (run with -s); measured
    (tier 0 / tier 1): f/P 3.3e-16 / 5.1e-16; dilatancy 9.6e-11 / 1.3e-11 over every face
    point, 1.6e-13 / 1.6e-13 where the plastic strain is resolved (>= 1e-3 of the strain
    magnitude: below, the rounding of the stored σ alone is 1e-16 |σ|/G); tangent
    4.4e-9 / 2.1e-8, on ~7500 FD-checked points per tier, 1260 of them pure tension."""
    worst = {}
    for tier in (0, 1):
        figures = {}
        for phi in (0.5, 1.0, 5.0, 15.0, 30.0, 45.0, 60.0):
            for t in (-1.0, -0.5, 0.0, 0.5, 1.0):
                for k, lam in enumerate((1e2, 1e4, 1e6)):
                    if tier == 0:
                        params = make_params(0, lam=lam, nu=(-0.3, 0.0, 0.1)[k], phi=phi,
                                             psi=t * phi)
                    else:
                        # φ(c) from 0.5 φ* to 1.5 φ* (clamped to [0.5°, 60°]) and ψ(c) from
                        # 1.2 t_max φ* of either sign over c* ± 0.08: through the ψ = ±φ clamps
                        params = make_params(1, lam=lam, nu=(-0.3, 0.0, 0.1)[k], phi_star=phi,
                                             dphi=0.5 * phi / 0.08,
                                             dpsi=(0.25 + abs(t)) * 1.2 * phi / 0.08,
                                             phi_min=0.5, phi_max=60.0)
                    seed = int(1000 * phi) + 10 * int(10 * t) + k
                    points = random_points(np.random.default_rng(seed), tier, params, 60,
                                           pure_tension=12)
                    check_update(tier, params, *points, figures=figures)
        print(f"\ntier {tier}: worst f/P {figures['f/P']:.2g} (|f|/P {figures['|f|/P']:.2g}), "
              f"dilatancy |tr Δεp - sin ψ (Δεp1 - Δεp2)|/(Δεp1 - Δεp2) {figures['dilatancy']:.2g} "
              f"(where Δεp1 - Δεp2 >= 1e-3 (|Δε| + |σ|/G): {figures['dilatancy resolved']:.2g}), "
              f"tangent |T - T_fd|/|T_fd| {figures['tangent']:.2g}; FD-checked points "
              f"elastic/face/apex {figures['points'].tolist()}, of them pure tension "
              f"{figures['pure tension']}, from σ = 0 {figures['apex start']}")
        worst[tier] = figures
        # (every point also passed check_update's bounds, which add the round-off floor)
        assert figures["f/P"] <= 1e-10 and figures["dilatancy resolved"] <= 1e-10
        assert figures["tangent"] <= 1e-6
        assert figures["points"].min() >= 100 and figures["pure tension"] >= 100
        assert figures["apex start"] >= 100


# --------------------------------------------------------------------------- references

def reference_return(params, tier, s_n, c_n, de):
    """Backward Euler solved by fsolve in Cartesian components (no principal frame):
    σ = σ_n + C(Δε - Δγ ∂g/∂σ), f(σ, c) = 0, ln(c/c_n) = -Δγ sin ψ(c)."""
    k, g = moduli(params, tier)
    cmat = np.array([[k + g, k - g, 0], [k - g, k + g, 0], [0, 0, g]])

    def eqs(x):
        s, dgam, c = x[:3], x[3], (x[4] if tier == 1 else c_n)
        sphi, spsi, _ = angles(params, tier, [c])
        p, r = pr(s[None])
        n_d, n_t = 0.5 * (s[0] - s[1]) / r[0], s[2] / r[0]
        dg = np.array([0.5 * (n_d + spsi[0]), 0.5 * (-n_d + spsi[0]), n_t])   # ∂g/∂σ, Voigt strain
        res = list((s - s_n - cmat @ (de - dgam * dg)) / k) + [(r[0] - sphi[0] * p[0]) / k]
        if tier == 1:
            res.append(np.log(c / c_n) + dgam * spsi[0])
        return res

    x0 = list(s_n + cmat @ de) + [0.0] + ([c_n] if tier == 1 else [])
    x = fsolve(eqs, x0, xtol=1e-13)
    assert np.max(np.abs(eqs(x))) < 1e-16     # strain units; increments are ~1e-3
    return x


@pytest.mark.parametrize("tier", [0, 1])
def test_face_return_component_by_component_against_reference(tier):
    params = make_params(tier, phi=35.0, psi=12.0, dphi=300.0, dpsi=500.0, c_star=0.8)
    k, g = moduli(params, tier)
    s_n = np.array([[-1.0, -1.6, 0.2], [-2.0, -1.0, -0.4], [-0.5, -0.5, 0.0]])
    de = np.array([[2e-3, -3e-3, 1e-3], [-2e-3, 1e-3, -2e-3], [-3e-3, 1e-3, 5e-3]])
    c_n = np.array([0.83, 0.78, 0.80])
    state = np.stack([np.zeros(3), c_n], 1) if tier == 1 else np.zeros((3, 1))
    res = tiers.update(tier, s_n, state, de, np.zeros(3), params)
    assert np.all(res.status == STATUS_FACE)
    for i in range(3):
        x = reference_return(params, tier, s_n[i], c_n[i], de[i])
        assert res.stress[i] == pytest.approx(x[:3], rel=1e-10, abs=1e-12)
        assert res.state[i, 0] == pytest.approx(x[3], rel=1e-10)
        if tier == 1:
            assert res.state[i, 1] == pytest.approx(x[4], rel=1e-12)


def test_apex_is_bounded_by_the_plastic_potential():
    """Non-associated flow: a trial state above the yield apex line but outside the
    potential's normal cone goes to the face, and σ = 0 only beyond the potential's line."""
    params = make_params(0, phi=30.0, psi=10.0)
    k, g = moduli(params, 0)
    spsi = np.sin(np.radians(10.0))
    # trial (P_tr, R_tr) with G P_tr + K sψ R_tr = ±small: apex boundary of the potential
    r_tr = 1.0
    p_line = -k * spsi * r_tr / g
    stress_tr = np.array([[-p + r_tr, -p - r_tr, 0.0] for p in (p_line + 1e-3, p_line - 1e-3)])
    res = tiers.update(0, stress_tr, np.zeros((2, 1)), np.zeros((2, 3)), np.zeros(2), params)
    assert list(res.status) == [STATUS_FACE, STATUS_APEX]
    assert pr(res.stress[:1])[0][0] == pytest.approx(1e-3 * g / (g + k * 0.5 * spsi), rel=1e-9)
    assert np.all(res.stress[1] == 0.0) and np.all(res.tangent[1] == 0.0)
    # the yield function alone would have sent both to the apex (P_tr < 0 is tension)
    assert p_line < 0


def test_pure_spin_rotates_stress_exactly_and_the_update_is_isotropic():
    params = make_params(1)
    rng = np.random.default_rng(3)
    s_n = np.array([[-1.0, -1.3, 0.1]] * 5)
    state = np.array([[0.0, 0.8]] * 5)
    w = rng.uniform(-3, 3, 5)
    res = tiers.update(1, s_n, state, np.zeros((5, 3)), w, params)
    assert np.all(res.status == STATUS_ELASTIC)
    assert np.allclose(res.stress, rotate_np(s_n, w), rtol=0, atol=1e-14)
    # rotating the inputs rotates the outputs (isotropic cone, objective update)
    de = np.array([[-2e-3, 1e-3, 4e-3]] * 5)
    base = tiers.update(1, s_n, state, de, np.zeros(5), params)
    assert np.all(base.status == STATUS_FACE)
    de_rot = rotate_np(de * [1, 1, 0.5], w) * [1, 1, 2]     # strain tensor with εxy = γxy/2
    turned = tiers.update(1, rotate_np(s_n, w), state, de_rot, np.zeros(5), params)
    assert np.allclose(turned.stress, rotate_np(base.stress, w), rtol=0, atol=1e-12)
    assert np.allclose(turned.state, base.state, rtol=1e-13)


def test_tier1_without_c_dependence_is_tier0_isochoric():
    t0 = make_params(0, phi=27.0, psi=0.0)
    t1 = make_params(1, phi_star=27.0, dphi=0.0, dpsi=0.0)
    rng = np.random.default_rng(5)
    s, _, de, w = random_points(rng, 0, t0, 300)
    state1 = np.stack([np.zeros(300), np.full(300, 0.7)], 1)
    a = tiers.update(0, s, np.zeros((300, 1)), de, w, t0)
    b = tiers.update(1, s, state1, de, w, t1)
    assert np.array_equal(a.status, b.status)
    assert np.allclose(a.stress, b.stress, rtol=1e-13, atol=1e-15)
    assert np.allclose(a.tangent, b.tangent, rtol=1e-12, atol=1e-12 * 1e3)
    # c stays put on the face (ψ ≡ 0) and opens at the apex: c = c_n exp(P_tr/K)
    apex = b.status == STATUS_APEX
    assert np.all(b.state[~apex, 1] == 0.7)
    k = moduli(t1, 1)[0]
    p_tr = pr(rotate_np(s, w))[0] - k * (de[:, 0] + de[:, 1])
    assert np.allclose(b.state[apex, 1], 0.7 * np.exp(p_tr[apex] / k), rtol=1e-14)


def test_friction_angles_follow_the_linear_law_and_its_clamps():
    prm = np.radians([25.0, 200.0, 300.0]).tolist() + [0.8] + np.radians([10.0, 30.0]).tolist()
    phi, psi, phi_c, psi_c = friction_angles(0.81, *prm)
    assert np.degrees([phi, psi]) == pytest.approx([27.0, 3.0])
    assert (phi_c, psi_c) == pytest.approx((prm[1], prm[2]))
    phi, psi, phi_c, psi_c = friction_angles(0.95, *prm)     # φ at φmax, ψ clamped to φ
    assert np.degrees([phi, psi]) == pytest.approx([30.0, 30.0]) and phi_c == psi_c == 0.0
    phi, psi, _, psi_c = friction_angles(0.7, *prm)          # φ at φmin, ψ = -φ
    assert np.degrees([phi, psi]) == pytest.approx([10.0, -10.0]) and psi_c == 0.0
    assert friction_angles(0.8, *prm)[1] == 0.0             # ψ(c*) = 0


def test_tier1_local_solve_does_not_cycle_between_a_clamp_and_the_apex_continuation():
    """Found by a soak run: H has slope 1 both where ψ(c) is clamped (c > c* + ...) and in
    its apex continuation, and is steep in between, so plain Newton jumped back and forth
    between two points forever; the bisection safeguard must take over."""
    params = make_params(1, lam=335.32334254554246, p_ref=107.3769338330418, nu=-0.17674876516767063,
                         phi_star=3.7172831425398623, dphi=469.33171658564146,
                         dpsi=728.3947549838374, c_star=0.6207524227313319,
                         phi_min=1.7901805457357356, phi_max=10.056995717798399)
    stress = np.array([[-524.8824243639351, -746.6923416033694, -5.185398844652718]])
    state = np.array([[0.0, 0.670219784517]])
    dstrain = np.array([[0.2559144354859468, -0.1767623681539971, -0.05354570861303294]])
    counts = check_update(1, params, stress, state, dstrain, np.array([0.0055742042855530085]))
    assert counts[STATUS_FACE] == 1


def test_tier1_local_solve_falls_back_to_bisection_when_newton_stalls():
    """Found by a soak run: Newton from each end of the bracket lands just inside the
    other end (Δγ < 0 over part of it), shrinking the bracket by 1e-9 per iteration."""
    params = make_params(1, lam=86.89184873708996, p_ref=0.7149576355326833, nu=-0.3229152532464896,
                         phi_star=44.742787368884365, dphi=503.3137706039964, dpsi=290.84964971017,
                         c_star=0.5324461927003603, phi_min=19.051875141152088,
                         phi_max=47.033053886228195)
    points = random_points(np.random.default_rng(3042667000), 1, params, 48)
    counts = check_update(1, params, *points)
    assert counts[STATUS_FACE] > 0

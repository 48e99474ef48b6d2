"""Stability matrix of the material point (tiers 0/1/2; :mod:`contfab.models.tiers`).

Validity range (declared by :mod:`contfab.params`, quoted by its errors): φ in (0°, 90°),
|ψ| <= φ, c in (0, 1), fabric admissible (0 <= B <= A, (π/6)A + (√3/4)B <= 1), λ > 0,
increments finite (a failed update returns status -1 and its inputs; the driver cuts).

The invariants every update is checked against (:func:`step_invariants`), with
C the regularization stiffness and Q the rotation by Δω:

* yield: R - sin φ(c) P <= 0 and P >= 0 (tiers 0/1, tension positive, P = -(σxx+σyy)/2);
  tier 2: |s + P α| - (sin φ(c) - w b_c) P <= 0, α = w (Bc, Bs)/A, s = ((σxx-σyy)/2, σxy);
* plastic dissipation per step D = σ_{n+1} · Δεp >= 0, Δεp = Δε - C⁻¹(σ_{n+1} - Qσ_nQᵀ)
  (Voigt, engineering shear: the work conjugate pair);
* c in (0, 1); fabric admissible (tier 2); every output finite; no status -1.

Each violation is measured relative to the magnitudes involved; the accuracy of a point is
the largest over its steps.
"""
from __future__ import annotations

import math

import numpy as np

from contfab import material_point as mp
from contfab.models import cone, tiers
from contfab.params import Params
from contfab.stability.core import Measured, Point
from contfab.tensors import isotropic_stiffness
from dem.conventions import admissibility_margin, fabric_polar
from dem.paths import parse_path

INVARIANT_TOL = 1e-9
"""Tolerance of the per-step invariants, relative to |σ| (|σ| |Δε| for the dissipation)."""


def params(tier: int, phi: float = 30.0, psi: float = 10.0, lam: float = 1e3, c0: float = 0.8,
           A0: float = 3.0 / math.pi, B0: float = 0.0, **tier2) -> Params:
    """A validated parameter set: tier 0 (φ, ψ), tier 1/2 around c* = 0.8 with φ* = φ; tier 2
    at the ``[tier2]`` defaults but for the fields given in ``tier2`` (by name)."""
    doc = {
        "tier": tier,
        "regularization": {"lambda": lam, "p_ref": 1.0, "nu": 0.0},
        "tier0": {"phi_deg": phi, "psi_deg": psi},
        "tier1": {"phi_star_deg": phi, "dphi_dc_deg": 100.0, "dpsi_dc_deg": 150.0,
                  "c_star": 0.8, "phi_min_deg": min(phi, 8.0), "phi_max_deg": max(phi, 60.0)},
        "initial": {"c0": c0, "A0": A0, "B0": B0},
    }
    if tier == 2:
        doc["tier2"] = dict(tier2)
    return Params.from_dict(doc)


def step_invariants(tier: int, prm: Params, stress_n, state_n, dstrain, dspin, res) -> dict:
    """Worst relative violation of each invariant of the module doc over a batch of updates."""
    k, g = prm.regularization.moduli()
    cinv = np.linalg.inv(isotropic_stiffness(k, g))
    rot = np.column_stack(_rotate(stress_n, dspin))
    deps_p = dstrain - (res.stress - rot) @ cinv.T
    dissipation = np.sum(res.stress * deps_p, axis=1)
    size = np.abs(res.stress).max(axis=1) + np.abs(stress_n).max(axis=1)
    # round-off of C⁻¹Δσ enters Δεp at eps·|σ|/G; the floor below covers it
    scale = size * (np.abs(dstrain).max(axis=1) + size / g) + 1e-300
    out = {"failed": int(np.sum(res.status == cone.STATUS_FAILED)),
           "finite": bool(np.all(np.isfinite(res.stress)) and np.all(np.isfinite(res.state))
                          and np.all(np.isfinite(res.tangent))),
           "dissipation": float(np.max(np.maximum(-dissipation, 0.0) / scale))}
    p = -0.5 * (res.stress[:, 0] + res.stress[:, 1])
    r = np.hypot(0.5 * (res.stress[:, 0] - res.stress[:, 1]), res.stress[:, 2])
    out["tension"] = float(np.max(np.maximum(-p, 0.0) / (size + 1e-300)))
    if tier == 0:
        sphi = math.sin(math.radians(prm.tier0.phi_deg))
        out["yield"] = float(np.max(np.maximum(r - sphi * p, 0.0) / (size + 1e-300)))
    elif tier == 1:
        a = prm.array(1)
        sphi = np.array([math.sin(cone.tier1_angles(c, a)[0]) for c in res.state[:, 1]])
        out["yield"] = float(np.max(np.maximum(r - sphi * p, 0.0) / (size + 1e-300)))
    elif tier == 2:
        a = prm.array(1)
        w = prm.tier2.fabric_weight
        m = np.array([math.sin(cone.tier1_angles(c, a)[0]) for c in res.state[:, 1]])
        m -= w * prm.tier2.b_ratio_crit
        ux = 0.5 * (res.stress[:, 0] - res.stress[:, 1]) + p * w * res.state[:, 3] / res.state[:, 2]
        uy = res.stress[:, 2] + p * w * res.state[:, 4] / res.state[:, 2]
        out["yield"] = float(np.max(np.maximum(np.hypot(ux, uy) - m * p, 0.0) / (size + 1e-300)))
    if tier >= 1:
        c = res.state[:, 1]
        out["c_range"] = float(np.max(np.maximum(np.maximum(-c, c - 1.0), 0.0)))
    if tier == 2:
        b, _ = fabric_polar(res.state[:, 3], res.state[:, 4])
        out["fabric"] = float(np.max(np.maximum(-admissibility_margin(res.state[:, 2], b), 0.0)))
        out["projected"] = int(np.sum(res.status == 3))
    return out


def _rotate(stress, angle):
    from contfab.tensors import rotate
    return rotate(stress[:, 0], stress[:, 1], stress[:, 2], angle)


def _judge(worst: dict, reference: str, extra: str = "") -> Measured:
    """A Measured from invariant violations: NaN if non-finite, inf if a point failed."""
    note = ", ".join(f"{k}={v:.2g}" if isinstance(v, float) else f"{k}={v}"
                     for k, v in worst.items()) + (f"; {extra}" if extra else "")
    if not worst["finite"]:
        return Measured(math.nan, INVARIANT_TOL, reference, note)
    if worst["failed"]:
        return Measured(math.inf, INVARIANT_TOL, reference, note)
    acc = max(v for key, v in worst.items() if isinstance(v, float))
    return Measured(acc, INVARIANT_TOL, reference, note)


def merge(a: dict | None, b: dict) -> dict:
    """Element-wise worst of two invariant dicts."""
    if a is None:
        return dict(b)
    out = {}
    for key, v in b.items():
        if key == "finite":
            out[key] = a[key] and v
        elif key in ("failed", "projected"):
            out[key] = a[key] + v
        else:
            out[key] = max(a[key], v)
    return out


def state_at(tier: int, prm: Params, n: int, c: float | None = None) -> np.ndarray:
    st = tiers.initial_state(tier, prm, n)
    if c is not None and tier >= 1:
        st[:, 1] = c
    return st


def cone_stresses(prm: Params, tier: int, state, rng, p_scale=1.0, inside=(0.5, 1.0)):
    """Stresses on or inside the cone at pressure ~p_scale, random directions: the deviator
    s = -P α + r e(direction), r = P m × uniform(inside), with the cone's radius m and axis α
    (tiers 0/1: m = sin φ, α = 0; tier 2: m = sin φ(c) - w b_c, α = w (Bc, Bs)/A)."""
    n = len(state)
    if tier == 0:
        radius = np.full(n, math.sin(math.radians(prm.tier0.phi_deg)))
    else:
        a = prm.array(1)
        radius = np.array([math.sin(cone.tier1_angles(c, a)[0]) for c in state[:, 1]])
    axis = np.zeros((n, 2))
    if tier == 2:
        w = prm.tier2.fabric_weight
        radius = radius - w * prm.tier2.b_ratio_crit
        axis = w * state[:, 3:5] / state[:, 2:3]
    p = p_scale * rng.uniform(0.5, 1.5, n)
    r = p * radius * rng.uniform(*inside, n)
    two = rng.uniform(0, 2 * np.pi, n)
    sx = -p * axis[:, 0] + r * np.cos(two)
    sy = -p * axis[:, 1] + r * np.sin(two)
    return np.column_stack([-p + sx, -p - sx, sy])


def random_walk(tier: int, prm: Params, chains: int, steps: int, seed: int = 0,
                sizes=(1e-7, 1e-3), progress=None) -> dict:
    """``chains`` points, each driven by ``steps`` random increments (log-uniform sizes,
    random directions, random spins of the same size), every step checked."""
    rng = np.random.default_rng(seed)
    state = state_at(tier, prm, chains)
    stress = cone_stresses(prm, tier, state, rng)
    out = tiers.allocate(tier, chains)
    worst = None
    lo, hi = np.log(sizes[0]), np.log(sizes[1])
    for k in range(steps):
        d = rng.standard_normal((chains, 3))
        size = np.exp(rng.uniform(lo, hi, chains))
        dstrain = d / np.linalg.norm(d, axis=1)[:, None] * size[:, None]
        dspin = rng.standard_normal(chains) * size
        res = tiers.update(tier, stress, state, dstrain, dspin, prm, out=out)
        worst = merge(worst, step_invariants(tier, prm, stress, state, dstrain, dspin, res))
        stress, state = res.stress.copy(), res.state.copy()
        if progress is not None and k % 10000 == 0:
            progress(k)
    return worst


# --------------------------------------------------------------------------- runners

def run_updates(tier: int, prm: Params, size: float, n: int = 400, seed: int = 1,
                p_scale: float = 1.0, spin: float | None = None, inside=(0.0, 1.0)) -> Measured:
    """One update of ``n`` points from stresses on/inside the cone, increments of ``size``."""
    rng = np.random.default_rng(seed)
    state = state_at(tier, prm, n)
    stress = cone_stresses(prm, tier, state, rng, p_scale, inside)
    d = rng.standard_normal((n, 3))
    dstrain = d / np.linalg.norm(d, axis=1)[:, None] * size
    dspin = rng.standard_normal(n) * (size if spin is None else spin)
    res = tiers.update(tier, stress, state, dstrain, dspin, prm)
    return _judge(step_invariants(tier, prm, stress, state, dstrain, dspin, res),
                  "yield, plastic dissipation >= 0, c and fabric admissible (per step)")


def run_apex(tier: int, beyond: bool) -> Measured:
    """σ_n = 0 (at the apex) or σ_n = +I (beyond it, tension) under dilating increments:
    closed form σ_{n+1} = 0, status apex."""
    prm = params(tier)
    n = 50
    rng = np.random.default_rng(3)
    stress = np.tile([1.0, 1.0, 0.0] if beyond else [0.0, 0.0, 0.0], (n, 1))
    state = state_at(tier, prm, n)
    dstrain = np.abs(rng.standard_normal((n, 3))) * 1e-3
    dstrain[:, 2] *= rng.choice([-1.0, 1.0], n)
    res = tiers.update(tier, stress, state, dstrain, np.zeros(n), prm)
    worst = step_invariants(tier, prm, stress, state, dstrain, np.zeros(n), res)
    m = _judge(worst, "closed form: sigma = 0 at the apex")
    err = float(np.abs(res.stress).max()) / (1.0 + prm.regularization.moduli()[0] * 1e-3)
    apex = int(np.sum(res.status == cone.STATUS_APEX))
    return Measured(max(m.accuracy, err), INVARIANT_TOL, m.reference,
                    f"max|sigma| = {err:.2g}, apex status {apex}/{n}; {m.note}")


def run_spin_only(tier: int, angle: float) -> Measured:
    """Δε = 0, Δω = angle from an anisotropic state: closed form σ' = QσQᵀ (and the fabric
    deviator turned by 2·angle); accuracy relative to |σ| (fabric: to A)."""
    prm = params(tier, B0=0.3)
    rng = np.random.default_rng(4)
    n = 20
    state = state_at(tier, prm, n)
    stress = cone_stresses(prm, tier, state, rng, inside=(0.0, 0.9))
    dspin = np.full(n, angle)
    res = tiers.update(tier, stress, state, np.zeros((n, 3)), dspin, prm)
    exact = np.column_stack(_rotate(stress, dspin))
    err = float(np.max(np.abs(res.stress - exact)) / np.abs(stress).max())
    if tier == 2:
        c2, s2 = np.cos(2 * angle), np.sin(2 * angle)
        bc = c2 * state[:, 3] - s2 * state[:, 4]
        bs = s2 * state[:, 3] + c2 * state[:, 4]
        err = max(err, float(np.max(np.abs(res.state[:, 3] - bc) + np.abs(res.state[:, 4] - bs))
                             / state[0, 2]))
    worst = step_invariants(tier, prm, stress, state, np.zeros((n, 3)), dspin, res)
    m = _judge(worst, "closed form: rigid rotation sigma' = Q sigma Q^T")
    return Measured(max(err, m.accuracy), 1e-12, m.reference, f"rotation error {err:.2g}; {m.note}")


def shear_path(gamma: float, back: float | None = None, output: float = 0.5):
    """Simple shear at constant σyy = -P0 to ``gamma``, then (optionally) back by ``back``."""
    stages = [{"name": "forward", "length": gamma, "output_every": output,
               "L": {"xx": 0.0, "xy": 1.0, "yx": 0.0}, "sigma": {"yy": -1.0}}]
    if back is not None:
        stages.append({"name": "reverse", "length": back, "output_every": output,
                       "L": {"xx": 0.0, "xy": -1.0, "yx": 0.0}, "sigma": {"yy": -1.0}})
    return parse_path({"name": "stability_shear", "stage": stages})


def run_path_check(tier: int, prm: Params, path, increment: float = 1e-2, state0=None,
                   steady_cone: bool = True) -> Measured:
    """A driven path: the stress target σyy = -P0 held, c in (0, 1), fabric admissible, and
    (tiers 0/1, ``steady_cone``) the end on the cone, R = sin φ(c) P (closed form of steady
    simple shear)."""
    res = mp.run_path(path, prm, tier, increment=increment, state0=state0)
    syy = res["syy"]
    err = float(np.max(np.abs(syy + 1.0)))
    notes = [f"|syy + 1| <= {err:.2g}"]
    if tier >= 1:
        c = res["c"]
        err = max(err, float(np.max(np.maximum(np.maximum(-c, c - 1), 0))))
        notes.append(f"c in [{c.min():.4f}, {c.max():.4f}]")
    if tier == 2:
        margin = admissibility_margin(res["A"], res["B"])
        err = max(err, float(np.max(np.maximum(-margin, 0))))
        notes.append(f"min fabric margin {margin.min():.3g}")
    tol = 1e-9
    if steady_cone and tier < 2:
        if tier == 0:
            sphi = math.sin(math.radians(prm.tier0.phi_deg))
        else:
            sphi = math.sin(cone.tier1_angles(res["c_p"][-1], prm.array(1))[0])
        cone_err = abs(res["R"][-1] - sphi * res["P"][-1]) / res["P"][-1]
        err = max(err, cone_err)
        notes.append(f"end R/P - sin(phi) = {cone_err:.2g}")
        tol = 1e-6                       # regularization: on the cone once plastic, to ~1/λ²
    if not all(np.all(np.isfinite(res[col])) for col in ("sxx", "syy", "sxy")):
        return Measured(math.nan, tol, "", "non-finite history")
    return Measured(err, tol, "stress target held; c, fabric admissible; steady state on the cone",
                    "; ".join(notes) + f"; {res.stats['increments']} increments")


def run_walk(tier: int, steps: int, chains: int = 10) -> Measured:
    prm = params(tier)
    worst = random_walk(tier, prm, chains, steps)
    return _judge(worst, "yield, plastic dissipation >= 0, c and fabric admissible (every step)",
                  f"{chains} chains x {steps} steps")


# --------------------------------------------------------------------------- the matrix

def points() -> list[Point]:
    """Every point of the material-point matrix (``full_only`` marks the long ones)."""
    pts: list[Point] = []

    # The supervised full run records a hang as FAIL (docs/stability.md).
    def add(axis, value, fn, budget=300.0, full=False):
        pts.append(Point("point", axis, str(value), fn, budget, full))

    for phi in (0.5, 1.0, 10.0, 30.0, 45.0, 60.0, 89.0):
        for tier in (0, 1):
            add(f"phi_deg (tier {tier})", phi,
                lambda phi=phi, tier=tier: run_updates(tier, params(tier, phi, 0.5 * phi), 1e-3),
                full=phi not in (0.5, 60.0))
    for phi in (0.0, 90.0):
        add("phi_deg (tier 0)", phi, lambda phi=phi: run_updates(0, params(0, phi, 0.0), 1e-3))
    for ratio in (-1.0, -0.5, 0.0, 0.5, 1.0, 1.2):
        add("psi/phi (tier 0, phi 30)", ratio,
            lambda ratio=ratio: run_updates(0, params(0, 30.0, 30.0 * ratio), 1e-3),
            full=ratio in (-0.5, 0.5))
    for tier in (0, 1, 2):
        add(f"apex (tier {tier})", "at", lambda tier=tier: run_apex(tier, False))
        add(f"apex (tier {tier})", "beyond", lambda tier=tier: run_apex(tier, True))
    shear = shear_path(1.0, output=0.25)
    add("B (tier 2)", 0.0, lambda: run_path_check(2, params(2, B0=0.0), shear, steady_cone=False),
        full=True)
    a_bound = 3.0 / math.pi
    b_bound = min(a_bound, (1.0 - math.pi / 6 * a_bound) / (math.sqrt(3) / 4))   # B = A binds
    add("B (tier 2)", f"bound {b_bound:.4f}",
        lambda: run_path_check(2, params(2, B0=b_bound), shear, steady_cone=False), full=True)
    add("B (tier 2)", f"beyond {b_bound + 1e-3:.4f}",
        lambda: run_path_check(2, params(2), shear, steady_cone=False,
                               state0={"Bc": b_bound + 1e-3, "A": a_bound}))
    for c0 in (0.05, 0.6, 0.95, 0.999, 1.0):
        add("c0 (tier 1)", c0, lambda c0=c0: run_path_check(1, params(1, c0=0.5), shear,
                                                            state0={"c": c0}, steady_cone=False),
            full=c0 in (0.6, 0.999))
    for size in (1e-12, 1e-9, 1e-6, 1e-3, 1e-1, 1.0):
        for tier in (0, 1, 2):
            add(f"increment (tier {tier})", f"{size:g}",
                lambda size=size, tier=tier: run_updates(tier, params(tier), size),
                full=size in (1e-9, 1e-6, 1.0), budget=300.0)
    for lam in (1e1, 1e8):
        add("lambda (tier 1)", f"{lam:g}",
            lambda lam=lam: run_updates(1, params(1, lam=lam), 1e-3))
    for angle in (1e-12, 0.1, math.pi, 3.0):
        for tier in (0, 1, 2):
            add(f"spin only (tier {tier})", f"{angle:g}",
                lambda angle=angle, tier=tier: run_spin_only(tier, angle),
                full=angle in (1e-12, math.pi), budget=300.0)
    for tier in (0, 1, 2):
        add(f"reversal after shear (tier {tier})", "gamma 5 then -1",
            lambda tier=tier: run_path_check(tier, params(tier), shear_path(5.0, 1.0),
                                             steady_cone=tier < 2), full=tier != 1, budget=300.0)
    for tier in (1, 2):
        add(f"random steps (tier {tier})", "1e4", lambda tier=tier: run_walk(tier, 1000),
            budget=300.0)
        add(f"random steps (tier {tier})", "1e6", lambda tier=tier: run_walk(tier, 100_000),
            budget=900, full=True)
    return pts

"""Least-squares fit of model parameters to DEM curves on the same loading paths.

The material point (:mod:`contfab.material_point`) runs each fitted path from the DEM's
mean initial state (packing fraction c0 and, for tier 2, the fabric A0, Bc0, Bs0; stress
-P0 I) and is sampled on the DEM curve's grid (:mod:`contfab.calibration.curves`). For every path and
fitted quantity q the residual vector holds

    (model - DEM mean) / scale_q / sqrt(n)     at the n grid points   (the whole curve)
    (model - DEM mean) / scale_q               of the residual-window means (steady state)

so each path weighs the same whatever its number of rows, and the steady values the
acceptance is stated on (residual R/P within 0.02, c within 0.005, A and B within 10%)
weigh as much as the whole curve. The scales are those tolerances: 0.02 for R/P, 0.005 for
c, 10 % of the DEM's residual A for A, 10 % of its residual B for Bc and Bs (θp enters
through (Bc, Bs): no angle wraps in the fit). A model run that fails (step cutting
exhausted) contributes a constant PENALTY per missing point.

:func:`fit` calls :func:`scipy.optimize.least_squares` (trust-region reflective) with
box bounds (:class:`FitParam`) that keep the model admissible — the same ranges the
parameter file validates, narrowed to physically sensible ones — and a forward-difference
Jacobian. **Uncertainty from the seed scatter**: from the optimum x*, one Gauss–Newton step
toward each seed's own curves, δx_k = -J⁺ r_k(x*), gives the parameters a single-seed
calibration would find (to first order); their standard deviation over the K seeds is the
single-seed scatter, and divided by sqrt(K) the standard error of the seed-mean fit.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from contfab import material_point as mp
from contfab.calibration.curves import DemCurve, history_of, sample
from contfab.params import ParamError, Params
from dem.paths import Path

PENALTY = 10.0
"""Residual (in units of the quantity's scale) of a grid point a failed model run missed."""
TOLERANCES = {"RP": 0.02, "c": 0.005}
FABRIC_REL = 0.1
TIER_QUANTITIES = {1: ("RP", "c"), 2: ("RP", "c", "A", "Bc", "Bs")}


@dataclass(frozen=True)
class FitParam:
    """A fitted parameter: section and field of :mod:`contfab.params`, and its bounds."""

    section: str
    key: str
    lo: float
    hi: float


TIER1 = (FitParam("tier1", "phi_star_deg", 8.0, 45.0),    # φ* >= the template's φ_min
         FitParam("tier1", "dphi_dc_deg", 0.0, 2000.0),
         FitParam("tier1", "dpsi_dc_deg", 0.0, 2000.0),
         FitParam("tier1", "c_star", 0.70, 0.90))
B_RATIO_CRIT = FitParam("tier2", "b_ratio_crit", 0.0, 0.27)
"""The critical anisotropy b_c = B/A: the relaxation law's target and, for either law, the
fabric part w b_c the cone's radius sin φ(c) - w b_c leaves to the forces. Its bound keeps
that radius positive down to tier 1's lower clamp φ_min = 8° of the calibration's template
(sin 8° > 0.5·0.27, at the fixed weight w = 1/2)."""
LAWS = {
    "balance": (FitParam("tier2", "kappa_a", 0.0, 100.0),
                FitParam("tier2", "k_c", 0.0, 200.0),
                FitParam("tier2", "k_o", 0.0, 100.0)),
    # z_crit <= 4 and B/A <= 0.27 keep the critical fabric inside the admissible set
    # (z/6 + (√3/4)(B/A) z/π <= 0.82)
    "relaxation": (FitParam("tier2", "z_crit", 1.5, 4.0),
                   B_RATIO_CRIT,
                   FitParam("tier2", "relax_rate", 0.0, 200.0)),
}
"""The fabric law's coefficients, fitted on the fabric alone (the cone reduced to tier 1's)."""
CONE = (FitParam("tier2", "dilatancy_fabric", 0.0, 3.0),)
"""The cone's own coefficient: the Rowe–Taylor slope k_d of the dilatancy (≈ 0.9–1.1 on the
DEM). The fabric weight w stays at its ``[tier2]`` value (1/2, the stress–force–fabric
relation's): in every steady state the fabric is the critical one, where w cancels from
the strength (w b_c + m(c) = sin φ(c)), so only transients could identify it."""


def tier2_spec(law: str) -> tuple[FitParam, ...]:
    """The parameters of tier 2's joint fit with ``law``: the cone's, the law's, and b_c
    (read by the cone's radius whichever the law)."""
    spec = CONE + LAWS[law]
    return spec if B_RATIO_CRIT in spec else spec + (B_RATIO_CRIT,)


def get_values(params: Params, spec: Sequence[FitParam]) -> np.ndarray:
    return np.array([getattr(params.sections[p.section], p.key) for p in spec], dtype=float)


def with_values(params: Params, spec: Sequence[FitParam], x) -> Params:
    """``params`` with the fitted fields set to ``x`` (validated)."""
    changes: dict[str, dict] = {}
    for p, v in zip(spec, x):
        changes.setdefault(p.section, {})[p.key] = float(v)
    for section, kw in changes.items():
        params = params.replace(section, **kw)
    return params


@dataclass(frozen=True)
class Target:
    """A DEM curve to fit (or to check): path, curve, and the model's start state."""

    name: str
    path: Path
    curve: DemCurve
    origin: Mapping = field(default_factory=dict)     # run spec, probe index, role

    def state0(self, tier: int) -> dict | None:
        """The DEM's mean start state in the variables of ``tier`` (tier 0 carries none)."""
        st = self.curve.start
        if tier == 0:
            return None
        return {"c": st["c"]} if tier == 1 else {k: st[k] for k in ("c", "A", "Bc", "Bs")}


def run_model(params: Params, tier: int, target: Target, increment: float = mp.DEFAULT_INCREMENT):
    """(sample on the target's grid, PointResult or None) of the material point on the
    target's path from the DEM's mean start state; a failed run gives its partial result."""
    try:
        res = mp.run_path(target.path, params, tier, increment=increment,
                          state0=target.state0(tier))
    except mp.IntegrationError as exc:
        res = exc.partial
    if res is None:
        return sample({"stage": np.zeros(1), "tau": np.zeros(1)}, target.curve.grid), None
    return sample(history_of(res), target.curve.grid), res


def scales(targets: Sequence[Target]) -> dict[str, float]:
    """Residual scales (module doc), the fabric ones from the DEM's residual A and B."""
    out = dict(TOLERANCES)
    a, b = [], []
    for t in targets:
        w = t.curve.grid.residual_window()
        a.append(np.nanmean(t.curve.mean["A"][w]))
        b.append(np.nanmean(t.curve.mean["B"][w]))
    if a:
        out["A"] = FABRIC_REL * float(np.nanmean(a))
        out["Bc"] = out["Bs"] = FABRIC_REL * float(np.nanmean(b))
    return out


def residuals(samples: Sequence[Mapping[str, np.ndarray]], refs: Sequence[Mapping[str, np.ndarray]],
              targets: Sequence[Target], quantities: Sequence[str],
              scale: Mapping[str, float]) -> np.ndarray:
    """The residual vector (module doc) of model samples against reference samples (the
    DEM mean, or one seed's curves)."""
    parts = []
    for model, ref, t in zip(samples, refs, targets):
        window = t.curve.grid.residual_window()
        for q in quantities:
            dem = ref[q]
            ok = np.isfinite(dem)
            d = (model[q][ok] - dem[ok]) / scale[q]
            d[~np.isfinite(d)] = PENALTY
            parts.append(d / math.sqrt(max(ok.sum(), 1)))
            # Window means as in contfab.calibration.curves.errors: over the points each curve has
            # (a model run ends at the path's end, a DEM grid can pass it by a time step:
            # one missing end point must not turn the steady-state term into PENALTY).
            w = window & ok
            mw = w & np.isfinite(model[q])
            r = ((np.mean(model[q][mw]) - np.mean(dem[w])) / scale[q] if mw.any()
                 else (PENALTY if w.any() else 0.0))
            parts.append(np.array([r]))
    return np.concatenate(parts)


@dataclass
class FitResult:
    """Outcome of :func:`fit`: the fitted parameters, their values, uncertainty, and cost."""

    params: Params
    spec: tuple[FitParam, ...]
    x: np.ndarray
    scatter: np.ndarray           # single-seed standard deviation (NaN with one seed)
    stderr: np.ndarray            # scatter / sqrt(K)
    cost: float                   # ½ Σ r² at the optimum
    evaluations: int
    message: str

    def table(self) -> list[dict]:
        return [{"section": p.section, "key": p.key, "value": float(v), "scatter": float(s),
                 "stderr": float(e), "lo": p.lo, "hi": p.hi,
                 "at_bound": bool(v <= p.lo + 1e-9 * (p.hi - p.lo) or v >= p.hi - 1e-9 * (p.hi - p.lo))}
                for p, v, s, e in zip(self.spec, self.x, self.scatter, self.stderr)]


def fit(params: Params, tier: int, spec: Sequence[FitParam], targets: Sequence[Target],
        quantities: Sequence[str] | None = None, scale: Mapping[str, float] | None = None,
        max_nfev: int = 60, progress: bool = True, desc: str = "fit") -> FitResult:
    """Least squares of ``spec`` (starting from their values in ``params``) on ``targets``."""
    from scipy.optimize import least_squares

    spec = tuple(spec)
    quantities = tuple(quantities or TIER_QUANTITIES[tier])
    scale = dict(scale or scales(targets))
    lo = np.array([p.lo for p in spec])
    hi = np.array([p.hi for p in spec])
    x0 = np.clip(get_values(params, spec), lo, hi)
    means = [t.curve.mean for t in targets]
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(desc=desc, unit="eval", mininterval=1.0)
    last = {}

    def model_samples(x):
        key = tuple(x.tolist())
        if key not in last:
            last.clear()
            try:
                p = with_values(params, spec, x)
            except ParamError:
                last[key] = None
            else:
                last[key] = [run_model(p, tier, t)[0] for t in targets]
        return last[key]

    def fun(x):
        samples = model_samples(x)
        if bar is not None:
            bar.update(1)
        if samples is None:
            n = len(residuals(model_samples(x0), means, targets, quantities, scale))
            return np.full(n, PENALTY)
        r = residuals(samples, means, targets, quantities, scale)
        if bar is not None:
            bar.set_postfix(cost=f"{0.5 * float(r @ r):.4g}")
        return r

    try:
        sol = least_squares(fun, x0, bounds=(lo, hi), x_scale=(hi - lo) / 10.0,
                            diff_step=1e-4, max_nfev=max_nfev, method="trf")
    finally:
        if bar is not None:
            bar.close()
    x = sol.x
    fitted = with_values(params, spec, x)
    samples = model_samples(x)
    jac = np.asarray(sol.jac)
    pinv = np.linalg.pinv(jac, rcond=1e-8)
    k = len(targets[0].curve.seeds) if targets else 0
    if k > 1:
        steps = []
        for j in range(k):
            refs = [t.curve.seeds[j] for t in targets]
            steps.append(-pinv @ residuals(samples, refs, targets, quantities, scale))
        scatter = np.std(np.array(steps), axis=0, ddof=1)
        stderr = scatter / math.sqrt(k)
    else:
        scatter = stderr = np.full(len(spec), math.nan)
    return FitResult(fitted, spec, x, scatter, stderr, float(sol.cost), int(sol.nfev),
                     str(sol.message))

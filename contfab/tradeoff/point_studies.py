"""Continuum studies on one material point: increment size and λ.

Every point drives the default parameters (tier 2, whose cone follows the fabric, so the
fabric feeds back on the stress) along a standard path
(:func:`contfab.material_point.run_path`). The measured curves are R/P, ε_v and the
fabric (Bc, Bs) at the output rows; the errors against a reference curve x* are

    R/P: max_τ |R/P - R/P*|,   ε_v: max_τ |ε_v - ε_v*|,   fabric: max_τ |(Bc, Bs) - (Bc, Bs)*|_∞ / A*

(dimensionless). The references:

* ``point_increment``: Richardson extrapolation of the two finest runs, the driver being
  first order in Δτ: x* = 2 x(h) - x(2h).
* ``point_lambda``: the rigid-plastic limit from the two stiffest runs, the regularization
  error being ∝ 1/λ: x* = (λ2 x2 - λ1 x1) / (λ2 - λ1).

Cost: microseconds of CPU time per increment (per material-point step); the table's times
are the whole path.
"""
from __future__ import annotations

import functools

import numpy as np

from contfab import material_point as mp
from contfab.params import default_params, default_params_digest
from contfab.tradeoff.study import Clock, Study

QUANTITIES = ("RP", "eps_v", "fabric")


def run_point(study: Study, point: dict) -> dict:
    """One material-point run of the study's path with the point's knobs."""
    params = default_params().with_tier(2)
    if "lam" in point:
        params = params.replace("regularization", lam=point["lam"])
    increment = point.get("increment", mp.DEFAULT_INCREMENT)
    _compiled(study.settings["path"])
    with Clock() as clock:
        res = mp.run_path(study.settings["path"], params, increment=increment)
    values = {k: res[k].tolist() for k in ("tau", "RP", "eps_v", "A", "Bc", "Bs")}
    return {"values": values, "wall_s": clock.wall, "cpu_s": clock.cpu,
            "cost": 1e6 * clock.cpu / max(int(res.stats["increments"]), 1)}


@functools.cache
def _compiled(path: str) -> None:
    """Compile (or load) the tier-2 kernels once per process, outside the timed runs."""
    mp.run_path(path, default_params().with_tier(2), increment=0.5)


def curve_errors(values: dict, reference: dict) -> dict:
    """The errors of the module doc of one run's curves against reference curves."""
    tau = np.asarray(reference["tau"])

    def on_ref(k):
        return np.interp(tau, values["tau"], values[k])
    fabric = max(np.max(np.abs(on_ref(k) - np.asarray(reference[k]))) for k in ("Bc", "Bs"))
    return {"RP": float(np.max(np.abs(on_ref("RP") - reference["RP"]))),
            "eps_v": float(np.max(np.abs(on_ref("eps_v") - reference["eps_v"]))),
            "fabric": float(fabric / np.min(reference["A"]))}


def _combine(a: dict, b: dict, wa: float, wb: float) -> dict:
    """wa·a + wb·b for every curve (``tau`` from a; both runs share the output rows)."""
    out = {"tau": a["tau"]}
    for k in ("RP", "eps_v", "A", "Bc", "Bs"):
        out[k] = (wa * np.asarray(a[k]) + wb * np.interp(a["tau"], b["tau"], b[k])).tolist()
    return out


def _rows(study: Study, points, results, reference) -> list[dict]:
    return [{"knobs": {k: p[k] for k in study.knobs}, **{k: r[k] for k in ("wall_s", "cpu_s", "cost")},
             "errors": curve_errors(r["values"], reference)}
            for p, r in zip(points, results)]


def _order(errors: list[float], knob: list[float]) -> float:
    """Least-squares slope of log error against log knob (the observed order)."""
    e, k = np.log(errors), np.log(knob)
    return float(np.polyfit(k, e, 1)[0])


def evaluate_increment(study, points, results):
    h = [p["increment"] for p in points]
    i1 = int(np.argmin(h))
    i2 = h.index(2 * h[i1])
    reference = _combine(results[i1]["values"], results[i2]["values"], 2.0, -1.0)
    rows = _rows(study, points, results, reference)
    notes = {"reference": f"Richardson extrapolation of increments {h[i1]:g} and {h[i2]:g}",
             "path": study.settings["path"],
             "observed order of the R/P error in the increment":
                 _order([r["errors"]["RP"] for r in rows], h)}
    return rows, notes


def evaluate_lambda(study, points, results):
    lam = [p["lam"] for p in points]
    i2, i1 = np.argsort(lam)[-1], np.argsort(lam)[-2]
    l1, l2 = lam[i1], lam[i2]
    reference = _combine(results[i2]["values"], results[i1]["values"],
                         l2 / (l2 - l1), -l1 / (l2 - l1))
    rows = _rows(study, points, results, reference)
    notes = {"reference": f"1/lambda extrapolation of lambda = {l1:g} and {l2:g}",
             "path": study.settings["path"],
             "observed order of the R/P error in 1/lambda":
                 -_order([r["errors"]["RP"] for r in rows], lam)}
    return rows, notes


def increment_study(fast: bool) -> Study:
    h = [4e-3, 2e-3, 1e-3, 5e-4] if fast else [3.2e-2 / 2**k for k in range(10)]
    return Study(
        name="point_increment", knobs=("increment",),
        description="material-point increment size Δτ_max (tier 2, simple shear with reversal)",
        points=tuple({"increment": x} for x in h), run_point=run_point,
        evaluate=evaluate_increment, default={"increment": mp.DEFAULT_INCREMENT},
        quantities=QUANTITIES, cost_unit="CPU µs per increment",
        error_meaning="max deviation from the Richardson-extrapolated curve",
        settings={"path": "simple_shear_reversal", "parameters": default_params_digest()})


def lambda_study(fast: bool) -> Study:
    lams = [1e2, 3e2, 1e3, 3e3] if fast else [1e2, 3e2, 1e3, 3e3, 1e4, 3e4, 1e5]
    return Study(
        name="point_lambda", knobs=("lam",),
        description="regularization stiffness λ (E_reg = λ p_ref) against the rigid-plastic limit "
                    "(tier 2, simple shear with reversal)",
        points=tuple({"lam": x, "increment": 4e-3 if fast else mp.DEFAULT_INCREMENT}
                     for x in lams),
        run_point=run_point, evaluate=evaluate_lambda,
        default={"lam": default_params().regularization.lam},
        quantities=QUANTITIES, cost_unit="CPU µs per increment",
        error_meaning="max deviation from the λ→∞ extrapolated curve",
        settings={"path": "simple_shear_reversal", "parameters": default_params_digest()})

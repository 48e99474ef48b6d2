"""Model tiers 0/1/2 against the DEM on a loading path: error per quantity against cost.

The DEM reference is the seed mean of ``seeds`` dense samples (μ_prep = 0, μ = 0.5) of N
discs run on the path (:func:`contfab.calibration.curves.dem_curve`); it is computed once per process
and path (not timed: it is the reference, not a knob). Each point runs the material point
of one tier with the shipped parameters from the DEM's mean start state
(:func:`contfab.calibration.fitting.run_model`) and compares on the DEM's grid
(:func:`contfab.calibration.curves.errors`): the RMS difference of R/P, ε_v and c over the path, and for
a multi-stage path (the reversal) the RMS of R/P over the first 0.1 strain after the
reversal (``RP_transient``). Cost: CPU µs per material-point increment.

Two studies, tiers 0, 1 and 2 each: ``tier_biaxial`` (monotonic: biaxial compression) and
``tier_reversal`` (simple shear with reversal; tier 2 joined it on 2026-12-01, once its
local solve from the DEM's anisotropic start fabric was fixed: it had not finished this
path in 200 s of CPU). Their DEM reference is small (``--fast``: N = 100, one seed); the
bounds :mod:`contfab.selection.auto_tier` chooses from come from the calibration campaign
instead (N = 1000, 3 seeds).
"""
from __future__ import annotations

import functools

import numpy as np

from contfab import material_point as mp
from contfab.calibration.curves import dem_curve, errors
from contfab.calibration.fitting import Target, run_model
from contfab.params import default_params, default_params_digest
from contfab.tradeoff.study import Clock, Study, dem_code_digest
from dem.job import Settings, prepare_sample
from dem.paths import load_path
from dem.rve import PathRunner

QUANTITIES = ("RP", "eps_v", "c", "RP_transient")


@functools.cache
def dem_histories(path_name: str, n: int, seeds: int, inertial: float, kappa: float) -> tuple:
    """Histories ({column: array}) of ``seeds`` dense DEM samples on ``path_name``."""
    out = []
    for seed in range(seeds):
        settings = Settings(n=n, seed=seed, kappa=kappa, inertial=inertial, mu=0.5, mu_prep=0.0)
        state, dyn, _ = prepare_sample(settings, progress=False)
        runner = PathRunner(load_path(path_name), dyn, dyn.gdot_ref)
        rows = runner.run(state, runner.start(state)).rows
        out.append({k: np.array([r[k] for r in rows], dtype=float) for k in rows[0]})
    return tuple(out)


def run_point(study: Study, point: dict) -> dict:
    """The material point of ``point["tier"]`` against the DEM curve (module doc)."""
    s = study.settings
    path = load_path(s["path"])
    with Clock() as dem_clock:
        curve = dem_curve(path, dem_histories(s["path"], s["n"], s["seeds"], s["inertial"],
                                              s["kappa"]))
    tier = point["tier"]
    params = default_params().with_tier(tier)
    target = Target(path.name, path, curve)
    run_model(params, tier, target, increment=0.5)          # compile/load outside the clock
    with Clock() as clock:
        sample, res = run_model(params, tier, target, increment=s["increment"])
    e = errors(curve, sample, quantities=("RP", "eps_v", "c"))
    values = {q: e[q]["rms"] for q in ("RP", "eps_v", "c")}
    values["RP_transient"] = e["RP"]["rms_transient"]
    values["RP_residual_rel"] = e["RP"]["residual_rel"]
    values["dem_cpu_s_first_call"] = dem_clock.cpu
    increments = int(res.stats["increments"]) if res is not None else 1
    return {"values": values, "wall_s": clock.wall, "cpu_s": clock.cpu,
            "cost": 1e6 * clock.cpu / max(increments, 1)}


def evaluate(study, points, results):
    rows = [{"knobs": {"tier": p["tier"]}, **{k: r[k] for k in ("wall_s", "cpu_s", "cost")},
             "errors": {q: float(r["values"][q]) for q in study.quantities}}
            for p, r in zip(points, results)]
    s = study.settings
    notes = {"DEM reference": f"{s['seeds']} dense samples, N = {s['n']}, I = {s['inertial']:g}, "
                              f"κ = {s['kappa']:g}, path {s['path']}",
             "parameters": f"the shipped contfab/data/default_params.toml (sha1 {s['parameters']})",
             "relative R/P error of the steady (residual) window per tier":
                 [r["values"]["RP_residual_rel"] for r in results]}
    return rows, notes


def _study(name: str, path: str, fast: bool, reversal: bool) -> Study:
    n, seeds = (100, 1) if fast else (400, 2)
    quantities = QUANTITIES if reversal else QUANTITIES[:3]
    return Study(
        name=name, knobs=("tier",),
        description=f"model tier against the DEM on {path}",
        points=tuple({"tier": t} for t in (0, 1, 2)), run_point=run_point, evaluate=evaluate,
        default={"tier": default_params().tier}, quantities=quantities,
        cost_unit="CPU µs per material-point increment",
        error_meaning="RMS difference from the DEM seed mean over the path",
        settings={"path": path, "n": n, "seeds": seeds, "inertial": 1e-2, "kappa": 1e3,
                  "increment": 4e-3 if fast else mp.DEFAULT_INCREMENT,
                  "parameters": default_params_digest(), "dem_code": dem_code_digest()})


def biaxial_study(fast: bool) -> Study:
    return _study("tier_biaxial", "biaxial", fast, reversal=False)


def reversal_study(fast: bool) -> Study:
    return _study("tier_reversal", "simple_shear_reversal", fast, reversal=True)

"""DEM studies: cell size N, inertial number I, stiffness number κ (docs/theory.md §1, §11).

Every point prepares a loose sample (μ_prep = μ = 0.5, so it reaches the critical state
without a peak) of N discs (diameters uniform in [0.8, 1.2]) at P0 = 1 and runs biaxial
compression along y at σxx = -1 to ``strain``, rows every 0.005. The steady state is the
window ε_yy <= -``steady_from``; the measured quantities are R/P, c, z, A and B on its rows.
Cost: CPU time of the test (preparation excluded, reported separately) per unit strain.

* ``dem_size``: the scatter of each quantity against N, over several seeds. ``scatter``
  = the standard deviation of all steady rows of all seeds about their grand mean, relative
  to the grand mean (B: relative to the mean A), i.e. the size of the fluctuations a single
  run shows; the seed-to-seed standard deviation of the window means is reported too. The
  exponent β of scatter ∝ N^-β is fitted by least squares in log-log with its standard
  error (expected 1/2 for intensive averages of N weakly correlated contributions; Madadi
  et al. 2004 report ∝ 1/M for its fabric-trace averages).
* ``dem_inertial`` and ``dem_stiffness``: the steady means of R/P, c and z against the
  quasi-static limit I → 0 (fit x = x0 + b I) and the rigid limit κ → ∞ (fit x = x∞ + b/κ)
  over the :data:`LIMIT_FIT_POINTS` settings nearest the limit; error = |x - x_lim| / |x_lim|. The seed-to-seed scatter of the means is
  a floor under these errors (stated in the notes).
"""
from __future__ import annotations

import functools

import numpy as np

from contfab.tradeoff.study import Clock, Study, dem_code_digest
from dem.job import Settings, prepare_sample
from dem.paths import parse_path
from dem.rve import PathRunner

QUANTITIES = ("RP", "c", "z", "A", "B")
DEFAULTS = Settings()
LIMIT_FIT_POINTS = 3
"""The limits I → 0 and κ → ∞ are fitted on the three settings nearest them."""


def _path(strain: float):
    return parse_path({"name": "biaxial_steady", "stage": [
        {"length": strain, "output_every": 0.005, "L": {"yy": -1.0, "xy": 0.0, "yx": 0.0},
         "sigma": {"xx": -1.0}}]})


# A preparation stops as soon as it relaxes, so a larger limit changes no relaxed sample;
# a point of the full studies needs more than dem.job's default 2e6 steps (after 2e6 its
# unbalanced force ratio is 1.1e-4, against the threshold 1e-4).
PREP_MAX_STEPS = 6_000_000


def run_point(study: Study, point: dict) -> dict:
    """One DEM sample and one biaxial test (module doc)."""
    s = study.settings
    _compiled()
    settings = Settings(n=point["n"], seed=point["seed"], kappa=point["kappa"],
                        inertial=point["inertial"], mu=0.5, mu_prep=0.5,
                        prep_max_steps=PREP_MAX_STEPS)
    with Clock() as prep:
        state, dyn, _ = prepare_sample(settings, progress=False)
    runner = PathRunner(_path(s["strain"]), dyn, dyn.gdot_ref)
    with Clock() as clock:
        rows = runner.run(state, runner.start(state)).rows
    steady = [r for r in rows if -r["eps_yy"] >= s["steady_from"] - 1e-9]
    values = {q: [float(r[q]) for r in steady] for q in QUANTITIES}
    values["prepare_cpu_s"] = prep.cpu
    return {"values": values, "wall_s": clock.wall, "cpu_s": clock.cpu,
            "cost": clock.cpu / s["strain"]}


@functools.cache
def _compiled() -> None:
    """Compile (or load) the DEM kernels once per process, outside the timed runs."""
    state, dyn, _ = prepare_sample(Settings(n=16, kappa=1e2, inertial=1e-1), progress=False)
    runner = PathRunner(_path(0.005), dyn, dyn.gdot_ref)
    runner.run(state, runner.start(state))


def _groups(points, results, knob):
    """{knob value: [results of its seeds]} in increasing knob order."""
    out: dict = {}
    for p, r in zip(points, results):
        out.setdefault(p[knob], []).append(r)
    return dict(sorted(out.items()))


def _mean_times(rs) -> dict:
    """Wall, CPU time and cost of a setting: the means over its seeds."""
    return {k: float(np.mean([r[k] for r in rs])) for k in ("wall_s", "cpu_s", "cost")}


def _scale(q: str, vals: dict) -> float:
    return float(np.mean(vals["A" if q == "B" else q]))


def fit_power(x, y) -> tuple[float, float]:
    """(β, standard error) of y ∝ x^-β by least squares in log-log."""
    if len(x) < 3:
        return float(-np.polyfit(np.log(x), np.log(y), 1)[0]), float("nan")
    coef, cov = np.polyfit(np.log(x), np.log(y), 1, cov=True)
    return float(-coef[0]), float(np.sqrt(cov[0, 0]))


def evaluate_size(study, points, results):
    rows, seed_scatter = [], {q: [] for q in QUANTITIES}
    groups = _groups(points, results, "n")
    for n, rs in groups.items():
        pooled = {q: np.concatenate([r["values"][q] for r in rs]) for q in QUANTITIES}
        errors = {q: float(np.std(pooled[q]) / abs(_scale(q, pooled))) for q in QUANTITIES}
        for q in QUANTITIES:
            means = [np.mean(r["values"][q]) for r in rs]
            seed_scatter[q].append(float(np.std(means, ddof=1)) / abs(_scale(q, pooled)))
        rows.append({"knobs": {"n": n, "seeds": len(rs)},
                     **_mean_times(rs), "errors": errors})
    ns = list(groups)
    notes = {"settings": {k: study.settings[k] for k in ("inertial", "kappa", "strain",
                                                        "steady_from")}}
    for q in QUANTITIES:
        beta, se = fit_power(ns, [r["errors"][q] for r in rows])
        notes[f"beta (row scatter of {q} ∝ N^-beta)"] = f"{beta:.3f} ± {se:.3f}"
    for q in QUANTITIES:
        beta, se = fit_power(ns, seed_scatter[q])
        notes[f"beta (seed-to-seed scatter of the window mean of {q})"] = f"{beta:.3f} ± {se:.3f}"
    notes["cost exponent (s per strain ∝ N^a)"] = -fit_power(ns, [r["cost"] for r in rows])[0]
    return rows, notes


def _evaluate_limit(study, points, results, knob, basis):
    """Rows against the limit of a linear fit x = x_lim + b · basis(knob) over all seeds."""
    groups = _groups(points, results, knob)
    keys = list(groups)
    means = {q: [float(np.mean([np.mean(r["values"][q]) for r in rs])) for rs in groups.values()]
             for q in ("RP", "c", "z")}
    spread = {q: float(np.mean([np.std([np.mean(r["values"][q]) for r in rs], ddof=1)
                                for rs in groups.values() if len(rs) > 1] or [np.nan]))
              for q in means}
    near = np.argsort(basis(np.array(keys)))[:LIMIT_FIT_POINTS]    # the settings nearest the limit
    limits = {q: float(np.polyfit(basis(np.array(keys))[near], np.array(means[q])[near], 1)[1])
              for q in means}
    rows = []
    for i, (k, rs) in enumerate(groups.items()):
        rows.append({"knobs": {knob: k, "seeds": len(rs)},
                     **_mean_times(rs),
                     "errors": {q: abs(means[q][i] - limits[q]) / abs(limits[q]) for q in means}})
    notes = {"limits": limits, "means": means,
             "seed-to-seed std of the steady means (averaged over the settings)": spread,
             "cost exponent (s per strain ∝ knob^a)":
                 -fit_power(keys, [r["cost"] for r in rows])[0]}
    return rows, notes


def evaluate_inertial(study, points, results):
    rows, notes = _evaluate_limit(study, points, results, "inertial", lambda i: i)
    notes["limit"] = "quasi-static, from x = x0 + b I"
    return rows, notes


def evaluate_stiffness(study, points, results):
    rows, notes = _evaluate_limit(study, points, results, "kappa", lambda k: 1.0 / k)
    notes["limit"] = "rigid, from x = x_inf + b / kappa"
    return rows, notes


def _points(values: dict, seeds: int):
    keys = list(values)
    grid = np.array(np.meshgrid(*values.values(), indexing="ij")).reshape(len(keys), -1).T
    return tuple({**{k: (int(v) if k == "n" else float(v)) for k, v in zip(keys, g)},
                  "seed": s} for g in grid for s in range(seeds))


def size_study(fast: bool) -> Study:
    ns = [64, 128, 512] if fast else [250, 500, 1000, 2000, 4000]
    seeds = 3
    strain, steady = (0.12, 0.06) if fast else (0.2, 0.1)
    return Study(
        name="dem_size", knobs=("n", "seeds"),
        description="DEM cell size N: scatter of steady-state R/P, c, z, A, B (biaxial, loose)",
        points=_points({"n": ns, "inertial": [1e-2], "kappa": [1e3]}, seeds),
        run_point=run_point, evaluate=evaluate_size, default={"n": DEFAULTS.n},
        quantities=QUANTITIES, cost_unit="CPU s per unit strain",
        error_meaning="steady-state scatter (std / mean; B: std / mean A)",
        settings={"strain": strain, "steady_from": steady, "inertial": 1e-2, "kappa": 1e3,
                  "dem_code": dem_code_digest()})


def inertial_study(fast: bool) -> Study:
    inertial = [1e-1, 3e-2, 1e-2] if fast else [1e-2, 3e-3, 1e-3, 3e-4, 1e-4]
    n, seeds = (100, 2) if fast else (250, 2)
    strain, steady = (0.12, 0.06) if fast else (0.15, 0.075)
    return Study(
        name="dem_inertial", knobs=("inertial", "seeds"),
        description=f"DEM inertial number I against the quasi-static limit (N = {n}, κ = 1e3)",
        points=_points({"n": [n], "inertial": inertial, "kappa": [1e3]}, seeds),
        run_point=run_point, evaluate=evaluate_inertial, default={"inertial": DEFAULTS.inertial},
        quantities=("RP", "c", "z"), cost_unit="CPU s per unit strain",
        error_meaning="|steady mean - extrapolated I→0 limit| / limit",
        settings={"strain": strain, "steady_from": steady, "n": n, "kappa": 1e3,
                  "dem_code": dem_code_digest()})


def stiffness_study(fast: bool) -> Study:
    kappa = [1e2, 1e3, 1e4] if fast else [1e2, 1e3, 1e4, 1e5, 1e6]
    n, seeds = (100, 2) if fast else (250, 2)
    strain, steady = (0.12, 0.06) if fast else (0.15, 0.075)
    return Study(
        name="dem_stiffness", knobs=("kappa", "seeds"),
        description=f"DEM stiffness number κ = kn/P0 against the rigid limit (N = {n}, I = 1e-2)",
        points=_points({"n": [n], "inertial": [1e-2], "kappa": kappa}, seeds),
        run_point=run_point, evaluate=evaluate_stiffness, default={"kappa": DEFAULTS.kappa},
        quantities=("RP", "c", "z"), cost_unit="CPU s per unit strain",
        error_meaning="|steady mean - extrapolated κ→∞ limit| / limit",
        settings={"strain": strain, "steady_from": steady, "n": n, "inertial": 1e-2,
                  "dem_code": dem_code_digest()})

"""Where the fabric matters: the model tiers against the DEM through transients.

The DEM runs of a loading path (``contfab dem run`` directories, several seeds of one
density) give a seed-mean curve (:func:`contfab.calibration.curves.dem_curve`); each
model tier runs the same path from the DEM's mean start state (c and, for tier 2, the
fabric) and is sampled on the same grid. The figures, computed by the same functions on
the DEM's mean curve and on each model's (s: the reference strain since the start of a
stage, γ in simple shear):

* after every change of loading (each stage k >= 1): the RMS error of R/P over
  0 < s <= TRANSIENT_RMS; the minimum of R/P over s <= EARLY and where it falls; the
  strain s_90 past that minimum where R/P is back to 90 % of the stage's steady value
  (its mean over the last RESIDUAL_FRACTION of the stage); the largest compaction
  Δc = max(c - c(0)) over s <= EARLY;
* the build-up from isotropy (stage 0 of a path that starts isotropic): the RMS errors of
  R/P and of B over s <= BUILD_UP;
* the rotation of the principal axes (stage 1 of ``axes_rotation``): the RMS error of θp
  and the mean non-coaxiality θσ - θD (θσ, θD the compressive principal directions of the
  stress and of the strain increment between grid points);
* the steady state: the residual R/P, c, A and B errors
  (:func:`contfab.calibration.curves.errors`), and the RMS error of R/P over the whole path.

**The** ``tier = "auto"`` **table** (``--auto-table FILE``, :func:`table_from_transients`):
per loading class and model tier, the bound is the largest R/P error of that tier over the
class's paths — "monotonic": the RMS over the whole path of the biaxial tests (dense and
loose); "reversal": the RMS over the first TRANSIENT_RMS after each change of loading of the
reversals and changes of direction (the held-out ``shear_cycles`` included) — and the cost
per increment is :func:`contfab.selection.auto_tier.measure_costs`'s.

``contfab transients RUN_DIR... --out DIR`` writes ``transients.csv`` / ``.md`` (one row
per path, density and figure, a column per source) and ``transients.json``, an overlay
figure per path (R/P, ε_v, c, A, B, θp against the grid's abscissa), and ``reference/``:
the DEM's seed-mean curves (:func:`contfab.calibration.curves.curve_table`) with their start
states and the DEM's figures in ``index.json`` (:func:`read_reference` reads them back; the
tests keep a copy).

**Fit on transients** (``--fit``, :func:`fit_transients`): the fabric parameters of tier 2
(:data:`FIT_NAMES`, tier 1's fixed) minimize

    J = Σ_paths Σ_figures ((model − DEM) / scale)²

over the figures above: the R/P error after each change (scale 0.03) and over the build-up
(R/P and B, 0.03), the minimum of R/P after a change (0.03), s_90 (30 % of the DEM's), the
compaction Δc after a change (0.003), and the residual R/P (0.02), c (0.005), A (0.05) and
B (0.025):
the scales are the acceptance bounds, so transients and steady states weigh alike. The
minimizer is Nelder–Mead (scipy) on the logarithms of the parameters, clipped to
:data:`FIT_BOUNDS` (the figures are not smooth in the parameters: s_90 and the minimum
move by grid steps, which a gradient method does not tolerate).
"""
from __future__ import annotations

import json
import math
from collections import defaultdict
from pathlib import Path as FsPath
from typing import Mapping, Sequence

import numpy as np

from contfab.calibration.curves import (DemCurve, curve_table, dem_curve, errors, read_curve,
                                       read_history)
from contfab.calibration.fitting import Target, run_model
from contfab.calibration.report import markdown_table, overlay_plot
from contfab.params import Params
from dem.fileio import atomic_path, write_csv, write_json
from dem.paths import load_path

TRANSIENT_RMS = 0.2
"""Strain after a change of loading over which the R/P error is measured."""
EARLY = 0.3
"""Strain after a change of loading where the minimum of R/P and the compaction are sought."""
BUILD_UP = 0.3
"""Strain of the build-up from isotropy."""
STEADY_FRACTION = 0.3
"""The steady part of a stage: its last fraction of strain."""
ISOTROPIC_RATIO = 0.1
"""A path starts from isotropy when the DEM's mean start B/A is below this (a prepared
sample keeps a few per cent of anisotropy)."""


def group_runs(run_dirs: Sequence[str | FsPath]) -> dict[tuple[str, str], list[FsPath]]:
    """Run directories grouped by (path name, density); density "dense" where the
    preparation was frictionless (μ_prep = 0), otherwise "loose"."""
    groups: dict[tuple[str, str], list[FsPath]] = defaultdict(list)
    for d in map(FsPath, run_dirs):
        info = json.loads((d / "history.json").read_text())
        density = "dense" if info["settings"].get("mu_prep") == 0.0 else "loose"
        groups[(info["path"]["name"], density)].append(d)
    return dict(groups)


def _angle(x):
    return np.mod(x + 0.5 * np.pi, np.pi) - 0.5 * np.pi


def _rms(x) -> float:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x * x))) if x.size else math.nan


def _nanmax(x) -> float:
    x = np.asarray(x, dtype=float)
    return float(np.max(x[np.isfinite(x)])) if np.any(np.isfinite(x)) else math.nan


def _first(mask) -> int | None:
    idx = np.flatnonzero(mask)
    return int(idx[0]) if idx.size else None


def change_figures(stage: np.ndarray, s: np.ndarray, d: Mapping[str, np.ndarray], k: int) -> dict:
    """R/P minimum, s at the minimum, s_90 and the largest compaction after the change of
    loading that starts stage ``k`` (module doc); s = 0 is the previous stage's last point."""
    prev = np.flatnonzero(stage == k - 1)
    rows = np.r_[prev[-1], np.flatnonzero(stage == k)]
    sk = np.r_[0.0, s[rows[1:]]]
    rp = d["RP"][rows]
    c = d["c"][rows]
    steady = sk >= (1.0 - STEADY_FRACTION) * sk.max()
    rp_ss = float(np.nanmean(rp[steady]))
    early = (sk > 0.0) & (sk <= EARLY)
    if not np.any(early & np.isfinite(rp)):
        return {"RP_min": math.nan, "s_min": math.nan, "s_90": math.nan, "dc_max": math.nan,
                "RP_steady": rp_ss}
    i_min = int(np.nanargmin(np.where(early, rp, np.inf)))
    back = _first((sk > sk[i_min]) & (rp >= 0.9 * rp_ss))
    finite = np.flatnonzero(np.isfinite(c))
    dc = c - (c[finite[0]] if finite.size else math.nan)
    return {"RP_min": float(rp[i_min]), "s_min": float(sk[i_min]),
            "s_90": float(sk[back]) if back is not None else math.nan,
            "dc_max": _nanmax(dc[(sk >= 0.0) & (sk <= EARLY)]), "RP_steady": rp_ss}


def noncoaxiality(stage: np.ndarray, d: Mapping[str, np.ndarray], k: int) -> float:
    """Mean θσ - θD over stage ``k`` in degrees (θD from the strain increments between grid
    points, engineering shear ``eps_xy`` halved as in :mod:`dem.history`)."""
    rows = np.flatnonzero(stage == k)
    rows = np.r_[rows[0] - 1, rows] if rows[0] > 0 else rows
    dxx = np.diff(d["eps_xx"][rows])
    dyy = np.diff(d["eps_yy"][rows])
    dxy = np.diff(d["eps_xy"][rows])
    theta_d = 0.5 * np.arctan2(-dxy, -0.5 * (dxx - dyy))
    sxx, syy, sxy = (d[q][rows[1:]] for q in ("sxx", "syy", "sxy"))
    theta_s = 0.5 * np.arctan2(-sxy, -0.5 * (sxx - syy))
    return float(np.degrees(np.nanmean(_angle(theta_s - theta_d))))


def figures(path_name: str, curve: DemCurve, model: Mapping[str, np.ndarray] | None) -> dict:
    """The module doc's figures of the DEM's mean curve (``model`` None) or of a model
    sampled on its grid (then with its errors against the DEM)."""
    g = curve.grid
    d = curve.mean if model is None else model
    out: dict[str, float] = {}
    changes = range(1, int(g.stage.max()) + 1) if path_name != "axes_rotation" else ()
    for k in changes:
        for name, v in change_figures(g.stage, g.s, d, k).items():
            out[f"change{k}_{name}"] = v
        if model is not None:
            win = (g.stage == k) & (g.s > 0.0) & (g.s <= TRANSIENT_RMS)
            out[f"change{k}_rms_RP"] = _rms(model["RP"][win] - curve.mean["RP"][win])
    if path_name == "axes_rotation" and g.stage.max() >= 1:
        if all(q in d for q in ("eps_xx", "eps_yy", "eps_xy", "sxx", "syy", "sxy")):
            # (a stored reference curve keeps no stresses and strains: its figure is in its index)
            out["rotation_noncoaxiality_deg"] = noncoaxiality(g.stage, d, 1)
        if model is not None:
            win = g.stage == 1
            out["rotation_rms_theta_p_deg"] = float(np.degrees(_rms(
                _angle(model["theta_p"][win] - curve.mean["theta_p"][win]))))
    if (model is not None and math.hypot(curve.start["Bc"], curve.start["Bs"])
            < ISOTROPIC_RATIO * curve.start["A"]):
        win = (g.stage == 0) & (g.s <= BUILD_UP)
        out["buildup_rms_RP"] = _rms(model["RP"][win] - curve.mean["RP"][win])
        out["buildup_rms_B"] = _rms(model["B"][win] - curve.mean["B"][win])
    if model is not None:
        out["path_rms_RP"] = _rms(model["RP"] - curve.mean["RP"])
        errs = errors(curve, model)
        for q in ("RP", "c", "A", "B"):
            if q in errs:
                out[f"residual_{q}"] = errs[q]["residual_error"]
    return out


FIT_NAMES = ("relax_rate", "fabric_speed", "fabric_dilation", "dilatancy_fabric",
             "b_ratio_crit", "fabric_weight", "z_crit")
"""The tier-2 parameters fitted on transients (``[tier2]`` names)."""
FIT_BOUNDS = {"relax_rate": (1.0, 300.0), "fabric_speed": (0.5, 100.0),
              "fabric_dilation": (1e-3, 100.0), "dilatancy_fabric": (1e-3, 4.0),
              "b_ratio_crit": (0.15, 0.3), "fabric_weight": (0.3, 0.6), "z_crit": (2.0, 4.0)}
"""Box of the fit (the upper ones keep m(c) > 0 with phi_min_deg >= 11)."""
FIT_SCALES = {"change_rms_RP": 0.03, "buildup_rms_RP": 0.03, "buildup_rms_B": 0.03,
              "RP_min": 0.03, "s_90": 0.3, "dc_max": 0.003, "residual_RP": 0.02,
              "residual_c": 0.005, "residual_A": 0.05, "residual_B": 0.025}
"""Scale of each figure in the objective (module doc; s_90's is relative to the DEM's)."""


def objective_terms(rows: Sequence[Mapping], source: str = "tier 2") -> list[tuple[str, float]]:
    """(label, scaled error) of every figure of ``rows`` that enters the fit's objective
    (module doc); a figure the model did not reach counts 10."""
    out = []
    for r in rows:
        fig, model, dem = r["figure"], r[source], r["DEM"]
        label = f"{r['path']} {r['density']} {fig}"
        kind = fig.split("_", 1)[1] if fig.startswith("change") else fig
        if fig.startswith("change") and kind == "rms_RP":
            e = model / FIT_SCALES["change_rms_RP"]
        elif r["path"] == "biaxial" and fig.startswith("change"):
            continue                      # biaxial has no change of loading
        elif kind in ("RP_min", "dc_max"):
            e = (model - dem) / FIT_SCALES[kind]
        elif kind == "s_90":
            e = (model - dem) / (FIT_SCALES[kind] * dem)
        elif kind in FIT_SCALES:
            e = model / FIT_SCALES[kind]
        else:
            continue
        out.append((label, float(e) if math.isfinite(e) else 10.0))
    return out


def fit_transients(params: Params, run_dirs: Sequence[str | FsPath], max_nfev: int = 150,
                   progress=None) -> tuple[Params, dict]:
    """Tier 2's :data:`FIT_NAMES` fitted on the runs' figures (module doc), from ``params``.
    Returns the fitted parameters and a record {start, fitted, objective, evaluations}."""
    from scipy.optimize import minimize

    lo = np.array([FIT_BOUNDS[n][0] for n in FIT_NAMES])
    hi = np.array([FIT_BOUNDS[n][1] for n in FIT_NAMES])
    start = {n: getattr(params.tier2, n) for n in FIT_NAMES}
    x0 = np.log(np.clip([min(start[n], hi[k]) for k, n in enumerate(FIT_NAMES)], lo, hi))
    curves = {k: v[0] for k, v in run_curves(run_dirs).items()}
    count = [0]

    def candidate(u) -> Params:
        return params.replace("tier2", **dict(zip(FIT_NAMES, map(float, np.clip(np.exp(u), lo, hi)))))

    def objective(u) -> float:
        rows = figure_rows(candidate(u), curves, (2,))[0]
        j = float(sum(e * e for _, e in objective_terms(rows)))
        count[0] += 1
        if progress is not None:
            progress(count[0], j)
        return j

    res = minimize(objective, x0, method="Nelder-Mead",
                   options={"maxfev": max_nfev, "xatol": 1e-3, "fatol": 1e-3})
    fitted = candidate(res.x)
    return fitted, {"start": start, "fitted": {n: getattr(fitted.tier2, n) for n in FIT_NAMES},
                    "objective": float(res.fun), "evaluations": count[0],
                    "runs": [str(d) for d in run_dirs]}


def run_curves(run_dirs: Sequence[str | FsPath]) -> dict[tuple[str, str], tuple[DemCurve, list]]:
    """{(path name, density): (the DEM's seed-mean curve, its run directories)}."""
    out = {}
    for (path_name, density), dirs in sorted(group_runs(run_dirs).items()):
        out[(path_name, density)] = (dem_curve(load_path(path_name),
                                               [read_history(d / "history.csv") for d in dirs]), dirs)
    return out


def figure_rows(params: Params, curves: Mapping[tuple[str, str], DemCurve],
                tiers: Sequence[int] = (1, 2), progress=None):
    """(rows, samples): rows {path, density, figure, DEM, tier t...} of every curve (the DEM
    column is empty for error figures), and each model's samples {name: {tier t: sample}}.
    ``progress(label)`` is called before each model run."""
    sources = ("DEM",) + tuple(f"tier {t}" for t in tiers)
    rows: list[dict] = []
    samples: dict[str, dict] = {}
    for (path_name, density), curve in curves.items():
        name = f"{path_name}_{density}"
        target = Target(name, load_path(path_name), curve)
        figs = {"DEM": figures(path_name, curve, None)}
        samples[name] = {}
        for t in tiers:
            if progress is not None:
                progress(f"{name}, tier {t}")
            samples[name][f"tier {t}"] = run_model(params.with_tier(t), t, target)[0]
            figs[f"tier {t}"] = figures(path_name, curve, samples[name][f"tier {t}"])
        for fig in dict.fromkeys(n for f in figs.values() for n in f):
            rows.append({"path": path_name, "density": density, "figure": fig,
                         **{src: figs[src].get(fig, math.nan) for src in sources}})
    return rows, samples


def evaluate(params: Params, run_dirs: Sequence[str | FsPath], tiers: Sequence[int] = (1, 2),
             out: str | FsPath | None = None, progress=None) -> list[dict]:
    """:func:`figure_rows` of the runs' curves; with ``out``, the tables, the JSON, the
    overlays and the reference curves (``reference/``, :func:`read_reference`) are written
    there."""
    curves = run_curves(run_dirs)
    rows, samples = figure_rows(params, {k: v[0] for k, v in curves.items()}, tiers, progress)
    if out is None:
        return rows
    out = FsPath(out)
    reference, plots = {}, {}
    for (path_name, density), (curve, dirs) in curves.items():
        name = f"{path_name}_{density}"
        columns, table = curve_table(curve)
        write_csv(out / "reference" / f"{name}.csv", columns, table)
        reference[name] = {"path": path_name, "density": density, "runs": [str(d) for d in dirs],
                           "start": curve.start, "file": f"{name}.csv",
                           "dem": figures(path_name, curve, None)}
        plots[name] = overlay_plot(curve, samples[name], out / f"{name}.png",
                                   f"{path_name}, {density}: DEM mean of {len(dirs)} seeds vs "
                                   f"the model tiers")
    columns = ("path", "density", "figure", "DEM") + tuple(f"tier {t}" for t in tiers)
    write_csv(out / "transients.csv", columns, [[r[c] for c in columns] for r in rows])
    with atomic_path(out / "transients.md") as tmp:
        tmp.write_text(markdown_table(rows, columns))
    write_json(out / "reference" / "index.json", {"curves": reference})
    write_json(out / "transients.json", {"params": params.source,
                                         "runs": [str(d) for d in run_dirs], "rows": rows,
                                         "plots": {k: str(v) for k, v in plots.items()}})
    return rows


AUTO_CLASSES = {"monotonic": ("biaxial",),
                "reversal": ("simple_shear_reversal", "direction_change", "shear_cycles")}
"""The paths whose errors bound each loading class of the ``tier = "auto"`` table."""


def table_from_transients(rows: Sequence[Mapping], costs: Mapping[tuple[str, str], float],
                          table: str | FsPath) -> FsPath:
    """The ``tier = "auto"`` table (module doc) from :func:`figure_rows`' rows of tiers 0-2
    and the costs {(loading, model): µs} of :func:`contfab.selection.auto_tier.measure_costs`."""
    from contfab.selection.auto_tier import MODELS

    out = []
    for loading, paths in AUTO_CLASSES.items():
        for model, (tier, params_file) in MODELS.items():
            values = [r[f"tier {tier}"] for r in rows if r["path"] in paths and (
                r["figure"] == "path_rms_RP" if loading == "monotonic"
                else r["figure"].startswith("change") and r["figure"].endswith("_rms_RP"))]
            if not values or not all(math.isfinite(v) for v in values):
                raise ValueError(f"no finite {loading} error of {model} in the rows "
                                 f"(paths {', '.join(paths)})")
            out.append([loading, model, tier, params_file, max(values), costs[(loading, model)]])
    return write_csv(table, ("loading", "model", "tier", "params_file", "error_RP", "cost_us"), out)


def read_reference(folder: str | FsPath) -> dict[str, tuple[str, DemCurve, dict]]:
    """{name: (path name, DEM curve, the DEM's figures)} of a ``reference/`` folder written
    by :func:`evaluate`."""
    folder = FsPath(folder)
    index = json.loads((folder / "index.json").read_text())["curves"]
    return {name: (e["path"], read_curve(folder / e["file"], e["start"]), e["dem"])
            for name, e in index.items()}


def reference_rows(params: Params, folder: str | FsPath, tiers: Sequence[int] = (1, 2)) -> list[dict]:
    """:func:`figure_rows` of the stored reference curves of ``folder`` (their DEM figures
    from the mean curves, as :func:`evaluate` computes them)."""
    index = json.loads((FsPath(folder) / "index.json").read_text())["curves"]
    curves = {(e["path"], e["density"]): read_curve(FsPath(folder) / e["file"], e["start"])
              for e in index.values()}
    return figure_rows(params, curves, tiers)[0]


def run_transients(run_dirs: Sequence[str | FsPath], out: str | FsPath,
                   params_file: str | None = None, fit: bool = False, max_nfev: int = 150,
                   command: str = "", auto_table: str | None = None) -> dict[str, FsPath]:
    """``contfab transients``: with ``fit``, fit tier 2 on the runs and write
    ``OUT/params.toml`` (its ``[provenance]`` records the command, the runs and the fit);
    then the figures of the module doc for tiers 1 and 2 into OUT. Returns the files."""
    from tqdm import tqdm

    from contfab.params import default_params, load_params
    from contfab.toml_writer import dumps
    from dem.provenance import code_versions

    if not run_dirs:
        raise ValueError("no DEM run directories given")
    missing = [str(d) for d in run_dirs if not (FsPath(d) / "history.json").is_file()]
    if missing:
        raise FileNotFoundError(f"not a finished 'contfab dem run' directory (no history.json): "
                                f"{', '.join(missing)}")
    if max_nfev < 1:
        raise ValueError(f"max_nfev = {max_nfev} out of range; accepted >= 1")
    params = default_params() if params_file is None else load_params(params_file)
    out = FsPath(out)
    written: dict[str, FsPath] = {}
    if fit:
        with tqdm(total=max_nfev, desc="fit on transients", unit="eval") as bar:
            def step(k, j):
                bar.update(1)
                bar.set_postfix_str(f"J = {j:.3g}")
            params, record = fit_transients(params, run_dirs, max_nfev, progress=step)
        doc = params.to_dict()
        doc["provenance"] = {"command": command,
                             "base_params": str(params_file) if params_file else "shipped defaults",
                             "fit_on_transients": record, "versions": code_versions()}
        with atomic_path(out / "params.toml") as tmp:
            tmp.write_text(dumps(doc, "contfab model parameters: tier 2's fabric fitted on DEM "
                                      "transients (contfab transients --fit)"))
        written["params"] = out / "params.toml"
    tiers = (0, 1, 2) if auto_table else (1, 2)
    with tqdm(desc="model runs", unit="run") as bar:
        rows = evaluate(params, run_dirs, tiers=tiers, out=out, progress=lambda label: bar.update(1))
    if auto_table:
        from contfab.selection.auto_tier import measure_costs

        written["auto_table"] = table_from_transients(rows, measure_costs(), auto_table)
    for name in ("transients.csv", "transients.md", "transients.json"):
        written[name] = out / name
    written["plots"] = out / "*.png"
    return written

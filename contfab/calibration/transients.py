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
  (:func:`contfab.calibration.curves.errors`).

``contfab transients RUN_DIR... --out DIR`` writes ``transients.csv`` / ``.md`` (one row
per path, density, figure and source) and ``transients.json``, and an overlay figure per
path (R/P, c, B against the grid's abscissa).
"""
from __future__ import annotations

import json
import math
from collections import defaultdict
from pathlib import Path as FsPath
from typing import Mapping, Sequence

import numpy as np

from contfab.calibration.curves import DemCurve, dem_curve, errors, read_history
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
ISOTROPIC_B = 0.02
"""A path starts isotropic when the DEM's mean start B is below this (1/rad)."""


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
        out["rotation_noncoaxiality_deg"] = noncoaxiality(g.stage, d, 1)
        if model is not None:
            win = g.stage == 1
            out["rotation_rms_theta_p_deg"] = float(np.degrees(_rms(
                _angle(model["theta_p"][win] - curve.mean["theta_p"][win]))))
    if model is not None and math.hypot(curve.start["Bc"], curve.start["Bs"]) < ISOTROPIC_B:
        win = (g.stage == 0) & (g.s <= BUILD_UP)
        out["buildup_rms_RP"] = _rms(model["RP"][win] - curve.mean["RP"][win])
        out["buildup_rms_B"] = _rms(model["B"][win] - curve.mean["B"][win])
    if model is not None:
        errs = errors(curve, model)
        for q in ("RP", "c", "A", "B"):
            if q in errs:
                out[f"residual_{q}"] = errs[q]["residual_error"]
    return out


def evaluate(params: Params, run_dirs: Sequence[str | FsPath], tiers: Sequence[int] = (1, 2),
             out: str | FsPath | None = None, progress=None) -> list[dict]:
    """Rows {path, density, seeds, figure, DEM, tier t...} for every path and density of
    the runs (module doc; the DEM column is empty for error figures); with ``out``, the
    tables, the JSON and the overlays are written there. ``progress(label)`` is called
    before each model run."""
    sources = ("DEM",) + tuple(f"tier {t}" for t in tiers)
    rows: list[dict] = []
    plots = {}
    for (path_name, density), dirs in sorted(group_runs(run_dirs).items()):
        path = load_path(path_name)
        curve = dem_curve(path, [read_history(d / "history.csv") for d in dirs])
        target = Target(f"{path_name}_{density}", path, curve)
        samples = {}
        figs = {"DEM": figures(path_name, curve, None)}
        for t in tiers:
            if progress is not None:
                progress(f"{target.name}, tier {t}")
            samples[f"tier {t}"] = run_model(params.with_tier(t), t, target)[0]
            figs[f"tier {t}"] = figures(path_name, curve, samples[f"tier {t}"])
        names = list(dict.fromkeys(n for f in figs.values() for n in f))
        for name in names:
            rows.append({"path": path_name, "density": density, "seeds": len(dirs),
                         "figure": name, **{src: figs[src].get(name, math.nan) for src in sources}})
        if out is not None:
            plots[target.name] = overlay_plot(curve, samples, FsPath(out) / f"{target.name}.png",
                                              f"{path_name}, {density}: DEM mean of {len(dirs)} "
                                              f"seeds vs the model tiers")
    if out is not None:
        out = FsPath(out)
        columns = ("path", "density", "seeds", "figure") + sources
        write_csv(out / "transients.csv", columns, [[r[c] for c in columns] for r in rows])
        with atomic_path(out / "transients.md") as tmp:
            tmp.write_text(markdown_table(rows, columns))
        write_json(out / "transients.json", {"params": params.source,
                                             "runs": [str(d) for d in run_dirs], "rows": rows,
                                             "plots": {k: str(v) for k, v in plots.items()}})
    return rows

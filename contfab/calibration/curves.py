"""DEM and model curves on the same loading path, sampled at the same strains, and their errors.

A history (DEM ``history.csv`` or a material-point :class:`~contfab.material_point.PointResult`)
is a table of :data:`dem.history.HISTORY_COLUMNS` rows. Within a stage both drivers apply
the same prescribed velocity-gradient components, so the natural abscissa is the stage
index k and the reference strain since the stage start, ``s = τ - τ_k`` (τ_k: τ of the
last row of stage k-1, 0 for the first stage). A :class:`Grid` lists (k, s) points:
every output interval of each stage, up to where *every* DEM seed reached (a stage ended by
an ``until`` crossing stops at slightly different s per seed).

:func:`sample` interpolates a history onto a grid, linearly in s within each stage (the
previous stage's last row anchors s = 0), NaN where the history does not reach. The fabric
is interpolated as (A, Bc, Bs); B and θp are derived from the interpolated (Bc, Bs).

:class:`DemCurve` is the seed statistics on a grid: the mean and the standard deviation
over seeds of every quantity (θp from the mean (Bc, Bs), since the angle wraps).

Errors (:func:`errors`), per quantity: the RMS difference over the grid, and the
**residual** difference — window means over the last ``RESIDUAL_FRACTION`` of the last
stage (the steady, critical-state part of the standard paths) — with the DEM's seed
scatter of that window mean; for multi-stage paths also the RMS over the first
``TRANSIENT_LENGTH`` of the last stage (the transient after a reversal or a change of
direction). θp differences are wrapped to (-90°, 90°] and reported in degrees.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path as FsPath
from typing import Mapping, Sequence

import numpy as np

from dem.conventions import fabric_polar
from dem.paths import Path

QUANTITIES = ("RP", "eps_v", "c", "A", "B", "theta_p")
"""Quantities compared and plotted (DESIGN: R/P, ε_v, c, A, B, θp)."""
SAMPLED = ("RP", "eps_v", "c", "A", "Bc", "Bs", "sxx", "syy", "sxy", "eps_xx", "eps_yy", "eps_xy")
"""Columns interpolated onto a grid (B and θp derive from Bc, Bs)."""
FABRIC = ("A", "B", "theta_p")
RESIDUAL_FRACTION = 0.3
TRANSIENT_LENGTH = 0.1


def read_history(file: str | FsPath) -> dict[str, np.ndarray]:
    """A history CSV as {column: float array} (empty cells -> NaN)."""
    with open(file, newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        raise ValueError(f"{file}: no rows")
    return {k: np.array([float(r[k]) if r[k] not in ("", None) else math.nan for r in rows])
            for k in rows[0]}


def history_of(result) -> dict[str, np.ndarray]:
    """A material-point result as the same {column: array} table."""
    return {k: np.asarray(v, dtype=float) for k, v in result.history.items()}


def stage_abscissa(h: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(stage, s) of every row (module doc)."""
    stage = np.asarray(h["stage"]).astype(int)
    tau = np.asarray(h["tau"], dtype=float)
    s = np.empty_like(tau)
    start = tau[0]
    for i in range(len(tau)):
        if i > 0 and stage[i] != stage[i - 1]:
            start = tau[i - 1]
        s[i] = tau[i] - start
    return stage, s


@dataclass(frozen=True)
class Grid:
    """(stage, s) sample points of one path; ``x`` is a continuous abscissa for plots
    (s plus the grid's end of every earlier stage)."""

    stage: np.ndarray
    s: np.ndarray
    x: np.ndarray

    def __len__(self) -> int:
        return len(self.s)

    def last_stage(self) -> np.ndarray:
        return self.stage == self.stage.max()

    def residual_window(self) -> np.ndarray:
        last = self.last_stage()
        end = self.s[last].max()
        return last & (self.s >= (1.0 - RESIDUAL_FRACTION) * end)

    def transient_window(self) -> np.ndarray:
        last = self.last_stage()
        if self.stage.max() == 0:
            return np.zeros(len(self), bool)
        return last & (self.s > 0.0) & (self.s <= TRANSIENT_LENGTH)


def make_grid(path: Path, histories: Sequence[Mapping[str, np.ndarray]]) -> Grid:
    """Every output interval of each stage of ``path``, up to the common reach of
    ``histories`` in that stage."""
    stages, ss, xs = [], [], []
    offset = 0.0
    for k, st in enumerate(path.stages):
        reach = []
        for h in histories:
            stage, s = stage_abscissa(h)
            if not np.any(stage == k):
                reach.append(-1.0)
            else:
                reach.append(s[stage == k].max())
        end = min(reach)
        if end <= 0.0:
            break
        step = st.output_interval
        n = int(math.floor(end / step * (1 + 1e-9)))
        s = step * np.arange(0 if k == 0 else 1, n + 1)
        if end - (s[-1] if len(s) else 0.0) > 1e-9 * step:
            s = np.append(s, end)
        stages.append(np.full(len(s), k))
        ss.append(s)
        xs.append(s + offset)
        offset += end
    return Grid(np.concatenate(stages), np.concatenate(ss), np.concatenate(xs))


def sample(h: Mapping[str, np.ndarray], grid: Grid) -> dict[str, np.ndarray]:
    """The history interpolated onto ``grid`` (module doc); NaN where it does not reach."""
    stage, s = stage_abscissa(h)
    out = {q: np.full(len(grid), math.nan) for q in SAMPLED}
    for k in np.unique(grid.stage):
        rows = np.flatnonzero(stage == k)
        if len(rows) == 0:
            continue
        if k > 0 and rows[0] > 0:
            rows = np.concatenate([[rows[0] - 1], rows])
        sk = s[rows].copy()
        if k > 0:
            sk[0] = 0.0
        at = grid.stage == k
        reach = (grid.s[at] >= sk[0] - 1e-12) & (grid.s[at] <= sk[-1] * (1 + 1e-9) + 1e-12)
        for q in SAMPLED:
            if q not in h:
                continue
            v = np.interp(grid.s[at], sk, np.asarray(h[q], dtype=float)[rows])
            v[~reach] = math.nan
            out[q][at] = v
    return _derive(out)


def _derive(d: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    b, theta = fabric_polar(d["Bc"], d["Bs"])
    d["B"] = np.asarray(b, dtype=float)
    d["theta_p"] = np.asarray(theta, dtype=float)
    return d


@dataclass(frozen=True)
class DemCurve:
    """Seed statistics of one path on a grid: ``mean`` and ``std`` per quantity, ``seeds``
    the per-seed samples, ``start`` the mean initial state (c, A, Bc, Bs)."""

    grid: Grid
    mean: Mapping[str, np.ndarray]
    std: Mapping[str, np.ndarray]
    seeds: tuple[Mapping[str, np.ndarray], ...]
    start: Mapping[str, float]


def dem_curve(path: Path, histories: Sequence[Mapping[str, np.ndarray]]) -> DemCurve:
    """Seed mean and scatter of DEM histories of ``path`` (module doc)."""
    grid = make_grid(path, histories)
    seeds = tuple(sample(h, grid) for h in histories)
    mean = {q: np.mean([d[q] for d in seeds], axis=0) for q in SAMPLED + ("B",)}
    std = {q: np.std([d[q] for d in seeds], axis=0) for q in SAMPLED + ("B",)}
    b_vec, theta = fabric_polar(mean["Bc"], mean["Bs"])
    mean["theta_p"] = np.asarray(theta, dtype=float)
    spread = np.degrees(np.std([_wrap(d["theta_p"] - mean["theta_p"]) for d in seeds], axis=0))
    std["theta_p"] = np.radians(spread)
    start = {q: float(np.mean([h[q][0] for h in histories])) for q in ("c", "A", "Bc", "Bs")}
    return DemCurve(grid, mean, std, seeds, start)


CURVE_MEANS = ("RP", "eps_v", "c", "A", "Bc", "Bs", "B", "theta_p")
CURVE_SDS = ("RP", "eps_v", "c", "A", "B", "theta_p")
CURVE_COLUMNS = (("stage", "s", "x") + tuple(f"{q}_mean" for q in CURVE_MEANS)
                 + tuple(f"{q}_sd" for q in CURVE_SDS))
"""Columns of a stored DEM curve (θp in radians)."""


def curve_table(curve: DemCurve, max_rows: int | None = None) -> tuple[tuple[str, ...], list[list]]:
    """(columns, rows) of a DEM curve for :func:`dem.fileio.write_csv`; with ``max_rows``
    every k-th grid point is kept, plus the last point of every stage."""
    g = curve.grid
    keep = np.arange(len(g))
    if max_rows is not None and len(g) > max_rows:
        k = int(math.ceil(len(g) / max_rows))
        ends = np.flatnonzero(np.append(g.stage[1:] != g.stage[:-1], True))
        keep = np.union1d(keep[::k], ends)
    rows = [[int(g.stage[i]), float(g.s[i]), float(g.x[i])]
            + [float(curve.mean[q][i]) for q in CURVE_MEANS]
            + [float(curve.std[q][i]) for q in CURVE_SDS] for i in keep]
    return CURVE_COLUMNS, rows


def read_curve(file: str | FsPath, start: Mapping[str, float]) -> DemCurve:
    """A stored DEM curve (:func:`curve_table`) with its start state; no per-seed data."""
    t = read_history(file)
    grid = Grid(t["stage"].astype(int), t["s"], t["x"])
    mean = {q: t[f"{q}_mean"] for q in CURVE_MEANS}
    std = {q: t[f"{q}_sd"] for q in CURVE_SDS}
    return DemCurve(grid, mean, std, (), dict(start))


def _wrap(dtheta):
    """An angle difference of directions mod π, wrapped to (-π/2, π/2]."""
    return -((-np.asarray(dtheta) + 0.5 * np.pi) % np.pi - 0.5 * np.pi)


def difference(q: str, model: np.ndarray, dem: np.ndarray) -> np.ndarray:
    """model - dem (θp: wrapped, in degrees)."""
    if q == "theta_p":
        return np.degrees(_wrap(model - dem))
    return model - dem


def _window_mean(v: np.ndarray, window: np.ndarray) -> float:
    w = v[window]
    w = w[np.isfinite(w)]
    return float(w.mean()) if len(w) else math.nan


def _window_angle(d: Mapping[str, np.ndarray], window: np.ndarray) -> float:
    """θp (degrees) of the window mean of (Bc, Bs)."""
    return math.degrees(0.5 * math.atan2(_window_mean(d["Bs"], window),
                                         _window_mean(d["Bc"], window)))


def errors(curve: DemCurve, model: Mapping[str, np.ndarray], quantities=QUANTITIES) -> dict:
    """{quantity: {rms, residual_dem, residual_model, residual_error, residual_rel,
    dem_scatter, rms_transient}} of a model sample against a DEM curve (module doc).
    θp entries are in degrees; ``residual_rel`` = |residual_error| / |residual_dem|."""
    g = curve.grid
    res, tr = g.residual_window(), g.transient_window()
    out = {}
    for q in quantities:
        if q not in model or np.all(~np.isfinite(model[q])):
            continue
        d = difference(q, model[q], curve.mean[q])
        ok = np.isfinite(d)
        rms = float(np.sqrt(np.mean(d[ok] ** 2))) if ok.any() else math.nan
        if q == "theta_p":           # directions: from the window means of (Bc, Bs)
            dem_res = _window_angle(curve.mean, res)
            mod_res = _window_angle(model, res)
            err = float(np.degrees(_wrap(np.radians(mod_res - dem_res))))
            per_seed = [float(np.degrees(_wrap(np.radians(_window_angle(s, res) - dem_res))))
                        for s in curve.seeds]
        else:
            dem_res = _window_mean(curve.mean[q], res)
            mod_res = _window_mean(model[q], res)
            err = mod_res - dem_res
            per_seed = [_window_mean(s[q], res) for s in curve.seeds]
        tr_ok = tr & ok
        out[q] = {"rms": rms, "residual_dem": dem_res, "residual_model": mod_res,
                  "residual_error": err,
                  "residual_rel": abs(err) / abs(dem_res) if dem_res else math.nan,
                  "dem_scatter": float(np.std(per_seed)) if len(per_seed) > 1 else math.nan,
                  "rms_transient": (float(np.sqrt(np.mean(d[tr_ok] ** 2))) if tr_ok.any()
                                    else math.nan)}
    return out

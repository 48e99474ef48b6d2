"""Curves on the same strains: stage-wise sampling, seed statistics, error metrics."""
import math

import numpy as np
import pytest

from contfab.calibration.curves import (curve_table, dem_curve, errors, make_grid, read_curve, sample,
                            stage_abscissa)
from dem.fileio import write_csv
from dem.paths import parse_path

TWO_STAGES = parse_path({"name": "two", "stage": [
    {"length": 0.1, "output_every": 0.01, "L": {"yy": -1.0}, "sigma": {"xx": -1.0}},
    {"length": 0.2, "output_every": 0.02, "L": {"yy": 1.0}, "sigma": {"xx": -1.0}}]})


def history(tau, stage, f, theta_deg=80.0, b=0.2):
    """A synthetic history: every sampled column a function f(stage, s) of the row."""
    h = {"tau": np.asarray(tau, float), "stage": np.asarray(stage, float)}
    st, s = stage_abscissa(h)
    v = np.array([f(k, x) for k, x in zip(st, s)])
    for q in ("RP", "eps_v", "c", "A", "sxx", "syy", "sxy", "eps_xx", "eps_yy", "eps_xy"):
        h[q] = v.copy()
    th = math.radians(theta_deg)
    h["Bc"] = np.full(len(v), b * math.cos(2 * th))
    h["Bs"] = np.full(len(v), b * math.sin(2 * th))
    return h


def test_sampling_is_exact_for_stagewise_linear_data_and_nan_beyond_reach():
    # rows at uneven τ (as the DEM's), stage 1 starting where stage 0 stopped (τ = 0.1003)
    tau = [0.0, 0.013, 0.05, 0.1003, 0.13, 0.21, 0.28]
    stage = [0, 0, 0, 0, 1, 1, 1]
    f = lambda k, s: 1.0 + 2.0 * s if k == 0 else 5.0 - 3.0 * s
    h = history(tau, stage, f)
    grid = make_grid(TWO_STAGES, [h])
    assert grid.s[grid.stage == 0][-1] == pytest.approx(0.1003)      # to where stage 0 ended
    assert grid.s[grid.stage == 1][-1] == pytest.approx(0.28 - 0.1003)
    d = sample(h, grid)
    s0 = grid.s[grid.stage == 0]
    # stage 1 is anchored on stage 0's last row at s = 0: linear from 1.2006 to 5 - 3 s
    s1 = grid.s[grid.stage == 1]
    anchor = f(0, 0.1003)
    first = f(1, 0.13 - 0.1003)
    expect1 = np.interp(s1, [0.0, 0.13 - 0.1003, 0.21 - 0.1003, 0.28 - 0.1003],
                        [anchor, first, f(1, 0.21 - 0.1003), f(1, 0.28 - 0.1003)])
    assert d["RP"][grid.stage == 0] == pytest.approx(1.0 + 2.0 * s0, abs=1e-14)
    assert d["RP"][grid.stage == 1] == pytest.approx(expect1, abs=1e-14)
    assert d["theta_p"] == pytest.approx(math.radians(80.0)) and d["B"] == pytest.approx(0.2)
    short = history(tau[:6], stage[:6], f)                    # stops earlier in stage 1
    d2 = sample(short, grid)
    beyond = (grid.stage == 1) & (grid.s > 0.21 - 0.1003 + 1e-9)
    assert beyond.any() and np.all(np.isnan(d2["RP"][beyond]))
    assert np.all(np.isfinite(d2["RP"][~beyond]))


def test_seed_mean_scatter_direction_and_error_metrics(tmp_path):
    tau = np.linspace(0.0, 0.1, 11)
    stage = np.zeros(11)
    a = history(tau, stage, lambda k, s: 0.3, theta_deg=88.0)
    b = history(tau, stage, lambda k, s: 0.4, theta_deg=-88.0)     # same direction mod 180°
    one = parse_path({"name": "one", "stage": [{"length": 0.1, "output_every": 0.01, "L": {"yy": -1.0}}]})
    curve = dem_curve(one, [a, b])
    assert curve.mean["RP"] == pytest.approx(0.35) and curve.std["RP"] == pytest.approx(0.05)
    assert abs(math.degrees(curve.mean["theta_p"][0])) == pytest.approx(90.0, abs=1e-9)
    model = {q: curve.mean[q] + 0.01 for q in ("RP", "eps_v", "c", "A", "B")}
    th = math.radians(-87.0)                                   # 3° from 90° across the wrap
    model.update(theta_p=np.full(len(curve.grid), th), Bc=0.2 * np.cos(2 * th) + 0 * model["B"],
                 Bs=0.2 * np.sin(2 * th) + 0 * model["B"])
    e = errors(curve, model)
    assert e["RP"]["rms"] == pytest.approx(0.01) and e["RP"]["residual_error"] == pytest.approx(0.01)
    assert e["RP"]["dem_scatter"] == pytest.approx(0.05) and math.isnan(e["RP"]["rms_transient"])
    assert e["theta_p"]["rms"] == pytest.approx(3.0) and e["theta_p"]["residual_error"] == pytest.approx(3.0)
    assert e["B"]["residual_rel"] == pytest.approx(0.01 / 0.2)
    write_csv(tmp_path / "c.csv", *curve_table(curve, max_rows=4))
    back = read_curve(tmp_path / "c.csv", curve.start)
    assert len(back.grid) == 5 and back.grid.s[-1] == pytest.approx(0.1)   # every 3rd + the end
    assert back.mean["RP"] == pytest.approx(0.35) and back.start == curve.start

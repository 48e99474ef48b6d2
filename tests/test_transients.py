"""contfab transients: its figures on constructed curves with known answers, and bad input."""
import math

import numpy as np
import pytest

from contfab.calibration.curves import DemCurve, Grid
from contfab.calibration.transients import change_figures, figures, run_transients
from contfab.cli import main


def test_change_figures_of_a_known_transient():
    """After a change at s = 0, R/P = 0.27 (1 - 0.8 exp(-s/0.05)) and c rises by
    0.01 s/0.1 then falls back: minimum 0.054 at the first point, 90 % of steady where
    exp(-s/0.05) = 0.125 (s = 0.104, the next grid point 0.11), largest Δc 0.01 at s = 0.1."""
    s = np.round(np.arange(0.0, 1.0 + 1e-9, 0.01), 10)
    stage = np.r_[np.zeros(1, int), np.ones(len(s) - 1, int)]
    rp = 0.27 * (1.0 - 0.8 * np.exp(-s / 0.05))
    c = 0.81 + 0.01 * np.minimum(s / 0.1, np.maximum(0.0, 2.0 - s / 0.1))
    f = change_figures(stage, s, {"RP": rp, "c": c}, 1)
    assert f["RP_min"] == pytest.approx(rp[1]) and f["s_90"] == pytest.approx(0.11)
    assert f["dc_max"] == pytest.approx(0.01) and f["RP_steady"] == pytest.approx(0.27, rel=1e-6)


def test_model_errors_vanish_on_the_dem_curve_itself():
    """A model that is the DEM's mean curve has zero RMS errors after the change and over
    the build-up, whatever the curve."""
    rng = np.random.default_rng(0)
    s = np.round(np.arange(0.0, 0.6 + 1e-9, 0.01), 10)
    stage = (s > 0.3).astype(int)
    keys = ("RP", "eps_v", "c", "A", "Bc", "Bs", "B", "theta_p")
    mean = {k: rng.uniform(0.1, 0.3, s.size) for k in keys}
    curve = DemCurve(Grid(stage, np.where(stage == 1, s - 0.3, s), s), mean,
                     {k: np.zeros(s.size) for k in keys}, (),
                     {"c": 0.8, "A": 1.0, "Bc": 0.0, "Bs": 0.0})
    f = figures("simple_shear_reversal", curve, dict(mean))
    assert f["change1_rms_RP"] == 0.0 and f["buildup_rms_RP"] == 0.0 and f["buildup_rms_B"] == 0.0
    assert f["path_rms_RP"] == 0.0 and math.isfinite(f["change1_RP_min"])


def test_bad_input_is_a_clear_error(tmp_path, capsys):
    with pytest.raises(ValueError, match="no DEM run directories given"):
        run_transients([], tmp_path / "out")
    (tmp_path / "empty").mkdir()
    assert main(["transients", str(tmp_path / "empty"), "--out", str(tmp_path / "out")]) == 2
    assert "not a finished 'contfab dem run' directory (no history.json)" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()

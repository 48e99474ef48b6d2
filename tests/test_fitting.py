"""The least-squares residual vector of contfab.calibration.fitting on a stored DEM curve,
and the stages of the tier-2 fit.

Each path and quantity contributes the whole curve, (model - DEM)/scale/sqrt(n) per grid
point, and one steady-state term, (window mean of the model - that of the DEM)/scale. A
model that misses grid points (a failed run, or one DEM row a time step past the path's
end) is penalized at those points in the curve part, while the steady-state term is taken
over the points it has, as in contfab.calibration.curves.errors — it turned into the constant PENALTY
when the model missed the DEM grid's last point, so the fit never saw the steady states.
"""
import json
import math
from pathlib import Path

import numpy as np
import pytest

from contfab.calibration.curves import errors, read_curve
from contfab.calibration.fitting import PENALTY, Target, residuals, run_model
from contfab.params import load_params
from dem.paths import load_path

REF = Path(__file__).parent / "data" / "dem_reference"
NAME = "biaxial_loose_k1000"
SHIFT = 0.01
SCALE = {"RP": 0.02}


@pytest.fixture(scope="module")
def target():
    entry = json.loads((REF / "index.json").read_text())["curves"][NAME]
    return Target(NAME, load_path(entry["path"]), read_curve(REF / entry["file"], entry["start"]))


def shifted(target, missing):
    """The DEM mean curve shifted by SHIFT in R/P, NaN at the grid points ``missing``."""
    model = {q: v.copy() for q, v in target.curve.mean.items()}
    model["RP"] = model["RP"] + SHIFT
    model["RP"][missing] = math.nan
    return model


def test_steady_state_term_survives_a_missing_end_point(target):
    n = len(target.curve.grid)
    r = residuals([shifted(target, [n - 1])], [target.curve.mean], [target], ("RP",), SCALE)
    assert len(r) == n + 1
    assert r[n - 1] == pytest.approx(PENALTY / math.sqrt(n), rel=1e-12)
    assert np.allclose(r[:n - 1], SHIFT / SCALE["RP"] / math.sqrt(n), rtol=1e-12)
    # the steady term is the shift, up to what dropping the end point moves the window mean
    dem = target.curve.mean["RP"]
    window = target.curve.grid.residual_window()
    moved = abs(dem[-1] - dem[window].mean()) / (window.sum() - 1) / SCALE["RP"]
    assert abs(r[-1] - SHIFT / SCALE["RP"]) <= moved * (1 + 1e-9)
    # and it is the reported steady error of the same sample (contfab.calibration.curves.errors)
    err = errors(target.curve, shifted(target, [n - 1]), ("RP",))["RP"]["residual_error"]
    assert err / SCALE["RP"] == pytest.approx(r[-1], rel=1e-12)


def test_a_model_missing_the_whole_window_is_penalized(target):
    window = np.flatnonzero(target.curve.grid.residual_window())
    r = residuals([shifted(target, window)], [target.curve.mean], [target], ("RP",), SCALE)
    assert r[-1] == PENALTY


def test_tier2_fit_takes_the_law_on_the_fabric_alone_then_the_cone_at_the_fixed_weight(
        target, monkeypatch):
    """contfab calibrate's tier-2 stages (contfab.calibration.calibrate.fit_tier2): the law's
    coefficients on (A, Bc, Bs) with the cone reduced to tier 1's (w = 0, k_d = 0, where the
    model's R/P is tier 1's: the fabric cannot act on the stress), then k_d, b_c and the
    law's coefficients on every quantity at the start's fabric weight, within their bounds."""
    from contfab.calibration import calibrate, fitting

    start = load_params(REF / "params.toml")
    calls = []
    real = fitting.fit

    def spy(params, tier, spec, targets, **kw):
        calls.append((params, tuple(p.key for p in spec), kw.get("quantities")))
        return real(params, tier, spec, targets, **kw)

    monkeypatch.setattr(fitting, "fit", spy)
    res = calibrate.fit_tier2(start.with_tier(1), "relaxation", [target],
                              fitting.scales([target]), False, max_nfev=1)
    (law_stage, law_keys, law_q), (joint, joint_keys, joint_q) = calls
    assert (law_stage.tier2.fabric_weight, law_stage.tier2.dilatancy_fabric) == (0.0, 0.0)
    assert law_keys == ("z_crit", "b_ratio_crit", "relax_rate") and law_q == ("A", "Bc", "Bs")
    rp2 = run_model(law_stage, 2, target)[0]["RP"]
    rp1 = run_model(law_stage, 1, target)[0]["RP"]
    assert np.nanmax(np.abs(rp2 - rp1)) < 1e-9
    assert joint.tier2.fabric_weight == start.tier2.fabric_weight
    assert joint.tier2.dilatancy_fabric == start.tier2.dilatancy_fabric
    assert set(joint_keys) == {"dilatancy_fabric", "z_crit", "b_ratio_crit", "relax_rate"}
    assert joint_q is None                                   # every tier-2 quantity
    assert res.params.tier2.fabric_weight == start.tier2.fabric_weight
    assert all(p.lo <= x <= p.hi for p, x in zip(res.spec, res.x))

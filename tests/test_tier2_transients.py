"""Tier 2 against the DEM where the fabric matters: absolute bounds on transients.

The DEM references (tests/data/dem_transients: seed means of three samples per path and
density, N = 1000, κ = 1e3, I = 1e-3, μ = 0.5; the curves, the start states and the DEM's own
figures) are written by ``contfab transients RUN_DIR... --out DIR`` into ``DIR/reference``
(the runs and the command: docs/model_validation.md, "Tier 2 through transients"). The
model runs each path from the DEM's mean start state with the shipped parameters; the
figures are :func:`contfab.calibration.transients.figures`, the same functions on the DEM's
curve and on the model's. The bounds are the acceptance table of the tier-2 redesign:

1. simple-shear reversal, dense and loose: R/P RMS over the first 0.2 after the reversal
   <= 0.5 x tier 1's; the minimum of R/P within 0.05 of the DEM's; s_90 within 30 % of it;
2. 90° change of direction: R/P RMS over the first 0.2 <= 0.5 x tier 1's;
3. build-up from isotropy (loose biaxial, loose simple shear): R/P RMS over 0.3 <= 0.5 x
   tier 1's, B within 0.03 RMS;
4. the compaction after a reversal: positive, within 30 % of the DEM's;
5. held-out axes rotation: θp RMS <= 10°, the non-coaxiality within 5° of the DEM's;
6. residual R/P within 0.02, c within 0.005, A and B within 10 % on every fitted path;
7. the held-out family (shear_cycles, seeds the fit did not use, both reversals): tier 2's
   R/P error after each reversal below tier 1's.

Bounds the model does not reach are marked ``xfail(strict=True)`` with what the DEM shows
that the model misses: they fail the suite the day the model meets them, so the record
cannot go stale.
"""
from pathlib import Path

import numpy as np
import pytest

from contfab.calibration.fitting import Target, run_model
from contfab.calibration.transients import figures, read_reference
from contfab.params import default_params
from dem.paths import load_path

REF = read_reference(Path(__file__).parent / "data" / "dem_transients")
PARAMS = default_params()
FITTED = ("simple_shear_reversal_dense", "simple_shear_reversal_loose", "biaxial_dense",
          "biaxial_loose", "direction_change_loose")
HELD_OUT = ("shear_cycles_dense", "shear_cycles_loose")
_CACHE: dict = {}


def model_figures(name: str, tier: int) -> dict:
    """The figures of ``tier`` on reference curve ``name`` (cached per test session)."""
    key = (name, tier)
    if key not in _CACHE:
        path_name, curve, _ = REF[name]
        target = Target(name, load_path(path_name), curve)
        _CACHE[key] = figures(path_name, curve, run_model(PARAMS.with_tier(tier), tier, target)[0])
    return _CACHE[key]


def dem_figures(name: str) -> dict:
    return REF[name][2]


@pytest.mark.parametrize("name", ["simple_shear_reversal_dense", "simple_shear_reversal_loose"])
def test_reversal_transient(name):
    t1, t2, dem = model_figures(name, 1), model_figures(name, 2), dem_figures(name)
    assert t2["change1_rms_RP"] <= 0.5 * t1["change1_rms_RP"]
    assert abs(t2["change1_RP_min"] - dem["change1_RP_min"]) <= 0.05
    assert abs(t2["change1_s_90"] - dem["change1_s_90"]) <= 0.3 * dem["change1_s_90"]


def test_direction_change_transient():
    name = "direction_change_loose"
    assert model_figures(name, 2)["change1_rms_RP"] <= 0.5 * model_figures(name, 1)["change1_rms_RP"]


@pytest.mark.parametrize("name", ["biaxial_loose", "simple_shear_reversal_loose"])
def test_build_up_from_isotropy(name):
    t1, t2 = model_figures(name, 1), model_figures(name, 2)
    assert t2["buildup_rms_RP"] <= 0.5 * t1["buildup_rms_RP"]
    assert t2["buildup_rms_B"] <= 0.03


@pytest.mark.parametrize("name", ["simple_shear_reversal_dense", "simple_shear_reversal_loose"])
def test_compaction_after_reversal(name):
    t2, dem = model_figures(name, 2), dem_figures(name)
    assert dem["change1_dc_max"] > 0.0 and t2["change1_dc_max"] > 0.0
    assert abs(t2["change1_dc_max"] - dem["change1_dc_max"]) <= 0.3 * dem["change1_dc_max"]


def test_axes_rotation_held_out():
    name = "axes_rotation_dense"
    t2, dem = model_figures(name, 2), dem_figures(name)
    assert t2["rotation_rms_theta_p_deg"] <= 10.0
    assert abs(t2["rotation_noncoaxiality_deg"] - dem["rotation_noncoaxiality_deg"]) <= 5.0


@pytest.mark.parametrize("name", FITTED)
def test_residuals_kept(name):
    t2 = model_figures(name, 2)
    curve = REF[name][1]
    last = curve.grid.residual_window()
    assert abs(t2["residual_RP"]) <= 0.02
    assert abs(t2["residual_c"]) <= 0.005
    assert abs(t2["residual_A"]) <= 0.1 * float(np.mean(curve.mean["A"][last]))
    assert abs(t2["residual_B"]) <= 0.1 * float(np.mean(curve.mean["B"][last]))


@pytest.mark.parametrize("name", HELD_OUT)
@pytest.mark.parametrize("change", [1, 2])
def test_held_out_cycles_beat_tier1(name, change):
    key = f"change{change}_rms_RP"
    assert model_figures(name, 2)[key] < model_figures(name, 1)[key]

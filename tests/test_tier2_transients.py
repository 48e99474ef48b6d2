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


REVERSALS = ["simple_shear_reversal_dense", "simple_shear_reversal_loose"]
KNOWN = {
    ("recovery", "simple_shear_reversal_loose"):
        "s_90 0.12 against the DEM's 0.18 (33 %): the loose DEM's R/P recovers more slowly "
        "than its fabric turns; one fabric speed serves both densities (dense: 0.12 vs 0.13)",
    ("build_up", "biaxial_loose"):
        "the DEM's R/P reaches 0.3 by 2 % strain with B/A at half its steady value: the force "
        "part rises above the critical one during the build-up; tier 2's force part is bounded "
        "by m(c), so its R/P follows the fabric (RMS 0.065 against tier 1's 0.055)",
    ("build_up", "simple_shear_reversal_loose"):
        "R/P 0.052 against tier 1's 0.063 and B 0.075: the loose DEM's fabric builds over "
        "γ ≈ 0.3 in simple shear but over 0.04 in biaxial compression (docs/"
        "stress_force_fabric.md §5); one fabric speed cannot give both",
    ("rotation", "axes_rotation_dense"):
        "below the cone tier 2 is rigid: the DEM's fabric follows the stress axes at R/P = 0.3 "
        "(B/A = 0.11, lag 2°) through its contacts' small strains, tier 2's has no plastic "
        "strain to evolve with (B = 0, θp undefined); its non-coaxiality is the "
        "regularization's 45° against the DEM's 38°",
    ("residual", "biaxial_loose"):
        "c: 0.00504 against 0.005 (tier 1: 0.00484); the loose DEM samples dilate past c* "
        "over the last 30 % of strain (c 0.8085 against 0.812), the model stays at c*",
}
"""Acceptance bounds not met, with what the DEM shows (strict xfails)."""


def _known(request, kind, name):
    if (kind, name) in KNOWN:
        request.applymarker(pytest.mark.xfail(strict=True, reason=KNOWN[kind, name]))


@pytest.mark.parametrize("name", REVERSALS)
def test_reversal_transient_error_halved(name):
    assert model_figures(name, 2)["change1_rms_RP"] <= 0.5 * model_figures(name, 1)["change1_rms_RP"]


@pytest.mark.parametrize("name", REVERSALS)
def test_reversal_minimum_of_RP(name):
    assert abs(model_figures(name, 2)["change1_RP_min"] - dem_figures(name)["change1_RP_min"]) <= 0.05


@pytest.mark.parametrize("name", REVERSALS)
def test_reversal_recovery_strain(name, request):
    _known(request, "recovery", name)
    dem = dem_figures(name)["change1_s_90"]
    assert abs(model_figures(name, 2)["change1_s_90"] - dem) <= 0.3 * dem


def test_direction_change_transient():
    name = "direction_change_loose"
    assert model_figures(name, 2)["change1_rms_RP"] <= 0.5 * model_figures(name, 1)["change1_rms_RP"]


@pytest.mark.parametrize("name", ["biaxial_loose", "simple_shear_reversal_loose"])
def test_build_up_from_isotropy(name, request):
    _known(request, "build_up", name)
    t1, t2 = model_figures(name, 1), model_figures(name, 2)
    assert t2["buildup_rms_RP"] <= 0.5 * t1["buildup_rms_RP"]
    assert t2["buildup_rms_B"] <= 0.03


@pytest.mark.parametrize("name", REVERSALS)
def test_compaction_after_reversal(name):
    t2, dem = model_figures(name, 2), dem_figures(name)
    assert dem["change1_dc_max"] > 0.0 and t2["change1_dc_max"] > 0.0
    assert abs(t2["change1_dc_max"] - dem["change1_dc_max"]) <= 0.3 * dem["change1_dc_max"]


def test_axes_rotation_held_out(request):
    name = "axes_rotation_dense"
    _known(request, "rotation", name)
    t2, dem = model_figures(name, 2), dem_figures(name)
    assert t2["rotation_rms_theta_p_deg"] <= 10.0
    assert abs(t2["rotation_noncoaxiality_deg"] - dem["rotation_noncoaxiality_deg"]) <= 5.0


@pytest.mark.parametrize("name", FITTED)
def test_residuals_kept(name, request):
    _known(request, "residual", name)
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

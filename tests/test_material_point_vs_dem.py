"""The material point against the DEM on the same loading paths, with the parameters
calibrated on that DEM.

(a) Stored DEM reference curves (tests/data/dem_reference: the seed-mean curves of a
    calibration campaign, at most 60 points each; index.json records the campaign, the
    runs, start states, and the errors the calibrated models had on exactly these curves;
    params.toml is that calibration's parameter file, with its provenance). They are
    written by ``contfab calibrate`` into ``DIR/report/reference/`` and ``DIR/params.toml``
    and copied here (README, "Calibration from the DEM"). For
    every standard path and tier: the steady (residual-window) error of each quantity may
    not move by more than RESIDUAL_SLACK, nor its RMS by more than RMS_SLACK (a model that
    got better also fails: then regenerate the record with the new calibration).
(b) A live DEM run (N = LIVE_N, one seed not in the campaign) of one fitted path
    (loose biaxial, κ = 1e3) and one held-out path (isochoric shear, dense, κ = 1e3)
    through ``contfab compare``: its steady R/P and c agree with the stored seed means
    within LIVE_DEM (a few single-sample standard deviations at that N), and the models
    agree with it within LIVE_MODEL.

A change of the model moves (a) and (b); a change of the DEM moves (b). The deliberate
perturbations of the model they catch are tested below; that of the DEM (friction μ 0.5
-> 0.3 in the live run) is reported with the calibration (issue 4).
"""
import json
import math
from pathlib import Path

import numpy as np
import pytest

from contfab.calibration.compare import compare
from contfab.calibration.curves import errors, read_curve
from contfab.calibration.fitting import Target, run_model
from contfab.params import load_params
from dem.paths import load_path

REF = Path(__file__).parent / "data" / "dem_reference"
INDEX = json.loads((REF / "index.json").read_text())
CAMPAIGN = INDEX["campaign"]
PARAMS = load_params(REF / "params.toml")
LAW = PARAMS.tier2.to_dict()["fabric_law"]
MODELS = {0: "tier 0", 1: "tier 1", 2: f"tier 2 {LAW}"}
QUANTITIES = {0: ("RP", "eps_v"), 1: ("RP", "eps_v", "c"),
              2: ("RP", "eps_v", "c", "A", "B", "theta_p")}
RESIDUAL_SLACK = {"RP": 0.01, "eps_v": 0.003, "c": 0.001, "A": 0.02, "B": 0.01, "theta_p": 3.0}
RMS_SLACK = {"RP": 0.01, "eps_v": 0.003, "c": 0.001, "A": 0.02, "B": 0.01, "theta_p": 3.0}


def stored_target(name: str) -> Target:
    entry = INDEX["curves"][name]
    path = load_path(entry["path"])
    if entry["probe"] >= 0:
        path = path.expand()[entry["probe"]]
    return Target(name, path, read_curve(REF / entry["file"], entry["start"]), entry)


def mismatches(params, tier: int, name: str) -> list[str]:
    """What of the model's errors on a stored curve left the recorded ones."""
    target = stored_target(name)
    now = errors(target.curve, run_model(params, tier, target)[0])
    recorded = INDEX["curves"][name]["errors"][MODELS[tier]]
    bad = []
    for q in QUANTITIES[tier]:
        e, r = now[q], recorded[q]
        for key, slack in (("residual_error", RESIDUAL_SLACK[q]), ("rms", RMS_SLACK[q])):
            if not _same(e[key], r[key], slack):
                bad.append(f"{q}: {key} {e[key]:.4g}, recorded {r[key]:.4g}")
    return bad


def _same(now: float, recorded: float, slack: float) -> bool:
    """Within ``slack``; NaN only where NaN was recorded (a model that cannot follow the path:
    e.g. tier 0 at φ* on axes_rotation, whose R/P = 0.3 lies outside its cone)."""
    if math.isnan(recorded) or math.isnan(now):
        return math.isnan(recorded) and math.isnan(now)
    return abs(now - recorded) <= slack


@pytest.mark.parametrize("tier", [0, 1, 2])
@pytest.mark.parametrize("name", sorted(INDEX["curves"]))
def test_model_against_stored_dem_curves(name, tier):
    assert mismatches(PARAMS, tier, name) == []


def test_every_standard_path_has_stored_dem_curves():
    from dem.paths import standard_paths

    assert {e["path"] for e in INDEX["curves"].values()} == set(standard_paths())
    assert {e["role"] for e in INDEX["curves"].values()} == {"fit", "heldout", "reference"}


@pytest.mark.parametrize("tier, section, change", [
    (1, "tier1", {"phi_star_deg": PARAMS.tier1.phi_star_deg + 2.0}),
    (1, "tier1", {"c_star": PARAMS.tier1.c_star + 0.004}),
    (2, "tier2", {"b_ratio_crit": PARAMS.tier2.b_ratio_crit - 0.03}),
])
def test_a_perturbed_model_is_caught(tier, section, change):
    """φ* + 2°, c* + 0.004 (tier 1), the critical anisotropy b_c - 0.03 (tier 2: the
    relaxation's target and the cone's fabric part): the stored-curve check fails."""
    perturbed = PARAMS.replace(section, **change)
    fitted = [n for n, e in INDEX["curves"].items() if e["role"] == "fit"]
    assert any(mismatches(perturbed, tier, n) for n in fitted)


# --------------------------------------------------------------------------- (b) live DEM

LIVE = {"biaxial_loose_k1000": ("biaxial", "loose"),
        "isochoric_shear_dense_k1000": ("isochoric_shear", "dense")}
LIVE_SEED = max(CAMPAIGN["seeds"]) + 1
LIVE_N = min(500, CAMPAIGN["n"])
"""The live runs' size: small enough for the normal suite (issue 4: N ≈ 500), never larger
than the campaign's (whose seed means are then the better estimate)."""
N_SCALE = math.sqrt(500.0 / LIVE_N)
"""Sample-to-sample fluctuations of an RVE's steady values fall as 1/sqrt(N)."""
LIVE_DEM = {"RP": 0.05 * N_SCALE, "c": 0.004 * N_SCALE}
"""|live steady value - stored seed mean|: ~2.5 single-sample standard deviations, 0.05 in
R/P and 0.004 in c at N = 500, scaled by 1/sqrt(N) to LIVE_N."""
LIVE_MODEL = {"RP": 0.06 * N_SCALE, "c": 0.006 * N_SCALE}


@pytest.fixture(scope="module")
def live(tmp_path_factory):
    out = tmp_path_factory.mktemp("live")
    runs = {}
    for name, (path, density) in LIVE.items():
        compare(path, out / name, str(REF / "params.toml"), 1, n=LIVE_N, seed=LIVE_SEED, kappa=1e3,
                density=density)
        runs[name] = json.loads((out / name / "errors.json").read_text())
    return out, runs


@pytest.mark.parametrize("name", sorted(LIVE))
def test_live_dem_matches_the_stored_dem_curves(live, name):
    _, runs = live
    stored = INDEX["curves"][name]["errors"]["tier 1"]
    live_err = runs[name]["errors"][LIVE[name][0]]          # keyed by the path's name
    for q, tol in LIVE_DEM.items():
        live_dem = live_err[q]["residual_dem"]
        stored_dem = stored[q]["residual_dem"]
        assert abs(live_dem - stored_dem) <= tol, (q, live_dem, stored_dem)


KNOWN_MODEL_FAILURES: dict[tuple[str, int], str] = {}
"""Model defects these live checks found, as strict xfails (a fix shows up as a failure
here and its entry must go). Emptied on 2026-12-01: the isochoric-shear c defects (tiers 1
and 2) were the comparison of the hardening c_p with the DEM's kinematic c
(tiers.packing_fraction), and tier 2 on the live loose biaxial passes with the calibrated
parameters (its local-solve failure from that start with the earlier parameters is a
kernel regression test)."""


@pytest.mark.parametrize("tier", [1, 2])
@pytest.mark.parametrize("name", sorted(LIVE))
def test_models_match_the_live_dem(live, name, tier, request):
    if (name, tier) in KNOWN_MODEL_FAILURES:
        request.applymarker(pytest.mark.xfail(strict=True, reason=KNOWN_MODEL_FAILURES[name, tier]))
    out, _ = live
    path, density = LIVE[name]
    run = out / name / "dem" / "run"
    from contfab.calibration.curves import dem_curve, read_history

    target = Target(name, load_path(path), dem_curve(load_path(path), [read_history(run / "history.csv")]))
    e = errors(target.curve, run_model(PARAMS, tier, target)[0])
    for q, tol in LIVE_MODEL.items():
        assert abs(e[q]["residual_error"]) <= tol, (q, e[q])
    assert math.isfinite(e["RP"]["rms"]) and np.isfinite(target.curve.mean["RP"]).all()


def test_a_perturbed_dem_is_caught(tmp_path):
    """The DEM with friction μ = 0.3 instead of 0.5 on the live loose biaxial: its steady c
    leaves the stored seed mean by more than LIVE_DEM (measured 0.8214 against 0.8101; R/P
    0.256 against 0.272 stays inside its tolerance, so c is what catches it)."""
    name, (path, density) = "biaxial_loose_k1000", LIVE["biaxial_loose_k1000"]
    compare(path, tmp_path, str(REF / "params.toml"), 1, n=LIVE_N, seed=LIVE_SEED, kappa=1e3,
            density=density, mu=0.3)
    live_err = json.loads((tmp_path / "errors.json").read_text())["errors"][path]
    stored = INDEX["curves"][name]["errors"]["tier 1"]
    off = {q: abs(live_err[q]["residual_dem"] - stored[q]["residual_dem"]) for q in LIVE_DEM}
    assert any(off[q] > tol for q, tol in LIVE_DEM.items()), off

"""The material point against the DEM on the same loading paths, with the shipped parameters
(tier 1 calibrated on this DEM campaign, tier 2's fabric on its transients).

(a) Stored DEM reference curves (tests/data/dem_reference: the seed-mean curves of a
    calibration campaign, at most 60 points each; index.json records the campaign, the
    runs and the start states). They are written by ``contfab calibrate`` into
    ``DIR/report/reference/`` and copied here (README, "Calibration from the DEM"). Every
    model must meet absolute bounds against them, not its own earlier errors: on the
    strain-driven paths the residual (steady) R/P within RESIDUAL["RP"] and c within
    RESIDUAL["c"], tier 2's A and B within 10 % of the DEM's; on the stress-driven paths (isotropic compression, the axes rotation,
    the stress probes) the strains: the residual ε_v within RESIDUAL["eps_v"]. The bounds
    the model does not reach are strict xfails in KNOWN with what the DEM shows.
    Transients: tests/test_tier2_transients.py.
(b) A live DEM run (N = LIVE_N, one seed not in the campaign) of one fitted path
    (loose biaxial, κ = 1e3) and one held-out path (isochoric shear, dense, κ = 1e3)
    through ``contfab compare``: its steady R/P and c agree with the stored seed means
    within LIVE_DEM (a few single-sample standard deviations at that N), and the models
    agree with it within LIVE_MODEL.

A change of the model moves (a) and (b); a change of the DEM moves (b). The deliberate
perturbations of the model they catch are tested below, and that of the DEM (friction
μ 0.5 -> 0.3 in the live run).
"""
import json
import math
from pathlib import Path

import numpy as np
import pytest

from contfab.calibration.compare import compare
from contfab.calibration.curves import errors, read_curve
from contfab.calibration.fitting import Target, run_model
from contfab.params import default_params, default_params_path
from dem.paths import load_path

REF = Path(__file__).parent / "data" / "dem_reference"
INDEX = json.loads((REF / "index.json").read_text())
CAMPAIGN = INDEX["campaign"]
PARAMS = default_params()
RESIDUAL = {"RP": 0.02, "c": 0.005, "eps_v": 0.006}
"""Acceptance bounds on the residual errors: R/P 0.02 and c 0.005 (the calibration's), and on
stress-driven paths ε_v 0.006 (c's bound as a volume strain, Δc/c)."""
FABRIC_RELATIVE = 0.10
STRESS_DRIVEN = ("isotropic_compression", "axes_rotation", "stress_probes")
KNOWN: dict[tuple[str, int], str] = {
    ("biaxial_dense_k10000", 2): "A: the DEM's coordination at κ = 1e4 is 11 % below that at "
                                 "κ = 1e3; tier 2 has one critical z_c (fitted at κ = 1e3)",
    ("biaxial_loose_k10000", 2): "A: as for the dense sample at κ = 1e4",
    ("direction_change_loose_k1000", 1): "R/P: 15 % of strain after a 90° change the DEM's "
                                         "R/P (0.33) is still above its critical 0.27",
    ("direction_change_loose_k1000", 2): "R/P: as for tier 1, less so (0.034 against 0.051); "
                                         "B 0.035 below the DEM's, still rising there",
    ("biaxial_loose_k3000", 2): "B: 0.024 above; these loose samples end at B = 0.221, 10 % "
                                "below the b_c A_c = 0.247 of the κ = 1e3 transients tier 2 "
                                "was fitted on",
    ("isochoric_shear_dense_k1000", 2): "A: held at c = 0.84 the DEM keeps its dense "
                                        "coordination (z = 3.7); tier 2's relaxes to one z_c",
}
"""Bounds not met, with what the DEM shows (strict: a fix fails the test until removed)."""


def stored_target(name: str) -> Target:
    entry = INDEX["curves"][name]
    path = load_path(entry["path"])
    if entry["probe"] >= 0:
        path = path.expand()[entry["probe"]]
    return Target(name, path, read_curve(REF / entry["file"], entry["start"]), entry)


def violations(params, tier: int, name: str) -> list[str]:
    """The bounds of the module doc (a) that the model breaks on stored curve ``name``."""
    target = stored_target(name)
    e = errors(target.curve, run_model(params, tier, target)[0])
    entry = INDEX["curves"][name]
    if entry["path"] in STRESS_DRIVEN:
        checks = {"eps_v": RESIDUAL["eps_v"]}
    else:
        checks = {"RP": RESIDUAL["RP"], "c": RESIDUAL["c"]}
        if tier == 2:
            last = target.curve.grid.residual_window()
            for q in ("A", "B"):
                checks[q] = FABRIC_RELATIVE * float(np.mean(target.curve.mean[q][last]))
    bad = []
    for q, bound in checks.items():
        v = e[q]["residual_error"]
        if not (math.isfinite(v) and abs(v) <= bound):
            bad.append(f"{q}: residual error {v:.4g}, bound {bound:.4g}")
    return bad


CHECKED = sorted(n for n, e in INDEX["curves"].items()
                 if e["probe"] <= 0 and (e["role"] != "reference" or e["path"] in STRESS_DRIVEN))
"""The fitted and held-out curves, and the stress-driven reference ones (the first probe)."""


@pytest.mark.parametrize("tier", [1, 2])
@pytest.mark.parametrize("name", CHECKED)
def test_model_against_stored_dem_curves(name, tier, request):
    if (name, tier) in KNOWN:
        request.applymarker(pytest.mark.xfail(strict=True, reason=KNOWN[name, tier]))
    assert violations(PARAMS, tier, name) == []


def test_every_standard_path_has_stored_dem_curves():
    """Every standard path but the held-out family of tier 2's transients (shear_cycles,
    stored with them: tests/data/dem_transients) has stored campaign curves."""
    from dem.paths import standard_paths

    assert {e["path"] for e in INDEX["curves"].values()} == set(standard_paths()) - {"shear_cycles"}
    assert {e["role"] for e in INDEX["curves"].values()} == {"fit", "heldout", "reference"}


@pytest.mark.parametrize("tier, section, change", [
    (1, "tier1", {"phi_star_deg": PARAMS.tier1.phi_star_deg + 2.0}),
    (1, "tier1", {"c_star": PARAMS.tier1.c_star + 0.008}),
    (2, "tier2", {"b_ratio_crit": PARAMS.tier2.b_ratio_crit - 0.05}),
])
def test_a_perturbed_model_is_caught(tier, section, change):
    """φ* + 2°, c* + 0.008 (tier 1), b_c - 0.05 (tier 2): a fitted curve breaks a bound."""
    perturbed = PARAMS.replace(section, **change)
    fitted = [n for n, e in INDEX["curves"].items()
              if e["role"] == "fit" and (n, tier) not in KNOWN]
    assert any(violations(perturbed, tier, n) for n in fitted)


# --------------------------------------------------------------------------- (b) live DEM

LIVE = {"biaxial_loose_k1000": ("biaxial", "loose"),
        "isochoric_shear_dense_k1000": ("isochoric_shear", "dense")}
LIVE_SEED = max(CAMPAIGN["seeds"]) + 1
LIVE_N = min(300, CAMPAIGN["n"])
"""The live runs' size: small enough for the normal suite, never larger
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
        compare(path, out / name, str(default_params_path()), 1, n=LIVE_N, seed=LIVE_SEED, kappa=1e3,
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
here and its entry must go). Empty: the isochoric-shear c is compared as the DEM's kinematic
c (tiers.packing_fraction), not the hardening c_p, and tier 2 on the live loose biaxial
passes with the calibrated parameters (a local-solve failure from that start with other
parameters is a kernel regression test)."""


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


@pytest.mark.slow
def test_a_perturbed_dem_is_caught(tmp_path):
    """The DEM with friction μ = 0.3 instead of 0.5 on the live loose biaxial: its steady c
    leaves the stored seed mean by more than LIVE_DEM (measured 0.8214 against 0.8101; R/P
    0.256 against 0.272 stays inside its tolerance, so c is what catches it)."""
    name, (path, density) = "biaxial_loose_k1000", LIVE["biaxial_loose_k1000"]
    compare(path, tmp_path, str(default_params_path()), 1, n=LIVE_N, seed=LIVE_SEED, kappa=1e3,
            density=density, mu=0.3)
    live_err = json.loads((tmp_path / "errors.json").read_text())["errors"][path]
    stored = INDEX["curves"][name]["errors"]["tier 1"]
    off = {q: abs(live_err[q]["residual_dem"] - stored[q]["residual_dem"]) for q in LIVE_DEM}
    assert any(off[q] > tol for q, tol in LIVE_DEM.items()), off

"""Trade-off studies: the machinery (front, resume, files) and each study's --fast shape.

The DEM and FEM studies' checks are slow (about 30 s together): the DEM and the FEM they
time are tested on their own in the normal suite; ``python -m pytest -m slow
tests/test_tradeoff.py`` runs them."""
import numpy as np
import pytest

from contfab.cli import main
from contfab.executor import ExecutorError
from contfab.tradeoff import load_study, run
from contfab.tradeoff.study import StudyError, pareto_front, point_key, run_study


def _row(t, e):
    return {"knobs": {}, "wall_s": 2 * t, "cpu_s": t, "cost": t, "errors": {"x": e}}


def test_pareto_front_keeps_only_undominated_rows():
    rows = [_row(1, 1.0), _row(2, 0.5), _row(3, 0.6), _row(4, 0.1), _row(0.5, 2.0),
            _row(2, 0.5)]
    # (3, 0.6) is beaten by (2, 0.5); equal rows do not dominate each other
    assert pareto_front(rows) == [True, True, False, True, True, True]


def test_the_default_setting_is_judged_against_the_front():
    from types import SimpleNamespace

    from contfab.tradeoff.report import default_verdict

    rows = [dict(_row(t, e), knobs={"k": k}) for k, t, e in ((1, 1.0, 1.0), (2, 2.0, 0.5),
                                                              (3, 3.0, 0.6))]
    study = lambda k: SimpleNamespace(knobs=("k",), default={"k": k})   # noqa: E731
    assert default_verdict(study(2), rows) == "on the Pareto front"
    assert default_verdict(study(3), rows).startswith("off the front, beaten by 2 ")
    assert default_verdict(study(9), rows) == "not among these settings"


def test_point_key_is_stable_and_distinguishes_points():
    assert point_key({"a": 1.0, "b": 2}) == point_key({"b": 2, "a": 1.0})
    assert point_key({"a": 1.0}) != point_key({"a": 1.0000001})


def test_unknown_study_or_executor_is_a_clean_error(tmp_path):
    with pytest.raises(StudyError, match="unknown study 'nope'; available: point_increment"):
        load_study("nope", True)
    with pytest.raises(ExecutorError, match="executor 'nope' is not known; accepted: serial"):
        run_study(load_study("point_increment", True), tmp_path, executor="nope")


def test_point_increment_fast_is_first_order_resumable_and_writes_files(tmp_path, capsys):
    assert main(["tradeoff", "point_increment", "--fast", "--quiet", "--out", str(tmp_path)]) == 0
    folder = tmp_path / "point_increment"
    table = np.genfromtxt(folder / "point_increment.csv", delimiter=",", names=True)
    # error halves with the increment (first-order driver; Richardson reference): the
    # fitted order is 1 within 0.15, and the finest run is the most accurate
    h, err = table["increment"], table["error_RP"]
    order = np.polyfit(np.log(h), np.log(err), 1)[0]
    assert abs(order - 1.0) < 0.15
    # the increments resolve the fabric's fastest relaxation (rate k (1 + β D) per unit
    # plastic shear while a dense sample dilates), so the errors are in the asymptotic range
    assert err[np.argmin(h)] == err.min()
    assert (folder / "point_increment.png").stat().st_size > 10_000
    md = (folder / "point_increment.md").read_text()
    assert "| increment | wall s |" in md and "Richardson" in md
    # a rerun reuses every point file: same numbers, no point recomputed
    stamp = {f.name: f.stat().st_mtime_ns for f in (folder / "points").glob("*.json")}
    assert len(stamp) == 4
    assert main(["tradeoff", "point_increment", "--fast", "--quiet", "--out", str(tmp_path)]) == 0
    assert {f.name: f.stat().st_mtime_ns for f in (folder / "points").glob("*.json")} == stamp
    again = np.genfromtxt(folder / "point_increment.csv", delimiter=",", names=True)
    assert np.array_equal(again["error"], table["error"])


def test_points_of_other_parameters_are_rerun_and_a_list_writes_the_summary(tmp_path, monkeypatch):
    """A study that drives the shipped parameters keys its points on their file's digest:
    after a recalibration its stored points are recomputed, not silently reused."""
    from contfab.tradeoff import point_studies
    from contfab.tradeoff import run

    written = run(["point_lambda", "point_increment"], tmp_path / "docs", fast=True,
                  progress=False)
    summary = written["summary"].read_text()
    assert written["summary"] == tmp_path / "docs.md"
    assert "tradeoff point_lambda point_increment --out" in summary
    assert "## point_increment" in summary
    lam = _table(tmp_path / "docs", "point_lambda")
    # the regularization error falls as 1/λ (measured order 1.1 on λ = 100 .. 3000)
    order = -np.polyfit(np.log(lam["lam"]), np.log(lam["error"]), 1)[0]
    assert np.all(np.diff(lam["error"]) < 0) and 0.8 < order < 1.4
    folder = tmp_path / "docs" / "point_lambda" / "points"
    stamp = {f.name: f.stat().st_mtime_ns for f in folder.glob("*.json")}
    monkeypatch.setattr(point_studies, "default_params_digest", lambda: "recalibrated")
    run("point_lambda", tmp_path / "docs", fast=True, progress=False)
    again = {f.name: f.stat().st_mtime_ns for f in folder.glob("*.json")}
    assert set(again) == set(stamp) and all(again[k] != stamp[k] for k in stamp)


def test_points_that_ran_the_dem_are_keyed_on_its_code():
    """DEM and tier studies carry a hash of dem/*.py in the settings their stored points
    must match (the mechanism above), so a change of the DEM's code reruns them."""
    from contfab.tradeoff import load_study
    from contfab.tradeoff.study import dem_code_digest
    from dem.numba_cache import source_digest

    assert dem_code_digest() == source_digest(("dem",)) != source_digest()
    for name in ("dem_size", "dem_inertial", "dem_stiffness", "tier_biaxial", "tier_reversal"):
        assert load_study(name, True).settings["dem_code"] == dem_code_digest(), name
    assert "dem_code" not in load_study("point_lambda", True).settings


def _table(folder, name):
    return np.genfromtxt(folder / name / f"{name}.csv", delimiter=",", names=True, dtype=None,
                         encoding="utf-8")


@pytest.fixture(scope="module")
def dem_fast(tmp_path_factory):
    """The three DEM studies at --fast (N = 64..256, I = 1e-1..1e-2, κ = 1e2..1e4)."""
    out = tmp_path_factory.mktemp("dem")
    for name in ("dem_size", "dem_inertial", "dem_stiffness"):
        run(name, out, fast=True, progress=False)
    return out


@pytest.mark.slow
def test_dem_size_fast_scatter_falls_with_n(dem_fast):
    t = _table(dem_fast, "dem_size")
    assert list(t["n"]) == [64, 128, 512]
    # fluctuations of the steady-state quantities shrink from N = 64 to N = 512 (by 0.35
    # for N^-1/2; measured 0.31-0.35 for c, z, A, B with 3 seeds, 13 rows each). R/P's row
    # scatter in such small, fast cells (I = 1e-2) is dominated by slow collective slips
    # (a seed's R/P fell from 0.39 to 0.10 over the window at N = 256, with either servo):
    # measured 0.76, so only a fall is asserted. (With N = 64..256 and 2 seeds, R/P's
    # scatter once rose with N: 0.20, 0.23, 0.29.)
    for q in ("c", "z", "A", "B"):
        assert t[f"error_{q}"][-1] < 0.6 * t[f"error_{q}"][0], q
    assert t["error_RP"][-1] < 0.9 * t["error_RP"][0]
    md = (dem_fast / "dem_size" / "dem_size.md").read_text()
    assert "beta (row scatter of RP ∝ N^-beta)" in md and "±" in md


@pytest.mark.slow
def test_dem_inertial_fast_error_falls_with_cost_toward_the_quasi_static_limit(dem_fast):
    t = _table(dem_fast, "dem_inertial")
    order = np.argsort(t["inertial"])          # slowest (most costly) first
    err, cost = t["error_RP"][order], t["cost"][order]
    # I = 1e-1 is far from quasi-static: R/P off by tens of percent, c by ~5 %; the error
    # falls monotonically as I falls and the cost per unit strain rises (checked end to end:
    # each point's CPU time is 25-80 ms here, and one run's was once inverted on the loaded
    # machine; measured 3.0x from I = 1e-1 to 1e-2, 10x in steps less the fixed overhead)
    assert np.all(np.diff(err) > 0) and cost[0] > 1.5 * cost[-1]
    assert err[-1] > 0.2 and t["error_c"][order][-1] > 0.02


@pytest.mark.slow
def test_dem_stiffness_fast_error_falls_with_cost_toward_the_rigid_limit(dem_fast):
    t = _table(dem_fast, "dem_stiffness")
    order = np.argsort(t["kappa"])[::-1]       # stiffest (most costly) first
    # soft contacts overlap: c is ~5 % too high at κ = 100, within 1 % at κ >= 1e3 (the
    # two stiff settings are within the N = 100, 2-seed scatter of each other: measured
    # 0.0053 at 1e4 and 0.0006 at 1e3 against the fitted κ → ∞ limit, so their order is
    # not asserted); the time step ∝ κ^-1/2 makes the stiff runs the costly ones (10x in
    # steps from 1e2 to 1e4; neighbours only 3.2x, which CPU time on a loaded machine once
    # inverted, so the cost is checked end to end)
    err_c = t["error_c"][order]
    assert err_c[-1] > 0.02 and np.all(err_c[:-1] < 0.01) and err_c[-1] > 4 * err_c[:-1].max()
    assert t["cost"][order][0] > 2 * t["cost"][order][-1]


@pytest.mark.slow
def test_fem_footing_fast_quadratic_elements_buy_accuracy(tmp_path):
    run("fem_footing_nq", tmp_path, fast=True, progress=False)
    t = _table(tmp_path, "fem_footing_nq")
    # P1 locks under isochoric flow: N_q ~9 % high on the level-1 mesh; P2 is within 3 %
    # at more cost per analysis (4x the DOFs)
    p1, p2 = (t[t["element"] == e] for e in ("P1", "P2"))
    assert p1["error_Nq"][0] > 0.06 and p2["error_Nq"][0] < 0.03
    assert p2["cpu_s"][0] > p1["cpu_s"][0]


@pytest.mark.slow
def test_fem_footing_ngamma_fast_quadratic_elements_buy_accuracy(tmp_path):
    run("fem_footing_ngamma", tmp_path, fast=True, progress=False)
    t = _table(tmp_path, "fem_footing_ngamma")
    # N_γ (Martin 2005: 14.75 at φ = 30°): P1 locks (+36 % on level 1), P2 is within 10 %
    # (+8.1 %) at about 15x the CPU time
    p1, p2 = (t[t["element"] == e] for e in ("P1", "P2"))
    assert p1["error_Ngamma"][0] > 0.2 and p2["error_Ngamma"][0] < 0.1
    assert p2["cpu_s"][0] > 3 * p1["cpu_s"][0]


@pytest.mark.slow
def test_fem_band_fast_peak_and_angle_within_the_case_bounds(tmp_path):
    """The dense shear band on levels 1 and 2 (P2): the peak σ1/σ3 within 2.5 % of the
    closed form at the initial density (measured 1.2 % and 2.0 %), the level-2 band at its
    onset within 5° of Arthur's angle of the peak state (measured 52.5° against 56.0°; level
    1: 55.5°), and the finer mesh costs more."""
    run("fem_band", tmp_path, fast=True, progress=False)
    t = _table(tmp_path, "fem_band")
    assert list(t["level"]) == [1, 2]
    assert np.all(t["error_peak"] < 0.025) and t["error_angle"][1] * 56.0 < 5.0
    assert np.all(np.isfinite(t["error_angle"]))
    assert t["cpu_s"][1] > 2 * t["cpu_s"][0]


def test_tier_studies_fast_tier1_carries_the_volume_change(tmp_path):
    """Both tier studies against an N = 100 DEM reference (one dense sample): tier 0
    (constant ψ, no c) misses ε_v by 3-5 % strain, tiers 1 and 2 (ψ(c)) come within 1.5 %
    and halve the R/P error on the monotonic path. The cost per increment is reported, not
    ordered here: at --fast sizes it is the driver's Python overhead
    (~200 CPU µs per increment for every tier; tier 2 measured below tier 1 once, 190 vs
    234), and speed belongs to `contfab bench model`."""
    run(["tier_biaxial", "tier_reversal"], tmp_path / "tiers", fast=True, progress=False)
    for name in ("tier_biaxial", "tier_reversal"):
        t = _table(tmp_path / "tiers", name)
        assert list(t["tier"]) == [0, 1, 2]
        assert t["error_eps_v"][0] > 0.02, name
        assert t["error_eps_v"][1] < 0.015 and t["error_eps_v"][2] < 0.015, name
        assert np.all(np.isfinite(t["cost"]) & (t["cost"] > 0)), name
    bx = _table(tmp_path / "tiers", "tier_biaxial")
    assert bx["error_RP"][1] < 0.6 * bx["error_RP"][0] and bx["error_RP"][2] < 0.6 * bx["error_RP"][0]

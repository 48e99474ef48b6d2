"""The boundary-value cases at their --fast presets: headline numbers with tolerances."""
import csv
import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from contfab.scenes.case import run_case
from contfab.cli import main
from contfab.params import default_params

PHI = default_params().tier0.phi_deg
"""The shipped (calibrated) tier-0 friction angle, φ* of the DEM: the cases' default φ."""


def test_strip_footing_nq_fast_within_4_percent_and_json(tmp_path, capsys):
    """N_q (the shipped φ = φ* = 15.66°, associated, P2 level 1) against Prandtl-Reissner."""
    code = main(["case", "strip_footing", "--fast", "--json", "--quiet", "--out", str(tmp_path)])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    reference = (math.exp(math.pi * math.tan(math.radians(PHI)))
                 * math.tan(math.radians(45 + PHI / 2)) ** 2)
    assert out["reference"] == pytest.approx(reference, rel=1e-12)
    assert 0 < out["relative_error"] < 0.04            # displacement FE: from above
    assert out["computed"] == pytest.approx(reference * (1 + out["relative_error"]))
    names = {p.name for p in tmp_path.iterdir()}
    stem = f"strip_footing_Nq_phi{PHI:g}_psi{PHI:g}"
    assert {f"{stem}.pvd", f"{stem}_curve.csv", f"{stem}_plastic_zone.png"} <= names
    note = out[f"N_q(phi={PHI:g}, psi={PHI:g})"]
    assert abs(note["plateau_drift"]) < 1e-3 and note["median_newton"] < 8


def test_newton_converges_quadratically_on_the_collapse_plateau():
    """The last step of the footing push (at collapse): the error order of the last
    three residuals is >= 1.5 (2 for Newton), ending below the 1e-8 tolerance."""
    result = run_case("strip_footing", ["--fast", "--quiet", "--out", "none"])
    r = result.notes[f"N_q(phi={PHI:g}, psi={PHI:g})"]["last_step_residuals"]
    assert r[-1] <= 1e-8 and len(r) >= 3
    order = math.log(r[-1] / r[-2]) / math.log(r[-2] / r[-3])
    assert order >= 1.5, r


def test_retaining_wall_fast_within_3_percent_of_rankine():
    result = run_case("retaining_wall", ["--fast", "--quiet", "--out", "none"])
    errors = {f.name: f.relative_error for f in result.figures}
    assert set(errors) == {f"K_a(phi={PHI:g})", f"K_p(phi={PHI:g})"}
    assert all(abs(e) < 0.03 for e in errors.values()), errors
    assert errors[f"K_a(phi={PHI:g})"] < 0 < errors[f"K_p(phi={PHI:g})"]   # stiff FE: K_a low, K_p high


def test_biaxial_band_angle_within_5_degrees_of_roscoe_coulomb_and_softening():
    result = run_case("biaxial_shear_band", ["--fast", "--quiet", "--out", "none"])
    angle, phi0, psi0 = result.figures[0].computed, result.notes["phi0"], result.notes["psi0"]
    assert 45 + psi0 / 2 - 5.0 <= angle <= 45 + phi0 / 2 + 5.0     # Roscoe - 5 ... Coulomb + 5
    assert result.notes["softening"] < -0.05          # the end load is > 5 % below the peak
    # the peak sits at φ(c0): σ1/σ3 = (1 + sin φ)/(1 - sin φ) to 2 %
    s = math.sin(math.radians(result.notes["phi0"]))
    assert result.notes["peak"] == pytest.approx((1 + s) / (1 - s), rel=0.02)


def test_band_references_are_roscoe_arthur_coulomb_of_the_peak_state_never_the_angle(
        monkeypatch):
    """The band angle is printed against Roscoe 45 + ψ/2, Arthur 45 + (φ + ψ)/4 and Coulomb
    45 + φ/2 of the peak state, each separately; the headline is Arthur's. An angle inside
    the range must not become its own reference (that made the headline error 0 %)."""
    from contfab.scenes.case import build_parser, load_case

    biax = load_case("biaxial_shear_band")
    run = {"peak": 3.0, "peak_strain": 0.01, "end": 2.5, "angle": 53.0, "phi0": 30.0,
           "psi0": 10.0, "band_c_min": 0.8, "dofs": 1, "wall_s": 0.0, "steps": 1,
           "median_newton": 1.0, "files": []}
    monkeypatch.setattr(biax, "solve", lambda *a, **k: run)
    args = build_parser(biax, "x").parse_args([])
    args.out = None
    result = biax.run(args)
    refs = {f.source.split(" ")[0]: f.reference for f in result.figures}
    assert refs == {"Arthur": 55.0, "Roscoe": 50.0, "Coulomb": 60.0}
    assert result.figures[0].source.startswith("Arthur")
    assert all(f.computed == 53.0 != f.reference for f in result.figures)
    assert result.notes["in_roscoe_coulomb"] is True


@pytest.mark.parametrize("argv, message", [
    (["case", "strip_footing", "--level", "99", "--out", "none"], "mesh level = 99 is outside"),
    (["case", "strip_footing", "--settlement", "2", "--out", "none"],
     "settlement = 2 B is outside the accepted range"),
    (["case", "strip_footing", "--element", "P2", "--relaxation-time", "-1", "--out", "none"],
     "relaxation_time = -1.0 is outside the accepted range"),
    (["case", "retaining_wall", "--phi", "95", "--out", "none"], "phi_deg = 95 is outside"),
    (["case", "biaxial_shear_band", "--dense", "0.5", "--out", "none"], "dense = 0.5"),
    (["case", "simple_shear_reversal", "--dgamma", "0.5", "--out", "none"],
     "dgamma = 0.5 is outside the accepted range (0, 0.1]"),
    (["case", "no_such_case"], "unknown case 'no_such_case'"),
])
def test_bad_case_input_is_a_clean_error(argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_case_listing(capsys):
    assert main(["case"]) == 0
    out = capsys.readouterr().out
    assert all(n in out for n in ("strip_footing", "retaining_wall", "biaxial_shear_band",
                                  "simple_shear_reversal"))


def test_simple_shear_reversal_fast_against_the_point_driver_and_the_dem(tmp_path):
    """The homogeneous layer is the material point (τ/σn to 1e-6); the references are the
    stored DEM curve's values at the stage ends; tier 2's fabric direction flips on
    reversal as the DEM's does (θp < 0 after γ = +1, > 0 after γ = -1, within 15°)."""
    # its own process (``python cases/NAME.py``): after a failed strip_footing case in the
    # same process its first tier-1 update hung (not yet understood; see the report)
    root = Path(__file__).parent.parent
    done = subprocess.run([sys.executable, str(root / "cases/simple_shear_reversal.py"), "--fast",
                           "--json", "--quiet", "--out", str(tmp_path)],
                          capture_output=True, text=True, timeout=180)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    with open(root / "contfab/scenes/data/simple_shear_reversal_dem.csv") as fh:
        rows = list(csv.DictReader(fh))
    forward_end = [r for r in rows if r["stage"] == "0"][-1]
    expected = {"+1": forward_end, "-1": rows[-1]}
    for f in out["figures"]:
        row = expected[f["name"].split("gamma = ")[1].split(" ")[0]]
        assert f["reference"] == pytest.approx(float(row["sxy"]) / -float(row["syy"]), rel=1e-9)
    # the layer and the driver integrate the same update on different step grids (the FEM's
    # Δγ = 0.05 after a dt/4 start, the driver's 0.01 output rows); from the DEM's start
    # (c0 - c* = 0.0023) c evolves, so they differ at O(Δγ): 6.1e-4 measured (1e-13 at c*)
    assert out["tier1"]["max_dev_vs_point"] < 2e-3
    t2 = out["tier2"]
    assert t2["theta_p_at_gamma_1"] < 0 < t2["theta_p_at_gamma_-1"]
    assert t2["dem_theta_p_at_gamma_1"] < 0 < t2["dem_theta_p_at_gamma_-1"]
    for g in ("1", "-1"):
        assert abs(t2[f"theta_p_at_gamma_{g}"] - t2[f"dem_theta_p_at_gamma_{g}"]) < 15.0
    assert "simple_shear_reversal_vs_dem.csv" in {p.name for p in tmp_path.iterdir()}


def _failure(value: float):
    """A ConvergenceError as the analysis driver raises it, with a one-row curve."""
    from contfab.fem.analysis import RunResult
    from contfab.fem.solver import ConvergenceError, FieldState

    last = FieldState("push", 0.25, *([None] * 7))
    curve = RunResult(["stage", "t", "Ngamma", "settlement", "stress_ratio", "axial_strain"],
                      [["push", 0.25, value, 0.01, value, 0.001]])
    return ConvergenceError("stage 'push': no converged step beyond t = 0.25", last, [], curve)


def test_a_failed_study_run_is_recorded_and_the_others_still_run(monkeypatch):
    """strip_footing --psi phi 10 0: the psi = 10 run fails, psi = 0 still runs, the table
    row says 'failed'; a failure of the headline (associated) run is still an error."""
    from contfab.scenes.case import build_parser, load_case
    from contfab.fem.solver import ConvergenceError

    case = load_case("strip_footing")
    done = []

    def fake(phi, psi, *a, **k):
        done.append(psi)
        if psi == 10.0:
            raise _failure(12.5)
        return {"computed": 14.0 + psi / 10, "reference": case.reference_factor("Ngamma", phi),
                "peak": 15.0, "plateau_drift": 0.0, "settlement_over_B": 0.1, "dofs": 1,
                "wall_s": 0.0, "steps": 1,
                "median_newton": 1.0, "residuals": [[1e-9]], "files": []}

    monkeypatch.setattr(case, "solve", fake)
    args = build_parser(case, "x").parse_args(["--factor", "Ngamma", "--phi", "30", "--psi",
                                               "phi", "10", "0"])
    args.out = None
    result = case.run(args)
    assert done == [30.0, 10.0, 0.0]
    failed = result.notes["N_gamma(phi=30, psi=10)"]
    assert failed["failed"] and "no converged step" in failed["message"]
    assert failed["last_converged"] == {"Ngamma": 12.5, "settlement": 0.01}
    assert result.notes["N_gamma(phi=30, psi=0)"]["drop_vs_associated"] == pytest.approx(14 / 17 - 1)
    args.psi = ["phi"]
    monkeypatch.setattr(case, "solve", lambda *a, **k: (_ for _ in ()).throw(_failure(1.0)))
    with pytest.raises(ConvergenceError):
        case.run(args)

    biax = load_case("biaxial_shear_band")
    main_run = {"peak": 3.0, "peak_strain": 0.01, "end": 2.5, "angle": 50.0, "phi0": 30.0,
                "psi0": 10.0, "band_c_min": 0.8, "dofs": 1, "wall_s": 0.0, "steps": 1,
                "median_newton": 1.0, "files": []}

    def fake_biax(params, element, level, dense, strain, out, progress, lam=None, **kw):
        if lam is not None:
            raise _failure(2.9)
        return main_run

    monkeypatch.setattr(biax, "solve", fake_biax)
    args = build_parser(biax, "x").parse_args(["--study"])
    args.out = None
    notes = biax.run(args).notes
    assert notes["lambda_10x"]["failed"] and "peak_change_10x_lambda" not in notes
    assert notes["lambda_10x"]["max_stress_ratio_so_far"] == 2.9
    assert all(notes[f"level{k}"]["peak"] == 3.0 for k in (1, 2, 3))

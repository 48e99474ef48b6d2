"""The boundary-value cases at their --fast presets: each computed value against its
published reference, evaluated here from constants of this file (never from the case's
own reference or error)."""
import contextlib
import csv
import io
import json
import math
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from contfab.scenes.case import run_case
from contfab.cli import main
from contfab.params import default_params, default_params_path

SHIPPED = default_params()
PHI = SHIPPED.tier0.phi_deg
"""The shipped (calibrated) tier-0 friction angle, φ* of the DEM: the cases' default φ."""


def prandtl_reissner_nq(phi_deg: float) -> float:
    """N_q = e^{π tan φ} tan²(45° + φ/2) (Prandtl 1920, Reissner 1924)."""
    phi = math.radians(phi_deg)
    return math.exp(math.pi * math.tan(phi)) * math.tan(math.pi / 4 + phi / 2) ** 2


def rankine_ka(phi_deg: float) -> float:
    """K_a = (1 - sin φ)/(1 + sin φ) (Rankine 1857); K_p = 1/K_a."""
    s = math.sin(math.radians(phi_deg))
    return (1 - s) / (1 + s)


def test_the_reference_formulas_match_their_published_tables():
    """The closed forms above against tabulated values: N_q(30°) = 18.40 (Vesić 1973,
    "Analysis of ultimate loads of shallow foundations", J. Soil Mech. Found. Div. 99(SM1),
    table of bearing-capacity factors); K_a(30°) = 1/3 exactly."""
    assert prandtl_reissner_nq(30.0) == pytest.approx(18.40, abs=0.005)
    assert rankine_ka(30.0) == pytest.approx(1 / 3, rel=1e-12)


def tier1_initial_angles(c0: float) -> tuple[float, float]:
    """(φ0, ψ0) [deg] of tier 1's linear laws about c* at c0, from the shipped parameters."""
    t1 = SHIPPED.tier1
    phi0 = min(max(t1.phi_star_deg + t1.dphi_dc_deg * (c0 - t1.c_star), t1.phi_min_deg),
               t1.phi_max_deg)
    return phi0, max(min(t1.dpsi_dc_deg * (c0 - t1.c_star), phi0), -phi0)


@pytest.fixture(scope="module")
def footing(tmp_path_factory):
    """One ``contfab case strip_footing --fast --json`` run (the CLI path, the main job at
    the test preset: tier 1 on the shipped parameters beside the tier-0 check), shared."""
    out = tmp_path_factory.mktemp("strip_footing")
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        code = main(["case", "strip_footing", "--fast", "--json", "--quiet", "--out", str(out)])
    return code, json.loads(text.getvalue()), out


CHECK = f"tier-0 check N_q(phi*={SHIPPED.tier1.phi_star_deg:.2f}, associated)"


def test_strip_footing_nq_fast_within_4_percent_and_json(footing):
    """The tier-0 check, N_q at φ* = 15.9° (associated, P2 level 1), against Prandtl-Reissner:
    displacement FE bounds the collapse load from above, within 4 % on this mesh."""
    code, out, folder = footing
    assert code == 0
    check = {f["name"]: f for f in out["figures"]}[CHECK]
    reference = prandtl_reissner_nq(SHIPPED.tier1.phi_star_deg)
    assert 0 < check["computed"] / reference - 1 < 0.04, (check["computed"], reference)
    names = {p.name for p in folder.iterdir()}
    stem = f"strip_footing_Nq_phi{PHI:g}_psi{PHI:g}"
    assert {f"{stem}.pvd", f"{stem}_curve.csv", f"{stem}_plastic_zone.png"} <= names
    note = out[CHECK]
    assert abs(note["plateau_drift"]) < 1e-3 and note["median_newton"] < 8


def test_newton_converges_quadratically_on_the_collapse_plateau():
    """The last step of the associated footing push (at collapse), converged to 1e-10: the
    error order of the last three residuals is >= 1.5 (2 for Newton)."""
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        code = main(["case", "strip_footing", "--fast", "--tier", "0", "--tol", "1e-10",
                     "--json", "--quiet", "--out", "none"])
    out = json.loads(text.getvalue())
    r = out[out["figure"]]["last_step_residuals"]
    assert code == 0 and r[-1] <= 1e-10 and len(r) >= 3
    order = math.log(r[-1] / r[-2]) / math.log(r[-2] / r[-3])
    assert order >= 1.5, r


def test_calibrated_tier1_footing_converges_to_0p3_b_between_the_tier0_bounds(footing):
    """The main job's calibrated material: tier 1 from the shipped dense state, non-associated
    (ψ0 < φ0), pushed by the rate-independent Newton to 0.3 B at every step. Its collapse
    load (the curve's peak) lies below Prandtl-Reissner at φ0 = φ(c0): no point's φ
    exceeds φ0 (ψ > 0 only dilates, lowering c), and the non-associated load lies below the
    associated one with the same yield surface (Radenković's first theorem). It lies above
    Prandtl-Reissner at the critical φ*: every point keeps φ >= φ* (ψ -> 0 at c*), and the
    dense peak comes before the zone has softened (the theorem's lower bound, at
    atan(sin φ*), is lower still). It softens after the peak. Files: the VTU series with c,
    and the plastic zone."""
    code, out, folder = footing
    phi0, psi0 = tier1_initial_angles(SHIPPED.initial.c0)
    assert psi0 < phi0 - 5                                    # strongly non-associated
    head = out["figures"][0]
    assert head["reference"] is None and "no published reference" in head["source"]
    note = out[head["name"]]
    assert note["settlement_over_B"] == pytest.approx(0.3, rel=1e-9)
    assert note["solution"].startswith("rate-independent Newton")
    low, high = prandtl_reissner_nq(SHIPPED.tier1.phi_star_deg), prandtl_reissner_nq(phi0)
    assert low < head["computed"] < high, (low, head["computed"], high)
    assert note["computed_end"] < head["computed"]            # the dense footing softens
    stem = f"strip_footing_Nq_tier1_c{SHIPPED.initial.c0:.4f}"
    names = {p.name for p in folder.iterdir()}
    assert {f"{stem}.pvd", f"{stem}_curve.csv", f"{stem}_plastic_zone.png"} <= names
    frames = sorted(folder.glob(f"{stem}_0*.vtu"))
    assert "c" in meshio_cell_fields(frames[-1])


def meshio_cell_fields(path) -> set:
    import meshio
    return set(meshio.read(path).cell_data)


def test_retaining_wall_fast_within_3_percent_of_rankine():
    """K_a and K_p at the shipped φ against Rankine's closed form; the stiff FE pushes
    K_a low and K_p high."""
    result = run_case("retaining_wall", ["--fast", "--quiet", "--out", "none"])
    computed = {f.name: f.computed for f in result.figures}
    ka = rankine_ka(PHI)
    errors = {"active": computed[f"K_a(phi={PHI:g})"] / ka - 1,
              "passive": computed[f"K_p(phi={PHI:g})"] * ka - 1}
    assert set(computed) == {f"K_a(phi={PHI:g})", f"K_p(phi={PHI:g})"}
    assert all(abs(e) < 0.03 for e in errors.values()), (computed, ka)
    assert errors["active"] < 0 < errors["passive"], errors


def _loose_active_wall(displacement: float):
    """The loose tier-1 wall moving away (P2, level 1): (figure, notes, K_a bounds)."""
    result = run_case("retaining_wall", ["--tier", "1", "--c0", "loose", "--mode", "active",
                                         "--element", "P2", "--displacement", str(displacement),
                                         "--quiet", "--out", "none"])
    head = result.figures[0]
    note = result.notes[head.name]
    assert note["displacement"] == pytest.approx(displacement, rel=1e-9)
    bounds = note["tier0_bounds"]
    assert bounds["phi_star"]["phi"] > bounds["phi0"]["phi"]          # loose: φ0 < φ*
    low, high = bounds["phi_star"]["tier0"], bounds["phi0"]["tier0"]
    assert low < high < rankine_ka(bounds["phi0"]["phi"]) * 1.01
    return head, note, (low, high)


def test_loose_active_wall_converges_between_the_tier0_bounds():
    """The loose tier-1 backfill (c0 = 0.805: contracting, hardening from φ0 = 13.3° toward
    φ* = 15.9°) behind a wall moving away by 0.02 H converges at every step, and its least
    K lies between the associated tier-0 K_a on the same mesh at φ* (the strength it
    hardens to) and at φ0 (its initial strength)."""
    head, note, (low, high) = _loose_active_wall(0.02)
    assert low < head.computed < high, (low, head.computed, high)


@pytest.mark.slow
def test_loose_active_wall_reaches_the_critical_state_at_a_tenth_of_the_height():
    """The same wall pushed to 0.1 H, the calibrated runs' displacement (its steps stall at
    a relative residual of 1e-4 down to the minimum step near 0.0124 H and pass on the
    last-resort stall tolerance): K still lies between the bounds, and by 0.1 H it has come
    within 2 % of the tier-0 K_a at φ*, the critical state's (the backfill has hardened)."""
    head, note, (low, high) = _loose_active_wall(0.1)
    assert low < head.computed < high, (low, head.computed, high)
    assert head.computed < low * 1.02
    assert note["last_resort_steps"] <= 0.02 * note["steps"]


def test_biaxial_band_angle_within_5_degrees_of_roscoe_coulomb_and_softening():
    """The band angle at onset lies within 5° of the Roscoe-Coulomb range of the peak state
    [45° + ψ0/2, 45° + φ0/2] (Vermeer 1990, "The orientation of shear bands in biaxial
    tests", Géotechnique 40(2), 223-236), and the peak is the Mohr-Coulomb ratio of φ0:
    σ1/σ3 = (1 + sin φ0)/(1 - sin φ0) to 2 %. φ0, ψ0 are tier 1's linear laws at the
    case's default start c0 = c* + 0.03, evaluated here from the shipped parameters. The
    onset window starts at the peak and closes before the end of the push (4 %), where
    the end window (its last tenth) starts; the band's c then lies between c* and c0."""
    t1 = SHIPPED.tier1
    dc = 0.03                                     # the case's default --dense
    phi0 = min(max(t1.phi_star_deg + t1.dphi_dc_deg * dc, t1.phi_min_deg), t1.phi_max_deg)
    psi0 = min(t1.dpsi_dc_deg * dc, phi0)
    result = run_case("biaxial_shear_band", ["--fast", "--quiet", "--out", "none"])
    angle = result.figures[0].computed
    roscoe, coulomb = 45 + psi0 / 2, 45 + phi0 / 2
    assert roscoe - 5.0 <= angle <= coulomb + 5.0, (angle, roscoe, coulomb)
    assert result.notes["softening"] < -0.05          # the end load is > 5 % below the peak
    s = math.sin(math.radians(phi0))
    assert result.notes["peak"] == pytest.approx((1 + s) / (1 - s), rel=0.02)
    onset, end = result.notes["band_onset"], result.notes["band_end"]
    assert onset["window_strain"][0] == result.notes["peak_strain"]
    assert onset["window_strain"][0] < onset["window_strain"][1] < end["window_strain"][0]
    assert end["window_strain"][1] == pytest.approx(0.04, rel=1e-9)
    assert t1.c_star - 1e-3 < end["band_c"] < onset["band_c"] < t1.c_star + dc


def test_band_width_is_the_full_width_at_half_maximum_of_a_gaussian_band():
    """A Gaussian band exp(-(s/σ)²) across the direction 50° on the case's mesh has the full
    width at half maximum 2σ√(ln 2); the measure finds it to 2 % (bins a quarter of an
    element wide, linear interpolation between them), whichever sense of the angle is given."""
    from contfab.fem import mesh as meshes
    from contfab.fem.assembly import Discretization
    from contfab.scenes.biaxial_shear_band import band_width

    disc = Discretization(meshes.delaunay_rectangle(1.0, 2.5, 1 / 24), "P2")
    theta, sigma = math.radians(50.0), 0.08
    s = (disc.points - [0.5, 1.25]) @ np.array([-math.sin(theta), math.cos(theta)])
    exact = 2 * sigma * math.sqrt(math.log(2))
    dgp = np.exp(-(s / sigma) ** 2)
    assert band_width(disc, dgp, 50.0) == pytest.approx(exact, rel=0.02)
    assert band_width(disc, dgp, 130.0) == pytest.approx(exact, rel=0.02)
    assert math.isnan(band_width(disc, dgp, math.nan))


def _band(angle: float, band_c: float, phi: float, psi: float) -> dict:
    """A band entry of the biaxial case's ``solve`` (angle, width, the band's c and its
    angles), for runs faked without the solver."""
    return {"angle": angle, "band_width": 0.1, "band_c": band_c, "window_strain": [0.01, 0.02],
            "band_phi": phi, "band_psi": psi}


def _fake_band_run(onset_angle: float, end_angle: float) -> dict:
    """A faked ``solve`` result: peak state φ0 = 30°, ψ0 = 10°; the band's state at the
    end φ = 16°, ψ = 2° (the band state at onset: φ = 28°, ψ = 8°)."""
    return {"peak": 3.0, "peak_strain": 0.01, "end": 2.5, "angle": end_angle, "phi0": 30.0,
            "psi0": 10.0, "band_c_min": 0.8, "band_width": 0.1, "h": 0.1, "dofs": 1,
            "wall_s": 0.0, "steps": 1, "median_newton": 1.0, "files": [],
            "onset_angle": onset_angle, "band_onset": _band(onset_angle, 0.84, 28.0, 8.0),
            "band_end": _band(end_angle, 0.81, 16.0, 2.0)}


def test_band_references_are_roscoe_arthur_coulomb_of_the_peak_state_never_the_angle(
        monkeypatch):
    """The band angle at onset is printed against Roscoe 45 + ψ/2, Arthur 45 + (φ + ψ)/4 and
    Coulomb 45 + φ/2 of the peak state (φ0, ψ0), the angle at the end against those of the
    band's state at the end (φ, ψ of its c), each separately; the headline is the onset
    against Arthur's. An angle inside its range must not become its own reference (that
    made the headline error 0 %), and each measurement says whether it lies in its range."""
    from contfab.scenes.case import build_parser, load_case

    biax = load_case("biaxial_shear_band")
    for onset_angle, end_angle, inside in ((53.0, 47.0, (True, True)),
                                           (49.0, 54.0, (False, False))):
        monkeypatch.setattr(biax, "solve",
                            lambda *a, **k: _fake_band_run(onset_angle, end_angle))
        args = build_parser(biax, "x").parse_args([])
        args.out = None
        result = biax.run(args)
        onset, end = result.figures[:3], result.figures[3:]
        assert {f.source.split(" ")[0]: f.reference for f in onset} == \
            {"Arthur": 55.0, "Roscoe": 50.0, "Coulomb": 60.0}
        assert {f.source.split(" ")[0]: f.reference for f in end} == \
            {"Arthur": 49.5, "Roscoe": 46.0, "Coulomb": 53.0}
        assert result.figures[0].source.startswith("Arthur") and "onset" in result.figures[0].name
        assert all(f.computed == onset_angle != f.reference for f in onset)
        assert all(f.computed == end_angle != f.reference for f in end)
        notes = result.notes
        assert (notes["band_onset"]["in_roscoe_coulomb"], notes["band_end"]["in_roscoe_coulomb"]) \
            == inside
        assert (notes["band_onset"]["arthur"], notes["band_end"]["arthur"]) == (55.0, 49.5)


def test_the_critical_state_band_references_are_45_degrees_and_45_plus_half_phi_star():
    """At c = c* tier 1's laws give ψ = 0 and φ = φ*: the band state's Roscoe angle is 45°
    and its Coulomb angle 45° + φ*/2 (Roscoe 1970; a band at the critical state dilates no
    more), with φ* the shipped calibration's."""
    from contfab.scenes.biaxial_shear_band import references
    from contfab.scenes.material_options import angles_at

    phi, psi = angles_at(SHIPPED, SHIPPED.tier1.c_star)
    assert (phi, psi) == (pytest.approx(SHIPPED.tier1.phi_star_deg, abs=1e-12), 0.0)
    ref = references(phi, psi, 46.0)
    assert ref["roscoe"] == 45.0 and ref["in_roscoe_coulomb"]
    assert ref["coulomb"] == pytest.approx(45.0 + SHIPPED.tier1.phi_star_deg / 2, abs=1e-12)


def test_the_onset_window_runs_from_the_peak_to_a_stated_share_of_the_drop():
    """On a curve rising to a peak at step 10 and softening to its end value, the onset
    window starts at the peak and ends at the first later step below
    peak − drop · (peak − end), before the end; a curve that does not soften has none, and
    a drop outside (0, 1) is refused naming the value."""
    from contfab.params import ParamError
    from contfab.scenes.biaxial_shear_band import onset_window

    k = np.arange(60)
    ratio = np.where(k <= 10, 1.0 + 0.32 * k - 0.016 * k**2,
                     1.8 + 0.8 * np.exp(-(k - 10) / 8.0))
    peak, end = ratio.max(), ratio[-1]
    for drop in (0.1, 0.25, 0.5):
        k0, k1 = onset_window(ratio, drop)
        assert k0 == 10 and ratio[k0] == peak
        assert k0 < k1 < len(ratio) - 1
        assert ratio[k1] <= peak - drop * (peak - end) < ratio[k1 - 1]
    assert onset_window(np.linspace(1.0, 2.0, 20)) is None          # hardening to the end
    with pytest.raises(ParamError, match="onset drop = 1 is outside"):
        onset_window(ratio, 1.0)


def test_the_band_measure_finds_a_strip_s_angle_and_the_mean_c_inside_it():
    """A plastic strain increment confined to a strip 0.1 wide at 55° through the specimen's
    centre, where c falls from 0.80 to 0.82 over the window (0.85 outside): the band lies
    at 55° to the grid's 0.5° and one bin, and its c is the window's mean inside, 0.81."""
    from contfab.fem import mesh as meshes
    from contfab.fem.assembly import Discretization
    from contfab.scenes.biaxial_shear_band import band_measure

    disc = Discretization(meshes.delaunay_rectangle(1.0, 2.5, 1 / 16), "P2")
    theta = math.radians(55.0)
    s = (disc.points - [0.5, 1.25]) @ np.array([-math.sin(theta), math.cos(theta)])
    inside = np.abs(s) < 0.05
    gp0 = np.zeros(disc.npoints)
    marks = [(gp0, np.where(inside, 0.80, 0.85)), (gp0 + inside, np.where(inside, 0.82, 0.85))]
    band = band_measure(disc, marks, (0, 1))
    assert band["angle"] == pytest.approx(55.0, abs=0.3)
    assert band["band_c"] == pytest.approx(0.81, abs=1e-12)
    assert math.isnan(band_measure(disc, marks, None)["band_c"])


@pytest.mark.parametrize("level", [1, 2])
def test_the_band_angle_of_prescribed_noisy_strips_is_within_half_a_degree(level):
    """Gaussian strips of plastic strain increment (full width 0.05–0.15 at half maximum,
    30 % multiplicative noise per point) at random angles 40–65° and offsets through the
    specimen of the band case, alone or (level 2) crossed by a weaker band: the measured
    angle lies within 0.5° of the prescribed one (a Hough transform alone scatters by
    1.4–4° RMS on these meshes)."""
    from contfab.fem import mesh as meshes
    from contfab.fem.assembly import Discretization
    from contfab.scenes.biaxial_shear_band import HEIGHT, WIDTH, band_angle

    disc = Discretization(meshes.delaunay_rectangle(WIDTH, HEIGHT, WIDTH / (8 * level)), "P2")
    rng = np.random.default_rng(level)

    def strip(angle, offset, fwhm):
        theta = math.radians(angle)
        s = (disc.points - [0.5 * WIDTH, 0.5 * HEIGHT + offset]) @ [-math.sin(theta), math.cos(theta)]
        return np.exp(-0.5 * (s / (fwhm / 2.3548)) ** 2)

    for _ in range(12):
        angle, offset, fwhm = rng.uniform(40, 65), rng.uniform(-0.15, 0.15), rng.uniform(0.05, 0.15)
        noise = np.clip(1.0 + 0.3 * rng.standard_normal(disc.npoints), 0.0, None)
        assert band_angle(disc, strip(angle, offset, fwhm) * noise) == pytest.approx(angle, abs=0.5)
    # an X: a weaker band (0.4-0.7 of the peak) crossing the first at its centre; on level 1
    # (eight elements across, the band two to three) the crossing pulls the fit by 1.2° on
    # average (up to 2.6°)
    for _ in range(8 if level > 1 else 0):
        angle, other, offset, fwhm = (rng.uniform(42, 60), rng.uniform(42, 60), rng.uniform(-0.1, 0.1),
                                      rng.uniform(0.05, 0.12))
        noise = np.clip(1.0 + 0.3 * rng.standard_normal(disc.npoints), 0.0, None)
        dgp = (strip(angle, offset, fwhm) + rng.uniform(0.4, 0.7) * strip(180.0 - other, offset, fwhm))
        assert band_angle(disc, dgp * noise) == pytest.approx(angle, abs=0.5)


@pytest.mark.parametrize("argv, message", [
    (["case", "strip_footing", "--level", "99", "--out", "none"], "mesh level = 99 is outside"),
    (["case", "strip_footing", "--settlement", "2", "--out", "none"],
     "settlement = 2 B is outside the accepted range"),
    (["case", "strip_footing", "--element", "P2", "--relaxation-time", "-1", "--out", "none"],
     "relaxation_time = -1.0 is outside the accepted range"),
    (["case", "strip_footing", "--tol-stall", "2", "--out", "none"],
     "need 0 < tol <= tol_stall < 1, got tol = 1e-08, tol_stall = 2.0"),
    (["case", "strip_footing", "--tol", "1.5", "--out", "none"],
     "tol = 1.5 is outside the accepted range (0, 1)"),
    (["case", "strip_footing", "--explicit", "0", "--out", "none"],
     "cycles = 0 is outside the accepted range: integers >= 1"),
    (["case", "strip_footing", "--explicit", "1000", "--relaxation-time", "1e-4", "--out",
      "none"], "--explicit and --relaxation-time are two solution strategies"),
    (["case", "retaining_wall", "--phi", "95", "--out", "none"], "phi_deg = 95 is outside"),
    (["case", "retaining_wall", "--tol-stall-last", "2", "--out", "none"],
     "tol_stall_last = 2.0 is outside the accepted range [tol_stall, 1)"),
    (["case", "strip_footing", "--c0", "dense-ish", "--out", "none"],
     "c0 = 'dense-ish' is not a packing fraction"),
    (["case", "retaining_wall", "--tier", "1", "--c0", "1.5", "--out", "none"],
     "c0 = 1.5 is outside the accepted range (0, 1)"),
    (["case", "strip_footing", "--tier", "1", "--phi", "30", "--out", "none"],
     "--phi/--psi set tier 0's constant angles"),
    (["case", "retaining_wall", "--tier", "2", "--displacement", "2", "--out", "none"],
     "displacement = 2 H is outside the accepted range"),
    (["case", "biaxial_shear_band", "--dense", "0.5", "--out", "none"], "dense = 0.5"),
    (["case", "biaxial_shear_band", "--internal-length", "0.1", "--nonlocal-weight", "0.5",
      "--out", "none"], "nonlocal weight m = 0.5 is outside the accepted range [1, inf)"),
    (["case", "biaxial_shear_band", "--internal-length", "0.9", "--out", "none"],
     "internal length = 0.9 is outside the accepted range [0, 0.5]"),
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


DEM_REFERENCE = Path(__file__).parent.parent / "contfab/scenes/data/simple_shear_reversal_dem"


def test_the_simple_shear_reference_is_a_dem_sample_the_calibration_did_not_use():
    """The stored DEM run has the calibration campaign's settings for this path (the
    loose sample at κ = 1000) and a seed outside the campaign's: a held-out sample."""
    run = json.loads(DEM_REFERENCE.with_suffix(".json").read_text())["settings"]
    with default_params_path().open("rb") as fh:
        prov = tomllib.load(fh)["provenance"]
    campaign = prov["campaign"]
    assert run["seed"] not in campaign["seeds"], (run["seed"], campaign["seeds"])
    assert {k: run[k] for k in ("n", "mu", "inertial", "radii")} == \
        {k: campaign[k] for k in ("n", "mu", "inertial", "radii")}
    spec = prov["runs"]["simple_shear_reversal_loose_k1000"]
    assert run["kappa"] == spec["kappa"] and run["mu_prep"] in (None, campaign["mu"])


def test_simple_shear_reversal_fast_against_the_point_driver_and_the_dem(tmp_path):
    """The homogeneous layer is the material point (τ/σn to 2e-3); the references are the
    stored DEM curve's values at the stage ends; tier 2's fabric direction flips on
    reversal as the DEM's does (θp < 0 after γ = +1, > 0 after γ = -1, within 15°); both
    tiers predict the held-out DEM sample's steady τ/σn (:func:`steady_gaps`)."""
    # its own process (``python cases/NAME.py``): after a failed strip_footing case in the
    # same process its first tier-1 update hung (not understood)
    root = Path(__file__).parent.parent
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(root)] + os.environ.get("PYTHONPATH", "").split(os.pathsep))}  # this checkout's
    done = subprocess.run([sys.executable, str(root / "cases/simple_shear_reversal.py"), "--fast",
                           "--json", "--quiet", "--out", str(tmp_path)],
                          capture_output=True, text=True, timeout=600, env=env)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    with open(DEM_REFERENCE.with_suffix(".csv")) as fh:
        rows = list(csv.DictReader(fh))
    forward_end = [r for r in rows if r["stage"] == "0"][-1]
    expected = {"+1": forward_end, "-1": rows[-1]}
    for f in out["figures"]:
        row = expected[f["name"].split("gamma = ")[1].split(" ")[0]]
        assert f["reference"] == pytest.approx(float(row["sxy"]) / -float(row["syy"]), rel=1e-9)
    # the layer and the driver integrate the same update on different step grids (the FEM's
    # Δγ = 0.05 after a dt/4 start, the driver's 0.01 output rows); from the DEM's start
    # (c0 - c* = -0.0036) c evolves, so they differ at O(Δγ): 1.0e-3 measured (1e-13 at c*)
    assert out["tier1"]["max_dev_vs_point"] < 2e-3
    t2 = out["tier2"]
    assert t2["theta_p_at_gamma_1"] < 0 < t2["theta_p_at_gamma_-1"]
    assert t2["dem_theta_p_at_gamma_1"] < 0 < t2["dem_theta_p_at_gamma_-1"]
    for g in ("1", "-1"):
        assert abs(t2[f"theta_p_at_gamma_{g}"] - t2[f"dem_theta_p_at_gamma_{g}"]) < 15.0
    with open(tmp_path / "simple_shear_reversal_vs_dem.csv") as fh:
        table = list(csv.DictReader(fh))
    gaps = steady_gaps(table)
    assert all(abs(gap) <= bound for gap, bound in gaps.values()), gaps


STEADY = 0.3
"""The steady part of each stage: its last 30 % (the calibration's residual window)."""


def steady_gaps(table: list[dict]) -> dict[tuple[str, int], tuple[float, float]]:
    """{(tier, stage): (model - DEM, bound)} of the mean τ/σn over the steady part of
    each stage, on the DEM's rows (``simple_shear_reversal_vs_dem.csv``). The bound is 3
    standard errors of the DEM sample's own mean there, sd/√rows (the rows, 0.01 of γ
    apart, taken as independent): the model predicts the held-out sample's steady stress
    ratio as closely as that sample determines it. Measured: tier 1 +0.0068 / -0.0016
    against bounds 0.0134 / 0.0121 (forward / reverse), tier 2 +0.0091 / -0.0018."""
    tau = np.array([float(r["tau"]) for r in table])
    gaps = {}
    for stage, (start, end) in enumerate(((0.0, 1.0), (1.0, 3.0))):
        rows = (tau >= end - STEADY * (end - start)) & (tau <= end + 1e-9)
        dem = np.array([float(r["dem_ratio"]) for r in table])[rows]
        for tier in ("tier1", "tier2"):
            model = np.array([float(r[f"{tier}_ratio"]) for r in table])[rows]
            gaps[(tier, stage)] = (float(model.mean() - dem.mean()),
                                   3.0 * float(dem.std(ddof=1)) / math.sqrt(rows.sum()))
    return gaps


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
    main_run = _fake_band_run(52.0, 50.0)

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

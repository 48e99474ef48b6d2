"""No false records: a resumed run's settings, an unrelaxed preparation, the bench's ratio."""
import json
from types import SimpleNamespace

import pytest

from contfab.cli import main
from dem.job import LOOSE, Settings, UnrelaxedWarning
from test_dem_cli import SHORT

SAMPLE = ["--n", "60", "--kappa", "1e3", "--mu", "0.4", "--seed", "3", "--inertial", "1e-2"]


@pytest.fixture(scope="module")
def sample(tmp_path_factory):
    d = tmp_path_factory.mktemp("records")
    (d / "short.toml").write_text(SHORT)
    assert main(["dem", "prepare", "--out", str(d / "s.npz"), *SAMPLE]) == 0
    return d


@pytest.mark.parametrize("flag, value, have", [
    ("--n", "80", "n = 60"), ("--mu", "0.5", "mu = 0.4"), ("--kappa", "1e4", "kappa = 1000.0"),
    ("--seed", "4", "seed = 3"), ("--mu-prep", "0", "mu_prep = 0.4")])
def test_resume_refuses_a_conflicting_flag_and_writes_nothing(sample, tmp_path, capsys, flag,
                                                               value, have):
    out = tmp_path / "o"
    assert main(["dem", "run", str(sample / "short.toml"), "--out", str(out), "--resume",
                 str(sample / "s.npz"), flag, value]) == 2
    err = capsys.readouterr().err
    assert f"{flag} " in err and have in err and "accepted: omit" in err
    assert not out.exists()


def test_resume_runs_and_records_the_checkpoints_settings(sample, tmp_path, capsys):
    out = tmp_path / "o"
    # no settings given: the checkpoint's (n = 60, κ = 1e3, μ = 0.4, I = 1e-2), not the defaults
    assert main(["dem", "run", str(sample / "short.toml"), "--out", str(out), "--resume",
                 str(sample / "s.npz"), "--n", "60"]) == 0
    assert f"those of the checkpoint {sample / 's.npz'}" in capsys.readouterr().out
    meta = json.loads((out / "history.json").read_text())
    s = meta["settings"]
    assert (s["n"], s["kappa"], s["mu"], s["seed"], s["inertial"]) == (60, 1e3, 0.4, 3, 1e-2)
    assert meta["settings_source"] == f"checkpoint {sample / 's.npz'}" and meta["warnings"] == []
    # what ran: the dynamics of the run and the number of discs in its history
    assert meta["dynamics"]["mu"] == 0.4 and meta["dynamics"]["gdot_ref"] == 1e-2
    # the test's rate may be set on a prepared sample, and is then recorded
    out2 = tmp_path / "o2"
    assert main(["dem", "run", str(sample / "short.toml"), "--out", str(out2), "--resume",
                 str(sample / "s.npz"), "--inertial", "2e-2"]) == 0
    meta2 = json.loads((out2 / "history.json").read_text())
    assert meta2["settings"]["inertial"] == 2e-2 and meta2["dynamics"]["gdot_ref"] == 2e-2
    # ... but not on a run under way, nor another path
    ck = out / "checkpoint.npz"
    for extra, word in ((["--inertial", "2e-2"], "inertial = 0.01"), ([], "differs from")):
        path = "biaxial" if not extra else str(sample / "short.toml")
        assert main(["dem", "run", path, "--out", str(tmp_path / "o3"), "--resume", str(ck),
                     *extra]) == 2
        assert word in capsys.readouterr().err
    assert not (tmp_path / "o3").exists()


def test_a_contact_style_runs_on_a_prepared_sample_and_is_recorded(sample, tmp_path, capsys):
    out = tmp_path / "h"
    assert main(["dem", "run", str(sample / "short.toml"), "--out", str(out), "--resume",
                 str(sample / "s.npz"), "--contact-style", "hooke/history"]) == 0
    meta = json.loads((out / "history.json").read_text())
    assert meta["settings"]["contact_style"] == "hooke/history"
    assert meta["dynamics"]["style"] == "hooke/history"
    # a run under way keeps the law it started with
    assert main(["dem", "run", str(sample / "short.toml"), "--out", str(tmp_path / "h2"),
                 "--resume", str(out / "checkpoint.npz"), "--contact-style",
                 "spring-dashpot"]) == 2
    assert "contact_style = 'hooke/history'" in capsys.readouterr().err
    assert not (tmp_path / "h2").exists()
    # the loose protocol's damped collapse runs the default style whatever the test's
    Settings(contact_style="hooke/history", **LOOSE).validate()


def test_unrelaxed_preparation_is_an_error_unless_allowed_and_then_recorded(tmp_path, capsys):
    args = ["--n", "60", "--kappa", "1e3", "--inertial", "1e-2", "--prep-max-steps", "1000"]
    assert main(["dem", "prepare", "--out", str(tmp_path / "s.npz"), *args]) == 2
    err = capsys.readouterr().err
    assert "did not relax within prep_max_steps = 1000" in err and "--allow-unrelaxed" in err
    assert not (tmp_path / "s.npz").exists()
    with pytest.warns(UnrelaxedWarning, match="UNRELAXED SAMPLE"):
        assert main(["dem", "prepare", "--out", str(tmp_path / "s.npz"), *args,
                     "--allow-unrelaxed"]) == 0
    (tmp_path / "short.toml").write_text(SHORT)
    run = ["dem", "run", str(tmp_path / "short.toml"), "--resume", str(tmp_path / "s.npz")]
    assert main([*run, "--out", str(tmp_path / "o")]) == 2      # a resumed unrelaxed sample too
    assert "UNRELAXED PREPARATION" in capsys.readouterr().err
    with pytest.warns(UnrelaxedWarning, match="UNRELAXED PREPARATION"):
        assert main([*run, "--out", str(tmp_path / "o"), "--allow-unrelaxed"]) == 0
    meta = json.loads((tmp_path / "o" / "history.json").read_text())
    assert meta["preparation"]["relaxed"] is False and meta["preparation"]["steps"] == 1000
    assert meta["warnings"] and meta["warnings"][0].startswith("UNRELAXED PREPARATION")


def test_a_quench_stopped_at_its_share_is_said_but_does_not_stop_a_run(monkeypatch, tmp_path):
    """A loose sample whose quenched collapse ran out of its share of the budget relaxed
    under the test law: its sidecar and every run on it say so, and the run goes on."""
    import dem.prepare

    monkeypatch.setattr(dem.prepare, "TEST_LAW_RESERVE", 1_999_000)   # no room for a quench
    args = ["--n", "60", "--kappa", "1e3", "--inertial", "1e-2", "--mu-prep", "10"]
    assert main(["dem", "prepare", "--out", str(tmp_path / "s.npz"), *args]) == 0
    (tmp_path / "short.toml").write_text(SHORT)
    run = ["dem", "run", str(tmp_path / "short.toml"), "--resume", str(tmp_path / "s.npz")]
    with pytest.warns(UnrelaxedWarning, match="QUENCH STOPPED UNRELAXED"):
        assert main([*run, "--out", str(tmp_path / "o")]) == 0
    meta = json.loads((tmp_path / "o" / "history.json").read_text())
    prep = meta["preparation"]
    assert prep["relaxed"] is True and prep["quench_relaxed"] is False
    assert prep["c_quenched"] is None and prep["c"] > prep["c_compressed"]
    assert len(meta["warnings"]) == 1 and meta["warnings"][0].startswith("QUENCH STOPPED")


def test_bench_prints_no_lammps_ratio_without_a_lammps_run(monkeypatch, tmp_path):
    import contfab.bench.dem as bench
    import contfab.bench.dem_lammps as dem_lammps

    small = dict(bench.reference_system(), n=40)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr(bench, "reference_system", lambda: small)

    def missing(*a, **k):
        raise dem_lammps.LammpsUnavailable("not here")
    monkeypatch.setattr(dem_lammps, "LammpsRun", missing)
    out = bench.run(SimpleNamespace(repeats=1))
    assert out["lammps"] == "not found: not here"
    assert not [k for k in out if "ratio" in k]

"""The command line parses, calls, and turns bad input into a one-line error."""
from contfab.cli import main


def test_paths_lists_and_shows(capsys):
    assert main(["paths"]) == 0
    assert "simple_shear_reversal" in capsys.readouterr().out
    assert main(["paths", "stress_probes"]) == 0
    assert capsys.readouterr().out.count("stage 0 'probe_") == 16


def test_unknown_path_is_a_clean_error(capsys):
    assert main(["paths", "nope"]) == 2
    err = capsys.readouterr().err
    assert "unknown loading path 'nope'" in err and "Traceback" not in err


def _compare(tmp_path, *extra):
    return main(["compare", "biaxial", "--out", str(tmp_path / "out"), "--n", "40", *extra])


def test_compare_refuses_bad_input_before_any_dem_run(tmp_path, capsys):
    """Acceptance 5: a missing or malformed parameter file, an out-of-range parameter, an
    unknown path: one-line errors naming the culprit, and nothing written."""
    bad_toml = tmp_path / "bad.toml"
    bad_toml.write_text("tier = 1\n[tier1\nphi_star_deg = 30\n")
    out_of_range = tmp_path / "range.toml"
    from conftest import FIXED_PARAMS
    out_of_range.write_text(FIXED_PARAMS.read_text().replace("c_star = ", "c_star = 1.5 #", 1))
    cases = [(["--params", str(tmp_path / "missing.toml")], "missing.toml"),
             (["--params", str(bad_toml)], "bad.toml"),
             (["--params", str(out_of_range)], "c_star = 1.5"),
             (["--density", "dense", "--kappa", "-1"], "kn = -1.0 out of range")]
    for extra, words in cases:
        assert _compare(tmp_path, *extra) == 2, extra
        err = capsys.readouterr().err
        assert words in err and "Traceback" not in err, (extra, err)
    assert main(["compare", "no_such_path", "--out", str(tmp_path / "out")]) == 2
    assert "unknown loading path 'no_such_path'" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_calibrate_refuses_bad_settings(tmp_path, capsys):
    for extra, words in [(["--seeds", "0"], "--seeds 0 out of range"),
                         (["--max-nfev", "0"], "--max-nfev 0 out of range"),
                         (["--kappas", "-5"], "kappa = -5.0 out of range"),
                         (["--n", "1"], "n = 1 out of range")]:
        assert main(["calibrate", "--out", str(tmp_path / "cal"), *extra]) == 2, extra
        err = capsys.readouterr().err
        assert words in err and "Traceback" not in err, (extra, err)
    assert not (tmp_path / "cal").exists()

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

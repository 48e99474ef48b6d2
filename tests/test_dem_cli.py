"""`contfab dem run/prepare`: files written, bad input refused with nothing written."""
import json

import pytest

from contfab.cli import main

SHORT = """name = "short"
[[stage]]
length = 0.004
output_every = 0.001
L = { yy = -1.0, xy = 0.0, yx = 0.0 }
sigma = { xx = -1.0 }
"""


def test_prepare_then_run_from_the_prepared_sample(tmp_path, capsys):
    path = tmp_path / "short.toml"
    path.write_text(SHORT)
    common = ["--n", "120", "--kappa", "1e3", "--inertial", "1e-2"]
    assert main(["dem", "prepare", "--out", str(tmp_path / "s.npz"), *common]) == 0
    out = tmp_path / "run"
    assert main(["dem", "run", str(path), "--out", str(out), "--resume",
                 str(tmp_path / "s.npz"), *common]) == 0
    printed = capsys.readouterr().out
    assert "history.csv" in printed
    names = {p.name for p in out.iterdir()}
    assert {"history.csv", "history.json", "checkpoint.npz", "history.png", "normals.png"} <= names
    rows = (out / "history.csv").read_text().splitlines()
    assert rows[0].startswith("stage,tau,sxx") and len(rows) >= 1 + 5
    assert abs(float(rows[-1].split(",")[1]) - 0.004) < 1e-4   # the path ran to its end
    meta = json.loads((out / "history.json").read_text())
    assert meta["settings"]["n"] == 120 and meta["path"]["name"] == "short"
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temporaries left


@pytest.mark.parametrize("args, word", [
    (["--kappa", "0"], "kn = 0.0"), (["--mu", "-1"], "mu = -1.0"), (["--e", "1.5"], "e = 1.5"),
    (["--radii", "uniform:1.2"], "0 <= W < 1"), (["--dt-fraction", "0.9"], "stability limit"),
    (["--inertial", "0"], "inertial = 0.0")])
def test_bad_settings_are_refused_and_nothing_is_written(tmp_path, capsys, args, word):
    out = tmp_path / "o"
    assert main(["dem", "run", "biaxial", "--out", str(out), "--n", "50", *args]) == 2
    err = capsys.readouterr().err
    assert word in err and "accepted" in err and "Traceback" not in err
    assert not out.exists()


def test_unknown_path_component_is_refused(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(SHORT.replace("yy = -1.0,", "zz = -1.0,"))
    assert main(["dem", "run", str(bad), "--out", str(tmp_path / "o"), "--n", "50"]) == 2
    assert "unknown velocity-gradient component ['zz']" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()

"""`contfab point` and `contfab bench point`: the files a run writes (the DEM's columns,
sidecar, plots), clean errors that leave no file behind, and the bench's figures."""
import csv
import json
from types import SimpleNamespace

import numpy as np
import pytest

from contfab import material_point as mp
from contfab.bench import point as bench_point
from contfab.calibration import point_job
from contfab.cli import main
from contfab.models import tiers
from dem.history import HISTORY_COLUMNS


def read_csv(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


def test_point_writes_the_dem_columns_a_sidecar_and_plots(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["point", "biaxial", "--out", str(out), "--tier", "1",
                 "--increment", "2.5e-3"]) == 0
    printed = capsys.readouterr().out
    assert str(out / "history.csv") in printed and str(out / "history.json") in printed
    header, rows = read_csv(out / "history.csv")
    assert tuple(header) == HISTORY_COLUMNS + mp.EXTRA_COLUMNS
    assert len(rows) == 193          # τ = 0, every 0.0002 to 0.02, then every 0.0025 to 0.25
    fabric = [header.index(c) for c in ("z", "A", "Bc", "Bs", "B", "theta_p")]
    assert all(row[i] == "" for row in rows for i in fabric)       # tier 1: no fabric
    sxx = np.array([float(r[header.index("sxx")]) for r in rows])
    assert np.abs(sxx + 1.0).max() < 1e-11
    assert float(rows[-1][header.index("eps_yy")]) == pytest.approx(-0.25, abs=1e-12)
    meta = json.loads((out / "history.json").read_text())
    assert meta["tier"] == 1 and meta["path"]["name"] == "biaxial"
    assert meta["params"]["regularization"]["lambda"] == 1000.0
    assert meta["increments"]["increment"] == 2.5e-3 and meta["increments"]["taken"] == 192
    assert meta["versions"]["contfab"] and meta["timing"]["total_s"] > 0
    assert (out / "history.png").stat().st_size > 10_000
    assert sorted(p.name for p in out.iterdir()) == ["history.csv", "history.json",
                                                     "history.png"]


def test_point_with_a_parameter_file_and_tier_2_writes_the_fabric_columns(tmp_path, capsys):
    """Issue 3's CLI form `contfab point PATH --params FILE --tier T --out DIR`: the file's
    values are used (sidecar), the tier-2 fabric columns of the DEM's CSV are filled."""
    from conftest import FIXED_PARAMS
    from contfab.params import load_params

    out = tmp_path / "run2"
    assert main(["point", "simple_shear_reversal", "--params", str(FIXED_PARAMS), "--tier", "2",
                 "--out", str(out), "--increment", "5e-3"]) == 0
    header, rows = read_csv(out / "history.csv")
    assert tuple(header) == HISTORY_COLUMNS + mp.EXTRA_COLUMNS
    col = {c: np.array([float(r[header.index(c)]) for r in rows])
           for c in ("z", "A", "B", "theta_p", "c", "RP", "gamma", "stage")}
    assert col["z"] == pytest.approx(np.pi * col["A"], rel=1e-12)
    assert col["B"][0] == 0.0 and col["B"][-1] > 0.05       # the fabric turns anisotropic
    # forward shear (L_xy > 0): contacts gather toward the compression axis at -45°, and
    # toward +45° after the reversal (measured -55.9° and +58.5°)
    forward_end = np.flatnonzero(col["stage"] == 0)[-1]
    assert -np.pi / 2 < col["theta_p"][forward_end] < 0.0 < col["theta_p"][-1] < np.pi / 2
    meta = json.loads((out / "history.json").read_text())
    assert meta["tier"] == 2
    assert meta["params"] == load_params(FIXED_PARAMS).with_tier(2).to_dict()
    assert (out / "history.png").stat().st_size > 10_000
    print(f"\ncontfab point simple_shear_reversal --params {FIXED_PARAMS.name} --tier 2: {len(rows)} rows, "
          f"at γ = {col['gamma'][-1]:.2f}: R/P {col['RP'][-1]:.4f}, c {col['c'][-1]:.4f}, "
          f"z {col['z'][-1]:.3f}, B {col['B'][-1]:.3f}, θp {np.degrees(col['theta_p'][-1]):.1f}°")


def test_a_cold_tier_2_kernel_is_announced_once_on_stderr(tmp_path, capsys, monkeypatch):
    """With the tier-2 kernel reported as not compiled (a cold cache), the first
    ``contfab point --tier 2`` says on stderr that it is compiling, a second one does not;
    a tier-0 run never does."""
    from dem import numba_cache

    monkeypatch.setattr(numba_cache, "is_compiled", lambda dispatcher: False)
    monkeypatch.setattr(numba_cache, "_ANNOUNCED", set())
    for k, tier in enumerate(("0", "2", "2")):
        assert main(["point", "isotropic_compression", "--tier", tier,
                     "--out", str(tmp_path / str(k))]) == 0
        err = capsys.readouterr().err
        said = [line for line in err.splitlines() if line.startswith("compiling ")]
        assert said == (["compiling the tier-2 model kernels (first use of this code; about "
                         f"{point_job.COMPILE_TIME[2]} on one core, cached for later runs)"]
                        if k == 1 else []), err


def test_probe_family_writes_one_history_per_probe_and_the_envelope(tmp_path):
    out = tmp_path / "probes"
    assert main(["point", "stress_probes", "--out", str(out), "--tier", "0"]) == 0
    assert len(list(out.glob("history_*.csv"))) == 16
    assert (out / "response.png").is_file()
    header, rows = read_csv(out / "history_4.csv")                  # the 90° probe: Δσyy > 0
    syy = float(rows[-1][header.index("syy")])
    assert syy == pytest.approx(-1.0 + 0.02, abs=1e-12)


@pytest.mark.parametrize("argv, words", [
    (["point", "nope"], ["unknown loading path 'nope'", "biaxial"]),
    (["point", "biaxial", "--tier", "9"], ["tier = 9", "accepted"]),
    (["point", "biaxial", "--increment", "-1"], ["increment = -1.0", "(0, inf)"]),
    (["point", "biaxial", "--params", "BAD"], ["phi_deg = 95", "(0, 90)"]),
    (["point", "biaxial", "--params", "MISSING"], ["No such file"]),
])
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys, argv, words):
    bad = tmp_path / "bad.toml"
    bad.write_text("tier = 0\n[regularization]\nlambda = 1e3\np_ref = 1.0\n"
                   "[tier0]\nphi_deg = 95.0\n")
    argv = [str(bad) if a == "BAD" else str(tmp_path / "none.toml") if a == "MISSING" else a
            for a in argv]
    out = tmp_path / "out"
    assert main(argv + ["--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    for w in words:
        assert w in err
    assert not out.exists()


def test_unfollowable_path_writes_nothing(tmp_path, capsys):
    path = tmp_path / "too_far.toml"
    path.write_text('name = "too_far"\n[[stage]]\nname = "ramp"\nlength = 0.1\n'
                    'L = { xy = 0.0, yx = 0.0 }\n'
                    'sigma = { xx = -1.0, yy = { target = -3.0, ramp = true } }\n')
    out = tmp_path / "out"
    assert main(["point", str(path), "--tier", "0", "--out", str(out)]) == 2
    assert "cannot be reached" in capsys.readouterr().err
    assert not out.exists()


def test_bench_point_figures(monkeypatch):
    monkeypatch.setattr(bench_point, "TRADE_INCREMENTS", (2.5e-3, 1.25e-3))
    monkeypatch.setattr(bench_point, "REFERENCE_FRACTION", 1.0 / 8.0)
    figures = bench_point.run(SimpleNamespace(repeats=1))
    for tier in sorted(tiers.KERNELS):
        assert figures[f"tier{tier}_biaxial_us_per_increment"] > 0
        assert figures[f"tier{tier}_isochoric_shear_updates_per_increment"] == 1.0
    coarse, fine = (figures[f"tier1_biaxial_h{h:.4g}_error_c"] for h in (2.5e-3, 1.25e-3))
    assert 1.5 < coarse / fine < 3.5          # first order against a reference at h/8

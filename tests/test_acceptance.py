"""Acceptance 4 and 5 of issue 2 at reduced size (normal suite) and full size (slow).

Reduced: N = 150, κ = 1e3, I = 1e-2 (the session fixtures). These still fail if dense and
loose samples respond alike, if the fabric leaves the admissible set, or if the fabric
does not turn on reversal. Full size: N = 2000, κ = 1e4, I <= 1e-3, to 50% axial strain
(acceptance 4), and
simple shear with reversal (acceptance 5); figures in the report of issue 2.
"""
import numpy as np
import pytest

from conftest import make_dynamics, prepared
from dem.paths import load_path, parse_path
from dem.rve import PathRunner


def _biaxial(state, strain, gdot, kappa):
    dyn = make_dynamics(state, kappa=kappa, mu=0.5, gdot=gdot)
    path = parse_path({"name": "b", "stage": [
        {"length": strain, "output_every": strain / 60, "L": {"yy": -1.0, "xy": 0.0, "yx": 0.0},
         "sigma": {"xx": -1.0}}]})
    runner = PathRunner(path, dyn, gdot)
    return runner.run(state, runner.start(state)).rows


def test_dense_and_loose_biaxial_reduced(packing_frictionless, packing_frictional):
    dense = _biaxial(packing_frictionless.copy(), 0.15, 1e-2, 1e3)
    loose = _biaxial(packing_frictional.copy(), 0.15, 1e-2, 1e3)
    rp = lambda rows, a, b: [r["RP"] for r in rows if a <= -r["eps_yy"] <= b]  # noqa: E731
    # the dense sample mobilizes more friction early and dilates; the loose one contracts first
    assert max(rp(dense, 0, 0.05)) > max(rp(loose, 0, 0.05)) + 0.03
    assert dense[-1]["eps_v"] > 0.01
    assert min(r["eps_v"] for r in loose) < 0 < max(r["eps_v"] for r in dense)
    for rows in (dense, loose):
        assert all(r["admissibility"] >= 0 for r in rows)


def test_shear_reversal_turns_the_fabric_reduced(packing_frictional):
    st = packing_frictional.copy()
    dyn = make_dynamics(st, kappa=1e3, mu=0.5, gdot=1e-2)
    path = parse_path({"name": "ssr", "stage": [
        {"name": "fwd", "length": 0.3, "output_every": 0.01, "L": {"xx": 0.0, "xy": 1.0, "yx": 0.0},
         "sigma": {"yy": -1.0}},
        {"name": "rev", "length": 0.6, "output_every": 0.01, "L": {"xx": 0.0, "xy": -1.0, "yx": 0.0},
         "sigma": {"yy": -1.0}}]})
    runner = PathRunner(path, dyn, 1e-2)
    rows = runner.run(st, runner.start(st)).rows
    fwd = [r for r in rows if r["stage"] == 0][-5:]
    rev = [r for r in rows if r["stage"] == 1][-5:]
    # forward shear (L_xy > 0): compression axis at -45°, normals gather there; reversed: +45°
    tp_f = np.mean([r["theta_p"] for r in fwd])
    tp_r = np.mean([r["theta_p"] for r in rev])
    assert abs(tp_f + np.pi / 4) < 0.35 and abs(tp_r - np.pi / 4) < 0.35
    # B dips on reversal before it builds up again
    b_rev = [r["B"] for r in rows if r["stage"] == 1]
    assert min(b_rev) < 0.6 * np.mean([r["B"] for r in fwd])
    assert all(r["admissibility"] >= 0 for r in rows)


def _steady(rows, key, lo, hi):
    """(mean, fluctuation, drift) of ``key`` over rows with lo <= -eps_yy <= hi: the
    fluctuation is the standard deviation about a linear fit in ε (the drift is removed,
    so a sample still dilating does not pass for a noisy steady one), the drift is the
    fit's change across the window."""
    e = np.array([-r["eps_yy"] for r in rows if lo <= -r["eps_yy"] <= hi])
    x = np.array([r[key] for r in rows if lo <= -r["eps_yy"] <= hi])
    slope, icpt = np.polyfit(e, x, 1)
    return x.mean(), np.std(x - (slope * e + icpt), ddof=2), slope * (hi - lo)


@pytest.mark.slow
def test_dense_and_loose_biaxial_full_size():
    """Acceptance 4: N = 2000, μ = 0.5, κ = 1e4, γ̇_ref = 4e-4 (measured I <= 1e-3).

    Run to 50% axial strain: the dense sample localizes into a band along the cell diagonal
    after its peak and is still dilating at 25% (its c drifts by -0.004 over 15-25%), so
    the residual state is taken over 35-50%, where both samples are steady (drift below
    the fluctuation). Measured (seed 7, helper report of issue 2): see the printed line.
    """
    gdot = 4e-4
    ctl = {"L": {"yy": -1.0, "xy": 0.0, "yx": 0.0}, "sigma": {"xx": -1.0}}
    path = parse_path({"name": "biaxial_50", "stage": [
        dict(name="peak", length=0.02, output_every=0.0002, **ctl),
        dict(name="compress", length=0.48, output_every=0.0025, **ctl)]})
    runs = {}
    for name, mu_prep in (("dense", 0.0), ("loose", 0.5)):
        st = prepared(2000, mu_prep, seed=7, kappa=1e4)
        dyn = make_dynamics(st, kappa=1e4, mu=0.5, gdot=gdot)
        runner = PathRunner(path, dyn, gdot)
        runs[name] = runner.run(st, runner.start(st)).rows
    dense, loose = runs["dense"], runs["loose"]
    # the dense peak is resolved: several rows before it, and it stands above the residual
    k = int(np.argmax([r["RP"] for r in dense]))
    res = {n: {q: _steady(rows, q, 0.35, 0.5) for q in ("RP", "c")} for n, rows in runs.items()}
    print(f"\nacceptance 4: dense peak R/P {dense[k]['RP']:.3f} at eps_yy {dense[k]['eps_yy']:.4f}; "
          + "; ".join(f"{n} residual R/P {v['RP'][0]:.3f} ± {v['RP'][1]:.3f} (drift {v['RP'][2]:+.3f}), "
                      f"c {v['c'][0]:.4f} ± {v['c'][1]:.4f} (drift {v['c'][2]:+.4f})" for n, v in res.items())
          + f"; max I {max(r['I'] for r in dense[1:] + loose[1:]):.2e}")
    assert 3 <= k and -dense[k]["eps_yy"] < 0.02
    assert dense[k]["RP"] > res["dense"]["RP"][0] + 3 * res["dense"]["RP"][1]
    for q in ("RP", "c"):
        (md, fd, dd), (ml, fl, dl) = res["dense"][q], res["loose"][q]
        assert abs(dd) < fd and abs(dl) < fl                  # steady over the window
        assert abs(md - ml) < np.hypot(fd, fl)                 # same within the fluctuation
    assert max(r["I"] for r in dense[1:] + loose[1:]) <= 1e-3
    assert all(r["admissibility"] >= 0 for r in dense + loose)


@pytest.mark.slow
def test_simple_shear_reversal_full_size():
    st = prepared(1000, 0.0, seed=3)
    dyn = make_dynamics(st, kappa=1e3, mu=0.5, gdot=1e-3)
    runner = PathRunner(load_path("simple_shear_reversal"), dyn, 1e-3)
    rows = runner.run(st, runner.start(st)).rows
    fwd = [r for r in rows if r["stage"] == 0 and r["gamma"] > 0.5]
    rev = [r for r in rows if r["stage"] == 1 and r["gamma"] < -0.5]
    assert abs(np.mean([r["theta_p"] for r in fwd]) + np.pi / 4) < 0.3
    assert abs(np.mean([r["theta_p"] for r in rev]) - np.pi / 4) < 0.3
    assert all(r["admissibility"] >= 0 for r in rows)

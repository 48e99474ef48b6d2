"""The DEM's acceptance checks at reduced size (normal suite) and full size (slow).

Reduced: N = 150, κ = 1e3, I = 1e-2 (the session fixtures). These still fail if dense and
loose samples respond alike, if the fabric leaves the admissible set, or if the fabric
does not turn on reversal. Full size: N = 2000, κ = 1e4, I <= 1e-3, to 50% axial strain,
three seeds (acceptance 4), and simple shear with reversal (acceptance 5); figures in
docs/dem_validation.md.
"""
from dataclasses import replace

import numpy as np
import pytest

from conftest import make_dynamics, prepared
from dem.job import Settings, prepare_sample
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


SEEDS = (7, 11, 12)
RESIDUAL = (0.35, 0.5)
"""Residual window in axial strain -ε_yy (see the slow test's doc)."""


def _window_mean(rows, key, lo, hi):
    return float(np.mean([r[key] for r in rows if lo <= -r["eps_yy"] <= hi]))


def _biaxial_full_size(seed, mu_prep):
    """The standard biaxial path continued to 50% on a sample of ``contfab dem prepare
    --n 2000 --seed SEED --mu 0.5 --mu-prep MU_PREP --kappa 1e4``, at γ̇_ref = 5e-4."""
    settings = Settings(n=2000, seed=seed, kappa=1e4, mu=0.5, mu_prep=mu_prep, inertial=5e-4)
    st, dyn, _ = prepare_sample(settings, progress=False)
    base = load_path("biaxial")
    peak, compress = base.stages
    path = replace(base, stages=(peak, replace(compress, length=0.48, until=())))
    runner = PathRunner(path, dyn, dyn.gdot_ref)
    return runner.run(st, runner.start(st)).rows


@pytest.mark.slow
def test_dense_and_loose_reach_the_same_residual_state_full_size():
    """Acceptance 4: N = 2000, μ = 0.5, κ = 1e4, γ̇_ref = 5e-4 (measured I: mean 9e-4),
    biaxial to 50%, seeds 7, 11, 12, each dense (μ_prep = 0) and loose (μ_prep = 0.5).

    Residual R/P and c of a run: its mean over -ε_yy in [0.35, 0.5]. Over 15-25% the dense
    samples are not there yet: their band has reached the loose c but the rest of the cell
    is still denser, and their R/P is 0.02 above the loose one in every seed measured. The
    fluctuation is the seed-to-seed one: dense and loose agree when their seed means differ
    by less than two standard errors of the difference, sqrt(sd_d²/n + sd_l²/n). Figures
    and wall time: docs/dem_validation.md (acceptance 4).
    """
    runs = {"dense": [], "loose": []}
    for seed in SEEDS:
        for name, mu_prep in (("dense", 0.0), ("loose", 0.5)):
            rows = _biaxial_full_size(seed, mu_prep)
            assert all(r["admissibility"] >= 0 for r in rows)
            assert np.mean([r["I"] for r in rows[1:]]) <= 1e-3
            residual = {q: _window_mean(rows, q, *RESIDUAL) for q in ("RP", "c")}
            if name == "dense":
                # a resolved peak: several rows before it, inside the first 2%, well above
                # the residual; and the dense sample loosens towards the residual c
                k = int(np.argmax([r["RP"] for r in rows]))
                assert 3 <= k and -rows[k]["eps_yy"] < 0.02
                assert rows[k]["RP"] > residual["RP"] + 0.1
                assert rows[0]["c"] - residual["c"] > 0.015
            runs[name].append(residual)
    print(f"\nacceptance 4 residual over -eps_yy in {RESIDUAL}, seeds {SEEDS}")
    for q in ("RP", "c"):
        d = np.array([r[q] for r in runs["dense"]])
        lo = np.array([r[q] for r in runs["loose"]])
        se = np.hypot(d.std(ddof=1), lo.std(ddof=1)) / np.sqrt(len(SEEDS))
        print(f"  {q}: dense {d.mean():.4f} (seeds {np.round(d, 4)}), loose {lo.mean():.4f} "
              f"(seeds {np.round(lo, 4)}), difference {d.mean() - lo.mean():+.4f}, 2 se {2 * se:.4f}")
        assert abs(d.mean() - lo.mean()) < 2 * se


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

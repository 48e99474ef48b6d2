"""Seed 002 (acceptance 3): tr<F>_V = C̄ ν g2 on frictionless packings.

Normal suite: N = 300 uniform (w0 = 0.5) at ν = 0.90, tolerance 5% (finite-size
fluctuations ∝ 1/M, seed 002 §4.1). The full-size check (both distributions, ν = 0.85
and 0.90, 3%) is marked slow."""
import pytest

from dem.fabric_trace import fabric_trace, g2_nominal


def test_nominal_g2_of_the_seed_distributions():
    assert round(g2_nominal("bidisperse:3:0.5"), 3) == 1.223
    assert round(g2_nominal("uniform:0.5"), 3) == 1.085


def test_fabric_trace_small_uniform_packing():
    r = fabric_trace("uniform:0.5", 300, 0.90, seed=2, max_steps=300_000)
    assert r["relaxed"]
    assert abs(r["ratio"] - 1.0) < 0.05
    assert r["z_no_rattlers"] >= 3.9


@pytest.mark.slow
@pytest.mark.parametrize("radii, c", [("bidisperse:3:0.5", 0.86), ("bidisperse:3:0.5", 0.90),
                                      ("uniform:0.5", 0.85), ("uniform:0.5", 0.90)])
def test_fabric_trace_full_size(radii, c):
    r = fabric_trace(radii, 2000, c, seed=1, max_steps=600_000)
    assert abs(r["ratio_no_rattlers"] - 1.0) < 0.03
    assert r["z_no_rattlers"] >= 3.9

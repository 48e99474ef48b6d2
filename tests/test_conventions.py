"""The conventions of docs/theory.md §1–§2: invariants, fabric conversions, admissible set."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from contfab.fabric import A_EDGE, A_ISO_MAX, project_admissible
from contfab.tensors import from_principal, principal, rotate
from dem.conventions import (admissibility_margin, deviator_radius, fabric_polar, fabric_state,
                             fabric_tensor, pressure)
from dem.history import HISTORY_COLUMNS, history_row


def test_pressure_and_radius_tension_positive():
    assert pressure(-1.0, -3.0) == 2.0
    assert deviator_radius(-1.0, -3.0, 0.0) == 1.0


def test_fabric_of_discrete_normals_matches_fourier_coefficients():
    # p(θ) = A + B cos 2(θ - θp) sampled finely: F = ∫ p n⊗n dθ must give back (A, Bc, Bs).
    a, b, tp = 1.1, 0.4, 0.3
    th = (np.arange(20000) + 0.5) * np.pi / 20000
    p = a + b * np.cos(2 * (th - tp))
    w = np.pi / th.size
    f = [np.sum(p * np.cos(th) ** 2) * w, np.sum(p * np.sin(th) ** 2) * w,
         np.sum(p * np.cos(th) * np.sin(th)) * w]
    A, Bc, Bs = fabric_state(*f)
    B, theta = fabric_polar(Bc, Bs)
    assert (A, B, theta) == pytest.approx((a, b, tp), rel=1e-10)
    assert np.allclose(fabric_tensor(A, Bc, Bs), f, rtol=1e-12)


def test_admissible_triangle_vertices():
    assert admissibility_margin(A_EDGE, A_EDGE) == pytest.approx(0.0, abs=1e-14)
    assert admissibility_margin(A_ISO_MAX, 0.0) == pytest.approx(0.0, abs=1e-14)
    assert admissibility_margin(1.0, 0.2) > 0 and admissibility_margin(1.0, 1.01) < 0


@settings(max_examples=300, deadline=None)
@given(st.floats(-1, 3), st.floats(-3, 3), st.floats(-3, 3))
def test_projection_lands_inside_and_is_idempotent(a, bc, bs):
    pa, pbc, pbs, moved = project_admissible(a, bc, bs)
    assert admissibility_margin(pa, np.hypot(pbc, pbs)) >= 0.0      # exactly, not to round-off
    assert moved == (admissibility_margin(a, np.hypot(bc, bs)) < 0)
    again = project_admissible(pa, pbc, pbs)
    assert np.allclose(again[:3], (pa, pbc, pbs), atol=1e-12)
    if np.hypot(bc, bs) > 1e-9 and np.hypot(pbc, pbs) > 1e-9:   # θp kept
        assert np.arctan2(pbs, pbc) == pytest.approx(np.arctan2(bs, bc), abs=1e-9)


@settings(max_examples=200, deadline=None)
@given(st.floats(-5, 5), st.floats(-5, 5), st.floats(-5, 5), st.floats(-4, 4))
def test_principal_and_rotation_round_trip(sxx, syy, sxy, ang):
    s1, s2, th = principal(sxx, syy, sxy)
    assert s1 >= s2
    assert np.allclose(from_principal(s1, s2, th), (sxx, syy, sxy), atol=1e-12)
    r = rotate(sxx, syy, sxy, ang)
    assert pressure(r[0], r[1]) == pytest.approx(pressure(sxx, syy), abs=1e-12)
    assert deviator_radius(*r) == pytest.approx(deviator_radius(sxx, syy, sxy), abs=1e-12)
    assert np.allclose(rotate(*r, -ang), (sxx, syy, sxy), atol=1e-12)


def test_history_row_derived_columns():
    row = history_row(0, 0.1, (-0.8, -1.2, 0.0), (0.01, -0.03, 0.005), 0.8, (1.0, 0.1, 0.0))
    assert tuple(row) == HISTORY_COLUMNS
    assert row["P"] == pytest.approx(1.0) and row["RP"] == pytest.approx(0.2)
    assert row["eps_v"] == pytest.approx(-0.02) and row["gamma"] == pytest.approx(0.01)
    assert row["z"] == pytest.approx(np.pi) and row["B"] == pytest.approx(0.1)
    assert history_row(0, 0, (0, 0, 0), (0, 0, 0), 0.8)["RP"] == 0.0

"""Cell kinematics: the Cayley step of dh/dt = L h, widths, lattice reduction."""
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm

from dem.periodic_cell import area, cayley_step, needs_reduction, reduce_cell, widths


def test_cayley_step_is_second_order_in_dt():
    h0 = np.array([[10.0, 1.0], [0.5, 8.0]])
    L = np.array([[-0.3, 0.7], [0.2, 0.1]])
    errs = []
    for n in (10, 20, 40):
        h = h0.copy()
        for _ in range(n):
            h = cayley_step(h, L, 1.0 / n)
        errs.append(np.abs(h - expm(L) @ h0).max())
    rates = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(np.abs(rates - 2.0) < 0.1)


def test_pure_spin_keeps_area_exactly():
    h = np.array([[10.0, 2.0], [0.0, 10.0]])
    L = np.array([[0.0, -1.0], [1.0, 0.0]])
    for _ in range(1000):
        h = cayley_step(h, L, 0.01)
    assert abs(area(h) - 100.0) < 1e-10


@settings(max_examples=50, deadline=None)
@given(st.floats(-4, 4), st.floats(0.5, 2.0))
def test_reduction_keeps_lattice_and_area(gamma, aspect):
    h = np.array([[10.0, gamma * 10.0 * aspect], [0.0, 10.0 * aspect]])
    hr, u = reduce_cell(h)
    assert np.allclose(hr, h @ u) and round(np.linalg.det(u)) == 1
    assert np.isclose(area(hr), area(h))
    a1, a2 = hr[:, 0], hr[:, 1]
    assert abs(a1 @ a2) <= 0.5 * min(a1 @ a1, a2 @ a2) + 1e-9
    assert not needs_reduction(hr)


def test_simple_shear_to_gamma_one_is_reduced_back_to_a_fat_cell():
    h = np.array([[10.0, 10.0], [0.0, 10.0]])
    assert needs_reduction(h)
    hr, _ = reduce_cell(h)
    assert min(widths(hr)) > min(widths(h)) * 1.3

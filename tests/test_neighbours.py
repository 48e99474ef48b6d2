"""Verlet lists: complete against brute force, overflow grows the arrays, histories kept."""
import numpy as np
import pytest

from dem import neighbours
from dem.periodic_cell import CellError
from dem.state import new_state


def brute_force_pairs(st, skin):
    x = st.s
    out = set()
    for i in range(st.n):
        for j in range(i + 1, st.n):
            for a in (-2, -1, 0, 1, 2):
                for b in (-2, -1, 0, 1, 2):
                    d = st.h @ (x[j] + (a, b) - x[i])
                    if np.hypot(*d) < st.radius[i] + st.radius[j] + skin:
                        out.add((i, j, a, b))
    return out


@pytest.mark.parametrize("shear", [0.0, 0.45, -1.3])
def test_pair_list_is_the_brute_force_list_in_a_sheared_cell(shear):
    rng = np.random.default_rng(4)
    n = 60
    h = np.array([[7.0, shear * 6.0], [0.0, 6.0]])
    st = new_state(rng.uniform(0.3, 0.6, n), rng.uniform(-0.2, 1.2, (n, 2)), h)
    neighbours.rebuild(st, 0.3)
    listed = {(int(i), int(j), int(a), int(b)) for (i, j), (a, b)
              in zip(st.pair_ij[:st.n_pairs], st.pair_shift[:st.n_pairs])}
    assert listed == brute_force_pairs(st, 0.3)
    assert np.all((st.s >= 0) & (st.s < 1))


def test_overflow_grows_capacity_and_drops_nothing():
    rng = np.random.default_rng(5)
    st = new_state(np.full(200, 0.5), rng.random((200, 2)), np.diag([12.0, 12.0]))
    st.pair_ij = np.zeros((3, 2), np.int64)  # far too small a capacity
    neighbours.rebuild(st, 0.2)
    assert st.pair_ij.shape[0] >= st.n_pairs > 3
    assert st.n_pairs == len(brute_force_pairs(st, 0.2))


def test_histories_survive_a_rebuild_with_wrapping():
    rng = np.random.default_rng(6)
    st = new_state(np.full(40, 0.5), rng.random((40, 2)), np.diag([8.0, 8.0]))
    neighbours.rebuild(st, 0.3)
    key = lambda q: (int(st.pair_ij[q, 0]), int(st.pair_ij[q, 1]))  # noqa: E731
    st.pair_hist[:st.n_pairs, 0] = np.arange(st.n_pairs) + 1.0
    before = {key(q) + tuple(st.pair_shift[q] - st.image[st.pair_ij[q, 1]]
                             + st.image[st.pair_ij[q, 0]]): st.pair_hist[q, 0] for q in range(st.n_pairs)}
    st.s += 0.5  # every disc crosses half the cell: many wrap
    neighbours.rebuild(st, 0.3)
    after = {key(q) + tuple(st.pair_shift[q] - st.image[st.pair_ij[q, 1]]
                            + st.image[st.pair_ij[q, 0]]): st.pair_hist[q, 0] for q in range(st.n_pairs)}
    assert after == before


def test_cell_narrower_than_two_cutoffs_is_refused():
    st = new_state(np.full(2, 0.5), np.array([[0.2, 0.2], [0.7, 0.7]]), np.diag([2.0, 2.0]))
    with pytest.raises(CellError, match="too small"):
        neighbours.rebuild(st, 0.2)


def test_rebuild_in_a_skewed_cell_reduces_it_without_moving_any_disc():
    rng = np.random.default_rng(7)
    h = np.array([[9.0, 9.0], [0.0, 9.0]])          # simple shear to γ = 1
    st = new_state(np.full(50, 0.45), rng.random((50, 2)), h)
    x0 = st.positions()
    neighbours.rebuild(st, 0.3)
    assert not np.allclose(st.h, h) and np.isclose(st.volume, 81.0)
    x1 = st.positions()
    lat = np.linalg.solve(st.h, (x1 - x0).T).T          # displacement in lattice vectors
    assert np.allclose(lat, np.rint(lat), atol=1e-9)     # same discs, periodic images only
    listed = {(int(i), int(j), int(a), int(b)) for (i, j), (a, b)
              in zip(st.pair_ij[:st.n_pairs], st.pair_shift[:st.n_pairs])}
    assert listed == brute_force_pairs(st, 0.3)

"""Verlet neighbour lists built from cell lists, in a periodic (possibly sheared) cell.

A pair (i, j, shift) with i < j is listed when the image of j displaced by the integer
lattice vector ``shift`` lies within ri + rj + skin of i:

    l = h (s_j + shift - s_i),   |l| < ri + rj + skin.

Cell list: the unit square of reduced coordinates is cut into n1 x n2 bins with
nk = floor(wk / rc), wk the perpendicular width of the cell across lattice vector k and
rc = 2 r_max + skin, so every disc within rc of disc i lies in the 3 x 3 block of bins
around it (|Δs_k| <= |Δx| / wk). With fewer than three bins along a direction the
wrapped neighbour bins coincide but carry different image shifts, so every image is
still visited once. The cell must be at least 2 rc wide (no disc can touch its own
image).

The list stays valid while no unlisted pair can have come into contact:

    2 max_i |h (s_i - s_ref,i)| + ||h h_ref⁻¹ - I|| (2 r_max + skin) < skin

(displacements relative to the cell, plus the affine stretch of the cell itself), which
the integrator checks every step.

Rebuild (:func:`rebuild`): optionally reduce a skewed cell (:mod:`dem.periodic_cell`),
wrap s into [0, 1) (updating ``image`` and every stored shift), bin, list, and carry the
tangential histories over by matching (i, j, shift). The output arrays have a fixed
capacity; when a list would overflow it, the kernel reports the count it needs and
:func:`rebuild` grows the arrays and builds again — a pair is never dropped.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from dem.periodic_cell import CellError, needs_reduction, reduce_cell, widths
from dem.state import HIST, State

GROWTH = 1.3
"""Capacity of new pair arrays, relative to the count needed."""


@njit(cache=True)
def wrap(s, image, pair_ij, pair_shift, n_pairs):
    """Wrap s into [0, 1), count the wraps in ``image``, and fix the stored pair shifts."""
    n = s.shape[0]
    k = np.zeros((n, 2), np.int64)
    for i in range(n):
        for a in range(2):
            f = np.floor(s[i, a])
            k[i, a] = np.int64(f)
            s[i, a] -= f
            if s[i, a] >= 1.0:  # -1e-17 wraps to 1.0 in floating point
                s[i, a] -= 1.0
                k[i, a] += 1
            image[i, a] += k[i, a]
    for q in range(n_pairs):
        i, j = pair_ij[q, 0], pair_ij[q, 1]
        for a in range(2):
            pair_shift[q, a] += k[j, a] - k[i, a]


@njit(cache=True)
def _neighbour_bin(b, offset, nb):
    """(bin, image shift) of the bin ``offset`` away from ``b`` among ``nb`` periodic bins."""
    c = b + offset
    if c < 0:
        return c + nb, -1
    if c >= nb:
        return c - nb, 1
    return c, 0


@njit(cache=True)
def build_pairs(s, radius, h, skin, n1, n2, old_ij, old_shift, old_hist, old_row_ptr,
                new_ij, new_shift, new_hist, new_row_ptr):
    """List all pairs (see module doc) into the ``new_*`` arrays; return the count.

    ``s`` must be wrapped into [0, 1). Histories are copied from the old list where
    (i, j, shift) matches, zero otherwise. If the count exceeds the capacity of the new
    arrays nothing past the capacity is written and the full count is still returned.
    """
    n = s.shape[0]
    cap = new_ij.shape[0]
    nb = n1 * n2
    bin_of = np.empty(n, np.int64)
    count = np.zeros(nb + 1, np.int64)
    for i in range(n):
        b1 = min(int(s[i, 0] * n1), n1 - 1)
        b2 = min(int(s[i, 1] * n2), n2 - 1)
        bin_of[i] = b1 + n1 * b2
        count[bin_of[i] + 1] += 1
    for b in range(nb):
        count[b + 1] += count[b]
    members = np.empty(n, np.int64)
    fill = count[:nb].copy()
    for i in range(n):
        members[fill[bin_of[i]]] = i
        fill[bin_of[i]] += 1
    h00, h01, h10, h11 = h[0, 0], h[0, 1], h[1, 0], h[1, 1]
    m = 0
    for i in range(n):
        new_row_ptr[i] = m
        b1 = bin_of[i] % n1
        b2 = bin_of[i] // n1
        for o2 in range(-1, 2):
            c2, sh2 = _neighbour_bin(b2, o2, n2)
            for o1 in range(-1, 2):
                c1, sh1 = _neighbour_bin(b1, o1, n1)
                b = c1 + n1 * c2
                for k in range(count[b], count[b + 1]):
                    j = members[k]
                    if j <= i:
                        continue
                    ds1 = s[j, 0] + sh1 - s[i, 0]
                    ds2 = s[j, 1] + sh2 - s[i, 1]
                    lx = h00 * ds1 + h01 * ds2
                    ly = h10 * ds1 + h11 * ds2
                    rc = radius[i] + radius[j] + skin
                    if lx * lx + ly * ly < rc * rc:
                        if m < cap:
                            new_ij[m, 0] = i
                            new_ij[m, 1] = j
                            new_shift[m, 0] = sh1
                            new_shift[m, 1] = sh2
                            new_hist[m, :] = 0.0
                            for q in range(old_row_ptr[i], old_row_ptr[i + 1]):
                                if (old_ij[q, 1] == j and old_shift[q, 0] == sh1
                                        and old_shift[q, 1] == sh2):
                                    new_hist[m, :] = old_hist[q, :]
                                    break
                        m += 1
    new_row_ptr[n] = m
    return m


@njit(cache=True)
def incidence(pair_ij, n_pairs, n):
    """(inc_ptr, inc): for each disc the pairs ``q`` in which it is j, in pair order.

    A disc's pairs as i are rows ``row_ptr[i]..row_ptr[i+1]`` of the list itself (sorted
    by i); this index completes them, so a disc gathers its forces without scattered
    writes. It is derived from the list alone (:func:`dem.checkpoint.load` rebuilds it).
    """
    ptr = np.zeros(n + 1, np.int64)
    for q in range(n_pairs):
        ptr[pair_ij[q, 1] + 1] += 1
    for i in range(n):
        ptr[i + 1] += ptr[i]
    fill = ptr[:n].copy()
    inc = np.empty(max(n_pairs, 1), np.int64)
    for q in range(n_pairs):
        j = pair_ij[q, 1]
        inc[fill[j]] = q
        fill[j] += 1
    return ptr, inc


def bins(h: np.ndarray, cutoff: float) -> tuple[int, int]:
    """Bins along each lattice direction; raises if the cell is narrower than 2 cutoffs."""
    w1, w2 = widths(h)
    if min(w1, w2) < 2.0 * cutoff:
        raise CellError(f"periodic cell too small: width {min(w1, w2):.4g} < 2 x (largest "
                        f"diameter + skin) = {2 * cutoff:.4g}; use more discs or a larger cell")
    return int(w1 // cutoff), int(w2 // cutoff)


def rebuild(state: State, skin: float) -> State:
    """Rebuild the pair list of ``state`` in place (returns it); see the module doc."""
    if needs_reduction(state.h):
        h_new, u = reduce_cell(state.h)
        u_inv = np.rint(np.linalg.inv(u)).astype(np.int64)
        state.h = h_new
        state.s = np.ascontiguousarray(state.s @ u_inv.T)
        state.image = np.ascontiguousarray(state.image @ u_inv.T)
        n = state.n_pairs
        state.pair_shift[:n] = state.pair_shift[:n] @ u_inv.T
    wrap(state.s, state.image, state.pair_ij, state.pair_shift, state.n_pairs)
    n1, n2 = bins(state.h, 2.0 * float(state.radius.max()) + skin)
    cap = max(state.pair_ij.shape[0], 16)
    while True:
        new_ij = np.zeros((cap, 2), np.int64)
        new_shift = np.zeros((cap, 2), np.int64)
        new_hist = np.zeros((cap, HIST))
        new_row = np.empty(state.n + 1, np.int64)
        m = build_pairs(state.s, state.radius, state.h, skin, n1, n2, state.pair_ij,
                        state.pair_shift, state.pair_hist, state.row_ptr, new_ij, new_shift,
                        new_hist, new_row)
        if m <= cap:
            break
        cap = int(GROWTH * m) + 16
    state.pair_ij, state.pair_shift, state.pair_hist = new_ij, new_shift, new_hist
    state.pair_f = np.zeros((cap, 4))
    state.row_ptr, state.n_pairs = new_row, m
    state.inc_ptr, state.inc = incidence(new_ij, m, state.n)
    state.s_ref = state.s.copy()
    state.h_ref = state.h.copy()
    state.rebuilds += 1
    return state

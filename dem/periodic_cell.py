"""The periodic cell: a 2x2 matrix h whose columns a1, a2 are the lattice vectors.

A disc's position is x = h s with reduced coordinates s (the unit square is one cell).
The cell deforms homogeneously with the velocity gradient L (L_ij = ∂v_i/∂x_j):

    ḣ = L h.

Because positions are stored as s, a change of h moves every disc affinely: the whole
sample deforms, not a layer at the periodic boundary, so a stress servo cannot pin a
shear band at the boundary (docs/theory.md §11). Discs move relative to the affine field with
the fluctuation velocity v' = h ṡ; the full velocity is u = L x + v'.

One step of the cell uses the Cayley (Crank–Nicolson) map of ḣ = L h at constant L,

    h_{n+1} = (I - dt L/2)^{-1} (I + dt L/2) h_n,

second-order accurate and exactly orthogonal for a pure spin.

Large shears skew the cell and thin it; :func:`reduce_cell` then picks a shorter,
Gauss-reduced basis of the same lattice, h' = h U with U an integer unimodular matrix,
and reduced coordinates map as s' = U⁻¹ s. The configuration is unchanged (same
lattice, same positions), only its description.
"""
from __future__ import annotations

import numpy as np
from numba import njit


class CellError(ValueError):
    """A cell that cannot hold the sample; the message names the value and range."""


@njit(cache=True)
def cayley_step(h, L, dt):
    """h_{n+1} = (I - dt L/2)^{-1} (I + dt L/2) h_n for a 2x2 h and L."""
    a = 0.5 * dt
    m00, m01, m10, m11 = 1.0 - a * L[0, 0], -a * L[0, 1], -a * L[1, 0], 1.0 - a * L[1, 1]
    det = m00 * m11 - m01 * m10
    p00, p01, p10, p11 = 1.0 + a * L[0, 0], a * L[0, 1], a * L[1, 0], 1.0 + a * L[1, 1]
    i00, i01, i10, i11 = m11 / det, -m01 / det, -m10 / det, m00 / det
    c00 = i00 * p00 + i01 * p10
    c01 = i00 * p01 + i01 * p11
    c10 = i10 * p00 + i11 * p10
    c11 = i10 * p01 + i11 * p11
    out = np.empty((2, 2))
    out[0, 0] = c00 * h[0, 0] + c01 * h[1, 0]
    out[0, 1] = c00 * h[0, 1] + c01 * h[1, 1]
    out[1, 0] = c10 * h[0, 0] + c11 * h[1, 0]
    out[1, 1] = c10 * h[0, 1] + c11 * h[1, 1]
    return out


@njit(cache=True)
def cayley_det(L, dt):
    """det of the Cayley map: area ratio V_{n+1}/V_n = det(I + dt L/2) / det(I - dt L/2)."""
    a = 0.5 * dt
    dp = (1.0 + a * L[0, 0]) * (1.0 + a * L[1, 1]) - a * a * L[0, 1] * L[1, 0]
    dm = (1.0 - a * L[0, 0]) * (1.0 - a * L[1, 1]) - a * a * L[0, 1] * L[1, 0]
    return dp / dm


def area(h: np.ndarray) -> float:
    """Cell area V = det h (> 0 for a right-handed basis)."""
    return float(h[0, 0] * h[1, 1] - h[0, 1] * h[1, 0])


def widths(h: np.ndarray) -> tuple[float, float]:
    """Perpendicular widths (w1, w2): distance between opposite faces, w1 = V/|a2|."""
    v = abs(area(h))
    return v / float(np.hypot(*h[:, 1])), v / float(np.hypot(*h[:, 0]))


def square_cell(side: float) -> np.ndarray:
    return np.array([[side, 0.0], [0.0, side]])


def reduce_cell(h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gauss (Lagrange) reduction: (h', U) with h' = h U, |a1'·a2'| <= |a1'|²/2 <= |a2'|²/2.

    U is an integer matrix with det U = 1 (h' spans the same lattice, same handedness).
    """
    u = np.eye(2, dtype=np.int64)
    a = h.astype(float).copy()
    for _ in range(64):
        if a[:, 1] @ a[:, 1] < a[:, 0] @ a[:, 0]:
            a = a[:, ::-1].copy()
            u = u[:, ::-1].copy()
        k = int(np.rint((a[:, 0] @ a[:, 1]) / (a[:, 0] @ a[:, 0])))
        if k == 0:
            break
        a[:, 1] -= k * a[:, 0]
        u[:, 1] -= k * u[:, 0]
    if np.linalg.det(a) < 0:
        a[:, 1] *= -1.0
        u[:, 1] *= -1
    return h @ u, u


def needs_reduction(h: np.ndarray, tolerance: float = 0.6) -> bool:
    """True once the basis is skewed past Gauss-reduced by a margin (hysteresis).

    A reduced basis has |a1·a2| <= ½ min(|a1|², |a2|²); we reduce only when the ratio
    exceeds ``tolerance`` (> ½) so the basis does not flip back and forth.
    """
    a1, a2 = h[:, 0], h[:, 1]
    return abs(a1 @ a2) > tolerance * min(a1 @ a1, a2 @ a2)

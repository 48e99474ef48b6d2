"""Fabric algebra on the continuum side: the admissible set and its projection.

The conversions F <-> (A, Bc, Bs) <-> (A, B, θp) and the admissibility margin are
in :mod:`dem.conventions` (shared with the DEM). The admissible set of Roux & Radjaï 2001
eqs 1.14–1.15,

    0 <= B <= A,   (π/6) A + (√3/4) B <= 1,

is, in the (A, B) half-plane, the triangle with vertices O = (0, 0),
V1 = (A1, A1) with A1 = 1/(π/6 + √3/4) (on B = A) and V2 = (6/π, 0) (on B = 0).
It is invariant under a rotation of θp, so the Euclidean projection of a state
(A, Bc, Bs) onto it keeps θp and projects (A, B) onto the triangle.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from dem.conventions import admissibility_margin, fabric_polar  # noqa: F401  (re-exported)

A_EDGE = 1.0 / (np.pi / 6.0 + np.sqrt(3.0) / 4.0)
"""A at the vertex where B = A meets the steric bound (≈ 1.0454, z ≈ 3.28)."""
A_ISO_MAX = 6.0 / np.pi
"""Largest isotropic A (z = 6, hexagonal packing)."""


@njit(cache=True)
def _project_segment(x, y, ax, ay, bx, by):
    """Closest point to (x, y) on the segment from (ax, ay) to (bx, by)."""
    ex = bx - ax
    ey = by - ay
    t = ((x - ax) * ex + (y - ay) * ey) / (ex * ex + ey * ey)
    t = min(max(t, 0.0), 1.0)
    return ax + t * ex, ay + t * ey


@njit(cache=True)
def project_admissible(a, bc, bs):
    """Euclidean projection of (A, Bc, Bs) onto the admissible set.

    Returns (A, Bc, Bs, moved) with ``moved`` True when the input was outside
    (callers must report that: a projection changes the balance law's result).
    θp is kept; at B = 0 the direction is irrelevant. The result passes
    ``admissibility_margin >= 0`` exactly (nudged a few ulps inside if round-off put it out).
    """
    b = np.hypot(bc, bs)
    if admissibility_margin(a, b) >= 0.0:
        return a, bc, bs, False
    best_d = np.inf
    pa = 0.0
    pb = 0.0
    # The closest point of a convex polygon to an outside point lies on an edge.
    for k in range(3):
        if k == 0:
            qa, qb = _project_segment(a, b, 0.0, 0.0, A_EDGE, A_EDGE)
        elif k == 1:
            qa, qb = _project_segment(a, b, A_EDGE, A_EDGE, A_ISO_MAX, 0.0)
        else:
            qa, qb = _project_segment(a, b, A_ISO_MAX, 0.0, 0.0, 0.0)
        d = (qa - a) ** 2 + (qb - b) ** 2
        if d < best_d:
            best_d = d
            pa = qa
            pb = qb
    if b > 0.0:
        scale = pb / b
        pbc = bc * scale
        pbs = bs * scale
    else:
        pbc = 0.0
        pbs = 0.0
    # The closest point is on the boundary, where round-off can leave the margin a few ulps
    # negative: shrink B by 4 ulps and A by 2 (inward for both faces) until it passes; a
    # subnormal B (no ulps to spare) becomes 0.
    for _ in range(8):
        if admissibility_margin(pa, np.hypot(pbc, pbs)) >= 0.0:
            return pa, pbc, pbs, True
        pbc *= 1.0 - 2.0 ** -50
        pbs *= 1.0 - 2.0 ** -50
        pa *= 1.0 - 2.0 ** -51
    return min(max(pa, 0.0), A_ISO_MAX * (1.0 - 2.0 ** -50)), 0.0, 0.0, True

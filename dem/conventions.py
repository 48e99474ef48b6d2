"""The conventions of docs/theory.md §1–§2, in one place for the DEM and the continuum.

Tension is positive. For a 2x2 symmetric stress (sxx, syy, sxy):

    P = -(sxx + syy)/2            (pressure, >= 0 in compression)
    R = sqrt(((sxx - syy)/2)^2 + sxy^2)   (deviator radius)
    R/P = sin(phi_mob)            (mobilized friction)

Fabric. Contact normals are counted per particle, p(θ) = A + B cos 2(θ - θp) on
[0, π), ∫ p dθ = z, A = z/π. The per-particle fabric tensor F = (1/N) Σ n⊗n (each
contact counted from both sides, tr F = z) relates to the state (A, Bc, Bs) =
(A, B cos 2θp, B sin 2θp) by

    F = (πA/2) I + (π/4) [[Bc, Bs], [Bs, -Bc]]
    A = tr F / π,   Bc = (4/π) F'xx,   Bs = (4/π) F'xy.

Admissible fabrics (Roux & Radjaï 2001, eqs 1.14–1.15): 0 <= B <= A and (π/6) A + (√3/4) B <= 1.

Every function is a numba ``njit`` that accepts scalars or equally shaped arrays, so
numba kernels and plain Python share the same formula. Angles are in radians.
"""
from __future__ import annotations

import numpy as np
from numba import njit

SQRT3_4 = np.sqrt(3.0) / 4.0


@njit(cache=True)
def pressure(sxx, syy):
    """P = -(sxx + syy)/2 (tension positive, so P >= 0 in compression)."""
    return -0.5 * (sxx + syy)


@njit(cache=True)
def deviator_radius(sxx, syy, sxy):
    """R = sqrt(((sxx - syy)/2)^2 + sxy^2): radius of Mohr's circle."""
    return np.sqrt((0.5 * (sxx - syy)) ** 2 + sxy**2)


@njit(cache=True)
def fabric_state(fxx, fyy, fxy):
    """(A, Bc, Bs) from the per-particle fabric tensor F (tr F = z)."""
    a = (fxx + fyy) / np.pi
    bc = (2.0 / np.pi) * (fxx - fyy)
    bs = (4.0 / np.pi) * fxy
    return a, bc, bs


@njit(cache=True)
def fabric_tensor(a, bc, bs):
    """(Fxx, Fyy, Fxy) from (A, Bc, Bs): the inverse of :func:`fabric_state`."""
    iso = 0.5 * np.pi * a
    return iso + 0.25 * np.pi * bc, iso - 0.25 * np.pi * bc, 0.25 * np.pi * bs


@njit(cache=True)
def fabric_polar(bc, bs):
    """(B, θp) from (Bc, Bs); θp in (-π/2, π/2], and θp = 0 at B = 0."""
    return np.hypot(bc, bs), 0.5 * np.arctan2(bs, bc)


@njit(cache=True)
def admissibility_margin(a, b):
    """min(A - B, 1 - (π/6)A - (√3/4)B, B): >= 0 exactly when (A, B) is admissible.

    The last term only guards against a negative B given directly; B derived
    from (Bc, Bs) is never negative.
    """
    return np.minimum(np.minimum(a - b, 1.0 - (np.pi / 6.0) * a - SQRT3_4 * b), b)

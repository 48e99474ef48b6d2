"""2x2 symmetric tensor algebra in the Voigt form used by the model and the FEM.

Conventions (docs/theory.md §1): tension positive; stress in Voigt form
``s = (sxx, syy, sxy)``; strain in Voigt form with *engineering* shear
``e = (exx, eyy, gxy)``, gxy = 2 exy, so that the work is ``s · e`` and a tangent
``D = ∂s/∂e`` is the 3x3 matrix the FEM assembles. Spin increment
``dw = (L_yx - L_xy)/2 · dt`` (counter-clockwise positive). Angles in radians.

P and R live in :mod:`dem.conventions` (one place for both the DEM and the model).
All functions are numba ``njit`` and take scalars, so kernels inline them.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from contfab.jit_flags import KERNEL


@njit(**KERNEL, inline="always")
def hypot(x, y):
    """sqrt(x² + y²) without overflow or underflow, fast: a plain sqrt of the sum of squares
    where that sum is well inside the normal range (within an ulp of np.hypot: 2.2e-16
    relative at most over 1e6 random pairs, measured), np.hypot elsewhere (tiny or huge
    values, NaN, inf). glibc's hypot costs ~30 ns of latency, the plain path ~10 ns
    (measured here); the tier-2 update takes about forty per point."""
    s = x * x + y * y
    if 1e-290 < s < 1e290:
        return np.sqrt(s)
    return np.hypot(x, y)


@njit(cache=True)
def principal(sxx, syy, sxy):
    """(s1, s2, angle): principal values s1 >= s2 and the direction of s1 from x.

    s1,2 = (sxx + syy)/2 ± R; angle = atan2(2 sxy, sxx - syy)/2 in (-π/2, π/2]
    (0 for an isotropic tensor).
    """
    mean = 0.5 * (sxx + syy)
    r = np.sqrt((0.5 * (sxx - syy)) ** 2 + sxy**2)
    return mean + r, mean - r, 0.5 * np.arctan2(2.0 * sxy, sxx - syy)


@njit(cache=True)
def from_principal(s1, s2, angle):
    """(sxx, syy, sxy) of the tensor with principal values s1, s2, s1 along ``angle``."""
    mean = 0.5 * (s1 + s2)
    half = 0.5 * (s1 - s2)
    c2 = np.cos(2.0 * angle)
    s2a = np.sin(2.0 * angle)
    return mean + half * c2, mean - half * c2, half * s2a


@njit(cache=True)
def rotate(sxx, syy, sxy, angle):
    """Components of Q s Qᵀ, Q the rotation by ``angle`` (counter-clockwise).

    The mean is unchanged and the deviator (dxx, sxy) turns by 2·angle.
    """
    mean = 0.5 * (sxx + syy)
    d = 0.5 * (sxx - syy)
    c2 = np.cos(2.0 * angle)
    s2a = np.sin(2.0 * angle)
    dn = c2 * d - s2a * sxy
    return mean + dn, mean - dn, s2a * d + c2 * sxy


@njit(cache=True)
def isotropic_stiffness_into(bulk, shear, out):
    """Write the 3x3 Voigt matrix of the 2D isotropic law s = K tr(e) I + 2G dev(e) into ``out``.

    With engineering shear: D = [[K+G, K-G, 0], [K-G, K+G, 0], [0, 0, G]].
    Allocation-free form for kernels that fill a preallocated tangent.
    """
    out[:, :] = 0.0
    out[0, 0] = bulk + shear
    out[1, 1] = bulk + shear
    out[0, 1] = bulk - shear
    out[1, 0] = bulk - shear
    out[2, 2] = shear


@njit(cache=True)
def isotropic_stiffness(bulk, shear):
    """3x3 Voigt matrix of the 2D isotropic law (see :func:`isotropic_stiffness_into`)."""
    d = np.empty((3, 3))
    isotropic_stiffness_into(bulk, shear, d)
    return d

"""The history columns that the DEM cell and the material point both write.

One row per output step, so a DEM curve and a model curve on the same loading
path overlay column by column. Stress in units of P0, tension positive; strain
ε = ∫ D dt (D = sym L), so ε_v = tr ε = ln(V/V0) and c = c0 exp(-ε_v).

=========  ===================================================================
stage      index of the stage in the path (0-based)
tau        reference strain τ since the path start (dτ = γ̇_ref dt)
sxx..sxy   Cauchy stress
P, R, RP   pressure, deviator radius, R/P (see :mod:`dem.conventions`)
eps_*      accumulated strain components; eps_v = eps_xx + eps_yy (dilation > 0)
gamma      engineering shear strain 2·eps_xy
c          packing fraction
z          coordination number (contacts per particle, rattlers included: z = πA)
A, Bc, Bs  fabric state; B, theta_p derived (theta_p in radians)
=========  ===================================================================

Fabric columns are empty for a model tier that carries no fabric. Drivers may
append columns of their own after these.
"""
from __future__ import annotations

import math

from dem.conventions import deviator_radius, fabric_polar, pressure

HISTORY_COLUMNS = ("stage", "tau", "sxx", "syy", "sxy", "P", "R", "RP",
                   "eps_xx", "eps_yy", "eps_xy", "eps_v", "gamma",
                   "c", "z", "A", "Bc", "Bs", "B", "theta_p")


def history_row(stage: int, tau: float, stress, strain, c: float,
                fabric=None) -> dict[str, float | int | None]:
    """One history row from the base quantities.

    ``stress`` and ``strain`` are (xx, yy, xy) triples (tensor shear, not
    engineering); ``fabric`` is (A, Bc, Bs) or None. R/P is 0 at P = 0 (a
    separated, stress-free state) rather than undefined.
    """
    sxx, syy, sxy = (float(v) for v in stress)
    exx, eyy, exy = (float(v) for v in strain)
    p = float(pressure(sxx, syy))
    r = float(deviator_radius(sxx, syy, sxy))
    row = {"stage": int(stage), "tau": float(tau), "sxx": sxx, "syy": syy, "sxy": sxy,
           "P": p, "R": r, "RP": r / p if p > 0.0 else 0.0,
           "eps_xx": exx, "eps_yy": eyy, "eps_xy": exy, "eps_v": exx + eyy, "gamma": 2.0 * exy,
           "c": float(c), "z": None, "A": None, "Bc": None, "Bs": None, "B": None,
           "theta_p": None}
    if fabric is not None:
        a, bc, bs = (float(v) for v in fabric)
        b, theta = fabric_polar(bc, bs)
        row.update(z=math.pi * a, A=a, Bc=bc, Bs=bs, B=float(b), theta_p=float(theta))
    return row

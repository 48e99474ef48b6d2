"""One measurement of a contact network, applied alike to the DEM and to LAMMPS.

Input: disc centres x (n, 2), radii, the cell h (columns = cell vectors), and the
contacts as index pairs (i, j) with the force on i (f_i, whole: normal plus tangential).
Branch vectors l = xj - xi are taken at the nearest periodic image; n = l/|l|,
t = (-ny, nx), fn = -f·n (> 0 in compression), ft = f·t. Then, tension positive:

* contact stress σ = (1/V) Σ f ⊗ l (symmetrized; the kinetic part is left out in both
  engines, so the sum is the same one), P = -(σxx + σyy)/2, R/P (:mod:`dem.conventions`);
* z = 2 Nc / N; z* = 2 Nc* / N* without rattlers (discs with fewer than 2 contacts,
  removed repeatedly, :func:`dem.measure.rattler_mask`);
* fabric F = (1/N) Σ_discs Σ_contacts n⊗n -> (A, Bc, Bs), B = |(Bc, Bs)|, and B/A;
* sliding fraction: contacts with |ft| >= (1 - SLIDE_TOL) μ fn, and the same with the
  strict tolerance 1e-3 (``sliding_strict``). Both engines give the forces of the step's
  force evaluation, where the Coulomb cap |ft| <= μ fn is applied (LAMMPS's read with the
  velocities of that evaluation: :mod:`contfab.verify.lammps_engine`, (m)), so contacts
  that slid at the step sit on the bound in both;
* packing fraction c = Σ π r² / V.
"""
from __future__ import annotations

import numpy as np

from dem.conventions import deviator_radius, fabric_polar, fabric_state, pressure
from dem.measure import fabric_tensor, rattler_mask

SLIDE_TOL = 1e-2
MEASURES = ("sxx", "syy", "sxy", "P", "RP", "c", "z", "z_no_rattlers", "A", "B", "BA",
            "sliding_fraction", "sliding_strict")


def contact_measures(x, radius, h, i, j, f_i, mu: float) -> dict:
    """The measures of the module doc (a dict keyed by :data:`MEASURES`)."""
    n = radius.shape[0]
    vol = float(h[0, 0] * h[1, 1] - h[0, 1] * h[1, 0])
    ds = (x[j] - x[i]) @ np.linalg.inv(h).T
    ds -= np.round(ds)
    lvec = ds @ h.T
    nvec = lvec / np.hypot(lvec[:, 0], lvec[:, 1])[:, None]
    fn = -np.einsum("ij,ij->i", f_i, nvec)
    ft = f_i[:, 1] * nvec[:, 0] - f_i[:, 0] * nvec[:, 1]
    sxx = float(np.sum(f_i[:, 0] * lvec[:, 0])) / vol
    syy = float(np.sum(f_i[:, 1] * lvec[:, 1])) / vol
    sxy = float(0.5 * np.sum(f_i[:, 0] * lvec[:, 1] + f_i[:, 1] * lvec[:, 0])) / vol
    p = float(pressure(sxx, syy))
    ratt = rattler_mask(n, i, j, 2)
    keep = ~(ratt[i] | ratt[j])
    n_act = int(n - ratt.sum())
    a, bc, bs = fabric_state(*fabric_tensor(nvec, n))
    b, _ = fabric_polar(bc, bs)
    ratio = np.abs(ft) / np.maximum(mu * fn, 1e-300)
    return {"sxx": sxx, "syy": syy, "sxy": sxy, "P": p,
            "RP": float(deviator_radius(sxx, syy, sxy)) / p if p > 0 else 0.0,
            "c": float(np.pi * np.sum(radius**2) / vol), "z": 2.0 * i.shape[0] / n,
            "z_no_rattlers": 2.0 * int(keep.sum()) / n_act if n_act else 0.0,
            "A": float(a), "B": float(b), "BA": float(b / a) if a > 0 else 0.0,
            "sliding_fraction": float(np.mean(ratio >= 1.0 - SLIDE_TOL)) if ratio.size else 0.0,
            "sliding_strict": float(np.mean(ratio >= 1.0 - 1e-3)) if ratio.size else 0.0}

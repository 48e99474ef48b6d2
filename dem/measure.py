"""Measurements on a DEM state (DESIGN §6): stress, packing, coordination, fabric,
force networks, energies, control numbers, homogeneity.

Conventions (DESIGN §2–§3, :mod:`dem.conventions`): tension positive. A contact is a
listed pair with overlap δ > 0; its branch vector is l = xj - xi, normal n = l/|l|, and
f the force on i (the forces of the last step, so the stress here is the one the servo
saw).

* Love–Weber stress  σ = (1/V) Σ_contacts f ⊗ l  - (1/V) Σ_discs m v'⊗v'  (kinetic part),
  symmetrized; P = -(σxx+σyy)/2 > 0 in compression.
* Coordination z = 2 Nc / N (rattlers included, z = πA); without rattlers: discs with
  fewer than 2 contacts (3 when frictionless, μ = 0) are removed repeatedly, then
  z* = 2 Nc* / N*.
* Fabric per particle F = (1/N) Σ_discs Σ_their contacts n⊗n (tr F = z) ->
  (A, Bc, Bs) by :func:`dem.conventions.fabric_state`.
* Volume-weighted fabric of seed 002 eq. (3): <F>_V = (1/V) Σ_p π r_p² Σ_{c∈p} n⊗n.
* Sliding fraction: contacts with |ft| >= (1 - 1e-9) μ fn (all contacts when μ = 0).
* Strong / weak network: contacts with fn above / not above the mean normal force.
* Force anisotropy (Rothenburg & Bathurst 1989): the mean contact forces per direction θ
  of the normal n = (cos θ, sin θ), in their second-order Fourier form,

      f̄n(θ) = f0 [1 + a_n cos 2(θ - θn)],      f̄t(θ) = -f0 a_t sin 2(θ - θt),

  fitted by least squares over the contacts (:func:`force_anisotropy`; exact whenever the
  forces follow that form, whatever the distribution of the normals). They are the
  components of the force on j, -f = fn n + (-ft) t, with t = (-sin θ, cos θ), fn = -f·n
  (> 0 in compression) and ft = f·t as in :class:`Contacts`. a_n, a_t >= 0; θn, θt in
  (-π/2, π/2] like θp: θn is the direction of the largest normal forces. To first order in the anisotropies the stress
  deviator, with the compressive major principal direction θσ, is

      (R/P) (cos 2θσ, sin 2θσ) ≈ ½ Σ_k a_k (cos 2θk, sin 2θk),   k ∈ {c, n, t},

  a_c = B/A and θc = θp (the contact density p(θ)/(πA) = (1/π)[1 + a_c cos 2(θ - θp)]);
  coaxial, R/P ≈ (a_c + a_n + a_t)/2.
* Energies: elastic Σ ½ kn δ² + ½ kt ξt² + ½ kr ξr² (kr = kt r_eff²), kinetic
  Σ ½ m v'² + ½ I ω², and the accumulators (external work V σ:L dt, damping, friction
  and rolling dissipation); balance error = (elastic + kinetic + dissipated - work) minus
  its initial value.
* Inertial number I = γ̇ d sqrt(ρ/P) with γ̇ = |ε̇1 - ε̇2| (the shear rate of D = sym L),
  stiffness number κ = kn / P.
* Homogeneity: the cell is cut into G x G cells of the reduced coordinates at a reference
  state (G = max(2, floor(sqrt(N/64))), about 64 discs each); in each the local strain
  increment since the reference is the least-squares affine fit of the disc displacements,
  Δu ≈ A (x - x̄) + b, and its shear Δγ = 2 sqrt(((ΔExx - ΔEyy)/2)² + ΔExy²), ΔE = sym A.
  The localization index is the coefficient of variation (standard deviation over mean)
  of Δγ across the cells: 0 for an affine deformation, about 0.4–0.5 for the granular
  noise of a homogeneous flow of N = 2000 discs over 0.2–1% strain, sqrt(G - 1) when all
  the shear sits in one row of cells, and it sees a band of any orientation (a band along
  the cell's diagonal, common in biaxial tests, crosses every row and column of cells,
  so binning by one coordinate would average it out).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from dem.contact_law import ContactLaw
from dem.conventions import fabric_polar, fabric_state
from dem.state import ACC_NAMES, State


@njit(cache=True)
def branch_vectors(s, h, radius, pair_ij, pair_shift, n_pairs):
    """(n_pairs, 3): branch vector (lx, ly) and overlap δ of every listed pair."""
    out = np.empty((n_pairs, 3))
    for q in range(n_pairs):
        i, j = pair_ij[q, 0], pair_ij[q, 1]
        d0 = s[j, 0] + pair_shift[q, 0] - s[i, 0]
        d1 = s[j, 1] + pair_shift[q, 1] - s[i, 1]
        lx = h[0, 0] * d0 + h[0, 1] * d1
        ly = h[1, 0] * d0 + h[1, 1] * d1
        out[q, 0] = lx
        out[q, 1] = ly
        out[q, 2] = radius[i] + radius[j] - math.sqrt(lx * lx + ly * ly)
    return out


class Contacts:
    """The active contacts of a state, as flat arrays (one entry per contact)."""

    def __init__(self, state: State):
        n = state.n_pairs
        g = branch_vectors(state.s, state.h, state.radius, state.pair_ij, state.pair_shift, n)
        on = g[:, 2] > 0.0
        self.i = state.pair_ij[:n, 0][on]
        self.j = state.pair_ij[:n, 1][on]
        self.l = g[on, :2]
        self.delta = g[on, 2]
        dist = np.hypot(self.l[:, 0], self.l[:, 1])
        self.n = self.l / dist[:, None]
        t = np.stack([-self.n[:, 1], self.n[:, 0]], axis=1)
        f = state.pair_f[:n, :2][on]
        self.f = f
        self.fn = -np.einsum("ij,ij->i", f, self.n)
        self.ft = np.einsum("ij,ij->i", f, t)
        self.xi = state.pair_hist[:n, :2][on]
        self.count = int(on.sum())


def rattler_mask(n: int, i: np.ndarray, j: np.ndarray, min_contacts: int) -> np.ndarray:
    """(n,) bool: discs left with fewer than ``min_contacts`` contacts after repeatedly
    removing such discs and their contacts."""
    keep = np.ones(i.shape[0], bool)
    ratt = np.zeros(n, bool)
    while True:
        deg = np.bincount(i[keep], minlength=n) + np.bincount(j[keep], minlength=n)
        new = (deg < min_contacts) & ~ratt
        if not new.any():
            return ratt
        ratt |= new
        keep &= ~(ratt[i] | ratt[j])


def force_anisotropy(normals: np.ndarray, fn: np.ndarray, ft: np.ndarray) -> dict:
    """f0, a_n, θn, a_t, θt of the module doc: least squares of fn and -ft on
    (1, cos 2θ, sin 2θ) over the contacts.

    An assembly without compressive forces (fewer than 3 contacts or f0 <= 0: a gas)
    has no force anisotropy and gets zeros.
    """
    out = {"f0": 0.0, "a_n": 0.0, "theta_n": 0.0, "a_t": 0.0, "theta_t": 0.0}
    if fn.shape[0] < 3:
        return out
    nx, ny = normals[:, 0], normals[:, 1]
    # cos 2θ, sin 2θ of the unit normals
    design = np.stack([np.ones_like(nx), nx * nx - ny * ny, 2.0 * nx * ny], axis=1)
    (f0, pn, qn), (_, pt, qt) = np.linalg.lstsq(design, np.stack([fn, -ft], axis=1),
                                                 rcond=None)[0].T
    if not f0 > 0.0:
        return out
    # f0 a_n cos 2(θ - θn) = pn cos 2θ + qn sin 2θ;  -f0 a_t sin 2(θ - θt) = pt cos 2θ + qt sin 2θ
    out.update(f0=float(f0), a_n=float(math.hypot(pn, qn) / f0),
               theta_n=float(0.5 * math.atan2(qn, pn)),
               a_t=float(math.hypot(pt, qt) / f0), theta_t=float(0.5 * math.atan2(pt, -qt)))
    return out


def fabric_tensor(normals: np.ndarray, n_discs: int) -> np.ndarray:
    """F = (1/N) Σ_discs Σ_contacts n⊗n = (2/N) Σ_contacts n⊗n: (Fxx, Fyy, Fxy)."""
    if n_discs == 0:
        return np.zeros(3)
    nx, ny = normals[:, 0], normals[:, 1]
    return 2.0 / n_discs * np.array([np.sum(nx * nx), np.sum(ny * ny), np.sum(nx * ny)])


def normal_histogram(normals: np.ndarray, n_discs: int, bins: int = 36):
    """(θ centres, p(θ)) on [0, π): contacts per disc per radian (∫ p dθ = z)."""
    theta = np.mod(np.arctan2(normals[:, 1], normals[:, 0]), np.pi)
    counts, edges = np.histogram(theta, bins=bins, range=(0.0, np.pi))
    width = edges[1] - edges[0]
    return 0.5 * (edges[1:] + edges[:-1]), 2.0 * counts / (max(n_discs, 1) * width)


def g2_exact(radius: np.ndarray) -> float:
    """Seed 002 eq. (12) for the empirical distribution of ``radius``:

        g2 = <a² / φ(a)> / (<1/φ(a)> <a²>),   φ(a) = arcsin(ā / (a + ā)).
    """
    a = np.asarray(radius, float)
    abar = a.mean()
    inv_phi = 1.0 / np.arcsin(abar / (a + abar))
    return float(np.mean(a * a * inv_phi) / (np.mean(inv_phi) * np.mean(a * a)))


def elastic_energy(state: State, law: ContactLaw, contacts: Contacts | None = None) -> float:
    c = contacts or Contacts(state)
    ri, rj = state.radius[c.i], state.radius[c.j]
    reff = ri * rj / (ri + rj)
    return float(0.5 * law.kn * np.sum(c.delta**2) + 0.5 * law.kt * np.sum(c.xi[:, 0] ** 2)
                 + 0.5 * law.kt * np.sum(reff**2 * c.xi[:, 1] ** 2))


def kinetic_energy(state: State, exclude: np.ndarray | None = None) -> float:
    """Σ ½ m v'² + ½ I ω² (over the discs not flagged in ``exclude``)."""
    inertia = 1.0 / state.inv_inertia
    e = 0.5 * np.sum(state.mass[:, None] * state.v**2, axis=1) + 0.5 * inertia * state.omega**2
    return float(e.sum() if exclude is None else e[~exclude].sum())


def energies(state: State, law: ContactLaw, contacts: Contacts | None = None) -> dict:
    """Stored, kinetic, accumulated work and dissipation; ``total`` = stored + kinetic +
    dissipated - work (constant for an exact integrator)."""
    e_el = elastic_energy(state, law, contacts)
    e_k = kinetic_energy(state)
    acc = dict(zip(ACC_NAMES, state.acc))
    dissipated = acc["d_damp"] + acc["d_fric"] + acc["d_roll"]
    return {"E_elastic": e_el, "E_kinetic": e_k, "W_external": acc["work"],
            "D_damping": acc["d_damp"], "D_friction": acc["d_fric"], "D_rolling": acc["d_roll"],
            "E_total": e_el + e_k + dissipated - acc["work"]}


def love_weber(state: State, contacts: Contacts | None = None) -> np.ndarray:
    """(sxx, syy, sxy): contact part plus kinetic part, tension positive, symmetrized."""
    c = contacts or Contacts(state)
    mv = state.mass[:, None] * state.v
    sxx = np.sum(c.f[:, 0] * c.l[:, 0]) - np.sum(mv[:, 0] * state.v[:, 0])
    syy = np.sum(c.f[:, 1] * c.l[:, 1]) - np.sum(mv[:, 1] * state.v[:, 1])
    sxy = 0.5 * np.sum(c.f[:, 0] * c.l[:, 1] + c.f[:, 1] * c.l[:, 0]) - np.sum(mv[:, 0] * state.v[:, 1])
    return np.array([sxx, syy, sxy]) / state.volume


def localization_grid(n: int) -> int:
    """G: cells per direction of the homogeneity grid (about 64 discs per cell, G >= 2)."""
    return max(2, int(math.sqrt(n / 64.0)))


def local_shear(s_unwrapped_ref: np.ndarray, h_ref: np.ndarray, s_unwrapped: np.ndarray,
                h: np.ndarray, grid: int) -> np.ndarray:
    """(grid², ) shear increment Δγ of each cell between two states (see the module doc)."""
    x0 = s_unwrapped_ref @ h_ref.T
    du = s_unwrapped @ h.T - x0
    b = np.floor(np.mod(s_unwrapped_ref, 1.0) * grid).astype(np.int64).clip(0, grid - 1)
    cell = b[:, 0] + grid * b[:, 1]
    nc = grid * grid
    count = np.maximum(np.bincount(cell, minlength=nc), 1)
    mean = lambda w: np.bincount(cell, weights=w, minlength=nc) / count  # noqa: E731
    xc = x0 - np.stack([mean(x0[:, 0]), mean(x0[:, 1])], axis=1)[cell]
    # normal equations per cell: M A^T = C with M = Σ xc xc^T, C = Σ xc du^T
    mxx, mxy, myy = mean(xc[:, 0] ** 2), mean(xc[:, 0] * xc[:, 1]), mean(xc[:, 1] ** 2)
    det = mxx * myy - mxy * mxy
    grad = np.empty((nc, 2, 2))                      # grad[g, a, b] = ∂u_a/∂x_b
    for a in range(2):
        cx, cy = mean(xc[:, 0] * du[:, a]), mean(xc[:, 1] * du[:, a])
        grad[:, a, 0] = (myy * cx - mxy * cy) / det
        grad[:, a, 1] = (mxx * cy - mxy * cx) / det
    exy = 0.5 * (grad[:, 0, 1] + grad[:, 1, 0])
    return 2.0 * np.hypot(0.5 * (grad[:, 0, 0] - grad[:, 1, 1]), exy)


def localization_index(state: State, s_unwrapped_ref: np.ndarray, h_ref: np.ndarray) -> float:
    """Coefficient of variation of the local shear since the reference (module doc)."""
    g = local_shear(s_unwrapped_ref, h_ref, state.s + state.image, state.h,
                    localization_grid(state.n))
    m = float(g.mean())
    return float(g.std() / m) if m > 1e-14 else 0.0


def measure(state: State, law: ContactLaw, strain_rate: np.ndarray | None = None) -> dict:
    """All scalar measurements of DESIGN §6 at the current state (a flat dict)."""
    c = Contacts(state)
    n = state.n
    sxx, syy, sxy = love_weber(state, c)
    p = -0.5 * (sxx + syy)
    fab = fabric_tensor(c.n, n)
    a, bc, bs = fabric_state(*fab)
    frictionless = law.mu == 0.0
    ratt = rattler_mask(n, c.i, c.j, 3 if frictionless else 2)
    keep = ~(ratt[c.i] | ratt[c.j])
    n_act = int(n - ratt.sum())
    per_disc = np.zeros((n, 3))
    nn = np.stack([c.n[:, 0] ** 2, c.n[:, 1] ** 2, c.n[:, 0] * c.n[:, 1]], axis=1)
    np.add.at(per_disc, c.i, nn)
    np.add.at(per_disc, c.j, nn)
    fv = (np.pi * state.radius**2) @ per_disc / state.volume
    if frictionless:
        sliding = 1.0
    else:
        sliding = float(np.mean(np.abs(c.ft) >= (1.0 - 1e-9) * law.mu * c.fn)) if c.count else 0.0
    strong = c.fn > c.fn.mean() if c.count else np.zeros(0, bool)
    fab_s = fabric_tensor(c.n[strong], n)
    a_s, bc_s, bs_s = fabric_state(*fab_s)
    fab_w = fabric_tensor(c.n[~strong], n)
    a_w, bc_w, bs_w = fabric_state(*fab_w)
    p_strong = -0.5 * np.sum(c.f[strong] * c.l[strong]) / state.volume
    out = {"sxx": sxx, "syy": syy, "sxy": sxy, "P": p,
           "c": state.packing_fraction, "z": 2.0 * c.count / n,
           "z_no_rattlers": 2.0 * int(keep.sum()) / n_act if n_act else 0.0,
           "rattler_fraction": float(ratt.mean()),
           "A": float(a), "Bc": float(bc), "Bs": float(bs),
           "trF_V": float(fv[0] + fv[1]), "F_V_xx": float(fv[0]), "F_V_yy": float(fv[1]),
           "F_V_xy": float(fv[2]),
           "sliding_fraction": sliding,
           "strong_fraction": float(strong.mean()) if c.count else 0.0,
           "P_strong_share": float(p_strong / p) if p > 0 else 0.0,
           "B_strong": float(fabric_polar(bc_s, bs_s)[0]), "A_strong": float(a_s),
           "B_weak": float(fabric_polar(bc_w, bs_w)[0]), "A_weak": float(a_w),
           "kappa": law.kn / p if p > 0 else math.inf}
    out.update(force_anisotropy(c.n, c.fn, c.ft))
    out.update(energies(state, law, c))
    if strain_rate is not None:
        dxx, dyy, dxy = strain_rate
        gdot = 2.0 * math.hypot(0.5 * (dxx - dyy), dxy)
        out["I"] = gdot * math.sqrt(1.0 / p) if p > 0 else math.inf
    return out

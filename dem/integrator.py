"""Time stepping: velocity Verlet in the fluctuation field of a deforming periodic cell.

With positions x = h s, full velocities u = L x + v' (:mod:`dem.periodic_cell`), the
equations of motion are integrated for the fluctuation velocity v', the spin ω, the
reduced coordinates s and the cell h:

    m dv'/dt = F - m L v',    I dω/dt = T,    ds/dt = h⁻¹ v',    dh/dt = L h.

The -m L v' term (the SLLOD form) makes the books close exactly: the kinetic energy of
the fluctuations plus the energy stored in the contacts changes at the rate
V σ:L - (dissipation), with σ the Love–Weber stress including its kinetic part
-(1/V) Σ m v'⊗v' (tension positive). That is the external work the cell does.

One step of length dt (kick–drift–kick; forces F_n known at the start):

    1. L for this step: prescribed components at their rate, stress-controlled ones
       from the servo (:mod:`dem.servo`) on the contact stress σ^c_n = (1/V) Σ f⊗l
       (the kinetic part, ~ρ v'² ≈ 1e-6 P0 in a quasi-static run, is not fed back);
    2. v' += dt/2 (F_n/m - L v'),  ω += dt/2 T_n/I;
    3. h_{n+1} by the Cayley map; s += dt h_mid⁻¹ v'  (h_mid = (h_n + h_{n+1})/2);
    4. if the neighbour list may have become invalid, return to rebuild it (the step
       then resumes at 5);
    5. contact forces at (s_{n+1}, h_{n+1}) with the half-step velocities
       (:mod:`dem.contact_law`), one pass over pairs;
    6. gather F, T per disc (no scattered writes), v' += dt/2 (F/m - L v'),
       ω += dt/2 T/I;
    7. σ_{n+1}, accumulators: strain ε += sym(L) dt, work += dt V_mid (σ_n+σ_{n+1})/2 : L.

Steps 6 of one step and 2–3 of the next touch the same disc data, so they run as one
pass over the discs, with the servo (1, a scalar update from the pair pass's sums) in
between: a step costs two parallel passes, one over pairs and one over discs.

Kernels run with numba ``prange`` over fixed chunks of CHUNK discs or pairs; every sum is
formed per chunk and the chunk sums are added in chunk order, so the results are
bitwise identical for any number of threads (tested). How many threads: one unless asked
(:mod:`dem.threads`, where the measurement that says so is).

Time step: dt = f sqrt(m_min/kn). Velocity Verlet is stable for ω_max dt < 2; a disc
with at most Z_MAX contacts, each coupling translation and rotation (a disc's tangential
effective mass is m/3, so a contact's stiffest mode is max(2 kn, 6 kt)/m_min), has
ω_max² <= Z_MAX max(2 kn, 6 kt)/m_min, and normal damping of ratio β lowers the limit
by the factor sqrt(1+β²) - β (β the largest damping ratio of a contact mode,
:func:`damping_ratio_bound`). :func:`time_step` refuses f above that limit.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from dem import neighbours
from dem.threads import get_threads, numba_threads
from dem.contact_law import ContactLaw, contact_response, damping_coefficient
from dem.periodic_cell import cayley_det, cayley_step
from dem.servo import L_MAX_FACTOR, servo_rate, time_constant
from dem.state import D_DAMP, D_FRIC, D_ROLL, EXX, EXY, EYY, TAU, TIME, WORK, State

CHUNK = 1024
FASTMATH = {"contract", "reassoc", "nsz"}
"""LLVM flags of the pass kernels: fused multiply-add and reordered sums (same code for
every thread count, so parallel runs stay bitwise equal to serial ones); no nnan/ninf, so
the non-finite check stays exact (with them LLVM may delete it)."""
Z_MAX = 6
DT_FRACTION = 0.1
"""Default dt in units of sqrt(m_min/kn)."""

OK, NEED_REBUILD, NOT_FINITE = 0, 1, 2


class TimeStepError(ValueError):
    """Time step above the stability limit (the message names both)."""


def damping_ratio_bound(law: ContactLaw, heavy: float = 1.0) -> float:
    """The largest damping ratio of a contact mode: β for ``spring-dashpot``; for
    ``hooke/history`` (γ = m_eff γn, γt = γ/2) the heaviest pair's, with ``heavy`` =
    m_max / m̄: normal β sqrt(heavy), tangential (effective mass m_eff/3, a disc's rim
    under a tangential force) β sqrt(3 heavy kn/kt) / 2."""
    beta = law.beta
    if law.style == "spring-dashpot":
        return beta
    return beta * math.sqrt(heavy) * max(1.0, 0.5 * math.sqrt(3.0 / law.kt_ratio))


def stable_fraction(law: ContactLaw, heavy: float = 1.0) -> float:
    """Largest f = dt / sqrt(m_min/kn) that :func:`time_step` accepts (see module doc;
    β there is :func:`damping_ratio_bound`)."""
    zeta = damping_ratio_bound(law, heavy)
    stiff = max(2.0, 6.0 * law.kt_ratio)
    return 2.0 / math.sqrt(Z_MAX * stiff) * (math.sqrt(1.0 + zeta * zeta) - zeta)


def time_step(law: ContactLaw, m_min: float, fraction: float = DT_FRACTION,
              heavy: float = 1.0) -> float:
    """dt = fraction · sqrt(m_min/kn), refused above the stability limit (``heavy`` =
    m_max / m̄ of the discs, for the ``hooke/history`` style's damping)."""
    limit = stable_fraction(law, heavy)
    if not (math.isfinite(fraction) and 0.0 < fraction <= limit):
        raise TimeStepError(f"time step fraction {fraction} x sqrt(m_min/kn) is above the "
                            f"stability limit; accepted range (0, {limit:.4g}] for kt/kn = "
                            f"{law.kt_ratio}, e = {law.e}, style {law.style}")
    return fraction * math.sqrt(m_min / law.kn)


@dataclass(frozen=True)
class Dynamics:
    """Settings fixed during a run: contact law, dt, skin, servo constants."""

    law: ContactLaw
    dt: float
    skin: float
    gdot_ref: float
    tau_servo: float
    l_max: float


def dynamics(law: ContactLaw, m_min: float, inertial: float, fraction: float = DT_FRACTION,
             skin: float = 0.2, l_max: float | None = None, heavy: float = 1.0) -> Dynamics:
    """Dynamics for a run at inertial number ``inertial`` (γ̇_ref = I in DEM units).

    The servo time constant follows κ (:func:`dem.servo.time_constant`) and its rate cap
    is L_MAX_FACTOR γ̇_ref unless ``l_max`` is given (preparation caps at its own rate).
    """
    if not (math.isfinite(inertial) and inertial > 0):
        raise ValueError(f"inertial number I = {inertial} out of range; accepted (0, inf) "
                         f"(quasi-static: I <= 1e-3)")
    if not (math.isfinite(skin) and skin > 0):
        raise ValueError(f"Verlet skin = {skin} out of range; accepted (0, inf) (units of d)")
    return Dynamics(law, time_step(law, m_min, fraction, heavy), skin, inertial,
                    time_constant(law.kn), l_max if l_max is not None else L_MAX_FACTOR * inertial)


@dataclass
class Control:
    """What the cell does during a call of :func:`advance`.

    rate (4,): prescribed L components (xx, yy, xy, yx) as absolute rates; controlled
    (4,) bool: which are servo-controlled instead; target0/target1 (3,): stress targets
    (sxx, syy, sxy) at the start and end of the call, interpolated linearly per step.
    """

    rate: np.ndarray
    controlled: np.ndarray
    target0: np.ndarray
    target1: np.ndarray

    @classmethod
    def fixed(cls) -> "Control":
        """A cell at rest (L = 0)."""
        return cls(np.zeros(4), np.zeros(4, bool), np.zeros(3), np.zeros(3))


# ----------------------------------------------------------------------------- kernels

@njit(cache=True)
def pair_constants(pair_ij, n_pairs, radius, mass, kn, beta, gamma_n, tangential):
    """(n_pairs, 3): normal damping coefficient γ, r_eff = ri rj/(ri + rj) and tangential
    damping coefficient γt = ``tangential`` · γ of every listed pair (fixed while the list
    is; computed once per list instead of every step). γ = 2β sqrt(m_eff kn) if
    ``gamma_n`` = 0, else m_eff γn (:class:`dem.contact_law.ContactLaw` styles)."""
    out = np.empty((max(n_pairs, 1), 3))
    for q in range(n_pairs):
        i, j = pair_ij[q, 0], pair_ij[q, 1]
        m_eff = mass[i] * mass[j] / (mass[i] + mass[j])
        gamma = m_eff * gamma_n if gamma_n > 0.0 else damping_coefficient(m_eff, kn, beta)
        out[q, 0] = gamma
        out[q, 1] = radius[i] * radius[j] / (radius[i] + radius[j])
        out[q, 2] = tangential * gamma
    return out


NPAIR_SUMS = 13  # sxx, syy, sxy, Mxx, Myy, Mxy, Myx, d_damp, d_fric, d_roll, dashpot sxx, syy, sxy


@njit(cache=True, parallel=True, fastmath=FASTMATH, error_model="numpy")
def pair_forces(h, L, s, v, omega, radius, pair_const, pair_ij, pair_shift, pair_hist, pair_f,
                n_pairs, kn, kt, mu, mu_roll, arm, dt):
    """Step 5: contact forces of every listed pair; returns the summed (NPAIR_SUMS,) terms.

    ``arm``: a of the contact arm ℓ = r - a δ (:attr:`dem.contact_law.ContactLaw.arm_offset`).

    Writes pair_f[q] = (fx, fy, torque on i, torque on j) with (fx, fy) the force on i,
    updates the histories (by dt; dt = 0 evaluates without advancing ξ), and sums
    f⊗l (stress · V), the affine stiffness · V of each L component, the dissipation, and
    the dashpot part of the stress · V, Σ (-fd n)⊗l (fd = fn - kn δ, the normal damping
    force; for the servo, :mod:`dem.servo`).
    ``pair_const`` is :func:`pair_constants` of the list. A contact that opened during
    the step (listed with δ_old > 0, now δ <= 0) is booked like every step, as the
    trapezoidal work of its last forces over this step's motion, ½ fn_old (δ - δ_old) on
    the normal, ½ ft_old vt dt (spring and dashpot) and ½ Mr_old (ωj - ωi) dt on the
    tangential and rolling springs, plus the energy they stored (lost with the contact).

    Each chunk of pairs is done in two loops: the first finds its live pairs (in contact
    now or at the last step) and zeroes every pair's forces, the second evaluates the live
    ones, in pair order. Whether a listed pair touches is data dependent, so testing it in
    the force loop would mispredict a branch on a large fraction of the pairs.
    """
    nchunk = (n_pairs + CHUNK - 1) // CHUNK
    part = np.zeros((max(nchunk, 1), NPAIR_SUMS))
    h00, h01, h10, h11 = h[0, 0], h[0, 1], h[1, 0], h[1, 1]
    L00, L01, L10, L11 = L[0, 0], L[0, 1], L[1, 0], L[1, 1]
    for c in prange(nchunk):
        q0 = c * CHUNK
        q1 = min(n_pairs, (c + 1) * CHUNK)
        # the chunk's live pairs with their (lx, ly, |l|²): 32 kB, reused chunk after chunk
        live = np.empty(CHUNK, np.int64)
        geo = np.empty((CHUNK, 3))
        m = 0
        for q in range(q0, q1):
            # unsigned: indexing without the negative-index wraparound test
            i, j = np.uint64(pair_ij[q, 0]), np.uint64(pair_ij[q, 1])
            ds0 = s[j, 0] + pair_shift[q, 0] - s[i, 0]
            ds1 = s[j, 1] + pair_shift[q, 1] - s[i, 1]
            lx = h00 * ds0 + h01 * ds1
            ly = h10 * ds0 + h11 * ds1
            rs = radius[i] + radius[j]
            d2 = lx * lx + ly * ly
            for a in range(4):
                pair_f[q, a] = 0.0
            live[m] = q
            geo[m, 0] = lx
            geo[m, 1] = ly
            geo[m, 2] = d2
            m += (d2 < rs * rs) | (pair_hist[q, 3] != 0.0)
        a0 = a1 = a2 = a3 = a4 = a5 = a6 = a7 = a8 = a9 = a10 = a11 = a12 = 0.0
        for k in range(m):
            q = np.uint64(live[k])
            lx, ly, d2 = geo[k, 0], geo[k, 1], geo[k, 2]
            i, j = np.uint64(pair_ij[q, 0]), np.uint64(pair_ij[q, 1])
            ri, rj = radius[i], radius[j]
            rs = ri + rj
            dist = math.sqrt(d2)
            inv = 1.0 / dist
            nx, ny = lx * inv, ly * inv
            tx, ty = -ny, nx
            delta = rs - dist
            li, lj = ri - arm * delta, rj - arm * delta
            spin = omega[i] * li + omega[j] * lj
            wx = L00 * lx + L01 * ly + v[j, 0] - v[i, 0] - spin * tx
            wy = L10 * lx + L11 * ly + v[j, 1] - v[i, 1] - spin * ty
            vn = wx * nx + wy * ny
            vt = wx * tx + wy * ty
            if not d2 < rs * rs:
                # the contact opened during this step: the forces of the last step did
                # their work over this step's motion (to the overlap δ <= 0 now), and the
                # energy stored in the springs is lost
                d0, fd0, x0, r0 = pair_hist[q, 3], pair_hist[q, 2], pair_hist[q, 0], pair_hist[q, 1]
                kr = kt * pair_const[q, 1] * pair_const[q, 1]
                a7 += (0.5 * (kn * d0 + fd0) * (delta - d0) + 0.5 * kn * d0 * d0
                       + 0.5 * pair_hist[q, 4] * vt * dt)
                a8 += 0.5 * kt * x0 * (vt * dt + x0)
                a9 += 0.5 * kr * r0 * ((omega[j] - omega[i]) * dt + r0)
                for a in range(5):
                    pair_hist[q, a] = 0.0
                continue
            fn, ft, mr, xi, xr, fd, fdt, dd, dfr, drl = contact_response(
                delta, pair_hist[q, 3], pair_hist[q, 2], pair_hist[q, 4], vn, vt,
                omega[j] - omega[i], pair_hist[q, 0], pair_hist[q, 1], pair_const[q, 0],
                pair_const[q, 2], pair_const[q, 1], kn, kt, mu, mu_roll, dt)
            pair_hist[q, 0] = xi
            pair_hist[q, 1] = xr
            pair_hist[q, 2] = fd
            pair_hist[q, 3] = delta
            pair_hist[q, 4] = fdt
            fx = -fn * nx + ft * tx
            fy = -fn * ny + ft * ty
            pair_f[q, 0] = fx
            pair_f[q, 1] = fy
            pair_f[q, 2] = li * ft + mr
            pair_f[q, 3] = lj * ft - mr
            a0 += fx * lx
            a1 += fy * ly
            a2 += 0.5 * (fx * ly + fy * lx)
            ax = kn * nx * nx + kt * tx * tx
            ay = kn * ny * ny + kt * ty * ty
            a3 += ax * lx * lx
            a4 += ay * ly * ly
            a5 += ax * ly * ly
            a6 += ay * lx * lx
            a7 += dd
            a8 += dfr
            a9 += drl
            a10 -= fd * nx * lx
            a11 -= fd * ny * ly
            a12 -= 0.5 * fd * (nx * ly + ny * lx)
        part[c, 0], part[c, 1], part[c, 2], part[c, 3], part[c, 4] = a0, a1, a2, a3, a4
        part[c, 5], part[c, 6], part[c, 7], part[c, 8], part[c, 9] = a5, a6, a7, a8, a9
        part[c, 10], part[c, 11], part[c, 12] = a10, a11, a12
    out = np.zeros(NPAIR_SUMS)
    for c in range(nchunk):
        out += part[c]
    return out


NDISC_SUMS = 5  # Σ m v'x², Σ m v'y², Σ m v'x v'y, non-finite count, max displacement²


@njit(cache=True, parallel=True, fastmath=FASTMATH)
def disc_pass(pair_f, row_ptr, inc_ptr, inc, force, torque, v, omega, s, s_ref, mass, inv_mass,
              inv_inertia, L_end, L_next, h_next, hmid_inv, half_dt, dt, gather, drift):
    """One pass over the discs: steps 6 and 2–3, fused across two consecutive steps.

    gather: F, T per disc from its pairs (no scattered writes), then the second half kick
    of the step that ends, v' += dt/2 (F/m - L_end v'), ω += dt/2 T/I. The kinetic sums
    are taken here, at the end of that step. drift: the first half kick of the next step
    with its L_next and the drift s += dt h_mid⁻¹ v', and the largest displacement
    |h_next (s - s_ref)| since the last rebuild (for the list check).
    Returns the (NDISC_SUMS,) sums (the displacement as its square).
    """
    n = v.shape[0]
    nchunk = (n + CHUNK - 1) // CHUNK
    part = np.zeros((max(nchunk, 1), NDISC_SUMS))
    for c in prange(nchunk):
        kxx = 0.0
        kyy = 0.0
        kxy = 0.0
        bad = 0.0
        dm = 0.0
        for p in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            if gather:
                fx = 0.0
                fy = 0.0
                t = 0.0
                # the pairs in pair order: first those with p as j (i < p), listed in inc,
                # then those with p as i, rows row_ptr[p]..row_ptr[p+1] of the list
                for k in range(inc_ptr[p], inc_ptr[p + 1]):
                    q = np.uint64(inc[k])
                    fx -= pair_f[q, 0]
                    fy -= pair_f[q, 1]
                    t += pair_f[q, 3]
                for q in range(np.uint64(row_ptr[p]), np.uint64(row_ptr[p + 1])):
                    fx += pair_f[q, 0]
                    fy += pair_f[q, 1]
                    t += pair_f[q, 2]
                force[p, 0] = fx
                force[p, 1] = fy
                torque[p] = t
                vx, vy = v[p, 0], v[p, 1]
                vx2 = vx + half_dt * (fx * inv_mass[p] - (L_end[0, 0] * vx + L_end[0, 1] * vy))
                vy2 = vy + half_dt * (fy * inv_mass[p] - (L_end[1, 0] * vx + L_end[1, 1] * vy))
                w = omega[p] + half_dt * t * inv_inertia[p]
                kxx += mass[p] * vx2 * vx2
                kyy += mass[p] * vy2 * vy2
                kxy += mass[p] * vx2 * vy2
                if not (math.isfinite(vx2) and math.isfinite(vy2) and math.isfinite(w)):
                    bad += 1.0
            else:
                fx, fy, t = force[p, 0], force[p, 1], torque[p]
                vx2, vy2, w = v[p, 0], v[p, 1], omega[p]
            if drift:
                vx3 = vx2 + half_dt * (fx * inv_mass[p] - (L_next[0, 0] * vx2 + L_next[0, 1] * vy2))
                vy3 = vy2 + half_dt * (fy * inv_mass[p] - (L_next[1, 0] * vx2 + L_next[1, 1] * vy2))
                vx2, vy2 = vx3, vy3
                w += half_dt * t * inv_inertia[p]
                s[p, 0] += dt * (hmid_inv[0, 0] * vx2 + hmid_inv[0, 1] * vy2)
                s[p, 1] += dt * (hmid_inv[1, 0] * vx2 + hmid_inv[1, 1] * vy2)
                d0, d1 = s[p, 0] - s_ref[p, 0], s[p, 1] - s_ref[p, 1]
                dx = h_next[0, 0] * d0 + h_next[0, 1] * d1
                dy = h_next[1, 0] * d0 + h_next[1, 1] * d1
                d2 = dx * dx + dy * dy
                if d2 > dm:
                    dm = d2
            v[p, 0], v[p, 1] = vx2, vy2
            omega[p] = w
        part[c, 0] = kxx
        part[c, 1] = kyy
        part[c, 2] = kxy
        part[c, 3] = bad
        part[c, 4] = dm
    out = np.zeros(NDISC_SUMS)
    for c in range(nchunk):
        for a in range(4):
            out[a] += part[c, a]
        out[4] = max(out[4], part[c, 4])
    return out


@njit(cache=True)
def _contact_stress(h, ps, stress_c, stress_d, stiff):
    """σ^c = (1/V) Σ f⊗l, its dashpot part σ^d, and the affine stiffness (1/V) of each L
    component."""
    vol = h[0, 0] * h[1, 1] - h[0, 1] * h[1, 0]
    for a in range(3):
        stress_c[a] = ps[a] / vol
        stress_d[a] = ps[10 + a] / vol
    for a in range(4):
        stiff[a] = ps[3 + a] / vol


@njit(cache=True)
def _servo(L, l_int, stress_c, stress_d, stiff, rate, controlled, target, dt, tau, l_max):
    """Step 1: set L (xx, yy, xy, yx -> L[0,0], L[1,1], L[0,1], L[1,0]); the proportional
    term sees σ^c - σ^d, the integral σ^c (:mod:`dem.servo`)."""
    for a in range(4):
        r, cc = (0, 0) if a == 0 else (1, 1) if a == 1 else (0, 1) if a == 2 else (1, 0)
        if controlled[a]:
            k = a if a < 2 else 2
            L[r, cc], l_int[a] = servo_rate(target[k] - stress_c[k],
                                            target[k] - stress_c[k] + stress_d[k], stiff[a],
                                            l_int[a], dt, tau, l_max)
        else:
            L[r, cc] = rate[a]


@njit(cache=True)
def _next_cell(L, l_int, stress_c, stress_d, stiff, rate, controlled, target0, target1, frac,
               dt, tau, l_max, h):
    """Step 1 and the cell part of step 3: L of the next step (target at ``frac`` of
    [target0, target1]), h_next by the Cayley map and h_mid⁻¹."""
    target = target0 + (target1 - target0) * frac
    _servo(L, l_int, stress_c, stress_d, stiff, rate, controlled, target, dt, tau, l_max)
    h_next = cayley_step(h, L, dt)
    hm = 0.5 * (h + h_next)
    det = hm[0, 0] * hm[1, 1] - hm[0, 1] * hm[1, 0]
    hmi = np.empty((2, 2))
    hmi[0, 0] = hm[1, 1] / det
    hmi[0, 1] = -hm[0, 1] / det
    hmi[1, 0] = -hm[1, 0] / det
    hmi[1, 1] = hm[0, 0] / det
    return h_next, hmi


@njit(cache=True)
def _begin_step(acc, L, dt, gdot_ref, h, h_ref, dmax2, r_max, skin):
    """The step has moved the cell and drifted the discs: advance time and strain; return
    True if the neighbour list may have become invalid (see :mod:`dem.neighbours`)."""
    acc[TIME] += dt
    acc[TAU] += gdot_ref * dt
    acc[EXX] += L[0, 0] * dt
    acc[EYY] += L[1, 1] * dt
    acc[EXY] += 0.5 * (L[0, 1] + L[1, 0]) * dt
    dr = h_ref[0, 0] * h_ref[1, 1] - h_ref[0, 1] * h_ref[1, 0]
    e00 = (h[0, 0] * h_ref[1, 1] - h[0, 1] * h_ref[1, 0]) / dr - 1.0
    e01 = (-h[0, 0] * h_ref[0, 1] + h[0, 1] * h_ref[0, 0]) / dr
    e10 = (h[1, 0] * h_ref[1, 1] - h[1, 1] * h_ref[1, 0]) / dr
    e11 = (-h[1, 0] * h_ref[0, 1] + h[1, 1] * h_ref[0, 0]) / dr - 1.0
    stretch = math.sqrt(e00 * e00 + e01 * e01 + e10 * e10 + e11 * e11)
    return 2.0 * math.sqrt(dmax2) + stretch * (2.0 * r_max + skin) >= skin


@njit(cache=True)
def _end_step(acc, h, L, dt, ps, ks, stress, stress_c):
    """Close a step: σ = σ^c - (1/V) Σ m v'⊗v', dissipation, and the external work
    dt V_mid (σ_start + σ_end)/2 : L, with V_start = V_end / det(Cayley map of L)."""
    vol = h[0, 0] * h[1, 1] - h[0, 1] * h[1, 0]
    s0, s1, s2 = stress[0], stress[1], stress[2]
    for a in range(3):
        stress[a] = stress_c[a] - ks[a] / vol
    acc[D_DAMP] += ps[7]
    acc[D_FRIC] += ps[8]
    acc[D_ROLL] += ps[9]
    vmid = 0.5 * vol * (1.0 + 1.0 / cayley_det(L, dt))
    acc[WORK] += dt * vmid * 0.5 * ((s0 + stress[0]) * L[0, 0] + (s1 + stress[1]) * L[1, 1]
                                    + (s2 + stress[2]) * (L[0, 1] + L[1, 0]))


@njit(cache=True)
def advance_kernel(nsteps, mid_step, k0, ktotal, dt, kn, kt, mu, mu_roll, arm, skin, r_max,
                   gdot_ref, tau_servo, l_max, radius, pair_const, mass, inv_mass, inv_inertia,
                   s, v, omega, force, torque, s_ref, h, h_ref, L, l_int, pair_ij, pair_shift,
                   pair_hist, pair_f, n_pairs, row_ptr, inc_ptr, inc, rate, controlled,
                   target0, target1, stress, stress_c, stress_d, stiff, acc):
    """Up to ``nsteps`` steps (see the module doc); returns (steps completed, status).

    Two parallel passes per step: the pairs (step 5), then the discs (step 6 of this
    step fused with steps 2–3 of the next, whose L the servo sets in between from the
    contact stress). The last step of a call ends after step 6, so between calls the
    state is at a full step. ``mid_step``: the first step already did 1–4 (resume after a
    rebuild). Step k of the call uses the stress target at fraction (k0 + k + 1)/ktotal of
    [target0, target1]. status NEED_REBUILD: step ``done`` + 1 stopped after 4;
    NOT_FINITE: a velocity is NaN/inf.
    """
    half = 0.5 * dt
    L_end = L.copy()
    if not mid_step:
        h_next, hmi = _next_cell(L, l_int, stress_c, stress_d, stiff, rate, controlled, target0,
                                 target1, (k0 + 1) / ktotal, dt, tau_servo, l_max, h)
        ks = disc_pass(pair_f, row_ptr, inc_ptr, inc, force, torque, v, omega, s, s_ref, mass,
                       inv_mass, inv_inertia, L_end, L, h_next, hmi, half, dt, False, True)
        h[:, :] = h_next
        if _begin_step(acc, L, dt, gdot_ref, h, h_ref, ks[4], r_max, skin):
            return 0, NEED_REBUILD
    for k in range(nsteps):
        ps = pair_forces(h, L, s, v, omega, radius, pair_const, pair_ij, pair_shift, pair_hist,
                         pair_f, n_pairs, kn, kt, mu, mu_roll, arm, dt)
        _contact_stress(h, ps, stress_c, stress_d, stiff)
        last = k + 1 == nsteps
        L_end[:, :] = L
        if last:
            h_next, hmi = h, h
        else:
            h_next, hmi = _next_cell(L, l_int, stress_c, stress_d, stiff, rate, controlled,
                                     target0, target1, (k0 + k + 2) / ktotal, dt, tau_servo,
                                     l_max, h)
        ks = disc_pass(pair_f, row_ptr, inc_ptr, inc, force, torque, v, omega, s, s_ref, mass,
                       inv_mass, inv_inertia, L_end, L, h_next, hmi, half, dt, True, not last)
        _end_step(acc, h, L_end, dt, ps, ks, stress, stress_c)
        if ks[3] != 0.0:
            return k + 1, NOT_FINITE
        if last:
            break
        h[:, :] = h_next
        if _begin_step(acc, L, dt, gdot_ref, h, h_ref, ks[4], r_max, skin):
            return k + 1, NEED_REBUILD
    return nsteps, OK


# ----------------------------------------------------------------------------- drivers

class DivergenceError(RuntimeError):
    """The integration produced NaN/inf (time step too large, or a bad configuration)."""


def _pair_constants(state: State, dyn: Dynamics) -> np.ndarray:
    law = dyn.law
    return pair_constants(state.pair_ij, state.n_pairs, state.radius, state.mass, law.kn,
                          law.beta, law.gamma_n(float(np.mean(state.mass))),
                          law.tangential_damping)


def evaluate_forces(state: State, dyn: Dynamics) -> State:
    """Forces, torques, stress and stiffness at the current state (ξ histories untouched)."""
    with numba_threads(get_threads()):
        return _evaluate_forces(state, dyn)


def _evaluate_forces(state: State, dyn: Dynamics) -> State:
    kn, kt, _, mu, mu_roll = dyn.law.kernel_params()
    ps = pair_forces(state.h, state.L, state.s, state.v, state.omega, state.radius,
                     _pair_constants(state, dyn), state.pair_ij, state.pair_shift,
                     state.pair_hist, state.pair_f, state.n_pairs, kn, kt, mu, mu_roll,
                     dyn.law.arm_offset, 0.0)
    _contact_stress(state.h, ps, state.stress_contact, state.stress_damping, state.stiff)
    none = np.zeros((2, 2))
    ks = disc_pass(state.pair_f, state.row_ptr, state.inc_ptr, state.inc, state.force,
                   state.torque, state.v, state.omega, state.s, state.s_ref, state.mass,
                   state.inv_mass, state.inv_inertia, state.L, state.L, none, none, 0.0, 0.0,
                   True, False)
    state.stress[:] = state.stress_contact - ks[:3] / state.volume
    return state


def advance(state: State, dyn: Dynamics, nsteps: int, control: Control | None = None) -> State:
    """Advance ``state`` by ``nsteps`` steps in place (and return it).

    Neighbour lists are rebuilt whenever the validity check asks for it; the rebuild
    schedule therefore depends on the state only, so a run restarted from a checkpoint
    takes exactly the same steps. The parallel passes run on :func:`dem.threads.get_threads`
    threads, whatever numba's process-wide count is.
    """
    with numba_threads(get_threads()):
        return _advance(state, dyn, nsteps, control or Control.fixed())


def _advance(state: State, dyn: Dynamics, nsteps: int, control: Control) -> State:
    kn, kt, _, mu, mu_roll = dyn.law.kernel_params()
    r_max = float(state.radius.max())
    done_total, mid = 0, False
    controlled = np.ascontiguousarray(control.controlled, dtype=np.bool_)
    const = _pair_constants(state, dyn)
    while done_total < nsteps:
        done, status = advance_kernel(
            nsteps - done_total, mid, done_total, nsteps, dyn.dt, kn, kt, mu, mu_roll,
            dyn.law.arm_offset, dyn.skin, r_max, dyn.gdot_ref, dyn.tau_servo, dyn.l_max,
            state.radius, const,
            state.mass, state.inv_mass, state.inv_inertia, state.s, state.v, state.omega,
            state.force, state.torque, state.s_ref, state.h, state.h_ref, state.L, state.L_int,
            state.pair_ij, state.pair_shift, state.pair_hist, state.pair_f, state.n_pairs,
            state.row_ptr, state.inc_ptr, state.inc, np.asarray(control.rate, float), controlled,
            np.asarray(control.target0, float), np.asarray(control.target1, float),
            state.stress, state.stress_contact, state.stress_damping, state.stiff, state.acc)
        state.step += done
        done_total += done
        if status == NOT_FINITE:
            raise DivergenceError(f"non-finite velocity at step {state.step}: the time step "
                                  f"{dyn.dt:.3g} is too large for this configuration, or "
                                  f"discs overlap far too much")
        if status == NEED_REBUILD:
            neighbours.rebuild(state, dyn.skin)
            const = _pair_constants(state, dyn)
            mid = True
        else:
            mid = False
    return state

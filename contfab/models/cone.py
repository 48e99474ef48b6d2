r"""Tiers 0 and 1: backward-Euler return on the circular Mohr–Coulomb cone, with its apex.

Conventions (docs/theory.md §1): tension positive, P = -(σxx+σyy)/2, R = sqrt(((σxx-σyy)/2)² + σxy²),
Voigt stress (σxx, σyy, σxy), Voigt strain with engineering shear (εxx, εyy, γxy).

**Model** (docs/theory.md §4–§5; Roux & Radjaï 2001, §3–§4). Yield f = R - sin φ·P <= 0 (a cone: no stress
scale); plastic potential g = R - sin ψ·P, non-associated for ψ ≠ φ. The flow
Δεp = Δγ ∂g/∂σ is coaxial with σ, with principal values Δεp1 - Δεp2 = Δγ and
tr Δεp = Δγ sin ψ (eq. 1.2 there). Tier 0: φ, ψ constant. Tier 1: φ(c), ψ(c) from
:func:`friction_angles`, and c_{n+1} = c_n exp(-tr Δεp) (eq. 1.4 there, integrated
exactly over the step).

**Update** of one point, stress σ_n, increments (Δε, Δω):

1. Objective rotation: σ_n ← Q σ_n Qᵀ, Q the rotation by Δω — the exact exponential
   of the 2D spin increment (Hughes–Winget's midpoint rule gives the angle
   2 atan(Δω/2) instead; in 2D the exact angle costs nothing, and a rigid rotation of
   any size is then reproduced exactly, as the fabric of tier 2 must be).
2. Elastic predictor with the regularization (:class:`contfab.params.Regularization`):
   P_tr = P_n - K tr Δε, deviator_tr = deviator_n + 2G dev Δε; R_tr and the unit
   deviator direction n = deviator_tr / R_tr.
3. f_tr = R_tr - sin φ P_tr <= 0: elastic (status 0), tangent C.
4. Otherwise the return keeps n (coaxial) and solves R = R_tr - G Δγ,
   P = P_tr + K sin ψ Δγ, R = sin φ P:

       Δγ = f_tr / D,   P = a / D,   R = sin φ · P,
       D = G + K sin φ sin ψ  (> 0: checked on load),   a = G P_tr + K sin ψ R_tr.

   a > 0: the plastic face (status 1).
5. a <= 0: the **apex** (status 2): σ = 0, the material separates; all of the trial
   strain C⁻¹σ_tr is plastic (Δεp1 - Δεp2 = R_tr/G, tr Δεp = -P_tr/K). Because the
   flow is non-associated, the apex region is bounded by the plastic potential, not
   the yield function: a <= 0 says exactly that C⁻¹σ_tr lies in the normal cone of g at
   the apex (it dilates at least as much as ψ demands: tr >= sin ψ (Δεp1 - Δεp2)). The
   face and apex formulas meet continuously at a = 0 (P = R = 0, Δγ = R_tr/G).

**Tier 1** has sin φ, sin ψ at c_{n+1}. With y = ln(c_{n+1}/c_n) the face return is
explicit for given y, so one scalar equation remains,

    H(y) = y + tr Δεp(y) = 0,   tr Δεp = Δγ(y) sin ψ(y) on the face, -P_tr/K at the apex,

solved by Newton safeguarded by bisection on the bracket c_{n+1} between c_n and c*
(y between 0 and y* = ln(c*/c_n)): H < 0 at one end and > 0 at the other because
ψ(c*) = 0 and φ, ψ do not decrease with c (checked on load), and every root in it has
Δγ > 0. No step divides by sin ψ, so ψ = 0 is not special (the "zero
cohesion, zero dilatancy" trap of cone returns). The apex is tested first: it has
c_{n+1} = c_n exp(P_tr/K) in closed form.

**Consistent tangent** ∂σ_{n+1}/∂Δε (not including Δω), exact on every branch:
elastic C; face: differentiating P(P_tr, R_tr, y), R = sin φ P and the rotation of n
(weight R/R_tr) — non-symmetric for ψ ≠ φ; for tier 1 y is differentiated through
H = 0 (implicit function theorem). Apex: the tangent is **zero** — the exact derivative,
since σ ≡ 0 in the interior of the apex region. A separated region has no stiffness;
that is physics, and a boundary-value solver needs its own device there (docs/theory.md §13).
Round-off near the face/apex boundary (ψ = 0: the boundary is P_tr = 0, where an
isochoric increment from σ = 0 lands): trial states within a band of relative width
APEX_BAND of the boundary return σ = 0 (status 2) but the face's one-sided limit
tangent, so such states never flip between a finite and a zero tangent at random and a
global Newton iteration sees one consistent derivative there.

**Failures** (status -1): non-finite input, c outside (0, 1), a tier-1 local solve that
does not converge or lands on a fold (H'(y) <= 0), or a non-finite result. The point
then returns its *input* stress and state and the elastic tangent; nothing non-finite
is produced. The caller cuts the step.

**Rigid-plastic limit.** The regularization E_reg = λ p_ref only sets how much strain
is elastic: of order |σ|/(λ p_ref). On any path the stress-strain response converges
to the rigid-plastic one at first order in 1/λ: the elastic strain shifts the strain
axis by O(1/λ) (the onset of yield, and the plastic strain that drives c, differ from
the rigid-plastic ones by the elastic strain), so e.g. c and σ at a given total strain
converge as O(1/λ) (tests/test_lambda_convergence.py measures the order: 1.0 ± 0.1).
Stress ratios at yield (R/P = sin φ) do not depend on λ at all.

**Parameter arrays** (built by :meth:`contfab.params.Params.array`; angles in radians),
read by the named offsets of :mod:`contfab.params`: tier 0 ``BULK`` K, ``SHEAR`` G,
``SIN_PHI``, ``SIN_PSI``; tier 1 ``BULK``, ``SHEAR``, ``PHI_STAR`` φ*, ``DPHI_DC`` φ' and
``DPSI_DC`` ψ' (per unit c), ``C_STAR`` c*, ``PHI_MIN``, ``PHI_MAX``.

**State columns**: tier 0 (gp,), tier 1 (gp, c); gp accumulates Δεp1 - Δεp2.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from contfab.params import (BULK, C_STAR, DPHI_DC, DPSI_DC, PHI_MAX, PHI_MIN, PHI_STAR, SHEAR,
                            SIN_PHI, SIN_PSI)
from contfab.tensors import isotropic_stiffness_into, rotate
from dem.conventions import deviator_radius, pressure

STATUS_ELASTIC = 0
STATUS_FACE = 1
STATUS_APEX = 2
STATUS_FAILED = -1

APEX_BAND = 1e-10
"""Relative width of the round-off band at the face/apex boundary (see the module doc)."""
# Per-point helpers are inlined into the kernels (numba inline="always"): a call that
# passes arrays costs an atomic reference-count update per array, which doubled the
# time per point when they were separate functions (measured: tier 0 100 -> 50 ns).
NEWTON_MAXIT = 60
NEWTON_RTOL = 1e-15
"""Tier-1 local solve: converged when |H| <= NEWTON_RTOL·Δγ (ln c consistent with the
plastic volume change to 1e-15 of the plastic shear strain of the step; looser
values show up as noise in finite-difference checks of the tangent at large steps)."""
NEWTON_LINEAR_STEP = 1e-9
"""Tier-1 local solve: a Newton step |Δy| below this is the last one, applied linearly;
the error, ½ H''Δy² ~ ½ (ψ' c)² (1 + K/G)² Δγ·1e-18, is far below NEWTON_RTOL·Δγ."""


# --------------------------------------------------------------------------- shared pieces

@njit(cache=True, error_model="numpy", inline="always")
def friction_angles(c, phi_star, dphi, dpsi, c_star, phi_min, phi_max):
    """(φ, ψ, dφ/dc, dψ/dc) of tier 1 at packing fraction c (radians).

    φ(c) = φ* + φ'(c - c*) clamped to [φ_min, φ_max]; ψ(c) = ψ'(c - c*) clamped to
    [-φ(c), φ(c)]. Both are continuous; the derivatives are the one-sided ones of the
    active piece.
    """
    phi = phi_star + dphi * (c - c_star)
    phi_c = dphi
    if phi < phi_min:
        phi = phi_min
        phi_c = 0.0
    elif phi > phi_max:
        phi = phi_max
        phi_c = 0.0
    psi = dpsi * (c - c_star)
    psi_c = dpsi
    if psi > phi:
        psi = phi
        psi_c = phi_c
    elif psi < -phi:
        psi = -phi
        psi_c = -phi_c
    return phi, psi, phi_c, psi_c


@njit(cache=True, error_model="numpy", inline="always")
def tier1_angles(c, prm):
    """:func:`friction_angles` at c with the tier-1 parameters of a kernel array ``prm``
    (:meth:`contfab.params.Params.array` of tier 1 or 2)."""
    return friction_angles(c, prm[PHI_STAR], prm[DPHI_DC], prm[DPSI_DC], prm[C_STAR],
                           prm[PHI_MIN], prm[PHI_MAX])


@njit(cache=True, error_model="numpy", inline="always")
def _trial(sxx, syy, sxy, dexx, deyy, dgxy, dspin, bulk, shear):
    """Rotate σ_n by Δω, add C Δε; return (P_tr, R_tr, n_d, n_t, scale).

    n = (n_d, n_t) is the unit deviator direction ((σxx-σyy)/2, σxy)/R_tr ((1, 0) if
    R_tr = 0); ``scale`` bounds the magnitudes summed into P_tr and R_tr (for round-off
    bands).
    """
    rxx, ryy, rxy = rotate(sxx, syy, sxy, dspin)
    dev = shear * (dexx - deyy)          # 2G·(Δεxx - Δεyy)/2
    vol = bulk * (dexx + deyy)           # change of the mean stress, K tr Δε
    txx = rxx + vol + dev
    tyy = ryy + vol - dev
    txy = rxy + shear * dgxy             # 2G·Δεxy = G·Δγxy
    p_tr = pressure(txx, tyy)
    r_tr = deviator_radius(txx, tyy, txy)
    scale = abs(pressure(rxx, ryy)) + deviator_radius(rxx, ryy, rxy) + abs(vol) + abs(dev) \
        + abs(shear * dgxy)
    if r_tr > 0.0:
        return p_tr, r_tr, 0.5 * (txx - tyy) / r_tr, txy / r_tr, scale
    return p_tr, r_tr, 1.0, 0.0, scale


@njit(cache=True, error_model="numpy", inline="always")
def _write_stress(stress, i, p, r, n_d, n_t):
    """σ = -P I + R (n_d, -n_d, n_t): the stress with pressure P, radius R, direction n."""
    stress[i, 0] = -p + r * n_d
    stress[i, 1] = -p - r * n_d
    stress[i, 2] = r * n_t


@njit(cache=True, error_model="numpy", inline="always")
def _coaxial_tangent(a_p, a_r, b_p, b_r, n_d, n_t, rho, bulk, shear, t):
    """Tangent of a return that keeps the direction n and maps (P_tr, R_tr) to (P, R).

    dP = a_p dP_tr + a_r dR_tr, dR = b_p dP_tr + b_r dR_tr; rho = R/R_tr scales the
    rotation of n. With dP_tr/dΔε = -K (1, 1, 0), dR_tr/dΔε = G (n_d, -n_d, n_t) and
    dn = (I - n nᵀ) J dΔε / R_tr, J = G [[1, -1, 0], [0, 0, 1]]:
    dσxx = -dP + d(R n_d), dσyy = -dP - d(R n_d), dσxy = d(R n_t).
    """
    for j in range(3):
        dp_tr = -bulk if j < 2 else 0.0
        if j == 0:
            dr_tr = shear * n_d
            j0 = shear
            j1 = 0.0
        elif j == 1:
            dr_tr = -shear * n_d
            j0 = -shear
            j1 = 0.0
        else:
            dr_tr = shear * n_t
            j0 = 0.0
            j1 = shear
        gp = a_p * dp_tr + a_r * dr_tr
        gr = b_p * dp_tr + b_r * dr_tr
        dd = n_d * gr + rho * ((1.0 - n_d * n_d) * j0 - n_d * n_t * j1)
        dt = n_t * gr + rho * ((1.0 - n_t * n_t) * j1 - n_d * n_t * j0)
        t[0, j] = -gp + dd
        t[1, j] = -gp - dd
        t[2, j] = dt


@njit(cache=True, error_model="numpy", inline="always")
def _finite_row(a, i):
    for j in range(a.shape[1]):
        if not np.isfinite(a[i, j]):
            return False
    return True


@njit(cache=True, error_model="numpy", inline="always")
def _inputs_finite(stress_n, state_n, dstrain, dspin, i):
    return (_finite_row(stress_n, i) and _finite_row(state_n, i) and _finite_row(dstrain, i)
            and np.isfinite(dspin[i]))


@njit(cache=True, error_model="numpy", inline="always")
def _finish(stress_n, state_n, stress, state, tangent, status, i, bulk, shear):
    """Guard the no-NaN rule: a failed or non-finite point returns its inputs (status -1)."""
    ok = status[i] != STATUS_FAILED and _finite_row(stress, i) and _finite_row(state, i)
    if ok:
        for j in range(3):
            for k in range(3):
                if not np.isfinite(tangent[i, j, k]):
                    ok = False
    if not ok:
        status[i] = STATUS_FAILED
        stress[i, :] = stress_n[i, :]
        state[i, :] = state_n[i, :]
        isotropic_stiffness_into(bulk, shear, tangent[i])


# --------------------------------------------------------------------------- tier 0

@njit(cache=True, error_model="numpy", inline="always")
def _tier0_point(i, stress_n, state_n, dstrain, dspin, bulk, shear, sphi, spsi,
                 stress, state, tangent, status):
    p_tr, r_tr, n_d, n_t, scale = _trial(stress_n[i, 0], stress_n[i, 1], stress_n[i, 2],
                                         dstrain[i, 0], dstrain[i, 1], dstrain[i, 2], dspin[i],
                                         bulk, shear)
    f_tr = r_tr - sphi * p_tr
    if f_tr <= 0.0:
        _write_stress(stress, i, p_tr, r_tr, n_d, n_t)
        state[i, 0] = state_n[i, 0]
        isotropic_stiffness_into(bulk, shear, tangent[i])
        status[i] = STATUS_ELASTIC
        return
    d = shear + bulk * sphi * spsi
    a = shear * p_tr + bulk * spsi * r_tr
    a_p = shear / d
    a_r = bulk * spsi / d
    if a > 0.0:
        p = a / d
        r = sphi * p
        _write_stress(stress, i, p, r, n_d, n_t)
        state[i, 0] = state_n[i, 0] + f_tr / d
        _coaxial_tangent(a_p, a_r, sphi * a_p, sphi * a_r, n_d, n_t, r / r_tr, bulk, shear,
                         tangent[i])
        status[i] = STATUS_FACE
        return
    _write_stress(stress, i, 0.0, 0.0, n_d, n_t)
    state[i, 0] = state_n[i, 0] + r_tr / shear
    status[i] = STATUS_APEX
    if r_tr > 0.0 and a > -APEX_BAND * (bulk + shear) * scale:
        _coaxial_tangent(a_p, a_r, sphi * a_p, sphi * a_r, n_d, n_t, 0.0, bulk, shear, tangent[i])
    else:
        tangent[i, :, :] = 0.0


@njit(cache=True, parallel=True, error_model="numpy")
def update_points_tier0(stress_n, state_n, dstrain, dspin, prm, stress, state, tangent, status):
    """Tier 0 update of every point (layout of ``prm``: module doc). Writes the outputs."""
    bulk = prm[BULK]
    shear = prm[SHEAR]
    sphi = prm[SIN_PHI]
    spsi = prm[SIN_PSI]
    for i in prange(stress_n.shape[0]):
        if _inputs_finite(stress_n, state_n, dstrain, dspin, i):
            _tier0_point(i, stress_n, state_n, dstrain, dspin, bulk, shear, sphi, spsi,
                         stress, state, tangent, status)
        else:
            status[i] = STATUS_FAILED
        _finish(stress_n, state_n, stress, state, tangent, status, i, bulk, shear)


# --------------------------------------------------------------------------- tier 1

@njit(cache=True, error_model="numpy", inline="always")
def _tier1_face(y, c, p_tr, r_tr, bulk, shear, prm):
    """The tier-1 face return for c_{n+1} = c = c_n exp(y), and what Newton and the tangent need.

    Returns (H, H_y, sφ, sψ, sφ_y, sψ_y, D, a, Δγ, dφ/dc, dψ/dc) with the face formulas
    H(y) = y + Δγ(y) sin ψ(y), Δγ = (R_tr - sin φ P_tr)/D, and derivatives in y.
    The face is valid where a > 0. (|φ|, |ψ| < π/2, so cos = sqrt(1 - sin²).)
    """
    phi, psi, phi_c, psi_c = tier1_angles(c, prm)
    sphi = np.sin(phi)
    spsi = np.sin(psi)
    sphi_y = np.sqrt(1.0 - sphi * sphi) * phi_c * c
    spsi_y = np.sqrt(1.0 - spsi * spsi) * psi_c * c
    d = shear + bulk * sphi * spsi
    a = shear * p_tr + bulk * spsi * r_tr
    num = r_tr - sphi * p_tr
    dgam = num / d
    dgam_y = -sphi_y * p_tr / d - num * bulk * (sphi_y * spsi + sphi * spsi_y) / (d * d)
    h = y + dgam * spsi
    h_y = 1.0 + dgam_y * spsi + dgam * spsi_y
    return h, h_y, sphi, spsi, sphi_y, spsi_y, d, a, dgam, phi_c, psi_c


@njit(cache=True, error_model="numpy", inline="always")
def _tier1_tangent(r_tr, n_d, n_t, rho, bulk, shear, sphi, spsi, sphi_y, spsi_y, d, a, h_y, t):
    """Face tangent of tier 1: P = a/D and R = sin φ P at y(P_tr, R_tr) from H = 0."""
    # H's partials: dΔγ/dP_tr = -sφ/D, dΔγ/dR_tr = 1/D, so H_P = -sψ sφ/D, H_R = sψ/D.
    y_p = spsi * sphi / (d * h_y)
    y_r = -spsi / (d * h_y)
    p = max(a, 0.0) / d
    p_y = bulk * spsi_y * r_tr / d - a * bulk * (sphi_y * spsi + sphi * spsi_y) / (d * d)
    a_p = shear / d + p_y * y_p
    a_r = bulk * spsi / d + p_y * y_r
    b_p = sphi * a_p + p * sphi_y * y_p
    b_r = sphi * a_r + p * sphi_y * y_r
    _coaxial_tangent(a_p, a_r, b_p, b_r, n_d, n_t, rho, bulk, shear, t)


@njit(cache=True, error_model="numpy", inline="always")
def _tier1_point(i, stress_n, state_n, dstrain, dspin, prm, sin_phi_star, stress, state,
                 tangent, status):
    bulk = prm[BULK]
    shear = prm[SHEAR]
    gp_n = state_n[i, 0]
    c_n = state_n[i, 1]
    if not (0.0 < c_n < 1.0):
        status[i] = STATUS_FAILED
        return
    p_tr, r_tr, n_d, n_t, scale = _trial(stress_n[i, 0], stress_n[i, 1], stress_n[i, 2],
                                         dstrain[i, 0], dstrain[i, 1], dstrain[i, 2], dspin[i],
                                         bulk, shear)
    # H at y = 0 (c = c_n): also gives sin φ(c_n) for the elastic check.
    h, h_y, sphi, spsi, sphi_y, spsi_y, d, a, dgam, phi_c, psi_c = _tier1_face(
        0.0, c_n, p_tr, r_tr, bulk, shear, prm)
    if r_tr - sphi * p_tr <= 0.0:
        _write_stress(stress, i, p_tr, r_tr, n_d, n_t)
        state[i, 0] = gp_n
        state[i, 1] = c_n
        isotropic_stiffness_into(bulk, shear, tangent[i])
        status[i] = STATUS_ELASTIC
        return
    # Apex first, with y = P_tr/K in closed form. It needs a <= 0, impossible when
    # G P_tr - K sin φ* R_tr > 0 (sin ψ >= -sin φ* at every c).
    if shear * p_tr - bulk * sin_phi_star * r_tr <= 0.0:
        y_apex = p_tr / bulk
        c_apex = c_n * np.exp(y_apex)
        ha, ha_y, sphia, spsia, sphia_y, spsia_y, da, aa, _, _, _ = _tier1_face(
            y_apex, c_apex, p_tr, r_tr, bulk, shear, prm)
        if aa <= 0.0:
            _write_stress(stress, i, 0.0, 0.0, n_d, n_t)
            state[i, 0] = gp_n + r_tr / shear
            state[i, 1] = c_apex
            status[i] = STATUS_APEX
            if r_tr > 0.0 and aa > -APEX_BAND * (bulk + shear) * scale:
                # round-off band: the face's one-sided limit tangent at a -> 0+
                _tier1_tangent(r_tr, n_d, n_t, 0.0, bulk, shear, sphia, spsia, sphia_y,
                               spsia_y, da, aa, ha_y, tangent[i])
            else:
                tangent[i, :, :] = 0.0
            return
    # Face: Newton on H(y) = 0 from y = 0, safeguarded by bisection on the bracket
    # c in [c_n, c*] (or [c*, c_n]); c = c_n exp(y) is carried along. As in "rtsafe", a
    # Newton step that leaves the bracket or is not at least twice shorter than the step
    # before the last one is replaced by a bisection (H can be steep between two pieces
    # where it has slope 1, and plain Newton then bounces between them).
    lo = min(c_n, prm[C_STAR])
    hi = max(c_n, prm[C_STAR])
    y = 0.0
    c = c_n
    dy_last = (hi - lo) / lo          # >= the bracket's width in y
    dy_before = dy_last
    converged = False
    for _ in range(NEWTON_MAXIT):
        if a <= 0.0:     # beyond the face: H continues with the apex's tr Δεp = -P_tr/K
            h = y - p_tr / bulk
            h_y = 1.0
        if abs(h) <= NEWTON_RTOL * dgam:
            converged = True
            break
        if h > 0.0:
            hi = c
        else:
            lo = c
        step = -h / h_y
        if a > 0.0 and abs(step) <= NEWTON_LINEAR_STEP:
            # Last Newton step: on one smooth piece of φ(c), ψ(c), H - y, sin φ and sin ψ
            # are linear in y to O(step²) << NEWTON_RTOL·Δγ: update them linearly.
            c_new = c * (1.0 + step * (1.0 + 0.5 * step))
            _, _, phi_c_new, psi_c_new = tier1_angles(c_new, prm)
            if lo <= c_new <= hi and phi_c_new == phi_c and psi_c_new == psi_c:
                sphi += sphi_y * step
                spsi += spsi_y * step
                d = shear + bulk * sphi * spsi
                a = shear * p_tr + bulk * spsi * r_tr
                dgam = (r_tr - sphi * p_tr) / d
                y += step
                c = c_new
                converged = True
                break
        c_new = c * np.exp(step) if h_y > 0.0 and abs(step) <= 0.5 * dy_before else -1.0
        if c_new == c:                   # no representable progress in c
            converged = abs(h) <= 1e3 * NEWTON_RTOL * dgam
            break
        if not (lo < c_new < hi):        # bisection in c (the bracket's ends are old iterates)
            c_new = 0.5 * (lo + hi)
            step = np.log(c_new / c)
        dy_before = dy_last
        dy_last = abs(step)
        y += step
        c = c_new
        h, h_y, sphi, spsi, sphi_y, spsi_y, d, a, dgam, phi_c, psi_c = _tier1_face(
            y, c, p_tr, r_tr, bulk, shear, prm)
    if not converged or h_y <= 0.0 or a <= 0.0:
        status[i] = STATUS_FAILED
        return
    p = a / d
    r = sphi * p
    _write_stress(stress, i, p, r, n_d, n_t)
    state[i, 0] = gp_n + dgam
    state[i, 1] = c
    _tier1_tangent(r_tr, n_d, n_t, r / r_tr, bulk, shear, sphi, spsi, sphi_y, spsi_y, d, a, h_y,
                   tangent[i])
    status[i] = STATUS_FACE


@njit(cache=True, parallel=True, error_model="numpy")
def update_points_tier1(stress_n, state_n, dstrain, dspin, prm, stress, state, tangent, status):
    """Tier 1 update of every point (layout of ``prm``: module doc). Writes the outputs."""
    sin_phi_star = np.sin(prm[PHI_STAR])
    for i in prange(stress_n.shape[0]):
        if _inputs_finite(stress_n, state_n, dstrain, dspin, i):
            _tier1_point(i, stress_n, state_n, dstrain, dspin, prm, sin_phi_star, stress, state,
                         tangent, status)
        else:
            status[i] = STATUS_FAILED
        _finish(stress_n, state_n, stress, state, tangent, status, i, prm[BULK], prm[SHEAR])

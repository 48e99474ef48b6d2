r"""Tier 2: the cone whose axis follows the fabric — strength and dilatancy carried by it.

Conventions (docs/theory.md §1): tension positive, P = -(σxx + σyy)/2, the deviator
s = ((σxx - σyy)/2, σxy), Voigt stress (σxx, σyy, σxy), Voigt strain with engineering
shear, spin increment Δω counter-clockwise. State columns (gp, c, A, Bc, Bs), the fabric
p(θ) = A + Bc cos 2θ + Bs sin 2θ (docs/theory.md §2).

**Model** (docs/theory.md §6). In 2D the stress–force–fabric relation (Rothenburg &
Bathurst 1989) splits the stress ratio into a contact part and a force part,
t = -s/P = ½ a_c e(θp) + (force part), with a_c = B/A the contact anisotropy and
e(θ) = (cos 2θ, sin 2θ); measured on the DEM the contacts carry 43–46 % of the steady
ratio and the forces the rest, and right after a reversal the old fabric *opposes* the
new loading (docs/stress_force_fabric.md). Tier 2 takes the fabric part as the axis of a
cone and bounds the force part by its radius:

    f(σ; c, q) = |s + P α(q)| - m(c) P <= 0,      α(q) = w (Bc, Bs)/A,
    m(c) = sin φ(c) - w b_c,

φ(c) tier 1's friction angle (φ*, φ', clamps of ``[tier1]``), w the fabric weight (½ in
the stress–force–fabric relation), b_c the critical anisotropy B/A. Where the fabric is
the critical one aligned with the loading, |t| = w b_c + m(c) = sin φ(c): tier 1's
strength. With an isotropic fabric (a fresh sample) the strength is m(c) < sin φ(c) and
builds up with the fabric; right after a reversal it is m(c) - w b_c, the fabric
opposing the loading, and recovers as the fabric turns. f is homogeneous of degree 1 in σ
(a cone, no stress scale).

**Flow.** With u = s + P α and û = u/|u|, the plastic increment has the deviatoric
direction û (coaxial with the force part, not with the stress) and the dilatancy D,

    Δεp = Δγ (½(D + û_x), ½(D - û_x), û_y),     Δεp1 - Δεp2 = Δγ,   tr Δεp = D Δγ,
    D = sin ψ(c) + k_d (ā - w b_c),   ā = -α·û,

ψ(c) tier 1's dilatancy angle and ā the fabric part's alignment with the flow's
compression axis. On the cone ā = t·n - m(c), n = -û, so D is Rowe–Taylor's gap between
the mobilized ratio along the flow and the one the critical fabric supports
(d = k (R/P - M) on the DEM, k ≈ 0.9–1.1), plus tier 1's packing term: zero at the
critical state, compaction right after a reversal (ā ≈ -w b_c), tier 1's dilatancy where
the fabric is critical and aligned.

**Fabric** q = (A, Bc, Bs) evolves with Δεp by the law of ``[tier2] fabric_law``
(:func:`contfab.models.fabric_law.fabric_step`: relaxation toward the critical fabric
aligned with the flow's compression axis at rate k per unit plastic shear, or the
projected balance law), after the spin has turned it by 2Δω.

**Update** of one point (backward Euler, fully implicit):

1. Objective rotation by the exact angle Δω of σ_n and (Bc, Bs) (as tiers 0/1).
2. Elastic predictor with the regularization: s_tr = s_n + G (Δεxx - Δεyy, Δγxy),
   P_tr = P_n - K tr Δε.
3. f(σ_tr; c_n, q_n) <= YIELD_TOL |σ_tr|: elastic (status 0), tangent C.
4. Otherwise unknowns x = (s_x, s_y, P, Δγ, c, A, Bc, Bs) and residuals

       s - s_tr + G Δγ û = 0,       P - P_tr - K D Δγ = 0,      |u| - m(c) P = 0,
       c - c_n exp(-D Δγ) = 0,      q - Φ(q_n, Δεp, c) = 0,

   solved by Newton with the analytic Jacobian (:func:`_assemble`) and backtracking on the
   scaled residual, from the return at the frozen start state (:func:`_frozen_return`: with
   α, m, D of the start, u stays parallel to u_tr + Δγ K D α and one scalar equation in
   Δγ remains). Accepted with Δγ >= 0 and P > 0 (status 1; status 3 where the fabric law
   had to be projected onto the admissible set).
5. Apex (status 2): where the frozen return reaches P = 0 before the cone (a contracting
   flow from a small pressure, or P_tr <= 0 with no face point): σ = 0, all of C⁻¹σ_tr
   plastic, c = c_n exp(P_tr/K), zero tangent (as tier 1).
6. gp += Δγ; the fabric is Φ(q_n, Δεp, c_{n+1}), admissible.

**Consistent tangent** ∂σ_{n+1}/∂Δε = the σ rows of -J⁻¹ ∂r/∂Δε (only s_tr and P_tr
depend on Δε), fabric coupling included; tested against central differences.

**Failures** (status -1): non-finite input, c outside (0, 1), a local solve that does not
converge; the point returns its input stress and state and the elastic tangent.

**Parameter array** (:meth:`contfab.params.Params.array`, named offsets of
:mod:`contfab.params`): ``BULK``, ``SHEAR``, tier 1's ``PHI_STAR`` ... ``PHI_MAX`` and
``FABRIC_WEIGHT`` w, ``DILATANCY_FABRIC`` k_d, ``FABRIC_LAW`` and the laws' constants.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit, prange

from contfab.jit_flags import KERNEL
from contfab.models.cone import (STATUS_APEX, STATUS_ELASTIC, STATUS_FACE, STATUS_FAILED,
                                 _finish, _inputs_finite, tier1_angles)
from contfab.models.fabric_law import balance_work, fabric_step, rotate_fabric
from contfab.params import (A_CRIT, B_RATIO_CRIT, BULK, DILATANCY_FABRIC, FABRIC_LAW,
                            FABRIC_DILATION, FABRIC_SPEED,
                            FABRIC_WEIGHT, K_C, K_O, KAPPA_A, RELAX_RATE, SHEAR)
from contfab.tensors import hypot, isotropic_stiffness_into, rotate

STATUS_PROJECTED = 3
"""Plastic, and the fabric law's result had to be projected onto the admissible set."""

N_X = 8
"""Unknowns of the local solve: (s_x, s_y, P, Δγ, c, A, Bc, Bs)."""
YIELD_TOL = 1e-10
"""Elastic where f(σ_tr) <= YIELD_TOL·|σ_tr| (keeps a state left on the cone, to the local
solve's tolerance, elastic under a pure rotation)."""
NEWTON_MAXIT = 50
NEWTON_TOL = 1e-12
"""Converged when every scaled residual (stress rows per |σ_tr|) is below NEWTON_TOL."""
FROZEN_MAXIT = 100

Scratch = namedtuple("Scratch", ("x", "res", "jac", "piv", "rhs", "trial", "q", "dq", "dep",
                                 "du", "dx", "xb", "ws"))


@njit(cache=True)
def _scratch():
    """Work arrays of one thread's range of points (allocated once per range)."""
    return Scratch(np.empty(N_X), np.empty(N_X), np.empty((N_X, N_X)),
                   np.empty(N_X, dtype=np.int64), np.empty((N_X, 3)), np.empty(5),
                   np.empty(3), np.empty((4, 3)), np.empty((3, N_X)), np.empty((2, N_X)),
                   np.empty(N_X), np.empty(N_X), balance_work())


@njit(**KERNEL, inline="always")
def _lu(a, piv, n):
    """In-place LU with partial pivoting of a[:n, :n]; False if singular."""
    for k in range(n):
        p = k
        big = abs(a[k, k])
        for i in range(k + 1, n):
            if abs(a[i, k]) > big:
                big = abs(a[i, k])
                p = i
        if not big > 0.0:
            return False
        piv[k] = p
        if p != k:
            for j in range(n):
                a[k, j], a[p, j] = a[p, j], a[k, j]
        inv = 1.0 / a[k, k]
        for i in range(k + 1, n):
            a[i, k] *= inv
            f = a[i, k]
            if f != 0.0:
                for j in range(k + 1, n):
                    a[i, j] -= f * a[k, j]
    return True


@njit(**KERNEL, inline="always")
def _lu_solve(lu, piv, b, n, m):
    """Solve (LU) X = b in place for the m columns of b[:n, :m]."""
    for col in range(m):
        for k in range(n):
            p = piv[k]
            if p != k:
                b[k, col], b[p, col] = b[p, col], b[k, col]
        for i in range(n):
            acc = b[i, col]
            for j in range(i):
                acc -= lu[i, j] * b[j, col]
            b[i, col] = acc
        for i in range(n - 1, -1, -1):
            acc = b[i, col]
            for j in range(i + 1, n):
                acc -= lu[i, j] * b[j, col]
            b[i, col] = acc / lu[i, i]


@njit(**KERNEL, inline="always")
def _strength(c, prm):
    """(m, ∂m/∂c, sin ψ, ∂ sin ψ/∂c, w b_c) at packing fraction c (module doc)."""
    phi, psi, phi_c, psi_c = tier1_angles(c, prm)
    shift = prm[FABRIC_WEIGHT] * prm[B_RATIO_CRIT]
    return (np.sin(phi) - shift, np.cos(phi) * phi_c, np.sin(psi), np.cos(psi) * psi_c,
            shift)


@njit(**KERNEL, inline="always")
def _fabric(q0, bc, bs, dexx, deyy, dgxy, c, prm, sc):
    """Φ(q_n, Δεp, c) into sc.q, ∂Φ into sc.dq; True if projected onto the admissible set."""
    return fabric_step(q0, bc, bs, dexx, deyy, dgxy, c, int(prm[FABRIC_LAW]), prm[KAPPA_A],
                       prm[K_C], prm[K_O], prm[A_CRIT], prm[B_RATIO_CRIT], prm[RELAX_RATE],
                       prm[FABRIC_SPEED], prm[FABRIC_DILATION], sc.q, sc.dq, sc.ws)


@njit(**KERNEL)
def _assemble(c_n, q0, bc0, bs0, prm, sc, s_ref):
    """Residuals r(x) into sc.res (stress rows divided by s_ref) and, with them, the
    Jacobian ∂r/∂x into sc.jac (the same scaling)."""
    x = sc.x
    res = sc.res
    jac = sc.jac
    tr = sc.trial
    bulk = prm[BULK]
    shear = prm[SHEAR]
    w = prm[FABRIC_WEIGHT]
    kd = prm[DILATANCY_FABRIC]
    sx, sy, p, dgam, c, a, bc, bs = x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7]
    m, m_c, spsi, spsi_c, shift = _strength(c, prm)
    ax = w * bc / a
    ay = w * bs / a
    ux = sx + p * ax
    uy = sy + p * ay
    nu = hypot(ux, uy)
    hx = ux / nu
    hy = uy / nu
    abar = -(ax * hx + ay * hy)
    d = spsi + kd * (abar - shift)
    # Derivatives by unknown j: du (2 x 8), dû = (I - ûûᵀ) du / |u|, dα (2 x 8).
    for j in range(N_X):
        for k in range(N_X):
            jac[j, k] = 0.0
    dux = sc.du[0]   # ∂u_x/∂x_j
    duy = sc.du[1]   # ∂u_y/∂x_j
    for j in range(N_X):
        dux[j] = 0.0
        duy[j] = 0.0
    dux[0] = 1.0
    duy[1] = 1.0
    dux[2] = ax
    duy[2] = ay
    # α = w (bc, bs)/a: ∂α/∂a = -α/a, ∂α_x/∂bc = w/a, ∂α_y/∂bs = w/a
    dax5 = -ax / a
    day5 = -ay / a
    dax6 = w / a
    day7 = w / a
    dux[5] = p * dax5
    duy[5] = p * day5
    dux[6] = p * dax6
    duy[7] = p * day7
    pxx = (1.0 - hx * hx) / nu
    pxy = -hx * hy / nu
    pyy = (1.0 - hy * hy) / nu
    dep = sc.dep
    # Row blocks use dû_j and dD_j; Δεp = Δγ (½(D + û_x), ½(D - û_x), û_y).
    for j in range(N_X):
        dhx = pxx * dux[j] + pxy * duy[j]
        dhy = pxy * dux[j] + pyy * duy[j]
        dax = dax5 if j == 5 else (dax6 if j == 6 else 0.0)
        day = day5 if j == 5 else (day7 if j == 7 else 0.0)
        dabar = -(dax * hx + day * hy + ax * dhx + ay * dhy)
        dd = kd * dabar + (spsi_c if j == 4 else 0.0)
        dg = 1.0 if j == 3 else 0.0
        jac[0, j] = ((1.0 if j == 0 else 0.0) + shear * (dgam * dhx + dg * hx)) / s_ref
        jac[1, j] = ((1.0 if j == 1 else 0.0) + shear * (dgam * dhy + dg * hy)) / s_ref
        jac[2, j] = ((1.0 if j == 2 else 0.0) - bulk * (dgam * dd + dg * d)) / s_ref
        jac[3, j] = (hx * dux[j] + hy * duy[j] - (m if j == 2 else 0.0)
                     - (p * m_c if j == 4 else 0.0)) / s_ref
        dvol = dgam * dd + dg * d        # ∂(D Δγ)
        jac[4, j] = (1.0 if j == 4 else 0.0) + c_n * np.exp(-d * dgam) * dvol
        dep[0, j] = 0.5 * (dgam * (dd + dhx) + dg * (d + hx))
        dep[1, j] = 0.5 * (dgam * (dd - dhx) + dg * (d - hx))
        dep[2, j] = dgam * dhy + dg * hy
    res[0] = (sx - tr[0] + shear * dgam * hx) / s_ref
    res[1] = (sy - tr[1] + shear * dgam * hy) / s_ref
    res[2] = (p - tr[2] - bulk * d * dgam) / s_ref
    res[3] = (nu - m * p) / s_ref
    res[4] = c - c_n * np.exp(-d * dgam)
    _fabric(q0, bc0, bs0, 0.5 * dgam * (d + hx), 0.5 * dgam * (d - hx), dgam * hy,
            c, prm, sc)
    q = sc.q
    dq = sc.dq
    for i in range(3):
        res[5 + i] = x[5 + i] - q[i]
        for j in range(N_X):
            v = dq[0, i] * dep[0, j] + dq[1, i] * dep[1, j] + dq[2, i] * dep[2, j]
            if j == 4:
                v += dq[3, i]
            jac[5 + i, j] = (1.0 if j == 5 + i else 0.0) - v


@njit(**KERNEL, inline="always")
def _res_norm(res):
    r = 0.0
    for k in range(N_X):
        r = max(r, abs(res[k]))
    return r


@njit(**KERNEL)
def _frozen_return(c_n, q0, bc0, bs0, prm, sc):
    """The return at the start state (α, m, D of q_n, c_n and the trial's direction) into
    sc.x. Returns 1 (a face point, P > 0), 2 (the apex: P reaches 0 first) or -1.

    With α, m, D fixed, s = s_tr - GΔγû and P = P_tr + KDΔγ give
    u (|u| + GΔγ)/|u| = u_tr + ΔγKDα: û is the direction of v(Δγ) = u_tr + ΔγKDα, and
    h(Δγ) = |v| - GΔγ - m (P_tr + KDΔγ) = 0 is one equation, h(0) = f_tr > 0, solved by
    bisection-safeguarded Newton on its bracket.
    """
    tr = sc.trial
    bulk = prm[BULK]
    shear = prm[SHEAR]
    w = prm[FABRIC_WEIGHT]
    m, _, spsi, _, shift = _strength(c_n, prm)
    ax = w * bc0 / q0
    ay = w * bs0 / q0
    utx = tr[0] + tr[2] * ax
    uty = tr[1] + tr[2] * ay
    nu = hypot(utx, uty)
    hx = utx / nu if nu > 0.0 else 1.0
    hy = uty / nu if nu > 0.0 else 0.0
    d = spsi + prm[DILATANCY_FABRIC] * (-(ax * hx + ay * hy) - shift)
    kdx = bulk * d * ax
    kdy = bulk * d * ay
    # Upper end of the bracket: where P reaches 0 (contracting flow), else where h < 0.
    lo = 0.0
    if d < 0.0:
        hi = tr[2] / (-bulk * d)
        if not hi > 0.0:
            return 2
        h_hi = hypot(utx + hi * kdx, uty + hi * kdy) - shear * hi
        if h_hi >= 0.0:
            return 2
    else:
        if tr[2] <= 0.0 and d == 0.0:
            return 2
        hi = max(nu, abs(tr[2])) / shear
        for _ in range(200):
            if hypot(utx + hi * kdx, uty + hi * kdy) - shear * hi - m * (tr[2] + bulk * d * hi) < 0.0:
                break
            hi *= 2.0
        else:
            return -1
    g = 0.5 * (lo + hi)
    for _ in range(FROZEN_MAXIT):
        vx = utx + g * kdx
        vy = uty + g * kdy
        nv = hypot(vx, vy)
        h = nv - shear * g - m * (tr[2] + bulk * d * g)
        if h > 0.0:
            lo = g
        else:
            hi = g
        dh = (vx * kdx + vy * kdy) / nv - shear - m * bulk * d if nv > 0.0 else -shear
        step = g - h / dh if dh < 0.0 else 0.5 * (lo + hi)
        if not (lo < step < hi):
            step = 0.5 * (lo + hi)
        if abs(step - g) <= 1e-15 * max(g, 1e-300) or hi - lo <= 1e-15 * hi:
            g = step
            break
        g = step
    vx = utx + g * kdx
    vy = uty + g * kdy
    nv = hypot(vx, vy)
    if not nv > 0.0:
        return 2
    hx = vx / nv
    hy = vy / nv
    p = tr[2] + bulk * d * g
    if not p > 0.0:
        return 2
    x = sc.x
    x[0] = tr[0] - shear * g * hx
    x[1] = tr[1] - shear * g * hy
    x[2] = p
    x[3] = g
    x[4] = c_n * np.exp(-d * g)
    _fabric(q0, bc0, bs0, 0.5 * g * (d + hx), 0.5 * g * (d - hx), g * hy, x[4], prm, sc)
    x[5] = sc.q[0]
    x[6] = sc.q[1]
    x[7] = sc.q[2]
    return 1


@njit(**KERNEL)
def _newton(c_n, q0, bc0, bs0, prm, sc, s_ref):
    """Newton on r(x) = 0 from sc.x (module doc, step 4); True when converged to an
    admissible face point (Δγ >= 0, P > 0, c in (0, 1), A > 0). Leaves the LU of the
    converged Jacobian in sc.jac / sc.piv for the tangent."""
    x = sc.x
    xb = sc.xb
    dx = sc.dx
    for _ in range(NEWTON_MAXIT):
        _assemble(c_n, q0, bc0, bs0, prm, sc, s_ref)
        r0 = _res_norm(sc.res)
        if not np.isfinite(r0):
            return False
        if r0 <= NEWTON_TOL:
            if not _lu(sc.jac, sc.piv, N_X):
                return False
            return x[3] >= 0.0 and x[2] > 0.0 and 0.0 < x[4] < 1.0 and x[5] > 0.0
        if not _lu(sc.jac, sc.piv, N_X):
            return False
        for k in range(N_X):
            sc.rhs[k, 0] = -sc.res[k]
        _lu_solve(sc.jac, sc.piv, sc.rhs, N_X, 1)
        for k in range(N_X):
            xb[k] = x[k]
            dx[k] = sc.rhs[k, 0]
        # Backtracking: halve the step until the scaled residual decreases and the
        # iterate stays where the residual is defined (P, A > 0, 0 < c < 1, Δγ >= 0 -ish).
        t = 1.0
        accepted = False
        for _ in range(30):
            for k in range(N_X):
                x[k] = xb[k] + t * dx[k]
            if x[5] > 0.0 and 0.0 < x[4] < 1.0 and x[3] > -1e-3:
                _assemble(c_n, q0, bc0, bs0, prm, sc, s_ref)
                r1 = _res_norm(sc.res)
                if r1 < r0 or r1 <= NEWTON_TOL:
                    accepted = True
                    break
            t *= 0.5
        if not accepted:
            return False
    return False


@njit(**KERNEL)
def _tangent(prm, sc, s_ref, tangent, i):
    """∂σ/∂Δε from the LU of the converged Jacobian (module doc): J dx = -∂r/∂Δε, where
    only the first three rows depend on Δε (through s_tr and P_tr), scaled by s_ref."""
    bulk = prm[BULK]
    shear = prm[SHEAR]
    rhs = sc.rhs
    for k in range(N_X):
        for j in range(3):
            rhs[k, j] = 0.0
    # r0 = (s_x - s_tr,x ...)/s_ref: ∂s_tr,x/∂Δε = G (1, -1, 0); r1: G (0, 0, 1);
    # r2 = (P - P_tr ...)/s_ref: ∂P_tr/∂Δε = -K (1, 1, 0). rhs = -∂r/∂Δε.
    rhs[0, 0] = shear / s_ref
    rhs[0, 1] = -shear / s_ref
    rhs[1, 2] = shear / s_ref
    rhs[2, 0] = -bulk / s_ref
    rhs[2, 1] = -bulk / s_ref
    _lu_solve(sc.jac, sc.piv, rhs, N_X, 3)
    for j in range(3):
        tangent[i, 0, j] = -rhs[2, j] + rhs[0, j]
        tangent[i, 1, j] = -rhs[2, j] - rhs[0, j]
        tangent[i, 2, j] = rhs[1, j]


@njit(**KERNEL)
def _point(i, stress_n, state_n, dstrain, dspin, prm, stress, state, tangent, status, sc):
    bulk = prm[BULK]
    shear = prm[SHEAR]
    c_n = state_n[i, 1]
    q0 = state_n[i, 2]
    if not (0.0 < c_n < 1.0) or not q0 > 0.0:
        status[i] = STATUS_FAILED
        return
    rxx, ryy, rxy = rotate(stress_n[i, 0], stress_n[i, 1], stress_n[i, 2], dspin[i])
    bc0, bs0 = rotate_fabric(state_n[i, 3], state_n[i, 4], dspin[i])
    dexx = dstrain[i, 0]
    deyy = dstrain[i, 1]
    dgxy = dstrain[i, 2]
    txx = rxx + (bulk + shear) * dexx + (bulk - shear) * deyy
    tyy = ryy + (bulk - shear) * dexx + (bulk + shear) * deyy
    txy = rxy + shear * dgxy
    tr = sc.trial
    tr[0] = 0.5 * (txx - tyy)
    tr[1] = txy
    tr[2] = -0.5 * (txx + tyy)
    s_ref = hypot(tr[2], hypot(tr[0], tr[1]))
    state[i, 0] = state_n[i, 0]
    state[i, 1] = c_n
    state[i, 2] = q0
    state[i, 3] = bc0
    state[i, 4] = bs0
    m, _, _, _, _ = _strength(c_n, prm)
    w = prm[FABRIC_WEIGHT]
    f_tr = hypot(tr[0] + tr[2] * w * bc0 / q0, tr[1] + tr[2] * w * bs0 / q0) - m * tr[2]
    if f_tr <= YIELD_TOL * s_ref:
        stress[i, 0] = txx
        stress[i, 1] = tyy
        stress[i, 2] = txy
        isotropic_stiffness_into(bulk, shear, tangent[i])
        status[i] = STATUS_ELASTIC
        return
    kind = _frozen_return(c_n, q0, bc0, bs0, prm, sc) if s_ref > 1e-200 * (bulk + shear) else 2
    face = kind == 1 and _newton(c_n, q0, bc0, bs0, prm, sc, s_ref)
    x = sc.x
    if face:
        sx, sy, p, dgam, c1 = x[0], x[1], x[2], x[3], x[4]
        stress[i, 0] = -p + sx
        stress[i, 1] = -p - sx
        stress[i, 2] = sy
        _tangent(prm, sc, s_ref, tangent, i)
        # The fabric law at the final (Δεp, c), from C⁻¹(σ_tr - σ): admissible, and equal
        # to x[5:8] to the solve's tolerance.
        pxx = 0.5 * ((tr[2] - p) / bulk * -1.0) + 0.5 * (tr[0] - sx) / shear
        pyy = 0.5 * ((tr[2] - p) / bulk * -1.0) - 0.5 * (tr[0] - sx) / shear
        pgg = (tr[1] - sy) / shear
        projected = _fabric(q0, bc0, bs0, pxx, pyy, pgg, c1, prm, sc)
        state[i, 0] = state_n[i, 0] + dgam
        state[i, 1] = c1
        status[i] = STATUS_PROJECTED if projected else STATUS_FACE
    elif kind == 2:
        # The apex: σ = 0, all of C⁻¹σ_tr plastic.
        stress[i, :] = 0.0
        tangent[i, :, :] = 0.0
        pxx = 0.5 * (-tr[2] / bulk) + 0.5 * tr[0] / shear
        pyy = 0.5 * (-tr[2] / bulk) - 0.5 * tr[0] / shear
        pgg = tr[1] / shear
        c1 = c_n * np.exp(tr[2] / bulk)
        projected = _fabric(q0, bc0, bs0, pxx, pyy, pgg, c1, prm, sc)
        state[i, 0] = state_n[i, 0] + hypot(pxx - pyy, pgg)
        state[i, 1] = c1
        status[i] = STATUS_PROJECTED if projected else STATUS_APEX
    else:
        status[i] = STATUS_FAILED
        return
    state[i, 2] = sc.q[0]
    state[i, 3] = sc.q[1]
    state[i, 4] = sc.q[2]


@njit(cache=True, error_model="numpy")
def _update_range(lo, hi, stress_n, state_n, dstrain, dspin, prm, stress, state, tangent, status):
    """Update points lo..hi-1 (scratch allocated once per range, never per point)."""
    sc = _scratch()
    for i in range(lo, hi):
        if _inputs_finite(stress_n, state_n, dstrain, dspin, i):
            _point(i, stress_n, state_n, dstrain, dspin, prm, stress, state, tangent, status, sc)
        else:
            status[i] = STATUS_FAILED
        _finish(stress_n, state_n, stress, state, tangent, status, i, prm[BULK], prm[SHEAR])


@njit(cache=True, parallel=True, error_model="numpy")
def update_points(stress_n, state_n, dstrain, dspin, prm, stress, state, tangent, status):
    """Tier 2 update of every point, threads over chunks (layout of ``prm``: module doc)."""
    n = stress_n.shape[0]
    n_chunks = min(n, 64)
    for chunk in prange(n_chunks):
        _update_range(chunk * n // n_chunks, (chunk + 1) * n // n_chunks, stress_n, state_n,
                      dstrain, dspin, prm, stress, state, tangent, status)

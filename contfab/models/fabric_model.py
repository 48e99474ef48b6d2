r"""Tier 2: slip-plane yield, plane-wise flow, fabric hardening — the return mapping.

Conventions (docs/theory.md §1): tension positive, Voigt stress (σxx, σyy, σxy), Voigt strain with
engineering shear, spin increment Δω counter-clockwise. State columns (gp, c, A, Bc, Bs).
Yield f and flow N: :mod:`contfab.models.slip_planes`; fabric laws:
:mod:`contfab.models.fabric_law`.

**Update** of one point, stress σ_n, state q_n, increments (Δε, Δω):

1. Objective rotation by the exact angle Δω (as tiers 0/1): σ_n ← Q σ_n Qᵀ and the fabric
   (Bc, Bs) turned by 2Δω, so a rigid rotation leaves A and B unchanged and turns θp by Δω.
2. Elastic predictor σ_tr = σ_n + C Δε (C: the isotropic regularization K, G).
3. f(σ_tr; q_n, c_n) <= 1e-10·|σ_tr|: elastic (status 0), tangent C. (The tolerance keeps a
   state left on the surface by the previous step — to the local solve's 1e-12 — elastic
   under a pure rotation, which is then exact.) Where |f_tr| is far from the tolerance the
   planes' predicted maxima decide it, and a plastic point keeps their terms for step 4's
   start (:func:`_trial_yield`); otherwise the exact plane search does.
4. Otherwise backward Euler on the face, fully implicit: unknowns x = (σ, Δγ, c, A, Bc, Bs),

       σ - σ_tr + Δγ C N(σ, c, q) = 0,         f(σ, c, q) = 0,
       c - c_n exp(-Δγ tr N) = 0,               q - Φ(q_n, Δγ N, c) = 0,

   q = (A, Bc, Bs) the fabric at the END of the step and Φ the fabric law's step
   (:func:`contfab.models.fabric_law.fabric_step`, from the rotated q_n); c is implicit
   exactly as in tier 1 (which makes the reduction to tier 1 exact). Local Newton with the
   analytic Jacobian (8x8; the slip planes condensed into it), from one cutting-plane step
   (near the surface) or tier 1's closed-form coaxial return; backtracking on max |residual|.
   Where Newton fails from both (increments of hundreds of percent), the same problem is
   reached by continuation in the trial stress (:func:`_continuation_return`). Near the apex
   (returns long against the stress they leave, |σ_tr - σ| >> P) Newton in σ converges only
   from starts within ~P of the solution, as N turns with the direction of σ at a rate 1/|σ|;
   where every start fails, and for every trial that tier 1's apex criterion (5.) takes on an
   anisotropic fabric, the face scan solves it (:func:`_scan_return`): at a fixed state,
   σ = P σ̂(α) (σ̂ the face point at P = 1 of principal direction α) makes the stress
   equations σ_tr = P σ̂(α) + Δγ C N(α) linear in (P, Δγ) and leaves one equation in α,
   sampled over [0, π) and refined in each bracket (where the flow jumps across a ridge of
   f, with the ridge's flows); a root with Δγ > 0 and P > 0, at the state of its own step,
   starts Newton.
   The face solution is accepted when it converged with Δγ >= 0 and P > 0, it lies on its
   own surface to YIELD_TOL·|σ| (:func:`_resolved`: Newton can reach σ ~ 0 past the apex,
   where f/|σ_tr| vanishes in any direction) and its planes
   are the arcs' maxima (status 1): where φ depends on θ an arc can have several local
   maxima (its ends, corners of the clamp of φ: slip_planes), and a solve on a lesser one is
   solved again from the searched planes (:func:`_face_return`). Where each one-plane
   solution makes the other plane the arc's higher one, the solution lies on a ridge of f:
   both planes carry the arc's maximum, h_a = h_b, and the arc's flow is λ N_a + (1 - λ) N_b,
   0 <= λ <= 1 (Koiter's rule; :func:`_ridge_residual`, one more unknown λ and equation).
   Its Newton (:func:`_ridge_newton`) keeps the three planes inside their arcs after each
   step: on loose states the arc's maxima are corners of φ's clamp next to the arc's ends,
   and a plane a step took past an end otherwise stalled the solve.
5. Apex (status 2): σ = 0, all of C⁻¹σ_tr plastic, c = c_n exp(P_tr/K), zero tangent
   (as tier 1), where C⁻¹σ_tr dilates at least as much as the admissible flow of its
   direction: the region is set by the plastic potential, not the yield function
   (docs/theory.md §4). With φ and ψ the same on every plane (a2 = b2 = 0) that is tier 1's criterion
   G P_tr + K sin ψ R_tr <= 0 (P <= 0 of its closed-form return), with ψ(θ)'s isotropic part
   at c_apex. Otherwise the flow's dilatancy depends on its direction (over the face of the
   start state of tests/test_fabric_model.py ``NEAR_APEX_FLICKER``, B/A = 0.64, tr/(ε1 - ε2)
   runs from -0.076 to +0.032 with the direction, sin ψ̄ = -0.012),
   and the scan decides at the apex's state: the apex where the return along an admissible
   flow passes the apex (a root with Δγ > 0 and P <= 0: C⁻¹σ_tr = Δγ N - P C⁻¹σ̂, the flow
   plus the dilating strain of taking a compression off) and no root gives a face point;
   face and apex meet continuously there.
   A face root whose solve fails is a failure (status -1), never the apex.
6. Δεp = C⁻¹(σ_tr - σ_{n+1}), gp += Δεp1 - Δεp2, and the fabric is Φ(q_n, Δεp, c_{n+1})
   (admissible; equal to the q of the solve to its tolerance); if Φ had to project it onto
   the admissible set, status 3.

Backward Euler is first order in the step size (tests/test_fabric_model.py measures the
order); every returned state lies on its own yield surface, f(σ_{n+1}; q_{n+1}, c_{n+1}) = 0.

**Consistent tangent** ∂σ_{n+1}/∂Δε: with the converged Jacobian J of the residuals r(x; Δε),
dx/dΔε = J⁻¹ [C; 0] (the only Δε-dependence is σ_tr), fabric coupling included; tested
against central differences of the whole update (through the fabric's projection when it
acts, and on a ridge: J of the ridge return there).

**Failures** (status -1): non-finite input, c outside (0, 1), a face solve that does not
converge (or whose ridge return leaves 0 <= λ <= 1, or finds a third plane higher) from any
start, the scan's included, where the scan does not put the trial at the apex, a non-finite
result. The point returns its input stress
and state and the elastic tangent; nothing non-finite is produced.

A step past a limit point of the regularized model fails too, deliberately. f's fabric
derivatives grow with |σ| and the elastic part of the return, ∂f/∂σ C N, with K and G: at
stresses of order the moduli (P ~ 3 K, far above p_ref) the fabric's evolution can raise f
as fast as the flow relaxes the stress, and the strain-driven response itself reaches a
limit point (tests/test_fabric_model.py, ``LIMIT_POINT_STEP``: P = 3101 p_ref = 3.1 K, 0.3 %
past the end of the step). Near it the step's backward-Euler problem keeps a root only far out
(Δγ = 0.15 for a strain increment of 6e-4, the fabric turned round): a solution of the
equations, but not of the path (substeps converge to a point 76 p_ref away), so no solve
here looks for it; the caller cuts the step.

**Compilation.** Every function here except the allocating ones (``_scratch``,
``_update_range``, ``update_points``), and those of :mod:`contfab.models.slip_planes` and
:mod:`contfab.models.fabric_law` (but ``drive_fabric``), is compiled with
:data:`contfab.jit_flags.KERNEL`: no reference counting (they never allocate), FMA
contraction (why, and what each flag gains: :mod:`contfab.jit_flags`).

Inlined at numba's level (``inline="always"``): the LU and its solves (with a constant
size, so they unroll), the residuals (``_residual``, ``_assemble``), the planes' check and
step, the face point's check (``_resolved``), and of the callees
``slip_planes.yield_and_flow`` with ``plane_terms`` and ``fabric_law.relaxation_step`` (inside
``fabric_step``). Each call of these passed the
scratch's arrays as a dozen fields apiece; inlining them took the bench's tier-2 update
from 3.3 to 2.8 µs, outputs bitwise unchanged (measured). Inlining the plane
search too (``yield_value``, ``arc_maxima``, ``_refine_on_arc``, ``_h_on_arc``) and the
start (``_cutting_plane_guess``) gained ~2 % more for a cold compile of 2.5 min instead of
1.5: not done.

Each call site of an inlined function is a copy of it that numba compiles anew, and every
compiled caller above optimizes it again, so they are called from as few sites as the algorithm
allows: the local Newton evaluates its residuals at one site for its start and its restart, the
ridge return its two configurations in a loop. A constant count or switch passed to a compiled
(not inlined) callee is a NumPy scalar (``slip_planes.WARM_START``, :data:`ONE_STEP`,
``np.True_``), not a Python literal, which numba would compile the callee for once per value.
Together these took a cold compile of :func:`update_points` (one update, fresh cache, one
thread; the two compiles side by side on a loaded 2-core machine) from 117 to 86 s of CPU time
(another pair: 106 to 78 s), outputs bitwise unchanged and the update's speed within noise
(kernel alone, median of the minimum per-update CPU time of 3 interleaved runs: 1.77 -> 1.78
µs, anisotropic fabric 1.86 -> 1.85 µs). Compiling ``_residual`` out of line as well took a
further ~17 % off the compile but slowed the update by 1-4 %: not done.

**Parameter array** (:meth:`contfab.params.Params.array` (2): the ``[regularization]``,
``[tier1]`` and ``[tier2]`` parts; angles in radians), read by the named offsets of
:mod:`contfab.params`: tier 1's (``BULK`` … ``PHI_MAX``; φ* unused here, a0 plays its role),
then ``A0`` … ``A3`` and ``B0`` … ``B3`` (the plane friction and dilatancy coefficients),
``SHARPNESS`` β, ``N_SEARCH`` (plane-search grid points per arc), ``FABRIC_LAW``
(0 balance, 1 relaxation), ``KAPPA_A``, ``K_C``, ``K_O`` (balance law), ``A_CRIT`` A_c = z_c/π,
``B_RATIO_CRIT`` b_c = B_c/A_c, ``RELAX_RATE`` k (relaxation rate per unit Δγs).
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit, prange

from contfab.jit_flags import KERNEL
from contfab.models.cone import (STATUS_APEX, STATUS_ELASTIC, STATUS_FACE, STATUS_FAILED,
                                 _finish, _inputs_finite)
from contfab.models.fabric_law import balance_work, fabric_step, rotate_fabric
from contfab.models.slip_planes import (N_P, N_PL, N_YF, PL_DT, PL_H, PL_HP, PL_HS, PL_TP, PL_TS,
                                        YF_F, YF_FP, YF_FS, YF_N, YF_NP, YF_NS, YF_TR, YF_TRP,
                                        YF_TRS, WARM_START, arc_maxima, arc_u, fabric_terms,
                                        fabric_terms_jacobian, single_maximum, stress_frame,
                                        yield_and_flow, yield_value)
from contfab.params import (A2, A_CRIT, B2, B_RATIO_CRIT, BULK, FABRIC_LAW, K_C, K_O, KAPPA_A,
                            N_SEARCH, RELAX_RATE, SHARPNESS, SHEAR)
from contfab.tensors import hypot, isotropic_stiffness_into, rotate

STATUS_PROJECTED = 3
"""Plastic (face or apex) and the fabric had to be projected onto the admissible set
(statuses 0, 1, 2, -1 as tiers 0/1: :mod:`contfab.models.cone`)."""

N_PRM = 25
N_X = 8
"""Unknowns of the local solve: σ (3), Δγ, c, A, Bc, Bs."""
N_XR = 9
"""Unknowns of the ridge return: those and λ, the share of the first of the arc's planes."""
YIELD_TOL = 1e-10
"""Elastic check: f(σ_tr) <= YIELD_TOL · |σ_tr| is elastic."""
NEWTON_MAXIT = 40
NEWTON_TOL = 1e-12
"""Local solve: max |residual| (stress residuals relative to |σ_tr|, c absolute)."""
CUTTING_PLANE_RANGE = 0.1
"""Local solve: trial states with f_tr <= this · |σ_tr| start from a cutting-plane step."""
NEWTON_TOL_LAST = 1e-8
"""Local solve: from max |residual| below this the Newton step is the last (no re-evaluation)."""
PLANE_STEP_TOL = 1e-9
"""Local solve: the planes' own Newton steps (radians) at convergence (values exact to ~δθ²)."""
CONTINUATION_STEPS = 4
"""Fallback of the local solve: trial stresses σ_n + (k/this) CΔε, k = 1..this, in turn."""
RESOLVED_STRESS = 0.1
"""Local solve: a face point with |σ| below this · |σ_tr| is checked on its own surface with
the plane search (:func:`_resolved`)."""
SCAN_POINTS = 32
"""Face scan (:func:`_scan_return`): principal directions sampled over [0, π)."""
SCAN_MAXIT = 100
SCAN_RHO_TOL = 1e-14
SCAN_ROOT_TOL = 1e-12
SCAN_ANGLE_TOL = 1e-13
"""Face scan: iterations of each 1-D solve; the last step of ρ = R/P (:func:`_unit_face`);
|g| (a sine; its round-off is ~1e-14) and the bracket (radians) that end a root's
refinement (:func:`_wedge_root`): a bracket that shrinks with |g| above SCAN_ROOT_TOL holds
a jump of g, not a root."""
SCAN_STATE_MAXIT = 4
SCAN_STATE_TOL = 1e-10
"""Face scan: a root's state (c, A, Bc, Bs) made its own step's, to this change at most."""
ONE_STEP = np.int64(1)
"""Plane refinements of a single Newton step (the cutting-plane start, the predicted maxima);
a NumPy scalar, not a literal (module doc, **Compilation**)."""
PREDICTED_PLANE_STEP = 1e-2
PREDICTED_F_GAP = 1e-6
"""Elastic check from the predicted plane maxima (:func:`_trial_yield`): the largest plane
step and the least |f|/|σ| (plus the prediction's error bound) it decides."""


# --------------------------------------------------------------------------- small linear algebra

@njit(**KERNEL, inline="always")
def _lu(a, piv, n):
    """In-place LU with partial pivoting of the leading n x n block of ``a``, PA = LU (L unit
    lower, row k swapped with piv[k] at step k); False if singular.

    Inlined (numba's ``inline="always"``) and called with a constant n (N_X or N_XR), so the
    loops have constant trip counts and compile unrolled: the 8x8 factorization takes about
    half the time of the out-of-line loop over ``a.shape[0]`` (measured), bitwise the same.
    """
    for k in range(n):
        p = k
        big = abs(a[k, k])
        for i in range(k + 1, n):
            v = abs(a[i, k])
            if v > big:
                big = v
                p = i
        piv[k] = p
        if big == 0.0 or not np.isfinite(big):
            return False
        if p != k:
            for j in range(n):
                tmp = a[k, j]
                a[k, j] = a[p, j]
                a[p, j] = tmp
        akk = a[k, k]
        for i in range(k + 1, n):
            lik = a[i, k] / akk
            a[i, k] = lik
            for j in range(k + 1, n):
                a[i, j] -= lik * a[k, j]
    return True


@njit(**KERNEL, inline="always")
def _lu_solve(lu, piv, b, n, m):
    """Solve A x = b in place for the m right-hand sides in the rows of ``b`` (m x n), with
    the factors of :func:`_lu` (leading n x n block): b ← P b, then L y = b forward and
    U x = y backward, each row's sums in locals. Inlined like :func:`_lu`, with constant n
    and m, so the loops unroll and the m substitutions interleave (the tangent's three
    columns: latency shared, measured)."""
    for k in range(n):
        p = piv[k]
        if p != k:
            for c in range(m):
                tmp = b[c, k]
                b[c, k] = b[c, p]
                b[c, p] = tmp
    for i in range(n):
        for c in range(m):
            s = b[c, i]
            for j in range(i):
                s -= lu[i, j] * b[c, j]
            b[c, i] = s
    for i in range(n - 1, -1, -1):
        inv = 1.0 / lu[i, i]
        for c in range(m):
            s = b[c, i]
            for j in range(i + 1, n):
                s -= lu[i, j] * b[c, j]
            b[c, i] = s * inv


# --------------------------------------------------------------------------- the local solve

Scratch = namedtuple("Scratch", "v planes yfs jac jacr piv rhs dpz dq ws")
"""Per-range work arrays of the local solve (allocated once per range, never per point), few
so that passing them costs little: ``v`` the vectors (rows V_*, 9 long), ``planes`` the plane
terms (rows 0-1: the planes of the solve, 2-3: the ridge return's second configuration),
``yfs`` the yield/flow terms (rows: the solve's, the ridge's two configurations), ``jac``,
``jacr`` the Jacobians (8x8, the ridge return's 9x9), ``piv`` their pivots (rows), ``rhs`` the
tangent's three right-hand sides, ``dpz`` ∂p/∂z,
``dq`` and ``ws`` the fabric law's."""
V_TTR, V_X, V_THETA, V_RES, V_DX, V_XT, V_X0, V_DTH, V_FQ, V_THB, V_XR, V_XRT, V_DXR, V_RESR = (
    range(14))


@njit(cache=True)
def _scratch():
    return Scratch(np.zeros((14, N_XR)), np.empty((4, N_PL)), np.empty((3, N_YF)),
                   np.empty((N_X, N_X)), np.empty((N_XR, N_XR)),
                   np.empty((2, N_XR), dtype=np.int64), np.empty((3, N_XR)), np.empty((N_P, 4)),
                   np.empty((4, 3)),
                   balance_work())


@njit(**KERNEL, inline="always")
def _residual(x, c_n, qn, prm, search, sc, s_ref):
    """Residuals of the backward-Euler step at x = (σxx, σyy, σxy, Δγ, c, A, Bc, Bs) into
    row V_RES of ``sc.v`` and their Jacobian into ``sc.jac`` (planes condensed:
    slip_planes.plane_terms):

        (σ - σ_tr + Δγ C N)/|σ_tr|,  f/|σ_tr|,  c - c_n exp(-Δγ tr N),  q - Φ(q_n, Δγ N, c)

    with f, N at (σ, c, q) and Φ the fabric law (from the rotated start fabric ``qn``).
    Row V_THETA: the planes; with ``search`` they are first moved to their exact maxima.
    Returns (max |res| (inf outside the domain c > 0), whether Φ had to be projected).
    """
    if not x[4] > 0.0:
        return np.inf, False
    fab = fabric_terms(x[4], x[5], x[6], x[7], prm, sc.dpz)
    yf = sc.yfs[0]
    yield_and_flow(x[0], x[1], x[2], fab, prm[SHARPNESS], search, WARM_START, sc.v[V_THETA],
                   sc.planes[0:2], yf)
    return _assemble(x, c_n, qn, prm, yf, sc, s_ref, sc.v[V_RES], sc.jac)


@njit(**KERNEL, inline="always")
def _assemble(x, c_n, qn, prm, yf, sc, s_ref, res, jac):
    """The step's residuals (:func:`_residual`) at x into ``res[:8]`` and their Jacobian in
    x[:8] into ``jac[:8, :8]``, from the yield/flow terms ``yf``; (max |res[:8]|, whether Φ
    had to be projected)."""
    bulk = prm[BULK]
    shear = prm[SHEAR]
    dgam = x[3]
    c = x[4]
    fq = sc.v[V_FQ]
    n0 = yf[YF_N]
    n1 = yf[YF_N + 1]
    n2 = yf[YF_N + 2]
    projected = fabric_step(qn[0], qn[1], qn[2], dgam * n0, dgam * n1, dgam * n2, c,
                            int(prm[FABRIC_LAW]), prm[KAPPA_A], prm[K_C], prm[K_O],
                            prm[A_CRIT], prm[B_RATIO_CRIT], prm[RELAX_RATE], fq, sc.dq, sc.ws)
    cn0 = (bulk + shear) * n0 + (bulk - shear) * n1
    cn1 = (bulk - shear) * n0 + (bulk + shear) * n1
    cn2 = shear * n2
    e = c_n * np.exp(-dgam * yf[YF_TR])
    inv = 1.0 / s_ref
    dq = sc.dq
    ttr = sc.v[V_TTR]
    res[0] = (x[0] - ttr[0] + dgam * cn0) * inv
    res[1] = (x[1] - ttr[1] + dgam * cn1) * inv
    res[2] = (x[2] - ttr[2] + dgam * cn2) * inv
    res[3] = yf[YF_F] * inv
    res[4] = c - e
    for i in range(3):
        res[5 + i] = x[5 + i] - fq[i]
    # Columns σ (0-2): C ∂N/∂σ, ∂f/∂σ, ∂trN/∂σ, and Φ through Δεp = Δγ N.
    for j in range(3):
        ns0 = yf[YF_NS + j]
        ns1 = yf[YF_NS + 3 + j]
        ns2 = yf[YF_NS + 6 + j]
        jac[0, j] = ((1.0 if j == 0 else 0.0) + dgam * ((bulk + shear) * ns0 + (bulk - shear) * ns1)) * inv
        jac[1, j] = ((1.0 if j == 1 else 0.0) + dgam * ((bulk - shear) * ns0 + (bulk + shear) * ns1)) * inv
        jac[2, j] = ((1.0 if j == 2 else 0.0) + dgam * shear * ns2) * inv
        jac[3, j] = yf[YF_FS + j] * inv
        jac[4, j] = e * dgam * yf[YF_TRS + j]
        for i in range(3):
            jac[5 + i, j] = -dgam * (dq[0, i] * ns0 + dq[1, i] * ns1 + dq[2, i] * ns2)
    # Column Δγ (3).
    jac[0, 3] = cn0 * inv
    jac[1, 3] = cn1 * inv
    jac[2, 3] = cn2 * inv
    jac[3, 3] = 0.0
    jac[4, 3] = e * yf[YF_TR]
    for i in range(3):
        jac[5 + i, 3] = -(dq[0, i] * n0 + dq[1, i] * n1 + dq[2, i] * n2)
    # Columns z = (c, A, Bc, Bs) (4-7): through the angle coefficients p, ∂p/∂z = sc.dpz.
    for z in range(4):
        nz0 = 0.0
        nz1 = 0.0
        nz2 = 0.0
        trz = 0.0
        fz = 0.0
        for j in range(N_P):
            d = sc.dpz[j, z]
            if d != 0.0:
                nz0 += yf[YF_NP + j] * d
                nz1 += yf[YF_NP + N_P + j] * d
                nz2 += yf[YF_NP + 2 * N_P + j] * d
                trz += yf[YF_TRP + j] * d
                if j < 3:
                    fz += yf[YF_FP + j] * d
        jac[0, 4 + z] = dgam * ((bulk + shear) * nz0 + (bulk - shear) * nz1) * inv
        jac[1, 4 + z] = dgam * ((bulk - shear) * nz0 + (bulk + shear) * nz1) * inv
        jac[2, 4 + z] = dgam * shear * nz2 * inv
        jac[3, 4 + z] = fz * inv
        jac[4, 4 + z] = (1.0 if z == 0 else 0.0) + e * dgam * trz
        for i in range(3):
            jac[5 + i, 4 + z] = ((1.0 if z == i + 1 else 0.0)
                                 - dgam * (dq[0, i] * nz0 + dq[1, i] * nz1 + dq[2, i] * nz2)
                                 - (dq[3, i] if z == 0 else 0.0))
    worst = 0.0
    for i in range(N_X):
        worst = max(worst, abs(res[i]))
    return worst, projected


@njit(**KERNEL)
def _isotropic_dilatancy(c, a, bc, bs, prm, dpz):
    """sin ψ̄ at (c, A, Bc, Bs): the isotropic part of ψ(θ), clamped as a plane's is (to
    [-φ, φ], φ the isotropic part of φ(θ) clamped to [φ_min, φ_max]) — every plane's where
    the fabric terms vanish (a2 = b2 = 0), and then tier 1's."""
    phi0, _, _, psi0, _, _, _, _, phi_lo, phi_hi = fabric_terms(c, a, bc, bs, prm, dpz)
    phi = min(max(phi0, phi_lo), phi_hi)
    return np.sin(min(max(psi0, -phi), phi))


@njit(**KERNEL)
def _initial_guess(c_n, qn, prm, sc, planes):
    """Tier 1's closed-form coaxial return with the isotropic part of φ(θ), ψ(θ) at c_n and
    the fabric at its start value; with ``planes`` also the planes at tier 1's
    θ = α ± (π/4 - φ/2)."""
    bulk = prm[BULK]
    shear = prm[SHEAR]
    ttr = sc.v[V_TTR]
    x = sc.v[V_X]
    phi0, _, _, psi0, _, _, _, _, phi_lo, phi_hi = fabric_terms(c_n, qn[0], qn[1], qn[2], prm,
                                                                sc.dpz)
    phi = min(max(phi0, phi_lo), phi_hi)
    psi = min(max(psi0, -phi), phi)
    m = 0.5 * (ttr[0] + ttr[1])
    d = 0.5 * (ttr[0] - ttr[1])
    r = hypot(d, ttr[2])
    ca = d / r if r > 0.0 else 1.0
    sa = ttr[2] / r if r > 0.0 else 0.0
    sphi = np.sin(phi)
    spsi = np.sin(psi)
    dgam = max((r + sphi * m) / (shear + bulk * sphi * spsi), 0.0)   # m = -P
    dgam = min(dgam, 0.5 * r / shear)
    r1 = r - shear * dgam
    m1 = m - bulk * spsi * dgam
    x[0] = m1 + r1 * ca
    x[1] = m1 - r1 * ca
    x[2] = r1 * sa
    # Same plastic strain with this tier's slip normalization: ε1 - ε2 = Δγ cos(φ - ψ̂).
    psi_hat = np.arctan2(spsi * np.cos(phi), 1.0 - spsi * sphi)
    x[3] = dgam / np.cos(phi - psi_hat)
    x[4] = c_n * np.exp(-dgam * spsi)
    x[5] = qn[0]
    x[6] = qn[1]
    x[7] = qn[2]
    if planes:
        alpha = 0.5 * np.arctan2(sa, ca)
        theta = sc.v[V_THETA]
        theta[0] = alpha + 0.25 * np.pi - 0.5 * phi
        theta[1] = alpha - 0.25 * np.pi + 0.5 * phi


@njit(**KERNEL)
def _cutting_plane_guess(c_n, qn, fab, prm, sc, hardening, have_terms):
    """One cutting-plane step from σ_tr (planes at their maxima from the elastic check), with
    the hardening of c and the fabric: f linearized in Δγ along σ = σ_tr - Δγ C N,
    c = c_n exp(-Δγ tr N), q = Φ(q_n, Δγ N, c),

        Δγ = f_tr / (∂f/∂σ · C N - ∂f/∂c ∂c/∂Δγ - ∂f/∂q · ∂q/∂Δγ),

    ∂q/∂Δγ the secant of Φ over the plain step Δγ0 = f_tr / (∂f/∂σ · C N) (Φ is not
    differentiable at Δεp = 0). The flow is then taken at the step's end to first order,
    N + ∂N/∂σ Δσ + ∂N/∂z Δz (tr N likewise; Δγ again with it), the fabric set to Φ of that
    plastic strain and the planes moved with the step (θ_σ Δσ + θ_p Δp), then by one
    Newton step on each arc's ∂h/∂θ = 0 there (which leaves them ~δθ² from the arcs' maxima;
    the solve's condensed planes do the rest). Each of these removes a first-order residual
    (the fabric's relaxation rate makes a start from q_n a first-order one, the planes'
    motion another): the solve then starts ~1e-5 from the solution at the bench's increments
    and takes two evaluations instead of three (without the plane step: 2.7-2.9; refining
    the planes to convergence instead costs 3.5 more evaluations of h per point and saves
    no evaluation of the solve, measured on the bench's points). The plain step where the
    hardening one is undefined, and
    without ``hardening`` (the plain cutting-plane step alone: σ, Δγ, c, fabric at q_n,
    planes untouched); False (the unknowns untouched) where ∂f/∂σ · C N <= 0. With
    ``have_terms`` the yield/flow terms at σ_tr and the planes are already in ``sc.yfs[0]``
    and ``sc.planes[0:2]`` (:func:`_trial_yield`)."""
    bulk = prm[BULK]
    shear = prm[SHEAR]
    ttr = sc.v[V_TTR]
    x = sc.v[V_X]
    yf = sc.yfs[0]
    fq = sc.v[V_FQ]
    if not have_terms:
        yield_and_flow(ttr[0], ttr[1], ttr[2], fab, prm[SHARPNESS], False, WARM_START,
                       sc.v[V_THETA], sc.planes[0:2], yf)
    n0 = yf[YF_N]
    n1 = yf[YF_N + 1]
    n2 = yf[YF_N + 2]
    cn0 = (bulk + shear) * n0 + (bulk - shear) * n1
    cn1 = (bulk - shear) * n0 + (bulk + shear) * n1
    cn2 = shear * n2
    den = yf[YF_FS] * cn0 + yf[YF_FS + 1] * cn1 + yf[YF_FS + 2] * cn2
    if not den > 0.0:
        return False
    dgam = yf[YF_F] / den
    if not hardening:
        x[0] = ttr[0] - dgam * cn0
        x[1] = ttr[1] - dgam * cn1
        x[2] = ttr[2] - dgam * cn2
        x[3] = dgam
        x[4] = c_n * np.exp(-dgam * yf[YF_TR])
        x[5] = qn[0]
        x[6] = qn[1]
        x[7] = qn[2]
        return True
    law = int(prm[FABRIC_LAW])
    fabric_step(qn[0], qn[1], qn[2], dgam * n0, dgam * n1, dgam * n2,
                c_n * np.exp(-dgam * yf[YF_TR]), law, prm[KAPPA_A], prm[K_C], prm[K_O],
                prm[A_CRIT], prm[B_RATIO_CRIT], prm[RELAX_RATE], fq, sc.dq, sc.ws)
    # ∂f/∂z · ∂z/∂Δγ, z = (c, A, Bc, Bs), through the angle coefficients p (∂p/∂z = sc.dpz);
    # the fabric's secant slope in row V_X0.
    slope = sc.v[V_X0]
    hard = 0.0
    for z in range(4):
        fz = 0.0
        for j in range(3):
            fz += yf[YF_FP + j] * sc.dpz[j, z]
        if z == 0:
            hard -= fz * c_n * yf[YF_TR]
        else:
            slope[z - 1] = (fq[z - 1] - qn[z - 1]) / dgam if dgam > 0.0 else 0.0
            hard += fz * slope[z - 1]
    if den - hard > 0.0 and dgam > 0.0:
        dgam = yf[YF_F] / (den - hard)
    # The step at first order: dx = (Δσ, Δγ, Δc, Δq) with the trial's flow.
    dx = sc.v[V_DX]
    dx[0] = -dgam * cn0
    dx[1] = -dgam * cn1
    dx[2] = -dgam * cn2
    dx[3] = dgam
    dx[4] = c_n * np.expm1(-dgam * yf[YF_TR])
    for i in range(3):
        dx[5 + i] = slope[i] * dgam
    # The flow there, N + ∂N/∂σ Δσ + ∂N/∂p ∂p/∂z Δz (and tr N likewise): the step with it
    # leaves residuals of second order in the flow's change.
    nn = sc.v[V_XT]
    for i in range(4):
        row_s = YF_NS + 3 * i if i < 3 else YF_TRS
        row_p = YF_NP + N_P * i if i < 3 else YF_TRP
        v = yf[YF_N + i] if i < 3 else yf[YF_TR]
        for j in range(3):
            v += yf[row_s + j] * dx[j]
        for j in range(N_P):
            for z in range(4):
                v += yf[row_p + j] * sc.dpz[j, z] * dx[4 + z]
        nn[i] = v
    cn0 = (bulk + shear) * nn[0] + (bulk - shear) * nn[1]
    cn1 = (bulk - shear) * nn[0] + (bulk + shear) * nn[1]
    cn2 = shear * nn[2]
    # Δγ again, with that flow in the stress's part of f's linearization.
    den = yf[YF_FS] * cn0 + yf[YF_FS + 1] * cn1 + yf[YF_FS + 2] * cn2 - hard
    if den > 0.0:
        dgam = yf[YF_F] / den
    c = c_n * np.exp(-dgam * nn[3])
    fabric_step(qn[0], qn[1], qn[2], dgam * nn[0], dgam * nn[1], dgam * nn[2], c, law,
                prm[KAPPA_A], prm[K_C], prm[K_O], prm[A_CRIT], prm[B_RATIO_CRIT], prm[RELAX_RATE],
                fq, sc.dq, sc.ws)
    # The planes follow to first order: θ_k + θ_σ·Δσ + θ_p·Δp (slip_planes.plane_terms).
    theta = sc.v[V_THETA]
    for k in range(2):
        theta[k] += _plane_step(sc.planes[0:2], k, dx, sc.dpz)
    x[0] = ttr[0] - dgam * cn0
    x[1] = ttr[1] - dgam * cn1
    x[2] = ttr[2] - dgam * cn2
    x[3] = dgam
    x[4] = c
    x[5] = fq[0]
    x[6] = fq[1]
    x[7] = fq[2]
    m, r, ca, sa = stress_frame(x[0], x[1], x[2])
    fab1 = fabric_terms(c, fq[0], fq[1], fq[2], prm, sc.dpz)
    arc_maxima(m, r, ca, sa, np.arctan2(sa, ca), fab1, WARM_START, ONE_STEP, theta, np.False_)
    return True


@njit(**KERNEL, inline="always")
def _plane_step(pl, k, dx, dpz):
    """The condensed step of plane k with the unknowns' step dx: δθ + θ_σ·dσ + θ_p·(∂p/∂z) dz."""
    d = pl[k, PL_DT] + pl[k, PL_TS] * dx[0] + pl[k, PL_TS + 1] * dx[1] + pl[k, PL_TS + 2] * dx[2]
    for j in range(3):
        for z in range(4):
            d += pl[k, PL_TP + j] * dpz[j, z] * dx[4 + z]
    return d


@njit(**KERNEL)
def _ridge_residual(x, k, c_n, qn, prm, sc, s_ref):
    """Residuals of the ridge return at x = (σ, Δγ, c, A, Bc, Bs, λ) into row V_RESR of
    ``sc.v`` and their Jacobian into ``sc.jacr``.

    On a ridge of f two planes of arc k, a (row V_THETA) and b (row V_THB), carry
    its maximum, h_a = h_b, and the arc's flow is their combination λ N_a + (1 - λ) N_b,
    0 <= λ <= 1 (Koiter's rule). With (·)_a, (·)_b the terms of yield_and_flow with the
    planes (a, o) and (b, o) (o: the other arc's plane, in both), the residuals are those of
    :func:`_residual` with f, N, tr N = λ (·)_a + (1 - λ) (·)_b — equal to the ridge's at
    h_a = h_b, where the softmax weights of both agree — and (h_a - h_b)/|σ_tr|.
    Returns as :func:`_residual`.
    """
    if not x[4] > 0.0:
        return np.inf, False
    fab = fabric_terms(x[4], x[5], x[6], x[7], prm, sc.dpz)
    yf = sc.yfs[0]
    yfa = sc.yfs[1]
    yfb = sc.yfs[2]
    pa = sc.planes[0:2]
    pb = sc.planes[2:4]
    for j in range(2):      # a (planes V_THETA), then b (V_THB): one inlined copy of it
        yield_and_flow(x[0], x[1], x[2], fab, prm[SHARPNESS], False, WARM_START,
                       sc.v[V_THETA if j == 0 else V_THB], sc.planes[2 * j:2 * j + 2],
                       sc.yfs[1 + j])
    lam = x[8]
    for i in range(N_YF):
        yf[i] = lam * yfa[i] + (1.0 - lam) * yfb[i]
    res = sc.v[V_RESR]
    jac = sc.jacr
    worst, projected = _assemble(x, c_n, qn, prm, yf, sc, s_ref, res, jac)
    bulk = prm[BULK]
    shear = prm[SHEAR]
    dgam = x[3]
    inv = 1.0 / s_ref
    dq = sc.dq
    # Column λ: the combined terms' ∂/∂λ = (·)_a - (·)_b.
    d0 = yfa[YF_N] - yfb[YF_N]
    d1 = yfa[YF_N + 1] - yfb[YF_N + 1]
    d2 = yfa[YF_N + 2] - yfb[YF_N + 2]
    jac[0, 8] = dgam * ((bulk + shear) * d0 + (bulk - shear) * d1) * inv
    jac[1, 8] = dgam * ((bulk - shear) * d0 + (bulk + shear) * d1) * inv
    jac[2, 8] = dgam * shear * d2 * inv
    jac[3, 8] = (yfa[YF_F] - yfb[YF_F]) * inv
    jac[4, 8] = c_n * np.exp(-dgam * yf[YF_TR]) * dgam * (yfa[YF_TR] - yfb[YF_TR])
    for i in range(3):
        jac[5 + i, 8] = -dgam * (dq[0, i] * d0 + dq[1, i] * d1 + dq[2, i] * d2)
    # Row 8: (h_a - h_b)/|σ_tr|, h_k's derivatives in σ and p (slip_planes.plane_terms).
    res[8] = (pa[k, PL_H] - pb[k, PL_H]) * inv
    for j in range(3):
        jac[8, j] = (pa[k, PL_HS + j] - pb[k, PL_HS + j]) * inv
    jac[8, 3] = 0.0
    for z in range(4):
        d = 0.0
        for j in range(3):
            d += (pa[k, PL_HP + j] - pb[k, PL_HP + j]) * sc.dpz[j, z]
        jac[8, 4 + z] = d * inv
    jac[8, 8] = 0.0
    return max(worst, abs(res[8])), projected


@njit(**KERNEL)
def _ridge_newton(k, c_n, qn, prm, sc, s_ref):
    """Newton on the ridge residuals (:func:`_ridge_residual`) from row V_XR, the planes a,
    b and o moving with their condensed steps and kept inside their arcs, backtracking on
    max |residual|: (converged with Δγ >= 0, P > 0 and 0 <= λ <= 1, fabric projected). On
    success ``sc.jacr`` holds the LU factors of the Jacobian at the solution."""
    x = sc.v[V_XR]
    xt = sc.v[V_XRT]
    dx = sc.v[V_DXR]
    res = sc.v[V_RESR]
    theta = sc.v[V_THETA]
    thb = sc.v[V_THB]
    pa = sc.planes[0:2]
    pb = sc.planes[2:4]
    piv = sc.piv[1]
    g = -1.0 if k == 0 else 1.0        # arc k's sign of τ (slip_planes: plane rows 0, 1)
    err, projected = _ridge_residual(x, k, c_n, qn, prm, sc, s_ref)
    for _ in range(NEWTON_MAXIT):
        if not np.isfinite(err) or not _lu(sc.jacr, piv, N_XR):
            return False, False
        if err <= NEWTON_TOL and max(abs(pa[0, PL_DT]), abs(pa[1, PL_DT]),
                                     abs(pb[k, PL_DT])) <= PLANE_STEP_TOL:
            return (x[3] >= 0.0 and -0.5 * (x[0] + x[1]) > 0.0 and 0.0 <= x[8] <= 1.0,
                    projected)
        for i in range(N_XR):
            dx[i] = -res[i]
        _lu_solve(sc.jacr, piv, sc.v[V_DXR:V_DXR + 1], N_XR, 1)
        d0 = _plane_step(pa, 0, dx, sc.dpz)
        d1 = _plane_step(pa, 1, dx, sc.dpz)
        db = _plane_step(pb, k, dx, sc.dpz)
        theta0 = theta[0]
        theta1 = theta[1]
        theta_b = thb[k]
        step = 1.0
        accepted = False
        for _ in range(30):
            for i in range(N_XR):
                xt[i] = x[i] + step * dx[i]
            theta[0] = theta0 + step * d0
            theta[1] = theta1 + step * d1
            thb[k] = theta_b + step * db
            thb[1 - k] = theta[1 - k]
            err_t, projected = _ridge_residual(xt, k, c_n, qn, prm, sc, s_ref)
            if err_t < err or err_t <= NEWTON_TOL:
                accepted = True
                break
            step *= 0.5
        if not accepted:
            return False, False
        for i in range(N_XR):
            x[i] = xt[i]
        err = err_t
        # Each plane to where its terms at x were taken: slip_planes.arc_u puts a plane that
        # a step took past an end of its arc (τ = 0) at that end; θ ← α + u/2 with u mapped
        # into the arc (the terms unchanged). Left past the end, a plane keeps the end's
        # terms while its condensed steps move the stored angle: their first-order step to
        # an interior maximum or a corner of φ's clamp (slip_planes.plane_terms) does not
        # bring the evaluated plane into the arc, the other residuals converge against that
        # estimate, and the full step to the plane's own maximum then raises max |residual|
        # by the estimate's second-order error: the line search stalls (loose states whose
        # arc maxima are corners next to the arc's ends, measured).
        _, _, ca, sa = stress_frame(x[0], x[1], x[2])
        two_alpha = np.arctan2(sa, ca)
        theta[k] = 0.5 * (two_alpha + arc_u(theta[k], g, two_alpha))
        thb[k] = 0.5 * (two_alpha + arc_u(thb[k], g, two_alpha))
        theta[1 - k] = 0.5 * (two_alpha + arc_u(theta[1 - k], -g, two_alpha))
        thb[1 - k] = theta[1 - k]
    return False, False


@njit(**KERNEL, inline="always")
def _planes_are_maxima(prm, sc):
    """Whether the planes of a converged solve carry the arcs' maxima at its solution as the
    elastic check finds them: the plane search (``n_search`` grid points and the ends per
    arc) gives |f(σ; c, q)| <= YIELD_TOL·|σ| (the solve's own f is 0 to NEWTON_TOL).

    Where φ depends on θ an arc can have several local maxima — its two ends (the principal
    planes) where the φ-anisotropy outweighs the stress ratio, the clamped plateau's and the
    free branch's maxima and corners where φ reaches a clamp (slip_planes) — and a solve can
    converge to any. With φ independent of θ (pc = ps = 0) each arc's h = -g R sin u +
    tan φ (m + R cos u) is one sinusoid, whose single maximum lies inside the arc, and where
    the anisotropy is weak enough for h to keep a single maximum per arc
    (slip_planes.single_maximum, a bound) the converged planes are those maxima: True
    without a search. Row V_DTH ← the searched planes.
    """
    x = sc.v[V_X]
    fab = fabric_terms(x[4], x[5], x[6], x[7], prm, sc.dpz)
    if fab[1] == 0.0 and fab[2] == 0.0:
        return True
    m, r, _, _ = stress_frame(x[0], x[1], x[2])
    if single_maximum(m, r, fab[0], fab[1], fab[2], fab[8], fab[9]):
        return True
    searched = sc.v[V_DTH]
    searched[0] = sc.v[V_THETA][0]
    searched[1] = sc.v[V_THETA][1]
    f = yield_value(x[0], x[1], x[2], fab, prm[SHARPNESS], int(prm[N_SEARCH]), searched)
    s = hypot(0.5 * (x[0] + x[1]), hypot(0.5 * (x[0] - x[1]), x[2]))
    return abs(f) <= YIELD_TOL * s


@njit(**KERNEL, inline="always")
def _resolved(prm, sc, s_ref):
    """Whether the face point of a converged solve (row V_X) lies on its own surface,
    |f(σ; c, q)| <= YIELD_TOL·|σ|, as the elastic check finds it.

    The solve's residuals are relative to |σ_tr|, so they bound f/|σ| only where |σ| is of
    the trial's order: a point with |σ| >= RESOLVED_STRESS·|σ_tr| (every point but those near
    the apex) passes (f/|σ| <= 1e-11); below, f is evaluated with the plane search. Newton
    reaches σ ~ 0 from trials past the apex boundary, where f/|σ_tr| -> 0 whatever the
    direction of σ (measured: P = 1.8e-14 with f/|σ| = 0.51, from tier 1's start,
    tests/test_fabric_model.py ``test_near_apex_family_meets_the_apex_continuously``): such a
    point is σ = 0 to the solve's accuracy, the apex's (:func:`_scan_return` decides)."""
    x = sc.v[V_X]
    s = hypot(0.5 * (x[0] + x[1]), hypot(0.5 * (x[0] - x[1]), x[2]))
    if s >= RESOLVED_STRESS * s_ref:
        return True
    searched = sc.v[V_DTH]
    searched[0] = sc.v[V_THETA][0]
    searched[1] = sc.v[V_THETA][1]
    fab = fabric_terms(x[4], x[5], x[6], x[7], prm, sc.dpz)
    f = yield_value(x[0], x[1], x[2], fab, prm[SHARPNESS], int(prm[N_SEARCH]), searched)
    return abs(f) <= YIELD_TOL * s


@njit(**KERNEL)
def _face_return(c_n, qn, prm, sc, s_ref):
    """The face solve from the unknowns and planes in ``sc.v`` (rows V_X, V_THETA): (converged
    to a valid face point whose planes are the arcs' maxima, fabric projected, on a ridge).

    :func:`_newton`; where its planes are a lesser local maximum (:func:`_planes_are_maxima`)
    it solves again from its solution with the searched planes, and where that fails too —
    each one-plane solution makes the other plane of the arc the higher: a ridge of f — the
    ridge return (:func:`_ridge_residual`) between the two. On success row V_X holds the
    solution; the LU factors of its Jacobian are in ``sc.jac`` (``sc.jacr`` on a ridge).
    """
    face, projected = _newton(c_n, qn, prm, sc, s_ref)
    if not face:
        return False, False, False
    if _planes_are_maxima(prm, sc):
        return True, projected, False
    x = sc.v[V_X]
    xr = sc.v[V_XR]
    theta = sc.v[V_THETA]
    thb = sc.v[V_THB]
    searched = sc.v[V_DTH]
    for i in range(N_X):
        xr[i] = x[i]
    theta0 = theta[0]
    theta1 = theta[1]
    thb[0] = searched[0]
    thb[1] = searched[1]
    theta[0] = searched[0]
    theta[1] = searched[1]
    face, projected = _newton(c_n, qn, prm, sc, s_ref)
    if face and _planes_are_maxima(prm, sc):
        return True, projected, False
    # The ridge between the first solution's plane and the searched one, on the arc whose
    # plane moved the most (angles modulo π).
    moved0 = abs(np.remainder(theta0 - thb[0] + 0.5 * np.pi, np.pi) - 0.5 * np.pi)
    moved1 = abs(np.remainder(theta1 - thb[1] + 0.5 * np.pi, np.pi) - 0.5 * np.pi)
    k = 0 if moved0 >= moved1 else 1
    theta[0] = theta0
    theta[1] = theta1
    thb[1 - k] = theta[1 - k]
    xr[8] = 0.5
    face, projected = _ridge_newton(k, c_n, qn, prm, sc, s_ref)
    if not face:
        return False, False, False
    for i in range(N_X):
        x[i] = xr[i]
    if xr[8] < 0.5:          # the dominant plane warm-starts what follows
        theta[k] = thb[k]
    return _planes_are_maxima(prm, sc), projected, True


@njit(**KERNEL)
def _newton(c_n, qn, prm, sc, s_ref):
    """Newton on the step's residuals from the unknowns in row V_X: (converged to a valid
    face point, fabric projected).

    The planes (row V_THETA) move with the condensed step δθ_k + θ_σ·dσ + θ_p·dp; the line
    search backtracks on max |residual|. If it cannot progress (near the apex the planes are
    ill-conditioned), the solve restarts from its start with the planes re-searched to their
    exact maxima at every evaluation. On success ``sc.jac`` holds the LU factors of the
    Jacobian at the solution, ``sc.yfs[0]`` the yield/flow terms and row V_FQ the fabric there.
    """
    x = sc.v[V_X]
    xt = sc.v[V_XT]
    dx = sc.v[V_DX]
    x0 = sc.v[V_X0]
    res = sc.v[V_RES]
    theta = sc.v[V_THETA]
    dth = sc.v[V_DTH]
    piv = sc.piv[0]
    pl = sc.planes[0:2]
    for i in range(N_X):
        x0[i] = x[i]
    start0 = theta[0]
    start1 = theta[1]
    search = False
    restart = True          # evaluate at x first (one call site for the start and the restart)
    err = np.inf
    err_prev = np.inf
    projected = False
    for _ in range(NEWTON_MAXIT):
        if restart:
            err, projected = _residual(x, c_n, qn, prm, search, sc, s_ref)
            err_prev = np.inf
            restart = False
        if not np.isfinite(err):
            return False, False
        if not _lu(sc.jac, piv, N_X):
            return False, False
        if err <= NEWTON_TOL and max(abs(pl[0, PL_DT]), abs(pl[1, PL_DT])) <= PLANE_STEP_TOL:
            p = -0.5 * (x[0] + x[1])
            return x[3] >= 0.0 and p > 0.0, projected
        for i in range(N_X):
            dx[i] = -res[i]
        _lu_solve(sc.jac, piv, sc.v[V_DX:V_DX + 1], N_X, 1)
        if (err <= NEWTON_TOL_LAST and err <= 1e-2 * err_prev
                and max(abs(pl[0, PL_DT]), abs(pl[1, PL_DT])) <= 1e-5):
            # Quadratic convergence (the last step cut the residual 100-fold): this step
            # leaves ~err² (< 1e-16); take it without another evaluation (the factors at x
            # serve the tangent to ~err).
            for i in range(N_X):
                x[i] += dx[i]
            p = -0.5 * (x[0] + x[1])
            return x[3] >= 0.0 and p > 0.0, projected
        for k in range(2):
            dth[k] = _plane_step(pl, k, dx, sc.dpz)
        theta0 = theta[0]
        theta1 = theta[1]
        step = 1.0
        accepted = False
        for _ in range(30):
            for i in range(N_X):
                xt[i] = x[i] + step * dx[i]
            theta[0] = theta0 + step * dth[0]
            theta[1] = theta1 + step * dth[1]
            err_t, projected = _residual(xt, c_n, qn, prm, search, sc, s_ref)
            if err_t < err or err_t <= NEWTON_TOL:
                accepted = True
                break
            step *= 0.5
            if step < 0.1 and not search:
                break
        if accepted:
            for i in range(N_X):
                x[i] = xt[i]
            err_prev = err
            err = err_t
        elif not search:
            # Restart from the start: where the condensed planes lead it astray, the iterate
            # reached can lie in a valley of the residual that exact planes do not leave.
            search = True
            for i in range(N_X):
                x[i] = x0[i]
            theta[0] = start0
            theta[1] = start1
            restart = True
        else:
            return False, False
    return False, False


@njit(**KERNEL)
def _continuation_return(rotated, c_n, qn, prm, sc):
    """The face solve by continuation in the trial stress, for increments too large for
    Newton from one start: the step's backward-Euler problem with σ_tr(t) = σ_n + t CΔε
    (``rotated`` = σ_n, row V_TTR = σ_tr(1)) at t = 1/k_max, 2/k_max, .., 1, each solve
    starting from the last. Only the last is the step's own problem; returns as
    :func:`_face_return`, with row V_TTR restored."""
    ttr = sc.v[V_TTR]
    full = (ttr[0], ttr[1], ttr[2])
    face = False
    projected = False
    ridge = False
    for k in range(1, CONTINUATION_STEPS + 1):
        t = k / CONTINUATION_STEPS
        for j in range(3):
            ttr[j] = rotated[j] + t * (full[j] - rotated[j])
        s_ref = hypot(0.5 * (ttr[0] + ttr[1]), hypot(0.5 * (ttr[0] - ttr[1]), ttr[2]))
        if k == 1:
            _initial_guess(c_n, qn, prm, sc, np.True_)
        face, projected, ridge = _face_return(c_n, qn, prm, sc, s_ref)
        if not face:
            break
    for j in range(3):
        ttr[j] = full[j]
    return face, projected, ridge


# --------------------------------------------------------------------------- the face scan

@njit(**KERNEL, inline="always")
def _unit_stress(alpha, rho):
    """σ̂ = (-1 + ρ cos 2α, -1 - ρ cos 2α, ρ sin 2α): P = 1, R = ρ, major principal direction α."""
    ca = np.cos(2.0 * alpha)
    return -1.0 + rho * ca, -1.0 - rho * ca, rho * np.sin(2.0 * alpha)


@njit(**KERNEL)
def _unit_face(alpha, fab, prm, sc, rho):
    """ρ = R/P of the face point at P = 1 with major principal direction α,
    σ̂ = (-1 + ρ cos 2α, -1 - ρ cos 2α, ρ sin 2α), f(σ̂) = 0; ``sc.yfs[0]``, ``sc.planes[0:2]``
    and row V_THETA then hold the yield/flow terms there (planes searched exactly,
    slip_planes.yield_and_flow; with ``n_search`` = 0 from tier 1's planes α ± (π/4 - φ0/2)).

    Newton on f(ρ) from ``rho``, safeguarded by bisection on the bracket [0, 1]: f < 0 at
    ρ = 0 (σ̂ = -I: h = -tan φ(θ) < 0 on every plane) and f > 0 at ρ = 1 (σ1 = 0: on each arc
    the planes next to the σ1-plane carry |τ| > 0 and σn ~ 0, so both arc maxima are
    positive). At fixed planes h is affine in ρ, so Newton takes a few steps (warm starts
    from the neighbouring direction of the scan).
    """
    ca = np.cos(2.0 * alpha)
    sa = np.sin(2.0 * alpha)
    theta = sc.v[V_THETA]
    yf = sc.yfs[0]
    n_search = int(prm[N_SEARCH])
    lo = 0.0
    hi = 1.0
    for _ in range(SCAN_MAXIT):
        if n_search == 0:
            theta[0] = alpha + 0.25 * np.pi - 0.5 * fab[0]
            theta[1] = alpha - 0.25 * np.pi + 0.5 * fab[0]
        s = _unit_stress(alpha, rho)
        yield_and_flow(s[0], s[1], s[2], fab, prm[SHARPNESS], True, n_search, theta,
                       sc.planes[0:2], yf)
        f = yf[YF_F]
        if f > 0.0:
            hi = rho
        else:
            lo = rho
        slope = (yf[YF_FS] - yf[YF_FS + 1]) * ca + yf[YF_FS + 2] * sa
        step = -f / slope if slope > 0.0 else np.inf
        if not lo < rho + step < hi:
            step = 0.5 * (lo + hi) - rho
        if abs(step) <= SCAN_RHO_TOL:
            return rho
        rho += step
    return rho


@njit(**KERNEL, inline="always")
def _flow_stress(yf, bulk, shear):
    """C N of the yield/flow terms ``yf`` (N Voigt with engineering shear, C N a stress)."""
    return ((bulk + shear) * yf[YF_N] + (bulk - shear) * yf[YF_N + 1],
            (bulk - shear) * yf[YF_N] + (bulk + shear) * yf[YF_N + 1], shear * yf[YF_N + 2])


@njit(**KERNEL, inline="always")
def _cross(a, b):
    """a × b of two 3-vectors (tuples)."""
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


@njit(**KERNEL, inline="always")
def _dot(a, b):
    """a · b of two 3-vectors (tuples)."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(**KERNEL, inline="always")
def _unit_trial(sc, s_ref):
    """t = σ_tr / |σ_tr| (row V_TTR; ``s_ref`` = |σ_tr|), which keeps the scan's products in
    range for any size of σ_tr."""
    ttr = sc.v[V_TTR]
    return ttr[0] / s_ref, ttr[1] / s_ref, ttr[2] / s_ref


@njit(**KERNEL)
def _wedge(alpha, fab, prm, sc, rho, s_ref):
    """(g, P, Δγ, ρ) of the face direction α (ρ: :func:`_unit_face`, warm start ``rho``).

    The returns from the face points of direction α, σ_tr = P σ̂ + Δγ C N(σ̂) with P, Δγ >= 0,
    fill the wedge spanned by σ̂ and C N (N is homogeneous of degree 0 in σ: one flow per
    direction): σ_tr lies in its plane where

        g = t · n / (|t| |n|) = 0,   n = σ̂ × C N,   t = σ_tr / |σ_tr|   (Voigt components),

    and then P = |σ_tr| (t × C N)·n/|n|², Δγ = |σ_tr| (σ̂ × t)·n/|n|² (Cramer; elsewhere those
    of its projection onto the plane). g is the sine of the angle between σ_tr and the plane.
    """
    rho = _unit_face(alpha, fab, prm, sc, rho)
    t = _unit_trial(sc, s_ref)
    a = _unit_stress(alpha, rho)
    b = _flow_stress(sc.yfs[0], prm[BULK], prm[SHEAR])
    n = _cross(a, b)
    nn = _dot(n, n)
    if not nn > 0.0:
        return 0.0, 0.0, 0.0, rho
    g = _dot(t, n) / np.sqrt(nn * _dot(t, t))
    return (g, _dot(_cross(t, b), n) / nn * s_ref, _dot(_cross(a, t), n) / nn * s_ref, rho)


@njit(**KERNEL)
def _wedge_root(a, b, ga, gb, fab, prm, sc, rho, s_ref):
    """(α, g, P, Δγ, ρ, a', b'): a zero of :func:`_wedge`'s g in the bracket [a, b] (g(a) = ga
    and g(b) = gb of opposite signs), by regula falsi with the Illinois modification (the
    value at an end kept twice is halved: superlinear, and the bracket [a', b'] shrinks to a
    jump of g, where the flow jumps across a ridge of f). Stops at |g| <= SCAN_ROOT_TOL or a
    bracket of SCAN_ANGLE_TOL; the scratch holds the terms at the returned α."""
    side = 0
    m = a
    g = ga
    p = 0.0
    dgam = 0.0
    for _ in range(SCAN_MAXIT):
        m = (a * gb - b * ga) / (gb - ga)
        g, p, dgam, rho = _wedge(m, fab, prm, sc, rho, s_ref)
        if abs(g) <= SCAN_ROOT_TOL or b - a <= SCAN_ANGLE_TOL:
            break
        if (g > 0.0) == (ga > 0.0):
            a = m
            ga = g
            if side == -1:
                gb *= 0.5
            side = -1
        else:
            b = m
            gb = g
            if side == 1:
                ga *= 0.5
            side = 1
    return m, g, p, dgam, rho, a, b


@njit(**KERNEL)
def _bracket_root(a, b, ga, gb, fab, prm, sc, rho, s_ref):
    """(α, P, Δγ, ρ) of the scan's bracket [a, b] (g(a) = ga, g(b) = gb of opposite signs):
    its root (:func:`_wedge_root`), or where g jumps (the bracket shrinks to [lo, hi] with
    |g| > SCAN_ROOT_TOL) the return on the ridge there. The flow jumps across a ridge of f,
    whose flows λ N_lo + (1 - λ) N_hi, 0 <= λ <= 1 (Koiter's rule, as
    :func:`_ridge_residual`), fill the gap:

        t = P σ̂ + μ_lo C N_lo + μ_hi C N_hi,   Δγ = μ_lo + μ_hi,   λ = μ_lo / Δγ,

    a 3x3 system (Cramer, t = σ_tr/|σ_tr|, σ̂ continuous through the jump); μ_lo and μ_hi
    have one sign, as g(lo) and g(hi) have opposite ones. The scratch holds the terms at the
    returned α (hi on a ridge)."""
    m, g, p, dgam, rho, lo, hi = _wedge_root(a, b, ga, gb, fab, prm, sc, rho, s_ref)
    if abs(g) <= SCAN_ROOT_TOL:
        return m, p, dgam, rho
    t = _unit_trial(sc, s_ref)
    rho = _unit_face(lo, fab, prm, sc, rho)
    b_lo = _flow_stress(sc.yfs[0], prm[BULK], prm[SHEAR])
    rho = _unit_face(hi, fab, prm, sc, rho)
    b_hi = _flow_stress(sc.yfs[0], prm[BULK], prm[SHEAR])
    s = _unit_stress(hi, rho)
    w = _cross(b_lo, b_hi)
    det = _dot(s, w)
    if det == 0.0:
        return hi, 0.0, 0.0, rho
    dgam = (_dot(s, _cross(t, b_hi)) + _dot(s, _cross(b_lo, t))) / det
    return hi, _dot(t, w) / det * s_ref, dgam * s_ref, rho


@njit(**KERNEL)
def _scan_face(a, b, m, p, dgam, rho, c_n, qn, z, prm, sc, s_ref):
    """The face solve from a root (α = ``m``, P = ``p`` > 0, Δγ = ``dgam`` > 0, ρ = ``rho``;
    its terms in the scratch; :func:`_bracket_root`) of the scan's bracket [a, b]
    at the state ``z`` = (c, A, Bc, Bs) (:func:`_scan_return`): (face, fabric projected, on a
    ridge, at the apex).

    The root is refined at the state of its own step, c = c_n exp(-Δγ tr N),
    q = Φ(q_n, Δγ N, c), by fixed-point iteration (to SCAN_STATE_TOL, while the bracket
    holds; the fabric's change is a small part of the step's, so each iteration shrinks the
    state's error ~100-fold at the increments measured), then Newton starts from it
    (:func:`_face_return`). At the apex: the root at its own state lies past it (P <= 0), or
    the solve converged to σ ~ 0 (:func:`_resolved`).
    """
    x = sc.v[V_X]
    theta = sc.v[V_THETA]
    fq = sc.v[V_FQ]
    law = int(prm[FABRIC_LAW])
    theta_root = (theta[0], theta[1])
    for _ in range(SCAN_STATE_MAXIT):
        yf = sc.yfs[0]
        c1 = c_n * np.exp(-dgam * yf[YF_TR])
        fabric_step(qn[0], qn[1], qn[2], dgam * yf[YF_N], dgam * yf[YF_N + 1],
                    dgam * yf[YF_N + 2], c1, law, prm[KAPPA_A], prm[K_C], prm[K_O],
                    prm[A_CRIT], prm[B_RATIO_CRIT], prm[RELAX_RATE], fq, sc.dq, sc.ws)
        change = max(abs(c1 - z[0]), abs(fq[0] - z[1]), abs(fq[1] - z[2]), abs(fq[2] - z[3]))
        z = (c1, fq[0], fq[1], fq[2])
        if change <= SCAN_STATE_TOL:
            break
        fab = fabric_terms(z[0], z[1], z[2], z[3], prm, sc.dpz)
        ga, _, _, _ = _wedge(a, fab, prm, sc, rho, s_ref)
        gb, _, _, _ = _wedge(b, fab, prm, sc, rho, s_ref)
        if (ga > 0.0) == (gb > 0.0):
            break        # the root left its bracket: the last one stands
        m, p, dgam, rho = _bracket_root(a, b, ga, gb, fab, prm, sc, rho, s_ref)
        theta_root = (theta[0], theta[1])
        if not (dgam > 0.0 and p > 0.0):
            return False, False, False, dgam > 0.0
    s = _unit_stress(m, rho)
    for i in range(3):
        x[i] = p * s[i]
    x[3] = dgam
    for i in range(4):
        x[4 + i] = z[i]
    theta[0] = theta_root[0]
    theta[1] = theta_root[1]
    face, projected, ridge = _face_return(c_n, qn, prm, sc, s_ref)
    if face and _resolved(prm, sc, s_ref):
        return True, projected, ridge, False
    return False, False, False, face


@njit(**KERNEL)
def _scan_return(c_n, qn, c_apex, prm, sc, s_ref):
    """The face solve by a scan of the face's directions, and the apex decision: (face,
    fabric projected, on a ridge, apex). The fallback where Newton from the other starts
    failed, and the solve of every trial that tier 1's criterion puts at the apex.

    **Why.** Near the apex the return is large against the stress it leaves (|σ_tr - σ| >>
    P), and N, homogeneous of degree 0 in σ, turns with the direction of σ at a rate 1/|σ|:
    the Jacobian's Δγ C ∂N/∂σ outweighs its identity by |σ_tr|/P, and Newton in σ converges
    only from starts within ~P of the solution. Measured (tests/test_fabric_model.py,
    ``NEAR_APEX_FLICKER``: σ_n = 0, R_tr/P_tr = 7, B/A = 0.64): the face point has P = 0.86,
    R/P = 0.449 and a flow dilating at tr/(ε1 - ε2) = +0.025 (against C⁻¹σ_tr's -0.085);
    tier 1's closed-form start, its Δγ capped at R_tr/(2G), leaves R = R_tr/2 = 2.4 at
    P = 0.63, and Newton from it stalls at max |residual| 0.04 where its Jacobian is nearly
    singular (uncapped, the start serves that family down to P ~ 0.4, not nearer the apex);
    the trial is far from the surface (f_tr = 1.05 |σ_tr|: no cutting-plane start), and
    continuation in σ_tr from σ_n = 0 poses the same problem, scaled, at every stage.

    **The scan.** With the state (c, q) fixed, σ = P σ̂(α) (σ̂ the face point at P = 1 of
    direction α, :func:`_unit_face`) and N = N(α), so the stress equations
    σ_tr = P σ̂(α) + Δγ C N(α) are linear in (P, Δγ) and leave one scalar equation in α,
    g(α) = 0 (:func:`_wedge`), well posed at any P, P = 0 included. g is sampled at
    SCAN_POINTS directions over [0, π) (α = π is α = 0) at the apex's state
    (c_apex, Φ(q_n, C⁻¹σ_tr, c_apex)) and each sign change refined to a root, or where g
    jumps (the flow jumps across a ridge of f) to the return with the ridge's flows
    (:func:`_bracket_root`).
    A root with Δγ > 0 and P > 0 is refined at the state of its own step and starts the
    face solve (:func:`_scan_face`); roots with Δγ <= 0 (flows running backwards) are not
    returns.

    **The apex** (σ = 0, Δεp = C⁻¹σ_tr, docs/theory.md §4: its region is set by the plastic
    potential, because the flow is non-associated): a root with Δγ > 0 and P <= 0 says that
    C⁻¹σ_tr = Δγ N + |P| C⁻¹(-σ̂): the trial strain is the admissible flow N of its plane
    plus the strain of taking a compression |P| σ̂ off (a dilation of |P|/K), so it dilates
    more than that flow, and the return along the flow passes the apex — tier 1's criterion
    G P_tr + K sin ψ R_tr <= 0, which is P <= 0 of its closed-form face return, for a flow
    that varies with the direction. (Not against every flow of the face at once: their
    dilatancy tr/(ε1 - ε2) ranges over -0.076 .. +0.032 on ``NEAR_APEX_FLICKER``'s fabric and
    reaches 0.74 on loose anisotropic states, where two planes' deviators cancel; beyond the
    flow of its own direction a trial has no face point, and a criterion against the most
    dilatant flow would leave it failed at every step size from σ_n = 0. Nor against the
    most dilatant plane: a flow's dilatancy exceeds max_θ sin ψ(θ) by up to 0.62 there.)
    It is taken at the apex's own state, which a face root's own state reaches as P -> 0: face and apex meet continuously, P -> 0 at the
    boundary. The apex is returned where such a root exists and none gives a face point
    (a solve converging to σ ~ 0, :func:`_resolved`, is the apex to its accuracy); a face
    root whose solve fails leaves the point failed (-1), never at the apex, and so does a
    trial without a root.

    Cost: ~SCAN_POINTS + 20 solves for ρ, each a few searched evaluations of f and N: about
    0.25 ms per trial with the shipped parameters, paid only where the other starts failed
    and by the trials tier 1's criterion puts at the apex. Measured (2000 points
    at σ_n = 0 with B/A = 0.25 under dilating increments, 72 % at the apex): 0.17 ms per
    update, 6.7 µs before the scan (whose apex came from tier 1's criterion directly).
    """
    fq = sc.v[V_FQ]
    ttr = sc.v[V_TTR]
    law = int(prm[FABRIC_LAW])
    pxx, pyy, pgg = _elastic_strain(ttr[0], ttr[1], ttr[2], prm[BULK], prm[SHEAR])
    fabric_step(qn[0], qn[1], qn[2], pxx, pyy, pgg, c_apex, law, prm[KAPPA_A], prm[K_C], prm[K_O],
                prm[A_CRIT], prm[B_RATIO_CRIT], prm[RELAX_RATE], fq, sc.dq, sc.ws)
    apex_state = (c_apex, fq[0], fq[1], fq[2])
    fab0 = fabric_terms(c_apex, fq[0], fq[1], fq[2], prm, sc.dpz)
    beyond = False
    unresolved = False
    step = np.pi / SCAN_POINTS
    g0, _, _, rho0 = _wedge(0.0, fab0, prm, sc, 0.5, s_ref)
    ga = g0
    rho_grid = rho0
    for j in range(1, SCAN_POINTS + 1):
        a = (j - 1) * step
        b = j * step
        if j < SCAN_POINTS:
            gb, _, _, rho_grid = _wedge(b, fab0, prm, sc, rho_grid, s_ref)
        else:
            gb = g0
        if (ga > 0.0) != (gb > 0.0):
            # A bracket: its root at the apex's state decides for the apex; a face root
            # starts the face solve.
            m, p, dgam, rho = _bracket_root(a, b, ga, gb, fab0, prm, sc, rho_grid, s_ref)
            if dgam > 0.0 and p > 0.0:
                face, projected, ridge, past = _scan_face(a, b, m, p, dgam, rho, c_n, qn,
                                                          apex_state, prm, sc, s_ref)
                if face:
                    return True, projected, ridge, False
                beyond = beyond or past
                unresolved = unresolved or not past
            elif dgam > 0.0:
                beyond = True
        ga = gb
    return False, False, False, beyond and not unresolved


# --------------------------------------------------------------------------- one point

@njit(**KERNEL)
def _trial_yield(fab, prm, n_search, sc):
    """f(σ_tr) for the elastic check (σ_tr in row V_TTR, planes in/out in row V_THETA), and
    whether ``sc.yfs[0]`` and ``sc.planes[0:2]`` now hold the yield/flow terms at σ_tr.

    Where each arc has a single maximum (slip_planes.single_maximum), one plane step from u*
    and the terms there (slip_planes.yield_and_flow: the predicted maxima, h + ½ h_θ δθ, or
    h + h_θ δθ at an arc's end) decide the check when the prediction's error, below
    |h_θθθ| δθ³/6 inside an arc and ½ |h_θθ| δθ² at an end (|h_θθ| <= 20 |σ| for
    φ <= 60°), is far smaller than |f|: |f| > (PREDICTED_F_GAP + 50 δθ²) |σ| with
    δθ <= PREDICTED_PLANE_STEP. The plastic branch then starts from those terms (the
    cutting-plane step needs them at σ_tr anyway), so the trial's plane search takes one
    step per arc instead of its three; elsewhere (near the surface, several maxima, large
    plane steps) the exact search decides, as before. Measured on the bench's points: the
    planes' step after one step from u* is 5e-5 (isotropic fabric) to 5e-4 (B/A = 0.25),
    so every point there is decided by the prediction.
    """
    ttr = sc.v[V_TTR]
    theta = sc.v[V_THETA]
    if n_search > 0:
        m, r, ca, sa = stress_frame(ttr[0], ttr[1], ttr[2])
        if single_maximum(m, r, fab[0], fab[1], fab[2], fab[8], fab[9]):
            arc_maxima(m, r, ca, sa, np.arctan2(sa, ca), fab, n_search, ONE_STEP, theta,
                       np.True_)
            yf = sc.yfs[0]
            pl = sc.planes[0:2]
            yield_and_flow(ttr[0], ttr[1], ttr[2], fab, prm[SHARPNESS], False, WARM_START,
                           theta, pl, yf)
            dt = max(abs(pl[0, PL_DT]), abs(pl[1, PL_DT]))
            if (dt <= PREDICTED_PLANE_STEP
                    and abs(yf[YF_F]) > (PREDICTED_F_GAP + 50.0 * dt * dt) * hypot(m, r)):
                return yf[YF_F], True
    return yield_value(ttr[0], ttr[1], ttr[2], fab, prm[SHARPNESS], n_search, theta), False


@njit(**KERNEL)
def _elastic_strain(sxx, syy, sxy, bulk, shear):
    """C⁻¹σ (Voigt, engineering shear): tr = (σxx+σyy)/(2K), deviator /(2G), γ = σxy/G."""
    vol = 0.25 * (sxx + syy) / bulk
    dev = 0.25 * (sxx - syy) / shear
    return vol + dev, vol - dev, sxy / shear


@njit(**KERNEL, inline="always")
def _tangent(lu, piv, rhs, n, bulk, shear, s_ref, tangent, i):
    """tangent[i] ← ∂σ/∂Δε, the σ-rows of J⁻¹ [C/s_ref; 0] (J: the LU factors ``lu``, ``piv``
    of the converged n x n Jacobian; ``rhs`` (3, >= n) scratch), the three columns at once."""
    for j in range(3):
        for k in range(n):
            rhs[j, k] = 0.0
    rhs[0, 0] = (bulk + shear) / s_ref
    rhs[0, 1] = (bulk - shear) / s_ref
    rhs[1, 0] = (bulk - shear) / s_ref
    rhs[1, 1] = (bulk + shear) / s_ref
    rhs[2, 2] = shear / s_ref
    _lu_solve(lu, piv, rhs, n, 3)
    for j in range(3):
        for k in range(3):
            tangent[i, k, j] = rhs[j, k]


@njit(**KERNEL)
def _point(i, stress_n, state_n, dstrain, dspin, prm, stress, state, tangent, status, sc):
    bulk = prm[BULK]
    shear = prm[SHEAR]
    c_n = state_n[i, 1]
    if not (0.0 < c_n < 1.0):
        status[i] = STATUS_FAILED
        return
    ttr = sc.v[V_TTR]
    rxx, ryy, rxy = rotate(stress_n[i, 0], stress_n[i, 1], stress_n[i, 2], dspin[i])
    bc, bs = rotate_fabric(state_n[i, 3], state_n[i, 4], dspin[i])
    q0 = state_n[i, 2]
    dexx = dstrain[i, 0]
    deyy = dstrain[i, 1]
    dgxy = dstrain[i, 2]
    ttr[0] = rxx + (bulk + shear) * dexx + (bulk - shear) * deyy
    ttr[1] = ryy + (bulk - shear) * dexx + (bulk + shear) * deyy
    ttr[2] = rxy + shear * dgxy
    n_search = int(prm[N_SEARCH])
    if n_search == 0:        # the tier-1 planes are the plane search's warm start
        _initial_guess(c_n, (q0, bc, bs), prm, sc, np.True_)
    fab = fabric_terms(c_n, q0, bc, bs, prm, sc.dpz)
    f_tr, have_terms = _trial_yield(fab, prm, n_search, sc)
    state[i, 0] = state_n[i, 0]
    state[i, 1] = c_n
    state[i, 2] = q0
    state[i, 3] = bc
    state[i, 4] = bs
    s_ref = hypot(0.5 * (ttr[0] + ttr[1]), hypot(0.5 * (ttr[0] - ttr[1]), ttr[2]))
    if f_tr <= YIELD_TOL * s_ref:
        stress[i, 0] = ttr[0]
        stress[i, 1] = ttr[1]
        stress[i, 2] = ttr[2]
        isotropic_stiffness_into(bulk, shear, tangent[i])
        status[i] = STATUS_ELASTIC
        return
    qs = (q0, bc, bs)
    p_tr = -0.5 * (ttr[0] + ttr[1])
    r_tr = hypot(0.5 * (ttr[0] - ttr[1]), ttr[2])
    # The apex first, as tier 1: at c_apex, C⁻¹σ_tr at least as dilatant as the flow (only
    # possible where G P_tr <= K R_tr, as |sin ψ| < 1). Exact where φ and ψ are the same on
    # every plane (a2 = b2 = 0); otherwise the flow's dilatancy depends on its direction and
    # a trial the criterion puts at the apex goes to the face scan, which decides.
    c_apex = c_n * np.exp(p_tr / bulk)
    face = False
    projected = False
    ridge = False
    # (and a plastic trial at a stress too small to resolve — |σ_tr| < 1e-200 (K+G), where
    # Newton's arithmetic underflows — is σ = 0 to that accuracy)
    apex = s_ref < 1e-200 * (bulk + shear)
    scan = False
    if not apex and shear * p_tr <= bulk * r_tr:
        spsi_iso = _isotropic_dilatancy(c_apex, q0, bc, bs, prm, sc.dpz)
        if shear * p_tr + bulk * spsi_iso * r_tr <= 0.0:
            apex = prm[A2] == 0.0 and prm[B2] == 0.0
            scan = not apex
    if not (apex or scan):
        # Near the surface (the common case in a converging global iteration) one cutting-
        # plane step from σ_tr is the better start; otherwise, or if that solve fails,
        # tier 1's coaxial return.
        near = f_tr <= CUTTING_PLANE_RANGE * s_ref
        theta = sc.v[V_THETA]
        theta_tr = (theta[0], theta[1])
        if not (near and _cutting_plane_guess(c_n, qs, fab, prm, sc, np.True_, have_terms)):
            _initial_guess(c_n, qs, prm, sc, np.False_)
        face, projected, ridge = _face_return(c_n, qs, prm, sc, s_ref)
        if near and not face:
            # The plain cutting-plane step from the trial's planes: the solve from it finds
            # a point in some cases where the one from the hardening step does not, and the
            # reverse (each ~1e-4 of the steps of loose anisotropic states, measured)
            theta[0] = theta_tr[0]
            theta[1] = theta_tr[1]
            if _cutting_plane_guess(c_n, qs, fab, prm, sc, np.False_, np.False_):
                face, projected, ridge = _face_return(c_n, qs, prm, sc, s_ref)
        if near and not face:
            _initial_guess(c_n, qs, prm, sc, np.True_)
            face, projected, ridge = _face_return(c_n, qs, prm, sc, s_ref)
        if not face:
            face, projected, ridge = _continuation_return((rxx, ryy, rxy), c_n, qs, prm, sc)
        face = face and _resolved(prm, sc, s_ref)
    # No face point found yet: the scan of the face's directions finds it, or decides the
    # apex by the flows (a root beyond the apex); otherwise the local solve failed.
    if not (apex or face):
        face, projected, ridge, apex = _scan_return(c_n, qs, c_apex, prm, sc, s_ref)
    x = sc.v[V_X]
    if face:
        for j in range(3):
            stress[i, j] = x[j]
        c1 = x[4]
        # Δεp = C⁻¹(σ_tr - σ) (backward Euler's identity; = Δγ N at convergence), and the
        # fabric law at the final (Δεp, c): the returned state satisfies both exactly.
        pxx, pyy, pgg = _elastic_strain(ttr[0] - x[0], ttr[1] - x[1], ttr[2] - x[2], bulk,
                                        shear)
        projected = fabric_step(q0, bc, bs, pxx, pyy, pgg, c1, int(prm[FABRIC_LAW]), prm[KAPPA_A],
                                prm[K_C], prm[K_O], prm[A_CRIT], prm[B_RATIO_CRIT],
                                prm[RELAX_RATE], sc.v[V_FQ], sc.dq, sc.ws)
        # Tangent: solve J X = [C/s_ref; 0], column by column (J of the ridge return there).
        if ridge:
            _tangent(sc.jacr, sc.piv[1], sc.rhs, N_XR, bulk, shear, s_ref, tangent, i)
        else:
            _tangent(sc.jac, sc.piv[0], sc.rhs, N_X, bulk, shear, s_ref, tangent, i)
        status[i] = STATUS_FACE
    elif apex:
        stress[i, :] = 0.0
        tangent[i, :, :] = 0.0
        pxx, pyy, pgg = _elastic_strain(ttr[0], ttr[1], ttr[2], bulk, shear)
        c1 = c_apex
        projected = fabric_step(q0, bc, bs, pxx, pyy, pgg, c1, int(prm[FABRIC_LAW]), prm[KAPPA_A],
                                prm[K_C], prm[K_O], prm[A_CRIT], prm[B_RATIO_CRIT],
                                prm[RELAX_RATE], sc.v[V_FQ], sc.dq, sc.ws)
        status[i] = STATUS_APEX
    else:
        status[i] = STATUS_FAILED
        return
    state[i, 0] = state_n[i, 0] + hypot(pxx - pyy, pgg)
    state[i, 1] = c1
    # Φ's (admissible) output; on the face it equals x[5:8] to the solve's tolerance.
    fq = sc.v[V_FQ]
    state[i, 2] = fq[0]
    state[i, 3] = fq[1]
    state[i, 4] = fq[2]
    if projected:
        status[i] = STATUS_PROJECTED


@njit(cache=True, error_model="numpy")
def _update_range(lo, hi, stress_n, state_n, dstrain, dspin, prm, stress, state, tangent, status):
    """Update points lo..hi-1 (scratch allocated once per range, never per point)."""
    sc = _scratch()
    fabric_terms_jacobian(prm, sc.dpz)
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

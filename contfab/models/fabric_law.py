r"""Fabric hardening of tier 2: how (A, Bc, Bs) evolve with the plastic strain increment.

State (DESIGN §3): the contact-normal density p(θ) = A + Bc cos 2θ + Bs sin 2θ on [0, π),
A = z/π, (Bc, Bs) = B (cos 2θp, sin 2θp). Admissible set K (seed 000 eqs 1.14-1.15):
0 <= B <= A and (π/6) A + (√3/4) B <= 1. The increment D = Δεp is given in Voigt form
with engineering shear (Δεxx, Δεyy, Δγxy); on a direction θ, d_n = n·D·n and d_t = t·D·n,
so d_n = m + dx cos 2θ + dy sin 2θ with m = tr D / 2, dx = (Δεxx - Δεyy)/2, dy = Δγxy/2,
and d_t = -dx sin 2θ + dy cos 2θ (tension positive: d_n > 0 where neighbours recede).

**Spin** (:func:`rotate_fabric`): a rigid rotation by Δω turns θp by Δω and leaves A and B
unchanged: (Bc, Bs) is rotated by 2Δω exactly. Applied before either law.

**Law 0, the projected balance law** (seed 000 §8, DESIGN §4). ∂p/∂t + ∂θ J = I+ - I- with

    J  = κa p d_t                                   (advection by the flow)
    I+ = kc (4c/π) S(θ) [-d_n]+                      (creation where neighbours approach)
    I- = ko p [d_n]+                                 (opening where they recede)
    S(θ) = 1 - ½ ∫_{θ-π/6}^{θ+π/6} p = 1 - (π/6) A - (√3/4)(Bc cos 2θ + Bs sin 2θ)

(the local steric factor: the free room in the π/3 sector around θ; its minimum over θ is
the steric margin of K). Weak form on w ∈ {1, cos 2θ, sin 2θ}: M q̇ = ∫ J ∂θw + ∫ (I+ - I-) w,
M = diag(π, π/2, π/2). Every integral is **closed form** — the products are trigonometric
polynomials times [d_n]+, whose moments over the arc where d_n > 0 are elementary
(:func:`positive_part_moments`) — so there is no θ-quadrature error at all (a grid
quadrature converges to these values at O(n⁻²); tests/test_fabric_law.py measures it).
Advection contributes only M Ḃ = κa π A (dx, dy): in the truncated fabric it creates
anisotropy along the *extension* direction, and no more. The law is affine in q for a
given D, q̇ = b(D) - L(D) q + a(D) A, with b, L, a positively homogeneous of degree 1 in D
(rate independence: increments replace rates exactly).

Step (first order): creation and opening implicit, advection explicit,

    (M + γ Q Σ + ko P) q_{n+1} = M q_n + γ Q e0 + κa π A_n (0, dx, dy),   γ = kc 4c/π,

with P_ij = ∫[d_n]+ w_i w_j, Q_ij = ∫[-d_n]+ w_i w_j, Σ = diag(π/6, √3/4, √3/4). The
creation/opening operator has eigenvalues of non-negative real part, so the matrix is
invertible for every increment (det >= det M); the advection coupling A -> B is kept
explicit because, with it implicit, advection-dominated coefficients make the matrix
singular at finite increments (the frozen-D law is unstable there). c is c_{n+1}.

**Law 1, relaxation to a critical fabric** (the anisotropic-critical-state route):

    q_{n+1} = q_c + (q_n - q_c) exp(-k Δγs),   Δγs = Δεp1 - Δεp2,
    q_c = (A_c, B_c cos 2θc, B_c sin 2θc),     B_c = b_c A_c,

θc the most compressive principal direction of Δεp (so the critical fabric is aligned with
the loading's compression axis). It is a convex combination of q_n and q_c ∈ K, hence
admissible for every increment by construction.

**Admissibility** (:func:`fabric_step`). Law 1 never leaves K. Law 0 is the balance law
while admissible; the truncated law itself can point out of K on its boundary (measured:
e.g. pure compaction from the steric face with B > 0 has d/dt margin = γ m B (3/16 - π√3/24)
< 0, and creation at ±45° of θp overfills the major sector after projection onto three
modes), so the fabric is a *projected* dynamical system: on ∂K the outward part of the
rate is removed, discretized (like the stress return) as the closest-point projection
onto K after the step (:func:`contfab.fabric.project_admissible`, θp kept). Every such
projection is reported to the caller (status 3 of the tier-2 kernel), never silent.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from contfab.fabric import project_admissible
from dem.conventions import admissibility_margin

LAW_BALANCE = 0
LAW_RELAXATION = 1
LAW_NAMES = {LAW_BALANCE: "balance", LAW_RELAXATION: "relaxation"}

SQRT3_4 = np.sqrt(3.0) / 4.0


@njit(cache=True, error_model="numpy")
def positive_part_moments(m, r):
    """(I0, I1, I2) with I_k = ∫_{-π}^{π} [m + r cos x]+ cos(kx) dx, r >= 0, in closed form.

    With x0 = arccos(-m/r) clipped to [0, π] (the half-width of the arc where the
    integrand is positive): I0 = 2 m x0 + 2 r sin x0, I1 = 2 m sin x0 + r (x0 + sin x0 cos x0),
    I2 = m sin 2x0 + r (sin x0 + sin 3x0 / 3). x0 = π (all positive) gives (2πm, πr, 0).
    """
    if r > 0.0:
        x0 = np.arccos(min(max(-m / r, -1.0), 1.0))
    elif m > 0.0:
        x0 = np.pi
    else:
        return 0.0, 0.0, 0.0
    s0 = np.sin(x0)
    c0 = np.cos(x0)
    i0 = 2.0 * m * x0 + 2.0 * r * s0
    i1 = 2.0 * m * s0 + r * (x0 + s0 * c0)
    i2 = 2.0 * m * s0 * c0 + r * (s0 + np.sin(3.0 * x0) / 3.0)
    return i0, i1, i2


@njit(cache=True, error_model="numpy")
def rotate_fabric(bc, bs, dspin):
    """(Bc, Bs) after a rigid rotation by ``dspin``: θp += dspin, B unchanged.

    Round-off can make the rotated B an ulp larger, which would push a fabric on the bound
    B = A out of the admissible set: such growth is trimmed, so B never increases (a
    subnormal B, below any physical meaning and without ulps to trim, becomes 0).
    """
    c = np.cos(2.0 * dspin)
    s = np.sin(2.0 * dspin)
    rc = c * bc - s * bs
    rs = s * bc + c * bs
    b = np.hypot(bc, bs)
    for _ in range(4):
        if np.hypot(rc, rs) <= b:
            return rc, rs
        rc *= 1.0 - 2.0 ** -52
        rs *= 1.0 - 2.0 ** -52
    return 0.0, 0.0


@njit(cache=True, error_model="numpy")
def _gram_positive(m, dx, dy):
    """The six distinct ∫_0^π [d_n]+ w_i w_j dθ, w = (1, cos 2θ, sin 2θ), d_n = m + dx c2 + dy s2.

    Returned as (P00, P01, P02, P11, P12, P22).
    """
    r = np.hypot(dx, dy)
    i0, i1, i2 = positive_part_moments(m, r)
    if r > 0.0:
        c2b = dx / r
        s2b = dy / r
    else:
        c2b = 1.0
        s2b = 0.0
    # ∫_0^π F(2θ) dθ = ½ ∫_{-π}^{π} F(x + 2β) dx, 2β the direction of (dx, dy).
    m0 = 0.5 * i0
    m1c = 0.5 * i1 * c2b
    m1s = 0.5 * i1 * s2b
    m2c = 0.5 * i2 * (c2b * c2b - s2b * s2b)
    m2s = 0.5 * i2 * (2.0 * c2b * s2b)
    return m0, m1c, m1s, 0.5 * (m0 + m2c), 0.5 * m2s, 0.5 * (m0 - m2c)


@njit(cache=True, error_model="numpy")
def _solve3(a00, a01, a02, a10, a11, a12, a20, a21, a22, b0, b1, b2):
    """Cramer's rule for a 3x3 system (used only where det is bounded away from 0)."""
    c00 = a11 * a22 - a12 * a21
    c01 = a12 * a20 - a10 * a22
    c02 = a10 * a21 - a11 * a20
    det = a00 * c00 + a01 * c01 + a02 * c02
    x0 = (b0 * c00 + a01 * (b2 * a12 - b1 * a22) + a02 * (b1 * a21 - b2 * a11)) / det
    x1 = (a00 * (b1 * a22 - b2 * a12) + b0 * c01 + a02 * (b2 * a10 - b1 * a20)) / det
    x2 = (a00 * (a11 * b2 - a21 * b1) + a01 * (b1 * a20 - b2 * a10) + b0 * c02) / det
    return x0, x1, x2


@njit(cache=True, error_model="numpy")
def balance_system(a, bc, bs, dexx, deyy, dgxy, c, kappa_a, k_c, k_o):
    """The step's linear system X q_{n+1} = y of law 0 (module doc), rows divided by M.

    Returns the 9 entries of X (row-major) and the 3 of y.
    """
    m = 0.5 * (dexx + deyy)
    dx = 0.5 * (dexx - deyy)
    dy = 0.5 * dgxy
    p00, p01, p02, p11, p12, p22 = _gram_positive(m, dx, dy)
    # [-d_n]+ = [d_n]+ - d_n; the moments of d_n itself are exact trigonometric integrals.
    hp = 0.5 * np.pi
    q00 = p00 - np.pi * m
    q01 = p01 - hp * dx
    q02 = p02 - hp * dy
    q11 = p11 - hp * m
    q12 = p12
    q22 = p22 - hp * m
    g = k_c * 4.0 * c / np.pi
    s0 = np.pi / 6.0
    s1 = SQRT3_4
    # Rows divided by the mass M = diag(π, π/2, π/2): X q_{n+1} = q_n + rhs.
    r0 = 1.0 / np.pi
    r1 = 2.0 / np.pi
    return (
        1.0 + r0 * (g * q00 * s0 + k_o * p00), r0 * (g * q01 * s1 + k_o * p01),
        r0 * (g * q02 * s1 + k_o * p02),
        r1 * (g * q01 * s0 + k_o * p01), 1.0 + r1 * (g * q11 * s1 + k_o * p11),
        r1 * (g * q12 * s1 + k_o * p12),
        r1 * (g * q02 * s0 + k_o * p02), r1 * (g * q12 * s1 + k_o * p12),
        1.0 + r1 * (g * q22 * s1 + k_o * p22),
        a + r0 * g * q00,
        bc + r1 * g * q01 + 2.0 * kappa_a * a * dx,
        bs + r1 * g * q02 + 2.0 * kappa_a * a * dy)


@njit(cache=True, error_model="numpy")
def balance_step(a, bc, bs, dexx, deyy, dgxy, c, kappa_a, k_c, k_o):
    """One step of the projected balance law (law 0): the unprojected (A, Bc, Bs) after it."""
    x00, x01, x02, x10, x11, x12, x20, x21, x22, y0, y1, y2 = balance_system(
        a, bc, bs, dexx, deyy, dgxy, c, kappa_a, k_c, k_o)
    return _solve3(x00, x01, x02, x10, x11, x12, x20, x21, x22, y0, y1, y2)


@njit(cache=True, error_model="numpy")
def relaxation_step(a, bc, bs, dexx, deyy, dgxy, a_crit, b_ratio, rate):
    """One step of the relaxation law (law 1, module doc) for the increment Δεp."""
    dx = 0.5 * (dexx - deyy)
    dy = 0.5 * dgxy
    r = np.hypot(dx, dy)
    if r == 0.0:
        return a, bc, bs
    w = -np.expm1(-rate * 2.0 * r)
    # Compression axis θc: the minor principal direction of Δεp, so 2θc = angle(dx, dy) + π.
    b_crit = b_ratio * a_crit
    return (a + w * (a_crit - a), bc + w * (-b_crit * dx / r - bc),
            bs + w * (-b_crit * dy / r - bs))


@njit(cache=True, error_model="numpy")
def fabric_step(a, bc, bs, dexx, deyy, dgxy, c, law, kappa_a, k_c, k_o, a_crit, b_ratio, rate):
    """The fabric after the plastic increment (spin already applied): (A, Bc, Bs, projected).

    ``projected`` is True when the result had to be projected onto K (module doc).
    """
    if law == LAW_RELAXATION:
        a1, bc1, bs1 = relaxation_step(a, bc, bs, dexx, deyy, dgxy, a_crit, b_ratio, rate)
    else:
        a1, bc1, bs1 = balance_step(a, bc, bs, dexx, deyy, dgxy, c, kappa_a, k_c, k_o)
    if admissibility_margin(a1, np.hypot(bc1, bs1)) >= 0.0:
        return a1, bc1, bs1, False
    pa, pbc, pbs, moved = project_admissible(a1, bc1, bs1)
    return pa, pbc, pbs, moved


@njit(cache=True, error_model="numpy")
def drive_fabric(q0, dstrain_p, dspin, c, law, kappa_a, k_c, k_o, a_crit, b_ratio, rate):
    """Run the fabric law alone along prescribed plastic increments (for studies and tests).

    ``q0`` (3,) initial (A, Bc, Bs); ``dstrain_p`` (n, 3) Voigt plastic increments;
    ``dspin`` (n,) spin increments; ``c`` (n,) packing fraction at each step's end.
    Returns (history (n+1, 3), number of projected steps).
    """
    n = dstrain_p.shape[0]
    out = np.empty((n + 1, 3))
    out[0, :] = q0
    a, bc, bs = q0[0], q0[1], q0[2]
    projected = 0
    for i in range(n):
        bc, bs = rotate_fabric(bc, bs, dspin[i])
        a, bc, bs, moved = fabric_step(a, bc, bs, dstrain_p[i, 0], dstrain_p[i, 1],
                                       dstrain_p[i, 2], c[i], law, kappa_a, k_c, k_o,
                                       a_crit, b_ratio, rate)
        projected += moved
        out[i + 1, 0] = a
        out[i + 1, 1] = bc
        out[i + 1, 2] = bs
    return out, projected

r"""Fabric hardening of tier 2: how (A, Bc, Bs) evolve with the plastic strain increment.

State (docs/theory.md §2): the contact-normal density p(θ) = A + Bc cos 2θ + Bs sin 2θ on [0, π),
A = z/π, (Bc, Bs) = B (cos 2θp, sin 2θp). Admissible set K (Roux & Radjaï 2001, eqs 1.14–1.15):
0 <= B <= A and (π/6) A + (√3/4) B <= 1. The increment D = Δεp is given in Voigt form
with engineering shear (Δεxx, Δεyy, Δγxy); on a direction θ, d_n = n·D·n and d_t = t·D·n,
so d_n = m + dx cos 2θ + dy sin 2θ with m = tr D / 2, dx = (Δεxx - Δεyy)/2, dy = Δγxy/2,
and d_t = -dx sin 2θ + dy cos 2θ (tension positive: d_n > 0 where neighbours recede).

**Spin** (:func:`rotate_fabric`): a rigid rotation by Δω turns θp by Δω and leaves A and B
unchanged: (Bc, Bs) is rotated by 2Δω exactly. Applied before either law.

**Law 0, the projected balance law** (docs/theory.md §7; Roux & Radjaï 2001, §8).
∂p/∂t + ∂θ J = I+ - I- with

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

The kernels but :func:`drive_fabric` allocate no array: compiled with
:data:`contfab.jit_flags.KERNEL`.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from contfab.fabric import project_admissible
from contfab.jit_flags import KERNEL
from contfab.tensors import hypot
from dem.conventions import admissibility_margin

LAW_BALANCE = 0
LAW_RELAXATION = 1
LAW_NAMES = {LAW_BALANCE: "balance", LAW_RELAXATION: "relaxation"}

SQRT3_4 = np.sqrt(3.0) / 4.0


@njit(**KERNEL)
def positive_part_moments(m, r):
    """(I0, I1, I2) with I_k = ∫_{-π}^{π} [m + r cos x]+ cos(kx) dx, r >= 0, in closed form.

    With x0 = arccos(-m/r) clipped to [0, π] (the half-width of the arc where the
    integrand is positive): I0 = 2 m x0 + 2 r sin x0, I1 = 2 m sin x0 + r (x0 + sin x0 cos x0),
    I2 = m sin 2x0 + r (sin x0 + sin 3x0 / 3). x0 = π (all positive) gives (2πm, πr, 0).
    """
    i = _moments(m, r)
    return i[0], i[1], i[2]


@njit(**KERNEL)
def _moments(m, r):
    """I0, I1, I2 (:func:`positive_part_moments`), I1/r, I2/r and ∂I_k/∂m, ∂I_k/∂r.

    Leibniz: the integrand vanishes at ±x0, so ∂I_k/∂m = ∫ cos kx and ∂I_k/∂r = ∫ cos x cos kx
    over the arc. I1/r and I2/r stay bounded as r -> 0 (returned for the direction terms).
    """
    # x0 = π (positive everywhere) or 0 (nowhere) exactly, with sin x0 = 0 exactly: I1/r and
    # I2/r must not pick up round-off from sin(π) when r is tiny.
    if m >= r:
        x0, s0, c0, s3 = np.pi, 0.0, -1.0, 0.0
    elif m <= -r:
        x0, s0, c0, s3 = 0.0, 0.0, 1.0, 0.0
    else:
        x0 = np.arccos(-m / r)
        s0 = np.sin(x0)
        c0 = np.cos(x0)
        s3 = np.sin(3.0 * x0)
    i0 = 2.0 * m * x0 + 2.0 * r * s0
    i1 = 2.0 * m * s0 + r * (x0 + s0 * c0)
    i2 = 2.0 * m * s0 * c0 + r * (s0 + s3 / 3.0)
    if r > 0.0:
        j1 = i1 / r
        j2 = i2 / r
    else:
        j1 = x0
        j2 = 0.0
    return (i0, i1, i2, j1, j2, 2.0 * x0, 2.0 * s0, 2.0 * s0 * c0,
            2.0 * s0, x0 + s0 * c0, s0 + s3 / 3.0)


@njit(**KERNEL)
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


@njit(**KERNEL)
def _gram_positive(m, dx, dy, gram, dgram):
    """∫_0^π [d_n]+ w_i w_j dθ, w = (1, cos 2θ, sin 2θ), d_n = m + dx c2 + dy s2, and their
    derivatives in (m, dx, dy).

    ``gram`` (3, 3) ← P; ``dgram`` (3, 3, 3) ← ∂P_ij/∂(m, dx, dy)_v at [i, j, v].
    """
    r = hypot(dx, dy)
    i0, i1, i2, j1, j2, i0m, i1m, i2m, i0r, i1r, i2r = _moments(m, r)
    if r > 0.0:
        c = dx / r
        s = dy / r
    else:
        c = 1.0
        s = 0.0
    c4 = c * c - s * s
    s4 = 2.0 * c * s
    # ∫_0^π F(2θ) dθ = ½ ∫_{-π}^{π} F(x + 2β) dx, 2β the direction of (dx, dy): the k-th
    # harmonic picks I_k (cos 2kβ, sin 2kβ). Derivatives: ∂r = (c, s), ∂(2β) = (-s, c)/r.
    m0 = 0.5 * i0
    m1c = 0.5 * i1 * c
    m1s = 0.5 * i1 * s
    m2c = 0.5 * i2 * c4
    m2s = 0.5 * i2 * s4
    d_m0 = (0.5 * i0m, 0.5 * i0r * c, 0.5 * i0r * s)
    d_m1c = (0.5 * i1m * c, 0.5 * (i1r * c * c + j1 * s * s), 0.5 * (i1r - j1) * c * s)
    d_m1s = (0.5 * i1m * s, 0.5 * (i1r - j1) * c * s, 0.5 * (i1r * s * s + j1 * c * c))
    d_m2c = (0.5 * i2m * c4, 0.5 * (i2r * c * c4 + 2.0 * j2 * s4 * s),
             0.5 * (i2r * s * c4 - 2.0 * j2 * s4 * c))
    d_m2s = (0.5 * i2m * s4, 0.5 * (i2r * c * s4 - 2.0 * j2 * c4 * s),
             0.5 * (i2r * s * s4 + 2.0 * j2 * c4 * c))
    gram[0, 0] = m0
    gram[0, 1] = gram[1, 0] = m1c
    gram[0, 2] = gram[2, 0] = m1s
    gram[1, 1] = 0.5 * (m0 + m2c)
    gram[2, 2] = 0.5 * (m0 - m2c)
    gram[1, 2] = gram[2, 1] = 0.5 * m2s
    for v in range(3):
        dgram[0, 0, v] = d_m0[v]
        dgram[0, 1, v] = dgram[1, 0, v] = d_m1c[v]
        dgram[0, 2, v] = dgram[2, 0, v] = d_m1s[v]
        dgram[1, 1, v] = 0.5 * (d_m0[v] + d_m2c[v])
        dgram[2, 2, v] = 0.5 * (d_m0[v] - d_m2c[v])
        dgram[1, 2, v] = dgram[2, 1, v] = 0.5 * d_m2s[v]


BalanceWork = namedtuple("BalanceWork", "mats vecs")
"""Work arrays of law 0's step in :func:`fabric_step` (from :func:`balance_work`): ``mats``
(9, 3, 3) holds P, its derivatives (3), the system X and ∂X (4); ``vecs`` (6, 3) holds y, a
3-vector and ∂y (4) (:func:`_balance_step` slices them). Two arrays, not seven: the tier-2
kernels pass this inside their scratch to every non-inlined call, and numba passes each
array as its ~10 fields (measured: a tier-2 update 1.81 -> 1.77 µs with two)."""


@njit(cache=True)
def balance_work():
    """Fresh :data:`BalanceWork` arrays."""
    return BalanceWork(np.empty((9, 3, 3)), np.empty((6, 3)))


MASS = (np.pi, 0.5 * np.pi, 0.5 * np.pi)
STERIC = (np.pi / 6.0, SQRT3_4, SQRT3_4)


@njit(**KERNEL)
def _d_moment(i, j, v):
    """∂/∂(m, dx, dy)_v of ∫_0^π d_n w_i w_j dθ (exact; d_n is linear in (m, dx, dy))."""
    if v == 0:
        if i == j:
            return np.pi if i == 0 else 0.5 * np.pi
        return 0.0
    k = v          # dx couples (0, 1), dy couples (0, 2)
    if (i == 0 and j == k) or (j == 0 and i == k):
        return 0.5 * np.pi
    return 0.0


@njit(**KERNEL)
def balance_system(a, bc, bs, dexx, deyy, dgxy, c, kappa_a, k_c, k_o, x, y, dxs, dys, gram,
                   dgram):
    """The step's linear system X q_{n+1} = y of law 0 (module doc), rows divided by M, and
    its derivatives in the increment and c.

    ``x`` (3, 3), ``y`` (3,); ``dxs`` (4, 3, 3), ``dys`` (4, 3): derivatives in
    v = (Δεxx, Δεyy, Δγxy, c); ``gram`` (3, 3), ``dgram`` (3, 3, 3) scratch.
    """
    m = 0.5 * (dexx + deyy)
    dx = 0.5 * (dexx - deyy)
    dy = 0.5 * dgxy
    _gram_positive(m, dx, dy, gram, dgram)
    g = k_c * 4.0 * c / np.pi
    g_c = k_c * 4.0 / np.pi
    for i in range(3):
        for j in range(3):
            # [-d_n]+ = [d_n]+ - d_n: Q = P minus the exact moments of d_n.
            qij = gram[i, j] - _d_moment(i, j, 0) * m - _d_moment(i, j, 1) * dx \
                - _d_moment(i, j, 2) * dy
            x[i, j] = (1.0 if i == j else 0.0) + (g * qij * STERIC[j] + k_o * gram[i, j]) / MASS[i]
            dxs[3, i, j] = g_c * qij * STERIC[j] / MASS[i]
            d0 = (g * (dgram[i, j, 0] - _d_moment(i, j, 0)) * STERIC[j]
                  + k_o * dgram[i, j, 0]) / MASS[i]
            d1 = (g * (dgram[i, j, 1] - _d_moment(i, j, 1)) * STERIC[j]
                  + k_o * dgram[i, j, 1]) / MASS[i]
            d2 = (g * (dgram[i, j, 2] - _d_moment(i, j, 2)) * STERIC[j]
                  + k_o * dgram[i, j, 2]) / MASS[i]
            # (m, dx, dy) -> Voigt: ∂exx = ½(∂m + ∂dx), ∂eyy = ½(∂m - ∂dx), ∂γ = ½ ∂dy
            dxs[0, i, j] = 0.5 * (d0 + d1)
            dxs[1, i, j] = 0.5 * (d0 - d1)
            dxs[2, i, j] = 0.5 * d2
        # creation's source γ Q_i0, and the explicit advection κa π A (0, dx, dy) / M
        qi0 = gram[i, 0] - _d_moment(i, 0, 0) * m - _d_moment(i, 0, 1) * dx \
            - _d_moment(i, 0, 2) * dy
        d0 = g * (dgram[i, 0, 0] - _d_moment(i, 0, 0)) / MASS[i]
        d1 = g * (dgram[i, 0, 1] - _d_moment(i, 0, 1)) / MASS[i]
        d2 = g * (dgram[i, 0, 2] - _d_moment(i, 0, 2)) / MASS[i]
        y[i] = g * qi0 / MASS[i]
        if i == 0:
            y[i] += a
        elif i == 1:
            y[i] += bc + 2.0 * kappa_a * a * dx
            d1 += 2.0 * kappa_a * a
        else:
            y[i] += bs + 2.0 * kappa_a * a * dy
            d2 += 2.0 * kappa_a * a
        dys[0, i] = 0.5 * (d0 + d1)
        dys[1, i] = 0.5 * (d0 - d1)
        dys[2, i] = 0.5 * d2
        dys[3, i] = g_c * qi0 / MASS[i]


@njit(**KERNEL)
def _invert3(x, out):
    """out = x⁻¹ for a 3x3 x (cofactors; used where det x >= 1)."""
    out[0, 0] = x[1, 1] * x[2, 2] - x[1, 2] * x[2, 1]
    out[0, 1] = x[0, 2] * x[2, 1] - x[0, 1] * x[2, 2]
    out[0, 2] = x[0, 1] * x[1, 2] - x[0, 2] * x[1, 1]
    out[1, 0] = x[1, 2] * x[2, 0] - x[1, 0] * x[2, 2]
    out[1, 1] = x[0, 0] * x[2, 2] - x[0, 2] * x[2, 0]
    out[1, 2] = x[0, 2] * x[1, 0] - x[0, 0] * x[1, 2]
    out[2, 0] = x[1, 0] * x[2, 1] - x[1, 1] * x[2, 0]
    out[2, 1] = x[0, 1] * x[2, 0] - x[0, 0] * x[2, 1]
    out[2, 2] = x[0, 0] * x[1, 1] - x[0, 1] * x[1, 0]
    inv_det = 1.0 / (x[0, 0] * out[0, 0] + x[0, 1] * out[1, 0] + x[0, 2] * out[2, 0])
    for i in range(3):
        for j in range(3):
            out[i, j] *= inv_det


@njit(**KERNEL, inline="always")
def one_minus_exp(x):
    """1 - exp(-x) for x >= 0, to a few ulps relative (as -expm1(-x), at less latency):
    the Taylor series through x⁸ below x = 1/32 (truncation below x⁸/9! < 3e-18
    relative), 1 - exp(-x) above (the subtraction's rounding is below 1.1e-16/(1 - e^(-1/32))
    = 3.6e-15 relative). glibc's expm1 took ~7 % of a tier-2 update (perf), called once per
    fabric step."""
    if x >= 0.03125:
        return 1.0 - np.exp(-x)
    return x * (1.0 - x * (0.5 - x * (1.0 / 6.0 - x * (1.0 / 24.0 - x * (
        1.0 / 120.0 - x * (1.0 / 720.0 - x * (1.0 / 5040.0 - x * (1.0 / 40320.0))))))))


@njit(**KERNEL, inline="always")
def relaxation_step(a, bc, bs, dexx, deyy, dgxy, a_crit, b_ratio, rate, speed, dilation, q, dq):
    """One step of the relaxation law (law 1, module doc): ``q`` (3,) ← the fabric after it,
    ``dq`` (4, 3) ← its derivatives in (Δεxx, Δεyy, Δγxy, c) (zero at Δεp = 0).

    The rate is k_eff = (k⁻² + (d/v)²)^(-1/2) (1 + β [tr Δεp]₊/Δγs): d = |B_c - B_n|/A_c the
    anisotropy's distance from its target at the step's start (v = ``speed``; inf gives
    k_eff = k), β = ``dilation`` the acceleration by dilation."""
    dx = 0.5 * (dexx - deyy)
    dy = 0.5 * dgxy
    r = hypot(dx, dy)
    if r == 0.0:
        dq[:, :] = 0.0
        q[0] = a
        q[1] = bc
        q[2] = bs
        return
    dq[3, :] = 0.0      # rows 0-2 are set below
    # Compression axis θc: the minor principal direction of Δεp, so 2θc = angle(dx, dy) + π.
    b_crit = b_ratio * a_crit
    cx = dx / r
    cy = dy / r
    tgt = (1.0 * a_crit, -b_crit * cx, -b_crit * cy)
    cur = (1.0 * a, 1.0 * bc, 1.0 * bs)
    # ∂(cx, cy)/∂(dx, dy) = [[cy², -cx cy], [-cx cy, cx²]] / r.
    d_tgt_dx = (0.0, -b_crit * cy * cy / r, b_crit * cx * cy / r)
    d_tgt_dy = (0.0, b_crit * cx * cy / r, -b_crit * cx * cx / r)
    # The effective rate k_eff = k_gap · f_dil and its derivatives in (dx, dy, tr).
    k_gap = rate
    dk_dx = 0.0
    dk_dy = 0.0
    if speed < np.inf and a_crit > 0.0:
        gap_x = tgt[1] - cur[1]
        gap_y = tgt[2] - cur[2]
        gap = hypot(gap_x, gap_y)
        d = gap / a_crit
        k_gap = 1.0 / np.sqrt(1.0 / (rate * rate) + (d / speed) ** 2)
        if gap > 0.0:
            dk_dd = -k_gap ** 3 * d / (speed * speed)
            dk_dx = dk_dd * (gap_x * d_tgt_dx[1] + gap_y * d_tgt_dx[2]) / (gap * a_crit)
            dk_dy = dk_dd * (gap_x * d_tgt_dy[1] + gap_y * d_tgt_dy[2]) / (gap * a_crit)
    tr = dexx + deyy
    f_dil = 1.0
    df_dx = 0.0
    df_dy = 0.0
    df_dtr = 0.0
    if dilation > 0.0 and tr > 0.0:
        # f = 1 + β tr / (2r): ∂f/∂tr = β/(2r), ∂f/∂(dx, dy) = -β tr (cx, cy) / (2r²)
        f_dil = 1.0 + dilation * tr / (2.0 * r)
        df_dtr = dilation / (2.0 * r)
        df_dx = -dilation * tr * cx / (2.0 * r * r)
        df_dy = -dilation * tr * cy / (2.0 * r * r)
    k_eff = k_gap * f_dil
    kx = dk_dx * f_dil + k_gap * df_dx
    ky = dk_dy * f_dil + k_gap * df_dy
    kt = k_gap * df_dtr
    w = one_minus_exp(k_eff * 2.0 * r)
    e = 1.0 - w          # exp(-2 k r), to round-off (it enters only the derivatives)
    for i in range(3):
        q[i] = cur[i] + w * (tgt[i] - cur[i])
        # ∂w = e (2 k_eff ∂r + 2 r ∂k_eff), ∂r/∂(dx, dy) = (cx, cy)
        ddx = e * (2.0 * k_eff * cx + 2.0 * r * kx) * (tgt[i] - cur[i]) + w * d_tgt_dx[i]
        ddy = e * (2.0 * k_eff * cy + 2.0 * r * ky) * (tgt[i] - cur[i]) + w * d_tgt_dy[i]
        dtr = e * 2.0 * r * kt * (tgt[i] - cur[i])
        # (dx, dy, tr) = (½(Δεxx - Δεyy), ½Δγxy, Δεxx + Δεyy)
        dq[0, i] = 0.5 * ddx + dtr
        dq[1, i] = -0.5 * ddx + dtr
        dq[2, i] = 0.5 * ddy


@njit(**KERNEL, inline="always")
def fabric_step(a, bc, bs, dexx, deyy, dgxy, c, law, kappa_a, k_c, k_o, a_crit, b_ratio, rate,
                speed, dilation, q, dq, ws):
    """The fabric after the plastic increment (spin already applied).

    ``q`` (3,) ← (A, Bc, Bs); ``dq`` (4, 3) ← ∂q/∂(Δεxx, Δεyy, Δγxy, c), through the
    projection when it acts; ``ws`` a :data:`BalanceWork` (law 0's scratch). Returns True
    when the result had to be projected onto K (module doc).

    Inlined into its callers (numba's ``inline="always"``), with law 0's step and the
    projection out of line: a call that passes ``ws`` costs ~40 ns by itself, more than
    law 1's whole step (measured), and the tier-2 update makes about six per point.
    """
    if law == LAW_RELAXATION:
        relaxation_step(a, bc, bs, dexx, deyy, dgxy, a_crit, b_ratio, rate, speed, dilation, q, dq)
    else:
        _balance_step(a, bc, bs, dexx, deyy, dgxy, c, kappa_a, k_c, k_o, q, dq, ws)
    # The margin is non-increasing in B (each term's rounding is monotone), so where it holds
    # at the fast norm raised past both norms' rounding (each within ~2 ulp of the exact
    # one), it holds at np.hypot's B, which project_admissible uses: only the doubtful
    # cases pay for np.hypot (~25 ns), and the decision is unchanged.
    if (admissibility_margin(q[0], hypot(q[1], q[2]) * (1.0 + 1e-15)) >= 0.0
            or admissibility_margin(q[0], np.hypot(q[1], q[2])) >= 0.0):
        return False
    return _project_step(q, dq)


@njit(**KERNEL)
def _balance_step(a, bc, bs, dexx, deyy, dgxy, c, kappa_a, k_c, k_o, q, dq, ws):
    """Law 0's step (:func:`balance_system`, solved): q and ∂q before any projection."""
    gram = ws.mats[0]
    dgram = ws.mats[1:4]
    x = ws.mats[4]
    dxs = ws.mats[5:9]
    y = ws.vecs[0]
    tmp = ws.vecs[1]
    dys = ws.vecs[2:6]
    balance_system(a, bc, bs, dexx, deyy, dgxy, c, kappa_a, k_c, k_o, x, y, dxs, dys,
                   gram, dgram)
    xi = gram          # P is no longer needed: reuse its storage for X⁻¹
    _invert3(x, xi)
    for i in range(3):
        q[i] = xi[i, 0] * y[0] + xi[i, 1] * y[1] + xi[i, 2] * y[2]
    # ∂q = X⁻¹ (∂y - ∂X q)
    for v in range(4):
        for i in range(3):
            tmp[i] = dys[v, i] - (dxs[v, i, 0] * q[0] + dxs[v, i, 1] * q[1]
                                  + dxs[v, i, 2] * q[2])
        for i in range(3):
            dq[v, i] = xi[i, 0] * tmp[0] + xi[i, 1] * tmp[1] + xi[i, 2] * tmp[2]


@njit(**KERNEL)
def _project_step(q, dq):
    """q ← its projection onto K, dq chained through it (:func:`_chain_projection`); whether
    it moved."""
    a1, bc1, bs1 = q[0], q[1], q[2]
    q[0], q[1], q[2], moved = project_admissible(a1, bc1, bs1)
    _chain_projection(a1, bc1, bs1, q, dq)
    return moved


@njit(**KERNEL)
def _chain_projection(a, bc, bs, q, dq):
    """dq ← (∂ projection / ∂(A, Bc, Bs)) dq for the projection of (a, bc, bs) onto q.

    The projection keeps θp and moves (A, B) to the closest point of the admissible triangle
    (:func:`contfab.fabric.project_admissible`): on an edge with unit direction t it is
    t tᵀ in (A, B) (0 at a vertex), and (Bc, Bs) = B' e with e = (Bc, Bs)/B, so
    d(Bc, Bs) = dB' e + (B'/B)(I - e eᵀ) d(Bc, Bs). This keeps the local Newton's Jacobian
    exact where the fabric law runs along a bound.
    """
    b = np.hypot(bc, bs)
    pa = q[0]
    pb = np.hypot(q[1], q[2])
    on_ba = abs(pa - pb) <= 1e-12 * max(pa, 1e-300)
    on_steric = abs(np.pi / 6.0 * pa + SQRT3_4 * pb - 1.0) <= 1e-12
    if on_ba and not on_steric:
        ta, tb = np.sqrt(0.5), np.sqrt(0.5)
    elif on_steric and not on_ba:
        norm = np.hypot(np.pi / 6.0, SQRT3_4)
        ta, tb = SQRT3_4 / norm, -np.pi / 6.0 / norm
    elif pb == 0.0 and pa > 0.0 and not on_steric:
        ta, tb = 1.0, 0.0                      # the edge B = 0 (A moves, B stays 0)
    else:
        ta, tb = 0.0, 0.0                      # a vertex: (A, B) fixed
    if b > 0.0:
        ec = bc / b
        es = bs / b
        ratio = pb / b
    else:
        ec, es, ratio = 1.0, 0.0, 0.0
    for v in range(dq.shape[0]):
        da = dq[v, 0]
        db = ec * dq[v, 1] + es * dq[v, 2]            # radial part of d(Bc, Bs)
        dt = -es * dq[v, 1] + ec * dq[v, 2]           # tangential part (turns θp)
        s = ta * da + tb * db                          # along the edge
        dq[v, 0] = ta * s
        dbp = tb * s
        dq[v, 1] = dbp * ec - ratio * dt * es
        dq[v, 2] = dbp * es + ratio * dt * ec


@njit(cache=True, error_model="numpy")
def drive_fabric(q0, dstrain_p, dspin, c, law, kappa_a, k_c, k_o, a_crit, b_ratio, rate, speed,
                 dilation):
    """Run the fabric law alone along prescribed plastic increments (for studies and tests).

    ``q0`` (3,) initial (A, Bc, Bs); ``dstrain_p`` (n, 3) Voigt plastic increments;
    ``dspin`` (n,) spin increments; ``c`` (n,) packing fraction at each step's end.
    Returns (history (n+1, 3), number of projected steps).
    """
    n = dstrain_p.shape[0]
    out = np.empty((n + 1, 3))
    out[0, :] = q0
    q = q0.copy()
    dq = np.empty((4, 3))
    work = balance_work()
    projected = 0
    for i in range(n):
        bc, bs = rotate_fabric(q[1], q[2], dspin[i])
        projected += fabric_step(q[0], bc, bs, dstrain_p[i, 0], dstrain_p[i, 1],
                                 dstrain_p[i, 2], c[i], law, kappa_a, k_c, k_o, a_crit,
                                 b_ratio, rate, speed, dilation, q, dq, work)
        out[i + 1, :] = q
    return out, projected

r"""Tier 2 yield function and flow over slip planes (docs/theory.md §6; Roux & Radjaï 2001, §5).

Conventions: tension positive, Voigt stress (σxx, σyy, σxy), Voigt strain with engineering
shear. A slip plane has normal n(θ) = (cos θ, sin θ) and tangent t(θ) = (-sin θ, cos θ);
σn = n·σ·n, τ = t·σ·n. With m = (σxx+σyy)/2, R and the major principal direction α
(σ1 = m + R along α): σn = m + R cos u, τ = -R sin u, u = 2(θ - α).

**Friction and dilatancy per plane.** With (Bc, Bs) the fabric and c the packing fraction,

    φ(θ) = a0 + φ'(c - c*) + a1 A + a2 B cos(2(θ - θp) + a3)      (eq. 1.8 there + tier 1's c-term)
    ψ(θ) = b0 + ψ'(c - c*) + b1 A + b2 B cos(2(θ - θp) + b3)

clamped like tier 1 (φ to [φ_min, φ_max], then ψ to [-φ, φ]). B cos(2(θ-θp) + a3) =
Bc' cos 2θ + Bs' sin 2θ with (Bc', Bs') the fabric rotated by -a3/2, so nothing is singular
at B = 0. Carrying tier 1's c-term is what makes the reduction exact: with a2 = b2 = 0,
a1 = b1 = 0, a0 = φ*, b0 = 0, every plane has tier 1's φ(c), ψ(c).

**Yield.** h(θ) = |τ| + tan φ(θ) σn, f(σ) = max over θ (compression makes σn < 0). The planes
split into two arcs by the sign of τ (u ∈ (0, π): τ < 0; u ∈ (-π, 0): τ > 0), the two
conjugate slip families; h is smooth on each (up to the clamp's corners, below). We take
the exact maximum h_k of each arc (a grid of ``n_search`` points per arc, then safeguarded
Newton on ∂h/∂θ = 0) and

    f = Σ_k w_k h_k,   w = softmax(β h_k / s),   s = sqrt(m² + R²),

the softmax-weighted mean of the two arc maxima. It is exact where it must be: at
isotropy the two maxima tie, w = (½, ½) and f = max h = (R - sin φ P)/cos φ — tier 1's yield
function divided by cos φ, the same surface. Elsewhere f <= max h, short of it by at most
0.28 s/β (measured in tests/test_slip_planes.py; β = 50: 0.6 % of s). f is positively
homogeneous of degree 1 (a cone). A plain log-sum-exp over a θ grid would overestimate the
max at isotropy by up to log(n)/β·s and break the reduction; this form does not.

**Flow.** On plane θ with sign g = sign τ: N(θ) = g cos ψ̂ sym(t⊗n) + sin ψ̂ n⊗n, i.e.
N = g cos ψ̂ ∂τ/∂σ + sin ψ̂ ∂σn/∂σ (trace sin ψ̂, Δε1 - Δε2 = 1 per unit slip), and the total
flow is N = Σ_k w_k N(θ_k) with the yield's weights: coaxial at isotropy (the two conjugate
planes weigh equally), one plane dominating under strong anisotropy (non-coaxial flow).

ψ(θ) keeps tier 1's meaning — the dilatancy sin ψ = tr/(ε1 - ε2) (eq. 1.2 there) of the
symmetric double slip on the planes θ and its conjugate. Averaging two conjugate planes at
±(π/4 - φ/2) cancels part of their deviators, so a plane slip angle equal to ψ would give
sin ψ_macro = sin ψ / cos(φ - ψ) (+6 % at φ = 30°, ψ = 10°). The plane's slip angle ψ̂ is
therefore the one that reproduces ψ exactly:

    tan ψ̂ = sin ψ cos φ / (1 - sin ψ sin φ)     (ψ̂ = 0 at ψ = 0, ψ̂ = φ at ψ = φ).

**Corners and ends.** Where φ_raw(θ) (before the clamp) crosses φ_min or φ_max, h is only
piecewise smooth: h = |τ| + tan(max(φ_raw, φ_min)) σn is the lesser of its two branches on a
plane in compression, so its graph has a kink at the boundary φ_raw(θ_b) = φ_min, and an arc
maximum can sit on that kink (h_θ jumping from + to -) for a whole range of stresses — e.g.
loose states, where φ(c) is low and the fabric term takes the weakest planes below φ_min.
Such a corner maximum is located exactly (θ_b in closed form). Where the φ-anisotropy
outweighs the stress ratio an arc's maximum can also sit on one of its ends, τ = 0 (the
principal planes θ = α, α + π/2, which the plane search therefore also evaluates). Both
have their own derivatives below.

**Derivatives** (for the local Newton and the consistent tangent), all analytic: interior
arc maxima obey the envelope theorem, ∂h_k/∂σ = ∂h/∂σ at fixed θ_k, and the planes move with
∂θ_k/∂σ = -h_θσ / h_θθ; a corner plane θ_b does not move with σ (∂θ_b/∂σ = 0, ∂h_k/∂σ =
∂h/∂σ at θ_b) but with the angle coefficients p, ∂θ_b/∂p = -∂φ_raw/∂p / φ_raw_θ, and then
∂h_k/∂p = ∂h/∂p + h_θ ∂θ_b/∂p; an end plane turns with the principal axis, ∂θ/∂σ = ∂α/∂σ,
∂h_k/∂σ = ∂h/∂σ + h_θ ∂α/∂σ, and not with p. The softmax weights are differentiated in
full.

Every kernel here takes arrays and allocates none: compiled with
:data:`contfab.jit_flags.KERNEL`.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from contfab.jit_flags import KERNEL
from contfab.params import (A0, A1, A2, A3, B0, B1, B2, B3, C_STAR, DPHI_DC, DPSI_DC, PHI_MAX,
                            PHI_MIN)
from contfab.tensors import hypot

# The six angle coefficients p = (φ0, pc, ps, ψ0, qc, qs) of φ(θ) = φ0 + pc cos 2θ + ps sin 2θ
# and ψ(θ) = ψ0 + qc cos 2θ + qs sin 2θ (:func:`fabric_terms`): c, A, Bc, Bs act only through
# them, so derivatives are taken in p (row-major (3, 6) blocks for N).
N_P = 6
# Layout of one plane's terms (row of the ``pl`` scratch array): h, ∂h/∂σ, ∂h/∂p (the three
# φ coefficients), ∂θ/∂σ, ∂θ/∂p, N, ∂N/∂θ, ∂N/∂p at fixed θ, sin ψ̂, its θ- and
# p-derivatives, the plane's own Newton step.
PL_H, PL_HS, PL_HP, PL_TS, PL_TP, PL_N, PL_NT, PL_NP, PL_SH, PL_SHT, PL_SHP, PL_DT = (
    0, 1, 4, 7, 10, 13, 16, 19, 37, 38, 39, 45)
N_PL = 46
# Layout of the aggregated yield/flow terms (the ``yf`` scratch array): f, ∂f/∂σ, ∂f/∂p (φ
# coefficients), N, ∂N/∂σ (3x3), ∂N/∂p (3x6), tr N, ∂trN/∂σ, ∂trN/∂p.
YF_F, YF_FS, YF_FP, YF_N, YF_NS, YF_NP, YF_TR, YF_TRS, YF_TRP = 0, 1, 4, 7, 10, 19, 37, 38, 41
N_YF = 47

NEWTON_MAXIT_PLANE = np.int64(60)
WARM_START = np.int64(0)
"""``n_search`` of a plane search from the warm start alone (no grid). This and the step limit
above are NumPy scalars, not Python literals: numba compiles a callee once per literal value
it is called with, once in all for a NumPy scalar."""
PLANE_TOL = 1e-13
"""Plane search: a Newton or bisection step below this (radians of u) ends it."""
PLANE_LAST_STEP = 1e-7
"""Plane search: a Newton step below this is the last (Newton converges quadratically: it
leaves ~1e-14, below PLANE_TOL's next step, without another evaluation of h)."""


@njit(**KERNEL)
def _clamped(angle, d1, d2, lo, hi):
    """(angle, d1, d2) with angle clamped to [lo, hi] (derivatives 0 where clamped)."""
    if angle < lo:
        return lo, 0.0, 0.0, False
    if angle > hi:
        return hi, 0.0, 0.0, False
    return angle, d1, d2, True


@njit(**KERNEL)
def _kink(c2, s2, phi0, pc, ps, phi_lo, phi_hi):
    """The clamp boundary of φ nearest to the plane with (cos 2θ, sin 2θ) = (c2, s2).

    With φ_raw(θ) = φ0 + pc cos 2θ + ps sin 2θ = φ0 + ρ cos(2θ - β) the boundaries are the
    planes where φ_raw = φ_b, b ∈ {min, max}: 2θ - β = ±arccos((φ_b - φ0)/ρ) (where
    |φ_b - φ0| < ρ). Returns (d, φ_raw_θ there, φ_b, s): d the change of 2θ to the nearest
    one (wrapped to (-π, π]; inf if φ_raw reaches neither bound), s = ±1 the direction of
    θ toward its free side (φ_min < φ_raw < φ_max).
    """
    rho = hypot(pc, ps)
    best = np.inf
    slope = 0.0
    bound = 0.0
    side = 0.0
    if rho == 0.0:
        return best, slope, bound, side
    gam = np.arctan2(pc * s2 - ps * c2, pc * c2 + ps * s2)      # 2θ - β
    for b, upper in ((phi_lo, False), (phi_hi, True)):
        x = (b - phi0) / rho
        if abs(x) < 1.0:
            a = np.arccos(x)
            for gk in (a, -a):
                d = gk - gam
                d -= 2.0 * np.pi * np.floor((d + np.pi) / (2.0 * np.pi))
                if abs(d) < abs(best):
                    best = d
                    slope = -2.0 * rho * np.sin(gk)
                    bound = b
                    side = (-1.0 if slope < 0.0 else 1.0) * (-1.0 if upper else 1.0)
    return best, slope, bound, side


@njit(**KERNEL)
def has_kinks(phi0, rho, phi_lo, phi_hi):
    """Whether φ_raw(θ) = φ0 + ρ cos(2θ - β) (:func:`_kink`; ρ = hypot(pc, ps), fab[6] of
    :func:`fabric_terms`) crosses a clamp bound: only then can an arc maximum sit on a corner
    of h."""
    return rho > 0.0 and (phi0 - rho < phi_lo or phi0 + rho > phi_hi)


@njit(**KERNEL)
def single_maximum(m, r, phi0, pc, ps, phi_lo, phi_hi):
    r"""Whether h has a single local maximum on each arc, proved from bounds (no search):
    then a safeguarded refinement from anywhere in the arc finds its maximum.

    Without a clamp corner (:func:`has_kinks` False) write tan φ(u) = T0 + δT(u), T0 = tan φ0,
    |φ - φ0| <= ρ = hypot(pc, ps). On arc g, h = T0 m + S cos(u - u*) + δh(u) with
    S = R sec φ0, u* = atan2(-g, T0) and δh = δT (m + R cos u). With |φ_u|, |φ_uu| <= ρ,
    K = sec²φ and t = |tan φ| at the larger |φ0 ± ρ|, M = |m| + R:

        |δh'| <= D1 = K ρ (M + R),   |δh''| <= D2 = K ρ (1 + 2 t ρ) M + 3 K ρ R.

    Let sin w = D1/S. Where |u - u*| is in [w, π - w], h' = -S sin(u - u*) + δh' keeps the
    sign of -sin(u - u*); where |u - u*| < w, h'' <= -S cos w + D2. So with D1 < S,
    D2 < S cos w and w <= |u*| <= π - w (the arc [0, π] or [-π, 0] then never reaches within
    w of the antipode u* ± π; as sin |u*| = cos φ0 = R/S this is D1 <= R), h rises, is
    strictly concave, then falls along the arc: one maximum (possibly at an end). With
    ρ = 0 (φ independent of θ) this holds wherever R > 0.
    """
    rho = hypot(pc, ps)
    if r <= 0.0 or has_kinks(phi0, rho, phi_lo, phi_hi):
        return False
    t0 = np.tan(phi0)
    amp = r * np.sqrt(1.0 + t0 * t0)
    t = np.tan(max(abs(phi0 - rho), abs(phi0 + rho)))
    k = 1.0 + t * t
    big = abs(m) + r
    d1 = k * rho * (big + r)
    d2 = k * rho * (1.0 + 2.0 * t * rho) * big + 3.0 * k * rho * r
    # w <= |u*| <= π - w  <=>  sin w <= sin |u*| = 1/sec φ0  <=>  D1 <= R (and then D1 < S).
    if not d1 <= r:
        return False
    sin_w = d1 / amp
    return d2 < amp * np.sqrt(1.0 - sin_w * sin_w)


@njit(**KERNEL)
def _h_on_arc(u, g, m, r, ca, sa, phi0, pc, ps, phi_lo, phi_hi):
    """h, ∂h/∂u, ∂²h/∂u² at u = 2(θ - α) on the arc of sign g (the plane search)."""
    cu = np.cos(u)
    su = np.sin(u)
    c2 = ca * cu - sa * su
    s2 = sa * cu + ca * su
    sn = m + r * cu
    phi, pu, puu, _ = _clamped(phi0 + pc * c2 + ps * s2, -pc * s2 + ps * c2,
                               -(pc * c2 + ps * s2), phi_lo, phi_hi)
    t = np.tan(phi)
    sec2 = 1.0 + t * t
    tu = sec2 * pu
    tuu = 2.0 * t * sec2 * pu * pu + sec2 * puu
    h = -g * r * su + t * sn
    hu = -g * r * cu + tu * sn - t * r * su
    huu = g * r * su + tuu * sn - 2.0 * tu * r * su - t * r * cu
    return h, hu, huu


@njit(**KERNEL)
def _corner_on_arc(u, g, m, r, ca, sa, slope, bound, side):
    """Whether h has a corner maximum at the clamp boundary u (:func:`_kink`: φ_raw = φ_b
    there, φ_raw_θ = ``slope``, ``side`` toward the free side): the clamped branch
    (φ = φ_b) rises toward the free side and the free branch (φ = φ_raw) falls into it,

        ∂h_clamped/∂u · s > 0 > ∂h_free/∂u · s,
        ∂h_free/∂u = ∂h_clamped/∂u + sec²φ_b φ_raw_u σn.
    """
    cu = np.cos(u)
    su = np.sin(u)
    t = np.tan(bound)
    hu_clamped = -g * r * cu - t * r * su
    hu_free = hu_clamped + (1.0 + t * t) * 0.5 * slope * (m + r * cu)
    return hu_clamped * side > 0.0 and hu_free * side < 0.0


@njit(**KERNEL)
def arc_maximum(g, u0, n_search, maxit, m, r, ca, sa, fab):
    """(u, h(u)): the maximum of h over the arc of sign g (u in [0, π] for g < 0, [-π, 0]
    else), h as :func:`_refine_on_arc` gives it.

    With ``n_search`` > 0: h on that many evenly spaced points and on the arc's two ends
    (τ = 0, the principal planes: h = tan φ σ1 at u = 0, tan φ σ2 at u = ±π, where a
    maximum on an end is missed by the grid's midpoints); the two highest local maxima of
    these values are each refined (:func:`_refine_on_arc`, bracketed by their neighbours)
    and the higher result is the maximum — two peaks nearly tied could otherwise be decided
    by the grid's samples, not by their values. Otherwise ``u0`` starts the refinement (a
    warm start) inside the whole arc. The grid's cos u, sin u follow by rotation through du.
    (:func:`arc_maxima` skips the grid where it is not needed.) Each refinement takes at most
    ``maxit`` steps (NEWTON_MAXIT_PLANE: to convergence). ``fab``: :func:`fabric_terms`.
    """
    phi0, pc, ps, phi_lo, phi_hi = fab[0], fab[1], fab[2], fab[8], fab[9]
    kinks = has_kinks(phi0, fab[6], phi_lo, phi_hi)
    if g < 0.0:
        lo = 0.0
        hi = np.pi
    else:
        lo = -np.pi
        hi = 0.0
    if n_search == 0:
        return _refine_on_arc(g, min(max(u0, lo), hi), lo, hi, kinks, maxit, m, r, ca, sa,
                              phi0, pc, ps, phi_lo, phi_hi)
    du = (hi - lo) / n_search
    h1 = -np.inf
    h2 = -np.inf
    u1 = lo
    u2 = lo
    # The values in order along the arc (end lo, the grid, end hi); v_cur is a local maximum
    # when neither neighbour is higher.
    v_prev = -np.inf
    u_cur = lo
    v_cur = _end_value(lo, m, r, ca, sa, phi0, pc, ps, phi_lo, phi_hi)
    cd = np.cos(du)
    sd = np.sin(du)
    cu = np.cos(lo + 0.5 * du)
    su = np.sin(lo + 0.5 * du)
    for i in range(1, n_search + 3):
        if i <= n_search:
            u_next = lo + (i - 0.5) * du
            v_next = _h_value(cu, su, g, m, r, ca, sa, phi0, pc, ps, phi_lo, phi_hi)
            cu, su = cu * cd - su * sd, su * cd + cu * sd
        elif i == n_search + 1:
            u_next = hi
            v_next = _end_value(hi, m, r, ca, sa, phi0, pc, ps, phi_lo, phi_hi)
        else:
            u_next = hi
            v_next = -np.inf
        if v_cur >= v_prev and v_cur >= v_next:
            if v_cur > h1:
                h2 = h1
                u2 = u1
                h1 = v_cur
                u1 = u_cur
            elif v_cur > h2:
                h2 = v_cur
                u2 = u_cur
        v_prev = v_cur
        v_cur = v_next
        u_cur = u_next
    u, h = _refine_on_arc(g, u1, max(lo, u1 - du), min(hi, u1 + du), kinks, maxit, m, r, ca,
                          sa, phi0, pc, ps, phi_lo, phi_hi)
    if h2 > -np.inf:
        ub, hb = _refine_on_arc(g, u2, max(lo, u2 - du), min(hi, u2 + du), kinks, maxit, m, r,
                                ca, sa, phi0, pc, ps, phi_lo, phi_hi)
        if hb > h:
            u = ub
            h = hb
    return u, h


@njit(**KERNEL)
def _h_value(cu, su, g, m, r, ca, sa, phi0, pc, ps, phi_lo, phi_hi):
    """h at the plane with (cos u, sin u) = (cu, su) on the arc of sign g (no derivatives)."""
    phi = min(max(phi0 + pc * (ca * cu - sa * su) + ps * (sa * cu + ca * su), phi_lo), phi_hi)
    return -g * r * su + np.tan(phi) * (m + r * cu)


@njit(**KERNEL)
def _end_value(u, m, r, ca, sa, phi0, pc, ps, phi_lo, phi_hi):
    """h at an arc's end u = 0 (the plane of σ1 = m + R) or u = ±π (σ2 = m - R), τ = 0."""
    sgn = 1.0 if u == 0.0 else -1.0
    return np.tan(min(max(phi0 + sgn * (pc * ca + ps * sa), phi_lo), phi_hi)) * (m + sgn * r)


@njit(**KERNEL)
def _refine_on_arc(g, u, lo, hi, kinks, maxit, m, r, ca, sa, phi0, pc, ps, phi_lo, phi_hi):
    """(u, h): the maximum of h in [lo, hi] from u: Newton on ∂h/∂u = 0, safeguarded by
    bisection on the sign of ∂h/∂u (a Newton step below PLANE_LAST_STEP is the last; at most
    ``maxit`` steps). Where φ(θ) reaches a clamp (``kinks``), h = |τ| + tan(clamp(φ_raw)) σn
    has a kink at the boundary and the maximum can sit on it (a corner, ∂h/∂u jumping from
    + to -): a step that crosses a boundary stops there if it is a corner maximum
    (:func:`_corner_on_arc`).

    h is the value at the returned u: evaluated there, or — after a last step δ taken
    without another evaluation, where h is smooth (no ``kinks``) — h + h_u δ + ½ h_uu δ²
    from the step's start, exact to |h_uuu| δ³/6 (δ < PLANE_LAST_STEP: below round-off;
    after ``maxit`` steps short of convergence the same second-order estimate)."""
    h = 0.0
    hu = 0.0
    huu = 0.0
    delta = 0.0
    for _ in range(maxit):
        h, hu, huu = _h_on_arc(u, g, m, r, ca, sa, phi0, pc, ps, phi_lo, phi_hi)
        if huu < 0.0 and abs(hu) < PLANE_TOL * -huu:   # the Newton step is below tolerance
            return u, h
        if hu > 0.0:
            lo = u
        elif hu < 0.0:
            hi = u
        else:
            return u, h
        un = u - hu / huu if huu < 0.0 else 0.5 * (lo + hi)
        newton = huu < 0.0 and lo < un < hi
        if not newton:
            un = 0.5 * (lo + hi)
        if kinks:
            cu = np.cos(u)
            su = np.sin(u)
            d, slope, bound, side = _kink(ca * cu - sa * su, sa * cu + ca * su, phi0, pc, ps,
                                          phi_lo, phi_hi)
            if d * (un - u) > 0.0 and abs(d) < abs(un - u) \
                    and _corner_on_arc(u + d, g, m, r, ca, sa, slope, bound, side):
                return u + d, _h_on_arc(u + d, g, m, r, ca, sa, phi0, pc, ps, phi_lo, phi_hi)[0]
        delta = un - u
        u = un
        if abs(delta) < PLANE_TOL or (newton and abs(delta) < PLANE_LAST_STEP):
            break
    if kinks:    # the last step may have crossed a kink of h: no Taylor estimate across it
        return u, _h_on_arc(u, g, m, r, ca, sa, phi0, pc, ps, phi_lo, phi_hi)[0]
    return u, h + (hu + 0.5 * huu * delta) * delta


@njit(**KERNEL)
def _slip_angle(sq, cq, sp, cp):
    """(sin ψ̂, cos ψ̂) and their ψ- and φ-partials from (sin ψ, cos ψ, sin φ, cos φ) (module
    doc): ψ̂ = atan2(num, den), num = sin ψ cos φ, den = 1 - sin ψ sin φ, ρ = hypot(num, den);
    along any (d num, d den), d(sin ψ̂) = (d num - sin ψ̂ dρ)/ρ, d(cos ψ̂) = (d den - cos ψ̂ dρ)/ρ,
    dρ = sin ψ̂ d num + cos ψ̂ d den. Returns (sh, ch, sh_ψ, ch_ψ, sh_φ, ch_φ)."""
    num = sq * cp
    den = 1.0 - sq * sp
    inv = 1.0 / hypot(num, den)
    sh = num * inv
    ch = den * inv
    n_q = cq * cp          # ∂(num, den)/∂ψ
    d_q = -cq * sp
    n_f = -sq * sp         # ∂(num, den)/∂φ
    d_f = -sq * cp
    r_q = sh * n_q + ch * d_q
    r_f = sh * n_f + ch * d_f
    return (sh, ch, (n_q - sh * r_q) * inv, (d_q - ch * r_q) * inv, (n_f - sh * r_f) * inv,
            (d_f - ch * r_f) * inv)


@njit(**KERNEL)
def _branch_slopes(g, sn, m, tau, t, sec2, p_t, p_tt):
    """(∂tan φ/∂θ, h_θ, h_θθ) of h = g τ + tan φ σn on one smooth branch φ(θ) with
    tan φ = ``t``, sec²φ = ``sec2``, φ_θ = ``p_t``, φ_θθ = ``p_tt`` (σn_θ = 2τ,
    τ_θ = -2(σn - m))."""
    t_t = sec2 * p_t
    t_tt = 2.0 * t * sec2 * p_t * p_t + sec2 * p_tt
    h_t = -2.0 * g * (sn - m) + t_t * sn + 2.0 * t * tau
    h_tt = -4.0 * g * tau + t_tt * sn + 4.0 * t_t * tau - 4.0 * t * (sn - m)
    return t_t, h_t, h_tt


@njit(**KERNEL, inline="always")
def plane_terms(cu, su, c2, s2, g, m, r, ca, sa, fab, pl, k):
    """Every term of the arc-g maximum near the plane u, written to row k of ``pl`` (layout
    PL_*); the plane is given by (cos u, sin u) = (``cu``, ``su``) (u = 2(θ - α) on arc g:
    :func:`arc_point`) and (cos 2θ, sin 2θ) = (``c2``, ``s2``), the stress by m, R and
    (cos 2α, sin 2α) = (``ca``, ``sa``).

    ``fab`` = (φ0, pc, ps, ψ0, qc, qs, ρ, ·, φ_min, φ_max) (:func:`fabric_terms`). u need
    not be the exact maximizer: with the plane's Newton step δθ = -h_θ/h_θθ (stored as
    PL_DT, limited to the arc) the values are those of the predicted maximum to second
    order — h + ½ h_θ δθ, N + N_θ δθ, ∂h/∂σ + h_θσ δθ — so an outer Newton iteration that
    also moves the plane by δθ + θ_σ dσ + θ_p dp solves the plane's optimality jointly
    (static condensation). At the exact maximizer δθ = 0 and every term is exact.

    Where φ(θ) reaches a clamp the maximum can be a corner of h at the boundary φ_raw = φ_b
    (:func:`_corner_on_arc`); there δθ is the step to the boundary, θ_σ = 0,
    θ_p = -∂φ_raw/∂p / φ_raw_θ, the values are h + h_θ δθ, N + N_θ δθ, ∂h/∂σ + h_θσ δθ and
    ∂h/∂p includes h_θ θ_p (no envelope theorem at a corner). Where the step leaves the arc
    (or h is not concave at u and rises toward an end) the plane goes to that end and turns
    with the principal axis there (θ_σ = ∂α/∂σ, θ_p = 0, values to first order, ∂h/∂σ
    including h_θ θ_σ).
    """
    phi0, pc, ps, psi0, qc, qs = fab[0], fab[1], fab[2], fab[3], fab[4], fab[5]
    sn = m + r * cu
    tau = -r * su
    # Voigt gradients of σn and τ, and their θ-derivatives (e = (½, ½, 0)).
    sn_s0 = 0.5 * (1.0 + c2)
    sn_s1 = 0.5 * (1.0 - c2)
    sn_s2 = s2
    ta_s0 = -0.5 * s2
    ta_s1 = 0.5 * s2
    ta_s2 = c2
    # Friction: φ_θ = 2 φ_u, φ_θθ = 4 φ_uu; basis of its coefficients (1, c2, s2).
    phr = phi0 + pc * c2 + ps * s2
    phr_t = 2.0 * (-pc * s2 + ps * c2)
    phr_tt = -4.0 * (pc * c2 + ps * s2)
    phi, p_t, p_tt, phi_free = _clamped(phr, phr_t, phr_tt, fab[8], fab[9])
    # tan φ and sec²φ from one sincos (|φ| < π/2, cos φ > 0), which the slip angle needs too:
    # in place of tan, a square root and a division (latencies measured here: sincos 15 ns,
    # tan 18, sqrt 5.5, division 4; the update's time moved within noise).
    sp = np.sin(phi)
    cp = np.cos(phi)
    t = sp / cp
    sec2 = 1.0 / (cp * cp)
    t_t, h_t, h_tt = _branch_slopes(g, sn, m, tau, t, sec2, p_t, p_tt)
    h = g * tau + t * sn
    # h_θσ = -2g(∂σn/∂σ - e) + T_θ ∂σn/∂σ + 2T ∂τ/∂σ
    hts0 = -2.0 * g * (sn_s0 - 0.5) + t_t * sn_s0 + 2.0 * t * ta_s0
    hts1 = -2.0 * g * (sn_s1 - 0.5) + t_t * sn_s1 + 2.0 * t * ta_s1
    hts2 = -2.0 * g * sn_s2 + t_t * sn_s2 + 2.0 * t * ta_s2
    lo = 0.0 if g < 0.0 else -np.pi
    corner = False
    kink_t = 0.0
    dk = 0.0
    if has_kinks(phi0, fab[6], fab[8], fab[9]):
        # Local model: the two smooth branches of h (φ clamped, φ free) as quadratics at θ,
        # meeting at the nearest clamp boundary θ + δk. Its maximum is that corner when the
        # clamped branch still rises toward the free side there and the free one falls.
        d, kink_t, bound, side = _kink(c2, s2, phi0, pc, ps, fab[8], fab[9])
        dk = 0.5 * d
        if lo <= arc_angle(cu, su, g) + d <= lo + np.pi:
            # the other branch's slopes (φ = φ_b if free here, φ_raw if clamped)
            o_phi = bound if phi_free else phr
            o_tan = np.tan(o_phi)
            _, o_t, o_tt = _branch_slopes(g, sn, m, tau, o_tan, 1.0 + o_tan * o_tan,
                                          0.0 if phi_free else phr_t,
                                          0.0 if phi_free else phr_tt)
            if phi_free:
                free_t = h_t + h_tt * dk
                clamped_t = o_t + o_tt * dk
            else:
                free_t = o_t + o_tt * dk
                clamped_t = h_t + h_tt * dk
            corner = clamped_t * side > 0.0 and free_t * side < 0.0
    # What the plane's step leads to: an interior maximum (θ_σ = -h_θσ/h_θθ, the envelope
    # theorem), a corner (above), or the arc's end, where the step leaves the arc (a
    # non-concave point ascends to it): there τ = 0, the plane is the principal plane
    # θ = α or α + π/2 and turns with it, θ_σ = ∂α/∂σ = (-sin 2α, sin 2α, 2 cos 2α)/(4R),
    # θ_p = 0, and ∂h/∂σ includes h_θ θ_σ.
    end = False
    if corner:
        # A corner maximum: the plane is pinned to the boundary φ_raw(θ) = φ_b, which moves
        # with p alone (θ_p = -∂φ_raw/∂p / φ_raw_θ, θ_σ = 0); its value follows h to first
        # order, h + h_θ δk, and its p-derivative includes the motion, ∂h/∂p + h_θ θ_p.
        inv = 0.0
        dt = dk
    else:
        if h_tt < -1e-12 * (abs(m) + r):     # an interior maximum, resolvable against |σ|
            inv = -1.0 / h_tt
            step = inv * h_t
        else:
            inv = 0.0
            step = np.pi if h_t > 0.0 else (-np.pi if h_t < 0.0 else 0.0)
        # The plane's step, kept inside the arc (u + 2δθ in [0, π] or [-π, 0]). A step with
        # |2δθ| <= |sin u| stays inside without u: |sin u| is the sine of the distance to the
        # arc's nearer end, and no more than that distance.
        if abs(2.0 * step) <= abs(su):
            dt = step
        else:
            u = arc_angle(cu, su, g)
            dt = min(max(step, 0.5 * (lo - u)), 0.5 * (lo + np.pi - u))
        end = dt != step and r > 0.0
    if end:
        inv = 0.0
        ts0 = -0.25 * sa / r
        ts1 = 0.25 * sa / r
        ts2 = 0.5 * ca / r
    else:
        ts0 = inv * hts0
        ts1 = inv * hts1
        ts2 = inv * hts2
    pl[k, PL_H] = h + (h_t if corner or end else 0.5 * h_t) * dt
    pl[k, PL_DT] = dt
    pl[k, PL_HS] = g * ta_s0 + t * sn_s0 + hts0 * dt + (h_t * ts0 if end else 0.0)
    pl[k, PL_HS + 1] = g * ta_s1 + t * sn_s1 + hts1 * dt + (h_t * ts1 if end else 0.0)
    pl[k, PL_HS + 2] = g * ta_s2 + t * sn_s2 + hts2 * dt + (h_t * ts2 if end else 0.0)
    # ∂θ/∂σ (0 at a corner, or where R ~ 1e-12 |σ| leaves the plane undetermined).
    pl[k, PL_TS] = ts0
    pl[k, PL_TS + 1] = ts1
    pl[k, PL_TS + 2] = ts2
    # Dilatancy, clamped to [-φ, φ] (then it follows φ).
    psi = psi0 + qc * c2 + qs * s2
    q_t = 2.0 * (-qc * s2 + qs * c2)
    clamp = 0.0
    if psi > phi:
        psi = phi
        q_t = p_t
        clamp = 1.0
    elif psi < -phi:
        psi = -phi
        q_t = -p_t
        clamp = -1.0
    sq = np.sin(psi)
    cq = np.cos(psi)
    # (sin ψ̂, cos ψ̂) are functions of (ψ, φ): their derivatives along any direction
    # (dψ, dφ) combine the two partials.
    sh, ch, sh_q, ch_q, sh_f, ch_f = _slip_angle(sq, cq, sp, cp)
    sh_t = sh_q * q_t + sh_f * p_t
    ch_t = ch_q * q_t + ch_f * p_t
    # N_θ: ∂(∂τ/∂σ)/∂θ = (-c2, c2, -2 s2), ∂(∂σn/∂σ)/∂θ = (-s2, s2, 2 c2).
    nt0 = g * ch_t * ta_s0 - g * ch * c2 + sh_t * sn_s0 - sh * s2
    nt1 = g * ch_t * ta_s1 + g * ch * c2 + sh_t * sn_s1 + sh * s2
    nt2 = g * ch_t * ta_s2 - 2.0 * g * ch * s2 + sh_t * sn_s2 + 2.0 * sh * c2
    pl[k, PL_N] = g * ch * ta_s0 + sh * sn_s0 + nt0 * dt
    pl[k, PL_N + 1] = g * ch * ta_s1 + sh * sn_s1 + nt1 * dt
    pl[k, PL_N + 2] = g * ch * ta_s2 + sh * sn_s2 + nt2 * dt
    pl[k, PL_NT] = nt0
    pl[k, PL_NT + 1] = nt1
    pl[k, PL_NT + 2] = nt2
    pl[k, PL_SH] = sh + sh_t * dt
    pl[k, PL_SHT] = sh_t
    # Derivatives in p at fixed θ: φ = φ0 + pc c2 + ps s2 (if not clamped), ψ likewise, linear
    # in the basis b = (1, c2, s2) of either's coefficients (b_θ = (0, -2 s2, 2 c2)). Per unit
    # dφ (0 where φ is clamped) ψ̂ moves with φ and, where ψ is clamped to ±φ, with ψ = ±φ; per
    # unit dψ only where ψ is free.
    free = 1.0 if phi_free else 0.0
    sh_pf = free * (sh_f + clamp * sh_q)
    ch_pf = free * (ch_f + clamp * ch_q)
    sh_pq = sh_q if clamp == 0.0 else 0.0
    ch_pq = ch_q if clamp == 0.0 else 0.0
    nf0 = g * ch_pf * ta_s0 + sh_pf * sn_s0
    nf1 = g * ch_pf * ta_s1 + sh_pf * sn_s1
    nf2 = g * ch_pf * ta_s2 + sh_pf * sn_s2
    nq0 = g * ch_pq * ta_s0 + sh_pq * sn_s0
    nq1 = g * ch_pq * ta_s1 + sh_pq * sn_s1
    nq2 = g * ch_pq * ta_s2 + sh_pq * sn_s2
    # h_θ per unit dφ: (2 tan φ sec²φ φ_θ σn + 2 sec²φ τ) b + sec²φ σn b_θ.
    ht_b = free * 2.0 * sec2 * (t * p_t * sn + tau)
    ht_bt = free * sec2 * sn
    for j in range(3):
        b = 1.0 if j == 0 else (c2 if j == 1 else s2)
        b_t = 0.0 if j == 0 else (-2.0 * s2 if j == 1 else 2.0 * c2)
        ht_p = ht_b * b + ht_bt * b_t
        if corner:
            tp = -b / kink_t
            pl[k, PL_HP + j] = free * sec2 * b * sn + ht_p * dt + h_t * tp
            pl[k, PL_TP + j] = tp
        else:
            pl[k, PL_HP + j] = free * sec2 * b * sn + ht_p * dt
            pl[k, PL_TP + j] = inv * ht_p
        pl[k, PL_NP + j] = nf0 * b
        pl[k, PL_NP + N_P + j] = nf1 * b
        pl[k, PL_NP + 2 * N_P + j] = nf2 * b
        pl[k, PL_NP + 3 + j] = nq0 * b
        pl[k, PL_NP + N_P + 3 + j] = nq1 * b
        pl[k, PL_NP + 2 * N_P + 3 + j] = nq2 * b
        pl[k, PL_SHP + j] = sh_pf * b
        pl[k, PL_SHP + 3 + j] = sh_pq * b


@njit(**KERNEL)
def fabric_terms_jacobian(prm, out):
    """``out`` (6, 4) ← ∂p/∂(c, A, Bc, Bs) of :func:`fabric_terms` (constant: p is affine)."""
    out[:, :] = 0.0
    out[0, 0] = prm[DPHI_DC]
    out[3, 0] = prm[DPSI_DC]
    out[0, 1] = prm[A1]
    out[3, 1] = prm[B1]
    for row, amp, ang in ((1, prm[A2], prm[A3]), (4, prm[B2], prm[B3])):
        out[row, 2] = amp * np.cos(ang)          # pc = amp (Bc cos a + Bs sin a)
        out[row, 3] = amp * np.sin(ang)
        out[row + 1, 2] = -amp * np.sin(ang)     # ps = amp (Bs cos a - Bc sin a)
        out[row + 1, 3] = amp * np.cos(ang)


@njit(**KERNEL)
def fabric_terms(c, a, bc, bs, prm, dpz):
    """The per-state constants ``fab`` = (φ0, pc, ps, ψ0, qc, qs, ρ, ψ', φ_min, φ_max) of
    :func:`plane_terms`, ρ = hypot(pc, ps) the amplitude of φ's anisotropy (:func:`has_kinks`)
    and ψ' unused here (layout of ``prm``: fabric_model).

    (Bc', Bs') = fabric rotated by -a3/2 gives a2 B cos(2(θ-θp) + a3) = pc cos 2θ + ps sin 2θ.
    p is affine in (c, A, Bc, Bs) with the constant Jacobian ``dpz`` of
    :func:`fabric_terms_jacobian` (which holds the trigonometry of a3, b3, done once).
    """
    dc = c - prm[C_STAR]
    phi0 = prm[A0] + dpz[0, 0] * dc + dpz[0, 1] * a
    psi0 = prm[B0] + dpz[3, 0] * dc + dpz[3, 1] * a
    pc = dpz[1, 2] * bc + dpz[1, 3] * bs
    ps = dpz[2, 2] * bc + dpz[2, 3] * bs
    qc = dpz[4, 2] * bc + dpz[4, 3] * bs
    qs = dpz[5, 2] * bc + dpz[5, 3] * bs
    return phi0, pc, ps, psi0, qc, qs, hypot(pc, ps), prm[DPSI_DC], prm[PHI_MIN], prm[PHI_MAX]


@njit(**KERNEL)
def stress_frame(sxx, syy, sxy):
    """(m, R, cos 2α, sin 2α): mean stress, deviator radius, major principal direction."""
    m = 0.5 * (sxx + syy)
    d = 0.5 * (sxx - syy)
    r = hypot(d, sxy)
    if r > 0.0:
        return m, r, d / r, sxy / r
    return m, r, 1.0, 0.0


@njit(**KERNEL)
def arc_u(theta, g, two_alpha):
    """u = 2(θ - α) of plane θ, wrapped to (-π, π] and moved to the nearest end of arc g.

    The wrap is one floor, not a loop: a loop of ±2π steps never ends for a plane angle of
    1e300 (an uninitialized warm start hung the tier-2 update that way). Where the floor's
    rounding leaves the period (|u| ~ 1e20, where the fused u - 2πk keeps what separate
    roundings cancelled) the exact remainder finishes the wrap."""
    u = 2.0 * theta - two_alpha
    u -= 2.0 * np.pi * np.floor((u + np.pi) / (2.0 * np.pi))
    if not -np.pi <= u <= np.pi:
        u = np.remainder(u + np.pi, 2.0 * np.pi) - np.pi
    if u == -np.pi:
        u = np.pi
    if g < 0.0 and u < 0.0:
        return 0.0 if u > -0.5 * np.pi else np.pi
    if g > 0.0 and u > 0.0:
        return 0.0 if u < 0.5 * np.pi else -np.pi
    return u


@njit(**KERNEL, inline="always")
def arc_point(theta, g, ca, sa):
    """(cos u, sin u, cos 2θ, sin 2θ) of plane θ, u = 2(θ - α), moved to the nearest end of
    arc g as :func:`arc_u` does, from (cos 2α, sin 2α) = (``ca``, ``sa``) alone: no angle α
    (an atan2, ~25 ns, per evaluation of :func:`yield_and_flow`)."""
    c2 = np.cos(2.0 * theta)
    s2 = np.sin(2.0 * theta)
    cu = c2 * ca + s2 * sa
    su = s2 * ca - c2 * sa
    if g * su > 0.0:       # the other arc's side: its nearer end of arc g (u = 0 or ±π)
        e = 1.0 if cu > 0.0 else -1.0
        return e, 0.0, e * ca, e * sa
    return cu, su, c2, s2


@njit(**KERNEL, inline="always")
def arc_angle(cu, su, g):
    """u of the plane (cos u, sin u) on arc g: in [0, π] for g < 0, [-π, 0] for g > 0."""
    u = np.arctan2(su, cu)
    if g < 0.0 and u < 0.0:
        return np.pi
    if g > 0.0 and u > 0.0:
        return -np.pi
    return u


@njit(**KERNEL)
def arc_maxima(m, r, ca, sa, two_alpha, fab, n_search, maxit, theta, single):
    """(h0, h1): the maximum values of both arcs (:func:`arc_maximum`, refinements of at most
    ``maxit`` steps) of the stress (m, R, 2α); ``theta`` (2,) in/out: the planes (warm
    starts in, maximizers out).

    Where h provably has a single maximum on each arc (``single``: the caller's
    :func:`single_maximum`, with ``n_search`` > 0) the grid of ``n_search`` points is not
    needed: each refinement starts inside its whole arc from u* = atan2(-g, tan φ0), the
    maximum of h's θ-independent part (for φ independent of θ the maximum itself;
    = -g(π/2 - φ0) where |φ0| < π/2).
    """
    phi0 = fab[0]
    if not single:
        u_star = 0.0
    elif abs(phi0) < 0.5 * np.pi:
        u_star = 0.5 * np.pi - phi0
    else:
        u_star = np.arctan2(1.0, np.tan(phi0))
    h0 = 0.0
    h1 = 0.0
    for k in range(2):
        g = -1.0 if k == 0 else 1.0
        start = -g * u_star if single else arc_u(theta[k], g, two_alpha)
        u, h = arc_maximum(g, start, 0 if single else n_search, maxit, m, r, ca, sa, fab)
        theta[k] = 0.5 * (two_alpha + u)
        if k == 0:
            h0 = h
        else:
            h1 = h
    return h0, h1


@njit(**KERNEL)
def yield_value(sxx, syy, sxy, fab, beta, n_search, theta):
    """f(σ) alone (the elastic check), searching both arcs (:func:`arc_maxima`).

    ``theta`` (2,) in/out: the planes of the arc maxima (warm starts in, maximizers out).
    """
    m, r, ca, sa = stress_frame(sxx, syy, sxy)
    single = n_search > 0 and single_maximum(m, r, fab[0], fab[1], fab[2], fab[8], fab[9])
    hk0, hk1 = arc_maxima(m, r, ca, sa, np.arctan2(sa, ca), fab, n_search, NEWTON_MAXIT_PLANE,
                          theta, single)
    return softmax_mean(hk0, hk1, beta, hypot(m, r))


@njit(**KERNEL, inline="always")
def softmax_mean(h0, h1, beta, s):
    """f = w0 h0 + w1 h1, w = softmax(β h_k / s) (module doc; w = (½, ½) at s = 0)."""
    w0 = 0.5 if s == 0.0 else 1.0 / (1.0 + np.exp(beta * (h1 - h0) / s))
    return w0 * h0 + (1.0 - w0) * h1


@njit(**KERNEL, inline="always")
def yield_and_flow(sxx, syy, sxy, fab, beta, search, n_search, theta, pl, yf):
    """f, N, tr N and their σ- and c-derivatives into ``yf`` (layout YF_*; module doc).

    ``theta`` (2,): the planes of the two arcs. With ``search`` each arc's maximum is found
    first (grid of ``n_search`` points, or from ``theta`` if 0) and ``theta`` updated;
    without, the terms are the one-step predictions of :func:`plane_terms` at ``theta``
    (the caller moves the planes). ``pl`` (2, N_PL) scratch. Blocks are row-major:
    yf[YF_NS + 3 i + j] = ∂N_i/∂σ_j, yf[YF_NP + 6 i + j] = ∂N_i/∂p_j.
    """
    m, r, ca, sa = stress_frame(sxx, syy, sxy)
    two_alpha = np.arctan2(sa, ca) if search else 0.0
    for k in range(2):
        g = -1.0 if k == 0 else 1.0
        if search:
            u = arc_u(theta[k], g, two_alpha)
            u, _ = arc_maximum(g, u, n_search, NEWTON_MAXIT_PLANE, m, r, ca, sa, fab)
            theta[k] = 0.5 * (two_alpha + u)
            cu = np.cos(u)
            su = np.sin(u)
            c2 = ca * cu - sa * su
            s2 = sa * cu + ca * su
        else:
            cu, su, c2, s2 = arc_point(theta[k], g, ca, sa)
        plane_terms(cu, su, c2, s2, g, m, r, ca, sa, fab, pl, k)
    h0 = pl[0, PL_H]
    h1 = pl[1, PL_H]
    s = hypot(m, r)
    # Softmax of z_k = β h_k / s over two arcs: w0 = 1/(1 + exp(z1 - z0)), dw0 = w0 w1 d(z0 - z1).
    if s > 0.0:
        w0 = 1.0 / (1.0 + np.exp(beta * (h1 - h0) / s))
        s_s = (sxx / (2.0 * s), syy / (2.0 * s), sxy / s)
        k_w = w0 * (1.0 - w0) * beta / s
    else:
        w0 = 0.5
        s_s = (0.0, 0.0, 0.0)
        k_w = 0.0
    w1 = 1.0 - w0
    dh = h0 - h1
    dsh = pl[0, PL_SH] - pl[1, PL_SH]
    yf[YF_F] = w0 * h0 + w1 * h1
    yf[YF_TR] = w0 * pl[0, PL_SH] + w1 * pl[1, PL_SH]
    for i in range(3):
        yf[YF_N + i] = w0 * pl[0, PL_N + i] + w1 * pl[1, PL_N + i]
    for j in range(3):
        dw = k_w * (pl[0, PL_HS + j] - pl[1, PL_HS + j] - dh * s_s[j] / s) if s > 0.0 else 0.0
        yf[YF_FS + j] = w0 * pl[0, PL_HS + j] + w1 * pl[1, PL_HS + j] + dh * dw
        yf[YF_TRS + j] = (dsh * dw + w0 * pl[0, PL_SHT] * pl[0, PL_TS + j]
                          + w1 * pl[1, PL_SHT] * pl[1, PL_TS + j])
        for i in range(3):
            yf[YF_NS + 3 * i + j] = ((pl[0, PL_N + i] - pl[1, PL_N + i]) * dw
                                     + w0 * pl[0, PL_NT + i] * pl[0, PL_TS + j]
                                     + w1 * pl[1, PL_NT + i] * pl[1, PL_TS + j])
    for j in range(N_P):
        if j < 3:    # the φ coefficients move h (the weights) and the planes
            dw = k_w * (pl[0, PL_HP + j] - pl[1, PL_HP + j])
            yf[YF_FP + j] = w0 * pl[0, PL_HP + j] + w1 * pl[1, PL_HP + j] + dh * dw
            tp0 = pl[0, PL_TP + j]
            tp1 = pl[1, PL_TP + j]
        else:
            dw = 0.0
            tp0 = 0.0
            tp1 = 0.0
        yf[YF_TRP + j] = (dsh * dw + w0 * (pl[0, PL_SHT] * tp0 + pl[0, PL_SHP + j])
                          + w1 * (pl[1, PL_SHT] * tp1 + pl[1, PL_SHP + j]))
        for i in range(3):
            yf[YF_NP + N_P * i + j] = (
                (pl[0, PL_N + i] - pl[1, PL_N + i]) * dw
                + w0 * (pl[0, PL_NT + i] * tp0 + pl[0, PL_NP + N_P * i + j])
                + w1 * (pl[1, PL_NT + i] * tp1 + pl[1, PL_NP + N_P * i + j]))

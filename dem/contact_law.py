"""The disc–disc contact law: linear spring–dashpot normal force, spring–Coulomb slider
tangential force, optional rolling resistance.

Geometry of a contact between discs i and j (radii ri, rj; branch vector l = xj - xi,
unit normal n = l/|l| from i to j, tangent t = (-ny, nx)): overlap δ = ri + rj - |l| > 0.
The contact point sits in the middle of the overlap, at arm ℓi = ri - δ/2 from i and
ℓj = rj - δ/2 from j (so ℓi + ℓj = |l| and a rigid rotation of the pair gives no
relative tangential motion). With u the full velocity of a centre and ω the spin, the
relative velocity of the contact points is

    w = uj - ui - (ωi ℓi + ωj ℓj) t,   vn = w·n (separating > 0),   vt = w·t.

Normal force (repulsive fn >= 0; no tension, the contact carries no cohesion):

    fn = max(0, kn δ - γ vn),   γ = 2 β sqrt(m_eff kn),   m_eff = mi mj / (mi + mj).

β follows from the restitution coefficient e by inverting the *exact* restitution of a
binary collision with this clamped law (:func:`restitution`); the familiar
e = exp(-βπ/sqrt(1-β²)) ignores the clamp (the force would turn attractive near the end
of the contact) and would miss e by up to a few tens of percent.

Tangential force (on i, along t): an elastic spring on the accumulated relative
tangential displacement ξ (ξ += vt dt), capped by Coulomb:

    ft = kt ξ,  |ft| <= μ fn;  on sliding ξ is truncated to ±μ fn / kt.

ξ is a scalar in the contact's own (n, t) frame, so it turns with the contact: the
incremental history stays consistent under any rotation of the pair (in 2D the frame
has one angle, and a scalar component along t is exactly the co-rotated history).
The frictional dissipation of a step is the mean spring force times the slip,
½ kt (ξ_old + ξ) (ξ_trial - ξ): with the stored energy ½ kt ξ² and the tangential work
½ kt (ξ_old + ξ) vt dt (trapezoidal, as the force enters the two half kicks) the books
then close exactly on the contact. μ = 0 (frictionless) and very large μ (no sliding) are both allowed.

Rolling resistance (off by default, μr = 0): a spring on the relative rotation
ξr += (ωj - ωi) dt with stiffness kr = kt r_eff² (r_eff = ri rj / (ri + rj)), moment
Mr = kr ξr on i (-Mr on j), capped at |Mr| <= μr r_eff fn.

Forces on i: f = -fn n + ft t, torque ℓi ft + Mr; on j: -f, torque ℓj ft - Mr.

Two styles (``ContactLaw.style``) differ in three terms:

* ``"spring-dashpot"`` (the default, everything above): the normal dashpot per pair,
  γ = 2 β sqrt(m_eff kn), so every binary collision has the restitution e; no tangential
  dashpot; arm ℓ = r - δ/2.
* ``"hooke/history"``, LAMMPS's ``pair_style gran/hooke/history`` with ``limit_damping``
  and its usual tangential dashpot: one normal damping rate γn for all pairs,
  γ = m_eff γn with γn = 2 β sqrt(kn / (m̄/2)) (:func:`hooke_gamma_n`, m̄ the sample's
  mean disc mass: a pair of mean mass has the ratio β, lighter pairs less, heavier more);
  a tangential dashpot γt = m_eff γn / 2; arm ℓ = r. The tangential force is spring plus
  dashpot, capped by Coulomb as a whole, and on sliding the spring is set so that the
  sum sits on the cap (LAMMPS's rescaling of the shear history):

      ft* = kt ξ* + γt vt,   ft = ft* if |ft*| <= μ fn,  else ft = ±μ fn, ξ = (ft - γt vt)/kt.

  LAMMPS keeps ξ as a vector in the lab frame and projects it on the new tangent each
  step; the scalar ξ here turns with the contact. In 2D the two differ by the factor
  cos Δθ per step (Δθ the contact's rotation in the step), second order in Δθ; at the
  first step of a contact they are equal.

Dissipation of the tangential force with a dashpot: with ft = kt ξ + fdt (fdt = γt vt
the dashpot's force, ξ after the slip) its trapezoidal work ½ (ft_old + ft) vt dt less the
change of ½ kt ξ² is the slip term ½ kt (ξ_old + ξ)(ξ_trial - ξ) plus ½ (fdt_old + fdt)
vt dt. A step in which the contact slides books the sum as friction, a sticking step (no
slip term) as damping. (Split term by term, friction would turn negative where the
dashpot alone exceeds the cap, |γt vt| > μ fn, and the spring is set against it.)
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cached_property

from numba import njit
from scipy.optimize import brentq


class ContactLawError(ValueError):
    """A contact-law parameter out of range; the message names the value and the range."""


def restitution(beta: float) -> float:
    """Restitution of a binary collision under the clamped law, damping ratio β >= 0.

    With ω0 = sqrt(kn/m_eff) the overlap obeys δ'' = -ω0² δ - 2βω0 δ' from δ = 0,
    δ' = v0 until the force kn δ + γ δ' (γ = 2βω0 m_eff) first vanishes; then the discs
    separate freely. For β < 1 (ωd = ω0 sqrt(1-β²), s = sqrt(1-β²)) the force vanishes at
    ωd t = φ = π - atan2(2βs, 1 - 2β²), and e = -δ'/v0 = -exp(-βφ/s)(cos φ - (β/s) sin φ).
    For β > 1 (q = sqrt(β²-1)) the same with tanh x = 2βq/(2β²-1), e = -exp(-βx/q)(cosh x
    - (β/q) sinh x). e decreases monotonically from 1 (β = 0) to 0 (β -> ∞).
    """
    if beta <= 0.0:
        return 1.0
    if abs(beta - 1.0) < 1e-9:
        beta = 1.0 - 1e-9
    if beta < 1.0:
        s = math.sqrt(1.0 - beta * beta)
        phi = math.pi - math.atan2(2.0 * beta * s, 1.0 - 2.0 * beta * beta)
        return -math.exp(-beta * phi / s) * (math.cos(phi) - beta / s * math.sin(phi))
    q = math.sqrt(beta * beta - 1.0)
    # x = atanh(r), r = 2βq/(2β²-1), with 1 - r = 1/((β+q)²(2β²-1)) formed without cancellation
    one_minus_r = 1.0 / ((beta + q) ** 2 * (2.0 * beta * beta - 1.0))
    x = 0.5 * math.log((2.0 - one_minus_r) / one_minus_r)
    return -math.exp(-beta * x / q) * (math.cosh(x) - beta / q * math.sinh(x))


def damping_ratio(e: float) -> float:
    """The damping ratio β for which :func:`restitution` gives ``e`` (e in (0, 1])."""
    if not (0.0 < e <= 1.0):
        raise ContactLawError(f"restitution coefficient e = {e} out of range; accepted (0, 1]")
    if e == 1.0:
        return 0.0
    return brentq(lambda b: restitution(b) - e, 0.0, 1e7, xtol=1e-15, rtol=1e-14)


STYLES = ("spring-dashpot", "hooke/history")
"""The contact-law styles (module doc); the first is the default."""


def hooke_gamma_n(kn: float, beta: float, mean_mass: float) -> float:
    """γn (1/time) of the ``hooke/history`` style: 2β sqrt(kn / (m̄/2)), the damping ratio β
    for a pair of mean mass m̄."""
    return 2.0 * beta * math.sqrt(kn / (0.5 * mean_mass))


@dataclass(frozen=True)
class ContactLaw:
    """Contact parameters (units: d = 1, ρ = 1, P0 = 1, so kn = κ in 2D).

    kn: normal stiffness (force per length of overlap), kt = kt_ratio · kn; e: restitution
    of a binary collision (of a pair of mean mass in the ``hooke/history`` style); mu:
    Coulomb friction; mu_roll: rolling-resistance coefficient; style: one of
    :data:`STYLES` (module doc).
    """

    kn: float
    kt_ratio: float = 0.5
    e: float = 0.5
    mu: float = 0.5
    mu_roll: float = 0.0
    style: str = STYLES[0]

    def __post_init__(self):
        if self.style not in STYLES:
            raise ContactLawError(f"contact law: style = {self.style!r} unknown; accepted "
                                  f"{', '.join(STYLES)}")
        checks = [("kn", self.kn, self.kn > 0, "(0, inf)"),
                  ("kt_ratio", self.kt_ratio, self.kt_ratio > 0, "(0, inf)"),
                  ("e", self.e, 0.0 < self.e <= 1.0, "(0, 1]"),
                  ("mu", self.mu, self.mu >= 0, "[0, inf)"),
                  ("mu_roll", self.mu_roll, self.mu_roll >= 0, "[0, inf)")]
        for name, v, ok, rng in checks:
            if not (isinstance(v, (int, float)) and math.isfinite(v) and ok) and not (
                    name == "mu" and v == math.inf):
                raise ContactLawError(f"contact law: {name} = {v} out of range; accepted {rng}")

    @property
    def kt(self) -> float:
        return self.kt_ratio * self.kn

    @cached_property
    def beta(self) -> float:
        return damping_ratio(self.e)

    def with_friction(self, mu: float) -> "ContactLaw":
        return replace(self, mu=mu)

    @property
    def arm_offset(self) -> float:
        """a of the contact arm ℓ = r - a δ: ½ (``spring-dashpot``) or 0 (``hooke/history``)."""
        return 0.5 if self.style == "spring-dashpot" else 0.0

    @property
    def tangential_damping(self) -> float:
        """γt / γ of every pair: 0 (``spring-dashpot``) or ½ (``hooke/history``)."""
        return 0.0 if self.style == "spring-dashpot" else 0.5

    def gamma_n(self, mean_mass: float) -> float:
        """γn of :func:`hooke_gamma_n` for ``hooke/history``; 0 for ``spring-dashpot`` (γ per
        pair from β)."""
        if self.style == "spring-dashpot":
            return 0.0
        return hooke_gamma_n(self.kn, self.beta, mean_mass)

    def kernel_params(self):
        """(kn, kt, β, μ, μr): the scalars the force kernel reads."""
        return float(self.kn), float(self.kt), float(self.beta), float(self.mu), float(self.mu_roll)


@njit(cache=True)
def damping_coefficient(m_eff, kn, beta):
    """γ = 2 β sqrt(m_eff kn) of the normal dashpot."""
    return 2.0 * beta * math.sqrt(m_eff * kn)


@njit(cache=True)
def contact_response(delta, delta_old, fd_old, fdt_old, vn, vt, wrel, xi_t, xi_r, gamma,
                     gamma_t, r_eff, kn, kt, mu, mu_roll, dt):
    """One contact update: (fn, ft, Mr, ξt, ξr, fd, fdt, damping, friction, rolling
    dissipation).

    Inputs as in the module docstring (δ > 0 overlap, vn, vt relative contact velocities,
    wrel = ωj - ωi, ξ histories before the step, γ (:func:`damping_coefficient`, or
    m_eff γn), the tangential dashpot γt (0 without one) and r_eff of the pair, constant
    while it is listed); δ_old, fd_old = fn - kn δ and fdt_old = γt vt are the overlap and
    the normal and tangential damping forces of the previous step. Dissipations are the
    energies lost in this step, as the trapezoidal work of the non-elastic force parts,
    which is how velocity Verlet transmits work to the discs: damping ½ (fd_old + fd)(δ -
    δ_old), friction ½ kt (ξ_old + ξ)(ξ_trial - ξ) (mean spring force times slip), and the
    tangential dashpot's ½ (fdt_old + fdt) vt dt as damping in a sticking step, as friction
    in a sliding one (module doc).
    δ_old = 0 marks a contact that closed during this step: it carried no force at the
    start of the step, when the overlap was δ - vn dt <= 0 (the drift of the half-step
    velocities), so the discs did the work ½ fn (-vn dt) on it, of which ½ kn δ² is
    stored: damping ½ fn (-vn dt) - ½ kn δ². Counting from δ_old = 0 instead misses
    ½ fn |δ - vn dt|, first order in dt and large for a stiff dashpot (γ vn >> kn δ at
    the onset): up to 30 % of a collision's loss at e = 0.01 (tests/test_contact_law.py).
    """
    fel = kn * delta
    fn = fel - gamma * vn
    if fn < 0.0:
        fn = 0.0
    fd = fn - fel
    if delta_old == 0.0:
        # the contact closed during this step: it carried no force before, and the
        # discs moved from the (negative) overlap δ - vn dt at the start of the step
        d_damp = 0.5 * fn * (-vn * dt) - 0.5 * fel * delta
    else:
        d_damp = 0.5 * (fd_old + fd) * (delta - delta_old)
    xi = xi_t + vt * dt
    fdt = gamma_t * vt
    ft_trial = kt * xi + fdt
    lim = mu * fn
    # sliding as selects, not a branch: whether a contact slides is data dependent
    xi_slip = (math.copysign(lim, ft_trial) - fdt) / kt
    slides = abs(ft_trial) > lim
    d_dashpot = 0.5 * (fdt_old + fdt) * vt * dt
    d_fric = 0.5 * kt * (xi_t + xi_slip) * (xi - xi_slip) + d_dashpot if slides else 0.0
    d_damp += 0.0 if slides else d_dashpot
    xi = xi_slip if slides else xi
    ft = kt * xi + fdt
    mr = 0.0
    xr = 0.0
    d_roll = 0.0
    if mu_roll > 0.0:
        kr = kt * r_eff * r_eff
        xr = xi_r + wrel * dt
        lim_r = mu_roll * r_eff * fn
        if kr * abs(xr) > lim_r:
            xr_new = math.copysign(lim_r / kr, xr)
            d_roll = 0.5 * kr * (xi_r + xr_new) * (xr - xr_new)
            xr = xr_new
        mr = kr * xr
    return fn, ft, mr, xi, xr, fd, fdt, d_damp, d_fric, d_roll

"""The stress servo: the cell's strain rate on stress-controlled components of L.

Plant. Because the cell deforms affinely (every disc is remapped, :mod:`dem.periodic_cell`),
a strain rate L_ab changes the contact forces of the whole sample at once. To first
order the stress responds as

    dσ_ab/dt = M_ab L_ab + d(t),   M_ab = (1/V) Σ_contacts (kn n_a² + kt t_a²) l_b²   (a)

(no summation over a, b; tension positive, so stretching makes σ less compressive).
M_ab is the affine stiffness of the contact network, measured every step from the
contacts (≈ 0.2 z c kn for an isotropic packing, so it scales with κ = kn/P); d(t)
collects everything else: the prescribed components, the non-affine relaxation of the
packing, rearrangements.

Controller. With the error e = σ*_ab - σ_ab, a PI law written in strain-rate space,

    L_ab = L_int + (2/τ) e / M_ab,   dL_int/dt = e / (M_ab τ²),                       (b)

turns (a) into ë + (2/τ) ė + e/τ² = -ḋ + σ̈*: a critically damped loop (ζ = 1, double
pole at -1/τ), which does not ring, and whose integral term carries the strain rate
that a steady drift of the stress needs, so a constant ḋ (a stress that drifts at a
steady rate under the prescribed components) leaves no steady error: the servo does not
lag. Dividing by the *measured* M_ab keeps the loop critically damped as the contact
network stiffens or softens.

The dashpots. Part of σ^c is the normal dashpots' force, σ^d = (1/V) Σ (-fd n)⊗l
with fd = -γ vn: it answers the cell's strain rate within the same step, σ^d ≈ C L
(C ~ γ z c per unit volume). Fed back through the proportional term, it closes a loop
L_n = (2/τ)(σ* - σ^s - C L_(n-1))/M of gain (2/τ) C/M ≈ 2.2 β (β the damping ratio of
the contact law): about 0.6–0.8 at e = 0.5 (stable, but the strain rate rings), above 1
at e <= 0.4 (it never settles: no preparation relaxed in 2e6 steps, measured). So the proportional term acts on the spring stress only,

    L_ab = L_int + (2/τ) (σ*_ab - σ^c_ab + σ^d_ab) / M_ab,   dL_int/dt = (σ*_ab - σ^c_ab) / (M_ab τ²),   (b')

which keeps (b)'s double pole for the spring stress σ^s = σ^c - σ^d (the plant (a) is
a statement about springs), while the integral term holds the whole contact stress σ^c,
dashpots included, at the target in a steady state.

Gain. τ must be (i) long compared with the time step (dt/τ <= 0.1 keeps the discrete
loop within a few percent of the continuous one) and (ii) short compared with the time
over which the packing relaxes non-affinely, so the loop sees the affine plant (a) it
was built for and not the softer relaxed one (on the relaxed plant, (b) would be
under-damped). The non-affine relaxation of a disc takes at least one binary contact
time t_c = π sqrt(m/(2 kn)) ∝ κ^(-1/2); we take

    τ = TAU_CONTACTS · t_c(mean pair),   TAU_CONTACTS = 0.5,

so the gain follows κ (dt/τ ≈ 0.07 at the default time step). Measured on a frictional
packing (tests/test_servo.py): a step of the target overshoots by 6% of the step and
settles without oscillating; longer τ (1, 2, 4 t_c) overshoot more (10, 14, 15%), the
under-damping that the relaxed plant predicts. The inertial number enters through a rate cap: the servo never
deforms the cell faster than L_MAX_FACTOR · γ̇_ref with γ̇_ref = I/d sqrt(P0/ρ) (the
loading stays quasi-static even while the error is large, e.g. compressing a gas), and
the integral stops accumulating while the cap is active (anti-windup). The test suite
checks both properties: a step in the target settles with no overshoot, and a biaxial
stage holds σxx within a stated tolerance.
"""
from __future__ import annotations

import math

from numba import njit

TAU_CONTACTS = 0.5
"""Servo time constant in binary contact times of a mean disc."""

L_MAX_FACTOR = 10.0
"""Rate cap of the servo, in units of γ̇_ref."""

M_FLOOR = 1e-12
"""Floor of the affine stiffness (relative to kn): an empty network compresses at the cap."""


def time_constant(kn: float, rho: float = 1.0, d_mean: float = 1.0) -> float:
    """τ = TAU_CONTACTS · t_c, t_c = π sqrt(m_eff/kn) of two mean discs (m_eff = m/2)."""
    m = rho * math.pi * (0.5 * d_mean) ** 2
    return TAU_CONTACTS * math.pi * math.sqrt(0.5 * m / kn)


@njit(cache=True)
def servo_rate(err, err_spring, stiffness, l_int, dt, tau, l_max):
    """One servo update (b'): returns (L_ab, new L_int); ``err`` = σ* - σ^c integrated,
    ``err_spring`` = σ* - (σ^c - σ^d) proportional (module docstring)."""
    m = stiffness
    if m < M_FLOOR:
        m = M_FLOOR
    li = l_int + dt * err / (m * tau * tau)
    rate = li + 2.0 * err_spring / (m * tau)
    if rate > l_max:
        return l_max, l_int
    if rate < -l_max:
        return -l_max, l_int
    return rate, li

"""Sample preparation: a random gas, compressed isotropically and relaxed (docs/theory.md §11).

1. :func:`random_gas`: N discs at packing fraction ``c_gas`` in a square cell, placed
   without overlap on randomly chosen sites of a square grid with a random offset each,
   at rest. The discs are numbered along the grid rows, so that discs near each other
   are near in memory (the pair pass reads both discs of a pair: with random numbering it
   runs about 10 % slower at N = 4000).
2. :func:`compress_to_pressure`: both normal stresses servo-controlled to -P0
   (:mod:`dem.servo`, strain rate capped at ``rate``) with the preparation friction
   μ_prep (the packing knob: μ_prep = 0 gives dense samples, μ_prep = μ the usual
   "loose" ones near the critical packing fraction, μ_prep > μ looser ones), until
   :func:`relaxed`:
       |P/P0 - 1| < P_TOL, unbalanced force ratio < ``force_tol`` and
       kinetic / elastic energy < ``kinetic_tol`` (kinetic energy of the discs that are
       not rattlers: a rattler may drift or spin freely in its cage forever),
   with σxy servo-controlled to 0 as well,
   then the friction is switched to the test value (tangential histories kept).
   When μ_prep > μ the switch leaves contacts above the new Coulomb bound, so
   :func:`lower_friction` relaxes the sample again at P0: first a quenched collapse,
   strongly damped contacts (restitution E_SWITCH) with the fluctuation velocities and
   spins set to zero every ``quench_every`` steps, until its own thresholds or until only
   TEST_LAW_RESERVE steps of the budget are left, then a relaxation with the test law.
   The quench removes the kinetic energy that the collapse releases before it can carry
   the discs past the first arrangement that is stable under μ, so the collapse stops in
   the nearest stable arrangement instead of a denser one (measured at N = 1000,
   κ = 1e3, μ_prep = 10, rate 1e-3, seeds 1–3: c0 0.8027 quenched against 0.8053 with
   inertia, docs/dem_validation.md); ``quench_every`` = 0 lets the collapse run with
   inertia.
3. :func:`compress_to_fraction` (check of Madadi et al. 2004): compression at a prescribed strain
   rate to a target packing fraction, then relaxation at fixed volume. Targets above
   C_MAX are refused: random disc packings jam near c ≈ 0.84, and past C_MAX the mean
   overlap would exceed what a linear contact law represents.

The unbalanced force ratio is mean_i |F_i| / mean_c fn over discs that are not rattlers
(:func:`dem.measure.rattler_mask`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from dem import neighbours
from dem.contact_law import ContactLaw
from dem.integrator import Control, Dynamics, advance, evaluate_forces, time_step
from dem.measure import Contacts, elastic_energy, kinetic_energy, rattler_mask
from dem.particles import ParticleError
from dem.periodic_cell import square_cell
from dem.state import NACC, State, new_state

VERSION = 2
"""Version of the preparation: raised whenever a seed's settings give a different sample
(caches of prepared samples are keyed on it)."""
C_MAX = 0.92
E_SWITCH = 0.05
P_TOL = 1e-3
FORCE_TOL = 1e-3
KINETIC_TOL = 1e-5
CHECK_EVERY = 500
QUENCH_EVERY = 10
"""Steps between the velocity resets of the quenched friction drop (a fraction of a contact
time, t_c ≈ 16 steps at the default time step; must divide CHECK_EVERY)."""
QUENCH_FORCE_TOL = 1e-4
"""Unbalanced force threshold that ends the quenched collapse (ten times below FORCE_TOL: a
quenched sample creeps slowly, and a creep stopped early turns into a collapse under
the test law)."""
TEST_LAW_RESERVE = 200_000
"""Steps of the preparation's budget that the quenched collapse leaves to the relaxation
under the test law. Some quenched samples creep without end at an unbalanced force ratio
of 8e-4 – 7e-3 (N = 400, κ = 1e4: docs/dem_validation.md, section 9); the quench then
stops at its share, is recorded as unrelaxed (``PrepInfo.quench_relaxed``) and the test
law relaxes the sample (that relaxation took 4.5e4 – 6e4 steps there). A quench that
ends with more steps than this left is not affected (every sample of the tables in
docs/dem_validation.md)."""


class PreparationError(ValueError):
    """Bad preparation settings (the message names the value and the accepted range)."""


@dataclass
class PrepInfo:
    """What the preparation did: steps, whether the thresholds were met, final values."""

    steps: int = 0
    relaxed: bool = False
    c: float = 0.0
    P: float = 0.0
    unbalanced: float = math.inf
    kinetic_ratio: float = math.inf
    c_compressed: float | None = None       # c before a friction drop (μ_prep > μ)
    c_quenched: float | None = None         # c after its quenched collapse
    quench_relaxed: bool | None = None      # whether that collapse met its thresholds
    realization: int = 0                    # which realization of the seed (dem.job)

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def random_gas(radius: np.ndarray, c_gas: float, rng: np.random.Generator) -> State:
    """Discs at packing fraction ``c_gas`` without overlap (see the module doc)."""
    n = radius.shape[0]
    k = int(math.ceil(math.sqrt(n)))
    side = math.sqrt(math.pi * float(np.sum(radius**2)) / c_gas)
    a = side / k
    if a <= 2.0 * radius.max():
        raise PreparationError(f"gas packing fraction c_gas = {c_gas} too dense to place "
                               f"{n} discs on a grid; accepted (0, {c_gas * (a / (2 * radius.max())) ** 2:.3f})")
    sites = np.sort(rng.permutation(k * k)[:n])   # numbered along the grid rows
    grid = np.stack([sites % k, sites // k], axis=1).astype(float)
    free = 0.5 * a - radius[:, None]
    x = (grid + 0.5) * a + (2.0 * rng.random((n, 2)) - 1.0) * free
    st = new_state(radius, x / side, square_cell(side))
    st.rng_state = rng.bit_generator.state
    return st


def check_configuration(radius: np.ndarray, positions: np.ndarray, h: np.ndarray) -> None:
    """Refuse an explicit configuration with overlapping discs (names the worst pair)."""
    st = new_state(radius, positions @ np.linalg.inv(h).T, h)
    neighbours.rebuild(st, 0.0)
    c = Contacts(st)
    if c.count:
        k = int(np.argmax(c.delta))
        raise ParticleError(f"explicit configuration: discs {c.i[k]} and {c.j[k]} overlap by "
                            f"{c.delta[k]:.4g} (and {c.count - 1} more pairs); accepted: no "
                            f"overlap (distance >= sum of radii)")


def _rattlers(state: State, law: ContactLaw) -> np.ndarray:
    c = Contacts(state)
    return rattler_mask(state.n, c.i, c.j, 3 if law.mu == 0 else 2)


def unbalanced_force_ratio(state: State, law: ContactLaw) -> float:
    c = Contacts(state)
    if c.count == 0:
        return math.inf
    ratt = _rattlers(state, law)
    fmag = np.hypot(state.force[:, 0], state.force[:, 1])[~ratt]
    return float(fmag.mean() / max(c.fn.mean(), 1e-300)) if fmag.size else math.inf


def relaxed(state: State, law: ContactLaw, p_target: float | None, info: PrepInfo,
            force_tol: float = FORCE_TOL, kinetic_tol: float = KINETIC_TOL) -> bool:
    """Update ``info`` and say whether the relaxation thresholds are met."""
    p = -0.5 * (state.stress[0] + state.stress[1])
    e_el = elastic_energy(state, law)
    info.P, info.c = float(p), state.packing_fraction
    info.unbalanced = unbalanced_force_ratio(state, law)
    info.kinetic_ratio = kinetic_energy(state, _rattlers(state, law)) / e_el if e_el > 0 else math.inf
    ok_p = p_target is None or abs(p / p_target - 1.0) < P_TOL
    info.relaxed = bool(ok_p and info.unbalanced < force_tol and info.kinetic_ratio < kinetic_tol)
    return info.relaxed


def _run_until_relaxed(state, dyn, control, p_target, max_steps, info, progress, quench_every=0,
                       force_tol=FORCE_TOL):
    """Advance until :func:`relaxed` (checked every CHECK_EVERY steps); with
    ``quench_every`` > 0 the fluctuation velocities and spins are set to zero every
    ``quench_every`` steps (after the check)."""
    chunk = quench_every if quench_every > 0 else CHECK_EVERY
    done = 0             # steps of this call (info.steps may start anywhere)
    while info.steps < max_steps:
        advance(state, dyn, chunk, control)
        info.steps += chunk
        done += chunk
        if done % CHECK_EVERY == 0:
            if progress is not None:
                progress(info)
            if relaxed(state, dyn.law, p_target, info, force_tol):
                break
        if quench_every > 0:
            state.v[:] = 0.0
            state.omega[:] = 0.0
    return state


def compress_to_pressure(state: State, dyn: Dynamics, p0: float = 1.0, max_steps: int = 2_000_000,
                         progress=None, quench_every: int = 0,
                         force_tol: float = FORCE_TOL) -> tuple[State, PrepInfo]:
    """Isotropic servo compression to P = p0, then relaxation (see the module doc);
    ``quench_every`` > 0: velocities reset every that many steps, ``force_tol``: the
    unbalanced force threshold (both for :func:`lower_friction`)."""
    if not (isinstance(quench_every, int) and quench_every >= 0
            and (quench_every == 0 or CHECK_EVERY % quench_every == 0)):
        raise PreparationError(f"quench_every = {quench_every} out of range; accepted 0 (no "
                               f"quench) or a divisor of {CHECK_EVERY}")
    info = PrepInfo()
    neighbours.rebuild(state, dyn.skin)
    evaluate_forces(state, dyn)
    target = np.array([-p0, -p0, 0.0])
    ctl = Control(np.zeros(4), np.array([True, True, True, False]), target, target)
    _run_until_relaxed(state, dyn, ctl, p0, max_steps, info, progress, quench_every, force_tol)
    return reset_accumulators(state), info


def compress_to_fraction(state: State, dyn: Dynamics, target_c: float, rate: float,
                         max_steps: int = 2_000_000, progress=None) -> tuple[State, PrepInfo]:
    """Isotropic compression at strain rate ``rate`` to packing fraction ``target_c``,
    then relaxation at fixed volume (no pressure target)."""
    if not (0.0 < target_c <= C_MAX):
        raise PreparationError(f"target packing fraction {target_c} is above the jamming range "
                               f"of random disc packings (c_J ≈ 0.84); accepted (0, {C_MAX}]")
    info = PrepInfo()
    neighbours.rebuild(state, dyn.skin)
    evaluate_forces(state, dyn)
    strain = math.log(state.packing_fraction / target_c)      # ε_v to apply (< 0: compress)
    if strain < 0.0:
        nsteps = int(math.ceil(-strain / (rate * dyn.dt)))
        # Cayley map of L = g I scales the area by ((1 + g dt/2)/(1 - g dt/2))² per step
        g = 2.0 / dyn.dt * math.tanh(strain / (4.0 * nsteps))
        ctl = Control(np.array([g, g, 0.0, 0.0]), np.zeros(4, bool), np.zeros(3), np.zeros(3))
        advance(state, dyn, nsteps, ctl)
        info.steps += nsteps
    state.L[:] = 0.0
    _run_until_relaxed(state, dyn, Control.fixed(), None, max_steps, info, progress)
    return reset_accumulators(state), info


def lower_friction(state: State, dyn: Dynamics, law: ContactLaw, info: PrepInfo,
                   p0: float = 1.0, max_steps: int = 2_000_000, progress=None,
                   quench_every: int = QUENCH_EVERY) -> tuple[State, PrepInfo]:
    """Relax at P = p0 under ``law`` a sample compressed with a higher friction (module
    doc, 2): a quenched collapse (velocities reset every ``quench_every`` steps; 0: none)
    with damped contacts, which leaves :data:`TEST_LAW_RESERVE` steps of ``max_steps``
    to the relaxation under the test law that follows; returns the state and ``info`` (of
    the compression) with the steps added, ``c_compressed``, ``c_quenched``,
    ``quench_relaxed`` set and the final values. A stage with no steps left does not run
    (the figures are then the last stage's, unrelaxed). ``dyn``: the preparation's
    dynamics; its time step is checked against both laws' stability limits."""
    out = replace(info, c_compressed=info.c)
    fraction = dyn.dt / math.sqrt(float(state.mass.min()) / law.kn)
    quenched = (replace(law, e=E_SWITCH), quench_every,
                QUENCH_FORCE_TOL if quench_every > 0 else FORCE_TOL, TEST_LAW_RESERVE)
    for stage_law, quench, force_tol, reserve in (quenched, (law, 0, FORCE_TOL, 0)):
        budget = max_steps - out.steps - reserve
        if budget <= 0:
            out.relaxed = False
            if reserve:
                out.quench_relaxed = False
            continue
        time_step(stage_law, float(state.mass.min()), fraction,
                  float(state.mass.max() / state.mass.mean()))
        state, more = compress_to_pressure(state, replace(dyn, law=stage_law), p0, budget,
                                           progress, quench, force_tol)
        out = replace(more, steps=out.steps + more.steps, c_compressed=out.c_compressed,
                      c_quenched=out.c_quenched, quench_relaxed=out.quench_relaxed)
        if reserve:
            out.c_quenched, out.quench_relaxed = more.c, more.relaxed
    return state, out


def switch_friction(dyn: Dynamics, mu: float) -> Dynamics:
    """The same dynamics with the test friction μ (tangential histories are kept)."""
    return replace(dyn, law=dyn.law.with_friction(mu))


def reset_accumulators(state: State) -> State:
    """Zero time, strain, work and dissipation (a prepared sample starts a test at 0)."""
    state.acc[:] = np.zeros(NACC)
    return state

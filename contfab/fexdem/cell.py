"""One DEM cell as a material point: a strain-and-spin increment, then relaxation.

A quadrature point's increment (Δεxx, Δεyy, Δγxy = 2Δεxy) and spin Δω =
(L_yx - L_xy)/2 · Δt (counter-clockwise, :mod:`contfab.models.tiers`) become the
velocity-gradient increment of the periodic cell (docs/theory.md §10, L_xy = ∂vx/∂y)

    ΔL = (Δεxx, Δεyy, Δγxy/2 - Δω, Δγxy/2 + Δω)        (xx, yy, xy, yx),

applied as ONE fully strain-controlled stage of a loading path (:mod:`dem.paths`) over
a pseudo-time Δt = n·dt set by the cell's inertial number: with the largest component
m = max|ΔL| and γ̇_ref = I (DEM units, P0 = ρ = d = 1), n = ceil(m / (I dt)) steps at
L = ΔL / (n dt), so the cell receives exactly ΔL (to round-off) at a rate ≤ γ̇_ref.
The stage has length n·dt·I in reference strain τ and rates ΔL/(n dt I), and it
continues from the forces of the cell's last step (:func:`start_cell` evaluates them
once, on the fresh clone), so a stand-alone :class:`dem.rve.PathRunner` given the
same stages as one path takes bitwise the same steps (tests/test_fexdem.py).

The cell is then held (L = 0) until quasi-static equilibrium,
:func:`dem.prepare.relaxed`: unbalanced force ratio < ``force_tol`` and kinetic /
elastic energy < ``kinetic_tol``, checked every ``check_every`` steps up to
``relax_budget`` steps, else :class:`CellNotRelaxed`. ``force_tol = inf`` skips the
relaxation. The result is the Love–Weber stress (units of P0, tension positive) and
the state (c, A, Bc, Bs) (docs/theory.md §2).

:func:`cell_tangent` is the cell's own incremental stiffness at an increment Δe, by
one-sided differences of the same map from the same committed state:

    D[:, j] = (σ(Δe + h_j e_j) - σ(Δe)) / h_j,   h_j = s_j · rel · max(max|Δe|, h_min),

with s_j = sign(Δe_j) (+1 for 0): the probe continues the loading direction, so it
stays in the same incremental branch as Δe (the DEM response is incrementally
non-linear: loading and unloading stiffnesses differ). ``rel`` must keep h above the
scale of the cells' stress noise (measured in docs/fexdem.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dem.conventions import fabric_state
from dem.integrator import Control, Dynamics, advance, evaluate_forces
from dem.measure import Contacts, fabric_tensor, love_weber
from dem.paths import Path, Stage
from dem.prepare import PrepInfo, relaxed
from dem.rve import PathRunner
from dem.state import State

CELL_STATE = ("c", "A", "Bc", "Bs")
"""What a cell reports besides its stress."""


class CellNotRelaxed(ValueError):
    """A cell did not reach quasi-static equilibrium within its relaxation budget."""


class IncrementTooLarge(ValueError):
    """An increment beyond ``CellOptions.max_increment`` (a diverging Newton iterate)."""


@dataclass(frozen=True)
class CellOptions:
    """Equilibrium thresholds, the relaxation budget (steps) and the largest increment.

    ``max_increment`` bounds max|ΔL| of one increment: the cell's cost grows with it
    (n = max|ΔL| / (I dt) steps) and an increment many times an FE step's strain comes
    from a diverging Newton iterate (measured: one such iterate of the biaxial case ran
    for minutes); it fails the point instead, and the solver cuts the step.
    """

    force_tol: float = 1e-2
    kinetic_tol: float = 1e-4
    relax_budget: int = 20_000
    check_every: int = 250
    max_increment: float = 1e-2

    def __post_init__(self):
        for name in ("force_tol", "kinetic_tol"):
            v = getattr(self, name)
            if not v > 0:
                raise ValueError(f"{name} = {v} out of range; accepted (0, inf] (inf: no relaxation)")
        if not (isinstance(self.relax_budget, int) and self.relax_budget >= 0):
            raise ValueError(f"relax_budget = {self.relax_budget} out of range; accepted integers >= 0")
        if not (np.isfinite(self.max_increment) and self.max_increment > 0):
            raise ValueError(f"max_increment = {self.max_increment} out of range; accepted (0, inf)")
        if not (isinstance(self.check_every, int) and self.check_every >= 1):
            raise ValueError(f"check_every = {self.check_every} out of range; accepted integers >= 1")

    @property
    def relaxes(self) -> bool:
        return math.isfinite(self.force_tol) or math.isfinite(self.kinetic_tol)


@dataclass(frozen=True)
class CellResult:
    """Stress (sxx, syy, sxy) in units of P0, state (c, A, Bc, Bs), steps taken."""

    stress: np.ndarray
    state: np.ndarray
    strain_steps: int
    relax_steps: int


def increment_gradient(dstrain, dspin: float) -> np.ndarray:
    """ΔL (xx, yy, xy, yx) of a Voigt strain increment and a spin increment (module doc)."""
    exx, eyy, gxy = (float(x) for x in dstrain)
    return np.array([exx, eyy, 0.5 * gxy - dspin, 0.5 * gxy + dspin])


def increment_stage(dL: np.ndarray, dyn: Dynamics, name: str = "increment") -> Stage | None:
    """The fully strain-controlled stage that applies ``dL`` (None for a zero increment)."""
    m = float(np.max(np.abs(dL)))
    if m == 0.0:
        return None
    gdot = dyn.gdot_ref
    n = max(1, math.ceil(m / (gdot * dyn.dt)))
    length = n * dyn.dt * gdot
    return Stage(name=name, length=length, rates=tuple(float(x) for x in dL / length),
                 output_every=length)


def measure_cell(state: State) -> tuple[np.ndarray, np.ndarray]:
    """(Love–Weber stress (3,), (c, A, Bc, Bs)) of a cell."""
    c = Contacts(state)
    stress = np.asarray(love_weber(state, c), dtype=float)
    a, bc, bs = fabric_state(*fabric_tensor(c.n, state.n))
    return stress, np.array([state.packing_fraction, a, bc, bs], dtype=float)


def relax(state: State, dyn: Dynamics, options: CellOptions) -> int:
    """Hold the cell until :func:`dem.prepare.relaxed`; returns the steps taken."""
    if not options.relaxes:
        return 0
    info, steps = PrepInfo(), 0
    while not relaxed(state, dyn.law, None, info, options.force_tol, options.kinetic_tol):
        if steps >= options.relax_budget:
            raise CellNotRelaxed(
                f"no quasi-static equilibrium after {steps} relaxation steps: unbalanced force "
                f"ratio {info.unbalanced:.3g} (tolerance {options.force_tol:g}), kinetic/elastic "
                f"energy {info.kinetic_ratio:.3g} (tolerance {options.kinetic_tol:g})")
        advance(state, dyn, options.check_every, Control.fixed())
        steps += options.check_every
    return steps


def cell_tangent(committed: State, dyn: Dynamics, dstrain, dspin: float, stress: np.ndarray,
                 options: CellOptions, rel: float, h_min: float = 1e-5) -> np.ndarray:
    """(3, 3) ∂σ/∂(Δεxx, Δεyy, Δγxy) of the cell at ``dstrain`` (P0 per unit strain, module
    doc); ``stress`` is σ(Δe) from ``committed``, which is not changed."""
    if not (np.isfinite(rel) and rel > 0):
        raise ValueError(f"tangent probe rel = {rel} out of range; accepted (0, inf)")
    de = np.asarray(dstrain, dtype=float)
    h = rel * max(float(np.max(np.abs(de))), h_min)
    d = np.empty((3, 3))
    for j in range(3):
        hj = h if de[j] >= 0 else -h
        probe = de.copy()
        probe[j] += hj
        res = advance_cell(committed.copy(), dyn, probe, dspin, options)
        d[:, j] = (res.stress - stress) / hj
    return d


def start_cell(state: State, dyn: Dynamics) -> State:
    """A fresh clone's forces at its positions (as :meth:`dem.rve.PathRunner.start`)."""
    return evaluate_forces(state, dyn)


def advance_cell(state: State, dyn: Dynamics, dstrain, dspin: float,
                 options: CellOptions) -> CellResult:
    """Apply one increment to ``state`` in place, relax, measure (see the module doc)."""
    dL = increment_gradient(dstrain, dspin)
    if float(np.max(np.abs(dL))) > options.max_increment:
        raise IncrementTooLarge(f"increment max|dL| = {np.max(np.abs(dL)):.3g} out of range; "
                                f"accepted <= max_increment = {options.max_increment:g}")
    stage = increment_stage(dL, dyn)
    steps0 = state.step
    if stage is not None:
        runner = PathRunner(Path(name="fexdem increment", stages=(stage,)), dyn, dyn.gdot_ref)
        runner.run(state, runner.start(state, evaluate=False))
    strain_steps = state.step - steps0
    relax_steps = relax(state, dyn, options)
    stress, cell_state = measure_cell(state)
    return CellResult(stress, cell_state, strain_steps, relax_steps)

r"""Explicit dynamic relaxation: a quasi-static solution without an equilibrium iteration.

The stage is followed in ``cycles`` explicit cycles of a fictitious damped dynamics,

    m_i v̇_i = F_i − α |F_i| sign(v_i),        F = f_ext − f_int(σ),

integrated by central differences with a unit time step: v ← v + (F − α |F| sign v)/m,
u ← u + v, the constrained DOFs moved at the constant rate ū/cycles, and the
constitutive update advanced from the last cycle's stress and state by each cycle's strain
and spin increment (:meth:`contfab.fem.material.TierMaterial.update`: the same return
mapping as the Newton solver's, without its tangent). The masses are the Gershgorin bound
m_i = ½ Σ_j |K_ij| of the elastic stiffness K (the material's elastic law at every point),
which keeps the highest frequency of M⁻¹K below √2, inside the stability limit 2 of a unit
step. The damping is local, not viscous (α = 0.8, Cundall 1987, "Distinct element models
of rock and soil structure", in *Analytical and Computational Methods in Engineering Rock
Mechanics*, 129–163; the scheme of FLAC): a force opposing the velocity in proportion to the
out-of-balance force, so it vanishes in equilibrium and adds no rate effect to a steady
state. A stage without a prescribed increment or load ramp (a geostatic stage) is relaxed
for ``relax_cycles`` cycles.

There is no equilibrium iteration and so no solvability condition: where the incremental
problem of a non-associated material has no unique solution (the symmetric part of its
tangent is indefinite: docs/fem_validation.md, section 7) the damped dynamics selects one.
How near a state is to static equilibrium is measured, not imposed: every record's residual
is the relative out-of-balance force |F_f| / max(|f_ext|, |r_c|) (as the Newton solver's),
and the result converges as the cycles grow (the loading slows against the damping):
``cycles`` is the accuracy knob, to be checked by doubling it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Iterator

import numpy as np

from contfab.fem.solver import (ConstrainedSystem, ConvergenceError, FieldState, Solver, Stage,
                                StepRecord, norm)
from contfab.fem.viscous import elastic_stiffness


@dataclass(frozen=True)
class ExplicitOptions:
    """``cycles`` per stage with a prescribed increment or load ramp, ``relax_cycles`` for a
    stage without, ``damping`` α in [0, 1), ``records`` per stage (each a
    :class:`~contfab.fem.solver.StepRecord` with one residual)."""

    cycles: int = 100_000
    relax_cycles: int = 20_000
    damping: float = 0.8
    records: int = 100

    def __post_init__(self):
        for name in ("cycles", "relax_cycles", "records"):
            value = getattr(self, name)
            if not (isinstance(value, (int, np.integer)) and value >= 1):
                raise ValueError(f"{name} = {value!r} is outside the accepted range: integers >= 1")
        if not 0.0 <= self.damping < 1.0:
            raise ValueError(f"damping = {self.damping!r} is outside the accepted range [0, 1)")


class ExplicitSolver(Solver):
    """Dynamic relaxation over stages (module doc) with the :class:`Solver` interface:
    ``committed`` (the state at the last record), ``records``, ``reactions``."""

    def __init__(self, disc, material, stress0: np.ndarray, state0: np.ndarray,
                 options: ExplicitOptions = ExplicitOptions()):
        super().__init__(disc, material, stress0, state0)
        self.explicit = options
        n = disc.npoints
        elastic = np.ascontiguousarray(np.broadcast_to(elastic_stiffness(material), (n, 3, 3)))
        k = disc.tangent(elastic, np.zeros((n, 3))).tocsr()
        self.mass = 0.5 * np.asarray(abs(k).sum(axis=1)).ravel()

    def run_stage(self, stage: Stage, start=None) -> Iterator[StepRecord]:
        """Advance ``stage`` from t = 0 to 1 in its cycles, yielding ``records`` records."""
        if start is not None:
            raise ValueError("an explicit stage cannot be resumed mid-stage (start must be None)")
        opt, disc, material = self.explicit, self.disc, self.material
        system = ConstrainedSystem(disc, stage.fixed_dofs, stage.ties, stage.tie_factors)
        if system.tie_map is not None:
            raise ValueError("tied DOFs are not supported by the explicit solver")
        free, fixed = system.free, system.fixed
        moving = np.any(stage.increment != 0) or stage.f_ramp is not None
        cycles = opt.cycles if moving else opt.relax_cycles
        every = max(cycles // opt.records, 1)
        c = self.committed
        self.stage_start = c.u[fixed].copy()
        u, stress, state = c.u.copy(), c.stress, c.state
        u_report = u.copy()
        v = np.zeros_like(u)
        v_fixed = stage.increment / cycles
        mass = self.mass[free]
        f_int = disc.internal_force(stress)
        for k in range(1, cycles + 1):
            t = k / cycles
            f_ext = stage.f_dead if stage.f_ramp is None else stage.f_dead + t * stage.f_ramp
            force = (f_ext - f_int)[free]
            v_free = v[free]
            v[free] = v_free + (force - opt.damping * np.abs(force) * np.sign(v_free)) / mass
            v[fixed] = v_fixed
            dstrain, dspin = disc.strain(v)
            res = material.update(stress, state, dstrain, dspin)
            if np.any(res.status < 0):
                raise ConvergenceError(f"stage {stage.name!r}: the constitutive update failed "
                                       f"at {int(np.sum(res.status < 0))} points in cycle {k} "
                                       f"(t = {t:.6g})", self.committed, [])
            stress, state = res.stress, res.state
            u += v
            f_int = disc.internal_force(stress)
            if k % every and k != cycles:
                continue
            r = f_int - f_ext
            rel = norm(r[free]) / (max(norm(f_ext), norm(r[fixed])) or 1.0)
            if not math.isfinite(rel):
                raise ConvergenceError(f"stage {stage.name!r}: the dynamics diverged in cycle "
                                       f"{k} (t = {t:.6g})", self.committed, [])
            self.committed = FieldState(stage.name, t, u.copy(), stress, state,
                                        np.ascontiguousarray(res.tangent),
                                        np.zeros_like(stress), res.status, r,
                                        disc.strain(u - u_report)[0])
            u_report = u.copy()
            record = StepRecord(stage.name, t, every / cycles, [rel], tol=math.inf)
            self.records.append(record)
            yield record
        if stage.reset_displacement:
            self.committed = replace(self.committed, u=np.zeros_like(self.committed.u))

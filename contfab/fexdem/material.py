"""The FEM material "tier" ``dem``: one DEM cell per quadrature point.

:class:`DemMaterial` follows the solver's update contract
(:class:`contfab.fem.solver.Material`): ``update(stress_n, state_n, dstrain, dspin)``
sends each cell its increment (:mod:`contfab.fexdem.cell`) through a cell backend
(:mod:`contfab.fexdem.backends`) and returns

* stress: the cell's Love–Weber stress times ``p_unit`` (the scene's stress per P0;
  cells are prepared at P0 = 1), tension positive;
* state (gp, c, A, Bc, Bs): c and the fabric measured in the cell; gp accumulates the
  total deviatoric strain Σ sqrt((Δεxx - Δεyy)² + Δγxy²) (the DEM has no elastic/
  plastic split; the column keeps the solver's outputs uniform across tiers);
* tangent: the calibrated continuum model's algorithmic tangent (``tangent_tier`` 1
  or 2) at the same committed stress and state, over the same increment, with the
  regularization stiffness replaced by the cell's measured elastic modulus (the DEM
  cell is stiffer than the default λ; a tangent softer than the material makes the
  quasi-Newton iteration overshoot). Where that model fails, its elastic tangent.
  ``tangent="dem"`` is the cells' own incremental stiffness at the trial increment
  (:func:`contfab.fexdem.cell.cell_tangent`, one-sided differences with a probe of
  ``probe`` max|Δe|: three more cell runs per point and iteration, i.e. Newton on the
  DEM map itself); where a probe fails, the model's tangent.
  ``tangent="elastic"`` uses that elastic tangent everywhere (a stiff secant: the
  iteration contracts at ~1 - E_DEM/E per iteration). Measured on a dense 150-disc
  cell with the shipped (uncalibrated) parameters: the tier-1 tangent diverged at the
  first step (tier 1 yields at R/P = sin φ where the cell is still elastic), the
  elastic one converged (residual halved per iteration);
* status: the model's status at that state (0 elastic, 1 plastic, ...), -1 for a
  cell that did not reach equilibrium: its error, naming the element, the quadrature
  point and the position, is kept in :attr:`DemMaterial.failures` and the solver
  cuts the step.

Trials never touch the committed cells: :meth:`commit` (called by
:class:`FexdemSolver` after each converged step) promotes the latest trial, which must
be the one the solver accepted. The solver therefore runs without line search and
without the spin-tangent difference (one update per Newton iteration, the accepted
one last): :class:`FexdemSolver` enforces both.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from contfab.fem.solver import ConvergenceError, FieldState, NewtonOptions, Solver, StepRecord
from contfab.fexdem.cell import CellOptions, advance_cell, measure_cell, start_cell
from contfab.fexdem.profile import Ledger
from contfab.models import tiers
from contfab.params import Params
from contfab.tensors import isotropic_stiffness
from dem import checkpoint
from dem.fileio import atomic_path

STATE_NAMES = ("gp", "c", "A", "Bc", "Bs")
TANGENTS = ("model", "elastic", "dem")
DEM_PROBE = 0.1
"""Relative probe of ``tangent="dem"``: h = 0.1 max|Δe| (docs/fexdem.md: the cells' stress
noise is ~1e-5 P0 against a probe response of ~1e-2 P0)."""
PROBE_STRAIN = 1e-5
"""Strain of the one-off probe that measures a cell's elastic modulus."""


def elastic_modulus(prepared: str) -> float:
    """E = Δσxx/Δεxx of the prepared cell under a small uniaxial strain (units of P0).

    For the isotropic regularization with ν = 0 (K = G = E/2) a uniaxial strain Δεxx
    gives Δσxx = (K + G) Δεxx = E Δεxx, so E is the matching λ·p_ref.
    """
    state, dyn, _, _ = checkpoint.load(prepared)
    s0, _ = measure_cell(start_cell(state, dyn))
    res = advance_cell(state, dyn, (-PROBE_STRAIN, 0.0, 0.0), 0.0,
                       CellOptions(force_tol=np.inf, kinetic_tol=np.inf))
    return float((res.stress[0] - s0[0]) / -PROBE_STRAIN)


def initial_fields(prepared: str, n: int, p_unit: float) -> tuple[np.ndarray, np.ndarray]:
    """(stress (n, 3) times ``p_unit``, state (n, 5): gp = 0, c, A, Bc, Bs) of the prepared
    sample at ``n`` points."""
    state, dyn, _, _ = checkpoint.load(prepared)
    stress, cell_state = measure_cell(start_cell(state, dyn))
    return (np.tile(stress * p_unit, (n, 1)), np.tile(np.concatenate([[0.0], cell_state]), (n, 1)))


class DemMaterial:
    """DEM cells at the points of ``disc`` run by ``cells`` (see the module doc)."""

    state_names = STATE_NAMES

    def __init__(self, cells, disc, params: Params, p_unit: float = 1.0, tangent_tier: int = 1,
                 modulus: float | None = None, tangent: str = "model", probe: float = DEM_PROBE):
        if tangent not in TANGENTS:
            raise ValueError(f"tangent = {tangent!r} unknown; accepted {TANGENTS}")
        self.tangent = tangent
        if not (np.isfinite(probe) and probe > 0):
            raise ValueError(f"probe = {probe} out of range; accepted (0, inf)")
        self.probe = float(probe)
        if not (np.isfinite(p_unit) and p_unit > 0):
            raise ValueError(f"p_unit = {p_unit} out of range; accepted (0, inf) (stress per P0)")
        if tangent_tier not in (1, 2):
            raise ValueError(f"tangent_tier = {tangent_tier} out of range; accepted 1 or 2")
        if cells.n != disc.npoints:
            raise ValueError(f"{cells.n} cells for {disc.npoints} quadrature points")
        self.cells, self.disc, self.p_unit = cells, disc, float(p_unit)
        self.modulus = elastic_modulus(cells.prepared) if modulus is None else float(modulus)
        self.params = params.with_tier(tangent_tier).replace(
            "regularization", lam=self.modulus, p_ref=self.p_unit, nu=0.0)
        self.tangent_tier = tangent_tier
        self._elastic = isotropic_stiffness(*self.params.regularization.moduli())
        self._cols = [STATE_NAMES.index(n) for n in tiers.STATE_NAMES[tangent_tier]]
        self.failures: list[str] = []
        self.last = None
        self.cell_steps = np.zeros(2, np.int64)

    def initial(self) -> tuple[np.ndarray, np.ndarray]:
        """(stress (n, 3), state (n, 5)) of the prepared sample at every point."""
        return initial_fields(self.cells.prepared, self.disc.npoints, self.p_unit)

    def where(self, k: int) -> str:
        """Element, quadrature point and position of point ``k`` (for messages)."""
        e, q = divmod(int(k), self.disc.nq)
        x, y = self.disc.points[k]
        return f"element {e}, quadrature point {q} at (x, y) = ({x:.4g}, {y:.4g})"

    def update(self, stress_n, state_n, dstrain, dspin) -> tiers.UpdateResult:
        with self.cells.ledger.timed("update"):
            return self._update(stress_n, state_n, dstrain, dspin)

    def _update(self, stress_n, state_n, dstrain, dspin) -> tiers.UpdateResult:
        stress_n = np.ascontiguousarray(stress_n, dtype=float)
        state_n = np.ascontiguousarray(state_n, dtype=float)
        dstrain = np.ascontiguousarray(dstrain, dtype=float)
        dspin = np.ascontiguousarray(dspin, dtype=float)
        out = self.cells.trial(dstrain, dspin, self.probe if self.tangent == "dem" else 0.0)
        model = tiers.update(self.tangent_tier, stress_n, state_n[:, self._cols], dstrain, dspin,
                             self.params)
        tangent = model.tangent.copy() if self.tangent != "elastic" else np.tile(self._elastic, (len(dspin), 1, 1))
        status = np.where(model.status < 0, 0, model.status).astype(np.int8)
        tangent[model.status < 0] = self._elastic
        if self.tangent == "dem":
            own = np.all(np.isfinite(out["tangent"]), axis=(1, 2))
            tangent[own] = out["tangent"][own] * self.p_unit
        stress = out["stress"] * self.p_unit
        dgp = np.hypot(dstrain[:, 0] - dstrain[:, 1], dstrain[:, 2])
        state = np.column_stack([state_n[:, 0] + dgp, out["state"]])
        bad = ~out["ok"]
        if np.any(bad):
            stress[bad], state[bad], status[bad] = stress_n[bad], state_n[bad], -1
            self.failures = [f"DEM cell at {self.where(k)}: {msg}"
                             for k, msg in sorted(out["errors"].items())]
        self.cell_steps += out["steps"][out["ok"]].sum(axis=0)
        self.last = tiers.UpdateResult(stress, state, tangent, status)
        return self.last

    def commit(self, accepted, fe_step: int) -> None:
        """Promote the cells' latest trial, which must be the solver's ``accepted`` state."""
        if self.last is None or accepted.stress is not self.last.stress:
            raise RuntimeError("the converged step is not the latest trial of the DEM cells "
                               "(line search or spin differences enabled?)")
        self.cells.commit(fe_step)
        self.failures = []


FE_CHECKPOINT = "fe_state.npz"
"""The FE field checkpoint of :class:`FexdemSolver` in its ``ckdir`` (beside the cells')."""
_FIELDS = ("u", "stress", "state", "tangent", "spin_tangent", "status", "residual")


def _fe_checkpoint(path: Path) -> dict:
    if not path.exists():
        raise FileNotFoundError(f"no FE×DEM checkpoint {path}")
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def checkpointed_step(ckdir) -> int:
    """The converged step of the FE field checkpoint in ``ckdir`` (the cells' step to
    resume from: :mod:`contfab.fexdem.registry` keeps it while the next is written)."""
    return int(_fe_checkpoint(Path(ckdir) / FE_CHECKPOINT)["fe_step"])


class FexdemSolver(Solver):
    """The FEM solver with DEM cells: commits the cells after every converged step.

    With ``ckdir`` the committed FE field (the :class:`~contfab.fem.solver.FieldState`
    arrays, the stage's t, its next step dt and start displacements, the step records)
    is written to ``ckdir/fe_state.npz`` (atomic) after the cells' commit of every
    converged step; :meth:`resume` rebuilds the solver from it, on cells made with
    ``resume=`` :func:`checkpointed_step` from the same ``ckdir``, and :meth:`run_stage` with the returned
    ``start`` finishes the stage: the same numbers as without the interruption (a trial
    is a function of the committed state and the increment only). A dashpot
    (``NewtonOptions.viscosity``, :mod:`contfab.fem.dashpot`) has no state: the checkpoint
    holds the cells' stress, the residual with its overstress, and the steps' overstress
    in their records; a run may be resumed with another viscosity.
    """

    def __init__(self, disc, material: DemMaterial, options: NewtonOptions,
                 ckdir: str | None = None):
        if options.line_search != 0 or options.spin_step != 0:
            raise ValueError(f"FE×DEM needs line_search = 0 and spin_step = 0 (each trial is a "
                             f"DEM run; the accepted one must be the last), got "
                             f"{options.line_search} and {options.spin_step}")
        stress0, state0 = material.initial()
        super().__init__(disc, material, stress0, state0, options)
        cells = material.cells
        cells.ledger = Ledger(cells.n, len(cells.blocks))   # the stages' costs only
        self.ckdir = None if ckdir is None else Path(ckdir)

    def run_stage(self, stage, start=None):
        """The solver's stage; a failure below the minimum step names the failed cells.
        Its wall time (without the caller's work between steps) and the checkpoints'
        go into the cells' ledger (:mod:`contfab.fexdem.profile`)."""
        ledger = self.material.cells.ledger
        ledger.mark_load()
        steps = super().run_stage(stage, start)
        try:
            while True:
                with ledger.timed("stage"):
                    record = next(steps, None)
                    if record is not None:
                        self.material.commit(self.committed, len(self.records))
                        if self.ckdir is not None:
                            with ledger.timed("checkpoint"):
                                self._checkpoint(record)
                if record is None:
                    break
                yield record
            ledger.mark_load()
        except ConvergenceError as exc:
            cells = self.material.failures
            if not cells:
                raise
            more = f" (and {len(cells) - 3} more)" if len(cells) > 3 else ""
            raise ConvergenceError(f"{exc}\nfailed DEM cells: " + "; ".join(cells[:3]) + more,
                                   exc.last, exc.attempts) from None

    def _checkpoint(self, record) -> None:
        o = self.options
        dt_next = record.dt * o.grow if record.iterations <= o.easy_iter else record.dt
        c = self.committed
        records = [{"stage": r.stage, "t": r.t, "dt": r.dt, "residuals": r.residuals,
                    "cuts": r.cuts, "extrapolated": r.extrapolated, "overstress": r.overstress,
                    "overstress_mean": r.overstress_mean} for r in self.records]
        with atomic_path(self.ckdir / FE_CHECKPOINT) as tmp:
            with open(tmp, "wb") as f:
                np.savez(f, fe_step=len(self.records), stage=c.stage, t=c.t, dt_next=dt_next,
                         stage_start=self.stage_start, records=json.dumps(records),
                         **{k: getattr(c, k) for k in _FIELDS})

    @classmethod
    def resume(cls, disc, material: DemMaterial, options: NewtonOptions, ckdir, stage):
        """(solver, start) from ``ckdir``'s FE checkpoint for ``stage`` (class doc).

        ``material``'s cells must have been made with ``resume=checkpointed_step(ckdir)``
        from ``ckdir``; cells of another step than the FE field's are an error.
        """
        path = Path(ckdir) / FE_CHECKPOINT
        data = _fe_checkpoint(path)
        step, name = int(data["fe_step"]), str(data["stage"])
        if name != stage.name:
            raise ValueError(f"checkpoint {path} is of stage {name!r}, not {stage.name!r}")
        cells = material.cells.steps()
        if np.any(cells != step):
            bad = np.flatnonzero(cells != step)
            raise ValueError(f"checkpoint {path} is of step {step} but cells {bad[:5].tolist()} "
                             f"are at steps {cells[bad[:5]].tolist()} (made with resume = "
                             f"checkpointed_step({ckdir})?)")
        solver = cls(disc, material, options, ckdir)
        solver.committed = FieldState(name, float(data["t"]),
                                      **{k: np.array(data[k]) for k in _FIELDS})
        solver.records = [StepRecord(tol=options.tol, **r) for r in json.loads(str(data["records"]))]
        dt = min(float(data["dt_next"]), stage.dt_max)
        return solver, (float(data["t"]), dt, data["stage_start"])

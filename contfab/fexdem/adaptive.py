"""Adaptive FE×DEM: a model where its measured error bound meets the tolerance, a DEM cell
where none does.

**Choice.** The measured bounds are those of ``tier = "auto"``
(:func:`contfab.selection.auto_tier.choose`: per loading class, the RMS error of R/P against
the DEM of each model, and its cost). The model points run one model, :func:`model_choice`:

* if a model meets ``tolerance`` in both loading classes, the cheapest such one, and no
  point ever needs a cell;
* else the cheapest model that meets it for monotonic loading; a point whose loading
  class turns to "reversal" (:class:`contfab.selection.indicators.Tracker`: a reversal of
  the deviator, or principal axes rotated by more than 15°) then has no model within the
  tolerance and **switches to a DEM cell** for the rest of the analysis;
* if no model meets it for monotonic loading, every point is a DEM cell (FE×DEM).

**Shadow cells** (``shadows`` = k > 0) check the bound on the scene's own cells: k model
points spread over the mesh also drive a cell through their committed increments, one cell
run per converged step (no probes, no Newton iterations); its stress does not enter the
analysis. Once the RMS over the steps so far of |R/P_model - R/P_cell| at a shadow exceeds
the tolerance, the measured bound is taken as not holding for these cells, and every model
point switches to a cell (``model_rejected_at_step``).

Tier 1 at least: the points report c. The indicators are updated after every converged
step, the switches made then, so a point runs its model through the step in which it
entered the reversal class.

**The switch.** The new cell is the prepared sample driven through the point's committed
strain and spin increments since the start, one cell increment per converged step
(:meth:`contfab.fexdem.registry.CellRegistry.add`): the cell the point would hold had it
been a DEM cell from the start along that path, which is the DEM's own state for it (c,
fabric and stress come out of the DEM, not out of the model). The model's state at the
switch differs from it by the model's error along the path; each switch records both
(``switches``: stress, R/P, c and fabric A of model and cell). The point's committed
stress and state are then the cell's, so the next step starts out of equilibrium by the
difference and its Newton iterations absorb it. Cost of a switch: the replay, one cell
run per converged step so far (without the three tangent probes and the Newton
iterations a cell running from the start would have had), and those extra iterations.

Stress unit and state columns as :class:`contfab.fexdem.material.DemMaterial` (gp, c, A,
Bc, Bs; a model point of tier t updates the first columns of its tier and carries the
rest, a cell's gp is its total deviatoric strain). Tangents: the model's algorithmic one
at model points, the cell's own (``probe``, three more cell runs) at cell points, the
isotropic elastic one of the cell's modulus where a probe fails. The spin tangent is the
model's exact one at model points and zero at cell points (their trials are DEM runs).
Cells run in this process (:class:`~contfab.fexdem.registry.CellRegistry`), without
checkpoints: an adaptive run is not resumable.
"""
from __future__ import annotations

import time
from dataclasses import asdict

import numpy as np

from contfab.fem.solver import ConvergenceError, NewtonOptions, Solver
from contfab.fexdem.cell import CellOptions
from contfab.fexdem.material import STATE_NAMES, elastic_modulus, initial_fields
from contfab.fexdem.registry import CellRegistry
from contfab.models import tiers
from contfab.models.tiers import spin_derivative
from contfab.params import Params
from contfab.selection.auto_tier import Choice, choose, load_table, params_for
from contfab.selection.indicators import Tracker
from contfab.tensors import isotropic_stiffness

DEM_PROBE = 0.1
"""Relative probe of the cells' own tangent (as :data:`contfab.fexdem.material.DEM_PROBE`)."""


def model_choice(tolerance: float, table=None) -> tuple[Choice | None, bool]:
    """(the model of the model points, None if every point needs a cell; whether points
    of the reversal class switch to cells); see the module doc."""
    table = load_table() if table is None else table
    mono = choose("monotonic", tolerance, table, min_tier=1)
    if not mono.met:
        return None, True
    rev = {r["model"]: r for r in table["reversal"]}
    both = [m for m in table["monotonic"] if m["tier"] >= 1 and m["error"] <= tolerance
            and m["model"] in rev and rev[m["model"]]["error"] <= tolerance]
    if not both:
        return mono, True
    best = min(both, key=lambda m: m["cost"])
    err = rev[best["model"]]["error"]
    return Choice("any", best["model"], best["tier"], best["params_file"],
                  max(best["error"], err), True,
                  f"{best['model']}: cheapest whose measured R/P errors ({best['error']:.3g} "
                  f"monotonic, {err:.3g} reversal) meet {tolerance:g}"), False


class AdaptiveMaterial:
    """Model points and DEM cells at the points of ``disc`` (see the module doc)."""

    state_names = STATE_NAMES

    def __init__(self, prepared: str, disc, params: Params, tolerance: float,
                 options: CellOptions, p_unit: float = 1.0, probe: float = DEM_PROBE,
                 modulus: float | None = None, table=None, shadows: int = 0):
        if not (isinstance(shadows, (int, np.integer)) and 0 <= shadows <= disc.npoints):
            raise ValueError(f"shadows = {shadows} out of range; accepted integers 0 .. "
                             f"{disc.npoints} (the points)")
        if not (np.isfinite(p_unit) and p_unit > 0):
            raise ValueError(f"p_unit = {p_unit} out of range; accepted (0, inf) (stress per P0)")
        if not (np.isfinite(probe) and probe > 0):
            raise ValueError(f"probe = {probe} out of range; accepted (0, inf)")
        self.choice, self.switching = model_choice(tolerance, table)
        self.tolerance, self.disc, self.p_unit, self.probe = tolerance, disc, float(p_unit), probe
        self.prepared = str(prepared)
        n = disc.npoints
        self.tier = 1 if self.choice is None else self.choice.tier
        base = params if self.choice is None else params_for(params, self.choice)
        self.params = base.with_tier(self.tier).replace("regularization", p_ref=self.p_unit)
        self._cols = len(tiers.STATE_NAMES[self.tier])
        self.modulus = elastic_modulus(prepared) if modulus is None else float(modulus)
        self._elastic = isotropic_stiffness(0.5 * self.modulus * self.p_unit,
                                            0.5 * self.modulus * self.p_unit)
        self.registry = CellRegistry(prepared, [], options)
        self.is_cell = np.zeros(n, bool)
        self.history: list[tuple[np.ndarray, np.ndarray]] = []
        self.tracker: Tracker | None = None
        self.switches: list[dict] = []
        self.failures: list[str] = []
        self.last = None
        self._inc = None
        self.cpu = {"model": 0.0, "cells": 0.0, "switch": 0.0, "shadows": 0.0}
        self.cell_runs = 0
        self.model_updates = 0
        self.shadow_ids = (np.unique(np.linspace(0, n - 1, shadows).round().astype(np.int64))
                           if shadows and self.choice is not None else np.zeros(0, np.int64))
        self.shadows = CellRegistry(prepared, self.shadow_ids, options)
        self.shadow_sq = np.zeros(len(self.shadow_ids))
        self.shadow_steps = 0
        self.rejected_at: int | None = None
        if self.choice is None:
            self.registry.add(range(n), [()] * n, 0)
            self.is_cell[:] = True

    def initial(self) -> tuple[np.ndarray, np.ndarray]:
        """(stress (n, 3), state (n, 5)) of the prepared sample at every point."""
        stress0, state0 = initial_fields(self.prepared, self.disc.npoints, self.p_unit)
        self.tracker = Tracker(stress0, self.params.tier1.c_star)
        return stress0, state0

    def update(self, stress_n, state_n, dstrain, dspin) -> tiers.UpdateResult:
        stress_n = np.ascontiguousarray(stress_n, dtype=float)
        state_n = np.ascontiguousarray(state_n, dtype=float)
        dstrain = np.ascontiguousarray(dstrain, dtype=float)
        dspin = np.ascontiguousarray(dspin, dtype=float)
        n = len(stress_n)
        stress, state = np.empty((n, 3)), state_n.copy()
        tangent, status = np.empty((n, 3, 3)), np.zeros(n, np.int8)
        model = np.flatnonzero(~self.is_cell)
        if len(model):
            cpu0 = time.process_time()
            k = self._cols
            out = tiers.update(self.tier, stress_n[model], state_n[model, :k], dstrain[model],
                               dspin[model], self.params)
            stress[model], state[model, :k] = out.stress, out.state
            tangent[model], status[model] = out.tangent, out.status
            self.cpu["model"] += time.process_time() - cpu0
            self.model_updates += len(model)
        cells = np.flatnonzero(self.is_cell)
        self.failures = []
        if len(cells):
            res = self.registry.trial(cells, dstrain[cells], dspin[cells], self.probe)
            self.cpu["cells"] += float(res["cpu"].sum())
            self.cell_runs += 4 * len(cells)
            stress[cells] = res["stress"] * self.p_unit
            dgp = np.hypot(dstrain[cells, 0] - dstrain[cells, 1], dstrain[cells, 2])
            state[cells, 0] = state_n[cells, 0] + dgp
            state[cells, 1:] = res["state"]
            own = np.all(np.isfinite(res["tangent"]), axis=(1, 2))
            tangent[cells] = np.where(own[:, None, None], res["tangent"] * self.p_unit,
                                      self._elastic)
            status[cells] = 1
            for j, msg in sorted(res["errors"].items()):
                k = cells[j]
                stress[k], state[k], status[k] = stress_n[k], state_n[k], -1
                self.failures.append(f"DEM cell at point {k}: {msg}")
        self._inc = (dstrain, dspin)
        self.last = tiers.UpdateResult(stress, state, tangent, status)
        return self.last

    def spin_tangent(self, stress_n, state_n, dstrain, dspin, res) -> np.ndarray:
        """∂σ/∂ω: the model's exact one at model points, zero at cell points."""
        g = spin_derivative(res.stress, res.tangent, dstrain)
        g[self.is_cell] = 0.0
        return g

    def commit(self, accepted, fe_step: int, stress_n: np.ndarray) -> np.ndarray:
        """Promote the cells' latest trial (the solver's ``accepted`` state), update the
        indicators from ``stress_n`` (the step's start), switch the points whose class no
        model meets (module doc: their committed stress and state become the cell's, in
        place); returns the switched points."""
        if self.last is None or accepted.stress is not self.last.stress:
            raise RuntimeError("the converged step is not the latest trial of the material "
                               "(line search or spin differences enabled?)")
        self.registry.commit(fe_step)
        dstrain, dspin = self._inc
        self.history.append((dstrain.copy(), dspin.copy()))
        c = accepted.state[:, STATE_NAMES.index("c")]
        self.tracker.update(stress_n, accepted.stress, dstrain, accepted.status >= 1, c)
        if self._shadow_rejects(accepted, fe_step):
            new = np.flatnonzero(~self.is_cell)
        elif not self.switching:
            return np.zeros(0, np.int64)
        else:
            new = np.flatnonzero(self.tracker.reversal_class() & ~self.is_cell)
        if len(new):
            self._switch(new, accepted, fe_step)
        return new

    def _shadow_rejects(self, accepted, fe_step: int) -> bool:
        """Advance the shadow cells by their points' committed increments; True when a
        shadow's RMS R/P error of the model over the steps so far exceeds the tolerance
        (module doc), the first time."""
        live = ~self.is_cell[self.shadow_ids]
        if self.rejected_at is not None or not live.any():
            return False
        ids = self.shadow_ids
        dstrain, dspin = self._inc
        cpu0 = time.process_time()
        res = self.shadows.trial(ids, dstrain[ids], dspin[ids])
        self.shadows.commit(fe_step)
        self.cpu["shadows"] += time.process_time() - cpu0
        self.cell_runs += len(ids)
        if not res["ok"].all():
            raise RuntimeError(f"shadow cells failed: {res['errors']}")
        model = _ratio(accepted.stress[ids] / self.p_unit)
        self.shadow_sq += (model - _ratio(res["stress"])) ** 2
        self.shadow_steps += 1
        rms = np.sqrt(self.shadow_sq / self.shadow_steps)
        if np.any(rms[live] > self.tolerance):
            self.rejected_at = fe_step
            return True
        return False

    def _switch(self, points: np.ndarray, accepted, fe_step: int) -> None:
        histories = [[(de[k], dw[k]) for de, dw in self.history] for k in points]
        cpu0 = time.process_time()
        res = self.registry.add(points, histories, fe_step)
        cpu = time.process_time() - cpu0
        self.cpu["switch"] += cpu
        self.cell_runs += len(points) * len(self.history)
        ind = self.tracker
        for j, k in enumerate(points):
            model_s, cell_s = accepted.stress[k] / self.p_unit, res["stress"][j]
            self.switches.append({
                "point": int(k), "step": fe_step, "rotation_deg": float(np.degrees(ind.rotation[k])),
                "reversal": bool(ind.reversal[k]), "replayed_increments": len(self.history),
                "replay_cpu_s": float(res["cpu"][j]),
                "model": _summary(model_s, accepted.state[k, 1:], self._cols),
                "cell": _summary(cell_s, res["state"][j], 5)})
        accepted.stress[points] = res["stress"] * self.p_unit
        accepted.state[points, 1:] = res["state"]
        accepted.tangent[points] = self._elastic
        accepted.spin_tangent[points] = 0.0
        self.is_cell[points] = True

    def report(self) -> dict:
        """The choice, the switches and what they cost (module doc)."""
        n = len(self.is_cell)
        sw = self.switches
        gap = {key: [abs(s["model"][key] - s["cell"][key]) for s in sw
                     if s["model"][key] is not None and s["cell"][key] is not None]
               for key in ("P", "R_over_P", "c", "A")}
        return {"tolerance": self.tolerance,
                "model": None if self.choice is None else asdict(self.choice),
                "switching": self.switching, "points": n,
                "cell_points": int(self.is_cell.sum()), "cell_share": float(self.is_cell.mean()),
                "model_updates": self.model_updates, "cell_runs": self.cell_runs,
                "cpu_s": dict(self.cpu),
                "shadows": {"points": self.shadow_ids.tolist(), "steps": self.shadow_steps,
                            "rms_R_over_P_error": (np.sqrt(self.shadow_sq / self.shadow_steps)
                                                   .tolist() if self.shadow_steps else []),
                            "model_rejected_at_step": self.rejected_at},
                "switch_mismatch_max": {k: (max(v) if v else None) for k, v in gap.items()},
                "switch_mismatch_mean": {k: (float(np.mean(v)) if v else None)
                                         for k, v in gap.items()},
                "switches": sw}


def _ratio(stress: np.ndarray) -> np.ndarray:
    """R/P of Voigt stresses (k, 3), tension positive."""
    p = -0.5 * (stress[:, 0] + stress[:, 1])
    return np.hypot(0.5 * (stress[:, 0] - stress[:, 1]), stress[:, 2]) / p


def _summary(stress: np.ndarray, state: np.ndarray, cols: int) -> dict:
    """P, R/P, c and A (None where the model carries no fabric) of a stress in P0 and a
    state (c, A, Bc, Bs)."""
    p = -0.5 * (stress[0] + stress[1])
    r = float(np.hypot(0.5 * (stress[0] - stress[1]), stress[2]))
    return {"sxx": float(stress[0]), "syy": float(stress[1]), "sxy": float(stress[2]),
            "P": float(p), "R_over_P": float(r / p) if p > 0 else None, "c": float(state[0]),
            "A": float(state[1]) if cols >= 3 else None}


class AdaptiveSolver(Solver):
    """The FEM solver with :class:`AdaptiveMaterial`: the material's commit (cells, the
    indicators, the switches) after every converged step."""

    def __init__(self, disc, material: AdaptiveMaterial, options: NewtonOptions):
        if options.line_search != 0:
            raise ValueError(f"adaptive FE×DEM needs line_search = 0 (each cell trial is a DEM "
                             f"run; the accepted one must be the last), got {options.line_search}")
        stress0, state0 = material.initial()
        super().__init__(disc, material, stress0, state0, options)

    def run_stage(self, stage, start=None):
        steps = super().run_stage(stage, start)
        stress_n = self.committed.stress.copy()
        try:
            for record in steps:
                self.material.commit(self.committed, len(self.records), stress_n)
                stress_n = self.committed.stress.copy()
                yield record
        except ConvergenceError as exc:
            cells = self.material.failures
            if not cells:
                raise
            raise ConvergenceError(f"{exc}\nfailed DEM cells: " + "; ".join(cells[:3]),
                                   exc.last, exc.attempts) from None


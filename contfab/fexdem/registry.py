"""The cells one worker owns: committed states, the latest trial of each, checkpoints.

A :class:`CellRegistry` lives where its cells run (in-process, in a worker process of
a :class:`~contfab.fexdem.backends.ProcessCells` pool, or as a dask actor), so particle
arrays never travel between steps: only strain increments go in and stresses come out.

* :meth:`trial` runs an increment on a *copy* of each cell's committed state and keeps
  that copy as the cell's trial (replacing the previous trial); the committed state is
  untouched, so any number of Newton iterations leave no trace.
* :meth:`commit` promotes the trials of a converged step and writes each cell's
  committed state to ``ckdir/cell_<id>_<step mod 2>.npz`` (:func:`dem.checkpoint.save`,
  atomic), tagged with the step number: two generations, so the files of step k are
  still there while those of step k + 1 are written (a run killed between the cells'
  and the FE field's checkpoint of a step resumes from the previous one). A registry
  made with ``resume=k`` starts from step k's files (k = 0: the prepared sample), so a
  lost worker's cells restart from their last converged step.

With ``probe`` > 0, :meth:`trial` also returns each cell's own tangent at its increment
(:func:`~contfab.fexdem.cell.cell_tangent`, three more runs per cell; NaN where a probe
fails, the caller then falls back to another tangent).

:meth:`add` makes cells that start later than the analysis (adaptive FE×DEM,
:mod:`contfab.fexdem.adaptive`): each is a clone of the prepared sample driven through a
given history of committed increments, one :func:`~contfab.fexdem.cell.advance_cell` per
increment, i.e. bitwise the cell a point would hold had it been a DEM cell from the start
with that history.

A cell that fails (no equilibrium within its budget, a DEM divergence) reports its
message instead of a stress; the caller turns it into a failed point.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from dem import checkpoint
from dem.integrator import DivergenceError
from contfab.fexdem.cell import (CELL_STATE, CellNotRelaxed, CellOptions, IncrementTooLarge,
                                 advance_cell, cell_tangent, measure_cell, start_cell)


def cell_file(ckdir: str | Path, cell: int, fe_step: int) -> Path:
    """Cell ``cell``'s checkpoint of converged step ``fe_step`` (module doc)."""
    return Path(ckdir) / f"cell_{cell:06d}_{fe_step % 2}.npz"


class CellRegistry:
    """Cells ``ids`` cloned from the prepared sample ``prepared`` (see the module doc)."""

    def __init__(self, prepared: str, ids, options: CellOptions, ckdir: str | None = None,
                 resume: int = 0):
        self.ids = [int(i) for i in ids]
        self.options = options
        self.ckdir = ckdir
        state, self.dyn, _, _ = checkpoint.load(prepared)
        self.sample = state
        if resume and ckdir is None:
            raise ValueError(f"resume from step {resume} needs a checkpoint directory")
        self.committed, self.step = {}, {}
        for i in self.ids:
            if resume:
                f = cell_file(ckdir, i, resume)
                self.committed[i], _, _, meta = checkpoint.load(f)
                if int(meta["fe_step"]) != resume:
                    raise ValueError(f"cell checkpoint {f} is of step {meta['fe_step']}, not of "
                                     f"the step {resume} to resume from")
            else:
                self.committed[i] = start_cell(state.copy(), self.dyn)
            self.step[i] = resume
        self.trials: dict = {}

    def steps(self) -> dict[int, int]:
        """The converged FE step each cell's committed state belongs to."""
        return dict(self.step)

    def trial(self, ids, dstrain: np.ndarray, dspin: np.ndarray, probe: float = 0.0) -> dict:
        """Run one increment per cell on a copy of its committed state.

        Returns arrays over ``ids``: ``stress`` (k, 3) in P0, ``state`` (k, 4) (c, A, Bc,
        Bs), ``steps`` (k, 2) (strain, relaxation steps), ``ok`` (k,) bool, ``errors``
        {position in ids: message}, and ``tangent`` (k, 3, 3) in P0 (zeros unless
        ``probe`` > 0, the relative probe of the cells' tangent; module doc); ``cpu`` (k,)
        the CPU time of each cell's runs (this thread's, in s) and ``wall`` the call's
        wall time here (:mod:`contfab.fexdem.profile`).
        """
        k = len(ids)
        out = {"stress": np.zeros((k, 3)), "state": np.zeros((k, len(CELL_STATE))),
               "steps": np.zeros((k, 2), np.int64), "ok": np.ones(k, bool), "errors": {},
               "tangent": np.zeros((k, 3, 3)), "cpu": np.zeros(k)}
        wall0 = time.perf_counter()
        for j, i in enumerate(ids):
            cpu0 = time.thread_time()
            self._trial_cell(j, int(i), dstrain[j], float(dspin[j]), probe, out)
            out["cpu"][j] = time.thread_time() - cpu0
        out["wall"] = time.perf_counter() - wall0
        return out

    def _trial_cell(self, j: int, i: int, dstrain, dspin: float, probe: float, out: dict) -> None:
        """Cell ``i``'s trial into row ``j`` of ``out`` (see :meth:`trial`)."""
        st = self.committed[i].copy()
        try:
            res = advance_cell(st, self.dyn, dstrain, dspin, self.options)
        except (CellNotRelaxed, IncrementTooLarge, DivergenceError) as exc:
            out["ok"][j] = False
            out["errors"][j] = str(exc)
            self.trials.pop(i, None)
            return
        self.trials[i] = st
        out["stress"][j], out["state"][j] = res.stress, res.state
        out["steps"][j] = (res.strain_steps, res.relax_steps)
        if probe > 0:
            try:
                out["tangent"][j] = cell_tangent(self.committed[i], self.dyn, dstrain, dspin,
                                                 res.stress, self.options, probe)
            except (CellNotRelaxed, IncrementTooLarge, DivergenceError):
                out["tangent"][j] = np.nan

    def add(self, ids, histories, fe_step: int) -> dict:
        """New cells ``ids`` (not yet held), each the prepared sample driven through its
        history: a sequence of (dstrain (3,), dspin) committed increments (module doc),
        the last that of converged step ``fe_step``.

        Returns arrays over ``ids`` as :meth:`trial` (``stress``, ``state``, ``steps``,
        ``cpu``; no tangent); a cell that fails is not added and raises its error.
        """
        k = len(ids)
        out = {"stress": np.zeros((k, 3)), "state": np.zeros((k, len(CELL_STATE))),
               "steps": np.zeros((k, 2), np.int64), "cpu": np.zeros(k)}
        for j, (i, history) in enumerate(zip(ids, histories)):
            i = int(i)
            if i in self.committed:
                raise ValueError(f"cell {i} is already held")
            cpu0 = time.thread_time()
            st = start_cell(self.sample.copy(), self.dyn)
            res = None
            for dstrain, dspin in history:
                res = advance_cell(st, self.dyn, dstrain, float(dspin), self.options)
                out["steps"][j] += (res.strain_steps, res.relax_steps)
            if res is None:
                res_stress, res_state = measure_cell(st)
            else:
                res_stress, res_state = res.stress, res.state
            out["stress"][j], out["state"][j] = res_stress, res_state
            out["cpu"][j] = time.thread_time() - cpu0
            self.committed[i] = st
            self.step[i] = fe_step
            self.ids.append(i)
        return out

    def commit(self, fe_step: int) -> dict:
        """Promote every cell's latest trial and checkpoint it as step ``fe_step``; returns
        the call's ``wall`` time and this thread's ``cpu`` time here (s)."""
        wall0, cpu0 = time.perf_counter(), time.thread_time()
        missing = [i for i in self.ids if i not in self.trials]
        if missing:
            raise RuntimeError(f"commit of step {fe_step} without a trial for cells {missing[:5]}")
        for i in self.ids:
            self.committed[i] = self.trials.pop(i)
            self.step[i] = fe_step
            if self.ckdir is not None:
                checkpoint.save(cell_file(self.ckdir, i, fe_step), self.committed[i], self.dyn, None,
                                {"fe_step": fe_step, "cell": i})
        return {"wall": time.perf_counter() - wall0, "cpu": time.thread_time() - cpu0}

    def ping(self) -> int:
        return len(self.ids)

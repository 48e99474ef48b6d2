"""Where an FE×DEM run's time goes, and a cost model measured from it.

A :class:`Ledger` is filled while the run goes (by :class:`~contfab.fexdem.backends.Cells`,
:class:`~contfab.fexdem.material.DemMaterial` and
:class:`~contfab.fexdem.material.FexdemSolver`):

* per cell call (``trial``, ``commit``) to the B blocks: the main process's wall time
  from the first dispatch to the last result; per block the worker's wall time inside
  the method; per cell (trials) the CPU time of its runs in the worker's thread
  (``time.thread_time``: this cell's DEM work, the tangent probes included); the bytes
  of the arguments sent and of the results received, and the main process's time to
  pickle both once (a lower bound of the serialization cost: the transport pickles on
  one side and unpickles on the other);
* on the main process: the time inside the material update outside the cell call
  (the tier tangent, merging), the cells' commits, the FE field checkpoints, and the
  stage's wall time. The FE solve (assembly, factorization, residuals, the solver's
  bookkeeping) is the stage's wall time minus all of those.

Per trial call, ``overhead`` = main wall − the slowest block's worker wall (transport,
scheduling, serialization, waiting) and ``imbalance`` = slowest − mean block wall.

The cost model (:func:`predict`) replays the measured per-cell CPU times of every trial
on W workers:

    T(W) = T_main + Σ_trials [ max_b Σ_{i ∈ b} t_i + o(W) ] + Σ_commits [ t_c ⌈n/W⌉ + o(W) ],
    o(W) = o_0 + o_1 W  (W = 1 in-process: o = 0)

with blocks b of ``layout`` (:func:`blocks_of`), t_i the measured CPU time of cell i in
that trial, T_main the main thread's CPU time outside the cell calls (FE solve, tier
tangent, checkpoints) and t_c a cell's commit time (worker wall). Assumptions: a cell
costs on a worker what it cost where it was measured (one core per worker, no memory-
bandwidth contention), the per-call overhead grows linearly with the number of blocks
(the main process dispatches and collects them one after the other), the bytes are
negligible (a cell sends 4 and receives ~20 floats per trial, measured), the FE part
stays on one core, and the iterations are those of the measured run (the result does
not depend on W).
"""
from __future__ import annotations

import os
import pickle
import time
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

LAYOUTS = ("interleaved", "contiguous")
MAIN_PARTS = ("stage", "update", "trial", "commit", "checkpoint")
"""What the main thread's CPU time is split by (``Ledger.main_cpu``)."""


def blocks_of(n: int, blocks: int, layout: str = "interleaved") -> list[np.ndarray]:
    """Cells 0..n-1 in ``blocks`` blocks: ``interleaved`` (cell i in block i mod B: the
    points of one region, e.g. a shear band, spread over all blocks) or ``contiguous``."""
    if layout not in LAYOUTS:
        raise ValueError(f"layout {layout!r} unknown; accepted {LAYOUTS}")
    if not (isinstance(blocks, int) and blocks >= 1):
        raise ValueError(f"blocks = {blocks} out of range; accepted integers >= 1")
    b = max(1, min(blocks, n))
    if layout == "contiguous":
        return [ids for ids in np.array_split(np.arange(n), b) if len(ids)]
    return [np.arange(k, n, b) for k in range(b)]


def pickled(obj) -> tuple[int, float]:
    """(bytes, seconds) of pickling ``obj`` once."""
    t0 = time.perf_counter()
    size = len(pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL))
    return size, time.perf_counter() - t0


@dataclass
class Ledger:
    """The run's measured costs (module doc); all times in s."""

    n: int
    blocks: int
    trial_wall: list = field(default_factory=list)
    trial_block_wall: list = field(default_factory=list)
    trial_cell_cpu: list = field(default_factory=list)
    commit_wall: list = field(default_factory=list)
    commit_block_wall: list = field(default_factory=list)
    bytes_sent: int = 0
    bytes_received: int = 0
    pickle_s: float = 0.0
    wall: dict = field(default_factory=lambda: dict.fromkeys(MAIN_PARTS, 0.0))
    main_cpu: dict = field(default_factory=lambda: dict.fromkeys(MAIN_PARTS, 0.0))
    load: list = field(default_factory=list)

    @contextmanager
    def timed(self, part: str):
        """Add the block's wall time and the main thread's CPU time to ``part``."""
        w0, c0 = time.perf_counter(), time.thread_time()
        try:
            yield
        finally:
            self.wall[part] += time.perf_counter() - w0
            self.main_cpu[part] += time.thread_time() - c0

    def call(self, method: str, wall: float, results: list, sent: tuple) -> None:
        """Record one call to all blocks: its main wall time, the blocks' results and
        the arguments sent (one tuple per block)."""
        size_out, t_out = pickled(sent)
        size_in, t_in = pickled(results)
        self.bytes_sent += size_out
        self.bytes_received += size_in
        self.pickle_s += t_out + t_in
        if method == "trial":
            self.trial_wall.append(wall)
            self.trial_block_wall.append([r["wall"] for r in results])
            self.trial_cell_cpu.append(None)      # filled by the caller in cell order
        else:
            self.commit_wall.append(wall)
            self.commit_block_wall.append([r["wall"] for r in results])

    def mark_load(self) -> None:
        """Record the 1-minute load average now (the machine's other work)."""
        self.load.append(round(os.getloadavg()[0], 2))

    def _main(self, d: dict) -> dict:
        """``d`` (wall or main CPU by part) as the FE solve, the material update's own
        work, the cell calls (dispatch and wait) and the checkpoints."""
        return {"fe_solve": d["stage"] - d["update"] - d["commit"] - d["checkpoint"],
                "material_main": d["update"] - d["trial"],
                "cell_calls": d["trial"] + d["commit"], "checkpoint": d["checkpoint"]}

    def summary(self) -> dict:
        """Totals by category (module doc)."""
        tw = np.array(self.trial_wall)
        bmax = np.array([max(b) for b in self.trial_block_wall])
        bmean = np.array([np.mean(b) for b in self.trial_block_wall])
        return {
            "load_1min": self.load, "cells": self.n, "blocks": self.blocks,
            "stage_s": self.wall["stage"], "main_wall_s": self._main(self.wall),
            "main_cpu_s": self._main(self.main_cpu),
            "trials": {"calls": len(tw), "wall_s": float(tw.sum()),
                       "cell_cpu_s": float(sum(np.sum(c) for c in self.trial_cell_cpu)),
                       "slowest_block_s": float(bmax.sum()), "mean_block_s": float(bmean.sum()),
                       "overhead_s": float(np.sum(tw - bmax)),
                       "imbalance_s": float(np.sum(bmax - bmean))},
            "commits": {"calls": len(self.commit_wall), "wall_s": float(np.sum(self.commit_wall)),
                        "slowest_block_s": float(sum(max(b) for b in self.commit_block_wall))},
            "bytes_sent": self.bytes_sent, "bytes_received": self.bytes_received,
            "pickle_s": self.pickle_s}

    def serial_part(self) -> float:
        """T_main: the main thread's CPU time outside the cell calls (module doc)."""
        m = self._main(self.main_cpu)
        return m["fe_solve"] + m["material_main"] + m["checkpoint"]

    def commit_per_cell(self) -> float:
        """t_c: a commit's worker time per cell."""
        return float(sum(np.sum(b) for b in self.commit_block_wall)) / max(
            1, self.n * len(self.commit_block_wall))


def predict(ledger: Ledger, workers: int, overhead: tuple[float, float] = (0.0, 0.0),
            layout: str = "interleaved") -> float:
    """T(W) of the cost model (module doc) from ``ledger``'s measured costs;
    ``overhead`` = (o_0, o_1) in s."""
    o = 0.0 if workers == 1 else overhead[0] + overhead[1] * workers
    blocks = blocks_of(ledger.n, workers, layout)
    cells = sum(max(float(np.sum(cpu[b])) for b in blocks) + o for cpu in ledger.trial_cell_cpu)
    commits = len(ledger.commit_wall) * (ledger.commit_per_cell() * int(np.ceil(ledger.n / workers)) + o)
    return ledger.serial_part() + cells + commits


CALL_OVERHEAD = (0.0, 1.4e-3)
"""(o_0, o_1) of the cost model's per-call overhead (s): a no-op call to B dask actor
blocks on 2 local workers took 2.2, 14, 48, 86 ms for B = 2, 8, 32, 64 (load 10;
docs/fexdem.md): the client dispatches and collects the blocks one after the other."""
PREDICT_WORKERS = (1, 2, 64, 256)


def save(ledger: Ledger, path) -> None:
    """The ledger's per-call arrays as ``path`` (npz, atomic), for :func:`load`."""
    from dem.fileio import atomic_path
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, cell_cpu=np.array(ledger.trial_cell_cpu).reshape(-1, ledger.n),
                     trial_wall=np.array(ledger.trial_wall),
                     trial_block_wall=np.array(ledger.trial_block_wall),
                     commit_wall=np.array(ledger.commit_wall),
                     commit_block_wall=np.array(ledger.commit_block_wall),
                     scalars=np.array([ledger.n, ledger.blocks, ledger.bytes_sent,
                                       ledger.bytes_received, ledger.pickle_s]),
                     wall=np.array([ledger.wall[k] for k in MAIN_PARTS]),
                     main_cpu=np.array([ledger.main_cpu[k] for k in MAIN_PARTS]))


def load(path) -> Ledger:
    """The ledger :func:`save` wrote."""
    with np.load(path) as z:
        n, blocks, sent, received, pickle_s = z["scalars"]
        return Ledger(int(n), int(blocks), list(z["trial_wall"]),
                      [list(b) for b in z["trial_block_wall"]], list(z["cell_cpu"]),
                      list(z["commit_wall"]), [list(b) for b in z["commit_block_wall"]],
                      int(sent), int(received), float(pickle_s),
                      dict(zip(MAIN_PARTS, map(float, z["wall"]))),
                      dict(zip(MAIN_PARTS, map(float, z["main_cpu"]))))


def costs(cells, path=None) -> dict:
    """The ledger's summary of ``cells``, the per-call round trip measured now, and the
    cost model's T(W) for :data:`PREDICT_WORKERS` (interleaved and contiguous blocks);
    the ledger is saved to ``path`` if given."""
    ledger = cells.ledger
    out = ledger.summary()
    out["round_trip_s"] = cells.round_trip()
    out["predicted_stage_s"] = {layout: {w: predict(ledger, w, CALL_OVERHEAD, layout)
                                         for w in PREDICT_WORKERS} for layout in LAYOUTS}
    if path is not None:
        save(ledger, path)
    return out

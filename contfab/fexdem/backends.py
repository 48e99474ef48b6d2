"""Where the cells run: in-process, in spawned processes, or on a dask cluster.

The cells 0..n-1 are split into blocks (:func:`~contfab.fexdem.profile.blocks_of`:
interleaved by default, so the cells of one region, e.g. a band whose cells take longer
increments, are spread over all blocks), one
:class:`~contfab.fexdem.registry.CellRegistry` per block, made as a *resident object* of
the campaign executor (:meth:`contfab.executor.Executor.resident`) and kept where it
runs for the whole analysis (particle arrays are never re-sent): ``SerialCells`` holds
one registry in-process (serial executor); ``ProcessCells`` starts ``workers``
spawned processes, one registry each (pool executor); ``DaskCells`` places one
registry per worker of a ``dask.distributed`` cluster as an actor (dask executor on
the caller's client).

A block whose worker dies (:class:`contfab.executor.WorkerLost`: process killed, dask
worker lost) is recovered: a new registry is made for it (dask: on any live worker)
from the cells' checkpoints of the last converged step (``ckdir``; ``resume=k`` starts
all blocks from step k's), and the
interrupted call is repeated. A trial is a pure function of the committed state and
the increment, so the numbers are the same as without the failure. Without ``ckdir``
there is nothing to recover from and the loss is an error.

All backends return :meth:`trial` results over all cells: ``stress`` (n, 3) in P0,
``state`` (n, 4), ``steps`` (n, 2), ``ok`` (n,), ``tangent`` (n, 3, 3) in P0 (with
``probe`` > 0), ``errors`` {cell: message}.

Every call is timed into :attr:`Cells.ledger` (:class:`~contfab.fexdem.profile.Ledger`).
"""
from __future__ import annotations

import time

import numpy as np
from tqdm import tqdm

from contfab.executor import DaskExecutor, Executor, PoolExecutor, SerialExecutor, WorkerLost
from contfab.fexdem.cell import CellOptions
from contfab.fexdem.profile import Ledger, blocks_of
from contfab.fexdem.registry import CellRegistry

MAX_RECOVERIES = 3
"""Restarts of one block within one call before the loss is an error."""


class Cells:
    """Blocks of cells as resident registries of ``executor``: dispatch, merge, recovery."""

    def __init__(self, prepared: str, n: int, options: CellOptions, executor: Executor,
                 blocks: int, ckdir: str | None = None, resume: int = 0,
                 progress: bool = False, layout: str = "interleaved"):
        if n < 1:
            raise ValueError(f"number of cells n = {n} out of range; accepted n >= 1")
        self.prepared, self.n, self.options = str(prepared), n, options
        self.executor = executor
        self.ckdir = None if ckdir is None else str(ckdir)
        self.progress = progress
        self.blocks = blocks_of(n, blocks, layout)
        self.ledger = Ledger(n, len(self.blocks))
        self.recoveries = 0
        self.step = int(resume)
        self.residents = [None] * len(self.blocks)
        for b in range(len(self.blocks)):
            self._start(b)

    def _start(self, b: int) -> None:
        """Make block ``b``'s registry from the last committed step's checkpoints."""
        old = self.residents[b]
        if old is not None:
            old.close()
        self.residents[b] = self.executor.resident(
            CellRegistry, (self.prepared, self.blocks[b], self.options, self.ckdir, self.step), b)

    def _submit(self, b: int, method: str, args: tuple):
        """Send a call to block ``b``; returns a handle whose ``result()`` is its value."""
        return self.residents[b].call(method, *args)

    def _call(self, method: str, args_of, bar=None) -> list:
        """Call ``method(*args_of(b))`` on every block concurrently, recovering lost blocks;
        trials and commits are timed into the ledger."""
        if method not in ("trial", "commit"):
            return self._dispatch(method, args_of, bar)
        with self.ledger.timed(method):
            t0 = time.perf_counter()
            results = self._dispatch(method, args_of, bar)
            self.ledger.call(method, time.perf_counter() - t0, results,
                             tuple(args_of(b) for b in range(len(self.blocks))))
        return results

    def _dispatch(self, method: str, args_of, bar=None) -> list:
        """``method(*args_of(b))`` on every block concurrently, recovering lost blocks."""
        handles = {b: self._submit(b, method, args_of(b)) for b in range(len(self.blocks))}
        results = [None] * len(self.blocks)
        for b in range(len(self.blocks)):
            for attempt in range(MAX_RECOVERIES + 1):
                try:
                    results[b] = handles[b].result()
                    break
                except WorkerLost as exc:
                    if self.ckdir is None or method == "commit" or attempt == MAX_RECOVERIES:
                        ids = self.blocks[b]
                        raise WorkerLost(f"cells {ids[0]}..{ids[-1]}: {exc}") from exc
                    self._start(b)
                    self.recoveries += 1
                    handles[b] = self._submit(b, method, args_of(b))
            if bar is not None:
                bar.update(len(self.blocks[b]))
        return results

    def trial(self, dstrain: np.ndarray, dspin: np.ndarray, probe: float = 0.0) -> dict:
        """One increment per cell on copies of the committed states (see the module doc)."""
        with tqdm(total=self.n, desc="DEM cells", unit="cell", leave=False,
                  disable=not self.progress) as bar:
            parts = self._call("trial", lambda b: (self.blocks[b], dstrain[self.blocks[b]],
                                                   dspin[self.blocks[b]], probe), bar)
        out = {"stress": np.zeros((self.n, 3)), "state": np.zeros((self.n, 4)),
               "steps": np.zeros((self.n, 2), np.int64), "ok": np.ones(self.n, bool),
               "tangent": np.zeros((self.n, 3, 3)), "cpu": np.zeros(self.n), "errors": {}}
        for ids, part in zip(self.blocks, parts):
            for key in ("stress", "state", "steps", "ok", "tangent", "cpu"):
                out[key][ids] = part[key]
            out["errors"].update({int(ids[j]): msg for j, msg in part["errors"].items()})
        self.ledger.trial_cell_cpu[-1] = out["cpu"]
        return out

    def commit(self, fe_step: int) -> None:
        """Promote the latest trials of every cell (a converged FE step) and checkpoint them."""
        self._call("commit", lambda b: (fe_step,))
        self.step = fe_step

    def round_trip(self, rounds: int = 20) -> float:
        """Mean wall time (s) of a no-op call to every block: the per-call overhead."""
        t0 = time.perf_counter()
        for _ in range(rounds):
            self._dispatch("ping", lambda b: ())
        return (time.perf_counter() - t0) / rounds

    def steps(self) -> np.ndarray:
        """(n,) the converged step each cell's committed state belongs to."""
        out = np.zeros(self.n, np.int64)
        for part in self._call("steps", lambda b: ()):
            for i, s in part.items():
                out[i] = s
        return out

    def close(self) -> None:
        """Release the registries and the executor's workers."""
        for r in self.residents:
            if r is not None:
                r.close()
        self.residents = [None] * len(self.blocks)
        self.executor.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class SerialCells(Cells):
    """All cells in this process (the reference the other backends must reproduce)."""

    def __init__(self, prepared, n, options, ckdir=None, resume=0, progress=False):
        super().__init__(prepared, n, options, SerialExecutor(), 1, ckdir, resume, progress)


class ProcessCells(Cells):
    """``workers`` spawned processes, one registry (block) each."""

    def __init__(self, prepared, n, options, workers=2, ckdir=None, resume=0, progress=False,
                 layout="interleaved"):
        super().__init__(prepared, n, options, PoolExecutor(workers), workers, ckdir, resume,
                         progress, layout)


class DaskCells(Cells):
    """One registry actor per block on a dask.distributed cluster (``client``)."""

    def __init__(self, prepared, n, options, client, blocks=None, ckdir=None, resume=0,
                 progress=False, layout="interleaved"):
        workers = list(client.scheduler_info()["workers"])
        if not workers:
            raise ValueError("the dask cluster has no workers")
        super().__init__(prepared, n, options, DaskExecutor(len(workers), client=client),
                         blocks or len(workers), ckdir, resume, progress, layout)

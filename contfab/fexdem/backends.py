"""Where the cells run: in-process, a persistent process pool, or a dask cluster.

Every backend splits the cells 0..n-1 into contiguous blocks, one
:class:`~contfab.fexdem.registry.CellRegistry` per block, resident where it runs for
the whole analysis (particle arrays are never re-sent): ``SerialCells`` holds one
registry in-process; ``ProcessCells`` starts ``workers`` spawned processes (spawn,
not fork: forking after OpenMP/numba threads started can hang, ENGINEERING.md), each
serving one registry over a pipe; ``DaskCells`` places one registry per worker of a
``dask.distributed`` cluster as an actor.

A block whose worker dies (process killed, dask worker lost) is recovered: a new
registry is started for it (dask: on any live worker) from the cells' checkpoints of
the last converged step (``ckdir``), and the interrupted call is repeated. A trial is
a pure function of the committed state and the increment, so the numbers are the same
as without the failure. Without ``ckdir`` there is nothing to recover from and the
loss is an error.

All backends return :meth:`trial` results over all cells: ``stress`` (n, 3) in P0,
``state`` (n, 4), ``steps`` (n, 2), ``ok`` (n,), ``errors`` {cell: message}.
"""
from __future__ import annotations

import multiprocessing
import traceback
from abc import ABC, abstractmethod

import numpy as np
from tqdm import tqdm

from contfab.fexdem.cell import CellOptions
from contfab.fexdem.registry import CellRegistry

MAX_RECOVERIES = 3
"""Restarts of one block within one call before the loss is an error."""


class WorkerLost(RuntimeError):
    """A block's worker died and could not be recovered."""


class Cells(ABC):
    """Common front of the backends: blocks, dispatch, merge, recovery."""

    def __init__(self, prepared: str, n: int, options: CellOptions, blocks: int,
                 ckdir: str | None, resume: bool, progress: bool):
        if n < 1:
            raise ValueError(f"number of cells n = {n} out of range; accepted n >= 1")
        self.prepared, self.n, self.options = str(prepared), n, options
        self.ckdir = None if ckdir is None else str(ckdir)
        self.progress = progress
        self.blocks = [b for b in np.array_split(np.arange(n), max(1, min(blocks, n))) if len(b)]
        self.recoveries = 0
        self._start_all(resume)

    # backend hooks: start one block's registry, submit a call, collect its result
    @abstractmethod
    def _start(self, b: int, resume: bool) -> None:
        """Start block ``b``'s registry (from the checkpoints when ``resume``)."""

    @abstractmethod
    def _submit(self, b: int, method: str, args: tuple):
        """Send a call to block ``b``; returns a handle for :meth:`_collect`."""

    @abstractmethod
    def _collect(self, b: int, handle):
        """The call's result; :class:`WorkerLost` if the block's worker died."""

    def _start_all(self, resume: bool) -> None:
        for b in range(len(self.blocks)):
            self._start(b, resume)

    def _call(self, method: str, args_of, bar=None) -> list:
        """Call ``method(*args_of(b))`` on every block concurrently, recovering lost blocks."""
        handles = {b: self._submit(b, method, args_of(b)) for b in range(len(self.blocks))}
        results = [None] * len(self.blocks)
        for b in range(len(self.blocks)):
            for attempt in range(MAX_RECOVERIES + 1):
                try:
                    results[b] = self._collect(b, handles[b])
                    break
                except WorkerLost:
                    if self.ckdir is None or method == "commit" or attempt == MAX_RECOVERIES:
                        raise
                    self._start(b, resume=True)
                    self.recoveries += 1
                    handles[b] = self._submit(b, method, args_of(b))
            if bar is not None:
                bar.update(len(self.blocks[b]))
        return results

    def trial(self, dstrain: np.ndarray, dspin: np.ndarray) -> dict:
        """One increment per cell on copies of the committed states (see the module doc)."""
        with tqdm(total=self.n, desc="DEM cells", unit="cell", leave=False,
                  disable=not self.progress) as bar:
            parts = self._call("trial", lambda b: (self.blocks[b], dstrain[self.blocks[b]],
                                                   dspin[self.blocks[b]]), bar)
        out = {"stress": np.zeros((self.n, 3)), "state": np.zeros((self.n, 4)),
               "steps": np.zeros((self.n, 2), np.int64), "ok": np.ones(self.n, bool), "errors": {}}
        for ids, part in zip(self.blocks, parts):
            for key in ("stress", "state", "steps", "ok"):
                out[key][ids] = part[key]
            out["errors"].update({int(ids[j]): msg for j, msg in part["errors"].items()})
        return out

    def commit(self, fe_step: int) -> None:
        """Promote the latest trials of every cell (a converged FE step) and checkpoint them."""
        self._call("commit", lambda b: (fe_step,))

    def steps(self) -> np.ndarray:
        """(n,) the converged step each cell's committed state belongs to."""
        out = np.zeros(self.n, np.int64)
        for part in self._call("steps", lambda b: ()):
            for i, s in part.items():
                out[i] = s
        return out

    def close(self) -> None:
        """Release the workers."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class SerialCells(Cells):
    """All cells in this process (the reference the other backends must reproduce)."""

    def __init__(self, prepared, n, options, ckdir=None, resume=False, progress=False):
        super().__init__(prepared, n, options, 1, ckdir, resume, progress)

    def _start(self, b, resume):
        self.registry = CellRegistry(self.prepared, self.blocks[b], self.options, self.ckdir, resume)

    def _submit(self, b, method, args):
        return getattr(self.registry, method)(*args)

    def _collect(self, b, handle):
        return handle


def _serve(conn, prepared, ids, options, ckdir, resume) -> None:
    """A pool process: one registry, calls in over the pipe, results or tracebacks out."""
    registry = CellRegistry(prepared, ids, options, ckdir, resume)
    while True:
        msg = conn.recv()
        if msg is None:
            return
        method, args = msg
        try:
            conn.send(("ok", getattr(registry, method)(*args)))
        except Exception:  # noqa: BLE001 - sent back and re-raised in the parent
            conn.send(("error", traceback.format_exc()))


class ProcessCells(Cells):
    """A persistent pool of ``workers`` spawned processes, one registry (block) each."""

    def __init__(self, prepared, n, options, workers=2, ckdir=None, resume=False, progress=False):
        self._ctx = multiprocessing.get_context("spawn")
        self.procs, self.conns = {}, {}
        super().__init__(prepared, n, options, workers, ckdir, resume, progress)

    def _start(self, b, resume):
        old = self.procs.get(b)
        if old is not None and old.is_alive():
            old.kill()
        parent, child = self._ctx.Pipe()
        p = self._ctx.Process(target=_serve, daemon=True,
                              args=(child, self.prepared, self.blocks[b], self.options,
                                    self.ckdir, resume))
        p.start()
        child.close()
        self.procs[b], self.conns[b] = p, parent

    def _submit(self, b, method, args):
        try:
            self.conns[b].send((method, args))
        except (BrokenPipeError, OSError):
            return None
        return b

    def _collect(self, b, handle):
        try:
            if handle is None:
                raise EOFError
            kind, value = self.conns[b].recv()
        except (EOFError, OSError) as exc:
            raise WorkerLost(f"pool process of cells {self.blocks[b][0]}..{self.blocks[b][-1]} "
                             f"died (exit code {self.procs[b].exitcode})") from exc
        if kind == "error":
            raise RuntimeError(f"cells {self.blocks[b][0]}..{self.blocks[b][-1]}: {value}")
        return value

    def close(self):
        for b, conn in self.conns.items():
            try:
                conn.send(None)
            except (BrokenPipeError, OSError):
                pass
        for p in self.procs.values():
            p.join(timeout=10)
            if p.is_alive():
                p.kill()
        self.procs, self.conns = {}, {}


class DaskCells(Cells):
    """One registry actor per block on a dask.distributed cluster (``client``)."""

    def __init__(self, prepared, n, options, client, blocks=None, ckdir=None, resume=False,
                 progress=False):
        self.client = client
        self.actors = {}
        workers = list(client.scheduler_info()["workers"])
        if not workers:
            raise ValueError("the dask cluster has no workers")
        super().__init__(prepared, n, options, blocks or len(workers), ckdir, resume, progress)

    def _start(self, b, resume):
        workers = sorted(self.client.scheduler_info()["workers"])
        if not workers:
            raise WorkerLost("the dask cluster has no live worker left")
        future = self.client.submit(CellRegistry, self.prepared, self.blocks[b], self.options,
                                    self.ckdir, resume, actor=True, pure=False,
                                    workers=[workers[b % len(workers)]], allow_other_workers=True)
        self.actors[b] = (future, future.result())

    def _submit(self, b, method, args):
        try:
            return getattr(self.actors[b][1], method)(*args)
        except Exception as exc:  # noqa: BLE001 - any transport failure means a lost actor
            return exc

    def _collect(self, b, handle):
        if isinstance(handle, Exception):
            raise WorkerLost(f"actor of cells {self.blocks[b][0]}..{self.blocks[b][-1]}: {handle}")
        try:
            return handle.result()
        except Exception as exc:  # noqa: BLE001
            if isinstance(exc, (ValueError, TypeError, KeyError)) and "actor" not in str(exc).lower():
                raise
            raise WorkerLost(f"actor of cells {self.blocks[b][0]}..{self.blocks[b][-1]} "
                             f"lost ({type(exc).__name__}: {exc})") from exc

    def close(self):
        self.actors = {}

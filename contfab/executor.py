"""One interface to run independent jobs: serially, on a local process pool, or on dask.

    with make_executor("pool", workers=2) as ex:
        results = ex.map(fn, items, desc="DEM runs")

``map`` returns ``[fn(x) for x in items]`` in the order of ``items``, whatever order the
jobs finish in, and shows a tqdm bar over finished jobs. The three kinds share that one
code path: each only says how to *submit* a job and returns futures that the common
loop waits on (:func:`concurrent.futures.as_completed` or dask's ``as_completed``).

* ``serial`` (default): jobs run in this process, one after the other.
* ``pool``: a :class:`concurrent.futures.ProcessPoolExecutor` whose workers are started
  with *spawn* (a forked child of a process that ran an OpenMP-parallel numba kernel
  hangs: ENGINEERING.md) and run one numba thread each.
* ``dask``: a dask.distributed cluster: an existing scheduler (``scheduler="tcp://..."``,
  workers started with ``dask worker``), or a LocalCluster of single-threaded worker
  processes made here. Workers get ``NUMBA_NUM_THREADS=1`` and ``OMP_NUM_THREADS=1``.
  dask is the optional extra ``dist`` (``pip install contfab[dist]``).

Every worker runs ``warm`` (if given) once before its first job, so numba kernels are
loaded (or compiled) per worker once, not per job. ``fn``, ``warm`` and the items must be
picklable (module-level functions, plain data). On 2 cores use either 2 single-threaded
workers or one process with 2 numba threads, never both.
"""
from __future__ import annotations

import os
from abc import ABC, abstractmethod
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from typing import Callable, Iterable, Sequence

KINDS = ("serial", "pool", "dask")
WORKER_ENV = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}


class ExecutorError(ValueError):
    """An executor that cannot be made as asked (unknown kind, bad worker count, no dask)."""


def _single_thread_worker(warm: Callable[[], object] | None) -> None:
    """Initializer of every worker process: one numba thread, then the warm-up."""
    os.environ.update(WORKER_ENV)
    import numba
    numba.set_num_threads(1)
    if warm is not None:
        warm()


class Executor(ABC):
    """Base: ``submit`` one job, ``map`` many (module doc). Use as a context manager."""

    kind = ""

    @abstractmethod
    def submit(self, fn: Callable, item) -> Future:
        """A future of ``fn(item)``."""

    def _as_completed(self, futures: Sequence):
        return as_completed(futures)

    def map(self, fn: Callable, items: Iterable, desc: str = "jobs", progress: bool = True) -> list:
        """``[fn(x) for x in items]`` through this executor; a tqdm bar over finished jobs.

        The first job that raises cancels the ones not yet started and re-raises."""
        items = list(items)
        futures = [self.submit(fn, x) for x in items]
        index = {id(f): k for k, f in enumerate(futures)}
        results: list = [None] * len(items)
        bar = None
        if progress and items:
            from tqdm import tqdm
            bar = tqdm(total=len(items), desc=f"{desc} [{self.kind}]", unit="job")
        try:
            for f in self._as_completed(futures):
                results[index[id(f)]] = f.result()
                if bar is not None:
                    bar.update(1)
        except BaseException:
            for f in futures:
                f.cancel()
            raise
        finally:
            if bar is not None:
                bar.close()
        return results

    def close(self) -> None:
        """Release the workers."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


class SerialExecutor(Executor):
    """Jobs run here, in submission order, each when the caller waits for it."""

    kind = "serial"

    def __init__(self, warm: Callable[[], object] | None = None):
        self._queue: dict[int, tuple[Callable, object]] = {}
        if warm is not None:
            warm()

    def submit(self, fn, item) -> Future:
        f: Future = Future()
        self._queue[id(f)] = (fn, item)
        return f

    def _as_completed(self, futures):
        for f in futures:
            fn, item = self._queue.pop(id(f))
            if f.set_running_or_notify_cancel():
                try:
                    f.set_result(fn(item))
                except BaseException as exc:     # noqa: BLE001 (re-raised by map via result())
                    f.set_exception(exc)
            yield f


class PoolExecutor(Executor):
    """A local process pool: spawned workers, one numba thread each."""

    kind = "pool"

    def __init__(self, workers: int, warm: Callable[[], object] | None = None):
        import multiprocessing

        self.workers = workers
        self._pool = ProcessPoolExecutor(max_workers=workers,
                                         mp_context=multiprocessing.get_context("spawn"),
                                         initializer=_single_thread_worker, initargs=(warm,))

    def submit(self, fn, item) -> Future:
        return self._pool.submit(fn, item)

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)


class DaskExecutor(Executor):
    """dask.distributed: a scheduler address, or a LocalCluster of ``workers`` processes."""

    kind = "dask"

    def __init__(self, workers: int, scheduler: str | None = None,
                 warm: Callable[[], object] | None = None):
        try:
            from dask.distributed import Client, LocalCluster
        except ImportError as exc:
            raise ExecutorError(
                "the dask executor needs dask.distributed, which is not installed: "
                "pip install 'contfab[dist]' (or dask[distributed]); or use --executor "
                "serial / pool") from exc
        self._cluster = None
        if scheduler is None:
            self._cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                         dashboard_address=None, env=dict(WORKER_ENV))
            self._client = Client(self._cluster)
        else:
            self._client = Client(scheduler)
        self._client.run(_single_thread_worker, warm)

    def submit(self, fn, item):
        return self._client.submit(fn, item, pure=False)

    def _as_completed(self, futures):
        from dask.distributed import as_completed as dask_as_completed
        return dask_as_completed(futures)

    def close(self) -> None:
        self._client.close()
        if self._cluster is not None:
            self._cluster.close()


def make_executor(kind: str = "serial", workers: int | None = None, scheduler: str | None = None,
                  warm: Callable[[], object] | None = None) -> Executor:
    """An executor of ``kind`` (module doc). ``workers`` defaults to the CPU count for a
    pool or a local dask cluster; ``scheduler`` (a dask scheduler address) implies dask."""
    if scheduler is not None and kind == "serial":
        kind = "dask"
    if kind not in KINDS:
        raise ExecutorError(f"executor {kind!r} is not known; accepted: {', '.join(KINDS)}")
    if scheduler is not None and kind != "dask":
        raise ExecutorError(f"a scheduler address ({scheduler}) needs the dask executor, "
                            f"not {kind!r}")
    if workers is None:
        workers = os.cpu_count() or 1
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ExecutorError(f"workers = {workers!r} out of range; accepted integers >= 1")
    if kind == "serial":
        return SerialExecutor(warm)
    if kind == "pool":
        return PoolExecutor(workers, warm)
    return DaskExecutor(workers, scheduler, warm)

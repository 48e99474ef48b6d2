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
  can hang) and run one numba thread each.
* ``dask``: a dask.distributed cluster: an existing scheduler (``scheduler="tcp://..."``,
  workers started with ``dask worker``), or a LocalCluster of single-threaded worker
  processes made here. Workers get ``NUMBA_NUM_THREADS=1`` and ``OMP_NUM_THREADS=1``.
  dask is the optional extra ``dist`` (``pip install contfab[dist]``).

Every worker runs ``warm`` (if given) once before its first job, so numba kernels are
loaded (or compiled) per worker once, not per job.

**Resident objects** (FE×DEM: the DEM cells of a quadrature-point block stay where they
run between load steps, so particle arrays are never re-sent).
``ex.resident(factory, args, slot)`` makes ``factory(*args)`` once on one worker and
returns a :class:`Resident` handle; ``handle.call(method, *a)`` runs ``obj.method(*a)``
there and returns a call whose ``result()`` is its value (one call at a time per
resident; calls to different residents run concurrently). A worker that dies makes
``result()`` raise :class:`WorkerLost` (an error raised by the method itself is
re-raised as such); the caller may then make a new resident, e.g. from checkpoints.

* ``serial``: the object lives in this process; a call runs when made.
* ``pool``: a dedicated spawned process per resident (single numba thread, ``warm``
  run first) serving calls over a pipe: a process-pool worker cannot be pinned to an
  object, so residents do not use the pool's workers.
* ``dask``: a dask actor on worker ``slot mod (number of workers)``, allowed to move
  to another worker when it is made anew. ``DaskExecutor(client=...)`` runs on a
  caller's client (not closed here). ``fn``, ``warm`` and the items must be
picklable (module-level functions, plain data). On 2 cores use either 2 single-threaded
workers or one process with 2 numba threads, never both.
"""
from __future__ import annotations

import os
import traceback
from abc import ABC, abstractmethod
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from typing import Callable, Iterable, Sequence

KINDS = ("serial", "pool", "dask")
WORKER_ENV = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}


class ExecutorError(ValueError):
    """An executor that cannot be made as asked (unknown kind, bad worker count, no dask)."""


class WorkerLost(RuntimeError):
    """The worker holding a resident object died (module doc)."""


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

    @abstractmethod
    def resident(self, factory: Callable, args: tuple, slot: int = 0) -> "Resident":
        """``factory(*args)`` made once on one worker (``slot`` picks it); module doc."""

    def close(self) -> None:
        """Release the workers."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


class Resident(ABC):
    """Handle of an object living on one worker (module doc)."""

    @abstractmethod
    def call(self, method: str, *args):
        """Start ``obj.method(*args)``; returns an object whose ``result()`` gives its value."""

    def close(self) -> None:
        """Let the object go (its worker stays)."""


class _LocalResident(Resident):
    def __init__(self, factory, args):
        self.obj = factory(*args)

    def call(self, method, *args):
        f: Future = Future()
        try:
            f.set_result(getattr(self.obj, method)(*args))
        except Exception as exc:     # noqa: BLE001 (re-raised by result())
            f.set_exception(exc)
        return f


def _serve(conn, warm, factory, args) -> None:
    """A resident's process: make the object, then calls in over the pipe, results (or
    tracebacks) out, until None."""
    _single_thread_worker(warm)
    obj = factory(*args)
    while True:
        msg = conn.recv()
        if msg is None:
            return
        method, a = msg
        try:
            conn.send(("ok", getattr(obj, method)(*a)))
        except Exception:  # noqa: BLE001 - sent back and re-raised in the parent
            conn.send(("error", traceback.format_exc()))


class _PipeCall:
    """A call sent to a resident process; ``result()`` receives its answer."""

    def __init__(self, resident: "_ProcessResident", sent: bool):
        self.resident, self.sent = resident, sent

    def result(self):
        r = self.resident
        try:
            if not self.sent:
                raise EOFError
            kind, value = r.conn.recv()
        except (EOFError, OSError) as exc:
            raise WorkerLost(f"resident process {r.process.pid} died (exit code "
                             f"{r.process.exitcode})") from exc
        if kind == "error":
            raise RuntimeError(f"in resident process {r.process.pid}: {value}")
        return value


class _ProcessResident(Resident):
    def __init__(self, ctx, warm, factory, args):
        self.conn, child = ctx.Pipe()
        self.process = ctx.Process(target=_serve, args=(child, warm, factory, args), daemon=True)
        self.process.start()
        child.close()

    def call(self, method, *args):
        try:
            self.conn.send((method, args))
        except (BrokenPipeError, OSError):
            return _PipeCall(self, sent=False)
        return _PipeCall(self, sent=True)

    def close(self):
        try:
            self.conn.send(None)
        except (BrokenPipeError, OSError):
            pass
        self.process.join(timeout=10)
        if self.process.is_alive():
            self.process.kill()
            self.process.join()


class _ActorCall:
    """An actor method call; ``result()`` maps a lost actor or worker to WorkerLost."""

    def __init__(self, handle):
        self.handle = handle

    def result(self):
        if isinstance(self.handle, Exception):
            raise WorkerLost(f"dask actor unreachable: {self.handle}") from self.handle
        try:
            return self.handle.result()
        except Exception as exc:  # noqa: BLE001
            if isinstance(exc, (ValueError, TypeError, KeyError)) \
                    and "actor" not in str(exc).lower():
                raise
            raise WorkerLost(f"dask actor lost ({type(exc).__name__}: {exc})") from exc


class _ActorResident(Resident):
    def __init__(self, client, factory, args, slot):
        workers = sorted(client.scheduler_info()["workers"])
        if not workers:
            raise WorkerLost("the dask cluster has no live worker")
        self.future = client.submit(factory, *args, actor=True, pure=False,
                                    workers=[workers[slot % len(workers)]],
                                    allow_other_workers=True)
        self.actor = self.future.result()

    def call(self, method, *args):
        try:
            return _ActorCall(getattr(self.actor, method)(*args))
        except Exception as exc:  # noqa: BLE001 - any transport failure means a lost actor
            return _ActorCall(exc)

    def close(self):
        self.future.release()


class SerialExecutor(Executor):
    """Jobs run here, in submission order, each when the caller waits for it."""

    kind = "serial"

    def __init__(self, warm: Callable[[], object] | None = None):
        self._queue: dict[int, tuple[Callable, object]] = {}
        if warm is not None:
            warm()

    def resident(self, factory, args, slot=0) -> Resident:
        return _LocalResident(factory, args)

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

        self.workers, self._warm = workers, warm
        self._ctx = multiprocessing.get_context("spawn")
        self._pool = ProcessPoolExecutor(max_workers=workers, mp_context=self._ctx,
                                         initializer=_single_thread_worker, initargs=(warm,))
        self._residents: list[_ProcessResident] = []

    def submit(self, fn, item) -> Future:
        return self._pool.submit(fn, item)

    def resident(self, factory, args, slot=0) -> Resident:
        r = _ProcessResident(self._ctx, self._warm, factory, args)
        self._residents.append(r)
        return r

    def close(self) -> None:
        for r in self._residents:
            r.close()
        self._residents = []
        self._pool.shutdown(wait=True, cancel_futures=True)


class DaskExecutor(Executor):
    """dask.distributed: a scheduler address, or a LocalCluster of ``workers`` processes."""

    kind = "dask"

    def __init__(self, workers: int, scheduler: str | None = None,
                 warm: Callable[[], object] | None = None, client=None):
        try:
            from dask.distributed import Client, LocalCluster
        except ImportError as exc:
            raise ExecutorError(
                "the dask executor needs dask.distributed, which is not installed: "
                "pip install 'contfab[dist]' (or dask[distributed]); or use --executor "
                "serial / pool") from exc
        self._cluster, self._owns_client = None, client is None
        if client is not None:
            self._client = client
        elif scheduler is None:
            self._cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                         dashboard_address=None, env=dict(WORKER_ENV))
            self._client = Client(self._cluster)
        else:
            self._client = Client(scheduler)
        self._client.run(_single_thread_worker, warm)

    def submit(self, fn, item):
        return self._client.submit(fn, item, pure=False)

    def resident(self, factory, args, slot=0) -> Resident:
        return _ActorResident(self._client, factory, args, slot)

    @property
    def client(self):
        return self._client

    def _as_completed(self, futures):
        from dask.distributed import as_completed as dask_as_completed
        return dask_as_completed(futures)

    def close(self) -> None:
        if self._owns_client:
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

"""How many threads the DEM's parallel passes use: one, unless asked.

A DEM step runs two parallel passes (:mod:`dem.integrator`) of a few to a few hundred µs
each, so every step wakes and joins the thread pool twice. On the 2-core virtual machines
it was measured on, that join costs more than the second thread gains, at every size
measured (idle machine, GNU OpenMP):

=====================================  ==========  ===========================  ==========
run                                    1 thread    2 threads, PASSIVE waiting   2, ACTIVE
=====================================  ==========  ===========================  ==========
``contfab bench dem`` (N = 4000)       1.70e7 /s   1.25e6 /s                    6.6e6 /s
live-DEM check of the suite (N = 500)  8.0 s       113 s (62 s of it in kernel) 10.3 s
=====================================  ==========  ===========================  ==========

(particle-steps per second; wall time). With PASSIVE waiting (the default set in
:mod:`dem`) each join is a futex wake of a halted virtual CPU; spinning instead takes the
other core from everything else. So the DEM does not follow numba's process-wide thread
count (which defaults to every core, and which other code and tests change): its kernels
run with :func:`get_threads` threads, 1 by default, set by :func:`set_threads` (the
``--threads`` option of the DEM commands) or for a block with :func:`using`. Results are
bitwise the same for any count (:mod:`dem.integrator`).
"""
from __future__ import annotations

import contextlib
from typing import Iterator

import numba

_threads = 1


def _checked(n: int) -> int:
    top = numba.config.NUMBA_NUM_THREADS
    if isinstance(n, bool) or int(n) != n or not 1 <= n <= top:
        raise ValueError(f"DEM threads {n!r} out of range; accepted 1 to {top} "
                         f"(NUMBA_NUM_THREADS on this machine)")
    return int(n)


def get_threads() -> int:
    """Threads of the DEM's parallel passes (1 unless :func:`set_threads` said otherwise)."""
    return _threads


def set_threads(n: int) -> None:
    """Run the DEM's parallel passes on ``n`` threads from now on (1 ≤ n ≤ NUMBA_NUM_THREADS)."""
    global _threads
    _threads = _checked(n)


@contextlib.contextmanager
def numba_threads(n: int) -> Iterator[None]:
    """numba's thread count of the calling thread set to ``n`` for the block, then restored."""
    before = numba.get_num_threads()
    numba.set_num_threads(_checked(n))
    try:
        yield
    finally:
        numba.set_num_threads(before)


@contextlib.contextmanager
def using(n: int) -> Iterator[None]:
    """The DEM's thread count set to ``n`` for the block, then restored."""
    global _threads
    before, _threads = _threads, _checked(n)
    try:
        yield
    finally:
        _threads = before

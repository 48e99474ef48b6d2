"""Benchmarks (``contfab bench NAME``): speed and memory figures, measured side by side.

Each benchmark module ``contfab/bench/NAME.py`` exposes ``run(args) -> dict`` of
named figures; the CLI prints them as a table, or with ``--json`` as one JSON object
(keys are the figure names) so they can be tracked over time. Timings are medians
of several repeats: a shared machine is noisy.
"""
from __future__ import annotations

import json
import resource
import statistics
import time
from typing import Callable


def median_seconds(fn: Callable[[], object], repeats: int = 5, warmup: int = 1,
                   clock: Callable[[], float] = time.perf_counter) -> float:
    """Median time of ``fn()`` over ``repeats`` calls after ``warmup`` untimed calls.

    ``clock`` defaults to wall time; ``time.process_time`` gives the CPU time of this
    process instead (a per-core figure for single-threaded work on a shared machine).
    """
    if repeats < 1:
        raise ValueError(f"repeats = {repeats} must be >= 1")
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        t0 = clock()
        fn()
        times.append(clock() - t0)
    return statistics.median(times)


def peak_rss_bytes() -> int:
    """Peak resident set size of this process so far (Linux reports kB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def print_figures(title: str, figures: dict, as_json: bool) -> None:
    """Print figures as one JSON object, or as an aligned two-column table."""
    if as_json:
        print(json.dumps(figures))
        return
    print(title)
    width = max(len(k) for k in figures)
    for k, v in figures.items():
        text = f"{v:.4g}" if isinstance(v, float) else str(v)
        print(f"  {k:<{width}}  {text}")

"""A trade-off study: knob settings (points), a runner per point, errors against cost.

A :class:`Study` lists its points (each a dict of knob values plus the fixed settings
the runner needs), names the runner ``run_point(study, point) -> dict`` and the
evaluation ``evaluate(study, points, results) -> (rows, notes)``. Runners are plain
module-level functions, so a point can run in another process or on a dask worker.

A runner returns ``{"values": {...}, "wall_s": s, "cpu_s": s, "cost": cost in
study.cost_unit}``: measured quantities, not errors, and the wall and CPU time of the
timed work (:class:`Clock`). The runs are single-threaded, and on a shared machine the CPU
time of this process is the reproducible figure (the wall time of the same run varied 10x
under load), so the front and the cost use CPU time; the tables list both. Errors need the whole study (a converged run, an
extrapolated limit, a spread across seeds), so :attr:`Study.evaluate` turns all the
results into table rows ``{"knobs": {...}, "wall_s", "cpu_s", "cost", "errors": {q: e}}``
(errors dimensionless, >= 0) and notes (fitted exponents, limits) for the summary.
The combined error of a row is the largest of its errors (:func:`combined_error`).

:func:`run_study` is resumable: each point's result is one JSON file in ``DIR/points/``,
written atomically when the point finishes, and reused on a rerun when its point (knobs
and settings) is identical. The points run through :mod:`contfab.executor` (serial, a
process pool or dask); each job writes its own point file as it finishes, so an interrupted
study keeps every finished point whatever the executor.
"""
from __future__ import annotations

import hashlib
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

from dem.fileio import write_json


class StudyError(ValueError):
    """A study cannot run as asked (unknown study or executor, bad result)."""


@dataclass(frozen=True)
class Study:
    """Points, their runner and the evaluation (module doc)."""

    name: str
    description: str
    knobs: tuple[str, ...]
    points: tuple[dict, ...]
    run_point: Callable[["Study", dict], dict]
    evaluate: Callable[["Study", list[dict], list[dict]], tuple[list[dict], dict]]
    default: dict
    quantities: tuple[str, ...]
    cost_unit: str
    error_meaning: str
    settings: dict = field(default_factory=dict)


class Clock:
    """Wall and CPU time of this process over a ``with`` block (``.wall``, ``.cpu`` in s)."""

    def __enter__(self) -> "Clock":
        self._w, self._c = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc) -> None:
        self.wall = time.perf_counter() - self._w
        self.cpu = time.process_time() - self._c


def dem_code_digest() -> str:
    """A short hash of the DEM's source: points that ran the DEM carry it in their
    settings, so a change of the DEM's code (its trajectories) reruns them."""
    from dem.numba_cache import source_digest

    return source_digest(("dem",))


def point_key(point: dict) -> str:
    """A stable file name for a point: readable knob values and a short content hash."""
    text = json.dumps(point, sort_keys=True, default=str)
    digest = hashlib.sha1(text.encode()).hexdigest()[:10]
    readable = "_".join(f"{k}{v:g}" if isinstance(v, (int, float)) else f"{k}{v}"
                        for k, v in sorted(point.items()) if not isinstance(v, (dict, list)))
    return f"{readable[:80]}_{digest}".replace("/", "-")


def combined_error(row: dict) -> float:
    """The largest of a row's errors (NaN if it has none that are finite)."""
    finite = [e for e in row["errors"].values() if math.isfinite(e)]
    return max(finite) if finite else math.nan


def pareto_front(rows: Sequence[dict]) -> list[bool]:
    """Whether each row is on the front: no other row is at most as costly *and* at most
    as wrong, being strictly better in one (cost = CPU time, error = combined)."""
    pts = [(r["cpu_s"], combined_error(r)) for r in rows]
    front = []
    for i, (t, e) in enumerate(pts):
        dominated = math.isnan(e) or any(
            j != i and not math.isnan(f) and s <= t and f <= e and (s < t or f < e)
            for j, (s, f) in enumerate(pts))
        front.append(not dominated)
    return front


def is_default(study: Study, row: dict) -> bool:
    return all(row["knobs"].get(k) == v for k, v in study.default.items())


def run_and_save(job: tuple) -> dict:
    """One executor job: run a point, check its result, write its point file; returns it."""
    study, point, path = job
    result = study.run_point(study, point)
    _check_result(study, point, result)
    write_json(path, {"point": point, "settings": study.settings, "result": result})
    return result


def run_study(study: Study, out: str | Path, executor: str = "serial", workers: int | None = None,
              scheduler: str | None = None, progress: bool = True) -> list[dict]:
    """Run the missing points of ``study`` (reusing ``out/points/*.json``) through the
    executor (:func:`contfab.executor.make_executor`); returns the results in point order."""
    from contfab.executor import make_executor

    folder = Path(out) / "points"
    results: dict[int, dict] = {}
    missing = []
    for i, point in enumerate(study.points):
        f = folder / f"{point_key(point)}.json"
        if f.is_file():
            saved = json.loads(f.read_text())
            if (saved.get("point") == json.loads(json.dumps(point))
                    and saved.get("settings") == json.loads(json.dumps(study.settings))):
                results[i] = saved["result"]
                continue
        missing.append(i)
    jobs = [(study, study.points[i], folder / f"{point_key(study.points[i])}.json")
            for i in missing]
    with make_executor(executor, workers, scheduler) as ex:
        for i, result in zip(missing, ex.map(run_and_save, jobs, desc=study.name,
                                             progress=progress)):
            results[i] = result
    return [results[i] for i in range(len(study.points))]


def _check_result(study: Study, point: dict, result: dict) -> None:
    for key in ("values", "wall_s", "cpu_s", "cost"):
        if key not in result:
            raise StudyError(f"study {study.name!r}: the runner's result for {point} has no "
                             f"{key!r} (it must return values, wall_s, cpu_s, cost)")
    bad = [k for k, v in result["values"].items()
           if isinstance(v, float) and not math.isfinite(v)]
    if bad or not math.isfinite(result["cpu_s"]):
        raise StudyError(f"study {study.name!r}: point {point} gave non-finite "
                         f"{', '.join(bad) or 'cpu_s'}")

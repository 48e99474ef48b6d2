"""The stability matrix: points, outcomes, and how one point is judged.

A :class:`Point` is one extreme setting of one component (``dem``, ``point``, ``fem``)
along one axis (a parameter and its value), with a runner that either returns a
:class:`Measured` (its accuracy against a stated reference and the tolerance that
reference allows) or raises. :func:`evaluate` turns that into one outcome:

* ``PASS``          accuracy <= tolerance;
* ``ACCURACY_LOST`` tolerance < accuracy <= the lost tolerance (the runner's stated degraded
                    accuracy, e.g. the FEM's stall tolerance; default LOST_FACTOR · tolerance):
                    a finite result whose accuracy is degraded at this point, reported as such;
* ``CLEAR_ERROR``   a ``ValueError`` (the project's error base) whose message names the
                    limit and the value (:func:`names_limit`);
* ``FAIL``          anything else: NaN or inf, accuracy beyond the lost tolerance
                    (a silently wrong result), another exception type, an error message
                    that does not name its limit, or a run longer than its time budget
                    (a hang; runs are serial and in-process, so it is judged after the fact).
"""
from __future__ import annotations

import math
import re
import time
import traceback
from dataclasses import dataclass, field
from typing import Callable

PASS, ACCURACY_LOST, CLEAR_ERROR, FAIL = "PASS", "ACCURACY_LOST", "CLEAR_ERROR", "FAIL"
OUTCOMES = (PASS, ACCURACY_LOST, CLEAR_ERROR, FAIL)
LOST_FACTOR = 10.0
COMPONENTS = ("dem", "point", "fem")

_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?|inf")
_LIMIT_WORDS = ("accepted", "range", "limit", "minimum", "maximum", "exceeds", "above", "below",
                "<", ">", "need")


@dataclass(frozen=True)
class Measured:
    """A finished run: ``accuracy`` (relative, against ``reference``) and its ``tolerance``."""

    accuracy: float
    tolerance: float
    reference: str
    note: str = ""
    lost_tolerance: float | None = None


@dataclass(frozen=True)
class Point:
    """One point of the matrix; ``full_only`` points run only in the full matrix."""

    component: str
    axis: str
    value: str
    run: Callable[[], Measured]
    budget_s: float
    full_only: bool = False


@dataclass
class Outcome:
    component: str
    axis: str
    value: str
    outcome: str
    accuracy: float = math.nan
    tolerance: float = math.nan
    reference: str = ""
    message: str = ""
    seconds: float = 0.0
    extra: dict = field(default_factory=dict)

    COLUMNS = ("component", "axis", "value", "outcome", "accuracy", "tolerance", "reference",
               "message", "seconds")

    def as_row(self) -> list:
        return [getattr(self, c) for c in self.COLUMNS]


def names_limit(message: str) -> bool:
    """True when an error message states a value and a limit (a number and a limit word)."""
    low = message.lower()
    return bool(_NUMBER.search(low)) and any(w in low for w in _LIMIT_WORDS)


def evaluate(point: Point) -> Outcome:
    """Run ``point`` and judge it (module doc)."""
    out = Outcome(point.component, point.axis, point.value, FAIL)
    t0 = time.perf_counter()
    try:
        m = point.run()
    except ValueError as exc:
        out.seconds = time.perf_counter() - t0
        msg = " ".join(str(exc).split())
        out.message = f"{type(exc).__name__}: {msg}"
        out.outcome = CLEAR_ERROR if names_limit(msg) else FAIL
        if out.outcome == FAIL:
            out.message = "error message names no limit: " + out.message
        return _timed(out, point)
    except Exception as exc:                           # noqa: BLE001 - judged, not hidden
        out.seconds = time.perf_counter() - t0
        tb = traceback.extract_tb(exc.__traceback__)[-1]
        out.message = f"{type(exc).__name__}: {exc} ({tb.filename}:{tb.lineno})"
        return out
    out.seconds = time.perf_counter() - t0
    out.accuracy, out.tolerance, out.reference, out.message = (
        float(m.accuracy), float(m.tolerance), m.reference, m.note)
    lost = LOST_FACTOR * m.tolerance if m.lost_tolerance is None else m.lost_tolerance
    if not math.isfinite(out.accuracy):
        out.message = f"non-finite result (accuracy {out.accuracy}); {m.note}"
    elif out.accuracy <= m.tolerance:
        out.outcome = PASS
    elif out.accuracy <= lost:
        out.outcome = ACCURACY_LOST
    else:
        out.message = (f"silently wrong: accuracy {out.accuracy:.3g} > {lost:.3g} "
                       f"(tolerance {m.tolerance:.3g}); {m.note}")
    return _timed(out, point)


def _timed(out: Outcome, point: Point) -> Outcome:
    if out.seconds > point.budget_s:
        out.outcome = FAIL
        out.message = f"exceeded its time budget {point.budget_s:g} s ({out.seconds:.1f} s); {out.message}"
    return out


def finite(*values) -> bool:
    """All entries of all (array-like) values are finite."""
    import numpy as np
    return all(bool(np.all(np.isfinite(np.asarray(v, dtype=float)))) for v in values)


def measured_or_nan(accuracy: float, tolerance: float, reference: str, note: str, *arrays) -> Measured:
    """A :class:`Measured` whose accuracy is NaN if any of ``arrays`` holds NaN or inf."""
    if not finite(*arrays):
        return Measured(math.nan, tolerance, reference, "non-finite output; " + note)
    return Measured(accuracy, tolerance, reference, note)

"""``tier = "auto"`` in a boundary-value problem: per point, the cheapest model that meets a
tolerance, from the measured bounds and the indicators of the run.

    result, report = run_auto(solve, params, tolerance)

``solve(params, point_tiers) -> dict`` is a case's analysis with the model given per
quadrature point (an int: one tier everywhere; an array: mixed tiers,
:class:`contfab.fem.material.TierMaterial` ``point_tiers``); its dict holds at least
``indicators`` (the run's :class:`contfab.selection.indicators.Tracker`), ``point_updates``
({tier: point updates}) and ``wall_s``.

**Passes.** Every point starts with the model chosen for monotonic loading
(:func:`contfab.selection.auto_tier.choose`). After a run, the points whose indicators put
them in the reversal class get the model chosen for that class where it is a higher tier
than theirs (``mode`` "mixed"), or every point does as soon as one asks (``mode``
"uniform": one tier in the mesh). If a point changed, the analysis runs again from the
start: a tier-2 point integrates its fabric from the initial state, which a tier-1 history
does not hold. A monotonic scene costs one run of the cheap tier; a scene with a reversal,
the tier-1 pilot and the final run (``max_passes`` = 2, the default). The choice has
settled when the last run's flagged points all had their class's model; where the
reversal zone moves with the model (a shear band), it need not, and the report counts the
points the last run flagged but ran with the cheaper model (``unsettled_points``).

``min_tier``: the lowest tier the case can run (a case measuring c needs tier 1). The
reversal class's model is chosen among tiers >= the monotonic one, so a flagged point
never drops below its neighbours' model.

Parameters: the case's ``params`` with the ``[tier2]`` section of the reversal class's
model (:func:`~contfab.selection.auto_tier.params_for`; both files share the tier-0/1
sections, so the bounds of both classes apply to one parameter set).
"""
from __future__ import annotations

from dataclasses import asdict
from typing import Callable

import numpy as np

from contfab.params import ParamError, Params
from contfab.selection.auto_tier import AutoTierError, choose, params_for

MODES = ("mixed", "uniform")


def run_auto(solve: Callable[[Params, object], dict], params: Params, tolerance: float,
             mode: str = "mixed", max_passes: int = 2, table=None, min_tier: int = 0
             ) -> tuple[dict, dict]:
    """(the last run's dict, its ``files`` those of every pass, and the report of the
    choice); see the module doc."""
    if mode not in MODES:
        raise ParamError(f"auto-tier mode = {mode!r}; accepted: {', '.join(MODES)}")
    if not 1 <= max_passes <= 10:
        raise ParamError(f"max_passes = {max_passes} is outside the accepted range [1, 10]")
    mono = choose("monotonic", tolerance, table, min_tier)
    rev = choose("reversal", tolerance, table, mono.tier)    # never below the monotonic tier
    if mono.tier == rev.tier == 2 and mono.params_file != rev.params_file:
        raise AutoTierError(f"at tolerance {tolerance:g} monotonic loading needs {mono.model} and "
                            f"reversal {rev.model}: two [tier2] sections, one mesh carries one")
    run_params = params_for(params, rev)
    tiers: int | np.ndarray = mono.tier
    passes, settled, files = [], False, []
    for _ in range(max_passes):
        result = solve(run_params, tiers)
        files += result.get("files", [])
        tracker = result["indicators"]
        flagged = tracker.reversal_class()
        current = np.broadcast_to(np.asarray(tiers), flagged.shape)
        wanted = np.where(flagged, rev.tier, mono.tier)
        if mode == "uniform" and flagged.any():
            wanted = np.full(flagged.shape, rev.tier)
        passes.append(_pass_summary(current, flagged, result))
        unsettled = int(np.sum(wanted > current))
        if unsettled == 0:
            settled = True
            break
        new = np.maximum(current, wanted)
        tiers = int(new[0]) if np.all(new == new[0]) else new
    report = {"tier": "auto", "tolerance": tolerance, "mode": mode, "settled": settled,
              "unsettled_points": unsettled,
              "wall_s": float(sum(p["wall_s"] for p in passes)),
              "choice": _choice_text(current, flagged, mono, rev),
              "monotonic": asdict(mono), "reversal": asdict(rev),
              "indicators": {"monotonic_points": asdict(tracker.worst(~flagged)),
                             "reversal_points": asdict(tracker.worst(flagged)),
                             "reversal_share": float(flagged.mean())},
              "passes": passes}
    return {**result, "files": files}, report


def _pass_summary(current: np.ndarray, flagged: np.ndarray, result: dict) -> dict:
    n = len(current)
    return {"points": n, "points_per_tier": {int(t): int(np.sum(current == t))
                                             for t in np.unique(current)},
            "reversal_points": int(flagged.sum()), "wall_s": result["wall_s"],
            "point_updates": {int(k): int(v) for k, v in result["point_updates"].items()}}


def _choice_text(current: np.ndarray, flagged: np.ndarray, mono, rev) -> str:
    n, k = len(current), int(flagged.sum())
    high = int(np.sum(current > mono.tier))
    if high == 0:
        where = ("none in the reversal class" if k == 0 else
                 f"{k} in the reversal class, where it is also the choice: {rev.reason}")
        return f"{mono.model} at all {n} points ({where}): {mono.reason}"
    if high == n:
        return f"{rev.model} at all {n} points: {rev.reason}"
    return (f"{rev.model} at {high} of {n} points ({100 * high / n:.1f} %, the reversal class: "
            f"{rev.reason}), {mono.model} elsewhere ({mono.reason})")

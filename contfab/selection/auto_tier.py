"""``tier = "auto"``: the cheapest model whose measured error bound meets a tolerance.

Two ingredients:

* **Measured bounds** (:data:`TABLE_FILE`, a small CSV in the package): per loading class
  ("monotonic", "reversal") and model tier, the error of R/P against the DEM and the cost per
  material-point increment, all with the shipped parameters. The errors come from the DEM
  runs of tier 2's transients (N = 1000, 3 seeds per path and density), written by
  ``contfab transients RUN_DIR... --auto-table FILE``
  (:func:`contfab.calibration.transients.table_from_transients`): for "monotonic" the largest
  RMS R/P error over the biaxial paths; for "reversal" the largest RMS R/P error over the
  first 0.2 strain after a reversal or change of direction — the part of such a path where
  the models differ. The cost is CPU µs per increment of the material-point driver on the
  class's path (:func:`measure_costs`).
* **Indicators** of the loading each point sees (:mod:`contfab.selection.indicators`: rotation of
  the principal stress axes, load reversal, distance from the critical state), which give
  its loading class.

:func:`choose` returns the cheapest model whose bound for the class is at most the tolerance,
with the reason; if none meets it, the most accurate, saying so. :mod:`contfab.fem.auto`
runs a boundary-value problem with the choice per point.
"""
from __future__ import annotations

import csv
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

from contfab.selection.indicators import CLASSES, Indicators
from contfab.params import Params, load_params

TABLE_FILE = Path(__file__).resolve().parent / "data" / "tier_errors.csv"
DATA_DIR = Path(__file__).resolve().parent.parent / "data"
MODELS = {"tier 0": (0, "default_params.toml"), "tier 1": (1, "default_params.toml"),
          "tier 2": (2, "default_params.toml")}
"""Model name -> (tier, parameter file in contfab/data)."""
COST_PATHS = {"monotonic": "biaxial", "reversal": "simple_shear_reversal"}


class AutoTierError(ValueError):
    """A tolerance or a table that cannot give a choice."""


# --------------------------------------------------------------------------- bounds and choice

@dataclass(frozen=True)
class Choice:
    """The model chosen for a loading class, its measured bound and why."""

    loading: str
    model: str
    tier: int
    params_file: str
    error: float
    met: bool
    reason: str


def load_table(path: str | Path = TABLE_FILE) -> dict[str, list[dict]]:
    """{loading class: [{model, tier, params_file, error, cost}] sorted by cost}."""
    table: dict[str, list[dict]] = {k: [] for k in CLASSES}
    with open(path, newline="") as fh:
        for row in csv.DictReader(fh):
            table[row["loading"]].append({
                "model": row["model"], "tier": int(row["tier"]), "params_file": row["params_file"],
                "error": float(row["error_RP"]), "cost": float(row["cost_us"])})
    for rows in table.values():
        rows.sort(key=lambda r: r["cost"])
    return table


def choose(ind: Indicators | str, tolerance: float,
           table: Mapping[str, list[dict]] | None = None, min_tier: int = 0) -> Choice:
    """The cheapest model of tier >= ``min_tier`` whose bound for the loading class of
    ``ind`` (Indicators, or a class name) meets ``tolerance`` (RMS error of R/P against
    the DEM)."""
    if isinstance(tolerance, bool) or not (isinstance(tolerance, (int, float))
                                           and tolerance > 0 and math.isfinite(tolerance)):
        raise AutoTierError(f"tolerance = {tolerance!r} out of range; accepted (0, inf) "
                            f"(RMS error of R/P against the DEM)")
    loading = ind if isinstance(ind, str) else ind.loading
    if loading not in CLASSES:
        raise AutoTierError(f"loading class {loading!r} unknown; accepted: {', '.join(CLASSES)}")
    table = load_table() if table is None else table
    rows = [r for r in table[loading] if r["tier"] >= min_tier]
    if not rows:
        raise AutoTierError(f"the error table has no rows of tier >= {min_tier} for {loading} "
                            f"loading")
    why = f"{loading} loading"
    if not isinstance(ind, str):
        why += (f" (axes rotation {ind.axes_rotation_deg:.1f}°, reversal "
                f"{'seen' if ind.reversal else 'not seen'}, |c - c*| <= {ind.critical_distance:.3g})")
    for r in rows:
        if r["error"] <= tolerance:
            dearer = [f"{x['model']} {x['error']:.3g}" for x in rows if x["cost"] < r["cost"]]
            return Choice(loading, r["model"], r["tier"], r["params_file"], r["error"], True,
                          f"{r['model']}: cheapest with measured R/P error {r['error']:.3g} <= "
                          f"{tolerance:g} for {why}"
                          + (f" (cheaper ones exceed it: {', '.join(dearer)})" if dearer else ""))
    best = min(rows, key=lambda r: r["error"])
    return Choice(loading, best["model"], best["tier"], best["params_file"], best["error"], False,
                  f"{best['model']}: no model meets {tolerance:g} for {why}; the most accurate "
                  f"(R/P error {best['error']:.3g})")


def params_for(base: Params, choice: Choice) -> Params:
    """``base`` with the ``[tier2]`` section of the chosen model's parameter file (the
    tier-0/1 sections and the scene's changes to the others stay ``base``'s)."""
    if choice.tier < 2:
        return base
    other = load_params(DATA_DIR / choice.params_file)
    if other.tier1 != base.tier1:
        raise AutoTierError(f"{choice.params_file}: its [tier1] differs from the case's; the "
                            f"measured bound of {choice.model} does not apply")
    return Params(base.tier, {**base.sections, "tier2": other.tier2},
                  f"{base.source} with [tier2] of {choice.params_file}")


def measure_costs(repeats: int = 3, increment: float = 4e-3) -> dict[tuple[str, str], float]:
    """CPU µs per material-point increment of each model on each class's path
    (:data:`COST_PATHS`), the least of ``repeats`` runs after a compiling one."""
    from contfab.material_point import run_path

    costs = {}
    for loading, path in COST_PATHS.items():
        for model, (tier, file) in MODELS.items():
            params = load_params(DATA_DIR / file)
            run_path(path, params, tier, increment=0.05)
            best = math.inf
            for _ in range(repeats):
                t0 = time.process_time()
                res = run_path(path, params, tier, increment=increment)
                best = min(best, time.process_time() - t0)
            costs[(loading, model)] = 1e6 * best / res.history["increments"][-1]
    return costs

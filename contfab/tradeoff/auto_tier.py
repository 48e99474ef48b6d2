"""``tier = "auto"``: the cheapest model tier whose measured error bound meets a tolerance.

Two ingredients:

* **Measured bounds** (:data:`TABLE_FILE`, a small CSV in the package): per loading class
  ("monotonic", "reversal") and tier, the RMS error of R/P against the DEM and the cost per
  material-point increment, as measured by the studies ``tier_biaxial`` and ``tier_reversal``
  (:mod:`contfab.tradeoff.tier_studies`; :func:`table_from_studies` rebuilds the file from
  their output tables).
* **Run-time indicators** of the loading a point sees (:func:`indicators`), from a history
  with the columns of :data:`dem.history.HISTORY_COLUMNS` (a cheap pilot run):
  rotation of the principal stress axes (largest change of α = ½ atan2(2σxy, σxx - σyy)
  from the first row with mobilized shear, R/P >= ``MOBILIZED``, degrees, mod 180°), load reversal (the deviatoric stress power
  s' : Δε = ½(σxx - σyy)(Δεxx - Δεyy) + σxy Δγxy, with the stress at the start of each
  row interval, changes sign from positive to negative after the shear was mobilized), and the largest distance from the critical
  state |c - c*|.

The loading class is "reversal" when a reversal is seen or the axes rotate by more than
:data:`ROTATION_LIMIT_DEG`, "monotonic" otherwise. :func:`choose` returns the cheapest tier
whose bound for that class is at most the tolerance, with the reason; if none meets it, the
most accurate tier, saying so.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

import numpy as np

TABLE_FILE = Path(__file__).resolve().parent / "data" / "tier_errors.csv"
ROTATION_LIMIT_DEG = 15.0
MOBILIZED = 0.1
"""Stress ratio R/P above which the shear counts as mobilized (reversal detection)."""
CLASSES = ("monotonic", "reversal")


class AutoTierError(ValueError):
    """A tolerance or a table that cannot give a choice."""


@dataclass(frozen=True)
class Indicators:
    axes_rotation_deg: float
    reversal: bool
    critical_distance: float

    @property
    def loading(self) -> str:
        rotated = self.axes_rotation_deg > ROTATION_LIMIT_DEG
        return "reversal" if (self.reversal or rotated) else "monotonic"


def indicators(history: Mapping[str, np.ndarray], c_star: float) -> Indicators:
    """The indicators of the module doc from a history (arrays per column)."""
    sxx, syy, sxy = (np.asarray(history[k], float) for k in ("sxx", "syy", "sxy"))
    rp = np.asarray(history["RP"], float)
    mobilized = rp >= MOBILIZED
    alpha = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)[mobilized]
    turn = (np.degrees(np.abs((alpha - alpha[0] + 0.5 * np.pi) % np.pi - 0.5 * np.pi))
            if len(alpha) else np.zeros(1))
    dexx, deyy = np.diff(history["eps_xx"]), np.diff(history["eps_yy"])
    dgam = 2.0 * np.diff(history["eps_xy"])
    start = slice(None, -1)      # the stress at the start of each interval meets its strain
    power = 0.5 * (sxx[start] - syy[start]) * (dexx - deyy) + sxy[start] * dgam
    positive = np.maximum.accumulate((power > 0) & mobilized[start])
    reversal = bool(np.any(positive & (power < 0)))
    c = np.asarray(history["c_p" if "c_p" in history else "c"], float)   # the hardening c
    dist = float(np.nanmax(np.abs(c - c_star))) if np.any(np.isfinite(c)) else math.nan
    return Indicators(float(turn.max()), reversal, dist)


def load_table(path: str | Path = TABLE_FILE) -> dict[str, list[dict]]:
    """{loading class: [{tier, error, cost}] sorted by cost}."""
    table: dict[str, list[dict]] = {k: [] for k in CLASSES}
    with open(path, newline="") as fh:
        for row in csv.DictReader(fh):
            table[row["loading"]].append({"tier": int(row["tier"]), "error": float(row["error_RP"]),
                                          "cost": float(row["cost_us"])})
    for rows in table.values():
        rows.sort(key=lambda r: r["cost"])
    return table


def choose(ind: Indicators, tolerance: float, table: Mapping[str, list[dict]] | None = None
           ) -> tuple[int, str]:
    """(tier, reason): the cheapest tier whose bound for the loading class meets ``tolerance``."""
    if not (isinstance(tolerance, (int, float)) and tolerance > 0 and math.isfinite(tolerance)):
        raise AutoTierError(f"tolerance = {tolerance!r} out of range; accepted (0, inf) "
                            f"(RMS error of R/P against the DEM)")
    table = load_table() if table is None else table
    rows = table[ind.loading]
    if not rows:
        raise AutoTierError(f"the error table has no rows for {ind.loading} loading")
    why = (f"{ind.loading} loading (axes rotation {ind.axes_rotation_deg:.1f}°, "
           f"reversal {'seen' if ind.reversal else 'not seen'}, |c - c*| <= "
           f"{ind.critical_distance:.3g})")
    for r in rows:
        if r["error"] <= tolerance:
            return r["tier"], (f"tier {r['tier']}: cheapest with measured R/P error "
                               f"{r['error']:.3g} <= {tolerance:g} for {why}")
    best = min(rows, key=lambda r: r["error"])
    return best["tier"], (f"tier {best['tier']}: no tier meets {tolerance:g} for {why}; "
                          f"the most accurate (R/P error {best['error']:.3g})")


def table_from_studies(out: str | Path, table: str | Path = TABLE_FILE) -> Path:
    """Rebuild the table from ``OUT/tier_biaxial/tier_biaxial.csv`` (monotonic) and
    ``OUT/tier_reversal/tier_reversal.csv`` (reversal)."""
    from dem.fileio import write_csv

    rows = []
    for loading, name in (("monotonic", "tier_biaxial"), ("reversal", "tier_reversal")):
        with open(Path(out) / name / f"{name}.csv", newline="") as fh:
            for r in csv.DictReader(fh):
                rows.append([loading, int(r["tier"]), float(r["error_RP"]), float(r["cost"])])
    return write_csv(table, ("loading", "tier", "error_RP", "cost_us"), rows)

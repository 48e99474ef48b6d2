"""Indicators of the loading a material point sees, which decide its model (``tier = "auto"``).

:class:`Tracker` follows ``n`` points one committed step at a time (the FEM driver feeds
it, :func:`contfab.fem.analysis.run`); :func:`indicators` feeds it a material-point
history (the columns of :data:`dem.history.HISTORY_COLUMNS` and ``gp``). Conventions:
Voigt stress (σxx, σyy, σxy), tension positive; strain increments with engineering shear.

- **Rotation of the principal stress axes**: the largest change of
  α = ½ atan2(2σxy, σxx - σyy) (degrees, mod 180°) from the first state with mobilized
  shear, R/P >= :data:`MOBILIZED`, over the mobilized states (R = the deviator's radius,
  P = -(σxx + σyy)/2).
- **Load reversal**: the deviatoric stress power s' : Δε = ½(σxx - σyy)(Δεxx - Δεyy) +
  σxy Δγxy (stress at the start of the step) turned negative after positive mobilized
  loading, and the point later loaded plastically with its major axis turned by more than
  45° from the one at that unloading (the deviator reversed: 2α turned by more than 90°).
  Elastic unloading, and unloading then plastic reloading the same way (beside a shear
  band after the peak), are no reversal: the tiers share the elasticity, and the fabric
  a reloading meets is the one it left.
- **Distance from the critical state**: the largest |c - c*|, c the hardening variable.
  Reported; it is no class of its own, the measured bounds of a class already hold it.

A point's loading class is "reversal" when it saw a reversal or its axes rotated by more
than :data:`ROTATION_LIMIT_DEG`, else "monotonic".
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

ROTATION_LIMIT_DEG = 15.0
MOBILIZED = 0.1
"""Stress ratio R/P above which the shear counts as mobilized."""
CLASSES = ("monotonic", "reversal")


@dataclass(frozen=True)
class Indicators:
    """Indicators of one point (or the worst over points): see the module doc."""

    axes_rotation_deg: float
    reversal: bool
    critical_distance: float

    @property
    def loading(self) -> str:
        rotated = self.axes_rotation_deg > ROTATION_LIMIT_DEG
        return "reversal" if (self.reversal or rotated) else "monotonic"


def _ratio_and_axis(stress: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """R/P and the major principal direction α (radians) of Voigt stresses (n, 3)."""
    half = 0.5 * (stress[:, 0] - stress[:, 1])
    radius = np.hypot(half, stress[:, 2])
    pressure = -0.5 * (stress[:, 0] + stress[:, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        rp = np.where(pressure > 0, radius / pressure, 0.0)
    return rp, 0.5 * np.arctan2(2.0 * stress[:, 2], stress[:, 0] - stress[:, 1])


def _turn(alpha: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """|α - ref| mod π, in [0, π/2] (NaN where ref is NaN)."""
    return np.abs((alpha - ref + 0.5 * np.pi) % np.pi - 0.5 * np.pi)


class Tracker:
    """Running indicators of ``n`` points from their initial stress (module doc)."""

    def __init__(self, stress0: np.ndarray, c_star: float):
        stress0 = np.asarray(stress0, dtype=float)
        n = len(stress0)
        rp, alpha = _ratio_and_axis(stress0)
        self.c_star = c_star
        self.alpha0 = np.where(rp >= MOBILIZED, alpha, np.nan)
        self.rotation = np.zeros(n)               # radians
        self.positive = np.zeros(n, dtype=bool)   # positive mobilized deviatoric power seen
        self.unloaded = np.zeros(n, dtype=bool)   # ... and a negative one after it
        self.alpha_unload = np.full(n, np.nan)     # α at the start of the last unloading
        self.reversal = np.zeros(n, dtype=bool)   # ... then plastic with the deviator reversed
        self.critical = np.zeros(n)
        self.steps = 0

    def update(self, stress_n, stress, dstrain, plastic, c=None) -> None:
        """One committed step: start and end stresses (n, 3), the strain increment (n, 3),
        Voigt with engineering shear, whether each point ended it plastic, and its c."""
        stress_n, stress, de = (np.asarray(a, dtype=float) for a in (stress_n, stress, dstrain))
        rp_n, alpha_n = _ratio_and_axis(stress_n)
        power = 0.5 * (stress_n[:, 0] - stress_n[:, 1]) * (de[:, 0] - de[:, 1]) \
            + stress_n[:, 2] * de[:, 2]
        unloading = self.positive & (power < 0) & (rp_n >= MOBILIZED)
        self.alpha_unload = np.where(unloading, alpha_n, self.alpha_unload)
        self.unloaded |= unloading
        self.positive |= (power > 0) & (rp_n >= MOBILIZED)
        rp, alpha = _ratio_and_axis(stress)
        mobilized = rp >= MOBILIZED
        reversed_ = _turn(alpha, self.alpha_unload) > 0.25 * np.pi
        self.reversal |= self.unloaded & np.asarray(plastic, dtype=bool) & mobilized & reversed_
        self.alpha0 = np.where(np.isnan(self.alpha0) & mobilized, alpha, self.alpha0)
        turn = _turn(alpha, self.alpha0)
        self.rotation = np.where(mobilized & np.isfinite(turn),
                                 np.maximum(self.rotation, turn), self.rotation)
        if c is not None:
            self.critical = np.maximum(self.critical, np.abs(np.asarray(c, float) - self.c_star))
        self.steps += 1

    def reversal_class(self) -> np.ndarray:
        """(n,) bool: the points whose loading class is "reversal"."""
        return self.reversal | (np.degrees(self.rotation) > ROTATION_LIMIT_DEG)

    def point(self, i: int) -> Indicators:
        return Indicators(float(np.degrees(self.rotation[i])), bool(self.reversal[i]),
                          float(self.critical[i]))

    def worst(self, where: np.ndarray | None = None) -> Indicators:
        """The largest rotation, any reversal and the largest |c - c*| over ``where``."""
        sel = slice(None) if where is None else where
        rot, crit = np.degrees(self.rotation[sel]), self.critical[sel]
        return Indicators(float(rot.max()) if rot.size else 0.0,
                          bool(self.reversal[sel].any()), float(crit.max()) if crit.size else 0.0)


def indicators(history: Mapping[str, np.ndarray], c_star: float) -> Indicators:
    """The indicators of a point's history (arrays per column, with ``gp``; ``c_p`` or
    ``c`` as the hardening c): rows are the committed states, plastic where gp grew."""
    stress = np.column_stack([np.asarray(history[k], float) for k in ("sxx", "syy", "sxy")])
    strain = np.column_stack([np.asarray(history[k], float) for k in ("eps_xx", "eps_yy")]
                             + [2.0 * np.asarray(history["eps_xy"], float)])
    plastic = np.diff(np.asarray(history["gp"], float)) > 0
    c = np.asarray(history["c_p" if "c_p" in history else "c"], float)
    tracker = Tracker(stress[:1], c_star)
    for i in range(len(stress) - 1):
        tracker.update(stress[i:i + 1], stress[i + 1:i + 2], strain[i + 1:i + 2] - strain[i:i + 1],
                       plastic[i:i + 1], c[i + 1:i + 2] if np.isfinite(c[i + 1]) else None)
    return tracker.point(0)

"""Localization in a strain field: how concentrated the shear is, and the band's angle.

For a strain field per quadrature point (Voigt, engineering shear; the total strain of a
run, or the increment between two states) the shear strain is
γ = sqrt((εxx - εyy)² + γxy²) (the diameter of Mohr's circle of strain). With the
quadrature weights w (areas):

* ``contrast``: the weighted coefficient of variation std(γ)/mean(γ) (0 for a uniform
  field);
* ``peak_ratio``: the mean γ of the most strained 10 % of the area over the mean γ;
* ``half_area``: the smallest share of the area that carries half of ∫γ dA (0.5 for a
  uniform field, the smaller the more the shear concentrates);
* ``angle_deg``: the band's inclination from the x axis in [0°, 180°), and ``offset`` its
  signed distance from the mesh centre: the straight strip, two elements wide, that holds
  the largest ∫ max(γ - median γ, 0) dA over the strips at every whole degree and every
  offset (a discrete Radon transform of the excess shear strain: a long band beats a
  corner); ``band_share`` = the share of ∫ max(γ - median γ, 0) dA in that strip.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from contfab.fem.output import plot_field

TOP_PEAK = 0.10


def shear_strain(strain: np.ndarray) -> np.ndarray:
    """γ per point of Voigt strains (n, 3) with engineering shear."""
    strain = np.asarray(strain, dtype=float)
    return np.hypot(strain[:, 0] - strain[:, 1], strain[:, 2])


def _top(gamma: np.ndarray, w: np.ndarray, share: float) -> np.ndarray:
    """Mask of the most strained points holding ``share`` of the area (at least one)."""
    order = np.argsort(gamma)[::-1]
    area = np.cumsum(w[order]) / w.sum()
    mask = np.zeros(len(gamma), bool)
    mask[order[:max(1, int(np.searchsorted(area, share)) + 1)]] = True
    return mask


def localization(disc, strain: np.ndarray) -> dict:
    """The measures of the module doc for ``strain`` (npoints, 3) on ``disc``."""
    gamma = shear_strain(strain)
    w = disc.weights.reshape(-1)
    if len(gamma) != len(w):
        raise ValueError(f"strain has {len(gamma)} points, the mesh {len(w)}")
    mean = float(np.sum(w * gamma) / w.sum())
    if not mean > 0:
        raise ValueError(f"mean shear strain {mean} out of range; accepted > 0 (a strained field)")
    std = float(np.sqrt(np.sum(w * (gamma - mean) ** 2) / w.sum()))
    peak = _top(gamma, w, TOP_PEAK)
    order = np.argsort(gamma)[::-1]
    carried = np.cumsum(w[order] * gamma[order]) / np.sum(w * gamma)
    half = float(np.sum(w[order][:int(np.searchsorted(carried, 0.5)) + 1]) / w.sum())
    excess = w * np.maximum(gamma - np.median(gamma), 0.0)
    angle, offset, share = _strongest_strip(disc, excess)
    return {"mean_gamma": mean, "max_gamma": float(gamma.max()), "contrast": std / mean,
            "peak_ratio": float(np.sum(w[peak] * gamma[peak]) / w[peak].sum() / mean),
            "half_area": half, "angle_deg": angle, "offset": offset, "band_share": share}


def _strongest_strip(disc, excess: np.ndarray) -> tuple[float, float, float]:
    """(angle in degrees, offset from the centre, share of the excess) of the strip two
    elements wide holding the largest sum of ``excess`` (module doc)."""
    xy = disc.points - 0.5 * (disc.points.max(axis=0) + disc.points.min(axis=0))
    width = 2.0 * np.sqrt(disc.weights.sum() / disc.ne)
    total = excess.sum()
    if not total > 0:
        return float("nan"), float("nan"), 0.0
    best = (-1.0, 0.0, 0.0)
    for deg in range(180):
        t = np.radians(deg)
        d = -np.sin(t) * xy[:, 0] + np.cos(t) * xy[:, 1]
        for c in np.arange(d.min(), d.max() + 0.25 * width, 0.25 * width):
            held = excess[np.abs(d - c) <= 0.5 * width].sum()
            if held > best[0]:
                best = (held, float(deg), float(c))
    return best[1], best[2], float(best[0] / total)


def band_figure(path: str | Path, disc, strain: np.ndarray, title: str) -> Path:
    """PNG of the element-mean shear strain γ of ``strain`` on the mesh."""
    return plot_field(path, disc, disc.element_mean(shear_strain(strain)), "shear strain γ", title)

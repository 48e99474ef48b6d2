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
* ``angle_deg``: the band's inclination from the x axis in [0°, 180°): the principal axis
  of the second moments of the points' positions weighted by w·max(γ - median γ, 0)
  (the points strained above the median, the more the heavier); ``elongation`` = the
  ratio of the larger to the smaller principal extent of that weight (1: a blob, large:
  a line-like band).
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
    wb = w * np.maximum(gamma - np.median(gamma), 0.0)
    if not wb.sum() > 0:
        wb = w
    xy = disc.points
    d = xy - np.average(xy, axis=0, weights=wb)
    cov = (d * wb[:, None]).T @ d / wb.sum()
    vals, vecs = np.linalg.eigh(cov)
    major = vecs[:, 1]
    angle = float(np.degrees(np.arctan2(major[1], major[0])) % 180.0)
    return {"mean_gamma": mean, "max_gamma": float(gamma.max()), "contrast": std / mean,
            "peak_ratio": float(np.sum(w[peak] * gamma[peak]) / w[peak].sum() / mean),
            "half_area": half, "angle_deg": angle,
            "elongation": float(np.sqrt(vals[1] / vals[0])) if vals[0] > 0 else float("inf")}


def band_figure(path: str | Path, disc, strain: np.ndarray, title: str) -> Path:
    """PNG of the element-mean shear strain γ of ``strain`` on the mesh."""
    return plot_field(path, disc, disc.element_mean(shear_strain(strain)), "shear strain γ", title)

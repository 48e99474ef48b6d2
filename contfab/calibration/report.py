"""The DEM-vs-model report: overlay plots and error tables (PNG, CSV, Markdown).

``overlay_plot``: one PNG per path, six panels (R/P, ε_v, c, A, B, θp) against the
path's continuous abscissa (:attr:`contfab.calibration.curves.Grid.x`): the DEM seed mean with a band
of ± one seed standard deviation, and one line per model. ``error_rows`` flattens
:func:`contfab.calibration.curves.errors` into table rows written by :func:`write_tables` as CSV and a
Markdown table. ``probe_plot``: the plastic strain responses of a probe family, DEM and
models, with the fitted yield normals and flow directions. Every file is written
atomically; matplotlib is imported lazily (Agg).
"""
from __future__ import annotations

import math
from pathlib import Path as FsPath
from typing import Mapping, Sequence

import numpy as np

from contfab.calibration.curves import QUANTITIES, DemCurve
from contfab.plots import pyplot, save_figure
from dem.fileio import atomic_path, write_csv

LABELS = {"RP": "R/P", "eps_v": "ε_v (dilation > 0)", "c": "packing fraction c",
          "A": "A = z/π", "B": "B", "theta_p": "θp (deg)"}
ERROR_COLUMNS = ("role", "path", "model", "quantity", "rms", "residual_dem", "residual_model",
                 "residual_error", "residual_rel", "dem_scatter", "rms_transient")


def _save(fig, plt, file) -> FsPath:
    save_figure(fig, plt, file)
    return FsPath(file)


def overlay_plot(curve: DemCurve, models: Mapping[str, Mapping[str, np.ndarray]], file,
                 title: str = "") -> FsPath:
    """DEM mean ± scatter and each model's sample, six panels (module doc)."""
    plt = pyplot()
    fig, axes = plt.subplots(3, 2, figsize=(10, 8), sharex=True)
    x = curve.grid.x
    for ax, q in zip(axes.T.ravel(), QUANTITIES):
        scale = 180.0 / math.pi if q == "theta_p" else 1.0
        m, s = curve.mean[q] * scale, curve.std[q] * scale
        if np.any(np.isfinite(m)):
            ax.fill_between(x, m - s, m + s, color="0.8", lw=0)
            ax.plot(x, m, "k-", lw=1.6, label="DEM (seed mean ± sd)")
        for k, (name, sample) in enumerate(models.items()):
            if q in sample and np.any(np.isfinite(sample[q])):
                ax.plot(x, sample[q] * scale, lw=1.2, label=name, color=f"C{k}")  # one colour a model
        ax.set_ylabel(LABELS[q])
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("reference strain τ along the path")
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(title)
    return _save(fig, plt, file)


def error_rows(role: str, path: str, model: str, errs: Mapping[str, Mapping]) -> list[dict]:
    return [{"role": role, "path": path, "model": model, "quantity": q, **e}
            for q, e in errs.items()]


def _fmt(v) -> str:
    if isinstance(v, float):
        return "" if math.isnan(v) else f"{v:.4g}"
    return str(v)


def markdown_table(rows: Sequence[Mapping], columns: Sequence[str]) -> str:
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(_fmt(r.get(c, "")) for c in columns) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def write_tables(rows: Sequence[Mapping], stem: FsPath) -> tuple[FsPath, FsPath]:
    """``stem``.csv and ``stem``.md of the error rows."""
    stem = FsPath(stem)
    csv_file = write_csv(stem.with_suffix(".csv"), ERROR_COLUMNS,
                         [[r.get(c) for c in ERROR_COLUMNS] for r in rows])
    md = stem.with_suffix(".md")
    with atomic_path(md) as tmp:
        tmp.write_text(markdown_table(rows, ERROR_COLUMNS))
    return csv_file, md


def probe_plot(responses: Mapping[str, object], analyses: Mapping[str, object], file,
               title: str = "") -> FsPath:
    """Plastic strain responses (normalized per family) with the fitted normal (dashed)
    and flow direction (solid) of each family."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(5.5, 5.5))
    for k, (name, resp) in enumerate(responses.items()):
        color = f"C{k}"
        p = resp.plastic / np.abs(resp.plastic).max()
        ax.plot(p[:, 0], p[:, 1], "o", ms=3, color=color, label=name)
        a = analyses[name]
        for ang, style in ((a.normal_deg, "--"), (a.flow_deg, "-")):
            ax.plot([0, math.cos(math.radians(ang))], [0, math.sin(math.radians(ang))], style,
                    color=color, lw=1.2)
    ax.axhline(0, color="k", lw=0.5)
    ax.axvline(0, color="k", lw=0.5)
    ax.set_xlabel("Δεp_xx (normalized)   [--- yield normal, — flow]")
    ax.set_ylabel("Δεp_yy (normalized)")
    ax.set_aspect("equal")
    ax.legend(fontsize=7)
    ax.set_title(title)
    return _save(fig, plt, file)

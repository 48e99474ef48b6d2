"""PNG plots of material-point runs (:class:`contfab.material_point.PointResult`).

``history_plot``: R/P, ε_v and c against the reference strain τ (the driving strain of
the standard paths, as in the DEM's plot, so the two read alike), plus A, B and θp for
tiers that carry a fabric; several runs (a probe family) are overlaid. ``response_plot``:
for a probe family, the stress increments and the strain responses at the end of each
probe (the response envelope of Karapiperis et al. 2020, in 2D). matplotlib is imported
lazily (Agg backend), and every file is written atomically.
"""
from __future__ import annotations

import numpy as np

from dem.fileio import atomic_path


def pyplot():
    """matplotlib.pyplot with the Agg backend (imported lazily)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def save_figure(fig, plt, file) -> None:
    """Lay out, write ``file`` atomically, close the figure."""
    fig.tight_layout()
    with atomic_path(file) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)


def history_plot(results, file, title: str = "") -> None:
    """R/P, ε_v, c (and A, B, θp in degrees with a fabric) against τ, one line per run."""
    plt = pyplot()
    panels = [("RP", "R/P"), ("eps_v", "ε_v (dilation > 0)"), ("c", "packing fraction c")]
    if results[0].has_fabric:
        panels += [("A", "A = z/π"), ("B", "B"), ("theta_p", "θp (deg)")]
    panels = [(k, label) for k, label in panels if k in results[0].history]
    fig, axes = plt.subplots(len(panels), 1, figsize=(6, 2.2 * len(panels) + 0.6), sharex=True,
                             squeeze=False)
    single = len(results) == 1
    for ax, (key, label) in zip(axes[:, 0], panels):
        for res in results:
            y = np.degrees(res[key]) if key == "theta_p" else res[key]
            ax.plot(res["tau"], y, lw=1.5 if single else 0.8)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("reference strain τ")
    axes[0, 0].set_title(title)
    save_figure(fig, plt, file)


def response_plot(results, file, title: str = "") -> None:
    """Probe family: stress increments (Δσxx, Δσyy) and strain responses (Δεxx, Δεyy)."""
    plt = pyplot()
    ds = np.array([[r["sxx"][-1] - r["sxx"][0], r["syy"][-1] - r["syy"][0]] for r in results])
    de = np.array([[r["eps_xx"][-1] - r["eps_xx"][0], r["eps_yy"][-1] - r["eps_yy"][0]]
                   for r in results])
    fig, ax = plt.subplots(1, 2, figsize=(9, 4.4))
    for a, v, name, unit in ((ax[0], ds, "Δσ", " (units of P0)"), (ax[1], de, "Δε", "")):
        closed = np.vstack([v, v[:1]])
        a.plot(closed[:, 0], closed[:, 1], "o-", ms=3)
        a.axhline(0, color="k", lw=0.5)
        a.axvline(0, color="k", lw=0.5)
        a.set_xlabel(f"{name}xx{unit}")
        a.set_ylabel(f"{name}yy{unit}")
        a.set_aspect("equal", adjustable="datalim")
        a.grid(alpha=0.3)
    ax[0].set_title("stress probes")
    ax[1].set_title("strain responses")
    fig.suptitle(title)
    save_figure(fig, plt, file)

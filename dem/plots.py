"""PNG plots of a DEM run: stress ratio, volumetric strain and coordination along the
path, and the polar histogram of contact normals with its A + B cos 2(θ - θp) fit."""
from __future__ import annotations

import numpy as np

from dem.conventions import fabric_polar, fabric_state
from dem.fileio import atomic_path
from dem.measure import Contacts, fabric_tensor, normal_histogram
from dem.state import State


def _figure():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def history_plot(rows: list[dict], file, title: str = "") -> None:
    """R/P, ε_v and z (with and without rattlers) against the reference strain τ."""
    plt = _figure()
    tau = np.array([r["tau"] for r in rows])
    fig, ax = plt.subplots(3, 1, figsize=(6, 8), sharex=True)
    ax[0].plot(tau, [r["RP"] for r in rows])
    ax[0].set_ylabel("R/P")
    ax[1].plot(tau, [r["eps_v"] for r in rows])
    ax[1].set_ylabel("ε_v (dilation > 0)")
    ax[2].plot(tau, [r["z"] for r in rows], label="z")
    ax[2].plot(tau, [r["z_no_rattlers"] for r in rows], label="z, rattlers excluded")
    ax[2].set_ylabel("coordination")
    ax[2].legend()
    ax[2].set_xlabel("reference strain τ")
    ax[0].set_title(title)
    fig.tight_layout()
    with atomic_path(file) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)


def polar_plot(state: State, file, title: str = "") -> None:
    """Histogram of contact normals (per disc, per radian; both n and -n) and the fit."""
    plt = _figure()
    c = Contacts(state)
    theta, p = normal_histogram(c.n, state.n)
    a, bc, bs = fabric_state(*fabric_tensor(c.n, state.n))
    b, tp = fabric_polar(bc, bs)
    fine = np.linspace(0, 2 * np.pi, 361)
    fit = a + b * np.cos(2 * (fine - tp))
    fig = plt.figure(figsize=(5, 5))
    ax = fig.add_subplot(projection="polar")
    width = theta[1] - theta[0]
    ax.bar(np.r_[theta, theta + np.pi], np.r_[p, p], width=width, alpha=0.5, label="DEM")
    ax.plot(fine, fit, "k-", label=f"A + B cos 2(θ-θp): A={a:.3f}, B={b:.3f}, "
                                   f"θp={np.degrees(tp):.1f}°")
    ax.set_title(title)
    ax.legend(loc="lower center", bbox_to_anchor=(0.5, -0.2), fontsize=8)
    fig.tight_layout()
    with atomic_path(file) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)

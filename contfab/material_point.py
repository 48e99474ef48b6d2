r"""The material-point driver: one constitutive point driven along a loading path.

It runs the loading paths the DEM cell runs (:mod:`dem.paths`, docs/theory.md §10) through the
one update interface :func:`contfab.models.tiers.update`, so every model tier works the
same way, and returns the history as arrays (:class:`PointResult`); writing files is a
separate step (:mod:`contfab.calibration.point_job`). Nothing here does I/O.

**Kinematics.** Time is the reference strain τ of the path. An increment Δτ of a stage
gives the velocity-gradient increment ΔL (components xx, yy, xy, yx; L_xy = ∂v_x/∂y) and

    Δε = (ΔL_xx, ΔL_yy, ΔL_xy + ΔL_yx)      (D = sym L; Voigt, engineering shear)
    Δω = (ΔL_yx - ΔL_xy) / 2                 (ω = skew L; counter-clockwise)

Rate-controlled components are ΔL_i = rate_i Δτ. The accumulated strain is ε = ∫ D dτ
(as the DEM's), the spin angle ω = ∫ ω dτ.

**Mixed control.** The stress-controlled components x = ΔL_c are unknown; the stress
targets σ*_c of :meth:`dem.paths.Stage.stress_target` at the end of the increment must hold:
r(x) = σ_{n+1}[i(c)] - σ*_c = 0, solved by Newton with the exact Jacobian

    ∂σ/∂ΔL_xx = T[:, 0],   ∂σ/∂ΔL_yy = T[:, 1],
    ∂σ/∂ΔL_xy = T[:, 2] - S/2,   ∂σ/∂ΔL_yx = T[:, 2] + S/2,

with T the consistent tangent ∂σ_{n+1}/∂Δε of the update and S = ∂σ_{n+1}/∂Δω. Every tier
rotates its inputs (stress, fabric) by the exact angle Δω and then updates objectively,
U(Qσ, Qq, QΔεQᵀ) = Q U(σ, q, Δε) Qᵀ; differentiating that identity in the rotation angle
gives, without any further derivative from the kernel,

    S = W(σ_{n+1}) - T W(Δε),   W(s) = d/dα (Q_α s Q_αᵀ) at α = 0
      = (-2 s_xy, 2 s_xy, s_xx - s_yy) for a stress, (-Δγ, Δγ, 2(Δε_xx - Δε_yy)) for Δε.

The solve starts from the previous increment's rates of the unknowns. It has converged
when max |r| <= min(RTOL · s + ROUNDOFF · (s + E_reg max |Δε|), TOL_CAP · s), s = max(|σ_n|, |σ*|)
(scale-free:
the model has no stress scale besides the regularization's E_reg = λ p_ref, whose C Δε
sets the round-off of the trial stress).

**Increments.** The knob is the increment Δτ_max (reference strain). Each output interval
of a stage (:attr:`dem.paths.Stage.output_interval`; the last one may be shorter) is split
into equal increments no larger than the current increment, so every output row lands
exactly on its τ and runs with different increments can be compared row by row. A stage
ends at its ``length`` or where an ``until`` quantity crosses its value
(:meth:`dem.paths.Stage.stop_reached`); the crossing is located inside the increment by
the Illinois (regula falsi) method on the increment fraction, so the end point depends on
the strain path, not on the increments. Stress ramps run over the full stage length.

**Step cutting.** An increment whose update fails at any point (status -1) or whose Newton
solve does not converge in NEWTON_MAXIT iterations (or meets a singular Jacobian, e.g. at
the apex where the tangent is zero) is retried at half the size from the committed state;
after a success the increment doubles again, up to the knob. Below ``min_increment`` the
run stops with :class:`IntegrationError`, naming the stage, τ, the last failure and the
stress targets.

**Units.** Path stresses are in units of P0, identified with the parameters' p_ref: the
model sees σ_model = p_ref · σ_path, and the history reports σ_model / p_ref. The start is
σ = -P0 I (isotropic at P0 = 1) and the ``[initial]`` state, unless given.

**History.** Rows at τ = 0 and at every output time, and at each stage end, with the
columns :data:`dem.history.HISTORY_COLUMNS` (fabric columns absent for tiers without a
fabric) plus :data:`EXTRA_COLUMNS`. c is the packing fraction the DEM measures (disc area
/ cell area, following the total strain): for tiers >= 1 :func:`contfab.models.tiers.
packing_fraction` of the state's hardening variable c_p (its own column, ``c_p``), for
tier 0 (no state) c0 exp(-ε_v) (empty without an ``[initial]`` section).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from dem.conventions import admissibility_margin, fabric_polar, pressure
from dem.history import HISTORY_COLUMNS, history_row
from dem.paths import COMPONENTS, STRESS_INDEX, Path, Stage, load_path
from dem.threads import numba_threads
from contfab.models import tiers
from contfab.models.tiers import spin_derivative
from contfab.params import Params, default_params

RTOL = 1e-12
"""Newton tolerance on the stress targets, relative to the stress level (module doc)."""
ROUNDOFF = 64.0 * np.finfo(float).eps
"""Round-off floor of the stress residual, relative to the trial stress magnitude."""
TOL_CAP = 1e-6
"""The round-off allowance never exceeds this fraction of the stress level: it grows with
E_reg |Δε| (the trial stress's round-off), and an unknown strain running away at a stress
target the model cannot carry (measured: Δε_yy = -4e14 at the apex, σ = 0 against a
target of -3 P0) must not make any residual pass. Legitimate increments stay far below
it (λ = 1e8, |Δε| = 0.1: 1.4e-7)."""
NEWTON_MAXIT = 25
DEFAULT_INCREMENT = 1e-3
"""Default increment Δτ_max (reference strain); see ``contfab bench point`` for its error."""
MIN_INCREMENT_FRACTION = 1e-6
"""Default minimum increment, as a fraction of the increment knob."""
STOP_RTOL = 1e-10
"""A stop crossing is located to this fraction of its quantity's change over the increment."""
STOP_MAXIT = 60

FABRIC_COLUMNS = ("z", "A", "Bc", "Bs", "B", "theta_p")
EXTRA_COLUMNS = ("gp", "c_p", "omega", "increments")
"""Driver columns after the shared ones: accumulated plastic shear strain Σ(Δεp1 - Δεp2),
the hardening packing fraction c_p (tiers >= 1; module doc), accumulated spin angle ∫ω dτ
(radians), and increments taken since the path start."""

STRAIN_OF_L = np.array([[1.0, 0.0, 0.0, 0.0],
                        [0.0, 1.0, 0.0, 0.0],
                        [0.0, 0.0, 1.0, 1.0]])
"""Δε (Voigt, engineering shear) = STRAIN_OF_L @ ΔL, ΔL in COMPONENTS order."""
SPIN_OF_L = np.array([0.0, 0.0, -0.5, 0.5])
"""Δω = SPIN_OF_L @ ΔL."""


class IntegrationError(ValueError):
    """The path cannot be followed: the increment was cut below its minimum.

    ``partial`` holds the :class:`PointResult` up to the last committed increment.
    """

    def __init__(self, message: str, partial: "PointResult | None" = None):
        super().__init__(message)
        self.partial = partial


# --------------------------------------------------------------------------- one increment

def control_jacobian(stress: np.ndarray, tangent: np.ndarray, dstrain: np.ndarray) -> np.ndarray:
    """(3, 4) ∂σ_{n+1}/∂ΔL, columns in COMPONENTS order (module doc)."""
    return tangent @ STRAIN_OF_L + np.outer(spin_derivative(stress, tangent, dstrain), SPIN_OF_L)


@dataclass
class StepSolution:
    """Outcome of :func:`solve_increment` (``stress``/``state`` are copies, model units)."""

    converged: bool
    dl: np.ndarray
    stress: np.ndarray
    state: np.ndarray
    status: int
    residuals: list[float]
    evaluations: int
    reason: str = ""


def solve_increment(tier: int, params: Params, stress_n: np.ndarray, state_n: np.ndarray,
                    dl: np.ndarray, unknown: np.ndarray, target: np.ndarray,
                    rtol: float = RTOL, maxit: int = NEWTON_MAXIT,
                    out: tiers.UpdateResult | None = None) -> StepSolution:
    """One mixed-control increment: find ΔL[unknown] so that σ_{n+1} meets ``target``.

    ``dl`` (4,) holds the prescribed ΔL of the rate-controlled components and the initial
    guess of the unknown ones (COMPONENTS order); ``unknown`` (4,) bool marks the
    stress-controlled ones; ``target`` (3,) the stress at the end of the increment (only
    the controlled entries are read), model units. ``residuals`` lists max |r| of every
    evaluation. Nothing is committed: the caller keeps or drops the result.
    """
    cols = [c for c in range(4) if unknown[c]]
    rows = [STRESS_INDEX[COMPONENTS[c]] for c in cols]
    dl = np.array(dl, dtype=np.float64)
    s_n = np.ascontiguousarray(stress_n, dtype=np.float64).reshape(1, 3)
    q_n = np.ascontiguousarray(state_n, dtype=np.float64).reshape(1, -1)
    goal = [float(target[i]) for i in rows]
    scale = max(max(map(abs, s_n[0].tolist())), max(map(abs, goal), default=0.0))
    if scale == 0.0:
        scale = params.p_ref
    e_reg = params.regularization.lam * params.p_ref
    spin_unknown = any(SPIN_OF_L[c] != 0.0 for c in cols)
    dstrain = np.empty((1, 3))
    dspin = np.empty(1)
    residuals: list[float] = []
    reason = f"Newton did not converge in {maxit} iterations"
    for it in range(maxit + 1):
        d = dl.tolist()
        dstrain[0, 0] = d[0]
        dstrain[0, 1] = d[1]
        dstrain[0, 2] = d[2] + d[3]
        dspin[0] = 0.5 * (d[3] - d[2])
        out = tiers.update(tier, s_n, q_n, dstrain, dspin, params, out=out)
        status = int(out.status[0])
        if status < 0:
            reason = "the constitutive update failed (status -1)"
            break
        sigma = out.stress[0].tolist()
        r = [sigma[i] - g for i, g in zip(rows, goal)]
        err = max(map(abs, r), default=0.0)
        if cols:
            residuals.append(err)
        tol = min(rtol * scale + ROUNDOFF * (scale + e_reg * max(abs(d[0]), abs(d[1]), abs(d[2] + d[3]))),
                  TOL_CAP * scale)
        if err <= tol:
            return StepSolution(True, dl, out.stress[0].copy(), out.state[0].copy(), status,
                                residuals, it + 1)
        if it == maxit or not math.isfinite(err):
            break
        t = out.tangent[0]
        full = control_jacobian(out.stress[0], t, dstrain[0]) if spin_unknown else t @ STRAIN_OF_L
        jac = full[rows][:, cols]
        try:
            step = np.linalg.solve(jac, r) if len(cols) > 1 else [r[0] / float(jac[0, 0])]
        except (np.linalg.LinAlgError, ZeroDivisionError):
            step = [math.inf]
        if not all(map(math.isfinite, step)):
            reason = f"singular control Jacobian (status {status}: {tiers.STATUS_NAMES[status]})"
            break
        dl[cols] -= step
    return StepSolution(False, dl, s_n[0].copy(), q_n[0].copy(), -1, residuals, it + 1, reason)


# --------------------------------------------------------------------------- results

@dataclass(frozen=True)
class PointResult:
    """The history of one material point along one (expanded) path.

    ``history`` maps each column (:attr:`columns`) to a float array, one entry per row;
    stresses in units of P0 = p_ref. ``stress``/``state`` are the final values in model
    units (``state`` in the columns ``tiers.STATE_NAMES[tier]``), ready to start another run.
    ``stats``: increments, cuts, update evaluations, Newton iterations, stop reasons per
    stage, seconds, the increment knob and minimum.
    """

    path: Path
    tier: int
    columns: tuple[str, ...]
    history: Mapping[str, np.ndarray]
    stress: np.ndarray
    state: np.ndarray
    stats: Mapping[str, object]

    def __contains__(self, column: str) -> bool:
        return column in self.history

    def __getitem__(self, column: str) -> np.ndarray:
        if column not in self.history:
            raise KeyError(f"no column {column!r} in this history (tier {self.tier}); "
                           f"columns: {', '.join(self.columns)}")
        return self.history[column]

    @property
    def has_fabric(self) -> bool:
        return "A" in self.history

    def rows(self) -> tuple[tuple[str, ...], list[list]]:
        """(column names, rows) for :func:`dem.fileio.write_csv`: all shared columns, the
        absent ones (fabric of tiers without one) as empty cells, then the extra columns."""
        names = HISTORY_COLUMNS + EXTRA_COLUMNS
        n = len(self.history["tau"])
        cols = [self.history.get(c) for c in names]
        table = []
        for i in range(n):
            row = []
            for name, col in zip(names, cols):
                if col is None:
                    row.append(None)
                elif name in ("stage", "increments"):
                    row.append(int(col[i]))
                else:
                    row.append(float(col[i]))
            table.append(row)
        return names, table


# --------------------------------------------------------------------------- the path runner

@dataclass
class _Point:
    """Committed state of the point (model units) and its accumulated kinematics."""

    stress: np.ndarray
    state: np.ndarray
    strain: np.ndarray = field(default_factory=lambda: np.zeros(3))   # tensor (xx, yy, xy)
    omega: float = 0.0
    tau: float = 0.0
    increments: int = 0


class _Runner:
    """Runs the stages of one path on a point (see the module doc)."""

    def __init__(self, path: Path, params: Params, tier: int, increment: float,
                 min_increment: float, rtol: float):
        self.path, self.params, self.tier = path, params, tier
        self.increment, self.min_increment, self.rtol = increment, min_increment, rtol
        self.bar = None               # a tqdm bar over τ, set by the caller
        self.h = increment
        self.p_ref = params.p_ref
        names = tiers.STATE_NAMES[tier]
        self.i_c = names.index("c") if "c" in names else None
        self.i_fabric = [names.index(k) for k in ("A", "Bc", "Bs")] if "A" in names else None
        initial = params.sections.get("initial")
        self.c0 = initial.c0 if initial is not None else None
        self.columns = tuple(
            c for c in HISTORY_COLUMNS + EXTRA_COLUMNS
            if not (c in FABRIC_COLUMNS and self.i_fabric is None)
            and not (c == "c" and self.i_c is None and self.c0 is None)
            and not (c == "c_p" and self.i_c is None))
        for k, stage in enumerate(path.stages):
            for cond in stage.until:
                if cond.quantity not in self.columns:
                    raise ValueError(
                        f"path {path.name!r}, stage {k} ({stage.name!r}): until.{cond.quantity} "
                        f"is not a quantity of tier {tier} (it carries no "
                        f"{'fabric' if cond.quantity in FABRIC_COLUMNS else 'packing fraction'}); "
                        f"accepted: {[c for c in self.columns if c not in ('stage', 'tau')]}")
        self.out = tiers.allocate(tier, 1)
        self.rows: list[dict] = []
        self.stats = {"increments": 0, "cuts": 0, "evaluations": 0, "newton_iterations": 0,
                      "stops": []}
        self.unknown = None           # the current stage's stress-controlled L components
        self.rate = None              # and its prescribed rates
        self.predict = None           # rates of the unknowns in the last increment

    # -- rows

    def row(self, pt: _Point, stage: int) -> dict:
        if self.i_c is not None:
            c = float(tiers.packing_fraction(pt.state[self.i_c], pressure(pt.stress[0], pt.stress[1]),
                                            self.params))
        elif self.c0 is not None:
            c = self.c0 * math.exp(-(pt.strain[0] + pt.strain[1]))
        else:
            c = math.nan             # tier 0 without [initial]: the column is dropped
        fabric = pt.state[self.i_fabric] if self.i_fabric is not None else None
        row = history_row(stage, pt.tau, pt.stress / self.p_ref, pt.strain, c, fabric)
        row.update(gp=float(pt.state[0]), omega=pt.omega, increments=pt.increments)
        if self.i_c is not None:
            row["c_p"] = float(pt.state[self.i_c])
        return row

    def emit(self, pt: _Point, stage: int) -> None:
        self.rows.append(self.row(pt, stage))
        if self.bar is not None:
            self.bar.update(pt.tau - self.bar.n)

    # -- one attempt from the committed point

    def attempt(self, pt: _Point, stage: Stage, start_stress: np.ndarray, tau_in_stage: float,
                h: float) -> StepSolution:
        dl = self.rate * h
        if self.predict is not None:
            dl[self.unknown] = self.predict * h      # predictor: the last increment's rates
        target = self.p_ref * stage.stress_target(start_stress, (tau_in_stage + h) / stage.length)
        sol = solve_increment(self.tier, self.params, pt.stress, pt.state, dl, self.unknown,
                              target, self.rtol, out=self.out)
        self.stats["evaluations"] += sol.evaluations
        self.stats["newton_iterations"] += max(sol.evaluations - 1, 0)
        return sol

    @staticmethod
    def advance(pt: _Point, sol: StepSolution, h: float) -> _Point:
        """The point after the solved increment ``sol`` of size ``h`` (not yet committed)."""
        dl = sol.dl
        strain = pt.strain + np.array([dl[0], dl[1], 0.5 * (dl[2] + dl[3])])
        return _Point(sol.stress, sol.state, strain, pt.omega + 0.5 * (dl[3] - dl[2]),
                      pt.tau + h, pt.increments + 1)

    def accept(self, stage: Stage, sol: StepSolution, h: float) -> None:
        """Book an accepted increment: its rates predict the next one's unknowns."""
        self.predict = sol.dl[self.unknown] / h
        self.stats["increments"] += 1

    def fail(self, pt: _Point, stage_index: int, stage: Stage, start_stress, tau_in_stage,
             h: float, sol: StepSolution) -> IntegrationError:
        target = stage.stress_target(start_stress, min(1.0, (tau_in_stage + h) / stage.length))
        controlled = [c for c, s in zip(COMPONENTS, stage.stress_controlled) if s]
        last = f"; last residuals {['%.3g' % r for r in sol.residuals[-4:]]}" if sol.residuals else ""
        return IntegrationError(
            f"path {self.path.name!r}, stage {stage_index} ({stage.name!r}) at τ = {pt.tau:.6g}: "
            f"the increment was cut to {h:.3g} < min_increment = {self.min_increment:.3g} and "
            f"still fails: {sol.reason}{last}. Stress targets (units of P0) of the controlled "
            f"components {controlled}: {np.round(target, 6).tolist()}, stress now "
            f"{np.round(pt.stress / self.p_ref, 6).tolist()}. A stress target outside the "
            f"yield cone of tier {self.tier} cannot be reached (and one on the cone of a "
            f"non-hardening state leaves the plastic flow undetermined)")

    # -- a stage

    def run_stage(self, pt: _Point, k: int, stage: Stage) -> _Point:
        unknown = stage.stress_controlled
        if not np.array_equal(unknown, self.unknown):
            self.predict = None                # another control: no predictor yet
        self.unknown, self.rate = unknown, stage.rate_vector
        start_stress = pt.stress / self.p_ref
        start_row = self.row(pt, k) if stage.until else None
        if start_row is not None and stage.stop_reached(start_row, start_row):
            self.stats["stops"].append(f"until {stage.stop_reached(start_row, start_row)} at start")
            return pt
        interval = stage.output_interval
        n_out = max(1, math.ceil(stage.length / interval - 1e-9))
        tau_s = 0.0
        for j in range(1, n_out + 1):
            t_end = min(j * interval, stage.length)
            while tau_s < t_end:
                remaining = t_end - tau_s
                n = max(1, math.ceil(remaining / self.h - 1e-9))
                h = remaining / n
                sol = self.attempt(pt, stage, start_stress, tau_s, h)
                if not sol.converged:
                    self.stats["cuts"] += 1
                    self.h = h / 2.0
                    if self.h < self.min_increment:
                        raise self.fail(pt, k, stage, start_stress, tau_s, h, sol)
                    continue
                new = self.advance(pt, sol, h)
                if start_row is not None:
                    hit = stage.stop_reached(start_row, self.row(new, k))
                    if hit is not None:
                        new, sol, h = self.locate_stop(pt, new, sol, k, stage, start_stress,
                                                       tau_s, h, hit)
                        self.accept(stage, sol, h)
                        self.stats["stops"].append(f"until {hit}")
                        self.emit(new, k)
                        return new
                self.accept(stage, sol, h)
                pt = new
                tau_s = t_end if n == 1 else tau_s + h
                self.h = min(2.0 * self.h, self.increment)
            self.emit(pt, k)
        self.stats["stops"].append("length")
        return pt

    def locate_stop(self, pt: _Point, new: _Point, sol: StepSolution, k: int, stage: Stage,
                    start_stress, tau_s: float, h: float, quantity: str):
        """(point, solution, increment) where ``quantity`` crosses its value inside the
        increment from ``pt`` (to ``new``), by the Illinois method on the increment fraction."""
        value = next(u.value for u in stage.until if u.quantity == quantity)
        g_a = self.row(pt, k)[quantity] - value
        g_b = self.row(new, k)[quantity] - value
        if g_b == 0.0:
            return new, sol, h
        tol = STOP_RTOL * abs(g_b - g_a)
        a, b = 0.0, 1.0
        for _ in range(STOP_MAXIT):
            theta = (a * g_b - b * g_a) / (g_b - g_a)
            sol = self.attempt(pt, stage, start_stress, tau_s, theta * h)
            if not sol.converged:       # a shorter increment from the same state: not expected
                raise self.fail(pt, k, stage, start_stress, tau_s, theta * h, sol)
            new = self.advance(pt, sol, theta * h)
            g = self.row(new, k)[quantity] - value
            if abs(g) <= tol or b - a <= 1e-14:
                break
            if (g > 0.0) == (g_b > 0.0):
                b, g_b = theta, g
                g_a *= 0.5
            else:
                a, g_a = theta, g
                g_b *= 0.5
        return new, sol, theta * h

    def run(self, pt: _Point) -> _Point:
        self.emit(pt, 0)
        for k, stage in enumerate(self.path.stages):
            pt = self.run_stage(pt, k, stage)
        return pt

    def result(self, pt: _Point, seconds: float) -> PointResult:
        history = {c: np.array([r[c] for r in self.rows],
                               dtype=np.int64 if c in ("stage", "increments") else np.float64)
                   for c in self.columns}
        stats = dict(self.stats, seconds=seconds, increment=self.increment,
                     min_increment=self.min_increment)
        return PointResult(self.path, self.tier, self.columns, history, pt.stress.copy(),
                           pt.state.copy(), stats)


# --------------------------------------------------------------------------- entry points

def start_state(tier: int, params: Params, state0=None) -> np.ndarray:
    """(k,) initial state: the ``[initial]`` values, overridden by ``state0`` (an array in
    the order ``tiers.STATE_NAMES[tier]`` or a mapping name -> value), validated."""
    names = tiers.STATE_NAMES[tier]
    state = tiers.initial_state(tier, params, 1)[0]
    if state0 is not None:
        if isinstance(state0, Mapping):
            unknown = sorted(set(state0) - set(names))
            if unknown:
                raise ValueError(f"state0 has unknown variable(s) {unknown} for tier {tier}; "
                                 f"accepted: {list(names)}")
            for name, value in state0.items():
                state[names.index(name)] = value
        else:
            state = np.array(state0, dtype=np.float64)
            if state.shape != (len(names),):
                raise ValueError(f"state0 has shape {state.shape}, expected ({len(names)},) "
                                 f"for the tier-{tier} state {list(names)}")
    if not np.all(np.isfinite(state)):
        raise ValueError(f"state0 = {state.tolist()} is not finite")
    if "c" in names and not 0.0 < state[names.index("c")] < 1.0:
        raise ValueError(f"state0: c = {state[names.index('c')]:g} is outside the accepted "
                         f"range (0, 1)")
    if "A" in names:
        a, bc, bs = (state[names.index(k)] for k in ("A", "Bc", "Bs"))
        if float(admissibility_margin(a, fabric_polar(bc, bs)[0])) < 0.0:
            raise ValueError(f"state0: the fabric A = {a:g}, B = {math.hypot(bc, bs):g} is not "
                             f"admissible (need B <= A and (π/6) A + (√3/4) B <= 1)")
    return state


def run_path(path: Path | str, params: Params | None = None, tier: int | None = None, *,
             increment: float = DEFAULT_INCREMENT, min_increment: float | None = None,
             stress0=None, state0=None, start: "PointResult | None" = None, rtol: float = RTOL,
             progress: bool = False) -> PointResult:
    """Drive one material point along ``path`` (a :class:`dem.paths.Path` or a standard
    path name / file; not a probe family: see :func:`run_family`).

    ``params`` defaults to the shipped defaults and ``tier`` to ``params.tier``;
    ``increment`` is the increment knob Δτ_max and ``min_increment`` the step-cutting
    floor (default ``MIN_INCREMENT_FRACTION`` · increment); ``stress0`` (3,) the start
    stress in units of P0 (default -I: isotropic at P0 = 1), ``state0`` the start state
    (see :func:`start_state`); or ``start``: a previous result of the same tier, whose
    final stress and state this run starts from (e.g. a probe family from a state that a
    loading path reached; the strain and τ columns restart at 0). Raises :class:`IntegrationError` when the path cannot be
    followed. See the module doc for everything else.
    """
    path = load_path(path) if isinstance(path, str) else path
    if path.probes is not None:
        raise ValueError(f"path {path.name!r} is a probe family: run it with run_family "
                         f"(one run per probe, each from the same start)")
    if start is not None:
        stress0, state0 = _start_from(start, params, tier, stress0, state0)
    params, tier, stress0, state0 = _prepare(params, tier, increment, min_increment, stress0,
                                             state0)
    min_increment = MIN_INCREMENT_FRACTION * increment if min_increment is None else min_increment
    runner = _Runner(path, params, tier, increment, min_increment, rtol)
    bar = None
    if progress:
        from tqdm import tqdm
        bar = runner.bar = tqdm(total=sum(s.length for s in path.stages), desc=f"{path.name} (τ)",
                                mininterval=0.5, leave=False,
                                bar_format="{l_bar}{bar}| {n:.3g}/{total:.3g} [{elapsed}<{remaining}]")
    t0 = time.perf_counter()
    pt = _Point(stress0, state0)
    try:
        with numba_threads(1):  # one point never pays for waking the thread pool
            pt = runner.run(pt)
    except IntegrationError as exc:
        exc.partial = runner.result(pt, time.perf_counter() - t0) if runner.rows else None
        raise
    finally:
        if bar is not None:
            bar.close()
    return runner.result(pt, time.perf_counter() - t0)


def run_family(path: Path | str, params: Params | None = None, tier: int | None = None,
               **options) -> list[PointResult]:
    """:func:`run_path` on each of ``path.expand()`` (one per probe of a probe family, or
    the path itself), each from the same start (``options`` as :func:`run_path`, e.g.
    ``start=`` a result whose final state the probes start from)."""
    path = load_path(path) if isinstance(path, str) else path
    return [run_path(p, params, tier, **options) for p in path.expand()]


def _start_from(start: PointResult, params, tier, stress0, state0):
    """(stress0 in units of P0, state0) of a run that continues from ``start``."""
    if stress0 is not None or state0 is not None:
        raise ValueError("give either start (a previous result) or stress0/state0, not both")
    p_ref = (default_params() if params is None else params).p_ref
    want = start.tier if tier is None else tier
    if want != start.tier:
        raise ValueError(f"start is a tier-{start.tier} result; it cannot start a tier-{want} "
                         f"run (its state has the variables {list(tiers.STATE_NAMES[start.tier])})")
    return start.stress / p_ref, start.state


def _prepare(params, tier, increment, min_increment, stress0, state0):
    params = default_params() if params is None else params
    tier = params.tier if tier is None else tier
    if tier != params.tier:
        params = params.with_tier(tier)          # validates the tier and its sections
    for name, v in (("increment", increment), ("min_increment", min_increment)):
        if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise ValueError(f"{name} = {v!r} is outside the accepted range (0, inf) "
                             f"(reference strain)")
    if min_increment is not None and min_increment > increment:
        raise ValueError(f"min_increment = {min_increment:g} exceeds increment = {increment:g}; "
                         f"accepted range (0, increment]")
    stress = np.array([-1.0, -1.0, 0.0] if stress0 is None else stress0, dtype=np.float64)
    if stress.shape != (3,) or not np.all(np.isfinite(stress)):
        raise ValueError(f"stress0 = {stress0!r} must be 3 finite numbers (sxx, syy, sxy) in "
                         f"units of P0, tension positive")
    return params, tier, params.p_ref * stress, start_state(tier, params, state0)

"""Full Newton with the consistent tangent, automatic step cutting and growth.

Equilibrium in residual form, tension-positive stress (docs/theory.md §13):

    r(u) = f_int(σ(u)) - f_ext(t) = 0   on the free DOFs,
    u = ū(t)                            on the constrained DOFs,

where σ(u) is the constitutive update from the last *committed* state over the
strain increment B(u - u_n) and spin increment W(u - u_n). On the constrained DOFs
r is the reaction: the force the supports exert on the body. Each Newton
iteration runs the update once over all quadrature points, assembles
K = Σ w Bᵀ(D B + g W) from its algorithmic tangent D = ∂σ/∂e (non-symmetric when
ψ ≠ φ) and the spin tangent g = ∂σ/∂ω, and solves K_ff δu_f = -r_f - K_fc δū_c.
The update contract's tangent leaves out g (the objective rotation of the stress by
the spin); without it Newton converges only linearly once the mechanism rotates
(measured on the footing: residual ÷5 per iteration instead of squaring). g comes
from the material (``material.spin_tangent``: exact for the objective tiers, no extra
update call) or else by a forward difference in ω, one extra update call per
iteration (``NewtonOptions.spin_step``; 0 turns it off).

A stage drives a parameter t from 0 to 1: prescribed displacements
ū(t) = ū_start + t Δū on its constrained DOFs (displacement control) and external
force f_ext(t) = f_dead + t f_ramp (load control). Steps grow after easy
convergence and are cut after a failure (too many iterations, a diverging or
non-finite residual, a singular tangent, a failed constitutive update); a failed
trial leaves no trace in the committed state. Below the minimum step the stage
ends with :class:`ConvergenceError`, which carries the last converged state (unless the
step passes on the last-resort stall tolerance, ``NewtonOptions.tol_stall_last``).

Convergence is scale-free: |r_f| ≤ tol · max(|f_ext|, |r_c|) (Euclidean norms),
the residual on free DOFs against the applied and reaction forces. A failed step's
message counts the points at the apex of the cone (σ = 0, no strength): when they are
the majority the body has no confinement and the problem no unique solution (a
cohesionless block at p = 0, docs/stability.md), the limit the message then names.

**Predictor** (docs/fem_validation.md §5 has the measurements). Near a collapse
mechanism or a softening peak the Newton matrix has modes whose stiffness is O(p)
against the O(λ p) of the rest (the plastic tangent is stiff only across the flow
direction), and with softening and non-associated flow some are negative (the biaxial
peak at λ = 1e4: a real eigenvalue of -0.008 and a pair -0.30 ± 1.4i times the smallest
elastic one). The first correction from the committed state and tangent, which carries
the prescribed increment, then overshoots along those modes (14x the converged
increment there, 3000x on a λ = 1e8 collapse plateau) and flips hundreds of points
between elastic and plastic. So after a stage's first step the iteration starts from the
extrapolated increment, u⁰ = u_n + (t - t_n)(u_n - u_{n-1})/(t_n - t_{n-1}), with u⁰ = ū(t) on
the constrained DOFs (``NewtonOptions.extrapolate``). Where that start cycles instead
(points at neutral loading flipping with a period of 2-7 iterations), the same step is
tried once more from the committed state before it is cut: the two starts lead to
different sequences of elastic/plastic point sets, and one converging is enough.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable, Iterator, Protocol

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from contfab.fem import dashpot
from contfab.fem.assembly import Discretization
from contfab.fem.viscous import blend, elastic_stiffness
from contfab.models.cone import STATUS_APEX


class ConvergenceError(ValueError):
    """Newton failed below the minimum step; ``last`` is the last converged state.

    ``curve`` is what the driver measured up to that state (set by
    :func:`contfab.fem.analysis.run`: its :class:`~contfab.fem.analysis.RunResult`), or None.
    """

    def __init__(self, message: str, last: "FieldState", attempts: list, curve=None):
        super().__init__(message)
        self.last = last
        self.attempts = attempts
        self.curve = curve


class Material(Protocol):
    """What the solver needs from a constitutive model (the update contract)."""

    state_names: tuple[str, ...]

    def update(self, stress_n, state_n, dstrain, dspin):
        """-> object with ``stress`` (n,3), ``state`` (n,k), ``tangent`` (n,3,3), ``status`` (n,)."""


@dataclass
class FieldState:
    """A complete solution: displacement, per-point stress/state/tangent/status, residual.

    ``t`` is the stage parameter and ``stage`` the stage's name; ``residual`` is
    r = f_int - f_ext (reactions on constrained DOFs, ≈ 0 elsewhere); ``dstrain`` is the
    strain increment per point of the step that led here (None for the initial state).
    """

    stage: str
    t: float
    u: np.ndarray
    stress: np.ndarray
    state: np.ndarray
    tangent: np.ndarray
    spin_tangent: np.ndarray
    status: np.ndarray
    residual: np.ndarray
    dstrain: np.ndarray | None = None


@dataclass(frozen=True)
class Stage:
    """A load stage: constrained DOFs, their displacement increment, external forces, steps.

    ``fixed_dofs`` lists every constrained DOF (supports and driven DOFs alike);
    ``increment`` is their prescribed displacement change over the stage (zeros for
    supports). ``ties`` make free DOFs move together (a rigid platen, a periodic or
    homogeneous layer): each follower DOF is ``tie_factors`` (default 1) times its
    leader, which must be free and not itself a follower; the ties must hold at the
    stage's start.
    ``reset_displacement`` zeroes u after the stage but keeps stress and
    state (a geostatic stage: the initial stress is in equilibrium, settlements
    count from there). ``duration`` is the time the stage takes (t runs over it
    uniformly): the unit of ``NewtonOptions.relaxation_time``.
    """

    name: str
    fixed_dofs: np.ndarray
    increment: np.ndarray
    f_dead: np.ndarray
    f_ramp: np.ndarray | None = None
    dt0: float = 0.05
    dt_min: float = 1e-4
    dt_max: float = 0.1
    reset_displacement: bool = False
    ties: np.ndarray | None = None      # (k, 2) free DOF pairs (follower, leader)
    tie_factors: np.ndarray | None = None   # (k,) u_follower = factor u_leader (default 1)
    duration: float = 1.0

    def __post_init__(self):
        if len(self.fixed_dofs) != len(self.increment):
            raise ValueError(f"stage {self.name!r}: {len(self.fixed_dofs)} constrained DOFs but "
                             f"{len(self.increment)} prescribed increments")
        if len(np.unique(self.fixed_dofs)) != len(self.fixed_dofs):
            raise ValueError(f"stage {self.name!r}: a DOF is constrained twice")
        if self.ties is not None:
            ties = np.asarray(self.ties)
            if ties.ndim != 2 or ties.shape[1] != 2:
                raise ValueError(f"stage {self.name!r}: ties must be (k, 2) pairs, got shape "
                                 f"{ties.shape}")
            bad = np.isin(ties, self.fixed_dofs).any() or len(np.unique(ties[:, 0])) != len(ties) \
                or np.isin(ties[:, 1], ties[:, 0]).any()
            if bad:
                raise ValueError(f"stage {self.name!r}: a tied DOF is constrained, a follower is "
                                 "tied twice, or a leader is itself a follower")
            if self.tie_factors is not None and np.shape(self.tie_factors) != (len(ties),):
                raise ValueError(f"stage {self.name!r}: {len(ties)} ties but tie_factors of "
                                 f"shape {np.shape(self.tie_factors)}")
        if not (math.isfinite(self.duration) and self.duration > 0):
            raise ValueError(f"stage {self.name!r}: duration = {self.duration!r} is outside the "
                             "accepted range (0, inf)")
        if not 0 < self.dt_min <= self.dt0 <= 1 or not self.dt0 <= self.dt_max <= 1:
            raise ValueError(f"stage {self.name!r}: need 0 < dt_min <= dt0 <= dt_max <= 1, "
                             f"got dt_min={self.dt_min}, dt0={self.dt0}, dt_max={self.dt_max}")


LINE_SEARCH_RULES = ("residual", "energy")
SLOPE_RATIO = 0.5
"""The energy line search accepts α once |s(α)| <= SLOPE_RATIO |s(0)| (Matthies & Strang
1979 use 0.5; 0.25 and 0.8 took as many or more linear solves on the N_q footing)."""


def stationary_alpha(slope: Callable[[float], float | None], s0: float, trials: int,
                     ratio: float = SLOPE_RATIO) -> float:
    """The step length α along a Newton correction δu where the potential is stationary.

    For an associated material the increment minimizes the convex incremental potential
    Π(u), whose gradient on the free DOFs is the residual r; along δu its slope is
    s(α) = δu·r(u + α δu), with s(0) = ``s0`` = -δu·K δu < 0 for a positive definite K.
    s increases with α (Π convex), so its root is bracketed by regula falsi: α = 1 first,
    then the secant through the last point below the root and the last above it (clipped
    to the bracket's inner 80 %; the Illinois variant, halving the slope kept at an end
    that two trials in a row did not move), or, while every trial still descends, the
    secant beyond the last one (within [1.25 α, 2 α]). Accepts the first α with
    |s(α)| <= ``ratio`` |s0| (Matthies & Strang 1979, "The solution of nonlinear finite
    element equations", Int. J. Numer. Meth. Eng. 14, 1613–1626); after ``trials`` further
    trials, the one with the smallest |s|. ``slope`` returns None where the update fails (α is then
    halved toward the bracket's lower end).
    """
    lo, s_lo, hi, s_hi = 0.0, s0, math.inf, math.inf
    previous, s_previous, side = lo, s_lo, 0
    alpha, best, s_best = 1.0, 1.0, math.inf
    for _ in range(trials + 1):
        s = slope(alpha)
        if s is None:
            hi, s_hi = alpha, math.inf
            alpha = 0.5 * (lo + alpha)
            continue
        if abs(s) < s_best:
            best, s_best = alpha, abs(s)
        if abs(s) <= ratio * abs(s0):
            return alpha
        if s < 0:
            previous, s_previous = lo, s_lo
            lo, s_lo = alpha, s
            s_hi *= 0.5 if side < 0 else 1.0     # Illinois: the kept end's slope halved
            side = -1
        else:
            hi, s_hi = alpha, s
            s_lo *= 0.5 if side > 0 else 1.0
            side = 1
        if math.isfinite(s_hi):
            alpha = hi - s_hi * (hi - lo) / (s_hi - s_lo)
            alpha = min(max(alpha, lo + 0.1 * (hi - lo)), hi - 0.1 * (hi - lo))
        elif math.isfinite(hi):
            alpha = 0.5 * (lo + hi)
        else:
            rising = s_lo > s_previous
            alpha = lo - s_lo * (lo - previous) / (s_lo - s_previous) if rising else 2 * lo
            alpha = min(max(alpha, 1.25 * lo), 2 * lo)
    return best


@dataclass(frozen=True)
class NewtonOptions:
    """Newton tolerances, step control, predictor and line search.

    A step is converged when the relative free residual is <= ``tol``, or <= ``tol_stall``
    once it stops decreasing (halved in none of the last three iterations) or at the
    last iteration: at a softening peak, points flipping between elastic unloading and
    plastic loading made Newton cycle at ~5e-6 forever (biaxial case). Records keep the
    residual sequence, so such steps are visible (:attr:`StepRecord.stalled`).
    ``max_iter`` bounds the linear solves of a step. A step grows by ``grow`` after
    <= ``easy_iter`` solves and is cut by ``cut`` on failure. ``extrapolate`` starts each
    step but a stage's first from the extrapolated increment, and on its failure from the
    committed state, before cutting (module doc; False: the committed state only).
    ``line_search`` bounds the extra trials along a correction, by ``line_search_rule``:
    ``"residual"`` halves it until the free residual falls (apex/face switching made plain
    Newton cycle on the non-associated N_γ footing); ``"energy"`` seeks the stationary point
    of the incremental potential along it (:func:`stationary_alpha`), for associated flow,
    where a potential exists, and falls back to halving where the correction is no descent
    direction of one;
    ``spin_step`` is the difference step of the spin tangent (0: off).
    ``relaxation_time`` τ (in the stages' ``duration`` unit) makes every step a Duvaut–Lions
    viscoplastic step with k = Δt/τ (:mod:`contfab.fem.viscous`).
    ``viscosity`` η (stress × the stages' ``duration`` unit, >= 0) puts a linear dashpot in
    parallel with the material at every point, σ = σ_mat + η Δε/Δt
    (:mod:`contfab.fem.dashpot`); 0 (default) leaves the solver as without it, bitwise.
    ``tol_stall_last`` (None: off) is the last resort of a step that failed from both starts
    at the stage's minimum step: it is tried once more from both starts and accepted when
    its residual stops falling at or below this looser tolerance (its record says so,
    :attr:`StepRecord.last_resort`); only then does the stage end in
    :class:`ConvergenceError`. A run that never reaches that point is unchanged by it, and
    the next step equilibrates the total stress to ``tol`` again (the residual is not
    incremental), so an accepted imbalance is not carried on.
    """

    tol: float = 1e-8
    tol_stall: float = 1e-4
    max_iter: int = 15
    grow: float = 1.5
    cut: float = 0.25
    easy_iter: int = 8
    diverge: float = 1e6
    spin_step: float = 1e-7
    line_search: int = 4
    line_search_rule: str = "residual"
    extrapolate: bool = True
    relaxation_time: float | None = None
    tol_stall_last: float | None = None
    viscosity: float = 0.0

    def __post_init__(self):
        if not 0 < self.tol <= self.tol_stall < 1:
            raise ValueError(f"need 0 < tol <= tol_stall < 1, got tol = {self.tol}, "
                             f"tol_stall = {self.tol_stall}")
        if self.tol_stall_last is not None and not self.tol_stall <= self.tol_stall_last < 1:
            raise ValueError(f"tol_stall_last = {self.tol_stall_last!r} is outside the accepted "
                             f"range [tol_stall, 1) = [{self.tol_stall}, 1)")
        if self.max_iter < 1:
            raise ValueError(f"max_iter = {self.max_iter} must be >= 1")
        if not self.grow >= 1 or not 0 < self.cut < 1:
            raise ValueError(f"need grow >= 1 and 0 < cut < 1, got {self.grow}, {self.cut}")
        if self.line_search < 0:
            raise ValueError(f"line_search = {self.line_search} must be >= 0")
        if self.line_search_rule not in LINE_SEARCH_RULES:
            raise ValueError(f"line_search_rule = {self.line_search_rule!r} is not one of "
                             f"{LINE_SEARCH_RULES}")
        if self.relaxation_time is not None and not (math.isfinite(self.relaxation_time)
                                                     and self.relaxation_time > 0):
            raise ValueError(f"relaxation_time = {self.relaxation_time!r} is outside the "
                             "accepted range (0, inf)")
        dashpot.check_viscosity(self.viscosity)
        if not 0 <= self.spin_step < 1e-3:
            raise ValueError(f"spin_step = {self.spin_step} must lie in [0, 1e-3)")


@dataclass
class StepRecord:
    """One committed step: stage, t, dt, relative residuals per iterate, failed attempts.

    With an extrapolated start (``extrapolated``) the first residual is the predictor's,
    before any linear solve. ``overstress`` and ``overstress_mean``: the largest and the
    quadrature-weighted mean |σ_v| of the dashpot over the points (stress units; 0 without
    one, ``NewtonOptions.viscosity``).
    """

    stage: str
    t: float
    dt: float
    residuals: list[float]
    cuts: int = 0
    extrapolated: bool = False
    viscous_ratio: float = math.inf
    last_resort: bool = False
    overstress: float = 0.0
    overstress_mean: float = 0.0

    tol: float = 1e-8

    @property
    def iterations(self) -> int:
        """Newton iterations: the linear solves of the step."""
        return len(self.residuals) - self.extrapolated

    @property
    def stalled(self) -> bool:
        """Accepted at the stall tolerance, not the Newton tolerance."""
        return self.residuals[-1] > self.tol


class ConstrainedSystem:
    """Solves K δu = -r with δu prescribed on constrained DOFs, reusing the CSR pattern.

    SuperLU with the minimum-degree ordering of Kᵀ + K (the FE matrix is structurally
    symmetric): 3-5x faster than the default COLAMD here (0.23 s vs 1.0 s at 54k DOFs).
    Tied DOFs (``ties``: follower, leader pairs of free DOFs, u_follower = factor ·
    u_leader) enter through u_f = P u_r, P mapping the independent free DOFs u_r onto
    all free DOFs: K_r = Pᵀ K_ff P and the equilibrium residual is Pᵀ r_f
    (:meth:`free_residual`).
    """

    def __init__(self, disc: Discretization, fixed: np.ndarray, ties: np.ndarray | None = None,
                 tie_factors: np.ndarray | None = None):
        n = disc.ndofs
        self.fixed = np.asarray(fixed, dtype=np.int64)
        self.free = np.setdiff1d(np.arange(n), self.fixed)
        self.tie_map = None
        if ties is not None and len(ties):
            ties = np.asarray(ties, dtype=np.int64)
            column = np.full(n, -1, dtype=np.int64)
            independent = np.setdiff1d(self.free, ties[:, 0])
            column[independent] = np.arange(len(independent))
            column[ties[:, 0]] = column[ties[:, 1]]
            factor = np.ones(n)
            if tie_factors is not None:
                factor[ties[:, 0]] = tie_factors
            rows = np.arange(len(self.free))
            self.tie_map = sp.csr_matrix((factor[self.free], (rows, column[self.free])),
                                         shape=(len(self.free), len(independent)))
        probe = sp.csr_matrix((np.arange(1.0, len(disc.indices) + 1), disc.indices, disc.indptr),
                              shape=(n, n))
        kff = probe[self.free][:, self.free].tocsc()
        kfc = probe[self.free][:, self.fixed].tocsr()
        self._ff = (kff.data.astype(np.int64) - 1, kff.indices, kff.indptr, kff.shape)
        self._fc = (kfc.data.astype(np.int64) - 1, kfc.indices, kfc.indptr, kfc.shape)

    def solve(self, k: sp.csr_matrix, r: np.ndarray, du_fixed: np.ndarray) -> np.ndarray:
        """Full δu with δu_c = ``du_fixed`` and K_ff δu_f = -r_f - K_fc δu_c (SuperLU)."""
        sel, ind, ptr, shape = self._ff
        kff = sp.csc_matrix((k.data[sel], ind, ptr), shape=shape)
        sel, ind, ptr, shape = self._fc
        kfc = sp.csr_matrix((k.data[sel], ind, ptr), shape=shape)
        du = np.zeros(len(r))
        du[self.fixed] = du_fixed
        rhs = -r[self.free] - kfc @ du_fixed
        p = self.tie_map
        if p is None:
            du[self.free] = spla.splu(kff, permc_spec="MMD_AT_PLUS_A").solve(rhs)
        else:
            kr = (p.T @ kff @ p).tocsc()
            du[self.free] = p @ spla.splu(kr, permc_spec="MMD_AT_PLUS_A").solve(p.T @ rhs)
        return du

    def free_residual(self, r: np.ndarray) -> np.ndarray:
        """The out-of-balance forces on the independent free DOFs: r_f, or Pᵀ r_f with ties."""
        return r[self.free] if self.tie_map is None else self.tie_map.T @ r[self.free]


@dataclass
class _Iterate:
    """A Newton iterate: displacement, strain and spin increments, update result, residual,
    |r_f| and relative |r_f|; ``spin_tangent`` is filled in once the iterate is accepted."""

    u: np.ndarray
    dstrain: np.ndarray
    dspin: np.ndarray
    res: object
    r: np.ndarray
    free: float
    rel: float
    spin_tangent: np.ndarray | None = None


def norm(x: np.ndarray) -> float:
    """Euclidean norm without BLAS: a threaded OpenBLAS dot on a loaded 2-core machine
    took 12 ms for 54k entries (vs 8 µs single-threaded), more than an assembly."""
    return float(np.sqrt(np.sum(x * x)))


class Solver:
    """Newton–Raphson over stages; ``committed`` is the last converged :class:`FieldState`."""

    def __init__(self, disc: Discretization, material: Material, stress0: np.ndarray,
                 state0: np.ndarray, options: NewtonOptions = NewtonOptions()):
        n, k = disc.npoints, len(material.state_names)
        stress0 = np.ascontiguousarray(stress0, dtype=float)
        state0 = np.ascontiguousarray(state0, dtype=float)
        if stress0.shape != (n, 3) or state0.shape != (n, k):
            raise ValueError(f"initial stress/state must have shapes {(n, 3)}/{(n, k)}, "
                             f"got {stress0.shape}/{state0.shape}")
        if not (np.all(np.isfinite(stress0)) and np.all(np.isfinite(state0))):
            raise ValueError("initial stress or state holds NaN or inf")
        self.disc = disc
        self.material = material
        self.options = options
        self._ratio = math.inf
        self._elastic = None
        if options.relaxation_time is not None:
            if getattr(material, "spin_tangent", None) is None:
                raise ValueError("a viscous step needs the material's exact spin tangent "
                                 "(material.spin_tangent)")
            self._elastic = elastic_stiffness(material)
        zero = np.zeros((n, 3))
        res = material.update(stress0, state0, zero, np.zeros(n))
        if np.any(res.status < 0):
            raise ValueError(f"the initial stress is not admissible at "
                             f"{int(np.sum(res.status < 0))} of {n} points")
        self.committed = FieldState("initial", 0.0, np.zeros(disc.ndofs), stress0, state0,
                                    np.ascontiguousarray(res.tangent),
                                    self._spin_tangent(stress0, state0, zero, np.zeros(n), res),
                                    res.status, disc.internal_force(stress0))
        self.records: list[StepRecord] = []
        self.stage_start: np.ndarray | None = None
        self._dashpot: np.ndarray | None = None

    def run_stage(self, stage: Stage, start: tuple[float, float, np.ndarray] | None = None
                  ) -> Iterator[StepRecord]:
        """Advance ``stage`` from t = 0 to 1, yielding a record after each committed step.

        Each step is tried from the extrapolated increment and then from the committed
        state (only the latter for a stage's first step, or without ``extrapolate``);
        if neither converges the step is cut. ``start`` = (t, dt, ū_start) continues the
        stage from the committed state at t with step dt (a resumed run), ū_start being
        the constrained DOFs' displacements at the stage's start (:attr:`stage_start`).
        """
        system = ConstrainedSystem(self.disc, stage.fixed_dofs, stage.ties, stage.tie_factors)
        if start is None:
            t, dt, u_start = 0.0, stage.dt0, self.committed.u[system.fixed].copy()
        else:
            t, dt, u_start = float(start[0]), float(start[1]), np.array(start[2], dtype=float)
            if not (0.0 <= t < 1.0 and 0.0 < dt <= 1.0 and u_start.shape == system.fixed.shape):
                raise ValueError(f"resume start t = {t}, dt = {dt} (accepted t in [0, 1), dt in "
                                 f"(0, 1]) with {u_start.shape} start displacements for "
                                 f"{system.fixed.shape} constrained DOFs")
        self.stage_start = u_start
        attempts, cuts, rate = [], 0, None
        opt = self.options
        while t < 1.0 - 1e-12:
            dt = min(dt, 1.0 - t)
            ratio = math.inf if opt.relaxation_time is None else \
                dt * stage.duration / opt.relaxation_time
            self._dashpot = None if opt.viscosity == 0 else \
                dashpot.stiffness(opt.viscosity, dt * stage.duration)
            starts = [None] if rate is None else [self.committed.u + dt * rate, None]
            at_min = dt <= stage.dt_min * (1 + 1e-9)
            stalls = [opt.tol_stall] + ([opt.tol_stall_last] if at_min and
                                        opt.tol_stall_last is not None else [])
            for tol_stall in stalls:
                for predictor in starts:
                    trial, residuals, reason = self._newton(stage, system, u_start, t + dt,
                                                            predictor, ratio, tol_stall)
                    if trial is not None:
                        break
                    attempts.append({"t": t + dt, "dt": dt, "reason": reason,
                                     "residuals": residuals, "tol_stall": tol_stall,
                                     "start": "committed" if predictor is None else "extrapolated"})
                if trial is not None:
                    break
            if trial is None:
                if at_min:
                    raise ConvergenceError(self._failure_message(stage, attempts, cuts),
                                           self.committed, attempts)
                dt = max(dt * self.options.cut, stage.dt_min)
                cuts += 1
                continue
            if self.options.extrapolate:
                rate = (trial.u - self.committed.u) / dt
            self.committed = trial
            t += dt
            record = StepRecord(stage.name, t, dt, residuals, cuts=cuts,
                                extrapolated=predictor is not None, tol=self.options.tol,
                                viscous_ratio=ratio, last_resort=tol_stall > opt.tol_stall,
                                **self._overstress(trial))
            self.records.append(record)
            attempts, cuts = [], 0
            yield record
            if record.iterations <= self.options.easy_iter:
                dt = min(dt * self.options.grow, stage.dt_max)
        if stage.reset_displacement:
            self.committed = replace(self.committed, u=np.zeros_like(self.committed.u))

    def _newton(self, stage: Stage, system: ConstrainedSystem, u_start: np.ndarray, t: float,
                predictor: np.ndarray | None, ratio: float = math.inf,
                tol_stall: float | None = None):
        """One step to stage parameter ``t``: (trial state or None, residual history, reason).

        ``tol_stall`` overrides the options' stall tolerance (the last resort of run_stage).

        ``ratio`` k = Δt/τ < inf makes it a Duvaut–Lions step
        (:func:`contfab.fem.viscous.blend`).

        ``predictor`` (the extrapolated displacement, or None) is the first iterate, with
        the constrained DOFs set to ū(t); without it the first correction, from the
        committed state and tangent, carries the prescribed increment.
        """
        c, opt, disc = self.committed, self.options, self.disc
        stall_tol = opt.tol_stall if tol_stall is None else tol_stall
        self._ratio = ratio
        f_ext = stage.f_dead if stage.f_ramp is None else stage.f_dead + t * stage.f_ramp
        target = u_start + t * stage.increment
        residuals: list[float] = []
        current = None
        if predictor is not None:
            u = predictor.copy()
            u[system.fixed] = target
            current = self._evaluate(c, system, f_ext, u)
            if current is None:
                return None, residuals, "constitutive update failed (status -1) at the predictor"
            residuals.append(current.rel)
            tangent, spin_tangent = self._accept(c, current)
            if current.rel <= opt.tol:
                return self._field(stage, t, current), residuals, ""
            r = current.r
        else:
            u = c.u
            r = disc.internal_force(c.stress) - f_ext
            tangent, spin_tangent = c.tangent, c.spin_tangent
            if self._dashpot is not None:
                tangent = tangent + self._dashpot
        for it in range(opt.max_iter):
            try:
                du = system.solve(disc.tangent(tangent, spin_tangent), r,
                                  target - u[system.fixed])
            except RuntimeError as exc:  # SuperLU: "Factor is exactly singular"
                return None, residuals, self._why(f"singular tangent ({exc}): a mechanism is free to move", current)
            if not np.all(np.isfinite(du)):
                return None, residuals, "non-finite Newton correction"
            current = self._line_search(c, system, f_ext, u, du, current)
            if current is None:
                return None, residuals, "constitutive update failed (status -1) along the step"
            u, r, rel = current.u, current.r, current.rel
            residuals.append(rel)
            if not np.isfinite(rel) or rel > opt.diverge:
                return None, residuals, self._why(f"residual diverged ({rel:.3g})", current)
            tangent, spin_tangent = self._accept(c, current)
            stalled = it >= 3 and rel > 0.5 * min(residuals[-4:-1])
            if rel <= opt.tol or (rel <= stall_tol and (stalled or it == opt.max_iter - 1)):
                return self._field(stage, t, current), residuals, ""
        return None, residuals, self._why(f"no convergence in {opt.max_iter} iterations", current)

    @staticmethod
    def _why(reason: str, current: _Iterate | None) -> str:
        """``reason`` with the share of points at the apex of the cone (status 2) in the last
        iterate, and, when they are the majority, what that means: a cohesionless material
        has no strength and the Newton matrix only the apex device's stiffness there, so
        the iteration has nothing to converge on (the validity range of the module doc)."""
        if current is None:
            return reason
        status = np.asarray(current.res.status)
        apex = int(np.count_nonzero(status == STATUS_APEX))
        if apex == 0:
            return reason
        reason += f"; {apex} of {status.size} points at the apex of the cone"
        if apex > status.size // 2:
            reason += (" (no confinement: most of the body has no strength; accepted range: "
                       "stress off the apex at most points, i.e. confinement p > 0 or cohesion)")
        return reason

    def _evaluate(self, c: FieldState, system: ConstrainedSystem, f_ext, u) -> _Iterate | None:
        """The update over u - u_n from the committed state, its residual and tangents;
        None if the update fails at some point."""
        dstrain, dspin = self.disc.strain(u - c.u)
        res = self.material.update(c.stress, c.state, dstrain, dspin)
        if self._ratio < math.inf:
            blend(res, c.stress, c.state, dstrain, dspin, self._elastic, self._ratio)
        if np.any(res.status < 0):
            return None
        total = res.stress if self._dashpot is None else \
            res.stress + dashpot.stress(dstrain, self._dashpot)
        r = self.disc.internal_force(total) - f_ext
        free = norm(system.free_residual(r))
        rel = free / (max(norm(f_ext), norm(r[system.fixed])) or 1.0)
        return _Iterate(u, dstrain, dspin, res, r, free, rel)

    def _accept(self, c: FieldState, it: _Iterate) -> tuple[np.ndarray, np.ndarray]:
        """The Newton-matrix tangents (D, g) at an accepted iterate (g stored on it); D
        includes the dashpot's (the stored field keeps the material's)."""
        it.spin_tangent = self._spin_tangent(c.stress, c.state, it.dstrain, it.dspin, it.res)
        tangent = np.ascontiguousarray(it.res.tangent)
        if self._dashpot is not None:
            tangent = tangent + self._dashpot
        return tangent, it.spin_tangent

    def _overstress(self, field: FieldState) -> dict:
        """{} without a dashpot, else its largest and weighted mean |σ_v| in ``field``."""
        if self._dashpot is None:
            return {}
        mag = dashpot.magnitude(dashpot.stress(field.dstrain, self._dashpot))
        w = self.disc.weights.reshape(-1)
        return {"overstress": float(mag.max()), "overstress_mean": float(w @ mag / w.sum())}

    def _line_search(self, c: FieldState, system: ConstrainedSystem, f_ext, u, du,
                     current: _Iterate | None) -> _Iterate | None:
        """The iterate u + α du by ``NewtonOptions.line_search_rule``; None if the update
        fails at every α tried.

        The first correction of a step without a predictor (``current`` None) carries the
        prescribed displacement increment and is taken whole. The energy rule takes the α
        of :func:`stationary_alpha` where du descends (du·r_f < 0), else the residual rule:
        α = 1, 1/2, ... (``line_search`` halvings) until |r_f| decreases, the first α that
        reduces it, else the best one tried.
        """
        free = system.free
        energy = self.options.line_search_rule == "energy" and current is not None
        s0 = float(du[free] @ current.r[free]) if energy else math.nan
        if s0 < 0:
            tried: dict[float, _Iterate | None] = {}

            def slope(alpha: float) -> float | None:
                tried[alpha] = self._evaluate(c, system, f_ext, u + alpha * du)
                return None if tried[alpha] is None else float(du[free] @ tried[alpha].r[free])

            return tried[stationary_alpha(slope, s0, self.options.line_search)]
        alpha, best = 1.0, None
        for _ in range(self.options.line_search + 1):
            trial = self._evaluate(c, system, f_ext, u + alpha * du)
            if trial is not None:
                if best is None or not trial.free >= best.free:
                    best = trial
                if current is None or not trial.free >= current.free:
                    return best
            if current is None:
                return best
            alpha *= 0.5
        return best

    def _field(self, stage: Stage, t: float, it: _Iterate) -> FieldState:
        return FieldState(stage.name, t, it.u, it.res.stress, it.res.state,
                          np.ascontiguousarray(it.res.tangent), it.spin_tangent, it.res.status,
                          it.r, it.dstrain)

    def _spin_tangent(self, stress_n, state_n, dstrain, dspin, res) -> np.ndarray:
        """g = ∂σ/∂ω: the material's own (``material.spin_tangent``) if it has one, else a
        forward difference of the update (zeros when spin_step = 0)."""
        exact = getattr(self.material, "spin_tangent", None)
        if exact is not None:
            return np.ascontiguousarray(exact(stress_n, state_n, dstrain, dspin, res))
        h = self.options.spin_step
        if h == 0:
            return np.zeros_like(res.stress)
        shifted = self.material.update(stress_n, state_n, dstrain, dspin + h)
        return (shifted.stress - res.stress) / h

    def _failure_message(self, stage: Stage, attempts: list, cuts: int) -> str:
        last = attempts[-1]
        seq = ", ".join(f"{x:.2e}" for x in last["residuals"]) or "none"
        return (f"stage {stage.name!r}: no converged step beyond t = {self.committed.t:.6g} "
                f"(step cut {cuts} times down to the minimum dt = {stage.dt_min:g}, "
                f"{len(attempts)} attempts); last attempt (from the {last['start']} state): "
                f"{last['reason']}; relative residuals [{seq}]")

    def reactions(self, dofs: np.ndarray) -> float:
        """Sum of the committed residual over ``dofs``: the support force on the body."""
        return float(np.sum(self.committed.residual[dofs]))

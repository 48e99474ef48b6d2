"""Rigid rough strip footing on a cohesionless cone: N_q and N_γ against exact solutions.

Scene (half model, symmetric about x = 0; docs/theory.md §13). A footing of half-width b = B/2 = 1
on the surface y = 0 of a soil block x ∈ [0, L], y ∈ [-H, 0], with L and H set from the
size of the Prandtl mechanism of φ (:func:`mechanism_size`) so that the failure zone
stays inside. Rollers on x = 0 (symmetry) and x = L, fixed base. The footing is rigid and
rough: its nodes move down by δ·t with ux = 0. The bearing pressure is q_u = Q/b, Q the
reaction force on the footing (of the half model).

**Model** (``--tier``, ``--params``, ``--c0``; :mod:`contfab.scenes.material_options`).
The default, tier 1, is the calibrated material (the parameter file's model from its
``[initial]`` state, dense by default): φ(c), ψ(c) move with the packing fraction, and
ψ < φ everywhere (non-associated). Its factor is the peak of the load–settlement curve,
pushed to 0.3 B; no published value exists for it, so it is printed with the exact tier-0
factors at the critical angle φ* and at the initial angle φ0 = φ(c0), between which it
must lie (:func:`tier0_bounds`), beside the **tier-0 check**: the same mesh with tier 0,
associated flow at φ*, against Prandtl–Reissner (``--no-check`` skips it). Tier 2 and
``auto`` run the same way. ``--tier 0`` (or ``--phi``/``--psi``) runs constant angles:

* ``--factor Nq``: weightless soil, surcharge q on the free surface, initial stress
  σ = -q I (in equilibrium with the surcharge and the rollers). N_q = q_u/q against
  Prandtl–Reissner, N_q = e^{π tan φ} tan²(π/4 + φ/2): exact for associated flow, and for
  rough and smooth footings alike (weightless soil).
* ``--factor Ngamma``: unit weight γ, no surcharge. A geostatic stage equilibrates
  σyy = γy, σxx = K0 σyy (K0 = 1 - sin φ) under gravity, then displacements are zeroed.
  N_γ = q_u/(½ γ B) against the exact method-of-characteristics values for a rough
  footing and associated flow of Martin (2005), "Exact bearing capacity calculations
  using the method of characteristics", Proc. 11th IACMAG, Turin, vol. 4, 441-450:
  N_γ = 14.75 at φ = 30°. With ψ < φ the collapse load drops: no exact value exists; the
  factor is printed with "no published reference" (N_γ), or against Prandtl–Reissner at
  Davis's reduced angle φ* (N_q, :func:`davis_angle`: a rough bound), and φ* is noted.
  ``--relaxation-time`` makes the material Duvaut–Lions viscoplastic
  (:mod:`contfab.fem.viscous`); ``--explicit CYCLES`` solves the push by explicit dynamic
  relaxation (:mod:`contfab.fem.explicit`), which carries the rate-independent
  non-associated footing through collapse where Newton fails (docs/fem_validation.md,
  section 7, measures both on non-associated N_γ).

The computed factor is the bearing pressure at the end of the push; the push is a
multiple of the elastic settlement scale N·b/λ, and the plateau is checked (the load
change over the last fifth of the push is reported as ``plateau_drift``).
"""
from __future__ import annotations

import math
import time
from pathlib import Path


import numpy as np

from contfab.scenes.case import CaseResult, Figure, failure_note
from contfab.scenes import material_options
from contfab.scenes.material_options import max_tier, point_updates
from contfab.fem import analysis, loads
from contfab.fem.auto import run_auto
from contfab.fem import mesh as meshes
from contfab.fem.assembly import Discretization
from contfab.fem.elements import ELEMENTS
from contfab.fem.material import TierMaterial
from contfab.fem.explicit import ExplicitOptions, ExplicitSolver
from contfab.fem.solver import (LINE_SEARCH_RULES, ConvergenceError, NewtonOptions, Solver,
                                Stage)
from contfab.params import ParamError
from dem.fileio import write_csv

DESCRIPTION = ("rigid rough strip footing on the calibrated material (any tier, dense or loose) "
               "beside its tier-0 check: N_q (Prandtl-Reissner), N_gamma (Martin 2005)")

B_HALF = 1.0
MECHANISM_SCALE = {"Nq": 1.0, "Ngamma": 0.6}
"""The N_γ mechanism (rough footing, self-weight) is about 0.6x the size of Prandtl's."""
PUSH_DT_MIN = 1e-6
"""Smallest push step. With ψ < φ a zone at yield with almost no plastic flow makes its
points flip between elastic and plastic from one Newton iterate to the next, leaving a
residual ∝ the step (2e-7 at 1e-6 of the push, 3e-5 at 1e-4; docs/fem_validation.md §5),
so these steps need to be small; the associated runs never get near it."""
ASSOCIATED_TOL = 1e-5
"""Newton's relative residual tolerance with associated flow (tier 0, ψ = φ, rate-independent),
which also takes the energy line search (``NewtonOptions.line_search_rule``). The increment
then minimizes a convex potential, so the solution does not depend on the tolerance: N_q on
the bench mesh moves by 2e-7 between 1e-8 and 1e-5, and the median iterations per step are
6 there, against 8 at 1e-8 with the residual line search. Non-associated runs keep
``NewtonOptions.tol`` (1e-8): their increment is not unique, and 1e-5 moved the calibrated
footing's peak by 1.2 % (docs/fem_validation.md, Benchmark)."""
NO_REFERENCE = "no published reference for these angles and this flow rule"
CALIBRATED_ELEMENT = "P2"
"""Default element of a tier >= 1 footing (and its tier-0 check), on mesh level 1: the
calibrated run's Newton takes 2-3x the steps and iterations of the associated one, and
P3 would make the main job several minutes long (docs/fem_validation.md §8)."""
CALIBRATED_SETTLEMENT = 0.3
"""Default push of a tier >= 1 footing, in B: far enough for a dense start to soften to
the critical state under the footing."""
MARTIN_2005_NGAMMA_ROUGH = {30.0: 14.75}
"""Exact N_γ, rough strip footing, associated flow (Martin 2005, method of characteristics)."""


def reference_factor(factor: str, phi_deg: float) -> float:
    """The exact factor for associated flow: Prandtl-Reissner N_q, or Martin's N_γ (NaN
    where no exact value is tabulated)."""
    if factor == "Nq":
        return prandtl_nq(phi_deg)
    return MARTIN_2005_NGAMMA_ROUGH.get(phi_deg, math.nan)


def davis_angle(phi_deg: float, psi_deg: float) -> float:
    """Davis's (1968) reduced friction angle of a non-associated material [deg]:
    tan φ* = sin φ cos ψ / (1 - sin φ sin ψ) (φ* = φ for ψ = φ); the associated solution at
    φ* is a rough (usually low) estimate of the non-associated collapse load."""
    phi, psi = math.radians(phi_deg), math.radians(psi_deg)
    return math.degrees(math.atan(math.sin(phi) * math.cos(psi)
                                  / (1.0 - math.sin(phi) * math.sin(psi))))


def prandtl_nq(phi_deg: float) -> float:
    """N_q = e^{π tan φ} tan²(π/4 + φ/2) (Prandtl 1920, Reissner 1924)."""
    phi = math.radians(phi_deg)
    return math.exp(math.pi * math.tan(phi)) * math.tan(math.pi / 4 + phi / 2) ** 2


def mechanism_size(phi_deg: float, b: float = B_HALF) -> tuple[float, float]:
    """(width from the axis, depth) of the Prandtl mechanism of a footing of half-width b.

    Active wedge under the footing, log-spiral fan r = r0 e^{θ tan φ} about the footing
    edge over θ ∈ [0, π/2] with r0 = b / cos(π/4 + φ/2), passive wedge to the surface:
    width b + 2 r1 cos(π/4 - φ/2) with r1 = r0 e^{(π/2) tan φ}; the deepest point is at
    θ = π/4 + φ/2, depth r0 e^{θ tan φ} cos φ.
    """
    phi = math.radians(phi_deg)
    r0 = b / math.cos(math.pi / 4 + phi / 2)
    r1 = r0 * math.exp(math.pi / 2 * math.tan(phi))
    width = b + 2 * r1 * math.cos(math.pi / 4 - phi / 2)
    depth = r0 * math.exp((math.pi / 4 + phi / 2) * math.tan(phi)) * math.cos(phi)
    return width, depth


def check_level(level: int) -> None:
    """A ParamError unless 1 <= ``level`` <= 8."""
    if not 1 <= level <= 8:
        raise ParamError(f"mesh level = {level} is outside the accepted range [1, 8]")


def footing_mesh(phi_deg: float, level: int, kind: str = "tri", factor: str = "Nq"):
    """Structured mesh resolving the mechanism box, coarse outside it.

    The mechanism box is 1.1x the mechanism's width and 1.2x its depth
    (:func:`mechanism_size`, scaled by :data:`MECHANISM_SCALE`); the block is 1.6x as
    wide and 2.2x as deep. Intervals per level: 6 across the footing half-width (refined
    2x toward its edge), 16 across the rest of the box and 10 down it (growing 4x away
    from the edge and the surface), 3 beyond it. The element study found the error set
    by the resolution of the whole mechanism (its slip lines), not by the edge
    singularity: grading harder toward the edge made N_q worse at equal DOFs.
    """
    check_level(level)
    width, depth = (MECHANISM_SCALE[factor] * v for v in mechanism_size(phi_deg))
    box_w, box_d = 1.1 * width, 1.2 * depth
    xs = np.concatenate((meshes.graded(0.0, B_HALF, 6 * level, 0.5),
                         meshes.graded(B_HALF, box_w, 16 * level, 4.0)[1:],
                         meshes.graded(box_w, 1.6 * width, 3 * level, 2.0)[1:]))
    ys = np.concatenate((meshes.graded(-2.2 * depth, -box_d, 3 * level, 0.5),
                         meshes.graded(-box_d, 0.0, 10 * level, 0.25)[1:]))
    m = meshes.tensor(xs, ys, kind=kind)
    tol = 1e-9
    return meshes.name_boundaries(m, {
        "footing": lambda x: (np.abs(x[1]) < tol) & (x[0] < B_HALF + tol),
        "free": lambda x: (np.abs(x[1]) < tol) & (x[0] > B_HALF - tol),
    })


def solve(phi_deg: float, psi_deg: float, factor: str, element: str, level: int, params,
          out: Path | None, progress: bool, push: float = 15.0,
          apex_stiffness: float = 1e-9, dt_max: float = 0.05,
          settlement: float | None = None, relaxation_time: float | None = None,
          tier=0, tol_stall: float = NewtonOptions.tol_stall,
          explicit: int | None = None, tol: float | None = None,
          line_search: str | None = None) -> dict:
    """One footing analysis; returns the factor, its curve summary, Newton figures, files.

    ``tier`` 0 runs the constant angles ``phi_deg``, ``psi_deg``; a tier >= 1 (or an array:
    a tier per quadrature point) runs the model of ``params`` from its ``[initial]`` state,
    its angles its own, ``phi_deg`` (φ0) then only sizing the mesh and ``psi_deg`` naming.

    ``push`` is the footing settlement in units of the elastic scale N·b/λ, or
    ``settlement`` the final settlement in units of B = 2b; ``dt_max`` the largest load
    step, as a fraction of the push (``contfab tradeoff fem_footing_nq`` measures its
    effect). ``relaxation_time`` τ makes the material Duvaut–Lions viscoplastic
    (:mod:`contfab.fem.viscous`), τ in units of the settlement over B (the push runs at unit
    settlement rate). ``tol_stall`` is the Newton stall tolerance
    (:class:`~contfab.fem.solver.NewtonOptions`). ``explicit`` = a number of cycles solves
    the push by explicit dynamic relaxation in that many cycles instead of Newton
    (:mod:`contfab.fem.explicit`; the curve has a point per hundredth of the push).
    ``tol`` (Newton's relative residual tolerance) and ``line_search``
    (``NewtonOptions.line_search_rule``) default by the flow rule: :data:`ASSOCIATED_TOL`
    and ``"energy"`` with associated flow, ``NewtonOptions.tol`` and ``"residual"`` otherwise.
    """
    if settlement is not None and not 0.0 < settlement <= 1.0:
        raise ParamError(f"settlement = {settlement:g} B is outside the accepted range (0, 1]")
    stress_scale = 1.0     # q (N_q) or γ b (N_γ): the scene's stress unit
    top = max_tier(tier)
    if top == 0:
        params = params.replace("tier0", phi_deg=phi_deg, psi_deg=psi_deg)
    params = params.with_tier(top).replace("regularization", p_ref=stress_scale)
    lam = params.regularization.lam
    disc = Discretization(footing_mesh(phi_deg, level, ELEMENTS[element].mesh_kind, factor),
                          element)
    if np.ndim(tier):
        material = TierMaterial(params, point_tiers=tier, apex_stiffness=apex_stiffness)
    else:
        material = TierMaterial(params, tier=top, apex_stiffness=apex_stiffness)
    n = disc.npoints
    stress0 = np.zeros((n, 3))
    f_dead = np.zeros(disc.ndofs)
    y = disc.points[:, 1]
    if factor == "Nq":
        q = stress_scale
        stress0[:, 0] = stress0[:, 1] = -q
        f_dead += loads.surface_load(disc, "free", pressure=q)
        norm = q * B_HALF                       # N_q = Q / (q b)
    else:
        gamma = stress_scale / B_HALF
        k0 = 1.0 - math.sin(math.radians(phi_deg))
        stress0[:, 1] = gamma * y
        stress0[:, 0] = k0 * gamma * y
        f_dead += loads.body_force(disc, by=-gamma)
        norm = gamma * B_HALF**2                # N_γ = q_u / (½ γ B) = Q / (γ b²)
    reference = reference_factor(factor, phi_deg) if top == 0 else math.nan
    associated = top == 0 and psi_deg == phi_deg and relaxation_time is None
    if tol is None:
        tol = ASSOCIATED_TOL if associated else NewtonOptions.tol
    if line_search is None:
        line_search = "energy" if associated else "residual"
    if explicit is None:
        solver = Solver(disc, material, stress0, material.initial_state(n),
                        NewtonOptions(relaxation_time=relaxation_time, tol=tol,
                                      tol_stall=max(tol, tol_stall),
                                      line_search_rule=line_search))
    else:
        solver = ExplicitSolver(disc, material, stress0, material.initial_state(n),
                                ExplicitOptions(cycles=explicit))
    dofs = {f"{s}_{c}": loads.boundary_dofs(disc, s, c)
            for s, c in (("left", "x"), ("right", "x"), ("bottom", "x"), ("bottom", "y"),
                         ("footing", "x"), ("footing", "y"))}
    supports = np.unique(np.concatenate([dofs[k] for k in ("left_x", "right_x", "bottom_x",
                                                            "bottom_y")]))
    stages = []
    if factor == "Ngamma":
        stages.append(Stage("geostatic", supports, np.zeros(len(supports)), f_dead, dt0=1.0,
                            dt_max=1.0, dt_min=1.0, reset_displacement=True))
    footing = np.concatenate((dofs["footing_x"], dofs["footing_y"]))
    fixed = np.unique(np.concatenate((supports, footing)))
    scale = reference if math.isfinite(reference) else prandtl_nq(phi_deg)
    delta = push * scale * B_HALF / lam if settlement is None else settlement * 2 * B_HALF
    increment = np.where(np.isin(fixed, dofs["footing_y"]), -delta, 0.0)
    stages.append(Stage("push", fixed, increment, f_dead, dt0=min(0.02, dt_max), dt_max=dt_max,
                        dt_min=PUSH_DT_MIN, duration=delta / (2 * B_HALF)))

    def measure(s: Solver) -> dict:
        u = s.committed.u[dofs["footing_y"]]
        return {"settlement": float(-u.mean() / B_HALF) if s.committed.stage == "push" else 0.0,
                factor: -s.reactions(dofs["footing_y"]) / norm}

    name = f"strip_footing_{factor}_phi{phi_deg:g}_psi{psi_deg:g}" if top == 0 else \
        f"strip_footing_{factor}_{'mixed' if np.ndim(tier) else f'tier{top}'}_c{params.initial.c0:.4f}"
    width, depth = (MECHANISM_SCALE[factor] * v for v in mechanism_size(phi_deg))
    outputs = analysis.Outputs(out, name, frame_every=5, curve_axes=("settlement", factor),
                               reference=reference if math.isfinite(reference) else None,
                               reference_label="exact (associated)",
                               window=(0.0, 1.2 * width, -1.2 * depth, 0.0))
    t0 = time.perf_counter()
    result = analysis.run(solver, stages, measure, outputs, progress=progress,
                          record_stages=["push"])
    wall = time.perf_counter() - t0
    values = result.column(factor)
    tail = values[result.column("t") >= 0.8 * result.column("t")[-1]]
    return {"phi": phi_deg, "psi": psi_deg, "reference": reference, "computed": float(values[-1]),
            "peak": float(values.max()), "plateau_drift": float(tail[-1] / tail[0] - 1.0),
            "settlement_over_B": float(result.column("settlement")[-1] / 2),
            "dofs": disc.ndofs, "element": element, "level": level, "wall_s": wall,
            "steps": len(result.iterations),
            "median_newton": float(np.median(result.iterations)),
            "cuts": int(sum(r.cuts for r in solver.records)),
            "curve_values": values, "curve_settlements": result.column("settlement"),
            "residuals": [r.residuals for r in solver.records[-3:]],
            "newton_per_step": list(result.iterations),
            "indicators": result.indicators, "point_updates": point_updates(material),
            "files": result.files}


def add_arguments(p) -> None:
    material_options.add_arguments(p, default_tier=None,
                                   default_help="1, or 0 when --phi or --psi is given")
    p.add_argument("--factor", choices=("Nq", "Ngamma"), default="Nq")
    p.add_argument("--phi", type=float, nargs="+", default=None,
                   help="tier 0: friction angle(s) in degrees (default: the parameter file's "
                        "tier-0 phi for N_q, 30 for N_gamma, where the exact value is known)")
    p.add_argument("--psi", nargs="+", default=None,
                   help="tier 0: dilatancy angle(s) in degrees, or 'phi' for associated flow "
                        "(default); several give the drop of the factor with psi")
    p.add_argument("--element", choices=sorted(ELEMENTS), nargs="+", default=None,
                   help="element famil(y/ies) (default: tier 0, P3, the element study's choice; "
                        f"tiers >= 1, {CALIBRATED_ELEMENT}, a minute's run with its check)")
    p.add_argument("--level", type=int, nargs="+", default=[1], help="mesh density level(s), 1..8")
    p.add_argument("--lam", type=float, default=None, help="override the regularization lambda")
    p.add_argument("--apex-stiffness", type=float, default=1e-9,
                   help="Newton-matrix stiffness fraction at apex points (0: off)")
    p.add_argument("--settlement", type=float, default=None,
                   help="push to this settlement over B (default: tier 0, 15 elastic settlement "
                        "scales N b / lambda, about 0.1 B for N_gamma at phi = 30; tiers >= 1, "
                        f"{CALIBRATED_SETTLEMENT} B)")
    p.add_argument("--relaxation-time", type=float, default=None,
                   help="Duvaut-Lions viscoplastic material with this relaxation time, in "
                        "units of settlement over B (default: rate-independent)")
    p.add_argument("--explicit", type=int, default=None, metavar="CYCLES",
                   help="solve the push by explicit dynamic relaxation in CYCLES cycles "
                        "(contfab.fem.explicit; no equilibrium iteration: carries "
                        "non-associated collapse; check by doubling CYCLES) instead of Newton")
    p.add_argument("--tol", type=float, default=None,
                   help="Newton's relative residual tolerance |r_f| / max(|f_ext|, |reactions|) "
                        f"(default {ASSOCIATED_TOL:g} with associated flow, "
                        f"{NewtonOptions.tol:g} otherwise; range (0, 1))")
    p.add_argument("--line-search", choices=LINE_SEARCH_RULES, default=None,
                   help="Newton's line search (default: energy with associated flow, residual "
                        "otherwise; contfab.fem.solver.stationary_alpha)")
    p.add_argument("--tol-stall", type=float, default=NewtonOptions.tol_stall,
                   help="accept a Newton step whose relative residual stops falling at or "
                        f"below this (default {NewtonOptions.tol_stall:g}; range [1e-8, 1))")
    p.add_argument("--no-check", action="store_true",
                   help="tiers >= 1: skip the tier-0 check against Prandtl-Reissner at phi*")


def solution_name(args) -> str:
    """The solution strategy of a run, as the notes name it."""
    if args.explicit is not None:
        return f"explicit dynamic relaxation, {args.explicit} cycles"
    if args.relaxation_time is not None:
        return f"Duvaut-Lions viscoplastic, tau = {args.relaxation_time:g} settlement/B"
    return "rate-independent Newton (consistent tangent)"


TABLE_COLUMNS = ("factor", "phi", "psi", "element", "level", "dofs", "computed", "reference",
                 "relative_error", "drop_vs_associated", "plateau_drift", "steps",
                 "median_newton", "wall_s", "status")


def run(args) -> CaseResult:
    """Tier 0: the (φ, ψ) study (:func:`run_tier0`); tiers >= 1 and auto: the calibrated
    material beside its tier-0 check (:func:`run_calibrated`)."""
    params = material_options.load(args)
    if args.lam is not None:
        params = params.replace("regularization", lam=args.lam)
    if args.fast:   # the test-suite preset: P2 on the level-1 mesh
        args.element, args.level = ["P2"], [1]
    if args.tier is None:
        args.tier = "0" if args.phi is not None or args.psi is not None else "1"
    if args.settlement is not None and not 0.0 < args.settlement <= 1.0:
        raise ParamError(f"settlement = {args.settlement:g} B is outside the accepted range (0, 1]")
    if args.tol is not None and not 0.0 < args.tol < 1.0:
        raise ParamError(f"tol = {args.tol:g} is outside the accepted range (0, 1)")
    tol = NewtonOptions.tol if args.tol is None else args.tol
    NewtonOptions(relaxation_time=args.relaxation_time, tol=tol,                  # ranges
                  tol_stall=max(tol, args.tol_stall))
    if args.explicit is not None:
        ExplicitOptions(cycles=args.explicit)                                        # range
        if args.relaxation_time is not None:
            raise ParamError("--explicit and --relaxation-time are two solution strategies; "
                             "give one")
    for level in args.level:
        check_level(level)
    tier = material_options.tier_arg(args.tier)
    if args.element is None:
        args.element = ["P3"] if tier == 0 else [CALIBRATED_ELEMENT]
    if tier == 0:
        return run_tier0(args, params)
    if args.phi is not None or args.psi is not None:
        raise ParamError(f"--phi/--psi set tier 0's constant angles; tier {tier} takes them "
                         "from the model at c0 (use --tier 0 for given angles)")
    return run_calibrated(args, params, tier)


def run_tier0(args, params) -> CaseResult:
    """Every (φ, ψ, element, level) combination; a table CSV when there is more than one.

    A combination whose Newton fails (ConvergenceError) is recorded in the notes
    (:func:`contfab.scenes.case.failure_note`: message, last converged settlement step and
    factor) and as a ``failed`` table row, and the others still run; only the run behind
    the headline figure (the first associated one with an exact reference) re-raises.
    """
    phis = args.phi or ([30.0] if args.factor == "Ngamma" else [params.tier0.phi_deg])
    symbol = "N_q" if args.factor == "Nq" else "N_gamma"
    source = "Prandtl-Reissner" if args.factor == "Nq" else "Martin (2005)"
    figures, unreferenced, notes, files, rows = [], [], {}, [], []
    for phi in phis:
        for element in args.element:
            for level in args.level:
                associated = None
                for psi_arg in args.psi or ["phi"]:
                    psi = phi if psi_arg == "phi" else float(psi_arg)
                    label = f"{symbol}(phi={phi:g}, psi={psi:g}, {element}, level {level})"
                    if len(args.element) == len(args.level) == 1:
                        label = f"{symbol}(phi={phi:g}, psi={psi:g})"
                    headline = not figures and psi == phi and \
                        math.isfinite(reference_factor(args.factor, phi))
                    t0 = time.perf_counter()
                    try:
                        r = solve(phi, psi, args.factor, element, level, params, args.out,
                                  not args.quiet, apex_stiffness=args.apex_stiffness,
                                  settlement=args.settlement,
                                  relaxation_time=args.relaxation_time,
                                  tol_stall=args.tol_stall, explicit=args.explicit, tol=args.tol,
                                  line_search=args.line_search)
                    except ConvergenceError as exc:
                        if headline:
                            raise
                        failure = exc
                        notes[label] = failure_note(exc, args.factor, "settlement")
                        notes[label]["wall_s"] = time.perf_counter() - t0
                        rows.append([args.factor, phi, psi, element, level, math.nan, math.nan,
                                     reference_factor(args.factor, phi), math.nan, math.nan,
                                     math.nan, math.nan, math.nan, math.nan, "failed"])
                        continue
                    if psi == phi:
                        associated = r["computed"]
                    drop = r["computed"] / associated - 1.0 if associated else math.nan
                    if math.isfinite(r["reference"]) and psi == phi:
                        figures.append(Figure(label, r["computed"], r["reference"], source))
                    elif psi != phi and args.factor == "Nq":
                        davis = prandtl_nq(davis_angle(phi, psi))
                        figures.append(Figure(label, r["computed"], davis, "Prandtl-Reissner at "
                                              "the Davis-reduced angle (a rough bound)"))
                    else:
                        unreferenced.append(Figure(label, r["computed"], math.nan,
                                                   NO_REFERENCE))
                    notes[label] = {k: r[k] for k in ("computed", "peak", "plateau_drift",
                                                      "settlement_over_B", "dofs", "wall_s",
                                                      "steps", "median_newton")}
                    notes[label]["last_step_residuals"] = r["residuals"][-1]
                    notes[label]["solution"] = solution_name(args)
                    if psi != phi:
                        notes[label]["davis_phi"] = davis_angle(phi, psi)
                    if psi != phi and associated:
                        notes[label]["drop_vs_associated"] = drop
                    rows.append([args.factor, phi, psi, element, level, r["dofs"], r["computed"],
                                 r["reference"], r["computed"] / r["reference"] - 1.0, drop,
                                 r["plateau_drift"], r["steps"], r["median_newton"], r["wall_s"],
                                 "converged"])
                    files += r["files"]
    figures += unreferenced
    if not figures:     # every run failed: the last failure is the error
        raise failure
    if len(rows) > 1 and args.out is not None:
        table = Path(args.out) / f"strip_footing_{args.factor}_table.csv"
        files.append(write_csv(table, TABLE_COLUMNS, rows))
    return CaseResult(figures, notes, files)



CALIBRATED_KEYS = ("peak", "peak_settlement_over_B", "computed_end", "settlement_over_B",
                   "dofs", "steps", "cuts", "median_newton", "max_newton", "wall_s")
"""What the notes keep of a calibrated-material run."""


def tier0_bounds(factor: str, params) -> dict:
    """The exact tier-0 (associated, constant φ) factor at the critical angle φ* and at the
    initial state's peak angle φ0 = φ(c0): N_q by Prandtl–Reissner (NaN for N_γ, which has
    no closed form at these angles). A dense start softens from φ0 to φ*, a loose one
    hardens from φ0 to φ*. The larger value bounds the load from above (no point's φ
    exceeds it, and non-associated flow carries no more than associated flow with the same
    yield surface: Radenković's first theorem); the smaller is where the load must lie
    above but not a theorem (the second theorem's lower bound is the associated load at
    atan(sin φ), lower still; docs/fem_validation.md §8)."""
    phi0, psi0 = material_options.initial_angles(params)
    phi_star = params.tier1.phi_star_deg
    value = prandtl_nq if factor == "Nq" else (lambda phi: math.nan)
    return {"phi_star": phi_star, "phi0": phi0, "psi0": psi0, "at_phi_star": value(phi_star),
            "at_phi0": value(phi0),
            "davis_phi0": davis_angle(phi0, psi0), "at_davis_phi0": value(davis_angle(phi0, psi0))}


def run_calibrated(args, params, tier) -> CaseResult:
    """The footing on the model of ``params`` (tier 1, 2 or auto) from its ``[initial]``
    state, beside the tier-0 check: tier 0 with associated flow at φ* against
    Prandtl–Reissner (N_q; skipped by ``--no-check`` and for N_γ). The calibrated factor is
    the peak of its load–settlement curve (the collapse load of a softening material;
    the end value of a hardening one), printed against the tier-0 values at φ* and at
    φ0 = φ(c0) (:func:`tier0_bounds`), with no published reference."""
    if len(args.element) != 1 or len(args.level) != 1:
        raise ParamError("tiers >= 1 run one element and one mesh level "
                         f"(got --element {' '.join(args.element)} --level "
                         f"{' '.join(map(str, args.level))})")
    element, level = args.element[0], args.level[0]
    bounds = tier0_bounds(args.factor, params)
    symbol = "N_q" if args.factor == "Nq" else "N_gamma"
    settlement = CALIBRATED_SETTLEMENT if args.settlement is None else args.settlement
    figures, notes, files = [], {}, []
    check = None
    if args.factor == "Nq" and not args.no_check:
        phi = bounds["phi_star"]
        check = solve(phi, phi, "Nq", element, level, params, args.out, not args.quiet,
                      apex_stiffness=args.apex_stiffness, tol=args.tol,
                      line_search=args.line_search)
        label = f"tier-0 check N_q(phi*={phi:.2f}, associated)"
        check_figure = Figure(label, check["computed"], check["reference"], "Prandtl-Reissner")
        notes[label] = {k: check[k] for k in ("plateau_drift", "dofs", "steps", "median_newton",
                                              "wall_s")}
        notes[label]["last_step_residuals"] = check["residuals"][-1]
        files += check["files"]

    def one(run_params, point_tiers) -> dict:
        return solve(bounds["phi0"], bounds["psi0"], args.factor, element, level, run_params,
                     args.out, not args.quiet, apex_stiffness=args.apex_stiffness,
                     settlement=settlement, relaxation_time=args.relaxation_time,
                     tier=point_tiers, tol_stall=args.tol_stall, explicit=args.explicit,
                     tol=args.tol, line_search=args.line_search)

    if tier == "auto":
        r, auto = run_auto(one, params, args.tolerance, min_tier=1)
    else:
        r, auto = one(params, tier), None
    curve_peak = int(np.argmax(r["curve_values"]))
    r["peak_settlement_over_B"] = float(r["curve_settlements"][curve_peak] / 2)
    r["computed_end"], r["max_newton"] = r["computed"], int(max(r["newton_per_step"]))
    low, high = sorted((bounds["at_phi_star"], bounds["at_phi0"]))
    within = bool(low <= r["peak"] <= high) if math.isfinite(low) else None
    c0 = params.initial.c0
    label = f"{symbol}(tier {args.tier}, c0={c0:.4f}: phi0={bounds['phi0']:.2f}, " \
            f"psi0={bounds['psi0']:.2f})"
    if within is None:
        source = f"{NO_REFERENCE}; no closed-form tier-0 value at phi* or phi0"
    else:
        source = (f"{NO_REFERENCE}; tier 0 (Prandtl-Reissner) gives {bounds['at_phi_star']:.4g} "
                  f"at phi*={bounds['phi_star']:.2f} and {bounds['at_phi0']:.4g} at "
                  f"phi0={bounds['phi0']:.2f}: {'between them' if within else 'NOT between them'}")
    figures.append(Figure(label, r["peak"], math.nan, source))
    if check is not None:
        figures.append(check_figure)
    notes[label] = {k: r[k] for k in CALIBRATED_KEYS}
    notes[label].update(
        within_tier0_bounds=within, tier0_bounds=bounds,
        solution=solution_name(args),
        newton_per_step=r["newton_per_step"])
    if auto is not None:
        notes[label]["auto"] = auto
    files += r["files"]
    return CaseResult(figures, notes, files)

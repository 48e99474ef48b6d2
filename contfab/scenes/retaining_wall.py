"""Smooth rigid wall translating away from / into a cohesionless backfill: K_a and K_p.

Scene (docs/theory.md §13). Backfill x ∈ [0, L], y ∈ [-H, 0] of unit weight γ, L = 4H; the wall
is the side x = 0 over the full height H. Smooth wall (uy free), rough fixed base
(ux = uy = 0), far side x = L on rollers (ux = 0). With a rough base the soil cannot
follow the wall homogeneously: a Rankine/Coulomb wedge forms from the wall's foot. A geostatic stage
equilibrates σyy = γy, σxx = K0 σyy (K0 = 1 - sin φ) under gravity, then displacements
are zeroed; the wall then translates by ux = ∓δ·t (active: away from the soil,
passive: into it). The earth-pressure coefficient is K = 2F/(γH²), F the horizontal
force of the soil on the wall (the reaction on the wall's DOFs).

Reference: Rankine (1857), K_a = (1 - sin φ)/(1 + sin φ), K_p = (1 + sin φ)/(1 - sin φ),
exact for a smooth vertical wall translating against a horizontal surface with
associated flow: the Rankine stress field is statically admissible (it puts no shear
on the base) and the planar Coulomb wedge from the foot, at π/4 ± φ/2 to the
horizontal, is a mechanism giving the same force. Associated flow (ψ = φ) by default.

**Model** (``--tier``, ``--params``, ``--c0``; :mod:`contfab.scenes.material_options`). The
default, tier 0, runs constant angles: the computed K is the value at the end of the
push (a multiple of the elastic strain scale H/λ) against Rankine, and the plateau is
checked. Tiers 1, 2 and auto run the parameter file's model from its ``[initial]``
state (dense by default, φ0 = φ(c0), ψ0 = ψ(c0) < φ0) to a wall displacement of 0.1 H;
their figure is the extreme K of the curve (the least active, the largest passive: the
strength the backfill mobilizes), printed with no published reference beside the tier-0
values on the same mesh (associated; with Rankine's) at the critical angle φ* and at φ0,
between which it must lie: the same mesh, because the stiff displacement solution puts K_a
below and K_p above Rankine by about 0.5 %, as much as a dense active wall's K lies above
K_a(φ0).

**Solver.** The rate-independent Newton of :mod:`contfab.fem.solver`, with the last-resort
stall tolerance ``--tol-stall-last`` (:data:`TOL_STALL_LAST`) for a step that fails at the
minimum step: the loose active wall needs it for three steps near 0.0124 H; a run that
never fails there is unchanged by it.
"""
from __future__ import annotations

import math
import time
from pathlib import Path


import numpy as np

from contfab.scenes import material_options
from contfab.scenes.case import CaseResult, Figure
from contfab.scenes.material_options import max_tier, point_updates
from contfab.fem.auto import run_auto
from contfab.fem import analysis, loads
from contfab.fem import mesh as meshes
from contfab.fem.assembly import Discretization
from contfab.fem.elements import ELEMENTS
from contfab.fem.material import TierMaterial
from contfab.fem.solver import NewtonOptions, Solver, Stage
from contfab.params import ParamError

DESCRIPTION = ("smooth retaining wall: active and passive earth pressure against Rankine, or on the "
               "calibrated material (any tier, dense or loose)")

HEIGHT = 1.0
CALIBRATED_DISPLACEMENT = 0.1
"""Default wall displacement of a tier >= 1 run, in H."""
TOL_STALL_LAST = 1e-3
"""Default last-resort stall tolerance (:class:`~contfab.fem.solver.NewtonOptions`): the
loose active wall (tier 1, P2 level 1) otherwise stops at 0.0124 H, where its steps stall at
a relative residual of 1e-4 down to the minimum step (docs/fem_validation.md §8)."""


def rankine(phi_deg: float, mode: str) -> float:
    """K_a = (1 - sin φ)/(1 + sin φ), K_p = 1/K_a (Rankine 1857)."""
    s = math.sin(math.radians(phi_deg))
    ka = (1.0 - s) / (1.0 + s)
    return ka if mode == "active" else 1.0 / ka


def solve(phi_deg: float, psi_deg: float, mode: str, element: str, level: int, params,
          out: Path | None, progress: bool, push: float = 30.0, tier=0,
          displacement: float | None = None, relaxation_time: float | None = None,
          tol_stall_last: float | None = TOL_STALL_LAST) -> dict:
    """One wall analysis; returns K, the reference, the curve summary and Newton figures.

    ``tier`` 0 runs the constant angles ``phi_deg``, ``psi_deg`` (K against Rankine); a tier
    >= 1 (or an array: a tier per quadrature point) the model of ``params`` from its
    ``[initial]`` state (no reference; ``phi_deg`` only names the files). The wall moves by
    ``push`` elastic strain scales H/λ, or by ``displacement`` · H. ``relaxation_time``: the
    Duvaut–Lions material (:mod:`contfab.fem.viscous`), τ in units of the wall displacement
    over H (the wall moves at unit rate). ``tol_stall_last`` is the Newton stall tolerance of
    a step that failed at the minimum step (None: such a step ends the run).
    """
    if displacement is not None and not 0.0 < displacement <= 0.5:
        raise ParamError(f"displacement = {displacement:g} H is outside the accepted range "
                         "(0, 0.5]")
    gamma = 1.0
    top = max_tier(tier)
    if top == 0:
        params = params.replace("tier0", phi_deg=phi_deg, psi_deg=psi_deg)
    params = params.with_tier(top).replace("regularization", p_ref=gamma * HEIGHT)
    if not 1 <= level <= 8:
        raise ParamError(f"mesh level = {level} is outside the accepted range [1, 8]")
    kind = ELEMENTS[element].mesh_kind
    mesh = meshes.tensor(meshes.graded(0.0, 4 * HEIGHT, 16 * level, 4.0),
                         meshes.graded(-HEIGHT, 0.0, 6 * level, 2.0), kind=kind)
    disc = Discretization(mesh, element)
    material = TierMaterial(params, point_tiers=tier) if np.ndim(tier) else \
        TierMaterial(params, tier=top)
    n = disc.npoints
    k0 = 1.0 - math.sin(math.radians(phi_deg))
    y = disc.points[:, 1]
    stress0 = np.column_stack((k0 * gamma * y, gamma * y, np.zeros(n)))
    solver = Solver(disc, material, stress0, material.initial_state(n),
                    NewtonOptions(relaxation_time=relaxation_time, tol_stall_last=tol_stall_last))
    f_dead = loads.body_force(disc, by=-gamma)
    wall = loads.boundary_dofs(disc, "left", "x")
    supports = np.setdiff1d(np.concatenate((loads.boundary_dofs(disc, "bottom", "x"),
                                             loads.boundary_dofs(disc, "bottom", "y"),
                                             loads.boundary_dofs(disc, "right", "x"))), wall)
    fixed = np.unique(np.concatenate((supports, wall)))
    geostatic = Stage("geostatic", fixed, np.zeros(len(fixed)), f_dead, dt0=1.0, dt_max=1.0,
                      dt_min=1.0, reset_displacement=True)
    delta = push * HEIGHT / params.regularization.lam if displacement is None \
        else displacement * HEIGHT
    sign = -1.0 if mode == "active" else 1.0
    move = Stage(mode, fixed, np.where(np.isin(fixed, wall), sign * delta, 0.0), f_dead,
                 dt0=0.05 if top == 0 else 0.01, dt_max=0.1 if top == 0 else 0.05,
                 dt_min=1e-4 if top == 0 else 1e-6, duration=delta / HEIGHT)
    reference = rankine(phi_deg, mode) if top == 0 else math.nan

    def measure(s: Solver) -> dict:
        ux = s.committed.u[wall].mean() if s.committed.stage == mode else 0.0
        return {"wall_displacement": float(abs(ux) / HEIGHT),
                "K": 2.0 * s.reactions(wall) / (gamma * HEIGHT**2)}

    name = f"retaining_wall_{mode}_phi{phi_deg:g}" if top == 0 else \
        f"retaining_wall_{mode}_{'mixed' if np.ndim(tier) else f'tier{top}'}_c{params.initial.c0:.4f}"
    outputs = analysis.Outputs(out, name, frame_every=5, curve_axes=("wall_displacement", "K"),
                               reference=reference if top == 0 else None,
                               reference_label=f"Rankine K_{mode[0]}")
    t0 = time.perf_counter()
    result = analysis.run(solver, [geostatic, move], measure, outputs, progress=progress,
                          record_stages=[mode])
    values = result.column("K")
    tail = values[result.column("t") >= 0.8]
    strongest = int(np.argmin(values) if mode == "active" else np.argmax(values))
    return {"mode": mode, "phi": phi_deg, "reference": reference, "computed": float(values[-1]),
            "strongest": float(values[strongest]),
            "strongest_displacement": float(result.column("wall_displacement")[strongest]),
            "plateau_drift": float(tail[-1] / tail[0] - 1.0), "dofs": disc.ndofs,
            "wall_s": time.perf_counter() - t0, "steps": len(result.iterations),
            "cuts": int(sum(r.cuts for r in solver.records)),
            "last_resort_steps": int(sum(r.last_resort for r in solver.records)),
            "median_newton": float(np.median(result.iterations)),
            "max_newton": int(max(result.iterations)), "newton_per_step": list(result.iterations),
            "displacement": float(delta / HEIGHT), "indicators": result.indicators,
            "point_updates": point_updates(material), "files": result.files}


def add_arguments(p) -> None:
    material_options.add_arguments(p, default_tier="0")
    p.add_argument("--phi", type=float, default=None,
                   help="tier 0: friction angle in degrees (default: the parameter file's "
                        "tier-0 phi)")
    p.add_argument("--psi", default="phi",
                   help="tier 0: dilatancy angle in degrees, or 'phi' for associated flow "
                        "(default)")
    p.add_argument("--mode", choices=("active", "passive", "both"), default="both")
    p.add_argument("--element", choices=sorted(ELEMENTS), default="P3",
                   help="element family (default P3: the element study's choice)")
    p.add_argument("--level", type=int, default=1, help="mesh density level, 1..8")
    p.add_argument("--displacement", type=float, default=None,
                   help="wall displacement over H (default: tier 0, 30 elastic strain scales "
                        f"H/lambda; tiers >= 1, {CALIBRATED_DISPLACEMENT})")
    p.add_argument("--relaxation-time", type=float, default=None,
                   help="Duvaut-Lions viscoplastic material with this relaxation time, in "
                        "units of wall displacement over H (default: rate-independent)")
    p.add_argument("--tol-stall-last", type=float, default=TOL_STALL_LAST,
                   help="accept a step that failed at the minimum step size when its relative "
                        "residual stops falling at or below this (default "
                        f"{TOL_STALL_LAST:g}; 0: off, the run stops there)")


CALIBRATED_KEYS = ("strongest", "strongest_displacement", "computed", "displacement", "dofs",
                   "steps", "cuts", "last_resort_steps", "median_newton", "max_newton", "wall_s",
                   "newton_per_step")
"""What the notes keep of a calibrated-material run (``computed``: K at the end)."""


def run(args) -> CaseResult:
    """Tier 0: K_a, K_p against Rankine at the given angles. Tiers >= 1 and auto: the model
    of the parameter file from its initial state; the figure is the extreme K of the curve
    (the least K active, the largest passive: the strength the wall mobilizes), printed
    against the tier-0 values on the same mesh at the critical angle φ* and the initial
    φ0 = φ(c0), with no published reference."""
    params = material_options.load(args)
    if args.fast:   # the test-suite preset: P2 on the level-1 mesh
        args.element, args.level = "P2", 1
    tier = material_options.tier_arg(args.tier)
    if tier != 0 and (args.phi is not None or args.psi != "phi"):
        raise ParamError(f"--phi/--psi set tier 0's constant angles; tier {tier} takes them "
                         "from the model at c0 (use --tier 0 for given angles)")
    phi = params.tier0.phi_deg if args.phi is None else args.phi
    psi = phi if args.psi == "phi" else float(args.psi)
    phi0, psi0 = material_options.initial_angles(params)
    phi_star = params.tier1.phi_star_deg
    displacement = args.displacement
    tol_stall_last = args.tol_stall_last or None
    NewtonOptions(relaxation_time=args.relaxation_time, tol_stall_last=tol_stall_last)  # ranges
    if tier != 0 and displacement is None:
        displacement = CALIBRATED_DISPLACEMENT
    figures, notes, files = [], {}, []
    for mode in (("active", "passive") if args.mode == "both" else (args.mode,)):
        def one(run_params, point_tiers):
            return solve(phi0 if tier != 0 else phi, psi, mode, args.element, args.level,
                         run_params, args.out, not args.quiet, tier=point_tiers,
                         displacement=displacement, relaxation_time=args.relaxation_time,
                         tol_stall_last=tol_stall_last)

        if tier == 0:
            r = one(params, 0)
            label = f"K_{mode[0]}(phi={phi:g})"
            figures.append(Figure(label, r["computed"], r["reference"], "Rankine"))
            notes[label] = {k: r[k] for k in ("plateau_drift", "dofs", "wall_s", "steps",
                                              "median_newton")}
            files += r["files"]
            continue
        auto = None
        if tier == "auto":
            r, auto = run_auto(one, params, args.tolerance, min_tier=1)
        else:
            r = one(params, tier)
        bounds = {}
        for key, angle in (("phi_star", phi_star), ("phi0", phi0)):
            t0 = solve(angle, angle, mode, args.element, args.level, params, None, False,
                       tol_stall_last=tol_stall_last)
            bounds[key] = {"phi": angle, "tier0": t0["computed"], "rankine": rankine(angle, mode),
                           "wall_s": t0["wall_s"]}
        low, high = sorted((bounds["phi_star"]["tier0"], bounds["phi0"]["tier0"]))
        within = bool(low <= r["strongest"] <= high)
        label = (f"K_{mode[0]}(tier {args.tier}, c0={params.initial.c0:.4f}: phi0={phi0:.2f}, "
                 f"psi0={psi0:.2f})")
        figures.append(Figure(
            label, r["strongest"], math.nan,
            f"no published reference; tier 0 on this mesh (associated) gives "
            f"{bounds['phi_star']['tier0']:.4g} at phi*={phi_star:.2f} and "
            f"{bounds['phi0']['tier0']:.4g} at phi0={phi0:.2f} (Rankine "
            f"{bounds['phi_star']['rankine']:.4g}, {bounds['phi0']['rankine']:.4g}): "
            + ("between them" if within else "NOT between them")))
        notes[label] = {k: r[k] for k in CALIBRATED_KEYS}
        notes[label].update(within_tier0_bounds=within, tier0_bounds=bounds)
        if auto is not None:
            notes[label]["auto"] = auto
        files += r["files"]
    return CaseResult(figures, notes, files)

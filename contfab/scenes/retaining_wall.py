"""Smooth rigid wall translating away from / into a cohesionless backfill: K_a and K_p.

Scene (DESIGN §8). Backfill x ∈ [0, L], y ∈ [-H, 0] of unit weight γ, L = 4H; the wall
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
horizontal, is a mechanism giving the same force. Associated flow (ψ = φ) by default. Model tier 0. The computed K is the value at the end of the
push (a multiple of the elastic strain scale H/λ); the plateau is checked.
"""
from __future__ import annotations

import math
import time
from pathlib import Path


import numpy as np

from contfab.scenes.case import CaseResult, Figure
from contfab.fem import analysis, loads
from contfab.fem import mesh as meshes
from contfab.fem.assembly import Discretization
from contfab.fem.elements import ELEMENTS
from contfab.fem.material import TierMaterial
from contfab.fem.solver import NewtonOptions, Solver, Stage
from contfab.params import ParamError, default_params, load_params

DESCRIPTION = "smooth retaining wall: active and passive earth pressure against Rankine"

HEIGHT = 1.0


def rankine(phi_deg: float, mode: str) -> float:
    """K_a = (1 - sin φ)/(1 + sin φ), K_p = 1/K_a (Rankine 1857)."""
    s = math.sin(math.radians(phi_deg))
    ka = (1.0 - s) / (1.0 + s)
    return ka if mode == "active" else 1.0 / ka


def solve(phi_deg: float, psi_deg: float, mode: str, element: str, level: int, params,
          out: Path | None, progress: bool, push: float = 30.0) -> dict:
    """One wall analysis; returns K, the reference, the curve summary and Newton figures."""
    gamma = 1.0
    params = params.with_tier(0).replace("tier0", phi_deg=phi_deg, psi_deg=psi_deg) \
        .replace("regularization", p_ref=gamma * HEIGHT)
    if not 1 <= level <= 8:
        raise ParamError(f"mesh level = {level} is outside the accepted range [1, 8]")
    kind = ELEMENTS[element].mesh_kind
    mesh = meshes.tensor(meshes.graded(0.0, 4 * HEIGHT, 16 * level, 4.0),
                         meshes.graded(-HEIGHT, 0.0, 6 * level, 2.0), kind=kind)
    disc = Discretization(mesh, element)
    material = TierMaterial(params, tier=0)
    n = disc.npoints
    k0 = 1.0 - math.sin(math.radians(phi_deg))
    y = disc.points[:, 1]
    stress0 = np.column_stack((k0 * gamma * y, gamma * y, np.zeros(n)))
    solver = Solver(disc, material, stress0, material.initial_state(n), NewtonOptions())
    f_dead = loads.body_force(disc, by=-gamma)
    wall = loads.boundary_dofs(disc, "left", "x")
    supports = np.setdiff1d(np.concatenate((loads.boundary_dofs(disc, "bottom", "x"),
                                             loads.boundary_dofs(disc, "bottom", "y"),
                                             loads.boundary_dofs(disc, "right", "x"))), wall)
    fixed = np.unique(np.concatenate((supports, wall)))
    geostatic = Stage("geostatic", fixed, np.zeros(len(fixed)), f_dead, dt0=1.0, dt_max=1.0,
                      dt_min=1.0, reset_displacement=True)
    delta = push * HEIGHT / params.regularization.lam
    sign = -1.0 if mode == "active" else 1.0
    move = Stage(mode, fixed, np.where(np.isin(fixed, wall), sign * delta, 0.0), f_dead,
                 dt0=0.05, dt_max=0.1, dt_min=1e-4)
    reference = rankine(phi_deg, mode)

    def measure(s: Solver) -> dict:
        ux = s.committed.u[wall].mean() if s.committed.stage == mode else 0.0
        return {"wall_displacement": float(abs(ux) / HEIGHT),
                "K": 2.0 * s.reactions(wall) / (gamma * HEIGHT**2)}

    name = f"retaining_wall_{mode}_phi{phi_deg:g}"
    outputs = analysis.Outputs(out, name, frame_every=5, curve_axes=("wall_displacement", "K"),
                               reference=reference, reference_label=f"Rankine K_{mode[0]}")
    t0 = time.perf_counter()
    result = analysis.run(solver, [geostatic, move], measure, outputs, progress=progress,
                          record_stages=[mode])
    values = result.column("K")
    tail = values[result.column("t") >= 0.8]
    return {"mode": mode, "phi": phi_deg, "reference": reference, "computed": values[-1],
            "plateau_drift": float(tail[-1] / tail[0] - 1.0), "dofs": disc.ndofs,
            "wall_s": time.perf_counter() - t0, "steps": len(result.iterations),
            "median_newton": float(np.median(result.iterations)), "files": result.files}


def add_arguments(p) -> None:
    p.add_argument("--phi", type=float, default=None,
                   help="friction angle in degrees (default: the parameter file's tier-0 phi)")
    p.add_argument("--psi", default="phi",
                   help="dilatancy angle in degrees, or 'phi' for associated flow (default)")
    p.add_argument("--mode", choices=("active", "passive", "both"), default="both")
    p.add_argument("--element", choices=sorted(ELEMENTS), default="P3",
                   help="element family (default P3: the element study's choice)")
    p.add_argument("--level", type=int, default=1, help="mesh density level, 1..8")
    p.add_argument("--params", default=None, help="parameter file (default: the shipped one)")


def run(args) -> CaseResult:
    params = default_params() if args.params is None else load_params(args.params)
    if args.fast:   # the test-suite preset: P2 on the level-1 mesh
        args.element, args.level = "P2", 1
    phi = params.tier0.phi_deg if args.phi is None else args.phi
    psi = phi if args.psi == "phi" else float(args.psi)
    figures, notes, files = [], {}, []
    for mode in (("active", "passive") if args.mode == "both" else (args.mode,)):
        r = solve(phi, psi, mode, args.element, args.level, params, args.out, not args.quiet)
        label = f"K_{mode[0]}(phi={phi:g})"
        figures.append(Figure(label, r["computed"], r["reference"], "Rankine"))
        notes[label] = {k: r[k] for k in ("plateau_drift", "dofs", "wall_s", "steps",
                                          "median_newton")}
        files += r["files"]
    return CaseResult(figures, notes, files)


"""A granular layer sheared to γ = 1 and reversed to γ = -1: tier 1 vs tier 2 vs the DEM.

Scene (docs/theory.md §13). A layer W × H = 1 × 1 in ideal simple shear: the base is fixed, every
point moves by ux = γ y (the rough top platen drives γ, the rigid rings or hinged walls
of a simple-shear apparatus keep the layer from bulging), and the height changes
uniformly, uy = (y/H) v with v the platen's settlement, under the constant normal
pressure P0 = p_ref = 1 on the top (dead load). The v of all points are one unknown
(``Stage.ties`` with factors y/H). Initial stress -P0 I and the parameter file's
``[initial]`` state. Why homogeneous: at the critical state the model is perfectly
plastic, and a free layer (u depending on y only) localizes into a horizontal band of
indeterminate thickness (measured: the shear strain ranged 0.01-1.3 across a 2-element
layer at γ = 1, and a 4-element layer had a singular Newton matrix at the onset of
flow); τ/σn is the same, but volume change and fabric are then not comparable with the
DEM cell, which is homogeneous on average (periodic). The stage parameter is the path
time τ of the standard path ``simple_shear_reversal`` (:mod:`dem.paths`): γ = τ on the
forward stage, γ = 1 - (τ - 1) on the reverse stage, L_xy = dγ/dτ = ±1 throughout;
the spin increment -Δγ/2 reaches the update as in the DEM cell.

Measured: τ/σn = σxy/(-σyy), σxy the horizontal force of the top platen on the layer
per unit width (the reaction, docs/theory.md §13), σyy the mean vertical stress; the volumetric
strain ε_v = v/H; the packing fraction c and, for tier 2, the fabric (B, θp), as means
over the quadrature points. The homogeneous layer must reproduce the material-point
driver on the same path (:func:`contfab.material_point.run_path`, tier 1): reported as
``max_dev_vs_point``, the largest difference in τ/σn at the driver's rows, leaving out
the first two steps of each stage (the elastic transient is ~1e-3 wide in γ, and
interpolating the two step grids across it is no comparison). The two integrate the
same update on different step grids, so off the critical state (c evolving) they differ
at first order in the step (6.1e-4 at the --fast Δγ = 0.05).

Reference: the 2D disc DEM (``dem/``) on the same path, stored in
``contfab/scenes/data/simple_shear_reversal_dem.csv`` (the shared history columns) with its
run sidecar ``simple_shear_reversal_dem.json``; it was produced (not run by this
case) by

    contfab dem run simple_shear_reversal --n 1000 --seed 4 --kappa 1000 --out DIR

at the DEM settings of the calibration campaign that made the shipped parameters (N = 1000
discs, inter-particle friction 0.5, sample prepared at the test friction: loose, c0 =
0.8085; stiffness number κ = 1000, inertial number 1e-3) but on a sample the calibration
did not see: the campaign ran seeds 1-3 (``[provenance.campaign]`` of
``contfab/data/default_params.toml``), this is seed 4, so the errors are those of a
prediction, not of a fit. The model starts from this sample's c and fabric, not from the
shipped ``[initial]`` state. Figures: τ/σn at γ = +1 (end of the
forward stage) and at γ = -1 (end of the reversal) per tier against the DEM's, and
the RMS difference of τ/σn over the whole path. The model parameters are the
shipped defaults (``contfab/data/default_params.toml``, calibrated from the DEM by
``contfab calibrate``, whose campaign holds this path): the errors measure that
calibration, not the solver.
"""
from __future__ import annotations

import csv
import math
import time
from pathlib import Path


import numpy as np

from contfab.scenes.case import CaseResult, Figure
from contfab.fem import analysis, loads
from contfab.fem import mesh as meshes
from contfab.fem.assembly import Discretization
from contfab.fem.auto import run_auto
from contfab.fem.elements import ELEMENTS
from contfab.fem.material import TierMaterial
from contfab.fem.solver import NewtonOptions, Solver, Stage
from contfab.material_point import run_path
from contfab.models import tiers
from contfab.params import ParamError, default_params, load_params
from dem.conventions import fabric_polar
from dem.fileio import write_csv

DESCRIPTION = "simple shear of a layer, forward and reversed: tier 1 vs tier 2 vs the DEM"

WIDTH = HEIGHT = 1.0
DEM_CSV = Path(__file__).resolve().parent / "data" / "simple_shear_reversal_dem.csv"
PATH = "simple_shear_reversal"
STAGES = (("forward", 1.0), ("reverse", -2.0))
"""(name, change of γ over the stage); the stage lengths in τ are |Δγ| (|L_xy| = 1)."""


def load_dem(path: Path = DEM_CSV) -> dict[str, np.ndarray]:
    """The DEM history: stage, tau, gamma, ratio (τ/σn = σxy/(-σyy)), eps_v, c, A, B, theta_p
    (degrees)."""
    if not path.is_file():
        raise FileNotFoundError(f"DEM reference {path} is missing (see this case's docstring "
                                f"for the command that makes it)")
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    col = {k: np.array([float(r[k]) for r in rows]) for k in
           ("stage", "tau", "sxy", "syy", "eps_v", "gamma", "c", "A", "B", "theta_p")}
    return {"stage": col["stage"], "tau": col["tau"], "gamma": col["gamma"], "ratio": col["sxy"] / -col["syy"],
            "eps_v": col["eps_v"], "c": col["c"], "A": col["A"], "B": col["B"],
            "theta_p": np.degrees(col["theta_p"])}


def layer_mesh(element: str, nx: int, ny: int):
    if not (1 <= nx <= 64 and 1 <= ny <= 64):
        raise ParamError(f"mesh nx = {nx}, ny = {ny}: each must lie in [1, 64]")
    return meshes.tensor(np.linspace(0, WIDTH, nx + 1), np.linspace(0, HEIGHT, ny + 1),
                         kind=ELEMENTS[element].mesh_kind)


def homogeneous_kinematics(disc: Discretization):
    """(fixed DOFs, their ux = y at γ = 1, ties, tie factors): every x DOF prescribed,
    every free y DOF y/H times one top DOF (DOFs interleave x, y)."""
    loc_y = disc.basis.doflocs[1]
    x_dofs = np.arange(0, disc.ndofs, 2, dtype=np.int64)
    y_dofs = np.arange(1, disc.ndofs, 2, dtype=np.int64)
    base = y_dofs[np.abs(loc_y[y_dofs]) < 1e-9 * HEIGHT]
    fixed = np.union1d(x_dofs, base)
    free_y = np.setdiff1d(y_dofs, base)
    leader = free_y[np.argmax(loc_y[free_y])]
    followers = free_y[free_y != leader]
    ties = np.column_stack((followers, np.full(len(followers), leader)))
    return fixed, loc_y[fixed], ties, loc_y[followers] / loc_y[leader]


def solve(params, tier, element: str, nx: int, ny: int, dgamma: float,
          out: Path | None, progress: bool, label: str | None = None) -> dict:
    """The layer along the path with model tier ``tier`` (an int, or a tier per quadrature
    point: mixed tiers); γ steps of at most ``dgamma``."""
    if not 0 < dgamma <= 0.1:
        raise ParamError(f"dgamma = {dgamma:g} is outside the accepted range (0, 0.1]")
    p0 = params.regularization.p_ref
    disc = Discretization(layer_mesh(element, nx, ny), element)
    mixed = np.ndim(tier) > 0
    material = TierMaterial(params, point_tiers=tier) if mixed else TierMaterial(params, tier=tier)
    n = disc.npoints
    stress0 = np.zeros((n, 3))
    stress0[:, :2] = -p0
    solver = Solver(disc, material, stress0, material.initial_state(n), NewtonOptions())
    fixed, y_fixed, ties, factors = homogeneous_kinematics(disc)
    top_x, top_y = (loads.boundary_dofs(disc, "top", c) for c in ("x", "y"))
    f_dead = loads.surface_load(disc, "top", pressure=p0)
    names = material.state_names
    stages = []
    for name, change in STAGES:
        dt = dgamma / abs(change)
        stages.append(Stage(name, fixed, change * y_fixed, f_dead, dt0=dt / 4, dt_max=dt,
                            dt_min=dt * 1e-4, ties=ties,
                            tie_factors=factors))

    def measure(s: Solver) -> dict:
        c = s.committed
        tau = c.t if c.stage in ("initial", "forward") else 1.0 + 2.0 * c.t
        mean = np.average(c.stress, axis=0, weights=disc.weights.ravel())
        row = {"tau": tau, "gamma": tau if tau <= 1.0 else 2.0 - tau,
               "ratio": s.reactions(top_x) / WIDTH / -mean[1],
               "syy": mean[1], "eps_v": float(c.u[top_y].mean() / HEIGHT)}
        state = np.average(c.state, axis=0, weights=disc.weights.ravel())
        if "c" in names:
            row["c"] = float(tiers.packing_fraction(state[names.index("c")],
                                                    -0.5 * (mean[0] + mean[1]), params))
        if "Bc" in names:
            b, theta = fabric_polar(state[names.index("Bc")], state[names.index("Bs")])
            row["B"], row["theta_p"] = float(b), math.degrees(theta)
        return row

    name = f"simple_shear_reversal_{label or f'tier{tier}'}"
    outputs = analysis.Outputs(out, name, frame_every=20,
                               curve_axes=("gamma", "ratio"))
    t0 = time.perf_counter()
    start = measure(solver)                              # τ = 0: the initial state
    result = analysis.run(solver, stages, measure, outputs, progress=progress)
    curve = {k: np.insert(result.column(k), 0, start[k]) for k in start}
    return {"curve": curve, "wall_s": time.perf_counter() - t0, "dofs": disc.ndofs,
            "steps": len(result.iterations), "median_newton": float(np.median(result.iterations)),
            "files": result.files, "indicators": result.indicators,
            "point_updates": dict(material.point_updates)}


def at_tau(curve: dict, key: str, tau: float) -> float:
    """The curve's ``key`` at path time ``tau`` (linear interpolation)."""
    return float(np.interp(tau, curve["tau"], curve[key]))


def add_arguments(p) -> None:
    p.add_argument("--tiers", nargs="+", default=["1", "2"], choices=("1", "2", "auto"),
                   help="model tiers to run (default 1 and 2); auto: the cheapest model per "
                        "point whose measured bound meets --tolerance (contfab.fem.auto)")
    p.add_argument("--tolerance", type=float, default=0.09,
                   help="auto: tolerated RMS error of R/P against the DEM (default 0.09)")
    p.add_argument("--element", choices=sorted(ELEMENTS), default="P2")
    p.add_argument("--nx", type=int, default=2, help="elements across the layer (default 2)")
    p.add_argument("--ny", type=int, default=2, help="elements through the layer (default 2)")
    p.add_argument("--dgamma", type=float, default=0.01,
                   help="largest shear-strain step (default 0.01, the DEM's output interval)")
    p.add_argument("--params", default=None, help="parameter file (default: the shipped one)")


def run(args) -> CaseResult:
    params = default_params() if args.params is None else load_params(args.params)
    if args.fast:   # the test-suite preset: one element, coarse steps
        args.nx, args.ny, args.dgamma = 1, 1, 0.05
    dem = load_dem()
    # the same path from the same state: the model starts from the DEM sample's c and fabric
    params = params.replace("initial", c0=dem["c"][0], A0=dem["A"][0], B0=dem["B"][0],
                            theta_p0_deg=dem["theta_p"][0])
    tau_fwd, tau_end = (dem["tau"][np.flatnonzero(dem["stage"] == k)[-1]] for k in (0, 1))
    figures, notes, files, table = [], {}, [], {"tau": dem["tau"], "gamma": dem["gamma"],
                                                 "dem_ratio": dem["ratio"]}
    for tier in args.tiers:
        auto = None
        if tier == "auto":
            r, auto = run_auto(lambda p, t: solve(p, t, args.element, args.nx, args.ny,
                                                  args.dgamma, args.out, not args.quiet,
                                                  f"auto_{'mixed' if np.ndim(t) else f'tier{t}'}"),
                               params, args.tolerance, min_tier=1)
        else:
            tier = int(tier)
            r = solve(params, tier, args.element, args.nx, args.ny, args.dgamma, args.out,
                      not args.quiet)
        curve = r["curve"]
        key = "auto" if auto is not None else f"tier{tier}"
        for label, tau in (("+1", tau_fwd), ("-1", tau_end)):   # the DEM's stage ends
            figures.append(Figure(f"tau/sigma_n at gamma = {label} ({key})",
                                  at_tau(curve, "ratio", tau), at_tau(dem, "ratio", tau),
                                  "DEM, N = 1000"))
        fe_on_dem = np.interp(dem["tau"], curve["tau"], curve["ratio"])
        table[f"{key}_ratio"] = fe_on_dem
        note = {"rms_ratio_diff_vs_dem": float(np.sqrt(np.mean((fe_on_dem - dem["ratio"])**2))),
                "eps_v_at_gamma_1": at_tau(curve, "eps_v", tau_fwd),
                "dem_eps_v_at_gamma_1": at_tau(dem, "eps_v", tau_fwd),
                "c_at_end": at_tau(curve, "c", tau_end), "dem_c_at_end": at_tau(dem, "c", tau_end),
                "dofs": r["dofs"], "steps": r["steps"], "median_newton": r["median_newton"],
                "wall_s": r["wall_s"]}
        if auto is not None:
            note["auto"] = auto
        if "B" in curve:
            for label, tau in (("1", tau_fwd), ("-1", tau_end)):
                for k in ("B", "theta_p"):
                    note[f"{k}_at_gamma_{label}"] = at_tau(curve, k, tau)
                    note[f"dem_{k}_at_gamma_{label}"] = at_tau(dem, k, tau)
        if tier == 1:
            point = run_path(PATH, params, tier=1, increment=args.dgamma)
            ratio = point["sxy"] / -point["syy"]
            since_start = np.minimum(point["tau"], np.where(point["tau"] >= 1.0,
                                                            point["tau"] - 1.0, np.inf))
            steady = since_start > 2.0 * args.dgamma    # not across an elastic transient
            note["max_dev_vs_point"] = float(np.max(np.abs(
                np.interp(point["tau"], curve["tau"], curve["ratio"]) - ratio)[steady]))
        notes[key] = note
        files += r["files"]
    if args.out is not None:
        files.append(write_csv(Path(args.out) / "simple_shear_reversal_vs_dem.csv",
                               list(table), np.column_stack(list(table.values())).tolist()))
    return CaseResult(figures, notes, files)


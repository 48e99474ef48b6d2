"""Stability matrix of the FEM solver (:mod:`contfab.fem`).

Validity range (declared by :mod:`contfab.fem.mesh` and :class:`contfab.fem.solver.Stage`,
quoted by their errors): non-degenerate, non-inverted elements; 0 < dt_min <= dt0 <=
dt_max <= 1; λ > 0 (:mod:`contfab.params`).

Every point runs one problem with a closed form: a smooth-platen biaxial test on a block
W x H (tier 0, φ = 30°, ψ = 0, P2 triangles). Rollers on the left (ux = 0) and bottom
(uy = 0), a confining pressure p on the right, the top pushed down by δ; initial stress
-p I. The stress stays homogeneous, so at collapse the vertical stress is the passive
limit σ1 = Kp p with Kp = (1 + sin φ)/(1 - sin φ), exact at any mesh, once δ is past the
collapse displacement δ_c ≈ (Kp - 1) p H / E_reg (for p = 0, where δ_c = 0, the push is
sized by p_ref: a cohesionless body without confinement has no strength, the problem no
unique solution, and a clear error is the expected outcome). The accuracy is the relative error of
the top reaction against Kp p W (for p = 0: the reaction against p_ref W, closed form 0),
within 1e-6. Beyond that, up to the regularization's stated error 1/λ (or the Newton
stall tolerance of :class:`contfab.fem.solver.NewtonOptions` when steps were accepted at
it), the point is ACCURACY_LOST: measured with load steps far past the collapse
displacement, which land on a slightly non-homogeneous equilibrium (σyy may vary
along x at σxx = -p, σxy = 0) with some points unloaded inside the cone (measured at
dt0 = 1, 2x2 cells: 3 of 48 points elastic, σyy in [-3.0018, -2.9977] p, mean 6e-5 low).
"""
from __future__ import annotations

import math

import numpy as np

from contfab.fem import loads
from contfab.fem import mesh as meshes
from contfab.fem.assembly import Discretization
from contfab.fem.material import TierMaterial
from contfab.fem.solver import Solver, Stage
from contfab.params import default_params
from contfab.stability.core import Measured, Point

PHI = 30.0
KP = (1 + math.sin(math.radians(PHI))) / (1 - math.sin(math.radians(PHI)))
TOL = 1e-6


def biaxial(nx: int = 2, ny: int = 2, width: float = 1.0, height: float = 1.0,
            lam: float = 1e3, p: float = 1.0, push: float = 10.0, dt0: float = 0.05,
            dt_min: float = 1e-4) -> Measured:
    """The block of the module doc; ``push`` is δ in units of the collapse displacement."""
    mesh = meshes.tensor(np.linspace(0, width, nx + 1), np.linspace(0, height, ny + 1))
    disc = Discretization(mesh, "P2")
    prm = default_params().with_tier(0).replace("tier0", phi_deg=PHI, psi_deg=0.0)
    prm = prm.replace("regularization", lam=lam, nu=0.0)
    material = TierMaterial(prm)
    n = disc.npoints
    stress0 = np.column_stack((-p * np.ones(n), -p * np.ones(n), np.zeros(n)))
    solver = Solver(disc, material, stress0, material.initial_state(n))
    top = loads.boundary_dofs(disc, "top", "y")
    fixed = np.unique(np.concatenate([top, loads.boundary_dofs(disc, "left", "x"),
                                      loads.boundary_dofs(disc, "bottom", "y")]))
    e_reg = lam * prm.p_ref
    delta_c = (KP - 1.0) * (p if p > 0 else prm.p_ref) * height / e_reg
    delta = push * delta_c
    f = loads.surface_load(disc, "right", pressure=p)
    stage = Stage("push", fixed, np.where(np.isin(fixed, top), -delta, 0.0), f, dt0=dt0,
                  dt_min=min(dt_min, dt0), dt_max=max(dt0, 0.1) if dt0 < 1 else 1.0)
    steps = cuts = stalled = 0
    for rec in solver.run_stage(stage):
        steps += 1
        cuts += rec.cuts
        stalled += rec.stalled
    reaction = -solver.reactions(top) / width
    c = solver.committed
    if not (np.all(np.isfinite(c.u)) and np.all(np.isfinite(c.stress))):
        return Measured(math.nan, TOL, "", "non-finite field")
    exact = KP * p
    err = abs(reaction - exact) / (exact if p > 0 else prm.p_ref)
    note = (f"top stress {reaction:.9g} vs Kp p = {exact:.9g}; delta = {push:g} delta_c; "
            f"{steps} steps, {cuts} cuts, {stalled} accepted at the stall tolerance; elements {len(mesh.t.T)}, aspect "
            f"{max(width / nx, height / ny) / min(width / nx, height / ny):.3g}")
    # degraded bound: the regularization's stated error ~1/λ (large steps reach a slightly
    # different, non-homogeneous equilibrium), or the stall tolerance of accepted steps
    lost = max(1.0 / lam, solver.options.tol_stall if stalled else 0.0)
    return Measured(err, TOL, "closed form: passive limit Kp p (homogeneous)", note,
                    lost_tolerance=lost)


def points() -> list[Point]:
    pts: list[Point] = []

    def add(axis, value, fn, budget=300.0, full=False):
        pts.append(Point("fem", axis, str(value), fn, budget, full))

    for ratio in (1, 10, 50):                          # element aspect: 50 columns, 1 row ...
        add("element aspect ratio", ratio,
            lambda ratio=ratio: biaxial(nx=ratio, ny=1, width=1.0, height=1.0),
            full=ratio == 10)
    add("element aspect ratio", "1000", lambda: biaxial(nx=1000, ny=1, width=1.0, height=1.0),
        full=True)
    for p in (1e-3, 1e-9, 0.0):                       # confinement towards the apex
        add("confinement p (free surface)", f"{p:g}", lambda p=p: biaxial(p=p), full=p == 1e-3)
    for n in (1, 16, 48):
        add("mesh (n x n)", n, lambda n=n: biaxial(nx=n, ny=n), full=n == 48, budget=900.0)
    for dt0, push in ((1e-4, 10.0), (1.0, 10.0), (1.0, 1000.0)):
        add("load step dt0 (push/collapse)", f"{dt0:g} ({push:g})",
            lambda dt0=dt0, push=push: biaxial(dt0=dt0, push=push, dt_min=1e-6),
            full=dt0 < 1e-3)
    add("load step dt0 (push/collapse)", "2 (10)", lambda: biaxial(dt0=2.0))
    for lam in (1e1, 1e3, 1e5, 1e8):
        add("lambda", f"{lam:g}", lambda lam=lam: biaxial(lam=lam), full=lam in (1e3, 1e5))
    add("lambda", "0", lambda: biaxial(lam=0.0))
    return pts

"""External loads and prescribed displacements on named boundaries.

Sign convention: forces and tractions are vectors in the global (x, y) frame;
a ``pressure`` p acts against the outward normal n (traction t = -p n, so a
surcharge on a top surface is p > 0). Body force b is per unit area (self-weight
of unit weight γ: b = (0, -γ)). Work-equivalent nodal vectors:

    f_body = ∫_Ω Nᵀ b dA,     f_surface = ∫_Γ Nᵀ (t - p n) ds.

Components are named ``"x"`` and ``"y"``.
"""
from __future__ import annotations

import numpy as np
import skfem
from skfem import LinearForm

from contfab.fem.assembly import Discretization
from contfab.fem.mesh import boundary

COMPONENTS = {"x": "u^1", "y": "u^2"}


def _component(component: str) -> str:
    if component not in COMPONENTS:
        raise ValueError(f"component {component!r}: expected one of {sorted(COMPONENTS)}")
    return COMPONENTS[component]


def boundary_dofs(disc: Discretization, name: str, component: str) -> np.ndarray:
    """The DOFs of one displacement component on a named boundary (sorted int64)."""
    dofs = disc.basis.get_dofs(boundary(disc.mesh, name)).all(_component(component))
    return np.unique(dofs).astype(np.int64)


def body_force(disc: Discretization, bx: float = 0.0, by: float = 0.0) -> np.ndarray:
    """f = ∫ Nᵀ (bx, by) dA (a uniform body force per unit area)."""

    @LinearForm
    def form(v, w):
        return bx * v[0] + by * v[1]

    return skfem.asm(form, disc.basis)


def surface_load(disc: Discretization, name: str, tx: float = 0.0, ty: float = 0.0,
                 pressure: float = 0.0) -> np.ndarray:
    """f = ∫_Γ Nᵀ ((tx, ty) - p n) ds on the named boundary (uniform traction and pressure)."""
    fb = skfem.FacetBasis(disc.mesh, disc.basis.elem, facets=boundary(disc.mesh, name),
                          intorder=2 * disc.basis.elem.maxdeg)

    @LinearForm
    def form(v, w):
        return (tx - pressure * w.n[0]) * v[0] + (ty - pressure * w.n[1]) * v[1]

    return skfem.asm(form, fb)

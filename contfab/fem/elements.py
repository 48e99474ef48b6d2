"""Element families for the displacement formulation, each with its quadrature.

The quadrature points are the material points: the model's stress and state live
there, so the rule is part of the element's definition (and of its cost and its
locking behaviour under isochoric plastic flow: the element study in
``docs/fem_validation.md`` and ``tests/test_fem_locking.py``).

    name  element                      mesh   points  (scikit-fem)
    P1    linear triangle              tri    1       ElementTriP1, centroid rule
    P2    quadratic triangle (6 nodes) tri    3       ElementTriP2, intorder 2
    P3    cubic triangle (10 nodes)    tri    6       ElementTriP3, intorder 4
    P4    quartic triangle (15 nodes)  tri    12      ElementTriP4, intorder 6
    Q8R   serendipity quad (8 nodes)   quad   4       ElementQuadS2, 2x2 Gauss (reduced)
    Q9    Lagrange quad (9 nodes)      quad   9       ElementQuad2, 3x3 Gauss

Each rule integrates BᵀDB exactly for a constant D on affine cells (degree 2(p-1)),
except Q8R, the reduced rule of the classic limit-load element.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import skfem

from contfab.fem.mesh import MeshError


@dataclass(frozen=True)
class ElementSpec:
    """An element family: scikit-fem element class, mesh kind and quadrature order."""

    element: type
    mesh_kind: str          # "tri" or "quad"
    intorder: int | None    # None: the one-point centroid rule
    description: str


ELEMENTS = {
    "P1": ElementSpec(skfem.ElementTriP1, "tri", None, "linear triangle, 1 point"),
    "P2": ElementSpec(skfem.ElementTriP2, "tri", 2, "quadratic triangle, 3 points"),
    "P3": ElementSpec(skfem.ElementTriP3, "tri", 4, "cubic triangle, 6 points"),
    "P4": ElementSpec(skfem.ElementTriP4, "tri", 6, "quartic triangle, 12 points"),
    "Q8R": ElementSpec(skfem.ElementQuadS2, "quad", 3, "8-node quad, 2x2 points (reduced)"),
    "Q9": ElementSpec(skfem.ElementQuad2, "quad", 4, "9-node quad, 3x3 points"),
}


def mesh_kind(mesh) -> str:
    """"tri" or "quad" for a scikit-fem mesh."""
    if isinstance(mesh, skfem.MeshTri1):
        return "tri"
    if isinstance(mesh, skfem.MeshQuad1):
        return "quad"
    raise MeshError(f"unsupported mesh type {type(mesh).__name__}: expected triangles or quads")


def vector_basis(mesh, name: str) -> skfem.CellBasis:
    """The vector-valued (ux, uy) basis of element ``name`` on ``mesh``, DOFs interleaved."""
    if name not in ELEMENTS:
        raise ValueError(f"unknown element {name!r}; choose one of {sorted(ELEMENTS)}")
    spec = ELEMENTS[name]
    kind = mesh_kind(mesh)
    if kind != spec.mesh_kind:
        raise ValueError(f"element {name!r} needs a {spec.mesh_kind} mesh, got a {kind} mesh")
    element = skfem.ElementVector(spec.element())
    if spec.intorder is None:
        centroid = (np.array([[1.0 / 3.0], [1.0 / 3.0]]), np.array([0.5]))
        return skfem.Basis(mesh, element, quadrature=centroid)
    return skfem.Basis(mesh, element, intorder=spec.intorder)

"""Strain, internal force and tangent from per-quadrature-point arrays.

Small-strain kinematics in Voigt form with engineering shear (docs/theory.md §1,
:mod:`contfab.tensors`): at a quadrature point of element e,

    (exx, eyy, gxy)  = B u_e,     gxy = ∂ux/∂y + ∂uy/∂x
    dω               = W u_e,     ω = (∂uy/∂x - ∂ux/∂y)/2  (counter-clockwise)

and with the quadrature weight w (reference weight × |det J|)

    f_int = Σ_e Σ_q w Bᵀ σ                   (internal force, tension-positive σ)
    K     = Σ_e Σ_q w Bᵀ (D B + g W),        D = ∂σ/∂e, g = ∂σ/∂ω

(non-symmetric when the model's D is, and whenever g ≠ 0: the update rotates the
stress by the spin increment, so σ depends on ω too).

The model is never called from here: the solver runs the constitutive update once
per Newton iteration over all points and passes stress (n, 3) and tangent
(n, 3, 3) in, with point k = e·nq + q (the update contract's C-order layout).
The sparsity pattern is computed once; each tangent assembly writes the element
matrices straight into the CSR data array through a precomputed position map.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numba import njit

from contfab.fem.elements import vector_basis


class Discretization:
    """A mesh with an element family: the B/W operators, weights and CSR pattern.

    Attributes: ``basis`` (scikit-fem), ``ndofs``, ``ne`` elements, ``nq`` points per
    element, ``npoints = ne·nq``, ``dofs`` (ne, nloc) int64, ``bw`` (ne, nq, 4, nloc)
    with rows exx, eyy, gxy, ω, ``weights`` (ne, nq), ``points`` (npoints, 2)
    quadrature point coordinates.
    """

    def __init__(self, mesh, element: str = "P2"):
        self.mesh = mesh
        self.element = element
        self.basis = vector_basis(mesh, element)
        b = self.basis
        self.ndofs = int(b.N)
        self.dofs = np.ascontiguousarray(b.element_dofs.T, dtype=np.int64)
        self.ne, self.nloc = self.dofs.shape
        self.nq = b.dx.shape[1]
        self.npoints = self.ne * self.nq
        grads = np.stack([phi[0].grad for phi in b.basis])       # (nloc, 2, 2, ne, nq)
        bw = np.empty((self.ne, self.nq, 4, self.nloc))
        g = np.moveaxis(grads, 0, -1)                               # (2, 2, ne, nq, nloc)
        bw[:, :, 0] = g[0, 0]
        bw[:, :, 1] = g[1, 1]
        bw[:, :, 2] = g[0, 1] + g[1, 0]
        bw[:, :, 3] = 0.5 * (g[1, 0] - g[0, 1])
        self.bw = bw
        self.weights = np.ascontiguousarray(b.dx, dtype=float)
        xq = np.asarray(b.global_coordinates())                    # (2, ne, nq)
        self.points = np.ascontiguousarray(xq.reshape(2, -1).T)
        self.indptr, self.indices, self.positions = _csr_pattern(self.dofs, self.ndofs)

    def strain(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(strain (npoints, 3), spin (npoints,)) of the displacement field ``u``."""
        strain = np.empty((self.npoints, 3))
        spin = np.empty(self.npoints)
        _strain_kernel(self.bw, self.dofs, np.ascontiguousarray(u, dtype=float), strain, spin)
        return strain, spin

    def internal_force(self, stress: np.ndarray) -> np.ndarray:
        """f_int = Σ w Bᵀσ for a stress array (npoints, 3)."""
        f = np.zeros(self.ndofs)
        _force_kernel(self.bw, self.dofs, self.weights, _points(stress, self.npoints, (3,)), f)
        return f

    def tangent(self, tangent: np.ndarray, spin_tangent: np.ndarray | None = None) -> sp.csr_matrix:
        """K = Σ w Bᵀ (D B + g W) as a CSR matrix.

        ``tangent`` D = ∂σ/∂e (npoints, 3, 3); ``spin_tangent`` g = ∂σ/∂ω (npoints, 3),
        the stress's dependence on the spin increment (zero if omitted).
        """
        data = np.zeros(len(self.indices))
        g = np.zeros((self.npoints, 3)) if spin_tangent is None else spin_tangent
        _tangent_kernel(self.bw, self.weights, _points(tangent, self.npoints, (3, 3)),
                        _points(g, self.npoints, (3,)), self.positions, data)
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.ndofs, self.ndofs))

    def element_mean(self, values: np.ndarray) -> np.ndarray:
        """Area-weighted mean over each element's points of (npoints, ...) data."""
        v = values.reshape(self.ne, self.nq, *values.shape[1:])
        w = self.weights.reshape(self.ne, self.nq, *([1] * (values.ndim - 1)))
        return (v * w).sum(axis=1) / w.sum(axis=1)

    def area(self) -> float:
        """Total area of the mesh (sum of the quadrature weights)."""
        return float(self.weights.sum())


def _points(a: np.ndarray, n: int, shape: tuple) -> np.ndarray:
    a = np.ascontiguousarray(a, dtype=float)
    if a.shape != (n, *shape):
        raise ValueError(f"expected a per-point array of shape {(n, *shape)}, got {a.shape}")
    return a


def _csr_pattern(dofs: np.ndarray, ndofs: int):
    """CSR (indptr, indices) of the element couplings and the (ne, nloc, nloc) data positions."""
    ne, nloc = dofs.shape
    rows = np.repeat(dofs, nloc, axis=1).ravel()
    cols = np.tile(dofs, (1, nloc)).ravel()
    keys = rows * ndofs + cols
    unique, inverse = np.unique(keys, return_inverse=True)
    indices = (unique % ndofs).astype(np.int32)
    counts = np.bincount(unique // ndofs, minlength=ndofs)
    indptr = np.concatenate(([0], np.cumsum(counts))).astype(np.int32)
    return indptr, indices, inverse.reshape(ne, nloc, nloc).astype(np.int64)


@njit(cache=True)
def _strain_kernel(bw, dofs, u, strain, spin):
    ne, nq, _, nloc = bw.shape
    for e in range(ne):
        for q in range(nq):
            k = e * nq + q
            s0 = 0.0
            s1 = 0.0
            s2 = 0.0
            s3 = 0.0
            for i in range(nloc):
                ui = u[dofs[e, i]]
                s0 += bw[e, q, 0, i] * ui
                s1 += bw[e, q, 1, i] * ui
                s2 += bw[e, q, 2, i] * ui
                s3 += bw[e, q, 3, i] * ui
            strain[k, 0] = s0
            strain[k, 1] = s1
            strain[k, 2] = s2
            spin[k] = s3


@njit(cache=True)
def _force_kernel(bw, dofs, weights, stress, f):
    ne, nq, _, nloc = bw.shape
    for e in range(ne):
        for q in range(nq):
            k = e * nq + q
            w = weights[e, q]
            s0 = w * stress[k, 0]
            s1 = w * stress[k, 1]
            s2 = w * stress[k, 2]
            for i in range(nloc):
                f[dofs[e, i]] += bw[e, q, 0, i] * s0 + bw[e, q, 1, i] * s1 + bw[e, q, 2, i] * s2


@njit(cache=True)
def _tangent_kernel(bw, weights, tangent, spin_tangent, positions, data):
    ne, nq, _, nloc = bw.shape
    db = np.empty((3, nloc))
    for e in range(ne):
        for q in range(nq):
            k = e * nq + q
            w = weights[e, q]
            for a in range(3):
                for j in range(nloc):
                    db[a, j] = w * (tangent[k, a, 0] * bw[e, q, 0, j]
                                    + tangent[k, a, 1] * bw[e, q, 1, j]
                                    + tangent[k, a, 2] * bw[e, q, 2, j]
                                    + spin_tangent[k, a] * bw[e, q, 3, j])
            for i in range(nloc):
                b0 = bw[e, q, 0, i]
                b1 = bw[e, q, 1, i]
                b2 = bw[e, q, 2, i]
                if b0 == 0.0 and b1 == 0.0 and b2 == 0.0:
                    continue
                for j in range(nloc):
                    data[positions[e, i, j]] += b0 * db[0, j] + b1 * db[1, j] + b2 * db[2, j]

"""Assembly and the Newton solver on linear elasticity: exactness, rates, reactions."""
import numpy as np
import pytest
import skfem
import skfem.models.elasticity
from skfem import LinearForm

from contfab.fem import loads as L
from contfab.fem import mesh as M
from contfab.fem.assembly import Discretization
from contfab.fem.solver import Solver, Stage
from contfab.tensors import isotropic_stiffness
from fem_helpers import Elastic

BULK, SHEAR = 2.0, 1.0


def _solve_elastic(disc, fixed, values, f):
    n = disc.npoints
    solver = Solver(disc, Elastic(BULK, SHEAR), np.zeros((n, 3)), np.zeros((n, 1)))
    records = list(solver.run_stage(Stage("load", fixed, values, np.zeros(disc.ndofs), f_ramp=f,
                                          dt0=1.0, dt_max=1.0)))
    return solver, records


def _all_sides(disc, component):
    return np.unique(np.concatenate([L.boundary_dofs(disc, s, component)
                                     for s in ("left", "right", "bottom", "top")]))


def test_tangent_matches_scikit_fem_linear_elasticity():
    m = M.tensor(M.graded(0, 1, 4, 0.3), np.linspace(0, 1, 3))
    mq = M.tensor(M.graded(0, 1, 4, 0.3), np.linspace(0, 1, 3), kind="quad")
    d_iso = isotropic_stiffness(BULK, SHEAR)
    for mesh, element in ((m, "P1"), (m, "P2"), (m, "P3"), (m, "P4"), (mq, "Q8R"), (mq, "Q9")):
        disc = Discretization(mesh, element)
        k = disc.tangent(np.broadcast_to(d_iso, (disc.npoints, 3, 3)))
        # 2D isotropic: σ = (K - G) tr ε I + 2 G ε, i.e. Lamé λ = K - G, μ = G
        ref = skfem.asm(skfem.models.elasticity.linear_elasticity(BULK - SHEAR, SHEAR), disc.basis)
        assert abs(k - ref).max() < 1e-12 * abs(ref).max()
        u = np.random.default_rng(0).normal(size=disc.ndofs)
        strain, _ = disc.strain(u)
        assert np.allclose(disc.internal_force(strain @ d_iso.T), ref @ u, atol=1e-12)


def test_patch_test_linear_field_is_exact_on_distorted_meshes():
    rng = np.random.default_rng(1)
    base = M.tensor(np.linspace(0, 1, 4), np.linspace(0, 1, 4), kind="quad")
    p = base.p.T.copy()
    interior = np.all((p > 1e-9) & (p < 1 - 1e-9), axis=1)
    p[interior] += rng.uniform(-0.08, 0.08, size=(interior.sum(), 2))
    grad = np.array([[1e-3, -4e-4], [7e-4, -2e-3]])           # ∂u_i/∂x_j
    exact = np.array([grad[0, 0], grad[1, 1], grad[0, 1] + grad[1, 0]])
    for kind, elements in (("quad", ("Q8R", "Q9")), ("tri", ("P1", "P2", "P3", "P4"))):
        cells = base.t.T if kind == "quad" else np.vstack((base.t.T[:, [0, 1, 2]],
                                                           base.t.T[:, [0, 2, 3]]))
        mesh = M.name_boundaries(M.from_arrays(p, cells), {
            s: (lambda x, a=a, v=v: np.abs(x[a] - v) < 1e-9)
            for s, (a, v) in {"left": (0, 0), "right": (0, 1), "bottom": (1, 0), "top": (1, 1)}.items()})
        for element in elements:
            disc = Discretization(mesh, element)
            dofs = np.concatenate([_all_sides(disc, "x"), _all_sides(disc, "y")])
            x = disc.basis.doflocs[:, dofs]
            comp = np.where(np.isin(dofs, _all_sides(disc, "x")), 0, 1)
            values = np.einsum("nj,jn->n", grad[comp], x)
            solver, _ = _solve_elastic(disc, dofs, values, np.zeros(disc.ndofs))
            strain, _ = disc.strain(solver.committed.u)
            assert np.allclose(strain, exact, rtol=0, atol=1e-12), element


def _manufactured_l2_error(element, n):
    """L2 error of ux = sin πx sin πy, uy = 0 on the unit square (zero on the boundary).

    Navier: div σ = G Δu + K ∇(div u), so b = -div σ =
    ((2G + K) π² sin πx sin πy, -K π² cos πx cos πy).
    """
    kind = "quad" if element.startswith("Q") else "tri"
    mesh = M.tensor(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1), kind=kind)
    disc = Discretization(mesh, element)

    @LinearForm
    def body(v, w):
        s = np.sin(np.pi * w.x[0]) * np.sin(np.pi * w.x[1])
        c = np.cos(np.pi * w.x[0]) * np.cos(np.pi * w.x[1])
        return np.pi**2 * ((2 * SHEAR + BULK) * s * v[0] - BULK * c * v[1])

    fine = skfem.Basis(mesh, disc.basis.elem, intorder=10)
    dofs = np.concatenate([_all_sides(disc, "x"), _all_sides(disc, "y")])
    solver, _ = _solve_elastic(disc, dofs, np.zeros(len(dofs)), skfem.asm(body, fine))
    uh = np.asarray(fine.interpolate(solver.committed.u))
    x = np.asarray(fine.global_coordinates())
    err = (uh[0] - np.sin(np.pi * x[0]) * np.sin(np.pi * x[1])) ** 2 + uh[1] ** 2
    return np.sqrt(np.sum(err * fine.dx))


@pytest.mark.parametrize("element, order, n", [("P1", 1, 4), ("P2", 2, 2), ("P3", 3, 2),
                                               ("P4", 4, 2), ("Q8R", 2, 3), ("Q9", 2, 3)])
def test_manufactured_solution_converges_at_the_element_rate(element, order, n):
    coarse = _manufactured_l2_error(element, n)
    fine = _manufactured_l2_error(element, 2 * n)
    rate = np.log2(coarse / fine)
    assert rate == pytest.approx(order + 1, abs=0.3), (element, coarse, fine)


def test_reactions_balance_applied_loads():
    """A block on rollers under a top pressure and self-weight: Σ reactions = -Σ loads."""
    mesh = M.tensor(np.linspace(0, 2, 5), np.linspace(0, 1, 4))
    disc = Discretization(mesh, "P2")
    bottom_y = L.boundary_dofs(disc, "bottom", "y")
    left_x = L.boundary_dofs(disc, "left", "x")
    f = L.surface_load(disc, "top", pressure=3.0) + L.body_force(disc, by=-0.5)
    fixed = np.concatenate([bottom_y, left_x])
    solver, records = _solve_elastic(disc, fixed, np.zeros(len(fixed)), f)
    assert solver.reactions(bottom_y) == pytest.approx(3.0 * 2 + 0.5 * 2, rel=1e-10)
    assert solver.reactions(left_x) == pytest.approx(0.0, abs=1e-10)
    assert records[0].iterations == 1 and records[0].residuals[0] < 1e-12

"""Explicit dynamic relaxation (contfab.fem.explicit) against closed forms, the Newton solver
and Radenković's bounds."""
import math

import numpy as np
import pytest

from contfab.fem import loads
from contfab.fem import mesh as meshes
from contfab.fem.assembly import Discretization
from contfab.fem.explicit import ExplicitOptions, ExplicitSolver
from contfab.fem.material import TierMaterial
from contfab.fem.solver import Stage
from contfab.params import default_params

PHI = 30.0
KP = (1 + math.sin(math.radians(PHI))) / (1 - math.sin(math.radians(PHI)))


@pytest.mark.parametrize("psi", [PHI, 0.0])
def test_a_smooth_platen_block_collapses_at_the_passive_limit(psi):
    """A block with smooth platens under a lateral dead pressure p, its top pushed down far
    past collapse: the stress stays homogeneous and the top carries σ1 = Kp p at collapse,
    Kp = (1 + sin φ)/(1 - sin φ), whatever ψ (the yield surface sets it). The explicit
    solution has no equilibrium iteration: it reaches the closed form to 0.5 % (+0.13 % and
    -0.03 % measured) with an out-of-balance force below 1e-3 at the end."""
    mesh = meshes.tensor(np.linspace(0, 1, 3), np.linspace(0, 1, 3))
    disc = Discretization(mesh, "P2")
    prm = default_params().with_tier(0).replace("tier0", phi_deg=PHI, psi_deg=psi)
    prm = prm.replace("regularization", lam=1e3, nu=0.0)
    material = TierMaterial(prm)
    n = disc.npoints
    solver = ExplicitSolver(disc, material, np.tile([-1.0, -1.0, 0.0], (n, 1)),
                            material.initial_state(n), ExplicitOptions(cycles=40_000))
    top = loads.boundary_dofs(disc, "top", "y")
    fixed = np.unique(np.concatenate([top, loads.boundary_dofs(disc, "left", "x"),
                                      loads.boundary_dofs(disc, "bottom", "y")]))
    delta = 10 * (KP - 1.0) / 1e3                         # ten collapse displacements
    stage = Stage("push", fixed, np.where(np.isin(fixed, top), -delta, 0.0),
                  loads.surface_load(disc, "right", pressure=1.0))
    records = list(solver.run_stage(stage))
    assert len(records) == 100 and records[-1].t == 1.0
    assert -solver.reactions(top) == pytest.approx(KP, rel=5e-3)
    assert records[-1].residuals[0] < 1e-3


@pytest.mark.parametrize("bad, text", [({"cycles": 0}, "cycles = 0 is outside"),
                                       ({"damping": 1.0}, r"damping = 1.0 is outside the "
                                                          r"accepted range \[0, 1\)"),
                                       ({"records": 2.5}, "records = 2.5 is outside")])
def test_bad_explicit_options_are_refused(bad, text):
    with pytest.raises(ValueError, match=text):
        ExplicitOptions(**bad)


@pytest.mark.slow
def test_the_footing_by_dynamic_relaxation_matches_newton_and_lies_between_radenkovic_s_bounds():
    """N_γ at φ = 30° on P2 level 1 to 0.3 B in 1e5 cycles: with associated flow the same
    value as the Newton solver on the mesh (to 0.5 %); with ψ = 0, where Newton fails, a
    value below the associated one at φ (Radenković's first theorem: non-associated flow
    carries no more) and above the associated one at φ* = atan(sin φ) (his second: no
    less), both by Newton on the same mesh. 1.5 min."""
    from contfab.scenes import strip_footing as footing

    def n_gamma(phi, psi, explicit=None):
        return footing.solve(phi, psi, "Ngamma", "P2", 1, default_params(), None, False,
                             settlement=0.3, explicit=explicit)["computed"]

    phi_star = math.degrees(math.atan(math.sin(math.radians(PHI))))
    upper, lower = n_gamma(PHI, PHI), n_gamma(phi_star, phi_star)
    assert n_gamma(PHI, PHI, explicit=100_000) == pytest.approx(upper, rel=5e-3)
    assert lower < n_gamma(PHI, 0.0, explicit=100_000) < upper

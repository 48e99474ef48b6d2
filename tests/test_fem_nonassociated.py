"""The non-associated footing (ψ = 0, coarse mesh) converges through collapse to 0.3 B."""
import math

import pytest

from contfab.scenes.case import run_case


def test_nonassociated_ngamma_footing_converges_to_a_plateau_at_0p3_b():
    """N_γ at φ = 30°, ψ = 0 on the P2 level-1 mesh with the Duvaut–Lions material
    (τ = 1e-4 of the settlement over B): every step converges to a settlement of 0.3 B
    (the rate-independent Newton fails near 0.06 B, docs/fem_validation.md), and at a
    constant settlement rate a perfectly plastic mechanism carries a constant load: the
    last fifth of the push is a plateau (< 1 % drift)."""
    result = run_case("strip_footing", ["--factor", "Ngamma", "--phi", "30", "--psi", "0",
                                        "--element", "P2", "--level", "1", "--settlement", "0.3",
                                        "--relaxation-time", "1e-4", "--quiet", "--out", "none"])
    head = result.figures[0]
    note = result.notes["N_gamma(phi=30, psi=0)"]
    assert math.isnan(head.reference) and "no published reference" in head.source
    assert note["settlement_over_B"] == pytest.approx(0.3, rel=1e-9)
    assert abs(note["plateau_drift"]) < 0.01
    assert note["davis_phi"] == math.degrees(math.atan(0.5))      # tan φ* = sin 30° cos 0
    assert head.computed == note["computed"] > 0


@pytest.mark.parametrize("psi", [30.0, 20.0, 10.0, 0.0])
def test_the_symmetric_tangent_is_indefinite_at_a_yielding_point_exactly_when_psi_is_below_phi(psi):
    """Hill's sufficient condition for a unique increment fails where the symmetric part of
    the tangent is indefinite. For a point on a face of the cone, D_ep = D - D b aᵀ D / aᵀ D b
    (a, b the yield and flow gradients); the eigenvalues of its symmetric part relative to D
    in the plane of a and b are ½ (1 ∓ 1/cos θ), cos θ = aᵀ D b / √(aᵀ D a · bᵀ D b)
    (Raniecki & Bruhns 1981, J. Mech. Phys. Solids 29, 153–172): 0 and 1 for associated
    flow, one negative for ψ < φ. Checked on tier 0's tangent in the normal block of a point
    in biaxial compression (principal axes x, y; a = (1 + sin φ, sin φ - 1) with σyy the
    major compression, b the same with ψ), against the 2D elastic law D = [[K+G, K-G],
    [K-G, K+G]]."""
    import numpy as np
    from scipy.linalg import eigh

    from contfab.fem.material import TierMaterial
    from contfab.params import default_params

    params = default_params().replace("tier0", phi_deg=30.0, psi_deg=psi)
    material = TierMaterial(params, tier=0)
    stress = np.array([[-1.0, -1.0, 0.0]])
    state = np.zeros((1, len(material.state_names)))
    for _ in range(100):                      # compress along y into plastic flow
        res = material.update(stress, state, np.array([[1e-5, -5e-5, 0.0]]), np.zeros(1))
        stress, state = res.stress.copy(), res.state.copy()
    assert int(res.status[0]) == 1 and abs(stress[0, 2]) < 1e-12 and stress[0, 1] < stress[0, 0]
    bulk, shear = params.regularization.moduli()
    d = np.array([[bulk + shear, bulk - shear], [bulk - shear, bulk + shear]])
    a = np.array([1.0 + math.sin(math.radians(30.0)), math.sin(math.radians(30.0)) - 1.0])
    b = np.array([1.0 + math.sin(math.radians(psi)), math.sin(math.radians(psi)) - 1.0])
    cos = a @ d @ b / math.sqrt((a @ d @ a) * (b @ d @ b))
    tangent = np.asarray(res.tangent)[0][:2, :2]
    relative = eigh(0.5 * (tangent + tangent.T), d, eigvals_only=True)
    np.testing.assert_allclose(relative, [0.5 * (1 - 1 / cos), 0.5 * (1 + 1 / cos)], atol=1e-9)
    assert (relative[0] < -1e-3) == (psi < 30.0)


class _Enough(Exception):
    """Stops a footing run once the symmetric tangent has been examined."""


@pytest.mark.parametrize("psi", [30.0, 0.0])
def test_the_footing_s_symmetric_tangent_is_indefinite_from_the_first_yield_when_psi_is_zero(
        psi, monkeypatch):
    """The point-wise loss above, in the boundary-value problem: on the N_γ footing (φ = 30°,
    P2 level 1) the symmetric part of the committed free-DOF matrix K_ff has negative
    eigenvalues after the first steps of the push (settlement 0.0014 B) with ψ = 0, and
    none with ψ = φ: the rate-independent non-associated increment is not guaranteed
    unique from the first yield on (docs/fem_validation.md, section 7)."""
    import numpy as np

    from contfab.fem import solver as fem_solver
    from contfab.params import default_params
    from contfab.scenes.case import load_case

    found = {}
    systems = []
    make_system = fem_solver.ConstrainedSystem.__init__
    run_stage = fem_solver.Solver.run_stage

    def remember(self, *args, **kwargs):
        make_system(self, *args, **kwargs)
        systems.append(self)

    def examine(self, stage, start=None):
        for record in run_stage(self, stage, start):
            yield record
            if stage.name == "push" and record.t >= 0.0045:
                c, system = self.committed, systems[-1]
                k = self.disc.tangent(c.tangent, c.spin_tangent).tocsr()
                kff = k[system.free][:, system.free].toarray()
                found["eigenvalues"] = np.linalg.eigvalsh(0.5 * (kff + kff.T))
                raise _Enough

    monkeypatch.setattr(fem_solver.ConstrainedSystem, "__init__", remember)
    monkeypatch.setattr(fem_solver.Solver, "run_stage", examine)
    with pytest.raises(_Enough):
        load_case("strip_footing").solve(30.0, psi, "Ngamma", "P2", 1, default_params(), None,
                                         progress=False, settlement=0.3)
    ev = found["eigenvalues"]
    negative = int(np.count_nonzero(ev < -1e-9 * ev[-1]))
    assert (negative > 0) == (psi < 30.0), (negative, ev[:3])

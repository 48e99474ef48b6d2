"""Adaptive FE×DEM: a model where its measured bound meets the tolerance, a DEM cell where
none does (contfab.fexdem.adaptive)."""
from types import SimpleNamespace

import numpy as np
import pytest

from contfab.fem.solver import NewtonOptions
from contfab.fexdem.adaptive import AdaptiveMaterial, AdaptiveSolver, model_choice
from contfab.fexdem.backends import SerialCells
from contfab.fexdem.cell import CellOptions, increment_gradient, increment_stage
from contfab.fexdem.material import DemMaterial, FexdemSolver
from contfab.fexdem.scenes import build
from contfab.params import default_params
from dem import checkpoint
from dem.contact_law import ContactLaw
from dem.integrator import dynamics
from dem.paths import Path
from dem.rve import PathRunner

from conftest import prepared

NO_RELAX = CellOptions(force_tol=np.inf, kinetic_tol=np.inf)
NEWTON = NewtonOptions(tol=2e-3, tol_stall=5e-3, max_iter=12, line_search=0, spin_step=0,
                       extrapolate=False)
TABLE = {"monotonic": [{"model": "tier 1", "tier": 1, "params_file": "default_params.toml",
                        "error": 0.04, "cost": 80.0},
                       {"model": "tier 2", "tier": 2,
                        "params_file": "default_params.toml", "error": 0.03, "cost": 110.0}],
         "reversal": [{"model": "tier 1", "tier": 1, "params_file": "default_params.toml",
                       "error": 0.13, "cost": 60.0},
                      {"model": "tier 2", "tier": 2,
                       "params_file": "default_params.toml", "error": 0.09, "cost": 90.0}]}


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    """A dense 80-disc cell (μ_prep = 0, κ = 1e3, P0 = 1) tested at μ = 0.5, I = 1e-3."""
    st = prepared(80, 0.0, seed=2)
    dyn = dynamics(ContactLaw(kn=1e3, e=0.5, mu=0.5), st.mass.min(), 1e-3)
    return checkpoint.save(tmp_path_factory.mktemp("adaptive") / "dense80.npz", st, dyn)


def test_model_choice_follows_the_measured_bounds():
    """Cheapest model meeting the tolerance in both classes (no cells); else the monotonic
    class's model with cells for the reversal class; else cells everywhere."""
    choice, switching = model_choice(0.15, TABLE)
    assert (choice.model, switching) == ("tier 1", False)
    choice, switching = model_choice(0.1, TABLE)
    assert (choice.model, switching) == ("tier 2", False)
    choice, switching = model_choice(0.05, TABLE)
    assert (choice.model, switching) == ("tier 1", True)
    choice, switching = model_choice(0.035, TABLE)
    assert (choice.model, switching) == ("tier 2", True)
    assert model_choice(0.02, TABLE) == (None, True)


def _standalone(sample, incs):
    """Stress of the prepared sample driven through ``incs`` [(dstrain, dspin)] as one
    stand-alone DEM path (dem.rve.PathRunner), one stage per increment."""
    state, dyn, _, _ = checkpoint.load(sample)
    stages = tuple(increment_stage(increment_gradient(de, dw), dyn, f"step{j}")
                   for j, (de, dw) in enumerate(incs))
    runner = PathRunner(Path("standalone", stages), dyn, dyn.gdot_ref)
    run = runner.run(state, runner.start(state))
    return np.array([run.rows[-1][q] for q in ("sxx", "syy", "sxy")]), run.rows[-1]["c"]


def test_points_whose_axes_turn_switch_to_the_dem_cell_of_their_path(small):
    """Four points compressed along y, then two of them sheared: those two turn their
    principal axes by more than 15° (measured here from their stresses), no model meets
    the tolerance for that class, and they switch to DEM cells whose stress is a
    stand-alone DEM run along their strain path; the other two keep the model. A further
    trial of a switched point is that DEM path continued."""
    scene = build("shear", nx=1, ny=1)
    mat = AdaptiveMaterial(small, scene.disc, default_params(), 0.05, NO_RELAX, table=TABLE,
                           modulus=1000.0)
    stress, state = mat.initial()
    n = len(stress)
    compress = np.tile([0.0, -2e-3, 0.0], (n, 1))
    shear = np.array([[0, 0, 0], [0, 0, 0], [0, 0, 3e-3], [0, 0, 3e-3]], float)
    incs, alpha, switched = [], [], []
    for step, de in enumerate([compress, shear, shear], start=1):
        res = mat.update(stress, state, de, np.zeros(n))
        accepted = SimpleNamespace(stress=res.stress, state=res.state, status=res.status,
                                   tangent=res.tangent, spin_tangent=np.zeros((n, 3)))
        before = accepted.stress.copy()
        switched.append(mat.commit(accepted, step, stress))
        incs.append(de)
        alpha.append(0.5 * np.degrees(np.arctan2(2 * before[:, 2], before[:, 0] - before[:, 1])))
        stress, state = accepted.stress.copy(), accepted.state.copy()
    turned = np.abs(alpha[1] - alpha[0]) > 15.0
    assert turned.tolist() == [False, False, True, True]
    assert [s.tolist() for s in switched] == [[], [2, 3], []]
    assert mat.is_cell.tolist() == [False, False, True, True]
    for k in (2, 3):
        ref, c = _standalone(small, [(incs[0][k], 0.0), (incs[1][k], 0.0)])
        np.testing.assert_allclose(mat.switches[k - 2]["cell"]["sxx"], ref[0], rtol=0, atol=1e-12)
        ref3, c3 = _standalone(small, [(de[k], 0.0) for de in incs])
        np.testing.assert_allclose(stress[k], ref3, rtol=0, atol=1e-12)
        assert abs(state[k, 1] - c3) < 1e-12
    # the model and the cell disagree at the switch: the model's error on that path
    assert mat.report()["switch_mismatch_max"]["P"] > 0


def test_cells_everywhere_reproduce_fexdem(small):
    """A tolerance no model meets puts a cell at every point: the one-element biaxial scene
    then gives the FE×DEM stresses (cells' own tangent) to round-off."""
    scene = build("biaxial", strain=6e-4, steps=3, rough=False)
    mat = AdaptiveMaterial(small, scene.disc, default_params(), 0.01, NO_RELAX, table=TABLE)
    solver = AdaptiveSolver(scene.disc, mat, NEWTON)
    for _ in solver.run_stage(scene.stage):
        pass
    with SerialCells(small, scene.disc.npoints, NO_RELAX) as cells:
        dem = DemMaterial(cells, scene.disc, default_params(), tangent="dem",
                          modulus=mat.modulus)
        ref = FexdemSolver(scene.disc, dem, NEWTON)
        for _ in ref.run_stage(scene.stage):
            pass
    assert mat.is_cell.all() and mat.model_updates == 0
    np.testing.assert_allclose(solver.committed.stress, ref.committed.stress, rtol=0, atol=1e-10)


def test_adaptive_against_a_finished_reference_run(small, tmp_path):
    """``compare.run(reference=DIR)`` takes a finished FE×DEM run as the reference: with a
    tolerance no model meets, the adaptive run (cells everywhere) is that run's curve, the
    dashpot in parallel with every point included; a reference of another scene or another
    viscosity is refused, naming the difference."""
    from contfab.fexdem import compare

    kw = dict(strain=6e-4, steps=2, nx=1, ny=1)
    eta = 50.0                 # overstress η Δε/Δt ≈ 0.03 p0: 1 % of the stress
    ref = compare.run("biaxial", small, tmp_path / "ref", default_params(), progress=False,
                      viscosity=eta, **kw)
    assert ref["dashpot"]["overstress_max_p0"] > 0.01
    rep = compare.run("biaxial", small, tmp_path / "adaptive", default_params(), progress=False,
                      adaptive=0.01, reference=tmp_path / "ref", viscosity=eta, **kw)
    assert rep["adaptive"]["cell_points"] == rep["cells"]
    assert rep["runs"]["adaptive"]["errors"]["curve"] < 1e-9
    with pytest.raises(ValueError, match="viscosity 50.0, this run with 0.0"):
        compare.run("biaxial", small, tmp_path / "other", default_params(), progress=False,
                    adaptive=0.01, reference=tmp_path / "ref", **kw)
    assert rep["runs"]["tier1"]["errors"] == ref["runs"]["tier1"]["errors"] | {
        "cost_ratio_dem_over_tier": rep["runs"]["tier1"]["errors"]["cost_ratio_dem_over_tier"]}
    with pytest.raises(ValueError, match="another scene: scene"):
        compare.run("biaxial", small, tmp_path / "other", default_params(), progress=False,
                    adaptive=0.01, reference=tmp_path / "ref", viscosity=eta,
                    **dict(kw, strain=1e-3))


def test_a_shadow_cell_that_contradicts_the_bound_sends_every_point_to_a_cell(small):
    """Shadow cells measure the model's R/P error on the scene's own cells: after one step of
    compression the tier-1 R/P differs from a stand-alone DEM run of the same path by more
    than the tolerance (computed here), so every point switches to its cell; the next steps
    follow that DEM path."""
    scene = build("shear", nx=1, ny=1)
    tol = 0.05
    mat = AdaptiveMaterial(small, scene.disc, default_params(), tol, NO_RELAX, table=TABLE,
                           modulus=1000.0, shadows=2)
    stress, state = mat.initial()
    n = len(stress)
    de = np.array([0.0, -5e-4, 0.0])
    ratio = lambda s: np.hypot(0.5 * (s[0] - s[1]), s[2]) / (-0.5 * (s[0] + s[1]))
    for step in (1, 2, 3):
        res = mat.update(stress, state, np.tile(de, (n, 1)), np.zeros(n))
        model = res.stress[0].copy()
        accepted = SimpleNamespace(stress=res.stress, state=res.state, status=res.status,
                                   tangent=res.tangent, spin_tangent=np.zeros((n, 3)))
        switched = mat.commit(accepted, step, stress)
        ref, _ = _standalone(small, [(de, 0.0)] * step)
        if step == 1:
            error = abs(ratio(model) - ratio(ref))
            assert error > tol
            assert switched.tolist() == list(range(n))
            shadows = mat.report()["shadows"]
            assert shadows["model_rejected_at_step"] == 1
            np.testing.assert_allclose(shadows["rms_R_over_P_error"], error, rtol=1e-12)
        else:
            assert len(switched) == 0
            np.testing.assert_allclose(accepted.stress, np.tile(ref, (n, 1)), rtol=0, atol=1e-12)
        stress, state = accepted.stress.copy(), accepted.state.copy()

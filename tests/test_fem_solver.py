"""Newton step control, failure reports and the written outputs (linear material)."""
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest

from contfab.fem import analysis
from contfab.fem import loads as L
from contfab.fem import mesh as M
from contfab.fem.assembly import Discretization
from contfab.fem.solver import ConvergenceError, NewtonOptions, Solver, Stage, stationary_alpha
from fem_helpers import Brittle, Elastic, Rough, Softening


def _compression(material, dt0=0.05, dt_min=1e-3):
    """A 2x1 block on rollers, top pushed down by 1 % (uniaxial strain eyy = -0.01 · t)."""
    mesh = M.tensor(np.linspace(0, 2, 5), np.linspace(0, 1, 3))
    disc = Discretization(mesh, "P2")
    top = L.boundary_dofs(disc, "top", "y")
    fixed = np.concatenate([L.boundary_dofs(disc, "bottom", "y"), L.boundary_dofs(disc, "left", "x"), top])
    inc = np.where(np.isin(fixed, top), -0.01, 0.0)
    stage = Stage("push", fixed, inc, np.zeros(disc.ndofs), dt0=dt0, dt_min=dt_min, dt_max=0.2)
    n = disc.npoints
    return disc, Solver(disc, material, np.zeros((n, 3)), np.zeros((n, 1))), stage, top


def test_steps_grow_after_easy_convergence():
    disc, solver, stage, top = _compression(Elastic())
    records = list(solver.run_stage(stage))
    dts = [r.dt for r in records]
    assert dts[0] == pytest.approx(0.05) and max(dts) == pytest.approx(0.2)
    assert sum(dts) == pytest.approx(1.0) and records[-1].t == pytest.approx(1.0)
    # uniaxial strain: σyy = (K + G - (K - G)²/(K + G)) εyy = 8/3 εyy per unit width
    assert solver.reactions(top) == pytest.approx(-0.01 * 8 / 3 * 2, rel=1e-10)


def test_failed_step_is_cut_and_leaves_no_trace():
    # the top strain is -0.01 t, so points break beyond t = 0.6
    disc, solver, stage, _ = _compression(Brittle(limit=0.006))
    with pytest.raises(ConvergenceError) as info:
        list(solver.run_stage(stage))
    err = info.value
    last = solver.committed
    assert err.last is last and 0.6 - 1e-3 <= last.t <= 0.6     # within dt_min of the break
    assert f"no converged step beyond t = {last.t:.6g}" in str(err)
    assert "constitutive update failed" in str(err) and "minimum dt = 0.001" in str(err)
    strain, _ = disc.strain(last.u)                    # committed stress matches committed u
    assert np.allclose(last.stress, strain @ Elastic().d.T, atol=1e-14)
    assert np.abs(strain).max() <= 0.006


def test_last_resort_stall_tolerance_accepts_only_steps_failed_at_the_minimum_step():
    """A material whose stress error (relative 3e-4) keeps the residual above the stall
    tolerance 1e-4 at any step: the stage fails at its first step without a last resort and
    with one no looser than tol_stall; with tol_stall_last = 1e-3 every step is taken at the
    minimum step, flagged, and the reaction matches the uniaxial-strain closed form to the
    error's size. A material Newton converges on is not affected."""
    for last in (None, 1e-4):
        disc, solver, stage, top = _compression(Rough(3e-4), dt0=0.1, dt_min=0.1)
        solver.options = NewtonOptions(tol_stall_last=last)
        with pytest.raises(ConvergenceError, match="no converged step beyond t = 0 "):
            list(solver.run_stage(stage))
    disc, solver, stage, top = _compression(Rough(3e-4), dt0=0.1, dt_min=0.1)
    solver.options = NewtonOptions(tol_stall_last=1e-3)
    records = list(solver.run_stage(stage))
    assert records[-1].t == pytest.approx(1.0)
    assert all(r.last_resort and r.dt == pytest.approx(0.1) for r in records)
    assert all(1e-4 < r.residuals[-1] <= 1e-3 for r in records)
    assert solver.reactions(top) == pytest.approx(-0.01 * 8 / 3 * 2, rel=1e-3)
    plain = [(r.t, r.residuals) for r in _run(Elastic(), None)]
    assert [(r.t, r.residuals) for r in _run(Elastic(), 1e-3)] == plain
    assert not any(r.last_resort for r in _run(Elastic(), 1e-3))


def _run(material, last):
    disc, solver, stage, _ = _compression(material)
    solver.options = NewtonOptions(tol_stall_last=last)
    return list(solver.run_stage(stage))


def test_bad_stage_and_options_are_clear_errors():
    with pytest.raises(ValueError, match="dt_min <= dt0"):
        Stage("s", np.array([0]), np.array([0.0]), np.zeros(2), dt0=0.5, dt_min=0.6)
    with pytest.raises(ValueError, match="2 prescribed increments"):
        Stage("s", np.array([0]), np.array([0.0, 1.0]), np.zeros(2))
    with pytest.raises(ValueError, match=r"need 0 < tol <= tol_stall < 1, got tol = 2"):
        NewtonOptions(tol=2)
    with pytest.raises(ValueError, match=r"tol_stall_last = 5e-05 is outside the accepted "
                                         r"range \[tol_stall, 1\)"):
        NewtonOptions(tol_stall_last=5e-5)
    with pytest.raises(ValueError, match=r"line_search_rule = 'newton' is not one of "
                                         r"\('residual', 'energy'\)"):
        NewtonOptions(line_search_rule="newton")


def test_failure_writes_last_state_and_report_and_no_partial_file(tmp_path):
    disc, solver, stage, top = _compression(Brittle(limit=0.006))
    out = analysis.Outputs(tmp_path, "block", frame_every=4, curve_axes=("t", "force"))
    with pytest.raises(ConvergenceError, match="last converged state and curve written"):
        analysis.run(solver, [stage], lambda s: {"force": -s.reactions(top)}, out, progress=False)
    names = sorted(p.name for p in tmp_path.iterdir())
    assert not [n for n in names if ".tmp" in n]
    assert {"block.pvd", "block_curve.csv", "block_failure.json", "block_curve.png",
            "block_plastic_zone.png"} <= set(names)
    frames = [d.get("file") for d in ET.parse(tmp_path / "block.pvd").getroot().iter("DataSet")]
    assert frames and all((tmp_path / f).exists() for f in frames)
    last = meshio.read(tmp_path / frames[-1])
    u = last.point_data["displacement"]
    assert u[:, 1].min() == pytest.approx(-0.01 * solver.committed.t, rel=1e-10)
    rows = np.genfromtxt(tmp_path / "block_curve.csv", delimiter=",", names=True)
    assert rows["force"][-1] == pytest.approx(0.01 * solver.committed.t * 8 / 3 * 2, rel=1e-9)


def _tier2_block(tmp_path, name, noise=0.0):
    """A tier-2 P2 block (1x1, 2x2 elements) at σ = -1 isotropic: bottom on rollers, left
    fixed in x, the right face under the pressure 1, the top pushed down by 2 %; relative
    ``noise`` (seeded) on the initial stress. Returns (solver, material, top dofs)."""
    from contfab.fem.material import TierMaterial
    from contfab.params import default_params

    mesh = M.tensor(np.linspace(0, 1, 3), np.linspace(0, 1, 3))
    disc = Discretization(mesh, "P2")
    material = TierMaterial(default_params(), tier=2)
    n = disc.npoints
    stress0 = np.column_stack((-np.ones(n), -np.ones(n), np.zeros(n)))
    stress0 *= 1.0 + noise * np.random.default_rng(0).standard_normal(stress0.shape)
    solver = Solver(disc, material, stress0, material.initial_state(n))
    top = L.boundary_dofs(disc, "top", "y")
    fixed = np.unique(np.concatenate([top, L.boundary_dofs(disc, "bottom", "y"),
                                      L.boundary_dofs(disc, "left", "x")]))
    f = L.surface_load(disc, "right", pressure=1.0)
    stage = Stage("compress", fixed, np.where(np.isin(fixed, top), -0.02, 0.0), f, dt0=0.1)
    out = analysis.Outputs(tmp_path, name)
    analysis.run(solver, [stage], lambda s: {"force": -s.reactions(top)}, out, progress=False)
    return solver, material, top


def test_tier2_block_writes_fabric_fields(tmp_path):
    """A tier-2 block sheared past yield: the state carries (gp, c, A, Bc, Bs) per point and
    the frames hold B and the θp director; the fabric stays admissible. The outcome is
    determined, not decided by round-off: 1e-12 of noise on the initial stress moves the
    final state and the top force by < 1e-9 (measured: ~1e-12), and the right face carries
    its pressure (mean σxx = -1 to 1e-6)."""
    from dem.conventions import admissibility_margin

    solver, material, top = _tier2_block(tmp_path, "t2")
    n = solver.disc.npoints
    assert solver.committed.t == pytest.approx(1.0, abs=1e-12)   # the whole stage ran
    state = solver.committed.state
    assert material.state_names == ("gp", "c", "A", "Bc", "Bs") and state.shape == (n, 5)
    assert state[:, 0].max() > 0.01                   # the block yielded
    b = np.hypot(state[:, 3], state[:, 4])
    assert b.max() > 0 and np.all(admissibility_margin(state[:, 2], b) >= -1e-12)
    assert solver.committed.stress[:, 0].mean() == pytest.approx(-1.0, abs=1e-6)
    frame = meshio.read(sorted(tmp_path.glob("t2_*.vtu"))[-1])
    director = frame.cell_data["director"][0]
    assert {"B", "A", "c", "gp", "yield", "R_over_P"} <= set(frame.cell_data)
    assert np.allclose(np.hypot(director[:, 0], director[:, 1]), 1.0)
    noisy, _, _ = _tier2_block(tmp_path, "t2_noisy", noise=1e-12)
    assert noisy.committed.t == pytest.approx(1.0, abs=1e-12)
    assert np.abs(noisy.committed.state - state).max() < 1e-9
    assert noisy.reactions(top) == pytest.approx(solver.reactions(top), rel=1e-9, abs=1e-12)


def _platen(ties: bool):
    """A 2x1 elastic block on a smooth base, left side on rollers, a point force F on the
    top-right corner; ``ties``: the top is a rigid platen (all top uy tied to one)."""
    mesh = M.tensor(np.linspace(0, 2, 5), np.linspace(0, 1, 3))
    disc = Discretization(mesh, "P2")
    top = L.boundary_dofs(disc, "top", "y")
    fixed = np.concatenate([L.boundary_dofs(disc, "bottom", "y"), L.boundary_dofs(disc, "left", "x")])
    fixed = np.unique(np.append(fixed, L.boundary_dofs(disc, "bottom", "x")[0]))
    corner = top[np.argmax(disc.basis.doflocs[0, top])]
    f = np.zeros(disc.ndofs)
    f[corner] = -0.3
    pairs = np.column_stack((top[top != corner], np.full(len(top) - 1, corner))) if ties else None
    n = disc.npoints
    solver = Solver(disc, Elastic(), np.zeros((n, 3)), np.zeros((n, 1)))
    return disc, solver, Stage("load", fixed, np.zeros(len(fixed)), f, dt0=1.0, dt_max=1.0,
                               ties=pairs), top


def test_tied_dofs_move_as_a_rigid_platen_and_balance_the_load():
    disc, solver, stage, top = _platen(ties=True)
    (record,) = list(solver.run_stage(stage))
    u_top = solver.committed.u[top]
    assert record.iterations == 1 and np.ptp(u_top) == 0.0 and u_top[0] < 0
    # the same platen settlement imposed as a displacement needs the same total force
    disc, solver2, free_stage, _ = _platen(ties=False)
    fixed = np.concatenate((free_stage.fixed_dofs, top))
    imposed = Stage("push", fixed, np.concatenate((np.zeros(len(free_stage.fixed_dofs)), u_top)),
                    np.zeros(disc.ndofs), dt0=1.0, dt_max=1.0)
    list(solver2.run_stage(imposed))
    assert solver2.reactions(top) == pytest.approx(-0.3, rel=1e-9)
    assert np.allclose(solver2.committed.u, solver.committed.u, rtol=0, atol=1e-12)


def test_bad_ties_are_clear_errors():
    fixed, f = np.array([0, 1]), np.zeros(8)
    with pytest.raises(ValueError, match="a tied DOF is constrained"):
        Stage("s", fixed, np.zeros(2), f, ties=np.array([[1, 2]]))
    with pytest.raises(ValueError, match=r"ties must be \(k, 2\) pairs"):
        Stage("s", fixed, np.zeros(2), f, ties=np.array([2, 3]))
    with pytest.raises(ValueError, match="2 ties but tie_factors of shape"):
        Stage("s", fixed, np.zeros(2), f, ties=np.array([[2, 3], [4, 3]]), tie_factors=np.ones(3))


def test_rigid_plastic_limit_plateau_converges_at_every_step():
    """The smooth-platen block (tier 0, φ = 30°) at λ = 1e8, and pushed to 1000 collapse
    displacements in steps of the whole push: the committed-state start overshot along
    the collapse mode (first correction 3000x the converged increment) and ended in
    ConvergenceError; from the extrapolated increment every step converges to the
    Newton tolerance (none accepted at the stall tolerance) and σ1 = Kp p to 1e-9."""
    from contfab.stability.fem_matrix import biaxial

    for m in (biaxial(lam=1e8), biaxial(dt0=1.0, push=1000.0, dt_min=1e-6)):
        assert m.accuracy < 1e-9, m.note
        assert " 0 accepted at the stall tolerance" in m.note, m.note


def test_dashpot_adds_an_isotropic_stiffness_over_the_step():
    """σ = σ_mat + η Δε/Δt with tensorial Δε (σ_v,xy = η Δγ/(2Δt)): for an elastic material
    (K, G) one step of time Δt is the elastic problem with K + η/(2Δt), G + η/(2Δt)
    (C + (η/Δt) diag(1, 1, 1/2) is isotropic). A sheared block (a non-uniform field)
    solved in one step of Δt = 0.5: the same displacements and reactions as that stiffer
    material, both in one Newton iteration (the dashpot's tangent is consistent), and the
    committed stress is the material's alone."""
    from contfab.fem.dashpot import check_viscosity, stiffness, stress

    eta, dt = 3.0, 0.5
    de = np.array([[1e-3, -2e-3, 4e-3]])
    np.testing.assert_allclose(stress(de, stiffness(eta, dt)),
                               [[eta * 1e-3 / dt, -eta * 2e-3 / dt, eta * 2e-3 / dt]], rtol=1e-15)
    mesh = M.tensor(np.linspace(0, 2, 4), np.linspace(0, 1, 3))
    disc = Discretization(mesh, "P2")
    top = L.boundary_dofs(disc, "top", "x")
    fixed = np.concatenate([L.boundary_dofs(disc, "bottom", "x"),
                            L.boundary_dofs(disc, "bottom", "y"), top])
    inc = np.where(np.isin(fixed, top), 0.01, 0.0)
    stage = Stage("shear", fixed, inc, np.zeros(disc.ndofs), dt0=1.0, dt_max=1.0, duration=dt)
    n = disc.npoints
    runs = {}
    for name, mat, visc in (("dashpot", Elastic(2.0, 1.0), eta),
                            ("stiffer", Elastic(2.0 + eta / (2 * dt), 1.0 + eta / (2 * dt)), 0.0)):
        solver = Solver(disc, mat, np.zeros((n, 3)), np.zeros((n, 1)),
                        NewtonOptions(viscosity=visc, extrapolate=False))
        runs[name] = solver, list(solver.run_stage(stage))
    (sd, rd), (ss, rs) = runs["dashpot"], runs["stiffer"]
    assert [r.iterations for r in rd] == [r.iterations for r in rs] == [1]
    np.testing.assert_allclose(sd.committed.u, ss.committed.u, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(sd.committed.residual[fixed], ss.committed.residual[fixed],
                               rtol=1e-10, atol=1e-12)
    strain = disc.strain(sd.committed.u)[0]
    np.testing.assert_allclose(sd.committed.stress, strain @ Elastic(2.0, 1.0).d.T, atol=1e-14)
    over = np.linalg.norm(stress(strain, stiffness(eta, dt)) * [1, 1, np.sqrt(2)], axis=1)
    assert rd[0].overstress == pytest.approx(over.max(), rel=1e-12)
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match=r"accepted range \[0, inf\)"):
            check_viscosity(bad)
        with pytest.raises(ValueError, match=r"accepted range \[0, inf\)"):
            NewtonOptions(viscosity=bad)


def test_dashpot_carries_a_snapping_back_bar_through_its_peak():
    """A bar of 10 elements pulled at one end, its first element 10 % weaker, with linear
    damage softening steep enough for a snap-back (the elastic unloading of the bar
    releases more than the weak element can take): under displacement control the
    rate-independent Newton cycles with period 2 at the peak and the stage fails at the
    minimum step; with the dashpot (η = 0.01) every step converges, the force falls
    after the peak and the strain localizes in the weak element: every other point stays
    below its damage threshold κ0 (the localized solution, the only one past the peak)."""
    mesh = M.tensor(np.linspace(0, 10, 11), np.linspace(0, 1, 2), "quad")
    disc = Discretization(mesh, "Q8R")
    weak = disc.points[:, 0] < 1.0
    right = L.boundary_dofs(disc, "right", "x")
    fixed = np.concatenate([L.boundary_dofs(disc, "left", "x"),
                            L.boundary_dofs(disc, "left", "y")[:1], right])
    inc = np.where(np.isin(fixed, right), 1.6e-3 * 10 * 0.7, 0.0)
    stage = Stage("pull", fixed, inc, np.zeros(disc.ndofs), dt0=0.1, dt_max=0.1, dt_min=1e-4)
    n = disc.npoints

    def solver(eta):
        mat = Softening(np.where(weak, 0.9e-3, 1e-3), 3e-3)
        return Solver(disc, mat, np.zeros((n, 3)), np.zeros((n, 5)), NewtonOptions(
            tol=1e-8, tol_stall=1e-6, viscosity=eta, line_search=0, extrapolate=False))

    with pytest.raises(ConvergenceError, match="no convergence"):
        list(solver(0.0).run_stage(stage))
    s = solver(0.01)
    forces = [s.reactions(right) for _ in s.run_stage(stage)]
    assert s.committed.t == pytest.approx(1.0)
    assert forces[-1] < 0.8 * max(forces)
    kappa = s.committed.state[:, 4]
    assert kappa[weak].min() > 1.5e-3 and kappa[~weak].max() <= 1e-3


def _kinked_slope(root, soft, stiff, fail_above=np.inf):
    """s(α) = Π'(α) of a convex potential along a correction: slope ``soft`` below the root
    and ``stiff`` above it (points yielding or unloading along the line); None (a failed
    update) above ``fail_above``."""
    return lambda a: None if a > fail_above else (soft if a < root else stiff) * (a - root)


@pytest.mark.parametrize("root, soft, stiff, fail_above", [
    (2.5, 4.0, 4.0, np.inf),      # beyond the Newton step: extrapolated
    (0.3, 10.0, 100.0, np.inf),   # a kink before α = 1: bracketed
    (0.45, 1.0, 10.0, 0.6),       # the update fails beyond 0.6
    (1.0, 3.0, 3.0, np.inf),      # the Newton step itself
])
def test_the_energy_line_search_stops_near_the_potential_s_minimum(root, soft, stiff, fail_above):
    """Π(α) = ∫ s: the accepted α has |s(α)| <= ½ |s(0)| (Matthies & Strang's criterion), so
    the potential has fallen, and it lies within ½ |s(0)| / (the smaller slope) of the
    minimizer, found in at most the 5 trials allowed."""
    slope = _kinked_slope(root, soft, stiff, fail_above)
    s0, calls = slope(0.0), []
    alpha = stationary_alpha(lambda a: calls.append(a) or slope(a), s0, trials=4)
    assert len(calls) <= 5 and slope(alpha) is not None
    assert abs(slope(alpha)) <= 0.5 * abs(s0)
    assert abs(alpha - root) <= 0.5 * abs(s0) / min(soft, stiff) + 1e-12
    if root == 1.0:
        assert calls == [1.0]

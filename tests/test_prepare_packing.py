"""The packing knob of the preparation: looser samples, which contract when sheared."""
import pytest

from dem.job import LOOSE, Settings, prepare_sample
from dem.paths import parse_path
from dem.rve import PathRunner

BASE = dict(n=300, kappa=1e3, mu=0.5, e=0.55, inertial=1e-3)


def _biaxial(state, dyn, strain):
    path = parse_path({"name": "b", "stage": [{"name": "c", "length": strain,
                                              "output_every": strain / 4,
                                              "L": {"yy": -1.0, "xy": 0.0, "yx": 0.0},
                                              "sigma": {"xx": -1.0}}]})
    runner = PathRunner(path, dyn, dyn.gdot_ref)
    run = runner.start(state)
    return runner.run(state, run).rows


def test_the_loose_protocol_packs_looser_and_the_samples_contract():
    """Packing fraction ordered by how much the preparation lets the discs rearrange:
    frictionless compression (μ_prep = 0) slides them into the densest arrangement; the
    test friction during compression (μ_prep = μ) keeps arches; μ_prep = 10 builds looser
    arches, which the lower test friction only partly undoes; and when the collapse that
    lowering the friction starts is quenched (LOOSE), no kinetic energy carries the discs
    past the first arrangement stable under μ. One seed (the preparation is deterministic;
    N = 300, where the seed scatter of c0 is about 0.005)."""
    c = {}
    for kind, packing in (("dense", {"mu_prep": 0.0}), ("usual", {}),
                          ("inertial drop", dict(LOOSE, prep_quench=0)), ("loose", LOOSE)):
        state, dyn, info = prepare_sample(Settings(seed=1, **BASE, **packing), progress=False)
        assert info.relaxed
        c[kind] = info.c
    # the friction was lowered to the test value and the sample relaxed again at P0
    assert dyn.law.mu == 0.5 and info.c_compressed < info.c
    assert abs(-0.5 * (state.stress[0] + state.stress[1]) - 1.0) < 1e-3
    # measured 0.844, 0.801, 0.798, 0.795; at N = 1000 the means of seeds 1-3 are 0.844,
    # 0.811, 0.805 and 0.803 (docs/dem_validation.md, section 9)
    assert c["dense"] > c["usual"] + 0.02
    assert c["usual"] > c["inertial drop"] > c["loose"] + 0.001
    # it compacts from the start of biaxial loading (ε_v < 0), by more than 0.1 %
    eps_v = [r["eps_v"] for r in _biaxial(state, dyn, 0.02)[1:]]
    assert max(eps_v) < 0 and min(eps_v) < -1e-3


@pytest.mark.slow
def test_loose_samples_at_realistic_size_start_below_the_usual_and_contract():
    """N = 1000, κ = 1e3 (docs/dem_validation.md, section 9: c0 0.8007 and 0.8034 against
    0.8134 and 0.8091 for μ_prep = μ; critical c* ≈ 0.811)."""
    size = dict(BASE, n=1000)
    gaps = []
    for seed in (1, 2):
        _, _, info_u = prepare_sample(Settings(seed=seed, **size), progress=False)
        loose, dyn, info = prepare_sample(Settings(seed=seed, **size, **LOOSE), progress=False)
        gaps.append(info_u.c - info.c)
        assert info.c < 0.804
        eps_v = [r["eps_v"] for r in _biaxial(loose, dyn, 0.1)[1:]]
        assert max(eps_v) < 0 and min(eps_v) < -0.006
    assert min(gaps) > 0 and sum(gaps) / 2 > 0.008


def test_a_time_step_too_large_for_the_friction_drop_is_refused_up_front():
    from dem.integrator import TimeStepError

    Settings(mu_prep=10.0, dt_fraction=0.1).validate()
    Settings(mu_prep=0.5, dt_fraction=0.2).validate()        # no friction drop: e = 0.5 only
    with pytest.raises(TimeStepError, match=r"0.2 .*accepted range \(0, 0.114\d*\] .*e = 0.05"):
        Settings(mu_prep=10.0, dt_fraction=0.2).validate()


@pytest.mark.parametrize("bad", [7, -10, 1.0])
def test_a_quench_interval_that_does_not_divide_the_check_interval_is_refused(bad):
    with pytest.raises(ValueError, match=rf"prep_quench = {bad} out of range; accepted 0 .*"
                                         r"divisor of 500"):
        Settings(mu_prep=10.0, prep_quench=bad).validate()

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
    c_usual, c_loose = [], []
    for seed in (1, 2):
        _, _, info_u = prepare_sample(Settings(seed=seed, **BASE), progress=False)
        loose, dyn, info = prepare_sample(Settings(seed=seed, **BASE, **LOOSE), progress=False)
        assert info.relaxed and info_u.relaxed
        # the friction was lowered to the test value and the sample relaxed again at P0
        assert dyn.law.mu == 0.5 and info.c_compressed < info.c
        assert abs(-0.5 * (loose.stress[0] + loose.stress[1]) - 1.0) < 1e-3
        c_usual.append(info_u.c)
        c_loose.append(info.c)
        # it compacts from the start of biaxial loading (ε_v < 0), by more than 0.1 %
        eps_v = [r["eps_v"] for r in _biaxial(loose, dyn, 0.02)[1:]]
        assert max(eps_v) < 0 and min(eps_v) < -1e-3
    # looser than the usual μ_prep = μ sample of the same discs (N = 300: seed scatter of
    # c0 about 0.002; at N = 1000 the mean difference is 0.006, docs/dem_validation.md)
    assert all(lo < us for lo, us in zip(c_loose, c_usual))
    assert sum(c_loose) / 2 < sum(c_usual) / 2 - 0.002


@pytest.mark.slow
def test_loose_samples_at_realistic_size_start_below_the_usual_and_contract():
    """N = 1000, κ = 1e3 (docs/dem_validation.md, section 9: c0 0.805 against 0.8115)."""
    size = dict(BASE, n=1000)
    gaps = []
    for seed in (1, 2):
        _, _, info_u = prepare_sample(Settings(seed=seed, **size), progress=False)
        loose, dyn, info = prepare_sample(Settings(seed=seed, **size, **LOOSE), progress=False)
        gaps.append(info_u.c - info.c)
        assert info.c < 0.807
        eps_v = [r["eps_v"] for r in _biaxial(loose, dyn, 0.1)[1:]]
        assert max(eps_v) < 0 and min(eps_v) < -0.004
    assert min(gaps) > 0 and sum(gaps) / 2 > 0.004


def test_a_time_step_too_large_for_the_friction_drop_is_refused_up_front():
    from dem.integrator import TimeStepError

    Settings(mu_prep=10.0, dt_fraction=0.1).validate()
    Settings(mu_prep=0.5, dt_fraction=0.2).validate()        # no friction drop: e = 0.5 only
    with pytest.raises(TimeStepError, match=r"0.2 .*accepted range \(0, 0.114\d*\] .*e = 0.05"):
        Settings(mu_prep=10.0, dt_fraction=0.2).validate()

"""Preparation: relaxed samples, dense vs loose, refusals (acceptance 7)."""
import numpy as np
import pytest

from conftest import make_dynamics
from dem.particles import ParticleError
from dem.prepare import C_MAX, PreparationError, check_configuration, compress_to_fraction, random_gas


def test_prepared_samples_meet_thresholds_and_friction_loosens(packing_frictionless, packing_frictional):
    for st in (packing_frictionless, packing_frictional):
        assert abs(-0.5 * (st.stress[0] + st.stress[1]) - 1.0) < 1e-3
        assert abs(st.stress[2]) < 1e-3
    # μ_prep = 0 packs denser than μ_prep = 0.5 (2D random packings: ~0.84 vs ~0.80)
    assert packing_frictionless.packing_fraction > packing_frictional.packing_fraction + 0.02
    assert 0.82 < packing_frictionless.packing_fraction < 0.86


def test_the_gas_is_numbered_along_the_grid_rows():
    # discs near in space are near in memory: each disc sits in its own grid site, and
    # the site index (row by row) grows with the disc number
    st = random_gas(np.full(50, 0.5), 0.3, np.random.default_rng(0))
    k = 8                                       # ceil(sqrt(50)) sites per row
    site = np.floor(st.s * k).astype(int)
    assert np.all(np.diff(site[:, 1] * k + site[:, 0]) > 0)


def test_target_fraction_above_jamming_range_is_refused():
    rng = np.random.default_rng(0)
    st = random_gas(np.full(50, 0.5), 0.3, rng)
    with pytest.raises(PreparationError, match=rf"0.95 .*accepted \(0, {C_MAX}\]"):
        compress_to_fraction(st, make_dynamics(st), 0.95, 1e-2)


def test_overlapping_explicit_configuration_is_refused():
    x = np.array([[1.0, 1.0], [1.8, 1.0], [4.0, 4.0]])
    with pytest.raises(ParticleError, match=r"discs 0 and 1 overlap by 0.2"):
        check_configuration(np.full(3, 0.5), x, np.diag([6.0, 6.0]))
    check_configuration(np.full(3, 0.5), x + [[0, 0], [0.3, 0], [0, 0]], np.diag([6.0, 6.0]))


def test_target_c0_takes_the_first_realization_at_or_below_it():
    from dem.job import Settings, prepare_sample
    from dem.prepare import PreparationError

    base = dict(n=60, seed=3, kappa=1e3, inertial=1e-2)
    _, _, first = prepare_sample(Settings(**base), progress=False)
    _, _, same = prepare_sample(Settings(**base, target_c0=first.c), progress=False)
    assert (same.realization, same.c) == (0, first.c)      # the seed's own sample meets it
    _, _, looser = prepare_sample(Settings(**base, target_c0=first.c - 1e-6), progress=False)
    assert looser.realization > 0 and looser.c <= first.c - 1e-6
    _, _, again = prepare_sample(Settings(**base, target_c0=first.c - 1e-6), progress=False)
    assert (again.realization, again.c) == (looser.realization, looser.c)   # reproducible
    with pytest.raises(PreparationError, match="no realization of seed 3 reached c0 <= "
                                               "target_c0 = 0.5 in target_tries = 2"):
        prepare_sample(Settings(**base, target_c0=0.5, target_tries=2), progress=False)


@pytest.mark.parametrize("bad, text", [({"target_c0": 0.95}, "target_c0 = 0.95 out of range"),
                                       ({"target_tries": 0}, "target_tries = 0 out of range")])
def test_bad_target_settings_are_refused(bad, text):
    from dem.job import Settings

    with pytest.raises(ValueError, match=text):
        Settings(**bad).validate()


def test_a_quench_that_does_not_relax_leaves_the_test_law_its_reserve(monkeypatch):
    """The quenched collapse stops where only TEST_LAW_RESERVE steps are left and says so;
    the test law then relaxes the sample at P0. With no room for the quench it does not
    run, and an unrelaxed end reports the figures of the stage that ran, never those of
    a stage that did not (P = 0, unbalanced force ratio inf)."""
    import dem.prepare as prep
    from dem.contact_law import ContactLaw
    from dem.prepare import compress_to_pressure, lower_friction

    monkeypatch.setattr(prep, "TEST_LAW_RESERVE", 30_000)
    rng = np.random.default_rng(2)
    gas = random_gas(np.full(60, 0.5) * rng.uniform(0.8, 1.2, 60), 0.3, rng)
    dyn = make_dynamics(gas, mu=10.0, l_max=2e-2)
    state, info = compress_to_pressure(gas, dyn)
    assert info.relaxed
    test_law = ContactLaw(kn=1e3, e=0.5, mu=0.5)

    short = state.copy()
    _, out = lower_friction(short, dyn, test_law, info, max_steps=info.steps + 30_500)
    assert out.quench_relaxed is False and out.c_quenched is not None
    assert out.relaxed and abs(out.P - 1.0) < 1e-3          # the test law relaxed it
    assert out.steps <= info.steps + 30_500

    none = state.copy()
    _, out = lower_friction(none, dyn, test_law, info, max_steps=info.steps + 500)
    assert out.quench_relaxed is False and out.c_quenched is None
    assert not out.relaxed
    assert out.P > 0.5 and np.isfinite(out.unbalanced)     # the test law's 500 steps

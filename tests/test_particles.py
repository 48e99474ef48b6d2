"""Radii distributions, masses and their validation."""
import numpy as np
import pytest

from dem.particles import ParticleError, RadiiSpec, inertia, masses, parse_radii, sample_radii


def test_uniform_radii_have_unit_mean_diameter_and_stated_width():
    r = sample_radii(parse_radii("uniform:0.2"), 1000, np.random.default_rng(0))
    assert abs(2 * r.mean() - 1.0) < 1e-3
    assert 0.4 <= r.min() < 0.401 and 0.599 < r.max() <= 0.6


def test_bidisperse_counts_ratio_and_mean():
    r = sample_radii(parse_radii("bidisperse:3:0.5"), 1000, np.random.default_rng(0))
    small, large = np.unique(r)
    assert np.isclose(large / small, 3.0) and np.sum(r == small) == 500
    assert np.isclose(2 * r.mean(), 1.0)


def test_mass_and_inertia_of_a_disc():
    m = masses(np.array([0.5]), rho=2.0)
    assert np.isclose(m[0], 2.0 * np.pi * 0.25)
    assert np.isclose(inertia(m, np.array([0.5]))[0], 0.5 * m[0] * 0.25)


@pytest.mark.parametrize("spec, word", [("uniform:1.0", "0 <= W < 1"), ("uniform:-0.1", "W = -0.1"),
                                        ("bidisperse:0.5:0.5", "1 <= Q"),
                                        ("bidisperse:3:1.5", "0 < F < 1"), ("gauss:1", "not understood")])
def test_bad_radii_specs_name_value_and_range(spec, word):
    with pytest.raises(ParticleError, match=word.replace("(", r"\(")):
        parse_radii(spec)


@pytest.mark.parametrize("bad", [0.0, -0.3, np.nan])
def test_nonpositive_explicit_radii_are_refused(bad):
    with pytest.raises(ParticleError, match=r"accepted range \(0, inf\)"):
        RadiiSpec.explicit([0.5, bad])

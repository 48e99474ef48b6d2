"""Shared DEM fixtures: small prepared packings, made once per test session."""
import numba
import numpy as np
import pytest

from dem.contact_law import ContactLaw
from dem.integrator import dynamics
from dem.particles import parse_radii, sample_radii
from dem.prepare import compress_to_pressure, random_gas


# The machine is shared: an OpenMP barrier with a descheduled second thread costs
# milliseconds per step. Tests run single-threaded; the parallel test sets its own count.
numba.set_num_threads(1)


def make_dynamics(state, kappa=1e3, mu=0.5, e=0.5, fraction=0.1, gdot=1e-3, l_max=None):
    law = ContactLaw(kn=kappa, e=e, mu=mu)
    return dynamics(law, state.mass.min(), gdot, fraction, l_max=l_max)


def prepared(n, mu_prep, seed=0, kappa=1e3):
    rng = np.random.default_rng(seed)
    st = random_gas(sample_radii(parse_radii("uniform:0.2"), n, rng), 0.3, rng)
    dyn = make_dynamics(st, kappa=kappa, mu=mu_prep, l_max=2e-2)
    st, info = compress_to_pressure(st, dyn)
    assert info.relaxed
    return st


@pytest.fixture(scope="session")
def packing_frictionless():
    """N = 150 discs (diameters uniform in [0.8, 1.2]), μ_prep = 0, κ = 1e3, at P0 = 1."""
    return prepared(150, 0.0)


@pytest.fixture(scope="session")
def packing_frictional():
    """N = 150 discs, μ_prep = 0.5, κ = 1e3, at P0 = 1."""
    return prepared(150, 0.5, seed=1)

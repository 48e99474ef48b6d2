"""Shared test helpers: model parameters and updates, small prepared DEM packings."""
from pathlib import Path

import numba
import numpy as np
import pytest

from contfab.models import slip_planes, tiers
from contfab.params import Params, load_params
from dem.contact_law import ContactLaw
from dem.integrator import dynamics
from dem.particles import parse_radii, sample_radii
from dem.prepare import compress_to_pressure, random_gas

FIXED_PARAMS = Path(__file__).parent / "data" / "model_params.toml"


def fixed_params() -> Params:
    """Fixed parameters for tests of the model and the driver (tests/data/model_params.toml:
    the pre-calibration values), independent of the shipped, calibrated defaults."""
    return load_params(FIXED_PARAMS)

TIER1 = dict(phi_star_deg=25.0, dphi_dc_deg=60.0, dpsi_dc_deg=80.0, c_star=0.81)
"""Tier-1 values tier 2 reads (c-terms and clamps); a0 = φ*, b0 = 0 reduce tier 2 to tier 1."""


def model_params(tier=2, lam=1500.0, nu=0.25, tier1=None, **tier2) -> Params:
    """Validated parameters; λ = 1500, ν = 0.25 give K = 1000, G = 600 (p_ref = 1)."""
    t1 = dict(TIER1, **(tier1 or {}))
    tier2.setdefault("a0_deg", t1["phi_star_deg"])
    return Params.from_dict({"tier": tier, "regularization": {"lambda": lam, "p_ref": 1.0, "nu": nu},
                             "tier1": t1, "tier2": tier2, "initial": {"c0": 0.81}})


@pytest.fixture(scope="session")
def tier2_prm():
    """The tier-2 kernel array of :func:`model_params` (same arguments)."""
    return lambda **kw: model_params(**kw).array(2)


def update(params, stress, state, dstrain, dspin, tier=2):
    """tiers.update as arrays (stress, state, tangent, status)."""
    out = tiers.update(tier, stress, state, dstrain, dspin, params)
    return out.stress, out.state, out.tangent, out.status


def stress_at(p, r, alpha):
    """Voigt stress with pressure p, deviator radius r, major principal direction alpha."""
    return np.array([-p + r * np.cos(2 * alpha), -p - r * np.cos(2 * alpha), r * np.sin(2 * alpha)])


def fabric_terms(prm, c, a, bc, bs):
    """slip_planes.fabric_terms of one state (its Jacobian built here)."""
    dpz = np.empty((slip_planes.N_P, 4))
    slip_planes.fabric_terms_jacobian(prm, dpz)
    return slip_planes.fabric_terms(c, a, bc, bs, prm, dpz)


# --------------------------------------------------------------- DEM fixtures


# The machine is shared: waking a second thread costs more than it gains at the sizes
# tested here (dem/threads.py). The DEM runs on its own count (1); the model kernels of
# large point sets follow numba's, which the tests keep at 1 (parallel tests set theirs).
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

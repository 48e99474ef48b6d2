"""Shared test helpers: model parameters and updates, small prepared DEM packings."""
from pathlib import Path

import numba
import numpy as np
import pytest

from contfab.models import tiers
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

TIER1 = dict(phi_star_deg=25.0, dphi_dc_deg=60.0, dpsi_dc_deg=80.0, c_star=0.81, phi_min_deg=8.0)
"""Tier-1 values tier 2 reads (c-terms and clamps; φ_min = 8° keeps tier 2's cone radius
sin φ - w b_c positive at the ``[tier2]`` defaults)."""


def model_params(tier=2, lam=1500.0, nu=0.25, tier1=None, **tier2) -> Params:
    """Validated parameters; λ = 1500, ν = 0.25 give K = 1000, G = 600 (p_ref = 1)."""
    t1 = dict(TIER1, **(tier1 or {}))
    return Params.from_dict({"tier": tier, "regularization": {"lambda": lam, "p_ref": 1.0, "nu": nu},
                             "tier1": t1, "tier2": tier2, "initial": {"c0": 0.81}})


def update(params, stress, state, dstrain, dspin, tier=2):
    """tiers.update as arrays (stress, state, tangent, status)."""
    out = tiers.update(tier, stress, state, dstrain, dspin, params)
    return out.stress, out.state, out.tangent, out.status


def stress_at(p, r, alpha):
    """Voigt stress with pressure p, deviator radius r, major principal direction alpha."""
    return np.array([-p + r * np.cos(2 * alpha), -p - r * np.cos(2 * alpha), r * np.sin(2 * alpha)])


def cone_yield(params, stress, state):
    """Tier 2's yield function f(σ; c, q) = |s + P α| - m(c) P from its definition
    (:mod:`contfab.models.fabric_cone`), in numpy for points (n, 3), (n, 5): s = ((σxx -
    σyy)/2, σxy), P = -(σxx + σyy)/2, α = w (Bc, Bs)/A, m(c) = sin φ(c) - w b_c with
    φ(c) = φ* + φ'(c - c*) clamped to [φ_min, φ_max] (``[tier1]``)."""
    stress, state = np.atleast_2d(stress), np.atleast_2d(state)
    t1, t2 = params.tier1, params.tier2
    phi = np.clip(t1.phi_star_deg + t1.dphi_dc_deg * (state[:, 1] - t1.c_star),
                  t1.phi_min_deg, t1.phi_max_deg)
    w = t2.fabric_weight
    p = -0.5 * (stress[:, 0] + stress[:, 1])
    ux = 0.5 * (stress[:, 0] - stress[:, 1]) + p * w * state[:, 3] / state[:, 2]
    uy = stress[:, 2] + p * w * state[:, 4] / state[:, 2]
    return np.hypot(ux, uy) - (np.sin(np.radians(phi)) - w * t2.b_ratio_crit) * p


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

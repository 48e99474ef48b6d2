"""Shared test helpers."""
import numpy as np
import pytest

from contfab.models import slip_planes, tiers
from contfab.params import Params

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

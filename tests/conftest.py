"""Shared test helpers."""
import numpy as np
import pytest

from contfab.models.fabric_model import Tier2Section, tier2_array

TIER1 = dict(phi_star_deg=25.0, dphi_dc_deg=60.0, dpsi_dc_deg=80.0, c_star=0.81)
"""Tier-1 values tier 2 reads (c-dependence and clamps); a0 = φ*, b0 = 0 reduce to tier 1."""


@pytest.fixture(scope="session")
def tier2_prm():
    """Build a tier-2 kernel array: tier2_prm(bulk=..., shear=..., **[tier2] fields)."""
    def build(bulk=1000.0, shear=600.0, tier1=None, **section):
        section.setdefault("a0_deg", TIER1["phi_star_deg"])
        return tier2_array(Tier2Section(**section), bulk=bulk, shear=shear, **(tier1 or TIER1))
    return build


def stress_at(p, r, alpha):
    """Voigt stress with pressure p, deviator radius r, major principal direction alpha."""
    return np.array([-p + r * np.cos(2 * alpha), -p - r * np.cos(2 * alpha), r * np.sin(2 * alpha)])

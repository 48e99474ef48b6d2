"""Localization measures of a strain field (contfab.fexdem.band)."""
import numpy as np
import pytest

from contfab.fexdem.band import localization
from contfab.fexdem.scenes import build


@pytest.fixture(scope="module")
def disc():
    return build("biaxial", nx=12, ny=24, width=1.0, height=2.0).disc


def test_a_uniform_field_has_no_contrast(disc):
    strain = np.tile([1e-3, -2e-3, 5e-4], (disc.npoints, 1))
    m = localization(disc, strain)
    assert m["contrast"] < 1e-12 and abs(m["peak_ratio"] - 1) < 1e-12
    assert abs(m["half_area"] - 0.5) < 0.01


@pytest.mark.parametrize("theta", [35.0, 60.0, 125.0])
def test_a_straight_band_is_found_at_its_angle(disc, theta):
    """Shear strain 10x higher within 0.08 of a line through the centre at angle θ: the
    measured angle is θ within the mesh's resolution, half the shear sits on a small
    share of the area, and the strip found holds most of the excess shear."""
    t = np.radians(theta)
    x, y = disc.points[:, 0] - 0.5, disc.points[:, 1] - 1.0
    dist = np.abs(-np.sin(t) * x + np.cos(t) * y)
    gamma = np.where(dist < 0.08, 1e-2, 1e-3)
    strain = np.column_stack([0.5 * gamma, -0.5 * gamma, np.zeros_like(gamma)])
    m = localization(disc, strain)
    assert abs(m["angle_deg"] - theta) <= 3.0 and abs(m["offset"]) < 0.1
    assert m["half_area"] < 0.25 and m["contrast"] > 1.0 and m["band_share"] > 0.8


def test_an_unstrained_field_is_an_error(disc):
    with pytest.raises(ValueError, match="mean shear strain"):
        localization(disc, np.zeros((disc.npoints, 3)))

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


def test_band_of_run_since_measures_the_increment(tmp_path):
    """`contfab fexdem-band --since`: a run whose field holds a band at 60° by an earlier
    checkpoint and a uniform simple shear after it: the total strain is localized, the
    increment since that checkpoint is uniform (no contrast); a checkpoint that is not
    earlier is refused."""
    from contfab.fexdem.compare import band_of_run
    from contfab.fexdem.material import FE_CHECKPOINT

    scene = build("biaxial", nx=6, ny=12, width=1.0, height=1.5)
    x, y = scene.disc.basis.doflocs
    t = np.radians(60.0)
    dist = -np.sin(t) * (x - 0.5) + np.cos(t) * (y - 0.75)
    slip = np.clip(dist / 0.15, -1.0, 1.0) * 0.01          # a shear band along the 60° line
    u0 = np.zeros(scene.disc.ndofs)
    u0[0::2], u0[1::2] = (slip * np.cos(t))[0::2], (slip * np.sin(t))[1::2]
    u1 = u0.copy()
    u1[0::2] += 1e-3 * y[0::2]                              # uniform simple shear γ = 1e-3
    (tmp_path / "cells").mkdir()
    np.savez(tmp_path / "early.npz", u=u0, t=0.2, fe_step=2)
    np.savez(tmp_path / "cells" / FE_CHECKPOINT, u=u1, t=0.5, fe_step=5)
    total = band_of_run("biaxial", tmp_path, 6, 12)
    inc = band_of_run("biaxial", tmp_path, 6, 12, since=tmp_path / "early.npz")
    assert total["contrast"] > 0.5 and abs(total["angle_deg"] - 60.0) <= 5.0
    assert inc["contrast"] < 1e-9 and inc["t_since"] == 0.2
    assert (tmp_path / "band_since.json").exists() and (tmp_path / "biaxial_dem_band_since.png").exists()
    with pytest.raises(ValueError, match="an earlier checkpoint"):
        band_of_run("biaxial", tmp_path, 6, 12, since=tmp_path / "cells" / FE_CHECKPOINT)

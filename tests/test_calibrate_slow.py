"""Slow: regenerate the shipped default parameters with `contfab calibrate` at the settings
recorded in their provenance (the DEM campaign and the fit budget) and check that every
fitted parameter agrees with the shipped one within the seed scatter recorded there."""
import math
import tomllib

import pytest

from contfab.calibration.calibrate import calibrate
from contfab.calibration.campaign import CampaignSettings
from contfab.params import default_params, default_params_path, load_params


@pytest.mark.slow
def test_regenerated_defaults_agree_with_the_shipped_ones_within_the_seed_scatter(tmp_path):
    shipped = default_params()
    with default_params_path().open("rb") as fh:
        prov = tomllib.load(fh)["provenance"]
    campaign = CampaignSettings.from_dict({**prov["campaign"], "runs": list(prov["runs"].values())})
    written = calibrate(tmp_path / "calibration", shipped.tier, campaign, executor="pool",
                        workers=2, progress=False, max_nfev=prov["max_nfev"])
    new = load_params(written["params"])
    assert new.tier2.to_dict()["fabric_law"] == prov["fabric_law_choice"]
    checked = 0
    for fit in ("tier1", prov["fabric_law_choice"]):
        for key, rec in prov["fitted"][fit].items():
            section, field = key.split(".")
            a = getattr(shipped.sections[section], field)
            b = getattr(new.sections[section], field)
            # two estimates, each with the standard error of a K-seed mean: 3 sd of their difference
            tol = 3.0 * math.sqrt(2.0) * rec["stderr"] + 1e-9 * max(1.0, abs(a))
            assert abs(b - a) <= tol, (key, a, b, rec)
            checked += 1
    assert checked >= 4

"""Stress probing: plastic flow direction, yield normal and non-associativity angle from a
load-unload probe family, against closed forms (a synthetic bilinear response, and the
tier-1 cone probed by the material point from a state reached on the yield surface)."""
import math
from pathlib import Path

import numpy as np
import pytest

from contfab import material_point as mp
from contfab.calibration.curves import history_of
from contfab.params import load_params
from contfab.calibration.probing import ProbeResponse, analyse, cone_angles, probe_response
from dem.paths import parse_path

PARAMS = load_params(Path(__file__).parent / "data" / "model_params.toml")
PROBES = parse_path({"name": "probes", "probes": {"directions": 16, "magnitude": 1e-4,
                                                  "length": 0.01, "unload": True, "hold": True}})
PRELOAD = parse_path({"name": "preload", "stage": [
    {"length": 0.02, "output_every": 0.002, "L": {"yy": -1.0, "xy": 0.0, "yx": 0.0},
     "sigma": {"xx": -1.0}}]})


def test_bilinear_response_gives_its_normal_and_flow_exactly():
    n, m = math.radians(-28.0), math.radians(-47.0)
    beta = np.radians(np.arange(16) * 22.5)
    dsig = 0.05 * np.stack([np.cos(beta), np.sin(beta)], 1)
    plastic = np.outer(np.maximum(0.0, dsig @ [math.cos(n), math.sin(n)]) / 20.0,
                       [math.cos(m), math.sin(m)])
    elastic = dsig @ np.array([[1e-3, -2e-4], [-2e-4, 1e-3]])
    a = analyse(ProbeResponse(dsig, elastic + plastic, plastic, np.array([-1.0, -1.5, 0.0])))
    assert a.normal_deg == pytest.approx(-28.0, abs=1e-6)
    assert a.flow_deg == pytest.approx(-47.0, abs=1e-9)
    assert a.nonassociativity_deg == pytest.approx(19.0, abs=1e-6) and a.fit_r2 > 1 - 1e-12


@pytest.mark.parametrize("tier", [1, 2])
def test_model_probes_from_a_state_on_the_yield_surface_give_the_cone_angles(tier):
    """A loose point (c0 = 0.79 < c* = 0.81: contractant, hardening) loaded to 2% axial
    strain, then probed from that state (run_family(start=...)): tier 1, and tier 2 reduced
    to it (w = k_d = 0: the cone's axis at the origin, the fabric's dilatancy off), give δ = angle(n) - angle(m) of the cone at φ(c), ψ(c)."""
    params = PARAMS.replace("tier2", fabric_weight=0.0, dilatancy_fabric=0.0)   # tier 2 = tier 1
    pre = mp.run_path(PRELOAD, params, tier, state0={"c": 0.79})
    runs = mp.run_family(PROBES, params, tier, start=pre)
    assert all(r["sxx"][0] == pre["sxx"][-1] and r["tau"][0] == 0.0 for r in runs)
    a = analyse(probe_response([history_of(r) for r in runs]))
    t1 = PARAMS.tier1
    c = pre["c_p"][-1]
    sphi = math.sin(math.radians(t1.phi_star_deg + t1.dphi_dc_deg * (c - t1.c_star)))
    spsi = math.sin(math.radians(t1.dpsi_dc_deg * (c - t1.c_star)))
    assert pre["RP"][-1] == pytest.approx(sphi, rel=1e-9)                # on the yield surface
    normal, flow, delta = cone_angles(sphi, spsi)
    assert a.flow_deg == pytest.approx(flow, abs=0.02)
    assert a.normal_deg == pytest.approx(normal, abs=0.05)
    assert a.nonassociativity_deg == pytest.approx(delta, abs=0.05) and delta > 20.0


def test_bad_probe_families_are_refused():
    runs = mp.run_family(PROBES, PARAMS, 1)
    with pytest.raises(ValueError, match="needs >= 4 probes and the hold reference"):
        probe_response([history_of(r) for r in runs[:3]])
    plain = parse_path({"name": "p", "probes": {"directions": 4, "magnitude": 0.01, "length": 0.01}})
    with pytest.raises(ValueError, match="unload = true"):
        probe_response([history_of(r) for r in mp.run_family(plain, PARAMS, 1)] * 2)
    inside = [history_of(r) for r in runs]            # from the isotropic state: no plasticity
    with pytest.raises(ValueError, match="not on the yield surface"):
        analyse(probe_response(inside))


def test_start_option_refuses_another_tier_and_mixed_starts():
    pre = mp.run_path(PRELOAD, PARAMS, 1, state0={"c": 0.79})
    with pytest.raises(ValueError, match="tier-1 result; it cannot start a tier-2 run"):
        mp.run_path(PRELOAD, PARAMS, 2, start=pre)
    with pytest.raises(ValueError, match="either start .* or stress0/state0"):
        mp.run_path(PRELOAD, PARAMS, 1, start=pre, state0={"c": 0.8})


def test_the_cone_tiers_report_their_closed_form_flow_direction():
    """Tiers 0/1 at c = c*: ψ = 0, so the plastic strain increment is isochoric (flow at
    -45°) and δ = normal + 45° with the normal atan2(-1 + sin φ*, 1 + sin φ*); this is the
    calibration report's answer where the tier-1 probes have none (zero hardening)."""
    import math

    from contfab.calibration.calibrate import _cone_probe
    from contfab.params import default_params

    prm = default_params()
    at_cstar = _cone_probe(prm.with_tier(1), 1, prm.tier1.c_star)
    s = math.sin(math.radians(prm.tier1.phi_star_deg))
    assert at_cstar["flow_deg"] == pytest.approx(-45.0, abs=1e-12)
    assert at_cstar["normal_deg"] == pytest.approx(math.degrees(math.atan2(s - 1, s + 1)), abs=1e-12)
    assert at_cstar["delta_deg"] == pytest.approx(at_cstar["normal_deg"] + 45.0, abs=1e-12)
    denser = _cone_probe(prm.with_tier(1), 1, prm.tier1.c_star + 0.003)
    # denser: dilatant (flow turns from -45° towards the normal) and stronger (normal up)
    assert denser["flow_deg"] > -45.0 and denser["normal_deg"] > at_cstar["normal_deg"]

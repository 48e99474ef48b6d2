"""Parameter files: the shipped defaults, the kernel array layout, and bad values (acceptance 7)."""
import math

import numpy as np
import pytest

from contfab.models import fabric_model, tiers
from contfab.params import ParamError, Params, default_params, default_params_path, load_params
from conftest import FIXED_PARAMS, fixed_params


def _doc(**changes):
    """The fixed test parameter document with some values changed: {"section.key": value}."""
    import tomllib
    with FIXED_PARAMS.open("rb") as fh:
        doc = tomllib.load(fh)
    for where, value in changes.items():
        if "." in where:
            section, key = where.split(".")
            doc[section][key] = value
        else:
            doc[where] = value
    return doc


def test_default_file_is_a_calibration_output_with_its_provenance():
    """The shipped file is what `contfab calibrate` wrote (issue 4): its provenance names the
    command and the campaign, and its values are those this DEM measures for μ = 0.5 discs
    (docs/dem_validation.md: residual R/P 0.27 and c 0.812 at N = 2000, i.e. φ* = 15.7°)."""
    import tomllib

    p = default_params()
    prov = tomllib.loads(default_params_path().read_text())["provenance"]
    assert prov["command"].startswith("contfab calibrate") and prov["campaign"]["mu"] == 0.5
    assert p.tier == 2 and p.p_ref == 1.0
    assert 15.0 <= p.tier1.phi_star_deg <= 17.5 and 0.80 <= p.tier1.c_star <= 0.82


def test_array_layout_matches_the_kernel_doc():
    # cone.py: tier 0 [K, G, sin φ, sin ψ]; tier 1 [K, G, φ*, φ', ψ', c*, φmin, φmax] (rad)
    p = Params.from_dict(_doc(**{"regularization.lambda": 200.0, "regularization.p_ref": 3.0,
                                 "regularization.nu": 0.25, "tier0.psi_deg": -5.0}))
    e = 600.0
    k, g = e / (2 * 0.75), e / (2 * 1.25)
    assert p.array(0) == pytest.approx([k, g, math.sin(math.radians(22)), math.sin(math.radians(-5))],
                                       rel=1e-15)
    assert p.array(1) == pytest.approx([k, g, math.radians(22), math.radians(250), math.radians(300),
                                        0.81, math.radians(1), math.radians(60)], rel=1e-15)
    # fabric_model.py: tier 2 = tier 1's array, then a0..a3, b0..b3 (rad), β, n_search, law,
    # κa, kc, ko, z_c/π, b_c, k
    assert p.array(2)[:8] == pytest.approx(p.array(1), rel=1e-15)
    assert p.array(2).size == fabric_model.N_PRM
    assert p.array(2)[8] == pytest.approx(math.radians(22)) and p.array(2)[18] == 0.0
    relax = p.replace("tier2", fabric_law=1.0, z_crit=3.3)
    assert relax.array(2)[18] == 1.0 and relax.array(2)[22] == pytest.approx(3.3 / math.pi)
    a = p.array(1)
    a[0] = -1.0                                      # a copy: the cached array is untouched
    assert p.array(1)[0] == pytest.approx(k)
    # K, G are those of the 2D isotropic law: uniaxial stress gives Young's E and ratio ν
    c = np.array([[k + g, k - g], [k - g, k + g]])
    strain = np.linalg.solve(c, [1.0, 0.0])
    assert 1.0 / strain[0] == pytest.approx(e) and -strain[1] / strain[0] == pytest.approx(0.25)


def test_initial_state_from_the_initial_section():
    p = Params.from_dict(_doc(**{"initial.B0": 0.2, "initial.theta_p0_deg": 30.0}))
    s1 = tiers.initial_state(1, p, 4)
    assert s1.shape == (4, 2) and np.all(s1 == [0.0, 0.81])
    assert np.all(tiers.initial_state(0, p, 3) == 0.0)
    values = p.initial.state_values()
    assert (values["Bc"], values["Bs"]) == pytest.approx((0.2 * 0.5, 0.2 * math.sqrt(3) / 2))


BAD = [
    ({"tier0.phi_deg": 0.0}, ["phi_deg = 0", "(0, 90)"]),
    ({"tier0.phi_deg": 90.0}, ["phi_deg = 90", "(0, 90)"]),
    ({"tier0.phi_deg": -3.0}, ["phi_deg = -3", "(0, 90)"]),
    ({"tier0.psi_deg": 30.0}, ["psi_deg = 30", "[-22, 22]"]),
    ({"tier0.psi_deg": -22.5}, ["psi_deg = -22.5", "[-22, 22]"]),
    ({"tier1.phi_star_deg": 95.0}, ["phi_star_deg = 95", "(0, 90)"]),
    ({"tier1.phi_star_deg": 0.5}, ["phi_star_deg = 0.5", "[1, 60]"]),
    ({"tier1.phi_star_deg": 0.0}, ["phi_star_deg = 0", "(0, 90)"]),
    ({"tier1.phi_max_deg": 90.0}, ["phi_max_deg = 90", "(0, 90)"]),
    ({"tier1.c_star": 1.0}, ["c_star = 1", "(0, 1)"]),
    ({"tier1.c_star": 0.0}, ["c_star = 0", "(0, 1)"]),
    ({"tier1.c_star": -0.2}, ["c_star = -0.2", "(0, 1)"]),
    ({"tier1.dpsi_dc_deg": -10.0}, ["dpsi_dc_deg = -10", "[0, inf)"]),
    ({"initial.c0": 1.2}, ["c0 = 1.2", "(0, 1)"]),
    ({"initial.c0": 0.0}, ["c0 = 0", "(0, 1)"]),
    ({"initial.A0": 1.5, "initial.B0": 0.9}, ["A0 = 1.5, B0 = 0.9", "(pi/6) A0 + (sqrt(3)/4) B0 <= 1",
                                              "1.175"]),
    ({"initial.A0": 0.5, "initial.B0": 0.6}, ["A0 = 0.5, B0 = 0.6", "B0 <= A0"]),
    ({"initial.B0": -0.1}, ["B0 = -0.1", "[0, 1.90986]"]),
    ({"initial.theta_p0_deg": 120.0}, ["theta_p0_deg = 120", "(-90, 90]"]),
    ({"regularization.lambda": 0.0}, ["lambda = 0", "(0, inf)"]),
    ({"regularization.lambda": -5.0}, ["lambda = -5", "(0, inf)"]),
    ({"regularization.p_ref": float("nan")}, ["p_ref = nan", "(0, inf)"]),
    ({"regularization.nu": 1.0}, ["nu = 1", "(-1, 1)"]),
    ({"regularization.lambda": "big"}, ["lambda = 'big' is not a number", "(0, inf)"]),
    ({"tier2.a0_deg": 0.0}, ["a0_deg = 0", "(0, 90)"]),
    ({"tier2.a0_deg": 90.0}, ["a0_deg = 90", "(0, 90)"]),
    ({"tier2.a2_deg": 45.0}, ["a2_deg = 45", "[-30, 30]"]),
    ({"tier2.sharpness": 0.0}, ["sharpness = 0", "(0, inf)"]),
    ({"tier2.n_search": 2.5}, ["n_search = 2.5 is not an integer", "[0, 1024]"]),
    ({"tier2.fabric_law": "diffusion"}, ["fabric_law = 'diffusion'", "balance, relaxation"]),
    ({"tier2.k_c": -1.0}, ["k_c = -1", "[0, inf)"]),
    ({"tier2.b_ratio_crit": 1.0}, ["b_ratio_crit = 1", "[0, 1)"]),
    ({"tier2.z_crit": 5.5, "tier2.b_ratio_crit": 0.3},
     ["z_crit = 5.5, b_ratio_crit = 0.3", "not an admissible critical fabric", "1.144"]),
    ({"tier": 3}, ["tier = 3", "accepted: 0, 1, 2"]),
    ({"tier": "one"}, ["tier = 'one'", "accepted: 0, 1"]),
    # a strongly contractant tier 0 with a high nu: G + K sin φ sin ψ <= 0
    ({"tier0.phi_deg": 60.0, "tier0.psi_deg": -60.0, "regularization.nu": 0.5},
     ["nu = 0.5", "nu < 0.1429"]),
]


@pytest.mark.parametrize("changes, fragments", BAD, ids=[str(c) for c, _ in BAD])
def test_bad_values_fail_at_load_naming_value_and_range(changes, fragments):
    with pytest.raises(ParamError) as err:
        Params.from_dict(_doc(**changes))
    print(f"\n{changes}: {err.value}")
    for fragment in fragments:
        assert fragment in str(err.value)
    assert isinstance(err.value, ValueError)


def test_structural_errors_are_clear(tmp_path):
    doc = _doc()
    doc["tier1"]["c_stra"] = 0.8
    with pytest.raises(ParamError, match="unknown key.*c_stra.*known: phi_star_deg"):
        Params.from_dict(doc)
    doc = _doc()
    del doc["tier1"]["c_star"]
    with pytest.raises(ParamError, match=r"\[tier1\] is missing c_star"):
        Params.from_dict(doc)
    doc = _doc()
    doc["tier3"] = {}
    with pytest.raises(ParamError, match="unknown section.*tier3"):
        Params.from_dict(doc)
    doc = _doc()
    del doc["tier1"]
    with pytest.raises(ParamError, match=r"tier 1 needs a \[tier1\] section"):
        Params.from_dict(doc)
    f = tmp_path / "p.toml"
    f.write_text(FIXED_PARAMS.read_text().replace("c_star = 0.81", "c_star = 1.81"))
    with pytest.raises(ParamError, match=r"c_star = 1.81 is outside the accepted range \(0, 1\)"):
        load_params(f)
    f.write_text("tier = 1\n[tier1\n")
    with pytest.raises(ParamError, match="not valid TOML"):
        load_params(f)


def test_replace_revalidates_and_unknown_tier_at_update():
    p = fixed_params()
    assert p.replace("regularization", lam=1e6).array(0)[0] == pytest.approx(5e5)
    with pytest.raises(ParamError, match="lambda = -1"):
        p.replace("regularization", lam=-1.0)
    with pytest.raises(ParamError, match="phi_deg = 0"):
        p.replace("tier0", phi_deg=0.0)
    with pytest.raises(ParamError, match="tier = 3 is not an available model tier"):
        tiers.update(3, np.zeros((1, 3)), np.zeros((1, 5)), np.zeros((1, 3)), np.zeros(1), p)
    with pytest.raises(ParamError, match="tier = 7"):
        p.with_tier(7)


def test_to_dict_round_trips_through_from_dict():
    """The sidecar of a run writes Params.to_dict(): reading it back gives the same kernels'
    arrays for every tier, with TOML keys (lambda) and the fabric law by name."""
    params = fixed_params()
    doc = params.to_dict()
    assert doc["regularization"]["lambda"] == params.regularization.lam
    assert doc["tier2"]["fabric_law"] == "balance"
    back = Params.from_dict(doc)
    for tier in sorted(tiers.KERNELS):
        assert np.array_equal(back.array(tier), params.array(tier))


def test_every_parameter_is_documented_with_its_range():
    """docs/model_validation.md lists every key of every section with the accepted range the
    code declares (a parameter added or re-ranged without its documentation fails here)."""
    from dataclasses import fields
    from pathlib import Path

    from contfab.params import SECTIONS

    doc = (Path(__file__).parent.parent / "docs" / "model_validation.md").read_text()
    for name, cls in SECTIONS.items():
        start = doc.index(f"`[{name}]`")
        block = doc[start:doc.find("\n`[", start + 1)]
        for f in fields(cls):
            key = f.metadata["key"] or f.name
            row = next((line for line in block.splitlines() if line.startswith(f"| `{key}` |")),
                       None)
            assert row is not None, f"[{name}] {key} is not in the parameter table"
            if name == "tier2" and key == "fabric_law":
                assert all(law in row for law in cls.LAWS), row
            else:
                assert f"`{f.metadata['range']}`" in row, (row, str(f.metadata["range"]))

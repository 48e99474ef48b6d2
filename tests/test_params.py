"""Parameter files: the shipped defaults, the kernel array layout, and bad values (acceptance 7)."""
import math
import re
from pathlib import Path

import numpy as np
import pytest

from contfab import params as params_module
from contfab import models
from contfab.models import tiers
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
    """The shipped file is what `contfab calibrate` wrote: its provenance names the
    command and the campaign, and its values are those this DEM measures for μ = 0.5 discs
    (docs/dem_validation.md: residual R/P 0.27 and c 0.812 at N = 2000, i.e. φ* = 15.7°)."""
    import tomllib

    p = default_params()
    prov = tomllib.loads(default_params_path().read_text())["provenance"]
    assert prov["command"].startswith("contfab calibrate") and prov["campaign"]["mu"] == 0.5
    assert p.tier == 2 and p.p_ref == 1.0
    assert 15.0 <= p.tier1.phi_star_deg <= 17.5 and 0.80 <= p.tier1.c_star <= 0.82


# One value per parameter, none equal to another once in the kernel arrays (radians, K, G,
# A_c = z_c/pi), so each named offset is checked against its own parameter.
DISTINCT = {
    "regularization": {"lambda": 200.0, "p_ref": 3.0, "nu": 0.25},
    "tier0": {"phi_deg": 22.0, "psi_deg": -5.0},
    "tier1": {"phi_star_deg": 23.0, "dphi_dc_deg": 250.0, "dpsi_dc_deg": 300.0, "c_star": 0.81,
              "phi_min_deg": 6.5, "phi_max_deg": 61.0},
    "tier2": {"fabric_weight": 0.45, "dilatancy_fabric": 1.3,
              "fabric_law": "relaxation", "kappa_a": 3.5, "k_c": 17.0, "k_o": 11.0,
              "z_crit": 3.3, "b_ratio_crit": 0.2, "relax_rate": 12.0, "fabric_speed": 4.5,
              "fabric_dilation": 30.0},
    "initial": {"c0": 0.8},
}
E_REG = 200.0 * 3.0                                   # lambda * p_ref
K_REG, G_REG = E_REG / (2 * 0.75), E_REG / (2 * 1.25)  # 2D: K = E/(2(1 - nu)), G = E/(2(1 + nu))
rad = math.radians
TIER1_VALUES = {"BULK": K_REG, "SHEAR": G_REG, "PHI_STAR": rad(23.0), "DPHI_DC": rad(250.0),
                "DPSI_DC": rad(300.0), "C_STAR": 0.81, "PHI_MIN": rad(6.5), "PHI_MAX": rad(61.0)}
EXPECTED = {
    0: {"BULK": K_REG, "SHEAR": G_REG, "SIN_PHI": math.sin(rad(22.0)),
        "SIN_PSI": math.sin(rad(-5.0))},
    1: TIER1_VALUES,
    2: {**TIER1_VALUES, "FABRIC_WEIGHT": 0.45, "DILATANCY_FABRIC": 1.3,
        "FABRIC_LAW": 1.0, "KAPPA_A": 3.5, "K_C": 17.0, "K_O": 11.0,
        "A_CRIT": 3.3 / math.pi, "B_RATIO_CRIT": 0.2, "RELAX_RATE": 12.0, "FABRIC_SPEED": 4.5,
        "FABRIC_DILATION": 30.0},
}
"""Each tier's array by offset name: what the kernels read at ``prm[NAME]``."""


@pytest.mark.parametrize("tier", sorted(EXPECTED))
def test_every_named_offset_reads_its_own_parameter(tier):
    prm = Params.from_dict({"tier": tier, **DISTINCT}).array(tier)
    assert len(set(prm)) == prm.size                  # distinct: no check below passes by chance
    offsets = {name: getattr(params_module, name) for name in EXPECTED[tier]}
    assert sorted(offsets.values()) == list(range(prm.size))    # every slot named, once
    for name, value in EXPECTED[tier].items():
        assert prm[offsets[name]] == pytest.approx(value, rel=1e-15), name


def test_kernels_read_their_parameters_by_name():
    """No kernel indexes its parameter array by a bare number (offsets: contfab.params)."""
    bare = re.compile(r"\bprm\[\s*[-+:0-9]")
    found = [f"{path.name}:{n}: {line.strip()}"
             for path in sorted(Path(models.__file__).parent.glob("*.py"))
             for n, line in enumerate(path.read_text().splitlines(), 1) if bare.search(line)]
    assert not found


def test_array_size_copy_and_moduli():
    p = Params.from_dict({"tier": 2, **DISTINCT})
    assert p.array(2).size == len(EXPECTED[2])
    a = p.array(1)
    a[params_module.BULK] = -1.0                     # a copy: the cached array is untouched
    assert p.array(1)[params_module.BULK] == pytest.approx(K_REG)
    # K, G are those of the 2D isotropic law: uniaxial stress gives Young's E and ratio nu
    c = np.array([[K_REG + G_REG, K_REG - G_REG], [K_REG - G_REG, K_REG + G_REG]])
    strain = np.linalg.solve(c, [1.0, 0.0])
    assert 1.0 / strain[0] == pytest.approx(E_REG) and -strain[1] / strain[0] == pytest.approx(0.25)


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
    ({"tier1.phi_star_deg": 7.5}, ["phi_star_deg = 7.5", "[8, 60]"]),
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
    ({"tier2.fabric_weight": 1.0}, ["fabric_weight = 1", "[0, 1)"]),
    ({"tier2.fabric_weight": -0.1}, ["fabric_weight = -0.1", "[0, 1)"]),
    ({"tier2.dilatancy_fabric": 12.0}, ["dilatancy_fabric = 12", "[0, 10]"]),
    ({"tier2.fabric_law": 0.5}, ["fabric_law = 0.5 is not a known law", "balance, relaxation"]),
    # the cone's radius sin φ - w b_c must stay positive down to φ_min (w b_c = 0.125)
    ({"tier1.phi_min_deg": 7.0, "tier1.phi_star_deg": 22.0},
     ["phi_min_deg = 7 leaves tier 2's cone empty", "phi_min_deg > 7.181", "w = 0.5",
      "b_ratio_crit = 0.25"]),
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
    assert p.replace("regularization", lam=1e6).array(0)[params_module.BULK] == pytest.approx(5e5)
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

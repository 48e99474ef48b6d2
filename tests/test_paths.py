"""The shared loading-path description: parsing, validation messages, semantics."""
import numpy as np
import pytest

from dem.paths import PathError, StopCondition, load_path, parse_path, standard_paths

STANDARD = ["axes_rotation", "biaxial", "direction_change", "isochoric_shear", "isotropic_compression",
            "proportional_strain", "shear_cycles", "simple_shear_reversal", "stress_probes"]


def test_standard_paths_ship_and_parse():
    assert standard_paths() == STANDARD
    for name in STANDARD:
        assert load_path(name).expand()


def test_direction_change_turns_the_compression_axis_by_90_degrees():
    y, x = load_path("direction_change").stages
    assert y.rate_vector.tolist() == [0.0, -1.0, 0.0, 0.0] and y.stress_controlled[0]
    assert x.rate_vector.tolist() == [-1.0, 0.0, 0.0, 0.0] and x.stress_controlled[1]
    assert x.stress_target(np.array([-1.0, -1.7, 0.0]), 0.0).tolist() == [-1.0, -1.0, 0.0]


def test_biaxial_controls():
    st = load_path("biaxial").stages[0]
    assert st.stress_controlled.tolist() == [True, False, False, False]
    assert st.rate_vector.tolist() == [0.0, -1.0, 0.0, 0.0]
    assert st.stress_target(np.array([-1.0, -2.0, 0.1]), 0.3).tolist() == [-1.0, -2.0, 0.1]


def test_ramp_is_linear_from_stage_start():
    st = load_path("isotropic_compression").stages[0]
    tgt = st.stress_target(np.array([-1.0, -1.0, 0.0]), 0.5)
    np.testing.assert_allclose(tgt, [-2.5, -2.5, 0.0], rtol=0, atol=1e-15)


def test_axes_rotation_keeps_p_and_r():
    st = load_path("axes_rotation").stages[1]
    assert st.stress_controlled.tolist() == [True, True, True, False]
    for s in np.linspace(0, 1, 7):
        sxx, syy, sxy = st.stress_target(np.zeros(3), s)
        assert -(sxx + syy) / 2 == pytest.approx(1.0, abs=1e-14)
        assert np.hypot((sxx - syy) / 2, sxy) == pytest.approx(0.3, abs=1e-14)
    # after 90 degrees the major compression has turned from y to x
    sxx, syy, _ = st.stress_target(np.zeros(3), 1.0)
    assert sxx == pytest.approx(-1.3) and syy == pytest.approx(-0.7)


def test_probe_family_is_a_circle():
    runs = load_path("stress_probes").expand()
    assert len(runs) == 16
    start = np.array([-0.8, -1.2, 0.0])
    ends = np.array([r.stages[0].stress_target(start, 1.0) for r in runs])
    np.testing.assert_allclose(np.hypot(*(ends[:, :2] - start[:2]).T), 0.02, rtol=1e-12)
    np.testing.assert_allclose(ends[:, 2], 0.0)


def test_stop_condition_crossing_either_way():
    up = StopCondition("gamma", 1.0)
    assert not up.reached(0.0, 0.99) and up.reached(0.0, 1.0) and up.reached(0.0, 1.2)
    down = StopCondition("gamma", -1.0)
    assert not down.reached(1.0, -0.5) and down.reached(1.0, -1.01)


@pytest.mark.parametrize("table, words", [
    ({"stage": [{"length": 1.0, "L": {"zz": 1.0}}]}, ["zz", "velocity-gradient component"]),
    ({"stage": [{"length": -1.0}]}, ["length = -1.0", "(0, inf)"]),
    ({"stage": [{"length": 1.0, "L": {"xx": 1.0}, "sigma": {"xx": -1.0}}]}, ["both"]),
    ({"stage": [{"length": 1.0, "sigma": {"xy": 0.0, "yx": 0.0}}]}, ["σxy"]),
    ({"stage": [{"length": 1.0, "sigma": {"xx": 2.0}}]}, ["target = 2.0", "tensile"]),
    ({"stage": [{"length": 1.0, "until": {"temperature": 3.0}}]}, ["temperature", "accepted"]),
    ({"stage": [{"length": 1.0, "rotation": {"P": 1.0, "R": 1.5, "from_deg": 0, "to_deg": 9}}]},
     ["R = 1.5", "[0, P)"]),
    ({"stage": [{"length": 1.0, "output_every": 2.0}]}, ["output_every = 2.0"]),
    ({}, ["at least one"]),
    ({"probes": {"directions": 4, "magnitude": 0.1, "length": 0.01, "unload": 1}},
     ["unload = 1", "true or false"]),
])
def test_bad_paths_name_the_value(table, words):
    with pytest.raises(PathError) as err:
        parse_path(table, "t.toml")
    for w in words:
        assert w in str(err.value)


def test_unknown_path_lists_the_standard_ones():
    with pytest.raises(PathError, match="biaxial"):
        load_path("no_such_path")


def test_probe_family_with_unloading_and_hold_reference():
    """Each probe ramps Δσ in and back out (Bardet's plastic residual), the last one holds."""
    fam = parse_path({"probes": {"directions": 4, "magnitude": 0.1, "length": 0.01,
                                 "unload": True, "hold": True}}, "p.toml").expand()
    assert [p.name.split("/")[1] for p in fam] == ["probe_000.0deg", "probe_090.0deg",
                                                    "probe_180.0deg", "probe_270.0deg", "probe_hold"]
    start = np.array([-1.0, -2.0, 0.1])
    for p, (dx, dy) in zip(fam, [(0.1, 0), (0, 0.1), (-0.1, 0), (0, -0.1), (0, 0)]):
        load, unload = p.stages
        assert load.stress_target(start, 1.0) == pytest.approx(start + [dx, dy, 0.0], abs=1e-15)
        assert load.stress_target(start, 0.5) == pytest.approx(start + [dx / 2, dy / 2, 0.0], abs=1e-15)
        end = load.stress_target(start, 1.0)
        assert unload.stress_target(end, 1.0) == pytest.approx(start, abs=1e-15)
        assert load.length == unload.length == 0.01

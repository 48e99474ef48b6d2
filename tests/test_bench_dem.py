"""The DEM benchmark's system definition matches the LAMMPS reference system."""
import math

from contfab.bench.dem import _dt_fraction, reference_system
from dem.contact_law import damping_ratio


def test_reference_system_and_its_time_step():
    s = reference_system()
    assert (s["n"], s["kappa"], s["mu"], s["kt_ratio"], s["radii"]) == (4000, 1e3, 0.5, 0.5, "uniform:0.2")
    # 0.05 t_c of a mean pair, in units of sqrt(m_min/kn): t_c ≈ π sqrt(m/2 / kn)/sqrt(1-β²)
    f = _dt_fraction(s)
    assert 0.1 < f < 0.2
    m_min = math.pi * 0.16
    assert math.isclose(f * math.sqrt(m_min), 0.05 * math.pi * math.sqrt(0.5 * math.pi * 0.25 * (1 + 0.04 / 3))
                        / math.sqrt(1 - damping_ratio(0.55) ** 2), rel_tol=1e-12)


def test_lammps_input_carries_the_reference_system(packing_frictional, tmp_path):
    import numpy as np

    from conftest import make_dynamics
    from contfab.bench.dem_lammps import commands, write_data
    from dem.contact_law import hooke_gamma_n, restitution

    st = packing_frictional.copy()
    st.h[1, 0] = 0.0
    dyn = make_dynamics(st, kappa=1e3, e=0.55, mu=0.5)
    cmds = commands(reference_system(), st, dyn, "x.data")
    pair = next(c for c in cmds if c.startswith("pair_style")).split()
    kn, kt, gamma_n, gamma_t, mu = map(float, pair[2:7])
    assert (kn, kt, gamma_t, mu) == (1e3, 500.0, 0.0, 0.5) and "limit_damping" in pair
    # a mean pair gets our damping ratio, hence the restitution e = 0.55
    m_eff = 0.5 * st.mass.mean()
    assert math.isclose(restitution(gamma_n / (2 * math.sqrt(kn / m_eff))), 0.55, rel_tol=1e-12)
    assert gamma_n == hooke_gamma_n(kn, dyn.law.beta, st.mass.mean())
    assert f"timestep {dyn.dt!r}" in cmds and f"neighbor {dyn.skin!r} bin" in cmds
    assert any(c.startswith("fix axial all deform 1 y erate -0.001") for c in cmds)
    f = tmp_path / "s.data"
    write_data(st, f)
    text = f.read_text().split("\n")
    atoms = np.array([[float(v) for v in line.split()] for line in
                      text[text.index("Atoms # sphere") + 2:text.index("Velocities") - 1]])
    assert np.allclose(atoms[:, 2], 2 * st.radius, rtol=0, atol=0)
    assert np.allclose(atoms[:, 4:6], st.s @ st.h.T, rtol=0, atol=0)


def test_lammps_missing_is_reported_with_the_reason(monkeypatch):
    import sys

    import pytest

    from contfab.bench.dem_lammps import LammpsUnavailable, lammps_class

    monkeypatch.setitem(sys.modules, "lammps", None)
    with pytest.raises(LammpsUnavailable, match="not importable.*contfab\\[bench\\]"):
        lammps_class()

"""The DEM benchmark's system definition matches the LAMMPS reference of issue 2."""
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

"""The stress servo: settles on a step of the target without ringing, holds it while shearing."""
import numpy as np

from conftest import make_dynamics
from dem.integrator import Control, advance, evaluate_forces
from dem.servo import servo_rate


def test_servo_law_is_pi_in_rate_space_with_cap_and_anti_windup():
    # integral on the whole contact-stress error, proportional on the spring-stress error
    rate, li = servo_rate(0.01, 0.03, 100.0, 0.0, 0.1, 1.0, 1.0)
    assert np.isclose(li, 0.1 * 0.01 / 100.0) and np.isclose(rate, li + 2 * 0.03 / 100.0)
    rate, li = servo_rate(10.0, 10.0, 1e-20, 0.3, 0.1, 1.0, 0.5)  # empty network: capped, frozen
    assert rate == 0.5 and li == 0.3


def test_step_in_target_settles_without_ringing(packing_frictional):
    st = packing_frictional.copy()
    dyn = make_dynamics(st, gdot=1e-3)
    evaluate_forces(st, dyn)
    target = np.array([-1.2, -1.2, 0.0])
    ctl = Control(np.zeros(4), np.array([True, True, False, False]), target, target)
    p = []
    for _ in range(400):
        advance(st, dyn, 10, ctl)
        p.append(-0.5 * (st.stress[0] + st.stress[1]))
    p = np.array(p)
    step = 0.2
    assert p.max() - 1.2 < 0.1 * step          # overshoot (measured 6% of the step)
    crossings = np.sum(np.diff(np.sign(p[20:] - 1.2 - 0.01 * step)) != 0)
    assert crossings == 0                       # no oscillation beyond 1% of the step
    assert abs(p[-100:].mean() - 1.2) < 1e-4 and p[-100:].std() < 1e-3


def test_lateral_stress_held_during_biaxial_compression(packing_frictional):
    st = packing_frictional.copy()
    dyn = make_dynamics(st, gdot=1e-3)
    evaluate_forces(st, dyn)
    ctl = Control(np.array([0.0, -1e-3, 0.0, 0.0]), np.array([True, False, False, False]),
                  np.array([-1.0, -1.0, 0.0]), np.array([-1.0, -1.0, 0.0]))
    sxx, syy = [], []
    for _ in range(100):                        # 2% axial strain
        advance(st, dyn, 90, ctl)
        sxx.append(st.stress[0])
        syy.append(st.stress[1])
    assert np.max(np.abs(np.array(sxx) + 1.0)) < 0.01
    assert np.min(syy) < -1.3                   # the axial stress did build up

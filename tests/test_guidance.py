"""controller_fmu.guidance and plant_model.remus100.setpoint_autopilot: the reference
velocity against scipy's exact discretisation, the set-point geometry against hand cases
and finite differences, the autopilot against the REMUS 100's own loops, anti-windup."""
from __future__ import annotations

import math
import re

import numpy as np
import pytest
from scipy.signal import cont2discrete

from controller_fmu.guidance import (
    check_mass_damping,
    depth_increment,
    reference_rate,
    reference_step,
    setpoints,
)
from plant_model.remus100.autopilot import AutopilotGains, autopilot_command
from plant_model.remus100.dynamics import STATE_SIZE
from plant_model.remus100.setpoint_autopilot import DepthLoop, limit_command, setpoint_command

M = np.array([31.9, 31.9, 60.5])
D = np.array([10.8, 10.8, 3.0])


def test_the_reference_step_and_the_depth_are_scipys_zero_order_hold():
    """Per axis [v; z]' = [[-D/M, 0], [1, 0]] [v; z] + [1/M; 0] u, sampled by scipy
    (zero-order hold): the new velocity and the depth increment to 1e-12."""
    rng = np.random.default_rng(1)
    for h in (0.01, 0.05, 0.7, 5.0):
        v, u = rng.normal(0, 1, 3), rng.normal(0, 20, 3)
        ours = reference_step(v, u, M, D, h)
        for i in range(3):
            A = np.array([[-D[i] / M[i], 0.0], [1.0, 0.0]])
            B = np.array([[1.0 / M[i]], [0.0]])
            Ad, Bd, *_ = cont2discrete((A, B, np.eye(2), np.zeros((2, 1))), h, "zoh")
            ref = Ad @ np.array([v[i], 0.0]) + Bd[:, 0] * u[i]
            assert ours[i] == pytest.approx(ref[0], rel=1e-12, abs=1e-12)
            dz = depth_increment(v[i], u[i], M[i], D[i], h)
            assert dz == pytest.approx(ref[1], rel=1e-10, abs=1e-12)


def test_the_set_points_of_hand_cases():
    U_min = 0.1
    sp = setpoints(np.array([1.0, 1.0, 0.0]), D * np.array([1.0, 1.0, 0.0]), M, D, 20.0,
                   0.3, U_min)          # u = D v: v' = 0, every rate 0
    assert sp == pytest.approx([math.sqrt(2), math.pi / 4, 20.0, 0.0, 0.0, 0.0], abs=1e-15)
    sp = setpoints(np.array([0.0, -2.0, 0.5]), np.zeros(3), M, D, 3.0, 0.3, U_min)
    assert sp[1] == pytest.approx(-math.pi / 2) and sp[5] == 0.5 and sp[2] == 3.0
    # straight down: the course is not defined, the held course is given, its rate is 0
    sp = setpoints(np.array([0.0, 0.05, 0.5]), np.array([5.0, 5.0, 0.0]), M, D, 3.0, 0.3,
                   U_min)
    assert sp[1] == 0.3 and sp[4] == 0.0 and sp[0] == pytest.approx(math.hypot(0.05, 0.5))


def test_the_rates_are_the_derivatives_of_the_set_points():
    """Central differences of speed, course and depth along the exact trajectory."""
    rng = np.random.default_rng(7)
    v, u = np.array([1.2, -0.7, 0.2]), rng.normal(0, 15, 3)
    eps = 1e-5
    plus = setpoints(reference_step(v, u, M, D, eps), u, M, D,
                     depth_increment(v[2], u[2], M[2], D[2], eps), 0.0, 0.1)
    minus = setpoints(reference_step(v, u, M, D, -eps), u, M, D,
                      depth_increment(v[2], u[2], M[2], D[2], -eps), 0.0, 0.1)
    rate = (plus[:3] - minus[:3]) / (2 * eps)
    sp = setpoints(v, u, M, D, 0.0, 0.0, 0.1)
    assert sp[3:] == pytest.approx(rate, rel=1e-7)
    assert reference_rate(v, u, M, D) == pytest.approx((u - D * v) / M)


@pytest.mark.parametrize("M_, D_, bad", [([1, 0, 1], [1, 1, 1], "M[2]"),
                                         ([1, 1, 1], [1, 1, -3], "D[3]"),
                                         ([1, 1, np.nan], [1, 1, 1], "M[3]")])
def test_mass_and_damping_must_be_positive(M_, D_, bad):
    with pytest.raises(ValueError, match=re.escape(bad)):
        check_mass_damping(np.array(M_, float), np.array(D_, float))


def _state(rng: np.random.Generator) -> np.ndarray:
    x = np.zeros(STATE_SIZE)
    x[:3] = rng.normal(0, 10, 3)
    x[3:6] = [rng.normal(0, 0.1), rng.normal(0, 0.15), rng.uniform(-math.pi, math.pi)]
    x[6:9] = [rng.uniform(0.8, 2.2), rng.normal(0, 0.1), rng.normal(0, 0.1)]
    x[9:12] = rng.normal(0, 0.05, 3)
    return x


def test_without_depth_loop_and_course_rate_it_is_the_remus_loops():
    """K_z = 0, chi_d' = 0 and no flight-path limit: equal to autopilot_command for the
    reference velocity of the same speed, course and flight path (200 random states and
    references, steep ones included; 1e-12)."""
    rng = np.random.default_rng(3)
    g, dl = AutopilotGains(), DepthLoop(K_z=0.0, gamma_max=math.pi / 2)
    worst = 0.0
    for _ in range(200):
        x, integ = _state(rng), rng.normal(0, 0.3, 2)
        v_ref = np.array([rng.uniform(-2, 2), rng.uniform(-2, 2), rng.normal(0, 0.2)])
        ref_cmd, ref_err = autopilot_command(g, x, v_ref, integ)
        sp = [np.linalg.norm(v_ref), math.atan2(v_ref[1], v_ref[0]), 0.0, 0.0, 0.0, v_ref[2]]
        cmd, err = setpoint_command(g, dl, np.array(sp), x[6:9], x[3:6], x[9:12], x[2], integ)
        worst = max(worst, np.abs(cmd - ref_cmd).max(), np.abs(err - ref_err).max())
    assert worst < 1e-12


def test_the_depth_loop_climbs_when_too_deep_and_the_course_rate_feeds_the_rudder():
    g = AutopilotGains()
    level = dict(velocity=np.array([1.5, 0, 0]), attitude=np.zeros(3), rates=np.zeros(3))
    sp = np.array([1.5, 0.0, 20.0, 0.0, 0.0, 0.0])
    deep, _ = setpoint_command(g, DepthLoop(), sp, depth=25.0, integrals=np.zeros(2), **level)
    shallow, _ = setpoint_command(g, DepthLoop(), sp, depth=15.0, integrals=np.zeros(2), **level)
    assert deep[1] < 0.0 < shallow[1]        # too deep: stern plane up (nose up), and back
    # 5 m too deep at K_z = 0.1: w_d = -0.5 m/s, gamma_d = atan(0.5/1.5); delta_s = -K_theta
    # (1 + K_gamma) gamma_d with theta = gamma = 0
    assert deep[1] == pytest.approx(-g.K_theta * (1 + g.K_gamma) * math.atan2(0.5, 1.5))
    turning = sp.copy()
    turning[4] = 0.1
    cmd, _ = setpoint_command(g, DepthLoop(), turning, depth=20.0, integrals=np.zeros(2),
                              **level)
    assert cmd[0] == pytest.approx(g.K_r * 0.1)


def test_an_integral_holds_while_its_actuator_is_saturated():
    """Speed set far above what n_max gives: the rpm command is beyond n_max and the speed
    integral's error is 0; a dive the stern planes cannot give: the flight-path error is 0.
    Within the limits both integrate."""
    g, dl = AutopilotGains(), DepthLoop()
    level = dict(velocity=np.array([1.5, 0, 0]), attitude=np.zeros(3), rates=np.zeros(3),
                 depth=20.0, integrals=np.zeros(2))
    cmd, err = setpoint_command(g, dl, np.array([6.0, 0, 20.0, 0, 0, 0]), **level)
    assert cmd[2] > g.n_max and err[0] == 0.0
    cmd, err = setpoint_command(g, dl, np.array([1.6, 0, 20.0, 0, 0, 0]), **level)
    assert abs(cmd[2]) < g.n_max and err[0] == pytest.approx(0.1)
    # diving steeply (theta = -0.5 rad) towards a depth 20 m below, nose pitching up fast:
    # the stern plane is beyond +delta_max (nose down) and the error asks for more dive
    diving = dict(level, attitude=np.array([0.0, -0.5, 0.0]))
    deeper = np.array([1.5, 0, 40.0, 0, 0, 0.0])
    cmd, err = setpoint_command(g, dl, deeper, **dict(diving, rates=np.array([0, 0.6, 0])))
    assert cmd[1] >= g.delta_max and err[1] == 0.0
    cmd, err = setpoint_command(g, dl, deeper, **dict(diving, rates=np.zeros(3)))
    assert abs(cmd[1]) < g.delta_max and err[1] < -0.01
    limited, sat = limit_command(g, np.array([1.0, -1.0, 3000.0]))
    assert sat and limited == pytest.approx([g.delta_max, -g.delta_max, g.n_max])
    assert limit_command(g, np.array([0.1, 0.0, 1000.0])) == (pytest.approx([0.1, 0, 1000]),
                                                              False)

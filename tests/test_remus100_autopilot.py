"""plant_model.remus100.autopilot on the nonlinear REMUS 100: a commanded NED velocity over
ground is reached and held, turned to, held across a current, and climbed or dived."""
from __future__ import annotations

import numpy as np
import pytest

from plant_model.remus100.autopilot import (
    AutopilotGains,
    ForceCommandedRemus,
    autopilot_command,
    wrap,
)
from plant_model.remus100.dynamics import STATE_SIZE, Remus100, step
from plant_model.remus100.rigid_body import rotation_ned_body


def _run(vehicle, v_ref, T=120.0, h=0.1):
    g, x, integ = AutopilotGains(), np.zeros(STATE_SIZE), np.zeros(2)
    rows = []
    for k in range(round(T / h)):
        cmd, err = autopilot_command(g, x, v_ref(k * h), integ)
        integ = integ + err * h
        x = step(vehicle, x, cmd, h, 1)
        rows.append(np.r_[x[:3], rotation_ned_body(*x[3:6]) @ x[6:9], cmd])
    return np.array(rows)


def test_a_velocity_north_is_reached_and_held_level():
    out = _run(Remus100(), lambda t: np.array([1.5, 0.0, 0.0]))
    assert np.allclose(out[-1, 3:6], [1.5, 0.0, 0.0], atol=0.01)
    assert np.abs(out[:, 2]).max() < 0.2                   # depth held within 20 cm


def test_a_new_course_is_turned_to_with_saturated_fins():
    """North, then east at 40 s: the vehicle turns and settles on east; the commanded
    rudder exceeds the 15 deg limit in the turn, which the actuator clips."""
    out = _run(Remus100(), lambda t: np.array([1.5, 0, 0]) if t < 40 else np.array([0, 1.5, 0]))
    assert np.allclose(out[-1, 3:6], [0.0, 1.5, 0.0], atol=0.01)
    assert np.abs(out[:, 6]).max() > Remus100().delta_max


def test_the_course_is_held_across_a_current_by_crabbing():
    """A 0.3 m/s current from the west: the ground velocity stays north (the heading turns
    into the current), the cross-track offset stays under a metre."""
    out = _run(Remus100(current=(0.0, 0.3, 0.0)), lambda t: np.array([1.5, 0.0, 0.0]))
    assert abs(out[-1, 4]) < 0.01 and out[-1, 3] == pytest.approx(1.5, abs=0.01)
    assert np.abs(out[:, 1]).max() < 1.0


def test_a_descent_rate_is_reached_by_the_flight_path_loop():
    out = _run(Remus100(), lambda t: np.array([1.5, 0.0, 0.2]))
    assert out[-1, 5] == pytest.approx(0.2, abs=0.01)


def test_wrap_keeps_angles_within_one_turn():
    assert wrap(3 * np.pi / 2) == pytest.approx(-np.pi / 2)
    assert wrap(-3 * np.pi / 2) == pytest.approx(np.pi / 2)


def test_the_force_commanded_vehicle_follows_the_linear_model():
    """The NED force that holds the linear remus100 at 1.5 m/s north (F = D_a 1.5), then a
    force step east at 20 s: the nonlinear vehicle settles on the linear model's velocity
    over ground (within 0.03 m/s from 50 s on), also in a 0.2 m/s current from the east
    that carries both alike. In the turn it lags: the linear model's 3 s time constant is
    faster than a torpedo turns 28 deg (about 0.5 m/s apart at the peak)."""
    from scipy.signal import StateSpace, lsim

    from plant_model.vehicles import remus100
    lin = remus100(cruise_speed=1.5)
    M, D = np.array(lin.parameters["total_mass"]), np.array(lin.parameters["damping"])
    for current in ((0.0, 0.0, 0.0), (0.0, -0.2, 0.0)):
        x0 = np.zeros(STATE_SIZE)
        x0[6], x0[14] = 1.5, 1525.0 * 1.5 / 2.55
        v = ForceCommandedRemus(Remus100(current=current), M, D, x0)
        h, T = 0.1, 120.0
        t = np.arange(0.0, T, h)
        F = np.zeros((t.size, 3))
        F[:, 0] = D[0] * 1.5
        F[t >= 20.0, 1] = D[1] * 0.8
        ned = []
        for k in range(t.size):
            ned.append(v.ned_state)
            v.step(F[k], h, 1)
        ned = np.array(ned)
        w = np.tile(current, (t.size, 1))
        sys = StateSpace(lin.A, np.hstack([lin.B1, lin.B2]), np.eye(6), np.zeros((6, 6)))
        x_lin0 = np.r_[0, 0, 0, 1.5, 0, 0]                 # the same start over ground
        _, y, _ = lsim(sys, np.hstack([F, w]), t, X0=x_lin0)
        gap = np.abs(ned[:, 3:5] - y[:, 3:5])
        assert gap[t >= 50.0].max() < 0.03 and 0.1 < gap.max() < 0.6, current
        assert ned[-1, 4] == pytest.approx(0.8 + current[1], abs=0.03)

"""The compiled REMUS 100 kernel against the numpy definition, term by term and in closed
loop (plant_model.remus100.kernel, plant_model.remus100.dynamics, plant_model.remus100.autopilot)."""
from __future__ import annotations

import numpy as np
import pytest

from plant_model.remus100 import kernel
from plant_model.remus100.autopilot import AutopilotGains, ForceCommandedRemus
from plant_model.remus100.dynamics import Remus100, derivative
from plant_model.vehicles import remus100

CURRENT = np.array([0.2, -0.15, 0.03])


def _states(count: int, seed: int = 3) -> np.ndarray:
    """Random states over the flight envelope: reverse and saturated actuators included."""
    rng = np.random.default_rng(seed)
    x = np.zeros((count, 15))
    x[:, :3] = rng.normal(scale=20.0, size=(count, 3))
    x[:, 3:6] = rng.uniform([-0.5, -0.6, -np.pi], [0.5, 0.6, np.pi], size=(count, 3))
    x[:, 6:9] = rng.normal([1.5, 0.0, 0.0], [0.8, 0.4, 0.3], size=(count, 3))
    x[:, 9:12] = rng.normal(scale=0.3, size=(count, 3))
    x[:, 12:14] = rng.uniform(-0.7, 0.7, size=(count, 2))        # beyond the 0.52 rad limit
    x[:, 14] = rng.uniform(-1700.0, 1700.0, size=count)
    return x


@pytest.mark.parametrize("current", [np.zeros(3), CURRENT])
def test_the_kernel_derivative_is_the_numpy_definition(current):
    v = Remus100(current=tuple(current))
    p = kernel.pack(v)
    rng = np.random.default_rng(5)
    out = np.empty(15)
    worst = 0.0
    for x in _states(200):
        cmd = rng.uniform([-0.8, -0.8, -1800.0], [0.8, 0.8, 1800.0])
        ref = derivative(v, x, cmd)
        kernel.derivative(p, x, cmd, current, out)
        worst = max(worst, float(np.max(np.abs(out - ref) / np.maximum(1.0, np.abs(ref)))))
        plain = np.empty(15)
        getattr(kernel.derivative, "py_func", kernel.derivative)(p, x, cmd, current, plain)
        assert np.allclose(plain, ref, rtol=1e-12, atol=1e-12)
    assert worst < 1e-12


def test_the_kernel_step_is_the_force_commanded_vehicle():
    """600 steps of 0.1 s with a varying force, turning and diving: the same state."""
    v = Remus100(current=tuple(CURRENT))
    lin = remus100(cruise_speed=1.5).parameters
    M, D = np.array(lin["total_mass"]), np.array(lin["damping"])
    x0 = np.zeros(15)
    x0[[2, 6, 14]] = 20.0, 1.5, 900.0
    ref = ForceCommandedRemus(v, M, D, x0)
    p, g = kernel.pack(v), kernel.pack_gains(AutopilotGains())
    x, v_ref, integ, cmd = x0.copy(), ref.v_ref.copy(), np.zeros(2), np.zeros(3)
    saturated = 0
    for k in range(600):
        F = np.array([25.0 * np.cos(0.02 * k), 30.0 * np.sin(0.05 * k), 3.0 * np.sin(0.01 * k)])
        ref.step(F, 0.1, 2)
        kernel.force_commanded_step(p, g, x, v_ref, integ, F, CURRENT, M, D, 0.1, 2, cmd)
        assert np.allclose(cmd, ref.command, rtol=1e-10, atol=1e-10)
        saturated += bool(np.abs(cmd[0]) >= v.delta_max or cmd[2] >= v.n_max)
    assert np.max(np.abs(x - ref.x)) < 1e-9
    assert np.allclose(v_ref, ref.v_ref, rtol=1e-12) and np.allclose(integ, ref.integrals)
    assert saturated > 10                     # the anti-windup branches were exercised
    assert np.linalg.norm(x[:2]) > 50.0       # it went somewhere


def test_the_speed_integral_holds_while_the_propeller_is_saturated():
    """Anti-windup: asking for 4 m/s (beyond 2.55) leaves the speed integral unchanged."""
    v = Remus100()
    g = kernel.pack_gains(AutopilotGains())
    x = np.zeros(15)
    x[6], x[14] = 2.0, 1525.0
    cmd, err = np.zeros(3), np.zeros(2)
    kernel.autopilot(g, x, np.array([4.0, 0.0, 0.0]), np.zeros(2), np.zeros(3), cmd, err)
    assert cmd[2] > v.n_max and err[0] == 0.0
    kernel.autopilot(g, x, np.array([1.0, 0.0, 0.0]), np.zeros(2), np.zeros(3), cmd, err)
    assert err[0] == pytest.approx(-1.0)

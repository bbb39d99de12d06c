"""The REMUS navigation sensors (plant_model.navigation): schedule, noise, dropouts, state."""
from __future__ import annotations

import numpy as np
import pytest

from plant_model.linalg_checks import ModelError
from plant_model.navigation import NavigationSensors, SensorStream


def _run(sensors, steps, seed=1, vehicle=2):
    stream = SensorStream(sensors, 0.01, seed, vehicle)
    p, v = np.array([10.0, -5.0, 20.0]), np.array([1.5, 0.2, -0.1])
    return np.array([stream.measure(k, p, v).copy() for k in range(steps)]), p, v


def test_reports_come_on_schedule_with_their_noise_and_dropouts():
    s = NavigationSensors(fix_period=2.0, fix_sigma=1.0, fix_dropout=0.25, dvl_period=0.2,
                          dvl_sigma=0.02, dvl_dropout=0.0, depth_period=0.1, depth_sigma=0.05)
    out, p, v = _run(s, 200_000)
    k = np.arange(len(out))
    valid = out[:, 7:10] > 0.5
    assert not valid[k % 20 != 0, 1].any() and valid[k % 20 == 0, 1].all()   # DVL, 5 Hz
    assert valid[k % 10 == 0, 2].all() and not valid[k % 10 != 0, 2].any()   # depth, 10 Hz
    fixes = valid[k % 200 == 0, 0]
    n, drop = fixes.size, 1.0 - fixes.mean()
    assert abs(drop - 0.25) < 5 * np.sqrt(0.25 * 0.75 / n)                   # binomial
    assert not valid[k % 200 != 0, 0].any()
    f = out[valid[:, 0], 0:3] - p
    assert np.std(f) == pytest.approx(1.0, rel=0.1) and abs(np.mean(f)) < 0.2
    d = out[valid[:, 1], 3:6] - v
    assert np.std(d) == pytest.approx(0.02, rel=0.05)
    z = out[valid[:, 2], 6] - p[2]
    assert np.std(z) == pytest.approx(0.05, rel=0.05)
    # between reports the last value is held
    held = np.flatnonzero(~valid[:, 0])
    held = held[held > 0]
    assert np.array_equal(out[held, 0:3], out[held - 1, 0:3])


def test_the_same_seed_gives_the_same_reports_and_the_state_round_trips():
    s = NavigationSensors()
    a, _, _ = _run(s, 3000)
    b, _, _ = _run(s, 3000)
    c, _, _ = _run(s, 3000, vehicle=3)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    stream = SensorStream(s, 0.01, 1, 2)
    p, v = np.zeros(3), np.ones(3)
    for k in range(1500):
        stream.measure(k, p, v)
    state = stream.get_state()
    first = [stream.measure(k, p, v).copy() for k in range(1500, 2500)]
    stream.set_state(state)
    assert np.array_equal(first, [stream.measure(k, p, v).copy() for k in range(1500, 2500)])


@pytest.mark.parametrize("table, fragment", [
    ({"fix_period": -2.0}, "fix_period = -2 must be positive"),
    ({"dvl_dropout": 1.0}, "dvl_dropout = 1 must be in [0, 1)"),
    ({"depth_sigma": float("nan")}, "depth_sigma = nan is not a finite number"),
    ({"gps_period": 1.0}, "unknown key(s) gps_period"),
])
def test_bad_sensor_data_is_one_line_naming_the_key(table, fragment):
    with pytest.raises(ModelError) as exc:
        NavigationSensors.from_mapping(table)
    assert fragment in str(exc.value) and str(exc.value).startswith("[sensors] ")


def test_a_period_that_is_not_a_whole_number_of_steps_is_refused():
    with pytest.raises(ModelError, match=r"dvl_period = 0.015 s is not a whole number of "
                                         r"steps h = 0.01 s"):
        NavigationSensors(dvl_period=0.015).steps(0.01)

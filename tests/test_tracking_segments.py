"""Straight legs, turns and saturation (orchestrator.analysis.tracking_segments)."""
from __future__ import annotations

import numpy as np
import pytest

from orchestrator.analysis.tracking_segments import (
    leader_turn_rate,
    segment_stats,
    segment_summary,
)
from plant_model.leader import circle, straight


def _states(path, times):
    from scipy.linalg import expm
    return np.array([expm(path.F * t) @ path.z0 for t in times])


def test_the_turn_rate_of_a_circle_is_speed_over_radius_and_of_a_line_zero():
    t = np.linspace(0.0, 60.0, 31)
    c = circle(radius=40.0, speed=2.0)
    rate = leader_turn_rate(_states(c, t), c.F, c.H)
    assert np.allclose(np.abs(rate), 2.0 / 40.0, rtol=1e-9)
    s = straight(1.5, heading_deg=30.0)
    assert np.allclose(leader_turn_rate(_states(s, t), s.F, s.H), 0.0, atol=1e-15)


def test_errors_split_by_turns_in_the_window_only():
    K, N = 10, 2
    e = np.zeros((K, 3 * N))
    e[:, 0] = np.arange(K)            # vehicle 1: |e| = k along north
    e[:, 4] = 3.0                     # vehicle 2: 3 m east, always
    e[0, 0] = 100.0                   # before the window: ignored
    turning = np.zeros(K, bool)
    turning[6:8] = True
    sat = np.zeros((K, N))
    sat[5:, 1] = 1.0
    st = segment_stats(e, turning, 4, sat)
    assert st["max_error"] == 9.0 and st["max_error_turns"] == 7.0
    assert st["max_error_straight"] == 9.0
    straight_vals = np.array([4, 5, 8, 9, 3, 3, 3, 3], float)
    assert st["rms_error_straight"] == pytest.approx(np.sqrt(np.mean(straight_vals ** 2)))
    assert st["rms_error_turns"] == pytest.approx(np.sqrt(np.mean([36, 49, 9, 9])))
    assert st["turn_fraction"] == pytest.approx(2 / 6)
    assert st["actuator_saturation_fraction"] == pytest.approx(5 / 12)
    assert st["actuator_saturation_fraction_per_vehicle"] == [0.0, pytest.approx(5 / 6)]
    lin = segment_stats(e, np.zeros(K, bool), 4)
    assert lin["actuator_saturation_fraction"] is None and lin["max_error_turns"] is None
    both = segment_summary([st, {**st, "max_error": 12.0, "rms_error_turns": 1.0}])
    assert both["max_error"] == 12.0
    assert both["rms_error_turns"] == pytest.approx(np.sqrt((st["rms_error_turns"] ** 2 + 1) / 2))

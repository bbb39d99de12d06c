"""orchestrator.analysis.remus_response: the nonlinear REMUS behind the force interface
against the linear remus100, by frequency."""
from __future__ import annotations

import math

import pytest

from orchestrator.analysis.remus_response import force_frequency_response


@pytest.mark.slow
@pytest.mark.parametrize("axis", [0, 1, 2])
def test_at_low_frequency_the_nonlinear_vehicle_responds_like_the_linear_model(axis):
    """At 0.05 rad/s (a 2-minute period) around 1.5 m/s north, the velocity per force
    agrees with 1 / (M_a j w + D_a) within 10 % in gain and 10 deg in phase on the
    along-track, cross-track and vertical axes; at 0.5 rad/s the torpedo lags by more than
    30 deg on every axis (its turns and pitch changes take time)."""
    low, high = force_frequency_response(axis, [0.05, 0.5], h=0.2)   # the 0.1 s figures +-3 deg
    assert low["gain_ratio"] == pytest.approx(1.0, abs=0.1)
    assert abs(low["phase_difference"]) < math.radians(10)
    assert high["phase_difference"] < -math.radians(30)

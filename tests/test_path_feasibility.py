"""plant_model.path_feasibility with a current and the controller's margin: the speed
through the water against a 2-sigma head current, and the rudder's lateral acceleration at
the slowest speed through the water (closed forms on a straight line and a circle)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from plant_model.leader_paths import make_leader
from plant_model.path_feasibility import path_findings

LIMITS = [SimpleNamespace(max_speed=2.5, min_turn_radius=20.0, max_depth_rate=1.0, source="x")]


def _path(kind, **kw):
    p = make_leader(kind, {"start": [0, 0, 20], **kw} if kind == "straight" else
                    {"center": [0, 0, 20], **kw})
    return p.F, p.H, p.z0


@pytest.mark.parametrize("sigma, findings", [(0.0, []), (0.2, []), (0.3, ["speed"])])
def test_the_top_speed_must_cover_the_path_against_a_two_sigma_current(sigma, findings):
    """2 m/s straight: 2 + 2 sigma against 2.5 m/s (sigma 0.3 exceeds it: 2.6 m/s)."""
    f = path_findings(*_path("straight", speed=2.0), 50.0, LIMITS, current_sigma=sigma)
    assert [x.limit for x in f] == findings
    if f:
        assert f[0].value == pytest.approx(2.6) and f[0].bound == 2.5


def test_steering_needs_the_path_s_and_the_controller_s_lateral_acceleration():
    """A 100 m circle at 2 m/s: it needs 2^2/100 = 0.04 m/s^2 plus the margin; at full
    rudder the vehicle gives (2 - 2 sigma)^2 / 20 m. sigma 0.1: 0.162, so a margin of
    0.1 fits and 0.15 does not (the finding gives need and bound at the worst sample)."""
    F, H, z0 = _path("circle", radius=100.0, speed=2.0)
    ok = path_findings(F, H, z0, 60.0, LIMITS, current_sigma=0.1, lateral_margin=0.1)
    assert ok == []
    (f,) = path_findings(F, H, z0, 60.0, LIMITS, current_sigma=0.1, lateral_margin=0.15)
    assert f.limit == "steering" and f.fraction == 1.0
    assert f.value == pytest.approx(0.04 + 0.15, rel=1e-6)
    assert f.bound == pytest.approx(1.8 ** 2 / 20.0, rel=1e-6)


def test_without_current_or_margin_the_steering_check_is_the_turn_radius_check():
    """sigma = 0, margin 0: a 15 m circle is refused once, as a turn radius."""
    F, H, z0 = _path("circle", radius=15.0, speed=1.0)
    f = path_findings(F, H, z0, 30.0, LIMITS)
    assert [x.limit for x in f] == ["turn radius"] and np.isclose(f[0].value, 15.0)

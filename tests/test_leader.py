"""plant_model.leader: closed forms of the leader paths, lawnmower accuracy, errors."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from plant_model.leader import (
    circle,
    explicit,
    lawnmower,
    lawnmower_turn_error,
    straight,
)
from plant_model.leader_paths import LEADER_PATHS, make_leader
from plant_model.linalg_checks import ModelError

T_GRID = np.linspace(0.0, 200.0, 41)


# straight ---------------------------------------------------------------------------
def test_straight_matches_closed_form():
    path = straight(1.5, heading_deg=30.0, start=(10.0, -4.0, 20.0), climb_rate=-0.2)
    expected = np.column_stack([
        10.0 + 1.5 * math.cos(math.radians(30.0)) * T_GRID,
        -4.0 + 1.5 * math.sin(math.radians(30.0)) * T_GRID,
        20.0 - 0.2 * T_GRID,
    ])
    np.testing.assert_allclose(path.position(T_GRID), expected, rtol=0, atol=1e-9)
    np.testing.assert_allclose(path.velocity_matrix() @ path.z0,
                               [1.5 * math.cos(math.pi / 6), 0.75, -0.2], atol=1e-15)


def test_straight_heading_90_moves_east():
    pos = straight(2.0, heading_deg=90.0).position(np.array([0.0, 10.0]))
    np.testing.assert_allclose(pos, [[0.0, 0.0, 0.0], [0.0, 20.0, 0.0]], atol=1e-12)


def test_straight_positive_climb_rate_descends():
    assert straight(0.0, climb_rate=0.5).position(4.0)[0, 2] == pytest.approx(2.0, abs=1e-12)


# circle -----------------------------------------------------------------------------
@pytest.mark.parametrize("clockwise", [True, False])
def test_circle_matches_closed_form(clockwise):
    R, v, th0 = 25.0, 1.8, math.radians(40.0)
    path = circle(R, v, center=(3.0, -7.0, 15.0), clockwise=clockwise, start_angle_deg=40.0)
    om = v / R if clockwise else -v / R
    th = th0 + om * T_GRID
    expected = np.column_stack([3.0 + R * np.cos(th), -7.0 + R * np.sin(th),
                                np.full_like(T_GRID, 15.0)])
    np.testing.assert_allclose(path.position(T_GRID), expected, rtol=0, atol=1e-9)


def test_circle_clockwise_from_north_heads_east():
    """Seen from above in NED (north up, east right), clockwise from due north goes east."""
    v_cw = circle(10.0, 1.0).velocity(0.0)[0]
    v_ccw = circle(10.0, 1.0, clockwise=False).velocity(0.0)[0]
    np.testing.assert_allclose(v_cw, [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(v_ccw, [0.0, -1.0, 0.0], atol=1e-15)


@settings(derandomize=True, max_examples=30, deadline=None)
@given(R=st.floats(0.5, 500.0), v=st.floats(0.0, 3.0), th=st.floats(-360.0, 360.0),
       cw=st.booleans())
def test_circle_speed_is_constant(R, v, th, cw):
    path = circle(R, v, clockwise=cw, start_angle_deg=th)
    speeds = np.linalg.norm(path.velocity(np.linspace(0.0, 300.0, 7)), axis=1)
    np.testing.assert_allclose(speeds, v, rtol=1e-9, atol=1e-12)


def test_circle_eigenvalues_are_zero_and_plus_minus_i_omega():
    eig = np.sort_complex(np.linalg.eigvals(circle(4.0, 2.0).F))
    np.testing.assert_allclose(eig, [-0.5j, 0, 0, 0, 0.5j], atol=1e-15)


# lawnmower --------------------------------------------------------------------------
@pytest.mark.parametrize("h", [1, 2, 3, 6])
def test_lawnmower_waypoints(h):
    """Mid-leg points are exact; at turns east is the middle of the step and north misses
    the leg end by exactly lawnmower_turn_error(L, h)."""
    Lg, sp, v = 100.0, 20.0, 2.0
    n0, e0, d0 = 5.0, -3.0, 12.0
    Tl = Lg / v
    path = lawnmower(Lg, sp, v, harmonics=h, start=(n0, e0, d0))
    k = np.arange(6)
    mid = path.position((k + 0.5) * Tl)
    np.testing.assert_allclose(mid[:, 0], n0 + Lg / 2, atol=1e-9)
    np.testing.assert_allclose(mid[:, 1], e0 + sp * k, atol=1e-9)
    np.testing.assert_allclose(mid[:, 2], d0, atol=1e-12)
    turn = path.position(k * Tl)
    err = lawnmower_turn_error(Lg, h)
    leg_end = np.where(k % 2 == 0, n0, n0 + Lg)     # north end where turn k happens
    inward = np.where(k % 2 == 0, 1.0, -1.0)        # the rounded turn falls short, inwards
    np.testing.assert_allclose(turn[:, 0], leg_end + inward * err, atol=1e-9)
    np.testing.assert_allclose(turn[:, 1], e0 + sp * (k - 0.5), atol=1e-9)


def test_lawnmower_turn_error_by_hand():
    # h = 1: 4L/pi^2 (pi^2/8 - 1) = L (1/2 - 4/pi^2) = 0.0947 L
    assert lawnmower_turn_error(1.0, 1) == pytest.approx(0.5 - 4 / math.pi**2, rel=1e-12)
    # h = 3: 0.5 - 4/pi^2 (1 + 1/9 + 1/25) = 0.03347 L
    assert lawnmower_turn_error(100.0, 3) == pytest.approx(3.3472, abs=1e-4)
    assert lawnmower_turn_error(1.0, 10) < lawnmower_turn_error(1.0, 3)


def test_lawnmower_average_east_speed_and_depth_default():
    Lg, sp, v = 60.0, 8.0, 1.5
    Tl = Lg / v
    path = lawnmower(Lg, sp, v, harmonics=4, start=(0.0, 0.0, 30.0))
    t = np.array([0.0, 3.7, 11.0])
    gain = path.position(t + 2 * Tl)[:, 1] - path.position(t)[:, 1]
    np.testing.assert_allclose(gain / (2 * Tl), sp / Tl, rtol=1e-10)
    np.testing.assert_allclose(path.position(t)[:, 2], 30.0, atol=1e-12)
    assert lawnmower(Lg, sp, v, start=(0, 0, 30.0), depth=5.0).position(1.0)[0, 2] == \
        pytest.approx(5.0)


def test_lawnmower_state_order_and_spectrum():
    h = 3
    path = lawnmower(100.0, 20.0, 2.0, harmonics=h)
    assert path.state_names == ("n0", "e_ramp", "d", "v_e", "nc_1", "ns_1", "nc_3", "ns_3",
                                "nc_5", "ns_5", "ec_1", "es_1", "ec_2", "es_2", "ec_3", "es_3")
    assert path.z0[3] == pytest.approx(20.0 / 50.0)         # v_e = spacing / T_leg
    eig = np.linalg.eigvals(path.F)
    np.testing.assert_allclose(eig.real, 0.0, atol=1e-12)
    w0 = math.pi / 50.0
    freqs = np.sort(eig.imag[eig.imag > 1e-9])
    np.testing.assert_allclose(freqs, w0 * np.array([1, 2, 3, 4, 5, 6]), rtol=1e-12)


def test_lawnmower_north_stays_near_the_legs():
    """The truncated triangle wave stays within the turn error of [start_n, start_n + L]."""
    Lg, h = 50.0, 3
    path = lawnmower(Lg, 10.0, 1.0, harmonics=h)
    north = path.position(np.linspace(0.0, 200.0, 801))[:, 0]
    err = lawnmower_turn_error(Lg, h)
    assert north.min() >= err - 1e-9 and north.max() <= Lg - err + 1e-9


# explicit ---------------------------------------------------------------------------
def test_explicit_oscillator_closed_form():
    path = explicit([[0.0, 1.0], [-4.0, 0.0]], [[1.0, 0.0]], [1.0, 0.0])
    np.testing.assert_allclose(path.position(T_GRID)[:, 0], np.cos(2.0 * T_GRID), atol=1e-9)
    assert path.state_names == ("z1", "z2")


def test_explicit_validates_shapes():
    with pytest.raises(ModelError, match=r"F: wrong shape 2x3"):
        explicit(np.zeros((2, 3)), np.zeros((1, 2)), [0.0, 0.0])
    with pytest.raises(ModelError, match=r"H: wrong shape 3x3, expected \?x2"):
        explicit(np.zeros((2, 2)), np.zeros((3, 3)), [0.0, 0.0])
    with pytest.raises(ModelError, match=r"z0: wrong length 3, expected 2"):
        explicit(np.zeros((2, 2)), np.zeros((3, 2)), [0.0, 0.0, 0.0])


# make_leader ------------------------------------------------------------------------
def test_make_leader_dispatch():
    assert LEADER_PATHS == ("straight", "circle", "lawnmower", "explicit")
    a = make_leader("circle", {"radius": 10.0, "speed": 1.0, "clockwise": False})
    b = circle(10.0, 1.0, clockwise=False)
    np.testing.assert_array_equal(a.F, b.F)
    np.testing.assert_array_equal(a.z0, b.z0)
    assert make_leader("straight", {"speed": 1.0}).kind == "straight"


@pytest.mark.parametrize("kind, params, expected", [
    ("spiral", {}, ("leader: unknown path 'spiral'; known paths: straight, circle, "
                    "lawnmower, explicit")),
    ("circle", {"radius": 5.0, "speed": 1.0, "colour": "red"},
     ("leader: unknown circle parameter(s) colour; accepted: radius, speed, center, "
      "clockwise, start_angle_deg")),
    ("circle", {"speed": 1.0}, "leader: circle path needs radius"),
    ("circle", {"radius": -5.0, "speed": 1.0}, "leader: radius = -5 m must be positive"),
    ("circle", {"radius": 5.0, "speed": 1.0, "clockwise": "yes"},
     "leader: clockwise: expected true or false, got 'yes'"),
    ("straight", {"speed": "fast"}, "leader: speed: not a number: 'fast'"),
    ("straight", {"speed": 1.0, "start": [0.0, 1.0]},
     "leader: start [north, east, down] (m): wrong length 2, expected 3"),
    ("lawnmower", {"leg_length": 100.0, "spacing": 10.0, "speed": 1.0, "harmonics": 0},
     "leader: harmonics = 0 must be at least 1"),
    ("lawnmower", {"leg_length": 100.0, "spacing": 10.0, "speed": 1.0, "harmonics": 2.5},
     "leader: harmonics: expected a whole number >= 1, got 2.5"),
    ("explicit", {"F": [[0.0]], "H": [[1.0]], "z0": [float("inf")]},
     "leader: z0[1] = inf is not finite"),
])
def test_make_leader_errors(kind, params, expected):
    with pytest.raises(ModelError) as exc:
        make_leader(kind, params)
    assert str(exc.value) == expected

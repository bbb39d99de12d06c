"""plant_model.vehicles: REMUS 100 numbers, model matrices, physics identities, errors."""
from __future__ import annotations

import math

import numpy as np
import pytest

from plant_model.leader import circle, straight
from plant_model.linalg_checks import ModelError
from plant_model.vehicle_models import VEHICLE_MODELS, make_vehicle
from plant_model.vehicle_targets import leader_state_map, state_offset
from plant_model.vehicles import (
    generic,
    remus100,
    remus100_parameters,
)

RHO, L, DIAM, CD = 1026.0, 1.6, 0.19, 0.42


# remus100_parameters ----------------------------------------------------------------
def test_spheroid_mass_and_frontal_area_by_hand():
    P = remus100_parameters()
    # 4/3 pi 1026 * 0.8 * 0.095^2 = 4/3 pi * 7.40772 = 31.02938 kg
    assert P["mass"] == pytest.approx(4 / 3 * math.pi * 7.40772, rel=1e-12)
    assert P["mass"] == pytest.approx(31.0294, abs=1e-4)
    # the spheroid is within 3 % of the real vehicle's 31.9 kg
    assert abs(P["mass"] - 31.9) / 31.9 < 0.03
    assert P["frontal_area"] == pytest.approx(math.pi * 0.095**2, rel=1e-12)
    assert P["time_constant"] == [20.0, 20.0, 20.0]
    assert (P["rho"], P["length"], P["diameter"], P["drag_coefficient"]) == (RHO, L, DIAM, CD)


def test_lamb_k_factors_satisfy_the_spheroid_identity():
    """alpha0 + 2 beta0 = 2 for any spheroid (the three shape factors sum to 2)."""
    P = remus100_parameters()
    m = P["mass"]
    k1 = P["added_mass"][0] / m
    k2 = P["added_mass"][1] / m
    alpha0 = 2 * k1 / (1 + k1)        # inverse of k = alpha/(2 - alpha)
    beta0 = 2 * k2 / (1 + k2)
    assert alpha0 + 2 * beta0 == pytest.approx(2.0, abs=1e-12)
    assert P["added_mass"][1] == P["added_mass"][2]          # sway = heave
    # slender body: little surge added mass, nearly the displaced mass in sway
    assert k1 == pytest.approx(0.027036, abs=1e-6)
    assert k2 == pytest.approx(0.948702, abs=1e-6)
    assert k2 < 1.0                    # (Fossen's code gives 1.026: log in the denominator)


def test_sphere_limit_gives_half_the_mass_as_added_mass():
    """Nearly a sphere (b -> a): k1 = k2 -> 1/2, the classical sphere added mass."""
    P = remus100_parameters(length=1.0, diameter=0.999)
    assert P["added_mass"][0] / P["mass"] == pytest.approx(0.5, abs=2e-3)
    assert P["added_mass"][1] / P["mass"] == pytest.approx(0.5, abs=2e-3)


def test_parameters_reject_an_oblate_hull():
    with pytest.raises(ModelError, match="diameter"):
        remus100_parameters(length=0.2, diameter=0.3)


# remus100 ---------------------------------------------------------------------------
def test_remus100_matrices_at_zero_speed():
    V = remus100()
    P = remus100_parameters()
    m, ma = P["mass"], P["added_mass"]
    M = np.array([m + ma[0], m + ma[0], m + ma[2]])
    assert (V.p, V.q, V.r, V.s) == (6, 3, 3, 3)
    np.testing.assert_allclose(M, [31.8683, 31.8683, 60.4670], atol=1e-4)
    np.testing.assert_array_equal(V.A[:3], np.hstack([np.zeros((3, 3)), np.eye(3)]))
    # at zero speed D/M = 1/T = 0.05 1/s on every axis
    np.testing.assert_allclose(np.diag(V.A[3:, 3:]), [-0.05, -0.05, -0.05], rtol=1e-12)
    np.testing.assert_allclose(np.diag(V.B2[3:]), [0.05, 0.05, 0.05], rtol=1e-12)
    np.testing.assert_allclose(np.diag(V.B1[3:]), 1.0 / M, rtol=1e-12)
    assert not V.B1[:3].any() and not V.B2[:3].any()
    np.testing.assert_array_equal(V.C, np.hstack([np.eye(3), np.zeros((3, 3))]))
    assert V.position_states == (0, 1, 2)
    assert V.state_units == ("m", "m", "m", "m/s", "m/s", "m/s")
    assert V.input_units == ("N",) * 3 and V.disturbance_units == ("m/s",) * 3


def test_secant_drag_is_exact_at_cruise_speed():
    """D U_c = M/T U_c + 0.5 rho Cd A U_c^2 on the horizontal axes; heave has no drag term."""
    Uc = 1.5
    V = remus100(cruise_speed=Uc)
    P = V.parameters
    M = np.array(P["total_mass"])
    D = -np.diag(V.A[3:, 3:]) * M
    quad = 0.5 * RHO * CD * math.pi * 0.095**2 * Uc**2
    for a in (0, 1):
        assert D[a] * Uc == pytest.approx(M[a] / 20 * Uc + quad, rel=1e-12)
    assert D[2] == pytest.approx(M[2] / 20, rel=1e-12)
    np.testing.assert_allclose(D, P["damping"], rtol=1e-12)
    # hand numbers: 31.8683/20 + 0.5*1026*0.42*0.028353*1.5 = 1.5934 + 9.1634
    assert D[0] == pytest.approx(10.7568, abs=1e-4)


def test_current_is_the_steady_velocity_without_thrust():
    """A v + B2 w = 0 for v = w: with no force the vehicle drifts with the current."""
    V = remus100(cruise_speed=1.0)
    w = np.array([0.3, -0.2, 0.05])
    x = np.concatenate([np.zeros(3), w])
    np.testing.assert_allclose((V.A @ x + V.B2 @ w)[3:], 0.0, atol=1e-15)


def test_steady_thrust_gives_speed_force_over_damping():
    V = remus100(mass=30.0, added_mass=[1.0, 20.0, 10.0], time_constant=[10.0, 5.0, 4.0],
                 drag_coefficient=0.0)
    # M = [31, 31, 40], D = [3.1, 3.1, 10] (sway values unused on the horizontal axes)
    tau = np.array([3.1, 6.2, 5.0])
    v = -np.linalg.solve(V.A[3:, 3:], V.B1[3:] @ tau)
    np.testing.assert_allclose(v, [1.0, 2.0, 0.5], rtol=1e-12)


def test_remus100_parameters_are_json_ready_and_read_only_matrices():
    import json

    V = remus100(cruise_speed=0.5)
    assert json.loads(json.dumps(V.parameters))["cruise_speed"] == 0.5
    with pytest.raises(ValueError):
        V.A[0, 0] = 1.0


@pytest.mark.parametrize("kwargs, words", [
    ({"mass": -1.0}, "mass = -1 kg must be positive"),
    ({"mass": "heavy"}, "mass: not a number"),
    ({"added_mass": [1.0, 2.0]}, "added_mass"),
    ({"added_mass": [1.0, -2.0, 3.0]}, "added_mass[2]"),
    ({"time_constant": [20.0, 0.0, 20.0]}, "time_constant[2] = 0 s must be positive"),
    ({"drag_coefficient": -0.1}, "drag_coefficient"),
    ({"cruise_speed": -1.0}, "cruise_speed = -1 m/s must not be negative"),
    ({"cruise_speed": 3.0}, "2.5 m/s"),
    ({"mass": float("nan")}, "mass = nan is not finite"),
])
def test_remus100_bad_arguments_name_the_parameter(kwargs, words):
    with pytest.raises(ModelError) as exc:
        remus100(**kwargs)
    assert words in str(exc.value)


# generic ----------------------------------------------------------------------------
def test_generic_keeps_matrices_and_names():
    V = generic([[-1.0, 0.0], [1.0, -2.0]], [[1.0], [0.0]], [[0.0], [1.0]], [[0.0, 1.0]])
    assert (V.p, V.q, V.r, V.s) == (2, 1, 1, 1)
    assert V.state_names == ("x1", "x2") and V.input_names == ("u1",)
    assert V.disturbance_names == ("w1",) and V.output_names == ("y1",)
    assert V.state_units == ("", "") and V.position_states is None
    np.testing.assert_array_equal(V.A, [[-1.0, 0.0], [1.0, -2.0]])


@pytest.mark.parametrize("args, words", [
    (([[1.0, 2.0]], [[1.0]], [[1.0]], [[1.0]]), "A: wrong shape 1x2, expected 1x1"),
    (([[1.0]], [[1.0], [2.0]], [[1.0]], [[1.0]]), "B1: wrong shape 2x1, expected 1x?"),
    ((np.eye(2), np.ones((2, 1)), np.ones((3, 1)), np.eye(2)), "B2: wrong shape 3x1, expected 2x?"),
    ((np.eye(2), np.ones((2, 1)), np.ones((2, 1)), np.ones((1, 3))), "C: wrong shape 1x3, expected ?x2"),
])
def test_generic_shape_errors_name_matrix_and_shape(args, words):
    with pytest.raises(ModelError) as exc:
        generic(*args)
    assert words in str(exc.value)


# make_vehicle -----------------------------------------------------------------------
def test_make_vehicle_dispatches_with_the_same_numbers():
    assert VEHICLE_MODELS == ("remus100", "remus100-6dof", "remus100-fitted", "generic",
                              "remus100-6dof-guided", "fmu")
    V = make_vehicle("remus100", {"cruise_speed": 1.5}, "vehicle 2")
    np.testing.assert_array_equal(V.A, remus100(cruise_speed=1.5).A)
    G = make_vehicle("generic", {"A": [[0.0]], "B1": [[1.0]], "B2": [[1.0]], "C": [[1.0]]},
                     "vehicle 1")
    assert G.name == "generic" and G.A.shape == (1, 1)


def test_make_vehicle_unknown_model():
    with pytest.raises(ModelError) as exc:
        make_vehicle("nautilus", {}, "vehicle 3")
    assert str(exc.value) == ("vehicle 3: unknown vehicle model 'nautilus'; "
                              "known models: remus100, remus100-6dof, remus100-fitted, generic, "
                              "remus100-6dof-guided, fmu")


def test_make_vehicle_unknown_key_lists_accepted_keys():
    with pytest.raises(ModelError) as exc:
        make_vehicle("remus100", {"mass": 31.0, "colour": "yellow"}, "vehicle 4")
    msg = str(exc.value)
    assert msg.startswith("vehicle 4: ") and "colour" in msg
    assert "mass, added_mass, time_constant, drag_coefficient, cruise_speed" in msg


def test_make_vehicle_prefixes_value_errors_and_missing_matrices():
    with pytest.raises(ModelError, match=r"^vehicle 2: mass = 0 kg must be positive"):
        make_vehicle("remus100", {"mass": 0}, "vehicle 2")
    with pytest.raises(ModelError, match=r"^vehicle 5: missing generic matrices: B2, C"):
        make_vehicle("generic", {"A": [[0.0]], "B1": [[1.0]]}, "vehicle 5")
    with pytest.raises(ModelError, match=r"^vehicle 1: B1: wrong shape"):
        make_vehicle("generic", {"A": [[0.0]], "B1": [[1.0], [1.0]], "B2": [[1.0]],
                                 "C": [[1.0]]}, "vehicle 1")


# leader_state_map / state_offset ----------------------------------------------------
def test_leader_state_map_remus_is_position_and_velocity_of_the_path():
    V = remus100()
    path = straight(1.2, heading_deg=90.0, start=(5.0, 6.0, 7.0), climb_rate=0.1)
    T = leader_state_map(V, path.H, path.F)
    np.testing.assert_allclose(T @ path.z0, [5.0, 6.0, 7.0, 0.0, 1.2, 0.1], atol=1e-15)


def test_leader_state_map_remus_is_consistent_with_the_dynamics():
    """C T = H and T F - A T lies in range(B1) (only velocity rows): the leader's state
    trajectory is one the vehicle can follow exactly with some force."""
    V = remus100(cruise_speed=1.0)
    path = circle(20.0, 1.0, center=(1.0, 2.0, 3.0))
    T = leader_state_map(V, path.H, path.F)
    np.testing.assert_allclose(V.C @ T, path.H, atol=1e-15)
    np.testing.assert_allclose((T @ path.F - V.A @ T)[:3], 0.0, atol=1e-15)


def test_leader_state_map_generic_least_squares():
    V = generic(np.zeros((3, 3)), np.eye(3), np.eye(3), [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    H = np.array([[1.0, 2.0], [4.0, -2.0]])
    T = leader_state_map(V, H, np.zeros((2, 2)))
    np.testing.assert_allclose(T, [[1.0, 2.0], [2.0, -1.0], [0.0, 0.0]], atol=1e-14)


def test_leader_state_map_shape_errors():
    with pytest.raises(ModelError, match=r"leader H: wrong shape 2x6, expected 3x6"):
        leader_state_map(remus100(), np.ones((2, 6)), np.zeros((6, 6)))
    with pytest.raises(ModelError, match=r"leader F: wrong shape 6x5"):
        leader_state_map(remus100(), np.ones((3, 6)), np.zeros((6, 5)))
    with pytest.raises(ModelError, match=r"leader H: wrong shape 3x4, expected 3x6"):
        leader_state_map(remus100(), np.ones((3, 4)), np.zeros((6, 6)))
    G = generic(np.eye(2), np.eye(2), np.eye(2), np.eye(2))
    with pytest.raises(ModelError, match=r"leader H: wrong shape 3x2, expected 2x2"):
        leader_state_map(G, np.ones((3, 2)), np.zeros((2, 2)))


def test_state_offset():
    np.testing.assert_array_equal(state_offset(remus100(), [1.0, -2.0, 3.0]),
                                  [1.0, -2.0, 3.0, 0.0, 0.0, 0.0])
    G = generic(np.zeros((2, 2)), np.eye(2), np.eye(2), [[2.0, 0.0], [0.0, 4.0]])
    np.testing.assert_allclose(state_offset(G, [1.0, 1.0]), [0.5, 0.25], atol=1e-15)
    with pytest.raises(ModelError, match=r"formation offset.*wrong length 2, expected 3"):
        state_offset(remus100(), [1.0, 2.0])

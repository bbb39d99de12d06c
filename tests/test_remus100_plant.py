"""The nonlinear REMUS 100 as a scenario model and a sampled plant (plant_model.remus100.plant,
plant_model.remus100.models.remus100_6dof_design)."""
from __future__ import annotations

import numpy as np
import pytest

from orchestrator.scenario import ScenarioError, load_scenario
from plant_model.linalg_checks import ModelError
from plant_model.per_vehicle import sample_vehicle
from plant_model.plant import Plant
from plant_model.remus100.autopilot import AutopilotGains
from plant_model.remus100.dynamics import Remus100
from plant_model.remus100.plant import (
    Remus6dofPlant,
    default_substep,
    linear_mass_damping,
    substep_count,
)
from plant_model.vehicle_models import make_vehicle
from plant_model.vehicles import remus100


@pytest.fixture(scope="module")
def f4_6dof():
    return load_scenario("formation-4").with_run(T=20.0, deployment="per-vehicle",
                                                  architecture="distributed"
                                                  ).with_vehicle_model("remus100-6dof")


def _plant(sc, i=0, seed=4, **kw):
    view = sc.fleet.views[i]
    linear = sample_vehicle(view, sc.h, i + 1)
    M, D = linear_mass_damping(view.B1, view.B2)
    return Remus6dofPlant(Remus100(), AutopilotGains(), linear, M, D, view.x0, view.w0,
                          seed, substep_count(sc.h, default_substep(sc.h)), **kw), view, linear


def test_the_design_model_is_the_linear_remus100_of_the_same_hull():
    six = make_vehicle("remus100-6dof", {"cruise_speed": 1.5}, "vehicle 1")
    lin = remus100(cruise_speed=1.5)
    for name in ("A", "B1", "B2", "C"):
        assert np.allclose(getattr(six, name), getattr(lin, name), rtol=1e-14)
    longer = make_vehicle("remus100-6dof", {"L": 2.0}, "vehicle 1")
    assert longer.parameters["nonlinear"]["L"] == 2.0
    assert longer.B1[3, 0] < six.B1[3, 0]           # a longer hull is heavier


@pytest.mark.parametrize("params, fragment", [
    ({"wingspan": 1.0}, "unknown remus100-6dof parameter(s) wingspan"),
    ({"L": -1.6}, "L = -1.6 m must be positive (the hull's length)"),
    ({"n_max": -1525.0}, "n_max = -1525 rpm must be positive"),
    ({"delta_max": -0.5}, "delta_max = -0.5 rad (-28.6 deg) must be in (0, 90) deg"),
    ({"rho": 0.0}, "rho = 0 kg/m^3 must be positive"),
    ({"substep": -0.01}, "substep"),
    ({"autopilot": {"K_x": 1.0}}, "unknown gain(s) ['K_x']"),
    ({"T_n": float("nan")}, "T_n = nan is not a finite number"),
    ({"r44": -0.5}, "r44 = -0.5 must be non-negative"),
    ({"r_g": [0.0, 0.0, -0.02]}, "r_g[3] = -0.02 m must be positive"),
])
def test_bad_vehicle_data_is_one_line_naming_the_parameter(params, fragment):
    with pytest.raises(ModelError) as exc:
        make_vehicle("remus100-6dof", params, "vehicle 2")
    msg = str(exc.value)
    assert msg.startswith("vehicle 2: ") and fragment in msg and "\n" not in msg


def test_a_substep_that_does_not_divide_the_step_is_refused():
    assert substep_count(0.1, 0.025) == 4 and substep_count(0.01, 0.01) == 1
    assert default_substep(0.12) == pytest.approx(0.04) and default_substep(0.01) == 0.01
    with pytest.raises(ModelError, match=r"substep = 0.03 s does not divide the step h = 0.1 s"):
        substep_count(0.1, 0.03)


def test_the_stacked_deployment_refuses_the_nonlinear_vehicle(f4_6dof):
    with pytest.raises(ScenarioError, match=r"remus100-6dof needs \[simulation\] deployment = "
                       r"\"per-vehicle\""):
        f4_6dof.with_run(deployment="stacked")


def test_current_and_sensor_noise_are_the_linear_vehicles_draws(f4_6dof):
    """Same generator [seed, vehicle]: the current w and the fix noise y - p are the linear
    vehicle's, draw for draw, whatever the vehicle does."""
    plant, view, linear = _plant(f4_6dof, i=2)
    lin = Plant(linear, np.concatenate([view.x0, view.w0]), 4)
    rng = np.random.default_rng(0)
    for _ in range(300):
        u = rng.normal(scale=20.0, size=3)
        o = plant.output
        assert np.allclose(o[9:12], lin.s[6:9], rtol=0, atol=1e-13)          # w
        assert np.allclose(o[:3] - o[3:6], lin.output[:3] - lin.s[:3], atol=1e-12)  # n[k]
        plant.step(u)
        lin.step(u)
    assert np.std(plant.output[9:12]) >= 0 and not np.allclose(plant.output[3:6], lin.s[:3])


def test_a_cruise_force_holds_cruise_speed_over_ground():
    """u = D v north: the linear model's steady state is 1.5 m/s north; so is the torpedo's
    (no current, no noise), at constant depth, with the propeller near its feedforward."""
    sc = load_scenario("formation-4").with_run(T=20.0)
    view = sc.fleet.views[0]
    quiet = view.__class__.from_mapping({**view.to_mapping(), "W_x": np.zeros((6, 6)),
                                         "W_w": np.zeros((3, 3)), "V_y": np.zeros((3, 3)),
                                         "w0": np.zeros(3),
                                         "x0": np.r_[0, 0, 20.0, 1.5, 0, 0]})
    linear = sample_vehicle(quiet, 0.05, 1)
    M, D = linear_mass_damping(quiet.B1, quiet.B2)
    plant = Remus6dofPlant(Remus100(), AutopilotGains(), linear, M, D, quiet.x0, quiet.w0, 0, 1)
    u = np.array([D[0] * 1.5, 0.0, 0.0])
    for _ in range(1200):
        plant.step(u)
    o = plant.output
    assert o[6] == pytest.approx(1.5, abs=0.01) and abs(o[7]) < 0.01 and abs(o[8]) < 0.01
    assert o[5] == pytest.approx(20.0, abs=0.2)
    assert 700 < o[15] < 1100 and o[18] == 0.0                  # rpm, not saturated


def test_state_round_trip_continues_identically(f4_6dof):
    plant, _, _ = _plant(f4_6dof, i=1)
    rng = np.random.default_rng(2)
    forces = rng.normal(scale=30.0, size=(200, 3))
    for u in forces[:50]:
        plant.step(u)
    state = plant.get_state()
    first = []
    for u in forces[50:]:
        plant.step(u)
        first.append(plant.output.copy())
    plant.set_state(state)
    second = []
    for u in forces[50:]:
        plant.step(u)
        second.append(plant.output.copy())
    assert np.array_equal(np.array(first), np.array(second))
    with pytest.raises(ValueError, match="seed 9"):
        plant.set_state({**state, "seed": 9})


def test_the_fitted_model_is_a_scenario_model_and_a_design_for_the_nonlinear_vehicle():
    from plant_model.remus100.models import FITTED_HORIZONTAL, FITTED_VERTICAL
    fitted = make_vehicle("remus100-fitted", {}, "vehicle 1")
    assert 1.0 / fitted.B1[3, 0] == pytest.approx(FITTED_HORIZONTAL[0])
    assert fitted.B2[5, 2] / fitted.B1[5, 2] == pytest.approx(FITTED_VERTICAL[1])
    six = make_vehicle("remus100-6dof", {"design": "remus100-fitted"}, "vehicle 1")
    assert np.array_equal(six.B1, fitted.B1) and six.parameters["design"] == "remus100-fitted"
    with pytest.raises(ModelError, match="vehicle 1: unknown remus100-fitted parameter"):
        make_vehicle("remus100-fitted", {"cruise_speed": 1.0}, "vehicle 1")
    with pytest.raises(ModelError, match="design = 'linear' is not one of remus100, "
                                         "remus100-fitted"):
        make_vehicle("remus100-6dof", {"design": "linear"}, "vehicle 1")


def test_the_vehicle_starts_at_its_scenario_velocity_over_ground_in_a_current():
    """x0's velocity is over ground: in a current w0 the hull starts with its nose along the
    velocity through the water v_g - w0 and moves over ground at v_g (before the fix, its
    surge was the through-water speed, so it started off by the current)."""
    from plant_model.remus100.plant import initial_state
    from plant_model.remus100.rigid_body import rotation_ned_body
    v_g, w0 = np.array([1.2, 0.5, 0.1]), np.array([0.3, -0.4, 0.0])
    x, v_ref = initial_state(Remus100(), AutopilotGains(), np.r_[0, 0, 5, v_g], w0)
    assert np.allclose(rotation_ned_body(*x[3:6]) @ x[6:9], v_g, atol=1e-12)
    assert np.allclose(v_ref, v_g - w0)
    vw = rotation_ned_body(*x[3:6]).T @ (v_g - w0)        # through the water, body axes
    assert vw[0] == pytest.approx(np.linalg.norm(v_g - w0)) and np.allclose(vw[1:], 0,
                                                                             atol=1e-12)

"""The AuvGuidance and AuvAutopilot FMUs, built the real way and run through fmpy: equal
to their plain-function mathematics, clean for fmpy's validator, errors as statuses with a
logged message (a NaN input, a non-positive mass or damping), state save and restore."""
from __future__ import annotations

import math

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

from controller_fmu.guidance import depth_increment, reference_step, setpoints
from orchestrator.cosim.build import build_fmus
from orchestrator.running.fmus import guidance_configs
from orchestrator.scenario import load_scenario
from plant_model.remus100.autopilot import AutopilotGains
from plant_model.remus100.setpoint_autopilot import DepthLoop, limit_command, setpoint_command
from plant_model.vehicles import remus100
from support.fmi import open_initializing

SETPOINTS = ["speed", "course", "depth", "speed_rate", "course_rate", "depth_rate"]
SENSORS = ([f"velocity[{i}]" for i in (1, 2, 3)] + [f"attitude[{i}]" for i in (1, 2, 3)]
           + [f"rates[{i}]" for i in (1, 2, 3)] + ["measured_depth"])
U = ["u[1]", "u[2]", "u[3]"]


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    """Both FMUs as ``auv-cosim build`` makes them for the example scenario."""
    sc = load_scenario("docs/examples/straight-leader.toml")
    return build_fmus(None, tmp_path_factory.mktemp("guidance"), kinds=guidance_configs(sc))


def _instance(fmus, key, tmp_path, name="probe", **parameters):
    return open_initializing(fmus[key], tmp_path, name, key, **parameters)


def _vr(inst, names):
    return [inst.vr[n] for n in names]


def test_both_validate_and_are_built_for_remus_scenarios_only(fmus):
    assert validate_fmu(str(fmus["guidance"])) == []
    assert validate_fmu(str(fmus["autopilot"])) == []
    assert guidance_configs(load_scenario("paper")) == {}          # dimensionless: none
    cfg = guidance_configs(load_scenario("docs/examples/straight-leader.toml"))["guidance"]
    design = remus100(cruise_speed=2.0).parameters
    assert cfg["guidance"]["M"] == design["total_mass"]
    assert cfg["guidance"]["D"] == design["damping"]
    assert cfg["guidance"]["v_ref0"] == pytest.approx([1.9, 0.05, 0.0])


def test_the_guidance_fmu_is_its_mathematics(fmus, tmp_path):
    """600 steps of a random force through fmpy against the plain functions: 1e-12."""
    inst = _instance(fmus, "guidance", tmp_path)
    s = inst.slave
    s.exitInitializationMode()
    names = ["M[1]", "M[2]", "M[3]", "D[1]", "D[2]", "D[3]", "v_ref0[1]", "v_ref0[2]", "v_ref0[3]",
             "depth0", "course0", "U_min"]
    par = np.array(s.getReal(_vr(inst, names)))
    M, D, v, depth, course, U_min = par[:3], par[3:6], par[6:9], par[9], par[10], par[11]
    rng = np.random.default_rng(5)
    h, worst = 0.05, 0.0
    for k in range(600):
        u = rng.normal(0, 10, 3) + (np.array([-40.0, -40.0, 0.0]) if k > 300 else 0.0)
        s.setReal(_vr(inst, U), list(u))
        out = np.array(s.getReal(_vr(inst, SETPOINTS + ["v_ref[1]", "v_ref[2]", "v_ref[3]"])))
        ref = np.concatenate([setpoints(v, u, M, D, depth, course, U_min), v])
        worst = max(worst, np.abs(out - ref).max())
        s.doStep(k * h, h)
        depth += depth_increment(v[2], u[2], M[2], D[2], h)
        v = reference_step(v, u, M, D, h)
        course = math.atan2(v[1], v[0]) if math.hypot(v[0], v[1]) > U_min else course
    assert worst < 1e-12
    assert np.ptp(out[:3]) > 0.0 and k == 599        # it moved
    blob = s.serializeFMUstate(s.getFMUstate())       # v_ref, depth, course round-trip
    s.doStep(600 * h, h)
    after = s.getReal(_vr(inst, SETPOINTS))
    s.setFMUstate(s.deSerializeFMUstate(blob))
    s.setReal(_vr(inst, U), list(u))
    s.doStep(600 * h, h)
    assert s.getReal(_vr(inst, SETPOINTS)) == after


def test_the_autopilot_fmu_is_its_mathematics_and_holds_its_integral_when_saturated(
        fmus, tmp_path):
    inst = _instance(fmus, "autopilot", tmp_path)
    s = inst.slave
    s.exitInitializationMode()
    g, dl = AutopilotGains(), DepthLoop()
    rng = np.random.default_rng(9)
    integ, h, worst = np.zeros(2), 0.05, 0.0
    for k in range(400):
        sp = np.array([rng.uniform(0.5, 2.5), rng.uniform(-3, 3), 20 + rng.normal(0, 3),
                       0.0, rng.normal(0, 0.05), rng.normal(0, 0.2)])
        if k >= 200:
            sp[0] = 6.0                        # beyond n_max: the speed integral holds
        meas = np.concatenate([[rng.uniform(1, 2), rng.normal(0, .1), rng.normal(0, .1)],
                               rng.normal(0, 0.1, 2), [rng.uniform(-3, 3)],
                               rng.normal(0, 0.05, 3), [20 + rng.normal(0, 3)]])
        s.setReal(_vr(inst, SETPOINTS + SENSORS), list(np.concatenate([sp, meas])))
        out = np.array(s.getReal(_vr(inst, ["rpm", "rudder", "stern", "saturated"])))
        cmd, err = setpoint_command(g, dl, sp, meas[:3], meas[3:6], meas[6:9], meas[9], integ)
        lim, sat = limit_command(g, cmd)
        worst = max(worst, np.abs(out - [lim[2], lim[0], lim[1], float(sat)]).max())
        s.doStep(k * h, h)
        integ = integ + err * h
        if k == 199:
            held = integ[0]
    assert worst < 1e-12
    assert integ[0] == held and out[0] == g.n_max and out[3] == 1.0
    state = s.getFMUstate()                                  # the integrals round-trip
    calm = [1.0, 0.0, 20.0, 0.0, 0.0, 0.0]
    s.setReal(_vr(inst, SETPOINTS), calm)
    before = s.getReal(_vr(inst, ["rpm", "stern"]))
    s.doStep(400 * h, h)
    assert s.getReal(_vr(inst, ["rpm", "stern"])) != before
    s.setFMUstate(state)
    s.setReal(_vr(inst, SETPOINTS), calm)
    assert s.getReal(_vr(inst, ["rpm", "stern"])) == before


def test_a_nan_input_refuses_the_step_with_a_message_and_the_host_goes_on(fmus, tmp_path):
    for key, name in (("guidance", "u[2]"), ("autopilot", "attitude[3]")):
        inst = _instance(fmus, key, tmp_path, name=key)
        s = inst.slave
        s.exitInitializationMode()
        s.setReal([inst.vr[name]], [math.nan])
        with pytest.raises(FMICallException):
            s.doStep(0.0, 0.05)
        assert any(f"input {name} = nan is not finite" in m for st, m in inst.messages
                   if st == "Error")
        s.setReal([inst.vr[name]], [0.0])
        s.doStep(0.0, 0.05)                                   # finite again: it steps
        inst.close()


@pytest.mark.parametrize("parameter, value", [("M[2]", 0.0), ("D[3]", -1.0)])
def test_a_non_positive_mass_or_damping_fails_initialization_naming_it(fmus, tmp_path,
                                                                       parameter, value):
    inst = _instance(fmus, "guidance", tmp_path, **{parameter: value})
    with pytest.raises(FMICallException):
        inst.slave.exitInitializationMode()
    assert any(f"parameter {parameter} = {value}" in m and "positive" in m
               for st, m in inst.messages if st == "Error")

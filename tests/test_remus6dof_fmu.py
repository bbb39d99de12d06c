"""The nonlinear REMUS 100 vehicle FMU (AuvRemus6dof) under fmpy: in the per-vehicle loop
against the same plant stepped by hand, its interface, and a state that goes non-finite."""
from __future__ import annotations

import ctypes

import numpy as np
import pytest
from fmpy.validation import validate_fmu

from orchestrator.cosim.build import build_fmus
from orchestrator.cosim.instance import Extracted, FmuInstance
from orchestrator.cosim.master import run_system
from orchestrator.cosim.per_vehicle import (
    build_configs,
    per_vehicle_configs,
    per_vehicle_system,
    stacked_traces,
)
from orchestrator.scenario import load_scenario
from plant_model.per_vehicle import sample_vehicle
from plant_model.remus100.autopilot import AutopilotGains
from plant_model.remus100.dynamics import Remus100
from plant_model.remus100.plant import (
    Remus6dofPlant,
    default_substep,
    linear_mass_damping,
    substep_count,
)

T = 10.0


@pytest.fixture(scope="module")
def loop(tmp_path_factory):
    sc = load_scenario("formation-4").with_run(
        T=T, deployment="per-vehicle", architecture="distributed", seed=3
    ).with_vehicle_model("remus100-6dof")
    cfgs = per_vehicle_configs(sc, "distributed", estimator="kalman", seed=3, tracking=sc.tracking)
    fmus = build_fmus(None, tmp_path_factory.mktemp("r6"), kinds=build_configs(cfgs))
    system = per_vehicle_system(sc, cfgs, "distributed")
    traces, _, _ = run_system(system, fmus, sc.steps)
    return sc, fmus, system, traces


@pytest.mark.slow
def test_every_vehicle_is_the_nonlinear_fmu_with_its_extra_outputs(loop):
    sc, fmus, system, traces = loop
    kinds = [c.fmu for c in system.components if c.name.startswith("vehicle_")]
    assert kinds == ["remus6dof"] * 4
    assert validate_fmu(str(fmus["remus6dof"])) == []
    names = system.trace_names()
    rpm = traces[names[("vehicle_1", "rpm")]][:, 0]
    att = traces[names[("vehicle_2", "attitude")]]
    assert 300.0 < rpm.mean() < 1525.0 and att.shape == (sc.steps, 3)
    assert np.ptp(att[:, 2]) > 0.05                       # it steers
    st = stacked_traces(sc, system, traces)
    assert st["x"].shape == (sc.steps, 24) and np.all(np.isfinite(st["e"]))


def test_the_fmu_in_the_loop_is_the_plant_stepped_by_hand(loop):
    """Vehicle 3's outputs, replayed offline from its recorded force: equal to 1e-12."""
    sc, _, system, traces = loop
    names = system.trace_names()
    view = sc.fleet.views[2]
    linear = sample_vehicle(view, sc.h, 3)
    M, D = linear_mass_damping(view.B1, view.B2)
    plant = Remus6dofPlant(Remus100(), AutopilotGains(), linear, M, D, view.x0, view.w0, 3,
                           substep_count(sc.h, default_substep(sc.h)))
    u = traces[names[("controller_3", "u")]]
    outs = ("y", "x", "w", "attitude", "rpm", "rudder", "stern", "saturated")
    rec = np.hstack([traces[names[("vehicle_3", o)]] for o in outs])
    worst = 0.0
    for k in range(sc.steps):
        worst = max(worst, float(np.max(np.abs(plant.output - rec[k]))))
        plant.step(u[k])
    assert worst < 1e-12


def test_a_state_gone_non_finite_is_an_error_naming_vehicle_and_time(loop):
    _, fmus, system, _ = loop
    comp = system.component("vehicle_2")
    ex = Extracted({"remus6dof": fmus["remus6dof"]})
    try:
        inst = FmuInstance("vehicle_2", fmus["remus6dof"], ex.dirs["remus6dof"], "nan_probe")
        # roll damping 1e7 times critical: RK4 at 0.01 s is unstable and blows up
        inst.initialize({**comp.parameters, "remus.zeta_roll": 1e7}, T=T)
        vr = (ctypes.c_uint * 3)(*[inst.vr[f"u[{k}]"] for k in (1, 2, 3)])
        push = (ctypes.c_double * 3)(20.0, 0.0, 0.0)
        assert inst.set_real(inst.component, vr, 3, push) == 0
        status, k = 0, 0
        while status == 0 and k < 50:
            status = inst.do_step(inst.component, k * 0.01, 0.01, 1)
            k += 1
        assert status != 0
        err = [m for s, m in inst.messages if s == "Error"][0]
        assert "(vehicle 2)" in err and (f"became non-finite in the step from t = "
                                         f"{(k - 1) * 0.01:g} s") in err
        # the host goes on: the instance answers and refuses further steps, no crash
        assert inst.do_step(inst.component, k * 0.01, 0.01, 1) != 0
        inst.close()
    finally:
        ex.cleanup()

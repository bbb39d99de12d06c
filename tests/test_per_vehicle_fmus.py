"""The per-vehicle FMUs one at a time under fmpy: FMU state, bad parameters, what they log."""
from __future__ import annotations

import numpy as np
import pytest

from orchestrator.cosim.build import build_fmus
from orchestrator.cosim.instance import CosimError, Extracted, FmuInstance
from orchestrator.cosim.per_vehicle import build_configs, per_vehicle_configs, per_vehicle_system
from orchestrator.scenario import load_scenario


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    sc = load_scenario("formation-4").with_run(T=10.0)
    cfgs = per_vehicle_configs(sc, "distributed", estimator="kalman", seed=2, tracking="regulator")
    fmus = build_fmus(None, tmp_path_factory.mktemp("pv"), kinds=build_configs(cfgs))
    system = per_vehicle_system(sc, cfgs, "distributed")
    ex = Extracted(fmus)
    yield fmus, system, ex
    ex.cleanup()


def _instance(built, component: str, name: str, **override) -> FmuInstance:
    fmus, system, ex = built
    comp = system.component(component)
    inst = FmuInstance(component, fmus[comp.fmu], ex.dirs[comp.fmu], name)
    inst.initialize({**comp.parameters, **override}, T=10.0)
    return inst


def _drive(inst: FmuInstance, inputs: np.ndarray, outputs: list[str], k0: int) -> np.ndarray:
    """Set every input of the instance from ``inputs`` rows, read ``outputs``, step."""
    ins = [v.name for v in inst.md.modelVariables if v.causality == "input"]
    s = inst.slave
    vin, vout = [inst.vr[n] for n in ins], [inst.vr[n] for n in outputs]
    rec = []
    for j, row in enumerate(inputs):
        s.setReal(vin, list(row[:len(vin)]))
        rec.append(s.getReal(vout))
        s.doStep((k0 + j) * 0.01, 0.01)
    return np.array(rec)


@pytest.mark.parametrize("component, outputs", [
    ("controller_4", ["u[1]", "u[2]", "eta[1]", "eta[5]", "eps[4]"]),
    ("vehicle_2", ["y[1]", "x[4]", "w[2]"]),
    ("estimator_3", ["xhat[1]", "what[3]"]),
])
@pytest.mark.slow
def test_fmu_state_round_trip_is_bit_identical(built, component, outputs):
    inst = _instance(built, component, f"{component}_state")
    rng = np.random.default_rng(1)
    n_in = sum(1 for v in inst.md.modelVariables if v.causality == "input")
    inputs = rng.standard_normal((400, max(n_in, 1)))
    _drive(inst, inputs[:150], outputs, 0)
    state = inst.slave.getFMUState()
    first = _drive(inst, inputs[150:], outputs, 150)
    inst.slave.setFMUState(state)
    second = _drive(inst, inputs[150:], outputs, 150)
    assert np.array_equal(first, second)
    assert np.std(first[:, 0]) > 0            # the outputs moved
    blob = inst.slave.serializeFMUState(state)
    inst.slave.setFMUState(inst.slave.deserializeFMUState(blob))
    assert np.array_equal(_drive(inst, inputs[150:], outputs, 150), first)
    inst.slave.freeFMUState(state)
    inst.close()


@pytest.mark.parametrize("name, value, fragment", [
    ("a[1]", -1.0, "a[1]"),
    ("mu", float("nan"), "mu"),
])
def test_a_bad_controller_parameter_is_an_error_status_naming_it(built, name, value, fragment):
    with pytest.raises(CosimError) as exc:
        _instance(built, "controller_4", f"bad_{name}", **{name: value})
    assert fragment in str(exc.value)


def test_an_unstable_design_is_refused_in_the_controller_fmu(built):
    """A vehicle whose actuators reach nothing cannot be regulated: the FMU says why."""
    zero = {f"B1[{i},{j}]": 0.0 for i in range(1, 7) for j in range(1, 4)}
    with pytest.raises(CosimError) as exc:
        _instance(built, "controller_2", "unstabilizable", **zero)
    assert "stabilizable" in str(exc.value)


@pytest.mark.slow
def test_every_per_vehicle_fmu_validates_and_declares_its_structure(built, tmp_path):
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    from orchestrator.running.setup import Method
    from orchestrator.running.systems import make_setup
    fmus = dict(built[0])
    sc = load_scenario("formation-4").with_run(T=10.0, deployment="per-vehicle",
                                               architecture="centralized")
    fmus.update(make_setup(sc, tmp_path).python_fmus(Method.of(sc)))
    assert set(fmus) == {"leader", "vehicle", "vehicle_estimator", "vehicle_controller",
                         "central_controller"}
    for key, path in fmus.items():
        assert validate_fmu(str(path)) == [], key
        md = read_model_description(str(path))
        assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate
        assert all(v.description for v in md.modelVariables), key
    # the distributed controller: u feeds through from the estimates and the slots' eps,
    # eta (the observer's state) from nothing
    md = read_model_description(str(fmus["vehicle_controller"]))
    deps = {u.variable.name: {d.name for d in (u.dependencies or [])}
            for u in md.outputs}
    assert deps["eta[1]"] == set()
    assert {"xhat[1]", "what[1]", "nbr[2].eps[6]"} <= deps["u[1]"]
    assert "nbr[1].eta[1]" not in deps["u[1]"]

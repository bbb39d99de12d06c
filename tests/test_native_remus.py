"""The native (C) REMUS 100 FMUs (AuvRemus6dofNative, AuvRemus6dofActuatedNative) against
the pythonfmu plant of the same seed: the C model with navigation sensors, the FMU with
its autopilot and open loop, the state round trip, and bad parameters and inputs."""
from __future__ import annotations

import ctypes
import shutil
import subprocess

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu

from orchestrator.cosim.build import build_fmus
from orchestrator.cosim.instance import FmuLog
from orchestrator.cosim.native_build import NATIVE_DIR
from orchestrator.cosim.native_remus import native_remus_fmu
from orchestrator.cosim.per_vehicle import build_configs, per_vehicle_configs
from orchestrator.scenario import load_scenario
from plant_model.navigation import NavigationSensors
from plant_model.per_vehicle import sample_vehicle
from plant_model.remus100.autopilot import AutopilotGains
from plant_model.remus100.dynamics import Remus100
from plant_model.remus100.native_constants import const_struct, remus_constants
from plant_model.remus100.plant import (
    ActuatedRemus6dofPlant,
    Remus6dofPlant,
    default_substep,
    linear_mass_damping,
    substep_count,
)

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler (cc)")

#: native vs pythonfmu, per signal, relative to the signal's largest magnitude (measured:
#: up to 5e-15; docs/native.md says where the last bits differ)
BOUND = 1e-12
SEED, VEHICLE = 3, 3


def _plant(cls, sensors=None):
    sc = load_scenario("formation-4")
    view = sc.fleet.views[VEHICLE - 1]
    linear = sample_vehicle(view, sc.h, VEHICLE)
    M, D = linear_mass_damping(view.B1, view.B2)
    return cls(Remus100(), AutopilotGains(), linear, M, D, view.x0, view.w0, SEED,
               substep_count(sc.h, default_substep(sc.h)), sensors=sensors), view


def _inputs(actuated: bool, steps: int) -> np.ndarray:
    t = np.arange(steps) * 0.01
    if actuated:                       # rpm, rudder, stern: a turn and a dive, open loop
        return np.column_stack([1000 + 300 * np.sin(t), 0.2 * np.sin(0.3 * t),
                                0.1 * np.cos(0.2 * t)])
    return np.random.default_rng(0).standard_normal((steps, 3)) * [30.0, 30.0, 10.0]


def _relative(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per column: max |a - b| over the largest |b| (1 where b is all 0)."""
    scale = np.abs(b).max(axis=0)
    return np.abs(a - b).max(axis=0) / np.where(scale > 0, scale, 1.0)


@pytest.fixture(scope="module")
def model_lib(tmp_path_factory):
    lib = tmp_path_factory.mktemp("remus_c") / "libremus.so"
    subprocess.run(["cc", "-shared", "-fPIC", "-O2", "-std=c99", "-Werror", "-Wall",
                    f"-I{NATIVE_DIR}", str(NATIVE_DIR / "remus6dof_model.c"),
                    str(NATIVE_DIR / "numpy_random.c"), "-o", str(lib), "-lm"], check=True)
    return ctypes.CDLL(str(lib))


@pytest.mark.parametrize("cls", [Remus6dofPlant, ActuatedRemus6dofPlant])
def test_the_c_model_with_sensors_is_the_python_plant(model_lib, cls):
    """1000 steps with navigation sensors (dropouts on): every output within BOUND."""
    plant, view = _plant(cls, NavigationSensors())
    c = const_struct(remus_constants(plant))
    st = ctypes.create_string_buffer(200_000)
    dp = ctypes.POINTER(ctypes.c_double)
    x0, w0 = np.array(view.x0, float), np.array(view.w0, float)
    model_lib.remus_reset(ctypes.byref(c), st, x0.ctypes.data_as(dp), w0.ctypes.data_as(dp),
                          ctypes.c_uint32(SEED), ctypes.c_uint32(VEHICLE))
    steps, o = 1000, np.zeros(plant.output.size)
    U = _inputs(cls is ActuatedRemus6dofPlant, steps)
    got, want = np.zeros((steps, o.size)), np.zeros((steps, o.size))
    for k in range(steps):
        model_lib.remus_outputs(ctypes.byref(c), st, o.ctypes.data_as(dp))
        got[k], want[k] = o, plant.output
        u = np.ascontiguousarray(U[k])
        plant.step(u)
        assert model_lib.remus_step(ctypes.byref(c), st, u.ctypes.data_as(dp)) == 0
    assert np.all(_relative(got, want) < BOUND)
    assert want[:, -3:].min() == 0.0 and want[:, -3:].max() == 1.0   # reports and dropouts


def test_the_c_derivative_and_rk4_are_the_numba_kernel_bit_for_bit(model_lib):
    """2000 random states, commands and currents: kernel.derivative and one RK4 step of
    0.01 s equal the C model's exactly (the same operations in the same order, the same
    libm); what differs over a run is only the noise colouring (docs/native.md)."""
    from plant_model.remus100 import kernel
    p = kernel.pack(Remus100())
    pc = np.zeros(134)
    pc[:p.size] = p
    dp = ctypes.POINTER(ctypes.c_double)
    rng = np.random.default_rng(1)
    scale = [10, 10, 10, .3, .3, 3, 1.5, .3, .3, .2, .2, .2, .2, .2, 800]
    for _ in range(2000):
        x = rng.standard_normal(15) * scale
        cmd, cur = rng.standard_normal(3) * [.3, .3, 1000], rng.standard_normal(3) * .2
        a, b = np.zeros(15), np.zeros(15)
        kernel.derivative(p, x, cmd, cur, a)
        model_lib.remus_derivative(pc.ctypes.data_as(dp), x.ctypes.data_as(dp),
                                   cmd.ctypes.data_as(dp), cur.ctypes.data_as(dp),
                                   b.ctypes.data_as(dp))
        assert np.array_equal(a, b)
        xa, xb = x.copy(), x.copy()
        kernel.rk4(p, xa, cmd, cur, 0.01, 1)
        model_lib.remus_rk4(pc.ctypes.data_as(dp), xb.ctypes.data_as(dp),
                            cmd.ctypes.data_as(dp), cur.ctypes.data_as(dp),
                            ctypes.c_double(0.01), 1)
        assert np.array_equal(xa, xb)
    assert np.any(a != 0.0)


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    """The pythonfmu FMUs of both kinds (formation-4, per vehicle) and their native ones."""
    out = tmp_path_factory.mktemp("remus_native")
    built = {}
    for model in ("remus100-6dof", "remus100-6dof-guided"):
        sc = load_scenario("formation-4").with_run(
            T=2.0, deployment="per-vehicle", architecture="distributed", seed=SEED
        ).with_vehicle_model(model)
        cfgs = per_vehicle_configs(sc, "distributed", estimator="kalman", seed=SEED,
                                   tracking=sc.tracking)
        built.update(build_fmus(None, out / model, kinds=build_configs(cfgs)))
    native = {k: native_remus_fmu(k, built[k], out / "native")
              for k in ("remus6dof", "remus6dof_actuated")}
    return {**native, **{f"python_{k}": built[k] for k in native}}


class _Fmu:
    def __init__(self, path, tmp):
        self.md = read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.outs = [v.name for v in self.md.modelVariables if v.causality == "output"]
        self.ins = [v.name for v in self.md.modelVariables if v.causality == "input"]
        self.log = FmuLog()
        self.messages = self.log.messages            # (status, text)
        self.s = FMU2Slave(guid=self.md.guid, unzipDirectory=extract(str(path), str(tmp)),
                           modelIdentifier=self.md.coSimulation.modelIdentifier,
                           instanceName="remus")
        self.s.instantiate(callbacks=self.log.callbacks, loggingOn=True)

    def init(self, reals=None, ints=None, strings=None):
        self.s.setupExperiment(startTime=0.0)
        self.s.enterInitializationMode()
        for k, v in (strings or {}).items():
            self.s.setString([self.vr[k]], [v])
        for k, v in (reals or {}).items():
            self.s.setReal([self.vr[k]], [v])
        for k, v in (ints or {}).items():
            self.s.setInteger([self.vr[k]], [v])
        self.s.exitInitializationMode()

    def out(self):
        return np.array(self.s.getReal([self.vr[o] for o in self.outs]))

    def step(self, k, u):
        self.s.setReal([self.vr[i] for i in self.ins], list(u))
        self.s.doStep(k * 0.01, 0.01)


def _start(f, view):
    f.init({**{f"x0[{i + 1}]": float(v) for i, v in enumerate(view.x0)}},
           {"vehicle": VEHICLE, "seed": SEED}, {"noise_convention": "intensity"})


@pytest.mark.slow
@pytest.mark.parametrize("kind, cls", [("remus6dof", Remus6dofPlant),
                                       ("remus6dof_actuated", ActuatedRemus6dofPlant)])
def test_the_native_fmu_is_the_pythonfmu_fmu(fmus, tmp_path, kind, cls):
    """Vehicle 3 with its autopilot (force in) and open loop (commands in), 500 steps: the
    native FMU's outputs against the pythonfmu FMU's (and the plant stepped by hand)."""
    assert validate_fmu(str(fmus[kind])) == []
    plant, view = _plant(cls)
    f = _Fmu(fmus[kind], tmp_path / "native")
    py = _Fmu(fmus[f"python_{kind}"], tmp_path / "python")
    assert f.outs == py.outs and f.ins == py.ins
    _start(f, view)
    _start(py, view)
    steps = 500
    U = _inputs(kind == "remus6dof_actuated", steps)
    got, ref, want = (np.zeros((steps, plant.output.size)) for _ in range(3))
    for k in range(steps):
        got[k], ref[k], want[k] = f.out(), py.out(), plant.output
        f.step(k, U[k])
        py.step(k, U[k])
        plant.step(U[k])
    py.s.terminate()
    rel = _relative(got, ref)
    assert np.all(rel < BOUND), dict(zip(f.outs, rel))
    assert np.array_equal(ref, want)                  # the pythonfmu FMU is that plant
    assert np.ptp(want[:, 14]) > 0.01                 # it turns: the test sees the dynamics


@pytest.mark.slow
def test_a_restored_state_repeats_the_steps_bit_for_bit(fmus, tmp_path):
    plant, view = _plant(Remus6dofPlant)
    f = _Fmu(fmus["remus6dof"], tmp_path)
    _start(f, view)
    U = _inputs(False, 100)
    for k in range(50):
        f.step(k, U[k])
    state = f.s.getFMUstate()
    blob = f.s.serializeFMUstate(state)
    first = []
    for k in range(50, 100):
        f.step(k, U[k])
        first.append(f.out())
    for restore in (lambda: f.s.setFMUstate(state),
                    lambda: f.s.setFMUstate(f.s.deSerializeFMUstate(blob))):
        restore()
        again = []
        for k in range(50, 100):
            f.step(k, U[k])
            again.append(f.out())
        assert np.array_equal(np.array(first), np.array(again))


@pytest.mark.slow
@pytest.mark.parametrize("reals, ints, named", [
    ({"remus.L": 1.7}, {}, "remus.L"),                     # derived at export
    ({"W_x[2,2]": 2e-4}, {}, "W_x[2,2]"),
    ({"substep": 0.003}, {}, "substep"),                   # does not divide h
    ({"autopilot.U_max": 0.0}, {}, "autopilot.U_max"),
    ({}, {"vehicle": 0}, "vehicle"),
    ({}, {}, "noise_convention"),                           # a String, built in at export
])
def test_a_bad_parameter_is_an_error_naming_it(fmus, tmp_path, reals, ints, named):
    f = _Fmu(fmus["remus6dof"], tmp_path)
    strings = {"noise_convention": "per_sample"} if named == "noise_convention" else {}
    with pytest.raises(Exception, match="fmi2ExitInitializationMode|fmi2SetString"):
        f.init(reals, ints, strings)
    assert any(f"parameter {named} " in m for _, m in f.messages), f.messages


@pytest.mark.slow
def test_a_nan_input_is_an_error_naming_it(fmus, tmp_path):
    f = _Fmu(fmus["remus6dof_actuated"], tmp_path)
    _start(f, _plant(ActuatedRemus6dofPlant)[1])
    with pytest.raises(Exception, match="fmi2DoStep"):
        f.step(0, [1000.0, float("nan"), 0.0])
    assert any("input rudder_command = nan" in m for _, m in f.messages), f.messages
    f.step(0, [1000.0, 0.0, 0.0])                      # the host goes on: no crash
    assert np.all(np.isfinite(f.out()))


def test_vehicles_that_differ_in_an_exported_parameter_are_refused_by_name():
    """One native FMU serves vehicles that differ only in what it reads at run time (x0,
    w0, seed, vehicle, substep, autopilot gains); a fixed parameter that differs is named
    (native_system then keeps the pythonfmu FMU)."""
    from types import SimpleNamespace

    from orchestrator.cosim.native_remus import VehiclesDiffer, native_remus_components
    one = {"remus.L": 1.6, "x0[1]": 0.0, "vehicle": 1, "autopilot.K_u": 300.0}
    comps = (SimpleNamespace(name="vehicle_1", fmu="remus6dof", parameters=one),
             SimpleNamespace(name="vehicle_2", fmu="remus6dof",
                             parameters={**one, "x0[1]": 5.0, "vehicle": 2,
                                         "autopilot.K_u": 200.0, "remus.L": 1.7}))
    with pytest.raises(VehiclesDiffer, match=r"vehicle_2: its parameter remus.L = 1.7"):
        native_remus_components("remus6dof", "unused.fmu", comps, "unused")

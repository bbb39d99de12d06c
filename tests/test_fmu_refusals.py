"""What a careless or hostile host meets, FMU by FMU: each refusal is an FMI status with a
logged message naming the variable, the value or the time, and the message reaches the
error the master raises for that instance.

- The native (C) FMUs (fmu_common/native/fmu_core.c) checked through fmpy with raw calls:
  non-finite inputs and parameters, steps and communication points, the state machine,
  fmi2Instantiate's name, type, GUID and resource location.
- The pythonfmu slaves: a non-finite parameter (any of them), and what pythonfmu 0.7 does
  not let a slave see (the GUID, the FMU type: docs/known-problems.md).
- The messages of every instance filed under that instance (orchestrator.cosim.instance),
  whatever the instance names and whichever instance was made last: a per-vehicle fleet
  whose vehicle refuses a step while another fleet with the same instance names has come
  and gone in the same process.
"""
from __future__ import annotations

import ctypes
import dataclasses
import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract

from orchestrator.cosim.instance import CosimError, Extracted, FmuInstance, FmuLog
from orchestrator.cosim.master import run_system
from orchestrator.interop.native import native_system
from orchestrator.running import build, scenario_system
from orchestrator.scenario import load_scenario
from support.fmi import steps_until_refused

OK, DISCARD, ERROR, FATAL = 0, 2, 3, 4
H = 0.01
needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler (cc)")


@pytest.fixture(scope="module")
def paper(tmp_path_factory):
    """The paper's scenario, its pythonfmu FMUs and (with a compiler) its native FMUs."""
    tmp = tmp_path_factory.mktemp("refusals")
    sc = load_scenario("paper").with_run(T=5.0)
    system = scenario_system(sc)
    py = build(sc, tmp / "py")
    ns = native_system(system, py, tmp / "native") if shutil.which("cc") else None
    return sc, system, py, ns, tmp


def _open(path: Path, folder: Path, name: str = "probe", **parameters) -> FmuInstance:
    """An instance of ``path`` in step mode at t = 0 (``parameters`` set first)."""
    inst = FmuInstance(name, path, extract(str(path), unzipdir=str(folder / name)), name)
    inst.initialize(parameters, T=10.0)
    return inst


def _raw(inst: FmuInstance, name: str, argtypes: list):
    f = inst.slave.dll[name]
    f.argtypes, f.restype = argtypes, ctypes.c_int
    return f


def _get(inst: FmuInstance, names: list[str]) -> tuple[int, list[float]]:
    out = (ctypes.c_double * len(names))()
    st = inst.get_real(inst.component, inst.vrs(names), len(names), out)
    return st, list(out)


def _set(inst: FmuInstance, names: list[str], values: list[float]) -> int:
    return inst.set_real(inst.component, inst.vrs(names), len(names),
                         (ctypes.c_double * len(values))(*values))


def _step(inst: FmuInstance, t: float, h: float = H) -> int:
    return inst.do_step(inst.component, t, h, 1)


def _last(inst: FmuInstance) -> str:
    return inst.messages[-1][1] if inst.messages else ""


def _names(inst: FmuInstance, causality: str) -> list[str]:
    return [v.name for v in inst.md.modelVariables if v.causality == causality]


# ------------------------------------------------------------------ native: values
@needs_cc
def test_native_nan_input_is_an_error_at_get_and_at_step_naming_it(paper, tmp_path):
    """The controller's estimate xhat[1] = NaN: its force u (direct feedthrough) is refused
    at fmi2GetReal naming the output and the input; the step is refused naming the input;
    a finite value set again, the controller steps on."""
    *_, ns, _ = paper
    c = _open(ns.fmus["controller"], tmp_path)
    assert _set(c, ["xhat[1]"], [math.nan]) == OK
    status, u = _get(c, ["u[1]", "u[2]"])
    assert status == ERROR and math.isnan(u[0])
    assert _last(c) == "output u[1] = nan at t = 0 s is not finite: input xhat[1] = nan"
    assert _step(c, 0.0) == ERROR
    assert _last(c) == ("step at t = 0 s refused: input xhat[1] = nan is not finite (set it "
                        "to a finite value and step again)")
    assert _set(c, ["xhat[1]"], [0.5]) == OK
    assert _get(c, ["u[1]"])[0] == OK and _step(c, 0.0) == OK
    c.close()


@needs_cc
def test_native_plant_fed_1e308_refuses_the_step_naming_the_state(paper, tmp_path):
    """Finite inputs of 1e308: the state would overflow; the step is refused (fmi2Error)
    naming the instance, the state element and the time; the state is left as it was."""
    *_, ns, _ = paper
    p = _open(ns.fmus["plant"], tmp_path, "plant_1e308")
    inputs = _names(p, "input")
    assert _set(p, inputs, [1e308] * len(inputs)) == OK
    k, status = steps_until_refused(lambda t: _step(p, t), H, 100)
    assert status == ERROR
    t = (k - 1) * H
    assert re.fullmatch(rf"plant_1e308: state element \d would become -?inf in the step from "
                        rf"t = {t:g} s to {t + H:g} s \(the step is not taken\)", _last(p))
    assert _step(p, (k - 1) * H) == ERROR             # nothing moved: the same refusal
    p.close()


@needs_cc
def test_native_nan_parameter_fails_initialization_naming_it(paper, tmp_path):
    *_, ns, _ = paper
    with pytest.raises(CosimError) as err:
        _open(ns.fmus["estimator"], tmp_path, "nan_gain", **{"Ce[1,1]": math.inf})
    assert str(err.value).endswith("parameter Ce[1,1] = inf is not finite")
    assert "fmi2ExitInitializationMode failed with status 3 (error)" in str(err.value)


# ------------------------------------------------------------------ native: time
@needs_cc
@pytest.mark.parametrize("key, t, h, message", [
    ("controller", 0.0, -0.01, "communication step -0.01 s at t = 0 s: the step size must be "
                               "a positive number"),
    ("controller", 0.0, math.nan, "communication step nan s at t = 0 s: the step size must "
                                  "be a positive number"),
    ("plant", 0.0, math.nan, "communication step nan s at t = 0 s: the step size must be a "
                             "positive number"),
    ("plant", 0.0, 0.02, "communication step 0.02 s at t = 0 s: this FMU is designed for "
                         "h = 0.01 s (a step within 1e-09 h of it)"),
    ("plant", 100.0, H, "communication point t = 100 s: this FMU expects t = 0 s (the end "
                        "of its last step, within 1e-08 s)"),
    ("plant", -50.0, H, "communication point t = -50 s: this FMU expects t = 0 s"),
    ("plant", 0.01, H, "communication point t = 0.01 s: this FMU expects t = 0 s"),
    ("controller", 3e-8, H, "communication point t = 2.9999999999999997e-08 s: this FMU "
                            "expects t = 0 s"),
])
def test_native_steps_and_communication_points_are_checked(paper, tmp_path, key, t, h,
                                                           message):
    """A step size that is not positive, not h (a fixed-step FMU), or a communication point
    other than the end of the last step (within 1e-6 of the step): fmi2Error, the message
    naming the step, the time and what was expected; nothing moves, and the right step is
    taken after it (t = 0 then 0.01: every point of the issue's list but the right one is
    refused)."""
    *_, ns, _ = paper
    inst = _open(ns.fmus[key], tmp_path, f"{key}_t")
    assert _step(inst, t, h) == ERROR
    assert message in _last(inst)
    assert _step(inst, 0.0) == OK and _step(inst, H) == OK
    assert _step(inst, 2 * H + 1e-9) == OK             # within 1e-6 h of 0.02: that point
    inst.close()


# ------------------------------------------------------------------ native: state machine
@needs_cc
def test_native_state_machine(paper, tmp_path):
    """fmi2DoStep before initialization, in initialization mode and after fmi2Terminate;
    a parameter set after initialization; a stop time before the start: fmi2Error, each
    named."""
    *_, ns, _ = paper
    path = ns.fmus["plant"]
    d = extract(str(path), unzipdir=str(tmp_path / "sm"))
    inst = FmuInstance("plant", path, d, "sm")
    assert _step(inst, 0.0) == ERROR
    assert _last(inst) == ("fmi2DoStep at t = 0 s refused: called before initialization "
                           "(fmi2EnterInitializationMode and fmi2ExitInitializationMode "
                           "come first)")
    setup = _raw(inst, "fmi2SetupExperiment", [ctypes.c_void_p, ctypes.c_int, ctypes.c_double,
                                               ctypes.c_double, ctypes.c_int, ctypes.c_double])
    assert setup(inst.component, 0, 0.0, 0.0, 1, -1.0) == ERROR
    assert _last(inst) == "stop time -1 s: it must not be before the start time 0 s"
    inst.slave.setupExperiment(startTime=0.0, stopTime=10.0)
    inst.slave.enterInitializationMode()
    assert _step(inst, 0.0) == ERROR
    assert "refused: called in initialization mode (call fmi2ExitInitializationMode first)" \
        in _last(inst)
    inst.slave.exitInitializationMode()
    assert _set(inst, ["Ad[1,1]"], [0.5]) == ERROR
    assert _last(inst) == "parameter Ad[1,1] is fixed after initialization"
    assert _step(inst, 0.0) == OK
    inst.slave.terminate()
    assert _step(inst, H) == ERROR
    assert "refused: called after fmi2Terminate (fmi2Reset or instantiate again)" \
        in _last(inst)
    inst.slave.freeInstance()


# ------------------------------------------------------------------ native: instantiation
def _instantiate(path: Path, folder: Path, *, name: bytes | None = b"inst", kind: int = 1,
                 guid: bytes | None = None, resources: bytes | None = b"") -> tuple[int, list]:
    """fmi2Instantiate of the FMU's library, raw; (component or 0, the messages logged)."""
    from fmpy import read_model_description
    md = read_model_description(str(path))
    d = extract(str(path), unzipdir=str(folder))
    lib = ctypes.CDLL(str(Path(d, "binaries", "linux64",
                                f"{md.coSimulation.modelIdentifier}.so")))
    inst = lib.fmi2Instantiate
    inst.argtypes = [ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p,
                     ctypes.c_void_p, ctypes.c_int, ctypes.c_int]
    inst.restype = ctypes.c_void_p
    log = FmuLog()
    if resources == b"":
        resources = Path(d, "resources").as_uri().encode()
    comp = inst(name, kind, md.guid.encode() if guid is None else guid, resources,
                ctypes.addressof(log.callbacks), 0, 1)
    if comp:
        free = lib.fmi2FreeInstance
        free.argtypes, free.restype = [ctypes.c_void_p], None
        free(comp)
    return comp or 0, [m for _, m in log.messages]


@needs_cc
@pytest.mark.parametrize("case, kwargs, message", [
    ("wrong GUID", {"guid": b"{not-this-one}"},
     "fmi2Instantiate of instance 'inst' refused: GUID {not-this-one} does not match this "
     "FMU's {"),
    ("no GUID", {"guid": b""}, "refused: GUID  does not match this FMU's"),
    ("model exchange", {"kind": 0},
     "fmi2Instantiate of instance 'inst' refused: the FMU type 0 is not fmi2CoSimulation "
     "(1): this FMU is for co-simulation only"),
    ("no name", {"name": None},
     "fmi2Instantiate refused: the instance name is NULL (FMI 2.0 asks for a non-empty one)"),
    ("empty name", {"name": b"  "},
     "fmi2Instantiate refused: the instance name is empty"),
])
def test_native_instantiation_refused_with_a_logged_reason(paper, tmp_path, case, kwargs,
                                                           message):
    *_, ns, _ = paper
    comp, messages = _instantiate(ns.fmus["controller"], tmp_path / "i", **kwargs)
    assert comp == 0
    assert len(messages) == 1 and message in messages[0], messages


@needs_cc
@pytest.mark.parametrize("resources", [None, b"file:///no/such/folder/resources",
                                       b"not a URI %zz"])
def test_native_fmu_needs_no_resource_location(paper, tmp_path, resources):
    """A NULL, missing or undecodable resource location (which crashes a host with
    pythonfmu 0.7's FMUs) is fine: a native FMU uses none."""
    *_, ns, _ = paper
    comp, messages = _instantiate(ns.fmus["plant"], tmp_path / "r", resources=resources)
    assert comp != 0 and messages == []


# ------------------------------------------------------------------ pythonfmu slaves
def test_pythonfmu_nan_parameter_fails_initialization_naming_it(paper, tmp_path):
    """The controller's gain K[1,1] = NaN (nothing else checks a gain): fmi2Fatal at
    fmi2ExitInitializationMode (all pythonfmu 0.7 lets a slave give there), the parameter
    named with its value."""
    sc, system, py, *_ = paper
    comp = system.component("controller")
    with pytest.raises(CosimError) as err:
        _open(py["controller"], tmp_path, "py_nan", **{**comp.parameters, "K[1,1]": math.nan})
    msg = str(err.value)
    assert "status 4 (fatal)" in msg
    assert ("AuvController instance 'py_nan': initialization failed: parameter K[1,1] = nan "
            "is not finite") in msg


def test_pythonfmu_nan_input_is_refused_at_the_step_naming_it(paper, tmp_path):
    sc, system, py, *_ = paper
    c = _open(py["controller"], tmp_path, "py_in", **system.component("controller").parameters)
    assert _set(c, ["xhat[2]"], [math.inf]) == OK         # pythonfmu: OK or Fatal only
    assert _step(c, 0.0) == DISCARD
    assert _last(c) == ("AuvController instance 'py_in': step at t = 0.0 s refused: input "
                        "xhat[2] = inf is not finite")
    c.close()


def test_pythonfmu_controller_fed_1e308_discards_the_step_naming_the_output(paper, tmp_path):
    """The counterpart of the native controller's refusal: estimates of 1e308 (finite,
    accepted) make u = -K xhat non-finite. fmi2GetReal answers fmi2OK (pythonfmu 0.7: OK or
    Fatal only) and logs the output; fmi2DoStep is refused with fmi2Discard (its only
    refusal) naming the instance, the output, its value and the time; with finite estimates
    set again the controller steps on."""
    sc, system, py, *_ = paper
    c = _open(py["controller"], tmp_path, "py_big", **system.component("controller").parameters)
    est = _names(c, "input")
    assert _set(c, est, [1e308] * len(est)) == OK
    status, u = _get(c, ["u[2]", "u[1]"])                 # not in order: the getters' path
    assert status == OK and not all(map(math.isfinite, u))
    assert re.fullmatch(r"AuvController instance 'py_big': output u\[1\] = (-?inf|nan) at "
                        r"t = 0\.0 s is not finite; the next step will be refused", _last(c))
    assert _step(c, 0.0) == DISCARD
    assert re.fullmatch(r"AuvController instance 'py_big': step at t = 0\.0 s refused: output "
                        r"u\[1\] = (-?inf|nan) at t = 0\.0 s is not finite", _last(c))
    assert _set(c, est, [0.5] * len(est)) == OK
    assert _step(c, 0.0) == OK and _get(c, ["u[1]"])[0] == OK
    c.close()


def test_pythonfmu_estimator_fed_1e308_discards_the_step_naming_the_output(paper, tmp_path):
    """Measurements of 1e308 into the estimator: its estimates grow until one overflows;
    that step is refused (fmi2Discard) naming the estimate, its value and the time, and the
    next one too while the inputs stay."""
    sc, system, py, *_ = paper
    e = _open(py["estimator"], tmp_path, "py_est", **system.component("estimator").parameters)
    inputs = _names(e, "input")
    assert _set(e, inputs, [1e308] * len(inputs)) == OK
    k, status = steps_until_refused(lambda t: _step(e, t), H, 100)
    assert status == DISCARD and k > 1                    # some steps were finite
    t = (k - 1) * H
    assert re.fullmatch(rf"AuvEstimator instance 'py_est': step at t = {t} s refused: output "
                        rf"(xhat|what|zhat)\[\d\] = -?inf at t = {t} s is not finite",
                        _last(e)), _last(e)
    assert _step(e, t) == DISCARD
    e.close()


def _with(system, comp: str, **parameters):
    return dataclasses.replace(system, components=tuple(
        dataclasses.replace(c, parameters={**c.parameters, **parameters})
        if c.name == comp else c for c in system.components))


def test_the_master_names_the_fmu_and_the_output_that_went_non_finite(paper):
    """Through the run path (run_system, pythonfmu FMUs): an unstable plant (A[1,1] = 100 /s)
    overflows; its step is refused and the error, one line, names the plant, the output and
    the time. An estimator started at 1e308: its estimate is read (fmi2OK: all pythonfmu 0.7
    lets a getter answer) and reaches the controller and the plant, which refuses the step;
    the error leads with the estimator and its output, not the plant's input."""
    sc, system, py, *_ = paper
    with pytest.raises(CosimError) as err:
        run_system(_with(system, "plant", **{"A[1,1]": 100.0}), py, 1000)
    msg = str(err.value)
    assert len(msg.splitlines()) == 1
    assert re.match(r"plant FMU: fmi2DoStep at t = [\d.]+ s returned Discard: AuvPlant "
                    r"instance 'plant': output \w+\[\d\] = -?inf at t = [\d.]+ s is not "
                    r"finite after the step from t = [\d.]+ s \(further steps are refused\)$",
                    msg), msg
    with pytest.raises(CosimError) as err:
        run_system(_with(system, "estimator", **{"x0[1]": 1e308}), py, sc.steps)
    msg = str(err.value)
    assert len(msg.splitlines()) == 1 and "status 2" not in msg
    assert re.match(r"estimator FMU: output xhat\[1\] = -?inf at t = 0\.0 s is not finite "
                    r"\(read with fmi2GetReal\); then plant FMU: fmi2DoStep at t = 0\.0 s "
                    r"returned Discard: ", msg), msg


# ------------------------------------------------------------------ messages reach the error
def test_messages_are_filed_by_instance_not_by_name(paper, tmp_path):
    """Two instances with one instance name (two runs in one process), then a third made
    and freed: each refusal is filed under the instance that logged it, and a message
    after the last-made instance is gone is still filed (fmpy's logger proxy would call
    that freed instance's callback: a crash)."""
    import gc
    sc, system, py, ns, _ = paper
    for kind, fmus in (("python", py), ("native", ns.fmus if ns else None)):
        if fmus is None:
            continue
        params = system.component("controller").parameters if kind == "python" else {}
        ex = Extracted({"controller": fmus["controller"]})
        first, second = (FmuInstance(label, fmus["controller"], ex.dirs["controller"], "same")
                         for label in ("first", "second"))
        for inst in (first, second):
            inst.initialize(params, T=10.0)
        assert _step(first, 0.0, -1.0) != OK
        assert "step size must be a positive number" in first.errors()
        assert second.errors() == "(the FMU logged no message)"
        third = FmuInstance("third", fmus["controller"], ex.dirs["controller"], "third")
        third.close()
        del third
        gc.collect()
        assert _step(second, 0.0, math.nan) != OK
        assert "step size must be a positive number" in second.errors(), kind
        first.close()
        second.close()
        ex.cleanup()


@pytest.mark.slow
def test_a_refusal_in_a_per_vehicle_fleet_names_the_instance_and_the_cause(tmp_path):
    """formation-4 per vehicle, vehicle 2 unstable (A[1,1] = 100 /s: its state overflows
    after a few seconds). While the run is under way (after its first 200 steps) the same
    fleet runs whole in the same process, with the same instance names, and is freed. The
    error raised for vehicle 2 names its instance and what became non-finite, with the
    time; before, the message went to the other fleet's instance of that name, or to a
    freed callback."""
    sc = load_scenario("formation-4").with_run(T=8.0, deployment="per-vehicle",
                                               architecture="distributed")
    system = scenario_system(sc)
    fmus = build(sc, tmp_path / "py")
    bad = dataclasses.replace(system, components=tuple(
        dataclasses.replace(c, parameters={**c.parameters, "A[1,1]": 100.0})
        if c.name == "vehicle_2" else c for c in system.components))

    class Meanwhile:
        """A progress bar whose first update runs the healthy fleet to the end."""
        done = 0

        def update(self, n: int) -> None:
            if not self.done:
                traces, _, _ = run_system(system, fmus, 300, instance_suffix="_run")
                assert np.all(np.isfinite(traces["vehicle_2.y"]))
            self.done += n

    bar = Meanwhile()
    with pytest.raises(CosimError) as err:
        run_system(bad, fmus, sc.steps, progress=bar, instance_suffix="_run")
    msg = str(err.value)
    assert bar.done >= 200                                   # it failed after the other run
    assert msg.startswith("vehicle_2 FMU: fmi2DoStep at t = "), msg
    assert "returned Discard: AuvVehicle instance 'vehicle_2_run'" in msg
    assert "fmi2DoStep refused: outputs" in msg and "became non-finite in the step" in msg
    assert "logged no message" not in msg


@needs_cc
def test_the_c_host_prints_the_fmus_reason_and_the_status(paper, tmp_path):
    """orchestrator/interop/native_host/c_host.c (no Python) on the paper's native system: a GUID that is not
    the controller's and a NaN input step: the FMU's own message through the logger (its
    instance in brackets), then one line naming the instance, the call, t and the status;
    exit status 1."""
    import subprocess

    from orchestrator.benchmarks.native import c_host_binary, write_c_host_system
    sc, _, _, ns, _ = paper
    exe = c_host_binary(tmp_path)
    sysfile = write_c_host_system(ns.system, ns.fmus, tmp_path / "u")
    text = sysfile.read_text()
    guid = next(ln.split()[3] for ln in text.splitlines() if ln.startswith("fmu controller "))
    (tmp_path / "guid.txt").write_text(text.replace(guid, "{0000}"))
    r = subprocess.run([str(exe), str(tmp_path / "guid.txt"), "10", repr(sc.h),
                        str(tmp_path / "a.csv")], capture_output=True, text=True, env={},
                       timeout=60)
    assert r.returncode == 1
    assert r.stderr.splitlines() == [
        f"[controller] fmi2Instantiate of instance 'controller' refused: GUID {{0000}} does "
        f"not match this FMU's {guid} (a modelDescription.xml of another build?)",
        "c_host: controller fmi2Instantiate failed at t = 0"]
    from fmpy import read_model_description
    vr = next(v.valueReference for v in read_model_description(str(ns.fmus["plant"]))
              .modelVariables if v.name == "Ad[1,1]")
    (tmp_path / "grow.txt").write_text(text + f"real plant {vr} 1e300\n")
    r = subprocess.run([str(exe), str(tmp_path / "grow.txt"), "10", repr(sc.h),
                        str(tmp_path / "b.csv")], capture_output=True, text=True, env={},
                       timeout=60)
    assert r.returncode == 1
    lines = r.stderr.splitlines()
    assert lines[-1].startswith("c_host: plant fmi2") and lines[-1].endswith("(Error)")
    assert lines[0].startswith("[plant] ") and (
        "is not finite" in lines[0] or "would become" in lines[0]), lines
    assert not (tmp_path / "b.csv").exists()

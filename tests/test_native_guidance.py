"""The native (C) AuvGuidance and AuvAutopilot (orchestrator.cosim.native_guidance,
fmu_common/native/guidance_fmu.c, autopilot_fmu.c), built from the pythonfmu FMUs the real
way and run side by side with them through fmpy: the same interface, the same numbers to
1e-12 (the held course below U_min, a saturated stretch with anti-windup), errors as
statuses with a logged message, state save and restore, fmpy's validator."""
from __future__ import annotations

import math
import shutil
import subprocess
import zipfile

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu
from lxml import etree

from orchestrator.cosim.build import build_fmus
from orchestrator.cosim.native_guidance import native_guidance_fmu
from orchestrator.running.fmus import guidance_configs
from orchestrator.scenario import load_scenario
from plant_model.remus100.autopilot import AutopilotGains
from plant_model.remus100.setpoint_autopilot import DepthLoop, limit_command, setpoint_command
from support.fmi import open_initializing

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler (cc)")

SETPOINTS = ["speed", "course", "depth", "speed_rate", "course_rate", "depth_rate"]
SENSORS = ([f"velocity[{i}]" for i in (1, 2, 3)] + [f"attitude[{i}]" for i in (1, 2, 3)]
           + [f"rates[{i}]" for i in (1, 2, 3)] + ["measured_depth"])
U = ["u[1]", "u[2]", "u[3]"]
INPUTS = {"guidance": U, "autopilot": SETPOINTS + SENSORS}
OUTPUTS = {"guidance": SETPOINTS + ["v_ref[1]", "v_ref[2]", "v_ref[3]"],
           "autopilot": ["rpm", "rudder", "stern", "saturated"]}


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    """{kind: (pythonfmu .fmu, native .fmu)} for the example scenario (vehicle 1's design
    model and start as start values)."""
    tmp = tmp_path_factory.mktemp("native_guidance")
    sc = load_scenario("docs/examples/straight-leader.toml")
    py = build_fmus(None, tmp / "py", kinds=guidance_configs(sc))
    return {k: (py[k], native_guidance_fmu(k, py[k], tmp / "native")) for k in py}


def _pair(fmus, kind, tmp_path):
    py, nat = (open_initializing(p, tmp_path, f"{kind}-{i}") for i, p in enumerate(fmus[kind]))
    py.slave.exitInitializationMode()
    nat.slave.exitInitializationMode()
    return py, nat


def _guidance_force(rng, k):
    """N: a random force; from step 150 to 299 almost none (the reference velocity decays
    below U_min: the course is held), then strong turns and dives."""
    if 150 <= k < 300:
        return rng.normal(0.0, 0.01, 3)
    return rng.normal(0.0, 10.0, 3) + (np.array([-40.0, 30.0, 5.0]) if k >= 300 else 0.0)


def _autopilot_inputs(rng, k):
    sp = np.array([rng.uniform(0.5, 2.5), rng.uniform(-3, 3), 20 + rng.normal(0, 3),
                   0.0, rng.normal(0, 0.05), rng.normal(0, 0.2)])
    if 150 <= k < 250:
        sp[0] = 6.0                  # beyond the propeller's reach: rpm at n_max, held
    if 250 <= k < 300:
        sp[0] = 0.05                 # below U_min: no flight path commanded
    meas = np.concatenate([[rng.uniform(1, 2), rng.normal(0, .1), rng.normal(0, .1)],
                           rng.normal(0, 0.1, 2), [rng.uniform(-3, 3)],
                           rng.normal(0, 0.05, 3), [20 + rng.normal(0, 3)]])
    return np.concatenate([sp, meas])


def _run_side_by_side(py, nat, kind, steps, seed):
    """Both FMUs on the same inputs, steps of 0.05 s and 0.02 s in turn; the outputs of
    each (steps x outputs) and the inputs."""
    rng = np.random.default_rng(seed)
    vin, vout = [py.vr[n] for n in INPUTS[kind]], [py.vr[n] for n in OUTPUTS[kind]]
    assert vin == [nat.vr[n] for n in INPUTS[kind]]          # the same value references
    outs, feed, t = {"py": [], "nat": []}, [], 0.0
    for k in range(steps):
        x = _guidance_force(rng, k) if kind == "guidance" else _autopilot_inputs(rng, k)
        feed.append(x)
        h = 0.05 if k % 3 else 0.02
        for key, inst in (("py", py), ("nat", nat)):
            inst.slave.setReal(vin, list(x))
            outs[key].append(inst.slave.getReal(vout))
            inst.slave.doStep(t, h)
        t += h
    return np.array(outs["py"]), np.array(outs["nat"]), np.array(feed)


def test_native_guidance_equals_the_pythonfmu_one_and_holds_the_course_below_U_min(
        fmus, tmp_path):
    py, nat = _pair(fmus, "guidance", tmp_path)
    ref, got, _ = _run_side_by_side(py, nat, "guidance", 450, seed=3)
    assert np.abs(got - ref).max() <= 1e-12
    U_min = nat.slave.getReal([nat.vr["U_min"]])[0]
    v_h = np.hypot(got[:, 6], got[:, 7])
    slow = v_h <= U_min
    assert slow.sum() > 20 and (~slow).sum() > 300               # both regimes visited
    course = got[:, 1]
    assert np.all(course[slow] == course[np.argmax(slow)])     # held, not atan2 of noise
    assert np.all(got[slow, 4] == 0.0)                          # no course rate there
    assert np.ptp(course) > 1.0 and np.ptp(got[:, 2]) > 0.1   # it turned and dived
    py.close()
    nat.close()


def test_native_autopilot_equals_the_pythonfmu_one_and_holds_its_integral_when_saturated(
        fmus, tmp_path):
    py, nat = _pair(fmus, "autopilot", tmp_path)
    ref, got, feed = _run_side_by_side(py, nat, "autopilot", 400, seed=9)
    assert np.abs(got - ref).max() <= 1e-12
    # the plain functions on the same inputs (steps 0.02, 0.05, 0.05, ...): the speed
    # integral does not move while the propeller is at its limit
    g, dl = AutopilotGains(), DepthLoop()
    integ, expect, held = np.zeros(2), [], []
    for k, x in enumerate(feed):
        cmd, err = setpoint_command(g, dl, x[:6], x[6:9], x[9:12], x[12:15], x[15], integ)
        lim, sat = limit_command(g, cmd)
        expect.append([lim[2], lim[0], lim[1], float(sat)])
        integ = integ + err * (0.05 if k % 3 else 0.02)
        held.append(integ[0])
    assert np.abs(got - np.array(expect)).max() <= 1e-12
    assert np.all(got[150:250, 0] == g.n_max) and np.all(got[150:250, 3] == 1.0)
    assert np.ptp(held[150:250]) == 0.0 and np.ptp(held[:150]) > 0.0
    assert np.abs(got[:, 2]).max() == g.delta_max                # the fins clip too
    py.close()
    nat.close()


@pytest.mark.parametrize("kind", ["guidance", "autopilot"])
def test_native_state_save_and_restore_continue_identically(fmus, tmp_path, kind):
    """Half way: get the state; the second half replays bit for bit after fmi2SetFMUstate
    and after a serialize / deserialize round trip (the time is part of the state)."""
    inst = open_initializing(fmus[kind][1], tmp_path)
    s = inst.slave
    s.exitInitializationMode()
    rng = np.random.default_rng(4)
    feed = [_guidance_force(rng, k) if kind == "guidance" else _autopilot_inputs(rng, k)
            for k in range(200)]
    vin, vout = [inst.vr[n] for n in INPUTS[kind]], [inst.vr[n] for n in OUTPUTS[kind]]

    def drive(k0, k1):
        rows = []
        for k in range(k0, k1):
            s.setReal(vin, list(feed[k]))
            rows.append(s.getReal(vout))
            s.doStep(k * 0.05, 0.05)
        return np.array(rows)

    drive(0, 100)
    state = s.getFMUState()
    first = drive(100, 200)
    s.setFMUState(state)
    assert np.array_equal(drive(100, 200), first)
    blob = s.serializeFMUState(state)
    s.setFMUState(s.deserializeFMUState(blob))
    assert np.array_equal(drive(100, 200), first)
    assert np.std(first[:, 0]) > 0
    s.freeFMUState(state)
    inst.close()


def _attributes(path):
    md = read_model_description(str(path))
    return [(v.name, v.valueReference, v.causality, v.variability, v.initial, v.unit,
             v.start, v.description, v.type) for v in md.modelVariables]


@pytest.mark.parametrize("kind", ["guidance", "autopilot"])
def test_native_fmus_validate_and_have_the_pythonfmu_interface(fmus, tmp_path, kind):
    """fmpy validates both clean; every variable (name, value reference, causality,
    variability, initial, unit, start, description) and the output dependencies are the
    pythonfmu FMU's; no Python needed (needsExecutionTool false, libc and libm only)."""
    py, nat = fmus[kind]
    assert validate_fmu(str(nat)) == []
    assert _attributes(nat) == _attributes(py)

    def structure(path):
        with zipfile.ZipFile(path) as z:
            root = etree.fromstring(z.read("modelDescription.xml"))
        return [(u.get("index"), u.get("dependencies"))
                for u in root.iterfind("ModelStructure/*/Unknown")]

    assert structure(nat) == structure(py)
    md = read_model_description(str(nat))
    cs = md.coSimulation
    assert cs.modelIdentifier == nat.stem and not cs.needsExecutionTool
    assert cs.canHandleVariableCommunicationStepSize and cs.canSerializeFMUstate
    with zipfile.ZipFile(nat) as z:
        lib = tmp_path / f"{nat.stem}.so"
        lib.write_bytes(z.read(f"binaries/linux64/{nat.stem}.so"))
        assert {"sources/fmu_core.c", "sources/native_model.h"} <= set(z.namelist())
    needed = subprocess.run(["ldd", str(lib)], capture_output=True, text=True).stdout
    assert {ln.split()[0] for ln in needed.splitlines() if "=>" in ln} <= {"libm.so.6",
                                                                         "libc.so.6"}


def _refused(inst, call, *args):
    with pytest.raises(FMICallException) as exc:
        getattr(inst.slave, call)(*args)
    return exc.value.status


@pytest.mark.parametrize("kind, case, status, fragment", [
    ("guidance", "nan input", 3, "input u[2] = nan is not finite"),
    ("autopilot", "nan input", 3, "input attitude[3] = nan is not finite"),
    ("guidance", "step -0.01", 3, "communication step -0.01 s at t = 0 s"),
    ("autopilot", "nan step", 3, "communication step nan s at t = 0 s"),
    ("guidance", "wrong point", 3, "communication point t = 0.5 s: this FMU expects t = 0 s"),
    ("autopilot", "wrong point", 3, "communication point t = 0.5 s: this FMU expects t = 0 s"),
])
def test_a_bad_input_or_step_is_an_error_status_naming_it_and_the_host_goes_on(
        fmus, tmp_path, kind, case, status, fragment):
    inst = open_initializing(fmus[kind][1], tmp_path)
    inst.slave.exitInitializationMode()
    name = "u[2]" if kind == "guidance" else "attitude[3]"
    if case == "nan input":
        inst.slave.setReal([inst.vr[name]], [math.nan])
    t, h = {"step -0.01": (0.0, -0.01), "nan step": (0.0, math.nan),
            "wrong point": (0.5, 0.05)}.get(case, (0.0, 0.05))
    assert _refused(inst, "doStep", t, h) == status
    assert any(fragment in m for st, m in inst.messages if st == "Error"), inst.messages
    inst.slave.setReal([inst.vr[name]], [0.0])
    inst.slave.doStep(0.0, 0.05)                      # fixed: it steps from where it was
    inst.slave.doStep(0.05, 0.05)
    inst.close()


@pytest.mark.parametrize("kind, parameter, value, fragment", [
    ("guidance", "M[2]", 0.0, "parameter M[2] = 0 must be a positive finite number (kg)"),
    ("guidance", "D[3]", -1.0, "parameter D[3] = -1 must be a positive finite number (kg/s)"),
    ("guidance", "depth0", math.nan, "parameter depth0 = nan is not finite"),
    ("autopilot", "n_max", 0.0, "parameter n_max = 0 must be positive"),
    ("autopilot", "K_u", math.inf, "parameter K_u = inf is not finite"),
])
def test_a_bad_parameter_fails_initialization_with_an_error_naming_it(
        fmus, tmp_path, kind, parameter, value, fragment):
    inst = open_initializing(fmus[kind][1], tmp_path, **{parameter: value})
    assert _refused(inst, "exitInitializationMode") == 3
    assert any(fragment in m for st, m in inst.messages if st == "Error"), inst.messages
    assert _refused(inst, "doStep", 0.0, 0.05) == 3                # not in step mode
    assert any("refused: called in initialization mode" in m for _, m in inst.messages)
    inst.close()


@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind is not installed")
def test_the_c_host_runs_guidance_into_autopilot_cleanly_under_valgrind(fmus, tmp_path):
    """orchestrator/interop/native_host/c_host.c (no Python in the process, an empty environment) runs the two
    native FMUs, the guidance's set-points wired into the autopilot, under valgrind
    (memcheck, full leak check): no invalid access, no definitely lost block; the guidance
    slows from its start velocity with no force (v' = -D v / M) and the autopilot follows."""
    from orchestrator.benchmarks.native import c_host_binary, write_c_host_system
    from orchestrator.cosim.build import FMU_KINDS, interface_of
    from orchestrator.cosim.system import Component, Connection, SystemDescription
    configs = guidance_configs(load_scenario("docs/examples/straight-leader.toml"))
    system = SystemDescription(
        "guidance-autopilot",
        tuple(Component(k, k, tuple(interface_of(FMU_KINDS[k], configs[k])))
              for k in ("guidance", "autopilot")),
        tuple(Connection("guidance", n, "autopilot", n) for n in SETPOINTS), 0.05, 10.0)
    exe = c_host_binary(tmp_path)
    sysfile = write_c_host_system(system, {k: fmus[k][1] for k in fmus}, tmp_path / "u",
                                  record=[("guidance", "speed"), ("autopilot", "rpm")])
    cmd = ["valgrind", "--leak-check=full", "--errors-for-leak-kinds=definite",
           "--error-exitcode=9", "-q", str(exe), str(sysfile), "200", "0.05",
           str(tmp_path / "v.csv")]
    r = subprocess.run(cmd, capture_output=True, text=True, env={}, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "Invalid" not in r.stderr and "definitely lost" not in r.stderr
    rows = np.loadtxt(tmp_path / "v.csv", delimiter=",", skiprows=1)
    assert rows.shape[0] == 200 and np.all(np.isfinite(rows))
    vr = {k: {v.name: v.valueReference for v in read_model_description(
        str(fmus[k][1])).modelVariables} for k in fmus}
    header = (tmp_path / "v.csv").read_text().splitlines()[0].split(",")
    assert header == ["time", f"guidance.{vr['guidance']['speed']}",
                      f"autopilot.{vr['autopilot']['rpm']}"]
    speed, rpm = rows[:, 1], rows[:, 2]
    assert speed[0] == pytest.approx(math.hypot(1.9, 0.05)) and np.all(np.diff(speed) < 0)
    assert np.ptp(rpm) > 100.0

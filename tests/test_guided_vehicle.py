"""remus100-6dof-guided in the project's run path: a run through ``auv-cosim run`` replayed
monolithically (guidance -> set-point autopilot -> actuated plant, plain functions over
numpy) to 1e-12, the system's wiring, and the actuated vehicle FMU under fmpy (a NaN
command refused naming it, FMU state round trips)."""
from __future__ import annotations

import ctypes
import json
import math
from pathlib import Path

import numpy as np
import pytest

from controller_fmu.guidance import depth_increment, reference_step, setpoints
from orchestrator.cli import main
from orchestrator.cosim.instance import Extracted, FmuInstance
from orchestrator.recording import read_rrd_scalars
from orchestrator.running.systems import scenario_system
from orchestrator.scenario import load_scenario
from plant_model.per_vehicle import sample_vehicle
from plant_model.remus100.autopilot import AutopilotGains
from plant_model.remus100.dynamics import Remus100
from plant_model.remus100.plant import (
    ActuatedRemus6dofPlant,
    Remus6dofPlant,
    default_substep,
    linear_mass_damping,
    substep_count,
)
from plant_model.remus100.setpoint_autopilot import DepthLoop, limit_command, setpoint_command

SEED = 3
H = 0.05            # every step recorded (the recording keeps about 20 samples per second)
T = 2.0
COMMANDS = ["rpm_command", "rudder_command", "stern_command"]
ROOT = Path(__file__).resolve().parent.parent


def _scenario(tmp_path):
    src = ROOT / "orchestrator/scenario/builtin/formation-4.toml"
    path = tmp_path / "formation-4-guided.toml"
    path.write_text(src.read_text().replace('model = "remus100"',
                                            'model = "remus100-6dof-guided"'))
    return path


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """formation-4 with remus100-6dof-guided, per-vehicle distributed, T = 2 s at h = 0.05 s,
    through ``auv-cosim run``."""
    tmp = tmp_path_factory.mktemp("guided")
    path = _scenario(tmp)
    out = tmp / "run"
    code = main(["run", "--scenario", str(path), "--T", str(T), "--h", str(H), "--seed",
                 str(SEED), "--quiet", "--out", str(out), "--deployment", "per-vehicle",
                 "--architecture", "distributed"])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    sc = load_scenario(str(path)).with_run(T=T, h=H, seed=SEED, deployment="per-vehicle",
                                           architecture="distributed")
    return sc, out, summary, read_rrd_scalars(out / f"{summary['scenario']}.rrd")


@pytest.mark.slow
def test_each_vehicle_is_guidance_autopilot_and_actuated_vehicle(run):
    sc, _, summary, scalars = run
    assert {"guidance", "autopilot", "remus6dof_actuated"} <= set(summary["fmus"])
    assert "remus6dof" not in summary["fmus"] and "vehicle" not in summary["fmus"]
    system = scenario_system(sc)
    kinds = {c.name: c.fmu for c in system.components}
    for i in range(1, 5):
        assert (kinds[f"guidance_{i}"], kinds[f"autopilot_{i}"], kinds[f"vehicle_{i}"]) == (
            "guidance", "autopilot", "remus6dof_actuated")
    conns = {str(c) for c in system.connections}
    assert {"controller_2.u -> guidance_2.u", "controller_2.u -> estimator_2.u",
            "guidance_2.course_rate -> autopilot_2.course_rate",
            "vehicle_2.depth -> autopilot_2.measured_depth",
            "vehicle_2.velocity -> autopilot_2.velocity",
            "autopilot_2.stern -> vehicle_2.stern_command"} <= conns
    assert not any(c.endswith("vehicle_2.u") for c in conns)
    # the guidance start values are each vehicle's own (its start depth), the autopilot's
    # the vehicle's gains
    v3 = sc.fleet.views[2]
    assert system.component("guidance_3").parameters["depth0"] == v3.x0[2] == 25.0
    assert system.component("autopilot_3").parameters["K_chi"] == AutopilotGains().K_chi
    # the set-points are recorded per vehicle: speed, course, depth
    t, _, sp = scalars["vehicles/3/setpoint/kalman"]
    assert sp.shape == (round(T / H), 3) and sp[0, 2] == 25.0
    assert any("/propeller/" in e for e in scalars)


def test_the_run_is_the_chain_replayed_monolithically(run):
    """Vehicle 1's recorded force through guidance, set-point autopilot and the actuated
    plant (plain functions, same seed): its recorded true state x to 1e-12."""
    sc, _, _, scalars = run
    _, _, u = scalars["vehicles/1/control/kalman"]
    _, _, x_rec = scalars["vehicles/1/state/kalman/true"]
    steps = round(T / H)
    assert u.shape == (steps, 3) and x_rec.shape == (steps, 6)
    model = sc.fleet.models[0]
    view = sc.fleet.views[0]
    par = model.parameters
    # the guidance: v_ref through the water, the depth set-point, the held course
    M, D = np.array(par["total_mass"], float), np.array(par["damping"], float)
    gains, loop = AutopilotGains(), DepthLoop()
    v = np.asarray(view.x0, float)[3:6] - np.asarray(view.w0, float)[:3]
    depth, held = float(view.x0[2]), math.atan2(v[1], v[0])
    integ = np.zeros(2)
    lin = sample_vehicle(view, H, 1)
    Mp, Dp = linear_mass_damping(view.B1, view.B2)
    plant = ActuatedRemus6dofPlant(Remus100(), gains, lin, Mp, Dp, view.x0, view.w0, SEED,
                                   substep_count(H, default_substep(H)))
    worst = 0.0
    for k in range(steps):
        worst = max(worst, float(np.max(np.abs(plant.output[3:9] - x_rec[k]))))
        sp = setpoints(v, u[k], M, D, depth, held, gains.U_min)
        o = plant.output
        cmd, err = setpoint_command(gains, loop, sp, o[19:22], o[12:15], o[22:25], o[25],
                                    integ)
        lim, _ = limit_command(gains, cmd)
        plant.step(np.array([lim[2], lim[0], lim[1]]))
        integ = integ + err * H
        depth += depth_increment(v[2], u[k][2], M[2], D[2], H)
        v = reference_step(v, u[k], M, D, H)
        held = math.atan2(v[1], v[0]) if math.hypot(v[0], v[1]) > gains.U_min else held
    print(f"replay: largest difference {worst:.3g}")
    assert worst < 1e-12, worst
    assert np.ptp(x_rec[:, 3]) > 0.1 and np.ptp(x_rec[:, 0]) > 0.2     # it moved


def test_actuated_plant_meets_the_internal_plants_current_and_noise(run):
    """Same seed and vehicle: the actuated and the force-driven plant draw the same current
    and sensor noise (the current does not depend on the vehicle's motion)."""
    sc, _, _, _ = run
    view = sc.fleet.views[1]
    lin = sample_vehicle(view, H, 2)
    M, D = linear_mass_damping(view.B1, view.B2)
    n = substep_count(H, default_substep(H))
    a = ActuatedRemus6dofPlant(Remus100(), AutopilotGains(), lin, M, D, view.x0, view.w0, 7, n)
    b = Remus6dofPlant(Remus100(), AutopilotGains(), lin, M, D, view.x0, view.w0, 7, n)
    assert np.array_equal(a.output[:19], b.output)          # the same start
    for _ in range(20):
        a.step(np.array([1200.0, 0.05, -0.02]))
        b.step(np.array([50.0, 0.0, 0.0]))
        assert np.array_equal(a.output[9:12], b.output[9:12])             # current
        fix_a, fix_b = a.output[0:3] - a.output[3:6], b.output[0:3] - b.output[3:6]
        assert np.allclose(fix_a, fix_b, rtol=0.0, atol=1e-12)           # sensor noise
    assert a.output[18] == 0.0
    a.step(np.array([AutopilotGains().n_max, 0.0, 0.0]))                  # at its limit
    assert a.output[18] == 1.0


@pytest.fixture
def actuated(run):
    _, out, summary, _ = run
    fmu = summary["fmus"]["remus6dof_actuated"]["path"]
    ex = Extracted({"remus6dof_actuated": fmu})
    inst = FmuInstance("vehicle_1", fmu, ex.dirs["remus6dof_actuated"], "probe")
    inst.initialize({}, T=T)
    yield inst
    inst.close()
    ex.cleanup()


def _set(inst, values):
    vr = (ctypes.c_uint * 3)(*[inst.vr[n] for n in COMMANDS])
    return inst.set_real(inst.component, vr, 3, (ctypes.c_double * 3)(*values))


def _get(inst, names):
    return np.array(inst.slave.getReal([inst.vr[n] for n in names]))


OUT = ([f"x[{i}]" for i in range(1, 7)] + [f"velocity[{i}]" for i in (1, 2, 3)]
       + [f"rates[{i}]" for i in (1, 2, 3)] + ["depth", "rpm", "saturated"])


def test_a_nan_command_is_a_discard_naming_it_and_the_host_goes_on(actuated):
    inst = actuated
    _set(inst, [1000.0, 0.0, 0.0])
    assert inst.do_step(inst.component, 0.0, H, 1) == 0
    _set(inst, [1000.0, math.nan, 0.0])
    assert inst.do_step(inst.component, H, H, 1) == 2                     # fmi2Discard
    assert any("rudder_command = nan is not finite" in m for s, m in inst.messages
               if s == "Error")
    _set(inst, [1000.0, 0.0, 0.0])
    assert inst.do_step(inst.component, H, H, 1) == 0                     # finite: it steps


def test_fmu_state_round_trips(actuated):
    inst = actuated
    _set(inst, [1100.0, 0.1, -0.05])
    for k in range(5):
        assert inst.do_step(inst.component, k * H, H, 1) == 0
    state = inst.slave.getFMUstate()
    before = _get(inst, OUT)
    ahead = []
    for k in range(5, 10):
        assert inst.do_step(inst.component, k * H, H, 1) == 0
        ahead.append(_get(inst, OUT))
    assert not np.array_equal(ahead[-1], before)
    inst.slave.setFMUstate(state)
    assert np.array_equal(_get(inst, OUT), before)
    for k in range(5, 10):                      # the same noise and motion again, bit for bit
        assert inst.do_step(inst.component, k * H, H, 1) == 0
        assert np.array_equal(_get(inst, OUT), ahead[k - 5])
    blob = inst.slave.serializeFMUstate(state)             # serialized too
    inst.slave.freeFMUstate(state)
    inst.slave.setFMUstate(inst.slave.deSerializeFMUstate(blob))
    assert np.array_equal(_get(inst, OUT), before)


def test_the_osp_and_ssp_exports_carry_the_three_fmus_and_their_wiring(tmp_path):
    import zipfile
    path = _scenario(tmp_path)
    for what in ("osp", "ssp"):
        assert main(["export", what, "--scenario", str(path), "--deployment", "per-vehicle",
                     "--architecture", "distributed", "--out", str(tmp_path / what)]) == 0
    osp = (tmp_path / "osp" / "OspSystemStructure.xml").read_text()
    for name in ("AuvGuidance.fmu", "AuvAutopilot.fmu", "AuvRemus6dofActuated.fmu"):
        assert (tmp_path / "osp" / name).exists() and name in osp
    (ssp,) = (tmp_path / "ssp").glob("*.ssp")
    with zipfile.ZipFile(ssp) as z:
        ssd = z.read("SystemStructure.ssd").decode()
        assert {"resources/AuvGuidance.fmu", "resources/AuvAutopilot.fmu",
                "resources/AuvRemus6dofActuated.fmu"} <= set(z.namelist())
    for text in (osp, ssd):
        for i in range(1, 5):
            assert f"guidance_{i}" in text and f"autopilot_{i}" in text
        assert "rpm_command" in text and "measured_depth" in text and "course_rate" in text

"""The controllers' actuator limit u_max, through real fmpy.

- the distributed controller FMU with u_max set equals the plain law clipped,
  sat(u) = min(max(u, -u_max), u_max), to 1e-12 (the law and its observer stepped in numpy);
  the centralized and stacked controllers equal their unclipped outputs clipped, bit for bit;
- a bad u_max is an error status naming the element; the native (C) controllers clip as
  the pythonfmu ones (1e-12);
- anti-windup matters: one vehicle's loop (leader, vehicle, estimator, controller FMUs)
  started 58 m off its target with 22 N per horizontal axis. With the clipped force fed to
  the estimator (the system's wiring) it settles without overshoot; with the law's force
  fed to the estimator while the actuator clips (a controller that does not know its
  limit) the current estimate winds up and the vehicle overshoots by more than 10 m;
- without u_max nothing changes: tests/test_golden_traces.py runs these FMUs against the
  recorded traces of main.
"""
from __future__ import annotations

import copy

import numpy as np
import pytest

from controller_fmu.distributed_observer import sampled_observer
from controller_fmu.regulator import tracking_law
from controller_fmu.slave_common import UNLIMITED, saturate
from orchestrator.analysis.per_vehicle import distributed_loop_of
from orchestrator.cosim.build import build_fmus
from orchestrator.cosim.instance import CosimError, Extracted, FmuInstance
from orchestrator.cosim.per_vehicle import (
    build_configs,
    fleet_slots,
    per_vehicle_configs,
    per_vehicle_system,
)
from orchestrator.scenario import load_scenario, scenario_from_dict

T = 10.0
UMAX = [60.0, 40.0, 20.0]


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    out = {}
    sc = load_scenario("formation-4").with_run(T=T)
    folder = tmp_path_factory.mktemp("limit")
    for arch in ("distributed", "centralized"):
        gain = None if arch == "distributed" else tracking_law(sc.system, "regulator").Ks
        cfgs = per_vehicle_configs(sc, arch, estimator="kalman", seed=1, tracking="regulator",
                                   gain=gain)
        fmus = build_fmus(None, folder / arch, kinds=build_configs(cfgs))
        out[arch] = (fmus, per_vehicle_system(sc, cfgs, arch), Extracted(fmus))
    yield sc, out
    for _, _, ex in out.values():
        ex.cleanup()


def _instance(parts, component: str, name: str, **override) -> FmuInstance:
    fmus, system, ex = parts
    comp = system.component(component)
    inst = FmuInstance(component, fmus[comp.fmu], ex.dirs[comp.fmu], name)
    inst.initialize({**comp.parameters, **override}, T=T)
    return inst


def _limit(values) -> dict[str, float]:
    return {f"u_max[{k}]": v for k, v in enumerate(values, start=1)}


def _inputs(inst: FmuInstance) -> list[str]:
    return [v.name for v in inst.md.modelVariables if v.causality == "input"]


def test_the_clipped_distributed_controller_is_the_plain_law_clipped(built):
    """Random estimates and neighbour messages, 300 steps: u = sat(U eta + Uw what + uc
    - (1 + c d) Kx eps + c Kx sum a_k eps_k) with eps and eta from numpy."""
    sc, parts = built
    inst = _instance(parts["distributed"], "controller_4", "clip4", **_limit(UMAX))
    law = distributed_loop_of(sc, "kalman", "regulator", sc.distributed).laws[3]
    slots = fleet_slots(sc.fleet)
    a, a0 = slots.weights[3], float(slots.pinning[3])
    F = sc.fleet.leader.F
    Aobs, Bobs = sampled_observer(F, sc.h, sc.distributed.mu).vehicle_matrices(a.sum() + a0)
    c = sc.distributed.cohesion
    l_ = F.shape[0]
    names = _inputs(inst)
    vin = [inst.vr[n] for n in names]
    vout = [inst.vr[f"u[{k}]"] for k in (1, 2, 3)]
    eta = np.zeros(l_)
    rng = np.random.default_rng(4)
    clipped = 0
    worst = 0.0
    for k in range(300):
        row = 1.0 * rng.standard_normal(len(names))
        inst.slave.setReal(vin, list(row))
        u_fmu = np.array(inst.slave.getReal(vout))
        x = dict(zip(names, row))
        xhat = np.array([x[f"xhat[{j}]"] for j in range(1, 7)])
        what = np.array([x[f"what[{j}]"] for j in range(1, 4)])
        nbr_eps = np.array([[x[f"nbr[{s}].eps[{j}]"] for j in range(1, 7)] for s in (1, 2)])
        nbr_eta = np.array([[x[f"nbr[{s}].eta[{j}]"] for j in range(1, l_ + 1)] for s in (1, 2)])
        z = np.array([x[f"z[{j}]"] for j in range(1, l_ + 1)])
        eps = xhat - law.X @ eta - law.Xw @ what - law.xc
        u = (law.U @ eta + law.Uw @ what + law.uc - (1.0 + c * (a.sum() + a0)) * law.Kx @ eps
             + c * law.Kx @ (a @ nbr_eps))
        u_ref = saturate(u, np.array(UMAX))
        clipped += int(np.any(u_ref != u))
        worst = max(worst, float(np.max(np.abs(u_fmu - u_ref))))
        eta = Aobs @ eta + Bobs @ (a @ nbr_eta + a0 * z)
        inst.slave.doStep(k * sc.h, sc.h)
    inst.close()
    assert worst <= 1e-12
    assert 50 < clipped < 300              # the limit was active, and not always


def test_the_clipped_central_controller_is_its_output_clipped(built):
    sc, parts = built
    free = _instance(parts["centralized"], "controller_2", "free2")
    lim = _instance(parts["centralized"], "controller_2", "lim2", **_limit(UMAX))
    names = _inputs(free)
    vin = [free.vr[n] for n in names]
    vout = [free.vr[f"u[{k}]"] for k in (1, 2, 3)]
    rng = np.random.default_rng(5)
    hits = 0
    for k in range(200):
        row = list(3.0 * rng.standard_normal(len(names)))
        free.slave.setReal(vin, row)
        lim.slave.setReal(vin, row)
        u = np.array(free.slave.getReal(vout))
        assert np.array_equal(np.array(lim.slave.getReal(vout)), saturate(u, np.array(UMAX)))
        hits += int(np.any(np.abs(u) > UMAX))
        for i in (free, lim):
            i.slave.doStep(k * sc.h, sc.h)
    assert hits > 20
    assert float(free.slave.getReal([free.vr["u_max[1]"]])[0]) == UNLIMITED
    free.close()
    lim.close()


@pytest.mark.parametrize("value, fragment", [(-1.0, "u_max[2] = -1.0 is outside its range"),
                                             (0.0, "u_max[2] = 0.0 must be a positive force")])
def test_a_bad_limit_is_an_error_status_naming_it(built, value, fragment):
    _, parts = built
    with pytest.raises(CosimError) as exc:
        _instance(parts["distributed"], "controller_1", f"bad{value}", **{"u_max[2]": value})
    assert fragment in str(exc.value)


@pytest.mark.slow
@pytest.mark.parametrize("deployment", ["per-vehicle", "stacked"])
def test_the_native_controllers_clip_as_the_pythonfmu_ones(tmp_path, deployment):
    """fmus = "native" with [design] u_max: the compiled controllers (role sat of
    linear_fmu.c) give the pythonfmu run's force to 1e-12, at the limit where it clips."""
    from orchestrator.running.setup import method_list
    from orchestrator.running.systems import make_setup
    path = _limited(tmp_path, deployment)
    forces = {}
    for fmus in ("python", "native"):
        sc = load_scenario(path).with_run(T=10.0, fmus=fmus)
        method = method_list(sc)[0]
        setup = make_setup(sc, tmp_path / fmus, [method])
        setup.fmus(method)
        key = "controller" if deployment == "stacked" else "vehicle_controller"
        assert setup.fmu_report(method)[key]["kind"] == fmus
        forces[fmus] = setup.run(method, 0).traces["u"]
    limit = np.tile([12.0, 12.0, 4.0], 4)
    assert np.max(np.abs(forces["native"] - forces["python"])) <= 1e-12 * limit.max()
    assert np.mean(np.abs(forces["native"]) == limit) > 0.05
    assert np.all(np.abs(forces["native"]) <= limit)


def _one_vehicle_loop(sc, parts, anti_windup: bool, umax: list[float], T_run: float):
    """Vehicle 1 (it hears the leader, no neighbour) with the leader, its estimator and its
    controller, stepped by hand: the actuator clips at ``umax``; the estimator gets the
    clipped force (anti-windup: the controller FMU clips) or the law's force."""
    tag = "aw" if anti_windup else "naive"
    run = parts
    L = _instance(run, "leader", f"L{tag}")
    V = _instance(run, "vehicle_1", f"V{tag}")
    E = _instance(run, "estimator_1", f"E{tag}")
    C = _instance(run, "controller_1", f"C{tag}", **(_limit(umax) if anti_windup else {}))

    def refs(inst, name, n):
        return [inst.vr[f"{name}[{j}]"] for j in range(1, n + 1)]
    l_ = sc.fleet.leader.F.shape[0]
    z_vr, y_vr, x_vr = refs(L, "z", l_), refs(V, "y", 3), refs(V, "x", 6)
    ey, eu, vu = refs(E, "y", 3), refs(E, "u", 3), refs(V, "u", 3)
    est = refs(E, "xhat", 6) + refs(E, "what", 3)
    c_in, c_u = refs(C, "xhat", 6) + refs(C, "what", 3) + refs(C, "z", l_), refs(C, "u", 3)
    steps = int(round(T_run / sc.h))
    X, Z, W = np.zeros((steps, 6)), np.zeros((steps, l_)), np.zeros((steps, 3))
    for k in range(steps):
        Z[k] = L.slave.getReal(z_vr)
        X[k] = V.slave.getReal(x_vr)
        E.slave.setReal(ey, V.slave.getReal(y_vr))
        xw = E.slave.getReal(est)
        W[k] = xw[6:]
        C.slave.setReal(c_in, list(xw) + list(Z[k]))
        u = np.array(C.slave.getReal(c_u))
        V.slave.setReal(vu, list(saturate(u, np.array(umax))))     # the actuator clips
        E.slave.setReal(eu, list(u))
        for inst in (L, V, E, C):
            inst.slave.doStep(k * sc.h, sc.h)
    for inst in (L, V, E, C):
        inst.close()
    H = sc.fleet.leader.H
    d = sc.fleet.offsets[0]
    return np.linalg.norm(Z @ H.T + d - X[:, :3], axis=1), W


@pytest.mark.slow
def test_anti_windup_matters_after_a_saturating_transient(tmp_path):
    """Straight leader at 1.5 m/s; vehicle 1 starts 58 m off. Both reach 1 m at the same
    time (the same clipped force until then); afterwards the anti-windup loop stays within
    1.5 m, the naive one overshoots by more than 5 m (9.8 m with seed 0 of noise stream 2)
    with a wound-up current estimate."""
    data = copy.deepcopy(dict(load_scenario("formation-4").raw))
    data["leader"] = {"path": "straight", "speed": 1.5, "start": [0.0, 0.0, 20.0],
                      "noise": 0.0}
    data["vehicles"]["positions"][0] = [-40.0, 30.0, 25.0]
    sc = scenario_from_dict(data, "windup").with_run(T=120.0)
    cfgs = per_vehicle_configs(sc, "distributed", estimator="kalman", seed=0, tracking="regulator")
    fmus = build_fmus(None, tmp_path, kinds=build_configs(cfgs))
    ex = Extracted(fmus)
    parts = (fmus, per_vehicle_system(sc, cfgs, "distributed"), ex)
    umax = [22.0, 22.0, 5.0]            # above the 16 N of drag at 1.5 m/s
    try:
        e_aw, w_aw = _one_vehicle_loop(sc, parts, True, umax, 120.0)
        e_naive, w_naive = _one_vehicle_loop(sc, parts, False, umax, 120.0)
    finally:
        ex.cleanup()
    assert e_aw[0] > 50.0
    k_aw, k_naive = int(np.argmax(e_aw < 1.0)), int(np.argmax(e_naive < 1.0))
    assert 0 < k_aw and abs(k_aw - k_naive) * sc.h < 2.0
    assert e_aw[k_aw:].max() < 1.5
    assert e_naive[k_naive:].max() > 5.0
    assert np.abs(w_aw).max() < 0.5 < 5.0 < np.abs(w_naive).max()


def _limited(tmp_path, deployment: str):
    """formation-4 with [design] bandwidth 0.3 rad/s and u_max = 12, 12, 4 N, as a file."""
    data = copy.deepcopy(dict(load_scenario("formation-4").raw))
    data["cost"].pop("R")
    data["simulation"]["deployment"] = deployment
    if deployment == "per-vehicle":
        data["simulation"]["architecture"] = "distributed"
    data["design"] = {"bandwidth": 0.3, "u_max": [12.0, 12.0, 4.0], "path_check": "off"}
    path = tmp_path / "limited.toml"
    path.write_text(_toml(data))
    return path


def test_the_stacked_controller_clips_at_the_design_limit(tmp_path):
    """The stacked deployment's AuvController gets every vehicle's u_max: the run's force
    reaches the limit and never exceeds it."""
    from orchestrator.running.setup import method_list
    from orchestrator.running.systems import make_setup
    sc = load_scenario(_limited(tmp_path, "stacked")).with_run(T=20.0)
    method = method_list(sc)[0]
    setup = make_setup(sc, tmp_path / "fmus", [method])
    setup.fmus(method)
    u = np.abs(setup.run(method, 0).traces["u"])
    limit = np.tile([12.0, 12.0, 4.0], 4)
    assert np.all(u <= limit)
    assert np.mean(u == limit) > 0.05


@pytest.mark.slow
def test_a_run_with_a_force_limit_reports_and_says_so(tmp_path, capsys):
    """`auv-cosim run` (per-vehicle, distributed) with [design] u_max and a bandwidth
    target: summary.json holds the chosen R and the limits; the printout has the design
    line and names the vehicles saturated more than 10 % of the window."""
    import json

    from orchestrator.cli import main
    path = _limited(tmp_path, "per-vehicle")
    assert main(["run", "--scenario", str(path), "--T", "40", "--quiet", "--out",
                 str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out.splitlines()
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    d = summary["design"]
    assert d["bandwidth"] == pytest.approx(0.3, rel=1e-8) and d["clip"] is True
    assert d["u_max"] == [[12.0, 12.0, 4.0]] * 4 and d["binding"] == "bandwidth"
    assert out[1].startswith(f"design: R = {d['R']:.4g} (the bandwidth target sets it)")
    sat = summary["methods"]["kalman"]["actuator_saturation_fraction_per_vehicle"]
    assert len(sat) == 4 and max(sat) > 0.1
    note = [line for line in out if "saturated more than 10%" in line]
    assert len(note) == 1
    assert all(f"vehicle {i}" in note[0] for i, f in enumerate(sat, start=1) if f > 0.1)


def _toml(data: dict) -> str:
    """A small TOML writer for the scenario tables (numbers, strings, lists, tables)."""
    def value(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return '"' + v + '"'
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{k} = {value(x)}" for k, x in v.items()) + " }"
        return repr(float(v)) if isinstance(v, float) else str(v)
    top = [f"{k} = {value(v)}" for k, v in data.items() if not isinstance(v, dict)]
    tables = [f"[{k}]\n" + "\n".join(f"{kk} = {value(vv)}" for kk, vv in v.items())
              for k, v in data.items() if isinstance(v, dict)]
    return "\n".join(top) + "\n\n" + "\n\n".join(tables) + "\n"


def test_the_saturation_note_names_few_vehicles_and_counts_many():
    """Up to six vehicles are named with their share; a fleet's note counts them, gives
    the range and the worst vehicle, and stays one line."""
    from orchestrator.cli.common import saturation_line
    assert saturation_line("kalman", [0.0, 0.05, 0.1]) is None
    few = saturation_line("kalman", [0.5, 0.05, 0.2])
    assert "vehicle 1 50%, vehicle 3 20%" in few and "vehicle 2" not in few
    many = saturation_line("kalman", [0.3] * 99 + [0.95])
    assert "100 of 100 vehicles, 30% to 95% (the most: vehicle 100)" in many
    assert "\n" not in many and len(many) < 250

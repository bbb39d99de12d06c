"""The periodic loop of the multi-rate filter (orchestrator.analysis.multirate_prediction):
the FMUs are that loop, and its cost is the periodic Lyapunov solution."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from orchestrator.analysis.distributed_verdict import predict_cost
from orchestrator.analysis.multirate_prediction import (
    multirate_reference,
    periodic_loop,
    predict_multirate_cost,
)
from orchestrator.analysis.per_vehicle import distributed_loop_of
from orchestrator.cosim.build import build_fmus
from orchestrator.cosim.master import run_system
from orchestrator.cosim.per_vehicle import (
    build_configs,
    per_vehicle_configs,
    per_vehicle_system,
    stacked_traces,
)
from orchestrator.scenario import load_scenario
from plant_model.linalg_checks import ModelError

BUILTIN = Path(__file__).parent.parent / "orchestrator/scenario/builtin/formation-4.toml"


def _scenario(tmp_path, sensors: str, T: float = 10.0):
    text = BUILTIN.read_text().replace('tracking = "regulator"', 'tracking = "regulator"\n'
                                       'deployment = "per-vehicle"\narchitecture = "distributed"')
    path = tmp_path / "f4.toml"
    path.write_text(text + '\n[sensors]\nkind = "remus"\n' + sensors)
    return load_scenario(path).with_run(T=T)


def _rel(a, b):
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-300))


@pytest.mark.slow
def test_the_fmus_are_the_periodic_loop(tmp_path):
    """No dropouts: the estimator FMUs start on the periodic filter, so the co-simulation
    equals the periodic loop driven by the same draws, to 1e-9."""
    sc = _scenario(tmp_path, "fix_period = 1.0\nfix_dropout = 0.0\ndvl_dropout = 0.0\n")
    cfgs = per_vehicle_configs(sc, "distributed", estimator="kalman", seed=3, tracking=sc.tracking)
    fmus = build_fmus(None, tmp_path / "fmus", kinds=build_configs(cfgs))
    system = per_vehicle_system(sc, cfgs, "distributed")
    traces, _, _ = run_system(system, fmus, sc.steps)
    fmu = stacked_traces(sc, system, traces)
    loop = distributed_loop_of(sc, "kalman", sc.tracking, sc.distributed)
    ref = multirate_reference(sc, loop, sc.sensors, 3,
                              sc.steps)
    for key in ("x", "u", "e"):
        assert _rel(fmu[key], ref[key]) < 1e-9, key
    assert np.abs(fmu["u"]).max() > 1.0


def test_every_sensor_every_step_is_the_steady_loop(tmp_path):
    """Period 1: the periodic prediction is the steady loop's Lyapunov prediction with the
    same rows and the Riccati gain."""
    sc = _scenario(tmp_path, "fix_period = 0.01\ndvl_period = 0.01\ndepth_period = 0.01\n"
                   "fix_dropout = 0.0\ndvl_dropout = 0.0\n")
    loop = distributed_loop_of(sc, "kalman", sc.tracking, sc.distributed)
    sensors = sc.sensors
    (phase,) = periodic_loop(sc, loop, sensors)
    from dataclasses import replace
    steady = replace(loop, Phi=phase["Phi"], Gam=phase["Gam"], W=phase["W"], Gx=phase["Gx"],
                     Geta=phase["Geta"])
    assert predict_multirate_cost(sc, loop, sensors).cost_rate == pytest.approx(
        predict_cost(steady).cost_rate, rel=1e-9)


def test_the_lifted_solution_is_the_iterated_second_moment(tmp_path):
    """The period's Lyapunov solution equals Sigma iterated phase by phase from 0 for 2^30
    periods (by doubling the one-period map (A, Q) -> (A A, A Q A' + Q), not by a
    Lyapunov solver); fixes every 0.1 s, DVL every 0.05 s, depth every 0.02 s: a period of
    10 steps."""
    sc = _scenario(tmp_path, "fix_period = 0.1\ndvl_period = 0.05\ndepth_period = 0.02\n"
                   "fix_dropout = 0.0\ndvl_dropout = 0.0\n")
    loop = distributed_loop_of(sc, "kalman", sc.tracking, sc.distributed)
    sensors = sc.sensors
    phases = periodic_loop(sc, loop, sensors)
    assert len(phases) == 10
    R = ~loop.deterministic
    A, Q = np.eye(R.sum()), np.zeros((R.sum(), R.sum()))
    for ph in phases:
        P, G = ph["Phi"][np.ix_(R, R)], ph["Gam"][R]
        A, Q = P @ A, P @ Q @ P.T + G @ ph["W"] @ G.T
    S = Q
    for _ in range(30):
        S = A @ S @ A.T + S
        A = A @ A
    cost = 0.0
    for ph in phases:
        Sig = np.zeros_like(loop.Phi)
        Sig[np.ix_(R, R)] = S
        cost += (np.trace(loop.Qc @ loop.Ce @ Sig @ loop.Ce.T)
                 + np.trace(loop.Rc @ (ph["Gx"] @ Sig @ ph["Gx"].T
                                       + ph["Geta"] @ ph["W"] @ ph["Geta"].T)))
        P, G = ph["Phi"][np.ix_(R, R)], ph["Gam"][R]
        S = P @ S @ P.T + G @ ph["W"] @ G.T
    assert predict_multirate_cost(sc, loop, sensors).cost_rate == pytest.approx(
        cost / len(phases), rel=1e-9)


def test_dropouts_have_no_prediction_and_say_why(tmp_path):
    sc = _scenario(tmp_path, "")
    loop = distributed_loop_of(sc, "kalman", sc.tracking, sc.distributed)
    with pytest.raises(ModelError, match="no prediction with sensor dropouts"):
        predict_multirate_cost(sc, loop, sc.sensors)

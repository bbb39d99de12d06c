"""[design]: the weight search, the vehicle's limits and the path check.

The mathematics (controller_fmu.weight_design) against independent references: python-control's
lqr and bandwidth, the project's stacked prediction of the distributed loop (another assembly of
the same loop), a doubling iteration for the Lyapunov sum; the limits of the nonlinear REMUS
follow its data; the loader's errors are one line naming the key.
"""
from __future__ import annotations

import copy
import dataclasses
import math
import tomllib

import control
import numpy as np
import pytest

from controller_fmu.weight_design import (
    choose_weight,
    closed_loop_bandwidth,
    noise_force_covariance,
)
from orchestrator.analysis.distributed import agents_from_fleet_spec, sample_agent
from orchestrator.analysis.distributed_verdict import predict_cost
from orchestrator.analysis.per_vehicle import distributed_loop_of
from orchestrator.analysis.weight_search import _noise_gain, design_fleet
from orchestrator.scenario import SCENARIO_DIR, ScenarioError, load_scenario, scenario_from_dict
from plant_model.leader import circle, straight
from plant_model.linalg_checks import ModelError
from plant_model.path_feasibility import path_demands, path_findings
from plant_model.remus100.dynamics import Remus100
from plant_model.remus100.limits import VehicleLimits, remus_limits

FLEET = tomllib.loads((SCENARIO_DIR / "formation-4.toml").read_text())


@pytest.fixture(scope="module")
def f4():
    sc = load_scenario("formation-4")
    agents, _, leader = agents_from_fleet_spec(sc.fleet.spec)
    return sc, agents, leader


@pytest.mark.parametrize("r", [1e-3, 0.01, 1.0, 30.0])
def test_gain_and_bandwidth_match_python_control(f4, r):
    """Kx = control.lqr; the -3 dB frequency of sigma_max(T) = the fastest axis' SISO
    bandwidth of T_a = K_a (sI - A_a + B_a K_a)^-1 B_a by control.bandwidth."""
    _, agents, leader = f4
    a = agents[0]
    Kx = _noise_gain(a, r, leader, "regulator", "continuous", 0.01)[0]
    K_ref, _, _ = control.lqr(a.A, a.B, a.C.T @ a.Q @ a.C, r * np.eye(3))
    assert np.allclose(Kx, K_ref, rtol=1e-9, atol=1e-12)
    bws = []
    for ax in range(3):
        idx = [ax, ax + 3]
        A, B, K = a.A[np.ix_(idx, idx)], a.B[idx, ax:ax + 1], Kx[ax:ax + 1, idx]
        bws.append(control.bandwidth(control.ss(A - B @ K, B, K, 0.0),
                                     dbdrop=-10.0 * math.log10(2.0)))   # 1/sqrt(2)
    assert closed_loop_bandwidth(a.A, a.B, Kx) == pytest.approx(max(bws), rel=1e-6)


def _doubling(Phi: np.ndarray, Q: np.ndarray, rounds: int = 40) -> np.ndarray:
    """sum_k Phi^k Q Phi'^k by doubling: S <- S + A S A', A <- A A (2^rounds terms)."""
    S, A = Q.copy(), Phi.copy()
    for _ in range(rounds):
        S = S + A @ S @ A.T
        A = A @ A
    return S


@pytest.mark.parametrize("estimator", ["kalman", "ideal"])
def test_noise_force_equals_the_stacked_prediction_of_the_fleet(f4, estimator):
    """The per-vehicle force covariance equals vehicle 1's rows of the project's stacked
    distributed loop (predict_cost, no cohesion, a planned leader: each vehicle's force
    is moved by its own noise only), to 1e-9."""
    sc, agents, leader = f4
    loop = distributed_loop_of(sc, estimator, "regulator", sc.distributed)
    ref = predict_cost(loop).rms_u[:3]
    sa = sample_agent(agents[0], sc.h, estimator=estimator)
    Ks = _noise_gain(agents[0], 0.01, leader, "regulator", "continuous", sc.h)[1]
    Suu = noise_force_covariance(sa.Ad, sa.Bd, Ks, sa.Qd, sa.M, sa.Rd, sa.L)
    assert np.sqrt(np.diag(Suu)) == pytest.approx(ref, rel=1e-9)


def test_noise_force_lyapunov_equals_a_doubling_sum(f4):
    """Ideal estimator: E[u u'] = Ks (sum_k Acl^k Qd Acl'^k) Ks' by doubling (2^40 terms)."""
    sc, agents, leader = f4
    sa = sample_agent(agents[0], 0.1, estimator="ideal")
    Ks = _noise_gain(agents[0], 1.0, leader, "regulator", "continuous", 0.1)[1]
    Sigma = _doubling(sa.Ad - sa.Bd @ Ks, sa.Qd)
    ref = Ks @ Sigma @ Ks.T
    assert np.allclose(noise_force_covariance(sa.Ad, sa.Bd, Ks, sa.Qd), ref, rtol=1e-9,
                       atol=1e-15)


def test_the_search_meets_each_target_and_both_take_the_larger_r(f4):
    """Bandwidth and 3-sigma force both fall with R (checked on the grid); the chosen R meets
    the target it names to 1e-8; with both targets the larger R is taken."""
    sc, _, _ = f4
    run = dict(h=sc.h, T=60.0, estimator="kalman", tracking="regulator")
    bw = design_fleet(sc.fleet.spec, {"bandwidth": 0.2, "path_check": "off"}, **run)
    assert bw.binding == "bandwidth" and bw.bandwidth == pytest.approx(0.2, rel=1e-8)
    fb = design_fleet(sc.fleet.spec, {"force_budget": 0.5, "u_max": "vehicle",
                                 "path_check": "off"}, **run)
    assert fb.binding == "force_budget" and fb.force_ratio == pytest.approx(0.5, rel=1e-8)
    both = design_fleet(sc.fleet.spec, {"bandwidth": 0.2, "force_budget": 0.5,
                                   "u_max": "vehicle", "path_check": "off"}, **run)
    assert both.R == pytest.approx(max(bw.R, fb.R), rel=1e-9)
    assert both.force_ratio <= 0.5 + 1e-9 and both.bandwidth <= 0.2 + 1e-9
    # u_max of the linear remus100: the drag at its top speed, D_a * 2.5 m/s, with D_a
    # from the model's own parameters
    D = np.asarray(sc.fleet.models[0].parameters["damping"], float)
    assert np.allclose(fb.u_max[0], D * 2.5, rtol=1e-12)


def test_choose_weight_refuses_what_it_cannot_do():
    with pytest.raises(ModelError, match="does not fall monotonically"):
        choose_weight(lambda r: math.sin(math.log10(r)) + 2.0, lambda r: 0.0, bandwidth=1.5)
    with pytest.raises(ModelError, match="force_budget = 1e-09 cannot be met"):
        choose_weight(lambda r: 1.0, lambda r: 1.0 / (1.0 + r), force_budget=1e-9)


@pytest.mark.slow
def test_remus_limits_follow_the_vehicle_data():
    """Simulated, not written down: the default REMUS tops out near its published 2.5 m/s
    and turns the 34.3 m diameter of docs/remus100-6dof.md (15 deg fins); fins of 30 deg
    tighten the turn, the top speed stays."""
    base = remus_limits(Remus100())
    assert 2.45 < base.max_speed < 2.65
    assert 2.0 * base.min_turn_radius == pytest.approx(34.3, abs=0.5)
    wide = remus_limits(dataclasses.replace(Remus100(), delta_max=math.radians(30.0)))
    assert wide.min_turn_radius < 0.75 * base.min_turn_radius
    assert wide.max_speed == pytest.approx(base.max_speed, rel=1e-6)


def test_path_demands_of_analytic_paths():
    """A circle of radius 10 m at 2 m/s: radius 10 m, speed 2 m/s; a straight path: no turn."""
    c = circle(10.0, 2.0)
    t, speed, radius, rate = path_demands(c.F, c.H, c.z0, 30.0, 0.5)
    assert np.allclose(speed, 2.0, rtol=1e-9) and np.allclose(radius, 10.0, rtol=1e-9)
    assert np.allclose(rate, 0.0, atol=1e-12)
    s = straight(3.0)
    lim = VehicleLimits(2.5, 16.0, 0.5, "test")
    f = path_findings(s.F, s.H, s.z0, 10.0, [lim, VehicleLimits(None, None, None)])
    assert [(x.vehicle, x.limit) for x in f] == [(1, "speed")]
    assert f[0].value == pytest.approx(3.0) and f[0].fraction == 1.0
    f = path_findings(c.F, c.H, c.z0, 10.0, [lim])
    assert [(x.limit, round(x.value, 6)) for x in f] == [("turn radius", 10.0)]


def _error(change) -> str:
    data = copy.deepcopy(FLEET)
    change(data)
    with pytest.raises(ScenarioError) as exc:
        scenario_from_dict(data, "case.toml")
    msg = str(exc.value)
    assert msg.startswith("case.toml: ") and "\n" not in msg, msg
    return msg


@pytest.mark.parametrize("design, expect", [
    ({"bandwidth": -1.0}, "[design] bandwidth = -1.0 must be a positive number of rad/s"),
    ({"force_budget": 2.0}, "[design] force_budget = 2.0 must be a fraction"),
    ({"u_max": "big"}, "[design] u_max = 'big' must be \"vehicle\", a positive force"),
    ({"u_max": [1.0, 2.0]}, "[design] u_max must be a positive number or 3 positive numbers"),
    ({"path_check": "maybe"}, "[design] path_check 'maybe' is unknown; expected one of warn"),
    ({"speed": 1.0}, "unknown key(s) in [design]: speed"),
    ({"force_budget": 1e-9, "u_max": "vehicle"}, "[design] force_budget = 1e-09 cannot be met"),
])
def test_bad_design_input_is_one_line_naming_the_key(design, expect):
    def change(d):
        d["cost"].pop("R")
        d["design"] = design
    assert expect in _error(change)


def test_design_and_cost_r_together_are_refused():
    assert "[design] bandwidth / force_budget choose R: remove [cost] R" in _error(
        lambda d: d.update(design={"bandwidth": 0.2}))


def test_the_path_check_refuses_naming_vehicle_time_and_limit():
    def change(d):
        d["design"] = {"path_check": "refuse", "min_turn_radius": 16.0}
        d["current"]["sigma"] = 0.0          # the turn radius alone (no current to fly in)
    msg = _error(change)
    assert "[design] path_check = \"refuse\": vehicles 1, 2, 3, 4 at t = " in msg
    assert "target turn radius 7.41 m below the smallest turn radius 16 m" in msg   # given


def test_the_chosen_r_is_the_scenarios_r():
    data = copy.deepcopy(FLEET)
    data["cost"].pop("R")
    data["design"] = {"bandwidth": 0.2}
    sc = scenario_from_dict(data, "case.toml")
    R = sc.design.R
    assert sc.design.bandwidth == pytest.approx(0.2, rel=1e-8)
    assert np.allclose(sc.system.R, R * np.eye(12))
    assert sc.design.lines()[0].startswith(f"design: R = {R:.4g} (the bandwidth target sets it)")


def test_the_path_force_of_a_straight_leader_is_its_drag():
    """Straight at 2 m/s with u_max = D * 2.5 m/s (the linear REMUS): the path needs
    D * 2 / (D * 2.5) = 0.8 of u_max, whatever D."""
    data = copy.deepcopy(FLEET)
    data["cost"].pop("R")
    data["leader"] = {"path": "straight", "speed": 2.0, "start": [0.0, 0.0, 20.0]}
    data["design"] = {"bandwidth": 0.2, "u_max": "vehicle"}
    sc = scenario_from_dict(data, "case.toml")
    assert sc.design.path_force_ratio == pytest.approx(0.8, rel=1e-12)
    assert sc.design.findings == []
    assert sc.design.lines()[0].endswith("the path itself needs up to 0.8 of u_max")


def test_a_run_checks_the_path_over_its_own_horizon():
    """formation-4's lawnmower turns tighter than 16 m from t = 1.6 s on: a 1 s run has no
    finding, the file's 600 s do (still water: the current's checks apart)."""
    data = copy.deepcopy(FLEET)
    data["design"] = {"min_turn_radius": 16.0}
    data["current"]["sigma"] = 0.0
    sc = scenario_from_dict(data, "case.toml")
    assert [f.limit for f in sc.design.findings] == ["turn radius"] * 4
    assert sc.with_run(T=1.0).design.findings == []
    assert len(sc.with_run(T=1.0).with_run(T=30.0).design.findings) == 4


def test_the_vehicle_s_band_is_where_it_follows_its_design_model():
    """bandwidth = "vehicle" on remus100-6dof at 2 m/s: the chosen target is the edge of
    the band where every axis's response to the force command stays within 20 deg and
    25 % of the design model (just inside: within it; 5 % above: out of it, on some axis),
    and the search meets it; on a linear vehicle it is refused, naming the key."""
    from orchestrator.analysis.remus_response import (
        VALID_GAIN,
        VALID_PHASE,
        force_frequency_response,
    )
    from orchestrator.analysis.weight_search import vehicle_band
    sc = load_scenario("survey-4-remus")
    mdl = sc.fleet.models[0]
    band = vehicle_band([mdl])
    M = 1.0 / np.diag(np.asarray(mdl.B1, float)[3:6, :3])
    D = -np.diag(np.asarray(mdl.A, float)[3:6, 3:6]) * M

    def worst(w):
        rs = [force_frequency_response(a, [w], U0=2.0, h=0.05, vehicle=Remus100(),
                                       design=(M, D))[0] for a in (0, 1, 2)]
        return (max(abs(r["phase_difference"]) for r in rs),
                max(max(r["gain_ratio"], 1 / r["gain_ratio"]) for r in rs))

    inside, outside = worst(band * 0.99), worst(band * 1.05)
    assert inside[0] <= VALID_PHASE and inside[1] <= VALID_GAIN
    assert outside[0] > VALID_PHASE or outside[1] > VALID_GAIN
    assert 0.1 < band < 0.5 and math.isfinite(band)
    data = copy.deepcopy(FLEET)
    data["cost"].pop("R")
    data["design"] = {"bandwidth": "vehicle"}
    with pytest.raises(ScenarioError, match='bandwidth = "vehicle" needs nonlinear vehicles'):
        scenario_from_dict(data, "case.toml")

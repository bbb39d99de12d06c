"""The per-vehicle deployment: one vehicle, estimator and controller FMU per AUV plus a leader
FMU, run by fmpy, against the stacked deployment and the monolithic distributed loop."""
from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from controller_fmu.regulator import tracking_law
from controller_fmu.vehicle_law import DistributedSettings
from orchestrator.analysis.per_vehicle import distributed_loop_of, distributed_reference
from orchestrator.cli import main
from orchestrator.cosim.build import build_fmus
from orchestrator.cosim.master import run_system
from orchestrator.cosim.per_vehicle import (
    build_configs,
    fleet_slots,
    per_vehicle_configs,
    per_vehicle_system,
    stacked_traces,
)
from orchestrator.running import scenario_config
from orchestrator.scenario import ScenarioError, load_scenario
from plant_model.discretization import discretize
from plant_model.per_vehicle import sample_vehicle
from plant_model.plant import NoiseStream
from support.cli import assert_one_line_error
from support.loop import run_cosimulation


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / np.abs(b).max())


@pytest.fixture(scope="module")
def f4():
    return load_scenario("formation-4").with_run(T=20.0)


def _per_vehicle(sc, arch, mode, seed, tmp, settings=None):
    sc = replace(sc, distributed=settings) if settings else sc
    gain = tracking_law(sc.system, sc.tracking).Ks if arch == "centralized" else None
    cfgs = per_vehicle_configs(sc, arch, estimator=mode, seed=seed, tracking=sc.tracking,
                               settings=sc.distributed, gain=gain)
    fmus = build_fmus(None, tmp, kinds=build_configs(cfgs))
    system = per_vehicle_system(sc, cfgs, arch)
    traces, _, info = run_system(system, fmus, sc.steps)
    return stacked_traces(sc, system, traces), system


def test_each_vehicle_draws_its_stacked_stream_alone(f4):
    """Vehicle i sampled alone draws, number for number, its columns of the stacked
    protocol form's noise (both sample the same block with one Van Loan exponential)."""
    model = discretize(f4.system, f4.h)
    rows = NoiseStream.all_rows(model, 11, 3000)
    for i, view in enumerate(f4.fleet.views, start=1):
        alone = NoiseStream.all_rows(sample_vehicle(view, f4.h, i), 11, 3000)
        assert np.array_equal(alone, rows[:, list(model.noise_blocks[i - 1])])
    # and another vehicle number draws another stream
    other = NoiseStream.all_rows(sample_vehicle(f4.fleet.views[0], f4.h, 2), 11, 3000)
    assert not np.allclose(other, rows[:, list(model.noise_blocks[0])])


def test_slots_hold_the_graph_with_unused_ones_weightless(f4):
    slots = fleet_slots(f4.fleet)
    assert slots.S == 2                                  # vehicle 4 hears 2 and 3
    assert slots.pinning.tolist() == [1.0, 0.0, 0.0, 0.0]
    assert slots.neighbours[3].tolist() == [2, 3] and slots.weights[3].tolist() == [0.5, 0.5]
    assert slots.neighbours[0].tolist() == [1, 1] and slots.weights[0].tolist() == [0.0, 0.0]
    assert slots.neighbours[1, 0] == 1 and slots.weights[1].tolist() == [1.0, 0.0]


def test_the_system_is_constant_size_per_vehicle_for_the_distributed_law(f4, tmp_path):
    cfgs = per_vehicle_configs(f4, "distributed", estimator="kalman", seed=0, tracking="regulator")
    system = per_vehicle_system(f4, cfgs, "distributed")
    assert len(system.components) == 1 + 3 * 4
    sizes = {c.name: sum(s.size for s in c.arrays("input")) for c in system.components}
    assert len({sizes[f"controller_{i}"] for i in range(1, 5)}) == 1
    # the leader reaches only the pinned vehicle
    from_leader = {c.target for c in system.connections if c.source == "leader"}
    assert from_leader == {"controller_1"}


@pytest.mark.slow
@pytest.mark.parametrize("mode, tol", [("ideal", 1e-9), ("kalman", 1e-9)])
def test_centralized_per_vehicle_equals_the_stacked_protocol_form(f4, tmp_path, mode, tol):
    """Ideal estimator: the same loop to rounding. Kalman: the stacked filter is block
    diagonal in the protocol form, so the per-vehicle filters equal it to the Riccati
    solver's precision."""
    per, _ = _per_vehicle(f4, "centralized", mode, 3, tmp_path / "pv")
    cfg = scenario_config(f4)
    res = run_cosimulation(build_fmus(cfg, tmp_path / "st"), cfg, mode=mode, seed=3,
                           steps=f4.steps, tracking=f4.tracking)
    for key in ("x", "u", "e", "xhat"):
        assert _rel(per[key], res.traces[key]) < tol, key
    assert np.abs(per["u"]).max() > 1.0                   # a loop that does something


@pytest.mark.slow
@pytest.mark.parametrize("mode, cohesion", [("ideal", 0.0), ("kalman", 0.0), ("kalman", 0.5)])
def test_distributed_fmus_equal_the_monolithic_loop(f4, tmp_path, mode, cohesion):
    settings = DistributedSettings(mu=2.0, cohesion=cohesion)
    per, _ = _per_vehicle(f4, "distributed", mode, 5, tmp_path, settings)
    loop = distributed_loop_of(f4, mode, f4.tracking, settings)
    ref = distributed_reference(f4, loop, 5, f4.steps)
    for key in ("x", "u", "e", "eta"):
        assert _rel(per[key], ref[key]) < 1e-9, key
    # the observers converge on the leader: the last eta of every vehicle is the leader
    l0 = f4.fleet.leader.F.shape[0]
    z = per["z"][-1, :l0]
    for i in range(4):
        assert np.abs(per["eta"][-1, i * l0:(i + 1) * l0] - z).max() < 1e-3 * np.abs(z).max()


@pytest.mark.slow
def test_the_distributed_gains_change_the_loop(f4, tmp_path):
    a, _ = _per_vehicle(f4, "distributed", "ideal", 5, tmp_path / "a",
                        DistributedSettings(mu=2.0))
    b, _ = _per_vehicle(f4, "distributed", "ideal", 5, tmp_path / "b",
                        DistributedSettings(mu=0.5))
    assert _rel(a["u"], b["u"]) > 1e-3


@pytest.mark.slow
def test_run_per_vehicle_writes_summary_and_recording(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", "--scenario", "formation-4", "--deployment", "per-vehicle",
                 "--architecture", "distributed", "--T", "30", "--out", str(out),
                 "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["deployment"] == "per-vehicle"
    m = s["methods"]["kalman"]
    assert m["architecture"] == "distributed" and m["seeds_completed"] == 1
    assert m["cost_rate"]["predicted"] > 0 and m["cost_rate"]["mean"] > 0
    # the expected value over this short window, start-up included, is what it should match
    assert abs(m["cost_rate"]["mean"] / m["cost_rate"]["predicted_window"] - 1) < 0.5
    assert set(s["fmus"]) == {"leader", "vehicle", "vehicle_estimator", "vehicle_controller"}
    assert (out / "formation-4.rrd").stat().st_size > 10_000


def test_per_vehicle_refused_where_it_cannot_be(capsys, tmp_path):
    def one_line(argv, *fragments):
        assert_one_line_error(capsys, argv, *fragments)
    one_line(["run", "--deployment", "per-vehicle", "--out", str(tmp_path / "a")],
             'deployment = "per-vehicle" needs a fleet scenario')
    one_line(["bench", "--scenario", "formation-4", "--deployment", "per-vehicle"],
             "give them with --fleet")
    one_line(["compare", "--scenario", "formation-4", "--what", "architectures",
              "--out", str(tmp_path / "c")], "add --deployment per-vehicle")
    text = (Path(__file__).parent.parent / "orchestrator/scenario/builtin/formation-4.toml"
            ).read_text().replace("[graph]", '[graph]\nconsensus = "in-plant"')
    text = text.replace('tracking = "regulator"', 'tracking = "regulator"\n'
                        'deployment = "per-vehicle"')
    (tmp_path / "inplant.toml").write_text(text)
    with pytest.raises(ScenarioError, match='needs \\[graph\\] consensus = "protocol"'):
        load_scenario(tmp_path / "inplant.toml")
    assert not (tmp_path / "a").exists() and not (tmp_path / "c").exists()


@pytest.mark.slow
def test_compare_architectures_reports_the_price_and_the_bound(tmp_path, capsys):
    out = tmp_path / "cmp"
    assert main(["compare", "--scenario", "formation-4", "--deployment", "per-vehicle",
                 "--what", "architectures", "--seeds", "0", "--T", "30", "--out", str(out),
                 "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    c, d = s["methods"]["centralized"], s["methods"]["distributed"]
    assert (c["architecture"], d["architecture"]) == ("centralized", "distributed")
    assert s["price_of_decentralization"] == pytest.approx(
        d["cost_rate"]["mean"] / c["cost_rate"]["mean"])
    assert s["price_of_decentralization_predicted"] == pytest.approx(
        d["cost_rate"]["predicted"] / c["cost_rate"]["predicted"])
    assert 0 < s["cost_rate_full_information"] < min(c["cost_rate"]["predicted_window"],
                                                     d["cost_rate"]["predicted_window"])
    assert "price of decentralization" in capsys.readouterr().out
    # the recording shows the architectures side by side: a 3D view each, both in the plots
    from support.rrd_readback import read_rrd_blueprint_views, read_rrd_series_styles
    views = {path for _, path in read_rrd_blueprint_views(out / "formation-4.rrd").values()}
    assert {"/world/centralized", "/world/distributed"} <= views
    series = read_rrd_series_styles(out / "formation-4.rrd")
    for arch in ("centralized", "distributed"):
        assert f"vehicles/4/error/{arch}" in series


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["ideal", "kalman"])
def test_the_distributed_prediction_agrees_with_simulation_over_seeds(mode):
    """The Lyapunov prediction over the window (mean motion included) against the window
    cost of 8 seeds of the monolithic loop (which the FMUs reproduce to 1e-9, above)."""
    from orchestrator.analysis.distributed_verdict import predict_cost
    from orchestrator.analysis.per_vehicle import distributed_initial_state
    from orchestrator.analysis.summary import stats_window
    sc = load_scenario("formation-4").with_run(T=200.0)
    loop = distributed_loop_of(sc, mode, sc.tracking, sc.distributed)
    k0 = stats_window(sc.T, sc.h, predict_cost(loop).settling_time)
    pred = predict_cost(loop, (k0, sc.steps), distributed_initial_state(sc, loop)).cost_rate
    Q, R = sc.system.Q, sc.system.R
    costs = []
    for seed in range(8):
        tr = distributed_reference(sc, loop, seed, sc.steps)
        e, u = tr["e"][k0:], tr["u"][k0:]
        costs.append(float(np.mean(np.einsum("ki,ij,kj->k", e, Q, e)
                                   + np.einsum("ki,ij,kj->k", u, R, u))))
    mean, sem = np.mean(costs), np.std(costs, ddof=1) / np.sqrt(len(costs))
    assert abs(mean - pred) < 4 * sem + 1e-3 * pred, (mean, sem, pred)


def test_an_unstable_observer_gain_is_one_line_naming_the_eigenvalue(tmp_path, capsys):
    text = (Path(__file__).parent.parent / "orchestrator/scenario/builtin/formation-4.toml"
            ).read_text() + "\n[distributed]\nmu = 500.0\n"
    (tmp_path / "fast.toml").write_text(text)
    assert main(["run", "--scenario", str(tmp_path / "fast.toml"), "--deployment",
                 "per-vehicle", "--architecture", "distributed", "--T", "1",
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert "unstable" in err and "L + G" in err and "mu = 500" in err


def test_a_centralized_fleet_too_large_is_refused_before_trying(tmp_path, capsys):
    from orchestrator.scenario.generator import scenario_toml, survey_grid_fleet
    (tmp_path / "big.toml").write_text(scenario_toml(survey_grid_fleet(200, T=1.0)))
    assert main(["run", "--scenario", str(tmp_path / "big.toml"), "--architecture",
                 "centralized", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert "200 vehicles" in err and "use --architecture distributed" in err
    assert not any((tmp_path / "o").glob("*.fmu")) and not (tmp_path / "o" / "fmus").exists()


@pytest.mark.slow
def test_a_planned_leader_path_needs_no_leader_messages(f4, tmp_path):
    """leader = "planned": every observer starts on the path and stays on it (eta = z to
    rounding), nothing flows from the leader FMU to a controller, and the loop is the
    monolithic one started there."""
    settings = DistributedSettings(mu=2.0, leader="planned")
    sc = replace(f4, distributed=settings)
    per, system = _per_vehicle(sc, "distributed", "kalman", 4, tmp_path, settings)
    assert not [c for c in system.connections if c.source == "leader"]
    l0 = f4.fleet.leader.F.shape[0]
    z = per["z"][:, :l0]
    for i in range(4):
        assert np.abs(per["eta"][:, i * l0:(i + 1) * l0] - z).max() < 1e-9 * np.abs(z).max()
    loop = distributed_loop_of(sc, "kalman", sc.tracking, settings)
    ref = distributed_reference(sc, loop, 4, sc.steps)
    for key in ("x", "u", "eta"):
        assert _rel(per[key], ref[key]) < 1e-9, key
    # with messages instead, the observers start at 0 and the start differs
    msgs, _ = _per_vehicle(f4, "distributed", "kalman", 4, tmp_path / "m",
                           DistributedSettings(mu=2.0))
    assert np.abs(msgs["u"][:50] - per["u"][:50]).max() > 1.0

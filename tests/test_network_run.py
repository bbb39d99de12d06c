"""Per-vehicle fleets over acoustic links end to end: the AuvNetwork FMUs in the system
against the monolithic reference, libcosim against our Jacobi master, the summary's network
keys, and bad input at the scenario loader and the CLI."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from orchestrator.running.network import network_reference
from orchestrator.running.setup import Method
from orchestrator.running.systems import make_setup
from orchestrator.scenario import ScenarioError, load_scenario

NET = {"latency": 1.0, "period": 2.0, "loss": 0.3}
#: formation-4's graph in two halves switching every 4 s (neither reaches every vehicle)
HALVES = {"schedule": [{"t": 0.0, "edges": [["leader", 1], [1, 2], [2, 4]]},
                       {"t": 4.0, "edges": [["leader", 1], [1, 3], [3, 4]]}],
          "schedule_period": 8.0}


def _scenario(architecture, receiver="propagate", schedule=None, **run):
    return load_scenario("formation-4").with_run(
        deployment="per-vehicle", architecture=architecture,
        network=dict(NET, receiver=receiver, **(schedule or {})), **run)


@pytest.mark.parametrize("architecture, receiver, schedule", [
    ("distributed", "propagate", None), ("distributed", "hold", None),
    ("centralized", "propagate", None), ("distributed", "propagate", HALVES)])
@pytest.mark.slow
def test_the_network_fmus_reproduce_the_monolithic_loop(tmp_path, architecture, receiver,
                                                        schedule):
    """1 + 4 N FMUs (leader; vehicle, estimator, controller, network per AUV) equal the
    networked loop stepped as one recursion with the same noise and loss draws, and every
    link's age of information equals the one the loss draws imply (also with the graph
    switching between two halves). 16 s: 8 message cycles, two periods of the switching."""
    sc = _scenario(architecture, receiver, schedule, T=16.0)
    pv = make_setup(sc, tmp_path / "fmus")
    res = pv.run(Method("kalman", "kalman", "regulator", architecture), 3)
    setup = pv.network(Method("kalman", "kalman", "regulator", architecture))
    ref = network_reference(sc, setup, 3, sc.steps)
    for key in ("u", "e"):
        scale = np.abs(ref[key]).max()
        assert np.abs(res.traces[key] - ref[key]).max() <= 1e-9 * scale, key
    ages = setup.net.ages(sc.steps, 3)
    want = np.column_stack([ages[(("leader" if j == "leader" else int(j)), int(i))]
                            for j, _, i in (s.split() for s in res.info["links"])])
    assert np.array_equal(res.traces["link_age"], want)
    done = res.traces["link_delivered"][-1] + res.traces["link_lost"][-1]
    assert np.all(done == 8)                         # 8 messages in 16 s, all accounted
    assert res.traces["link_lost"][-1].sum() > 0
    if schedule:                                     # 1 -> 2 up 0-4 s of 8 s: 2 sends of 4
        c = res.info["links"].index("1 -> 2")
        assert res.traces["link_lost"][-1, c] >= 4
    system = pv.system(Method("kalman", "kalman", "regulator", architecture), 3)
    assert sum(c.fmu == "network" for c in system.components) == 4


@pytest.mark.slow
@pytest.mark.parametrize("architecture", ["distributed", "centralized"])
def test_libcosim_runs_the_networked_export_like_our_jacobi_master(tmp_path, architecture):
    pytest.importorskip("libcosimpy")
    from orchestrator.cosim.master import run_system
    from orchestrator.interop import libcosim
    from orchestrator.interop.osp import export_osp
    from orchestrator.running import scenario_system
    libcosim.quiet_libcosim()
    sc = _scenario(architecture, schedule=HALVES if architecture == "distributed" else None)
    paths = export_osp(sc, tmp_path)
    system = scenario_system(sc)
    assert "network" in paths and len(system.components) == 17
    steps = 500
    lc = libcosim.run_libcosim(paths["system"], system, steps)
    traces, _, _ = run_system(system, {c.fmu: paths[c.fmu] for c in system.components},
                              steps, coupling="jacobi")
    assert set(lc["traces"]) == set(traces)
    for key, arr in lc["traces"].items():
        assert np.array_equal(arr, traces[key]), key
    assert lc["traces"]["network_4.link[1].delivered"][-1, 0] >= 1


@pytest.mark.slow
def test_the_summary_reports_the_network_and_the_age_of_information(tmp_path):
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "orchestrator", "run", "--scenario",
                        "formation-4", "--deployment", "per-vehicle", "--architecture",
                        "distributed", "--latency", "1", "--period", "2", "--loss", "0.2",
                        "--T", "40", "--h", "0.05", "--out", str(out), "--quiet",
                        "--predict", "full"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    m = json.loads((out / "summary.json").read_text())["methods"]["kalman"]
    net = m["network"]
    assert (net["latency"], net["period"], net["loss"]) == (1.0, 2.0, 0.2)
    assert net["receiver"] == "propagate" and net["links"] == 5 and net["cycle_s"] == 2.0
    assert net["critical_loss"] is None and "none" in net["critical_loss_note"]
    assert m["cost_rate"]["predicted"] > 0
    age = m["age_of_information"]
    assert set(age) == {"1", "2", "3", "4"} and set(age["4"]) == {"2", "3"}
    a = age["1"]["leader"]
    assert 1.0 <= a["mean"] <= a["max"] and a["predicted_mean"] == pytest.approx(
        1.0 + 0.975 / 2 * 2 + 2.0 * 0.25, rel=1e-9)     # D h + (P - 1) h / 2 + P h p/(1-p)
    # the recording: every link's counts, every vehicle's age of information, read back
    from orchestrator.recording.reader import read_rrd_scalars
    from support.rrd_readback import read_rrd_blueprint_views
    rrd = out / "formation-4.rrd"
    series = read_rrd_scalars(rrd)
    counts = series["network/links/3-4/kalman"]
    delivered, lost, in_flight = (counts[2][:, c] for c in range(3))
    assert delivered[-1] + lost[-1] + in_flight[-1] == 20     # 20 messages sent in 40 s
    assert np.all(np.diff(delivered) >= 0) and set(np.unique(in_flight)) <= {0.0, 1.0}
    ages = series["vehicles/4/network/kalman/age"][2]
    assert ages.shape[1] == 2 and ages.max() >= 3.0 - 1e-9     # hears 2 and 3, age saws
    views = {path for _, path in read_rrd_blueprint_views(rrd).values()}
    assert "/network/links" in views and "/vehicles/4/network" in views


SWITCHING = """
[network]
latency = 1.0
period = 2.0
loss = 0.2
schedule_period = 8.0

[[network.schedule]]      # vehicle 3 hears nobody, vehicle 4 only 2
t = 0.0
down = [[1, 3], [3, 4]]

[[network.schedule]]      # vehicle 2 hears nobody, vehicle 4 only 3
t = 4.0
down = [[1, 2], [2, 4]]
"""


@pytest.mark.slow
def test_a_scenario_file_with_a_schedule_reports_joint_connectivity_and_the_verdict(tmp_path):
    """formation-4's file with a switching [network] appended, through the CLI: the summary
    says that neither graph reaches every vehicle, their union does, and gives the
    mean-square radius over one 8 s period (below 1); no age prediction with switching."""
    from orchestrator.scenario.loader import SCENARIO_DIR
    src = tmp_path / "f4-switching.toml"
    src.write_text((SCENARIO_DIR / "formation-4.toml").read_text() + SWITCHING)
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "orchestrator", "run", "--scenario", str(src),
                        "--deployment", "per-vehicle", "--architecture", "distributed",
                        "--T", "40", "--h", "0.05", "--out", str(out), "--quiet",
                        "--predict", "full"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    m = json.loads((out / "summary.json").read_text())["methods"]["kalman"]
    sch = m["network"]["schedule"]
    assert sch["switch_times"] == [0.0, 4.0] and sch["period"] == 8.0
    assert sch["connected_graphs"] == [False, False] and sch["jointly_connected"] is True
    assert 0.0 < sch["spectral_radius_per_period"] < 1.0 and sch["mean_square_stable"]
    assert m["network"]["cycle_s"] == 8.0
    assert m["age_of_information"]["2"]["1"]["predicted_mean"] is None
    # vehicle 2 hears 1 only in the first half of each period: its information ages
    assert m["age_of_information"]["2"]["1"]["max"] >= 5.0
    bad = tmp_path / "bad.toml"
    bad.write_text(src.read_text().replace("down = [[1, 2], [2, 4]]", "down = [[1, 9]]"))
    r = subprocess.run([sys.executable, "-m", "orchestrator", "run", "--scenario", str(bad),
                        "--deployment", "per-vehicle", "--out", str(tmp_path / "no")],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 2 and "vehicle 9 does not exist" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and not (tmp_path / "no").exists()


@pytest.mark.parametrize("network, fragment", [
    ({"latency": -1.0}, "[network]: latency = -1 s is negative"),
    ({"loss": 1.5}, "[network]: loss = 1.5 is not a probability in [0, 1)"),
    ({"period": 0.0}, "[network]: period = 0 s must be positive"),
    ({"receiver": "guess"}, "[network] receiver = 'guess' is not one of hold, propagate"),
    ({"links": [{"from": 9, "to": 1, "loss": 0.1}]},
     "vehicle 9 does not exist (vehicles are 1..4)"),
    ({"links": [{"from": 2, "to": 2}]}, "network link 2 -> 2: no such communication edge"),
    ({"colour": "blue"}, "[network]: unknown key(s) colour"),
    ({"range": -5.0}, "[network] range = -5 m must be positive"),
    ({"period": 2.005}, "period = 2.005 s is not a whole number of steps h = 0.01 s"),
])
def test_bad_network_settings_are_one_line_naming_the_entry(network, fragment):
    with pytest.raises(ScenarioError) as exc:
        load_scenario("formation-4").with_run(deployment="per-vehicle", network=network)
    msg = str(exc.value)
    assert fragment in msg and "\n" not in msg


def test_a_network_needs_the_per_vehicle_deployment():
    with pytest.raises(ScenarioError, match=r"\[network\] needs \[simulation\] deployment"):
        load_scenario("formation-4").with_run(network={"loss": 0.1})


def test_the_cli_refuses_a_bad_loss_in_one_line(tmp_path):
    r = subprocess.run([sys.executable, "-m", "orchestrator", "run", "--scenario",
                        "formation-4", "--deployment", "per-vehicle", "--loss", "1.2",
                        "--out", str(tmp_path / "x")], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "loss = 1.2 is not a probability" in lines[0]
    assert not (tmp_path / "x").exists()


@pytest.mark.slow
def test_an_ssp_archive_with_the_network_runs_in_fmpy(tmp_path):
    """fmpy's simulate_ssp runs the per-vehicle system with its 4 network FMUs, each with
    its own parameter set: every link's deliveries and losses (its own loss stream, not
    the wiring) are our run's, one sample later (fmpy's row j holds sample j + 1)."""
    pytest.importorskip("fmpy.ssp.simulation")
    from fmpy.ssp.simulation import simulate_ssp

    from orchestrator.cosim.master import run_system
    from orchestrator.interop.ssp import export_ssp, fmpy_parameter_set
    from orchestrator.running import build, scenario_system
    sc = load_scenario("formation-4").with_run(
        deployment="per-vehicle", architecture="distributed",
        network={"latency": 0.2, "period": 0.5, "loss": 0.3})
    ssp = export_ssp(sc, tmp_path / "f4.ssp")
    steps = 300
    result = simulate_ssp(str(ssp), stop_time=steps * sc.h, step_size=sc.h,
                          parameter_set=fmpy_parameter_set(ssp))
    ours, _, _ = run_system(scenario_system(sc), build(sc, tmp_path / "fmus"), steps)
    lost = 0.0
    for i, k in ((1, "leader"), (2, "link[1]"), (4, "link[2]")):
        for s in ("delivered", "lost"):
            got = np.asarray(result[f"network_{i}.{k}.{s}"])[:steps - 1]
            assert np.array_equal(got, ours[f"network_{i}.{k}.{s}"][1:steps, 0]), (i, k, s)
        lost += ours[f"network_{i}.{k}.lost"][-1, 0]
    assert lost > 0


@pytest.mark.slow
@pytest.mark.parametrize("architecture", ["distributed", "centralized"])
def test_a_modem_range_loses_what_is_sent_out_of_range(tmp_path, architecture):
    """[network] range = 14.5 m on formation-4 (10 m offsets: neighbours 14.1 m apart in
    formation, launched up to 33 m apart): the FMUs equal the reference, every message sent
    while its sender was out of range (true positions, computed here from the trajectory) is
    lost, and the prediction says it does not cover a range."""
    from plant_model.acoustic.links import send_steps
    sc = load_scenario("formation-4").with_run(
        T=16.0, deployment="per-vehicle", architecture=architecture,
        network={"latency": 1.0, "period": 2.0, "loss": 0.1, "range": 14.5})
    pv = make_setup(sc, tmp_path / "fmus")
    res = pv.run(Method("kalman", "kalman", "regulator", architecture), 3)
    setup = pv.network(Method("kalman", "kalman", "regulator", architecture))
    ref = network_reference(sc, setup, 3, sc.steps)
    assert np.abs(res.traces["u"] - ref["u"]).max() <= 1e-9 * np.abs(ref["u"]).max()
    limit, pos = setup.net.modem
    far_total = 0
    for c, name in enumerate(res.info["links"]):
        j, _, i = name.split()
        key = ("leader" if j == "leader" else int(j), int(i))
        sends = send_steps(setup.links[key], sc.h, sc.steps - 100)     # arrived by T
        far = sum(np.linalg.norm(pos[key[0]] @ ref["Z"][k] - pos[key[1]] @ ref["Z"][k])
                  > limit for k in sends)
        assert res.traces["link_lost"][-1, c] >= far, name
        far_total += far
    assert far_total > 0
    pred = pv.predictions(Method("kalman", "kalman", "regulator", architecture)).window
    assert pred.cost_rate is None and "modem range" in pred.reason


@pytest.mark.slow
def test_a_long_latency_at_a_message_every_step_is_not_predicted_and_does_not_crash(tmp_path):
    """latency 5 s with a message every step h = 0.01: 500 messages in flight per link,
    32233 states. The run works; the prediction is refused by its estimated work, said in
    one reason, and nothing n x n is built."""
    sc = load_scenario("formation-4").with_run(
        T=1.0, deployment="per-vehicle", architecture="distributed",
        network={"latency": 5.0})
    pv = make_setup(sc, tmp_path / "fmus")
    setup = pv.network(Method("kalman", "kalman", "regulator", "distributed"))
    assert setup.net.n > 30000
    p = pv.predictions(Method("kalman", "kalman", "regulator", "distributed"))
    pred, window = p.window, p.window_from_start
    assert pred.cost_rate is None and window is None and "1e13" in pred.reason
    res = pv.run(Method("kalman", "kalman", "regulator", "distributed"), 0)
    assert np.all(res.traces["link_delivered"][-1] == 0)      # nothing arrives within 1 s

"""A compare uses one statistics window for all its methods: the latest of their own windows
(each starts at its settling time, 5 time constants of its slowest closed-loop mode), so
that the methods are compared on the same samples, and predicted over them. summary.json
says so: the top-level ``stats_window_s`` is that window, every method's
``window_start_s`` its start and ``prediction_window_s`` the window of its window
predictions.

The scenario is the paper's system with a slow plant, fast exosystems and a noisy sensor:
the Kalman loop then settles in 9.95 s, the ideal one in 8.16 s."""
from __future__ import annotations

import json

import numpy as np
import pytest

from orchestrator.cli import main
from orchestrator.recording import read_rrd_scalars

T, H = 24.0, 0.01
#: the paper's example (orchestrator/scenario/builtin/paper.toml) with a plant pole at
#: -0.5, exosystem poles near -9 and -8, and V_y = 100: two settling times
SCENARIO = f"""
name = "two-settling-times"
[simulation]
T = {T}
h = {H}
seed = 0
estimator = "kalman"
[vehicles]
A  = [[-0.5, 0.0], [0.0, -0.5]]
B1 = [[3.0, 2.0], [4.0, 5.0]]
B2 = [[-0.1, 0.0], [0.0, 1.0]]
C  = [[1.0, 2.0], [3.0, 4.0]]
x0 = [0.0, 0.0]
[disturbance]
K  = [[-9.0, 1.0], [-1.0, -9.0]]
w0 = [0.3, 0.4]
[reference]
F  = [[-8.0, 1.0], [-1.0, -8.0]]
H  = [[0.2, 4.0], [2.0, 5.0]]
z0 = [0.4, 0.5]
[noise]
convention = "intensity"
W_x = 2.0
W_w = 2.0
W_z = 2.0
V_y = 100.0
V_ybar = 2.0
[cost]
Q = 1.0
R = 1.0
"""


def _recomputed(series: dict, method: str, k0: int) -> tuple[float, list[float]]:
    """Cost rate (Q = R = I) and RMS of each error component of ``method``'s recorded
    traces over samples k >= k0, from the .rrd."""
    e = np.column_stack([series[f"error/{i}/{method}"][2] for i in (1, 2)])[k0:]
    u = np.column_stack([series[f"control/{i}/{method}"][2] for i in (1, 2)])[k0:]
    cost = float(np.mean(np.sum(e * e, axis=1) + np.sum(u * u, axis=1)))
    return cost, np.sqrt(np.mean(e * e, axis=0)).tolist()


def _window_prediction(sc, mode: str, k0: int):
    """The expected statistics over [k0 h, T) from the known start, straight from the
    analysis function (orchestrator.analysis.prediction.predict_stationary)."""
    from controller_fmu.regulator import tracking_law
    from estimator_fmu.registry import make_estimator
    from orchestrator.analysis.prediction import predict_stationary
    from plant_model.discretization import discretize
    model = discretize(sc.system, sc.h)
    return predict_stationary(sc.system, model, make_estimator(sc.system, model, mode),
                              tracking_law(sc.system, sc.tracking).Ks,
                              window=(k0, sc.steps), transient=True)


def test_one_window_for_every_method(tmp_path, capsys):
    from orchestrator.running.setup import method_list
    from orchestrator.running.systems import make_setup
    from orchestrator.scenario import load_scenario

    spec = tmp_path / "two.toml"
    spec.write_text(SCENARIO)
    sc = load_scenario(str(spec))
    methods = method_list(sc, ["kalman", "ideal"])
    setup = make_setup(sc, tmp_path / "fmus", methods)
    own = {m.name: setup.predictions(m).k0 for m in methods}
    assert own == {"kalman": 995, "ideal": 816}          # the case: two settling times
    k0 = max(own.values())

    out = tmp_path / "cmp"
    assert main(["compare", "--scenario", str(spec), "--methods", "kalman,ideal",
                 "--seeds", "0", "--quiet", "--out", str(out)]) == 0
    printed = capsys.readouterr().out.splitlines()
    summary = json.loads((out / "summary.json").read_text())

    assert summary["stats_window_s"] == [k0 * H, T]
    starts = {n: m["window_start_s"] for n, m in summary["methods"].items()}
    assert starts == {"kalman": k0 * H, "ideal": k0 * H}
    assert summary["stationary"] is True
    # every method's window predictions are over the common window, ideal's too (its own
    # starts at 8.16 s): the value is the analysis function's for that window
    assert printed[0].endswith("statistics over t in [9.95, 24) s")
    assert not any("own window" in line for line in printed)
    for name, mode in (("kalman", "kalman"), ("ideal", "ideal")):
        m = summary["methods"][name]
        assert m["prediction_window_s"] == [k0 * H, T]
        expected = _window_prediction(sc, mode, k0)
        assert m["cost_rate"]["predicted_window"] == pytest.approx(expected.cost_rate,
                                                                   rel=1e-12)
        assert m["rms_e"]["predicted_window"] == pytest.approx(expected.rms_e, rel=1e-12)
    own_window = _window_prediction(sc, "ideal", own["ideal"])
    assert summary["methods"]["ideal"]["cost_rate"]["predicted_window"] != pytest.approx(
        own_window.cost_rate, rel=1e-9)                 # the window matters

    series = read_rrd_scalars(out / "two-settling-times.rrd")
    assert summary["rrd"]["recorded_every_steps"] == 1
    for name in ("kalman", "ideal"):
        m = summary["methods"][name]
        cost, rms_e = _recomputed(series, name, k0)
        assert m["cost_rate"]["per_seed"] == [pytest.approx(cost, rel=1e-12)]
        assert m["cost_rate"]["mean"] == pytest.approx(cost, rel=1e-12)
        assert m["rms_e"]["mean"] == pytest.approx(rms_e, rel=1e-12)
    # the ideal method's own, earlier window gives other figures: the window matters
    early, _ = _recomputed(series, "ideal", own["ideal"])
    assert summary["methods"]["ideal"]["cost_rate"]["mean"] != pytest.approx(early,
                                                                              rel=1e-6)


@pytest.mark.parametrize("scenario, deployment, architecture", [
    ("formation-4", "stacked", "centralized"),
    ("formation-4", "per-vehicle", "centralized"),
    ("formation-4", "per-vehicle", "distributed"),
    ("formation-4-links", "per-vehicle", "distributed"),
])
def test_window_predictions_over_a_given_window_in_every_deployment(
        tmp_path, scenario, deployment, architecture):
    """What compare asks of every deployment: the window predictions of a method over the
    common window [k0 h, T) (here 2 s after the method's own start), equal to what the
    analysis functions give for that window; the stationary ones unchanged."""
    from orchestrator.analysis.distributed_verdict import predict_cost
    from orchestrator.analysis.per_vehicle import distributed_initial_state, distributed_loop_of
    from orchestrator.analysis.prediction import method_predictions
    from orchestrator.running.network import network_predictions
    from orchestrator.running.setup import Method, window_dependent
    from orchestrator.running.systems import make_setup
    from orchestrator.scenario import load_scenario
    from plant_model.discretization import discretize

    sc = load_scenario(scenario).with_run(T=60.0, deployment=deployment,
                                          architecture=architecture)
    method = Method.of(sc)
    setup = make_setup(sc, tmp_path / "fmus", [method])
    own = setup.predictions(method)
    assert window_dependent(own)
    k0 = own.k0 + 200
    common = setup.predictions(method, k0)
    assert common.k0 == k0 and common.stationary == own.stationary
    if sc.network is not None:
        expected = network_predictions(sc, setup.network(method), None, k0)[1]
    elif architecture == "distributed":
        loop = distributed_loop_of(sc, method.estimator, method.tracking, sc.distributed)
        expected = predict_cost(loop, (k0, sc.steps), distributed_initial_state(sc, loop))
    else:
        from controller_fmu.regulator import tracking_law
        from estimator_fmu.registry import make_estimator
        model = discretize(sc.system, sc.h)
        expected = method_predictions(sc, model, make_estimator(sc.system, model,
                                                                method.estimator),
                                      tracking_law(sc.system, method.tracking).Ks, k0)[1]
    assert common.window.cost_rate == pytest.approx(expected.cost_rate, rel=1e-12)
    assert common.window.cost_rate != pytest.approx(own.window.cost_rate, rel=1e-9)

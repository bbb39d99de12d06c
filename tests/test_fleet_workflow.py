"""formation-4 end to end: Monte-Carlo against the Lyapunov prediction, and the .rrd a
user opens (3D positions and per-vehicle errors read back against the monolithic loop)."""
from __future__ import annotations

import json
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

from controller_fmu.regulator import tracking_law
from estimator_fmu.registry import make_estimator
from orchestrator.analysis.prediction import predict_stationary
from orchestrator.analysis.reference import run_monolithic
from orchestrator.analysis.summary import stats_window, trace_stats
from orchestrator.cli import main
from orchestrator.recording import read_rrd_points, read_rrd_series
from orchestrator.scenario import load_scenario
from plant_model.discretization import discretize

pytestmark = pytest.mark.slow


def _seed_cost(args: tuple[str, int, int]) -> float:
    """The window cost rate of one seed of formation-4's monolithic loop (a worker)."""
    tracking, seed, k0 = args
    sc = load_scenario("formation-4")
    s = sc.system
    return trace_stats(run_monolithic(s, sc.h, "kalman", seed, sc.steps, tracking), s.Q, s.R,
                       k0)["cost_rate"]


@pytest.mark.slow
@pytest.mark.parametrize("tracking", ["lq", "regulator"])
def test_formation_4_cost_rate_agrees_with_the_lyapunov_prediction(tracking):
    """8 seeds of the full 600 s run; the prediction is the stationary Lyapunov part plus
    the mean motion along the planned survey path over the same window."""
    sc = load_scenario("formation-4")
    s = sc.system
    model = discretize(s, sc.h)
    Ks = tracking_law(s, tracking).Ks
    est = make_estimator(s, model, "kalman")
    k0 = stats_window(sc.T, sc.h, predict_stationary(s, model, est, Ks).settling_time)
    pred = predict_stationary(s, model, est, Ks, window=(k0, sc.steps))
    with ProcessPoolExecutor(max_workers=2) as pool:         # the seeds on both cores
        costs = np.array(list(pool.map(_seed_cost, [(tracking, seed, k0) for seed in range(8)])))
    se = costs.std(ddof=1) / np.sqrt(len(costs))
    assert abs(costs.mean() - pred.cost_rate) < 3 * se + 1e-3 * pred.cost_rate, (
        costs.mean(), se, pred.cost_rate)
    # the noise-driven part is a small but resolved share of the total
    stochastic = predict_stationary(s, model, est, Ks).cost_rate
    assert 0.02 * pred.cost_rate < stochastic < 0.2 * pred.cost_rate


@pytest.mark.slow
def test_compare_writes_the_3d_view_and_per_vehicle_series(tmp_path, capsys):
    out = tmp_path / "f4"
    assert main(["compare", "--scenario", "formation-4", "--T", "60", "--seeds", "0",
                 "--quiet", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["methods"]) == {"lq", "regulator"}
    stride = summary["rrd"]["recorded_every_steps"]
    assert stride == 5                      # 20 Hz at h = 0.01 s
    sc = load_scenario("formation-4").with_run(T=60.0)
    rrd = out / "formation-4.rrd"
    for tracking in ("lq", "regulator"):
        ref = run_monolithic(sc.system, sc.h, "kalman", 0, sc.steps, tracking)
        step, _, pos = read_rrd_points(rrd, f"world/{tracking}/vehicles")
        assert step[1] - step[0] == stride
        x = ref["x"][step]
        expected = np.stack([x[:, 6 * i:6 * i + 3] for i in range(4)], axis=1)
        np.testing.assert_allclose(pos, expected, atol=1e-4, rtol=1e-6)
        step_e, _, e2 = read_rrd_series(rrd, f"vehicles/2/error/{tracking}")
        np.testing.assert_allclose(e2, ref["e"][step_e, 3:6], atol=1e-9)
    m = summary["methods"]
    assert (m["regulator"]["steady_error"]["max_rms_e_without_noise_predicted"]
            < 0.1 * m["lq"]["steady_error"]["max_rms_e_without_noise_predicted"])

"""The time-varying Kalman filter (kalman-tv): P0 checks, its gains, its predictions against
an independent reference (the monolithic numpy loop over many seeds, and a brute-force
recursion), its convergence to the steady filter, and its pythonfmu FMU against the
monolithic loop."""
from __future__ import annotations

import numpy as np
import pytest

from controller_fmu.regulator import tracking_law
from estimator_fmu.estimators import kalman_estimator
from estimator_fmu.kalman_tv import check_initial_covariance, gain_sequence
from estimator_fmu.registry import estimator_kind, make_estimator
from orchestrator.analysis.prediction import predict_stationary
from orchestrator.analysis.reference import run_monolithic
from orchestrator.analysis.tv_prediction import tv_window_moments
from orchestrator.running import scenario_config
from orchestrator.scenario import ScenarioError, load_scenario
from plant_model.discretization import discretize
from plant_model.linalg_checks import ModelError
from support.loop import run_cosimulation

TV = "kalman-tv"


@pytest.fixture(scope="module")
def loop():
    sc = load_scenario("paper")
    model = discretize(sc.system, sc.h)
    return sc, model, tracking_law(sc.system, "lq").Ks


@pytest.mark.parametrize("value, says", [
    ([[1.0, 0.0], [0.0, 1.0]], "must be 6 x 6 (the filter's state), got shape 2 x 2"),
    (np.diag([1, 1, 1, 1, 1, -2.0]).tolist(), "least eigenvalue is -2"),
    ((np.eye(6) + np.triu(np.ones((6, 6)), 1)).tolist(), "is not symmetric: entry [1,2]"),
    (True, "not a boolean"),
])
def test_bad_P0_is_refused_in_one_line_naming_it(value, says):
    with pytest.raises(ModelError) as exc:
        check_initial_covariance(value, 6)
    assert "[estimator] P0" in str(exc.value) and says in str(exc.value)
    assert "\n" not in str(exc.value)


def test_a_scenario_with_a_bad_P0_is_refused_naming_the_file(tmp_path):
    from orchestrator.scenario.loader import SCENARIO_DIR
    text = (SCENARIO_DIR / "paper.toml").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(text + '\n[estimator]\nP0 = [[1.0, 2.0], [3.0, 4.0]]\n')
    with pytest.raises(ScenarioError) as exc:
        load_scenario(str(bad))
    msg = str(exc.value)
    assert "bad.toml" in msg and "P0 must be 6 x 6" in msg and "2 x 2" in msg
    good = tmp_path / "good.toml"
    good.write_text(text.replace('estimator = "kalman"', f'estimator = "{TV}"')
                    + "\n[estimator]\nP0 = 4.0\n")
    sc = load_scenario(str(good))
    assert sc.estimator == TV and np.array_equal(sc.estimator_P0, 4.0 * np.eye(6))


@pytest.mark.parametrize("P0", [0.0, 50.0])
def test_gains_follow_the_riccati_recursion_to_the_steady_gain(loop, P0):
    sc, model, _ = loop
    steady = kalman_estimator(sc.system, model).gain[0]
    Ls = gain_sequence(P0 * np.eye(6), model.Ad, model.M, model.Qd, model.Rd, 3000)
    if P0 == 0.0:
        assert np.abs(Ls[0]).max() == 0.0         # the known start: no trust in the first y
    assert np.abs(Ls[1] - steady).max() > 1e-3 * np.abs(steady).max()   # a real transient
    assert np.abs(Ls[-1] - steady).max() <= 1e-9 * np.abs(steady).max()


def test_the_closed_form_tail_equals_the_recursion_step_by_step(loop):
    sc, model, Ks = loop
    est = make_estimator(sc.system, model, TV, {"P0": 20.0 * np.eye(6)})
    fast = tv_window_moments(sc.system, model, est, Ks, (50, 4000))
    slow = tv_window_moments(sc.system, model, est, Ks, (50, 4000), tol=0.0)
    assert fast["kc"] < 4000 and slow["kc"] == 4000
    for key in ("ee", "uu", "ee_mean"):
        assert np.allclose(fast[key], slow[key], rtol=1e-9, atol=1e-12 * np.abs(slow[key]).max())


def test_after_convergence_the_prediction_is_the_steady_filters(loop):
    sc, model, Ks = loop
    est = make_estimator(sc.system, model, TV, {"P0": 20.0 * np.eye(6)})
    steady = predict_stationary(sc.system, model, kalman_estimator(sc.system, model), Ks)
    # a window long after the start: the gains and the covariance have converged
    m = tv_window_moments(sc.system, model, est, Ks, (20000, 40000))
    cost = np.trace(sc.system.Q @ m["ee"]) + np.trace(sc.system.R @ m["uu"])
    assert cost == pytest.approx(steady.cost_rate, rel=1e-9)
    # over the first second the transient costs more with a large P0 and less with the
    # known start than the steady filter's window from the same start
    first = {p: tv_window_moments(sc.system, model, make_estimator(
        sc.system, model, TV, {"P0": p * np.eye(6)}), Ks, (0, 100)) for p in (0.0, 20.0)}
    costs = {p: np.trace(sc.system.Q @ v["ee"]) + np.trace(sc.system.R @ v["uu"])
             for p, v in first.items()}
    assert costs[20.0] > 1.2 * costs[0.0]


@pytest.mark.parametrize("P0", [0.0, 20.0])
def test_predicted_transient_cost_matches_the_monolithic_loop_over_seeds(loop, P0):
    """The expected cost over samples 0..149 (the gains' transient) against the mean of
    the independent numpy loop (explicit inverse, standard-form update) over 300 seeds:
    within 3.5 standard errors."""
    sc, model, Ks = loop
    K = 150
    est = make_estimator(sc.system, model, TV, {"P0": P0 * np.eye(6)})
    m = tv_window_moments(sc.system, model, est, Ks, (0, K))
    pred = float(np.trace(sc.system.Q @ m["ee"]) + np.trace(sc.system.R @ m["uu"]))
    costs = []
    for seed in range(300):
        tr = run_monolithic(sc.system, sc.h, TV, seed, K, P0=P0 * np.eye(6))
        costs.append(np.mean(np.einsum("ki,ij,kj->k", tr["e"], sc.system.Q, tr["e"])
                             + np.einsum("ki,ij,kj->k", tr["u"], sc.system.R, tr["u"])))
    costs = np.array(costs)
    se = costs.std(ddof=1) / np.sqrt(costs.size)
    assert abs(costs.mean() - pred) <= 3.5 * se, (costs.mean(), pred, se)


def test_the_registry_row_says_what_the_deployments_need():
    row = estimator_kind(TV)
    assert row.time_varying and row.solves_riccati and not row.uses_truth
    assert row.distributed is None and not row.over_links and row.navigation is None
    assert row.native == "covariance"


@pytest.mark.parametrize("P0", [0.0, 20.0])
def test_the_pythonfmu_loop_reproduces_the_monolithic_loop(tmp_path, P0):
    from orchestrator.cosim.build import build_fmus
    sc = load_scenario("paper")
    cfg = dict(scenario_config(sc), P0=(P0 * np.eye(6)).tolist())
    res = run_cosimulation(build_fmus(cfg, tmp_path), cfg, mode=TV, seed=5, steps=300)
    ref = run_monolithic(sc.system, sc.h, TV, 5, 300, P0=P0 * np.eye(6))
    for key in ("x", "xhat", "what", "zhat", "u"):
        scale = np.abs(ref[key]).max()
        assert np.abs(res.traces[key] - ref[key]).max() <= 1e-9 * scale, key

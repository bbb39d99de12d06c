"""orchestrator.analysis.prediction: stationary RMS and cost rate, against hand formulas and
long Monte-Carlo runs of the same closed loop (Plant + estimator + LQ gains)."""
from __future__ import annotations

import numpy as np
import pytest

from controller_fmu.design import lq_tracking_design
from estimator_fmu.registry import ESTIMATORS, make_estimator
from orchestrator.analysis.prediction import closed_loop, predict_stationary
from plant_model.discretization import discretize
from plant_model.plant import Plant, plant_output_layout
from plant_model.system import LinearSystem

#: the time-invariant estimators (kalman-tv has its own predictions: tests/test_kalman_tv.py)
ESTIMATOR_MODES = tuple(k for k, e in ESTIMATORS.items() if not e.time_varying)


def _setup(system, h, mode):
    model = discretize(system, h)
    design = lq_tracking_design(system)
    Ks = design.gain_on_state()
    est = make_estimator(system, model, mode)
    return model, design, Ks, est


def _predict(system, h, mode):
    model, design, Ks, est = _setup(system, h, mode)
    return predict_stationary(system, model, est, Ks)


def monte_carlo(system, h, mode, steps, seed, burn=2000, batches=20):
    """Run the sampled closed loop; return per-batch means of the cost rate, e^2 and u^2."""
    model, design, Ks, est = _setup(system, h, mode)
    lay = plant_output_layout(model)
    plant = Plant(model, system.initial_state(), seed)
    Q, R = system.Q, system.R
    cost = np.empty(steps)
    e2 = np.empty((steps, system.p))
    u2 = np.empty((steps, system.m))
    for k in range(steps):
        out = plant.output
        mvec = np.concatenate([out[lay["y"]], out[lay["ybar"]], out[lay["x"]],
                               out[lay["w"]], out[lay["z"]]])
        xhat = est.estimate(mvec)
        u = -Ks @ xhat
        e = out[lay["e"]]
        cost[k] = e @ Q @ e + u @ R @ u
        e2[k] = e * e
        u2[k] = u * u
        est.update(xhat, u)
        plant.step(u)
    n_used = (steps - burn) // batches * batches

    def bm(a):
        return a[burn:burn + n_used].reshape(batches, n_used // batches, *a.shape[1:]).mean(axis=1)

    return bm(cost), bm(e2), bm(u2)


def assert_agrees(batch_means, predicted, nse=4.0):
    mean = batch_means.mean(axis=0)
    se = batch_means.std(axis=0, ddof=1) / np.sqrt(batch_means.shape[0])
    z = np.abs(mean - predicted) / se
    assert np.all(z < nse), f"MC {mean} +- {se} vs predicted {predicted}: {z} SE"
    return mean, se


# hand formulas -----------------------------------------------------------------------
def _scalar_lq(a, b, c, q, rr):
    root = np.sqrt(a * a + b * b * c * c * q / rr)
    P = rr * (a + root) / (b * b)
    return b * P / rr                                # kx


def test_ideal_scalar_cost_by_hand(make_scalar):
    """Noise only on x, exact state feedback u = -kx x (w, z decay to 0):
    x[k+1] = phi x + v, Var x = qd / (1 - phi^2), J/T = (q c^2 + R kx^2) Var x."""
    a, b, c, q, rr, W, h = -0.5, 2.0, 1.5, 2.0, 0.5, 3.0, 0.05
    s = make_scalar(A=[[a]], B1=[[b]], C=[[c]], Q=q, R=rr, W_x=W, W_w=0.0, W_z=0.0)
    model, design, Ks, est = _setup(s, h, "ideal")
    kx = _scalar_lq(a, b, c, q, rr)
    assert design.Kx[0, 0] == pytest.approx(kx, rel=1e-12)
    ad = np.exp(a * h)
    bd = b * (ad - 1) / a
    qd = W * (np.exp(2 * a * h) - 1) / (2 * a)
    phi = ad - bd * kx
    var_x = qd / (1 - phi * phi)
    pred = predict_stationary(s, model, est, Ks)
    assert pred.cost_rate == pytest.approx((q * c * c + rr * kx * kx) * var_x, rel=1e-10)
    assert pred.rms_e[0] == pytest.approx(abs(c) * np.sqrt(var_x), rel=1e-10)
    assert pred.rms_u[0] == pytest.approx(abs(kx) * np.sqrt(var_x), rel=1e-10)
    # spectral radius: the slowest of phi, exp(K h), exp(F h)
    assert pred.spectral_radius == pytest.approx(max(abs(phi), np.exp(-2 * h), np.exp(-0.5 * h)),
                                                 rel=1e-12)
    assert pred.reason is None


def test_kalman_scalar_cost_by_hand(make_scalar):
    """Noise on x and on y (plus a little on ybar, needed for the z filter); no noise on
    w and z, and B2 = 0, so only the x filter matters:
      P = ad^2 P - ad^2 P^2 c^2 / (c^2 P + rd) + qd,  L = P c / (c^2 P + rd),
      Pf = P rd / (c^2 P + rd),  xf[k+1] = phi xf[k] + L nu[k+1], Var nu = c^2 P + rd,
      Var xf = L^2 (c^2 P + rd) / (1 - phi^2),  Var x = Var xf + Pf,
      J/T = q c^2 Var x + R kx^2 Var xf."""
    a, b, c, q, rr, W, V, h = 0.3, 1.0, 2.0, 1.0, 2.0, 1.5, 0.2, 0.02
    s = make_scalar(A=[[a]], B1=[[b]], B2=[[0.0]], C=[[c]], Q=q, R=rr, W_x=W, W_w=0.0,
                    W_z=0.0, V_y=V, V_ybar=0.7)
    model, design, Ks, est = _setup(s, h, "kalman")
    kx = _scalar_lq(a, b, c, q, rr)
    ad = np.exp(a * h)
    bd = b * (ad - 1) / a
    qd = W * (np.exp(2 * a * h) - 1) / (2 * a)
    rd = V / h
    # c^2 P^2 + (rd - ad^2 rd - qd c^2) P - qd rd = 0
    bq = rd - ad * ad * rd - qd * c * c
    P = (-bq + np.sqrt(bq * bq + 4 * c * c * qd * rd)) / (2 * c * c)
    L = P * c / (c * c * P + rd)
    Pf = P * rd / (c * c * P + rd)
    phi = ad - bd * kx
    var_xf = L * L * (c * c * P + rd) / (1 - phi * phi)
    var_x = var_xf + Pf
    pred = predict_stationary(s, model, est, Ks)
    assert pred.cost_rate == pytest.approx(q * c * c * var_x + rr * kx * kx * var_xf, rel=1e-9)
    assert pred.rms_e[0] == pytest.approx(abs(c) * np.sqrt(var_x), rel=1e-9)
    assert pred.rms_u[0] == pytest.approx(abs(kx) * np.sqrt(var_xf), rel=1e-9)


def _smith_lyapunov(Phi, Q, iters=60):
    """sum_k Phi^k Q Phi'^k by the doubling (Smith) iteration, without scipy."""
    S, A = Q.copy(), Phi.copy()
    for _ in range(iters):
        S = S + A @ S @ A.T
        A = A @ A
        if np.abs(A).max() < 1e-18:
            break
    return S


def test_paper_ideal_against_independent_closed_loop(paper_system):
    """Ideal mode: X = s, Phi = Ad - Bd Ks, noise v with covariance Qd; built by hand."""
    model, design, Ks, est = _setup(paper_system, 0.01, "ideal")
    Phi = model.Ad - model.Bd @ Ks
    Sigma = _smith_lyapunov(Phi, model.Qd)
    See = model.E @ Sigma @ model.E.T
    Suu = Ks @ Sigma @ Ks.T
    pred = predict_stationary(paper_system, model, est, Ks)
    assert pred.cost_rate == pytest.approx(np.trace(See) + np.trace(Suu), rel=1e-8)
    np.testing.assert_allclose(pred.rms_e, np.sqrt(np.diag(See)), rtol=1e-8)
    np.testing.assert_allclose(pred.rms_u, np.sqrt(np.diag(Suu)), rtol=1e-8)


@pytest.mark.parametrize("mode", ESTIMATOR_MODES)
def test_closed_loop_matrices_reproduce_one_step(paper_system, mode):
    """X[k+1] = Phi X + Gam eta, u = Gx X + Geta eta, against the components stepped
    by hand with an arbitrary state and noise vector."""
    model, design, Ks, est = _setup(paper_system, 0.01, mode)
    Phi, Gam, Gx, Geta = closed_loop(model, est, Ks)
    rng = np.random.default_rng(3)
    ns, p = model.ns, model.p
    s = rng.standard_normal(ns)
    q = rng.standard_normal(est.q0.shape[0])
    eta = rng.standard_normal(ns + 2 * p)
    est.q = q.copy()
    mvec = np.concatenate([model.M @ s + eta[ns:], s])
    xhat = est.estimate(mvec)
    u = -Ks @ xhat
    est.update(xhat, u)
    s_next = model.Ad @ s + model.Bd @ u + eta[:ns]
    X = np.concatenate([s, q])
    np.testing.assert_allclose(Phi @ X + Gam @ eta, np.concatenate([s_next, est.q]),
                               rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(Gx @ X + Geta @ eta, u, rtol=1e-12, atol=1e-12)


# the paper's ordering -------------------------------------------------------------------
def test_paper_kalman_beats_classical_and_ideal_beats_kalman(paper_system):
    costs = {}
    for mode in ESTIMATOR_MODES:
        model, design, Ks, est = _setup(paper_system, 0.01, mode)
        pred = predict_stationary(paper_system, model, est, Ks)
        assert pred.reason is None and pred.spectral_radius < 1
        assert np.all(np.isfinite(pred.rms_e)) and np.all(np.isfinite(pred.rms_u))
        costs[mode] = pred.cost_rate
    assert costs["kalman"] < costs["classical"]
    assert costs["ideal"] <= costs["kalman"]
    assert costs["ideal"] > 0


def test_prediction_scales_with_noise(paper_system):
    """Every term is quadratic in the noise: doubling every intensity doubles the cost."""
    m2 = paper_system.to_mapping()
    for k in ("W_x", "W_w", "W_z", "V_y", "V_ybar"):
        m2[k] = (2 * np.array(m2[k])).tolist()
    s2 = LinearSystem.from_mapping(m2)
    for mode in ESTIMATOR_MODES:
        c1 = _predict(paper_system, 0.01, mode).cost_rate
        c2 = _predict(s2, 0.01, mode).cost_rate
        assert c2 == pytest.approx(2 * c1, rel=1e-8), mode


def test_not_stationary_gives_a_reason(paper_mapping):
    """A marginally stable reference (a circle) with noise has no stationary state."""
    paper_mapping["F"] = [[0.0, 1.0], [-1.0, 0.0]]
    s = LinearSystem.from_mapping(paper_mapping)
    model, design, Ks, est = _setup(s, 0.01, "kalman")
    pred = predict_stationary(s, model, est, Ks)
    assert pred.cost_rate is None and pred.rms_e is None and pred.rms_u is None
    assert pred.spectral_radius >= 1.0 - 1e-12
    assert "not stationary" in pred.reason and "spectral radius" in pred.reason
    assert pred.settling_time == float("inf")


def test_settling_time_is_five_time_constants(make_scalar):
    s = make_scalar(F=[[-0.2]], K=[[-3.0]])
    model, design, Ks, est = _setup(s, 0.05, "ideal")
    pred = predict_stationary(s, model, est, Ks)
    # the slowest mode is the reference, time constant 1 / 0.2 s
    assert pred.spectral_radius == pytest.approx(np.exp(-0.2 * 0.05), rel=1e-12)
    assert pred.settling_time == pytest.approx(5 / 0.2, rel=1e-9)


# Monte-Carlo --------------------------------------------------------------------------
def _mc_scalar(make_scalar):
    # all noises on, every time constant <= 2 s, h = 0.05 s
    return make_scalar(A=[[-1.0]], B1=[[1.0]], B2=[[1.0]], C=[[1.0]], F=[[-0.5]], H=[[1.0]],
                       K=[[-2.0]], W_x=1.0, W_w=1.0, W_z=1.0, V_y=1.0, V_ybar=1.0)


def _monte_carlo_agrees(s, mode: str, steps: int, max_rel_se: float, **kw) -> None:
    """Monte-Carlo cost rate and mean squares of e and u agree with the prediction, with a
    standard error below ``max_rel_se`` of the predicted cost."""
    model, design, Ks, est = _setup(s, 0.05, mode)
    pred = predict_stationary(s, model, est, Ks)
    cost, e2, u2 = monte_carlo(s, 0.05, mode, steps, **kw)
    mean, se = assert_agrees(cost, pred.cost_rate)
    assert se < max_rel_se * pred.cost_rate
    assert_agrees(e2, np.square(pred.rms_e))
    assert_agrees(u2, np.square(pred.rms_u))


def test_monte_carlo_scalar_kalman_short(make_scalar):
    """40,000 steps (2,000 s, 1,000 correlation times of the slowest mode)."""
    _monte_carlo_agrees(_mc_scalar(make_scalar), "kalman", 40_000, 0.05, seed=17, burn=400)


@pytest.mark.slow
@pytest.mark.parametrize("mode", ESTIMATOR_MODES)
def test_monte_carlo_scalar_200k(make_scalar, mode):
    _monte_carlo_agrees(_mc_scalar(make_scalar), mode, 200_000, 0.02, seed=2024, burn=1000,
                        batches=40)


@pytest.mark.slow
@pytest.mark.parametrize("mode", ESTIMATOR_MODES)
def test_monte_carlo_paper_example(paper_system, mode):
    """The paper's example at h = 0.01 s: 200,000 steps = 2,000 s (about 60 settling
    times of 33 s), 20 batches of 100 s."""
    model, design, Ks, est = _setup(paper_system, 0.01, mode)
    pred = predict_stationary(paper_system, model, est, Ks)
    cost, e2, u2 = monte_carlo(paper_system, 0.01, mode, 202_000, seed=7, burn=2000)
    assert_agrees(cost, pred.cost_rate)
    assert_agrees(e2, np.square(pred.rms_e))
    assert_agrees(u2, np.square(pred.rms_u))


def test_window_average_covariance_against_the_recursion(paper_system):
    """Sigma_{k+1} = Phi Sigma_k Phi' + G from Sigma_0 = 0, averaged over k0..K-1 by brute
    force, against the closed form of two Lyapunov equations and matrix powers."""
    from scipy.linalg import block_diag, solve_discrete_lyapunov

    from orchestrator.analysis.prediction import window_average_covariance
    model, _, Ks, est = _setup(paper_system, 0.01, "kalman")
    Phi, Gam, _, _ = closed_loop(model, est, Ks)
    G = Gam @ block_diag(model.Qd, model.Rd) @ Gam.T
    Sigma = solve_discrete_lyapunov(Phi, G)
    for k0, K in ((0, 1), (0, 50), (120, 700), (3000, 3400)):
        S, total = np.zeros_like(Phi), np.zeros_like(Phi)
        for k in range(K):
            if k >= k0:
                total += S
            S = Phi @ S @ Phi.T + G
        brute = total / (K - k0)
        closed = window_average_covariance(Phi, Sigma, k0, K)
        np.testing.assert_allclose(closed, brute, rtol=1e-9, atol=1e-9 * np.abs(Sigma).max())
    # a window long after the start: the stationary covariance
    far = window_average_covariance(Phi, Sigma, 200_000, 300_000)
    np.testing.assert_allclose(far, Sigma, rtol=1e-9, atol=1e-12)


def test_transient_prediction_is_below_the_stationary_one_early(paper_system):
    model, _, Ks, est = _setup(paper_system, 0.01, "kalman")
    stat = predict_stationary(paper_system, model, est, Ks)
    early = predict_stationary(paper_system, model, est, Ks, window=(250, 500), transient=True)
    late = predict_stationary(paper_system, model, est, Ks, window=(20_000, 30_000),
                              transient=True)
    assert early.cost_rate < 0.95 * stat.cost_rate          # noise has not built up yet
    assert late.cost_rate == pytest.approx(stat.cost_rate, rel=1e-3)

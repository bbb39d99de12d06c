"""estimator_fmu.estimators: steady-state Kalman, classical and ideal estimators."""
from __future__ import annotations

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm

from estimator_fmu.estimators import steady_kalman
from estimator_fmu.registry import ESTIMATOR_MODES, make_estimator
from plant_model.discretization import discretize
from plant_model.linalg_checks import ModelError
from plant_model.plant import Plant, plant_output_layout
from plant_model.system import LinearSystem

H = 0.01


def riccati_iteration(Ad, Cm, Qd, Rd, iters=200_000, tol=1e-14):
    """Prediction covariance of the filter by iterating the Riccati recursion from P = Qd."""
    P = Qd.copy()
    for _ in range(iters):
        S = Cm @ P @ Cm.T + Rd
        Pn = Ad @ (P - P @ Cm.T @ np.linalg.solve(S, Cm @ P)) @ Ad.T + Qd
        Pn = 0.5 * (Pn + Pn.T)
        if np.abs(Pn - P).max() <= tol * (1 + np.abs(P).max()):
            return Pn
        P = Pn
    raise AssertionError("Riccati recursion did not converge")


@pytest.fixture(scope="module")
def model(paper_system):
    return discretize(paper_system, H)


def _blocks(model):
    n, r = model.n, model.r
    nxw = n + r
    Cxw = np.hstack([model.M[:model.p, :n], np.zeros((model.p, r))])
    return nxw, Cxw


# Kalman gain --------------------------------------------------------------------------
def test_kalman_xw_gain_equals_riccati_iteration_and_dlqe(paper_system, model):
    nxw, Cxw = _blocks(model)
    Ad, Qd, Rd = model.Ad[:nxw, :nxw], model.Qd[:nxw, :nxw], model.Rd[:2, :2]
    kf = steady_kalman("xw", Ad, Cxw, Qd, Rd)
    P_it = riccati_iteration(Ad, Cxw, Qd, Rd)
    L_it = P_it @ Cxw.T @ np.linalg.inv(Cxw @ P_it @ Cxw.T + Rd)
    np.testing.assert_allclose(kf.P_pred, P_it, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(kf.L, L_it, rtol=1e-8, atol=1e-12)
    # python-control's dlqe returns the predictor gain A P C'(C P C' + R)^-1 = Ad L
    L_pred, P_dlqe, E = control.dlqe(Ad, np.eye(nxw), Cxw, Qd, Rd)
    np.testing.assert_allclose(kf.P_pred, P_dlqe, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(Ad @ kf.L, L_pred, rtol=1e-8, atol=1e-12)
    assert np.all(np.abs(E) < 1)


def test_kalman_z_gain_equals_riccati_iteration(paper_system, model):
    nxw = model.n + model.r
    Ad, Qd, Rd = model.Ad[nxw:, nxw:], model.Qd[nxw:, nxw:], model.Rd[2:, 2:]
    kf = steady_kalman("z", Ad, paper_system.H, Qd, Rd)
    P_it = riccati_iteration(Ad, paper_system.H, Qd, Rd)
    np.testing.assert_allclose(kf.P_pred, P_it, rtol=1e-8, atol=1e-12)
    L_it = P_it @ paper_system.H.T @ np.linalg.inv(paper_system.H @ P_it @ paper_system.H.T + Rd)
    np.testing.assert_allclose(kf.L, L_it, rtol=1e-8, atol=1e-12)


def test_filtered_covariance_is_smaller_than_predicted(model):
    nxw, Cxw = _blocks(model)
    kf = steady_kalman("xw", model.Ad[:nxw, :nxw], Cxw, model.Qd[:nxw, :nxw], model.Rd[:2, :2])
    gap = np.linalg.eigvalsh(kf.P_pred - kf.P_filt)
    assert gap.min() >= -1e-12
    assert np.trace(kf.P_filt) < np.trace(kf.P_pred)
    # the filtered covariance is the Joseph-form update of the predicted one
    L, P, Rd = kf.L, kf.P_pred, model.Rd[:2, :2]
    I_LC = np.eye(nxw) - L @ Cxw
    np.testing.assert_allclose(kf.P_filt, I_LC @ P @ I_LC.T + L @ Rd @ L.T, rtol=1e-9, atol=1e-12)
    assert np.linalg.eigvalsh(kf.P_filt).min() > 0


def test_scalar_kalman_closed_form():
    """x[k+1] = a x + v, y = c x + n: P = a^2 P - a^2 P^2 c^2 / (c^2 P + r) + q."""
    a, c, q, r = 0.9, 2.0, 0.3, 0.5
    kf = steady_kalman("x", np.array([[a]]), np.array([[c]]), np.array([[q]]), np.array([[r]]))
    # c^2 P^2 + (r - a^2 r - q c^2) P - q r = 0
    b = r - a * a * r - q * c * c
    P = (-b + np.sqrt(b * b + 4 * c * c * q * r)) / (2 * c * c)
    assert kf.P_pred[0, 0] == pytest.approx(P, rel=1e-12)
    assert kf.L[0, 0] == pytest.approx(P * c / (c * c * P + r), rel=1e-12)
    assert kf.P_filt[0, 0] == pytest.approx(P * r / (c * c * P + r), rel=1e-12)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 6), p=st.integers(1, 4))
def test_random_kalman_gain_against_dlqe(seed, n, p):
    rng = np.random.default_rng(seed)
    Ad = rng.standard_normal((n, n))
    Ad *= rng.uniform(0.3, 1.2) / max(np.abs(np.linalg.eigvals(Ad)).max(), 1e-3)
    Cm = rng.standard_normal((p, n))
    G = rng.standard_normal((n, n))
    Qd = G @ G.T + 0.01 * np.eye(n)
    Gr = rng.standard_normal((p, p))
    Rd = Gr @ Gr.T + 0.1 * np.eye(p)
    kf = steady_kalman("random", Ad, Cm, Qd, Rd)
    L_pred, P_dlqe, E = control.dlqe(Ad, np.eye(n), Cm, Qd, Rd)
    np.testing.assert_allclose(kf.P_pred, P_dlqe, rtol=1e-7, atol=1e-10 * np.abs(P_dlqe).max())
    np.testing.assert_allclose(Ad @ kf.L, L_pred, rtol=1e-7, atol=1e-9 * (1 + np.abs(L_pred).max()))
    # DARE residual by direct substitution
    P = kf.P_pred
    S = Cm @ P @ Cm.T + Rd
    res = Ad @ P @ Ad.T - Ad @ P @ Cm.T @ np.linalg.solve(S, Cm @ P @ Ad.T) + Qd - P
    assert np.abs(res).max() <= 1e-8 * (1 + np.abs(P).max())
    # the filter error dynamics Ad (I - L C) are stable
    assert np.abs(np.linalg.eigvals(Ad @ (np.eye(n) - kf.L @ Cm))).max() < 1


# Kalman refusals ----------------------------------------------------------------------
def test_kalman_refuses_undetectable_xw_pair(paper_mapping):
    """An unstable vehicle mode that C does not see: ([[A, B2], [0, K]], [C, 0]) is not
    detectable (the LQ design is not asked here)."""
    paper_mapping.update(A=[[-1.0, 0.0], [0.0, 0.5]], C=[[1.0, 0.0], [2.0, 0.0]],
                         B2=[[1.0, 0.0], [0.0, 0.0]])
    s = LinearSystem.from_mapping(paper_mapping)
    with pytest.raises(ModelError) as exc:
        make_estimator(s, discretize(s, H), "kalman")
    msg = str(exc.value)
    assert "Kalman filter on [x; w] from y" in msg and "not detectable" in msg, msg
    assert f"{np.exp(0.5 * H):.6g}" in msg, msg       # the sampled mode exp(0.5 h)


def test_kalman_refuses_undetectable_reference(paper_mapping):
    """A marginal reference (F = circle) whose ybar does not see it: H = 0."""
    paper_mapping.update(F=[[0.0, 1.0], [-1.0, 0.0]], H=[[0.0, 0.0], [0.0, 0.0]])
    s = LinearSystem.from_mapping(paper_mapping)
    with pytest.raises(ModelError) as exc:
        make_estimator(s, discretize(s, H), "kalman")
    msg = str(exc.value)
    assert "Kalman filter on z from ybar (pair (F, H))" in msg and "not detectable" in msg, msg


def test_kalman_allows_unseen_but_stable_modes(paper_mapping):
    paper_mapping.update(H=[[0.0, 0.0], [0.0, 0.0]])       # F is Hurwitz: detectable
    s = LinearSystem.from_mapping(paper_mapping)
    est = make_estimator(s, discretize(s, H), "kalman")
    assert est.mode == "kalman"


@pytest.mark.parametrize("name", ["V_y", "V_ybar"])
def test_kalman_refuses_singular_sensor_noise(paper_mapping, name):
    paper_mapping[name] = [[2.0, 0.0], [0.0, 0.0]]
    s = LinearSystem.from_mapping(paper_mapping)
    with pytest.raises(ModelError) as exc:
        make_estimator(s, discretize(s, H), "kalman")
    msg = str(exc.value)
    which = "[x; w] from y" if name == "V_y" else "z from ybar"
    assert which in msg and "positive definite measurement noise" in msg, msg


# the estimators in the loop ------------------------------------------------------------
def _run_open_loop(system, model, mode, steps, seed=5):
    """Drive the plant with a random u, feed the estimator; return truth and estimates."""
    lay = plant_output_layout(model)
    plant = Plant(model, system.initial_state(), seed)
    est = make_estimator(system, model, mode)
    U = np.random.default_rng(seed + 1).standard_normal((steps, system.m))
    truth, ests, meas = [], [], []
    for k in range(steps):
        out = plant.output
        mvec = np.concatenate([out[lay["y"]], out[lay["ybar"]], plant.s])
        e = est.estimate(mvec)
        truth.append(plant.s.copy())
        ests.append(e.copy())
        meas.append(mvec[:2 * model.p].copy())
        est.update(e, U[k])
        plant.step(U[k])
    return np.array(truth), np.array(ests), np.array(meas), U


def test_kalman_estimator_equals_textbook_filter(paper_system, model):
    """The one-form estimator reproduces a textbook predict / update loop."""
    steps = 400
    truth, ests, meas, U = _run_open_loop(paper_system, model, "kalman", steps)
    p = model.p
    nxw, Cxw = _blocks(model)
    Pxw = riccati_iteration(model.Ad[:nxw, :nxw], Cxw, model.Qd[:nxw, :nxw], model.Rd[:p, :p])
    Lxw = Pxw @ Cxw.T @ np.linalg.inv(Cxw @ Pxw @ Cxw.T + model.Rd[:p, :p])
    Az, Hz = model.Ad[nxw:, nxw:], paper_system.H
    Pz = riccati_iteration(Az, Hz, model.Qd[nxw:, nxw:], model.Rd[p:, p:])
    Lz = Pz @ Hz.T @ np.linalg.inv(Hz @ Pz @ Hz.T + model.Rd[p:, p:])
    xp = paper_system.initial_state()[:nxw]
    zp = paper_system.initial_state()[nxw:]
    Bxw = model.Bd[:nxw]
    for k in range(steps):
        xf = xp + Lxw @ (meas[k, :p] - Cxw @ xp)
        zf = zp + Lz @ (meas[k, p:] - Hz @ zp)
        np.testing.assert_allclose(ests[k], np.concatenate([xf, zf]), rtol=1e-7, atol=1e-9)
        xp = model.Ad[:nxw, :nxw] @ xf + Bxw @ U[k]
        zp = Az @ zf


def test_kalman_estimate_error_matches_filtered_covariance(paper_system, model):
    """After the transient, the mean squared error of [x; w] is tr(P_filt), within 4
    standard errors from 20 batch means of 3,000 steps (30 s, many correlation times)."""
    steps, burn, nb = 61_000, 1_000, 20
    truth, ests, meas, _ = _run_open_loop(paper_system, model, "kalman", steps, seed=21)
    nxw, Cxw = _blocks(model)
    kf = steady_kalman("xw", model.Ad[:nxw, :nxw], Cxw, model.Qd[:nxw, :nxw], model.Rd[:2, :2])
    err = (truth - ests)[burn:, :nxw]
    sq = np.sum(err ** 2, axis=1)
    batches = sq.reshape(nb, -1).mean(axis=1)
    se = batches.std(ddof=1) / np.sqrt(nb)
    assert abs(batches.mean() - np.trace(kf.P_filt)) < 4 * se, (batches.mean(), se)
    assert se < 0.1 * np.trace(kf.P_filt)        # the check has teeth
    # and the Kalman estimate of x beats the raw inverse of y by far
    xraw = meas[burn:, :2] @ np.linalg.inv(paper_system.C).T
    assert np.mean((xraw - truth[burn:, :2]) ** 2) > 5 * np.mean(err[:, :2] ** 2)


def test_kalman_without_process_noise_tracks_exactly(paper_mapping):
    """Exact initial state and no process noise: the prediction error stays zero, so the
    filter returns the true state whatever the sensor noise is."""
    paper_mapping.update(W_x=0.0, W_w=0.0, W_z=0.0)
    s = LinearSystem.from_mapping(paper_mapping)
    model = discretize(s, H)
    truth, ests, _, _ = _run_open_loop(s, model, "kalman", 300)
    np.testing.assert_allclose(ests, truth, atol=1e-10)


def test_classical_estimator(paper_system, model):
    truth, ests, meas, _ = _run_open_loop(paper_system, model, "classical", 300)
    n, r, p = model.n, model.r, model.p
    Cinv, Hinv = np.linalg.inv(paper_system.C), np.linalg.inv(paper_system.H)
    np.testing.assert_allclose(ests[:, :n], meas[:, :p] @ Cinv.T, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(ests[:, n + r:], meas[:, p:] @ Hinv.T, rtol=1e-10, atol=1e-12)
    # what runs open loop from w(0): expm(K h k) w0
    eKh = expm(paper_system.K * H)
    w = paper_system.w0.copy()
    for k in range(300):
        np.testing.assert_allclose(ests[k, n:n + r], w, rtol=1e-10, atol=1e-14)
        w = eKh @ w


def test_classical_with_rectangular_full_rank_c_uses_least_squares(paper_mapping):
    paper_mapping.update(C=[[1.0, 2.0], [3.0, 4.0], [0.0, 1.0]],
                         H=[[0.2, 4.0], [2.0, 5.0], [1.0, 0.0]], Q=1.0, V_y=1.0, V_ybar=1.0)
    s = LinearSystem.from_mapping(paper_mapping)
    model = discretize(s, H)
    est = make_estimator(s, model, "classical")
    y = np.array([1.0, -2.0, 0.5])
    mvec = np.concatenate([y, np.zeros(3), np.zeros(model.ns)])
    xhat = est.estimate(mvec)[:2]
    np.testing.assert_allclose(xhat, np.linalg.lstsq(s.C, y, rcond=None)[0], rtol=1e-12)


@pytest.mark.parametrize("name, value", [
    ("C", [[1.0, 2.0], [2.0, 4.0]]),
    ("H", [[1.0, 2.0], [0.5, 1.0]]),
])
def test_classical_refuses_rank_deficient_output_matrix(paper_mapping, name, value):
    paper_mapping[name] = value
    s = LinearSystem.from_mapping(paper_mapping)
    with pytest.raises(ModelError) as exc:
        make_estimator(s, discretize(s, H), "classical")
    msg = str(exc.value)
    assert f"needs {name} with full column rank" in msg and f"{name} has rank 1 < 2" in msg, msg


def test_classical_refuses_too_few_outputs(paper_mapping):
    paper_mapping.update(C=[[1.0, 2.0]], H=[[1.0, 0.0]], Q=1.0, V_y=1.0, V_ybar=1.0)
    s = LinearSystem.from_mapping(paper_mapping)
    with pytest.raises(ModelError, match=r"C has rank 1 < 2"):
        make_estimator(s, discretize(s, H), "classical")


def test_ideal_passes_the_truth_through_exactly(paper_system, model):
    truth, ests, _, _ = _run_open_loop(paper_system, model, "ideal", 200)
    np.testing.assert_array_equal(ests, truth)
    est = make_estimator(paper_system, model, "ideal")
    assert est.uses_truth and est.q0.size == 0


def test_only_ideal_uses_the_truth(paper_system, model):
    """Estimates of kalman and classical must not depend on the truth part of mvec."""
    rng = np.random.default_rng(0)
    for mode in ESTIMATOR_MODES:
        est = make_estimator(paper_system, model, mode)
        a = np.concatenate([np.ones(4), rng.standard_normal(model.ns)])
        b = np.concatenate([np.ones(4), rng.standard_normal(model.ns)])
        same = np.array_equal(est.estimate(a), est.estimate(b))
        assert same == (not est.uses_truth), mode
        assert est.uses_truth == (mode == "ideal")


def test_reset_restores_initial_state(paper_system, model):
    est = make_estimator(paper_system, model, "kalman")
    q0 = est.q.copy()
    e = est.estimate(np.ones(4 + model.ns))
    est.update(e, np.ones(2))
    assert not np.allclose(est.q, q0)
    est.reset()
    np.testing.assert_array_equal(est.q, q0)
    np.testing.assert_array_equal(q0, paper_system.initial_state())


@pytest.mark.parametrize("mode", ["Kalman", "lqe", "", "open_loop"])
def test_unknown_mode_is_named(paper_system, model, mode):
    with pytest.raises(ModelError) as exc:
        make_estimator(paper_system, model, mode)
    msg = str(exc.value)
    assert f"unknown estimator mode {mode!r}" in msg
    for known in ESTIMATOR_MODES:
        assert known in msg

"""The full-information bound of a fleet's cost (orchestrator.analysis.full_information)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm, solve_discrete_are, solve_discrete_lyapunov

from orchestrator.analysis.full_information import best_steady_motion, full_information_bound
from orchestrator.running.setup import Method
from orchestrator.running.systems import make_setup
from orchestrator.scenario import load_scenario
from plant_model.per_vehicle import sample_vehicle


@pytest.fixture(scope="module")
def f4():
    return load_scenario("formation-4").with_run(deployment="per-vehicle", T=300.0)


def _pieces(sc):
    v = sc.fleet.views[1]
    model = sample_vehicle(v, sc.h, 2)
    p = v.n
    return v, model, model.Ad[:p, :p], model.Bd[:p], expm(v.F * sc.h)


@pytest.mark.parametrize("name", ["formation-4", "formation-20"])   # lawnmower, circle
def test_the_steady_motion_is_a_motion_and_costs_what_it_says(name):
    sc = load_scenario(name)
    v, model, Ad, Bd, Phi = _pieces(sc)
    k0, K = 1000, 4000
    z = np.linalg.matrix_power(Phi, k0) @ v.z0
    zs = []
    for _ in range(k0, K):
        zs.append(z)
        z = Phi @ z
    zs = np.array(zs)
    Zbar = zs.T @ zs / len(zs)
    X, U, cost = best_steady_motion(Ad, Bd, v.C, v.H, v.Q, v.R, Phi, Zbar)
    assert np.abs(X @ Phi - Ad @ X - Bd @ U).max() < 1e-9 * (1 + np.abs(X).max())
    # simulate it: start on the motion, apply u = U z, noise-free
    x, J = X @ zs[0], 0.0
    for zk in zs:
        assert np.allclose(x, X @ zk, atol=1e-6 * (1 + np.abs(x).max()))
        u = U @ zk
        e = v.H @ zk - v.C @ x
        J += e @ v.Q @ e + u @ v.R @ u
        x = Ad @ x + Bd @ u
    assert J / len(zs) == pytest.approx(cost, rel=1e-6)
    # optimal among motions: any other feasible (X, U) costs more
    rng = np.random.default_rng(0)
    p, l_ = X.shape
    for _ in range(5):
        dU = rng.standard_normal(U.shape) * 0.1 * max(np.abs(U).max(), 1e-3)
        # X' solving X' Phi - Ad X' = Bd (U + dU) (the constraint) by vectorisation
        M = np.kron(Phi.T, np.eye(p)) - np.kron(np.eye(l_), Ad)
        Xn = np.linalg.lstsq(M, (Bd @ (U + dU)).reshape(-1, order="F"),
                             rcond=None)[0].reshape((p, l_), order="F")
        E = v.H - v.C @ Xn
        other = np.trace((E.T @ v.Q @ E + (U + dU).T @ v.R @ (U + dU)) @ Zbar)
        assert other > cost


def test_the_noise_part_is_the_discrete_lq_optimum(f4):
    """tr(P Qd) equals the Lyapunov cost of the DARE gain, and a sampled continuous-time LQ
    gain costs more."""
    v, model, *_ = _pieces(f4)
    p = v.n
    Qs = np.zeros((model.ns, model.ns))
    Qs[:p, :p] = v.C.T @ v.Q @ v.C
    P = solve_discrete_are(model.Ad, model.Bd, Qs, v.R)
    Kd = np.linalg.solve(v.R + model.Bd.T @ P @ model.Bd, model.Bd.T @ P @ model.Ad)

    def cost(K):
        Acl = model.Ad - model.Bd @ K
        S = solve_discrete_lyapunov(Acl, model.Qd)
        return np.trace(Qs @ S) + np.trace(K.T @ v.R @ K @ S)
    assert cost(Kd) == pytest.approx(np.trace(P @ model.Qd), rel=1e-8)
    from controller_fmu.design import lq_riccati_gain
    _, Kx, _, _ = lq_riccati_gain(v.A, v.B1, v.C, v.Q, v.R)
    Kc = np.hstack([Kx, np.zeros((Kx.shape[0], v.r))])
    assert cost(Kc) > cost(Kd)


def test_the_bound_is_below_both_architectures(f4, tmp_path):
    pv = make_setup(f4, tmp_path)
    k0 = pv.predictions(Method("ideal", "ideal", f4.tracking, "centralized")).k0
    bound = full_information_bound(f4, (k0, f4.steps))
    assert len(bound.per_vehicle) == 4
    assert bound.cost_rate == pytest.approx(bound.noise + bound.mean)
    for arch in ("centralized", "distributed"):
        for mode in ("ideal", "kalman"):
            p = pv.predictions(Method(mode, mode, f4.tracking, arch))
            pred, k = p.window, p.k0
            assert k == k0
            assert bound.cost_rate < pred.cost_rate, (arch, mode)

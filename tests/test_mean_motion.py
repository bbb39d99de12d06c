"""orchestrator.analysis.mean_motion: the window sums of e e' and u u' along the mean motion
X_{k+1} = Phi X_k against the plain per-step loop, on random loops driven by a marginally
stable exosystem (a Jordan block at 1 as a leader at constant velocity, a rotation as a
periodic path, the constant 1) and on formation-4's distributed loop."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from orchestrator.analysis.mean_motion import steady_map, window_mean_sums
from orchestrator.analysis.per_vehicle import distributed_initial_state, distributed_loop_of
from orchestrator.scenario.loader import load_scenario


def _reference(Phi, X, k0, K, E, G):
    """The sums step by step: ee = sum_{k0 <= k < K} e_k e_k', e_k = E Phi^k X."""
    ee = np.zeros((E.shape[0], E.shape[0]))
    uu = np.zeros((G.shape[0], G.shape[0]))
    for k in range(K):
        if k >= k0:
            e, u = E @ X, G @ X
            ee += np.outer(e, e)
            uu += np.outer(u, u)
        X = Phi @ X
    return ee, uu


def _extended_reference(Phi, X, k0, K, E, G):
    """:func:`_reference` in extended precision, Phi applied by its nonzeros."""
    P = sp.csr_matrix(Phi)
    assert np.all(np.diff(P.indptr) > 0)
    data, ext = P.data.astype(np.longdouble), np.longdouble
    X, E, G = X.astype(ext), E.astype(ext), G.astype(ext)
    ee = np.zeros((E.shape[0], E.shape[0]), dtype=ext)
    uu = np.zeros((G.shape[0], G.shape[0]), dtype=ext)
    for k in range(K):
        if k >= k0:
            e, u = E @ X, G @ X
            ee += np.outer(e, e)
            uu += np.outer(u, u)
        X = np.add.reduceat(data * X[P.indices], P.indptr[:-1])
    return ee.astype(float), uu.astype(float)


def _assert_close(new, ref, rtol=1e-9):
    """|new - ref| <= rtol sqrt(ref_ii ref_jj), and a floor of 1e-12 of the largest for
    components that are the rounding of a cancellation (e of nanometres beside positions of
    a kilometre)."""
    d = np.diag(ref)
    bound = rtol * np.sqrt(np.outer(d, d)) + 1e-12 * d.max()
    assert np.all(np.abs(new - ref) <= bound), np.max(np.abs(new - ref) / bound)


def _exosystem(h=0.05, w=0.3):
    """v = [position, velocity, rotation (2), 1]: eigenvalues on the unit circle, a Jordan
    chain of length 2 at 1."""
    c, s = np.cos(w * h), np.sin(w * h)
    return np.array([[1, h, 0, 0, 0], [0, 1, 0, 0, 0], [0, 0, c, -s, 0], [0, 0, s, c, 0],
                     [0, 0, 0, 0, 1.0]])


def _random_loop(seed, n=12, rho=0.9):
    """(Phi, X0, E, G, mask): a stable error part of n states (spectral radius ``rho``)
    driven by the exosystem, the states shuffled so that the mask is not a leading block."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    A *= rho / np.max(np.abs(np.linalg.eigvals(A)))
    S = _exosystem()
    m = S.shape[0]
    Phi = np.block([[A, rng.standard_normal((n, m))], [np.zeros((m, n)), S]])
    det = np.r_[np.zeros(n, bool), np.ones(m, bool)]
    X = np.r_[rng.standard_normal(n) * 10, [3.0, 0.7, 2.0, 0.0, 1.0]]
    E = rng.standard_normal((3, n + m))
    G = rng.standard_normal((2, n + m))
    perm = rng.permutation(n + m)
    return Phi[np.ix_(perm, perm)], X[perm], E[:, perm], G[:, perm], det[perm]


@pytest.mark.parametrize("sparse", [False, True])
@pytest.mark.parametrize("k0,K", [(0, 1), (0, 800), (5, 6), (37, 1000), (700, 1500),
                                  (0, 1003), (1234, 1237), (250, 250)])
def test_random_loops_with_an_exosystem_against_the_loop(sparse, k0, K):
    Phi, X, E, G, det = _random_loop(1)
    P = sp.csr_matrix(Phi) if sparse else Phi
    ee, uu = window_mean_sums(P, X, k0, K, E, G, 64, det)
    ref_ee, ref_uu = _reference(Phi, X, k0, K, E, G)
    if K <= k0:
        assert not ee.any() and not uu.any()
        return
    _assert_close(ee, ref_ee)
    _assert_close(uu, ref_uu)
    assert np.array_equal(ee, ee.T)


@pytest.mark.parametrize("seed", [2, 3, 4])
@pytest.mark.parametrize("block", [1, 7, 100, 5000])
def test_block_sizes_and_seeds(seed, block):
    Phi, X, E, G, det = _random_loop(seed, rho=0.95)
    ee, uu = window_mean_sums(Phi, X, 111, 2345, E, G, block, det)
    ref_ee, ref_uu = _reference(Phi, X, 111, 2345, E, G)
    _assert_close(ee, ref_ee)
    _assert_close(uu, ref_uu)


def test_stable_loop_without_a_mask_and_marginal_loop_without_one():
    Phi, X, E, G, det = _random_loop(5)
    R = ~det
    for P, x, e, g in ((Phi[np.ix_(R, R)], X[R], E[:, R], G[:, R]), (Phi, X, E, G)):
        ee, uu = window_mean_sums(P, x, 20, 900, e, g, 50)     # no exosystem named
        ref_ee, ref_uu = _reference(P, x, 20, 900, e, g)
        _assert_close(ee, ref_ee)
        _assert_close(uu, ref_uu)


def test_a_mask_that_is_not_autonomous_falls_back_to_the_loop():
    Phi, X, E, G, det = _random_loop(6)
    Phi = Phi.copy()
    Phi[np.flatnonzero(det)[0], np.flatnonzero(~det)[0]] = 1e-3   # v hears x
    ee, uu = window_mean_sums(Phi, X, 3, 400, E, G, 32, det)
    ref_ee, ref_uu = _reference(Phi, X, 3, 400, E, G)
    _assert_close(ee, ref_ee)
    _assert_close(uu, ref_uu)


def test_steady_map_solves_the_sylvester_equation():
    Phi, _, _, _, det = _random_loop(7)
    R, V = ~det, det
    A, B, S = Phi[np.ix_(R, R)], Phi[np.ix_(R, V)], Phi[np.ix_(V, V)]
    Pi = steady_map(sp.csr_matrix(A), B, S)
    assert np.abs(Pi @ S - A @ Pi - B).max() < 1e-12 * np.abs(B).max()
    assert steady_map(np.eye(2), np.ones((2, 1)), np.eye(1)) is None     # shared eigenvalue 1


def test_a_long_window_takes_the_closed_form():
    """x_{k+1} = x_k / 2 + v / 2, v = 1, x_0 = 0: x_k = 1 - 2^-k, so over 0 <= k < K
    sum x_k^2 = K - 4 (1 - 2^-K) + (4/3) (1 - 4^-K): 10^8 samples, far beyond a step loop."""
    Phi = np.array([[0.5, 0.5], [0.0, 1.0]])
    K = 10 ** 8
    ee, uu = window_mean_sums(Phi, np.array([0.0, 1.0]), 0, K, np.array([[1.0, 0.0]]),
                              np.array([[0.0, 2.0]]), 10 ** 4, np.array([False, True]))
    assert ee[0, 0] == pytest.approx(K - 4 + 4 / 3, rel=1e-13)
    assert uu[0, 0] == 4.0 * K


@pytest.fixture(scope="module")
def formation4_fast():
    """formation-4's distributed loop at h = 0.5 s: its slowest error mode (30 s) takes
    60 samples, so a window of a few thousand covers the transient and the steady pattern."""
    sc = load_scenario("formation-4").with_run(h=0.5)
    loop = distributed_loop_of(sc, "kalman", "regulator", sc.distributed)
    return loop, distributed_initial_state(sc, loop)


@pytest.mark.skipif(np.finfo(np.longdouble).eps > 1e-18, reason="no extended precision")
@pytest.mark.parametrize("k0,K", [(0, 1), (0, 3000), (700, 4001), (3999, 4000)])
def test_formation4_loop_against_the_loop(formation4_fast, k0, K):
    """Against the loop in extended precision: in double precision its own rounding is
    about 1e-8 of e late in the window (e ~ 1e-3 m beside positions of a kilometre)."""
    loop, X0 = formation4_fast
    ee, uu = window_mean_sums(sp.csr_matrix(loop.Phi), X0, k0, K, loop.Ce, loop.Gx, 1000,
                              np.asarray(loop.deterministic))
    ref_ee, ref_uu = _extended_reference(loop.Phi, X0, k0, K, loop.Ce, loop.Gx)
    _assert_close(ee, ref_ee)
    _assert_close(uu, ref_uu)

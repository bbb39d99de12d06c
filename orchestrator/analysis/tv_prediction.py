"""Predictions of the loop with the time-varying Kalman filter (``kalman-tv``).

The gain L_k of sample k follows the Riccati difference equation from P0
(:mod:`estimator_fmu.kalman_tv`), so the sampled closed loop of
:func:`orchestrator.analysis.prediction.closed_loop` is time-varying:

    X[k+1] = Phi_k X[k] + Gam_k eta[k],   u[k] = Gx_k X[k] + Geta_k eta[k],   e[k] = E s[k]

(Phi_k, Gam_k, Gx_k, Geta_k the loop of the current-estimator filter with gain L_k). Its
mean and covariance from the known start X(0) (covariance Sigma_0, 0 for the project's
runs) follow

    m[k+1]     = Phi_k m[k]
    Sigma[k+1] = Phi_k Sigma[k] Phi_k' + Gam_k W Gam_k'           (time-varying Lyapunov)

and the expected statistics over the window k0 <= k < K (L = K - k0 samples) are

    E[e e']  = (1/L) sum_k E (Sigma[k] + m m') E'
    E[u u']  = (1/L) sum_k Gx_k (Sigma[k] + m m') Gx_k' + Geta_k W Geta_k'
    J/T      = tr(Q E[e e']) + tr(R E[u u'])

Once the gain has converged (relative change of P_k below ``TOL`` at sample kc) the loop is
the steady filter's (Phi, Gam, Gx, Geta) and the rest of the covariance is summed in closed
form: Sigma[k] = Sigma_ss + Phi^j D Phi'^j (j = k - kc, D = Sigma[kc] - Sigma_ss, on the
noise-driven states), sum_{j=a}^{b-1} Phi^j D Phi'^j = Phi^a Z Phi'^a - Phi^b Z Phi'^b with
Z = Phi Z Phi' + D. The planned-path states are deterministic (no covariance) and enter
through the mean. After convergence the prediction is the steady filter's: the stationary
prediction of a ``kalman-tv`` run is the steady ``kalman`` loop's.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.linalg import block_diag, solve_discrete_lyapunov

from estimator_fmu.estimators import LinearEstimator, kalman_estimator
from estimator_fmu.kalman_tv import TimeVaryingKalman, riccati_step
from plant_model.discretization import DiscreteModel
from plant_model.system import LinearSystem

from .prediction import MARGINAL, Prediction, closed_loop, deterministic_states, predict_stationary

if TYPE_CHECKING:
    from ..scenario import Scenario

__all__ = ["TOL", "tv_gain_estimator", "tv_method_predictions", "tv_window_moments"]

#: the gain has converged when the prior covariance changes by less than this, relative
TOL = 1e-13


def tv_gain_estimator(est: TimeVaryingKalman, L: np.ndarray, nmvec: int) -> LinearEstimator:
    """The filter of sample k as a linear estimator with gain L = L_k (est = q + L (meas -
    Mm q), q+ = Ad est + Bd u; meas the first rows of mvec, of length ``nmvec``): what
    :func:`closed_loop` takes."""
    ns = L.shape[0]
    nm = est.Mm.shape[0]
    Dm = np.zeros((ns, nmvec))
    Dm[:, :nm] = L
    return LinearEstimator("tv", np.eye(ns) - L @ est.Mm, Dm, est.Ad, est.Bd, est.q0,
                           uses_truth=False)


def tv_window_moments(system: LinearSystem, model: DiscreteModel, est: TimeVaryingKalman,
                      Ks: np.ndarray, window: tuple[int, int],
                      Sigma0: np.ndarray | None = None, X0: np.ndarray | None = None,
                      tol: float = TOL) -> dict[str, Any]:
    """Window sums of the time-varying loop (module docstring).

    Parameters
    ----------
    system, model : LinearSystem, DiscreteModel
        The stacked model and its sampling (mvec = [y; ybar; x; w; z]).
    est : TimeVaryingKalman
        The filter (its Ad, Bd, Qd, Rd, Mm, P0, q0).
    Ks : np.ndarray
        The law, u = -Ks est.
    window : tuple[int, int]
        (k0, K): samples k0 <= k < K.
    Sigma0 : np.ndarray or None
        Covariance of X(0) = [s(0); q(0)] (None: 0, the known start).
    X0 : np.ndarray or None
        Mean of X(0) (None: [s(0); q0]).
    tol : float
        Convergence of P_k (relative); 0 runs the recursion over the whole window.

    Returns
    -------
    dict
        ``ee``, ``uu`` (window averages of e e' and u u'), ``ee_mean`` (of the mean's part),
        ``kc`` (first sample of the steady gain, or K), ``rho`` (spectral radius of the
        steady loop's noise-driven part), ``Phi`` (the steady loop).
    """
    k0, K = window
    L_n = max(K - k0, 1)
    ns = model.ns
    W = block_diag(model.Qd, model.Rd)
    D = deterministic_states(system, model, est)
    R = ~D
    nX = ns + est.q0.size
    X = np.concatenate([system.initial_state(), est.q0]) if X0 is None else np.array(X0, float)
    S = np.zeros((nX, nX)) if Sigma0 is None else np.array(Sigma0, float)
    Eb = np.zeros((model.E.shape[0], nX))
    Eb[:, :ns] = model.E
    ee = np.zeros((Eb.shape[0], Eb.shape[0]))
    uu = np.zeros((Ks.shape[0], Ks.shape[0]))
    ee_mean = np.zeros_like(ee)
    P = est.P0.copy()
    k = 0
    while k < K:
        L, _, Pn = riccati_step(P, est.Ad, est.Mm, est.Qd, est.Rd)
        Phi, Gam, Gx, Geta = closed_loop(model, tv_gain_estimator(est, L, 2 * model.p + ns), Ks)
        if tol > 0 and np.abs(Pn - P).max() <= tol * max(np.abs(P).max(), 1e-300):
            break                       # L_k is the steady gain from here on
        if k >= k0:
            e, u = Eb @ X, Gx @ X
            ee += Eb @ S @ Eb.T + np.outer(e, e)
            ee_mean += np.outer(e, e)
            uu += Gx @ S @ Gx.T + Geta @ W @ Geta.T + np.outer(u, u)
        X = Phi @ X
        S = Phi @ S @ Phi.T + Gam @ W @ Gam.T
        S = 0.5 * (S + S.T)
        P = Pn
        k += 1
    kc = k
    PhiR = Phi[np.ix_(R, R)]
    rho = float(np.max(np.abs(np.linalg.eigvals(PhiR)))) if PhiR.size else 0.0
    if kc < K:                          # the steady loop from kc on
        if rho >= MARGINAL:
            return {"ee": None, "uu": None, "ee_mean": None, "kc": kc, "rho": rho, "Phi": Phi}
        a, b = max(k0, kc) - kc, K - kc
        GR = Gam[R]
        Sss = np.zeros_like(S)
        Sss[np.ix_(R, R)] = solve_discrete_lyapunov(PhiR, GR @ W @ GR.T)
        Z = np.zeros_like(S)
        Z[np.ix_(R, R)] = solve_discrete_lyapunov(PhiR, (S - Sss)[np.ix_(R, R)])
        Pa = np.linalg.matrix_power(Phi, a)
        Pb = np.linalg.matrix_power(Phi, b)
        Ssum = (b - a) * Sss + Pa @ Z @ Pa.T - Pb @ Z @ Pb.T
        ee += Eb @ Ssum @ Eb.T
        uu += Gx @ Ssum @ Gx.T + (b - a) * (Geta @ W @ Geta.T)
        # the mean, a block of samples at a time
        k = kc
        rows = np.empty((min(1024, max(K - kc, 1)), nX))
        while k < K:
            nb = min(rows.shape[0], K - k)
            for j in range(nb):
                rows[j] = X
                X = Phi @ X
            first = max(k0 - k, 0)
            if first < nb:
                e, u = rows[first:nb] @ Eb.T, rows[first:nb] @ Gx.T
                ee += e.T @ e
                ee_mean += e.T @ e
                uu += u.T @ u
            k += nb
    return {"ee": ee / L_n, "uu": uu / L_n, "ee_mean": ee_mean / L_n, "kc": kc, "rho": rho,
            "Phi": Phi}


def _prediction(system: LinearSystem, m: dict[str, Any], stat: Prediction) -> Prediction:
    if m["ee"] is None:
        return Prediction(None, None, None, m["rho"], float("inf"),
                          reason=f"the steady loop of the time-varying filter is not "
                                 f"stationary: spectral radius {m['rho']:.6g} >= 1")
    cost = float(np.trace(system.Q @ m["ee"]) + np.trace(system.R @ m["uu"]))
    return Prediction(rms_e=np.sqrt(np.clip(np.diag(m["ee"]), 0, None)).tolist(),
                      rms_u=np.sqrt(np.clip(np.diag(m["uu"]), 0, None)).tolist(),
                      cost_rate=cost, spectral_radius=stat.spectral_radius,
                      settling_time=stat.settling_time,
                      rms_e_mean=np.sqrt(np.clip(np.diag(m["ee_mean"]), 0, None)).tolist())


def tv_method_predictions(sc: Scenario, model: DiscreteModel, est: TimeVaryingKalman,
                          Ks: np.ndarray, k0: int | None = None
                          ) -> tuple[Prediction, Prediction, Prediction | None, int]:
    """The predictions a run's summary gives for ``kalman-tv`` (the registry's form:
    stationary, window, window from the start, k0).

    The stationary prediction is the steady filter's loop (the limit of the gains); the
    window's and the window's from the start are both the time-varying second moment from
    the known start (:func:`tv_window_moments`), the expected statistics of the run.
    """
    from .summary import stats_window
    stat = predict_stationary(sc.system, model, kalman_estimator(sc.system, model), Ks)
    if k0 is None:
        k0 = stats_window(sc.T, sc.h, stat.settling_time)
    if stat.cost_rate is None:
        return stat, stat, None, k0
    win = _prediction(sc.system, tv_window_moments(sc.system, model, est, Ks, (k0, sc.steps)),
                      stat)
    return stat, win, win, k0

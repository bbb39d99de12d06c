"""Exact stationary performance of the sampled closed loop, from a Lyapunov equation.

Closed-loop state X = [s; q] (plant state s = [x; w; z], estimator state q), noise per
step eta = [v; n; n_z] with covariance W = blkdiag(Qd, Rd), independent of X[k]:

    mvec = Ms s + J eta,  est = Ce q + Dm mvec,  u = -Ks est
    s'   = Ad s + Bd u + [I 0] eta,   q' = Aq est + Bu u
    =>  X[k+1] = Phi X[k] + Gam eta[k],   u[k] = Gx X[k] + Geta eta[k],   e[k] = E s[k]

Stationary covariance: Sigma = Phi Sigma Phi' + Gam W Gam' (scipy's
``solve_discrete_lyapunov``), so E[e e'] = E Sigma_ss E', E[u u'] = Gx Sigma Gx' +
Geta W Geta', and the cost rate J/T = tr(Q E[e e']) + tr(R E[u u']) at the sample instants.

A planned leader path (reference states without noise, known to the estimator) never
settles: its states and their exact estimates are deterministic and are left out of the
Lyapunov equation (their deviation from the mean is zero). Their effect is the mean
motion X_mean[k] = Phi^k X(0); with a statistics window [k0, K) the prediction adds the
window average of e_mean' Q e_mean + u_mean' R u_mean, and E[e e'] = Cov + mean mean'
(:func:`orchestrator.analysis.mean_motion.window_mean_sums`: the transient, then the
exosystem's steady pattern in closed form).

Over a finite window, transient included (``transient=True``): the run starts from a known
state, so Sigma_0 = 0 and Sigma_k = Sigma - Phi^k Sigma Phi'^k. Its average over samples
k0..K-1 (L = K - k0 of them) is Sigma - Phi^k0 (Y - Phi^L Y Phi'^L) Phi'^k0 / L with
Y = Phi Y Phi' + Sigma (a second Lyapunov equation): the expected value of the statistics
a run of that length computes, which short runs can be compared with.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.linalg import block_diag, solve_discrete_lyapunov

from estimator_fmu.estimators import LinearEstimator
from plant_model.discretization import DiscreteModel
from plant_model.system import LinearSystem

from .mean_motion import window_mean_sums

if TYPE_CHECKING:
    from ..scenario import Scenario

__all__ = ["Prediction", "closed_loop", "deterministic_states", "method_predictions",
           "predict_stationary", "window_average_covariance", "window_mean_sums"]


#: a spectral radius at or above this is not stationary: an eigenvalue on the unit circle
#: (a circling reference) comes out of the eigenvalue solver within rounding of 1, on either
#: side depending on the BLAS kernels (time constant over 1e9 steps)
MARGINAL = 1.0 - 1e-9


@dataclass(frozen=True)
class Prediction:
    """Stationary RMS of e and u and the cost rate; ``None`` values when not stationary."""

    rms_e: list[float] | None
    rms_u: list[float] | None
    cost_rate: float | None
    spectral_radius: float | None  #: None: not predicted (--predict none)
    settling_time: float          #: 5 time constants of the slowest closed-loop mode (s)
    reason: str | None = None     #: why there is no stationary prediction
    #: with a window: RMS over the window of the noise-free error (the steady-state error
    #: the law leaves on a persistent reference), per component
    rms_e_mean: list[float] | None = None


def closed_loop(model: DiscreteModel, est: LinearEstimator,
                Ks: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(Phi, Gam, Gx, Geta) of the sampled closed loop described in the module docstring.

    X[k+1] = Phi X[k] + Gam eta[k],  u[k] = Gx X[k] + Geta eta[k],  X = [s; q],
    eta = [v; n; n_z].

    Parameters
    ----------
    model : DiscreteModel
        The plant sampled at the communication step h.
    est : LinearEstimator
        The estimator (its Ce, Dm, Aq, Bu, q0).
    Ks : np.ndarray
        Control gain, u = -Ks est, m x (n + r + l).

    Returns
    -------
    Phi : np.ndarray
        Closed-loop transition, (ns + nq) x (ns + nq).
    Gam : np.ndarray
        Noise input, (ns + nq) x (ns + 2 p).
    Gx : np.ndarray
        Control from the state, m x (ns + nq).
    Geta : np.ndarray
        Control from the noise of the same sample, m x (ns + 2 p).
    """
    ns, p = model.ns, model.p
    nq = est.q0.shape[0]
    nm = 2 * p + ns
    Ms = np.vstack([model.M, np.eye(ns)])
    neta = ns + 2 * p
    J = np.zeros((nm, neta))
    J[:2 * p, ns:] = np.eye(2 * p)
    Es, Eq, Eeta = est.Dm @ Ms, est.Ce, est.Dm @ J          # est = Es s + Eq q + Eeta eta
    Gs, Gq, Geta = -Ks @ Es, -Ks @ Eq, -Ks @ Eeta           # u = Gs s + Gq q + Geta eta
    Phi = np.zeros((ns + nq, ns + nq))
    Phi[:ns, :ns] = model.Ad + model.Bd @ Gs
    Phi[:ns, ns:] = model.Bd @ Gq
    Phi[ns:, :ns] = est.Aq @ Es + est.Bu @ Gs
    Phi[ns:, ns:] = est.Aq @ Eq + est.Bu @ Gq
    Gam = np.zeros((ns + nq, neta))
    Gam[:ns, :ns] = np.eye(ns)
    Gam[:ns] += model.Bd @ Geta
    Gam[ns:] = est.Aq @ Eeta + est.Bu @ Geta
    Gx = np.hstack([Gs, Gq])
    return Phi, Gam, Gx, Geta


def deterministic_states(system: LinearSystem, model: DiscreteModel,
                         est: LinearEstimator) -> np.ndarray:
    """Mask over the closed-loop state [s; q] of the deterministic states.

    The planned-path reference states (:meth:`LinearSystem.known_reference_mask`) and,
    for the Kalman estimator (whose q is a copy of s), their exact estimates.

    Parameters
    ----------
    system : LinearSystem
        The model.
    model : DiscreteModel
        The plant sampled at h.
    est : LinearEstimator
        The estimator.

    Returns
    -------
    np.ndarray
        Boolean mask of length ns + nq.
    """
    ns = model.ns
    known = np.zeros(ns, dtype=bool)
    known[system.n + system.r:] = system.known_reference_mask()
    nq = est.q0.shape[0]
    q_known = known.copy() if nq == ns else np.zeros(nq, dtype=bool)
    return np.concatenate([known, q_known])


def window_average_covariance(Phi: np.ndarray, Sigma: np.ndarray, k0: int,
                              K: int) -> np.ndarray:
    """Average of Sigma_k over k = k0..K-1 for Sigma_{k+1} = Phi Sigma_k Phi' + G, Sigma_0 = 0,
    where Sigma = Phi Sigma Phi' + G is the stationary covariance (Phi stable).

    Sigma_k = Sigma - Phi^k Sigma Phi'^k, so the average is
    Sigma - Phi^k0 (Y - Phi^L Y Phi'^L) Phi'^k0 / L, L = K - k0, Y = Phi Y Phi' + Sigma.

    Parameters
    ----------
    Phi : np.ndarray
        Stable transition matrix, n x n.
    Sigma : np.ndarray
        Its stationary covariance, n x n.
    k0, K : int
        The window: samples k0 <= k < K.

    Returns
    -------
    np.ndarray
        The window average, n x n.
    """
    L = max(K - k0, 1)
    if Phi.size == 0:
        return Sigma.copy()
    Y = solve_discrete_lyapunov(Phi, Sigma)
    PL = np.linalg.matrix_power(Phi, L)
    Pk0 = np.linalg.matrix_power(Phi, k0)
    S = Pk0 @ (Y - PL @ Y @ PL.T) @ Pk0.T
    avg = Sigma - S / L
    return (avg + avg.T) / 2


def predict_stationary(system: LinearSystem, model: DiscreteModel, est: LinearEstimator,
                       Ks: np.ndarray, window: tuple[int, int] | None = None,
                       x0: np.ndarray | None = None, *,
                       transient: bool = False) -> Prediction:
    """RMS of each e and u component and the cost rate of the closed loop.

    Without ``window``: the stationary (noise-driven) part only. With ``window`` = (k0, K)
    the mean motion from the initial state over samples k0..K-1 is added (needed when the
    reference is a planned path that never settles). Cost rate J/T = tr(Q E[e e']) +
    tr(R E[u u']) (module docstring).

    Parameters
    ----------
    system : LinearSystem
        The model (its cost weights Q, R and initial state).
    model : DiscreteModel
        The plant sampled at the communication step h, s.
    est : LinearEstimator
        The estimator.
    Ks : np.ndarray
        Control gain, u = -Ks est.
    window : tuple[int, int] or None, optional
        Statistics window (k0, K) in samples; None: the stationary part only.
    x0 : np.ndarray or None, optional
        Initial closed-loop state [s; q] for the mean motion; default [s(0); q0].
    transient : bool, optional
        With ``window``: the covariance averaged over the window from Sigma_0 = 0 (the
        expected statistics of a run of that length) instead of the stationary one.

    Returns
    -------
    Prediction
        RMS of e and u, the cost rate, the spectral radius of the loop and the settling
        time (5 time constants of the slowest mode, s); None values and ``reason`` when
        the loop is not stationary.
    """
    Phi, Gam, Gx, Geta = closed_loop(model, est, Ks)
    D = deterministic_states(system, model, est)
    R = ~D
    PhiR = Phi[np.ix_(R, R)]
    # settling: every mode when all decay; else the noise-driven modes (a planned path
    # never settles, its mean motion is accounted for through ``window``)
    rho = float(np.max(np.abs(np.linalg.eigvals(Phi)))) if Phi.size else 0.0
    if rho >= MARGINAL:
        rho = float(np.max(np.abs(np.linalg.eigvals(PhiR)))) if PhiR.size else 0.0
    if rho >= MARGINAL:
        return Prediction(None, None, None, rho, float("inf"),
                          reason=f"the closed loop (with its exosystems) is not stationary: "
                                 f"spectral radius {rho:.6g} >= 1")
    tau = -model.h / np.log(rho) if rho > 0 else model.h
    W = block_diag(model.Qd, model.Rd)
    Sigma = np.zeros_like(Phi)
    GR = Gam[R]
    Sigma[np.ix_(R, R)] = solve_discrete_lyapunov(PhiR, GR @ W @ GR.T)
    if transient and window is not None:
        Sigma[np.ix_(R, R)] = window_average_covariance(PhiR, Sigma[np.ix_(R, R)], *window)
    ns = model.ns
    See = model.E @ Sigma[:ns, :ns] @ model.E.T
    Suu = Gx @ Sigma @ Gx.T + Geta @ W @ Geta.T
    if window is not None:
        k0, K = window
        X = np.concatenate([system.initial_state(), est.q0]) if x0 is None else x0.copy()
        Eb = np.zeros((model.E.shape[0], Phi.shape[0]))
        Eb[:, :ns] = model.E
        ee, uu = window_mean_sums(Phi, X, k0, K, Eb, Gx, 1024, D)
        See = See + ee / max(K - k0, 1)
        Suu = Suu + uu / max(K - k0, 1)
        rms_e_mean = np.sqrt(np.diag(ee) / max(K - k0, 1)).tolist()
    else:
        rms_e_mean = None
    cost = float(np.trace(system.Q @ See) + np.trace(system.R @ Suu))
    return Prediction(
        rms_e=np.sqrt(np.clip(np.diag(See), 0, None)).tolist(),
        rms_u=np.sqrt(np.clip(np.diag(Suu), 0, None)).tolist(),
        cost_rate=cost, spectral_radius=rho, settling_time=float(5 * tau),
        rms_e_mean=rms_e_mean,
    )


def method_predictions(sc: Scenario, model: DiscreteModel, est: LinearEstimator, Ks: np.ndarray,
                       k0: int | None = None
                       ) -> tuple[Prediction, Prediction, Prediction | None, int]:
    """The predictions a run's summary gives for one method of the stacked law.

    (stationary, over the statistics window with the mean motion (fleets; the stationary
    one otherwise), the window average from the known start, k0), k0 the first sample of
    the window (:func:`orchestrator.analysis.summary.stats_window`). Without a stationary
    prediction the last two are the stationary one and None.

    Parameters
    ----------
    sc : Scenario
        The scenario (system, T, h, steps, fleet).
    model : DiscreteModel
        Its sampled model.
    est : LinearEstimator
        The estimator.
    Ks : np.ndarray
        The law's gain, u = -Ks [x; w; z].
    k0 : int or None, optional
        First sample of the window (a compare's common window); None: this method's own
        (:func:`orchestrator.analysis.summary.stats_window` of its settling time).

    Returns
    -------
    tuple[Prediction, Prediction, Prediction | None, int]
        As above.
    """
    from .summary import stats_window
    pred0 = predict_stationary(sc.system, model, est, Ks)
    if k0 is None:
        k0 = stats_window(sc.T, sc.h, pred0.settling_time)
    if pred0.cost_rate is None:
        return pred0, pred0, None, k0
    win = (k0, sc.steps)
    pred = (pred0 if sc.fleet is None
            else predict_stationary(sc.system, model, est, Ks, window=win))
    return (pred0, pred,
            predict_stationary(sc.system, model, est, Ks, window=win, transient=True), k0)

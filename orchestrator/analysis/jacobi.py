"""Stationary prediction of the loop as libcosim runs it (``coupling="jacobi"``).

libcosim's fixed-step algorithm (and our master's ``coupling="jacobi"``) feeds every
connection from the previous communication point, which delays the measurement-to-control
path by two steps; :func:`predict_stationary_jacobi` predicts the cost of that delayed
loop from the discrete Lyapunov equation, as :mod:`.prediction` does for the exact loop.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from estimator_fmu.estimators import LinearEstimator
    from plant_model.discretization import DiscreteModel
    from plant_model.system import LinearSystem

__all__ = ["jacobi_closed_loop", "predict_stationary_jacobi"]


def jacobi_closed_loop(model: DiscreteModel, est: LinearEstimator,
                       Ks: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(Phi, Gam, Gx, Geta) of the loop as libcosim (``coupling="jacobi"``) runs it.

    State X[k] = [s; q; EST; U] at communication point t_k: plant state s, estimator
    state q, the estimate EST the estimator outputs at t_k (computed after its step from
    q[k] and the measurement it still holds, mvec[k-1]) and the control U that the
    controller outputs at t_k (from the estimate it held, EST[k-1]). With
    mvec[k] = Ms s[k] + J eta[k] (the same Ms, J as
    orchestrator.analysis.prediction.closed_loop):

        s[k+1]   = Ad s + Bd U + [I 0] eta
        q[k+1]   = Aq (Ce q + Dm mvec[k]) + Bu U
        EST[k+1] = Ce q[k+1] + Dm mvec[k]
        U[k+1]   = -Ks EST[k]

    u[k] = U[k] is the control the plant holds over step k; e[k] = E s[k]. Parameters as
    :func:`orchestrator.analysis.prediction.closed_loop`.

    Returns
    -------
    Phi : np.ndarray
        X[k+1] = Phi X[k] + Gam eta[k], X of length ns + nq + (n + r + l) + m.
    Gam : np.ndarray
        Noise input matrix, columns eta = [v; n; n_z] (ns + 2 p).
    Gx : np.ndarray
        u[k] = Gx X[k] + Geta eta[k], m rows.
    Geta : np.ndarray
        Zero: u[k] = U[k] has no direct noise term.
    """
    ns, p = model.ns, model.p
    nq = est.q0.shape[0]
    ne = est.Ce.shape[0]
    m = Ks.shape[0]
    nm = 2 * p + ns
    neta = ns + 2 * p
    Ms = np.vstack([model.M, np.eye(ns)])
    J = np.zeros((nm, neta))
    J[:2 * p, ns:] = np.eye(2 * p)
    iS, iQ, iE, iU = (np.arange(a, b) for a, b in
                      ((0, ns), (ns, ns + nq), (ns + nq, ns + nq + ne),
                       (ns + nq + ne, ns + nq + ne + m)))
    nX = ns + nq + ne + m
    Phi = np.zeros((nX, nX))
    Gam = np.zeros((nX, neta))
    Phi[np.ix_(iS, iS)] = model.Ad
    Phi[np.ix_(iS, iU)] = model.Bd
    Gam[iS, :ns] = np.eye(ns)
    # q[k+1] = Aq Dm Ms s + Aq Ce q + Bu U + Aq Dm J eta
    Phi[np.ix_(iQ, iS)] = est.Aq @ est.Dm @ Ms
    Phi[np.ix_(iQ, iQ)] = est.Aq @ est.Ce
    Phi[np.ix_(iQ, iU)] = est.Bu
    Gam[iQ] = est.Aq @ est.Dm @ J
    # EST[k+1] = Ce q[k+1] + Dm Ms s + Dm J eta
    Phi[np.ix_(iE, iS)] = est.Ce @ Phi[np.ix_(iQ, iS)] + est.Dm @ Ms
    Phi[np.ix_(iE, iQ)] = est.Ce @ Phi[np.ix_(iQ, iQ)]
    Phi[np.ix_(iE, iU)] = est.Ce @ est.Bu
    Gam[iE] = est.Ce @ Gam[iQ] + est.Dm @ J
    # U[k+1] = -Ks EST[k]
    Phi[np.ix_(iU, iE)] = -Ks
    Gx = np.zeros((m, nX))
    Gx[:, iU] = np.eye(m)
    Geta = np.zeros((m, neta))
    return Phi, Gam, Gx, Geta


def predict_stationary_jacobi(system: LinearSystem, model: DiscreteModel,
                              est: LinearEstimator, Ks: np.ndarray) -> dict[str, Any]:
    """Stationary RMS of e and u and the cost rate of the Jacobi-coupled loop.

    From the loop of :func:`jacobi_closed_loop` and Sigma = Phi Sigma Phi' + Gam W Gam',
    W = blkdiag(Qd, Rd): E[e e'] = E Sigma_ss E', E[u u'] = Gx Sigma Gx' + Geta W Geta',
    cost rate tr(Q E[e e']) + tr(R E[u u']) (per second). Only for loops whose every
    state is noise-driven and stable (the paper's example).

    Parameters
    ----------
    system : LinearSystem
        The model (its cost weights Q, R).
    model : DiscreteModel
        The plant sampled at the communication step h.
    est : LinearEstimator
        The estimator.
    Ks : np.ndarray
        Control gain, u = -Ks est.

    Returns
    -------
    dict[str, Any]
        ``rms_e`` (p values), ``rms_u`` (m values), ``cost_rate``, ``spectral_radius``
        and ``reason``; the first three are None, and ``reason`` says why, when the loop
        is not stationary.
    """
    from scipy.linalg import block_diag, solve_discrete_lyapunov

    Phi, Gam, Gx, Geta = jacobi_closed_loop(model, est, Ks)
    rho = float(np.max(np.abs(np.linalg.eigvals(Phi))))
    if rho >= 1.0:
        return {"rms_e": None, "rms_u": None, "cost_rate": None, "spectral_radius": rho,
                "reason": f"the Jacobi-coupled loop is not stationary: spectral radius "
                          f"{rho:.6g} >= 1"}
    W = block_diag(model.Qd, model.Rd)
    Sigma = solve_discrete_lyapunov(Phi, Gam @ W @ Gam.T)
    ns = model.ns
    See = model.E @ Sigma[:ns, :ns] @ model.E.T
    Suu = Gx @ Sigma @ Gx.T + Geta @ W @ Geta.T
    return {"rms_e": np.sqrt(np.clip(np.diag(See), 0, None)).tolist(),
            "rms_u": np.sqrt(np.clip(np.diag(Suu), 0, None)).tolist(),
            "cost_rate": float(np.trace(system.Q @ See) + np.trace(system.R @ Suu)),
            "spectral_radius": rho, "reason": None}

"""Exact stationary performance of the sampled closed loop, from a Lyapunov equation.

Closed-loop state X = [s; q] (plant state s = [x; w; z], estimator state q), noise per
step eta = [v; n; n_z] with covariance W = blkdiag(Qd, Rd), independent of X[k]:

    mvec = Ms s + J eta,  est = Ce q + Dm mvec,  u = -Ks est
    s'   = Ad s + Bd u + [I 0] eta,   q' = Aq est + Bu u
    =>  X[k+1] = Phi X[k] + Gam eta[k],   u[k] = Gx X[k] + Geta eta[k],   e[k] = E s[k]

Stationary covariance: Sigma = Phi Sigma Phi' + Gam W Gam' (scipy's
``solve_discrete_lyapunov``), so E[e e'] = E Sigma_ss E', E[u u'] = Gx Sigma Gx' +
Geta W Geta', and the cost rate J/T = tr(Q E[e e']) + tr(R E[u u']) at the sample instants.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import block_diag, solve_discrete_lyapunov

from estimator_fmu.estimators import LinearEstimator
from plant_model.discretization import DiscreteModel
from plant_model.system import LinearSystem

__all__ = ["Prediction", "closed_loop", "predict_stationary"]


@dataclass(frozen=True)
class Prediction:
    """Stationary RMS of e and u and the cost rate; ``None`` values when not stationary."""

    rms_e: list[float] | None
    rms_u: list[float] | None
    cost_rate: float | None
    spectral_radius: float
    settling_time: float          #: 5 time constants of the slowest closed-loop mode (s)
    reason: str | None = None     #: why there is no stationary prediction


def closed_loop(model: DiscreteModel, est: LinearEstimator, Ks: np.ndarray):
    """(Phi, Gam, Gx, Geta) of the sampled closed loop described in the module docstring."""
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


def predict_stationary(system: LinearSystem, model: DiscreteModel, est: LinearEstimator,
                       Ks: np.ndarray) -> Prediction:
    """Stationary RMS of each e and u component and the cost rate of the closed loop."""
    Phi, Gam, Gx, Geta = closed_loop(model, est, Ks)
    rho = float(np.max(np.abs(np.linalg.eigvals(Phi)))) if Phi.size else 0.0
    if rho >= 1.0:
        return Prediction(None, None, None, rho, float("inf"),
                          reason=f"the closed loop (with its exosystems) is not stationary: "
                                 f"spectral radius {rho:.6g} >= 1")
    tau = -model.h / np.log(rho) if rho > 0 else model.h
    W = block_diag(model.Qd, model.Rd)
    Sigma = solve_discrete_lyapunov(Phi, Gam @ W @ Gam.T)
    ns = model.ns
    See = model.E @ Sigma[:ns, :ns] @ model.E.T
    Suu = Gx @ Sigma @ Gx.T + Geta @ W @ Geta.T
    cost = float(np.trace(system.Q @ See) + np.trace(system.R @ Suu))
    return Prediction(
        rms_e=np.sqrt(np.clip(np.diag(See), 0, None)).tolist(),
        rms_u=np.sqrt(np.clip(np.diag(Suu), 0, None)).tolist(),
        cost_rate=cost, spectral_radius=rho, settling_time=float(5 * tau),
    )

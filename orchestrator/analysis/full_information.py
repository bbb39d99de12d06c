"""The full-information optimum of a fleet's cost: the lower bound both architectures face.

Scored as every run is, the cost rate is the window average of e'Qe + u'Ru at the samples,
with u held over each step. With the consensus protocol as a force the fleet's physics and
noise are block diagonal and the cost is a sum over vehicles, so a controller that knows
every state exactly (vehicles, currents, leader) can do no better than each vehicle's own
optimum: the bound is a sum over vehicles. For vehicle i (sampled alone,
:func:`plant_model.per_vehicle.sample_vehicle`; z = [z_l; c] its view of the leader and
offset, z[k] = Phi^k z0 a planned path) split the motion into its mean and the noise:

- **noise**: the deviation obeys ds+ = Ad ds + Bd du + v, v ~ N(0, Qd); the least stationary
  E[e'Qe + u'Ru] over all causal policies is tr(P Qd), P the stabilizing solution of the
  discrete Riccati equation with state weight blkdiag(C'QC, 0) (the discrete LQ regulator);
- **mean**: the best steady motion the leader admits, x = X z, u = U z with
  X Phi = Ad_x X + Bd_x U (Ad_x, Bd_x the vehicle rows; the current's mean decays), chosen to
  minimize the window average tr(M Zbar), M = (H - C X)' Q (H - C X) + U' R U,
  Zbar = mean over the window of z z': a linear least-squares problem on the null space of
  the constraint.

Cross terms vanish (the noise has zero mean), so J_FI = sum_i tr(P_i Qd_i) + min_i tr(M_i
Zbar). A law held over the step, with estimates, neighbour-only information or a consensus
force, can only add to it (up to the start-up transient inside a short window). Only for a
leader without process noise (a planned path; otherwise None with the reason).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.linalg import expm, solve_discrete_are

from plant_model.per_vehicle import sample_vehicle

if TYPE_CHECKING:
    from ..scenario import Scenario

__all__ = ["FullInformationBound", "full_information_bound", "best_steady_motion",
           "fleet_bound", "fleet_comparison"]


@dataclass(frozen=True)
class FullInformationBound:
    """J_FI = noise + mean, summed over vehicles (1/s units of the cost rate: m^2 Q + N^2 R)."""

    cost_rate: float | None
    noise: float | None
    mean: float | None
    per_vehicle: list[float]
    reason: str | None = None


def _zbar(Phi: np.ndarray, z0: np.ndarray, k0: int, K: int) -> np.ndarray:
    """Mean of z z' over k0 <= k < K for z[k] = Phi^k z0 (the vehicles of a fleet share
    the leader's: computed once per content, :func:`_zbar_cached`)."""
    Phi, z0 = np.ascontiguousarray(Phi, dtype=float), np.ascontiguousarray(z0, dtype=float)
    return _zbar_cached(Phi.tobytes(), Phi.shape, z0.tobytes(), int(k0), int(K)).copy()


@lru_cache(maxsize=16)
def _zbar_cached(phi: bytes, shape: tuple[int, int], z0: bytes, k0: int,
                 K: int) -> np.ndarray:
    """:func:`_zbar` of the arrays given by their bytes: the samples as rows, one product."""
    Phi = np.frombuffer(phi).reshape(shape)
    z = np.linalg.matrix_power(Phi, k0) @ np.frombuffer(z0)
    Z = np.empty((max(K - k0, 0), z.size))
    for j in range(Z.shape[0]):
        Z[j] = z
        z = Phi @ z
    return (Z.T @ Z) / max(K - k0, 1)


def best_steady_motion(Ad: np.ndarray, Bd: np.ndarray, C: np.ndarray, H: np.ndarray,
                       Q: np.ndarray, R: np.ndarray, Phi: np.ndarray,
                       Zbar: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """(X, U, cost): min tr(M Zbar) s.t. X Phi = Ad X + Bd U (module docstring).

    Solved as a least-squares problem on the constraint's null space (so the motion is
    one to machine precision, however singular Zbar or the constraint): with
    S = Zbar^(1/2), Q = Qh' Qh, R = Rh' Rh the cost is
    ||Qh (H - C X) S||_F^2 + ||Rh U S||_F^2, linear in (X, U).

    Parameters
    ----------
    Ad, Bd : np.ndarray
        The vehicle's sampled x-dynamics, p x p and p x q.
    C, H : np.ndarray
        Output (s x p) and the target's map from z (s x l).
    Q, R : np.ndarray
        Cost weights (s x s, q x q).
    Phi : np.ndarray
        The reference's step map, l x l.
    Zbar : np.ndarray
        Window mean of z z', l x l.

    Returns
    -------
    tuple[np.ndarray, np.ndarray, float]
        X (p x l), U (q x l) and the window-average cost tr(M Zbar).
    """
    from scipy.linalg import cholesky, null_space

    p, q, l_ = Ad.shape[0], Bd.shape[1], Phi.shape[0]
    w, V = np.linalg.eigh(0.5 * (Zbar + Zbar.T))
    S = (V * np.sqrt(np.clip(w, 0.0, None))) @ V.T
    Qh, Rh = cholesky(Q), cholesky(R)
    nx, nu = p * l_, q * l_
    # unknowns vec(X), vec(U) (column-major); vec(A X B) = (B' kron A) vec X
    A = np.zeros((Qh.shape[0] * l_ + Rh.shape[0] * l_, nx + nu))
    A[:Qh.shape[0] * l_, :nx] = -np.kron(S.T, Qh @ C)
    A[Qh.shape[0] * l_:, nx:] = np.kron(S.T, Rh)
    b = np.zeros(A.shape[0])
    b[:Qh.shape[0] * l_] = -(Qh @ H @ S).reshape(-1, order="F")
    G = np.hstack([np.kron(Phi.T, np.eye(p)) - np.kron(np.eye(l_), Ad),
                   -np.kron(np.eye(l_), Bd)])
    N = null_space(G)
    y = np.linalg.lstsq(A @ N, b, rcond=None)[0]
    sol = N @ y
    X = sol[:nx].reshape((p, l_), order="F")
    U = sol[nx:].reshape((q, l_), order="F")
    # the cost in the whitened form: tr(M Zbar) itself loses digits to cancellation
    # between the large entries of Zbar (positions of hundreds of metres)
    cost = float(np.sum((Qh @ (H - C @ X) @ S) ** 2) + np.sum((Rh @ U @ S) ** 2))
    return X, U, cost


def full_information_bound(sc: Scenario, window: tuple[int, int]) -> FullInformationBound:
    """J_FI of a fleet scenario over the statistics window (module docstring).

    Parameters
    ----------
    sc : Scenario
        A fleet scenario (its vehicles' views, h, cost weights).
    window : tuple[int, int]
        Samples k0 <= k < K of the statistics.

    Returns
    -------
    FullInformationBound
        The bound and its parts; ``cost_rate`` None (with the reason) for a leader with
        process noise.
    """
    views = sc.fleet.views
    if np.any(views[0].W_z != 0.0):
        return FullInformationBound(None, None, None, [], reason=(
            "the leader has process noise: its random motion has no finite full-information "
            "optimum in these coordinates"))
    h = sc.h
    noise = mean = 0.0
    per = []
    for i, v in enumerate(views, start=1):
        model = sample_vehicle(v, h, i)
        p = v.n
        Qs = np.zeros((model.ns, model.ns))
        Qs[:p, :p] = v.C.T @ v.Q @ v.C
        P = solve_discrete_are(model.Ad, model.Bd, Qs, v.R)
        Jn = float(np.trace(P @ model.Qd))
        Zbar = _zbar(expm(v.F * h), v.z0, *window)
        _, _, Jm = best_steady_motion(model.Ad[:p, :p], model.Bd[:p], v.C, v.H, v.Q, v.R,
                                      expm(v.F * h), Zbar)
        noise, mean = noise + Jn, mean + Jm
        per.append(Jn + Jm)
    return FullInformationBound(cost_rate=noise + mean, noise=noise, mean=mean, per_vehicle=per)


def fleet_bound(sc: Scenario, k0: int) -> float | None:
    """J_FI over the window [k0, K) of a fleet in the protocol form (None otherwise).

    Parameters
    ----------
    sc : Scenario
        A fleet scenario.
    k0 : int
        First sample of the statistics window.

    Returns
    -------
    float or None
        The bound's cost rate.
    """
    if sc.fleet is None or sc.fleet.consensus != "protocol":
        return None
    return full_information_bound(sc, (k0, sc.steps)).cost_rate


def fleet_comparison(sc: Scenario, methods: dict[str, Any]) -> dict[str, Any]:
    """Summary keys that compare a fleet's methods with each other and with the bound.

    ``cost_rate_full_information``: the bound over the first method's window;
    ``price_of_decentralization``: J_distributed / J_centralized (simulated, same noise) and
    ``price_of_decentralization_predicted``, when both architectures ran with the same
    estimator and tracking law (the first such pair).

    Parameters
    ----------
    sc : Scenario
        The scenario.
    methods : dict[str, Any]
        The summary's methods.

    Returns
    -------
    dict[str, Any]
        The keys above (empty for a single system).
    """
    if sc.fleet is None:
        return {}
    ran = {n: m for n, m in methods.items() if m.get("seeds_completed")}
    first = next(iter(ran.values()), {})
    out: dict[str, Any] = {"cost_rate_full_information": first.get("cost_rate_full_information")}
    by = {(m["architecture"], m["estimator"], m["tracking"]): m for m in ran.values()}
    for (arch, est, trk), cen in by.items():
        dis = by.get(("distributed", est, trk))
        if arch != "centralized" or dis is None:
            continue
        pc, pd = cen["cost_rate"], dis["cost_rate"]
        out["price_of_decentralization"] = pd["mean"] / pc["mean"]
        out["price_of_decentralization_predicted"] = (
            None if pc["predicted"] is None or pd["predicted"] is None
            else pd["predicted"] / pc["predicted"])
        out["price_of_decentralization_methods"] = {"estimator": est, "tracking": trk}
        break
    return out

"""State estimators for the control law, all in one linear form.

Every mode is a discrete linear system with internal state q[k]; at sample k it maps
the measurement vector mvec[k] = [y; ybar; x; w; z] (the last three are the plant's
truth, used only by ``ideal``) and the applied u[k] to the estimate est = [xhat; what; zhat]:

    est[k]  = Ce q[k] + Dm mvec[k]            (direct feedthrough of y[k], ybar[k])
    q[k+1]  = Aq est[k] + Bu u[k]

Modes:
- ``kalman``: a steady-state Kalman filter in current-estimator form on [x; w; z] from
  [y; ybar] (using the applied u), built on the plant's exact sampled model:
  q is the one-step prediction, est = q + L (meas - M q), q[k+1] = Ad est + Bd u.
  Without Bz (the paper) the joint filter splits exactly into the filter on [x; w] from y
  and the filter on z from ybar (docs/theory.md section 5). Reference states that form a
  known planned path (:meth:`LinearSystem.known_reference_mask`) are not filtered: their
  estimate is propagated exactly from z(0), and ybar is not used when the whole reference
  is known.
- ``classical``: the paper's comparison law: xhat = C^+ y, zhat = H^+ ybar, and what run
  open loop from w(0): what[k+1] = expm(K h) what[k].
- ``ideal``: est = the true state (a lower bound on the achievable cost).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import LinAlgError, solve_discrete_are

from plant_model.discretization import DiscreteModel
from plant_model.linalg_checks import ModelError, unobservable_modes
from plant_model.memo import DesignCache
from plant_model.system import LinearSystem

__all__ = ["LinearEstimator", "SteadyKalman", "steady_kalman", "kalman_estimator",
           "classical_estimator", "ideal_estimator", "kalman_vehicle_estimator",
           "classical_vehicle_estimator", "ideal_vehicle_estimator"]


#: filter gains of this process, by the numbers they come from (plant_model.memo)
_KALMAN_CACHE = DesignCache("steady_kalman")


@dataclass(frozen=True)
class SteadyKalman:
    """Steady-state discrete Kalman filter x[k+1] = A x + B u + v, y = C x + n."""

    L: np.ndarray        #: gain: xf = xp + L (y - C xp)
    P_pred: np.ndarray   #: stationary covariance of the prediction error
    P_filt: np.ndarray   #: stationary covariance of the filtered error


def steady_kalman(name: str, Ad: np.ndarray, Cm: np.ndarray, Qd: np.ndarray,
                  Rd: np.ndarray) -> SteadyKalman:
    """Gain of the stationary filter from the discrete algebraic Riccati equation (DARE).

        P = Ad P Ad' - Ad P Cm'(Cm P Cm' + Rd)^-1 Cm P Ad' + Qd,  L = P Cm'(Cm P Cm' + Rd)^-1

    and the filtered covariance P_filt = (I - L Cm) P. Solved once per process for
    identical numbers (:mod:`plant_model.memo`; the result's arrays are read-only).

    Parameters
    ----------
    name : str
        Describes the filtered pair in error messages.
    Ad : np.ndarray
        State transition over one step, k x k.
    Cm : np.ndarray
        Measurement matrix, q x k.
    Qd : np.ndarray
        Covariance of the process noise added per step, k x k.
    Rd : np.ndarray
        Covariance of the measurement noise per sample, q x q (positive definite).

    Returns
    -------
    SteadyKalman
        The gain L (k x q) and the stationary prediction and filtered error covariances.

    Raises
    ------
    ModelError
        If (Ad, Cm) is not detectable, Rd is singular or the DARE has no solution.
    """
    return _KALMAN_CACHE.get((Ad, Cm, Qd, Rd), lambda: _steady_kalman(name, Ad, Cm, Qd, Rd))


def _steady_kalman(name: str, Ad: np.ndarray, Cm: np.ndarray, Qd: np.ndarray,
                   Rd: np.ndarray) -> SteadyKalman:
    bad = unobservable_modes(Ad, Cm, continuous=False)
    if bad:
        modes = ", ".join(f"{z:.6g}" for z in bad)
        raise ModelError(
            f"the Kalman filter on {name} cannot exist: the pair is not detectable "
            f"(sampled modes {modes} with |mode| >= 1 are not seen by the measurement)"
        )
    if np.linalg.matrix_rank(Rd) < Rd.shape[0]:
        raise ModelError(
            f"the Kalman filter on {name} needs a positive definite measurement noise "
            "covariance; set a nonzero sensor noise or use the 'ideal' or 'classical' mode"
        )
    try:
        P = solve_discrete_are(Ad.T, Cm.T, Qd, Rd)
    except (LinAlgError, ValueError) as exc:
        raise ModelError(f"the Kalman filter Riccati equation for {name} has no solution: "
                         f"{exc}") from None
    P = 0.5 * (P + P.T)
    S = Cm @ P @ Cm.T + Rd
    L = np.linalg.solve(S, Cm @ P).T
    Pf = (np.eye(P.shape[0]) - L @ Cm) @ P
    return SteadyKalman(L=L, P_pred=P, P_filt=0.5 * (Pf + Pf.T))


@dataclass
class LinearEstimator:
    """est = Ce q + Dm mvec;  q <- Aq est + Bu u  (see the module docstring)."""

    mode: str
    Ce: np.ndarray
    Dm: np.ndarray
    Aq: np.ndarray
    Bu: np.ndarray
    q0: np.ndarray
    uses_truth: bool
    #: Kalman form (L, M): est = q + L (meas - M q), meas = mvec[:2p]; the same map as
    #: Ce q + Dm mvec with Ce = I - L M, evaluated with fewer flops when 2p < n + r + l
    gain: tuple[np.ndarray, np.ndarray] | None = None

    def __post_init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Restart from the initial internal state: q <- q0."""
        self.q = self.q0.copy()

    # ndarray.dot rather than `@`: the same BLAS gemv (same bits) without the matmul
    # ufunc's dispatch, which costs more than these small products
    def estimate(self, mvec: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """est[k] = Ce q[k] + Dm mvec[k], from the current q[k] and the measurements mvec[k].

        In Kalman form est[k] = q[k] + L (meas[k] - M q[k]), meas = [y; ybar].

        Parameters
        ----------
        mvec : np.ndarray
            The measurement vector [y; ybar; x; w; z], shape (2 p + n + r + l,).
        out : np.ndarray or None, optional
            Where to write the estimate, shape (n + r + l,); a new array if None.

        Returns
        -------
        np.ndarray
            The estimate [xhat; what; zhat] (``out`` if given).
        """
        q = self.q
        if self.gain is not None:
            L, M = self.gain
            return np.add(q, L.dot(mvec[:M.shape[0]] - M.dot(q)), out=out)
        return np.add(self.Ce.dot(q), self.Dm.dot(mvec), out=out)

    def update(self, est: np.ndarray, u: np.ndarray) -> None:
        """q[k+1] = Aq est[k] + Bu u[k].

        Parameters
        ----------
        est : np.ndarray
            The estimate of sample k, shape (n + r + l,).
        u : np.ndarray
            The control input applied over the step, shape (m,).
        """
        q = self.Aq.dot(est)
        q += self.Bu.dot(u)
        self.q = q

    def get_state(self) -> dict:
        """What evolves: the internal state q (a copy); the mode for checking.

        Returns
        -------
        dict
            Keys ``mode`` (str) and ``q`` (array).
        """
        return {"mode": self.mode, "q": self.q.copy()}

    def set_state(self, state: dict) -> None:
        """Restore a :meth:`get_state` result (validated first: on error nothing changes).

        Parameters
        ----------
        state : dict
            A result of :meth:`get_state` of an estimator of the same mode and size.

        Raises
        ------
        ValueError
            If the mode differs or q is not a real array of the right shape.
        """
        if state["mode"] != self.mode:
            raise ValueError(f"the estimator state is of mode {state['mode']!r}, "
                             f"this estimator is {self.mode!r}")
        q = np.asarray(state["q"])
        if q.dtype.kind not in "fiu" or q.shape != self.q0.shape:
            raise ValueError(f"estimator state q must be a real array of shape {self.q0.shape}, "
                             f"got {q.dtype} of shape {q.shape}")
        self.q = np.array(q, dtype=float)


def _one_based(idx: np.ndarray) -> str:
    return "[" + ",".join(str(i + 1) for i in idx) + "]"


def kalman_estimator(system: LinearSystem, model: DiscreteModel) -> LinearEstimator:
    """``kalman``: the steady filter on the stacked s (module docstring)."""
    n, r, p, ns = system.n, system.r, system.p, model.ns
    nm = 2 * p + ns                     # length of mvec = [y; ybar; x; w; z]
    known = system.known_reference_mask()
    zs = n + r + np.flatnonzero(~known)           # filtered reference states
    xw = np.arange(n + r)
    y_rows, ybar_rows = np.arange(p), np.arange(p, 2 * p)
    zname = "z" if known.sum() == 0 else f"z{_one_based(zs - n - r)}"
    if not np.any(system.Bz[:, ~known]):
        # No filtered reference state drives the vehicles: the joint filter splits
        # exactly into a filter on [x; w] from y and one on the reference from ybar.
        blocks = [("[x; w] from y (pair ([[A, B2], [0, K]], [C, 0]))", xw, y_rows)]
        if zs.size:
            blocks.append((f"{zname} from ybar (pair (F, H))", zs, ybar_rows))
    else:
        blocks = [(f"[x; w; {zname}] from [y; ybar]", np.concatenate([xw, zs]),
                   np.arange(2 * p))]
    L = np.zeros((ns, 2 * p))
    for name, S, rows in blocks:
        kf = steady_kalman(name, model.Ad[np.ix_(S, S)], model.M[np.ix_(rows, S)],
                           model.Qd[np.ix_(S, S)], model.Rd[np.ix_(rows, rows)])
        L[np.ix_(S, rows)] = kf.L
    Ce = np.eye(ns) - L @ model.M
    Dm = np.zeros((ns, nm))
    Dm[:, :2 * p] = L
    return LinearEstimator("kalman", Ce, Dm, model.Ad.copy(), model.Bd.copy(),
                           system.initial_state(), uses_truth=False,
                           gain=(L, model.M.copy()))


def classical_estimator(system: LinearSystem, model: DiscreteModel) -> LinearEstimator:
    """``classical``: xhat = C^+ y, zhat = H^+ ybar, what open loop (module docstring)."""
    n, r, l_, p, ns = system.n, system.r, system.l, system.p, model.ns
    nm = 2 * p + ns
    for name, M, cols in (("C", system.C, n), ("H", system.H, l_)):
        rank = np.linalg.matrix_rank(M)
        if rank < cols:
            raise ModelError(
                f"the classical estimator needs {name} with full column rank to "
                f"recover the state from its output ({name} has rank {rank} < {cols})"
            )
    Ce = np.zeros((ns, r))
    Ce[n:n + r] = np.eye(r)
    Dm = np.zeros((ns, nm))
    Dm[:n, :p] = np.linalg.pinv(system.C)
    Dm[n + r:, p:2 * p] = np.linalg.pinv(system.H)
    Aq = np.zeros((r, ns))
    Aq[:, n:n + r] = model.Ad[n:n + r, n:n + r]     # expm(K h)
    return LinearEstimator("classical", Ce, Dm, Aq, np.zeros((r, system.m)), system.w0.copy(),
                           uses_truth=False)


def ideal_estimator(system: LinearSystem, model: DiscreteModel) -> LinearEstimator:
    """``ideal``: est = [x; w; z], the truth."""
    p, ns = system.p, model.ns
    nm = 2 * p + ns
    Dm = np.zeros((ns, nm))
    Dm[:, 2 * p:] = np.eye(ns)
    return LinearEstimator("ideal", np.zeros((ns, 0)), Dm, np.zeros((0, ns)),
                           np.zeros((0, system.m)), np.zeros(0), uses_truth=True)


def kalman_vehicle_estimator(system: LinearSystem, model: DiscreteModel,
                             where: str = "vehicle") -> LinearEstimator:
    """``kalman`` of one vehicle (:func:`estimator_fmu.registry.make_vehicle_estimator`)."""
    s, ns = system.p, model.ns
    nm = s + ns
    M = np.ascontiguousarray(model.M[:s])
    L = steady_kalman(f"{where} [x; w] from y (pair ([[A, B2], [0, K]], [C, 0]))",
                      model.Ad, M, model.Qd, model.Rd[:s, :s]).L
    Dm = np.zeros((ns, nm))
    Dm[:, :s] = L
    return LinearEstimator("kalman", np.eye(ns) - L @ M, Dm, model.Ad.copy(), model.Bd.copy(),
                           np.concatenate([system.x0, system.w0]), uses_truth=False,
                           gain=(L, M))


def classical_vehicle_estimator(system: LinearSystem, model: DiscreteModel,
                                where: str = "vehicle") -> LinearEstimator:
    """``classical`` of one vehicle (:func:`estimator_fmu.registry.make_vehicle_estimator`)."""
    n, r, s, ns = system.n, system.r, system.p, model.ns
    nm = s + ns
    rank = np.linalg.matrix_rank(system.C)
    if rank < n:
        raise ModelError(f"{where}: the classical estimator needs C with full column rank "
                         f"to recover the state from y (C has rank {rank} < {n})")
    Ce = np.zeros((ns, r))
    Ce[n:] = np.eye(r)
    Dm = np.zeros((ns, nm))
    Dm[:n, :s] = np.linalg.pinv(system.C)
    Aq = np.zeros((r, ns))
    Aq[:, n:] = model.Ad[n:, n:]
    return LinearEstimator("classical", Ce, Dm, Aq, np.zeros((r, system.m)), system.w0.copy(),
                           uses_truth=False)


def ideal_vehicle_estimator(system: LinearSystem, model: DiscreteModel,
                            where: str = "vehicle") -> LinearEstimator:
    """``ideal`` of one vehicle (:func:`estimator_fmu.registry.make_vehicle_estimator`)."""
    s, ns = system.p, model.ns
    nm = s + ns
    Dm = np.zeros((ns, nm))
    Dm[:, s:] = np.eye(ns)
    return LinearEstimator("ideal", np.zeros((ns, 0)), Dm, np.zeros((0, ns)),
                           np.zeros((0, system.m)), np.zeros(0), uses_truth=True)

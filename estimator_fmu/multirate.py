"""A time-varying Kalman filter for measurements that arrive at different rates and
sometimes not at all (plant_model.navigation): acoustic fixes, DVL, depth.

On s = [x; w] of one vehicle sampled alone (Ad, Bd, Qd of
:func:`plant_model.per_vehicle.sample_vehicle`), with the measurement vector
mvec = [fix (3), dvl (3), depth, valid (3), x, w]:

    rows present at k:  J_k = the rows of [fix, dvl, depth] whose valid flag is 1
    H = [[I, 0, 0], [0, I, 0], [e_d', 0, 0]] (7 x 9),  R = diag(sigma^2)
    est[k]   = q[k] + K_k (m_J - H_J q[k]),  K_k = P_k H_J' (H_J P_k H_J' + R_J)^-1
    P+_k     = (I - K_k H_J) P_k (I - K_k H_J)' + K_k R_J K_k'      (Joseph form)
    q[k+1]   = Ad est[k] + Bd u[k],  P_{k+1} = Ad P+_k Ad' + Qd

With no measurement at k, est[k] = q[k]. q(0) = [x0; w0]; P_0 the periodic filter's
prior at phase 0 when no report is ever lost (:func:`periodic_filter`: the filter is then
periodic from the first step), else the stationary prior of a filter with a fix every
step (the start is known to that accuracy). The estimate has
direct feedthrough from the measurements, as the steady filter's.

The current estimate is projected onto |w_i| <= ``current_max`` (m/s, per axis; the
estimate-projection form of a constrained Kalman filter, the covariance unchanged). On
the nonlinear vehicle this is what keeps the loop stable: when the vehicle cannot produce
the commanded force (rpm at its limit, fins lagging), an accurate DVL makes the filter
explain the missing motion as a current of tens of m/s, which the controller's current
feedforward then pushes against, a runaway (docs/remus100-6dof.md).
"""
from __future__ import annotations

import math

import numpy as np

from plant_model.discretization import DiscreteModel
from plant_model.linalg_checks import ModelError
from plant_model.navigation import NAV_SIZE, NavigationSensors
from plant_model.system import LinearSystem

from .covariance_filter import CovarianceFilter
from .estimators import LinearEstimator, steady_kalman

__all__ = ["SENSOR_ROWS", "MultiRateKalman", "navigation_estimator", "navigation_rows",
           "periodic_filter"]

#: the rows of [fix; dvl; depth] (:func:`navigation_rows`) each sensor reports
SENSOR_ROWS = (np.arange(0, 3), np.arange(3, 6), np.arange(6, 7))


def navigation_rows(n: int, r: int) -> np.ndarray:
    """H (7 x (n + r)) of [fix; dvl; depth] on s = [x; w] of a remus model (x = [p; v])."""
    H = np.zeros((7, n + r))
    H[0:3, 0:3] = np.eye(3)
    H[3:6, 3:6] = np.eye(3)
    H[6, 2] = 1.0
    return H


def periodic_filter(Ad: np.ndarray, Qd: np.ndarray, sensors: NavigationSensors, h: float,
                    n: int, r: int
                    ) -> tuple[list[tuple[np.ndarray, np.ndarray, np.ndarray]], np.ndarray]:
    """The periodic Kalman filter of a schedule without dropouts: per phase k of the
    sensors' period P = lcm(n_fix, n_dvl, n_depth) (rows J_k, gain L_k (ns x |J_k|), R_k),
    and the prior covariance at phase 0, from P_{k+1} = Ad (I - L_k H_k) P_k Ad' + Qd
    iterated (report to report, the silent steps in one product) until the prior at
    phase 0 repeats to 1e-12 relative. Ad, Qd: the vehicle sampled at h; n, r: its
    state and current sizes.

    Raises
    ------
    ModelError
        If it does not converge in 100000 periods.
    """
    every = sensors.steps(h)
    P = math.lcm(*(int(v) for v in every))
    H, R = navigation_rows(n, r), np.diag(sensors.sigmas ** 2)
    rows = []
    for k in range(P):
        present = [g for g, nj in zip(SENSOR_ROWS, every) if k % nj == 0]
        rows.append(np.concatenate(present) if present else np.zeros(0, dtype=int))
    ns = Ad.shape[0]
    eye = np.eye(ns)
    reports = [k for k in range(P) if rows[k].size]          # phase 0 always: all report
    gaps = [((reports[(i + 1) % len(reports)] - k) % P) or P for i, k in enumerate(reports)]
    # between two reports: P <- A^m P A^m' + Q_m, Q_m = sum_{j<m} A^j Qd A^j'
    power: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    for m in sorted(set(gaps)):
        A, Q = eye.copy(), np.zeros((ns, ns))
        for _ in range(m):
            Q = Ad @ Q @ Ad.T + Qd
            A = Ad @ A
        power[m] = (A, Q)
    out = [(np.zeros(0, dtype=int), np.zeros((ns, 0)), np.zeros((0, 0))) for _ in range(P)]
    Pm = Qd.copy()
    for _ in range(100_000):
        start = Pm.copy()
        for k, m in zip(reports, gaps):
            J = rows[k]
            Hk, Rk = H[J], R[np.ix_(J, J)]
            L = np.linalg.solve(Hk @ Pm @ Hk.T + Rk, Hk @ Pm).T
            IKH = eye - L @ Hk
            Pp = IKH @ Pm @ IKH.T + L @ Rk @ L.T
            out[k] = (J, L, Rk)
            A, Q = power[m]
            Pm = A @ Pp @ A.T + Q
            Pm = 0.5 * (Pm + Pm.T)
        if np.abs(Pm - start).max() <= 1e-12 * np.abs(Pm).max():
            return out, Pm
    raise ModelError("the periodic Kalman filter of [sensors] did not converge")



class MultiRateKalman(CovarianceFilter):
    """The filter of the module docstring; ``estimate`` then ``update`` once per step."""

    state_mode = "kalman-multirate"
    label = "the multi-rate Kalman filter"

    @property
    def mode(self) -> str:
        """Its estimator's name (the registry row whose navigation is this filter)."""
        from .registry import NAVIGATION_FILTER
        return NAVIGATION_FILTER

    def __init__(self, model: DiscreteModel, sensors: NavigationSensors, q0: np.ndarray):
        ns = model.ns
        self.Ad, self.Bd, self.Qd = (np.ascontiguousarray(a) for a in
                                     (model.Ad, model.Bd, model.Qd))
        self.H = navigation_rows(model.n, model.r)
        self.R = np.diag(sensors.sigmas ** 2)
        self.current_max = float(sensors.current_max)
        self._w = slice(model.n, model.n + model.r)
        self.q0 = np.array(q0, dtype=float)
        if sensors.lossless:
            self.P0 = periodic_filter(model.Ad, model.Qd, sensors, model.h, model.n,
                                      model.r)[1]
        else:
            self.P0 = steady_kalman("the multi-rate filter's start (a fix every step)",
                                    model.Ad, self.H[:3], model.Qd, self.R[:3, :3]).P_pred
        self._eye = np.eye(ns)
        self.reset()

    def estimate(self, mvec: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """est[k] from q[k], P[k] and the measurements present in mvec (module docstring);
        the filtered covariance is kept for :meth:`update` (the prior is not changed, so
        calling this twice in a step gives the same estimate)."""
        valid = mvec[7:NAV_SIZE] > 0.5
        q, P = self.q, self.P
        if not valid.any():
            self._P_post = P
            if out is None:
                return q.copy()
            out[:] = q
            return out
        J = np.concatenate([rows for rows, v in zip(SENSOR_ROWS, valid) if v])
        H, R = self.H[J], self.R[np.ix_(J, J)]
        S = H @ P @ H.T + R
        K = np.linalg.solve(S, H @ P).T
        IKH = self._eye - K @ H
        self._P_post = IKH @ P @ IKH.T + K @ R @ K.T
        est = q + K @ (mvec[J] - H @ q)
        np.clip(est[self._w], -self.current_max, self.current_max, out=est[self._w])
        if out is None:
            return est
        out[:] = est
        return out


def navigation_estimator(system: LinearSystem, model: DiscreteModel, mode: str,
                         sensors: NavigationSensors) -> MultiRateKalman | LinearEstimator:
    """One vehicle's estimator from its navigation sensors, as its registry row's
    ``navigation`` says: "filter" the :class:`MultiRateKalman`, "truth" the truth
    (mvec = [nav; x; w]).

    Raises
    ------
    ModelError
        For an estimator that needs a position fix every step (``navigation`` None).
    """
    from .registry import ESTIMATORS, estimator_kind
    ns = model.ns
    kind = estimator_kind(mode)
    if kind.navigation == "filter":
        return MultiRateKalman(model, sensors, np.concatenate([system.x0, system.w0]))
    if kind.navigation == "truth":
        Dm = np.zeros((ns, NAV_SIZE + ns))
        Dm[:, NAV_SIZE:] = np.eye(ns)
        return LinearEstimator(mode, np.zeros((ns, 0)), Dm, np.zeros((0, ns)),
                               np.zeros((0, system.m)), np.zeros(0), uses_truth=True)
    ok = " or ".join(k for k, e in ESTIMATORS.items() if e.navigation)
    raise ModelError(f"estimator mode {mode!r} needs a position fix every step; with [sensors] "
                     f"(acoustic fixes, DVL, depth at their own rates) use {ok}")

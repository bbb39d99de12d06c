"""``kalman-tv``: the time-varying Kalman filter started from a given covariance P0.

The steady filter (:func:`estimator_fmu.estimators.steady_kalman`) uses the limit gain from
the first sample on. This one follows the Riccati difference equation from P0, on the
plant's own sampled model (Ad, Bd, Qd, Rd, measurement matrix Mm), in the current-estimator
form of the steady filter (q[k] the one-step prediction, P[k] its covariance):

    S_k      = Mm P_k Mm' + Rd                                  (innovation covariance)
    L_k      = P_k Mm' S_k^-1                                   (gain of sample k)
    est[k]   = q[k] + L_k (meas[k] - Mm q[k])
    P+_k     = (I - L_k Mm) P_k (I - L_k Mm)' + L_k Rd L_k'     (Joseph form)
    q[k+1]   = Ad est[k] + Bd u[k],   P_{k+1} = sym(Ad P+_k Ad' + Qd)

with q[0] the known start and P_0 = P0. L_k tends to the steady gain L when (Ad, Mm) is
detectable, (Ad, Qd^1/2) has no uncontrollable mode on the unit circle and Rd > 0
(:func:`gain_sequence` shows it; docs/theory.md section 5). Units: P in the states'
units squared; Rd in the measurements' units squared (per sample).

Filtered state and P0 (:func:`stacked_initial_covariance`): on the stacked [x; w; z] the
filter is one joint filter on every state from [y; ybar]; the planned-path reference
states (:meth:`LinearSystem.known_reference_mask`) have zero rows and columns in P0, so
their gain rows stay exactly zero (they are propagated, as in the steady filter). Per
vehicle the filter is on [x; w] from y. P0 = 0 is the known start (q[0] is the true
state): L_0 = 0, the gains grow to the steady one.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from plant_model.discretization import DiscreteModel
from plant_model.linalg_checks import ModelError
from plant_model.system import LinearSystem

from .covariance_filter import CovarianceFilter

__all__ = ["NAME", "TimeVaryingKalman", "check_initial_covariance", "gain_sequence",
           "riccati_step", "stacked_initial_covariance", "tv_estimator", "tv_vehicle_estimator"]

#: the registry's name of this estimator (estimator_fmu.registry)
NAME = "kalman-tv"


def check_initial_covariance(value: Any, size: int, name: str = "[estimator] P0") -> np.ndarray:
    """P0 as a size x size symmetric positive semidefinite matrix (a number: that times I).

    Raises
    ------
    ModelError
        One line naming the matrix and what is wrong: its shape, an asymmetry, or its
        least eigenvalue.
    """
    if isinstance(value, bool):
        raise ModelError(f"{name} must be a number or a {size} x {size} matrix, not a boolean")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"{name} must be a number or a {size} x {size} matrix of "
                         "numbers") from None
    if arr.ndim == 0:
        arr = float(arr) * np.eye(size)
    if arr.shape != (size, size):
        raise ModelError(f"{name} must be {size} x {size} (the filter's state), got shape "
                         f"{' x '.join(str(d) for d in arr.shape)}")
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"{name} must be finite")
    scale = max(float(np.abs(arr).max()), 1e-300)
    asym = float(np.abs(arr - arr.T).max())
    if asym > 1e-12 * scale:
        i, j = np.unravel_index(int(np.argmax(np.abs(arr - arr.T))), arr.shape)
        raise ModelError(f"{name} is not symmetric: entry [{i + 1},{j + 1}] = {arr[i, j]:.6g} "
                         f"but [{j + 1},{i + 1}] = {arr[j, i]:.6g}")
    low = float(np.linalg.eigvalsh(0.5 * (arr + arr.T)).min()) if size else 0.0
    if low < -1e-12 * scale:
        raise ModelError(f"{name} is not positive semidefinite: its least eigenvalue is "
                         f"{low:.6g}")
    return 0.5 * (arr + arr.T)


def stacked_initial_covariance(system: LinearSystem, P0: Any = 0.0,
                               per_vehicle: int | None = None) -> np.ndarray:
    """P0 on the stacked s = [x; w; z]: zero on the planned-path reference states.

    ``P0`` is a number (times I on the filtered states), an (n + r + l) square matrix, or,
    with ``per_vehicle`` = n_i + r_i of a fleet of N identical-size vehicles, one
    vehicle's matrix repeated on each vehicle's [x_i; w_i] block (the stacked order is
    x_1..x_N, w_1..w_N: the block is scattered accordingly) with zero on the reference.
    """
    n, r, l_ = system.n, system.r, system.l
    ns = n + r + l_
    known = np.zeros(ns, dtype=bool)
    known[n + r:] = system.known_reference_mask()
    if per_vehicle is None or np.ndim(P0) == 0:
        out = check_initial_covariance(P0, ns)
        if per_vehicle is not None:          # a fleet's number: zero on the reference
            out[n + r:, n + r:] = 0.0
    else:
        one = check_initial_covariance(P0, per_vehicle)
        nv = None
        for cand in range(1, n + 1):          # N vehicles: n = N n_i, r = N r_i
            if n % cand == 0 and r % cand == 0 and n // cand + r // cand == per_vehicle:
                nv = cand
                break
        if nv is None:
            raise ModelError(f"[estimator] P0 of {per_vehicle} x {per_vehicle} does not fit "
                             f"a vehicle of the stacked system ({n} states, {r} currents)")
        ni, ri = n // nv, r // nv
        out = np.zeros((ns, ns))
        idx = [np.concatenate([np.arange(i * ni, (i + 1) * ni), n + np.arange(i * ri,
                                                                            (i + 1) * ri)])
               for i in range(nv)]
        for ix in idx:
            out[np.ix_(ix, ix)] = one
    out[known, :] = 0.0
    out[:, known] = 0.0
    return out


def riccati_step(P: np.ndarray, Ad: np.ndarray, Mm: np.ndarray, Qd: np.ndarray,
                 Rd: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One step of the Riccati difference equation (module docstring): (L_k, P+_k, P_{k+1})
    from the prior P_k."""
    S = Mm @ P @ Mm.T + Rd
    L = np.linalg.solve(S, Mm @ P).T
    IKH = np.eye(P.shape[0]) - L @ Mm
    Pp = IKH @ P @ IKH.T + L @ Rd @ L.T
    Pn = Ad @ Pp @ Ad.T + Qd
    return L, Pp, 0.5 * (Pn + Pn.T)


def gain_sequence(P0: np.ndarray, Ad: np.ndarray, Mm: np.ndarray, Qd: np.ndarray,
                  Rd: np.ndarray, steps: int) -> np.ndarray:
    """L_0 .. L_{steps-1} of the Riccati difference equation from P0, shape (steps, k, q)."""
    out = np.empty((steps, Ad.shape[0], Mm.shape[0]))
    P = np.array(P0, dtype=float)
    for k in range(steps):
        out[k], _, P = riccati_step(P, Ad, Mm, Qd, Rd)
    return out


class TimeVaryingKalman(CovarianceFilter):
    """The filter of the module docstring; ``estimate`` then ``update`` once per step.

    mvec = [meas; anything else] (the first Mm.shape[0] entries are read); est has the
    size of q.
    """

    mode = state_mode = NAME
    label = repr(NAME)

    def __init__(self, Ad: np.ndarray, Bd: np.ndarray, Qd: np.ndarray, Rd: np.ndarray,
                 Mm: np.ndarray, P0: np.ndarray, q0: np.ndarray):
        self.Ad, self.Bd, self.Qd, self.Rd, self.Mm = (
            np.ascontiguousarray(a, dtype=float) for a in (Ad, Bd, Qd, Rd, Mm))
        if np.linalg.matrix_rank(self.Rd) < self.Rd.shape[0]:
            raise ModelError("the time-varying Kalman filter needs a positive definite "
                             "measurement noise covariance; set a nonzero sensor noise")
        self.P0 = np.array(P0, dtype=float)
        self.q0 = np.array(q0, dtype=float)
        self.reset()

    def gain(self) -> np.ndarray:
        """L_k of the current prior P_k."""
        Mm = self.Mm
        return np.linalg.solve(Mm @ self.P @ Mm.T + self.Rd, Mm @ self.P).T

    def estimate(self, mvec: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """est[k] = q + L_k (meas - Mm q); P+_k kept for :meth:`update` (calling this twice
        in a step gives the same estimate)."""
        Mm, q = self.Mm, self.q
        L, Pp, _ = riccati_step(self.P, self.Ad, Mm, self.Qd, self.Rd)
        self._P_post = Pp
        est = q + L @ (mvec[:Mm.shape[0]] - Mm @ q)
        if out is None:
            return est
        out[:] = est
        return out


def tv_estimator(system: LinearSystem, model: DiscreteModel,
                 options: dict[str, Any] | None = None) -> TimeVaryingKalman:
    """The stacked filter on s = [x; w; z] from [y; ybar] (mvec = [y; ybar; x; w; z]; from
    y alone when the whole reference is a planned path, whose ybar is then not read),
    q0 = s(0), P0 from ``options["P0"]`` by :func:`stacked_initial_covariance` (one
    vehicle's matrix when ``options["fleet"]``; default 0, the known start)."""
    options = options or {}
    P0 = options.get("P0")
    if P0 is None:
        P0 = np.zeros((model.ns, model.ns))
    else:
        P0 = np.asarray(P0, dtype=float)
        fleet = bool(options.get("fleet")) and P0.ndim == 2
        P0 = stacked_initial_covariance(system, P0, per_vehicle=P0.shape[0] if fleet
                                        else None)
    # ybar only when some reference state is filtered (a planned path is propagated)
    rows = model.p if system.known_reference_mask().all() else 2 * model.p
    return TimeVaryingKalman(model.Ad, model.Bd, model.Qd, model.Rd[:rows, :rows],
                             model.M[:rows], P0, system.initial_state())


def tv_vehicle_estimator(system: LinearSystem, model: DiscreteModel, where: str = "vehicle",
                         options: dict[str, Any] | None = None) -> TimeVaryingKalman:
    """One vehicle's filter on [x; w] from its own y (mvec = [y; x; w]), q0 = [x0; w0],
    P0 = ``options["P0"]`` ((n + r) square or a number; default 0)."""
    s = system.p
    P0 = (options or {}).get("P0")
    P0 = check_initial_covariance(0.0 if P0 is None else P0, model.ns, f"{where}: P0")
    return TimeVaryingKalman(model.Ad, model.Bd, model.Qd, model.Rd[:s, :s], model.M[:s],
                             P0, np.concatenate([system.x0, system.w0]))

"""Choosing the control weight from the vehicle: bandwidth and force budget.

The LQ law's only free scale is the input weight relative to the output weight; with
R = r I (1/N^2) and Q given (1/m^2) this module finds r from what the vehicle can do.

**Closed-loop bandwidth.** With the state feedback u = -Kx x on x' = A x + B u, the loop
broken at the plant input is L(s) = Kx (sI - A)^-1 B and its complementary sensitivity

    T(s) = L (I + L)^-1 = Kx (sI - A + B Kx)^-1 B            (push-through identity).

The bandwidth (rad/s) is the lowest frequency at which the largest singular value of
T(jw) falls below 1/sqrt(2) of its value at w = 0 (-3 dB; for a position loop T(0) = I,
so -3 dB absolute). For the REMUS design model, R = 0.01 gives about 0.5 rad/s, R = 1
about 0.17 rad/s (docs/remus100-6dof.md).

**Noise-driven force.** One vehicle sampled at h (zero-order hold), s = [x; w],

    s[k+1] = Ad s + Bd u + nu,  nu ~ N(0, Qd);   y[k] = M s + n,  n ~ N(0, Rd)
    est    = q + L (y - M q),   q[k+1] = Ad est + Bd u       (current-form Kalman filter;
                                                             L = 0, M = I for "ideal")
    u      = -Ks est            (the part of the law the noise moves; the leader's planned
                                 path and the offsets are deterministic)

gives X = [s; q], X[k+1] = Phi X + Gam [nu; n], u = Gx X + Geta [nu; n] with

    Phi  = [[Ad - Bd Ks L M, -Bd Ks (I - L M)], [Acl L M, Acl (I - L M)]],  Acl = Ad - Bd Ks
    Gam  = [[I, -Bd Ks L], [0, Acl L]],   Gx = [-Ks L M, -Ks (I - L M)],   Geta = [0, -Ks L]

and the stationary force covariance E[u u'] = Gx Sigma Gx' + Geta W Geta' with
Sigma = Phi Sigma Phi' + Gam W Gam' (discrete Lyapunov), W = blkdiag(Qd, Rd). With the
ideal estimator est = s: Phi = Ad - Bd Ks, Gam = I, Gx = -Ks, W = Qd. The predicted
3-sigma force per axis is 3 sqrt(E[u_a^2]) (N).

**The search.** Both figures fall as r grows (a dearer force, a slower loop); the search
checks that on a grid of log10 r and solves f(log10 r) = target by Brent's method
(scipy.optimize.brentq) between the grid points that bracket it. With both targets the
larger r is taken: the fastest design that stays within the bandwidth and the budget.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.linalg import block_diag, solve_discrete_lyapunov
from scipy.optimize import brentq

from plant_model.linalg_checks import ModelError

__all__ = ["WeightChoice", "choose_weight", "closed_loop_bandwidth", "complementary_gain",
           "noise_force_covariance", "LOG10_R_RANGE"]

#: the search range of log10 r
LOG10_R_RANGE = (-6.0, 6.0)


def complementary_gain(A: np.ndarray, B: np.ndarray, Kx: np.ndarray, w: float) -> float:
    """Largest singular value of T(jw) = Kx (jw I - A + B Kx)^-1 B (module docstring).

    Parameters
    ----------
    A, B : np.ndarray
        The design model, n x n (1/s) and n x m.
    Kx : np.ndarray
        State feedback gain, m x n.
    w : float
        Frequency, rad/s (>= 0).

    Returns
    -------
    float
        sigma_max(T(jw)), dimensionless.
    """
    n = A.shape[0]
    T = Kx @ np.linalg.solve(1j * w * np.eye(n) - A + B @ Kx, B.astype(complex))
    return float(np.linalg.svd(T, compute_uv=False)[0])


def closed_loop_bandwidth(A: np.ndarray, B: np.ndarray, Kx: np.ndarray) -> float:
    """The -3 dB frequency of sigma_max(T(jw)) relative to w = 0 (module docstring), rad/s.

    Scanned on a logarithmic grid from 1e-6 to 1e4 times the fastest closed-loop pole,
    then refined by Brent's method on the first grid interval that crosses.

    Raises
    ------
    ModelError
        If A - B Kx is not Hurwitz or T never falls 3 dB below its DC value.
    """
    poles = np.linalg.eigvals(A - B @ Kx)
    if np.max(poles.real) >= 0.0:
        raise ModelError("closed_loop_bandwidth: A - B Kx is not Hurwitz")
    level = complementary_gain(A, B, Kx, 0.0) / np.sqrt(2.0)
    top = float(np.max(np.abs(poles)))
    grid = top * np.logspace(-6, 4, 401)
    gains = np.array([complementary_gain(A, B, Kx, w) for w in grid])
    below = np.nonzero(gains < level)[0]
    if below.size == 0:
        raise ModelError("closed_loop_bandwidth: the complementary sensitivity never falls "
                         "3 dB below its DC value")
    k = int(below[0])
    if k == 0:
        return float(grid[0])
    return float(10.0 ** brentq(lambda lw: complementary_gain(A, B, Kx, 10.0 ** lw) - level,
                                np.log10(grid[k - 1]), np.log10(grid[k]), xtol=1e-13))


def noise_force_covariance(Ad: np.ndarray, Bd: np.ndarray, Ks: np.ndarray, Qd: np.ndarray,
                           M: np.ndarray | None = None, Rd: np.ndarray | None = None,
                           L: np.ndarray | None = None) -> np.ndarray:
    """Stationary E[u u'] (N^2) of the noise-driven force of one sampled vehicle.

    The loop of the module docstring; without ``L`` (M, Rd unused) the ideal estimator
    est = s.

    Parameters
    ----------
    Ad, Bd : np.ndarray
        The sampled plant [x; w], ns x ns and ns x m.
    Ks : np.ndarray
        The law's gain on [x; w], m x ns (u = -Ks est).
    Qd : np.ndarray
        Process noise covariance per step, ns x ns.
    M, Rd, L : np.ndarray or None
        Measurement matrix (p x ns), its noise covariance per sample (p x p) and the
        current-form Kalman gain (ns x p).

    Returns
    -------
    np.ndarray
        E[u u'], m x m (symmetric).

    Raises
    ------
    ModelError
        If the loop is not stable (spectral radius >= 1).
    """
    ns = Ad.shape[0]
    Acl = Ad - Bd @ Ks
    if L is None:
        Phi, Gam, Gx, Geta, W = Acl, np.eye(ns), -Ks, np.zeros((Ks.shape[0], ns)), Qd
    else:
        LM = L @ M
        ImLM = np.eye(ns) - LM
        Phi = np.block([[Ad - Bd @ Ks @ LM, -Bd @ Ks @ ImLM], [Acl @ LM, Acl @ ImLM]])
        p = M.shape[0]
        Gam = np.block([[np.eye(ns), -Bd @ Ks @ L], [np.zeros((ns, ns)), Acl @ L]])
        Gx = np.hstack([-Ks @ LM, -Ks @ ImLM])
        Geta = np.hstack([np.zeros((Ks.shape[0], ns)), -Ks @ L])
        W = block_diag(Qd, Rd)
        assert Gam.shape[1] == ns + p
    rho = float(np.max(np.abs(np.linalg.eigvals(Phi))))
    if rho >= 1.0:
        raise ModelError(f"the sampled loop is not stable (spectral radius {rho:.6g}); "
                         "no stationary force")
    Sigma = solve_discrete_lyapunov(Phi, Gam @ W @ Gam.T)
    Suu = Gx @ Sigma @ Gx.T + Geta @ W @ Geta.T
    return 0.5 * (Suu + Suu.T)


@dataclass(frozen=True)
class WeightChoice:
    """The chosen r (R = r I) and why."""

    r: float                     #: the chosen input weight scale, 1/N^2
    binding: str                 #: "bandwidth", "force_budget" or "range" (hit a bound)
    r_bandwidth: float | None    #: r that meets the bandwidth target alone
    r_force: float | None        #: r that meets the force budget alone


def _solve(f: Callable[[float], float], target: float, name: str,
           grid: np.ndarray, values: np.ndarray) -> float:
    """log10 r with f(log10 r) = target on a decreasing f sampled as ``values``."""
    if np.any(np.diff(values) > 1e-9 * np.max(np.abs(values))):
        k = int(np.argmax(np.diff(values)))
        raise ModelError(f"{name} does not fall monotonically with R: {values[k]:.6g} at R = "
                         f"1e{grid[k]:g}, {values[k + 1]:.6g} at R = 1e{grid[k + 1]:g}")
    if values[0] <= target:
        return float(grid[0])
    if values[-1] > target:
        raise ModelError(f"{name} = {target:.6g} cannot be met: even R = 1e{grid[-1]:g} "
                         f"gives {values[-1]:.6g}")
    k = int(np.nonzero(values <= target)[0][0])
    return float(brentq(lambda x: f(x) - target, grid[k - 1], grid[k], xtol=1e-10))


def choose_weight(bandwidth_of: Callable[[float], float],
                  force_ratio_of: Callable[[float], float], *,
                  bandwidth: float | None = None, force_budget: float | None = None,
                  points: int = 25) -> WeightChoice:
    """The input weight scale r meeting a bandwidth target and/or a force budget.

    Parameters
    ----------
    bandwidth_of : callable
        r -> closed-loop bandwidth, rad/s (decreasing in r).
    force_ratio_of : callable
        r -> predicted 3-sigma force over the maximum force, the worst axis (decreasing).
    bandwidth : float or None
        Target bandwidth, rad/s: the loop is at most this fast.
    force_budget : float or None
        Largest predicted 3-sigma force as a fraction of the maximum force.
    points : int, optional
        Grid points on LOG10_R_RANGE for the monotonicity check and the bracket.

    Returns
    -------
    WeightChoice
        r = max of the r each target needs (module docstring).

    Raises
    ------
    ModelError
        If neither target is given, a figure is not monotone in r, or a target cannot be
        met within LOG10_R_RANGE.
    """
    if bandwidth is None and force_budget is None:
        raise ModelError("choose_weight: give a bandwidth and/or a force budget")
    grid = np.linspace(*LOG10_R_RANGE, points)
    found: dict[str, float | None] = {"bandwidth": None, "force_budget": None}
    for name, target, fun in (("bandwidth", bandwidth, bandwidth_of),
                              ("force_budget", force_budget, force_ratio_of)):
        if target is None:
            continue
        def f(x: float, fun: Callable[[float], float] = fun) -> float:
            return fun(10.0 ** x)
        values = np.array([f(x) for x in grid])
        found[name] = 10.0 ** _solve(f, float(target), name, grid, values)
    bw_r, f_r = found["bandwidth"], found["force_budget"]
    r = max(x for x in (bw_r, f_r) if x is not None)
    binding = "bandwidth" if r == bw_r else "force_budget"
    if r <= 10.0 ** LOG10_R_RANGE[0] * (1 + 1e-12):
        binding = "range"
    return WeightChoice(r=float(r), binding=binding, r_bandwidth=bw_r, r_force=f_r)

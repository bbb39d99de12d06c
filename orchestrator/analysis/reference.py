"""Monolithic reference: the same discrete-time loop as a plain numpy loop, no FMI.

Written out explicitly per estimator design (its registry row's ``design``: predict /
update of the steady Kalman filters, the time-varying filter's Riccati recursion in its
standard (not Joseph) form with an explicit inverse, pseudo-inverses of the classical
law, the truth) rather than through the
estimator classes the FMUs use, so the co-simulation is checked against an independent
implementation of the same algorithm over the same noise rows
(:meth:`plant_model.plant.NoiseStream.all_rows`).
"""
from __future__ import annotations

import numpy as np

from controller_fmu.regulator import tracking_law
from estimator_fmu.estimators import steady_kalman
from estimator_fmu.registry import estimator_kind
from plant_model.discretization import discretize
from plant_model.linalg_checks import ModelError
from plant_model.plant import NoiseStream
from plant_model.system import LinearSystem

__all__ = ["run_monolithic"]


def run_monolithic(system: LinearSystem, h: float, mode: str, seed: int,
                   steps: int, tracking: str = "lq",
                   timing: dict[str, float] | None = None,
                   P0: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Traces (row k = sample k) of the closed loop: y, ybar, x, w, z, e, xhat, what, zhat, u.

    s[k+1] = Ad s[k] + Bd u[k] + v[k], u[k] = -(Kx xhat + Kw what + Kz zhat), with the
    estimates of ``mode`` written out explicitly (module docstring).

    Parameters
    ----------
    system : LinearSystem
        The validated model.
    h : float
        Sampling period, s.
    mode : str
        Estimator (estimator_fmu.registry).
    seed : int
        Seed of the noise rows (:meth:`NoiseStream.all_rows`).
    steps : int
        Number of samples.
    tracking : str, optional
        Tracking law: 'lq' or 'regulator'.
    timing : dict[str, float] or None, optional
        If given, receives ``setup_s`` (design, sampling, filter gains) and ``loop_s``
        (the noise draws and the time-stepping loop), s.
    P0 : np.ndarray or None, optional
        The time-varying filter's start covariance on s = [x; w; z] (None: 0).

    Returns
    -------
    dict[str, np.ndarray]
        Name -> array of shape (steps, size), row k = sample k.

    Raises
    ------
    ModelError
        If the mode is unknown or the design or a filter does not exist.
    """
    import time
    t_setup = time.perf_counter()
    model = discretize(system, h)
    Ks = tracking_law(system, tracking).Ks
    n, r, l_, p, m = system.n, system.r, system.l, system.p, system.m
    ns, nxw = n + r + l_, n + r
    C, H = system.C, system.H
    Kx, Kw, Kz = Ks[:, :n], Ks[:, n:nxw], Ks[:, nxw:]
    Ad, Bd = model.Ad, model.Bd
    design = estimator_kind(mode).design
    if design == "riccati-recursion":
        # P_k: the prior covariance on s; the gain of sample k from it (explicit inverse)
        Pk = np.zeros((ns, ns)) if P0 is None else np.array(P0, dtype=float)
        Ms, Qd, Rd = model.M, model.Qd, model.Rd
        pred = system.initial_state()
    elif design == "steady-riccati":
        # one gain L on s = [x; w; z] from [y; ybar]; planned-path reference states
        # (no noise) are propagated, not filtered; the filter splits into [x; w] from y
        # and z from ybar unless a filtered reference state drives the vehicles (Bz).
        zs = nxw + np.flatnonzero(~system.known_reference_mask())
        Lfull = np.zeros((ns, 2 * p))
        xw, yr, ybr = np.arange(nxw), np.arange(p), np.arange(p, 2 * p)
        split = not np.any(system.Bz[:, zs - nxw])
        blocks = ([(xw, yr), (zs, ybr)] if split else
                  [(np.concatenate([xw, zs]), np.arange(2 * p))])
        for S, rows in blocks:
            if S.size:
                Lfull[np.ix_(S, rows)] = steady_kalman(
                    "reference filter", Ad[np.ix_(S, S)], model.M[np.ix_(rows, S)],
                    model.Qd[np.ix_(S, S)], model.Rd[np.ix_(rows, rows)]).L
        Ms = model.M
        pred = system.initial_state()
    elif design == "pseudo-inverse":
        Cp, Hp = np.linalg.pinv(C), np.linalg.pinv(H)
        AK = Ad[n:nxw, n:nxw]
        what_ol = system.w0.copy()
    elif design != "none":
        raise ModelError(f"no reference loop for estimator {mode!r}")
    out = {k: np.zeros((steps, d)) for k, d in
           (("y", p), ("ybar", p), ("x", n), ("w", r), ("z", l_), ("e", p),
            ("xhat", n), ("what", r), ("zhat", l_), ("u", m))}
    s = system.initial_state()
    t_loop = time.perf_counter()
    noise = NoiseStream.all_rows(model, seed, steps)   # timed with the loop, as in the plant
    for k in range(steps):
        v, nm = noise[k, :ns], noise[k, ns:]
        x, w, z = s[:n], s[n:nxw], s[nxw:]
        y = C @ x + nm[:p]
        ybar = H @ z + nm[p:]
        if design == "riccati-recursion":
            Lk = Pk @ Ms.T @ np.linalg.inv(Ms @ Pk @ Ms.T + Rd)
            filt = pred + Lk @ (np.concatenate([y, ybar]) - Ms @ pred)
            xhat, what, zhat = filt[:n], filt[n:nxw], filt[nxw:]
            Pk = Ad @ ((np.eye(ns) - Lk @ Ms) @ Pk) @ Ad.T + Qd
            Pk = 0.5 * (Pk + Pk.T)
        elif design == "steady-riccati":
            filt = pred + Lfull @ (np.concatenate([y, ybar]) - Ms @ pred)
            xhat, what, zhat = filt[:n], filt[n:nxw], filt[nxw:]
        elif design == "pseudo-inverse":
            xhat, what, zhat = Cp @ y, what_ol, Hp @ ybar
        else:
            xhat, what, zhat = x, w, z
        u = -(Kx @ xhat + Kw @ what + Kz @ zhat)
        for key, val in (("y", y), ("ybar", ybar), ("x", x), ("w", w), ("z", z),
                         ("e", H @ z - C @ x), ("xhat", xhat), ("what", what),
                         ("zhat", zhat), ("u", u)):
            out[key][k] = val
        s = Ad @ s + Bd @ u + v
        if design in ("riccati-recursion", "steady-riccati"):
            pred = Ad @ filt + Bd @ u
        elif design == "pseudo-inverse":
            what_ol = AK @ what_ol
    if timing is not None:
        timing["setup_s"] = t_loop - t_setup
        timing["loop_s"] = time.perf_counter() - t_loop
    return out

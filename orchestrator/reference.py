"""Monolithic reference: the same discrete-time loop as a plain numpy loop, no FMI.

Written out explicitly per estimator mode (predict / update of the two Kalman filters,
pseudo-inverses of the classical law, the truth for ``ideal``) rather than through the
estimator classes the FMUs use, so the co-simulation is checked against an independent
implementation of the same algorithm over the same noise rows
(:meth:`plant_model.plant.NoiseStream.all_rows`).
"""
from __future__ import annotations

import numpy as np

from controller_fmu.design import lq_tracking_design
from estimator_fmu.estimators import steady_kalman
from plant_model.discretization import discretize
from plant_model.linalg_checks import ModelError
from plant_model.plant import NoiseStream
from plant_model.system import LinearSystem

__all__ = ["run_monolithic"]


def run_monolithic(system: LinearSystem, h: float, mode: str, seed: int,
                   steps: int) -> dict[str, np.ndarray]:
    """Traces (row k = sample k) of the closed loop: y, ybar, x, w, z, e, xhat, what, zhat, u."""
    model = discretize(system, h)
    design = lq_tracking_design(system)
    n, r, l_, p, m = system.n, system.r, system.l, system.p, system.m
    ns, nxw = n + r + l_, n + r
    C, H = system.C, system.H
    Kx, Kw, Kz = design.Kx, design.Kw, design.Kz
    Ad, Bd = model.Ad, model.Bd
    Axw, Bx, Az = Ad[:nxw, :nxw], Bd[:nxw], Ad[nxw:, nxw:]
    noise = NoiseStream.all_rows(model, seed, steps)
    if mode == "kalman":
        Cxw = np.hstack([C, np.zeros((p, r))])
        Lxw = steady_kalman("[x; w]", Axw, Cxw, model.Qd[:nxw, :nxw], model.Rd[:p, :p]).L
        Lz = steady_kalman("z", Az, H, model.Qd[nxw:, nxw:], model.Rd[p:, p:]).L
        pred_xw = np.concatenate([system.x0, system.w0])
        pred_z = system.z0.copy()
    elif mode == "classical":
        Cp, Hp = np.linalg.pinv(C), np.linalg.pinv(H)
        AK = Ad[n:nxw, n:nxw]
        what_ol = system.w0.copy()
    elif mode != "ideal":
        raise ModelError(f"unknown estimator mode {mode!r}")
    out = {k: np.zeros((steps, d)) for k, d in
           (("y", p), ("ybar", p), ("x", n), ("w", r), ("z", l_), ("e", p),
            ("xhat", n), ("what", r), ("zhat", l_), ("u", m))}
    s = system.initial_state()
    for k in range(steps):
        v, nm = noise[k, :ns], noise[k, ns:]
        x, w, z = s[:n], s[n:nxw], s[nxw:]
        y = C @ x + nm[:p]
        ybar = H @ z + nm[p:]
        if mode == "kalman":
            filt_xw = pred_xw + Lxw @ (y - C @ pred_xw[:n])
            filt_z = pred_z + Lz @ (ybar - H @ pred_z)
            xhat, what, zhat = filt_xw[:n], filt_xw[n:], filt_z
        elif mode == "classical":
            xhat, what, zhat = Cp @ y, what_ol, Hp @ ybar
        else:
            xhat, what, zhat = x, w, z
        u = -(Kx @ xhat + Kw @ what + Kz @ zhat)
        for key, val in (("y", y), ("ybar", ybar), ("x", x), ("w", w), ("z", z),
                         ("e", H @ z - C @ x), ("xhat", xhat), ("what", what),
                         ("zhat", zhat), ("u", u)):
            out[key][k] = val
        s = Ad @ s + Bd @ u + v
        if mode == "kalman":
            pred_xw = Axw @ filt_xw + Bx @ u
            pred_z = Az @ filt_z
        elif mode == "classical":
            what_ol = AK @ what_ol
    return out

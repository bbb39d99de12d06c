"""Frequency responses of the nonlinear REMUS 100 behind the force interface against the
linear ``remus100``, and the first-order model fitted to them (``remus100-fitted``).

At a trim (straight and level at ``U0`` m/s north), a sinusoidal NED force of amplitude A
(N) on one axis (0 along track, 1 cross track, 2 vertical) is added to the trim force;
after one period to settle, the velocity over ground on that axis is fitted over two
periods by least squares to c + a sin(w t) + b cos(w t). The linear model's velocity per
force is 1 / (M_a j w + D_a) (plant_model.vehicles.remus100 at cruise speed U0). The
vehicle is stepped by the compiled kernel (plant_model.remus100.kernel, the same equations
as ForceCommandedRemus to 1e-12).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from plant_model.first_order_fit import FIT_OMEGAS, fit_first_order_response, sine_response
from plant_model.remus100 import kernel
from plant_model.remus100.autopilot import AutopilotGains
from plant_model.remus100.dynamics import STATE_SIZE, Remus100
from plant_model.remus100.rigid_body import rotation_ned_body
from plant_model.vehicles import remus100

__all__ = ["FIT_OMEGAS", "VALID_GAIN", "VALID_PHASE", "fit_first_order",
           "force_frequency_response", "valid_band"]



def force_frequency_response(axis: int, omegas: list[float], *, U0: float = 1.5,
                             amplitude: float = 2.0, h: float = 0.1,
                             vehicle: Remus100 | None = None,
                             design: tuple[np.ndarray, np.ndarray] | None = None
                             ) -> list[dict[str, Any]]:
    """Gain (m/s per N) and phase (rad) of the velocity over ground per NED force, of the
    nonlinear vehicle and of the linear model, at each frequency (rad/s).

    Parameters
    ----------
    axis : int
        0 along track (north), 1 cross track (east), 2 vertical (down).
    omegas : list[float]
        Frequencies, rad/s.
    U0 : float, optional
        Trim speed north, m/s.
    amplitude : float, optional
        Force amplitude, N.
    h : float, optional
        Step, s (one RK4 sub-step).
    vehicle : Remus100, optional
        The vehicle's data (default: the published REMUS 100).
    design : (M, D), optional
        The linear design model per NED axis (kg, kg/s; default ``remus100`` at U0).

    Returns
    -------
    list[dict[str, Any]]
        Per frequency: omega, gain and phase of both, their ratio and difference.
    """
    if design is None:
        lin = remus100(cruise_speed=U0)
        M, D = np.array(lin.parameters["total_mass"]), np.array(lin.parameters["damping"])
    else:
        M, D = (np.asarray(a, float) for a in design)
    vehicle = vehicle or Remus100()
    p, g = kernel.pack(vehicle), kernel.pack_gains(AutopilotGains())
    current = np.zeros(3)
    out = []
    for w in omegas:
        x = np.zeros(STATE_SIZE)
        x[6], x[14] = U0, 1525.0 * U0 / 2.55
        v_ref, integ, cmd = x[6:9].copy(), np.zeros(2), np.zeros(3)
        T = 2.0 * math.pi / w
        n = round(3.0 * T / h)
        t = np.arange(n) * h
        vel = np.empty(n)
        F = np.zeros(3)
        for k in range(n):
            F[:] = (D[0] * U0, 0.0, 0.0)
            F[axis] += amplitude * math.sin(w * t[k])
            vel[k] = (rotation_ned_body(*x[3:6]) @ x[6:9])[axis]
            kernel.force_commanded_step(p, g, x, v_ref, integ, F, current, M, D, h, 1, cmd)
        keep = t >= T
        resp = sine_response(t[keep], vel[keep], w, amplitude)
        gain, phase = abs(resp), math.atan2(resp.imag, resp.real)
        G = 1.0 / complex(D[axis], M[axis] * w)
        out.append({"omega": w, "gain": gain, "phase": phase, "linear_gain": abs(G),
                    "linear_phase": math.atan2(G.imag, G.real),
                    "gain_ratio": gain / abs(G),
                    "phase_difference": (phase - math.atan2(G.imag, G.real) + math.pi)
                    % (2.0 * math.pi) - math.pi})
    return out


def fit_first_order(axes: list[int], omegas: tuple[float, ...] = FIT_OMEGAS, *,
                    U0: float = 1.5, h: float = 0.05) -> tuple[float, float]:
    """(M, D): the first-order model G_f = 1 / (M j w + D) (kg, kg/s) closest to the
    nonlinear vehicle's velocity per force G on ``axes`` (stacked) in relative error,
    sum |G - G_f|^2 / |G|^2 = sum |1/G - (D + j w M)|^2 / |D + j w M|^2, by
    Sanathanan-Koerner iteration: linear least squares on the inverse response, each pass
    weighted by the previous pass's 1 / |D + j w M| (:func:`force_frequency_response`;
    :func:`plant_model.first_order_fit.fit_first_order_response`)."""
    G, om = [], []
    for axis in axes:
        for r in force_frequency_response(axis, list(omegas), U0=U0, h=h):
            G.append(r["gain"] * complex(math.cos(r["phase"]), math.sin(r["phase"])))
            om.append(r["omega"])
    return fit_first_order_response(np.array(om), np.array(G))


#: the design model is valid where the vehicle's velocity per force stays within this
#: phase (rad) and this gain ratio (1/x to x) of it, on every axis
VALID_PHASE = math.radians(20.0)
VALID_GAIN = 1.25


def valid_band(vehicle: Remus100, M: np.ndarray, D: np.ndarray, U0: float, *,
               lo: float = 0.02, hi: float = 2.0, rel_tol: float = 0.02) -> float:
    """The highest frequency (rad/s) up to which the nonlinear vehicle behind the force
    interface responds like its linear design model (M, D per NED axis) on every axis:
    |phase difference| <= :data:`VALID_PHASE` and the gain ratio within
    [1 / VALID_GAIN, VALID_GAIN] (:func:`force_frequency_response` at trim speed U0).
    Eight frequencies from ``lo`` to ``hi`` (geometric) find the first that fails, then
    bisection on log w narrows the edge to ``rel_tol``.

    Raises
    ------
    ValueError
        If the model is not valid even at ``lo``.
    """
    def ok(w: float) -> bool:
        for axis in (0, 1, 2):
            (r,) = force_frequency_response(axis, [w], U0=U0, h=0.05, vehicle=vehicle,
                                            design=(M, D))
            if abs(r["phase_difference"]) > VALID_PHASE or not (
                    1.0 / VALID_GAIN <= r["gain_ratio"] <= VALID_GAIN):
                return False
        return True

    grid = np.geomspace(lo, hi, 8)
    if not ok(float(grid[0])):
        raise ValueError(f"the linear design model is not valid even at {lo:g} rad/s")
    good, bad = float(grid[0]), None
    for w in grid[1:]:
        if not ok(float(w)):
            bad = float(w)
            break
        good = float(w)
    if bad is None:
        return good
    while bad / good > 1.0 + rel_tol:
        mid = math.sqrt(good * bad)
        good, bad = (mid, bad) if ok(mid) else (good, mid)
    return good

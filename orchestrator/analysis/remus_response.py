"""Frequency responses of the nonlinear REMUS 100 behind the force interface against the
linear ``remus100`` (issue "A nonlinear 6-DOF REMUS 100", in progress).

At a trim (straight and level at ``U0`` m/s north), a sinusoidal NED force of amplitude A
(N) on one axis (0 along track, 1 cross track, 2 vertical) is added to the trim force;
after one period to settle, the velocity over ground on that axis is fitted over two
periods by least squares to c + a sin(w t) + b cos(w t). The linear model's velocity per
force is 1 / (M_a j w + D_a) (plant_model.vehicles.remus100 at cruise speed U0).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from plant_model.remus100_6dof import STATE_SIZE, Remus100
from plant_model.remus100_autopilot import ForceCommandedRemus
from plant_model.vehicles import remus100

__all__ = ["force_frequency_response"]


def force_frequency_response(axis: int, omegas: list[float], *, U0: float = 1.5,
                             amplitude: float = 2.0, h: float = 0.1) -> list[dict[str, Any]]:
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

    Returns
    -------
    list[dict[str, Any]]
        Per frequency: omega, gain and phase of both, their ratio and difference.
    """
    lin = remus100(cruise_speed=U0)
    M, D = np.array(lin.parameters["total_mass"]), np.array(lin.parameters["damping"])
    out = []
    for w in omegas:
        x0 = np.zeros(STATE_SIZE)
        x0[6], x0[14] = U0, 1525.0 * U0 / 2.55
        veh = ForceCommandedRemus(Remus100(), M, D, x0)
        T = 2.0 * math.pi / w
        n = round(3.0 * T / h)
        t = np.arange(n) * h
        vel = np.empty(n)
        for k in range(n):
            F = np.array([D[0] * U0, 0.0, 0.0])
            F[axis] += amplitude * math.sin(w * t[k])
            vel[k] = veh.ned_state[3 + axis]
            veh.step(F, h, 1)
        keep = t >= T
        X = np.column_stack([np.ones(keep.sum()), np.sin(w * t[keep]), np.cos(w * t[keep])])
        _, a, b = np.linalg.lstsq(X, vel[keep], rcond=None)[0]
        gain, phase = math.hypot(a, b) / amplitude, math.atan2(b, a)
        G = 1.0 / complex(D[axis], M[axis] * w)
        out.append({"omega": w, "gain": gain, "phase": phase, "linear_gain": abs(G),
                    "linear_phase": math.atan2(G.imag, G.real),
                    "gain_ratio": gain / abs(G),
                    "phase_difference": (phase - math.atan2(G.imag, G.real) + math.pi)
                    % (2.0 * math.pi) - math.pi})
    return out

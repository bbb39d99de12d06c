"""Guidance: the formation controller's NED force turned into the set-points a vehicle
stack takes (speed through water, course, depth and their rates).

The controller is designed on a linear model whose velocity through the water obeys, per
NED axis i (M_i total mass, kg; D_i linear damping, kg/s; u_i the commanded force, N),

    v_i' = (u_i - D_i v_i) / M_i                                     (m/s^2)

Its solution over a step h with u held (exact; a_i = exp(-D_i h / M_i)):

    v_i(t + h) = a_i v_i(t) + (1 - a_i) u_i / D_i                    (m/s)
    int_t^{t+h} v_i dt = (u_i / D_i) h + (v_i(t) - u_i / D_i) (M_i / D_i) (1 - a_i)   (m)

as :class:`plant_model.remus100.autopilot.ForceCommandedRemus` uses it behind the
nonlinear REMUS 100. From v = v_ref = [v_N, v_E, v_D] the set-points are

    speed     U_d   = |v|                                  (m/s, through the water)
    course    chi_d = atan2(v_E, v_N)                      (rad; held below U_min, below)
    depth     z_d   = z_d(0) + int_0^t v_D dt              (m, positive down)
    rates     U_d'  = v . v' / |v|                         (m/s^2; 0 at |v| <= U_min)
              chi_d' = (v_N v_E' - v_E v_N') / (v_N^2 + v_E^2)   (rad/s; 0 below U_min)
              z_d'  = v_D                                  (m/s)

The course is not defined when the horizontal speed |v_h| = hypot(v_N, v_E) is at or
below U_min: the last defined course is held (initially the parameter course0).

The depth set-point is the design model's own depth, integrated from the parameter
``depth0`` (the vehicle's depth at the start), not reset from a measured depth: a vehicle
stack's depth autopilot expects a smooth set-point with its rate as feedforward, and a
position fix (acoustic, metres of noise, every few seconds) would carry its noise and its
jumps into the set-point. The formation controller closes the loop on the measured
position: a depth error makes it command a vertical force, which moves v_D and so z_d.

Everything here is a plain function over numpy arrays; no FMI.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["SETPOINT_NAMES", "check_mass_damping", "depth_increment", "reference_rate",
           "reference_step", "setpoints"]

#: the set-points, in the order :func:`setpoints` returns them
SETPOINT_NAMES = ("speed", "course", "depth", "speed_rate", "course_rate", "depth_rate")


def check_mass_damping(M: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """M (kg) and D (kg/s) as float arrays of 3, each finite and positive.

    Raises
    ------
    ValueError
        Naming the first element that is not (``M[2] = -1`` in FMI structured names).
    """
    out = []
    for name, arr in (("M", M), ("D", D)):
        a = np.asarray(arr, dtype=float).reshape(-1)
        if a.size != 3:
            raise ValueError(f"{name} must have 3 elements (N, E, D), got {a.size}")
        for i, v in enumerate(a):
            if not (math.isfinite(v) and v > 0.0):
                unit = "kg" if name == "M" else "kg/s"
                raise ValueError(f"parameter {name}[{i + 1}] = {v} must be a positive "
                                 f"finite number ({unit})")
        out.append(a)
    return out[0], out[1]


def reference_rate(v: np.ndarray, u: np.ndarray, M: np.ndarray, D: np.ndarray) -> np.ndarray:
    """v' = (u - D v) / M per NED axis (m/s^2) for v (m/s), u (N), M (kg), D (kg/s)."""
    return (np.asarray(u, dtype=float) - D * v) / M


def reference_step(v: np.ndarray, u: np.ndarray, M: np.ndarray, D: np.ndarray,
                   h: float) -> np.ndarray:
    """v(t + h) = a v + (1 - a) u / D, a = exp(-D h / M): the exact step with u held (m/s)."""
    a = np.exp(-D * h / M)
    return a * v + (1.0 - a) * np.asarray(u, dtype=float) / D


def depth_increment(v_down: float, u_down: float, M_down: float, D_down: float,
                    h: float) -> float:
    """int_t^{t+h} v_D dt (m), exact with u_D held: (u/D) h + (v - u/D) (M/D) (1 - a)."""
    tau = M_down / D_down
    v_inf = u_down / D_down
    return v_inf * h + (v_down - v_inf) * tau * (-math.expm1(-h / tau))


def setpoints(v: np.ndarray, u: np.ndarray, M: np.ndarray, D: np.ndarray, depth: float,
              held_course: float, U_min: float) -> np.ndarray:
    """[speed (m/s), course (rad), depth (m), speed rate (m/s^2), course rate (rad/s),
    depth rate (m/s)] from the reference velocity v (m/s, NED, through the water), the
    force u (N) held from now, the depth set-point (m) and the course held below U_min
    (rad) (module docstring)."""
    vd = reference_rate(v, u, M, D)
    U = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    h2 = v[0] * v[0] + v[1] * v[1]
    defined = math.sqrt(h2) > U_min
    course = math.atan2(v[1], v[0]) if defined else held_course
    course_rate = (v[0] * vd[1] - v[1] * vd[0]) / h2 if defined else 0.0
    speed_rate = float(v @ vd) / U if U > U_min else 0.0
    return np.array([U, course, depth, speed_rate, course_rate, v[2]])

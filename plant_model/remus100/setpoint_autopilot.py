"""Inner loops on set-points: speed through water, course and depth (and their rates) to
propeller rpm, rudder and stern-plane angles, from the vehicle's measured velocity through
the water (body axes), attitude, body rates and depth.

The loops of :func:`plant_model.remus100.autopilot.autopilot_command` (its gains,
:class:`~plant_model.remus100.autopilot.AutopilotGains`), with a depth loop on top of the
flight-path loop and the course rate as yaw-rate feedforward. With v_w = R(Theta) nu_w the
measured velocity through the water in NED (m/s), U = |v_w|, chi = atan2(v_wE, v_wN) and
gamma = atan2(-v_wD, |v_wh|) (chi, gamma replaced by psi, theta at or below U_min):

- speed:  n = n_max U_d / U_max + K_u (U_d - U) + K_ui int (U_d - U) dt            (rpm)
- course: delta_r = K_chi wrap(chi_d - chi) + K_r (chi_d' - r)                       (rad)
- depth:  w_d = z_d' + K_z (z_d - z) (m/s, positive down),
          U_h = sqrt(max(U_d^2 - z_d'^2, 0)) (m/s),
          gamma_d = clip(atan2(-w_d, U_h), -gamma_max, gamma_max)  (0 at U_d <= U_min)
- flight path: theta_d = gamma_d + K_gamma (gamma_d - gamma) + K_gi int (gamma_d - gamma) dt,
          delta_s = K_theta (theta - theta_d) + K_q q  (rad; positive: nose down)

With K_z = 0 and chi_d' = 0 these are autopilot_command's loops for the reference velocity
v_ref = U_d [cos(gamma_d) cos(chi_d), cos(gamma_d) sin(chi_d), -sin(gamma_d)].

Anti-windup by conditional integration, as autopilot_command: an integral holds while its
actuator's command is at or beyond its limit (n_max, delta_max) in the direction its error
pushes. The commands sent are clipped to the limits. Units: m, m/s, rad, rad/s, rpm, s.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .autopilot import AutopilotGains, wrap
from .rigid_body import rotation_ned_body

__all__ = ["DepthLoop", "limit_command", "setpoint_command"]


@dataclass(frozen=True)
class DepthLoop:
    """The depth loop's gains (on top of :class:`AutopilotGains`' flight-path loop)."""

    K_z: float = 0.1                         #: 1/s: m/s of vertical speed per m of depth error
    gamma_max: float = math.radians(30.0)    #: rad: the steepest flight path commanded


def setpoint_command(g: AutopilotGains, dl: DepthLoop, setpoint: np.ndarray,
                     velocity: np.ndarray, attitude: np.ndarray, rates: np.ndarray,
                     depth: float, integrals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The unclipped command [delta_r (rad), delta_s (rad), n (rpm)] and the errors to
    integrate next, [U_d - U (m/s), gamma_d - gamma (rad)], each 0 while its actuator is
    saturated in its direction (module docstring).

    Parameters
    ----------
    g, dl : AutopilotGains, DepthLoop
        The gains.
    setpoint : np.ndarray
        [U_d (m/s), chi_d (rad), z_d (m), U_d' (m/s^2), chi_d' (rad/s), z_d' (m/s)].
    velocity : np.ndarray
        Velocity through the water in body axes [u, v, w], m/s.
    attitude : np.ndarray
        [phi, theta, psi], rad.
    rates : np.ndarray
        [p, q, r], rad/s.
    depth : float
        Measured depth, m.
    integrals : np.ndarray
        [int (U_d - U) dt (m), int (gamma_d - gamma) dt (rad s)].
    """
    U_d, chi_d, z_d, _, chi_rate, z_rate = (float(s) for s in setpoint)
    v_w = rotation_ned_body(*attitude) @ np.asarray(velocity, dtype=float)
    U = float(np.linalg.norm(v_w))
    h = math.hypot(v_w[0], v_w[1])
    n = g.n_max * U_d / g.U_max + g.K_u * (U_d - U) + g.K_ui * integrals[0]
    chi = math.atan2(v_w[1], v_w[0]) if h > g.U_min else float(attitude[2])
    delta_r = g.K_chi * wrap(chi_d - chi) + g.K_r * (chi_rate - float(rates[2]))
    if U_d > g.U_min:
        w_d = z_rate + dl.K_z * (z_d - depth)
        U_h = math.sqrt(max(U_d * U_d - z_rate * z_rate, 0.0))
        gamma_d = min(max(math.atan2(-w_d, U_h), -dl.gamma_max), dl.gamma_max)
    else:
        gamma_d = 0.0
    gamma = math.atan2(-v_w[2], h) if U > g.U_min else float(attitude[1])
    theta_d = gamma_d + g.K_gamma * (gamma_d - gamma) + g.K_gi * integrals[1]
    delta_s = g.K_theta * (float(attitude[1]) - theta_d) + g.K_q * float(rates[1])
    e_u = 0.0 if (n >= g.n_max and U_d > U) or (n <= -g.n_max and U_d < U) else U_d - U
    e_g = gamma_d - gamma
    if (delta_s >= g.delta_max and e_g < 0.0) or (delta_s <= -g.delta_max and e_g > 0.0):
        e_g = 0.0
    return np.array([delta_r, delta_s, n]), np.array([e_u, e_g])


def limit_command(g: AutopilotGains, command: np.ndarray) -> tuple[np.ndarray, bool]:
    """The command clipped to [-delta_max, delta_max] (fins, rad) and [-n_max, n_max]
    (rpm), and whether any element was at or beyond its limit."""
    lim = np.array([g.delta_max, g.delta_max, g.n_max])
    return np.clip(command, -lim, lim), bool(np.any(np.abs(command) >= lim))

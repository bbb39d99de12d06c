"""Inner loops of the nonlinear REMUS 100 (in progress): a commanded NED velocity over
ground turned into propeller rpm, rudder and stern-plane angles.

The formation controller commands a force in NED (N), the linear ``remus100`` model's
input. The vehicle's inner loops track the velocity that force would give that model,
v_ref' = (F - D_a v_ref) / M_a (plant_model.vehicles), with three autopilots on the
velocity over ground v_g = R(Theta) nu (a Doppler velocity log with bottom lock):

- speed:  n = n_max U_d / U_max + K_u (U_d - U) + K_ui int (U_d - U) dt        (rpm)
- course: delta_r = K_chi wrap(chi_d - chi) - K_r r                             (rad)
  with chi = atan2(v_gE, v_gN): the vehicle crabs into a cross current
- flight path: theta_d = gamma_d + K_gamma (gamma_d - gamma) + K_gi int (gamma_d - gamma),
  gamma = atan2(-v_gD, |v_gh|) (the integral finds the angle of attack a climb needs);
  delta_s = K_theta (theta - theta_d) + K_q q   (positive stern plane: nose down)

Anti-windup by conditional integration: an integral holds while its actuator's command is
at or beyond the limit in the direction the error pushes (n_max, delta_max).

Below ``U_min`` the course is not defined: the heading is held. Units: m/s, rad, rpm, s.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .dynamics import Remus100
from .rigid_body import rotation_ned_body

__all__ = ["AutopilotGains", "ForceCommandedRemus", "autopilot_command", "wrap"]


@dataclass(frozen=True)
class AutopilotGains:
    """Gains of the three loops (tuned on plant_model.remus100.dynamics with the 2025 data;
    docs/remus100-6dof.md)."""

    U_max: float = 2.55        #: m/s, the model's speed at n_max (1525 rpm)
    n_max: float = Remus100.n_max          #: rpm, the vehicle's limit
    K_u: float = 300.0         #: rpm per m/s
    K_ui: float = 30.0         #: rpm per m
    K_chi: float = 2.0         #: rad of rudder per rad of course error
    K_r: float = 1.0           #: rad of rudder per rad/s of yaw rate
    K_gamma: float = 1.0
    K_gi: float = 0.2          #: 1/s
    K_theta: float = 2.0       #: rad of stern plane per rad of pitch error
    K_q: float = 1.0           #: rad of stern plane per rad/s of pitch rate
    U_min: float = 0.1         #: m/s: below it the heading is held
    delta_max: float = Remus100.delta_max  #: rad: the fin limit (anti-windup)


def wrap(a: float) -> float:
    """An angle in [-pi, pi) (rad)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def autopilot_command(g: AutopilotGains, x: np.ndarray, v_ref: np.ndarray,
                      integrals: np.ndarray, current: np.ndarray | None = None
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The actuator command [delta_r, delta_s (rad), n (rpm)] for the vehicle state x
    (plant_model.remus100.dynamics), the NED velocity reference v_ref (m/s) and the loops'
    integrals [int (U_d - U) dt (m), int (gamma_d - gamma) dt (rad s)]; and the errors to
    integrate next, [U_d - U (m/s), gamma_d - gamma (rad)] (module docstring). With
    ``current`` (NED, m/s) the loops track the velocity through the water instead of over
    ground (a DVL's water track): v_g - current."""
    eta, nu = x[:6], x[6:12]
    v_g = rotation_ned_body(*eta[3:6]) @ nu[:3]
    if current is not None:
        v_g = v_g - np.asarray(current, dtype=float)
    U, U_d = float(np.linalg.norm(v_g)), float(np.linalg.norm(v_ref))
    n = g.n_max * U_d / g.U_max + g.K_u * (U_d - U) + g.K_ui * integrals[0]
    h_ref = math.hypot(v_ref[0], v_ref[1])
    chi_d = math.atan2(v_ref[1], v_ref[0]) if h_ref > g.U_min else eta[5]
    chi = math.atan2(v_g[1], v_g[0]) if math.hypot(v_g[0], v_g[1]) > g.U_min else eta[5]
    delta_r = g.K_chi * wrap(chi_d - chi) - g.K_r * nu[5]
    gamma_d = math.atan2(-v_ref[2], h_ref) if U_d > g.U_min else 0.0
    gamma = math.atan2(-v_g[2], math.hypot(v_g[0], v_g[1])) if U > g.U_min else eta[4]
    theta_d = gamma_d + g.K_gamma * (gamma_d - gamma) + g.K_gi * integrals[1]
    delta_s = g.K_theta * (eta[4] - theta_d) + g.K_q * nu[4]
    # anti-windup: an integral stops while its actuator is saturated in its direction
    e_u = 0.0 if (n >= g.n_max and U_d > U) or (n <= -g.n_max and U_d < U) else U_d - U
    e_g = gamma_d - gamma
    if (delta_s >= g.delta_max and e_g < 0.0) or (delta_s <= -g.delta_max and e_g > 0.0):
        e_g = 0.0
    return np.array([delta_r, delta_s, n]), np.array([e_u, e_g])


class ForceCommandedRemus:
    """The nonlinear REMUS 100 behind the linear ``remus100`` interface: the NED force F
    (N) the formation controller commands drives the linear model's velocity through the
    water, v_ref' = (F - D_a v_ref) / M_a (sampled exactly over the step), which the
    autopilots track through the water; the current then carries the vehicle as it carries
    the linear model. ``ned_state`` is the linear model's state [n, e, d, v_n, v_e, v_d]
    (m, m/s) over ground.

    Parameters
    ----------
    vehicle : Remus100
        The 6-DOF vehicle (its ``current``).
    M, D : np.ndarray
        The linear model's total mass (kg) and damping (kg/s) per NED axis
        (``remus100().parameters["total_mass"]``, ``["damping"]``).
    x0 : np.ndarray
        Initial 6-DOF state (plant_model.remus100.dynamics).
    gains : AutopilotGains, optional
        The loops' gains.
    """

    def __init__(self, vehicle: Any, M: np.ndarray, D: np.ndarray, x0: np.ndarray,
                 gains: AutopilotGains | None = None):
        self.vehicle, self.gains = vehicle, gains or AutopilotGains()
        self.M, self.D = np.asarray(M, dtype=float), np.asarray(D, dtype=float)
        self.x = np.array(x0, dtype=float)
        current = np.asarray(vehicle.current, dtype=float)
        self.v_ref = rotation_ned_body(*self.x[3:6]) @ self.x[6:9] - current
        self.integrals = np.zeros(2)
        self.command = np.zeros(3)

    def step(self, F: np.ndarray, h: float, substeps: int) -> None:
        """One communication step h (s) with the force F (N, NED) held."""
        from .dynamics import step as vehicle_step
        current = np.asarray(self.vehicle.current, dtype=float)
        self.command, err = autopilot_command(self.gains, self.x, self.v_ref, self.integrals,
                                              current)
        self.x = vehicle_step(self.vehicle, self.x, self.command, h, substeps)
        self.integrals = self.integrals + err * h
        a = np.exp(-self.D * h / self.M)
        self.v_ref = a * self.v_ref + (1.0 - a) * np.asarray(F, dtype=float) / self.D

    @property
    def ned_state(self) -> np.ndarray:
        """[n, e, d, v_n, v_e, v_d] over ground (m, m/s)."""
        return np.concatenate([self.x[:3], rotation_ned_body(*self.x[3:6]) @ self.x[6:9]])

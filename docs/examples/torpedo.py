"""A plain REMUS-like torpedo AUV for the example hosts: the host's own vehicle, written
here with numpy only (nothing from the auv-cosim project).

A reduced 6-DOF model: roll is left out (phi = p = 0: a REMUS is roll-stable), so five
degrees of freedom remain, surge u, sway v, heave w, pitch q, yaw r, in body axes through
the water. The equations are Prestero's (T. Prestero, "Verification of a six-degree of
freedom simulation model for the REMUS autonomous underwater vehicle", MSc thesis,
MIT/WHOI, 2001, chapter 4), without roll and without the CG's offset in the inertia:

    (m - X_u') u' = X_uu u|u| + T + X_wq w q + X_qq q^2 + X_vr v r + X_rr r^2
                    + m (v r - w q) - (W - B) sin(theta)
    (m - Y_v') v' - Y_r' r' = Y_vv v|v| + Y_rr r|r| + Y_uv u v + Y_ur u r
                    + Y_uudr u^2 delta_r - m u r
    (m - Z_w') w' - Z_q' q' = Z_ww w|w| + Z_qq q|q| + Z_uw u w + Z_uq u q
                    + Z_uuds u^2 delta_s + m u q + (W - B) cos(theta)
    -M_w' w' + (I_yy - M_q') q' = M_ww w|w| + M_qq q|q| + M_uw u w + M_uq u q
                    + M_uuds u^2 delta_s - z_g W sin(theta)
    -N_v' v' + (I_zz - N_r') r' = N_vv v|v| + N_rr r|r| + N_uv u v + N_ur u r
                    + N_uudr u^2 delta_r

    n' = cos(psi) cos(theta) u - sin(psi) v + cos(psi) sin(theta) w + c_N
    e' = sin(psi) cos(theta) u + cos(psi) v + sin(psi) sin(theta) w + c_E
    d' = -sin(theta) u + cos(theta) w,   theta' = q,   psi' = r / cos(theta)

with a constant ocean current c (NED, m/s) and the velocities relative to the water.
The coefficients are Prestero's (most of them his estimates, some revised by Fodrea), as
tabulated in R. Hall and S. Anstee, "Trim calculation methods for a dynamical model of
the REMUS 100 autonomous underwater vehicle", DSTO-TR-2576, 2011. Units: kg, m, s, rad.
Two choices of ours: the propeller thrust T = k_T n|n| is scaled so that 1525 rpm gives
2.5 m/s in still water (T. I. Fossen's remus100.py: "the maximum speed of 2.5 m/s is
obtained when the propeller runs at 1525 rpm"); the fins (15 deg, 0.1 s lag, as
Fossen's 2024 revision) and the propeller (0.1 s lag, assumed) are first-order actuators
with limits. Signs: a positive rudder turns to starboard (Prestero's positive rudder
turns to port, so his Y_uudr and N_uudr change sign here), a positive stern plane
pitches the nose down, as Prestero's.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

RHO, G = 1030.0, 9.81
m, W = 30.48, 30.48 * 9.81
B = W + 0.75 * 4.44822162            # N: 0.75 lbf buoyant
z_g, I_yy, I_zz = 0.0196, 3.45, 3.45
X_ud, Y_vd, Y_rd, Z_wd, Z_qd = -0.93, -35.5, 1.93, -35.5, -1.93
M_wd, M_qd, N_vd, N_rd = -1.93, -4.88, 1.93, -4.88
X_uu = -0.5 * RHO * 0.2 * 0.0285     # kg/m: C_d 0.2 on the frontal area 0.0285 m^2
X_wq, X_qq, X_vr, X_rr = -35.5, -1.93, 35.5, -1.93
Y_vv, Y_rr, Y_uv, Y_ur, Y_uudr = -1310.0, 0.632, -28.6, 5.22, -9.64
Z_ww, Z_qq, Z_uw, Z_uq, Z_uuds = -1310.0, -0.632, -28.6, -5.22, -9.64
M_ww, M_qq, M_uw, M_uq, M_uuds = 3.18, -188.0, 24.0, -2.0, -6.15
N_vv, N_rr, N_uv, N_ur, N_uudr = -3.18, -94.0, -24.0, -2.0, 6.15
N_MAX, DELTA_MAX, T_ACT = 1525.0, math.radians(15.0), 0.1
K_T = -X_uu * (2.5 / N_MAX) ** 2     # N/rpm^2: 2.5 m/s at 1525 rpm

MASS = np.array([[m - X_ud, 0, 0, 0, 0],
                 [0, m - Y_vd, 0, 0, -Y_rd],
                 [0, 0, m - Z_wd, -Z_qd, 0],
                 [0, 0, -M_wd, I_yy - M_qd, 0],
                 [0, -N_vd, 0, 0, I_zz - N_rd]])
MASS_INV = np.linalg.inv(MASS)


def derivative(s: np.ndarray, command: np.ndarray, current: np.ndarray) -> np.ndarray:
    """ds/dt of s = [n, e, d, theta, psi, u, v, w, q, r, delta_r, delta_s, rpm] for the
    command [delta_r, delta_s (rad), rpm] and the current (NED, m/s)."""
    _, _, _, th, ps, u, v, w, q, r, dr, ds, n = s
    tau = np.array([
        X_uu * u * abs(u) + K_T * n * abs(n) + X_wq * w * q + X_qq * q * q + X_vr * v * r
        + X_rr * r * r + m * (v * r - w * q) - (W - B) * math.sin(th),
        Y_vv * v * abs(v) + Y_rr * r * abs(r) + Y_uv * u * v + Y_ur * u * r
        + Y_uudr * u * u * dr - m * u * r,
        Z_ww * w * abs(w) + Z_qq * q * abs(q) + Z_uw * u * w + Z_uq * u * q
        + Z_uuds * u * u * ds + m * u * q + (W - B) * math.cos(th),
        M_ww * w * abs(w) + M_qq * q * abs(q) + M_uw * u * w + M_uq * u * q
        + M_uuds * u * u * ds - z_g * W * math.sin(th),
        N_vv * v * abs(v) + N_rr * r * abs(r) + N_uv * u * v + N_ur * u * r
        + N_uudr * u * u * dr])
    ct, st, cp, sp = math.cos(th), math.sin(th), math.cos(ps), math.sin(ps)
    lim = np.array([DELTA_MAX, DELTA_MAX, N_MAX])
    act = (np.clip(command, -lim, lim) - s[10:13]) / T_ACT
    return np.concatenate([
        [cp * ct * u - sp * v + cp * st * w + current[0],
         sp * ct * u + cp * v + sp * st * w + current[1],
         -st * u + ct * w + current[2], q, r / ct],
        MASS_INV @ tau, act])


class Torpedo:
    """The vehicle: RK4 sub-steps of at most 0.025 s, the command held over a step."""

    n_max, delta_max = N_MAX, DELTA_MAX

    def __init__(self, position: Sequence[float], velocity_water: Sequence[float],
                 current: Sequence[float], fix_sigma: float = 0.5, seed: int = 0) -> None:
        """Start at ``position`` (NED, m) moving at ``velocity_water`` (NED, m/s, through
        the water; the nose along it), in a constant ``current`` (NED, m/s); position
        fixes with ``fix_sigma`` (m) of Gaussian noise."""
        v = np.asarray(velocity_water, float)
        U = float(np.linalg.norm(v))
        self.s = np.zeros(13)
        self.s[:3] = position
        self.s[3] = math.atan2(-v[2], math.hypot(v[0], v[1]))
        self.s[4] = math.atan2(v[1], v[0])
        self.s[5], self.s[12] = U, N_MAX * U / 2.5
        self.current = np.asarray(current, float)
        self.fix_sigma, self.rng = fix_sigma, np.random.default_rng(seed)

    def step(self, command: Sequence[float], h: float) -> None:
        """Advance h seconds with the command [delta_r, delta_s (rad), rpm] held."""
        c = np.asarray(command, float)
        k = max(1, math.ceil(h / 0.025 - 1e-9))
        dt = h / k
        for _ in range(k):
            s = self.s
            k1 = derivative(s, c, self.current)
            k2 = derivative(s + 0.5 * dt * k1, c, self.current)
            k3 = derivative(s + 0.5 * dt * k2, c, self.current)
            k4 = derivative(s + dt * k3, c, self.current)
            self.s = s + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)

    @property
    def position(self) -> np.ndarray:
        """True NED position, m."""
        return self.s[:3].copy()

    def fix(self) -> list[float]:
        """A position fix: the NED position plus noise, m."""
        return list(self.s[:3] + self.rng.normal(0.0, self.fix_sigma, 3))

    def sensors(self) -> list[float]:
        """[u, v, w (m/s, body, through the water), phi, theta, psi (rad), p, q, r (rad/s),
        depth (m)]: what a DVL's water track, an AHRS and a depth cell report."""
        s = self.s
        return [s[5], s[6], s[7], 0.0, s[3], s[4], 0.0, s[8], s[9], s[2]]


def wrap(a: float) -> float:
    """An angle in [-pi, pi), rad."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


class PidAutopilot:
    """The host's own simple autopilot (speed, heading, depth), taking only set-points:

        rpm     = N_MAX U_d / 2.5 + 300 (U_d - u) + 30 int (U_d - u) dt
        rudder  = 1.0 wrap(psi_d - psi) - 1.0 r                (heading := course set-point)
        theta_d = clip(0.3 (d - d_d) + 0.02 int (d - d_d) dt, +-20 deg)
        stern   = 2.0 (theta - theta_d) + 1.0 q

    integrals frozen while their actuator is at its limit (units rpm, rad, m, s)."""

    def __init__(self) -> None:
        self.i_u = self.i_d = 0.0

    def command(self, setpoint: Sequence[float], sensors: Sequence[float],
                h: float) -> list[float]:
        """[rudder, stern (rad), rpm] for [U_d (m/s), psi_d (rad), d_d (m)] and
        :meth:`Torpedo.sensors`; the integrals advance by h (s)."""
        U_d, psi_d, d_d = setpoint
        u, theta, psi, q, r, d = (sensors[i] for i in (0, 4, 5, 7, 8, 9))
        rpm = N_MAX * U_d / 2.5 + 300.0 * (U_d - u) + 30.0 * self.i_u
        rudder = wrap(psi_d - psi) - r
        lim = math.radians(20.0)
        theta_d = min(max(0.3 * (d - d_d) + 0.02 * self.i_d, -lim), lim)
        stern = 2.0 * (theta - theta_d) + q
        if abs(rpm) < N_MAX:
            self.i_u += (U_d - u) * h
        if abs(stern) < DELTA_MAX:
            self.i_d += (d - d_d) * h
        return [rudder, stern, rpm]

"""Six-degree-of-freedom rigid-body mathematics of a marine craft (Fossen's vectorial form).

NED position and Euler angles eta = [x, y, z, phi, theta, psi] (m, rad), body-fixed
velocities nu = [u, v, w, p, q, r] (m/s, rad/s), with the origin CO of the body frame on
the centreline. A vehicle obeys

    M nu_r' + C(nu_r) nu_r + D(nu_r) nu_r + g(eta) = tau,    eta' = J(eta) nu

with nu_r = nu - nu_c the velocity relative to an irrotational ocean current that is
constant in NED (its body-frame velocity nu_c = [R(Theta)' v_c; 0]), M = M_RB + M_A the
rigid-body and added mass, C the Coriolis-centripetal matrix of both (from M, skew
symmetric), D the damping, g the restoring forces and tau the actuators' forces and
moments (N, N m). For a constant current the rigid-body terms can be written in nu_r
(Fossen 2021, Property 10.1), which is the form used here.

Everything is a plain function over numpy arrays; no FMI, no vehicle data.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["coriolis_from_mass", "coriolis_times", "euler_kinematics", "quaternion_xyzw",
           "rigid_body_mass", "restoring_forces", "rk4_step", "rotation_ned_body", "skew"]


def skew(a: np.ndarray) -> np.ndarray:
    """S(a) with S(a) b = a x b (3 x 3, skew symmetric)."""
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def rotation_ned_body(phi: float, theta: float, psi: float) -> np.ndarray:
    """R(Theta): body-fixed to NED, zyx convention (yaw psi, pitch theta, roll phi), rad."""
    cf, sf, ct, st, cp, sp = (np.cos(phi), np.sin(phi), np.cos(theta), np.sin(theta),
                              np.cos(psi), np.sin(psi))
    return np.array([
        [cp * ct, -sp * cf + cp * st * sf, sp * sf + cp * cf * st],
        [sp * ct, cp * cf + sf * st * sp, -cp * sf + st * sp * cf],
        [-st, ct * sf, ct * cf]])


def quaternion_xyzw(attitude: np.ndarray) -> np.ndarray:
    """Unit quaternions [x, y, z, w] of R(Theta) (body to NED, zyx) for rows of Euler
    angles [phi, theta, psi] (rad), shape (..., 3) -> (..., 4)."""
    a = 0.5 * np.asarray(attitude, dtype=float)
    cr, sr = np.cos(a[..., 0]), np.sin(a[..., 0])
    cp, sp = np.cos(a[..., 1]), np.sin(a[..., 1])
    cy, sy = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack([sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
                     cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy], axis=-1)


def euler_kinematics(eta: np.ndarray) -> np.ndarray:
    """J(eta) = blkdiag(R(Theta), T(Theta)): eta' = J(eta) nu (6 x 6).

    T(Theta) maps body rates to Euler-angle rates; it is singular at theta = +-90 deg,
    which an AUV in level flight never reaches.
    """
    phi, theta, psi = eta[3], eta[4], eta[5]
    cf, sf, ct, tt = np.cos(phi), np.sin(phi), np.cos(theta), np.tan(theta)
    T = np.array([[1.0, sf * tt, cf * tt], [0.0, cf, -sf], [0.0, sf / ct, cf / ct]])
    J = np.zeros((6, 6))
    J[:3, :3] = rotation_ned_body(phi, theta, psi)
    J[3:, 3:] = T
    return J


def rigid_body_mass(m: float, r_g: np.ndarray, I_g: np.ndarray) -> np.ndarray:
    """M_RB about CO for a body of mass m (kg) whose centre of gravity is r_g (m, from CO)
    and whose inertia about the CG is I_g (kg m^2):

        M_RB = [[m I, -m S(r_g)], [m S(r_g), I_g - m S(r_g)^2]]
    """
    S = skew(np.asarray(r_g, dtype=float))
    M = np.zeros((6, 6))
    M[:3, :3] = m * np.eye(3)
    M[:3, 3:] = -m * S
    M[3:, :3] = m * S
    M[3:, 3:] = np.asarray(I_g, dtype=float) - m * S @ S
    return M


def coriolis_from_mass(M: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """C(nu) of a symmetric mass matrix M = [[M11, M12], [M21, M22]] (Fossen's m2c):

        C = [[0, -S(M11 nu1 + M12 nu2)], [-S(M11 nu1 + M12 nu2), -S(M21 nu1 + M22 nu2)]]

    skew symmetric, so nu' C(nu) nu = 0: the Coriolis and centripetal forces do no work.
    """
    Ms = 0.5 * (M + M.T)
    nu1, nu2 = nu[:3], nu[3:]
    a = Ms[:3, :3] @ nu1 + Ms[:3, 3:] @ nu2
    b = Ms[3:, :3] @ nu1 + Ms[3:, 3:] @ nu2
    C = np.zeros((6, 6))
    C[:3, 3:] = -skew(a)
    C[3:, :3] = -skew(a)
    C[3:, 3:] = -skew(b)
    return C


def coriolis_times(M: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """C(nu) nu of :func:`coriolis_from_mass` without forming C: with a = M11 nu1 + M12 nu2
    and b = M21 nu1 + M22 nu2, C(nu) nu = [nu2 x a; nu1 x a + nu2 x b] (a symmetric M)."""
    ab = M @ nu
    a, b = ab[:3], ab[3:]
    nu1, nu2 = nu[:3], nu[3:]
    return np.concatenate([np.cross(nu2, a), np.cross(nu1, a) + np.cross(nu2, b)])


def restoring_forces(eta: np.ndarray, W: float, B: float, r_g: np.ndarray,
                     r_b: np.ndarray) -> np.ndarray:
    """g(eta) of a submerged body: weight W and buoyancy B (N) acting at the centres of
    gravity r_g and buoyancy r_b (m, from CO), in body axes (Fossen 2021, eq. 4.6)."""
    phi, theta = eta[3], eta[4]
    sf, cf, st, ct = np.sin(phi), np.cos(phi), np.sin(theta), np.cos(theta)
    xg, yg, zg = r_g
    xb, yb, zb = r_b
    return np.array([
        (W - B) * st,
        -(W - B) * ct * sf,
        -(W - B) * ct * cf,
        -(yg * W - yb * B) * ct * cf + (zg * W - zb * B) * ct * sf,
        (zg * W - zb * B) * st + (xg * W - xb * B) * ct * cf,
        -(xg * W - xb * B) * ct * sf - (yg * W - yb * B) * st])


def rk4_step(f: Callable[[np.ndarray], np.ndarray], x: np.ndarray, dt: float) -> np.ndarray:
    """One classical fourth-order Runge-Kutta step of x' = f(x) over dt (s): local error
    O(dt^5), global O(dt^4)."""
    k1 = f(x)
    k2 = f(x + 0.5 * dt * k1)
    k3 = f(x + 0.5 * dt * k2)
    k4 = f(x + dt * k3)
    return x + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)

"""plant_model.remus100.rigid_body against independent facts: skew symmetry, energy conservation to
the integrator's order, rotation matrices, the parallel-axis theorem, righting moments."""
from __future__ import annotations

import numpy as np
import pytest

from plant_model.remus100.rigid_body import (
    coriolis_from_mass,
    coriolis_times,
    euler_kinematics,
    restoring_forces,
    rigid_body_mass,
    rk4_step,
    rotation_ned_body,
    skew,
)


def _mass(seed=0):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((3, 3))
    I_g = A @ A.T + 3.0 * np.eye(3)
    M = rigid_body_mass(30.0, np.array([0.01, -0.02, 0.05]), I_g)
    Ma = np.diag([1.5, 35.0, 35.0, 0.0, 4.0, 4.0])       # a slender body's added mass
    return M, M + Ma


def test_the_coriolis_matrix_is_skew_symmetric_and_does_no_work():
    M_rb, M = _mass()
    nu = np.random.default_rng(1).standard_normal(6)
    for mat in (M_rb, M):
        C = coriolis_from_mass(mat, nu)
        assert np.allclose(C, -C.T, atol=1e-14)
        assert abs(nu @ C @ nu) < 1e-12
        assert np.allclose(coriolis_times(mat, nu), C @ nu, rtol=1e-14, atol=1e-13)


def test_kinetic_energy_is_conserved_to_the_integrators_order():
    """M nu' = -C(nu) nu (no damping, restoring, current or forcing): the kinetic energy
    1/2 nu' M nu drifts only by the integration error, which falls at least 2^4 = 16 times
    when the sub-step is halved (RK4; about 2^4.7 measured at these steps)."""
    _, M = _mass(2)
    Minv = np.linalg.inv(M)
    nu0 = np.array([1.5, 0.2, -0.1, 0.3, -0.4, 0.5])

    def f(nu):
        return -Minv @ (coriolis_from_mass(M, nu) @ nu)

    def drift(dt, T=20.0):
        nu = nu0.copy()
        for _ in range(round(T / dt)):
            nu = rk4_step(f, nu, dt)
        return abs(0.5 * nu @ M @ nu - 0.5 * nu0 @ M @ nu0) / (0.5 * nu0 @ M @ nu0)

    d1, d2 = drift(0.05), drift(0.025)
    order = np.log2(d1 / d2)
    assert d1 < 1e-4 and 3.8 < order < 5.5, (d1, d2)


def test_rotations_are_orthonormal_and_the_kinematics_integrate_a_yaw_rate():
    R = rotation_ned_body(0.3, -0.2, 1.1)
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-15) and np.linalg.det(R) == pytest.approx(1)
    # body x-axis of a vehicle pitched up 0.2 rad points up: negative NED z
    assert rotation_ned_body(0.0, 0.2, 0.0)[2, 0] == pytest.approx(-np.sin(0.2))
    eta, nu, dt = np.zeros(6), np.array([1.0, 0, 0, 0, 0, 0.1]), 0.01
    for _ in range(1000):
        eta = rk4_step(lambda e: euler_kinematics(e) @ nu, eta, dt)
    # a circle of radius u / r = 10 m: after 10 s, psi = 1 rad
    assert eta[5] == pytest.approx(1.0, rel=1e-12)
    assert eta[0] == pytest.approx(10.0 * np.sin(1.0), rel=1e-9)
    assert eta[1] == pytest.approx(10.0 * (1.0 - np.cos(1.0)), rel=1e-9)


def test_the_rigid_body_mass_obeys_the_parallel_axis_theorem():
    I_g = np.diag([0.2, 3.0, 3.0])
    r_g = np.array([0.1, 0.0, 0.02])
    M = rigid_body_mass(30.0, r_g, I_g)
    assert np.allclose(M, M.T) and np.all(np.linalg.eigvalsh(M) > 0)
    want = I_g + 30.0 * (r_g @ r_g * np.eye(3) - np.outer(r_g, r_g))
    assert np.allclose(M[3:, 3:], want, atol=1e-14)
    assert np.allclose(M[:3, 3:] @ np.array([0, 0, 1.0]), -30.0 * skew(r_g)[:, 2])


def test_restoring_forces_right_a_rolled_and_pitched_vehicle():
    """Neutral buoyancy, CG 2 cm below CB: no net force, and the moments oppose a roll or a
    pitch (they enter the left-hand side: M nu' = ... - g)."""
    W = B = 300.0
    r_g, r_b = np.array([0.0, 0.0, 0.02]), np.zeros(3)
    g = restoring_forces(np.array([0, 0, 0, 0.1, 0.0, 0.0]), W, B, r_g, r_b)
    assert np.allclose(g[:3], 0.0) and g[3] > 0.0          # a positive roll is pushed back
    assert g[3] == pytest.approx(W * 0.02 * np.sin(0.1))
    g = restoring_forces(np.array([0, 0, 0, 0.0, 0.1, 0.0]), W, B, r_g, r_b)
    assert g[4] == pytest.approx(W * 0.02 * np.sin(0.1)) and g[4] > 0.0
    heavy = restoring_forces(np.zeros(6), W + 10.0, B, r_g, r_b)
    assert heavy[2] == pytest.approx(-10.0)       # -(W - B): the net weight is +z on the LHS


def test_the_quaternion_is_the_rotation_matrix():
    """quaternion_xyzw against scipy's Rotation of R(Theta) (body to NED)."""
    from scipy.spatial.transform import Rotation

    from plant_model.remus100.rigid_body import quaternion_xyzw, rotation_ned_body
    rng = np.random.default_rng(7)
    att = rng.uniform([-np.pi, -1.4, -np.pi], [np.pi, 1.4, np.pi], size=(50, 3))
    q = quaternion_xyzw(att)
    for a, qi in zip(att, q):
        R = Rotation.from_quat(qi).as_matrix()
        assert np.allclose(R, rotation_ned_body(*a), atol=1e-12)

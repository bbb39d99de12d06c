"""plant_model.remus100.dynamics against independent facts: the published speed at 1525 rpm,
energy conservation with every force off, the RK4 sub-step's convergence order, a
turning circle's geometry, and one-line errors for bad data."""
from __future__ import annotations

import math

import numpy as np
import pytest

from plant_model.linalg_checks import ModelError
from plant_model.remus100.dynamics import STATE_SIZE, Remus100, hull_mass, step
from plant_model.remus100.rigid_body import coriolis_from_mass, rk4_step

FULL = np.array([0.0, 0.0, 1525.0])


def test_the_hull_is_a_neutrally_buoyant_spheroid_of_about_31_kg():
    """m = 4/3 pi rho a b^2 = 31.0 kg for L = 1.6 m, diam = 0.19 m (REMUS 100 weighs about
    31 kg in air); the added mass is large across the hull and small along it."""
    M_rb, M_a, W = hull_mass(Remus100())
    assert M_rb[0, 0] == pytest.approx(31.03, abs=0.01) and W == pytest.approx(M_rb[0, 0] * 9.81)
    assert M_a[1, 1] > 30 * M_a[0, 0] > 0 and np.allclose(M_a, np.diag(np.diag(M_a)))


def test_kinetic_energy_of_the_remus_is_conserved_with_every_force_off():
    """M nu' = -C(nu) nu with the REMUS mass matrix (rigid body and added mass): C is skew
    symmetric, so 1/2 nu' M nu stays put to the integrator's accuracy (RK4, order >= 4
    when the sub-step is halved)."""
    M_rb, M_a, _ = hull_mass(Remus100())
    M = M_rb + M_a
    Minv = np.linalg.inv(M)
    nu0 = np.array([2.0, 0.3, -0.2, 0.5, -0.1, 0.3])
    C = coriolis_from_mass(M, nu0)
    assert np.allclose(C, -C.T)

    def drift(dt, T=10.0):
        nu = nu0.copy()
        for _ in range(round(T / dt)):
            nu = rk4_step(lambda n: -Minv @ (coriolis_from_mass(M, n) @ n), nu, dt)
        return abs(nu @ M @ nu - nu0 @ M @ nu0) / (nu0 @ M @ nu0)

    d1, d2 = drift(0.02), drift(0.01)
    assert d1 < 1e-4 and np.log2(d1 / d2) > 3.8, (d1, d2)


def test_full_propeller_speed_gives_the_published_2_5_m_s():
    """1525 rpm, fins at 0, no current: the vehicle settles at about 2.5 m/s (Allen et al.
    2000; Fossen 2021), straight and level."""
    v, x = Remus100(), np.zeros(STATE_SIZE)
    for _ in range(500):
        x = step(v, x, FULL, 0.2, 2)
    assert x[6] == pytest.approx(2.5, rel=0.05)
    assert abs(x[7]) < 0.02 and abs(x[8]) < 0.01 and abs(x[5]) < 0.05


def test_the_rk4_sub_step_is_small_enough_and_converges_at_fourth_order():
    """A 20 s manoeuvre (full rudder and stern planes at 1525 rpm from 2 m/s) with sub-steps
    of 0.1, 0.05 and 0.025 s: the position differs by under a millimetre between the two
    finest, and the differences fall about 16 times per halving."""
    v = Remus100()
    x0 = np.zeros(STATE_SIZE)
    x0[6], x0[14] = 2.0, 1525.0
    cmd = np.array([math.radians(15), math.radians(10), 1525.0])

    def run(sub):
        x = x0.copy()
        for _ in range(100):
            x = step(v, x, cmd, 0.2, sub)
        return x

    a, b, c = run(2), run(4), run(8)
    e1, e2 = np.linalg.norm(a[:3] - b[:3]), np.linalg.norm(b[:3] - c[:3])
    assert e2 < 1e-3 and 3.0 < np.log2(e1 / e2) < 5.5, (e1, e2)


def test_a_turning_circle_at_full_rudder_closes_with_radius_u_over_r():
    """Full rudder (15 deg) at 1525 rpm: a steady turn to starboard, banked and slowly
    diving (a helix). Its traced horizontal diameter equals 2 U_h / psi' (the NED speed
    over the heading rate, within 1 %): about 34 m, some 21 vehicle lengths."""
    from plant_model.remus100.rigid_body import euler_kinematics
    v, x = Remus100(), np.zeros(STATE_SIZE)
    x[6], x[14] = 2.5, 1525.0
    cmd = np.array([math.radians(15), 0.0, 1525.0])
    path = []
    for k in range(600):
        x = step(v, x, cmd, 0.2, 2)
        if k >= 300:
            path.append(x[:2].copy())
    path = np.array(path)
    rate = euler_kinematics(x[:6]) @ x[6:12]
    U_h, psi_dot = math.hypot(rate[0], rate[1]), rate[5]
    assert x[11] > 0.0 and psi_dot > 0.0                 # positive rudder: starboard
    traced = path[:, 0].max() - path[:, 0].min()
    assert traced == pytest.approx(2 * U_h / psi_dot, rel=0.01)
    assert 10 * v.L < traced < 40 * v.L


@pytest.mark.parametrize("kwargs, fragment", [
    ({"rho": -1026.0}, "rho = -1026 kg/m^3 must be positive"),
    ({"L": 0.0}, "L = 0 m must be positive"),
    ({"delta_max": -0.5}, "delta_max = -0.5 rad (-28.6 deg) must be in (0, 90) deg"),
    ({"n_max": -1525.0}, "n_max = -1525 rpm must be positive"),
    ({"diam": 2.0}, "diam = 2 m must be below L = 1.6 m"),
    ({"T_delta": float("nan")}, "T_delta = nan is not a finite number"),
])
def test_bad_vehicle_data_is_one_line_naming_the_parameter(kwargs, fragment):
    with pytest.raises(ModelError) as exc:
        Remus100(**kwargs)
    assert fragment in str(exc.value) and "\n" not in str(exc.value)


def test_a_sub_step_count_that_is_not_whole_is_refused():
    with pytest.raises(ModelError, match="substeps = 2.5 must be a positive whole number"):
        step(Remus100(), np.zeros(STATE_SIZE), FULL, 0.1, 2.5)

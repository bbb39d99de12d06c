"""The nonlinear 6-DOF REMUS 100: the vehicle its formation controller meets (model
``remus100-6dof``; docs/remus100-6dof.md).

The model follows T. I. Fossen's Python Vehicle Simulator, ``vehicles/remus100.py`` as
published on 2025-01-15 (repository cybergalactic/PythonVehicleSimulator, commit
7e1db8e; unchanged up to its 2025-05-13 head c717e07), with ``lib/gnc.py`` of the same
version. Deliberate differences are listed in :class:`Remus100` and docs/remus100-6dof.md.

State x = [eta (6); nu (6); delta_r, delta_s (rad); n (rpm)]: NED position and Euler
angles, body velocities (plant_model.remus100.rigid_body), the rudder and stern-plane angles and
the propeller speed. With the velocity relative to a current constant in NED,
nu_r = nu - nu_c, nu_c = [R(Theta)' v_c; 0]:

    M nu_r' + C(nu_r) nu_r + D(nu_r) nu_r + g(eta) = tau_prop + tau_fins + tau_hull
    nu' = nu_r' + nu_c',  nu_c' = [-omega x (R' v_c); 0],  eta' = J(eta) nu

- M = M_RB + M_A: a prolate spheroid of the hull's length and diameter filled with
  water (neutrally buoyant), CG 2 cm below CB; added mass from Lamb's k-factors, roll
  added inertia 0.3 I_x;
- C(nu_r) = C_RB(nu_r) + C_A(nu_r) from M, with the reference's eight entries of C_A
  removed in skew-symmetric pairs (the Munk moments in pitch and yaw and the velocity
  products that pair with them; :func:`_munk_balance`);
- D(nu_r): linear damping from time constants (surge and sway fading as exp(-3 U_r),
  where drag and lift take over), cross-flow drag by strip theory, hull lift and drag
  against the angle of attack;
- fins: two rudders and two stern planes, lift 1/2 rho U^2 A CL_delta delta at the tail
  (moment r x F), drag with the same coefficient times delta^2;
- propeller: thrust rho D^4 KT(J_a) n|n| with KT linear in the advance ratio
  J_a = V_a / (n D), V_a = 0.944 U (wake), thrust deduction 0.1; its torque
  rho D^5 KQ(J_a) n|n|, scaled by 0.1 as the reference does, rolls the hull;
- actuators: first-order lags (fins 0.1 s, propeller 1 s) towards the commands, rate
  limited to their range per time constant, saturated at +-15 deg and 1525 rpm.

Units: m, s, rad, N, N m, rpm for the propeller. Integrated with fixed RK4 sub-steps
(:func:`step`); docs/remus100-6dof.md shows the sub-step is small enough.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np

from ..bounds import Bound, nonnegative, positive
from ..linalg_checks import ModelError
from ..vehicles import lamb_factors, remus100_parameters
from .rigid_body import (
    coriolis_times,
    euler_kinematics,
    restoring_forces,
    rigid_body_mass,
    rk4_step,
    rotation_ned_body,
)

__all__ = ["REMUS_BOUNDS", "Remus100", "STATE_SIZE", "derivative", "hull_mass", "step"]

STATE_SIZE = 15
G = 9.81   #: m/s^2


@dataclass(frozen=True)
class Remus100:
    """REMUS 100 data. Sources: [P] T. I. Fossen, Python Vehicle Simulator,
    ``vehicles/remus100.py`` of 2025-01-15 (commit 7e1db8e) and ``lib/gnc.py``; [F] T. I.
    Fossen, Handbook of Marine Craft Hydrodynamics and Motion Control, 2nd ed., Wiley 2021,
    section 8.4.2; [A] B. Allen, W. S. Vorus, T. Prestero, "Propulsion system performance
    enhancements on REMUS AUVs", OCEANS 2000; [H] S. F. Hoerner, Fluid-Dynamic Drag, 1965
    (2D cross-flow drag of a circular section, as [P]'s ``Hoerner(B, T)`` at B/2T = 0.5).

    Deliberate differences from [P] (each measured in docs/remus100-6dof.md):
    cross-flow drag in both planes (the hull is axisymmetric; [P] has it in sway and yaw
    only) over 20 strips by the midpoint rule ([P] sums 21 points over L + dx); with
    ``published_crossflow = 1`` the model takes [P]'s cross-flow drag as it is. Fin and
    propeller commands rate limited to their range per time constant and saturated before
    the lag ([P] saturates the lagged value only); RK4 sub-steps instead of forward Euler."""

    L: float = 1.6                  #: length, m [P, A]
    diam: float = 0.19              #: hull diameter, m [P, A]
    rho: float = 1026.0             #: sea water, kg/m^3 [P]
    r_g: tuple[float, float, float] = (0.0, 0.0, 0.02)   #: CG from CO (= CB), m [P]
    r44: float = 0.3                #: roll added inertia A44 = r44 I_x [P]
    Cd_surge: float = 0.42          #: hull drag on the frontal area pi b^2 [A, P]
    hull_area_ratio: float = 0.7    #: lifting area S = 0.7 L diam [P]
    oswald: float = 0.7             #: Oswald efficiency of the hull as a wing [P]
    Cd_crossflow: float = 1.198     #: 2D cross-flow drag, Hoerner's curve at B/2T = 0.5 [H, P]
    T_surge: float = 20.0           #: low-speed damping time constants, s [P]
    T_sway: float = 20.0            #: (heave: the same) [P]
    T_yaw: float = 1.0              #: s, not fading with speed [P]
    zeta_roll: float = 0.3          #: relative damping in roll and pitch [P]
    zeta_pitch: float = 0.8
    A_rudder: float = 2 * 0.00665   #: two rudder fins of 0.00665 m^2 [P]
    CL_rudder: float = 0.5          #: rudder lift slope, 1/rad [P]
    A_stern: float = 2 * 0.00665    #: two stern planes of 0.00665 m^2 [P]
    CL_stern: float = 0.7           #: stern-plane lift slope, 1/rad [P]
    delta_max: float = math.radians(15.0)  #: fin limit, rad [P]
    T_delta: float = 0.1            #: fin time constant, s [P]
    n_max: float = 1525.0           #: propeller limit, rpm (2.55 m/s) [P, A]
    T_n: float = 1.0                #: propeller time constant, s [P]
    D_prop: float = 0.14            #: propeller diameter (5.5 in), m [P, A]
    thrust_deduction: float = 0.1   #: [P]
    wake_factor: float = 0.944      #: V_a = 0.944 U [A, P]
    KT0: float = 0.4566             #: Wageningen B3-71.8 (BAR 0.718), J = 0 [P]
    KQ0: float = 0.0700
    KT_max: float = 0.1798          #: at J_a = 0.6632 (2.5 m/s at 1525 rpm) [P]
    KQ_max: float = 0.0312
    Ja_max: float = 0.6632
    torque_scale: float = 0.1       #: propeller roll moment scale, "to match experimental
    #: results" [P]
    published_crossflow: float = 0.0   #: 1: [P]'s cross-flow sum (21 points, sway and yaw
    #: only); 0: 20 midpoint strips in both planes
    current: tuple[float, float, float] = field(default=(0.0, 0.0, 0.0))  #: NED, m/s

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            vals = v if isinstance(v, tuple) else (v,)
            if not all(isinstance(x, (int, float)) and not isinstance(x, bool)
                       and math.isfinite(x) for x in vals):
                raise ModelError(f"remus100-6dof: {f.name} = {v!r} is not a finite number")
        if self.published_crossflow not in (0.0, 1.0):
            raise ModelError(f"remus100-6dof: published_crossflow = "
                             f"{self.published_crossflow:g} must be 0 or 1")
        for name, bound in REMUS_BOUNDS.items():
            try:
                bound.check(name, getattr(self, name))
            except ModelError as exc:
                raise ModelError(f"remus100-6dof: {exc}") from None
        if self.r_g[2] <= 0.0:
            raise ModelError(f"remus100-6dof: r_g[3] = {self.r_g[2]:g} m must be positive (the "
                             "CG below the CB keeps the hull upright)")
        if self.diam >= self.L:
            raise ModelError(f"remus100-6dof: diam = {self.diam:g} m must be below L = "
                             f"{self.L:g} m (a slender hull)")


_TIME = "a time constant"
#: the physical bounds of the scalar fields of :class:`Remus100` (every field but
#: ``published_crossflow``, 0 or 1, and the vectors ``r_g``, ``current``), each with its unit
REMUS_BOUNDS: dict[str, Bound] = {
    "L": positive("m", "the hull's length"),
    "diam": positive("m", "the hull's diameter"),
    "rho": positive("kg/m^3", "the water's density"),
    "r44": nonnegative("", "the roll added inertia A44 = r44 I_x"),
    "Cd_surge": nonnegative("", "a drag coefficient"),
    "hull_area_ratio": Bound(0.0, 1.0, hi_closed=True, why="the lifting area over L diam"),
    "oswald": Bound(0.0, 1.0, hi_closed=True, why="an Oswald efficiency"),
    "Cd_crossflow": nonnegative("", "a drag coefficient"),
    "T_surge": positive("s", _TIME),
    "T_sway": positive("s", _TIME),
    "T_yaw": positive("s", _TIME),
    "zeta_roll": nonnegative("", "a relative damping: below 0 the roll grows by itself"),
    "zeta_pitch": nonnegative("", "a relative damping: below 0 the pitch grows by itself"),
    "A_rudder": positive("m^2", "a fin area"),
    "CL_rudder": positive("1/rad", "a lift slope"),
    "A_stern": positive("m^2", "a fin area"),
    "CL_stern": positive("1/rad", "a lift slope"),
    "delta_max": Bound(0.0, math.pi / 2, unit="rad", why="the fins' deflection limit",
                       shown=("deg", 180.0 / math.pi)),
    "T_delta": positive("s", _TIME),
    "n_max": positive("rpm", "the propeller's speed limit"),
    "T_n": positive("s", _TIME),
    "D_prop": positive("m", "the propeller's diameter"),
    "thrust_deduction": Bound(0.0, 1.0, lo_closed=True,
                              why="the share of the thrust the hull's suction takes back"),
    "wake_factor": Bound(0.0, 1.0, hi_closed=True,
                         why="the advance speed over the vehicle's speed, 1 - wake fraction"),
    "KT0": positive("", "the thrust coefficient at J = 0"),
    "KQ0": positive("", "the torque coefficient at J = 0"),
    "KT_max": nonnegative("", "the thrust coefficient at J_a,max"),
    "KQ_max": nonnegative("", "the torque coefficient at J_a,max"),
    "Ja_max": positive("", "an advance ratio"),
    "torque_scale": nonnegative("", "the propeller roll moment's scale"),
}


def hull_mass(v: Remus100) -> tuple[np.ndarray, np.ndarray, float]:
    """(M_RB, M_A, W) of the spheroid hull: m = 4/3 pi rho a b^2 (a = L/2, b = diam/2),
    I_x = 2/5 m b^2, I_y = I_z = 1/5 m (a^2 + b^2) about the CG; added mass from Lamb's
    k-factors (eccentricity e = sqrt(1 - (b/a)^2)); weight W = buoyancy (N)."""
    a, b = v.L / 2.0, v.diam / 2.0
    hull = remus100_parameters(v.rho, v.L, v.diam, v.Cd_surge)   # the linear model's numbers
    m = hull["mass"]
    Ix, Iy = 0.4 * m * b * b, 0.2 * m * (a * a + b * b)
    M_rb = rigid_body_mass(m, np.asarray(v.r_g), np.diag([Ix, Iy, Iy]))
    kp = lamb_factors(a, b)[2]
    M_a = np.diag([*hull["added_mass"], v.r44 * Ix, kp * Iy, kp * Iy])
    return M_rb, M_a, m * G


@dataclass(frozen=True)
class _Derived:
    M: np.ndarray
    Ma: np.ndarray
    Minv: np.ndarray
    W: float
    lin: np.ndarray        #: linear damping diagonal at zero speed
    CD0: float
    S: float
    current: np.ndarray    #: NED, m/s
    r_g: np.ndarray
    limits: np.ndarray     #: actuator limits [rad, rad, rpm]
    taus: np.ndarray       #: actuator time constants, s
    strip_x: np.ndarray    #: cross-flow strip centres, m
    strip_k: float         #: 1/2 rho Cd diam dx
    vertical: float        #: 1: cross-flow drag in heave and pitch too; 0: not


def _derived(v: Remus100) -> _Derived:
    M_rb, M_a, W = hull_mass(v)
    M = M_rb + M_a
    zg = v.r_g[2]
    w_roll, w_pitch = math.sqrt(W * zg / M[3, 3]), math.sqrt(W * zg / M[4, 4])
    lin = np.array([M[0, 0] / v.T_surge, M[1, 1] / v.T_sway, M[2, 2] / v.T_sway,
                    2 * v.zeta_roll * w_roll * M[3, 3], 2 * v.zeta_pitch * w_pitch * M[4, 4],
                    M[5, 5] / v.T_yaw])
    S = v.hull_area_ratio * v.L * v.diam
    strips = 20
    dx = v.L / strips
    if v.published_crossflow:      # [P]: x = -L/2 + i dx, i = 0..20, each weighted dx
        strip_x = -v.L / 2 + dx * np.arange(strips + 1)
    else:                          # midpoint rule over the hull
        strip_x = -v.L / 2 + dx * (np.arange(strips) + 0.5)
    return _Derived(M=M, Ma=M_a, Minv=np.linalg.inv(M), W=W, lin=lin,
                    CD0=v.Cd_surge * math.pi * (v.diam / 2) ** 2 / S, S=S,
                    current=np.asarray(v.current, dtype=float), r_g=np.asarray(v.r_g, float),
                    limits=np.array([v.delta_max, v.delta_max, v.n_max]),
                    taus=np.array([v.T_delta, v.T_delta, v.T_n]),
                    strip_x=strip_x, strip_k=0.5 * v.rho * v.Cd_crossflow * v.diam * dx,
                    vertical=0.0 if v.published_crossflow else 1.0)


_CACHE: dict[Remus100, _Derived] = {}
_ZERO3 = np.zeros(3)


def _d(v: Remus100) -> _Derived:
    if v not in _CACHE:
        _CACHE[v] = _derived(v)
    return _CACHE[v]


def _crossflow(d: _Derived, nu_r: np.ndarray) -> np.ndarray:
    """Strip-theory cross-flow drag in sway/yaw and (unless ``published_crossflow``)
    heave/pitch: each strip at x sees the transverse velocity v + x r (or w - x q) and
    resists with 1/2 rho Cd diam |.|(.) dx."""
    x, k = d.strip_x, d.strip_k
    vy = nu_r[1] + x * nu_r[5]
    vz = nu_r[2] - x * nu_r[4]
    Fy, Fz = -k * np.abs(vy) * vy, -d.vertical * k * np.abs(vz) * vz
    return np.array([0.0, Fy.sum(), Fz.sum(), 0.0, -(x * Fz).sum(), (x * Fy).sum()])


def _hull_lift_drag(v: Remus100, d: _Derived, nu_r: np.ndarray) -> np.ndarray:
    """The hull as a low-aspect-ratio wing in the vertical plane (angle of attack
    alpha = atan2(w_r, u_r)): CL = CL_alpha alpha, CD = CD0 + CL^2 / (pi e AR)."""
    U2 = nu_r[0] ** 2 + nu_r[2] ** 2
    if U2 == 0.0:
        return np.zeros(6)
    alpha = math.atan2(nu_r[2], nu_r[0])
    AR = v.diam ** 2 / d.S
    CL = math.pi * AR / (1.0 + math.sqrt(1.0 + (AR / 2.0) ** 2)) * alpha
    CD = d.CD0 + CL * CL / (math.pi * v.oswald * AR)
    q = 0.5 * v.rho * (nu_r[:3] @ nu_r[:3]) * d.S       # 1/2 rho U_r^2 S
    drag, lift = q * CD, q * CL
    ca, sa = math.cos(alpha), math.sin(alpha)
    return np.array([-ca * drag + sa * lift, 0.0, -sa * drag - ca * lift, 0.0, 0.0, 0.0])


def _munk_balance(d: _Derived, nu_r: np.ndarray) -> np.ndarray:
    """The part of C_A(nu_r) nu_r that [P] removes, to be added back: [P] sets the entries
    C_A[4,0], C_A[0,4], C_A[4,2], C_A[2,4] (pitch) and C_A[5,0], C_A[0,5], C_A[5,1],
    C_A[1,5] (yaw) to zero, "destabilizing if quadratic rotational damping is missing".
    They go in skew-symmetric pairs, so C stays skew symmetric and the kinetic energy is
    conserved without forces. With M_A = diag(X, Y, Z, K, M, N) (positive added masses),
    a = [X u, Y v, Z w] and C_A = [[0, -S(a)], [-S(a), -S(b)]]:

        surge (Z w) q - (Y v) r,  sway (X u) r,  heave -(X u) q,
        pitch (X - Z) u w,        yaw (Y - X) u v      (N, N m)
    """
    X, Y, Z = d.Ma[0, 0], d.Ma[1, 1], d.Ma[2, 2]
    u, v_, w, q, r = nu_r[0], nu_r[1], nu_r[2], nu_r[4], nu_r[5]
    return np.array([Z * w * q - Y * v_ * r, X * u * r, -X * u * q, 0.0,
                     (X - Z) * u * w, (Y - X) * u * v_])


def _propeller(v: Remus100, n_rpm: float, U: float) -> tuple[float, float]:
    """(thrust, torque) at n rpm and speed U: rho D^4 KT n|n|, rho D^5 KQ n|n| (n in rps),
    KT and KQ linear in J_a = 0.944 U / (n D) between J = 0 and J_a,max; reverse: J = 0."""
    n = n_rpm / 60.0
    if n > 0.0:
        Ja_n = v.wake_factor * U / v.D_prop          # J_a n
        KTn = v.KT0 * n * n + (v.KT_max - v.KT0) / v.Ja_max * Ja_n * n
        KQn = v.KQ0 * n * n + (v.KQ_max - v.KQ0) / v.Ja_max * Ja_n * n
    else:
        KTn, KQn = v.KT0 * abs(n) * n, v.KQ0 * abs(n) * n
    return v.rho * v.D_prop ** 4 * KTn, v.rho * v.D_prop ** 5 * KQn


def derivative(v: Remus100, x: np.ndarray, command: np.ndarray) -> np.ndarray:
    """x' for the state x and the actuator command [delta_r, delta_s (rad), n (rpm)]
    (module docstring). Positive delta_r turns to starboard (yaw rate > 0), positive
    delta_s dives (pitch down)."""
    d = _d(v)
    eta, nu, act = x[:6], x[6:12], x[12:]
    R = rotation_ned_body(*eta[3:6])
    vc_body = R.T @ d.current
    nu_c = np.concatenate([vc_body, np.zeros(3)])
    nu_r = nu - nu_c
    U_r = math.sqrt(nu_r[:3] @ nu_r[:3])
    U = math.sqrt(nu[:3] @ nu[:3])
    dm = v.delta_max
    dr, ds = min(max(float(act[0]), -dm), dm), min(max(float(act[1]), -dm), dm)
    n = min(max(float(act[2]), -v.n_max), v.n_max)
    thrust, torque = _propeller(v, n, U)
    U_h2, U_v2 = nu_r[0] ** 2 + nu_r[1] ** 2, nu_r[0] ** 2 + nu_r[2] ** 2
    Yr = -0.5 * v.rho * U_h2 * v.A_rudder * v.CL_rudder * dr
    Zs = -0.5 * v.rho * U_v2 * v.A_stern * v.CL_stern * ds
    x_tail = -v.L / 2.0
    tau = np.array([
        (1.0 - v.thrust_deduction) * thrust
        - 0.5 * v.rho * (U_h2 * v.A_rudder * v.CL_rudder * dr * dr
                         + U_v2 * v.A_stern * v.CL_stern * ds * ds),
        Yr, Zs, v.torque_scale * torque, -x_tail * Zs, x_tail * Yr])
    lin = d.lin.copy()
    lin[[0, 1]] *= math.exp(-3.0 * U_r)
    force = (tau + _crossflow(d, nu_r) + _hull_lift_drag(v, d, nu_r)
             + _munk_balance(d, nu_r) - coriolis_times(d.M, nu_r) - lin * nu_r
             - restoring_forces(eta, d.W, d.W, d.r_g, _ZERO3))
    nu_c_dot = np.concatenate([-np.cross(nu[3:], vc_body), _ZERO3])
    limits, taus = d.limits, d.taus
    target = np.clip(command, -limits, limits)
    act_dot = np.clip((target - act) / taus, -limits / taus, limits / taus)
    return np.concatenate([euler_kinematics(eta) @ nu, nu_c_dot + d.Minv @ force, act_dot])


def step(v: Remus100, x: np.ndarray, command: np.ndarray, h: float, substeps: int
         ) -> np.ndarray:
    """The state after one communication step h (s), the command held, with ``substeps``
    RK4 sub-steps of h / substeps.

    Raises
    ------
    ModelError
        If substeps is not a positive whole number.
    """
    if int(substeps) != substeps or substeps < 1:
        raise ModelError(f"remus100-6dof: substeps = {substeps!r} must be a positive whole "
                         "number (the sub-step h / substeps must divide the step)")
    dt = h / int(substeps)
    for _ in range(int(substeps)):
        x = rk4_step(lambda s: derivative(v, s, command), x, dt)
    return x

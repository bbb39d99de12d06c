"""The nonlinear REMUS 100 as a compiled kernel: the same equations as
:mod:`plant_model.remus100.dynamics` and :mod:`plant_model.remus100.autopilot`, written on
scalars over one flat parameter vector so that numba compiles them to machine code.

Why a second form: the readable numpy form costs about 350 us per derivative (some 100
small-array operations), 1.4 ms per RK4 step; formation-20 for 600 s at h = 0.01 s needs
1.2 million vehicle steps. Compiled, a whole communication step (autopilots, RK4, the
reference velocity) takes a few microseconds. The numpy form stays the definition and the
reference: tests/test_remus100_kernel.py holds the two equal to 1e-12 over every term.

numba (a well-kept LLVM compiler for numerical Python) is a dependency for this alone.
Without it (or with ``AUV_COSIM_NO_JIT=1``) the same functions run as plain Python, about
100 times slower. Compilation takes a few seconds once per process (``cache=True`` keeps
the machine code beside this file when the directory is writable).

Parameter vector (:func:`pack`): index constants ``P_*`` below. Units: m, s, rad, N, N m,
rpm. State x (15) = [eta (6); nu (6); delta_r, delta_s, n]; current v_c (3, NED, m/s).
"""
from __future__ import annotations

import math
import os

import numpy as np

from .dynamics import Remus100, _d

__all__ = ["pack", "pack_gains", "derivative", "rk4", "autopilot", "force_commanded_step",
           "plant_step", "actuated_step", "plant_outputs", "actuated_outputs", "JIT"]

try:                                              # pragma: no cover - depends on the machine
    if os.environ.get("AUV_COSIM_NO_JIT", "") == "1":
        raise ImportError("AUV_COSIM_NO_JIT=1")
    from numba import njit as _njit

    def _jit(f):                                  # noqa: ANN001, ANN202 - decorator
        return _njit(cache=True, fastmath=False, nogil=True)(f)

    JIT = True
except ImportError:                               # pragma: no cover
    def _jit(f):                                  # noqa: ANN001, ANN202 - decorator
        return f

    JIT = False

# parameter vector layout
P_M = 0            # M (6 x 6, row major), kg / kg m / kg m^2
P_MINV = 36        # M^-1 (6 x 6)
P_MA = 72          # diagonal of M_A (6)
P_LIN = 78         # linear damping at zero speed (6)
P_W = 84           # weight = buoyancy, N
P_RG = 85          # CG from CO (3), m
P_LIM = 88         # actuator limits [rad, rad, rpm]
P_TAU = 91         # actuator time constants (3), s
P_RHO = 94
P_L = 95
P_ARUD = 96        # A_rudder CL_rudder, m^2
P_ASTE = 97        # A_stern CL_stern, m^2
P_TD = 98          # thrust deduction
P_WAKE = 99
P_DPROP = 100
P_KT0 = 101
P_KQ0 = 102
P_KTS = 103        # (KT_max - KT0) / Ja_max
P_KQS = 104
P_S = 105          # hull lifting area, m^2
P_CLA = 106        # hull lift slope, 1/rad
P_CDI = 107        # 1 / (pi e AR)
P_CD0 = 108
P_SK = 109         # strip coefficient 1/2 rho Cd diam dx
P_NS = 110         # number of strips
P_TQS = 111        # propeller torque scale
P_CFV = 112        # 1: cross-flow drag in heave and pitch too
P_SX = 113         # strip centres (P_NS of them), m


def pack(v: Remus100) -> np.ndarray:
    """The flat parameter vector of a vehicle (layout ``P_*``), from the same derived
    numbers as the numpy form (:func:`plant_model.remus100.dynamics._d`)."""
    d = _d(v)
    ns = len(d.strip_x)
    p = np.zeros(P_SX + ns)
    p[P_M:P_M + 36] = d.M.ravel()
    p[P_MINV:P_MINV + 36] = d.Minv.ravel()
    p[P_MA:P_MA + 6] = np.diag(d.Ma)
    p[P_LIN:P_LIN + 6] = d.lin
    p[P_W] = d.W
    p[P_RG:P_RG + 3] = d.r_g
    p[P_LIM:P_LIM + 3] = d.limits
    p[P_TAU:P_TAU + 3] = d.taus
    p[P_RHO], p[P_L] = v.rho, v.L
    p[P_ARUD], p[P_ASTE] = v.A_rudder * v.CL_rudder, v.A_stern * v.CL_stern
    p[P_TD], p[P_WAKE], p[P_DPROP] = v.thrust_deduction, v.wake_factor, v.D_prop
    p[P_KT0], p[P_KQ0] = v.KT0, v.KQ0
    p[P_KTS], p[P_KQS] = (v.KT_max - v.KT0) / v.Ja_max, (v.KQ_max - v.KQ0) / v.Ja_max
    AR = v.diam ** 2 / d.S
    p[P_S] = d.S
    p[P_CLA] = math.pi * AR / (1.0 + math.sqrt(1.0 + (AR / 2.0) ** 2))
    p[P_CDI] = 1.0 / (math.pi * v.oswald * AR)
    p[P_CD0], p[P_SK], p[P_NS] = d.CD0, d.strip_k, ns
    p[P_TQS], p[P_CFV] = v.torque_scale, d.vertical
    p[P_SX:] = d.strip_x
    return p


def pack_gains(g: object) -> np.ndarray:
    """The autopilot gains (:class:`plant_model.remus100.autopilot.AutopilotGains`) as
    [U_max, n_max, K_u, K_ui, K_chi, K_r, K_gamma, K_gi, K_theta, K_q, U_min,
    delta_max]."""
    return np.array([g.U_max, g.n_max, g.K_u, g.K_ui, g.K_chi, g.K_r, g.K_gamma, g.K_gi,
                     g.K_theta, g.K_q, g.U_min, g.delta_max], dtype=float)


@_jit
def _clip(a: float, lo: float, hi: float) -> float:
    return min(max(a, lo), hi)


@_jit
def derivative(p: np.ndarray, x: np.ndarray, cmd: np.ndarray, cur: np.ndarray,
               out: np.ndarray) -> None:
    """out = x' (15) for the state x, the command [delta_r, delta_s (rad), n (rpm)] and
    the current v_c (NED, m/s): :func:`plant_model.remus100.dynamics.derivative` term by
    term."""
    phi, theta = x[3], x[4]
    cf, sf, ct, st = math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta)
    R00, R01, R02, R10, R11, R12, R20, R21, R22 = _rotation(phi, theta, x[5])
    c0, c1, c2 = cur[0], cur[1], cur[2]
    vb0 = R00 * c0 + R10 * c1 + R20 * c2                  # R' v_c
    vb1 = R01 * c0 + R11 * c1 + R21 * c2
    vb2 = R02 * c0 + R12 * c1 + R22 * c2
    u, v, w, pr, q, r = x[6], x[7], x[8], x[9], x[10], x[11]
    nr = np.empty(6)
    nr[0], nr[1], nr[2], nr[3], nr[4], nr[5] = u - vb0, v - vb1, w - vb2, pr, q, r
    ur, vr, wr = nr[0], nr[1], nr[2]
    U_r = math.sqrt(ur * ur + vr * vr + wr * wr)
    U = math.sqrt(u * u + v * v + w * w)
    dm = p[P_LIM]
    nmax = p[P_LIM + 2]
    dr = _clip(x[12], -dm, dm)
    ds = _clip(x[13], -dm, dm)
    n_rpm = _clip(x[14], -nmax, nmax)
    rho = p[P_RHO]
    # propeller
    n = n_rpm / 60.0
    if n > 0.0:
        Ja_n = p[P_WAKE] * U / p[P_DPROP]
        KTn = p[P_KT0] * n * n + p[P_KTS] * Ja_n * n
        KQn = p[P_KQ0] * n * n + p[P_KQS] * Ja_n * n
    else:
        KTn = p[P_KT0] * abs(n) * n
        KQn = p[P_KQ0] * abs(n) * n
    D4 = p[P_DPROP] ** 4
    thrust, torque = rho * D4 * KTn, p[P_TQS] * rho * D4 * p[P_DPROP] * KQn
    # fins
    U_h2, U_v2 = ur * ur + vr * vr, ur * ur + wr * wr
    Yr = -0.5 * rho * U_h2 * p[P_ARUD] * dr
    Zs = -0.5 * rho * U_v2 * p[P_ASTE] * ds
    x_tail = -p[P_L] / 2.0
    f = np.empty(6)
    f[0] = ((1.0 - p[P_TD]) * thrust
            - 0.5 * rho * (U_h2 * p[P_ARUD] * dr * dr + U_v2 * p[P_ASTE] * ds * ds))
    f[1], f[2], f[3], f[4], f[5] = Yr, Zs, torque, -x_tail * Zs, x_tail * Yr
    # strip-theory cross-flow drag
    k = p[P_SK]
    Fy = Fz = My = Mz = 0.0
    for i in range(int(p[P_NS])):
        xs = p[P_SX + i]
        vy = vr + xs * r
        vz = wr - xs * q
        fy, fz = -k * abs(vy) * vy, -p[P_CFV] * k * abs(vz) * vz
        Fy += fy
        Fz += fz
        My += xs * fz
        Mz += xs * fy
    f[1] += Fy
    f[2] += Fz
    f[4] -= My
    f[5] += Mz
    # hull lift and drag in the vertical plane
    if ur * ur + wr * wr != 0.0:
        alpha = math.atan2(wr, ur)
        CL = p[P_CLA] * alpha
        CD = p[P_CD0] + CL * CL * p[P_CDI]
        qd = 0.5 * rho * (ur * ur + vr * vr + wr * wr) * p[P_S]
        drag, lift = qd * CD, qd * CL
        ca, sa = math.cos(alpha), math.sin(alpha)
        f[0] += -ca * drag + sa * lift
        f[2] += -sa * drag - ca * lift
    # the C_A entries the reference removes, added back (dynamics._munk_balance)
    Xa, Ya, Za = p[P_MA], p[P_MA + 1], p[P_MA + 2]
    f[0] += Za * wr * q - Ya * vr * r
    f[1] += Xa * ur * r
    f[2] -= Xa * ur * q
    f[4] += (Xa - Za) * ur * wr
    f[5] += (Ya - Xa) * ur * vr
    # Coriolis C(nu_r) nu_r = [nu2 x a; nu1 x a + nu2 x b], [a; b] = M nu_r
    ab = np.zeros(6)
    for i in range(6):
        s = 0.0
        for j in range(6):
            s += p[P_M + 6 * i + j] * nr[j]
        ab[i] = s
    a0, a1, a2, b0, b1, b2 = ab[0], ab[1], ab[2], ab[3], ab[4], ab[5]
    f[0] -= q * a2 - r * a1
    f[1] -= r * a0 - pr * a2
    f[2] -= pr * a1 - q * a0
    f[3] -= vr * a2 - wr * a1 + q * b2 - r * b1
    f[4] -= wr * a0 - ur * a2 + r * b0 - pr * b2
    f[5] -= ur * a1 - vr * a0 + pr * b1 - q * b0
    # linear damping, fading with speed in surge and sway
    fade = math.exp(-3.0 * U_r)
    for i in range(6):
        li = p[P_LIN + i]
        if i == 0 or i == 1:
            li *= fade
        f[i] -= li * nr[i]
    # restoring forces (W = B, CB at CO)
    W = p[P_W]
    xg, yg, zg = p[P_RG], p[P_RG + 1], p[P_RG + 2]
    f[3] -= -(yg * W) * ct * cf + (zg * W) * ct * sf
    f[4] -= (zg * W) * st + (xg * W) * ct * cf
    f[5] -= -(xg * W) * ct * sf - (yg * W) * st
    # kinematics
    out[0] = R00 * u + R01 * v + R02 * w
    out[1] = R10 * u + R11 * v + R12 * w
    out[2] = R20 * u + R21 * v + R22 * w
    tt = st / ct
    out[3] = pr + sf * tt * q + cf * tt * r
    out[4] = cf * q - sf * r
    out[5] = sf / ct * q + cf / ct * r
    # nu' = nu_c' + M^-1 force, nu_c' = [-omega x (R' v_c); 0]
    ncd0 = -(q * vb2 - r * vb1)
    ncd1 = -(r * vb0 - pr * vb2)
    ncd2 = -(pr * vb1 - q * vb0)
    for i in range(6):
        s = 0.0
        for j in range(6):
            s += p[P_MINV + 6 * i + j] * f[j]
        out[6 + i] = s
    out[6] += ncd0
    out[7] += ncd1
    out[8] += ncd2
    # actuators: first-order lag to the saturated command, rate limited
    for i in range(3):
        lim, tau = p[P_LIM + i], p[P_TAU + i]
        target = _clip(cmd[i], -lim, lim)
        out[12 + i] = _clip((target - x[12 + i]) / tau, -lim / tau, lim / tau)


@_jit
def rk4(p: np.ndarray, x: np.ndarray, cmd: np.ndarray, cur: np.ndarray, dt: float,
        substeps: int) -> None:
    """x <- the state after ``substeps`` classical RK4 steps of dt (s), command and
    current held (in place)."""
    k1, k2, k3, k4 = np.empty(15), np.empty(15), np.empty(15), np.empty(15)
    y = np.empty(15)
    for _ in range(substeps):
        derivative(p, x, cmd, cur, k1)
        for i in range(15):
            y[i] = x[i] + 0.5 * dt * k1[i]
        derivative(p, y, cmd, cur, k2)
        for i in range(15):
            y[i] = x[i] + 0.5 * dt * k2[i]
        derivative(p, y, cmd, cur, k3)
        for i in range(15):
            y[i] = x[i] + dt * k3[i]
        derivative(p, y, cmd, cur, k4)
        for i in range(15):
            x[i] = x[i] + dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])


@_jit
def _rotation(phi: float, theta: float, psi: float) -> tuple:
    """The entries R00, R01, ..., R22 of R(Theta), body to NED (zyx; rigid_body)."""
    cf, sf, ct, st = math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta)
    cp, sp = math.cos(psi), math.sin(psi)
    return (cp * ct, -sp * cf + cp * st * sf, sp * sf + cp * cf * st,
            sp * ct, cp * cf + sf * st * sp, -cp * sf + st * sp * cf,
            -st, ct * sf, ct * cf)


@_jit
def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@_jit
def autopilot(g: np.ndarray, x: np.ndarray, v_ref: np.ndarray, integ: np.ndarray,
              cur: np.ndarray, cmd: np.ndarray, err: np.ndarray) -> None:
    """cmd = [delta_r, delta_s, n], err = [U_d - U, gamma_d - gamma]: the three loops of
    :func:`plant_model.remus100.autopilot.autopilot_command` on the velocity through the
    water (gains vector of :func:`pack_gains`), with the same anti-windup."""
    U_max, n_max, K_u, K_ui, K_chi, K_r = g[0], g[1], g[2], g[3], g[4], g[5]
    K_gamma, K_gi, K_theta, K_q, U_min = g[6], g[7], g[8], g[9], g[10]
    theta, psi = x[4], x[5]
    R00, R01, R02, R10, R11, R12, R20, R21, R22 = _rotation(x[3], theta, psi)
    u, v, w = x[6], x[7], x[8]
    g0 = R00 * u + R01 * v + R02 * w - cur[0]             # over ground, less the current
    g1 = R10 * u + R11 * v + R12 * w - cur[1]
    g2 = R20 * u + R21 * v + R22 * w - cur[2]
    U = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
    U_d = math.sqrt(v_ref[0] ** 2 + v_ref[1] ** 2 + v_ref[2] ** 2)
    cmd[2] = n_max * U_d / U_max + K_u * (U_d - U) + K_ui * integ[0]
    h_ref = math.hypot(v_ref[0], v_ref[1])
    chi_d = math.atan2(v_ref[1], v_ref[0]) if h_ref > U_min else psi
    h_g = math.hypot(g0, g1)
    chi = math.atan2(g1, g0) if h_g > U_min else psi
    cmd[0] = K_chi * _wrap(chi_d - chi) - K_r * x[11]
    gamma_d = math.atan2(-v_ref[2], h_ref) if U_d > U_min else 0.0
    gamma = math.atan2(-g2, h_g) if U > U_min else theta
    theta_d = gamma_d + K_gamma * (gamma_d - gamma) + K_gi * integ[1]
    cmd[1] = K_theta * (theta - theta_d) + K_q * x[10]
    dmax = g[11]
    e_u = U_d - U
    if (cmd[2] >= n_max and U_d > U) or (cmd[2] <= -n_max and U_d < U):
        e_u = 0.0
    e_g = gamma_d - gamma
    if (cmd[1] >= dmax and e_g < 0.0) or (cmd[1] <= -dmax and e_g > 0.0):
        e_g = 0.0
    err[0], err[1] = e_u, e_g


@_jit
def force_commanded_step(p: np.ndarray, g: np.ndarray, x: np.ndarray, v_ref: np.ndarray,
                         integ: np.ndarray, F: np.ndarray, cur: np.ndarray,
                         M: np.ndarray, D: np.ndarray, h: float, substeps: int,
                         cmd: np.ndarray) -> None:
    """One communication step h (s) of :class:`plant_model.remus100.autopilot.
    ForceCommandedRemus` in place: the loops' command (held), ``substeps`` RK4 steps, the
    integrals, then v_ref <- a v_ref + (1 - a) F / D, a = exp(-D h / M)."""
    err = np.empty(2)
    autopilot(g, x, v_ref, integ, cur, cmd, err)
    rk4(p, x, cmd, cur, h / substeps, substeps)
    integ[0] += err[0] * h
    integ[1] += err[1] * h
    for i in range(3):
        a = math.exp(-D[i] * h / M[i])
        v_ref[i] = a * v_ref[i] + (1.0 - a) * F[i] / D[i]


@_jit
def _saturation(cmd: np.ndarray, limits: np.ndarray) -> float:
    """1.0 when some command [delta_r, delta_s, n] is at or beyond its limit, else 0.0."""
    sat = 0.0
    for i in range(3):
        if abs(cmd[i]) >= limits[i]:
            sat = 1.0
    return sat


@_jit
def _disturb(x: np.ndarray, w: np.ndarray, v: np.ndarray, Aw: np.ndarray) -> None:
    """The process noise and the current's step after the dynamics, in place: position
    p += v[0:3] (m), body velocity nu[:3] += R(Theta)' v[3:6] (the NED velocity over ground
    moved by v[3:6], m/s), current w <- Aw w + v[6:9] (m/s)."""
    for i in range(3):
        x[i] += v[i]
    R00, R01, R02, R10, R11, R12, R20, R21, R22 = _rotation(x[3], x[4], x[5])
    a, b, c = v[3], v[4], v[5]                                   # nu[:3] += R' v
    x[6] += R00 * a + R10 * b + R20 * c
    x[7] += R01 * a + R11 * b + R21 * c
    x[8] += R02 * a + R12 * b + R22 * c
    w0, w1, w2 = w[0], w[1], w[2]
    for i in range(3):
        w[i] = Aw[i, 0] * w0 + Aw[i, 1] * w1 + Aw[i, 2] * w2 + v[6 + i]


@_jit
def plant_step(p: np.ndarray, g: np.ndarray, s: np.ndarray, u: np.ndarray, v: np.ndarray,
               Aw: np.ndarray, M: np.ndarray, D: np.ndarray, h: float, substeps: int,
               cmd: np.ndarray, limits: np.ndarray) -> float:
    """One step of :class:`plant_model.remus100.plant.Remus6dofPlant` on its evolving
    vector s = [x (15), v_ref, integrals (2), w] in place: :func:`force_commanded_step` in
    the current w held, then the process noise v (9: position, velocity over ground,
    current) and w <- Aw w + v_w (:func:`_disturb`). Returns 1.0 when some command was at
    or beyond its limit."""
    x, v_ref, integ, w = s[0:15], s[15:18], s[18:20], s[20:23]
    force_commanded_step(p, g, x, v_ref, integ, u, w, M, D, h, substeps, cmd)
    sat = _saturation(cmd, limits)
    _disturb(x, w, v, Aw)
    return sat


@_jit
def actuated_step(p: np.ndarray, s: np.ndarray, command: np.ndarray, v: np.ndarray,
                  Aw: np.ndarray, h: float, substeps: int, cmd: np.ndarray,
                  limits: np.ndarray) -> float:
    """One step of :class:`plant_model.remus100.plant.ActuatedRemus6dofPlant` on the
    evolving vector s (layout of :func:`plant_step`; v_ref and the integrals unused) in
    place: the actuator command = [n (rpm), delta_r (rad), delta_s (rad)] held over h (s)
    (cmd <- [delta_r, delta_s, n], the kernel's order), ``substeps`` RK4 steps of h /
    substeps in the current w held, then the same process noise and current step as
    :func:`plant_step` (:func:`_disturb`). Returns 1.0 when some command was at or beyond
    its limit."""
    x, w = s[0:15], s[20:23]
    cmd[0], cmd[1], cmd[2] = command[1], command[2], command[0]
    sat = _saturation(cmd, limits)
    rk4(p, x, cmd, w, h / substeps, substeps)
    _disturb(x, w, v, Aw)
    return sat


@_jit
def actuated_outputs(s: np.ndarray, o: np.ndarray) -> None:
    """o[19:26] = [velocity through the water in body axes nu[:3] - R(Theta)' w (m/s),
    body rates p, q, r (rad/s), depth (m)] of the evolving vector s (:func:`plant_step`):
    what an autopilot measures (a DVL's water track, a gyro, a pressure sensor)."""
    R00, R01, R02, R10, R11, R12, R20, R21, R22 = _rotation(s[3], s[4], s[5])
    c0, c1, c2 = s[20], s[21], s[22]
    o[19] = s[6] - (R00 * c0 + R10 * c1 + R20 * c2)
    o[20] = s[7] - (R01 * c0 + R11 * c1 + R21 * c2)
    o[21] = s[8] - (R02 * c0 + R12 * c1 + R22 * c2)
    o[22], o[23], o[24] = s[9], s[10], s[11]
    o[25] = s[2]


@_jit
def plant_outputs(s: np.ndarray, n: np.ndarray, sat: float, o: np.ndarray) -> None:
    """o[:19] = [y = p + n, p, v over ground, w, attitude, rpm, rudder, stern, sat] of the
    evolving vector s (:func:`plant_step`) and the fix noise n (3)."""
    x = s
    R00, R01, R02, R10, R11, R12, R20, R21, R22 = _rotation(x[3], x[4], x[5])
    u, v, w = x[6], x[7], x[8]
    for i in range(3):
        o[i] = x[i] + n[i]
        o[3 + i] = x[i]
        o[9 + i] = s[20 + i]
        o[12 + i] = x[3 + i]
    o[6] = R00 * u + R01 * v + R02 * w
    o[7] = R10 * u + R11 * v + R12 * w
    o[8] = R20 * u + R21 * v + R22 * w
    o[15], o[16], o[17], o[18] = x[14], x[12], x[13], sat

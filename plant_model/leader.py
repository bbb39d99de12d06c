"""Virtual-leader paths: the reference exosystem z' = F z, leader position = H z.

The leader's position H z(t) = H expm(F t) z0 is a NED position (north, east, down; m) at
time t (s); its velocity is H F z (m/s). Every path here is an exact linear exosystem, so
the eigenvalues of F lie on the imaginary axis (constants, ramps, oscillators).

Paths:

* :func:`straight` -- constant velocity. z = [n, e, d, v_n, v_e, v_d] (m, m/s),
  F = [[0, I], [0, 0]], H = [I, 0]. The horizontal velocity is ``speed`` along the
  heading psi (measured from north toward east): v_n = speed cos psi, v_e = speed sin psi;
  v_d = ``climb_rate`` (the down-velocity, positive = descending).
* :func:`circle` -- uniform circular motion at constant depth. z = [c_n, c_e, c_d, a, b]
  (m) with a = R cos theta, b = R sin theta, theta' = omega, so a' = -omega b,
  b' = omega a; north = c_n + a, east = c_e + b, down = c_d. omega = speed/R for
  ``clockwise`` (seen from above in NED: theta grows from north toward east) and
  -speed/R otherwise.
* :func:`lawnmower` -- a boustrophedon survey with rounded turns, as a Fourier-truncated
  exosystem (state order and accuracy in its docstring).
* :func:`explicit` -- any F, H, z0.

By name from a scenario table: :func:`plant_model.leader_paths.make_leader`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.linalg import expm

from .bounds import Bound
from .linalg_checks import (
    ModelError,
    as_matrix,
    as_number,
    as_positive,
    as_square,
    as_vector,
    readonly,
)

__all__ = [
    "LEADER_SPEED",
    "MAX_LEADER_SPEED",
    "MAX_TURN_PER_STEP",
    "check_turn_rate",
    "LeaderPath",
    "circle",
    "explicit",
    "lawnmower",
    "lawnmower_turn_error",
    "straight",
]

#: the fastest a leader path may go (m/s, horizontal or vertical): faster than any
#: underwater vehicle (a supercavitating torpedo makes about 100 m/s)
MAX_LEADER_SPEED = 100.0
LEADER_SPEED = Bound(0.0, MAX_LEADER_SPEED, lo_closed=True, hi_closed=True, unit="m/s",
                     why="beyond it: faster than any underwater vehicle")
#: the most a leader path may turn in one step h (rad): at least 20 steps per full turn,
#: so that the sampled exosystem and the controllers see the turn
MAX_TURN_PER_STEP = 2.0 * math.pi / 20


def check_turn_rate(path: LeaderPath, h: float) -> None:
    """Refuse a path that turns faster than the step h samples: its fastest rotation
    omega = max |Im eig F| (rad/s) at most :data:`MAX_TURN_PER_STEP` / h.

    Raises
    ------
    ModelError
        Naming the path (a circle: its radius and speed), omega, the turn per step, the
        bound, and for a circle the smallest radius at that speed.
    """
    omega = float(np.max(np.abs(np.linalg.eigvals(path.F).imag))) if path.l else 0.0
    if omega * h <= MAX_TURN_PER_STEP * (1 + 1e-12):
        return
    hint = (f"; at this speed the radius must be at least "
            f"{math.hypot(*path.z0[3:5]) * omega * h / MAX_TURN_PER_STEP:.3g} m"
            if path.kind == "circle" else
            f"; use h <= {MAX_TURN_PER_STEP / omega:.3g} s")
    raise ModelError(f"leader: the {path.description} turns at {omega:.4g} rad/s, "
                     f"{omega * h:.3g} rad per step h = {h:g} s: more than the "
                     f"{MAX_TURN_PER_STEP:.3g} rad (20 steps per turn) a step samples{hint}")


@dataclass(frozen=True, eq=False)
class LeaderPath:
    """A virtual-leader exosystem z' = F z, z(0) = z0, leader position H z (NED, m)."""

    kind: str
    F: np.ndarray
    H: np.ndarray
    z0: np.ndarray
    state_names: tuple[str, ...]
    description: str

    def __post_init__(self) -> None:
        F = as_square("leader F", self.F)
        l_ = F.shape[0]
        H = as_matrix("leader H", self.H, (None, l_))
        z0 = as_vector("leader z0", self.z0, l_)
        names = tuple(str(n) for n in self.state_names)
        if len(names) != l_:
            raise ModelError(
                f"leader: {len(names)} state names for {l_} exosystem states"
            )
        object.__setattr__(self, "F", readonly(F))
        object.__setattr__(self, "H", readonly(H))
        object.__setattr__(self, "z0", readonly(z0))
        object.__setattr__(self, "state_names", names)

    @property
    def l(self) -> int:  # noqa: E743 - the paper's and python-control's name for this size
        """Number of exosystem states."""
        return self.F.shape[0]

    @property
    def s(self) -> int:
        """Number of position outputs (3 for the NED paths)."""
        return self.H.shape[0]

    def state(self, t: Any) -> np.ndarray:
        """z(t) = expm(F t) z0, shape (len(t), l); t in s (a scalar counts as one time).

        Parameters
        ----------
        t : Any
            Time or 1-D array of times, s.

        Returns
        -------
        np.ndarray
            The exosystem states, shape (len(t), l).

        Raises
        ------
        ModelError
            If ``t`` is not a scalar or a 1-D array.
        """
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        if tt.ndim != 1:
            raise ModelError(f"leader: times must be a 1-D array, got shape {tt.shape}")
        Phi = expm(tt[:, None, None] * self.F)          # (len(t), l, l)
        return Phi @ self.z0

    def position(self, t: Any) -> np.ndarray:
        """Leader position H expm(F t) z0, shape (len(t), s), in m (NED).

        ``t`` and the errors as :meth:`state`; returns the positions, shape (len(t), s), m.
        """
        return self.state(t) @ self.H.T

    def velocity(self, t: Any) -> np.ndarray:
        """Leader velocity H F expm(F t) z0, shape (len(t), s), in m/s (NED).

        ``t`` and the errors as :meth:`state`; returns the velocities, shape (len(t), s),
        m/s.
        """
        return self.state(t) @ self.velocity_matrix().T

    def velocity_matrix(self) -> np.ndarray:
        """H F: maps the exosystem state to the leader velocity (m/s).

        Returns
        -------
        np.ndarray
            H F, s x l.
        """
        return self.H @ self.F


# ------------------------------------------------------------------------------------
# argument checks
def _point(name: str, value: Any) -> np.ndarray:
    if isinstance(value, (str, bytes)):
        raise ModelError(f"{name}: expected [north, east, down] in m, got {value!r}")
    return as_vector(f"{name} [north, east, down] (m)", value, 3)


# ------------------------------------------------------------------------------------
# paths
def straight(speed: float, heading_deg: float = 0.0, start: Any = (0.0, 0.0, 0.0),
             climb_rate: float = 0.0) -> LeaderPath:
    """Straight line at constant velocity from ``start`` (NED, m).

    ``speed`` horizontal speed (m/s, >= 0), ``heading_deg`` from north toward east (deg),
    ``climb_rate`` down-velocity (m/s, positive = descending). State z = [n, e, d, v_n,
    v_e, v_d]; position(t) = start + [speed cos psi, speed sin psi, climb_rate] t.

    Parameters
    ----------
    speed : float
        Horizontal speed, m/s (>= 0).
    heading_deg : float, optional
        Heading psi from north toward east, deg.
    start : Any, optional
        Position at t = 0, [north, east, down] in m.
    climb_rate : float, optional
        Down-velocity, m/s (positive = descending).

    Returns
    -------
    LeaderPath
        The 6-state exosystem F = [[0, I], [0, 0]], H = [I, 0].

    Raises
    ------
    ModelError
        If an argument is not a finite number, ``speed`` is negative or ``start`` is not
        3 numbers.
    """
    v = LEADER_SPEED.check("speed", speed)
    psi = math.radians(as_number("heading_deg", heading_deg))
    vd = as_number("climb_rate", climb_rate)
    if abs(vd) > MAX_LEADER_SPEED:
        raise ModelError(f"climb_rate = {vd:g} m/s is beyond +-{MAX_LEADER_SPEED:g} m/s "
                         f"({LEADER_SPEED.why})")
    p0 = _point("start", start)
    Z, I3 = np.zeros((3, 3)), np.eye(3)
    F = np.block([[Z, I3], [Z, Z]])
    H = np.hstack([I3, Z])
    z0 = np.concatenate([p0, [v * math.cos(psi), v * math.sin(psi), vd]])
    return LeaderPath(
        kind="straight", F=F, H=H, z0=z0,
        state_names=("n", "e", "d", "v_n", "v_e", "v_d"),
        description=(f"straight line at {v:g} m/s, heading {math.degrees(psi):g} deg, "
                     f"down-velocity {vd:g} m/s from {p0.tolist()} m"),
    )


def circle(radius: float, speed: float, center: Any = (0.0, 0.0, 0.0), clockwise: bool = True,
           start_angle_deg: float = 0.0) -> LeaderPath:
    """Circle of ``radius`` (m) around ``center`` (NED, m) at ``speed`` (m/s), constant depth.

    State z = [c_n, c_e, c_d, a, b] with a = R cos theta, b = R sin theta; theta(0) =
    ``start_angle_deg`` measured from north toward east (0 = due north of the center);
    theta' = +speed/R when ``clockwise`` (seen from above), -speed/R otherwise.

    Parameters
    ----------
    radius : float
        Radius R, m (> 0).
    speed : float
        Speed along the circle, m/s (>= 0).
    center : Any, optional
        Center [north, east, down], m.
    clockwise : bool, optional
        Direction seen from above (NED).
    start_angle_deg : float, optional
        theta(0), deg from north toward east.

    Returns
    -------
    LeaderPath
        The 5-state exosystem.

    Raises
    ------
    ModelError
        If an argument is out of range or of the wrong type.
    """
    R = as_positive("radius", radius, "m")
    v = LEADER_SPEED.check("speed", speed)
    c = _point("center", center)
    if not isinstance(clockwise, (bool, np.bool_)):
        raise ModelError(f"clockwise: expected true or false, got {clockwise!r}")
    th0 = math.radians(as_number("start_angle_deg", start_angle_deg))
    omega = (v / R) if clockwise else -(v / R)
    F = np.zeros((5, 5))
    F[3, 4] = -omega
    F[4, 3] = omega
    H = np.array([[1.0, 0, 0, 1, 0], [0, 1, 0, 0, 1], [0, 0, 1, 0, 0]])
    z0 = np.concatenate([c, [R * math.cos(th0), R * math.sin(th0)]])
    return LeaderPath(
        kind="circle", F=F, H=H, z0=z0,
        state_names=("c_n", "c_e", "c_d", "a", "b"),
        description=(f"{'clockwise' if clockwise else 'counterclockwise'} circle of radius "
                     f"{R:g} m around {c.tolist()} m at {v:g} m/s"),
    )


def lawnmower_turn_error(leg_length: float, harmonics: int) -> float:
    """North error (m) of the truncated triangle wave at a turn, t = k T_leg.

    (4 L / pi^2) (pi^2/8 - sum_{j=1..h} 1/(2j-1)^2): about 0.095 L for h = 1, 0.045 L
    for h = 2, 0.034 L for h = 3, roughly L/(pi^2 h) for large h. It is the largest
    position error of :func:`lawnmower` at the waypoints (it is zero at mid-leg).

    Parameters
    ----------
    leg_length : float
        Leg length L, m.
    harmonics : int
        Number h of harmonics kept.

    Returns
    -------
    float
        The north error at a turn, m.
    """
    h = int(harmonics)
    tail = math.pi**2 / 8.0 - sum(1.0 / (2 * j - 1) ** 2 for j in range(1, h + 1))
    return 4.0 * float(leg_length) / math.pi**2 * tail


def lawnmower(leg_length: float, spacing: float, speed: float, harmonics: int = 3,
              start: Any = (0.0, 0.0, 0.0), depth: float | None = None) -> LeaderPath:
    """Boustrophedon survey along north legs with rounded turns, as a linear exosystem.

    Ideal path: leg k (k = 0, 1, ...) runs at east = start_e + k ``spacing`` from north =
    start_n to start_n + ``leg_length`` (k even) or back (k odd) during k T_leg < t <
    (k+1) T_leg, T_leg = leg_length / speed; at t = k T_leg the leader steps east by
    ``spacing`` (negative spacing steps west). Down = ``depth`` (default start_d).

    With w0 = pi / T_leg and h = ``harmonics``:

        north(t) = start_n + L/2 - (4 L/pi^2) sum_{k = 1, 3, .., 2h-1} cos(k w0 t) / k^2
        east(t)  = start_e - spacing/2 + (spacing/T_leg) t
                   + sum_{k = 1..h} (spacing/(pi k)) sin(2 k w0 t)

    i.e. the triangle wave and the staircase (ramp minus sawtooth) truncated to their
    first h Fourier harmonics. The north frequencies are odd and the east ones even
    multiples of w0, so all 2h frequencies differ.

    State order (4 + 4h states):

        z[0] n0     north mean, start_n + L/2 (m, constant)
        z[1] e_ramp east ramp, start_e - spacing/2 + (spacing/T_leg) t (m)
        z[2] d      depth (m, constant)
        z[3] v_e    ramp rate spacing/T_leg (m/s, constant; e_ramp' = v_e)
        then for k = 1, 3, .., 2h-1: (nc_k, ns_k), the north oscillator at k w0 (m)
        then for k = 1, .., h:       (ec_k, es_k), the east oscillator at 2 k w0 (m)

    each pair (c, s) obeys c' = -w s, s' = w c; north = n0 + sum nc_k,
    east = e_ramp + sum es_k.

    Accuracy: at mid-leg, t = (k + 1/2) T_leg, the position is exactly the ideal one
    (north = start_n + L/2, east = start_e + k spacing). At a turn, t = k T_leg, east is
    exactly the middle of the step (start_e + (k - 1/2) spacing) and north falls short of
    the leg end by :func:`lawnmower_turn_error` (0.034 L for h = 3). In particular at
    t = 0 the leader is near (start_n, start_e - spacing/2): the middle of the rounded
    turn into the first leg. The mean east speed is exactly spacing / T_leg. The speed
    along a leg is not constant (at mid-leg it is (4/pi) speed (1 - 1/3 + 1/5 ...), h
    terms: 1.27, 0.85, 1.10 times speed for h = 1, 2, 3).

    Parameters
    ----------
    leg_length : float
        Leg length L, m (> 0).
    spacing : float
        East step between legs, m (negative: west).
    speed : float
        Nominal speed along a leg, m/s (> 0); T_leg = leg_length / speed, s.
    harmonics : int, optional
        Number h >= 1 of Fourier harmonics kept.
    start : Any, optional
        Start of the first leg [north, east, down], m.
    depth : float or None, optional
        Constant down position, m (default: start's down).

    Returns
    -------
    LeaderPath
        The (4 + 4 h)-state exosystem.

    Raises
    ------
    ModelError
        If an argument is out of range or of the wrong type.
    """
    L = as_positive("leg_length", leg_length, "m")
    sp = as_number("spacing", spacing)
    v = as_positive("speed", LEADER_SPEED.check("speed", speed), "m/s")
    if isinstance(harmonics, bool) or not isinstance(harmonics, (int, np.integer)):
        raise ModelError(f"harmonics: expected a whole number >= 1, got {harmonics!r}")
    h = int(harmonics)
    if h < 1:
        raise ModelError(f"harmonics = {h} must be at least 1")
    p0 = _point("start", start)
    d = p0[2] if depth is None else as_number("depth", depth)
    T = L / v
    w0 = math.pi / T
    l_ = 4 + 4 * h
    F = np.zeros((l_, l_))
    H = np.zeros((3, l_))
    z0 = np.zeros(l_)
    names = ["n0", "e_ramp", "d", "v_e"]
    z0[:4] = [p0[0] + L / 2.0, p0[1] - sp / 2.0, d, sp / T]
    F[1, 3] = 1.0
    H[0, 0] = H[1, 1] = H[2, 2] = 1.0

    def pair(idx: int, w: float) -> None:
        F[idx, idx + 1] = -w
        F[idx + 1, idx] = w

    idx = 4
    for j in range(1, h + 1):
        k = 2 * j - 1
        pair(idx, k * w0)
        z0[idx] = -4.0 * L / (math.pi**2 * k * k)
        H[0, idx] = 1.0
        names += [f"nc_{k}", f"ns_{k}"]
        idx += 2
    for k in range(1, h + 1):
        pair(idx, 2 * k * w0)
        z0[idx] = sp / (math.pi * k)
        H[1, idx + 1] = 1.0
        names += [f"ec_{k}", f"es_{k}"]
        idx += 2
    return LeaderPath(
        kind="lawnmower", F=F, H=H, z0=z0, state_names=tuple(names),
        description=(f"lawnmower: {L:g} m north legs spaced {sp:g} m east at {v:g} m/s "
                     f"(T_leg = {T:g} s, {h} harmonics) from {p0.tolist()} m, depth {d:g} m"),
    )


def explicit(F: Any, H: Any, z0: Any) -> LeaderPath:
    """Any exosystem: F (l x l), H (s x l; 3 rows n, e, d for NED vehicles), z0 (l).

    Parameters
    ----------
    F : Any
        Exosystem matrix, l x l, 1/s.
    H : Any
        Output (position) matrix, s x l.
    z0 : Any
        Initial exosystem state, length l.

    Returns
    -------
    LeaderPath
        The exosystem, states named z1..zl.

    Raises
    ------
    ModelError
        If F is not square, H has not l columns or z0 not l entries, or a value is not
        finite.
    """
    F = as_square("F", F)
    l_ = F.shape[0]
    H = as_matrix("H", H, (None, l_))
    z0 = as_vector("z0", z0, l_)
    return LeaderPath(
        kind="explicit", F=F, H=H, z0=z0,
        state_names=tuple(f"z{i + 1}" for i in range(l_)),
        description=f"explicit exosystem with {l_} states and {H.shape[0]} outputs",
    )

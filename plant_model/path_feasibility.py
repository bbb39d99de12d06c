"""Can each vehicle fly its target path?

Vehicle i's target is the leader's position plus its formation offset, H z(t) + d_i (NED,
m; :mod:`plant_model.vehicle_targets`), so its target velocity and acceleration are the
leader's, v = H F z, a = H F^2 z, with z(t) = expm(F t) z0 (:mod:`plant_model.leader`).
Sampled exactly (z[k+1] = expm(F dt) z[k]) every ``dt`` seconds over [0, T], the target asks

- a speed |v| (m/s), against the vehicle's top speed through the water;
- a horizontal turn radius |v_h|^3 / |v_n a_e - v_e a_n| (m), against its smallest;
- a depth rate |v_d| (m/s), against its largest.

With a current of standard deviation sigma_c per axis (m/s) and ``current_factor`` k
(default 2: a 2-sigma current), the speed through the water may be |v| + k sigma_c against
the current, which the top speed must cover, and |v_h| - k sigma_c with it. Then the
**steering** check: at full rudder the vehicle turns R_min at any speed, so it can give a
lateral acceleration of (|v_h| - k sigma_c)^2 / R_min (m/s^2), which must cover the path's
own |v_h|^2 / R_path plus ``lateral_margin`` (m/s^2: what the controller adds on top, e.g.
its predicted 3-sigma noise-driven force over the mass). Without a current and a margin
it is the turn-radius check and is skipped. The worst excess of each
limit is reported with its time and the share of the horizon the limit is exceeded, per
vehicle, as one line (:func:`finding_line`; vehicles with the same finding together,
:func:`finding_lines`).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

__all__ = ["Finding", "finding_line", "finding_lines", "path_demands", "path_findings"]


@dataclass(frozen=True)
class Finding:
    """Vehicle ``vehicle`` (1-based) asks more than ``limit`` allows: the worst sample."""

    vehicle: int
    time: float          #: s, of the worst sample
    limit: str           #: "speed", "turn radius", "depth rate" or "steering"
    value: float         #: what the path asks there (m/s, m or m/s^2)
    bound: float         #: what the vehicle can do (m/s, m or m/s^2)
    source: str = ""     #: where the bound comes from
    fraction: float = 0.0  #: share of the samples over [0, T] beyond the limit


def finding_line(f: Finding, vehicles: str | None = None) -> str:
    """One line: ``vehicle 3 at t = 42.5 s: target speed 3.02 m/s above the top speed
    2.55 m/s (beyond it 12 % of the time; <source>)``; ``vehicles`` replaces
    ``vehicle 3``."""
    what = {"speed": ("target speed through the water", "m/s", "above the top speed"),
            "turn radius": ("target turn radius", "m", "below the smallest turn radius"),
            "depth rate": ("target depth rate", "m/s", "above the largest depth rate"),
            "steering": ("lateral acceleration needed", "m/s^2",
                         "above what full rudder gives at the speed through the water")}
    name, unit, rel = what[f.limit]
    who = vehicles or f"vehicle {f.vehicle}"
    return (f"{who} at t = {f.time:.4g} s: {name} {f.value:.3g} {unit} {rel} "
            f"{f.bound:.3g} {unit} (beyond it {f.fraction:.0%} of the time"
            + (f"; {f.source})" if f.source else ")"))


def finding_lines(findings: Sequence[Finding]) -> list[str]:
    """:func:`finding_line` per distinct finding, the vehicles that share it named
    together (``vehicles 1, 2, 3, 4``)."""
    groups: dict[tuple, list[Finding]] = {}
    for f in findings:
        groups.setdefault((f.limit, f.time, f.value, f.bound, f.source, f.fraction),
                          []).append(f)
    return [finding_line(fs[0], None if len(fs) == 1 else
                         "vehicles " + ", ".join(str(f.vehicle) for f in fs))
            for fs in groups.values()]


def path_samples(T: float, dt: float) -> int:
    """The samples of a path every ``dt`` s over [0, T]: floor(T / dt) + 1."""
    return int(np.floor(T / dt + 1e-9)) + 1


def path_states(F: np.ndarray, z0: np.ndarray, T: float, dt: float) -> np.ndarray:
    """The exosystem's states z(k dt) = expm(F k dt) z0, k = 0 .. floor(T / dt), one row
    each: filled by doubling blocks (rows [m, 2m) = rows [0, m) times expm(F m dt)'), a
    few dozen products for any horizon instead of one per sample.

    Parameters
    ----------
    F, z0 : np.ndarray
        The exosystem (l x l, 1/s) and its start (l).
    T, dt : float
        Horizon and sampling interval, s.

    Returns
    -------
    np.ndarray
        :func:`path_samples` x l.
    """
    F = np.asarray(F, float)
    n = path_samples(T, dt)
    Z = np.empty((n, F.shape[0]))
    Z[0] = np.asarray(z0, float)
    P = expm(F * dt)                   # expm(F filled dt)
    filled = 1
    while filled < n:
        m = min(filled, n - filled)
        Z[filled:filled + m] = Z[:m] @ P.T
        filled += m
        P = P @ P
    return Z


def path_demands(F: np.ndarray, H: np.ndarray, z0: np.ndarray, T: float, dt: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(t, speed, turn radius, depth rate) of the leader's path every ``dt`` s over [0, T].

    Parameters
    ----------
    F, H, z0 : np.ndarray
        The leader's exosystem (l x l, 1/s), NED position output (3 x l, m) and start.
    T, dt : float
        Horizon and sampling interval, s.

    Returns
    -------
    tuple of np.ndarray
        Times (s), |v| (m/s), the horizontal turn radius (m; inf on a straight line),
        |v_d| (m/s), each of length floor(T / dt) + 1.
    """
    F, H = np.asarray(F, float), np.asarray(H, float)
    Z = path_states(F, z0, T, dt)
    n = Z.shape[0]
    V = Z @ (H @ F).T
    A = Z @ (H @ F @ F).T
    speed = np.linalg.norm(V, axis=1)
    vh = np.hypot(V[:, 0], V[:, 1])
    cross = np.abs(V[:, 0] * A[:, 1] - V[:, 1] * A[:, 0])
    with np.errstate(divide="ignore", invalid="ignore"):
        radius = np.where(cross > 1e-12 * np.maximum(vh, 1e-12) ** 3, vh ** 3 / cross, np.inf)
    return np.arange(n) * dt, speed, radius, np.abs(V[:, 2])


def path_findings(F: np.ndarray, H: np.ndarray, z0: np.ndarray, T: float,
                  limits: Sequence[object], dt: float = 0.1, *, current_sigma: float = 0.0,
                  lateral_margin: float = 0.0, current_factor: float = 2.0
                  ) -> list[Finding]:
    """Per vehicle, the worst excess of each of its known limits.

    Parameters
    ----------
    F, H, z0 : np.ndarray
        The leader's path (:func:`path_demands`).
    T : float
        Horizon, s.
    limits : sequence
        Per vehicle (1-based order) an object with ``max_speed``, ``min_turn_radius``,
        ``max_depth_rate`` (None: not known, not checked) and ``source``
        (:class:`plant_model.remus100.limits.VehicleLimits`).
    dt : float, optional
        Sampling interval, s.
    current_sigma : float, optional
        The current's standard deviation per axis, m/s (module docstring).
    lateral_margin : float, optional
        Lateral acceleration the controller adds to the path's, m/s^2.
    current_factor : float, optional
        How many standard deviations of current the vehicle must fly against.

    Returns
    -------
    list[Finding]
        In vehicle order, then speed, turn radius, depth rate, steering; empty when all fit.
    """
    t, speed, radius, depth_rate = path_demands(F, H, z0, T, dt)
    c = current_factor * current_sigma
    through = speed + c                                   # against the current
    vh = np.sqrt(np.maximum(speed ** 2 - depth_rate ** 2, 0.0))       # horizontal, m/s
    with np.errstate(divide="ignore"):
        need = np.where(np.isinf(radius), 0.0, vh ** 2 / radius) + lateral_margin
    out: list[Finding] = []
    for i, lim in enumerate(limits, start=1):
        checks = [("speed", through, lim.max_speed, through > (lim.max_speed or 0), 1.0),
                  ("turn radius", radius, lim.min_turn_radius,
                   radius < (lim.min_turn_radius or 0), -1.0),
                  ("depth rate", depth_rate, lim.max_depth_rate,
                   depth_rate > (lim.max_depth_rate or 0), 1.0)]
        for name, values, bound, bad, sign in checks:
            if bound is None or not bad.any():
                continue
            k = int(np.argmax(sign * values))          # the worst sample
            out.append(Finding(i, float(t[k]), name, float(values[k]), float(bound),
                               getattr(lim, "source", ""), float(bad.mean())))
        if lim.min_turn_radius and (c > 0.0 or lateral_margin > 0.0):
            avail = np.maximum(vh - c, 0.0) ** 2 / lim.min_turn_radius
            bad = need > avail
            if bad.any():
                k = int(np.argmax(need - avail))
                out.append(Finding(i, float(t[k]), "steering", float(need[k]),
                                   float(avail[k]), getattr(lim, "source", ""),
                                   float(bad.mean())))
    return out

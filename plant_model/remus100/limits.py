"""What the nonlinear REMUS 100 can do, found by simulating it.

Three steady manoeuvres of :func:`plant_model.remus100.dynamics.step` (the model as it
is, whatever its data: nothing here is a number of the vehicle), each from straight and
level flight at 1.5 m/s with the actuators at rest, the command held for ``duration``
seconds (RK4, sub-step 0.05 s), the figures averaged over the last ``tail`` seconds:

- top speed U_max (m/s): the speed through the water at n = n_max, fins at 0;
- turn radius R_min (m): at n = n_max and the rudder at +delta_max, the horizontal speed
  over the yaw rate, U_h / |psi'| (the vehicle also sinks or rises; no depth autopilot);
- depth rate (m/s): at n = n_max and the stern planes at -delta_max (rise) and
  +delta_max (dive), |z'|; the smaller of the two is the limit.

Results are cached per vehicle data (:class:`Remus100` is frozen and hashable).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from .dynamics import STATE_SIZE, Remus100, step

__all__ = ["VehicleLimits", "remus_limits"]

#: the sub-step (s) and the communication step (s) of the manoeuvres
_SUBSTEP, _STEP = 0.05, 0.5


@dataclass(frozen=True)
class VehicleLimits:
    """A vehicle's limits (None: not known for this model)."""

    max_speed: float | None          #: m/s through the water at full rpm
    min_turn_radius: float | None    #: m, at full rudder and full rpm
    max_depth_rate: float | None     #: m/s, the smaller of full-rise and full-dive
    source: str = ""                 #: where the figures come from


def _manoeuvre(v: Remus100, command: tuple[float, float, float], duration: float,
               tail: float) -> np.ndarray:
    """States every _STEP s over the last ``tail`` s of ``duration`` s with ``command``
    ([delta_r, delta_s] rad, n rpm) held, from level flight at 1.5 m/s north."""
    x = np.zeros(STATE_SIZE)
    x[6] = 1.5
    cmd = np.asarray(command, float)
    substeps = int(round(_STEP / _SUBSTEP))
    steps = int(round(duration / _STEP))
    keep = int(round(tail / _STEP))
    out = np.empty((keep, STATE_SIZE))
    for k in range(steps):
        x = step(v, x, cmd, _STEP, substeps)
        if k >= steps - keep:
            out[k - (steps - keep)] = x
    return out


@lru_cache(maxsize=32)
def remus_limits(v: Remus100, duration: float = 80.0, tail: float = 20.0) -> VehicleLimits:
    """The top speed, turn radius and depth rate of ``v`` (module docstring).

    Parameters
    ----------
    v : Remus100
        The vehicle data.
    duration, tail : float, optional
        Seconds each command is held, and the last seconds averaged.

    Returns
    -------
    VehicleLimits
        The three limits, ``source`` naming the manoeuvres.
    """
    full = v.n_max
    straight = _manoeuvre(v, (0.0, 0.0, full), duration, tail)
    speed = float(np.mean(np.linalg.norm(straight[:, 6:9], axis=1)))
    turn = _manoeuvre(v, (v.delta_max, 0.0, full), duration, tail)
    # yaw rate from the heading's unwrapped slope, horizontal speed from the NED track
    psi = np.unwrap(turn[:, 5])
    rate = abs(float(np.polyfit(np.arange(psi.size) * _STEP, psi, 1)[0]))
    track = np.diff(turn[:, :2], axis=0) / _STEP
    u_h = float(np.mean(np.linalg.norm(track, axis=1)))
    radius = u_h / rate if rate > 0 else math.inf
    rates = []
    for ds in (-v.delta_max, v.delta_max):
        z = _manoeuvre(v, (0.0, ds, full), duration, tail)[:, 2]
        rates.append(abs(float(np.polyfit(np.arange(z.size) * _STEP, z, 1)[0])))
    return VehicleLimits(max_speed=speed, min_turn_radius=radius, max_depth_rate=min(rates),
                                  source=f"remus100-6dof simulated at {v.n_max:g} rpm, fins "
                                f"+-{math.degrees(v.delta_max):g} deg")

"""FMI 2.0 co-simulation slave ``AuvAutopilot``: speed, course and depth set-points (and
their rates) and the vehicle's measured velocity through the water, attitude, body rates
and depth in; propeller rpm, rudder and stern-plane commands out (the mathematics:
plant_model.remus100.setpoint_autopilot; docs/guidance.md).

The commands are computed from the inputs just set (direct feedthrough) and the loops'
integrals; a step integrates the errors of the inputs held over it (explicit Euler, as
the nonlinear REMUS 100's own loops), each held while its actuator is saturated. Any
communication step. FMU state: the two integrals, plus what the base class saves.
"""
from __future__ import annotations

from dataclasses import fields
from typing import Any

import numpy as np

from fmu_common.interface import ArraySpec

# pythonfmu's loader looks for "class X(Fmi2Slave):"
from fmu_common.slave_base import VectorStateSlave as Fmi2Slave
from plant_model.remus100.autopilot import AutopilotGains
from plant_model.remus100.setpoint_autopilot import DepthLoop, limit_command, setpoint_command

SETPOINTS = ("speed", "course", "depth", "speed_rate", "course_rate", "depth_rate")
SETPOINT_UNITS = ("m/s", "rad", "m", "m/s2", "rad/s", "m/s")
MEASURED = ("velocity", "attitude", "rates", "measured_depth")

_GAIN_DOC = {
    "U_max": ("m/s", "speed at n_max (the rpm feedforward n_max U_d / U_max)"),
    "n_max": ("rpm", "propeller limit (commands clipped to +-n_max; anti-windup)"),
    "K_u": (None, "speed loop: rpm per m/s of speed error"),
    "K_ui": (None, "speed loop: rpm per m of integrated speed error"),
    "K_chi": (None, "course loop: rad of rudder per rad of course error"),
    "K_r": ("s", "course loop: rad of rudder per rad/s of yaw-rate error"),
    "K_gamma": (None, "flight-path loop: rad of pitch per rad of flight-path error"),
    "K_gi": ("1/s", "flight-path loop: integral gain"),
    "K_theta": (None, "pitch loop: rad of stern plane per rad of pitch error"),
    "K_q": ("s", "pitch loop: rad of stern plane per rad/s of pitch rate"),
    "U_min": ("m/s", "speed at or below which course and flight path are not measured "
                     "(heading and pitch are used)"),
    "delta_max": ("rad", "fin limit (rudder and stern planes; commands clipped; "
                         "anti-windup)"),
    "K_z": ("1/s", "depth loop: m/s of vertical speed commanded per m of depth error"),
    "gamma_max": ("rad", "depth loop: the steepest flight path commanded"),
}
GAIN_NAMES = tuple(f.name for f in fields(AutopilotGains))
DEPTH_NAMES = tuple(f.name for f in fields(DepthLoop))


class AuvAutopilot(Fmi2Slave):
    """Set-points and measurements -> rpm, rudder, stern planes (anti-windup)."""

    state_name = "integrals"   #: [int (U_d - U) dt (m), int (gamma_d - gamma) dt (rad s)]

    description = ("Speed, course and depth autopilot of a torpedo AUV: set-points and the "
                   "measured velocity through water, attitude, rates and depth in; rpm, "
                   "rudder and stern-plane commands out, clipped to the actuator limits, "
                   "with anti-windup")

    @staticmethod
    def interface(config: dict[str, Any]) -> list[ArraySpec]:
        """The gains and limits (configuration key ``autopilot``: {name: start value},
        default AutopilotGains() and DepthLoop()), the set-points and measurements in, the
        commands out."""
        start = {**{n: getattr(AutopilotGains(), n) for n in GAIN_NAMES},
                 **{n: getattr(DepthLoop(), n) for n in DEPTH_NAMES},
                 **config.get("autopilot", {})}
        specs = [ArraySpec(n, (), "parameter", _GAIN_DOC.get(n, (None, n))[1],
                           start=float(start[n]), unit=_GAIN_DOC.get(n, (None, ""))[0])
                 for n in GAIN_NAMES + DEPTH_NAMES]
        specs += [ArraySpec(n, (), "input", f"set-point: {n.replace('_', ' ')}", unit=u)
                  for n, u in zip(SETPOINTS, SETPOINT_UNITS)]
        everything = SETPOINTS + MEASURED
        return specs + [
            ArraySpec("velocity", (3,), "input", "measured velocity through the water in "
                      "body axes [u, v, w] (a DVL's water track)", unit="m/s"),
            ArraySpec("attitude", (3,), "input", "measured roll, pitch, yaw phi, theta, psi",
                      unit="rad"),
            ArraySpec("rates", (3,), "input", "measured body rates p, q, r", unit="rad/s"),
            ArraySpec("measured_depth", (), "input", "measured depth (positive down)",
                      unit="m"),
            ArraySpec("rpm", (), "output", "propeller speed command, clipped to +-n_max",
                      unit="rpm", depends_on=everything),
            ArraySpec("rudder", (), "output", "rudder command (positive: turn to starboard), "
                      "clipped to +-delta_max", unit="rad", depends_on=everything),
            ArraySpec("stern", (), "output", "stern-plane command (positive: nose down), "
                      "clipped to +-delta_max", unit="rad", depends_on=everything),
            ArraySpec("saturated", (), "output", "1 when a command is at or beyond its "
                      "limit, else 0", depends_on=everything),
        ]

    def setup(self) -> None:
        """Gains from the parameters; integrals at 0.

        Raises
        ------
        ValueError
            If a gain is not finite, or n_max, delta_max, U_max or gamma_max is not positive.
        """
        for n in GAIN_NAMES + DEPTH_NAMES:
            v = float(self.par[n])
            if not np.isfinite(v):
                raise ValueError(f"parameter {n} = {v} is not finite")
            if n in ("n_max", "delta_max", "U_max", "gamma_max") and v <= 0.0:
                raise ValueError(f"parameter {n} = {v} must be positive")
        self.gains = AutopilotGains(**{n: float(self.par[n]) for n in GAIN_NAMES})
        self.depth_loop = DepthLoop(**{n: float(self.par[n]) for n in DEPTH_NAMES})
        self.integrals = np.zeros(2)

    def _command(self) -> tuple[np.ndarray, np.ndarray]:
        io = self.io
        sp = np.array([float(io[n]) for n in SETPOINTS])
        return setpoint_command(self.gains, self.depth_loop, sp, io["velocity"],
                                io["attitude"], io["rates"], float(io["measured_depth"]),
                                self.integrals)

    def compute_outputs(self) -> None:
        """rpm, rudder, stern (clipped) and saturated from the inputs and integrals."""
        cmd, _ = self._command()
        limited, sat = limit_command(self.gains, cmd)
        self._out[:] = [limited[2], limited[0], limited[1], float(sat)]

    def advance(self, step: float) -> None:
        """integrals += errors * step (each 0 while its actuator is saturated its way)."""
        _, err = self._command()
        self.integrals = self.integrals + err * step

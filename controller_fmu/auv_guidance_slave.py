"""FMI 2.0 co-simulation slave ``AuvGuidance``: the formation controller's NED force in,
the set-points a vehicle stack takes out (speed through water, course, depth and their
rates), through the design model's reference velocity v_ref' = (u - D v_ref) / M per NED
axis (the mathematics: controller_fmu.guidance; docs/guidance.md).

The set-points and ``v_ref`` at a communication point are the state (no feedthrough); the
rates depend on the force u just set (direct feedthrough). A step of any size advances
v_ref and the depth exactly with u held. FMU state: v_ref, the depth set-point and the held
course, plus what the base class saves.
"""
from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np

from controller_fmu.guidance import (
    check_mass_damping,
    depth_increment,
    reference_step,
    setpoints,
)
from fmu_common.interface import ArraySpec

# pythonfmu's loader looks for "class X(Fmi2Slave):"
from fmu_common.slave_base import VectorStateSlave as Fmi2Slave

RATES = ("speed_rate", "course_rate", "depth_rate")


def guidance_defaults() -> dict[str, Any]:
    """Start values when a build names none: the design model of ``remus100-6dof`` with
    its default parameters (``remus100`` linearized at its default cruise speed;
    plant_model.vehicle_models), at rest, 0 m deep, course north."""
    return {k: list(v) if isinstance(v, tuple) else v for k, v in _defaults().items()}


@functools.cache
def _defaults() -> dict[str, Any]:
    """:func:`guidance_defaults`, built once per process (a fleet asks once per vehicle)."""
    from plant_model.remus100.autopilot import AutopilotGains
    from plant_model.vehicle_models import get
    par = get("remus100-6dof").build({}).parameters
    return {"M": tuple(par["total_mass"]), "D": tuple(par["damping"]),
            "v_ref0": (0.0,) * 3, "depth0": 0.0, "course0": 0.0,
            "U_min": AutopilotGains().U_min}


class AuvGuidance(Fmi2Slave):
    """Force (N, NED) -> speed, course, depth set-points and their rates."""

    description = ("Guidance for a vehicle stack: the formation controller's NED force in; "
                   "speed through water, course, depth set-points and their rates out, "
                   "through the design model's reference velocity v' = (u - D v)/M")

    @staticmethod
    def interface(config: dict[str, Any]) -> list[ArraySpec]:
        """Parameters M, D, v_ref0, depth0, course0, U_min; input u (3); outputs the six
        set-points and v_ref (3). Configuration key ``guidance`` ({name: start value}),
        default :func:`guidance_defaults`."""
        g = {**guidance_defaults(), **config.get("guidance", {})}
        return [
            ArraySpec("M", (3,), "parameter", "total mass (rigid body and added) of the "
                      "design model per NED axis: v' = (u - D v)/M", start=g["M"], unit="kg"),
            ArraySpec("D", (3,), "parameter", "linear damping of the design model per NED "
                      "axis", start=g["D"], unit="kg/s"),
            ArraySpec("v_ref0", (3,), "parameter", "initial reference velocity through the water, "
                      "NED", start=g["v_ref0"], unit="m/s"),
            ArraySpec("depth0", (), "parameter", "initial depth set-point (the vehicle's "
                      "depth at the start)", start=float(g["depth0"]), unit="m"),
            ArraySpec("course0", (), "parameter", "course held while the horizontal "
                      "reference speed is at or below U_min from the start",
                      start=float(g["course0"]), unit="rad"),
            ArraySpec("U_min", (), "parameter", "horizontal speed at or below which the "
                      "course is not defined (the last course is held)",
                      start=float(g["U_min"]), unit="m/s", min=0.0),
            ArraySpec("u", (3,), "input", "NED force commanded by the formation controller",
                      unit="N"),
            ArraySpec("speed", (), "output", "speed set-point through the water, the norm of "
                      "v_ref",
                      unit="m/s"),
            ArraySpec("course", (), "output", "course set-point atan2(v_E, v_N) through the "
                      "water (held below U_min)", unit="rad"),
            ArraySpec("depth", (), "output", "depth set-point: depth0 + integral of v_ref_D",
                      unit="m"),
            ArraySpec("speed_rate", (), "output",
                      "rate of the speed set-point, v_ref . v_ref' / speed",
                      unit="m/s2", depends_on=("u",)),
            ArraySpec("course_rate", (), "output", "rate of the course set-point",
                      unit="rad/s", depends_on=("u",)),
            ArraySpec("depth_rate", (), "output", "rate of the depth set-point (v_ref_D)",
                      unit="m/s"),
            ArraySpec("v_ref", (3,), "output", "the design model's reference velocity "
                      "through the water, NED", unit="m/s"),
        ]

    def setup(self) -> None:
        """Check M, D (positive), v_ref0, depth0, course0 (finite) and start the state.

        Raises
        ------
        ValueError
            Naming the parameter that is invalid.
        """
        self.M, self.D = check_mass_damping(self.par["M"], self.par["D"])
        for name in ("v_ref0", "depth0", "course0", "U_min"):
            if not np.all(np.isfinite(self.par[name])):
                raise ValueError(f"parameter {name} = {self.par[name].tolist()} is not finite")
        self.U_min = float(self.par["U_min"])
        self.s = np.zeros(5)           # [v_ref (3), depth, held course]
        self.s[:3] = self.par["v_ref0"]
        self.s[3] = float(self.par["depth0"])
        self.s[4] = self._course(self.s[:3], float(self.par["course0"]))

    def _course(self, v: np.ndarray, held: float) -> float:
        return math.atan2(v[1], v[0]) if math.hypot(v[0], v[1]) > self.U_min else held

    def compute_outputs(self) -> None:
        """The set-points of the state and the rates with the force just set."""
        sp = setpoints(self.s[:3], self.io["u"], self.M, self.D, self.s[3], self.s[4],
                       self.U_min)
        self._out[:6] = sp
        self._out[6:] = self.s[:3]

    def advance(self, step: float) -> None:
        """v_ref and the depth over one step with u held (exact); the course held or new."""
        u = self.io["u"]
        s = self.s
        s[3] += depth_increment(s[2], u[2], self.M[2], self.D[2], step)
        s[:3] = reference_step(s[:3], u, self.M, self.D, step)
        s[4] = self._course(s[:3], s[4])

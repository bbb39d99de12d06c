"""What the two FMU slaves of the nonlinear REMUS 100 share: ``AuvRemus6dof`` (NED force
in, its own autopilot inside; model ``remus100-6dof``) and ``AuvRemus6dofActuated``
(actuator commands in; model ``remus100-6dof-guided``, the autopilot an FMU of its own).

Both have the linear design model's matrices (the force interface M, D, the current's
exosystem and the noise), the vehicle's data, the RK4 sub-step and the navigation sensors
as parameters, and the outputs y, x, w, attitude, rpm, rudder, stern, saturated (and nav).
They differ in their input and in what the autopilot gains are for (:class:`Remus6dofSlave`'s
class attributes). pythonfmu takes one slave class per file, and a slave module is not
shipped inside another FMU, so the shared code lives here.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from fmu_common.interface import ArraySpec
from plant_model.navigation import (
    nav_output_spec,
    sensor_parameter_specs,
    sensors_from_parameters,
)
from plant_model.parameters import VEHICLE_PARAMETERS, vehicle_parameter_specs
from plant_model.per_vehicle import sample_vehicle
from plant_model.remus100.autopilot import AutopilotGains
from plant_model.remus100.dynamics import Remus100
from plant_model.remus100.plant import (
    GAIN_FIELDS,
    REMUS_FIELDS,
    Remus6dofPlant,
    default_substep,
    linear_mass_damping,
    remus_from_parameters,
    substep_count,
)
from plant_model.slave_common import PlantSlave, vehicle_view

__all__ = ["REMUS_OUTPUTS", "Remus6dofSlave", "VEHICLE_PARAMETERS"]

_UNITS = {"L": "m", "diam": "m", "rho": "kg/m3", "T_surge": "s", "T_sway": "s", "T_yaw": "s",
          "A_rudder": "m2", "A_stern": "m2", "delta_max": "rad", "T_delta": "s",
          "n_max": "rpm", "T_n": "s", "D_prop": "m", "U_max": "m/s", "U_min": "m/s"}

#: the outputs both vehicle FMUs have, in order (then their own, then nav)
REMUS_OUTPUTS = (
    ArraySpec("y", (3,), "output", "position fix: NED position plus sensor noise", unit="m"),
    ArraySpec("x", (6,), "output", "NED position (m) and velocity over ground (m/s)"),
    ArraySpec("w", (3,), "output", "ocean current, NED", unit="m/s"),
    ArraySpec("attitude", (3,), "output", "roll, pitch, yaw phi, theta, psi", unit="rad"),
    ArraySpec("rpm", (), "output", "propeller speed", unit="rpm"),
    ArraySpec("rudder", (), "output", "rudder angle (positive: turn to starboard)",
              unit="rad"),
    ArraySpec("stern", (), "output", "stern-plane angle (positive: dive)", unit="rad"),
    ArraySpec("saturated", (), "output", "1 when an actuator command of the last step "
              "was at or beyond its limit, else 0"),
)


class Remus6dofSlave(PlantSlave):
    """One nonlinear REMUS 100 (module docstring); a subclass names its inputs, its extra
    outputs, the autopilot gains it takes and its plant class."""

    #: the gains of plant_model.remus100.autopilot.AutopilotGains that are parameters
    gain_fields: tuple[str, ...] = GAIN_FIELDS
    #: what the gains are for (the parameters' descriptions)
    gain_role = "autopilot gain"
    #: the plant (Remus6dofPlant or a subclass)
    plant_class: type[Remus6dofPlant] = Remus6dofPlant

    @classmethod
    def inputs(cls) -> list[ArraySpec]:
        """The inputs, in order (the buffer the plant's ``step`` takes)."""
        raise NotImplementedError

    @classmethod
    def extra_outputs(cls) -> list[ArraySpec]:
        """Outputs after :data:`REMUS_OUTPUTS` (before nav), in the plant's output order."""
        return []

    @classmethod
    def interface(cls, config: dict[str, Any]) -> list[ArraySpec]:
        """Parameters (the linear design model, the vehicle's data, the autopilot gains,
        the sub-step), the inputs and the outputs. Configuration keys (see
        :meth:`ArraySlave.interface`): ``dims``, ``system``, ``h``, ``seed``, ``vehicle``,
        ``remus`` ({field: value}), ``autopilot`` ({gain: value}), ``substep``.
        """
        default_remus, default_gains = Remus100(), AutopilotGains()
        remus = {**{f: getattr(default_remus, f) for f in REMUS_FIELDS},
                 **config.get("remus", {})}
        gains = {**{f: getattr(default_gains, f) for f in GAIN_FIELDS},
                 **config.get("autopilot", {})}
        specs = vehicle_parameter_specs(config, "sample period: the communication step",
                                        "the vehicle's number in the fleet, 1..N") + [
            ArraySpec("substep", (), "parameter", "RK4 sub-step; must divide h",
                      start=config.get("substep") or default_substep(float(config["h"])),
                      unit="s"),
            ArraySpec("remus.r_g", (3,), "parameter", "centre of gravity from CO (= CB), body "
                      "axes", start=np.asarray(config.get("remus", {}).get(
                          "r_g", default_remus.r_g), float), unit="m"),
        ]
        specs += [ArraySpec(f"remus.{f}", (), "parameter", f"REMUS 100 data: {f} "
                            "(plant_model.remus100.dynamics.Remus100)", start=float(remus[f]),
                            unit=_UNITS.get(f)) for f in REMUS_FIELDS]
        specs += [ArraySpec(f"autopilot.{f}", (), "parameter", f"{cls.gain_role} {f} "
                            "(plant_model.remus100.autopilot.AutopilotGains)",
                            start=float(gains[f]), unit=_UNITS.get(f))
                  for f in cls.gain_fields]
        return (specs + sensor_parameter_specs(config) + cls.inputs() + list(REMUS_OUTPUTS)
                + cls.extra_outputs() + nav_output_spec(config))

    def setup(self) -> None:
        """Build the vehicle from the parameters and start it at [x0; w0].

        Raises
        ------
        ModelError
            Naming the parameter that is invalid (a vehicle datum, a gain, the sub-step).
        """
        view = vehicle_view(self, VEHICLE_PARAMETERS)
        h = float(self.par["h"])
        linear = sample_vehicle(view, h, int(self.par["vehicle"]))
        vehicle = remus_from_parameters(
            {**{f: self.par[f"remus.{f}"] for f in REMUS_FIELDS}, "r_g": self.par["remus.r_g"]})
        gains = AutopilotGains(**{f: float(self.par[f"autopilot.{f}"])
                                  for f in self.gain_fields})
        M, D = linear_mass_damping(view.B1, view.B2)
        substeps = substep_count(h, float(self.par["substep"]))
        sensors = sensors_from_parameters(self.par) if self.config.get("sensors") else None
        self.plant = self.plant_class(vehicle, gains, linear, M, D, view.x0, view.w0,
                                      int(self.par["seed"]), substeps, out=self._out,
                                      sensors=sensors)
        self._u = self._in            # the inputs, in order: what the plant's step takes

    def _who(self) -> str:
        return f"{super()._who()} (vehicle {int(self.par.get('vehicle', 0))})"

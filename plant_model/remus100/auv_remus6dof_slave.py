"""FMI 2.0 co-simulation slave of one nonlinear REMUS 100 (model ``remus100-6dof``,
per-vehicle deployment; plant_model.remus100.plant).

The same inputs and first outputs as the linear ``AuvVehicle``: input u (NED force, N);
outputs y (position fix), x (position and velocity over ground), w (current). Extra
outputs: attitude, propeller rpm, rudder and stern-plane angles, ``saturated``. The linear
matrices (A, B1, B2, C, K, noise) are the design model's: they give the force interface
(M, D), the current's exosystem and the noise, drawn from the generator [seed, vehicle]
as the linear vehicle draws it. A state that becomes non-finite ends the step with an
error status naming the vehicle and the time.
"""
from typing import Any

import numpy as np

from fmu_common.interface import ArraySpec
from plant_model.navigation import (
    nav_output_spec,
    sensor_parameter_specs,
    sensors_from_parameters,
)
from plant_model.parameters import (
    integer_spec,
    noise_convention_spec,
    sample_period_spec,
    system_parameter_specs,
    vehicle_seed_spec,
)
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

# pythonfmu's loader looks for "class X(Fmi2Slave):"
from plant_model.slave_common import PlantSlave as Fmi2Slave
from plant_model.slave_common import vehicle_view

VEHICLE_PARAMETERS = ("A", "B1", "B2", "C", "K", "x0", "w0", "W_x", "W_w", "V_y", "V_ybar")

_UNITS = {"L": "m", "diam": "m", "rho": "kg/m3", "T_surge": "s", "T_sway": "s", "T_yaw": "s",
          "A_rudder": "m2", "A_stern": "m2", "delta_max": "rad", "T_delta": "s",
          "n_max": "rpm", "T_n": "s", "D_prop": "m", "U_max": "m/s", "U_min": "m/s"}


class AuvRemus6dof(Fmi2Slave):
    """One nonlinear 6-DOF REMUS 100 with its autopilots, current and position sensor."""

    description = ("One nonlinear 6-DOF REMUS 100 (per-vehicle deployment): NED force in, "
                   "autopilots to rpm, rudder and stern planes, RK4 sub-steps; its own "
                   "ocean current and noisy position sensor")

    @staticmethod
    def interface(config: dict[str, Any]) -> list[ArraySpec]:
        """Parameters (the linear design model, the vehicle's data, the autopilot gains,
        the sub-step), the input u (3) and the outputs. Configuration keys (see
        :meth:`ArraySlave.interface`): ``dims``, ``system``, ``h``, ``seed``, ``vehicle``,
        ``remus`` ({field: value}), ``autopilot`` ({gain: value}), ``substep``.
        """
        remus = {**{f: getattr(Remus100(), f) for f in REMUS_FIELDS},
                 **config.get("remus", {})}
        gains = {**{f: getattr(AutopilotGains(), f) for f in GAIN_FIELDS},
                 **config.get("autopilot", {})}
        specs = system_parameter_specs(config, VEHICLE_PARAMETERS) + [
            sample_period_spec(config, "sample period: the communication step"),
            vehicle_seed_spec(config),
            integer_spec("vehicle", "the vehicle's number in the fleet, 1..N",
                         config.get("vehicle", 1), 1),
            noise_convention_spec(config),
            ArraySpec("substep", (), "parameter", "RK4 sub-step; must divide h",
                      start=config.get("substep") or default_substep(float(config["h"])),
                      unit="s"),
            ArraySpec("remus.r_g", (3,), "parameter", "centre of gravity from CO (= CB), body "
                      "axes", start=np.asarray(config.get("remus", {}).get(
                          "r_g", Remus100().r_g), float), unit="m"),
        ]
        specs += [ArraySpec(f"remus.{f}", (), "parameter", f"REMUS 100 data: {f} "
                            "(plant_model.remus100.dynamics.Remus100)", start=float(remus[f]),
                            unit=_UNITS.get(f)) for f in REMUS_FIELDS]
        specs += [ArraySpec(f"autopilot.{f}", (), "parameter", f"autopilot gain {f} "
                            "(plant_model.remus100.autopilot.AutopilotGains)",
                            start=float(gains[f]), unit=_UNITS.get(f)) for f in GAIN_FIELDS]
        return specs + sensor_parameter_specs(config) + [
            ArraySpec("u", (3,), "input", "NED force commanded (control and consensus)",
                      unit="N"),
            ArraySpec("y", (3,), "output", "position fix: NED position plus sensor noise",
                      unit="m"),
            ArraySpec("x", (6,), "output", "NED position (m) and velocity over ground (m/s)"),
            ArraySpec("w", (3,), "output", "ocean current, NED", unit="m/s"),
            ArraySpec("attitude", (3,), "output", "roll, pitch, yaw phi, theta, psi",
                      unit="rad"),
            ArraySpec("rpm", (), "output", "propeller speed", unit="rpm"),
            ArraySpec("rudder", (), "output", "rudder angle (positive: turn to starboard)",
                      unit="rad"),
            ArraySpec("stern", (), "output", "stern-plane angle (positive: dive)", unit="rad"),
            ArraySpec("saturated", (), "output", "1 when an actuator command of the last step "
                      "was at or beyond its limit, else 0"),
        ] + nav_output_spec(config)

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
        gains = AutopilotGains(**{f: float(self.par[f"autopilot.{f}"]) for f in GAIN_FIELDS})
        M, D = linear_mass_damping(view.B1, view.B2)
        substeps = substep_count(h, float(self.par["substep"]))
        sensors = sensors_from_parameters(self.par) if self.config.get("sensors") else None
        self.plant = Remus6dofPlant(vehicle, gains, linear, M, D, view.x0, view.w0,
                                    int(self.par["seed"]), substeps, out=self._out,
                                    sensors=sensors)
        self._u = self.io["u"]

    def _who(self) -> str:
        return f"{super()._who()} (vehicle {int(self.par.get('vehicle', 0))})"

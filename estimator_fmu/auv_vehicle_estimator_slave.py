"""FMI 2.0 co-simulation slave of one vehicle's estimator (per-vehicle deployment).

Inputs y (the vehicle's own measurement), the truth x, w (read only in mode 'ideal'), then
u; outputs the estimate xhat, what of sample k, which already includes y[k] (direct
feedthrough). The mathematics is estimator_fmu.estimators.make_vehicle_estimator on the
vehicle sampled alone (plant_model.per_vehicle). FMU state: q, plus what the base class
saves.
"""
from typing import Any

from estimator_fmu.multirate import navigation_estimator
from estimator_fmu.registry import (
    ESTIMATOR_MODES,
    make_vehicle_estimator,
    options_of,
    parameter_specs,
)

# pythonfmu's loader looks for "class X(Fmi2Slave):"
from estimator_fmu.slave_common import EstimatorSlave as Fmi2Slave
from fmu_common.interface import ArraySpec
from plant_model.navigation import NAV_SIZE, sensor_parameter_specs, sensors_from_parameters
from plant_model.parameters import (
    noise_convention_spec,
    sample_period_spec,
    system_parameter_specs,
)
from plant_model.per_vehicle import sample_vehicle
from plant_model.slave_common import vehicle_view

ESTIMATOR_PARAMETERS = ("A", "B1", "B2", "C", "K", "x0", "w0", "W_x", "W_w", "V_y")
MEASUREMENTS = ("y", "x", "w")


class AuvVehicleEstimator(Fmi2Slave):
    """One vehicle's steady-state Kalman filter on [x; w] from its own y (or the truth)."""

    description = ("Estimator of one AUV (per-vehicle deployment): steady-state Kalman filter "
                   "on the vehicle and its ocean current from its own position fixes")

    @staticmethod
    def interface(config: dict[str, Any]) -> list[ArraySpec]:
        """The vehicle's parameters, h, noise convention, mode; y (p,) (or the navigation
        sensors), x (n,), w (r,), u (m,) in; xhat (n,), what (r,) out, fed through from the
        measurements. Configuration keys (see :meth:`ArraySlave.interface`): ``dims``,
        ``system``, ``h``, ``mode``.
        """
        d = config["dims"]
        n, m, r, p = d["n"], d["m"], d["r"], d["p"]
        measured = (ArraySpec("nav", (NAV_SIZE,), "input", "navigation sensors [fix (3), dvl "
                              "(3), depth, valid (3)] (plant_model.navigation)")
                    if config.get("sensors") else
                    ArraySpec("y", (p,), "input", "the vehicle's measured output y"))
        return system_parameter_specs(config, ESTIMATOR_PARAMETERS) + [
            sample_period_spec(config, "sample period the filter is designed for"),
            noise_convention_spec(config),
            ArraySpec("mode", (), "parameter", "estimator: " + ", ".join(ESTIMATOR_MODES),
                      start=config["estimator"], type="String"),
            *parameter_specs(config),
            *sensor_parameter_specs(config),
            measured,
            ArraySpec("x", (n,), "input", "true vehicle state (read only in mode 'ideal')"),
            ArraySpec("w", (r,), "input", "true disturbance state (read only in mode 'ideal')"),
            ArraySpec("u", (m,), "input", "force applied over the coming step"),
            ArraySpec("xhat", (n,), "output", "estimate of the vehicle state x",
                      depends_on=(measured.name, "x", "w")),
            ArraySpec("what", (r,), "output", "estimate of the disturbance state w",
                      depends_on=(measured.name, "x", "w")),
        ]

    def setup(self) -> None:
        """Sample the vehicle at h and make the estimator of the chosen mode.

        Raises
        ------
        ModelError
            If the parameters do not make a valid vehicle or the estimator does not exist.
        """
        view = vehicle_view(self, ESTIMATOR_PARAMETERS)
        model = sample_vehicle(view, float(self.par["h"]), 1)
        if self.config.get("sensors"):        # acoustic fixes, DVL, depth at their rates
            self.estimator = navigation_estimator(view, model, self.par["mode"],
                                                  sensors_from_parameters(self.par))
            self._mvec = self._in[:NAV_SIZE + model.ns]
        else:
            self.estimator = make_vehicle_estimator(view, model, self.par["mode"],
                                                    options=options_of(self.par, {}))
            self._mvec = self._in[:view.p + model.ns]
        self._u = self.io["u"]

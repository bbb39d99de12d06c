"""FMI 2.0 co-simulation slave of one vehicle (per-vehicle deployment; plant_model.per_vehicle).

Input u (the total force the vehicle's controller applies, held over the step); outputs the
measured y = C x + n and the truth x, w (for scoring and the ``ideal`` estimator). Only the
vehicle's own physics and its own ocean current: no consensus term, no leader. Its noise
stream is the generator seeded [seed, vehicle], the same numbers as vehicle ``vehicle`` of
the stacked fleet. FMU state: the plant's s, k, current noise row and noise stream, plus what
the base class saves.
"""
from typing import Any

import numpy as np

from fmu_common.interface import ArraySpec
from fmu_common.native_form import NativeForm
from plant_model.navigation import (
    NAV_SIZE,
    SensedVehicle,
    nav_output_spec,
    sensor_parameter_specs,
    sensors_from_parameters,
)
from plant_model.parameters import (
    VEHICLE_PARAMETERS,
    vehicle_parameter_specs,
)
from plant_model.per_vehicle import sample_vehicle
from plant_model.plant import Plant

# pythonfmu's loader looks for "class X(Fmi2Slave):"
from plant_model.slave_common import PlantSlave as Fmi2Slave
from plant_model.slave_common import vehicle_view


class AuvVehicle(Fmi2Slave):
    """One AUV: its dynamics, its ocean current and its position sensor, sampled at h."""

    description = ("One AUV of a fleet (per-vehicle deployment): linear vehicle, its own "
                   "ocean current, noisy position sensor, its own noise stream; exact sampling")

    @staticmethod
    def interface(config: dict[str, Any]) -> list[ArraySpec]:
        """One vehicle's model parameters, h, seed and number; u (m,) in; y (p,), x (n,),
        w (r,) out. Configuration keys (see :meth:`ArraySlave.interface`): ``dims``,
        ``system``, ``h``, ``seed``, ``vehicle``.
        """
        d = config["dims"]
        n, m, r, p = d["n"], d["m"], d["r"], d["p"]
        return vehicle_parameter_specs(
            config, "sample period: the communication step the vehicle is discretized for",
            "the vehicle's number in the fleet, 1..N (keys its noise stream)") + [
            ArraySpec("u", (m,), "input", "total force u held over the step (control and "
                      "consensus)"),
            ArraySpec("y", (p,), "output", "measured output y = C x + n"),
            ArraySpec("x", (n,), "output", "true vehicle state x"),
            ArraySpec("w", (r,), "output", "true disturbance (ocean current) state w"),
        ] + sensor_parameter_specs(config) + nav_output_spec(config)

    def setup(self) -> None:
        """Sample the vehicle at h and start it at [x0; w0] with its own noise stream.

        Raises
        ------
        ModelError
            If the parameters do not make a valid vehicle or h is not positive.
        """
        view = vehicle_view(self, VEHICLE_PARAMETERS)
        self.model = sample_vehicle(view, float(self.par["h"]), int(self.par["vehicle"]))
        self._buf = np.empty(3 * view.p + self.model.ns)      # [y, ybar, x, w, e]
        self._s0 = np.concatenate([view.x0, view.w0])
        self.plant = Plant(self.model, self._s0, int(self.par["seed"]), out=self._buf)
        if self.config.get("sensors"):          # the nav output closes the output buffer
            self.plant = SensedVehicle(self.plant, sensors_from_parameters(self.par),
                                       self._out[-NAV_SIZE:])
        s, ns = view.p, self.model.ns
        self._from = np.r_[0:s, 2 * s:2 * s + ns]             # y, then x and w
        self._u = self.io["u"]
        self._copy()

    def _copy(self) -> None:
        np.take(self._buf, self._from, out=self._out[:self._from.size])

    def native_form(self) -> NativeForm:
        """y, x, w = Cq s (+ Lr xi), s+ = Ad s + Bd u + Lq xi (numpy's normals, stream [seed, i]).

        Raises
        ------
        NotImplementedError
            With navigation sensors (their schedule and dropouts are not linear).
        """
        if self.config.get("sensors"):
            raise NotImplementedError("AuvVehicle with navigation sensors has no native (C) "
                                      "form")
        return self.plant_native_form(self._s0, self._from)

    def advance(self, step: float) -> None:
        """One sample period, then the outputs of sample k + 1 copied (compute_outputs: none).

        Parameters
        ----------
        step : float
            The communication step, s (checked against h by the base class).
        """
        super().advance(step)
        self._copy()

    def restore_model_state(self, state: Any) -> None:
        """Restore the plant's state (:meth:`Plant.set_state`) and its outputs.

        ``state`` is the dict :meth:`model_state` returned; ValueError if it does not fit
        this vehicle (seed, shapes).
        """
        super().restore_model_state(state)
        self._copy()

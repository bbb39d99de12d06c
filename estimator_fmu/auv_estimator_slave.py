"""FMI 2.0 co-simulation slave of the estimator (a thin adapter over estimator_fmu.estimators).

Inputs y, ybar (and the truth x, w, z, read only in mode 'ideal'), then u; outputs the
estimate xhat, what, zhat of sample k, which already includes y[k] (direct feedthrough).
FMU state: the estimator's q (LinearEstimator.get_state), plus what the base class saves.
"""
from typing import Any

from estimator_fmu.registry import ESTIMATOR_MODES, make_estimator, options_of, parameter_specs

# pythonfmu's loader looks for "class X(Fmi2Slave):"
from estimator_fmu.slave_common import EstimatorSlave as Fmi2Slave
from fmu_common.interface import ArraySpec
from plant_model.parameters import (
    model_parameter_specs,
    noise_convention_spec,
    sample_period_spec,
)
from plant_model.slave_common import sampled_system

ESTIMATOR_PARAMETERS = ("A", "B1", "B2", "C", "F", "H", "K", "x0", "w0", "z0",
                        "W_x", "W_w", "W_z", "V_y", "V_ybar")
MEASUREMENTS = ("y", "ybar", "x", "w", "z")


class AuvEstimator(Fmi2Slave):
    """The estimator of its ``mode`` (estimator_fmu.registry): Kalman filters, the classical
    law or the truth."""

    description = ("State estimator for the AUV tracking law: steady-state Kalman filters "
                   "(current-estimator form), the paper's classical law, or the true state")

    @staticmethod
    def interface(config: dict[str, Any]) -> list[ArraySpec]:
        """Model parameters, h, noise convention, mode; the inputs y, ybar (p,), x (n,),
        w (r,), z (l,), u (m,); the outputs xhat (n,), what (r,), zhat (l,), which feed
        through from the measurements. Configuration keys (see
        :meth:`ArraySlave.interface`): ``dims``, ``system``, ``h``, ``mode``, ``fleet``.
        """
        d = config["dims"]
        n, m, r, p, l_ = d["n"], d["m"], d["r"], d["p"], d["l"]
        return model_parameter_specs(config, "estimator", ESTIMATOR_PARAMETERS) + [
            sample_period_spec(config, "sample period the filters are designed for"),
            noise_convention_spec(config),
            ArraySpec("mode", (), "parameter", "estimator: " + ", ".join(ESTIMATOR_MODES),
                      start=config["estimator"], type="String"),
            *parameter_specs(config),
            ArraySpec("y", (p,), "input", "measured vehicle output y"),
            ArraySpec("ybar", (p,), "input", "measured reference output ybar"),
            ArraySpec("x", (n,), "input", "true vehicle state (read only in mode 'ideal')"),
            ArraySpec("w", (r,), "input", "true disturbance state (read only in mode 'ideal')"),
            ArraySpec("z", (l_,), "input", "true reference state (read only in mode 'ideal')"),
            ArraySpec("u", (m,), "input", "control input applied over the coming step"),
            ArraySpec("xhat", (n,), "output", "estimate of the vehicle state x",
                      depends_on=MEASUREMENTS),
            ArraySpec("what", (r,), "output", "estimate of the disturbance state w",
                      depends_on=MEASUREMENTS),
            ArraySpec("zhat", (l_,), "output", "estimate of the reference state z",
                      depends_on=MEASUREMENTS),
        ]

    def setup(self) -> None:
        """Build the system from the parameters, sample it at h and make the estimator.

        Raises
        ------
        ModelError
            If the parameters do not make a valid system, h is not positive or the
            estimator of the chosen mode does not exist.
        """
        system, model = sampled_system(self, "estimator", ESTIMATOR_PARAMETERS)
        self.estimator = make_estimator(system, model, self.par["mode"],
                                        options_of(self.par, self.config))
        nm = 2 * system.p + model.ns
        self._mvec = self._in[:nm]
        self._u = self.io["u"]

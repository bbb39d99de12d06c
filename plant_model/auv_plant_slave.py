"""FMI 2.0 co-simulation slave of the plant (a thin adapter over plant_model.plant).

Inputs u; outputs y, ybar (noisy measurements) and the truth x, w, z, e = H z - C x.
No output depends directly on u (the plant is strictly proper when sampled).
FMU state: the plant's s, k, current noise row and noise stream (Plant.get_state), plus
what the base class saves (parameters, buffers, flags).
"""
from typing import Any

from fmu_common.interface import ArraySpec
from fmu_common.native_form import NativeForm
from plant_model.parameters import (
    integer_spec,
    model_parameter_specs,
    noise_convention_spec,
    sample_period_spec,
)
from plant_model.plant import Plant

# pythonfmu's loader looks for "class X(Fmi2Slave):"
from plant_model.slave_common import PlantSlave as Fmi2Slave
from plant_model.slave_common import sampled_system

PLANT_PARAMETERS = ("A", "B1", "B2", "C", "F", "H", "K", "x0", "w0", "z0",
                    "W_x", "W_w", "W_z", "V_y", "V_ybar")


class AuvPlant(Fmi2Slave):
    """Vehicles, disturbance and reference exosystems and noisy sensors, sampled at h."""

    description = ("AUV consensus tracking plant (Yuan, Zhang, Zhou): linear vehicles, "
                   "disturbance and reference exosystems, noisy sensors; exact sampling")

    @staticmethod
    def interface(config: dict[str, Any]) -> list[ArraySpec]:
        """Model parameters, h, seed, noise convention; the input u (m,); the outputs y,
        ybar (p,), x (n,), w (r,), z (l,), e (p,). Configuration keys (see
        :meth:`ArraySlave.interface`): ``dims``, ``system``, ``h``, ``seed``, ``fleet``.
        """
        d = config["dims"]
        n, m, r, p, l_ = d["n"], d["m"], d["r"], d["p"], d["l"]
        return model_parameter_specs(config, "plant", PLANT_PARAMETERS) + [
            sample_period_spec(config, "sample period: the communication step the plant "
                               "is discretized for"),
            integer_spec("seed", "seed of the noise generator (numpy PCG64)", config["seed"], 0),
            noise_convention_spec(config),
            ArraySpec("u", (m,), "input", "control input u held over the step"),
            ArraySpec("y", (p,), "output", "measured vehicle output y = C x + n"),
            ArraySpec("ybar", (p,), "output", "measured reference output ybar = H z + n_z"),
            ArraySpec("x", (n,), "output", "true vehicle state x"),
            ArraySpec("w", (r,), "output", "true disturbance state w"),
            ArraySpec("z", (l_,), "output", "true reference state z"),
            ArraySpec("e", (p,), "output", "true tracking error e = H z - C x"),
        ]

    def setup(self) -> None:
        """Build the system from the parameters, sample it at h and start the plant at s(0).

        Raises
        ------
        ModelError
            If the parameters do not make a valid system or h is not positive.
        """
        system, self.model = sampled_system(self, "plant", PLANT_PARAMETERS)
        # the plant writes [y, ybar, x, w, z, e] straight into this FMU's output buffer
        self._s0 = system.initial_state()
        self.plant = Plant(self.model, self._s0, int(self.par["seed"]), out=self._out)
        self._u = self.io["u"]

    def native_form(self) -> NativeForm:
        """y, ybar, x, w, z, e = Cq s (+ Lr xi), s+ = Ad s + Bd u + Lq xi (this plant's normals)."""
        return self.plant_native_form(self._s0, range(self._out.size))

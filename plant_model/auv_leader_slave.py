"""FMI 2.0 co-simulation slave of the virtual leader (per-vehicle deployment).

The leader's exosystem alone, z[k+1] = expm(F h) z[k] + v_z[k] (plant_model.per_vehicle);
output z. No input. Its noise (zero for a planned path) comes from the generator seeded
[seed, 0]. FMU state: s = z, k, the noise row and stream, plus what the base class saves.
"""
from typing import Any

import numpy as np

from fmu_common.interface import ArraySpec
from fmu_common.native_form import NativeForm
from plant_model.parameters import (
    integer_spec,
    noise_convention_spec,
    sample_period_spec,
    system_parameter_specs,
)
from plant_model.per_vehicle import leader_system, sample_leader
from plant_model.plant import Plant

# pythonfmu's loader looks for "class X(Fmi2Slave):"
from plant_model.slave_common import PlantSlave as Fmi2Slave

LEADER_PARAMETERS = ("F", "z0", "W_z")


class AuvLeader(Fmi2Slave):
    """The virtual leader: a reference exosystem (a planned survey path or a noisy one)."""

    description = ("Virtual leader of an AUV fleet (per-vehicle deployment): the reference "
                   "exosystem z' = F z + m_z, exactly sampled")

    @staticmethod
    def interface(config: dict[str, Any]) -> list[ArraySpec]:
        """F, z0, W_z, h, seed and noise convention; the output z (l,). Configuration keys
        (see :meth:`ArraySlave.interface`): ``dims``, ``system``, ``h``, ``seed``.
        """
        return system_parameter_specs(config, LEADER_PARAMETERS) + [
            sample_period_spec(config, "sample period the leader is discretized for"),
            integer_spec("seed", "seed of the fleet's noise (the leader draws from the "
                         "generator seeded [seed, 0])", config["seed"], 0),
            noise_convention_spec(config),
            ArraySpec("z", (config["dims"]["l"],), "output", "the leader's state z"),
        ]

    def setup(self) -> None:
        """Sample the leader at h and start it at z0.

        Raises
        ------
        ModelError
            If F, z0 or W_z are invalid or h is not positive.
        """
        conv = self.par["noise_convention"]
        F, z0, W = leader_system(self.par["F"], self.par["z0"], self.par["W_z"], conv)
        self.model = sample_leader(F, W, float(self.par["h"]), conv)
        self._z0 = z0
        self.plant = Plant(self.model, z0, int(self.par["seed"]), out=self._out)
        self._u = np.zeros(0)

    def native_form(self) -> NativeForm:
        """z = z_k, z+ = Phi z + Lq xi (numpy's normals of the stream [seed, 0], as here)."""
        return self.plant_native_form(self._z0, range(self._out.size))

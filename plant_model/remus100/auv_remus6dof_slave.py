"""FMI 2.0 co-simulation slave of one nonlinear REMUS 100 (model ``remus100-6dof``,
per-vehicle deployment; plant_model.remus100.plant).

The same inputs and first outputs as the linear ``AuvVehicle``: input u (NED force, N);
outputs y (position fix), x (position and velocity over ground), w (current). Extra
outputs: attitude, propeller rpm, rudder and stern-plane angles, ``saturated``. The linear
matrices (A, B1, B2, C, K, noise) are the design model's: they give the force interface
(M, D), the current's exosystem and the noise, drawn from the generator [seed, vehicle]
as the linear vehicle draws it. A state that becomes non-finite ends the step with an
error status naming the vehicle and the time. The code it shares with
``AuvRemus6dofActuated``: plant_model.remus100.remus6dof_slave_base.
"""
from fmu_common.interface import ArraySpec

# pythonfmu's loader looks for "class X(Fmi2Slave):"
from plant_model.remus100.remus6dof_slave_base import Remus6dofSlave as Fmi2Slave


class AuvRemus6dof(Fmi2Slave):
    """One nonlinear 6-DOF REMUS 100 with its autopilots, current and position sensor."""

    description = ("One nonlinear 6-DOF REMUS 100 (per-vehicle deployment): NED force in, "
                   "autopilots to rpm, rudder and stern planes, RK4 sub-steps; its own "
                   "ocean current and noisy position sensor")

    @classmethod
    def inputs(cls) -> list[ArraySpec]:
        """u (3): the NED force commanded, N."""
        return [ArraySpec("u", (3,), "input", "NED force commanded (control and consensus)",
                          unit="N")]

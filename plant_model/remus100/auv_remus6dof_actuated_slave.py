"""FMI 2.0 co-simulation slave of one nonlinear REMUS 100 driven by actuator commands
(model ``remus100-6dof-guided``, per-vehicle deployment: AuvGuidance -> AuvAutopilot ->
this FMU; plant_model.remus100.plant.ActuatedRemus6dofPlant, docs/guidance.md).

Inputs: ``rpm_command`` (rpm), ``rudder_command`` and ``stern_command`` (rad), held over
the step. Outputs: those of ``AuvRemus6dof`` (y, x, w, attitude, rpm, rudder, stern,
saturated: 1 when a command input was at or beyond its limit; nav with navigation
sensors) and what the autopilot measures: ``velocity`` (through the water, body axes),
``rates`` (p, q, r) and ``depth``. No output depends directly on an input. The same
vehicle data, current and noise stream (generator [seed, vehicle]) as ``AuvRemus6dof``.
A NaN command is refused at the next fmi2DoStep (fmi2Discard, the input named in the
log); a state that becomes non-finite ends the step with an error naming the vehicle.
"""
from fmu_common.interface import ArraySpec
from plant_model.remus100.plant import ActuatedRemus6dofPlant

# pythonfmu's loader looks for "class X(Fmi2Slave):"
from plant_model.remus100.remus6dof_slave_base import Remus6dofSlave as Fmi2Slave


class AuvRemus6dofActuated(Fmi2Slave):
    """One nonlinear 6-DOF REMUS 100: rpm, rudder and stern-plane commands in."""

    description = ("One nonlinear 6-DOF REMUS 100 (per-vehicle deployment, the autopilot "
                   "outside): rpm, rudder and stern-plane commands in, RK4 sub-steps; its "
                   "own ocean current and noisy position sensor; velocity through the water, "
                   "body rates and depth out for the autopilot")

    #: the gains that set only the start: the propeller at n_max U / U_max, heading above U_min
    gain_fields = ("U_max", "n_max", "U_min")
    gain_role = "start only (the propeller at the feedforward rpm n_max U / U_max):"
    plant_class = ActuatedRemus6dofPlant

    @classmethod
    def inputs(cls) -> list[ArraySpec]:
        """rpm_command (rpm), rudder_command, stern_command (rad), in the plant's order."""
        return [ArraySpec("rpm_command", (), "input", "propeller speed command",
                          unit="rpm"),
                ArraySpec("rudder_command", (), "input", "rudder command (positive: turn to "
                          "starboard)", unit="rad"),
                ArraySpec("stern_command", (), "input", "stern-plane command (positive: "
                          "dive)", unit="rad")]

    @classmethod
    def extra_outputs(cls) -> list[ArraySpec]:
        """velocity (3, m/s), rates (3, rad/s), depth (m): what the autopilot measures."""
        return [ArraySpec("velocity", (3,), "output", "velocity through the water in body "
                          "axes [u, v, w]: nu - R(Theta)' w (a DVL's water track)",
                          unit="m/s"),
                ArraySpec("rates", (3,), "output", "body rates p, q, r", unit="rad/s"),
                ArraySpec("depth", (), "output", "depth (positive down)", unit="m")]

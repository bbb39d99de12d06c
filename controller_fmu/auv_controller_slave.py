"""FMI 2.0 co-simulation slave of the LQ feedforward-feedback controller.

Solves the paper's design (eq. 13-15, corrected) in exitInitializationMode from whatever
parameters the host set, then u = -(Kx xhat + Kw what + Kz zhat) on demand (direct
feedthrough from the estimates). Static law: any communication step works.
"""
import numpy as np

from controller_fmu.design import lq_tracking_design
from fmu_common.interface import ArraySpec
from fmu_common.slave_base import ArraySlave as Fmi2Slave  # pythonfmu's loader looks for "class X(Fmi2Slave):"
from fmu_common.system_parameters import system_mapping_from_parameters, system_parameter_specs
from plant_model.system import LinearSystem

CONTROLLER_PARAMETERS = ("A", "B1", "B2", "C", "F", "H", "K", "Q", "R")
ESTIMATES = ("xhat", "what", "zhat")


class AuvController(Fmi2Slave):
    """u = -R^-1 B1' (P xhat + P1 zhat + P2 what)."""

    config_file = "auv_controller_config.json"
    description = ("Optimal LQ feedforward-feedback consensus tracking controller "
                   "(Riccati and Sylvester equations) for AUVs with disturbances")
    author = "auv-cosim"

    @staticmethod
    def interface(config):
        d = config["dims"]
        n, m, r, l_ = d["n"], d["m"], d["r"], d["l"]
        return system_parameter_specs(config, CONTROLLER_PARAMETERS) + [
            ArraySpec("xhat", (n,), "input", "estimate of the vehicle state x"),
            ArraySpec("what", (r,), "input", "estimate of the disturbance state w"),
            ArraySpec("zhat", (l_,), "input", "estimate of the reference state z"),
            ArraySpec("u", (m,), "output", "control input u = -(Kx xhat + Kw what + Kz zhat)",
                      depends_on=ESTIMATES),
        ]

    def setup(self):
        mapping = system_mapping_from_parameters(self.par, CONTROLLER_PARAMETERS)
        system = LinearSystem.from_mapping(mapping)
        self.design = lq_tracking_design(system)
        self._negK = -self.design.gain_on_state()
        self.log(f"design: closed-loop poles {np.round(self.design.closed_loop_poles, 6).tolist()}, "
                 f"relative residuals {self.design.residuals}")

    def compute_outputs(self):
        np.dot(self._negK, self._in, out=self._out)

    def advance(self, step):
        pass

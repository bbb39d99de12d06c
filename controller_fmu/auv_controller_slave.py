"""FMI 2.0 co-simulation slave of the LQ feedforward-feedback controller.

Solves the paper's design (eq. 13-15, corrected) in exitInitializationMode from whatever
parameters the host set, then u = sat(-(Kx xhat + Kw what + Kz zhat)) on demand (clipped at
the parameter u_max, controller_fmu.slave_common; direct
feedthrough from the estimates); with tracking = 'regulator' the feedforward comes from the
output-regulation equations instead (controller_fmu.regulator). Static law: any
communication step works. FMU state: the gain matrix (restored as is, the design is not
solved again), plus what the base class saves (parameters, buffers, flags).
"""
from typing import Any

import numpy as np

from controller_fmu.regulator import TRACKING_MODES, tracking_law

# pythonfmu's loader looks for "class X(Fmi2Slave):"
from controller_fmu.slave_common import StaticLawSlave as Fmi2Slave
from controller_fmu.slave_common import clip_roles, force_limit, u_max_spec
from fmu_common.interface import ArraySpec
from fmu_common.native_form import NativeForm, Role
from plant_model.parameters import model_parameter_specs, system_from_parameters

CONTROLLER_PARAMETERS = ("A", "B1", "B2", "C", "F", "H", "K", "Q", "R")
ESTIMATES = ("xhat", "what", "zhat")


class AuvController(Fmi2Slave):
    """u = -R^-1 B1' (P xhat + P1 zhat + P2 what)."""

    description = ("Optimal LQ feedforward-feedback consensus tracking controller "
                   "(Riccati and Sylvester equations) for AUVs with disturbances")

    @staticmethod
    def interface(config: dict[str, Any]) -> list[ArraySpec]:
        """Model parameters and tracking mode; the estimates xhat (n,), what (r,), zhat (l,)
        in; u (m,) out, fed through from the estimates. Configuration keys (see
        :meth:`ArraySlave.interface`): ``dims``, ``system``, ``tracking``, ``fleet``.
        """
        d = config["dims"]
        n, m, r, l_ = d["n"], d["m"], d["r"], d["l"]
        return model_parameter_specs(config, "controller", CONTROLLER_PARAMETERS) + [
            ArraySpec("tracking", (), "parameter",
                      "tracking law: 'lq' (the paper, eq. 12-15) or 'regulator' (zero steady "
                      "error for persistent references: output regulation with the same Riccati "
                      "feedback)", start=config.get("tracking", "lq"), type="String"),
            u_max_spec(config, m),
            ArraySpec("xhat", (n,), "input", "estimate of the vehicle state x"),
            ArraySpec("what", (r,), "input", "estimate of the disturbance state w"),
            ArraySpec("zhat", (l_,), "input", "estimate of the reference state z"),
            ArraySpec("u", (m,), "output", "control input u = sat(-(Kx xhat + Kw what + Kz "
                      "zhat)), clipped at u_max",
                      depends_on=ESTIMATES),
        ]

    def setup(self) -> None:
        """Solve the design (13)-(15) (or the regulator equations) from the parameters.

        Raises
        ------
        ValueError
            If the parameter ``tracking`` is not one of TRACKING_MODES.
        ModelError
            If the parameters do not make a valid system or the design fails.
        """
        system = system_from_parameters(self.config, "controller", self.par,
                                        CONTROLLER_PARAMETERS)
        mode = self.par["tracking"]
        if mode not in TRACKING_MODES:
            raise ValueError(f"parameter tracking = {mode!r} is not one of "
                             f"{', '.join(TRACKING_MODES)}")
        self.law = tracking_law(system, mode)
        self.design = self.law.design
        self._negK = -self.law.Ks
        self._umax = force_limit(self.par)
        poles = self.design.closed_loop_poles
        self.log(f"design ({mode}): slowest closed-loop pole {poles[np.argmax(poles.real)]:.6g}, "
                 f"relative residuals {self.design.residuals}")

    def native_form(self) -> NativeForm:
        """u = -Ks [xhat; what; zhat]: a static gain (any communication step); the
        force clipped at u_max when it is limited (controller_fmu.slave_common.clip_roles)."""
        return self.static_native_form([
            Role("D", "Ks", -self._negK, "the designed gain: u = -Ks [xhat; what; zhat] "
                 f"({self.par['tracking']} law)", sign=-1.0), *clip_roles(self._umax)])

    def compute_outputs(self) -> None:
        """u = sat(-(Kx xhat + Kw what + Kz zhat)) into the output buffer."""
        self._negK.dot(self._in, out=self._out)     # ndarray.dot: np.dot's gemv, less dispatch
        if self._umax is not None:
            np.minimum(np.maximum(self._out, -self._umax), self._umax, out=self._out)

    restores_math_from_state = True       # the state carries the gain: no design on restore

    def model_state(self) -> dict[str, np.ndarray]:
        """The gain of the law, so that a restore needs no new design.

        Returns
        -------
        dict[str, np.ndarray]
            ``gain``: Ks with u = -Ks [xhat; what; zhat], m x (n + r + l) (a new array).
        """
        return {"gain": -self._negK}       # u = -gain [xhat; what; zhat] (a new array)

    def restore_model_state(self, state: Any) -> None:
        """Restore a :meth:`model_state` result: the gain, as is.

        Parameters
        ----------
        state : Any
            The dict :meth:`model_state` returned (decoded from a serialized FMU state).

        Raises
        ------
        ValueError
            If the gain is not a real array of shape (m, n + r + l).
        """
        gain = state["gain"]
        shape = (self._out.size, self._in.size)
        if not isinstance(gain, np.ndarray) or gain.dtype.kind != "f" or gain.shape != shape:
            raise ValueError(f"the controller gain in the state must be a real array of shape "
                             f"{shape}, got {getattr(gain, 'shape', type(gain).__name__)}")
        self._negK = -gain
        self._umax = force_limit(self.par)

"""FMI 2.0 co-simulation slave of one vehicle's centralized controller (per-vehicle deployment).

The paper's stacked law cut by vehicle (controller_fmu.vehicle_law.centralized_rows): vehicle
i applies its rows u_i = sat(u0 - K [xhat_1; what_1; ...; xhat_N; what_N; z]) of the stacked
gain, consensus force included. It reads every vehicle's estimate and the leader's state:
O(N) inputs, the one FMU of the per-vehicle deployment whose size grows with the fleet (all-to-all
information is what the centralized architecture means). The stacked Riccati and
Sylvester equations are solved once by whoever builds the system; K and u0 are parameters.
Static law: any communication step works.
"""
from typing import Any

import numpy as np

# pythonfmu's loader looks for "class X(Fmi2Slave):"
from controller_fmu.slave_common import StaticLawSlave as Fmi2Slave
from controller_fmu.slave_common import clip_roles, force_limit, u_max_spec
from fmu_common.interface import ArraySpec
from fmu_common.native_form import NativeForm, Role


def vehicle_inputs(N: int, what: str) -> list[str]:
    """The input arrays ``vehicle[j].<what>``, j = 1..N."""
    return [f"vehicle[{j}].{what}" for j in range(1, N + 1)]


class AuvCentralController(Fmi2Slave):
    """u_i = u0 - K [xhat_1; what_1; ...; z]: one vehicle's rows of the stacked law."""

    description = ("Centralized consensus tracking controller of one AUV: its rows of the "
                   "paper's stacked LQ feedforward-feedback law (all-to-all information)")

    @staticmethod
    def interface(config: dict[str, Any]) -> list[ArraySpec]:
        """Parameters K (m x (N n + N r + l)), u0 (m,); inputs vehicle[j].xhat (n,),
        vehicle[j].what (r,), z (l,); output u (m,), which feeds through from every input.
        Configuration keys (see :meth:`ArraySlave.interface`): ``dims``, ``vehicles`` N,
        ``gain``, ``u0``.
        """
        d = config["dims"]
        n, m, r, l_ = d["n"], d["m"], d["r"], d["l"]
        N = int(config["vehicles"])
        cols = N * (n + r) + l_
        ins = vehicle_inputs(N, "xhat") + vehicle_inputs(N, "what")
        return [
            ArraySpec("K", (m, cols), "parameter", "the vehicle's rows of the stacked gain on "
                      "[xhat_1; what_1; ...; xhat_N; what_N; z]",
                      start=np.asarray(config["gain"], float)),
            ArraySpec("u0", (m,), "parameter", "constant force (formation offsets)",
                      start=np.asarray(config["u0"], float)),
            u_max_spec(config, m),
            # per vehicle xhat then what, the order of its estimator's outputs: one
            # fmi2SetReal per vehicle
            *(spec for j in range(1, N + 1) for spec in (
                ArraySpec(f"vehicle[{j}].xhat", (n,), "input", f"vehicle {j}'s state estimate"),
                ArraySpec(f"vehicle[{j}].what", (r,), "input",
                          f"vehicle {j}'s disturbance estimate"))),
            ArraySpec("z", (l_,), "input", "the leader's state"),
            ArraySpec("u", (m,), "output", "u = sat(u0 - K [xhat_1; what_1; ...; z]), "
                      "clipped at u_max",
                      depends_on=tuple(ins) + ("z",)),
        ]

    def setup(self) -> None:
        """Take the gain as set (nothing to solve)."""
        self._negK = -np.ascontiguousarray(self.par["K"], dtype=float)
        self._u0 = np.array(self.par["u0"], dtype=float)
        self._umax = force_limit(self.par)

    def native_form(self) -> NativeForm:
        """u = u0 - K [xhat_1; what_1; ...; z]: a static gain (any communication step); the
        force clipped at u_max when it is limited (controller_fmu.slave_common.clip_roles)."""
        return self.static_native_form([
            Role("D", "K", -self._negK, "the vehicle's rows of the stacked gain: u = u0 - K "
                 "[xhat_1; what_1; ...; z]", sign=-1.0),
            Role("c", "u0", self._u0, "constant force (formation offsets)", unit="N"),
            *clip_roles(self._umax)])

    def compute_outputs(self) -> None:
        """u = u0 - K [xhat_1; what_1; ...; xhat_N; what_N; z] into the output buffer."""
        self._negK.dot(self._in, out=self._out)
        self._out += self._u0
        if self._umax is not None:
            np.minimum(np.maximum(self._out, -self._umax), self._umax, out=self._out)

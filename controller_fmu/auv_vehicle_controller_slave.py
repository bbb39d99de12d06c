"""FMI 2.0 co-simulation slave of one vehicle's distributed controller (per-vehicle deployment).

Neighbour-only information (controller_fmu.vehicle_law, controller_fmu.distributed): the
vehicle's own estimates xhat, what; per neighbour slot k = 1..S (S the graph's largest
in-degree) the neighbour's leader estimate nbr[k].eta and regulation error nbr[k].eps with
weight a[k] (0: an unused slot); the leader's state z with weight a0 (0: not pinned). Outputs

    eps = xhat - X eta - Xw what - xc                               (feeds through)
    u   = sat(U eta + Uw what + uc - Kx eps + c Kx (sum_k a[k] nbr[k].eps - d eps))
          (clipped per axis at the parameter u_max, controller_fmu.slave_common)
    eta   the vehicle's distributed observer of the leader (a state: no feedthrough),
          eta[k+1] = (Phi - mu d Gam_F) eta + mu Gam_F (sum_k a[k] nbr[k].eta + a0 z)

with d = sum_k a[k] + a0. The design (regulator equations or the paper's LQ law on the
vehicle's own view, local Riccati equation) is solved in exitInitializationMode, per vehicle,
independent of the fleet's size. FMU state: eta, plus what the base class saves.
"""
from typing import Any

import numpy as np

from controller_fmu.distributed import REGULATOR_FORMS, sampled_observer
from controller_fmu.regulator import TRACKING_MODES
from controller_fmu.slave_common import clip_roles, force_limit, u_max_spec
from controller_fmu.vehicle_law import vehicle_law
from fmu_common.interface import ArraySpec
from fmu_common.native_form import BlockLayout, NativeForm, Role

# pythonfmu's loader looks for "class X(Fmi2Slave):"
from fmu_common.slave_base import ArraySlave as Fmi2Slave
from plant_model.parameters import sample_period_spec, system_parameter_specs

CONTROLLER_PARAMETERS = ("A", "B1", "B2", "C", "K", "F", "H", "Q", "R")


def slot_names(S: int, what: str) -> list[str]:
    """The input arrays of the neighbour slots: ``nbr[k].<what>``, k = 1..S."""
    return [f"nbr[{k}].{what}" for k in range(1, S + 1)]


class AuvVehicleController(Fmi2Slave):
    """u_i from the vehicle's own estimates, its observer of the leader and its neighbours."""

    step_parameter = "h"
    description = ("Distributed consensus tracking controller of one AUV (cooperative output "
                   "regulation with a distributed observer of the leader; neighbour-only "
                   "information)")

    @staticmethod
    def interface(config: dict[str, Any]) -> list[ArraySpec]:
        """Parameters (model, cost, leader, offset, gains, slot weights), inputs and
        outputs as the module docstring. Configuration keys (see
        :meth:`ArraySlave.interface`): ``dims``, ``system``, ``h``, ``slots``, ``offset``,
        ``weights``, ``pinning``, ``mu``, ``cohesion``, ``regulator``, ``tracking``.
        """
        d = config["dims"]
        n, m, r, p, l_ = d["n"], d["m"], d["r"], d["p"], d["l"]
        S = int(config["slots"])
        est = ("xhat", "what")
        return system_parameter_specs(config, CONTROLLER_PARAMETERS) + [
            sample_period_spec(config, "communication step the observer is sampled for"),
            ArraySpec("offset", (p,), "parameter", "formation offset d from the leader's "
                      "output", start=np.asarray(config["offset"], float), unit="m"),
            ArraySpec("a", (S,), "parameter", "weight a_ij of neighbour slot k (0: unused)",
                      start=np.asarray(config["weights"], float), min=0.0),
            ArraySpec("a0", (), "parameter", "weight a_i0 of the leader (0: not pinned)",
                      start=float(config["pinning"]), min=0.0),
            ArraySpec("mu", (), "parameter", "gain of the distributed observer of the leader",
                      start=float(config["mu"]), unit="1/s", min=0.0),
            ArraySpec("cohesion", (), "parameter", "gain c of the cohesion term on the "
                      "neighbours' regulation errors (0: off)", start=float(config["cohesion"]),
                      min=0.0),
            ArraySpec("eta0", (l_,), "parameter", "initial estimate of the leader's state",
                      start=np.asarray(config.get("eta0", np.zeros(l_)), float)),
            ArraySpec("tracking", (), "parameter", "law: 'regulator' (Su and Huang) or 'lq' "
                      "(the paper's law on the vehicle's own view)",
                      start=config.get("tracking", "regulator"), type="String"),
            ArraySpec("regulator", (), "parameter", "regulator equations: 'continuous' or "
                      "'sampled' (zero error at the samples)",
                      start=config.get("regulator", "continuous"), type="String"),
            u_max_spec(config, m),
            ArraySpec("xhat", (n,), "input", "the vehicle's estimate of its state"),
            ArraySpec("what", (r,), "input", "the vehicle's estimate of its disturbance"),
            ArraySpec("z", (l_,), "input", "the leader's state (read when a0 > 0)"),
            # per slot eta then eps, the order of the sender's outputs: one fmi2SetReal each
            *(spec for k in range(1, S + 1) for spec in (
                ArraySpec(f"nbr[{k}].eta", (l_,), "input",
                          f"neighbour slot {k}: its estimate of the leader"),
                ArraySpec(f"nbr[{k}].eps", (n,), "input",
                          f"neighbour slot {k}: its regulation error"))),
            ArraySpec("u", (m,), "output", "total force of the distributed law, clipped at "
                      "u_max",
                      depends_on=est + tuple(slot_names(S, "eps"))),
            ArraySpec("eta", (l_,), "output", "the vehicle's estimate of the leader's state "
                      "(sent to the neighbours)"),
            ArraySpec("eps", (n,), "output", "regulation error xhat - X eta - Xw what - xc "
                      "(sent to the neighbours)", depends_on=est),
        ]

    def setup(self) -> None:
        """Solve the vehicle's design and sample its observer.

        Raises
        ------
        ValueError
            If tracking or regulator is not one of the modes.
        ModelError
            If the design fails (named) or h, mu are invalid.
        """
        par = self.par
        for key, modes in (("tracking", TRACKING_MODES), ("regulator", REGULATOR_FORMS)):
            if par[key] not in modes:
                raise ValueError(f"parameter {key} = {par[key]!r} is not one of "
                                 f"{', '.join(modes)}")
        h = float(par["h"])
        law = vehicle_law(**{k: par[k] for k in CONTROLLER_PARAMETERS}, offset=par["offset"],
                          tracking=par["tracking"], regulator=par["regulator"], h=h)
        obs = sampled_observer(par["F"], h, float(par["mu"]))
        a, a0, c = np.array(par["a"], float), float(par["a0"]), float(par["cohesion"])
        d = float(a.sum()) + a0
        self._Aobs, self._Bobs = (np.ascontiguousarray(x) for x in obs.vehicle_matrices(d))
        self._a, self._a0, self._c = a, a0, c
        self._X, self._Xw, self._xc = law.X, law.Xw, law.xc
        self._U, self._Uw, self._uc = law.U, law.Uw, law.uc
        self._Geps = -(1.0 + c * d) * law.Kx
        self._cK = c * law.Kx
        self.eta = np.array(par["eta0"], dtype=float)
        S, n, l_ = a.size, law.Kx.shape[1], self.eta.size
        io = self.io
        self._xhat, self._what, self._z = io["xhat"], io["what"], io["z"]
        slots = self._in[self._in.size - S * (l_ + n):].reshape(S, l_ + n)   # the last inputs
        self._nbr_eta, self._nbr_eps = slots[:, :l_], slots[:, l_:]
        self._o_u, self._o_eps, self._o_eta = io["u"], io["eps"], io["eta"]
        self.law, self.observer = law, obs
        self._umax = force_limit(par)
        self.log(f"distributed law ({par['tracking']}, {par['regulator']}): slowest local "
                 f"pole {law.poles[np.argmax(law.poles.real)]:.6g}, observer gain mu = "
                 f"{obs.mu:g} 1/s, in-degree {d:g}")

    def native_form(self) -> NativeForm:
        """The law and observer with eps substituted (q = eta)::

            eps = xhat - X eta - Xw what - xc
            u   = (U - Geps X) eta + Geps xhat + (Uw - Geps Xw) what + c Kx sum_k a_k eps_k
                  + uc - Geps xc
            eta+ = Aobs eta + Bobs (sum_k a_k eta_k + a0 z)

        With a force limit u is then clipped at u_max (the role sat,
        controller_fmu.slave_common.clip_roles).
        """
        inputs, outputs = self.io_specs()
        In, Out = BlockLayout(inputs), BlockLayout(outputs)
        l_, n = self.eta.size, self._X.shape[0]
        Ge, X, Xw = self._Geps, self._X, self._Xw
        C = np.zeros((Out.size, l_))
        C[Out["u"]], C[Out["eps"]], C[Out["eta"]] = self._U - Ge @ X, -X, np.eye(l_)
        D = np.zeros((Out.size, In.size))
        D[Out["u"], In["xhat"]], D[Out["eps"], In["xhat"]] = Ge, np.eye(n)
        if Xw.shape[1]:
            D[Out["u"], In["what"]], D[Out["eps"], In["what"]] = self._Uw - Ge @ Xw, -Xw
        B = np.zeros((l_, In.size))
        B[:, In["z"]] = self._a0 * self._Bobs
        for k, a in enumerate(self._a, start=1):
            D[Out["u"], In[f"nbr[{k}].eps"]] = a * self._cK
            B[:, In[f"nbr[{k}].eta"]] = a * self._Bobs
        c = np.zeros(Out.size)
        c[Out["u"]], c[Out["eps"]] = self._uc - Ge @ self._xc, -self._xc
        return NativeForm(inputs=inputs, outputs=outputs, nq=l_, h=float(self.par["h"]),
                          description=self.description, roles=[
                              Role("A", "A_eta", self._Aobs, "observer over one step: eta+ = "
                                   "A_eta eta + B_eta [z; nbr eta]"),
                              Role("B", "B_eta", B, "observer input (weights a0, a_k applied)"),
                              Role("C", "C_eta", C, "outputs [u; eps; eta] from eta"),
                              Role("D", "D", D, "outputs [u; eps; eta] from the inputs (direct "
                                   "feedthrough of the estimates and the neighbours' eps)"),
                              Role("c", "y0", c, "constant part of the outputs (offsets)"),
                              Role("q0", "eta0", self.eta, "the observer's initial state"),
                              *clip_roles(self._umax, Out["u"].start),
                          ])

    def compute_outputs(self) -> None:
        """eps and u from the current inputs; eta is the observer's state."""
        eps = self._xhat - self._X.dot(self.eta) - self._Xw.dot(self._what) - self._xc
        self._o_eps[:] = eps
        u = self._U.dot(self.eta) + self._Uw.dot(self._what) + self._uc + self._Geps.dot(eps)
        if self._c:
            u += self._cK.dot(self._a.dot(self._nbr_eps))
        if self._umax is not None:
            u = np.minimum(np.maximum(u, -self._umax), self._umax)
        self._o_u[:] = u
        self._o_eta[:] = self.eta

    def advance(self, step: float) -> None:
        """The observer over one step with the values received at its start.

        Parameters
        ----------
        step : float
            The communication step, s (checked against h by the base class).
        """
        r = self._a.dot(self._nbr_eta)
        if self._a0:
            r = r + self._a0 * self._z
        self.eta = self._Aobs.dot(self.eta) + self._Bobs.dot(r)

    def evolving(self) -> np.ndarray:
        """The observer state eta (checked to stay finite after every step)."""
        return self.eta

    def model_state(self) -> dict[str, Any]:
        """The observer state.

        Returns
        -------
        dict[str, Any]
            ``eta`` (a copy).
        """
        return {"eta": self.eta.copy()}

    def restore_model_state(self, state: Any) -> None:
        """Restore a :meth:`model_state` result (the dict it returned), validated first as
        :meth:`ArraySlave.restore_model_state` asks: ValueError if eta is not a real array
        of the observer's shape.
        """
        eta = np.asarray(state["eta"])
        if eta.dtype.kind != "f" or eta.shape != self.eta.shape:
            raise ValueError(f"the observer state eta must be a real array of shape "
                             f"{self.eta.shape}, got {eta.dtype} of shape {eta.shape}")
        self.eta = eta.astype(float)

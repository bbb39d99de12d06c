"""The nonlinear REMUS 100 behind the linear vehicle's plant interface (model
``remus100-6dof``; docs/remus100-6dof.md).

The vehicle FMU of the per-vehicle deployment keeps its inputs and outputs: input u, the
NED force (N) the formation controller commands; outputs y (position fix, m), x = [n, e,
d, v_n, v_e, v_d] over ground (m, m/s) and w (the ocean current, m/s). Inside, the
force drives the linear model's velocity through the water, v_ref' = (u - D v_ref) / M
(M, D per axis from the linear design model: B1 = [0; diag(1/M)], B2 = [0; diag(D/M)]),
which the autopilots track with rpm, rudder and stern planes
(:mod:`plant_model.remus100.autopilot`); the 6-DOF equations
(:mod:`plant_model.remus100.dynamics`, compiled in :mod:`plant_model.remus100.kernel`) move
the vehicle, with ``substeps`` RK4 steps per communication step.

What the linear vehicle has beside its physics stays as it is, drawn from the same noise
stream (generator [seed, vehicle], row [v_x; v_w; n; n_bar] of the linear vehicle sampled
at h, :func:`plant_model.per_vehicle.sample_vehicle`), so the linear and the nonlinear
plant of a vehicle meet the same current and the same sensor noise:

    w[k+1] = exp(K h) w[k] + v_w[k]        (Gauss-Markov current, held over the step)
    p[k+1] = p_6dof + v_x,pos[k],  v_g[k+1] = v_6dof + v_x,vel[k]   (process noise)
    y[k]   = p[k] + n[k]

Extra outputs for the recording: attitude [phi, theta, psi] (rad), the propeller speed n
(rpm), the rudder and stern-plane angles (rad), and ``saturated``: 1 when some actuator
command of the step lay at or beyond its limit. With navigation sensors
(:mod:`plant_model.navigation`) the output ends with their vector [fix, dvl, depth, valid]
of sample k, measured on the true position and velocity over ground.
"""
from __future__ import annotations

import math

import numpy as np

from ..discretization import DiscreteModel
from ..linalg_checks import ModelError
from ..navigation import NAV_SIZE, NavigationSensors, SensorStream
from ..plant import NoiseStream
from . import kernel
from .autopilot import AutopilotGains
from .dynamics import STATE_SIZE, Remus100
from .models import GAIN_FIELDS, REMUS_FIELDS, remus_from_parameters
from .rigid_body import rotation_ned_body

__all__ = ["REMUS_FIELDS", "GAIN_FIELDS", "ActuatedRemus6dofPlant", "Remus6dofPlant",
           "default_substep",
           "initial_state", "linear_mass_damping", "remus_from_parameters", "substep_count"]

#: the longest default RK4 sub-step, s (docs/remus100-6dof.md: converged at 0.05 s)
MAX_SUBSTEP = 0.05


def default_substep(h: float) -> float:
    """The default sub-step: h / ceil(h / 0.05 s), the longest that divides h (s)."""
    return h / max(1, math.ceil(h / MAX_SUBSTEP - 1e-9))


def substep_count(h: float, substep: float) -> int:
    """The whole number h / substep (RK4 sub-steps per communication step).

    Raises
    ------
    ModelError
        Naming ``substep`` if it is not positive or does not divide h.
    """
    if not (math.isfinite(substep) and substep > 0.0):
        raise ModelError(f"remus100-6dof: substep = {substep!r} s must be a positive number")
    k = round(h / substep)
    if k < 1 or abs(k * substep - h) > 1e-9 * h:
        raise ModelError(f"remus100-6dof: substep = {substep:g} s does not divide the step "
                         f"h = {h:g} s")
    return int(k)


def linear_mass_damping(B1: np.ndarray, B2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(M, D) per NED axis (kg, kg/s) of the linear REMUS model: B1[3:, :] = diag(1/M),
    B2[3:, :] = diag(D/M)."""
    M = 1.0 / np.diag(np.asarray(B1, float)[3:6, :3])
    D = np.diag(np.asarray(B2, float)[3:6, :3]) * M
    if not (np.all(np.isfinite(M)) and np.all(M > 0) and np.all(D > 0)):
        raise ModelError("remus100-6dof: the linear design model must be a remus100 "
                         "(B1 = [0; diag(1/M)], B2 = [0; diag(D/M)] with M, D > 0)")
    return M, D


def initial_state(v: Remus100, gains: AutopilotGains, x0: np.ndarray, w0: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The 6-DOF state and v_ref at the linear state x0 = [p; v_g] (m, m/s) in the current
    w0 (m/s): the nose along the velocity through the water v_g - w0 (heading and flight
    path angle; at rest: north, level), the body velocity nu = R(Theta)' v_g so that the
    vehicle moves over ground as the scenario says (through the water: v_g - w0, all in
    surge), the propeller at that speed's feedforward rpm, the fins at 0.
    Returns (x (15), v_ref (3) = v_g - w0)."""
    x = np.zeros(STATE_SIZE)
    x[:3] = x0[:3]
    v_g = np.asarray(x0[3:6], float)
    vw = v_g - np.asarray(w0, float)
    U = float(np.linalg.norm(vw))
    if U > gains.U_min:
        x[5] = math.atan2(vw[1], vw[0])
        x[4] = math.atan2(-vw[2], math.hypot(vw[0], vw[1]))
    x[6:9] = rotation_ned_body(0.0, x[4], x[5]).T @ v_g
    x[14] = min(v.n_max, gains.n_max * U / gains.U_max)
    return x, vw


class Remus6dofPlant:
    """One nonlinear REMUS 100 sampled at h (module docstring). ``output`` is the vector
    [y (3), x (6), w (3), attitude (3), n, delta_r, delta_s, saturated] of sample k;
    ``s`` the evolving vector [x_6dof (15), v_ref, integrals (2), w]."""

    OUTPUT_SIZE = 3 + 6 + 3 + 3 + 4

    def __init__(self, vehicle: Remus100, gains: AutopilotGains, linear: DiscreteModel,
                 M: np.ndarray, D: np.ndarray, x0: np.ndarray, w0: np.ndarray, seed: int,
                 substeps: int, out: np.ndarray | None = None,
                 sensors: NavigationSensors | None = None):
        if linear.n != 6 or linear.r != 3 or linear.p != 3:
            raise ModelError("remus100-6dof: the linear design model must have 6 states, 3 "
                             "current states and 3 outputs (a remus100)")
        self.vehicle, self.gains, self.model = vehicle, gains, linear
        self.seed, self.substeps = int(seed), int(substeps)
        self._p, self._g = kernel.pack(vehicle), kernel.pack_gains(gains)
        self._M, self._D = np.array(M, float), np.array(D, float)
        self._Aw = np.ascontiguousarray(linear.Ad[6:9, 6:9])
        self._limits = np.array([vehicle.delta_max, vehicle.delta_max, vehicle.n_max])
        self.sensors = sensors
        size = self.OUTPUT_SIZE + (NAV_SIZE if sensors is not None else 0)
        self.output = np.empty(size) if out is None else out
        if self.output.shape != (size,):
            raise ValueError(f"vehicle output buffer has shape {self.output.shape}, expected "
                             f"({size},)")
        self._x0, self._w0 = np.array(x0, float), np.array(w0, float)
        self.reset()

    def reset(self) -> None:
        """Restart at k = 0 from x0, w0 with a fresh noise stream of the same seed."""
        self.k = 0
        x, v_ref = initial_state(self.vehicle, self.gains, self._x0, self._w0)
        self.s = np.concatenate([x, v_ref, np.zeros(2), self._w0])
        self._cmd = np.zeros(3)
        self._saturated = 0.0
        self._noise = NoiseStream(self.model, self.seed)
        self._row = self._noise.next_row()
        self._nav = (None if self.sensors is None else
                     SensorStream(self.sensors, self.model.h, self.seed,
                                  int(self.model.noise_keys[0])))
        self._outputs()
        self._measure()

    def _outputs(self) -> None:
        """The outputs of sample k but the navigation sensors' (from the state)."""
        kernel.plant_outputs(self.s, self._row[9:12], self._saturated, self.output)

    def _measure(self) -> None:
        """The navigation sensors' outputs of sample k (drawn once per sample)."""
        if self._nav is not None:
            o = self.output
            o[self.OUTPUT_SIZE:] = self._nav.measure(self.k, o[3:6], o[6:9])

    def _refresh(self) -> None:
        """The outputs of sample k from the state (at a reset or a restored state)."""
        self._outputs()
        if self._nav is not None:
            self.output[self.OUTPUT_SIZE:] = self._nav.out

    def step(self, u: np.ndarray) -> None:
        """Advance one step with the force u (N, NED) held (module docstring; the
        arithmetic in :func:`plant_model.remus100.kernel.plant_step`)."""
        self._saturated = self._advance(np.asarray(u, dtype=float))
        self.k += 1
        self._row = self._noise.next_row()
        self._outputs()
        self._measure()

    def _advance(self, u: np.ndarray) -> float:
        """The state over one step with the input u held; 1.0 if a command saturated."""
        return kernel.plant_step(self._p, self._g, self.s, u, self._row[:9], self._Aw,
                                 self._M, self._D, self.model.h, self.substeps, self._cmd,
                                 self._limits)

    @property
    def command(self) -> np.ndarray:
        """The last step's actuator command [delta_r, delta_s (rad), n (rpm)]."""
        return self._cmd.copy()

    def get_state(self) -> dict:
        """Everything that evolves (copies): k, s, the command, the noise row and stream."""
        return {"k": self.k, "seed": self.seed, "s": self.s.copy(), "cmd": self._cmd.copy(),
                "saturated": self._saturated, "row": self._row.copy(),
                "noise": self._noise.get_state(),
                "nav": None if self._nav is None else self._nav.get_state()}

    def set_state(self, state: dict) -> None:
        """Restore a :meth:`get_state` result (validated first: on error nothing changes).

        Raises
        ------
        ValueError
            If the seed differs or an entry has the wrong shape.
        """
        if int(state["seed"]) != self.seed:
            raise ValueError(f"the vehicle state was drawn with seed {state['seed']}, "
                             f"this vehicle has seed {self.seed}")
        s = np.array(state["s"], dtype=float)
        row = np.array(state["row"], dtype=float)
        cmd = np.array(state["cmd"], dtype=float)
        if s.shape != self.s.shape or row.shape != self._row.shape or cmd.shape != (3,):
            raise ValueError(f"the vehicle state has shapes {s.shape}, {row.shape}, "
                             f"{cmd.shape}; expected {self.s.shape}, {self._row.shape}, (3,)")
        if (state.get("nav") is None) != (self._nav is None):
            raise ValueError("the vehicle state and this vehicle differ in having navigation "
                             "sensors")
        self._noise.set_state(state["noise"])
        if self._nav is not None:
            self._nav.set_state(state["nav"])
        self.k, self.s, self._row, self._cmd = int(state["k"]), s, row, cmd
        self._saturated = float(state["saturated"])
        self._refresh()


class ActuatedRemus6dofPlant(Remus6dofPlant):
    """The same vehicle, current, noise and sensors as :class:`Remus6dofPlant`, driven by
    actuator commands in place of a force (model ``remus100-6dof-guided``: the autopilot
    is an FMU of its own, docs/guidance.md).

    :meth:`step` takes the command [n (rpm), delta_r (rad), delta_s (rad)], held over h;
    ``substeps`` RK4 steps move the 6-DOF state (the actuators follow the command with
    their lags and limits), then the process noise and the current step exactly as in
    :class:`Remus6dofPlant` (:func:`plant_model.remus100.kernel.actuated_step`).
    ``saturated`` is 1 when a command was at or beyond its limit (delta_max, n_max).
    ``output`` appends to the parent's 19 outputs what an autopilot measures:
    velocity through the water in body axes nu[:3] - R(Theta)' w (3, m/s), the body
    rates p, q, r (3, rad/s) and the depth (m); then the navigation sensors, if any.
    The evolving vector keeps the parent's layout; its v_ref and integrals stay at their
    start values (unused). ``gains`` only set the start (the propeller at the feedforward
    rpm n_max U / U_max, the heading defined above U_min).
    """

    OUTPUT_SIZE = Remus6dofPlant.OUTPUT_SIZE + 7

    def _outputs(self) -> None:
        super()._outputs()
        kernel.actuated_outputs(self.s, self.output)

    def _advance(self, command: np.ndarray) -> float:
        return kernel.actuated_step(self._p, self.s, command, self._row[:9], self._Aw,
                                    self.model.h, self.substeps, self._cmd, self._limits)

    def step(self, command: np.ndarray) -> None:
        """Advance one step with the actuator command [n (rpm), delta_r (rad), delta_s
        (rad)] held (class docstring)."""
        super().step(command)

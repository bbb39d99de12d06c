"""A vehicle flown through the guidance FMUs in the per-vehicle system (a model whose
registry entry names a ``stack``: ``remus100-6dof-guided``, docs/guidance.md).

Per such vehicle i the force of ``controller_i`` goes through two more components before
the vehicle FMU (``AuvRemus6dofActuated``), which takes actuator commands::

    controller_i.u                                   -> guidance_i.u  (and estimator_i.u)
    guidance_i.speed, course, depth, speed_rate,
              course_rate, depth_rate                -> autopilot_i.<the same names>
    vehicle_i.velocity, attitude, rates, depth       -> autopilot_i.velocity, attitude,
                                                        rates, measured_depth
    autopilot_i.rpm, rudder, stern                   -> vehicle_i.rpm_command,
                                                        rudder_command, stern_command

Feedthrough within a step (the master's evaluation order resolves it): the vehicle's
outputs depend on its state only; the guidance's set-points on its state, its rates on u;
the autopilot's commands on all its inputs. So: vehicle -> estimator -> controller ->
guidance -> autopilot -> vehicle's inputs, then every FMU steps; no algebraic loop.

:func:`stack_configs` gives the two FMUs' configurations of one vehicle (the guidance's
M, D per NED axis from the vehicle's design model, its start velocity through the water,
depth and course; the autopilot's gains from the vehicle's ``autopilot`` parameters); the
build of the guidance FMUs beside a REMUS 100 scenario's system uses it for vehicle 1.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from controller_fmu.guidance import SETPOINT_NAMES
from plant_model.remus100.autopilot import AutopilotGains
from plant_model.system import LinearSystem
from plant_model.vehicles import VehicleModel

from .system import Connection, SystemDescription

__all__ = ["GUIDED_STACK", "MEASURED", "COMMANDS", "RECORDED_SETPOINTS", "setpoint_traces",
           "stack_configs", "stack_connections"]

#: the stack this module wires: AuvGuidance, then AuvAutopilot (keys of FMU_KINDS)
GUIDED_STACK = ("guidance", "autopilot")
#: vehicle output -> autopilot input
MEASURED = (("velocity", "velocity"), ("attitude", "attitude"), ("rates", "rates"),
            ("depth", "measured_depth"))
#: autopilot output -> vehicle input
COMMANDS = (("rpm", "rpm_command"), ("rudder", "rudder_command"), ("stern", "stern_command"))
#: the guidance outputs recorded per vehicle (m/s, rad, m)
RECORDED_SETPOINTS = ("speed", "course", "depth")


def stack_configs(model: VehicleModel, view: LinearSystem, h: float, T: float,
                  seed: int) -> dict[str, dict[str, Any]]:
    """The ``guidance`` and ``autopilot`` FMU configurations of one REMUS 100 vehicle.

    The guidance's reference velocity v_ref' = (u - D v_ref) / M per NED axis takes M
    (kg) and D (kg/s) from the design model's ``total_mass`` and ``damping``; it starts at
    the velocity through the water v_ref0 = x0[3:6] - w0 (m/s), the depth depth0 = x0[2]
    (m) and the course atan2(v_E, v_N) (rad); U_min (m/s) is the autopilot's. The
    autopilot's start values are the vehicle's ``autopilot`` gains (the defaults of
    :class:`~plant_model.remus100.autopilot.AutopilotGains` for the others).

    Parameters
    ----------
    model : VehicleModel
        The vehicle's model (a REMUS 100: ``total_mass``, ``damping`` among its parameters).
    view : LinearSystem
        The vehicle alone (its x0, w0; :func:`plant_model.per_vehicle.vehicle_views`).
    h, T : float
        Communication step and stop time, s.
    seed : int
        The run's seed (the FMUs draw no noise; it keys the build like the others').

    Returns
    -------
    dict[str, dict[str, Any]]
        {'guidance': config, 'autopilot': config} (keys of FMU_KINDS).
    """
    par = model.parameters
    gains = dict(par.get("autopilot", {}))
    v0 = np.asarray(view.x0, float)[3:6] - np.asarray(view.w0, float)[:3]
    base = {"dims": {}, "h": float(h), "T": float(T), "seed": int(seed)}
    # a set-point vehicle FMU names the guidance's own M, D (plant_model.vehicle_fmu)
    guidance = {"M": [float(v) for v in par.get("guidance_mass", par["total_mass"])],
                "D": [float(v) for v in par.get("guidance_damping", par["damping"])],
                "v_ref0": v0.tolist(),
                "depth0": float(view.x0[2]),
                "course0": float(math.atan2(v0[1], v0[0])),
                "U_min": float(AutopilotGains(**gains).U_min)}
    return {"guidance": dict(base, guidance=guidance), "autopilot": dict(base, autopilot=gains)}


def stack_connections(i: int, stack: tuple[str, ...],
                      vehicle_inputs: tuple[str, ...] = ()) -> list[Connection]:
    """The connections of vehicle i's force through its stack to its vehicle FMU (module
    docstring); the controller's force to the estimator is the caller's.

    Parameters
    ----------
    i : int
        The vehicle (1-based): components ``controller_i``, ``guidance_i``,
        ``autopilot_i``, ``vehicle_i``.
    stack : tuple[str, ...]
        The model's stack (:meth:`plant_model.vehicle_models.ModelEntry.stack_for`):
        :data:`GUIDED_STACK`, or ``("guidance",)`` before a set-point vehicle FMU, whose
        inputs named after the guidance's outputs (``vehicle_inputs``) it feeds.

    Returns
    -------
    list[Connection]

    Raises
    ------
    ValueError
        For a stack other than those two.
    """
    c, g, a, v = (f"{n}_{i}" for n in ("controller", "guidance", "autopilot", "vehicle"))
    if tuple(stack) == ("guidance",):       # a set-point vehicle FMU: its inputs by name
        return [Connection(c, "u", g, "u")] + [Connection(g, s, v, s) for s in vehicle_inputs
                                               if s in SETPOINT_NAMES]
    if tuple(stack) != GUIDED_STACK:
        raise ValueError(f"no wiring for the stack {stack!r} (known: {GUIDED_STACK})")
    return ([Connection(c, "u", g, "u")]
            + [Connection(g, s, a, s) for s in SETPOINT_NAMES]
            + [Connection(v, out, a, inp) for out, inp in MEASURED]
            + [Connection(a, out, v, inp) for out, inp in COMMANDS])


def setpoint_traces(system: SystemDescription, traces: Mapping[str, np.ndarray],
                    N: int) -> dict[str, np.ndarray]:
    """The guidance set-points of every vehicle, when each has a guidance component.

    Parameters
    ----------
    system : SystemDescription
        A per-vehicle system.
    traces : Mapping[str, np.ndarray]
        Its traces.
    N : int
        The number of vehicles.

    Returns
    -------
    dict[str, np.ndarray]
        ``setpoint`` (steps, 3 N): per vehicle [speed (m/s), course (rad), depth (m)];
        empty if some vehicle has no guidance.
    """
    names = system.trace_names()
    if not all((f"guidance_{i}", "speed") in names for i in range(1, N + 1)):
        return {}
    return {"setpoint": np.hstack([traces[names[(f"guidance_{i}", s)]]
                                   for i in range(1, N + 1) for s in RECORDED_SETPOINTS])}

"""Fleet scenarios: N vehicles on a communication graph following a virtual leader.

A fleet scenario file has these sections (SI units, NED frame; vehicles are numbered 1..N)::

    name, description
    [simulation] T (s), h (s), seed, estimator, tracking ("lq" | "regulator")
    [leader]     path ("straight" | "circle" | "lawnmower" | "explicit") and its parameters
                 (see plant_model.leader), noise (intensity W_z of the leader; 0 = a planned
                 path known to every vehicle)
    [vehicles]   count, model ("remus100" | "generic"), params (model parameters for all),
                 offsets (count x 3, NED m: target = leader + offset), positions (count x 3,
                 initial NED positions; default: at the targets) or x0 (count x p),
                 overrides = [{vehicle = i, model, params, offset, position, x0, current,
                 noise = {process, position, reference}, cost = {Q, R}}, ...] (per vehicle)
    [graph]      edges = [[j, i, a_ij], ...] (vehicle i hears vehicle j), pinning = [[i, a_i0]],
                 coupling (p x p matrix on the vehicle state; identity by default)
    [current]    time_constant (s), sigma (m/s), w0 (m/s): an ocean current per vehicle as a
                 first-order Gauss-Markov process; or [disturbance] K, W_w, w0 for generic models
    [noise]      convention, process (W_x), position (V_y), reference (V_ybar): numbers (times
                 the identity) or matrices, the same for every vehicle
    [cost]       Q, R per vehicle (numbers or matrices)
    [design]     the weight from the vehicle (docs/design.md): bandwidth (rad/s) and/or
                 force_budget (3-sigma force / maximum force) choose R = r I; u_max (N,
                 "vehicle" or per axis) the controllers' force limit; path_check ("warn" |
                 "refuse" | "off"); max_speed, min_turn_radius, max_depth_rate
    [network]    acoustic links of the per-vehicle deployment (plant_model.acoustic): fleet-wide
                 latency (s), period (s), loss (probability), tdma (senders take turns),
                 receiver ("propagate" | "hold"), links = [{from, to, latency, period,
                 loss}, ...] per-link overrides (from: a vehicle or "leader")

The sections are validated by :class:`.schema_fleet.FleetScenario`; the result is the
JSON-ready fleet spec of :mod:`plant_model.fleet`.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from plant_model.vehicle_models import get

from .errors import validate_scenario

if TYPE_CHECKING:
    from .schema_fleet import FleetScenario

__all__ = ["is_fleet_scenario", "fleet_spec_from_dict", "fleet_spec"]


def is_fleet_scenario(data: Mapping[str, Any]) -> bool:
    """True when the parsed file describes a fleet (it has a [leader] or [graph] section)."""
    return "leader" in data or "graph" in data


def fleet_spec_from_dict(data: Mapping[str, Any], where: str = "scenario"
                         ) -> tuple[dict[str, Any], dict[str, Any]]:
    """(fleet spec, [simulation] table) of a parsed fleet scenario; raises a one-line
    :class:`.errors.ScenarioError` naming ``where``, the section and the key."""
    from .schema_fleet import FleetScenario  # networkx & co.: only for fleets
    scenario = validate_scenario(FleetScenario, data, where)
    return fleet_spec(scenario), dict(data["simulation"])


def fleet_spec(scenario: FleetScenario) -> dict[str, Any]:
    """The fleet spec of a validated scenario: per vehicle its model, parameters, offset,
    x0 (a position becomes a state moving with the leader), current or disturbance, noise
    (W_x, V_y, V_ybar) and cost (Q, R), each from its override or else from the section."""
    path = scenario.leader.leader_path
    velocity = path.velocity_matrix() @ path.z0
    shared_current = scenario.current.model_dump(exclude_unset=True) if scenario.current else {}
    noise, cost = scenario.noise, scenario.cost
    vehicles = []
    for merged, mdl in zip(scenario.vehicles.merged, scenario.vehicles.models):
        v = dict(merged, params=dict(merged["params"]))
        position = v.pop("position", None)
        if position is not None:
            x0 = np.zeros(mdl.p)
            x0[list(mdl.position_states)] = position
            if get(mdl.name).layout == "ned":
                x0[3:6] = velocity                     # start moving with the leader
            v["x0"] = x0.tolist()
        own_noise = v.pop("noise").model_dump(exclude_unset=True) if "noise" in v else {}
        own_cost = v.pop("cost").model_dump(exclude_unset=True) if "cost" in v else {}
        if scenario.disturbance is not None:
            v["disturbance"] = scenario.disturbance.model_dump(exclude_unset=True)
        else:
            own_current = v["current"].model_dump(exclude_unset=True) if "current" in v else {}
            v["current"] = {**shared_current, **own_current}
        for key, name in (("W_x", "process"), ("V_y", "position"), ("V_ybar", "reference")):
            v[key] = own_noise.get(name, getattr(noise, name))
        for key in ("Q", "R"):
            v[key] = own_cost.get(key, getattr(cost, key))
        vehicles.append(v)
    graph, leader = scenario.graph, scenario.leader
    return {
        "vehicles": vehicles,
        "graph": {"edges": graph.edges, "pinning": graph.pinning, "coupling": graph.coupling,
                  "consensus": graph.consensus},
        "leader": {"kind": leader.path, "F": path.F.tolist(), "H": path.H.tolist(),
                   "z0": path.z0.tolist(), "W_z": leader.noise, "params": leader.parameters},
        "noise_convention": noise.convention,
    }

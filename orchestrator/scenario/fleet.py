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

The result is the JSON-ready fleet spec of :mod:`plant_model.fleet`.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from plant_model.leader import make_leader
from plant_model.linalg_checks import ModelError
from plant_model.vehicles import make_vehicle

__all__ = ["FLEET_SCHEMA", "is_fleet_scenario", "fleet_spec_from_dict"]

FLEET_SCHEMA: dict[str, set[str]] = {
    "simulation": {"T", "h", "seed", "estimator", "tracking"},
    "leader": set(),             # checked by plant_model.leader.make_leader
    "vehicles": {"count", "model", "params", "offsets", "positions", "x0", "overrides"},
    "graph": {"edges", "pinning", "coupling"},
    "current": {"time_constant", "sigma", "w0"},
    "disturbance": {"K", "W_w", "w0"},
    "noise": {"convention", "process", "position", "reference"},
    "cost": {"Q", "R"},
}
_OVERRIDE_KEYS = {"vehicle", "model", "params", "offset", "position", "x0", "current", "noise",
                  "cost"}


class _Err(ValueError):
    """A problem in one section of a fleet scenario (section, message)."""

    def __init__(self, section: str, msg: str) -> None:
        super().__init__(msg)
        self.section = section


def is_fleet_scenario(data: dict[str, Any]) -> bool:
    """True when the parsed file describes a fleet (it has a [leader] or [graph] section)."""
    return "leader" in data or "graph" in data


def _rows(section: str, key: str, value: Any, count: int, width: int | None) -> list[list[float]]:
    want = f"{count} rows" + (f" of {width}" if width else "")
    try:
        arr = np.asarray(value, dtype=float) if not isinstance(value, str) else None
    except (TypeError, ValueError):
        # ragged rows or non-numbers: numpy's own message names neither section nor key
        raise _Err(section, f"{key} must have one row per vehicle ({want}) of numbers; "
                            f"got {value!r}") from None
    if arr is None or arr.ndim != 2 or arr.shape[0] != count or (width and arr.shape[1] != width):
        got = "a string" if arr is None else f"shape {arr.shape}"
        raise _Err(section, f"{key} must have one row per vehicle ({want}); got {got}")
    if not np.all(np.isfinite(arr)):
        raise _Err(section, f"{key} has non-finite entries")
    return arr.tolist()


def fleet_spec_from_dict(data: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """(fleet spec, run settings) from a parsed fleet scenario; raises ValueError subclass
    ``_Err`` with ``.section`` set (the scenario loader adds the file name)."""
    unknown = sorted(set(data) - set(FLEET_SCHEMA) - {"name", "description"})
    if unknown:
        raise _Err("", f"unknown section(s) or key(s): {', '.join(unknown)}")
    for section, keys in FLEET_SCHEMA.items():
        sec = data.get(section, {})
        if not isinstance(sec, dict):
            raise _Err(section, "must be a table")
        if keys:
            bad = sorted(set(sec) - keys)
            if bad:
                raise _Err(section, f"unknown key(s): {', '.join(bad)} (allowed: {', '.join(sorted(keys))})")
    for section in ("simulation", "leader", "vehicles", "graph"):
        if section not in data:
            raise _Err(section, "section is missing")
    veh = data["vehicles"]
    count = veh.get("count")
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise _Err("vehicles", f"count = {count!r} must be a positive integer")

    # leader -------------------------------------------------------------------------
    lead = dict(data["leader"])
    kind = lead.pop("path", None)
    if kind is None:
        raise _Err("leader", "path is missing (straight, circle, lawnmower or explicit)")
    W_z = lead.pop("noise", 0.0)
    try:
        path = make_leader(kind, lead)
    except ModelError as exc:
        raise _Err("leader", str(exc)) from None
    leader = {"kind": kind, "F": path.F.tolist(), "H": path.H.tolist(), "z0": path.z0.tolist(),
              "W_z": W_z, "params": lead}

    # vehicles -----------------------------------------------------------------------
    base = {"model": veh.get("model", "remus100"), "params": dict(veh.get("params", {}))}
    vehicles: list[dict[str, Any]] = [dict(base, params=dict(base["params"])) for _ in range(count)]
    for j, ov in enumerate(veh.get("overrides", []), start=1):
        if not isinstance(ov, dict) or "vehicle" not in ov:
            raise _Err("vehicles", f"overrides entry {j} must be a table with a 'vehicle' number")
        bad = sorted(set(ov) - _OVERRIDE_KEYS)
        if bad:
            raise _Err("vehicles", f"overrides entry {j}: unknown key(s) {', '.join(bad)}")
        i = ov["vehicle"]
        if isinstance(i, bool) or not isinstance(i, int) or not 1 <= i <= count:
            raise _Err("vehicles", f"overrides entry {j}: vehicle {i!r} does not exist; vehicles are 1..{count}")
        target = vehicles[i - 1]
        if "model" in ov and ov["model"] != target["model"]:
            target["params"] = {}
        for key in ("model", "current", "x0", "offset", "position", "noise", "cost"):
            if key in ov:
                target[key] = ov[key]
        target["params"].update(ov.get("params", {}))
    models = []
    for i, v in enumerate(vehicles, start=1):
        try:
            models.append(make_vehicle(v["model"], v["params"], f"vehicle {i}"))
        except ModelError as exc:
            raise _Err("vehicles", str(exc)) from None
    s = models[0].s
    if "offsets" in veh:
        for v, row in zip(vehicles, _rows("vehicles", "offsets", veh["offsets"], count, s)):
            v.setdefault("offset", row)
    if "positions" in veh and "x0" in veh:
        raise _Err("vehicles", "give positions or x0, not both")
    if "positions" in veh:
        for v, row in zip(vehicles, _rows("vehicles", "positions", veh["positions"], count, 3)):
            v.setdefault("position", row)
    if "x0" in veh:
        for v, row in zip(vehicles, _rows("vehicles", "x0", veh["x0"], count, None)):
            v.setdefault("x0", row)
    z0 = path.z0
    for i, (v, mdl) in enumerate(zip(vehicles, models), start=1):
        pos = v.pop("position", None)
        if pos is not None:
            if mdl.position_states is None:
                raise _Err("vehicles", f"vehicle {i}: model {mdl.name} has no position states; give x0")
            if "x0" in v:
                raise _Err("vehicles", f"vehicle {i}: give position or x0, not both")
            x0 = np.zeros(mdl.p)
            # start at the given position, moving with the leader
            vel = path.velocity_matrix() @ z0
            x0[list(mdl.position_states)] = pos
            if mdl.name == "remus100":
                x0[3:6] = vel
            v["x0"] = x0.tolist()

    # disturbances, noise, cost ------------------------------------------------------
    if "current" in data and "disturbance" in data:
        raise _Err("current", "give [current] or [disturbance], not both")
    for v in vehicles:
        if "disturbance" in data:
            v["disturbance"] = dict(data["disturbance"])
        else:
            cur = dict(data.get("current", {}))
            cur.update(v.get("current", {}))
            v["current"] = cur
    noise = data.get("noise", {})
    cost = data.get("cost", {})
    for i, v in enumerate(vehicles, start=1):
        own_noise, own_cost = v.pop("noise", {}), v.pop("cost", {})
        bad = sorted(set(own_noise) - {"process", "position", "reference"})
        bad += sorted(set(own_cost) - FLEET_SCHEMA["cost"])
        if bad:
            raise _Err("vehicles", f"overrides for vehicle {i}: unknown noise/cost key(s) {', '.join(bad)}")
        v["W_x"] = own_noise.get("process", noise.get("process", 0.0))
        v["V_y"] = own_noise.get("position", noise.get("position", 0.0))
        v["V_ybar"] = own_noise.get("reference", noise.get("reference", 0.0))
        v["Q"] = own_cost.get("Q", cost.get("Q", 1.0))
        v["R"] = own_cost.get("R", cost.get("R", 1.0))
    graph = data["graph"]
    spec = {
        "vehicles": vehicles,
        "graph": {"edges": graph.get("edges", []), "pinning": graph.get("pinning", []),
                  "coupling": graph.get("coupling")},
        "leader": leader,
        "noise_convention": noise.get("convention", "intensity"),
    }
    sim = data["simulation"]
    return spec, dict(sim)


def section_of_model_error(msg: str) -> str:
    """The scenario section a fleet ModelError message most likely refers to."""
    low = msg.lower()
    for word, section in (("edge", "graph"), ("pinning", "graph"), ("graph", "graph"),
                          ("leader", "leader"), ("hears", "graph"), ("path from", "graph"),
                          ("current", "current"), ("disturbance", "disturbance"),
                          ("vehicle", "vehicles")):
        if word in low:
            return section
    return ""

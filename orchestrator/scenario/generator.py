"""Generated fleets: N REMUS 100 vehicles in a grid formation behind a leader.

Used by the benchmark (N = 1, 5, 20, 50) and to write the built-in ``formation-20``
scenario. Vehicles are placed row by row, ``columns`` per row, rows 10 m apart behind the
leader and columns 10 m apart across; the front-centre vehicle hears the leader; every
other vehicle hears the vehicle in front of it (weight 1) and its neighbour towards the
centre of its row (weight 0.5), so information flows from the leader outwards and
backwards and every vehicle has a path from the leader.
"""
from __future__ import annotations

import json
import math
from typing import Any

from estimator_fmu.registry import DEFAULT_ESTIMATOR

__all__ = ["grid_fleet", "on_remus", "survey_grid_fleet", "scenario_toml"]

#: the second-order consensus coupling of formation-4: acceleration from relative
#: position (0.02 1/s^2) and relative velocity (0.2 1/s)
SECOND_ORDER_COUPLING = [[0.0] * 6, [0.0] * 6, [0.0] * 6,
                         [0.02, 0.0, 0.0, 0.2, 0.0, 0.0],
                         [0.0, 0.02, 0.0, 0.0, 0.2, 0.0],
                         [0.0, 0.0, 0.02, 0.0, 0.0, 0.2]]


def grid_fleet(N: int, *, columns: int = 5, spacing: float = 10.0, T: float = 300.0,
               h: float = 0.01, name: str | None = None) -> dict[str, Any]:
    """A fleet scenario mapping (as parsed from TOML) of N vehicles in a grid."""
    if N < 1:
        raise ValueError(f"N = {N} must be at least 1")
    cols = min(columns, N)
    centre = (cols - 1) // 2
    index = {}
    offsets, positions = [], []
    for k in range(N):
        row, col = divmod(k, cols)
        index[(row, col)] = k + 1
        off = [-spacing * row + 0.0, spacing * (col - centre) + 0.0, 0.0]
        offsets.append(off)
        # launched off formation by a few metres (deterministic)
        positions.append([round(off[0] + 3.0 * math.sin(1.7 * k) - 5.0, 3),
                          round(off[1] + 3.0 * math.cos(1.3 * k), 3),
                          round(20.0 + 1.5 * math.sin(0.9 * k), 3)])
    edges = []
    for (row, col), i in index.items():
        if row > 0 and (row - 1, col) in index:
            edges.append([index[(row - 1, col)], i, 1.0])
        if col != centre:
            towards = col - 1 if col > centre else col + 1
            if (row, towards) in index:
                edges.append([index[(row, towards)], i, 0.5 if row > 0 else 1.0])
    leader = index[(0, centre)]
    return {
        "name": name or f"grid-{N}",
        "description": f"{N} REMUS 100 AUVs in a {cols}-wide grid behind a leader on a circle",
        "simulation": {"T": T, "h": h, "seed": 0, "estimator": DEFAULT_ESTIMATOR,
                       "tracking": "regulator"},
        "leader": {"path": "circle", "radius": 150.0, "speed": 1.5, "center": [150.0, 0.0, 20.0],
                   "clockwise": True, "start_angle_deg": 180.0, "noise": 0.0},
        "vehicles": {"count": N, "model": "remus100", "params": {"cruise_speed": 1.5},
                     "offsets": offsets, "positions": positions},
        "graph": {"edges": edges, "pinning": [[leader, 1.0]], "coupling": SECOND_ORDER_COUPLING},
        "current": {"time_constant": 30.0, "sigma": 0.1, "w0": [0.1, -0.05, 0.0]},
        "noise": {"convention": "intensity", "process": 1e-4, "position": 0.25, "reference": 0.0},
        "cost": {"Q": 1.0, "R": 0.01},
    }


def survey_grid_fleet(N: int = 100, *, columns: int = 10, spacing: float = 10.0,
                      T: float = 300.0, h: float = 0.01,
                      name: str | None = None) -> dict[str, Any]:
    """A fleet scenario mapping of N vehicles in a ``columns``-wide grid behind a leader on a
    survey (lawnmower) path, deployed per vehicle with the distributed law.

    Rows are ``spacing`` m apart behind the leader, columns ``spacing`` m apart across,
    centred on the leader's track. The front row hears the leader (a_i0 = 1); a vehicle in
    row r > 0 hears the (up to three) vehicles of row r - 1 in the columns c - 1, c, c + 1
    (weights 0.25, 0.5, 0.25) and the vehicle two rows ahead in its column (0.25): at most
    four neighbours, all nearer the leader, so information flows backwards and every
    vehicle has a path from the leader. The survey legs (600 m north, 200 m apart) are wide
    enough that the outer vehicles of a 90 m wide formation turn at about 2.2 m/s.

    Parameters
    ----------
    N : int, optional
        Number of vehicles (at least 1).
    columns : int, optional
        Vehicles per row.
    spacing : float, optional
        Distance between rows and between columns, m.
    T, h : float, optional
        Horizon and communication step, s.
    name : str or None, optional
        Scenario name (default ``survey-<N>``).

    Returns
    -------
    dict[str, Any]
        The scenario as parsed from TOML.
    """
    if N < 1:
        raise ValueError(f"N = {N} must be at least 1")
    from plant_model.leader_paths import make_leader

    leader = {"leg_length": 600.0, "spacing": 200.0, "speed": 1.5, "harmonics": 3,
              "start": [0.0, 0.0, 20.0]}
    # the lawnmower starts in the middle of its rounded turn, spacing / 2 west of start:
    # the vehicles are launched around where the leader is at t = 0
    lead0 = make_leader("lawnmower", leader).position(0.0).reshape(-1)
    cols = min(columns, N)
    centre = (cols - 1) / 2.0
    index = {}
    offsets, positions = [], []
    for k in range(N):
        row, col = divmod(k, cols)
        index[(row, col)] = k + 1
        off = [-spacing * (row + 1) + 0.0, spacing * (col - centre) + 0.0, 0.0]
        offsets.append(off)
        positions.append([round(float(lead0[0]) + off[0] + 2.0 * math.sin(1.7 * k) - 3.0, 3),
                          round(float(lead0[1]) + off[1] + 2.0 * math.cos(1.3 * k), 3),
                          round(float(lead0[2]) + 1.0 * math.sin(0.9 * k), 3)])
    edges = []
    for (row, col), i in index.items():
        for dr, dc, a in ((1, -1, 0.25), (1, 0, 0.5), (1, 1, 0.25), (2, 0, 0.25)):
            j = index.get((row - dr, col + dc))
            if row > 0 and j is not None:
                edges.append([j, i, a])
    pinning = [[i, 1.0] for (row, _), i in index.items() if row == 0]
    return {
        "name": name or f"survey-{N}",
        "description": (f"{N} REMUS 100 AUVs in a {cols}-wide grid behind a leader on a "
                        "lawnmower survey; the front row hears the leader"),
        "simulation": {"T": T, "h": h, "seed": 0, "estimator": DEFAULT_ESTIMATOR,
                       "tracking": "regulator",
                       "deployment": "per-vehicle", "architecture": "distributed"},
        "leader": {"path": "lawnmower", **leader, "noise": 0.0},
        "vehicles": {"count": N, "model": "remus100", "params": {"cruise_speed": 1.5},
                     "offsets": offsets, "positions": positions},
        "graph": {"edges": edges, "pinning": pinning, "coupling": SECOND_ORDER_COUPLING},
        "current": {"time_constant": 30.0, "sigma": 0.1, "w0": [0.1, -0.05, 0.0]},
        "noise": {"convention": "intensity", "process": 1e-4, "position": 0.25, "reference": 0.0},
        "cost": {"Q": 1.0, "R": 0.01},
    }


def on_remus(data: dict[str, Any], *, speed: float = 2.0, bandwidth: float = 0.2,
             name: str | None = None) -> dict[str, Any]:
    """The same fleet on the nonlinear REMUS 100 (``remus100-6dof``) with its navigation
    sensors, deployed per vehicle with the distributed law: the leader at ``speed`` (m/s;
    the design model linearized there), the weight chosen by ``[design] bandwidth``
    (rad/s) instead of ``[cost] R``, the controllers clipped at the vehicle's force, and
    the path refused if a vehicle cannot fly it (docs/design.md)."""
    out = {k: (dict(v) if isinstance(v, dict) else v) for k, v in data.items()}
    out["name"] = name or f"{data['name']}-remus"
    out["description"] = (f"{data['vehicles']['count']} nonlinear REMUS 100 AUVs with REMUS "
                          f"navigation, the {data['leader']['path']} leader at {speed:g} m/s")
    out["simulation"].update(deployment="per-vehicle", architecture="distributed")
    out["leader"]["speed"] = speed
    out["vehicles"].update(model="remus100-6dof", params={"cruise_speed": speed})
    out["cost"] = {k: v for k, v in data["cost"].items() if k != "R"}
    sections = list(out)
    at = sections.index("noise")
    items = list(out.items())
    items.insert(at, ("sensors", {"kind": "remus"}))
    out = dict(items)
    out["design"] = {"bandwidth": bandwidth, "u_max": "vehicle", "path_check": "refuse"}
    return out


def _toml_value(v: Any) -> str:
    """TOML text of a value (floats by repr: nan, inf and -inf are TOML too)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + " }"
    if v and isinstance(v[0], list):
        return "[\n" + "".join(f"  {_toml_value(x)},\n" for x in v) + "]"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {v!r} as TOML")


def scenario_toml(data: dict[str, Any], header: str = "") -> str:
    """The TOML text of a scenario mapping (top-level keys, then one table per section)."""
    lines = [header.rstrip()] if header else []
    for k, v in data.items():
        if not isinstance(v, dict):
            lines.append(f"{k} = {_toml_value(v)}")
    for section, table in data.items():
        if isinstance(table, dict):
            lines.append(f"\n[{section}]")
            lines += [f"{k} = {_toml_value(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"

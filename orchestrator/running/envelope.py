"""``auv-cosim envelope``: where a formation holds. A grid of leader speed, turn radius and
ocean-current strength around a fleet scenario; at each point one run of the scenario's
fleet (its vehicles, graph, design, sensors and estimator) behind a leader on a straight
line (radius ``inf``) or a circle of that radius at that speed, the current's stationary
standard deviation set to that strength, the vehicles started in formation. The formation
*holds* at a point when the largest tracking error over the statistics window,
``max_error`` (orchestrator.analysis.tracking_segments), stays within the tolerance.

Writes ``<out>/summary.json`` with ``envelope``: the tolerance and per point its leader
speed (m/s), radius (m, null for a straight line), current (m/s), ``holds``,
``max_error``, ``rms_error`` (over the window, m), ``actuator_saturation_fraction`` and
the folder of its run (``points/<i>``, its own .rrd and summary.json).
"""
from __future__ import annotations

import copy
import itertools
import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..atomic import write_text_atomically
from ..scenario import Scenario, scenario_from_dict

__all__ = ["envelope_point", "run_envelope"]


def envelope_point(sc: Scenario, speed: float, radius: float, current: float) -> Scenario:
    """The scenario of one grid point (module docstring); ``radius`` inf: a straight line.

    Raises
    ------
    ScenarioError
        If the point does not make a valid scenario (named by the loader).
    """
    data = copy.deepcopy(dict(sc.raw))
    leader = sc.fleet["leader"]
    depth = float((np.asarray(leader["H"], float) @ np.asarray(leader["z0"], float))[2])
    if math.isinf(radius):
        data["leader"] = {"path": "straight", "speed": speed, "start": [0.0, 0.0, depth],
                          "noise": 0.0}
    else:
        data["leader"] = {"path": "circle", "radius": radius, "speed": speed,
                          "center": [0.0, 0.0, depth], "noise": 0.0}
    data.setdefault("current", {})["sigma"] = current
    vehicles = data["vehicles"]
    for key in ("positions", "x0"):                  # start in formation
        vehicles.pop(key, None)
    for o in vehicles.get("overrides", []):
        o.pop("position", None)
        o.pop("x0", None)
    where = f"{sc.source} (envelope: speed {speed:g} m/s, radius {radius:g} m, current " \
            f"{current:g} m/s)"
    new = scenario_from_dict(data, where)
    return new.with_run(T=sc.T, h=sc.h, seed=sc.seed, estimator=sc.estimator,
                        tracking=sc.tracking, deployment=sc.deployment,
                        architecture=sc.architecture, fmus=sc.fmus)


def run_envelope(sc: Scenario, speeds: Sequence[float], radii: Sequence[float],
                 currents: Sequence[float], tolerance: float, out: Path, *,
                 log: Callable[[str], None]) -> dict[str, Any]:
    """Run every grid point (module docstring) on the scenario's seed.

    Returns
    -------
    dict[str, Any]
        The summary (also ``out / summary.json``).
    """
    from .compare import simulate

    points = []
    grid = list(itertools.product(speeds, radii, currents))
    for i, (speed, radius, current) in enumerate(grid, start=1):
        variant = envelope_point(sc, speed, radius, current)
        folder = Path("points") / str(i)
        s = simulate(variant, [sc.estimator], [sc.seed], out / folder, progress=False,
                     log=lambda _: None)
        (m,) = s["methods"].values()
        rms = [v for v in (m.get("rms_error_straight"), m.get("rms_error_turns"))
               if v is not None]
        point = {"speed": speed, "radius": None if math.isinf(radius) else radius,
                 "current": current, "holds": m.get("max_error") is not None
                 and m["max_error"] <= tolerance, "max_error": m.get("max_error"),
                 "rms_error": max(rms) if rms else None,
                 "actuator_saturation_fraction": m.get("actuator_saturation_fraction"),
                 "folder": str(folder)}
        points.append(point)
        log(f"{i:3d}/{len(grid)} speed {speed:g} m/s, radius "
            f"{'straight' if point['radius'] is None else format(radius, 'g') + ' m'}, "
            f"current {current:g} m/s: max error {point['max_error']:.3g} m -> "
            f"{'holds' if point['holds'] else 'does not hold'}")
        if s.get("interrupted"):
            break
    summary = {"scenario": sc.name, "T": sc.T, "h": sc.h, "seed": sc.seed,
               "estimator": sc.estimator, "architecture": sc.architecture,
               "models": sorted({v.get("model", "remus100") for v in sc.fleet["vehicles"]}),
               "envelope": {"tolerance_m": tolerance, "points": points},
               "interrupted": len(points) < len(grid)}
    write_text_atomically(out / "summary.json", json.dumps(summary, indent=2) + "\n")
    return summary
